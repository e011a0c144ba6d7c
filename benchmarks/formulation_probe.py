"""Probe one formulation at the paper size: build time, NLP size, the first IPOPT iterations with
IPOPT's timing statistics and the peak RSS (docs/results/formulations.md).

    python benchmarks/formulation_probe.py GRID FORMULATION MAX_ITER [MUMPS_MEM_PERCENT [HESSIAN]]

HESSIAN: auto (default), exact or limited-memory (``formulation_hessian``).  MUMPS_MEM_PERCENT defaults to
the formulation's own choice (100 for multiple shooting / direct transcription).
"""
import sys, time, resource
from swarmfield.ocp.settings import PlannerSettings, IpoptSettings
from swarmfield.ocp.planner import ReferencePlanner
from swarmfield.ocp.grid import Grid
from swarmfield.sim.scenario import box_density, first_step_target
n=int(sys.argv[1]); form=sys.argv[2]; it=int(sys.argv[3])
extra={'print_timing_statistics':'yes'}
if len(sys.argv)>4: extra['mumps_mem_percent']=int(sys.argv[4])
hess=sys.argv[5] if len(sys.argv)>5 else 'auto'
s=PlannerSettings(nx=n,ny=n, formulation=form, formulation_hessian=hess, accept_feasible_iterate=False, ipopt=IpoptSettings(max_iter=it, print_level=5, extra=extra)); g=Grid(s.domain,n,n)
p0=box_density(g); tg,_=first_step_target(g)
t=time.time(); c=time.process_time(); pl=ReferencePlanner(s); print('build wall %.1f cpu %.1f'%(time.time()-t, time.process_time()-c), flush=True)
t=time.time(); c=time.process_time(); print(pl.formulation.sizes(pl.solver)); print('sizes wall %.1f cpu %.1f'%(time.time()-t, time.process_time()-c), flush=True)
t=time.time(); c=time.process_time()
try:
    pl.solve(p0,tg)
except Exception as e: print(type(e).__name__, e)
print('solve wall %.1f cpu %.1f'%(time.time()-t, time.process_time()-c), 'maxrss MB', resource.getrusage(resource.RUSAGE_SELF).ru_maxrss//1024, flush=True)
