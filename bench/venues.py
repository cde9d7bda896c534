"""The benchmarks' venues: the venue families rendered once (data/families/) and modelled once
per configuration, cached by what is modelled, and every clip's answer with its confidence
inputs cached beside them (`rows_for`), so that a confidence refit or a new report is judged
without running anything again.
"""

from __future__ import annotations

import fcntl
import hashlib
import json
import shutil
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

from bench.ablation import CONFIGS as LADDER
from omninav.aggregate import SURE, confidence
from omninav.evaluate import clip_ends, evaluate_spectra, query_spectra, walk_local
from omninav.lens import load_lens
from omninav.locate import Locator
from omninav.model_venue import model_video
from omninav.presets import resolve
from omninav.store import Store
from omninav.synth import upgrade_names
from omninav.synth.families import FAMILIES, make_family_dataset
from omninav.verify import DIM_SHARE, FAST_DIM, FAST_THRESHOLD, checked_confidence
from omninav.walk_path import load_walk_path

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
    return upgrade_names(root)


def venue(root: Path, config: str, overrides: dict[str, Any] | None = None) -> Locator:
    """The family's venue modelled with a configuration (cached: a venue keeps its settings)."""
    preset, over, _ = CONFIGS[config]
    settings = {**resolve(preset), **over, **(overrides or {})}
    return cached_venue(root, config, settings)


def venue_key(tag: str, settings: dict[str, Any]) -> str:
    """A bench venue's id: `tag` and a hash of what is modelled with `settings`.

    The confidence model is not part of what is modelled (a recalibration reuses the venue), nor
    is tracking (tracking.py's track_* keys: a venue modelled before them is the same venue), nor
    how a clip is searched (SEARCH_KEYS: the answers' cache is named by them, rows_for), nor the
    settings' format version, nor verification's margin (or its absence: local_features null).
    A venue with local features is also keyed by their detector's FAST thresholds and dim share (verify.py)."""
    kept = {
        k: v
        for k, v in settings.items()
        if k not in CONFIDENCE_KEYS
        and k not in SEARCH_KEYS
        and not k.startswith("track_")
        and k != "version"
        and k != "local_margin"
        and not (k == "local_features" and v is None)  # (venues modelled before them)
    }
    if kept.get("local_features"):  # the keypoints' detector too: another threshold is another venue
        kept["fast_thresholds"] = [FAST_THRESHOLD, FAST_DIM, DIM_SHARE]
    return f"{tag}-{hashlib.sha1(json.dumps(kept, sort_keys=True).encode()).hexdigest()[:10]}"


def cached_venue(
    root: Path,
    tag: str,
    settings: dict[str, Any],
    lens: str = "model_lens.json",
    walk_path: str = "model_walk_path.json",
    store: Path | None = None,
) -> Locator:
    """root's model.mp4 (walked along root/`walk_path`, through root/`lens`) modelled with `settings`
    into `store` (default root/bench-data), once per settings: the venue id is `tag` and a hash of
    what is modelled, so a changed default is another venue, never a stale one (bench/accuracy.py,
    bench/lens_shift.py and bench/foreign.py cache their venues here too)."""
    st = Store(store or root / "bench-data")
    vid = venue_key(tag, settings)
    if st.generation(vid) is None:
        t = time.perf_counter()
        model_video(
            st, vid, root / "model.mp4", load_walk_path(root / walk_path), load_lens(root / lens), settings=settings
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
            loc, root / "query.mp4", load_walk_path(root / "query_walk_path.json"), load_lens(root / "lens.json")
        )
        agg = CONFIGS[config][2]
        for c in todo:
            ends = None
            if loc.verifies:  # each clip verified by its last frame, as `omninav evaluate` does
                walk = load_walk_path(root / "query_walk_path.json")
                at = clip_ends(loc, spec[4], c, False)
                ends = walk_local(loc, root / "query.mp4", load_lens(root / "lens.json"), at, walk.fps)
            rows = evaluate_spectra(loc, *spec, aggregate=agg, clip_s=c, ends=ends).rows
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
    # (rows cached before answers said `verified` carry `moved` on a moved answer)
    said = [r.get("verified") or ("moved" if r.get("moved") else None) for r in rows]
    return np.array([checked_confidence(v, confidence(r, conf)) for v, r in zip(said, rows, strict=True)])


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


def extra_seeds(specs: list[str], seeds: list[int]) -> list[tuple[str, int]]:
    """--extra FAMILY:S1,S2 -> (family, seed) pairs; only tuning families may be fit on, and a
    seed already fit on (`seeds`, every tuning family's) is not counted twice."""
    out = []
    for spec in specs:
        fam, _, more = spec.partition(":")
        if fam not in FAMILIES:
            raise SystemExit(f"--extra {spec}: unknown family {fam!r} (known: {', '.join(FAMILIES)})")
        if FAMILIES[fam].split != "tuning":
            raise SystemExit(f"--extra {spec}: {fam} is held out (the held-out families are never fit on)")
        try:
            got = [int(v) for v in more.split(",") if v.strip()]
        except ValueError:
            raise SystemExit(f"--extra {spec}: seeds are whole numbers, FAMILY:3,4") from None
        if not got or set(got) & set(seeds):
            raise SystemExit(f"--extra {spec}: name seeds beyond --seeds {seeds}, FAMILY:3,4")
        out += [(fam, v) for v in got]
    return out
