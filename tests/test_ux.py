"""Issue 17: what a newcomer meets -- --version, python -m swarmfield, plain help, figures with content,
thread limits that the environment overrides."""
import argparse
import copy
import json
import os
import pickle
import subprocess
import sys

import numpy as np
import pytest

COMMANDS = {
    "plan-reference": "swarmfield.cli.plan_reference",
    "simulate-swarm": "swarmfield.cli.simulate_swarm",
    "compare-controllers": "swarmfield.studies.compare",
    "solver-study": "swarmfield.studies.solver_study",
}


# ----------------------------------------------------------------------------------- commands
@pytest.mark.parametrize("prog", COMMANDS)
def test_version_on_every_command(prog, capsys):
    import importlib
    import swarmfield
    with pytest.raises(SystemExit) as info:
        importlib.import_module(COMMANDS[prog]).main(["--version"])
    assert info.value.code == 0
    assert capsys.readouterr().out.strip() == f"{prog} swarmfield {swarmfield.__version__}"


def test_python_m_swarmfield_lists_the_commands_and_loads_nothing_heavy():
    code = ("import runpy, sys; sys.argv = ['swarmfield']\n"
            "try:\n    runpy.run_module('swarmfield', run_name='__main__')\nexcept SystemExit as e:\n    rc = e.code\n"
            "heavy = sorted(m for m in sys.modules if m.split('.')[0] in ('numpy', 'scipy', 'casadi', 'matplotlib'))\n"
            "print('HEAVY', heavy, rc)")
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
    lines = proc.stdout.splitlines()
    assert lines[-1] == "HEAVY [] 0", proc.stdout + proc.stderr
    listed = [line.split()[0] for line in lines if line.startswith("  ")]
    assert listed == list(COMMANDS)
    assert all(len(line.split(None, 1)[1]) > 20 for line in lines if line.startswith("  "))   # a line each
    assert "--help" in proc.stdout


def test_python_m_swarmfield_runs_a_command_and_rejects_unknown_ones(capsys):
    from swarmfield.__main__ import main
    with pytest.raises(SystemExit) as info:
        main(["compare-controllers", "--version"])
    assert info.value.code == 0 and capsys.readouterr().out.startswith("compare-controllers swarmfield ")
    assert main(["simulate-swarms"]) == 2
    assert "unknown command 'simulate-swarms'" in capsys.readouterr().err


def _parsers():
    from swarmfield.cli import plan_reference, simulate_swarm
    from swarmfield.studies import compare
    return {"plan-reference": plan_reference.build_parser(), "simulate-swarm": simulate_swarm.build_parser(),
            "compare-controllers": compare.build_parser()}


@pytest.mark.parametrize("prog", ["plan-reference", "simulate-swarm", "compare-controllers"])
def test_help_is_plain_text_with_each_default_stated_once(prog):
    parser = _parsers()[prog]
    text = parser.format_help()
    assert "``" not in text and ":mod:" not in text and ":func:" not in text
    formatter = parser._get_formatter()
    helped = 0
    for action in parser._actions:
        if action.help in (None, argparse.SUPPRESS):
            continue
        line = formatter._get_help_string(action) % {"default": action.default}
        assert line.count("(default") <= 1, line
        helped += 1
        # an option with a default to show states it (by hand or by the formatter)
        if action.default not in (None, False, argparse.SUPPRESS) and action.option_strings[0] not in ("-h",):
            assert "(default" in line, line
    assert helped >= 10


def test_solver_study_has_one_documented_way_to_run_the_fixed_studies(capsys):
    from swarmfield.studies.solver_study import main
    with pytest.raises(SystemExit):
        main(["--help"])
    text = capsys.readouterr().out
    assert "--preset" in text and "--study" not in text and "``" not in text
    assert main(["--study", "hessian", "--preset", "ipopt", "--quick"]) == 2
    assert "--study is the old name of --preset" in capsys.readouterr().err


# ----------------------------------------------------------------------------------- threads
def _pool_threads(_task=None):
    from threadpoolctl import threadpool_info
    return [{"threads": [p["num_threads"] for p in threadpool_info() if p["user_api"] == "blas"],
             "env": os.environ.get("OPENBLAS_NUM_THREADS")}]


