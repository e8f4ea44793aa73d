"""A user's own measurement: a CSV with columns ``t`` (s) and ``accel`` (m/s²), uniformly sampled."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from experiments.simulate.datasets import MIN_SAMPLES
from methods.estimate import MAX_ABS_ACCEL_M_S2

__all__ = ["REQUIRED", "load_csv"]

REQUIRED = ("t", "accel")


def load_csv(path) -> tuple[np.ndarray, float]:
    """Return (accel, dt) from a CSV; raise ``ValueError`` naming the offending row (1 = first data row).

    Time stamps must increase with a constant step (relative jitter below 1e-6 of the step).
    """
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"measurement file {path} does not exist")
    values = _read_numeric(path)
    if values is None:                  # some field is not a plain number: find it and say where
        values = _read_text(path)
    t, accel = values["t"], values["accel"]
    big = np.flatnonzero(np.abs(accel) > MAX_ABS_ACCEL_M_S2)
    if big.size:
        r = int(big[0])
        raise ValueError(f"{path}: row {r + 1}: accel = {accel[r]:g} m/s² is not a physical acceleration "
                         f"(|accel| ≤ {MAX_ABS_ACCEL_M_S2:g} m/s², 1e5 g); check the units")
    if t.size < MIN_SAMPLES:
        raise ValueError(f"{path}: {t.size} samples; at least {MIN_SAMPLES} are needed")
    step = np.diff(t)
    if np.any(step <= 0):
        r = int(np.flatnonzero(step <= 0)[0]) + 1
        raise ValueError(f"{path}: row {r + 1}: t = {t[r]} does not increase (previous row t = {t[r - 1]})")
    dt = float(np.median(step))
    jitter = np.abs(step - dt) > 1e-6 * dt
    if np.any(jitter):
        r = int(np.flatnonzero(jitter)[0]) + 1
        raise ValueError(f"{path}: row {r + 1}: t = {t[r]} breaks the uniform sampling "
                         f"(step {step[r - 1]:g} s, expected {dt:g} s)")
    return accel, dt


def _read_numeric(path: Path) -> dict[str, np.ndarray] | None:
    """The columns t and accel parsed straight to floats by pandas' C parser (10⁶ rows in about a second),
    or None when a field is not a finite number (then :func:`_read_text` finds and names it).

    pandas' parser gives every value as the float nearest its decimal text, as ``float()`` does (checked in
    tests/experiments/jobs/test_measurements.py); ``keep_default_na=False``: an empty field or "NA" is an
    error, not a silent NaN.
    """
    try:
        df = pd.read_csv(path, dtype=float, keep_default_na=False, skipinitialspace=True)
    except (ValueError, pd.errors.ParserError, pd.errors.EmptyDataError, UnicodeDecodeError):
        return None
    df.columns = [str(c).strip() for c in df.columns]
    if any(col not in df.columns for col in REQUIRED) or len(set(df.columns)) != len(df.columns):
        return None
    values = {col: df[col].to_numpy(dtype=float) for col in REQUIRED}
    if not all(np.isfinite(v).all() for v in values.values()):
        return None
    return values


def _read_text(path: Path) -> dict[str, np.ndarray]:
    """The columns as text, each field checked: ``ValueError`` naming the first row that is not a number."""
    try:
        df = pd.read_csv(path, dtype=str, keep_default_na=False, skipinitialspace=True)
    except (pd.errors.ParserError, pd.errors.EmptyDataError, UnicodeDecodeError) as exc:
        raise ValueError(f"{path}: not a readable CSV ({exc})") from None
    df.columns = [str(c).strip() for c in df.columns]
    for col in REQUIRED:
        if col not in df.columns:
            raise ValueError(f"{path}: missing column '{col}' (found: {', '.join(df.columns) or 'none'}); "
                             f"columns t (s) and accel (m/s²) are required")
    values = {}
    for col in REQUIRED:
        num = pd.to_numeric(df[col], errors="coerce").to_numpy(dtype=float)
        bad = np.flatnonzero(~np.isfinite(num))
        if bad.size:
            r = int(bad[0])
            raise ValueError(f"{path}: row {r + 1}: {col} = '{df[col].iloc[r]}' is not a finite number")
        values[col] = num
    return values
