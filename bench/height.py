"""What the height the phone is held at costs, and what undoing it could buy (a measurement, not
yet in the engine).

Every family's query walk holds the phone at its own height (the walks of seed 0 at 1.18 m, seed
1 at 1.53 m, seed 2 at 1.47 m; atrium-glass 1.06, 1.66 and 1.56 m), the modelling walk at
1.35 m. A wall at horizontal distance d seen from a camera dh higher appears where tan(elevation)
is dh / d lower, so the band rows look at other parts of the walls. Unwarping the query with the
rows' elevations warped, tan(el') = tan(el) - delta, moves them back, exactly for walls at
d = dh / delta.

Without `--accuracy`: `bench/tilt.py`-style scores. At `--places` poses of each tuning family's
modelling walk (seed 0, rendered without optics, noise or people: only the height changes), the
place is rendered at 1.35 m and at HEIGHTS, and 3 m further along at HEIGHTS too; each is scored
against the 1.35 m frame (heading.relative_heading, as the search scores a match) at every delta.
Printed: the mean score per height and delta, for the same place and the place 3 m on.

`--accuracy`: every family's 1 s clips (bench/venues.py's venues and query walks, levelled as
the default preset is), each query frame extracted at every delta of DELTAS (one decode, one tilt
estimate), then answered per delta. Printed, per family and pooled by split:
  - `as is` (delta 0: bench/venues.py's default rows, to the clip);
  - `true h` (the delta nearest (h_query - 1.35) / 3 m: knowing the height);
  - `per clip` (the delta whose answer has the highest support: what a server could do with a
    record per delta, at as many times the search);
  - `per walk` (the delta with the highest mean support over the whole walk: a phone that learns
    its user's height over a session).

    python -m bench.height [--families ring-offices,hall-daylight] [--places 12]
    python -m bench.height --accuracy [--families tuning|held-out|NAME,...] [--seeds 0,1]
"""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

import numpy as np

from bench.common import machine
from bench.families import HEAD, line
from bench.venues import dataset, family_names, summarise, venue
from omninav.calib.correct import ClipLens
from omninav.evaluate import evaluate_spectra
from omninav.extract import Extractor
from omninav.heading import relative_heading
from omninav.lens import Lens, load_lens
from omninav.level import estimate_tilt, tilt_map
from omninav.presets import resolve
from omninav.synth.families import family_venue, pano_width
from omninav.synth.render import CameraModel, camera_frame, world_panorama
from omninav.synth.walks import grid_for, poses_from_walk_path, walk_heading
from omninav.unwarp import UnwarpMap, build_map
from omninav.video import VideoInfo, iter_video
from omninav.walk_path import load_walk_path, parse_walk_path

DELTAS = (-0.10, -0.05, 0.0, 0.05, 0.10)
MODEL_H = 1.35  # every family's modelling walk (synth.walks.MODELLING)
WALL_M = 3.0  # the distance at which delta undoes a height change exactly (the scores' best)


def warped(lens: Lens, m: UnwarpMap, delta: float) -> UnwarpMap:
    """`m` with each row looking where tan(elevation) is `delta` lower. Its `elevations` are
    those looked at (what level.tilted_map turns); Heights puts the nominal ones back, the bands
    the rows are summed into."""
    el = np.rad2deg(np.arctan(np.tan(np.deg2rad(np.asarray(m.elevations, np.float64))) - delta))
    w = build_map(lens, el, m.map_x.shape[1])
    # a cell counts only where the lens sees both what it reads and what it stood for
    return UnwarpMap(w.map_x, w.map_y, el.astype(np.float32), m.valid & w.valid, m.border)


class Heights:
    """A frame -> (D, C, K) spectra, one per delta, through one tilt estimate (the engine's
    Extractor otherwise: its band map, its levelling; delta 0 gives the engine's spectra)."""

    def __init__(self, lens: Lens, conf: dict[str, Any]):
        self.ext = Extractor(lens, conf)
        self.lens = lens
        self.iters = int(conf.get("level_iters") or 0)
        self.maps = [warped(lens, self.ext.map, d) for d in DELTAS]

    def __call__(self, frame: np.ndarray) -> np.ndarray:
        e = self.ext
        tilt = estimate_tilt(frame, self.lens, e.coarse, self.iters) if e.coarse is not None else (0.0, 0.0)
        # each delta's rows through the tilt found; the bands are summed over the nominal rows
        return np.stack([e.spectrum(frame, tilt_map(self.lens, m, tilt)) for m in self.maps])