def test_limit_threads_sets_one_and_the_environment_wins(monkeypatch):
    pytest.importorskip("threadpoolctl")
    import numpy  # noqa: F401 -- a BLAS must be loaded for threadpoolctl to see it
    from swarmfield.runtime import threads
    for var in threads.ENV_VARS:
        monkeypatch.delenv(var, raising=False)
    assert threads.environment_sets_threads() is None
    with threads.limit_threads(1):
        assert set(_pool_threads()[0]["threads"]) == {1}
    monkeypatch.setenv("OMP_NUM_THREADS", "3")
    assert threads.environment_sets_threads() == "OMP_NUM_THREADS"
    assert isinstance(threads.limit_threads(1), threads._NoLimit)          # nothing changed
    assert threads.thread_info()["source"] == "environment: OMP_NUM_THREADS=3"
    wrapped = pickle.loads(pickle.dumps(threads.limited(_pool_threads, 1)))
    assert wrapped.fn is _pool_threads and wrapped.n == 1


def test_limit_reaches_scipys_own_blas_loaded_later():
    """NumPy and SciPy wheels each bundle an OpenBLAS; SciPy's loads with scipy.linalg, possibly after
    the command limited the threads: the limit must reach it too (fresh interpreter, nothing pinned)."""
    pytest.importorskip("threadpoolctl")
    if (os.cpu_count() or 1) < 2:
        pytest.skip("one core: every BLAS starts with one thread anyway")
    from swarmfield.runtime.threads import ENV_VARS
    env = {k: v for k, v in os.environ.items() if k not in ENV_VARS}
    code = ("from swarmfield.runtime.threads import limit_threads\nlimit_threads(1)\nimport scipy.linalg\n"
            "from threadpoolctl import threadpool_info\n"
            "print(sorted(p['num_threads'] for p in threadpool_info() if p['user_api'] == 'blas'))")
    proc = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, timeout=120)
    pools = json.loads(proc.stdout.strip().splitlines()[-1])
    assert pools and set(pools) == {1}, proc.stdout + proc.stderr


def test_sweep_workers_run_one_blas_thread(tmp_path, monkeypatch):
    pytest.importorskip("threadpoolctl")
    from swarmfield.runtime import threads
    from swarmfield.studies.runner import run_tasks
    for var in threads.ENV_VARS:
        monkeypatch.delenv(var, raising=False)
    rows = run_tasks([{"i": 0}, {"i": 1}], _pool_threads, tmp_path / "runs", workers=2, stream=None)
    assert [r[0]["threads"] and set(r[0]["threads"]) for r in rows] == [{threads.WORKER_THREADS}] * 2
    # and a BLAS a task loads later reads the worker's environment
    assert [r[0]["env"] for r in rows] == [str(threads.WORKER_THREADS)] * 2
    assert threads.environment_sets_threads() is None          # this process's environment is untouched


def _blas_threads():
    from threadpoolctl import threadpool_info
    return sorted({p["num_threads"] for p in threadpool_info() if p["user_api"] in ("blas", "openmp")})


def _two_threads_or_skip():
    """A context with every BLAS/OpenMP pool at 2 threads (skip where the pools cannot hold 2)."""
    pytest.importorskip("threadpoolctl")
    import scipy.linalg  # noqa: F401 -- SciPy's own OpenBLAS, so that the limit can be seen on it too
    from threadpoolctl import threadpool_limits
    ctx = threadpool_limits(limits=2)
    if _blas_threads() != [2]:
        ctx.restore_original_limits()
        pytest.skip("the BLAS pools cannot be set to 2 threads here")
    return ctx


