"""The asynchronous front: the only part of `omninav serve` that talks to the network.

    phones, admins --TLS/HTTP--> front (one asyncio process) --HTTP on a unix socket--> gunicorn workers

Why it exists: gunicorn's gthread workers read each request, and run its TLS handshake, in a worker
thread, so a handful of slow or idle connections held every thread and the server stopped answering
(slowloris; six idle TCP connections were enough under --https). The front reads whole requests
asynchronously under deadlines, then hands complete requests to the workers over a local socket, and
takes their whole answers back before writing them out at the client's pace: a worker thread is never
held by a client's network. This is what nginx's request and response buffering does; the front also
owns what must be the same for every worker: the locate rate limit per client (one bucket per client
for the whole server, not one per worker process), the client's address (with TRUST_PROXY, the one
the trusted proxy appended to X-Forwarded-For), connection caps, and JSON errors for requests too
malformed to reach Flask (gunicorn answered those in HTML).

Why not a library: nginx or Caddy cannot be installed by pip or npm (npm start must work without
root on a fresh laptop); Python's async servers (uvicorn, hypercorn) run the WSGI app in their own
process and stream bodies into it or hold a thread per slow reader. HTTP/1.1 parsing here is h11's
(both sides), TLS is asyncio's; this module is only the policy: deadlines, sizes, caps, buffering.

Streaming is kept where buffering would be wrong: a video upload (PUT .../videos/NAME/content, up to
16 GiB) carrying the valid admin token is passed through as it arrives, with an idle timeout; a
response without a length (server-sent events) is passed through as the backend writes it.
"""

from __future__ import annotations

import asyncio
import contextlib
import hashlib
import hmac
import json
import logging
import re
import ssl
import tempfile
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import h11

from .ratelimit import RateLimiter

log = logging.getLogger("omninav.front")

LOCATE = re.compile(r"^/api/venues/[^/?]+/locate$")
UPLOAD = re.compile(r"^/api/admin/venues/[^/?]+/videos/[^/?]+/content$")
HOP_BY_HOP = {
    b"connection",
    b"keep-alive",
    b"proxy-authenticate",
    b"proxy-authorization",
    b"te",
    b"trailer",
    b"transfer-encoding",
    b"upgrade",
    b"expect",
    b"content-length",
    b"x-forwarded-for",
    b"x-forwarded-proto",
    b"x-real-ip",
    b"forwarded",
}
CHUNK = 64 * 1024


@dataclass
class Limits:
    """Every bound the front enforces; each one is a way a client could otherwise hold the server."""

    handshake_s: float = 10.0  # TLS handshake
    head_s: float = 10.0  # from a request's first byte to the end of its head
    keepalive_s: float = 30.0  # an idle kept-alive connection, between requests
    first_byte_s: float = 10.0  # a new connection that sends nothing
    body_idle_s: float = 10.0  # no byte of a body for this long: 408
    body_min_rate: float = 32 * 1024  # bytes/s a buffered body must average (after body_idle_s of grace)
    upload_idle_s: float = 60.0  # a streamed video upload may pause this long
    write_s: float = 30.0  # a client that reads nothing of its answer for this long is dropped
    max_head: int = 16 * 1024  # request line and headers
    max_body: int = 32 * 1024 * 1024  # any body but a streamed upload (MAX_CONTENT_LENGTH)
    buffer_budget: int = 512 * 1024 * 1024  # bodies and answers held in memory at once, all clients
    max_response_buffer: int = 32 * 1024 * 1024  # larger answers are spooled to a temporary file
    max_conns: int = 2048
    max_conns_per_client: int = 256
    backend_concurrency: int = 16  # requests in the workers at once (workers x threads): the rest queue here


class HttpError(Exception):
    def __init__(self, status: int, message: str, headers: list[tuple[str, str]] | None = None):
        super().__init__(message)
        self.status, self.message, self.headers = status, message, headers or []


def client_address(peer: str, headers: list[tuple[bytes, bytes]], trust_proxy: bool) -> str:
    """The client: the peer, or behind a trusted proxy the address that proxy appended (the last
    X-Forwarded-For entry; everything left of it was written by the client and proves nothing)."""
    if trust_proxy:
        fwd = [v.decode("latin-1") for k, v in headers if k == b"x-forwarded-for"]
        if fwd:
            last = ",".join(fwd).split(",")[-1].strip()
            if last:
                return last
    return peer


