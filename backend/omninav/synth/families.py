"""Venue families: synthetic buildings that differ in what real buildings differ in.

The engine was tuned on one renderer's venue; a real building is another renderer again (issue 13).
Each family here is a kind of building: its layout (rings, junctions and dead ends, halls and
atria, long repetitive corridors, look-alike side corridors, stairwells), its materials and how
busy its walls are, its lighting (fluorescent rows, dim stretches, mixed colour temperatures,
daylight that changes between the modelling and the query walk), its people, how the phone is
held, the lens geometry and image size, real optics and the video's compression. Settings are
chosen on the `tuning` families and judged on the `held-out` ones.

    make_family_dataset(root, "long-bare", seed)   # the same files synth.make_dataset writes
"""

from __future__ import annotations

import dataclasses
import json
from collections.abc import Iterable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from ..lens import Catadioptric, Equirectangular, Lens
from . import Dataset, dataset_files, donut_lens, equirect_lens
from .clipon import geometries, resized
from .layouts import Point
from .optics import MILD, REAL
from .scene import COOL, DEFAULT_DECOR, NEUTRAL, WARM, Decor, Lighting, Scene, build_scene
from .walks import (
    MODELLING,
    QUERY,
    Perturb,
    default_routes,
    offset_route,
    poses_from_walk_path,
    render_frames,
    walk_path_for,
    write_video,
)

SPLITS = ("tuning", "held-out")


@dataclass(frozen=True)
class Family:
    """A kind of building and how it is filmed (see the module's docstring)."""

    name: str
    split: str  # "tuning" | "held-out"
    describe: str  # one sentence for docs/benchmarks.md
    layout: str  # a layout of synth.layouts.LAYOUTS (its own modelling and query routes)
    model_lens: Lens  # the camera the venue is modelled with
    query_lens: Lens  # the donut the user films with
    decor: Decor = DEFAULT_DECOR
    lighting: Lighting | None = None
    query_hour: float | None = None  # daylight of the query walk (the modelling walk's: lighting.hour)
    model_perturb: Perturb = MODELLING
    query_perturb: Perturb = QUERY
    model_jpeg: int | None = None  # JPEG quality each frame goes through before the video codec
    query_jpeg: int | None = None
    model_speed: float = 1.2  # m/s
    query_speeds: tuple[float, ...] = (1.0, 1.3, 1.1, 0.9)  # m/s, per leg, cycled
    query_route: tuple[Point, ...] | None = None  # instead of the layout's own


def square_lens(scale: float = 1.0) -> Catadioptric:
    """A third geometry: an 800x600 video whose ring (70-290 px, -35..+50 deg, a cubic profile)
    sits a little off centre, forward to the image's right."""
    r_in, r_out = 70.0, 290.0
    rs = np.linspace(r_in, r_out, 4)
    coef = np.polyfit(rs, [-35.0, -12.0, 15.0, 50.0], 3)[::-1]  # ascending powers
    lens = Catadioptric(
        image_size=(800, 600),
        center=(406.0, 296.0),
        r_inner=r_in,
        r_outer=r_out,
        elevation_poly=tuple(float(c) for c in coef),
        forward_deg=0.0,
        ccw=True,
    )
    return resized(lens, scale)


# the ring's modelling walk backwards, less its last 24 m (make_dataset's query walk goes half of
# the ring the same way as the modelling walk)
RING_QUERY_ROUTE: tuple[Point, ...] = (
    (27.0, 23.0),
    (27.0, 3.0),
    (3.0, 3.0),
    (3.0, 23.0),
    (27.0, 23.0),
    (51.0, 23.0),
    (51.0, 3.0),
    (27.0, 3.0),
)