def test_run_simulation_limits_blas_threads_inside_the_run_and_restores_them(monkeypatch):
    """The Python API runs as the commands do: one BLAS/OpenMP thread inside the run (seen by a recorder
    at every measurement), the caller's limits back afterwards, the environment's count respected."""
    from swarmfield import run_simulation
    from swarmfield.runtime import threads
    from swarmfield.sim import config_from_dict
    from swarmfield.sim.recorders import Recorder

    class Probe(Recorder):
        def __init__(self):
            self.seen = []

        def start(self, sim):
            self.seen.append(_blas_threads())

        measured = start

    for var in threads.ENV_VARS:
        monkeypatch.delenv(var, raising=False)
    config = config_from_dict({"sim": {"domain": [0.0, 10.0, 0.0, 10.0], "start_box": [0.0, 4.0, 0.0, 4.0],
                                       "robots": 12, "max_periods": 1, "substeps": 2, "controller": "greedy"},
                               "planner": {"nx": 12, "ny": 12}})
    ctx = _two_threads_or_skip()
    try:
        probe = Probe()
        run_simulation(config, recorders=[probe])
        assert len(probe.seen) >= 2 and all(s == [threads.COMMAND_THREADS] for s in probe.seen), probe.seen
        assert _blas_threads() == [2]                                       # restored
        probe = Probe()
        run_simulation(config, recorders=[probe], threads=None)             # the caller's limits kept
        assert all(s == [2] for s in probe.seen), probe.seen
        monkeypatch.setenv("OPENBLAS_NUM_THREADS", "2")                     # the environment wins
        probe = Probe()
        run_simulation(config, recorders=[probe])
        assert all(s == [2] for s in probe.seen), probe.seen
    finally:
        ctx.restore_original_limits()


def test_sweep_in_this_process_runs_one_blas_thread_and_restores(tmp_path, monkeypatch):
    from swarmfield.runtime import threads
    from swarmfield.studies.runner import run_tasks
    for var in threads.ENV_VARS:
        monkeypatch.delenv(var, raising=False)
    ctx = _two_threads_or_skip()
    try:
        rows = run_tasks([{"i": 0}, {"i": 1}], _pool_threads, tmp_path / "runs", workers=1, stream=None)
        assert [set(r[0]["threads"]) for r in rows] == [{threads.WORKER_THREADS}] * 2
        assert _blas_threads() == [2]
    finally:
        ctx.restore_original_limits()


# ----------------------------------------------------------------------------------- figures
@pytest.fixture(scope="module")
def result():
    from test_sim import SMALL
    from swarmfield.sim.config import config_from_dict
    from swarmfield.sim.loop import run_simulation
    doc = copy.deepcopy(SMALL)
    doc["sim"].update(max_periods=2, gamma=0.0)
    return run_simulation(config_from_dict(doc))


def _labels(fig):
    return [(a.get_xlabel(), a.get_ylabel(), a.get_title()) for a in fig.axes]


def test_panels_figure_content(result):
    from swarmfield.sim.figures import make_panels, panel_snapshots
    fig = make_panels(result)
    snaps = panel_snapshots(result)
    ncol = len(snaps)
    # a run of 2 periods: t = 0, T, 2T (the snapshot nearest 3T and 4T is shown once, not three times)
    assert [sn.t for sn in snaps] == [0.0, result.config.sim.period, 2 * result.config.sim.period]
    bars = [a for a in fig.axes if getattr(a, "_colorbar", None) is not None]
    rows = [a for a in fig.axes if a not in bars]
    # one Axes per row (robots over p_hat, f_bar, sqrt(V), v), its panels side by side and framed
    assert len(rows) == 4 and len(bars) == 4 and all(b.get_ylabel() for b in bars)
    assert [len(a.images) for a in rows[:3]] == [ncol] * 3               # p_hat, f_bar, sqrt(V) per column
    assert all(len(a.patches) == ncol for a in rows)                     # a frame per panel
    quivers = [c for c in rows[3].collections if type(c).__name__ == "Quiver"]
    assert len(quivers) == sum(sn.velocity is not None for sn in snaps)
    # the panels do not overlap: each image's extent lies in its own frame, clipped to it
    extents = [im.get_extent() for im in rows[0].images]
    assert all(e[1] < f[0] for e, f in zip(extents, extents[1:]))
    for a in rows[:3]:                     # a rectangle clip path becomes the artist's clip box
        assert all(np.allclose(im.get_clip_box().extents, fr.get_window_extent().extents)
                   for im, fr in zip(a.images, a.patches))
    x0, x1, y0, y1 = result.grid.domain
    assert all(np.isclose(e[1] - e[0], x1 - x0) and np.allclose(e[2:], (y0, y1)) for e in extents)
    # y ticks on every row, x ticks (in the domain's own coordinates) under every panel of the last row only
    assert all(a.yaxis.get_visible() and a.get_ylabel().endswith("y [m]") for a in rows)
    assert not any(a.xaxis.get_visible() for a in rows[:3]) and rows[3].get_xlabel() == "x [m]"
    labels = [t.get_text() for t in rows[3].get_xticklabels()]
    assert len(labels) == 3 * ncol and labels[:3] == [f"{v:g}" for v in np.linspace(x0, x1, 3)]
    titles = [t.get_text() for t in rows[0].texts]
    assert len(titles) == ncol and all(t.startswith("t = ") for t in titles)
    assert "[1/m²]" in bars[0].get_ylabel() and "[m/s]" in bars[3].get_ylabel()
    assert fig.get_suptitle()


