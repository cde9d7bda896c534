"""A user where the venue was never modelled: how often does omninav say it is sure anyway?

Every other benchmark films its queries inside the modelled venue, so its confidence is judged
only against places the venue knows. A user also walks where the admin never filmed: a room off
the corridor, another wing, another floor built like the modelled one. Nothing in the venue is
right then, and every answer given as sure (confidence >= 0.8, the app's "sure") is wrong.

For each venue family and seed (bench/venues.py renders and models them; bench/tracking.py's
walk spectra are reused), the venue is asked about query walks filmed elsewhere:

  look-alike   the same family's other seed: another building of the same kind (the same decor
               and lighting, another layout), as another floor or wing of the building would be;
  other        another family of the same split, the same seed: another kind of building.

Each walk is answered as bench/tracking.py answers the venue's own walk: every 1 s the 1 s clip
ending there, alone (a locate) and through the tracking filter (no IMU); and standing still, a
1 s clip at 10, 30 and 50 s of the walk held for 30 s (the phone filming the same spot), without
and with the phone's sensors (no step, no turn: what the app sends of a phone held still). Printed
per split and kind, over the seconds after the first 5: the share of answers given as sure, and
the share said "not sure" (confidence < 0.5, what the app says as "not sure"). The venue's own
walks, the same way, beside them (the share of sure answers a user inside the venue gets).

    python -m bench.elsewhere [--families all|tuning|held-out|NAME,...] [--seeds 0,1] [--set KEY=JSON]
                              [--json OUT]
"""

from __future__ import annotations

import argparse
import functools
import json
import sys
from pathlib import Path
from typing import Any

import numpy as np

from bench.common import machine
from bench.tracking import SKIP_S, Walk, graph_tracker, run, venues, walk
from bench.venues import dataset, family_names, settings
from omninav.aggregate import SURE
from omninav.motion import Imu
from omninav.synth.families import FAMILIES

LOW = 0.5  # below it the app says "not sure" (config.py LOW_CONFIDENCE)
STILL_AT_S = (10.0, 30.0, 50.0)  # where along a walk the phone is held still
STILL_FOR_S = 30.0
STILL_IMU = Imu(np.zeros(0), np.array([-1e6, 1e6]), np.zeros(2))  # a phone's sensors: no step, no turn


def still(w: Walk, at: float, fps: float, hold_s: float = STILL_FOR_S) -> Walk | None:
    """The 1 s clip at `at` s of the walk, filmed again and again for `hold_s` (a phone held still
    on one spot): its frames repeated, with times going on (None: the walk is shorter)."""
    i = int(np.searchsorted(w.t, w.t[0] + at - 1e-6))
    n = int(round(fps))
    if i + n > len(w.t):
        return None
    reps = int(np.ceil(hold_s))
    spec = np.concatenate([w.spec[i : i + n]] * reps)
    t = w.t[i] + np.arange(len(spec)) / fps
    return Walk(t, np.repeat(w.xy[i : i + 1], len(t), 0), np.repeat(w.heading[i : i + 1], len(t), 0), spec)


def answered(rows: list[dict[str, Any]]) -> dict[str, list[float]]:
    """The confidences after the first SKIP_S seconds: tracked and single."""
    rs = [r for r in rows if r["t"] >= SKIP_S]
    return {
        "tracked": [r["confidence"] for r in rs],
        "single": [r["single_confidence"] for r in rs],
        "tracked_err_m": [r["err_m"] for r in rs],
        "single_err_m": [r["single_err_m"] for r in rs],
        # the single answer's confidence inputs (a model fit with clips filmed elsewhere)
        **{f"single_{k}": [r[f"single_{k}"] for r in rs] for k in ("support", "rival", "agree")},
    }


