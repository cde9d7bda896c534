"""Find the donut ring (centre, inner and outer radius) in ordinary frames, without any target.

THE ALGORITHM (the browser's worker ports this text; Python and TypeScript must agree within 0.5 px)
====================================================================================================
Pixel coordinates: x right, y down, pixel (i, j) has its centre at x = i, y = j (the image spans
-0.5 .. w - 0.5). Rounding is floor(v + 0.5) everywhere. Angles are atan2(dy, dx) in radians.
The cosine and sine of the fixed angles (the bins, profiles and visibility points below) are
rounded to multiples of 2^-40, floor(v 2^40 + 0.5) / 2^40, and lengths are sqrt(dx^2 + dy^2), never
hypot: the C library and the browser's Math differ in the last bit there, and on a real picture's
smooth ramp, where several samples of a profile's derivative tie, a last bit decides which is first.
Only OpenCV operations that opencv.js has are used (cvtColor, resize INTER_AREA, GaussianBlur,
Sobel, Canny), the rest is plain loops over arrays; no randomness.

A. Coarse stage, on a copy whose longer side is at most COARSE_MAX = 640 px.
 1. grey = cvtColor(frame, BGR2GRAY) (RGBA2GRAY in the browser: the same weights), uint8.
 2. f = min(1, 640 / max(w, h)); cw = floor(w f + 0.5), ch = floor(h f + 0.5); if f < 1:
    small = resize(grey, (cw, ch), INTER_AREA), else small = grey. Per-axis scales sx = cw / w,
    sy = ch / h; a coarse point (u, v) is the full-resolution point ((u + 0.5) / sx - 0.5,
    (v + 0.5) / sy - 0.5).
 3. blur = GaussianBlur(small, ksize 5x5, sigma 1.5, BORDER_DEFAULT); gx, gy = Sobel(blur,
    CV_32F, dx/dy = 1, ksize 3); edges = Canny(blur, 20, 50, aperture 3, L2gradient false).
 4. Edge points: every pixel with edges != 0 and g = sqrt(gx^2 + gy^2) > 0, in row-major order, with
    its unit gradient (ux, uy) = (gx, gy) / g (it points towards the brighter side).
 5. Centre votes (a Hough transform along gradients): the outer edge of the ring is brighter on
    its inside, so its gradient points at the centre. Radii rmin = floor(0.15 min(cw, ch) + 0.5),
    rmax = floor(0.6 max(cw, ch) + 0.5). For every VOTE_EVERY = 3rd edge point (indices 0, 3,
    6, ... of the row-major list) and every k = rmin, rmin + VOTE_STEP, ... <= rmax (VOTE_STEP = 3):
    (a, b) = (floor(x + k ux + 0.5), floor(y + k uy + 0.5)); if 0 <= a < cw and 0 <= b < ch:
    acc[b, a] += 1 (ch x cw counts).
 6. accB = the VOTE_BOX x VOTE_BOX (15 x 15, centred) box sum of acc, cells off the image counting
    0; (a0, b0) = its first maximum in row-major order. No ring if that maximum < MIN_VOTES = 30.
    (The votes of a ring make a blob a few pixels wide, gradient directions being a degree or
    two off: the wide box finds its middle, a 3x3 one lands anywhere on it under noise.)
 7. Outer circle around a centre (a, b) with a radius window W (OUTER_WINDOWS: run twice, W = 3
    around (a0, b0), then W = 1 around the centre of a circle the first run found). For every
    edge point with d = sqrt((x - a)^2 + (y - b)^2) > 0: the radial cosine c = (ux (x - a) +
    uy (y - b)) / d; the point is "inward" if c < -RADIAL_COS (RADIAL_COS = 0.9: brighter towards
    the centre), "outward" if c > RADIAL_COS. Its angle bin is
    n = floor(mod(atan2(y - b, x - a), 2 pi) / (2 pi) * 360) (clamped to 0..359), its radius bin
    q = floor(d + 0.5); hit[q][n] = true for the inward points.
    For each integer r from max(rmin, W + 1) to rmax: a bin n is visible if its point
    (a + r cos t, b + r sin t), t = (n + 0.5) 2 pi / 360, lies in -0.5 <= x <= cw - 0.5 and
    -0.5 <= y <= ch - 0.5; vis(r) = visible bins; cov(r) = visible bins with hit[q][n] for some
    q in r - W .. r + W; score(r) = cov(r) / vis(r), 0 when vis(r) < 36 (a tenth of the circle).
    best = max score; no ring if best < MIN_COVERAGE = 0.5. The candidates are the r with
    score(r) >= OUTER_PICK (0.8) * best that are local maxima (score(r) >= score(r - 1) and
    >= score(r + 1), a missing neighbour counting as -1), SMALLEST first, and of consecutive such
    r only the first (a plateau is one candidate): a bright plastic rim further out is as
    complete a circle, but never inside the ring. A candidate's circle: the
    inward points with |d - r| <= W + 1 (at least 20, else it has none) -> algebraic circle fit
    (B3). The first run's candidates are taken in turn, skipping those without a circle: the
    second run around a candidate's centre gives the circle (a1, b1, r1') of its own first
    candidate, or, when that has no circle, the next candidate of the first run is tried (a circle
    of the scene just inside the ring, fitted on its arcs, can put the centre a few pixels off the
    ring's, where the narrow window no longer sees the ring). No ring when none gives one.
 8. Inner circle around (a1, b1) (A9's circle, after A9): the "outward" points of A7 (a dark
    centre: brighter outwards), r from max(lo, W + 1) to hi, lo = floor(0.1 r1 + 0.5), hi =
    floor(0.9 r1 + 0.5) (only if lo >= 1 and hi > lo + 2), with the window W = INNER_WINDOW (3: a
    mirror's dark centre can sit a few pixels off its rim's centre) and score(r) = cov(r) / vis(r)
    / fill(r), fill(r) = min(1, 2 pi r / N_BINS): a circle of radius r crosses about 2 pi r of the
    bins, one an edge pixel, so a small dark centre could never fill half of them (the score may
    pass 1). Candidates: the r whose score >= MIN_COVERAGE is a local maximum (as A7) and that are
    dark inside: at INNER_DARK (0.75) of the N_BINS angles t_n whose two pixels (u, v) = (floor(a1
    + q cos t_n + 0.5), floor(b1 + q sin t_n + 0.5)) at q = r + W + 2 and q = max(0, r - W - 2) lie
    in the image (at least 36 of them), blur (A3) is brighter at the outer by more than INNER_STEP
    (4 grey levels) (a scene's own circles, a floor's tiles under a fisheye, are brighter outwards
    at some angles only). The chosen r: the largest candidate at most s + gap (s the start of A9's
    scene run around (a1, b1), gap of A9's; any candidate without a run): the scene begins at the
    dark centre's edge, and circles further in are the camera's reflection, the mirror's post or a
    lens barrel; when none is, the smallest candidate (a dim scene's texture starts further out).
    The inner circle (a2, b2, r2): the algebraic fit (B3) of the outward points with |d - r| <=
    W + 1 (at least 20, else none). Without one, the same again with the edge points of a fainter
    Canny(blur, 8, 20) (CANNY_FAINT: a dim scene's inner edge); else r2 = 0 (no inner circle: a
    fisheye, not a failure).
 9. Which annulus holds the scene (A9, around (a1, b1) of A7, before A8): a housing, its rim or a
    bright surround makes circles as complete as the mirror's edge, but only the scene has texture
    *along* the circle. The texture T(r), for r = 0 .. floor(r1 + 3 + gap): at the N_BINS angles
    t_n = (n + 0.5) 2 pi / 360 the pixel (u, v) = (floor(a1 + r cos t_n + 0.5), floor(b1 + r sin t_n
    + 0.5)), where 0 <= u < cw and 0 <= v < ch, gives |-sin t_n gx(u, v) + cos t_n gy(u, v)| (gx, gy of
    A3); T(r) = their mean over those angles, undefined when fewer than 36. Ts(r) = the mean of the
    defined T over r - 2 .. r + 2 (undefined when none). rp = the first r >= 1 of the largest Ts,
    P = Ts(rp); the scene runs from s down and e up from rp while Ts >= SCENE_SHARE (0.3) * P (an
    undefined Ts ends the run). gap = 0.05 r1 + 3.
    - Outer: if r1 - e > gap, the circle at r1 lies outside the scene (a housing). Around (a1, b1),
      for each kind of radial edge point (inward: the surround darker; outward: brighter) the
      coverage with window 1 (as A7) at each integer r from max(2, floor(e - gap)) to
      floor(r1 - gap) (the scene's texture fades before its edge where the mirror vignettes). The
      best of the two (first maximum, inward first on a tie) replaces the circle if its score >=
      MIN_COVERAGE and at least 20 points of that kind lie within 2 px of its radius: their
      algebraic circle fit is the new (a1, b1, r1), the old r1 is reported as the housing, and
      stage B's sign for the outer edge is that kind's (-1 inward, +1 outward); the surround is
      "darker" or "brighter" accordingly.
    - A8 then looks for the inner edge around the circle A9 kept (around the mirror's edge rather
      than the housing's, it finds the dark centre there, not the mirror's edge).
    - texture_ratio = the median of the defined T over [r2, r1] (over [s, r1] when r2 = 0, s the
      scene's start recomputed around A9's circle) divided by max(TEXTURE_FLOOR, the median over
      r1 + 3 .. r1 + 3 + gap) (the surround; TEXTURE_FLOOR = 0.05: a flat, clipped surround is
      the clearest case, not a missing one), or 0 when no surround lies in the picture: how
      clearly the annulus called the scene stands out from what surrounds it.

B. Sub-pixel stage, at full resolution.
 1. fine = GaussianBlur(grey, 5x5, sigma 1.0, BORDER_DEFAULT) (uint8 in, uint8 out), then read as
    float; centre (cx, cy) and radii R from A (coarse -> full as in A2, radii divided by
    (sx + sy) / 2).
 2. Radial profiles: for each circle (outer: sign -1, inner: sign +1) and each of N_PROFILES = 360
    angles t_k = 2 pi k / 360: n = 2 H / 0.25 + 1 samples at s_j = -H + 0.25 j, j = 0..n-1 (the
    half width H = 6 px on the first pass, 3 px on the second) at (cx + (R + s_j) cos t_k,
    cy + (R + s_j) sin t_k); the angle is left out (not "in the image") if any of its samples lies
    outside 0 <= x <= w - 1, 0 <= y <= h - 1. Values I_j by bilinear interpolation of fine.
    D_j = (I_{j+1} - I_{j-1}) / 0.5 for j = 1..n-2; e_j = sign * D_j (the outer edge gets darker
    outwards, the inner edge brighter). j* = the first j with the largest e_j; the angle gives no
    point if e_j* < MIN_EDGE = 2.0 grey levels / px or j* is 1 or n-2 (the window's ends).
    Parabolic peak: A, B, C = e_{j*-1}, e_j*, e_{j*+1}, den = A - 2B + C, delta = 0.5 (A - C) / den
    if den < 0 else 0, clamped to [-0.5, 0.5]; the point is at radius R + s_j* + 0.25 delta along
    angle t_k from (cx, cy).
 3. Circle fit of points: algebraic (Kasa: least squares of x^2 + y^2 + D x + E y + F = 0, solved
    about the points' mean for conditioning -> centre (-D/2, -E/2), radius sqrt(cx^2 + cy^2 - F)),
    then geometric Gauss-Newton from it (residual e_i = sqrt((x_i - cx)^2 + (y_i - cy)^2) - r, Jacobian
    rows (-(x_i - cx)/d_i, -(y_i - cy)/d_i, -1); 3x3 normal equations; at most 20 steps, stopping
    after a step whose largest component is < 1e-6). Then twice: e_i = |residual| of every point
    to the current circle, sigma = max(0.05, 1.4826 * median of e_i over the points still kept);
    keep only the kept points with e_i <= 3 sigma; refit them (algebraic, then geometric).
 4. Outer circle: pass 1 = B2 (H = 6, the sign of A9: -1 unless A9 chose an edge with a brighter
    surround) around the circle from A (full resolution), then B3; pass 2
    = B2 (H = 3) around pass 1's circle, then B3. In each pass, no ring if the profiles gave
    fewer than max(20, MIN_SHARE * m) points or the fit kept fewer than that (MIN_SHARE = 0.5,
    m = the number of that pass's angles in the image). The kept points of pass 2 are the outer
    edge points (for the ellipse check).
 5. Inner circle (only if A gave r2 > 0): the same two passes with sign +1, the first around A8's
    circle (a2, b2, r2), converted as B1, the second around the first's, each fitted as B3 (its
    own centre: a decentred mirror's dark centre sits a few pixels off its rim's); a fit whose
    centre lies more than INNER_OFFSET (0.25) of its radius from the outer circle's final centre
    gives none, as does a pass that falls short as in B4 (r_inner = 0). r_inner = the second
    pass's radius. The ring keeps the outer circle's centre (the outer edge is the longer, sharper
    one); the dark centre's own centre is not reported.
 6. Radius convention: the radii are where the intensity crosses half way between the ring and
    its surround (the strongest derivative). EDGE_BIAS_PX = 0.0 would be subtracted from r_outer
    and added to r_inner: on the renderer's hard-edged rings (a pixel is on the ring when its
    centre is within [r_inner, r_outer]) under synth/clipon.py's surround the crossing is
    within 0.1 px of the true radius (measured: r_outer -0.05 px, r_inner +0.03 px, both pulled
    into the ring by the vignetting's slope), so there is nothing to correct.
 7. visible = the share of N_VISIBLE = 3600 points (cx + r_outer cos t, cy + r_outer sin t),
    t = 2 pi (k + 0.5) / 3600, with -0.5 <= x <= w - 0.5 and -0.5 <= y <= h - 0.5.

C. Over frames (`find_ring`): first the majority of the frames with a ring, by whether A9 took a
   circle for the housing or not (on a tie, those that did not: the two see different circles); then
   the median of cx, cy, r_outer over those frames, and of
   r_inner over those of them with r_inner > 0 (r_inner = 0 when those are fewer than half);
   `spread` = the standard deviations over the same frames (population, ddof 0), center_px =
   sqrt(std_x^2 + std_y^2). Over the same frames: the surround is "brighter" when more than half
   of them say so, texture_ratio is the median, and the housing the median of the nonzero
   housings when more than half of all the frames have one (else 0). frames_used counts them all.
   Fewer than half the frames with a ring: NoRing. `ellipse_ratio`: the median over frames of the
   major / minor axis of cv2.fitEllipse on the kept outer edge points (1.0 for a circle).
====================================================================================================

`lens_fit.fit_lens` then says whether a lens profile still fits the ring a video shows, and corrects it
when the lens was clipped on a few pixels off (calib/README.md; the decisions of issue 12).
"""

