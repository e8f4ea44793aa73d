"""One acceleration channel of a measurement file, in m/s², with its sampling step; the file read by the
reader of its extension (:mod:`experiments.recordings.formats`):

=============  =======================  ==============================================================
extension      library                  channel, unit and time taken from
=============  =======================  ==============================================================
.csv           numpy.loadtxt, csv       columns; a time column ``t``/``time``; ``name [unit]`` headers
.uff .unv      pyuff (UFF type 58)      one set per channel (``id1``), ``ordinate_axis_units_lab``,
                                        ``abscissa_inc``
.lvm           lvm-read                 ``Channel names``, ``Y_Unit_Label``, ``X_Value``/``Delta_X``
.tdms          npTDMS                   ``group/channel``, ``unit_string``, ``wf_increment``
.mat           scipy.io.loadmat         numeric variables; ``t``/``time``, ``dt`` or ``fs``; ``units``
=============  =======================  ==============================================================

Units: g (9.80665 m/s²), m/s², mm/s². The file's own unit wins when it names one; ``units`` given by the
user and contradicted by the file is an error, and a file that names no unit needs ``units`` (a CSV's
column ``accel`` without a unit is m/s², as it always was).

The sampling step. Loggers round their time stamps (LabVIEW writes 1 µs), so the step is not the
difference of two stamps: it is the slope of a least-squares fit of t against the sample index,
tₖ ≈ t₀ + k·Δt, over the whole record (``numpy.polyfit``). The stamps are refused only when they do not
increase, open a gap, make a step or deviate from the fit by more than their printed precision allows
(:func:`uniform_step`); what was found is said in :attr:`Record.notes`.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from experiments.recordings.formats import FORMATS, RawFile
from experiments.units import G_M_S2, MAX_ABS_ACCEL_M_S2

__all__ = ["G_M_S2", "UNITS_M_S2", "MIN_SAMPLES", "MAX_ABS_ACCEL_M_S2", "LEGACY_CSV_CHANNEL", "Record",
           "read_record", "uniform_step"]

UNITS_M_S2 = {"g": G_M_S2, "m/s^2": 1.0, "mm/s^2": 1e-3}
MIN_SAMPLES = 8                       # the fewest samples any method accepts (methods.check_inputs)
LEGACY_CSV_CHANNEL = "accel"          # the CSV column of the first release: m/s² when no unit is named


@dataclass(frozen=True)
class Record:
    """One channel of a measurement, in SI units.

    Attributes
    ----------
    accel_m_s2 : ndarray, shape (N,)
        Acceleration in m/s².
    dt_s, t0_s : float
        Sample interval and time of the first sample, s.
    path : str
        The file read.
    channel : str
        The channel's name in the file.
    unit : str
        The unit the file's samples were in (``g``, ``m/s^2`` or ``mm/s^2``).
    notes : list of str
        What the reader found and decided (time step, unit), to be printed.
    """

    accel_m_s2: np.ndarray
    dt_s: float
    t0_s: float
    path: str
    channel: str
    unit: str
    notes: list[str] = field(default_factory=list)


def read_record(path, *, channel: str | None = None, units: str | None = None,
                dt: float | None = None) -> Record:
    """Read one acceleration channel of a measurement file; the reader follows the extension.

    Parameters
    ----------
    path : str or Path
        The file (.csv, .uff, .unv, .lvm, .tdms, .mat).
    channel : str, optional
        Which channel of a multi-channel file; required when there are several (the error lists them).
    units : str, optional
        ``g``, ``m/s^2`` (or ``m/s²``) or ``mm/s^2``, for a file that names none; must agree with one that
        does.
    dt : float, optional
        Sample interval in s, for a file without time stamps or step; must agree with one that has them.

    Returns
    -------
    Record

    Raises
    ------
    ValueError
        One line naming the file and the problem; FileNotFoundError when there is no file.
    """
    path = Path(path)
    ext = path.suffix.lower()
    if ext not in FORMATS:
        raise ValueError(f"{path}: unknown extension '{path.suffix}'; known: {', '.join(sorted(FORMATS))}")
    if not path.is_file():
        raise FileNotFoundError(f"measurement file {path} does not exist")
    wanted_unit = _unit(units, f"{path}: data.units") if units is not None else None
    if dt is not None and not (np.isfinite(dt) and dt > 0):
        raise ValueError(f"{path}: data.dt = {dt} must be a positive sample interval in s")
    raw = FORMATS[ext](path)
    name = _pick_channel(path, raw, channel)
    y = np.asarray(raw.channels[name], dtype=float).reshape(-1)
    unit, unit_note = _resolve_unit(path, name, raw.units.get(name), wanted_unit, ext)
    notes = [f"channel '{name}' of {len(raw.channels)}" if len(raw.channels) > 1 else f"channel '{name}'", unit_note]
    if y.size < MIN_SAMPLES:
        raise ValueError(f"{path}: {y.size} samples; at least {MIN_SAMPLES} are needed")
    bad = np.flatnonzero(~np.isfinite(y))
    if bad.size:
        raise ValueError(f"{path}: sample {int(bad[0]) + 1} of channel '{name}' is not a finite number")
    y = y * UNITS_M_S2[unit]
    big = np.flatnonzero(np.abs(y) > MAX_ABS_ACCEL_M_S2)
    if big.size:
        r = int(big[0])
        shown = unit.replace("^2", "²")
        raise ValueError(f"{path}: row {r + 1}: {name} = {y[r] / UNITS_M_S2[unit]:g} {shown} is not a physical "
                         f"acceleration (|accel| ≤ {MAX_ABS_ACCEL_M_S2:g} m/s², 1e5 g); check the units")
    step, t0, time_note = _time_step(path, raw, dt, y.size)
    notes.append(time_note)
    return Record(y, step, t0, str(path), name, unit, notes)


# ---------------------------------------------------------------------------------------------- units

def _unit(text: str, what: str) -> str:
    """The canonical name of an acceleration unit (``g``, ``m/s^2``, ``mm/s^2``), or ValueError."""
    u = str(text).strip().lower().replace(" ", "").replace("²", "^2").replace("**", "^")
    u = {"g0": "g", "gn": "g", "gs": "g", "m/s2": "m/s^2", "ms^-2": "m/s^2", "m*s^-2": "m/s^2",
         "m/sec^2": "m/s^2", "mm/s2": "mm/s^2", "mms^-2": "mm/s^2"}.get(u, u)
    if u not in UNITS_M_S2:
        raise ValueError(f"{what} = '{text}' is not an acceleration unit; known: g, m/s^2, mm/s^2")
    return u


def _resolve_unit(path: Path, name: str, in_file: str | None, wanted: str | None, ext: str) -> tuple[str, str]:
    if in_file is not None and str(in_file).strip():
        found = _unit(in_file, f"{path}: the unit of channel '{name}'")
        if wanted is not None and wanted != found:
            raise ValueError(f"{path}: data.units={wanted} contradicts the file, whose channel '{name}' is in "
                             f"{found}; leave data.units out or correct it")
        return found, f"unit {found} (from the file)"
    if wanted is not None:
        return wanted, f"unit {wanted} (data.units)"
    if ext == ".csv" and name == LEGACY_CSV_CHANNEL:
        return "m/s^2", "unit m/s^2 (a CSV column 'accel' without a unit)"
    raise ValueError(f"{path}: the file names no unit for channel '{name}'; give data.units= (g, m/s^2 or mm/s^2)")


def _pick_channel(path: Path, raw: RawFile, channel: str | None) -> str:
    names = list(raw.channels)
    if not names:
        raise ValueError(f"{path}: no acceleration channel found in the file")
    if channel is None:
        if len(names) > 1:
            raise ValueError(f"{path}: {len(names)} channels; choose one with data.channel= "
                             f"(channels: {', '.join(names)})")
        return names[0]
    if channel not in raw.channels:
        raise ValueError(f"{path}: no channel '{channel}' (channels: {', '.join(names)})")
    return channel


# ----------------------------------------------------------------------------------------------- time

def _time_step(path: Path, raw: RawFile, dt: float | None, n: int) -> tuple[float, float, str]:
    """Δt, t₀ and a note: from the stamps (least squares), the file's step, or ``dt``; they must agree."""
    if raw.time is not None:
        t = np.asarray(raw.time, dtype=float)
        if t.size != n:
            raise ValueError(f"{path}: {t.size} time stamps for {n} samples")
        step, t0, note = uniform_step(path, t, raw.time_quantum)
    elif raw.dt is not None:
        step, t0, note = float(raw.dt), float(raw.t0), f"time step {raw.dt:.10g} s from the file"
        if not (np.isfinite(step) and step > 0):
            raise ValueError(f"{path}: the file's sample interval {raw.dt} s is not a positive number")
    elif dt is not None:
        return float(dt), 0.0, f"time step {dt:.10g} s (data.dt; the file has no time)"
    else:
        raise ValueError(f"{path}: the file has no time column or sample interval; give data.dt= (s)")
    if dt is not None and abs(dt - step) > 1e-6 * step:
        raise ValueError(f"{path}: data.dt = {dt:g} s contradicts the file's step {step:.10g} s; leave data.dt out")
    return step, t0, note


