"""Tracking while walking (tracking.py): the filter over the walk graph, its state, its CLI.

Most tests feed the filter made-up candidate matches on a venue of frames along known corridors
(no rendering): where the truth is, where its look-alike is, and how well each scores. That pins
what the filter does with evidence a single clip cannot settle. The last ones run it on the small
rendered venue (conftest.py), through Locator.track and the `omninav track` / `evaluate
--track-mode` commands.
"""

from __future__ import annotations

import json
import struct
import zlib
from dataclasses import fields, replace
from pathlib import Path

import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st

from conftest import cli_model, run_cli
from omninav.aggregate import sequence
from omninav.errors import OmninavError
from omninav.index import Matches
from omninav.lens import load_lens
from omninav.locate import Locator
from omninav.lookalikes import node_frames
from omninav.motion import Motion, parse_imu, parts, share
from omninav.presets import resolve
from omninav.synth import Dataset
from omninav.synth.layouts import TWIN_RING, twin_routes
from omninav.synth.walks import imu_for, walk_path_for
from omninav.tracking import FIT_M, STEPS_WORK_S, Tracker
from omninav.tracking_state import MAX_STORED, ClipAnswer, TrackState
from omninav.walk_path import parse_walk_path
from omninav.walkgraph import build

CONF = resolve("default")
FPS = 10.0
K = 16


def heading_of(a: np.ndarray, b: np.ndarray) -> float:
    """Plan heading from a to b: clockwise from up (y down)."""
    return float(np.degrees(np.arctan2(b[0] - a[0], -(b[1] - a[1]))) % 360.0)


def frames_along(route: list[tuple[float, float]], step: float = 0.12) -> tuple[np.ndarray, np.ndarray]:
    """Venue frames every `step` m along a modelling route: (V, 2) positions, (V,) headings."""
    xy, hd = [], []
    for a, b in zip(route[:-1], route[1:], strict=True):
        a, b = np.asarray(a, float), np.asarray(b, float)
        n = max(1, int(np.ceil(np.hypot(*(b - a)) / step)))
        for f in np.arange(n) / n:
            xy.append(a + f * (b - a))
            hd.append(heading_of(a, b))
    xy.append(np.asarray(route[-1], float))
    hd.append(hd[-1])
    return np.array(xy), np.array(hd)


class Venue:
    """Frames along a route, its walk graph and a tracker; made-up matches for any truth."""

    def __init__(self, route: list[tuple[float, float]], conf: dict | None = None):
        self.xy, self.hd = frames_along(route)
        self.graph = build([(self.xy, "1")])
        self.conf = {**CONF, **(conf or {})}
        self.tracker = Tracker(self.graph, self.xy, np.full(len(self.xy), "1"), self.conf)

    def matches(
        self, sources: list[list[tuple[float, float, float, float]]], rng: np.random.Generator, per: int = 4
    ) -> Matches:
        """Per frame, a list of (x, y, heading, score): each source's `per` nearest venue frames
        score about `score` (less with distance) and give `heading`; the rest are random frames."""
        q = len(sources)
        idx = np.zeros((q, K), np.int64)
        sc = np.zeros((q, K), np.float32)
        hd = np.zeros((q, K), np.float32)
        for i, srcs in enumerate(sources):
            cols: list[tuple[int, float, float]] = []
            for x, y, h, s in srcs:
                d = np.hypot(self.xy[:, 0] - x, self.xy[:, 1] - y)
                for j in np.argsort(d)[:per]:
                    cols.append((int(j), s - 0.03 * float(d[j]) + rng.normal(0, 0.005), h + rng.normal(0, 1.0)))
            while len(cols) < K:
                cols.append((int(rng.integers(len(self.xy))), rng.uniform(0.2, 0.4), rng.uniform(0, 360)))
            cols.sort(key=lambda c: -c[1])
            for j, (r, s, h) in enumerate(cols[:K]):
                idx[i, j], sc[i, j], hd[i, j] = r, s, h % 360.0
        return Matches(idx, sc.copy(), sc, hd)


def walk_poses(points: list[tuple[float, float]], speed: float = 1.2) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A walk along points at `speed`, sampled at FPS: times, (T, 2) positions, headings."""
    walk_path = parse_walk_path(walk_path_for(points, [speed], FPS))
    t = np.arange(0.0, walk_path.times[-1] + 1e-9, 1.0 / FPS)
    xy, hd, _ = walk_path.pose_at(t)
    return t, xy, hd


def half_turn(x: float, y: float) -> tuple[float, float]:
    x0, y0, x1, y1 = TWIN_RING
    return x0 + x1 - x, y0 + y1 - y


def in_west_wing(x: float, y: float) -> bool:
    """The west twin's stretch that looks like the east one (its corners differ)."""
    x0, y0, _, y1 = TWIN_RING
    return abs(x - x0) < 0.3 and y0 + 1.5 < y < y1 - 1.5


def run_walk(
    v: Venue,
    t: np.ndarray,
    xy: np.ndarray,
    hd: np.ndarray,
    evidence,
    every: float = 1.0,
    seed: int = 0,
    motion=None,
    per: int = 4,
    own: bool = False,
):
    """Update the filter every `every` s with the 1 s clip ending there (`own`: with what the clip
    answers alone, as Locator.track gives it); -> per update (t, pose, the single clip's Estimate,
    truth xy, state)."""
    rng = np.random.default_rng(seed)
    state, out, t_prev = None, [], None
    for e in range(int(FPS) - 1, len(t), int(round(every * FPS))):
        w = slice(e - int(FPS) + 1, e + 1)
        m = v.matches([evidence(x, y, h) for (x, y), h in zip(xy[w], hd[w], strict=True)], rng, per)
        mo = motion(t_prev, t[e]) if motion is not None and t_prev is not None else None
        est = sequence(m, v.xy, t[w], v.conf)
        state, pose = v.tracker.update(state, m, t[w], float(t[e]), mo, ClipAnswer.of(est, v.conf) if own else None)
        t_prev = float(t[e])
        out.append((float(t[e]), pose, est, xy[e], state))
    return out


@pytest.fixture(scope="module")
def twin() -> Venue:
    return Venue(twin_routes()[0])


def twin_evidence(true_s: float, alike_s: float):
    """In the west wing's middle, its half-turned look-alike in the east wing scores alike_s."""

    def ev(x: float, y: float, h: float) -> list[tuple[float, float, float, float]]:
        out = [(x, y, h, true_s if in_west_wing(x, y) else 0.8)]
        if in_west_wing(x, y):
            out.append((*half_turn(x, y), h + 180.0, alike_s))
        return out

    return ev


def err(pose, xy) -> float:
    return float(np.hypot(pose.x - xy[0], pose.y - xy[1]))


def test_the_filter_rules_out_the_look_alike_a_single_clip_picks(twin: Venue) -> None:
    """Down the west wing from the north corridor: every second's clip prefers the east twin
    (0.81 against 0.79), so the single clip answers ~10 m away; the filter knows where the walk
    came from and stays right, and says it is sure."""
    x0, y0, _, y1 = TWIN_RING
    t, xy, hd = walk_poses([(12.0, y0), (x0, y0), (x0, y1)])
    out = run_walk(twin, t, xy, hd, twin_evidence(0.79, 0.81))
    wing = [(p, e, truth) for tt, p, e, truth, _ in out if in_west_wing(*truth) and tt > 3]
    assert len(wing) >= 6
    single_wrong = [np.hypot(e.x - truth[0], e.y - truth[1]) > 5 for _, e, truth in wing]
    assert np.mean(single_wrong) >= 0.8
    assert all(err(p, truth) <= 2.0 for p, _, truth in wing)
    assert all(not p.ambiguous and p.confidence >= 0.8 for p, _, _ in wing)


def test_an_ambiguous_start_says_so_then_resolves_within_seconds(twin: Venue) -> None:
    """Starting in the middle of a twin wing (the look-alike scores the same), the answer is
    "not sure" (ambiguous, confidence < 0.5), never a confident wrong one; a few seconds after
    the walk leaves the wing it is right and sure."""
    x0, y0, _, _ = TWIN_RING
    t, xy, hd = walk_poses([(x0, 16.0), (x0, y0), (12.0, y0)])
    out = run_walk(twin, t, xy, hd, twin_evidence(0.8, 0.8))
    first = out[0][1]
    assert first.ambiguous and first.confidence < 0.5 and first.spread_m > 5
    for tt, p, _, truth, _ in out:
        if p.confidence >= 0.8:
            assert err(p, truth) <= 2.0, f"confident and wrong at {tt:.0f} s"
    left = next(tt for tt, _, _, truth, _ in out if not in_west_wing(*truth))
    after = [(tt, p, truth) for tt, p, _, truth, _ in out if tt >= left + 3.0]
    assert after and all(err(p, truth) <= 2.0 and not p.ambiguous and p.confidence >= 0.8 for _, p, truth in after)


def test_a_split_belief_is_ambiguous_with_low_confidence(twin: Venue) -> None:
    tr = twin.tracker
    a = twin.graph.nearest(3.0, 14.0)
    b = twin.graph.nearest(*half_turn(3.0, 14.0))
    m = twin.matches([[(3.0, 14.0, 0.0, 0.8)]], np.random.default_rng(0))
    for p_a, ambiguous in ((0.5, True), (0.65, True), (1.0, False)):
        belief = np.zeros(tr.n)
        belief[a], belief[b] = p_a, 1 - p_a
        pose = tr.pose(belief, m, np.array([0.0]), 0.0, updates=10)
        assert pose.ambiguous is ambiguous
        assert (pose.confidence < 0.5) if ambiguous else (pose.confidence >= 0.8)


