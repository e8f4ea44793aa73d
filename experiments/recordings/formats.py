"""The format readers behind :func:`experiments.recordings.read.read_record`, one per extension, each from
a maintained library: what a file holds, as channels (name -> samples), their units as the file names them
(None: not named) and its time (stamps, or a step). Checking and converting is read.py's.
"""

from __future__ import annotations

import csv
import re
import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import scipy.io

__all__ = ["TIME_NAMES", "RawFile", "UFF_ACCELERATION", "UFF_TIME_RESPONSE", "FORMATS", "INSTALL_HINT"]

# The optional extra that brings the readers of UFF, LabVIEW and TDMS files and the stabilisation diagram.
INSTALL_HINT = "pip install -e '.[measurements]'"

TIME_NAMES = ("t", "time", "x_value")


@dataclass
class RawFile:
    """What a format reader finds: channels (name -> samples), their units (None: not named), and the time
    as stamps (with their printed precision) or as a step."""

    channels: dict[str, np.ndarray]
    units: dict[str, str | None]
    time: np.ndarray | None = None
    time_quantum: np.ndarray | float | None = None
    dt: float | None = None
    t0: float = 0.0


_HEADER_UNIT = re.compile(r"^\s*(.*?)\s*[\[(]\s*([^\])]*)\s*[\])]\s*$")


def _split_header(col: str) -> tuple[str, str | None]:
    """``'accel [g]'`` -> (``'accel'``, ``'g'``); ``'accel'`` -> (``'accel'``, None)."""
    m = _HEADER_UNIT.match(col)
    return (m.group(1), m.group(2)) if m else (col.strip(), None)


def _read_csv(path: Path) -> RawFile:
    """The header by the csv module, the numbers by numpy's C parser (``numpy.loadtxt``: 10⁵ rows in a few
    tens of ms, every value the float nearest its text, as ``float()`` reads it; pandas, which the job
    otherwise never needs, costs 0.8 s to import). When a field is not a finite number the file is read
    again as text by pandas to name the first such row. The stamps' printed precision is read back from the
    floats (:func:`_decimal_quantum`)."""
    try:
        with open(path, newline="", encoding="utf-8-sig") as f:      # a byte-order mark is not a name
            header = next(csv.reader(f, skipinitialspace=True), None)
    except (UnicodeDecodeError, csv.Error) as exc:
        raise ValueError(f"{path}: not a readable CSV ({' '.join(str(exc).split())})") from None
    if not header:
        raise ValueError(f"{path}: not a readable CSV (no header line)")
    try:
        with warnings.catch_warnings():       # a file of no rows: said below in one line, not warned of too
            warnings.simplefilter("ignore", UserWarning)
            values = np.loadtxt(path, delimiter=",", skiprows=1, ndmin=2, dtype=float, encoding="utf-8")
        columns = dict(zip(header, values.T, strict=True)) if np.isfinite(values).all() and values.size else None
    except ValueError:
        columns = None
    if columns is None:
        columns = _read_csv_text(path)
    raw = RawFile({}, {})
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
    import pandas as pd  # 0.8 s, only to name a bad row (see _read_csv)

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


def _read_uff(path: Path) -> RawFile:
    import pyuff  # optional extra (.[measurements])

    try:
        uff = pyuff.UFF(str(path))
        types = list(uff.get_set_types())
        sets = [s for s, ty in zip(_as_list(uff.read_sets()), types, strict=True) if int(ty) == 58]
    except Exception as exc:  # noqa: BLE001 - pyuff raises anything on a malformed file
        raise ValueError(f"{path}: not a readable UFF file ({type(exc).__name__}: {' '.join(str(exc).split())})"
                         ) from None
    if not sets:
        raise ValueError(f"{path}: no UFF type-58 (function at nodal DOF) data set in the file")
    raw = RawFile({}, {})
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


def _read_lvm(path: Path) -> RawFile:
    """lvm-read, told neither to read nor to write its pickle cache beside the file (a job writes nothing
    but its run folder, and loads no pickle)."""
    import lvm_read  # optional extra (.[measurements])

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
    raw = RawFile({}, {})
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


def _read_tdms(path: Path) -> RawFile:
    from nptdms import TdmsFile  # optional extra (.[measurements])

    try:
        tdms = TdmsFile.read(str(path))
        chans = [(f"{g.name}/{c.name}", c) for g in tdms.groups() for c in g.channels()]
        arrays = {name: np.asarray(c[:]) for name, c in chans}
    except Exception as exc:  # noqa: BLE001 - npTDMS raises anything on a malformed file
        raise ValueError(f"{path}: not a readable TDMS file ({type(exc).__name__}: {' '.join(str(exc).split())})"
                         ) from None
    if not chans:
        raise ValueError(f"{path}: not a readable TDMS file (no channel in it)")
    raw = RawFile({}, {})
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


def _read_mat(path: Path) -> RawFile:
    """``scipy.io.loadmat`` (v4–v7.2 files). Numeric vectors are channels (a matrix N × C gives channels
    ``name[j]``); ``t``/``time`` the stamps, ``dt`` or ``fs`` the step, ``units`` (or ``<name>_units``)
    the unit."""
    try:
        mat = scipy.io.loadmat(str(path), squeeze_me=True)
    except Exception as exc:  # noqa: BLE001 - scipy.io raises anything on a malformed file
        raise ValueError(f"{path}: not a readable MATLAB file ({type(exc).__name__}: {' '.join(str(exc).split())};"
                         f" v7.3 files are HDF5: save with -v7)") from None
    vars_ = {k: v for k, v in mat.items() if not k.startswith("__")}
    low = {k.lower(): k for k in vars_}
    raw = RawFile({}, {})
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
