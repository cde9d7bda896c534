"""Modelling jobs under concurrency and faults: one active job per venue however many ask at once
(on SQLite and on a real PostgreSQL); a job whose runner died queued again with a growing wait and
failed after MAX_ATTEMPTS; bad input failed at once; a full disk met while writing the new
generation: the venue answers as before, nothing half-written stays, and the job is retried; a
runner whose job another host took over writes nothing more (no progress, no generation).

The apps here run no job thread: each test runs the job runner's steps itself (claim, run_next,
reap), so that it decides when time passes. The database is SQLite, or PostgreSQL with
OMNINAV_TEST_DB=postgres (make_app)."""

from __future__ import annotations

import errno
import json
import os
import subprocess
import sys
import threading
import time

import numpy as np
import pytest

from omninav.server import jobs as jobs_mod
from omninav.spectrum import encode_binary
from server_helpers import ADMIN, Api, clip_spectra, query_clip
from test_server import add_video, make_app, upload

OCTET = "application/octet-stream"


def prepared(small_ds, data, **over):
    """An app without a job thread, venue 'lab' with a plan, a lens and video walk.mp4 uploaded."""
    app = make_app(data, JOB_RUNNER=False, **over)
    api = Api(app.test_client())
    assert api.post("/api/admin/venues", json={"id": "lab", "name": "Lab"}, headers=ADMIN).status_code == 201
    api.put(
        "/api/admin/venues/lab/floors/1/plan",
        data=small_ds.floorplan.read_bytes(),
        headers=ADMIN,
        content_type="image/png",
    )
    api.put("/api/admin/venues/lab/floors/1", json={"px_per_m": 20}, headers=ADMIN)
    lens = json.loads((small_ds.root / "model_lens.json").read_text())
    assert api.put("/api/admin/venues/lab/lenses/donut", json=lens, headers=ADMIN).status_code == 200
    data = add_video(api, "lab", "walk.mp4", small_ds)
    assert upload(api, "lab", "walk.mp4", data).json["status"] == "ready"
    return app, api


def job(api, job_id):
    return api.get(f"/api/admin/jobs/{job_id}", headers=ADMIN).json


@pytest.mark.parametrize("database", ["sqlite", "postgres"])
def test_six_simultaneous_submissions_create_exactly_one_job(small_ds, tmp_path, database, request):
    url = request.getfixturevalue("pg").url(f"six_{os.getpid()}") if database == "postgres" else None
    app, _ = prepared(small_ds, tmp_path, **({"DATABASE_URL": url} if url else {}))
    start = threading.Barrier(6)
    answers: list[tuple[int, dict]] = []

    def submit() -> None:
        api = Api(app.test_client())  # one client per thread, as six admins' browsers would be
        start.wait()
        r = api.post("/api/admin/venues/lab/jobs", json={"videos": ["walk.mp4"]}, headers=ADMIN)
        answers.append((r.status_code, r.json))

    threads = [threading.Thread(target=submit) for _ in range(6)]
    for t in threads:
        t.start()
    for t in threads:
        t.join(60)
    assert sorted(s for s, _ in answers) == [201, 409, 409, 409, 409, 409], answers
    created = next(b for s, b in answers if s == 201)
    for s, b in answers:
        if s == 409:
            assert b["error"] == f"venue 'lab' is already being modelled by job {created['id']}"
    rows = app.extensions["omninav"].db.all("SELECT id, state FROM jobs")
    assert rows == [{"id": created["id"], "state": "queued"}]


@pytest.fixture(scope="module")
def lab(small_ds, tmp_path_factory):
    """Venue 'lab' modelled once from walk.mp4, and a query clip's feature record."""
    app, api = prepared(small_ds, tmp_path_factory.mktemp("jobs"))
    runner = app.extensions["omninav"].jobs
    first = api.post("/api/admin/venues/lab/jobs", headers=ADMIN).json
    assert runner.run_next() and job(api, first["id"])["state"] == "done"
    frames, _ = query_clip(small_ds, 100)
    conf = app.extensions["omninav"].catalog.venues.settings("lab")
    record = encode_binary(clip_spectra(small_ds, frames, conf), conf)
    assert api.post("/api/venues/lab/locate", data=record, content_type=OCTET).json["confidence"] > 0.5
    return app, api, record


