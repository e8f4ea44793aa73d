"""Fig. 3's position_units: the record handed to the filters is the acceleration in the chosen length unit
(× 100 for cm), so that the paper's unitless Qd and Rd are read in that unit; an unknown unit is refused."""

import numpy as np
import pytest

from experiments.paper import fig3
from methods.kalman import akf


def test_unknown_unit_is_refused():
    with pytest.raises(ValueError, match="km"):
        fig3._check(fig3.Params(position_units=["km"]))


def test_cm_record_is_the_metre_record_with_qd_and_rd_divided_by_1e4(noisy_record):
    """The filter is linear in the modal states: scaling the record by c and (Qd_modal, Rd) by c² leaves the
    frequency estimates unchanged (P0 of the modal states follows the record's magnitude). So the cm reading
    equals metres with Qd_modal = 1e-8 m², Rd = 1e-6 m²."""
    y = noisy_record(n_samples=200, noise_ug=10.0, seed=3)
    opts = {"p0_frequency_var": [1.0, 20.0, 40.0, 200.0], "estimate_bias": False}
    prior = [3.8, 16.0, 26.0, 46.0]
    cm = akf.identify(y * fig3.UNIT_PER_METRE["cm"], 0.02, prior, **opts)
    metres = akf.identify(y, 0.02, prior, qd_modal=1e-8, rd=1e-6, **opts)
    assert cm.history.shape == metres.history.shape
    assert np.allclose(cm.history, metres.history, rtol=1e-6)      # the whole frequency track (Fig. 3's curves)
    paper_m = akf.identify(y, 0.02, prior, **opts).history
    k = min(len(paper_m), len(cm.history))
    assert not np.allclose(cm.history[:k], paper_m[:k], rtol=1e-3)
