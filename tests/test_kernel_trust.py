"""Compiled kernels come from trusted places only (runtime.cbuild): a library planted by another user,
a cache made under a lax umask, a damaged (truncated) cached library or a tampered installed one is
never loaded; the run goes on with one line on stderr."""
import hashlib
import os
import shutil
import stat
import subprocess
import sys
import tempfile
from pathlib import Path

import pytest

from swarmfield.runtime import cbuild

needs_cc = pytest.mark.skipif(cbuild._compiler() is None, reason="no C compiler")

#: the victim: loads the (small) GP power-sums kernel from the cache (never from the install folder)
VICTIM = (
    "from swarmfield.runtime import cbuild\n"
    "cbuild.INSTALLED_DIR = None\n"
    "from swarmfield.regression import power_sums_kernel as K\n"
    "lib = K._LIB.lib()\n"
    "print(lib is not None, getattr(K._LIB, 'origin', None), K._LIB.error)\n")

EVIL = r"""
#include <stdio.h>
__attribute__((constructor)) static void planted(void) {
    FILE *f = fopen(MARKER, "w");
    if (f) { fputs("loaded", f); fclose(f); }
}
int sf_power_sums(void) { return 0; }
"""


def _victim(cache, umask=None):
    env = dict(os.environ, SWARMFIELD_CACHE=str(cache), SWARMFIELD_NO_CKERNELS="0")
    pre = (lambda: os.umask(umask)) if umask is not None else None
    return subprocess.run([sys.executable, "-c", VICTIM], capture_output=True, text=True, env=env, timeout=300,
                          preexec_fn=pre)


def _files(root: Path):
    return sorted(p.relative_to(root) for p in root.rglob("*") if p.is_file())


@needs_cc
@pytest.mark.skipif(not hasattr(os, "geteuid") or os.geteuid() != 0 or shutil.which("setpriv") is None,
                    reason="a second user can only be played as root with setpriv")
def test_a_library_planted_by_another_user_is_never_loaded(tmp_path):
    # what the victim's cache looks like: the names an attacker has to plant
    ref = tmp_path / "ref"
    res = _victim(ref)
    assert res.returncode == 0 and res.stdout.startswith("True"), res.stderr
    names = _files(ref)
    assert names
    base = Path(tempfile.mkdtemp(prefix="sf-attack-"))
    try:
        os.chmod(base, 0o1777)                  # a shared place like /tmp: anyone may create folders
        marker = base / "planted-code-ran"
        plant = base / "plant"
        plant.mkdir()
        src = plant / "evil.c"
        src.write_text(EVIL)
        evil = base / "evil.so"
        subprocess.run([cbuild._compiler(), "-shared", "-fPIC", f'-DMARKER="{marker}"', str(src), "-o", str(evil)],
                       check=True, capture_output=True)
        src.unlink()
        data = evil.read_bytes()
        for rel in names:                       # the same layout, the attacker's code, matching hashes
            p = plant / rel
            p.parent.mkdir(parents=True, exist_ok=True)
            p.write_bytes(hashlib.sha256(data).hexdigest().encode() + b"\n" if p.suffix == ".sha256" else data)
        for p in [plant, *plant.rglob("*")]:
            os.chmod(p, 0o755 if p.is_dir() or p.suffix == ".so" else 0o644)
        attacker = ["setpriv", "--reuid=4242", "--regid=4242", "--clear-groups"]
        cache = base / "cache"
        subprocess.run(attacker + ["sh", "-c", f"cp -r '{plant}' '{cache}' && chmod -R go-w '{cache}'"],
                       check=True, capture_output=True)
        assert cache.stat().st_uid == 4242
        res = _victim(cache)
        assert not marker.exists(), "the planted library was loaded"
        assert res.returncode == 0, res.stderr
        assert res.stdout.split()[:2] == ["True", "private"], res.stdout      # built afresh, privately
        lines = res.stderr.strip().splitlines()
        assert len(lines) == 1 and "belongs to another user" in lines[0], res.stderr
        # the attacker's folder is left as it was
        assert _files(cache) == names
    finally:
        shutil.rmtree(base, ignore_errors=True)


@needs_cc
def test_cache_is_private_whatever_the_umask_and_no_shared_fallback(tmp_path):
    cache = tmp_path / "deep" / "cache"
    res = _victim(cache, umask=0)
    assert res.returncode == 0 and res.stdout.startswith("True"), res.stderr
    for p in [tmp_path / "deep", cache, *cache.rglob("*")]:
        assert stat.S_IMODE(p.stat().st_mode) & 0o077 == 0, (p, oct(p.stat().st_mode))
    # an unusable cache: a private temporary build, never the predictable /tmp/swarmfield-<uid>
    shared = Path(tempfile.gettempdir()) / f"swarmfield-{os.getuid()}"
    existed = shared.exists()
    blocker = tmp_path / "file"
    blocker.write_text("not a folder")
    res = _victim(blocker / "cache")
    assert res.returncode == 0 and res.stdout.split()[:2] == ["True", "private"], (res.stdout, res.stderr)
    assert "private temporary folder" in res.stderr and res.stderr.count("\n") == 1
    assert shared.exists() == existed


@needs_cc
def test_a_truncated_cached_library_is_rebuilt_with_one_line(tmp_path):
    cache = tmp_path / "cache"
    assert _victim(cache).returncode == 0
    libs = [p for p in cache.rglob("*.so")]
    assert libs
    for p in libs:
        p.write_bytes(p.read_bytes()[: p.stat().st_size // 3])
    res = _victim(cache)
    assert res.returncode == 0, (res.returncode, res.stderr)            # never SIGBUS
    assert res.stdout.startswith("True"), res.stdout
    lines = res.stderr.strip().splitlines()
    assert len(lines) == 1 and "rebuilding" in lines[0], res.stderr
    assert len(list(cache.rglob("*.so"))) == len(libs)                    # rebuilt in place, nothing left over


@needs_cc
def test_a_tampered_installed_library_is_refused(tmp_path, monkeypatch, capsys):
    from swarmfield.regression import power_sums_kernel as K
    keys = cbuild.library_keys(K.C_SOURCE)
    inst = tmp_path / "inst"
    inst.mkdir()
    key, lib = cbuild.build_library(K.C_SOURCE, "powersums", tmp_path / "inst", keys, None)
    name = cbuild.installed_name("powersums", keys[0][0])
    os.replace(lib, inst / name)
    (inst / (name + ".sha256")).write_text("0" * 64 + "\n")              # not this library's hash
    monkeypatch.setattr(cbuild, "INSTALLED_DIR", inst)
    monkeypatch.setenv("SWARMFIELD_CACHE", str(tmp_path / "cache"))
    fresh = cbuild.CLibrary("powersums", K.C_SOURCE, K._declare, K._SMOKE, "power sums")
    assert fresh.lib() is not None and fresh.origin == "cache"
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "recorded SHA-256" in err[0]
    # with the right hash (and private modes) the installed library is the one used
    (inst / (name + ".sha256")).write_text(hashlib.sha256((inst / name).read_bytes()).hexdigest() + "\n")
    again = cbuild.CLibrary("powersums", K.C_SOURCE, K._declare, K._SMOKE, "power sums")
    assert again.lib() is not None and again.origin == "installed"
    os.chmod(inst / name, 0o777)                                          # writable by anyone: refused
    third = cbuild.CLibrary("powersums", K.C_SOURCE, K._declare, K._SMOKE, "power sums")
    assert third.lib() is not None and third.origin == "cache"
    assert "writable by group or others" in capsys.readouterr().err
