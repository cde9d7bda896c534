"""Test data for the web app, made by the Python engine at test time (nothing binary is committed).

    python e2e/fixtures.py golden OUT   # frames + the engine's panoramas, curves and records
    python e2e/fixtures.py ring OUT     # only the ring frames and the engine's rings (ring.json)
    python e2e/fixtures.py clip OUT [SCENE]  # a Y4M clip for Chromium's fake camera, at a known pose
                                             # (SCENE: another venue's seed; the demo's is 0)
    python e2e/fixtures.py admin OUT  # what an admin builds a venue from on the admin page: the
                                      # plan, the lens, a walk and an evaluation walk, and the truth
    python e2e/fixtures.py lens OUT KIND  # a Y4M clip for the phone's lens check: KIND is shifted
                                          # (the clip's lens clipped on 6 px off), nolens (a plain
                                          # picture, no ring) or cut (the ring cut by the edge)
    python e2e/fixtures.py walk OUT NAME  # a walk through the demo venue for route guidance: NAME is
                                         # to-stairs or wrong-way (OUT/NAME.y4m and its truth NAME.json)
    python e2e/fixtures.py renders WORK  # the renders kept while their recipe holds: the admin
                                         # page's (WORK/admin) and the guidance walks (WORK/walk)
    python e2e/fixtures.py age DATA VENUE  # (the server stopped) venue VENUE of data directory DATA
                                           # as an omninav from before the soft clipping left it

Golden files: a few frames of the synthetic venue through the engine's stages, so that the
TypeScript extractor (in Node and in Chromium) can be checked against them stage by stage; and
(ring.json) frames with known lens shifts and the ring the engine's `find_ring_frame` finds in
each, for the phone's ring finder (web/src/worker/ring.ts).
"""

from __future__ import annotations

import json
import sys
from collections.abc import Iterable
from dataclasses import replace
from pathlib import Path

import cv2
import numpy as np

from omninav.extract import Extractor
from omninav.lens import Catadioptric
from omninav.presets import FEATURE_KEYS, TWO_BANDS, resolve, settings_id
from omninav.spectrum import encode_binary, encode_local
from omninav.synth import QUERY, donut_lens, equirect_lens
from omninav.synth.clipon import REAL_MIRROR_SENSOR
from omninav.synth.scene import build_scene
from omninav.synth.walks import Perturb, Pose, render_frames
from omninav.unwarp import unwarp
from omninav.verify import FAST_THRESHOLD, detect, grey_panorama, panorama_map

# poses in the small synthetic layout (scene.py): corridor points, headings all round
POSES = [Pose(0.0, 6.0, 2.0, 30.0), Pose(0.1, 14.5, 2.2, 200.0), Pose(0.2, 20.0, 8.0, 300.0)]
# the same places with the phone held 4-7 degrees off vertical: what levelling (level.py) undoes
TILTED = [replace(p, tilt=t, tilt_dir=d) for p, t, d in zip(POSES, (6.0, 4.0, 7.0), (40.0, 170.0, 300.0), strict=True)]


def _case(out: Path, name: str, lens, preset: str, frames: list[np.ndarray], over: dict | None = None) -> dict:
    conf = resolve(preset, over)
    ext = Extractor(lens, conf)
    items = []
    specs = []
    for i, bgr in enumerate(frames):
        stem = f"{name}-{i}"
        cv2.imwrite(str(out / f"{stem}.png"), bgr)
        rgb = cv2.cvtColor(bgr, cv2.COLOR_BGR2RGB)
        rgba = np.dstack([rgb, np.full(rgb.shape[:2], 255, np.uint8)])
        (out / f"{stem}.rgba").write_bytes(rgba.tobytes())
        pano = cv2.cvtColor(unwarp(bgr, ext.frame_map(bgr)), cv2.COLOR_BGR2RGB)  # levelled, if the preset levels
        (out / f"{stem}.pano").write_bytes(pano.tobytes())
        (out / f"{stem}.curves").write_bytes(ext.curves(bgr).astype("<f4").tobytes())
        spec = ext.spectrum(bgr)
        specs.append(spec)
        (out / f"{stem}.rec").write_bytes(encode_binary(spec, conf))
        items.append({"stem": stem})
    (out / f"{name}.rec").write_bytes(encode_binary(np.stack(specs), conf))
    return {
        "name": name,
        "lens": lens.to_dict(),
        "settings": {k: conf.get(k) for k in FEATURE_KEYS},
        "settings_id": settings_id(conf),
        "pano_shape": [int(ext.map.map_x.shape[0]), int(ext.map.map_x.shape[1]), 3],
        "frames": items,
    }


