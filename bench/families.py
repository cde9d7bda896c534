"""Accuracy on venue families: settings chosen on the tuning families, judged on the held-out ones.

Renders (once, cached under data/families/) one venue per family and seed with
synth.families.make_family_dataset, models it through the real modelling path with each
configuration (ours, and the paper's method beside it), extracts the query walk's spectra once
and cuts them into clips of each length. Prints, per family and pooled per split, what issue 13
asks of held-out families: within 2 m, within 1 m, median heading error, and of the answers a
user would trust (confidence >= 0.8) how many there are and how many of them are wrong (> 2 m).

Every answer's confidence features are kept (data/families/<family>-<seed>/rows-*.json), so that
bench/calibrate.py fits the confidence on the tuning families' answers and draws the held-out
families' reliability diagram without running anything again.

    python -m bench.families [--families all|tuning|held-out|NAME,...] [--seeds 0] [--clips 1]
                             [--configs default,paper] [--json OUT]
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import Any

from bench.common import machine
from bench.venues import CONFIGS, family_names, rows_for, settings, summarise
from omninav.presets import resolve
from omninav.synth.families import FAMILIES

HEAD = (
    f"{'family':<20}{'split':<9}{'config':<8}{'clip s':>7}{'clips':>6}{'<=1 m':>8}{'<=2 m':>8}"
    f"{'hdg med':>8}{'conf>=.8':>9}{'wrong':>7}  worst misses (m)"
)


def line(name: str, split: str, config: str, clip: float, s: dict[str, Any]) -> str:
    return (
        f"{name:<20}{split:<9}{config:<8}{clip:>7g}{s['clips']:>6}{s['within_1m']:>8.1%}{s['within_2m']:>8.1%}"
        f"{s['median_heading_deg']:>7.2f}°{s['coverage']:>9.0%}{s['confident_wrong']:>7.1%}  {s['wrong_far_m']}"
    )


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--families", default="all")
    ap.add_argument("--seeds", default="0")
    ap.add_argument("--clips", default="1", help="clip lengths in seconds, comma-separated")
    ap.add_argument("--configs", default="default,paper")
    ap.add_argument("--json", type=Path, help="write every summary here")
    ap.add_argument(
        "--set", action="append", default=[], metavar="KEY=JSON", help="a setting over every configuration (tuning)"
    )
    a = ap.parse_args()
    names = family_names(a.families)
    seeds = [int(s) for s in a.seeds.split(",")]
    clips = [float(c) for c in a.clips.split(",")]
    configs = [c.strip() for c in a.configs.split(",")]
    over = settings(a.set)
    if over:
        print(f"settings over the configurations: {over}")
    print(f"machine: {machine()}")
    print(HEAD)
    print("-" * len(HEAD))
    pooled: dict[tuple[str, str, float], list[dict[str, Any]]] = {}
    out: list[dict[str, Any]] = []
    for name in names:
        for config in configs:
            conf = resolve(CONFIGS[config][0], over)
            for seed in seeds:
                for clip, rows in rows_for(name, seed, config, clips, over).items():
                    s = summarise(rows, conf)
                    print(line(f"{name}/{seed}", FAMILIES[name].split, config, clip, s), flush=True)
                    out.append({"family": name, "seed": seed, "config": config, "clip_s": clip, **s})
                    pooled.setdefault((FAMILIES[name].split, config, clip), []).extend(rows)
    print("-" * len(HEAD))
    for (split, config, clip), rows in sorted(pooled.items()):
        s = summarise(rows, resolve(CONFIGS[config][0], over))
        print(line("ALL", split, config, clip, s))
        out.append({"family": "ALL", "split": split, "config": config, "clip_s": clip, **s})
    if a.json:
        a.json.write_text(json.dumps(out, indent=1))


if __name__ == "__main__":
    main()
