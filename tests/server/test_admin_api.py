"""The admin API the admin page needs (issue 11): the admin's venue document, deleting a venue,
videos registered before their walk path (and tagged later), their facts and frames, and optimistic
concurrency (If-Match / ETag / 412) on every write. Through the real Flask app (test client) on a
real database, every response checked against openapi.yaml (server_helpers.Api)."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import threading
import weakref
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import pytest
from sqlalchemy import text

from conftest import OMNINAV, db_url_for, run_cli
from omninav.catalog.db import SCHEMA_VERSION, Db
from omninav.lens import direction_to_pixel, load_lens
from omninav.server import create_app
from server_helpers import ADMIN, TOKEN, Api

TABLES = ("floors", "places", "lenses", "videos", "jobs", "job_videos")


def make_app(data: Path) -> Any:
    conf = {"DATA": str(data), "ADMIN_TOKEN": TOKEN, "LOCATE_RATE": 0.0, "VENUE_CACHE_S": 0.0, "JOB_RUNNER": False}
    if url := db_url_for(data):
        conf["DATABASE_URL"] = url
    app = create_app(conf)
    if app.config["DATABASE_URL"].startswith("postgresql"):  # its pooled connections close when it goes
        weakref.finalize(app, app.extensions["omninav"].db.engine.dispose)
    return app


def build_venue(api: Api, small_ds: Any, vid: str) -> None:
    """A venue with the small synthetic venue's plan (460 x 300 px at 20 px/m), places and lens."""
    assert api.post("/api/admin/venues", json={"id": vid, "name": vid.title()}, headers=ADMIN).status_code == 201
    base = f"/api/admin/venues/{vid}"
    plan = small_ds.floorplan.read_bytes()
    assert api.put(f"{base}/floors/1/plan", data=plan, headers=ADMIN, content_type="image/png").status_code == 200
    assert api.put(f"{base}/floors/1", json={"px_per_m": 20}, headers=ADMIN).status_code == 200
    places = [{"name": "Room 1", "x": 11.0, "y": 2.0, "area": [10, 1, 12, 3]}]
    assert api.put(f"{base}/places", json=places, headers=ADMIN).status_code == 200
    lens = json.loads((small_ds.root / "model_lens.json").read_text())
    assert api.put(f"{base}/lenses/donut", json=lens, headers=ADMIN).status_code == 200


def post_video(api: Api, vid: str, name: str, size: int, **body: Any) -> Any:
    return api.post(
        f"/api/admin/venues/{vid}/videos", json={"name": name, "size": size, "lens": "donut", **body}, headers=ADMIN
    )


def send(api: Api, vid: str, name: str, data: bytes) -> Any:
    return api.put(
        f"/api/admin/venues/{vid}/videos/{name}/content",
        data=data,
        headers=ADMIN,
        content_type="application/octet-stream",
    )


def revision(api: Api, vid: str) -> int:
    return int(api.get(f"/api/venues/{vid}").json["revision"])


@pytest.fixture(scope="module")
def lab(small_ds: Any, tmp_path_factory: pytest.TempPathFactory) -> tuple[Any, Api]:
    """Venue 'lab' with walk.mp4 uploaded but not tagged, and half.mp4 half uploaded."""
    app = make_app(tmp_path_factory.mktemp("admin") / "data")
    api = Api(app.test_client())
    build_venue(api, small_ds, "lab")
    data = small_ds.model_video.read_bytes()
    r = post_video(api, "lab", "walk.mp4", len(data))
    assert r.status_code == 201, r.json
    assert send(api, "lab", "walk.mp4", data).json["status"] == "ready"
    assert post_video(api, "lab", "half.mp4", len(data)).status_code == 201
    r = api.put(
        "/api/admin/venues/lab/videos/half.mp4/content",
        data=data[:1000],
        headers={**ADMIN, "Content-Range": f"bytes 0-999/{len(data)}"},
        content_type="application/octet-stream",
    )
    assert r.status_code == 202
    return app, api


