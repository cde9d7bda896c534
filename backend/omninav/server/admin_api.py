"""Admin API (/api/admin/...): venues, floors and plans, places, lenses, modelling videos and jobs.

Every call needs the admin token (auth.py). Video uploads are streamed to disk in pieces and can
be resumed: PUT the bytes from where GET says the upload stands, with a Content-Range header.

Every write on a venue answers the venue's new revision as its ETag, and honours If-Match: a write
that names the revision it read is refused with 412 if the venue changed since (another tab saved
first). The check is the catalogue's (catalog/venues.py `bump`), in the write's own transaction.
"""

from __future__ import annotations

import json
import math
import re
import time
from typing import Any

from flask import Blueprint, Response, current_app, g, jsonify, request

from ..catalog import Catalog
from ..catalog.venues import begin_write, end_write
from ..errors import Busy, OmninavError, is_finite_number
from ..presets import settings_id
from .auth import require_admin
from .http import ApiError, json_body, str_field
from .jobs import FINAL, job_doc
from .venues_api import floor_doc, venue_doc

bp = Blueprint("admin", __name__, url_prefix="/api/admin")
bp.before_request(require_admin)
CONTENT_RANGE = re.compile(r"^bytes (\d+)-(\d+)/(\d+)$")
IF_MATCH = re.compile(r'^(?:W/)?"?(\d{1,15})"?$')
WRITES = ("POST", "PUT", "PATCH", "DELETE")


def _svc() -> Any:
    return current_app.extensions["omninav"]


def _cat() -> Catalog:
    return _svc().catalog  # type: ignore[no-any-return]


def if_match() -> int | None:
    """The revision the client read (If-Match: "7"), or None: no header, or '*'."""
    raw = request.headers.get("If-Match")
    if raw is None or raw.strip() == "*":
        return None
    m = IF_MATCH.match(raw.strip())
    if not m:
        raise ApiError(400, f'If-Match must be the venue\'s revision as its ETag gives it (e.g. "7"), got {raw!r}')
    return int(m.group(1))


@bp.before_request
def _begin_write() -> None:
    """A write on a venue: note the revision the client read, for the catalogue's check."""
    venue_id = (request.view_args or {}).get("venue_id")
    if request.method in WRITES and venue_id is not None:
        g.omninav_write, g.omninav_write_token = begin_write(venue_id, if_match())


@bp.after_request
def _etag(resp: Response) -> Response:
    """A write that changed a venue answers the revision it made as its ETag.

    A write that changed nothing (an upload's bytes, a job started) answers none: the venue's
    current revision there would tell a stale tab it is up to date with edits it never read,
    and its next save (If-Match that revision) would silently undo another tab's work.
    """
    w = g.get("omninav_write")
    if w is not None and resp.status_code < 400 and request.endpoint != "admin.delete_venue":
        if w.revision is not None:
            resp.headers["ETag"] = f'"{w.revision}"'
    return resp


@bp.teardown_request
def _end_write(_exc: BaseException | None) -> None:
    token = g.pop("omninav_write_token", None)
    if token is not None:
        end_write(token)


def _created(body: Any, location: str) -> Any:
    resp = jsonify(body)
    resp.status_code = 201
    resp.headers["Location"] = location
    return resp


# ---- venues, floors, places, lenses ------------------------------------------------------------
@bp.post("/venues")
def create_venue() -> Any:
    body = json_body()
    vid = str_field(body, "id", "venue", max_len=64) or ""
    name = str_field(body, "name", "venue", required=False) or vid
    preset = str_field(body, "preset", "venue", required=False) or "default"
    cat = _cat()
    cat.venues.create(vid, name, preset)
    return _created(venue_doc(cat, vid), f"/api/venues/{vid}")


def admin_venue_doc(cat: Catalog, venue_id: str) -> dict[str, Any]:
    """The public venue document and what only the admin sees: which generation is live, since
    when, and whether its feature settings are still the preset's (`settings_current` false: it
    was modelled before the preset improved, and a modelling anew brings it up to date)."""
    generation, at = cat.venues.modelled(venue_id)
    doc = venue_doc(cat, venue_id)
    preset_id = settings_id(cat.venues.preset_settings(venue_id))
    current = None if generation is None else doc["features"]["settings_id"] == preset_id
    return {
        **doc,
        "generation": generation,
        "modelled_at": at,
        "settings_current": current,
        "preset_settings_id": preset_id,
    }


@bp.get("/venues/<venue_id>")
def get_venue(venue_id: str) -> Any:
    doc = admin_venue_doc(_cat(), venue_id)
    resp = jsonify(doc)
    resp.headers["ETag"] = f'"{doc["revision"]}"'
    return resp


@bp.delete("/venues/<venue_id>")
def delete_venue(venue_id: str) -> Any:
    """The venue and everything of it: jobs (cancelled), frames, plans, videos, places, results."""
    return jsonify(_cat().venues.delete(venue_id))


