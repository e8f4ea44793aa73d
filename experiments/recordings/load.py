"""A user's measurement file as a job reads it: the record of one channel and the segment to work on.

Both jobs on a user's file read it here (docs/measurements.md): the identify job
(:mod:`experiments.jobs.identify`, the free decay after the largest impulse) and the track job
(:mod:`experiments.jobs.track_file`, the whole record). The file is read once per process and version of the
file: a job's pre-check and its task both ask for it.
"""

from __future__ import annotations

import functools
import os
from pathlib import Path

from experiments.recordings.formats import INSTALL_HINT
from experiments.recordings.read import Record, read_record
from experiments.recordings.segment import Segment, choose_segment

__all__ = ["load_segment"]


def load_segment(data, cover_hz: float = 0.0, *, whole_record: bool = False) -> tuple[Record, Segment]:
    """The record of the file ``data.path`` and the segment of it to identify or track.

    Parameters
    ----------
    data : DataConfig
        The job's ``data`` config (:class:`experiments.config_schema.DataConfig`): ``path``, ``channel``,
        ``units``, ``dt``, ``start_s``, ``stop_s``, ``band_hz``.
    cover_hz : float
        The band must reach this frequency, Hz (the prior's highest mode with a margin; 0: from the spectrum).
    whole_record : bool
        Without ``data.start_s``: the segment starts at the record's first sample (a tracked record), instead
        of the free decay after the largest impulse (an identified one).

    ``ValueError`` (one line naming the file) for a file that cannot be read, or whose format needs a package
    that is not installed (with the command that installs it).
    """
    path = Path(data.path)
    band = data.band_hz
    band = band if isinstance(band, str | int | float) or band is None else tuple(band)
    stamp = os.stat(path).st_mtime_ns if path.is_file() else None
    return _load(str(path), stamp, data.channel, data.units, data.dt, data.start_s, data.stop_s, band, cover_hz,
                 whole_record)


@functools.lru_cache(maxsize=4)
def _load(path, _stamp, channel, units, dt, start_s, stop_s, band_hz, cover_hz, whole_record):
    try:
        rec = read_record(path, channel=channel, units=units, dt=dt)
    except ModuleNotFoundError as exc:
        raise ValueError(f"{path}: reading this format needs the package '{exc.name}': {INSTALL_HINT}") from None
    from_start = whole_record and start_s is None     # no impulse is looked for: the span starts at the record's
    seg = choose_segment(rec.accel_m_s2, rec.dt_s, rec.t0_s, start_s=rec.t0_s if from_start else start_s,
                         stop_s=stop_s, band_hz=list(band_hz) if isinstance(band_hz, tuple) else band_hz,
                         cover_hz=cover_hz, where=path)
    if from_start:
        seg.notes[0] = seg.notes[0].replace("(data.start_s)", "(the record's start; set data.start_s= to choose)")
    return rec, seg
