"""Fit the confidence model on the tuning families; judge it on the held-out ones.

P(answer within 2 m) = logistic(w . [1, inputs]), the inputs named by the settings'
`confidence_features` (or --features, any of aggregate.CONFIDENCE_INPUTS). The weights are fit by
L2-regularised log-loss on every answer of the tuning families (bench/venues.py's cached rows,
at several clip lengths, so that the fit sees the harder short clips and the app's 3 s ones), then
applied unchanged to the held-out families. Printed for both splits, for the preset's weights and
the refit: the reliability table (answers binned by confidence against the share within 2 m), the
share answered with confidence >= 0.8 and how many of those were further than 2 m. --png draws the
preset's model's reliability diagram. A refit becomes the default (settings.py's
`confidence_coef`, the model it replaces added to settings_upgrade.SUPERSEDED_CONFIDENCE) only when
it does better on the held-out families as well: fewer of the answers it calls sure wrong, and no
more clips filmed elsewhere called sure (docs/benchlog.md says what was tried; the model since
"Ties" has the worse held-out Brier, modest about the venues' own clips).

--elsewhere FILE (bench/elsewhere.py --json) adds the single answers of the tuning families'
clips filmed where the venue was never modelled (another seed's building, another family's), each
labelled wrong, weighing --elsewhere-weight W of the venue's own answers in all: a user also asks
in a room nobody filmed, and a model fit on the venue's own clips alone calls more of those sure
(docs/benchlog.md, "Ties"). Its sure share there is printed for both splits.

--extra FAMILY:SEEDS adds more seeds of a tuning family to the fit (ring-bare:3,4,5,6: the
tuning side's corridor of identical doors, rendered again for the ties it holds). --cover
preset moves the refit's intercept so that it answers as large a share of the tuning answers
with confidence >= 0.8 as the preset's model does: a log-loss fit on clips this accurate says
"sure" to nearly all of them, and the held-out families are harder than the tuning ones, so the
refit keeps the preset's boldness and changes only which answers it trusts (a fixed point: the
preset refit so answers the same share).

    python -m bench.calibrate [--seeds 0,1] [--held-out-seeds 0,1,2,3] [--clips 0.5,1,2,3]
                              [--features support,margin,...] [--extra ring-bare:3,4,5,6]
                              [--cover preset|SHARE] [--elsewhere E.json --elsewhere-weight W]
                              [--look-alike-prior W] [--png docs/reliability.png]
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import Any

import numpy as np

from bench.common import machine
from bench.scoring import cover, fit
from bench.venues import extra_seeds, family_names, rows_for
from omninav.aggregate import SURE, confidence, confidence_inputs
from omninav.presets import resolve

BINS = (0.0, 0.2, 0.4, 0.5, 0.6, 0.7, 0.8, 0.9, 0.95, 1.0001)


def design(rows: list[dict[str, Any]], names: list[str]) -> tuple[np.ndarray, np.ndarray]:
    x = np.array([[1.0, *confidence_inputs(r, names)] for r in rows])
    y = np.array([r["err_m"] <= 2.0 for r in rows], float)
    return x, y


def look_alikes(rows: list[dict[str, Any]], names: list[str]) -> tuple[np.ndarray, np.ndarray]:
    """The prior the tuning families are short of: every answer again with a rival exactly as good
    (rival = support), labelled 0.5. Two places that explain a clip equally well are a coin toss,
    however well they match; a venue of identical corridors is made of such answers, and without
    them in the fit a high support alone reads as "right"."""
    x = np.array([[1.0, *confidence_inputs({**r, "rival": r["support"]}, names)] for r in rows])
    return x, np.full(len(rows), 0.5)


def cover_share(spec: str | None) -> float | None:
    """--cover: None (no cover, or "preset": the preset's own share, known once the rows are)."""
    if spec is None or spec == "preset":
        return None
    try:
        share = float(spec)
    except ValueError:
        share = float("nan")
    if not 0.0 < share < 1.0:
        raise SystemExit(f"--cover {spec}: 'preset' or a share between 0 and 1 (0.89, not 89)")
    return share


def elsewhere_rows(path: Path | None) -> dict[str, list[dict[str, Any]]]:
    """bench/elsewhere.py --json -> per split, the single answers of clips filmed where the venue
    was never modelled (no answer is right: err_m inf)."""
    out: dict[str, list[dict[str, Any]]] = {"tuning": [], "held-out": []}
    if path is None:
        return out
    for w in json.loads(path.read_text()):
        if w["kind"] == "own" or w["mode"] == "still, IMU":  # (the same single answers as "still")
            continue
        keys = ("single_support", "single_rival", "single_agree")
        if not all(k in w for k in keys):
            raise SystemExit(f"{path}: made before bench/elsewhere.py kept the answers' inputs; run it again")
        out[w["split"]] += [
            {"support": s, "rival": r, "agree": g, "err_m": float("inf")}
            for s, r, g in zip(*(w[k] for k in keys), strict=True)
        ]
    return out


def reliability(p: np.ndarray, y: np.ndarray) -> list[tuple[float, float, int, float, float]]:
    """(lo, hi, answers, mean confidence, share within 2 m) per confidence bin."""
    out = []
    for lo, hi in zip(BINS[:-1], BINS[1:], strict=True):
        m = (p >= lo) & (p < hi)
        if m.any():
            out.append((lo, min(hi, 1.0), int(m.sum()), float(p[m].mean()), float(y[m].mean())))
    return out


def report(label: str, p: np.ndarray, y: np.ndarray, err: np.ndarray) -> None:
    hi = p >= SURE
    brier = float(np.mean((p - y) ** 2))
    print(
        f"\n{label}: {len(y)} answers, within 2 m {y.mean():.1%}; conf >= {SURE}: {hi.mean():.1%} of answers, "
        f"{np.mean(err[hi] > 2.0) if hi.any() else 0:.2%} of them > 2 m; Brier {brier:.4f}"
    )
    print("| confidence | answers | mean confidence | within 2 m |\n| --- | ---: | ---: | ---: |")
    for lo, hi_, n, mc, share in reliability(p, y):
        print(f"| {lo:.2f}-{hi_:.2f} | {n} | {mc:.3f} | {share:.1%} |")


def diagram(path: Path, curves: list[tuple[str, np.ndarray, np.ndarray]]) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (ax, bx) = plt.subplots(2, 1, figsize=(5.5, 6.5), dpi=100, gridspec_kw={"height_ratios": [3, 1]})
    ax.plot([0, 1], [0, 1], ls="--", c="#888888", lw=1, label="perfectly calibrated")
    edges = np.array(BINS)
    for (label, p, y), colour in zip(curves, ("#1f77b4", "#d62728", "#2ca02c"), strict=False):
        rel = reliability(p, y)
        ax.plot([r[3] for r in rel], [r[4] for r in rel], "o-", c=colour, label=f"{label} ({len(y)} answers)")
        bx.hist(p, bins=edges, histtype="step", color=colour, lw=1.5)
    ax.axvline(SURE, c="#444444", lw=0.8, ls=":")
    ax.set_xlim(0, 1)
    ax.set_ylim(0, 1.02)
    ax.set_ylabel("share of answers within 2 m")
    ax.set_title("Confidence reliability: tuning and held-out families")
    ax.legend(loc="upper left", fontsize=8)
    bx.set_xlim(0, 1)
    bx.set_yscale("log")
    bx.set_xlabel("confidence")
    bx.set_ylabel("answers")
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", default="0")
    ap.add_argument("--clips", default="0.5,1,2,3")
    ap.add_argument("--png", type=Path)
    ap.add_argument("--l2", type=float, default=1e-4)
    ap.add_argument("--features", help="inputs of aggregate.CONFIDENCE_INPUTS (default: the preset's)")
    ap.add_argument("--held-out-seeds", help="the held-out families' seeds judged (default: --seeds)")
    ap.add_argument("--extra", action="append", default=[], help="FAMILY:SEEDS, more seeds of a tuning family")
    ap.add_argument("--cover", help="preset, or a share: the refit's share of tuning answers >= 0.8")
    ap.add_argument("--elsewhere", type=Path, help="bench/elsewhere.py --json: clips filmed elsewhere, all wrong")
    ap.add_argument("--elsewhere-weight", type=float, default=0.0, help="their weight, a share of the answers'")
    ap.add_argument("--look-alike-prior", type=float, default=0.0, help="weight of the look-alike rows")
    a = ap.parse_args()
    conf = resolve("default")
    names = a.features.split(",") if a.features else list(conf["confidence_features"])
    seeds = [int(s) for s in a.seeds.split(",")]
    clips = [float(c) for c in a.clips.split(",")]
    rows: dict[str, list[dict[str, Any]]] = {"tuning": [], "held-out": []}
    judged = [int(s) for s in a.held_out_seeds.split(",")] if a.held_out_seeds else seeds
    extra = extra_seeds(a.extra, seeds)  # (refused before anything is rendered)
    share = cover_share(a.cover)
    for split in rows:
        for fam in family_names(split):
            for seed in seeds if split == "tuning" else judged:
                for rs in rows_for(fam, seed, "default", clips).values():
                    rows[split] += rs
    for fam, seed in extra:
        for rs in rows_for(fam, seed, "default", clips).values():
            rows["tuning"] += rs
    # the confidence each answer gets from the preset's model (the diagram's, and --cover preset's)
    now = {split: np.array([confidence(r, conf) for r in rs]) for split, rs in rows.items()}
    away = elsewhere_rows(a.elsewhere)
    print(f"machine: {machine()}")
    x, y = design(rows["tuning"], names)
    wt = np.ones(len(y))
    if a.look_alike_prior > 0:
        px, py = look_alikes(rows["tuning"], names)
        x, y = np.vstack([x, px]), np.concatenate([y, py])
        wt = np.concatenate([wt, np.full(len(py), a.look_alike_prior)])
    if away["tuning"] and a.elsewhere_weight > 0:
        ex, ey = design(away["tuning"], names)
        x, y = np.vstack([x, ex]), np.concatenate([y, ey])
        wt = np.concatenate([wt, np.full(len(ey), a.elsewhere_weight * len(rows["tuning"]) / len(ey))])
    w = fit(x, y, a.l2, wt)
    if a.cover:
        xt = x[: len(rows["tuning"])]  # the answers themselves, not the look-alike prior's rows
        target = float(np.mean(now["tuning"] >= SURE)) if share is None else share
        w = cover(xt, w, target)
        print(f"intercept moved: {target:.1%} of the tuning answers at >= {SURE}")
    print(f"features: {names}; look-alike prior weight {a.look_alike_prior}; elsewhere weight {a.elsewhere_weight}")
    print("confidence_coef:", [round(float(v), 3) for v in w])
    curves = []
    for split, rs in rows.items():
        xs, ys = design(rs, names)
        err = np.array([r["err_m"] for r in rs])
        for label, p in (("the preset's", now[split]), ("refit", 1 / (1 + np.exp(-(xs @ w))))):
            report(f"{split}, {label} coefficients", p, ys, err)
        curves.append((split, now[split], ys))  # the diagram: the model answers are given with
        if away[split]:
            xe, _ = design(away[split], names)
            pre = np.mean([confidence(r, conf) >= SURE for r in away[split]])
            print(
                f"\n{split}, clips filmed elsewhere ({len(xe)}, all wrong): called sure by the preset's model "
                f"{pre:.1%}, by the refit {np.mean(xe @ w >= np.log(SURE / (1 - SURE))):.1%}"
            )
    if a.png:
        diagram(a.png, curves)
        print(f"\nwrote {a.png}")


if __name__ == "__main__":
    main()
