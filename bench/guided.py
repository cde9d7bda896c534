"""Guided to a place: what the route guide tells a walker, on walks nobody drove by hand (issue 14).

bench/tracking.py judges the tracked pose second by second; a guided user hears only what the
guide (route.py) makes of it, and the one sentence that ends the guidance is "You have arrived".
Here every family's walk with three stops (bench/tracking.py `stops`, rendered once beside the
query walk) is cut at its stops, and each stop is a destination: a place at the spot where the
walker stands. The guidance towards it starts APPROACH_M of walking before the stop (or where the
walker set off, the walk's start or the end of the stop before, when that is nearer), as a user
who chose the place there and pressed Start: the walks loop round their venues, and a walker
who goes the long way round is rightly told "off the route"; over the last 30 m the walk is the
route (the guide fed the truth, below, says whether it was). It runs on until GO_ON_S after the
walker leaves the stop (the walk goes on; a guide that never said arrival there is left behind).

The phone is the app's guided loop: a new tracking session at the start, its first request
filming 1 s, then 2 s filmed every 2.5 s, without and with the phone's motion sensors (the walk's
imu.json, as bench/tracking.py). Each answer's tracked pose goes through `route.guide` as the
server's guided locate passes it (route planned from the pose at the first answer, the guide's
state carried from answer to answer). Beside it, the same guide fed the truth (the walker's
position and heading, confidence 1): where it says "off the route", the walk itself left the
planned route (a walk is not always the shortest way), which no pose is to blame for.

Per split and phone, over the destinations:
  arrived, right  "You have arrived" said while the walker was within RIGHT_M of the place
                  (the guide's 2 m plus a metre of pose);
  arrived, wrong  said while the walker was further (a user told to stop at the wrong door);
  never           no arrival said before the walker had left the stop GO_ON_S behind;
  probably        "You are probably at ..." said (`probably_arrived`), and of those, said while
                  the walker was further than RIGHT_M;
  delay           seconds from the walker first within 2 m of the place to the arrival said
                  (median and worst, right arrivals);
  off the route   "You are off the route" said per destination, by the tracked guide and by the
                  guide fed the truth.
The rules side by side from the same answers: arrival said as a fact from 0.8 once tracking
has settled (no more than a third of the last 30 s of answers low: the guide now), from 0.8 alone,
and from 0.5 (the guide before `probably_arrived`: every pose it acts on).

And a walker where the venue was never modelled (as bench/elsewhere.py's look-alike: the same
family's other seed, another building of the same kind), guided towards each of the venue's own
destinations for the whole of that building's walk with stops: every arrival said there is
wrong, and so is every "probably at"; "You may be outside the mapped area" (`not_here`) is right
there. And each family's whole walk with stops guided towards its last stop (a minute and more:
long enough for `not_here`, which is wrong in the venue).

    python -m bench.guided [--families all|tuning|held-out|NAME,...] [--seeds 0,1] [--json OUT] [--set KEY=JSON]
"""

from __future__ import annotations

import argparse
import functools
import json
import sys
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from bench.common import machine
from bench.tracking import Walk, graph_tracker, stops_walk, venue_graph, venues, walk, walk_imu
from bench.venues import dataset, family_names, settings
from omninav import route as rt
from omninav import walkgraph as wg
from omninav.aggregate import SURE, confidence, sequence
from omninav.locate import Locator
from omninav.motion import Imu
from omninav.synth.families import FAMILIES
from omninav.tracking import Tracker

EVERY_S = 2.5  # the app's guided loop: a request every 2.5 s ...
FILM_S = 2.0  # ... filming 2 s (its first request 1 s)
APPROACH_M = 30.0  # the guidance starts this much walking before the stop
GO_ON_S = 5.0  # the guidance runs on this long after the walker leaves the stop
RIGHT_M = 3.0  # an arrival said with the walker this near the place is right (ARRIVE_M + 1 m of pose)
LOW = 0.5  # config.py LOW_CONFIDENCE: the guide's own "not sure" line, as the server passes it
# arrival said as a fact: (from this confidence, with tracking settled over this many seconds; 0: not asked)
RULES = {"0.8, settled (now)": (SURE, rt.SETTLE_S), "0.8": (SURE, 0.0), "0.5 (before)": (LOW, 0.0)}


