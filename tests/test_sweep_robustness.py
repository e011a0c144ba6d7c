"""Issue 18: sweeps that survive their users (F1-F12).

Every test reproduces a failure of the code before issue 18: a second Ctrl-C that hung the sweep
(F1), workers that outlived a killed main process and kept its output folder locked (F2), repeated
axis values (F3), bad or unreadable field files found only inside the runs (F4, F5), tracebacks for
a bad ``--scheduler`` (F6), a robot loss leaving one robot (F7), a full disk while storing a run
(F8), "nothing written" after the files were written (F9), unchecked ``--times`` (F10) and
``--loss-time`` (F11), a complex warm-start plan cast to real (F12).

The signal tests run the real command in a new session and signal it the way a terminal or a
batch system does (``os.killpg`` for Ctrl-C, the main process alone for SIGTERM and SIGKILL),
wait for a progress line instead of sleeping, and have bounded timeouts.
"""
import errno
import fcntl
import json
import os
import signal
import socket
import subprocess
import sys
import threading
import time

import numpy as np
import pytest

from swarmfield.cli import plan_reference as plan_cli
from swarmfield.cli import simulate_swarm as sim_cli
from swarmfield.studies import compare, solver_spec, solver_study

TINY_TOML = """
[sim]
robots = 20
domain = [0.0, 10.0, 0.0, 10.0]
start_box = [0.0, 4.0, 0.0, 4.0]
period = 1.75
substeps = 2
[gp]
length_scale = 1.5
[kde]
bins = [32, 32]
"""
TINY = ["--controllers", "lawnmower", "--max-periods", "1", "--no-plots"]
SMALL_PLAN = ["--nx", "12", "--ny", "10", "--intervals", "3", "--modes", "3", "3"]


@pytest.fixture
def cfg(tmp_path):
    p = tmp_path / "tiny.toml"
    p.write_text(TINY_TOML)
    return p


def cmp(argv, capsys):
    code = compare.main([str(a) for a in argv])
    return code, capsys.readouterr().err


def one_line(err):
    """The one message line of ``err`` (progress lines as runs start are not messages)."""
    lines = [ln for ln in err.strip().splitlines() if ": starting run " not in ln]
    assert len(lines) == 1 and "Traceback" not in err, err
    return lines[0]


# ------------------------------------------------------------------------------ F1, F2: real signals
SIGNAL_SEEDS = 8


def start_sweep(cfg, out):
    """A real sweep of 8 lawnmower runs of 16 periods on 2 workers, in its own session (a terminal's
    process group); returns once the first run is stored (the workers are busy then)."""
    cmd = [sys.executable, "-c", "from swarmfield.studies.compare import main; main()",
           "--controllers", "lawnmower", "--seeds", *map(str, range(SIGNAL_SEEDS)), "--max-periods", "10",
           "--config", str(cfg), "--out", str(out), "--workers", "2", "--no-plots"]
    env = dict(os.environ, OPENBLAS_NUM_THREADS="1", OMP_NUM_THREADS="1", MPLBACKEND="Agg")
    proc = subprocess.Popen(cmd, stderr=subprocess.PIPE, text=True, start_new_session=True, env=env)
    head = wait_for(proc, f"1/{SIGNAL_SEEDS} runs done")
    return proc, head


def wait_for(proc, text, limit=120):
    lines, t0 = [], time.monotonic()
    while time.monotonic() - t0 < limit:
        line = proc.stderr.readline()
        lines.append(line)
        if text in line:
            return "".join(lines)
        if not line:
            break
    os.killpg(proc.pid, signal.SIGKILL)
    pytest.fail(f"no {text!r} on stderr: {''.join(lines)}")


def session_members(sid):
    """Live processes of the session ``sid`` (the command and everything it started)."""
    out = []
    for d in os.listdir("/proc"):
        if not d.isdigit():
            continue
        try:
            with open(f"/proc/{d}/stat") as fh:
                fields = fh.read().rsplit(")", 1)[1].split()
        except OSError:
            continue
        if int(fields[3]) == sid and fields[0] != "Z":
            out.append(int(d))
    return out


