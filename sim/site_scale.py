"""The tuned preset's absolute lengths and weights scaled to the site (``sim.site_scale``).

The tuned preset's settings were measured on the paper's 20 m x 20 m rectangle (docs/results/tuned-preset.md).
Two of them, measured on a 60 m x 40 m yard (docs/results/map-quality.md, "Larger sites"), hold the swarm back on a
larger site:

* **the planner's energy weight** ``planner.w_v``: the cost w_v int int |v|^2 dx dt (eq. "optimization problem")
  grows with the site's area, the information and KL terms are means over the cells and do not.  On the yard the
  same reference velocities cost six times as much against the same information, and the plans moved slowly
  (median planned |v_r| at the robots ~1.1-1.3 m/s in the second period);
* **the KDE's bandwidth** ``kde.bandwidth`` (1 m): a robot's own kernel, 1 / (2 pi n h^2) = 1.6e-3 m^-2 at its
  centre for 100 robots, is 0.64 of the uniform density 1 / 400 m^-2 on the paper's rectangle but 3.8 times the
  uniform density 1 / 2400 m^-2 on the yard: every robot sees itself as a crowd (p̂ / p_r ~ 1.7 at the robots), and
  the reference flux v_r p_r and the stirring J of eq. "density feedback law using estimation" are divided by it.

With ``sim.site_scale = "area"`` (the tuned preset's) the settings of :data:`SCALED` are multiplied by a power of

    s = max(1, sqrt(|Omega| / A_ref)),    A_ref = 400 m^2 (the paper's 20 m x 20 m),

|Omega| the site's area: the free area of the ``[domain]`` map when there is one (:func:`site_area`), else the area of
``sim.domain``'s rectangle.  The free area, not the map's bounding rectangle: on a 482 m^2 pond drawn inside a
36 m x 26 m rectangle the rectangle gave s = 1.53, the robots' spacing gives 1.10, and with 1.10 the feedback's map at
2 T was 0.91 / 0.92x what it was with 1.53 (seeds 0 / 1; docs/results/map-quality.md, "The site's area on a map").
The bandwidth by s (the robots' spacing sqrt(|Omega| / n) grows
with s), the energy weight by 1 / s^2 (the penalty on the site's mean |v|^2 stays the rectangle's).  On any
rectangle of at most 400 m^2 s is 1 and these two do not change (not a bit): a bandwidth wider than the robots' spacing
only smooths more, and the preset was not measured on smaller sites.  Only values the user's configuration does not
give are scaled: the preset's values and the defaults; a value given in a ``--config`` file is used as given, so a
run's own ``DIR/config.toml`` (which spells out every resolved value) repeats it.  ``"off"`` (the paper preset's)
keeps every value as given.  summary.json records the factor and the resolved values (:func:`site_summary`).

**A site smaller than the paper's** (:data:`LENGTH_SCALED`; docs/results/stop-rule.md, "A length-scale prior relative
to a small site").  On a rectangle of less than 400 m^2 the GP's prior length scale ``gp.length_scale`` (the centre of
its log-normal prior, regression.hyper, and the length the robust stop rule checks its threshold at, sim.stopping;
``gp.length_scale_y`` too when set) is multiplied by

    s_small = sqrt(|Omega| / A_ref) < 1,

|Omega| the free area as above, but not below twice the inducing grid's cell (longer side / ``gp.grid_cells``;
1.5 x ``gp.inducing_spacing`` when that is given; :func:`length_floor`): the grid min(l / 2, longer side / grid_cells)
stays the one the 1 m prior gets, and the prior's centre stays a third above the shortest learnable length.  With the
tuned preset's 40 cells that floor is what binds on a rectangle (longer side / 20: the paper's 1 m on its 20 m): 0.15 m
on a 3 m x 2 m table, 0.25 m on a 5 m x 3 m bench.  On the table, 100 measurements in the start box refitted at t = 0
learned the 1 m prior's median (0.98 m), the band was as narrow as 1 m makes it and the stop fired at 0.12-0.62 T
with the band covering 0.57-0.88 of the cells.  Every rectangle of 400 m^2 or more (with or without a map) keeps its
length scale, bit for bit; the KDE bandwidth and the energy weight are not scaled down (a bandwidth wider than the
robots' spacing only smooths more; on the bench a smaller one did not help).  Values given in the configuration are
used as given, as above; summary.json's block records s_small (``length_factor``) and the resolved length scales.

Not scaled, measured on the yard (same page): the reference speed (``planner.reference_speed`` x s: the plans did
not use the budget they had, the same maps within the runs' spread) and the stirring speed (x s: the robots
drove 79 m instead of 63 m in 4 T, and the map was worse).

**A swarm sparser than the paper's** (``sim.swarm_scale``; docs/results/map-quality.md, "A small swarm").  The same
lengths are a matter of the robots' spacing sqrt(|Omega| / n) as much as of the site: 100 robots on 400 m^2 are 2 m
apart, 30 robots on the same square 3.65 m, and a robot's own KDE kernel, 1 / (2 pi n h^2) at its centre, is 2.1 times
the uniform density there (0.64 times at 100 robots).  With ``sim.swarm_scale = "spacing"`` the settings of
:data:`SWARM_SCALED` are multiplied by

    c = max(1, q / s),    q = sqrt(|Omega| / (n a_ref)),    a_ref = 4 m^2 (:data:`REFERENCE_ROBOT_AREA`),

q the robots' spacing relative to the paper's 2 m and s the site's factor above (1 with ``site_scale = "off"``): the
KDE bandwidth becomes h max(s, q), the larger of what the site and the spacing ask for.  c = 1 (not a bit changed) for
100 robots or more on the paper's square, and for any swarm at least as dense as the paper's, i.e. whenever
n >= |Omega| / 4 m^2 (100 robots on any site larger than 400 m^2: q = s).  ``"off"`` (the default) keeps every
value; ``"spacing"`` (measured and not adopted: it cost the fine field's map, see the page) scales them when the
configuration is resolved.  Values the configuration gives are used as
given, as for the site rule; summary.json's ``swarm_scale`` block records the factor.

``"spacing-capped"`` scales the same settings during the run instead, at every hyperparameter
refit, by

    f = max(1, min(c, l / l_0)),

l the GP's learned length scale (the geometric mean of an anisotropic kernel's two) and l_0 its prior one
(``gp.length_scale``, the tuned preset's 1 m, equal to its KDE bandwidth): the kernel is widened towards the robots'
spacing, but never beyond the field's own length scale in the tuned ratio h / l_0.  A smooth field (the kPa field's
l = 3.5-3.9 m) gets the spacing's c, a field with structure at l_0 or finer (the fine field's 0.9-1.05 m) keeps the
preset's 1 m kernel, which resolves the gaps its map needs.  With 30 robots, seeds 0-3: the pressure field's map at
2 T 1.34 / 1.21 / 1.01 / 1.12 -> 1.13 / 1.16 / 0.96 / 1.03 of greedy's and its threshold never on three seeds ->
within 3 T on four; bumps 0.96 / 1.07 / 0.85 / 0.91 (0.98 / 1.03 / 0.89 / 1.00, within the runs' scatter), fine
unchanged to 2 T; with 50 robots the kPa field's map at 2 T 1.09 / 1.00 -> 1.01 / 0.96, but bumps' time to a map
within 1.25x of the best later on three of four seeds (by 0.12-0.38 T).  Over eight seeds, paired by seed, that
cost is not resolved (1.03x [0.87-1.21]) while the pressure field's gain is (its map at 2 T 0.92x [0.89-0.95] with 30
robots), so the tuned preset uses "spacing-capped" (docs/results/map-quality.md, "A small swarm: eight seeds,
paired").
The run's resolved values are scaled (a run cannot tell a value given from a preset's: keep yours with
``swarm_scale = "off"``); summary.json's ``kernel`` block records the last factor (``swarm_factor``).  With c = 1
(the paper's density or denser) f = 1 at every refit and nothing is touched.

``sim.swarm_radius = "spacing"`` (opt-in; the default ``"capped"`` is the rule above) scales the spreading radius by
c from the first refit on, whatever l, the bandwidth still by f: the holes between a sparse swarm's measurements are a
matter of its spacing, not of the field's length scale.  With 30 robots, seeds 0-3, it made the map at 2 T better or
level on six fields (bumps and a 0.6 m ppm field 7 % better) but at 3 T better on one (bumps, 3.5 %), the same on
one and 0.03-1.7 % worse on four, so no preset uses it (docs/results/map-quality.md, "Small swarms against greedy").

**Lengths that follow a small site** (``sim.site_lengths``; docs/results/map-quality.md, "Lengths that follow a small
site").  With ``"scaled"`` (opt-in; ``"given"``, the default, keeps every value as before, bit for bit) a site whose
shorter side is below :data:`SMALL_SIDE` (5 m) and whose area is below :data:`REFERENCE_AREA` gets
the settings of :data:`SIDE_SCALED` that are the algorithms' choices multiplied by

    r = shorter side / 20 m < 1      (:func:`side_factor`),

the KDE's bandwidth ``kde.bandwidth``, the feedback's ``feedback.spread_radius``, greedy's ``sim.greedy_separation``
and ``sim.greedy_radius``, the lawnmower's ``sim.lawnmower_lane`` and the plan's ``planner.reference_speed`` (by r,
not below the robots' ``planner.v_max``: the transport's substeps an interval stay those of the paper's square,
and the plan never runs slower than the robots) -- what a hand-scaled tabletop file did (round 6's
``table_note.toml``).  Not scaled: the robots' speed limits (``planner.v_max``, ``feedback.v_max``) and their noise
``feedback.sigma``, which are the user's robots, not a choice of the algorithm.  Only values the user's configuration
does not give are scaled (as for the rules above; a ``[sim]`` override such as a command-line flag counts as given;
summary.json's ``site_lengths`` block records r and the lengths the run used, :func:`side_summary`), so every controller of a comparison resolved from the same file gets the same lengths, and a run's own
``DIR/config.toml`` repeats them.  A site whose shorter side is 5 m or more is untouched, and so is every site of
:data:`REFERENCE_AREA` or more: an elongated site (a 60 m x 10 m canal, a 150 m x 8 m river reach, a 30 m x 15 m floor)
keeps the area and stirring rules measured there, and 12-16 m wide building maps below 400 m^2 keep 0.12.0's runs,
since the rule was measured on sites of 4-15 m^2 with sides of 2-3 m only.  The tuned preset uses "scaled": on three small sites not from round 6 (a 3 m x 2 m tabletop, a 5 m x 3 m
bench, the sinc field on a 2 m square) the tuned feedback's RMSE at 2 T and 3 T with the option over without it was
0.97 / 0.99, 1.00 / 0.98 and 0.84 / 0.80 (geometric means of seeds 0-3), the paper's square unchanged bit for bit;
the threshold came later on the tabletop and the bench (docs/results/map-quality.md, "Lengths that follow a small
site").
"""
from __future__ import annotations

