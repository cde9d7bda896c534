"""Admin API (/api/admin/...): venues, floors and plans, places, lenses, modelling videos and jobs.

Every call needs the admin token (auth.py). Video uploads are streamed to disk in pieces and can
be resumed: PUT the bytes from where GET says the upload stands, with a Content-Range header.
"""

from __future__ import annotations

import errno
import json
import os
import re
import time
import uuid
from collections.abc import Iterator
from contextlib import contextmanager, suppress
from pathlib import Path
from typing import Any

from flask import Blueprint, Response, current_app, jsonify, request

from ..errors import OmninavError
from ..video import VideoInfo
from .auth import require_admin
from .http import ApiError, json_body, str_field
from .jobs import FINAL, job_doc

bp = Blueprint("admin", __name__, url_prefix="/api/admin")
bp.before_request(require_admin)
CHUNK = 1 << 20
WRITER_LEASE_S = 60.0  # an upload whose request died frees the video for another after this long
CONTENT_RANGE = re.compile(r"^bytes (\d+)-(\d+)/(\d+)$")


def _svc() -> Any:
    return current_app.extensions["omninav"]


def _created(body: Any, location: str) -> Any:
    resp = jsonify(body)
    resp.status_code = 201
    resp.headers["Location"] = location
    return resp


# ---- venues, floors, places, lenses ------------------------------------------------------------
@bp.post("/venues")
def create_venue() -> Any:
    body = json_body()
    vid = str_field(body, "id", "venue", max_len=64)
    name = str_field(body, "name", "venue", required=False) or vid
    preset = str_field(body, "preset", "venue", required=False) or "default"
    _svc().catalog.create_venue(vid, name, preset)
    return _created(_svc().catalog.doc(vid), f"/api/venues/{vid}")


@bp.patch("/venues/<venue_id>")
def edit_venue(venue_id: str) -> Any:
    body = json_body()
    _svc().catalog.rename_venue(venue_id, str_field(body, "name", "venue"))
    return jsonify(_svc().catalog.doc(venue_id))


@bp.put("/venues/<venue_id>/floors/<floor>")
def put_floor(venue_id: str, floor: str) -> Any:
    cat = _svc().catalog
    return jsonify(cat.floor_doc(venue_id, cat.put_floor(venue_id, floor, json_body())))


@bp.put("/venues/<venue_id>/floors/<floor>/plan")
def put_plan(venue_id: str, floor: str) -> Any:
    if request.mimetype not in ("image/png", "image/jpeg"):
        raise ApiError(415, f"a floor plan is sent as image/png or image/jpeg, got {request.mimetype or 'none'}")
    cat = _svc().catalog
    return jsonify(cat.floor_doc(venue_id, cat.set_plan(venue_id, floor, request.get_data())))


@bp.put("/venues/<venue_id>/places")
def replace_places(venue_id: str) -> Any:
    return jsonify({"places": _svc().catalog.add_places(venue_id, json_body(require_object=False), replace=True)})


@bp.post("/venues/<venue_id>/places")
def add_places(venue_id: str) -> Any:
    body = json_body(require_object=False)
    items = body if isinstance(body, list) else [body]
    return _created({"places": _svc().catalog.add_places(venue_id, items, replace=False)}, f"/api/venues/{venue_id}")


@bp.delete("/venues/<venue_id>/places/<place_id>")
def delete_place(venue_id: str, place_id: str) -> Any:
    _svc().catalog.delete_place(venue_id, place_id)
    return Response(status=204)


@bp.put("/venues/<venue_id>/lenses/<name>")
def put_lens(venue_id: str, name: str) -> Any:
    return jsonify(_svc().catalog.put_lens(venue_id, name, json_body()))


# ---- videos -------------------------------------------------------------------------------------
@bp.get("/venues/<venue_id>/videos")
def list_videos(venue_id: str) -> Any:
    cat = _svc().catalog
    return jsonify({"videos": [cat.video_doc(v) for v in cat.videos(venue_id)]})


@bp.post("/venues/<venue_id>/videos")
def create_video(venue_id: str) -> Any:
    cat = _svc().catalog
    v = cat.create_video(venue_id, json_body(), current_app.config["MAX_UPLOAD_BYTES"])
    return _created(cat.video_doc(v), f"/api/admin/venues/{venue_id}/videos/{v['name']}")


@bp.get("/venues/<venue_id>/videos/<name>")
def get_video(venue_id: str, name: str) -> Any:
    cat = _svc().catalog
    return jsonify(cat.video_doc(cat.video(venue_id, name)))


@bp.delete("/venues/<venue_id>/videos/<name>")
def delete_video(venue_id: str, name: str) -> Any:
    removed = _svc().catalog.delete_video(venue_id, name)
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
    """Stream the video's bytes to disk, in one request or in resumable pieces; one writer at a time."""
    cat = _svc().catalog
    v = cat.video(venue_id, name)
    if v["status"] != "uploading":
        raise ApiError(409, f"video {name!r} is already uploaded ({v['status']}); POST it again to replace it")
    size = int(v["size"])
    start, end = _content_range(size)
    request.max_content_length = current_app.config["MAX_UPLOAD_BYTES"]
    with _writer(cat, venue_id, name) as lease:
        received = int(cat.video(venue_id, name)["received"])  # read under the lease: nobody else moves it
        if start != received:
            raise ApiError(
                409,
                f"upload of {name!r} stands at byte {received}; send the piece that starts there",
                received=received,
            )
        limit = (end if end is not None else size) - start
        d = cat.video_dir(venue_id)
        d.mkdir(parents=True, exist_ok=True)
        part = d / f"{name}.part"
        got = _receive(part, start, limit, size, lease)
        received = start + got  # a dropped connection keeps what arrived: resume from there
        lease.update("received = :r", r=received)
        if received < size:
            return jsonify(cat.video_doc(cat.video(venue_id, name))), 202 if end is not None else 200
        return jsonify(cat.video_doc(_finish_upload(venue_id, name, part, lease)))


