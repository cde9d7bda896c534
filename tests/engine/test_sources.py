"""The three-source report and its adoption rule (bench/scoring.py, bench/sources.py,
bench/ablation.py): the noise of a source, the verdicts that decide a default, the clips scored as
the foreign pack's README says, and the ladder of changes the ablation reads."""

from __future__ import annotations

import math

import numpy as np
import pytest

from omninav.lens import Catadioptric, Equirectangular
from omninav.presets import resolve


def _clips(near: list[bool], sure_far: list[bool] | None = None) -> dict[str, np.ndarray]:
    n = np.array(near)
    sf = np.array(sure_far if sure_far is not None else [False] * len(near))
    ids = np.array([f"q{i:03d}" for i in range(len(n))])
    return {"id": ids, "near": n, "near1": n, "sure": sf | n, "sure_far": sf, "heading": np.zeros(len(n))}


def test_paired_noise_counts_only_the_clips_the_two_answer_differently() -> None:
    from omninav.choose import paired_se

    a = np.array([True] * 50 + [False] * 10)
    assert paired_se(a, a) == 0.0  # the same answers: no noise, whatever the share
    b = a.copy()
    b[:4] = False  # four clips only the baseline gets
    assert paired_se(a, b) == pytest.approx(math.sqrt(4 - 16 / 60) / 60)
    c = a.copy()
    c[:3], c[-3:] = False, True  # three lost, three won: no change, but noise
    assert paired_se(a, c) == pytest.approx(math.sqrt(6) / 60)


def test_a_candidate_loses_a_source_only_beyond_its_noise() -> None:
    from bench.scoring import clip_verdict

    base = [True] * 50 + [False] * 10
    one_lost = [False] + base[1:]
    assert clip_verdict(_clips(base), _clips(one_lost))[0] == "same"  # one clip in 60 is noise
    many_lost = [False] * 8 + base[8:]
    verdict, d = clip_verdict(_clips(base), _clips(many_lost))
    assert verdict == "loses" and d["d_within_2m"] == pytest.approx(-8 / 60)
    many_won = base[:50] + [True] * 8 + [False] * 2
    assert clip_verdict(_clips(base), _clips(many_won))[0] == "wins"
    # as many within 2 m, but four more of them answered sure where they were wrong: it loses
    worse_sure = _clips(base, [False] * 50 + [True] * 4 + [False] * 6)
    assert clip_verdict(_clips(base), worse_sure)[0] == "loses"
    other = _clips(base)
    other["id"] = other["id"][::-1]  # answers of other clips, or in another order, are not paired
    with pytest.raises(ValueError, match="same clips"):
        clip_verdict(_clips(base), other)


def test_clips_are_scored_as_the_foreign_packs_readme_says() -> None:
    from bench.scoring import scores, summary

    conf = {"confidence_features": ["support", "sqrt_margin"], "confidence_coef": [-7.67, 9.761, 7.692]}
    sure = {"support": 0.95, "rival": 0.3, "agree": 1.0}  # confidence well above 0.8
    unsure = {"support": 0.4, "rival": 0.39, "agree": 1.0}
    rows = [
        {"clip": "q0", "err_m": 0.5, "heading_err_deg": 1.0, **sure},
        {"clip": "q1", "err_m": 1.5, "heading_err_deg": -3.0, **sure},
        {"clip": "q2", "err_m": 12.0, "heading_err_deg": 170.0, **sure},  # sure and far: counts against the clips
        {"clip": "q3", "err_m": 30.0, "heading_err_deg": 90.0, **unsure},
    ]
    s = summary(scores(rows, conf))
    assert s["within_1m"] == 0.25 and s["within_2m"] == 0.5
    assert s["heading_deg"] == 2.0  # over the answers within 2 m only
    assert s["sure"] == 0.75 and s["sure_far"] == 0.25  # shares of all clips
    assert s["wrong_among_sure"] == pytest.approx(1 / 3)
    family_row = {"family": "long-bare", "seed": 1, "frame": 40, "err_m": 1.0, "heading_err_deg": 0.0, **sure}
    assert list(scores([family_row], conf)["id"]) == ["long-bare/1/40"]


def test_the_real_photo_judges_the_elevation_cost_and_the_heading() -> None:
    from bench.scoring import elevation_cost, real_verdict

    turns = np.full(8, 0.93)

    def photo(cost: float, heading: float = 0.1, seed: int = 0) -> dict:
        jitter = np.random.default_rng(seed).normal(0, 0.002, 8)  # each turn resamples the picture
        return {"turned": turns, "elev -2°": turns - cost + jitter, "elev +2°": turns, "heading_deg": heading}

    base = photo(0.04)
    assert np.allclose(elevation_cost(base), 0.04, atol=0.003)
    assert real_verdict(base, photo(0.007, seed=1)) == "wins"  # the wide band's cost against the default's
    assert real_verdict(photo(0.007, seed=1), base) == "loses"
    assert real_verdict(base, photo(0.0405, seed=1)) == "same"  # within the spread over the turns
    assert real_verdict(base, photo(0.04, heading=0.8, seed=1)) == "loses"  # 0.7 degrees worse


def test_a_lens_off_in_elevation_reads_every_radius_that_much_higher() -> None:
    from bench.ablation import elevation_off

    lens = Catadioptric((960, 720), (480.0, 360.0), 100.0, 340.0, (-80.0, 0.5, -0.001))
    off = elevation_off(lens, 2.0)
    r = np.linspace(100.0, 340.0, 7)
    assert np.allclose(off.elevation(r) - lens.elevation(r), 2.0)
    assert off.center == lens.center and off.r_outer == lens.r_outer
    assert elevation_off(lens, 0.0) is lens
    pano = Equirectangular((1920, 960), 0.0)
    assert elevation_off(pano, 2.0) is pano  # a 360 camera has no elevation profile to be off


def test_the_ladder_adds_one_change_a_rung() -> None:
    """bench/ablation.py: the rungs resolve to valid settings, each differs from the one before it
    in the settings its name says (the ablation table's reading), and the bench's name for the
    wide preset has its settings."""
    from bench.ablation import CONFIGS, LADDER

    conf = {name: resolve(p, over) for name, (p, over) in CONFIGS.items()}

    def diff(a: str, b: str) -> set[str]:
        return {k for k in conf[b] if conf[a].get(k) != conf[b][k] and k != "preset"}

    assert LADDER[0] == "paper" and LADDER[-1] == "default" and conf["default"] == resolve("default")
    assert diff("paper", "paper-sequence") == {"aggregate"}
    assert diff("paper-sequence", "six") == {"channels", "aggregate"}
    assert diff("six", "six-sequence") == {"aggregate"}
    assert diff("six-sequence", "gray-world") == {"gray_world"}
    assert diff("gray-world", "opponent") == {"channels"}
    assert diff("opponent", "two-bands") == {"bands", "n_harmonics"}
    assert diff("soft-clip", "two-bands") == {"soft_clip_sd"}
    assert diff("soft-clip", "five-bands") == {"bands", "band_channels"}
    assert diff("five-bands", "levelled") == {"level_iters"}
    assert diff("levelled", "shared") == {"shared_candidates", "shortlist"}
    assert diff("shared", "default") == {"shortlist"}
    assert not conf["levelled"]["shared_candidates"] and conf["default"]["shared_candidates"]
    assert diff("one-band-levelled", "wide" if "wide" in conf else "one-band-levelled") == set()
    wide = resolve("wide")
    assert {k for k in wide if wide[k] != conf["one-band-levelled"][k]} == {"preset"}
