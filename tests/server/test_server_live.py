"""The server as `npm start` runs it (omninav serve: gunicorn, two worker processes) over real HTTP:
a venue built with chunked uploads, a job killed with its server and taken up again on restart, the
venue answering from its previous frames meanwhile, server-sent events, HTTPS."""

from __future__ import annotations

import http.client
import json
import os
import ssl
import subprocess
import time
import urllib.error
import urllib.request
from pathlib import Path

import pytest

from conftest import OMNINAV, seed_quick_demo
from omninav.devserver import ServeProcess, free_port
from omninav.spectrum import encode_binary
from server_helpers import ADMIN, TOKEN, check_response, clip_spectra, query_clip


class Server(ServeProcess):
    """`omninav serve` as `npm start` runs it (two workers, four threads each, no demo unless asked),
    with the test admin token and no locate limit; its log in data/../server-PORT.log."""

    def __init__(self, data: Path, *args: str, token: bool = True, env: dict[str, str] | None = None):
        port = free_port()
        env = {"OMNINAV_LOCATE_RATE": "0", **(env or {})}
        if token:
            env["OMNINAV_ADMIN_TOKEN"] = TOKEN
        if "--demo" not in args:
            args = ("--demo", "none", *args)
        super().__init__(
            data, "--workers", "2", "--threads", "4", *args, env=env, port=port, log=data.parent / f"server-{port}.log"
        )

    def call(self, method: str, path: str, body: bytes | None = None, headers: dict | None = None, admin=False):
        h = {**(headers or {}), **(ADMIN if admin else {})}
        if isinstance(body, dict | list):
            body, h["Content-Type"] = json.dumps(body).encode(), "application/json"
        req = urllib.request.Request(self.base + path, data=body, method=method, headers=h)
        try:
            with urllib.request.urlopen(req, timeout=60, context=self.ctx) as r:
                status, ctype, data = r.status, r.headers.get("Content-Type", ""), r.read()
        except urllib.error.HTTPError as e:
            status, ctype, data = e.code, e.headers.get("Content-Type", ""), e.read()
        check_response(method, path, status, ctype, data)
        return status, (json.loads(data) if ctype.startswith("application/json") else data)


def upload(srv: Server, venue: str, name: str, data: bytes, walk_path: dict, piece: int) -> dict:
    st, v = srv.call(
        "POST",
        f"/api/admin/venues/{venue}/videos",
        {"name": name, "size": len(data), "walk_path": walk_path, "lens": "donut"},
        admin=True,
    )
    assert st == 201, v
    for a in range(0, len(data), piece):
        b = min(len(data), a + piece) - 1
        st, v = srv.call(
            "PUT",
            v["upload_url"] if a == 0 else f"/api/admin/venues/{venue}/videos/{name}/content",
            data[a : b + 1],
            {"Content-Range": f"bytes {a}-{b}/{len(data)}", "Content-Type": "application/octet-stream"},
            admin=True,
        )
        assert st in (200, 202), v
    assert v["status"] == "ready" and v["received"] == len(data)
    return v


def wait_job(srv: Server, job_id: str, until=lambda j: j["state"] not in ("queued", "running"), timeout=180):
    t0 = time.time()
    while time.time() - t0 < timeout:
        _, j = srv.call("GET", f"/api/admin/jobs/{job_id}", admin=True)
        if until(j):
            return j
        time.sleep(0.05)
    raise AssertionError(f"job {job_id}: {j}")


def sse_events(srv: Server, job_id: str) -> list[tuple[str, dict]]:
    conn = http.client.HTTPConnection("127.0.0.1", srv.port, timeout=120)
    conn.request("GET", f"/api/admin/jobs/{job_id}/events", headers=ADMIN)
    r = conn.getresponse()
    assert r.status == 200 and r.headers["Content-Type"].startswith("text/event-stream")
    events, block = [], []
    while True:
        line = r.readline().decode()
        if not line:
            break
        if line.strip():
            block.append(line.strip())
            continue
        if block and block[0].startswith("event: "):
            events.append((block[0][7:], json.loads(block[1][6:])))
            if events[-1][0] != "progress":
                break
        block = []
    conn.close()
    return events


