"""The package's import graph, read from the source (AST), its layering rules, and a picture of it.

    python scripts/import_graph.py [--png docs/_generated/imports.png]

prints the package-level graph and any layout problem (exit 1 if there is one).  The test
``tests/test_layout.py`` runs the same checks; the documentation build draws the picture with
:func:`draw`, so the architecture page shows the graph of the code it documents.

Layers, lowest first (a module may import its own layer and the ones below, never above):

    runtime            infrastructure: publication, atomic writes, argument parsing, validation
    ocp, control, regression, domain    the science (control may use ocp's ReferencePlan; regression,
                       ocp and domain import none of the others; the planner and the feedback receive
                       the domain's geometry as arrays)
    sim                the closed loop (Algorithm 1), controllers, fields, metrics, figures
    studies            sweeps of runs: the runner, the controller comparison, the solver study
    cli                command-line entry points (nothing imports them)

The namespace's ``__init__`` (version, lazy public names), ``__main__`` and the deprecated aliases at
the root (``sweep``, ``checks``) stand outside the layers.
"""
from __future__ import annotations

import argparse
import ast
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
SKIP = {"tests", "benchmarks", "scripts", "docs", "examples", "build", "dist"}
LAYER = {"runtime": 0, "ocp": 1, "control": 1, "regression": 1, "domain": 1, "sim": 2, "studies": 3, "cli": 4}
#: imports allowed inside the science layer (importer -> importees)
SCIENCE = {"ocp": set(), "regression": set(), "control": {"ocp"}, "domain": set()}


def modules(root: Path = ROOT) -> dict[str, Path]:
    """Dotted module name (relative to the namespace; "" is its ``__init__``) -> file."""
    out = {}
    for p in sorted(root.rglob("*.py")):
        rel = p.relative_to(root)
        if set(rel.parts) & SKIP or any(part.startswith(".") for part in rel.parts):
            continue
        parts = list(rel.with_suffix("").parts)
        if parts[-1] == "__init__":
            parts = parts[:-1]
        out[".".join(parts)] = p
    return out


def _targets(name: str, path: Path, node, mods) -> list[str]:
    pkg = name.split(".") if path.name == "__init__.py" else name.split(".")[:-1]
    if name == "":
        pkg = []
    found = []
    if isinstance(node, ast.ImportFrom):
        if node.level:
            base = pkg[: len(pkg) - (node.level - 1)] if node.level > 1 else pkg
            stem = base + (node.module.split(".") if node.module else [])
        else:
            parts = (node.module or "").split(".")
            if parts[0] != "swarmfield":
                return []
            stem = parts[1:]
        for alias in node.names:
            cand = ".".join(stem + [alias.name])
            found.append(cand if cand in mods else ".".join(stem))
    else:
        for alias in node.names:
            parts = alias.name.split(".")
            if parts[0] == "swarmfield":
                s = parts[1:]
                while s and ".".join(s) not in mods:
                    s = s[:-1]
                found.append(".".join(s))
    return [f for f in found if f in mods and f != name]


def module_graph(root: Path = ROOT) -> dict[str, set[str]]:
    """Module -> modules it imports (anywhere in the file, lazily or not)."""
    mods = modules(root)
    graph = {m: set() for m in mods}
    for m, p in mods.items():
        for node in ast.walk(ast.parse(p.read_text(encoding="utf-8"), filename=str(p))):
            if isinstance(node, (ast.Import, ast.ImportFrom)):
                graph[m].update(_targets(m, p, node, mods))
    # a package __init__ re-exporting its own modules, and a module reading its own package's
    # __init__, are not edges of the layout
    for m in graph:
        graph[m] = {w for w in graph[m] if not (m and w.startswith(m + ".")) and not (w and m.startswith(w + "."))}
    return graph


def package(m: str) -> str:
    return m.split(".")[0] if m else ""


def package_graph(graph) -> dict[str, dict[str, int]]:
    """Package -> {imported package: number of module imports}, layered packages only."""
    out = {p: {} for p in LAYER}
    for m, ws in graph.items():
        a = package(m)
        for w in ws:
            b = package(w)
            if a in LAYER and b in LAYER and a != b:
                out[a][b] = out[a].get(b, 0) + 1
    return out


def cycles(graph) -> list[list[str]]:
    """Strongly connected components with more than one node (Tarjan)."""
    index, low, stack, on, res = {}, {}, [], set(), []
    counter = [0]
    sys.setrecursionlimit(max(10000, sys.getrecursionlimit()))

    def visit(v):
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on.add(v)
        for w in graph.get(v, ()):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                res.append(sorted(comp))

    for v in graph:
        if v not in index:
            visit(v)
    return res