import dataclasses
import math

__all__ = ["SITE_SCALE_RULES", "REFERENCE_AREA", "SCALED", "area_ratio", "site_area", "site_factor", "scaled_value",
           "scale_document", "LENGTH_SCALED", "length_ratio", "length_factor", "length_floor", "scale_lengths", "site_summary", "resolved_site_area", "unscaled_map_note", "small_site_note", "SMALL_SITE_WARNING", "SWARM_SCALE_RULES", "REFERENCE_ROBOT_AREA",
           "SWARM_SCALED", "SWARM_RADIUS_RULES", "spacing_ratio", "spacing_factor", "swarm_summary", "capped_factor", "SpacingCappedByLength",
           "SITE_LENGTH_RULES", "REFERENCE_SIDE", "SMALL_SIDE", "SIDE_SCALED", "side_factor", "scale_sides", "side_summary"]

#: ``sim.site_scale``: "off" (values as given) or "area" (scaled by s = max(1, sqrt(area / REFERENCE_AREA)))
SITE_SCALE_RULES = ("off", "area")

#: the area [m^2] the tuned preset's values were measured on: the paper's 20 m x 20 m
REFERENCE_AREA = 400.0

#: (section, key, power of s): the settings the rule scales.  kde.bandwidth is a length: the KDE resolves the
#: robots' spacing sqrt(|Omega| / n), not the robots themselves, on every site; planner.w_v weighs an integral over
#: the site's area against means over its cells
SCALED: tuple[tuple[str, str, int], ...] = (
    ("kde", "bandwidth", 1),
    ("planner", "w_v", -2),
)


