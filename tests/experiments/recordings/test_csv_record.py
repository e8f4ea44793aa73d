import pytest

from experiments.recordings import read_record


def load_csv(path):
    """(accel in m/s², dt) of a CSV's single acceleration channel, the whole record (no segmentation)."""
    rec = read_record(path)
    return rec.accel_m_s2, rec.dt_s


def write(tmp_path, text):
    p = tmp_path / "m.csv"
    p.write_text(text)
    return p


def rows(n=10, dt=0.02, start=0):
    return "".join(f"{(start + k) * dt:.6f},{0.1 * k}\n" for k in range(n))


def test_reads_uniform_record(tmp_path):
    accel, dt = load_csv(write(tmp_path, "t,accel\n" + rows()))
    assert dt == pytest.approx(0.02)
    assert accel.size == 10


@pytest.mark.parametrize("text, message", [
    ("accel\n" + "".join(f"{0.1 * k}\n" for k in range(10)), "no time column or sample interval; give data.dt="),
    ("t,acc\n" + rows(), "names no unit for channel 'acc'; give data.units="),
    ("t,accel\n" + rows(3) + "0.06,abc\n" + rows(6, start=4), r"row 4: accel = 'abc' is not a finite number"),
    ("t,accel\n" + rows(3) + "0.06,nan\n" + rows(6, start=4), r"row 4: accel = 'nan'"),
    ("t,accel\n" + rows(3) + "0.05,1\n" + rows(6, start=4), r"row 4: t = 0.05 breaks the uniform sampling"),
    ("t,accel\n" + rows(3) + "0.03,1\n" + rows(6, start=4), r"row 4: t = 0.03 does not increase"),
    ("t,accel\n" + rows(3) + "0.04,1\n" + rows(6, start=4), r"row 4: t = 0.04 does not increase"),
    ("t,accel\n" + rows(5), "5 samples; at least 8"),
])
def test_bad_csv_names_the_row(tmp_path, text, message):
    with pytest.raises(ValueError, match=message):
        load_csv(write(tmp_path, text))


def test_fast_reader_gives_the_float_nearest_each_decimal(tmp_path):
    """The numeric fast path must read every value exactly as float() reads its text."""
    import numpy as np

    rng = np.random.default_rng(2)
    values = (rng.standard_normal(5000) * 10.0 ** rng.integers(-9, 5, 5000)).tolist()
    text = "t,accel\n" + "".join(f"{0.02 * k:.2f},{v!r}\n" for k, v in enumerate(values))
    accel, dt = load_csv(write(tmp_path, text))
    assert accel.tolist() == values
    assert dt == pytest.approx(0.02)


def test_non_physical_acceleration_names_the_row(tmp_path):
    with pytest.raises(ValueError, match=r"row 4: accel = 1e\+300 m/s² is not a physical acceleration"):
        load_csv(write(tmp_path, "t,accel\n" + rows(3) + "0.06,1e300\n" + rows(6, start=4)))
