"""Venue layouts in plan metres: the corridor rectangles and centre lines a synthetic venue is
built on (scene.build_scene). The ring of the default and small venues, the `twin` venue (two
identical corridors, a copy turned half round, joined by stairs) and the venue families' plans
(`PLANS`: junctions, a hall, long corridors, a comb of side corridors, an atrium, an irregular
loop). `LAYOUTS` names them all; `NAMES` names the corridors of those whose corridors have names.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

Point = tuple[float, float]  # plan metres
Rect = tuple[float, float, float, float]  # x0, y0, x1, y1 (plan metres)
Layout = tuple[Point, list[Rect], list[list[Point]]]  # plan size, corridor rectangles, centre lines


# --- layout ---------------------------------------------------------------------------------


def _ring(x0: float, y0: float, x1: float, y1: float, xm: float, w: float) -> tuple[list[Rect], list[list[Point]]]:
    """A rectangular ring of corridors w wide with a north-south cross corridor at x = xm:
    rectangles (north, south, west, east, middle) and their centre lines."""
    rects = [
        (x0 - w / 2, y0 - w / 2, x1 + w / 2, y0 + w / 2),  # north
        (x0 - w / 2, y1 - w / 2, x1 + w / 2, y1 + w / 2),  # south
        (x0 - w / 2, y0 - w / 2, x0 + w / 2, y1 + w / 2),  # west
        (x1 - w / 2, y0 - w / 2, x1 + w / 2, y1 + w / 2),  # east
        (xm - w / 2, y0 - w / 2, xm + w / 2, y1 + w / 2),  # middle
    ]
    lines = [
        [(x0, y0), (x1, y0)],
        [(x0, y1), (x1, y1)],
        [(x0, y0), (x0, y1)],
        [(x1, y0), (x1, y1)],
        [(xm, y0), (xm, y1)],
    ]
    return rects, lines


def default_layout() -> Layout:
    """A rectangular ring of corridors with a cross corridor: 48 x 20 m between centre lines."""
    x0, y0, x1, y1, xm = 3.0, 3.0, 51.0, 23.0, 27.0
    rects, lines = _ring(x0, y0, x1, y1, xm, 2.4)
    return (x1 + 3.0, y1 + 3.0), rects, lines


def small_layout() -> Layout:
    """An L of two corridors (18 m and 10 m): small enough for fast unit tests."""
    w = 2.4
    rects = [
        (2.0 - w / 2, 2.0 - w / 2, 20.0 + w / 2, 2.0 + w / 2),
        (20.0 - w / 2, 2.0 - w / 2, 20.0 + w / 2, 12.0 + w / 2),
    ]
    lines = [[(2.0, 2.0), (20.0, 2.0)], [(20.0, 2.0), (20.0, 12.0)]]
    return (23.0, 15.0), rects, lines


# The twin layout: a ring of corridors whose west and east sides are twins (the east side is the
# west side turned half round about the ring's centre: the same walls, doors, boards and floor),
# a unique middle corridor, and a dead-end stairwell off the north corridor that no route enters.
TWIN_RING = (3.0, 8.0, 27.0, 20.0)  # x0, y0, x1, y1 of the ring's centre lines
TWIN_MIDDLE_X = 15.0
TWIN_STAIRS = ((9.0, 8.0), (9.0, 2.0))
TWINS = (2, 3)  # rectangles: the original, and its copy turned half round


def twin_layout() -> Layout:
    """A 24 x 12 m ring whose west and east corridors are identical, a middle corridor and a
    6 m stairwell: the venue of the quality map's tests (a deliberately repeated stretch)."""
    w = 2.4
    x0, y0, x1, y1 = TWIN_RING
    xm = TWIN_MIDDLE_X
    (sx, sy0), (_, sy1) = TWIN_STAIRS
    rects, lines = _ring(x0, y0, x1, y1, xm, w)  # the east corridor: the west one turned half round
    rects.append((sx - w / 2, sy1 - w / 2, sx + w / 2, sy0 - w / 2))  # stairwell, ending at the north corridor
    lines.append([TWIN_STAIRS[0], TWIN_STAIRS[1]])
    return (x1 + 3.0, y1 + 3.0), rects, lines