def uniform_step(path, t: np.ndarray, quantum) -> tuple[float, float, str]:
    """The sample interval of time stamps ``t`` by least squares, tₖ ≈ t₀ + k·Δt, and a note.

    Parameters
    ----------
    t : ndarray, shape (N,)
        Time stamps, s.
    quantum : float or ndarray or None
        The resolution of each stamp as written (10^-d for d printed decimals); None: the float's own.

    Raises
    ------
    ValueError
        The first row that does not increase, opens a gap (a step over 1.5 times the median step), makes a
        step that differs from the median one by more than the two stamps' resolution allows, or deviates
        from the fit by more than its resolution allows (0.6 of a unit of its last digit: rounding gives at
        most 0.5; this catches a drifting clock).
    """
    with np.errstate(over="ignore", invalid="ignore"):    # stamps near the float's range: refused below
        dt, t0, note = _uniform_step(path, t, quantum)
    if not (np.isfinite(dt) and np.isfinite(t0)):
        raise ValueError(f"{path}: the time stamps ({t[0]:.3g} ... {t[-1]:.3g} s) are too large to fit a step to")
    return dt, t0, note


def _uniform_step(path, t: np.ndarray, quantum) -> tuple[float, float, str]:
    n = t.size
    step = np.diff(t)
    if np.any(step <= 0):
        r = int(np.flatnonzero(step <= 0)[0]) + 1
        raise ValueError(f"{path}: row {r + 1}: t = {t[r]:.10g} does not increase (previous row t = {t[r - 1]:.10g})")
    q = _decimal_quantum(t) if quantum is None else np.broadcast_to(np.asarray(quantum, float), t.shape)
    typical = float(np.median(step))
    gap = np.flatnonzero(step > 1.5 * typical)
    if gap.size:
        r = int(gap[0]) + 1
        raise ValueError(f"{path}: row {r + 1}: t = {t[r]:.10g} breaks the uniform sampling: a gap of "
                         f"{step[r - 1]:.6g} s where the step is {typical:.6g} s")
    # each step between two rounded stamps is off the true one by at most half a unit of each; the mean
    # step end to end is the true one to within a unit / (N − 1) (a median of rounded steps is not)
    typical = float((t[-1] - t[0]) / (n - 1))
    local = np.abs(step - typical) > 0.6 * (q[1:] + q[:-1]) + 8 * np.spacing(np.abs(t[1:]))
    if local.any():
        r = int(np.flatnonzero(local)[0]) + 1
        raise ValueError(f"{path}: row {r + 1}: t = {t[r]:.10g} breaks the uniform sampling (step "
                         f"{step[r - 1]:.6g} s, expected {typical:.6g} s within the stamps' precision {q[r]:.2g} s)")
    k = np.arange(n, dtype=float)
    dt, t0 = np.polyfit(k - k.mean(), t, 1)              # centred index: a well-conditioned fit
    t0 -= dt * k.mean()
    tol = 0.6 * q + 8 * np.spacing(np.abs(t).max())
    dev = t - (t0 + dt * k)
    bad = np.flatnonzero(np.abs(dev) > tol)
    if bad.size:
        r = int(bad[0])
        raise ValueError(f"{path}: row {r + 1}: t = {t[r]:.10g} breaks the uniform sampling: it is "
                         f"{dev[r]:.3g} s off the fitted step {dt:.10g} s, more than its precision "
                         f"{q[r]:.3g} s allows (largest deviation {np.abs(dev).max():.3g} s)")
    t0 = float(np.round(t0 / np.median(q)) * np.median(q))     # the first stamp, to the stamps' resolution
    return float(dt), float(t0), (f"time step {dt:.10g} s ({1 / dt:.6g} Hz) fitted to {n} time stamps; "
                                  f"they deviate from it by at most {np.abs(dev).max():.2g} s, within their "
                                  f"printed precision ({float(np.median(q)):.2g} s)")


