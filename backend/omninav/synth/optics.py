"""Real optics for synthetic donut frames: what a real mirror lens and a phone camera add, and the
measurements of a real donut photo that say how much.

The renderer photographs its world through an ideal lens. A real donut frame (measured on the
photo in the MIT-licensed `pyomniunwarp` 0.2.5, `bench/real_optics.py`) differs from it in:

- the mirror's rim: the ring does not end sharply but fades over its last few per cent, and the
  fading edge turns blue;
- the phone's own reflection: the camera looks at the mirror, so the phone is seen in the ring's
  inner part (the photo's tan case reaches 14 % into the ring at its corners);
- blur and lateral chromatic aberration, which the photo has little of at its 1920x1080 (the
  phone corrects the aberration; both are kept so that a cheaper lens can be imitated);
- gentle vignetting across the ring;
- the phone's auto-exposure, which steers the ring's mean to a grey level (the photo's is 121),
  and its auto white balance, following the scene with a lag and off by a per-walk residual.

`OpticsSim` applies these to one walk's rendered frames in order; `Optics()` does nothing. A 360
camera's (equirectangular) frames get the phone's exposure and white balance only.
All sizes are fractions of the ring's width (r_outer - r_inner), so one `Optics` fits any image
size; `u` is the position across the ring, 0 at r_inner and 1 at r_outer.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import cv2
import numpy as np

from ..lens import Catadioptric, Lens


@dataclass(frozen=True)
class Optics:
    """What a real lens and phone do to a frame; the defaults do nothing."""

    vignette: tuple[float, float] = (0.0, 0.0)  # gain 1 + a (u - 0.5) + b (u - 0.5)^2 across the ring
    rim_width: float = 0.0  # the outer rim fades over this share of the ring (10-90 % of the fall)
    rim_level: float = 1.0  # relative level at r_outer, the fall's bottom
    rim_blue: float = 0.0  # blue excess (B/G - 1) at r_outer: the fading edge's colour
    chroma: float = 0.0  # lateral chromatic aberration: red out, blue in, by this share of r at r_outer
    blur: float = 0.0  # Gaussian sigma everywhere
    edge_blur: float = 0.0  # more sigma towards both edges of the ring (added at u = 0 and 1)
    phone: tuple[float, float] = (0.0, 0.0)  # the phone's reflection reaches u at its sides, corners
    phone_rgb: tuple[float, float, float] = (173.0, 149.0, 119.0)  # its colour at the target exposure
    exposure_target: float = 0.0  # auto-exposure steers the ring's mean grey level here; 0 = off
    exposure_lag: float = 0.0  # share of the exposure error kept each frame (0: at once)
    wb_lag: float = -1.0  # auto white balance (grey world): share of the error kept a frame; < 0 off
    wb_error: float = 0.0  # the white balance's residual: +- this per channel gain, drawn per walk


# Measured on the real photo (bench/real_optics.py prints the measurements these come from):
# - rim: the ring fades from 584 to 600 px of its 235-600 (10-90 % over 3.1 % of the ring, down to
#   0.28 of the level inside, B/G 1.21 there);
# - the phone's tan case: its run along rays from the inner edge reaches u 0.14 at the corners, 0.01
#   at the sides (median);
# - white board cells: their level grows ~11 % per ring width over u 0.26-0.70 (a line fits them to
#   2 %, no curvature shows, so none is extrapolated to the edges);
# - re-blur sigma ~0.95 px = 0.10-0.19 deg of azimuth, sharper than the renderer's own 0.15-0.30 deg,
#   and barely more at the edges: no blur added; lateral chroma under 0.01 px: none added;
# - ring mean grey 121, channels within 1 % of each other (the phone's exposure and balance).
# Not measurable in one photo, so a typical phone's: exposure and white balance settling in ~0.3 s
# at 10 fps (70 % of the error kept a frame), the balance off by up to 3 % per channel.
REAL = Optics(
    vignette=(0.11, 0.0),
    rim_width=0.033,
    rim_level=0.26,
    rim_blue=0.2,
    chroma=0.0,
    blur=0.0,
    edge_blur=0.0,
    phone=(0.01, 0.14),
    exposure_target=121.0,
    exposure_lag=0.7,
    wb_lag=0.7,
    wb_error=0.03,
)


def scaled(o: Optics, k: float) -> Optics:
    """`o`'s lens k times as strong (k = 0: an ideal lens, 1: `o`'s): a milder or harsher lens. The
    phone's auto-exposure and white balance stay as they are (only their residual scales)."""

    def mix(a: float, b: float) -> float:
        return a + k * (b - a)

    z = Optics()
    return dataclasses.replace(
        o,
        vignette=(k * o.vignette[0], k * o.vignette[1]),
        rim_width=k * o.rim_width,
        rim_level=mix(z.rim_level, o.rim_level),
        rim_blue=k * o.rim_blue,
        chroma=k * o.chroma,
        blur=k * o.blur,
        edge_blur=k * o.edge_blur,
        phone=(k * o.phone[0], k * o.phone[1]),
        wb_error=k * o.wb_error,
    )


