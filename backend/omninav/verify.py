"""Verify: local features check the global search's candidate places, and may move the answer.

The global curves compare whole panoramas; a metre or two of viewpoint, people or another light
moves every curve at once. Local features do not: ORB keypoints and their binary descriptors on
the unwarped panorama (every elevation the lens sees, STEP_DEG a pixel), matched with Lowe's ratio
test, then checked for one rigid motion between the two panoramas: an essential matrix on the
keypoints' bearing vectors, by RANSAC. A place whose modelled panorama shares many such inliers
with the clip's last frame was seen from near where the user stands.

A venue modelled with `local_features` set (the `verified` preset) stores, for one modelled frame
every SPACING_M of each walk, its keypoints' bearings and descriptors (`LocalFeatures`, in the
generation beside the spectra: docs/formats.md). A single clip that brings its last frame's
local features (found in its frames: the CLI, a video or frames sent to the server, an
evaluation walk; or carried by a version-2 record) is then verified. The global answer's place
is scored first, by its inliers with the clip's last frame; with SETTLED_INLIERS it stands, and
nothing else is compared (most answers: a request then costs one place, not up to PLACES).
Otherwise the candidate places are the global answer's, then the global search's (the last
frame's shared best, then the clip's other frames' and the last WIDE_FRAMES frames' own WIDE_K
best, a search run only then; one a PLACE_M, at most PLACES), each scored where it could
change the verdict by its ratio-test matches (counted first over every SCREEN-th keypoint,
where one far short is left at a third of a scan; a place with the matches of those that
cleared a bar on the tuning families is left so 1 time in 500 or fewer); the answer moves
to the place with the most, where it has at least MIN_INLIERS and at least `local_margin` times
the global answer's place's. Where none of these moves the answer and the global answer's own
place is not confirmed (fewer than MIN_INLIERS), the venue votes: each of the clip's keypoints
votes for the places that hold one of its VOTE_K nearest stored descriptors (Hamming, brute
force over every place: 0.35-1.2 ms a place on the 2-core machines measured, so a venue of more
than VOTE_MAX_PLACES has no vote), and the VOTE_PLACES best-voted not yet scored are scored
too. An answer that moves is then refined: the REFINE_PLACES nearest places within PLACE_M of
it not yet scored are scored, and the one with the most inliers is the answer (the candidates
are one a PLACE_M, so a moved answer could otherwise sit up to PLACE_M from a better-seen place).
A moved answer is said with MOVED_CONFIDENCE: below "sure" until a calibration has enough moved
answers to fit (the tuning families moved 4 answers in 532 clips; docs/decisions.md). An answer
that stands is "confirmed" where its own place has MIN_INLIERS or more, else "unconfirmed": said
with at most UNCONFIRMED_CONFIDENCE (below "sure": the keypoints looked and found nothing there).
The answer says which (`verified`, docs/formats.md); a clip with under 8 keypoints, or whose
answer's video has no stored places, is not verified (nothing was compared).

A place's descriptors are matched by a compiled exact Hamming scan (hamming.py: vector popcounts,
half faiss's time for a place), the whole venue's for the vote by faiss's (`nearest`). The
essential-matrix RANSAC is our own (8-point samples, their matrices and inliers counted in
compiled loops: essential.py; the refits in NumPy): OpenCV's `findEssentialMat` takes pinhole
image points, and a panorama's bearings cover the sphere (half of them behind any pinhole); the
libraries that take bearing vectors (OpenGV) have no maintained Python wheels.
"""

from __future__ import annotations

import functools
from collections.abc import Callable
from dataclasses import dataclass
from typing import Literal

import cv2
import numpy as np

from .index import Matches
from .lens import Lens
from .spectrum import LocalQuery, bearing_vectors
from .unwarp import UnwarpMap, build_map, panorama_elevations

