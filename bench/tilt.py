"""What a phone held off vertical costs a frame's match, and whether undoing it is worth building.

A real phone is never held quite level: the donut's axis leans a few degrees (the query walks of
every family lean up to 5 deg, atrium-glass's up to 8), so the band of elevations the curves sum
over rises on one side of the panorama and falls on the other. The phone knows its tilt (gravity
from DeviceMotion) and could unwarp through it: the remap would look up, for each panorama
direction (azimuth, elevation) of the upright world, the camera direction the tilt turned it into.
Before building that into the worker and the engine, this measures what it would buy.

For each TUNING family (seed 0; synth.families, nothing held-out is looked at), at `--places`
poses along the modelling walk, the same place is rendered upright and then (no optics, no noise,
no people: only the one change):
  - tilted 3, 5 and 8 deg towards a random side, unwarped as the engine does (as is), and through
    the true tilt (`corrected`, the upper bound of a correction: the phone's gravity is never exact);
  - the camera 0.2 m higher; 0.3 m to the side; 0.5, 1 and 2 m further along the walk.
Each is scored against the upright frame as the search scores a match (heading.relative_heading
on the quantised spectra: a cosine, 1 = the same panorama). Printed: mean, p10 and min per change.

`--accuracy`: what it buys where it counts. The families' 1 s clips (bench/venues.py's venues
and query walks, --seeds) answered twice: every query frame unwarped as it is, and through the
tilt the renderer gave it (the upper bound again). Both through the lens where the renderer put
it (its re-clipping shift), so that the two differ by the tilt alone. Printed like families.py.

    python -m bench.tilt [--families tuning|NAME,...] [--places 25] [--set KEY=JSON]
    python -m bench.tilt --accuracy [--families tuning|held-out|NAME,...] [--seeds 0,1]
"""

from __future__ import annotations

import argparse
import copy
import dataclasses
import json
from typing import Any

import numpy as np

from bench.common import machine
from bench.families import HEAD, line
from bench.venues import dataset, family_names, summarise, venue
from omninav.evaluate import evaluate_spectra
from omninav.extract import Extractor
from omninav.heading import relative_heading
from omninav.lens import Catadioptric, load_lens
from omninav.level import tilted_map  # the engine's: a direction the donut does not see reads its upright cell
from omninav.presets import resolve
from omninav.synth.families import FAMILIES, family_venue, pano_width
from omninav.synth.render import CameraModel, camera_frame, tilt_rotation, world_panorama
from omninav.synth.walks import grid_for, poses_from_walk_path, walk_heading
from omninav.unwarp import UnwarpMap
from omninav.video import VideoInfo, iter_video
from omninav.walk_path import load_walk_path, parse_walk_path

TILTS = (3.0, 5.0, 8.0)
CORRECTED = (5.0, 8.0)
ALONG_M = (0.5, 1.0, 2.0)


def family_scores(
    name: str, places: int, seed: int = 0, overrides: dict[str, Any] | None = None
) -> dict[str, list[float]]:
    v = family_venue(name, seed)
    lens = v.family.query_lens
    conf = resolve("default", overrides)  # what every family is modelled and queried with (bench/venues.py)
    ext = Extractor(lens, conf)
    grid = grid_for(lens, pano_width(lens))
    cam = CameraModel.create(lens)
    tr = parse_walk_path(v.model_walk_path)
    rng = np.random.default_rng(5)

    def shot(x: float, y: float, hd: float, h: float = 1.35, rot: np.ndarray | None = None) -> np.ndarray:
        return camera_frame(cam, world_panorama(v.scene, x, y, h, grid, []), grid, hd, rot)[..., ::-1].copy()

    def through(m: UnwarpMap) -> Extractor:  # the engine's extractor, its remap swapped
        e = copy.copy(ext)
        e.map = m
        return e

    out: dict[str, list[float]] = {}
    speed = 1.2  # the modelling walk's m/s, near enough: "along" is what the walk path says at t + d / speed
    for t in np.sort(rng.uniform(2.0, tr.times[-1] - 5.0, places)):
        ts = np.array([t, *(t + d / speed for d in ALONG_M)])
        xy, _, ok = tr.pose_at(ts)
        if not ok.all():
            continue
        hd = float(walk_heading(tr, ts[:1], 0.0)[0])
        base = ext.spectrum(shot(xy[0, 0], xy[0, 1], hd))

        def add(key: str, spec: np.ndarray, base: np.ndarray = base) -> None:
            out.setdefault(key, []).append(float(relative_heading(spec, base)[1]))

        for tilt in TILTS:
            rot = tilt_rotation(tilt, rng.uniform(0.0, 360.0))
            frame = shot(xy[0, 0], xy[0, 1], hd, rot=rot)
            add(f"tilted {tilt:g} deg, as is", ext.spectrum(frame))
            if tilt in CORRECTED:
                add(f"tilted {tilt:g} deg, corrected", through(tilted_map(lens, ext.map, rot)).spectrum(frame))
        add("0.2 m higher", ext.spectrum(shot(xy[0, 0], xy[0, 1], hd, h=1.55)))
        h = np.deg2rad(hd)  # heading h walks along (sin h, -cos h) (docs/formats.md): its right is (cos h, sin h)
        add("0.3 m to the side", ext.spectrum(shot(xy[0, 0] + 0.3 * np.cos(h), xy[0, 1] + 0.3 * np.sin(h), hd)))
        for j, d in enumerate(ALONG_M, 1):
            add(f"{d:g} m along", ext.spectrum(shot(xy[j, 0], xy[j, 1], hd)))
    return out


