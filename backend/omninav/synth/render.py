"""Ray-cast world panoramas of a Scene and photograph them through a lens.

`world_panorama` renders, for a camera position and height, what every direction (world azimuth
clockwise from plan-up, elevation) sees: a 2.5-D ray caster (one plan ray per column against wall
segments and people, then per row floor, wall or ceiling). `camera_frame` then samples it through a
lens profile, optionally tilted and with the lens re-clipped off centre, which is how a real donut
frame relates to the world.
"""

from __future__ import annotations

import dataclasses
import functools
from dataclasses import dataclass
from typing import Any

import cv2
import numpy as np

from ..lens import Catadioptric, Lens, pixel_to_direction
from .scene import PLAN_PPM, TEX_PPM, Person, Scene


@dataclass(frozen=True)
class PanoGrid:
    width: int  # columns over 360 deg
    el_top: float
    el_bottom: float
    rows: int

    @property
    def step(self) -> float:
        return (self.el_top - self.el_bottom) / (self.rows - 1)

    def elevations(self) -> np.ndarray:
        return np.linspace(self.el_top, self.el_bottom, self.rows)


def _cast(scene: Scene, x: float, y: float, az: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Nearest wall along each plan ray: distance t, atlas column, incidence cosine."""
    dx, dy = np.sin(az), -np.cos(az)
    s = scene.seg
    ex, ey = s[:, 2] - s[:, 0], s[:, 3] - s[:, 1]
    # Solve (x,y) + t d = a + u e for t, u (2x2 per ray-segment pair).
    den = dx[:, None] * ey[None, :] - dy[:, None] * ex[None, :]
    wx, wy = s[None, :, 0] - x, s[None, :, 1] - y
    with np.errstate(divide="ignore", invalid="ignore"):
        t = (wx * ey[None, :] - wy * ex[None, :]) / den
        u = (wx * dy[:, None] - wy * dx[:, None]) / den
    ok = (np.abs(den) > 1e-12) & (t > 1e-3) & (u >= 0) & (u <= 1)
    t = np.where(ok, t, np.inf)
    k = np.argmin(t, axis=1)
    tt = t[np.arange(len(az)), k]
    uu = u[np.arange(len(az)), k] * np.hypot(ex[k], ey[k])
    col = scene.seg_off[k] + np.clip((uu * TEX_PPM).astype(np.int64), 0, None)
    col = np.minimum(col, scene.atlas.shape[1] - 1)
    nx, ny = ey[k], -ex[k]
    cosi = np.abs(nx * dx + ny * dy) / np.maximum(np.hypot(nx, ny), 1e-9)
    return tt, col, cosi, k


def _flat_textures(scene: Scene) -> tuple[np.ndarray, int, int]:
    """Atlas, floor and ceiling as one flat (M, 3) float32 buffer: one gather renders a panorama."""
    cached = getattr(scene, "_flat", None)
    if cached is None:
        a = scene.atlas.reshape(-1, 3)
        f = scene.floor.reshape(-1, 3)
        c = scene.ceiling.reshape(-1, 3)
        cached = (np.concatenate([a, f, c]).astype(np.float32), len(a), len(a) + len(f))
        scene._flat = cached  # type: ignore[attr-defined]
    return cached


def world_panorama(
    scene: Scene, x: float, y: float, cam_h: float, grid: PanoGrid, people: list[Person] | None = None
) -> np.ndarray:
    """(rows, width, 3) uint8 RGB: what a camera at plan (x, y), height cam_h sees all around.

    Column j looks at world azimuth (j + 0.5) * 360 / width (clockwise from plan-up).
    """
    tex, off_floor, off_ceil = _flat_textures(scene)
    az = np.deg2rad((np.arange(grid.width) + 0.5) * 360.0 / grid.width)
    el = np.deg2rad(grid.elevations())
    tw, col, cosi, _ = _cast(scene, x, y, az)
    tan_el = np.tan(el).astype(np.float32)[:, None]  # (rows, 1)
    dx, dy = np.sin(az).astype(np.float32), -np.cos(az).astype(np.float32)
    with np.errstate(divide="ignore"):
        t_plane = np.where(tan_el < 0, cam_h / -tan_el, (scene.wall_h - cam_h) / tan_el)
    t_plane = np.minimum(t_plane, 200.0).astype(np.float32)  # (rows, 1)
    tw32 = tw.astype(np.float32)[None, :]
    on_wall = tw32 <= t_plane  # (rows, cols)
    aw = scene.atlas.shape[1]
    zr = ((scene.wall_h - cam_h) * TEX_PPM - (tw32 * TEX_PPM) * tan_el).astype(np.int32)
    np.clip(zr, 0, scene.atlas.shape[0] - 1, out=zr)
    wall_idx = zr * aw + col.astype(np.int32)[None, :]
    fw, fh = scene.floor.shape[1], scene.floor.shape[0]
    px = ((x * PLAN_PPM) + (t_plane * PLAN_PPM) * dx[None, :]).astype(np.int32)
    py = ((y * PLAN_PPM) + (t_plane * PLAN_PPM) * dy[None, :]).astype(np.int32)
    np.clip(px, 0, fw - 1, out=px)
    np.clip(py, 0, fh - 1, out=py)
    plane_idx = py * fw + px + np.where(tan_el < 0, off_floor, off_ceil).astype(np.int32)
    idx = np.where(on_wall, wall_idx, plane_idx)
    wall_shade = ((0.72 + 0.28 * cosi) / (1.0 + 0.012 * tw)).astype(np.float32)[None, :]
    shade = np.where(on_wall, wall_shade, 1.0 / (1.0 + 0.02 * t_plane))
    img = tex[idx]
    img *= shade[..., None]
    if people:
        img = _draw_people(img, people, x, y, cam_h, dx, dy, tan_el, np.where(on_wall, tw32, t_plane))
    out: np.ndarray = np.clip(img, 0, 255).astype(np.uint8)
    return out


def _draw_people(
    img: np.ndarray,
    people: list[Person],
    x: float,
    y: float,
    cam_h: float,
    dx: np.ndarray,
    dy: np.ndarray,
    tan_el: np.ndarray,
    dist: np.ndarray,
) -> np.ndarray:
    """Passers-by: vertical cylinders (head, shirt, trousers) in front of whatever else is there."""
    for p in people:
        ox, oy = x - p.x, y - p.y
        b = ox * dx + oy * dy
        disc = b * b - (ox * ox + oy * oy - p.radius**2)
        hit = disc > 0
        tpn = np.where(hit, -b - np.sqrt(np.maximum(disc, 0)), np.inf)
        cols = np.flatnonzero(hit & (tpn > 0.05))
        if cols.size == 0:
            continue
        tc = tpn[cols][None, :]
        zp = cam_h + tc * tan_el
        m = (tc < dist[:, cols]) & (zp >= 0) & (zp <= p.height)
        colour = np.where(
            (zp > 0.85 * p.height)[..., None],
            np.array((200, 160, 130), np.float32),
            np.where(
                (zp > 0.5 * p.height)[..., None],
                np.array(p.shirt, np.float32),
                np.array(p.trousers, np.float32),
            ),
        )
        sub = img[:, cols]
        img[:, cols] = np.where(m[..., None], colour, sub)
        dist[:, cols] = np.where(m, tc, dist[:, cols])
    return img


def tilt_rotation(tilt_deg: float, tilt_dir_deg: float) -> np.ndarray:
    """Rotation (3x3) of camera-frame vectors (forward, right, up) by a tilt of tilt_deg
    towards camera azimuth tilt_dir_deg: the phone held a few degrees off vertical."""
    a = np.deg2rad(tilt_dir_deg + 90.0)
    axis = np.array([np.cos(a), np.sin(a), 0.0])
    rot: np.ndarray = cv2.Rodrigues(axis * np.deg2rad(tilt_deg))[0]
    return rot


@dataclass
class CameraModel:
    """Per-pixel camera directions of a lens, precomputed once per (lens, lens shift)."""

    lens: Lens
    vec: np.ndarray  # (N, 3) camera-frame unit vectors of the seen pixels
    index: np.ndarray  # (N,) flat pixel index into the image
    size: tuple[int, int]

    @classmethod
    def create(cls, lens: Lens, shift_px: tuple[float, float] = (0.0, 0.0)) -> CameraModel:
        """`shift_px` moves the true optical centre away from the profile's: a re-clipped lens."""
        true = lens
        if isinstance(lens, Catadioptric):
            true = dataclasses.replace(lens, center=(lens.center[0] + shift_px[0], lens.center[1] + shift_px[1]))
        w, h = lens.image_size
        ys, xs = np.mgrid[0:h, 0:w]
        az, el = pixel_to_direction(true, xs.ravel().astype(np.float64), ys.ravel().astype(np.float64))
        ok = np.isfinite(el)
        a, e = np.deg2rad(az[ok]), np.deg2rad(el[ok])
        vec = np.stack([np.cos(e) * np.cos(a), np.cos(e) * np.sin(a), np.sin(e)], -1)
        return cls(lens, vec, np.flatnonzero(ok), (w, h))


@functools.cache
def _blas() -> Any:
    from threadpoolctl import ThreadpoolController  # type: ignore[import-untyped]

    return ThreadpoolController()


def camera_frame(
    cam: CameraModel, pano: np.ndarray, grid: PanoGrid, heading_deg: float, rot: np.ndarray | None = None
) -> np.ndarray:
    """Photograph a world panorama: (h, w, 3) uint8 frame for a camera facing heading_deg."""
    if rot is None:
        v = cam.vec
    else:  # one BLAS thread: the same product, but threads fighting over a busy machine took 20x longer
        with _blas().limit(limits=1, user_api="blas"):
            v = cam.vec @ rot.T
    az = np.rad2deg(np.arctan2(v[:, 1], v[:, 0])) + heading_deg
    el = np.rad2deg(np.arcsin(np.clip(v[:, 2], -1, 1)))
    mx = (np.mod(az, 360.0) * grid.width / 360.0 - 0.5).astype(np.float32)
    my = ((grid.el_top - el) / grid.step).astype(np.float32)
    w, h = cam.size
    # remap wants maps under 32767 wide: fold the pixel list into rows of 4096
    n = len(mx)
    pad = (-n) % 4096
    mx = np.concatenate([mx, np.zeros(pad, np.float32)]).reshape(-1, 4096)
    my = np.concatenate([my, np.zeros(pad, np.float32)]).reshape(-1, 4096)
    samp = cv2.remap(pano, mx, my, cv2.INTER_LINEAR, borderMode=cv2.BORDER_WRAP)
    out = np.zeros((h * w, 3), np.uint8)
    out[cam.index] = samp.reshape(-1, 3)[:n]
    return out.reshape(h, w, 3)
