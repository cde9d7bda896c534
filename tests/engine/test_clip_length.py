"""Clips of any length in (0.3 s, 5 s] (issue 13): the sequence aggregation's reach and heading gate
follow the time between two frames, the engine answers from a clip's last 5 s, and the server takes
50-frame records and refuses a longer clip with a 413 that says why."""

from __future__ import annotations

import dataclasses
import io
import json
import shutil

import cv2
import numpy as np
import pytest

from omninav.aggregate import NEAR_M, WALK_MPS, gate_deg, reach_m, sequence
from omninav.errors import OmninavError
from omninav.heading import wrap_deg
from omninav.index import Matches
from omninav.lens import load_lens
from omninav.locate import MAX_CLIP_S, Locator, clip_groups
from omninav.presets import DEFAULTS, resolve
from omninav.server import create_app
from omninav.settings_upgrade import upgrade
from omninav.spectrum import encode_binary, encode_json
from omninav.synth.walks import QUERY, Pose, render_frames
from omninav.tracking_state import ClipAnswer
from server_helpers import TOKEN, Api, clip_spectra, heading_error, query_clip

CONF = resolve("default")
FPS = 10.0


# ---- the rule: as before within a second, growing with time beyond -----------------------------
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


# ---- the engine on the small venue ------------------------------------------------------------
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


def test_the_benches_keep_the_answers_of_each_search_apart(monkeypatch):
    """bench/venues.py caches a venue's answers under a name that says how its clips were
    searched: the answers of the search before the shortlist keep their names (and their figures),
    and the shortlist's are not read for them, nor they for it."""
    from bench.venues import SEARCH_KEYS, search_tag

    assert "shortlist" in SEARCH_KEYS  # a --set shortlist reaches the search, not a new venue
    conf = resolve("default")
    assert search_tag(conf) == "-shared-sl32"
    assert search_tag({**conf, "shortlist": 16}) == search_tag({**conf, "shortlist": 8}) == "-shared"
    assert search_tag(resolve("paper")) == ""


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
    # a part of the clip answers from the shared best alone, as a locate of those frames would
    assert seen["part"] == ClipAnswer.of(sequence(best.rows(slice(0, 5)), loc.xy, t[:5], loc.conf), loc.conf)


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


# ---- the server: 5 s of records, and no more -----------------------------------------------------
@pytest.fixture(scope="module")
def api(modelled, small_ds, tmp_path_factory) -> Api:
    st, _ = modelled
    data = tmp_path_factory.mktemp("cliplen") / "data"
    shutil.copytree(st.root, data)
    app = create_app({"DATA": str(data), "ADMIN_TOKEN": TOKEN, "JOB_RUNNER": False, "LOCATE_RATE": 0.0})
    cat = app.extensions["omninav"].catalog
    cat.venues.create("lab", "Lab")
    cat.floors.set_plan("lab", "1", small_ds.floorplan.read_bytes())
    cat.floors.put("lab", "1", {"px_per_m": 20.0})
    cat.lenses.put("lab", "donut", json.loads((small_ds.root / "model_lens.json").read_text()))
    return Api(app.test_client())


@pytest.fixture(scope="module")
def five_s(small_ds, loc) -> tuple[np.ndarray, tuple[float, float, float]]:
    frames, truth = query_clip(small_ds, 60, n=51)
    return clip_spectra(small_ds, frames, loc.conf), truth


def post(api: Api, body: bytes, query: str = "") -> dict:
    r = api.post(f"/api/venues/lab/locate{query}", data=body, content_type="application/octet-stream")
    return {"status": r.status_code, **r.json}


def test_the_server_answers_a_five_second_record(api, five_s, loc):
    spec, truth = five_s
    a = post(api, encode_binary(spec[1:], loc.conf))
    assert a["status"] == 200 and a["frames"] == 50, a
    assert np.hypot(a["x"] - truth[0], a["y"] - truth[1]) <= 2.0, (a, truth)
    r = api.post("/api/venues/lab/locate", json={**encode_json(spec[1:], loc.conf), "fps": 10})
    assert r.status_code == 200 and r.json["frames"] == 50


def test_a_longer_clip_is_refused_with_its_length(api, five_s, loc):
    spec, _ = five_s
    a = post(api, encode_binary(spec, loc.conf))
    assert a["status"] == 413 and "5.1 s long (51 frames at 10 frames/s)" in a["error"], a
    assert "at most 5 s" in a["error"]
    r = api.post("/api/venues/lab/locate", json={**encode_json(spec[1:], loc.conf), "fps": 8})
    assert r.status_code == 413 and "6.25 s long" in r.json["error"]
    # the same 51 frames filmed faster are 2.55 s: taken
    assert post(api, encode_binary(spec, loc.conf), "?fps=20")["status"] == 200


def test_frames_for_a_longer_clip_are_refused_before_any_is_decoded(api, small_ds):
    frames, _ = query_clip(small_ds, 60, n=1)
    png = cv2.imencode(".png", frames[0])[1].tobytes()
    files = [(io.BytesIO(png[:64] + b"\0" * 10), f"f{i}.png") for i in range(51)]  # cut short: never decoded
    r = api.post("/api/venues/lab/locate?lens=donut", data={"frame": files}, content_type="multipart/form-data")
    assert r.status_code == 413 and "51 frames" in r.json["error"], r.json


def test_a_video_is_timed_by_itself_not_by_the_fps_argument(api, small_ds, tmp_path):
    """A 3 s video sent with a wrong ?fps=5: its own 10 fps times its frames (at 5 fps it would
    be a 6 s clip, refused)."""
    from omninav.synth.walks import write_video

    frames, truth = query_clip(small_ds, 60, n=30)
    path = tmp_path / "clip.mp4"
    write_video(path, frames, 10.0, (frames[0].shape[1], frames[0].shape[0]))
    r = api.post("/api/venues/lab/locate?lens=donut&fps=5", data=path.read_bytes(), content_type="video/mp4")
    assert r.status_code == 200 and r.json["frames"] == 30, r.json
    assert np.hypot(r.json["x"] - truth[0], r.json["y"] - truth[1]) <= 2.0


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
