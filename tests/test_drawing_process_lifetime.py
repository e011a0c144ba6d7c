"""The drawing process (runtime.plotting.DrawingProcess) dies with its parent, whatever ends the parent,
and with it the output folder's lock it inherited (a next run into OUT must not be refused)."""
import errno
import fcntl
import os
import signal
import subprocess
import sys
import time

import pytest

SCRIPT = r"""
import fcntl, os, sys, time
from swarmfield.runtime.plotting import DrawingProcess
fd = os.open(sys.argv[1], os.O_RDONLY | os.O_DIRECTORY)
fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)          # as simulate-swarm holds OUT
d = DrawingProcess.start()
print(d._proc.pid if d is not None else 0, flush=True)
if d is None:
    sys.exit(0)
d.call(time.sleep, 0.01)                                 # the child is up
print("busy", flush=True)
d.call(time.sleep, 120)                                  # the child is drawing when the parent is ended
"""


def _alive(pid: int) -> bool:
    try:
        with open(f"/proc/{pid}/stat") as fh:
            return fh.read().rsplit(")", 1)[1].split()[0] != "Z"     # a zombie has ended
    except FileNotFoundError:
        return False
    except OSError:
        try:
            os.kill(pid, 0)
        except ProcessLookupError:
            return False
        return True


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc")
@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGKILL])
def test_drawing_process_dies_with_its_parent_and_releases_the_lock(tmp_path, sig):
    out = tmp_path / "out"
    out.mkdir()
    proc = subprocess.Popen([sys.executable, "-c", SCRIPT, str(out)], stdout=subprocess.PIPE, text=True)
    child = 0
    try:
        child = int(proc.stdout.readline())
        if child == 0:
            pytest.skip("no drawing process here (one CPU or no fork)")
        assert proc.stdout.readline().strip() == "busy"
        time.sleep(0.2)
        proc.send_signal(sig)
        proc.wait(timeout=30)
        deadline = time.monotonic() + 10
        while _alive(child) and time.monotonic() < deadline:
            time.sleep(0.05)
        assert not _alive(child), "the drawing process outlived its parent"
        fd = os.open(out, os.O_RDONLY | os.O_DIRECTORY)
        try:
            while True:                  # the lock went with them (the kernel may release it a moment later)
                try:
                    fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
                    break
                except OSError as exc:
                    if exc.errno not in (errno.EWOULDBLOCK, errno.EAGAIN) or time.monotonic() > deadline:
                        raise AssertionError(f"OUT is still locked: {exc}") from None
                    time.sleep(0.05)
        finally:
            os.close(fd)
    finally:
        if proc.poll() is None:
            proc.kill()
        if child and _alive(child):
            os.kill(child, signal.SIGKILL)