def test_a_sure_answer_is_not_stood_by_while_the_recent_clips_are_unsure() -> None:
    """The walk has made the belief sure; then the clips stop matching the model well (their own
    confidence low): the answer's place is unchanged but it is no longer "sure" (held at
    track_doubt_cap) until the clips' mean over about track_recent_s seconds recovers."""
    # the clips below are one view again and again, without sensors: what the clips alone take
    # for a phone held still (track_still_seen, tested below); off, the rule here is alone
    twin = Venue(twin_routes()[0], {"track_still_seen": False})
    x0, y0, _, _ = TWIN_RING
    t, xy, hd = walk_poses([(12.0, y0), (x0, y0), (x0, 16.0)])
    state = run_walk(twin, t, xy, hd, twin_evidence(0.8, 0.8))[-1][-1]
    cap, low = twin.conf["track_doubt_cap"], twin.conf["track_recent_min"]
    assert cap < 0.8 and low is not None and state.recent is None  # (run_walk gives no clip confidence)
    m = twin.matches([[(x0, 16.0, 180.0, 0.8)]] * 10, np.random.default_rng(2))

    def step(st: TrackState, dt: float, c: float | None):
        times = st.t + dt + np.arange(-0.9, 0.01, 0.1)
        return twin.tracker.update(st, m, times, float(times[-1]), None, None if c is None else ClipAnswer(c))

    plain = step(state, 1.0, None)[1]
    assert plain.confidence >= 0.8
    sure, p_sure = step(state, 1.0, 0.95)
    assert sure.recent == pytest.approx(0.95) and p_sure.confidence == pytest.approx(plain.confidence)
    doubt, p_doubt = step(state, 1.0, 0.1)  # a first clip says the mean
    assert doubt.recent == pytest.approx(0.1) and p_doubt.confidence == pytest.approx(cap)
    assert (p_doubt.node, p_doubt.x, p_doubt.y) == (plain.node, plain.x, plain.y)  # the same answer
    # after sure clips, one middling clip does not undo them; a run of unsure ones does
    mid, p_mid = step(sure, 1.0, 0.6)
    assert low < mid.recent < 0.95 and p_mid.confidence >= 0.8
    st, conf = sure, []
    for _ in range(3):
        st, p = step(st, 1.0, 0.2)
        conf.append(p.confidence)
    assert conf[-1] == pytest.approx(cap) and st.recent < low
    # and clips that match well again bring "sure" back within a few seconds
    for _ in range(3):
        st, p = step(st, 1.0, 0.95)
    assert st.recent > low and p.confidence >= 0.8
    # the mean is over time, not over clips: one clip 2.5 s after sure ones moves it further
    assert step(sure, 2.5, 0.2)[0].recent < step(sure, 1.0, 0.2)[0].recent
    # off: the rule never holds an answer back
    off = Tracker(twin.graph, twin.xy, np.full(len(twin.xy), "1"), {**twin.conf, "track_recent_min": None})
    times = state.t + 1 + np.arange(-0.9, 0.01, 0.1)
    assert off.update(state, m, times, float(times[-1]), None, ClipAnswer(0.1))[1].confidence == pytest.approx(
        plain.confidence
    )
    # an update without the clip's confidence (or with one that is no number) leaves the rule out,
    # and the mean starts over at the next clip rather than carrying a stale one across the gap
    for none in (None, float("nan")):
        gap, p_gap = step(doubt, 1.0, none)
        assert gap.recent is None and p_gap.confidence >= 0.8  # (the mean was 0.1: not held)
        assert step(gap, 1.0, 0.9)[0].recent == pytest.approx(0.9)


def test_a_sure_answer_is_not_stood_by_when_a_sure_clip_says_it_is_elsewhere(twin: Venue) -> None:
    """The walk is sure of the west wing; the clip alone is sure of the east twin, 3 m or more
    away: two calibrated sources disagree, so the answer (still the walk's) is held below "sure".
    A clip that agrees, or is not sure, or does not say where, changes nothing."""
    x0, y0, _, _ = TWIN_RING
    t, xy, hd = walk_poses([(12.0, y0), (x0, y0), (x0, 16.0)])
    state = run_walk(twin, t, xy, hd, twin_evidence(0.8, 0.8))[-1][-1]
    m = twin.matches([[(x0, 16.0, 180.0, 0.8)]] * 10, np.random.default_rng(4))
    times = state.t + 1 + np.arange(-0.9, 0.01, 0.1)

    def row(x: float, y: float) -> int:  # the venue frame nearest (x, y)
        return int(np.argmin(np.hypot(twin.xy[:, 0] - x, twin.xy[:, 1] - y)))

    def pose(tr: Tracker, clip: ClipAnswer | None):
        return tr.update(state, m, times, float(times[-1]), None, clip)[1]

    plain = pose(twin.tracker, None)
    assert plain.confidence >= 0.8 and np.hypot(plain.x - x0, plain.y - 16.0) <= 2.0
    ex, ey = half_turn(x0, 16.0)
    there = pose(twin.tracker, ClipAnswer(0.95, ex, ey, row(ex, ey)))
    assert there.confidence == pytest.approx(twin.conf["track_doubt_cap"])
    assert (there.node, there.x, there.y) == (plain.node, plain.x, plain.y)  # the walk's answer, unsure
    for agrees in (
        ClipAnswer(0.95, plain.x, plain.y + 1.5, row(plain.x, plain.y + 1.5)),  # 1.5 m: the same place
        ClipAnswer(0.7, ex, ey, row(ex, ey)),  # not sure itself (and its mean not low)
        ClipAnswer(0.95),  # no place given
    ):
        assert pose(twin.tracker, agrees).confidence == pytest.approx(plain.confidence)
    # a sure clip on another floor is elsewhere too, however close in x and y
    floors = np.full(len(twin.xy), "1")
    up = row(plain.x, plain.y + 1.0)
    floors[up] = "2"
    two = Tracker(twin.graph, twin.xy, floors, twin.conf)
    assert pose(two, ClipAnswer(0.95, plain.x, plain.y + 1.0, up)).confidence == pytest.approx(
        twin.conf["track_doubt_cap"]
    )


def test_a_sure_clip_breaks_a_tie_the_walk_cannot_but_never_overrules_the_walk(twin: Venue) -> None:
    """The belief is split between a spot of the west wing and its east twin, a little more on
    the west; the clips score both alike. The clip alone is sure of the east twin: with
    track_clip_tie the answer is the clip's place (still not sure: the walk holds the other), and
    without it the walk's. A belief that has all but ruled the east out keeps its answer."""
    x0, _, _, _ = TWIN_RING
    ex, ey = half_turn(x0, 16.0)
    a, b = twin.graph.nearest(x0, 16.0), twin.graph.nearest(ex, ey)
    m = twin.matches([[(x0, 16.0, 180.0, 0.8), (ex, ey, 0.0, 0.8)]] * 10, np.random.default_rng(5))
    times = 20.0 + np.arange(-0.9, 0.01, 0.1)
    row = int(np.argmin(np.hypot(twin.xy[:, 0] - ex, twin.xy[:, 1] - ey)))
    clip = ClipAnswer(0.95, ex, ey, row)

    def answer(tie: float | None, west: float, c: ClipAnswer | None = clip, **conf):
        belief = np.full(twin.tracker.n, 1e-6)
        belief[a], belief[b] = west, 1.0 - west
        state = TrackState(19.0, belief / belief.sum(), twin.graph.key, 10, None, None, None, None, None)
        tr = Tracker(twin.graph, twin.xy, np.full(len(twin.xy), "1"), {**twin.conf, "track_clip_tie": tie, **conf})
        return tr.update(state, m, times, float(times[-1]), None, c)[1]

    walk = answer(None, 0.6)
    assert np.hypot(walk.x - x0, walk.y - 16.0) <= 2.0  # the walk's place, a little the likelier
    broken = answer(0.5, 0.6)
    assert np.hypot(broken.x - ex, broken.y - ey) <= 2.0 and broken.node != walk.node
    assert broken.confidence < 0.8 and broken.alike_mass is not None  # (the second belief read there too)
    # the clip's place is held below sure like the walk's would be: the two sources disagreed
    low = answer(0.5, 0.6, track_doubt_cap=0.2)
    assert low.node == broken.node and low.confidence <= 0.2
    assert answer(0.5, 0.6, ClipAnswer(0.7, ex, ey, row)).node == walk.node  # a clip not sure itself
    assert answer(0.5, 0.6, ClipAnswer(0.95)).node == walk.node  # a clip that does not say where
    assert answer(0.5, 0.6, ClipAnswer(0.95, float("nan"), ey, row)).node == walk.node  # nor as a point
    assert answer(0.5, 0.6, ClipAnswer(0.95, ex + 6.0, ey, row)).node == walk.node  # 6 m from any node
    ruled_out = answer(0.5, 0.97)  # the walk holds the east twin 1 in 30: not about as likely
    assert ruled_out.node == answer(None, 0.97).node and np.hypot(ruled_out.x - x0, ruled_out.y - 16.0) <= 2.0
    assert answer(1.0, 0.6).node == walk.node  # asked for as much belief there as here: not broken


@pytest.mark.parametrize(
    "key, bad",
    [
        ("track_clip_tie", 0),
        ("track_clip_tie", -1.0),
        ("track_clip_tie", "0.5"),
        ("track_clip_tie", float("nan")),
        ("track_clip_tie", 1.5),
        ("track_zero_steps_m", 0),
        ("track_zero_steps_m", True),
        ("track_recent_s", 0),
        ("track_recent_s", -1.0),
        ("track_recent_s", None),
        ("track_recent_s", float("inf")),
        ("track_recent_min", 1.5),
        ("track_recent_min", "0.5"),
        ("track_doubt_cap", None),
        ("track_doubt_cap", -0.1),
        ("track_doubt_cap", True),
    ],
)
def test_bad_settings_of_the_clips_own_answer_are_refused(twin: Venue, key: str, bad: object) -> None:
    with pytest.raises(OmninavError, match=key):
        Tracker(twin.graph, twin.xy, np.full(len(twin.xy), "1"), {**twin.conf, key: bad})


def test_the_recent_clips_mean_is_saved_with_the_state(twin: Venue) -> None:
    x0, y0, _, _ = TWIN_RING
    t, xy, hd = walk_poses([(12.0, y0), (x0, y0)])
    state = run_walk(twin, t, xy, hd, twin_evidence(0.8, 0.8))[-1][-1]
    m = twin.matches([[(x0, y0, 180.0, 0.8)]] * 10, np.random.default_rng(3))
    times = state.t + 1 + np.arange(-0.9, 0.01, 0.1)
    new, _ = twin.tracker.update(state, m, times, float(times[-1]), None, ClipAnswer(0.3))
    assert new.recent == pytest.approx(0.3) and new.alike is not None
    b = new.to_bytes()
    back = TrackState.from_bytes(b, twin.graph)
    assert back is not None and back.recent == pytest.approx(0.3) and back.alike is not None
    # a state saved without it (before it existed: the same bytes less the tail) reads with None
    old = TrackState.from_bytes(state.to_bytes(), twin.graph)
    assert old is not None and old.recent is None and old.alike is not None
    # without the second belief (a venue without look-alikes, tempering off) the mean still travels
    lone = TrackState(new.t, new.belief, new.graph_key, new.updates, new.heading, new.facing, None, 0.3)
    got = TrackState.from_bytes(lone.to_bytes(), twin.graph)
    assert got is not None and got.alike is None and got.recent == pytest.approx(0.3)
    # the sections in another order are no state this code wrote
    rc = b"RC" + struct.pack("<d", 0.3)
    head = lone.to_bytes()[: -4 - len(rc)]
    with_alike = replace(new, best=None).to_bytes()[:-4]
    swapped = head + rc + with_alike[len(head) + 0 : -len(rc)]
    assert TrackState.from_bytes(swapped + struct.pack("<I", zlib.crc32(swapped)), twin.graph) is None
    # a mean that is no probability, or bytes after it: refused like any corrupt state
    body = replace(new, best=None).to_bytes()[:-4]
    for bad in (body[:-8] + struct.pack("<d", 1.5), body[:-8] + struct.pack("<d", float("nan")), body + b"x"):
        assert TrackState.from_bytes(bad + struct.pack("<I", zlib.crc32(bad)), twin.graph) is None