_FAMILIES = [
    Family(
        "ring-offices",
        "tuning",
        "The original venue: a 48 x 20 m ring of office corridors with a cross corridor, doors of "
        "two colours, the odd board or window, fluorescent rows; 480x360 donut, MPEG-4.",
        "default",
        donut_lens(0.5),
        donut_lens(0.5),
        query_route=RING_QUERY_ROUTE,
    ),
    Family(
        "junctions-rich",
        "tuning",
        "A grid of corridors with T, X and L junctions and dead-end stubs, walls dense with posters, "
        "boards and direction signs, warm, cool and neutral lamps by wing; a second donut geometry "
        "(640x360, ring off centre, clockwise), JPEG 70.",
        "grid",
        geometries(0.5)["wide"],
        geometries(0.5)["wide"],
        decor=Decor(
            wall_colours=((236, 226, 196), (196, 214, 230), (230, 206, 200), (206, 224, 206)),
            door_colours=((139, 90, 50), (58, 95, 138), (150, 50, 45)),
            glazed_p=0.5,
            board_every_m=3.0,
            signs_every_m=3.0,
        ),
        lighting=Lighting(tints=(WARM, COOL, NEUTRAL, WARM)),
        query_perturb=dataclasses.replace(QUERY, people=4),
        query_jpeg=70,
    ),
    Family(
        "hall-daylight",
        "tuning",
        "An open 16 x 12 m hall glazed along one side between corridor wings, windows on the outer "
        "corridors; modelled at 10:00 and queried at 16:30 (other daylight), more people, mild "
        "lens optics; 640x480 donut.",
        "hall",
        donut_lens(2 / 3),
        donut_lens(2 / 3),
        decor=Decor(wall_h=3.0, board_every_m=6.0),
        lighting=Lighting(tints=(NEUTRAL,), hour=10.0, daylight=0.8),
        query_hour=16.5,
        model_perturb=dataclasses.replace(MODELLING, people=2),
        query_perturb=dataclasses.replace(QUERY, people=6, optics=MILD),
    ),
    Family(
        "twin-wings",
        "tuning",
        "A 24 x 12 m ring whose west and east wings are the same corridor turned half round (walls, "
        "doors, boards and floor), a middle corridor and a stairwell; doors at a steady 4 m, "
        "sparse boards, warm lamps; 640x480 donut. Look-alike places for the confidence to learn.",
        "twin",
        donut_lens(2 / 3),
        donut_lens(2 / 3),
        decor=Decor(alternate_p=1.0, board_every_m=14.0),
        lighting=Lighting(tints=(WARM,)),
    ),
    Family(
        "ring-bare",
        "tuning",
        "The ring of office corridors (48 x 20 m, a cross corridor) with identical doors every 4 m, "
        "bare walls, a board every ~35 m, some stretches dim, the query's light x0.6-1.25; 480x360 "
        "donut. The tuning side's repetitive corridor: what long-bare is, in another building.",
        "default",
        donut_lens(0.5),
        donut_lens(0.5),
        decor=Decor(
            wall_colours=((205, 210, 214),),
            door_colours=((70, 80, 95),),
            alternate_p=1.0,
            door_phase=(1.0, 1.0),
            glazed_p=0.0,
            windows=False,
            board_every_m=35.0,
            plaster=2.5,
            pillar_p=0.05,
        ),
        lighting=Lighting(tints=((1.0, 1.0, 0.97),), dim_p=0.25, dim=0.5),
        query_perturb=dataclasses.replace(QUERY, light=(0.6, 1.25)),
        query_route=RING_QUERY_ROUTE,
    ),
    Family(
        "long-bare",
        "held-out",
        "Two 60 m double-loaded corridors with identical doors every 4 m, bare painted walls, almost "
        "no boards, fluorescent rows with some stretches dark; 480x360 donut.",
        "long",
        donut_lens(0.5),
        donut_lens(0.5),
        decor=Decor(
            wall_colours=((218, 214, 200),),
            door_colours=((120, 85, 55),),
            alternate_p=1.0,
            door_phase=(1.0, 1.0),
            glazed_p=0.0,
            windows=False,
            board_every_m=45.0,
            plaster=2.0,
            pillar_p=0.03,
        ),
        lighting=Lighting(tints=((0.95, 1.0, 1.04),), dim_p=0.3, dim=0.4),
        query_perturb=dataclasses.replace(QUERY, light=(0.5, 1.3)),
    ),
    Family(
        "comb-mixed",
        "held-out",
        "A 59 m spine with six look-alike side corridors (dead ends, two joined) and a stairwell, "
        "carpet, strip lights of mixed colour, some dark stretches, mixed decor; an 800x600-type "
        "lens at 600x450 with real optics, JPEG 25.",
        "comb",
        square_lens(0.75),
        square_lens(0.75),
        decor=Decor(
            wall_colours=((230, 222, 200), (180, 196, 210), (226, 200, 190), (150, 160, 150)),
            door_colours=((139, 90, 50), (58, 95, 138), (90, 90, 95)),
            board_every_m=10.0,
            signs_every_m=12.0,
            tile_m=0.5,
            floor_shades=(95, 120),
            floor_tint=(0.85, 0.9, 1.0),
            grout=False,
            lights="strips",
        ),
        lighting=Lighting(tints=(WARM, COOL, NEUTRAL, COOL), dim_p=0.2, dim=0.45),
        model_jpeg=80,
        query_perturb=dataclasses.replace(QUERY, optics=REAL),
        query_jpeg=25,
    ),
    Family(
        "atrium-glass",
        "held-out",
        "A 26 x 16 m atrium glazed on two sides with a corridor loop off it, 3.6 m ceilings, "
        "terrazzo, downlights; modelled at 11:00, queried at 15:30, many people, the phone held "
        "at 1.0-1.7 m tilted up to 8 deg, real optics; 640x480 donut, JPEG 60.",
        "atrium",
        donut_lens(2 / 3),
        donut_lens(2 / 3),
        decor=Decor(
            wall_colours=((236, 236, 232), (214, 216, 218), (228, 224, 216), (220, 226, 228)),
            door_colours=((170, 190, 200), (110, 112, 118)),
            board_every_m=8.0,
            wall_h=3.6,
            tile_m=1.0,
            floor_shades=(175, 215),
            floor_tint=(1.0, 0.98, 0.95),
            lights="downlights",
            light_spacing=2.0,
        ),
        lighting=Lighting(tints=(NEUTRAL,), hour=11.0, daylight=1.0),
        query_hour=15.5,
        model_perturb=dataclasses.replace(MODELLING, people=3),
        query_perturb=dataclasses.replace(
            QUERY, lateral_m=0.7, height_m=(1.0, 1.7), tilt_deg=8.0, people=6, optics=REAL
        ),
        query_jpeg=60,
    ),
    Family(
        "cross-device",
        "held-out",
        "An irregular loop of 2.0-3.2 m corridors with a cross link, pastel walls by wing and mixed "
        "lamps, modelled with a 360 camera (1024x512 equirectangular) and queried with the 480x360 "
        "donut, JPEG 75.",
        "loop",
        equirect_lens(1024),
        donut_lens(0.5),
        decor=Decor(
            wall_colours=((232, 226, 214), (200, 214, 226), (226, 206, 196), (210, 226, 210)),
            door_colours=((150, 110, 70), (90, 90, 95)),
            board_every_m=8.0,
            tile_m=0.45,
        ),
        lighting=Lighting(tints=(NEUTRAL, WARM, NEUTRAL, COOL)),
        query_jpeg=75,
    ),
]
FAMILIES: dict[str, Family] = {
    f.name: f for split in SPLITS for f in _FAMILIES if f.split == split
}  # ordered: tuning ones first


