"""Routes along the walk graph, and the spoken guide that walks a user along one.

`plan` takes the shortest path on the walk graph (walkgraph.py) to a place and cuts it into legs:
the path is simplified (Douglas-Peucker, SIMPLIFY_M) and changes of direction under TURN_DEG are
no turns (a corridor that bends a little, a route that steps across from one walk to another), so
every leg boundary is a turn the user makes, or a floor change. Each leg says what is at its end:
a place near it, else "the end of the corridor" (nothing walkable straight on) or "the junction".

`guide` is geometric, not another filter: the tracking filter (tracking.py) already smooths the
pose over time and says when it is unsure, so the guide only has to project that pose onto the
route and decide what to say. What it remembers between answers is a small JSON dict (the route's
nodes, the leg last announced, the furthest point reached, what was said last, where and when, a
spell off the route), so the server keeps it beside the tracking state and any worker can continue
it; a key added later is read with its default from a state written before it. The thresholds are
the issue's, chosen for a walker who cannot see: off the route beyond OFF_ROUTE_M (3 m, wider than
a corridor's half width plus the filter's error) or walking back along it for two answers (more
than AWAY_M behind the furthest point reached, facing more than AWAY_DEG from the leg's way: a
pose that jitters while the user stands is not walking back); arrived within ARRIVE_M (2 m, the
filter's accuracy target); a turn announced before its corner, with the metres still to the
corner (`in_m`: a user told to turn while the corner is ahead would turn into the wall), early
enough at the walker's pace (measured along the route from answer to answer) that the sentence
ends CLEAR_M before the corner though the next answer may be 2.5 s away and saying it takes 4 s
(turn_ahead_m: 11.4 m at 1.2 m/s), never under TURN_AHEAD_M, and cutting in (urgent) rather than
waiting behind another sentence; a lift or stairs TURN_AHEAD_M before them;
the instruction again when the walker, on the route, has faced away from the way on for FACE_AWAY_S;
reassurance every REASSURE_M of walking but never within QUIET_S of the last sentence (a sentence
takes ~3 s to say, and a listener needs a pause); a sentence just said is not said again (`speak`
false).

Arrival ends the guidance (the app stops filming and says so), so it is said as a fact only from a
sure pose (aggregate.SURE, 0.8, the line at which an answer stops being "probably") on a track that
has settled: no more than a third of the guidance's answers of the last SETTLE_S (30 s) low. Within
ARRIVE_M otherwise the guide says "You are probably at Room 102; ..." (`probably_arrived`, urgent
too: the walker should stop and listen) and goes on: the next sure answer there on a settled track
says "You have arrived", and one that finds the walker elsewhere (a look-alike place, or walked on
past it) guides on from there. Why both: in the modelled venue a tracked pose under 0.8 is within
2 m of the truth 84-100 % of the time, a sure one 99.5 %; and the settling is the guide's "not
here": a walker somewhere the venue never modelled gets two thirds of their answers low, and the
odd sure one between them landed on the destination's look-alike in a quarter of such guidances
(bench/guided.py, held-out, a look-alike building: 6 of 24, and 1 with the rule, for 1-2 of 24
destinations in the venue told "probably" instead). SETTLE_S and SETTLE_LOW were chosen on the
tuning families (docs/benchlog.md, "Arrival").

"Not here": when more than half the answers of a whole minute of guidance (NOT_HERE_S) were low,
the guide says once, of a low answer (never in place of a sure one), "You may be outside the
mapped area; ..." (`not_here`, no instruction), and again only after the answers have settled
meanwhile (no more than SETTLE_LOW of the minute low). The minute is one of answers: a pause of
more than PAUSE_S between two (Start pressed a while after the preview, the page hidden) starts it
again.
Somewhere the venue never modelled two thirds of the answers are low; in the venue more than half
of a minute never was on the tuning walks (bench/guided.py: heard in 20-23 of 24 held-out
guidances in a look-alike building, in none of the 8 held-out walks guided in the venue). The
state keeps the answers of the last minute for both rules (at most RECENT_MAX of them).

"Not sure" has hysteresis, since the filter's confidence of a split belief sits just under the
threshold (capped at 0.45) and a pose that crosses it at every answer would make the guide talk at
every answer: the guide says "not sure" after LOW_ANSWERS low answers in a row (ambiguous, or under
`low_confidence`) or one clearly low one (under CLEAR_LOW); a single low answer is held (nothing
said, nothing decided on it: no turn, no off route, no arrival; a user's turn may then be said one
answer later, nearer its corner, which `in_m` still says). After a spell of "not sure" the
instruction is said again only when its leg changed or QUIET_S has passed since it was last said.

Off the route is said once per spell, not at every departure: a walker who goes on the wrong way
leaves each new route within an answer or two, and hearing "You are off the route" every 4 s is
noise that hides the instructions. The first departure says it (urgent) and starts a spell; the
next answer that finds the walker on the new route says its instruction, as ever. While the spell
lasts, a further departure plans a new route from where the walker is (the plan and the bearings
follow them) but says "off the route" again only at the first departure OFF_AGAIN_S (15 s) or more
after the spell's last warning (the same words as that one, said all the same: a walker who keeps
going hears it about every 15 s); in between it says the new route's instruction instead (not
urgent) when its way is news: a bearing TURNED_DEG (45 degrees) or more from the last one said in
the spell (the walker turned; a bearing that wavers by a few degrees is not news), another floor
change, or anything after a "not sure"; else nothing (the instruction stays in the answer for
"What next?"). The spell ends when the walker is back on a route: a sure answer within
OFF_ROUTE_M of it, having walked REJOIN_M along it; a departure after that is news again and is
said at once.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any, Protocol

import numpy as np

from .aggregate import SURE  # arrival is said as a fact from this confidence, as an answer is
from .walkgraph import WalkGraph, place_key, simplify

TURN_DEG = 30.0  # a change of direction under this is no turn
SIMPLIFY_M = 1.0  # a route's nodes within this of the straight line between its corners lie on it
MIN_LEG_M = 1.5  # a leg shorter than this (a step across at a junction) joins its neighbour
UNTIL_M = 3.0  # a place within this of a leg's end names what is there
STRAIGHT_ON_M = 3.0  # the walkable space this far beyond a leg's end, straight on: a junction
OFF_ROUTE_M = 3.0
AWAY_M = 1.0  # more than this behind the furthest point reached on the route (and facing back) is walking away
AWAY_ANSWERS = 2
AWAY_DEG = 90.0  # and facing more than this from the leg's way
ARRIVE_M = 2.0
TURN_AHEAD_M = 3.0  # a turn is said at least this far before its corner ...
# ... and, at the walker's pace, early enough that its sentence ends CLEAR_M before the corner: the
# next answer may come an ANSWER_S later (the app films 2 s every 2.5 s while guiding), it reaches
# the phone LATENCY_S after its clip ended, and it takes SPEAK_S to say
SPEAK_S = 4.0
ANSWER_S = 2.5
LATENCY_S = 0.5
CLEAR_M = 3.0  # (2 m asked; a metre more for the error of a pace measured from two or three answers)
PACE_MPS = 1.0  # the pace assumed before two answers on the route measure it
MAX_PACE_MPS = 2.0  # a faster move between two answers is the pose jumping, not walking
REASSURE_M = 10.0
QUIET_S = 6.0
FACE_AWAY_S = 6.0  # facing away from the way on this long (and QUIET_S since the last sentence): said
OFF_AGAIN_S = 15.0  # "off the route" again, in one spell, no sooner than this after the last
TURNED_DEG = 45.0  # in a spell off the route, a new way this far from the last one said is news
REJOIN_M = 3.0  # metres walked along a new route that end a spell off the route (one answer's walk)
LOW_CONFIDENCE = 0.5  # below it the pose is low (config.py's default for single answers)
LOW_ANSWERS = 2  # low answers in a row before "not sure"
CLEAR_LOW = 0.35  # a confidence under this is "not sure" at once
SETTLE_S = 30.0  # arrival as a fact: the guidance's answers of the last 30 s ...
SETTLE_LOW = 1.0 / 3.0  # ... no more than a third of them low
NOT_HERE_S = 60.0  # "not here": of the guidance's answers of the last minute (a whole minute guided) ...
NOT_HERE_LOW = 0.5  # ... more than half low; said once, until no more than SETTLE_LOW of them are
PAUSE_S = 10.0  # answers further apart than this start "not here"'s minute again
RECENT_MAX = 64  # the most answers kept (a client's clock that stands still must not grow the state)
INSTRUCTIONS = ("start", "turn", "floor_change")  # the kinds that say the instruction
LOST = ("unsure", "not_here")  # the kinds that say where the user is not known, and no instruction
STATE_VERSION = 1
END_OF_CORRIDOR = "the end of the corridor"
JUNCTION = "the junction"


@dataclass(frozen=True)
class Leg:
    nodes: list[int]
    length_m: float
    heading_deg: float  # plan heading of the leg, clockwise from up
    turn_deg: float  # relative to the previous leg, clockwise, (-180, 180]; 0 for a floor's first
    floor: str
    via: str | None = None  # a floor change leg: "lift" | "stairs"
    to_floor: str | None = None
    until: str | None = None  # what is at its end: a place, else END_OF_CORRIDOR / JUNCTION


@dataclass(frozen=True, eq=False)
class Route:
    nodes: list[int]
    xy: np.ndarray  # (len(nodes), 2) plan metres
    length_m: float  # metres walked (a floor change adds none)
    legs: list[Leg]
    to: dict[str, Any]  # the destination place: {"id", "name", "floor"[, "say"]}
    along: np.ndarray = field(default_factory=lambda: np.zeros(0))  # (len(nodes),) metres walked to each node

    def preview(self) -> dict[str, Any]:
        """The route in numbers: {"length_m", "turns", "first_turn_m", "floors"} (metres rounded)."""
        turns = [k for k, leg in enumerate(self.legs) if leg.via is None and leg.turn_deg != 0.0]
        first = _round(_leg_span(self, turns[0])[0]) if turns else None
        floors: list[str] = []
        for leg in self.legs:
            for f in (leg.floor, leg.to_floor):
                if f is not None and (not floors or floors[-1] != f):
                    floors.append(f)
        if not floors:
            floors = [str(self.to.get("floor", ""))]
        return {"length_m": _round(self.length_m), "turns": len(turns), "first_turn_m": first, "floors": floors}


class Pose(Protocol):
    """What the guide needs of a pose (tracking_state.TrackPose has it)."""

    @property
    def x(self) -> float: ...
    @property
    def y(self) -> float: ...
    @property
    def floor(self) -> str: ...
    @property
    def heading(self) -> float: ...
    @property
    def confidence(self) -> float: ...
    @property
    def ambiguous(self) -> bool: ...


def _signed(b: float) -> float:
    r = (b + 180.0) % 360.0 - 180.0
    return 180.0 if r == -180.0 else r


def _round(v: float) -> int:
    return math.floor(v + 0.5)


def heading_of(dx: float, dy: float) -> float:
    """Plan heading of a step (dx, dy), degrees clockwise from up (y down), in [0, 360)."""
    return math.degrees(math.atan2(dx, -dy)) % 360.0


# --- planning -----------------------------------------------------------------------------------


def _corners(p: np.ndarray) -> list[int]:
    """A floor's stretch of route (K, 2) -> indices of its corners (ends included): simplified,
    then the smallest turn under TURN_DEG dropped until none is left, then legs under MIN_LEG_M
    joined to a neighbour."""
    keep: list[int] = [int(k) for k in simplify(p, SIMPLIFY_M)]

    def turn(k: int) -> float:
        a, b, c = p[keep[k - 1]], p[keep[k]], p[keep[k + 1]]
        return abs(_signed(heading_of(*(c - b)) - heading_of(*(b - a))))

    def seg(k: int) -> float:
        return float(np.hypot(*(p[keep[k + 1]] - p[keep[k]])))

    while len(keep) > 2:
        turns = [turn(k) for k in range(1, len(keep) - 1)]
        k = int(np.argmin(turns))
        if turns[k] < TURN_DEG:
            del keep[k + 1]
            continue
        short = [k for k in range(len(keep) - 1) if seg(k) < MIN_LEG_M]
        if not short:
            break
        k = short[0]
        del keep[k + 1 if k + 1 < len(keep) - 1 else k]  # never an end of the stretch
    return keep


def _until(graph: WalkGraph, nodes: list[int], heading: float, places: Sequence[Mapping[str, Any]]) -> str:
    """What is at the end of a leg: the nearest place within UNTIL_M (points, not areas), else
    JUNCTION when the walkable space goes on straight ahead, else END_OF_CORRIDOR."""
    end = nodes[-1]
    ex, ey = graph.xy[end]
    fl = str(graph.floor[end])
    near = [
        (math.hypot(float(p["x"]) - ex, float(p["y"]) - ey), str(p["name"]))
        for p in places
        if not p.get("area") and str(p.get("floor") or fl) == fl
    ]
    near = [n for n in near if n[0] <= UNTIL_M]
    if near:
        return min(near)[1]
    d = graph.distances(end, limit=STRAIGHT_ON_M + 1.0)[0]
    ids = np.flatnonzero(np.isfinite(d) & (graph.floor == fl))
    for k in ids:
        dx, dy = graph.xy[k] - (ex, ey)
        r = math.hypot(dx, dy)
        if r >= STRAIGHT_ON_M * 0.5 and abs(_signed(heading_of(dx, dy) - heading)) <= TURN_DEG:
            return JUNCTION
    return END_OF_CORRIDOR


def target(place: Mapping[str, Any], floor: str) -> dict[str, Any]:
    """The guidance's `to`: {"id", "name", "floor"} (+ "say" when the place has one)."""
    to = {"id": place_key(place), "name": str(place["name"]), "floor": str(place.get("floor") or floor)}
    if place.get("say"):
        to["say"] = str(place["say"])
    return to


