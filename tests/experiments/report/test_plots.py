"""Figure styling that tables and figures rely on: variants stay recognisable, big grids wrap."""

import matplotlib.colors
import numpy as np
import pandas as pd

from experiments.report import plots


def test_a_variant_keeps_its_methods_hue_but_not_its_colour():
    base, _ = plots._style("akf")
    for variant in ("akf:tuned", "akf:paper", "akf:other"):
        color, _ = plots._style(variant)
        assert color != base
        h0 = matplotlib.colors.rgb_to_hsv(matplotlib.colors.to_rgb(base))[0]
        h1 = matplotlib.colors.rgb_to_hsv(matplotlib.colors.to_rgb(color))[0]
        assert abs(h1 - h0) < 0.02
    assert plots._style("akf:tuned")[0] != plots._style("akf:paper")[0]


def test_failure_map_wraps_more_than_five_methods_into_rows(tmp_path, monkeypatch):
    methods = [f"m{i}" for i in range(7)]
    summary = pd.DataFrame([{"method": m, "noise_ug": 10.0, "n_samples": 64, "mode": 1, "failure_rate": 0.5}
                            for m in methods])
    figs = []
    monkeypatch.setattr(plots, "_save", lambda fig, stem: figs.append(fig) or [])
    plots.failure_map(summary, tmp_path / "f")
    panels = [ax for ax in figs[0].axes if ax.get_title() in methods]
    assert len(panels) == 7
    rows = {round(ax.get_position().y0, 3) for ax in panels}
    assert len(rows) == 2
    assert np.isclose(panels[0].images[0].get_array()[0, 0], 50)