#: (section, key, power of s_small): the settings the rule scales on a site smaller than :data:`REFERENCE_AREA`
#: (:func:`length_ratio`): the GP's prior length scale, the centre of its log-normal prior and the length the robust
#: stop rule checks the threshold at (sim.stopping), and an anisotropic kernel's second one
LENGTH_SCALED: tuple[tuple[str, str, int], ...] = (
    ("gp", "length_scale", 1),
    ("gp", "length_scale_y", 1),
)

#: ``sim.swarm_scale``: "off" (values as given), "spacing" (scaled by c = max(1, q / s) when the configuration is
#: resolved) or "spacing-capped" (scaled during the run by max(1, min(c, l / l_0)), :class:`SpacingCappedByLength`)
SWARM_SCALE_RULES = ("off", "spacing", "spacing-capped")

#: ``sim.swarm_radius``: with ``swarm_scale = "spacing-capped"``, the spreading radius's factor: "capped" (default) the
#: bandwidth's f = max(1, min(c, l / l_0)); "spacing" the spacing's c from the first refit on, whatever l
SWARM_RADIUS_RULES = ("capped", "spacing")

#: the area per robot [m^2] the tuned preset's values were measured at: 100 robots on the paper's 400 m^2
REFERENCE_ROBOT_AREA = 4.0

#: (section, key, power of c): the settings the swarm rule scales.  kde.bandwidth: the KDE resolves the robots'
#: spacing, so that a robot's own kernel weighs against the density as it does at the paper's density;
#: feedback.spread_radius: a landing point moves within the same fraction of the robots' spacing
SWARM_SCALED: tuple[tuple[str, str, int], ...] = (
    ("kde", "bandwidth", 1),
    ("feedback", "spread_radius", 1),
)


#: ``sim.site_lengths``: "given" (values as given) or "scaled" (the :data:`SIDE_SCALED` settings x
#: :func:`side_factor` on a site whose shorter side is below :data:`REFERENCE_SIDE`)
SITE_LENGTH_RULES = ("given", "scaled")

