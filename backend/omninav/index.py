"""The batched index: every query frame of a clip against every venue frame in one array pass.

Stage 1 (retrieval): FFT magnitudes are rotation-invariant, so the inner product of two frames'
magnitude vectors ranks venue frames without knowing the heading. Because every frame's spectrum
has unit energy, that inner product is also an *upper bound* of the two frames' best phase
correlation (Cauchy-Schwarz per harmonic), so it prunes without discarding a frame that could
verify better than the ones kept, up to the top-k cut. One matrix product scores the clip against
the whole venue: the paper's three levels of parallelism (frames x venue frames x harmonics).

Stage 2 (verification): for the kept candidates only, the phase correlation over all rotations
(heading.py) gives the rotation-compensated score and the relative heading.

Shared candidates (`search(..., groups=...)`): the frames of one second of a clip were filmed a
metre or so apart, so a place that stage 1 kept for one of them is a place for all of them. Each
frame of a group is verified against every candidate that stage 1 kept for any frame of the group
and keeps the k that verify best. Stage 1 ranks by magnitudes alone, and a frame that people,
another hour's light or a tilt spoil there can drop its right place from its own top k while its
neighbours in time keep it: the phase verification, which sees the shape and not only its
spectrum's magnitudes, then finds it (docs/benchlog.md, "Shared candidates": held-out 1 s clips
94.0 % -> 95.6 % within 2 m). Ranking the group's candidates by stage 1's bound first and verifying
only the best of them lost most of that gain, so all of them are verified: a 1 s clip's frames
verify 3-8 times the candidates a lone frame does (26-132 a frame on the venue families before
the shortlist below; more since), the cross-power as one complex matrix product per harmonic
(verify_all).

The shortlist: with shared candidates, stage 1 keeps more a frame (`shortlist`, 32) than each
frame keeps after verification (k, 16). In a corridor of identical doors every frame's magnitudes
look alike, and the right place, which verifies at 0.95, can rank 20th by magnitude for every
frame of the second. Keeping 32 after verification instead adds as many weak supporters and
rivals to the clip's aggregation as it finds places, and was worse (docs/benchlog.md, "The
shortlist"). With projected keys the projection still shortlists PREFILTER*k, and the exact
magnitudes choose the 32 among them: a wider projected pass cost a tenth of a millisecond at
8,000 frames and chose the same 32.

The code is written once over the array namespace `xp`: NumPy here, CuPy on a GPU. Results leave
as NumPy at the `search` boundary (they are small: frames x candidates).
"""

from __future__ import annotations

from dataclasses import dataclass, fields
from types import ModuleType
from typing import Any

import numpy as np

from .arrays import device_namespace, namespace_of, to_numpy
from .heading import cross_correlation, peak, relative_heading


@dataclass
class Matches:
    """Per query frame, its k candidates: (Q, k) arrays, NumPy."""

    index: np.ndarray  # venue frame row
    coarse: np.ndarray  # stage-1 magnitude score
    score: np.ndarray  # stage-2 phase-correlation score (cosine)
    heading: np.ndarray  # absolute heading of the query frame if it is at that venue frame (deg)

    def rows(self, sel: Any) -> Matches:
        """The matches of some of the query frames (a slice, an index or a boolean array)."""
        return Matches(*(np.asarray(getattr(self, f.name))[sel] for f in fields(self)))


def magnitude_keys(spec: Any) -> Any:
    """(N, C, K) complex -> (N, C*K) float32 magnitudes: the rotation-invariant search keys."""
    xp = namespace_of(spec)
    return xp.ascontiguousarray(xp.abs(spec).reshape(spec.shape[0], -1).astype(xp.float32))


