"""The server through its real Flask app (test client): every endpoint, every bad input, each
response checked against openapi.yaml. The venue is built through the admin API as a user would:
floor plan, scale, places, lens, a chunked video upload, a background modelling job."""

from __future__ import annotations

import atexit
import io
import json
import re
import time
import weakref
from pathlib import Path

import cv2
import numpy as np
import pytest

from conftest import db_url_for
from omninav.presets import FEATURE_KEYS, feature_keys, resolve
from omninav.server import create_app
from omninav.spectrum import encode_binary, encode_json
from omninav.synth.walks import write_video
from server_helpers import ADMIN, SPEC, TOKEN, Api, clip_spectra, heading_error, query_clip, spec_path

CLIP_START = 100  # a 1 s query clip on the first corridor of the small venue


def make_app(tmp, **over):
    conf = {"DATA": str(tmp), "ADMIN_TOKEN": TOKEN, "LOCATE_RATE": 0.0, "VENUE_CACHE_S": 0.0}
    if url := db_url_for(tmp):  # OMNINAV_TEST_DB=postgres: the data directory's own PostgreSQL database
        conf["DATABASE_URL"] = url
    conf.update(over)
    app = create_app(conf)
    if app.config["DATABASE_URL"].startswith("postgresql"):
        if app.config["JOB_RUNNER"]:  # its thread stops at exit, before the PostgreSQL server does
            atexit.register(app.extensions["omninav"].jobs.stop, 10.0)
        else:  # its pooled connections close when it goes (the job thread of another holds its engine)
            weakref.finalize(app, app.extensions["omninav"].db.engine.dispose)
    return app


def wait_job(api, job_id, timeout=120):
    t0 = time.time()
    while time.time() - t0 < timeout:
        j = api.get(f"/api/admin/jobs/{job_id}", headers=ADMIN).json
        if j["state"] not in ("queued", "running"):
            return j
        time.sleep(0.1)
    raise AssertionError(f"job {job_id} did not end: {j}")


def upload(api, venue, name, data, piece=None):
    """PUT the bytes in pieces with Content-Range (or whole), as a resumable client does."""
    piece = piece or len(data)
    r = None
    for a in range(0, len(data), piece):
        b = min(len(data), a + piece) - 1
        r = api.put(
            f"/api/admin/venues/{venue}/videos/{name}/content",
            data=data[a : b + 1],
            headers={**ADMIN, "Content-Range": f"bytes {a}-{b}/{len(data)}"},
            content_type="application/octet-stream",
        )
    return r


def add_video(api, venue, name, ds, lens="donut", walk_path=None):
    data = ds.model_video.read_bytes()
    walk_path = walk_path or json.loads(ds.model_walk_path.read_text())
    r = api.post(
        f"/api/admin/venues/{venue}/videos",
        json={"name": name, "floor": "1", "size": len(data), "walk_path": walk_path, "lens": lens},
        headers=ADMIN,
    )
    assert r.status_code == 201, r.json
    return data


