"""Publishing a command's outputs as one unit (``plan-reference``, ``solver-study``, ``simulate-swarm``,
``compare-controllers``).

Every output is first written somewhere the user does not look (a temporary file beside its
destination, or a private staging folder), and only when *all* of a run's outputs exist are they
*published*: moved into place by renames, in a section where SIGINT and SIGTERM are deferred
(:func:`deferred_signals`; they are delivered right after it).  So

* an interrupted, failed or crashed run leaves the previous outputs exactly as they were (the
  new ones were never renamed into place), and a finished run leaves a complete set;
* a disk-full or other write error happens while staging, never half-way through publication.

Two forms:

:func:`publish_files`
    a few single files in any folders (``plan-reference --out p.npz --plot p.png``): each is
    written to a temporary file beside its destination, then all are renamed together.

:class:`OutputFolder`
    a folder of outputs (``simulate-swarm --out DIR``, ``solver-study --out DIR``):

    * **lock** — a run holds an exclusive ``flock`` on DIR itself from before its first write to
      after publication; a second run into the same DIR is refused at once with one line
      (:class:`FolderBusy`), so two runs never mix.
    * **staging** — each run writes into its own new folder ``DIR/.<program>-stage-XXXXXXXX``
      (``mkdtemp``); a folder of that pattern holding the tag file :data:`STAGE_TAG` is provably
      ours.
    * **manifest** — ``DIR/.<program>`` (JSON) lists the files the published run wrote with
      their inode, size and modification time.  A later run removes a file it does not rewrite
      only if it is named there *and* still is that very file; nothing else in DIR is ever
      deleted (a user's own files, or files of the same name the user replaced, stay).
    * **journal** — publication first writes ``DIR/.<program>-publishing`` (the stage, the files
      to move, the stale files to remove, the new manifest), then performs it, then removes the
      journal.  If the process dies inside that window (SIGKILL, power loss: a few renames), the
      next run into DIR finds the journal and completes the publication before starting.
    * **set aside** — the staged files of a run that did not finish (interrupt, error, a planner
      failure when DIR holds a complete run) are kept in ``DIR/.<program>-incomplete`` (replacing
      an older one of ours), never in place of a published run.

Single-file writes (:mod:`runtime.atomic`) stay atomic on their own.
"""
from __future__ import annotations

import errno
import fcntl
import json
import os
import shutil
import signal
import tempfile
import threading
from contextlib import contextmanager
from pathlib import Path

from .atomic import FILE_MODE, write_atomic

STAGE_TAG = ".swarmfield-stage"
DEFERRED = (signal.SIGINT, signal.SIGTERM)


class FolderBusy(ValueError):
    """Another run holds the output folder's lock."""


class InterruptedAfterPublish(KeyboardInterrupt):
    """Ctrl-C arrived while the outputs were being published; the publication was completed first."""