def problems(graph) -> list[str]:
    """Every breach of the layering rules, and every cycle (module and package level)."""
    out = [f"module cycle: {' <-> '.join(c)}" for c in cycles({m: {w for w in ws if w} for m, ws in graph.items()})]
    pg = {a: set(bs) for a, bs in package_graph(graph).items()}
    out += [f"package cycle: {' <-> '.join(c)}" for c in cycles(pg)]
    for m, ws in sorted(graph.items()):
        a = package(m)
        if a not in LAYER:
            continue
        for w in sorted(ws):
            b = package(w)
            if b not in LAYER or a == b:
                continue
            if LAYER[b] > LAYER[a]:
                out.append(f"{m} imports {w}: layer {a} may not import the higher layer {b}")
            elif LAYER[a] == LAYER[b] == 1 and b not in SCIENCE[a]:
                out.append(f"{m} imports {w}: science package {a} may not import {b}")
    return out


def draw(graph, path: Path) -> Path:
    """The package-level graph as layered boxes (module count, lines) and arrows (import count)."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.patches import FancyBboxPatch

    mods = modules()
    lines = {p: 0 for p in LAYER}
    count = {p: 0 for p in LAYER}
    for m, f in mods.items():
        p = package(m)
        if p in LAYER:
            count[p] += 1
            lines[p] += sum(1 for _ in f.open(encoding="utf-8"))
    # layers bottom-up; runtime (imported by every layer) stands apart on the right
    pos = {"ocp": (0.1, 0.2), "control": (0.31, 0.2), "regression": (0.52, 0.2), "domain": (0.73, 0.2),
           "sim": (0.41, 0.45),
           "studies": (0.27, 0.68), "cli": (0.55, 0.88)}
    fig, ax = plt.subplots(figsize=(8.0, 6.2))
    ax.set_axis_off()
    w, h = 0.19, 0.1
    boxes = {p: (x - w / 2, y - h / 2, w, h) for p, (x, y) in pos.items()}
    boxes["runtime"] = (0.86, 0.12, 0.13, 0.82)
    for p, (x, y, bw, bh) in boxes.items():
        ax.add_patch(FancyBboxPatch((x, y), bw, bh, boxstyle="round,pad=0.01",
                                    fc="#dbe9f6" if LAYER[p] == 1 else "#eeeeee", ec="#333333"))
        cx, cy = x + bw / 2, y + bh / 2
        ax.text(cx, cy + 0.015, f"{p}/", ha="center", va="center", fontsize=11, weight="bold")
        ax.text(cx, cy - 0.02, f"{count[p]} modules\n{lines[p]} lines" if p == "runtime" else
                f"{count[p]} modules, {lines[p]} lines", ha="center", va="top" if p == "runtime" else "center",
                fontsize=7.5)
    for a, bs in package_graph(graph).items():
        if a == "runtime":
            continue
        xa, ya = pos[a]
        for b, n in bs.items():
            style = dict(arrowstyle="->", color="#555555", lw=0.6 + 0.12 * min(n, 12), shrinkA=1, shrinkB=1)
            if b == "runtime" and LAYER[a] == 1:     # under the science row, into runtime's foot
                yl = 0.1 - 0.02 * list(SCIENCE).index(a)
                xr = 0.88 + 0.03 * list(SCIENCE).index(a)
                ax.plot([xa, xa, xr], [ya - h / 2, yl, yl], color="#555555", lw=style["lw"])
                start, end = (xr, yl), (xr, 0.12)
                label = (0.5 * (xa + xr), yl + 0.006)
            elif b == "runtime":
                start, end = (xa + w / 2, ya), (0.86, ya)
                label = (0.5 * (start[0] + end[0]), ya + 0.012)
            else:
                xb, yb = pos[b]
                start, end = (xa, ya - h / 2), (xb, yb + h / 2)
                style["connectionstyle"] = "arc3,rad=0.0"
                label = (0.5 * (xa + xb) + 0.012, 0.5 * (ya - h / 2 + yb + h / 2))
            ax.annotate("", xy=end, xytext=start, arrowprops=style)
            ax.text(*label, str(n), fontsize=7, color="#aa3300")
    ax.set_xlim(0, 1)
    ax.set_ylim(0.0, 1)
    ax.set_title("swarmfield imports (arrow: 'imports', number: module-level imports)\n"
                 "generated from the source by scripts/import_graph.py", fontsize=9)
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110, bbox_inches="tight")
    plt.close(fig)
    return path


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="import_graph.py", description=__doc__.split("\n\n")[0])
    ap.add_argument("--png", type=Path, help="also draw the package graph to this PNG")
    args = ap.parse_args(argv)
    g = module_graph()
    for a, bs in package_graph(g).items():
        print(f"{a:10s} -> {', '.join(f'{b} ({n})' for b, n in sorted(bs.items())) or '-'}")
    found = problems(g)
    for p in found:
        print(p)
    print(f"{len(g)} modules, {sum(len(v) for v in g.values())} imports; {len(found)} layout problems")
    if args.png:
        print(f"wrote {draw(g, args.png)}")
    return 1 if found else 0


if __name__ == "__main__":
    sys.exit(main())
