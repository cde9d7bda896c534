"""A first measurement for local features (issue 43), not a product path: does verifying the
global search's candidates with ORB keypoints on the unwarped panoramas pick the right place
more often than the global curves alone, on the foreign pack?

Per query clip (its last frame: the truth's pose), as `omninav locate` answers it with the
default settings: the clip's candidate places (the last frame's shared best, distinct places at
least PLACE_M apart, at most PLACES), each a modelled frame of the walk decoded from model.mp4.
The query frame and each candidate frame are unwarped to a full panorama (every elevation the lens
sees, 0.25 degree a pixel), ORB finds keypoints and binary descriptors there (OpenCV), matches
pass Lowe's ratio test, and an essential matrix between the two panoramas' bearing vectors
(8-point algorithm in a RANSAC, both cameras upright or not) counts the inliers. The answer
becomes the candidate with the most inliers where it has at least MIN_INLIERS and more than
a margin times the global answer's place's (each of MARGINS printed); else the global answer
stands. Printed per venue: within 1 m / 2 m,
the global answer beside, how often each was kept, and the ORB cost a frame.

    python -m bench.local_probe [--pack DIR] [--venues inst21,var22h] [--own long-bare-0,...] [--features 2000]

Written as an experiment: its findings, not its code, go to docs/decisions.md.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from bench.common import machine
from bench.foreign import PACK, modelled, pack_venues, query_spectra
from bench.scoring import conf_of
from omninav.calib.correct import FIRST
from omninav.calib.lens_fit import corrected_lens
from omninav.lens import Catadioptric, load_lens
from omninav.locate import Locator, clip_frames
from omninav.unwarp import build_map, panorama_elevations, unwarp

PLACE_M = 2.0  # candidates closer than this are one place
PLACES = 10  # candidate places verified a clip
MIN_INLIERS = 20
STEP_DEG = 0.25
RATIO = 0.8


def panorama_map(lens: Any) -> tuple[Any, np.ndarray, np.ndarray]:
    """The full panorama every elevation the lens sees, and its rows' elevations and columns'
    azimuths (degrees)."""
    el = panorama_elevations(60.0, -80.0, STEP_DEG)
    width = int(round(360.0 / STEP_DEG))
    m = build_map(lens, el, width)
    seen = (m.map_x >= 0).all(axis=1)
    el = el[seen]
    m = build_map(lens, el, width)
    az = (np.arange(width) + 0.5) * STEP_DEG
    return m, el, az


def features(orb: Any, frame: np.ndarray, pmap: tuple[Any, np.ndarray, np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """(n, 3) unit bearing vectors (x = cos e sin a, y = cos e cos a, z = sin e: azimuth a from the
    panorama's first column, elevation e up) and (n, 32) ORB descriptors of a frame's panorama."""
    m, el, az = pmap
    pano = cv2.cvtColor(unwarp(frame, m), cv2.COLOR_BGR2GRAY)
    kp, des = orb.detectAndCompute(pano, None)
    if des is None or not kp:
        return np.zeros((0, 3)), np.zeros((0, 32), np.uint8)
    pt = np.array([k.pt for k in kp])
    a = np.radians(np.interp(pt[:, 0], np.arange(len(az)), az))
    e = np.radians(np.interp(pt[:, 1], np.arange(len(el)), el))
    return np.stack([np.cos(e) * np.sin(a), np.cos(e) * np.cos(a), np.sin(e)], 1), des


def ratio_matches(d1: np.ndarray, d2: np.ndarray) -> np.ndarray:
    """(m, 2) index pairs passing Lowe's ratio test (Hamming, brute force)."""
    if len(d1) < 2 or len(d2) < 2:
        return np.zeros((0, 2), np.int64)
    bf = cv2.BFMatcher(cv2.NORM_HAMMING)
    out = [(a.queryIdx, a.trainIdx) for a, b in bf.knnMatch(d1, d2, k=2) if a.distance < RATIO * b.distance]
    return np.array(out, np.int64).reshape(-1, 2)


def essential_inliers(b1: np.ndarray, b2: np.ndarray, rng: np.random.Generator, iters: int = 300) -> int:
    """Most matches consistent with one essential matrix (b2^T E b1 = 0, bearing vectors), by an
    8-point RANSAC; the angular residual threshold 0.5 degree."""
    n = len(b1)
    if n < 8:
        return 0
    a = np.einsum("ni,nj->nij", b2, b1).reshape(n, 9)
    thr = np.radians(0.5)
    best = 0
    for _ in range(iters):
        s = rng.choice(n, 8, replace=False)
        _, _, vt = np.linalg.svd(a[s])
        e = vt[-1].reshape(3, 3)
        u, _, vt2 = np.linalg.svd(e)
        e = u @ np.diag([1.0, 1.0, 0.0]) @ vt2
        eb1 = b1 @ e.T  # (n, 3): epipolar plane normals in camera 2
        r = np.abs(np.einsum("ni,ni->n", b2, eb1)) / np.maximum(np.linalg.norm(eb1, axis=1), 1e-12)
        best = max(best, int((r < np.sin(thr)).sum()))
    return best


def model_frames(video: Path, wanted: set[int]) -> dict[int, np.ndarray]:
    """The walk's frames by index, decoded in one pass."""
    cap = cv2.VideoCapture(str(video))
    out, i, last = {}, 0, max(wanted)
    while i <= last:
        ok, f = cap.read()
        if not ok:
            break
        if i in wanted:
            out[i] = f
        i += 1
    cap.release()
    return out


def places(m: Any, xy: np.ndarray) -> list[int]:
    """The clip's candidate rows (every frame's shared best; the last frame's first), best
    first, one a place."""
    last = m.index[-1][np.argsort(-m.score[-1])]
    rest = m.index[:-1].ravel()[np.argsort(-m.score[:-1].ravel())]
    rows = np.concatenate([last, rest])
    kept: list[int] = []
    for r in rows:
        if all(np.hypot(*(xy[r] - xy[k])) >= PLACE_M for k in kept):
            kept.append(int(r))
        if len(kept) == PLACES:
            break
    return kept


def decide(loc: Locator, e: Any, cand: list[int], inl: list[int], truth_xy: np.ndarray) -> dict[str, Any]:
    """The verified answer of one clip beside the global one, and what each candidate scored."""
    g = np.array([e.x, e.y])
    at = int(np.argmax(inl)) if inl else -1
    near_g = [i for i, r in enumerate(cand) if np.hypot(*(loc.xy[r] - g)) < PLACE_M]
    g_inl = max((inl[i] for i in near_g), default=0)
    return {
        "global_m": float(np.hypot(*(g - truth_xy))),
        "global_inliers": g_inl,
        "inliers": inl,
        "cand_m": [float(np.hypot(*(loc.xy[r] - truth_xy))) for r in cand],
        "best": at,
    }


def verified_m(row: dict[str, Any], margin: float) -> float:
    """The verified answer's error: the candidate with the most inliers where it has at least
    MIN_INLIERS and `margin` times the global answer's place's (more than it at margin 1); else
    the global answer."""
    at, inl = row["best"], row["inliers"]
    if (
        at >= 0
        and inl[at] >= MIN_INLIERS
        and inl[at] > row["global_inliers"]
        and inl[at] >= margin * row["global_inliers"]
    ):
        return float(row["cand_m"][at])
    return float(row["global_m"])


class Verifier:
    """ORB on panoramas and the essential-matrix inliers of a query frame against modelled frames
    (each modelled frame's features made once)."""

    def __init__(self, loc: Locator, model_video: Path, model_lens: Any, wanted_rows: set[int], n_features: int):
        self.loc, self.orb, self.rng = loc, cv2.ORB_create(nfeatures=n_features), np.random.default_rng(0)
        self.mmap = panorama_map(model_lens)
        frame_of = {r: int(loc.gen.frames["frame"][r]) for r in wanted_rows}
        decoded = model_frames(model_video, set(frame_of.values()))
        self.feats = {r: features(self.orb, decoded[f], self.mmap) for r, f in frame_of.items() if f in decoded}
        self.cost: list[float] = []
        self.maps: dict[str, Any] = {}

    def inliers(self, frame: np.ndarray, lens: Any, cand: list[int]) -> list[int]:
        key = json.dumps(lens.to_dict(), sort_keys=True)
        if key not in self.maps:
            self.maps[key] = panorama_map(lens)
        t0 = time.perf_counter()
        qb, qd = features(self.orb, frame, self.maps[key])
        self.cost.append(time.perf_counter() - t0)
        out = []
        for r in cand:
            vb, vd = self.feats.get(r, (np.zeros((0, 3)), np.zeros((0, 32), np.uint8)))
            mt = ratio_matches(qd, vd)
            out.append(essential_inliers(qb[mt[:, 0]], vb[mt[:, 1]], self.rng) if len(mt) else 0)
        return out


def probe(pack: Path, venue: str, n_features: int) -> dict[str, Any]:
    """The foreign pack's venue: each query clip as `omninav locate` answers it, then verified."""
    conf = conf_of("default")
    loc: Locator = modelled(pack, venue, "default", conf)
    src = pack / venue
    lens = load_lens(src / "lens.json")
    model_lens = load_lens(src / ("model_lens.json" if (src / "model_lens.json").is_file() else "lens.json"))
    queries = []
    for truth, spec, fps in query_spectra(pack, venue, loc):
        t = np.arange(len(spec)) / fps
        m, times = loc.search_clip(spec, t)
        queries.append((truth, loc.aggregated(m, times), places(m, loc.xy)))
    ver = Verifier(loc, src / "model.mp4", model_lens, {r for _, _, p in queries for r in p}, n_features)
    rows = []
    for truth, e, cand in queries:
        qf, _ = clip_frames(src / "queries" / truth["clip"], conf["model_fps"])
        # the lens as it sat in this clip (the ring found in its first frames, as locate does)
        qlens = corrected_lens(lens, qf[:FIRST]).lens if isinstance(lens, Catadioptric) else lens
        inl = ver.inliers(qf[-1], qlens, cand)
        rows.append({"clip": truth["clip"], **decide(loc, e, cand, inl, np.array([truth["x"], truth["y"]]))})
    return {"venue": venue, "rows": rows, "orb_ms": 1e3 * float(np.median(ver.cost))}


def probe_own(family: str, seed: int, n_features: int) -> dict[str, Any]:
    """One of our held-out families: its query walk's consecutive 1 s clips (bench/venues.py),
    each answered at its last frame, then verified."""
    from bench.venues import dataset, venue
    from omninav.evaluate import query_spectra as walk_query_spectra
    from omninav.walk_path import load_walk_path

    root = dataset(family, seed)
    loc = venue(root, "default")
    lens = load_lens(root / "lens.json")
    spec, t, xy, _, idx = walk_query_spectra(
        loc, root / "query.mp4", load_walk_path(root / "query_walk_path.json"), lens
    )
    n = int(round(loc.conf["model_fps"]))
    clips = []
    for s0 in range(0, len(t) - n + 1, n):
        w = slice(s0, s0 + n)
        m, times = loc.search_clip(spec[w], t[w])
        clips.append((int(idx[s0 + n - 1]), xy[s0 + n - 1], loc.aggregated(m, times), places(m, loc.xy)))
    ver = Verifier(
        loc, root / "model.mp4", load_lens(root / "model_lens.json"), {r for *_, p in clips for r in p}, n_features
    )
    decoded = model_frames(root / "query.mp4", {c[0] for c in clips} | set(range(FIRST)))
    qlens = corrected_lens(lens, [decoded[i] for i in range(FIRST)]).lens if isinstance(lens, Catadioptric) else lens
    rows = [
        {"frame": f, **decide(loc, e, cand, ver.inliers(decoded[f], qlens, cand), np.asarray(txy, np.float64))}
        for f, txy, e, cand in clips
    ]
    return {"venue": f"{family}-{seed}", "rows": rows, "orb_ms": 1e3 * float(np.median(ver.cost))}


MARGINS = (1.0, 1.25, 1.5, 2.0)


def report(r: dict[str, Any]) -> str:
    g = np.array([x["global_m"] for x in r["rows"]])
    best = np.array([min(x["cand_m"]) if x["cand_m"] else np.inf for x in r["rows"]])
    out = (
        f"{r['venue']}: {len(g)} clips; global within 1 m / 2 m {np.mean(g <= 1):.1%} / {np.mean(g <= 2):.1%}; "
        f"a candidate place within 2 m {np.mean(best <= 2):.1%}; ORB a query frame {r['orb_ms']:.1f} ms"
    )
    for margin in MARGINS:
        lo = np.array([verified_m(x, margin) for x in r["rows"]])
        out += (
            f"\n    margin {margin:g}: verified {np.mean(lo <= 1):.1%} / {np.mean(lo <= 2):.1%}, "
            f"gained {int(np.sum((lo <= 2) & (g > 2)))}, lost {int(np.sum((lo > 2) & (g <= 2)))}"
        )
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--pack", type=Path, default=PACK)
    ap.add_argument("--venues", default="all")
    ap.add_argument("--features", type=int, default=2000)
    ap.add_argument("--own", default="", help="held-out families as FAMILY-SEED, comma-separated")
    ap.add_argument("--json", type=Path)
    a = ap.parse_args()
    print(f"machine: {machine()}; ORB {a.features} features, ratio {RATIO}, {PLACES} places a clip")
    out = []
    for venue in pack_venues(a.pack) if a.venues == "all" else [v for v in a.venues.split(",") if v]:
        out.append(probe(a.pack, venue, a.features))
        print(report(out[-1]), flush=True)
    for fs in [v for v in a.own.split(",") if v]:
        family, seed = fs.rsplit("-", 1)
        out.append(probe_own(family, int(seed), a.features))
        print(report(out[-1]), flush=True)
    if a.json:
        a.json.write_text(json.dumps(out, indent=1))


if __name__ == "__main__":
    main()
