"""Analysis jobs through the admin API (server/analysis_api.py, server/jobs.py): suggested waypoints
of a walk video, the quality map of a modelled venue, the evaluation of a walk; each a background
job with progress, cancel and the event stream of a modelling job, its result a JSON file served by
the API; and the refusals that say what is missing (4xx).

As in tests/server/test_jobs.py, the app runs no job thread: each test runs the job runner's steps itself
(run_next), on a real SQLite database, with the small synthetic venue (a 23 s walk at 10 fps)."""

from __future__ import annotations

import errno
import json
import os
import threading
import time
from pathlib import Path

import pytest

from omninav.server import jobs as jobs_mod
from server_helpers import ADMIN, Api
from test_jobs import wait_progress
from test_server import make_app, upload

V = "/api/admin/venues/lab"
PNG = b"\x89PNG\r\n\x1a\n"
PLACES = [
    {"name": "North corridor", "floor": "1", "x": 11.0, "y": 2.0, "area": [0.8, 0.8, 21.2, 3.2]},
    {"name": "East corridor", "floor": "1", "x": 20.0, "y": 7.0, "area": [18.8, 0.8, 21.2, 13.2]},
    {"name": "Store room", "floor": "1", "x": 6.0, "y": 10.0, "area": [2.0, 8.0, 10.0, 12.0]},  # never walked
]


def register(api, name, path: Path, walk_path=None, role="model", send=None):
    """POST a video of venue 'lab' (walk_path None: tagged later) and PUT its bytes (the first `send`)."""
    data = path.read_bytes()
    body = {"name": name, "floor": "1", "size": len(data), "lens": "donut", "role": role}
    if walk_path is not None:
        body["walk_path"] = json.loads(walk_path.read_text())
    r = api.post(f"{V}/videos", json=body, headers=ADMIN)
    assert r.status_code == 201, r.json
    if send is None:
        r = upload(api, "lab", name, data)
        assert r.json["status"] == "ready", r.json
    else:
        r = api.put(
            f"{V}/videos/{name}/content",
            data=data[:send],
            headers={**ADMIN, "Content-Range": f"bytes 0-{send - 1}/{len(data)}"},
            content_type="application/octet-stream",
        )
        assert r.status_code == 202 and r.json["status"] == "uploading", r.json
    return r.json


def job(api, job_id):
    return api.get(f"/api/admin/jobs/{job_id}", headers=ADMIN).json


@pytest.fixture(scope="module")
def lab(small_ds, tmp_path_factory):
    """Venue 'lab' (plan, scale, lens, places) modelled from walk.mp4, with an evaluation walk
    eval.mp4 (the query walk and its walk path), a walk without one and a half-uploaded one; and an
    empty venue 'empty'. No job thread."""
    app = make_app(tmp_path_factory.mktemp("analysis"), JOB_RUNNER=False)
    api = Api(app.test_client())
    for vid in ("lab", "empty"):
        assert api.post("/api/admin/venues", json={"id": vid}, headers=ADMIN).status_code == 201
    plan = small_ds.floorplan.read_bytes()
    assert api.put(f"{V}/floors/1/plan", data=plan, headers=ADMIN, content_type="image/png").status_code == 200
    assert api.put(f"{V}/floors/1", json={"px_per_m": 20}, headers=ADMIN).status_code == 200
    lens = json.loads((small_ds.root / "model_lens.json").read_text())
    assert api.put(f"{V}/lenses/donut", json=lens, headers=ADMIN).status_code == 200
    assert api.put(f"{V}/places", json=PLACES, headers=ADMIN).status_code == 200
    register(api, "walk.mp4", small_ds.model_video, small_ds.model_walk_path)
    register(api, "eval.mp4", small_ds.query_video, small_ds.query_walk_path, role="evaluation")
    register(api, "untagged.mp4", small_ds.query_video, role="evaluation")
    register(api, "half.mp4", small_ds.model_video, small_ds.model_walk_path, send=1000)
    runner = app.extensions["omninav"].jobs
    model = api.post(f"{V}/jobs", headers=ADMIN)  # every tracked modelling walk: walk.mp4 alone
    assert model.status_code == 201 and model.json["videos"] == ["walk.mp4"] and model.json["kind"] == "model"
    assert runner.run_next() and job(api, model.json["id"])["state"] == "done"
    assert job(api, model.json["id"])["result_url"] is None
    app.config["MODEL_JOB"] = model.json["id"]
    return app, api


