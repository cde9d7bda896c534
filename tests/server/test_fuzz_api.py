"""Schema-driven fuzzing of the whole HTTP API (schemathesis) against the real Flask app.

Every operation in openapi.yaml is called with requests generated from its schema, valid and
invalid, through the in-process WSGI app on a real SQLite database and data directory. Before the
fuzzing a small venue is built through the API (floor plan and scale, a second floor, places, a
lens, a video modelled by a job, one half uploaded), put back before each operation, and most
generated path parameters are pointed at those real objects (`_aim`), so that requests reach the
handlers' validation instead of stopping at "unknown venue". Each response must: not be a 5xx, have
a status code and content type the spec documents, and match the spec's schema for that status; and
valid data may be refused only for a reason JSON Schema cannot state (CANNOT_STATE).
"""

from __future__ import annotations

import time
import zlib
from typing import Any

import cv2
import hypothesis
import numpy as np
import pytest
import schemathesis
from schemathesis.checks import not_a_server_error
from schemathesis.core.parameters import ParameterLocation
from schemathesis.generation import GenerationMode
from schemathesis.specs.openapi.checks import (
    content_type_conformance,
    response_schema_conformance,
    status_code_conformance,
)

from omninav.extract import Extractor
from omninav.lens import lens_from_dict
from omninav.server import create_app
from omninav.server.venues_api import openapi_doc
from omninav.spectrum import encode_binary, encode_json
from omninav.synth.walks import write_video
from server_helpers import ADMIN, TOKEN

VENUE = "hall"
PLAN_PX = (400, 200)  # 20 x 10 m at 20 px/m
LENS = {"model": "equirectangular", "image_size": [360, 180], "forward_x": 180, "ccw": False}
CHECKS = [not_a_server_error, status_code_conformance, content_type_conformance, response_schema_conformance]
MAX_EXAMPLES = 25

schemathesis.serializer.alias("video/mp4", "application/octet-stream")  # a video body is raw bytes
schema = schemathesis.openapi.from_dict(openapi_doc())
# the admin token goes with every request (below); generated Authorization headers would replace it
schema.config.generation.update(max_examples=MAX_EXAMPLES, deterministic=True, with_security_parameters=False)


def _walk_video(path: Any, n: int = 30) -> bytes:
    """A tiny equirectangular clip: a seeded random panorama turning 3 degrees a frame."""
    rng = np.random.default_rng(7)
    pano = cv2.resize(rng.integers(0, 255, (18, 36, 3), dtype=np.uint8), (360, 180), interpolation=cv2.INTER_CUBIC)
    write_video(path, (np.roll(pano, 3 * i, axis=1) for i in range(n)), 10.0, (360, 180))
    return path.read_bytes()


def _ok(r: Any, status: int = 200) -> Any:
    assert r.status_code == status, r.get_json()
    return r.get_json()


PLACES = [{"name": "Room 1", "x": 3, "y": 4, "area": [1, 1, 5, 6]}, {"name": "lifts", "floor": "2", "x": 5, "y": 5}]
WALK_PATH = {"fps": 10, "waypoints": [{"frame": 0, "x": 2, "y": 5}, {"frame": 29, "x": 8, "y": 5}]}


@pytest.fixture(scope="module")
def fuzz_app(tmp_path_factory: pytest.TempPathFactory) -> Any:
    """The app with venue 'hall' built through the API and modelled from a tiny video; then its job
    runner stops, so that jobs the fuzzer queues stay queued (no modelling runs while it fuzzes)."""
    tmp = tmp_path_factory.mktemp("fuzz")
    app = create_app({"DATA": str(tmp / "data"), "ADMIN_TOKEN": TOKEN, "LOCATE_RATE": 0.0, "VENUE_CACHE_S": 0.0})
    app.config["FUZZ_VIDEO"] = _walk_video(tmp / "walk.mp4")
    app.config["FUZZ_PATH"] = tmp / "walk.mp4"
    c = app.test_client()
    _ok(c.post("/api/admin/venues", json={"id": VENUE, "name": "Hall"}, headers=ADMIN), 201)
    _ok(c.post("/api/admin/venues", json={"id": "empty"}, headers=ADMIN), 201)
    _restock(app)
    base = f"/api/admin/venues/{VENUE}"
    job = _ok(c.post(f"{base}/jobs", json={"videos": ["walk.mp4"]}, headers=ADMIN), 201)
    t0 = time.time()
    while _ok(c.get(f"/api/admin/jobs/{job['id']}", headers=ADMIN))["state"] in ("queued", "running"):
        assert time.time() - t0 < 60, "the tiny modelling job did not end"
        time.sleep(0.05)
    assert _ok(c.get(f"/api/venues/{VENUE}"))["modelled"]
    app.extensions["omninav"].jobs.stop()
    return app