def assert_all_gone_and_unlocked(proc, out, limit=20.0):
    t0 = time.monotonic()
    while session_members(proc.pid) and time.monotonic() - t0 < limit:
        time.sleep(0.1)
    left = session_members(proc.pid)
    if left:
        for pid in left:
            os.kill(pid, signal.SIGKILL)
        pytest.fail(f"processes of the sweep outlived it: {left}")
    fd = os.open(out, os.O_RDONLY)
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)         # the output folder is free for the resume
    finally:
        os.close(fd)
    stored = list((out / "runs").glob("*.json"))
    assert stored and all("rows" in json.loads(p.read_text()) for p in stored)
    assert not list((out / "runs").glob(".*.tmp")) and not (out / "runs.csv").exists()
    return len(stored)


def finish(proc, limit=60):
    """Wait for the main process, then for every process of its session (orphaned workers hold the
    stderr pipe: reading it to the end first would wait for them), then read stderr."""
    try:
        proc.wait(timeout=limit)
    except subprocess.TimeoutExpired:
        os.killpg(proc.pid, signal.SIGKILL)
        proc.communicate()
        pytest.fail("the sweep did not end after the signal")
    t0 = time.monotonic()
    while session_members(proc.pid) and time.monotonic() - t0 < 20:
        time.sleep(0.1)
    left = session_members(proc.pid)
    if left:
        os.killpg(proc.pid, signal.SIGKILL)
        pytest.fail(f"processes of the sweep outlived it: {left}")
    return proc.communicate(timeout=10)[1]


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc")
def test_f1_second_ctrl_c_ends_the_sweep_promptly_and_it_resumes(tmp_path, cfg):
    out = tmp_path / "o"
    proc, _ = start_sweep(cfg, out)
    os.killpg(proc.pid, signal.SIGINT)          # Ctrl-C, and again while the first is being handled
    time.sleep(0.05)
    os.killpg(proc.pid, signal.SIGINT)
    err = finish(proc)
    assert proc.returncode == 130
    assert one_line(err).startswith("compare-controllers: interrupted; nothing written") and "resumes" in err
    done = assert_all_gone_and_unlocked(proc, out)
    # the same command resumes: the stored runs are skipped; a third Ctrl-C there ends it too
    proc2 = subprocess.Popen(proc.args, stderr=subprocess.PIPE, text=True, start_new_session=True, env=None)
    head = wait_for(proc2, "already done")
    assert f"{SIGNAL_SEEDS} runs, {done} already done" in head
    os.killpg(proc2.pid, signal.SIGINT)
    err2 = finish(proc2)
    assert proc2.returncode == 130 and "Traceback" not in err2
    assert_all_gone_and_unlocked(proc2, out)


def test_f1_an_interrupt_while_a_run_is_stored_leaves_no_temporary_file(tmp_path, monkeypatch):
    # the second Ctrl-C can land while the main process stores a finished run: only OSError cleaned up before
    from swarmfield.studies import runner

    def interrupted(src, dst):
        raise KeyboardInterrupt
    monkeypatch.setattr(runner.os, "replace", interrupted)
    with pytest.raises(KeyboardInterrupt):
        runner._store(tmp_path, {"x": 1}, [{"y": 2}])
    assert list(tmp_path.iterdir()) == []


def test_f2_a_signal_between_writes_leaves_no_progress_line_open():
    # CI once saw "... preset papercompare-controllers: terminated (SIGTERM); ...": print() writes the
    # text and its newline in two calls, and the SIGTERM landed between them
    from swarmfield.runtime.signals import Terminated
    from swarmfield.studies.runner import _Progress

    class Stream:
        def __init__(self):
            self.written, self.armed = [], None

        def write(self, text):                      # once armed, the signal lands before the second write
            if self.armed is not None and len(self.written) == self.armed + 1:
                self.armed = None
                raise Terminated()
            self.written.append(text)

        def flush(self):
            pass

    stream = Stream()
    progress = _Progress(8, 2, "compare-controllers", stream)
    stream.armed = len(stream.written)
    with pytest.raises(Terminated):
        progress.start({"controller": "lawnmower", "seed": 2})
        progress.start({"controller": "greedy", "seed": 2})
    assert all(w.endswith("\n") and w.count("\n") == 1 for w in stream.written), stream.written
    progress.tick()
    assert stream.written[-1].endswith(" s\n") and "3/8 runs done" in stream.written[-1]


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc")
def test_f2_sigterm_of_the_main_process_stops_its_workers(tmp_path, cfg):
    out = tmp_path / "o"
    proc, _ = start_sweep(cfg, out)
    proc.send_signal(signal.SIGTERM)            # timeout(1), batch schedulers, systemctl stop
    err = finish(proc)
    assert proc.returncode == 143 and "resumes" in one_line(err)
    assert_all_gone_and_unlocked(proc, out)


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc")
def test_f2_sigkill_of_the_main_process_takes_its_workers_along(tmp_path, cfg):
    out = tmp_path / "o"
    proc, _ = start_sweep(cfg, out)
    helpers = [pid for pid in session_members(proc.pid) if pid != proc.pid]
    assert len(helpers) >= 2                    # the workers (and the fork server)
    for pid in helpers:                         # none holds a descriptor of the output folder (its lock)
        for fd in os.listdir(f"/proc/{pid}/fd"):
            try:
                target = os.readlink(f"/proc/{pid}/fd/{fd}")
            except OSError:
                continue
            assert not target.startswith(str(out)), (pid, target)
    proc.kill()
    finish(proc)
    assert_all_gone_and_unlocked(proc, out)     # no orphan holds the lock: "another run is writing" is gone


