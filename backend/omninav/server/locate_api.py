"""POST /api/venues/{id}/locate: a clip -> where the user is, in numbers and in words.

A clip comes as its feature record (JSON or binary: what the phone sends, a few hundred bytes per
frame) or, for clients without WebAssembly, as frames (multipart JPEG/PNG) or a short video; the
server then extracts the same features itself. Each worker keeps the venues it has answered for
loaded (a memory map of one shared copy) and checks for edits at most every VENUE_CACHE_S.

With ?session= the clip is one step of a walk: the venue's walk graph and tracking filter (built
once per generation and revision: in the background as soon as a worker loads the venue, with
WARM_VENUES, else on the first tracked request) update the session's state, which
lives in the catalogue database (catalog/sessions.py) so that the walk continues on any worker and
after a restart; the answer's pose and words are the filter's. With ?to= the route guide adds the
next instruction towards a place (route.py), its state kept beside the filter's.
"""

from __future__ import annotations

import base64
import logging
import math
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from flask import Blueprint, current_app, jsonify, request

from ..aggregate import SURE
from ..calib.correct import ClipLens
from ..catalog import Catalog
from ..catalog.sessions import Session, check_session_id
from ..describe import DEFAULT_STYLE, Style, describe
from ..errors import NotFound, OmninavError
from ..extract import Extractor
from ..lens import Lens
from ..locate import DEFAULT_CLIP_FPS, MAX_CLIP_S, Locator, answer_heading
from ..media import decode_image, iter_sampled, probe_image, probe_mp4, same_size, sampled_count
from ..motion import Motion
from ..presets import n_curves
from ..route import guide
from ..spectrum import (
    HEADER_BYTES,
    LOCAL_JSON_BYTES,
    LOCAL_MAX_BYTES,
    LocalQuery,
    decode_binary_local,
    decode_json_local,
    record_bytes_per_frame,
)
from ..tracking_state import TrackState
from ..walkgraph import WalkGraph
from .http import ApiError, client_address, json_body
from .plan import annotate
from .runtimes import Runtime

log = logging.getLogger("omninav.calib")

bp = Blueprint("locate", __name__)
RECORD_TYPES = ("application/octet-stream", "application/vnd.omninav.record")
PATH_WINDOW_S = 6.0  # the matched modelling path drawn on the plan: this long either side of the match
JSON_HEAD_BYTES = 4096  # a JSON feature record's fields other than its numbers
JSON_NUMBER_BYTES = 48  # a number in a JSON record: digits, sign, exponent, separator, indentation
MAX_VIDEO_FRAMES = int(MAX_CLIP_S * 240)  # frames decoded from one video clip (5 s at 240 fps), sampled or not
CLIP_S_SLACK = 1.01  # a phone measures its frame rate over the clip: 50 frames at 9.95 frames/s are 5 s too


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


def _clip_lens(cat: Catalog, venue_id: str, loc: Locator) -> tuple[Extractor, str]:
    """The extractor for the clip's lens (the 'lens' form or query parameter, else the lens the
    venue was modelled with) and how to name that lens in a message."""
    name = request.form.get("lens") or request.args.get("lens")
    ext = loc.extractor(cat.lenses.get(venue_id, name) if name else None)
    return ext, (f"lens {name!r}" if name else "the venue's modelling lens")


def _check_duration(frames: int, fps: float) -> None:
    """413 for a clip longer than MAX_CLIP_S (frames at `fps`): the engine answers from at most
    that much (locate.py), and a longer clip would be answered from part of what was sent."""
    if frames / fps > MAX_CLIP_S * CLIP_S_SLACK:
        raise ApiError(
            413,
            f"the clip is {frames / fps:.3g} s long ({frames} frames at {fps:g} frames/s); "
            f"a clip may be at most {MAX_CLIP_S:g} s",
        )