from __future__ import annotations

import dataclasses
import json
import math
from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from ..errors import OmninavError, Unusable, finite

# The constants, shared with the phone's port (web/src/worker/ring.ts) through one file:
# ring_constants.json. What each does is in the docstring above.
CONSTANTS: dict[str, Any] = json.loads((Path(__file__).parent / "ring_constants.json").read_text())
COARSE_MAX = int(CONSTANTS["COARSE_MAX"])
COARSE_SIGMA = float(CONSTANTS["COARSE_SIGMA"])
CANNY: tuple[int, int] = (int(CONSTANTS["CANNY"][0]), int(CONSTANTS["CANNY"][1]))
CANNY_FAINT: tuple[int, int] = (int(CONSTANTS["CANNY_FAINT"][0]), int(CONSTANTS["CANNY_FAINT"][1]))
VOTE_STEP = int(CONSTANTS["VOTE_STEP"])
VOTE_EVERY = int(CONSTANTS["VOTE_EVERY"])
VOTE_BOX = int(CONSTANTS["VOTE_BOX"])
OUTER_WINDOWS: tuple[int, ...] = tuple(int(v) for v in CONSTANTS["OUTER_WINDOWS"])
MIN_VOTES = int(CONSTANTS["MIN_VOTES"])
RADIAL_COS = float(CONSTANTS["RADIAL_COS"])
N_BINS = int(CONSTANTS["N_BINS"])
MIN_COVERAGE = float(CONSTANTS["MIN_COVERAGE"])
OUTER_PICK = float(CONSTANTS["OUTER_PICK"])
FINE_SIGMA = float(CONSTANTS["FINE_SIGMA"])
N_PROFILES = int(CONSTANTS["N_PROFILES"])
PROFILE_STEP = float(CONSTANTS["PROFILE_STEP"])
MIN_EDGE = float(CONSTANTS["MIN_EDGE"])
MIN_SHARE = float(CONSTANTS["MIN_SHARE"])
EDGE_BIAS_PX = float(CONSTANTS["EDGE_BIAS_PX"])
N_VISIBLE = int(CONSTANTS["N_VISIBLE"])
MIN_SIDE = int(CONSTANTS["MIN_SIDE"])
SCENE_SHARE = float(CONSTANTS["SCENE_SHARE"])
SCENE_SMOOTH = int(CONSTANTS["SCENE_SMOOTH"])
GAP: tuple[float, float] = (float(CONSTANTS["GAP"][0]), float(CONSTANTS["GAP"][1]))
TEXTURE_FLOOR = float(CONSTANTS["TEXTURE_FLOOR"])
# texture_ratio below it: the annulus called the scene hardly stands out (unsure)
SURE_TEXTURE = float(CONSTANTS["SURE_TEXTURE"])
INNER_WINDOW = int(CONSTANTS["INNER_WINDOW"])
INNER_OFFSET = float(CONSTANTS["INNER_OFFSET"])
INNER_DARK = float(CONSTANTS["INNER_DARK"])
INNER_STEP = float(CONSTANTS["INNER_STEP"])


