"""The one figure of a run on a user's measurement: is the fit believable?

Top: the segment identified with the fitted model (the modes' damped sinusoids, least squares) and,
below it, the residual on its own scale. Bottom left: the segment's spectrum (Welch's estimate,
:func:`experiments.recordings.spectral.welch`) with
each identified mode marked and shaded over ±2σ of its frequency. Bottom right, when no prior was given:
the stabilisation diagram (model order against frequency; stable poles filled, others open) with the
modes it gave. Written as PNG and SVG beside ``estimate.json``.

Drawn for speed (the figure was half of the job's time; experiments.benchmarks.measurement): a record longer
than the plot is wide in pixels is drawn as its min/max envelope per pixel column (:func:`envelope`: every
peak and trough kept, the picture the same), the margins are fixed (no tight-bbox layout pass per file) and
the PNG is compressed at zlib level 1.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from experiments.io import save_figure
from experiments.recordings.spectral import welch
from experiments.units import G_M_S2

__all__ = ["G_M_S2", "DPI", "envelope", "measurement_figure"]

DPI = 150                  # experiments.io.save_figure's


def envelope(t: np.ndarray, y: np.ndarray, columns: int) -> tuple[np.ndarray, np.ndarray]:
    """The samples a line plot of (t, y) needs at ``columns`` pixel columns: per column the smallest and the
    largest sample, in their order in time (a line through them covers the same pixels as one through every
    sample); (t, y) as they are when there are fewer than four samples per column."""
    n = y.size
    per = n // max(int(columns), 1)
    if per < 4:
        return t, y
    m = n // per * per
    blocks = y[:m].reshape(-1, per)
    lo, hi = blocks.argmin(axis=1), blocks.argmax(axis=1)
    first, second = np.minimum(lo, hi), np.maximum(lo, hi)
    idx = (np.arange(blocks.shape[0])[:, None] * per + np.column_stack([first, second])).ravel()
    idx = np.r_[idx, np.arange(m, n)]          # the last partial column, as it is
    return t[idx], y[idx]


def measurement_figure(stem, *, y, dt: float, t0: float, model, residual, freq_rad_s, std_rad_s,
                       determined, diagram=None, title: str = "") -> list[Path]:
    """Draw the figure (module docstring) to ``<stem>.png`` and ``<stem>.svg``; the record in m/s²,
    drawn in g. ``diagram``: a :class:`methods.peers.stabilisation.Diagram`, or None."""
    import matplotlib.ticker  # matplotlib: only a job that draws pays its import
    from matplotlib.figure import Figure  # not pyplot: no backend machinery, 0.3 s less import

    t = t0 + np.arange(y.size) * dt
    # fixed margins: constrained layout cost 0.6 s of the job's 3 s (measured, experiments.benchmarks.measurement)
    fig = Figure(figsize=(11, 7.5))
    grid = fig.add_gridspec(3, 2, height_ratios=[2.2, 1, 2.4], left=0.08, right=0.99, top=0.965, bottom=0.06,
                            hspace=0.35, wspace=0.2)
    ax_rec = fig.add_subplot(grid[0, :])
    ax_res = fig.add_subplot(grid[1, :], sharex=ax_rec)
    ax_psd = fig.add_subplot(grid[2, 0] if diagram is not None else grid[2, :])
    columns = int(np.ceil(ax_rec.get_position().width * fig.get_figwidth() * DPI))
    ax_rec.plot(*envelope(t, y / G_M_S2, columns), lw=0.6, color="0.35", label="record")
    ax_rec.plot(*envelope(t, model / G_M_S2, columns), lw=0.8, color="C3", ls="--", label="fitted modes")
    ax_rec.set_ylabel("acceleration (g)")
    ax_rec.legend(loc="upper right", fontsize=8)
    ax_rec.set_title(title, fontsize=10)
    rms = float(np.sqrt(np.mean(residual**2)))
    ax_res.plot(*envelope(t, residual / G_M_S2, columns), lw=0.5, color="C0")
    ax_res.set_ylabel("residual (g)")
    ax_res.set_xlabel("time (s)")
    ax_res.text(0.01, 0.9, f"rms {rms / G_M_S2:.3g} g ({100 * rms / max(np.std(y), 1e-300):.2g} % of the record's)",
                transform=ax_res.transAxes, fontsize=8, va="top")
    f, p = welch(y - y.mean(), 1.0 / dt, min(2048, y.size))
    fr, pr = welch(residual, 1.0 / dt, min(2048, y.size))
    ax_psd.semilogy(f, p / G_M_S2**2, lw=0.8, color="0.35", label="record")
    ax_psd.semilogy(fr, pr / G_M_S2**2, lw=0.6, color="C0", alpha=0.7, label="residual")
    ax_psd.set_xlabel("frequency (Hz)")
    ax_psd.set_ylabel("PSD (g²/Hz)")
    # plain tick labels: the default 10^k mathtext is parsed by pyparsing, 0.8 s of CPU per figure (measured)
    ax_psd.yaxis.set_major_formatter(matplotlib.ticker.FuncFormatter(lambda v, _: f"{v:.0e}"))
    ax_psd.yaxis.set_minor_locator(matplotlib.ticker.NullLocator())   # 60 unlabelled marks: 0.1 s of drawing
    for i, (w, s, ok) in enumerate(zip(freq_rad_s, std_rad_s, determined, strict=True)):
        if not np.isfinite(w):
            continue
        fh, sh = w / (2 * np.pi), (s if np.isfinite(s) else 0.0) / (2 * np.pi)
        color = "C3" if ok else "C1"
        ax_psd.axvline(fh, color=color, lw=0.6, ls=":")
        ax_psd.axvspan(fh - 2 * sh, fh + 2 * sh, color=color, alpha=0.35, lw=0)
        ax_psd.annotate(f"{i + 1}: {fh:.4g} Hz ± {2 * sh:.2g} (2σ)" + ("" if ok else " (not determined)"),
                        (fh, 0.97 - 0.07 * i), xycoords=("data", "axes fraction"), fontsize=7, color=color,
                        ha="left", va="top", rotation=0, xytext=(3, 0), textcoords="offset points")
    ax_psd.legend(loc="lower left", fontsize=8)
    if diagram is not None:
        ax_st = fig.add_subplot(grid[2, 1], sharex=ax_psd)
        fd = diagram.freq_rad_s / (2 * np.pi)
        ax_st.scatter(fd[~diagram.stable], diagram.order[~diagram.stable], s=6, marker="o", facecolors="none",
                      edgecolors="0.6", lw=0.5, label="pole")
        ax_st.scatter(fd[diagram.stable], diagram.order[diagram.stable], s=8, color="C2", label="stable pole")
        for w in diagram.modes_rad_s:
            ax_st.axvline(w / (2 * np.pi), color="C3", lw=0.8, ls=":")
        ax_st.set_xlabel("frequency (Hz)")
        ax_st.set_ylabel("model order")
        ax_st.set_title(f"stabilisation diagram: {diagram.modes_rad_s.size} modes", fontsize=9)
        ax_st.legend(loc="lower right", fontsize=7)
    ax_psd.set_xlim(0, 0.5 / dt)
    stem = Path(stem)
    paths = [save_figure(fig, stem.with_suffix(".png"), tight=False, png_compression=1),
             save_figure(fig, stem.with_suffix(".svg"), tight=False)]
    return paths
