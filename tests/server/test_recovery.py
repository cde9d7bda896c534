"""Faults a building's server meets sooner or later, injected: a crash in the middle of a commit, a
full disk during an upload, a video damaged in transit. Each leaves the venue answering as before and
says what happened (findings 7, 8 and 13 of issue 9)."""

from __future__ import annotations

import errno
import io
import json
import shutil
from pathlib import Path

import numpy as np
import pytest

from omninav.catalog import videos as videos_mod
from omninav.errors import OmninavError
from omninav.lens import load_lens
from omninav.model_venue import model_video, remove_video
from omninav.walk_path import load_walk_path
from server_helpers import ADMIN, Api
from test_server import make_app


def damaged(src: Path, dst: Path, lo: float = 0.4, hi: float = 0.7) -> Path:
    """The video with bytes lo..hi of its length zeroed, as a broken transfer leaves it."""
    b = bytearray(src.read_bytes())
    b[int(len(b) * lo) : int(len(b) * hi)] = bytes(int(len(b) * hi) - int(len(b) * lo))
    dst.write_bytes(bytes(b))
    return dst


def test_a_crash_between_writing_a_generation_and_switching_to_it_heals_itself(copy_store, small_ds, monkeypatch):
    """Finding 8: the folder a crashed commit left made every later commit fail with ENOTEMPTY."""
    st, vid = copy_store
    before = st.generation(vid)
    n = st.frame_count(vid)
    import omninav.store as store_mod

    real = store_mod._write_atomic

    def crash_on_current(path: Path, text: str) -> None:
        if path.name == "CURRENT":
            raise KeyboardInterrupt  # the process dies here: the new folder exists, CURRENT is old
        real(path, text)

    monkeypatch.setattr(store_mod, "_write_atomic", crash_on_current)
    with pytest.raises(KeyboardInterrupt):
        model_video(
            st,
            vid,
            small_ds.model_video,
            load_walk_path(small_ds.model_walk_path),
            load_lens(small_ds.root / "model_lens.json"),
        )
    monkeypatch.setattr(store_mod, "_write_atomic", real)
    d = st.venue_dir(vid)
    orphans = [p.name for p in d.glob("gen-*") if p.name > before]
    assert orphans, "the injected crash should have left a generation that never went live"
    assert st.generation(vid) == before and st.frame_count(vid) == n  # still answering as before

    # the next commit (a video deleted) just works, and the orphan is gone
    assert remove_video(st, vid, small_ds.model_video.name) == n
    assert st.frame_count(vid) == 0 and st.generation(vid) != before
    assert not [p for p in d.glob("gen-*") if p.name in orphans and (p / "CURRENT").exists()]

    # at start the server drops such leftovers by itself
    (d / "gen-999999").mkdir()
    (d / "gen-999999" / "frames.npy").write_bytes(b"half")
    assert st.recover_all() == {vid: ["gen-999999"]}
    assert not (d / "gen-999999").exists()


def test_a_damaged_video_fails_its_modelling_naming_where_decoding_stopped(copy_store, small_ds, tmp_path):
    """Finding 7: a video with 40-70 % of its bytes zeroed modelled as done with 68 of 234 frames."""
    st, vid = copy_store
    before, n = st.generation(vid), st.frame_count(vid)
    bad = damaged(small_ds.model_video, tmp_path / "walk2.mp4")
    with pytest.raises(OmninavError) as e:
        model_video(
            st, vid, bad, load_walk_path(small_ds.model_walk_path), load_lens(small_ds.root / "model_lens.json")
        )
    msg = str(e.value)
    assert msg.startswith("walk2.mp4: the video stops decoding at 0:") and "damaged" in msg
    assert str(tmp_path) not in msg  # the video's name, never a path on the server (finding 10)
    assert st.generation(vid) == before and st.frame_count(vid) == n


