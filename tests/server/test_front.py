"""The server as a building runs it (`omninav serve`: nginx in front, gunicorn workers, the events
worker, the job runner), attacked over real sockets the way someone on the same Wi-Fi could: slow and
idle connections, malformed requests, forged X-Forwarded-For, unfinished huge bodies from a few
addresses, thousands of sockets, open job-event streams, two uploads of one video at once. Each test
names the finding it guards (of issue 9, or the break of issue 39)."""

from __future__ import annotations

import json
import os
import socket
import threading
import time
import urllib.request

import pytest

from omninav.devserver import unfinished_bodies
from server_helpers import ADMIN
from test_server_live import Server


@pytest.fixture
def fast_timeouts(monkeypatch):
    """Deadlines of 1.5 s instead of 10 s, so the tests see the front hang up."""
    monkeypatch.setenv("OMNINAV_FRONT_TIMEOUT_S", "1.5")


def health_ms(srv: Server) -> float:
    t0 = time.perf_counter()
    with urllib.request.urlopen(srv.base + "/api/health", timeout=5, context=srv.ctx) as r:
        assert r.status == 200 and json.loads(r.read())["status"] == "ok"
    return (time.perf_counter() - t0) * 1000


def slow_sockets(port: int, n: int, tls: bool = False) -> list[socket.socket]:
    """n connections that announce a 100 KB body and send 3 bytes of it (or, with tls, nothing at all:
    not even a TLS handshake)."""
    out = []
    for i in range(n):  # from 8 addresses, none of them the tests' own: nginx limits each address
        s = socket.create_connection(("127.0.0.1", port), source_address=(f"127.0.3.{i % 8 + 1}", 0))
        if not tls:
            s.sendall(
                b"POST /api/venues/lab/locate HTTP/1.1\r\nHost: x\r\nContent-Type: application/json\r\n"
                b"Content-Length: 100000\r\n\r\nabc"
            )
        out.append(s)
    return out


def raw_request(port: int, data: bytes, timeout: float = 10, until: bytes | None = None) -> bytes:
    """What the server sends back, to its close (or, with `until`, to the first time that appears)."""
    with socket.create_connection(("127.0.0.1", port), timeout=timeout) as s:
        s.sendall(data)
        got = b""
        while (until is None or until not in got) and (chunk := s.recv(65536)):
            got += chunk
    return got


def test_slow_bodies_do_not_starve_anyone_and_are_cut_off(tmp_path, fast_timeouts):
    """Finding 3: 8 sockets that announced a 100 KB body and sent 3 bytes stopped /api/health for minutes."""
    srv = Server(tmp_path / "data")
    try:
        socks = slow_sockets(srv.port, 64)  # more than every worker thread together (2 x 4)
        times = [health_ms(srv) for _ in range(20)]
        assert max(times) < 1000, times
        # nginx hangs up on the stalled ones once the body stops for 1.5 s (no answer: none is read)
        socks[0].settimeout(10)
        t0 = time.monotonic()
        assert socks[0].recv(65536) == b"" and time.monotonic() - t0 < 5
        for s in socks:
            s.close()
    finally:
        srv.kill()


def test_idle_connections_under_https_do_not_block_the_handshake(tmp_path, fast_timeouts):
    """Finding 3: under --https six idle TCP connections blocked /api/health (the handshake ran in a
    worker thread). Now the handshake is asynchronous, and an idle connection is closed."""
    srv = Server(tmp_path / "data", "--https")
    try:
        idle = slow_sockets(srv.port, 40, tls=True)
        assert max(health_ms(srv) for _ in range(10)) < 1000
        idle[0].settimeout(10)
        t0 = time.monotonic()
        assert idle[0].recv(100) == b""  # hung up on, after the handshake deadline
        assert time.monotonic() - t0 < 5
        with urllib.request.urlopen(srv.base + "/", timeout=5, context=srv.ctx) as r:
            assert r.headers["Strict-Transport-Security"].startswith("max-age=")  # finding 14: HSTS on HTTPS
        for s in idle:
            s.close()
    finally:
        srv.kill()


