"""Accuracy against clip length: what a longer clip (the app's "keep turning slowly") buys.

Two kinds of clip on each venue, every length answered at the same end frames so that the lengths
compare like for like:

- walking: the venue's query walk (every perturbation of issue 2), clips of 0.3-5 s ending every
  second from the fifth on;
- turning: the user stands at places along the query walk and turns slowly (10-30 deg/s, either
  way, from any heading) for 5 s, with the query walk's perturbations (height, tilt, light and
  cast, people, lens shift, noise, MPEG-4 compression); each stand answered at its last frame.

Columns: clips; within 1 m / 2 m; median heading error; the share answered with confidence >= 0.8;
confident-wrong (confidence >= 0.8 and further than 2 m, as a share of all clips); not sure
(confidence below the app's 0.5); and the search's time per clip. The last row of each kind is the
app's policy: a 1 s answer, and when it is not sure, the 3 s clip that ends 2 s later (the same
frames and 20 more); the row after it asks for more below confidence 0.8 instead, for comparison.

    python -m bench.clip_length                       # data/bench-venue-0 and data/bench-venue-twin-0
    python -m bench.clip_length --root DIR [--layout twin] [--seed 0]
    python -m bench.clip_length --family long-bare [--family ...] [--seed 0]
"""

from __future__ import annotations

import argparse
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from bench.common import machine
from bench.venues import dataset, venue
from omninav.aggregate import SURE, confidence
from omninav.evaluate import query_spectra
from omninav.heading import wrap_deg
from omninav.lens import Lens, load_lens
from omninav.locate import Locator
from omninav.synth import QUERY, build_scene, make_dataset, upgrade_names
from omninav.synth.scene import Scene
from omninav.synth.walks import Perturb, Pose, render_frames, write_video
from omninav.video import VideoInfo, iter_video
from omninav.walk_path import load_walk_path

LENGTHS_S = (0.3, 0.5, 1.0, 2.0, 3.0, 5.0)
FPS = 10.0
LOW = 0.5  # config.py's LOW_CONFIDENCE: below it the app says "not sure"
STAND_S = 5.0  # each turning clip is this long: the longest length
STAND_EVERY_S = 5.0  # a stand every this many seconds of the query walk
TURN_DPS = (10.0, 30.0)  # turning slowly


@dataclass
class Walk:
    """A walk's spectra and truth per sampled frame, and where its clips end."""

    spec: np.ndarray
    t: np.ndarray
    xy: np.ndarray
    heading: np.ndarray
    ends: np.ndarray  # frame indices at which every length is answered
    starts: np.ndarray  # the first frame a clip ending there may use (a stand's first frame)


def modelled(root: Path) -> Locator:
    """The venue modelled from root's modelling walk with the default settings, cached as
    bench/venues.py caches it (answers scored with today's confidence model)."""
    return venue(root, "default")


def _cached(path: Path, key: str, make: Callable[[], dict[str, np.ndarray]]) -> dict[str, np.ndarray]:
    if path.exists():
        z = np.load(path)
        if str(z["key"]) == key:
            return {k: z[k] for k in z.files if k != "key"}
    out = make()
    np.savez(path, key=key, **out)
    return out


def walking(root: Path, loc: Locator) -> Walk:
    key = f"{loc.venue_id}/{loc.generation}/query"

    def make() -> dict[str, np.ndarray]:
        walk_path, lens = load_walk_path(root / "query_walk_path.json"), load_lens(root / "lens.json")
        spec, t, xy, hd, _ = query_spectra(loc, root / "query.mp4", walk_path, lens)
        return {"spec": spec, "t": t, "xy": xy, "heading": hd}

    z = _cached(root / "bench-data" / "clip-length-walk.npz", key, make)
    n = int(round(max(LENGTHS_S) * FPS))
    ends = np.arange(n - 1, len(z["t"]), int(FPS))
    return Walk(z["spec"], z["t"], z["xy"], z["heading"], ends, np.zeros_like(ends))