@pytest.fixture
def venue_app(small_ds, tmp_path):
    app = make_app(tmp_path / "data")
    api = Api(app.test_client())
    assert api.post("/api/admin/venues", json={"id": "lab"}, headers=ADMIN).status_code == 201
    plan = small_ds.floorplan.read_bytes()
    assert api.put("/api/admin/venues/lab/floors/1/plan", data=plan, headers=ADMIN, content_type="image/png").json
    assert api.put("/api/admin/venues/lab/floors/1", json={"px_per_m": 20}, headers=ADMIN).status_code == 200
    lens = json.loads((small_ds.root / "model_lens.json").read_text())
    assert api.put("/api/admin/venues/lab/lenses/donut", json=lens, headers=ADMIN).status_code == 200
    return app, api


def announce(api, small_ds, name: str, size: int) -> None:
    walk_path = json.loads(small_ds.model_walk_path.read_text())
    body = {"name": name, "size": size, "walk_path": walk_path, "lens": "donut"}
    assert api.post("/api/admin/venues/lab/videos", json=body, headers=ADMIN).status_code == 201


class FullDisk(io.FileIO):
    """A file on a disk with `room` bytes left: writes past it fail as the kernel's would (ENOSPC)."""

    room = 0

    def write(self, b) -> int:  # type: ignore[override]
        left = FullDisk.room - self.tell()
        if left <= 0:
            raise OSError(errno.ENOSPC, "No space left on device")
        return super().write(bytes(b)[:left])


def test_a_full_disk_during_an_upload_keeps_what_came_and_says_disk_full(venue_app, small_ds, monkeypatch):
    """Finding 13: a full disk during an upload must say 'disk full', keep what was written, and let the
    upload resume from there once there is room."""
    _, api = venue_app
    data = small_ds.model_video.read_bytes()
    announce(api, small_ds, "walk.mp4", len(data))
    FullDisk.room = len(data) // 3
    monkeypatch.setattr(videos_mod, "open", lambda p, mode: FullDisk(p, mode.replace("b", "")), raising=False)
    url = "/api/admin/venues/lab/videos/walk.mp4/content"
    r = api.put(url, data=data, headers=ADMIN, content_type="application/octet-stream")
    assert r.status_code == 507 and r.json["error"].startswith("disk full") and "'walk.mp4'" in r.json["error"]
    assert r.json["received"] == len(data) // 3
    v = api.get("/api/admin/venues/lab/videos/walk.mp4", headers=ADMIN).json
    assert v["status"] == "uploading" and v["received"] == len(data) // 3
    # room again: the upload resumes where the server says it stands, and the file is whole
    monkeypatch.undo()
    a = v["received"]
    r = api.put(
        url,
        data=data[a:],
        headers={**ADMIN, "Content-Range": f"bytes {a}-{len(data) - 1}/{len(data)}"},
        content_type="application/octet-stream",
    )
    assert r.status_code == 200 and r.json["status"] == "ready"
    assert (Path(venue_app[0].config["DATA"]) / "videos" / "lab" / "walk.mp4").read_bytes() == data


def test_a_video_that_ends_early_is_refused_at_upload_by_name(venue_app, small_ds, tmp_path):
    """A file cut short names the video in its error, not the server's path to it (finding 10)."""
    _, api = venue_app
    data = small_ds.model_video.read_bytes()[:2000]
    announce(api, small_ds, "cut.mp4", len(data))
    r = api.put("/api/admin/venues/lab/videos/cut.mp4/content", data=data, headers=ADMIN, content_type="video/mp4")
    assert r.status_code == 422 and "'cut.mp4'" in r.json["error"]
    assert str(tmp_path) not in r.json["error"] and "/videos/" not in r.json["error"]


def test_only_what_a_commit_made_live_is_served_after_a_partial_copy(copy_store):
    """A generation folder is complete or absent: a half-copied one beside CURRENT never loads."""
    st, vid = copy_store
    d = st.venue_dir(vid)
    live = d / st.generation(vid)
    half = d / ".tmp-gen-crash"
    shutil.copytree(live, half)
    (half / "spectra.npy").write_bytes(b"")
    with st.lock(vid):
        assert st.recover(vid) == [".tmp-gen-crash"]
    assert np.load(live / "frames.npy").shape[0] == st.frame_count(vid)