def test_malformed_requests_get_json_errors_not_html(tmp_path):
    """Finding 14: gunicorn answered an over-long request line with an HTML 414. Breaks 7 and 8 of
    issue 39: HTTP/1.0 without Host got 502, and heads past the front's check got gunicorn's HTML."""
    srv = Server(tmp_path / "data")
    try:
        got = raw_request(srv.port, b"GET /api/health HTTP/1.0\r\n\r\n")  # a health check's form
        assert got.split(b"\r\n")[0].split()[1] == b"200" and b'"status":"ok"' in got, got[:200]
        big = raw_request(srv.port, b"GET /api/health HTTP/1.1\r\nHost: x\r\nX-A: " + b"a" * 20000 + b"\r\n\r\n")
        assert big.startswith(b"HTTP/1.1 431") and json.loads(big.split(b"\r\n\r\n", 1)[1])["status"] == 431
        # what nginx lets through, gunicorn takes: a 12 KB line, 300 headers
        line = raw_request(
            srv.port, b"GET /api/health?" + b"a" * 12000 + b" HTTP/1.1\r\nHost: x\r\nConnection: close\r\n\r\n"
        )
        many = b"".join(b"X-%d: a\r\n" % i for i in range(300)) + b"X-Big: " + b"b" * 15000 + b"\r\n"
        fields = raw_request(srv.port, b"GET /api/health HTTP/1.1\r\nHost: x\r\n" + many + b"Connection: close\r\n\r\n")
        for got in (line, fields):
            assert got.startswith(b"HTTP/1.1 200") and b"<html" not in got.lower(), got[:300]
        # odd bytes and methods are refused in JSON too (gunicorn's HTML 400 never reaches a client)
        odd_heads = (
            b"GET /api/h\xc3\xa4lth HTTP/1.1\r\n",
            b"ET /api/health HTTP/1.1\r\n",
            b"GET /api/health HTTP/2.0\r\n",
            b"GET /api/health HTTP/1.1\r\nX-A: a\x01b\r\n",  # nginx passes it on; gunicorn refuses it
        )
        for odd in odd_heads:
            got = raw_request(srv.port, odd + b"Host: x\r\nConnection: close\r\n\r\n")
            assert b"<html" not in got.lower() and json.loads(got.split(b"\r\n\r\n", 1)[1])["status"] >= 400, got
        got = raw_request(srv.port, b"GET /api/" + b"a" * 70000 + b" HTTP/1.1\r\nHost: x\r\n\r\n")
        status, _, rest = got.partition(b"\r\n")
        assert status.split()[1] in (b"414", b"431"), status
        body = json.loads(rest.split(b"\r\n\r\n", 1)[1])
        assert body["status"] in (414, 431) and "too large" in body["error"]
        got = raw_request(srv.port, b"GARBAGE\r\n\r\n")
        assert got.startswith(b"HTTP/1.1 400") and b'"error"' in got and b"<html" not in got.lower()
        # an announced body over the limit is refused before it is read
        got = raw_request(
            srv.port,
            b"POST /api/venues/x/locate HTTP/1.1\r\nHost: x\r\nContent-Type: application/json\r\n"
            b"Content-Length: 999999999\r\n\r\n",
        )
        assert got.startswith(b"HTTP/1.1 413") and b"too large" in got
    finally:
        srv.kill()