#: the side [m] of the square the tuned preset's lengths were measured on: the paper's 20 m x 20 m
REFERENCE_SIDE = 20.0

#: ``sim.site_lengths = "scaled"`` acts on a site whose shorter side is below this [m] (and whose area is below
#: :data:`REFERENCE_AREA`): its rule was measured on sides of 2-3 m; on 12-16 m wide building maps it moved the tuned
#: feedback's map by -2 % to +12 % (docs/results/map-quality.md, "Published tiny-site rows re-run"), untested by it
SMALL_SIDE = 5.0

#: (section, key): the algorithms' lengths (and the plan's reference speed) that ``sim.site_lengths = "scaled"``
#: multiplies by r = shorter side / :data:`REFERENCE_SIDE`; not the robots' speed limits or noise (the user's robots)
SIDE_SCALED: tuple[tuple[str, str], ...] = (
    ("kde", "bandwidth"),
    ("feedback", "spread_radius"),
    ("sim", "greedy_separation"),
    ("sim", "greedy_radius"),
    ("sim", "lawnmower_lane"),
    ("planner", "reference_speed"),
)


def side_factor(domain, rule: str = "scaled") -> float:
    """r = shorter side / :data:`REFERENCE_SIDE` of the rectangle ``domain`` = (x0, x1, y0, y1) for ``rule``
    "scaled" on a site much smaller than the paper's square (its shorter side below :data:`SMALL_SIDE`, its area below
    :data:`REFERENCE_AREA`); 1.0 for "given" and for every other site: the rule was measured on sites of 4-15 m^2 with
    sides of 2-3 m, an elongated site (a 150 m x 8 m river reach, a 30 m x 15 m floor) has the tuned preset's area and
    stirring rules instead, measured there, and on 12-16 m wide building maps below 400 m^2 it moved runs either way."""
    if rule not in SITE_LENGTH_RULES:
        raise ValueError(f"sim.site_lengths must be one of {', '.join(repr(r) for r in SITE_LENGTH_RULES)}, "
                         f"got {rule!r}")
    if rule == "given":
        return 1.0
    x0, x1, y0, y1 = (float(v) for v in domain)
    short = min(x1 - x0, y1 - y0)
    if short >= SMALL_SIDE or (x1 - x0) * (y1 - y0) >= REFERENCE_AREA:
        return 1.0
    return short / REFERENCE_SIDE


def scale_sides(doc: dict, given: dict, factor: float, defaults: dict, sim) -> tuple[dict, dict, dict]:
    """``doc`` with the :data:`SIDE_SCALED` settings that ``given`` (the user's document and ``[sim]`` overrides)
    does not set multiplied by ``factor`` (:func:`side_factor`); ``sim`` the resolved ``[sim]`` settings (their
    values of the ``sim`` entries), ``defaults[section]`` the settings class of the others.  The reference speed is
    not scaled below the robots' ``planner.v_max`` (nor above its own value), and a reference speed of None (the
    robots' own) is left alone.  Returns (the new document, {key: value} of the new ``[sim]`` values, {"section.key":
    [before, after]} of the values scaled); a factor of 1 returns ``doc`` itself and nothing scaled."""
    scaled: dict = {}
    new_sim: dict = {}
    if factor == 1.0:
        return doc, new_sim, scaled
    out = {k: (dict(v) if isinstance(v, dict) else v) for k, v in doc.items()}
    for section, key in SIDE_SCALED:
        if section == "sim":                              # the resolved [sim] settings hold the value
            mine = given.get("sim")
            value = None if isinstance(mine, dict) and key in mine else _number(getattr(sim, key))
        else:
            value = _unset_number(out, given, section, key, defaults)
        if value is None:
            continue
        new = float(value) * factor
        if (section, key) == ("planner", "reference_speed"):
            v_max = _number(out.get("planner", {}).get("v_max", getattr(defaults["planner"], "v_max", None)))
            if v_max is not None:
                new = min(float(value), max(new, float(v_max)))
        if section == "sim":
            new_sim[key] = new
        else:
            out[section][key] = new
        scaled[f"{section}.{key}"] = [float(value), new]
    return out, new_sim, scaled


def _rectangle_area(domain) -> float:
    x0, x1, y0, y1 = (float(v) for v in domain)
    return (x1 - x0) * (y1 - y0)


def site_area(domain, source="") -> float:
    """The site's area |Omega| [m^2]: the free area of the map ``source`` (a ``[domain] source``: a built-in name, a
    file or a :class:`domain.Domain`; loaded on ``domain`` = (x0, x1, y0, y1), once per process) or, without one,
    the area of the rectangle ``domain``."""
    if source is None or (isinstance(source, str) and not source):
        return _rectangle_area(domain)
    from ..domain import make_domain
    region = make_domain(source, domain)
    return _rectangle_area(domain) if region is None else float(region.free_area)