# ---- videos without a walk path, their facts, walk paths -----------------------------------------
def test_a_video_registered_without_a_walk_path_is_uploaded_checked_but_not_modelled(lab: Any, small_ds: Any) -> None:
    app, api = lab
    v = api.get("/api/admin/venues/lab/videos/walk.mp4", headers=ADMIN).json
    lens = load_lens(small_ds.root / "model_lens.json")
    assert v["status"] == "ready" and v["role"] == "model" and v["error"] is None
    assert v["has_walk_path"] is False and v["walk_path"] is None and v["suggestions"] is None
    assert (v["width"], v["height"]) == tuple(lens.image_size)
    frames = int(cv2.VideoCapture(str(small_ds.model_video)).get(cv2.CAP_PROP_FRAME_COUNT))
    assert v["fps"] > 0 and v["duration_s"] == pytest.approx(frames / v["fps"])
    r = api.post("/api/admin/venues/lab/jobs", headers=ADMIN)
    assert r.status_code == 409 and "has no walk path yet" in r.json["error"]
    r = api.post("/api/admin/venues/lab/jobs", json={"videos": ["walk.mp4"]}, headers=ADMIN)
    assert r.status_code == 409 and "video 'walk.mp4' has no walk path yet" in r.json["error"]
    r = api.get("/api/admin/venues/lab/videos/walk.mp4/walk-path", headers=ADMIN)
    assert r.status_code == 404 and "no walk path yet" in r.json["error"]


def test_a_refused_upload_says_why_on_the_video(lab: Any, small_ds: Any) -> None:
    _, api = lab
    junk = b"not a video at all" * 100
    assert post_video(api, "lab", "junk.mp4", len(junk), role="evaluation").json["role"] == "evaluation"
    r = send(api, "lab", "junk.mp4", junk)
    assert r.status_code == 422 and r.json["received"] == 0
    v = api.get("/api/admin/venues/lab/videos/junk.mp4", headers=ADMIN).json
    assert v["status"] == "uploading" and "was not accepted" in v["error"] and v["duration_s"] is None
    assert api.delete("/api/admin/venues/lab/videos/junk.mp4", headers=ADMIN).status_code == 200


def test_a_walk_path_is_tagged_later_downloaded_and_replaced(lab: Any, small_ds: Any) -> None:
    app, api = lab
    walk_path = json.loads(small_ds.model_walk_path.read_text())
    r = api.put("/api/admin/venues/lab/videos/walk.mp4/walk-path", json=walk_path, headers=ADMIN)
    assert r.status_code == 200 and r.json["has_walk_path"] is True and r.json["walk_path"] == walk_path
    r = api.get("/api/admin/venues/lab/videos/walk.mp4/walk-path", headers=ADMIN)
    assert r.status_code == 200 and r.json == walk_path
    assert r.headers["Content-Disposition"] == 'attachment; filename="walk.mp4.walk_path.json"'
    # a modelled video whose walk path changes is ready to be modelled again
    db = app.extensions["omninav"].db
    db.run("UPDATE videos SET status = 'modelled' WHERE venue = 'lab' AND name = 'walk.mp4'")
    moved = {**walk_path, "waypoints": [{**w, "x": w["x"] + 0.1} for w in walk_path["waypoints"]]}
    r = api.put("/api/admin/venues/lab/videos/walk.mp4/walk-path", json=moved, headers=ADMIN)
    assert r.json["status"] == "ready" and r.json["walk_path"]["waypoints"][0]["x"] == moved["waypoints"][0]["x"]
    # the default modelling selection takes it now (the job is left queued: no runner here)
    job = api.post("/api/admin/venues/lab/jobs", headers=ADMIN)
    assert job.status_code == 201 and job.json["videos"] == ["walk.mp4"]
    r = api.put("/api/admin/venues/lab/videos/walk.mp4/walk-path", json=walk_path, headers=ADMIN)
    assert r.status_code == 409 and "being modelled" in r.json["error"]
    assert api.post(f"/api/admin/jobs/{job.json['id']}/cancel", headers=ADMIN).status_code == 202


