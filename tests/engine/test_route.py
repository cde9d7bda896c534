"""Routes and the spoken guide (route.py) on the synthetic layouts' walk graphs: the route to each
place is the shortest along the graph, legs turn where the corridors do, and a simulated walk along
a known route hears exactly the expected sentences (a wrong turn: off the route, then a new
instruction; a lift: take it to the other floor). Poses are made along polylines; nothing is
rendered."""

from __future__ import annotations

import json
from dataclasses import dataclass, replace
from typing import Any

import numpy as np
import pytest

from omninav import route as rt
from omninav import walkgraph as wg
from omninav.demo import LANDMARKS
from omninav.synth.layouts import small_layout, twin_routes
from test_walkgraph import default_model_route, dense


@dataclass(frozen=True)
class Pose:
    x: float
    y: float
    floor: str
    heading: float
    confidence: float = 0.9
    ambiguous: bool = False


def venue_places(layout: str) -> list[dict[str, Any]]:
    return [{"id": f"p{i}", "name": n, "floor": "1", "x": x, "y": y} for i, (n, x, y) in enumerate(LANDMARKS[layout])]


PLACES = venue_places("default")
ROOM_102 = next(p for p in PLACES if p["name"] == "Room 102") | {"say": "The door is on your left."}


@pytest.fixture(scope="module")
def ring() -> wg.WalkGraph:
    return wg.build([(dense(default_model_route()), "1")], PLACES)


def walk(points: list[tuple[float, float]], step: float = 3.0, floor: str = "1") -> list[Pose]:
    """Poses every `step` metres along a polyline, facing the way walked (at a corner: the way on)."""
    p = np.asarray(points, float)
    seg = np.hypot(*np.diff(p, axis=0).T)
    ends = np.cumsum(seg)
    out = []
    for at in np.arange(0.0, ends[-1] + 1e-9, step):
        k = min(int(np.searchsorted(ends, at, side="right")), len(seg) - 1)
        t = (at - (ends[k] - seg[k])) / seg[k]
        x, y = p[k] + t * (p[k + 1] - p[k])
        out.append(Pose(round(float(x), 6), round(float(y), 6), floor, rt.heading_of(*(p[k + 1] - p[k]))))
    return out


def follow(
    graph: wg.WalkGraph,
    place: dict[str, Any],
    poses: list[Pose],
    state: dict[str, Any] | None = None,
    t0: float = 0.0,
    dt: float = 2.5,
    **kw: Any,
) -> tuple[list[dict[str, Any]], dict[str, Any] | None]:
    """Each pose one answer dt seconds apart; the state through JSON, as the server stores it."""
    node = wg.attach(graph, [place])[wg.place_key(place)]
    out = []
    for i, p in enumerate(poses):
        g, state = rt.guide(graph, None, place, node, p, state, t0 + i * dt, PLACES, **kw)
        state = json.loads(json.dumps(state))
        json.dumps(g)
        out.append(g)
    return out, state


def spoken(gs: list[dict[str, Any]]) -> list[tuple[str, str]]:
    return [(g["kind"], g["sentence"]) for g in gs if g["speak"]]


# --- planning -----------------------------------------------------------------------------------


def twin_graph() -> tuple[wg.WalkGraph, list[dict[str, Any]]]:
    model = twin_routes()[0]
    places = [{"name": f"corner {i}", "floor": "1", "x": x, "y": y} for i, (x, y) in enumerate(model[:6])]
    places.append({"name": "stair foot", "floor": "1", "x": 9.0, "y": 8.0})
    return wg.build([(dense(model), "1")], places), places


def small_graph() -> tuple[wg.WalkGraph, list[dict[str, Any]]]:
    _, _, lines = small_layout()
    return wg.build([(dense([lines[0][0], lines[0][1], lines[1][1]]), "1")]), venue_places("small")


@pytest.mark.parametrize("layout", ["default", "twin", "small"])
def test_the_route_to_each_place_is_the_shortest_along_the_walk_graph(layout: str, ring: wg.WalkGraph):
    graph, places = (ring, PLACES) if layout == "default" else twin_graph() if layout == "twin" else small_graph()
    at = wg.attach(graph, places)
    assert len(at) == len(places)
    starts = [graph.nearest(*graph.xy[k]) for k in range(0, len(graph), 7)]
    dist = graph.distances(starts)
    for si, start in enumerate(starts):
        for p in places:
            r = rt.plan(graph, start, p, at[wg.place_key(p)], places)
            assert r is not None and r.nodes[0] == start and r.nodes[-1] == at[wg.place_key(p)]
            assert r.length_m == pytest.approx(dist[si, r.nodes[-1]], abs=1e-6)
            steps = [graph.edge_m(i, j) for i, j in zip(r.nodes[:-1], r.nodes[1:], strict=True)]
            assert sum(steps) == pytest.approx(r.length_m, abs=1e-6)
            assert sum(leg.length_m for leg in r.legs) == pytest.approx(r.length_m, abs=1e-6)
            # legs follow each other, sharing their corners, and every boundary is a real turn
            assert [n for leg in r.legs for n in leg.nodes[1:]] == r.nodes[1:]
            assert all(abs(leg.turn_deg) >= rt.TURN_DEG for leg in r.legs[1:])
            assert r.to == {"id": wg.place_key(p), "name": p["name"], "floor": "1"}


def test_legs_turn_where_the_corridors_do_and_say_what_is_at_their_end(ring: wg.WalkGraph):
    at = wg.attach(ring, PLACES)
    r = rt.plan(ring, ring.nearest(15, 23), ROOM_102, at["p3"], PLACES)
    assert r is not None and r.length_m == pytest.approx(44.0)
    got = [(round(leg.length_m, 1), leg.heading_deg, leg.turn_deg, leg.until) for leg in r.legs]
    assert got == [
        (12.0, 90.0, 0.0, "the stairs"),  # east along the south corridor
        (20.0, 0.0, -90.0, "the lifts"),  # left, up the middle corridor
        (12.0, 90.0, 90.0, "Room 102"),  # right, east along the north corridor
    ]
    assert r.preview() == {"length_m": 44, "turns": 2, "first_turn_m": 12, "floors": ["1"]}
    assert np.allclose(r.xy, ring.xy[r.nodes])
    # without places: a corridor that goes on past the corner is a junction
    bare = rt.plan(ring, ring.nearest(15, 23), ROOM_102, at["p3"])
    # and one that does not (a T: the north corridor crosses ahead) is the end of the corridor
    assert bare is not None
    assert [leg.until for leg in bare.legs] == ["the junction", "the end of the corridor", "Room 102"]


