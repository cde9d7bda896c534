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

    python bench/families.py [--families all|tuning|held-out|NAME,...] [--seeds 0] [--clips 1]
                             [--configs default,paper] [--json OUT]
"""

from __future__ import annotations

import argparse
import fcntl
import hashlib
import json
import shutil
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

from omninav.aggregate import SURE, confidence
from omninav.evaluate import evaluate_spectra, query_spectra
from omninav.lens import load_lens
from omninav.locate import Locator
from omninav.model_venue import model_video
from omninav.presets import resolve
from omninav.store import Store
from omninav.synth.families import FAMILIES, make_family_dataset
from omninav.track import load_track

sys.path.insert(0, str(Path(__file__).parent))
from ablation import CONFIGS as LADDER  # noqa: E402
from search_speed import machine  # noqa: E402

DATA = Path("data") / "families"
# name: preset, overrides, aggregation (bench/ablation.py's ladder of the changes since the paper)
CONFIGS: dict[str, tuple[str, dict[str, Any], str]] = {
    name: (preset, over, str(resolve(preset, over)["aggregate"])) for name, (preset, over) in LADDER.items()
}
CONFIDENCE_KEYS = ("confidence_features", "confidence_coef")
SEARCH_KEYS = ("shared_candidates", "shortlist")  # how a clip is searched: the same venue, other answers


def settings(pairs: list[str]) -> dict[str, Any]:
    """The benches' --set KEY=JSON pairs -> the settings they override."""
    return {k: json.loads(v) for k, v in (kv.split("=", 1) for kv in pairs)}


def family_names(spec: str) -> list[str]:
    if spec in ("all", "tuning", "held-out"):
        return [n for n, f in FAMILIES.items() if spec == "all" or f.split == spec]
    names = [s.strip() for s in spec.split(",") if s.strip()]
    unknown = [n for n in names if n not in FAMILIES]
    if unknown:
        raise SystemExit(f"unknown families {unknown} (known: {', '.join(FAMILIES)})")
    return names


def dataset(family: str, seed: int) -> Path:
    root = DATA / f"{family}-{seed}"
    DATA.mkdir(parents=True, exist_ok=True)
    # one renderer per venue: a second bench run waits for the first's render instead of redoing it
    with open(DATA / f".{root.name}.lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        if not root.exists():
            t = time.perf_counter()
            print(f"rendering {root} ...", file=sys.stderr, flush=True)
            part = root.with_name(root.name + ".part")  # an interrupted render is not taken for a venue
            shutil.rmtree(part, ignore_errors=True)
            make_family_dataset(part, family, seed)
            part.rename(root)
            print(f"rendered {root} in {time.perf_counter() - t:.0f} s", file=sys.stderr, flush=True)
    return root


def venue(root: Path, config: str, overrides: dict[str, Any] | None = None) -> Locator:
    """The family's venue modelled with a configuration (cached: a venue keeps its settings)."""
    preset, over, _ = CONFIGS[config]
    settings = {**resolve(preset), **over, **(overrides or {})}
    return cached_venue(root, config, settings)


def venue_key(tag: str, settings: dict[str, Any]) -> str:
    """A bench venue's id: `tag` and a hash of what is modelled with `settings`.

    The confidence model is not part of what is modelled (a recalibration reuses the venue), nor
    is tracking (tracking.py's track_* keys: a venue modelled before them is the same venue), nor
    how a clip is searched (SEARCH_KEYS: the answers' cache is named by them, rows_for)."""
    kept = {
        k: v
        for k, v in settings.items()
        if k not in CONFIDENCE_KEYS and k not in SEARCH_KEYS and not k.startswith("track_")
    }
    return f"{tag}-{hashlib.sha1(json.dumps(kept, sort_keys=True).encode()).hexdigest()[:10]}"


def cached_venue(
    root: Path,
    tag: str,
    settings: dict[str, Any],
    lens: str = "model_lens.json",
    track: str = "model_track.json",
    store: Path | None = None,
) -> Locator:
    """root's model.mp4 (walked along root/`track`, through root/`lens`) modelled with `settings`
    into `store` (default root/bench-data), once per settings: the venue id is `tag` and a hash of
    what is modelled, so a changed default is another venue, never a stale one (bench/accuracy.py,
    bench/lens_shift.py and bench/foreign.py cache their venues here too)."""
    st = Store(store or root / "bench-data")
    vid = venue_key(tag, settings)
    if st.generation(vid) is None:
        t = time.perf_counter()
        model_video(
            st, vid, root / "model.mp4", load_track(root / track), load_lens(root / lens), settings=settings
        )  # fmt: skip
        print(f"modelled {root.name} as {vid} in {time.perf_counter() - t:.0f} s", file=sys.stderr, flush=True)
    loc = Locator(st, vid, device="cpu")
    loc.change_settings({k: settings[k] for k in (*CONFIDENCE_KEYS, *SEARCH_KEYS)})
    return loc


def rows_for(
    family: str, seed: int, config: str, clips: list[float], overrides: dict[str, Any] | None = None
) -> dict[float, list[dict[str, Any]]]:
    """Every clip's answer and confidence features, per clip length (cached beside the venue)."""
    root = dataset(family, seed)
    loc = venue(root, config, overrides)
    cache = root / f"rows-{loc.venue_id}{search_tag(loc.conf)}.json"
    have: dict[str, list[dict[str, Any]]] = json.loads(cache.read_text()) if cache.exists() else {}
    todo = [c for c in clips if f"{c:g}" not in have]
    if todo:
        spec = query_spectra(
            loc, root / "query.mp4", load_track(root / "query_track.json"), load_lens(root / "lens.json")
        )
        agg = CONFIGS[config][2]
        for c in todo:
            rows = evaluate_spectra(loc, *spec, aggregate=agg, clip_s=c).rows
            for r in rows:
                r.update(family=family, split=FAMILIES[family].split, seed=seed, config=config, clip_s=c)
            have[f"{c:g}"] = rows
        cache.write_text(json.dumps(have))
    return {c: have[f"{c:g}"] for c in clips}


def search_tag(conf: dict[str, Any]) -> str:
    """How the rows' clips were searched, in their cache's name. Rows searched as before shared
    candidates, and before the shortlist, keep the names they had then."""
    if not conf["shared_candidates"]:
        return ""
    wider = int(conf["shortlist"]) > int(conf["candidates"])
    return f"-shared-sl{int(conf['shortlist'])}" if wider else "-shared"


def rescore(rows: list[dict[str, Any]], conf: dict[str, Any]) -> np.ndarray:
    """The confidence each answer gets from the confidence model in `conf` (not the one stored
    when the rows were made: a recalibration is judged without running anything again)."""
    return np.array([confidence(r, conf) for r in rows])


def summarise(rows: list[dict[str, Any]], conf: dict[str, Any]) -> dict[str, Any]:
    err = np.array([r["err_m"] for r in rows])
    herr = np.abs([r["heading_err_deg"] for r in rows])
    c = rescore(rows, conf)
    hi = c >= SURE  # a user is told to trust these (issue 13: <= 1 % of them wrong)
    return {
        "clips": len(rows),
        "within_1m": float(np.mean(err <= 1.0)),
        "within_2m": float(np.mean(err <= 2.0)),
        "median_heading_deg": float(np.median(herr)),
        "coverage": float(hi.mean()),
        "confident_wrong": float(np.mean(err[hi] > 2.0)) if hi.any() else 0.0,
        "wrong_far_m": sorted(round(float(e), 1) for e in err[err > 2.0])[-3:],
    }


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