def test_the_walk_paths_old_names_still_work_for_a_release(lab: Any, small_ds: Any) -> None:
    """`.../track` and the registration key `track` were the walk path's names until the rename:
    still read, to the same place; both keys at once is refused, and nothing is registered."""
    _, api = lab
    walk_path = json.loads(small_ds.model_walk_path.read_text())
    v = "/api/admin/venues/lab/videos"
    r = api.put(f"{v}/walk.mp4/track", json=walk_path, headers=ADMIN)
    assert r.status_code == 200 and r.json["walk_path"] == walk_path
    assert api.get(f"{v}/walk.mp4/track", headers=ADMIN).json == walk_path
    assert api.get(f"{v}/walk.mp4/walk-path", headers=ADMIN).json == walk_path
    r = api.post(v, json={"name": "old.mp4", "size": 10, "track": walk_path, "lens": "donut"}, headers=ADMIN)
    assert r.status_code == 201 and r.json["has_walk_path"] and r.json["walk_path"] == walk_path
    both = {"name": "both.mp4", "size": 10, "track": walk_path, "walk_path": walk_path, "lens": "donut"}
    r = api.post(v, json=both, headers=ADMIN)
    assert r.status_code == 400 and "give 'walk_path' only" in r.json["error"]
    assert api.get(f"{v}/both.mp4", headers=ADMIN).status_code == 404


def _off_plan(t: dict[str, Any]) -> dict[str, Any]:
    return {**t, "waypoints": [*t["waypoints"][:-1], {**t["waypoints"][-1], "x": 99.0}]}


def _backwards(t: dict[str, Any]) -> dict[str, Any]:
    return {**t, "waypoints": list(reversed(t["waypoints"]))}


@pytest.mark.parametrize(
    ("name", "change", "status", "says"),
    [
        ("walk.mp4", _off_plan, 422, "lies outside the floor plan"),
        ("walk.mp4", _backwards, 422, "increasing time"),
        ("walk.mp4", lambda t: {"fps": 30, "waypoints": [{"frame": 0, "x": 1, "y": 1}]}, 422, "at least two"),
        ("walk.mp4", lambda t: {**t, "fps": -1}, 422, "'fps' must be positive"),
        ("walk.mp4", lambda t: [t], 400, "must be a JSON object"),
        ("nope.mp4", lambda t: t, 404, "has no video 'nope.mp4'"),
        ("bad..name", lambda t: t, 400, "invalid video name"),
    ],
)
def test_a_bad_walk_path_is_refused_naming_what_is_wrong(
    lab: Any, small_ds: Any, name: str, change: Any, status: int, says: str
) -> None:
    _, api = lab
    before = api.get("/api/admin/venues/lab/videos/walk.mp4", headers=ADMIN).json
    walk_path = change(json.loads(small_ds.model_walk_path.read_text()))
    r = api.put(f"/api/admin/venues/lab/videos/{name}/walk-path", json=walk_path, headers=ADMIN)
    assert r.status_code == status and says in r.json["error"], r.json
    assert api.get("/api/admin/venues/lab/videos/walk.mp4", headers=ADMIN).json == before


@pytest.mark.parametrize(
    ("body", "status", "says"),
    [
        ({"role": "judge"}, 400, "'role' must be one of model, evaluation"),
        ({"floor": "9"}, 404, "has no floor '9'"),
        ({"walk_path": {"fps": 30, "waypoints": []}}, 400, "at least two"),
        ({"walk_path": None, "lens": "nolens"}, 404, "no lens profile 'nolens'"),
    ],
)
def test_a_bad_video_registration_is_refused(lab: Any, body: dict[str, Any], status: int, says: str) -> None:
    _, api = lab
    r = post_video(api, "lab", "new.mp4", 1000, **body)
    assert r.status_code == status and says in r.json["error"], r.json


def test_suggestions_are_kept_on_the_video(lab: Any) -> None:
    app, api = lab
    result = {"duration_s": 10.0, "fps": 30.0, "frames": 300, "heading": [[0.0, 0.0], [0.5, 1.0]]}
    result["suggestions"] = [{"t": 2.0, "kind": "turn", "turn_deg": 90.0, "duration_s": None}]
    app.extensions["omninav"].catalog.videos.set_suggestions("lab", "walk.mp4", result)
    assert api.get("/api/admin/venues/lab/videos/walk.mp4", headers=ADMIN).json["suggestions"] == result
    app.extensions["omninav"].catalog.videos.set_suggestions("lab", "gone.mp4", result)  # no such video: nothing


# ---- frames ---------------------------------------------------------------------------------------
def _jpeg(r: Any) -> np.ndarray:
    assert r.status_code == 200, r.get_json()
    assert r.mimetype == "image/jpeg" and r.data[:3] == b"\xff\xd8\xff"
    img = cv2.imdecode(np.frombuffer(r.data, np.uint8), cv2.IMREAD_COLOR)
    assert img is not None
    return np.asarray(img)


