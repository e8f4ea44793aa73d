"""MLflow run logging (``runlog``): the store (``store``), the runs of the identify and tracking grids
(``identify_runs``, ``tracker_runs``), a job's run logged after it (``pending``) and the records they log
(``records``). Switched by the config key ``runlog.enabled``; run by the rules ``runlog`` and
``tracking_runlog``. "tracking" in this project means frequency tracking only (``methods.track``)."""

__all__ = []
