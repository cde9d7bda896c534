"""Verification by local features (verify.py): the geometry, the stored features as a venue's
videos come and go, and a clip whose global answer is wrong moved to where it was filmed."""

from __future__ import annotations

import dataclasses

import cv2
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from omninav.errors import OmninavError
from omninav.index import Matches
from omninav.lens import load_lens
from omninav.locate import Locator, read_record
from omninav.model_venue import model_video, remove_video
from omninav.presets import resolve
from omninav.settings_upgrade import upgrade
from omninav.spectrum import decode_binary_local, encode_binary
from omninav.store import Store
from omninav.verify import (
    LOCAL_DTYPE,
    MIN_INLIERS,
    MOVED_CONFIDENCE,
    PLACE_M,
    PLACES,
    RATIO,
    SPACING_M,
    VOTE_HAMMING,
    VOTE_K,
    LocalFeatures,
    candidate_rows,
    detect,
    essential_fit,
    one_place,
    place_index,
    place_of_rows,
    place_votes,
    ratio_matches,
    turn_deg,
    verify,
)
from omninav.walk_path import load_walk_path
from server_helpers import clip_spectra, far_and_truth, heading_error, query_clip


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.linalg.norm(v, axis=1, keepdims=True)


def _rot_z(deg: float) -> np.ndarray:
    c, s = np.cos(np.radians(deg)), np.sin(np.radians(deg))
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def test_bearings_of_one_scene_from_two_places_are_inliers_and_shuffled_ones_are_not():
    rng = np.random.default_rng(1)
    pts = rng.uniform(-8, 8, (200, 3)) * [1, 1, 0.3]  # a room's points around both cameras
    pts = pts[np.linalg.norm(pts[:, :2], axis=1) > 1.5]
    r, t = _rot_z(37.0), np.array([0.8, -0.5, 0.0])  # camera 2: turned 37 degrees, 0.94 m away
    b1 = _unit(pts)
    b2 = _unit((pts - t) @ r)  # the same points in camera 2's frame
    n = len(b1)
    assert essential_fit(b1, b2)[0].sum() >= 0.95 * n
    wrong = b2[rng.permutation(n)]
    assert essential_fit(b1, wrong)[0].sum() < 0.2 * n
    assert essential_fit(b1[:7], b2[:7])[0].sum() == 0  # fewer than the 8-point algorithm needs
    assert np.array_equal(essential_fit(b1, b2, seed=3)[0], essential_fit(b1, b2, seed=3)[0])


@settings(max_examples=60, deadline=None)
@given(
    n=st.integers(8, 400),
    outliers=st.floats(0.0, 0.9),
    turn=st.floats(-180.0, 180.0),
    noise=st.sampled_from([0.0, 0.002, 0.01]),
    seed=st.integers(0, 2**31),
)
def test_the_compiled_samples_give_the_matrices_and_inliers_of_lapacks_arithmetic(n, outliers, turn, noise, seed):
    """essential.sample_counts: for every sample of 8 distinct pairs, the essential matrix of
    verify._essential (QR's null vector, then two equal singular values by SVD: NumPy's LAPACK),
    to 1e-9 and up to its sign, and the same inliers (a pair within INLIER_DEG of its plane)."""
    import omninav.verify as vf
    from omninav.essential import sample_counts

    rng = np.random.default_rng(seed)
    pts = rng.uniform(-8, 8, (n, 3)) * [1, 1, 0.3] + [0.0, 0.0, 0.2]
    b1 = _unit(pts)
    b2 = _unit((pts - [0.7, 0.4, 0.05]) @ _rot_z(turn) + rng.normal(0.0, noise, (n, 3)))
    bad = rng.random(n) < outliers
    b2[bad] = _unit(rng.normal(size=(int(bad.sum()), 3)))
    a = np.einsum("ni,nj->nij", b2, b1).reshape(n, 9)
    picks = np.array([rng.choice(n, 8, replace=False) for _ in range(40)])
    counts, es = sample_counts(a, b1, b2, picks, vf.INLIER_DEG)
    for bad in (picks[:, :7], picks + n, picks - n):  # (the compiled loops check no index)
        with pytest.raises(ValueError):
            sample_counts(a, b1, b2, bad, vf.INLIER_DEG)
    want = vf._essential(a[picks])
    sign = np.sign(np.einsum("sij,sij->s", es, want))[:, None, None]
    assert np.abs(es * sign - want).max() < 1e-9
    # a pair within 1e-9 of the threshold could fall either side; none does here
    assert np.array_equal(counts, vf._inliers(want, b1, b2).sum(axis=1))


def test_a_matrix_of_rank_under_two_leaves_no_essential_matrix():
    from omninav.essential import _two_equal

    out = np.ones((3, 3))
    assert not _two_equal(np.diag([1.0, 0.0, 0.0]), np.zeros((3, 3)), np.zeros((3, 3)), out)
    assert not out.any()  # (zero: it explains no pair)
    assert not _two_equal(np.zeros((3, 3)), np.zeros((3, 3)), np.zeros((3, 3)), out) and not out.any()
    e = np.diag([2.0, 1.0, 0.0])
    assert _two_equal(e, np.zeros((3, 3)), np.zeros((3, 3)), out) and np.allclose(out, np.diag([1.0, 1.0, 0.0]))


