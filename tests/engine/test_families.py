"""Venue families (synth/families.py): every family builds, differs from the others in what it
claims to, walks sane routes, and renders the files make_dataset writes; the original venue
renders exactly as before."""

from __future__ import annotations

import dataclasses
import hashlib
import json

import cv2
import numpy as np
import pytest

from omninav.lens import Catadioptric, Equirectangular, load_lens
from omninav.synth import QUERY, build_scene, donut_lens
from omninav.synth.families import FAMILIES, family_venue, make_family_dataset
from omninav.synth.layouts import COMB_TEETH
from omninav.synth.optics import REAL
from omninav.synth.render import PanoGrid, world_panorama
from omninav.synth.scene import GRID, TEX_PPM, Lighting
from omninav.synth.walks import Perturb, default_routes, poses_from_walk_path, render_frames, walk_path_for
from omninav.walk_path import load_walk_path


def _pts(walk_path: dict) -> np.ndarray:
    """Points every 0.25 m along a walk path's waypoints."""
    wp = [(w["x"], w["y"]) for w in walk_path["waypoints"]]
    out = []
    for a, b in zip(wp[:-1], wp[1:], strict=True):
        n = max(1, int(np.hypot(b[0] - a[0], b[1] - a[1]) / 0.25))
        out += [(a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1])) for t in np.linspace(0, 1, n + 1)]
    return np.array(out)


def test_families_are_named_and_split():
    names = list(FAMILIES)
    assert names == [
        "ring-offices",
        "junctions-rich",
        "hall-daylight",
        "twin-wings",
        "ring-bare",
        "long-bare",
        "comb-mixed",
        "atrium-glass",
        "cross-device",
    ]
    splits = [f.split for f in FAMILIES.values()]
    assert splits == sorted(splits, key=lambda s: s != "tuning")  # tuning ones first
    for f in FAMILIES.values():
        assert f.split in ("tuning", "held-out") and f.describe.endswith(".")
    assert isinstance(FAMILIES["cross-device"].model_lens, Equirectangular)
    assert isinstance(FAMILIES["cross-device"].query_lens, Catadioptric)
    # each family films through the donut, at least QUERY's perturbations
    for f in FAMILIES.values():
        q = f.query_perturb
        assert q.lateral_m >= QUERY.lateral_m and q.tilt_deg >= QUERY.tilt_deg and q.people >= QUERY.people
        assert q.height_m[0] <= QUERY.height_m[0] and q.height_m[1] >= QUERY.height_m[1]
    # the tuning side has a corridor of identical doors too (long-bare's kind, another building)
    assert FAMILIES["ring-bare"].decor.door_phase == FAMILIES["long-bare"].decor.door_phase
    assert FAMILIES["ring-bare"].layout != FAMILIES["long-bare"].layout
    assert FAMILIES["atrium-glass"].query_perturb.optics == REAL
    assert FAMILIES["comb-mixed"].query_perturb.optics == REAL
    assert FAMILIES["hall-daylight"].query_perturb.optics not in (None, REAL)  # the milder lens
    sizes = {f.query_lens.image_size for f in FAMILIES.values()}
    assert len(sizes) >= 4  # image sizes and lens geometries vary


@pytest.mark.parametrize("name", list(FAMILIES))
def test_every_family_builds_and_walks_its_corridors(name):
    v = family_venue(name, 0)
    sc = v.scene
    assert sc.seg.shape[0] > 20 and sc.atlas.shape[0] == int(round(sc.wall_h * TEX_PPM))
    m, q = _pts(v.model_walk_path), _pts(v.query_walk_path)
    for x, y in np.concatenate([m, q]):  # both walks stay in free space
        assert sc.free[int(y / GRID), int(x / GRID)]
    # 75-150 one-second clips in the query walk (twin-wings's small ring: 79); the modelling walk
    # passes every query position (within the query's sideways offsets)
    assert 75 <= v.query_walk_path["waypoints"][-1]["t"] <= 150
    d = np.min(np.hypot(q[:, None, 0] - m[None, :, 0], q[:, None, 1] - m[None, :, 1]), axis=1)
    assert d.max() <= FAMILIES[name].query_perturb.lateral_m + 0.1
    # the query walk is not the modelling walk: it walks each corridor the other way (dead-end
    # stubs, walked in and out, both ways)
    qs, ms = np.diff(q, axis=0), np.diff(m, axis=0)
    qm, mm = (q[1:] + q[:-1]) / 2, (m[1:] + m[:-1]) / 2
    moving = np.hypot(*qs.T) > 1e-6
    near = np.hypot(qm[:, None, 0] - mm[None, :, 0], qm[:, None, 1] - mm[None, :, 1]) < 1.0
    cos = (qs @ ms.T) / np.maximum(np.hypot(*qs.T)[:, None] * np.hypot(*ms.T)[None, :], 1e-9)
    against = (near & (cos < -0.9)).any(axis=1)[moving]
    along = (near & (cos > 0.9)).any(axis=1)[moving]
    assert against.mean() > 0.9 and along.mean() < 0.35
    assert all(p["name"] for p in sc.places) and len(sc.places) == len(sc.centerlines)


