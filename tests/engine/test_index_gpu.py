"""The index on a GPU (CuPy) against the NumPy reference, the way faiss tests its GPU indexes: the
full candidate lists equal (two candidates whose scores tie may trade places), scores and headings
close. Every path the search takes: plain keys, projected keys (key_dims > 0: a shortlist re-ranked
exactly), and the sampled-threshold top-k that rows of 65,536 frames or more go through.

Marked `gpu` (run them alone with `pytest -m gpu`); skipped without CuPy and a CUDA device. CuPy
comes with the `gpu` extra: `.venv/bin/pip install -e 'backend[gpu]'`.
"""

import numpy as np
import pytest

from omninav.arrays import device_namespace
from omninav.index import Index, index_arrays, magnitude_keys, top_k
from omninav.spectrum import quantise

HAS_GPU = device_namespace("auto") is not np

pytestmark = [pytest.mark.gpu, pytest.mark.skipif(not HAS_GPU, reason="needs CuPy and a CUDA device")]

SCORE_TOL = 1e-4  # float32 GEMMs summed in another order
HEADING_TOL = 0.05  # degrees


def walk_spectra(n: int, seed: int, c: int = 6, k: int = 32, rank: int = 12) -> np.ndarray:
    """(n, c, k) quantised unit-energy spectra that drift slowly from frame to frame, as along a
    corridor (neighbours look alike: the candidate lists are crowded with near misses), and close
    to low-rank, as real curve spectra are (so projected keys still find the frame)."""
    rng = np.random.default_rng(seed)
    latent = np.cumsum(rng.normal(size=(n, rank)) * 0.05, axis=0) + rng.normal(size=(1, rank))
    mix = rng.normal(size=(rank, c * k)) + 1j * rng.normal(size=(rank, c * k))
    spec = (latent @ mix).reshape(n, c, k) + 0.05 * rng.normal(size=(n, c, k))
    spec /= np.sqrt((np.abs(spec) ** 2).sum(axis=(1, 2), keepdims=True))
    return quantise(spec.astype(np.complex64))


def queries(spec: np.ndarray, rows: list[int], seed: int) -> np.ndarray:
    """Venue frames seen again, turned (each by its own angle) and a little noisy."""
    rng = np.random.default_rng(seed)
    turn = rng.uniform(0, 360, len(rows))
    k = np.arange(1, spec.shape[-1] + 1)
    q = spec[rows] * np.exp(2j * np.pi * k * turn[:, None, None] / 360.0)
    q = q * (1 + 0.02 * rng.normal(size=q.shape))
    return quantise(q.astype(np.complex64))


def assert_same_candidates(ref_idx, ref_val, idx, val, full) -> None:
    """(Q, k) candidate lists: the same ids in the same order, except where the reference scores
    two candidates alike (within SCORE_TOL), which may then trade places or swap in at the cut.

    `full` (Q, N) is the reference's score of every frame: a candidate that differs from the
    reference's at some position must score what the reference's does there."""
    assert idx.shape == ref_idx.shape
    assert all(len(set(r)) == len(r) for r in idx.tolist()), "a candidate listed twice"
    assert np.allclose(val, ref_val, atol=SCORE_TOL)
    differ = idx != ref_idx
    got = np.take_along_axis(full, idx, axis=1)
    assert np.allclose(got[differ], ref_val[differ], atol=SCORE_TOL), "a candidate differs where nothing ties"


PATHS = {  # n frames, key_dims
    "plain": (5000, 0),
    "projected": (5000, 32),
    "sampled": (70000, 0),  # top_k thresholds a strided sample for rows of >= 65,536
    "sampled-projected": (70000, 32),  # and so does the projected shortlist (k = PREFILTER * 16)
}


