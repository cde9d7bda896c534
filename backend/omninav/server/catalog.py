"""The venue catalogue: what the admin edits and the public API shows.

Metadata lives in the database (db.py); a venue's modelled frames in its store directory
(store.py); floor plans and modelling videos as files under the data directory. Every edit bumps
the venue's `revision`, which is how each worker notices that its cached copy is stale.
"""

from __future__ import annotations

import json
import math
import re
import reprlib
import time
import uuid
from pathlib import Path
from typing import Any

import cv2
from sqlalchemy import Connection, text

from ..errors import OmninavError, is_finite_number
from ..lens import Lens, lens_from_dict
from ..model_venue import remove_video
from ..presets import PRESETS, n_curves, settings_id
from ..spectrum import HEADER_BYTES, record_bytes_per_frame
from ..store import Store, check_id
from ..track import Track, parse_track
from .db import Db, inline_lens_name
from .http import ApiError

FLOOR_ID = re.compile(r"^[A-Za-z0-9][A-Za-z0-9_-]{0,31}$")
VIDEO_NAME = re.compile(r"^[A-Za-z0-9][A-Za-z0-9_-]*(\.[A-Za-z0-9_-]+)*$")
PLAN_MAX_PX = 8192  # a floor plan's side; more is no use on any screen, and costs memory to draw
PLAN_MAX_MEGAPIXELS = 40  # and its area (120 MB decoded)
DEFAULT_LENS = "default"


def valid_venue_id(venue_id: str) -> str:
    try:
        return check_id(venue_id)
    except OmninavError as e:
        raise ApiError(400, str(e)) from None


def valid_floor_id(floor: str) -> str:
    if not isinstance(floor, str) or not FLOOR_ID.fullmatch(floor):  # match would let "1\n" through
        raise ApiError(400, f"invalid floor id {floor!r}: use 1-32 letters, digits, '-' or '_'")
    return floor


def valid_video_name(name: str) -> str:
    if not isinstance(name, str) or len(name) > 128 or not VIDEO_NAME.fullmatch(name) or name.endswith(".part"):
        raise ApiError(
            400, f"invalid video name {name!r}: use up to 128 letters, digits, '-', '_' and dots between them"
        )
    return name


def _num(v: Any, what: str) -> float:
    if not is_finite_number(v):  # 1e400 written as an integer is one too
        raise ApiError(400, f"{what} must be a finite number, got {reprlib.repr(v)}")
    return float(v)


def _point(v: Any, what: str) -> tuple[float, float]:
    if not isinstance(v, list) or len(v) != 2:
        raise ApiError(400, f"{what} must be [x, y]")
    return _num(v[0], f"{what}[0]"), _num(v[1], f"{what}[1]")


