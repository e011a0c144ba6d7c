"""
Compare controllers with robot loss
===================================

Is the paper's mean-field feedback worth its planner?  ``compare-controllers`` runs every
combination of controllers, fields, seeds, robot losses and swarm sizes through one sweep runner
and writes a tidy table (``runs.csv``: one row per run and measurement), a Markdown summary and
plots.  Here 30 % of the robots stop for good at :math:`t = T` (they neither move nor measure, and
the density estimate no longer sees them), and three strategies are compared:

* ``feedback`` -- the paper's method: planner + mean-field feedback;
* ``lawnmower`` -- fixed strips assigned at the start, swept back and forth;
* ``greedy`` -- every robot drives to the highest GP variance nearby.

The sweep is tiny (10 m x 10 m, 30 robots, two seeds, two periods, one worker process); the
command below is the same call from a shell.  The documentation's *Results* pages show the full
comparison, including where the paper's method loses.

.. code-block:: bash

    compare-controllers --controllers feedback lawnmower greedy --robot-loss 0.3 --seeds 0 1 \\
        --max-periods 2 --config small.toml --workers 1 --out compare
"""
import csv
import tempfile
from collections import defaultdict
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np

from swarmfield.studies import compare

work = Path(tempfile.mkdtemp())
(work / "small.toml").write_text("""
[sim]
domain = [0.0, 10.0, 0.0, 10.0]
start_box = [0.0, 4.0, 0.0, 4.0]
robots = 30
substeps = 4
gamma = 0.12
metrics_every = 2        # the GP posterior every second measurement (and at every period end)

[planner]
nx = 20
ny = 20
n_intervals = 6
n_modes_x = 4
n_modes_y = 4
""")

code = compare.main(["--controllers", "feedback", "lawnmower", "greedy", "--fields", "plumes",
                     "--robot-loss", "0.3", "--seeds", "0", "1", "--max-periods", "2",
                     "--config", str(work / "small.toml"), "--workers", "1", "--quiet",
                     "--out", str(work / "compare")])
print("exit code", code)
print((work / "compare" / "summary.md").read_text())

# %%
# ``runs.csv`` is tidy, so any plot is a few lines: the median over the seeds of the RMSE of the
# estimate and of :math:`\sup_x V`, against time in periods :math:`T`.  The vertical line is the
# loss.

with open(work / "compare" / "runs.csv", newline="") as fh:
    rows = list(csv.DictReader(fh))
curves = defaultdict(lambda: defaultdict(list))        # controller -> t/T -> values over seeds
for r in rows:
    curves[r["controller"]][float(r["t_T"])].append((float(r["rmse"]), float(r["max_variance"])))

fig, (a1, a2) = plt.subplots(1, 2, figsize=(11, 3.6), constrained_layout=True)
for name, by_t in curves.items():
    ts = sorted(by_t)
    med = np.array([np.median(by_t[t], axis=0) for t in ts])
    a1.plot(ts, med[:, 0], label=name)
    a2.plot(ts, med[:, 1], label=name)
for ax in (a1, a2):
    ax.axvline(1.0, color="grey", ls=":", label="30 % lost")
    ax.set_xlabel("t / T")
a1.set(ylabel="RMSE of the estimate", title="estimation error (median of 2 seeds)")
a2.set(ylabel=r"$\sup\,V$", title="largest posterior variance")
a2.axhline(0.12, color="k", ls="--", lw=0.8, label=r"$\gamma$")
a1.legend()
a2.legend()