STEP_DEG = 0.25  # the local panorama's pixel, in degrees of azimuth and elevation
EL_TOP, EL_BOTTOM = 60.0, -80.0  # elevations looked at; the rows the lens sees are kept
SPACING_M = 0.5  # one modelled frame with local features every this far along a walk
PLACE_M = 2.0  # candidates closer than this are one place
PLACES = 20  # candidate places verified a clip
WIDE_K = 64  # the last WIDE_FRAMES frames' own search, this many candidates each (0: none)
WIDE_FRAMES = 3
RATIO = 0.8  # Lowe's ratio test on Hamming distances
VOTE_K = 4  # each keypoint's nearest stored descriptors over the venue, for the vote
VOTE_HAMMING = 64  # a nearest descriptor votes only this close (of 256 bits)
VOTE_PLACES = 8  # the venue's best-voted places scored where the global search's are not confirmed
VOTE_MAX_PLACES = 1000  # a venue with more places has no vote (up to ~1 ms a place: a request's cost bounded)
REFINE_PLACES = 8  # at most this many places beside a moved answer refine it (the nearest first)
MIN_KEYPOINTS = 8  # a clip with fewer keypoints is not compared (the essential matrix's 8-point sample)
MIN_INLIERS = 20  # fewer prove nothing (two unrelated panoramas' 900 keypoints share up to ~19)
# The global answer's place with this many inliers settles it: it stands without the other
# candidates compared (most answers cost one place, not up to PLACES). Chosen on the tuning families: the most a moved
# answer's own place had there was 52 (a bare ring corridor's look-alike 4.3 m off; the right
# place 187), and at 40 that move is lost (decisions.md)
SETTLED_INLIERS = 60
# A candidate that must clear a bar of inliers (MIN_INLIERS or more) has its ratio-test matches
# counted over every SCREEN-th query keypoint first, and is not fitted where SCREEN times that
# count is under SCREEN_SHARE of the bar. Inliers never exceed matches, and the 25 places that
# cleared a bar on the tuning families (of 1,074 compared) held 1.6x it in matches or more
# (median 3.7x; 45 % of them inliers), their third 1.5x or more: at 1.6x a bar of MIN_INLIERS, a
# third of the keypoints count under a sixth of it with probability 0.002 (binomial), at 2x
# 1e-4, at a bar of 60 under 1e-7. Those that fall that short (a fifth of the tuning families'
# candidates, half of the foreign pack's) cost a third of a scan (a scan: ~0.5 ms, 900 x 900)
SCREEN = 3
SCREEN_SHARE = 0.5
RANSAC_ITERS = 500  # at most; drawn RANSAC_BATCH at a time until one clean sample is RANSAC_SURE
RANSAC_BATCH = 100
RANSAC_SURE = 0.99
REFITS = 3  # LO-RANSAC's refits of the best hypothesis on its inliers
INLIER_DEG = 0.5  # a match's angular distance from its epipolar plane, to count as an inlier
MOVED_CONFIDENCE = 0.75  # a moved answer's confidence: below aggregate.SURE (not yet calibrated)
UNCONFIRMED_CONFIDENCE = 0.75  # at most this for an answer its own place's keypoints do not confirm
# A verified answer's heading is the curves' (stage 2's phase correlation, to a degree or two)
# unless the keypoints' turn from the place's modelled frame says otherwise by more than this:
# then theirs. The curves fail whole, by a crossing corridor or the corridor's other end (90 or
# 180 deg); the keypoints' turn is only as good as the place's modelled heading, which at a corner
# is its walk leg's, up to 45 deg from where the camera looked (decisions.md)
HEADING_AGREE_DEG = 60.0
DESCRIPTOR_BYTES = 32  # ORB's
FAST_THRESHOLD = 20  # ORB's FAST corner threshold (OpenCV's default)
DIM_SHARE = 0.5
# A frame with fewer than DIM_SHARE of the keypoints asked for at FAST_THRESHOLD (a dim or bare one: at a quarter of
# the light it keeps a tenth, and its own place seldom reaches MIN_INLIERS) is detected again at
# this threshold, which keeps about half (chosen on the tuning families with their queries dimmed;
# a lower threshold on every frame lost on the held-out families' bare corridors, decisions.md).
# The phone's worker follows the same rule (web/src/worker/local.ts).
FAST_DIM = 10

Outcome = Literal["moved", "confirmed", "unconfirmed"]  # what verification made of an answer

LOCAL_DTYPE = np.dtype([("video", "<i4"), ("frame", "<i4"), ("start", "<i8"), ("count", "<i4")])