LOCAL_FEATURES = 900  # the `verified` preset's


def _local_case(out: Path, name: str, lens, frames: list[np.ndarray], rgba: str) -> dict:
    """The engine's local features of each frame (verify.py): the panorama's remap (NAME.localmap:
    x then y, float32), each frame's grey panorama (STEM.lgrey) and its keypoints as a record's
    local block (STEM.local, docs/formats.md). The frames are those of the golden case `rgba`."""
    pm = panorama_map(lens)
    (out / f"{name}.localmap").write_bytes(
        pm.remap.map_x.astype("<f4").tobytes() + pm.remap.map_y.astype("<f4").tobytes()
    )
    stems = []
    for i, bgr in enumerate(frames):
        stem = f"{name}-{i}"
        (out / f"{stem}.lgrey").write_bytes(grey_panorama(bgr, pm).tobytes())
        q = detect(bgr, lens, LOCAL_FEATURES)
        (out / f"{stem}.local").write_bytes(encode_local(q))
        stems.append({"stem": stem, "rgba": f"{rgba}-{i}", "n": len(q[0])})
    rows, cols = pm.remap.map_x.shape
    return {
        "name": name,
        "lens": lens.to_dict(),
        "n_features": LOCAL_FEATURES,
        "shape": [rows, cols],
        "el": [float(pm.el[0]), float(pm.el[-1])],
        "frames": stems,
    }


LOOK = replace(QUERY, people=0, lateral_m=0.0)  # a colour cast, gain, tilt and noise, as a phone sees


def golden_frames() -> list[np.ndarray]:
    """The golden donut frames: the small venue at POSES, as a phone sees it."""
    return [f for _, f in render_frames(build_scene(0, "small"), donut_lens(1.0), POSES, LOOK, seed=7)]


def golden(out: Path) -> None:
    out.mkdir(parents=True, exist_ok=True)
    scene = build_scene(0, "small")
    donut = donut_lens(1.0)
    dframes = golden_frames()
    eq = equirect_lens(1440)
    eframes = [f for _, f in render_frames(scene, eq, POSES[:1], LOOK, seed=8)]
    tilted = [f for _, f in render_frames(scene, donut, TILTED, LOOK, seed=9)]
    cases = [
        _case(out, "donut-default", donut, "default", dframes),
        _case(out, "donut-six", donut, "six", dframes[:1]),
        _case(out, "donut-wide", donut, "wide", dframes[:1]),  # the venue option: one wide band, levelled
        _case(out, "equirect-default", eq, "default", eframes),
        # the default before per-band channels: what a phone makes for a venue modelled with it
        _case(out, "donut-before-bands", donut, "default", dframes[:1], TWO_BANDS),
        # levelled: the tilted phone's frames, each read through the remap its own edges level
        _case(out, "donut-tilted", donut, "default", tilted),
        # a real mirror's profile (`calib lens` on a real catadioptric camera: a skewed stretch and
        # decentring, lens.json's `sensor`), read on the same frames: the phone's sums are the engine's
        _case(out, "donut-sensor", replace(donut, sensor=REAL_MIRROR_SENSOR), "default", [dframes[0], tilted[0]]),
    ]
    # a dim frame (a quarter of the light): under half its keypoints at ORB's FAST_THRESHOLD, so
    # both detect it again at FAST_DIM
    dim = (dframes[0] * 0.25).astype(np.uint8)
    _rgba(out, "local-dim-0", dim)
    local = [
        _local_case(out, "local-donut", donut, dframes, "donut-default"),
        _local_case(out, "local-equirect", eq, eframes, "equirect-default"),
        _local_case(out, "local-dim", donut, [dim], "local-dim"),
    ]
    pano = grey_panorama(dim, panorama_map(donut))
    at_first = len(cv2.ORB.create(nfeatures=LOCAL_FEATURES, fastThreshold=FAST_THRESHOLD).detect(pano, None))
    assert at_first < LOCAL_FEATURES / 2, f"the dim golden frame keeps {at_first} keypoints at FAST_THRESHOLD"
    (out / "golden.json").write_text(json.dumps({"cases": cases, "local": local}, indent=1))
    ring_golden(out, dframes)