def test_the_velocity_panels_share_one_scale_no_arrow_longer_than_a_spacing(result):
    # each panel scaled its arrows to its own mean speed, a share of the panel's width: on round 6's 100 m campus the
    # fast arrows ran over two arrow spacings, across walls, and equal arrows meant other speeds in other panels;
    # now the figure's 95th percentile of speed is one spacing long, faster arrows drawn at that length
    from swarmfield.sim.figures import make_panels, panel_snapshots
    fig = make_panels(result)
    fig.canvas.draw()
    snaps = [sn for sn in panel_snapshots(result) if sn.velocity is not None]
    x0, x1, y0, y1 = result.grid.domain
    m, n = snaps[0].velocity.shape[:2]
    spacing = min((x1 - x0) / m, (y1 - y0) / n)
    quivers = [c for a in fig.axes for c in a.collections if type(c).__name__ == "Quiver"]
    assert len(quivers) == len(snaps) >= 2 and len({q.scale for q in quivers}) == 1 and quivers[0].scale_units == "xy"
    longest = max(float(np.max(np.hypot(q.U, q.V))) for q in quivers) / quivers[0].scale
    assert longest == pytest.approx(spacing)                          # the 95th percentile's length, and no longer
    fastest = max(float(np.hypot(sn.velocity[..., 0], sn.velocity[..., 1]).max()) for sn in snaps)
    assert max(float(np.max(q.get_array())) for q in quivers) == pytest.approx(fastest)    # colour: the true speed


@pytest.mark.parametrize("domain", [(0.0, 20.0, 0.0, 20.0), (5.0, 25.0, -2.0, 3.0), (-1.0, 2.0, 10.0, 16.0)])
def test_panel_rows_keep_equal_scales_and_their_frames_inside_the_axes(domain):
    """Panels side by side in one Axes (panels.png): whatever the domain's origin and shape, each frame lies in
    the Axes' limits, the frames do not overlap, and x and y have the same scale (metres per inch)."""
    from swarmfield.runtime.plotting import new_figure
    from swarmfield.sim.figures import _PanelRow, panel_height
    fig = new_figure(10, 3)
    size, gap = 2.0, 0.3
    height = panel_height(domain, size)
    ax = fig.add_axes([0.05, 0.1, (4 * size + 3 * gap) / 10, height / 3])
    row = _PanelRow(ax, domain, 4, gap, size)
    (xa, xb), (ya, yb) = ax.get_xlim(), ax.get_ylim()
    x0, x1, y0, y1 = domain
    spans = [(x0 + dx, x1 + dx) for dx in row.offsets]
    assert all(xa - 1e-9 <= a and b <= xb + 1e-9 for a, b in spans) and (ya, yb) == (y0, y1)
    assert all(b < c for (_, b), (c, _) in zip(spans, spans[1:]))
    assert np.isclose((xb - xa) / (4 * size + 3 * gap), (yb - ya) / height)      # metres per inch, x and y
    assert height <= size and max(x1 - x0, y1 - y0) * height == pytest.approx(size * (y1 - y0))


