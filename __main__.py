"""``python -m swarmfield``: the four commands, one line each; ``python -m swarmfield COMMAND ...`` runs one.

Imports nothing but this package's top (no NumPy, no CasADi) until a command is run.
"""
from __future__ import annotations

import sys

from . import DISTRIBUTION, __version__

#: command -> (module, one line); the console scripts of pyproject.toml
COMMANDS = {
    "plan-reference": ("swarmfield.cli.plan_reference",
                       "solve the reference-density optimal-control problem once and write a plan (.npz)"),
    "simulate-swarm": ("swarmfield.cli.simulate_swarm",
                       "run the closed loop (the paper's Algorithm 1) and write metrics, summary and figures"),
    "compare-controllers": ("swarmfield.studies.compare",
                            "compare controllers over fields, seeds, robot losses and robot counts, in parallel"),
    "solver-study": ("swarmfield.studies.solver_study",
                     "time the planner's formulations, discretisations and solver options"),
}


def usage() -> str:
    width = max(map(len, COMMANDS))
    lines = [f"{DISTRIBUTION} {__version__}: field estimation with robotic swarms (Zheng & Lin)", "",
             "commands:"]
    lines += [f"  {name:<{width}}  {line}" for name, (_, line) in COMMANDS.items()]
    lines += ["", "Run 'COMMAND --help' (or 'python -m swarmfield COMMAND --help') for a command's options."]
    return "\n".join(lines)


def main(argv=None) -> int:
    argv = sys.argv[1:] if argv is None else list(argv)
    if not argv or argv[0] in ("-h", "--help"):
        print(usage())
        return 0
    if argv[0] == "--version":
        print(f"{DISTRIBUTION} {__version__}")
        return 0
    if argv[0] not in COMMANDS:
        print(f"python -m swarmfield: error: unknown command {argv[0]!r}; commands: {', '.join(COMMANDS)}",
              file=sys.stderr)
        return 2
    from importlib import import_module
    module = import_module(COMMANDS[argv[0]][0])
    sys.argv[0] = argv[0]
    return module.main(argv[1:])


if __name__ == "__main__":
    sys.exit(main())