def test_state_round_trips_and_refuses_another_graph_or_corrupt_bytes(twin: Venue) -> None:
    x0, y0, _, _ = TWIN_RING
    t, xy, hd = walk_poses([(12.0, y0), (x0, y0), (x0, 16.0)])
    state = run_walk(twin, t, xy, hd, twin_evidence(0.8, 0.8))[-1][-1]
    b = state.to_bytes()
    back = TrackState.from_bytes(b, twin.graph)
    assert back is not None
    assert (back.t, back.updates, back.graph_key) == (state.t, state.updates, state.graph_key)
    assert back.heading == pytest.approx(state.heading, abs=1e-3)
    big = state.belief >= 1e-3
    np.testing.assert_allclose(back.belief[big], state.belief[big], rtol=2e-3)
    assert back.belief.sum() == pytest.approx(1.0)
    # the next update continues from the restored state as from the original
    m = twin.matches([[(3.0, 15.0, 180.0, 0.8)]] * 10, np.random.default_rng(1))
    times = state.t + 1 + np.arange(-0.9, 0.01, 0.1)
    p1 = twin.tracker.update(state, m, times, float(times[-1]))[1]
    p2 = twin.tracker.update(back, m, times, float(times[-1]))[1]
    assert (p1.node, p1.ambiguous) == (p2.node, p2.ambiguous)
    assert p1.confidence == pytest.approx(p2.confidence, abs=1e-3)
    # another graph (another venue, or this one re-modelled), and broken bytes: None
    other = build([(twin.xy[::-1] + [0.0, 1.0], "1")])
    assert TrackState.from_bytes(b, other) is None
    for bad in (b"", b[:-1], b[:20], b[:30] + bytes([b[30] ^ 1]) + b[31:], b"\x00" * len(b), b + b"x"):
        assert TrackState.from_bytes(bad, twin.graph) is None


def test_state_of_a_2000_node_graph_fits_in_16_kb() -> None:
    # a 2 km serpentine of corridors: ~2,000 nodes; the worst belief is a flat one
    pts = [(0.0, 0.0)]
    for i in range(20):
        pts += [(100.0 if i % 2 == 0 else 0.0, 5.0 * i), (100.0 if i % 2 == 0 else 0.0, 5.0 * (i + 1))]
    g = build([(np.array(pts), "1")])
    assert len(g.xy) >= 2000
    st = TrackState(12.5, np.full(len(g.xy), 1.0 / len(g.xy)), g.key, 3, 90.0)
    b = st.to_bytes()
    assert len(b) <= 16 * 1024
    back = TrackState.from_bytes(b, g)
    assert back is not None and back.heading == 90.0 and back.updates == 3
    np.testing.assert_allclose(back.belief, st.belief)  # flat stays flat: every node, not the first 1,500


def test_a_broad_young_belief_on_a_big_graph_is_kept_whole() -> None:
    """More than MAX_STORED nodes with belief (a young track on a 2,000-node graph: a clip that
    says little, so most nodes tie): the saved state keeps every part of the building, not the
    lowest-numbered nodes; a sharp belief is still kept node by node (8 bytes each)."""
    pts = [(0.0, 0.0)]
    for i in range(20):
        pts += [(100.0 if i % 2 == 0 else 0.0, 5.0 * i), (100.0 if i % 2 == 0 else 0.0, 5.0 * (i + 1))]
    g = build([(np.array(pts), "1")])
    n = len(g.xy)
    assert n > MAX_STORED
    rng = np.random.default_rng(3)
    p = np.full(n, 1.0)
    p[rng.choice(n, 40, replace=False)] = 5.0  # a few places a little likelier, anywhere
    p /= p.sum()
    facing = np.where(np.arange(n) % 3 == 0, 90.0, np.nan)
    back = TrackState.from_bytes(TrackState(1.0, p, g.key, 1, None, facing).to_bytes(), g)
    assert back is not None and back.heading is None
    np.testing.assert_allclose(back.belief, p, rtol=2e-3)
    assert back.facing is not None and np.array_equal(np.isnan(back.facing), np.isnan(facing))
    late = np.arange(n) >= n - 500  # the last-numbered nodes (the serpentine's far end) keep theirs
    assert back.belief[late].sum() == pytest.approx(p[late].sum(), rel=2e-3)
    sharp = np.zeros(n)
    sharp[[5, n - 5]] = [0.7, 0.3]
    b = TrackState(1.0, sharp, g.key, 9, 45.0).to_bytes()
    assert len(b) < 200
    back = TrackState.from_bytes(b, g)
    assert back is not None and back.belief[n - 5] == pytest.approx(0.3, abs=1e-3)
    for bad in (b[:-5] + b[-4:], b"ONTA" + b[4:]):
        assert TrackState.from_bytes(bad, g) is None


def test_the_look_alike_belief_is_saved_beside_the_belief_and_a_state_without_it_still_reads() -> None:
    """A venue with look-alikes (the twin's wings, half turned): the state keeps both beliefs,
    node by node or whole; a state saved without the look-alike one (before it existed, or a
    venue without look-alikes) still reads, and the next update starts it as the belief; a
    damaged look-alike part is refused with the rest."""
    v = Venue(twin_routes()[0], {"track_alike_cost": 10.0})
    rows = node_frames(v.graph, v.xy, np.full(len(v.xy), "1"))
    like = v.matches([[(*half_turn(*v.xy[r]), 0.0, 0.95)] for r in rows], np.random.default_rng(2), per=1)
    v.tracker = Tracker(v.graph, v.xy, np.full(len(v.xy), "1"), v.conf, like)
    x0, y0, _, _ = TWIN_RING
    t, xy, hd = walk_poses([(12.0, y0), (x0, y0), (x0, 16.0)])
    state = run_walk(v, t, xy, hd, twin_evidence(0.8, 0.8))[-1][-1]
    assert state.alike is not None and not np.allclose(state.alike, state.belief, atol=1e-3)
    b = state.to_bytes()
    back = TrackState.from_bytes(b, v.graph)
    assert back is not None and back.alike is not None
    big = state.alike >= 1e-3
    np.testing.assert_allclose(back.alike[big], state.alike[big], rtol=2e-3)
    np.testing.assert_allclose(back.belief[state.belief >= 1e-3], state.belief[state.belief >= 1e-3], rtol=2e-3)
    # without it: read, and the next update makes one
    old = TrackState(state.t, state.belief, state.graph_key, state.updates, state.heading, state.facing)
    got = TrackState.from_bytes(old.to_bytes(), v.graph)
    assert got is not None and got.alike is None and len(old.to_bytes()) < len(b)
    m = v.matches([[(3.0, 15.0, 180.0, 0.8)]] * 10, np.random.default_rng(1))
    times = state.t + 1 + np.arange(-0.9, 0.01, 0.1)
    new, pose = v.tracker.update(got, m, times, float(times[-1]))
    assert new.alike is not None and new.alike.sum() == pytest.approx(1.0)
    # whole (a broad belief on a big graph): both kept
    pts = [(0.0, 0.0)]
    for i in range(20):
        pts += [(100.0 if i % 2 == 0 else 0.0, 5.0 * i), (100.0 if i % 2 == 0 else 0.0, 5.0 * (i + 1))]
    g = build([(np.array(pts), "1")])
    n = len(g.xy)
    p = np.linspace(1.0, 2.0, n) / np.linspace(1.0, 2.0, n).sum()
    q = p[::-1].copy()
    whole = TrackState.from_bytes(TrackState(1.0, p, g.key, 1, None, None, q).to_bytes(), g)
    assert whole is not None and whole.alike is not None
    np.testing.assert_allclose(whole.belief, p, rtol=2e-3)
    np.testing.assert_allclose(whole.alike, q, rtol=2e-3)
    # a node-by-node belief with a whole look-alike one, and the other way round
    sharp = np.zeros(n)
    sharp[[5, n - 5]] = [0.7, 0.3]
    for main, like in ((sharp, q), (p, sharp)):
        mixed = TrackState.from_bytes(TrackState(1.0, main, g.key, 3, None, None, like).to_bytes(), g)
        assert mixed is not None and mixed.alike is not None
        np.testing.assert_allclose(mixed.belief[main > 0], main[main > 0], rtol=2e-3)
        np.testing.assert_allclose(mixed.alike[like > 0], like[like > 0], rtol=2e-3)

    def sealed(body: bytes) -> bytes:
        return body + struct.pack("<I", zlib.crc32(body))

    # a damaged or cut look-alike part, the checksum made good: refused
    assert TrackState.from_bytes(sealed(b[:-4][:-3]), v.graph) is None
    plain_len = len(old.to_bytes()) - 4
    assert TrackState.from_bytes(sealed(b[: plain_len + 5]), v.graph) is None
    body = bytearray(b[:-4])
    at = (
        len(TrackState(state.t, state.belief, state.graph_key, state.updates, state.heading, state.facing).to_bytes())
        - 4
    )
    assert bytes(body[at : at + 2]) in (b"AS", b"AW")
    body[at : at + 2] = b"XX"
    assert TrackState.from_bytes(bytes(body) + struct.pack("<I", zlib.crc32(bytes(body))), v.graph) is None


# States as the filter saved them before the look-alike belief (7f7ef8a's TrackState.to_bytes,
# checked byte for byte against it): a server updated in the middle of a walk reads them on
OLD_SPARSE = (
    "4f4e54320000000000002940070000000000344207000000106662303366353731643135366435623302000000010000"
    "0004000000003c5535a055007e68b27665"
)
OLD_WHOLE = (
    "4f4e54410000000000000840020000000000c07fa50600001065353131656263633735323134323562789cedc3310d00"
    "000803b0c9e2401bdad1b0bf699acd445555d5e6010000d0793afec6d789ca1aaa"
)


def test_states_saved_before_the_look_alike_belief_still_read() -> None:
    g = build([(np.array([(0.0, 0.0), (6.0, 0.0)]), "1")])
    st = TrackState.from_bytes(bytes.fromhex(OLD_SPARSE), g)
    assert st is not None and st.alike is None
    assert (st.t, st.updates, st.heading) == (12.5, 7, 45.0)
    assert st.belief[1] == pytest.approx(0.75, abs=1e-3) and st.belief[4] == pytest.approx(0.25, abs=1e-3)
    assert st.facing is not None and st.facing[1] == 90.0 and np.isnan(st.facing[0])
    big = build([(np.array([(0.0, 0.0), (0.0, 1700.0)]), "1")])
    st = TrackState.from_bytes(bytes.fromhex(OLD_WHOLE), big)
    assert st is not None and st.alike is None and st.heading is None and len(st.belief) == len(big.xy)
    assert st.belief[0] == pytest.approx(2 * st.belief[1], rel=1e-3)


def test_a_state_of_another_graph_starts_over(twin: Venue) -> None:
    m = twin.matches([[(3.0, 14.0, 0.0, 0.8)]], np.random.default_rng(0))
    stale = TrackState(0.0, np.full(7, 1 / 7), "another", 9)
    state, _ = twin.tracker.update(stale, m, np.array([1.0]), 1.0)
    assert state.updates == 1 and state.graph_key == twin.graph.key
    old = TrackState(0.0, np.full(twin.tracker.n, 1 / twin.tracker.n), twin.graph.key, 9)
    assert twin.tracker.update(old, m, np.array([1000.0]), 1000.0)[0].updates == 1  # long forgotten
    assert twin.tracker.update(old, m, np.array([1.0]), 1.0)[0].updates == 10