class TokenCheck:
    """Is this the admin token? Its SHA-256 is read from the database, at most every few seconds
    (`omninav admin-token --reset` takes effect without a restart)."""

    def __init__(self, digest: Callable[[], str | None], ttl_s: float = 3.0):
        self._digest = digest
        self.ttl_s = ttl_s
        self._cached: tuple[float, str | None] = (-1e9, None)

    async def ok(self, authorization: str | None) -> bool:
        scheme, _, token = (authorization or "").partition(" ")
        if scheme.lower() != "bearer" or not token.strip():
            return False
        t, want = self._cached
        if time.monotonic() - t > self.ttl_s:
            want = await asyncio.get_running_loop().run_in_executor(None, self._digest)
            self._cached = (time.monotonic(), want)
        have = hashlib.sha256(token.strip().encode()).hexdigest()
        return bool(want) and hmac.compare_digest(have, want or "")


class Backend:
    """Keep-alive HTTP/1.1 connections to the gunicorn workers' unix socket."""

    def __init__(self, path: str, concurrency: int):
        self.path = path
        self.idle: list[tuple[asyncio.StreamReader, asyncio.StreamWriter]] = []
        self.gate = asyncio.Semaphore(concurrency)

    async def connect(self) -> tuple[asyncio.StreamReader, asyncio.StreamWriter, bool]:
        while self.idle:
            r, w = self.idle.pop()
            if not w.is_closing() and not r.at_eof():
                return r, w, True
            w.close()
        r, w = await asyncio.open_unix_connection(self.path, limit=CHUNK * 4)
        return r, w, False

    def release(self, r: asyncio.StreamReader, w: asyncio.StreamWriter, reusable: bool) -> None:
        if reusable and len(self.idle) < 64:
            self.idle.append((r, w))
        else:
            w.close()