@pytest.fixture(autouse=True)
def no_active_jobs(lab):
    """Each test starts and ends with no queued or running job (run_next takes the oldest)."""
    yield
    lab[0].extensions["omninav"].db.run(
        "UPDATE jobs SET state = 'cancelled', finished = :t WHERE state IN ('queued', 'running')", t=time.time()
    )


def result_file(app, job_id) -> Path:
    return Path(app.config["DATA"]) / "results" / "lab" / f"{job_id}.json"


def test_suggest_job_finds_the_corner_and_keeps_the_result_on_the_video(lab):
    app, api = lab
    runner = app.extensions["omninav"].jobs
    r = api.post(f"{V}/videos/walk.mp4/suggest", headers=ADMIN)
    assert r.status_code == 201, r.json
    j = r.json
    assert r.headers["Location"] == f"/api/admin/jobs/{j['id']}"
    assert (j["kind"], j["target"], j["videos"], j["state"], j["result_url"]) == (
        "suggest",
        "walk.mp4",
        ["walk.mp4"],
        "queued",
        None,
    )
    # one active suggest job per video, but others may run beside it (another video, the quality map)
    again = api.post(f"{V}/videos/walk.mp4/suggest", headers=ADMIN)
    assert again.status_code == 409 and again.json["job"] == j["id"], again.json
    assert "suggesting waypoints for video 'walk.mp4'" in again.json["error"]
    other = api.post(f"{V}/videos/eval.mp4/suggest", headers=ADMIN)
    assert other.status_code == 201, other.json
    assert runner.run_next() and runner.run_next()

    d = job(api, j["id"])
    assert d["state"] == "done" and d["attempts"] == 1 and d["error"] is None, d
    assert d["frames_total"] > 0 and d["frames_done"] == d["frames_total"] and d["frames_per_s"] > 0
    assert d["result_url"] == f"/api/admin/jobs/{j['id']}/result"
    got = api.get(d["result_url"], headers=ADMIN)
    assert got.status_code == 200 and got.mimetype == "application/json"
    result = got.json
    assert json.loads(result_file(app, j["id"]).read_text()) == result
    assert d["videos"] == ["walk.mp4"] and abs(result["duration_s"] - 23.4) < 0.2
    # the walk's one corner is at 15 s (the walk path's second waypoint)
    turns = [s for s in result["suggestions"] if s["kind"] == "turn"]
    assert any(abs(s["t"] - 15.0) <= 1.0 for s in turns), result["suggestions"]
    assert api.get(f"{V}/videos/walk.mp4", headers=ADMIN).json["suggestions"] == result
    assert job(api, other.json["id"])["state"] == "done"
    events = api.get(f"/api/admin/jobs/{j['id']}/events", headers=ADMIN).get_data(as_text=True)
    assert events.startswith("event: done\n") and json.loads(events.split("data: ", 1)[1])["kind"] == "suggest"


def test_quality_job_maps_the_modelled_venue(lab):
    app, api = lab
    runner = app.extensions["omninav"].jobs
    r = api.post(f"{V}/quality", headers=ADMIN)
    assert r.status_code == 201 and r.json["kind"] == "quality" and r.json["target"] is None, r.json
    assert api.post(f"{V}/quality", headers=ADMIN).status_code == 409  # one at a time
    assert runner.run_next()
    d = job(api, r.json["id"])
    assert d["state"] == "done" and d["frames_done"] == d["frames_total"] > 0, d
    q = api.get(f"{V}/quality", headers=ADMIN)
    assert q.status_code == 200 and q.json == api.get(d["result_url"], headers=ADMIN).json
    q = q.json
    assert q["frames"] > 0 and q["segments"] and q["sentence"]
    assert q["generation"] == api.get(V, headers=ADMIN).json["generation"] is not None  # the live one
    assert {c["place"]: c["verdict"] for c in q["corridors"]}["Store room"] == "grey"
    assert q["summary"]["share_green"] >= 0.5, q["summary"]
    png = api.get(f"{V}/quality.png?floor=1", headers=ADMIN)
    assert png.status_code == 200 and png.mimetype == "image/png" and png.data.startswith(PNG)
    assert api.get(f"{V}/quality.png", headers=ADMIN).data == png.data  # the first floor by default
    assert api.get(f"{V}/quality.png?floor=9", headers=ADMIN).status_code == 404