def stand_poses(root: Path, seed: int) -> list[Pose]:
    """Stands along the query walk: the place it passes every STAND_EVERY_S, any heading, a slow
    turn either way, the query walk's camera height and a slowly varying tilt."""
    rng = np.random.default_rng(seed + 77)
    walk_path = load_walk_path(root / "query_walk_path.json")
    times = np.arange(STAND_EVERY_S / 2, walk_path.times[-1], STAND_EVERY_S)
    xy, _, ok = walk_path.pose_at(times)
    per = int(round(STAND_S * FPS))
    poses: list[Pose] = []
    for s, (x, y) in enumerate(xy[ok]):
        h0 = rng.uniform(0, 360)
        rate = rng.uniform(*TURN_DPS) * rng.choice([-1.0, 1.0])
        cam_h = rng.uniform(*QUERY.height_m)
        tilt, tdir = rng.uniform(0, QUERY.tilt_deg, 2), rng.uniform(0, 360, 2)
        for i in range(per):
            f = i / (per - 1)
            t = s * STAND_S + i / FPS
            poses.append(
                Pose(
                    t,
                    float(x),
                    float(y),
                    float((h0 + rate * i / FPS) % 360.0),
                    cam_h + 0.01 * np.sin(t * 2 * np.pi * 1.8),  # breathing, as the walks have it
                    float(tilt[0] + f * (tilt[1] - tilt[0])),
                    float(tdir[0] + f * (tdir[1] - tdir[0])),
                )
            )
    return poses


def turning(root: Path, loc: Locator, scene: Scene, name: str, seed: int, look: Perturb = QUERY) -> Walk:
    """The stands in `scene` (the venue of root, called `name`), filmed as `look` says: rendered
    once (cached beside the venue) and located at their last frames."""
    lens: Lens = load_lens(root / "lens.json")
    poses = stand_poses(root, seed)
    per = int(round(STAND_S * FPS))
    key = f"{loc.venue_id}/{loc.generation}/turning/{name}/{seed}/{len(poses)}/{lens.to_dict()}/{look}"

    def make() -> dict[str, np.ndarray]:
        video = root / "bench-data" / "clip-length-turning.mp4"
        t0 = time.perf_counter()
        print(f"rendering {len(poses) // per} stands of {STAND_S:g} s ...", file=sys.stderr, flush=True)
        frames = (f for _, f in render_frames(scene, lens, poses, look, seed + 5))
        write_video(video, frames, FPS, lens.image_size)
        print(f"rendered in {time.perf_counter() - t0:.0f} s", file=sys.stderr, flush=True)
        ext = loc.extractor(lens)
        clip = loc.clip_lens(lens, lambda f: ext.check_frame(f, str(video)))
        specs = []
        for _, frame in iter_video(VideoInfo(video)):
            specs.extend(clip.feed(frame))
        specs.extend(clip.flush())
        return {
            "spec": np.stack(specs),
            "t": np.array([p.t for p in poses]),
            "xy": np.array([(p.x, p.y) for p in poses]),
            "heading": np.array([p.heading for p in poses]),
        }

    z = _cached(root / "bench-data" / "clip-length-turning.npz", key, make)
    ends = np.arange(per - 1, len(z["t"]), per)
    return Walk(z["spec"], z["t"], z["xy"], z["heading"], ends, ends - per + 1)


def answers(loc: Locator, w: Walk, seconds: float, early_s: float = 0.0) -> dict[str, np.ndarray]:
    """Every end frame's answer from the clip of `seconds` that ends there (or `early_s` before)."""
    n = max(1, int(round(seconds * FPS)))
    err, herr, conf, ms = [], [], [], []
    for end, s in zip(w.ends, w.starts, strict=True):
        e = int(end) - int(round(early_s * FPS))
        a = max(int(s), e - n + 1)
        t0 = time.perf_counter()
        est = loc.estimate(w.spec[a : e + 1], w.t[a : e + 1])
        ms.append((time.perf_counter() - t0) * 1000)
        err.append(float(np.hypot(est.x - w.xy[e, 0], est.y - w.xy[e, 1])))
        herr.append(abs(float(wrap_deg(est.heading - w.heading[e]))))
        conf.append(confidence(est, loc.conf))
    return {"err": np.array(err), "herr": np.array(herr), "conf": np.array(conf), "ms": np.array(ms)}