def test_a_full_disk_while_committing_keeps_the_venue_and_the_job_is_retried(lab, small_ds, monkeypatch):
    app, api, record = lab
    runner, store = app.extensions["omninav"].jobs, app.extensions["omninav"].catalog.store
    answer = api.post("/api/venues/lab/locate", data=record, content_type=OCTET).json
    gen, frames = store.generation("lab"), api.get("/api/venues/lab").json["frames"]
    assert upload(api, "lab", "again.mp4", add_video(api, "lab", "again.mp4", small_ds)).status_code == 200
    j = api.post("/api/admin/venues/lab/jobs", json={"videos": ["again.mp4"]}, headers=ADMIN).json

    real_save, saves = np.save, []

    def disk_fills_up(file, arr, *a, **kw):  # the first array is written, then the disk is full
        saves.append(file)
        if len(saves) == 2:
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), str(file))
        return real_save(file, arr, *a, **kw)

    monkeypatch.setattr(np, "save", disk_fills_up)
    t0 = time.time()
    assert runner.run_next()
    monkeypatch.undo()
    d = job(api, j["id"])
    assert len(saves) == 2 and d["state"] == "queued" and d["error"].startswith("disk full"), d
    assert d["attempts"] == 1 and d["max_attempts"] == 3
    assert t0 + jobs_mod.BACKOFF_S <= d["retry_at"] <= time.time() + jobs_mod.BACKOFF_S
    # the venue is as it was: same generation, same answer, nothing half-written left behind
    venue_dir = store.venue_dir("lab")
    assert store.generation("lab") == gen and not list(venue_dir.glob(".tmp-gen-*"))
    assert sorted(p.name for p in venue_dir.glob("gen-*"))[-1] == gen
    assert api.post("/api/venues/lab/locate", data=record, content_type=OCTET).json == answer
    assert runner.claim() is None  # not before its backoff

    time.sleep(max(0.0, d["retry_at"] - time.time()) + 0.05)
    assert runner.run_next()
    d = job(api, j["id"])
    assert d["state"] == "done" and d["attempts"] == 2 and d["error"].startswith("disk full")
    assert store.generation("lab") != gen and api.get("/api/venues/lab").json["frames"] == 2 * frames
    again = api.post("/api/venues/lab/locate", data=record, content_type=OCTET).json
    assert np.hypot(again["x"] - answer["x"], again["y"] - answer["y"]) < 1.0


def test_a_job_on_bad_input_fails_at_once(lab, small_ds):
    app, api, record = lab
    runner = app.extensions["omninav"].jobs
    answer = api.post("/api/venues/lab/locate", data=record, content_type=OCTET).json
    walk_path = json.loads(small_ds.model_walk_path.read_text())
    late = {**walk_path, "waypoints": [{**w, "t": w["t"] + 10000.0} for w in walk_path["waypoints"]]}
    assert (
        upload(api, "lab", "late.mp4", add_video(api, "lab", "late.mp4", small_ds, walk_path=late)).status_code == 200
    )
    j = api.post("/api/admin/venues/lab/jobs", json={"videos": ["late.mp4"]}, headers=ADMIN).json
    assert runner.run_next()
    d = job(api, j["id"])
    assert d["state"] == "failed" and d["attempts"] == 1 and d["retry_at"] is None
    assert "walk path starts after the video ends" in d["error"] and "attempt" not in d["error"]
    assert runner.claim() is None
    assert api.post("/api/venues/lab/locate", data=record, content_type=OCTET).json == answer
    assert api.delete("/api/admin/venues/lab/videos/late.mp4", headers=ADMIN).status_code == 200


CLAIM_AND_DIE = """
import sys
from omninav.catalog import Catalog
from omninav.catalog.db import Db
from omninav.server.jobs import Jobs
print(Jobs(Catalog(Db(sys.argv[1]), sys.argv[2])).claim()["id"])
"""


def test_a_job_whose_runner_died_is_retried_with_backoff_then_failed(lab):
    """Each attempt is claimed by a real process that then exits without a word, as a killed
    server does; the job is queued again 2 s, then 4 s later, and fails after the third."""
    app, api, _ = lab
    runner, db = app.extensions["omninav"].jobs, app.extensions["omninav"].db
    j = api.post("/api/admin/venues/lab/jobs", json={"videos": ["walk.mp4"]}, headers=ADMIN).json
    for attempt in (1, 2, 3):
        p = subprocess.run(
            [sys.executable, "-c", CLAIM_AND_DIE, db.url, app.config["DATA"]],
            capture_output=True,
            text=True,
            timeout=60,
        )
        assert p.stdout.strip() == j["id"], p.stderr
        t0 = time.time()
        d = job(api, j["id"])  # every API read reaps first
        assert d["attempts"] == attempt and "server stopped" in d["error"]
        if attempt < 3:
            wait = jobs_mod.BACKOFF_S * 2 ** (attempt - 1)
            assert d["state"] == "queued" and t0 - 1 + wait <= d["retry_at"] <= time.time() + wait
            assert runner.claim() is None
            db.run("UPDATE jobs SET not_before = :t WHERE id = :id", t=time.time() - 1, id=j["id"])  # time passes
    assert d["state"] == "failed" and d["error"].endswith("(attempt 3 of 3). Start the job again.")
    assert d["retry_at"] is None and runner.claim() is None