def test_evaluate_job_locates_the_evaluation_walk(lab):
    app, api = lab
    runner = app.extensions["omninav"].jobs
    none = api.get(f"{V}/videos/eval.mp4/evaluation", headers=ADMIN)
    assert none.status_code == 404 and "no evaluation yet" in none.json["error"]
    r = api.post(f"{V}/videos/eval.mp4/evaluate", headers=ADMIN)
    assert r.status_code == 201 and (r.json["kind"], r.json["target"]) == ("evaluate", "eval.mp4"), r.json
    assert runner.run_next()
    d = job(api, r.json["id"])
    assert d["state"] == "done" and d["frames_done"] == d["frames_total"] > 0, d
    ev = api.get(f"{V}/videos/eval.mp4/evaluation", headers=ADMIN)
    assert ev.status_code == 200 and ev.json == api.get(d["result_url"], headers=ADMIN).json
    s = ev.json["summary"]
    assert s["clips"] == len(ev.json["clips"]) >= 15 and s["within_2m"] >= 0.7, s
    # a video registered again under this name (another walk) is not shown the old walk's result
    db = app.extensions["omninav"].db
    was = db.one("SELECT created FROM videos WHERE venue = 'lab' AND name = 'eval.mp4'")["created"]
    db.run("UPDATE videos SET created = :t WHERE venue = 'lab' AND name = 'eval.mp4'", t=time.time() + 60)
    try:
        assert api.get(f"{V}/videos/eval.mp4/evaluation", headers=ADMIN).status_code == 404
    finally:
        db.run("UPDATE videos SET created = :t WHERE venue = 'lab' AND name = 'eval.mp4'", t=was)
    assert api.get(f"{V}/videos/eval.mp4/evaluation", headers=ADMIN).status_code == 200


def test_a_running_analysis_job_is_cancelled_and_publishes_nothing(lab):
    app, api = lab
    svc = app.extensions["omninav"]
    before = api.get(f"{V}/videos/untagged.mp4", headers=ADMIN).json["suggestions"]
    j = api.post(f"{V}/videos/untagged.mp4/suggest", headers=ADMIN).json
    t = threading.Thread(target=svc.jobs.run_next)
    t.start()
    try:
        wait_progress(svc.db, j["id"], full=False)
        c = api.post(f"/api/admin/jobs/{j['id']}/cancel", headers=ADMIN)
        assert c.status_code == 202 and c.json["state"] == "running"  # its runner stops at its next frame
    finally:
        t.join(60)
    d = job(api, j["id"])
    assert d["state"] == "cancelled" and d["result_url"] is None and d["error"] is None, d
    assert not result_file(app, j["id"]).exists() and not list(result_file(app, j["id"]).parent.glob(".*"))
    assert api.get(f"/api/admin/jobs/{j['id']}/result", headers=ADMIN).status_code == 409
    assert api.get(f"{V}/videos/untagged.mp4", headers=ADMIN).json["suggestions"] == before


def test_an_analysis_job_taken_over_by_another_runner_publishes_nothing(lab):
    app, api = lab
    svc = app.extensions["omninav"]
    j = api.post(f"{V}/videos/untagged.mp4/suggest", headers=ADMIN).json
    before = api.get(f"{V}/videos/untagged.mp4", headers=ADMIN).json["suggestions"]
    t = threading.Thread(target=svc.jobs.run_next)
    t.start()
    try:
        wait_progress(svc.db, j["id"], full=False)
        # what reap + claim on another host leave: the job running there, attempt 2
        assert svc.db.run(
            "UPDATE jobs SET owner = 'another-host:4242:1', heartbeat = :t, attempts = attempts + 1 WHERE id = :id",
            t=time.time(),
            id=j["id"],
        )
    finally:
        t.join(60)
    row = svc.db.one("SELECT * FROM jobs WHERE id = :id", id=j["id"])
    assert row["owner"] == "another-host:4242:1" and row["state"] == "running" and row["result"] is None
    assert not result_file(app, j["id"]).exists() and not list(result_file(app, j["id"]).parent.glob(".*"))
    assert api.get(f"{V}/videos/untagged.mp4", headers=ADMIN).json["suggestions"] == before


def test_a_cancel_after_the_engine_finished_still_wins(lab, monkeypatch):
    # the admin presses Cancel just as the engine returns, after the runner's last look at the
    # flag: the cancel was answered 202, so the job ends cancelled and publishes nothing
    app, api = lab
    svc = app.extensions["omninav"]
    before = api.get(f"{V}/videos/untagged.mp4", headers=ADMIN).json["suggestions"]
    j = api.post(f"{V}/videos/untagged.mp4/suggest", headers=ADMIN).json
    real = jobs_mod._write_beside

    def cancel_then_write(path, text):
        assert api.post(f"/api/admin/jobs/{j['id']}/cancel", headers=ADMIN).status_code == 202
        return real(path, text)

    monkeypatch.setattr(jobs_mod, "_write_beside", cancel_then_write)
    assert svc.jobs.run_next()
    d = job(api, j["id"])
    assert d["state"] == "cancelled" and d["result_url"] is None, d
    assert not result_file(app, j["id"]).exists() and not list(result_file(app, j["id"]).parent.glob(".*"))
    assert api.get(f"{V}/videos/untagged.mp4", headers=ADMIN).json["suggestions"] == before


