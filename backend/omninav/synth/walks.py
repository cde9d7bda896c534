"""Walks through a synthetic venue: poses, perturbations, walk paths and rendered videos.

A modelling walk follows the corridor centre lines at a steady pace with the lens forward along
the direction of travel, as a person recording a venue does. A query walk is recorded as a user
would: off the centre line by up to 0.5 m, the phone at 1.15-1.55 m and tilted up to 5 degrees,
light x0.6-1.3 with a colour cast, up to three passers-by, the lens re-clipped 2 px off centre,
sensor noise and video compression. Its walk path (docs/formats.md) is the ground truth.
"""

from __future__ import annotations

import json
from collections.abc import Iterable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import cv2
import numpy as np

from ..lens import Lens
from .layouts import Point
from .optics import Optics, OpticsSim
from .render import CameraModel, PanoGrid, camera_frame, tilt_rotation, world_panorama
from .scene import GRID, Person, Scene, random_people

if TYPE_CHECKING:
    from ..walk_path import WalkPath


@dataclass(frozen=True)
class Perturb:
    lateral_m: float = 0.0
    height_m: tuple[float, float] = (1.35, 1.35)
    tilt_deg: float = 0.0
    light: tuple[float, float] = (1.0, 1.0)
    cast: float = 0.0  # per-channel gain spread
    people: int = 0
    lens_shift_px: float = 0.0
    noise: float = 1.0  # sensor noise sigma, grey levels
    sway_deg: float = 0.0  # the yaw swinging +- this at 0.9 Hz (once a stride), walking or standing
    optics: Optics | None = None  # a real lens and phone (synth/optics.py); None: the ideal lens


MODELLING = Perturb(noise=1.5)
QUERY = Perturb(
    lateral_m=0.5,
    height_m=(1.15, 1.55),
    tilt_deg=5.0,
    light=(0.6, 1.3),
    cast=0.12,
    people=3,
    lens_shift_px=2.0,
    noise=3.0,
)


@dataclass
class Pose:
    t: float
    x: float
    y: float
    heading: float
    cam_h: float = 1.35
    tilt: float = 0.0
    tilt_dir: float = 0.0


def route_through(scene: Scene, order: list[int], reverse: list[bool] | None = None) -> list[tuple[float, float]]:
    """A route that walks the given centre lines in order (each possibly reversed)."""
    pts: list[tuple[float, float]] = []
    for i, li in enumerate(order):
        line = list(scene.centerlines[li])
        if reverse and reverse[i]:
            line = line[::-1]
        for p in line:
            if not pts or np.hypot(p[0] - pts[-1][0], p[1] - pts[-1][1]) > 1e-6:
                pts.append(p)
    return pts


def default_routes(scene: Scene) -> tuple[list[Point], list[Point]]:
    """(modelling route, query route) for a built-in layout; the query walks the other way round."""
    if scene.routes is not None:  # the layout's own (scene.py: twin)
        return scene.routes
    n = len(scene.centerlines)
    if n == 5:  # the default ring + middle corridor
        a, b, c, d, m = (3.0, 3.0), (51.0, 3.0), (51.0, 23.0), (3.0, 23.0), (27.0, 3.0)
        model = [a, m, b, c, (27.0, 23.0), d, a, m, (27.0, 23.0)]
        query = [(27.0, 23.0), c, b, m, (27.0, 23.0), d, a, m]
        return model, query
    line = route_through(scene, list(range(n)))
    return line, line[::-1]


def _is_free(scene: Scene, x: float, y: float) -> bool:
    r, c = int(y / GRID), int(x / GRID)
    return 0 <= r < scene.free.shape[0] and 0 <= c < scene.free.shape[1] and bool(scene.free[r, c])


def offset_route(
    scene: Scene, route: list[Point], lateral_m: float, rng: np.random.Generator, step_m: float = 6.0
) -> list[tuple[float, float]]:
    """Resample a route every ~step_m and push each point sideways by up to lateral_m."""
    out: list[tuple[float, float]] = []
    for (ax, ay), (bx, by) in zip(route[:-1], route[1:], strict=True):
        seg = np.hypot(bx - ax, by - ay)
        n = max(1, int(round(seg / step_m)))
        nx, ny = -(by - ay) / seg, (bx - ax) / seg
        for k in range(n):
            f = k / n
            o = rng.uniform(-lateral_m, lateral_m) if k > 0 else 0.0
            px, py = ax + f * (bx - ax) + o * nx, ay + f * (by - ay) + o * ny
            if _is_free(scene, px, py):
                out.append((px, py))
    out.append(route[-1])
    return out