@pytest.fixture(scope="module")
def corridor() -> Venue:
    """A 48 m corridor whose doors repeat every 4 m: one distinctive end."""
    return Venue([(0.0, 0.0), (48.0, 0.0)])


def unique(x: float, y: float, h: float) -> list[tuple[float, float, float, float]]:
    """Every place looks like itself alone: the truth scores 0.8."""
    return [(x, y, h, 0.8)]


def periodic(x: float, y: float, h: float) -> list[tuple[float, float, float, float]]:
    """Near the west end (x < 3) the place is unique; beyond it, every 4 m looks the same."""
    if x < 3.0:
        return [(x, y, h, 0.8)]
    return [(x + 4.0 * k, y, h, 0.8) for k in range(-12, 13) if 3.0 <= x + 4.0 * k <= 48.0]


def test_motion_helps_in_a_repetitive_corridor(corridor: Venue) -> None:
    """Walking 3 m between updates (the phone's 2.5 s) past identical doors every 4 m from a
    distinctive end: without the step count, a slower walk to the door behind explains the clips
    as well, and the answer soon slips back a door; with the steps (noisy, as a phone counts them,
    this walker's stride 0.76 m where the filter assumes 0.7) it keeps the right door ~1.5 times as
    long. Nothing holds the phase of a truly periodic corridor for ever: its end will."""
    t, xy, hd = walk_poses([(0.5, 0.0), (47.0, 0.0)])
    walk_path = walk_path_for([(0.5, 0.0), (47.0, 0.0)], [1.2], FPS)
    imu = parse_imu(imu_for(walk_path, np.random.default_rng(5)))

    def right_until(motion) -> float:
        out = run_walk(corridor, t, xy, hd, periodic, every=2.5, motion=motion, per=1)
        return next((tt for tt, p, _, truth, _ in out if err(p, truth) > 2.0), np.inf)

    without, with_steps = right_until(None), right_until(imu.motion)
    assert with_steps >= 15.0
    assert with_steps >= 1.4 * without


def test_a_clip_is_cut_into_seconds_and_the_phones_motion_shared_among_them() -> None:
    t = np.arange(50) / FPS
    lengths = {n: [len(p) for p in parts(t[:n])] for n in (1, 10, 14, 15, 20, 25, 50)}
    assert lengths == {1: [1], 10: [10], 14: [14], 15: [7, 8], 20: [10, 10], 25: [8, 8, 9], 50: [10] * 5}
    cut = parts(t[:25])
    assert np.array_equal(np.concatenate(cut), np.arange(25))  # every frame once, in time order
    assert parts(np.array([3.0]))[0].tolist() == [0]
    # a gap in the frame times leaves no part of a frame or two (each part counts as a clip)
    gap = np.r_[0.0, 2.0 + np.arange(10) / FPS]
    assert [len(p) for p in parts(gap)] == [11]
    assert [len(p) for p in parts(np.r_[np.arange(10) / FPS, 5.0])] == [11]
    assert [len(p) for p in parts(np.repeat(np.arange(10) / FPS, 2))] == [20]  # a second, frames twice
    assert [len(p) for p in parts(np.r_[np.arange(19) / FPS, np.nan])] == [20]  # no time: one part
    moved = share(Motion(7, 30.0), [1.5, 1.0, 1.0])
    assert sum(m.steps for m in moved) == 7 and sum(m.turn_deg for m in moved) == pytest.approx(30.0)
    assert [m.steps for m in moved] == [3, 2, 2]
    assert share(Motion(None, None), [1.0, 1.0]) == [Motion(None, None)] * 2
    assert share(Motion(4, None), [0.0, 0.0]) == [Motion(2, None), Motion(2, None)]  # no time: evenly


def test_a_longer_clip_is_walked_second_by_second_so_its_first_second_counts(corridor: Venue) -> None:
    """A 2 s clip (the app films everything between two answers): its first second is at the
    corridor's distinctive end, its last second among doors that repeat every 4 m. Answered from
    its last second alone the filter cannot tell the door; walked second by second (update_clip)
    the first second places it and the walk keeps it there. The same as two updates a second apart
    with the motion shared, which is what it is."""
    t = np.arange(20) / FPS
    x = 1.5 + 1.2 * t
    rng = np.random.default_rng(3)

    def sources(i: int) -> list[tuple[float, float, float, float]]:
        if i < 10:  # the end of the corridor in view
            return [(x[i], 0.0, 90.0, 0.9)]
        return [(x[i] + 4.0 * k, 0.0, 90.0, 0.9) for k in range(-12, 13) if 0.0 <= x[i] + 4.0 * k <= 48.0]

    m = corridor.matches([sources(i) for i in range(20)], rng, per=1)
    truth = (x[-1], 0.0)
    _, last_only = corridor.tracker.update(None, m, t, float(t[-1]), None)
    asked: list[int] = []

    def answer(mp: Matches, tp: np.ndarray) -> ClipAnswer:
        asked.append(len(tp))
        return ClipAnswer(0.9)

    state, walked = corridor.tracker.update_clip(None, m, t, float(t[-1]), Motion(3, 0.0), answer)
    # (a fresh start is "not sure" either way after two seconds; what the belief holds differs)
    assert last_only.mass <= 0.3  # one door of a dozen alike
    assert walked.mass >= 0.5 and err(walked, truth) <= 1.5
    assert state.updates == 2 and asked == [10, 10] and walked.restarted
    # what it is: two updates a second apart (a belief that starts over takes no motion: the
    # phone's reading is of the walk before it)
    first, second = (Matches(*(getattr(m, f.name)[s] for f in fields(Matches))) for s in (slice(0, 10), slice(10, 20)))
    s1, _ = corridor.tracker.update(None, first, t[:10], float(t[9]), None, ClipAnswer(0.9))
    s2, p2 = corridor.tracker.update(s1, second, t[10:], float(t[-1]), None, ClipAnswer(0.9))
    assert np.array_equal(s2.belief, state.belief)
    assert (p2.x, p2.y, p2.confidence) == (walked.x, walked.y, walked.confidence) and not p2.restarted
    # going on from a state (0.5 s unseen, then 2 s filmed): the phone's motion since the state,
    # shared among the seconds by time
    later = t + 2.5
    _, on = corridor.tracker.update_clip(state, m, later, float(later[-1]), Motion(7, 30.0), answer)
    moves = share(Motion(7, 30.0), [float(later[9]) - state.t, float(later[-1] - later[9])])
    assert moves == [Motion(4, pytest.approx(18.0)), Motion(3, pytest.approx(12.0))]
    sa, _ = corridor.tracker.update(state, first, later[:10], float(later[9]), moves[0], ClipAnswer(0.9))
    sb, pb = corridor.tracker.update(sa, second, later[10:], float(later[-1]), moves[1], ClipAnswer(0.9))
    assert (pb.x, pb.y, pb.confidence) == (on.x, on.y, on.confidence) and not on.restarted
    # a phone's clock a little behind (the server allows a second): a part that ends by the
    # state's time joins the next, and the filter never goes back in time
    asked.clear()
    behind, _ = corridor.tracker.update_clip(state, m, t + 1.0, float(t[-1] + 1.0), Motion(2, 0.0), answer)
    assert asked == [20] and behind.updates == state.updates + 1 and behind.t == pytest.approx(t[-1] + 1.0)
    # a state too old to go on from: the belief starts over, and the phone's reading (of the walk
    # before it) is not shared among the clip's seconds as if walked in them
    seen: list[Motion | None] = []
    step = corridor.tracker._step
    try:
        corridor.tracker._step = lambda *a: seen.append(a[4]) or step(*a)  # type: ignore[method-assign]
        _, old = corridor.tracker.update_clip(state, m, t + 500.0, float(t[-1] + 500.0), Motion(400, 90.0), answer)
    finally:
        del corridor.tracker._step
    assert old.restarted and seen == [Motion(), Motion()]


def test_steps_that_miss_a_walk_cost_a_few_answers_at_most(corridor: Venue) -> None:
    """A phone that counts no steps while its user walks 3 m between updates (held steady, a slow
    walker, a wheelchair, a stalled sensor feed): the steps sharpen the walking model, never
    forbid a move, so clips that agree keep a confident right answer (a wrong count once left
    the moves the steps did not explain ~1e-8 and drove the answer to "not sure" for good)."""
    t, xy, hd = walk_poses([(0.5, 0.0), (47.0, 0.0)])

    out = run_walk(corridor, t, xy, hd, unique, every=2.5, motion=lambda t0, t1: Motion(0, 0.0), per=1)
    assert len(out) >= 15
    later = out[2:]  # a fresh start's first answers may be "not sure"
    assert all(err(p, truth) <= 2.0 for _, p, _, truth, _ in later)
    assert min(p.confidence for _, p, _, _, _ in later) >= 0.9
    # and a count that stops for a while: back to confident within a few answers of walking
    stalled = lambda t0, t1: Motion(0 if 10.0 < t1 < 25.0 else int(round((t1 - t0) * 1.2 / 0.7)), 0.0)  # noqa: E731
    out = run_walk(corridor, t, xy, hd, unique, every=2.5, motion=stalled, per=1)
    unsure = [tt for tt, p, _, truth, _ in out[2:] if p.confidence < 0.8 or err(p, truth) > 2.0]
    assert len(unsure) <= 2


DOORS_FROM = 6.0  # the corridor below: unique west of this, a door every 4 m from here on


def doors(x: float) -> list[float]:
    """Where the corridor looks as it does at x: x alone west of DOORS_FROM, else every 4 m."""
    if x < DOORS_FROM:
        return [x]
    return [x + 4.0 * k for k in range(-12, 13) if DOORS_FROM <= x + 4.0 * k <= 48.0]


def corridor_alikes(v: Venue, score: float) -> Matches:
    """What the venue's own index says of the corridor's nodes (lookalikes.look_alikes): each
    node's frame matches the same spot at every door with `score` (1: the same panorama)."""
    rows = node_frames(v.graph, v.xy, np.full(len(v.xy), "1"))
    idx = np.zeros((len(rows), K), np.int64)
    sc = np.zeros((len(rows), K), np.float32)
    for i, r in enumerate(rows):
        spots = doors(float(v.xy[r, 0]))
        near = [int(np.argmin(np.abs(v.xy[:, 0] - p))) for p in spots][:K]
        idx[i, : len(near)], sc[i, : len(near)] = near, score
        idx[i, len(near) :], sc[i, len(near) :] = r, 0.2  # (pad: itself, poorly)
    return Matches(idx, sc, sc, np.zeros((len(rows), K), np.float32))


