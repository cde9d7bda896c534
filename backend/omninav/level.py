"""Levelling: undo a tilted lens from the picture itself, before the curves are summed.

A phone is never held level, and a clip-on donut leans with it: the band of elevations the curves
sum over then rises on one side of the panorama and falls on the other, and the curves change
with how the phone is held rather than with where it is. Five 10-degree bands feel that more than
two wide ones did: tilted 5 degrees, the right place's score falls from 1 to 0.956 on average (8
degrees: 0.911; docs/benchlog.md, "Levelling"; levelled, 0.992 and 0.991).

Why from the picture and not from the phone's gravity: which way the lens's axis and its image
axes sit in the phone's frame depends on the phone, the clip-on and the browser, none of which
the app can check; a wrong sign would double the tilt. The picture shows the tilt by itself. A
building's vertical edges (door frames, corners, pillars) stand upright in a level panorama; a
lens tilted by t towards azimuth d leans the edge at azimuth a by about
t * sin(d - a) / cos^2(el) degrees of azimuth per degree of elevation. So:

  1. `edge_lean`: on the band's intensity at one column a degree (`estimate_map`: a quarter of
     the band panorama's columns, for the phone's sake), the lean of every strong near-vertical edge
     pixel (-dI/d_el over dI/d_az; the strongest tenth of the horizontal gradients, leaning
     less than LEAN_MAX), fit by weighted least squares as (a sin az + b cos az) / cos^2 el;
  2. `lean_tilt`: (a, b) -> the tilt and the azimuth it leans towards;
  3. `tilted_map`: a remap through that tilt (each panorama direction of the upright world looked
     up where the tilt turned it; a direction the donut does not see reads its upright cell);
  4. `level_map`: steps 1-3 `level_iters` times, each on the panorama the last estimate levelled,
     then the band panorama's own remap through the tilt found. One pass finds about three
     quarters of the tilt (the leans' noise pulls a least-squares slope towards zero); the next
     pass fits what is left. A frame with too few edges (a blank wall, a lens cap) keeps the
     upright map.

Measured on the renderer's tilted frames: under a degree left of tilts up to 8 degrees after
two passes, about what a phone's gravity would give (tests/engine/test_level.py). Small pure
functions, NumPy: the phone's worker (web/src/worker/level.ts) does the same arithmetic, in
doubles, on the same panorama bytes.
"""

from __future__ import annotations

import functools
import math
from typing import Any

import numpy as np

from .curves import circular_diff
from .lens import Catadioptric, Lens, direction_to_pixel
from .unwarp import UnwarpMap, band_map, unwarp

LEAN_PERCENTILE = 90.0  # the strongest tenth of the horizontal gradients: the edges whose lean counts
LEAN_MAX = 0.5  # an edge leaning more than this (deg of azimuth per deg of elevation) is not upright
MIN_EDGES = 200  # fewer edge pixels than this: no estimate (the map stays upright)
MAX_TILT_DEG = 15.0  # a larger estimate is capped: nobody films a corridor held further off
ANCHOR_DEG = 2.0  # tilted_map turns a map exactly at columns this many degrees apart ...
JUMP_PX = 64.0  # ... and cell by cell between two whose pixels lie further apart than this


def intensity(pano: np.ndarray) -> np.ndarray:
    """(rows, cols, 3 or 4) panorama -> (rows, cols) float64 mean of its first three channels (of
    uint8 bytes, summed in 16 bits: exact, so the same bits as a float64 sum's)."""
    if pano.dtype != np.uint8:
        flt: np.ndarray = pano[..., :3].astype(np.float64).sum(axis=-1) / 3.0
        return flt
    total = pano[..., 0].astype(np.uint16) + pano[..., 1] + pano[..., 2]
    out: np.ndarray = total / 3.0
    return out