def test_a_map_in_utm_coordinates_is_labelled_from_its_corner():
    """A 32 m x 22 m yard at UTM (389100, 5819100): tick labels 0 ... 32 under each panel and an axis named
    "x − 389100 [m]", not six-digit eastings that run into the next panel's (nor matplotlib's +5.8191e6 offset);
    the paper's domain and a map near the origin keep their own coordinates."""
    from swarmfield.runtime.plotting import new_figure
    from swarmfield.sim.figures import _PanelRow, _axis_labels, _ticks, panel_height
    dom = (389100.0, 389132.0, 5819100.0, 5819122.0)
    fig = new_figure(10, 3)
    ax = fig.add_axes([0.05, 0.1, 0.9, 0.5])
    row = _PanelRow(ax, dom, 3, 0.3, 2.0)
    row.ticks(x=True)
    assert [t.get_text() for t in ax.get_xticklabels()] == ["0", "16", "32"] * 3
    assert [t.get_text() for t in ax.get_yticklabels()] == ["0", "11", "22"]
    assert ax.get_xlabel() == "x − 389100 [m]"
    ax2 = fig.add_axes([0.05, 0.7, 0.3, 0.25])
    _ticks(ax2, dom)
    _axis_labels(ax2, dom)
    assert [t.get_text() for t in ax2.get_yticklabels()] == ["0", "11", "22"]
    assert (ax2.get_xlabel(), ax2.get_ylabel()) == ("x − 389100 [m]", "y − 5819100 [m]")
    for near in ((0.0, 20.0, 0.0, 20.0), (5.0, 25.0, -2.0, 3.0), (1000.0, 1300.0, 0.0, 200.0)):
        ax3 = fig.add_axes([0.5, 0.7, 0.3, 0.25])
        _ticks(ax3, near)
        _axis_labels(ax3, near)
        assert (ax3.get_xlabel(), ax3.get_ylabel()) == ("x [m]", "y [m]")
        assert ax3.get_xticklabels()[-1].get_text() == f"{near[1]:g}"
        fig.delaxes(ax3)
    assert panel_height(dom, 2.0) > 0


def test_convergence_figure_has_no_duplicated_curve(result):
    from swarmfield.sim.figures import make_convergence
    fig = make_convergence(result)
    assert len(fig.axes) == 4 and all(t and y for _, y, t in _labels(fig))
    n = len(result.rows)
    curves = [ln.get_ydata() for a in fig.axes for ln in a.lines if len(ln.get_ydata()) == n]
    assert len(curves) == 5                    # sup V, mean V, RMSE, tracking error, speed (no L2 = RMSE x c)
    norm = [np.asarray(c, float) / np.nanmax(np.abs(c)) for c in curves]
    for i in range(len(norm)):
        for j in range(i):
            assert not np.allclose(norm[i], norm[j], equal_nan=True), (i, j)
    first = fig.axes[0]
    assert [ln.get_label() for ln in first.lines[:2]] == ["sup V", "mean V"] and first.get_legend() is not None


def test_field_error_colour_bar_states_clipping(result):
    from swarmfield.sim.figures import make_field_error
    clean = copy.copy(result)
    clean.mean = result.f_true.copy()
    fig = make_field_error(clean)
    assert sum(len(a.images) for a in fig.axes) == 3
    assert [a.get_xlabel() for a in fig.axes[:3]] == ["x [m]"] * 3
    assert not any("clipped" in a.get_ylabel() for a in fig.axes)
    over = copy.copy(result)
    over.mean = result.f_true + 0.5 * (result.f_true.max() - result.f_true.min())
    fig = make_field_error(over)
    bar = [a for a in fig.axes if getattr(a, "_colorbar", None) is not None][1]   # the prediction's colour bar
    lo, hi = float(result.f_true.min()), float(result.f_true.max())
    assert f"clipped to [{lo:.3g}, {hi:.3g}]" in bar.get_ylabel()


def test_gif_has_one_frame_per_measurement(result, tmp_path):
    PIL = pytest.importorskip("PIL.Image")
    from swarmfield.sim.figures import write_animation
    write_animation(result, tmp_path / "a.gif")
    with PIL.open(tmp_path / "a.gif") as im:
        assert im.n_frames == len(result.times)
        im.seek(im.n_frames - 1)
        rgb = np.asarray(im.convert("RGB"))
    assert rgb.std() > 10                                  # a picture, not a blank frame


def test_outputs_record_each_figure_time_and_report_progress(result, tmp_path):
    from swarmfield.sim.outputs import write_outputs
    seen = []
    files = write_outputs(result, tmp_path, figures=True, gif=False, progress=seen.append)
    assert seen == ["panels.png", "convergence.png", "field_error.png"]
    timings = json.loads((tmp_path / "summary.json").read_text())["output_timings_s"]
    assert set(timings) == {"tables", *seen} and all(v > 0 for v in timings.values())
    assert set(seen) <= set(files)