def test_a_corner_with_nothing_straight_on_is_the_end_of_the_corridor():
    graph, places = small_graph()
    stairs = next(p for p in places if p["name"] == "the stairs")
    r = rt.plan(graph, graph.nearest(2, 2), stairs, wg.attach(graph, [stairs])[wg.place_key(stairs)])
    assert r is not None
    assert [(leg.until, leg.turn_deg) for leg in r.legs] == [("the end of the corridor", 0.0), ("the stairs", 90.0)]
    assert r.preview() == {"length_m": 28, "turns": 1, "first_turn_m": 18, "floors": ["1"]}


def test_bends_under_thirty_degrees_are_not_turns():
    # a corridor that bends by 20 degrees, then a real corner of 70 degrees, then a 0.8 m jog
    bend = [(0.0, 0.0), (10.0, 0.0), (10.0 + 10 * np.cos(np.radians(20)), 10 * np.sin(np.radians(20)))]
    corner = bend[-1]
    h = np.radians(90.0)  # plan heading 90 + 20 = 110 -> turn 70 more: 180 (down the plan)
    del h
    down = (corner[0], corner[1] + 10.0)
    jog = [(down[0] + 0.8, down[1] + 0.8), (down[0] + 0.8, down[1] + 10.8)]
    pts = [*bend, down, *jog]
    g = wg.build([(dense(pts), "1")])
    end = {"name": "the end", "floor": "1", "x": jog[-1][0], "y": jog[-1][1]}
    r = rt.plan(g, g.nearest(0, 0), end, g.nearest(*jog[-1]))
    assert r is not None and len(r.legs) == 2
    assert r.legs[1].turn_deg == pytest.approx(75.0, abs=8.0)  # the chords' headings: 100 -> 176
    assert r.preview()["turns"] == 1


def two_floor_graph() -> tuple[wg.WalkGraph, list[dict[str, Any]]]:
    _, _, lines = small_layout()
    walk_ = dense([lines[0][0], lines[0][1], lines[1][1]])  # the L: 18 m east, 10 m south
    places = [
        {"id": "l1", "name": "the lifts", "floor": "1", "x": 20.0, "y": 1.0, "kind": "lift"},
        {"id": "l2", "name": "the lifts", "floor": "2", "x": 20.0, "y": 1.0, "kind": "lift"},
        {"id": "e1", "name": "the entrance", "floor": "1", "x": 2.0, "y": 2.0},
        {"id": "r2", "name": "Room 214", "floor": "2", "x": 20.0, "y": 11.0},
    ]
    return wg.build([(walk_, "1"), (walk_, "2")], places), places


def test_a_route_to_another_floor_takes_the_lift():
    g, places = two_floor_graph()
    at = wg.attach(g, places)
    r = rt.plan(g, at["e1"], places[3], at["r2"], places)
    assert r is not None
    legs = [(leg.floor, leg.via, leg.to_floor, round(leg.length_m, 1), leg.turn_deg, leg.until) for leg in r.legs]
    assert legs == [
        ("1", None, None, 18.0, 0.0, "the lifts"),
        ("1", "lift", "2", 0.0, 0.0, None),
        ("2", None, None, 9.0, 0.0, "Room 214"),  # the first leg of a floor turns from nothing
    ]
    assert r.length_m == pytest.approx(27.0)  # metres walked: the ride is not a walk
    assert r.preview() == {"length_m": 27, "turns": 0, "first_turn_m": None, "floors": ["1", "2"]}


def test_the_guide_takes_the_lift_and_walks_on_upstairs():
    g, places = two_floor_graph()
    names = {"1": "Floor 1", "2": "Floor 2"}
    first = walk([(2.0, 2.0), (20.0, 2.0)])
    upstairs = [Pose(20.0, 2.0, "2", 90.0)] + walk([(20.0, 2.0), (20.0, 11.0)], floor="2")[1:]
    node = wg.attach(g, places)["r2"]
    state, said = None, []
    for i, p in enumerate(first + upstairs):
        gd, state = rt.guide(g, None, places[3], node, p, state, i * 2.5, places, floor_names=names)
        said.append((gd["kind"], gd["speak"], gd["sentence"], gd["floor_change"]))
    assert [s[:3] for s in said if s[1]] == [
        ("start", True, "Walk straight ahead 18 metres, to the lifts."),
        ("reassure", True, "Keep going, 6 metres to the lifts."),
        ("floor_change", True, "Take the lift to Floor 2."),  # 3 m before the lift
        ("turn", True, "Turn to 3 o'clock and walk 9 metres, to Room 214."),  # out of the lift, upstairs
        ("arrived", True, "You have arrived at Room 214."),  # at the place itself: no bearing to say
    ]
    assert next(s[3] for s in said if s[0] == "floor_change") == {
        "via": "lift",
        "to_floor": "2",
        "to_floor_name": "Floor 2",
    }


def test_a_route_that_starts_at_the_lift_says_take_it_first():
    g, places = two_floor_graph()
    at = wg.attach(g, places)
    gd, _ = rt.guide(g, None, places[3], at["r2"], Pose(20.0, 2.0, "1", 270.0), None, 0.0, places)
    assert (gd["kind"], gd["sentence"]) == ("start", "Take the lift to floor 2.")
    assert gd["preview"] == {"length_m": 9, "turns": 0, "first_turn_m": None, "floors": ["1", "2"]}


# --- guiding ------------------------------------------------------------------------------------


