"""The one place that writes files: every write goes to a temporary file in the target folder, then
``os.replace`` renames it, so a killed job never leaves a half-written file that Snakemake takes for done.
Files get the permissions of an ordinary ``open`` (0666 less the umask), and the same content gives the
same bytes (.npz timestamps, SVG ids and metadata fixed). An .npz carries a checksum of its arrays that
:func:`read_npz` verifies.
"""

from __future__ import annotations

import contextlib
import hashlib
import io
import json
import os
import tempfile
import zipfile
import zlib
from collections.abc import Iterator
from pathlib import Path

import numpy as np

__all__ = ["CHECKSUM_KEY", "atomic_path", "atomic_write_bytes", "atomic_write_text", "write_json", "array_checksum",
           "write_npz", "read_npz", "write_table", "markdown_table", "save_figure"]

# A fixed timestamp inside the .npz zip, so that the same arrays give the same bytes.
_ZIP_EPOCH = (1980, 1, 1, 0, 0, 0)
# The .npz entry holding the SHA-256 of the other arrays (see array_checksum).
CHECKSUM_KEY = "checksum_sha256"


def _umask() -> int:
    mask = os.umask(0)         # the only portable way to read the umask is to set it
    os.umask(mask)
    return mask


@contextlib.contextmanager
def atomic_path(path: str | os.PathLike) -> Iterator[Path]:
    """Yield a temporary path beside ``path``; on success rename it onto ``path``, on error remove it."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    # mkstemp creates the file 0600, and the rename keeps the mode: give it what open() would have.
    os.fchmod(fd, 0o666 & ~_umask())
    os.close(fd)
    tmp = Path(tmp)
    try:
        yield tmp
        os.replace(tmp, path)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise


def atomic_write_bytes(path, data: bytes) -> Path:
    with atomic_path(path) as tmp:
        tmp.write_bytes(data)
    return Path(path)


def atomic_write_text(path, text: str) -> Path:
    return atomic_write_bytes(path, text.encode("utf-8"))


def write_json(path, obj) -> Path:
    return atomic_write_text(path, json.dumps(obj, indent=2, sort_keys=True, default=_json_default) + "\n")


def _json_default(x):
    if isinstance(x, np.ndarray):
        return x.tolist()
    if isinstance(x, np.generic):
        return x.item()
    raise TypeError(f"cannot write {type(x).__name__} to JSON")


def array_checksum(arrays: dict[str, np.ndarray]) -> str:
    """SHA-256 over the arrays in key order: each key, dtype, shape and C-order bytes (``CHECKSUM_KEY`` left
    out). Independent of the zip container, so it checks what a reader gets, not how it was packed."""
    h = hashlib.sha256()
    for key in sorted(k for k in arrays if k != CHECKSUM_KEY):
        a = np.ascontiguousarray(arrays[key])
        h.update(f"{key}\0{a.dtype.str}\0{a.shape}\0".encode())
        h.update(a.tobytes())
    return h.hexdigest()


def write_npz(path, arrays: dict[str, np.ndarray]) -> Path:
    """A ``numpy.load``-able .npz whose bytes depend only on the arrays (fixed zip timestamps, sorted keys),
    with the arrays' checksum in the entry ``checksum_sha256``."""
    arrays = {k: np.asanyarray(v) for k, v in arrays.items() if k != CHECKSUM_KEY}
    arrays[CHECKSUM_KEY] = np.array(array_checksum(arrays))
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w", compression=zipfile.ZIP_DEFLATED) as zf:
        for key in sorted(arrays):
            arr = io.BytesIO()
            np.lib.format.write_array(arr, arrays[key], allow_pickle=False)
            info = zipfile.ZipInfo(f"{key}.npy", date_time=_ZIP_EPOCH)
            info.compress_type = zipfile.ZIP_DEFLATED
            info.external_attr = 0o644 << 16
            zf.writestr(info, arr.getvalue())
    return atomic_write_bytes(path, buf.getvalue())


