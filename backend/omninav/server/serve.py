"""`omninav serve`: prepare the data directory, then run three kinds of process:

    front (this process, asyncio)  the network: TLS, deadlines, limits, the locate rate limit (front.py)
    gunicorn workers (gthread)     the Flask app, on a unix socket only the front can reach
    job runner (one, niced)        modelling jobs, outside any worker: a job never holds a worker's GIL

Before any of them starts: the database schema is migrated, what an interrupted commit left in a
venue's folder is dropped, an admin token is made (and printed once) if there is none, the demo venue
is set up on first start, and with --https a self-signed certificate is made for this machine's LAN
address. The children die with this process (SIGTERM on the parent's death, Linux).
"""

from __future__ import annotations

import asyncio
import contextlib
import ctypes
import multiprocessing
import os
import shutil
import signal
import ssl
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

from gunicorn.app.base import BaseApplication  # type: ignore[import-untyped]

from ..catalog import Catalog
from ..catalog.db import Db
from ..config import database_url
from ..demo import VENUE as DEMO_VENUE
from ..errors import OmninavError
from .auth import KEY, ensure_token
from .front import Front, Limits, run_front
from .jobs import Jobs
from .ratelimit import RateLimiter


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
    cat = Catalog.open(conf)  # migrated, and venues of an older omninav imported (catalog/legacy.py)
    db = cat.db
    for venue, gone in cat.store.recover_all().items():
        echo(f"venue {venue}: dropped what an interrupted modelling run left ({', '.join(gone)})")
    if not conf["ADMIN_TOKEN"]:
        token = ensure_token(db)
        if token:
            echo("")
            echo(f"  admin token (shown once; 'omninav admin-token --reset' makes a new one): {token}")
            echo("")
    if demo != "none":
        from ..demo import ensure_demo

        if ensure_demo(cat, quick=demo == "quick", log=echo):
            job = Jobs(cat).submit(DEMO_VENUE, None)
            echo(f"demo venue created; modelling job {job['id']} queued")
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
    run_dir = tempfile.mkdtemp(prefix="omninav-")  # short: a unix socket path has ~100 bytes
    sock = os.path.join(run_dir, "workers.sock")
    options: dict[str, Any] = {
        "bind": f"unix:{sock}",
        "workers": workers,
        "worker_class": "gthread",
        "threads": threads,
        "timeout": 60,
        "graceful_timeout": 10,
        "keepalive": 75,  # the front keeps its connections to the workers open
        "accesslog": None,
        "errorlog": "-",
        "loglevel": "warning",
        "proc_name": "omninav",
    }
    # the front limits locate per client for the whole server; jobs run in their own process
    overrides = {"DATA": conf["DATA"], "JOB_RUNNER": False, "LOCATE_RATE": 0.0}
    ssl_ctx = None
    scheme = "https" if https else "http"
    if https:
        from .tls import ensure_cert, lan_addresses

        cert, key, made = ensure_cert(Path(conf["DATA"]) / "tls")
        ssl_ctx = ssl.create_default_context(ssl.Purpose.CLIENT_AUTH)
        ssl_ctx.load_cert_chain(cert, key)
        if made:
            echo(f"made a self-signed certificate: {cert} (docs/app.md says how to trust it on a phone)")
        urls = [f"{scheme}://{ip}:{port}/" for ip in lan_addresses()]
    else:
        shown = "localhost" if host in ("127.0.0.1", "0.0.0.0") else host
        urls = [f"{scheme}://{shown}:{port}/"]
    fork = multiprocessing.get_context("fork")  # before any thread exists in this process
    children = [fork.Process(target=_run_workers, args=(options, overrides), name="omninav-workers", daemon=False)]
    if conf["JOB_RUNNER"]:
        children.append(_job_runner(conf))
    for c in children:
        c.start()
    try:
        _wait_for_socket(sock, children[0])
        for u in urls:
            echo(f"omninav: {u}")
        echo(f"admin page: {urls[0]}admin (sign in with the token printed on the first start)")
        sys.stdout.flush()
        t = conf["FRONT_TIMEOUT_S"]
        fds = _raise_fd_limit()
        limits = Limits(
            max_conns=max(64, min(2048, fds - 256)),  # a socket each, and room for the workers' and files
            handshake_s=t,
            head_s=t,
            first_byte_s=t,
            body_idle_s=t,
            max_body=conf["MAX_CONTENT_LENGTH"],
            backend_concurrency=workers * threads,
        )
        asyncio.run(_front(conf, sock, host, port, ssl_ctx, limits, children))
    finally:
        for c in children:
            if c.is_alive():
                c.terminate()
        for c in children:
            c.join(15)
            if c.is_alive():
                c.kill()
        shutil.rmtree(run_dir, ignore_errors=True)