def _dist(dx: np.ndarray, dy: np.ndarray) -> np.ndarray:
    """sqrt(dx^2 + dy^2): every distance of the algorithm, as the phone's port sums it (hypot()
    differs between the C library and the browser in the last bit)."""
    out: np.ndarray = np.sqrt(dx * dx + dy * dy)
    return out


def unit_circle(n: int, half: bool) -> tuple[np.ndarray, np.ndarray]:
    """cos and sin of 2 pi (k + 0.5 if half else k) / n, k = 0 .. n - 1, rounded to multiples of
    2^-40 (the docstring above says why), as the phone's port computes them."""
    key = (n, half)
    got = _UNIT.get(key)
    if got is None:
        t = 2.0 * np.pi * (np.arange(n) + (0.5 if half else 0.0)) / n
        got = (np.floor(np.cos(t) * 2.0**40 + 0.5) / 2.0**40, np.floor(np.sin(t) * 2.0**40 + 0.5) / 2.0**40)
        for a in got:
            a.flags.writeable = False  # shared by every caller
        _UNIT[key] = got
    return got


_UNIT: dict[tuple[int, bool], tuple[np.ndarray, np.ndarray]] = {}


class NoRing(Unusable):
    """No donut ring in the frames: no lens attached, the lens covered, or an ordinary photo."""


