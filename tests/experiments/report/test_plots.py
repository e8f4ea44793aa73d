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


def test_label_points_keeps_crowded_names_apart():
    """Seven names on points within 1.3x of each other (a log-log cluster like the peers' on the Pareto
    figure): after drawing, no two names' rendered boxes (matplotlib's own text extents) overlap, and each name
    stays within 20 points across and 50 up or down of its marker."""
    import matplotlib.pyplot as plt

    from experiments.report.plots import label_points

    fig, ax = plt.subplots(figsize=(6.4, 4.6))
    pts = [(3.0, 1.00), (3.3, 1.05), (3.6, 1.02), (3.2, 1.12), (3.9, 1.08), (0.9, 1.0), (4.2, 0.98)]
    ax.scatter([p[0] for p in pts], [p[1] for p in pts])
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlim(0.3, 30)
    ax.set_ylim(0.5, 1e3)
    label_points(ax, [(x, y, f"method_{k} (12% fail)") for k, (x, y) in enumerate(pts)])
    fig.canvas.draw()
    boxes = [t.get_window_extent() for t in ax.texts]
    assert len(boxes) == len(pts)
    overlaps = [(i, j) for i in range(len(boxes)) for j in range(i) if boxes[i].overlaps(boxes[j])]
    assert not overlaps, overlaps
    px = fig.dpi / 72
    assert sorted(t.xy for t in ax.texts) == sorted(pts)
    for t in ax.texts:
        u, v = ax.transData.transform(t.xy)
        b = t.get_window_extent()
        near = min(abs(b.x0 - u), abs(b.x1 - u)) / px
        assert near < 20 and min(abs(b.y0 - v), abs(b.y1 - v)) / px < 50
    plt.close(fig)
