"""POST /api/venues/{id}/locate: a clip -> where the user is, in numbers and in words.

A clip comes as its feature record (JSON or binary: what the phone sends, a few hundred bytes per
frame) or, for clients without WebAssembly, as frames (multipart JPEG/PNG) or a short video; the
server then extracts the same features itself. Each worker keeps the venues it has answered for
loaded (a memory map of one shared copy) and checks for edits at most every VENUE_CACHE_S.
"""

from __future__ import annotations

import base64
import tempfile
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import cv2
import numpy as np
from flask import Blueprint, current_app, jsonify, request

from ..errors import OmninavError
from ..lens import Lens
from ..locate import DEFAULT_CLIP_FPS, Locator, clip_frames
from ..spectrum import decode_binary, decode_json
from .catalog import Catalog
from .describe import UNSURE, describe
from .http import ApiError, client_address, json_body
from .plan import annotate

bp = Blueprint("locate", __name__)
RECORD_TYPES = ("application/octet-stream", "application/vnd.omninav.record")
PATH_WINDOW_S = 6.0  # the matched modelling path drawn on the plan: this long either side of the match


@dataclass
class Runtime:
    """One venue as a worker answers for it."""

    locator: Locator
    revision: int
    generation: str | None
    floors: dict[str, dict[str, Any]]
    places: dict[str, list[dict[str, Any]]]  # by floor
    video_floor: list[str]  # floor of each modelling video, by its index in the generation
    checked: float = field(default_factory=time.monotonic)


class Runtimes:
    def __init__(self, catalog: Catalog, cache_s: float, device: str | None):
        self.cat = catalog
        self.cache_s = cache_s
        self.device = device
        self._rt: dict[str, Runtime] = {}
        self._lock = threading.Lock()

    def get(self, venue_id: str) -> Runtime:
        rt = self._rt.get(venue_id)
        now = time.monotonic()
        if rt is not None and now - rt.checked < self.cache_s:
            return rt
        v = self.cat.venue(venue_id)  # 404 for an unknown venue
        gen = self.cat.store.generation(venue_id)
        if gen is None:
            raise ApiError(409, f"venue {venue_id!r} has no modelled frames yet; upload a video and model it first")
        if rt is not None and rt.revision == v["revision"] and rt.generation == gen:
            rt.checked = now
            return rt
        with self._lock:  # one load per venue, however many requests wait for it
            rt = self._rt.get(venue_id)
            if rt is None or rt.revision != v["revision"] or rt.generation != gen:
                rt = self._load(venue_id, v["revision"], gen, rt)
                self._rt[venue_id] = rt
        return rt

    def _load(self, venue_id: str, revision: int, gen: str, old: Runtime | None) -> Runtime:
        if old is not None and old.generation == gen:
            loc = old.locator  # only the catalogue changed: keep the loaded index
        else:
            try:
                loc = Locator(self.cat.store, venue_id, device=self.device)
            except OmninavError as e:
                raise ApiError(409, str(e)) from None
        floors = {f["id"]: f for f in self.cat.floors(venue_id)}
        places: dict[str, list[dict[str, Any]]] = {}
        for p in self.cat.places(venue_id):
            places.setdefault(p["floor"], []).append(p)
        vf = {
            r["name"]: r["floor"]
            for r in self.cat.db.all("SELECT name, floor FROM videos WHERE venue = :v", v=venue_id)
        }
        first = min(floors) if floors else "1"
        video_floor = [vf.get(name, first) for name in loc.gen.videos]
        return Runtime(loc, revision, loc.generation, floors, places, video_floor)


def _float_arg(name: str, lo: float, hi: float) -> float | None:
    raw = request.args.get(name)
    if raw is None:
        return None
    try:
        v = float(raw)
    except ValueError:
        raise ApiError(400, f"query parameter '{name}' must be a number, got {raw!r}") from None
    if not lo < v <= hi:
        raise ApiError(400, f"query parameter '{name}' must be in ({lo:g}, {hi:g}], got {raw}")
    return v


def _decode_image(data: bytes, what: str) -> np.ndarray:
    img = cv2.imdecode(np.frombuffer(data, np.uint8), cv2.IMREAD_COLOR) if data else None
    if img is None:
        raise ApiError(422, f"{what} is not a readable JPEG or PNG image")
    return img


def _query_lens(cat: Catalog, venue_id: str) -> Lens | None:
    name = request.form.get("lens") or request.args.get("lens")
    return cat.lens(venue_id, name) if name else None