def route_of(
    graph: WalkGraph, nodes: Sequence[int], place: Mapping[str, Any], places: Sequence[Mapping[str, Any]] = ()
) -> Route:
    """A path's nodes (start -> the place's node) -> the Route with its legs."""
    nodes = [int(n) for n in nodes]
    xy = graph.xy[nodes]
    fl = [str(graph.floor[n]) for n in nodes]
    along = np.zeros(len(nodes))
    for k in range(1, len(nodes)):
        step = 0.0 if fl[k] != fl[k - 1] else float(np.hypot(*(xy[k] - xy[k - 1])))
        along[k] = along[k - 1] + step
    legs: list[Leg] = []
    start = 0
    prev_heading: float | None = None
    for k in range(1, len(nodes) + 1):
        if k < len(nodes) and fl[k] == fl[k - 1]:
            continue
        run = list(range(start, k))  # one floor's stretch: route indices start..k-1
        if len(run) > 1:
            corners = _corners(xy[run])
            for a, b in zip(corners[:-1], corners[1:], strict=True):
                seg = nodes[start + a : start + b + 1]
                h = heading_of(*(xy[start + b] - xy[start + a]))
                last = k == len(nodes) and b == len(run) - 1
                legs.append(
                    Leg(
                        nodes=seg,
                        length_m=float(along[start + b] - along[start + a]),
                        heading_deg=round(h, 1),
                        turn_deg=0.0 if prev_heading is None else round(_signed(h - prev_heading), 1),
                        floor=fl[k - 1],
                        until=str(place["name"]) if last else _until(graph, seg, h, places),
                    )
                )
                prev_heading = h
        if k < len(nodes):  # a floor change k-1 -> k
            i, j = nodes[k - 1], nodes[k]
            via = graph.via.get((min(i, j), max(i, j)), "lift")
            legs.append(Leg([i, j], 0.0, round(prev_heading or 0.0, 1), 0.0, fl[k - 1], via, fl[k]))
            prev_heading = None
            start = k
    return Route(nodes, xy, float(along[-1]) if len(along) else 0.0, legs, target(place, fl[-1]), along)


