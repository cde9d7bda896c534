"""The quality map (quality.py) and the evaluation walk (evaluate.evaluate_walk).

The venue is the synthetic twin layout (scene.py): a ring whose west and east corridors are the
same corridor turned half round, a unique middle corridor, and a stairwell no walk enters. Its
modelling and query walks are rendered here, at half resolution.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import pytest

from conftest import cli_model, run_cli
from omninav.arrays import device_namespace
from omninav.evaluate import evaluate_walk
from omninav.index import Index
from omninav.lens import load_lens
from omninav.locate import Locator
from omninav.model_venue import model_video
from omninav.presets import n_curves, resolve
from omninav.quality import (
    _runs,
    axis_coverage,
    directions,
    quality_map,
    quality_png,
    sentence,
    verdict_of,
)
from omninav.store import FRAME_DTYPE, Generation, Store
from omninav.synth import Dataset, donut_lens, make_dataset
from omninav.synth.layouts import TWINS
from omninav.synth.render import world_panorama
from omninav.synth.scene import build_scene, floorplan_image
from omninav.synth.walks import grid_for
from omninav.walk_path import load_walk_path

SEED = 5


@pytest.fixture(scope="module")
def twin(tmp_path_factory: pytest.TempPathFactory) -> tuple[Dataset, Store]:
    ds = make_dataset(tmp_path_factory.mktemp("twin"), seed=SEED, layout="twin", scale=0.5)
    st = Store(tmp_path_factory.mktemp("twin-store"))
    model_video(st, "twin", ds.model_video, load_walk_path(ds.model_walk_path), load_lens(ds.root / "model_lens.json"))
    return ds, st


@pytest.fixture(scope="module")
def result(twin: tuple[Dataset, Store]) -> dict[str, Any]:
    ds, st = twin
    seen: list[tuple[int, int]] = []
    r = quality_map(st.load("twin"), ds.scene.places, {}, progress=lambda d, t, _s: seen.append((d, t)))
    assert seen and seen[-1][0] == seen[-1][1] and r["frames"] - 10 < seen[-1][1] <= r["frames"]
    return r


def _inside(p: list[float], area: list[float], tol: float = 0.0) -> bool:
    return area[0] - tol <= p[0] <= area[2] + tol and area[1] - tol <= p[1] <= area[3] + tol


# --- the venue ------------------------------------------------------------------------------------


def test_twin_corridors_are_the_same_corridor() -> None:
    scene = build_scene(SEED, "twin")
    a, b = (scene.places[i]["area"] for i in TWINS)
    in_b = [i for i, s in enumerate(scene.seg) if _inside([(s[0] + s[2]) / 2, (s[1] + s[3]) / 2], b, 0.05)]
    in_a = [i for i, s in enumerate(scene.seg) if _inside([(s[0] + s[2]) / 2, (s[1] + s[3]) / 2], a, 0.05)]
    assert len(in_b) == 2 and {int(scene.seg_off[i]) for i in in_b} == {int(scene.seg_off[i]) for i in in_a}
    grid = grid_for(donut_lens(0.5), 720)
    # the middle of the west corridor, and the same place of the east one, half a turn round
    west = world_panorama(scene, 3.0, 12.0, 1.35, grid).astype(np.float32)
    east = np.roll(world_panorama(scene, 27.0, 16.0, 1.35, grid), grid.width // 2, axis=1).astype(np.float32)
    middle = world_panorama(scene, 15.0, 12.0, 1.35, grid).astype(np.float32)
    assert np.abs(west - east).mean() < 2.0 < 10.0 < np.abs(west - middle).mean()
    # the other layouts are what they were: the twin's changes are its own
    assert build_scene(SEED, "small").routes is None


# --- the quality map ------------------------------------------------------------------------------


def test_the_repeated_stretch_is_flagged_and_the_rest_is_green(result: dict[str, Any]) -> None:
    scene = build_scene(SEED, "twin")
    twins = [scene.places[i]["area"] for i in TWINS]
    # the twins' straight middle: more than a metre from the corners, which differ
    core = [[x0, y0 + 3.4, x1, y1 - 3.4] for x0, y0, x1, y1 in twins]
    segs = result["segments"]
    flagged = [s["verdict"] != "green" for s in segs if any(_inside(s["points"][-1], c) for c in core)]
    rest = [s["verdict"] == "green" for s in segs if not any(_inside(s["points"][-1], t) for t in twins)]
    # measured (seed 5, and 7): 12 of the 14 core segments amber or red; all 46 of the rest green
    assert len(flagged) >= 10 and np.mean(flagged) >= 0.7
    assert len(rest) >= 30 and np.mean(rest) >= 0.85
    by_name = {c["place"]: c for c in result["corridors"]}
    for i in TWINS:
        assert by_name[scene.places[i]["name"]]["verdict"] in ("amber", "red")
    for name in ("North corridor", "South corridor", "Middle corridor"):
        assert by_name[name]["verdict"] == "green" and by_name[name]["share_green"] >= 0.85
    # a wrong segment's match is the other twin: the look-alike the page shows side by side
    red = [s for s in segs if s["verdict"] == "red" and any(_inside(s["points"][-1], c) for c in core)]
    assert red and all(s["error_m"] > 2.0 for s in red)
    for s in red:
        here = next(i for i in TWINS if _inside(s["points"][-1], twins[TWINS.index(i)]))
        other = twins[1 - TWINS.index(here)]
        assert _inside([s["match"]["x"], s["match"]["y"]], other)
        assert s["match"]["video"] == s["query"]["video"] == "model.mp4"


def test_an_uncovered_corridor_is_grey_and_named(result: dict[str, Any]) -> None:
    stairs = next(c for c in result["corridors"] if c["place"] == "Stairwell")
    assert stairs["verdict"] == "grey" and stairs["covered"] == 0.0 and stairs["share_green"] is None
    assert result["summary"]["uncovered"] == ["Stairwell"]
    assert "the Stairwell is not covered" in result["sentence"]
    walked = [c for c in result["corridors"] if c["place"] != "Stairwell"]
    assert all(c["covered"] >= 0.8 for c in walked)
    # every corridor was walked once: one sense each, and the sentence says so
    assert all(sum(c["directions"].values()) == 1 for c in walked)
    assert sorted(result["summary"]["one_direction"]) == sorted(c["place"] for c in walked)


def test_the_result_has_the_contract_format(result: dict[str, Any]) -> None:
    assert set(result) == {"generation", "frames", "radius_m", "segments", "corridors", "summary", "sentence"}
    assert result["radius_m"] == 2.0 and result["frames"] > 600
    s = result["segments"][0]
    assert set(s) == {"video", "floor", "t0", "t1", "points", "verdict", "error_m", "margin", "query", "match"}
    assert set(s["match"]) == {"video", "t", "x", "y"} and set(s["query"]) == {"video", "t"}
    assert s["floor"] == "1" and s["t0"] < s["t1"] and len(s["points"]) == 10
    assert set(result["corridors"][0]) == {
        "place",
        "floor",
        "area",
        "covered",
        "verdict",
        "share_green",
        "directions",
    }
    summary = result["summary"]
    assert set(summary) == {"share_green", "ambiguous", "wrong", "uncovered", "one_direction"}
    assert result["sentence"].startswith(f"{round(100 * summary['share_green'])} % of the walked corridors")
    json.dumps(result)  # plain JSON all the way down


def test_green_agrees_with_an_independent_walk(twin: tuple[Dataset, Store], result: dict[str, Any]) -> None:
    ds, st = twin
    seen: list[int] = []
    walk = evaluate_walk(
        Locator(st, "twin"),
        ds.query_video,
        load_walk_path(ds.query_walk_path),
        load_lens(ds.lens),
        progress=lambda d, t, _s: seen.append(d),
    )
    s = walk["summary"]
    # measured (seed 5): the quality map 77 % green, the query walk 73 % (within 2 m with the
    # same margin), 96 % within 2 m: its twin clips are right, by margins under 0.1
    assert abs(result["summary"]["share_green"] - s["share_green"]) <= 0.10
    assert s["within_2m"] >= s["share_green"] and s["within_2m"] >= 0.85
    assert seen and seen == sorted(seen)
    c = walk["clips"][0]
    assert set(c) == {"t", "truth", "answer", "error_m", "heading_error_deg"}
    assert set(c["truth"]) == {"x", "y", "heading_deg"}
    assert set(c["answer"]) == {"x", "y", "heading_deg", "confidence", "low_confidence", "margin"}
    assert set(s) == {
        "clips",
        "within_1m",
        "within_2m",
        "median_error_m",
        "median_heading_error_deg",
        "not_sure",
        "probably",
        "sure_over_2m",
        "share_green",
    }
    assert s["clips"] == len(walk["clips"]) > 60
    assert s["not_sure"] == sum(c["answer"]["low_confidence"] for c in walk["clips"])
    said = [(c["answer"]["low_confidence"], c["answer"]["confidence"] >= 0.8, c["error_m"] > 2) for c in walk["clips"]]
    assert s["probably"] == sum(not low and not sure for low, sure, _ in said)
    assert s["sure_over_2m"] == sum(sure and off for _, sure, off in said)
    assert s["not_sure"] + s["probably"] + sum(sure for _, sure, _ in said) == s["clips"]


def test_png_is_the_plan_size(result: dict[str, Any]) -> None:
    plan = floorplan_image(build_scene(SEED, "twin"), 20.0)
    png = quality_png(result, plan, 20.0, "1")
    img = cv2.imdecode(np.frombuffer(png, np.uint8), cv2.IMREAD_COLOR)
    assert img is not None and img.shape == plan.shape
    # the walk is drawn in the colours of its verdicts; another floor gets the pale plan only
    rgb = cv2.cvtColor(img, cv2.COLOR_BGR2RGB).reshape(-1, 3)
    for colour in ((46, 160, 67), (214, 39, 40)):
        assert (np.abs(rgb.astype(int) - colour).sum(axis=1) == 0).sum() > 100
    other = cv2.imdecode(np.frombuffer(quality_png(result, plan, 20.0, "2"), np.uint8), cv2.IMREAD_COLOR)
    assert not (np.abs(other.reshape(-1, 3).astype(int) - (67, 160, 46)).sum(axis=1) == 0).any()


def test_cli_quality(twin: tuple[Dataset, Store], tmp_path: Path) -> None:
    ds, _ = twin
    data = tmp_path / "data"
    (tmp_path / "places.json").write_text(json.dumps(ds.scene.places))
    run_cli(
        "venue",
        "create",
        "tw",
        "--floorplan",
        str(ds.floorplan),
        "--px-per-m",
        "20",
        "--places",
        str(tmp_path / "places.json"),
        data=data,
        check=True,
    )
    cli_model(ds, "tw", data)
    p = run_cli("quality", "tw", "-o", str(tmp_path / "q.json"), "--png", str(tmp_path / "q.png"), data=data)
    assert p.returncode == 0, p.stderr
    r = json.loads((tmp_path / "q.json").read_text())
    assert p.stdout.strip() == r["sentence"] and "the Stairwell is not covered" in r["sentence"]
    assert r["generation"] == 1
    assert cv2.imread(str(tmp_path / "q.png")).shape[:2] == cv2.imread(str(ds.floorplan)).shape[:2]
    bad = run_cli("quality", "tw", "--png", str(tmp_path / "q.png"), "--floor", "9", data=data)
    assert bad.returncode == 2 and "has no plan" in bad.stderr
    ev = run_cli(
        "evaluate",
        "tw",
        str(ds.query_video),
        "--walk-path",
        str(ds.query_walk_path),
        "--lens",
        str(ds.lens),
        "--clips",
        "--plot",
        str(tmp_path / "e.png"),
        data=data,
    )
    assert ev.returncode == 0, ev.stderr
    assert set(json.loads(ev.stdout)) == {"clips", "summary"}


# --- the parts ------------------------------------------------------------------------------------


def _walk(a: tuple[float, float], b: tuple[float, float], step: float = 0.12) -> np.ndarray:
    n = int(np.hypot(b[0] - a[0], b[1] - a[1]) / step) + 1
    return np.stack([np.linspace(a[0], b[0], n), np.linspace(a[1], b[1], n)], -1)


AREA = [0.0, 0.0, 10.0, 2.0]  # a corridor along x


def test_coverage_of_a_walk_half_way_along() -> None:
    xy = _walk((0.0, 1.0), (5.0, 1.0))
    s = axis_coverage(AREA, xy, np.zeros(len(xy), bool))
    assert s["covered"] == pytest.approx(0.5, abs=0.05) and s["backward"] == 0.0
    assert directions(s) == {"forward": True, "backward": False}


def test_coverage_both_ways_and_along_y() -> None:
    xy = np.concatenate([_walk((0.0, 1.0), (10.0, 1.0)), _walk((10.0, 1.2), (0.0, 1.2))])
    s = axis_coverage(AREA, xy, np.zeros(len(xy), bool))
    assert s["covered"] == s["forward"] == s["backward"] == 1.0
    assert directions(s) == {"forward": True, "backward": True}
    # the same along y, walked towards smaller y (backward)
    xy = _walk((1.0, 10.0), (1.0, 0.0))
    s = axis_coverage([0.0, 0.0, 2.0, 10.0], xy, np.zeros(len(xy), bool))
    assert s["covered"] == 1.0 and directions(s) == {"forward": False, "backward": True}


def test_coverage_ignores_crossings_and_cuts() -> None:
    # crossing the corridor: a bin or two covered, no sense walked
    xy = _walk((5.0, -3.0), (5.0, 5.0))
    s = axis_coverage(AREA, xy, np.zeros(len(xy), bool))
    assert 0 < s["covered"] <= 0.1 and directions(s) == {"forward": False, "backward": False}
    # two videos that end and start at the two ends do not cover what lies between them
    xy = np.array([[0.5, 1.0], [0.6, 1.0], [9.4, 1.0], [9.5, 1.0]])
    s = axis_coverage(AREA, xy, np.array([True, False, True, False]))
    assert s["covered"] == pytest.approx(0.1)
    # nor does a jump within one video (a walk path with a gap)
    s = axis_coverage(AREA, xy, np.array([True, False, False, False]))
    assert s["covered"] == pytest.approx(0.1)
    # a walk that never enters, and one lone frame inside
    assert axis_coverage(AREA, _walk((0.0, 5.0), (10.0, 5.0)), np.zeros(84, bool))["covered"] == 0.0
    assert axis_coverage(AREA, np.array([[3.2, 1.0]]), np.array([True]))["covered"] == pytest.approx(0.05)


def test_verdicts_runs_and_the_sentence() -> None:
    assert verdict_of([]) == "grey"
    assert verdict_of(["green"] * 6 + ["red"] * 2) == "red"  # a quarter wrong is wrong
    assert verdict_of(["green"] * 8 + ["red"] + ["amber"] * 2) == "amber"
    assert verdict_of(["green"] * 9 + ["amber"]) == "green"

    def seg(video: str, verdict: str) -> dict[str, Any]:
        return {"video": video, "verdict": verdict}

    segs = [seg("a", v) for v in ("green", "amber", "amber", "green", "amber")] + [seg("b", "amber")]
    assert _runs(segs, "amber") == 3 and _runs(segs, "red") == 0
    summary = {"share_green": 0.923, "ambiguous": 3, "wrong": 0, "uncovered": ["East stairwell"], "one_direction": []}
    assert sentence(summary) == (
        "92 % of the walked corridors answer within 2 m; 3 ambiguous stretches; the East stairwell is not covered"
    )
    summary.update(ambiguous=1, wrong=2, uncovered=["Corridor 1", "the hall"], one_direction=["West corridor"])
    assert sentence(summary) == (
        "92 % of the walked corridors answer within 2 m; 1 ambiguous stretch; 2 wrong stretches; "
        "Corridor 1 and the hall are not covered; the West corridor is filmed in one direction only"
    )
    summary.update(share_green=1.0, ambiguous=0, wrong=0, uncovered=[], one_direction=[])
    assert sentence(summary) == "100 % of the walked corridors answer within 2 m; no ambiguous stretches"


@pytest.mark.parametrize("key_dims", [0, 8])
def test_search_leaves_out_the_excluded_rows(key_dims: int) -> None:
    rng = np.random.default_rng(0)
    spec = (rng.normal(size=(300, 4, 8)) + 1j * rng.normal(size=(300, 4, 8))).astype(np.complex64)
    spec /= np.linalg.norm(spec.reshape(300, -1), axis=1)[:, None, None]
    index = Index(spec, np.zeros(300, np.float32), device="cpu", key_dims=key_dims)
    q = spec[100:110]
    plain = index.search(q, 5)
    assert (plain.index[:, 0] == np.arange(100, 110)).all()  # a frame finds itself
    lo, hi = np.arange(100, 110) - 2, np.arange(100, 110) + 3
    m = index.search(q, 5, exclude=(lo, hi))
    assert not ((m.index >= lo[:, None]) & (m.index < hi[:, None])).any()
    assert np.isfinite(m.coarse).all() and (m.score > -1).all()
    # with fewer rows left than candidates asked, an excluded row scores -1: it supports nothing
    small = Index(spec[:4], np.zeros(4, np.float32), device="cpu")
    m = small.search(spec[:1], 4, exclude=(np.array([0]), np.array([2])))
    assert sorted(m.index[0].tolist()) == [0, 1, 2, 3]
    assert (m.score[0][np.isin(m.index[0], [0, 1])] == -1).all()


def _drifting_generation(n: int, seed: int = 0) -> Generation:
    """n frames along a serpentine walk whose spectra drift slowly (bench/quality_speed.py's kind)."""
    conf = resolve("default")
    c, k = n_curves(conf), conf["n_harmonics"]
    rng = np.random.default_rng(seed)
    latent = np.cumsum(rng.normal(size=(n, 12)) * 0.05, axis=0) + rng.normal(size=(1, 12))
    mix = rng.normal(size=(12, c * k)) + 1j * rng.normal(size=(12, c * k))
    spec = (latent @ mix).reshape(n, c, k) + 0.05 * rng.normal(size=(n, c, k))
    spec /= np.sqrt((np.abs(spec) ** 2).sum(axis=(1, 2), keepdims=True))
    frames = np.zeros(n, FRAME_DTYPE)
    s = np.arange(n) * 0.12
    leg, along = np.divmod(s, 30.0)
    frames["x"], frames["y"] = np.where(leg % 2 == 0, along, 30.0 - along), 3.0 * leg
    frames["heading"] = np.where(leg % 2 == 0, 90.0, 270.0)
    frames["video"] = np.arange(n) // 1000
    frames["t"] = (np.arange(n) % 1000) / 10.0
    videos = [f"w{v}.mp4" for v in range(int(frames["video"].max()) + 1)]
    return Generation(conf, donut_lens(0.5), frames, spec.astype(np.complex64), videos)


@pytest.mark.gpu
@pytest.mark.skipif(device_namespace("auto") is np, reason="needs CuPy and a CUDA device")
@pytest.mark.parametrize("n", [1500, 2500])  # plain keys, and projected keys (key_project_above)
def test_gpu_quality_map_matches_cpu(n: int) -> None:
    gen = _drifting_generation(n)
    cpu = quality_map(gen, [], {}, device="cpu")
    gpu = quality_map(gen, [], {}, device="gpu")
    same = [a["verdict"] == b["verdict"] for a, b in zip(cpu["segments"], gpu["segments"], strict=True)]
    assert np.mean(same) >= 0.98  # float32 sums in another order may swap two near-tied candidates
    close = [
        abs(a["error_m"] - b["error_m"]) < 0.05
        for a, b in zip(cpu["segments"], gpu["segments"], strict=True)
        if a["match"]["t"] == b["match"]["t"]
    ]
    assert len(close) >= 0.95 * len(same) and all(close)


def test_quality_map_of_a_walk_in_two_videos() -> None:
    """Rows not in video-then-time order (a re-modelled video is appended) give the same map."""
    gen = _drifting_generation(2200)
    plain = quality_map(gen, [], {})
    order = np.random.default_rng(1).permutation(len(gen.frames))
    shuffled = Generation(gen.settings, gen.lens, gen.frames[order], gen.spectra[order], gen.videos)
    again = quality_map(shuffled, [], {})
    assert again["segments"] == plain["segments"] and again["summary"] == plain["summary"]


def test_the_quality_map_searches_as_a_locate_does(monkeypatch: pytest.MonkeyPatch) -> None:
    """Each clip of the walk is searched with the venue's shortlist (the default's where a venue
    modelled before it has none): the map says what a locate would answer."""
    seen: list[Any] = []
    real = Index.search

    def search(self: Index, *args: Any, **kwargs: Any) -> Any:
        seen.append(kwargs.get("shortlist"))
        return real(self, *args, **kwargs)

    monkeypatch.setattr(Index, "search", search)
    gen = _drifting_generation(400)
    wide = quality_map(gen, [], {})
    assert seen and set(seen) == {32}
    seen.clear()
    del gen.settings["shortlist"]  # a venue modelled before the shortlist
    assert quality_map(gen, [], {})["segments"] == wide["segments"] and set(seen) == {32}
    seen.clear()
    gen.settings["shortlist"] = 16
    quality_map(gen, [], {})
    assert set(seen) == {16}
