"""Argument parsing shared by the command-line tools (``plan-reference``, ``solver-study``, ``simulate-swarm``).

* :class:`UsageError` — bad command-line input; every CLI prints it as one line and exits 2
  (DESIGN.md: "CLIs exit non-zero with one readable line").
* :class:`OneLineParser` — ``argparse`` raises :class:`UsageError` instead of printing the usage
  block and calling ``sys.exit(2)`` itself.
* :func:`cli_main` — the common ``main``: limits the BLAS/OpenMP threads (:mod:`runtime.threads`), runs a
  command, turns :class:`UsageError` into one line and exit 2 and Ctrl-C into one line and exit 130
  (SIGTERM: 143; runtime.signals), and exits the process when called as a script.
* :class:`DefaultsFormatter` — ``--help`` in plain text (no reST markup) showing "(default: X)"
  once, only where there is a default to show and the help does not state it: options whose
  default is resolved later from a TOML file (``None``) and plain switches (``False``) state their
  default in their own help text.
* ``--version`` on every command: ``PROG swarmfield X.Y.Z``.
"""
from __future__ import annotations

import argparse
import sys


class UsageError(ValueError):
    """Bad user input: reported in one line on stderr, exit code 2."""


def plain(text: str) -> str:
    """Help text as plain text: reST inline literals (double backticks) lose their markup."""
    return text.replace("``", "")


class DefaultsFormatter(argparse.RawDescriptionHelpFormatter):
    """Plain-text help (no reST markup) that states each default once: "(default: X)" is added
    only where the option has a default to show and its help does not state it already (options
    whose default is resolved later from a TOML file, ``None``, say so in their own words)."""

    def _get_help_string(self, action):
        text = plain(action.help or "")
        d = action.default
        if d is None or d is False or d == argparse.SUPPRESS or "(default" in text or \
                isinstance(action, (argparse._VersionAction, argparse._HelpAction)):
            return text
        if isinstance(d, (list, tuple)):
            d = " ".join(str(v) for v in d)
        return f"{text} (default: {str(d).replace('%', '%%')})"

    def _format_text(self, text):
        return super()._format_text(plain(text))


def version_string(prog: str) -> str:
    """What ``PROG --version`` prints: ``PROG swarmfield X.Y.Z``."""
    from .. import DISTRIBUTION, __version__
    return f"{prog} {DISTRIBUTION} {__version__}"


class OneLineParser(argparse.ArgumentParser):
    """``argparse`` with one-line errors (:class:`UsageError`), no abbreviated flags, plain-text
    help with each default stated once (:class:`DefaultsFormatter`) and ``--version``."""

    def __init__(self, *args, **kwargs):
        kwargs.setdefault("formatter_class", DefaultsFormatter)
        # no prefixes of long flags: a misspelt flag is an error, not whichever flag it abbreviates
        kwargs.setdefault("allow_abbrev", False)
        super().__init__(*args, **kwargs)
        self.add_argument("--version", action="version", version=version_string(self.prog),
                          help="print the program's name and the swarmfield version, then exit")

    def error(self, message):
        raise UsageError(self._with_guess(message))

    def _with_guess(self, message: str) -> str:
        """A misspelt flag or choice gets ``did you mean ...?`` when one is a close spelling of it."""
        import difflib
        import re

        def close(word, known):
            found = difflib.get_close_matches(word, sorted(known), n=1, cutoff=0.75)
            return found[0] if found else None
        if message.startswith("unrecognized arguments: "):
            flags = [a for a in self._option_string_actions if a.startswith("--")]
            words = [w.split("=")[0] for w in message[len("unrecognized arguments: "):].split() if w.startswith("--")]
            guesses = [f"{g} for {w}" if len(words) > 1 else g for w in words if (g := close(w, flags))]
            return message + (f"; did you mean {', '.join(guesses)}?" if guesses else "")
        chosen = re.search(r"invalid choice: '([^']*)' \(choose from (.*)\)$", message)
        if chosen:
            guess = close(chosen.group(1), [c.strip().strip("'") for c in chosen.group(2).split(",")])
            return message + (f"; did you mean {guess}?" if guess else "")
        return message


def cli_main(prog: str, run, argv=None, *, value_errors: bool = False) -> int:
    """Run ``run(argv)`` as the command ``prog``: exit code 2 with one line for a
    :class:`UsageError` (any ``ValueError`` if ``value_errors``: validation inside the library),
    130 with one line for Ctrl-C; ``sys.exit`` with the code when ``argv`` is None (console script)."""
    from .signals import exit_code, ignore_interrupts

    errors = ValueError if value_errors else UsageError
    from .threads import limit_threads
    limit_threads()          # BLAS/OpenMP threads: the measured best unless the environment sets them
    try:
        code = run(argv)
    except errors as exc:
        print(f"{prog}: error: {exc}", file=sys.stderr)
        code = 2
    except KeyboardInterrupt as exc:
        code = exit_code(exc)
        if argv is None:
            ignore_interrupts()
        print(f"{prog}: {'terminated' if code == 143 else 'interrupted'}", file=sys.stderr)
    if argv is None:
        ignore_interrupts()             # the outcome is decided: a late Ctrl-C must not turn it into a traceback
        sys.exit(code)
    return code


def check_path(path, what: str) -> None:
    """:class:`UsageError` for a path the file system or the outputs cannot hold: a name that is
    not valid UTF-8 (it could not be recorded in summary.json or a plan's meta), a component
    longer than the folder allows (NAME_MAX) or a whole path longer than PATH_MAX.  Checked
    before any work, so that such a path fails in one line, not after a solve or a run."""
    import os
    from pathlib import Path

    text = os.fspath(path)
    try:
        text.encode("utf-8")
    except UnicodeEncodeError:
        raise UsageError(f"{what} {text.encode('utf-8', 'surrogateescape')!r}: the name is not valid UTF-8") from None
    p = Path(text)
    anchor = p.parent if str(p.parent) else Path(".")
    while not anchor.exists() and anchor != anchor.parent:
        anchor = anchor.parent
    try:
        name_max = os.pathconf(anchor, "PC_NAME_MAX")
        path_max = os.pathconf(anchor, "PC_PATH_MAX")
    except (OSError, ValueError):
        name_max, path_max = 255, 4096
    if len(os.fsencode(os.path.abspath(text))) >= path_max:
        raise UsageError(f"{what} path is longer than the file system allows ({path_max} bytes)")
    for part in p.parts:
        if len(os.fsencode(part)) > name_max:
            raise UsageError(f"{what} {text[:40]}...: the name {part[:20]}... is longer than the file system "
                             f"allows ({name_max} bytes)")