def shares(c: list[float]) -> tuple[int, float, float]:
    v = np.asarray(c)
    return len(v), float(np.mean(v >= SURE)) if len(v) else 0.0, float(np.mean(v < LOW)) if len(v) else 0.0


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--families", default="all")
    ap.add_argument("--seeds", default="0,1")
    ap.add_argument("--set", action="append", default=[], metavar="KEY=JSON", help="a tracking setting (tuning)")
    ap.add_argument("--json", type=Path, help="every answer's confidences, here")
    a = ap.parse_args()
    over = settings(a.set)
    print(f"machine: {machine()}")
    if over:
        print(f"settings: {over}")
    names = family_names(a.families)
    seeds = [int(s) for s in a.seeds.split(",")]
    loc_of = venues(over)
    spectra = functools.cache(lambda name, seed: walk(dataset(name, seed), loc_of(name, seed)))

    def walk_of(name: str, seed: int) -> Walk:
        """The walk's spectra, read once; a new Walk for each venue (its matches are that venue's)."""
        w = spectra(name, seed)
        return Walk(w.t, w.xy, w.heading, w.spec)

    out: list[dict[str, Any]] = []
    for name in names:
        split = FAMILIES[name].split
        for seed in seeds:
            loc = loc_of(name, seed)
            fps = float(loc.conf["model_fps"])
            tr = graph_tracker(loc, over)
            queries = [("own", name, seed)]
            queries += [("look-alike", name, s) for s in seeds if s != seed]
            queries += [("other", n, seed) for n in names if n != name and FAMILIES[n].split == split]
            for kind, wname, wseed in queries:
                w = walk_of(wname, wseed)
                where = {"split": split, "kind": kind, "venue": f"{name}/{seed}", "walk": f"{wname}/{wseed}"}
                out.append({**where, "mode": "walking", **answered(run(loc, tr, w, 1.0, None, 0.0, True))})
                for at in STILL_AT_S:
                    sw = still(w, at, fps)
                    if sw is None:
                        continue
                    # without and with the phone's sensors: no step, no turn (what the app sends then)
                    for mode, imu in (("still", None), ("still, IMU", STILL_IMU)):
                        got = answered(run(loc, tr, sw, 1.0, imu, 0.0, True))
                        out.append({**where, "mode": mode, "at": at, **got})
                print(f"  {name}/{seed} <- {wname}/{wseed} ({kind})", file=sys.stderr, flush=True)

    print(
        "\n| split | walk filmed | phone | seconds | single: sure | single: not sure | tracked: sure | "
        "tracked: not sure |\n| --- | --- | --- | ---: | ---: | ---: | ---: | ---: |"
    )
    words = {"own": "in the venue (its own walk)", "look-alike": "elsewhere: a look-alike building",
             "other": "elsewhere: another kind of building"}  # fmt: skip
    for split in ("tuning", "held-out"):
        for kind in ("own", "look-alike", "other"):
            for mode in ("walking", "still", "still, IMU"):
                rs = [r for r in out if r["split"] == split and r["kind"] == kind and r["mode"] == mode]
                if not rs:
                    continue
                n, s_sure, s_low = shares([c for r in rs for c in r["single"]])
                _, t_sure, t_low = shares([c for r in rs for c in r["tracked"]])
                print(
                    f"| {split} | {words[kind]} | {mode} | {n} | {s_sure:.1%} | {s_low:.1%} | "
                    f"**{t_sure:.1%}** | {t_low:.1%} |"
                )
    # inside the venue the sure answers should be right: how many are not (> 2 m)
    print("\nInside the venue, sure answers further than 2 m (single / tracked):")
    for split in ("tuning", "held-out"):
        for mode in ("walking", "still", "still, IMU"):
            rs = [r for r in out if r["split"] == split and r["kind"] == "own" and r["mode"] == mode]
            if rs:
                bad = [
                    sum(1 for r in rs for c, e in zip(r[who], r[f"{who}_err_m"], strict=True) if c >= SURE and e > 2.0)
                    for who in ("single", "tracked")
                ]
                print(f"  {split}, {mode}: {bad[0]} / {bad[1]}")
    # how many of the held-still spots end sure: a user standing there is told a wrong place
    print("\nSpots held still for 30 s whose last tracked answer is sure (elsewhere: wrong):")
    for split in ("tuning", "held-out"):
        for kind in ("look-alike", "other"):
            for mode in ("still", "still, IMU"):
                rs = [r for r in out if r["split"] == split and r["kind"] == kind and r["mode"] == mode]
                if rs:
                    end = sum(1 for r in rs if r["tracked"] and r["tracked"][-1] >= SURE)
                    print(f"  {split}, {words[kind]} ({mode}): {end} of {len(rs)}")
    if a.json:
        a.json.write_text(json.dumps(out))


if __name__ == "__main__":
    main()