@dataclass(frozen=True)
class Ring:
    """The donut ring in full-resolution pixels (see the module docstring for how it is found)."""

    image_size: tuple[int, int]  # (w, h)
    center: tuple[float, float]
    r_inner: float
    r_outer: float
    visible: float  # share of the outer circle inside the image
    frames_used: int = 1
    frames_total: int = 1
    spread: dict[str, float] | None = None  # std over frames: "center_px", "r_inner_px", "r_outer_px"
    ellipse_ratio: float = 1.0  # major / minor axis of an ellipse fitted to the outer edge
    surround: str = "darker"  # outside the outer edge: "darker", or "brighter" (a bright housing, a wall)
    housing: float = 0.0  # radius of a complete circle outside the scene taken for the housing (0: none)
    texture_ratio: float = 0.0  # the scene annulus's texture over its surround's (0: no surround seen)
    points: np.ndarray | None = dataclasses.field(default=None, repr=False, compare=False)  # (n, 2) outer edge

    def to_dict(self) -> dict[str, Any]:
        """ring.json: what `omninav calib ring` writes."""
        return {
            "image_size": list(self.image_size),
            "center": [round(self.center[0], 3), round(self.center[1], 3)],
            "r_inner": round(self.r_inner, 3),
            "r_outer": round(self.r_outer, 3),
            "visible": round(self.visible, 4),
            "frames_used": self.frames_used,
            "frames_total": self.frames_total,
            "spread": {k: round(v, 3) for k, v in (self.spread or {}).items()},
            "ellipse_ratio": round(self.ellipse_ratio, 4),
            "surround": self.surround,
            "housing": round(self.housing, 3),
            "texture_ratio": round(self.texture_ratio, 3),
        }


def ring_from_dict(d: Any, where: str = "ring") -> Ring:
    """A ring.json (as `calib ring -o` writes it, or typed by hand from a frame: `image_size`,
    `center`, `r_outer`, optionally `r_inner`) -> Ring; every problem names its field."""
    if not isinstance(d, dict):
        raise OmninavError(f"{where}: a ring must be a JSON object")
    size, c = d.get("image_size"), d.get("center")
    if not isinstance(size, list) or len(size) != 2 or not all(type(v) is int and v > 0 for v in size):
        raise OmninavError(f"{where}: 'image_size' must be [width, height] in pixels")
    if not isinstance(c, list) or len(c) != 2:
        raise OmninavError(f"{where}: 'center' must be [x, y] in pixels")
    cx, cy = (finite(v, "ring field 'center'", where) for v in c)
    ri = finite(d.get("r_inner", 0.0), "ring field 'r_inner'", where)
    ro = finite(d.get("r_outer"), "ring field 'r_outer'", where)
    if not 0 <= ri < ro:
        raise OmninavError(f"{where}: a ring needs 0 <= r_inner < r_outer, got {ri}, {ro}")
    wh = (int(size[0]), int(size[1]))
    return Ring(wh, (cx, cy), ri, ro, visible_share((cx, cy), ro, wh), frames_used=0, frames_total=0)


# ---- small geometry helpers -------------------------------------------------------------------
def visible_share(center: tuple[float, float], radius: float, size: tuple[int, int]) -> float:
    """Share of the circle's circumference inside a (w, h) image (B7)."""
    w, h = size
    ct, st = unit_circle(N_VISIBLE, True)
    x = center[0] + radius * ct
    y = center[1] + radius * st
    inside = (x >= -0.5) & (x <= w - 0.5) & (y >= -0.5) & (y <= h - 0.5)
    return float(inside.mean())


def fit_circle_algebraic(pts: np.ndarray) -> tuple[float, float, float]:
    """Kasa's circle fit: (N, 2) points -> (cx, cy, r), least squares of x^2+y^2+Dx+Ey+F = 0."""
    x, y = pts[:, 0], pts[:, 1]
    # centred for conditioning: the same solution, computed about the points' mean
    mx, my = float(x.mean()), float(y.mean())
    u, v = x - mx, y - my
    a = np.stack([u, v, np.ones_like(u)], 1)
    sol = np.linalg.lstsq(a, -(u * u + v * v), rcond=None)[0]
    cx, cy = -sol[0] / 2.0, -sol[1] / 2.0
    r2 = cx * cx + cy * cy - sol[2]
    return float(cx + mx), float(cy + my), float(math.sqrt(max(r2, 0.0)))


def fit_circle_geometric(pts: np.ndarray, init: tuple[float, float, float]) -> tuple[float, float, float]:
    """Gauss-Newton on the geometric residuals |p - c| - r, from `init`; (N, 2) -> (cx, cy, r)."""
    cx, cy, r = init
    for _ in range(20):
        dx, dy = pts[:, 0] - cx, pts[:, 1] - cy
        d = np.maximum(np.sqrt(dx * dx + dy * dy), 1e-9)
        e = d - r
        j = np.stack([-dx / d, -dy / d, -np.ones_like(d)], 1)
        step = np.linalg.solve(j.T @ j, -(j.T @ e))
        cx, cy, r = cx + float(step[0]), cy + float(step[1]), r + float(step[2])
        if float(np.abs(step).max()) < 1e-6:
            break
    return cx, cy, r


def _fit_robust(pts: np.ndarray) -> tuple[tuple[float, float, float], np.ndarray]:
    """B3: circle fit with two rounds of 3-sigma rejection; returns (circle, kept mask)."""
    keep = np.ones(len(pts), bool)
    c = fit_circle_geometric(pts, fit_circle_algebraic(pts))
    for _ in range(2):
        e = np.abs(_dist(pts[:, 0] - c[0], pts[:, 1] - c[1]) - c[2])
        sigma = max(0.05, 1.4826 * float(np.median(e[keep])))
        keep = keep & (e <= 3.0 * sigma)
        if keep.sum() < 3:
            break
        c = fit_circle_geometric(pts[keep], fit_circle_algebraic(pts[keep]))
    return c, keep


# ---- A: coarse ---------------------------------------------------------------------------------
def _grey(frame: np.ndarray) -> np.ndarray:
    if frame.ndim == 3 and frame.shape[2] == 3:
        g: np.ndarray = cv2.cvtColor(frame, cv2.COLOR_BGR2GRAY)
        return g
    if frame.ndim == 2:
        return frame
    raise OmninavError(f"a frame must be (H, W, 3) BGR or (H, W) grey, got shape {frame.shape}")


def _coverage(
    hits: np.ndarray, center: tuple[float, float], radii: np.ndarray, size: tuple[int, int], win: int
) -> np.ndarray:
    """A7: per radius in `radii`, the share of visible angle bins with an edge hit at r-win..r+win."""
    cw, ch = size
    ct, st = unit_circle(N_BINS, True)
    x = center[0] + radii[:, None] * ct[None, :]
    y = center[1] + radii[:, None] * st[None, :]
    inside = (x >= -0.5) & (x <= cw - 0.5) & (y >= -0.5) & (y <= ch - 0.5)
    near = np.zeros((len(radii), N_BINS), bool)
    for o in range(-win, win + 1):
        near |= hits[radii + o]
    vis = inside.sum(1)
    cov = (near & inside).sum(1)
    return np.where(vis >= 36, cov / np.maximum(vis, 1), 0.0)