@dataclass
class LocalFeatures:
    """A venue's stored local features: per place (a modelled frame, by video and frame number)
    its slice of the keypoints' unit bearings (x = cos e sin a, y = cos e cos a, z = sin e) and
    ORB descriptors."""

    places: np.ndarray  # (P,) LOCAL_DTYPE
    bearings: np.ndarray  # (T, 3) float16
    descriptors: np.ndarray  # (T, 32) uint8

    @staticmethod
    def empty() -> LocalFeatures:
        return LocalFeatures(
            np.zeros(0, LOCAL_DTYPE), np.zeros((0, 3), np.float16), np.zeros((0, DESCRIPTOR_BYTES), np.uint8)
        )

    def span(self, place: int) -> slice:
        """A place's rows of `bearings` and `descriptors`."""
        p = self.places[place]
        return slice(int(p["start"]), int(p["start"]) + int(p["count"]))

    def of(self, place: int) -> LocalQuery:
        """A place's (bearings float32, descriptors)."""
        s = self.span(place)
        return np.asarray(self.bearings[s], np.float32), np.asarray(self.descriptors[s])

    def keep(self, mask: np.ndarray) -> LocalFeatures:
        """The places where `mask` holds, their keypoints packed anew."""
        places = np.asarray(self.places)[mask]
        parts = [slice(int(p["start"]), int(p["start"]) + int(p["count"])) for p in places]
        out = places.copy()
        out["start"] = np.concatenate([[0], np.cumsum(places["count"])[:-1]]) if len(places) else []
        return LocalFeatures(
            out,
            np.concatenate([self.bearings[s] for s in parts]) if parts else LocalFeatures.empty().bearings,
            np.concatenate([self.descriptors[s] for s in parts]) if parts else LocalFeatures.empty().descriptors,
        )

    def __add__(self, other: LocalFeatures) -> LocalFeatures:
        return concat([self, other])

    def nbytes(self) -> int:
        return int(self.places.nbytes + self.bearings.nbytes + self.descriptors.nbytes)


def concat(parts: list[LocalFeatures]) -> LocalFeatures:
    """Several LocalFeatures as one, in order (each part's places' slices moved along)."""
    if not parts:
        return LocalFeatures.empty()
    places = np.concatenate([np.asarray(p.places) for p in parts])
    offset = np.cumsum([0] + [len(p.bearings) for p in parts[:-1]])
    places["start"] += np.repeat(offset, [len(p.places) for p in parts])
    return LocalFeatures(
        places,
        np.concatenate([np.asarray(p.bearings) for p in parts]),
        np.concatenate([np.asarray(p.descriptors) for p in parts]),
    )


def one_place(video: int, frame: int, bearings: np.ndarray, descriptors: np.ndarray) -> LocalFeatures:
    places = np.zeros(1, LOCAL_DTYPE)
    places[0] = (video, frame, 0, len(bearings))
    return LocalFeatures(places, bearings.astype(np.float16), descriptors.astype(np.uint8))


@dataclass(frozen=True)
class PanoramaMap:
    """The local panorama of a lens: its remap, and its rows' elevations and columns' azimuths
    (degrees). `fixed` is the remap as OpenCV's fixed-point pair (cv2.convertMaps, CV_16SC2): what
    frames are read through, here and in the phone's worker, the same pixels on both."""

    remap: UnwarpMap
    el: np.ndarray
    az: np.ndarray
    fixed: tuple[np.ndarray, np.ndarray]


COARSE = 4  # the local panorama's remap is computed every COARSE pixels and interpolated