def row(label: str, r: dict[str, np.ndarray]) -> str:
    err, conf = r["err"], r["conf"]
    hi = conf >= SURE
    return (
        f"{label:<22}{len(err):>6}{np.mean(err <= 1):>8.1%}{np.mean(err <= 2):>8.1%}{np.median(r['herr']):>8.2f}°"
        f"{hi.mean():>9.0%}{np.mean(hi & (err > 2)):>9.1%}{np.mean(conf < LOW):>9.1%}{np.mean(r['ms']):>8.1f}"
    )


def ask_more(loc: Locator, w: Walk, below: float = LOW) -> dict[str, np.ndarray]:
    """The app's policy: a 1 s answer; where its confidence is below `below` (the app: not sure),
    the 3 s clip of the same frames and the 20 that follow, answered 2 s later."""
    first = answers(loc, w, 1.0, early_s=2.0)
    more = answers(loc, w, 3.0)
    unsure = first["conf"] < below
    return {k: first[k] + unsure * more[k] if k == "ms" else np.where(unsure, more[k], first[k]) for k in first}


def report(root: Path, scene: Scene, name: str, seed: int, look: Perturb = QUERY) -> dict[str, Any]:
    """Both tables for the dataset in root, whose venue is `scene` (called `name`)."""
    loc = modelled(root)
    print(f"\nvenue: {root} ({name}, seed {seed}), {len(loc.xy)} modelled frames")
    head = f"{'clip':<22}{'clips':>6}{'<=1 m':>8}{'<=2 m':>8}{'hdg med':>9}{'conf>=.8':>9}"
    head += f"{'conf-wr':>9}{'unsure':>9}{'ms':>8}"
    out: dict[str, Any] = {}
    for kind, w in (("walking", walking(root, loc)), ("turning", turning(root, loc, scene, name, seed, look))):
        print(f"{kind}:")
        print(head)
        print("-" * len(head))
        res = {s: answers(loc, w, s) for s in LENGTHS_S}
        for s, r in res.items():
            print(row(f"{s:g} s ({int(round(s * FPS))} frames)", r), flush=True)
        print(row("1 s, 3 s if unsure", ask_more(loc, w)))
        print(row("1 s, 3 s if conf < 0.8", ask_more(loc, w, SURE)))
        out[kind] = res
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--root", type=Path, action="append", help="a dataset folder (make_dataset's files); repeatable")
    ap.add_argument("--layout", default=None, help="the root's layout (default: twin if its name says so)")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument(
        "--family", action="append", help="a venue family (synth.families; rendered as bench/venues.py does)"
    )
    a = ap.parse_args()
    print(f"machine: {machine()}")
    if a.family:
        from omninav.synth.families import FAMILIES, family_venue

        for name in a.family:
            fam = FAMILIES.get(name)
            if fam is None:
                ap.error(f"unknown family {name!r} (known: {', '.join(FAMILIES)})")
            # the stands are filmed in the building as the query walk saw it, as the query walk was
            scene = family_venue(name, a.seed).query_scene
            report(dataset(name, a.seed), scene, f"{name} ({fam.split})", a.seed, fam.query_perturb)
        return
    roots = a.root or [Path("data") / f"bench-venue-{a.seed}", Path("data") / f"bench-venue-twin-{a.seed}"]
    for root in roots:
        layout = a.layout or ("twin" if "twin" in root.name else "default")
        if not (root / "query.mp4").exists():
            print(f"rendering {root} ...", file=sys.stderr, flush=True)
            make_dataset(root, seed=a.seed, layout=layout)
        report(upgrade_names(root), build_scene(a.seed, layout), f"{layout} layout", a.seed)


if __name__ == "__main__":
    main()
