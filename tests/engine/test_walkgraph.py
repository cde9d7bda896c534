"""The walk graph (walkgraph.py): nodes along the modelling walks, joined where walks cross, floors
joined by lifts and stairs, shortest paths in metres. Built from the synthetic layouts' own
modelling routes (scene.py, walks.py), densified as a modelling video's frames are; no rendering."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from omninav import walkgraph as wg
from omninav.store import FRAME_DTYPE
from omninav.synth.layouts import default_layout, small_layout, twin_routes
from omninav.synth.walks import default_routes


def dense(route: list[tuple[float, float]], step: float = 0.047) -> np.ndarray:
    """A polyline as a modelling video's positions: a point every `step` metres, corners included."""
    out = [np.asarray(route[:1], float)]
    for a, b in zip(route[:-1], route[1:], strict=True):
        a_, b_ = np.asarray(a, float), np.asarray(b, float)
        n = max(1, int(np.ceil(np.hypot(*(b_ - a_)) / step)))
        out.append(a_ + (np.arange(1, n + 1)[:, None] / n) * (b_ - a_))
    return np.concatenate(out)


def default_model_route() -> list[tuple[float, float]]:
    _, _, lines = default_layout()
    return default_routes(SimpleNamespace(routes=None, centerlines=lines))[0]  # type: ignore[arg-type]


def ring_graph() -> wg.WalkGraph:
    return wg.build([(dense(default_model_route()), "1")])


def test_nodes_are_about_a_metre_apart_and_corners_are_nodes():
    g = ring_graph()
    i, j = g.adj.nonzero()
    w = np.asarray(g.adj[i, j]).ravel()
    assert w.max() <= 1.5 + 1e-9 and w.min() > 0
    assert np.allclose((g.adj - g.adj.T).data, 0)  # symmetric
    for corner in [(3, 3), (51, 3), (51, 23), (3, 23), (27, 3), (27, 23)]:
        k = g.nearest(*corner)
        assert np.hypot(*(g.xy[k] - corner)) < 1e-6
    # the ring is 136 m of corridor plus the 20 m middle one: one node a metre, the corridors
    # walked twice (a -> m, the middle one) one chain of nodes, not two
    assert len(g) == 136 + 19
    assert g.floor.dtype.kind == "U" and set(g.floor.tolist()) == {"1"}


def test_graph_distances_are_corridor_distances():
    g = ring_graph()
    a, c, m_s = g.nearest(3, 3), g.nearest(51, 23), g.nearest(27, 23)
    d = g.distances([a, c])
    assert d.shape == (2, len(g))
    assert d[0, c] == pytest.approx(68.0, abs=0.01)  # round the ring (both ways are 68 m)
    assert d[0, m_s] == pytest.approx(44.0, abs=0.01)  # 24 east + 20 down the middle
    assert d[1, g.nearest(39, 3)] == pytest.approx(32.0, abs=0.01)
    # limit: nothing beyond it
    near = g.distances(a, limit=10.0)[0]
    assert np.isfinite(near).sum() == pytest.approx(21, abs=2) and np.nanmax(near[np.isfinite(near)]) <= 10.0


def test_walks_that_cross_are_joined_wherever_their_nodes_fall():
    # a plus: two walks crossing at (10.3, 10.6), neither with a node there
    h = dense([(0.0, 10.6), (20.0, 10.6)])
    v = dense([(10.3, 0.0), (10.3, 21.0)])
    g = wg.build([(h, "1"), (v, "1")])
    d = g.distances(g.nearest(0, 10.6))[0]
    assert d[g.nearest(10.3, 0.0)] == pytest.approx(10.3 + 10.6, abs=0.8)
    assert d[g.nearest(10.3, 21.0)] == pytest.approx(10.3 + 10.4, abs=0.8)


def test_parallel_corridors_behind_a_wall_are_not_joined():
    g = wg.build([(dense([(0.0, 0.0), (10.0, 0.0)]), "1"), (dense([(0.0, 2.5), (10.0, 2.5)]), "1")])
    assert not np.isfinite(g.distances(g.nearest(0, 0))[0, g.nearest(0, 2.5)])
    assert g.path(g.nearest(0, 0), g.nearest(0, 2.5)) == []


def test_the_shortest_path_is_connected_and_as_long_as_its_distance():
    g = ring_graph()
    a, b = g.nearest(15, 23), g.nearest(51, 13)
    p = g.path(a, b)
    assert p[0] == a and p[-1] == b
    steps = [g.edge_m(i, j) for i, j in zip(p[:-1], p[1:], strict=True)]
    assert all(np.isfinite(steps)) and sum(steps) == pytest.approx(g.distances(a)[0, b])
    assert sum(steps) == pytest.approx(36 + 10, abs=0.01)  # east along the south side, up the east side
    assert g.path(a, a) == [a]


def two_floors(places: list[dict]) -> wg.WalkGraph:
    _, _, lines = small_layout()
    walk = dense([lines[0][0], lines[0][1], lines[1][1]])  # the L: 18 m east, 10 m south
    return wg.build([(walk, "1"), (walk, "2")], places)


LIFTS = [
    {"name": "the lifts", "floor": "1", "x": 20.0, "y": 1.0, "kind": "lift"},
    {"name": "the lifts", "floor": "2", "x": 20.0, "y": 1.0, "kind": "lift"},
    {"name": "the stairs", "floor": "1", "x": 20.0, "y": 12.0, "kind": "stairs"},
    {"name": "the stairs", "floor": "2", "x": 20.0, "y": 12.0, "kind": "stairs"},
    {"name": "Room 1", "floor": "2", "x": 11.0, "y": 2.0},
]


