"""
A solver-study sweep
====================

How do grid size and solver change the planner's cost and its optimum?  ``solver-study`` solves the
paper's first planning step (robots released on :math:`[0, 7]^2`, target from the GP variance of
their first measurements) for every combination of the axes it is given -- here three grids and
the two solvers: IPOPT on the CasADi problem (the default) and the paper's generalised reduced
gradient (GRG) -- and writes ``study.csv`` (one row per run), ``study.md`` and two plots.

``--quick`` starts from a small problem (N = 4 intervals, 3 x 3 modes) so that every solve takes a
fraction of a second; the axes given on the command line override it.  Same call from a shell:

.. code-block:: bash

    solver-study --grid 12 16 24 --solver ipopt grg --quick --workers 1 --out study

Without ``--quick`` and axes, ``solver-study`` runs the paper-size studies behind the *Results*
pages (minutes).
"""
import csv
import tempfile
from pathlib import Path

import matplotlib.pyplot as plt

from swarmfield.studies import solver_study

out = Path(tempfile.mkdtemp()) / "study"
code = solver_study.main(["--grid", "12", "16", "24", "--solver", "ipopt", "grg", "--quick",
                          "--workers", "1", "--out", str(out)])
print("exit code", code)
with open(out / "study.csv", newline="") as fh:
    rows = list(csv.DictReader(fh))
for r in rows:
    print(f"{r['method']:5s} {r['nx']:>3s} x {r['ny']:<3s} {r['status']:28s} {int(r['iterations']):3d} it. "
          f"{float(r['solve_s']):6.3f} s  J = {float(r['objective']):.5f}")

# %%
# Both solvers reach the same optimum on every grid (GRG stops on its projected-gradient test,
# IPOPT at its acceptable level, so the last digits differ); the optimum itself changes with the
# grid, because a finer grid is a different discrete problem with less numerical diffusion.
# Solve times of this tiny problem are dominated by fixed costs and by whatever else the machine
# is doing; the *Results* pages show the paper-size numbers.

fig, (a1, a2) = plt.subplots(1, 2, figsize=(10, 3.6), constrained_layout=True)
for method, marker in (("ipopt", "o"), ("grg", "s")):
    sel = [r for r in rows if r["method"] == method]
    cells = [int(r["nx"]) * int(r["ny"]) for r in sel]
    a1.plot(cells, [float(r["solve_s"]) for r in sel], marker=marker, label=method)
    a2.plot(cells, [float(r["objective"]) for r in sel], marker=marker, label=method)
a1.set(xlabel="cells", ylabel="solve time [s]", title="solve time")
a2.set(xlabel="cells", ylabel="objective J", title="optimum")
a1.legend()
a2.legend()