MILD = scaled(REAL, 0.5)  # a tuning family's lens: half the rim, a smaller phone, half the residual


def ring_of(lens: Lens) -> tuple[float, float, float, float]:
    """(cx, cy, r_inner, r_outer) of a lens; a 360 camera's frame stands in as a ring from its centre."""
    if isinstance(lens, Catadioptric):
        return lens.center[0], lens.center[1], lens.r_inner, lens.r_outer
    w, h = lens.image_size
    return w / 2.0, h / 2.0, 0.0, math.hypot(w, h) / 2.0


def _polar(size: tuple[int, int], ring: tuple[float, float, float, float]) -> tuple[np.ndarray, ...]:
    """Per pixel of a (w, h) frame: dx, dy from the centre, r, u (float32)."""
    cx, cy, r_in, r_out = ring
    w, h = size
    ys, xs = np.mgrid[0:h, 0:w].astype(np.float32)
    dx, dy = xs - np.float32(cx), ys - np.float32(cy)
    r = np.hypot(dx, dy)
    u = (r - np.float32(r_in)) / np.float32(max(r_out - r_in, 1e-6))
    return dx, dy, r, u


def rim_gain(u: np.ndarray, o: Optics) -> np.ndarray:
    """(..., 3) per-channel gain of the vignetting and the fading rim at ring positions u."""
    a, b = o.vignette
    g = 1.0 + a * (u - 0.5) + b * (u - 0.5) ** 2
    out = np.repeat(g[..., None], 3, axis=-1).astype(np.float32)
    if o.rim_width > 0:
        # a logistic fall whose 10-90 % spans rim_width, centred 0.8 widths inside r_outer: there
        # it has all but reached rim_level, as the photo's ring edge (its ROI) has
        s = o.rim_width / (2.0 * math.log(9.0))
        fall = 1.0 / (1.0 + np.exp(np.clip((u - (1.0 - 0.8 * o.rim_width)) / s, -50.0, 50.0)))
        out *= (o.rim_level + (1.0 - o.rim_level) * fall)[..., None].astype(np.float32)
        out[..., 2] *= (1.0 + o.rim_blue * (1.0 - fall)).astype(np.float32)
    return out


