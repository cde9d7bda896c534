"""Accuracy on the synthetic venue, the paper's method and each of our additions in the same run.

Renders (once, cached) the default synthetic venue at 960x720: a modelling walk and an independent
query walk with every perturbation of issue 2 (lateral offsets up to 0.5 m, camera height
1.15-1.55 m, tilt up to 5 degrees, light x0.6-1.3 with colour casts, up to three people, 2 px lens
shift, sensor noise, MPEG-4 compression). Each configuration models the venue through the real
modelling path and evaluates 1 s clips (10 frames at 10 fps) of the query walk.

    python -m bench.accuracy [--seed 0] [--root DIR] [--cross-device] [--only default]
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

from bench.common import machine
from bench.venues import cached_venue
from omninav.evaluate import Evaluation, evaluate, plot
from omninav.lens import load_lens
from omninav.presets import TWO_BANDS, resolve
from omninav.synth import equirect_lens, make_dataset, upgrade_names
from omninav.walk_path import load_walk_path

O = ["I", "O1", "O2", "dI", "dO1", "dO2"]
CONFIGS = [  # label, preset, overrides, aggregation
    ("paper: I curve, median", "paper", {}, "median"),
    ("paper: I curve, sequence", "paper", {"aggregate": "sequence"}, "sequence"),
    ("six curves, median", "six", {}, "median"),
    ("six curves, sequence", "six", {}, "sequence"),
    ("+ gray world", "six", {"gray_world": True}, "sequence"),
    ("+ opponent colours", "six", {"gray_world": True, "channels": O}, "sequence"),
    ("+ two bands, K=16", "default", {"soft_clip_sd": None, **TWO_BANDS}, "sequence"),
    ("+ soft clipping", "default", TWO_BANDS, "sequence"),
    ("+ five bands of intensity", "default", {"level_iters": None}, "sequence"),
    ("default: + levelled", "default", {}, "sequence"),
]


def dataset(root: Path, seed: int, equirect: bool = False) -> Path:
    if not (root / "query.mp4").exists():
        t = time.perf_counter()
        print(f"rendering {root} ...", file=sys.stderr, flush=True)
        make_dataset(root, seed=seed, model_lens=equirect_lens() if equirect else None)
        print(f"rendered in {time.perf_counter() - t:.0f} s", file=sys.stderr, flush=True)
    return upgrade_names(root)


def run(root: Path, label: str, preset: str, over: dict, agg: str, tag: str, clip_s: float = 1.0) -> Evaluation:
    loc = cached_venue(root, tag, {**resolve(preset), **over})
    ev = evaluate(
        loc,
        root / "query.mp4",
        load_walk_path(root / "query_walk_path.json"),
        load_lens(root / "lens.json"),
        agg,
        clip_s,
    )
    plot(ev, loc, root / f"{loc.venue_id}-{agg}.png", title=label)
    return ev


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--root", type=Path)
    ap.add_argument("--cross-device", action="store_true", help="also: venue from a 360 camera")
    ap.add_argument("--only", help="run only configurations whose label contains this")
    a = ap.parse_args()
    root = dataset(a.root or Path("data") / f"bench-venue-{a.seed}", a.seed)
    print(f"machine: {machine()}")
    print(f"venue: {root} (seed {a.seed})")
    head = (
        f"{'configuration':<30}{'clips':>6}{'<=1 m':>8}{'<=2 m':>8}{'med m':>7}{'hdg med':>9}{'conf>=.8':>9}{'ok':>6}"
    )
    print(head)
    print("-" * len(head))
    rows = [c for c in CONFIGS if not a.only or a.only in c[0]]
    cross = []
    if a.cross_device:
        eq = dataset(root.with_name(root.name + "-equirect"), a.seed, equirect=True)
        cross = [("360-camera venue, donut clips", "default", {}, "sequence", eq)]
    for label, preset, over, agg, *r in [(*c, root) for c in rows] + cross:
        s = run(r[0], label, preset, over, agg, "v").summary()
        ok = s["confident_within_2m"]
        print(
            f"{label:<30}{s['clips']:>6}{s['within_1m']:>8.1%}{s['within_2m']:>8.1%}"
            f"{s['median_err_m']:>7.2f}{s['median_heading_err_deg']:>8.2f}°"
            f"{s['confident_share']:>9.0%}{'' if ok is None else f'{ok:.0%}':>6}",
            flush=True,
        )


if __name__ == "__main__":
    main()
