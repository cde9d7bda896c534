"""aggregate.py: the sequence aggregation's reach and heading gate follow the time between two
frames (as before within a second, growing at a walking pace and a slow turn beyond), and a clip
of a second is answered exactly as before clips could be longer."""

from __future__ import annotations

import numpy as np
import pytest

from omninav.aggregate import NEAR_M, WALK_MPS, gate_deg, reach_m, sequence
from omninav.heading import wrap_deg
from omninav.index import Matches
from omninav.presets import resolve

CONF = resolve("default")
FPS = 10.0


def test_within_a_second_reach_and_gate_are_what_they_were():
    dt = np.linspace(0.0, 1.0, 41)
    old_reach = np.minimum(NEAR_M + WALK_MPS * dt, CONF["clip_radius_m"] + NEAR_M)
    np.testing.assert_allclose(reach_m(dt, CONF), old_reach, rtol=1e-6)
    np.testing.assert_allclose(gate_deg(dt, CONF), CONF["heading_gate_deg"])


def test_beyond_a_second_they_grow_with_time_at_a_walking_pace_and_a_slow_turn():
    dt = np.array([1.0, 2.0, 3.0, 5.0])
    reach = reach_m(dt, CONF) - NEAR_M
    assert np.all(np.diff(reach) > 0)
    assert np.all(reach <= WALK_MPS * dt)  # never faster than the fastest walk
    assert reach[-1] >= 1.2 * 5  # a steady walk of 5 s (1.2 m/s) stays in reach
    gate = gate_deg(dt, CONF)
    assert np.all(np.diff(gate) >= 0) and gate[-1] <= 180.0
    assert gate[2] >= 25.0 * 3  # turning at 25 deg/s for 3 s stays within the gate


# ---- sequence on hand-made matches: a corridor and a look-alike one ----------------------------
VENUE = np.concatenate([np.stack([np.arange(700) * 0.1, np.full(700, 3.0)], -1)] * 2)
VENUE[700:, 1] = 23.0  # the second corridor, 20 m away, looks the same


def clip_matches(x: np.ndarray, heading: np.ndarray, seed: int = 0) -> Matches:
    """Per frame: the true venue frame (score 0.6) and a look-alike elsewhere that scores higher
    (0.7) but lands somewhere different every frame, as a repetitive corridor's matches do."""
    rng = np.random.default_rng(seed)
    q = len(x)
    true = np.clip(np.round(x / 0.1).astype(int), 0, 699)
    decoy = 700 + rng.integers(0, 700, q)
    index = np.stack([true, decoy], -1)
    score = np.tile(np.array([0.6, 0.7], np.float32), (q, 1))
    hd = np.stack([heading, rng.uniform(0, 360, q)], -1).astype(np.float32)
    return Matches(index, score, score, hd)


def test_a_five_second_walk_is_supported_by_every_frame():
    t = np.arange(50) / FPS
    x = 20.0 + 1.2 * t
    e = sequence(clip_matches(x, np.full(50, 90.0)), VENUE, t, CONF)
    assert e.agree == pytest.approx(1.0)  # capped at 1.95 m, only the last ~1.3 s used to count
    assert abs(e.x - x[-1]) <= 0.3 and abs(e.y - 3.0) <= 0.1
    assert e.support > e.rival


def test_turning_slowly_for_five_seconds_is_supported_by_every_frame():
    t = np.arange(50) / FPS
    heading = (200.0 + 25.0 * t) % 360.0  # 122 deg in all: a fixed 35 deg gate split it in three
    e = sequence(clip_matches(np.full(50, 30.0), heading, seed=1), VENUE, t, CONF)
    assert e.agree == pytest.approx(1.0)
    assert abs(e.x - 30.0) <= 0.3
    assert abs(wrap_deg(e.heading - heading[-1])) <= 2.0


def test_frames_too_far_apart_for_the_time_between_them_do_not_support_each_other():
    t = np.arange(50) / FPS
    x = np.where(t < 2.5, 10.0, 60.0)  # 50 m in a tenth of a second
    e = sequence(clip_matches(x, np.full(50, 90.0)), VENUE, t, CONF)
    assert e.agree <= 0.55
    assert abs(e.x - 60.0) <= 0.3  # the later half wins the tie: the answer is where the clip ends


# What `sequence` answered for these 1 s clips before clips could be longer (computed with the
# aggregate.py of commit dca0edd): a clip of a second must be answered exactly as it was.
BEFORE_LONG_CLIPS = {
    1: (-4.144501584290717, -0.5502131584169601, 183.54169488562786, 331, 0.601956307888031, 0.43522825837135315, 0.8),
    2: (-0.23848194124883504, -4.700070405846014, 38.31688678168084, 355, 0.6165151596069336, 0.43530434370040894, 0.9),
    3: (0.34924424615674354, 1.152199328615451, 20.09594328014245, 135, 0.5281327962875366, 0.41243138909339905, 0.7),
}


@pytest.mark.parametrize("seed", sorted(BEFORE_LONG_CLIPS))
def test_a_one_second_clip_is_answered_exactly_as_before(seed):
    from omninav.aggregate import sequence
    from omninav.index import Matches
    from omninav.presets import resolve

    rng = np.random.default_rng(seed)
    q, k, n = 10, 16, 400
    xy = np.cumsum(rng.normal(0, 0.15, (n, 2)), axis=0)
    idx = rng.integers(0, n, (q, k))
    m = Matches(
        idx,
        rng.random((q, k)).astype(np.float32),
        (rng.random((q, k)) * 1.2 - 0.2).astype(np.float32),
        (rng.random((q, k)) * 360).astype(np.float32),
    )
    e = sequence(m, xy, np.arange(q) / 10.0, resolve("default"))
    assert (e.x, e.y, e.heading, e.venue_row, e.support, e.rival, e.agree) == BEFORE_LONG_CLIPS[seed]