def edge_lean(gray: np.ndarray, elevations: np.ndarray, valid: np.ndarray) -> tuple[float, float, int]:
    """(rows, cols) intensity of a band panorama (rows: `elevations`, descending; columns: azimuths
    (j + 0.5) * 360 / cols) -> (a, b, n): its upright edges' lean fit as (a sin az + b cos az) /
    cos^2 el (degrees of azimuth per degree of elevation), from n edge pixels (0: no fit)."""
    rows, cols = gray.shape
    if rows < 3:
        return 0.0, 0.0, 0
    daz = 360.0 / cols
    d_el = float(elevations[0] - elevations[1])
    gx = circular_diff(gray) / (2.0 * daz)
    gy = np.zeros_like(gray)
    gy[1:-1] = (gray[:-2] - gray[2:]) / (2.0 * d_el)  # d/d(elevation): the row above is higher
    ok = valid.copy()  # and both neighbours along the row (it wraps)
    ok[:, 1:] &= valid[:, :-1]
    ok[:, :1] &= valid[:, -1:]
    ok[:, :-1] &= valid[:, 1:]
    ok[:, -1:] &= valid[:, :1]
    ok[0] = ok[-1] = False
    ok[1:-1] &= valid[:-2] & valid[2:]
    w = gx * gx
    if ok.sum() < MIN_EDGES:
        return 0.0, 0.0, 0
    thr = float(np.percentile(w[ok], LEAN_PERCENTILE))
    sel = ok & (w >= thr) & (w > 0) & (np.abs(gy) < LEAN_MAX * np.abs(gx))
    n = int(sel.sum())
    if n < MIN_EDGES:
        return 0.0, 0.0, 0
    r, c = np.nonzero(sel)
    lean = -gy[sel] / gx[sel]
    c2 = np.cos(np.deg2rad(elevations[r].astype(np.float64))) ** 2
    az = np.deg2rad((c + 0.5) * daz)
    # weighted least squares (weights gx^2) by its 2x2 normal equations, as the phone solves them
    ww = w[sel]
    u, v = np.sin(az) / c2, np.cos(az) / c2
    suu, suv, svv = float((ww * u * u).sum()), float((ww * u * v).sum()), float((ww * v * v).sum())
    su, sv = float((ww * u * lean).sum()), float((ww * v * lean).sum())
    det = suu * svv - suv * suv
    if not det > 1e-12 * max(suu * svv, 1e-300):
        return 0.0, 0.0, 0
    return (svv * su - suv * sv) / det, (suu * sv - suv * su) / det, n


def lean_tilt(a: float, b: float) -> tuple[float, float]:
    """edge_lean's (a, b) -> (tilt in degrees, the camera azimuth it leans towards, degrees)."""
    return math.degrees(math.hypot(a, b)), math.degrees(-math.atan2(b, a)) % 360.0


def tilt_rotation(tilt_deg: float, toward_deg: float) -> np.ndarray:
    """3x3 rotation of camera-frame vectors (forward, right, up) by `tilt_deg` towards camera
    azimuth `toward_deg` (Rodrigues' formula about the horizontal axis square to it)."""
    t = math.radians(tilt_deg)
    a = math.radians(toward_deg + 90.0)
    k = np.array([math.cos(a), math.sin(a), 0.0])
    kx = np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])
    rot: np.ndarray = math.cos(t) * np.eye(3) + math.sin(t) * kx + (1.0 - math.cos(t)) * np.outer(k, k)
    return rot


