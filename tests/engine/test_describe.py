"""The answer in words (describe.py), against the table of cases that the app's
directions.ts is also held to (tests/data/sentences.json, run by web/tests/sentences.test.ts)."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import pytest

from omninav import describe as words

TABLE = json.loads((Path(__file__).parents[1] / "data" / "sentences.json").read_text())
CASES = [(c, style) for c in TABLE["cases"] for style in c["say"]]


def test_the_thresholds_and_words_are_the_tables():
    assert (words.NEAR_M, words.FACING_M, words.FACING_DEG) == (
        TABLE["near_m"],
        TABLE["facing_m"],
        TABLE["facing_deg"],
    )
    assert words.UNSURE == TABLE["unsure"] and words.DEFAULT_STYLE == TABLE["default_style"]
    assert words.SURE == TABLE["sure"]


@pytest.mark.parametrize(("case", "style"), CASES, ids=[f"{c['case']} [{s}]" for c, s in CASES])
def test_each_answer_is_said_as_the_table_says(case: dict[str, Any], style: words.Style):
    assert words.sentence(case["answer"], style, case["floor_name"]) == case["say"][style]


POSES = [c for c in TABLE["cases"] if c.get("pose")]


@pytest.mark.parametrize("case", POSES, ids=[c["case"] for c in POSES])
def test_a_pose_on_the_plan_gives_the_answers_fields_and_sentence(case: dict[str, Any]):
    """What locate() adds to an answer: the table's fields, and the default style's sentence."""
    a = case["answer"]
    got = words.describe(
        a["x"], a["y"], a["heading_deg"], TABLE["places"], case["floor_name"], a["low_confidence"], a["confidence"]
    )
    want = {k: a[k] for k in ("place", "area", "nearest", "facing")}
    assert got == {**want, "sentence": case["say"][TABLE["default_style"]]}


def test_every_style_and_the_boundaries_are_covered():
    """Keep the table honest: each style is pinned, and so are the clock's and the sides' boundaries."""
    assert {s for c in TABLE["cases"] for s in c["say"]} == {"clock", "sides", "degrees"}
    bearings = {c["answer"]["nearest"]["bearing_deg"] for c in TABLE["cases"] if c["answer"]["nearest"]}
    assert {15.0, -15.0, 60.0, 120.0, 165.0, -165.0, 180.0, -180.0} <= bearings


def test_bearings_are_clockwise_from_the_heading_on_a_y_down_plan():
    assert words.relative_bearing(0, 0, 0, 0, -5) == 0  # straight up the plan, facing up
    assert words.relative_bearing(0, 0, 0, 5, 0) == 90  # to the right: clockwise
    assert words.relative_bearing(0, 0, 90, 0, -5) == -90  # facing east, "up" is on the left
    assert words.relative_bearing(0, 0, 0, 0, 5) == 180  # behind is +180, never -180


def test_the_smallest_area_holding_the_point_is_the_one_named():
    places = [
        {"name": "West wing", "x": 10, "y": 10, "area": [0, 0, 40, 40]},
        {"name": "Room 7", "x": 5, "y": 5, "area": [2, 2, 8, 8]},
    ]
    w = words.describe(5, 5, 0, places, "Floor 2")
    assert w["area"] == "Room 7" and w["place"] == "Room 7" and w["nearest"] is None
    assert w["sentence"] == "You are in Room 7."


def test_probably_is_said_exactly_under_the_sure_line():
    """Every answer that is not "not sure" is "You are probably ..." under SURE and "You are ..." from it."""
    sure = [c for c in TABLE["cases"] if not c["answer"]["low_confidence"]]
    assert {c["answer"]["confidence"] < words.SURE for c in sure} == {True, False}
    assert any(c["answer"]["confidence"] == words.SURE for c in sure)
    for c in sure:
        for said in c["say"].values():
            assert said.startswith("You are probably ") == (c["answer"]["confidence"] < words.SURE), c["case"]