def _outer_circles(
    pts: np.ndarray, grad: np.ndarray, c: tuple[float, float], rlim: tuple[int, int], size: tuple[int, int], win: int
) -> list[tuple[float, float, float] | None]:
    """A7 around centre c with a radius window +-win: the candidate outer circles, smallest radius
    first (None for a candidate with too few points to fit); empty without a ring."""
    rmin, rmax = rlim
    hits, d, sel = _hits(pts, grad, c, rmax + win, outward=False)
    radii = np.arange(max(rmin, win + 1), rmax + 1)
    score = _coverage(hits, c, radii, size, win)
    best = float(score.max()) if len(score) else 0.0
    if best < MIN_COVERAGE:
        return []
    prev = np.concatenate([[-1.0], score[:-1]])
    nxt = np.concatenate([score[1:], [-1.0]])
    out: list[tuple[float, float, float] | None] = []
    ks = np.flatnonzero((score >= OUTER_PICK * best) & (score >= prev) & (score >= nxt))
    for i, k in enumerate(ks):
        if i > 0 and k == ks[i - 1] + 1:  # a plateau's radii are one candidate: its first
            continue
        near = sel & (np.abs(d - float(radii[k])) <= win + 1.0)
        out.append(fit_circle_algebraic(pts[near]) if near.sum() >= 20 else None)
    return out


def _outer_circle(
    pts: np.ndarray, grad: np.ndarray, c: tuple[float, float], rlim: tuple[int, int], size: tuple[int, int]
) -> tuple[float, float, float] | None:
    """A7: the coarse outer circle around the votes' centre c, or None: the first run's candidates
    in turn, each refined by the second run around its centre, until one gives a circle."""
    wide, narrow = OUTER_WINDOWS
    for circle in _outer_circles(pts, grad, c, rlim, size, wide):
        if circle is None:
            continue
        got = _outer_circles(pts, grad, (circle[0], circle[1]), rlim, size, narrow)
        if got and got[0] is not None:
            return got[0]
    return None