@functools.lru_cache(maxsize=8)
def panorama_map(lens: Lens) -> PanoramaMap:
    """The local panorama of `lens` (the rows every column of which the lens sees), cached. Its
    remap is unwarp.build_map's on a grid COARSE times coarser (the lens's directions every degree),
    interpolated bilinearly: a clip-on lens's profile is corrected per clip, so every clip has its
    own map, and the full grid's directions cost ~60 ms (the coarse one ~4 ms; over a degree the
    map's curvature moves a pixel by < 0.01 px)."""
    step_c = STEP_DEG * COARSE
    width = int(round(360.0 / STEP_DEG))
    el_c = panorama_elevations(EL_TOP, EL_BOTTOM, step_c)
    coarse = build_map(lens, el_c, width // COARSE)
    seen = coarse.valid.all(axis=1)
    az = (np.arange(width) + 0.5) * STEP_DEG
    if seen.sum() < 2:
        empty = np.zeros((0, width), np.float32)
        none = (np.zeros((0, width, 2), np.int16), np.zeros((0, width), np.uint16))
        return PanoramaMap(
            UnwarpMap(empty, empty, np.zeros(0, np.float32), empty.astype(bool), 0), np.zeros(0), az, none
        )
    el_c = el_c[seen]
    # one coarse column beyond each end, the azimuth wrapping round: column j + 1 looks at (j + 0.5) * step_c
    x, y = (np.concatenate([m[seen][:, -1:], m[seen], m[seen][:, :1]], 1) for m in (coarse.map_x, coarse.map_y))
    el = panorama_elevations(float(el_c[0]), float(el_c[-1]), STEP_DEG)
    u, v = np.meshgrid(az / step_c + 0.5, (el_c[0] - el) / step_c)
    u, v = u.astype(np.float32), v.astype(np.float32)
    mx = cv2.remap(x, u, v, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
    my = cv2.remap(y, u, v, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
    remap = UnwarpMap(mx, my, el.astype(np.float32), np.ones(mx.shape, bool), cv2.BORDER_CONSTANT)
    return PanoramaMap(remap, el, az, cv2.convertMaps(mx, my, cv2.CV_16SC2))


def _none() -> LocalQuery:
    """No keypoints."""
    return np.zeros((0, 3), np.float32), np.zeros((0, DESCRIPTOR_BYTES), np.uint8)


def grey_panorama(frame: np.ndarray, pm: PanoramaMap) -> np.ndarray:
    """A BGR frame -> its grey local panorama: the frame made grey, then remapped through the
    fixed-point tables (a third of the colour remap's work, and a third of float tables' time; the
    phone's worker, web/src/worker/local.ts, takes the same steps)."""
    grey = cv2.cvtColor(frame, cv2.COLOR_BGR2GRAY)
    return cv2.remap(grey, *pm.fixed, cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT)


def detect(frame: np.ndarray, lens: Lens, n_features: int) -> LocalQuery:
    """A frame -> ((n, 3) float32 unit bearings, (n, 32) uint8 ORB descriptors) of its panorama."""
    pm = panorama_map(lens)
    if len(pm.el) < 32:  # a lens that sees no band of elevations all round
        return _none()
    pano = grey_panorama(frame, pm)
    kp, des = cv2.ORB.create(nfeatures=n_features, fastThreshold=FAST_THRESHOLD).detectAndCompute(pano, None)
    if len(kp) < DIM_SHARE * n_features:  # a dim frame: its weaker corners too
        kp, des = cv2.ORB.create(nfeatures=n_features, fastThreshold=FAST_DIM).detectAndCompute(pano, None)
    if des is None or not kp:
        return _none()
    pt = np.array([k.pt for k in kp])
    az = np.interp(pt[:, 0], np.arange(len(pm.az)), pm.az)
    el = np.interp(pt[:, 1], np.arange(len(pm.el)), pm.el)
    return bearing_vectors(az, el), des


def nearest(query: np.ndarray, stored: np.ndarray, k: int) -> tuple[np.ndarray, np.ndarray]:
    """Each query descriptor's k nearest stored descriptors, exactly (Hamming, brute force):
    ((n, k) bit distances, ascending; (n, k) their rows in `stored`; past its end -1, at distance
    2**31 - 1). faiss's popcount scan: OpenCV's brute-force matcher takes 4-5x as long here and
    refuses 2**18 rows. One OpenMP thread, set in the calling thread (OpenMP's count is per
    thread, and each of the server's request threads calls): requests are the server's
    parallelism (as its BLAS pool, server/serve.py), and a 900 x 900 scan gains a tenth from two."""
    import faiss

    faiss.omp_set_num_threads(1)
    out: tuple[np.ndarray, np.ndarray] = faiss.knn_hamming(
        np.ascontiguousarray(query, np.uint8), np.ascontiguousarray(stored, np.uint8), k
    )
    return out


def ratio_matches(d1: np.ndarray, d2: np.ndarray) -> np.ndarray:
    """(m, 2) index pairs (into d1, d2) passing Lowe's ratio test (Hamming, brute force:
    hamming.two_nearest)."""
    from .hamming import two_nearest

    if len(d1) == 0 or len(d2) < 2:  # (a keypoint's test needs two stored descriptors)
        return np.zeros((0, 2), np.int64)
    two = two_nearest(d1, d2)
    ok = np.flatnonzero(two[:, 0] < RATIO * two[:, 1])
    return np.stack([ok, two[ok, 2]], axis=1)


def _essential(a: np.ndarray) -> np.ndarray:
    """(..., m, 9) rows of b2 (x) b1 -> (..., 3, 3) the least-squares essential matrix of each set,
    made rank 2 (two equal singular values)."""
    if a.shape[-2] == 8:  # a sample's null vector: the one direction QR's Q adds to 8 rows (2x eigh's speed)
        q, _ = np.linalg.qr(np.swapaxes(a, -1, -2), mode="complete")
        e = q[..., :, -1].reshape(*a.shape[:-2], 3, 3)
    else:  # least squares: the least eigenvalue's vector
        _, vec = np.linalg.eigh(np.swapaxes(a, -1, -2) @ a)
        e = vec[..., :, 0].reshape(*a.shape[:-2], 3, 3)
    u, _, vt2 = np.linalg.svd(e)
    out: np.ndarray = u @ (np.array([1.0, 1.0, 0.0])[:, None] * vt2)
    return out


def _inliers(e: np.ndarray, b1: np.ndarray, b2: np.ndarray) -> np.ndarray:
    """(..., 3, 3) essential matrices -> (..., n) whether each pair lies within INLIER_DEG of its
    epipolar plane."""
    # the epipolar planes' normals in camera 2, one component at a time (contiguous: 2x the speed)
    x, y, z = np.ascontiguousarray(np.moveaxis(e @ b1.T, -2, 0))
    dot = x * b2[:, 0] + y * b2[:, 1] + z * b2[:, 2]  # (the sine of the angle, times the normal's length)
    out: np.ndarray = dot * dot < np.sin(np.radians(INLIER_DEG)) ** 2 * (x * x + y * y + z * z)
    return out


def _samples_needed(inlier_share: float) -> int:
    """Samples of 8 after which one clean sample has been drawn with RANSAC_SURE probability, were
    `inlier_share` of the pairs inliers."""
    clean = inlier_share**8
    if clean <= 0.0:
        return RANSAC_ITERS
    if clean >= 1.0:
        return 1
    return int(np.ceil(np.log(1.0 - RANSAC_SURE) / np.log(1.0 - clean)))


def essential_fit(b1: np.ndarray, b2: np.ndarray, seed: int = 0) -> tuple[np.ndarray, np.ndarray | None]:
    """Which matched bearing pairs (b1[i], b2[i]) are consistent with one essential matrix
    (b2^T E b1 = 0), and that matrix fitted to them by least squares (None under 8 inliers):
    8-point hypotheses RANSAC_BATCH at a time (at most RANSAC_ITERS, fewer where the best so far
    makes a clean sample already RANSAC_SURE), then the best one refit on its inliers while that
    finds more (LO-RANSAC: with a third of the matches inliers, few 8-point samples are clean, and
    the refit recovers what a near-clean sample's matrix misses). A pair is an inlier within
    INLIER_DEG of its epipolar plane. Seeded: the same pairs give the same inliers. Where fewer
    than about 40 % of the matches are inliers, RANSAC_ITERS samples of 8 seldom hold a clean one
    and the count comes out low (a minimal solver for upright cameras would not)."""
    n = len(b1)
    none = np.zeros(n, bool), None
    if n < 8:
        return none
    b1, b2 = np.asarray(b1, np.float64), np.asarray(b2, np.float64)
    if not (np.isfinite(b1).all() and np.isfinite(b2).all()):
        return none
    from .essential import sample_counts

    a = np.einsum("ni,nj->nij", b2, b1).reshape(n, 9)
    rng = np.random.default_rng(seed)
    best = np.zeros(n, bool)
    done = 0
    while done < min(RANSAC_ITERS, _samples_needed(best.sum() / n)):
        pick = rng.integers(0, n, (RANSAC_BATCH, 8))  # (a repeated pair makes one arbitrary hypothesis)
        counts, es = sample_counts(a, b1, b2, pick, INLIER_DEG)
        top = _inliers(es[int(counts.argmax())], b1, b2)
        if top.sum() > best.sum():
            best = top
        done += RANSAC_BATCH
    for _ in range(REFITS):
        if best.sum() < 8:
            break
        again = _inliers(_essential(a[best]), b1, b2)
        if again.sum() <= best.sum():
            break
        best = again
    return (best, _essential(a[best])) if best.sum() >= 8 else (best, None)


def turn_deg(e: np.ndarray) -> float:
    """An essential matrix (b2^T E b1 = 0) -> how far camera 1 is turned clockwise from camera 2,
    degrees in (-180, 180]: the azimuth in camera 2 of camera 1's forward direction, through the
    upright one of E's two rotations (the other turns the world upside down: the cameras here
    are held within tilts of a few degrees; only a baseline near vertical, which a held camera
    does not make, leaves the two alike)."""
    u, _, vt = np.linalg.svd(e)
    u, vt = u * np.sign(np.linalg.det(u)), vt * np.sign(np.linalg.det(vt))
    w = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
    r = max((u @ w @ vt, u @ w.T @ vt), key=lambda m: float(m[2, 2]))
    fwd = r @ np.array([0.0, 1.0, 0.0])  # the bearing convention: azimuth 0 along +y, clockwise to +x
    deg = float(np.degrees(np.arctan2(fwd[0], fwd[1])))
    return 180.0 if deg == -180.0 else deg


def candidate_rows(m: Matches, xy: np.ndarray, first: int | None = None, wide: Matches | None = None) -> list[int]:
    """A clip's candidate venue rows, one a place (PLACE_M apart), at most PLACES: `first` (the
    global answer's row: its place is always scored), then the last frame's matches by score, then
    every other frame's and the `wide` search's, by score."""
    last = m.index[-1][np.argsort(-m.score[-1])]
    more_idx, more_score = [m.index[:-1].ravel()], [m.score[:-1].ravel()]
    if wide is not None:
        more_idx.append(np.asarray(wide.index).ravel())
        more_score.append(np.asarray(wide.score).ravel())
    idx, score = np.concatenate(more_idx), np.concatenate(more_score)
    rest = idx[np.argsort(-score, kind="stable")]
    ranked = np.concatenate([[] if first is None else [first], last, rest]).astype(np.int64)
    _, at = np.unique(ranked, return_index=True)  # each row once, where it ranks first
    order = ranked[np.sort(at)]
    # greedily, by rank: a row is kept unless within PLACE_M of one kept before it (each kept row
    # strikes out the rows near it: a loop over the kept places, not over every ranked row)
    free = np.ones(len(order), bool)
    pts = xy[order]
    kept: list[int] = []
    while len(kept) < PLACES and free.any():
        i = int(free.argmax())
        kept.append(int(order[i]))
        free &= np.hypot(*(pts - pts[i]).T) >= PLACE_M
    return kept


def place_of_rows(frames: np.ndarray, local: LocalFeatures) -> np.ndarray:
    """(N,) for each venue frame the stored place of its video at or before it (at most SPACING_M
    behind, as modelling spaces them), else the first after it; -1 where its video has none."""
    pv = np.asarray(local.places["video"], np.int64)
    pf = np.asarray(local.places["frame"], np.int64)
    order = np.lexsort((pf, pv))
    key = (pv[order] << 32) + pf[order]
    rv, rf = np.asarray(frames["video"], np.int64), np.asarray(frames["frame"], np.int64)
    out = np.full(len(rv), -1, np.int64)
    if not len(key):
        return out
    rkey = (rv << 32) + rf
    at = np.searchsorted(key, rkey, side="right") - 1  # the last place at or before
    before = (at >= 0) & (pv[order][np.maximum(at, 0)] == rv)
    after = np.minimum(at + 1, len(key) - 1)
    later = ~before & (pv[order][after] == rv)
    out[before] = order[at[before]]
    out[later] = order[after[later]]
    return out


@dataclass(frozen=True)
class PlaceIndex:
    """A venue's places as the vote and the refinement need them (made once a generation):
    `owner` (T,) the place of each stored keypoint, `rows` (P,) each place's venue row (-1: none),
    `xy` (P, 2) its position (NaN where it has no row)."""

    owner: np.ndarray
    rows: np.ndarray
    xy: np.ndarray


def place_index(frames: np.ndarray, local: LocalFeatures, xy: np.ndarray) -> PlaceIndex:
    """Each stored keypoint's place, and each place's venue row (its video's frame) and position."""
    places = np.asarray(local.places)
    owner = np.full(len(local.descriptors), -1, np.int32)
    for p, (s, n) in enumerate(zip(places["start"], places["count"], strict=True)):
        owner[int(s) : int(s) + int(n)] = p
    rkey = (np.asarray(frames["video"], np.int64) << 32) + np.asarray(frames["frame"], np.int64)
    order = np.argsort(rkey, kind="stable")
    pkey = (places["video"].astype(np.int64) << 32) + places["frame"].astype(np.int64)
    at = np.minimum(np.searchsorted(rkey[order], pkey), max(len(rkey) - 1, 0))
    found = (at < len(rkey)) & (rkey[order][at] == pkey) if len(rkey) else np.zeros(len(pkey), bool)
    rows = np.where(found, order[at] if len(rkey) else -1, -1).astype(np.int64)
    pxy = np.where(found[:, None], np.asarray(xy, np.float64)[np.maximum(rows, 0)], np.nan)
    return PlaceIndex(owner, rows, pxy)


def place_votes(descriptors: np.ndarray, local: LocalFeatures, owner: np.ndarray) -> np.ndarray:
    """(P,) each place's votes: the query keypoints (`descriptors`) one of whose VOTE_K nearest
    stored descriptors, within VOTE_HAMMING bits, is that place's (a keypoint votes once a place)."""
    if len(descriptors) == 0 or len(local.descriptors) == 0:
        return np.zeros(len(local.places), np.int64)
    dist, idx = nearest(descriptors, local.descriptors, VOTE_K)
    place = np.sort(np.where((dist <= VOTE_HAMMING) & (idx >= 0), owner[np.maximum(idx, 0)], -1), axis=1)
    once = np.ones(place.shape, bool)  # a keypoint votes once a place
    once[:, 1:] = place[:, 1:] != place[:, :-1]
    out: np.ndarray = np.bincount(place[once & (place >= 0)], minlength=len(local.places))
    return out


@dataclass
class Verdict:
    """What verification made of a clip: its candidate rows, their inliers (0 for a place with too
    few matches to change the verdict: not fitted), and the row the answer moves to (None: the
    global answer stands)."""

    rows: list[int]
    inliers: list[int]
    moved_to: int | None
    scored: bool = True  # whether the global answer's own place was compared with the clip
    # the essential matrix of the answer's place (the moved-to one's, else the global one's) where
    # it is moved or confirmed: how far the clip is turned from that place (turn_deg)
    essential: np.ndarray | None = None

    @property
    def outcome(self) -> Outcome | None:
        """What verification made of the answer: "moved", "confirmed" (the global answer's place
        has MIN_INLIERS), "unconfirmed", or None where its place could not be compared and
        nothing moved (not verified)."""
        if self.moved_to is not None:
            return "moved"
        if not self.scored:
            return None
        return "confirmed" if self.inliers[0] >= MIN_INLIERS else "unconfirmed"


def checked_confidence(outcome: Outcome | None, model: float) -> float:
    """An answer's confidence, given what verification made of it (None: not verified) and the
    venue's model's confidence for it."""
    if outcome == "moved":
        return MOVED_CONFIDENCE
    if outcome == "unconfirmed":
        return min(model, UNCONFIRMED_CONFIDENCE)
    return model


def _fitted(query: LocalQuery, local: LocalFeatures, place: int, bar: float) -> tuple[int, np.ndarray | None]:
    """A place's inliers with the query and their essential matrix, or (0, None) where its
    ratio-test matches number fewer than `bar` (inliers never exceed matches: such a place cannot
    clear the bar, so it is not fitted), or, for a bar of MIN_INLIERS or more, where the matches
    of every SCREEN-th query keypoint fall far short of it (SCREEN_SHARE)."""
    qb, qd = query
    s = local.span(place)
    vd = np.asarray(local.descriptors[s])  # (the bearings only where it is fitted)
    if bar >= MIN_INLIERS:
        third = ratio_matches(qd[::SCREEN], vd)
        if SCREEN * len(third) < SCREEN_SHARE * bar:
            return 0, None
        mt = _with_the_rest(third, qd, vd)
    else:
        mt = ratio_matches(qd, vd)
    if len(mt) < max(bar, 8):
        return 0, None
    vb = np.asarray(local.bearings[s], np.float32)
    ok, e = essential_fit(qb[mt[:, 0]], vb[mt[:, 1]])
    return int(ok.sum()), e


def _with_the_rest(third: np.ndarray, qd: np.ndarray, vd: np.ndarray) -> np.ndarray:
    """The ratio-test matches of every query keypoint, given `third`, those of every SCREEN-th:
    the others' scanned and merged in query order (a keypoint's test looks at no other keypoint,
    so these are ratio_matches(qd, vd), for two thirds of its scan)."""
    others = np.flatnonzero(np.arange(len(qd)) % SCREEN != 0)
    rest = ratio_matches(qd[others], vd)
    both = np.concatenate([third * [SCREEN, 1], np.stack([others[rest[:, 0]], rest[:, 1]], axis=1)])
    out: np.ndarray = both[np.argsort(both[:, 0], kind="stable")]
    return out


def _bar(inl: list[int], margin: float) -> float:
    """The matches another place needs to be worth fitting: MIN_INLIERS, more than the global
    answer's place's inliers (inl[0]) and `margin` times them, more than the best so far."""
    return max(MIN_INLIERS, inl[0] + 1, max(inl[1:], default=0) + 1, margin * inl[0])


def _moves(inl: list[int], margin: float) -> bool:
    best = max(inl)
    return best >= MIN_INLIERS and best > inl[0] and best >= margin * inl[0]


def verify(
    query: LocalQuery,
    m: Matches,
    xy: np.ndarray,
    local: LocalFeatures,
    place_of: np.ndarray,
    global_row: int,
    margin: float,
    wide: Callable[[], Matches | None] | None = None,
    index: PlaceIndex | None = None,
) -> Verdict:
    """The clip's last frame's local features (`query`: bearings, descriptors) against the global
    answer's place, which stands where it has SETTLED_INLIERS; else against every candidate place
    (the global answer's first; `wide`: a wider search, run only then); with the venue's `index`,
    the vote where these confirm nothing and the refinement of a moved answer."""
    if len(query[0]) < MIN_KEYPOINTS:  # nothing to compare
        return Verdict([global_row], [0], None, scored=False)
    inl: list[int] = []
    ess: list[np.ndarray | None] = []  # each fitted place's essential matrix

    def fit(p: int, bar: float) -> None:
        n, e = (0, None) if p < 0 else _fitted(query, local, p, bar)
        inl.append(n)
        ess.append(e)

    # the global answer's place (the only candidate within PLACE_M of it) is counted whenever
    # RANSAC can run: it sets the bar; another is fitted only where it could clear it
    fit(int(place_of[global_row]), 8)
    scored = int(place_of[global_row]) >= 0
    if inl[0] >= SETTLED_INLIERS:
        return Verdict([global_row], inl, None, scored, ess[0])
    rows = candidate_rows(m, xy, global_row, None if wide is None else wide())
    for r in rows[1:]:
        fit(int(place_of[r]), _bar(inl, margin))
    seen = {int(place_of[r]) for r in rows}
    vote = len(local.places) <= VOTE_MAX_PLACES and not _moves(inl, margin) and inl[0] < MIN_INLIERS
    if index is not None and vote:
        votes = place_votes(query[1], local, index.owner)
        voted = [int(p) for p in np.argsort(-votes, kind="stable") if votes[p] > 0 and index.rows[p] >= 0]
        for p in [p for p in voted if p not in seen][:VOTE_PLACES]:
            rows.append(int(index.rows[p]))
            fit(p, _bar(inl, margin))
            seen.add(p)
    if not _moves(inl, margin):
        return Verdict(rows, inl, None, scored, ess[0] if inl[0] >= MIN_INLIERS else None)
    if index is not None:  # refined: the places beside the moved answer, each fitted only to beat it
        at = xy[rows[int(np.argmax(inl))]]
        near = np.flatnonzero(np.hypot(*(index.xy - at).T) < PLACE_M)
        near = near[np.argsort(np.hypot(*(index.xy[near] - at).T), kind="stable")]
        for p in [int(p) for p in near if int(p) not in seen][:REFINE_PLACES]:
            rows.append(int(index.rows[p]))
            fit(p, max(inl) + 1)
            seen.add(p)
    best = int(np.argmax(inl))
    return Verdict(rows, inl, rows[best], scored, ess[best])
