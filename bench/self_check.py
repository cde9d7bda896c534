"""A venue that checks itself: its own modelling walk, read as a user's phone would see it, located
against the venue without the frames themselves, for each candidate configuration.

What differs between the modelling walk and a user's phone is mostly where each elevation row
lands: the lens profile (a re-clipped lens, another phone: an elevation offset), the phone's height
(tan(elevation) shifted: bench/height.py), and where the user walks across the corridor (the side
walls nearer on one side and further on the other: tan(elevation) scaled by 1 / (1 - r sin(phi)),
phi the azimuth from the walking direction, r the offset as a share of the corridor's half width);
then the exposure. Each of a walk's 1 s segments (every `--every` seconds) is read through a remap
with a random draw of all four (not levelled: the walk is filmed upright), and searched with its own
frames and their neighbours within the quality map's LEAVE_OUT_M left out (quality.py). The score
of a configuration is the share within 2 m; the venue would pick the configuration that scores
best. Measured, not used: it could not tell the configurations apart (docs/decisions.md); a
building's evaluation walk does (choose.py).

Printed per venue: each configuration's self-check score beside its accuracy on the venue's real
queries (bench/venues.py's query walk, or the foreign pack's clips), the pick, and whether the
pick is the configuration that answered the real queries best.

    python -m bench.self_check [--configs default,one-band-soft] [--families held-out] [--seeds 0]
                               [--foreign] [--every 3]
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

import numpy as np

from bench import foreign
from bench.common import machine
from bench.scoring import conf_of, scores
from bench.venues import dataset, family_names, rows_for, venue
from omninav.aggregate import AGGREGATORS
from omninav.extract import Extractor
from omninav.lens import Lens, direction_to_pixel, load_lens
from omninav.locate import Locator
from omninav.presets import setting
from omninav.quality import LEAVE_OUT_M, _walked
from omninav.synth.families import FAMILIES
from omninav.synth.optics import reexpose
from omninav.unwarp import UnwarpMap
from omninav.video import VideoInfo, iter_video

ELEV_DEG = 2.0  # lens profile off by up to this
HEIGHT_DELTA = 0.08  # tan(elevation) shifted by up to this (0.24 m at walls 3 m away)
SIDE_SHARE = 0.3  # walking up to 30 % of the half width off the modelling walk's line
GAIN = (0.6, 1.4)


def perturbed_map(lens: Lens, base: UnwarpMap, rng: np.random.Generator) -> UnwarpMap:
    """`base` (a band map: rows at nominal elevations) read where a user's phone would see them."""
    width = base.map_x.shape[1]
    az = (np.arange(width, dtype=np.float64) + 0.5) * 360.0 / width
    el = np.asarray(base.elevations, np.float64)
    azg, elg = np.meshgrid(az, el)
    e, d, r = rng.uniform(-ELEV_DEG, ELEV_DEG), rng.uniform(-HEIGHT_DELTA, HEIGHT_DELTA), rng.uniform(-1, 1)
    k = 1.0 / (1.0 - SIDE_SHARE * r * np.sin(np.deg2rad(azg)))
    el2 = np.rad2deg(np.arctan((np.tan(np.deg2rad(elg)) - d) * k)) + e
    x, y = direction_to_pixel(lens, azg, el2)
    valid = np.isfinite(x) & np.isfinite(y)
    x = np.where(valid, x, -10.0).astype(np.float32)
    y = np.where(valid, y, -10.0).astype(np.float32)
    return UnwarpMap(x, y, base.elevations, base.valid & valid, base.border)


def read_frames(video: Path, wanted: set[int]) -> dict[int, np.ndarray]:
    """The frames of `video` with these indices (BGR), decoded once in order."""
    out: dict[int, np.ndarray] = {}
    last = max(wanted)
    for i, f in iter_video(VideoInfo(video)):
        if i in wanted:
            out[i] = f
        if i >= last:
            break
    return out


