"""Fit the confidence model: P(answer within 2 m) = logistic(w . [1, support, margin]).

Evaluates the default preset on the given synthetic venues (rendered once by bench/accuracy.py's
cache), fits the three weights by L2-regularised log-loss, and prints them with a reliability table.
Paste the weights into presets.py's `confidence_coef`; tests check calibration on a held-out venue.

    python bench/calibrate.py --seeds 0,1
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np
from scipy.optimize import minimize

sys.path.insert(0, str(Path(__file__).parent))
from accuracy import dataset, run  # noqa: E402


def features(rows: list[dict]) -> tuple[np.ndarray, np.ndarray]:
    x = np.array([[1.0, r["support"], r["support"] - r["rival"]] for r in rows])
    y = np.array([r["err_m"] <= 2.0 for r in rows], float)
    return x, y


def fit(x: np.ndarray, y: np.ndarray, l2: float = 1e-5) -> np.ndarray:
    def loss(w: np.ndarray) -> float:
        z = x @ w
        return float(np.mean(np.logaddexp(0, z) - y * z) + l2 * np.sum(w[1:] ** 2))

    return minimize(loss, np.zeros(x.shape[1]), method="BFGS").x


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--seeds", default="0,1")
    a = ap.parse_args()
    rows: list[dict] = []
    for seed in (int(s) for s in a.seeds.split(",")):
        root = dataset(Path("data") / f"bench-venue-{seed}", seed)
        rows += run(root, "default", "default", {}, "sequence", "v").rows
        # clips of 3 and 5 frames too: harder, so the fit sees more wrong answers
        rows += run(root, "default", "default", {}, "sequence", "v", clip_s=0.3).rows
        rows += run(root, "default", "default", {}, "sequence", "v", clip_s=0.5).rows
    x, y = features(rows)
    w = fit(x, y)
    p = 1 / (1 + np.exp(-(x @ w)))
    print(f"clips {len(y)}, within 2 m {y.mean():.1%}")
    print("confidence_coef:", [round(float(v), 3) for v in w])
    for lo, hi in ((0, 0.5), (0.5, 0.8), (0.8, 0.9), (0.9, 1.01)):
        m = (p >= lo) & (p < hi)
        if m.any():
            print(f"  conf [{lo:.1f}, {hi:.1f}): {m.sum():4d} answers, {y[m].mean():.1%} within 2 m")


if __name__ == "__main__":
    main()