def _frame(small_ds: Any, index: int) -> np.ndarray:
    cap = cv2.VideoCapture(str(small_ds.model_video))
    cap.set(cv2.CAP_PROP_POS_FRAMES, index)
    ok, f = cap.read()
    cap.release()
    assert ok
    return np.asarray(f)


def test_the_raw_frame_at_a_time(lab: Any, small_ds: Any) -> None:
    _, api = lab
    v = api.get("/api/admin/venues/lab/videos/walk.mp4", headers=ADMIN).json
    url = "/api/admin/venues/lab/videos/walk.mp4/frame"
    img = _jpeg(api.get(f"{url}?t=2", headers=ADMIN))
    assert img.shape == (v["height"], v["width"], 3)  # 480 x 360: below the default 960, never enlarged
    want = _frame(small_ds, int(2 * v["fps"]))
    assert np.abs(img.astype(int) - want.astype(int)).mean() < 4  # the same frame, up to JPEG
    other = _frame(small_ds, int(2 * v["fps"]) + int(v["fps"]))
    assert np.abs(img.astype(int) - other.astype(int)).mean() > 4  # not just any frame
    small = _jpeg(api.get(f"{url}?t=0&view=raw&width=240", headers=ADMIN))
    assert small.shape == (180, 240, 3)
    last = _jpeg(api.get(f"{url}?t={v['duration_s']}", headers=ADMIN))
    assert last.shape == img.shape


def test_the_panorama_is_the_engines_unwarp_with_forward_at_the_centre(lab: Any, small_ds: Any) -> None:
    _, api = lab
    v = api.get("/api/admin/venues/lab/videos/walk.mp4", headers=ADMIN).json
    lens = load_lens(small_ds.root / "model_lens.json")
    pano = _jpeg(api.get("/api/admin/venues/lab/videos/walk.mp4/frame?t=2&view=panorama&width=720", headers=ADMIN))
    lo, hi = lens.elevation_range()
    rows = int(round((hi - lo) / 0.5)) + 1  # as many degrees a row as a column: 360 / 720
    assert pano.shape == (rows, 720, 3)
    default = _jpeg(api.get("/api/admin/venues/lab/videos/walk.mp4/frame?t=2&view=panorama", headers=ADMIN))
    assert default.shape[1] == 1440
    # column j looks at azimuth (j + 0.5 - 360) * 0.5 degrees: the centre column looks forward
    frame = _frame(small_ds, int(2 * v["fps"]))
    el = np.linspace(hi, lo, rows)
    for j in (360, 0, 540):
        az = (j + 0.5) * 0.5 - 180.0
        x, y = direction_to_pixel(lens, np.full(rows, az), el)
        col = cv2.remap(frame, x.astype(np.float32)[:, None], y.astype(np.float32)[:, None], cv2.INTER_LINEAR)
        assert np.abs(pano[:, j].astype(int) - col[:, 0].astype(int)).mean() < 12, j


@pytest.mark.parametrize(
    ("video", "query", "status", "says"),
    [
        ("walk.mp4", "", 400, "'t' is required"),
        ("walk.mp4", "t=abc", 400, "'t' must be a finite number"),
        ("walk.mp4", "t=nan", 400, "'t' must be a finite number"),
        ("walk.mp4", "t=-1", 422, "t must be within the video's 0 to"),
        ("walk.mp4", "t=100000", 422, "t must be within the video's 0 to"),
        ("walk.mp4", "t=1&view=fisheye", 400, "view must be one of raw, panorama"),
        ("walk.mp4", "t=1&width=8", 400, "width must be 16 to 2880 pixels, got 8"),
        ("walk.mp4", "t=1&view=panorama&width=9000", 400, "width must be 16 to 2880 pixels, got 9000"),
        ("walk.mp4", "t=1&width=100.5", 400, "whole number of pixels"),
        ("half.mp4", "t=1", 409, "is not uploaded yet (1000 of"),
        ("nope.mp4", "t=1", 404, "has no video 'nope.mp4'"),
    ],
)
def test_a_bad_frame_request_says_why(lab: Any, video: str, query: str, status: int, says: str) -> None:
    _, api = lab
    r = api.get(f"/api/admin/venues/lab/videos/{video}/frame?{query}", headers=ADMIN)
    assert r.status_code == status and says in r.json["error"], r.json


