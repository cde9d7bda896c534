"""The batched index against references: brute force and the sequential loop (GPU against CPU:
test_index_gpu.py)."""

import numpy as np

from omninav.curves import normalise
from omninav.index import Index, magnitude_keys, sequential_search, top_k
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


def test_projected_keys_still_find_the_frame(modelled):
    """Real curve spectra are close to low-rank: 32 projected dims keep the right candidates."""
    st, vid = modelled
    spec = np.asarray(st.load(vid).spectra)
    n = len(spec)
    ix = Index(spec, np.zeros(n), device="cpu", key_dims=32)
    assert ix.keys_t.shape == (32, n) and ix.keys.shape == (n, spec.shape[1] * spec.shape[2])
    rows = np.array([3, n // 2, n - 1])
    k = np.arange(1, spec.shape[-1] + 1)
    q = spec[rows] * np.exp(2j * np.pi * k * 123.0 / 360.0)
    m = ix.search(q.astype(np.complex64), 16)
    best = m.index[np.arange(3), m.score.argmax(axis=1)]  # stage 2 decides among the candidates
    assert np.all(np.abs(best - rows) <= 1)
    assert np.all(m.score.max(axis=1) > 0.99)