def walk_path_for(
    route: list[Point],
    speeds: list[float],
    fps: float,
    heading_offset: float = 0.0,
    stops: dict[int, float] | None = None,
) -> dict[str, Any]:
    """A walk path (docs/formats.md): a waypoint (t in seconds) at every route vertex.

    `stops` maps a route vertex index to seconds stood still there: the vertex is repeated at the
    later time, which the walk path's linear interpolation reads as standing still.
    """
    stops = stops or {}
    t = 0.0
    wps = [{"t": 0.0, "x": round(route[0][0], 4), "y": round(route[0][1], 4)}]

    def stand(i: int) -> None:
        nonlocal t
        if stops.get(i, 0.0) > 0:
            t += stops[i]
            wps.append({"t": round(t, 4), "x": round(route[i][0], 4), "y": round(route[i][1], 4)})

    stand(0)
    for i, ((ax, ay), (bx, by)) in enumerate(zip(route[:-1], route[1:], strict=True)):
        t += np.hypot(bx - ax, by - ay) / speeds[i % len(speeds)]
        wps.append({"t": round(t, 4), "x": round(bx, 4), "y": round(by, 4)})
        stand(i + 1)
    return {"fps": fps, "waypoints": wps, "heading_offset_deg": heading_offset}


def walk_events(
    walk_path: dict[str, Any], min_turn_deg: float = 30.0
) -> tuple[list[tuple[float, float]], list[tuple[float, float]]]:
    """The ground truth of a synthetic walk: (turns [(t, signed deg, + clockwise)], stops [(t, s)]).

    A turn is a waypoint where the leg heading changes by at least `min_turn_deg` (after a stop,
    at the end of the stop, where the walker sets off the new way); a stop is a waypoint repeated.
    """
    from ..walk_path import parse_walk_path

    tr = parse_walk_path(walk_path)
    legs = np.unwrap(tr.leg_headings(), period=360.0)
    turns = [
        (float(tr.times[i + 1]), float(legs[i + 1] - legs[i]))
        for i in range(len(legs) - 1)
        if abs(legs[i + 1] - legs[i]) >= min_turn_deg
    ]
    d = np.hypot(*np.diff(tr.xy, axis=0).T)
    stops = [(float(tr.times[i]), float(tr.times[i + 1] - tr.times[i])) for i in np.flatnonzero(d <= 1e-6)]
    return turns, stops


def walk_heading(tr: WalkPath, ts: np.ndarray, turn_s: float = 0.0) -> np.ndarray:
    """The walker's heading at times `ts` (degrees clockwise from plan up, before the walk path's
    heading offset and any sway): the direction of the leg, turning at once at a waypoint or,
    with `turn_s` > 0, steadily over `turn_s` seconds centred on it (then unwrapped). One
    function for the rendered heading (poses_from_walk_path) and the gyroscope's truth (imu_for),
    so that the two cannot drift apart."""
    legs = tr.leg_headings()
    if turn_s > 0 and len(legs) > 1:
        legs = np.unwrap(legs, period=360.0)
        # the heading ramps from one leg's to the next over turn_s around each inner waypoint
        kt, kh = [tr.times[0]], [legs[0]]
        for i in range(1, len(legs)):
            if legs[i] != legs[i - 1]:
                half = min(turn_s / 2, (tr.times[i] - tr.times[i - 1]) / 2, (tr.times[i + 1] - tr.times[i]) / 2)
                kt += [tr.times[i] - half, tr.times[i] + half]
                kh += [legs[i - 1], legs[i]]
        kt.append(tr.times[-1])
        kh.append(legs[-1])
        return np.asarray(np.interp(ts, kt, kh))
    leg = np.clip(np.searchsorted(tr.times, ts, side="right") - 1, 0, len(legs) - 1)
    return np.asarray(legs[leg])


