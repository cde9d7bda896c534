"""One accuracy report over three sources, and the adoption rule that reads it.

A change to features, search, aggregation or confidence is judged on three sources, side by side:

- **own**: our renderer's held-out families (bench/venues.py, 1 s clips, the seeds given),
  pooled; never tuned on, but drawn by the same code that drew the tuning families;
- **foreign**: the foreign pack (bench/foreign.py: each venue modelled and located as `omninav
  model` and `omninav locate` do), venues from a renderer nobody on the team wrote;
- **real**: the real donut photo of pyomniunwarp 0.2.5 (MIT; bench/real_optics.py fetches it):
  with no second photo of known position to locate it against, it measures what a real picture
  does to a match: the photo against itself read through a lens profile 2 degrees off in
  elevation (either way), after another exposure, and turned about the lens axis (the heading).

The adoption rule (docs/benchmarks.md, "Accuracy on three sources"): a candidate becomes the default only
where it loses on none of the sources by more than that source's noise; otherwise it is a venue
option. The noise of a source of clips is the paired standard error of the difference in the
share within 2 m over the same clips (the Wald form of McNemar's test, choose.paired_se:
sqrt(b + c - (b - c)^2 / n) / n for b clips only the baseline gets and c only the candidate
does); a loss is a drop of more than twice it, or more clips answered sure and > 2 m off by more
than twice their own paired error (scoring.clip_verdict). On the real
photo, whose scores are on each feature set's own scale, a loss is a larger elevation cost (the
score a lens 2 degrees off takes away) by more than twice its paired standard error over the
photo's eight turns, or a heading error 0.5 degrees worse.

    python -m bench.sources [--configs default,two-bands-shared] [--seeds 0,1,2] [--pack DIR]
    python -m bench.sources --ladder [--seeds 0]   # every change since the paper, each judged
                                                   # against the rung before it
"""

from __future__ import annotations

import argparse
import functools
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from bench import foreign
from bench.ablation import LADDER, elevation_off
from bench.common import machine
from bench.real_optics import real_photo
from bench.scoring import BINS, clip_verdict, conf_of, elevation_cost, real_verdict, reliability, scores, summary
from bench.venues import rows_for
from omninav.extract import Extractor
from omninav.heading import relative_heading, wrap_deg
from omninav.lens import Catadioptric
from omninav.synth.families import FAMILIES
from omninav.synth.optics import reexpose

TURNS = (23.0, 71.0, 118.0, 167.0, 204.0, 251.0, 299.0, 337.0)  # the photo turned about its lens axis
SHOT = {"gain": 0.6, "tone": 0.8, "wb": (0.9, 1.0, 1.12), "noise": 3.0, "jpeg": 60}  # real_optics' "all"


# ---- own: the held-out families ---------------------------------------------------------------
def own(config: str, seeds: list[int]) -> dict[str, np.ndarray]:
    """Every held-out family's 1 s clips at each seed, pooled in one order (for pairing)."""
    conf = conf_of(config)
    rows: list[dict[str, Any]] = []
    for name, fam in FAMILIES.items():
        if fam.split != "held-out":
            continue
        for seed in seeds:
            rows += rows_for(name, seed, config, [1.0])[1.0]
    return scores(rows, conf)


# ---- foreign: the pack ------------------------------------------------------------------------
def foreign_scores(config: str, pack: Path, venues: list[str]) -> dict[str, dict[str, np.ndarray]]:
    conf = conf_of(config)
    return {v: scores(foreign.rows_for(pack, v, config, conf), conf) for v in venues}


# ---- real: the photo --------------------------------------------------------------------------
def turned(rgb: np.ndarray, centre: tuple[float, float], deg: float) -> np.ndarray:
    """The donut photo turned `deg` counter-clockwise (as drawn) about the lens axis."""
    m = cv2.getRotationMatrix2D(centre, deg, 1.0)
    out: np.ndarray = cv2.warpAffine(rgb, m, (rgb.shape[1], rgb.shape[0]), flags=cv2.INTER_LINEAR)
    return out