@dataclass(frozen=True)
class Truth:
    """The walker's own pose, for the guide fed the truth."""

    x: float
    y: float
    heading: float
    floor: str = "1"
    confidence: float = 1.0
    ambiguous: bool = False


def stops(walk_path: dict[str, Any]) -> list[tuple[float, float, float, float]]:
    """The walk's stops from its walk path: (x, y, t arrived, t left) where a waypoint is repeated."""
    wps = walk_path["waypoints"]
    return [
        (float(a["x"]), float(a["y"]), float(a["t"]), float(b["t"]))
        for a, b in zip(wps, wps[1:], strict=False)
        if a["x"] == b["x"] and a["y"] == b["y"] and b["t"] > a["t"]
    ]


def ends_of(w: Walk, t0: float, t1: float, fps: float) -> list[tuple[slice, float]]:
    """The guided loop's requests between t0 and t1: (the frames it filmed, its time)."""
    n = int(round(fps))
    out: list[tuple[slice, float]] = []
    first = int(np.searchsorted(w.t, t0 - 1e-6))
    at = w.t[first] + 1.0 - 0.5 / fps
    while at <= min(t1, w.t[-1]) + 1e-6:
        e = int(np.searchsorted(w.t, at - 1e-6))
        film = 1.0 if not out else FILM_S
        out.append((slice(max(first, e - int(round(film * n)) + 1), e + 1), float(w.t[e])))
        at += EVERY_S
    return out


def guided(
    loc: Locator,
    tr: Tracker,
    graph: wg.WalkGraph,
    w: Walk,
    imu: Imu | None,
    dest: tuple[float, float, float, float],
    t0: float,
) -> dict[str, Any]:
    """One destination: the tracked guide under each rule and the guide fed the truth, answer by answer."""
    x, y, t_in, t_out = dest
    place = {"id": "stop", "name": "the stop", "floor": "1", "x": x, "y": y}
    node = wg.attach(graph, [place])[wg.place_key(place)]
    fps = float(loc.conf["model_fps"])
    state = None
    t_prev: float | None = None
    guides: dict[str, Any] = {rule: None for rule in RULES} | {"truth": None}
    said: dict[str, list[dict[str, Any]]] = {k: [] for k in guides}
    done: set[str] = set()
    poses: list[dict[str, Any]] = []  # every answer's tracked pose: its confidence, where it was
    for s, t_now in ends_of(w, t0, t_out + GO_ON_S, fps):
        m, evidence = w.matches(loc, s)
        times = w.t[s]
        motion = imu.motion(t_prev, t_now) if imu is not None and t_prev is not None else None
        est = sequence(m, loc.xy, times, loc.conf)  # the clip alone, as "Where am I?" answers it
        own = loc.own_answers(est, len(times), "sequence")
        state, pose = tr.update_clip(state, evidence, times, t_now, motion, own)
        t_prev = t_now
        e = s.stop - 1
        off_m = float(np.hypot(w.xy[e, 0] - x, w.xy[e, 1] - y))  # the walker from the place
        truth = Truth(float(w.xy[e, 0]), float(w.xy[e, 1]), float(w.heading[e]))
        poses.append(
            {
                "t": t_now - t0,
                "confidence": pose.confidence,
                "ambiguous": pose.ambiguous,
                "off_m": off_m,
                "to_m": float(np.hypot(pose.x - x, pose.y - y)),
                "single_to_m": float(np.hypot(est.x - x, est.y - y)),
                "single_confidence": confidence(est, loc.conf),
            }
        )
        for k in guides:
            if k in done:
                continue
            p, (sure, settle) = (truth, (SURE, 0.0)) if k == "truth" else (pose, RULES[k])
            g, guides[k] = rt.guide(
                graph, None, place, node, p, guides[k], t_now, [place], low_confidence=LOW, sure=sure, settle_s=settle
            )
            guides[k] = json.loads(json.dumps(guides[k]))  # the server stores it as JSON
            if g["speak"]:
                said[k].append({"t": t_now - t0, "kind": g["kind"], "off_m": off_m, "confidence": p.confidence})
            if g["kind"] == "arrived":  # the app stops filming
                done.add(k)
    near = np.flatnonzero(np.hypot(w.xy[:, 0] - x, w.xy[:, 1] - y) <= rt.ARRIVE_M)
    near = near[(w.t[near] >= t0) & (w.t[near] <= t_out)]
    return {"t_near": float(w.t[near[0]]) - t0 if len(near) else None, "said": said, "poses": poses}