# ---- the admin's venue document ---------------------------------------------------------------
def test_the_admin_venue_says_which_generation_is_live(tmp_path: Path, small_ds: Any, modelled: Any) -> None:
    app = make_app(tmp_path / "data")
    api = Api(app.test_client())
    build_venue(api, small_ds, "v")
    r = api.get("/api/admin/venues/v", headers=ADMIN)
    assert r.status_code == 200 and r.json["generation"] is None and r.json["modelled_at"] is None
    assert r.headers["ETag"] == f'"{r.json["revision"]}"'
    public = api.get("/api/venues/v").json
    assert {k: r.json[k] for k in public} == public
    assert [v["modelled"] for v in api.get("/api/venues").json["venues"]] == [False]  # the app's list too
    st, vid = modelled
    shutil.copytree(st.venue_dir(vid), tmp_path / "data" / "venues" / "v")
    r = api.get("/api/admin/venues/v", headers=ADMIN)
    assert r.json["generation"] == 1 and r.json["modelled_at"] > 0 and r.json["frames"] > 0
    assert [v["modelled"] for v in api.get("/api/venues").json["venues"]] == [True]
    assert api.get("/api/admin/venues/nope", headers=ADMIN).status_code == 404


# ---- optimistic concurrency -------------------------------------------------------------------
def _writes(small_ds: Any) -> list[tuple[str, str, dict[str, Any]]]:
    plan = small_ds.floorplan.read_bytes()
    walk_path = json.loads(small_ds.model_walk_path.read_text())
    lens = json.loads((small_ds.root / "model_lens.json").read_text())
    return [
        ("PATCH", "", {"json": {"name": "Renamed"}}),
        ("PUT", "/floors/1", {"json": {"name": "Ground"}}),
        ("PUT", "/floors/2", {"json": {"name": "First"}}),
        ("PUT", "/floors/1/plan", {"data": plan, "content_type": "image/png"}),
        ("PUT", "/places", {"json": [{"name": "Lifts", "x": 1, "y": 1}]}),
        ("POST", "/places", {"json": {"name": "Stairs", "x": 2, "y": 2}}),
        ("DELETE", "/places/{place}", {}),
        ("PUT", "/lenses/other", {"json": lens}),
        ("POST", "/videos", {"json": {"name": "b.mp4", "size": 10, "walk_path": walk_path, "lens": "donut"}}),
        ("POST", "/videos", {"json": {"name": "c.mp4", "size": 10, "lens": lens}}),  # an inline lens: two bumps
        ("PUT", "/videos/a.mp4/walk-path", {"json": walk_path}),
        ("DELETE", "/videos/a.mp4", {}),
        ("DELETE", "", {}),
    ]


def _snapshot(app: Any, vid: str) -> dict[str, Any]:
    db = app.extensions["omninav"].db
    rows = {t: db.all(f"SELECT * FROM {t} WHERE venue = :v ORDER BY 1, 2", v=vid) for t in TABLES}
    rows["venue"] = db.all("SELECT * FROM venues WHERE id = :v", v=vid)
    plan = Path(app.config["DATA"]) / "plans" / vid / "1.png"
    rows["plan"] = plan.read_bytes() if plan.is_file() else None
    return rows


@pytest.fixture
def fresh(tmp_path: Path, small_ds: Any) -> tuple[Any, Api]:
    """Venue 'v' with a plan, a place, a lens, and video a.mp4 registered."""
    app = make_app(tmp_path / "data")
    api = Api(app.test_client())
    build_venue(api, small_ds, "v")
    assert post_video(api, "v", "a.mp4", 10).status_code == 201
    return app, api


def _call(api: Api, app: Any, method: str, path: str, kw: dict[str, Any], headers: dict[str, str]) -> Any:
    if "{place}" in path:
        place = app.extensions["omninav"].db.one("SELECT id FROM places WHERE venue = 'v'")["id"]
        path = path.replace("{place}", place)
    return api.open(f"/api/admin/venues/v{path}", method=method, headers={**ADMIN, **headers}, **kw)