@pytest.fixture(scope="module")
def venue_data(small_ds, tmp_path_factory):
    """A data directory with venue 'lab' built and modelled through a running server."""
    data = tmp_path_factory.mktemp("live") / "data"
    data.mkdir()
    srv = Server(data)
    try:
        assert srv.call("POST", "/api/admin/venues", {"id": "lab", "name": "Lab"}, admin=True)[0] == 201
        st, _ = srv.call(
            "PUT",
            "/api/admin/venues/lab/floors/1/plan",
            small_ds.floorplan.read_bytes(),
            {"Content-Type": "image/png"},
            admin=True,
        )
        assert st == 200
        assert srv.call("PUT", "/api/admin/venues/lab/floors/1", {"px_per_m": 20}, admin=True)[0] == 200
        lens = json.loads((small_ds.root / "model_lens.json").read_text())
        assert srv.call("PUT", "/api/admin/venues/lab/lenses/donut", lens, admin=True)[0] == 200
        walk_path = json.loads(small_ds.model_walk_path.read_text())
        upload(srv, "lab", "walk.mp4", small_ds.model_video.read_bytes(), walk_path, piece=256 * 1024)
        st, job = srv.call("POST", "/api/admin/venues/lab/jobs", admin=True)
        assert st == 201
        assert wait_job(srv, job["id"])["state"] == "done"
    finally:
        srv.kill()
    return data


def test_a_job_killed_with_its_server_is_taken_up_again_on_restart(venue_data, small_ds):
    srv = Server(venue_data)
    try:
        _, v = srv.call("GET", "/api/venues/lab")
        before = v["frames"]
        frames, truth = query_clip(small_ds, 100)
        _, venue = srv.call("GET", "/api/venues/lab")
        spec = clip_spectra(small_ds, frames, venue["features"]["settings"])
        record = encode_binary(spec, venue["features"]["settings"])
        octet = {"Content-Type": "application/octet-stream"}
        st, a0 = srv.call("POST", "/api/venues/lab/locate", record, octet)
        assert st == 200 and abs(a0["x"] - truth[0]) < 2 and abs(a0["y"] - truth[1]) < 2
        walk_path = json.loads(small_ds.model_walk_path.read_text())
        data = small_ds.model_video.read_bytes()
        names = [f"copy{i}.mp4" for i in range(4)]
        for n in names:
            upload(srv, "lab", n, data, walk_path, piece=len(data))
        _, job = srv.call("POST", "/api/admin/venues/lab/jobs", {"videos": names}, admin=True)
        running = wait_job(srv, job["id"], until=lambda j: j["state"] == "running" and j["frames_done"] > 20)
        assert running["frames_done"] < running["frames_total"] and running["eta_s"] is not None
        srv.kill()

        srv = Server(venue_data)
        _, j = srv.call("GET", f"/api/admin/jobs/{job['id']}", admin=True)
        # the restarted server queues the job again by itself and takes it up after a short wait
        assert j["state"] in ("queued", "running") and "server stopped" in j["error"], j
        assert j["attempts"] in (1, 2) and j["max_attempts"] == 3
        _, v = srv.call("GET", "/api/venues/lab")
        assert v["frames"] == before  # the killed job wrote nothing
        st, a1 = srv.call("POST", "/api/venues/lab/locate", record, octet)
        assert st == 200 and (a1["x"], a1["y"]) == (a0["x"], a0["y"])

        events = sse_events(srv, job["id"])
        assert events[-1][0] == "done" and {k for k, _ in events[:-1]} <= {"progress"}
        assert events[-1][1]["frames_done"] == events[-1][1]["frames_total"]
        assert events[-1][1]["attempts"] == 2  # claimed once by each server
        _, v = srv.call("GET", "/api/venues/lab")
        assert v["frames"] == before * 5
        # every worker sees the new generation (VENUE_CACHE_S): the answer still holds
        for _ in range(6):
            st, a2 = srv.call("POST", "/api/venues/lab/locate", record, octet)
            assert st == 200 and abs(a2["x"] - truth[0]) < 2
        time.sleep(1.2)
        assert srv.call("POST", "/api/venues/lab/locate", record, octet)[1]["frames"] == 10
    finally:
        srv.kill()