class Front:
    def __init__(
        self,
        backend_socket: str,
        limits: Limits,
        limiter: RateLimiter,
        token_digest: Callable[[], str | None],
        trust_proxy: bool = False,
        https: bool = False,
        max_upload: int = 16 * 1024**3,
    ):
        self.limits = limits
        self.backend = Backend(backend_socket, limits.backend_concurrency)
        self.limiter = limiter
        self.tokens = TokenCheck(token_digest)
        self.trust_proxy = trust_proxy
        self.https = https
        self.max_upload = max_upload
        self.conns: dict[str, int] = {}
        self.total = 0
        self.buffered = 0  # bytes of bodies and answers held in memory now

    # ---- connections ------------------------------------------------------------------------------
    async def handle(self, reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
        peer = (writer.get_extra_info("peername") or ("?",))[0]
        per_client = not self.trust_proxy  # behind a proxy every connection comes from the proxy
        if self.total >= self.limits.max_conns or (
            per_client and self.conns.get(peer, 0) >= self.limits.max_conns_per_client
        ):
            writer.close()  # no answer: an answer is what a flood wants
            return
        self.total += 1
        self.conns[peer] = self.conns.get(peer, 0) + 1
        try:
            await self._serve(reader, writer, peer)
        except (ConnectionError, asyncio.IncompleteReadError, ssl.SSLError, TimeoutError):
            pass
        except Exception:  # a bug here must not take the front down: drop this connection only
            log.exception("front: connection from %s", peer)
        finally:
            self.total -= 1
            self.conns[peer] -= 1
            if not self.conns[peer]:
                del self.conns[peer]
            writer.close()
            with contextlib.suppress(Exception):
                await asyncio.wait_for(writer.wait_closed(), 1.0)

    async def _serve(self, reader: asyncio.StreamReader, writer: asyncio.StreamWriter, peer: str) -> None:
        conn = h11.Connection(h11.SERVER, max_incomplete_event_size=self.limits.max_head)
        first = True
        while True:
            try:
                req = await self._read_head(conn, reader, first)
            except HttpError as e:
                await self._error(conn, writer, e)
                return
            if req is None:
                return
            first = False
            keep = await self._exchange(conn, reader, writer, req, peer)
            if not keep or conn.our_state is not h11.DONE or conn.their_state is not h11.DONE:
                return
            conn.start_next_cycle()

    async def _recv(self, conn: h11.Connection, reader: asyncio.StreamReader, timeout: float) -> None:
        if timeout <= 0:
            raise TimeoutError
        data = await asyncio.wait_for(reader.read(CHUNK), timeout)
        conn.receive_data(data)  # b"" is the end of the stream, which h11 understands

    async def _read_head(self, conn: h11.Connection, reader: asyncio.StreamReader, first: bool) -> h11.Request | None:
        wait = self.limits.first_byte_s if first else self.limits.keepalive_s
        deadline: float | None = None
        while True:
            try:
                ev = conn.next_event()
            except h11.RemoteProtocolError as e:  # h11's hint: 431 for a head over max_head, else 400
                what = "request line and headers too large" if e.error_status_hint == 431 else "malformed request"
                raise HttpError(e.error_status_hint, f"{what}: {e}") from None
            if ev is h11.NEED_DATA:
                if deadline is None and conn.trailing_data[0]:
                    deadline = time.monotonic() + self.limits.head_s
                try:
                    if deadline is None:  # waiting for the first byte of a request
                        await self._recv(conn, reader, wait)
                        deadline = time.monotonic() + self.limits.head_s
                    else:
                        await self._recv(conn, reader, deadline - time.monotonic())
                except TimeoutError:
                    if deadline is None:
                        return None  # an idle connection: close it quietly
                    raise HttpError(408, f"the request head did not arrive within {self.limits.head_s:g} s") from None
                continue
            if isinstance(ev, h11.Request):
                return ev
            return None  # ConnectionClosed or the like

    # ---- one request ------------------------------------------------------------------------------
    async def _exchange(
        self,
        conn: h11.Connection,
        reader: asyncio.StreamReader,
        writer: asyncio.StreamWriter,
        req: h11.Request,
        peer: str,
    ) -> bool:
        target = req.target.decode("latin-1")
        path = target.split("?", 1)[0]
        method = req.method.decode("latin-1")
        headers = list(req.headers)
        hmap = {k: v for k, v in headers}
        client = client_address(peer, headers, self.trust_proxy)
        try:
            length = int(hmap[b"content-length"]) if b"content-length" in hmap else None
            chunked = b"transfer-encoding" in hmap
            stream = (
                method == "PUT"
                and UPLOAD.match(path) is not None
                and await self.tokens.ok(hmap.get(b"authorization", b"").decode("latin-1"))
            )
            limit = self.max_upload if stream else self.limits.max_body
            if length is not None and length > limit:
                raise HttpError(413, f"request body too large: {length} bytes (the limit here is {limit})")
            if method == "POST" and LOCATE.match(path):
                wait = self.limiter.take(client)
                if wait > 0:
                    raise HttpError(
                        429,
                        "too many locate requests from this client; slow down",
                        [("Retry-After", str(max(1, int(wait + 0.999))))],
                    )
            if conn.they_are_waiting_for_100_continue:
                await self._send(writer, conn.send(h11.InformationalResponse(status_code=100, headers=[])))
            fwd = [(k, v) for k, v in headers if k not in HOP_BY_HOP]
            fwd += [
                (b"x-forwarded-for", client.encode("latin-1")),
                (b"x-forwarded-proto", b"https" if self.https else b"http"),
            ]
            if stream:
                return await self._forward_streamed(conn, reader, writer, req, fwd, length, chunked)
            body = await self._read_body(conn, reader, length)
        except HttpError as e:
            await self._error(conn, writer, e)
            return False
        try:
            fwd.append((b"content-length", str(len(body)).encode()))
            return await self._forward(conn, writer, req, fwd, body)
        finally:
            self.buffered -= len(body)

    async def _read_body(self, conn: h11.Connection, reader: asyncio.StreamReader, length: int | None) -> bytes:
        lim = self.limits
        grace = lim.body_idle_s + (length or 0) / lim.body_min_rate
        deadline = time.monotonic() + grace
        parts: list[bytes] = []
        got = 0
        try:
            while True:
                ev = conn.next_event()
                if ev is h11.NEED_DATA:
                    left = min(lim.body_idle_s, deadline - time.monotonic())
                    try:
                        await self._recv(conn, reader, left)
                    except TimeoutError:
                        raise HttpError(408, "the request body arrived too slowly; send it again") from None
                    continue
                if isinstance(ev, h11.Data):
                    got += len(ev.data)
                    if got > lim.max_body:
                        raise HttpError(413, f"request body too large (the limit here is {lim.max_body} bytes)")
                    if self.buffered + len(ev.data) > lim.buffer_budget:
                        raise HttpError(503, "the server is busy; try again in a moment", [("Retry-After", "2")])
                    self.buffered += len(ev.data)
                    parts.append(bytes(ev.data))
                    continue
                if isinstance(ev, h11.EndOfMessage):
                    break
                raise HttpError(400, "the request ended before its body")
        except h11.RemoteProtocolError as e:
            self.buffered -= got
            raise HttpError(400, f"malformed request body: {e}") from None
        except HttpError:
            self.buffered -= sum(len(p) for p in parts)
            raise
        return b"".join(parts)

    async def _forward(
        self, conn: h11.Connection, writer: asyncio.StreamWriter, req: h11.Request, fwd: list, body: bytes
    ) -> bool:
        async with self.backend.gate:
            for attempt in (0, 1):  # a kept-alive backend connection may have been closed meanwhile
                r, w, reused = await self.backend.connect()
                bc = h11.Connection(h11.CLIENT)
                try:
                    w.write(bc.send(h11.Request(method=req.method, target=req.target, headers=fwd)))
                    if body:
                        w.write(bc.send(h11.Data(data=body)))
                    w.write(bc.send(h11.EndOfMessage()))
                    await w.drain()
                    resp = await self._backend_event(bc, r)
                except (ConnectionError, h11.RemoteProtocolError, asyncio.IncompleteReadError):
                    w.close()
                    if reused and attempt == 0:
                        continue
                    raise HttpError(502, "the server's workers did not answer; try again") from None
                break
            return await self._relay(conn, writer, bc, r, w, resp)

    async def _forward_streamed(
        self,
        conn: h11.Connection,
        reader: asyncio.StreamReader,
        writer: asyncio.StreamWriter,
        req: h11.Request,
        fwd: list,
        length: int | None,
        chunked: bool,
    ) -> bool:
        """An admin's video upload: passed on as it arrives. A pause longer than upload_idle_s ends
        it; the workers keep what arrived and the client resumes from there."""
        if length is not None:
            fwd.append((b"content-length", str(length).encode()))
        elif chunked:
            fwd.append((b"transfer-encoding", b"chunked"))
        async with self.backend.gate:
            r, w, _ = await self.backend.connect()
            bc = h11.Connection(h11.CLIENT)
            w.write(bc.send(h11.Request(method=req.method, target=req.target, headers=fwd)))
            # the workers may answer before taking the body (409: another upload holds the video)
            pump = asyncio.create_task(self._pump(conn, reader, bc, w))
            answer = asyncio.create_task(self._backend_event(bc, r))
            await asyncio.wait({pump, answer}, return_when=asyncio.FIRST_COMPLETED)
            early = not pump.done()
            if early:
                pump.cancel()
            try:
                resp = await answer
            except (ConnectionError, h11.RemoteProtocolError, asyncio.IncompleteReadError):
                w.close()
                raise HttpError(502, "the server's workers did not answer; try again") from None
            keep = await self._relay(conn, writer, bc, r, w, resp)
            return keep and not early and conn.their_state is h11.DONE

    async def _pump(
        self, conn: h11.Connection, reader: asyncio.StreamReader, bc: h11.Connection, w: asyncio.StreamWriter
    ) -> None:
        """The client's body to the workers as it arrives; a pause longer than upload_idle_s ends it
        (the workers see a short body and keep what came)."""
        try:
            while True:
                ev = conn.next_event()
                if ev is h11.NEED_DATA:
                    try:
                        await self._recv(conn, reader, self.limits.upload_idle_s)
                    except TimeoutError:
                        break
                    continue
                if isinstance(ev, h11.Data):
                    w.write(bc.send(h11.Data(data=ev.data)))
                    await w.drain()
                    continue
                if isinstance(ev, h11.EndOfMessage):
                    w.write(bc.send(h11.EndOfMessage()))
                    await w.drain()
                    return
                break
            if w.can_write_eof():
                w.write_eof()
        except (ConnectionError, h11.ProtocolError):
            pass  # the workers stopped reading: their answer says why

    async def _backend_event(self, bc: h11.Connection, r: asyncio.StreamReader) -> Any:
        while True:
            ev = bc.next_event()
            if ev is h11.NEED_DATA:
                data = await r.read(CHUNK)
                if not data and bc.their_state is h11.SEND_RESPONSE:
                    raise ConnectionError("backend closed")
                bc.receive_data(data)
                continue
            if isinstance(ev, h11.InformationalResponse):
                continue
            return ev

    async def _relay(
        self,
        conn: h11.Connection,
        writer: asyncio.StreamWriter,
        bc: h11.Connection,
        r: asyncio.StreamReader,
        w: asyncio.StreamWriter,
        resp: h11.Response,
    ) -> bool:
        """The backend's answer to the client. With a length: read it all (memory up to a bound,
        then a temporary file), give the backend connection back, then write at the client's pace.
        Without one (server-sent events): pass each piece on as it comes."""
        headers = [
            (k, v) for k, v in resp.headers if k != b"server" and (k not in HOP_BY_HOP or k == b"content-length")
        ]
        if not any(k == b"content-length" for k, _ in resp.headers):
            await self._send(
                writer, conn.send(h11.Response(status_code=resp.status_code, headers=headers, reason=resp.reason))
            )
            try:
                while isinstance(ev := await self._backend_event(bc, r), h11.Data):
                    await self._send(writer, conn.send(h11.Data(data=ev.data)))
                await self._send(writer, conn.send(h11.EndOfMessage()))
            except BaseException:
                w.close()
                raise
            self.backend.release(r, w, bc.our_state is h11.DONE and bc.their_state is h11.DONE)
            return True
        spool = tempfile.SpooledTemporaryFile(max_size=self.limits.max_response_buffer)  # noqa: SIM115
        held = 0
        try:
            while True:
                ev = await self._backend_event(bc, r)
                if isinstance(ev, h11.Data):
                    spool.write(ev.data)
                    if held < self.limits.max_response_buffer:
                        held += len(ev.data)
                        self.buffered += len(ev.data)
                    continue
                break
            self.backend.release(r, w, bc.our_state is h11.DONE and bc.their_state is h11.DONE)
            await self._send(
                writer, conn.send(h11.Response(status_code=resp.status_code, headers=headers, reason=resp.reason))
            )
            spool.seek(0)
            while piece := spool.read(CHUNK):
                await self._send(writer, conn.send(h11.Data(data=piece)))
            await self._send(writer, conn.send(h11.EndOfMessage()))
        finally:
            spool.close()
            self.buffered -= held
        return not any(k == b"connection" and v.lower() == b"close" for k, v in resp.headers)

    async def _send(self, writer: asyncio.StreamWriter, data: bytes | None) -> None:
        if data:
            writer.write(data)
            await asyncio.wait_for(writer.drain(), self.limits.write_s)

    async def _error(self, conn: h11.Connection, writer: asyncio.StreamWriter, e: HttpError) -> None:
        """A JSON error, as the API's own: {"error", "status"}; then the connection is closed."""
        if conn.our_state not in (h11.IDLE, h11.SEND_RESPONSE):
            return
        body = json.dumps({"error": e.message, "status": e.status}).encode()
        headers = [
            ("Content-Type", "application/json"),
            ("Content-Length", str(len(body))),
            ("Connection", "close"),
            ("X-Content-Type-Options", "nosniff"),
            *e.headers,
        ]
        with contextlib.suppress(Exception):
            await self._send(writer, conn.send(h11.Response(status_code=e.status, headers=headers)))
            await self._send(writer, conn.send(h11.Data(data=body)))
            await self._send(writer, conn.send(h11.EndOfMessage()))


async def run_front(
    front: Front,
    host: str,
    port: int,
    ssl_ctx: ssl.SSLContext | None,
    stop: asyncio.Event,
    ready: Callable[[], None] | None = None,
) -> None:
    server = await asyncio.start_server(
        front.handle,
        host,
        port,
        ssl=ssl_ctx,
        ssl_handshake_timeout=front.limits.handshake_s if ssl_ctx else None,
        backlog=1024,
        limit=CHUNK * 4,
        reuse_address=True,
    )
    if ready:
        ready()
    async with server:
        await stop.wait()