def test_security_headers_on_the_app_and_the_api(tmp_path):
    """Finding 14: CSP (opencv.js needs 'wasm-unsafe-eval' and nothing more), nosniff, Referrer-Policy,
    frame-ancestors."""
    srv = Server(tmp_path / "data")
    try:
        for path in ("/", "/api/health"):
            with urllib.request.urlopen(srv.base + path, timeout=5) as r:
                csp = r.headers["Content-Security-Policy"]
                assert "script-src 'self' 'wasm-unsafe-eval';" in csp and "unsafe-inline" not in csp
                assert "frame-ancestors 'none'" in csp and "'unsafe-eval'" not in csp
                assert r.headers["X-Content-Type-Options"] == "nosniff"
                assert r.headers["Referrer-Policy"] == "no-referrer"
                assert "Strict-Transport-Security" not in r.headers  # plain HTTP: no HSTS
                assert "gunicorn" not in (r.headers.get("Server") or "")
    finally:
        srv.kill()


def locate_statuses(srv: Server, n: int, forwarded: list[str] | None = None) -> list[int]:
    out = []
    for i in range(n):
        h = {"Content-Type": "application/json"}
        if forwarded:
            h["X-Forwarded-For"] = forwarded[i % len(forwarded)]
        out.append(srv.call("POST", "/api/venues/lab/locate", {"mag": []}, h)[0])
    return out


@pytest.mark.parametrize("trust_proxy", [False, True])
def test_the_locate_limit_is_per_client_across_workers_and_cannot_be_forged(tmp_path, trust_proxy):
    """Finding 10: with 2 workers 66 of 150 passed a limit of 30 (each worker had its own buckets), and
    with TRUST_PROXY the client chose its own address with the leftmost X-Forwarded-For."""
    env = {"OMNINAV_LOCATE_RATE": "1", "OMNINAV_LOCATE_BURST": "10", "OMNINAV_TRUST_PROXY": str(int(trust_proxy))}
    srv = Server(tmp_path / "data", env=env)
    try:
        assert srv.call("POST", "/api/admin/venues", {"id": "lab"}, admin=True)[0] == 201
        t0 = time.monotonic()
        # every request forges a new leftmost address; the proxy (trusted or not) appended the last one
        forged = [f"10.0.{i}.1, 192.0.2.7" for i in range(60)]
        got = locate_statuses(srv, 60, forged)
        passed = sum(s != 429 for s in got)
        allowed = 10 + (time.monotonic() - t0) * 1.0
        assert 10 <= passed <= allowed + 1, (passed, allowed, got)
        assert set(got) == {409, 429}  # not modelled (it got through) or limited, nothing else
        if trust_proxy:  # another client behind the same trusted proxy has its own bucket
            assert locate_statuses(srv, 3, ["192.0.2.8"]) == [409] * 3
        else:  # without a trusted proxy the header means nothing: same client, still limited
            assert locate_statuses(srv, 3, ["192.0.2.8"]) == [429] * 3
    finally:
        srv.kill()