def self_check(
    loc: Locator, video: Path, lens: Lens, every_s: float = 3.0, seed: int = 0, leave_m: float = LEAVE_OUT_M
) -> dict[str, Any]:
    """The venue's own walk as users would film it, located without itself: share within 2 m."""
    conf = loc.conf
    fr = np.asarray(loc.gen.frames)
    n = max(2, int(round(conf["model_fps"])))
    t = fr["t"].astype(np.float64)
    order = np.argsort(t, kind="stable")
    if not np.array_equal(order, np.arange(len(fr))):
        raise SystemExit("self_check expects one walk's frames in time order")
    xy = loc.xy
    walked = _walked(xy, fr["video"])  # the quality map's path length, a gap between videos
    step = max(n, int(round(every_s * conf["model_fps"])))
    segs = [np.arange(s, s + n) for s in range(0, len(fr) - n + 1, step)]
    frames = read_frames(video, {int(fr["frame"][r]) for s in segs for r in s})
    ext = Extractor(lens, conf)
    rng = np.random.default_rng(seed)
    agg = AGGREGATORS[conf["aggregate"]]
    k, shortlist = conf["candidates"], int(setting(conf, "shortlist"))
    shared = setting(conf, "shared_candidates")
    near = []
    for s in segs:
        m = perturbed_map(lens, ext.map, rng)
        gain = rng.uniform(*GAIN)
        wb = (rng.uniform(0.9, 1.1), 1.0, rng.uniform(0.9, 1.1))
        spec = []
        for r in s:
            rgb = reexpose(frames[int(fr["frame"][r])][..., ::-1].copy(), gain=gain, wb=wb, jpeg=80)
            # read through the perturbed map itself: the modelling walk is filmed upright, so its
            # frames are not levelled again here
            spec.append(ext.spectrum(np.ascontiguousarray(rgb[..., ::-1]), m))
        q = np.stack(spec)
        lo = np.searchsorted(walked, walked[s] - leave_m, side="left")
        hi = np.searchsorted(walked, walked[s] + leave_m, side="right")
        groups = np.zeros(len(s), int) if shared else None
        mt = loc.index.search(q, k, exclude=(lo, hi), groups=groups, shortlist=shortlist)
        e = agg(mt, xy, t[s] - t[s[0]], conf)
        near.append(float(np.hypot(e.x - xy[s[-1], 0], e.y - xy[s[-1], 1])) <= 2.0)
    return {"segments": len(segs), "within_2m": float(np.mean(near))}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--configs", default="default,one-band-soft")
    ap.add_argument("--families", default="none")
    ap.add_argument("--seeds", default="0")
    ap.add_argument("--foreign", action="store_true")
    ap.add_argument("--every", type=float, default=3.0)
    ap.add_argument("--leave", type=float, default=LEAVE_OUT_M, help="metres of the walk left out each side")
    a = ap.parse_args()
    configs = a.configs.split(",")
    print(f"machine: {machine()}")
    venues: list[tuple[str, Any]] = []
    if a.families != "none":
        for name in family_names(a.families):
            for seed in (int(s) for s in a.seeds.split(",")):
                venues.append((f"{name}/{seed}", (name, seed)))
    if a.foreign:
        venues += [(v, v) for v in foreign.pack_venues(foreign.PACK)]
    for label, what in venues:
        cells, real = [], {}
        for c in configs:
            if isinstance(what, tuple):
                name, seed = what
                root = dataset(name, seed)
                loc = venue(root, c)
                video, lens = root / "model.mp4", load_lens(root / "model_lens.json")
                real[c] = float(scores(rows_for(name, seed, c, [1.0])[1.0], conf_of(c))["near"].mean())
            else:
                conf = conf_of(c)
                loc = foreign.modelled(foreign.PACK, what, c, conf)
                src = foreign.PACK / what
                lens = load_lens(src / ("model_lens.json" if (src / "model_lens.json").is_file() else "lens.json"))
                video = src / "model.mp4"
                real[c] = float(scores(foreign.rows_for(foreign.PACK, what, c, conf), conf)["near"].mean())
            sc = self_check(loc, video, lens, a.every, leave_m=a.leave)
            cells.append((c, sc["within_2m"], sc["segments"]))
        pick = max(cells, key=lambda x: x[1])[0]
        best = max(real, key=lambda c: real[c])
        text = "  ".join(f"{c}: self {s:.1%} real {real[c]:.1%}" for c, s, _ in cells)
        split = FAMILIES[what[0]].split if isinstance(what, tuple) else "foreign"
        print(f"{label:<22}{split:<9}{text}  -> picks {pick} ({'right' if real[pick] >= real[best] else 'wrong'})")
        print(json.dumps({"venue": label, "cells": cells, "real": real}), file=sys.stderr, flush=True)


if __name__ == "__main__":
    main()