def test_look_alikes_turn_a_steady_bias_into_not_sure_instead_of_a_wrong_door() -> None:
    """Past identical doors every 4 m, every clip prefers the door ahead a little (0.82 against
    0.80: the query's light, the same from one second to the next, not noise that averages out).
    Compounded clip after clip, that took the track a door ahead, and sure of it (>= 0.9). With
    the venue's own look-alikes (its model finds the doors the same), a clip no longer tells
    doors apart: where the walk cannot either (a standing walker and one who walked a door on
    look the same), the answer says "not sure", never a confident wrong door."""
    route = [(0.0, 0.0), (48.0, 0.0)]
    t, xy, hd = walk_poses([(0.5, 0.0), (40.0, 0.0)])

    def ahead(x: float, y: float, h: float) -> list[tuple[float, float, float, float]]:
        if x < DOORS_FROM:
            return [(x, y, h, 0.8)]
        return [(x, y, h, 0.8)] + [(x + 4.0, y, h, 0.82)] * int(x + 4.0 <= 48.0)

    def wrong(v: Venue) -> tuple[int, int]:
        """(answers further than 2 m, of them confident)"""
        out = [(p, truth) for _, p, _, truth, _ in run_walk(v, t, xy, hd, ahead)]
        bad = [p for p, truth in out if err(p, truth) > 2.0]
        return len(bad), sum(p.confidence >= 0.8 for p in bad)

    # (the clips' evidence untempered, so that the look-alikes alone are what differs)
    plain = Venue(route, {"track_alike_cost": None, "track_beta_ref": None})
    n_wrong, sure = wrong(plain)
    assert n_wrong >= 20 and sure >= 15  # a door ahead, and sure of it, for most of the walk

    v = Venue(route, {"track_alike_cost": 10.0, "track_beta_ref": None})
    v.tracker = Tracker(v.graph, v.xy, np.full(len(v.xy), "1"), v.conf, corridor_alikes(v, 1.0))
    n_wrong, sure = wrong(v)
    assert n_wrong >= 20 and sure == 0  # the same answers, but it says it is not sure of them
    # the answer is the main belief's, unchanged: only its confidence (and "not sure") differ
    a = run_walk(plain, t, xy, hd, ahead)
    b = run_walk(v, t, xy, hd, ahead)
    assert [(p.node, p.x, p.y, p.heading) for _, p, *_ in a] == [(p.node, p.x, p.y, p.heading) for _, p, *_ in b]
    assert all(q.confidence <= p.confidence + 1e-12 for (_, p, *_), (_, q, *_) in zip(a, b, strict=True))


def test_clips_that_match_poorly_are_not_stood_by_until_the_walk_agrees() -> None:
    """Clips that match every place poorly (best 0.5: another hour's daylight on glass, people,
    a tilt) and favour a spot 5 m ahead a little (0.53, the same second after second: the same
    conditions, not noise that averages out). Compounded, that made the track sure of the wrong
    spot. With track_beta_ref the second belief weighs such clips (1 - 0.85) / (1 - 0.5) as much:
    the answers are the same, but none is given as sure. Clips that match as poorly but point to
    one place are stood by after a few seconds; clips that match well are not touched."""
    route = [(0.0, 0.0), (48.0, 0.0)]
    t, xy, hd = walk_poses([(0.5, 0.0), (40.0, 0.0)])

    def biased(s: float):
        def ev(x: float, y: float, h: float) -> list[tuple[float, float, float, float]]:
            return [(x, y, h, s)] + [(x + 5.0, y, h, s + 0.03)] * int(x + 5.0 <= 48.0)

        return ev

    def walk(ref: float | None, evidence) -> list:
        return run_walk(Venue(route, {"track_alike_cost": None, "track_beta_ref": ref}), t, xy, hd, evidence)

    plain, tempered = walk(None, biased(0.5)), walk(0.85, biased(0.5))
    assert sum(err(p, truth) > 2.0 and p.confidence >= 0.8 for _, p, _, truth, _ in plain) >= 25
    assert all(err(p, truth) > 2.0 for _, p, _, truth, _ in tempered)  # the same wrong spot...
    assert max(p.confidence for _, p, *_ in tempered) < 0.8  # ...never given as sure
    answers = [[(p.node, p.x, p.y, p.heading) for _, p, *_ in out] for out in (plain, tempered)]
    assert answers[0] == answers[1]
    # a venue without look-alikes runs the second belief for this alone
    assert tempered[-1][1].alike_mass is not None and plain[-1][1].alike_mass is None

    def one_place(s: float):
        return lambda x, y, h: [(x, y, h, s)]

    poor = walk(0.85, one_place(0.5))
    assert all(err(p, truth) <= 2.0 for _, p, _, truth, _ in poor)
    first = next(tt for tt, p, *_ in poor if p.confidence >= 0.8)
    assert first <= 5.0 and sum(p.confidence >= 0.8 for _, p, *_ in poor) >= len(poor) - 4
    # clips that match well (best >= 0.85) count in full: the same bias is as sure as before
    good_plain, good = walk(None, biased(0.9)), walk(0.85, biased(0.9))
    assert [p.confidence for _, p, *_ in good] == pytest.approx([p.confidence for _, p, *_ in good_plain])


def test_the_second_beliefs_weight_of_a_clip_falls_with_its_best_score() -> None:
    """Tracker.beta: track_beta at or above track_beta_ref, times (1 - ref) / (1 - best) below."""
    v = Venue([(0.0, 0.0), (10.0, 0.0)], {"track_beta": 25.0, "track_beta_ref": 0.85})
    assert v.tracker.beta(0.95) == 25.0
    assert v.tracker.beta(0.85) == 25.0
    assert v.tracker.beta(0.55) == pytest.approx(25.0 * 0.15 / 0.45)
    assert v.tracker.beta(0.0) == pytest.approx(25.0 * 0.15)
    off = Venue([(0.0, 0.0), (10.0, 0.0)], {"track_beta_ref": None})
    assert off.tracker.beta(0.3) == off.conf["track_beta"]
    for bad in (1.0, 1.5, -0.1):  # at 1 or more the weight would be 0 or turn the evidence over
        with pytest.raises(OmninavError, match="track_beta_ref"):
            Venue([(0.0, 0.0), (10.0, 0.0)], {"track_beta_ref": bad})


def test_a_look_alike_never_falls_further_below_than_the_model_allows(corridor: Venue) -> None:
    """with_alikes: a node's log-likelihood is raised to its look-alike's less the pair's cost
    (track_alike_cost * (1 - score)), either way round; nearer than 3 m is the same place."""
    v = Venue([(0.0, 0.0), (48.0, 0.0)], {"track_alike_cost": 10.0})
    tr = Tracker(v.graph, v.xy, np.full(len(v.xy), "1"), v.conf, corridor_alikes(v, 0.9))
    a, b = v.graph.nearest(10.0, 0.0), v.graph.nearest(14.0, 0.0)
    ll = np.full(tr.n, -50.0)
    ll[a] = 0.0
    out = tr.with_alikes(ll)
    assert out[a] == 0.0
    assert out[b] == pytest.approx(-1.0)  # 10 * (1 - 0.9)
    assert out[v.graph.nearest(11.0, 0.0)] == -50.0  # a neighbour: not a look-alike
    assert out[v.graph.nearest(12.0, 0.0)] == -50.0  # between doors: nothing alike
    assert out[v.graph.nearest(2.0, 0.0)] == -50.0  # the distinctive end
    ll2 = np.full(tr.n, -50.0)
    ll2[b] = 0.0  # either way round
    assert tr.with_alikes(ll2)[a] == pytest.approx(-1.0)
    # off (None), or without the venue's look-alikes: unchanged
    assert np.array_equal(corridor.tracker.with_alikes(ll), ll)
    off = Tracker(v.graph, v.xy, np.full(len(v.xy), "1"), {**v.conf, "track_alike_cost": None}, corridor_alikes(v, 0.9))
    assert np.array_equal(off.with_alikes(ll), ll)


def test_standing_still_keeps_the_place(corridor: Venue) -> None:
    """Zero steps: most of the belief stays where it was (a stop is no reason to drift to a
    look-alike), yet a walk the steps missed keeps a share (the steps sharpen, never forbid)."""
    tr = corridor.tracker
    node = corridor.graph.nearest(20.0, 0.0)
    belief = np.zeros(tr.n)
    belief[node] = 1.0
    d_stay = np.hypot(tr.xy[:, 0] - 20.0, tr.xy[:, 1])
    for dt in (1.0, 2.5, 5.0):
        stay = tr._transition(belief, dt, steps=0)[0]
        walk = tr._transition(belief, dt)[0]
        assert stay[node] > 2.5 * walk[node]
        assert stay[d_stay <= 2.5].sum() > walk[d_stay <= 2.5].sum() + 0.1
        assert stay[d_stay > 2.5].sum() > 0.01 * dt  # never forbidden: clips can say otherwise
    assert stay[d_stay <= 2.5].sum() > 0.45
    assert walk[d_stay <= 13.0].sum() > 0.99  # 1.8 m/s at most (and a slack of a metre or two)


def test_the_node_the_last_clip_matched_best_is_saved_with_the_state(twin: Venue) -> None:
    x0, y0, _, _ = TWIN_RING
    t, xy, hd = walk_poses([(12.0, y0), (x0, y0)])
    state = run_walk(twin, t, xy, hd, twin_evidence(0.8, 0.8))[-1][-1]
    assert state.best is not None and float(np.hypot(*(twin.tracker.xy[state.best] - xy[-1]))) <= 1.5
    back = TrackState.from_bytes(state.to_bytes(), twin.graph)
    assert back is not None and back.best == state.best and back.recent == state.recent
    # saved before it existed: the same bytes less its section read with None
    old = TrackState.from_bytes(replace(state, best=None).to_bytes(), twin.graph)
    assert old is not None and old.best is None and old.alike is not None
    # a node the graph does not have, or the sections in another order: refused like any corrupt state
    body = replace(state, best=twin.tracker.n).to_bytes()[:-4]
    assert TrackState.from_bytes(body + struct.pack("<I", zlib.crc32(body)), twin.graph) is None
    both = replace(state, recent=0.3)
    assert both.best is not None
    bn, rc = b"BN" + struct.pack("<I", both.best), b"RC" + struct.pack("<d", 0.3)
    body = both.to_bytes()[:-4]
    assert body.endswith(rc + bn)
    swapped = body[: -len(rc + bn)] + bn + rc
    assert TrackState.from_bytes(swapped + struct.pack("<I", zlib.crc32(swapped)), twin.graph) is None


