"""Two `omninav serve` instances on one PostgreSQL and one data directory, as a building runs two
machines behind a balancer: a job submitted through one runs exactly once (one claim among every
job runner of both), both serve the new generation, and when the instance running a job is killed
(kill -9, its whole process group) the other takes the job over and finishes it."""

from __future__ import annotations

import json
import os
import time

import pytest

from omninav.catalog.db import Db
from omninav.spectrum import encode_binary
from server_helpers import clip_spectra, query_clip
from test_server_live import Server, upload, wait_job

OCTET = {"Content-Type": "application/octet-stream"}


def owner_pid(row: dict) -> int:
    return int(row["owner"].rsplit(":", 2)[1])


@pytest.fixture(scope="module")
def pair(small_ds, pg_url, tmp_path_factory):
    """Servers a and b on one data directory and one PostgreSQL database, venue 'lab' with a plan,
    a lens and walk.mp4 uploaded through a (not modelled yet), and a query clip's record."""
    data = tmp_path_factory.mktemp("pg") / "data"
    data.mkdir()
    env = {"OMNINAV_DATABASE_URL": pg_url}
    a = Server(data, env=env)
    b = Server(data, env=env)
    db = Db(pg_url)
    try:
        assert a.call("POST", "/api/admin/venues", {"id": "lab", "name": "Lab"}, admin=True)[0] == 201
        plan = small_ds.floorplan.read_bytes()
        assert (
            b.call("PUT", "/api/admin/venues/lab/floors/1/plan", plan, {"Content-Type": "image/png"}, admin=True)[0]
            == 200
        )
        assert a.call("PUT", "/api/admin/venues/lab/floors/1", {"px_per_m": 20}, admin=True)[0] == 200
        lens = json.loads((small_ds.root / "model_lens.json").read_text())
        assert b.call("PUT", "/api/admin/venues/lab/lenses/donut", lens, admin=True)[0] == 200
        walk_path = json.loads(small_ds.model_walk_path.read_text())
        upload(a, "lab", "walk.mp4", small_ds.model_video.read_bytes(), walk_path, piece=512 * 1024)
        frames, truth = query_clip(small_ds, 100)
        _, venue = b.call("GET", "/api/venues/lab")
        settings = venue["features"]["settings"]
        record = encode_binary(clip_spectra(small_ds, frames, settings), settings)
        yield a, b, db, record, truth
    finally:
        for srv in (a, b):
            if srv.proc.poll() is None:
                srv.kill()
        db.engine.dispose()


def locate_on_both(a: Server, b: Server, record: bytes) -> tuple[dict, dict]:
    time.sleep(1.2)  # VENUE_CACHE_S: how long a worker trusts its cached venue
    sa, ans_a = a.call("POST", "/api/venues/lab/locate", record, OCTET)
    sb, ans_b = b.call("POST", "/api/venues/lab/locate", record, OCTET)
    assert sa == sb == 200
    return ans_a, ans_b


def test_a_job_runs_exactly_once_and_both_servers_serve_its_generation(pair):
    a, b, db, record, truth = pair
    st, job = a.call("POST", "/api/admin/venues/lab/jobs", admin=True)
    assert st == 201
    # b sees the job at once (one database) and refuses a second one for the venue
    st, busy = b.call("POST", "/api/admin/venues/lab/jobs", {"videos": ["walk.mp4"]}, admin=True)
    assert st == 409 and job["id"] in busy["error"]
    done = wait_job(b, job["id"])
    assert done["state"] == "done" and done["attempts"] == 1 and done["error"] is None, done
    row = db.one("SELECT owner, attempts FROM jobs WHERE id = :id", id=job["id"])
    assert row is not None and row["attempts"] == 1 and row["owner"]  # one claim among four runners
    assert (a.data / "venues" / "lab" / "CURRENT").read_text().strip() == "gen-000001"  # one commit
    ans_a, ans_b = locate_on_both(a, b, record)
    assert ans_a == ans_b and abs(ans_a["x"] - truth[0]) < 2 and abs(ans_a["y"] - truth[1]) < 2
    assert a.call("GET", "/api/venues/lab")[1]["frames"] == b.call("GET", "/api/venues/lab")[1]["frames"] > 0


def test_killing_the_server_running_a_job_lets_the_other_take_it_over(pair, small_ds):
    a, b, db, record, truth = pair
    before = a.call("GET", "/api/venues/lab")[1]["frames"]
    walk_path = json.loads(small_ds.model_walk_path.read_text())
    names = [f"copy{i}.mp4" for i in range(3)]
    for n in names:
        upload(b, "lab", n, small_ds.model_video.read_bytes(), walk_path, piece=8 * 1024 * 1024)
    st, job = b.call("POST", "/api/admin/venues/lab/jobs", {"videos": names}, admin=True)
    assert st == 201
    wait_job(a, job["id"], until=lambda j: j["state"] == "running" and j["frames_done"] > 20)
    row = db.one("SELECT owner FROM jobs WHERE id = :id", id=job["id"])
    assert row is not None
    running_on = {os.getpgid(owner_pid(row))}  # the killed server's whole process group goes
    victim, survivor = (a, b) if running_on == {a.proc.pid} else (b, a)
    assert running_on == {victim.proc.pid}
    victim.kill()

    done = wait_job(survivor, job["id"])
    assert done["state"] == "done" and done["attempts"] == 2 and "server stopped" in done["error"], done
    row = db.one("SELECT owner FROM jobs WHERE id = :id", id=job["id"])
    assert row is not None and os.getpgid(owner_pid(row)) == survivor.proc.pid
    _, v = survivor.call("GET", "/api/venues/lab")
    assert v["frames"] == before * 4
    time.sleep(1.2)
    st, ans = survivor.call("POST", "/api/venues/lab/locate", record, OCTET)
    assert st == 200 and abs(ans["x"] - truth[0]) < 2 and abs(ans["y"] - truth[1]) < 2
    # the killed attempt committed nothing; the one that took over committed once
    assert (survivor.data / "venues" / "lab" / "CURRENT").read_text().strip() == "gen-000002"


def test_servers_starting_at_once_migrate_a_new_database_once(pg):
    """Two instances starting together on a new PostgreSQL must not both run a migration (the
    second failed on 'relation already exists')."""
    import threading

    from omninav.catalog.db import SCHEMA_VERSION

    url = pg.url("migrate_race")
    dbs = [Db(url) for _ in range(4)]
    ran: list[int] = []
    errors: list[BaseException] = []
    go = threading.Barrier(len(dbs))

    def start(db: Db) -> None:
        go.wait()
        try:
            ran.append(db.migrate())
        except BaseException as e:  # noqa: BLE001 - the assertion below reports it
            errors.append(e)

    threads = [threading.Thread(target=start, args=(db,)) for db in dbs]
    for t in threads:
        t.start()
    for t in threads:
        t.join(60)
    version = dbs[0].version()
    for db in dbs:
        db.engine.dispose()
    assert not errors, errors
    assert sum(ran) == SCHEMA_VERSION and version == SCHEMA_VERSION