def test_walking_a_known_route_hears_the_expected_sentences(ring: wg.WalkGraph):
    gs, _ = follow(ring, ROOM_102, walk([(15.0, 23.0), (27.0, 23.0), (27.0, 3.0), (39.0, 3.0)]))
    assert spoken(gs) == [
        ("start", "Walk straight ahead 12 metres, to the stairs."),
        # each turn said at the walker's pace (3 m every 2.5 s) early enough to be heard before it
        ("turn", "In 9 metres, turn to 9 o'clock and walk 20 metres, to the lifts."),
        ("reassure", "Keep going, 17 metres to the lifts."),
        ("turn", "In 11 metres, turn to 3 o'clock and walk 12 metres, to Room 102."),
        ("reassure", "Keep going, 11 metres to Room 102."),  # round the corner, 10 m and 6 s after the turn
        ("arrived", "You have arrived at Room 102; it is at 12 o'clock, 2 metres. The door is on your left."),
    ]
    first, last = gs[0], gs[-1]
    assert first["preview"] == {"length_m": 44, "turns": 2, "first_turn_m": 12, "floors": ["1"]}
    assert first["route"] == [[15.0, 23.0], [27.0, 23.0], [27.0, 3.0], [39.0, 3.0]]
    assert first | {"preview": None, "route": None} == {
        "to": {"id": "p3", "name": "Room 102", "floor": "1", "say": "The door is on your left."},
        "kind": "start",
        "speak": True,
        "urgent": False,
        "bearing_deg": 0.0,
        "walk_m": 12.0,
        "until": "the stairs",
        "in_m": None,
        "next_turn_m": 12.0,
        "remaining_m": 44.0,
        "on_route": True,
        "arrived": False,
        "floor_change": None,
        "preview": None,
        "route": None,
        "sentence": "Walk straight ahead 12 metres, to the stairs.",
    }
    assert all("preview" not in g for g in gs[1:])
    assert last["urgent"] and last["arrived"] and last["remaining_m"] == 0.0
    assert (last["bearing_deg"], last["walk_m"]) == (0.0, 2.0)  # the place itself, from the user
    # between the sentences: nothing said, the current instruction kept for "What next?"
    quiet = [g for g in gs if not g["speak"]]
    assert quiet and all(g["kind"] == "continue" for g in quiet)
    assert [g["remaining_m"] for g in gs] == [44.0 - 3 * k for k in range(len(gs) - 1)] + [0.0]


def test_a_wrong_turn_is_off_the_route_then_a_new_instruction(ring: wg.WalkGraph):
    # straight on past the corner where the route turns left, then back as told
    gone, state = follow(ring, ROOM_102, walk([(15.0, 23.0), (27.0, 23.0), (33.0, 23.0)]))
    assert spoken(gone) == [
        ("start", "Walk straight ahead 12 metres, to the stairs."),
        ("turn", "In 9 metres, turn to 9 o'clock and walk 20 metres, to the lifts."),
        ("off_route", "You are off the route; turn to 6 o'clock."),
    ]
    off = gone[-1]
    assert off["urgent"] and not off["on_route"] and off["bearing_deg"] == 180.0
    assert off["remaining_m"] == 38.0 and np.allclose(off["route"][:2], [[33.0, 23.0], [27.0, 23.0]], atol=0.01)
    back, _ = follow(ring, ROOM_102, walk([(33.0, 23.0), (27.0, 23.0), (27.0, 3.0)])[1:4], state, t0=20.0)
    assert spoken(back) == [("turn", "In 3 metres, turn to 3 o'clock and walk 20 metres, to the lifts.")]
    assert back[0]["in_m"] == 3.0 and back[0]["next_turn_m"] == 3.0 and back[0]["walk_m"] == 20.0
    assert all(g["on_route"] for g in back)


def corridor() -> tuple[wg.WalkGraph, dict[str, Any]]:
    """A straight corridor 60 m long, its end the place: nowhere to go the wrong way but back."""
    return wg.build([(dense([(0.0, 0.0), (60.0, 0.0)]), "1")]), {"id": "e", "name": "the end", "x": 55.0, "y": 0.0}


def test_walking_on_the_wrong_way_hears_off_the_route_once_per_spell_not_at_every_answer():
    # issue 14: facing the right way, then round and 29 m the wrong way, one answer every 2.5 s
    graph, end = corridor()
    poses = [Pose(30.0, 0.0, "1", 90.0)] + walk([(30.0, 0.0), (1.0, 0.0)])[1:]
    gs, state = follow(graph, end, poses)
    assert [(t * 2.5, g["kind"], g["sentence"]) for t, g in enumerate(gs) if g["speak"]] == [
        (0.0, "start", "Walk straight ahead 25 metres, to the end."),
        (5.0, "off_route", "You are off the route; turn to 6 o'clock."),
        (7.5, "turn", "Turn to 6 o'clock and walk 34 metres, to the end."),  # the new route, as ever
        # each answer leaves the new route again (10, 15 s): planned anew, the same way, nothing said
        (20.0, "off_route", "You are off the route; turn to 6 o'clock."),  # OFF_AGAIN_S since the last
        (22.5, "turn", "Turn to 6 o'clock and walk 52 metres, to the end."),
    ]
    assert [g["urgent"] for g in gs if g["speak"]] == [False, True, False, True, False]
    # the departures in between are planned anew all the same: the route and the bearing follow
    quiet = [gs[4], gs[6]]
    assert [(g["kind"], g["on_route"], g["remaining_m"], g["bearing_deg"]) for g in quiet] == [
        ("continue", False, 37.0, 180.0),
        ("continue", False, 43.0, 180.0),
    ]
    assert state is not None and state["off"] == {"t": 20.0, "b": 180.0, "f": None}
    # while the walker is off, never silent for much longer than OFF_AGAIN_S (the warning comes at
    # the first answer off the route after it): at the 2 s the app answers at, too
    for dt in (2.5, 2.0):
        gs, _ = follow(graph, end, poses, dt=dt)
        said_at = [t * dt for t, g in enumerate(gs) if g["speak"]][1:]
        assert max(b - a for a, b in zip(said_at[:-1], said_at[1:], strict=True)) <= rt.OFF_AGAIN_S + 2 * dt


def test_back_on_the_new_route_a_new_departure_is_said_at_once():
    # off the route (3 s), back along the new route past where it began, then the wrong way again
    # at 12 s: under OFF_AGAIN_S since the first, but after the walker was on a route again
    graph, end = corridor()
    there = walk([(30.0, 0.0), (21.0, 0.0)])[1:]
    back = walk([(21.0, 0.0), (30.0, 0.0)])[1:]
    again = walk([(30.0, 0.0), (18.0, 0.0)])[1:]
    gs, _ = follow(graph, end, [Pose(30.0, 0.0, "1", 90.0), *there, *back, *again], dt=1.5)
    assert [(t * 1.5, g["kind"]) for t, g in enumerate(gs) if g["speak"]] == [
        (0.0, "start"),
        (3.0, "off_route"),
        (4.5, "turn"),
        (7.5, "back_on_route"),  # 3 m along the new route: the walker hears that they turned back right
        (12.0, "off_route"),
        (13.5, "turn"),
    ]
    assert gs[7]["on_route"] and gs[7]["kind"] == "continue"  # 9 m back along the new route


