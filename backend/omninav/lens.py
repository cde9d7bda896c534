"""Lens profiles (`lens.json`, docs/formats.md): which camera pixel looks in which direction.

Two models: a catadioptric "donut" lens (the paper's Eq. 1 geometry) and an equirectangular
360-camera frame. Every direction is expressed as (azimuth, elevation) in degrees relative to the
lens's forward direction: azimuth grows *clockwise seen from above* (the plan heading convention),
elevation is 0 at the horizon and positive upwards.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from .errors import OmninavError, finite, read_json

# lens.json's `sensor` bounds, shared with the phone's lens.ts: a real mirror's decentring is a few
# hundredths, and up to MAX_DECENTRING the term folds the plane no nearer the centre than twice
# `scale` (about 1 / (6 |p|)), outside any ring, so every pixel has one direction; the matrix near
# the identity (its determinant within DETERMINANT, off-diagonals under MAX_SKEW)
SENSOR_LIMITS: dict[str, Any] = json.loads((Path(__file__).parent / "sensor_limits.json").read_text())
MAX_DECENTRING = float(SENSOR_LIMITS["MAX_DECENTRING"])
DETERMINANT: tuple[float, float] = (float(SENSOR_LIMITS["DETERMINANT"][0]), float(SENSOR_LIMITS["DETERMINANT"][1]))
MAX_SKEW = float(SENSOR_LIMITS["MAX_SKEW"])


def decentring(x: np.ndarray, y: np.ndarray, p: tuple[float, float], s: float) -> tuple[np.ndarray, np.ndarray]:
    """Brown-Conrady's tangential term t((x, y) / s) of offsets (x, y) px, in units of s: the
    point is seen at (x, y) + s t. One formula for lens.json's Sensor and calib's Ocam (and the
    phone's lens.ts `sensorInto`, in the same order)."""
    p1, p2 = p
    xn = x / s
    yn = y / s
    q = xn * xn + yn * yn
    return 2.0 * p1 * xn * yn + p2 * (q + 2.0 * xn * xn), p1 * (q + 2.0 * yn * yn) + 2.0 * p2 * xn * yn


def undo_decentring(ux: np.ndarray, uy: np.ndarray, p: tuple[float, float], s: float) -> tuple[np.ndarray, np.ndarray]:
    """The offsets (x, y) whose decentred point (x, y) + s t((x, y) / s) is (ux, uy), by Newton's
    method on the term's 2x2 Jacobian from (ux, uy) (the term is a few hundredths of the offset on
    a real mirror: three or four steps reach a millionth of a pixel). NaN where it does not
    converge: far enough out the quadratic term folds the plane, and no direction is seen there."""
    p1, p2 = p
    ux = np.asarray(ux, np.float64)
    uy = np.asarray(uy, np.float64)
    x, y = ux, uy
    with np.errstate(all="ignore"):
        for step in range(11):
            tx, ty = decentring(x, y, p, s)
            fx, fy = x + s * tx - ux, y + s * ty - uy
            xn, yn = x / s, y / s
            # the Jacobian [[a, b], [b, d]] (symmetric)
            a, b, d = (
                1.0 + 2.0 * p1 * yn + 6.0 * p2 * xn,
                2.0 * p1 * xn + 2.0 * p2 * yn,
                1.0 + 6.0 * p1 * yn + 2.0 * p2 * xn,
            )
            det = a * d - b * b
            if step == 10:
                break
            x, y = x - (d * fx - b * fy) / det, y - (a * fy - b * fx) / det
        # converged, and on the sheet that holds the centre (the Jacobian's determinant positive)
        ok = (np.hypot(fx, fy) <= 1e-6 * s) & (det > 0)
    return np.where(ok, x, np.nan), np.where(ok, y, np.nan)


@dataclass(frozen=True)
class Sensor:
    """Where a real mirror's picture departs from a radially symmetric one (lens.json `sensor`).

    The symmetric model puts a direction at the offset o = r(el) (cos phi, sin phi) from `center`;
    the pixel that sees it is center + M (o + s t(o / s)): t the decentring (tangential) term of
    the Brown-Conrady model, t_x = 2 p1 x y + p2 (q + 2 x^2), t_y = p1 (q + 2 y^2) + 2 p2 x y with
    q = x^2 + y^2, for a mirror whose axis is not the camera's; M a 2x2 matrix for a sensor whose
    pixels are not square or whose axes are skewed (OCamCalib's stretch). `calib lens` fits both
    (calib/ocam.py): on a real catadioptric camera's corners they take the reprojection error
    from 2.0 to 0.80 px (docs/decisions.md, "Decentring").
    """

    matrix: tuple[float, float, float, float] = (1.0, 0.0, 0.0, 1.0)  # m00, m01, m10, m11
    tangential: tuple[float, float] = (0.0, 0.0)  # p1, p2
    scale: float = 1.0  # s, pixels: the offsets' unit in t (the ring's outer radius)

    def to_pixel(self, ox: np.ndarray, oy: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Symmetric offsets (px) -> the offsets from `center` of the pixels that see them
        (the phone's lens.ts `sensorOffsets` does the same operations in the same order)."""
        m00, m01, m10, m11 = self.matrix
        tx, ty = decentring(ox, oy, self.tangential, self.scale)
        ux = ox + self.scale * tx
        uy = oy + self.scale * ty
        return m00 * ux + m01 * uy, m10 * ux + m11 * uy

    def from_pixel(self, dx: np.ndarray, dy: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Offsets of pixels from `center` -> the symmetric offsets they see (to_pixel's inverse):
        the matrix solved, the decentring undone (undo_decentring); NaN where no offset maps there."""
        m00, m01, m10, m11 = self.matrix
        det = m00 * m11 - m01 * m10
        ux = (m11 * dx - m01 * dy) / det
        uy = (m00 * dy - m10 * dx) / det
        return undo_decentring(ux, uy, self.tangential, self.scale)

    def to_dict(self) -> dict[str, Any]:
        m00, m01, m10, m11 = self.matrix
        return {"matrix": [[m00, m01], [m10, m11]], "tangential": list(self.tangential), "scale": self.scale}


@dataclass(frozen=True)
class Catadioptric:
    image_size: tuple[int, int]
    center: tuple[float, float]
    r_inner: float
    r_outer: float
    elevation_poly: tuple[float, ...]
    forward_deg: float = 0.0
    ccw: bool = True
    # The ring's visible edges (cx, cy, r_inner, r_outer) as `omninav calib` measured them when the
    # profile was made. A re-clipped lens is corrected by how far the ring moved from *these*, not
    # from `center`: the optical centre a board fit finds may sit a few pixels off the ring's.
    # None (hand-typed and rendered profiles): the ring is `center`, `r_inner`, `r_outer`.
    ring: tuple[float, float, float, float] | None = None
    # A real mirror's departure from radial symmetry (Sensor); None: none (rendered and hand-typed
    # profiles, and those made before `calib lens` fitted it)
    sensor: Sensor | None = None
    model: str = field(default="catadioptric", init=False)

    def elevation(self, r: np.ndarray) -> np.ndarray:
        """Elevation (deg) seen at radius r (px): the profile's polynomial, ascending powers."""
        elev: np.ndarray = np.polynomial.polynomial.polyval(r, np.asarray(self.elevation_poly, np.float64))
        return elev

    def elevation_range(self) -> tuple[float, float]:
        e = self.elevation(np.array([self.r_inner, self.r_outer]))
        return float(e.min()), float(e.max())

    def radius(self, elev_deg: np.ndarray) -> np.ndarray:
        """Inverse of `elevation` over [r_inner, r_outer] (monotonic): dense table + interpolation.

        Elevations outside the ring map to NaN so that callers can tell "not seen" from "seen".
        """
        r = np.linspace(self.r_inner, self.r_outer, 4097)
        e = self.elevation(r)
        if e[0] > e[-1]:
            r, e = r[::-1], e[::-1]
        out = np.interp(np.asarray(elev_deg, np.float64), e, r, left=np.nan, right=np.nan)
        return out

    def reference_ring(self) -> tuple[float, float, float, float]:
        """(cx, cy, r_inner, r_outer) of the ring this profile was made with (see `ring`)."""
        return self.ring or (self.center[0], self.center[1], self.r_inner, self.r_outer)

    def to_dict(self) -> dict[str, Any]:
        d: dict[str, Any] = {
            "model": "catadioptric",
            "image_size": list(self.image_size),
            "center": list(self.center),
            "r_inner": self.r_inner,
            "r_outer": self.r_outer,
            "elevation_poly": list(self.elevation_poly),
            "forward_deg": self.forward_deg,
            "ccw": self.ccw,
        }
        if self.ring is not None:
            cx, cy, ri, ro = self.ring
            d["ring"] = {"center": [cx, cy], "r_inner": ri, "r_outer": ro}
        if self.sensor is not None:
            d["sensor"] = self.sensor.to_dict()
        return d

    def pixel(self, ox: np.ndarray, oy: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The pixel (x, y) that sees the symmetric offset (ox, oy) from the centre."""
        if self.sensor is None:
            return self.center[0] + ox, self.center[1] + oy
        sx, sy = self.sensor.to_pixel(ox, oy)
        return self.center[0] + sx, self.center[1] + sy


@dataclass(frozen=True)
class Equirectangular:
    image_size: tuple[int, int]
    forward_x: float
    ccw: bool = False
    model: str = field(default="equirectangular", init=False)

    def elevation_range(self) -> tuple[float, float]:
        return -90.0, 90.0

    def to_dict(self) -> dict[str, Any]:
        return {
            "model": "equirectangular",
            "image_size": list(self.image_size),
            "forward_x": self.forward_x,
            "ccw": self.ccw,
        }


Lens = Catadioptric | Equirectangular


def _need(d: dict[str, Any], key: str, where: str) -> Any:
    if key not in d:
        raise OmninavError(f"{where}: lens profile is missing the field '{key}'")
    return d[key]


def _num(v: Any, key: str, where: str) -> float:
    return finite(v, f"lens field '{key}'", where)


def _flag(d: dict[str, Any], key: str, default: bool, where: str) -> bool:
    """A true/false field: "false" or 0 would otherwise read as true or be guessed at."""
    v = d.get(key, default)
    if not isinstance(v, bool):
        raise OmninavError(f"{where}: lens field '{key}' must be true or false, got {v!r}")
    return v


def _whole(x: Any) -> bool:
    """A JSON integer: 720, or 720.0 as some encoders write it (JSON Schema counts both)."""
    return not isinstance(x, bool) and (isinstance(x, int) or (isinstance(x, float) and x.is_integer()))


def _size(v: Any, where: str) -> tuple[int, int]:
    if not isinstance(v, list | tuple) or len(v) != 2 or not all(_whole(x) and x > 0 for x in v):
        raise OmninavError(f"{where}: lens field 'image_size' must be [width, height] in pixels")
    return int(v[0]), int(v[1])


def _ring(v: Any, where: str) -> tuple[float, float, float, float] | None:
    """The optional measured ring: {"center": [x, y], "r_inner": r, "r_outer": R}."""
    if v is None:
        return None
    if not isinstance(v, dict) or not isinstance(v.get("center"), list | tuple) or len(v["center"]) != 2:
        raise OmninavError(f'{where}: lens field \'ring\' must be {{"center": [x, y], "r_inner": r, "r_outer": R}}')
    cx, cy = (_num(c, "ring", where) for c in v["center"])
    ri, ro = _num(v.get("r_inner"), "ring", where), _num(v.get("r_outer"), "ring", where)
    if not 0 <= ri < ro:
        raise OmninavError(f"{where}: lens field 'ring' needs 0 <= r_inner < r_outer, got {ri}, {ro}")
    return cx, cy, ri, ro


def _sensor(v: Any, where: str) -> Sensor | None:
    """The optional {"matrix": [[a, b], [c, d]], "tangential": [p1, p2], "scale": s}."""
    if v is None:
        return None
    shape = (
        '{"matrix": [[a, b], [c, d]], "tangential": [p1, p2], "scale": s}'
        " (a matrix near the identity, |p| <= 0.08, s > 0)"
    )
    m, t = (v.get("matrix"), v.get("tangential")) if isinstance(v, dict) else (None, None)
    rows_ok = isinstance(m, list | tuple) and len(m) == 2
    rows_ok = rows_ok and all(isinstance(r, list | tuple) and len(r) == 2 for r in m)  # type: ignore[union-attr]
    if not rows_ok or not isinstance(t, list | tuple) or len(t) != 2:
        raise OmninavError(f"{where}: lens field 'sensor' must be {shape}")
    assert isinstance(v, dict) and isinstance(m, list | tuple)
    mat = tuple(_num(x, "sensor", where) for r in m for x in r)
    p = tuple(_num(x, "sensor", where) for x in t)
    s = _num(v.get("scale"), "sensor", where)
    det = mat[0] * mat[3] - mat[1] * mat[2]
    # near the identity and a small decentring (a real mirror's is a few hundredths)
    lo, hi = DETERMINANT
    near = lo < det < hi and max(abs(mat[1]), abs(mat[2])) < MAX_SKEW and max(map(abs, p)) <= MAX_DECENTRING
    if not (s > 0 and near):
        raise OmninavError(f"{where}: lens field 'sensor' must be {shape}")
    return Sensor((mat[0], mat[1], mat[2], mat[3]), (p[0], p[1]), s)


def lens_from_dict(d: Any, where: str = "lens") -> Lens:
    """Validate a parsed `lens.json` and build the profile; every problem names its field."""
    if not isinstance(d, dict):
        raise OmninavError(f"{where}: a lens profile must be a JSON object")
    model = _need(d, "model", where)
    if model == "catadioptric":
        size = _size(_need(d, "image_size", where), where)
        c = _need(d, "center", where)
        if not isinstance(c, list | tuple) or len(c) != 2:
            raise OmninavError(f"{where}: lens field 'center' must be [x, y] in pixels")
        center = (_num(c[0], "center", where), _num(c[1], "center", where))
        r_in = _num(_need(d, "r_inner", where), "r_inner", where)
        r_out = _num(_need(d, "r_outer", where), "r_outer", where)
        if not 0 <= r_in < r_out:
            raise OmninavError(f"{where}: lens needs 0 <= r_inner < r_outer, got {r_in}, {r_out}")
        poly = _need(d, "elevation_poly", where)
        if not isinstance(poly, list | tuple) or not 1 <= len(poly) <= 8:
            raise OmninavError(f"{where}: lens field 'elevation_poly' must be a list of 1-8 numbers")
        coeffs = tuple(_num(p, "elevation_poly", where) for p in poly)
        lens = Catadioptric(
            image_size=size,
            center=center,
            r_inner=r_in,
            r_outer=r_out,
            elevation_poly=coeffs,
            forward_deg=_num(d.get("forward_deg", 0.0), "forward_deg", where),
            ccw=_flag(d, "ccw", True, where),
            ring=_ring(d.get("ring"), where),
            sensor=_sensor(d.get("sensor"), where),
        )
        with np.errstate(all="ignore"):  # huge coefficients or radii overflow: refused below, not raised
            e = lens.elevation(np.linspace(r_in, r_out, 512))
            de = np.diff(e)
        if not np.isfinite(e).all():
            raise OmninavError(f"{where}: 'elevation_poly' overflows over [r_inner, r_outer]")
        if not (np.all(de > 0) or np.all(de < 0)):
            raise OmninavError(f"{where}: 'elevation_poly' is not monotonic over [r_inner, r_outer]")
        return lens
    if model == "equirectangular":
        size = _size(_need(d, "image_size", where), where)
        return Equirectangular(
            image_size=size,
            forward_x=_num(_need(d, "forward_x", where), "forward_x", where),
            ccw=_flag(d, "ccw", False, where),
        )
    raise OmninavError(f"{where}: unknown lens model {model!r} (expected 'catadioptric' or 'equirectangular')")


def load_lens(path: str | Path) -> Lens:
    return lens_from_dict(read_json(path, "lens profile"), where=str(path))


def direction_to_pixel(lens: Lens, az_deg: np.ndarray, el_deg: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Pixel (x, y) that sees direction (azimuth clockwise from forward, elevation), float64.

    For the donut this is the paper's Eq. 1 (polar to Cartesian), generalised by the calibrated
    radius-elevation polynomial instead of a linear radius.
    """
    az = np.asarray(az_deg, np.float64)
    el = np.asarray(el_deg, np.float64)
    if isinstance(lens, Catadioptric):
        r = lens.radius(el)
        sign = -1.0 if lens.ccw else 1.0
        phi = np.deg2rad(lens.forward_deg + sign * az)
        return lens.pixel(r * np.cos(phi), r * np.sin(phi))
    w, h = lens.image_size
    sign = -1.0 if lens.ccw else 1.0
    x = np.mod(lens.forward_x + sign * az * w / 360.0, w)
    y = (90.0 - el) * h / 180.0 - 0.5
    return x, y


def pixel_to_direction(lens: Lens, x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Direction (azimuth, elevation) in degrees seen by pixel (x, y); inverse of the above."""
    x = np.asarray(x, np.float64)
    y = np.asarray(y, np.float64)
    if isinstance(lens, Catadioptric):
        dx, dy = x - lens.center[0], y - lens.center[1]
        if lens.sensor is not None:
            dx, dy = lens.sensor.from_pixel(dx, dy)
        r = np.hypot(dx, dy)
        phi = np.rad2deg(np.arctan2(dy, dx))
        sign = -1.0 if lens.ccw else 1.0
        az = np.mod(sign * (phi - lens.forward_deg), 360.0)
        el = lens.elevation(r)
        el = np.where((r >= lens.r_inner) & (r <= lens.r_outer), el, np.nan)
        return az, el
    w, h = lens.image_size
    sign = -1.0 if lens.ccw else 1.0
    az = np.mod(sign * (x - lens.forward_x) * 360.0 / w, 360.0)
    el = 90.0 - (y + 0.5) * 180.0 / h
    return az, el