@settings(max_examples=100, deadline=None)
@given(q=st.integers(0, 200), v=st.integers(0, 120), bits=st.integers(0, 40), seed=st.integers(0, 2**31))
def test_a_screened_place_counted_in_full_has_the_matches_of_one_scan(q, v, bits, seed):
    """A place that passes the screen is scanned for its other query keypoints only; merged with
    the screen's, its matches are one scan's, in the same order (descriptors near copies of
    each other up to `bits` flipped, so that some pass the ratio test and some tie)."""
    import omninav.verify as vf

    rng = np.random.default_rng(seed)
    vd = rng.integers(0, 256, (v, 32), dtype=np.uint8)
    qd = rng.integers(0, 256, (q, 32), dtype=np.uint8)
    if v:
        near = rng.random(q) < 0.5
        qd[near] = vd[rng.integers(0, v, int(near.sum()))]
        flip = rng.integers(0, 256, (q, bits), dtype=np.uint8) if bits else np.zeros((q, 0), np.uint8)
        for j in range(flip.shape[1]):
            qd[near, j % 32] ^= flip[near, j]
    third = ratio_matches(qd[:: vf.SCREEN], vd)
    assert np.array_equal(vf._with_the_rest(third, qd, vd), ratio_matches(qd, vd))


def _places(*spec: tuple[int, int, int]) -> LocalFeatures:
    out = LocalFeatures.empty()
    for video, frame, n in spec:
        out = out + one_place(video, frame, np.full((n, 3), frame, np.float32), np.full((n, 32), frame, np.uint8))
    return out


def test_local_features_keep_their_places_slices_when_places_go():
    lf = _places((0, 3, 2), (0, 9, 4), (1, 5, 3))
    b, d = lf.of(1)
    assert len(b) == 4 and (d == 9).all()
    kept = lf.keep(lf.places["video"] != 0)
    assert list(kept.places["start"]) == [0] and len(kept.bearings) == 3
    assert (kept.of(0)[1] == 5).all()
    assert len(lf.keep(np.zeros(3, bool)).places) == 0


def test_places_that_cannot_change_the_verdict_are_not_fitted_and_the_verdict_is_the_same(monkeypatch):
    """verify() fits a place only where its ratio-test matches could clear the bar (inliers never
    exceed matches): on 3,000 random candidate lists (matches, inliers at most the matches, places
    without local features, margins from 1 to huge), its verdict is that of fitting every place,
    and it fits fewer."""
    import omninav.verify as vf

    local = _places(*[(0, p, 1) for p in range(vf.PLACES)])
    rng = np.random.default_rng(7)
    state: dict = {}
    monkeypatch.setattr(vf, "candidate_rows", lambda *a, **k: state["rows"])

    def ratio(qd, vd):  # the place's matches, query keypoint j % 8 the j-th's, of those asked (the screen asks a third)
        asked = list(qd[:, 1])
        js = [j for j in range(state["matches"][int(vd[0, 0])]) if j % 8 in asked]
        return np.array([[asked.index(j % 8), 0] for j in js], np.int64).reshape(-1, 2)

    monkeypatch.setattr(vf, "ratio_matches", ratio)

    def fit(b1, b2):  # the stand-in inliers of the place whose matches these are (none under 8 pairs)
        state["fits"] += 1
        return np.arange(len(b1)) < (int(state["inliers"][len(b1)]) if len(b1) >= 8 else 0), None

    monkeypatch.setattr(vf, "essential_fit", fit)
    query = (np.zeros((8, 3), np.float32), np.zeros((8, 32), np.uint8))
    query[1][:, 1] = np.arange(8)  # (each keypoint's number, for the stand-in matches)
    fewer = 0
    for _ in range(3000):
        k = int(rng.integers(1, vf.PLACES + 1))
        # each place a distinct match count, so that a count names its place's inliers
        matches = rng.permutation(np.arange(0, 160))[: vf.PLACES]  # (the first's inliers across SETTLED_INLIERS)
        inliers = {int(n): int(rng.integers(0, n + 1)) for n in matches}
        margin = float(rng.choice([1.0, 1.5, 2.0, 3.7, 1e308]))
        place_of = np.where(rng.random(vf.PLACES) < 0.1, -1, np.arange(vf.PLACES))
        state.update(rows=list(range(k)), matches=matches, inliers=inliers, fits=0)
        got = verify(query, None, None, local, place_of, 0, margin)
        # every place fitted, by the rule as it reads
        inl = [
            0 if place_of[i] < 0 or matches[i] < (8 if i == 0 else MIN_INLIERS) else inliers[int(matches[i])]
            for i in range(k)
        ]
        best = int(np.argmax(inl))
        moves = inl[best] >= MIN_INLIERS and inl[best] > inl[0] and inl[best] >= margin * inl[0]
        if inl[0] >= vf.SETTLED_INLIERS:  # the answer's place settles it: nothing else is asked
            assert got.moved_to is None and got.rows == [0] and state["fits"] == 1
            continue
        assert got.moved_to == (best if moves else None)
        fewer += state["fits"] < sum(1 for i in range(k) if place_of[i] >= 0 and matches[i] >= 8)
    assert fewer > 300