def test_a_wrong_turn_that_finds_another_way_says_the_new_way_not_another_warning(ring: wg.WalkGraph):
    # straight on past the corner where the route turns left, and on: from (39, 23) the way on round
    # the ring is the shorter one, and the walker is told so, as an instruction
    gs, state = follow(ring, ROOM_102, walk([(15.0, 23.0), (27.0, 23.0), (51.0, 23.0)]))
    assert [(g["kind"], g["sentence"], g["urgent"], g["on_route"]) for g in gs if g["speak"]] == [
        ("start", "Walk straight ahead 12 metres, to the stairs.", False, True),
        # a turn before its corner cuts in (urgent): it must be heard before the corner
        ("turn", "In 9 metres, turn to 9 o'clock and walk 20 metres, to the lifts.", True, True),
        ("off_route", "You are off the route; turn to 6 o'clock.", True, False),
        # from where the walker is, past the start of the route planned when they left the last
        ("turn", "Turn to 6 o'clock and walk 9 metres, to the stairs.", False, True),
        ("turn", "Walk straight ahead 12 metres, to the toilets.", False, False),  # off again, another way
        ("back_on_route", "You are on the route again; keep going, 9 metres to the toilets.", False, True),
        ("turn", "In 6 metres, turn to 9 o'clock and walk 20 metres, to the café.", True, True),
    ]
    assert state is not None and state["off"] is None  # on the new route since: the spell is over


def test_off_the_graph_the_warning_is_said_again_though_its_words_are_the_same():
    # into a room at right angles to the corridor: every answer plans from the same nearest node,
    # so the repeat's words are the last warning's, and still it is said about every 15 s
    graph, end = corridor()
    poses = [Pose(30.0, 0.0, "1", 90.0)] + [Pose(30.0, 4.0 + 0.5 * k, "1", 180.0) for k in range(20)]
    gs, _ = follow(graph, end, poses, dt=2.0)
    warned = [t * 2.0 for t, g in enumerate(gs) if g["speak"] and g["kind"] == "off_route"]
    assert len(warned) >= 3 and warned[0] == 2.0
    assert all(b - a <= rt.OFF_AGAIN_S + 2.0 for a, b in zip(warned[:-1], warned[1:], strict=True))


def test_a_bearing_that_wavers_across_a_sector_edge_is_not_said_again():
    # off the route, the walker's heading wavering by 2 degrees about a sector's edge (60 degrees
    # from the way to go): one warning, and nothing more until OFF_AGAIN_S, not an instruction at
    # every answer
    graph, end = corridor()
    poses = [Pose(30.0, 0.0, "1", 90.0)] + [
        Pose(30.0 - 2.0 * k, 0.0, "1", 270.0 - 60.0 + (2.0 if k % 2 else -2.0)) for k in range(1, 8)
    ]
    gs, _ = follow(graph, end, poses, dt=2.0)
    spoken_kinds = [(t * 2.0, g["kind"]) for t, g in enumerate(gs) if g["speak"]]
    assert spoken_kinds[0] == (0.0, "start") and spoken_kinds[1][1] == "off_route"
    assert len(spoken_kinds) <= 3, spoken_kinds


def test_a_guide_state_without_the_off_route_spell_is_read_as_none():
    # a state written before the spell was kept (or one with junk in it) goes on from where it was
    graph, end = corridor()
    _, state = follow(graph, end, walk([(30.0, 0.0), (24.0, 0.0)]))
    assert state is not None and state["off"] == {"t": 5.0, "b": 180.0, "f": None} and state["v"] == 1
    junk = ({"t": "junk"}, {"t": 5.0, "b": 1e400}, {"t": float("nan")}, {"t": 5.0, "b": "x"}, [1, 2], "x")
    for old in ({k: v for k, v in state.items() if k != "off"}, *({**state, "off": j} for j in junk)):
        gs, st = follow(graph, end, [Pose(21.0, 0.0, "1", 270.0), Pose(15.0, 0.0, "1", 270.0)], old, t0=7.5)
        assert [(g["kind"], g["speak"]) for g in gs] == [("turn", True), ("off_route", True)]
        assert st is not None and st["off"] == {"t": 10.0, "b": 180.0, "f": None}
    # the state as it is: still in the spell, so the second departure says nothing
    gs, _ = follow(graph, end, [Pose(21.0, 0.0, "1", 270.0), Pose(15.0, 0.0, "1", 270.0)], state, t0=7.5)
    assert [(g["kind"], g["speak"]) for g in gs] == [("turn", True), ("continue", False)]


def test_walking_back_along_the_route_for_two_answers_is_off_the_route(ring: wg.WalkGraph):
    there = walk([(15.0, 23.0), (27.0, 23.0), (27.0, 14.0)])
    back = [replace(p, heading=180.0) for p in walk([(27.0, 14.0), (27.0, 23.0)], step=2.0)[1:]]
    gs, _ = follow(ring, ROOM_102, there + back)
    kinds = [g["kind"] for g in gs]
    k = kinds.index("off_route")
    assert k == len(there) + 1  # the second answer walking away
    assert gs[k]["sentence"] == "You are off the route; turn to 6 o'clock." and gs[k]["urgent"]
    # the new route starts where the user is: on it again at once
    assert gs[k + 1]["on_route"] and gs[k + 1]["kind"] == "turn"


def test_a_pose_wavering_about_the_turns_announcement_says_it_once(ring: wg.WalkGraph):
    poses = [Pose(x, 23.0, "1", 90.0) for x in (15.0, 24.2, 23.8, 24.2, 23.9)]
    gs, _ = follow(ring, ROOM_102, poses)
    assert spoken(gs) == [
        ("start", "Walk straight ahead 12 metres, to the stairs."),
        ("turn", "In 3 metres, turn to 9 o'clock and walk 20 metres, to the lifts."),
    ]
    assert [g["kind"] for g in gs[2:]] == ["continue"] * 3


