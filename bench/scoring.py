"""Scores of a source's clips, the same for every bench: per-clip outcomes, their summary, the
adoption rule's verdict on one source (docs/benchmarks.md, "Accuracy on three sources"), the reliability table.

Rows are what bench/venues.py and bench/foreign.py cache for every answer: its error, its
heading error and its confidence inputs (rescored with the configuration's model).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from scipy.optimize import minimize  # type: ignore[import-untyped]

from bench.ablation import CONFIGS
from bench.venues import rescore
from omninav.aggregate import SURE
from omninav.choose import paired_se
from omninav.presets import resolve


def conf_of(config: str) -> dict[str, Any]:
    preset, over = CONFIGS[config]
    return {**resolve(preset), **over}


def clip_id(r: dict[str, Any]) -> str:
    """Which clip a row answers: the pack's clip name, or a family walk's venue, seed and frame."""
    if "clip" in r:
        return str(r["clip"])
    return f"{r.get('family')}/{r.get('seed')}/{r.get('frame')}"


def scores(rows: list[dict[str, Any]], conf: dict[str, Any]) -> dict[str, np.ndarray]:
    """Per clip: its id, confidence, within 2 m, within 1 m, sure, sure and > 2 m off, and the
    heading error."""
    err = np.array([r["err_m"] for r in rows])
    c = rescore(rows, conf)
    sure = c >= SURE
    return {
        "id": np.array([clip_id(r) for r in rows]),
        "confidence": c,
        "near": err <= 2.0,
        "near1": err <= 1.0,
        "sure": sure,
        "sure_far": sure & (err > 2.0),
        "heading": np.abs([r["heading_err_deg"] for r in rows]),
    }


def summary(s: dict[str, np.ndarray]) -> dict[str, float]:
    """The shares the reports print. The heading error is the median over the answers within 2 m
    (as the foreign pack's README scores it); "sure_far" is a share of all clips."""
    near = s["near"]
    return {
        "clips": float(len(near)),
        "within_1m": float(s["near1"].mean()),
        "within_2m": float(near.mean()),
        "heading_deg": float(np.median(s["heading"][near])) if near.any() else math.nan,
        "sure": float(s["sure"].mean()),
        "sure_far": float(s["sure_far"].mean()),
        "wrong_among_sure": float(s["sure_far"].sum() / max(1, s["sure"].sum())),
    }


def clip_verdict(base: dict[str, np.ndarray], cand: dict[str, np.ndarray]) -> tuple[str, dict[str, float]]:
    """'loses', 'wins' or 'same' for a candidate against the baseline on one source of clips: a
    loss is a share within 2 m lower by more than twice its paired standard error, or a share of
    clips answered sure and > 2 m off higher by more than twice its own."""
    if not np.array_equal(base["id"], cand["id"]):
        raise ValueError("the two configurations did not answer the same clips in the same order")
    d_near = float(cand["near"].mean() - base["near"].mean())
    se_near = paired_se(base["near"], cand["near"])
    d_far = float(cand["sure_far"].mean() - base["sure_far"].mean())
    se_far = paired_se(base["sure_far"], cand["sure_far"])
    loses = d_near < -2 * se_near or d_far > 2 * se_far
    wins = not loses and (d_near > 2 * se_near or d_far < -2 * se_far)
    return ("loses" if loses else "wins" if wins else "same"), {
        "d_within_2m": d_near,
        "se_within_2m": se_near,
        "d_sure_far": d_far,
        "se_sure_far": se_far,
    }


BINS = (0.0, 0.5, 0.8, 0.9, 0.95, 1.01)


def reliability(s: dict[str, np.ndarray]) -> list[tuple[int, float]]:
    """Per confidence bin (BINS): how many answers, and the share of them within 2 m (the
    reliability diagram as a table: a calibrated confidence has each share inside its bin)."""
    out = []
    for lo, hi in zip(BINS[:-1], BINS[1:], strict=True):
        m = (s["confidence"] >= lo) & (s["confidence"] < hi)
        out.append((int(m.sum()), float(s["near"][m].mean()) if m.any() else math.nan))
    return out


def elevation_cost(r: dict[str, Any]) -> np.ndarray:
    """Per turn, how much of the turned photo's score a lens 2 degrees off in elevation (the worse
    way) takes away: scores of two feature sets are on scales of their own, their costs are not."""
    cost: np.ndarray = r["turned"] - np.minimum(r["elev -2°"], r["elev +2°"])
    return cost


def real_verdict(base: dict[str, Any], cand: dict[str, Any]) -> str:
    """'loses' where the elevation cost grows by more than twice its paired standard error over the
    turns, or the heading error grows by more than 0.5 degrees; 'wins' the other way."""
    d = elevation_cost(cand) - elevation_cost(base)
    se = float(np.std(d, ddof=1)) / math.sqrt(len(d))
    dh = cand["heading_deg"] - base["heading_deg"]
    if float(np.mean(d)) > 2 * se or dh > 0.5:
        return "loses"
    return "wins" if float(np.mean(d)) < -2 * se or dh < -0.5 else "same"


def fit(x: np.ndarray, y: np.ndarray, l2: float = 1e-4, weight: np.ndarray | None = None) -> np.ndarray:
    wt = np.ones(len(y)) if weight is None else weight

    def loss(w: np.ndarray) -> float:
        z = x @ w
        return float(np.sum(wt * (np.logaddexp(0, z) - y * z)) / wt.sum() + l2 * np.sum(w[1:] ** 2))

    return np.asarray(minimize(loss, np.zeros(x.shape[1]), method="BFGS").x)


def cover(x: np.ndarray, w: np.ndarray, share: float) -> np.ndarray:
    """w with its intercept moved so that `share` of the answers x get confidence >= SURE."""
    z = x @ w
    out = w.copy()
    out[0] += np.log(SURE / (1.0 - SURE)) - float(np.quantile(z, 1.0 - share))
    return out