def _corridor(seen: dict[int, np.ndarray], n: int = 10, seed: int = 3):
    """A corridor of `n` places a metre apart along x (row i: video 0, frame i, at (i, 0)), each
    seeing its own random scene points, except where `seen` gives the indices of the shared scene's
    points it sees instead; and a query 0.3 m past place 6, turned 25 degrees, seeing the whole
    shared scene. -> (local features, frames, xy, the query)."""
    rng = np.random.default_rng(seed)
    shared = rng.uniform(-8, 8, (120, 3)) * [1, 1, 0.3] + [6, 0, 0]
    shared_d = rng.integers(0, 256, (len(shared), 32), dtype=np.uint8)
    local = LocalFeatures.empty()
    for i in range(n):
        pts = shared[seen[i]] if i in seen else rng.uniform(-8, 8, (100, 3)) * [1, 1, 0.3] + [i, 0, 0]
        d = shared_d[seen[i]] if i in seen else rng.integers(0, 256, (len(pts), 32), dtype=np.uint8)
        local = local + one_place(0, i, _unit(pts - [i, 0, 0]), d)
    frames = np.zeros(n, [("video", "<i4"), ("frame", "<i4")])
    frames["frame"] = np.arange(n)
    xy = np.stack([np.arange(n, dtype=float), np.zeros(n)], axis=1)
    query = (_unit((shared - [6.3, 0, 0]) @ _rot_z(25.0)).astype(np.float32), shared_d)
    return local, frames, xy, query


def _candidates(*rows: int) -> Matches:
    k = len(rows)
    return Matches(np.array([rows]), np.linspace(0.9, 0.5, k)[None], np.full((1, k), 0.9), np.zeros((1, k)))


def test_a_place_the_global_search_missed_is_found_by_the_venues_vote(monkeypatch):
    """Where no candidate confirms the global answer, the clip's keypoints vote over every place,
    and the best-voted are verified: the answer moves to the one place that saw the scene."""
    import omninav.verify as vf

    local, frames, xy, q = _corridor({6: np.arange(120)})
    place_of, index = place_of_rows(frames, local), place_index(frames, local, xy)
    m = _candidates(0, 2, 4)  # the global search's places: none of them saw the scene
    assert verify(q, m, xy, local, place_of, 0, 2.0).moved_to is None  # (without the vote)
    v = verify(q, m, xy, local, place_of, 0, 2.0, index=index)
    assert v.moved_to == 6 and max(v.inliers) >= 100 and v.rows[:3] == [0, 2, 4]
    # a global answer its own place confirms is not put to the vote (though it does not settle it)
    votes = []
    monkeypatch.setattr(vf, "SETTLED_INLIERS", 10**9)
    monkeypatch.setattr(vf, "place_votes", lambda *a: votes.append(1) or np.zeros(len(local.places)))
    assert verify(q, _candidates(6, 2), xy, local, place_of, 6, 2.0, index=index).moved_to is None
    assert votes == []
    # nor is a venue too big to vote over within a request's time
    monkeypatch.setattr(vf, "VOTE_MAX_PLACES", len(local.places) - 1)
    assert verify(q, m, xy, local, place_of, 0, 2.0, index=index).outcome == "unconfirmed"
    assert votes == []


def test_a_moved_answer_goes_to_the_neighbouring_place_that_saw_more():
    """The candidates are one every PLACE_M: a moved answer is refined among the places beside it
    (here the place a metre on saw the whole scene, the candidate half of it)."""
    local, frames, xy, q = _corridor({6: np.arange(0, 120, 2), 7: np.arange(120)})
    place_of, index = place_of_rows(frames, local), place_index(frames, local, xy)
    m = _candidates(0, 6, 9)
    assert verify(q, m, xy, local, place_of, 0, 2.0).moved_to == 6
    v = verify(q, m, xy, local, place_of, 0, 2.0, index=index)
    assert v.moved_to == 7 and v.inliers[v.rows.index(7)] > v.inliers[v.rows.index(6)]
    assert 8 not in v.rows[3:]  # only places within PLACE_M of the moved answer are refined


def test_a_place_that_confirms_the_answer_stands_without_the_other_candidates_or_a_wider_search(monkeypatch):
    """The global answer's place with SETTLED_INLIERS stands: the other candidates are not
    compared and the wider search does not run, though a place it finds saw more (here place 9 all
    of the scene, the answer's place 6 two thirds of it); with fewer, they are, and the answer moves."""
    import omninav.verify as vf

    local, frames, xy, q = _corridor({6: np.flatnonzero(np.arange(120) % 3), 9: np.arange(120)})
    place_of = place_of_rows(frames, local)
    asked: list[int] = []

    def wide() -> Matches:
        asked.append(1)
        return _candidates(9)

    v = verify(q, _candidates(6, 0), xy, local, place_of, 6, 1.4, wide)
    assert v.outcome == "confirmed" and v.rows == [6] and v.inliers[0] >= vf.SETTLED_INLIERS
    assert asked == [] and v.essential is not None
    monkeypatch.setattr(vf, "SETTLED_INLIERS", 10**9)
    v = verify(q, _candidates(6, 0), xy, local, place_of, 6, 1.4, wide)
    assert asked == [1] and v.moved_to == 9 and v.inliers[v.rows.index(9)] >= 1.4 * v.inliers[0]