def test_a_full_disk_while_writing_the_result_is_retried(lab, monkeypatch):
    app, api = lab
    svc = app.extensions["omninav"]
    real, calls = jobs_mod._write_beside, []

    def disk_full(path, text):
        calls.append(path)
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), str(path))

    monkeypatch.setattr(jobs_mod, "_write_beside", disk_full)
    j = api.post(f"{V}/videos/walk.mp4/suggest", headers=ADMIN).json
    assert svc.jobs.run_next()
    d = job(api, j["id"])
    assert calls and d["state"] == "queued" and d["attempts"] == 1, d
    assert d["error"].startswith("disk full") and "the job's result" in d["error"] and d["retry_at"]
    monkeypatch.setattr(jobs_mod, "_write_beside", real)
    svc.db.run("UPDATE jobs SET not_before = :t WHERE id = :id", t=time.time() - 1, id=j["id"])  # time passes
    assert svc.jobs.run_next()
    d = job(api, j["id"])
    assert d["state"] == "done" and d["attempts"] == 2 and d["result_url"], d


def test_an_analysis_job_on_bad_input_fails_at_once(lab, small_ds):
    app, api = lab
    svc = app.extensions["omninav"]
    register(api, "gone.mp4", small_ds.query_video, small_ds.query_walk_path, role="evaluation")
    j = api.post(f"{V}/videos/gone.mp4/evaluate", headers=ADMIN).json
    (Path(app.config["DATA"]) / "videos" / "lab" / "gone.mp4").unlink()  # lost from the disk meanwhile
    assert svc.jobs.run_next()
    d = job(api, j["id"])
    assert d["state"] == "failed" and d["attempts"] == 1 and d["retry_at"] is None, d
    assert d["error"] == "video 'gone.mp4' has no uploaded file" and d["result_url"] is None


@pytest.mark.parametrize(
    ("method", "path", "status", "says"),
    [
        ("post", f"{V}/videos/nope.mp4/suggest", 404, "has no video 'nope.mp4'"),
        ("post", f"{V}/videos/half.mp4/suggest", 409, "not completely uploaded (1000 of"),
        ("post", "/api/admin/venues/nope/videos/walk.mp4/suggest", 404, "nope"),
        ("post", f"{V}/videos/nope.mp4/evaluate", 404, "has no video 'nope.mp4'"),
        ("post", f"{V}/videos/half.mp4/evaluate", 409, "not completely uploaded"),
        ("post", f"{V}/videos/walk.mp4/evaluate", 409, "is a modelling walk"),
        ("post", f"{V}/videos/untagged.mp4/evaluate", 409, "has no walk path yet"),
        ("post", "/api/admin/venues/empty/quality", 409, "model the venue first"),
        ("get", "/api/admin/venues/empty/quality", 404, "no quality map yet"),
        ("get", "/api/admin/venues/empty/quality.png", 409, "needs a floor plan"),
        ("get", f"{V}/videos/nope.mp4/evaluation", 404, "has no video 'nope.mp4'"),
        ("get", f"{V}/videos/walk.mp4/evaluation", 404, "no evaluation yet"),
        ("get", "/api/admin/jobs/nope/result", 404, "unknown job"),
    ],
)
def test_what_an_analysis_needs_is_said_clearly(lab, method, path, status, says):
    _, api = lab
    r = getattr(api, method)(path, headers=ADMIN)
    assert r.status_code == status and says in r.json["error"], r.json


def test_results_need_the_token_and_a_modelling_job_has_none(lab):
    app, api = lab
    for path in (f"{V}/quality", f"{V}/videos/walk.mp4/evaluation", "/api/admin/jobs/x/result"):
        assert api.get(path).status_code == 401
    assert api.post(f"{V}/quality").status_code == 401
    r = api.get(f"/api/admin/jobs/{app.config['MODEL_JOB']}/result", headers=ADMIN)
    assert r.status_code == 404 and "modelling job" in r.json["error"]
    queued = api.post(f"{V}/videos/walk.mp4/suggest", headers=ADMIN).json
    r = api.get(f"/api/admin/jobs/{queued['id']}/result", headers=ADMIN)
    assert r.status_code == 409 and "queued" in r.json["error"]