def test_a_tracking_session_continues_on_every_worker_and_across_a_restart(venue_data, small_ds):
    """A walk's session lives in the database: whichever of the two workers answers, and after the
    server is stopped and started again on the same data folder (new processes, nothing of the walk
    in their memory), the filter goes on counting."""
    octet = {"Content-Type": "application/octet-stream"}
    srv = Server(venue_data)
    try:
        _, venue = srv.call("GET", "/api/venues/lab")
        conf = venue["features"]["settings"]
        records = []
        for start in (60, 80, 100, 120):
            frames, _ = query_clip(small_ds, start)
            records.append((encode_binary(clip_spectra(small_ds, frames, conf), conf), (start + 9) / 10.0))
        seen = []
        for i in range(12):  # two workers of four threads: the requests land on either
            record, t = records[i % len(records)]
            st, a = srv.call("POST", f"/api/venues/lab/locate?session=livewalk01&t={t + 8 * (i // 4)}", record, octet)
            assert st == 200, a
            seen.append(a["tracking"])
        assert [tr["updates"] for tr in seen] == list(range(1, 13))
        assert seen[0]["reason"] == "new" and all(tr["reason"] is None for tr in seen[1:])
        srv.stop()

        srv = Server(venue_data)
        record, t = records[0]
        st, a = srv.call("POST", f"/api/venues/lab/locate?session=livewalk01&t={t + 24}", record, octet)
        assert st == 200 and a["tracking"]["updates"] == 13 and not a["tracking"]["restarted"], a["tracking"]
        st, d = srv.call("GET", "/api/venues/lab/destinations")
        assert st == 200 and d["venue"] == "lab"
    finally:
        srv.kill()


def test_https_with_a_certificate_from_the_local_authority(venue_data):
    srv = Server(venue_data, "--https")  # srv.ctx trusts data/tls/ca.pem only, as a phone does
    try:
        st, h = srv.call("GET", "/api/health")
        assert st == 200 and h["status"] == "ok" and srv.base.startswith("https://")
        with pytest.raises(urllib.error.URLError):  # the authority is not trusted by default
            urllib.request.urlopen(srv.base + "/api/health", timeout=10, context=ssl.create_default_context())
        from cryptography import x509

        from omninav.server.tls import issued_by, san_hosts

        ca_pem = (venue_data / "tls" / "ca.pem").read_bytes()
        st, body = srv.call("GET", "/ca.pem")  # what the phone downloads to trust
        assert st == 200 and body == ca_pem
        leaf = x509.load_pem_x509_certificate((venue_data / "tls" / "cert.pem").read_bytes())  # the chain's first
        assert issued_by(leaf, x509.load_pem_x509_certificate(ca_pem))
        assert {"localhost", "127.0.0.1"} <= san_hosts(leaf)
    finally:
        srv.kill()


def test_the_web_app_or_its_placeholder_is_served_at_the_root(venue_data):
    srv = Server(venue_data)
    try:
        req = urllib.request.urlopen(srv.base + "/", timeout=10)
        assert req.status == 200 and b"<html" in req.read()
        st, body = srv.call("GET", "/api/venues")
        assert st == 200 and body["venues"][0]["id"] == "lab"
    finally:
        srv.kill()


def test_first_start_prints_a_token_and_models_the_demo_venue_in_the_background(tmp_path, quick_demo_render):
    data = tmp_path / "data"
    seed_quick_demo(data, quick_demo_render)  # rendered once a run (conftest); set up and modelled here
    srv = Server(data, "--demo", "quick", token=False)
    try:
        log = (tmp_path / f"server-{srv.port}.log").read_text()
        token = log.split("admin token", 1)[1].split(": ", 1)[1].split()[0]
        st, jobs = srv.call("GET", "/api/admin/venues/demo/jobs", headers={"Authorization": f"Bearer {token}"})
        assert st == 200 and jobs["jobs"][0]["videos"] == ["model.mp4"]
        assert srv.call("GET", "/api/admin/venues/demo/jobs", admin=True)[0] == 403  # not the test token
        t0 = time.time()
        while not srv.call("GET", "/api/venues/demo")[1]["modelled"]:
            assert time.time() - t0 < 300, "the demo venue was not modelled"
            time.sleep(0.5)
        _, v = srv.call("GET", "/api/venues/demo")
        assert v["floors"][0]["plan_url"] and any(p.get("area") for p in v["places"])
        assert srv.call("GET", v["floors"][0]["plan_url"])[0] == 200
    finally:
        srv.kill()
    # a second start neither makes a token nor sets the demo up again
    srv = Server(data, "--demo", "quick", token=False)
    try:
        log = (tmp_path / f"server-{srv.port}.log").read_text()
        assert "admin token" not in log and "rendering" not in log
        p = subprocess.run(
            [OMNINAV, "admin-token", "--reset"],
            env={**os.environ, "OMNINAV_DATA": str(data)},
            capture_output=True,
            text=True,
            timeout=60,
        )
        new = p.stdout.strip()
        assert p.returncode == 0 and len(new) > 20 and new != token
        auth = {"Authorization": f"Bearer {new}"}
        assert srv.call("GET", "/api/admin/venues/demo/videos", headers=auth)[0] == 200
        assert srv.call("GET", "/api/admin/venues/demo/videos", headers={"Authorization": f"Bearer {token}"})[0] == 403
    finally:
        srv.kill()
