"""locate.py on the small venue: a clip of up to 5 s answered from its last 5 s, its seconds
searched with shared candidates, a tracked clip giving the tracker both, standing and turning."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from omninav.aggregate import sequence
from omninav.errors import OmninavError
from omninav.lens import load_lens
from omninav.locate import MAX_CLIP_S, Locator, clip_groups
from omninav.presets import DEFAULTS
from omninav.settings_upgrade import upgrade
from omninav.synth.walks import QUERY, Pose, render_frames
from omninav.tracking_state import ClipAnswer
from server_helpers import clip_spectra, heading_error, query_clip

FPS = 10.0


@pytest.fixture(scope="module")
def loc(modelled) -> Locator:
    st, vid = modelled
    return Locator(st, vid, device="cpu")


def test_a_five_second_walking_clip_is_located_and_a_longer_one_by_its_last_five_seconds(loc, small_ds):
    frames, truth = query_clip(small_ds, 60, n=60)
    spec = clip_spectra(small_ds, frames, loc.conf)
    ans = loc.locate_spectra(spec, "long")
    assert np.hypot(ans["x"] - truth[0], ans["y"] - truth[1]) <= 2.0, (ans, truth)
    assert heading_error(ans["heading_deg"], truth[2]) <= 5.0
    a, b = loc.estimate(spec), loc.estimate(spec[-int(MAX_CLIP_S * FPS) :])  # 60 frames: the last 50
    assert (a.x, a.y, a.heading, a.venue_row) == pytest.approx((b.x, b.y, b.heading, b.venue_row), abs=1e-6)
    short = loc.estimate(spec[-3:])  # 0.3 s: three frames still answer
    assert np.isfinite([short.x, short.y, short.heading]).all()


def test_clip_groups_are_the_seconds_counted_back_from_the_last_frame():
    assert clip_groups(np.arange(10) / FPS).tolist() == [0] * 10  # a 1 s clip: one group
    assert clip_groups(np.arange(25) / FPS).tolist() == [2] * 5 + [1] * 10 + [0] * 10
    assert clip_groups(np.array([3.0])).tolist() == [0]
    # a time that is no number, or one after the last, goes with the last second (no error)
    assert clip_groups(np.array([0.0, np.nan, 0.3, 0.2])).tolist() == [0, 0, 0, 0]


def test_each_second_of_a_clip_shares_its_candidates(loc, small_ds):
    """A locate searches its clip second by second, every frame of a second verified against the
    shortlists of all of them (`shortlist` a frame, by stage 1), each keeping its `candidates`
    best; with `shared_candidates` off, each frame keeps its own."""
    frames, _ = query_clip(small_ds, 60, n=25)
    spec = clip_spectra(small_ds, frames, loc.conf)
    t = np.arange(25) / FPS
    k = loc.conf["candidates"]
    assert loc.conf["shortlist"] > k
    own = loc.index.search(spec, k)
    listed, _ = loc.index.shortlisted(spec, k, loc.conf["shortlist"])
    m, times = loc.search_clip(spec, t)
    assert m.index.shape == (25, k) and np.array_equal(times, t)
    groups = clip_groups(t)
    gained = 0
    for g in np.unique(groups):
        rows = np.flatnonzero(groups == g)
        union = set(listed[rows].ravel().tolist())
        for i in rows:
            assert set(m.index[i].tolist()) <= union  # only the second's own shortlists, no other's
            assert m.score[i, 0] >= own.score[i].max() - 1e-5  # never worse than its own best
            gained += len(set(m.index[i].tolist()) - set(own.index[i].tolist()))
    assert gained > 0  # some frame kept a place only another frame of its second had found
    # the tracker's evidence: the shared best, then each frame's own candidates as verified
    best, evidence, _ = loc.clip_matches(spec, t)
    assert np.array_equal(best.index, m.index) and evidence.index.shape == (25, 2 * k)
    assert np.array_equal(evidence.index[:, :k], m.index) and np.array_equal(evidence.index[:, k:], own.index)
    assert np.allclose(evidence.score[:, k:], own.score, atol=1e-5)
    loc.change_settings({"shared_candidates": False})  # (the fixture's Locator: set back below)
    plain, _ = loc.search_clip(spec, t)
    assert np.array_equal(plain.index, own.index) and np.array_equal(plain.score, own.score)
    assert loc.clip_matches(spec, t)[1].index.shape == (25, k)  # without sharing: the frame's own
    loc.change_settings({"shared_candidates": True})
    # a venue modelled before the shortlist (no key) searches with the default's; a shortlist of
    # `candidates` is the search before it
    stored = {key: v for key, v in loc.conf.items() if key not in ("shortlist", "version")}
    assert upgrade(stored)["shortlist"] == loc.search.shortlist == DEFAULTS["shortlist"]
    loc.change_settings({"shortlist": k})
    before, _ = loc.search_clip(spec, t)
    loc.change_settings({"shortlist": DEFAULTS["shortlist"]})
    # what the frames were made with cannot change under them; a bad value is refused whole
    with pytest.raises(OmninavError, match="bands"):
        loc.change_settings({"bands": [[-10.0, 10.0]]})
    with pytest.raises(OmninavError, match="shortlist"):
        loc.change_settings({"shortlist": 0})
    assert loc.search.shortlist == DEFAULTS["shortlist"]
    for i in range(25):
        assert set(before.index[i].tolist()) <= set(own.index[groups == groups[i]].ravel().tolist())
    assert np.all(m.score[:, 0] >= before.score[:, 0] - 1e-5)
    assert not np.array_equal(m.index, before.index)  # the venue's shortlist is the one searched


def test_a_tracked_clip_gives_the_tracker_both_and_each_part_answers_from_the_shared_best(loc, small_ds, monkeypatch):
    frames, _ = query_clip(small_ds, 60, n=25)
    spec = clip_spectra(small_ds, frames, loc.conf)
    t = np.arange(25) / FPS
    k = loc.conf["candidates"]
    tracker, seen = loc.tracker, {}
    update_clip = tracker.update_clip

    def spy(state, m, times, t_now, motion, answer=None):
        seen["width"], seen["part"] = m.index.shape[1], answer(m.rows(slice(0, 5)), times[:5])
        return update_clip(state, m, times, t_now, motion, answer)

    monkeypatch.setattr(tracker, "update_clip", spy)
    _, _, e = loc.track(tracker, spec, t, None)
    best, _ = loc.search_clip(spec, t)
    assert seen["width"] == 2 * k  # the shared best and the frames' own candidates
    assert e == sequence(best, loc.xy, t, loc.conf)  # the clip's own answer: the shared best's
    # a part of the clip answers from the shared best alone, as a locate of those frames would (to
    # the float's rounding: the tracker hands its part on as a view of a wider array, whose sums
    # NumPy may add in another order)
    want = ClipAnswer.of(sequence(best.rows(slice(0, 5)), loc.xy, t[:5], loc.conf), loc.conf)
    assert seen["part"].row == want.row
    assert dataclasses.astuple(seen["part"]) == pytest.approx(dataclasses.astuple(want), rel=1e-12, abs=1e-12)


def test_standing_and_turning_slowly_for_three_seconds(loc, small_ds):
    """The app's "keep turning slowly": the user stands and turns at 20 deg/s while it films 3 s."""
    x, y, h0 = 6.0, 2.2, 40.0  # on the first corridor of the small layout
    poses = [Pose(i / FPS, x, y, (h0 + 20.0 * i / FPS) % 360.0, 1.3, 2.0, 30.0) for i in range(30)]
    look = dataclasses.replace(QUERY, people=0)
    frames = [f for _, f in render_frames(small_ds.scene, load_lens(small_ds.lens), poses, look, seed=5)]
    e = loc.estimate(clip_spectra(small_ds, frames, loc.conf))
    assert np.hypot(e.x - x, e.y - y) <= 1.0, e
    assert heading_error(e.heading, poses[-1].heading) <= 3.0, e
    assert e.agree >= 0.9  # every frame supports the answer, the first ones 60 deg round from the last
