"""The figure of a tracked measurement (experiments.jobs.track_file): what a person looks at.

Top, the record's spectrogram (``scipy.signal.spectrogram``: Hann windows of about eight periods of the
slowest tracked mode, 7/8 overlap, zero-padded 8×, power in dB, each column stamped at its window's
centre) with, over it, each tracked mode's frequency (solid where the tracker calls it converged, dotted
where not) and its ±2σ band; the track is stamped at the time of the last sample it used (it is causal),
so after a jump it trails the spectrogram by up to a window. Below, the record itself in g (its min/max
envelope per pixel column when denser than the plot).
"""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np

from experiments.io import save_figure
from experiments.report.measurement_figure import DPI, G_M_S2, envelope

__all__ = ["SPECTROGRAM_PERIODS", "spectrogram_window", "track_figure"]

SPECTROGRAM_PERIODS = 8.0          # the spectrogram's window, in periods of the slowest tracked mode


def spectrogram_window(n: int, dt: float, slowest_rad_s: float) -> int:
    """Samples per spectrogram window: :data:`SPECTROGRAM_PERIODS` periods of the slowest mode, between 16
    samples and a quarter of the record."""
    per = SPECTROGRAM_PERIODS * 2 * np.pi / slowest_rad_s / dt if np.isfinite(slowest_rad_s) else n / 8
    return int(np.clip(round(per), 16, max(16, n // 4)))


def track_figure(stem, *, y, dt: float, t0: float, t_s, freq_rad_s, std_rad_s, converged,
                 title: str = "") -> list[Path]:
    """Draw the figure (module docstring) to ``<stem>.png`` and ``<stem>.svg``.

    Parameters
    ----------
    y : ndarray, shape (N,)
        The tracked record, m/s², sampled every ``dt`` s from file time ``t0``.
    t_s : ndarray, shape (K,)
        File times of the estimates, s.
    freq_rad_s, std_rad_s : ndarray, shape (K, m)
        The track and its 1σ, rad/s (NaN where none).
    converged : ndarray of bool, shape (K, m)
    """
    from matplotlib.figure import Figure  # matplotlib: only a job that draws pays its import
    from scipy.signal import spectrogram  # the figure only (scipy.signal's import is 1 s)

    y = np.asarray(y, float)
    t = t0 + np.arange(y.size) * dt
    f_hz = np.asarray(freq_rad_s, float) / (2 * np.pi)
    s_hz = np.asarray(std_rad_s, float) / (2 * np.pi)
    conv = np.asarray(converged, bool)
    with np.errstate(all="ignore"), warnings.catch_warnings(action="ignore", category=RuntimeWarning):
        slowest = float(np.nanmin(np.nanmedian(f_hz, axis=0))) * 2 * np.pi      # a mode never tracked: NaN
    nperseg = spectrogram_window(y.size, dt, slowest if np.isfinite(slowest) and slowest > 0 else np.nan)
    # zero-padded to 8× the window: the same resolution, drawn smoothly (a line between bins is visible)
    f, tt, p = spectrogram(y - y.mean(), fs=1.0 / dt, window="hann", nperseg=nperseg, nfft=8 * nperseg,
                           noverlap=nperseg - max(1, nperseg // 8), scaling="density", mode="psd")
    p_db = 10 * np.log10(np.maximum(p, np.max(p) * 1e-12 if np.max(p) > 0 else 1e-300))
    fig = Figure(figsize=(11, 7.0))
    # the colour bar in a column of its own, so that the spectrogram and the record below share one time axis
    grid = fig.add_gridspec(2, 2, height_ratios=[2.6, 1], width_ratios=[1, 0.02], left=0.08, right=0.93, top=0.94,
                            bottom=0.08, hspace=0.12, wspace=0.015)
    ax = fig.add_subplot(grid[0, 0])
    ax_rec = fig.add_subplot(grid[1, 0], sharex=ax)
    top = np.nanmax(f_hz + 2 * np.nan_to_num(s_hz)) if np.isfinite(f_hz).any() else f[-1]
    fmax = min(f[-1], 1.3 * top) if np.isfinite(top) else f[-1]
    keep = f <= fmax
    vmax = float(np.max(p_db[keep])) if keep.any() else float(np.max(p_db))
    mesh = ax.pcolormesh(t0 + tt, f[keep], p_db[keep], shading="nearest", cmap="Greys", vmin=vmax - 60, vmax=vmax,
                         rasterized=True)
    cbar = fig.colorbar(mesh, cax=fig.add_subplot(grid[0, 1]))
    cbar.set_label("PSD (dB re max)", fontsize=8)
    for i in range(f_hz.shape[1]):
        color = f"C{(i + 3) % 10}"
        lo, hi = f_hz[:, i] - 2 * s_hz[:, i], f_hz[:, i] + 2 * s_hz[:, i]
        ax.fill_between(t_s, lo, hi, where=np.isfinite(lo) & np.isfinite(hi), color=color, alpha=0.35, lw=0,
                        step="post")
        ax.plot(t_s, np.where(conv[:, i], f_hz[:, i], np.nan), color=color, lw=1.2, drawstyle="steps-post",
                label=f"mode {i + 1}" + ("" if np.isfinite(f_hz[:, i]).any() else " (never tracked)"))
        ax.plot(t_s, np.where(conv[:, i], np.nan, f_hz[:, i]), color=color, lw=0.8, ls=":",
                drawstyle="steps-post")
    ax.set_ylim(0, fmax)
    ax.set_ylabel("frequency (Hz)")
    ax.set_title(title, fontsize=10)
    ax.legend(loc="upper right", fontsize=7, ncol=min(3, f_hz.shape[1]), framealpha=0.8)
    ax.text(0.01, 0.02, f"spectrogram: Hann {nperseg} samples ({nperseg * dt:.3g} s, resolution "
                        f"{1 / (nperseg * dt):.3g} Hz), at window centres; "
                        "track (±2σ shaded): at its last sample (causal); dotted: not converged",
            transform=ax.transAxes, fontsize=7, color="k", backgroundcolor=(1, 1, 1, 0.7))
    ax.tick_params(labelbottom=False)
    columns = int(np.ceil(ax_rec.get_position().width * fig.get_figwidth() * DPI))
    ax_rec.plot(*envelope(t, y / G_M_S2, columns), lw=0.5, color="0.3")
    ax_rec.set_ylabel("record (g)")
    ax_rec.set_xlabel("time (s)")
    ax_rec.set_xlim(t[0], t[-1])
    stem = Path(stem)
    return [save_figure(fig, stem.with_suffix(".png"), tight=False, png_compression=1),
            save_figure(fig, stem.with_suffix(".svg"), tight=False)]