@dataclass
class SentClip:
    """A locate request's clip: its (F, C, K) spectra, its frame rate where the body says one,
    what was sent ("features" or "frames"), and what local features verify (verify.py) with: a
    version-2 record's, or the last frame sent and the lens it was seen through (corrected for
    this clip), whose features are found only where a single clip is verified."""

    spec: np.ndarray
    fps: float | None
    kind: str
    local: LocalQuery | None = None
    last: np.ndarray | None = None
    lens: Lens | None = None

    def local_features(self, loc: Locator) -> LocalQuery | None:
        if self.local is None and self.last is not None and self.lens is not None and loc.verifies:
            return loc.local_features(self.last, self.lens)
        return self.local


def _read_clip(cat: Catalog, venue_id: str, rt: Runtime, max_frames: int, fps: float | None) -> SentClip:
    """The request body -> the clip it sent. `fps`: the query's."""
    loc = rt.locator
    ct = request.mimetype
    if ct in RECORD_TYPES or ct == "application/json":
        _check_record_size(loc.conf, max_frames, as_json=ct == "application/json")
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
        spec, local = decode_json_local(obj, loc.conf)
        return SentClip(spec, rec_fps, "features", local)
    if ct in RECORD_TYPES:
        spec, local = decode_binary_local(request.get_data(), loc.conf)
        if len(spec) > max_frames:
            raise ApiError(413, f"too many frames: {len(spec)} (a clip may have at most {max_frames})")
        return SentClip(spec, None, "features", local)
    if ct == "multipart/form-data":
        files = request.files.getlist("frame")
        video = request.files.get("video")
        if video is not None and not files:
            return _video_spectra(video.read(), *_clip_lens(cat, venue_id, loc), loc, max_frames)
        if not files:
            raise ApiError(400, "a multipart locate request needs 'frame' files (JPEG/PNG, in order) or one 'video'")
        if len(files) > max_frames:
            raise ApiError(413, f"too many frames: {len(files)} (a clip may have at most {max_frames})")
        _check_duration(len(files), fps or DEFAULT_CLIP_FPS)  # before any frame is decoded
        images = [(f.read(), f"frame {i} ({f.filename})") for i, f in enumerate(files)]
        return _image_spectra(images, *_clip_lens(cat, venue_id, loc), loc)
    if ct in ("image/jpeg", "image/png"):
        return _image_spectra([(request.get_data(), "the frame")], *_clip_lens(cat, venue_id, loc), loc)
    if ct.startswith("video/"):
        return _video_spectra(request.get_data(), *_clip_lens(cat, venue_id, loc), loc, max_frames)
    raise ApiError(
        415,
        f"unsupported Content-Type {ct or 'none'}: send a feature record (application/json or "
        "application/octet-stream), frames (multipart/form-data, image/jpeg, image/png) or a video (video/*)",
    )


def _check_record_size(conf: dict[str, Any], max_frames: int, as_json: bool) -> None:
    """413 for a feature record longer than one of `max_frames` frames can be, before it is parsed:
    parsing is what costs (31 MB of JSON numbers took 410 MB and 6 s to parse and refuse)."""
    n = request.content_length if request.content_length is not None else len(request.get_data(cache=True))
    if not as_json:  # binary: a fixed header, 4 bytes a harmonic of a curve, maybe a local block
        frames = max(0, n - HEADER_BYTES - LOCAL_MAX_BYTES) // record_bytes_per_frame(conf)
        if frames > max_frames:
            raise ApiError(413, f"too many frames: {frames} (a clip may have at most {max_frames})")
        return
    # JSON: two numbers a harmonic of a curve, each at most JSON_NUMBER_BYTES however it is printed
    limit = JSON_HEAD_BYTES + max_frames * 2 * n_curves(conf) * conf["n_harmonics"] * JSON_NUMBER_BYTES
    limit += LOCAL_JSON_BYTES  # a version-2 record's local features
    if n > limit:
        raise ApiError(
            413, f"the JSON feature record is {n} bytes; one of at most {max_frames} frames is at most {limit}"
        )
    # and its arrays: 'mag' and 'phase' are [frames][curves][harmonics]; parsing a body of small
    # arrays costs what its bytes allow (200,000 '[[0]]' in 1.2 MB took 0.7 s to parse and refuse)
    arrays = 2 * (1 + max_frames * (1 + n_curves(conf))) + 16 + 2  # (+ the local block's two)
    if request.get_data(cache=True).count(b"[") > arrays:
        raise ApiError(413, f"the JSON feature record has more arrays than one of at most {max_frames} frames can")


