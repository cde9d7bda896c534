"""The batched index against references: brute force and the sequential loop (GPU against CPU:
test_index_gpu.py)."""

import numpy as np
import pytest

from omninav.curves import normalise
from omninav.heading import cross_correlation
from omninav.index import Index, index_arrays, magnitude_keys, scan_top, sequential_search, top_k
from omninav.spectrum import quantise, spectrum


def venue_spectra(n: int, seed: int = 0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    # a smooth random walk of curves: neighbouring venue frames look alike, as along a corridor
    base = np.cumsum(rng.normal(size=(n, 6, 360)) * 0.3, axis=0) + rng.normal(size=(1, 6, 360)) * 3
    return quantise(spectrum(normalise(base.astype(np.float32)), 32))


def test_top_k_matches_a_full_sort():
    rng = np.random.default_rng(1)
    s = rng.normal(size=(5, 1000)).astype(np.float32)
    idx, val = top_k(s, 7)
    ref = np.argsort(-s, axis=1)[:, :7]
    assert np.array_equal(idx, ref) and np.allclose(val, np.take_along_axis(s, ref, 1))
    idx_all, _ = top_k(s[:, :5], 10)  # k larger than n: everything, sorted
    assert np.array_equal(idx_all, np.argsort(-s[:, :5], axis=1))


def test_search_finds_rotated_venue_frames():
    spec = venue_spectra(2000)
    headings = np.random.default_rng(2).uniform(0, 360, 2000).astype(np.float32)
    ix = Index(spec, headings, device="cpu")
    rows = np.array([5, 700, 1999])
    turn = np.array([30.0, 200.0, 359.0])
    k = np.arange(1, 33)
    q = spec[rows] * np.exp(2j * np.pi * k * turn[:, None, None] / 360.0)  # q(j) = v(j + s)
    m = ix.search(q.astype(np.complex64), 8)
    assert np.array_equal(m.index[:, 0], rows)
    assert np.allclose(np.mod(m.heading[:, 0] - (headings[rows] + turn) + 180, 360) - 180, 0, atol=0.2)
    assert np.all(m.score[:, 0] > 0.99)
    # the magnitude score bounds the phase score (Cauchy-Schwarz), so verification never exceeds it
    assert np.all(m.score <= m.coarse + 1e-4)


def test_batched_stage_one_agrees_with_the_sequential_loop():
    spec = venue_spectra(300, seed=4)
    rng = np.random.default_rng(5)
    q = quantise(spec[[3, 150, 299]] * (1 + 0.05 * rng.normal(size=(3, 6, 32))))
    ix = Index(spec, np.zeros(300), device="cpu")
    # unit-energy keys: max inner product ~ min distance (up to the query's own norm)
    kq = magnitude_keys(q)
    d = ((kq[:, None, :] - ix.keys[None]) ** 2).sum(-1)
    assert np.array_equal(sequential_search(q, spec), d.argmin(1))
    assert np.array_equal(sequential_search(q, spec), [3, 150, 299])


def test_sampled_threshold_top_k_is_exact_on_long_rows():
    rng = np.random.default_rng(8)
    s = np.cumsum(rng.normal(size=(4, 200_000)), axis=1).astype(np.float32)  # correlated, like venues
    s[2, 123_456] = s.max() + 5  # one clear winner
    idx, val = top_k(s, 16)
    ref = np.argsort(-s, axis=1)[:, :16]
    assert np.allclose(val, np.take_along_axis(s, ref, 1))
    assert idx[2, 0] == 123_456


def _exact_top(qk: np.ndarray, first: np.ndarray, k: int) -> np.ndarray:
    return np.sort(np.argsort(-(qk @ first.T), axis=1, kind="stable")[:, :k], axis=1)


def test_the_chunked_scan_keeps_each_querys_exact_k_best():
    """Stage 1's fused scan (chunks, a sampled threshold, queries of very different scales)
    keeps what a full product and a sort keep, with their scores."""
    rng = np.random.default_rng(11)
    first = np.abs(np.cumsum(rng.normal(size=(50_000, 32)), axis=0)).astype(np.float32)
    qk = first[[10, 20_000, 49_999]] * np.array([[1.0], [40.0], [0.01]], np.float32)  # scores 4,000x apart
    sample = np.ascontiguousarray(first[::8])
    idx, val = scan_top(qk, first, 64, sample, chunk=7_000)
    assert np.array_equal(np.sort(idx, axis=1), _exact_top(qk, first, 64))
    assert np.allclose(val, np.take_along_axis(qk @ first.T, idx, axis=1), rtol=1e-5)


def test_the_scan_falls_back_to_the_full_product_when_its_sample_misleads_it():
    """A sample that holds the venue's best frames sets the cut too high: fewer than k survive
    for a query, and the full product decides."""
    rng = np.random.default_rng(12)
    first = rng.uniform(0.0, 0.1, size=(20_000, 8)).astype(np.float32)
    first[::8] += 1.0  # every sampled frame scores high, the others low
    qk = rng.uniform(0.5, 1.0, size=(2, 8)).astype(np.float32)
    idx, _ = scan_top(qk, first, 2_600, np.ascontiguousarray(first[::8]), chunk=4_096)
    assert np.array_equal(np.sort(idx, axis=1), _exact_top(qk, first, 2_600))


def test_the_scan_falls_back_to_the_full_product_when_a_threshold_is_not_positive():
    """Scores at or below zero (never seen with magnitudes) cannot be scaled by their threshold."""
    rng = np.random.default_rng(13)
    first = -rng.uniform(0.1, 1.0, size=(10_000, 8)).astype(np.float32)
    qk = rng.uniform(0.5, 1.0, size=(3, 8)).astype(np.float32)
    idx, _ = scan_top(qk, first, 40, np.ascontiguousarray(first[::8]), chunk=4_096)
    assert np.array_equal(np.sort(idx, axis=1), _exact_top(qk, first, 40))


def test_a_generation_written_with_keys_t_searches_as_a_new_one():
    """Generations written before the first pass was frame-major carry (d, N) keys_t and no
    `first`: they answer the same."""
    spec = venue_spectra(3000, seed=6)
    heads = np.random.default_rng(7).uniform(0, 360, 3000).astype(np.float32)
    new = index_arrays(spec, 32)
    old = {"keys": new["keys"], "basis": new["basis"], "keys_t": np.ascontiguousarray(new["first"].T)}
    k = np.arange(1, 33)
    q = (spec[[40, 1500, 2990]] * np.exp(2j * np.pi * k * 77.0 / 360.0)).astype(np.complex64)
    a = Index(spec, heads, device="cpu", key_dims=32, arrays=new).search(q, 8, groups=np.zeros(3, int))
    b = Index(spec, heads, device="cpu", key_dims=32, arrays=old).search(q, 8, groups=np.zeros(3, int))
    assert np.array_equal(a.index, b.index) and np.allclose(a.score, b.score, atol=1e-6)
    assert np.array_equal(a.index[:, 0], [40, 1500, 2990])


def test_projected_keys_still_find_the_frame(modelled):
    """Real curve spectra are close to low-rank: 32 projected dims keep the right candidates."""
    st, vid = modelled
    spec = np.asarray(st.load(vid).spectra)
    n = len(spec)
    ix = Index(spec, np.zeros(n), device="cpu", key_dims=32)
    assert ix.first.shape == (n, 32) and ix.keys.shape == (n, spec.shape[1] * spec.shape[2])
    rows = np.array([3, n // 2, n - 1])
    k = np.arange(1, spec.shape[-1] + 1)
    q = spec[rows] * np.exp(2j * np.pi * k * 123.0 / 360.0)
    m = ix.search(q.astype(np.complex64), 16)
    best = m.index[np.arange(3), m.score.argmax(axis=1)]  # stage 2 decides among the candidates
    assert np.all(np.abs(best - rows) <= 1)
    assert np.all(m.score.max(axis=1) > 0.99)


def _spoiled_clip(spec: np.ndarray, r: int, spoil: float, seed: int = 0) -> np.ndarray:
    """Three frames filmed at venue rows r-1, r, r+1, turned by 40 degrees; the middle one
    spoiled by noise `spoil` times its own energy (people in the way, another light)."""
    k = np.arange(1, spec.shape[-1] + 1)
    q = spec[[r - 1, r, r + 1]] * np.exp(2j * np.pi * k * 40.0 / 360.0)
    rng = np.random.default_rng(seed)
    noise = rng.normal(size=q[1].shape) + 1j * rng.normal(size=q[1].shape)
    q[1] = q[1] + noise * spoil * np.linalg.norm(q[1]) / np.linalg.norm(noise)
    q[1] /= np.linalg.norm(q[1])
    return q.astype(np.complex64)


def test_shared_candidates_give_a_spoiled_frame_its_place_back():
    """A frame whose own magnitude ranking lost its place gets it from the frames filmed beside it."""
    spec = venue_spectra(2000)
    ix = Index(spec, np.random.default_rng(2).uniform(0, 360, 2000), device="cpu")
    q = _spoiled_clip(spec, 700, 1.2)
    own = ix.search(q, 4)
    shared = ix.search(q, 4, groups=np.zeros(3, np.int64))
    assert np.all(np.abs(own.index[1] - 700) > 20)  # its own candidates are elsewhere
    assert abs(shared.index[1, 0] - 700) <= 3  # ... the clip's bring its place back
    assert shared.score[1, 0] > own.score[1, 0]
    # the unspoiled frames keep (at least) their own best match and its heading
    for i in (0, 2):
        assert shared.index[i, 0] == own.index[i, 0] and shared.score[i, 0] >= own.score[i, 0] - 1e-6
        assert abs(shared.heading[i, 0] - own.heading[i, 0]) < 1e-3
    assert np.all(np.diff(shared.score, axis=1) <= 1e-6)  # best first
    assert np.all(shared.score <= shared.coarse + 1e-4)  # the magnitude bound still bounds them


def test_shared_candidates_are_the_best_verified_of_the_group_union():
    """Against a brute-force reference: every frame verified on its own against the union of its
    group's stage-1 candidates, its k best kept; groups do not mix."""
    spec = venue_spectra(600, seed=6)
    ix = Index(spec, np.zeros(600), device="cpu")
    rng = np.random.default_rng(7)
    q = quantise(spec[[10, 11, 12, 300, 301]] * (1 + 0.3 * rng.normal(size=(5, 6, 32))))
    groups = np.array([0, 0, 0, 1, 1])
    own = ix.search(q, 5)
    m = ix.search(q, 5, groups=groups)
    for g in (0, 1):
        rows = np.flatnonzero(groups == g)
        union = np.unique(own.index[rows])
        for i in rows:
            score, _ = ix.verify(q[i : i + 1], union[None])
            ref = union[np.argsort(-score[0], kind="stable")[:5]]
            assert np.allclose(np.sort(m.score[i])[::-1], np.sort(score[0])[::-1][:5], atol=1e-5)
            assert set(m.index[i]) <= set(union) and set(m.index[i]) == set(ref)


def test_shared_candidates_keep_out_the_rows_a_frame_may_not_match():
    """The quality map's leave-one-out: a row in a frame's excluded range never comes back for it
    from another frame's candidates while rows it may match are left."""
    spec = venue_spectra(400, seed=9)
    ix = Index(spec, np.zeros(400), device="cpu")
    q = spec[[100, 101, 102]]
    lo, hi = np.array([95, 96, 97]), np.array([106, 107, 108])
    m = ix.search(q, 6, exclude=(lo, hi), groups=np.zeros(3, np.int64))
    for i in range(3):
        assert not np.any((m.index[i] >= lo[i]) & (m.index[i] < hi[i]))
        assert np.all(np.isfinite(m.score[i])) and np.all(m.score[i] > -1)


def test_shared_candidates_on_a_venue_smaller_than_k_and_rows_kept_for_want_of_others():
    """A venue of fewer frames than candidates keeps them all; rows a frame may not match come back
    only when nothing else is left, then supporting nothing (score -1, coarse -inf)."""
    spec = venue_spectra(30, seed=10)
    ix = Index(spec, np.zeros(30), device="cpu")
    q = spec[[3, 4, 5]]
    m = ix.search(q, 16, groups=np.zeros(3, np.int64))
    assert m.index.shape == (3, 16) and np.all(m.index[:, 0] == [3, 4, 5])
    small = Index(spec[:10], np.zeros(10), device="cpu")
    best, own = small.search_shared(q, 16, np.zeros(3, np.int64))
    assert best.index.shape == own.index.shape == (3, 10)  # all ten, no error
    lo, hi = np.zeros(3, np.int64), np.full(3, 25)  # only rows 25-29 may be matched
    m = ix.search(q, 8, exclude=(lo, hi), groups=np.zeros(3, np.int64))
    allowed = m.index >= 25
    assert np.all(allowed.sum(axis=1) == 5) and np.all(allowed[:, :5])  # the allowed ones first
    assert np.all(m.score[~allowed] == -1.0) and np.all(np.isneginf(m.coarse[~allowed]))
    assert np.all(m.score[allowed] > -1.0) and np.all(np.isfinite(m.coarse[allowed]))


def _look_alikes(seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """A venue of 300 frames and twelve look-alikes of row 150 (identical doors: its magnitudes,
    other phases), and a clip of three frames filmed at row 150, turned by 25 degrees. The
    look-alikes' magnitudes are the clip's own, closer to it than row 150's: stage 1 ranks all
    twelve first for every frame, and only the phase correlation tells them apart."""
    rng = np.random.default_rng(seed)
    filler = venue_spectra(300, seed=seed)
    turn = np.exp(2j * np.pi * np.arange(1, 33) * 25.0 / 360.0)
    q = filler[150] * turn * (1 + 0.05 * rng.normal(size=(3, *filler.shape[1:])))
    q = quantise(q / np.linalg.norm(q, axis=(1, 2), keepdims=True))
    mag = np.abs(q).mean(axis=0)
    alike = mag / np.linalg.norm(mag) * np.exp(2j * np.pi * rng.uniform(size=(12, *mag.shape)))
    return quantise(np.concatenate([filler, alike])), q


def test_a_longer_shortlist_finds_the_place_that_look_alikes_outrank_by_magnitude():
    spec, q = _look_alikes()
    ix = Index(spec, np.zeros(len(spec)), device="cpu")
    one = np.zeros(3, np.int64)
    short = ix.search(q, 4, groups=one)  # stage 1 keeps 4: twelve look-alikes fill them
    assert np.all(short.index >= 300) and np.all(short.score < 0.5)
    m = ix.search(q, 4, groups=one, shortlist=16)
    assert m.index.shape == (3, 4)  # each frame still keeps k
    assert np.all(np.abs(m.index - 150) <= 2) and np.all(m.score[:, 0] > 0.95)
    assert np.allclose(m.heading[:, 0], 25.0, atol=1.0)
    assert np.all(np.diff(m.score, axis=1) <= 1e-6)
    # the tracker's own candidates are still a frame's k best by stage 1, not its whole shortlist
    best, own = ix.search_shared(q, 4, one, 16)
    assert np.array_equal(best.index, m.index) and own.index.shape == (3, 4)
    assert np.array_equal(own.index, ix.coarse(q, 16)[0][:, :4]) and np.all(own.index >= 300)


def test_the_shortlist_through_projected_keys_is_the_exact_one(monkeypatch):
    """Above key_project_above frames the projection still shortlists PREFILTER x k a frame (not
    PREFILTER x the shortlist: the cost of the projected pass) and the exact magnitudes choose
    the shortlist among them: on a smooth venue, the same answer as exact keys."""
    import omninav.index as index_module

    spec = venue_spectra(3000, seed=3)
    rng = np.random.default_rng(4)
    q = quantise(spec[[100, 101, 102]] * (1 + 0.2 * rng.normal(size=(3, 6, 32))))
    one = np.zeros(3, np.int64)
    exact = Index(spec, np.zeros(3000), device="cpu").search(q, 16, groups=one, shortlist=32)
    proj_ix = Index(spec, np.zeros(3000), device="cpu", key_dims=32)
    cuts: list[int] = []
    real_top_k = index_module.top_k
    monkeypatch.setattr(index_module, "top_k", lambda s, k, ordered=True: cuts.append(k) or real_top_k(s, k, ordered))
    proj = proj_ix.search(q, 16, groups=one, shortlist=32)
    assert cuts[:2] == [index_module.PREFILTER * 16, 32]  # the projected pass, then the exact re-rank
    assert np.array_equal(exact.index, proj.index) and np.allclose(exact.score, proj.score, atol=1e-5)


@pytest.mark.parametrize("dtype", [np.complex64, np.complex128])
def test_the_correlation_over_shifts_is_the_inverse_fft_of_the_cross_power(dtype):
    rng = np.random.default_rng(11)
    x = (rng.normal(size=(4, 7, 16)) + 1j * rng.normal(size=(4, 7, 16))).astype(dtype)
    for n in (34, 64, 128, 129):
        pad = np.zeros((4, 7, n // 2 + 1), np.complex128)
        pad[..., 1:17] = np.conj(x)
        ref = np.fft.irfft(pad, n=n, axis=-1) * (n / 2.0)
        got = cross_correlation(x, n)
        assert got.shape == (4, 7, n) and got.dtype == np.real(x).dtype
        assert np.allclose(got, ref, atol=1e-4 if dtype == np.complex64 else 1e-10)
    with pytest.raises(ValueError):
        cross_correlation(x, 33)
