"""Render this code base's plain-text docstrings without reST warnings.

The docstrings of swarmfield are written to be read in a terminal (``help()``, an editor): formulas
indented under a sentence ending in a colon, columns of ``name    description`` with hanging
indentation, absolute values written ``|v|``.  reST reads those as block quotes, broken definition
lists and substitution references.  This hook (run after napoleon) rewrites a docstring's lines:

* a paragraph ending in ``:`` followed by a more indented block -> ``::`` (the block is shown verbatim);
* a paragraph with hanging indentation (lines indented deeper than its first line, or
  deeper-then-shallower, that is not a list, a field list, a directive or a definition list item)
  -> shown verbatim as a literal block;
* ``|`` outside literals -> ``\\|`` (never a substitution reference).

Docstrings that already are valid reST (``::`` literal blocks, lists, napoleon sections, roles) pass
through unchanged.
"""
from __future__ import annotations

import re

_LIST = re.compile(r"^(\*|-|\+|\d+[.)]|#\.|\(\d+\)|[a-z][.)])\s+\S")
_LITERAL = re.compile(r"(``.+?``|:[\w:+-]+:`[^`]*`|`[^`]*`_?_?)")


def _indent(line: str) -> int:
    return len(line) - len(line.lstrip(" "))


def _is_construct(first: str) -> bool:
    s = first.lstrip(" ")
    return (s.startswith(("..", ":", ">>>", "|")) or bool(_LIST.match(s)) or s.startswith("=")
            or s.startswith("+-"))


def _escape_pipes(line: str) -> str:
    if "|" not in line:
        return line
    parts = _LITERAL.split(line)
    for k in range(0, len(parts), 2):           # even parts are outside literals and roles
        parts[k] = re.sub(r"(?<!\\)\|", r"\\|", parts[k])
    return "".join(parts)


def _blocks(lines):
    """Yield (start, end) of runs of non-blank lines."""
    i, n = 0, len(lines)
    while i < n:
        if not lines[i].strip():
            i += 1
            continue
        j = i
        while j < n and lines[j].strip():
            j += 1
        yield i, j
        i = j


def fix_lines(lines: list[str]) -> list[str]:
    out: list[str] = []
    literal_indent = None          # inside a literal block: lines indented deeper than this are verbatim
    blocks = list(_blocks(lines))
    prev_end = 0
    for bi, (a, b) in enumerate(blocks):
        out.extend(lines[prev_end:a])          # blank lines kept
        prev_end = b
        block = lines[a:b]
        base = _indent(block[0])
        if literal_indent is not None:
            if base > literal_indent:
                out.extend(block)
                continue
            literal_indent = None
        nxt = blocks[bi + 1] if bi + 1 < len(blocks) else None
        deeper_next = nxt is not None and _indent(lines[nxt[0]]) > _indent(block[-1])
        ends_literal = block[-1].rstrip().endswith("::")
        indents = [_indent(x) for x in block]
        if len(block) >= 2 and not _is_construct(block[0]) and not ends_literal:
            uniform = all(i == base for i in indents)
            # "term\n    definition" (every later line at one deeper indent) is a valid definition list item
            definition = indents[1] > base and all(i == indents[1] for i in indents[1:])
            if not (uniform or definition):
                out.append(" " * base + "::")
                out.append("")
                out.extend("    " + x for x in block)
                continue
        fixed = [_escape_pipes(x) for x in block]
        last = fixed[-1].rstrip()
        if not ends_literal and deeper_next and last.endswith(":") and not _is_construct(block[0]):
            nxt_first = lines[nxt[0]].lstrip(" ")
            if not _is_construct(nxt_first):
                fixed[-1] = last + ":"
                ends_literal = True
        out.extend(fixed)
        if ends_literal:
            literal_indent = _indent(block[-1]) if not block[-1].lstrip().startswith("..") else _indent(block[0])
    out.extend(lines[prev_end:])
    return out


def _process(app, what, name, obj, options, lines):
    lines[:] = fix_lines(list(lines))


def setup(app):
    app.connect("autodoc-process-docstring", _process, priority=600)   # after napoleon (500)
    return {"parallel_read_safe": True, "parallel_write_safe": True}