# ------------------------------------------------------------------------------ signals
@contextmanager
def deferred_signals(signums=DEFERRED):
    """Hold SIGINT/SIGTERM back during the block and deliver them (in arrival order, first one
    only) when it ends.  A signal that is ignored (``SIG_IGN``, e.g. SIGINT of a background job)
    stays ignored.  Outside the main thread, handlers cannot be installed and nothing changes."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    pending, previous = [], {}
    for s in signums:
        old = signal.getsignal(s)
        if old in (signal.SIG_IGN, None):
            continue
        previous[s] = old
        signal.signal(s, lambda signum, frame: pending.append(signum))
    try:
        yield
    finally:
        for s, old in previous.items():
            signal.signal(s, old)
        if pending:
            signal.raise_signal(pending[0])


def _commit(action):
    """Run ``action`` with signals deferred; a Ctrl-C that arrived meanwhile is re-raised as
    :class:`InterruptedAfterPublish`, so that a CLI can report truthfully that the outputs are new."""
    try:
        with deferred_signals():
            result = action()
    except KeyboardInterrupt as exc:
        after = InterruptedAfterPublish()
        after.signum = getattr(exc, "signum", signal.SIGINT)       # SIGTERM (runtime.signals.Terminated): 143
        raise after from None
    return result


# ------------------------------------------------------------------------------ single files
@contextmanager
def staged_files(paths):
    """Yield ``{final path: temporary path}`` for the given destinations (temporary files beside
    them, so that the renames stay on one file system); on normal exit all of them are renamed
    into place together (:func:`publish_files`); on an exception none is, and the temporaries go."""
    tmps = _Staged()
    try:
        for p in paths:
            p = Path(p)
            fd, tmp = tempfile.mkstemp(prefix=f".{p.name}.", suffix=".tmp" + p.suffix, dir=p.parent)
            os.close(fd)
            tmps[p] = Path(tmp)
        yield tmps
        publish_files(tmps)
    finally:
        for tmp in tmps.values():
            try:
                tmp.unlink()
            except FileNotFoundError:
                pass


class _Staged(dict):
    """``{final: temporary}``; ``published`` turns true once the renames are done (so that an
    interrupt arriving afterwards can be reported as "after writing")."""
    published = False


def publish_files(tmps: dict) -> None:
    """Rename every temporary file over its destination, all inside one signal-deferred section."""
    def rename_all():
        for final, tmp in tmps.items():
            os.chmod(tmp, FILE_MODE)
        for final, tmp in tmps.items():
            os.replace(tmp, final)
        if isinstance(tmps, _Staged):
            tmps.published = True
    _commit(rename_all)


# ------------------------------------------------------------------------------ folders
def _signature(path: Path):
    st = path.stat()
    return [st.st_ino, st.st_size, st.st_mtime_ns]


class OutputFolder:
    """A folder of outputs of ``program`` with lock, staging, manifest and journal (module docstring).

    ``outputs`` are the only names the program ever writes into the folder (relative paths; a name
    may lie in a subfolder, e.g. ``plots/a.png``, created at publication).  ``foreign_ok``:
    a non-empty folder without a manifest is accepted (``solver-study`` writes beside other
    files, e.g. into ``docs/figures``); otherwise such a folder needs ``force``.
    """

    def __init__(self, path, program: str, outputs, *, force: bool = False, foreign_ok: bool = False,
                 folders=()):
        self.path = Path(path)
        self.program = program
        self.outputs = tuple(outputs)
        for name in self.outputs:
            parts = Path(name).parts
            if not parts or Path(name).is_absolute() or any(p in ("..", ".") for p in parts):
                raise ValueError(f"output name {name!r} would leave the output folder")
        #: the subfolders the program writes into (those of the outputs, and e.g. ``runs``)
        self.folders = tuple(dict.fromkeys([*folders, *(str(Path(n).parent) for n in self.outputs
                                                        if len(Path(n).parts) > 1)]))
        self.force = force
        self.foreign_ok = foreign_ok
        self.marker = self.path / f".{program}"
        self.journal = self.path / f".{program}-publishing"
        self.incomplete = self.path / f".{program}-incomplete"
        self.stage_prefix = f".{program}-stage-"
        self._fd = None

    # -------------------------------------------------------------- checks (no writes)
    def check(self) -> None:
        """``ValueError`` if the folder cannot be used; touches nothing."""
        path = self.path
        if path.exists() and not path.is_dir():
            raise ValueError(f"output {path} exists and is not a folder")
        if path.is_dir():
            # this program's own hidden entries (manifest, journal, stages of a running or killed run,
            # set-aside files) do not make the folder foreign
            entries = [p for p in path.iterdir() if not p.name.startswith(f".{self.program}")]
            if entries and not self.marker.exists() and not (self.force or self.foreign_ok):
                raise ValueError(f"output folder {path} is not empty and holds no previous {self.program} run; "
                                 "choose another --out or pass --force")
            if entries and not self.marker.exists() and not self.force:
                # beside other files, but not over files of the same names that this program did not write
                clash = [n for n in self.outputs if (path / n).is_file()]
                if clash:
                    raise ValueError(f"output folder {path} holds {', '.join(clash[:3])}"
                                     f"{' ...' if len(clash) > 3 else ''}, which no previous {self.program} run "
                                     "wrote and this one would replace; choose another --out or pass --force")
            if not os.access(path, os.W_OK | os.X_OK):
                raise ValueError(f"output folder {path} is not writable")
            for sub in self.folders:                 # never followed out of the folder
                for p in [path.joinpath(*Path(sub).parts[:k]) for k in range(1, len(Path(sub).parts) + 1)]:
                    if p.is_symlink():
                        raise ValueError(f"{p} is a symbolic link; the run writes into a folder of that name "
                                         "inside the output folder: remove the link or choose another --out")
                    if p.exists() and not p.is_dir():
                        raise ValueError(f"{p} is not a folder; the run writes into a folder of that name")
            for name in self.outputs + (self.marker.name, self.journal.name):
                if (path / name).is_dir() and not (path / name).is_symlink():
                    raise ValueError(f"{path / name} is a folder; the run writes a file of that name")
        else:
            parent = path.parent
            while not parent.exists():
                parent = parent.parent
            if not parent.is_dir() or not os.access(parent, os.W_OK | os.X_OK):
                raise ValueError(f"cannot create output folder {path}: {parent} is not a writable folder")

    def holds_complete_run(self) -> bool:
        return bool(self._manifest().get("complete", False))

    def _manifest(self) -> dict:
        try:
            doc = json.loads(self.marker.read_text())
        except (OSError, ValueError, UnicodeDecodeError):
            return {}
        return doc if isinstance(doc, dict) else {}

    # -------------------------------------------------------------- lock
    def lock(self) -> None:
        """Create the folder if needed and take its exclusive lock; :class:`FolderBusy` if another
        run holds it.  Completes a publication that a killed run left half-done, removes its stages."""
        try:
            self.path.mkdir(parents=True, exist_ok=True)
            fd = os.open(self.path, os.O_RDONLY | os.O_DIRECTORY)
        except OSError as exc:
            raise ValueError(f"cannot write to output folder {self.path}: {exc.strerror or exc}") from None
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError as exc:
            os.close(fd)
            if exc.errno in (errno.EWOULDBLOCK, errno.EAGAIN, errno.EACCES):
                raise FolderBusy(f"another {self.program} run is writing to {self.path}; wait for it to finish "
                                 "or choose another --out") from None
            raise ValueError(f"cannot lock output folder {self.path}: {exc.strerror or exc}") from None
        self._fd = fd
        self._recover()

    def unlock(self) -> None:
        if self._fd is not None:
            os.close(self._fd)          # closing the descriptor releases the flock
            self._fd = None

    def __enter__(self):
        self.lock()
        return self

    def __exit__(self, *exc):
        self.unlock()

    def _ours(self, folder: Path) -> bool:
        return folder.is_dir() and not folder.is_symlink() and (folder / STAGE_TAG).is_file()

    def _recover(self) -> None:
        if self.journal.is_file():
            try:
                plan = json.loads(self.journal.read_text())
                self._roll_forward(plan)
            except (OSError, ValueError, KeyError, TypeError):
                pass                     # a journal we cannot read was never completed: keep everything
        for p in self.path.glob(self.stage_prefix + "*"):
            if self._ours(p):
                shutil.rmtree(p, ignore_errors=True)    # stage of a run that was killed (we hold the lock)

    # -------------------------------------------------------------- staging and publication
    def stage(self) -> Path:
        """A new, empty staging folder of this run (``ValueError`` if it cannot be created)."""
        if self._fd is None:
            raise RuntimeError("lock the output folder before staging")
        try:
            stage = Path(tempfile.mkdtemp(prefix=self.stage_prefix, dir=self.path))
            (stage / STAGE_TAG).write_bytes(b"")
        except OSError as exc:
            raise ValueError(f"cannot write to output folder {self.path}: {exc.strerror or exc}") from None
        return stage

    def publish(self, stage, files, *, complete: bool = True) -> list:
        """Publish the staged ``files`` into the folder as one unit; returns their names.

        Files of the previous run that this one does not write are removed if the manifest proves
        they are ours (name, inode, size, mtime); nothing else is touched."""
        stage = Path(stage)
        files = sorted(set(files))
        old = self._manifest().get("files", {})
        remove = []
        if isinstance(old, dict):
            for name, sig in old.items():
                if name in files or name not in self.outputs:
                    continue
                try:
                    if _signature(self.path / name) == sig:
                        remove.append(name)
                except OSError:
                    pass
        manifest = {"program": self.program, "complete": bool(complete),
                    "files": {n: _signature(stage / n) for n in files}}
        plan = {"stage": stage.name, "files": files, "remove": remove, "manifest": manifest}
        write_atomic(self.journal, json.dumps(plan))
        _commit(lambda: self._roll_forward(plan))
        return files

    def write_and_publish(self, write, *, complete: bool = True) -> list:
        """Stage, ``write(stage)`` (returns the names it wrote) and publish those as one unit; returns
        the names.  On any failure or interrupt the stage is removed and the exception propagates, so
        the folder keeps its previous outputs (publication itself removes the stage on success)."""
        stage = self.stage()
        try:
            return self.publish(stage, write(stage), complete=complete)
        except BaseException:
            self.discard(stage)
            raise

    def _roll_forward(self, plan: dict) -> None:
        stage = self.path / plan["stage"]
        for name in plan["remove"]:
            try:
                (self.path / name).unlink()
            except FileNotFoundError:
                pass
        for name in plan["files"]:
            if name in self.outputs and (stage / name).is_file():
                self._subfolder(Path(name).parent)          # outputs may sit in subfolders
                os.replace(stage / name, self.path / name)
        write_atomic(self.marker, json.dumps(plan["manifest"], indent=1) + "\n")
        self.journal.unlink()
        for folder in (stage, self.incomplete):      # a published run supersedes an earlier unfinished one
            if self._ours(folder):
                shutil.rmtree(folder, ignore_errors=True)

    def _subfolder(self, rel: Path) -> None:
        """Create ``DIR/rel`` as real folders; a symbolic link in the way (made after the checks) is
        replaced by a folder, never followed."""
        p = self.path
        for part in rel.parts:
            p = p / part
            if p.is_symlink():
                p.unlink()
            if not p.is_dir():
                p.mkdir()

    def set_aside(self, stage) -> Path:
        """Keep the staged files of an unfinished run in ``DIR/.<program>-incomplete`` (replacing an
        older folder of ours of that name); returns where they are.  The published run is untouched."""
        stage = Path(stage)

        def move():
            target = self.incomplete
            if target.exists() or target.is_symlink():
                if not self._ours(target):
                    return stage                  # not ours: leave it, keep the stage under its own name
                shutil.rmtree(target)
            os.replace(stage, target)
            return target
        try:
            with deferred_signals():
                return move()
        except OSError:
            return stage

    def discard(self, stage) -> None:
        if self._ours(Path(stage)):
            shutil.rmtree(stage, ignore_errors=True)
