"""A venue modelled before its preset improved is brought up to date by a modelling anew (issue 13:
the held-out accuracy the softly clipped curves bring reaches a venue only with its frames made
anew). Through the real Flask app on a real database, a real video decoded, every response checked
against openapi.yaml: the admin's venue document says the live frames' settings are not the
preset's; a plain modelling keeps the venue's settings (frames made otherwise could not be searched
together); `anew` models every modelling video with the preset as it is now, the venue answering
from its old frames until the new generation is complete, and a cancelled one changing nothing; a
phone that still sends the old settings' features gets a 400 that names the venue's settings now.
"""

from __future__ import annotations

import json
from typing import Any

import numpy as np
import pytest

from omninav import presets
from omninav.lens import load_lens
from omninav.model_venue import model_video
from omninav.presets import resolve, settings_id
from omninav.spectrum import encode_binary
from omninav.walk_path import load_walk_path
from server_helpers import ADMIN, Api, clip_spectra, heading_error, query_clip
from test_jobs import job, prepared
from test_server import add_video, upload

OCTET = "application/octet-stream"
QUERY_AT = 100  # the query walk's frame a clip starts at


def admin_doc(api: Api) -> dict[str, Any]:
    r = api.get("/api/admin/venues/lab", headers=ADMIN)
    assert r.status_code == 200, r.json
    return r.json


def record_for(small_ds: Any, conf: dict[str, Any]) -> tuple[bytes, tuple[float, float, float]]:
    frames, truth = query_clip(small_ds, QUERY_AT)
    return encode_binary(clip_spectra(small_ds, frames, conf), conf), truth


def locate(api: Api, record: bytes) -> Any:
    return api.post("/api/venues/lab/locate", data=record, content_type=OCTET)


@pytest.fixture(scope="module")
def old_lab(small_ds: Any, tmp_path_factory: pytest.TempPathFactory) -> tuple[Any, Api, dict[str, Any]]:
    """Venue 'lab' modelled from walk.mp4 as an omninav from before the soft clipping did: the
    default preset without it (and so in its two bands, 12 curves), a settings.json without
    either key, and the confidence model that was the default then."""
    app, api = prepared(small_ds, tmp_path_factory.mktemp("anew"))
    runner, store = app.extensions["omninav"].jobs, app.extensions["omninav"].catalog.store
    with pytest.MonkeyPatch.context() as m:
        m.setitem(presets.PRESETS["default"], "soft_clip_sd", None)
        for key, value in presets.TWO_BANDS.items():
            m.setitem(presets.PRESETS["default"], key, value)
        first = api.post("/api/admin/venues/lab/jobs", headers=ADMIN).json
        assert runner.run_next() and job(api, first["id"])["state"] == "done"
    path = store.venue_dir("lab") / store.generation("lab") / "settings.json"
    drop = ("soft_clip_sd", "band_channels", "version")  # (a settings.json from before the version too)
    old = {k: v for k, v in json.loads(path.read_text()).items() if k not in drop}
    old.update(confidence_features=["support", "margin"], confidence_coef=[-6.68, 10.731, 10.215])
    path.write_text(json.dumps(old))
    return app, api, old


def test_the_admin_venue_says_its_frames_have_older_settings(old_lab: Any) -> None:
    _, api, old = old_lab
    doc = admin_doc(api)
    assert doc["features"]["settings_id"] == settings_id(old) != settings_id(resolve("default"))
    assert doc["settings_current"] is False and doc["preset_settings_id"] == settings_id(resolve("default"))
    # the phone reads the venue's settings, not the preset's: its records still match the frames
    published = api.get("/api/venues/lab").json["features"]["settings"]
    assert published["soft_clip_sd"] is None  # off, as its features were made (settings_upgrade, 2)
    # ... and the confidence model it answers with, the default's now, not the superseded one it stores
    assert published["confidence_coef"] == resolve("default")["confidence_coef"] != old["confidence_coef"]
    assert published["confidence_features"] == resolve("default")["confidence_features"]


def test_bad_requests_for_a_modelling_anew_say_why(old_lab: Any) -> None:
    _, api, _ = old_lab
    for body, says in [
        ({"anew": "yes"}, "'anew' must be true or false"),
        ({"anew": 1}, "'anew' must be true or false"),
        ({"anew": True, "videos": ["walk.mp4"]}, "leave out 'videos'"),
        ({"anew": True, "videos": None}, "leave out 'videos'"),
    ]:
        r = api.post("/api/admin/venues/lab/jobs", json=body, headers=ADMIN)
        assert r.status_code == 400 and says in r.json["error"], (body, r.json)
    assert api.get("/api/admin/venues/lab/jobs", headers=ADMIN).json["jobs"][0]["state"] == "done"  # none queued


def test_a_venue_with_no_modelling_walk_cannot_be_modelled_anew(small_ds: Any, tmp_path: Any) -> None:
    app, api = prepared(small_ds, tmp_path)
    assert api.delete("/api/admin/venues/lab/videos/walk.mp4", headers=ADMIN).status_code == 200
    r = api.post("/api/admin/venues/lab/jobs", json={"anew": True}, headers=ADMIN)
    assert r.status_code == 409 and "no uploaded modelling video with a walk path" in r.json["error"]
    assert "upload a modelling walk and tag its walk path first" in r.json["error"]
    # frames of a walk the catalogue does not know: modelled by the command line, upgraded there
    cli_walk = tmp_path / "cli-walk.mp4"
    cli_walk.write_bytes(small_ds.model_video.read_bytes())
    store = app.extensions["omninav"].catalog.store
    model_video(
        store, "lab", cli_walk, load_walk_path(small_ds.model_walk_path), load_lens(small_ds.root / "model_lens.json")
    )
    r = api.post("/api/admin/venues/lab/jobs", json={"anew": True}, headers=ADMIN)
    assert r.status_code == 409 and "its frames are from 'cli-walk.mp4'" in r.json["error"]
    assert "omninav model ... --anew" in r.json["error"]


