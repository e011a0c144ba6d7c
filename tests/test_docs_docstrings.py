"""The documentation's docstring hook (docs/_ext/plaintext_docstrings.py) turns this code base's
plain-text docstrings into reST that docutils parses without a warning, and leaves valid reST alone."""
import io

import pytest
from file_module import load

docutils_core = pytest.importorskip("docutils.core")


def _fix_lines():
    return load("docs/_ext/plaintext_docstrings.py").fix_lines


def _warnings(text: str) -> str:
    stream = io.StringIO()
    docutils_core.publish_doctree(text, settings_overrides={"warning_stream": stream, "report_level": 2,
                                                            "halt_level": 5})
    return stream.getvalue()


PLAIN = """Gains of the feedback law.

alpha : feedback gain (> 0), |v| <= v_max
sigma : diffusion coefficient of the robots'
        Brownian motion; must match the simulation.
p_floor : lower bound on p_hat

Formulation (single shooting):

    min_a   w_f KLs(p(t_f), q)
    s.t.    sum |a| <= v_max

with KLs(p, q) = sum (p - q) log(p / q) and ``a|b`` literal.
"""

VALID = """A valid docstring.

Example::

    x = |y|

* item one
  continued
* item two

``code`` and *emphasis*.
"""


def test_plain_text_docstring_parses_without_warnings_after_the_hook():
    fix = _fix_lines()
    assert _warnings(PLAIN), "the sample should be invalid reST without the hook"
    fixed = "\n".join(fix(PLAIN.split("\n")))
    assert _warnings(fixed) == ""
    assert "Formulation (single shooting)::" in fixed          # the formula block becomes a literal block
    assert "\\|v\\|" not in fixed                               # inside the literal block: kept verbatim
    assert "``a|b``" in fixed                                   # inline literals untouched


def test_valid_rest_is_left_alone():
    fix = _fix_lines()
    assert _warnings(VALID) == ""
    assert fix(VALID.split("\n")) == VALID.split("\n")
