"""Public read API: health, the OpenAPI document, venues and their floor plans."""

from __future__ import annotations

import json
from functools import cache
from importlib.resources import files
from typing import Any

import yaml
from flask import Blueprint, current_app, jsonify, send_file

from .. import __version__
from .catalog import valid_floor_id
from .http import ApiError

bp = Blueprint("venues", __name__)


@cache
def openapi_doc() -> dict[str, Any]:
    return yaml.safe_load(files("omninav.server").joinpath("openapi.yaml").read_text())


@bp.get("/api/health")
def health() -> Any:
    return jsonify({"status": "ok", "version": __version__})


@bp.get("/api/openapi.json")
def openapi() -> Any:
    return current_app.response_class(json.dumps(openapi_doc()), mimetype="application/json")


@bp.get("/api/venues")
def venues() -> Any:
    cat = current_app.extensions["omninav"].catalog
    return jsonify(
        {"venues": [{"id": v["id"], "name": v["name"], "url": f"/api/venues/{v['id']}"} for v in cat.venues()]}
    )


@bp.get("/api/venues/<venue_id>")
def venue(venue_id: str) -> Any:
    return jsonify(current_app.extensions["omninav"].catalog.doc(venue_id))


@bp.get("/api/venues/<venue_id>/floors/<floor>/plan.png")
def plan(venue_id: str, floor: str) -> Any:
    cat = current_app.extensions["omninav"].catalog
    f = cat.floor(venue_id, valid_floor_id(floor))
    if not f["plan_file"]:
        raise ApiError(404, f"floor {floor!r} of venue {venue_id!r} has no floor plan yet")
    # streamed from the file, not read whole: a plan may be 40 megapixels (catalog.PLAN_MAX_PX)
    return send_file(cat.plan_path(venue_id, floor), mimetype="image/png", max_age=60)