def plan(
    graph: WalkGraph,
    start: int,
    place: Mapping[str, Any],
    place_node: int,
    places: Sequence[Mapping[str, Any]] = (),
) -> Route | None:
    """The shortest route along the walk graph from node `start` to the place (at `place_node`),
    None when the place cannot be reached. `places` (the venue's) name what is at each leg's end."""
    nodes = graph.path(int(start), int(place_node))
    return route_of(graph, nodes, place, places) if nodes else None


# --- guiding ------------------------------------------------------------------------------------


@dataclass(frozen=True)
class _Where:
    """A pose projected on the route: metres walked along it, metres off it, the route index of
    the segment it is on."""

    along: float
    off: float
    k: int


def _project(route: Route, floor: np.ndarray, x: float, y: float, fl: str) -> _Where | None:
    """The nearest point of the route's stretches on floor `fl` (None: the route has none there)."""
    if len(route.nodes) == 1:
        if floor[0] != fl:
            return None
        return _Where(0.0, float(np.hypot(*(route.xy[0] - (x, y)))), 0)
    a, b = route.xy[:-1], route.xy[1:]
    same = (floor[:-1] == fl) & (floor[1:] == fl)
    if not same.any():
        return None
    ab = b - a
    L2 = np.einsum("ij,ij->i", ab, ab)
    t = np.clip(np.einsum("ij,ij->i", np.array([x, y]) - a, ab) / np.where(L2 > 0, L2, 1.0), 0.0, 1.0)
    d = np.hypot(*(a + t[:, None] * ab - (x, y)).T)
    d = np.where(same, d, np.inf)
    k = int(np.argmin(d))  # the first of equals: the earlier part of the route
    along = float(route.along[k] + t[k] * (route.along[k + 1] - route.along[k]))
    return _Where(along, float(d[k]), k)