@pytest.fixture(scope="module")
def built(small_ds, tmp_path_factory):
    """An app with venue 'lab' built and modelled entirely through the API."""
    app = make_app(tmp_path_factory.mktemp("server"))
    api = Api(app.test_client())
    assert api.post("/api/admin/venues", json={"id": "lab", "name": "Lab"}, headers=ADMIN).status_code == 201
    plan = small_ds.floorplan.read_bytes()
    r = api.put("/api/admin/venues/lab/floors/1/plan", data=plan, headers=ADMIN, content_type="image/png")
    assert r.status_code == 200 and r.json["plan_size_px"] == [460, 300]
    # scale by two points 200 px apart that are 10 m apart: 20 px/m
    r = api.put(
        "/api/admin/venues/lab/floors/1",
        json={"name": "Second floor", "scale": {"a": [10, 10], "b": [210, 10], "distance_m": 10}},
        headers=ADMIN,
    )
    assert r.json["px_per_m"] == pytest.approx(20.0)
    places = [{**p, "floor": "1"} for p in small_ds.scene.places] + [
        {"name": "the lifts", "x": 20.0, "y": 2.0},
        {"name": "Room 1", "x": 11.0, "y": 2.0},
    ]
    assert api.put("/api/admin/venues/lab/places", json=places, headers=ADMIN).status_code == 200
    lens = json.loads((small_ds.root / "model_lens.json").read_text())
    assert api.put("/api/admin/venues/lab/lenses/donut", json=lens, headers=ADMIN).status_code == 200
    data = add_video(api, "lab", "walk.mp4", small_ds)
    r = upload(api, "lab", "walk.mp4", data, piece=len(data) // 3 + 1)
    assert r.status_code == 200 and r.json["status"] == "ready"
    job = api.post("/api/admin/venues/lab/jobs", headers=ADMIN).json
    assert job["state"] in ("queued", "running") and job["videos"] == ["walk.mp4"]
    done = wait_job(api, job["id"])
    assert done["state"] == "done", done
    return app, api


@pytest.fixture(scope="module")
def clip(small_ds, built):
    frames, truth = query_clip(small_ds, CLIP_START)
    conf = built[0].extensions["omninav"].catalog.venues.settings("lab")
    return frames, truth, clip_spectra(small_ds, frames, conf), conf


def assert_near(ans, truth, metres=2.0, degrees=10.0):
    assert np.hypot(ans["x"] - truth[0], ans["y"] - truth[1]) <= metres, (ans, truth)
    assert heading_error(ans["heading_deg"], truth[2]) <= degrees, (ans, truth)


def test_every_api_route_is_documented_and_every_documented_path_exists(built):
    app, _ = built
    routes = set()
    for rule in app.url_map.iter_rules():
        if rule.rule.startswith("/api/") or rule.rule in SPEC["paths"]:  # the API, and /ca.pem
            tmpl = rule.rule.replace("<", "{").replace(">", "}")
            assert spec_path(tmpl) == tmpl, f"{rule.rule} is not in openapi.yaml"
            for m in rule.methods - {"HEAD", "OPTIONS"}:
                assert m.lower() in SPEC["paths"][tmpl], f"{m} {tmpl} is not in openapi.yaml"
            routes.add(tmpl)
    assert routes == set(SPEC["paths"])


def test_public_venue_describes_what_a_client_needs(built):
    _, api = built
    assert api.get("/api/health").json["status"] == "ok"
    assert api.get("/api/openapi.json").json["openapi"].startswith("3.1")
    assert [(v["id"], v["modelled"]) for v in api.get("/api/venues").json["venues"]] == [("lab", True)]
    v = api.get("/api/venues/lab").json
    assert v["modelled"] and v["frames"] > 100
    assert v["floors"][0]["name"] == "Second floor"
    assert v["lenses"]["donut"]["model"] == "catadioptric"
    assert v["features"]["record_bytes_per_frame"] == 896
    assert "level_iters" in v["features"]["feature_keys"] and "track_radius_m" not in v["features"]["feature_keys"]
    assert any(p["name"] == "the lifts" for p in v["places"])
    png = api.get(v["floors"][0]["plan_url"])
    assert png.status_code == 200 and png.mimetype == "image/png"
    assert cv2.imdecode(np.frombuffer(png.data, np.uint8), cv2.IMREAD_COLOR).shape[:2] == (300, 460)
    png.close()  # a file response: close it, or its file is closed at some later garbage collection


@pytest.mark.parametrize("form", ["binary", "json"])
def test_locate_features_answers_within_2m_and_10deg_with_words(built, clip, form):
    _, api = built
    _, truth, spec, conf = clip
    if form == "binary":
        r = api.post(
            "/api/venues/lab/locate?clip=q1", data=encode_binary(spec, conf), content_type="application/octet-stream"
        )
    else:
        r = api.post("/api/venues/lab/locate?clip=q1", json=encode_json(spec, conf))
    assert r.status_code == 200, r.json
    a = r.json
    assert_near(a, truth)
    assert a["clip"] == "q1" and a["floor"] == "1" and a["frames"] == 10 and a["sent"] == "features"
    assert a["confidence"] >= 0.8 and not a["low_confidence"] and a["accuracy_m"] == 2.0
    assert a["area"] == "Corridor 1"
    # the clip ends about 16 m along the first corridor, walking west: the lifts behind, Room 1 ahead
    assert a["sentence"].startswith("You are in Corridor 1, near the lifts") and a["sentence"].endswith(".")
    assert a["nearest"]["name"] == "the lifts" and abs(a["nearest"]["bearing_deg"]) > 150
    assert a["facing"] == "Room 1"
    assert "plan_png" not in a


def test_locate_answers_the_same_from_frames_video_and_features(built, clip, tmp_path):
    _, api = built
    frames, truth, spec, conf = clip
    # JPEG, as a phone sends (small enough that the test client does not spool it to a file)
    jpgs = [(io.BytesIO(cv2.imencode(".jpg", f)[1].tobytes()), f"f{i}.jpg") for i, f in enumerate(frames)]
    r = api.post("/api/venues/lab/locate?lens=donut", data={"frame": jpgs}, content_type="multipart/form-data")
    assert r.status_code == 200, r.json
    assert r.json["sent"] == "frames"
    assert_near(r.json, truth)
    feat = api.post("/api/venues/lab/locate", data=encode_binary(spec, conf), content_type="application/octet-stream")
    assert (r.json["x"], r.json["y"]) == pytest.approx((feat.json["x"], feat.json["y"]), abs=0.05)
    vid = tmp_path / "clip.mp4"
    write_video(vid, iter(frames), 10.0, (frames[0].shape[1], frames[0].shape[0]))
    r = api.post("/api/venues/lab/locate", data=vid.read_bytes(), content_type="video/mp4")
    assert r.status_code == 200, r.json
    assert_near(r.json, truth)
    r = api.post("/api/venues/lab/locate", data={"video": (io.BytesIO(vid.read_bytes()), "c.mp4")})
    assert r.status_code == 200 and r.json["sent"] == "frames"


def test_locate_can_return_the_annotated_plan(built, clip):
    import base64

    _, api = built
    _, _, spec, conf = clip
    r = api.post("/api/venues/lab/locate?plan=1", json=encode_json(spec, conf))
    url = r.json["plan_png"]
    assert url.startswith("data:image/png;base64,")
    img = cv2.imdecode(np.frombuffer(base64.b64decode(url.split(",")[1]), np.uint8), cv2.IMREAD_COLOR)
    assert img.shape[:2] == (300, 460)
    x, y = int(r.json["x"] * 20), int(r.json["y"] * 20)
    b, g, rr = img[y, x].astype(int)
    assert rr > 180 and g < 60 and b < 60  # the red position dot is drawn at the answer


def test_low_confidence_says_not_sure(built, clip):
    _, api = built
    _, _, spec, conf = clip
    rng = np.random.default_rng(0)
    noise = spec * np.exp(1j * rng.uniform(-np.pi, np.pi, spec.shape)).astype(np.complex64)
    noise = noise[:, :, rng.permutation(spec.shape[2])]  # magnitudes of no place in the venue
    a = api.post("/api/venues/lab/locate", json=encode_json(noise.astype(np.complex64), conf)).json
    assert a["low_confidence"] and a["confidence"] < 0.5
    assert a["sentence"] == "Not sure where you are; turn slowly and try again."
    assert a["accuracy_m"] is None
    # features of nowhere at all: random magnitudes, at unit energy as every record's frames are
    mag = rng.uniform(0, 1, spec.shape)
    mag /= np.sqrt((mag**2).sum(axis=(1, 2), keepdims=True))
    nowhere = (mag * np.exp(1j * rng.uniform(-np.pi, np.pi, spec.shape))).astype(np.complex64)
    a = api.post("/api/venues/lab/locate", json=encode_json(nowhere, conf)).json
    assert a["low_confidence"] and a["confidence"] < 0.5 and a["accuracy_m"] is None


BAD_RECORDS = [
    ("application/json", b"{not json", 400, "not valid JSON"),
    ("application/json", b"[1, 2]", 400, "JSON object"),
    ("application/json", b'{"version": 1, "mag": [[[NaN]]], "phase": [[[0]]]}', 400, "NaN"),
    ("application/octet-stream", b"ONV", 400, "too short"),
    ("application/octet-stream", b"XYZ" + bytes(40), 400, "bad magic"),
    ("text/plain", b"hello", 415, "unsupported Content-Type"),
]


@pytest.mark.parametrize("ctype,body,status,words", BAD_RECORDS)
def test_malformed_locate_bodies_are_refused_with_the_reason(built, ctype, body, status, words):
    _, api = built
    r = api.post("/api/venues/lab/locate", data=body, content_type=ctype)
    assert r.status_code == status and words in r.json["error"], r.json


def test_record_problems_are_named(built, clip):
    _, api = built
    _, _, spec, conf = clip
    rec = encode_json(spec, conf)
    cases = [
        ({**rec, "version": 2}, "version 2"),
        (
            {
                **rec,
                "mag": [[row[:8] for row in f] for f in rec["mag"]],
                "phase": [[row[:8] for row in f] for f in rec["phase"]],
            },
            "harmonics",
        ),
        ({**rec, "settings_id": 1}, "other settings"),
        ({k: v for k, v in rec.items() if k != "phase"}, "missing 'phase'"),
        ({**rec, "pano_width": "wide"}, "pano_width"),
        ({**rec, "fps": 0}, "'fps'"),
        # magnitudes anywhere in [0, 1], not scaled to unit energy (a broken client): such frames
        # would score up to sqrt(C*K) times a perfect match, and used to be answered as sure
        ({**rec, "mag": np.random.default_rng(0).uniform(0, 1, spec.shape).tolist()}, "frame 0 is not at unit energy"),
    ]
    for body, words in cases:
        r = api.post("/api/venues/lab/locate", json=body)
        assert r.status_code == 400 and words in r.json["error"], (words, r.json)
    f, c, k = spec.shape
    huge = json.dumps({**rec, "mag": [[[7.0] * k] * c] * f}).replace("7.0", "1e999", 1)  # parses as inf
    r = api.post("/api/venues/lab/locate", data=huge, content_type="application/json")
    assert r.status_code == 400 and "NaN or Inf" in r.json["error"]
    binary = encode_binary(spec, conf)
    r = api.post("/api/venues/lab/locate", data=binary[:-7], content_type="application/octet-stream")
    assert r.status_code == 400 and "header says" in r.json["error"]
    many = np.concatenate([spec] * 7)
    r = api.post("/api/venues/lab/locate", data=encode_binary(many, conf), content_type="application/octet-stream")
    assert r.status_code == 413 and "too many frames: 70" in r.json["error"]
    r = api.post("/api/venues/lab/locate?fps=-3", json=rec)
    assert r.status_code == 400 and "'fps'" in r.json["error"]


def test_bad_frames_and_videos_are_refused(built, clip):
    _, api = built
    frames, *_ = clip
    r = api.post("/api/venues/lab/locate", data=b"\x00" * 500, content_type="video/mp4")
    assert r.status_code == 422 and "does not decode" in r.json["error"]
    r = api.post("/api/venues/lab/locate", data=b"\x89PNG broken", content_type="image/png")
    assert r.status_code == 422 and "not a readable JPEG or PNG" in r.json["error"]
    small = cv2.imencode(".png", cv2.resize(frames[0], (100, 80)))[1].tobytes()
    r = api.post("/api/venues/lab/locate?lens=donut", data=small, content_type="image/png")
    assert r.status_code == 422 and "100x80" in r.json["error"]
    r = api.post("/api/venues/lab/locate?lens=fisheye", data=small, content_type="image/png")
    assert r.status_code == 404 and "fisheye" in r.json["error"]
    r = api.post("/api/venues/lab/locate", data={"nothing": "here"}, content_type="multipart/form-data")
    assert r.status_code == 400 and "'frame' files" in r.json["error"]


def test_unknown_venue_and_ids_with_path_characters(built):
    _, api = built
    assert api.post("/api/venues/nowhere/locate", json={}).status_code == 404
    assert api.get("/api/venues/nowhere").json["error"] == "unknown venue 'nowhere'"
    r = api.get("/api/venues/..")
    assert r.status_code in (400, 404)
    for bad in ("a..b", "%2e%2e", "x%2Fy", "-lead"):
        r = api.c.get(f"/api/venues/{bad}")
        assert 400 <= r.status_code < 500 and r.is_json and r.json["error"], bad
    r = api.get("/api/venues/lab/floors/..%2F..%2Fsecret/plan.png")
    assert 400 <= r.status_code < 500
    r = api.c.get("/../../etc/passwd")
    assert r.status_code == 404 and r.is_json


def test_an_oversized_locate_body_is_413(small_ds, tmp_path):
    api = Api(make_app(tmp_path, MAX_CONTENT_LENGTH=1000, JOB_RUNNER=False).test_client())
    api.post("/api/admin/venues", json={"id": "v"}, headers=ADMIN)
    r = api.post("/api/venues/v/locate", data=b"x" * 5000, content_type="application/octet-stream")
    assert r.status_code == 413 and "too large" in r.json["error"]


def test_locate_is_rate_limited_per_client(built, clip, tmp_path):
    app = make_app(tmp_path, LOCATE_RATE=1.0, LOCATE_BURST=3, JOB_RUNNER=False)
    # share the modelled venue's files: a second app over the same data directory
    app = make_app(built[0].config["DATA"], LOCATE_RATE=1.0, LOCATE_BURST=3, JOB_RUNNER=False)
    api = Api(app.test_client())
    _, _, spec, conf = clip
    body = encode_binary(spec, conf)
    codes = [
        api.post("/api/venues/lab/locate", data=body, content_type="application/octet-stream").status_code
        for _ in range(5)
    ]
    assert codes[:3] == [200, 200, 200] and codes[3] == 429
    r = api.post("/api/venues/lab/locate", data=body, content_type="application/octet-stream")
    assert int(r.headers["Retry-After"]) >= 1 and "slow down" in r.json["error"]
    other = api.post(
        "/api/venues/lab/locate",
        data=body,
        content_type="application/octet-stream",
        environ_base={"REMOTE_ADDR": "10.0.0.9"},
    )
    assert other.status_code == 200  # another client has its own bucket


def test_no_admin_call_works_without_the_token(built):
    app, api = built
    seen = 0
    for rule in app.url_map.iter_rules():
        if not rule.rule.startswith("/api/admin/"):
            continue
        path = rule.rule
        for arg in rule.arguments:
            path = path.replace(f"<{arg}>", {"venue_id": "lab", "floor": "1", "name": "walk.mp4"}.get(arg, "x"))
        for m in rule.methods - {"HEAD", "OPTIONS"}:
            for headers, code in (
                ({}, 401),
                ({"Authorization": "Bearer wrong"}, 403),
                ({"Authorization": "Basic x"}, 401),
            ):
                r = api.open(path, method=m, headers=headers, json={})
                assert r.status_code == code, (m, path, r.status_code)
                seen += 1
    assert seen >= 3 * 23  # every admin method of every admin route (23 before the analysis jobs came)
    assert api.get("/api/admin/venues/lab/videos", headers=ADMIN).status_code == 200


def test_admin_edits_venue_floors_places_and_lenses(built, small_ds):
    _, api = built
    assert api.post("/api/admin/venues", json={"id": "lab"}, headers=ADMIN).status_code == 409
    r = api.post("/api/admin/venues", json={"id": "b/c"}, headers=ADMIN)
    assert r.status_code == 400 and "invalid venue id" in r.json["error"]
    assert api.post("/api/admin/venues", json={"id": "x", "preset": "magic"}, headers=ADMIN).status_code == 400
    assert api.patch("/api/admin/venues/lab", json={"name": "The Lab"}, headers=ADMIN).json["name"] == "The Lab"
    r = api.put("/api/admin/venues/lab/floors/2", json={"px_per_m": 25}, headers=ADMIN)
    assert r.json == {"id": "2", "name": "Floor 2", "plan_url": None, "plan_size_px": None, "px_per_m": 25.0}
    r = api.put(
        "/api/admin/venues/lab/floors/2", json={"scale": {"a": [0, 0], "b": [0, 0], "distance_m": 3}}, headers=ADMIN
    )
    assert r.status_code == 400 and "must differ" in r.json["error"]
    r = api.put("/api/admin/venues/lab/floors/2/plan", data=b"GIF89a", headers=ADMIN, content_type="image/gif")
    assert r.status_code == 415
    r = api.put("/api/admin/venues/lab/floors/2/plan", data=b"\x89PNG nope", headers=ADMIN, content_type="image/png")
    assert r.status_code == 422 and "not a readable PNG or JPEG" in r.json["error"]
    r = api.post("/api/admin/venues/lab/places", json={"name": "Kiosk", "floor": "2", "x": 1, "y": 2}, headers=ADMIN)
    assert r.status_code == 201
    kiosk = next(p for p in r.json["places"] if p["name"] == "Kiosk")
    r = api.post(
        "/api/admin/venues/lab/places", json=[{"name": "Nowhere", "floor": "9", "x": 1, "y": 2}], headers=ADMIN
    )
    assert r.status_code == 400 and "no floor '9'" in r.json["error"]
    r = api.post(
        "/api/admin/venues/lab/places", json={"name": "Hall", "x": 1, "y": 2, "area": [3, 3, 1, 1]}, headers=ADMIN
    )
    assert r.status_code == 400 and "x0 < x1" in r.json["error"]
    # a place keeps its kind and the sentence to say on arrival (docs/formats.md); others are refused
    lift = {"name": "Lift lobby", "x": 3, "y": 1, "kind": "lift", "say": "The lifts are on your right."}
    r = api.post("/api/admin/venues/lab/places", json=lift, headers=ADMIN)
    assert r.status_code == 201
    got = next(p for p in api.get("/api/venues/lab").json["places"] if p["name"] == "Lift lobby")
    assert got["kind"] == "lift" and got["say"] == "The lifts are on your right."
    assert "kind" not in kiosk and "say" not in kiosk
    r = api.post("/api/admin/venues/lab/places", json={**lift, "kind": "lobby"}, headers=ADMIN)
    assert r.status_code == 400 and "'kind' must be one of room, door" in r.json["error"]
    r = api.post("/api/admin/venues/lab/places", json={**lift, "say": "x" * 501}, headers=ADMIN)
    assert r.status_code == 400 and "'say'" in r.json["error"]
    assert api.delete(f"/api/admin/venues/lab/places/{kiosk['id']}", headers=ADMIN).status_code == 204
    assert api.delete(f"/api/admin/venues/lab/places/{kiosk['id']}", headers=ADMIN).status_code == 404
    r = api.put("/api/admin/venues/lab/lenses/bad", json={"model": "pinhole"}, headers=ADMIN)
    assert r.status_code == 400 and "pinhole" in r.json["error"]
    r = api.put("/api/admin/venues/lab/floors/1", data="{", headers=ADMIN, content_type="application/json")
    assert r.status_code == 400 and "not valid JSON" in r.json["error"]
    assert api.put("/api/admin/venues/lab/floors/1", data="x", headers=ADMIN).status_code == 415


def test_video_uploads_refuse_bad_input_and_lose_nothing(built, small_ds):
    _, api = built
    walk_path = json.loads(small_ds.model_walk_path.read_text())
    base = {"name": "v2.mp4", "floor": "1", "size": 1000, "walk_path": walk_path, "lens": "donut"}
    outside = {**walk_path, "waypoints": [*walk_path["waypoints"][:-1], {**walk_path["waypoints"][-1], "x": 99.0}]}
    cases = [
        ({**base, "walk_path": outside}, 422, "outside the floor plan"),
        ({**base, "size": 10**12}, 413, "limit"),
        ({**base, "size": -1}, 400, "'size'"),
        ({**base, "name": "../evil.mp4"}, 400, "invalid video name"),
        ({**base, "name": "a/b.mp4"}, 400, "invalid video name"),
        ({**base, "lens": "fisheye"}, 404, "fisheye"),
        ({**base, "floor": "7"}, 404, "no floor '7'"),
        ({**base, "walk_path": {"fps": 30, "waypoints": [{"frame": 0, "x": 1, "y": 1}]}}, 400, "at least two"),
    ]
    for body, code, words in cases:
        r = api.post("/api/admin/venues/lab/videos", json=body, headers=ADMIN)
        assert r.status_code == code and words in r.json["error"], (body.get("name"), r.json)
    # a file that is not a video: refused when its last byte arrives, and nothing else changes
    frames_before = api.get("/api/venues/lab").json["frames"]
    junk = bytes(range(256)) * 8
    assert api.post("/api/admin/venues/lab/videos", json={**base, "size": len(junk)}, headers=ADMIN).status_code == 201
    r = upload(api, "lab", "v2.mp4", junk)
    assert r.status_code == 422 and "not accepted" in r.json["error"] and r.json["received"] == 0
    assert api.get("/api/admin/venues/lab/videos/v2.mp4", headers=ADMIN).json["status"] == "uploading"
    # resumable: a piece that does not start where the upload stands is refused with where it stands
    r = api.put(
        "/api/admin/venues/lab/videos/v2.mp4/content",
        data=junk[100:200],
        headers={**ADMIN, "Content-Range": f"bytes 100-199/{len(junk)}"},
    )
    assert r.status_code == 409 and r.json["received"] == 0
    r = api.put(
        "/api/admin/venues/lab/videos/v2.mp4/content", data=junk[:10], headers={**ADMIN, "Content-Range": "bytes 0-9/5"}
    )
    assert r.status_code == 400 and "declared size" in r.json["error"]
    r = api.put("/api/admin/venues/lab/videos/v2.mp4/content", data=junk + b"more", headers=ADMIN)
    assert r.status_code == 413 and "larger than" in r.json["error"]
    r = api.put(
        "/api/admin/venues/lab/videos/v2.mp4/content", data=junk[:10], headers={**ADMIN, "Content-Range": "bits"}
    )
    assert r.status_code == 400
    assert api.post("/api/admin/venues/lab/jobs", json={"videos": ["v2.mp4"]}, headers=ADMIN).status_code == 409
    assert api.post("/api/admin/venues/lab/jobs", json={"videos": ["ghost.mp4"]}, headers=ADMIN).status_code == 404
    assert api.post("/api/admin/venues/lab/jobs", json={"videos": "walk.mp4"}, headers=ADMIN).status_code == 400
    assert api.get("/api/venues/lab").json["frames"] == frames_before
    assert api.delete("/api/admin/venues/lab/videos/v2.mp4", headers=ADMIN).json["frames_removed"] == 0


def test_a_video_that_ends_before_its_walk_path_starts_fails_its_job_and_keeps_the_frames(built, small_ds, clip):
    _, api = built
    walk_path = json.loads(small_ds.model_walk_path.read_text())
    late = {**walk_path, "waypoints": [{**w, "t": w["t"] + 10000.0} for w in walk_path["waypoints"]]}
    data = add_video(api, "lab", "late.mp4", small_ds, walk_path=late)
    assert upload(api, "lab", "late.mp4", data).status_code == 200
    before = api.get("/api/venues/lab").json["frames"]
    job = wait_job(api, api.post("/api/admin/venues/lab/jobs", headers=ADMIN).json["id"])
    assert job["state"] == "failed" and "walk path starts after the video ends" in job["error"]
    assert api.get("/api/venues/lab").json["frames"] == before
    _, truth, spec, conf = clip
    assert_near(api.post("/api/venues/lab/locate", json=encode_json(spec, conf)).json, truth)
    assert api.delete("/api/admin/venues/lab/videos/late.mp4", headers=ADMIN).status_code == 200


def test_jobs_report_progress_by_polling_and_server_sent_events(small_ds, tmp_path):
    app = make_app(tmp_path)
    api = Api(app.test_client())
    api.post("/api/admin/venues", json={"id": "v"}, headers=ADMIN)
    api.put("/api/admin/venues/v/floors/1", json={"px_per_m": 20}, headers=ADMIN)
    api.put(
        "/api/admin/venues/v/floors/1/plan",
        data=small_ds.floorplan.read_bytes(),
        headers=ADMIN,
        content_type="image/png",
    )
    lens = json.loads((small_ds.root / "model_lens.json").read_text())
    data = add_video(api, "v", "walk.mp4", small_ds, lens=lens)  # an inline lens profile
    upload(api, "v", "walk.mp4", data)
    job = api.post("/api/admin/venues/v/jobs", json={"videos": ["walk.mp4"]}, headers=ADMIN).json
    r = api.get(f"/api/admin/jobs/{job['id']}/events", headers=ADMIN)
    assert r.mimetype == "text/event-stream"
    events = [
        (b.split("\n")[0].removeprefix("event: "), json.loads(b.split("\n")[1].removeprefix("data: ")))
        for b in r.get_data(as_text=True).strip().split("\n\n")
        if b.startswith("event:")
    ]
    kinds = [k for k, _ in events]
    assert kinds[-1] == "done" and set(kinds[:-1]) <= {"progress"}
    last = events[-1][1]
    assert last["frames_done"] == last["frames_total"] > 100 and last["frames_per_s"] > 0
    assert api.get(f"/api/admin/jobs/{job['id']}", headers=ADMIN).json["state"] == "done"
    assert api.get("/api/admin/venues/v/jobs", headers=ADMIN).json["jobs"][0]["id"] == job["id"]
    assert api.get("/api/admin/venues/v/videos/walk.mp4", headers=ADMIN).json["status"] == "modelled"
    assert api.post("/api/admin/venues/v/jobs", headers=ADMIN).status_code == 409  # nothing left to model
    assert api.post(f"/api/admin/jobs/{job['id']}/cancel", headers=ADMIN).status_code == 409
    assert api.get("/api/admin/jobs/nope", headers=ADMIN).status_code == 404
    # deleting the video deletes its frames: the venue no longer answers
    r = api.delete("/api/admin/venues/v/videos/walk.mp4", headers=ADMIN)
    assert r.json["frames_removed"] == last["frames_total"]
    assert api.post("/api/venues/v/locate", json={}).status_code == 409
    assert api.get("/api/venues/v").json["frames"] == 0


def test_cancelling_a_job_keeps_the_venue_as_it_was(built, small_ds, clip):
    """A queued job is cancelled at once; a running one at its next frame; neither writes frames."""
    # the built app's runner shares the database and would claim the job queued here (it looks
    # every second: a race that PostgreSQL's rerun lost once); this test plays the runner itself
    runner = built[0].extensions["omninav"].jobs
    runner.stop(10.0)
    try:
        _cancel_a_queued_and_a_running_job(built, small_ds)
    finally:
        runner.start()


def _cancel_a_queued_and_a_running_job(built, small_ds):
    app = make_app(built[0].config["DATA"], JOB_RUNNER=False)
    api = Api(app.test_client())
    jobs = app.extensions["omninav"].jobs
    store = app.extensions["omninav"].catalog.store
    gen = store.generation("lab")
    data = add_video(api, "lab", "again.mp4", small_ds)
    upload(api, "lab", "again.mp4", data)
    j = api.post("/api/admin/venues/lab/jobs", json={"videos": ["again.mp4"]}, headers=ADMIN).json
    r = api.post(f"/api/admin/jobs/{j['id']}/cancel", headers=ADMIN)
    assert r.status_code == 202 and r.json["state"] == "cancelled"
    j = api.post("/api/admin/venues/lab/jobs", json={"videos": ["again.mp4"]}, headers=ADMIN).json
    claimed = jobs.claim()
    assert claimed["id"] == j["id"]
    assert api.get(f"/api/admin/jobs/{j['id']}", headers=ADMIN).json["state"] == "running"
    assert api.delete("/api/admin/venues/lab/videos/again.mp4", headers=ADMIN).status_code == 409
    assert api.post(f"/api/admin/jobs/{j['id']}/cancel", headers=ADMIN).json["state"] == "running"
    jobs._run(claimed)  # the runner sees the flag at its first progress report
    assert api.get(f"/api/admin/jobs/{j['id']}", headers=ADMIN).json["state"] == "cancelled"
    assert store.generation("lab") == gen
    assert api.delete("/api/admin/venues/lab/videos/again.mp4", headers=ADMIN).json["frames_removed"] == 0


def test_the_web_app_is_served_gzipped_to_browsers_that_accept_it(tmp_path):
    import gzip

    dist = tmp_path / "dist"
    (dist / "assets").mkdir(parents=True)
    (dist / "index.html").write_text("<!doctype html><html><title>app</title></html>")
    big = b"const x = 1;\n" * 5000
    (dist / "assets" / "worker-1.js").write_bytes(big)
    (dist / "assets" / "worker-1.js.gz").write_bytes(gzip.compress(big))
    client = make_app(tmp_path, WEB_DIST=str(dist)).test_client()

    def get(path, **kw):  # file responses stream: read and close them
        r = client.get(path, **kw)
        r.get_data()
        r.close()
        return r

    r = get("/assets/worker-1.js", headers={"Accept-Encoding": "gzip, deflate, br"})
    assert r.status_code == 200 and r.headers["Content-Encoding"] == "gzip"
    assert r.mimetype in ("text/javascript", "application/javascript") and "Accept-Encoding" in r.headers["Vary"]
    assert gzip.decompress(r.data) == big and "Content-Disposition" not in r.headers
    r = get("/assets/worker-1.js")  # a client that does not accept gzip gets the plain file
    assert r.status_code == 200 and "Content-Encoding" not in r.headers and r.data == big
    r = get("/")
    assert r.status_code == 200 and b"<title>app" in r.data and r.cache_control.max_age == 0
    r = get("/assets/nothing.js", headers={"Accept-Encoding": "gzip"})
    assert r.status_code == 404 and r.is_json
    assert get("/assets/../../etc/passwd", headers={"Accept-Encoding": "gzip"}).status_code == 404


def test_the_app_knows_every_feature_key():
    """The app refuses a venue whose records depend on a key it does not know (record.ts): its list
    must hold every key the engine has, or a venue modelled with a new one would be answered from
    curves made without it."""
    ts = (Path(__file__).resolve().parents[2] / "web" / "src" / "shared" / "settings.ts").read_text()
    block = re.search(r"KNOWN_FEATURE_KEYS: readonly \(keyof FeatureSettings\)\[\] = \[(.*?)\];", ts, re.S)
    assert block, "settings.ts no longer declares KNOWN_FEATURE_KEYS"
    assert re.findall(r"'(\w+)'", block.group(1)) == list(FEATURE_KEYS)
    # the venue document lists the later keys only where set: a venue modelled before them is
    # served to apps that predate them too
    assert "level_iters" not in feature_keys({**resolve("default"), "level_iters": None})
    assert feature_keys(resolve("default")) == sorted(FEATURE_KEYS)
