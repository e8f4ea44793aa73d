"""Variants side by side: the per-cell numbers on a known summary, and the configs' provenance headers."""

import numpy as np
import pandas as pd
import pytest

from experiments.report import variants


def summary_rows(method, ratios, failure=0.0, identifiable=(True, True, True, False)):
    return [dict(method=method, noise_ug=10.0, n_samples=256, mode=m + 1, rmse_over_crlb=r, failure_rate=failure,
                 identifiable=i, coverage_1std=0.5) for m, (r, i) in enumerate(zip(ratios, identifiable,
                                                                                    strict=True))]


def test_medians_over_identifiable_modes_and_only_methods_with_several_variants():
    s = pd.DataFrame(summary_rows("akf", [100, 300, 200, 1e9]) + summary_rows("akf:tuned", [1, 3, 2, 1e9])
                     + summary_rows("pem", [1, 1, 1, 1]) + summary_rows("wkf:tuned", [5, 5, 5, 5], failure=0.8))
    t = variants.table(s).set_index("variant")
    assert set(t.index) == {"akf", "akf:tuned"}                   # pem, wkf:tuned: one variant each
    assert t.loc["akf", "median_rmse_over_crlb"] == pytest.approx(200)   # mode 4 not identifiable: left out
    assert t.loc["akf:tuned", "median_rmse_over_crlb"] == pytest.approx(2)
    assert (t["method"] == "akf").all() and (t["identifiable_modes"] == 3).all()


def test_a_variant_failing_more_than_half_has_no_accuracy_number():
    s = pd.DataFrame(summary_rows("pll", [1, 1, 1, 1], failure=0.9) + summary_rows("pll:tuned", [2, 2, 2, 2]))
    t = variants.table(s).set_index("variant")
    assert np.isnan(t.loc["pll", "median_rmse_over_crlb"]) and t.loc["pll", "worst_failure_rate"] == 0.9


def test_provenance_is_the_header_of_the_variant_config():
    (label, header), = variants.provenance(["pem:paper"])
    assert label.endswith("configs/method/pem_paper.yaml")
    assert header.strip()
