"""experiments.io: checksummed datasets, file-level errors in a user's words, permissions, reproducible bytes."""

import io
import os
import subprocess
import sys
import zipfile

import numpy as np
import pytest

from experiments.io import CHECKSUM_KEY, array_checksum, atomic_write_text, read_npz, save_figure, write_npz

ARRAYS = {"t_s": np.arange(8) * 0.02, "accel_m_s2": np.linspace(0, 1, 16).reshape(2, 8),
          "seed": np.int64(3), "truth_freq_rad_s": np.array([3.23, 20.24])}


@pytest.fixture
def cell(tmp_path):
    return write_npz(tmp_path / "cell.npz", ARRAYS)


def test_a_written_dataset_reads_back_with_its_checksum(cell):
    got = read_npz(cell, required=tuple(ARRAYS))
    assert set(got) == set(ARRAYS) | {CHECKSUM_KEY}
    np.testing.assert_array_equal(got["accel_m_s2"], ARRAYS["accel_m_s2"])
    assert str(got[CHECKSUM_KEY]) == array_checksum(ARRAYS)


def test_the_checksum_changes_with_any_value_dtype_or_shape():
    base = array_checksum(ARRAYS)
    changed = dict(ARRAYS, accel_m_s2=ARRAYS["accel_m_s2"].copy())
    changed["accel_m_s2"][1, 7] += 1e-15
    assert array_checksum(changed) != base
    assert array_checksum(dict(ARRAYS, seed=np.int32(3))) != base
    assert array_checksum(dict(ARRAYS, accel_m_s2=ARRAYS["accel_m_s2"].reshape(4, 4))) != base


def _one_line(exc, *words):
    text = str(exc.value)
    assert "\n" not in text
    for w in words:
        assert w in text, text


def test_a_truncated_dataset_is_refused_naming_the_file(cell):
    data = cell.read_bytes()
    mtime = cell.stat().st_mtime_ns
    cell.write_bytes(data[: len(data) // 2])
    os.utime(cell, ns=(mtime, mtime))                   # same mtime: Snakemake would not notice
    with pytest.raises(ValueError) as exc:
        read_npz(cell)
    _one_line(exc, str(cell), "damaged")


def test_an_edited_dataset_fails_its_checksum(cell, tmp_path):
    # rewrite one array inside the zip, keeping the stored checksum: a valid .npz with other content
    with zipfile.ZipFile(cell) as zf:
        members = {n: zf.read(n) for n in zf.namelist()}
    buf = io.BytesIO()
    np.lib.format.write_array(buf, ARRAYS["accel_m_s2"] * 1.001)
    members["accel_m_s2.npy"] = buf.getvalue()
    with zipfile.ZipFile(cell, "w") as zf:
        for name, data in members.items():
            zf.writestr(name, data)
    with pytest.raises(ValueError) as exc:
        read_npz(cell)
    _one_line(exc, str(cell), "checksum mismatch")


def test_dataset_file_errors_say_what_is_wrong_in_words(tmp_path):
    not_zip = tmp_path / "notes.npz"
    not_zip.write_text("hello")
    with pytest.raises(ValueError) as exc:
        read_npz(not_zip)
    _one_line(exc, str(not_zip), "not a readable dataset file")

    pickled = tmp_path / "objects.npz"
    np.savez(pickled, a=np.array([{"x": 1}], dtype=object))
    with pytest.raises(ValueError) as exc:
        read_npz(pickled)
    _one_line(exc, str(pickled), "pickled")

    plain = tmp_path / "plain.npz"
    np.savez(plain, a=np.arange(3))
    with pytest.raises(ValueError) as exc:
        read_npz(plain)
    _one_line(exc, str(plain), CHECKSUM_KEY)

    partial = write_npz(tmp_path / "partial.npz", {"t_s": np.arange(8.0)})
    with pytest.raises(ValueError) as exc:
        read_npz(partial, required=("t_s", "truth_freq_rad_s"))
    _one_line(exc, str(partial), "missing entry 'truth_freq_rad_s'")


def test_identify_refuses_a_truncated_dataset_in_one_line(cell, tmp_path):
    cell.write_bytes(cell.read_bytes()[:200])
    proc = subprocess.run([sys.executable, "-m", "experiments.jobs.identify", "method=fft",
                           f"data.dataset={cell}", "runlog.enabled=false", f"hydra.run.dir={tmp_path / 'run'}"],
                          capture_output=True, text=True, cwd=tmp_path)
    assert proc.returncode == 2
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: ") and str(cell) in lines[0], proc.stderr


@pytest.mark.parametrize("umask", [0o022, 0o077, 0o002])
def test_written_files_honour_the_umask(tmp_path, umask):
    old = os.umask(umask)
    try:
        path = atomic_write_text(tmp_path / "a.txt", "x")
    finally:
        os.umask(old)
    assert path.stat().st_mode & 0o777 == 0o666 & ~umask


def test_the_same_figure_gives_the_same_svg_and_png_bytes(tmp_path):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    def draw(path):
        fig, ax = plt.subplots()
        ax.semilogy([1, 2, 3], [1, 10, 100], "o-", label="rmse")
        ax.fill_between([1, 2, 3], [0.5, 5, 50], [2, 20, 200], alpha=0.3)   # a clip path: random ids
        ax.legend()
        save_figure(fig, path)
        plt.close(fig)
        return path.read_bytes()

    for suffix in (".svg", ".png"):
        assert draw(tmp_path / f"a{suffix}") == draw(tmp_path / f"b{suffix}")