def test_a_job_on_another_host_is_taken_back_only_when_its_heartbeat_stops(lab):
    app, api, _ = lab
    runner, db = app.extensions["omninav"].jobs, app.extensions["omninav"].db
    j = api.post("/api/admin/venues/lab/jobs", json={"videos": ["walk.mp4"]}, headers=ADMIN).json
    claimed = runner.claim()
    assert claimed["id"] == j["id"]
    elsewhere = "another-host:4242:1"
    db.run("UPDATE jobs SET owner = :o, heartbeat = :t WHERE id = :id", o=elsewhere, t=time.time(), id=j["id"])
    assert runner.reap() == 0 and job(api, j["id"])["state"] == "running"
    stale = time.time() - runner.stale_s - 1
    db.run("UPDATE jobs SET heartbeat = :t WHERE id = :id", t=stale, id=j["id"])
    assert runner.reap() == 1
    d = job(api, j["id"])
    assert d["state"] == "queued" and d["attempts"] == 1 and "server stopped" in d["error"]
    # cancelled while running, then its runner dies: it ends cancelled, not queued again
    db.run("UPDATE jobs SET not_before = NULL WHERE id = :id", id=j["id"])
    assert runner.claim()["attempts"] == 2
    assert api.post(f"/api/admin/jobs/{j['id']}/cancel", headers=ADMIN).json["state"] == "running"
    db.run("UPDATE jobs SET owner = :o, heartbeat = :t WHERE id = :id", o=elsewhere, t=stale, id=j["id"])
    assert runner.reap() == 1 and job(api, j["id"])["state"] == "cancelled"


@pytest.mark.parametrize("when", ["extracting", "before_commit"])
def test_a_runner_whose_job_was_taken_over_commits_nothing_and_writes_nothing(lab, when):
    """A runner whose heartbeat went stale (a paused machine, a network cut) is taken over by
    another host's runner while it still runs; when it goes on it must stop: no progress or
    heartbeat over the new owner's, no generation, no video rows. The test holds the venue's lock,
    so the runner cannot commit before the takeover: it is taken over either while it extracts
    (after its first progress write) or once it has extracted everything and waits for the lock."""
    app, api, record = lab
    svc = app.extensions["omninav"]
    runner, db, store = svc.jobs, svc.db, svc.catalog.store
    answer = api.post("/api/venues/lab/locate", data=record, content_type=OCTET).json
    gen, videos = store.generation("lab"), db.all("SELECT * FROM videos WHERE venue = 'lab' ORDER BY name")
    j = api.post("/api/admin/venues/lab/jobs", json={"videos": ["walk.mp4"]}, headers=ADMIN).json
    done = threading.Event()
    try:
        with store.lock("lab"):  # a commit (or a backup) holds the venue: this runner must wait
            t = threading.Thread(target=lambda: (runner.run_next(), done.set()))
            t.start()
            seen = wait_progress(db, j["id"], full=when == "before_commit")
            beat = time.time()
            # what reap + claim on the other host leave: the job running there, attempt 2, no progress yet
            assert db.run(
                "UPDATE jobs SET owner = 'another-host:4242:1', heartbeat = :t, attempts = attempts + 1, "
                "frames_done = 0, fps = 0 WHERE id = :id AND state = 'running'",
                t=beat,
                id=j["id"],
            )
        t.join(60)
        assert done.is_set()
        row = db.one("SELECT * FROM jobs WHERE id = :id", id=j["id"])
        assert (seen["frames_done"] < seen["frames_total"]) == (when == "extracting"), seen
        assert row["owner"] == "another-host:4242:1" and row["state"] == "running" and row["attempts"] == 2
        assert row["frames_done"] == 0 and row["fps"] == 0 and row["heartbeat"] == beat, row
        assert store.generation("lab") == gen and not list(store.venue_dir("lab").glob(".tmp-gen-*"))
        assert db.all("SELECT * FROM videos WHERE venue = 'lab' ORDER BY name") == videos
        assert api.post("/api/venues/lab/locate", data=record, content_type=OCTET).json == answer
    finally:  # the other host's runner "finishes": the next test may model the venue again
        db.run("UPDATE jobs SET state = 'cancelled', finished = :t WHERE id = :id", t=time.time(), id=j["id"])


def wait_progress(db, job_id, full, timeout=60.0):
    """The job's row once its runner has written progress (all its frames, with full)."""
    t_end = time.monotonic() + timeout
    while time.monotonic() < t_end:
        r = db.one("SELECT frames_done, frames_total FROM jobs WHERE id = :id", id=job_id)
        if r["frames_done"] > 0 and (not full or r["frames_done"] == r["frames_total"]):
            return r
        time.sleep(0.005)
    raise AssertionError(f"job {job_id} wrote no progress in {timeout} s")