def _leg_start(route: Route, i: int) -> int:
    """Route index of leg i's first node (legs follow each other, sharing their corner nodes)."""
    return sum(len(leg.nodes) - 1 for leg in route.legs[:i])


def _leg_span(route: Route, i: int) -> tuple[float, float]:
    """Metres along the route where leg i starts and ends."""
    k0 = _leg_start(route, i)
    return float(route.along[k0]), float(route.along[k0 + len(route.legs[i].nodes) - 1])


def _leg_at(route: Route, s: float, fl: str) -> int:
    """The leg being walked at `s` metres along on floor `fl`: the last walking leg of that floor
    starting at or before s; where the route walks nowhere on that floor (it starts at a lift),
    its floor change from there."""
    cur = -1
    for i, leg in enumerate(route.legs):
        if leg.via is None and leg.floor == fl and (cur < 0 or _leg_span(route, i)[0] <= s + 1e-9):
            cur = i
    if cur < 0:
        cur = next((i for i, leg in enumerate(route.legs) if leg.floor == fl), 0)
    return cur


def _ahead(route: Route, floors: np.ndarray, w: _Where, fl: str) -> list[list[float]]:
    """The route ahead on the user's floor, from the user's point on it, as its corners."""
    k = w.k
    pts = [route.xy[k]]
    if k + 1 < len(route.nodes) and floors[k + 1] == fl:
        seg = float(route.along[k + 1] - route.along[k])
        t = (w.along - float(route.along[k])) / seg if seg > 0 else 0.0
        pts = [route.xy[k] + t * (route.xy[k + 1] - route.xy[k])]
        for j in range(k + 1, len(route.nodes)):
            if floors[j] != fl:
                break
            pts.append(route.xy[j])
    p = np.asarray(pts)
    p = p[simplify(p, 0.05)]
    return [[round(float(x), 2), round(float(y), 2)] for x, y in p]


def turn_ahead_m(pace: float | None) -> float:
    """How far before its corner a turn is said, at a walker's pace (m/s; None: not measured yet):
    the walk of the wait for the next answer, its latency and its sentence, plus CLEAR_M, and never
    under TURN_AHEAD_M. At 1.2 m/s, 11.4 m: the sentence ends 3-6 m before the corner."""
    v = PACE_MPS if pace is None else pace
    return max(TURN_AHEAD_M, v * (ANSWER_S + LATENCY_S + SPEAK_S) + CLEAR_M)