def test_a_modelling_anew_never_drops_a_walk_it_cannot_model_again(small_ds: Any, tmp_path: Any) -> None:
    app, api = prepared(small_ds, tmp_path)
    cat, runner = app.extensions["omninav"].catalog, app.extensions["omninav"].jobs
    first = api.post("/api/admin/venues/lab/jobs", headers=ADMIN).json
    assert runner.run_next() and job(api, first["id"])["state"] == "done"
    # its file gone (a backup restored without videos): refused at once, not a job that fails later
    moved = tmp_path / "walk.mp4"
    (cat.videos.dir("lab") / "walk.mp4").rename(moved)
    r = api.post("/api/admin/venues/lab/jobs", json={"anew": True}, headers=ADMIN)
    assert r.status_code == 409 and "'walk.mp4' has no uploaded file here" in r.json["error"], r.json
    moved.rename(cat.videos.dir("lab") / "walk.mp4")
    # a walk modelled with the command line (frames, no video of the catalogue): its frames would go
    cli = tmp_path / "cli.mp4"
    cli.write_bytes(small_ds.model_video.read_bytes())
    model_video(
        cat.store, "lab", cli, load_walk_path(small_ds.model_walk_path), load_lens(small_ds.root / "model_lens.json")
    )
    gen = cat.store.generation("lab")
    r = api.post("/api/admin/venues/lab/jobs", json={"anew": True}, headers=ADMIN)
    assert r.status_code == 409 and "would drop the frames of 'cli.mp4'" in r.json["error"], r.json
    assert cat.store.generation("lab") == gen and not runner.run_next()  # nothing queued


def test_a_cancelled_modelling_anew_changes_nothing(old_lab: Any, small_ds: Any, monkeypatch: Any) -> None:
    app, api, old = old_lab
    runner, store = app.extensions["omninav"].jobs, app.extensions["omninav"].catalog.store
    gen, before = store.generation("lab"), admin_doc(api)
    record, _ = record_for(small_ds, old)
    answer = locate(api, record).json
    j = api.post("/api/admin/venues/lab/jobs", json={"anew": True}, headers=ADMIN).json
    assert j["anew"] is True and j["videos"] == ["walk.mp4"]
    real = runner._check_cancel

    def cancelled_meanwhile(jid: str) -> None:  # the admin presses Cancel while it runs
        assert locate(api, record).json == answer  # meanwhile the venue answers from its frames
        assert api.post(f"/api/admin/jobs/{jid}/cancel", headers=ADMIN).status_code == 202  # stops at its next frame
        real(jid)

    monkeypatch.setattr(runner, "_check_cancel", cancelled_meanwhile)
    assert runner.run_next()
    monkeypatch.undo()
    assert job(api, j["id"])["state"] == "cancelled"
    after = admin_doc(api)
    assert store.generation("lab") == gen and after["settings_current"] is False
    assert after["features"] == before["features"] and after["frames"] == before["frames"]
    assert locate(api, record).json == answer


def test_a_plain_modelling_keeps_the_venues_settings_and_anew_brings_the_presets(old_lab: Any, small_ds: Any) -> None:
    app, api, old = old_lab
    runner = app.extensions["omninav"].jobs
    old_record, truth = record_for(small_ds, old)
    # a second walk, modelled the plain way: into the old settings, or it could not be searched with the first
    assert upload(api, "lab", "again.mp4", add_video(api, "lab", "again.mp4", small_ds)).status_code == 200
    j = api.post("/api/admin/venues/lab/jobs", headers=ADMIN).json
    assert j["anew"] is False and j["videos"] == ["again.mp4"]
    assert runner.run_next() and job(api, j["id"])["state"] == "done"
    doc = admin_doc(api)
    assert doc["settings_current"] is False and doc["features"]["settings_id"] == settings_id(old)
    frames_before, generation_before = doc["frames"], doc["generation"]

    j = api.post("/api/admin/venues/lab/jobs", json={"anew": True}, headers=ADMIN).json
    assert j["anew"] is True and sorted(j["videos"]) == ["again.mp4", "walk.mp4"]
    assert locate(api, old_record).status_code == 200  # queued: the venue answers as before
    assert runner.run_next() and job(api, j["id"])["state"] == "done"

    doc = admin_doc(api)
    now = resolve("default")
    assert doc["settings_current"] is True and doc["features"]["settings_id"] == settings_id(now)
    assert doc["features"]["settings"]["soft_clip_sd"] == now["soft_clip_sd"]
    assert doc["generation"] == generation_before + 1 and doc["frames"] == frames_before  # both walks, once each
    videos = {v["name"]: v for v in api.get("/api/admin/venues/lab/videos", headers=ADMIN).json["videos"]}
    assert {n: v["status"] for n, v in videos.items()} == {"walk.mp4": "modelled", "again.mp4": "modelled"}
    assert sum(v["frames"] for v in videos.values()) == doc["frames"]

    # a phone that read the venue before: a 400 naming the settings now, so that it reads it again
    r = locate(api, old_record)
    assert r.status_code == 400 and r.json["venue_settings_id"] == settings_id(now), r.json
    assert "other settings" in r.json["error"]
    # ... and the record it makes then is answered, at the right place
    new_record, truth = record_for(small_ds, api.get("/api/venues/lab").json["features"]["settings"])
    a = locate(api, new_record).json
    assert np.hypot(a["x"] - truth[0], a["y"] - truth[1]) <= 2.0 and heading_error(a["heading_deg"], truth[2]) <= 10.0
    assert a["confidence"] > 0.5