@settings(max_examples=300, deadline=None)
@given(
    n=st.integers(1, 300),
    k=st.integers(1, 30),
    span=st.sampled_from([1.0, 4.0, 20.0, 100.0]),
    decimals=st.integers(0, 2),
    first=st.booleans(),
    wide=st.booleans(),
    seed=st.integers(0, 2**31),
)
def test_the_candidates_are_the_best_ranked_row_of_each_place(n, k, span, decimals, first, wide, seed):
    """candidate_rows keeps, in rank order (the global answer's row first, then the last frame's
    matches by score, then the other frames' and the wider search's), each row PLACE_M or more
    from every row kept before it, and nothing else, up to PLACES (positions and scores rounded,
    so that ties and places exactly PLACE_M apart occur)."""
    rng = np.random.default_rng(seed)
    xy = rng.uniform(0, span, (n, 2)).round(decimals)
    f = int(rng.integers(1, 6))
    score = rng.random((f, k)).round(1)
    m = Matches(rng.integers(0, n, (f, k)), score, score, score)
    ws = rng.random((3, 8)).round(1)
    w = Matches(rng.integers(0, n, (3, 8)), ws, ws, ws) if wide else None
    top = int(rng.integers(0, n)) if first else None
    got = candidate_rows(m, xy, top, w)
    # the rule, row by row in rank order
    last = list(m.index[-1][np.argsort(-m.score[-1])])
    idx = [m.index[:-1].ravel()] + ([w.index.ravel()] if w else [])
    sc = [m.score[:-1].ravel()] + ([w.score.ravel()] if w else [])
    rest = list(np.concatenate(idx)[np.argsort(-np.concatenate(sc), kind="stable")])
    want: list[int] = []
    for r in ([top] if first else []) + last + rest:
        if len(want) < PLACES and r not in want and all(np.hypot(*(xy[r] - xy[q])) >= PLACE_M for q in want):
            want.append(int(r))
    assert got == want


def test_a_candidate_far_short_of_the_bar_costs_a_third_of_a_scan_and_one_near_it_is_counted_in_full(monkeypatch):
    """A candidate that must clear MIN_INLIERS is first counted over every SCREEN-th query
    keypoint: place 2 (6 of the 120 scene points: 2 over the third) is left there; place 4 (15:
    5 over the third, so possibly the bar) is counted in full (its other two thirds scanned)
    and, short of the bar, not fitted;
    place 6, which saw the whole scene, is fitted and the answer moves to it."""
    import omninav.verify as vf

    local, frames, xy, q = _corridor({2: np.arange(6), 4: np.arange(15), 6: np.arange(120)})
    place_of = place_of_rows(frames, local)
    scanned: list[tuple[int, int]] = []  # (query keypoints, the place's) of each ratio test
    fitted: list[int] = []
    ratio, fit = vf.ratio_matches, vf.essential_fit
    monkeypatch.setattr(vf, "ratio_matches", lambda qd, vd: scanned.append((len(qd), len(vd))) or ratio(qd, vd))
    monkeypatch.setattr(vf, "essential_fit", lambda b1, b2: fitted.append(len(b1)) or fit(b1, b2))
    v = verify(q, _candidates(0, 2, 4, 6), xy, local, place_of, 0, 2.0)
    assert vf.SCREEN == 3 and len(q[1]) == 120
    assert scanned == [(120, 100), (40, 6), (40, 15), (80, 15), (40, 120), (80, 120)]
    assert fitted == [120] and v.moved_to == 6 and v.inliers == [0, 0, 0, v.inliers[3]] and v.inliers[3] >= 100


def test_an_answer_says_what_its_keypoints_made_of_it_and_an_unconfirmed_one_is_never_sure(
    verified, small_ds, monkeypatch
):
    import omninav.verify as vf

    local, frames, xy, q = _corridor({6: np.arange(120)})
    place_of = place_of_rows(frames, local)
    assert verify(q, _candidates(6, 2), xy, local, place_of, 6, 2.0).outcome == "confirmed"
    assert verify(q, _candidates(0, 2), xy, local, place_of, 0, 2.0).outcome == "unconfirmed"
    assert verify(q, _candidates(0, 6), xy, local, place_of, 0, 2.0).outcome == "moved"
    # nothing compared: not verified (a clip without keypoints; an answer whose place has none)
    assert verify((q[0][:7], q[1][:7]), _candidates(6, 2), xy, local, place_of, 6, 2.0).outcome is None
    no_place = np.where(np.arange(len(place_of)) == 0, -1, place_of)
    assert verify(q, _candidates(0, 2), xy, local, no_place, 0, 2.0).outcome is None
    assert vf.checked_confidence("unconfirmed", 0.97) == vf.UNCONFIRMED_CONFIDENCE < 0.8
    assert vf.checked_confidence("unconfirmed", 0.3) == 0.3
    assert vf.checked_confidence("confirmed", 0.97) == 0.97 and vf.checked_confidence(None, 0.97) == 0.97
    assert vf.checked_confidence("moved", 0.97) == MOVED_CONFIDENCE
    # through the Locator: a right, sure answer whose own place the keypoints do not confirm
    loc = Locator(*verified)
    frames_, (tx, ty, _) = query_clip(small_ds, 60)
    lens = load_lens(small_ds.lens)
    sure = loc.locate_frames(frames_, "c", lens, 10.0)
    assert sure["verified"] == "confirmed" and sure["confidence"] >= 0.8
    monkeypatch.setattr(vf, "verify", lambda *a, **k: vf.Verdict([0], [5], None))
    a = loc.locate_frames(frames_, "c", lens, 10.0)
    assert a["verified"] == "unconfirmed" and a["confidence"] == vf.UNCONFIRMED_CONFIDENCE
    assert (a["x"], a["y"]) == (sure["x"], sure["y"])


