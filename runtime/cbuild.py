"""Build and load the small C kernels from trusted places only (infrastructure).

Where a library comes from, in this order (``docs/design/kernel.md``, "Where compiled code comes from"):

1. **Built when the package was installed.**  ``pip install`` (also editable) compiles every kernel
   next to this module, as ``_ck_<name>_<key>.so`` with ``<file>.sha256`` beside it
   (``setup.py``: an optional build step -- without a compiler the install still succeeds).
   It is loaded only if the folder and the file belong to the current user or root and are not
   writable by group or others, and the file's SHA-256 is the one recorded beside it.
2. **Built on first use into a private per-user cache** (``$SWARMFIELD_CACHE``, else
   ``$XDG_CACHE_HOME`` or ``~/.cache``, under ``swarmfield``), when there is no installed library
   for this source (an editable install whose C source changed).  The folder is created ``0700``
   whatever the umask; each library sits in its own entry ``<name>_<key>/`` with ``lib.so`` and
   ``lib.sha256``, built in a ``mkdtemp`` folder and renamed into place as a whole.  Before loading,
   folder, entry and files must belong to the current user, not be writable by group or others, and
   the library's SHA-256 must be the recorded one; a damaged entry (a truncated file) is rebuilt, a
   cache folder that fails the checks is not used: the library is built into a fresh private
   temporary folder instead, loaded and removed -- one line on stderr either way.  There is no shared
   or predictable fallback path.

The checked bytes are the loaded bytes: the file is opened once (``O_NOFOLLOW``), checked through
that descriptor and loaded as ``/proc/self/fd/N`` where the platform has it, so nothing can be
swapped in between (the descriptor stays open).  ``<key>`` is a hash of the source, the flags, the platform and -- with
``-march=native``, tried first where the CPU can be identified -- the CPU; a fresh build is
smoke-tested in a child process (an instruction the CPU lacks kills the child, not the caller).
:class:`CLibrary` loads lazily and remembers a failure: ``lib()`` is the ``ctypes.CDLL`` or None,
``error`` says why, ``warn_fallback()`` prints one line on stderr once per process.
``SWARMFIELD_NO_CKERNELS=1`` disables them (NumPy everywhere, no message).  Nothing here is needed to
run the package: without a library the callers use their NumPy code.

This module uses the standard library only: ``setup.py`` loads it to build the installed kernels.
"""
from __future__ import annotations

import ctypes
import hashlib
import os
import platform
import shutil
import stat
import subprocess
import sys
import sysconfig
import tempfile
from pathlib import Path

__all__ = ["CLibrary", "cache_dir", "CFLAGS", "library_keys", "build_library", "installed_name", "Untrusted"]

#: no contraction, no reassociation: every operation is rounded as written (so a C loop can reproduce
#: NumPy's results bit for bit where it does the same operations in the same order)
CFLAGS = ("-O3", "-fPIC", "-shared", "-fno-fast-math", "-fno-trapping-math", "-fno-math-errno", "-ffp-contract=off")
NATIVE_FLAGS = ("-march=native",)

#: where the install step puts the libraries (this module's folder); None: do not look there
INSTALLED_DIR: Path | None = Path(__file__).resolve().parent

_NOFOLLOW = getattr(os, "O_NOFOLLOW", 0)
_DIRECTORY = getattr(os, "O_DIRECTORY", 0)
_CLOEXEC = getattr(os, "O_CLOEXEC", 0)


class Untrusted(Exception):
    """A library or folder failed the owner, mode or hash check (the message says which, on one line)."""


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


def library_keys(source: str) -> list:
    """``[(key, flags), ...]`` to try in order: the native build (where the CPU is identified and
    ``SWARMFIELD_KERNEL_NATIVE`` is not 0), then the generic one."""
    cpu = _cpu_id() if os.environ.get("SWARMFIELD_KERNEL_NATIVE", "1") != "0" else None
    out = []
    for native in ([True] if cpu else []) + [False]:
        text = source + " ".join(CFLAGS) + platform.machine() + sys.platform + (" native " + cpu if native else "")
        out.append((hashlib.sha256(text.encode()).hexdigest()[:16], CFLAGS + (NATIVE_FLAGS if native else ())))
    return out


def installed_name(name: str, key: str) -> str:
    """File name of an install-time library (in :data:`INSTALLED_DIR`)."""
    return f"_ck_{name}_{key}.so"


# ------------------------------------------------------------------------------ checks
def _euid() -> int | None:
    return os.geteuid() if hasattr(os, "geteuid") else None


def _check_stat(st, what: str, allow_root: bool) -> None:
    euid = _euid()
    if euid is None:
        return
    owners = {euid, 0} if allow_root else {euid}
    if st.st_uid not in owners:
        raise Untrusted(f"{what} belongs to another user (uid {st.st_uid})")
    if st.st_mode & 0o022:
        raise Untrusted(f"{what} is writable by group or others (mode {stat.S_IMODE(st.st_mode):o})")