def _hits(
    pts: np.ndarray, grad: np.ndarray, center: tuple[float, float], rmax: int, outward: bool
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A7: (rmax + 3, N_BINS) bool table of radial edge points around `center`, and the points'
    distances and a mask of which were radial in the asked sense."""
    dx, dy = pts[:, 0] - center[0], pts[:, 1] - center[1]
    d = _dist(dx, dy)
    ok = d > 0
    c = np.where(ok, (grad[:, 0] * dx + grad[:, 1] * dy) / np.maximum(d, 1e-9), 0.0)
    sel = ok & ((c > RADIAL_COS) if outward else (c < -RADIAL_COS))
    q = np.floor(d + 0.5).astype(np.int64)
    sel &= q <= rmax + 2
    ang = np.mod(np.arctan2(dy, dx), 2.0 * np.pi)
    n = np.clip(np.floor(ang / (2.0 * np.pi) * N_BINS).astype(np.int64), 0, N_BINS - 1)
    table = np.zeros((rmax + 3, N_BINS), bool)
    table[q[sel], n[sel]] = True
    return table, d, sel


def _edge_points(
    blur: np.ndarray, gx: np.ndarray, gy: np.ndarray, canny: tuple[int, int]
) -> tuple[np.ndarray, np.ndarray]:
    """A3-A4: Canny edge points in row-major order, (N, 2) float64 (x, y), and their unit
    gradients (N, 2) (towards the brighter side)."""
    edges = cv2.Canny(blur, canny[0], canny[1], apertureSize=3, L2gradient=False)
    ys, xs = np.nonzero(edges)
    gxe, gye = gx[ys, xs].astype(np.float64), gy[ys, xs].astype(np.float64)
    g = _dist(gxe, gye)
    ok = g > 0
    pts = np.stack([xs[ok], ys[ok]], 1).astype(np.float64)
    return pts, np.stack([gxe[ok] / g[ok], gye[ok] / g[ok]], 1)


def _dark_inside(blur: np.ndarray, c: tuple[float, float], r: int) -> bool:
    """A8: is the blurred picture brighter just outside radius r than just inside, all round?"""
    ch, cw = blur.shape
    ct, st = unit_circle(N_BINS, True)
    q = np.array([[r + INNER_WINDOW + 2], [max(0, r - INNER_WINDOW - 2)]], np.float64)
    u = np.floor(c[0] + q * ct + 0.5).astype(np.int64)
    v = np.floor(c[1] + q * st + 0.5).astype(np.int64)
    ok = ((u >= 0) & (u < cw) & (v >= 0) & (v < ch)).all(0)
    if ok.sum() < 36:
        return False
    g = blur[v[:, ok], u[:, ok]].astype(np.float64)
    return bool(((g[0] - g[1]) > INNER_STEP).mean() >= INNER_DARK)


def _inner_circle(
    blur: np.ndarray,
    pts: np.ndarray,
    grad: np.ndarray,
    c: tuple[float, float],
    rlim: tuple[int, int],
    size: tuple[int, int],
    scene_start: float | None,
    gap: float,
) -> tuple[float, float, float] | None:
    """A8: the dark centre's circle of outward edges (found around c, fitted with its own centre),
    or None."""
    lo, hi = rlim
    win = INNER_WINDOW
    hits, d, sel = _hits(pts, grad, c, hi + win, outward=True)
    radii = np.arange(max(lo, win + 1), hi + 1)
    if not len(radii):
        return None
    sc = _coverage(hits, c, radii, size, win) / np.minimum(1.0, 2.0 * np.pi * radii / N_BINS)
    prev = np.concatenate([[-1.0], sc[:-1]])
    nxt = np.concatenate([sc[1:], [-1.0]])
    cand = radii[(sc >= MIN_COVERAGE) & (sc >= prev) & (sc >= nxt)]
    cand = cand[[_dark_inside(blur, c, int(r)) for r in cand]] if len(cand) else cand
    if not len(cand):
        return None
    inside = cand[cand <= scene_start + gap] if scene_start is not None else cand
    # the largest inside where the scene starts; else (a dim scene's texture starts further out)
    # the smallest
    r = float(inside[-1] if len(inside) else cand[0])
    near = sel & (np.abs(d - r) <= win + 1.0)
    if near.sum() < 20:
        return None
    return fit_circle_algebraic(pts[near])


@dataclass(frozen=True)
class Coarse:
    """Stage A's ring, in coarse pixels, and what A9 decided about its edges."""

    center: tuple[float, float]
    r_inner: float
    r_outer: float
    scale: tuple[float, float]  # (sx, sy): coarse / full resolution
    outer_sign: float = -1.0  # B2's sign for the outer edge: -1 darker outside, +1 brighter
    housing: float = 0.0
    texture_ratio: float = 0.0
    inner_center: tuple[float, float] | None = None  # A8: the dark centre's own centre


def _gap(r: float) -> float:
    return GAP[0] * r + GAP[1]


def _texture(gx: np.ndarray, gy: np.ndarray, c: tuple[float, float], rmax: int) -> np.ndarray:
    """A9: T(r) for r = 0 .. rmax, the mean tangential gradient along the circle of radius r
    (NaN where fewer than 36 of its angles fall in the image)."""
    ch, cw = gx.shape
    ct, st = unit_circle(N_BINS, True)
    r = np.arange(rmax + 1, dtype=np.float64)[:, None]
    u = np.floor(c[0] + r * ct + 0.5).astype(np.int64)
    v = np.floor(c[1] + r * st + 0.5).astype(np.int64)
    ok = (u >= 0) & (u < cw) & (v >= 0) & (v < ch)
    uc, vc = np.clip(u, 0, cw - 1), np.clip(v, 0, ch - 1)
    tg = np.abs(-st * gx[vc, uc].astype(np.float64) + ct * gy[vc, uc].astype(np.float64))
    n = ok.sum(1)
    total = np.where(ok, tg, 0.0).sum(1)
    out: np.ndarray = np.where(n >= 36, total / np.maximum(n, 1), np.nan)
    return out


def _smooth(t: np.ndarray) -> np.ndarray:
    """A9: Ts, the mean of the defined T over r - SCENE_SMOOTH .. r + SCENE_SMOOTH."""
    defined = ~np.isnan(t)
    k = np.ones(2 * SCENE_SMOOTH + 1)
    total = np.convolve(np.where(defined, t, 0.0), k, "same")
    count = np.convolve(defined.astype(np.float64), k, "same")
    out: np.ndarray = np.where(count > 0, total / np.maximum(count, 1), np.nan)
    return out


def _scene_run(ts: np.ndarray, r_hi: int) -> tuple[int, int] | None:
    """A9: (s, e), the radii in 1 .. r_hi over which the smoothed texture stays above
    SCENE_SHARE of its peak, around the peak; None when none is defined."""
    seg = ts[1 : r_hi + 1]
    if not len(seg) or np.isnan(seg).all():
        return None
    rp = int(np.nanargmax(seg)) + 1
    floor_ = SCENE_SHARE * float(ts[rp])
    e = rp
    while e + 1 <= r_hi and ts[e + 1] >= floor_:
        e += 1
    s = rp
    while s - 1 >= 1 and ts[s - 1] >= floor_:
        s -= 1
    return s, e


def _either(
    pts: np.ndarray, grad: np.ndarray, c: tuple[float, float], rlim: tuple[int, int], size: tuple[int, int]
) -> tuple[float, int, float]:
    """A9: the most complete circle of radial edges of either kind with r in rlim: (score, r,
    sign), sign -1 for inward points (darker outside), +1 for outward; (0, 0, 0) for none."""
    lo, hi = rlim
    best = (0.0, 0, 0.0)
    if hi < lo:
        return best
    radii = np.arange(lo, hi + 1)
    for outward, sign in ((False, -1.0), (True, 1.0)):
        hits, _, _ = _hits(pts, grad, c, hi + 1, outward)
        sc = _coverage(hits, c, radii, size, 1)
        k = int(np.argmax(sc))
        if sc[k] > best[0]:
            best = (float(sc[k]), int(radii[k]), sign)
    return best


def _scene_outer(
    pts: np.ndarray, grad: np.ndarray, circle: tuple[float, float, float], ts: np.ndarray, size: tuple[int, int]
) -> tuple[tuple[float, float, float], float, float]:
    """A9, outer: (circle, sign, housing) - the circle of A7 unless it lies outside the scene and
    an edge where the scene ends replaces it."""
    a1, b1, r1 = circle
    run = _scene_run(ts, int(math.floor(r1)))
    gap = _gap(r1)
    if run is None or r1 - run[1] <= gap:
        return circle, -1.0, 0.0
    e = run[1]
    lim = (max(2, int(math.floor(e - gap))), int(math.floor(r1 - gap)))
    score, r, sign = _either(pts, grad, (a1, b1), lim, size)
    if score < MIN_COVERAGE:
        return circle, -1.0, 0.0
    _, d, sel = _hits(pts, grad, (a1, b1), r + 2, sign > 0)
    near = sel & (np.abs(d - r) <= 2.0)
    if near.sum() < 20:
        return circle, -1.0, 0.0
    return fit_circle_algebraic(pts[near]), sign, r1


def _texture_ratio(t: np.ndarray, start: float, r1: float) -> float:
    """A9: the median texture over the scene [start, r1] over the surround's."""
    gap = _gap(r1)
    r = np.arange(len(t))
    inside = t[(r >= start) & (r <= r1) & ~np.isnan(t)]
    out = t[(r >= r1 + 3) & (r <= r1 + 3 + gap) & ~np.isnan(t)]
    if not len(inside) or not len(out):
        return 0.0
    return float(np.median(inside) / max(TEXTURE_FLOOR, float(np.median(out))))


def coarse_ring(grey: np.ndarray) -> Coarse | None:
    """Stage A: the ring in coarse pixels, or None without a ring."""
    h, w = grey.shape
    f = min(1.0, COARSE_MAX / max(w, h))
    cw, ch = int(math.floor(w * f + 0.5)), int(math.floor(h * f + 0.5))
    small = cv2.resize(grey, (cw, ch), interpolation=cv2.INTER_AREA) if f < 1.0 else grey
    blur = cv2.GaussianBlur(small, (5, 5), COARSE_SIGMA)
    gx = cv2.Sobel(blur, cv2.CV_32F, 1, 0, ksize=3)
    gy = cv2.Sobel(blur, cv2.CV_32F, 0, 1, ksize=3)
    pts, grad = _edge_points(blur, gx, gy, CANNY)
    if len(pts) < 20:
        return None
    xs, ys, ux, uy = pts[:, 0], pts[:, 1], grad[:, 0], grad[:, 1]
    rmin = int(math.floor(0.15 * min(cw, ch) + 0.5))
    rmax = int(math.floor(0.6 * max(cw, ch) + 0.5))
    # A5: votes along each gradient, towards the brighter side, from every VOTE_EVERY-th point
    # (float32 for speed: a vote a rounding apart changes nothing that stage B does not refine)
    ks = np.arange(rmin, rmax + 1, VOTE_STEP, dtype=np.float32)
    vx, vy = xs[::VOTE_EVERY].astype(np.float32), ys[::VOTE_EVERY].astype(np.float32)
    vux, vuy = ux[::VOTE_EVERY].astype(np.float32), uy[::VOTE_EVERY].astype(np.float32)
    a = np.floor(vx[:, None] + ks[None, :] * vux[:, None] + np.float32(0.5)).astype(np.int32)
    b = np.floor(vy[:, None] + ks[None, :] * vuy[:, None] + np.float32(0.5)).astype(np.int32)
    idx = b * cw + a
    idx[(a < 0) | (a >= cw) | (b < 0) | (b >= ch)] = cw * ch  # off the image: one spare cell
    acc = np.bincount(idx.ravel(), minlength=cw * ch + 1)[: cw * ch].reshape(ch, cw).astype(np.float32)
    accb = cv2.boxFilter(acc, -1, (VOTE_BOX, VOTE_BOX), normalize=False, borderType=cv2.BORDER_CONSTANT)
    k = int(np.argmax(accb))
    if int(accb.flat[k]) < MIN_VOTES:
        return None
    c0 = (float(k % cw), float(k // cw))
    # A7: the outer circle, first tolerant of the votes' error, then around the better centre
    circle = _outer_circle(pts, grad, c0, (rmin, rmax), (cw, ch))
    if circle is None:
        return None
    # A9: is that circle the scene's edge, or a housing's outside it?
    t = _texture(gx, gy, (circle[0], circle[1]), int(math.floor(circle[2] + 3 + _gap(circle[2]))))
    (a1, b1, r1), osign, housing = _scene_outer(pts, grad, circle, _smooth(t), (cw, ch))
    if housing > 0:
        t = _texture(gx, gy, (a1, b1), int(math.floor(r1 + 3 + _gap(r1))))
    # A8: the inner radius (a dark centre) just inside where the scene starts; a dim scene's faint
    # inner edge: again with fainter edges
    run = _scene_run(_smooth(t), int(math.floor(r1)))
    lo, hi = int(math.floor(0.1 * r1 + 0.5)), int(math.floor(0.9 * r1 + 0.5))
    inner: tuple[float, float, float] | None = None
    if hi > lo + 2 and lo >= 1:
        where = ((a1, b1), (lo, hi), (cw, ch), float(run[0]) if run is not None else None, _gap(r1))
        inner = _inner_circle(blur, pts, grad, *where)
        if inner is None:
            pts2, grad2 = _edge_points(blur, gx, gy, CANNY_FAINT)
            inner = _inner_circle(blur, pts2, grad2, *where)
    r2 = inner[2] if inner is not None else 0.0
    # A9: the texture ratio, over the scene from its inner edge (or from where its texture starts)
    start = r2 or (float(run[0]) if run is not None else 0.0)
    return Coarse(
        center=(a1, b1),
        r_inner=r2,
        r_outer=r1,
        scale=(cw / w, ch / h),
        inner_center=(inner[0], inner[1]) if inner is not None else None,
        outer_sign=osign,
        housing=housing,
        texture_ratio=_texture_ratio(t, start, r1),
    )


# ---- B: sub-pixel ------------------------------------------------------------------------------
def _bilinear(img: np.ndarray, x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Bilinear samples of a float32 (H, W) image at points inside [0, W-1] x [0, H-1]."""
    h, w = img.shape
    x0 = np.clip(np.floor(x).astype(np.int64), 0, w - 2)
    y0 = np.clip(np.floor(y).astype(np.int64), 0, h - 2)
    fx, fy = x - x0, y - y0
    i00, i01 = img[y0, x0], img[y0, x0 + 1]
    i10, i11 = img[y0 + 1, x0], img[y0 + 1, x0 + 1]
    out: np.ndarray = (i00 * (1 - fx) + i01 * fx) * (1 - fy) + (i10 * (1 - fx) + i11 * fx) * fy
    return out


def edge_points(
    fine: np.ndarray, center: tuple[float, float], radius: float, sign: float, half: float
) -> tuple[np.ndarray, int]:
    """B2: the sub-pixel edge on each radial profile across a circle: ((n, 2) points, number of
    profiles inside the image). sign -1: darker outwards (outer edge), +1: brighter outwards."""
    h, w = fine.shape

    n_s = int(round(2 * half / PROFILE_STEP)) + 1
    s = -half + PROFILE_STEP * np.arange(n_s)
    ct, st = (v[:, None] for v in unit_circle(N_PROFILES, False))
    x = center[0] + (radius + s[None, :]) * ct
    y = center[1] + (radius + s[None, :]) * st
    inside = ((x >= 0) & (x <= w - 1) & (y >= 0) & (y <= h - 1)).all(1)
    n_in = int(inside.sum())
    if n_in == 0:
        return np.zeros((0, 2)), 0
    prof = _bilinear(fine, x[inside], y[inside]).astype(np.float64)
    e = sign * (prof[:, 2:] - prof[:, :-2]) / (2 * PROFILE_STEP)  # D_j for j = 1 .. n_s - 2
    jj = np.argmax(e, axis=1)  # index into e; j* = jj + 1
    rows = np.arange(len(e))
    peak = e[rows, jj]
    ok = (peak >= MIN_EDGE) & (jj >= 1) & (jj <= e.shape[1] - 2)
    jc = np.clip(jj, 1, e.shape[1] - 2)
    a_, b_, c_ = e[rows, jc - 1], e[rows, jc], e[rows, jc + 1]
    den = a_ - 2 * b_ + c_
    delta = np.where(den < 0, 0.5 * (a_ - c_) / np.where(den < 0, den, -1.0), 0.0)
    delta = np.clip(delta, -0.5, 0.5)
    r = radius + s[jj + 1] + PROFILE_STEP * delta
    pts = np.stack([center[0] + r * ct[inside, 0], center[1] + r * st[inside, 0]], 1)
    return pts[ok], n_in


def _refine_outer(
    fine: np.ndarray, circle: tuple[float, float, float], sign: float = -1.0
) -> tuple[tuple[float, float, float], np.ndarray] | None:
    """B2-B4 for the outer circle: (cx, cy, r) and the kept edge points, or None."""
    for half in (6.0, 3.0):
        pts, n_in = edge_points(fine, (circle[0], circle[1]), circle[2], sign, half)
        if n_in == 0 or len(pts) < 20 or len(pts) < MIN_SHARE * n_in:
            return None
        circle, keep = _fit_robust(pts)
        if keep.sum() < max(20, MIN_SHARE * n_in):
            return None
    return circle, pts[keep]


def _refine_inner(fine: np.ndarray, center: tuple[float, float], start: tuple[float, float, float]) -> float:
    """B5: the radius of the dark centre's own circle, from A8's circle `start`, or 0 without an
    inner edge (or one further than INNER_OFFSET of its radius from the ring's `center`)."""
    c, r = (start[0], start[1]), start[2]
    for half in (6.0, 3.0):
        pts, n_in = edge_points(fine, c, r, 1.0, half)
        if n_in == 0 or len(pts) < 20 or len(pts) < MIN_SHARE * n_in:
            return 0.0
        (cx, cy, r), keep = _fit_robust(pts)
        dx, dy = cx - center[0], cy - center[1]
        off = math.sqrt(dx * dx + dy * dy)
        if keep.sum() < max(20, MIN_SHARE * n_in) or not off <= INNER_OFFSET * r:  # (a NaN fit: none)
            return 0.0
        c = (cx, cy)
    return r


def _ellipse_ratio(pts: np.ndarray) -> float:
    if len(pts) < 5:
        return 1.0
    (_, _), (ax1, ax2), _ = cv2.fitEllipse(pts.astype(np.float32))
    lo, hi = min(ax1, ax2), max(ax1, ax2)
    return float(hi / lo) if lo > 0 else 1.0


def _check_frame(frame: np.ndarray) -> None:
    if not isinstance(frame, np.ndarray) or frame.dtype != np.uint8 or frame.ndim not in (2, 3):
        raise OmninavError("a frame must be a (H, W, 3) BGR or (H, W) grey uint8 image")
    h, w = frame.shape[:2]
    if min(w, h) < MIN_SIDE:
        raise OmninavError(
            f"the image is {w}x{h} pixels: too small to find a lens ring in (at least {MIN_SIDE} a side)"
        )


def find_ring_frame(frame: np.ndarray) -> Ring | None:
    """The ring in one (H, W, 3) BGR or (H, W) uint8 frame, or None when it shows none."""
    _check_frame(frame)
    grey = _grey(frame)
    h, w = grey.shape
    coarse = coarse_ring(grey)
    if coarse is None:
        return None
    (a, b), ri, ro, (sx, sy) = coarse.center, coarse.r_inner, coarse.r_outer, coarse.scale
    s = 0.5 * (sx + sy)
    cx, cy = (a + 0.5) / sx - 0.5, (b + 0.5) / sy - 0.5
    fine = cv2.GaussianBlur(grey, (5, 5), FINE_SIGMA).astype(np.float32)
    got = _refine_outer(fine, (cx, cy, ro / s), coarse.outer_sign)
    if got is None:
        return None
    (cx, cy, r_out), pts = got
    r_in = 0.0
    if ri > 0 and coarse.inner_center is not None:
        (ia, ib) = coarse.inner_center
        r_in = _refine_inner(fine, (cx, cy), ((ia + 0.5) / sx - 0.5, (ib + 0.5) / sy - 0.5, ri / s))
    r_out -= EDGE_BIAS_PX
    if r_in > 0:
        r_in += EDGE_BIAS_PX
    return Ring(
        image_size=(w, h),
        center=(cx, cy),
        r_inner=r_in,
        r_outer=r_out,
        visible=visible_share((cx, cy), r_out, (w, h)),
        ellipse_ratio=_ellipse_ratio(pts),
        points=pts,
        surround="brighter" if coarse.outer_sign > 0 else "darker",
        housing=coarse.housing / s,
        texture_ratio=coarse.texture_ratio,
    )


def find_ring(frames: Iterable[np.ndarray]) -> Ring:
    """The ring over many frames: the median of each frame's, their spread, how many showed one.

    Raises NoRing when fewer than half the frames show a ring, OmninavError for frames of
    different sizes or too small an image.
    """
    found: list[Ring] = []
    total = 0
    size: tuple[int, ...] | None = None
    for f in frames:
        _check_frame(f)
        if size is None:
            size = f.shape[:2]
        elif f.shape[:2] != size:
            raise OmninavError(
                f"frames have different sizes ({size[1]}x{size[0]} and {f.shape[1]}x{f.shape[0]}): "
                "give frames of one camera at one resolution"
            )
        total += 1
        r = find_ring_frame(f)
        if r is not None:
            found.append(r)
    if total == 0:
        raise OmninavError("no frames to find the lens ring in")
    if len(found) * 2 < total or not found:
        raise NoRing(
            f"no lens ring found in {total - len(found)} of {total} frames: "
            "is the panoramic lens attached and uncovered?"
        )
    # frames that took a housing for it and frames that did not see different circles: the majority's
    housed = [r.housing for r in found if r.housing > 0]
    major = [r for r in found if (r.housing > 0) == (2 * len(housed) > len(found))]
    arr = np.array([[r.center[0], r.center[1], r.r_inner, r.r_outer] for r in major])
    med = np.median(arr, axis=0)
    sd = arr.std(axis=0)
    inner = arr[arr[:, 2] > 0, 2]  # frames where the inner edge was too faint say 0: not a radius
    med[2], sd[2] = (float(np.median(inner)), float(inner.std())) if 2 * len(inner) >= len(arr) else (0.0, 0.0)
    assert size is not None
    wh = (int(size[1]), int(size[0]))
    return Ring(
        image_size=wh,
        center=(float(med[0]), float(med[1])),
        r_inner=float(med[2]),
        r_outer=float(med[3]),
        visible=visible_share((float(med[0]), float(med[1])), float(med[3]), wh),
        frames_used=len(found),
        frames_total=total,
        spread={
            "center_px": float(math.hypot(sd[0], sd[1])),
            "r_inner_px": float(sd[2]),
            "r_outer_px": float(sd[3]),
        },
        ellipse_ratio=float(np.median([r.ellipse_ratio for r in major])),
        surround="brighter" if 2 * sum(r.surround == "brighter" for r in major) > len(major) else "darker",
        housing=float(np.median(housed)) if 2 * len(housed) > len(found) else 0.0,
        texture_ratio=float(np.median([r.texture_ratio for r in major])),
    )
