"""The prior as a distribution: ``prior_std_rad_s`` on the filters is their P0 of the frequencies."""

import numpy as np
import pytest

import methods
from methods.kalman._filter import settings_from

PRIOR = np.array([3.80, 16.0, 26.0, 46.0])       # Table 3's a-priori frequencies


@pytest.mark.parametrize("name", ["akf", "wkf"])
def test_filter_p0_of_the_frequencies_is_the_prior_spread_squared(name):
    opts = methods.check_options(name, PRIOR, 0.02, {"prior_std_rad_s": [1.0, 4.0, 6.0, 14.0]})
    np.testing.assert_allclose(settings_from(opts, PRIOR, name).p0_frequency_var, [1.0, 16.0, 36.0, 196.0])
    one = methods.check_options(name, PRIOR, 0.02, {"prior_std_rad_s": 2.0})
    np.testing.assert_allclose(settings_from(one, PRIOR, name).p0_frequency_var, [4.0] * 4)
    with pytest.raises(ValueError, match="not both"):
        methods.check_options(name, PRIOR, 0.02, {"prior_std_rad_s": 1.0, "p0_frequency_var": [1, 2, 3, 4]})
    with pytest.raises(ValueError, match="prior_std_rad_s"):
        methods.check_options(name, PRIOR, 0.02, {"prior_std_rad_s": [1.0, -2.0, 3.0, 4.0]})