def twin_routes() -> tuple[list[Point], list[Point]]:
    """Each corridor of the ring and the middle one walked once, the stairwell never: the
    modelling walk goes east along the north corridor, south along the east twin, west, north
    along the west twin and down the middle; the query walk is the same the other way round."""
    x0, y0, x1, y1 = TWIN_RING
    xm = TWIN_MIDDLE_X
    model = [(xm, y0), (x1, y0), (x1, y1), (xm, y1), (x0, y1), (x0, y0), (xm, y0), (xm, y1)]
    return model, model[::-1]


def half_turn(x: float, y: float) -> Point:
    """The twin layout's symmetry: half a turn about the ring's centre."""
    x0, y0, x1, y1 = TWIN_RING
    return x0 + x1 - x, y0 + y1 - y


# --- the venue families' layouts (synth/families.py) -------------------------------------------
# Each is a list of centre lines, one corridor rectangle per line (`_corridors`), the layout's own
# modelling and query routes (the query the other way round, on a subset, as a visitor walks), and
# where its glass walls, stairs and halls are.


@dataclass(frozen=True)
class Plan:
    size: Point
    lines: list[tuple[Point, Point, float]]  # centre line ends and corridor width (m)
    names: list[str]
    model: list[Point]  # the modelling route: every corridor the query uses
    query: list[Point]
    halls: list[int] = field(default_factory=list)  # lines whose rectangle is a hall (own rect)
    hall_rects: dict[int, Rect] = field(default_factory=dict)
    glass: list[Rect] = field(default_factory=list)  # walls inside these are glass curtain
    stairs: list[Rect] = field(default_factory=list)  # walls inside these are a stairwell's
    # look-alike corridors: walls inside each of these are painted the same (same place in the
    # rectangle, same wall), as a building's identical side corridors are
    alike: list[Rect] = field(default_factory=list)


def _corridors(plan: Plan) -> Layout:
    rects: list[Rect] = []
    for i, ((ax, ay), (bx, by), w) in enumerate(plan.lines):
        if i in plan.hall_rects:
            rects.append(plan.hall_rects[i])
        else:
            rects.append((min(ax, bx) - w / 2, min(ay, by) - w / 2, max(ax, bx) + w / 2, max(ay, by) + w / 2))
    return plan.size, rects, [[a, b] for a, b, _ in plan.lines]


def _grid_plan() -> Plan:
    """Junctions: two 36 m corridors joined by three cross corridors (T, X and L junctions) and
    two dead-end stubs; 118 m of corridor."""
    w = 2.4
    lines = [
        ((3.0, 5.0), (39.0, 5.0), w),
        ((3.0, 17.0), (39.0, 17.0), w),
        ((3.0, 5.0), (3.0, 17.0), w),
        ((21.0, 5.0), (21.0, 23.0), w),  # crosses the south corridor: an X, then a dead end
        ((39.0, 5.0), (39.0, 17.0), w),
        ((12.0, 17.0), (12.0, 23.0), w),  # dead-end stub
        ((30.0, 5.0), (30.0, 1.6), w),  # dead-end stub to the north
    ]
    names = ["North corridor", "South corridor", "West link", "Middle link", "East link", "South stub", "North stub"]
    model = [
        (3.0, 17.0), (3.0, 5.0), (21.0, 5.0), (21.0, 17.0), (21.0, 23.0), (21.0, 17.0), (39.0, 17.0),
        (39.0, 5.0), (30.0, 5.0), (30.0, 1.6), (30.0, 5.0), (21.0, 5.0), (21.0, 17.0), (12.0, 17.0),
        (12.0, 23.0), (12.0, 17.0), (3.0, 17.0),
    ]  # fmt: skip
    query = [
        (12.0, 23.0), (12.0, 17.0), (21.0, 17.0), (21.0, 5.0), (39.0, 5.0), (39.0, 17.0), (21.0, 17.0),
        (21.0, 5.0), (3.0, 5.0), (3.0, 17.0), (10.0, 17.0),
    ]  # fmt: skip
    return Plan((42.0, 25.5), lines, names, model, query)


