"""Does the model explain the record? The lines and the JSON part a job shows for an estimate's residual
check and drift test (``extra["residual_check"]``, ``extra["drift"]`` of :mod:`methods.pem`; docs/uncertainty.md).
"""

from __future__ import annotations

import numpy as np

__all__ = ["check_lines", "check_json"]


def check_lines(extra: dict) -> list[str]:
    """Terminal lines: the residual's verdict with its numbers, then one line per drifting mode."""
    check = extra.get("residual_check") if isinstance(extra, dict) else None
    if check is None:
        return []
    verdict = ("white: the model explains the record, std is the white-noise one" if check["white"] else
               "NOT white: the model does not explain the record, std is the robust (sandwich) one")
    lines = [f"residual: {verdict} (Ljung-Box p = {check['ljung_box_p']:.2g} on {check['ljung_box_lags']} lags; "
             f"largest line {check['peak_over_floor']:.3g}x the noise floor {check['noise_floor_m_s2']:.3g} m/s² "
             f"at {check['peak_rad_s']:.4g} rad/s, threshold {check['peak_threshold']:.3g}; residual variance "
             f"{check['variance_ratio']:.3g}x the floor"
             + (f"; judged below {check['band_rad_s']:.4g} rad/s, the decimated record's pass band"
                if check.get("band_rad_s") is not None else "") + ")"]
    clip = extra.get("saturation")
    if clip is not None:
        lines.append(f"saturation: the sensor clipped ({clip['clipped_samples']} samples at "
                     + ", ".join(f"{v:.4g}" for v in clip["levels_m_s2"]) + " m/s²); "
                     + (f"fitted from sample {clip['fit_start']}, after the last clipped one" if clip["fit_start"]
                        else "too few samples follow it: fitted as it is, the distortion included"))
    if "robust_std_rad_s" in check:
        robust = np.asarray(check["robust_std_rad_s"])
        lines.append("robust std (rad/s): " + ", ".join(f"{s:.3g}" for s in robust))
    drift = extra.get("drift")
    if drift is not None:
        lines += [f"drift: {note}" for note in drift["notes"]]
        reported = extra.get("drift_reported") or []
        small = [i + 1 for i, kind in enumerate(reported) if kind == "small_amplitude"]
        if small:
            lines.append("drift: the frequency given for mode" + ("s " if len(small) > 1 else " ")
                         + ", ".join(map(str, small)) + " is its small-amplitude one (a → 0, the linear "
                         "structure's); the record's own average and the amplitude it refers to are above")
    return lines


def check_json(extra: dict) -> dict:
    """The ``estimate.json`` entries: ``residual_check`` and ``drift`` (present when the method gives them)."""
    if not isinstance(extra, dict):
        return {}
    return {key: extra[key] for key in ("residual_check", "drift", "drift_reported", "white_noise_std",
                                        "saturation") if extra.get(key) is not None}
