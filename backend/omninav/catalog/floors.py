"""Floors and their plans: a plan is a picture with a scale (pixels per metre).

Places, walk paths and answers are in metres on the floor, so a plan can be replaced or re-scaled
without touching them. A plan's size is read from its header before it is decoded (a 16,384^2 PNG
is a 100 KB upload and 800 MB decoded) and bounded: no screen needs more.
"""

from __future__ import annotations

import math
import re
import reprlib
import uuid
from pathlib import Path
from typing import TYPE_CHECKING, Any

import cv2
import numpy as np
from sqlalchemy import Connection, text

from ..errors import Conflict, NotFound, OmninavError, Unusable, is_finite_number
from .venues import bump, check_name

if TYPE_CHECKING:
    from . import Catalog

FLOOR_ID = re.compile(r"^[A-Za-z0-9][A-Za-z0-9_-]{0,31}$")
PLAN_MAX_PX = 8192  # a floor plan's side; more is no use on any screen, and costs memory to draw
PLAN_MAX_MEGAPIXELS = 40  # and its area (120 MB decoded)


def check_floor_id(floor: Any) -> str:
    if not isinstance(floor, str) or not FLOOR_ID.fullmatch(floor):  # match would let "1\n" through
        raise OmninavError(f"invalid floor id {floor!r}: use 1-32 letters, digits, '-' or '_'")
    return floor


def number(v: Any, what: str) -> float:
    if not is_finite_number(v):  # 1e400 written as an integer is one too
        raise OmninavError(f"{what} must be a finite number, got {reprlib.repr(v)}")
    return float(v)


def check_scale(px_per_m: Any) -> float:
    s = number(px_per_m, "'px_per_m'")
    if not s > 0:
        raise OmninavError("'px_per_m' must be positive")
    return s


def _point(v: Any, what: str) -> tuple[float, float]:
    if not isinstance(v, list) or len(v) != 2:
        raise OmninavError(f"{what} must be [x, y]")
    return number(v[0], f"{what}[0]"), number(v[1], f"{what}[1]")


def scale_from_points(s: Any) -> float:
    """Scale by two points clicked on the plan (pixels) and the real distance between them."""
    if not isinstance(s, dict):
        raise OmninavError('\'scale\' must be {"a": [x, y], "b": [x, y], "distance_m": d} in plan pixels')
    a, b = _point(s.get("a"), "scale 'a'"), _point(s.get("b"), "scale 'b'")
    d = number(s.get("distance_m"), "scale 'distance_m'")
    px = math.hypot(b[0] - a[0], b[1] - a[1])
    if d <= 0 or px <= 0:
        raise OmninavError("scale: the two points must differ and 'distance_m' must be positive")
    if not math.isfinite(px / d):  # points 1e308 apart, or 1e-300 m: no JSON number holds the scale
        raise OmninavError("scale: the points and 'distance_m' must give a finite number of pixels a metre")
    return px / d


def insert_floor(c: Connection, venue_id: str, floor: str, name: str, px_per_m: float | None) -> None:
    """Add a floor row in the caller's transaction (a new venue's first floor is made in the
    venue's own transaction, before the venue is committed)."""
    c.execute(
        text("INSERT INTO floors (venue, id, name, px_per_m) VALUES (:v, :f, :n, :s)"),
        {"v": venue_id, "f": floor, "n": name, "s": px_per_m},
    )


def decode_plan(data: bytes) -> np.ndarray:
    """A floor plan's bytes -> its pixels (upright), refused before decoding if too large."""
    from ..media import decode_image, probe_image

    head = probe_image(data)
    if head is None:
        raise Unusable("the floor plan is not a readable PNG or JPEG image")
    w, h = head.width, head.height
    if max(w, h) > PLAN_MAX_PX:
        raise Unusable(f"the floor plan is {w}x{h} pixels; at most {PLAN_MAX_PX} on a side")
    if w * h > PLAN_MAX_MEGAPIXELS * 1e6:
        raise Unusable(
            f"the floor plan is {w}x{h} pixels ({w * h / 1e6:.1f} megapixels); at most {PLAN_MAX_MEGAPIXELS} megapixels"
        )
    img = decode_image(data)  # OpenCV applies a JPEG's EXIF orientation
    if img is None:
        raise Unusable("the floor plan is not a readable PNG or JPEG image")
    return img