def hd_lens() -> Catadioptric:
    """The synthetic donut on a 1920x1080 (16:9) sensor: ring 157.5-510 px, a little off centre."""
    return replace(donut_lens(1.5), image_size=(1920, 1080), center=(962.0, 534.0))


# (stem, lens, shift px, scale, seed): clip-ons of the synthetic lens as a phone films them
RING_CASES = [
    ("ring-donut-still", "donut", (0.0, 0.0), 1.0, 1),
    ("ring-donut-shift", "donut", (6.0, -4.0), 1.01, 2),
    ("ring-donut-far", "donut", (-9.5, 3.0), 0.99, 3),
    ("ring-wide", "wide", (4.0, 2.5), 1.0, 4),
    ("ring-hd", "hd", (5.0, 3.0), 1.0, 5),
    ("ring-cut", "donut", (3.0, -30.0), 1.0, 6),  # off the top of the picture: "cut"
    ("ring-larger", "donut", (0.0, 0.0), 1.05, 7),  # 5 % larger: the usable circle leaves the top
    ("ring-housing", "donut", (4.0, -3.0), 1.0, 11),  # a bright housing hugs the ring (HOUSING_RIM)
]
# a small mirror's dark centre off its rim's centre: radius, offset (px), seed (synth.clipon.small_centre_frames)
SMALL_CENTRE = (40.0, (3.0, -2.0), 12)
# the bright annulus of a real clip-on's housing, right against the mirror's edge: brighter outside
# the ring than in it, and a more complete circle further out (calib/ring.py, A9)
HOUSING_RIM = (1.0, 1.15, 180.0)


def _rgba(out: Path, stem: str, bgr: np.ndarray) -> None:
    cv2.imwrite(str(out / f"{stem}.png"), bgr)
    rgb = cv2.cvtColor(bgr, cv2.COLOR_BGR2RGB)
    (out / f"{stem}.rgba").write_bytes(np.dstack([rgb, np.full(rgb.shape[:2], 255, np.uint8)]).tobytes())


def real_photos(out: Path) -> list[tuple[str, np.ndarray, Catadioptric]]:
    """Real lenses' frames for the phone's ring check against the engine's, each with the profile
    its own calibration gives: pyomniunwarp 0.2.5's donut photo (MIT, 1920x1080; bench/real_optics.py
    fetches it once with pip into OUT/real); none offline (the Vitest case says so)."""
    import subprocess

    sys.path.insert(0, str(Path(__file__).resolve().parent.parent))  # the repository's bench/
    from bench.real_optics import real_photo

    try:
        rgb, profile, _, _ = real_photo(out / "real")
    except (subprocess.SubprocessError, OSError):
        return []
    return [("real-pyomniunwarp", cv2.cvtColor(rgb, cv2.COLOR_RGB2BGR), profile)]


