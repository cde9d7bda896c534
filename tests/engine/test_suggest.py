"""Suggested waypoints (omninav/suggest.py): turns and stops found in a walk video.

Walks with known corners and stops are rendered here (small, low resolution, 10 fps) and the
suggestions compared with their walk paths; the signal processing is checked alone on made-up signals,
where a straight walk must suggest nothing.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from click.testing import CliRunner

from omninav.cli import cli
from omninav.errors import OmninavError
from omninav.lens import Lens
from omninav.suggest import (
    change_signal,
    find_stops,
    find_turns,
    frame_rotation,
    gaussian_smooth,
    robust_rotation,
    sector_shifts,
    sector_windows,
    settings_for,
    suggest_from_signals,
    suggest_waypoints,
)
from omninav.synth import MODELLING, QUERY, Perturb, build_scene, donut_lens, equirect_lens
from omninav.synth.walks import render_walk, walk_events, walk_path_for


@dataclass
class Walk:
    video: Path
    lens: Lens
    walk_path: dict[str, Any]
    turns: list[tuple[float, float]]  # the truth: (t, signed deg)
    stops: list[tuple[float, float]]  # (t, seconds)


def _walk(
    root: Path,
    name: str,
    layout: str,
    lens: Lens,
    route: list[tuple[float, float]],
    perturb: Perturb,
    turn_s: float,
    **walk_path: Any,
) -> Walk:
    tr = walk_path_for(route, fps=10.0, **walk_path)
    video = root / f"{name}.mp4"
    render_walk(video, build_scene(3, layout), lens, tr, perturb, seed=7, turn_s=turn_s, pano_width=720)
    turns, stops = walk_events(tr)
    return Walk(video, lens, tr, turns, stops)


@pytest.fixture(scope="module")
def walks(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Walk]:
    root = tmp_path_factory.mktemp("suggest")
    return {
        # the small L, its corner turned at once (as docs/formats.md's heading does)
        "L": _walk(
            root, "L", "small", donut_lens(0.5), [(2.0, 2.0), (20.0, 2.0), (20.0, 12.0)], MODELLING, 0.0, speeds=[1.2]
        ),
        # the default ring: right and left corners, a stop at a corner and one mid-corridor
        "ring": _walk(
            root,
            "ring",
            "default",
            donut_lens(0.5),
            [(15.0, 3.0), (27.0, 3.0), (27.0, 23.0), (39.0, 23.0), (51.0, 23.0), (51.0, 3.0), (39.0, 3.0)],
            MODELLING,
            1.0,
            speeds=[1.5, 1.3],
            stops={2: 3.0, 3: 2.0},
        ),
        # a 360 camera held 40 degrees off the walking direction, walked as a user would (people,
        # tilt, a colour cast, the body swaying +-5 deg a stride), with a U-turn at the end of a
        # corridor and a stop at the end
        "equirect": _walk(
            root,
            "equirect",
            "small",
            equirect_lens(360),
            [(2.0, 2.0), (20.0, 2.0), (20.0, 11.0), (20.0, 5.0)],
            replace(QUERY, sway_deg=5.0),
            1.5,
            speeds=[1.3],
            heading_offset=40.0,
            stops={3: 2.0},
        ),
    }


@pytest.fixture(scope="module")
def results(walks: dict[str, Walk]) -> dict[str, dict[str, Any]]:
    return {k: suggest_waypoints(w.video, w.lens) for k, w in walks.items()}


def _of(r: dict[str, Any], kind: str) -> list[dict[str, Any]]:
    return [s for s in r["suggestions"] if s["kind"] == kind]


@pytest.mark.parametrize("name", ["L", "ring", "equirect"])
def test_every_corner_has_a_turn_within_1s(
    walks: dict[str, Walk], results: dict[str, dict[str, Any]], name: str
) -> None:
    w, r = walks[name], results[name]
    turns = _of(r, "turn")
    assert w.turns, "the walk has corners"
    for t, deg in w.turns:
        near = [s for s in turns if abs(s["t"] - t) <= 1.0]
        assert near, f"no turn suggested within 1 s of the corner at {t:.1f} s: {turns}"
        got = near[0]["turn_deg"]
        if abs(deg) == 180:  # a U-turn may go either way round
            assert abs(abs(got) - 180) <= 25, got
        else:
            assert abs(got - deg) <= 25, f"turn at {t:.1f} s: {got} deg suggested, {deg} walked"


@pytest.mark.parametrize("name", ["L", "ring", "equirect"])
def test_few_suggestions_and_start_end(walks: dict[str, Walk], results: dict[str, dict[str, Any]], name: str) -> None:
    w, r = walks[name], results[name]
    sug = r["suggestions"]
    events = len(w.turns) + len(w.stops)
    assert len(sug) <= 2 * events + 2, sug
    assert sug[0]["kind"] == "start" and sug[0]["t"] == 0.0
    last_t = w.walk_path["waypoints"][-1]["t"]
    assert sug[-1]["kind"] == "end" and abs(sug[-1]["t"] - last_t) <= 0.15
    assert [s["t"] for s in sug] == sorted(s["t"] for s in sug)
    assert r["fps"] == pytest.approx(10.0) and r["frames"] == int(last_t * 10) + 1
    assert r["duration_s"] == pytest.approx(r["frames"] / 10.0)
    for s in sug:
        assert set(s) == {"t", "kind", "turn_deg", "duration_s"}
        assert (s["turn_deg"] is not None) == (s["kind"] == "turn")
        assert (s["duration_s"] is not None) == (s["kind"] == "stop")
    json.dumps(r, allow_nan=False)  # plain JSON, as the server stores it


@pytest.mark.parametrize("name", ["ring", "equirect"])
def test_stops_found_with_their_duration(walks: dict[str, Walk], results: dict[str, dict[str, Any]], name: str) -> None:
    w, r = walks[name], results[name]
    stops = _of(r, "stop")
    assert w.stops
    for t, dur in w.stops:
        near = [s for s in stops if abs(s["t"] - t) <= 1.0]
        assert near, f"no stop suggested within 1 s of the stop at {t:.1f} s: {stops}"
        assert abs(near[0]["duration_s"] - dur) <= 1.0, (near[0], dur)


def test_no_stop_in_a_walk_without_one(results: dict[str, dict[str, Any]]) -> None:
    assert _of(results["L"], "stop") == []


def test_heading_curve(walks: dict[str, Walk], results: dict[str, dict[str, Any]]) -> None:
    """The cumulative heading, twice a second: each corner turns it by the corner's angle, and
    walking straight drifts it by well under a degree a second."""
    for name in ("L", "ring", "equirect"):
        h = np.array(results[name]["heading"])
        assert h.shape[1] == 2 and np.allclose(np.diff(h[:, 0]), 0.5) and h[0, 0] == 0.0
        for t, deg in walks[name].turns:
            change = np.interp(t + 2.0, h[:, 0], h[:, 1]) - np.interp(t - 2.0, h[:, 0], h[:, 1])
            assert abs(abs(change) - abs(deg)) <= 25, (name, t, change, deg)
        total = sum(d for _, d in walks[name].turns)
        if name != "equirect":  # (the U-turn's sign is either)
            assert abs(h[-1, 1] - total) <= 0.75 * h[-1, 0], (name, h[-1, 1], total)


def test_progress_and_wrong_lens(walks: dict[str, Walk]) -> None:
    w = walks["L"]
    seen: list[tuple[int, int]] = []
    suggest_waypoints(w.video, w.lens, {"sample_fps": 5.0}, progress=lambda d, n, e: seen.append((d, n)))
    frames = int(w.walk_path["waypoints"][-1]["t"] * 10) + 1
    assert seen[-1][0] == seen[-1][1] == len(seen) == (frames - 1) // 2 + 1  # every other frame of 10 fps
    assert [d for d, _ in seen] == list(range(1, len(seen) + 1))
    with pytest.raises(OmninavError, match="lens profile is for 960x720"):
        suggest_waypoints(w.video, donut_lens(1.0))
    with pytest.raises(OmninavError, match="not found"):
        suggest_waypoints(w.video.with_name("nothing.mp4"), w.lens)


def test_cli_table_and_json(walks: dict[str, Walk], tmp_path: Path) -> None:
    w = walks["L"]
    (tmp_path / "lens.json").write_text(json.dumps(w.lens.to_dict()))
    out = tmp_path / "s.json"
    res = CliRunner().invoke(
        cli, ["suggest-waypoints", str(w.video), "--lens", str(tmp_path / "lens.json"), "-o", str(out)]
    )
    assert res.exit_code == 0, res.output
    lines = res.output.splitlines()
    assert any("turn" in ln and "right" in ln for ln in lines), res.output
    assert lines[2].split()[:2] == ["0:00.0", "start"]
    r = json.loads(out.read_text())
    assert [s["kind"] for s in r["suggestions"]] == ["start", "turn", "end"]
    bad = CliRunner().invoke(
        cli,
        [
            "suggest-waypoints",
            str(w.video),
            "--lens",
            str(tmp_path / "lens.json"),
            "-o",
            str(tmp_path / "no" / "s.json"),
        ],
    )
    assert bad.exit_code != 0 and "does not exist" in str(bad.exception)


# --- the signal processing alone -----------------------------------------------------------------


def _signals(heading: np.ndarray, fps: float = 10.0) -> tuple[np.ndarray, np.ndarray]:
    t = np.arange(len(heading)) / fps
    return t, np.diff(heading)


def test_a_straight_walk_suggests_no_turn() -> None:
    """Noise of 1.5 deg a frame and a slow drift of 20 deg a minute: no turn, only start and end."""
    rng = np.random.default_rng(0)
    n = 600
    h = np.cumsum(rng.normal(0, 1.5, n)) * 0.3 + np.linspace(0, 20, n)
    t, rel = _signals(h)
    walking = np.full(n - 5, 0.5)
    r = suggest_from_signals(t, rel, walking, t[-1])
    assert [s["kind"] for s in r["suggestions"]] == ["start", "end"]


def test_a_sway_is_not_a_turn() -> None:
    """Swinging +-10 deg once a second turns fast but never far."""
    t = np.arange(300) / 10.0
    assert find_turns(t, 10 * np.sin(2 * np.pi * t)) == []


@pytest.mark.parametrize(("deg", "over_s"), [(90, 1.0), (-90, 0.5), (45, 2.0), (90, 4.0), (180, 1.5), (-135, 0.1)])
def test_a_turn_is_found_at_its_middle(deg: float, over_s: float) -> None:
    t = np.arange(400) / 10.0
    h = np.interp(t, [20 - over_s / 2, 20 + over_s / 2], [0, deg])
    h += np.random.default_rng(1).normal(0, 0.3, len(t))
    turns = find_turns(t, gaussian_smooth(h, 3.0))
    assert len(turns) == 1
    assert turns[0][0] == pytest.approx(20.0, abs=0.15) and turns[0][1] == pytest.approx(deg, abs=5)


def test_an_s_bend_is_two_turns_and_a_small_one_none() -> None:
    t = np.arange(400) / 10.0
    h = np.interp(t, [10, 11, 14, 15, 30, 31], [0, 90, 90, 0, 0, 20])
    turns = find_turns(t, gaussian_smooth(h, 3.0))
    assert [round(d / 10) * 10 for _, d in turns] == [90, -90]
    assert [round(tt) for tt, _ in turns] == [10, 14]  # 10.5 and 14.5: middles


def test_stops_merge_across_a_blip_and_short_ones_drop() -> None:
    t = np.arange(200) / 10.0
    c = np.full(200, 0.5)
    c[50:80] = 0.003  # stood 5.0 .. 8.0 s (the last still pair ends 0.5 s later)
    c[62:66] = 0.08  # someone walked into view
    c[120:124] = 0.003  # 0.9 s: not a stop
    assert find_stops(t, c, 0.5, 0.05, 1.0) == [(5.0, pytest.approx(3.4))]
    assert find_stops(t, np.full(200, 0.5), 0.5, 0.05, 1.0) == []


def test_sector_shifts_rotation_and_parallax() -> None:
    rng = np.random.default_rng(2)
    b = gaussian_smooth(rng.normal(0, 1, 360 * 6), 2.0).reshape(6, 360).astype(np.float32)
    win = sector_windows(360, 12, 30.0)
    # a pure rotation of 7 deg clockwise: a(j) = b(j + 7), found in every sector
    a = np.roll(b, -7, axis=1)
    sh, pk = sector_shifts(a, b, win, guess_deg=5.0)
    assert np.allclose(sh, 7.0, atol=0.2) and (pk > 0.99).all()
    # far beyond the search range only with the right guess
    a = np.roll(b, -95, axis=1)
    sh, _ = sector_shifts(a, b, win, guess_deg=92.0)
    assert np.allclose(sh, 95.0, atol=0.2)
    # a corridor looks alike both ways: a whole-circle guess 180 deg out loses to "no turn"
    a = np.roll(b, -3, axis=1)
    assert frame_rotation(a, b, win, [183.0, 0.0, 0.0], 20.0, 0.5) == pytest.approx(3.0, abs=0.2)
    # parallax: one side slides back, the other forward; the median keeps the rotation
    par = np.array([0.0, -2.0, -4.0, -5.0, -4.0, -2.0, 0.0, 2.0, 4.0, 5.0, 4.0, 2.0])
    assert robust_rotation(3.0 + par, np.ones(12), 0.5, 99.0) == pytest.approx(3.0)
    assert robust_rotation(3.0 + par, np.zeros(12), 0.5, 99.0) == 99.0  # nothing trusted: the guess


def test_change_ignores_rotation() -> None:
    rng = np.random.default_rng(3)
    f = np.fft.rfft(rng.normal(0, 1, (12, 360)), axis=-1)[:, 1:17]
    f /= np.sqrt((np.abs(f) ** 2).sum())
    turned = f * np.exp(-1j * 2 * np.pi * np.arange(1, 17) * 40 / 360)
    other = np.fft.rfft(rng.normal(0, 1, (12, 360)), axis=-1)[:, 1:17]
    other /= np.sqrt((np.abs(other) ** 2).sum())
    c = change_signal(np.stack([f, turned, other]).astype(np.complex64), 1)
    assert c[0] < 1e-3 and c[1] > 0.3


def test_bad_input_is_refused() -> None:
    with pytest.raises(OmninavError, match="unknown suggestion setting 'fsp'"):
        settings_for({"fsp": 5})
    with pytest.raises(OmninavError, match="positive"):
        settings_for({"sample_fps": 0})
    with pytest.raises(ValueError):
        suggest_from_signals(np.arange(5.0), np.zeros(5), np.zeros(3), 4.0)
    with pytest.raises(ValueError):
        find_turns(np.arange(5.0), np.zeros(4))


def test_signals_of_a_one_frame_video_and_a_standing_start() -> None:
    r = suggest_from_signals(np.zeros(1), np.zeros(0), np.zeros(0), 0.0)
    assert [s["kind"] for s in r["suggestions"]] == ["start", "end"] and r["heading"] == [[0.0, 0.0]]
    t = np.arange(100) / 10.0
    change = np.where(t[:95] < 2.0, 0.002, 0.5)  # stood for the first 2.5 s (pairs 0.5 s apart)
    r = suggest_from_signals(t, np.zeros(99), change, t[-1])
    assert [(s["kind"], s["t"], s["duration_s"]) for s in r["suggestions"]] == [
        ("start", 0.0, None),
        ("stop", 0.0, 2.4),
        ("end", 9.9, None),
    ]
