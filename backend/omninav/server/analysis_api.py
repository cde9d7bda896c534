"""Analysis jobs of the admin API (/api/admin/...): suggested waypoints of a video, the quality
map of a venue, the evaluation of a walk. Each POST queues a background job (jobs.py) whose
progress, cancel and event stream are those of any job; its result is a JSON file, served by
GET /api/admin/jobs/{id}/result and, the latest of each, by the GETs here.

Every call needs the admin token (auth.py).
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import cv2
from flask import Blueprint, Response, current_app, jsonify, request

from ..catalog import Catalog
from ..errors import Conflict, NotFound
from .auth import require_admin
from .jobs import Jobs, job_doc
from .plan import prepared_plan

bp = Blueprint("analysis", __name__, url_prefix="/api/admin")
bp.before_request(require_admin)


def _cat() -> Catalog:
    return current_app.extensions["omninav"].catalog  # type: ignore[no-any-return]


def _jobs() -> Jobs:
    return current_app.extensions["omninav"].jobs  # type: ignore[no-any-return]


def _queued(job: dict[str, Any]) -> Any:
    resp = jsonify(job_doc(job))
    resp.status_code = 201
    resp.headers["Location"] = f"/api/admin/jobs/{job['id']}"
    return resp


def _json_file(path: Path) -> Response:
    """A result file as it was written (it is JSON already)."""
    return Response(path.read_bytes(), mimetype="application/json", headers={"Cache-Control": "no-store"})


def _latest(venue_id: str, kind: str, target: str | None, none_yet: str) -> Path:
    row = _jobs().latest_done(venue_id, kind, target)
    if row is None:
        raise NotFound(none_yet)
    return _jobs().result_path(row)


# ---- suggested waypoints -------------------------------------------------------------------------
@bp.post("/venues/<venue_id>/videos/<name>/suggest")
def suggest(venue_id: str, name: str) -> Any:
    return _queued(_jobs().submit_analysis(venue_id, "suggest", name))


# ---- the quality map -----------------------------------------------------------------------------
@bp.post("/venues/<venue_id>/quality")
def start_quality(venue_id: str) -> Any:
    return _queued(_jobs().submit_analysis(venue_id, "quality"))


@bp.get("/venues/<venue_id>/quality")
def quality(venue_id: str) -> Any:
    return _json_file(_quality_file(venue_id))


def _quality_file(venue_id: str) -> Path:
    return _latest(
        venue_id, "quality", None, f"venue {venue_id!r} has no quality map yet (POST .../venues/{venue_id}/quality)"
    )


@bp.get("/venues/<venue_id>/quality.png")
def quality_png(venue_id: str) -> Any:
    """The latest quality map drawn on a floor's plan (?floor=, default the venue's first floor)."""
    from ..quality import quality_png as draw

    cat = _cat()
    floor = request.args.get("floor")
    if floor is None:
        floors = cat.floors.all(cat.venues.get(venue_id)["id"])
        if not floors:
            raise NotFound(f"venue {venue_id!r} has no floor")
        floor = str(floors[0]["id"])
    f = cat.floors.get(venue_id, floor)
    if not f["plan_file"] or not f["px_per_m"]:
        raise Conflict(f"floor {floor!r} needs a floor plan and its scale first (PUT .../floors/{floor}/plan)")
    result = json.loads(_quality_file(venue_id).read_text())
    bgr, shrink = prepared_plan(cat.floors.plan_path(venue_id, floor))
    png = draw(result, cv2.cvtColor(bgr, cv2.COLOR_BGR2RGB), float(f["px_per_m"]) * shrink, floor)
    return Response(png, mimetype="image/png", headers={"Cache-Control": "no-store"})


# ---- evaluation walks ------------------------------------------------------------------------------
@bp.post("/venues/<venue_id>/videos/<name>/evaluate")
def evaluate(venue_id: str, name: str) -> Any:
    return _queued(_jobs().submit_analysis(venue_id, "evaluate", name))


@bp.get("/venues/<venue_id>/videos/<name>/evaluation")
def evaluation(venue_id: str, name: str) -> Any:
    _cat().videos.get(venue_id, name)  # 404 for an unknown video before "no evaluation yet"
    none_yet = f"video {name!r} has no evaluation yet (POST .../videos/{name}/evaluate)"
    return _json_file(_latest(venue_id, "evaluate", name, none_yet))


# ---- any job's result ------------------------------------------------------------------------------
@bp.get("/jobs/<job_id>/result")
def job_result(job_id: str) -> Any:
    jobs = _jobs()
    return _json_file(jobs.result_path(jobs.get(job_id)))