# The original venues, rendered before the families were added (numpy 2 / OpenCV 4 here): the
# e2e golden frames and every benchmark depend on them staying as they are.
BEFORE = {
    "default": "9ca8fb9034976d1ae72202d9b47623596c232711",
    "small": "4b3c0b8cb8ee907885de1888021cf2ed7a327255",
    "twin": "ce6256d69003d6555b45f2b8b16cbd4eeeba0b32",
}
QUERY_FRAMES = "a32d35aee303aa598dc45dd3cd7ed7a215c5d632"  # 25 query frames of the default venue


@pytest.mark.parametrize("layout", list(BEFORE))
def test_original_layouts_render_as_before(layout):
    sc = build_scene(0, layout)
    (x, y), _ = sc.centerlines[0]
    pano = world_panorama(sc, x + 1.0, y, 1.35, PanoGrid(720, 60.0, -60.0, 241))
    assert hashlib.sha1(pano.tobytes()).hexdigest() == BEFORE[layout]


def test_query_walk_renders_as_before():
    """QUERY's perturbations, no optics: the same frames as before the optics hook."""
    sc = build_scene(0)
    _, q = default_routes(sc)
    poses = poses_from_walk_path(walk_path_for(q[:3], [1.0], 10.0), QUERY, np.random.default_rng(3))[:25]
    h = hashlib.sha1()
    for _, f in render_frames(sc, donut_lens(0.5), poses, QUERY, 4, 720):
        h.update(f.tobytes())
    assert h.hexdigest() == QUERY_FRAMES


def test_optics_hook_changes_frames_deterministically():
    sc = build_scene(0, "small")
    poses = poses_from_walk_path(walk_path_for([(2.0, 2.0), (6.0, 2.0)], [1.0], 10.0), QUERY, np.random.default_rng(0))[
        :3
    ]
    lens = donut_lens(0.25)

    def frames(p: Perturb) -> list[np.ndarray]:
        return [f for _, f in render_frames(sc, lens, poses, p, 1, 480)]

    with_optics = dataclasses.replace(QUERY, optics=REAL)
    plain, real, again = frames(QUERY), frames(with_optics), frames(with_optics)
    assert all(np.array_equal(a, b) for a, b in zip(real, again, strict=True))
    assert np.mean([np.abs(a.astype(int) - b).mean() for a, b in zip(plain, real, strict=True)]) > 1.0


def _busyness(atlas: np.ndarray) -> float:
    """Mean colour change from one wall column to the next: boards, signs and doors make it high."""
    return float(np.abs(np.diff(atlas.astype(np.int16), axis=1)).mean())


def test_families_differ_where_they_say():
    scenes = {n: family_venue(n, 0).scene for n in ("long-bare", "junctions-rich", "comb-mixed", "ring-offices")}
    busy = {n: _busyness(s.atlas) for n, s in scenes.items()}
    assert busy["junctions-rich"] > 1.5 * busy["long-bare"]
    assert busy["ring-offices"] > 1.2 * busy["long-bare"]
    # layouts: the grid has dead ends and the long corridors are long
    lens = {n: sum(np.hypot(b[0] - a[0], b[1] - a[1]) for a, b in s.centerlines) for n, s in scenes.items()}
    assert max(np.hypot(b[0] - a[0], b[1] - a[1]) for a, b in scenes["long-bare"].centerlines) >= 60
    assert all(100 <= v <= 160 for v in lens.values())
    # taller atrium
    assert family_venue("atrium-glass", 0).scene.wall_h > 3.0


