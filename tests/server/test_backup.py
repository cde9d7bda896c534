"""Backups: `omninav backup DIR` taken while the server models and answers, restored elsewhere
(a fresh data folder and database, SQLite or PostgreSQL), answers the same; a damaged backup and a
non-empty target are refused with one line.

The venue is built through the admin API on the small synthetic venue (rendered at test time),
as in test_server.py.
"""

from __future__ import annotations

import json
import shutil
import threading
import time
from pathlib import Path

import pytest

from conftest import run_cli
from omninav.catalog import Catalog
from omninav.catalog import db as db_mod
from omninav.catalog.db import SCHEMA_VERSION, Db
from omninav.errors import OmninavError
from omninav.server import create_app
from omninav.server.backup import backup, dump_rows, restore
from omninav.spectrum import encode_binary
from omninav.store import Store
from server_helpers import ADMIN, Api, clip_spectra, query_clip
from test_server import CLIP_START, add_video, make_app, upload, wait_job

PUBLIC = {"Authorization": "Bearer not-the-token"}


def locate(api, body):
    r = api.post("/api/venues/lab/locate?clip=q", data=body, content_type="application/octet-stream")
    assert r.status_code == 200, r.json
    return r.json


def catalogue(api):
    """What a restore must give back: the public venue, its plan's bytes, its videos, as the API shows them."""
    doc = api.get("/api/venues/lab").json
    r = api.get(doc["floors"][0]["plan_url"])
    plan = r.data
    r.close()  # a file response streams: close it
    vids = api.get("/api/admin/venues/lab/videos", headers=ADMIN).json["videos"]
    for k in ("revision", "frames", "modelled"):  # these follow the generation: compared on their own
        doc.pop(k)
    return doc, plan, {v["name"]: v for v in vids}


def frames_per_video(store, venue):
    g = store.load(venue)
    return {n: int((g.frames["video"] == i).sum()) for i, n in enumerate(g.videos)}


@pytest.fixture(scope="module")
def served(small_ds, tmp_path_factory):
    """Venue 'lab' modelled through the API; then a backup taken while a second job models a
    second video and locate requests are answered. Returns what each side saw."""
    app = make_app(tmp_path_factory.mktemp("live"))
    api = Api(app.test_client())
    assert api.post("/api/admin/venues", json={"id": "lab", "name": "Lab"}, headers=ADMIN).status_code == 201
    r = api.put("/api/admin/venues/lab/floors/1/plan", data=small_ds.floorplan.read_bytes(), headers=ADMIN,
                content_type="image/png")  # fmt: skip
    assert r.status_code == 200
    r = api.put("/api/admin/venues/lab/floors/1", json={"name": "Ground", "px_per_m": 20.0}, headers=ADMIN)
    assert r.status_code == 200
    places = [{**p, "floor": "1"} for p in small_ds.scene.places] + [{"name": "the lifts", "x": 20.0, "y": 2.0}]
    assert api.put("/api/admin/venues/lab/places", json=places, headers=ADMIN).status_code == 200
    lens = json.loads((small_ds.root / "model_lens.json").read_text())
    assert api.put("/api/admin/venues/lab/lenses/donut", json=lens, headers=ADMIN).status_code == 200
    data = add_video(api, "lab", "walk.mp4", small_ds)
    upload(api, "lab", "walk.mp4", data)
    assert wait_job(api, api.post("/api/admin/venues/lab/jobs", headers=ADMIN).json["id"])["state"] == "done"

    frames, _ = query_clip(small_ds, CLIP_START)
    conf = app.extensions["omninav"].catalog.venues.settings("lab")
    body = encode_binary(clip_spectra(small_ds, frames, conf), conf)
    before = {"answer": locate(api, body), "frames": frames_per_video(Store(app.config["DATA"]), "lab")}
    # a second video uploaded; a third half uploaded (its .part is not backed up)
    upload(api, "lab", "walk2.mp4", add_video(api, "lab", "walk2.mp4", small_ds))
    part = add_video(api, "lab", "part.mp4", small_ds)
    r = api.put("/api/admin/venues/lab/videos/part.mp4/content", data=part[:1000], content_type="video/mp4",
                headers={**ADMIN, "Content-Range": f"bytes 0-999/{len(part)}"})  # fmt: skip
    assert r.status_code == 202 and r.json["received"] == 1000
    job = api.post("/api/admin/venues/lab/jobs", headers=ADMIN).json
    assert job["videos"] == ["walk2.mp4"]

    stop, answers = threading.Event(), []

    def keep_locating():  # a client of its own, as another phone
        other = app.test_client()
        while not stop.is_set():
            r = other.post("/api/venues/lab/locate?clip=q", data=body, content_type="application/octet-stream")
            answers.append((r.status_code, r.json))

    t = threading.Thread(target=keep_locating)
    t.start()
    try:
        while (j := api.get(f"/api/admin/jobs/{job['id']}", headers=ADMIN).json)["frames_done"] == 0:
            assert j["state"] in ("queued", "running"), j
            time.sleep(0.02)
        n0 = len(answers)
        summary = backup(app.config, tmp_path_factory.mktemp("bk") / "b1")
        during = {"job": api.get(f"/api/admin/jobs/{job['id']}", headers=ADMIN).json, "locates": len(answers) - n0}
    finally:
        stop.set()
        t.join()
    assert wait_job(api, job["id"])["state"] == "done"
    after = {"answer": locate(api, body), "frames": frames_per_video(Store(app.config["DATA"]), "lab")}
    return {
        "app": app,
        "api": api,
        "body": body,
        "backup": Path(summary["backup"]),
        "summary": summary,
        "before": before,
        "after": after,
        "during": during,
        "answers": answers,
    }