def _restock(app: Any) -> None:
    """Put back what the fuzzer may have changed or deleted, so that every operation starts from
    the same venue: floors 1 (plan, 20 px/m) and 2, two places, the lens, and videos in each state
    (walk.mp4 ready or modelled, b.mp4 half uploaded)."""
    c, base = app.test_client(), f"/api/admin/venues/{VENUE}"
    for vid in (VENUE, "empty"):  # the fuzzer may have deleted a venue: it comes back (unmodelled)
        if c.get(f"/api/venues/{vid}").status_code == 404:
            _ok(c.post("/api/admin/venues", json={"id": vid}, headers=ADMIN), 201)
    png = cv2.imencode(".png", np.full((PLAN_PX[1], PLAN_PX[0], 3), 255, np.uint8))[1].tobytes()
    _ok(c.put(f"{base}/floors/1/plan", data=png, headers=ADMIN, content_type="image/png"))
    _ok(c.put(f"{base}/floors/1", json={"name": "Ground", "px_per_m": 20}, headers=ADMIN))
    _ok(c.put(f"{base}/floors/2", json={"name": "First"}, headers=ADMIN))
    _ok(c.put(f"{base}/lenses/default", json=LENS, headers=ADMIN))
    if len(_ok(c.get(f"/api/venues/{VENUE}"))["places"]) < len(PLACES):
        _ok(c.put(f"{base}/places", json=PLACES, headers=ADMIN))
    data = app.config["FUZZ_VIDEO"]
    have = {v["name"]: v for v in _ok(c.get(f"{base}/videos", headers=ADMIN))["videos"]}
    if have.get("walk.mp4", {}).get("status") in (None, "uploading"):
        _announce_and_send(c, "walk.mp4", data, len(data))
    b = have.get("b.mp4", {})
    if b.get("status") != "uploading" or not b.get("received"):
        _announce_and_send(c, "b.mp4", data, len(data) // 2)


def _announce_and_send(c: Any, name: str, data: bytes, n: int) -> None:
    """POST the video and PUT its first n bytes (all: it becomes ready; fewer: still uploading)."""
    base = f"/api/admin/venues/{VENUE}"
    r = c.post(f"{base}/videos", json={"name": name, "size": len(data), "walk_path": WALK_PATH}, headers=ADMIN)
    if r.status_code == 409:  # a job that the fuzzer queued holds it: leave it so
        return
    _ok(r, 201)
    head = {**ADMIN, "Content-Range": f"bytes 0-{n - 1}/{len(data)}"}
    url = f"{base}/videos/{name}/content"
    _ok(
        c.put(url, data=data[:n], headers=head, content_type="application/octet-stream"), 200 if n == len(data) else 202
    )


def _real_ids(app: Any, venue: str, path: str) -> dict[str, list[str]]:
    """Ids of objects of `venue` that exist now, by path-parameter name."""
    db = app.extensions["omninav"].db
    table = "videos" if "/videos/" in path else "lenses"
    return {
        "floor": ["1", "2"],
        "name": [r["name"] for r in db.all(f"SELECT name FROM {table} WHERE venue = :v ORDER BY name", v=venue)],
        "place_id": [r["id"] for r in db.all("SELECT id FROM places WHERE venue = :v ORDER BY id", v=venue)],
        "job_id": [r["id"] for r in db.all("SELECT id FROM jobs ORDER BY created")],
    }


def _aim(app: Any, case: Any) -> None:
    """Point most path parameters (3 in 4, chosen by a hash of the generated case, so reproducibly)
    at real objects of the venue; the rest stay as generated, so "unknown id" paths get fuzzed too.
    A case whose path is the deliberately invalid part (negative mode) keeps it. Done here, when the
    case runs, not in a schemathesis hook: coverage-phase cases are made before any fixture runs."""
    params = case.path_parameters
    if not params or case.meta.is_negative_at(ParameterLocation.PATH):
        return
    h = zlib.crc32(repr((params, case.body, case.query)).encode())
    if "venue_id" in params and h % 4:
        params["venue_id"] = (VENUE, VENUE, "empty")[h % 3]
    real = _real_ids(app, params.get("venue_id", VENUE), case.operation.path)
    for key in params:
        h = zlib.crc32(repr((key, h)).encode())
        if real.get(key) and h % 4:
            params[key] = real[key][h % len(real[key])]


def _served(app: Any) -> Any:
    """The app as a WSGI server runs it: the body read whole and the iterable closed (send_file's
    file handle), except that an event stream is cut after its first event (a queued job's stream
    only ends when the job does, and no job runs here)."""

    def wsgi(environ: dict[str, Any], start_response: Any) -> list[bytes]:
        sent: list[tuple[str, str]] = []

        def start(status: str, headers: list[tuple[str, str]], exc_info: Any = None) -> Any:
            sent[:] = headers
            return start_response(status, headers, exc_info)

        body = app(environ, start)
        try:
            stream = any(k.lower() == "content-type" and v.startswith("text/event-stream") for k, v in sent)
            return [next(iter(body), b"")] if stream else [b"".join(body)]
        finally:
            if hasattr(body, "close"):
                body.close()

    return wsgi


@pytest.fixture
def live(fuzz_app: Any) -> Any:
    """The app, restocked before each operation is fuzzed."""
    _restock(fuzz_app)
    return fuzz_app


@pytest.mark.parametrize("media_type", ["application/json", "application/octet-stream"])
def test_a_real_clip_is_answered_as_the_spec_says(fuzz_app: Any, media_type: str) -> None:
    """The one answer random data never reaches: a record of the venue's own walk is located, and
    the 200 answer (with the annotated plan) passes the same checks as every fuzzed response. It
    runs before the fuzzing, which may delete the modelled video."""
    _restock(fuzz_app)
    conf = fuzz_app.extensions["omninav"].catalog.venues.settings(VENUE)
    video = cv2.VideoCapture(str(fuzz_app.config["FUZZ_PATH"]))
    frames = [video.read()[1] for _ in range(10)]
    video.release()
    spec = Extractor(lens_from_dict(LENS), conf).spectra(frames)
    body = encode_json(spec, conf) if media_type == "application/json" else encode_binary(spec, conf)
    op = schema["/api/venues/{venue_id}/locate"]["POST"]
    case = op.Case(path_parameters={"venue_id": VENUE}, query={"plan": "1"}, body=body, media_type=media_type)
    r = case.call_and_validate(app=_served(fuzz_app), checks=CHECKS)
    assert r.status_code == 200 and r.json()["sent"] == "features" and r.json()["plan_png"].startswith("data:")


# Why a request that the spec allows may still be refused with 400: what JSON Schema cannot say
# (one field against another, or against the venue's state). Any other 400 to valid data means the
# spec allows something the server refuses: state it in openapi.yaml.
CANNOT_STATE = (
    "must differ",  # floor scale: the two points
    "finite number of pixels",  # floor scale: 1e308 px over 1e-300 m
    "x0 < x1",  # place area corners
    "has no floor",  # a place on a floor the venue lacks
    "r_inner < r_outer",
    "not monotonic",  # lens elevation polynomial
    "overflows",
    "increasing time",  # walk path waypoints
    "must both be",  # a feature record's 'mag' and 'phase' have one shape
    "this venue needs",  # a feature record for other settings than the venue's
    "other settings",
    "declared size",  # Content-Range: its total must be the size the video was announced with
    "feature record",  # a binary body is "bytes" to the spec; the record's layout is in its description
    "needs a tracking 'session'",  # locate's ?to= without ?session=
)


@schema.parametrize()
# `live` restocks once per operation, not per example, on purpose: examples of one operation meet
# what the previous ones did (a deleted place, a cancelled job), as a real client sequence would
@hypothesis.settings(
    max_examples=MAX_EXAMPLES,
    derandomize=True,
    deadline=None,
    database=None,
    suppress_health_check=[hypothesis.HealthCheck.function_scoped_fixture],
)
def test_api_fuzz(case: Any, live: Any) -> None:
    """No request takes the server down or gets an undocumented answer; valid data is refused only
    for a reason the spec cannot state."""
    _aim(live, case)
    r = case.call_and_validate(app=_served(live), headers=ADMIN, checks=CHECKS)
    if case.meta.generation.mode is GenerationMode.POSITIVE and not any(
        case.meta.is_negative_at(loc) for loc in case.meta.components
    ):
        assert r.status_code != 415, (case.operation.label, r.text)
        if r.status_code == 400:
            msg = r.json()["error"]
            assert any(why in msg for why in CANNOT_STATE), f"{case.operation.label}: valid data refused: {msg}"