@pytest.fixture
def drawer():
    from swarmfield.runtime.plotting import DrawingProcess
    proc = DrawingProcess.start()
    if proc is None:
        pytest.skip("no fork or a single CPU: the commands draw in their own process")
    with proc:
        yield proc


def test_figures_drawn_by_the_drawing_process_are_those_drawn_here(result, tmp_path, drawer):
    """write_figures(drawer=...): the same files, pixel for pixel, as when this process draws them; each
    figure's time recorded; the GIF too."""
    from PIL import Image
    from swarmfield.sim.figures import FIGURE_FILES, write_animation, write_figures
    for sub, d in (("here", None), ("there", drawer)):
        (tmp_path / sub).mkdir()
        seen, timings = [], {}
        assert write_figures(result, tmp_path / sub, progress=seen.append, timings=timings, drawer=d) == list(FIGURE_FILES)
        assert seen == list(FIGURE_FILES) and set(timings) == set(FIGURE_FILES) and all(v > 0 for v in timings.values())
    assert drawer.call(write_animation, result, tmp_path / "there" / "a.gif") == "a.gif"
    write_animation(result, tmp_path / "here" / "a.gif")
    for name in (*FIGURE_FILES, "a.gif"):
        with Image.open(tmp_path / "here" / name) as a, Image.open(tmp_path / "there" / name) as b:
            np.testing.assert_array_equal(np.asarray(a), np.asarray(b))


def _fails(message):
    raise ValueError(message)


def test_the_drawing_process_reports_errors_and_its_end(drawer):
    import os
    import signal
    with pytest.raises(ValueError, match=r"^no data to draw$"):
        drawer.call(_fails, "no data to draw")
    with pytest.raises(FileNotFoundError):
        drawer.call(open, "/nonexistent/folder/figure.png", "rb")
    assert drawer.call(max, 3, 4) == 4                           # still serving
    os.kill(drawer._proc.pid, signal.SIGINT)                     # ignored there: the command handles an interrupt
    assert drawer.call(max, 5, 6) == 6
    drawer._proc.kill()
    drawer._proc.join()
    with pytest.raises(RuntimeError, match=r"the drawing process ended \(exit code -9\) before max returned"):
        drawer.call(max, 1, 2)
    drawer.close()
    drawer.close()                                               # idempotent