def test_reassurance_waits_for_quiet_and_ten_metres(ring: wg.WalkGraph):
    long_walk = walk([(3.0, 23.0), (51.0, 23.0)], step=2.0)  # to the toilets, 48 m straight
    toilets = next(p for p in PLACES if p["name"] == "the toilets")
    slow, _ = follow(ring, toilets, long_walk)
    assert spoken(slow) == [
        ("start", "Walk straight ahead 48 metres, to the toilets."),
        ("reassure", "Keep going, 38 metres to the toilets."),
        ("reassure", "Keep going, 28 metres to the toilets."),
        ("reassure", "Keep going, 18 metres to the toilets."),
        ("reassure", "Keep going, 8 metres to the toilets."),
        ("arrived", "You have arrived at the toilets; it is at 12 o'clock, 2 metres."),
    ]
    # answers 1 s apart, 2 m each (a brisk 2 m/s): 10 m takes 5 s, so each waits for the 6th second
    fast, _ = follow(ring, toilets, long_walk, dt=1.0)
    assert [s for _, s in spoken(fast)][1:3] == [
        "Keep going, 36 metres to the toilets.",
        "Keep going, 24 metres to the toilets.",
    ]


def test_not_sure_is_said_after_two_low_answers_and_then_the_instruction_again(ring: wg.WalkGraph):
    poses = walk([(15.0, 23.0), (24.0, 23.0)])
    unsure = [replace(p, ambiguous=True) for p in poses[1:3]] + [replace(poses[3], confidence=0.2)]
    gs, _ = follow(ring, ROOM_102, [poses[0], *unsure, poses[3]])
    assert [(g["kind"], g["speak"]) for g in gs] == [
        ("start", True),
        ("continue", False),  # one low answer is held: nothing said, nothing decided
        ("unsure", True),  # the second in a row
        ("unsure", False),
        ("turn", True),  # a new leg: said at once
    ]
    assert gs[1]["sentence"] == "In 9 metres, turn to 9 o'clock and walk 20 metres, to the lifts."
    assert gs[2]["sentence"] == "Not sure where you are yet; keep walking slowly."
    assert gs[2]["bearing_deg"] is None and gs[2]["walk_m"] is None and gs[2]["remaining_m"] == 44.0
    assert gs[-1]["sentence"] == "In 3 metres, turn to 9 o'clock and walk 20 metres, to the lifts."


def test_a_confidence_hovering_about_the_threshold_says_a_handful_of_sentences(ring: wg.WalkGraph):
    # 0.9 and 0.4 in turn (the filter caps a split belief at 0.45): no "not sure", and the route's
    # sentences once each, not one at every answer
    poses = walk([(15.0, 23.0), (27.0, 23.0), (27.0, 3.0), (39.0, 3.0)], step=2.0)
    hovering = [replace(p, confidence=0.4 if i % 2 == 0 and i > 0 else 0.9) for i, p in enumerate(poses)]
    gs, _ = follow(ring, ROOM_102, hovering, dt=2.0)
    assert len(gs) == 23
    assert spoken(gs) == [
        ("start", "Walk straight ahead 12 metres, to the stairs."),
        ("turn", "In 10 metres, turn to 9 o'clock and walk 20 metres, to the lifts."),
        ("reassure", "Keep going, 18 metres to the lifts."),
        ("turn", "In 10 metres, turn to 3 o'clock and walk 12 metres, to Room 102."),
        ("reassure", "Keep going, 10 metres to Room 102."),
        # half the answers of the last 30 s were low: a track that has not settled arrives "probably"
        ("probably_arrived", "You are probably at Room 102; it is at 12 o'clock, 2 metres. The door is on your left."),
    ]
    assert all(g["on_route"] for g in gs) and "unsure" not in {g["kind"] for g in gs}
    # the other phase: the answers before the corners are the low ones, held; the turn is said at
    # the next sure answer
    other = [replace(p, confidence=0.4 if i % 2 else 0.9) for i, p in enumerate(poses)]
    gs, _ = follow(ring, ROOM_102, other, dt=2.0)
    assert len(spoken(gs)) == 6 and "unsure" not in {g["kind"] for g in gs}
    # a single low pose off the route decides nothing: not off the route, nothing said
    poses = [Pose(15.0, 23.0, "1", 90.0), Pose(20.0, 30.0, "1", 90.0, confidence=0.45), Pose(18.0, 23.0, "1", 90.0)]
    gs, _ = follow(ring, ROOM_102, poses)
    assert [(g["kind"], g["speak"], g["on_route"]) for g in gs] == [
        ("start", True, True),
        ("unsure", False, True),
        ("continue", False, True),
    ]


def test_a_clearly_low_answer_is_not_sure_at_once_and_the_instruction_waits_for_quiet(ring: wg.WalkGraph):
    at = [Pose(x, 23.0, "1", 90.0) for x in (15.0, 16.0, 17.0, 18.0, 19.0, 20.0)]
    poses = [at[0], replace(at[1], confidence=0.3), at[2], at[3], replace(at[4], confidence=0.3), at[5]]
    gs, _ = follow(ring, ROOM_102, poses, dt=2.0)
    assert [(g["kind"], g["speak"]) for g in gs] == [
        ("start", True),  # t 0
        ("unsure", True),  # t 2: under CLEAR_LOW, at once
        ("continue", False),  # t 4: the same leg, said 4 s ago: not again yet
        ("turn", True),  # t 6: QUIET_S since it was said
        ("unsure", True),  # t 8
        ("continue", False),  # t 10: said 4 s ago
    ]
    assert gs[3]["sentence"] == "Walk straight ahead 9 metres, to the stairs."


def test_an_unsure_first_answer_starts_the_route_when_sure(ring: wg.WalkGraph):
    p = Pose(15.0, 23.0, "1", 90.0)
    gs, _ = follow(ring, ROOM_102, [replace(p, confidence=0.1), p])
    assert [(g["kind"], g["speak"]) for g in gs] == [("unsure", True), ("start", True)]
    assert gs[0]["on_route"] is False and gs[0]["remaining_m"] is None and gs[0]["route"] == []


def test_a_turn_said_before_its_corner_says_how_far_the_corner_is(ring: wg.WalkGraph):
    # 2 m before the corner where the route turns left; then at the corner itself
    gs, _ = follow(ring, ROOM_102, [Pose(25.0, 23.0, "1", 90.0), Pose(27.0, 23.0, "1", 90.0)], style="sides")
    assert [(g["kind"], g["sentence"], g["in_m"], g["next_turn_m"]) for g in gs] == [
        ("start", "In 2 metres, turn left and walk 20 metres, to the lifts.", 2.0, 2.0),
        ("continue", "Turn left and walk 20 metres, to the lifts.", None, 20.0),
    ]
    assert gs[0]["bearing_deg"] == -90.0 and gs[0]["walk_m"] == 20.0  # from the user's heading now
    gs, _ = follow(ring, ROOM_102, [Pose(24.4, 23.0, "1", 90.0)], style="degrees")
    assert gs[0]["sentence"] == "In 3 metres, turn 90 degrees left and walk 20 metres, to the lifts."
    # walking the first leg, far from its corner: no in_m
    gs, _ = follow(ring, ROOM_102, [Pose(15.0, 23.0, "1", 90.0)])
    assert gs[0]["in_m"] is None