def test_when_the_phone_last_counted_a_step_is_kept_with_the_state(corridor: Venue) -> None:
    """`stepped`: set by an update whose phone counted steps, carried through counts of none,
    forgotten when the belief starts over; saved and read back, and a state saved before it
    existed (no section) reads with None; a time that is no number is refused as corrupt."""
    t, xy, hd = walk_poses([(0.5, 0.0), (12.0, 0.0)])

    counts = lambda t0, t1: Motion(2 if t1 < 6.0 else 0, 0.0)  # noqa: E731
    out = run_walk(corridor, t, xy, hd, unique, motion=counts, per=1)
    stepped = [s.stepped for *_, s in out]
    assert stepped[0] is None  # a fresh start: no reading yet
    last = max(tt for tt, *_ in out if tt < 6.0)
    assert all(v == pytest.approx(last) for (tt, *_), v in zip(out, stepped, strict=True) if tt >= last)
    state = out[-1][-1]
    back = TrackState.from_bytes(state.to_bytes(), corridor.graph)
    assert back is not None and back.stepped == pytest.approx(last) and back.best == state.best
    old = TrackState.from_bytes(replace(state, stepped=None).to_bytes(), corridor.graph)
    assert old is not None and old.stepped is None and old.best == state.best
    body = replace(state, stepped=float("nan")).to_bytes()[:-4]
    assert TrackState.from_bytes(body + struct.pack("<I", zlib.crc32(body)), corridor.graph) is None
    # one false step (a phone held steady) does not say the counter works; a walker's two do
    m = corridor.matches([[(12.0, 0.0, 90.0, 0.8)]] * 10, np.random.default_rng(8))
    times = state.t + 1 + np.arange(-0.9, 0.01, 0.1)
    one, _ = corridor.tracker.update(replace(state, stepped=None), m, times, float(times[-1]), Motion(1, 0.0))
    two, _ = corridor.tracker.update(replace(state, stepped=None), m, times, float(times[-1]), Motion(2, 0.0))
    assert one.stepped is None and two.stepped == pytest.approx(times[-1])
    # the belief starting over (the phone's clock gone back) forgets it; a clip whose request
    # counted steps sets it even then (update_clip: the parts get no motion of the walk before)
    back_in_time = state.t - 5.0 + np.arange(-0.9, 0.01, 0.1)
    fresh, _ = corridor.tracker.update(state, m, back_in_time, float(back_in_time[-1]), Motion(0, 0.0))
    assert fresh.updates == 1 and fresh.stepped is None
    fresh, _ = corridor.tracker.update_clip(state, m, back_in_time, float(back_in_time[-1]), Motion(3, 0.0))
    assert fresh.updates == 1 and fresh.stepped == pytest.approx(back_in_time[-1])


def test_a_counter_that_counted_a_moment_ago_keeps_its_zeros_then_not(corridor: Venue) -> None:
    """A phone counts steps for its first 5 s, then none while its user walks on (a stalled
    feed): for STEPS_WORK_S its zeros are stops, tracked exactly as with the zero rule off;
    after that they say nothing (the rule on tracks otherwise)."""
    t, xy, hd = walk_poses([(0.5, 0.0), (47.0, 0.0)], speed=1.0)

    stalls = lambda t0, t1: Motion(3 if t1 < 5.0 else 0, 0.0)  # noqa: E731

    def answers(zero: float | None) -> list[tuple[float, int, float]]:
        v = Venue([(0.0, 0.0), (48.0, 0.0)], {"track_zero_steps_m": zero})
        out = run_walk(v, t, xy, hd, unique, every=2.5, motion=stalls, per=1)
        return [(tt, p.node, round(p.confidence, 9)) for tt, p, *_ in out]

    on, off = answers(2.0), answers(None)
    last = max(tt for tt, *_ in on if tt < 5.0)
    within = [a for a in on if a[0] <= last + STEPS_WORK_S]
    assert within == off[: len(within)] and len(within) < len(on)
    assert on[len(within) :] != off[len(within) :]


def test_the_best_nodes_facing_is_saved_even_where_the_belief_there_is_too_small_to_keep(twin: Venue) -> None:
    """The next update compares its clip's facing at the last clip's best node with the one saved
    (track_still_seen): a node the belief has all but left keeps its facing in the saved state."""
    n = twin.tracker.n
    belief = np.zeros(n)
    belief[0] = 1.0
    facing = np.full(n, np.nan)
    far = n - 1
    facing[[0, far]] = (10.0, 123.0)
    state = TrackState(5.0, belief, twin.graph.key, 4, 10.0, facing, best=far)
    back = TrackState.from_bytes(state.to_bytes(), twin.graph)
    assert back is not None and back.best == far and back.facing is not None
    assert back.facing[far] == 123.0 and back.facing[0] == 10.0 and back.belief[0] == pytest.approx(1.0)
    # without a best node, only the belief's nodes keep theirs (as before)
    plain = TrackState.from_bytes(replace(state, best=None).to_bytes(), twin.graph)
    assert plain is not None and plain.facing is not None and np.isnan(plain.facing[far])


def held_still(conf: dict, motion: Motion | None, updates: int = 30) -> tuple[list[float], float]:
    """The same clip again and again, a second apart, from a fresh start: a phone held still
    where the venue was never filmed, its view a moderate match to x = 20 m of a corridor and a
    slightly worse one to x = 34 m. -> the answer's confidence after each update, and the
    clip's own (what it answers alone, as Locator.track gives it)."""
    v = Venue([(0.0, 0.0), (48.0, 0.0)], conf)
    m = v.matches([[(20.0, 0.0, 90.0, 0.62), (34.0, 0.0, 90.0, 0.58)]] * 10, np.random.default_rng(4), per=2)
    own = ClipAnswer.of(sequence(m, v.xy, np.arange(10) / FPS, v.conf), v.conf)
    state, out = None, []
    for u in range(updates):
        times = u + np.arange(-0.9, 0.01, 0.1)
        state, pose = v.tracker.update(state, m, times, float(times[-1]), motion if u else None, own)
        assert err(pose, (20.0, 0.0)) <= 2.0  # the better match, every time
        out.append(pose.confidence)
    return out, own.said  # what a locate without a session answers for it


def test_a_phone_held_still_is_no_surer_than_its_clip() -> None:
    """Its sensors say it has not moved (no step, no turn) and each clip is best where the last
    was: the clip is the view filmed again, and the answer no surer than that clip alone.
    With the rule off, as before, the repetition alone made it sure."""
    still, clip = held_still({}, Motion(0, 0.0))
    before, _ = held_still({"track_still_cap": False}, Motion(0, 0.0))
    assert clip < 0.8  # a moderate match: the clip alone is not sure
    assert max(before) >= 0.9
    assert all(c <= clip + 1e-9 for c in still[1:])
    # a turn is a move: the view changed, and the walk's evidence counts again
    turned, _ = held_still({}, Motion(0, 40.0))
    assert max(turned) >= 0.9


def test_without_sensors_the_clip_says_when_the_phone_is_held_still() -> None:
    """No sensors (or a phone that refused them): the clip best where the last was and facing
    as it did there is the view filmed again (track_still_seen), so the answer is no surer than
    the clip; without that rule nothing was known to be still, and the repetition made it sure.
    Sensors that say it moved (a step, a turn) overrule what the clip looks like."""
    unknown, clip = held_still({}, None)
    blind, _ = held_still({"track_still_seen": False}, None)
    assert clip < 0.8 and max(blind) >= 0.9
    assert all(c <= clip + 1e-9 for c in unknown[1:])
    # steps counted, no gyroscope: the sensors say it moved
    stepped, _ = held_still({}, Motion(2, None))
    assert max(stepped) >= 0.9
    # a step counter that says no step, no gyroscope: the clip's facing decides, as it faces alike here
    no_gyro, _ = held_still({}, Motion(0, None))
    assert all(c <= clip + 1e-9 for c in no_gyro[1:])


def test_without_sensors_a_clip_facing_another_way_is_not_held_still() -> None:
    """The same place, but each clip faces 40 degrees on from the last (the user turning where
    they stand, with no gyroscope to say so): not the view filmed again, and the walk's evidence
    counts as it did before the rule."""
    out = {}
    for seen in (True, False):
        v = Venue([(0.0, 0.0), (48.0, 0.0)], {"track_still_seen": seen})
        state, out[seen] = None, []
        for u in range(12):
            h = (90.0 + 40.0 * u) % 360.0
            m = v.matches([[(20.0, 0.0, h, 0.62), (34.0, 0.0, h, 0.58)]] * 10, np.random.default_rng(4), per=2)
            own = ClipAnswer.of(sequence(m, v.xy, np.arange(10) / FPS, v.conf), v.conf)
            times = u + np.arange(-0.9, 0.01, 0.1)
            state, pose = v.tracker.update(state, m, times, float(times[-1]), None, own)
            out[seen].append(pose.confidence)
    assert out[True] == out[False] and max(out[True]) >= 0.9


def test_a_phone_counting_no_steps_while_its_user_moves_is_not_held_still(corridor: Venue) -> None:
    """No step and no turn, yet each clip is best at another node than the last (a wheelchair,
    a step counter that has stalled): the clips are new views, and the answers are those of the
    filter without the rule."""
    t, xy, hd = walk_poses([(0.5, 0.0), (40.0, 0.0)])

    still = lambda t0, t1: Motion(0, 0.0)  # noqa: E731
    a = run_walk(corridor, t, xy, hd, unique, motion=still, per=1, own=True)
    loose = Venue([(0.0, 0.0), (48.0, 0.0)], {"track_still_cap": False})
    b = run_walk(loose, t, xy, hd, unique, motion=still, per=1, own=True)
    assert [(p.node, p.confidence) for _, p, _, _, _ in a] == [(p.node, p.confidence) for _, p, _, _, _ in b]
    assert all(err(p, truth) <= 2.0 for _, p, _, truth, _ in a[2:])
    # what keeps it out: each clip is best at another node than the last
    assert all(s1.best != s0.best for (*_, s0), (*_, s1) in zip(a[:-1], a[1:], strict=True))


def test_no_steps_counted_while_the_clips_move_on_is_read_as_no_count(corridor: Venue) -> None:
    """A phone held steady (or a wheelchair) counts no steps while its user walks 3 m between
    updates: each clip is best 2 m or more from where the last was, so with track_zero_steps_m
    the zero is read as no count at all, and the walk is tracked exactly as a phone without a
    step counter is. Off, the zero pulls the belief back towards standing still."""
    t, xy, hd = walk_poses([(0.5, 0.0), (47.0, 0.0)])

    def answers(conf: dict, steps: int | None) -> list[tuple[int, float]]:
        v = Venue([(0.0, 0.0), (48.0, 0.0)], conf)
        out = run_walk(v, t, xy, hd, unique, every=2.5, motion=lambda t0, t1: Motion(steps, 0.0), per=1)
        assert all(s1.best != s0.best for (*_, s0), (*_, s1) in zip(out[:-1], out[1:], strict=True))
        return [(p.node, round(p.confidence, 9)) for _, p, _, _, _ in out]

    uncounted = answers({"track_zero_steps_m": 2.0}, None)
    assert answers({"track_zero_steps_m": 2.0}, 0) == uncounted
    assert answers({"track_zero_steps_m": None}, 0) != uncounted