def area_ratio(domain, rule: str = "area", area: float | None = None) -> float:
    """s^2 = max(1, |Omega| / :data:`REFERENCE_AREA`) for ``rule`` "area", 1.0 for "off"; |Omega| is ``area`` if
    given (e.g. :func:`site_area` of a map), else the area of ``domain`` = (x0, x1, y0, y1)."""
    if rule not in SITE_SCALE_RULES:
        raise ValueError(f"sim.site_scale must be one of {', '.join(repr(r) for r in SITE_SCALE_RULES)}, got {rule!r}")
    if rule == "off":
        return 1.0
    area = _rectangle_area(domain) if area is None else float(area)
    return area / REFERENCE_AREA if area > REFERENCE_AREA else 1.0


def site_factor(domain, rule: str = "area", area: float | None = None) -> float:
    """s = sqrt(:func:`area_ratio`): max(1, sqrt(|Omega| / :data:`REFERENCE_AREA`)) for "area", 1.0 for "off"."""
    return math.sqrt(area_ratio(domain, rule, area))


def resolved_site_area(sim, source="") -> float | None:
    """The area the rule scales by for a run's ``[sim]`` settings and ``[domain] source``: None when it cannot
    matter (rule "off", or a rectangle of exactly :data:`REFERENCE_AREA`: neither factor applies), else
    :func:`site_area` (which loads the map)."""
    if sim.site_scale == "off" or _rectangle_area(sim.domain) == REFERENCE_AREA:
        return None
    return site_area(sim.domain, source)


def length_ratio(domain, rule: str = "area", area: float | None = None) -> float:
    """s_small^2 = min(1, |Omega| / :data:`REFERENCE_AREA`) for ``rule`` "area" on a rectangle ``domain`` smaller than
    :data:`REFERENCE_AREA`, else 1.0 (rule "off", and every rectangle of 400 m^2 or more, with or without a map:
    not measured); |Omega| is ``area`` if given (a map's free area, :func:`site_area`), else the rectangle's."""
    if rule not in SITE_SCALE_RULES:
        raise ValueError(f"sim.site_scale must be one of {', '.join(repr(r) for r in SITE_SCALE_RULES)}, got {rule!r}")
    rect = _rectangle_area(domain)
    if rule == "off" or rect >= REFERENCE_AREA:
        return 1.0
    area = rect if area is None else float(area)
    return area / REFERENCE_AREA if area < REFERENCE_AREA else 1.0


def length_factor(domain, rule: str = "area", area: float | None = None) -> float:
    """s_small = sqrt(:func:`length_ratio`): the factor of the prior length scale on a small site."""
    return math.sqrt(length_ratio(domain, rule, area))


def length_floor(gp: dict, domain, defaults) -> float:
    """The shortest prior length scale the rule gives on ``domain`` for the ``[gp]`` table ``gp`` (defaults from the
    settings class ``defaults``): twice the inducing grid's cell, longer side / ``grid_cells``, so that the grid
    min(l / 2, longer side / grid_cells) stays the one the unscaled length scale gets (no finer, no costlier) and the
    prior's centre lies a third above the shortest learnable length (1.5 cells; regression.hyper); 1.5 x a given
    ``inducing_spacing``; 0 with neither (the grid is l / 2 and follows)."""
    spacing = gp.get("inducing_spacing", getattr(defaults, "inducing_spacing", None))
    if isinstance(spacing, (int, float)) and not isinstance(spacing, bool):
        return 1.5 * float(spacing)
    cells = gp.get("grid_cells", getattr(defaults, "grid_cells", None))
    if isinstance(cells, int) and not isinstance(cells, bool) and cells > 0:
        x0, x1, y0, y1 = (float(v) for v in domain)
        return 2.0 * max(x1 - x0, y1 - y0) / cells
    return 0.0


def scale_lengths(doc: dict, given: dict, ratio: float, defaults: dict, domain) -> tuple[dict, dict]:
    """``doc`` with the :data:`LENGTH_SCALED` settings that ``given`` does not set multiplied by s_small
    (s_small^2 = ``ratio``, :func:`length_ratio`) but not below :func:`length_floor` (nor above the value itself);
    like :func:`scale_document`, whose (document, scaled values) it returns.  A ratio of 1 returns ``doc`` itself."""
    out, scaled = scale_document(doc, given, ratio, defaults, LENGTH_SCALED)
    if not scaled:
        return out, scaled
    floor = length_floor(out.get("gp", {}), domain, defaults["gp"])
    for name, (before, after) in scaled.items():
        new = min(before, max(after, floor))
        out["gp"][name.split(".", 1)[1]] = new
        scaled[name] = [before, new]
    return out, scaled