def _hall_plan() -> Plan:
    """An open hall (16 x 12 m, glazed along its north side) between two wings of corridors,
    with a ring of corridors round the south; 125 m of corridor and hall."""
    w = 2.4
    lines = [
        ((2.5, 7.0), (16.0, 7.0), w),
        ((16.0, 7.0), (32.0, 7.0), w),  # the hall
        ((32.0, 7.0), (46.0, 7.0), w),
        ((2.5, 7.0), (2.5, 22.0), w),
        ((46.0, 7.0), (46.0, 22.0), w),
        ((2.5, 22.0), (46.0, 22.0), w),
        ((24.0, 3.0), (24.0, 22.0), w),  # through the hall to the south corridor
    ]
    names = ["West wing", "Hall", "East wing", "West corridor", "East corridor", "South corridor", "Hall passage"]
    model = [(24.0, 3.0), (24.0, 22.0), (2.5, 22.0), (2.5, 7.0), (46.0, 7.0), (46.0, 22.0), (24.0, 22.0)]
    query = [(34.0, 22.0), (46.0, 22.0), (46.0, 7.0), (2.5, 7.0), (2.5, 22.0), (24.0, 22.0), (24.0, 5.0)]
    hall = (16.0, 0.8, 32.0, 12.8)
    return Plan(
        (47.5, 24.5), lines, names, model, query, halls=[1], hall_rects={1: hall}, glass=[(15.5, 0.0, 32.5, 1.3)]
    )


def _long_plan() -> Plan:
    """Two 60 m corridors joined at their ends: an institutional floor's long double-loaded
    corridors; 140 m."""
    w = 2.2
    lines = [
        ((3.0, 3.0), (63.0, 3.0), w),
        ((3.0, 13.0), (63.0, 13.0), w),
        ((3.0, 3.0), (3.0, 13.0), w),
        ((63.0, 3.0), (63.0, 13.0), w),
    ]
    names = ["North corridor", "South corridor", "West end", "East end"]
    model = [(3.0, 3.0), (63.0, 3.0), (63.0, 13.0), (3.0, 13.0), (3.0, 3.0)]
    query = [(33.0, 13.0), (63.0, 13.0), (63.0, 3.0), (3.0, 3.0), (3.0, 13.0), (20.0, 13.0)]
    return Plan((66.0, 16.0), lines, names, model, query)


COMB_TEETH = (8.0, 17.0, 26.0, 35.0, 44.0, 53.0)


def _comb_plan() -> Plan:
    """A 59 m spine with six look-alike 8 m side corridors (four dead ends, two joined at their
    far ends) and a stairwell at the spine's east end; 146 m."""
    lines = [((2.5, 3.0), (61.5, 3.0), 2.6)]
    lines += [((x, 3.0), (x, 11.0), 2.0) for x in COMB_TEETH]
    lines += [((44.0, 11.0), (53.0, 11.0), 2.0), ((61.5, 3.0), (61.5, 8.5), 2.6)]
    names = ["Spine", *(f"Side corridor {k + 1}" for k in range(len(COMB_TEETH))), "Back link", "Stairwell"]
    model: list[Point] = [(2.5, 3.0)]
    for x in COMB_TEETH[:4]:
        model += [(x, 3.0), (x, 11.0), (x, 3.0)]
    model += [(44.0, 3.0), (44.0, 11.0), (53.0, 11.0), (53.0, 3.0), (61.5, 3.0), (61.5, 8.5)]
    query = [(61.5, 8.5), (61.5, 3.0), (53.0, 3.0), (53.0, 11.0), (44.0, 11.0), (44.0, 3.0), (35.0, 3.0), (35.0, 11.0)]
    query += [(35.0, 3.0), (17.0, 3.0), (17.0, 11.0), (17.0, 3.0), (2.5, 3.0)]
    alike = [(x - 1.1, 4.0, x + 1.1, 12.1) for x in COMB_TEETH]
    return Plan((64.0, 13.0), lines, names, model, query, stairs=[(60.0, 5.8, 63.0, 10.0)], alike=alike)