def ring_golden(out: Path, rendered: list[np.ndarray] | None = None) -> None:
    """ring.json: frames (.png, .rgba), the engine's `find_ring_frame` on each (null: no ring) and
    its `fit_lens` of the frame's lens profile (as it was before the lens was clipped on again).
    The clip-ons' frames (rendered once, kept while their recipe holds: the 1920x1080 one takes a
    few seconds) wear a real lens's surround; the golden donut frames above are bare renders."""
    from omninav.calib.lens_fit import fit_lens
    from omninav.calib.ring import find_ring_frame
    from omninav.synth.clipon import (
        Surround,
        covered_lens,
        plain_photo,
        reclip,
        ring_frames,
        small_centre_frames,
        wide_lens,
    )

    out.mkdir(parents=True, exist_ok=True)
    if rendered is None:
        rendered = golden_frames()
        for i, bgr in enumerate(rendered):
            _rgba(out, f"donut-default-{i}", bgr)

    lenses = {"donut": donut_lens(1.0), "wide": wide_lens(), "hd": hd_lens()}
    recipe = json.dumps(
        [
            RING_CASES,
            HOUSING_RIM,
            [lens.to_dict() for lens in lenses.values()],
            1,
            "dim",
            "measured",
            ["small-centre", SMALL_CENTRE],
        ]
    )
    old = out / "ring.json"
    cached = old.exists() and json.loads(old.read_text()).get("recipe") == recipe
    items = []
    Frame = tuple[str, np.ndarray, Catadioptric, tuple[float, float, float, float] | None]
    frames: list[Frame] = []
    for stem, name, shift, scale, seed in RING_CASES:
        true = reclip(lenses[name], shift, scale)
        if cached:
            bgr = cv2.imread(str(out / f"{stem}.png"))
        else:
            sur = Surround(rim=HOUSING_RIM) if stem == "ring-housing" else Surround()
            bgr = ring_frames(true, 1, seed=seed, sur=sur)[0]
            _rgba(out, stem, bgr)
        frames.append((stem, bgr, lenses[name], (true.center[0], true.center[1], true.r_inner, true.r_outer)))
    for i, bgr in enumerate(rendered):
        frames.append((f"donut-default-{i}", bgr, lenses["donut"], None))  # the golden frames (.rgba above)
    if not cached:
        _rgba(out, "ring-plain", plain_photo((960, 720), seed=6))
        _rgba(out, "ring-covered", covered_lens((960, 720), seed=6))
    # a profile made by `calib lens`: its optical centre 3.6 px off the ring it measured (`ring`)
    base = lenses["donut"]
    measured = replace(
        base, center=(base.center[0] + 3.0, base.center[1] - 2.0), ring=(*base.center, base.r_inner, base.r_outer)
    )
    moved = reclip(base, (2.0, 1.5), 1.0)
    if not cached:
        _rgba(out, "ring-measured", ring_frames(moved, 1, seed=8)[0])
    truth = (*moved.center, moved.r_inner, moved.r_outer)
    frames.append(("ring-measured", cv2.imread(str(out / "ring-measured.png")), measured, truth))
    # a dim room (a third of the light): the inner edge is found only by A8's second, fainter look
    dim = reclip(lenses["donut"], (2.0, 1.0), 1.0)
    if not cached:
        _rgba(out, "ring-dim", ring_frames(dim, 1, seed=9, sur=Surround(light=0.35))[0])
    frames.append(
        ("ring-dim", cv2.imread(str(out / "ring-dim.png")), lenses["donut"], (*dim.center, dim.r_inner, dim.r_outer))
    )
    # a small mirror's dark centre, 3.6 px off the rim's centre (A8's window and its fill)
    if not cached:
        _rgba(out, "ring-small-centre", small_centre_frames(lenses["donut"], 1, *SMALL_CENTRE)[0])
    base = lenses["donut"]
    frames.append(
        (
            "ring-small-centre",
            cv2.imread(str(out / "ring-small-centre.png")),
            base,
            (*base.center, SMALL_CENTRE[0], base.r_outer),
        )
    )
    for stem in ("ring-plain", "ring-covered"):
        frames.append((stem, cv2.imread(str(out / f"{stem}.png")), lenses["donut"], None))
    # real lenses: the phone must see the ring the engine sees (no truth but the engine's own)
    for stem, bgr, lens in real_photos(out):
        _rgba(out, stem, bgr)
        frames.append((stem, bgr, lens, None))
    for stem, bgr, lens, truth in frames:
        ring = find_ring_frame(bgr)
        fit = fit_lens(lens, ring)
        items.append(
            {
                "stem": stem,
                "size": [int(bgr.shape[1]), int(bgr.shape[0])],
                "truth": list(truth) if truth else None,
                "engine": ring.to_dict() if ring else None,
                "lens": lens.to_dict(),
                "fit": {k: v for k, v in fit.to_dict().items() if k != "lens"} | {"lens": fit.lens.to_dict()},
            }
        )
    old.write_text(json.dumps({"recipe": recipe, "frames": items}, indent=1))


def write_y4m(path: Path, frames: Iterable[np.ndarray], fps: int) -> int:
    """BGR frames (of one size; a list or as they are rendered) -> a YUV 4:2:0 Y4M file, the format
    Chromium's fake camera plays; returns how many."""
    n = 0
    with path.open("wb") as f:
        for bgr in frames:
            if not n:
                h, w = bgr.shape[:2]
                f.write(f"YUV4MPEG2 W{w} H{h} F{fps}:1 Ip A1:1 C420jpeg\n".encode())
            f.write(b"FRAME\n")
            f.write(cv2.cvtColor(bgr, cv2.COLOR_BGR2YUV_I420).tobytes())
            n += 1
    return n