def key_basis(keys: Any, dims: int, sample: int = 65536) -> Any:
    """(N, D) keys -> (D, dims) projection onto the top eigenvectors of the keys' second moment.

    Uncentred on purpose: it is the best rank-`dims` approximation of the inner products that
    stage 1 ranks by, so a large venue is searched with a fraction of the memory traffic.
    """
    xp = namespace_of(keys)
    step = max(1, keys.shape[0] // sample)
    x = keys[::step].astype(xp.float64)
    _, vec = xp.linalg.eigh(x.T @ x)
    return xp.ascontiguousarray(vec[:, ::-1][:, :dims].astype(xp.float32))


def top_k(scores: Any, k: int, ordered: bool = True) -> tuple[Any, Any]:
    """(Q, N) -> indices and values of the k largest per row, best first (ties in any order);
    `ordered=False` skips the final sort, for shortlists.

    For long rows a threshold from a strided sample first discards almost everything in one
    comparison pass (much cheaper than a partition of the whole row); rows where the threshold
    kept fewer than k fall back to the exact partition.
    """
    xp = namespace_of(scores)
    q, n = scores.shape
    k = min(k, n)
    if n >= 65536 and k <= 256:
        step = n // 16384
        thr = sample_threshold(scores[:, ::step], k, n)
        rows, cols = xp.nonzero(scores >= thr[:, None])
        got = select(rows, cols, scores[rows, cols], q, k, ordered)
        if got is not None:
            return got
    if k < n:
        part = xp.argpartition(scores, n - k, axis=1)[:, n - k :]
    else:
        part = xp.broadcast_to(xp.arange(n), scores.shape).copy()
    vals = xp.take_along_axis(scores, part, axis=1)
    if not ordered:  # a shortlist: any order will do
        return part, vals
    order = xp.argsort(-vals, axis=1)
    return xp.take_along_axis(part, order, axis=1), xp.take_along_axis(vals, order, axis=1)


def sample_threshold(sample: Any, k: int, n: int) -> Any:
    """(Q, m) scores of a strided sample of rows of n -> (Q,) a score that at least k of each
    row's n exceed, but not many more: the cut of a comparison pass that keeps a row's k best.

    A row's k best are about k m / n of the sample; the cut is that many plus six standard
    deviations (at least 8) from the top, so that a row left with fewer than k is never seen.
    """
    xp = namespace_of(sample)
    m = sample.shape[1]
    mean = k * m / n
    r = min(m - 1, max(8, int(np.ceil(mean + 6.0 * np.sqrt(mean)))))
    return -xp.partition(-sample, r, axis=1)[:, r]


def select(
    rows: Any, cols: Any, vals: Any, q: int, k: int, ordered: bool = True, by_row: bool = True
) -> tuple[Any, Any] | None:
    """The survivors of a threshold, (row, column, score) triples (`by_row`: in row order, as
    nonzero() gives them; else in any) -> each row's k best (top_k's), or None when a row has
    fewer than k (the threshold was too high)."""
    xp = namespace_of(vals)
    counts = xp.bincount(rows, minlength=q)
    if int(counts.min()) < k:
        return None
    if not by_row:
        order = xp.argsort(rows, kind="stable")
        rows, cols, vals = rows[order], cols[order], vals[order]
    width = int(counts.max())
    starts = xp.cumsum(counts) - counts
    pos = xp.arange(rows.shape[0]) - starts[rows]
    cand = xp.zeros((q, width), dtype=cols.dtype)
    v = xp.full((q, width), -xp.inf, dtype=vals.dtype)
    cand[rows, pos] = cols
    v[rows, pos] = vals
    part, val = top_k(v, k, ordered)
    return xp.take_along_axis(cand, part, axis=1), val


def first_scores(qk: Any, first: Any) -> Any:
    """(Q, d) query keys, (N, d) venue keys -> (Q, N) inner products, C-ordered: the venue's keys as
    the first factor of the product (scan_top says why)."""
    return namespace_of(first).ascontiguousarray((first @ qk.T).T)


def scan_top(qk: Any, first: Any, k: int, sample: Any | None = None, chunk: int | None = None) -> tuple[Any, Any]:
    """(Q, d) query keys, (N, d) venue keys -> each query's k best venue frames by inner product
    and their scores ((Q, k), in any order): stage 1's first pass, top_k(qk @ first.T, k) fused.

    The product is made `chunk` venue frames at a time, each chunk's scores compared at once
    with a threshold from `sample` (m, d), a strided sample of first's rows, so that the (Q, N)
    score matrix is never written out: at a million frames it is 40 MB, written and read again,
    against the keys' 128 MB read once; on a few thousand frames the comparison pass is also
    3-4x cheaper than a partition of each row. Rows that the threshold leaves with fewer than k
    survivors (never seen: the threshold keeps about eight times k) are scored again in full.

    The venue's keys are frame-major, (N, d), and each chunk's product is (chunk, Q): OpenBLAS
    streams the long operand a quarter faster as the first factor of its product than as the
    second (bench/search_speed.py, docs/decisions.md "The first pass, frame-major").
    """
    xp = namespace_of(first)
    q, n = qk.shape[0], first.shape[0]
    k = min(k, n)
    if sample is None:
        return top_k(first_scores(qk, first), k, ordered=False)
    thr = sample_threshold((sample @ qk.T).T, k, n)
    if not bool((thr > 0).all()):  # (inner products of magnitudes: never seen)
        return scan_top(qk, first, k)
    chunk = chunk or n
    # each query scaled by its threshold, so that one scalar comparison cuts every column
    qk_t = xp.ascontiguousarray((qk / thr[:, None]).T)
    rows, cols, vals = [], [], []
    for a in range(0, n, chunk):
        sc = (first[a : a + chunk] @ qk_t).reshape(-1)  # (w, Q), frame-major
        at = xp.flatnonzero(sc >= 1.0)  # frame (at // Q), query (at % Q)
        f = at // q
        r = at - f * q
        rows.append(r)
        cols.append(f + a)
        vals.append(sc[at] * thr[r])
    r, c, v = (xp.concatenate(x) for x in (rows, cols, vals)) if len(rows) > 1 else (rows[0], cols[0], vals[0])
    got = select(r, c, v, q, k, ordered=False, by_row=False)
    return got if got is not None else scan_top(qk, first, k)


PREFILTER = 8  # shortlist factor of the projected first pass
SAMPLE = 4096  # at most this many venue frames sampled for stage 1's threshold (scan_top), ...
SAMPLE_STEP = 8  # ... at least every this many, ...
SCAN_ABOVE = 2048  # ... on venues of more frames than this (below, 224 unprojected dims: a partition is as cheap)
SCAN_CHUNK = 16384  # venue frames a CPU scores at a time in stage 1 (10 query frames: 0.7 MB of scores)


def _best_first(idx: Any, val: Any) -> tuple[Any, Any]:
    """(Q, k) candidates and scores in any order -> sorted best first."""
    xp = namespace_of(val)
    order = xp.argsort(-val, axis=1)
    return xp.take_along_axis(idx, order, axis=1), xp.take_along_axis(val, order, axis=1)


def index_arrays(spectra: Any, key_dims: int = 0) -> dict[str, Any]:
    """The search arrays derived from a generation's spectra: written once at modelling time so
    that every server worker memory-maps one copy instead of computing its own.

    keys (N, D): the full magnitude keys, the exact stage-1 score and, on a venue of few frames,
    what the first pass multiplies by; on a large one, projected keys `first` (N, d) and their
    `basis` (D, d): a cheap first pass over every frame, re-ranked exactly below.
    """
    xp = namespace_of(spectra)
    keys = magnitude_keys(spectra)
    out = {"keys": keys}
    if 0 < key_dims < keys.shape[1]:
        out["basis"] = key_basis(keys, key_dims)
        out["first"] = xp.ascontiguousarray(keys @ out["basis"])
    return out


def first_keys(arrays: dict[str, Any]) -> Any:
    """The first pass's (N, d) keys of index_arrays(): `first`, else the keys themselves; a
    generation written before the first pass was frame-major has (d, N) `keys_t` (its transpose
    serves, a little slower)."""
    if "first" in arrays:
        return arrays["first"]
    if "basis" in arrays:
        return arrays["keys_t"].T
    return arrays["keys"]


class Index:
    """Search structure of one venue generation, resident on the chosen device."""

    def __init__(
        self,
        spectra: np.ndarray,
        headings: np.ndarray,
        device: str | None = None,
        xp: ModuleType | None = None,
        key_dims: int = 0,
        arrays: dict[str, np.ndarray] | None = None,
    ):
        """`arrays`: precomputed index_arrays(spectra, key_dims) (e.g. memory-mapped); else computed."""
        self.xp = xp or device_namespace(device)
        self.spec = self.xp.asarray(np.ascontiguousarray(spectra))
        if arrays is None or ("basis" in arrays) != (0 < key_dims < self.spec.shape[1] * self.spec.shape[2]):
            arrays = index_arrays(self.spec, key_dims)
        self.keys = self.xp.asarray(arrays["keys"])
        self.basis = self.xp.asarray(arrays["basis"]) if "basis" in arrays else None
        self.first = self.xp.asarray(first_keys(arrays))  # (N, d): what the first pass multiplies by
        self.heading = self.xp.asarray(np.asarray(headings, np.float32))
        self.n = int(spectra.shape[0])
        # stage 1's scan (scan_top): a strided sample of the first pass's keys for its threshold,
        # and on a CPU chunks whose scores stay in the cache (a GPU scores the venue in one pass)
        step = max(SAMPLE_STEP, self.n // SAMPLE)
        self.sample = self.xp.ascontiguousarray(self.first[::step]) if self.n > SCAN_ABOVE else None
        self.chunk = SCAN_CHUNK if self.xp is np else None

    def coarse(
        self, q_spec: Any, k: int, exclude: tuple[Any, Any] | None = None, prefilter: int | None = None
    ) -> tuple[Any, Any]:
        """Stage 1: (Q, C, K) -> (Q, k) candidate rows and magnitude scores, best first, on the device.

        With projected keys, the projection shortlists PREFILTER*k frames per query frame
        (`prefilter` where given, at least k) and the full magnitude inner product re-ranks them: the
        memory traffic of d dims, the ranking of all C*K. `exclude`: per query frame, a range
        [lo, hi) of venue rows it may not match ((Q,) arrays; leave-one-out, quality.py); such a
        row comes back only if nothing else is left, with score -inf.
        """
        xp = self.xp
        kq = magnitude_keys(xp.asarray(q_spec))
        first_q = kq if self.basis is None else kq @ self.basis
        s = k if self.basis is None else max(k, prefilter or PREFILTER * k)
        if exclude is None:
            short, first_v = scan_top(first_q, self.first, s, self.sample, self.chunk)
        else:
            short, first_v = top_k(self._masked(first_scores(first_q, self.first), exclude), s, ordered=False)
        if self.basis is None:
            return _best_first(short, first_v)
        # the exact scores of the shortlists: every frame's against the clip's union of them in one
        # product (a clip's frames shortlist much the same venue frames)
        u, inv = xp.unique(short, return_inverse=True)
        exact = (self.keys[u] @ kq.T)[inv.reshape(short.shape), xp.arange(short.shape[0])[:, None]]
        if exclude is not None:
            exact = xp.where(xp.isfinite(first_v), exact, -xp.inf)
        best, val = top_k(exact, k)
        return xp.take_along_axis(short, best, axis=1), val

    def _masked(self, scores: Any, exclude: tuple[Any, Any] | None) -> Any:
        """Scores (Q, N), fresh from a product: the excluded ranges set to -inf, in place (they
        are narrow: O(Q x width), not a pass over the whole matrix)."""
        if exclude is None:
            return scores
        xp = self.xp
        lo, hi = (xp.asarray(v) for v in exclude)
        width = int((hi - lo).max()) if lo.shape[0] else 0
        if width > 0:
            cols = lo[:, None] + xp.arange(width)[None, :]
            keep = cols < hi[:, None]
            rows = xp.broadcast_to(xp.arange(scores.shape[0])[:, None], cols.shape)
            scores[rows[keep], cols[keep]] = -xp.inf
        return scores

    def verify(self, q_spec: Any, idx: Any) -> tuple[Any, Any]:
        """Stage 2: phase correlation of each query frame with its candidates -> score, heading."""
        q = self.xp.asarray(q_spec)
        # 8 shift samples per harmonic: the parabola then lands well under a tenth of a degree
        n = max(64, 8 * int(q.shape[-1]))
        rel, score = relative_heading(q[:, None], self.spec[idx], n_shifts=n)
        return score, (self.heading[idx] + rel) % 360.0

    def verify_all(self, q_spec: Any, rows: Any) -> tuple[Any, Any]:
        """Stage 2 for frames against one shared set of candidates: (G, C, K) query spectra and
        (U,) venue rows -> (G, U) scores and headings, as verify() gives each pair. The
        cross-power summed over curves is one (G, C) x (C, U) complex product per harmonic."""
        xp = self.xp
        q = xp.asarray(q_spec)
        v = self.spec[rows]  # (U, C, K)
        x = xp.matmul(q.transpose(2, 0, 1), xp.conj(v).transpose(2, 1, 0))  # (K, G, U)
        n = max(64, 8 * int(q.shape[-1]))
        rel, score = peak(cross_correlation(x.transpose(1, 2, 0), n))
        return score, (self.heading[rows][None, :] + rel) % 360.0

    def shared(
        self,
        q_spec: Any,
        idx: Any,
        groups: np.ndarray,
        k: int,
        exclude: tuple[Any, Any] | None,
        own: bool = False,
        own_coarse: Any | None = None,
    ) -> tuple[Matches, Matches | None]:
        """Stage 2 with shared candidates: each frame verified against every stage-1 candidate of
        its group (`groups` (Q,) labels); (Q, s) idx from coarse(), best first, s >= k (the
        shortlist: search's `shortlist`).
        -> (each frame's k best of them, best first; its own k best stage-1 candidates as
        verified, for search_shared, which excludes nothing). `own_coarse`: coarse()'s scores of
        idx, where the caller has them (else they are scored again)."""
        xp = self.xp
        q = xp.asarray(q_spec)
        qn = q.shape[0]
        k = min(int(k), int(idx.shape[1]))  # coarse() keeps min(shortlist, venue frames)
        mine = idx[:, :k]  # a frame's own candidates: its k best by stage 1, however long the shortlist
        groups = np.asarray(groups)
        labels = np.unique(groups)
        parts = []
        for g in labels:
            # (one group, a clip of a second, as every locate has: its frames as they are)
            r = xp.asarray(np.flatnonzero(groups == g)) if len(labels) > 1 else slice(None)
            u = xp.unique(idx[r].ravel())  # at least k: each frame's own candidates are distinct rows
            score, heading = self.verify_all(q[r], u)
            ar = xp.arange(score.shape[0])[:, None]
            got = []
            if own:  # the frame's own candidates among them (u is sorted)
                at = xp.searchsorted(u, mine[r])
                got = [score[ar, at], heading[ar, at]]
            if exclude is not None:  # a row a frame may not match never wins over one it may
                lo, hi = (xp.asarray(e)[r][:, None] for e in exclude)
                score = xp.where((u[None, :] >= lo) & (u[None, :] < hi), -xp.inf, score)
            best, val = top_k(score, k)
            parts.append((r, [u[best], val, heading[ar, best], *got]))
        if len(parts) == 1:
            out = parts[0][1]
        else:
            out = [xp.zeros((qn, k), dtype=a.dtype) for a in parts[0][1]]
            for r, arrays in parts:
                for o, a in zip(out, arrays, strict=True):
                    o[r] = a
        out_i, out_s, out_h = out[:3]
        # the magnitude bound of each kept pair (Matches.coarse): cheap for k rows a frame
        kq = magnitude_keys(q)
        coarse = (self.keys[out_i] @ kq[:, :, None])[..., 0]
        if exclude is not None:  # kept for want of others (an excluded row): supports nothing
            bad = ~xp.isfinite(out_s)
            out_s = xp.where(bad, -1.0, out_s)
            coarse = xp.where(bad, -xp.inf, coarse)
        best_m = Matches(to_numpy(out_i), to_numpy(coarse), to_numpy(out_s), to_numpy(out_h))
        if not own:  # (a plain search's: the tracker's own columns are not made for nothing)
            return best_m, None
        own_c = (self.keys[mine] @ kq[:, :, None])[..., 0] if own_coarse is None else own_coarse[:, :k]
        return best_m, Matches(to_numpy(mine), to_numpy(own_c), to_numpy(out[3]), to_numpy(out[4]))

    def shortlisted(
        self, q_spec: Any, k: int, shortlist: int | None, exclude: tuple[Any, Any] | None = None
    ) -> tuple[Any, Any]:
        """Stage 1 of a shared search: each frame's `shortlist` (at least k) best by magnitude;
        with projected keys the projection still shortlists PREFILTER*k ("The shortlist"), or
        twice a shortlist longer than half that, so that the exact magnitudes still choose."""
        s = max(k, shortlist or k)
        return self.coarse(q_spec, s, exclude, prefilter=max(PREFILTER * k, 2 * s))

    def search_shared(
        self, q_spec: np.ndarray, k: int, groups: np.ndarray, shortlist: int | None = None
    ) -> tuple[Matches, Matches]:
        """search() with `groups`, and each frame's own k best stage-1 candidates as verified
        beside its shared best (what the tracker reads: tracking.Tracker.emission)."""
        idx, val = self.shortlisted(q_spec, k, shortlist)
        best, own = self.shared(q_spec, idx, groups, k, None, own=True, own_coarse=val)
        assert own is not None
        return best, own

    def search(
        self,
        q_spec: np.ndarray,
        k: int,
        exclude: tuple[Any, Any] | None = None,
        groups: np.ndarray | None = None,
        shortlist: int | None = None,
    ) -> Matches:
        """(Q, C, K) query spectra -> each frame's k candidates, verified. `groups` (Q,) labels:
        the frames of a group (a second of one clip) share their candidates (`shared`): stage 1
        then keeps `shortlist` (>= k) a frame, all of the group's verified, and each frame keeps
        its k best; None: every frame verifies its own k. `exclude`: coarse()'s."""
        if groups is not None:
            idx, _ = self.shortlisted(q_spec, k, shortlist, exclude)
            return self.shared(q_spec, idx, groups, k, exclude)[0]
        idx, coarse = self.coarse(q_spec, k, exclude)
        score, heading = self.verify(q_spec, idx)
        if exclude is not None:  # an excluded row kept for want of others supports nothing
            score = self.xp.where(self.xp.isfinite(coarse), score, -1.0)
        return Matches(to_numpy(idx), to_numpy(coarse), to_numpy(score), to_numpy(heading))


def sequential_search(q_spec: np.ndarray, spectra: np.ndarray) -> np.ndarray:
    """The paper's sequential CPU baseline: a Python loop, one venue frame at a time.

    Returns each query frame's best venue frame by magnitude distance. Kept for benchmarks only.
    """
    qm = np.abs(q_spec).reshape(q_spec.shape[0], -1)
    best = np.zeros(len(qm), np.int64)
    for i, q in enumerate(qm):
        bd, bj = np.inf, -1
        for j in range(spectra.shape[0]):
            d = float(np.sum((np.abs(spectra[j]).ravel() - q) ** 2))
            if d < bd:
                bd, bj = d, j
        best[i] = bj
    return best