# ------------------------------------------------------------------------------ F3: repeated axis values
def test_f3_repeated_axis_values_are_dropped_with_a_note(tmp_path, cfg, capsys):
    out = tmp_path / "o"
    code, err = cmp(TINY + ["--controllers", "lawnmower", "lawnmower", "--seeds", "0", "0", "--robot-loss", "0", "0.0",
                            "--fields", "sinc", "sinc", "--config", cfg, "--out", out, "--workers", "1"], capsys)
    assert code == 0, err
    notes = [ln for ln in err.splitlines() if ln.startswith("note:")]
    assert notes == ["note: --controllers: dropped repeated value(s) lawnmower",
                     "note: --fields: dropped repeated value(s) sinc",
                     "note: --seeds: dropped repeated value(s) 0",
                     "note: --robot-loss: dropped repeated value(s) 0.0"]
    assert len(list((out / "runs").glob("*.json"))) == 1
    # solver-study: the same rule, the same note
    parsed = solver_spec.parse_spec({"grid": [12, 12, 16], "seeds": [0]})
    assert parsed["grid"] == [12, 16]
    assert capsys.readouterr().err == "note: --grid: dropped repeated value(s) 12\n"


# ------------------------------------------------------------------------------ F4, F5: field files in the parent
def _bad_fields(tmp):
    nan = tmp / "nan.npz"
    np.savez(nan, values=np.array([[1.0, np.nan], [2.0, 3.0]]), extent=np.array([0, 10, 0, 10.0]))
    (tmp / "empty.csv").write_text("")
    (tmp / "header.csv").write_text("x,y,value\n")
    np.savez(tmp / "keyless.npz")
    (tmp / "nothing.npz").write_bytes(b"")
    with open(tmp / "huge.npy", "wb") as fh:             # declares 200000 x 200000, holds nothing
        np.lib.format.write_array_header_1_0(fh, {"descr": "<f8", "fortran_order": False, "shape": (200000, 200000)})
    return ["nan.npz", "empty.csv", "header.csv", "keyless.npz", "nothing.npz", "huge.npy"]


def test_f4_bad_field_files_are_refused_before_any_worker(tmp_path, cfg, capsys):
    names = _bad_fields(tmp_path)
    for name in names:
        out = tmp_path / f"out_{name}"
        code, err = cmp(TINY + ["--fields", "sinc", tmp_path / name, "--config", cfg, "--out", out, "--workers", "2"],
                        capsys)
        assert code == 2 and name in one_line(err), (name, err)
        assert not out.exists()                          # nothing created, not even OUT/runs/


def test_f5_unreadable_field_file_is_one_line(tmp_path, cfg, capsys, monkeypatch):
    field = tmp_path / "secret.csv"
    field.write_text("x,y,value\n0,0,1\n10,0,1\n0,10,1\n10,10,2\n")
    field.chmod(0)
    if os.access(field, os.R_OK):                        # root reads anything: refuse the read as the kernel would
        real = type(field).read_bytes

        def denied(self):
            if self.name == "secret.csv":
                raise PermissionError(errno.EACCES, "Permission denied", str(self))
            return real(self)
        monkeypatch.setattr(type(field), "read_bytes", denied)
    out = tmp_path / "o"
    code, err = cmp(TINY + ["--fields", field, "--config", cfg, "--out", out], capsys)
    assert code == 2 and "secret.csv" in one_line(err) and "Permission denied" in err
    assert not out.exists()


