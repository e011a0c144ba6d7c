"""One planning step under planner.speed_limit l1 and face (README "Beyond the paper"): python scripts/speed_limit_step.py NX MODES N_INTERVALS."""
import sys, time, numpy as np
from swarmfield.ocp import ReferencePlanner, PlannerSettings
from swarmfield.ocp.basis import velocity_on_grid
nx = int(sys.argv[1]); I = int(sys.argv[2]); N=int(sys.argv[3])
for lim in ("l1", "face"):
    s = PlannerSettings(nx=nx, ny=nx, n_modes_x=I, n_modes_y=I, n_intervals=N, speed_limit=lim)
    pl = ReferencePlanner(s)
    g = pl.grid
    X, Y = np.meshgrid(g.xc, g.yc, indexing="ij")
    p0 = np.exp(-((X-3.5)**2 + (Y-3.5)**2)/4); pf = np.exp(-((X-15)**2+(Y-15)**2)/20)
    t = time.perf_counter(); plan = pl.solve(p0, pf); w = time.perf_counter()-t
    xs = np.linspace(0, 20, 4*nx+1)
    sup = max(np.hypot(*velocity_on_grid(c, g.domain, xs, xs)).max() for c in plan.coef)
    print(lim, "substeps", plan.meta["substeps"], "obj %.4f" % plan.meta["objective"], "sup|v| fine %.3f" % sup,
          "solve %.1fs" % w, plan.meta["solver"].get("status"), plan.meta["solver"].get("iterations"), "KLend %.4f" % plan.meta["symmetric_kl_final"])