def pano_width(lens: Lens) -> int:
    """World panorama width that matches the lens's sampling (the ring's outer circumference,
    the 360 camera's width): finer costs time, coarser blurs."""
    if isinstance(lens, Equirectangular):
        return int(lens.image_size[0])
    return int(np.clip(8 * round(2 * np.pi * lens.r_outer / 8), 720, 1440))


def _jpeg(frames: Iterable[np.ndarray], quality: int | None) -> Iterator[np.ndarray]:
    """Frames through a JPEG round trip at `quality` (a phone's cheap encoder; None: as they are)."""
    for f in frames:
        if quality is None:
            yield f
            continue
        ok, buf = cv2.imencode(".jpg", f, [cv2.IMWRITE_JPEG_QUALITY, int(quality)])
        out = cv2.imdecode(buf, cv2.IMREAD_COLOR) if ok else None
        if out is None:
            raise RuntimeError("JPEG round trip failed")
        yield out


def _lens_at(lens: Lens, scale: float) -> Lens:
    if scale == 1.0:
        return lens
    if isinstance(lens, Equirectangular):
        w = 2 * int(round(lens.image_size[0] * scale / 2))
        return equirect_lens(w)
    return resized(lens, scale)


def _cut(route: list[Point], length_m: float) -> list[Point]:
    """The first `length_m` metres of a route."""
    out = [route[0]]
    left = length_m
    for a, b in zip(route[:-1], route[1:], strict=True):
        d = float(np.hypot(b[0] - a[0], b[1] - a[1]))
        if d >= left:
            f = left / d
            out.append((a[0] + f * (b[0] - a[0]), a[1] + f * (b[1] - a[1])))
            return out
        out.append(b)
        left -= d
    return out


