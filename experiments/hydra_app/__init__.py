"""What every Hydra app of the pipeline (the jobs, tuning) shares before its task runs.

- :mod:`~experiments.hydra_app.command_line`: the command line composed and checked before Hydra starts, so
  that bad input is one line ``error: ...``, exit status 2 and nothing written (``run_app``, ``fail``);
- :mod:`~experiments.hydra_app.config_store`: the structured-config schemas an app stores in Hydra's
  ConfigStore (``register``), with only the methods its command line names imported.

It sits between the stages the jobs read (io, simulate, report, runlog) and the jobs themselves.
"""

__all__ = []