def test_standing_still_with_a_jittering_pose_is_not_off_the_route(ring: wg.WalkGraph):
    # the filter's pose wanders a metre or so back and forth, and the heading by 25 degrees
    xs = [20.0, 18.8, 17.6, 18.9, 20.1, 18.7, 17.5, 19.0]
    poses = [Pose(x, 23.0, "1", 90.0 + (25.0 if k % 2 else -25.0 if k else 0.0)) for k, x in enumerate(xs)]
    gs, _ = follow(ring, ROOM_102, poses)
    assert spoken(gs) == [("start", "In 7 metres, turn to 9 o'clock and walk 20 metres, to the lifts.")]
    assert all(g["on_route"] and g["kind"] in ("start", "continue") for g in gs)


def test_a_place_moved_while_guided_starts_over(ring: wg.WalkGraph):
    p = Pose(15.0, 23.0, "1", 90.0)
    _, state = follow(ring, ROOM_102, [p])
    assert state is not None and state["remaining_m"] == 44.0
    moved = ROOM_102 | {"x": 19.0, "y": 23.0}  # the same place (id p3), now 4 m ahead
    gs, state = follow(ring, moved, [p], state)
    assert gs[0]["kind"] == "start" and gs[0]["remaining_m"] == 4.0
    assert gs[0]["sentence"] == "Walk straight ahead 4 metres, to Room 102."
    assert state is not None and state["nodes"][-1] == ring.nearest(19.0, 23.0)


def test_a_state_from_another_graph_or_place_starts_over(ring: wg.WalkGraph):
    p = Pose(15.0, 23.0, "1", 90.0)
    _, state = follow(ring, ROOM_102, [p])
    assert state is not None and state["graph"] == ring.key and len(json.dumps(state)) < 2000
    again, _ = follow(ring, ROOM_102, [p], state)
    assert again[0]["kind"] == "continue" and not again[0]["speak"]
    other = wg.build([(dense(default_model_route()), "1")], PLACES, join_m=1.5)
    toilets = next(q for q in PLACES if q["name"] == "the toilets")
    for graph, place, st in [
        (other, ROOM_102, state),
        (ring, toilets, state),
        (ring, ROOM_102, {**state, "nodes": [10**6]}),
        (ring, ROOM_102, {"v": 99}),
        (ring, ROOM_102, {**state, "nodes": "junk"}),
    ]:
        gs, _ = follow(graph, place, [p], st)
        assert gs[0]["kind"] == "start", st


def test_arrival_is_said_once_with_the_places_bearing(ring: wg.WalkGraph):
    near = Pose(39.0, 4.5, "1", 270.0)  # 1.5 m below Room 102's node, facing west
    gs, _ = follow(ring, ROOM_102, [Pose(33.0, 3.0, "1", 90.0), near, near])
    assert [(g["kind"], g["speak"], g["urgent"]) for g in gs[1:]] == [("arrived", True, True), ("arrived", False, True)]
    assert gs[1]["bearing_deg"] == 90.0 and gs[1]["walk_m"] == 1.5
    assert gs[1]["sentence"] == "You have arrived at Room 102; it is at 3 o'clock, 2 metres. The door is on your left."


def test_an_arrival_under_sure_is_said_as_probably_and_guidance_goes_on_until_it_is_sure(ring: wg.WalkGraph):
    near = Pose(39.0, 4.5, "1", 270.0)  # 1.5 m below Room 102's node, facing west
    unsure, sure = replace(near, confidence=0.7), replace(near, confidence=0.8)
    gs, _ = follow(ring, ROOM_102, [Pose(33.0, 3.0, "1", 90.0), unsure, unsure, sure, sure])
    got = [(g["kind"], g["speak"], g["urgent"], g["arrived"]) for g in gs[1:]]
    assert got == [
        ("probably_arrived", True, True, False),  # said, cutting in, but not the end of the guidance
        ("probably_arrived", False, True, False),  # not said again
        ("arrived", True, True, True),  # the pose firmed up: now it is a fact, and the guidance ends
        ("arrived", False, True, True),
    ]
    assert gs[1]["sentence"] == "You are probably at Room 102; it is at 3 o'clock, 2 metres. The door is on your left."
    assert gs[3]["sentence"] == "You have arrived at Room 102; it is at 3 o'clock, 2 metres. The door is on your left."
    assert gs[1]["remaining_m"] == 0.0 and gs[1]["on_route"]


def test_a_probable_arrival_that_was_elsewhere_guides_on(ring: wg.WalkGraph):
    # "probably at Room 102" at 0.7, then sure answers 10 m back along the corridor (the probable
    # pose was a look-alike, or the walker went on): the guide does not stop; it guides from there
    near = Pose(39.0, 4.5, "1", 270.0, confidence=0.7)
    back = [Pose(29.0, 3.0, "1", 90.0), Pose(30.0, 3.0, "1", 90.0)]
    gs, _ = follow(ring, ROOM_102, [Pose(33.0, 3.0, "1", 90.0), near, *back])
    assert [g["kind"] for g in gs] == ["start", "probably_arrived", "off_route", "turn"]
    assert not any(g["arrived"] for g in gs)
    assert gs[-1]["sentence"] == "Walk straight ahead 9 metres, to Room 102." and gs[-1]["remaining_m"] == 9.0