def clip(out: Path, scene_seed: int = 0, scale: float = 0.5, frames: int = 20, fps: int = 10) -> None:
    """A user standing still in the quick demo venue (small layout), the phone turned away from the
    corridor: `frames` frames with sensor noise, a cast and a lens shift, and the truth. Another
    `scene_seed` films another building instead, one the demo venue has never seen."""
    out.mkdir(parents=True, exist_ok=True)
    scene = build_scene(scene_seed, "small")
    lens = donut_lens(scale)
    truth = {"x": 14.0, "y": 2.3, "heading_deg": 250.0}
    poses = [Pose(i / fps, truth["x"], truth["y"], truth["heading_deg"]) for i in range(frames)]
    look = Perturb(height_m=(1.3, 1.3), light=(0.9, 0.9), cast=0.05, lens_shift_px=1.0, noise=2.0)
    bgr = [f for _, f in render_frames(scene, lens, poses, look, seed=11)]
    write_y4m(out / "clip.y4m", bgr, fps)
    (out / "clip.json").write_text(json.dumps({**truth, "fps": fps, "frames": frames, "size": list(lens.image_size)}))


# the admin's building (the quick demo's scene, so that the fake camera's clip is in it): the walk
# leaves the far end of the second corridor unfilmed, where the admin draws "the stairwell"
ADMIN_WALK = [(2.0, 2.0), (20.0, 2.0), (20.0, 6.5)]
ADMIN_EVAL = [(20.0, 6.0), (20.0, 2.0), (3.0, 2.0)]
ADMIN_PLACES = [
    {"name": "Corridor 1", "area": [0.8, 0.8, 21.2, 3.2]},
    {"name": "Corridor 2", "area": [18.8, 3.2, 21.2, 8.0]},
    {"name": "the stairwell", "area": [18.8, 9.5, 21.2, 13.2]},  # never walked: grey
    {"name": "the entrance", "x": 2.0, "y": 2.0},
    {"name": "Room 1", "x": 11.0, "y": 2.0},
]


def admin(out: Path) -> None:
    """The admin page's inputs (plan.png, lens.json, walk.mp4, eval.mp4) and admin.json: the truth
    (each walk's waypoints, corners and duration), the places to draw and the scale's two plan pixels.
    Deterministic, and small: two walks of about 20 s at 480 x 360."""
    from omninav.synth.scene import floorplan_image
    from omninav.synth.walks import MODELLING, poses_from_walk_path, walk_path_for, write_video

    out.mkdir(parents=True, exist_ok=True)
    # rendered once (about 25 s on two cores), again when what it is made from changes
    recipe = json.dumps([ADMIN_WALK, ADMIN_EVAL, ADMIN_PLACES, 2])  # 2: the truth's walk_path key
    if (out / "admin.json").exists() and json.loads((out / "admin.json").read_text()).get("recipe") == recipe:
        return
    scene = build_scene(0, "small")
    lens = donut_lens(0.5)
    px_per_m, fps = 20.0, 10.0
    plan = floorplan_image(scene, px_per_m)
    cv2.imwrite(str(out / "plan.png"), cv2.cvtColor(plan, cv2.COLOR_RGB2BGR))
    (out / "lens.json").write_text(json.dumps(lens.to_dict(), indent=1))
    look = Perturb(height_m=(1.25, 1.45), light=(0.85, 1.1), cast=0.05, lens_shift_px=1.0, noise=2.0)
    walks = {}
    for name, route, speed, perturb, seed in (
        ("walk.mp4", ADMIN_WALK, 1.2, MODELLING, 21),
        ("eval.mp4", ADMIN_EVAL, 1.0, look, 31),
    ):
        walk_path = walk_path_for(route, [speed], fps)
        poses = poses_from_walk_path(walk_path, perturb, np.random.default_rng(seed), turn_s=1.5)
        frames = (f for _, f in render_frames(scene, lens, poses, perturb, seed + 1))
        n = write_video(out / name, frames, fps, lens.image_size)
        walks[name] = {"walk_path": walk_path, "frames": n, "duration_s": (n - 1) / fps}
    (out / "admin.json").write_text(
        json.dumps(
            {
                "recipe": recipe,
                "plan": {"size_px": [plan.shape[1], plan.shape[0]], "px_per_m": px_per_m},
                # two plan pixels 18 m apart along the first corridor's centre line
                "scale": {"a_px": [40, 40], "b_px": [400, 40], "distance_m": 18.0},
                "places": ADMIN_PLACES,
                "walk": walks["walk.mp4"],
                "eval": walks["eval.mp4"],
            },
            indent=1,
        )
    )


