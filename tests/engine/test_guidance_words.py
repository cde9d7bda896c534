"""The words of route guidance (describe.py), against the table of cases that the app's
directions.ts is also held to (tests/data/guidance.json, run by web/tests/guidance.test.ts)."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import pytest

from omninav import describe as words

TABLE = json.loads((Path(__file__).parents[1] / "data" / "guidance.json").read_text())
CASES = [(c, style) for c in TABLE["cases"] for style in c["say"]]


def test_the_thresholds_and_words_are_the_tables():
    assert words.STRAIGHT_DEG == TABLE["straight_deg"] and words.GUIDE_UNSURE == TABLE["unsure"]
    assert words.GUIDE_NOT_HERE == TABLE["not_here"]
    assert list(words.SECTOR_DEG) == TABLE["sector_deg"] and words.AROUND_DEG == TABLE["around_deg"]


@pytest.mark.parametrize("style", ["clock", "sides", "degrees"])
def test_turns_and_directions_share_the_sectors(style: words.Style):
    """One sector function words both a turn and a place's direction: no turn exactly where a place
    is "straight ahead", and in the sides style the same sector for both, but that a turn beyond
    AROUND_DEG is "Turn around"."""
    for b in [x / 2 for x in range(-360, 361)]:
        k = words.sector(b)
        assert (words.turn_phrase(b, style) is None) == (k == 0), b
        if style == "sides":
            turn = "Turn around" if abs(b) > words.AROUND_DEG else ["", "Bear", "Turn", "Turn sharp", "Turn around"][k]
            place = ["straight ahead", "ahead on your", "to your", "behind you on your", "behind you"][k]
            assert (words.turn_phrase(b, style) or "").startswith(turn) and words.direction(b, style).startswith(place)


@pytest.mark.parametrize(("case", "style"), CASES, ids=[f"{c['case']} [{s}]" for c, s in CASES])
def test_each_guidance_is_said_as_the_table_says(case: dict[str, Any], style: words.Style):
    assert words.guidance_sentence(case["guidance"], style) == case["say"][style]


@pytest.mark.parametrize("case", TABLE["previews"], ids=[c["case"] for c in TABLE["previews"]])
def test_each_preview_is_said_as_the_table_says(case: dict[str, Any]):
    assert words.preview_sentence(case["preview"], case["to"]) == case["say"]


def test_every_kind_style_and_boundary_is_covered():
    """Keep the table honest: every kind and style pinned, and the boundaries of the turns."""
    cases = TABLE["cases"]
    assert {c["guidance"]["kind"] for c in cases} == {
        "start",
        "turn",
        "continue",
        "reassure",
        "off_route",
        "back_on_route",
        "arrived",
        "probably_arrived",
        "floor_change",
        "unsure",
        "not_here",
    }
    assert all(set(c["say"]) == {"clock", "sides", "degrees"} for c in cases)
    bearings = {c["guidance"]["bearing_deg"] for c in cases}
    assert {15.0, -15.0, 60.0, 120.0, 150.0, -161.0, 180.0} <= bearings
    assert {p["preview"]["turns"] for p in TABLE["previews"]} >= {0, 1, 2}
    # a turn said before its corner: metres to it, under half a metre (the turn is now), none
    in_m = [c["guidance"].get("in_m") for c in cases]
    assert None in in_m and any(m is not None and m < 0.5 for m in in_m)
    assert {c["guidance"]["kind"] for c in cases if (c["guidance"].get("in_m") or 0) >= 0.5} == {"start", "turn"}


def test_the_issues_sentences_are_said_word_for_word():
    said = {s for c in TABLE["cases"] for s in c["say"].values()} | {p["say"] for p in TABLE["previews"]}
    assert {
        "Turn to 2 o'clock and walk 12 metres, to the end of the corridor.",
        "Keep going, 8 metres to the lifts.",
        "You are off the route; turn to 7 o'clock.",
        "You have arrived at Room 102; it is at 3 o'clock, 2 metres.",
        "Room 102: 45 metres, 2 turns, first turn after 12 metres.",
        "Take the lift to Floor 2.",
        "Walk straight ahead 12 metres, to the end of the corridor.",
        "In 3 metres, turn to 9 o'clock and walk 9 metres, to Room 1.",
        "In 3 metres, turn left and walk 9 metres, to Room 1.",
        "In 3 metres, turn 90 degrees left and walk 9 metres, to Room 1.",
    } <= said