def scaled_value(value: float, ratio: float, power: int) -> float:
    """``value`` x s^power with s^2 = ``ratio``: even powers by the ratio itself (w_v / ratio, not w_v / sqrt(ratio)^2),
    odd ones with one sqrt(ratio); a negative power divides."""
    k, odd = divmod(abs(int(power)), 2)
    m = ratio ** k * (math.sqrt(ratio) if odd else 1.0)
    return float(value) * m if power > 0 else float(value) / m


def spacing_ratio(area: float, robots: int, rule: str = "spacing", site_ratio: float = 1.0) -> float:
    """c^2 = max(1, q^2 / s^2) for ``rule`` "spacing", 1.0 for "off": q^2 = ``area`` / (``robots`` x
    :data:`REFERENCE_ROBOT_AREA`), s^2 = ``site_ratio`` (:func:`area_ratio`, 1 without the site rule)."""
    if rule not in SWARM_SCALE_RULES:
        raise ValueError(f"sim.swarm_scale must be one of {', '.join(repr(r) for r in SWARM_SCALE_RULES)}, got {rule!r}")
    if rule == "off":
        return 1.0
    # "spacing" and "spacing-capped" alike: the run-time rule's cap is the static rule's value
    q2 = float(area) / (int(robots) * REFERENCE_ROBOT_AREA)
    ratio = q2 / float(site_ratio)
    return ratio if ratio > 1.0 else 1.0


def spacing_factor(area: float, robots: int, rule: str = "spacing", site_ratio: float = 1.0) -> float:
    """c = sqrt(:func:`spacing_ratio`): max(1, q / s), the swarm rule's factor."""
    return math.sqrt(spacing_ratio(area, robots, rule, site_ratio))


def scale_document(doc: dict, given: dict, ratio: float, defaults: dict, settings=SCALED) -> tuple[dict, dict]:
    """``doc`` (a configuration document laid over its preset) with the ``settings`` (default :data:`SCALED`;
    :data:`SWARM_SCALED` for the swarm rule) that ``given`` (the
    user's own document) does not set multiplied by s^power, s^2 = ``ratio`` (:func:`area_ratio`);
    ``defaults[section]`` is the settings class whose default stands for a value the preset does not set either.
    Returns (the new document, {"section.key": [value before, value after]} of the values scaled).  A ratio of
    exactly 1 returns ``doc`` itself; a value of ``None`` (e.g. a Silverman bandwidth) is left alone."""
    scaled: dict = {}
    if ratio == 1.0:
        return doc, scaled
    out = {k: (dict(v) if isinstance(v, dict) else v) for k, v in doc.items()}
    for section, key, power in settings:
        value = _unset_number(out, given, section, key, defaults)
        if value is None:
            continue
        new = scaled_value(value, ratio, power)
        out[section][key] = new
        scaled[f"{section}.{key}"] = [float(value), new]
    return out, scaled


def _number(value):
    """``value`` if it is a number (not a bool), else None."""
    return value if isinstance(value, (int, float)) and not isinstance(value, bool) else None


def _unset_number(out: dict, given: dict, section: str, key: str, defaults: dict):
    """The value of ``section.key`` that the user's own document ``given`` does not set, for a rule to scale: ``out``'s
    (the document laid over its preset; its ``section`` table made if missing), else the settings class
    ``defaults[section]``'s default; None when the user sets it, ``out[section]`` is not a table (reported by the
    settings class) or the value is not a number (e.g. a Silverman bandwidth of None)."""
    mine = given.get(section)
    if isinstance(mine, dict) and key in mine:
        return None
    table = out.setdefault(section, {})
    if not isinstance(table, dict):
        return None
    return _number(table.get(key, getattr(defaults[section], key, None)))


def unscaled_map_note(sim, free_area: float) -> str | None:
    """One line when a configuration resolved without a map (``[domain] source`` empty) runs on one whose free area
    ``free_area`` [m^2] gives other factors than the rectangle's area did (:func:`area_ratio`, :func:`length_ratio`,
    :func:`spacing_ratio`): e.g. ``run_simulation(config, domain=Domain)`` with the tuned preset.  The run keeps the
    values as resolved; the note says how to have them scaled by the map.  None when the factors agree (always with
    the paper preset's rules "off")."""
    rect = _rectangle_area(sim.domain)

    def factors(area):
        site = area_ratio(sim.domain, sim.site_scale, area)
        return (site, length_ratio(sim.domain, sim.site_scale, area),
                spacing_ratio(area, sim.robots, sim.swarm_scale, site))

    if all(math.isclose(a, b, rel_tol=1e-12) for a, b in zip(factors(rect), factors(float(free_area)))):
        return None
    return (f"the configuration was resolved without this map, so the site and swarm rules (sim.site_scale, "
            f"sim.swarm_scale) scaled its defaults by the rectangle's {rect:.4g} m^2, not the map's free "
            f"{float(free_area):.4g} m^2; to scale by the map, give it as [domain] source (a file or built-in name; "
            f"config_from_dict(..., domain_source=...), the commands' --domain)")