# ------------------------------------------------------------------------------ F6: scheduler
@pytest.fixture
def not_dask():
    """A TCP endpoint that answers like a web server."""
    srv = socket.socket()
    srv.bind(("127.0.0.1", 0))
    srv.listen(8)

    def serve():
        while True:
            try:
                conn, _ = srv.accept()
            except OSError:
                return
            conn.sendall(b"HTTP/1.1 200 OK\r\nContent-Length: 5\r\n\r\nhello" * 20)
            conn.close()
    threading.Thread(target=serve, daemon=True).start()
    yield f"tcp://127.0.0.1:{srv.getsockname()[1]}"
    srv.close()


def test_f6_bad_scheduler_is_one_line_exit_2_and_nothing_in_out(tmp_path, cfg, capsys, not_dask):
    pytest.importorskip("distributed")
    free = socket.socket()
    free.bind(("127.0.0.1", 0))
    unreachable = f"tcp://127.0.0.1:{free.getsockname()[1]}"       # bound, not listening: nobody answers
    cases = [("foo:bar:baz", "not a scheduler address"), (not_dask, "does not speak the Dask protocol"),
             (unreachable, "within 1 s")]
    for address, msg in cases:
        out = tmp_path / "cmp"
        code, err = cmp(TINY + ["--config", cfg, "--out", out, "--scheduler", address, "--scheduler-timeout", "1"],
                        capsys)
        assert code == 2 and msg in one_line(err), (address, err)
        assert not out.exists()
        out = tmp_path / "study"
        code = solver_study.main(["--quick", "--grid", "12", "--out", str(out), "--scheduler", address,
                                  "--scheduler-timeout", "1"])
        err = capsys.readouterr().err
        assert code == 2 and msg in one_line(err), (address, err)
        assert not out.exists()
    free.close()


# ------------------------------------------------------------------------------ F7, F10, F11: checked against the run
def test_f7_a_loss_leaving_fewer_than_two_robots_is_refused(tmp_path, cfg, capsys):
    out = tmp_path / "sim"
    code = sim_cli.main(["--config", str(cfg), "--robots", "3", "--robot-loss", "0.5", "--controller", "lawnmower",
                         "--max-periods", "2", "--loss-time", "1.75", "--no-figures", "--quiet", "--out", str(out)])
    err = capsys.readouterr().err
    assert code == 2 and "leaves 1 robot" in one_line(err) and not out.exists()
    code, err = cmp(TINY + ["--robots", "2", "--robot-loss", "0", "0.5", "--config", cfg, "--out", tmp_path / "c"],
                    capsys)
    assert code == 2 and "leaves 1 robot" in one_line(err) and not (tmp_path / "c").exists()


def test_f10_times_outside_the_runs_are_refused(tmp_path, cfg, capsys):
    for t in ("99", "-1", "0", "nan"):
        code, err = cmp(TINY + ["--times", t, "--config", cfg, "--out", tmp_path / "c"], capsys)
        assert code == 2 and "--times" in one_line(err), (t, err)
        assert not (tmp_path / "c").exists()


def test_f11_loss_time_after_the_end_of_the_runs_is_refused(tmp_path, cfg, capsys):
    code, err = cmp(TINY + ["--robot-loss", "0", "0.5", "--loss-time", "100", "--config", cfg, "--out", tmp_path / "c"],
                    capsys)
    assert code == 2 and "sim.loss_time 100 s is after the end of the run" in one_line(err)
    assert not (tmp_path / "c").exists()


# ------------------------------------------------------------------------------ F8: disk full while storing a run
@pytest.mark.parametrize("err_no", [errno.ENOSPC, errno.EROFS])
def test_f8_full_disk_while_storing_a_run_is_one_line_and_resumes(tmp_path, cfg, capsys, monkeypatch, err_no):
    out = tmp_path / "o"
    argv = TINY + ["--seeds", "0", "1", "--config", cfg, "--out", out, "--workers", "1"]
    stores = []
    import builtins
    import io
    real_open = builtins.open

    def full(path, *a, **k):
        """The file system refuses the second run's file (ENOSPC, or EROFS as if remounted read-only)."""
        if str(path).endswith(".tmp") and str(out / "runs") in str(path):
            stores.append(path)
            if len(stores) == 2:
                real_open(path, "w").close()           # a partial file, which must not stay behind
                raise OSError(err_no, os.strerror(err_no), str(path))
        return real_open(path, *a, **k)
    monkeypatch.setattr(builtins, "open", full)
    monkeypatch.setattr(io, "open", full)
    code, err = cmp(argv + ["--quiet"], capsys)
    line = one_line(err)
    assert code == 1 and os.strerror(err_no) in line and str(out / "runs") in line and "resumes" in line
    assert len(list((out / "runs").glob("*.json"))) == 1 and not list((out / "runs").glob(".*"))
    assert not (out / "runs.csv").exists()
    monkeypatch.undo()
    code, err = cmp(argv, capsys)
    assert code == 0 and "2 runs, 1 already done, 1 to run" in err and (out / "runs.csv").exists()