def accuracy(names: list[str], seeds: list[int]) -> None:
    conf = resolve("default")
    print(f"machine: {machine()}\ndeltas: {DELTAS}; the true height's: (h - {MODEL_H}) / {WALL_M} m, nearest\n{HEAD}")
    pooled: dict[tuple[str, str], list[dict[str, Any]]] = {}
    for name in names:
        for seed in seeds:
            root = dataset(name, seed)
            loc = venue(root, "default")
            v = family_venue(name, seed)
            h = poses_from_walk_path(v.query_walk_path, v.family.query_perturb, np.random.default_rng(seed + 3))[
                0
            ].cam_h
            # the deltas and the query path (v2: through the re-clipped lens) in the name: a cache
            # made otherwise is never read as this one
            tag = "_".join(f"{d:+.2f}" for d in DELTAS)
            cache = root / "bench-data" / f"heights-v2-{tag}-{loc.venue_id}.npz"
            if cache.exists():
                z = np.load(cache)
                spec, t, idx = z["spec"], z["t"], z["idx"]
            else:
                spec, t, idx = walk(loc, root / "query.mp4", load_lens(root / "lens.json"), loc.conf)
                np.savez(cache, spec=spec, t=t, idx=idx)
            xy, hd, ok = load_walk_path(root / "query_walk_path.json").pose_at(t)
            per = []
            for k in range(len(DELTAS)):
                rows = evaluate_spectra(
                    loc, spec[ok, k], t[ok], xy[ok], hd[ok], idx[ok], aggregate="sequence", clip_s=1.0
                ).rows
                per.append(rows)
            true_k = int(np.argmin([abs(d - (h - MODEL_H) / WALL_M) for d in DELTAS]))
            sup = np.array([[r["support"] for r in rows] for rows in per])  # (D, clips)
            walk_k = int(np.argmax(sup.mean(axis=1)))
            clip_k = np.argmax(sup, axis=0)
            ways = {
                "as is": per[DELTAS.index(0.0)],
                "true h": per[true_k],
                "per clip": [per[int(k)][i] for i, k in enumerate(clip_k)],
                "per walk": per[walk_k],
            }
            print(
                f"# {name}/{seed}: query h {h:.2f} m; delta true {DELTAS[true_k]:+.2f}, walk's {DELTAS[walk_k]:+.2f}; "
                f"clips choose {np.bincount(clip_k, minlength=len(DELTAS)).tolist()}",
                flush=True,
            )
            for how, rows in ways.items():
                pooled.setdefault((v.family.split, how), []).extend(rows)
                print(line(f"{name}/{seed}", v.family.split, how, 1.0, summarise(rows, conf)), flush=True)
    for (split, how), rows in pooled.items():
        print(line("ALL", split, how, 1.0, summarise(rows, conf)))


def walk(loc: Any, video: Path, lens: Lens, conf: dict[str, Any]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The walk's frames at model_fps -> (F, D, C, K), times, frame index: evaluate.walk_spectra's,
    through the lens corrected for where the ring sits in the walk (calib/correct.py, as every
    query is), at every delta."""
    info = VideoInfo(video)
    stride = max(1, int(round(info.fps / loc.conf["model_fps"])))
    check = Extractor(lens, conf).check_frame  # a frame of the wrong size refused, as walk_spectra does
    clip = ClipLens(lens, lambda fit: Heights(fit, conf), lambda f: check(f, str(video)))
    specs: list[np.ndarray] = []
    idx = []
    for i, frame in iter_video(info, stride=stride):
        specs.extend(clip.feed(frame))
        idx.append(i)
    specs.extend(clip.flush())
    return np.stack(specs), np.array(idx) / info.fps, np.array(idx)


HEIGHTS = (1.05, 1.18, 1.53, 1.65)


def scores(names: list[str], places: int) -> None:
    conf = resolve("default")
    print(f"machine: {machine()}\nmean score against the place at {MODEL_H} m, per delta {DELTAS}")
    for name in names:
        v = family_venue(name, 0)
        lens = v.family.query_lens
        heights = Heights(lens, conf)
        grid = grid_for(lens, pano_width(lens))
        cam = CameraModel.create(lens)
        tr = parse_walk_path(v.model_walk_path)
        rng = np.random.default_rng(5)
        out: dict[tuple[float, str], list[np.ndarray]] = {}
        for t in np.sort(rng.uniform(2.0, tr.times[-1] - 5.0, places)):
            ts = np.array([t, t + 3.0 / 1.2])  # the modelling walk's 1.2 m/s: 3 m on
            xy, _, ok = tr.pose_at(ts)
            if not ok.all():
                continue
            hd = float(walk_heading(tr, ts[:1], 0.0)[0])
            base = heights(
                camera_frame(cam, world_panorama(v.scene, *xy[0], MODEL_H, grid, []), grid, hd, None)[..., ::-1].copy()
            )
            for h in HEIGHTS:
                for where, (x, y) in (("same place", xy[0]), ("3 m on", xy[1])):
                    frame = camera_frame(cam, world_panorama(v.scene, x, y, h, grid, []), grid, hd, None)[..., ::-1]
                    spec = heights(frame.copy())
                    ref = base[DELTAS.index(0.0)]
                    out.setdefault((h, where), []).append(np.array([relative_heading(s, ref)[1] for s in spec]))
        for (h, where), rows in out.items():
            m = np.mean(rows, axis=0)
            cells = "".join(f"  {d:+.2f}: {x:.3f}" for d, x in zip(DELTAS, m, strict=True))
            print(f"{name:<15} {h:.2f} m  {where:<11}{cells}", flush=True)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--accuracy", action="store_true")
    ap.add_argument("--families", default="ring-offices,hall-daylight")
    ap.add_argument("--seeds", default="0,1")
    ap.add_argument("--places", type=int, default=12)
    a = ap.parse_args()
    if a.accuracy:
        accuracy(family_names(a.families), [int(s) for s in a.seeds.split(",")])
    else:
        scores(family_names(a.families), a.places)


if __name__ == "__main__":
    main()