#: a plan whose transport takes more than this many explicit substeps an interval gets named (the tuned preset on the
#: paper's 20 m square: 45; on a 5 m x 3 m bench 181; ocp.settings.PlannerSettings.substeps)
MAX_PLAN_SUBSTEPS = 450


#: greedy's goals more than this many measurement steps away (sim.greedy_radius, at most the site's diagonal, over
#: v_max dt) get named: 1.9 on the paper's square and on a 5 m bench at 3 m/s, 3.8 at 1.5 m/s; 13 on the table below,
#: where greedy never stopped within 3 T (0.13-0.39 of the field's sd at 3 T) until its radius was scaled with the rest
MAX_GREEDY_STEPS = 8.0


#: a regular expression matching :func:`small_site_note`'s line, for the commands that check every configuration
#: before its runs and say it once there (compare-controllers)
SMALL_SITE_WARNING = r"a site of .* is smaller than settings given in metres"


def small_site_note(config, controller) -> str | None:
    """One line naming the settings, given in metres and m/s for the paper's 20 m square, that a site is too small
    for: for a run of ``controller`` (:class:`sim.controllers.Controller`) on ``config.sim.domain``, the lengths of
    the controller's that are longer than the site's shorter side (``kde.bandwidth`` and ``feedback.spread_radius``
    for the feedback, ``sim.greedy_separation`` for greedy, ``sim.lawnmower_lane`` for the lawnmower), greedy's goals
    more than :data:`MAX_GREEDY_STEPS` measurement steps away (``sim.greedy_radius`` over v_max dt), the robots'
    noise ``sqrt(2 sigma T)`` a period when it is as long (not for the diffusion baseline, whose strategy it is),
    and a plan whose ``planner.reference_speed`` takes more than :data:`MAX_PLAN_SUBSTEPS` transport substeps an
    interval on the site's cells (each plan's time grows with them).  On a 0.5 m x 0.3 m tabletop of microrobots at
    0.05 m/s (docs/results/map-quality.md, "Held-out cases, round 6") the KDE's 1 m bandwidth made the density
    estimate uniform, the 0.05 m^2/s noise moved each robot 0.84 m a period, and the plans took 17 s each, silently.
    None when nothing is named (the paper's square, a 5 m bench)."""
    s = config.sim
    x0, x1, y0, y1 = s.domain
    short, long_ = sorted((x1 - x0, y1 - y0))
    plans = bool(getattr(controller, "needs_plan", False))
    lengths = []
    if plans or getattr(controller, "reads_density", False):
        lengths.append(("kde.bandwidth", config.kde.bandwidth))
    if plans:
        lengths.append(("feedback.spread_radius", config.feedback.spread_radius))
    name = getattr(controller, "name", "")
    if name == "greedy":
        lengths.append(("sim.greedy_separation", s.greedy_separation))
    if name == "lawnmower":
        lengths.append(("sim.lawnmower_lane", s.lawnmower_lane))
    said = [f"{k} {v:g} m" for k, v in lengths if v is not None and v > short]
    parts = []
    if said:
        parts.append(f"{' and '.join(said)} {'is' if len(said) == 1 else 'are'} longer than its shorter side "
                     f"{short:g} m")
    if name == "greedy":
        step = float(getattr(controller, "v_max", config.planner.v_max)) * s.dt
        reach = min(s.greedy_radius, math.hypot(x1 - x0, y1 - y0))
        if step > 0 and reach > MAX_GREEDY_STEPS * step:
            parts.append(f"sim.greedy_radius {s.greedy_radius:g} m puts a robot's goal up to {reach / step:.0f} "
                         f"measurement steps of {step:.3g} m away, and each robot chooses its goal again every step")
    sigma = float(getattr(controller, "sigma", 0.0) or 0.0)
    drift = math.sqrt(2.0 * sigma * s.period)
    if drift >= short and name != "diffusion":          # the diffusion baseline's noise is its strategy
        parts.append(f"the robots' noise (feedback.sigma {sigma:g} m^2/s) moves each one sqrt(2 sigma T) = "
                     f"{drift:.3g} m a period")
    pl = config.planner
    if plans:
        speed = pl.reference_speed or pl.v_max
        sub = dataclasses.replace(pl, v_max=speed, reference_speed=None).substeps
        if sub > MAX_PLAN_SUBSTEPS:
            key = "planner.reference_speed" if pl.reference_speed else "planner.v_max"
            parts.append(f"{key} {speed:g} m/s ({speed / pl.v_max:.3g} x the robots' planner.v_max "
                         f"{pl.v_max:g} m/s) takes {sub} transport substeps an interval on its cells of "
                         f"{(x1 - x0) / pl.nx:.3g} m x {(y1 - y0) / pl.ny:.3g} m (45 with the tuned preset on the "
                         "paper's square), and each plan about as much longer")
    if not parts:
        return None
    return (f"a site of {x1 - x0:g} m x {y1 - y0:g} m is smaller than settings given in metres for the paper's 20 m "
            f"square: {'; '.join(parts)}; scale them to the site (getting started, \"A smaller site\")")