def test_no_steps_counted_where_the_clips_stay_put_or_say_nothing_still_count(corridor: Venue) -> None:
    """Standing still (the clip best where the last one was), or a blank clip (best nowhere),
    the count of no steps is kept with track_zero_steps_m as without it, and is not the same as
    no count at all."""
    t, xy, hd = walk_poses([(0.5, 0.0), (20.0, 0.0)])

    walked = run_walk(corridor, t, xy, hd, unique, per=1)[-1][-1]
    here = corridor.matches([[(20.0, 0.0, 90.0, 0.8)]] * 10, np.random.default_rng(7))
    blank = Matches(here.index, np.zeros_like(here.score), np.zeros_like(here.score), here.heading)

    def stay(conf: dict, steps: int | None, m: Matches) -> list[tuple[int, float, float]]:
        tr = Tracker(corridor.graph, corridor.xy, np.full(len(corridor.xy), "1"), {**corridor.conf, **conf})
        state, out = walked, []
        for k in range(1, 6):
            times = walked.t + k + np.arange(-0.9, 0.01, 0.1)
            state, p = tr.update(state, m, times, float(times[-1]), Motion(steps, 0.0))
            out.append((p.node, round(p.mass, 9), round(p.confidence, 9)))
        return out

    for m in (here, blank):
        kept = stay({"track_zero_steps_m": None}, 0, m)
        assert stay({"track_zero_steps_m": 2.0}, 0, m) == kept
        assert stay({"track_zero_steps_m": 2.0}, None, m) != kept


def test_the_heading_without_a_match_near_the_answer_is_the_gyroscopes_or_unsure(corridor: Venue) -> None:
    """A clip whose matches all lie far from where the belief is (one odd clip cannot move a
    settled track): the answer's heading is the last one plus the gyroscope's turn, or, without
    a gyroscope, unknown and the answer "not sure" (never a made-up 0°)."""
    tr = corridor.tracker
    belief = np.zeros(tr.n)
    belief[corridor.graph.nearest(20.0, 0.0)] = 1.0
    state = TrackState(10.0, belief, corridor.graph.key, 12, 90.0)
    far = np.argsort(np.hypot(corridor.xy[:, 0] - 44.0, corridor.xy[:, 1]))[:K]  # every candidate at 44 m
    sc = np.full((10, K), 0.8, np.float32)
    m = Matches(np.tile(far, (10, 1)), sc, sc, np.full((10, K), 270.0, np.float32))
    times = 11.0 + np.arange(-0.9, 0.01, 0.1)
    new, pose = tr.update(state, m, times, 11.0, Motion(1, 30.0))
    assert abs(pose.x - 20.0) <= 2.0 and pose.heading_known
    assert pose.heading == pytest.approx(120.0) and new.heading == pytest.approx(120.0)
    assert pose.confidence > 0.8
    new, pose = tr.update(state, m, times, 11.0, Motion(1, None))
    assert abs(pose.x - 20.0) <= 2.0 and not pose.heading_known
    assert pose.heading == pytest.approx(90.0)  # the last answer's stands in, flagged unknown
    assert pose.confidence <= 0.45 and new.heading is None
    # the next answer with a match there has a heading again
    m2 = corridor.matches([[(21.0, 0.0, 95.0, 0.8)]] * 10, np.random.default_rng(1))
    _, pose = tr.update(new, m2, times + 1.0, 12.0, Motion(1, None))
    assert pose.heading_known and abs(pose.heading - 95.0) < 5.0


def test_a_lift_takes_the_belief_to_the_other_floor() -> None:
    """Two floors, one corridor each, joined by a lift at their east end (walkgraph's `via`):
    walking to the lift on floor 1, then clips that only floor 2 explains, the answer follows to
    floor 2 within a few updates (and never leaves floor 1 before the lift)."""
    xy1, _ = frames_along([(0.0, 0.0), (20.0, 0.0)])
    xy2, _ = frames_along([(20.0, 0.0), (20.0, 15.0)])
    vxy = np.concatenate([xy1, xy2])
    vfl = np.array(["1"] * len(xy1) + ["2"] * len(xy2))
    lift = [{"name": "Lift", "kind": "lift", "floor": f, "x": 20.0, "y": 0.0} for f in ("1", "2")]
    g = build([(xy1, "1"), (xy2, "2")], lift)
    assert set(g.via.values()) == {"lift"}
    tr = Tracker(g, vxy, vfl, CONF)
    rng = np.random.default_rng(0)

    def clip(x: float, y: float, floor: str) -> Matches:
        rows = np.flatnonzero(vfl == floor)
        near = rows[np.argsort(np.hypot(vxy[rows, 0] - x, vxy[rows, 1] - y))[:4]]
        idx = np.concatenate([near, rng.integers(0, len(vxy), K - 4)])
        sc = np.concatenate([np.full(4, 0.8), rng.uniform(0.2, 0.4, K - 4)]).astype(np.float32)
        one = Matches(idx[None], sc[None], sc[None], np.full((1, K), 90.0, np.float32))
        return Matches(*(np.repeat(a, 10, axis=0) for a in (one.index, one.coarse, one.score, one.heading)))

    state, t = None, 0.0
    for x in np.arange(2.0, 20.1, 1.2):  # floor 1, east to the lift
        t += 1.0
        state, pose = tr.update(state, clip(x, 0.0, "1"), t + np.arange(-0.9, 0.01, 0.1), t)
        assert pose.floor == "1"
    for _ in range(3):  # in the lift: the clips say nothing (a blank wall everywhere alike)
        t += 10.0
        blank = Matches(rng.integers(0, len(vxy), (10, K)), *(np.full((3, 10, K), 0.3, np.float32)))
        state, pose = tr.update(state, blank, t + np.arange(-0.9, 0.01, 0.1), t)
    floors = []
    for y in np.arange(1.0, 8.0, 1.2):  # out on floor 2, south
        t += 1.0
        state, pose = tr.update(state, clip(20.0, y, "2"), t + np.arange(-0.9, 0.01, 0.1), t)
        floors.append(pose.floor)
    assert floors[2:] == ["2"] * (len(floors) - 2) and pose.confidence >= 0.8


def test_which_counts_of_no_steps_are_read_as_none() -> None:
    """track_zero_steps_m: a zero says nothing only when the clip is best that far from where
    the last one was, on the same floor; not a count of steps, not an unknown one, not a blank
    clip (best nowhere), not across a lift (its ride counts no steps, truly), and not off."""
    xy1, _ = frames_along([(0.0, 0.0), (20.0, 0.0)])
    xy2, _ = frames_along([(20.0, 0.0), (20.0, 15.0)])
    vxy = np.concatenate([xy1, xy2])
    vfl = np.array(["1"] * len(xy1) + ["2"] * len(xy2))
    lift = [{"name": "Lift", "kind": "lift", "floor": f, "x": 20.0, "y": 0.0} for f in ("1", "2")]
    g = build([(xy1, "1"), (xy2, "2")], lift)
    tr = Tracker(g, vxy, vfl, {**CONF, "track_zero_steps_m": 2.0})
    at = lambda x, y, f: int(g.snap(np.array([[x, y]]), np.array([f]))[0])  # noqa: E731
    here, on, near, up = at(10.0, 0.0, "1"), at(13.0, 0.0, "1"), at(11.0, 0.0, "1"), at(20.0, 1.0, "2")
    zero = Motion(0, 0.0)
    assert tr.zero_read_as_none(zero, here, on)  # 3 m on, no step: the count says nothing
    assert not tr.zero_read_as_none(zero, here, near)  # 1 m: a held phone's clip, a node on
    assert not tr.zero_read_as_none(zero, here, here)
    assert not tr.zero_read_as_none(Motion(4, 0.0), here, on) and not tr.zero_read_as_none(Motion(), here, on)
    assert not tr.zero_read_as_none(zero, here, None) and not tr.zero_read_as_none(zero, None, on)
    assert not tr.zero_read_as_none(zero, at(20.0, 0.0, "1"), up)  # out of the lift on floor 2
    off = Tracker(g, vxy, vfl, {**CONF, "track_zero_steps_m": None})
    assert not off.zero_read_as_none(zero, here, on)
    # a counter that counted a step within STEPS_WORK_S works: its zero is a stop, kept
    assert not tr.zero_read_as_none(zero, here, on, stepped=70.0, t_now=70.0 + STEPS_WORK_S)
    assert tr.zero_read_as_none(zero, here, on, stepped=70.0, t_now=71.0 + STEPS_WORK_S)
    # and a blank clip is best nowhere: what the update passes for it
    blank = Matches(np.zeros((10, K), np.int64), *(np.zeros((3, 10, K), np.float32)))
    state, _ = tr.update(None, blank, np.arange(0.1, 1.01, 0.1), 1.0)
    assert state.best is None


def test_imu_motion_between_two_moments_and_bad_files() -> None:
    imu = parse_imu({"steps": [0.5, 1.0, 1.6, 2.2], "yaw": {"t": [0.0, 1.0, 2.0], "deg": [0.0, 10.0, -80.0]}})
    m = imu.motion(1.0, 2.0)
    assert m.steps == 1 and m.turn_deg == pytest.approx(-90.0)  # steps in (1.0, 2.0]
    assert imu.motion(0.4, 2.2).steps == 4
    assert imu.motion(0.0, 0.5).turn_deg == pytest.approx(5.0)
    assert parse_imu({"steps": [1.0]}).motion(0.0, 2.0) == Motion(1, None)  # no gyroscope: turn unknown
    for bad in ([], {"steps": "x"}, {"steps": [2.0, 1.0]}, {"yaw": {"t": [0, 1], "deg": [0]}}, {"steps": [None]}):
        with pytest.raises(OmninavError):
            parse_imu(bad)


def test_a_tracking_confidence_model_that_cannot_be_evaluated_is_refused() -> None:
    with pytest.raises(OmninavError, match="luck"):
        resolve("default", {"track_confidence_features": ["mass", "luck"], "track_confidence_coef": [0, 1, 1]})
    with pytest.raises(OmninavError, match="3 weights"):
        resolve("default", {"track_confidence_features": ["mass", "far"], "track_confidence_coef": [0, 1]})
    # a venue modelled before tracking existed has none of the keys: today's defaults apply
    old = {k: v for k, v in CONF.items() if not k.startswith("track_")}
    v = Venue([(0.0, 0.0), (10.0, 0.0)], conf=None)
    tr = Tracker(v.graph, v.xy, np.full(len(v.xy), "1"), old)
    m = v.matches([[(5.0, 0.0, 90.0, 0.8)]], np.random.default_rng(0))
    assert 0.0 <= tr.update(None, m, np.array([0.0]), 0.0)[1].confidence <= 1.0


# ---- on the small rendered venue ---------------------------------------------------------------


@pytest.fixture(scope="module")
def walk_spec(modelled, small_ds: Dataset):
    from omninav.evaluate import query_spectra
    from omninav.walk_path import load_walk_path

    st, vid = modelled
    loc = Locator(st, vid, device="cpu")
    spec = query_spectra(loc, small_ds.query_video, load_walk_path(small_ds.query_walk_path), load_lens(small_ds.lens))
    return loc, spec