def test_daylight_changes_with_the_hour_and_nothing_else():
    v = family_venue("hall-daylight", 0)
    a, b = v.scene, v.query_scene
    assert np.array_equal(a.seg, b.seg) and np.array_equal(a.seg_off, b.seg_off)
    diff = np.abs(a.atlas.astype(int) - b.atlas).max(axis=(0, 2))
    assert (diff > 30).mean() > 0.02  # glass and the walls by it
    far = build_scene(0, "hall", FAMILIES["hall-daylight"].decor, Lighting())
    far2 = build_scene(0, "hall", FAMILIES["hall-daylight"].decor, Lighting())
    assert np.array_equal(far.atlas, far2.atlas)  # deterministic
    # lamps of a colour per wing: warm and cool wings of the grid differ in their red/blue balance
    g = family_venue("junctions-rich", 0).scene
    h, w = g.floor.shape[:2]
    west, east = g.floor[:, : w // 2].reshape(-1, 3).mean(0), g.floor[: h // 2, w // 2 :].reshape(-1, 3).mean(0)
    assert west[0] / west[2] > east[0] / east[2] + 0.1


@pytest.mark.parametrize("name", ["cross-device", "atrium-glass"])
def test_family_dataset_files(tmp_path, name):
    ds = make_family_dataset(tmp_path / name, name, 0, scale=0.2, route_m=3.0)
    for p in (ds.model_video, ds.query_video, ds.model_walk_path, ds.query_walk_path, ds.lens, ds.floorplan):
        assert p.exists() and p.stat().st_size > 0
    assert (tmp_path / name / "model_lens.json").exists()
    assert json.loads((tmp_path / name / "family.json").read_text())["family"] == name
    for video, walk_path, lens in (
        (ds.model_video, ds.model_walk_path, tmp_path / name / "model_lens.json"),
        (ds.query_video, ds.query_walk_path, ds.lens),
    ):
        cap = cv2.VideoCapture(str(video))
        n, w, h = (
            int(cap.get(k)) for k in (cv2.CAP_PROP_FRAME_COUNT, cv2.CAP_PROP_FRAME_WIDTH, cv2.CAP_PROP_FRAME_HEIGHT)
        )
        cap.release()
        tr = load_walk_path(walk_path)
        assert n == int(np.floor(tr.times[-1] * tr.fps)) + 1
        assert (w, h) == load_lens(lens).image_size
    if name == "cross-device":
        assert isinstance(load_lens(tmp_path / name / "model_lens.json"), Equirectangular)


def test_comb_side_corridors_look_alike():
    """The comb's side corridors are painted alike: the same wall at the same place in each."""
    sc = build_scene(0, "comb", FAMILIES["comb-mixed"].decor)
    strips = {}
    for k, x in enumerate(COMB_TEETH):
        for (x0, y0, x1, y1), off in zip(sc.seg, sc.seg_off, strict=True):
            if abs((x0 + x1) / 2 - x) < 1.1 and 4.5 < (y0 + y1) / 2 < 12.1:
                w = int(round(np.hypot(x1 - x0, y1 - y0) * TEX_PPM))
                key = tuple(np.round([x0 - x, y0, x1 - x, y1], 1))
                strips.setdefault(key, []).append((k, sc.atlas[:, off : off + w]))
    same = [all(np.array_equal(a[1], b[1]) for b in v[1:]) for v in strips.values() for a in v[:1] if len(v) >= 3]
    assert len(same) >= 3 and np.mean(same) >= 0.5
    # and the spine's walls are not alike (a random wall elsewhere differs)
    assert _busyness(sc.atlas) > 0


def test_a_render_cached_under_the_old_file_names_is_renamed_in_place(tmp_path):
    """A render made before the walk path's rename keeps working: its `*_track.json` files take
    the new names (nothing rendered again), and a render under the new names is left alone."""
    from omninav.synth import OLD_NAMES, upgrade_names

    for old in OLD_NAMES:
        (tmp_path / old).write_text(json.dumps({"from": old}))
    assert upgrade_names(tmp_path) == tmp_path
    for old, new in OLD_NAMES.items():
        assert not (tmp_path / old).exists() and json.loads((tmp_path / new).read_text()) == {"from": old}
    before = {p.name: p.read_text() for p in tmp_path.iterdir()}
    upgrade_names(tmp_path)
    assert {p.name: p.read_text() for p in tmp_path.iterdir()} == before
