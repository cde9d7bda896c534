"""The quality map on the twin venue (docs/benchlog.md, "Quality map"): what the map says against
what an independent walk finds, for the default preset and the same with one setting changed.

The twin venue (scene.py `twin`, half-resolution donut, 10 fps; as tests/engine/test_quality.py builds
it): a ring whose west and east corridors are one corridor turned half round. Per seed and
setting: the map's green / amber / red segments, how many of the twins' straight middles it
flags, whether the segments outside the twins are green, the query walk's clips within 2 m and
"green by the map's rule" (within 2 m, margin >= quality.AMBIGUOUS_MARGIN), and the margins of
the query walk's right answers (10th percentile / median / 90th, and how many fall below the
rule's margin), printed as markdown with the machine.

    python -m bench.quality_twin [--seeds 5,7] [--set soft_clip_sd=null] [--out DIR]
"""

from __future__ import annotations

import argparse
import json
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

from bench.common import machine
from omninav.evaluate import evaluate_walk
from omninav.lens import load_lens
from omninav.locate import Locator
from omninav.model_venue import model_video
from omninav.presets import resolve
from omninav.quality import AMBIGUOUS_MARGIN, RADIUS_M, quality_map
from omninav.store import Store
from omninav.synth import Dataset, make_dataset
from omninav.synth.layouts import TWINS
from omninav.synth.scene import build_scene
from omninav.walk_path import load_walk_path

Area = list[float]


def _inside(p: Any, a: Area) -> bool:
    return a[0] <= p[0] <= a[2] and a[1] <= p[1] <= a[3]


def margins(m: np.ndarray) -> str:
    if not len(m):
        return "-"
    p10, p50, p90 = np.percentile(m, [10, 50, 90])
    return f"{p10:.3f} / {p50:.3f} / {p90:.3f} ({int((m < AMBIGUOUS_MARGIN).sum())} of {len(m)} below)"


def measure(ds: Dataset, seed: int, settings: dict[str, Any], root: Path) -> dict[str, Any]:
    st = Store(root)
    lens = load_lens(ds.root / "model_lens.json")
    model_video(st, "twin", ds.model_video, load_walk_path(ds.model_walk_path), lens, settings=settings)
    q = quality_map(st.load("twin"), ds.scene.places, {})
    twins = [build_scene(seed, "twin").places[i]["area"] for i in TWINS]
    middles = [[x0, y0 + 3.4, x1, y1 - 3.4] for x0, y0, x1, y1 in twins]  # test_quality.py's
    segs = q["segments"]
    count = {v: sum(s["verdict"] == v for s in segs) for v in ("green", "amber", "red")}
    flagged = [s["verdict"] != "green" for s in segs if any(_inside(s["points"][-1], c) for c in middles)]
    rest = [s["verdict"] == "green" for s in segs if not any(_inside(s["points"][-1], t) for t in twins)]
    walk = evaluate_walk(Locator(st, "twin"), ds.query_video, load_walk_path(ds.query_walk_path), load_lens(ds.lens))
    clips = walk["clips"]
    right = np.array([c["answer"]["margin"] for c in clips if c["error_m"] <= RADIUS_M])
    return {
        "map": f"{count['green']} / {count['amber']} / {count['red']} ({100 * count['green'] / len(segs):.0f} % green)",
        "middles": f"{sum(flagged)} of {len(flagged)}",
        "rest": f"{sum(rest)} of {len(rest)}",
        "within": f"{100 * len(right) / len(clips):.1f} %",
        "green_rule": f"{100 * int((right >= AMBIGUOUS_MARGIN).sum()) / len(clips):.1f} %",
        "margins": margins(right),
        "sentence": q["sentence"].split(";")[0:3],
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seeds", default="5,7")
    ap.add_argument("--set", action="append", default=[], metavar="KEY=JSON", help="the other setting to compare")
    ap.add_argument("--out", type=Path, help="render and model here (default: a temporary folder)")
    a = ap.parse_args()
    other = {k: json.loads(v) for k, v in (s.split("=", 1) for s in a.set)} or {"soft_clip_sd": None}
    configs = {
        "default": resolve("default"),
        ", ".join(f"{k}={v}" for k, v in other.items()): {**resolve("default"), **other},
    }
    print(f"machine: {machine()}")
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        root = a.out or Path(tmp)
        for seed in (int(s) for s in a.seeds.split(",")):
            t0 = time.perf_counter()
            ds = make_dataset(root / f"twin-{seed}", seed=seed, layout="twin", scale=0.5)
            for name, settings in configs.items():
                r = measure(ds, seed, settings, root / f"store-{seed}-{len(rows)}")
                rows.append((seed, name, r))
                print(f"seed {seed}, {name}: {'; '.join(r['sentence'])}", flush=True)
            print(f"seed {seed}: {time.perf_counter() - t0:.0f} s", flush=True)
    print()
    print(
        "| seed | settings | map: green / amber / red | twins' middles flagged | outside the twins green "
        "| query walk within 2 m | green by the map's rule | right answers' margin p10 / median / p90 |"
    )
    print("| ---: | --- | ---: | ---: | ---: | ---: | ---: | ---: |")
    for seed, name, r in rows:
        print(
            f"| {seed} | {name} | {r['map']} | {r['middles']} | {r['rest']} | {r['within']} | {r['green_rule']} "
            f"| {r['margins']} |"
        )


if __name__ == "__main__":
    main()