def test_arrival_on_a_track_that_has_not_settled_is_probably_until_the_low_answers_are_30_s_old(ring: wg.WalkGraph):
    # four low answers (two of them said as "not sure"), then sure answers at the place, 2.5 s apart:
    # of the last 30 s, more than a third low until the low ones are older than 30 s
    go, there = Pose(33.0, 3.0, "1", 90.0), Pose(39.0, 4.5, "1", 270.0)
    low = Pose(34.0, 3.0, "1", 90.0, confidence=0.45)
    gs, state = follow(ring, ROOM_102, [go, low, low, low, low] + [there] * 10)
    kinds = [(g["kind"], g["speak"]) for g in gs]
    assert kinds[2] == ("unsure", True) and kinds[5] == ("probably_arrived", True)
    assert kinds[6:13] == [("probably_arrived", False)] * 7  # 4 of 5 ... 4 of 11 low: not settled
    assert kinds[13:] == [("arrived", True), ("arrived", False)]  # at 32.5 s: 4 of 12, a third
    assert gs[13]["sentence"].startswith("You have arrived at Room 102") and gs[13]["urgent"]
    # the state keeps the last minute (for "not here"; settling reads its last 30 s), the first answer not counted
    assert state is not None and [t for t, _ in state["recent"]] == [2.5 * k for k in range(1, 15)]


def test_the_first_answer_of_a_guidance_is_not_counted_against_settling(ring: wg.WalkGraph):
    # a new session's first answer is young and low; a walk of sure answers after it arrives at once
    first = Pose(33.0, 3.0, "1", 90.0, confidence=0.45)
    gs, _ = follow(ring, ROOM_102, [first, Pose(33.0, 3.0, "1", 90.0), Pose(39.0, 4.5, "1", 270.0)])
    assert [g["kind"] for g in gs] == ["unsure", "start", "arrived"]


def test_answers_at_a_clock_that_stands_still_keep_the_state_small(ring: wg.WalkGraph):
    p = Pose(33.0, 3.0, "1", 90.0)
    _, state = follow(ring, ROOM_102, [p] * 200, dt=0.0)
    assert state is not None and len(state["recent"]) == rt.RECENT_MAX and len(json.dumps(state)) < 2000


def lost_walk(pattern: str, n: int) -> list[Pose]:
    """Answers 2.5 s apart on the first leg: "s" a sure one, "l" a low one, the pattern repeated."""
    sure, low = Pose(15.0, 23.0, "1", 90.0), Pose(16.0, 23.0, "1", 90.0, confidence=0.45)
    return [sure] + [low if pattern[i % len(pattern)] == "l" else sure for i in range(n)]


def test_most_of_a_minute_low_says_once_that_the_user_may_be_outside_the_mapped_area(ring: wg.WalkGraph):
    gs, state = follow(ring, ROOM_102, lost_walk("lls", 40))
    said = [(round(i * 2.5, 1), g["kind"]) for i, g in enumerate(gs) if g["speak"]]
    lost = [t for t, k in said if k == "not_here"]
    # a whole minute guided, two thirds low: said at its first low answer (62.5 s; the one at 60 s is
    # sure), once, not again while it lasts
    assert lost == [62.5] and gs[24]["kind"] != "not_here"
    g = gs[25]
    assert g["sentence"] == "You may be outside the mapped area; keep walking slowly, or stop guidance."
    assert not g["urgent"] and not g["on_route"] and g["bearing_deg"] is None
    assert gs[26]["kind"] == "unsure" and not gs[26]["speak"]  # its "keep walking slowly" is not said twice
    assert state is not None and state["lost"] is True
    # the answers settle (a third low at most over the minute), then most are low again: said again
    gs, state = follow(ring, ROOM_102, [Pose(15.0, 23.0, "1", 90.0)] * 20 + lost_walk("ll", 30)[1:], state, t0=102.5)
    assert [k for k in (g["kind"] for g in gs if g["speak"]) if k == "not_here"] == ["not_here"]


def test_a_pause_in_the_guidance_starts_its_minute_again(ring: wg.WalkGraph):
    # a sure answer, then 90 s without answers (Start pressed late, the page hidden): the first low
    # answer after it is not "most of a minute"
    gs, state = follow(ring, ROOM_102, [Pose(15.0, 23.0, "1", 90.0)])
    low = Pose(16.0, 23.0, "1", 90.0, confidence=0.45)
    gs, state = follow(ring, ROOM_102, [low] * 3, state, t0=90.0)
    assert "not_here" not in {g["kind"] for g in gs} and state is not None and state["t0"] == 90.0
    # then all low: "not here" once a minute of answers has passed since the pause, not before
    gs, _ = follow(ring, ROOM_102, [low] * 24, state, t0=97.5)
    said = [round(97.5 + i * 2.5, 1) for i, g in enumerate(gs) if g["kind"] == "not_here"]
    assert said == [150.0]


@pytest.mark.parametrize("pattern", ["lss", "l" * 30 + "s" * 30])
def test_a_third_low_or_a_minute_not_yet_whole_says_nothing_of_the_map(ring: wg.WalkGraph, pattern: str):
    # a third of a minute low (as in the venue, at worst); or all low for the first 23 answers
    n = 40 if len(pattern) == 3 else 23
    gs, _ = follow(ring, ROOM_102, lost_walk(pattern, n))
    assert "not_here" not in {g["kind"] for g in gs}


@pytest.mark.parametrize("t0", [None, "junk", float("nan"), 1e9])
def test_a_guidance_whose_start_cannot_be_read_starts_its_minute_now(ring: wg.WalkGraph, t0: Any):
    _, state = follow(ring, ROOM_102, lost_walk("l", 30))  # 75 s, all low after the first
    assert state is not None and state["lost"] is True
    state = {**state, "lost": False, "t0": t0}
    gs, state = follow(ring, ROOM_102, lost_walk("l", 5)[1:], state, t0=80.0)
    assert "not_here" not in {g["kind"] for g in gs} and state is not None and state["t0"] == 80.0


@pytest.mark.parametrize("recent", [None, "junk", [[0.0]], [["x", 1]], [[float("inf"), 1]]])
def test_a_state_without_readable_recent_answers_counts_none(ring: wg.WalkGraph, recent: Any):
    # a state written before "recent", or one that cannot be read: nothing recent, arrival as ever
    _, state = follow(ring, ROOM_102, [Pose(33.0, 3.0, "1", 90.0)])
    assert state is not None
    old = {k: v for k, v in state.items() if k != "recent"} | ({} if recent is None else {"recent": recent})
    gs, state = follow(ring, ROOM_102, [Pose(39.0, 4.5, "1", 270.0)], old, t0=2.5)
    assert gs[0]["kind"] == "arrived" and state is not None and state["recent"] == [[2.5, 0]]