def restored_app(data, **over):
    """A server on the restored data: the admin token is the restored one (none given here)."""
    return create_app({"DATA": str(data), "LOCATE_RATE": 0.0, "VENUE_CACHE_S": 0.0, "JOB_RUNNER": False, **over})


def check_restored(served, app):
    """The restored server answers and describes the venue as the original did at the backup."""
    man = json.loads((served["backup"] / "manifest.json").read_text())
    gen = man["venues"]["lab"]["generation"]
    # the backup holds the generation before the job's commit or the one after: either is
    # consistent, and the original answered with each (before and after the job)
    seen = served["before"] if gen == "gen-000001" else served["after"]
    assert gen in ("gen-000001", "gen-000002")
    api = Api(app.test_client())
    assert locate(api, served["body"]) == seen["answer"]
    st = app.extensions["omninav"].catalog.store
    assert st.generation("lab") == gen
    # the catalogue describes the generation it came with: each video's frames, and no job half done
    assert frames_per_video(st, "lab") == seen["frames"]
    doc, plan, vids = catalogue(api)
    assert {n: v["frames"] for n, v in vids.items() if v["frames"]} == seen["frames"]
    assert api.get("/api/venues/lab").json["frames"] == sum(seen["frames"].values())
    jobs = api.get("/api/admin/venues/lab/jobs", headers=ADMIN).json["jobs"]
    # the first job done; the second done (its commit is in) or failed (it ran at the backup)
    assert sorted(j["state"] for j in jobs) in (["done", "done"], ["done", "failed"])
    for j in jobs:
        assert j["state"] == "done" or "Start the job again" in j["error"]
    # places, floors, plan, lenses, videos: as the original has them
    odoc, oplan, ovids = catalogue(served["api"])
    assert doc == odoc and plan == oplan
    for n in ("walk.mp4", "walk2.mp4"):
        assert {k: v for k, v in vids[n].items() if k not in ("frames", "status")} == {
            k: v for k, v in ovids[n].items() if k not in ("frames", "status")
        }
    assert vids["part.mp4"]["status"] == "uploading" and vids["part.mp4"]["received"] == 0
    return api, st


def test_a_backup_taken_while_modelling_and_answering_restores_to_the_same_answers(served, tmp_path):
    during = served["during"]
    # the backup was taken while the job ran and a phone was answered: every answer was one of
    # the venue's two (before the job's commit, after it)
    assert during["job"]["state"] == "running" and during["locates"] > 0
    good = (served["before"]["answer"], served["after"]["answer"])
    assert all(code == 200 and a in good for code, a in served["answers"])
    s = served["summary"]
    assert s["venues"] == 1 and s["files"] > 10 and s["bytes"] > 0 and s["videos"] is True
    names = json.loads((served["backup"] / "manifest.json").read_text())["files"]
    assert "videos/lab/walk.mp4" in names and not any(n.endswith(".part") or "/.lock" in n for n in names)

    out = restore({"DATA": str(tmp_path / "data"), "DATABASE_URL": ""}, served["backup"])
    assert out["venues"] == 1 and out["files"] == s["files"] and out["bytes"] == s["bytes"]
    api, st = check_restored(served, restored_app(tmp_path / "data"))
    # the videos' bytes, and the admin token (its hash came back with the catalogue)
    src = Path(served["app"].config["DATA"]) / "videos" / "lab"
    for n in ("walk.mp4", "walk2.mp4"):
        assert (tmp_path / "data" / "videos" / "lab" / n).read_bytes() == (src / n).read_bytes()
    assert not (tmp_path / "data" / "videos" / "lab" / "part.mp4.part").exists()
    assert api.get("/api/admin/venues/lab/videos", headers=PUBLIC).status_code == 403
    # the restored venue can be modelled again: its videos are there
    r = api.post("/api/admin/venues/lab/jobs", json={"videos": ["walk.mp4"]}, headers=ADMIN)
    assert r.status_code == 201, r.json