def test_each_place_knows_its_venue_row_and_each_keypoint_its_place():
    local = _places((0, 3, 2), (1, 5, 3), (0, 9, 1))
    frames = np.zeros(4, [("video", "<i4"), ("frame", "<i4")])
    frames["video"], frames["frame"] = [1, 0, 0, 1], [5, 9, 3, 7]
    xy = np.arange(8, dtype=float).reshape(4, 2)
    ix = place_index(frames, local, xy)
    assert list(ix.rows) == [2, 0, 1] and list(ix.owner) == [0, 0, 1, 1, 1, 2]
    assert np.array_equal(ix.xy, xy[[2, 0, 1]])
    gone = place_index(frames[:2], local, xy[:2])  # a place whose frame is not a venue row
    assert list(gone.rows) == [-1, 0, 1] and np.isnan(gone.xy[0]).all()


def test_the_vote_counts_over_a_venue_of_more_than_two_to_the_eighteen_descriptors():
    # 300 places of 900 keypoints: 270,000 stored descriptors (OpenCV's matcher refuses 2**18 at once)
    n_places, per = 300, 900
    rng = np.random.default_rng(5)
    places = np.zeros(n_places, LOCAL_DTYPE)
    places["frame"], places["start"], places["count"] = np.arange(n_places), np.arange(n_places) * per, per
    desc = rng.integers(0, 256, (n_places * per, 32), dtype=np.uint8)
    local = LocalFeatures(places, np.zeros((len(desc), 3), np.float16), desc)
    assert len(desc) > 1 << 18
    owner = np.repeat(np.arange(n_places, dtype=np.int32), per)
    # the first place, one whose keypoints straddle row 2**17, the last
    for p, at in ((3, 0), (145, (1 << 17) - 145 * per - 60), (299, 0)):
        q = local.of(p)[1][at : at + 120].copy()
        q[:, 0] ^= 1  # one bit off: still each keypoint's nearest
        votes = place_votes(q, local, owner)
        assert int(np.argmax(votes)) == p and votes[p] == 120