def site_summary(config) -> dict:
    """summary.json's ``site_scale`` block: the rule, the reference area, the site's area (the map's free area with a
    ``[domain]`` map, :func:`site_area`), the factor s, the small site's factor s_small (:func:`length_factor`) and
    the resolved values of the settings the rule scales (whether scaled or given)."""
    s = config.sim
    area = site_area(s.domain, config.domain.source)
    return {"rule": s.site_scale, "reference_area_m2": REFERENCE_AREA, "area_m2": area,
            "factor": site_factor(s.domain, s.site_scale, area),
            "length_factor": length_factor(s.domain, s.site_scale, area),
            "settings": {f"{sec}.{key}": getattr(getattr(config, sec), key) for sec, key, _ in SCALED + LENGTH_SCALED}}


def side_summary(config) -> dict:
    """summary.json's ``site_lengths`` block: the rule (``sim.site_lengths``), the site's shorter side and area, the
    limits under which the rule acts (:data:`SMALL_SIDE`, :data:`REFERENCE_AREA`), the factor r = shorter side /
    :data:`REFERENCE_SIDE` applied (:func:`side_factor`; 1 where the rule does not act) and the resolved values of the
    settings it scales (:data:`SIDE_SCALED`: the lengths the run used, whether scaled or given in the configuration,
    which the rule leaves as given)."""
    s = config.sim
    x0, x1, y0, y1 = (float(v) for v in s.domain)
    return {"rule": s.site_lengths, "shorter_side_m": min(x1 - x0, y1 - y0), "area_m2": (x1 - x0) * (y1 - y0),
            "small_side_m": SMALL_SIDE, "reference_area_m2": REFERENCE_AREA, "reference_side_m": REFERENCE_SIDE,
            "factor": side_factor(s.domain, s.site_lengths),
            "settings": {f"{sec}.{key}": getattr(getattr(config, sec), key) for sec, key in SIDE_SCALED}}


def swarm_summary(config) -> dict:
    """summary.json's ``swarm_scale`` block: the rule, the robots, the site's area, the reference area per robot, the
    factor c (:func:`spacing_factor`) and the resolved values of the settings the rule scales (scaled or given)."""
    s = config.sim
    area = site_area(s.domain, config.domain.source)
    site = area_ratio(s.domain, s.site_scale, area)
    return {"rule": s.swarm_scale, "robots": s.robots, "area_m2": area, "reference_robot_area_m2": REFERENCE_ROBOT_AREA,
            "factor": spacing_factor(area, s.robots, s.swarm_scale, site),
            "settings": {f"{sec}.{key}": getattr(getattr(config, sec), key) for sec, key, _ in SWARM_SCALED}}


def capped_factor(cap: float, length_scale: float, prior_length_scale: float) -> float:
    """f = max(1, min(``cap``, ``length_scale`` / ``prior_length_scale``)): exactly 1.0 when ``cap`` <= 1."""
    if not cap > 1.0:
        return 1.0
    f = min(float(cap), float(length_scale) / float(prior_length_scale))
    return f if f > 1.0 else 1.0


class SpacingCappedByLength:
    """The run-time side of ``sim.swarm_scale = "spacing-capped"`` (module docstring): ``bandwidth`` and ``radius``
    the run's KDE bandwidth and spreading radius at f = 1 (None: left alone, a Silverman bandwidth or no
    spreading), ``cap`` the spacing factor c (:func:`spacing_factor`).  :meth:`update`
    returns the new factor f after a refit, or None when it has not changed (nothing to do).  ``radius_rule``
    (``sim.swarm_radius``, :data:`SWARM_RADIUS_RULES`): the spreading radius at f ("capped") or at c ("spacing",
    :attr:`radius_factor`)."""

    def __init__(self, cap: float, bandwidth: float | None, radius: float | None, radius_rule: str = "capped"):
        if radius_rule not in SWARM_RADIUS_RULES:
            raise ValueError(f"sim.swarm_radius must be one of {', '.join(repr(r) for r in SWARM_RADIUS_RULES)}, "
                             f"got {radius_rule!r}")
        self.cap, self.bandwidth, self.radius = float(cap), bandwidth, radius
        self.radius_rule = radius_rule
        self.factor = 1.0

    @property
    def radius_factor(self) -> float:
        """The spreading radius's factor now: f ("capped"), or the spacing's c ("spacing")."""
        return self.cap if self.radius_rule == "spacing" else self.factor

    def update(self, length_scale: float, prior_length_scale: float) -> float | None:
        f = capped_factor(self.cap, length_scale, prior_length_scale)
        if f == self.factor:
            return None
        self.factor = f
        return f
