"""Physical constants the experiments share, each written once (the ground floor: imports nothing).

``methods/`` imports nothing from ``experiments/``, so the methods' own input rule keeps its copy of the
acceleration bound (:data:`methods.estimate.MAX_ABS_ACCEL_M_S2`); tests/experiments/test_units.py checks that
the two agree.
"""

from __future__ import annotations

__all__ = ["G_M_S2", "MAX_ABS_ACCEL_M_S2"]

G_M_S2 = 9.80665                 # standard gravity, m/s² per g
# Largest |acceleration| a record may hold, m/s²: ±10⁵ g, the range of the largest shock accelerometers. A
# record beyond it is a units or parsing error (the reader refuses it); a cell whose noise alone exceeds it
# is refused (experiments.simulate.datasets).
MAX_ABS_ACCEL_M_S2 = 1e6