def _decimal_quantum(t: np.ndarray) -> np.ndarray:
    """The resolution of each stamp as its writer printed it, read back from the floats.

    A decimal text read as a float is the float nearest it, so the fewest decimals dᵢ that reproduce a stamp
    (``numpy.round(t, d) == t`` to a few ulp) are the decimals its writer printed, trailing zeros dropped.
    A writer prints either a fixed number of decimals (then the finest unit seen, 10^-max d, is every
    stamp's) or a fixed number S of significant digits (the most seen; each stamp's unit is that of its
    S-th digit); trailing zeros make a stamp look coarser than it is, so its resolution is its own printed
    one, but no coarser than the finer of those two rules. No decimals reproduce a stamp: the float's own
    spacing (a binary time channel).
    """
    t = np.asarray(t, float)
    ulp = 4 * np.spacing(np.abs(t))
    d = np.full(t.shape, -1)
    for k in range(16):                                  # 16 vectorised passes
        hit = (d < 0) & (np.abs(np.round(t, k) - t) <= ulp)
        d[hit] = k
    if (d < 0).any():
        return np.maximum(ulp, 1e-300)
    printed = 10.0 ** -d.astype(float)
    fixed = printed.min()
    with np.errstate(divide="ignore"):
        magnitude = np.floor(np.log10(np.abs(t)))
    digits = np.where(np.isfinite(magnitude), d + magnitude + 1, 1)
    by_digits = np.where(np.isfinite(magnitude), 10.0 ** (magnitude - digits.max() + 1), fixed)
    return np.minimum(printed, np.fmax(fixed, by_digits))
