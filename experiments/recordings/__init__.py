"""A practitioner's own measurement: read it, choose the free decay, bring it to a useful band.

The lowest stage of the pipeline beside :mod:`experiments.io` (it imports nothing from the later stages):

- :mod:`~experiments.recordings.read`: the record of one channel, in m/s², with its sampling step (channel,
  units and time checked once, one line naming the file and the problem), from the reader of its format
  (:mod:`~experiments.recordings.formats`, chosen by extension: CSV, UFF 58, LabVIEW .lvm and .tdms,
  MATLAB .mat, each from a maintained library);
- :mod:`~experiments.recordings.segment`: the free decay after the largest impulse (or the span asked
  for) and the decimation to the band of interest with an anti-alias filter
  (:mod:`~experiments.recordings.spectral`: scipy.signal's filter and Welch estimate, in numpy);
- :mod:`~experiments.recordings.modal_fit`: the identified modes' amplitudes, model and residual;
- :mod:`~experiments.recordings.load`: the record and segment a job on a user's file works on (read once);
- :mod:`~experiments.recordings.modes_found`: the modes of a segment without a prior, from a stabilisation
  diagram (:mod:`methods.peers.stabilisation`).

See docs/measurements.md.
"""

from experiments.recordings.read import FORMATS, Record, read_record
from experiments.recordings.segment import Segment, choose_segment

__all__ = ["FORMATS", "Record", "Segment", "choose_segment", "read_record"]