def _read_clip(cat: Catalog, venue_id: str, rt: Runtime, max_frames: int) -> tuple[np.ndarray, float | None, str]:
    """The request body -> ((F, C, K) spectra, fps or None, what it was)."""
    loc = rt.locator
    ct = request.mimetype
    if ct == "application/json":
        obj = json_body()
        n = len(obj.get("mag") or []) if isinstance(obj.get("mag"), list) else 0
        if n > max_frames:
            raise ApiError(413, f"too many frames: {n} (a clip may have at most {max_frames})")
        rec_fps = obj.get("fps")
        if rec_fps is not None and (
            isinstance(rec_fps, bool) or not isinstance(rec_fps, int | float) or not 0 < rec_fps <= 240
        ):
            raise ApiError(400, "'fps' must be a number in (0, 240]")
        return decode_json(obj, loc.conf), rec_fps, "features"
    if ct in RECORD_TYPES:
        spec = decode_binary(request.get_data(), loc.conf)
        if len(spec) > max_frames:
            raise ApiError(413, f"too many frames: {len(spec)} (a clip may have at most {max_frames})")
        return spec, None, "features"
    frames: list[np.ndarray]
    fps: float | None = None
    if ct == "multipart/form-data":
        files = request.files.getlist("frame")
        video = request.files.get("video")
        if video is not None and not files:
            frames, fps = _video_frames(video.read(), loc, max_frames)
        elif files:
            if len(files) > max_frames:
                raise ApiError(413, f"too many frames: {len(files)} (a clip may have at most {max_frames})")
            frames = [_decode_image(f.read(), f"frame {i} ({f.filename})") for i, f in enumerate(files)]
        else:
            raise ApiError(400, "a multipart locate request needs 'frame' files (JPEG/PNG, in order) or one 'video'")
    elif ct in ("image/jpeg", "image/png"):
        frames = [_decode_image(request.get_data(), "the frame")]
    elif ct.startswith("video/"):
        frames, fps = _video_frames(request.get_data(), loc, max_frames)
    else:
        raise ApiError(
            415,
            f"unsupported Content-Type {ct or 'none'}: send a feature record (application/json or "
            "application/octet-stream), frames (multipart/form-data, image/jpeg, image/png) or a video (video/*)",
        )
    ext = loc.extractor(_query_lens(cat, venue_id))
    for i, f in enumerate(frames):
        try:
            ext.check_frame(f, f"frame {i}")
        except OmninavError as e:
            raise ApiError(422, f"{e}; name the clip's lens profile with 'lens'") from None
    return ext.spectra(frames), fps, "frames"


def _video_frames(data: bytes, loc: Locator, max_frames: int) -> tuple[list[np.ndarray], float]:
    with tempfile.TemporaryDirectory(prefix="omninav-clip-") as d:
        p = Path(d) / "clip"
        p.write_bytes(data)
        try:
            frames, fps = clip_frames(p, loc.conf["model_fps"])
        except OmninavError:
            raise ApiError(422, "the video does not decode (no readable frames)") from None
    if len(frames) > max_frames:
        raise ApiError(413, f"too many frames: {len(frames)} after sampling (a clip may have at most {max_frames})")
    return frames, fps


def accuracy_m(confidence: float, low: float) -> float | None:
    """Radius for the accuracy circle. Calibrated only at the top: of answers with confidence >= 0.8,
    at least 80 % are within 2 m (CONVENTIONS.md); below that the circle widens, and below the
    low-confidence line the answer is not shown as a position at all."""
    if confidence >= 0.8:
        return 2.0
    if confidence >= low:
        return 5.0
    return None


@bp.post("/api/venues/<venue_id>/locate")
def locate(venue_id: str) -> Any:
    app = current_app
    svc = app.extensions["omninav"]
    wait = svc.limiter.take(client_address())
    if wait > 0:
        raise ApiError(429, "too many locate requests from this client; slow down", retry_after_s=round(wait, 2))
    rt = svc.runtimes.get(venue_id)
    spec, body_fps, kind = _read_clip(svc.catalog, venue_id, rt, app.config["MAX_LOCATE_FRAMES"])
    fps = _float_arg("fps", 0, 240) or body_fps or DEFAULT_CLIP_FPS
    clip = request.args.get("clip", "clip")[:200]
    loc = rt.locator
    e = loc.estimate(spec, np.arange(len(spec)) / fps)
    ans = loc.answer(e, clip)
    floor = rt.video_floor[int(loc.gen.frames["video"][e.venue_row])]
    fl = rt.floors.get(floor)
    words = describe(ans["x"], ans["y"], ans["heading_deg"], rt.places.get(floor, []), fl["name"] if fl else floor)
    near = words["nearest"]
    low = ans["confidence"] < app.config["LOW_CONFIDENCE"]
    ans.update(
        floor=floor,
        place=(near["name"] if near and near["distance_m"] <= 10 else words["area"] or (near and near["name"])),
        area=words["area"],
        nearest=near,
        facing=words["facing"],
        sentence=UNSURE if low else words["sentence"],
        low_confidence=low,
        accuracy_m=accuracy_m(ans["confidence"], app.config["LOW_CONFIDENCE"]),
        frames=int(len(spec)),
        sent=kind,
    )
    if request.args.get("plan") in ("1", "true", "png"):
        ans["plan_png"] = _plan_png(svc.catalog, venue_id, rt, e.venue_row, ans, fl)
    return jsonify(ans)


def _plan_png(
    cat: Catalog, venue_id: str, rt: Runtime, row: int, ans: dict[str, Any], fl: dict[str, Any] | None
) -> str | None:
    if not fl or not fl["plan_file"] or not fl["px_per_m"]:
        return None
    fr = rt.locator.gen.frames
    same = (fr["video"] == fr["video"][row]) & (np.abs(fr["t"] - fr["t"][row]) <= PATH_WINDOW_S)
    path = np.stack([fr["x"][same], fr["y"][same]], -1)[np.argsort(fr["t"][same])]
    png = annotate(
        cat.plan_path(venue_id, fl["id"]),
        fl["px_per_m"],
        ans["x"],
        ans["y"],
        ans["heading_deg"],
        ans["accuracy_m"],
        path,
    )
    return "data:image/png;base64," + base64.b64encode(png).decode()