def _pace(st: Mapping[str, Any], s: float, t: float, replanned: bool) -> float | None:
    """The walker's pace after an answer at `s` metres along the route at `t`: the last one's (a
    state written before it: none), halfway to the pace since the last answer (metres along the
    route over seconds, forward only, at most MAX_PACE_MPS); unchanged across a new route or a
    pause of more than PAUSE_S (the walk then is not this one's)."""
    pace = st.get("pace")
    ts = st.get("ts")
    if ts is None or replanned or not 0.0 < t - float(ts) <= PAUSE_S:
        return None if pace is None else float(pace)
    v = min(MAX_PACE_MPS, max(0.0, s - float(st["s"])) / (t - float(ts)))
    return v if pace is None else 0.5 * float(pace) + 0.5 * v


def new_state(graph: WalkGraph, place: Mapping[str, Any]) -> dict[str, Any]:
    """The guide's memory before its first answer (JSON-able; the server stores it as it is)."""
    return {
        "v": STATE_VERSION,
        "graph": graph.key,  # a state from another graph (the venue modelled again) starts over
        "to": place_key(place),
        "started": False,  # the route's start has been said
        "nodes": [],  # the route being followed (graph nodes)
        "leg": -1,  # the leg last announced
        "s": 0.0,  # metres along the route at the last answer
        "far": 0.0,  # the furthest metres along the route reached
        "away": 0,  # answers in a row walking back along the route
        "low": 0,  # low-confidence answers in a row
        "said": None,  # the last sentence spoken: {"kind", "key", "t", "s"}
        "told": None,  # when the instruction (start, turn, floor change) was last spoken: t
        "off": None,  # a spell off the route: {"t": its last warning, "way": the last way said}
        "on_route": False,
        "remaining_m": None,
        "recent": [],  # the answers of the last NOT_HERE_S (after the first): [t, 1 if low else 0]
        "t0": None,  # when this guidance's first answer came
        "lost": False,  # "not here" was said, and the answers have not settled since
        "pace": None,  # the walker's pace along the route (m/s, smoothed), None before it is measured
        "ts": None,  # when the pose was at "s"
    }


def _valid(state: Mapping[str, Any] | None, graph: WalkGraph, place: Mapping[str, Any], place_node: int) -> bool:
    """A state to continue: this graph's, this place's, and its route ends at the place's node (a
    place moved since the route was planned starts over)."""
    try:
        return bool(
            state is not None
            and state.get("v") == STATE_VERSION
            and state.get("graph") == graph.key
            and state.get("to") == place_key(place)
            and all(0 <= int(n) < len(graph) for n in state["nodes"])
            and (not state["started"] or (len(state["nodes"]) > 0 and int(state["nodes"][-1]) == int(place_node)))
        )
    except (TypeError, ValueError, KeyError, AttributeError):
        return False


