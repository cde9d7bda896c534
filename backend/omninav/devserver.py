"""A real `omninav serve` in a process of its own, for the tests and the benchmarks.

The live tests (tests/), the benchmarks (bench/) and anyone scripting against a running server all
need the same thing: start the command `npm start` runs on a data directory, wait until it answers
`/api/health`, and later stop every process it made (nginx, gunicorn arbiters and workers, job
runner). It lives in the package, rather than in tests/ or bench/, because the package is installed
(editable) into `.venv`, so pytest and `.venv/bin/python -m bench.x` both import it with no
`sys.path` edits; it is not part of the server (nothing under `omninav.server` imports it) and uses
only the standard library. The JavaScript side (e2e, bench/web_extract.mjs) has its own, e2e/server.cjs.

    with ServeProcess(data, "--demo", "none", env={"OMNINAV_ADMIN_TOKEN": "t"}) as srv:
        urllib.request.urlopen(srv.base + "/api/venues")
"""

from __future__ import annotations

import os
import signal
import socket
import ssl
import subprocess
import sys
import tempfile
import time
import urllib.error
import urllib.request
from collections.abc import Mapping
from pathlib import Path
from types import TracebackType
from typing import IO


class ServerDidNotStart(RuntimeError):
    """`omninav serve` exited, or did not answer /api/health in time; the message ends with its log."""


def free_port() -> int:
    """A TCP port on 127.0.0.1 that nothing listens on right now."""
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port: int = s.getsockname()[1]
        return port


