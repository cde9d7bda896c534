"""Ring-only test data: donut frames of ordinary venue scenes with the lens clipped on again and again.

A clip-on donut lens never sits in the same place twice: each time it is clipped on, the ring's
centre moves by some pixels and (the lens sits a little higher or lower) its radii scale by up to
~2 %. `clipon_set` renders frames of a corridor walk through such re-clipped lenses and puts the
surround of a real lens around them: the dark housing (textured, grey 10-40, never pure black), a
bright plastic rim further out, vignetting that darkens the ring towards both edges, a soft edge,
sensor noise and, optionally, JPEG compression. It also makes what a ring finder must refuse: a
plain photo without a lens (`plain_photo`), a covered lens (`covered_lens`), and a ring cut by the
picture's edge (`cut_lens`). Everything is seeded; nothing is stored.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from ..lens import Catadioptric, Sensor
from . import donut_lens
from .render import CameraModel, PanoGrid, camera_frame, world_panorama
from .scene import Scene, build_scene
from .walks import default_routes, grid_for

# a real mirror's sensor (lens.json `sensor`): what `calib lens` fits on OpenCV's real catadioptric
# corners (tests/calib/test_calib_corners.py), a skewed stretch and decentring, its unit the donut's
# outer radius: for renders, golden frames and tests that need a real mirror's profile
REAL_MIRROR_SENSOR = Sensor((1.0, -0.02556, 0.02424, 1.00408), (0.0296, -0.00463), 340.0)


def wide_lens() -> Catadioptric:
    """A second geometry, 1280x720 (a phone's 16:9 video) with its ring off the image centre and
    a thinner ring: 95-330 px around (655, 368), -55..+25 deg, clockwise."""
    r_in, r_out = 95.0, 330.0
    rm = 0.5 * (r_in + r_out)
    c2, c1, c0 = np.polyfit([r_in, rm, r_out], [-55.0, -17.0, 25.0], 2)
    return Catadioptric(
        image_size=(1280, 720),
        center=(655.0, 368.0),
        r_inner=r_in,
        r_outer=r_out,
        elevation_poly=(float(c0), float(c1), float(c2)),
        forward_deg=-90.0,
        ccw=False,
    )


def resized(lens: Catadioptric, scale: float) -> Catadioptric:
    """The same optics on a sensor `scale` times the size (a smaller video of the same lens)."""
    return dataclasses.replace(
        lens,
        image_size=(int(round(lens.image_size[0] * scale)), int(round(lens.image_size[1] * scale))),
        center=(lens.center[0] * scale, lens.center[1] * scale),
        r_inner=lens.r_inner * scale,
        r_outer=lens.r_outer * scale,
        elevation_poly=tuple(c / scale**k for k, c in enumerate(lens.elevation_poly)),
        sensor=None if lens.sensor is None else dataclasses.replace(lens.sensor, scale=lens.sensor.scale * scale),
    )


def geometries(scale: float = 1.0) -> dict[str, Catadioptric]:
    """The lens geometries the ring finder is tested on (at `scale` of their size, for speed)."""
    return {"donut": donut_lens(scale), "wide": resized(wide_lens(), scale)}


def reclip(lens: Catadioptric, shift: tuple[float, float] = (0.0, 0.0), scale: float = 1.0) -> Catadioptric:
    """The lens as clipped on again: its centre moved by `shift` px and its picture `scale` times
    larger (elevation(r) becomes elevation(r / scale)). The result's centre and radii are the
    ring a finder should measure. (The same arithmetic as the engine's `calib.lens_fit.scaled_lens`,
    written again on purpose: the renderer's truth must not come from the code it tests.)"""
    return dataclasses.replace(
        lens,
        center=(lens.center[0] + shift[0], lens.center[1] + shift[1]),
        r_inner=lens.r_inner * scale,
        r_outer=lens.r_outer * scale,
        elevation_poly=tuple(c / scale**k for k, c in enumerate(lens.elevation_poly)),
        ring=None,
    )


def cut_lens(lens: Catadioptric, poke: float = 0.1) -> Catadioptric:
    """The lens clipped on so low that its ring pokes out of the picture's bottom edge by
    `poke` x r_outer (a lens not centred over the camera)."""
    dy = lens.image_size[1] - 0.5 - (lens.center[1] + lens.r_outer) + poke * lens.r_outer
    return reclip(lens, (0.0, max(0.0, dy)))


@dataclass(frozen=True)
class Surround:
    """What a real clip-on puts around the ring, and what the phone's camera adds."""

    housing: tuple[float, float] = (10.0, 40.0)  # grey range of the housing's texture
    rim: tuple[float, float, float] = (1.07, 1.13, 175.0)  # bright rim: from, to (x r_outer), grey
    vignette: float = 0.35  # brightness lost at the ring's edges
    blur: float = 1.0  # soft edge: Gaussian sigma, px
    noise: float = 2.0  # sensor noise sigma, grey levels
    jpeg: int | None = None  # JPEG quality, or None for none
    light: float = 1.0  # the scene's brightness (a dim room: 0.3)


def surround(frame: np.ndarray, lens: Catadioptric, sur: Surround, rng: np.random.Generator) -> np.ndarray:
    """(H, W, 3) uint8 BGR rendered donut frame (black off the ring) -> the same frame as a phone
    with a clip-on lens sees it. `lens` is the lens that rendered the frame (its true ring)."""
    h, w = frame.shape[:2]
    ys, xs = np.mgrid[0:h, 0:w].astype(np.float32)
    rho = np.hypot(xs - np.float32(lens.center[0]), ys - np.float32(lens.center[1]))
    ring = (rho >= lens.r_inner) & (rho <= lens.r_outer)  # as the renderer decides which pixels see
    # vignetting: dark towards both edges of the ring (a 4th power of the distance from mid-ring)
    half = 0.5 * (lens.r_outer - lens.r_inner)
    u = np.clip((rho - 0.5 * (lens.r_outer + lens.r_inner)) / half, -1.0, 1.0)
    gain = 1.0 - sur.vignette * u**4
    # the housing: smooth blotches of grey within the housing range, not pure black
    lo, hi = sur.housing
    small = rng.uniform(0.0, 1.0, (max(2, h // 24), max(2, w // 24))).astype(np.float32)
    tex = cv2.resize(small, (w, h), interpolation=cv2.INTER_CUBIC)
    house = lo + (hi - lo) * np.clip(tex, 0.0, 1.0)
    r0, r1, grey = sur.rim
    rim = (rho >= r0 * lens.r_outer) & (rho <= r1 * lens.r_outer)
    back = np.where(rim, np.float32(grey), house)
    out = np.where(ring[..., None], frame.astype(np.float32) * (sur.light * gain)[..., None], back[..., None])
    if sur.blur > 0:
        out = cv2.GaussianBlur(out, (0, 0), sur.blur)
    if sur.noise > 0:
        out = out + rng.normal(0.0, sur.noise, out.shape).astype(np.float32)
    img: np.ndarray = np.clip(out + 0.5, 0, 255).astype(np.uint8)
    if sur.jpeg is not None:
        ok, buf = cv2.imencode(".jpg", img, [cv2.IMWRITE_JPEG_QUALITY, sur.jpeg])
        assert ok
        dec = cv2.imdecode(buf, cv2.IMREAD_COLOR)
        assert dec is not None
        img = dec
    return img


def _poses(scene: Scene, n: int, rng: np.random.Generator) -> list[tuple[float, float, float]]:
    """n (x, y, heading) along the first legs of the venue's modelling route, headings varied."""
    route, _ = default_routes(scene)
    (ax, ay), (bx, by) = route[0], route[1]
    head = float(np.rad2deg(np.arctan2(bx - ax, -(by - ay))))
    out = []
    for f in np.linspace(0.05, 0.95, n):
        out.append((ax + f * (bx - ax), ay + f * (by - ay), head + float(rng.uniform(-40, 40))))
    return out


def ring_frames(
    lens: Catadioptric,
    n: int,
    seed: int = 0,
    sur: Surround | None = None,
    scene: Scene | None = None,
    pano_width: int = 720,
) -> list[np.ndarray]:
    """n BGR frames of a corridor seen through `lens` (the lens as it sits: see `reclip`), with the
    surround of a clip-on. The frames' true ring is lens.center, lens.r_inner, lens.r_outer."""
    rng = np.random.default_rng(seed)
    scene = scene or build_scene(seed % 4)
    sur = sur or Surround()
    grid: PanoGrid = grid_for(lens, pano_width)
    cam = CameraModel.create(lens)
    frames = []
    for x, y, hd in _poses(scene, n, rng):
        pano = world_panorama(scene, x, y, 1.35, grid)
        bgr = cv2.cvtColor(camera_frame(cam, pano, grid, hd), cv2.COLOR_RGB2BGR)
        frames.append(surround(bgr, lens, sur, rng))
    return frames


def small_centre_frames(
    lens: Catadioptric,
    n: int,
    radius: float,
    offset: tuple[float, float],
    seed: int = 0,
    sur: Surround | None = None,
) -> list[np.ndarray]:
    """ring_frames() of a small mirror off its rim's axis: the dark centre (the camera's
    reflection, the post) a disc of `radius` px whose centre is `offset` px from the ring's, hard
    edged as the renderer's ring (a pixel is in it when its centre is). The frames' true ring is
    lens.center, `radius` (the dark centre's own radius), lens.r_outer."""
    inner = max(1.0, radius - float(np.hypot(*offset)) - 2.0)  # the rendered one, under the disc
    frames = ring_frames(dataclasses.replace(lens, r_inner=min(lens.r_inner, inner)), n, seed=seed, sur=sur)
    h, w = frames[0].shape[:2]
    y, x = np.mgrid[0:h, 0:w]
    disc = np.hypot(x - (lens.center[0] + offset[0]), y - (lens.center[1] + offset[1])) <= radius
    for f in frames:
        f[disc] = 22
    return frames


@dataclass(frozen=True)
class ClipOn:
    """One clip-on: the lens as it sat (its ring is the truth) and the frames filmed through it."""

    lens: Catadioptric
    shift: tuple[float, float]
    scale: float
    frames: list[np.ndarray]

    @property
    def truth(self) -> tuple[float, float, float, float]:
        """(cx, cy, r_inner, r_outer) of the ring in these frames."""
        return self.lens.center[0], self.lens.center[1], self.lens.r_inner, self.lens.r_outer


def clipon_set(
    lens: Catadioptric,
    n_clips: int = 4,
    frames_per_clip: int = 3,
    seed: int = 0,
    sur: Surround | None = None,
    max_shift: float = 10.0,
    max_scale: float = 0.02,
) -> list[ClipOn]:
    """n_clips clip-ons of `lens`: the first sits exactly as the profile says, the others have
    their centre moved 0.25..1 x max_shift px in a random direction and their radii scaled by
    1 +- max_scale."""
    rng = np.random.default_rng(seed)
    scene = build_scene(seed % 4)
    out = []
    for i in range(n_clips):
        if i == 0:
            shift, s = (0.0, 0.0), 1.0
        else:
            d, a = rng.uniform(0.25, 1.0) * max_shift, rng.uniform(0.0, 2 * np.pi)
            shift, s = (float(d * np.cos(a)), float(d * np.sin(a))), float(1.0 + rng.uniform(-max_scale, max_scale))
        true = reclip(lens, shift, s)
        frames = ring_frames(true, frames_per_clip, seed * 100 + i, sur, scene)
        out.append(ClipOn(true, shift, s, frames))
    return out


def write_images(folder: Path, frames: list[np.ndarray], ext: str = ".png") -> list[Path]:
    """Frames as numbered still images (PNG, or JPEG with ext ".jpg"), as a phone's photos."""
    folder.mkdir(parents=True, exist_ok=True)
    out = []
    for i, f in enumerate(frames):
        p = folder / f"{i:03d}{ext}"
        if not cv2.imwrite(str(p), f):
            raise RuntimeError(f"cannot write {p}")
        out.append(p)
    return out


def plain_photo(size: tuple[int, int], seed: int = 0, noise: float = 2.0) -> np.ndarray:
    """(h, w, 3) BGR: an ordinary perspective-like view of a corridor, no lens (no ring): a
    stretch of the venue's panorama around the horizon, scaled to the frame."""
    rng = np.random.default_rng(seed)
    scene = build_scene(seed % 4)
    x, y, hd = _poses(scene, 1, rng)[0]
    grid = PanoGrid(1440, 40.0, -40.0, 321)
    pano = world_panorama(scene, x, y, 1.35, grid)
    c0 = int(round((hd % 360.0) / 360.0 * 1440))
    view = np.roll(pano, -c0 + 200, axis=1)[:, :400]  # 100 deg wide, the heading in the middle
    w, h = size
    img = cv2.resize(view, (w, h), interpolation=cv2.INTER_LINEAR).astype(np.float32)
    img += rng.normal(0.0, noise, img.shape)
    out: np.ndarray = cv2.cvtColor(np.clip(img + 0.5, 0, 255).astype(np.uint8), cv2.COLOR_RGB2BGR)
    return out


def covered_lens(size: tuple[int, int], seed: int = 0, level: float = 12.0, noise: float = 3.0) -> np.ndarray:
    """(h, w, 3) BGR: a finger or cap over the lens: a dark frame, a little uneven, with noise."""
    rng = np.random.default_rng(seed)
    w, h = size
    small = rng.uniform(0.0, 1.0, (4, 4)).astype(np.float32)
    shade = level * (0.6 + 0.8 * cv2.resize(small, (w, h), interpolation=cv2.INTER_CUBIC))
    img = shade[..., None] + rng.normal(0.0, noise, (h, w, 3)).astype(np.float32)
    out: np.ndarray = np.clip(img + 0.5, 0, 255).astype(np.uint8)
    return out
