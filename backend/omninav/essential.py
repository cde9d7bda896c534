"""Essential: how many matched bearing pairs each RANSAC sample's essential matrix explains.

verify.essential_fit draws samples of 8 matched pairs (b1[i], b2[i]: unit bearings of one
keypoint in two panoramas) and keeps the sample whose essential matrix E (b2^T E b1 = 0) has the
most inliers: pairs within an angle of their epipolar plane. `sample_counts` does the per-sample
work for a batch of samples: the null vector of the sample's 8 x 9 rows (b2 (x) b1), by Householder
reflections as LAPACK's QR takes it; the nearest matrix with two equal singular values, from the
eigenvectors of E^T E (Jacobi rotations); and its inliers among every pair.

Compiled by numba, in loops: NumPy's batched LAPACK spends ~3 us of per-matrix overhead on a 9 x 8
QR and ~1.6 us on a 3 x 3 SVD, so a fit of 500 samples cost ~3.7 ms, ~7 times what these loops
take. The arithmetic is verify._essential's: a sample of 8 distinct pairs gives the same matrix to
~1e-12 and the same inliers. A sample that repeats a pair (rank 7: a plane of null vectors) gets
one of that plane's vectors, not necessarily the one LAPACK's rounding picks. No library fits
batches of essential matrices to bearing vectors from Python (OpenGV has no maintained wheels;
OpenCV's takes pinhole points, and a panorama's bearings cover the sphere).
"""

from __future__ import annotations

import math

import numpy as np

from .jit import compiled


@compiled
def _null_vector(a: np.ndarray, rows: np.ndarray, m: np.ndarray, v: np.ndarray, y: np.ndarray) -> None:
    """y <- a unit vector orthogonal to the 8 rows a[rows] (9 long): the last column of Q in the
    QR of their transpose (m, 9 x 8, and v, the 8 reflectors, are scratch)."""
    for i in range(8):
        for j in range(9):
            m[j, i] = a[rows[i], j]
    for k in range(8):
        norm2 = 0.0
        for i in range(k, 9):
            norm2 += m[i, k] * m[i, k]
        norm = math.sqrt(norm2)
        for i in range(9):
            v[k, i] = 0.0
        if norm == 0.0:
            continue
        alpha = -norm if m[k, k] >= 0.0 else norm
        for i in range(k, 9):
            v[k, i] = m[i, k]
        v[k, k] -= alpha
        vn = 0.0
        for i in range(k, 9):
            vn += v[k, i] * v[k, i]
        vn = math.sqrt(vn)
        if vn == 0.0:
            continue
        for i in range(k, 9):
            v[k, i] /= vn
        for j in range(k + 1, 8):
            s = 0.0
            for i in range(k, 9):
                s += v[k, i] * m[i, j]
            for i in range(k, 9):
                m[i, j] -= 2.0 * s * v[k, i]
    for i in range(9):
        y[i] = 0.0
    y[8] = 1.0
    for k in range(7, -1, -1):
        s = 0.0
        for i in range(k, 9):
            s += v[k, i] * y[i]
        for i in range(k, 9):
            y[i] -= 2.0 * s * v[k, i]