# the lens check's clips: the demo venue at clip()'s pose through a lens clipped on off centre
LENS_SHIFT = {"shifted": (5.0, -3.3), "cut": (2.0, -15.0)}


def lens_clip(out: Path, kind: str, frames: int = 20, fps: int = 10) -> None:
    """lens.y4m and lens.json (the truth, the shift) for the phone's lens check. "shifted": the
    lens clipped on 6 px off its profile's centre (the app corrects it and answers); "cut": 15 px
    up, so the ring leaves the picture at the top; "nolens": a plain picture, no ring at all."""
    from omninav.synth.clipon import plain_photo
    from omninav.synth.render import CameraModel, camera_frame, world_panorama
    from omninav.synth.walks import grid_for

    out.mkdir(parents=True, exist_ok=True)
    lens = donut_lens(0.5)
    truth = {"x": 14.0, "y": 2.3, "heading_deg": 250.0}
    rng = np.random.default_rng(17)
    if kind == "nolens":
        still = plain_photo(lens.image_size, seed=3, noise=0.0).astype(np.float32)
        shots = [still + rng.normal(0.0, 2.0, still.shape).astype(np.float32) for _ in range(frames)]
        shift = None
    else:
        shift = LENS_SHIFT[kind]
        scene = build_scene(0, "small")
        grid = grid_for(lens)
        cam = CameraModel.create(lens, shift)
        pano = world_panorama(scene, truth["x"], truth["y"], 1.3, grid)
        rgb = camera_frame(cam, pano, grid, truth["heading_deg"]).astype(np.float32) * 0.9
        shots = [rgb + rng.normal(0.0, 2.0, rgb.shape).astype(np.float32) for _ in range(frames)]
        shots = [cv2.cvtColor(np.clip(f, 0, 255).astype(np.uint8), cv2.COLOR_RGB2BGR) for f in shots]
    write_y4m(out / "lens.y4m", [np.clip(f, 0, 255).astype(np.uint8) for f in shots], fps)
    (out / "lens.json").write_text(json.dumps({**truth, "kind": kind, "shift_px": shift, "fps": fps}))


# Walks for route guidance (issue 14) in the quick demo venue (the L of scene.py's small layout:
# the entrance (2, 2), Room 1 (11, 2), the lifts at the corner (20, 2), the stairs (20, 12)), both
# to the stairs. Chromium's fake camera plays a walk in real time from when the app opens the camera
# (its first locate: the route's preview) and starts again at its end: each walk stands still first,
# long enough for the preview and Start, and stands at its end, long enough for a late answer.
# Steps: ("stand", s), ("turn", heading, s) on the spot, ("walk", x, y): at WALK_SPEED, turning to
# the new leg over TURN_S around its start (a corner is turned over TURN_S, walking).
WALK_SPEED = 1.0
TURN_S = 1.5
WALK_STAND_S = 8.0
WALKS: dict[str, dict] = {
    # the entrance to the stairs: 18 m east (a reassurance on the way), the turn at the lifts, 10 m south
    "to-stairs": {
        "from": (2.0, 2.0, 90.0),
        "steps": [("stand", WALK_STAND_S), ("walk", 20.0, 2.0), ("walk", 20.0, 12.0), ("stand", 25.0)],
    },
    # the L has no side corridor to take by mistake: the wrong way is back, away from the route. From
    # Room 1, facing the right way (east), the user turns round and walks west (walking back along
    # the route for two answers, and more than 3 m off it from x = 8 on), stands at the west end,
    # turns back and walks the new route as far as Room 1
    "wrong-way": {
        "from": (11.0, 2.0, 90.0),
        "steps": [
            ("stand", WALK_STAND_S),
            ("turn", 270.0, 2.0),
            ("walk", 2.5, 2.0),
            ("stand", 5.0),
            ("turn", 450.0, 2.0),
            ("walk", 11.0, 2.0),
            ("stand", 10.0),
        ],
    },
}
WALK_LOOK = Perturb(light=(0.85, 1.1), cast=0.06, people=1, lens_shift_px=1.0, noise=2.0)  # QUERY, milder