def test_a_damaged_or_incomplete_backup_is_refused_with_one_line(served, tmp_path):
    bad = tmp_path / "bad"
    shutil.copytree(served["backup"], bad)
    spectra = next(bad.glob("venues/lab/gen-*/spectra.npy"))
    data = spectra.read_bytes()
    spectra.unlink()  # the copy may be a hard link: never write into the original's bytes
    spectra.write_bytes(data[: len(data) // 2])
    target = {"DATA": str(tmp_path / "t"), "DATABASE_URL": ""}
    with pytest.raises(OmninavError, match=r"is damaged: venues/lab/gen-\d+/spectra.npy has \d+ bytes") as e:
        restore(target, bad)
    assert "\n" not in str(e.value)
    assert not (tmp_path / "t").exists()  # checked before anything was touched
    (bad / "manifest.json").unlink()  # as a backup cut off before its end
    with pytest.raises(OmninavError, match="not a complete omninav backup"):
        restore(target, bad)
    with pytest.raises(OmninavError, match="exists and is not empty"):
        backup(served["app"].config, bad)


def test_restore_refuses_a_target_with_venues_unless_forced(served, tmp_path):
    conf = {"DATA": str(tmp_path / "data"), "DATABASE_URL": ""}
    restore(conf, served["backup"])
    with pytest.raises(OmninavError, match=r"has 1 venue\(s\): restore into an empty one, or --force"):
        restore(conf, served["backup"])
    # the database empty but the folder not: refused as well
    other = {"DATA": str(tmp_path / "data"), "DATABASE_URL": f"sqlite:///{tmp_path / 'other.sqlite'}"}
    with pytest.raises(OmninavError, match="holds venues, plans or videos"):
        restore(other, served["backup"])
    restore(conf, served["backup"], force=True)
    check_restored(served, restored_app(tmp_path / "data"))


def test_the_cli_backs_up_without_videos_and_restores_with_force(served, tmp_path, monkeypatch):
    live = served["app"].config
    with monkeypatch.context() as m:  # the live server's database (PostgreSQL with OMNINAV_TEST_DB=postgres)
        m.setenv("OMNINAV_DATABASE_URL", live["DATABASE_URL"])
        p = run_cli("backup", str(tmp_path / "b"), "--no-videos", data=Path(live["DATA"]), check=True)
    s = json.loads(p.stdout)
    assert s["venues"] == 1 and s["videos"] is False and s["frames"] > 0
    assert not (tmp_path / "b" / "videos").exists() and not (tmp_path / "b.tmp").exists()
    target = tmp_path / "data"
    run_cli("restore", str(served["backup"]), data=target, check=True)
    p = run_cli("restore", str(tmp_path / "b"), data=target)
    assert p.returncode == 2 and p.stderr.count("\n") == 1 and "--force" in p.stderr
    p = run_cli("restore", str(tmp_path / "b"), "--force", data=target, check=True)
    assert json.loads(p.stdout)["frames"] == s["frames"]
    api = Api(restored_app(target).test_client())
    assert locate(api, served["body"]) == served["after"]["answer"]  # the job had ended: its frames are in
    assert not (target / "videos").exists()


def test_rows_that_lag_the_generation_are_made_to_describe_it(served, tmp_path):
    """A job commits its generation, then updates its rows: a backup between the two must still
    restore a catalogue that describes the generation. And the backup waits for the venue's lock,
    so no commit can swap the generation while it is read."""
    conf = {"DATA": str(tmp_path / "data"), "DATABASE_URL": ""}
    restore(conf, served["backup"])
    db = Db(f"sqlite:///{tmp_path / 'data' / 'omninav.sqlite'}")
    db.run("UPDATE videos SET frames = 0")  # as if the job's commit had not been recorded yet
    db.run("UPDATE jobs SET state = 'running', owner = 'elsewhere:1:1', finished = NULL WHERE state = 'done'")
    db.engine.dispose()
    store = Store(tmp_path / "data")
    done = threading.Event()
    with store.lock("lab"):  # a commit in progress
        t = threading.Thread(target=lambda: (backup(conf, tmp_path / "b"), done.set()))
        t.start()
        assert not done.wait(0.5)  # the backup waits for it
    t.join()
    assert done.is_set()
    rows = [json.loads(line) for line in (tmp_path / "b" / "db.jsonl").read_text().splitlines()]
    vids = {r["row"]["name"]: r["row"]["frames"] for r in rows if r["table"] == "videos"}
    assert {n: f for n, f in vids.items() if f} == frames_per_video(store, "lab") and vids["part.mp4"] == 0
    jobs = [r["row"] for r in rows if r["table"] == "jobs"]
    assert len(jobs) == 2 and all(j["state"] in ("done", "failed") for j in jobs)


@pytest.mark.parametrize("kind", ["sqlite", "postgresql"])
def test_the_snapshot_is_one_moment_while_a_writer_commits(kind, tmp_path, request):
    """Each write replaces a venue's places and bumps its revision in one transaction: a dump that
    read the tables at different moments would pair a revision with another write's places."""
    url = request.getfixturevalue("pg").url("snapshot") if kind == "postgresql" else f"sqlite:///{tmp_path}/c.db"
    db = Db(url)
    db.migrate()
    cat = Catalog(db, tmp_path)
    cat.venues.create("v", "V")
    r0 = cat.venues.get("v")["revision"]
    stop = threading.Event()

    def write():
        k = 0
        while not stop.is_set():
            k += 1
            cat.places.add("v", [{"name": f"p{k}", "x": 1.0, "y": float(i)} for i in range(3)], replace=True)

    t = threading.Thread(target=write)
    t.start()
    try:
        seen = set()
        t_end = time.monotonic() + 1.0
        while time.monotonic() < t_end:
            rows = dump_rows(db)
            k = rows["venues"][0]["revision"] - r0
            assert sorted(p["name"] for p in rows["places"]) == ([f"p{k}"] * 3 if k else []), k
            seen.add(k)
    finally:
        stop.set()
        t.join()
        db.engine.dispose()
    assert len(seen) > 5  # the writer did commit while the dumps ran


def test_a_backup_moves_between_sqlite_and_postgresql(served, pg, tmp_path):
    url = pg.url("backup_restore")  # a real PostgreSQL server, a new empty database
    conf = {"DATA": str(tmp_path / "pg-data"), "DATABASE_URL": url}
    restore(conf, served["backup"])
    app = restored_app(tmp_path / "pg-data", DATABASE_URL=url)
    try:
        check_restored(served, app)
        # and a backup of the PostgreSQL deployment restores into SQLite the same
        again = backup(conf, tmp_path / "from-pg")
        assert again["frames"] == served["summary"]["frames"] and again["rows"] == served["summary"]["rows"]
        restore({"DATA": str(tmp_path / "sq"), "DATABASE_URL": ""}, tmp_path / "from-pg")
        back = Api(restored_app(tmp_path / "sq").test_client())
        assert locate(back, served["body"]) == locate(Api(app.test_client()), served["body"])
        assert catalogue(back) == catalogue(Api(app.test_client()))
    finally:
        app.extensions["omninav"].db.engine.dispose()


def test_a_backup_never_migrates_the_database_it_reads(tmp_path, monkeypatch):
    """A newer omninav's CLI beside an older server: the backup refuses the server's database with
    one line and leaves its schema as it is (migrating it would change it under that server)."""
    url = f"sqlite:///{tmp_path / 'old.sqlite'}"
    old = Db(url)
    with monkeypatch.context() as m:  # the database of an omninav one schema version older
        m.setattr(db_mod, "SCHEMA_VERSION", SCHEMA_VERSION - 1)
        old.migrate()
    assert old.version() == SCHEMA_VERSION - 1
    monkeypatch.setenv("OMNINAV_DATABASE_URL", url)
    p = run_cli("backup", str(tmp_path / "b"), data=tmp_path)
    assert p.returncode == 2 and p.stderr.count("\n") == 1, p.stderr
    assert f"schema version {SCHEMA_VERSION - 1}, this omninav {SCHEMA_VERSION}" in p.stderr
    assert "never migrates" in p.stderr
    assert old.version() == SCHEMA_VERSION - 1 and not (tmp_path / "b").exists() and not (tmp_path / "b.tmp").exists()
    old.engine.dispose()
    # no database at all: nothing to back up, and the look does not create one
    none = {"DATA": str(tmp_path), "DATABASE_URL": f"sqlite:///{tmp_path / 'none.sqlite'}"}
    with pytest.raises(OmninavError, match="holds no omninav catalogue: nothing to back up"):
        backup(none, tmp_path / "b")
    assert not (tmp_path / "none.sqlite").exists()