def test_locator_track_feeds_the_clip_estimate_and_the_filter(walk_spec, monkeypatch) -> None:
    from omninav.aggregate import confidence
    from omninav.evaluate import evaluate_track, track_summary

    loc, (spec, t, xy, hd, idx) = walk_spec
    w = slice(30, 40)
    fed: list[ClipAnswer | None] = []
    step = loc.tracker._step
    monkeypatch.setattr(loc.tracker, "_step", lambda *a: fed.append(a[5]) or step(*a))
    state, pose, est = loc.track(loc.tracker, spec[w], t[w], None, 100.0)
    monkeypatch.undo()
    same = loc.estimate(spec[w], t[w])
    assert (est.x, est.y, est.heading) == (same.x, same.y, same.heading)  # the clip's answer, unchanged
    # the filter is told what the clip answers alone, place and all (the rules of the clip's own
    # answer), its confidence by the rules' own model of the clip
    assert fed == [ClipAnswer.of(est, loc.conf)]
    assert (fed[0].x, fed[0].y, fed[0].row) == (est.x, est.y, est.venue_row) and 0 < fed[0].confidence < 1
    assert confidence(est, loc.conf) != fed[0].confidence  # not the single answer's (refit) model
    assert state.t == 100.0 and state.updates == 1 and state.graph_key == loc.graph.key
    assert 0.0 <= pose.confidence <= 1.0 and pose.floor == "1"
    # the venue's own look-alikes, from its index: pairs 3 m or more apart, at a cost in [0, 8]
    tr = loc.tracker
    assert len(tr.alike_a) > 0 and state.alike is not None
    assert (np.hypot(*(tr.xy[tr.alike_a] - tr.xy[tr.alike_b]).T) >= 3.0).all()
    assert (tr.alike_cost >= 0).all() and (tr.alike_cost <= 8.0).all()
    single, tracked = evaluate_track(loc, spec, t, xy, hd, idx)
    s1, s2 = track_summary(single), track_summary(tracked)
    assert s2["clips"] == s1["clips"] >= 15
    assert s2["within_2m"] >= max(0.9, s1["within_2m"] - 0.05)
    assert s2["confident_over_5m"] == 0


def test_a_walk_answered_every_few_seconds_reads_all_of_it(walk_spec) -> None:
    """`omninav track --every N` / `evaluate --track-mode` (track_walk): each answer reads the
    walk since the last one (the first, its first second; answers under a second apart, the last
    second each), so no frame of the walk is left out however far apart the answers."""
    from omninav.evaluate import track_walk

    loc, (spec, t, _, _, _) = walk_spec
    got = [(e, n) for e, _, _, n in track_walk(loc, spec, t, every=2.5)]
    assert len(got) >= 5 and got[0][1] == 10
    assert [n for _, n in got[1:]] == [b - a for (a, _), (b, _) in zip(got[:-1], got[1:], strict=True)]
    assert {n for _, n in got[1:]} == {25}
    assert {n for _, _, _, n in track_walk(loc, spec, t[:60], every=0.5)} == {10}


def test_locator_tracks_each_modelling_video_on_its_own_floor(modelled, walk_spec) -> None:
    """Locator.use_floors (what `omninav track` and `evaluate --track-mode` do with the
    catalogue's video floors): the walk graph and the venue frames keep each video's floor, and
    an answer names the floor of the place it gives (the modelling walk cut in two videos here,
    on floors 2 and 3)."""
    from omninav.evaluate import track_walk
    from omninav.walkgraph import from_frames

    st, vid = modelled
    _, (spec, t, _, _, _) = walk_spec
    loc = Locator(st, vid, device="cpu", floor="2")
    frames = np.array(loc.gen.frames)
    frames["video"] = (frames["t"] > np.median(frames["t"])).astype(frames["video"].dtype)
    loc.gen.frames, loc.gen.videos = frames, ["first", "second"]
    video_floor = ["2", "3"]
    loc.use_floors(video_floor, from_frames(frames, video_floor))
    assert set(loc.graph.floor.tolist()) == {"2", "3"}
    answers = [loc.track_answer(pose, "walk", float(t[e])) for e, pose, _, _ in track_walk(loc, spec, t)]
    assert {a["floor"] for a in answers} == {"2", "3"}
    for a in answers:  # the answer's frame is on the answer's floor
        row = int(np.flatnonzero(frames["frame"] == a["frame"])[0])
        assert video_floor[int(frames["video"][row])] == a["floor"]


@pytest.fixture(scope="module")
def cli_venue(small_ds: Dataset, tmp_path_factory: pytest.TempPathFactory) -> Path:
    data = tmp_path_factory.mktemp("track-cli")
    run_cli("venue", "create", "lab", "--floor", "2", data=data, check=True)
    cli_model(small_ds, "lab", data)
    return data


def test_cli_track_prints_one_answer_per_second(cli_venue: Path, small_ds: Dataset, tmp_path: Path) -> None:
    walk_path = json.loads(small_ds.query_walk_path.read_text())
    imu = tmp_path / "imu.json"
    imu.write_text(json.dumps(imu_for(walk_path, np.random.default_rng(0))))
    p = run_cli("track", "lab", str(small_ds.query_video), "--lens", str(small_ds.lens), data=cli_venue, check=True)
    lines = [json.loads(s) for s in p.stdout.splitlines()]
    duration = walk_path["waypoints"][-1]["t"]
    assert len(lines) == pytest.approx(duration, abs=1.5)
    assert [round(a["t"]) for a in lines[:3]] == [1, 2, 3]
    for a in lines:
        assert {"clip", "t", "x", "y", "heading_deg", "confidence", "floor", "place", "frame", "ambiguous"} <= set(a)
        assert a["floor"] == "2" and 0 <= a["confidence"] <= 1 and 0 <= a["heading_deg"] < 360
    tr = parse_walk_path(walk_path)
    truth, _, _ = tr.pose_at(np.array([a["t"] for a in lines]))
    e = np.hypot(*(np.array([[a["x"], a["y"]] for a in lines]) - truth).T)
    assert np.mean(e[5:] <= 2.0) >= 0.9
    p2 = run_cli(
        "track", "lab", str(small_ds.query_video), "--lens", str(small_ds.lens), "--every", "2.5", "--imu", str(imu),
        data=cli_venue, check=True,
    )  # fmt: skip
    assert len(p2.stdout.splitlines()) == pytest.approx(len(lines) / 2.5, abs=1.5)
    bad = run_cli("track", "lab", str(small_ds.query_video), "--imu", str(tmp_path / "nope.json"), data=cli_venue)
    assert bad.returncode == 2 and "imu file not found" in bad.stderr and "Traceback" not in bad.stderr


def test_cli_evaluate_track_mode(cli_venue: Path, small_ds: Dataset, tmp_path: Path) -> None:
    args = ["evaluate", "lab", str(small_ds.query_video), "--walk-path", str(small_ds.query_walk_path)]
    args += ["--lens", str(small_ds.lens), "--plot", str(tmp_path / "t.png"), "--track-mode"]
    out = json.loads(run_cli(*args, "--json", data=cli_venue, check=True).stdout)
    for key in ("single", "track"):
        s = out[key]
        assert s["clips"] >= 15 and {"within_1m", "within_2m", "median_heading_err_deg"} <= set(s)
        assert {"confident_over_5m", "confident_over_2m"} <= set(s)
    assert out["track"]["clips"] == out["single"]["clips"]
    assert out["track"]["within_2m"] >= 0.9 and out["track"]["confident_over_5m"] == 0
    table = run_cli(*args, "--every", "2", data=cli_venue, check=True).stdout
    assert "tracking (filter)" in table and "single clip" in table
    bad = run_cli("evaluate", *args[1:-1], "--every", "2", data=cli_venue)
    assert bad.returncode == 2 and "--track-mode" in bad.stderr


def test_an_answers_heading_is_below_360_however_it_rounds():
    from omninav.locate import answer_heading

    assert [answer_heading(h) for h in (359.996, 360.0, -0.001, 90.004, 720.5)] == [0.0, 0.0, 0.0, 90.0, 0.5]


def test_the_rules_read_the_clips_confidence_with_the_model_they_were_chosen_with() -> None:
    """The single answer's confidence model was refit (ring-bare among the tuning families); the
    rules of the clip's own answer keep reading the clip with the model their thresholds were
    chosen on (`track_clip_confidence_*`), and a venue modelled before the key reads the same."""
    from omninav.aggregate import Estimate, confidence

    conf = resolve("default")
    e = Estimate(1.0, 2.0, 90.0, 7, 0.62, 0.5, 0.8)  # support, rival, agree
    clip = ClipAnswer.of(e, conf)
    z = -6.68 + 10.731 * 0.62 + 10.215 * (0.62 - 0.5)
    assert clip.confidence == pytest.approx(1 / (1 + np.exp(-z)))
    assert clip.confidence != pytest.approx(confidence(e, conf))  # the single answer's own model differs
    assert (clip.x, clip.y, clip.row) == (1.0, 2.0, 7)
    older = {k: v for k, v in conf.items() if not k.startswith("track_clip_")}
    assert ClipAnswer.of(e, older).confidence == clip.confidence


@settings(max_examples=100, deadline=None)
@example(seed=916084442, k=8, frames=6, node=67)  # a hypothesis beyond FIT_M, supported from within it, wins
@given(seed=st.integers(0, 2**31 - 1), k=st.integers(1, 40), frames=st.integers(1, 12), node=st.integers(0, 200))
def test_the_fit_reads_only_the_matches_that_can_matter_and_answers_the_same(
    corridor: Venue, seed: int, k: int, frames: int, node: int
) -> None:
    """Tracker._fit drops the matches too far from the answer's node to support or be supported
    (_compact): on any matches, its answer is aggregate.sequence's on all of the clip's last second
    with those further than FIT_M set to 0, bit for bit (ties between equal scores included)."""
    rng = np.random.default_rng(seed)
    tr = corridor.tracker
    node %= tr.n
    # most matches within a few metres of the node: where the ones that can matter and the ones
    # that cannot meet
    around = np.flatnonzero(np.hypot(*(corridor.xy - tr.xy[node]).T) <= 6.0)
    idx = np.where(
        rng.random((frames, k)) < 0.8, rng.choice(around, (frames, k)), rng.integers(0, len(corridor.xy), (frames, k))
    )
    score = np.round(rng.uniform(-0.2, 1.0, (frames, k)), 1).astype(np.float32)  # ties, often
    head = rng.choice(np.float32([10.0, 100.0, 190.0, 280.0]), (frames, k))  # a few ways, so that some agree
    m = Matches(idx, score, score, head)
    times = 5.0 + np.arange(frames) / 10.0
    got = tr._fit(node, m, times, float(times[-1]), None)
    near = np.hypot(*(corridor.xy[idx] - tr.xy[node]).transpose(2, 0, 1)) <= FIT_M
    if not (near & (score > 0))[times > times[-1] - 1.0 - 1e-6].any():
        return  # (the node and no heading: not a fit)
    last = times > times[-1] - 1.0 - 1e-6  # (the fit reads the clip's last second)
    masked = Matches(idx[last], score[last], np.where(near, score, 0.0).astype(np.float32)[last], head[last])
    e = sequence(masked, corridor.xy, times[last], tr.conf)
    x, y = e.x, e.y
    nx, ny = tr.xy[node]
    dd = float(np.hypot(x - nx, y - ny))
    if dd > FIT_M:
        x, y = nx + (x - nx) * FIT_M / dd, ny + (y - ny) * FIT_M / dd
    assert got == (float(x), float(y), float(e.heading % 360.0), True)