@dataclass
class FamilyVenue:
    """A family's venue for a seed, before anything is rendered: its scenes and walks."""

    family: Family
    scene: Scene  # as the modelling walk sees it
    query_scene: Scene  # the same building as the query walk sees it (another hour's daylight)
    model_walk_path: dict[str, Any]
    query_walk_path: dict[str, Any]


def family_venue(family: str, seed: int, fps: float = 10.0, route_m: float | None = None) -> FamilyVenue:
    """Build a family's venue and its two walks (`route_m`: only each route's first metres)."""
    if family not in FAMILIES:
        raise ValueError(f"unknown family {family!r} (known: {', '.join(FAMILIES)})")
    fam = FAMILIES[family]
    scene = build_scene(seed, fam.layout, fam.decor, fam.lighting)
    qscene = scene
    if fam.query_hour is not None and fam.lighting is not None:  # the same building, other daylight
        qscene = build_scene(seed, fam.layout, fam.decor, dataclasses.replace(fam.lighting, hour=fam.query_hour))
    m_route, q_route = default_routes(scene)  # the layout's own (scene.routes), or the ring's
    if fam.query_route is not None:
        q_route = list(fam.query_route)
    if route_m is not None:
        m_route, q_route = _cut(m_route, route_m), _cut(q_route, route_m)
    rng = np.random.default_rng(seed + 1000)
    q_route = offset_route(scene, q_route, fam.query_perturb.lateral_m, rng)
    m_path = walk_path_for(m_route, [fam.model_speed], fps)
    q_path = walk_path_for(q_route, list(fam.query_speeds), fps)
    return FamilyVenue(fam, scene, qscene, m_path, q_path)


def make_family_dataset(
    root: Path, family: str, seed: int, fps: float = 10.0, scale: float = 1.0, route_m: float | None = None
) -> Dataset:
    """Render one venue of a family: a modelling walk over every corridor and an independent query
    walk (the other way round, off the centre line), with walk paths, lens files and a floor plan:
    the files `synth.make_dataset` writes, and `family.json` saying which venue it is.

    For quick tests: `scale` shrinks both videos' image size, `route_m` walks only the first
    metres of each route (the venue is the same)."""
    v = family_venue(family, seed, fps, route_m)
    fam, scene, qscene, m_path, q_path = v.family, v.scene, v.query_scene, v.model_walk_path, v.query_walk_path
    mlens, qlens = _lens_at(fam.model_lens, scale), _lens_at(fam.query_lens, scale)
    ds = dataset_files(root, scene, m_path, q_path, qlens, mlens)
    (root / "family.json").write_text(
        json.dumps({"family": fam.name, "split": fam.split, "seed": seed, "describe": fam.describe}, indent=1)
    )
    for video, walk_path, sc, lens, perturb, jpeg, s in (
        (ds.model_video, m_path, scene, mlens, fam.model_perturb, fam.model_jpeg, seed + 1),
        (ds.query_video, q_path, qscene, qlens, fam.query_perturb, fam.query_jpeg, seed + 3),
    ):
        poses = poses_from_walk_path(walk_path, perturb, np.random.default_rng(s))
        frames = (f for _, f in render_frames(sc, lens, poses, perturb, s + 1, pano_width(lens)))
        write_video(video, _jpeg(frames, jpeg), fps, lens.image_size)
    return ds