class Catalog:
    def __init__(self, db: Db, data: Path):
        self.db = db
        self.data = Path(data)
        self.store = Store(self.data)

    # ---- venues -------------------------------------------------------------------------------
    def venue(self, venue_id: str) -> dict[str, Any]:
        row = self.db.one("SELECT * FROM venues WHERE id = :id", id=valid_venue_id(venue_id))
        if row is None:
            raise ApiError(404, f"unknown venue {venue_id!r}")
        return row

    def venues(self) -> list[dict[str, Any]]:
        return self.db.all("SELECT * FROM venues ORDER BY id")

    def bump(self, venue_id: str) -> None:
        self.db.run("UPDATE venues SET revision = revision + 1 WHERE id = :id", id=venue_id)

    def create_venue(self, venue_id: str, name: str, preset: str = "default") -> dict[str, Any]:
        valid_venue_id(venue_id)
        if preset not in PRESETS:
            raise ApiError(400, f"unknown preset {preset!r} (use one of {', '.join(PRESETS)})")
        if self.db.one("SELECT id FROM venues WHERE id = :id", id=venue_id):
            raise ApiError(409, f"venue {venue_id!r} already exists")
        # The rows and the store folder together: the folder is made inside the transaction, after
        # the database has taken the rows, and removed again if anything fails, so a refused venue
        # leaves nothing behind (a name the database cannot store used to leave an orphan folder).
        d = self.store.venue_dir(venue_id)
        new_dir = not d.exists()  # a venue made by the CLI keeps its folder: only the rows are new
        try:
            with self.db.tx() as c:
                c.execute(
                    text("INSERT INTO venues (id, name, preset, created, revision) VALUES (:id, :n, :p, :t, 1)"),
                    {"id": venue_id, "n": name, "p": preset, "t": time.time()},
                )
                self._insert_floor(c, venue_id, "1", "Floor 1", None)  # in this transaction, not put_floor's
                if not self.store.exists(venue_id):
                    self.store.create(venue_id, name=name, preset=preset)
        except BaseException:
            if new_dir:
                import shutil  # here only: the one place the catalogue removes a folder it made

                shutil.rmtree(d, ignore_errors=True)
            raise
        return self.venue(venue_id)

    def rename_venue(self, venue_id: str, name: str) -> None:
        self.venue(venue_id)
        self.db.run("UPDATE venues SET name = :n, revision = revision + 1 WHERE id = :id", id=venue_id, n=name)

    def settings(self, venue_id: str) -> dict[str, Any]:
        return self.store.settings(venue_id)

    def doc(self, venue_id: str, url_root: str = "") -> dict[str, Any]:
        """The public description of a venue: all a client needs to extract matching features."""
        v = self.venue(venue_id)
        conf = self.settings(venue_id)
        frames = self.store.frame_count(venue_id)
        return {
            "id": v["id"],
            "name": v["name"],
            "revision": v["revision"],
            "modelled": frames > 0,
            "frames": frames,
            "floors": [self.floor_doc(venue_id, f, url_root) for f in self.floors(venue_id)],
            "places": self.places(venue_id),
            "lenses": {r["name"]: json.loads(r["profile"]) for r in self._lens_rows(venue_id)},
            "features": {
                "preset": v["preset"],
                "settings": {k: conf[k] for k in sorted(conf)},
                "settings_id": settings_id(conf),
                "n_curves": n_curves(conf),
                "n_harmonics": conf["n_harmonics"],
                "record_header_bytes": HEADER_BYTES,
                "record_bytes_per_frame": record_bytes_per_frame(conf),
            },
        }

    # ---- floors -------------------------------------------------------------------------------
    def floors(self, venue_id: str) -> list[dict[str, Any]]:
        return self.db.all("SELECT * FROM floors WHERE venue = :v ORDER BY id", v=venue_id)

    def floor(self, venue_id: str, floor: str) -> dict[str, Any]:
        self.venue(venue_id)
        row = self.db.one("SELECT * FROM floors WHERE venue = :v AND id = :f", v=venue_id, f=valid_floor_id(floor))
        if row is None:
            raise ApiError(404, f"venue {venue_id!r} has no floor {floor!r}")
        return row

    def floor_doc(self, venue_id: str, f: dict[str, Any], url_root: str = "") -> dict[str, Any]:
        has_plan = bool(f["plan_file"])
        return {
            "id": f["id"],
            "name": f["name"],
            "plan_url": f"{url_root}/api/venues/{venue_id}/floors/{f['id']}/plan.png" if has_plan else None,
            "plan_size_px": [f["plan_w"], f["plan_h"]] if has_plan else None,
            "px_per_m": f["px_per_m"],
        }

    def put_floor(self, venue_id: str, floor: str, body: dict[str, Any]) -> dict[str, Any]:
        self.venue(venue_id)
        valid_floor_id(floor)
        old = self.db.one("SELECT * FROM floors WHERE venue = :v AND id = :f", v=venue_id, f=floor)
        name = body.get("name", old["name"] if old else f"Floor {floor}")
        if not isinstance(name, str) or not name.strip() or len(name) > 200:
            raise ApiError(400, "floor 'name' must be a non-empty string of at most 200 characters")
        px_per_m = old["px_per_m"] if old else None
        if "px_per_m" in body:
            px_per_m = _num(body["px_per_m"], "'px_per_m'")
        if "scale" in body:
            px_per_m = self._scale_from_points(body["scale"])
        if px_per_m is not None and not px_per_m > 0:
            raise ApiError(400, "'px_per_m' must be positive")
        with self.db.tx() as c:
            if old:
                c.execute(
                    text("UPDATE floors SET name = :n, px_per_m = :s WHERE venue = :v AND id = :f"),
                    {"n": name.strip(), "s": px_per_m, "v": venue_id, "f": floor},
                )
            else:
                self._insert_floor(c, venue_id, floor, name.strip(), px_per_m)
            c.execute(text("UPDATE venues SET revision = revision + 1 WHERE id = :id"), {"id": venue_id})
        return self.floor(venue_id, floor)

    @staticmethod
    def _insert_floor(c: Connection, venue_id: str, floor: str, name: str, px_per_m: float | None) -> None:
        """Add a floor row in the caller's transaction: put_floor's, or create_venue's for a new
        venue's first floor (put_floor itself cannot serve there: it opens its own transaction and
        looks the venue up, which create_venue has not committed yet)."""
        c.execute(
            text("INSERT INTO floors (venue, id, name, px_per_m) VALUES (:v, :f, :n, :s)"),
            {"v": venue_id, "f": floor, "n": name, "s": px_per_m},
        )

    @staticmethod
    def _scale_from_points(s: Any) -> float:
        """Scale by two points clicked on the plan (pixels) and the real distance between them."""
        if not isinstance(s, dict):
            raise ApiError(400, '\'scale\' must be {"a": [x, y], "b": [x, y], "distance_m": d} in plan pixels')
        a, b = _point(s.get("a"), "scale 'a'"), _point(s.get("b"), "scale 'b'")
        d = _num(s.get("distance_m"), "scale 'distance_m'")
        px = math.hypot(b[0] - a[0], b[1] - a[1])
        if d <= 0 or px <= 0:
            raise ApiError(400, "scale: the two points must differ and 'distance_m' must be positive")
        if not math.isfinite(px / d):  # points 1e308 apart, or 1e-300 m: no JSON number holds the scale
            raise ApiError(400, "scale: the points and 'distance_m' must give a finite number of pixels a metre")
        return px / d

    def plan_path(self, venue_id: str, floor: str) -> Path:
        return self.data / "plans" / venue_id / f"{floor}.png"

    def set_plan(self, venue_id: str, floor: str, data: bytes) -> dict[str, Any]:
        self.floor(venue_id, floor)
        # The size from the header first: a 16384^2 plan is a 100 KB upload and 800 MB decoded
        from .media import decode_image, probe_image

        head = probe_image(data)
        if head is None:
            raise ApiError(422, "the floor plan is not a readable PNG or JPEG image")
        w, h = head.width, head.height
        if max(w, h) > PLAN_MAX_PX:
            raise ApiError(422, f"the floor plan is {w}x{h} pixels; at most {PLAN_MAX_PX} on a side")
        if w * h > PLAN_MAX_MEGAPIXELS * 1e6:
            raise ApiError(
                422,
                f"the floor plan is {w}x{h} pixels ({w * h / 1e6:.1f} megapixels); "
                f"at most {PLAN_MAX_MEGAPIXELS} megapixels",
            )
        img = decode_image(data)
        if img is None:
            raise ApiError(422, "the floor plan is not a readable PNG or JPEG image")
        h, w = img.shape[:2]  # upright: OpenCV applies a JPEG's EXIF orientation
        p = self.plan_path(venue_id, floor)
        p.parent.mkdir(parents=True, exist_ok=True)
        tmp = p.with_suffix(".tmp.png")
        cv2.imwrite(str(tmp), img)
        tmp.replace(p)
        self.db.run(
            "UPDATE floors SET plan_file = :p, plan_w = :w, plan_h = :h WHERE venue = :v AND id = :f",
            p=p.name,
            w=w,
            h=h,
            v=venue_id,
            f=floor,
        )
        self.bump(venue_id)
        return self.floor(venue_id, floor)

    def plan_extent_m(self, f: dict[str, Any]) -> tuple[float, float]:
        if not f["plan_file"] or not f["px_per_m"]:
            raise ApiError(
                409, f"floor {f['id']!r} needs a floor plan and its scale first (PUT .../floors/{f['id']}/plan)"
            )
        return f["plan_w"] / f["px_per_m"], f["plan_h"] / f["px_per_m"]

    # ---- places -------------------------------------------------------------------------------
    def places(self, venue_id: str) -> list[dict[str, Any]]:
        out = []
        for r in self.db.all("SELECT * FROM places WHERE venue = :v ORDER BY floor, name, id", v=venue_id):
            p = {"id": r["id"], "floor": r["floor"], "name": r["name"], "x": r["x"], "y": r["y"]}
            if r["area"]:
                p["area"] = json.loads(r["area"])
            out.append(p)
        return out

    def _place_row(self, venue_id: str, p: Any, i: int, floors: set[str]) -> dict[str, Any]:
        where = f"place {i}"
        if not isinstance(p, dict):
            raise ApiError(400, f"{where} must be an object")
        name = p.get("name")
        if not isinstance(name, str) or not name.strip() or len(name) > 200:
            raise ApiError(400, f"{where}: 'name' must be a non-empty string")
        floor = str(p.get("floor", "1"))
        if floor not in floors:
            raise ApiError(400, f"{where} ({name}): venue has no floor {floor!r}")
        x, y = _num(p.get("x"), f"{where} 'x'"), _num(p.get("y"), f"{where} 'y'")
        area = p.get("area")
        if area is not None:
            if not isinstance(area, list) or len(area) != 4:
                raise ApiError(400, f"{where}: 'area' must be [x0, y0, x1, y1] in metres")
            area = [_num(v, f"{where} 'area'") for v in area]
            if area[2] <= area[0] or area[3] <= area[1]:
                raise ApiError(400, f"{where}: 'area' needs x0 < x1 and y0 < y1")
        return {
            "id": uuid.uuid4().hex[:12],
            "venue": venue_id,
            "floor": floor,
            "name": name.strip(),
            "x": x,
            "y": y,
            "area": json.dumps(area) if area is not None else None,
        }

    def add_places(self, venue_id: str, items: Any, replace: bool) -> list[dict[str, Any]]:
        self.venue(venue_id)
        if not isinstance(items, list):
            raise ApiError(400, "places must be a JSON list of {name, floor, x, y[, area]}")
        floors = {f["id"] for f in self.floors(venue_id)}
        rows = [self._place_row(venue_id, p, i, floors) for i, p in enumerate(items)]
        with self.db.tx() as c:
            if replace:
                c.execute(text("DELETE FROM places WHERE venue = :v"), {"v": venue_id})
            for r in rows:
                c.execute(
                    text(
                        "INSERT INTO places (id, venue, floor, name, x, y, area) "
                        "VALUES (:id, :venue, :floor, :name, :x, :y, :area)"
                    ),
                    r,
                )
            c.execute(text("UPDATE venues SET revision = revision + 1 WHERE id = :id"), {"id": venue_id})
        return self.places(venue_id)

    def delete_place(self, venue_id: str, place_id: str) -> None:
        self.venue(venue_id)
        if not self.db.run("DELETE FROM places WHERE venue = :v AND id = :p", v=venue_id, p=place_id):
            raise ApiError(404, f"venue {venue_id!r} has no place {place_id!r}")
        self.bump(venue_id)

    # ---- lenses -------------------------------------------------------------------------------
    def _lens_rows(self, venue_id: str) -> list[dict[str, Any]]:
        return self.db.all("SELECT * FROM lenses WHERE venue = :v ORDER BY name", v=venue_id)

    def put_lens(self, venue_id: str, name: str, profile: Any) -> dict[str, Any]:
        self.venue(venue_id)
        try:
            try:
                check_id(name)
            except OmninavError:  # check_id speaks of venue ids: say which name was wrong
                raise OmninavError(f"invalid lens name {name!r}: use 1-64 letters, digits, '-' or '_'") from None
            lens = lens_from_dict(profile, where=f"lens {name!r}")
        except OmninavError as e:
            raise ApiError(400, str(e)) from None
        self.db.run(
            "INSERT INTO lenses (venue, name, profile) VALUES (:v, :n, :p) "
            "ON CONFLICT (venue, name) DO UPDATE SET profile = excluded.profile",
            v=venue_id,
            n=name,
            p=json.dumps(lens.to_dict()),
        )
        self.bump(venue_id)
        return lens.to_dict()

    def lens(self, venue_id: str, name: str) -> Lens:
        row = self.db.one("SELECT profile FROM lenses WHERE venue = :v AND name = :n", v=venue_id, n=name)
        if row is None:
            raise ApiError(404, f"venue {venue_id!r} has no lens profile {name!r}")
        return lens_from_dict(json.loads(row["profile"]), where=f"lens {name!r}")

    # ---- videos -------------------------------------------------------------------------------
    def video_dir(self, venue_id: str) -> Path:
        return self.data / "videos" / venue_id

    def video_doc(self, r: dict[str, Any]) -> dict[str, Any]:
        return {
            "name": r["name"],
            "floor": r["floor"],
            "lens": r["lens"],
            "size": r["size"],
            "received": r["received"],
            "status": r["status"],
            "frames": r["frames"],
            "track": json.loads(r["track"]),
            "upload_url": f"/api/admin/venues/{r['venue']}/videos/{r['name']}/content",
        }

    def videos(self, venue_id: str) -> list[dict[str, Any]]:
        self.venue(venue_id)
        return self.db.all("SELECT * FROM videos WHERE venue = :v ORDER BY created, name", v=venue_id)

    def video(self, venue_id: str, name: str) -> dict[str, Any]:
        self.venue(venue_id)
        row = self.db.one("SELECT * FROM videos WHERE venue = :v AND name = :n", v=venue_id, n=valid_video_name(name))
        if row is None:
            raise ApiError(404, f"venue {venue_id!r} has no video {name!r}")
        return row

    def check_track(self, venue_id: str, floor: str, track: Any) -> Track:
        f = self.floor(venue_id, floor)
        try:
            t = parse_track(track, where="track")
        except OmninavError as e:
            raise ApiError(400, str(e)) from None
        w, h = self.plan_extent_m(f)
        for i, (x, y) in enumerate(t.xy):
            if not (0 <= x <= w and 0 <= y <= h):
                raise ApiError(
                    422,
                    f"track waypoint {i} ({x:.2f}, {y:.2f}) m lies outside the floor plan of floor {floor!r} "
                    f"({w:.1f} x {h:.1f} m)",
                )
        return t

    def create_video(self, venue_id: str, body: dict[str, Any], max_bytes: int) -> dict[str, Any]:
        self.venue(venue_id)
        name = valid_video_name(body.get("name"))  # type: ignore[arg-type]
        floor = str(body.get("floor", "1"))
        size = body.get("size")
        if isinstance(size, float) and size.is_integer():  # 1.0 is a JSON integer too
            size = int(size)
        if isinstance(size, bool) or not isinstance(size, int) or size <= 0:
            raise ApiError(400, "'size' must be the video's length in bytes (a positive integer)")
        if size > max_bytes:
            raise ApiError(413, f"the video is {size} bytes; the limit is {max_bytes}")
        track = body.get("track")
        self.check_track(venue_id, floor, track)
        lens = body.get("lens", DEFAULT_LENS)
        if isinstance(lens, dict):  # an inline profile becomes the video's own named lens
            try:  # named by its normalised content: the same profile is one lens, and no name leaks
                profile = lens_from_dict(lens, where="the video's lens").to_dict()
            except OmninavError as e:
                raise ApiError(400, str(e)) from None
            lens = inline_lens_name(profile)
            self.put_lens(venue_id, lens, profile)
        if not isinstance(lens, str):
            raise ApiError(400, "'lens' must be a lens profile name or a lens profile object")
        self.lens(venue_id, lens)
        self.check_not_modelling(venue_id, name)
        old = self.db.one("SELECT * FROM videos WHERE venue = :v AND name = :n", v=venue_id, n=name)
        if old is not None and old["writer"] and (old["writer_until"] or 0) > time.time():
            raise ApiError(
                409, f"video {name!r} is being uploaded right now; wait for that upload to end, then send it again"
            )
        if old is not None:  # a new upload under the same name replaces the file when it completes
            self.db.run("DELETE FROM videos WHERE venue = :v AND name = :n", v=venue_id, n=name)
        part = self.video_dir(venue_id) / f"{name}.part"
        part.unlink(missing_ok=True)
        self.db.run(
            "INSERT INTO videos (venue, name, floor, lens, track, size, received, status, frames, created) "
            "VALUES (:v, :n, :f, :l, :t, :s, 0, 'uploading', :fr, :c)",
            v=venue_id,
            n=name,
            f=floor,
            l=lens,
            t=json.dumps(track),
            s=size,
            fr=old["frames"] if old else 0,
            c=time.time(),
        )
        return self.video(venue_id, name)

    def check_not_modelling(self, venue_id: str, name: str) -> None:
        busy = self.db.one(
            "SELECT id FROM jobs WHERE venue = :v AND state IN ('queued', 'running') AND videos LIKE :n",
            v=venue_id,
            n=f'%"{name}"%',
        )
        if busy:
            raise ApiError(409, f"video {name!r} is being modelled by job {busy['id']}; cancel it first")

    def delete_video(self, venue_id: str, name: str) -> int:
        """Delete a video, its file and its frames (the venue answers from its other videos' frames);
        returns how many frames went."""
        v = self.video(venue_id, name)
        self.check_not_modelling(venue_id, v["name"])
        removed = remove_video(self.store, venue_id, v["name"])
        d = self.video_dir(venue_id)
        for p in (d / v["name"], d / f"{v['name']}.part"):
            p.unlink(missing_ok=True)
        self.db.run("DELETE FROM videos WHERE venue = :v AND name = :n", v=venue_id, n=v["name"])
        self.bump(venue_id)
        return removed
