"""Calibration videos: a printed board moved around a donut lens, rendered exactly through it.

Every pixel of the ring looks along `pixel_to_direction` of the lens (x forward, y right, z up in
the lens frame, as `render.CameraModel`); the ray meets the board's plane, and the board's printed
picture is sampled there with anti-aliasing (2x2 supersamples, each from the mip level that
matches its footprint). The true pixel of every corner is `direction_to_pixel` of its direction,
so a detector and a fit are checked against the lens that made the pictures. Nothing is stored:
tests render what they need, seeded.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import cv2
import numpy as np

from ..calib.board import BoardSpec, board_image
from ..lens import Catadioptric, direction_to_pixel, pixel_to_direction
from . import donut_lens
from .walks import write_video


def _poly_over_ring(
    r_in: float, r_out: float, e_in: float, e_out: float, shape: tuple[float, ...]
) -> tuple[float, ...]:
    """Elevation polynomial in r (ascending powers) of e_in + (e_out - e_in) * shape(t), t = (r -
    r_in) / (r_out - r_in); `shape` ascending powers of t with shape(0) = 0, shape(1) = 1."""
    p = np.polynomial.Polynomial(shape) * (e_out - e_in) + e_in
    t = np.polynomial.Polynomial([-r_in / (r_out - r_in), 1.0 / (r_out - r_in)])
    return tuple(float(c) for c in p(t).coef)


# Lens geometries the calibration is tested on: centres off the image centre, radii, quadratic
# and quartic elevation polynomials, three image sizes, both senses of rotation, forward varied.
LENS_GEOMETRIES: dict[str, Catadioptric] = {
    "donut960": donut_lens(1.0),  # 960x720, quadratic -45..+35, ccw, forward 90
    "wide1280": Catadioptric(
        image_size=(1280, 960),
        center=(612.0, 503.0),
        r_inner=120.0,
        r_outer=450.0,
        elevation_poly=_poly_over_ring(120.0, 450.0, -60.0, 15.0, (0.0, 0.6, 0.7, -0.5, 0.2)),  # quartic
        forward_deg=-30.0,
        ccw=False,
    ),
    "hd1920": Catadioptric(
        image_size=(1920, 1080),
        center=(1003.0, 517.0),
        r_inner=150.0,
        r_outer=495.0,
        elevation_poly=_poly_over_ring(150.0, 495.0, -25.0, 50.0, (0.0, 1.25, -0.25)),  # quadratic
        forward_deg=200.0,
        ccw=True,
    ),
    "small960": Catadioptric(
        image_size=(960, 720),
        center=(452.0, 383.0),
        r_inner=85.0,
        r_outer=320.0,
        elevation_poly=_poly_over_ring(85.0, 320.0, -50.0, 30.0, (0.0, 1.4, -0.9, 0.8, -0.3)),  # quartic
        forward_deg=135.0,
        ccw=False,
    ),
}


def fisheye_lens() -> Catadioptric:
    """A fisheye looking down its axis, kept out of LENS_GEOMETRIES (the lens fit's held-out
    case): no dark centre, -90 deg at the centre to +15 at the edge, a cubic between."""
    el = np.polynomial.polynomial.polyfit([0, 120, 240, 340], [-90, -55, -18, 15], 3)
    return Catadioptric(
        image_size=(960, 720),
        center=(478.0, 362.0),
        r_inner=0.0,
        r_outer=340.0,
        elevation_poly=tuple(float(c) for c in el),
        forward_deg=90.0,
        ccw=True,
    )


@dataclass
class CalibSet:
    """A rendered calibration video and its truth.

    `poses[i] = (R, t)`: board point X (board coordinates, `spec.object_points()`) lies at
    `R @ X + t` in the lens frame (metres; x forward, y right, z up - the render's camera frame);
    `truth[i]`: (N, 2) float64 true pixel of every corner (NaN where the corner is off the ring,
    off the image or on the board's back).
    """

    lens: Catadioptric
    spec: BoardSpec
    frames: list[np.ndarray]  # (H, W, 3) uint8 BGR
    poses: list[tuple[np.ndarray, np.ndarray]]
    truth: list[np.ndarray]
    board_dirs: list[tuple[float, float, float]] = field(default_factory=list)  # (az, el, distance) of the centre

    def whole(self, i: int) -> bool:
        """Every corner of frame i lies on the ring (the board is wholly seen)."""
        return bool(np.isfinite(self.truth[i]).all())


@dataclass
class _Rays:
    """Per-pixel lens-frame rays of the ring (pixel centres), computed once per lens."""

    index: np.ndarray  # (M,) flat pixel index
    vec: np.ndarray  # (M, 3) unit rays
    background: np.ndarray  # (M,) float32 grey the room shows there
    mask: np.ndarray  # (H, W) bool: the ring


def _unit(az_deg: np.ndarray, el_deg: np.ndarray) -> np.ndarray:
    a, e = np.deg2rad(az_deg), np.deg2rad(el_deg)
    return np.stack([np.cos(e) * np.cos(a), np.cos(e) * np.sin(a), np.sin(e)], -1)


def _room(az: np.ndarray, el: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """A plain room around the lens: floor darker than the ceiling, a few posters and doors (edges
    that are no board), so that a detector has something to be wrong about."""
    g = 120.0 + 0.9 * el + 12.0 * np.sin(np.deg2rad(az) * 2.0 + 0.7)
    for _ in range(14):
        a0, w = rng.uniform(0, 360), rng.uniform(8, 40)
        e0, h = rng.uniform(-30, 25), rng.uniform(6, 30)
        da = np.mod(az - a0, 360.0)
        inside = (da < w) & (el > e0) & (el < e0 + h)
        g = np.where(inside, rng.uniform(40, 220), g)
    out: np.ndarray = np.clip(g, 10, 245).astype(np.float32)
    return out


def _ring_rays(lens: Catadioptric, rng: np.random.Generator) -> _Rays:
    w, h = lens.image_size
    ys, xs = np.mgrid[0:h, 0:w]
    az, el = pixel_to_direction(lens, xs.ravel().astype(np.float64), ys.ravel().astype(np.float64))
    ok = np.isfinite(el)
    return _Rays(np.flatnonzero(ok), _unit(az[ok], el[ok]), _room(az[ok], el[ok], rng), ok.reshape(h, w))


def _rot(axis: np.ndarray, deg: float) -> np.ndarray:
    r: np.ndarray = cv2.Rodrigues(np.asarray(axis, np.float64) * math.radians(deg))[0]
    return r


def board_pose(
    spec: BoardSpec, az: float, el: float, dist: float, tilt_u: float, tilt_v: float, roll: float
) -> tuple[np.ndarray, np.ndarray]:
    """(R, t) of a board whose centre is `dist` m away at (azimuth, elevation), facing the lens
    upright (its columns to the viewer's right, rows down) then tilted about its own axes (deg)."""
    a, e = math.radians(az), math.radians(el)
    d = _unit(np.array(az), np.array(el))
    right = np.array([-math.sin(a), math.cos(a), 0.0])
    down = np.array([math.sin(e) * math.cos(a), math.sin(e) * math.sin(a), -math.cos(e)])
    # The lens frame (forward, right, up) is left-handed, so cross(u, v) points *towards* the
    # viewer: the board's printed side faces the lens when R[:, 2] . t < 0.
    upright = np.stack([right, down, np.cross(right, down)], 1)
    local = _rot(np.array([0.0, 0.0, 1.0]), roll) @ _rot(np.array([1.0, 0.0, 0.0]), tilt_u)
    local = _rot(np.array([0.0, 1.0, 0.0]), tilt_v) @ local
    rmat = upright @ local
    u0, v0, u1, v1 = spec.outline()
    centre = np.array([(u0 + u1) / 2, (v0 + v1) / 2, 0.0])
    t = d * dist - rmat @ centre
    return rmat, t


def corner_truth(lens: Catadioptric, spec: BoardSpec, rmat: np.ndarray, t: np.ndarray) -> np.ndarray:
    """(N, 2) true pixels of the board's corners (NaN: off the ring or image, or seen from behind)."""
    x = spec.object_points() @ rmat.T + t
    az = np.rad2deg(np.arctan2(x[:, 1], x[:, 0]))
    el = np.rad2deg(np.arcsin(np.clip(x[:, 2] / np.linalg.norm(x, axis=1), -1, 1)))
    px, py = direction_to_pixel(lens, az, el)
    w, h = lens.image_size
    seen = (px >= 0) & (px <= w - 1) & (py >= 0) & (py <= h - 1) & (float(rmat[:, 2] @ t) < 0)
    return np.where(seen[:, None], np.stack([px, py], -1), np.nan)


class _Texture:
    """The printed board as a mip pyramid (float32), board metres -> level-0 texels."""

    def __init__(self, spec: BoardSpec, px_per_square: int = 96):
        img, off = board_image(spec, px_per_square, margin_squares=0.75)
        self.scale = px_per_square / spec.square_m
        self.offset = off
        self.levels: list[np.ndarray] = [img.astype(np.float32)]
        while min(self.levels[-1].shape) > 32 and len(self.levels) < 6:
            self.levels.append(np.asarray(cv2.pyrDown(self.levels[-1]), np.float32))

    def sample(self, tx: np.ndarray, ty: np.ndarray, level: np.ndarray) -> np.ndarray:
        """Bilinear samples at level-0 texel coordinates; -1 outside the paper. pyrDown keeps
        level-L texel i at level-0 texel 2^L i, so coordinates scale exactly by 2^-L."""
        out = np.full(tx.shape, -1.0, np.float32)
        for lv in np.unique(level):
            m = level == lv
            f = 0.5**lv
            n = int(m.sum())
            pad = (-n) % 4096  # remap wants maps under 32767 wide: fold them into rows of 4096
            mx = np.concatenate([tx[m] * f, np.zeros(pad)]).astype(np.float32).reshape(-1, 4096)
            my = np.concatenate([ty[m] * f, np.zeros(pad)]).astype(np.float32).reshape(-1, 4096)
            s = cv2.remap(self.levels[lv], mx, my, cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT, borderValue=-1.0)
            out[m] = s.ravel()[:n]
        return out


def _hits(rays: np.ndarray, rmat: np.ndarray, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Board coordinates (u, v) in metres where each ray meets the board's plane; ok: in front."""
    n = rmat[:, 2]
    den = rays @ n
    with np.errstate(divide="ignore", invalid="ignore"):
        s = float(n @ t) / den
    ok = np.isfinite(s) & (s > 0)
    p = rays * np.where(ok, s, 0.0)[:, None] - t
    uv = p @ rmat[:, :2]
    return uv[:, 0], uv[:, 1], ok


def render_board(
    lens: Catadioptric,
    tex: _Texture,
    spec: BoardSpec,
    rays: _Rays,
    rmat: np.ndarray,
    t: np.ndarray,
    paper: tuple[float, float],
) -> np.ndarray:
    """(H, W) float32 grey frame: the room, and the board where the rays meet its paper; `paper`
    (black, white) grey levels of the print under this frame's light."""
    w, h = lens.image_size
    out = np.zeros(h * w, np.float32)
    out[rays.index] = rays.background
    u0, v0, u1, v1 = spec.outline()
    mg = 0.75 * spec.square_m + 0.02  # paper margin + a safety band for the supersamples
    # only rays in a cone around the board need the plane: the full ring costs 20 ms a frame
    corners = np.array([[u0 - mg, v0 - mg, 0], [u1 + mg, v0 - mg, 0], [u0 - mg, v1 + mg, 0], [u1 + mg, v1 + mg, 0]])
    cx = corners @ rmat.T + t
    centre = cx.mean(0) / np.linalg.norm(cx.mean(0))
    cos_cone = float((cx @ centre / np.linalg.norm(cx, axis=1)).min()) - 0.01
    cand = np.flatnonzero(rays.vec.astype(np.float32) @ centre.astype(np.float32) > cos_cone)
    u, v, ok = _hits(rays.vec[cand], rmat, t)
    near = ok & (u > u0 - mg) & (u < u1 + mg) & (v > v0 - mg) & (v < v1 + mg)
    idx = rays.index[cand[near]]
    if idx.size == 0:
        return out.reshape(h, w)
    px, py = (idx % w).astype(np.float64), (idx // w).astype(np.float64)
    subs = []
    for dx, dy in ((-0.25, -0.25), (0.25, -0.25), (-0.25, 0.25), (0.25, 0.25)):
        az, el = pixel_to_direction(lens, px + dx, py + dy)
        su, sv, sok = _hits(_unit(az, np.nan_to_num(el)), rmat, t)
        sok &= np.isfinite(el)
        subs.append((tex.offset + su * tex.scale, tex.offset + sv * tex.scale, sok))
    tx = np.stack([s[0] for s in subs])
    ty = np.stack([s[1] for s in subs])
    # footprint of one supersample in level-0 texels: half the spread of the pixel's four samples
    spread = np.maximum(np.ptp(tx, axis=0), np.ptp(ty, axis=0))
    level = np.clip(np.floor(np.log2(np.maximum(spread, 1.0))), 0, len(tex.levels) - 1).astype(np.int64)
    bg = out[idx]
    acc = np.zeros(idx.size, np.float32)
    for k in range(4):
        s = tex.sample(tx[k], ty[k], level)
        on = subs[k][2] & (s >= 0)
        ink = paper[0] + (paper[1] - paper[0]) * s / 255.0
        acc += np.where(on, ink, bg)
    out[idx] = acc / 4.0
    return out.reshape(h, w)


def _finish(
    grey: np.ndarray,
    lens: Catadioptric,
    rays: _Rays,
    noise: float,
    blur: float,
    rng: np.random.Generator,
    jpeg: int | None,
) -> np.ndarray:
    """Optics and sensor: Gaussian blur, noise, black outside the ring, optional JPEG; BGR uint8."""
    if blur > 0:
        grey = cv2.GaussianBlur(grey, (0, 0), blur)
    if noise > 0:
        grey = grey + np.float32(noise) * rng.standard_normal(grey.shape, dtype=np.float32)
    g = np.where(rays.mask, np.clip(np.rint(grey), 0, 255), 0).astype(np.uint8)
    bgr = cv2.cvtColor(g, cv2.COLOR_GRAY2BGR)
    if jpeg is not None:
        ok, buf = cv2.imencode(".jpg", bgr, [cv2.IMWRITE_JPEG_QUALITY, int(jpeg)])
        return np.asarray(cv2.imdecode(buf, cv2.IMREAD_COLOR), np.uint8)
    return np.asarray(bgr, np.uint8)


def _board_size(spec: BoardSpec) -> tuple[float, float]:
    u0, v0, u1, v1 = spec.outline()
    return u1 - u0, v1 - v0


def protocol_directions(
    lens: Catadioptric,
    spec: BoardSpec,
    n: int,
    rng: np.random.Generator,
    protocol: bool = True,
    span_deg: tuple[float, float] | None = None,
) -> list[tuple[float, float, float]]:
    """(azimuth, elevation, distance) of the board's centre per frame.

    Protocol: the first three frames hold it straight ahead of the lens's forward direction near
    the horizon; then it moves to the phone's LEFT (azimuth decreasing: counter-clockwise seen from
    above) and on round the ring at varied elevations and distances (0.4-1.5 m, scaled so the
    board spans `span_deg`: by default 20-45 degrees for a chessboard, 30-55 for ChArUco, whose
    markers need ~3 px a cell). Without the protocol every frame is anywhere on the ring.
    """
    lo_span, hi_span = span_deg or ((30.0, 55.0) if spec.kind == "charuco" else (20.0, 45.0))
    bw, bh = _board_size(spec)
    e_lo, e_hi = lens.elevation_range()
    out = []
    for k in range(n):
        span = math.radians(rng.uniform(lo_span, hi_span))
        dist = float(np.clip(max(bw, bh) / (2 * math.tan(span / 2)), 0.4, 1.5))
        half = math.degrees(math.atan2(0.5 * math.hypot(bw, bh), dist))
        lo, hi = e_lo + half + 1.0, e_hi - half - 1.0
        if protocol and k < 3:
            az, el = rng.uniform(-2, 2), float(np.clip(rng.uniform(-3, 3), lo, max(lo, hi)))
        else:
            if protocol:
                az = -360.0 * (k - 2) / max(n - 2, 1) + rng.uniform(-5, 5)
            else:
                az = rng.uniform(0, 360)
            el = rng.uniform(lo, hi) if hi > lo else 0.5 * (e_lo + e_hi)
        out.append((float(np.mod(az, 360.0)), float(el), dist))
    return out


def board_video(
    lens: Catadioptric,
    spec: BoardSpec,
    n_frames: int = 24,
    noise: float = 2.0,
    blur: float = 0.6,
    seed: int = 0,
    protocol: bool = True,
    jpeg: int | None = None,
    max_tilt: float = 35.0,
    span_deg: tuple[float, float] | None = None,
    directions: Sequence[tuple[float, float, float]] | None = None,
) -> CalibSet:
    """Render a calibration video of `spec` through `lens` (see `protocol_directions`): tilts up
    to `max_tilt` deg about each board axis, roll up to 20 deg, light varying frame to frame, the
    board spanning `span_deg` (see `protocol_directions`), or at the given `directions`
    ((azimuth, elevation, distance) of its centre per frame; n_frames is then their number);
    `noise` grey levels of sensor noise, Gaussian `blur` px, optional JPEG quality."""
    rng = np.random.default_rng(seed)
    rays = _ring_rays(lens, rng)
    tex = _Texture(spec)
    frames, poses, truth = [], [], []
    if directions is not None:
        dirs = [(float(a), float(e), float(d)) for a, e, d in directions]
    else:
        dirs = protocol_directions(lens, spec, n_frames, rng, protocol, span_deg)
    for az, el, dist in dirs:
        tu, tv = rng.uniform(-max_tilt, max_tilt, 2)
        roll = rng.uniform(-20, 20)
        rmat, t = board_pose(spec, az, el, dist, float(tu), float(tv), float(roll))
        light = rng.uniform(0.75, 1.0)
        grey = render_board(lens, tex, spec, rays, rmat, t, (28.0 * light, 225.0 * light))
        frames.append(_finish(grey, lens, rays, noise, blur, rng, jpeg))
        poses.append((rmat, t))
        truth.append(corner_truth(lens, spec, rmat, t))
    return CalibSet(lens, spec, frames, poses, truth, dirs)


def save_video(path: Path, cs: CalibSet, fps: float = 2.0) -> int:
    """The set's frames as an MP4 (or Motion-JPEG .avi) for `omninav calib lens VIDEO`."""
    return write_video(path, cs.frames, fps, cs.lens.image_size)


def save_stills(folder: Path, cs: CalibSet) -> list[Path]:
    """The set's frames as PNG stills (`frame_000.png`, ...) for `omninav calib lens IMAGES...`."""
    folder.mkdir(parents=True, exist_ok=True)
    paths = []
    for i, f in enumerate(cs.frames):
        p = folder / f"frame_{i:03d}.png"
        if not cv2.imwrite(str(p), f):
            raise OSError(f"cannot write {p}")
        paths.append(p)
    return paths
