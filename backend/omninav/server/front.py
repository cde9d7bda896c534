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
from urllib.parse import unquote

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
    # after an answer given before the body was read (401, 409, 413, 429): the rest is read and
    # dropped this long at most, a pause of linger_idle_s ending it, before the connection closes
    linger_s: float = 5.0
    linger_idle_s: float = 1.0
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
        have = hashlib.sha256(token.strip().encode()).hexdigest()
        t, want = self._cached
        age = time.monotonic() - t
        # a token that does not match is checked again against the database (at most once a
        # second): a token made a moment ago by `admin-token --reset` works at once
        if age > self.ttl_s or (age > 1.0 and not (want and hmac.compare_digest(have, want))):
            want = await asyncio.get_running_loop().run_in_executor(None, self._digest)
            self._cached = (time.monotonic(), want)
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
        self.buffered = 0  # bytes of request bodies and answers held in memory now, all clients
        self.client_buffered: dict[str, int] = {}  # and per client: no one client may hold the budget
        self.tasks: set[asyncio.Task[None]] = set()

    # ---- connections ------------------------------------------------------------------------------
    async def handle(self, reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
        peer = (writer.get_extra_info("peername") or ("?",))[0]
        per_client = not self.trust_proxy  # behind a proxy every connection comes from the proxy
        if self.total >= self.limits.max_conns or (
            per_client and self.conns.get(peer, 0) >= self.limits.max_conns_per_client
        ):
            writer.close()  # no answer: an answer is what a flood wants
            return
        task = asyncio.current_task()
        if task is not None:
            self.tasks.add(task)
        self.total += 1
        self.conns[peer] = self.conns.get(peer, 0) + 1
        try:
            await self._serve(reader, writer, peer)
        except (ConnectionError, asyncio.IncompleteReadError, ssl.SSLError, TimeoutError, h11.ProtocolError):
            pass
        except asyncio.CancelledError:  # the server is stopping
            pass
        except Exception:  # a bug here must not take the front down: drop this connection only
            log.exception("front: connection from %s", peer)
        finally:
            self.total -= 1
            self.conns[peer] -= 1
            if not self.conns[peer]:
                del self.conns[peer]
            writer.close()
            self.tasks.discard(task)

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
                if conn.their_state is h11.SEND_BODY:  # answered before its body was read
                    await self._linger(conn, reader)
                return
            conn.start_next_cycle()

    async def _linger(self, conn: h11.Connection, reader: asyncio.StreamReader) -> None:
        """Read and drop the rest of a body that was answered without being read, up to its end
        (as its head framed it) or for a bounded while, before the connection closes. Closing on
        unread bytes resets the connection, and a client still sending (most send the whole body
        before they read) loses the answer: a broken pipe instead of the 409 that said why.
        nginx's lingering close; bounded by linger_s and linger_idle_s, so it costs a hostile
        client's connection no more than its other deadlines do."""
        end = time.monotonic() + self.limits.linger_s
        with contextlib.suppress(Exception):
            while (left := end - time.monotonic()) > 0:
                ev = conn.next_event()
                if ev is h11.NEED_DATA:
                    data = await asyncio.wait_for(reader.read(CHUNK), min(left, self.limits.linger_idle_s))
                    if not data:
                        return
                    conn.receive_data(data)
                elif isinstance(ev, h11.EndOfMessage | h11.ConnectionClosed):
                    return  # all of it sent: the client reads its answer now

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
        method = req.method.decode("latin-1")
        headers = list(req.headers)
        hmap = {k: v for k, v in headers}
        client = client_address(peer, headers, self.trust_proxy)
        body = b""
        try:
            path = route_path(req.target)
            length = int(hmap[b"content-length"]) if b"content-length" in hmap else None
            chunked = b"transfer-encoding" in hmap
            if chunked and length is not None:  # two framings: a request smuggler's favourite
                raise HttpError(400, "a request may not have both Content-Length and Transfer-Encoding")
            admin = path.startswith("/api/admin/")
            authorised = admin and await self.tokens.ok(hmap.get(b"authorization", b"").decode("latin-1"))
            stream = authorised and method == "PUT" and UPLOAD.match(path) is not None
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
            fwd = forwarded_headers(headers, client, self.https)
            if admin and not authorised:  # the workers refuse it (401/403) before reading a body:
                fwd.append((b"content-length", b"0"))  # so the body is never read, never buffered
                return await self._forward(conn, writer, req, fwd, b"") and False
            if conn.they_are_waiting_for_100_continue:
                await self._send(writer, conn.send(h11.InformationalResponse(status_code=100, headers=[])))
            if stream:
                return await self._forward_streamed(conn, reader, writer, req, fwd, length, chunked)
            body = await self._read_body(conn, reader, length, client)
            fwd.append((b"content-length", str(len(body)).encode()))
            return await self._forward(conn, writer, req, fwd, body)
        except HttpError as e:
            await self._error(conn, writer, e)
            return False
        finally:
            self._unhold(client, len(body))

    def _hold(self, client: str, n: int) -> None:
        """Count n more bytes held in memory for `client`; 503 when the server or this client is at
        its share (a quarter of the budget each: one client cannot starve the others)."""
        mine = self.client_buffered.get(client, 0)
        if self.buffered + n > self.limits.buffer_budget or mine + n > self.limits.buffer_budget // 4:
            raise HttpError(503, "the server is busy; try again in a moment", [("Retry-After", "2")])
        self.buffered += n
        self.client_buffered[client] = mine + n

    def _unhold(self, client: str, n: int) -> None:
        if n:
            self.buffered -= n
            left = self.client_buffered.get(client, 0) - n
            if left > 0:
                self.client_buffered[client] = left
            else:
                self.client_buffered.pop(client, None)

    async def _read_body(
        self, conn: h11.Connection, reader: asyncio.StreamReader, length: int | None, client: str
    ) -> bytes:
        """The whole body, held in memory (counted against the budget), arriving at no less than
        body_min_rate on average after body_idle_s of grace, with no pause over body_idle_s."""
        lim = self.limits
        t0 = time.monotonic()
        parts: list[bytes] = []
        got = 0
        try:
            while True:
                ev = conn.next_event()
                if ev is h11.NEED_DATA:
                    due = t0 + lim.body_idle_s + (length if length is not None else got + CHUNK) / lim.body_min_rate
                    try:
                        await self._recv(conn, reader, min(lim.body_idle_s, due - time.monotonic()))
                    except TimeoutError:
                        raise HttpError(408, "the request body arrived too slowly; send it again") from None
                    continue
                if isinstance(ev, h11.Data):
                    if got + len(ev.data) > lim.max_body:
                        raise HttpError(413, f"request body too large (the limit here is {lim.max_body} bytes)")
                    self._hold(client, len(ev.data))
                    got += len(ev.data)
                    parts.append(bytes(ev.data))
                    continue
                if isinstance(ev, h11.EndOfMessage):
                    return b"".join(parts)
                raise HttpError(400, "the request ended before its body")
        except h11.RemoteProtocolError as e:
            self._unhold(client, got)
            raise HttpError(400, f"malformed request body: {e}") from None
        except BaseException:  # an error, a reset, a cancelled task: whatever was held is let go
            self._unhold(client, got)
            raise

    async def _forward(
        self,
        conn: h11.Connection,
        writer: asyncio.StreamWriter,
        req: h11.Request,
        fwd: list[tuple[bytes, bytes]],
        body: bytes,
    ) -> bool:
        """A complete request to the workers; their answer read whole (memory within the budget,
        else a temporary file) and the worker let go, then written at the client's pace."""
        idempotent = req.method in (b"GET", b"HEAD", b"OPTIONS")
        async with self.backend.gate:
            for attempt in (0, 1):
                written = False
                r = w = None
                try:
                    r, w, reused = await self.backend.connect()
                    bc = h11.Connection(h11.CLIENT)
                    w.write(bc.send(h11.Request(method=req.method, target=req.target, headers=fwd)))
                    if body:
                        w.write(bc.send(h11.Data(data=body)))
                    w.write(bc.send(h11.EndOfMessage()))
                    await w.drain()
                    written = True
                    resp = await self._backend_event(bc, r)
                except (OSError, h11.ProtocolError, asyncio.IncompleteReadError):
                    if w is not None:
                        w.close()
                    # a kept-alive connection the workers had closed: safe to send again only if
                    # the request never went out, or if doing it twice does no harm
                    if attempt == 0 and r is not None and reused and (idempotent or not written):
                        continue
                    raise HttpError(502, "the server's workers did not answer; try again") from None
                break
            assert r is not None and w is not None  # the loop either connected or raised
            if not any(k == b"content-length" for k, _ in resp.headers):
                return await self._stream_answer(conn, writer, bc, r, w, resp)  # server-sent events
            try:
                answer = await self._take_answer(bc, r, w)
            except (OSError, h11.ProtocolError, asyncio.IncompleteReadError):
                w.close()
                raise HttpError(502, "the server's workers stopped in the middle of an answer") from None
        return await self._write_answer(conn, writer, resp, *answer)

    async def _take_answer(self, bc: h11.Connection, r: Any, w: Any) -> tuple[Any, int, int]:
        """The rest of a worker's answer -> (spool, size, bytes held in memory); the connection
        goes back to the pool. Memory up to the per-answer bound and what the budget has left."""
        room = max(1, min(self.limits.max_response_buffer, self.limits.buffer_budget - self.buffered))
        spool = tempfile.SpooledTemporaryFile(max_size=room)  # (0 would mean: never to a file)  # noqa: SIM115 (closed by _write_answer)
        size = 0
        try:
            while isinstance(ev := await self._backend_event(bc, r), h11.Data):
                spool.write(ev.data)
                size += len(ev.data)
        except BaseException:
            spool.close()
            raise
        self.backend.release(r, w, bc.our_state is h11.DONE and bc.their_state is h11.DONE)
        held = size if size <= room else 0
        self.buffered += held
        return spool, size, held

    async def _write_answer(
        self, conn: h11.Connection, writer: asyncio.StreamWriter, resp: h11.Response, spool: Any, size: int, held: int
    ) -> bool:
        """Write a taken answer; the client must read it at body_min_rate on average (after write_s
        of grace), or it is dropped."""
        lim = self.limits
        try:
            due = time.monotonic() + lim.write_s + size / lim.body_min_rate
            await self._send(writer, conn.send(answer_head(resp)), due)
            spool.seek(0)
            while piece := spool.read(CHUNK):
                await self._send(writer, conn.send(h11.Data(data=piece)), due)
            await self._send(writer, conn.send(h11.EndOfMessage()), due)
        finally:
            spool.close()
            self.buffered -= held
        return not any(k == b"connection" and v.lower() == b"close" for k, v in resp.headers)

    async def _stream_answer(
        self, conn: h11.Connection, writer: asyncio.StreamWriter, bc: h11.Connection, r: Any, w: Any, resp: Any
    ) -> bool:
        """An answer without a length (server-sent events, admin only): passed on piece by piece."""
        try:
            await self._send(writer, conn.send(answer_head(resp)))
            while isinstance(ev := await self._backend_event(bc, r), h11.Data):
                await self._send(writer, conn.send(h11.Data(data=ev.data)))
            await self._send(writer, conn.send(h11.EndOfMessage()))
        except BaseException:
            w.close()
            raise
        self.backend.release(r, w, bc.our_state is h11.DONE and bc.their_state is h11.DONE)
        return True

    async def _forward_streamed(
        self,
        conn: h11.Connection,
        reader: asyncio.StreamReader,
        writer: asyncio.StreamWriter,
        req: h11.Request,
        fwd: list[tuple[bytes, bytes]],
        length: int | None,
        chunked: bool,
    ) -> bool:
        """An admin's video upload: passed on as it arrives. A pause longer than upload_idle_s, or
        the client going away, ends the body where it stands; the workers keep what arrived, and
        the client resumes from there."""
        if length is not None:
            fwd.append((b"content-length", str(length).encode()))
        elif chunked:
            fwd.append((b"transfer-encoding", b"chunked"))
        async with self.backend.gate:
            try:
                r, w, _ = await self.backend.connect()
            except OSError:
                raise HttpError(502, "the server's workers did not answer; try again") from None
            bc = h11.Connection(h11.CLIENT)
            w.write(bc.send(h11.Request(method=req.method, target=req.target, headers=fwd)))
            # the workers may answer before taking the body (409: another upload holds the video)
            pump = asyncio.create_task(self._pump(conn, reader, bc, w))
            answer = asyncio.create_task(self._backend_event(bc, r))
            try:
                await asyncio.wait({pump, answer}, return_when=asyncio.FIRST_COMPLETED)
                early = not pump.done()
                if early:
                    pump.cancel()
                    with contextlib.suppress(BaseException):
                        await pump
                resp = await asyncio.wait_for(answer, self.limits.upload_idle_s * 2)
            except (OSError, h11.ProtocolError, asyncio.IncompleteReadError, TimeoutError):
                w.close()
                raise HttpError(502, "the server's workers did not answer; try again") from None
            finally:
                for t in (pump, answer):
                    t.cancel()
            if not any(k == b"content-length" for k, _ in resp.headers):
                return await self._stream_answer(conn, writer, bc, r, w, resp) and False
            try:
                taken = await self._take_answer(bc, r, w)
            except (OSError, h11.ProtocolError, asyncio.IncompleteReadError):
                w.close()
                raise HttpError(502, "the server's workers stopped in the middle of an answer") from None
        keep = await self._write_answer(conn, writer, resp, *taken)
        return keep and not early and conn.their_state is h11.DONE

    async def _pump(
        self, conn: h11.Connection, reader: asyncio.StreamReader, bc: h11.Connection, w: asyncio.StreamWriter
    ) -> None:
        """The client's body to the workers as it arrives. However it ends short (a pause over
        upload_idle_s, a reset, a broken TLS record, too many bytes) the workers are told at once
        (end of stream), so none of their threads waits on a client that has gone."""
        sent = 0
        try:
            while True:
                ev = conn.next_event()
                if ev is h11.NEED_DATA:
                    await self._recv(conn, reader, self.limits.upload_idle_s)
                    continue
                if isinstance(ev, h11.Data):
                    sent += len(ev.data)
                    if sent > self.max_upload:
                        return
                    w.write(bc.send(h11.Data(data=ev.data)))
                    await w.drain()
                    continue
                if isinstance(ev, h11.EndOfMessage):
                    w.write(bc.send(h11.EndOfMessage()))
                    await w.drain()
                return
        except Exception:  # noqa: BLE001 - any way the client's side ends: the workers keep what came
            return
        finally:
            if bc.our_state is not h11.DONE and not w.is_closing():
                with contextlib.suppress(Exception):
                    w.write_eof()

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

    async def _send(self, writer: asyncio.StreamWriter, data: bytes | None, due: float | None = None) -> None:
        if data:
            writer.write(data)
            wait = self.limits.write_s if due is None else due - time.monotonic()
            await asyncio.wait_for(writer.drain(), max(wait, 0.001))

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


def route_path(target: bytes) -> str:
    """The path the workers will route: percent-decoded as gunicorn decodes it, so that
    /api/venues/x/%6Cocate is the locate it is. Only origin-form targets ("/...") are taken."""
    t = target.decode("latin-1")
    if not t.startswith("/"):
        raise HttpError(400, "the request target must be a path starting with '/'")
    return unquote(t.split("?", 1)[0], encoding="latin-1")


def _without_connection_tokens(headers: list[tuple[bytes, bytes]]) -> list[tuple[bytes, bytes]]:
    """Drop hop-by-hop headers: the fixed list and any named in Connection (RFC 9110 7.6.1)."""
    named = {t.strip().lower() for k, v in headers if k == b"connection" for t in v.split(b",")}
    return [(k, v) for k, v in headers if k not in HOP_BY_HOP and k not in named]


def forwarded_headers(headers: list[tuple[bytes, bytes]], client: str, https: bool) -> list[tuple[bytes, bytes]]:
    return [
        *_without_connection_tokens(headers),
        (b"x-forwarded-for", client.encode("latin-1")),
        (b"x-forwarded-proto", b"https" if https else b"http"),
    ]


def answer_head(resp: h11.Response) -> h11.Response:
    """The workers' answer head for the client: their framing kept, hop-by-hop and Server dropped."""
    length = [(k, v) for k, v in resp.headers if k == b"content-length"]
    kept = [(k, v) for k, v in _without_connection_tokens(list(resp.headers)) if k != b"server"]
    return h11.Response(status_code=resp.status_code, headers=kept + length, reason=resp.reason)


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
    try:
        await stop.wait()
    finally:
        server.close()
        for t in list(front.tasks):  # open connections end now (Python 3.12+ would wait for them)
            t.cancel()
        await asyncio.gather(*front.tasks, return_exceptions=True)