@functools.cache
def shots(cache: Path) -> tuple[np.ndarray, Catadioptric, list[np.ndarray]]:
    """The photo (RGB), its lens, and the photo turned by each of TURNS and re-exposed (BGR, as
    the extractor reads frames): made once for every configuration."""
    rgb, lens, _, _ = real_photo(cache)
    turns = [
        np.ascontiguousarray(reexpose(turned(rgb, lens.center, deg), rng=np.random.default_rng(i), **SHOT)[..., ::-1])
        for i, deg in enumerate(TURNS)
    ]
    return rgb, lens, turns


def real(config: str, cache: Path) -> dict[str, Any]:
    """The photo against itself: through a lens 2 degrees off in elevation, another exposure, and
    turned; mean verification score of each (the spread over TURNS: the noise) and the heading
    error of the turned ones."""
    rgb, lens, turns = shots(cache)
    conf = conf_of(config)
    ref = Extractor(lens, conf).spectrum(rgb[..., ::-1].copy())
    n = max(64, 8 * ref.shape[-1])
    out: dict[str, Any] = {}
    for label, el in (("elev -2°", -2.0), ("elev +2°", 2.0)):
        ext = Extractor(elevation_off(lens, el), conf)
        out[label] = np.array([float(relative_heading(ext.spectrum(s), ref, n_shifts=n)[1]) for s in turns])
    ext = Extractor(lens, conf)
    res, herr = [], []
    for deg, shot in zip(TURNS, turns, strict=True):
        rel, val = relative_heading(ext.spectrum(shot), ref, n_shifts=n)
        res.append(float(val))
        # turned() turns the picture counter-clockwise: through a lens whose azimuths run
        # counter-clockwise the phone has turned by -deg (clockwise headings), else by +deg
        want = -deg if lens.ccw else deg
        herr.append(abs(float(wrap_deg(float(rel) - want))))
    out["turned"] = np.array(res)
    out["heading_deg"] = float(np.median(herr))
    return out


# ---- the report -------------------------------------------------------------------------------
def row(label: str, s: dict[str, float]) -> str:
    return (
        f"  {label:<30}{int(s['clips']):>6}{s['within_1m']:>8.1%}{s['within_2m']:>8.1%}{s['heading_deg']:>8.2f}°"
        f"{s['sure']:>7.0%}{s['sure_far']:>9.1%}{s['wrong_among_sure']:>8.1%}"
    )


HEAD = f"  {'config':<30}{'clips':>6}{'<=1 m':>8}{'<=2 m':>8}{'hdg med':>9}{'sure':>7}{'sure>2m':>9}{'of sure':>8}"


def verdicts(
    base: str, cand: str, own_s: dict, for_s: dict, real_s: dict, venues: list[str]
) -> tuple[dict[str, tuple[str, dict[str, float]]], str]:
    """The adoption rule's reading of `cand` against `base` on every source of clips, and on the photo."""
    out = {"own": clip_verdict(own_s[base], own_s[cand])}
    for v in venues:
        out[f"foreign {v}"] = clip_verdict(for_s[base][v], for_s[cand][v])
    return out, real_verdict(real_s[base], real_s[cand])


def pack_or_exit(pack: Path) -> list[str]:
    """The pack's venues; without them the rule would judge on two sources, so none is judged."""
    venues = foreign.pack_venues(pack) if pack.is_dir() else []
    if not venues:
        raise SystemExit(f"{pack}: no foreign pack there (--pack): the rule needs all three sources")
    return venues


