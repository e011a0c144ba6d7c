"""Build and load a small C library with the system compiler, once per source hash (infrastructure).

The same recipe as the planner's transport kernel (:mod:`ocp.kernel`): the source is compiled with
``cc`` (or ``$CC``) into a per-user cache folder (``$SWARMFIELD_CACHE``, else ``$XDG_CACHE_HOME`` or
``~/.cache``, under ``swarmfield``; a per-user temporary folder if that is read-only), under a file name
keyed by a hash of the source, the flags, the platform and -- with ``-march=native``, tried first where
the CPU can be identified -- the CPU; the fresh library is smoke-tested in a child process (an
instruction the CPU lacks kills the child, not the caller) and moved into place atomically, so
concurrent processes never load half a file.  :class:`CLibrary` loads lazily and remembers a failure:
``lib()`` is the ``ctypes.CDLL`` or None, ``error`` says why, ``warn_fallback()`` prints one line on
stderr once per process.  ``SWARMFIELD_NO_CKERNELS=1`` disables them (NumPy everywhere, no message).  Nothing here is needed to install the package: without a compiler the
callers use their NumPy code.
"""
from __future__ import annotations

import ctypes
import hashlib
import os
import platform
import shutil
import subprocess
import sys
import sysconfig
import tempfile
from pathlib import Path

__all__ = ["CLibrary", "cache_dir", "CFLAGS"]

#: no contraction, no reassociation: every operation is rounded as written (so a C loop can reproduce
#: NumPy's results bit for bit where it does the same operations in the same order)
CFLAGS = ("-O3", "-fPIC", "-shared", "-fno-fast-math", "-fno-trapping-math", "-fno-math-errno", "-ffp-contract=off")
NATIVE_FLAGS = ("-march=native",)


def cache_dir() -> Path:
    """Per-user cache folder of compiled kernels ($SWARMFIELD_CACHE, else $XDG_CACHE_HOME or ~/.cache)."""
    env = os.environ.get("SWARMFIELD_CACHE")
    if env:
        return Path(env)
    base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    return Path(base) / "swarmfield"


def _compiler() -> str | None:
    cc = os.environ.get("CC") or sysconfig.get_config_var("CC") or "cc"
    exe = cc.split()[0] if cc else "cc"
    if shutil.which(exe):
        return exe
    return shutil.which("cc") or shutil.which("gcc") or shutil.which("clang")


def _cpu_id() -> str | None:
    try:
        with open("/proc/cpuinfo", encoding="utf-8", errors="replace") as fh:
            lines = fh.read().splitlines()
    except OSError:
        return None
    keep = [ln.split(":", 1)[1].strip() for ln in lines
            if ln.split(":", 1)[0].strip() in ("model name", "flags", "Features", "CPU part", "CPU implementer")]
    return "|".join(dict.fromkeys(keep)) or None


class CLibrary:
    """A C source compiled on first use.  ``name`` names the cached file; ``declare(lib)`` sets the
    ctypes signatures; ``smoke`` is Python source run in a child with the library path as ``sys.argv[1]``
    (exit status 0 = usable); ``what`` is how the one-line fallback message names the library."""

    def __init__(self, name: str, source: str, declare, smoke: str, what: str):
        self.name, self.source, self.declare, self.smoke, self.what = name, source, declare, smoke, what
        self._lib = None
        self.error: str | None = None
        self._warned = False

    def lib(self):
        """The loaded ``ctypes.CDLL``, or None (and :attr:`error` set) if it cannot be built or loaded."""
        if self._lib is not None or self.error is not None:
            return self._lib
        if os.environ.get("SWARMFIELD_NO_CKERNELS", "0") not in ("", "0"):
            self.error = "disabled by SWARMFIELD_NO_CKERNELS"
            CLibrary._warned_any = True            # asked for: no message
            return None
        try:
            self._lib = self._build()
        except Exception as exc:                           # noqa: BLE001 - any failure means: use NumPy
            self.error = str(exc) or type(exc).__name__
        return self._lib

    def available(self) -> bool:
        return self.lib() is not None

    _warned_any = False

    def warn_fallback(self) -> None:
        """One line on stderr, once per process (for all libraries), when the library is not available."""
        if not CLibrary._warned_any and self.error is not None:
            CLibrary._warned_any = True
            print(f"swarmfield: compiled {self.what} unavailable ({self.error}); using NumPy (slower; "
                  "set SWARMFIELD_NO_CKERNELS=1 to silence)", file=sys.stderr)

    def _smoke_ok(self, path) -> bool:
        try:
            res = subprocess.run([sys.executable, "-c", self.smoke, str(path)], capture_output=True, timeout=60)
        except (OSError, subprocess.SubprocessError):
            return False
        return res.returncode == 0

    def _build(self):
        cc = _compiler()
        if cc is None:
            raise RuntimeError("no C compiler found (cc, gcc, clang or $CC)")
        cpu = _cpu_id() if os.environ.get("SWARMFIELD_KERNEL_NATIVE", "1") != "0" else None
        attempts = ([CFLAGS + NATIVE_FLAGS] if cpu else []) + [CFLAGS]
        key = hashlib.sha256((self.source + " ".join(CFLAGS) + platform.machine() + sys.platform
                              + (" native " + cpu if cpu else "")).encode()).hexdigest()[:16]
        folder = cache_dir()
        try:
            folder.mkdir(parents=True, exist_ok=True)
            if not os.access(folder, os.W_OK):
                raise PermissionError(str(folder))
        except OSError:
            folder = Path(tempfile.gettempdir()) / f"swarmfield-{os.getuid() if hasattr(os, 'getuid') else 'user'}"
            folder.mkdir(parents=True, exist_ok=True)
        lib_path = folder / f"{self.name}_{key}.so"
        if not lib_path.exists():
            with tempfile.TemporaryDirectory(dir=folder) as tmp:
                src = Path(tmp) / f"{self.name}.c"
                src.write_text(self.source)
                out = Path(tmp) / f"{self.name}.so"
                res = None
                for flags in attempts:                  # native first (if any), the generic build otherwise
                    res = subprocess.run([cc, *flags, str(src), "-o", str(out), "-lm"], capture_output=True,
                                         text=True, timeout=120)
                    if res.returncode == 0 and self._smoke_ok(out):
                        break
                    res = res if res.returncode != 0 else subprocess.CompletedProcess(res.args, 1, "", "smoke test failed")
                if res is None or res.returncode != 0:
                    msg = (res.stderr or res.stdout).strip().splitlines()[-1:] if res is not None else []
                    raise RuntimeError(f"{cc} failed: {msg}")
                os.replace(out, lib_path)
        lib = ctypes.CDLL(str(lib_path))
        self.declare(lib)
        return lib