@pytest.mark.parametrize("path", PATHS)
def test_gpu_search_matches_numpy(path):
    n, key_dims = PATHS[path]
    spec = walk_spectra(n, seed=6)
    head = np.random.default_rng(7).uniform(0, 360, n).astype(np.float32)
    # as a server does: the arrays are made once at modelling time (NumPy) and loaded onto the device
    arrays = index_arrays(spec, key_dims)
    cpu = Index(spec, head, device="cpu", key_dims=key_dims, arrays=arrays)
    gpu = Index(spec, head, device="gpu", key_dims=key_dims, arrays=arrays)
    assert (cpu.basis is None) == (key_dims == 0) and (gpu.basis is None) == (key_dims == 0)
    q = queries(spec, [10, n // 2, n - 1, 1234], seed=8)
    a, b = cpu.search(q, 16), gpu.search(q, 16)

    full = magnitude_keys(q) @ arrays["keys"].T  # the exact stage-1 score of every frame
    assert_same_candidates(a.index, a.coarse, b.index, b.coarse, full)
    same = a.index == b.index
    assert np.allclose(a.score[same], b.score[same], atol=SCORE_TOL)
    dh = np.mod(a.heading[same] - b.heading[same] + 180, 360) - 180
    assert np.allclose(dh, 0, atol=HEADING_TOL)
    assert all(r in c for r, c in zip([10, n // 2, n - 1, 1234], a.index.tolist(), strict=True))  # found


@pytest.mark.parametrize("shortlist,key_dims", [(16, 0), (32, 0), (32, 32)])
def test_gpu_shared_search_matches_numpy(shortlist, key_dims):
    """A clip's frames sharing their candidates (index.Index.shared), with the shortlist and
    projected keys: the same kept scores, and the tracker's own candidates the same rows."""
    n = 5000
    spec = walk_spectra(n, seed=6)
    head = np.random.default_rng(7).uniform(0, 360, n).astype(np.float32)
    arrays = index_arrays(spec, key_dims)
    cpu = Index(spec, head, device="cpu", key_dims=key_dims, arrays=arrays)
    gpu = Index(spec, head, device="gpu", key_dims=key_dims, arrays=arrays)
    q = queries(spec, [10, 11, 12, 2000, 2001], seed=8)
    groups = np.array([0, 0, 0, 1, 1])
    a, b = (ix.search(q, 16, groups=groups, shortlist=shortlist) for ix in (cpu, gpu))
    (_, own_a), (_, own_b) = (ix.search_shared(q, 16, groups, shortlist) for ix in (cpu, gpu))
    assert own_a.index.shape == own_b.index.shape == (5, 16)
    assert (own_a.index == own_b.index).mean() > 0.9  # (near-ties at stage 1's cut may swap)
    # best first on both: the same leading values (a near-tie at stage 1's cut may change a
    # group's union, and so the tail of its kept scores)
    assert np.allclose(a.score[:, :3], b.score[:, :3], atol=SCORE_TOL)
    same = a.index == b.index
    assert same[:, :3].mean() > 0.9  # (near-ties may swap places)
    dh = np.mod(a.heading[same] - b.heading[same] + 180, 360) - 180
    assert np.allclose(dh, 0, atol=HEADING_TOL)


@pytest.mark.parametrize("ordered", [True, False])
def test_gpu_top_k_matches_numpy_on_long_rows(ordered):
    """The sampled-threshold top-k alone, on long correlated rows (many near-equal neighbours)."""
    import cupy

    rng = np.random.default_rng(9)
    s = np.cumsum(rng.normal(size=(4, 200_000)), axis=1).astype(np.float32)
    s[2, 123_456] = s.max() + 5
    ref_idx, ref_val = top_k(s, 16)
    idx, val = (cupy.asnumpy(x) for x in top_k(cupy.asarray(s), 16, ordered=ordered))
    if not ordered:  # a shortlist in any order: compare it sorted best first
        order = np.argsort(-val, axis=1, kind="stable")
        idx, val = np.take_along_axis(idx, order, 1), np.take_along_axis(val, order, 1)
    assert_same_candidates(ref_idx, ref_val, idx, val, s)
    assert idx[2, 0] == 123_456
