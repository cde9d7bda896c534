"""Choosing a building's preset from an evaluation walk (choose.py, `omninav choose-preset`)."""

from __future__ import annotations

import json

import pytest

from conftest import run_cli
from omninav.choose import CANDIDATES, check_presets, pick
from omninav.errors import OmninavError
from omninav.presets import PRESETS
from omninav.synth import Dataset


def _r(preset: str, near: float, sure: float) -> dict:
    return {"preset": preset, "within_2m": near, "confident_share": sure}


def test_the_most_clips_within_2_m_win_then_the_surest_then_the_first_listed() -> None:
    assert pick([_r("default", 0.90, 0.8), _r("wide", 0.95, 0.6)]) == "wide"
    assert pick([_r("default", 0.95, 0.8), _r("wide", 0.95, 0.9)]) == "wide"  # as many near: the surer
    assert pick([_r("default", 0.95, 0.8), _r("wide", 0.95, 0.8)]) == "default"  # a tie keeps the first
    assert set(CANDIDATES) <= set(PRESETS) and CANDIDATES[0] == "default"


@pytest.mark.parametrize("bad", [["default"], ["default", "default"], ["default", "nope"], []])
def test_two_or_more_different_known_presets_or_a_clear_refusal(bad: list[str]) -> None:
    with pytest.raises(OmninavError, match="presets"):
        check_presets(bad)


def _args(ds: Dataset, *more: str) -> list[str]:
    walk = [str(ds.model_video), "--track", str(ds.model_track), "--lens", str(ds.root / "model_lens.json")]
    return ["choose-preset", *walk, "--eval", str(ds.query_video), "--eval-track", str(ds.query_track), *more]


def test_refusals_come_before_any_work(small_ds: Dataset, tmp_path) -> None:
    p = run_cli(*_args(small_ds, "--presets", "default,robust"), data=tmp_path)
    assert p.returncode != 0 and "unknown presets ['robust']" in p.stderr and "modelling" not in p.stderr
    p = run_cli(*[a if a != str(small_ds.query_video) else str(tmp_path / "no.mp4") for a in _args(small_ds)])
    assert p.returncode != 0 and "no.mp4: video not found" in p.stderr


@pytest.mark.slow
def test_the_building_chooses_the_preset_that_locates_its_evaluation_walk_best(small_ds: Dataset, tmp_path) -> None:
    """The paper's method listed first against the default on the small venue's independent query
    walk (the default locates it far better: tests/test_accuracy.py): the default is chosen, from
    the figures it prints, and nothing is written to the data folder."""
    p = run_cli(
        *_args(small_ds, "--presets", "paper,default", "--eval-lens", str(small_ds.lens), "--json"), data=tmp_path
    )
    assert p.returncode == 0, p.stderr
    out = json.loads(p.stdout)
    got = {r["preset"]: r for r in out["presets"]}
    assert list(got) == ["paper", "default"] and all(r["clips"] > 10 and r["venue_frames"] > 100 for r in got.values())
    assert got["default"]["within_2m"] > got["paper"]["within_2m"] + 0.1
    assert out["chosen"] == "default"
    assert not any(tmp_path.iterdir())  # a scratch store: the catalogue is not touched