def _open_dir(path: Path, allow_root: bool) -> int:
    fd = os.open(path, os.O_RDONLY | _DIRECTORY | _NOFOLLOW | _CLOEXEC)
    try:
        st = os.fstat(fd)
        if not stat.S_ISDIR(st.st_mode):
            raise Untrusted(f"{path} is not a folder")
        _check_stat(st, f"folder {path}", allow_root)
    except BaseException:
        os.close(fd)
        raise
    return fd


def _read_checked(dir_fd: int, name: str, where: Path, allow_root: bool) -> tuple:
    """``(fd, bytes)`` of the regular file ``name`` in the open folder, after the owner/mode check."""
    try:
        fd = os.open(name, os.O_RDONLY | _NOFOLLOW | _CLOEXEC, dir_fd=dir_fd)
    except OSError as exc:
        if exc.errno == getattr(__import__("errno"), "ELOOP", -1):
            raise Untrusted(f"{where / name} is a symbolic link") from None
        raise
    try:
        st = os.fstat(fd)
        if not stat.S_ISREG(st.st_mode):
            raise Untrusted(f"{where / name} is not a regular file")
        _check_stat(st, str(where / name), allow_root)
        chunks = []
        while True:
            b = os.read(fd, 1 << 20)
            if not b:
                break
            chunks.append(b)
    except BaseException:
        os.close(fd)
        raise
    return fd, b"".join(chunks)


def _open_verified(folder: Path, lib_name: str, hash_name: str, allow_root: bool) -> int:
    """An open descriptor of ``folder/lib_name`` whose folder and file passed the owner/mode checks and
    whose SHA-256 equals the one in ``folder/hash_name``.  ``FileNotFoundError`` if either file is
    missing, :class:`Untrusted` if a check fails."""
    dfd = _open_dir(folder, allow_root)
    try:
        hfd, recorded = _read_checked(dfd, hash_name, folder, allow_root)
        os.close(hfd)
        fd, data = _read_checked(dfd, lib_name, folder, allow_root)
    finally:
        os.close(dfd)
    if hashlib.sha256(data).hexdigest() != recorded.decode("ascii", "replace").strip():
        os.close(fd)
        raise Untrusted(f"{folder / lib_name} does not match its recorded SHA-256 (damaged or replaced)")
    return fd


def _load_fd(fd: int, path: Path):
    """``ctypes.CDLL`` of the file open as ``fd`` (the checked bytes themselves where /proc exists).

    The descriptor stays open for the life of the process: the dynamic loader knows a library by its
    name, so ``/proc/self/fd/N`` must never name a second library."""
    proc = f"/proc/self/fd/{fd}"
    if os.path.exists(proc):
        try:
            return ctypes.CDLL(proc)
        except BaseException:
            os.close(fd)
            raise
    os.close(fd)
    return ctypes.CDLL(str(path))


def _make_private_dir(path: Path) -> None:
    """Create ``path`` (and missing parents) with mode 0700 whatever the umask."""
    missing = []
    p = path
    while not p.exists() and not p.is_symlink():
        missing.append(p)
        if p.parent == p:
            break
        p = p.parent
    for p in reversed(missing):
        try:
            os.mkdir(p, 0o700)
        except FileExistsError:
            continue
        os.chmod(p, 0o700)


# ------------------------------------------------------------------------------ building
def _smoke_ok(smoke: str, path, python: str | None = None) -> bool:
    try:
        res = subprocess.run([python or sys.executable, "-c", smoke, str(path)], capture_output=True, timeout=60)
    except (OSError, subprocess.SubprocessError):
        return False
    return res.returncode == 0


def build_library(source: str, name: str, folder: Path, attempts, smoke: str | None, cc: str | None = None) -> tuple:
    """Compile ``source`` into ``folder/lib.so`` (mode 0700) and write its SHA-256 to
    ``folder/lib.sha256``; tries each ``(key, flags)`` of ``attempts`` until one compiles and passes
    the smoke test.  Returns ``(key, path)``; ``RuntimeError`` on failure."""
    cc = cc or _compiler()
    if cc is None:
        raise RuntimeError("no C compiler found (cc, gcc, clang or $CC)")
    folder = Path(folder)
    src = folder / f"{name}.c"
    src.write_text(source)
    out = folder / "lib.so"
    msg = "no build attempted"
    for key, flags in attempts:                  # native first (if any), the generic build otherwise
        try:
            res = subprocess.run([cc, *flags, str(src), "-o", str(out), "-lm"], capture_output=True,
                                 text=True, timeout=120)
        except (OSError, subprocess.SubprocessError) as exc:
            msg = f"{cc} failed: {exc}"
            continue
        if res.returncode != 0:
            lines = (res.stderr or res.stdout).strip().splitlines()
            msg = f"{cc} failed: {lines[-1]}" if lines else f"{cc} failed (exit code {res.returncode}, no output)"
            continue
        os.chmod(out, 0o700)
        if smoke is not None and not _smoke_ok(smoke, out):
            msg = f"{cc} built {name}, but its smoke test failed"
            continue
        (folder / "lib.sha256").write_text(hashlib.sha256(out.read_bytes()).hexdigest() + "\n")
        os.chmod(folder / "lib.sha256", 0o600)
        src.unlink()
        return key, out
    raise RuntimeError(msg)


