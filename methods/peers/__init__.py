"""The field's established identifiers as thin adapters with the project's one face (not in the paper).

Each module wraps a maintained library (the optional extra ``.[peers]``) and is registered by name:
:mod:`~methods.peers.era` (python-control), :mod:`~methods.peers.n4sid` (nfoursid),
:mod:`~methods.peers.ssi_cov` and :mod:`~methods.peers.ssi_data` (strid), :mod:`~methods.peers.lsce`
(sdypy-ema), :mod:`~methods.peers.hdmd` and :mod:`~methods.peers.bopdmd` (pydmd). What every adapter needs
afterwards, picking the m physical modes out of a model's poles and matching them to the prior, is written
once in ``_mode_picker``. See methods/peers/README.md.

>>> import numpy as np
>>> from methods.peers import era
>>> t = 0.02 * np.arange(256)
>>> y = np.cos(20.3 * t) * np.exp(-0.1 * t) + np.cos(56.7 * t) * np.exp(-0.3 * t)
>>> np.round(era.identify(y, 0.02, [18.0, 52.0]).frequencies, 2).tolist()
[20.3, 56.7]
"""

from methods.peers import bopdmd, era, hdmd, lsce, n4sid, ssi_cov, ssi_data

__all__ = ["bopdmd", "era", "hdmd", "lsce", "n4sid", "ssi_cov", "ssi_data"]