class OpticsSim:
    """Applies an `Optics` to one walk's frames, in order (stateful: exposure, white balance).

    The per-walk draw (the white balance's residual) comes from `rng` at construction: the same
    seed gives the same frames.
    """

    def __init__(self, lens: Lens, optics: Optics, rng: np.random.Generator) -> None:
        self.optics = o = optics
        self.size = lens.image_size
        w, h = self.size
        cx, cy, r_in, r_out = self.ring = ring_of(lens)
        width = max(r_out - r_in, 1e-6)
        dx, dy, r, u = _polar(self.size, self.ring)
        inside = (r >= r_in) & (r <= r_out)
        self.mask = inside.astype(np.uint8)
        # the lens's effects belong to the donut's mirror; a 360 camera gets the phone's exposure
        # and white balance only
        donut = isinstance(lens, Catadioptric)
        self.gain: np.ndarray | None = None
        if donut and (o.vignette != (0.0, 0.0) or o.rim_width > 0):
            self.gain = np.where(inside[..., None], rim_gain(np.clip(u, 0.0, 1.0), o), np.float32(1.0))
        self.phone: np.ndarray | None = None
        if donut and o.phone[1] > 0:
            # the phone seen in the mirror: a square (its case, edges along the frame's) whose
            # corners the mirror's inner rim cuts off, in front of whatever the ring shows there
            side, corner = r_in + o.phone[0] * width, r_in + o.phone[1] * width
            sq = (np.maximum(np.abs(dx), np.abs(dy)) <= side) & (r <= corner) & inside
            self.phone = sq
        self.chroma: tuple[np.ndarray, ...] | None = None
        if donut and o.chroma:
            s = np.float32(o.chroma)
            # red lands further out than green: sample it from nearer the centre; blue the other way
            self.chroma = (cx + dx * (1 - s), cy + dy * (1 - s), cx + dx * (1 + s), cy + dy * (1 + s))
        self.sigma = o.blur * width if donut else 0.0
        self.edge_sigma = o.edge_blur * width if donut else 0.0
        self.edge = (np.clip(np.abs(u - 0.5) * 2.0, 0.0, 1.0) ** 2)[..., None].astype(np.float32)
        self.residual = (1.0 + rng.uniform(-o.wb_error, o.wb_error, 3)).astype(np.float32)
        self.exposure = 1.0
        self.balance = np.ones(3, np.float32)
        self.first = True
        self.identity = o == Optics()

    def _ring_mean(self, rgb: np.ndarray) -> np.ndarray:
        return np.asarray(cv2.mean(rgb, self.mask)[:3], np.float32)

    def __call__(self, rgb: np.ndarray) -> np.ndarray:
        """(h, w, 3) float32 RGB, 0-255 -> the same, as the real lens and phone would give it."""
        w, h = self.size
        if rgb.shape != (h, w, 3) or rgb.dtype != np.float32:
            raise ValueError(f"want a ({h}, {w}, 3) float32 frame, got {rgb.shape} {rgb.dtype}")
        if self.identity:
            return rgb
        o = self.optics
        out = rgb.copy()
        if self.phone is not None:
            # lit by the same room as the scene: its level follows the ring's
            level = float(self._ring_mean(rgb).mean()) / (o.exposure_target or 121.0)
            out[self.phone] = np.asarray(o.phone_rgb, np.float32) * np.float32(level)
        if self.chroma is not None:
            rx, ry, bx, by = self.chroma
            src = out.copy()
            out[..., 0] = cv2.remap(src[..., 0], rx, ry, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
            out[..., 2] = cv2.remap(src[..., 2], bx, by, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
        if self.sigma > 0 or self.edge_sigma > 0:
            base = cv2.GaussianBlur(out, (0, 0), self.sigma) if self.sigma > 0 else out
            if self.edge_sigma > 0:
                more = cv2.GaussianBlur(out, (0, 0), math.hypot(self.sigma, self.edge_sigma))
                base = base + (more - base) * self.edge
            out = base
        if self.gain is not None:
            out *= self.gain
        if o.wb_lag >= 0 or o.wb_error:
            if o.wb_lag >= 0:
                mean = self._ring_mean(out)
                want = np.float32(mean.mean()) / np.maximum(mean, np.float32(1.0))
                keep = np.float32(0.0 if self.first else o.wb_lag)
                self.balance = (keep * self.balance + (1 - keep) * want).astype(np.float32)
            out *= (self.balance * self.residual)[None, None, :]
        if o.exposure_target > 0:
            # the exposure that would put this frame's ring mean on target, reached with a lag
            want_e = o.exposure_target / max(float(self._ring_mean(out).mean()), 1e-3)
            lag = 0.0 if self.first else o.exposure_lag
            self.exposure = lag * self.exposure + (1 - lag) * want_e
            out *= np.float32(self.exposure)
        self.first = False
        np.clip(out, 0.0, 255.0, out=out)
        return out


# ---- a second exposure of a frame ---------------------------------------------------------------
def reexpose(
    rgb: np.ndarray,
    gain: float = 1.0,
    wb: tuple[float, float, float] = (1.0, 1.0, 1.0),
    tone: float = 1.0,
    noise: float = 0.0,
    jpeg: int = 0,
    rng: np.random.Generator | None = None,
) -> np.ndarray:
    """(h, w, 3) uint8 RGB -> the same scene as another exposure would have recorded it, uint8.

    The frame is taken back to linear light (sRGB-like gamma 2.2), scaled by `gain` and the white
    balance `wb` per channel, clipped (highlights burn out), re-encoded with gamma 2.2 * `tone`
    (another tone curve), then given sensor noise (sigma in grey levels) and JPEG at quality
    `jpeg` (0: none).
    """
    if rgb.ndim != 3 or rgb.shape[2] != 3 or rgb.dtype != np.uint8:
        raise ValueError(f"want an (h, w, 3) uint8 frame, got {rgb.shape} {rgb.dtype}")
    lin = (rgb.astype(np.float32) / 255.0) ** 2.2
    lin *= np.float32(gain) * np.asarray(wb, np.float32)[None, None, :]
    out = np.clip(lin, 0.0, 1.0) ** np.float32(1.0 / (2.2 * tone)) * 255.0
    if noise:
        gen = rng or np.random.default_rng(0)
        out += gen.normal(0.0, noise, out.shape).astype(np.float32)
    res: np.ndarray = np.clip(np.round(out), 0, 255).astype(np.uint8)
    if jpeg:
        ok, buf = cv2.imencode(".jpg", res[..., ::-1], [cv2.IMWRITE_JPEG_QUALITY, int(jpeg)])
        if not ok:
            raise RuntimeError("JPEG encoding failed")
        back = cv2.imdecode(buf, cv2.IMREAD_COLOR)
        if back is None:
            raise RuntimeError("JPEG decoding failed")
        res = back[..., ::-1].copy()
    return res


# ---- measuring a frame --------------------------------------------------------------------------
def _in_frame_polar(
    img: np.ndarray, ring: tuple[float, float, float, float], r0: float, r1: float, dr: float
) -> tuple[np.ndarray, np.ndarray]:
    """Polar resampling (rows: radius r0..r1 step dr; columns: azimuth, ~1 px apart at r1) of an
    image, keeping only the azimuths whose whole radial span lies inside the frame."""
    cx, cy = ring[0], ring[1]
    rr = np.arange(r0, r1, dr, dtype=np.float32)
    n = max(64, int(2 * np.pi * r1))
    pp = np.linspace(0, 2 * np.pi, n, endpoint=False, dtype=np.float32)
    mx = (cx + rr[:, None] * np.cos(pp)[None, :]).astype(np.float32)
    my = (cy + rr[:, None] * np.sin(pp)[None, :]).astype(np.float32)
    h, w = img.shape[:2]
    ok = ((mx >= 0) & (mx <= w - 1) & (my >= 0) & (my <= h - 1)).all(axis=0)
    pol = cv2.remap(img, mx[:, ok], my[:, ok], cv2.INTER_CUBIC)
    return pol, rr


def rim_profile(rgb: np.ndarray, ring: tuple[float, float, float, float]) -> dict[str, float]:
    """The fading outer rim of a (h, w, 3) RGB frame: where and how steeply the ring ends.

    Per azimuth the luminance across the rim is divided by its level just inside (u 0.90-0.93),
    over azimuths bright there (a dark object would fake a rim); medians over azimuths.
    Returns width (10-90 % of the fall, share of the ring), level at r_outer, B/G - 1 at r_outer.
    """
    cx, cy, r_in, r_out = ring
    width = r_out - r_in
    pol, rr = _in_frame_polar(rgb.astype(np.float32), ring, r_in + 0.85 * width, r_out + 0.05 * width, 0.5)
    u = (rr - r_in) / width
    ref = (u >= 0.90) & (u < 0.93)
    base = pol[ref].mean(axis=0)  # (cols, 3)
    good = base.mean(axis=-1) > 60
    lum = pol[:, good].mean(axis=-1) / base[good].mean(axis=-1)
    prof = np.median(lum, axis=1)
    bg = np.median(pol[:, good, 2] / np.maximum(pol[:, good, 1], 1.0), axis=1)
    bg_ref = float(np.median(bg[ref]))
    at = int(np.argmin(np.abs(u - 1.0)))
    bottom = float(prof[at])
    # 10 % and 90 % of the fall from 1 down to the level at r_outer, searching outwards
    fall = (1.0 - prof) / max(1.0 - bottom, 1e-6)
    cross = [float(np.interp(q, np.maximum.accumulate(fall[: at + 1]), u[: at + 1])) for q in (0.1, 0.9)]
    return {"width": cross[1] - cross[0], "level": bottom, "blue": float(bg[at]) / bg_ref - 1.0}


def radial_shift(
    rgb: np.ndarray, ring: tuple[float, float, float, float], bands: int = 3, span: float = 0.95
) -> np.ndarray:
    """(bands, 2): radial shift (px, + outwards) of red and of blue against green in each band of
    the ring's inner `span` (the rim's own fall and colour left out), by phase correlation of the
    radial gradients in polar coordinates: lateral chromatic aberration."""
    cx, cy, r_in, r_out = ring
    edges = np.linspace(r_in, r_in + span * (r_out - r_in), bands + 1)
    out = np.zeros((bands, 2))
    for i, (a, b) in enumerate(zip(edges[:-1], edges[1:], strict=True)):
        pol, _ = _in_frame_polar(rgb.astype(np.float32), ring, float(a), float(b), 0.5)
        g = [np.ascontiguousarray(np.diff(pol[..., c], axis=0)) for c in range(3)]
        win = cv2.createHanningWindow((g[1].shape[1], g[1].shape[0]), cv2.CV_32F)
        for j, c in enumerate((0, 2)):
            (_, dy), _ = cv2.phaseCorrelate(g[1], g[c], win)
            out[i, j] = 0.5 * dy
    return out


def edge_sigma(rgb: np.ndarray, ring: tuple[float, float, float, float], bands: int = 3) -> np.ndarray:
    """(bands,) blur (Gaussian sigma, px) at the edges of each band of the ring, by re-blurring:
    an edge blurred by sigma loses gradient by sqrt(1 + s0^2 / sigma^2) when blurred again by s0
    (Zhuo & Sim 2011); medians over strong edges. Compare frames by it, not absolute truth: Sobel's
    own smoothing and the image's sharpening enter both alike."""
    cx, cy, r_in, r_out = ring
    grey = cv2.cvtColor(np.clip(rgb, 0, 255).astype(np.uint8), cv2.COLOR_RGB2GRAY).astype(np.float32)
    s0 = 1.0

    def grad(x: np.ndarray) -> np.ndarray:
        g: np.ndarray = np.hypot(cv2.Sobel(x, cv2.CV_32F, 1, 0), cv2.Sobel(x, cv2.CV_32F, 0, 1))
        return g

    g1, g2 = grad(grey), grad(cv2.GaussianBlur(grey, (0, 0), s0))
    edge = cv2.Canny(grey.astype(np.uint8), 60, 150) > 0
    _, _, r, u = _polar((grey.shape[1], grey.shape[0]), ring)
    edges = np.linspace(0.0, 1.0, bands + 1)
    out = np.full(bands, np.nan)
    for i, (a, b) in enumerate(zip(edges[:-1], edges[1:], strict=True)):
        sel = edge & (u >= a) & (u < b) & (g1 > 40)
        ratio = g1[sel] / np.maximum(g2[sel], 1e-3)
        ratio = ratio[ratio > 1.01]
        if ratio.size >= 20:
            out[i] = float(np.median(s0 / np.sqrt(ratio**2 - 1.0)))
    return out


def noise_sigma(rgb: np.ndarray, mask: np.ndarray | None = None) -> float:
    """Noise sigma (grey levels) of a frame: Immerkaer's Laplacian-difference estimator over the
    flattest quarter of its pixels, flatness judged on a smoothed copy (judged on the frame itself,
    the noise would pick its own quietest pixels)."""
    grey = cv2.cvtColor(np.clip(rgb, 0, 255).astype(np.uint8), cv2.COLOR_RGB2GRAY).astype(np.float32)
    k = np.array([[1, -2, 1], [-2, 4, -2], [1, -2, 1]], np.float32)
    lap = np.abs(cv2.filter2D(grey, -1, k))
    smooth = cv2.GaussianBlur(grey, (0, 0), 2.0)
    g = np.hypot(cv2.Sobel(smooth, cv2.CV_32F, 1, 0), cv2.Sobel(smooth, cv2.CV_32F, 0, 1))
    m = np.ones(g.shape, bool) if mask is None else mask
    sel = m & (g <= np.percentile(g[m], 25))
    return float(math.sqrt(math.pi / 2) * lap[sel].mean() / 6.0)