def test_a_lift_and_stairs_of_the_same_name_join_two_floors():
    g = two_floors(LIFTS)
    assert sorted(g.via.values()) == ["lift", "stairs"]
    for (i, j), kind in g.via.items():
        assert i < j and g.floor[i] != g.floor[j]
        assert g.edge_m(i, j) == (wg.LIFT_COST_M if kind == "lift" else wg.STAIRS_COST_M)
    a, b = g.nearest(2, 2, "1"), g.nearest(11, 2, "2")
    assert g.distances(a)[0, b] == pytest.approx(18 + wg.LIFT_COST_M + 9)
    p = g.path(a, b)
    assert [g.floor[k] for k in (p[0], p[-1])] == ["1", "2"]
    assert sum(g.floor[i] != g.floor[j] for i, j in zip(p[:-1], p[1:], strict=True)) == 1


def test_floors_stay_apart_without_a_named_pair():
    alone = [p | {"name": "lift " + p["floor"]} for p in LIFTS[:2]]  # two lifts of different names
    g = two_floors(alone + [{"name": "Room 1", "floor": "1", "x": 11, "y": 2, "kind": "lift"}])
    assert g.via == {}
    assert g.path(g.nearest(2, 2, "1"), g.nearest(2, 2, "2")) == []


def test_nearest_keeps_to_the_floor_and_snap_agrees():
    g = two_floors(LIFTS)
    k1, k2 = g.nearest(20, 5, "1"), g.nearest(20, 5, "2")
    assert g.floor[k1] == "1" and g.floor[k2] == "2" and np.allclose(g.xy[k1], g.xy[k2])
    assert g.floor[g.nearest(20, 5, "9")] in {"1", "2"}  # a floor without nodes: any floor
    pts = np.array([[3.2, 2.1], [19.7, 8.2], [20, 5]])
    fl = np.array(["1", "2", "2"])
    assert g.snap(pts, fl).tolist() == [g.nearest(x, y, f) for (x, y), f in zip(pts, fl, strict=True)]
    assert np.allclose(g.xy[g.snap(pts)], g.xy[[g.nearest(x, y) for x, y in pts]])


def test_the_key_fingerprints_nodes_and_edges():
    a, b = ring_graph(), ring_graph()
    assert a.key == b.key and len(a.key) == 16 and int(a.key, 16) >= 0
    moved = wg.build([(dense(default_model_route()) + [0.5, 0.0], "1")])
    more = wg.build([(dense(default_model_route()), "1")], join_m=1.5)  # diagonals at the corners
    other_floor = wg.build([(dense(default_model_route()), "2")])
    assert len({a.key, moved.key, more.key, other_floor.key}) == 4


def test_attach_places_to_their_nearest_node_on_their_floor():
    g = two_floors(LIFTS)
    places = LIFTS + [
        {"id": "p9", "name": "Room 9", "floor": "1", "x": 19.0, "y": 9.0},
        {"name": "far away", "floor": "1", "x": 10.0, "y": 14.0},
        {"name": "no floor here", "floor": "3", "x": 2.0, "y": 2.0},
    ]
    at = wg.attach(g, places)
    assert set(at) == {"the lifts", "the stairs", "Room 1", "p9"}
    assert g.floor[at["p9"]] == "1" and np.allclose(g.xy[at["p9"]], (20, 9))
    assert g.floor[at["Room 1"]] == "2" and np.allclose(g.xy[at["Room 1"]], (11, 2))
    assert "far away" in wg.attach(g, places, max_m=12.0)


def test_from_frames_makes_one_walk_per_video_in_time_order():
    model = dense(twin_routes()[0], step=0.2)
    other = dense([(3.0, 8.0), (3.0, 2.0)], step=0.2)  # a dead end off the ring, on floor 2 here
    rows = np.zeros(len(model) + len(other), FRAME_DTYPE)
    rows["x"] = np.r_[model[:, 0], other[:, 0]]
    rows["y"] = np.r_[model[:, 1], other[:, 1]]
    rows["t"] = np.r_[np.arange(len(model)) * 0.1, np.arange(len(other)) * 0.1]
    rows["video"] = np.r_[np.zeros(len(model)), np.ones(len(other))]
    shuffled = rows[np.random.default_rng(0).permutation(len(rows))]
    g = wg.from_frames(shuffled, ["1", "2"])
    want = wg.build([(model.astype(np.float32).astype(float), "1"), (other.astype(np.float32).astype(float), "2")])
    assert g.key == want.key
    assert (g.floor == "2").sum() == 7  # 6 m every metre
    ring = g.floor == "1"
    assert np.isfinite(g.distances(g.nearest(3, 8, "1"))[0][ring]).all()


def test_simplify_keeps_corners_and_a_dead_ends_turning_point():
    p = dense([(0.0, 0.0), (10.0, 0.0), (10.0, 5.0), (10.0, 0.0), (0.0, 0.0)], step=0.3)
    kept = p[wg.simplify(p, 0.1)]
    assert np.allclose(kept, [(0, 0), (10, 0), (10, 5), (10, 0), (0, 0)])
    nodes = wg.resample(p, 1.0)
    assert len(nodes) == 10 + 5 + 5 + 10 + 1
    assert wg.resample(np.array([[1.0, 1.0], [1.0, 1.0]])).tolist() == [[1.0, 1.0]]  # standing still
