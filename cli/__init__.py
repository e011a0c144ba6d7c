"""Command-line entry points: ``plan-reference`` and ``simulate-swarm`` (``compare-controllers`` and
``solver-study`` have their ``main`` in :mod:`studies`).  Nothing imports this package."""