@bp.patch("/venues/<venue_id>")
def edit_venue(venue_id: str) -> Any:
    body = json_body()
    cat = _cat()
    cat.venues.rename(venue_id, str_field(body, "name", "venue") or "")
    return jsonify(venue_doc(cat, venue_id))


@bp.put("/venues/<venue_id>/floors/<floor>")
def put_floor(venue_id: str, floor: str) -> Any:
    return jsonify(floor_doc(venue_id, _cat().floors.put(venue_id, floor, json_body())))


@bp.put("/venues/<venue_id>/floors/<floor>/plan")
def put_plan(venue_id: str, floor: str) -> Any:
    if request.mimetype not in ("image/png", "image/jpeg"):
        raise ApiError(415, f"a floor plan is sent as image/png or image/jpeg, got {request.mimetype or 'none'}")
    return jsonify(floor_doc(venue_id, _cat().floors.set_plan(venue_id, floor, request.get_data())))


@bp.put("/venues/<venue_id>/places")
def replace_places(venue_id: str) -> Any:
    return jsonify({"places": _cat().places.add(venue_id, json_body(require_object=False), replace=True)})


@bp.post("/venues/<venue_id>/places")
def add_places(venue_id: str) -> Any:
    body = json_body(require_object=False)
    items = body if isinstance(body, list) else [body]
    return _created({"places": _cat().places.add(venue_id, items)}, f"/api/venues/{venue_id}")


@bp.delete("/venues/<venue_id>/places/<place_id>")
def delete_place(venue_id: str, place_id: str) -> Any:
    _cat().places.delete(venue_id, place_id)
    return Response(status=204)


@bp.put("/venues/<venue_id>/lenses/<name>")
def put_lens(venue_id: str, name: str) -> Any:
    return jsonify(_cat().lenses.put(venue_id, name, json_body()))


# ---- videos -------------------------------------------------------------------------------------
def video_doc(r: dict[str, Any]) -> dict[str, Any]:
    walk_path = json.loads(r["walk_path"])
    return {
        "name": r["name"],
        "floor": r["floor"],
        "lens": r["lens"],
        "role": r["role"],
        "size": r["size"],
        "received": r["received"],
        "status": r["status"],
        "frames": r["frames"],
        "has_walk_path": walk_path is not None,
        "walk_path": walk_path,
        "duration_s": r["duration_s"],
        "fps": r["fps"],
        "width": r["width"],
        "height": r["height"],
        "error": r["error"],
        "suggestions": json.loads(r["suggestions"]) if r["suggestions"] else None,
        "upload_url": f"/api/admin/venues/{r['venue']}/videos/{r['name']}/content",
    }


@bp.get("/venues/<venue_id>/videos")
def list_videos(venue_id: str) -> Any:
    return jsonify({"videos": [video_doc(v) for v in _cat().videos.all(venue_id)]})


@bp.post("/venues/<venue_id>/videos")
def create_video(venue_id: str) -> Any:
    v = _cat().videos.create(venue_id, json_body(), current_app.config["MAX_UPLOAD_BYTES"])
    return _created(video_doc(v), f"/api/admin/venues/{venue_id}/videos/{v['name']}")


@bp.get("/venues/<venue_id>/videos/<name>")
def get_video(venue_id: str, name: str) -> Any:
    return jsonify(video_doc(_cat().videos.get(venue_id, name)))


@bp.delete("/venues/<venue_id>/videos/<name>")
def delete_video(venue_id: str, name: str) -> Any:
    removed = _cat().videos.delete(venue_id, name)
    return jsonify({"deleted": name, "frames_removed": removed})


@bp.put("/venues/<venue_id>/videos/<name>/walk-path")
@bp.put("/venues/<venue_id>/videos/<name>/track")  # its name until the rename, for one release
def put_walk_path(venue_id: str, name: str) -> Any:
    return jsonify(video_doc(_cat().videos.set_walk_path(venue_id, name, json_body())))


@bp.get("/venues/<venue_id>/videos/<name>/walk-path")
@bp.get("/venues/<venue_id>/videos/<name>/track")  # its name until the rename, for one release
def get_walk_path(venue_id: str, name: str) -> Any:
    resp = jsonify(_cat().videos.walk_path(venue_id, name))
    resp.headers["Content-Disposition"] = f'attachment; filename="{name}.walk_path.json"'
    return resp


def _number_arg(key: str, required: bool) -> float | None:
    raw = request.args.get(key)
    if raw is None:
        if required:
            raise ApiError(400, f"query parameter '{key}' is required")
        return None
    try:
        v = float(raw)
    except ValueError:
        v = math.nan
    if not is_finite_number(v):
        raise ApiError(400, f"query parameter '{key}' must be a finite number, got {raw!r}")
    return v


