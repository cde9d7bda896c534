"""Admin API (/api/admin/...): venues, floors and plans, places, lenses, modelling videos and jobs.

Every call needs the admin token (auth.py). Video uploads are streamed to disk in pieces and can
be resumed: PUT the bytes from where GET says the upload stands, with a Content-Range header.
"""

from __future__ import annotations

import json
import re
import time
from typing import Any

from flask import Blueprint, Response, current_app, jsonify, request

from ..catalog import Catalog
from .auth import require_admin
from .http import ApiError, json_body, str_field
from .jobs import FINAL, job_doc
from .venues_api import floor_doc, venue_doc

bp = Blueprint("admin", __name__, url_prefix="/api/admin")
bp.before_request(require_admin)
CONTENT_RANGE = re.compile(r"^bytes (\d+)-(\d+)/(\d+)$")


def _svc() -> Any:
    return current_app.extensions["omninav"]


def _cat() -> Catalog:
    return _svc().catalog  # type: ignore[no-any-return]


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
    job = _svc().jobs.submit(venue_id, body.get("videos"))
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


@bp.get("/jobs/<job_id>/events")
def job_events(job_id: str) -> Any:
    """Server-sent events: 'progress' while it runs, then one of 'done', 'failed', 'cancelled'."""
    jobs = _svc().jobs
    jobs.get(job_id)  # 404 before the stream starts

    def stream() -> Any:
        last = None
        quiet = time.monotonic()
        while True:
            doc = job_doc(jobs.get(job_id))
            if doc != last:
                final = doc["state"] in FINAL
                yield f"event: {doc['state'] if final else 'progress'}\ndata: {json.dumps(doc)}\n\n"
                last, quiet = doc, time.monotonic()
                if final:
                    return
            elif time.monotonic() - quiet > 15:
                yield ": still running\n\n"  # keeps proxies from closing an idle stream
                quiet = time.monotonic()
            time.sleep(0.5)

    return Response(
        stream(), mimetype="text/event-stream", headers={"Cache-Control": "no-cache", "X-Accel-Buffering": "no"}
    )