@functools.lru_cache(maxsize=16)
def _directions(elevations: bytes, cols: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The unit vectors of a band panorama's cells (rows: float32 `elevations`), once per map."""
    el = np.frombuffer(elevations, np.float32).astype(np.float64)
    az = (np.arange(cols, dtype=np.float64) + 0.5) * 360.0 / cols
    azg, elg = np.meshgrid(az, el)
    a, e = np.deg2rad(azg), np.deg2rad(elg)
    return np.cos(e) * np.cos(a), np.cos(e) * np.sin(a), np.sin(e)


def tilted_map(lens: Lens, upright: UnwarpMap, rot: np.ndarray) -> UnwarpMap:
    """The remap `upright` through a tilt: each panorama direction (azimuth, elevation) of the
    upright world, turned into the tilted camera's frame, looked up through the lens. Where that
    direction lies outside what the lens sees (a narrow donut's band reaches its ring's edge), the
    cell reads what it read upright: the tilt is left there, not turned into black or a smear of
    the ring's edge, which both differ from the upright venue more than the tilt does.

    The map is turned exactly at every column ANCHOR_DEG apart (`anchor_step`: the band's eighth,
    the coarse map's second) and linearly between (`_between`): over two degrees of azimuth the
    ring leaves a straight line by under 0.08 px (0.05 px level, at r = 340 px; on the renderer's
    walk panorama bytes move by up to 9 levels, spectra by 0.3 %, and no answer of the three
    sources got worse), at a fraction of the cost (levelling's largest: docs/decisions.md,
    "Levelling's maps"). A stretch whose ends are not both seen, or lie more than JUMP_PX
    apart (the 360 camera's seam), is turned cell by cell.
    """
    w0, w1, w2 = _directions(np.asarray(upright.elevations, np.float32).tobytes(), upright.map_x.shape[1])
    step = anchor_step(w0.shape[1])
    x, y = _turned(lens, rot, w0[:, ::step], w1[:, ::step], w2[:, ::step])  # NaN where the donut does not see
    if step == 1:
        x, y = _seen_or(x, y, upright.map_x, upright.map_y)
    else:
        x, y, redo = _between(x, y, step)
        if redo[0].size:  # the stretches not filled: cell by cell
            ex, ey = _turned(lens, rot, w0[redo], w1[redo], w2[redo])
            x[redo], y[redo] = _seen_or(ex, ey, upright.map_x[redo], upright.map_y[redo])
    return UnwarpMap(x, y, upright.elevations, upright.valid, upright.border)


def _seen_or(x: np.ndarray, y: np.ndarray, ux: np.ndarray, uy: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Turned pixels (NaN: not seen) -> float32 tables, an unseen cell reading its upright one."""
    ok = np.isfinite(x) & np.isfinite(y)
    return np.where(ok, x, ux).astype(np.float32), np.where(ok, y, uy).astype(np.float32)


def anchor_step(cols: int) -> int:
    """Columns from one exactly turned column to the next in a map `cols` wide: ANCHOR_DEG's worth
    where that is more than one and divides the columns, else 1 (every column exact)."""
    step = int(cols * ANCHOR_DEG / 360.0)
    return step if step > 1 and cols % step == 0 else 1


def _between(ax: np.ndarray, ay: np.ndarray, step: int) -> tuple[np.ndarray, np.ndarray, tuple[np.ndarray, ...]]:
    """(rows, n) float64 pixels of every `step`-th column (NaN: not seen) -> (rows, n * step)
    float32 tables, each column linear from its anchor to the next (the last to the first:
    azimuth wraps), as a + (b - a) * (s / step) in float64; and the (row, column) indices of the
    stretches left to tilted_map: those whose ends are not both seen or lie more than JUMP_PX
    apart."""
    bx, by = np.roll(ax, -1, axis=1), np.roll(ay, -1, axis=1)
    dx, dy = bx - ax, by - ay
    with np.errstate(invalid="ignore"):
        bad = ~((np.abs(dx) <= JUMP_PX) & (np.abs(dy) <= JUMP_PX))  # (NaN compares False)
    r, m = np.nonzero(bad)
    redo = (np.repeat(r, step), (m[:, None] * step + np.arange(step)).ravel())
    return _fill(ax, dx, step), _fill(ay, dy, step), redo


def _fill(a: np.ndarray, d: np.ndarray, step: int) -> np.ndarray:
    """(rows, n) anchors and their differences to the next -> (rows, n * step) float32, column
    m * step + s being a + d * (s / step), in float64 and then rounded (the worker's order)."""
    rows, n = a.shape
    out = np.empty((rows, n * step), np.float32)
    for s in range(step):
        out[:, s::step] = a + d * (s / step)
    return out


def _turned(
    lens: Lens, rot: np.ndarray, w0: np.ndarray, w1: np.ndarray, w2: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Unit vectors (w0, w1, w2) of upright panorama cells -> the pixels that see them tilted by
    `rot` (NaN where the lens does not)."""
    # each direction times rot (rot's transpose applied: the tilt undone), term by term as the
    # phone's worker sums it
    c0 = w0 * rot[0, 0] + w1 * rot[1, 0] + w2 * rot[2, 0]
    c1 = w0 * rot[0, 1] + w1 * rot[1, 1] + w2 * rot[2, 1]
    c2 = w0 * rot[0, 2] + w1 * rot[1, 2] + w2 * rot[2, 2]
    return _turned_pixels(lens, c0, c1, c2)


def _turned_pixels(lens: Lens, c0: np.ndarray, c1: np.ndarray, c2: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Pixels (x, y) that see the unit vectors (c0, c1, c2) of the camera's frame (forward, right,
    up): direction_to_pixel of their azimuth and elevation.

    Notes
    -----
    A donut's pixel is centre + r(el) (cos phi, sin phi) with phi = forward + sign * azimuth; the
    azimuth's cosine and sine are c0 / h and c1 / h (h the horizontal length), so no arctan2, cos
    or sin is taken per cell: the same point to a few units in the last place, and the phone's
    worker (level.ts `tiltInto`) turns it term by term the same way. A 360 camera's column is
    linear in the azimuth itself.
    """
    el = np.rad2deg(np.arcsin(np.clip(c2, -1.0, 1.0)))
    if not isinstance(lens, Catadioptric):
        return direction_to_pixel(lens, np.mod(np.rad2deg(np.arctan2(c1, c0)), 360.0), el)
    r = lens.radius(el)
    h = np.sqrt(c0 * c0 + c1 * c1)
    up = h > 0  # not straight up or down: there the azimuth is 0, as arctan2(0, 0) says
    if up.all():
        ca, sa = c0 / h, c1 / h
    else:
        hh = np.where(up, h, 1.0)
        ca, sa = np.where(up, c0 / hh, 1.0), np.where(up, c1 / hh, 0.0)
    sign = -1.0 if lens.ccw else 1.0
    f = math.radians(lens.forward_deg)
    cf, sf = math.cos(f), math.sin(f)
    return lens.pixel(r * (cf * ca - sign * sf * sa), r * (sf * ca + sign * cf * sa))


def level_map(
    frame: np.ndarray, lens: Lens, upright: UnwarpMap, coarse: UnwarpMap, iters: int
) -> tuple[UnwarpMap, float, float]:
    """(H, W, 3) frame -> (the band remap that levels it, the tilt found, its azimuth): the tilt
    estimate_tilt finds, then `upright` through it (0 passes, or no edges: `upright`)."""
    vx, vy = estimate_tilt(frame, lens, coarse, iters)
    if vx == 0.0 and vy == 0.0:
        return upright, 0.0, 0.0
    return tilted_map(lens, upright, _rotation(vx, vy)), math.hypot(vx, vy), math.degrees(math.atan2(vy, vx)) % 360.0


def estimate_tilt(frame: np.ndarray, lens: Lens, coarse: UnwarpMap, iters: int) -> tuple[float, float]:
    """(H, W, 3) frame -> its tilt as a vector (degrees, x and y as lean_tilt's azimuth turns
    them): `iters` passes of edge_lean, each on the panorama the estimate so far levels, read
    through `coarse` (the band's rows at one column a degree, estimate_map: a quarter of the work,
    the same tilt to a tenth of a degree). (0, 0): no pass, or no edges. tilt_map turns a remap
    through it."""
    m, vx, vy = coarse, 0.0, 0.0
    for k in range(iters):
        a, b, n = edge_lean(intensity(unwarp(frame, m)), coarse.elevations, m.valid)
        if n == 0:
            break
        t, d = lean_tilt(a, b)
        vx += t * math.cos(math.radians(d))
        vy += t * math.sin(math.radians(d))
        scale = min(1.0, MAX_TILT_DEG / max(math.hypot(vx, vy), 1e-9))
        vx, vy = vx * scale, vy * scale
        if k + 1 < iters:
            m = tilted_map(lens, coarse, _rotation(vx, vy))
    return vx, vy


def tilt_map(lens: Lens, m: UnwarpMap, tilt: tuple[float, float]) -> UnwarpMap:
    """`m` through an estimate_tilt vector (`m` itself for (0, 0)): what level_map does with it."""
    return m if tilt == (0.0, 0.0) else tilted_map(lens, m, _rotation(*tilt))


def _rotation(vx: float, vy: float) -> np.ndarray:
    """The rotation of a tilt vector (degrees, towards its angle as atan2 gives it)."""
    return tilt_rotation(math.hypot(vx, vy), math.degrees(math.atan2(vy, vx)))


def estimate_map(lens: Lens, conf: dict[str, Any]) -> UnwarpMap:
    """The remap the tilt is estimated through: the band panorama's rows at one column a degree
    (the preset's pano_width, where the band panorama has `oversample` times as many)."""
    return band_map(lens, {**conf, "oversample": 1})
