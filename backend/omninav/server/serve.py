"""`omninav serve`: prepare the data directory, then run four kinds of process:

    nginx (a child)                 the network: TLS, deadlines, limits, the locate rate limit (nginx.py)
    gunicorn app workers (gthread)  the Flask app, on a unix socket only nginx reaches
    gunicorn events worker          job progress streams, on a socket of its own: no number of open
                                    streams takes an app worker
    job runner (one, niced)         modelling jobs, outside any worker: a job never holds a worker's GIL

This process starts them and watches them: it stops everything when nginx or a worker pool stops,
and starts the job runner again when it dies (e.g. killed for memory mid-job). Before any of them
starts: the database schema is migrated, what an interrupted commit left in a venue's folder is
dropped, an admin token is made (and printed once) if there is none, the demo venue is set up on
first start, and with --https a certificate from the local certificate authority is issued for this
machine's LAN addresses (tls.py). The children die with this process (SIGTERM on the parent's death).
"""

from __future__ import annotations

import contextlib
import ctypes
import json
import logging
import multiprocessing
import os
import shutil
import signal
import socket
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
from ..model_venue import start_workers
from .auth import ensure_token
from .jobs import Jobs
from .nginx import Front, binary, start

log = logging.getLogger("omninav.server")


class _Gunicorn(BaseApplication):  # type: ignore[misc]
    def __init__(self, options: dict[str, Any], overrides: dict[str, Any]):
        self.options = options
        self.overrides = overrides
        super().__init__()

    def load_config(self) -> None:
        for k, v in self.options.items():
            self.cfg.set(k, v)

    def load(self) -> Any:
        import gunicorn.util  # type: ignore[import-untyped]
        from threadpoolctl import threadpool_limits  # type: ignore[import-untyped]

        from . import create_app

        gunicorn.util.write_error = _json_error  # in this worker: see _json_error

        # Requests are the parallelism here (processes x threads): a BLAS thread pool per request
        # thread would only fight over the cores (measured: 106 locate/s with it, see docs/benchlog.md).
        threadpool_limits(1)
        return create_app(self.overrides)  # in each worker, after the fork: its own engine and threads