class CLibrary:
    """A C source compiled at install time or on first use.  ``name`` names the library file;
    ``declare(lib)`` sets the ctypes signatures; ``smoke`` is Python source run in a child with the
    library path as ``sys.argv[1]`` (exit status 0 = usable); ``what`` is how the one-line fallback
    message names the library."""

    def __init__(self, name: str, source: str, declare, smoke: str, what: str):
        self.name, self.source, self.declare, self.smoke, self.what = name, source, declare, smoke, what
        self._lib = None
        self.error: str | None = None
        self.origin: str | None = None           # "installed", "cache" or "private" once loaded

    def lib(self):
        """The loaded ``ctypes.CDLL``, or None (and :attr:`error` set) if it cannot be built or loaded."""
        if self._lib is not None or self.error is not None:
            return self._lib
        if os.environ.get("SWARMFIELD_NO_CKERNELS", "0") not in ("", "0"):
            self.error = "disabled by SWARMFIELD_NO_CKERNELS"
            CLibrary._warned_any = True            # asked for: no message
            return None
        try:
            lib = self._find()
            self.declare(lib)
            self._lib = lib
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

    def _note(self, text: str) -> None:
        print(f"swarmfield: {self.what}: {text}", file=sys.stderr)

    # -------------------------------------------------------------- where the library comes from
    def _find(self):
        keys = library_keys(self.source)
        if INSTALLED_DIR is not None:
            for key, _ in keys:
                fname = installed_name(self.name, key)
                try:
                    fd = _open_verified(INSTALLED_DIR, fname, fname + ".sha256", allow_root=True)
                except FileNotFoundError:
                    continue
                except Untrusted as exc:
                    self._note(f"installed library not loaded: {exc}")
                    break
                self.origin = "installed"
                return _load_fd(fd, INSTALLED_DIR / fname)
        return self._from_cache(keys)

    def _from_cache(self, keys):
        folder = cache_dir()
        try:
            folder = folder.resolve()
            _make_private_dir(folder)
            st = os.lstat(folder)
            if stat.S_ISDIR(st.st_mode) and st.st_uid == _euid() and st.st_mode & 0o077:
                os.chmod(folder, 0o700)                 # our own cache made under a lax umask: close it
            os.close(_open_dir(folder, allow_root=False))
            if not os.access(folder, os.W_OK | os.X_OK):
                raise Untrusted(f"folder {folder} is not writable")
        except (OSError, Untrusted) as exc:
            self._note(f"kernel cache not used ({exc}); building into a private temporary folder")
            return self._build_private(keys)
        for key, _ in keys:                             # an existing, intact entry of ours
            entry = folder / f"{self.name}_{key}"
            if not (entry.exists() or entry.is_symlink()):
                continue
            try:
                fd = _open_verified(entry, "lib.so", "lib.sha256", allow_root=False)
            except (OSError, Untrusted) as exc:
                self._note(f"cached library not loaded ({exc}); rebuilding it")
                self._discard(folder, entry)
                break
            self.origin = "cache"
            return _load_fd(fd, entry / "lib.so")
        tmp = Path(tempfile.mkdtemp(prefix=f".{self.name}-build-", dir=folder))
        try:
            key, _ = build_library(self.source, self.name, tmp, keys, self.smoke)
            entry = folder / f"{self.name}_{key}"
            try:
                os.rename(tmp, entry)                   # the whole entry appears at once
                where = entry
            except OSError:                             # another process was first: use our own copy
                where = tmp
            fd = _open_verified(where, "lib.so", "lib.sha256", allow_root=False)
            self.origin = "cache"
            return _load_fd(fd, where / "lib.so")
        finally:
            if tmp.exists():
                shutil.rmtree(tmp, ignore_errors=True)

    @staticmethod
    def _discard(folder: Path, entry: Path) -> None:
        """Move a damaged entry of ours aside and delete it (a symbolic link is only unlinked)."""
        try:
            if entry.is_symlink() or not entry.is_dir():
                entry.unlink()
                return
            trash = Path(tempfile.mkdtemp(prefix=".discard-", dir=folder))
            os.rename(entry, trash / "old")
            shutil.rmtree(trash, ignore_errors=True)
        except OSError:
            pass

    def _build_private(self, keys):
        tmp = Path(tempfile.mkdtemp(prefix=f"swarmfield-{self.name}-"))     # 0700, unpredictable name
        try:
            build_library(self.source, self.name, tmp, keys, self.smoke)
            fd = _open_verified(tmp, "lib.so", "lib.sha256", allow_root=False)
            self.origin = "private"
            return _load_fd(fd, tmp / "lib.so")          # loaded: the files can go
        finally:
            shutil.rmtree(tmp, ignore_errors=True)