def _image_spectra(images: list[tuple[bytes, str]], ext: Extractor, lens_name: str, loc: Locator) -> SentClip:
    """JPEG/PNG frames -> their clip (spectra; the last frame where the venue verifies). Every
    header is checked against the lens's frame size before any frame is decoded, and each frame
    becomes its spectrum before the next is decoded: the request holds one decoded frame, of the
    size the lens allows, whatever it sent."""
    want = ext.lens.image_size
    for data, what in images:
        head = probe_image(data)
        if head is None:
            raise ApiError(422, f"{what} is not a readable JPEG or PNG image")
        if not same_size(head.width, head.height, want):
            raise ApiError(
                422,
                f"{what} is {head.width}x{head.height} but {lens_name} is for {want[0]}x{want[1]} images; "
                "name the clip's lens profile with 'lens'",
            )
    clip = loc.clip_lens(ext.lens)  # corrected for where the ring sits in this clip
    out = []
    last: np.ndarray | None = None
    for data, what in images:
        last = decode_image(data)
        if last is None:
            raise ApiError(422, f"{what} is not a readable JPEG or PNG image")
        _check_frame(ext, last, what)
        out.extend(clip.feed(last))
    out.extend(clip.flush())
    _log_lens(clip)
    return SentClip(np.stack(out), None, "frames", None, last, clip.lens)


def _check_frame(ext: Extractor, frame: np.ndarray, what: str) -> None:
    try:
        ext.check_frame(frame, what)  # exact, once decoded (a rotated frame may come either way round)
    except OmninavError as e:
        raise ApiError(422, f"{e}; name the clip's lens profile with 'lens'") from None


def _log_lens(clip: ClipLens[np.ndarray]) -> None:
    if (w := clip.warning("a locate request")) is not None:
        log.warning(w)


def _video_spectra(data: bytes, ext: Extractor, lens_name: str, loc: Locator, max_frames: int) -> SentClip:
    """An MP4/QuickTime clip -> its clip: spectra of its frames sampled at the venue's modelling
    rate, ending at its last frame; the sampled frame rate; the last frame where the venue verifies.

    The container's boxes say the frame size, the frame count and the duration: all are checked
    before the clip is written to a file or any frame is decoded, and decoding stops at the count
    it declared, so a clip costs what its lens and MAX_CLIP_S allow, whatever its stream holds.
    """
    tracks = probe_mp4(data)
    if tracks is None:
        raise ApiError(422, "the video does not decode: send an MP4 or QuickTime (.mov) video")
    want = ext.lens.image_size
    for t in tracks:  # FFmpeg decodes a frame of every track when it opens the file
        if not same_size(t.width, t.height, want):
            raise ApiError(422, f"the video is {t.width}x{t.height} but {lens_name} is for {want[0]}x{want[1]}")
    v = tracks[0]
    if v.duration_s > MAX_CLIP_S:
        raise ApiError(413, f"the video is {v.duration_s:g} s long; a clip may be at most {MAX_CLIP_S:g} s")
    if v.frames > MAX_VIDEO_FRAMES:
        raise ApiError(413, f"the video has {v.frames} frames; a clip may have at most {MAX_VIDEO_FRAMES}")
    stride = max(1, int(round(v.fps / loc.conf["model_fps"]))) if v.fps else 1
    if sampled_count(v.frames, stride) > max_frames:
        raise ApiError(
            413,
            f"too many frames: {sampled_count(v.frames, stride)} after sampling (a clip may have at most {max_frames})",
        )
    spectra: list[np.ndarray] = []
    last = None
    clip = loc.clip_lens(ext.lens)  # corrected for where the ring sits in this clip
    with tempfile.TemporaryDirectory(prefix="omninav-clip-") as d:
        p = Path(d) / "clip.mp4"
        p.write_bytes(data)
        for i, frame in enumerate(iter_sampled(p, v.frames, stride, MAX_VIDEO_FRAMES)):
            if i >= max_frames:  # a clip whose container gave no count
                raise ApiError(
                    413, f"too many frames: over {max_frames} after sampling (a clip may have at most {max_frames})"
                )
            _check_frame(ext, frame, f"the video's sampled frame {i}")
            spectra.extend(clip.feed(frame))
            last = frame
    spectra.extend(clip.flush())
    _log_lens(clip)
    if not spectra:
        raise ApiError(422, "the video does not decode (no readable frames)")
    return SentClip(np.stack(spectra), (v.fps or DEFAULT_CLIP_FPS) / stride, "frames", None, last, clip.lens)


