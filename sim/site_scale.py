"""The tuned preset's absolute lengths and speeds scaled to the site (``sim.site_scale``).

The tuned preset's settings were measured on the paper's 20 m x 20 m rectangle (docs/results/tuned-preset.md).
Some of them are absolute lengths or speeds whose right value grows with the site.  The clearest is the KDE's
bandwidth of 1 m: with 100 robots on 20 m x 20 m a robot's own kernel, 1 / (2 pi n h^2) = 1.6e-3 m^-2 at its
centre, is 0.64 of the uniform density 1 / 400 m^-2; on a 60 m x 40 m yard it is 3.8 times the uniform density
1 / 2400 m^-2, so every robot sees itself as a crowd, p̂ / p_r ~ 1.7 at the robots (measured), and the reference
flux v_r p_r and the stirring J of eq. "density feedback law using estimation" are divided by that crowd: the
swarm crawls where it should run (docs/results/map-quality.md, "Larger sites").

With ``sim.site_scale = "area"`` (the tuned preset's) the settings of :data:`SCALED` are multiplied by a power of

    s = max(1, sqrt(|Omega| / A_ref)),    A_ref = 400 m^2 (the paper's 20 m x 20 m),

|Omega| the area of ``sim.domain``'s rectangle (see :data:`SCALED` for the powers).  On any rectangle of at most
400 m^2 s is 1 and nothing changes (not a bit): a bandwidth wider than the robots' spacing only smooths more, and
the preset was not measured on smaller sites.  Only values the user's configuration does not give are
scaled: the preset's values and the defaults; a value given in a ``--config`` file is used as given, so a run's own
``DIR/config.toml`` (which spells out every resolved value) repeats it.  ``"off"`` (the paper preset's) keeps every
value as given.  summary.json records the factor and the resolved values (:func:`site_summary`).
"""
from __future__ import annotations

import math

__all__ = ["SITE_SCALE_RULES", "REFERENCE_AREA", "SCALED", "site_factor", "scale_document", "site_summary"]

#: ``sim.site_scale``: "off" (values as given) or "area" (scaled by s = max(1, sqrt(area / REFERENCE_AREA)))
SITE_SCALE_RULES = ("off", "area")

#: the area [m^2] the tuned preset's values were measured on: the paper's 20 m x 20 m
REFERENCE_AREA = 400.0

#: (section, key, power of s): the settings the rule scales.  kde.bandwidth is a length: the KDE resolves the
#: robots' spacing sqrt(|Omega| / n), not the robots themselves, on every site
SCALED: tuple[tuple[str, str, int], ...] = (
    ("kde", "bandwidth", 1),
)


def site_factor(domain, rule: str = "area") -> float:
    """s = max(1, sqrt(area of ``domain`` = (x0, x1, y0, y1) / :data:`REFERENCE_AREA`)) for ``rule`` "area", 1.0 for
    "off"."""
    if rule not in SITE_SCALE_RULES:
        raise ValueError(f"sim.site_scale must be one of {', '.join(repr(r) for r in SITE_SCALE_RULES)}, got {rule!r}")
    if rule == "off":
        return 1.0
    x0, x1, y0, y1 = (float(v) for v in domain)
    area = (x1 - x0) * (y1 - y0)
    return math.sqrt(area / REFERENCE_AREA) if area > REFERENCE_AREA else 1.0


def scale_document(doc: dict, given: dict, factor: float, defaults: dict) -> tuple[dict, dict]:
    """``doc`` (a configuration document laid over its preset) with the :data:`SCALED` settings that ``given`` (the
    user's own document) does not set multiplied by ``factor ** power``; ``defaults[section]`` is the settings class
    whose default stands for a value the preset does not set either.  Returns (the new document, {"section.key":
    [value before, value after]} of the values scaled).  A factor of exactly 1 returns ``doc`` itself; a value of
    ``None`` (e.g. a Silverman bandwidth) is left alone."""
    scaled: dict = {}
    if factor == 1.0:
        return doc, scaled
    out = {k: (dict(v) if isinstance(v, dict) else v) for k, v in doc.items()}
    for section, key, power in SCALED:
        mine = given.get(section)
        if isinstance(mine, dict) and key in mine:
            continue
        table = out.setdefault(section, {})
        if not isinstance(table, dict):
            continue                                  # reported by the settings class
        value = table.get(key, getattr(defaults[section], key, None))
        if value is None or isinstance(value, bool) or not isinstance(value, (int, float)):
            continue
        new = float(value) * factor ** power
        table[key] = new
        scaled[f"{section}.{key}"] = [float(value), new]
    return out, scaled


def site_summary(config) -> dict:
    """summary.json's ``site_scale`` block: the rule, the reference area, the site's area, the factor s and the
    resolved values of the settings the rule scales (whether scaled or given)."""
    s = config.sim
    x0, x1, y0, y1 = s.domain
    return {"rule": s.site_scale, "reference_area_m2": REFERENCE_AREA, "area_m2": (x1 - x0) * (y1 - y0),
            "factor": site_factor(s.domain, s.site_scale),
            "settings": {f"{sec}.{key}": getattr(getattr(config, sec), key) for sec, key, _ in SCALED}}