@pytest.mark.parametrize("which", range(13))
def test_every_write_with_a_stale_revision_is_refused_and_changes_nothing(
    fresh: Any, small_ds: Any, which: int
) -> None:
    app, api = fresh
    method, path, kw = _writes(small_ds)[which]
    rev = revision(api, "v")
    before = _snapshot(app, "v")
    r = _call(api, app, method, path, kw, {"If-Match": f'"{rev - 1}"'})
    assert r.status_code == 412, r.json
    assert r.json["error"] == (
        f"the venue changed since you opened it (revision {rev} now, you had {rev - 1}); reload it"
    )
    assert r.json["revision"] == rev and r.json["details"] == {"revision": rev}
    assert _snapshot(app, "v") == before
    r = _call(api, app, method, path, kw, {"If-Match": f'"{rev}"'})
    assert r.status_code < 300, r.get_json()
    if path == "" and method == "DELETE":
        assert "ETag" not in r.headers and api.get("/api/venues/v").status_code == 404
        return
    now = revision(api, "v")
    assert now > rev and r.headers["ETag"] == f'"{now}"'
    # the answer's ETag is the next write's If-Match; no header at all: last write wins
    head = {**ADMIN, "If-Match": r.headers["ETag"]}
    assert api.patch("/api/admin/venues/v", json={"name": "X"}, headers=head).status_code == 200
    assert api.patch("/api/admin/venues/v", json={"name": "Y"}, headers=ADMIN).status_code == 200


def test_a_write_that_changes_nothing_answers_no_etag(fresh: Any, small_ds: Any) -> None:
    # tab A read revision N; tab B then saved (N+1). A's upload piece changes nothing: if it answered
    # the venue's current revision, A would take N+1 as its own and its next save would undo B's
    app, api = fresh
    data = small_ds.model_video.read_bytes()
    assert post_video(api, "v", "walk.mp4", len(data)).status_code == 201
    stale = revision(api, "v")
    assert api.patch("/api/admin/venues/v", json={"name": "B's"}, headers=ADMIN).status_code == 200
    r = api.put(
        "/api/admin/venues/v/videos/walk.mp4/content",
        data=data[:1000],
        headers={**ADMIN, "Content-Range": f"bytes 0-999/{len(data)}"},
        content_type="application/octet-stream",
    )
    assert r.status_code == 202 and "ETag" not in r.headers
    r = api.patch("/api/admin/venues/v", json={"name": "A's"}, headers={**ADMIN, "If-Match": f'"{stale}"'})
    assert r.status_code == 412 and api.get("/api/venues/v").json["name"] == "B's"


@pytest.mark.parametrize("value", ["7", 'W/"7"', "*"])
def test_if_match_forms(fresh: Any, value: str) -> None:
    app, api = fresh
    app.extensions["omninav"].db.run("UPDATE venues SET revision = 7 WHERE id = 'v'")
    r = api.patch("/api/admin/venues/v", json={"name": "Z"}, headers={**ADMIN, "If-Match": value})
    assert r.status_code == 200 and r.headers["ETag"] == '"8"'


@pytest.mark.parametrize("value", ['"seven"', '"1", "2"', ""])
def test_a_malformed_if_match_is_a_400(fresh: Any, value: str) -> None:
    _, api = fresh
    r = api.patch("/api/admin/venues/v", json={"name": "Z"}, headers={**ADMIN, "If-Match": value})
    assert r.status_code == 400 and "If-Match must be the venue's revision" in r.json["error"]


def test_an_invalid_write_does_not_move_the_revision(fresh: Any) -> None:
    """A write refused for its content (422, 400) leaves the revision: the tab's next save still fits."""
    _, api = fresh
    rev = revision(api, "v")
    head = {**ADMIN, "If-Match": f'"{rev}"'}
    assert api.put("/api/admin/venues/v/floors/1", json={"px_per_m": -1}, headers=head).status_code == 400
    assert (
        api.put("/api/admin/venues/v/floors/1/plan", data=b"x", headers=head, content_type="image/png").status_code
        == 422
    )
    assert revision(api, "v") == rev
    assert api.put("/api/admin/venues/v/floors/1", json={"px_per_m": 10}, headers=head).status_code == 200