def accuracy_m(confidence: float, low: float) -> float | None:
    """Radius for the accuracy circle. Calibrated only at the top: of answers with confidence >= 0.8,
    at least 80 % are within 2 m (docs/formats.md); below that the circle widens, and below the
    low-confidence line the answer is not shown as a position at all."""
    if confidence >= SURE:
        return 2.0
    if confidence >= low:
        return 5.0
    return None


@dataclass(frozen=True)
class TrackArgs:
    """A tracked locate's query parameters (?session=&t=&steps=&turn_deg=&to=&style=)."""

    session: str
    t: float | None  # the phone's clock at the clip's last frame (seconds), None: the server's
    motion: Motion | None
    to: str | None
    style: Style


STYLES: tuple[Style, ...] = ("clock", "sides", "degrees")
# `t` up to this much before the session's last update is jitter (the filter takes it so); more is
# a clock that went back: the walk starts over (reason "clock")
CLOCK_SLACK_S = 1.0
MAX_T = 1e12  # seconds: any phone clock (Unix time in seconds is 1.8e9, a monotonic one far less)


def _number(name: str, lo: float, hi: float, integer: bool = False) -> float | None:
    """A query parameter as a finite number in [lo, hi] (an integer if asked), None if absent; 400 else."""
    raw = request.args.get(name)
    if raw is None:
        return None
    try:
        v = float(int(raw)) if integer else float(raw)
    except ValueError:
        raise ApiError(
            400, f"query parameter '{name}' must be {'an integer' if integer else 'a number'}, got {raw[:40]!r}"
        ) from None
    if not (math.isfinite(v) and lo <= v <= hi):
        raise ApiError(400, f"query parameter '{name}' must be in [{lo:g}, {hi:g}], got {raw[:40]}")
    return v


def _track_args() -> TrackArgs | None:
    """The tracking parameters, checked (400 naming the one that is wrong), before any work;
    None when the request does not track (no session: the answer is the clip's alone)."""
    t = _number("t", 0.0, MAX_T)
    steps = _number("steps", 0, 10000, integer=True)
    turn = _number("turn_deg", -36000, 36000)
    style = request.args.get("style", DEFAULT_STYLE)
    if style not in STYLES:
        raise ApiError(400, f"query parameter 'style' must be one of {', '.join(STYLES)}, got {style[:40]!r}")
    to = request.args.get("to")
    if to is not None and not 0 < len(to) <= 200:
        raise ApiError(400, "query parameter 'to' must name a place (its id or name, at most 200 characters)")
    session = request.args.get("session")
    if session is None:
        if to is not None:
            raise ApiError(400, "'to' needs a tracking 'session' (an id the app makes for this walk)")
        return None
    check_session_id(session)  # an OmninavError: a 400 with its message (http.py)
    motion = None if steps is None and turn is None else Motion(None if steps is None else int(steps), turn)
    return TrackArgs(session, t, motion, to, style)