class _Lease:
    """This request's claim on writing one video (videos.writer): every write of the row names it,
    so a request that lost its claim (it stalled past WRITER_LEASE_S and another took over) changes
    nothing."""

    def __init__(self, cat: Any, venue_id: str, name: str):
        self.cat, self.venue, self.name = cat, venue_id, name
        self.me = uuid.uuid4().hex
        self.renewed = 0.0

    def claim(self) -> bool:
        now = time.time()
        self.renewed = now
        return bool(
            self.cat.db.run(
                "UPDATE videos SET writer = :w, writer_until = :u WHERE venue = :v AND name = :n "
                "AND status = 'uploading' AND (writer IS NULL OR writer_until < :now)",
                w=self.me,
                u=now + WRITER_LEASE_S,
                now=now,
                v=self.venue,
                n=self.name,
            )
        )

    def update(self, assignments: str, **params: Any) -> None:
        got = self.cat.db.run(
            f"UPDATE videos SET {assignments} WHERE venue = :v AND name = :n AND writer = :w",
            v=self.venue,
            n=self.name,
            w=self.me,
            **params,
        )
        if not got:
            raise ApiError(409, f"the upload of {self.name!r} was taken over by another request; resume from there")

    def renew(self) -> None:
        """Called while bytes flow: keeps the claim alive (a dead writer's claim lapses by itself)."""
        now = time.time()
        if now - self.renewed > WRITER_LEASE_S / 4:
            self.update("writer_until = :u", u=now + WRITER_LEASE_S)
            self.renewed = now

    def release(self) -> None:
        self.cat.db.run(
            "UPDATE videos SET writer = NULL, writer_until = NULL WHERE venue = :v AND name = :n AND writer = :w",
            v=self.venue,
            n=self.name,
            w=self.me,
        )


@contextmanager
def _writer(cat: Any, venue_id: str, name: str) -> Iterator[_Lease]:
    lease = _Lease(cat, venue_id, name)
    if not lease.claim():
        v = cat.video(venue_id, name)
        if v["status"] != "uploading":
            raise ApiError(409, f"video {name!r} is already uploaded ({v['status']}); POST it again to replace it")
        raise ApiError(
            409,
            f"another upload of {name!r} is in progress; resume from byte {v['received']} when it stops",
            received=v["received"],
        )
    try:
        yield lease
    finally:
        lease.release()


def _receive(part: Path, start: int, limit: int, size: int, lease: _Lease) -> int:
    """The body into `part` from byte `start`: -> bytes written. A full disk keeps what was written
    and says so (507); the client resumes once there is room."""
    got = 0
    with open(part, "r+b" if part.exists() else "wb") as f:
        f.seek(start)
        f.truncate()
        stream = request.stream
        try:
            while True:
                chunk = stream.read(min(CHUNK, limit - got + 1))
                if not chunk:
                    break
                got += len(chunk)
                if got > limit:  # more bytes than declared: nothing of this piece is kept
                    f.truncate(start)
                    raise ApiError(
                        413, f"the body is larger than the {limit} bytes this piece should have (video size {size})"
                    )
                f.write(chunk)
                lease.renew()
            f.flush()
        except OSError as e:
            if e.errno not in (errno.ENOSPC, errno.EDQUOT):
                raise
            kept = _keep_written(f, start)
            lease.update("received = :r", r=start + kept)
            raise ApiError(
                507,
                f"disk full: the server has no room for the rest of {part.name[:-5]!r}; {start + kept} of "
                f"{size} bytes are kept. Free space on the server, then resume from there",
                received=start + kept,
            ) from None
    return got


def _keep_written(f: Any, start: int) -> int:
    """After a failed write: how much of this piece is really on disk (flush what can be)."""
    with suppress(OSError):
        f.flush()
    on_disk = max(start, os.fstat(f.fileno()).st_size)
    with suppress(OSError):
        f.truncate(on_disk)
    return on_disk - start


def _finish_upload(venue_id: str, name: str, part: Any, lease: _Lease) -> dict[str, Any]:
    """The last byte is in: the file must be a video the video's lens can read, else it goes."""
    cat = _svc().catalog
    v = cat.video(venue_id, name)
    final = part.with_name(name)
    try:
        info = VideoInfo(part, label=name)
        w, h = cat.lens(venue_id, v["lens"]).image_size
        if (info.width, info.height) != (w, h):
            raise OmninavError(f"frames are {info.width}x{info.height} but lens {v['lens']!r} is for {w}x{h}")
    except OmninavError as e:
        part.unlink(missing_ok=True)
        lease.update("received = 0")
        raise ApiError(422, f"video {name!r} was not accepted: {e}; upload it again", received=0) from None
    part.replace(final)
    lease.update("status = 'ready'")
    return cat.video(venue_id, name)


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
