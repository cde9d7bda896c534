"""Scoring a walk (evaluate.py): which clips an evaluation walk is cut into."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np

from omninav.aggregate import Estimate, confidence
from omninav.evaluate import evaluate_spectra
from omninav.presets import resolve
from omninav.verify import checked_confidence


def test_every_second_of_an_admins_walk_is_scored_its_last_part_second_too() -> None:
    """25 frames at 10 frames/s: two whole 1 s clips, and with `tail` a third that ends at the last
    frame (overlapping the second), scored against the walk path there; without it, as the benchmarks
    measured, the last half second is left out."""
    conf = resolve("default")
    seen: list[np.ndarray] = []

    def estimate(spec: np.ndarray, t: np.ndarray, aggregate: str | None = None) -> Estimate:
        seen.append(t)
        return Estimate(1.0, 2.0, 90.0, 0, 0.9, 0.1, 1.0)

    loc = SimpleNamespace(
        conf=conf,
        estimate=estimate,
        confidence=lambda e, outcome=None: checked_confidence(outcome, confidence(e, conf)),
    )
    n = 25
    t = np.arange(n) / 10.0
    xy = np.stack([t, np.zeros(n)], axis=1)
    args = (np.zeros((n, 2, 3), np.complex64), t, xy, np.zeros(n), np.arange(n))
    plain = evaluate_spectra(loc, *args)  # type: ignore[arg-type]
    assert [r["t"] for r in plain.rows] == [0.9, 1.9]
    seen.clear()
    every = evaluate_spectra(loc, *args, tail=True)  # type: ignore[arg-type]
    assert [r["t"] for r in every.rows] == [0.9, 1.9, 2.4]
    assert len(seen[-1]) == 10 and seen[-1][0] == 1.5  # a whole second, ending at the last frame
    assert every.rows[-1]["true_x"] == 2.4