@bp.post("/api/venues/<venue_id>/locate")
def locate(venue_id: str) -> Any:
    app = current_app
    svc = app.extensions["omninav"]
    wait = svc.limiter.take(client_address())
    if wait > 0:
        raise ApiError(429, "too many locate requests from this client; slow down", retry_after_s=round(wait, 2))
    track = _track_args()
    rt = svc.runtimes.get(venue_id)
    targets = _targets(venue_id, rt, track.to) if track is not None and track.to is not None else []
    asked_fps = _float_arg("fps", 0, 240)
    sent = _read_clip(svc.catalog, venue_id, rt, app.config["MAX_LOCATE_FRAMES"], asked_fps)
    spec, body_fps, kind = sent.spec, sent.fps, sent.kind
    # a video's frames are timed by the video itself (as sampled); ?fps= times what carries none
    video_fps = body_fps if kind == "frames" else None
    fps = video_fps or asked_fps or body_fps or DEFAULT_CLIP_FPS
    _check_duration(len(spec), fps)
    clip = request.args.get("clip", "clip")[:200]
    loc = rt.locator
    if track is None:
        e, outcome = loc.estimate_local(spec, np.arange(len(spec)) / fps, None, sent.local_features(loc))
        ans = loc.answer(e, clip, outcome)
        floor = rt.video_floor[int(loc.gen.frames["video"][e.venue_row])]
        ambiguous = False
    else:
        e, ans, floor, ambiguous, extra = _tracked(svc.catalog, venue_id, rt, track, targets, spec, fps, clip)
    fl = rt.floors.get(floor)
    low = ans["confidence"] < app.config["LOW_CONFIDENCE"] or ambiguous
    places = rt.places.get(floor, [])
    fname = fl["name"] if fl else floor
    words = describe(ans["x"], ans["y"], ans["heading_deg"], places, fname, low, ans["confidence"])
    ans.update(
        floor=floor,
        **words,  # place, area, nearest, facing, sentence
        low_confidence=low,
        accuracy_m=None if ambiguous else accuracy_m(ans["confidence"], app.config["LOW_CONFIDENCE"]),
        frames=int(len(spec)),
        sent=kind,
    )
    if track is not None:
        ans.update(extra)  # tracking, guidance
    if request.args.get("plan") in ("1", "true", "png"):
        row = e.venue_row if track is None else _row_near(rt, ans["x"], ans["y"], floor)
        ans["plan_png"] = _plan_png(svc.catalog, venue_id, rt, row, ans, fl)
    return jsonify(ans)


def _row_near(rt: Runtime, x: float, y: float, floor: str) -> int:
    """The modelled frame nearest to a (filtered) pose on its floor: the plan draws the modelling
    path around the pose the answer gives, not around the single clip's match."""
    fr = rt.locator.gen.frames
    vf = np.asarray(rt.video_floor)[fr["video"]]
    d = np.hypot(fr["x"] - x, fr["y"] - y)
    d = np.where(vf == floor, d, np.inf) if (vf == floor).any() else d
    return int(np.argmin(d))


def _targets(venue_id: str, rt: Runtime, to: str) -> list[dict[str, Any]]:
    """The places ?to= names (on the walk graph), or 404 pointing at the list of them."""
    found = rt.destinations(to)
    if not found:
        raise NotFound(
            f"no place {to[:80]!r} in venue {venue_id!r}; the places you can be guided to are listed at "
            f"/api/venues/{venue_id}/destinations"
        )
    return found


def _restart_reason(
    sess: Session | None, rt: Runtime, graph: WalkGraph, t_now: float, now: float, life_s: float
) -> tuple[TrackState | None, str | None]:
    """The session's filter state to continue from, or None and why it starts over."""
    if sess is None:
        return None, "new"
    if sess.expired(now):
        return None, "expired"
    if sess.generation != rt.generation:
        return None, "venue changed"
    state = TrackState.from_bytes(sess.state, graph)
    if state is None:  # another walk graph (the places that join floors changed), or unreadable
        return None, "venue changed"
    if t_now < state.t - CLOCK_SLACK_S:
        return None, "clock"
    if t_now - state.t > life_s:
        return None, "expired"
    return state, None