def _atrium_plan() -> Plan:
    """A 26 x 16 m atrium glazed on its north and east sides, with a corridor loop off its west
    and south; 122 m of atrium and corridor."""
    w = 2.4
    lines = [
        ((16.0, 9.0), (40.0, 9.0), w),  # across the atrium
        ((30.0, 3.0), (30.0, 27.0), w),  # the atrium's north-south walk, on to the south corridor
        ((3.0, 9.0), (16.0, 9.0), w),
        ((3.0, 9.0), (3.0, 27.0), w),
        ((3.0, 27.0), (30.0, 27.0), w),
        ((30.0, 3.0), (40.0, 3.0), w),  # along the glass
        ((40.0, 3.0), (40.0, 9.0), w),
    ]
    names = ["Atrium", "Atrium walk", "West corridor", "West side", "South corridor", "Glass front", "East walk"]
    model = [(30.0, 3.0), (30.0, 27.0), (3.0, 27.0), (3.0, 9.0), (40.0, 9.0), (40.0, 3.0), (30.0, 3.0)]
    query = [(40.0, 3.0), (40.0, 9.0), (3.0, 9.0), (3.0, 27.0), (30.0, 27.0), (30.0, 10.0)]
    atrium = (16.0, 0.8, 42.8, 17.0)
    return Plan(
        (44.0, 29.5), lines, names, model, query, halls=[0], hall_rects={0: atrium},
        glass=[(15.5, 0.0, 44.0, 1.3), (42.3, 0.0, 44.0, 17.5)],
    )  # fmt: skip


def _loop_plan() -> Plan:
    """An irregular loop of corridors 2.0-3.2 m wide with a cross link: the cross-device venue;
    131 m."""
    lines = [
        ((3.0, 3.0), (40.0, 3.0), 2.0),
        ((40.0, 3.0), (40.0, 14.0), 3.0),
        ((40.0, 14.0), (25.0, 14.0), 2.2),
        ((25.0, 14.0), (25.0, 22.0), 2.0),
        ((25.0, 22.0), (3.0, 22.0), 3.2),
        ((3.0, 22.0), (3.0, 3.0), 2.4),
        ((14.0, 3.0), (14.0, 22.0), 2.0),
    ]
    names = ["North corridor", "East hall", "Middle corridor", "Link", "South corridor", "West corridor", "Cross link"]
    model = [
        (3.0, 3.0),
        (40.0, 3.0),
        (40.0, 14.0),
        (25.0, 14.0),
        (25.0, 22.0),
        (3.0, 22.0),
        (3.0, 3.0),
        (14.0, 3.0),
        (14.0, 22.0),
    ]
    query = [
        (14.0, 22.0),
        (14.0, 3.0),
        (3.0, 3.0),
        (3.0, 22.0),
        (25.0, 22.0),
        (25.0, 14.0),
        (40.0, 14.0),
        (40.0, 3.0),
        (30.0, 3.0),
    ]
    return Plan((43.0, 25.0), lines, names, model, query)


PLANS = {
    "grid": _grid_plan,
    "hall": _hall_plan,
    "long": _long_plan,
    "comb": _comb_plan,
    "atrium": _atrium_plan,
    "loop": _loop_plan,
}


def _plan_layout(name: str) -> Any:
    return lambda: _corridors(PLANS[name]())


LAYOUTS = {
    "default": default_layout,
    "small": small_layout,
    "twin": twin_layout,
    **{name: _plan_layout(name) for name in PLANS},
}
_RING = ["North corridor", "South corridor", "West corridor", "East corridor", "Middle corridor"]
NAMES = {"default": _RING, "twin": [*_RING, "Stairwell"]}  # of the layouts' corridors (else numbered)