def _json_error(sock: Any, status: int, reason: str, message: str) -> None:
    """gunicorn's answer to a request it cannot parse (a control byte in a header value, say: nginx
    passes those on), in the API's JSON rather than gunicorn's HTML page. gunicorn has no setting
    for that page's form; its workers write it with util.write_error, which each worker replaces
    with this."""
    import gunicorn.util

    body = json.dumps({"error": message or reason, "status": status}).encode()
    head = f"HTTP/1.1 {status} {reason}\r\nConnection: close\r\nContent-Type: application/json\r\n"
    gunicorn.util.write_nonblock(sock, f"{head}Content-Length: {len(body)}\r\n\r\n".encode("latin-1") + body)


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
    nginx = binary(conf["NGINX"])  # before anything is set up: a missing nginx says so at once
    prepare(conf, demo, echo)
    # nginx limits locate per client for the whole server; jobs run in their own process
    overrides = {"DATA": conf["DATA"], "JOB_RUNNER": False, "LOCATE_RATE": 0.0}
    cert = key = ""
    scheme = "https" if https else "http"
    if https:
        from .tls import ca_cert, ca_fingerprint, ensure_cert, lan_addresses

        tls_dir = Path(conf["DATA"]) / "tls"
        c, k, made = ensure_cert(tls_dir)
        cert, key = str(c), str(k)
        if made:
            echo(f"issued a server certificate from the local certificate authority {ca_cert(tls_dir)}")
        echo(f"phones trust it once from /ca.pem (SHA-256 {ca_fingerprint(tls_dir)}; docs/app.md)")
        urls = [f"{scheme}://{ip}:{port}/" for ip in lan_addresses()]
    else:
        shown = "localhost" if host in ("127.0.0.1", "0.0.0.0") else host
        urls = [f"{scheme}://{shown}:{port}/"]
    _check_port_free(host, port)  # before anything starts: nginx would say so only in its log
    run_dir = tempfile.mkdtemp(prefix="omninav-")  # short: a unix socket path has ~100 bytes
    app_sock, events_sock = os.path.join(run_dir, "app.sock"), os.path.join(run_dir, "events.sock")
    streams = conf["EVENT_STREAMS"]
    front = Front(
        run_dir=run_dir,
        app_socket=app_sock,
        events_socket=events_sock,
        host=host,
        port=port,
        cert=cert,
        key=key,
        timeout_s=conf["FRONT_TIMEOUT_S"],
        max_body=conf["MAX_CONTENT_LENGTH"],
        max_upload=conf["MAX_UPLOAD_BYTES"],
        locate_rate=conf["LOCATE_RATE"],
        locate_burst=conf["LOCATE_BURST"],
        client_requests=conf["CLIENT_REQUESTS"],
        trust_proxy=conf["TRUST_PROXY"],
        connections=max(256, min(65536, _raise_fd_limit() - 64)),  # its file limit, less its own files
    )
    fork = multiprocessing.get_context("fork")  # before any thread exists in this process
    pools = [
        fork.Process(
            target=_run_workers, args=(_gunicorn(app_sock, workers, threads), overrides), name="omninav-workers"
        ),
        # one process for the streams: each holds a thread, EVENT_STREAMS at once (the app counts
        # them), and a few threads more to answer the one over that 503
        fork.Process(
            target=_run_workers,
            args=(_gunicorn(events_sock, 1, streams + 4), {**overrides, "WARM_VENUES": False}),
            name="omninav-events",
        ),
    ]
    runner = _job_runner(conf) if conf["JOB_RUNNER"] else None
    proxy = None
    stop = [False]

    def stopping(*_: Any) -> None:
        stop[0] = True

    for sig in (signal.SIGTERM, signal.SIGINT):
        signal.signal(sig, stopping)
    try:
        for p in pools:
            p.start()
        if runner is not None:
            runner.start()
        for p, sock in zip(pools, (app_sock, events_sock), strict=True):
            _wait_for_socket(sock, p)
        proxy = start(nginx, front, _die_with_parent)
        _wait_for_port(host, port, proxy)
        for u in urls:
            echo(f"omninav: {u}")
        whose = (
            "OMNINAV_ADMIN_TOKEN" if os.environ.get("OMNINAV_ADMIN_TOKEN") else "the token printed on the first start"
        )
        echo(f"admin page: {urls[0]}admin (sign in with {whose})")
        sys.stdout.flush()
        while not stop[0]:
            if proxy.poll() is not None:
                _say_unless(stop, "omninav: nginx stopped; shutting down")
                break
            if not all(p.is_alive() for p in pools):  # the server is down if its workers are
                _say_unless(stop, "omninav: the worker processes stopped; shutting down")
                break
            if runner is not None and not runner.is_alive():  # e.g. killed for memory mid-job
                print("omninav: the job runner stopped; starting it again", file=sys.stderr)
                runner = _job_runner(conf)  # its job is taken up again (Jobs.reap)
                runner.start()
                time.sleep(5.0)
            time.sleep(0.5)
    finally:
        if proxy is not None and proxy.poll() is None:
            proxy.terminate()  # nginx's fast shutdown: open connections close now
            with contextlib.suppress(Exception):
                proxy.wait(10)
        children = [*pools, *([runner] if runner is not None else [])]
        for c in children:
            if c.is_alive():
                c.terminate()
        for c in children:
            c.join(15)
            if c.is_alive():
                c.kill()
        shutil.rmtree(run_dir, ignore_errors=True)


def _gunicorn(sock: str, workers: int, threads: int) -> dict[str, Any]:
    """gunicorn's options for a pool behind nginx. Its own head limits are lifted: nginx's are the
    ones that hold (a head nginx lets through must not come back as gunicorn's HTML 400 or 414)."""
    return {
        "bind": f"unix:{sock}",
        "workers": workers,
        "worker_class": "gthread",
        "threads": threads,
        "timeout": 60,
        "graceful_timeout": 10,
        "keepalive": 75,  # nginx keeps its connections to the workers open
        "limit_request_line": 0,
        "limit_request_field_size": 32768,  # 0 would be gunicorn's 8,190, under nginx's 16 KB
        "limit_request_fields": 32768,
        "permit_unconventional_http_method": True,  # nginx has checked the method: no HTML 400 here
        "accesslog": None,
        "errorlog": "-",
        "loglevel": "warning",
        "proc_name": "omninav",
    }


