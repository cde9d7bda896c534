"""The locate endpoint and clip length: 50-frame records taken, a longer clip refused with a 413
that says why (before any frame is decoded), a video timed by its own frame rate."""

from __future__ import annotations

import io
import json
import shutil

import cv2
import numpy as np
import pytest

from omninav.locate import Locator
from omninav.server import create_app
from omninav.spectrum import encode_binary, encode_json
from server_helpers import TOKEN, Api, clip_spectra, query_clip


@pytest.fixture(scope="module")
def loc(modelled) -> Locator:
    st, vid = modelled
    return Locator(st, vid, device="cpu")


@pytest.fixture(scope="module")
def api(modelled, small_ds, tmp_path_factory) -> Api:
    st, _ = modelled
    data = tmp_path_factory.mktemp("cliplen") / "data"
    shutil.copytree(st.root, data)
    app = create_app({"DATA": str(data), "ADMIN_TOKEN": TOKEN, "JOB_RUNNER": False, "LOCATE_RATE": 0.0})
    cat = app.extensions["omninav"].catalog
    cat.venues.create("lab", "Lab")
    cat.floors.set_plan("lab", "1", small_ds.floorplan.read_bytes())
    cat.floors.put("lab", "1", {"px_per_m": 20.0})
    cat.lenses.put("lab", "donut", json.loads((small_ds.root / "model_lens.json").read_text()))
    return Api(app.test_client())


@pytest.fixture(scope="module")
def five_s(small_ds, loc) -> tuple[np.ndarray, tuple[float, float, float]]:
    frames, truth = query_clip(small_ds, 60, n=51)
    return clip_spectra(small_ds, frames, loc.conf), truth


def post(api: Api, body: bytes, query: str = "") -> dict:
    r = api.post(f"/api/venues/lab/locate{query}", data=body, content_type="application/octet-stream")
    return {"status": r.status_code, **r.json}


def test_the_server_answers_a_five_second_record(api, five_s, loc):
    spec, truth = five_s
    a = post(api, encode_binary(spec[1:], loc.conf))
    assert a["status"] == 200 and a["frames"] == 50, a
    assert np.hypot(a["x"] - truth[0], a["y"] - truth[1]) <= 2.0, (a, truth)
    r = api.post("/api/venues/lab/locate", json={**encode_json(spec[1:], loc.conf), "fps": 10})
    assert r.status_code == 200 and r.json["frames"] == 50


def test_a_longer_clip_is_refused_with_its_length(api, five_s, loc):
    spec, _ = five_s
    a = post(api, encode_binary(spec, loc.conf))
    assert a["status"] == 413 and "5.1 s long (51 frames at 10 frames/s)" in a["error"], a
    assert "at most 5 s" in a["error"]
    r = api.post("/api/venues/lab/locate", json={**encode_json(spec[1:], loc.conf), "fps": 8})
    assert r.status_code == 413 and "6.25 s long" in r.json["error"]
    # the same 51 frames filmed faster are 2.55 s: taken
    assert post(api, encode_binary(spec, loc.conf), "?fps=20")["status"] == 200


def test_frames_for_a_longer_clip_are_refused_before_any_is_decoded(api, small_ds):
    frames, _ = query_clip(small_ds, 60, n=1)
    png = cv2.imencode(".png", frames[0])[1].tobytes()
    files = [(io.BytesIO(png[:64] + b"\0" * 10), f"f{i}.png") for i in range(51)]  # cut short: never decoded
    r = api.post("/api/venues/lab/locate?lens=donut", data={"frame": files}, content_type="multipart/form-data")
    assert r.status_code == 413 and "51 frames" in r.json["error"], r.json


def test_a_video_is_timed_by_itself_not_by_the_fps_argument(api, small_ds, tmp_path):
    """A 3 s video sent with a wrong ?fps=5: its own 10 fps times its frames (at 5 fps it would
    be a 6 s clip, refused)."""
    from omninav.synth.walks import write_video

    frames, truth = query_clip(small_ds, 60, n=30)
    path = tmp_path / "clip.mp4"
    write_video(path, frames, 10.0, (frames[0].shape[1], frames[0].shape[0]))
    r = api.post("/api/venues/lab/locate?lens=donut&fps=5", data=path.read_bytes(), content_type="video/mp4")
    assert r.status_code == 200 and r.json["frames"] == 30, r.json
    assert np.hypot(r.json["x"] - truth[0], r.json["y"] - truth[1]) <= 2.0


def test_a_verified_venue_checks_clips_sent_as_video_frames_or_a_record_with_local_features(
    verified, wrong_global, small_ds, tmp_path
):
    """A venue with the `verified` preset, every clip's global answer made wrong: a video, frames,
    and a version-2 record (binary and JSON: the last frame's local features) are moved to where
    the clip was filmed, said at 0.75, and say so (`verified`); a version-1 record, which carries
    none, keeps the global (wrong) answer, not verified."""
    from omninav.lens import load_lens
    from omninav.spectrum import encode_binary, encode_json
    from omninav.synth.walks import write_video
    from omninav.verify import MOVED_CONFIDENCE

    frames, (tx, ty, _), _ = wrong_global
    data = tmp_path / "data"
    shutil.copytree(verified[0].root, data)
    app = create_app({"DATA": str(data), "ADMIN_TOKEN": TOKEN, "JOB_RUNNER": False, "LOCATE_RATE": 0.0})
    cat = app.extensions["omninav"].catalog
    cat.venues.create("lab", "Lab", preset="verified")
    cat.lenses.put("lab", "donut", json.loads((small_ds.root / "model_lens.json").read_text()))
    api = Api(app.test_client())

    def moved(r) -> bool:
        assert r.status_code == 200, r.json
        near = np.hypot(r.json["x"] - tx, r.json["y"] - ty) < 1.0
        return bool(near and r.json["confidence"] == MOVED_CONFIDENCE and r.json["verified"] == "moved")

    path = tmp_path / "clip.mp4"
    write_video(path, frames, 10.0, (frames[0].shape[1], frames[0].shape[0]))
    assert moved(api.post("/api/venues/lab/locate?lens=donut", data=path.read_bytes(), content_type="video/mp4"))
    jpgs = [(io.BytesIO(cv2.imencode(".jpg", f)[1].tobytes()), f"{i}.jpg") for i, f in enumerate(frames)]
    assert moved(api.post("/api/venues/lab/locate?lens=donut", data={"frame": jpgs}))
    conf = cat.venues.settings("lab")
    spec = clip_spectra(small_ds, frames, conf)
    local = Locator(*verified).local_features(frames[-1], load_lens(small_ds.lens))
    body = encode_binary(spec, conf, local)
    assert len(body) - len(encode_binary(spec, conf)) <= 32 * 1024  # the local block's budget
    assert moved(api.post("/api/venues/lab/locate", data=body, content_type="application/octet-stream"))
    r = api.post(
        "/api/venues/lab/locate", data=json.dumps(encode_json(spec, conf, local)), content_type="application/json"
    )
    assert moved(r)
    plain = api.post("/api/venues/lab/locate", data=encode_binary(spec, conf), content_type="application/octet-stream")
    assert plain.status_code == 200 and "verified" not in plain.json
    assert np.hypot(plain.json["x"] - tx, plain.json["y"] - ty) > 5.0
