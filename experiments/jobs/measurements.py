"""A user's own measurement: a CSV with columns ``t`` (s) and ``accel`` (m/s²), uniformly sampled."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from experiments.simulate.datasets import MIN_SAMPLES

REQUIRED = ("t", "accel")


def load_csv(path) -> tuple[np.ndarray, float]:
    """Return (accel, dt) from a CSV; raise ``ValueError`` naming the offending row (1 = first data row).

    Time stamps must increase with a constant step (relative jitter below 1e-6 of the step).
    """
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"measurement file {path} does not exist")
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
    t, accel = values["t"], values["accel"]
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
