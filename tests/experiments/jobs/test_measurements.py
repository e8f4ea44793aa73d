import pytest

from experiments.jobs.measurements import load_csv


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
    ("time,accel\n" + rows(), "missing column 't'"),
    ("t,acc\n" + rows(), "missing column 'accel'"),
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