@bp.get("/venues/<venue_id>/videos/<name>/frame")
def video_frame(venue_id: str, name: str) -> Any:
    """The video's frame at ?t= seconds, as filmed (view=raw) or unwrapped (view=panorama)."""
    t = _number_arg("t", required=True)
    width = _number_arg("width", required=False)
    if width is not None and not width.is_integer():
        raise ApiError(400, f"query parameter 'width' must be a whole number of pixels, got {request.args['width']!r}")
    view = request.args.get("view", "raw")
    jpeg = _cat().videos.frame(venue_id, name, float(t or 0.0), view, int(width) if width is not None else None)
    return Response(jpeg, mimetype="image/jpeg", headers={"Cache-Control": "no-cache"})


def _content_range(size: int) -> tuple[int, int | None]:
    """-> (first byte, last byte + 1 or None for 'to the end of the body')."""
    raw = request.headers.get("Content-Range")
    if raw is None:
        return 0, None
    m = CONTENT_RANGE.match(raw.strip())
    if not m:
        raise ApiError(400, f"Content-Range must be 'bytes FIRST-LAST/TOTAL', got {raw!r}")
    a, b, total = (int(g) for g in m.groups())
    if total != size:
        raise ApiError(400, f"Content-Range total {total} differs from the video's declared size {size}")
    if b < a or b >= size:
        raise ApiError(416, f"Content-Range {a}-{b} lies outside the video's {size} bytes")
    return a, b + 1


@bp.put("/venues/<venue_id>/videos/<name>/content")
def upload_content(venue_id: str, name: str) -> Any:
    """Stream the video's bytes to disk, in one request or in resumable pieces (catalog/videos.py)."""
    videos = _cat().videos
    v = videos.get(venue_id, name)
    start, end = _content_range(int(v["size"]))
    request.max_content_length = current_app.config["MAX_UPLOAD_BYTES"]
    v = videos.upload(venue_id, name, request.stream, start, end)
    if v["received"] < v["size"] and end is not None:
        return jsonify(video_doc(v)), 202
    return jsonify(video_doc(v))


# ---- jobs ---------------------------------------------------------------------------------------
@bp.post("/venues/<venue_id>/jobs")
def start_job(venue_id: str) -> Any:
    body = json_body() if request.get_data() else {}
    anew = body.get("anew", False)
    if not isinstance(anew, bool):
        raise OmninavError("job 'anew' must be true or false")
    if anew and "videos" in body:
        raise OmninavError("a modelling anew models every modelling video of the venue: leave out 'videos'")
    job = _svc().jobs.submit(venue_id, body.get("videos"), anew)
    return _created(job_doc(job), f"/api/admin/jobs/{job['id']}")


@bp.get("/venues/<venue_id>/jobs")
def list_jobs(venue_id: str) -> Any:
    return jsonify({"jobs": [job_doc(j) for j in _svc().jobs.for_venue(venue_id)]})


@bp.get("/jobs/<job_id>")
def get_job(job_id: str) -> Any:
    return jsonify(job_doc(_svc().jobs.get(job_id)))


@bp.post("/jobs/<job_id>/cancel")
def cancel_job(job_id: str) -> Any:
    resp = jsonify(job_doc(_svc().jobs.cancel(job_id)))
    resp.status_code = 202
    return resp


@bp.get("/token")
def check_token() -> Any:
    """204: the token is right (require_admin checked it). nginx asks this before it reads the body
    of an admin request (server/nginx.py), so a request without the token costs no upload."""
    return Response(status=204)


HEARTBEAT_S = 2.0  # a comment on a quiet stream: a client gone is noticed, and its thread let go, this soon


@bp.get("/jobs/<job_id>/events")
def job_events(job_id: str) -> Any:
    """Server-sent events: 'progress' while it runs, then one of 'done', 'failed', 'cancelled'.

    Each open stream holds a thread (of the events worker under `omninav serve`), so a process
    serves at most EVENT_STREAMS at once: another gets 503, and the admin page reads the job
    instead. The count is the app's, after the token check: a client without the token takes none."""
    svc = _svc()
    svc.jobs.get(job_id)  # 404 before the stream starts
    if not svc.streams.acquire(blocking=False):
        raise Busy(
            f"at most {current_app.config['EVENT_STREAMS']} job-event streams at once: read the job instead",
            retry_after_s=2,
        )

    def stream() -> Any:
        last = None
        quiet = time.monotonic()
        while True:
            doc = job_doc(svc.jobs.get(job_id))
            if doc != last:
                final = doc["state"] in FINAL
                yield f"event: {doc['state'] if final else 'progress'}\ndata: {json.dumps(doc)}\n\n"
                last, quiet = doc, time.monotonic()
                if final:
                    return
            elif time.monotonic() - quiet > HEARTBEAT_S:
                yield ": still running\n\n"  # a write is how a stream whose client left ends
                quiet = time.monotonic()
            time.sleep(0.5)

    resp = Response(
        stream(), mimetype="text/event-stream", headers={"Cache-Control": "no-cache", "X-Accel-Buffering": "no"}
    )
    resp.call_on_close(svc.streams.release)  # however it ends, or if it never starts
    return resp
