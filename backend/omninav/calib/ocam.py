"""Scaramuzza's omnidirectional camera model (OCamCalib), fitted to board corners, and the
`lens.json` profile it converts to.

The model (Scaramuzza, Martinelli, Siegwart, "A Toolbox for Easily Calibrating Omnidirectional
Cameras", IROS 2006; OCamCalib's MATLAB toolbox and its `calib_results.txt`):

- Decentring (not OCamCalib's): a mirror off the camera's axis moves the sensor point by Brown-Conrady's
  tangential term, ``(u, v) + s t((u, v) / s)`` with coefficients (p1, p2) and s the ring's outer radius,
  before Eq. 1 (`Ocam.tangential`, `Ocam.unit`; (0, 0) is OCamCalib's model).
- Eq. 1, sensor to pixel: in OCamCalib's order (row, column), ``p = [[c, d], [e, 1]] (u, v) + (yc, xc)``:
  an affine stretch and the centre. `Ocam.center` is kept as (x, y) = (column, row), as lens.json
  has it; `stretch` is (c, d, e) exactly as OCamCalib writes it (so it acts on (row, column)).
- Eq. 2, sensor point to ray: (u, v) sees the ray ``(u, v, f(rho))``, rho = |(u, v)|,
  ``f(rho) = a0 + a2 rho^2 + ... + aN rho^N`` (a1 = 0). The ray frame is OCamCalib's: x along the
  image rows (down), y along the columns (right), z = f.

Our profile's elevation is ``atan2(f(rho), rho)`` in degrees. Which way "up" is cannot be told
from a planar board: mirroring the world top-to-bottom (f -> -f, each board's z-row negated) fits the
same corners exactly. So a convention decides it: the axis is chosen so that the ring's outer edge
looks *higher* than its inner edge (`outer_down=False`, the common convex-mirror donut: inner edge
looks down at the phone, outer edge above the horizon), which is OCamCalib's own f(0) = a0 < 0 for
such a lens. `outer_down=True` picks the other solution.

Fitting (`fit_ocam`) follows OCamCalib: per view a linear solve of the pose's first two rows from
the cross-product constraint (SVD), r31/r32 from orthonormality, the sign choices; one linear least
squares for the polynomial and every view's t3; a coarse-to-fine search of the centre around the
ring's centre minimising the linear solution's ray error; then Levenberg-Marquardt
(`scipy.optimize.least_squares`, soft-L1 loss) on the reprojection error over centre, stretch,
polynomial and poses; then the same with the decentring free too, kept where it takes the RMS below
DECENTRING_GAIN of the first (on a symmetric lens the two extra freedoms only trade against the
centre). Held-out views are then posed with the model fixed and scored.

Board labels: a chessboard's corners may come labelled from either end (180 degrees) or, seen
through the donut's mirror, mirror-labelled. Neither changes the fit: every view has its own pose, a
relabelled planar grid is the same point set under another pose (180 degrees: a proper rotation;
mirrored: the other sign of r3, which the linear step chooses anyway). Labels matter only for the
fit's *handedness* (does the printed face look at the lens with a proper rotation?), which is
therefore reported but trusted only as a cross-check of the protocol's `ccw`.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass, field
from typing import Any, Protocol

import numpy as np
from scipy.optimize import least_squares, minimize  # type: ignore[import-untyped]
from scipy.sparse import lil_matrix  # type: ignore[import-untyped]
from scipy.spatial.transform import Rotation  # type: ignore[import-untyped]

from ..errors import OmninavError
from ..lens import Catadioptric, Sensor, decentring, undo_decentring
from .board import RingLike

DEGREES = (4, 5, 6, 7)  # f's degree, chosen per fit: 4 is OCamCalib's default, a ring often needs more
N_FIXED = 7  # the fit's intrinsics before f: centre (2), stretch (3), decentring (2)
DECENTRING_GAIN = 0.8  # the mirror's decentring is fitted only where it takes the RMS below this share
SENSOR_PX = 0.25  # px: a stretch or decentring moving no ring pixel this far (a similarity aside) is left out
STRETCH_WARN = 0.005  # a stretch more anisotropic than 0.5 % is more than a rendered lens ever shows


class View(Protocol):
    """A view of the board: `calib.board.Detection` is one."""

    @property
    def frame(self) -> int: ...
    @property
    def image_points(self) -> np.ndarray: ...  # (n, 2) float64 pixels (x, y)
    @property
    def object_points(self) -> np.ndarray: ...  # (n, 3) float64 metres, z = 0


# ---- the model ---------------------------------------------------------------------------------
@dataclass(frozen=True)
class Ocam:
    """Scaramuzza's model: `center` (x, y) pixels; `stretch` (c, d, e) as OCamCalib; `poly` f's
    coefficients, ascending, a1 = 0 included (OCamCalib's `ss`); `image_size` (w, h)."""

    center: tuple[float, float]
    stretch: tuple[float, float, float]
    poly: tuple[float, ...]
    image_size: tuple[int, int]
    # the mirror's decentring (p1, p2), Brown-Conrady's tangential term on the sensor point (u, v)
    # in units of `unit` px, before the stretch: (0, 0) is OCamCalib's model
    tangential: tuple[float, float] = (0.0, 0.0)
    unit: float = 1.0

    def _tangential(self, uv: np.ndarray) -> np.ndarray:
        """(n, 2) sensor points -> their decentring offsets (n, 2) (lens.decentring)."""
        return self.unit * np.stack(decentring(uv[:, 0], uv[:, 1], self.tangential, self.unit), -1)

    def _a(self) -> np.ndarray:
        c, d, e = self.stretch
        return np.array([[c, d], [e, 1.0]])

    def sensor(self, xy: np.ndarray) -> np.ndarray:
        """(n, 2) pixels (x, y) -> (n, 2) sensor points (u, v) of Eq. 1 (u along rows)."""
        xy = np.asarray(xy, np.float64).reshape(-1, 2)
        rc = np.stack([xy[:, 1] - self.center[1], xy[:, 0] - self.center[0]], -1)
        out: np.ndarray = np.linalg.solve(self._a(), rc.T).T
        if self.tangential != (0.0, 0.0):
            u, v = undo_decentring(out[:, 0], out[:, 1], self.tangential, self.unit)
            out = np.stack([u, v], -1)
        return out

    def pixel(self, uv: np.ndarray) -> np.ndarray:
        """(n, 2) sensor points (u, v) -> (n, 2) pixels (x, y): Eq. 1, the decentring first."""
        uv = np.asarray(uv, np.float64).reshape(-1, 2)
        if self.tangential != (0.0, 0.0):
            uv = uv + self._tangential(uv)
        rc = uv @ self._a().T
        return np.stack([rc[:, 1] + self.center[0], rc[:, 0] + self.center[1]], -1)

    def f(self, rho: np.ndarray) -> np.ndarray:
        out: np.ndarray = np.polynomial.polynomial.polyval(rho, np.asarray(self.poly))
        return out

    def elevation(self, rho: np.ndarray) -> np.ndarray:
        """Elevation (deg) of the ray seen at sensor radius rho: atan2(f(rho), rho)."""
        rho = np.asarray(rho, np.float64)
        out: np.ndarray = np.rad2deg(np.arctan2(self.f(rho), rho))
        return out

    def cam2world(self, xy: np.ndarray) -> np.ndarray:
        """(n, 2) pixels (x, y) -> (n, 3) unit rays in OCamCalib's frame (Eq. 1 then Eq. 2)."""
        uv = self.sensor(xy)
        ray = np.column_stack([uv, self.f(np.hypot(uv[:, 0], uv[:, 1]))])
        out: np.ndarray = ray / np.linalg.norm(ray, axis=1, keepdims=True)
        return out

    def world2cam(self, xyz: np.ndarray, clamp: bool = False) -> np.ndarray:
        """(n, 3) rays (any length) -> (n, 2) pixels (x, y); NaN for rays the model never sees
        (`clamp`: the nearest seen radius instead, for the optimiser)."""
        xyz = np.asarray(xyz, np.float64).reshape(-1, 3)
        n = np.hypot(xyz[:, 0], xyz[:, 1])
        rho = _solve_rho(np.asarray(self.poly), n, xyz[:, 2], _rho_max(self.image_size), clamp)
        with np.errstate(invalid="ignore", divide="ignore"):
            k = np.where(n > 0, rho / np.where(n > 0, n, 1.0), 0.0)
        return self.pixel(xyz[:, :2] * k[:, None])

    def anisotropy(self) -> float:
        """How far the stretch is from a similarity (rotation + scale): sigma_max / sigma_min - 1.
        A similarity is absorbed by the polynomial and the poses; the rest lens.json holds in its
        `sensor` (profile_sensor)."""
        s = np.linalg.svd(self._a(), compute_uv=False)
        return float(s[0] / s[1] - 1.0)

    def to_dict(self) -> dict[str, object]:
        return {
            "center": list(self.center),
            "stretch": list(self.stretch),
            "poly": list(self.poly),
            "image_size": list(self.image_size),
            "tangential": list(self.tangential),
            "unit": self.unit,
        }


def _rho_max(image_size: tuple[int, int]) -> float:
    return float(math.hypot(*image_size))


def _solve_rho(poly: np.ndarray, n: np.ndarray, z: np.ndarray, rho_max: float, clamp: bool) -> np.ndarray:
    """Sensor radius rho where the ray (n, z) (n = horizontal length) meets f: f(rho) n = z rho.

    A dense table of the ray angle atan2(f, rho) over the monotonic stretch of f that starts at the
    centre gives the start, Newton's method on h(rho) = f(rho) n - z rho the precision
    (h' = n (f' rho - f) / rho > 0 there, so it converges fast).
    """
    grid = np.linspace(0.0, rho_max, 4097)
    ang = np.arctan2(np.polynomial.polynomial.polyval(grid, poly), grid)
    d = np.diff(ang)
    sgn = np.sign(d[0]) if d[0] != 0 else 1.0
    bad = np.flatnonzero(np.sign(d) != sgn)
    end = int(bad[0]) + 1 if bad.size else grid.size
    grid, ang = grid[:end], ang[:end]
    if sgn < 0:
        grid, ang = grid[::-1], ang[::-1]
    theta = np.arctan2(z, n)
    rho = np.interp(theta, ang, grid)
    dpoly = np.polynomial.polynomial.polyder(poly)
    for _ in range(8):
        h = np.polynomial.polynomial.polyval(rho, poly) * n - z * rho
        dh = np.polynomial.polynomial.polyval(rho, dpoly) * n - z
        with np.errstate(divide="ignore", invalid="ignore"):
            step = np.where(dh != 0, h / dh, 0.0)
        new = rho - step
        ok = np.isfinite(new) & (new >= grid.min()) & (new <= grid.max())
        rho = np.where(ok, new, rho)
    if not clamp:
        rho = np.where((theta >= ang[0]) & (theta <= ang[-1]), rho, np.nan)
    out: np.ndarray = rho
    return out


# ---- the linear steps (OCamCalib's calibrate.m, omni_find_parameters_fun.m) ---------------------
@dataclass
class _Lin:
    """One view's linear pose candidates: r1, r2 (3,) and t1, t2, for each sign of r3 (x, y)."""

    r1: np.ndarray  # (2, 3): candidate, component
    r2: np.ndarray
    t12: np.ndarray  # (2,)


def _pose_candidates(uv: np.ndarray, xy: np.ndarray) -> _Lin:
    """The cross-product constraint's third row, u P2 - v P1 = 0, solved for (r11, r12, r21, r22,
    t1, t2) up to scale by SVD; r31, r32 from |r1| = |r2|, r1 . r2 = 0; the scale's sign so that
    (P1, P2) points the way (u, v) does (rays have a positive length). Two candidates: +-(r31, r32)."""
    u, v = uv[:, 0], uv[:, 1]
    bx, by = xy[:, 0], xy[:, 1]
    m = np.column_stack([-v * bx, -v * by, u * bx, u * by, -v, u])
    r11, r12, r21, r22, t1, t2 = np.linalg.svd(m, full_matrices=False)[2][-1]
    a = r11 * r12 + r21 * r22
    b = (r12**2 + r22**2) - (r11**2 + r21**2)
    r31 = math.sqrt(max((b + math.sqrt(b * b + 4 * a * a)) / 2, 0.0))
    r32 = math.copysign(math.sqrt(max(r31 * r31 - b, 0.0)), -a) if r31 > 1e-12 else math.sqrt(max(-b, 0.0))
    lam = 1.0 / math.sqrt(r11**2 + r21**2 + r31**2)
    p1, p2 = lam * (r11 * bx + r12 * by + t1), lam * (r21 * bx + r22 * by + t2)
    if np.sum(u * p1 + v * p2) < 0:
        lam = -lam
    flip = np.array([1.0, 1.0, -1.0])
    r1 = np.array([lam * r11, lam * r21, lam * r31])
    r2 = np.array([lam * r12, lam * r22, lam * r32])
    r1, r2 = np.stack([r1, r1 * flip]), np.stack([r2, r2 * flip])
    return _Lin(r1, r2, np.array([lam * t1, lam * t2]))


def _poly_rows(
    uv: np.ndarray, xy: np.ndarray, r1: np.ndarray, r2: np.ndarray, t12: np.ndarray, powers: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The cross product's first two rows, linear in f's coefficients and t3:
    f P2 - v t3 = v (r31 X + r32 Y), f P1 - u t3 = u (r31 X + r32 Y).
    Returns (rows over the coefficients (2n, k), the t3 column (2n,), the right side (2n,))."""
    u, v = uv[:, 0], uv[:, 1]
    bx, by = xy[:, 0], xy[:, 1]
    p1 = r1[0] * bx + r2[0] * by + t12[0]
    p2 = r1[1] * bx + r2[1] * by + t12[1]
    p3 = r1[2] * bx + r2[2] * by
    rp = np.hypot(u, v)[:, None] ** powers[None, :]
    a = np.concatenate([p2[:, None] * rp, p1[:, None] * rp])
    return a, np.concatenate([-v, -u]), np.concatenate([v * p3, u * p3])


def _ray_error(uv: np.ndarray, xy: np.ndarray, coef: np.ndarray, powers: np.ndarray, pose: np.ndarray) -> np.ndarray:
    """Angles (rad) between the rays the model gives to (u, v) and the board points' directions."""
    ray = np.column_stack([uv, (np.hypot(uv[:, 0], uv[:, 1])[:, None] ** powers[None, :]) @ coef])
    p = xy[:, 0:1] * pose[0] + xy[:, 1:2] * pose[1] + pose[2]
    cos = np.sum(ray * p, 1) / (np.linalg.norm(ray, axis=1) * np.linalg.norm(p, axis=1))
    out: np.ndarray = np.arccos(np.clip(cos, -1.0, 1.0))
    return out


@dataclass
class _Linear:
    coef: np.ndarray  # f's coefficients at `powers`, in scaled units
    poses: list[np.ndarray]  # per view (3, 3): columns r1, r2, t (r3 = r1 x r2 implied)
    err: float  # RMS ray angle (rad)


def _linear_solve(uvs: list[np.ndarray], xys: list[np.ndarray], powers: np.ndarray, outer_down: bool) -> _Linear:
    """OCamCalib's linear estimate for a given centre: poses' first rows, then f and every t3.

    The two signs of (r31, r32) of a view fit equally well with opposite f (the up/down mirror), so
    each view first takes the sign whose own f makes its outer points look higher (or lower with
    `outer_down`); one joint solve follows, then each view re-chooses its sign against the joint f
    (a board seen over a narrow band of radii can get the first choice wrong), until stable.
    """
    cands = [_pose_candidates(uv, xy) for uv, xy in zip(uvs, xys, strict=True)]
    choice = []
    for uv, xy, c in zip(uvs, xys, cands, strict=True):
        rho = np.hypot(uv[:, 0], uv[:, 1])
        lo, hi = np.argmin(rho), np.argmax(rho)
        # a0 + a2 rho^2 alone: one view spans few radii, the full degree would only add noise here
        a, b = _drop_t3(*_poly_rows(uv, xy, c.r1[0], c.r2[0], c.t12, powers[:2]))
        sol = np.linalg.solve(a.T @ a, a.T @ b)
        fl = sol[0] + sol[1] * rho[[lo, hi]] ** 2
        up = math.atan2(fl[1], rho[hi]) > math.atan2(fl[0], rho[lo])
        choice.append(0 if up != outer_down else 1)
    rows = [
        [_poly_rows(uv, xy, c.r1[k], c.r2[k], c.t12, powers) for k in (0, 1)]
        for uv, xy, c in zip(uvs, xys, cands, strict=True)
    ]
    # t3 is one unknown per view: eliminate it (project each view's rows off its t3 column), then
    # f's few coefficients are one small least squares over every view.
    proj = [[_drop_t3(*r) for r in rv] for rv in rows]
    coef = np.zeros(len(powers))
    for _ in range(4):
        a = np.concatenate([proj[j][k][0] for j, k in enumerate(choice)])
        b = np.concatenate([proj[j][k][1] for j, k in enumerate(choice)])
        coef = np.linalg.lstsq(a, b, rcond=None)[0]
        new = [int(np.argmin([np.sum((pk[1] - pk[0] @ coef) ** 2) for pk in pj])) for pj in proj]
        if new == choice:
            break
        choice = new
    t3 = []
    for j, k in enumerate(choice):
        a, tcol, rhs = rows[j][k]
        r = rhs - a @ coef
        t3.append(float(tcol @ r / (tcol @ tcol)))
    poses = []
    errs = []
    for uv, xy, c, k, t in zip(uvs, xys, cands, choice, t3, strict=True):
        pose = np.stack([c.r1[k], c.r2[k], np.array([c.t12[0], c.t12[1], t])])
        poses.append(pose)
        errs.append(_ray_error(uv, xy, coef, powers, pose))
    return _Linear(coef, poses, float(np.sqrt(np.mean(np.concatenate(errs) ** 2))))


def _drop_t3(a: np.ndarray, tcol: np.ndarray, rhs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Rows and right side with the t3 column projected out (its least-squares value eliminated)."""
    w = tcol / (tcol @ tcol)
    return a - np.outer(tcol, w @ a), rhs - tcol * (w @ rhs)


def choose_degree(uvs: list[np.ndarray], xys: list[np.ndarray], outer_down: bool) -> int:
    """f's degree by the Bayesian information criterion on the linear solution's ray error: the
    lowest that the corners ask for. A ring spans only part of f's domain, and elevations that are
    near linear in the radius (as many donuts are) need f(rho) = rho tan(elevation) beyond degree 4."""
    n = 2 * sum(len(u) for u in uvs)
    best: tuple[float, int] | None = None
    for deg in DEGREES:
        powers = np.array([0, *range(2, deg + 1)])
        err = _linear_solve(uvs, xys, powers, outer_down).err
        bic = n * math.log(max(err, 1e-12) ** 2) + len(powers) * math.log(n)
        if best is None or bic < best[0]:
            best = (bic, deg)
    assert best is not None
    return best[1]


def _full(coef: np.ndarray, powers: np.ndarray) -> np.ndarray:
    """Coefficients at `powers` -> the full ascending list (zeros elsewhere, a1 = 0)."""
    out = np.zeros(int(powers.max()) + 1)
    out[powers] = coef
    return out


# ---- the fit ------------------------------------------------------------------------------------
@dataclass
class ViewResult:
    frame: int
    held_out: bool
    rms: float  # px, sqrt(mean |residual|^2) over the view's corners
    residuals: np.ndarray  # (n, 2) px, detected - reprojected
    rvec: np.ndarray  # (3,) board -> OCamCalib frame
    tvec: np.ndarray  # (3,) metres
    facing: bool  # the board's printed face looks at the lens under a proper rotation


@dataclass
class OcamFit:
    ocam: Ocam
    views: list[ViewResult]
    rms_fit: float  # px, over every corner of the fitted views
    rms_held: float | None  # px, over every corner of the held-out views (None: none held out)
    linear_rms_deg: float  # the linear solution's ray error at the chosen centre
    seconds: float
    ccw_fit: bool | None  # the handedness the poses imply (None: the views disagree)
    degree: int = 4  # f's degree
    support: tuple[float, float] = (0.0, 0.0)  # px: radii from the optical centre the fitted corners cover
    notes: list[str] = field(default_factory=list)

    @property
    def per_image(self) -> dict[int, float]:
        return {v.frame: v.rms for v in self.views}


def _to_params(
    ocam_c: tuple[float, float], cde: tuple[float, float, float], coef: np.ndarray, poses: list[np.ndarray]
) -> np.ndarray:
    rv = [Rotation.from_matrix(_rot(p)).as_rotvec() for p in poses]
    tv = [p[2] for p in poses]
    poses_x = [np.concatenate([r, t]) for r, t in zip(rv, tv, strict=True)]
    return np.concatenate([[*ocam_c, *cde, 0.0, 0.0], coef, *poses_x])


def _rot(pose: np.ndarray) -> np.ndarray:
    """(3, 3) rotation with columns r1, r2, r1 x r2 from a linear pose (rows r1, r2, t)."""
    r1 = pose[0] / np.linalg.norm(pose[0])
    r2 = pose[1] - r1 * (r1 @ pose[1])
    r2 /= np.linalg.norm(r2)
    return np.column_stack([r1, r2, np.cross(r1, r2)])


def _model(params: np.ndarray, powers: np.ndarray, scale: float, size: tuple[int, int], nodes: np.ndarray) -> Ocam:
    """Parameters -> model. f enters as its values at `nodes` (scaled radii across the ring), not its
    coefficients: the monomials are nearly collinear over a ring and LM crawls along that valley."""
    cx, cy, c, d, e, p1, p2 = params[:N_FIXED]
    coef = np.linalg.solve(nodes[:, None] ** powers[None, :], params[N_FIXED : N_FIXED + len(powers)])
    coef = coef / scale ** (powers - 1.0)
    stretch = (float(c), float(d), float(e))
    return Ocam(
        (float(cx), float(cy)), stretch, tuple(_full(coef, powers).tolist()), size, (float(p1), float(p2)), scale
    )


def _project(ocam: Ocam, rvecs: np.ndarray, tvecs: np.ndarray, obj: np.ndarray, idx: np.ndarray) -> np.ndarray:
    """Pixels of board points `obj` (n, 3) of views `idx` (n,) under poses (m, 3) rvecs, tvecs."""
    rot = Rotation.from_rotvec(rvecs).as_matrix()
    p = np.einsum("nij,nj->ni", rot[idx], obj) + tvecs[idx]
    return ocam.world2cam(p, clamp=True)


def fit_ocam(
    detections: Sequence[View],
    image_size: tuple[int, int],
    ring: RingLike,
    holdout: int = 4,
    degree: int | None = None,
    outer_down: bool = False,
    search_px: float | None = None,
) -> OcamFit:
    """Fit Scaramuzza's model to board views (OCamCalib's method; module docstring).

    `holdout`: every `holdout`-th view (the 4th, 8th, ... in frame order; 0: none) is left out of
    the fit and scored afterwards with only its pose fitted. `degree`: f's (default: chosen by
    `choose_degree`). `search_px`: half-width of the centre search around the ring's centre
    (default 6 % of the outer radius, at least 8 px). Needs >= 3 fitted views of >= 6 corners each.
    """
    from threadpoolctl import threadpool_limits  # type: ignore[import-untyped]

    # Thousands of small least-squares solves: BLAS threads only fight over them (100x slower on
    # two busy cores), one thread each is fastest.
    with threadpool_limits(1, user_api="blas"):
        return _fit_ocam(detections, image_size, ring, holdout, degree, outer_down, search_px)


def _fit_ocam(
    detections: Sequence[View],
    image_size: tuple[int, int],
    ring: RingLike,
    holdout: int,
    degree: int | None,
    outer_down: bool,
    search_px: float | None,
) -> OcamFit:
    t0 = time.perf_counter()
    views = sorted((v for v in detections if len(v.image_points) >= 6), key=lambda v: v.frame)
    held = [holdout > 0 and i % holdout == holdout - 1 for i in range(len(views))]
    fit_v = [v for v, h in zip(views, held, strict=True) if not h]
    if len(fit_v) < 3:
        raise OmninavError(f"only {len(fit_v)} usable board views to fit; film the board in more places round the ring")
    scale = float(ring.r_outer)
    xys = [np.asarray(v.object_points, np.float64)[:, :2] for v in fit_v]
    pts = [np.asarray(v.image_points, np.float64) for v in fit_v]

    def uv_at(cx: float, cy: float) -> list[np.ndarray]:
        return [np.stack([p[:, 1] - cy, p[:, 0] - cx], -1) / scale for p in pts]

    if degree is None:
        degree = choose_degree(uv_at(*ring.center), xys, outer_down)
    powers = np.array([0, *range(2, degree + 1)])

    # Centre search: the linear solution's ray error around the ring's centre, a coarse grid
    # (the error is not convex far out) then Nelder-Mead from its best point.
    def lin_err(c: np.ndarray) -> float:
        return _linear_solve(uv_at(float(c[0]), float(c[1])), xys, powers, outer_down).err

    half = search_px if search_px is not None else max(8.0, 0.06 * scale)
    grid = [
        np.array(ring.center, float) + (dx, dy)
        for dx in np.linspace(-half, half, 5)
        for dy in np.linspace(-half, half, 5)
    ]
    start = min(grid, key=lin_err)
    step = half / 4
    simplex = np.array([start, start + (step, 0.0), start + (0.0, step)])
    nm = minimize(
        lin_err, start, method="Nelder-Mead", options={"initial_simplex": simplex, "xatol": 0.05, "fatol": 1e-12}
    )
    best = (float(nm.x[0]), float(nm.x[1]))
    lin = _linear_solve(uv_at(*best), xys, powers, outer_down)

    # Levenberg-Marquardt on reprojection error (px); scaled polynomial keeps the columns comparable.
    obj = np.concatenate([np.asarray(v.object_points, np.float64) for v in fit_v])
    obs = np.concatenate(pts)
    idx = np.concatenate([np.full(len(p), j) for j, p in enumerate(pts)])
    n_in = N_FIXED + len(powers)
    nodes = np.linspace(float(ring.r_inner) / scale, 1.0, len(powers))
    x0 = _to_params(best, (1.0, 0.0, 0.0), (nodes[:, None] ** powers[None, :]) @ lin.coef, lin.poses)

    def resid(x: np.ndarray) -> np.ndarray:
        oc = _model(x, powers, scale, image_size, nodes)
        pv = x[n_in:].reshape(-1, 6)
        return (_project(oc, pv[:, :3], pv[:, 3:], obj, idx) - obs).ravel()

    # OCamCalib's model first (the decentring held at 0), then with the decentring free; the second
    # is kept only where it explains the corners clearly better (DECENTRING_GAIN): on a symmetric
    # lens its two extra freedoms would only trade against the centre
    # Each view's residuals depend on the intrinsics and its own pose only: a sparse Jacobian, so
    # finite differences cost n_intrinsics + 6 evaluations, not 6 per view.
    sparsity = lil_matrix((2 * len(obs), len(x0)), dtype=int)
    sparsity[:, :n_in] = 1
    for j in range(len(fit_v)):
        rows = np.flatnonzero(np.repeat(idx == j, 2))
        sparsity[rows[:, None], n_in + 6 * j + np.arange(6)[None, :]] = 1
    free = np.ones(len(x0), bool)
    free[N_FIXED - 2 : N_FIXED] = False  # the decentring (p1, p2), the intrinsics' last two
    sol = _lm(resid, x0, free, sparsity)
    dec = _lm(resid, sol.x, np.ones(len(x0), bool), sparsity)
    if _rms(dec.fun.reshape(-1, 2)) < DECENTRING_GAIN * _rms(sol.fun.reshape(-1, 2)):
        sol = dec
    ocam = _model(sol.x, powers, scale, image_size, nodes)
    pv = sol.x[n_in:].reshape(-1, 6)

    results: list[ViewResult] = []
    k = 0
    for v, h in zip(views, held, strict=True):
        img = np.asarray(v.image_points, np.float64)
        o3 = np.asarray(v.object_points, np.float64)
        if h:
            rvec, tvec = pose_for(ocam, img, o3)
        else:
            rvec, tvec = pv[k, :3], pv[k, 3:]
            k += 1
        res = img - _project(ocam, rvec[None], tvec[None], o3, np.zeros(len(o3), int))
        rot = Rotation.from_rotvec(rvec).as_matrix()
        results.append(ViewResult(v.frame, h, _rms(res), res, rvec, tvec, bool(rot[:, 2] @ tvec > 0)))
    fit_res = np.concatenate([r.residuals for r in results if not r.held_out])
    held_res = [r.residuals for r in results if r.held_out]
    facing = [r.facing for r in results]
    # The OCamCalib frame (x rows, y columns, z up) is right-handed in the world when the printed
    # faces look at the lens; then the image angle grows clockwise seen from above: ccw False.
    ccw_fit = None if 0 < sum(facing) < len(facing) else not facing[0]
    notes = []
    if 0 < sum(facing) < len(facing):
        notes.append(
            f"board handedness differs between views ({sum(facing)} of {len(facing)} facing): mirror-labelled corners"
        )
    return OcamFit(
        ocam=ocam,
        views=results,
        rms_fit=_rms(fit_res),
        rms_held=_rms(np.concatenate(held_res)) if held_res else None,
        linear_rms_deg=math.degrees(lin.err),
        seconds=time.perf_counter() - t0,
        ccw_fit=ccw_fit,
        degree=degree,
        support=_support(ocam, obs),
        notes=notes,
    )


def _lm(resid: Callable[[np.ndarray], np.ndarray], x0: np.ndarray, free: np.ndarray, sparsity: Any) -> Any:
    """least_squares on the parameters where `free` (the others held at x0's values), given the
    residuals' Jacobian sparsity over all of them -> its result, `x` the whole parameter vector."""
    at = np.flatnonzero(free)

    def sub(y: np.ndarray) -> np.ndarray:
        x = x0.copy()
        x[at] = y
        return resid(x)

    sol = least_squares(
        sub, x0[at], jac_sparsity=sparsity[:, at], loss="soft_l1", f_scale=1.0, x_scale="jac", max_nfev=200
    )
    x = x0.copy()
    x[at] = sol.x
    sol.x = x
    return sol


def _support(ocam: Ocam, pts: np.ndarray) -> tuple[float, float]:
    """Radii (px from the optical centre) that the corners cover: 0.5 and 99.5 percentiles, so
    that a stray corner does not claim an edge."""
    uv = ocam.sensor(pts)
    r = np.hypot(uv[:, 0], uv[:, 1])
    return float(np.percentile(r, 0.5)), float(np.percentile(r, 99.5))


def _rms(res: np.ndarray) -> float:
    return float(np.sqrt(np.mean(np.sum(res**2, axis=1)))) if len(res) else float("nan")


def pose_for(ocam: Ocam, image_points: np.ndarray, object_points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """A board view's pose (rvec, tvec) with the model fixed: the linear pose (the r3 sign that
    fits f, and t3 by least squares), then least squares on its reprojection error."""
    uv = ocam.sensor(image_points)
    xy = np.asarray(object_points, np.float64)[:, :2]
    scale = float(np.max(np.hypot(uv[:, 0], uv[:, 1]))) or 1.0
    uvs = uv / scale
    powers = np.arange(len(ocam.poly))
    coef = np.asarray(ocam.poly) * scale ** (powers - 1.0)
    c = _pose_candidates(uvs, xy)
    best: tuple[float, np.ndarray] | None = None
    for k in (0, 1):
        a, tcol, rhs = _poly_rows(uvs, xy, c.r1[k], c.r2[k], c.t12, powers)
        r = rhs - a @ coef
        t = float(tcol @ r / (tcol @ tcol))
        err = float(np.sum((r - tcol * t) ** 2))
        if best is None or err < best[0]:
            best = (err, np.stack([c.r1[k], c.r2[k], np.array([c.t12[0], c.t12[1], t])]))
    assert best is not None
    pose = best[1]
    x0 = np.concatenate([Rotation.from_matrix(_rot(pose)).as_rotvec(), pose[2]])
    o3 = np.asarray(object_points, np.float64)
    img = np.asarray(image_points, np.float64)
    zero = np.zeros(len(o3), int)

    def resid(x: np.ndarray) -> np.ndarray:
        return (_project(ocam, x[None, :3], x[None, 3:], o3, zero) - img).ravel()

    sol = least_squares(resid, x0, loss="soft_l1", f_scale=1.0, x_scale="jac", method="trf", max_nfev=100)
    return sol.x[:3], sol.x[3:]


# ---- to lens.json -------------------------------------------------------------------------------
def ring_elevations(
    ocam: Ocam, r_inner: float, r_outer: float, n_r: int = 96, n_phi: int = 90
) -> tuple[np.ndarray, np.ndarray]:
    """(radii (n_r * n_phi,), elevations deg) the model gives to pixels around its centre over the ring."""
    r = np.linspace(r_inner, r_outer, n_r)
    phi = np.linspace(0, 2 * np.pi, n_phi, endpoint=False)
    rr, pp = np.meshgrid(r, phi)
    xy = np.stack([ocam.center[0] + rr * np.cos(pp), ocam.center[1] + rr * np.sin(pp)], -1).reshape(-1, 2)
    ray = ocam.cam2world(xy)
    el = np.rad2deg(np.arctan2(ray[:, 2], np.hypot(ray[:, 0], ray[:, 1])))
    return rr.ravel(), el


def to_profile(
    ocam: Ocam,
    ring: RingLike,
    forward_deg: float,
    ccw: bool,
    degree: int = 4,
    support: tuple[float, float] | None = None,
) -> tuple[Catadioptric, float]:
    """The lens.json profile of a fitted model: centre = the optical centre, r_inner/r_outer = the
    ring's measured edges (and `ring` = the measured ring), elevation = a `degree` polynomial of the
    radius fitted to atan2(f(rho), rho): the sensor radius rho where the profile has a `sensor`
    (profile_sensor: the stretch and decentring it holds), else the pixel radius in every direction.

    `support` (px): the radii the board's corners covered (`OcamFit.support`). The polynomial is
    fitted there only and carried on to the ring's edges: a whole board never reaches an edge, and
    there a high-degree f, free of data, bends away (0.5 deg at 15 px out on our renders) where the
    smooth low-degree profile does not.

    Returns (profile, elevation residual deg: the largest difference between the profile and the
    model over the supported radii; without a sensor the stretch's share included, with one the
    polynomial's only). Refuses a non-monotonic elevation."""
    r_in, r_out = float(ring.r_inner), float(ring.r_outer)
    lo, hi = (max(r_in, support[0]), min(r_out, support[1])) if support else (r_in, r_out)
    if hi - lo < 0.25 * (r_out - r_in):
        raise OmninavError(
            f"the board's corners cover radii {lo:.0f}-{hi:.0f} px of the ring's {r_in:.0f}-{r_out:.0f}: "
            "film the board near the ring's inner and outer edges too"
        )
    sensor = profile_sensor(ocam, r_out)
    if sensor is None:
        rr, el = ring_elevations(ocam, lo, hi)
    else:  # the profile's radius is the model's own sensor radius
        rr = np.linspace(lo, hi, 96)
        el = ocam.elevation(rr)
    s = r_out
    coef = np.polynomial.polynomial.polyfit(rr / s, el, degree)
    poly = coef / s ** np.arange(degree + 1)
    resid = float(np.max(np.abs(np.polynomial.polynomial.polyval(rr, poly) - el)))
    de = np.diff(np.polynomial.polynomial.polyval(np.linspace(r_in, r_out, 512), poly))
    if not (np.all(de > 0) or np.all(de < 0)):
        raise OmninavError(
            "the fitted elevation does not rise steadily across the ring; film the board over the whole ring "
            "(near the inner and the outer edge) and try again"
        )
    profile = Catadioptric(
        image_size=ocam.image_size,
        center=(round(ocam.center[0], 4), round(ocam.center[1], 4)),
        r_inner=round(r_in, 4),
        r_outer=round(r_out, 4),
        elevation_poly=tuple(float(p) for p in poly),
        forward_deg=round(float(forward_deg) % 360.0, 4),
        ccw=bool(ccw),
        ring=(float(ring.center[0]), float(ring.center[1]), r_in, r_out),
        sensor=sensor,
    )
    return profile, resid


def profile_sensor(ocam: Ocam, r_outer: float) -> Sensor | None:
    """lens.json's `sensor` of a fitted model (lens.Sensor, in (x, y) = (column, row) order): the
    stretch [[c, d], [e, 1]] on (row, column) is [[1, e], [d, c]] on (x, y), the decentring's
    (p1, p2) on (u, v) = (row, column) is (p2, p1) on (x, y). None where neither moves a pixel of
    the ring by SENSOR_PX beyond what a similarity does (a rotation and a scale, which forward_deg
    and the polynomial of the pixel radius absorb): a lens with no stretch or decentring to speak
    of, as every rendered one, keeps a profile of circles."""
    c, d, e = ocam.stretch
    p1, p2 = ocam.tangential
    sensor = Sensor((1.0, e, d, c), (p2, p1), ocam.unit)
    phi = np.linspace(0.0, 2.0 * np.pi, 72, endpoint=False)
    r = np.concatenate([np.full(72, 0.5 * r_outer), np.full(72, r_outer)])
    ox, oy = r * np.cos(np.tile(phi, 2)), r * np.sin(np.tile(phi, 2))
    sx, sy = sensor.to_pixel(ox, oy)
    m00, m01, m10, m11 = sensor.matrix
    a, b = 0.5 * (m00 + m11), 0.5 * (m10 - m01)  # the matrix's nearest similarity [[a, -b], [b, a]]
    moved = np.hypot(sx - (a * ox - b * oy), sy - (b * ox + a * oy))
    return None if float(np.max(moved)) < SENSOR_PX else sensor


# ---- forward and sense of rotation from the protocol ------------------------------------------
@dataclass(frozen=True)
class Orientation:
    forward_deg: float
    ccw: bool
    ahead_views: int  # views averaged for forward_deg
    turn_deg: float  # image-angle change to the first view clearly to the left


def board_angles(detections: Sequence[View], ocam: Ocam) -> Iterator[tuple[int, float]]:
    """(frame, image angle deg) of each view's board centre, in frame order: the centre of its
    corners' grid reprojected through the view's pose (exact under perspective, unlike the corners'
    mean). Lazy: the protocol needs only the first few."""
    for v in sorted(detections, key=lambda v: v.frame):
        if len(v.image_points) < 6:
            continue
        o3 = np.asarray(v.object_points, np.float64)
        rvec, tvec = pose_for(ocam, v.image_points, o3)
        c = Rotation.from_rotvec(rvec).as_matrix() @ o3.mean(0) + tvec
        # the image angle of the symmetric model, as lens.json's azimuth has it (the sensor point,
        # (u, v) = (row, column)): a pixel's own angle differs by the stretch and the decentring
        yield v.frame, math.degrees(math.atan2(c[0], c[1]))


def _wrap(a: float) -> float:
    return (a + 180.0) % 360.0 - 180.0


def protocol_orientation(detections: Sequence[View], ocam: Ocam) -> tuple[float, bool]:
    """(forward_deg, ccw) from the protocol: `orientation` has the details."""
    o = orientation(detections, ocam)
    return o.forward_deg, o.ccw


def orientation(detections: Sequence[View], ocam: Ocam, hold_deg: float = 5.0, turn_deg: float = 10.0) -> Orientation:
    """forward_deg and ccw from the protocol (calib/README.md): the video starts with the board held
    straight ahead of the phone, then moves it to the phone's LEFT.

    forward_deg: the mean image angle of the board's centre over the leading views within
    `hold_deg` of the first. ccw: moving left turns the world azimuth counter-clockwise (seen from
    above); ccw is true when that is the way the image angle grows, so ccw = the image angle of the
    first view more than `turn_deg` away from forward is larger than forward.
    """
    from threadpoolctl import threadpool_limits

    with threadpool_limits(1, user_api="blas"):  # small solves: see fit_ocam
        return _orientation(board_angles(detections, ocam), hold_deg, turn_deg)


def _orientation(angles: Iterator[tuple[int, float]], hold_deg: float, turn_deg: float) -> Orientation:
    first = next(angles, None)
    if first is None:
        raise OmninavError("the board was not seen; film it straight ahead of the phone, then move it to the left")
    ahead = [first[1]]
    holding = True
    for _, a in angles:
        if holding and abs(_wrap(a - first[1])) <= hold_deg:
            ahead.append(a)
            continue
        holding = False
        fwd = _circmean(ahead)
        turn = _wrap(a - fwd)
        if abs(turn) > turn_deg:
            return Orientation(forward_deg=fwd % 360.0, ccw=turn > 0, ahead_views=len(ahead), turn_deg=turn)
    raise OmninavError(
        "the board never moved away from straight ahead; after holding it in front, move it to the phone's left"
    )


def _circmean(deg: list[float]) -> float:
    r = np.radians(deg)
    return math.degrees(math.atan2(float(np.mean(np.sin(r))), float(np.mean(np.cos(r)))))


# ---- synthetic views (tests, bench): board corners projected through a known profile -------------
@dataclass(frozen=True)
class SyntheticView:
    frame: int
    image_points: np.ndarray  # (n, 2) px, noisy
    object_points: np.ndarray  # (n, 3) metres
    ids: np.ndarray  # (n,) corner index
    whole: bool
    truth: np.ndarray  # (n, 2) px, noise-free


def lens_direction(p: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(n, 3) points in the lens's world frame (x forward, y left, z up: right-handed) -> (azimuth
    clockwise from forward seen from above, elevation), degrees, as lens.json counts them."""
    az = np.rad2deg(np.arctan2(-p[:, 1], p[:, 0]))
    el = np.rad2deg(np.arctan2(p[:, 2], np.hypot(p[:, 0], p[:, 1])))
    return az, el


def synthetic_views(
    lens: Catadioptric,
    object_points: np.ndarray,
    n_views: int = 40,
    noise_px: float = 0.3,
    seed: int = 0,
    dist: tuple[float, float] = (1.0, 2.0),
    project: Callable[[np.ndarray, np.ndarray], tuple[np.ndarray, np.ndarray]] | None = None,
) -> list[SyntheticView]:
    """Board views following the protocol, projected through `lens` (lens.direction_to_pixel; or
    `project`, (azimuth, elevation) -> pixels, NaN where unseen: another camera model over the
    lens's elevations, as tests/calib/test_calib_mirrors.py's mirrors): two
    views straight ahead, then moving to the LEFT (azimuth decreasing), then on round the ring at
    varied elevations, distances (`dist`, in board widths) and tilts, the printed face always
    towards the lens. Only views with every corner inside the ring are kept (a chessboard is found
    whole or not at all). Gaussian pixel noise `noise_px` per axis."""
    from ..lens import direction_to_pixel

    rng = np.random.default_rng(seed)
    obj = np.asarray(object_points, np.float64)
    centred = obj - obj.mean(0)
    span = float(np.ptp(centred[:, :2], axis=0).max())
    lo, hi = lens.elevation_range()
    mid = 0.5 * (lo + hi)
    views: list[SyntheticView] = []
    tries = 0
    while len(views) < n_views and tries < 50 * n_views:
        tries += 1
        i = len(views)
        if i < 2:  # straight ahead, held still
            az0, el0, d, tilt = 0.0, mid, 2.0 * span, np.zeros(3)
        else:
            az0 = -25.0 * (i - 1) + rng.uniform(-6, 6) if i < 4 else rng.uniform(-180, 180)
            el0 = rng.uniform(lo, hi) if i >= 4 else mid  # views that leave the ring are dropped below
            d = rng.uniform(*dist) * span
            tilt = np.radians(rng.uniform([-35, -35, -25], [35, 35, 25]))
        a, e = math.radians(az0), math.radians(el0)
        zb = np.array([math.cos(e) * math.cos(a), -math.cos(e) * math.sin(a), math.sin(e)])  # away from the lens
        yb = np.array([0.0, 0.0, -1.0]) - zb * -zb[2]  # the page's "down" as near world-down as it can be
        yb /= np.linalg.norm(yb)
        xb = np.cross(yb, zb)
        basis = np.column_stack([xb, yb, zb]) @ Rotation.from_rotvec(tilt).as_matrix()
        p = d * zb + centred @ basis.T
        az, el = lens_direction(p)
        x, y = direction_to_pixel(lens, az, el) if project is None else project(az, el)
        truth = np.stack([x, y], -1)
        if not np.isfinite(truth).all():
            continue
        noisy = truth + rng.normal(0.0, noise_px, truth.shape)
        views.append(SyntheticView(i, noisy, obj.copy(), np.arange(len(obj)), True, truth))
    return views
