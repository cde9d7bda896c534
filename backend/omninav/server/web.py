"""The web app at /: the built PWA (web/dist) when there is one, else a page that says how to build it."""

from __future__ import annotations

from importlib.resources import files
from pathlib import Path
from typing import Any

from flask import Blueprint, Response, current_app, send_from_directory

bp = Blueprint("web", __name__)


def _dist() -> Path:
    return Path(current_app.config["WEB_DIST"])


@bp.get("/")
def index() -> Any:
    if (_dist() / "index.html").is_file():
        return send_from_directory(_dist(), "index.html", max_age=0)
    page = files("omninav.server").joinpath("placeholder.html").read_text()
    return Response(page, mimetype="text/html")


@bp.get("/<path:asset>")
def asset(asset: str) -> Any:
    # send_from_directory refuses paths that leave the directory; unknown files are a JSON 404
    return send_from_directory(_dist(), asset, max_age=0 if asset in ("sw.js", "index.html") else 3600)