def walk_script(name: str) -> tuple[list[dict], list[tuple[float, float]], list[dict]]:
    """A walk's waypoints ({t, x, y}: linear in time, a point repeated = standing), its heading
    keys ((t, unwrapped heading): linear in time) and its marks ({t, what}: each step's start)."""
    spec = WALKS[name]
    x, y, h = spec["from"]
    t = 0.0
    wps = [{"t": 0.0, "x": x, "y": y}]
    keys = [(0.0, h)]
    marks = []
    for step in spec["steps"]:
        marks.append({"t": round(t, 3), "what": " ".join(str(s) for s in step)})
        if step[0] == "stand":
            t += step[1]
            keys.append((t, h))
        elif step[0] == "turn":
            h = step[1]
            t += step[2]
            keys.append((t, h))
        else:
            bx, by = step[1], step[2]
            leg = float(np.degrees(np.arctan2(bx - x, -(by - y))))
            leg += 360.0 * round((h - leg) / 360.0)  # the nearer way round
            d = float(np.hypot(bx - x, by - y))
            # the turn onto the leg, over TURN_S around its start (the key before it moved back)
            if abs(leg - h) > 1e-6 and keys[-1][0] == t:
                keys[-1] = (t - TURN_S / 2, h)
            keys.append((t + min(TURN_S / 2, d / WALK_SPEED / 2), leg))
            x, y, h = bx, by, leg
            t += d / WALK_SPEED
            keys.append((t, h))
        wps.append({"t": round(t, 3), "x": x, "y": y})
    marks.append({"t": round(t, 3), "what": "end"})
    return wps, keys, marks


def walk_poses(name: str, fps: float, rng: np.random.Generator) -> list[Pose]:
    """One pose per frame along the walk: the phone at 1.3-1.4 m, bobbing with each step and
    swaying 2 degrees once a stride while walking, tilted up to 3 degrees."""
    wps, keys, _ = walk_script(name)
    wt = np.array([w["t"] for w in wps])
    ts = np.arange(int(np.floor(wt[-1] * fps)) + 1) / fps
    x = np.interp(ts, wt, [w["x"] for w in wps])
    y = np.interp(ts, wt, [w["y"] for w in wps])
    kt, kh = np.array(keys).T
    moving = np.hypot(np.gradient(x), np.gradient(y)) > 1e-6
    hd = np.interp(ts, kt, kh) + moving * 2.0 * np.sin(2 * np.pi * 0.9 * ts)
    cam_h = rng.uniform(1.3, 1.4)
    tilt = np.interp(ts, np.arange(int(ts[-1]) + 2), rng.uniform(0.0, 3.0, int(ts[-1]) + 2))
    tdir = np.interp(ts, np.arange(int(ts[-1]) + 2), rng.uniform(0.0, 360.0, int(ts[-1]) + 2))
    return [
        Pose(
            float(t),
            float(px),
            float(py),
            float(np.mod(h, 360.0)),
            cam_h + 0.01 * moving[i] * np.sin(t * 2 * np.pi * 1.8),
            float(a),
            float(d),
        )
        for i, (t, px, py, h, a, d) in enumerate(zip(ts, x, y, hd, tilt, tdir, strict=True))
    ]