def test_a_keypoint_votes_once_for_each_place_among_its_near_stored_descriptors():
    places = np.zeros(3, LOCAL_DTYPE)
    places["frame"], places["start"], places["count"] = [0, 1, 2], [0, 2, 4], [2, 2, 2]
    q = np.zeros((1, 32), np.uint8)
    far = np.full(32, 0xFF, np.uint8)  # 256 bits off
    near = q[0].copy()
    near[:4] = 0xFF  # 32 bits off: within VOTE_HAMMING
    edge = q[0].copy()
    edge[: VOTE_HAMMING // 8 + 1] = 0xFF  # just past it
    desc = np.stack([q[0], near, far, edge, near, q[0]])  # place 0 twice near, 1 past the edge, 2 near
    assert VOTE_K >= 4
    local = LocalFeatures(places, np.zeros((6, 3), np.float16), desc)
    votes = place_votes(q, local, np.array([0, 0, 1, 1, 2, 2], np.int32))
    assert list(votes) == [1, 0, 1]
    assert list(place_votes(q[:0], local, np.array([0, 0, 1, 1, 2, 2], np.int32))) == [0, 0, 0]
    # fewer stored than VOTE_K (the rest: no neighbour), one of them past VOTE_HAMMING
    two = LocalFeatures(places[:2].copy(), np.zeros((2, 3), np.float16), np.stack([q[0], edge]))
    two.places["start"], two.places["count"] = [0, 1], [1, 1]
    assert list(place_votes(q, two, np.array([0, 1], np.int32))) == [1, 0]


def test_ratio_matches_are_the_brute_force_matchers():
    rng = np.random.default_rng(3)
    d2 = rng.integers(0, 256, (700, 32), dtype=np.uint8)
    d1 = np.concatenate([d2[rng.permutation(700)[:300]], rng.integers(0, 256, (400, 32), dtype=np.uint8)])
    d1[:300, :2] ^= rng.integers(0, 256, (300, 2), dtype=np.uint8)  # up to 16 bits off
    pairs = cv2.BFMatcher(cv2.NORM_HAMMING).knnMatch(d1, d2, k=2)
    want = [(p[0].queryIdx, p[0].trainIdx) for p in pairs if p[0].distance < RATIO * p[1].distance]
    got = ratio_matches(d1, d2)
    assert 250 <= len(got) < 400 and [tuple(r) for r in got] == want
    # one keypoint is tested as in the many (the screen's split scan relies on it); one stored
    # descriptor, or no keypoint, tests nothing
    assert [tuple(r) for r in ratio_matches(d1[:1], d2)] == [p for p in want if p[0] == 0] != []
    assert ratio_matches(d1, d2[:1]).shape == (0, 2) and ratio_matches(d1[:0], d2).shape == (0, 2)


@settings(max_examples=100, deadline=None)
@given(n=st.integers(1, 50), m=st.integers(2, 1200), bits=st.integers(0, 3), seed=st.integers(0, 2**31))
def test_the_compiled_scan_finds_faiss_nearest_two(n, m, bits, seed):
    """hamming.two_nearest: each query descriptor's least and second least distance are faiss's,
    and where the least is strictly least (the ratio test's only matches), the same stored row
    (descriptors of few random bytes, so that distances tie often)."""
    from omninav.hamming import two_nearest
    from omninav.verify import nearest

    rng = np.random.default_rng(seed)
    stored = (rng.integers(0, 256, (m, 32)) & (2 ** (bits * 2 + 2) - 1)).astype(np.uint8)
    query = (rng.integers(0, 256, (n, 32)) & (2 ** (bits * 2 + 2) - 1)).astype(np.uint8)
    got = two_nearest(query, stored)
    dist, idx = nearest(query, stored, 2)
    assert np.array_equal(got[:, :2], dist)
    strict = dist[:, 0] < dist[:, 1]
    assert np.array_equal(got[strict, 2], idx[strict, 0])
    # a record's descriptors (read-only, unaligned bytes) take the same compiled code
    raw = np.frombuffer(b"x" + query.tobytes(), np.uint8, offset=1).reshape(n, 32)
    assert np.array_equal(two_nearest(raw, stored), got)
    from omninav import hamming

    assert len(hamming._two_nearest.signatures) == 1
    for bad in (stored[:1], stored[:, :16], stored.ravel()):
        with pytest.raises(ValueError):
            two_nearest(query, bad)


def test_each_venue_frame_finds_the_place_of_its_own_video_at_or_before_it():
    lf = _places((1, 4, 1), (0, 0, 1), (0, 10, 1))  # (stored in any order)
    frames = np.zeros(6, [("frame", "<i4"), ("video", "<i4")])
    frames["frame"], frames["video"] = [0, 6, 10, 11, 1, 2], [0, 0, 0, 0, 1, 2]
    # modelling keeps a place at most SPACING_M behind every frame: the one at or before it
    # (video 1's frame 1 comes before its first place: the first after it)
    assert list(place_of_rows(frames, lf)) == [1, 1, 2, 2, 0, -1]
    assert list(place_of_rows(frames, LocalFeatures.empty())) == [-1] * 6


def test_a_verified_venue_stores_a_place_every_half_metre_of_its_walk(verified):
    st, vid = verified
    g = st.load(vid)
    assert g.local is not None and g.settings["local_features"] == 900
    xy = np.stack([g.frames["x"], g.frames["y"]], 1)
    step = float(np.hypot(*np.diff(xy, axis=0).T).max())  # the walk between two sampled frames
    row = np.searchsorted(g.frames["frame"], g.local.places["frame"])
    assert np.array_equal(g.frames["frame"][row], g.local.places["frame"]) and row[0] == 0
    gaps = np.hypot(*np.diff(xy[row], axis=0).T)
    assert gaps.min() >= SPACING_M and gaps.max() <= SPACING_M + step + 1e-6
    assert 300 <= np.median(g.local.places["count"]) <= 900
    assert np.allclose(np.linalg.norm(np.asarray(g.local.bearings, np.float32), axis=1), 1, atol=2e-3)


def test_a_venues_places_for_verification_are_made_once_with_the_compiled_loops_loaded(verified, monkeypatch):
    from omninav import essential, hamming

    called: list[str] = []
    counts, scan = essential.sample_counts, hamming.two_nearest
    monkeypatch.setattr(essential, "sample_counts", lambda *a: called.append("ransac") or counts(*a))
    monkeypatch.setattr(hamming, "two_nearest", lambda *a: called.append("scan") or scan(*a))
    st, vid = verified
    loc = Locator(st, vid)
    place_of, index = loc.verification_places()
    assert called == ["ransac", "scan"]  # (run once, so loaded: the first request does not compile)
    assert loc.verification_places()[0] is place_of and called == ["ransac", "scan"]
    assert len(place_of) == len(loc.gen.frames) and (index.rows[place_of[place_of >= 0]] >= 0).all()


def test_local_features_follow_the_venues_videos(verified, small_ds, tmp_path):
    import shutil

    shutil.copytree(verified[0].root, tmp_path / "data")
    st = Store(tmp_path / "data")
    first = st.load("lab").local
    assert first is not None
    model_video(st, "lab", small_ds.query_video, load_walk_path(small_ds.query_walk_path), load_lens(small_ds.lens))
    both = st.load("lab").local
    assert both is not None and set(both.places["video"]) == {0, 1} and len(both.places) > len(first.places)
    remove_video(st, "lab", "model.mp4")  # the first video goes: the second one's places are video 0
    left = st.load("lab")
    assert left.local is not None and set(left.local.places["video"]) == {0}
    assert len(left.local.places) == len(both.places) - len(first.places)
    assert np.array_equal(left.local.descriptors, both.descriptors[len(first.descriptors) :])


def test_a_wrong_global_answer_moves_to_the_place_the_geometry_confirms(verified, small_ds, monkeypatch):
    import omninav.verify as vf

    st, vid = verified
    loc = Locator(st, vid)
    frames, (tx, ty, th) = query_clip(small_ds, 60)
    far, truth = far_and_truth(loc, tx, ty)
    # the global search ranked a far place first and the true one second
    m = Matches(np.array([[far, truth]]), np.array([[0.9, 0.8]]), np.array([[0.9, 0.6]]), np.array([[10.0, 20.0]]))
    lens = load_lens(small_ds.lens)
    q = loc.local_features(frames[-1], lens)
    place_of = place_of_rows(loc.gen.frames, loc.gen.local)
    v = verify(q, m, loc.xy, loc.gen.local, place_of, far, 2.0)
    assert v.rows == [far, truth]
    assert v.inliers[1] >= MIN_INLIERS and v.inliers[1] >= 2 * v.inliers[0] and v.moved_to == truth
    # where the global answer is the true place, it stands; and its place is scored even where no
    # frame's matches hold it
    assert verify(q, m, loc.xy, loc.gen.local, place_of, truth, 2.0).moved_to is None
    only_far = Matches(np.array([[far]]), np.array([[0.9]]), np.array([[0.9]]), np.array([[10.0]]))
    with monkeypatch.context() as mp:
        mp.setattr(vf, "SETTLED_INLIERS", 10**9)  # (not settled by its place: the candidates are listed)
        assert verify(q, only_far, loc.xy, loc.gen.local, place_of, truth, 2.0).rows == [truth, far]
    # and the Locator says a moved answer with its own confidence, at the true place, facing the
    # way the last frame's curves say there (not the far match's heading)
    e = loc.aggregated(m, np.zeros(1))
    moved, outcome = loc.verified(q, m, e, clip_spectra(small_ds, frames, loc.conf))
    assert outcome == "moved" and moved.venue_row == truth
    assert heading_error(moved.heading, th) < 5.0


def test_a_clip_sent_as_frames_or_as_a_record_with_local_features_is_moved(wrong_global, verified, small_ds, tmp_path):
    frames, (tx, ty, th), truth = wrong_global
    loc = Locator(*verified)
    lens = load_lens(small_ds.lens)
    a = loc.locate_frames(frames, "c", lens, 10.0)
    assert a["confidence"] == MOVED_CONFIDENCE and np.hypot(a["x"] - tx, a["y"] - ty) < 1.0
    assert heading_error(a["heading_deg"], th) < 5.0
    spec = clip_spectra(small_ds, frames, loc.conf)
    rec = decode_binary_local(encode_binary(spec, loc.conf, loc.local_features(frames[-1], lens)), loc.conf)
    b = loc.locate_spectra(*rec[:1], "c", 10.0, None, rec[1])
    assert b["confidence"] == MOVED_CONFIDENCE and np.hypot(b["x"] - tx, b["y"] - ty) < 1.0
    path = tmp_path / "c.onv"  # as `omninav locate` reads a record file
    path.write_bytes(encode_binary(spec, loc.conf, loc.local_features(frames[-1], lens)))
    c = loc.locate_spectra(*read_record(path, loc.conf)[:1], "c", 10.0, None, read_record(path, loc.conf)[1])
    assert c["confidence"] == MOVED_CONFIDENCE and np.hypot(c["x"] - tx, c["y"] - ty) < 1.0
    plain = loc.locate_spectra(spec, "c", 10.0)  # a version-1 record: the global answer, wrong here
    assert np.hypot(plain["x"] - tx, plain["y"] - ty) > 5.0 and plain["confidence"] != MOVED_CONFIDENCE


def test_an_evaluation_walk_is_verified_clip_by_clip(wrong_global, verified, small_ds):
    from omninav.evaluate import evaluate

    loc = Locator(*verified)
    ev = evaluate(loc, small_ds.query_video, load_walk_path(small_ds.query_walk_path), load_lens(small_ds.lens))
    # every clip's global answer is the far place; the clip that ends at frame 69 is moved home
    [row] = [r for r in ev.rows if r["frame"] == 69]
    assert row["verified"] == "moved" and row["err_m"] < 1.0 and row["confidence"] == MOVED_CONFIDENCE


def test_verification_leaves_right_answers_where_they_are(verified, small_ds):
    ver = Locator(*verified)
    lens = load_lens(small_ds.lens)
    for start in (0, 60, 120):
        frames, (tx, ty, _) = query_clip(small_ds, start)
        a = ver.locate_frames(frames, "c", lens, 10.0)
        assert np.hypot(a["x"] - tx, a["y"] - ty) < 1.0


@pytest.mark.parametrize("error", [cv2.error("broken"), RuntimeError("cannot cache function: no locator available")])
def test_an_error_in_verification_leaves_the_global_answer(verified, small_ds, monkeypatch, caplog, error):
    """OpenCV's, or numba's where it can write no cache (RuntimeError), among others."""
    from omninav import verify as verify_mod

    loc = Locator(*verified)
    frames, (tx, ty, _) = query_clip(small_ds, 60)

    def broken(*a, **k):
        raise error

    monkeypatch.setattr(verify_mod, "verify", broken)
    a = loc.locate_frames(frames, "c", load_lens(small_ds.lens), 10.0)
    assert np.hypot(a["x"] - tx, a["y"] - ty) < 1.0 and a["confidence"] != MOVED_CONFIDENCE
    assert "verification failed" in caplog.text


def test_a_clip_with_too_few_keypoints_is_answered_by_its_curves_without_a_wider_search(
    verified, small_ds, monkeypatch
):
    import omninav.verify as vf

    loc = Locator(*verified)
    frames, _ = query_clip(small_ds, 60)
    spec = clip_spectra(small_ds, frames, loc.conf)
    bearings, desc = loc.local_features(frames[-1], load_lens(small_ds.lens))
    searches: list[int] = []
    search = loc.index.search
    loc.index.search = lambda *a, **k: searches.append(1) or search(*a, **k)  # type: ignore[method-assign]

    def located(local=None):
        searches.clear()
        return loc.locate_spectra(spec, "c", 10.0, local=local), len(searches)

    (plain, n), (few, n_few), (full, n_full) = located(), located((bearings[:5], desc[:5])), located((bearings, desc))
    assert "verified" not in few and (few["x"], few["y"], few["confidence"]) == (
        plain["x"],
        plain["y"],
        plain["confidence"],
    )
    assert n_few == n  # the clip's own search only
    assert full["verified"] == "confirmed" and n_full == n  # its place confirmed it: no wider one
    monkeypatch.setattr(vf, "SETTLED_INLIERS", 10**9)
    again, n_again = located((bearings, desc))
    assert again["verified"] == "confirmed" and n_again > n  # the last frames' wider one


def test_a_dim_frame_keeps_a_third_of_its_keypoints(small_ds):
    # light at a quarter (a dim corridor): ORB's default FAST threshold keeps a tenth of the corners
    # on our renders, too few for its own place to reach MIN_INLIERS; FAST_DIM keeps about half
    frames, _ = query_clip(small_ds, 60)
    lens = load_lens(small_ds.lens)
    bright = len(detect(frames[-1], lens, 900)[0])
    dim = len(detect((frames[-1] * 0.25).astype(np.uint8), lens, 900)[0])
    assert bright > 600 and dim > bright / 3


@pytest.mark.parametrize("turn", [-150.0, -30.0, 10.0, 100.0, 179.0])
def test_the_keypoints_say_how_far_the_clip_is_turned_from_the_place(turn):
    # points around a corridor; the place's camera faces azimuth 0, the clip's 0.8 m along and
    # turned `turn` degrees clockwise (a bearing's azimuth is clockwise from +y)
    rng = np.random.default_rng(1)
    pts = np.c_[rng.uniform(-6, 6, 300), rng.uniform(-10, 10, 300), rng.uniform(-1.2, 1.5, 300)]
    pts = pts[np.hypot(pts[:, 0], pts[:, 1]) > 1.5]
    at = np.array([0.3, 0.8, 0.05])
    c, s = np.cos(np.radians(turn)), np.sin(np.radians(turn))
    seen = pts - at
    clip = np.c_[seen[:, 0] * c - seen[:, 1] * s, seen[:, 1] * c + seen[:, 0] * s, seen[:, 2]]
    ok, e = essential_fit(_unit(clip), _unit(pts))
    assert ok.mean() > 0.95 and e is not None
    assert abs((turn_deg(e) - turn + 180.0) % 360.0 - 180.0) < 0.5


def test_a_verified_answer_takes_the_keypoints_heading_where_the_curves_turned_it_round(
    verified, small_ds, monkeypatch
):
    loc = Locator(*verified)
    frames, (_, _, th) = query_clip(small_ds, 60)
    spec = clip_spectra(small_ds, frames, loc.conf)
    local = loc.local_features(frames[-1], load_lens(small_ds.lens))
    right = loc.locate_spectra(spec, "c", 10.0, local=local)
    assert right["verified"] == "confirmed" and heading_error(right["heading_deg"], th) < 5.0
    aggregated = loc.aggregated

    # the curves' heading turned round (a corridor's two ends alike): the keypoints turn it back
    def flip(*a):
        e = aggregated(*a)
        return dataclasses.replace(e, heading=(e.heading + 180.0) % 360.0)

    monkeypatch.setattr(loc, "aggregated", flip)
    turned = loc.locate_spectra(spec, "c", 10.0, local=local)
    assert heading_error(turned["heading_deg"], th) < 10.0  # (the keypoints' turn: within a few degrees)
    assert heading_error(loc.locate_spectra(spec, "c", 10.0)["heading_deg"], th) > 170.0  # not verified
    # turned by less than HEADING_AGREE_DEG (a corner's modelled heading is that far off): the curves' stands

    def turned_by(deg):
        def turned(*a):
            e = aggregated(*a)
            return dataclasses.replace(e, heading=(e.heading + deg) % 360.0)

        return turned

    monkeypatch.setattr(loc, "aggregated", turned_by(30.0))
    assert (
        heading_error(loc.locate_spectra(spec, "c", 10.0, local=local)["heading_deg"], right["heading_deg"] + 30.0)
        < 0.01
    )


def test_local_features_are_fixed_when_modelled_and_absent_from_older_venues(verified):
    loc = Locator(*verified)
    with pytest.raises(OmninavError, match="local_features"):
        loc.change_settings({"local_features": 500})
    loc.change_settings({"local_margin": 3.0})
    assert loc.conf["local_margin"] == 3.0
    old = {k: v for k, v in resolve("default").items() if k not in ("local_features", "local_margin")}
    old["version"] = 3
    assert upgrade(old)["local_features"] is None and upgrade(old)["local_margin"] == 2.0
    with pytest.raises(OmninavError, match="local_features"):
        resolve("default", {"local_features": 50})