def read_npz(path, required: tuple[str, ...] = ()) -> dict[str, np.ndarray]:
    """Read an .npz written by :func:`write_npz` into a dict of arrays (scalars as 0-d arrays), no pickle.

    The checksum is verified and every key of ``required`` must be present; otherwise ``ValueError`` with
    one sentence naming the file and what is wrong with it.
    """
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"dataset file {path} does not exist")
    damaged = f"{path}: not a readable dataset file: it is damaged, truncated or not an .npz"
    if not zipfile.is_zipfile(path):         # np.load would take it for a pickle and say so
        raise ValueError(damaged)
    try:
        with np.load(path, allow_pickle=False) as f:
            arrays = {k: f[k] for k in f.files}
    except (zipfile.BadZipFile, EOFError, zlib.error, OSError) as exc:
        raise ValueError(f"{damaged} ({' '.join(str(exc).split())})") from None
    except ValueError as exc:
        if "object" in str(exc).lower() or "pickle" in str(exc).lower():
            raise ValueError(f"{path}: holds Python objects (pickled data), which are not loaded for "
                             f"safety; a dataset holds plain numeric arrays") from None
        raise ValueError(f"{damaged} ({' '.join(str(exc).split())})") from None
    if CHECKSUM_KEY not in arrays:
        raise ValueError(f"{path}: has no '{CHECKSUM_KEY}' entry, so its content cannot be verified; "
                         f"write datasets with experiments.jobs.make_dataset")
    if str(arrays[CHECKSUM_KEY]) != array_checksum(arrays):
        raise ValueError(f"{path}: checksum mismatch: the file was changed or damaged after it was "
                         f"written; regenerate it")
    missing = [k for k in required if k not in arrays]
    if missing:
        raise ValueError(f"{path}: not a dataset cell: missing entr{'y' if len(missing) == 1 else 'ies'} "
                         f"{', '.join(repr(k) for k in missing)}")
    return arrays


def write_table(df, stem) -> list[Path]:
    """Write a pandas table as ``<stem>.csv`` and ``<stem>.md`` (a GitHub Markdown table)."""
    stem = Path(stem)
    csv = atomic_write_text(stem.with_suffix(".csv"), df.to_csv(index=False, lineterminator="\n"))
    md = atomic_write_text(stem.with_suffix(".md"), markdown_table(df) + "\n")
    return [csv, md]


def markdown_table(df, floatfmt: str = ".4g") -> str:
    """A Markdown table of a DataFrame (written here so no optional ``tabulate`` dependency is needed)."""
    def cell(v):
        if isinstance(v, float | np.floating):
            return "" if np.isnan(v) else format(float(v), floatfmt)
        return str(v)
    head = "| " + " | ".join(map(str, df.columns)) + " |"
    rule = "|" + "|".join("---" for _ in df.columns) + "|"
    rows = ["| " + " | ".join(cell(v) for v in row) + " |" for row in df.itertuples(index=False)]
    return "\n".join([head, rule, *rows])


def save_figure(fig, path, tight: bool = True, png_compression: int = 6) -> Path:
    """Save a matplotlib figure atomically; the format follows the suffix (.png at 150 dpi, .svg, .pdf).

    Identical figures give identical bytes: no date or software version in the metadata, and SVG element
    ids from a fixed hash salt (matplotlib's ``svg.hashsalt``) instead of random ones. ``tight``: crop to
    what is drawn (``bbox_inches="tight"``, an extra layout pass per file; a figure with fixed margins can do
    without); ``png_compression``: zlib's level for a PNG (6, PIL's default; 1 is faster, a larger file).
    """
    import matplotlib  # ~0.5 s: not paid by the jobs that never draw

    path = Path(path)
    fmt = path.suffix.lstrip(".")
    metadata = {"svg": {"Date": None, "Creator": None}, "pdf": {"CreationDate": None, "Producer": None,
                "Creator": None}, "png": {"Software": None}}.get(fmt)
    with atomic_path(path) as tmp, matplotlib.rc_context({"svg.hashsalt": "spacecraft-modal-id"}):
        fig.savefig(tmp, format=fmt, dpi=150, bbox_inches="tight" if tight else None, metadata=metadata,
                    **({"pil_kwargs": {"compress_level": png_compression}} if fmt == "png" else {}))
    return path


# Folders an output path may nest (Python's recursive mkdir stops near 1000; no sensible path comes close).
MAX_DEPTH = 200


def check_writable(path: str | os.PathLike, what: str) -> None:
    """Raise ``ValueError`` (one line) when files cannot be written at or under ``path``: the nearest folder
    that exists on the way is a file, or this process may not write there (read-only folder or file
    system). Called before any work, so that a job refused for it leaves nothing behind."""
    target = Path(path).absolute()
    name_max = os.pathconf("/", "PC_NAME_MAX") if hasattr(os, "pathconf") else 255
    path_max = os.pathconf("/", "PC_PATH_MAX") if hasattr(os, "pathconf") else 4096
    if len(os.fsencode(target)) >= path_max or any(len(os.fsencode(p)) > name_max for p in target.parts):
        raise ValueError(f"{what} {str(path)[:60]}...: too long a path for this file system (at most {name_max} "
                         f"bytes a name, {path_max} in all); choose a shorter path")
    if len(target.parts) > MAX_DEPTH:
        raise ValueError(f"{what} {str(path)[:60]}...: {len(target.parts)} folders deep (at most {MAX_DEPTH}); "
                         f"choose a shorter path")
    here = target
    while not here.exists():
        here = here.parent
    if not here.is_dir():
        raise ValueError(f"{what} {path}: {here} is a file, not a folder; choose another path")
    if not os.access(here, os.W_OK | os.X_OK):
        raise ValueError(f"{what} {path}: cannot write in {here} (read-only or no permission); choose a "
                         f"writable path")