# ------------------------------------------------------------------------------ F9, F12: plan-reference
def test_f9_ctrl_c_after_publication_says_the_files_were_written(tmp_path, capsys, monkeypatch):
    plan, png = tmp_path / "p.npz", tmp_path / "p.png"
    from pathlib import Path
    real = Path.unlink

    def ctrl_c_after_publication(self, *a, **k):      # the temporaries are removed after the renames
        if not self.exists() and self.name.endswith(".tmp.npz"):
            raise KeyboardInterrupt
        return real(self, *a, **k)
    monkeypatch.setattr(Path, "unlink", ctrl_c_after_publication)
    code = plan_cli.main([str(a) for a in SMALL_PLAN + ["--out", plan, "--plot", png]])
    err = capsys.readouterr().err
    assert code == 130 and one_line(err) == f"plan-reference: interrupted after writing {plan} and {png}"
    assert plan.is_file() and png.is_file()
    monkeypatch.undo()
    # F12: a warm-start plan with complex coefficients is refused, not cast to real
    with np.load(plan) as z:
        doc = {k: z[k] for k in z.files}
    doc["coef"] = doc["coef"] + 1j
    bad = tmp_path / "complex.npz"
    np.savez(bad, **doc)
    code = plan_cli.main([str(a) for a in SMALL_PLAN + ["--out", tmp_path / "q.npz", "--warm-start", bad]])
    err = capsys.readouterr().err
    assert code == 2 and "complex.npz" in one_line(err) and "coef must hold real numbers" in err
    assert not (tmp_path / "q.npz").exists()


# ------------------------------------------------------------------------------ a worker that dies
def die_or_square(task):
    if task.get("die"):
        os._exit(3)                                # as a worker killed by the OOM killer would end
    return [{"x": task["x"], "y": task["x"] ** 2}]


def test_a_worker_that_dies_fails_its_task_only_and_is_replaced(tmp_path):
    from swarmfield.studies import runner
    tasks = [{"x": 0}, {"x": 1, "die": True}, {"x": 2}, {"x": 3}]
    with pytest.raises(runner.SweepError) as info:
        runner.run_tasks(tasks, die_or_square, tmp_path, workers=2, stream=None)
    assert [t for t, _ in info.value.failures] == [tasks[1]] and "exit code 3" in info.value.failures[0][1]
    assert len(list(tmp_path.glob("*.json"))) == 3             # the others ran, in a replacement worker too


@pytest.mark.parametrize("flag,value", [("--robots", "1"), ("--max-periods", "0"), ("--seeds", "-1")])
def test_each_bad_count_is_named(tmp_path, cfg, capsys, flag, value):
    argv = [a for a in TINY if a not in ("--max-periods", "1")] + [flag, value, "--config", cfg, "--out", tmp_path / "c"]
    code, err = cmp(argv, capsys)
    line = one_line(err)
    assert code == 2 and f"{flag} must be >= " in line and f"got {value}" in line
    assert [f for f in ("--robots", "--max-periods", "--seeds") if f in line] == [flag]


def test_files_of_the_same_names_that_no_sweep_wrote_are_not_replaced(tmp_path, cfg, capsys):
    out = tmp_path / "c"
    out.mkdir()
    (out / "notes.txt").write_text("mine")                         # other files beside the sweep's: fine
    (out / "summary.md").write_text("my own summary")
    code, err = cmp(TINY + ["--config", cfg, "--out", out], capsys)
    assert code == 2 and "holds summary.md, which no previous compare-controllers run wrote" in one_line(err)
    assert (out / "summary.md").read_text() == "my own summary" and not (out / "runs.csv").exists()
    code, err = cmp(TINY + ["--config", cfg, "--out", out, "--force", "--quiet"], capsys)
    assert code == 0 and (out / "runs.csv").exists() and (out / "notes.txt").read_text() == "mine"
    code, err = cmp(TINY + ["--config", cfg, "--out", out, "--quiet"], capsys)      # now it is the sweep's own
    assert code == 0
