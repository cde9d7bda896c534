"""omninav's settings, one place for the CLI and the server: defaults, then the instance file
`<data>/omninav.cfg`, then `OMNINAV_*` variables, then command-line options (or a test's overrides).

Every key below can be set from the environment as OMNINAV_<KEY> (e.g. OMNINAV_LOCATE_RATE=20) or
in omninav.cfg as `KEY = value` (Python syntax); an environment value is parsed as the type of its
default. The "Settings" table of docs/operations.md lists them.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

from .errors import OmninavError

REPO = Path(__file__).resolve().parents[2]

DEFAULTS: dict[str, Any] = {
    "DATA": "data",  # feature files, uploads, floor plans, the SQLite database (relative: to the working folder)
    "HOST": "",  # omninav serve's address; empty: 127.0.0.1, or every interface (0.0.0.0) with HTTPS
    "PORT": 8000,  # and its port
    "HTTPS": False,  # serve HTTPS on the LAN, from a local certificate authority (phones need it for the camera)
    "WORKERS": 0,  # worker processes; 0: one per core plus one
    "THREADS": 4,  # threads per worker process
    "DEMO": "full",  # the demo venue set up on first start: full, quick or none
    "DATABASE_URL": "",  # empty: sqlite:///<DATA>/omninav.sqlite; postgresql+psycopg://... works too
    "ADMIN_TOKEN": "",  # set: this is the admin token (else one is made at first start)
    "MAX_CONTENT_LENGTH": 32 * 1024 * 1024,  # any request body but a video upload
    "MAX_UPLOAD_BYTES": 16 * 1024**3,  # one modelling video
    "MAX_LOCATE_FRAMES": 60,  # frames in one locate request (records or images)
    "LOCATE_RATE": 10.0,  # sustained locate requests per second per client (the whole server: nginx's limit)
    "LOCATE_BURST": 30,  # and the burst it allows
    "TRUST_PROXY": False,  # behind another reverse proxy: the client is the last X-Forwarded-For entry
    "FRONT_TIMEOUT_S": 10.0,  # TLS handshake, request head, a pause in a body: longer and nginx hangs up
    "CLIENT_REQUESTS": 16,  # requests of one client address in progress at once (more: 503; job streams apart)
    "EVENT_STREAMS": 8,  # job progress streams open at once (more: 503, and the admin page polls)
    "NGINX": "",  # the nginx binary omninav serve runs in front; empty: nginx on PATH or in /usr/sbin
    "LOW_CONFIDENCE": 0.5,  # below it, the spoken answer says 'not sure' instead of a place
    "JOB_RUNNER": True,  # run modelling jobs in this process's background thread
    "JOB_STALE_S": 30.0,  # a running job with no heartbeat for this long died with its server
    "DEVICE": "auto",  # array device for the search: auto (the GPU when CuPy finds one), cpu or gpu
    "VENUE_CACHE_S": 1.0,  # how long a worker trusts its cached venue before checking for edits
    "WARM_VENUES": True,  # build each venue's walk graph and tracker in the background, at start and on load
    "TRACK_SESSION_S": 900.0,  # a tracking session (locate ?session=) ends this long after its last request
    "WEB_DIST": str(REPO / "web" / "dist"),  # the built web app served at /
}


def _parse(default: Any, raw: str, key: str) -> Any:
    if isinstance(default, bool):
        if raw.lower() in ("1", "true", "yes", "on"):
            return True
        if raw.lower() in ("0", "false", "no", "off", ""):
            return False
        raise OmninavError(f"OMNINAV_{key}={raw!r}: expected true or false")
    try:
        return type(default)(raw)
    except ValueError:
        raise OmninavError(
            f"OMNINAV_{key}={raw!r}: expected a{'n' if isinstance(default, int) else ''} {type(default).__name__}"
        ) from None


def from_env(environ: dict[str, str] | None = None) -> dict[str, Any]:
    env = os.environ if environ is None else environ
    out: dict[str, Any] = {}
    for key, default in DEFAULTS.items():
        raw = env.get(f"OMNINAV_{key}")
        if raw is not None:
            out[key] = _parse(default, raw, key)
    return out


def load_config(overrides: dict[str, Any] | None = None) -> dict[str, Any]:
    """The settings in force: defaults < omninav.cfg < OMNINAV_* < overrides. DATA comes out
    absolute (the server's processes and the CLI must agree on it whatever their working folder)."""
    conf = dict(DEFAULTS)
    env = from_env()
    over = {k: v for k, v in (overrides or {}).items() if v is not None}
    data = Path(over.get("DATA") or env.get("DATA") or conf["DATA"])
    cfg = data / "omninav.cfg"
    if cfg.is_file():
        scope: dict[str, Any] = {}
        exec(compile(cfg.read_text(), str(cfg), "exec"), scope)
        conf.update({k: v for k, v in scope.items() if k in DEFAULTS})
    conf.update(env)
    conf.update(over)
    conf["DATA"] = str(Path(conf["DATA"]).resolve())
    if conf["DEMO"] not in ("full", "quick", "none"):
        raise OmninavError(f"DEMO={conf['DEMO']!r}: expected full, quick or none")
    return conf


def database_url(conf: dict[str, Any]) -> str:
    return conf["DATABASE_URL"] or f"sqlite:///{Path(conf['DATA']) / 'omninav.sqlite'}"
