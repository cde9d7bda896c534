"""Tracking while walking (issue 14): the filter's answers per second beside single clips'.

For every venue family and seed (bench/venues.py renders, models and caches them), a walk's
spectra are extracted once (cached beside it) and each clip searched as a locate searches it
(Locator.clip_matches: each second's frames share their candidates); then every 1 s and every 2.5 s (the phone's
pace) the 1 s clip ending there is answered twice: alone (aggregate.sequence, what a locate
without a session answers) and through the tracking filter (tracking.py; fed that answer's
confidence too, as a server's tracked locate does), with only the evidence up to that moment,
without and with the phone's motion (an imu.json of steps and gyroscope yaw with realistic
noise, synth/walks.imu_for, made once beside the walk; and, from 0 s, that IMU with no steps
counted at all: a phone held steady, a wheelchair). Walks: `query`, the
family's query walk (also started afresh at 0, 20, 40, 60 and 80 s), and `stops`, the same walk
with three stops of 3-8 s, rendered once like the query walk. Printed as markdown, per family
and per split (tuning / held-out), over the seconds after the first 5: within 2 m, within 1 m,
median heading error, the answers with confidence >= 0.8 further than 5 m and 2 m; the seconds
of walking a fresh start takes to its first confident answer (and whether it was right); the
worst case (long-bare's walk starts in the middle of a 60 m corridor of identical doors); the CPU
time of an update, on the families and on made-up venues of up to 20,000 frames.

`--fit` fits the filter's confidence (settings.py's track_confidence_coef) on the TUNING families'
walks only (started afresh, every 1 s and 2.5 s, with and without IMU), then judges it on both.

    python -m bench.tracking [--families all] [--seeds 0,1] [--walks query,stops] [--fit]
                             [--set track_beta=20] [--json OUT] [--threads 1]
"""

from __future__ import annotations

import argparse
import fcntl
import functools
import json
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from bench.common import machine, pin_threads
from bench.venues import CONFIDENCE_KEYS, SEARCH_KEYS, dataset, family_names, settings, venue
from omninav.aggregate import SURE, TRACK_CONFIDENCE_INPUTS, confidence, sequence
from omninav.evaluate import query_spectra
from omninav.heading import wrap_deg
from omninav.index import Matches
from omninav.lens import load_lens
from omninav.locate import Locator
from omninav.lookalikes import ALIKE_K, frame_search, look_alikes
from omninav.motion import Imu, Motion, parse_imu
from omninav.presets import DEFAULTS, n_curves, resolve
from omninav.synth.families import FAMILIES, _jpeg, family_venue, pano_width
from omninav.synth.walks import imu_for, poses_from_walk_path, render_frames, with_stops, write_video
from omninav.tracking import Tracker
from omninav.walk_path import load_walk_path
from omninav.walkgraph import WalkGraph, from_frames

SKIP_S = 5.0  # the figures count the seconds after the first 5 of a walk


@dataclass
class Walk:
    """A walk's sampled frames: truth and spectra; each clip is searched as a locate searches it
    (Locator.clip_matches: its frames share their candidates by the second), once per clip."""

    t: np.ndarray
    xy: np.ndarray
    heading: np.ndarray
    spec: np.ndarray  # (F, C, K)
    imu: Imu | None = None
    seen: dict[tuple[int, int], tuple[Matches, Matches]] = field(default_factory=dict)

    def matches(self, loc: Locator, s: slice) -> tuple[Matches, Matches]:
        """The clip's matches and the tracker's evidence (Locator.clip_matches)."""
        key = (s.start, s.stop)
        if key not in self.seen:
            self.seen[key] = loc.clip_matches(self.spec[s], self.t[s])[:2]
        return self.seen[key]


