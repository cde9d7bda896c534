"""`omninav serve`: prepare the data directory, then run the app under gunicorn (gthread workers).

Before any worker starts: the database schema is migrated, an admin token is made (and printed
once) if there is none, the demo venue is set up on first start, and with --https a self-signed
certificate is made for this machine's LAN address.
"""

from __future__ import annotations

import multiprocessing
import sys
from pathlib import Path
from typing import Any

from gunicorn.app.base import BaseApplication  # type: ignore[import-untyped]

from .auth import ensure_token
from .catalog import Catalog
from .config import database_url
from .db import Db
from .jobs import Jobs


class _Gunicorn(BaseApplication):  # type: ignore[misc]
    def __init__(self, options: dict[str, Any], overrides: dict[str, Any]):
        self.options = options
        self.overrides = overrides
        super().__init__()

    def load_config(self) -> None:
        for k, v in self.options.items():
            self.cfg.set(k, v)

    def load(self) -> Any:
        from threadpoolctl import threadpool_limits  # type: ignore[import-untyped]

        from . import create_app

        # Requests are the parallelism here (processes x threads): a BLAS thread pool per request
        # thread would only fight over the cores (measured: 106 locate/s with it, see benchmarks.md).
        threadpool_limits(1)
        return create_app(self.overrides)  # in each worker, after the fork: its own engine and threads


def prepare(conf: dict[str, Any], demo: str, echo: Any = print) -> None:
    db = Db(database_url(conf))
    db.migrate()
    if not conf["ADMIN_TOKEN"]:
        token = ensure_token(db)
        if token:
            echo("")
            echo(f"  admin token (shown once; 'omninav admin-token --reset' makes a new one): {token}")
            echo("")
    if demo != "none":
        from .demo import ensure_demo

        cat = Catalog(db, Path(conf["DATA"]))
        ensure_demo(cat, Jobs(cat), quick=demo == "quick", log=echo)
    db.engine.dispose()  # no connection may cross the fork into the workers


def serve(
    conf: dict[str, Any],
    host: str,
    port: int,
    https: bool,
    workers: int,
    threads: int,
    demo: str,
    echo: Any = print,
) -> None:
    prepare(conf, demo, echo)
    options: dict[str, Any] = {
        "bind": f"{host}:{port}",
        "workers": workers,
        "worker_class": "gthread",
        "threads": threads,
        "timeout": 60,
        "graceful_timeout": 10,
        "keepalive": 30,
        "accesslog": None,
        "errorlog": "-",
        "loglevel": "warning",
        "proc_name": "omninav",
    }
    scheme = "http"
    if https:
        from .tls import ensure_cert, lan_addresses

        cert, key, made = ensure_cert(Path(conf["DATA"]) / "tls")
        options.update(certfile=str(cert), keyfile=str(key))
        scheme = "https"
        if made:
            echo(f"made a self-signed certificate: {cert} (see the README to trust it on a phone)")
        for ip in lan_addresses():
            echo(f"omninav: {scheme}://{ip}:{port}/")
    else:
        shown = "localhost" if host in ("127.0.0.1", "0.0.0.0") else host
        echo(f"omninav: {scheme}://{shown}:{port}/")
    sys.stdout.flush()
    _Gunicorn(options, {k: conf[k] for k in ("DATA",)}).run()


def default_workers() -> int:
    """One process per core and one more: a request's Python holds the GIL, so processes, not
    threads, use the cores; the extra one takes up the slack while others wait on I/O."""
    return max(2, min(9, multiprocessing.cpu_count() + 1))