def both(
    loc: Locator,
    tr: Tracker,
    graph: wg.WalkGraph,
    w: Walk,
    imu: Imu,
    dest: tuple[float, float, float, float],
    t0: float,
) -> list[dict[str, Any]]:
    """`guided` without and with the phone's sensors, each with its "imu"."""
    return [{"imu": use, **guided(loc, tr, graph, w, imu if use else None, dest, t0)} for use in (False, True)]


def verdicts(d: dict[str, Any], rule: str) -> dict[str, Any]:
    """What a destination's walker heard under `rule`: arrival right / wrong / never, probably, delay, off the route."""
    said = d["said"][rule]
    arr = next((s for s in said if s["kind"] == "arrived"), None)
    prob = [s for s in said if s["kind"] == "probably_arrived"]
    v: dict[str, Any] = {
        "arrived": "never" if arr is None else "right" if arr["off_m"] <= RIGHT_M else "wrong",
        "probably": len(prob) > 0,
        "probably_far": any(s["off_m"] > RIGHT_M for s in prob),
        "off_route": sum(s["kind"] == "off_route" for s in said),
        "not_here": sum(s["kind"] == "not_here" for s in said),
        "delay": None,
    }
    if arr is not None and v["arrived"] == "right" and d["t_near"] is not None:
        v["delay"] = arr["t"] - d["t_near"]
    return v