def test_lean_import_keeps_set_working():
    """runtime.plotting.lean_import skips the set methods' generated signatures and tables; set() still
    dispatches every property (a fresh interpreter: matplotlib must not be loaded yet)."""
    code = ("from swarmfield.runtime.plotting import lean_import, new_figure\n"
            "lean_import()\n"
            "import matplotlib.lines, matplotlib.text\n"
            "fig = new_figure(2, 2); ax = fig.add_subplot()\n"
            "line, = ax.plot([0, 1], [0, 1]); line.set(color='r', linewidth=3, label='x')\n"
            "t = ax.set_title('t'); t.set(fontsize=7)\n"
            "assert line.get_color() == 'r' and line.get_linewidth() == 3 and t.get_fontsize() == 7\n"
            "assert 'omitted' in matplotlib.lines.Line2D.set.__doc__\n"
            "class Mine(matplotlib.lines.Line2D): pass\n"
            "assert 'linewidth' in str(__import__('inspect').signature(Mine.set))\n"
            "fig.canvas.draw(); print('ok')\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "ok"


def test_plan_figure_content():
    from swarmfield.ocp import PlannerSettings, ReferencePlanner
    from swarmfield.ocp.figures import make_plan_figure
    from swarmfield.ocp.grid import Grid
    from swarmfield.sim.scenario import box_density, first_step_target
    s = PlannerSettings(nx=10, ny=10, n_intervals=2, n_modes_x=2, n_modes_y=2)
    grid = Grid(s.domain, s.nx, s.ny)
    plan = ReferencePlanner(s).solve(box_density(grid), first_step_target(grid, seed=0)[0], t0=0.0)
    fig = make_plan_figure(plan, n_snapshots=3)
    image_axes = [a for a in fig.axes if a.images]
    assert len(image_axes) == 4 and image_axes[-1].get_title() == "target p_f"
    assert all(a.get_xlabel() == "x [m]" for a in image_axes) and image_axes[0].get_ylabel() == "y [m]"
    assert sum(1 for a in image_axes for c in a.collections if type(c).__name__ == "Quiver") == 3
    assert fig.axes[-1].get_ylabel() == "density [1/m²]"


def test_plan_figure_of_a_map_in_utm_is_labelled_from_its_corner():
    from swarmfield.ocp import PlannerSettings, ReferencePlanner
    from swarmfield.ocp.figures import make_plan_figure
    from swarmfield.ocp.grid import Grid
    s = PlannerSettings(domain=(389100.0, 389132.0, 5819100.0, 5819122.0), nx=8, ny=6, n_intervals=2, n_modes_x=2,
                        n_modes_y=2)
    grid = Grid(s.domain, s.nx, s.ny)
    p0 = grid.normalize(np.ones((8, 6)))
    target = grid.normalize(np.add.outer(np.arange(8.0), np.ones(6)))
    fig = make_plan_figure(ReferencePlanner(s).solve(p0, target, t0=0.0), n_snapshots=2)
    image_axes = [a for a in fig.axes if a.images]
    assert all(a.get_xlabel() == "x − 389100 [m]" for a in image_axes)
    assert image_axes[0].get_ylabel() == "y − 5819100 [m]"
    assert [t.get_text() for t in image_axes[0].get_xticklabels()] == ["0", "16", "32"]
    assert [t.get_text() for t in image_axes[0].get_yticklabels()] == ["0", "11", "22"]


# ----------------------------------------------------------------------------------- study plots
def _rows(sizes, exponent=1.5):
    return [{"study": "s", "case": f"n{n}", "method": "ipopt", "kernel": "compiled", "nx": n, "ny": n,
             "solve_s": 1e-3 * (n * n) ** exponent, "objective": 1.0, "iterations": 5} for n in sizes]


def test_no_exponent_from_fewer_than_three_sizes():
    from swarmfield.studies.sweepcli import exponent_text, fit_exponent, make_scaling
    two, three = _rows([8, 16]), _rows([8, 16, 32])
    assert np.isnan(fit_exponent([64, 256], [1.0, 4.0]))
    assert fit_exponent([r["nx"] ** 2 for r in three], [r["solve_s"] for r in three]) == pytest.approx(1.5)
    assert exponent_text([(64, 1.0, 0), (256, 4.0, 0)]).startswith("too few sizes (2")
    leg = [t.get_text() for t in make_scaling(two).axes[0].get_legend().get_texts()]
    assert len(leg) == 1 and "too few sizes" in leg[0] and "nan" not in leg[0]
    leg = [t.get_text() for t in make_scaling(three).axes[0].get_legend().get_texts()]
    assert leg == ["ipopt / compiled: exponent 1.50 (3 sizes)"]


def test_study_md_says_too_few_sizes(tmp_path):
    from swarmfield.studies.sweepcli import write_sweep_outputs
    write_sweep_outputs(_rows([8, 16]), tmp_path)
    md = (tmp_path / "study.md").read_text()
    assert "too few sizes (2; an exponent needs 3)" in md and "nan" not in md


def test_compare_plot_one_curve_per_controller_with_labels():
    from swarmfield.studies.compare import make_plot, scenario_curves
    def rows(scale):
        return [{"t_T": k / 2, "rmse": scale / (1 + k), "max_variance": 0.25 * scale / (1 + k), "threshold": 0.1}
                for k in range(5)]
    runs = [({"preset": "paper", "controller": c, "field": "sinc", "robots": 20, "robot_loss": 0.0}, rows(s))
            for c, s in (("feedback", 1.0), ("feedback", 1.1), ("lawnmower", 2.0))]
    curves = scenario_curves(runs)
    fig = make_plot(("", "sinc", 20, 0.0), curves[("", "sinc", 20, 0.0)], 0.1)   # (domain, field, robots, loss)
    rmse_ax, var_ax = fig.axes
    assert [ln.get_label() for ln in rmse_ax.lines] == ["feedback", "lawnmower"]
    assert len(rmse_ax.collections) == 1                   # a min-max band only where there are two seeds
    assert "[field units]" in rmse_ax.get_ylabel() and rmse_ax.get_xlabel() == "t / T (periods)"
    assert var_ax.get_yscale() == "log" and var_ax.get_title()
    np.testing.assert_allclose(var_ax.lines[1].get_ydata(), [0.25 * 2.0 / (1 + k) / 0.1 for k in range(5)])


def test_the_wall_labels_of_neighbouring_panels_do_not_run_together():
    """A ROS map from origin (-7.3, -4.15): the x labels at the walls, "24.7" under one panel's east wall and
    "-7.3" under the next one's west wall, ran together ("24.7-7.3"); the labels at the walls now sit inside their
    panel's span."""
    from swarmfield.runtime.plotting import new_figure
    from swarmfield.sim.figures import _PanelRow, panel_height
    dom = (-7.3, 24.7, -4.15, 15.85)
    fig = new_figure(9.4, 3)
    ax = fig.add_axes([0.1, 0.2, 0.8, panel_height(dom, 2.4) / 3])
    row = _PanelRow(ax, dom, 3, 0.3, 2.4)
    row.ticks(x=True)
    fig.canvas.draw()
    r = fig.canvas.get_renderer()
    boxes = [t.get_window_extent(r) for t in ax.get_xticklabels()]
    assert [t.get_text() for t in ax.get_xticklabels()] == ["-7.3", "8.7", "24.7"] * 3
    assert all(a.x1 < b.x0 for a, b in zip(boxes, boxes[1:])), [(round(a.x0), round(a.x1)) for a in boxes]


def test_colour_bar_labels_stay_beside_their_own_bar():
    """The f̄ bar's "clipped to [1.6, 8.89] (data 1.56 to 8.28)" and the √V bar's nugget note were each longer than
    their bar and ran into each other (a pond of 48 m x 32 m, tuned preset): labels are wrapped to their bar."""
    from swarmfield.runtime.plotting import new_figure
    from swarmfield.sim.figures import _colorbar, _row_axes
    fig = new_figure(9.4, 11)
    rows, cax = _row_axes(fig, 4, 1.15, 0.55, 0.85, 0.32, 7.8, 2.4, 1.6)
    im = [rows[r].imshow(np.random.default_rng(r).random((4, 4)) * 9) for r in range(2)]
    _colorbar(fig, im[0], cax[0], "f̄ [field units]", np.array([1.56, 8.28, 9.5]))
    _colorbar(fig, im[1], cax[1], "√V [field units] (resolvable; + nugget τ = 0.0196)")
    fig.canvas.draw()
    r = fig.canvas.get_renderer()
    a, b = (c.yaxis.label.get_window_extent(r) for c in cax[:2])
    assert a.y0 > b.y1, (a, b)                       # the upper bar's label ends above the lower one's
    bars = [c.get_window_extent(r) for c in cax[:2]]
    assert a.y0 >= bars[0].y0 - 12 and b.y1 <= bars[1].y1 + 12     # about as long as its bar



def test_no_velocity_arrows_inside_obstacles(result):
    """The feedback row drew a zero arrow, a dot, at every grid point inside an obstacle (a grid of dots over a
    pond); those points are left out."""
    from swarmfield.domain import Domain
    from swarmfield.sim.figures import make_panels, panel_snapshots
    x0, x1, y0, y1 = result.grid.domain
    free = np.ones((100, 100), bool)
    free[50:, 50:] = False                                   # the north-east quarter is an obstacle
    with_pond = copy.copy(result)
    with_pond.region = Domain.from_raster(free, (x0, x1, y0, y1))
    shapes = [sn.velocity.shape[:2] for sn in panel_snapshots(with_pond) if sn.velocity is not None]
    fig = make_panels(with_pond)
    quivers = [c for a in fig.axes for c in a.collections if type(c).__name__ == "Quiver"]
    assert len(quivers) == len(shapes) > 0
    for q, (m, n) in zip(quivers, shapes):
        xs = x0 + (np.arange(m) + 0.5) * (x1 - x0) / m
        ys = y0 + (np.arange(n) + 0.5) * (y1 - y0) / n
        X, Y = np.meshgrid(xs, ys, indexing="ij")
        n_free = int(with_pond.region.contains(np.column_stack([X.ravel(), Y.ravel()])).sum())
        assert q.N == n_free < m * n