def guide(
    graph: WalkGraph,
    route: Route | None,
    place: Mapping[str, Any],
    place_node: int,
    pose: Pose,
    state: Mapping[str, Any] | None,
    t_now: float,
    places: Sequence[Mapping[str, Any]] = (),
    floor_names: Mapping[str, str] | None = None,
    style: str = "clock",
    low_confidence: float = LOW_CONFIDENCE,
    sure: float = SURE,
    settle_s: float = SETTLE_S,
) -> tuple[dict[str, Any], dict[str, Any]]:
    """One answer's guidance towards `place` -> (guidance JSON, the new state JSON).

    `state` is what the previous answer returned (None, or one from another graph or place, or one
    whose route no longer ends at `place_node`: start over). `route` is used for the start (the
    caller planned it); None plans from the pose. Later answers follow the state's route, and
    replan here when the user leaves it. `places` (the venue's) name what is at the legs' ends; the
    sentence is in `style`; floors are named by `floor_names` (default "floor <id>"). Arrival is
    said as a fact from `sure`, and only if no more than a third of the answers of the last
    `settle_s` were low (0: not asked; bench/guided.py measures the rules before)."""
    from .describe import guidance_sentence  # the words: pure, shared with the app

    ok = state is not None and _valid(state, graph, place, place_node)
    st: dict[str, Any] = dict(state) if state is not None and ok else new_state(graph, place)
    st["nodes"] = [int(n) for n in st["nodes"]]
    st["far"] = float(st.get("far", st["s"]))  # a state written before these keys
    st["low"] = int(st.get("low", 0))
    st.setdefault("told", None)
    st["off"] = _spell(st.get("off"))
    said: dict[str, Any] | None = st.get("said")
    fl = str(pose.floor)
    names = dict(floor_names or {})
    cur = route_of(graph, st["nodes"], place, places) if st["started"] else None
    to = cur.to if cur else target(place, str(graph.floor[place_node]))

    hold = False  # a single low answer: nothing decided on it (below)
    rejoined = False  # this answer ends a spell off the route (said, when nothing else is)

    def answer(
        kind: str, key: str | None = None, speak: bool = True, **kw: Any
    ) -> tuple[dict[str, Any], dict[str, Any]]:
        g: dict[str, Any] = {
            "to": to,
            "kind": kind,
            "speak": speak,
            "urgent": kind in ("off_route", "arrived", "probably_arrived"),
            "bearing_deg": None,
            "walk_m": None,
            "until": None,
            "in_m": None,
            "next_turn_m": None,
            "remaining_m": st["remaining_m"],
            "on_route": bool(st["on_route"]),
            "arrived": kind == "arrived",
            "floor_change": None,
        }
        g.update(kw)
        g.setdefault("route", [])
        if kind not in ("start", "turn", "continue"):
            g["in_m"] = None
        for f in ("bearing_deg", "walk_m", "in_m", "next_turn_m", "remaining_m"):
            if g[f] is not None:
                g[f] = round(float(g[f]), 1)
        if g["in_m"] == 0.0:  # at the corner: the turn is now
            g["in_m"] = None
        if kind == "turn" and g["in_m"] is not None:  # before its corner: heard before it, cutting in
            g["urgent"] = True
        g["sentence"] = guidance_sentence(g, style)  # type: ignore[arg-type]
        key = key or kind
        if said is not None and said.get("key") == key:  # nothing said again that was just said
            g["speak"] = False
        if kind == "unsure" and st.get("lost") and said is not None and said.get("kind") == "not_here":
            g["speak"] = False  # "not here" said "keep walking slowly" already
        if g["speak"]:
            st["said"] = {"kind": kind, "key": key, "t": float(t_now), "s": float(st["s"])}
            if kind in INSTRUCTIONS:
                st["told"] = float(t_now)
            # the spell off the route: when it was last said, and the last way said in it
            if kind == "off_route":
                st["off"] = {"t": float(t_now), **_way(g)}
            elif st["off"] is not None and kind in INSTRUCTIONS:
                st["off"] = {**st["off"], **_way(g)}
        if not hold:  # a held answer leaves the state as the last sure one left it
            st["on_route"], st["remaining_m"] = g["on_route"], g["remaining_m"]
        return g, st

    # not sure where the user is: say so once, and no instruction. One low answer on a route is
    # held instead (a confidence that hovers about the threshold must not make the guide talk)
    c = float(pose.confidence)
    low = bool(pose.ambiguous) or not (math.isfinite(c) and c >= low_confidence)  # NaN is not sure
    st["low"] = st["low"] + 1 if low else 0
    # the guidance's answers of the last `settle_s`, for arrival (the one that started this state
    # is not counted: a new session's first answer is always young)
    past = _recent(st.get("recent"), float(t_now), max(settle_s, NOT_HERE_S)) if ok else []
    last = [v for t, v in past if t >= float(t_now) - settle_s]
    unsettled = bool(last) and sum(last) > SETTLE_LOW * len(last)
    st["recent"] = (past + [[float(t_now), int(low)]])[-RECENT_MAX:] if ok else []
    # the minute "not here" asks for is one of answers: a pause (Start pressed a while after the
    # preview, the page hidden, Stop and Start) starts it again
    t0 = st.get("t0")
    going = bool(past) and float(t_now) - past[-1][0] <= PAUSE_S
    fine = ok and going and isinstance(t0, int | float) and math.isfinite(t0) and t0 <= float(t_now)
    st["t0"] = float(t0) if fine else float(t_now)  # type: ignore[arg-type]
    # not here: most of a minute's answers low (two thirds where the venue was never modelled, a
    # tenth at most in it); said once, and again only after the answers have settled meanwhile
    share = sum(v for _, v in st["recent"]) / len(st["recent"]) if st["recent"] else 0.0
    whole = float(t_now) - float(st["t0"]) >= NOT_HERE_S
    if st.get("lost") and share <= SETTLE_LOW:
        st["lost"] = False
    if low and whole and share > NOT_HERE_LOW and not st.get("lost"):  # said of a low answer, never of a sure one
        st["lost"] = True
        st["low"] = LOW_ANSWERS  # what follows is "not sure" until a sure answer, said as ever
        return answer("not_here", key=f"not_here:{float(t_now)}", on_route=False)
    if low and (not st["started"] or pose.confidence < CLEAR_LOW or st["low"] >= LOW_ANSWERS):
        return answer("unsure")
    hold = low  # nothing decided on this pose: not spoken, the state's progress kept

    fresh = cur is None
    if cur is None:
        cur = route or plan(graph, graph.nearest(pose.x, pose.y, fl), place, place_node, places)
        if cur is None:  # no way from here to there
            return answer("unsure", on_route=False)
        st.update(started=True, nodes=list(cur.nodes), leg=-1, s=0.0, far=0.0, away=0, off=None)

    # arrived: within ARRIVE_M of the place's node, on its floor (or a route with nowhere to walk)
    px, py = float(place["x"]), float(place["y"])
    nx, ny = graph.xy[place_node]
    there = fl == str(graph.floor[place_node]) and math.hypot(nx - pose.x, ny - pose.y) <= ARRIVE_M
    if not there and not cur.legs and not fresh and not hold:  # planned at the place, and the user has left it since
        new = plan(graph, graph.nearest(pose.x, pose.y, fl), place, place_node, places)
        if new is not None and new.legs:
            cur, fresh = new, True
            st.update(nodes=list(cur.nodes), leg=-1, s=0.0, far=0.0, away=0, off=None)
    if (there and not hold) or not cur.legs:
        st["away"] = 0
        # arrival ends the guidance, so it is said as a fact only from a sure pose; under that it is
        # "probably" there and the guide goes on until the pose firms up (or shows it was elsewhere)
        fact = not hold and c >= sure and not unsettled
        return answer(
            "arrived" if fact else "probably_arrived",
            speak=not hold,
            bearing_deg=_bearing(pose, px, py),
            walk_m=math.hypot(px - pose.x, py - pose.y),
            remaining_m=0.0,
            on_route=True,
        )

    floors = np.array([str(graph.floor[n]) for n in cur.nodes])
    w = _project(cur, floors, pose.x, pose.y, fl)
    if hold and (w is None or w.off > OFF_ROUTE_M):  # a low pose away from the route: nothing to say of it
        return answer("unsure", speak=False)
    off = False
    if not fresh and not hold:
        if w is None or w.off > OFF_ROUTE_M:
            off = True
        else:  # walking back: behind the furthest point reached, facing away from the leg's way
            way = cur.legs[_leg_at(cur, w.along, fl)].heading_deg
            facing_away = abs(_signed(pose.heading - way)) > AWAY_DEG
            back = w.along < float(st["far"]) - AWAY_M and facing_away
            st["away"] = st["away"] + 1 if back else 0
            off = st["away"] >= AWAY_ANSWERS
            # since when the walker faces away from the way on (standing, or turned round in place)
            st["facing_away"] = (st.get("facing_away") or float(t_now)) if facing_away and not off else None
    if off:  # a new route from where the user is
        new = plan(graph, graph.nearest(pose.x, pose.y, fl), place, place_node, places)
        if new is None:
            return answer("unsure", on_route=False)
        cur = new
        st.update(nodes=list(cur.nodes), leg=-1, far=0.0, away=0)
        floors = np.array([str(graph.floor[n]) for n in cur.nodes])
        w = _project(cur, floors, pose.x, pose.y, fl)
    if w is None:  # the route starts on another floor than the pose's (a caller's route)
        w = _Where(0.0, 0.0, 0)
    s = w.along
    if not hold:
        st["pace"] = _pace(st, s, float(t_now), off)
        st["s"], st["far"], st["ts"] = s, max(float(st["far"]), s), float(t_now)
        if not off and st["far"] >= REJOIN_M:  # back on a route: the next departure is news again
            rejoined = st["off"] is not None
            st["off"] = None
    remaining = max(0.0, cur.length_m - s)

    # the instruction: the leg being walked, or the next one when its corner is near
    li = _leg_at(cur, s, fl)
    # a turn is said in time at the walker's pace; a lift or stairs when there (the sentence does
    # not say how far, and a walker told to take the lift 9 m early looks for it here)
    lift_next = li + 1 < len(cur.legs) and cur.legs[li + 1].via is not None
    ahead_m = TURN_AHEAD_M if lift_next else turn_ahead_m(st.get("pace"))
    # (off the route, the way back onto it first: "turn to 9 o'clock" for the corner after it would
    # turn a walker who overshot the corner into the wall)
    near_end = _leg_span(cur, li)[1] - s <= (TURN_AHEAD_M if off else ahead_m)
    ci = li + 1 if cur.legs[li].via is None and li + 1 < len(cur.legs) and near_end else li
    leg = cur.legs[ci]
    a, b = _leg_span(cur, ci)
    # the next leg's turn, said before its corner: how far the corner still is
    in_m = _leg_span(cur, li)[1] - s if ci == li + 1 and leg.via is None else None
    common: dict[str, Any] = {
        "bearing_deg": _signed(leg.heading_deg - pose.heading),
        "remaining_m": remaining,
        "on_route": not off,
        "route": _ahead(cur, floors, w, fl),
    }
    if leg.via is not None:  # the lift or the stairs: what is there, how far
        common.update(walk_m=max(0.0, a - s), until=cur.legs[ci - 1].until if ci > 0 else None)
        common.update(next_turn_m=common["walk_m"], floor_change=floor_change(leg, names))
    else:
        walk = b - max(s, a)  # an instruction about the next leg, before its corner: all of it
        if ci == 0 and s <= 0.0 and w.off > 1.0:  # the walker is past the route's start (a route
            walk += w.off  # planned from where they left the last one): the way to it too
        # the next turn: the corner ahead, else the end of this leg (none on the last)
        nxt = in_m if in_m is not None else walk if ci + 1 < len(cur.legs) else None
        common.update(walk_m=walk, until=leg.until, in_m=in_m, next_turn_m=nxt)
    kind = "floor_change" if leg.via is not None else "turn"
    if hold:  # the instruction as the pose has it, for "What next?"; nothing said or decided
        return answer("continue" if leg.via is None else kind, key=f"continue:{ci}", speak=False, **common)
    if fresh:
        st["leg"] = ci
        return answer("start", key=f"start:{ci}", preview=cur.preview(), **common)
    said_kind = said.get("kind") if said is not None else None
    if off:
        spell = st["off"]
        if spell is None or float(t_now) - spell["t"] >= OFF_AGAIN_S:
            # the new route's first leg is announced at the next answer on it; a repeat is its own
            # sentence (the same words as the last warning, which may be all that was said since)
            key = f"off_route:{cur.nodes[0]}" + ("" if spell is None else f":{float(t_now)}")
            return answer("off_route", key=key, **common)
        # off again within the spell: the new route's instruction if the walker turned (or it has
        # not been said since a "not sure"), else nothing
        st["leg"] = ci
        if said_kind in LOST or _turned(spell, _way(common)):
            return answer(kind, key=f"{kind}:{ci}:{cur.nodes[0]}:{float(t_now)}", **common)
        return answer("continue" if leg.via is None else kind, key=f"continue:{ci}", speak=False, **common)
    # a new leg ahead (never one behind: a pose that wavers about the corner says nothing twice),
    # or the route planned anew; after a spell of "not sure", the same leg again once QUIET_S has
    # passed since it was last said
    told = st["told"]
    again = said_kind in LOST and (told is None or float(t_now) - float(told) >= QUIET_S)
    if ci > st["leg"] or said_kind == "off_route" or again:
        st["leg"] = max(ci, int(st["leg"]))
        return answer(kind, key=f"{kind}:{ci}:{cur.nodes[-1]}", **common)
    told_t = float(said.get("t", -math.inf)) if said is not None else -math.inf
    away_since = st.get("facing_away")
    facing_long = away_since is not None and float(t_now) - float(away_since) >= FACE_AWAY_S
    if facing_long and st["off"] is None and float(t_now) - told_t >= QUIET_S:
        # on the route, facing away from the way on for a while: the instruction again, from where
        # the walker faces now ("Turn to 6 o'clock and walk ..."). (Off the route the spell's own
        # rules speak: "off the route" every OFF_AGAIN_S, a new way when it is news.)
        return answer(kind, key=f"{kind}:{ci}:away:{float(t_now)}", **common)
    if rejoined and leg.via is None:  # the walker turned back as told: said, not left to guess
        return answer("back_on_route", key=f"back_on_route:{ci}:{float(t_now)}", **common)
    if said is not None and leg.via is None:
        walked = s - float(said.get("s", 0.0))
        quiet = float(t_now) - told_t
        # no reassurance while a turn is pending (said, its corner still ahead: "keep going" there
        # would send the walker past it), nor where one is about to be said; before the
        # destination, to its last metres
        before = ahead_m if ci + 1 < len(cur.legs) else TURN_AHEAD_M
        if ci == li and walked >= REASSURE_M and quiet >= QUIET_S and common["walk_m"] > before:
            return answer("reassure", key=f"reassure:{ci}:{_round(common['walk_m'])}", **common)
    # nothing new: not spoken, but the sentence is there for "What next?"
    return answer("continue" if leg.via is None else kind, key=f"continue:{ci}", speak=False, **common)


