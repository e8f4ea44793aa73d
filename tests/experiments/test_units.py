"""The constants of experiments/units.py against independent values, and the copy methods/ keeps."""

from experiments import units
from experiments.recordings import read
from experiments.simulate import datasets
from methods import estimate


def test_standard_gravity_is_the_cgpm_value():
    assert units.G_M_S2 == 9.80665          # 3rd CGPM (1901), exact by definition
    assert datasets.G0 == read.G_M_S2 == units.G_M_S2


def test_the_methods_and_the_records_refuse_the_same_accelerations():
    """methods/ imports nothing from experiments/: its input rule keeps its own bound, which must agree."""
    assert estimate.MAX_ABS_ACCEL_M_S2 == units.MAX_ABS_ACCEL_M_S2
    assert abs(units.MAX_ABS_ACCEL_M_S2 / (1e5 * units.G_M_S2) - 1) < 0.02     # ±10⁵ g, rounded
    assert read.MAX_ABS_ACCEL_M_S2 == units.MAX_ABS_ACCEL_M_S2