async def _front(
    conf: dict[str, Any],
    sock: str,
    host: str,
    port: int,
    ssl_ctx: ssl.SSLContext | None,
    limits: Limits,
    children: list[Any],
) -> None:
    db = Db(database_url(conf))
    front = Front(
        sock,
        limits,
        RateLimiter(conf["LOCATE_RATE"], conf["LOCATE_BURST"]),
        lambda: db.get_meta(KEY),
        trust_proxy=conf["TRUST_PROXY"],
        https=ssl_ctx is not None,
        max_upload=conf["MAX_UPLOAD_BYTES"],
    )
    stop = asyncio.Event()
    loop = asyncio.get_running_loop()
    for sig in (signal.SIGTERM, signal.SIGINT):
        loop.add_signal_handler(sig, stop.set)

    async def watch() -> None:
        while not stop.is_set():
            if not children[0].is_alive():  # the server is down if its workers are: say so and stop
                print("omninav: the worker processes stopped; shutting down", file=sys.stderr)
                stop.set()
            if len(children) > 1 and not children[1].is_alive():  # e.g. killed for memory mid-job
                print("omninav: the job runner stopped; starting it again", file=sys.stderr)
                children[1] = _job_runner(conf)  # its job is taken up again (Jobs.reap)
                children[1].start()
                await asyncio.sleep(5.0)
            await asyncio.sleep(1.0)

    watcher = asyncio.create_task(watch())
    try:
        await run_front(front, host, port, ssl_ctx, stop)
    finally:
        watcher.cancel()
        db.engine.dispose()


def _job_runner(conf: dict[str, Any]) -> Any:
    # spawned, not forked: the front has threads by the time it may need a new runner
    return multiprocessing.get_context("spawn").Process(target=_run_jobs, args=(conf,), name="omninav-jobs")


def _raise_fd_limit() -> int:
    """Every connection is a file descriptor: raise the soft limit to the hard one; -> the limit."""
    import resource

    soft, hard = resource.getrlimit(resource.RLIMIT_NOFILE)
    want = hard if hard != resource.RLIM_INFINITY else max(soft, 65536)
    with contextlib.suppress(ValueError, OSError):
        resource.setrlimit(resource.RLIMIT_NOFILE, (want, hard))
        soft = want
    return soft


def _wait_for_socket(sock: str, proc: Any, timeout_s: float = 120.0) -> None:
    t0 = time.monotonic()
    while not os.path.exists(sock):
        if not proc.is_alive():
            raise OmninavError("the server's worker processes did not start (see the messages above)")
        if time.monotonic() - t0 > timeout_s:
            raise OmninavError("the server's worker processes did not start within 2 minutes")
        time.sleep(0.05)


def _die_with_parent() -> None:
    """Linux: this child gets SIGTERM when the front dies, even by kill -9 (prctl PR_SET_PDEATHSIG)."""
    try:
        ctypes.CDLL(None, use_errno=True).prctl(1, signal.SIGTERM)
    except (OSError, AttributeError):
        pass


def _run_workers(options: dict[str, Any], overrides: dict[str, Any]) -> None:
    _die_with_parent()
    _Gunicorn(options, overrides).run()


def _run_jobs(conf: dict[str, Any]) -> None:
    """The job runner: claims queued jobs from the database and models them, at a lower priority
    than the workers (a modelling job must not slow the answers: measured in docs/benchmarks.md)."""
    _die_with_parent()
    os.nice(10)
    db = Db(database_url(conf))
    jobs = Jobs(Catalog(db, Path(conf["DATA"])), stale_s=conf["JOB_STALE_S"], device=conf["DEVICE"] or None)
    # SIGTERM (the server stopping) ends the process at once: a job it was running wrote nothing
    # live, and the next runner takes it up again (its owner is gone: Jobs.reap)
    signal.signal(signal.SIGTERM, lambda *_: sys.exit(0))
    jobs.run_forever()


def default_workers() -> int:
    """One process per core and one more: a request's Python holds the GIL, so processes, not
    threads, use the cores; the extra one takes up the slack while others wait on I/O."""
    return max(2, min(9, multiprocessing.cpu_count() + 1))