def _two_tabs(app: Any, what: str, rev: int, plan: bytes) -> list[int]:
    """Two clients send a write from revision `rev` at the same moment: their status codes."""
    barrier = threading.Barrier(2)
    codes: list[int] = []

    def save(i: int) -> None:
        c = app.test_client()
        head = {**ADMIN, "If-Match": f'"{rev}"'}
        barrier.wait()
        if what == "rename":
            r = c.patch("/api/admin/venues/v", json={"name": f"Tab {i}"}, headers=head)
        elif what == "places":
            r = c.put("/api/admin/venues/v/places", json=[{"name": f"Tab {i}", "x": 1, "y": 1}], headers=head)
        else:
            r = c.put("/api/admin/venues/v/floors/1/plan", data=plan, headers=head, content_type="image/png")
        codes.append(r.status_code)

    threads = [threading.Thread(target=save, args=(i,)) for i in range(2)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    return codes


@pytest.mark.parametrize("what", ["rename", "places", "plan"])
def test_two_tabs_saving_at_once_from_one_revision_one_wins(fresh: Any, small_ds: Any, what: str) -> None:
    """The check is in the write's transaction: of two writers that read the same revision, one
    succeeds and the other gets 412, however their requests interleave."""
    app, api = fresh
    plan = small_ds.floorplan.read_bytes()
    for attempt in range(8):
        rev = revision(api, "v")
        codes = _two_tabs(app, what, rev, plan)
        assert sorted(codes) == [200, 412], (attempt, codes)
        assert revision(api, "v") == rev + 1


# ---- deleting a venue -------------------------------------------------------------------------
def test_deleting_a_venue_leaves_nothing_behind(tmp_path: Path, small_ds: Any, modelled: Any) -> None:
    data = tmp_path / "data"
    app = make_app(data)
    api = Api(app.test_client())
    for vid in ("gone", "kept"):
        build_venue(api, small_ds, vid)
        video = small_ds.model_video.read_bytes()
        walk_path = json.loads(small_ds.model_walk_path.read_text())
        assert post_video(api, vid, "walk.mp4", len(video), walk_path=walk_path).status_code == 201
        assert send(api, vid, "walk.mp4", video).status_code == 200
        st, src = modelled
        shutil.copytree(st.venue_dir(src), data / "venues" / vid)
        (data / "results" / vid).mkdir(parents=True)
        (data / "results" / vid / "x.json").write_text("{}")
    job = api.post("/api/admin/venues/gone/jobs", headers=ADMIN).json  # queued: no runner here
    frames = api.get("/api/venues/gone").json["frames"]
    before = _snapshot(app, "kept")
    r = api.delete("/api/admin/venues/gone", headers=ADMIN)
    assert r.status_code == 200 and r.json == {"deleted": "gone", "frames_removed": frames, "videos_removed": 1}
    assert api.get("/api/venues/gone").status_code == 404
    assert api.get(f"/api/admin/jobs/{job['id']}", headers=ADMIN).status_code == 404
    db = app.extensions["omninav"].db
    for t in TABLES:
        assert db.all(f"SELECT * FROM {t} WHERE venue = 'gone'") == [], t
    for tree in ("venues", "plans", "videos", "results"):
        assert not (data / tree / "gone").exists(), tree
    assert _snapshot(app, "kept") == before and (data / "results" / "kept" / "x.json").is_file()
    assert api.get("/api/venues/kept").json["frames"] == frames
    assert api.delete("/api/admin/venues/gone", headers=ADMIN).status_code == 404
    assert [v["id"] for v in api.get("/api/venues").json["venues"]] == ["kept"]


def test_deleting_a_venue_stops_its_running_job(tmp_path: Path, small_ds: Any) -> None:
    """A job that is running when its venue goes is stopped (cancel flag) and waited for."""
    app = make_app(tmp_path / "data")
    api = Api(app.test_client())
    build_venue(api, small_ds, "v")
    video = small_ds.model_video.read_bytes()
    walk_path = json.loads(small_ds.model_walk_path.read_text())
    assert post_video(api, "v", "walk.mp4", len(video), walk_path=walk_path).status_code == 201
    assert send(api, "v", "walk.mp4", video).status_code == 200
    jobs = app.extensions["omninav"].jobs
    job = api.post("/api/admin/venues/v/jobs", headers=ADMIN).json
    runner = threading.Thread(target=jobs.run_next)
    runner.start()
    db = app.extensions["omninav"].db
    while (row := db.one("SELECT state FROM jobs WHERE id = :id", id=job["id"])) and row["state"] == "queued":
        threading.Event().wait(0.02)
    r = api.delete("/api/admin/venues/v", headers=ADMIN)
    runner.join(60)
    assert r.status_code == 200 and not runner.is_alive()
    assert not (tmp_path / "data" / "venues" / "v").exists()
    assert db.all("SELECT * FROM jobs") == [] and db.all("SELECT * FROM venues") == []


def test_the_cli_deletes_a_venue(tmp_path: Path) -> None:
    data = tmp_path / "data"
    run_cli("venue", "create", "hall", "--name", "Hall", data=data, check=True)
    asked = subprocess.run(
        [OMNINAV, "venue", "delete", "hall"],
        input="n\n",
        capture_output=True,
        text=True,
        env={**os.environ, "OMNINAV_DATA": str(data)},
        timeout=60,
    )
    assert asked.returncode != 0 and "Delete venue 'hall' (Hall)" in asked.stdout  # it asks first
    assert "hall" in run_cli("venue", "list", data=data, check=True).stdout
    p = run_cli("venue", "delete", "hall", "--yes", data=data, check=True)
    assert json.loads(p.stdout) == {"deleted": "hall", "frames_removed": 0, "videos_removed": 0}
    assert run_cli("venue", "list", data=data, check=True).stdout == ""
    p = run_cli("venue", "delete", "hall", "--yes", data=data)
    assert p.returncode != 0 and "unknown venue 'hall'" in p.stderr


# ---- migration 4 --------------------------------------------------------------------------------
def test_migration_4_keeps_videos_and_jobs_of_a_version_3_catalogue(tmp_path: Path) -> None:
    from omninav.catalog import db as db_mod

    url = f"sqlite:///{tmp_path / 'c.db'}"
    old = Db(url)
    migrations = db_mod.MIGRATIONS
    db_mod.MIGRATIONS = migrations[:3]
    try:
        db_mod.SCHEMA_VERSION = 3
        old.migrate()
    finally:
        db_mod.MIGRATIONS, db_mod.SCHEMA_VERSION = migrations, len(migrations)
    with old.tx() as c:
        c.execute(text("INSERT INTO venues (id, name, preset, created, revision) VALUES ('v', 'V', 'default', 0, 3)"))
        c.execute(
            text(
                "INSERT INTO videos (venue, name, floor, lens, track, size, status, created) "
                "VALUES ('v', 'a.mp4', '1', 'default', '{\"waypoints\": []}', 10, 'ready', 0)"
            )
        )
        c.execute(text("INSERT INTO jobs (id, venue, videos, state, created) VALUES ('j', 'v', '[]', 'done', 0)"))
    assert old.version() == 3 and old.migrate() == SCHEMA_VERSION - 3 and old.version() == SCHEMA_VERSION
    v = old.one("SELECT * FROM videos")
    assert v is not None and v["role"] == "model" and v["walk_path"] == '{"waypoints": []}' and v["suggestions"] is None
    j = old.one("SELECT * FROM jobs")
    assert j is not None and j["kind"] == "model" and j["target"] is None and j["result"] is None


def test_a_backup_holds_the_job_results(tmp_path: Path, small_ds: Any) -> None:
    """Analysis results are files (DATA/results/<venue>/<job>.json, named in jobs.result): a
    backup takes them, and a result whose file is gone is not promised."""
    from omninav.server.backup import backup, restore

    app = make_app(tmp_path / "data")
    api = Api(app.test_client())
    build_venue(api, small_ds, "v")
    db = app.extensions["omninav"].db
    for job, result in (("j1", "results/v/j1.json"), ("j2", "results/v/j2.json")):
        db.run(
            "INSERT INTO jobs (id, venue, videos, state, created, kind, result) "
            "VALUES (:id, 'v', '[]', 'done', 0, 'quality', :r)",
            id=job,
            r=result,
        )
    (tmp_path / "data" / "results" / "v").mkdir(parents=True)
    (tmp_path / "data" / "results" / "v" / "j1.json").write_text('{"ok": 1}')
    backup(app.config, tmp_path / "b")
    assert (tmp_path / "b" / "results" / "v" / "j1.json").read_text() == '{"ok": 1}'
    conf = {"DATA": str(tmp_path / "again"), "DATABASE_URL": f"sqlite:///{tmp_path / 'again.db'}"}
    restore(conf, tmp_path / "b")
    assert (tmp_path / "again" / "results" / "v" / "j1.json").read_text() == '{"ok": 1}'
    rows = {r["id"]: r["result"] for r in Db(conf["DATABASE_URL"]).all("SELECT id, result FROM jobs")}
    assert rows == {"j1": "results/v/j1.json", "j2": None}