def _tracked(
    cat: Catalog,
    venue_id: str,
    rt: Runtime,
    track: TrackArgs,
    targets: list[dict[str, Any]],
    spec: np.ndarray,
    fps: float,
    clip: str,
) -> tuple[Any, dict[str, Any], str, bool, dict[str, Any]]:
    """One step of a tracked walk: the session's state read, updated by this clip, written back.
    -> (the clip's own estimate, the answer's numbers (the filtered pose), its floor, whether the
    filter is split between places, the answer's `tracking` and `guidance`)."""
    walk = rt.walk()
    life_s = float(current_app.config["TRACK_SESSION_S"])
    now = time.time()
    t_now = now if track.t is None else track.t
    sess = cat.sessions.get(venue_id, track.session)
    state, reason = _restart_reason(sess, rt, walk.graph, t_now, now, life_s)
    times = t_now - (len(spec) - 1 - np.arange(len(spec))) / fps
    loc = rt.locator
    new_state, pose, e = loc.track(walk.tracker, spec, times, state, t_now, track.motion)
    if state is not None and pose.restarted:  # the filter forgot a walk left too long
        reason = "expired"
    single = loc.answer(e, clip)
    ans = {
        **single,
        "x": round(float(pose.x), 3),
        "y": round(float(pose.y), 3),
        "heading_deg": answer_heading(pose.heading),
        "confidence": round(float(pose.confidence), 3),
    }
    extra: dict[str, Any] = {
        "tracking": {
            "session": track.session,
            "restarted": reason is not None,
            "reason": reason,
            "updates": int(new_state.updates),
            "single": {k: single[k] for k in ("x", "y", "heading_deg", "confidence")},
        }
    }
    guide_saved = None  # a request without ?to= ends the guidance (the app's "Stop guidance")
    if targets:
        place = min(targets, key=lambda p: p["floor"] != pose.floor)  # a lift's name: the one on this floor
        # the guide's own state (it starts over by itself for another place or walk graph)
        before = sess.guide if sess is not None and reason is None else None
        g, guide_saved = guide(
            walk.graph,
            None,  # planned from the pose at the first answer, then followed (and replanned) by the state
            place,
            walk.nodes[place["id"]],
            pose,
            before,
            t_now,
            places=[p for ps in rt.places.values() for p in ps],
            floor_names={f: fl["name"] for f, fl in rt.floors.items()},
            style=track.style,
            low_confidence=float(current_app.config["LOW_CONFIDENCE"]),
        )
        extra["guidance"] = g
    gen = rt.generation or ""
    cat.sessions.put(venue_id, track.session, gen, new_state.to_bytes(), guide_saved, life_s, now)
    return e, ans, str(pose.floor), bool(pose.ambiguous), extra


def _plan_png(
    cat: Catalog, venue_id: str, rt: Runtime, row: int, ans: dict[str, Any], fl: dict[str, Any] | None
) -> str | None:
    if not fl or not fl["plan_file"] or not fl["px_per_m"]:
        return None
    fr = rt.locator.gen.frames
    same = (fr["video"] == fr["video"][row]) & (np.abs(fr["t"] - fr["t"][row]) <= PATH_WINDOW_S)
    path = np.stack([fr["x"][same], fr["y"][same]], -1)[np.argsort(fr["t"][same])]
    png = annotate(
        cat.floors.plan_path(venue_id, fl["id"]),
        fl["px_per_m"],
        ans["x"],
        ans["y"],
        ans["heading_deg"],
        ans["accuracy_m"],
        path,
    )
    return "data:image/png;base64," + base64.b64encode(png).decode()
