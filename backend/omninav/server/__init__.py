"""The omninav HTTP server: a Flask app factory with a blueprint per resource.

    create_app()          settings from config.DEFAULTS, then <data>/omninav.cfg, then OMNINAV_*
    create_app({...})     and then these (tests)

Each process gets its own database engine, venue cache, rate limiter and job runner thread; they
share the database and the memory-mapped feature files (serve.py runs several such processes).
"""

from __future__ import annotations

import threading
from dataclasses import dataclass
from typing import Any

from flask import Flask, request

from ..catalog import Catalog
from ..catalog.db import Db
from ..config import load_config
from .auth import set_token
from .http import CSP, ApiError, install_error_handlers
from .jobs import Jobs
from .ratelimit import RateLimiter
from .runtimes import Runtimes


@dataclass
class Services:
    db: Db
    catalog: Catalog
    jobs: Jobs
    runtimes: Runtimes
    limiter: RateLimiter
    streams: threading.BoundedSemaphore  # job-event streams open now (admin_api.job_events)


def create_app(overrides: dict[str, Any] | None = None) -> Flask:
    conf = load_config(overrides)
    app = Flask(__name__)
    app.config.update(conf)
    app.json.sort_keys = False  # type: ignore[attr-defined]
    catalog = Catalog.open(conf)  # migrated, and venues of an older omninav imported
    db = catalog.db
    if conf["ADMIN_TOKEN"]:
        set_token(db, conf["ADMIN_TOKEN"])
    device = conf["DEVICE"] or None
    jobs = Jobs(catalog, stale_s=conf["JOB_STALE_S"], device=device)
    app.extensions["omninav"] = Services(
        db,
        catalog,
        jobs,
        Runtimes(catalog, conf["VENUE_CACHE_S"], device, warm=conf["WARM_VENUES"]),
        RateLimiter(conf["LOCATE_RATE"], conf["LOCATE_BURST"]),
        threading.BoundedSemaphore(conf["EVENT_STREAMS"]),
    )
    install_error_handlers(app)

    @app.before_request
    def _refuse_large_bodies() -> None:  # before any work, and before any of it is read
        limit = conf["MAX_CONTENT_LENGTH"]
        n = request.content_length
        if n is not None and n > limit and request.endpoint != "admin.upload_content":
            raise ApiError(413, f"request body too large: {n} bytes (the limit here is {limit})")

    @app.after_request
    def _read_what_was_refused(resp: Any) -> Any:
        """A body refused before it was read (a record too long for its frames: 413) is read and
        dropped before the answer goes: closing on unread bytes resets the connection, and nginx
        answers 502 for the app's 413. The body is within MAX_CONTENT_LENGTH (nginx saw to that)
        and waits whole on nginx's side. A video upload is streamed through nginx: it is read only
        when refused (a second upload of a video being uploaded: 409) and within that bound, else
        left alone; its client may stall, and then the read ends with nginx's deadline."""
        n = request.content_length
        upload = request.endpoint == "admin.upload_content"
        if n and n <= conf["MAX_CONTENT_LENGTH"] and (not upload or resp.status_code >= 400):
            try:
                while request.stream.read(1 << 16):
                    pass
            except OSError:  # the client went away: nothing left to keep the connection for
                pass
        return resp

    @app.after_request
    def _security_headers(resp: Any) -> Any:
        h = resp.headers
        h.setdefault("Content-Security-Policy", CSP)
        h.setdefault("X-Content-Type-Options", "nosniff")
        h.setdefault("Referrer-Policy", "no-referrer")
        h.setdefault("X-Frame-Options", "DENY")
        h.setdefault("Permissions-Policy", "camera=(self), microphone=(), geolocation=()")
        # nginx says whether the client came over TLS (it terminates it; no client reaches us directly)
        if request.is_secure or request.headers.get("X-Forwarded-Proto") == "https":
            h.setdefault("Strict-Transport-Security", "max-age=31536000")
        return resp

    from . import admin_api, analysis_api, locate_api, venues_api, web

    for mod in (venues_api, locate_api, admin_api, analysis_api, web):
        app.register_blueprint(mod.bp)
    if conf["JOB_RUNNER"]:
        jobs.start()
    else:
        jobs.reap()
    if conf["WARM_VENUES"]:
        app.extensions["omninav"].runtimes.warm_all()
    return app