@pytest.mark.parametrize(("confidence", "first"), [(0.79, "probably_arrived"), (float("nan"), "unsure")])
def test_a_route_started_at_the_place_is_not_arrived_there_unless_sure(
    ring: wg.WalkGraph, confidence: float, first: str
):
    # under 0.8: "probably"; a confidence that is not a number is no confidence: "not sure"
    at_place = Pose(39.0, 3.0, "1", 90.0, confidence=confidence)
    gs, _ = follow(ring, ROOM_102, [at_place, replace(at_place, confidence=0.95)])
    assert [(g["kind"], g["arrived"]) for g in gs] == [(first, False), ("arrived", True)]
    if first == "probably_arrived":
        assert gs[0]["sentence"] == "You are probably at Room 102. The door is on your left."


def test_a_single_low_answer_at_the_place_is_held_not_arrived(ring: wg.WalkGraph):
    # a route with nowhere to walk (started at the place), then one low answer there: nothing
    # decided on it, so it cannot end the guidance (it did, silently, before arrival needed a sure pose)
    at_place = Pose(39.0, 3.0, "1", 90.0, confidence=0.7)
    gs, _ = follow(ring, ROOM_102, [at_place, replace(at_place, confidence=0.45)])
    assert [(g["kind"], g["speak"], g["arrived"]) for g in gs] == [
        ("probably_arrived", True, False),
        ("probably_arrived", False, False),
    ]


def test_a_route_given_by_the_caller_is_the_one_started(ring: wg.WalkGraph):
    at = wg.attach(ring, PLACES)
    r = rt.plan(ring, ring.nearest(15, 23), ROOM_102, at["p3"], PLACES)
    g, state = rt.guide(ring, r, ROOM_102, at["p3"], Pose(15, 23, "1", 0.0), None, 0.0, PLACES, style="sides")
    assert g["kind"] == "start" and state["nodes"] == r.nodes if r else False
    assert g["sentence"] == "Turn right and walk 12 metres, to the stairs." and g["bearing_deg"] == 90.0


def test_leaving_the_place_a_guidance_started_at_gives_a_route_again(ring: wg.WalkGraph):
    # the first answer is at Room 102 (a route with nowhere to walk); then the user walks 10 m away
    at_place = Pose(39.0, 3.0, "1", 90.0)
    gs, _ = follow(ring, ROOM_102, [at_place, Pose(29.0, 3.0, "1", 270.0), Pose(28.0, 3.0, "1", 270.0)])
    assert [g["kind"] for g in gs] == ["arrived", "start", "continue"]
    assert gs[1]["sentence"] == "Turn to 6 o'clock and walk 10 metres, to Room 102." and not gs[1]["arrived"]
    assert gs[1]["remaining_m"] == 10.0 and gs[1]["urgent"] is False


@pytest.mark.parametrize("phase", [0.0, 0.6, 1.2, 1.8, 2.4])
def test_a_turn_is_said_in_time_to_be_heard_before_its_corner(ring: wg.WalkGraph, phase: float):
    """At 1.2 m/s with an answer every 2.5 s (the app's guided pace), whichever way the answers fall
    the turn's sentence (SPEAK_S long, said LATENCY_S after its clip) ends at least 2 m before
    the corner, and the turn cuts in; a walker standing still is told it no earlier than 3 m."""
    pace, dt = 1.2, 2.5
    poses = walk([(15.0 - phase, 23.0), (27.0, 23.0), (27.0, 3.0)], step=pace * dt)
    gs, _ = follow(ring, ROOM_102, poses, dt=dt)
    first = next(i for i, g in enumerate(gs) if g["speak"] and g["kind"] in ("start", "turn") and g["in_m"])
    corner_m = 27.0 - poses[first].x
    ends_m = corner_m - pace * (rt.LATENCY_S + rt.SPEAK_S)
    assert ends_m >= 2.0, (first, corner_m)
    assert gs[first]["urgent"] and gs[first]["in_m"] == round(corner_m, 1)
    # a slow walker (0.2 m/s): told 3-4.5 m before it, not 11 (never under TURN_AHEAD_M)
    slow = walk([(15.0, 23.0), (27.0, 23.0)], step=0.5)
    gs, _ = follow(ring, ROOM_102, slow, dt=dt)
    told = next(g for g in gs if g["speak"] and g["in_m"])
    assert rt.TURN_AHEAD_M <= told["in_m"] <= 4.5, told["sentence"]
    assert rt.turn_ahead_m(0.0) == rt.TURN_AHEAD_M and rt.turn_ahead_m(1.2) == pytest.approx(11.4)


@pytest.mark.parametrize("pace", [1.4, 1.6])
@pytest.mark.parametrize("phase", [0.0, 1.0, 2.5])
def test_no_keep_going_between_a_turn_said_and_its_corner(ring: wg.WalkGraph, pace: float, phase: float):
    """A turn is said 11-17 m before its corner at a brisk pace: a "Keep going" after it and before
    the corner would send the walker past the corner."""
    route = [(15.0 - phase, 23.0), (27.0, 23.0), (27.0, 3.0), (39.0, 3.0)]
    gs, _ = follow(ring, ROOM_102, walk(route, step=pace * 2.5), dt=2.5)
    corners = [(27.0, 23.0), (27.0, 3.0)]
    pending, reassured = False, 0
    for g in gs:
        if g["speak"] and g["kind"] in ("turn", "start") and g["in_m"]:
            pending = True
        elif g["in_m"] is None and g["bearing_deg"] == 0.0:
            pending = False  # round the corner: the new leg straight ahead
        assert not (pending and g["speak"] and g["kind"] == "reassure"), (g["sentence"], corners)
        reassured += g["speak"] and g["kind"] == "reassure"
    assert reassured >= 1  # (round the corners it still reassures)


def test_standing_on_the_route_facing_away_hears_the_way_again():
    """Issue 44: standing facing away from the way on said nothing. After FACE_AWAY_S facing away
    (and QUIET_S since the last sentence) the instruction is said again from the way the walker
    faces now; turned back the right way, nothing more."""
    graph, end = corridor()
    right = Pose(30.0, 0.0, "1", 90.0)
    away = Pose(30.2, 0.0, "1", 270.0)
    gs, _ = follow(graph, end, [right, away, away, away, away, right, right], dt=2.5)
    said = [(t * 2.5, g["kind"], g["sentence"]) for t, g in enumerate(gs) if g["speak"]]
    assert said == [
        (0.0, "start", "Walk straight ahead 25 metres, to the end."),
        (10.0, "turn", "Turn to 6 o'clock and walk 25 metres, to the end."),  # facing away from 2.5 s on
    ]
    assert all(g["on_route"] for g in gs)
