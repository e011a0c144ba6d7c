"""Argument parsing shared by the command-line tools (``plan-reference``, ``solver-study``, ``simulate-swarm``).

* :class:`UsageError` — bad command-line input; every CLI prints it as one line and exits 2
  (DESIGN.md: "CLIs exit non-zero with one readable line").
* :class:`OneLineParser` — ``argparse`` raises :class:`UsageError` instead of printing the usage
  block and calling ``sys.exit(2)`` itself.
* :class:`DefaultsFormatter` — ``--help`` shows "(default: X)" only where there is a default to
  show: options whose default is resolved later from a TOML file (``None``) and plain switches
  (``False``) state their default in their own help text.
"""
from __future__ import annotations

import argparse


class UsageError(ValueError):
    """Bad user input: reported in one line on stderr, exit code 2."""


class DefaultsFormatter(argparse.RawDescriptionHelpFormatter):
    def _get_help_string(self, action):
        text = action.help or ""
        d = action.default
        if not (d is None or d is False or d == argparse.SUPPRESS) and "%(default)" not in text:
            text += " (default: %(default)s)"
        return text


class OneLineParser(argparse.ArgumentParser):
    def __init__(self, *args, **kwargs):
        kwargs.setdefault("formatter_class", DefaultsFormatter)
        super().__init__(*args, **kwargs)

    def error(self, message):
        raise UsageError(message)