def walk(out: Path, name: str, fps: int = 10, scale: float = 0.5) -> None:
    """OUT/NAME.y4m (the walk WALKS[NAME] for the fake camera, at `fps`) and OUT/NAME.json: its
    truth (its positions as a walk path in docs/formats.md's form, for `omninav evaluate`; the pose,
    heading included, every half second; each step's start time). Rendered once (about 30 s on two
    cores), again when its recipe changes; the truth is written last, so a cut-off render is redone."""
    out.mkdir(parents=True, exist_ok=True)
    recipe = json.dumps([WALKS[name], WALK_SPEED, TURN_S, repr(WALK_LOOK), fps, scale, 2])  # 2: walk_path
    truth_path = out / f"{name}.json"
    if (out / f"{name}.y4m").exists() and truth_path.exists():
        if json.loads(truth_path.read_text()).get("recipe") == recipe:
            return
    lens = donut_lens(scale)
    poses = walk_poses(name, fps, np.random.default_rng(41))
    frames = (f for _, f in render_frames(build_scene(0, "small"), lens, poses, WALK_LOOK, seed=43))
    n = write_y4m(out / f"{name}.y4m", frames, fps)
    wps, _, marks = walk_script(name)
    half = [p for p in poses if round(p.t * fps) % max(1, fps // 2) == 0]
    truth_path.write_text(
        json.dumps(
            {
                "recipe": recipe,
                "name": name,
                "to": "the stairs",
                "fps": fps,
                "frames": n,
                "duration_s": (n - 1) / fps,
                "size": list(lens.image_size),
                "walk_path": {"fps": fps, "waypoints": wps, "heading_offset_deg": 0.0},
                "poses": [[round(p.t, 2), round(p.x, 3), round(p.y, 3), round(p.heading, 1)] for p in half],
                "marks": marks,
            },
            indent=1,
        )
    )


def age(data: Path, venue: str) -> None:
    """Make a modelled venue's live generation say what an omninav from before the soft clipping
    wrote (its feature settings without `soft_clip_sd`, so another settings id than the preset's,
    and without a format version: read through the migrations, settings_upgrade.py),
    as tests/server/test_model_anew.py's venue does, for the admin page's "Model anew" (admin-anew.spec.ts).
    Its spectra stay as they are: the spec models the venue anew before any phone locates there."""
    from omninav.store import Store

    store = Store(data)
    gen = store.generation(venue)
    if gen is None:
        sys.exit(f"venue {venue!r} of {data} is not modelled")
    path = store.venue_dir(venue) / gen / "settings.json"
    settings = json.loads(path.read_text())
    if "soft_clip_sd" not in settings:
        sys.exit(f"{path} has no soft_clip_sd: aged already, or the preset changed (update this fixture)")
    old = {k: v for k, v in settings.items() if k not in ("soft_clip_sd", "version")}  # (nor a version)
    if settings_id(old) == settings_id(resolve("default")):
        sys.exit("without soft_clip_sd the settings id is the preset's: this fixture no longer ages a venue")
    path.write_text(json.dumps(old, indent=1))


def renders(work: Path) -> None:
    """What Playwright's setup renders and keeps while its recipe holds (e2e/global-setup.ts):
    `npm test` makes it beside the API fuzzing and the PostgreSQL run (scripts/test.sh), which
    leave a core idle part of the time, and the setup then finds it made."""
    admin(work / "admin")
    for name in WALKS:
        walk(work / "walk", name)


if __name__ == "__main__":
    kinds = ("golden", "ring", "clip", "admin", "lens", "walk", "renders", "age")
    if len(sys.argv) not in (3, 4) or sys.argv[1] not in kinds:
        sys.exit(__doc__)
    if sys.argv[1] == "renders":
        renders(Path(sys.argv[2]))
    elif sys.argv[1] == "age":
        if len(sys.argv) != 4:
            sys.exit("age DATA VENUE")
        age(Path(sys.argv[2]), sys.argv[3])
    elif sys.argv[1] == "walk":
        if len(sys.argv) != 4 or sys.argv[3] not in WALKS:
            sys.exit(f"walk NAME: one of {', '.join(WALKS)}")
        walk(Path(sys.argv[2]), sys.argv[3])
    elif sys.argv[1] == "golden":
        golden(Path(sys.argv[2]))
    elif sys.argv[1] == "ring":
        ring_golden(Path(sys.argv[2]))
    elif sys.argv[1] == "admin":
        admin(Path(sys.argv[2]))
    elif sys.argv[1] == "lens":
        lens_clip(Path(sys.argv[2]), sys.argv[3] if len(sys.argv) == 4 else "shifted")
    else:
        clip(Path(sys.argv[2]), int(sys.argv[3]) if len(sys.argv) == 4 else 0)