def test_two_uploads_of_one_video_at_once_have_one_writer(tmp_path, small_ds):
    """Finding 6: two simultaneous uploads could leave a file marked ready with the other upload's bytes."""
    srv = Server(tmp_path / "data")
    try:
        data = build_lab(srv, small_ds)
        walk_path = json.loads(small_ds.model_walk_path.read_text())
        body = {"name": "walk.mp4", "size": len(data), "walk_path": walk_path, "lens": "donut"}
        url = "/api/admin/venues/lab/videos/walk.mp4/content"

        # upload A sends half, pauses while B tries, then sends the rest
        a = socket.create_connection(("127.0.0.1", srv.port), timeout=30)
        a.sendall(
            f"PUT {url} HTTP/1.1\r\nHost: x\r\nAuthorization: {ADMIN['Authorization']}\r\n"
            f"Content-Type: application/octet-stream\r\nContent-Length: {len(data)}\r\n\r\n".encode()
        )
        a.sendall(data[: len(data) // 2])
        time.sleep(1.0)
        other = bytes(len(data))  # B's bytes differ everywhere
        st, err = srv.call("PUT", url, other, {"Content-Type": "application/octet-stream"}, admin=True)
        assert st == 409 and "another upload" in err["error"], err
        st, err = srv.call("POST", "/api/admin/venues/lab/videos", body, admin=True)  # nor replaced meanwhile
        assert st == 409 and "being uploaded" in err["error"]
        a.sendall(data[len(data) // 2 :])
        reply = b""
        while b"\r\n\r\n" not in reply or not reply.rstrip().endswith(b"}"):
            reply += a.recv(65536)
        a.close()
        assert reply.startswith(b"HTTP/1.1 200"), reply[:200]
        _, v = srv.call("GET", "/api/admin/venues/lab/videos/walk.mp4", admin=True)
        assert v["status"] == "ready" and v["received"] == len(data)
        assert (tmp_path / "data" / "videos" / "lab" / "walk.mp4").read_bytes() == data
        # once A is done, the video is not writable as an upload any more
        st, err = srv.call("PUT", url, other, {"Content-Type": "application/octet-stream"}, admin=True)
        assert st == 409 and "already uploaded" in err["error"]
    finally:
        srv.kill()


def test_health_answers_while_many_clients_trickle(tmp_path):
    """50 clients trickling a body one byte a second (the default 10 s deadlines: they are still
    connected while the health checks run) and 50 holding idle connections: everyone else is
    answered at once."""
    srv = Server(tmp_path / "data")
    stop = threading.Event()

    def trickle(i: int) -> None:
        try:
            with socket.create_connection(
                ("127.0.0.1", srv.port), timeout=10, source_address=(f"127.0.4.{i % 8 + 1}", 0)
            ) as s:
                s.sendall(b"POST /api/venues/x/locate HTTP/1.1\r\nHost: x\r\nContent-Length: 5000\r\n\r\n")
                while not stop.is_set():
                    s.sendall(b"[")
                    time.sleep(1.0)
        except OSError:
            pass

    threads = [threading.Thread(target=trickle, args=(i,), daemon=True) for i in range(50)]
    try:
        for t in threads:
            t.start()
        idle = slow_sockets(srv.port, 50, tls=True)
        time.sleep(0.5)
        assert max(health_ms(srv) for _ in range(20)) < 1000
        for s in idle:
            s.close()
    finally:
        stop.set()
        for t in threads:
            t.join(5)
        srv.kill()


def test_slow_readers_of_a_large_answer_hold_no_worker(tmp_path):
    """Review finding: answers were written to the client while a worker slot was held, so a few
    clients reading a large file slowly blocked everyone (the front now takes the whole answer
    first, lets the worker go, and writes at the client's pace)."""
    dist = tmp_path / "dist"
    dist.mkdir()
    (dist / "index.html").write_text("<!doctype html><html lang=en><title>x</title></html>")
    (dist / "big.bin").write_bytes(bytes(8 * 1024 * 1024))
    srv = Server(tmp_path / "data", env={"OMNINAV_WEB_DIST": str(dist)})
    readers = []
    try:
        for i in range(24):  # three times every worker thread (2 workers x 4 threads), 8 addresses
            s = socket.create_connection(("127.0.0.1", srv.port), source_address=(f"127.0.5.{i % 8 + 1}", 0))
            s.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 65536)
            s.sendall(b"GET /big.bin HTTP/1.1\r\nHost: x\r\nAccept-Encoding: identity\r\n\r\n")
            readers.append(s)
        time.sleep(1.0)
        # held workers would never answer (these readers read nothing until the end), so any
        # answer well within health_ms's 5 s shows none is held; 1 s was too tight beside other
        # work (2.5 s measured with two benchmarks running on the 2 cores)
        assert max(health_ms(srv) for _ in range(10)) < 4000
        got = b""
        while len(got) < 8 * 1024 * 1024:  # and a slow reader still gets all of it
            chunk = readers[0].recv(1 << 20)
            assert chunk
            got += chunk if got or b"\r\n\r\n" not in chunk else chunk.split(b"\r\n\r\n", 1)[1]
    finally:
        for s in readers:
            s.close()
        srv.kill()


def test_uploads_cut_off_mid_body_free_their_worker_and_resume(tmp_path, small_ds):
    """Review finding: a client that went away in the middle of an upload left a worker thread
    waiting for the rest for ever; ten such uploads (more than the workers' threads) and the server
    still answers, and each time the upload resumes where the server says it stands.

    A cut-off piece keeps its bytes when they reached the app before the cut, or none when nginx
    was still asking the app about the token (a loaded machine): either is right, so the test
    resumes from the server's count; of five pieces cut off each way (a close, a reset) at least
    one must have kept them. A worker still held shows as 409 "another upload in
    progress" until its 60 s lease lapses, so a resume that succeeds within 10 s shows it freed."""
    srv = Server(tmp_path / "data")
    try:
        data = build_lab(srv, small_ds)
        url = "/api/admin/venues/lab/videos/walk.mp4/content"
        total = len(data)

        def received() -> int:
            return srv.call("GET", "/api/admin/venues/lab/videos/walk.mp4", admin=True)[1]["received"]

        def piece(at: int, n: int) -> tuple[int, dict]:
            rng = f"bytes {at}-{at + n - 1}/{total}"
            head = {"Content-Type": "application/octet-stream", "Content-Range": rng}
            return srv.call("PUT", url, data[at : at + n], head, admin=True)

        kept = [0, 0]  # bytes kept by pieces cut off by a normal close, and by an abortive one (RST)
        for i in range(10):
            sent = received()
            with socket.create_connection(("127.0.0.1", srv.port), timeout=30) as a:
                a.sendall(
                    f"PUT {url} HTTP/1.1\r\nHost: x\r\nAuthorization: {ADMIN['Authorization']}\r\n"
                    f"Content-Type: application/octet-stream\r\nContent-Range: bytes {sent}-{total - 1}/"
                    f"{total}\r\nContent-Length: {total - sent}\r\n\r\n".encode()
                )
                a.sendall(data[sent : sent + 1000])
                time.sleep(0.3)  # mostly: nginx has asked the app about the token and passed the bytes on
                if i % 2:
                    a.setsockopt(socket.SOL_SOCKET, socket.SO_LINGER, b"\x01\x00\x00\x00\x00\x00\x00\x00")
            deadline = time.time() + 10  # the worker sees the end of the body, keeps what came, lets go
            while True:
                at = received()
                assert at in (sent, sent + 1000), f"a cut-off piece kept {at - sent} of 1000 bytes"
                st, v = piece(at, 500)
                if st == 202:
                    break
                assert st == 409 and time.time() < deadline, f"the cut-off upload did not end: {st} {v}"
                time.sleep(0.1)
            kept[i % 2] += at - sent
            assert v["received"] == at + 500
            assert health_ms(srv) < 2000
        assert kept[0] > 0 and kept[1] > 0, f"cut-off pieces kept no bytes (normal close, RST): {kept}"
        at = received()
        st, v = piece(at, total - at)
        assert st == 200 and v["status"] == "ready"
        assert (tmp_path / "data" / "videos" / "lab" / "walk.mp4").read_bytes() == data
    finally:
        srv.kill()


def test_an_encoded_locate_path_is_still_limited_and_admin_bodies_need_the_token(tmp_path):
    """Review findings: /api/venues/x/%6Cocate reached locate past the limit (the workers decode
    the path); an admin body without the token was read before the workers refused it. Break 4 of
    issue 39: a '#' in the target dodged the limit."""
    env = {"OMNINAV_LOCATE_RATE": "0.5", "OMNINAV_LOCATE_BURST": "2"}
    srv = Server(tmp_path / "data", env=env)
    try:
        paths = ["/api/venues/lab/locate", "/api/venues/lab/%6Cocate", "/api/venues/lab/loc%61te"] * 2
        paths += ["/api/venues/lab/locate#x", "//api/venues/lab/./locate"]  # break 4 of issue 39: 89/s got through
        got = [
            int(
                raw_request(
                    srv.port,
                    f"POST {p} HTTP/1.1\r\nHost: x\r\nContent-Type: application/json\r\n"
                    "Content-Length: 2\r\nConnection: close\r\n\r\n{}".encode(),
                ).split()[1]
            )
            for p in paths
        ]
        assert got[:2] == [404, 404] and set(got[2:]) == {429}, got
        # an absolute target is the same locate, and as limited
        assert raw_request(
            srv.port, b"POST http://x/api/venues/lab/locate HTTP/1.1\r\nHost: x\r\nConnection: close\r\n\r\n"
        ).startswith(b"HTTP/1.1 429")
        t0 = time.monotonic()
        head = (
            b"POST /api/admin/venues HTTP/1.1\r\nHost: x\r\nContent-Type: application/json\r\n"
            b"Content-Length: 30000000\r\n\r\n"
        )
        got = raw_request(srv.port, head)  # no token, and no byte of the 30 MB body is sent
        assert got.startswith(b"HTTP/1.1 401") and b"admin token" in got and time.monotonic() - t0 < 5
        # an upload over the other bodies' limit with a wrong token is told about the token, in JSON
        got = raw_request(
            srv.port,
            b"PUT /api/admin/venues/lab/videos/a.mp4/content HTTP/1.1\r\nHost: x\r\nAuthorization: Bearer nope\r\n"
            b"Content-Length: 100000000\r\n\r\n",
        )
        assert got.startswith(b"HTTP/1.1 403") and json.loads(got.split(b"\r\n\r\n", 1)[1])["status"] == 403
        # and with the token it reaches the app, whose own answer comes back (no such venue here)
        got = raw_request(
            srv.port,
            b"PUT /api/admin/venues/lab/videos/a.mp4/content HTTP/1.1\r\nHost: x\r\nAuthorization: "
            + ADMIN["Authorization"].encode()
            + b"\r\nContent-Length: 100000000\r\nConnection: close\r\n\r\n",
        )
        assert got.startswith(b"HTTP/1.1 404") and b"lab" in got, got[:300]
    finally:
        srv.kill()


def build_lab(srv: Server, small_ds) -> bytes:
    """Venue 'lab' with a plan, a scale and a lens, and video walk.mp4 announced: -> its bytes."""
    assert srv.call("POST", "/api/admin/venues", {"id": "lab"}, admin=True)[0] == 201
    plan = small_ds.floorplan.read_bytes()
    assert srv.call("PUT", "/api/admin/venues/lab/floors/1/plan", plan, {"Content-Type": "image/png"}, True)[0] == 200
    assert srv.call("PUT", "/api/admin/venues/lab/floors/1", {"px_per_m": 20}, admin=True)[0] == 200
    lens = json.loads((small_ds.root / "model_lens.json").read_text())
    assert srv.call("PUT", "/api/admin/venues/lab/lenses/donut", lens, admin=True)[0] == 200
    data = small_ds.model_video.read_bytes()
    walk_path = json.loads(small_ds.model_walk_path.read_text())
    body = {"name": "walk.mp4", "size": len(data), "walk_path": walk_path, "lens": "donut"}
    assert srv.call("POST", "/api/admin/venues/lab/videos", body, admin=True)[0] == 201
    return data


def test_an_answer_given_before_the_body_reaches_a_client_still_sending_it(tmp_path):
    """CI finding: some requests are answered without their body being read (an admin request
    without the token: 401; a video upload the workers refuse at once: 409; a locate over the rate:
    429; a body over the limit: 413). Closing on unread bytes resets the connection, and a client
    still sending (urllib sends the whole body before it reads) got a broken pipe instead of the
    answer; nginx reads and drops the rest for a bounded while first (its lingering close)."""
    srv = Server(tmp_path / "data")
    try:
        big = bytes(24 * 1024 * 1024)  # more than the sockets' buffers hold: the close would come first
        for _ in range(3):
            st, err = srv.call("PUT", "/api/admin/venues/lab/videos/walk.mp4/content", big)
            assert st == 401 and "token" in err["error"].lower(), err
        # over the body limit (32 MiB): refused from its head, the body still in flight
        st, err = srv.call("POST", "/api/venues/lab/locate", bytes(33 * 1024 * 1024))
        assert st == 413 and "too large" in err["error"], err
        # and a client that stops sending is not waited on past the linger
        s = socket.create_connection(("127.0.0.1", srv.port), timeout=30)
        s.sendall(
            b"PUT /api/admin/venues/lab/videos/walk.mp4/content HTTP/1.1\r\nHost: x\r\nContent-Length: 1000000\r\n\r\n"
        )
        t0 = time.monotonic()
        got = b""
        while chunk := s.recv(65536):
            got += chunk
        assert got.startswith(b"HTTP/1.1 401") and time.monotonic() - t0 < 15, (got[:100], time.monotonic() - t0)
        s.close()
    finally:
        srv.kill()


def test_unfinished_huge_bodies_keep_nginx_small_and_take_no_ones_share(tmp_path):
    """Breaks 2 and 3 of issue 39: 16 unfinished 32 MB bodies from 4 addresses grew the front to
    2.4 GB over four rounds (its budget 512 MB) and held it, and while they trickled every other
    phone's locate got 503. Bodies now wait on disk: nginx stays within a few MB whatever they
    carry, gives it back when they go, and everyone else is answered meanwhile."""
    srv = Server(tmp_path / "data")
    try:
        assert srv.call("POST", "/api/admin/venues", {"id": "lab"}, admin=True)[0] == 201
        base = srv.rss_mb("nginx")
        assert base > 0
        peak = 0.0
        for _ in range(4):
            socks = unfinished_bodies(srv.port, [f"127.0.0.{i}" for i in range(2, 6)], 4, 32, "/api/venues/lab/locate")
            peak = max(peak, srv.rss_mb("nginx"))
            # another phone's locate goes through to the app (409: 'lab' is not modelled), at once
            t0 = time.monotonic()
            assert [srv.call("POST", "/api/venues/lab/locate", {"mag": []})[0] for _ in range(5)] == [409] * 5
            assert time.monotonic() - t0 < 2
            for s in socks:
                s.close()
        time.sleep(1.0)
        after = srv.rss_mb("nginx")
        assert peak - base < 64, (base, peak)  # 512 MB of bodies each round
        assert after - base < 16, (base, after)
    finally:
        srv.kill()


def test_thousands_of_sockets_from_a_few_addresses_do_not_shut_others_out(tmp_path):
    """Break 5 of issue 39: 2,048 sockets from 9 addresses filled the front's connection cap. An
    idle connection costs nginx a few KB, its cap is in the thousands, and an idle one is closed
    after the head deadline."""
    import resource

    soft, hard = resource.getrlimit(resource.RLIMIT_NOFILE)
    resource.setrlimit(resource.RLIMIT_NOFILE, (min(hard, 8192), hard))
    srv = Server(tmp_path / "data")
    socks = []
    try:
        for i in range(2100):
            socks.append(socket.create_connection(("127.0.0.1", srv.port), source_address=(f"127.0.1.{i % 9 + 1}", 0)))
        assert max(health_ms(srv) for _ in range(10)) < 1000
    finally:
        for s in socks:
            s.close()
        srv.kill()
        resource.setrlimit(resource.RLIMIT_NOFILE, (soft, hard))


def test_a_body_the_app_refuses_unread_gets_its_json_answer(tmp_path):
    """Break 6 of issue 39: a body the workers refused before reading it (a 1 MB record, a 10 MB
    multipart, a 30 MB JSON string) came back as 502: the worker closed on the unread bytes. The
    app reads and drops such a body before it answers, so its JSON 4xx arrives."""
    srv = Server(tmp_path / "data")
    try:
        multipart = (
            b'--XX\r\nContent-Disposition: form-data; name="f"; filename="a.jpg"\r\nContent-Type: image/jpeg\r\n\r\n'
            + os.urandom(10 << 20)
            + b"\r\n--XX--\r\n"
        )
        bodies = [
            (os.urandom(1 << 20), "application/octet-stream"),
            (multipart, "multipart/form-data; boundary=XX"),
            (b'"' + b"a" * (30 << 20) + b'"', "application/json"),
        ]
        for _ in range(2):
            for body, ctype in bodies:
                st, err = srv.call("POST", "/api/venues/nowhere/locate", body, {"Content-Type": ctype})
                assert st == 404 and "unknown venue" in err["error"], (st, err)
    finally:
        srv.kill()


def test_job_event_streams_take_no_worker_and_are_bounded(tmp_path, small_ds):
    """Break 1 of issue 39: six idle job-event streams took every worker thread, and health,
    locate and the admin API timed out until ~30 s after they closed. Streams are served by a
    worker of their own, at most EVENT_STREAMS at once (more: 503, and the page polls), counted
    after the token check."""
    srv = Server(tmp_path / "data", env={"OMNINAV_JOB_RUNNER": "0"})  # EVENT_STREAMS: 8
    streams = []
    try:
        data = build_lab(srv, small_ds)
        url = "/api/admin/venues/lab/videos/walk.mp4/content"
        assert srv.call("PUT", url, data, {"Content-Type": "application/octet-stream"}, admin=True)[0] == 200
        st, job = srv.call("POST", "/api/admin/venues/lab/jobs", admin=True)
        assert st == 201 and job["state"] == "queued"  # and it stays queued: no job runner
        head = (
            f"GET /api/admin/jobs/{job['id']}/events HTTP/1.1\r\nHost: x\r\n"
            f"Authorization: {ADMIN['Authorization']}\r\nAccept: text/event-stream\r\n\r\n"
        ).encode()
        for _ in range(8):  # as many as the app workers have threads (2 x 4)
            s = socket.create_connection(("127.0.0.1", srv.port), timeout=10)
            s.sendall(head)
            first = b""
            while b"event: progress" not in first and (chunk := s.recv(65536)):
                first += chunk
            assert first.startswith(b"HTTP/1.1 200") and b"event: progress" in first, first[:300]
            streams.append(s)
        over = raw_request(srv.port, head.replace(b"\r\n\r\n", b"\r\nConnection: close\r\n\r\n"))
        assert over.startswith(b"HTTP/1.1 503") and b"Retry-After: 2" in over, over[:300]
        err = json.loads(over.split(b"\r\n\r\n", 1)[1])
        assert err["status"] == 503 and "job-event streams at once" in err["error"]  # the app's count
        # a client without the token holds no stream: refused before the count
        tokenless = head.replace(ADMIN["Authorization"].encode(), b"Bearer nope").replace(
            b"\r\n\r\n", b"\r\nConnection: close\r\n\r\n"
        )
        assert raw_request(srv.port, tokenless).startswith(b"HTTP/1.1 403")
        # the app is untouched meanwhile
        t0 = time.monotonic()
        for _ in range(20):
            health_ms(srv)
            assert srv.call("GET", f"/api/admin/jobs/{job['id']}", admin=True)[0] == 200
            assert srv.call("POST", "/api/venues/lab/locate", {"mag": []})[0] == 409
        assert time.monotonic() - t0 < 5
        for s in streams:
            s.close()
        streams.clear()
        # a closed stream gives its place back at its next heartbeat (2 s), not ~30 s later
        t0 = time.monotonic()
        closing = head.replace(b"\r\n\r\n", b"\r\nConnection: close\r\n\r\n")
        while not (got := raw_request(srv.port, closing, timeout=5, until=b"event: ")).startswith(b"HTTP/1.1 200"):
            assert got.startswith(b"HTTP/1.1 503") and time.monotonic() - t0 < 6, got[:200]
            time.sleep(0.2)
    finally:
        for s in streams:
            s.close()
        srv.kill()