def searched(over: dict[str, Any]) -> dict[str, Any]:
    """The --set keys that are the venue's, not the tracker's: how a clip is searched
    (SEARCH_KEYS: --set shared_candidates=false reaches the search) and the venue's confidence
    model (CONFIDENCE_KEYS: the single clip's answer, and the cap of a phone held still)."""
    return {k: v for k, v in over.items() if k in SEARCH_KEYS or k in CONFIDENCE_KEYS}


def venues(over: dict[str, Any]) -> Callable[[str, int], Locator]:
    """(family, seed) -> its venue with the --set keys that are the venue's (`searched`), each loaded
    once a run (a bench that visits a venue more than once: its own walk, elsewhere's)."""
    return functools.cache(lambda name, seed: venue(dataset(name, seed), "default", searched(over)))


def venue_graph(loc: Locator) -> WalkGraph:
    """The family venue's walk graph (one floor, "1")."""
    return from_frames(loc.gen.frames, ["1"] * max(1, len(loc.gen.videos)))


def graph_tracker(loc: Locator, conf: dict[str, Any] | None = None, graph: WalkGraph | None = None) -> Tracker:
    """A tracker over the venue's walk graph (`graph`, when the caller built it already)."""
    return loc.new_tracker(venue_graph(loc) if graph is None else graph, np.full(len(loc.xy), "1"), conf)


