"""Public read API: health, the OpenAPI document, venues and their floor plans, the places one can
be guided to; and the public documents of a venue and a floor, which the admin API answers with too."""

from __future__ import annotations

import json
import re
from functools import cache
from importlib.resources import files
from typing import Any

import yaml
from flask import Blueprint, current_app, jsonify, send_file

from .. import __version__
from ..catalog import Catalog
from ..errors import NotFound
from ..presets import feature_keys, n_curves, settings_id
from ..spectrum import HEADER_BYTES, record_bytes_per_frame

bp = Blueprint("venues", __name__)


@cache
def openapi_doc() -> dict[str, Any]:
    doc: dict[str, Any] = yaml.safe_load(files("omninav.server").joinpath("openapi.yaml").read_text())
    return doc


def _cat() -> Catalog:
    return current_app.extensions["omninav"].catalog  # type: ignore[no-any-return]


def floor_doc(venue_id: str, f: dict[str, Any], url_root: str = "") -> dict[str, Any]:
    has_plan = bool(f["plan_file"])
    return {
        "id": f["id"],
        "name": f["name"],
        "plan_url": f"{url_root}/api/venues/{venue_id}/floors/{f['id']}/plan.png" if has_plan else None,
        "plan_size_px": [f["plan_w"], f["plan_h"]] if has_plan else None,
        "px_per_m": f["px_per_m"],
    }


def venue_doc(cat: Catalog, venue_id: str, url_root: str = "") -> dict[str, Any]:
    """The public description of a venue: all a client needs to extract matching features."""
    v = cat.venues.get(venue_id)
    conf = cat.venues.settings(venue_id)
    frames = cat.store.frame_count(venue_id)
    return {
        "id": v["id"],
        "name": v["name"],
        "revision": v["revision"],
        "modelled": frames > 0,
        "frames": frames,
        "floors": [floor_doc(venue_id, f, url_root) for f in cat.floors.all(venue_id)],
        "places": cat.places.all(venue_id),
        "lenses": cat.lenses.profiles(venue_id),
        "features": {
            "preset": v["preset"],
            "settings": {k: conf[k] for k in sorted(conf)},
            "settings_id": settings_id(conf),
            # the settings a record depends on here: an app that does not know one of them would
            # make other curves under the same id (web/src/shared/record.ts refuses to)
            "feature_keys": feature_keys(conf),
            "n_curves": n_curves(conf),
            "n_harmonics": conf["n_harmonics"],
            "record_header_bytes": HEADER_BYTES,
            "record_bytes_per_frame": record_bytes_per_frame(conf),
        },
    }


@bp.get("/api/health")
def health() -> Any:
    return jsonify({"status": "ok", "version": __version__})


@bp.get("/api/openapi.json")
def openapi() -> Any:
    return current_app.response_class(json.dumps(openapi_doc()), mimetype="application/json")


@bp.get("/api/venues")
def venues() -> Any:
    """Every venue, and whether it is modelled: an app with none chosen opens the first that is."""
    cat = _cat()
    return jsonify(
        {
            "venues": [
                {
                    "id": v["id"],
                    "name": v["name"],
                    "url": f"/api/venues/{v['id']}",
                    "modelled": cat.venues.modelled(v["id"])[0] is not None,
                }
                for v in cat.venues.all()
            ]
        }
    )


@bp.get("/api/venues/<venue_id>")
def venue(venue_id: str) -> Any:
    return jsonify(venue_doc(_cat(), venue_id))


@bp.get("/api/venues/<venue_id>/floors/<floor>/plan.png")
def plan(venue_id: str, floor: str) -> Any:
    cat = _cat()
    f = cat.floors.get(venue_id, floor)
    if not f["plan_file"]:
        raise NotFound(f"floor {floor!r} of venue {venue_id!r} has no floor plan yet")
    # streamed from the file, not read whole: a plan may be 40 megapixels (catalog/floors.py)
    return send_file(cat.floors.plan_path(venue_id, floor), mimetype="image/png", max_age=60)


def filing_name(name: str) -> tuple[tuple[int, int | str], ...]:
    """A place's name as a list files it: without case, without a leading article, so that "the
    café" comes under C and "the lifts" under L, where a user skimming the list by ear, or jumping
    to a letter, looks for them; and numbers by their value, Room 2 before Room 10. "A" or "An"
    is an article only before a word in lower case: "A Wing" and "A 4" are names ("a café" is not)."""
    words = name.split()
    if len(words) > 1 and (
        words[0].casefold() == "the" or (words[0].casefold() in ("a", "an") and words[1][:1].islower())
    ):
        words = words[1:]
    n = " ".join(words).casefold()
    # (0, number) before (1, text), so that a key compares whatever its parts; ASCII digits only
    # ("²" is a digit to str.isdigit but no number to int())
    return tuple((0, int(t)) if t[0] in "0123456789" else (1, t) for t in re.findall(r"[0-9]+|[^0-9]+", n))


@bp.get("/api/venues/<venue_id>/destinations")
def destinations(venue_id: str) -> Any:
    """The places on the venue's walk graph (locate's ?to=), by floor in the venue's order, each
    floor's sorted by name as a list is read (`filing_name`); floors without one are left out. 409
    while the venue has no frames."""
    rt = current_app.extensions["omninav"].runtimes.get(venue_id)
    nodes = rt.walk().nodes
    floors = []
    for fid, f in rt.floors.items():
        on = [p for p in rt.places.get(fid, []) if p["id"] in nodes]
        if on:
            on.sort(key=lambda p: (filing_name(p["name"]), p["name"], p["id"]))
            places = [{k: p.get(k) for k in ("id", "name", "kind", "x", "y")} for p in on]
            floors.append({"id": fid, "name": f["name"], "places": places})
    return jsonify({"venue": venue_id, "floors": floors})