def _say_unless(stop: list[bool], message: str) -> None:
    """A child's end is news only if this process was not told to stop (Ctrl-C reaches them all)."""
    time.sleep(0.2)
    if not stop[0]:
        print(message, file=sys.stderr)


def _check_port_free(host: str, port: int) -> None:
    """OmninavError if another program listens on host:port (nginx would fail to bind it later)."""
    family = socket.AF_INET6 if ":" in host else socket.AF_INET
    with socket.socket(family, socket.SOCK_STREAM) as s:
        s.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        try:
            s.bind((host, port))
        except OSError as e:
            raise OmninavError(f"cannot listen on {host}:{port} ({e.strerror}): use --port for another") from None


def _wait_for_port(host: str, port: int, proxy: Any, timeout_s: float = 30.0) -> None:
    """Until nginx accepts connections on the port; an error if it exits first (port taken, say)."""
    target = "127.0.0.1" if host in ("0.0.0.0", "") else ("::1" if host == "::" else host)
    t0 = time.monotonic()
    while True:
        if proxy.poll() is not None:
            raise OmninavError(f"nginx did not start on {host}:{port} (its message is above)")
        with contextlib.suppress(OSError), socket.create_connection((target, port), timeout=1):
            return
        if time.monotonic() - t0 > timeout_s:
            raise OmninavError(f"nginx did not listen on {host}:{port} within {timeout_s:g} s")
        time.sleep(0.05)


def _job_runner(conf: dict[str, Any]) -> Any:
    # spawned, not forked: a fresh interpreter, whatever this process holds by then
    return multiprocessing.get_context("spawn").Process(target=_run_jobs, args=(conf,), name="omninav-jobs")


def _raise_fd_limit() -> int:
    """Every connection is a file descriptor: raise the soft limit to the hard one (nginx, a child,
    inherits it); -> the limit."""
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
    """Linux: this child gets SIGTERM when `omninav serve` dies, even by kill -9 (prctl PR_SET_PDEATHSIG)."""
    try:
        ctypes.CDLL(None, use_errno=True).prctl(1, signal.SIGTERM)
    except (OSError, AttributeError):
        pass


def _run_workers(options: dict[str, Any], overrides: dict[str, Any]) -> None:
    _die_with_parent()
    _Gunicorn(options, overrides).run()


def _run_jobs(conf: dict[str, Any]) -> None:
    """The job runner: claims queued jobs from the database and models them, at a lower priority
    than the workers (a modelling job must not slow the answers: measured in docs/benchlog.md)."""
    _die_with_parent()
    os.nice(10)
    # one BLAS thread, as in the app workers (_Gunicorn.load): the runner shares the cores with
    # them, and a pool of threads that wait for each other is slowest exactly when a worker is
    # busy on one of the cores (a 10-frame search against 8,000 frames: 8.0 ms with the default
    # two threads beside one busy process, 1.8 ms with one)
    from threadpoolctl import threadpool_limits

    threadpool_limits(1)
    # SIGTERM (the server stopping) ends the process at once: a job it was running wrote nothing
    # live, and the next runner takes it up again (its owner is gone: Jobs.reap). A terminal's
    # Ctrl-C is for `omninav serve`, which stops this process with SIGTERM.
    signal.signal(signal.SIGTERM, lambda *_: sys.exit(0))
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:  # a modelling job's processes, started once for every job (extract_pool.py)
        start_workers()
    except Exception as e:  # noqa: BLE001 - a job starts them again, and fails saying why it cannot
        log.warning("the extraction processes did not start: %s", e)
    db = Db(database_url(conf))
    jobs = Jobs(Catalog(db, Path(conf["DATA"])), stale_s=conf["JOB_STALE_S"], device=conf["DEVICE"] or None)
    jobs.run_forever()


def default_workers() -> int:
    """One process per core and one more: a request's Python holds the GIL, so processes, not
    threads, use the cores; the extra one takes up the slack while others wait on I/O."""
    return max(2, min(9, multiprocessing.cpu_count() + 1))