def accuracy(names: list[str], seeds: list[int], overrides: dict[str, Any]) -> None:
    """1 s clips of each family's query walk, as they are and unwarped through the true tilt
    (unlevelled unless --set says otherwise: levelling would estimate the tilt over the true one)."""
    overrides = {"level_iters": None, **overrides}
    conf = resolve("default", overrides)
    print(f"config: 'as is', or 'untilted' (every query frame unwarped through its true tilt)\n{HEAD}")
    pooled: dict[tuple[str, str], list[dict[str, Any]]] = {}
    for name in names:
        for seed in seeds:
            root = dataset(name, seed)
            loc = venue(root, "default", overrides)
            v = family_venue(name, seed)
            pert = v.family.query_perturb
            # the query walk's poses and lens as synth.families.make_family_dataset rendered them
            # (its seeds: seed + 3 for the poses, seed + 4 for render_frames' draws, the shift first)
            poses = poses_from_walk_path(v.query_walk_path, pert, np.random.default_rng(seed + 3))
            lens = load_lens(root / "lens.json")
            ang = np.random.default_rng(seed + 4).uniform(0.0, 2.0 * np.pi)
            if isinstance(lens, Catadioptric):
                cx, cy = lens.center
                shift = pert.lens_shift_px
                lens = dataclasses.replace(lens, center=(cx + shift * np.cos(ang), cy + shift * np.sin(ang)))
            ext = loc.extractor(lens)
            spec: dict[str, list[np.ndarray]] = {"as is": [], "untilted": []}
            for i, frame in iter_video(VideoInfo(root / "query.mp4")):
                p = poses[i]
                spec["as is"].append(ext.spectrum(frame))
                tilted = copy.copy(ext)
                tilted.map = tilted_map(lens, ext.map, tilt_rotation(p.tilt, p.tilt_dir)) if p.tilt else ext.map
                spec["untilted"].append(tilted.spectrum(frame))
            t = np.array([p.t for p in poses[: len(spec["as is"])]])
            xy, hd, ok = load_walk_path(root / "query_walk_path.json").pose_at(t)
            for how, frames in spec.items():
                sp = np.stack(frames)[ok]
                idx = np.flatnonzero(ok)
                rows = evaluate_spectra(loc, sp, t[ok], xy[ok], hd[ok], idx, aggregate="sequence", clip_s=1.0).rows
                pooled.setdefault((v.family.split, how), []).extend(rows)
                print(line(f"{name}/{seed}", v.family.split, how, 1.0, summarise(rows, conf)), flush=True)
    for (split, how), rows in pooled.items():
        print(line("ALL", split, how, 1.0, summarise(rows, conf)))


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--families", default="tuning")
    ap.add_argument("--places", type=int, default=25)
    ap.add_argument("--set", action="append", default=[], metavar="KEY=JSON", help="override a preset setting")
    ap.add_argument("--accuracy", action="store_true", help="the families' 1 s clips, as is and through the true tilt")
    ap.add_argument("--seeds", default="0,1", help="with --accuracy")
    a = ap.parse_args()
    overrides = {k: json.loads(v) for k, v in (s.split("=", 1) for s in a.set)}
    if a.accuracy:
        print(f"machine: {machine()}")
        accuracy(family_names(a.families), [int(s) for s in a.seeds.split(",")], overrides)
        return
    names = (
        [n for n, f in FAMILIES.items() if f.split == "tuning"]
        if a.families == "tuning"
        else [s.strip() for s in a.families.split(",") if s.strip()]
    )
    print(f"machine: {machine()}")
    print(f"families: {', '.join(names)} (seed 0), {a.places} places each; score against the upright frame")
    if overrides:
        print(f"settings: default with {json.dumps(overrides)}")
    pooled: dict[str, list[float]] = {}
    for name in names:
        for k, s in family_scores(name, a.places, overrides=overrides).items():
            pooled.setdefault(k, []).extend(s)
            print(f"  {name:15s} {k:26s} mean {np.mean(s):.3f}  p10 {np.percentile(s, 10):.3f}")
    print(f"{'change (all families)':28s} {'n':>4s} {'mean':>6s} {'p10':>6s} {'min':>6s}")
    for k, s in pooled.items():
        print(f"{k:28s} {len(s):4d} {np.mean(s):6.3f} {np.percentile(s, 10):6.3f} {np.min(s):6.3f}")


if __name__ == "__main__":
    main()