def poses_from_walk_path(
    walk_path: dict[str, Any], perturb: Perturb, rng: np.random.Generator, turn_s: float = 0.0
) -> list[Pose]:
    """One pose per video frame, exactly where the walk path says (its ground truth).

    The heading is the direction of the leg plus the walk path's heading offset, turning at once at a
    waypoint (as docs/formats.md has it) or, with `turn_s` > 0, turning steadily over `turn_s`
    seconds centred on the waypoint, as a person walks round a corner. A stop (a waypoint repeated
    at a later time) keeps the heading it arrived with.
    """
    from ..walk_path import parse_walk_path

    tr = parse_walk_path(walk_path)
    n = int(np.floor(tr.times[-1] * tr.fps)) + 1
    ts = np.arange(n) / tr.fps
    xy, _, ok = tr.pose_at(ts)
    hd = walk_heading(tr, ts, turn_s)
    if perturb.sway_deg:
        hd = hd + perturb.sway_deg * np.sin(2 * np.pi * 0.9 * ts)
    hd = np.mod(hd + tr.heading_offset, 360.0)
    h0 = rng.uniform(*perturb.height_m)
    # slowly varying tilt: a smoothed random walk within +-tilt_deg
    tilt = np.zeros(n)
    tdir = np.zeros(n)
    if perturb.tilt_deg > 0:
        k = max(1, int(tr.fps))
        raw = rng.uniform(0, perturb.tilt_deg, n // k + 2)
        dirs = rng.uniform(0, 360, n // k + 2)
        tilt = np.interp(np.arange(n) / k, np.arange(len(raw)), raw)
        tdir = np.interp(np.arange(n) / k, np.arange(len(dirs)), np.unwrap(dirs, period=360))
    return [
        Pose(
            float(ts[i]),
            float(xy[i, 0]),
            float(xy[i, 1]),
            float(hd[i]),
            h0 + 0.01 * np.sin(ts[i] * 2 * np.pi * 1.8),
            float(tilt[i]),
            float(tdir[i]),
        )
        for i in range(n)
        if ok[i]
    ]


def grid_for(lens: Lens, width: int = 1440) -> PanoGrid:
    lo, hi = lens.elevation_range()
    top, bottom = min(89.0, hi + 8.0), max(-89.0, lo - 8.0)
    step = 360.0 / width
    return PanoGrid(width, top, bottom, int(round((top - bottom) / step)) + 1)


def render_frames(
    scene: Scene, lens: Lens, poses: list[Pose], perturb: Perturb, seed: int, pano_width: int = 1440
) -> Iterator[tuple[Pose, np.ndarray]]:
    """Yield (pose, BGR uint8 frame) for each pose, with the perturbations applied."""
    rng = np.random.default_rng(seed)
    grid = grid_for(lens, pano_width)
    ang = rng.uniform(0, 2 * np.pi)
    cam = CameraModel.create(lens, (perturb.lens_shift_px * np.cos(ang), perturb.lens_shift_px * np.sin(ang)))
    gain = rng.uniform(*perturb.light)
    cast = 1.0 + rng.uniform(-perturb.cast, perturb.cast, 3)
    people: list[Person] = []
    vel: list[tuple[float, float]] = []
    # its own generator: a walk without optics draws exactly what it drew before
    sim = OpticsSim(lens, perturb.optics, np.random.default_rng(seed + 7)) if perturb.optics is not None else None
    for i, p in enumerate(poses):
        if perturb.people and i % 20 == 0:
            people = random_people(scene, rng, (p.x, p.y), int(rng.integers(0, perturb.people + 1)))
            vel = [(rng.uniform(-1, 1), rng.uniform(-1, 1)) for _ in people]
        elif people:
            dt = poses[i].t - poses[i - 1].t
            for j, q in enumerate(people):
                q.x += vel[j][0] * dt
                q.y += vel[j][1] * dt
        pano = world_panorama(scene, p.x, p.y, p.cam_h, grid, people)
        rot = tilt_rotation(p.tilt, p.tilt_dir) if p.tilt else None
        rgb = camera_frame(cam, pano, grid, p.heading, rot).astype(np.float32)
        rgb *= (gain * cast)[None, None, :]
        if sim is not None:
            rgb = sim(rgb)
        if perturb.noise:
            rgb += rng.normal(0.0, perturb.noise, rgb.shape).astype(np.float32)
        frame = np.clip(rgb, 0, 255).astype(np.uint8)
        yield p, cv2.cvtColor(frame, cv2.COLOR_RGB2BGR)


def write_video(path: Path, frames: Iterable[np.ndarray], fps: float, size: tuple[int, int]) -> int:
    """Encode frames (BGR) to an MP4 (MPEG-4 part 2) or, for .avi, Motion-JPEG; returns count."""
    fourcc = cv2.VideoWriter.fourcc(*("MJPG" if path.suffix.lower() == ".avi" else "mp4v"))
    vw = cv2.VideoWriter(str(path), fourcc, fps, size)
    if not vw.isOpened():
        raise RuntimeError(f"cannot open a video writer for {path}")
    n = 0
    try:
        for f in frames:
            vw.write(f)
            n += 1
    finally:
        vw.release()
    return n


def render_walk(
    path: Path,
    scene: Scene,
    lens: Lens,
    walk_path: dict[str, Any],
    perturb: Perturb = MODELLING,
    seed: int = 0,
    turn_s: float = 0.0,
    pano_width: int = 1440,
) -> int:
    """Render the walk `walk_path` describes (its corners turned over `turn_s`) into a video at the
    walk path's fps; returns the number of frames. A smaller `pano_width` renders faster, coarser."""
    poses = poses_from_walk_path(walk_path, perturb, np.random.default_rng(seed), turn_s=turn_s)
    frames = (f for _, f in render_frames(scene, lens, poses, perturb, seed + 1, pano_width))
    return write_video(path, frames, float(walk_path["fps"]), lens.image_size)


def write_json(path: Path, obj: dict[str, Any]) -> None:
    path.write_text(json.dumps(obj, indent=1))


def imu_for(
    walk_path: dict[str, Any],
    rng: np.random.Generator,
    step_m: tuple[float, float] = (0.62, 0.78),
    miss_p: float = 0.05,
    extra_p: float = 0.03,
    gyro_bias_dps: float = 0.3,
    gyro_walk_dps: float = 0.2,
    gyro_noise_deg: float = 0.5,
    rate_hz: float = 20.0,
    turn_s: float = 0.0,
) -> dict[str, Any]:
    """The phone's own motion on a walk (imu.json, docs/formats.md), as a phone would measure it.

    Steps: the walker's step length is drawn once from `step_m` and varies +-8 % a step; a step is
    detected when walked, missed with `miss_p`, and a false one is added with `extra_p` (standing
    still: none, but the odd false one at the same rate per second). Yaw: the true heading's change
    since the start (the walk's corners, turned over `turn_s` like poses_from_walk_path), plus a
    constant gyroscope bias, a random walk and white noise.
    """
    from ..walk_path import parse_walk_path

    tr = parse_walk_path(walk_path)
    length = rng.uniform(*step_m)
    t_end = float(tr.times[-1])
    # distance walked along the walk path, finely sampled in time
    ts = np.arange(0.0, t_end + 1e-9, 0.02)
    xy, _, _ = tr.pose_at(ts)
    s = np.r_[0.0, np.cumsum(np.hypot(*np.diff(xy, axis=0).T))]
    steps: list[float] = []
    at = length * rng.uniform(0.5, 1.0)
    while at < s[-1]:
        t = float(np.interp(at, s, ts))
        if rng.random() >= miss_p:
            steps.append(t)
        at += length * rng.uniform(0.92, 1.08)
    n_extra = rng.poisson(extra_p * max(len(steps), t_end))
    steps = sorted(steps + list(rng.uniform(0.0, t_end, n_extra)))
    # yaw: the true heading, unwrapped, from the start
    yt = np.arange(0.0, t_end + 1e-9, 1.0 / rate_hz)
    true = np.unwrap(walk_heading(tr, yt, turn_s), period=360.0)  # what the renderer shows
    bias = rng.uniform(-gyro_bias_dps, gyro_bias_dps)
    walk = np.cumsum(rng.normal(0.0, gyro_walk_dps / np.sqrt(rate_hz), len(yt)))
    yaw = true - true[0] + bias * yt + walk + rng.normal(0.0, gyro_noise_deg, len(yt))
    return {
        "steps": [round(float(t), 3) for t in steps],
        "yaw": {"t": [round(float(t), 3) for t in yt], "deg": [round(float(d), 2) for d in yaw]},
    }


def with_stops(
    walk_path: dict[str, Any], rng: np.random.Generator, n: int = 3, stop_s: tuple[float, float] = (3.0, 8.0)
) -> dict[str, Any]:
    """The same walk standing still `n` times (drawn from `stop_s` seconds each) at interior
    waypoints spread along it (a person waiting, reading a sign, talking): every later waypoint
    moves by the time stood. The heading while standing is the one arrived with (walk_path.py)."""
    wps = [dict(w) for w in walk_path["waypoints"]]
    inner = np.arange(1, len(wps) - 1)
    if n <= 0 or len(inner) == 0:
        return {**walk_path, "waypoints": wps}
    at = sorted(int(i) for i in rng.choice(inner, size=min(n, len(inner)), replace=False))
    out: list[dict[str, Any]] = []
    shift = 0.0
    for i, w in enumerate(wps):
        t = float(w["t"]) + shift
        out.append({**w, "t": round(t, 4)})
        if i in at:
            s = float(rng.uniform(*stop_s))
            shift += s
            out.append({**w, "t": round(t + s, 4)})
    return {**walk_path, "waypoints": out}