@compiled
def _two_equal(e: np.ndarray, s: np.ndarray, w: np.ndarray, out: np.ndarray) -> bool:
    """out <- U diag(1, 1, 0) V^T of e's SVD (the nearest essential matrix), from the eigenvectors
    of e^T e by cyclic Jacobi rotations (s, w scratch); False, out zero, where e has rank under 2.
    Squaring e squares its conditioning: the SVD's matrix to ~1e-12 where the second singular
    value is over 1e-3 of the first, to ~1e-8 at 1e-4 (a sample's matrix that near rank 1
    explains few pairs either way)."""
    for i in range(3):
        for j in range(3):
            t = 0.0
            for k in range(3):
                t += e[k, i] * e[k, j]
            s[i, j] = t
            w[i, j] = 1.0 if i == j else 0.0
    for _ in range(12):
        off = s[0, 1] * s[0, 1] + s[0, 2] * s[0, 2] + s[1, 2] * s[1, 2]
        diag = s[0, 0] * s[0, 0] + s[1, 1] * s[1, 1] + s[2, 2] * s[2, 2]
        if off <= 1e-32 * diag:
            break
        for p, q in ((0, 1), (0, 2), (1, 2)):
            apq = s[p, q]
            if apq == 0.0:
                continue
            theta = (s[q, q] - s[p, p]) / (2.0 * apq)
            t = (1.0 if theta >= 0.0 else -1.0) / (abs(theta) + math.sqrt(theta * theta + 1.0))
            c = 1.0 / math.sqrt(t * t + 1.0)
            sn = t * c
            for k in range(3):
                skp, skq = s[k, p], s[k, q]
                s[k, p], s[k, q] = c * skp - sn * skq, sn * skp + c * skq
            for k in range(3):
                spk, sqk = s[p, k], s[q, k]
                s[p, k], s[q, k] = c * spk - sn * sqk, sn * spk + c * sqk
            for k in range(3):
                wkp, wkq = w[k, p], w[k, q]
                w[k, p], w[k, q] = c * wkp - sn * wkq, sn * wkp + c * wkq
    least = 0
    for i in (1, 2):
        if s[i, i] < s[least, least]:
            least = i
    for i in range(3):
        for j in range(3):
            out[i, j] = 0.0
    for col in range(3):
        if col == least:
            continue
        if s[col, col] <= 0.0:
            for i in range(3):
                for j in range(3):
                    out[i, j] = 0.0
            return False
        sigma = math.sqrt(s[col, col])
        for i in range(3):  # u = e v / sigma, and out += u v^T
            u = (e[i, 0] * w[0, col] + e[i, 1] * w[1, col] + e[i, 2] * w[2, col]) / sigma
            for j in range(3):
                out[i, j] += u * w[j, col]
    return True


@compiled
def _sample_counts(
    a: np.ndarray, b1: np.ndarray, b2: np.ndarray, picks: np.ndarray, sin2: float
) -> tuple[np.ndarray, np.ndarray]:
    n, samples = b1.shape[0], picks.shape[0]
    counts = np.zeros(samples, np.int64)
    es = np.zeros((samples, 3, 3))
    m, v, y = np.zeros((9, 8)), np.zeros((8, 9)), np.zeros(9)
    s, w = np.zeros((3, 3)), np.zeros((3, 3))
    t1, t2 = np.ascontiguousarray(b1.T), np.ascontiguousarray(b2.T)  # each component contiguous
    for h in range(samples):
        _null_vector(a, picks[h], m, v, y)
        e = es[h]
        if not _two_equal(y.reshape(3, 3), s, w, e):
            continue
        e00, e01, e02 = e[0, 0], e[0, 1], e[0, 2]
        e10, e11, e12 = e[1, 0], e[1, 1], e[1, 2]
        e20, e21, e22 = e[2, 0], e[2, 1], e[2, 2]
        c = 0
        for i in range(n):  # (branch-free over the bearings' components: the compiler vectorises it)
            p, q, r = t1[0, i], t1[1, i], t1[2, i]
            x = e00 * p + e01 * q + e02 * r
            yy = e10 * p + e11 * q + e12 * r
            z = e20 * p + e21 * q + e22 * r
            d = x * t2[0, i] + yy * t2[1, i] + z * t2[2, i]
            c += 1 if d * d < sin2 * (x * x + yy * yy + z * z) else 0
        counts[h] = c
    return counts, es


def sample_counts(
    a: np.ndarray, b1: np.ndarray, b2: np.ndarray, picks: np.ndarray, inlier_deg: float
) -> tuple[np.ndarray, np.ndarray]:
    """(n, 9) rows b2 (x) b1 of n matched unit bearings (n, 3) each, (S, 8) samples of row numbers
    -> ((S,) each sample's essential matrix's inliers: pairs within `inlier_deg` of their epipolar
    plane; (S, 3, 3) those matrices, zero where a sample's rows leave no matrix of rank 2).
    ValueError on shapes that do not fit or a row number outside the pairs."""
    a, b1, b2 = (np.ascontiguousarray(x, np.float64) for x in (a, b1, b2))
    picks = np.ascontiguousarray(picks, np.int64)
    n = len(b1)
    # (the compiled loops do not check their indices)
    if a.shape != (n, 9) or b1.shape != (n, 3) or b2.shape != (n, 3) or picks.ndim != 2 or picks.shape[1] != 8:
        raise ValueError(f"sample_counts: rows {a.shape}, bearings {b1.shape} {b2.shape}, samples {picks.shape}")
    if picks.size and (picks.min() < 0 or picks.max() >= n):
        raise ValueError(f"sample_counts: a sample's row outside 0..{n - 1}")
    sin2 = math.sin(math.radians(inlier_deg)) ** 2
    return _sample_counts(a, b1, b2, picks, sin2)