class Floors:
    def __init__(self, cat: Catalog):
        self.cat = cat
        self.db = cat.db

    def all(self, venue_id: str) -> list[dict[str, Any]]:
        return self.db.all("SELECT * FROM floors WHERE venue = :v ORDER BY id", v=venue_id)

    def get(self, venue_id: str, floor: str) -> dict[str, Any]:
        self.cat.venues.get(venue_id)
        row = self.db.one("SELECT * FROM floors WHERE venue = :v AND id = :f", v=venue_id, f=check_floor_id(floor))
        if row is None:
            raise NotFound(f"venue {venue_id!r} has no floor {floor!r}")
        return row

    def put(self, venue_id: str, floor: str, changes: dict[str, Any]) -> dict[str, Any]:
        """Create or edit a floor: 'name', and the scale as 'px_per_m' or as 'scale' (two points
        on the plan and their distance)."""
        self.cat.venues.get(venue_id)
        check_floor_id(floor)
        old = self.db.one("SELECT * FROM floors WHERE venue = :v AND id = :f", v=venue_id, f=floor)
        name = check_name(changes.get("name", old["name"] if old else f"Floor {floor}"), "floor")
        px_per_m = old["px_per_m"] if old else None
        if "px_per_m" in changes:
            px_per_m = check_scale(changes["px_per_m"])
        if "scale" in changes:
            px_per_m = scale_from_points(changes["scale"])
        with self.db.tx() as c:
            if old:
                c.execute(
                    text("UPDATE floors SET name = :n, px_per_m = :s WHERE venue = :v AND id = :f"),
                    {"n": name, "s": px_per_m, "v": venue_id, "f": floor},
                )
            else:
                insert_floor(c, venue_id, floor, name, px_per_m)
            bump(c, venue_id)
        return self.get(venue_id, floor)

    def plan_path(self, venue_id: str, floor: str) -> Path:
        return self.cat.data / "plans" / venue_id / f"{floor}.png"

    def set_plan(self, venue_id: str, floor: str, data: bytes) -> dict[str, Any]:
        """Store a floor's plan (PNG or JPEG bytes) as PNG: written beside, then, inside the row's
        transaction and after its bump (which refuses a writer's stale revision), renamed over the
        old plan; so a refused write leaves the old plan."""
        self.get(venue_id, floor)
        img = decode_plan(data)
        h, w = img.shape[:2]
        p = self.plan_path(venue_id, floor)
        p.parent.mkdir(parents=True, exist_ok=True)
        tmp = p.with_name(f".{p.stem}.{uuid.uuid4().hex[:8]}.tmp.png")
        cv2.imwrite(str(tmp), img)
        try:
            with self.db.tx() as c:
                bump(c, venue_id)
                c.execute(
                    text("UPDATE floors SET plan_file = :p, plan_w = :w, plan_h = :h WHERE venue = :v AND id = :f"),
                    {"p": p.name, "w": w, "h": h, "v": venue_id, "f": floor},
                )
                tmp.replace(p)
        finally:
            tmp.unlink(missing_ok=True)
        return self.get(venue_id, floor)

    @staticmethod
    def extent_m(f: dict[str, Any]) -> tuple[float, float]:
        """The floor's plan in metres (width, height): what walk paths and places must lie in."""
        if not f["plan_file"] or not f["px_per_m"]:
            raise Conflict(f"floor {f['id']!r} needs a floor plan and its scale first (PUT .../floors/{f['id']}/plan)")
        return f["plan_w"] / f["px_per_m"], f["plan_h"] / f["px_per_m"]