class ServeProcess:
    """`omninav serve --port PORT *args` on `data`, started (and waited for) on construction, like
    `subprocess.Popen`; a context manager that stops it on exit.

    - `env` is laid over this process's environment and `OMNINAV_DATA=data`.
    - The server runs in a session (process group) of its own, so `stop` and `kill` reach gunicorn's
      workers and the job runner too.
    - Its stdout and stderr go to `log` (kept), or to a temporary file removed when it stops; `log_text()`
      reads it, and the error raised when it does not start ends with it.
    - With `--https` in `args`, `base` is https:// and `ctx` trusts exactly the certificate the server
      made for itself.
    """

    def __init__(
        self,
        data: str | os.PathLike[str],
        *args: str,
        env: Mapping[str, str] | None = None,
        port: int | None = None,
        log: str | os.PathLike[str] | None = None,
        timeout: float = 60.0,
        executable: str | None = None,
    ) -> None:
        self.data = Path(data)
        self.port = port if port is not None else free_port()
        self.https = "--https" in args
        self.base = f"{'https' if self.https else 'http'}://127.0.0.1:{self.port}"
        self._keep_log = log is not None
        if log is None:
            fd, name = tempfile.mkstemp(prefix=f"omninav-serve-{self.port}-", suffix=".log")
            os.close(fd)
            log = name
        self.log_path = Path(log)
        self._log: IO[bytes] = open(self.log_path, "wb")  # noqa: SIM115 (open as long as the server runs)
        exe = executable or str(Path(sys.executable).with_name("omninav"))
        cmd = [exe, "serve", "--port", str(self.port), *args]
        full_env = {**os.environ, "OMNINAV_DATA": str(self.data), **(env or {})}
        try:
            self.proc = subprocess.Popen(
                cmd,
                env=full_env,
                stdin=subprocess.DEVNULL,
                stdout=self._log,
                stderr=subprocess.STDOUT,
                start_new_session=True,
            )
        except BaseException:
            self._close()
            raise
        try:
            self._wait_healthy(timeout)
        except BaseException:
            self.stop()
            raise

    @property
    def pid(self) -> int:
        """The `omninav serve` process (it watches the rest); also the id of the server's process group."""
        return self.proc.pid

    @property
    def ctx(self) -> ssl.SSLContext | None:
        """For https: trust exactly the local authority that issued the server's certificate, as a
        phone does (it exists once the server listens)."""
        return ssl.create_default_context(cafile=str(self.data / "tls" / "ca.pem")) if self.https else None

    def rss_mb(self, name: str | None = None) -> float:
        """Resident memory of the server's processes (its session's), or of those called `name`
        (e.g. "nginx": master and worker), in MB (Linux /proc)."""
        total = 0
        for pid in (p for p in os.listdir("/proc") if p.isdigit()):
            try:
                stat = Path(f"/proc/{pid}/stat").read_text()
                comm, rest = stat[stat.index("(") + 1 : stat.rindex(")")], stat[stat.rindex(")") + 2 :].split()
                if int(rest[3]) == self.pid and name in (None, comm):  # field 6: the session
                    total += int(Path(f"/proc/{pid}/status").read_text().split("VmRSS:")[1].split()[0])
            except (OSError, IndexError, ValueError):
                continue
        return total / 1024

    def log_text(self) -> str:
        """What the server has written so far (stdout and stderr)."""
        try:
            return self.log_path.read_text(errors="replace")
        except FileNotFoundError:
            return ""

    def healthy(self) -> bool:
        """One `GET /api/health`: True when it answers 200."""
        try:
            with urllib.request.urlopen(self.base + "/api/health", timeout=5, context=self.ctx) as r:
                return bool(r.status == 200)
        except (OSError, urllib.error.URLError, ssl.SSLError):
            return False

    def _wait_healthy(self, timeout: float) -> None:
        deadline = time.monotonic() + timeout
        while not self.healthy():
            if self.proc.poll() is not None:
                raise ServerDidNotStart(f"omninav serve exited ({self.proc.returncode}):\n{self.log_text()}")
            if time.monotonic() > deadline:
                raise ServerDidNotStart(f"omninav serve did not answer within {timeout:g} s:\n{self.log_text()}")
            time.sleep(0.2)

    def _signal_group(self, sig: signal.Signals) -> None:
        # only while the leader is not yet reaped: until then its pid, the group's id, cannot be reused
        if self.proc.returncode is None:
            try:
                os.killpg(self.proc.pid, sig)
            except ProcessLookupError:
                pass

    def stop(self, grace: float = 10.0) -> int:
        """SIGTERM to the whole process group, then SIGKILL if the server has not exited after `grace`
        seconds: -> its exit status. Stopping a stopped server does nothing."""
        self._signal_group(signal.SIGTERM)
        try:
            self.proc.wait(grace)
        except subprocess.TimeoutExpired:
            self._signal_group(signal.SIGKILL)
            self.proc.wait(10)
        self._close()
        return self.proc.returncode

    def kill(self) -> None:
        """SIGKILL to the whole process group at once: the server gets no chance to clean up (as
        when a machine loses power)."""
        self._signal_group(signal.SIGKILL)
        self.proc.wait(10)
        self._close()

    def _close(self) -> None:
        self._log.close()
        if not self._keep_log:
            self.log_path.unlink(missing_ok=True)

    def __enter__(self) -> ServeProcess:
        return self

    def __exit__(
        self, exc_type: type[BaseException] | None, exc: BaseException | None, tb: TracebackType | None
    ) -> None:
        self.stop()


def unfinished_bodies(port: int, addresses: list[str], each: int, mb: int, path: str) -> list[socket.socket]:
    """An attacker's bodies: `each` connections from each (loopback) address, each sending all but
    the last byte of an `mb` MB POST to `path`; -> the open sockets (the caller closes them)."""
    head = (
        f"POST {path} HTTP/1.1\r\nHost: x\r\nContent-Type: application/octet-stream\r\n"
        f"Content-Length: {mb << 20}\r\n\r\n"
    ).encode()
    chunk, out = bytes(1 << 20), []
    for a in addresses:
        for _ in range(each):
            s = socket.create_connection(("127.0.0.1", port), source_address=(a, 0))
            out.append(s)
            s.sendall(head)
            for _ in range(mb - 1):
                s.sendall(chunk)
            s.sendall(chunk[:-1])
    return out
