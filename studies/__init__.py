"""Sweeps of runs -> one tidy table, a Markdown summary and plots.

* :mod:`studies.runner` — the one sweep runner (local worker processes or Dask), resumable per task;
* :mod:`studies.compare` — the controller comparison (``compare-controllers``);
* :mod:`studies.solver_study`, :mod:`studies.solver_spec`, :mod:`studies.sweepcli` — the solver study
  (``solver-study``): its fixed studies, its sweep axes and its command line.

Imports the science packages and :mod:`sim`; nothing below imports it.
"""
