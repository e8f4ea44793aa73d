"""Readers of a measured acceleration record, chosen by the file's extension.

=============  =======================  ==============================================================
extension      library                  channel, unit and time taken from
=============  =======================  ==============================================================
.csv           pandas                   columns; a time column ``t``/``time``; ``name [unit]`` headers
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
increase, when there is a gap (a step over 1.5 Δt) or when a stamp deviates from the fit by more than
its printed precision allows (half a unit of the last printed digit, with margin); what was found is
said in :attr:`Record.notes`.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

G_M_S2 = 9.80665                      # standard gravity, m/s² per g
UNITS_M_S2 = {"g": G_M_S2, "m/s^2": 1.0, "mm/s^2": 1e-3}
MIN_SAMPLES = 8                       # the fewest samples any method accepts (methods.check_inputs)
# Largest |sample| accepted, m/s²: ±10⁵ g (as methods.estimate.MAX_ABS_ACCEL_M_S2, the methods' own rule).
MAX_ABS_ACCEL_M_S2 = 1e6
TIME_NAMES = ("t", "time", "x_value")
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


@dataclass
class _Raw:
    """What a format reader finds: channels (name -> samples), their units (None: not named), and the time
    as stamps (with their printed precision) or as a step."""

    channels: dict[str, np.ndarray]
    units: dict[str, str | None]
    time: np.ndarray | None = None
    time_quantum: np.ndarray | float | None = None
    dt: float | None = None
    t0: float = 0.0


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


def _pick_channel(path: Path, raw: _Raw, channel: str | None) -> str:
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

def _time_step(path: Path, raw: _Raw, dt: float | None, n: int) -> tuple[float, float, str]:
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


# -------------------------------------------------------------------------------------------- readers

_HEADER_UNIT = re.compile(r"^\s*(.*?)\s*[\[(]\s*([^\])]*)\s*[\])]\s*$")


def _split_header(col: str) -> tuple[str, str | None]:
    """``'accel [g]'`` -> (``'accel'``, ``'g'``); ``'accel'`` -> (``'accel'``, None)."""
    m = _HEADER_UNIT.match(col)
    return (m.group(1), m.group(2)) if m else (col.strip(), None)


def _read_csv(path: Path) -> _Raw:
    """The header by the csv module, the numbers by numpy's C parser (``numpy.loadtxt``: 10⁵ rows in a few
    tens of ms, every value the float nearest its text, as ``float()`` reads it; pandas, which the job
    otherwise never needs, costs 0.8 s to import). When a field is not a finite number the file is read
    again as text by pandas to name the first such row. The stamps' printed precision is read back from the
    floats (:func:`_decimal_quantum`)."""
    import csv

    try:
        with open(path, newline="", encoding="utf-8") as f:
            header = next(csv.reader(f, skipinitialspace=True), None)
    except (UnicodeDecodeError, csv.Error) as exc:
        raise ValueError(f"{path}: not a readable CSV ({' '.join(str(exc).split())})") from None
    if not header:
        raise ValueError(f"{path}: not a readable CSV (no header line)")
    try:
        values = np.loadtxt(path, delimiter=",", skiprows=1, ndmin=2, dtype=float, encoding="utf-8")
        columns = dict(zip(header, values.T, strict=True)) if np.isfinite(values).all() and values.size else None
    except ValueError:
        columns = None
    if columns is None:
        columns = _read_csv_text(path)
    raw = _Raw({}, {})
    for col, num in columns.items():
        name, unit = _split_header(str(col))
        if name.lower() in TIME_NAMES and raw.time is None:
            if unit is not None and unit.strip().lower() not in ("s", "sec", "seconds"):
                raise ValueError(f"{path}: time column '{col}' is in '{unit}'; give it in s")
            raw.time, raw.time_quantum = num, None
        else:
            raw.channels[name], raw.units[name] = num, unit
    return raw


def _read_csv_text(path: Path) -> dict[str, np.ndarray]:
    """The CSV as text, each field checked: ``ValueError`` naming the first field that is not a number."""
    import pandas as pd

    try:
        df = pd.read_csv(path, dtype=str, keep_default_na=False, skipinitialspace=True)
    except (pd.errors.ParserError, pd.errors.EmptyDataError, UnicodeDecodeError, ValueError) as exc:
        raise ValueError(f"{path}: not a readable CSV ({' '.join(str(exc).split())})") from None
    if df.shape[1] == 0 or len(df) == 0:
        raise ValueError(f"{path}: not a readable CSV (no columns or no rows)")
    out = {}
    for col in df.columns:
        num = pd.to_numeric(df[col].str.strip(), errors="coerce").to_numpy(dtype=float)
        bad = np.flatnonzero(~np.isfinite(num))
        if bad.size:
            r = int(bad[0])
            name = _split_header(str(col))[0]
            raise ValueError(f"{path}: row {r + 1}: {name} = '{df[col].iloc[r]}' is not a finite number")
        out[str(col).strip()] = num
    return out


UFF_ACCELERATION = 12                 # ordinate_spec_data_type of an acceleration (UFF 58, record 8)
UFF_TIME_RESPONSE = 1                 # func_type of a time response (UFF 58, record 6)


def _read_uff(path: Path) -> _Raw:
    import pyuff

    try:
        uff = pyuff.UFF(str(path))
        types = list(uff.get_set_types())
        sets = [s for s, ty in zip(_as_list(uff.read_sets()), types, strict=True) if int(ty) == 58]
    except Exception as exc:  # noqa: BLE001 - pyuff raises anything on a malformed file
        raise ValueError(f"{path}: not a readable UFF file ({type(exc).__name__}: {' '.join(str(exc).split())})"
                         ) from None
    if not sets:
        raise ValueError(f"{path}: no UFF type-58 (function at nodal DOF) data set in the file")
    raw = _Raw({}, {})
    steps = set()
    for i, s in enumerate(sets):
        name = str(s.get("id1") or "").strip() or f"node{s.get('rsp_node')}:{s.get('rsp_dir')}"
        if name in raw.channels:
            name = f"{name}#{i + 1}"
        if int(s.get("func_type", UFF_TIME_RESPONSE)) != UFF_TIME_RESPONSE:
            continue                                  # a spectrum or FRF: not a time record
        kind = int(s.get("ordinate_spec_data_type", 0))
        if kind not in (0, UFF_ACCELERATION):         # 0: unknown; 8 displacement, 11 velocity, 13 force...
            continue
        raw.channels[name] = np.real(np.asarray(s["data"]))
        raw.units[name] = s.get("ordinate_axis_units_lab") or None
        if int(s.get("abscissa_spacing", 1)) == 0:            # uneven: the abscissae are the time stamps
            raw.time = np.asarray(s["x"], float)
        steps.add((float(s.get("abscissa_inc")), float(s.get("abscissa_min", 0.0))))
    if not raw.channels:
        raise ValueError(f"{path}: no acceleration time record among its {len(sets)} type-58 sets")
    if len(steps) > 1:
        raise ValueError(f"{path}: the channels have different sampling ({sorted(steps)})")
    if raw.time is None:
        raw.dt, raw.t0 = steps.pop()
    return raw


def _as_list(sets):
    return sets if isinstance(sets, list) else [sets]


def _read_lvm(path: Path) -> _Raw:
    """lvm-read, told neither to read nor to write its pickle cache beside the file (a job writes nothing
    but its run folder, and loads no pickle)."""
    import lvm_read

    try:
        lvm = lvm_read.read(str(path), read_from_pickle=False, dump_file=False)
        seg = lvm[0]
        data = np.asarray(seg["data"], dtype=float)
        names = [str(c).strip() for c in seg["Channel names"]]
    except Exception as exc:  # noqa: BLE001 - lvm-read raises anything on a malformed file
        raise ValueError(f"{path}: not a readable LabVIEW measurement file ({type(exc).__name__}: "
                         f"{' '.join(str(exc).split())})") from None
    if lvm.get("Segments", 1) > 1:
        raise ValueError(f"{path}: {lvm['Segments']} segments; one segment (one record) is read")
    if data.ndim != 2 or data.shape[1] < len(names):
        raise ValueError(f"{path}: the data block does not match its {len(names)} channel names")
    raw = _Raw({}, {})
    units = list(seg.get("Y_Unit_Label", []))
    chan = 0
    for j, name in enumerate(names):
        if name.lower() == "comment":
            continue
        if name.lower() in TIME_NAMES:
            if lvm.get("X_Columns", "One") != "No" and np.isfinite(data[:, j]).all():
                raw.time = data[:, j]
            continue
        raw.channels[name] = data[:, j]
        raw.units[name] = units[chan] if chan < len(units) and units[chan] else None
        chan += 1
    deltas = [d for d in seg.get("Delta_X", []) if np.isfinite(d)]
    if raw.time is not None:
        pass                     # floats from lvm-read: their printed precision is found by uniform_step
    elif deltas:
        raw.dt, raw.t0 = float(deltas[0]), float((seg.get("X0") or [0.0])[0] or 0.0)
    return raw


def _read_tdms(path: Path) -> _Raw:
    from nptdms import TdmsFile

    try:
        tdms = TdmsFile.read(str(path))
        chans = [(f"{g.name}/{c.name}", c) for g in tdms.groups() for c in g.channels()]
        arrays = {name: np.asarray(c[:]) for name, c in chans}
    except Exception as exc:  # noqa: BLE001 - npTDMS raises anything on a malformed file
        raise ValueError(f"{path}: not a readable TDMS file ({type(exc).__name__}: {' '.join(str(exc).split())})"
                         ) from None
    if not chans:
        raise ValueError(f"{path}: not a readable TDMS file (no channel in it)")
    raw = _Raw({}, {})
    steps = set()
    for name, c in chans:
        if arrays[name].dtype.kind not in "iuf":
            continue
        if c.name.strip().lower() in TIME_NAMES:
            raw.time = arrays[name].astype(float)
            continue
        raw.channels[name] = arrays[name]
        raw.units[name] = c.properties.get("unit_string") or None
        if "wf_increment" in c.properties:
            steps.add((float(c.properties["wf_increment"]), float(c.properties.get("wf_start_offset", 0.0))))
    if raw.time is None and len(steps) == 1:
        raw.dt, raw.t0 = steps.pop()
    return raw


MAT_DT_NAMES, MAT_FS_NAMES, MAT_UNIT_NAMES = ("dt",), ("fs", "sample_rate", "sampling_rate"), ("units", "unit")


def _read_mat(path: Path) -> _Raw:
    """``scipy.io.loadmat`` (v4–v7.2 files). Numeric vectors are channels (a matrix N × C gives channels
    ``name[j]``); ``t``/``time`` the stamps, ``dt`` or ``fs`` the step, ``units`` (or ``<name>_units``)
    the unit."""
    import scipy.io

    try:
        mat = scipy.io.loadmat(str(path), squeeze_me=True)
    except Exception as exc:  # noqa: BLE001 - scipy.io raises anything on a malformed file
        raise ValueError(f"{path}: not a readable MATLAB file ({type(exc).__name__}: {' '.join(str(exc).split())};"
                         f" v7.3 files are HDF5: save with -v7)") from None
    vars_ = {k: v for k, v in mat.items() if not k.startswith("__")}
    low = {k.lower(): k for k in vars_}
    raw = _Raw({}, {})
    common_unit = next((str(vars_[low[u]]) for u in MAT_UNIT_NAMES if u in low), None)
    for key, v in vars_.items():
        a = np.asarray(v)
        if a.dtype.kind not in "iuf" or a.size < 2 or a.ndim > 2:
            continue
        if key.lower() in TIME_NAMES:
            raw.time = a.astype(float).reshape(-1)
        elif a.ndim == 1:
            raw.channels[key] = a
        else:
            a = a if a.shape[0] >= a.shape[1] else a.T
            raw.channels.update({f"{key}[{j}]": a[:, j] for j in range(a.shape[1])})
    for name in raw.channels:
        base = name.split("[")[0]
        own = low.get(f"{base.lower()}_units")
        raw.units[name] = str(vars_[own]) if own else common_unit
    dt = next((float(vars_[low[n]]) for n in MAT_DT_NAMES if n in low), None)
    fs = next((float(vars_[low[n]]) for n in MAT_FS_NAMES if n in low), None)
    if raw.time is None and (dt or fs):
        raw.dt = dt if dt else 1.0 / fs
    return raw


FORMATS = {".csv": _read_csv, ".uff": _read_uff, ".unv": _read_uff, ".lvm": _read_lvm, ".tdms": _read_tdms,
           ".mat": _read_mat}