def ladder(seeds: list[int], pack: Path, cache: Path) -> None:
    """The ablation: each rung, its figures on the three sources, and the rule's verdict against
    the rung before it (the change it adds)."""
    venues = pack_or_exit(pack)
    own_s = {c: own(c, seeds) for c in LADDER}
    for_s = {c: foreign_scores(c, pack, venues) for c in LADDER}
    real_s = {c: real(c, cache) for c in LADDER}
    head = f"{'rung':<16}{'own <=2m':>9}{'sure>2m':>8}" + "".join(f"{v + ' <=2m':>13}{'sure>2m':>8}" for v in venues)
    print(head + f"{'el. cost':>9}  verdict against the rung before")
    for i, c in enumerate(LADDER):
        o = summary(own_s[c])
        cells = "".join(
            f"{summary(for_s[c][v])['within_2m']:>13.1%}{summary(for_s[c][v])['sure_far']:>8.1%}" for v in venues
        )
        word = "-"
        if i:
            vs, rv = verdicts(LADDER[i - 1], c, own_s, for_s, real_s, venues)
            word = ", ".join(f"{k} {w}" for k, (w, _) in vs.items()) + f", real {rv}"
        cost = float(np.mean(elevation_cost(real_s[c])))
        print(f"{c:<16}{o['within_2m']:>9.1%}{o['sure_far']:>8.1%}{cells}{cost:>9.3f}  {word}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--configs", default="default,two-bands-shared", help="the first is the baseline")
    ap.add_argument("--seeds", default="0", help="held-out families' seeds")
    ap.add_argument("--pack", type=Path, default=foreign.PACK)
    ap.add_argument("--cache", type=Path, default=Path("data/cache/real-optics"))
    ap.add_argument("--no-paper", action="store_true", help="leave the paper's method out")
    ap.add_argument("--ladder", action="store_true", help="the ablation: every rung against the one before")
    a = ap.parse_args()
    if a.ladder:
        print(f"machine: {machine()}")
        ladder([int(s) for s in a.seeds.split(",")], a.pack, a.cache)
        return
    configs = a.configs.split(",")
    shown = configs + ([] if a.no_paper or "paper" in configs else ["paper"])
    seeds = [int(s) for s in a.seeds.split(",")]
    venues = pack_or_exit(a.pack)
    print(f"machine: {machine()}")
    print(f"own: held-out families, seeds {seeds}; foreign: {', '.join(venues)}; real: the photo")
    own_s = {c: own(c, seeds) for c in shown}
    for_s = {c: foreign_scores(c, a.pack, venues) for c in shown}
    real_s = {c: real(c, a.cache) for c in shown}
    print("\nown (held-out families, 1 s clips; 'sure>2m' of all clips, 'of sure' of the sure ones)")
    print(HEAD)
    for c in shown:
        print(row(c, summary(own_s[c])))
    for v in venues:
        print(f"\nforeign {v} (1 s clips)")
        print(HEAD)
        for c in shown:
            print(row(c, summary(for_s[c][v])))
    print("\nreal (the photo against itself: mean verification score, spread over 8 turns; heading error)")
    print(f"  {'config':<30}{'elev -2°':>14}{'elev +2°':>14}{'turned':>14}{'el. cost':>10}{'heading':>9}")
    for c in shown:
        r = real_s[c]
        cells = "".join(f"{np.mean(r[k]):>8.3f} ±{np.std(r[k]):.3f}" for k in ("elev -2°", "elev +2°", "turned"))
        print(f"  {c:<30}{cells}{np.mean(elevation_cost(r)):>10.3f}{r['heading_deg']:>8.2f}°")
    print("\nreliability of the first configuration: answers in each confidence bin, and the share within 2 m")
    edges = [f"{lo:.2f}-{min(hi, 1.0):.2f}" for lo, hi in zip(BINS[:-1], BINS[1:], strict=True)]
    print(f"  {'source':<30}" + "".join(f"{e:>14}" for e in edges))
    sources = {"own (held-out)": own_s[configs[0]], **{f"foreign {v}": for_s[configs[0]][v] for v in venues}}
    for name, sc in sources.items():
        cells = "".join(f"{n:>5} {share:>7.0%} " if n else f"{n:>5} {'-':>7} " for n, share in reliability(sc))
        print(f"  {name:<30}{cells}")
    base = configs[0]
    print(f"\nadoption rule against {base} (loses: worse by more than the source's noise, docs/benchmarks.md)")
    for c in configs[1:]:
        vs, rv = verdicts(base, c, own_s, for_s, real_s, venues)
        cells = [
            f"{k} {w} ({d['d_within_2m']:+.1%} ±{d['se_within_2m']:.1%}, sure>2m {d['d_sure_far']:+.1%})"
            for k, (w, d) in vs.items()
        ]
        adopt = all(w != "loses" for w, _ in vs.values()) and rv != "loses"
        print(f"  {c}: {'; '.join(cells)}; real {rv} -> {'may become the default' if adopt else 'a venue option'}")


if __name__ == "__main__":
    main()