def stops_walk(root: Path, family: str, seed: int) -> str:
    """The family's query walk with three stops of 3-8 s (synth/walks.with_stops), rendered as
    its query walk is (the same scene, lens, perturbations and compression) once, beside it."""
    name = "stops"
    video = root / f"{name}.mp4"
    with open(root.parent / f".{root.name}-{name}.lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        if not video.exists():
            t0 = time.perf_counter()
            v = family_venue(family, seed)
            fam = v.family
            walk_path = with_stops(
                json.loads((root / "query_walk_path.json").read_text()), np.random.default_rng(seed + 50)
            )
            lens = load_lens(root / "lens.json")
            poses = poses_from_walk_path(walk_path, fam.query_perturb, np.random.default_rng(seed + 53))
            frames = (
                f for _, f in render_frames(v.query_scene, lens, poses, fam.query_perturb, seed + 54, pano_width(lens))
            )
            part = video.with_name(f"{name}.part.mp4")
            write_video(part, _jpeg(frames, fam.query_jpeg), float(walk_path["fps"]), lens.image_size)
            (root / f"{name}_walk_path.json").write_text(json.dumps(walk_path, indent=1))
            part.rename(video)
            print(f"rendered {video} in {time.perf_counter() - t0:.0f} s", file=sys.stderr, flush=True)
    return name


def walk(root: Path, loc: Locator, name: str = "query") -> Walk:
    """The family's query walk's spectra (cached beside the venue)."""
    cache = root / "bench-data" / f"tracking-{name}-spec.npz"
    key = f"{loc.venue_id}/{loc.generation}/{name}"
    if cache.exists():
        z = np.load(cache)
        if str(z["key"]) == key:
            return Walk(z["t"], z["xy"], z["heading"], z["spec"])
    spec, t, xy, hd, _ = query_spectra(
        loc, root / f"{name}.mp4", load_walk_path(root / f"{name}_walk_path.json"), load_lens(root / "lens.json")
    )
    np.savez(cache, key=key, t=t, xy=xy, heading=hd, spec=spec)
    return Walk(t, xy, hd, spec)


def walk_imu(root: Path, name: str = "query", seed: int = 0) -> Imu:
    """The walk's imu.json (made once, deterministically, beside it)."""
    path = root / f"{name}_imu.json"
    if not path.exists():
        walk_path = json.loads((root / f"{name}_walk_path.json").read_text())
        path.write_text(json.dumps(imu_for(walk_path, np.random.default_rng(seed + 77))))
    return parse_imu(json.loads(path.read_text()))


def imu_word(imu: bool | str) -> str:
    return imu if isinstance(imu, str) else ("yes" if imu else "no")


def no_steps(imu: Imu) -> Imu:
    """The walk's IMU from a phone that counts no steps while its user walks (held steady, a slow
    walker, a wheelchair, a stalled step feed): 0 steps every update, the gyroscope as it was."""
    return Imu(np.zeros(0), imu.yaw_t, imu.yaw_deg)


def run(
    loc: Locator,
    tr: Tracker,
    w: Walk,
    every: float = 1.0,
    imu: Imu | None = None,
    start: float = 0.0,
    single: bool = True,
    film: str = "1 s",
) -> list[dict[str, Any]]:
    """Every `every` s from `start` + 1 s: the clip of `film` ending there ("1 s"; "2 s" as the
    app films a guided walk and "Keep telling me" now, "3 s" as "Keep telling me" filming its whole
    interval (tried); the first always 1 s; the filter walks a longer clip second by second,
    Tracker.update_clip as Locator.track does), alone and through the filter."""
    fps = loc.conf["model_fps"]
    n = int(round(fps))
    rows: list[dict[str, Any]] = []
    state = None
    t_prev = None
    first = int(np.searchsorted(w.t, w.t[0] + start - 1e-6))
    ends = []
    at = w.t[first] + 1.0 - 0.5 / fps
    while at <= w.t[-1] + 1e-6:
        ends.append(int(np.searchsorted(w.t, at - 1e-6)))
        at += every
    e_prev = None
    for e in ends:
        s = slice(max(first, e - n + 1), e + 1)
        if e_prev is not None:  # the app's requests after the first (which films 1 s)
            s = slice(max(first, e - int(round(float(film.split()[0]) * n)) + 1), e + 1)
        (m, evidence), times = w.matches(loc, s), w.t[s]
        t_now = float(times[-1])
        motion = imu.motion(t_prev, t_now) if imu is not None and t_prev is not None else None
        est = sequence(m, loc.xy, times, loc.conf)  # the clip alone, as a locate without a session answers
        c1 = confidence(est, loc.conf)
        own = loc.own_answers(est, len(times), "sequence")  # each part's own answer, as Locator.track's
        c0 = time.process_time()
        state, pose = tr.update_clip(state, evidence, times, t_now, motion, own)
        cpu = time.process_time() - c0
        t_prev, e_prev = t_now, e
        tx, ty = w.xy[e]
        row = {
            "t": t_now - w.t[first],
            "err_m": float(np.hypot(pose.x - tx, pose.y - ty)),
            "heading_err_deg": float(abs(wrap_deg(pose.heading - w.heading[e]))),
            "confidence": pose.confidence,
            "ambiguous": pose.ambiguous,
            "mass": pose.mass,
            "far": pose.far,
            "alike_mass": pose.alike_mass,
            "alike_far": pose.alike_far,
            "spread_m": pose.spread_m,
            "updates": pose.updates,
            "cpu_s": cpu,
        }
        row["single_confidence"] = c1
        # what the confidence model reads (aggregate.CONFIDENCE_INPUTS): a model can be fit on these
        row.update(single_support=est.support, single_rival=est.rival, single_agree=est.agree)
        row["disagree_m"] = float(np.hypot(pose.x - est.x, pose.y - est.y))  # the clip's answer from the filter's
        if single:
            row.update(
                single_err_m=float(np.hypot(est.x - tx, est.y - ty)),
                single_heading_err_deg=float(abs(wrap_deg(est.heading - w.heading[e]))),
            )
        rows.append(row)
    return rows


def summary(rows: list[dict[str, Any]], prefix: str = "") -> dict[str, Any]:
    rs = [r for r in rows if r["t"] >= SKIP_S]
    err = np.array([r[f"{prefix}err_m"] for r in rs])
    herr = np.array([r[f"{prefix}heading_err_deg"] for r in rs])
    conf = np.array([r[f"{prefix}confidence"] for r in rs])
    hi = conf >= SURE
    return {
        "answers": len(rs),
        "within_2m": float(np.mean(err <= 2.0)),
        "within_1m": float(np.mean(err <= 1.0)),
        "median_heading_deg": float(np.median(herr)),
        "confident": float(hi.mean()),
        "confident_over_5m": int(np.sum(hi & (err > 5.0))),
        "confident_over_2m": int(np.sum(hi & (err > 2.0))),
    }


def pct(v: float) -> str:
    return f"{v:.1%}"


def cells(f: dict[str, Any], s: dict[str, Any]) -> str:
    """Filtered / single-clip, side by side, as markdown table cells."""
    return (
        f"{f['answers']} | {pct(f['within_2m'])} / {pct(s['within_2m'])} | {pct(f['within_1m'])} / "
        f"{pct(s['within_1m'])} | {f['median_heading_deg']:.2f}° / {s['median_heading_deg']:.2f}° | "
        f"{f['confident']:.0%} / {s['confident']:.0%} | {f['confident_over_5m']} / {s['confident_over_5m']} | "
        f"{f['confident_over_2m']} / {s['confident_over_2m']} |"
    )


HEAD = (
    "| {what} | answers | within 2 m | within 1 m | heading median | conf >= 0.8 | conf >= 0.8 and > 5 m "
    "| conf >= 0.8 and > 2 m |\n| --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: |"
)


def first_confident(rows: list[dict[str, Any]]) -> tuple[float | None, bool | None]:
    """Seconds of walking to the first answer given with confidence >= 0.8, and whether it was right."""
    for r in rows:
        if r["confidence"] >= SURE:
            return r["t"], r["err_m"] <= 2.0
    return None, None


STARTS_S = (0.0, 20.0, 40.0, 60.0, 80.0)  # the calibration's walks start afresh at these seconds


def calibration_rows(names: list[str], seeds: list[int], over: dict[str, Any]) -> list[dict[str, Any]]:
    """Every filtered answer of the families' query walks, started afresh at STARTS_S, every 1 s
    and 2.5 s, with and without IMU: the confidence features and the error."""
    rows: list[dict[str, Any]] = []
    for name in names:
        for seed in seeds:
            root = dataset(name, seed)
            loc = venue(root, "default", searched(over))
            tr = graph_tracker(loc, over)
            w = walk(root, loc)
            imu = walk_imu(root, seed=seed)
            for start in STARTS_S:
                if start > w.t[-1] - 15.0:
                    continue
                for every in (1.0, 2.5):
                    for use in (None, imu):
                        for r in run(loc, tr, w, every, use, start, single=False):
                            r.update(family=name, seed=seed, start=start, every=every, imu=use is not None)
                            rows.append(r)
    return rows


def fit_confidence(over: dict[str, Any]) -> None:
    """Fit track_confidence_coef on the tuning families (the main belief's inputs); judge it on
    the held-out ones as the answer takes it: the lower of the two beliefs' confidence."""
    from bench.calibrate import reliability
    from bench.scoring import fit

    names = list(DEFAULTS["track_confidence_features"])
    data = {split: calibration_rows(family_names(split), [0, 1], over) for split in ("tuning", "held-out")}

    def design(rows: list[dict[str, Any]]) -> tuple[np.ndarray, np.ndarray]:
        x = np.array([[1.0, *(TRACK_CONFIDENCE_INPUTS[n](r) for n in names)] for r in rows])
        return x, np.array([r["err_m"] <= 2.0 for r in rows], float)

    x, y = design(data["tuning"])
    w = fit(x, y, 1e-4)
    print(f"features {names}: track_confidence_coef = {[round(float(v), 3) for v in w]}")
    for split, rows in data.items():
        xs, ys = design(rows)
        p = 1 / (1 + np.exp(-(xs @ w)))
        # the answer's confidence is the lower of the two beliefs' (the cautious one's, where the
        # tracker runs it: the same model on its mass near and far from the answer)
        twin = [
            {**r, "mass": r["alike_mass"], "far": r["alike_far"]} if r.get("alike_mass") is not None else r
            for r in rows
        ]
        p = np.minimum(p, 1 / (1 + np.exp(-(design(twin)[0] @ w))))
        amb = np.array([r["ambiguous"] for r in rows])
        p = np.where(amb, np.minimum(p, 0.45), p)
        err = np.array([r["err_m"] for r in rows])
        hi = p >= SURE
        print(
            f"\n{split}: {len(rows)} answers (walks started afresh at {STARTS_S} s), within 2 m {ys.mean():.1%}; "
            f"conf >= {SURE}: {hi.mean():.1%}, of them > 2 m {np.mean(err[hi] > 2) if hi.any() else 0:.2%}, "
            f"> 5 m {np.mean(err[hi] > 5) if hi.any() else 0:.2%} ({int(np.sum(hi & (err > 5)))})"
        )
        print("| confidence | answers | mean confidence | within 2 m |\n| --- | ---: | ---: | ---: |")
        for lo, hi_, n, mc, share in reliability(p, ys):
            print(f"| {lo:.2f}-{hi_:.2f} | {n} | {mc:.3f} | {share:.1%} |")


def alike_build(frames: int = 8000, seed: int = 0) -> tuple[int, int, float, float]:
    """What a venue's first tracked request costs to build, on a made-up venue of `frames`
    frames (the serpentine of cpu_large, random unit-energy spectra of the default record: 14
    curves x 16 harmonics; the index as the server loads it): -> (frames, nodes, seconds for
    the graph and the Tracker without look-alikes, seconds for look_alikes' search)."""
    from omninav.index import Index
    from omninav.store import key_dims_for
    from omninav.walkgraph import build

    rng = np.random.default_rng(seed)
    vxy, _ = serpentine(frames)
    conf = resolve("default")
    shape = (frames, n_curves(conf), conf["n_harmonics"])
    spec = rng.normal(size=shape) + 1j * rng.normal(size=shape)
    spec = (spec / np.linalg.norm(spec.reshape(frames, -1), axis=1)[:, None, None]).astype(np.complex64)
    index = Index(spec, rng.uniform(0, 360, frames), key_dims=key_dims_for(DEFAULTS, frames))
    floor = np.full(frames, "1")
    c0 = time.process_time()
    g = build([(vxy, "1")])
    Tracker(g, vxy, floor, DEFAULTS)
    plain = time.process_time() - c0
    c0 = time.process_time()
    look_alikes(frame_search(index.search, spec), g, vxy, floor, DEFAULTS)
    return frames, len(g.xy), plain, time.process_time() - c0


def serpentine(frames: int) -> tuple[np.ndarray, Any]:
    """Venue frames 0.12 m apart along corridors 100 m long and 5 m apart, and their walk graph."""
    from omninav.walkgraph import build

    length = frames * 0.12
    rows = int(np.ceil(length / 100.0))
    pts = [(0.0, 0.0)]
    for i in range(rows):
        x = 100.0 if i % 2 == 0 else 0.0
        pts += [(x, 5.0 * i), (x, 5.0 * (i + 1))]
    seg = np.array(pts)
    d = np.r_[0.0, np.cumsum(np.hypot(*np.diff(seg, axis=0).T))]
    s_at = np.linspace(0.0, d[-1], frames)
    vxy = np.stack([np.interp(s_at, d, seg[:, 0]), np.interp(s_at, d, seg[:, 1])], axis=1)
    return vxy, build([(seg, "1")])


def cpu_large(frames: int = 8000, seed: int = 0, alike: bool = True) -> tuple[int, int, float, float]:
    """Tracker.update on a made-up venue of `frames` frames (0.12 m apart along a serpentine of
    corridors 5 m apart, ~1 node a metre) with random matches (10 frames x 16 candidates) and,
    with `alike`, random look-alikes (64 a node, scores 0.3-1: most are kept, more than a real
    venue has): -> (frames, nodes, median ms, p95 ms) of CPU per update."""
    rng = np.random.default_rng(seed)
    vxy, g = serpentine(frames)
    like = None
    if alike:
        li = rng.integers(0, frames, (len(g.xy), ALIKE_K))
        ls = rng.uniform(0.3, 1.0, li.shape).astype(np.float32)
        like = Matches(li, ls, ls, np.zeros(li.shape, np.float32))
    tr = Tracker(g, vxy, np.full(frames, "1"), DEFAULTS, like)
    state = None
    cpu = []
    for u in range(60):
        idx = rng.integers(0, frames, (10, 16))
        sc = rng.uniform(0.2, 0.9, (10, 16)).astype(np.float32)
        m = Matches(idx, sc, sc, rng.uniform(0, 360, (10, 16)).astype(np.float32))
        times = 2.5 * u + np.arange(-0.9, 0.01, 0.1)
        c0 = time.process_time()
        state, _ = tr.update(state, m, times, float(times[-1]), Motion(3, 5.0))
        cpu.append(time.process_time() - c0)
    ms = np.array(cpu[5:]) * 1000
    return frames, tr.n, float(np.median(ms)), float(np.percentile(ms, 95))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--families", default="all")
    ap.add_argument("--seeds", default="0,1")
    ap.add_argument("--walks", default="query,stops", help="query (the families' walk), stops (with stops)")
    ap.add_argument("--set", action="append", default=[], metavar="KEY=JSON", help="a tracking setting (tuning)")
    ap.add_argument("--json", type=Path, help="every answer, here")
    ap.add_argument("--fit", action="store_true", help="fit the confidence on the tuning families, then judge it")
    ap.add_argument("--threads", type=int, default=1, help="BLAS threads, as a server worker's (0: the default)")
    a = ap.parse_args()
    over = settings(a.set)
    pools = pin_threads(a.threads) if a.threads > 0 else "library default threads"
    print(f"machine: {machine()}; BLAS: {pools}")
    if a.fit:
        fit_confidence(over)
        return
    if over:
        print(f"settings: {over}")
    names = family_names(a.families)
    seeds = [int(s) for s in a.seeds.split(",")]
    runs: list[dict[str, Any]] = []  # one per (family, seed, walk, every, imu, start)
    sizes: dict[str, tuple[int, int]] = {}
    for name in names:
        for seed in seeds:
            root = dataset(name, seed)
            loc = venue(root, "default", searched(over))
            tr = graph_tracker(loc, over)
            sizes[f"{name}/{seed}"] = (len(loc.xy), tr.n)
            for wname in a.walks.split(","):
                if wname == "stops":
                    stops_walk(root, name, seed)
                w = walk(root, loc, wname)
                imu = walk_imu(root, wname, seed)
                starts = STARTS_S if wname == "query" else (0.0,)
                for start in starts:
                    if start > w.t[-1] - 15.0:
                        continue
                    # every 2.5 s: the 1 s clip ending there (the app before), and 2 s (the app now)
                    # and "Keep telling me" every 3 s: 1 s a turn and then the 3 s (every ~4 s: the
                    # app before), 2 s a turn and then 2 s (every ~4 s: the app now), or from one
                    # turn's start to the next's filming the 3 s (~3.3 s: tried)
                    keep = ((4.0, "1 s"), (4.0, "2 s"), (3.3, "3 s")) if start == 0.0 and wname == "query" else ()
                    for every, film in ((1.0, "1 s"), (2.5, "1 s"), (2.5, "2 s"), *keep):
                        for use in (False, True):
                            rows = run(loc, tr, w, every, imu if use else None, start, start == 0.0, film)
                            runs.append(
                                {"family": name, "split": FAMILIES[name].split, "seed": seed, "walk": wname,
                                 "every": every, "film": film, "imu": use, "start": start, "rows": rows}
                            )  # fmt: skip
                        if start == 0.0 and wname == "query" and every in (1.0, 2.5):  # no steps counted
                            rows = run(loc, tr, w, every, no_steps(imu), start, True, film)
                            runs.append(
                                {"family": name, "split": FAMILIES[name].split, "seed": seed, "walk": wname,
                                 "every": every, "film": film, "imu": "no steps", "start": start, "rows": rows}
                            )  # fmt: skip
            print(f"{name}/{seed}: {sizes[f'{name}/{seed}'][0]} venue frames, {tr.n} graph nodes", flush=True)

    def pool(**k: Any) -> list[dict[str, Any]]:
        k.setdefault("film", "1 s")  # "2 s": only where a table asks for it
        return [r for x in runs if all(x[a] == v for a, v in k.items()) for r in x["rows"]]

    def paces(every: float) -> tuple[str, ...]:
        return ("1 s", "2 s") if every != 1.0 else ("1 s",)

    def pace(every: float, film: str) -> str:
        return f"{every:g} s" + (f", {film} filmed" if every != 1.0 else "")

    print("\n### Per family: answers every 1 s, no IMU, after the first 5 s (filtered / single clip)\n")
    print(HEAD.format(what="family (split)"))
    for name in names:
        rows = pool(family=name, every=1.0, imu=False, start=0.0)
        print(f"| {name} ({FAMILIES[name].split}) | " + cells(summary(rows), summary(rows, "single_")))
    for split in ("tuning", "held-out"):
        rows = pool(split=split, every=1.0, imu=False, start=0.0)
        if rows:
            print(f"| **all {split}** | " + cells(summary(rows), summary(rows, "single_")))

    print("\n### Updates every 1 s or every 2.5 s (the phone), with and without IMU (filtered / single clip)\n")
    print("| split | every | IMU | answers | within 2 m | within 1 m | heading median | conf >= 0.8 "
          "| conf >= 0.8 and > 5 m | conf >= 0.8 and > 2 m |")  # fmt: skip
    print("| --- | ---: | --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: |")
    for split in ("tuning", "held-out"):
        for every in (1.0, 2.5):
            for film in paces(every):
                for use in (False, True):
                    rows = pool(split=split, every=every, imu=use, start=0.0, film=film)
                    if rows:
                        f, s1 = summary(rows), summary(rows, "single_")
                        print(f"| {split} | {pace(every, film)} | {'yes' if use else 'no'} | " + cells(f, s1))

    print("\n### A phone that counts no steps while walking (gyroscope on): 0 steps every update\n")
    print(HEAD.format(what="split, every"))
    for split in ("tuning", "held-out"):
        for every in (1.0, 2.5):
            for film in paces(every):
                rows = pool(split=split, every=every, imu="no steps", start=0.0, film=film)
                if rows:
                    print(f"| {split}, {pace(every, film)} | " + cells(summary(rows), summary(rows, "single_")))

    print(
        '\n### "Keep telling me" every 3 s: 1 s a turn, every ~4 s (before) / 2 s a turn, every ~4 s (the app) '
        "/ 3 s a turn, every ~3.3 s (tried)\n"
    )
    print(HEAD.format(what="split, turns, IMU"))
    for split in ("tuning", "held-out"):
        for every, film in ((4.0, "1 s"), (4.0, "2 s"), (3.3, "3 s")):
            for use in (False, True):
                rows = pool(split=split, every=every, imu=use, start=0.0, film=film)
                if rows:
                    what = f"{split}, {film} every {every:g} s, IMU {'yes' if use else 'no'}"
                    print(f"| {what} | " + cells(summary(rows), summary(rows, "single_")))

    print("\n### Starting afresh (at 0, 20, 40, 60, 80 s into each query walk): seconds to the first")
    print("answer given with confidence >= 0.8, and whether it was right (within 2 m)\n")
    print("| split | every | IMU | starts | first answer 'not sure' | s to confident: median | worst "
          "| never confident | first confident right |")  # fmt: skip
    print("| --- | ---: | --- | ---: | ---: | ---: | ---: | ---: | ---: |")
    for split in ("tuning", "held-out"):
        for every in (1.0, 2.5):
            for film in paces(every):
                for use in (False, True):
                    xs = [x for x in runs if x["split"] == split and x["walk"] == "query" and x["every"] == every
                          and x["imu"] == use and x["film"] == film]  # fmt: skip
                    if not xs:
                        continue
                    firsts = [first_confident(x["rows"]) for x in xs]
                    ts = [t for t, _ in firsts if t is not None]
                    right = [ok for _, ok in firsts if ok is not None]
                    unsure = np.mean([x["rows"][0]["confidence"] < 0.5 for x in xs])
                    print(
                        f"| {split} | {pace(every, film)} | {'yes' if use else 'no'} | {len(xs)} | {unsure:.0%} | "
                        f"{np.median(ts):.1f} | {max(ts):.1f} | {len(xs) - len(ts)} | {np.mean(right):.0%} |"
                    )

    print("\n### The worst case: long-bare's query walk starts in the middle of a 60 m corridor of identical doors\n")
    print("| seed | every | IMU | first 'not sure' answers | s to first confident answer | right? | its error |")
    print("| --- | ---: | --- | ---: | ---: | --- | ---: |")
    for x in runs:
        if x["family"] == "long-bare" and x["walk"] == "query" and x["start"] == 0.0:
            t, ok = first_confident(x["rows"])
            err = next((r["err_m"] for r in x["rows"] if r["confidence"] >= SURE), None)
            unsure = sum(r["confidence"] < 0.5 for r in x["rows"] if t is None or r["t"] < t)
            print(
                f"| {x['seed']} | {pace(x['every'], x['film'])} | {imu_word(x['imu'])} | {unsure} | "
                f"{'never' if t is None else f'{t:.1f}'} | {'-' if ok is None else ('yes' if ok else 'NO')} | "
                f"{'-' if err is None else f'{err:.1f} m'} |"
            )

    if "stops" in a.walks.split(","):
        print("\n### Walks with three stops of 3-8 s (every 1 s, after the first 5 s; filtered / single clip)\n")
        print(HEAD.format(what="split, IMU"))
        for split in ("tuning", "held-out"):
            for use in (False, True):
                rows = pool(split=split, walk="stops", every=1.0, imu=use)
                if rows:
                    print(
                        f"| {split}, IMU {'yes' if use else 'no'} | " + cells(summary(rows), summary(rows, "single_"))
                    )

    cpu = np.array([r["cpu_s"] for x in runs if x["film"] == "1 s" for r in x["rows"]]) * 1000  # one update each
    big = max(sizes.values())
    print(
        f"\nCPU per tracked update (Tracker.update, after the index search): median {np.median(cpu):.2f} ms, "
        f"p95 {np.percentile(cpu, 95):.2f} ms, max {cpu.max():.2f} ms over {len(cpu)} updates; "
        f"venues of up to {big[0]} frames ({big[1]} graph nodes)"
    )
    for n in (3000, 8000, 20000):
        for alike in (False, True):
            f, nodes, med, p95 = cpu_large(n, alike=alike)
            print(
                f"made-up venue of {f} frames ({nodes} graph nodes), random matches, "
                f"{'with' if alike else 'without'} look-alikes: median {med:.2f} ms, p95 {p95:.2f} ms"
            )
    for n in (3000, 8000, 20000):
        f, nodes, plain, alike = alike_build(n)
        print(
            f"made-up venue of {f} frames ({nodes} graph nodes): graph and tracker built in {plain * 1000:.0f} ms, "
            f"its look-alikes searched in {alike * 1000:.0f} ms more (once per venue generation)"
        )
    if a.json:
        a.json.write_text(json.dumps(runs))


if __name__ == "__main__":
    main()