def groups(out: list[dict[str, Any]], kind: str) -> Iterator[tuple[str, str, list[dict[str, Any]]]]:
    """The destinations of `kind` by split and phone: (split, "no IMU" | "IMU", them), none empty."""
    for split in ("tuning", "held-out"):
        for use in (False, True):
            ds = [d for d in out if d["split"] == split and d["imu"] == use and d["kind"] == kind]
            if ds:
                yield split, "IMU" if use else "no IMU", ds


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--families", default="all")
    ap.add_argument("--seeds", default="0,1")
    ap.add_argument("--json", type=Path, help="every destination's sentences, here")
    ap.add_argument("--set", action="append", default=[], metavar="KEY=JSON", help="a tracking setting (tuning)")
    a = ap.parse_args()
    print(f"machine: {machine()}")
    over = settings(a.set)
    if over:
        print(f"settings: {over}")
    out: list[dict[str, Any]] = []
    seeds = [int(s) for s in a.seeds.split(",")]
    loc_of = venues(over)

    @functools.cache
    def walk_of(name: str, seed: int) -> Walk:
        """The venue's walk with stops (its spectra read once); matched against its own venue."""
        return walk(dataset(name, seed), loc_of(name, seed), stops_walk(dataset(name, seed), name, seed))

    for name in family_names(a.families):
        for seed in seeds:
            root = dataset(name, seed)
            loc = loc_of(name, seed)
            graph = venue_graph(loc)
            tr = graph_tracker(loc, over, graph=graph)
            w = walk_of(name, seed)
            imu = walk_imu(root, "stops", seed)

            base = {"family": name, "split": FAMILIES[name].split, "seed": seed}
            walked = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(w.xy, axis=0).T))])
            set_off = float(w.t[0])
            dests = stops(json.loads((root / "stops_walk_path.json").read_text()))
            for k, dest in enumerate(dests):
                at = walked[int(np.searchsorted(w.t, dest[2] - 1e-6))]
                t0 = max(set_off, float(w.t[int(np.searchsorted(walked, at - APPROACH_M))]))
                out += [
                    {**base, **d, "walk": seed, "stop": k, "kind": "own"}
                    for d in both(loc, tr, graph, w, imu, dest, t0)
                ]
                set_off = dest[3]  # the next destination's guidance starts after the walker leaves this one
            # the whole walk guided towards its last stop (a minute and more: what "not here" sees in the venue)
            whole = both(loc, tr, graph, w, imu, dests[-1], float(w.t[0]))
            out += [{**base, **d, "walk": seed, "stop": len(dests) - 1, "kind": "whole"} for d in whole]
            print(f"  {name}/{seed}: {len(dests)} destinations", file=sys.stderr, flush=True)
            for other in seeds:  # the look-alike building's walk, guided towards this venue's places
                if other == seed:
                    continue
                ow = walk_of(name, other)
                ow = Walk(ow.t, ow.xy, ow.heading, ow.spec)  # its matches: this venue's
                oimu = walk_imu(dataset(name, other), "stops", other)  # what that walker's phone felt
                end = float(ow.t[-1]) - GO_ON_S
                for k, dest in enumerate(dests):
                    ds = both(loc, tr, graph, ow, oimu, (dest[0], dest[1], end, end), float(ow.t[0]))
                    out += [{**base, **d, "walk": other, "stop": k, "kind": "look-alike"} for d in ds]

    print(
        "\n| split | phone | arrival from | destinations | arrived, right | arrived, wrong | never | "
        "delay (median / worst) | probably said (of them far) | off the route said (truth-fed guide) |\n"
        "| --- | --- | --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: |"
    )
    for split, phone, ds in groups(out, "own"):
        truth_off = sum(verdicts(d, "truth")["off_route"] for d in ds)
        for rule in RULES:
            vs = [verdicts(d, rule) for d in ds]
            n = {k: sum(v["arrived"] == k for v in vs) for k in ("right", "wrong", "never")}
            delays = [v["delay"] for v in vs if v["delay"] is not None]
            dl = f"{np.median(delays):.1f} / {max(delays):.1f} s" if delays else "-"
            prob = sum(v["probably"] for v in vs)
            far = sum(v["probably_far"] for v in vs)
            off = sum(v["off_route"] for v in vs)
            print(
                f"| {split} | {phone} | {rule} | {len(ds)} | {n['right']} | "
                f"**{n['wrong']}** | {n['never']} | {dl} | {prob} ({far}) | {off} ({truth_off}) |"
            )
    print(
        "\nGuided in a look-alike building the venue never modelled (every sentence below is wrong):\n\n"
        '| split | phone | arrival from | guidances | "You have arrived" said | "probably at" said | '
        '"outside the mapped area" said |\n| --- | --- | --- | ---: | ---: | ---: | ---: |'
    )
    for split, phone, ds in groups(out, "look-alike"):
        for rule in RULES:
            vs = [verdicts(d, rule) for d in ds]
            arrived = sum(v["arrived"] != "never" for v in vs)
            prob = sum(v["probably"] for v in vs)
            lost = sum(v["not_here"] > 0 for v in vs)
            print(f"| {split} | {phone} | {rule} | {len(ds)} | **{arrived}** | {prob} | {lost} |")
    print(
        '\n"You may be outside the mapped area" (`not_here`), the guide now: guidances that heard it\n\n'
        "| split | phone | in the venue, the whole walk guided (wrong) | in a look-alike building (right) |\n"
        "| --- | --- | ---: | ---: |"
    )
    now = next(iter(RULES))
    heard = {
        (split, phone, kind): f"{sum(verdicts(d, now)['not_here'] > 0 for d in ds)} of {len(ds)}"
        for kind in ("whole", "look-alike")
        for split, phone, ds in groups(out, kind)
    }
    for split, phone, _ in groups(out, "whole"):
        print(
            f"| {split} | {phone} | {heard[split, phone, 'whole']} | {heard.get((split, phone, 'look-alike'), '-')} |"
        )
    if a.json:
        a.json.write_text(json.dumps(out))


if __name__ == "__main__":
    main()
