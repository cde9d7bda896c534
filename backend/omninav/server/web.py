"""The web app at /: the built PWA (web/dist) when there is one, else a page that says how to build it."""

from __future__ import annotations

import mimetypes
from importlib.resources import files
from pathlib import Path
from typing import Any

from flask import Blueprint, Response, current_app, request, send_from_directory

from .http import WORKER_CSP

bp = Blueprint("web", __name__)
NO_CACHE = ("sw.js", "index.html", "manifest.webmanifest")  # must update as soon as the app does


def _dist() -> Path:
    return Path(current_app.config["WEB_DIST"])


def _send(name: str) -> Any:
    """A file of the app, gzipped when the build made a .gz copy and the browser accepts it."""
    resp = _file(name)
    if name.startswith("assets/worker-") and name.endswith(".js"):
        resp.headers["Content-Security-Policy"] = WORKER_CSP
    return resp


def _file(name: str) -> Any:
    max_age = 0 if name in NO_CACHE else 3600
    gz = _dist() / f"{name}.gz"
    if request.accept_encodings["gzip"] > 0 and gz.is_file() and ".." not in Path(name).parts:
        mime = mimetypes.guess_type(name)[0] or "application/octet-stream"
        resp = send_from_directory(_dist(), f"{name}.gz", mimetype=mime, max_age=max_age)
        resp.headers["Content-Encoding"] = "gzip"
        resp.headers.pop("Content-Disposition", None)
        resp.vary.add("Accept-Encoding")
        return resp
    resp = send_from_directory(_dist(), name, max_age=max_age)
    resp.vary.add("Accept-Encoding")
    return resp


@bp.get("/")
def index() -> Any:
    if (_dist() / "index.html").is_file():
        return _send("index.html")
    page = files("omninav.server").joinpath("placeholder.html").read_text()
    return Response(page, mimetype="text/html")


@bp.get("/<path:asset>")
def asset(asset: str) -> Any:
    # send_from_directory refuses paths that leave the directory; unknown files are a JSON 404
    return _send(asset)