def _recent(v: Any, t_now: float, span_s: float) -> list[list[float]]:
    """The state's recent answers within `span_s` before `t_now`, [[t, low]]; none for a state
    written before them, or one that cannot be read (a clock gone back drops what is ahead of it)."""
    try:
        out = [[float(t), float(lo)] for t, lo in v]
    except (TypeError, ValueError):
        return []
    return [[t, 1 if lo else 0] for t, lo in out if t_now - span_s <= t <= t_now and math.isfinite(t)]


def _spell(v: Any) -> dict[str, Any] | None:
    """The state's spell off the route, {"t", "b", "f"}; None for none, for a state written before
    it (missing keys are defaults: the state's version stays 1), or for one that cannot be read."""
    try:
        if v is None or not math.isfinite(t := float(v["t"])):
            return None
        b = None if v.get("b") is None else float(v["b"])
        f = None if v.get("f") is None else str(v["f"])
        return None if b is not None and not math.isfinite(b) else {"t": t, "b": b, "f": f}
    except (TypeError, ValueError, KeyError, AttributeError, OverflowError):
        return None


def _way(g: Mapping[str, Any]) -> dict[str, Any]:
    """The way an instruction sends the walker, to tell whether they turned: its bearing, or the
    floor change it names (a floor change's words have no bearing)."""
    fc = g.get("floor_change")
    if fc:
        return {"b": None, "f": f"{fc['via']}:{fc['to_floor']}"}
    b = g.get("bearing_deg")
    return {"b": None if b is None else float(b), "f": None}


def _turned(spell: Mapping[str, Any], way: Mapping[str, Any]) -> bool:
    """Whether an instruction's way is news to the spell: another floor change, or a bearing at
    least TURNED_DEG from the last one said (a bearing that wavers by a few degrees is not)."""
    if way["f"] is not None or spell["f"] is not None:
        return bool(way["f"] != spell["f"])
    if way["b"] is None or spell["b"] is None:
        return way["b"] is not None
    return abs(_signed(way["b"] - spell["b"])) >= TURNED_DEG


def floor_change(leg: Leg, names: Mapping[str, str]) -> dict[str, Any]:
    """The guidance's `floor_change` for a floor change leg."""
    to = str(leg.to_floor)
    return {"via": leg.via, "to_floor": to, "to_floor_name": names.get(to, f"floor {to}")}


def _bearing(pose: Pose, px: float, py: float) -> float:
    return _signed(heading_of(px - pose.x, py - pose.y) - pose.heading)
