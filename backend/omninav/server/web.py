"""The web app at / (the built PWA, web/dist, when there is one, else a page that says how to build it),
the admin page at /admin (admin.html of the same build; linked from nowhere in the phone app), and
the local certificate authority at /ca.pem (for a phone to trust once; tls.py)."""

from __future__ import annotations

import mimetypes
from importlib.resources import files
from pathlib import Path
from typing import Any

from flask import Blueprint, Response, current_app, request, send_from_directory

from ..errors import NotFound
from .http import WORKER_CSP
from .tls import CA_CERT

bp = Blueprint("web", __name__)
# The admin page runs no WebAssembly and needs no camera; Leaflet styles its elements through the
# CSSOM (element.style), which a policy without 'unsafe-inline' allows: no inline style or script.
ADMIN_CSP = (
    "default-src 'self'; script-src 'self'; worker-src 'self'; connect-src 'self'; "
    "img-src 'self' data: blob:; media-src 'self' blob:; style-src 'self'; object-src 'none'; "
    "base-uri 'none'; form-action 'self'; frame-ancestors 'none'"
)
NO_CACHE = ("sw.js", "index.html", "admin.html", "manifest.webmanifest")  # must update as soon as the app does


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


@bp.get("/admin")
@bp.get("/admin/")
def admin() -> Any:
    if not (_dist() / "admin.html").is_file():
        page = files("omninav.server").joinpath("placeholder.html").read_text()
        return Response(page, mimetype="text/html")
    resp = _send("admin.html")
    resp.headers["Content-Security-Policy"] = ADMIN_CSP
    resp.headers["Permissions-Policy"] = "camera=(), microphone=(), geolocation=()"
    return resp


@bp.get("/ca.pem")
def ca_pem() -> Any:
    """The certificate of the authority that issues this server's HTTPS certificate (data/tls/,
    made by `omninav serve --https`): a phone that trusts it once trusts every certificate the
    server is issued, whatever its address. It is public; its key never leaves data/tls/."""
    d = Path(current_app.config["DATA"]) / "tls"
    if not (d / CA_CERT).is_file():
        raise NotFound("this server has no certificate authority: `omninav serve --https` makes one")
    return send_from_directory(d, CA_CERT, mimetype="application/x-x509-ca-cert", max_age=0)


@bp.get("/<path:asset>")
def asset(asset: str) -> Any:
    # send_from_directory refuses paths that leave the directory; unknown files are a JSON 404
    return _send(asset)
