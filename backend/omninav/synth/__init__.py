"""The synthetic venue renderer: deterministic venues, walks and videos for tests and the demo."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from ..lens import Catadioptric, Equirectangular, Lens
from .layouts import Point
from .scene import Scene, build_scene, floorplan_image
from .walks import (
    MODELLING,
    QUERY,
    Perturb,
    default_routes,
    offset_route,
    poses_from_walk_path,
    render_frames,
    walk_path_for,
    write_json,
    write_video,
)

__all__ = [
    "Scene",
    "build_scene",
    "donut_lens",
    "equirect_lens",
    "make_dataset",
    "Dataset",
    "MODELLING",
    "QUERY",
    "Perturb",
]


def donut_lens(scale: float = 1.0) -> Catadioptric:
    """The synthetic clip-on donut lens: 960x720 (at scale 1), ring 105-340 px, -45..+35 deg."""
    r_in, r_out = 105.0 * scale, 340.0 * scale
    # el(r) quadratic through (r_in, -45), (mid, -8), (r_out, 35): mildly non-linear like real mirrors
    rm = 0.5 * (r_in + r_out)
    c2, c1, c0 = np.polyfit([r_in, rm, r_out], [-45.0, -8.0, 35.0], 2)
    return Catadioptric(
        image_size=(int(round(960 * scale)), int(round(720 * scale))),
        center=(487.0 * scale, 352.0 * scale),
        r_inner=r_in,
        r_outer=r_out,
        elevation_poly=(float(c0), float(c1), float(c2)),
        forward_deg=90.0,
        ccw=True,
    )


def equirect_lens(width: int = 1440) -> Equirectangular:
    return Equirectangular(image_size=(width, width // 2), forward_x=width / 2, ccw=False)


@dataclass
class Dataset:
    root: Path
    model_video: Path
    model_walk_path: Path
    query_video: Path
    query_walk_path: Path
    lens: Path
    floorplan: Path
    px_per_m: float
    scene: Scene


OLD_NAMES = {
    "model_track.json": "model_walk_path.json",
    "query_track.json": "query_walk_path.json",
    "stops_track.json": "stops_walk_path.json",  # bench/tracking.py's walk with stops
    "track30.json": "walk_path30.json",  # bench/model_speed.py's and bench/suggest_speed.py's
}


def upgrade_names(root: Path) -> Path:
    """A dataset rendered before the walk path's files had that name, its files renamed in place.

    Renders are cached for days (the demo's, the benchmarks'); renaming is cheaper than rendering
    again. Kept for one release, like the other old names (docs/decisions.md). Returns `root`.
    """
    for old, new in OLD_NAMES.items():
        if (root / old).exists() and not (root / new).exists():
            (root / old).rename(root / new)
    return root


def dataset_files(
    root: Path,
    scene: Scene,
    model_walk_path: dict[str, Any],
    query_walk_path: dict[str, Any],
    query_lens: Lens,
    model_lens: Lens,
    px_per_m: float = 20.0,
) -> Dataset:
    """Everything of a rendered dataset but its two videos: the walk paths, both lens profiles
    (lens.json is the query's) and the floor plan. Returns the Dataset naming all its files."""
    root.mkdir(parents=True, exist_ok=True)
    ds = Dataset(
        root,
        root / "model.mp4",
        root / "model_walk_path.json",
        root / "query.mp4",
        root / "query_walk_path.json",
        root / "lens.json",
        root / "floorplan.png",
        px_per_m,
        scene,
    )
    write_json(ds.model_walk_path, model_walk_path)
    write_json(ds.query_walk_path, query_walk_path)
    write_json(ds.lens, query_lens.to_dict())
    write_json(root / "model_lens.json", model_lens.to_dict())
    cv2.imwrite(str(ds.floorplan), cv2.cvtColor(floorplan_image(scene, px_per_m), cv2.COLOR_RGB2BGR))
    return ds


def make_dataset(
    root: Path,
    seed: int = 0,
    layout: str = "default",
    fps: float = 10.0,
    scale: float = 1.0,
    model_lens: Lens | None = None,
    query_lens: Lens | None = None,
    query_perturb: Perturb = QUERY,
    query_route: list[Point] | None = None,
    model_speed: float = 1.2,
    query_speeds: tuple[float, ...] = (1.0, 1.3, 1.1, 0.9),
) -> Dataset:
    """Render a venue's modelling walk and an independent query walk, with walk paths and lens files.

    The modelling video is taken with `model_lens`, the query with `query_lens` (both default to
    the synthetic donut at `scale`).
    """
    root.mkdir(parents=True, exist_ok=True)
    scene = build_scene(seed, layout)
    rng = np.random.default_rng(seed + 1000)
    lens = query_lens or donut_lens(scale)
    mlens = model_lens or lens
    m_route, q_route = default_routes(scene)
    if query_route is not None:
        q_route = query_route
    q_route = offset_route(scene, q_route, query_perturb.lateral_m, rng)
    m_path = walk_path_for(m_route, [model_speed], fps)
    q_path = walk_path_for(q_route, list(query_speeds), fps)
    ds = dataset_files(root, scene, m_path, q_path, lens, mlens)
    mposes = poses_from_walk_path(m_path, MODELLING, np.random.default_rng(seed + 1))
    write_video(
        ds.model_video, (f for _, f in render_frames(scene, mlens, mposes, MODELLING, seed + 2)), fps, mlens.image_size
    )
    qposes = poses_from_walk_path(q_path, query_perturb, np.random.default_rng(seed + 3))
    write_video(
        ds.query_video,
        (f for _, f in render_frames(scene, lens, qposes, query_perturb, seed + 4)),
        fps,
        lens.image_size,
    )
    return ds
