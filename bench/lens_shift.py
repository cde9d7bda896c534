"""A re-clipped lens, with and without the per-clip correction (calib/correct.py), in one run.

The default synthetic venue is modelled with the true lens profile (bench/accuracy.py's render,
cached). Query clips (1 s, 10 frames at 10 fps) are rendered along the independent query walk
with issue 2's perturbations (lateral offsets, camera height, tilt, light and colour casts,
people, noise), each clip with the lens clipped on SHIFT px off in a random direction (0 = the
profile's own place). Every clip is located twice from the same frames: through the profile as it
is, and through the profile corrected for where the clip's ring sits (what `omninav locate`, the
server and, in its worker, the phone do).

    python -m bench.lens_shift [--clips 60] [--shifts 0,3,6,10] [--seed 0] [--layout twin]
"""

from __future__ import annotations

import argparse
import json
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

from bench.accuracy import dataset
from bench.common import machine
from bench.venues import cached_venue
from omninav.calib.correct import FIRST, ClipLens
from omninav.calib.lens_fit import corrected_lens
from omninav.extract import Extractor
from omninav.heading import wrap_deg
from omninav.lens import load_lens
from omninav.presets import resolve
from omninav.synth import QUERY, make_dataset, upgrade_names
from omninav.synth.scene import build_scene
from omninav.synth.walks import poses_from_walk_path, render_frames


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--clips", type=int, default=60, help="clips per shift")
    ap.add_argument("--shifts", default="0,3,6,10")
    ap.add_argument("--root", type=Path)
    ap.add_argument("--layout", default="default", help="default, or twin: look-alike corridors")
    a = ap.parse_args()
    if a.layout == "default":
        root = dataset(a.root or Path("data") / f"bench-venue-{a.seed}", a.seed)
    else:
        root = a.root or Path("data") / f"bench-venue-{a.layout}-{a.seed}"
        if not (root / "query.mp4").exists():
            make_dataset(root, seed=a.seed, layout=a.layout)
        upgrade_names(root)
    lens = load_lens(root / "lens.json")
    loc = cached_venue(root, "lens-shift", resolve("default"), lens="lens.json")
    conf = loc.conf
    scene = build_scene(a.seed, a.layout)
    walk_path = json.loads((root / "query_walk_path.json").read_text())
    n = int(round(walk_path["fps"]))  # a 1 s clip (the query walk is rendered at the venue's 10 fps)
    look = replace(QUERY, lens_shift_px=0.0)
    poses = poses_from_walk_path(walk_path, look, np.random.default_rng(a.seed + 7))
    starts = np.linspace(0, len(poses) - n, a.clips).astype(int)
    plain = Extractor(lens, conf)
    print(f"machine: {machine()}")
    print(f"venue: {root} ({len(loc.gen.frames)} frames); {a.clips} clips per shift, 1 s each, issue 2 perturbations")
    cols = ("<=2 m as is", 13), ("<=2 m corr.", 13), ("hdg as is", 11), ("hdg corr.", 11), ("found px", 10)
    head = f"{'shift px':>9}" + "".join(f"{c:>{w}}" for c, w in cols) + f"{'ring ms':>9}"
    print(head)
    print("-" * len(head))
    for shift in [float(s) for s in a.shifts.split(",")]:
        err = {"as is": [], "corrected": []}
        herr: dict[str, list[float]] = {"as is": [], "corrected": []}
        found: list[float] = []
        cost = 0.0
        for k, s0 in enumerate(starts):
            win = poses[s0 : s0 + n]
            per = replace(look, lens_shift_px=shift)
            frames = [f for _, f in render_frames(scene, lens, win, per, seed=a.seed * 1000 + k)]
            truth = win[-1]
            times = np.arange(n) / conf["model_fps"]
            t = time.perf_counter()
            corrected_lens(lens, frames[:FIRST])  # what the correction adds to a clip: its ring
            cost += time.perf_counter() - t
            clip = ClipLens(lens, lambda lz: Extractor(lz, conf).spectrum)
            spec_c = np.stack(list(clip.spectra(frames)))
            found.append(clip.fit.moved_px if clip.fit else float("nan"))
            for name, spec in (("as is", plain.spectra(frames)), ("corrected", spec_c)):
                e = loc.estimate(spec, times)
                err[name].append(float(np.hypot(e.x - truth.x, e.y - truth.y)))
                herr[name].append(abs(float(wrap_deg(e.heading - truth.heading))))
        w = {k: np.mean(np.array(v) <= 2.0) for k, v in err.items()}
        h = {k: np.median(v) for k, v in herr.items()}
        print(
            f"{shift:>9.0f}{w['as is']:>13.1%}{w['corrected']:>13.1%}{h['as is']:>10.2f}°{h['corrected']:>10.2f}°"
            f"{np.nanmedian(found):>10.2f}{1000 * cost / len(starts):>9.0f}",
            flush=True,
        )


if __name__ == "__main__":
    main()
