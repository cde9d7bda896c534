"""WARM_VENUES: a worker builds each modelled venue's walk graph and tracker (its look-alike
search: seconds of CPU on a big venue) in a background daemon thread, at app start and whenever it
loads a venue, so that the first tracked request does not pay for it; a failing warm-up is only
logged, and the request that needs the walk then builds it and answers as without the warm-up."""

from __future__ import annotations

import logging
import shutil
import threading
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import pytest

from omninav.locate import Locator
from omninav.server.runtimes import Runtime, Runtimes
from omninav.spectrum import encode_binary
from server_helpers import ADMIN, Api, clip_spectra, query_clip
from test_tracking_api import make_app

WAIT_S = 60.0  # a bounded wait for a background build (the small venue's takes well under a second)


@pytest.fixture(scope="module")
def data(small_ds: Any, modelled: Any, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A data folder with venues 'lab' (the shared modelled frames, a place), 'empty' (nothing
    modelled) and 'lab2' (the same frames), made by an app that warms nothing: each test starts
    its own app on it."""
    data = tmp_path_factory.mktemp("warm") / "data"
    app = make_app(data, WARM_VENUES=False)
    api = Api(app.test_client())
    for vid in ("lab", "empty", "lab2"):
        assert api.post("/api/admin/venues", json={"id": vid, "name": vid}, headers=ADMIN).status_code == 201
    assert api.put("/api/admin/venues/lab/floors/1", json={"name": "Ground"}, headers=ADMIN).status_code == 200
    place = [{"name": "Room 1", "floor": "1", "x": 11.0, "y": 2.5, "kind": "room"}]
    assert api.put("/api/admin/venues/lab/places", json=place, headers=ADMIN).status_code == 200
    st, vid = modelled
    shutil.copytree(st.venue_dir(vid), data / "venues" / "lab")
    shutil.copytree(st.venue_dir(vid), data / "venues" / "lab2")  # a second modelled venue
    app.extensions["omninav"].db.engine.dispose()
    return data


@pytest.fixture(scope="module")
def record(small_ds: Any, data: Path) -> bytes:
    """One clip of the query walk as the app sends it."""
    app = make_app(data, WARM_VENUES=False)
    conf = app.extensions["omninav"].catalog.venues.settings("lab")
    frames, _ = query_clip(small_ds, 0)
    out = encode_binary(clip_spectra(small_ds, frames, conf), conf)
    app.extensions["omninav"].db.engine.dispose()
    return out


@pytest.fixture(autouse=True)
def _no_warm_up_left_running() -> Iterator[None]:
    """No warm-up of another test's app runs during a test (it would race its monkeypatches)."""
    join_warm_ups()
    yield
    join_warm_ups()


def join_warm_ups() -> None:
    for t in threading.enumerate():
        if t.name.startswith("omninav-warm"):
            t.join(WAIT_S)


def locate(app: Any, record: bytes, **params: Any) -> Any:
    q = "&".join(f"{k}={v}" for k, v in params.items())
    return app.test_client().post(f"/api/venues/lab/locate?{q}", data=record, content_type="application/octet-stream")


def runtime(app: Any) -> Runtime | None:
    return app.extensions["omninav"].runtimes._rt.get("lab")  # type: ignore[no-any-return]


def walk_built(app: Any) -> bool:
    rt = runtime(app)
    return rt is not None and rt._walk is not None


def wait_for(ok: Callable[[], bool], wait_s: float = WAIT_S) -> bool:
    end = time.monotonic() + wait_s
    while not ok():
        if time.monotonic() > end:
            return False
        time.sleep(0.05)
    return True


def edit_lab(app: Any) -> None:
    """A catalogue edit: a new revision, so the next request loads a new runtime."""
    r = Api(app.test_client()).put("/api/admin/venues/lab/floors/1", json={"name": "Ground"}, headers=ADMIN)
    assert r.status_code == 200


def test_the_app_warms_every_modelled_venue_at_start_without_a_request(
    data: Path, record: bytes, caplog: pytest.LogCaptureFixture
) -> None:
    caplog.set_level(logging.WARNING)
    app = make_app(data, WARM_VENUES=True)  # (conftest.py turns it off for the other tests)
    runtimes = app.extensions["omninav"].runtimes
    assert runtimes.warmer is not None and runtimes.warmer.daemon
    assert wait_for(lambda: walk_built(app)), "the walk was not built in the background"
    runtimes.warmer.join(WAIT_S)
    assert not runtimes.warmer.is_alive()
    assert "empty" not in runtimes._rt  # no modelled frames: skipped, quietly
    assert not [r for r in caplog.records if r.levelno >= logging.WARNING], caplog.text
    # the first tracked request uses that walk rather than building another
    rt = runtime(app)
    assert rt is not None
    walk = rt._walk
    r = locate(app, record, session="warmwalk01", t=1.0)
    assert r.status_code == 200, r.json
    assert r.json["tracking"]["reason"] == "new" and runtime(app) is rt and rt._walk is walk


def test_a_venue_that_verifies_is_warmed_with_its_places_for_verification(
    data: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A `verified` venue's warm-up also makes its places for verification and loads the RANSAC's
    compiled loops (Locator.verification_places), so that its first request does not pay for them."""
    warmed: list[str] = []
    monkeypatch.setattr(Locator, "verifies", property(lambda self: self.venue_id == "lab"))
    monkeypatch.setattr(Locator, "verification_places", lambda self: warmed.append(self.venue_id))
    app = make_app(data, WARM_VENUES=True)
    assert app.extensions["omninav"].runtimes.warm_idle(WAIT_S)
    assert warmed == ["lab"]  # (lab2 does not verify; empty has nothing modelled)


def test_a_venue_a_request_loads_is_warmed_in_a_daemon_thread(
    data: Path, record: bytes, monkeypatch: pytest.MonkeyPatch
) -> None:
    app = make_app(data, WARM_VENUES=True)
    runtimes = app.extensions["omninav"].runtimes
    assert runtimes.warm_idle(WAIT_S)
    before = runtime(app)
    gate = threading.Event()  # holds the build, so that its thread can be seen running
    real = Locator.new_tracker

    def held(self: Locator, *a: Any, **kw: Any) -> Any:
        gate.wait(WAIT_S)
        return real(self, *a, **kw)

    monkeypatch.setattr(Locator, "new_tracker", held)
    edit_lab(app)
    assert locate(app, record).status_code == 200  # untracked: loads the new revision's runtime
    rt = runtime(app)
    assert rt is not None and rt is not before and rt._walk is None
    thread = runtimes.warmer
    assert thread is not None and thread.daemon and thread.is_alive()
    gate.set()
    assert wait_for(lambda: rt._walk is not None), "the walk was not built in the background"


def test_with_warm_venues_off_the_walk_waits_for_a_tracked_request(data: Path, record: bytes) -> None:
    app = make_app(data, WARM_VENUES=False)
    assert app.extensions["omninav"].runtimes.warmer is None
    assert locate(app, record).status_code == 200
    time.sleep(1.0)  # long enough for a background build of the small venue to show
    assert runtime(app) is not None and not walk_built(app)
    assert not [t for t in threading.enumerate() if t.name.startswith("omninav-warm")]
    r = locate(app, record, session="coldwalk01", t=1.0)
    assert r.status_code == 200, r.json
    assert walk_built(app)


def test_a_failing_warm_up_is_logged_and_the_requests_answer_as_before(
    data: Path, record: bytes, monkeypatch: pytest.MonkeyPatch, caplog: pytest.LogCaptureFixture
) -> None:
    def broken(self: Locator, *a: Any, **kw: Any) -> Any:
        raise RuntimeError("no tracker today")

    monkeypatch.setattr(Locator, "new_tracker", broken)
    app = make_app(data, WARM_VENUES=True)
    runtimes = app.extensions["omninav"].runtimes
    assert runtimes.warm_idle(WAIT_S) and not walk_built(app)
    failed = [r for r in caplog.records if r.levelno == logging.ERROR and "warming venue 'lab'" in r.getMessage()]
    assert failed and "no tracker today" in caplog.text
    # a new runtime's warm-up fails the same way, in its own thread, logged
    edit_lab(app)
    caplog.clear()
    assert locate(app, record).status_code == 200  # untracked answers need no walk
    join_warm_ups()
    assert "no tracker today" in caplog.text and not walk_built(app)
    # the tracked request builds the walk itself and reports the error as it always did
    r = locate(app, record, session="brokenwalk", t=1.0)
    assert r.status_code == 500 and "RuntimeError" in r.json["error"]
    monkeypatch.undo()
    r = locate(app, record, session="brokenwalk", t=2.0)
    assert r.status_code == 200, r.json
    assert walk_built(app)


def test_a_tracked_request_during_the_background_build_waits_for_it_and_nothing_is_built_twice(
    data: Path, record: bytes, monkeypatch: pytest.MonkeyPatch
) -> None:
    gate = threading.Event()
    built: list[str] = []
    real = Locator.new_tracker

    def counted(self: Locator, *a: Any, **kw: Any) -> Any:
        built.append(self.venue_id)
        gate.wait(WAIT_S)
        return real(self, *a, **kw)

    monkeypatch.setattr(Locator, "new_tracker", counted)
    app = make_app(data, WARM_VENUES=True)
    assert wait_for(lambda: "lab" in built), "the background build did not start"
    out: dict[str, Any] = {}
    asker = threading.Thread(target=lambda: out.update(r=locate(app, record, session="duringbuild", t=1.0)))
    asker.start()
    asker.join(1.0)
    assert asker.is_alive()  # waiting for the build the warm-up holds, not building its own
    gate.set()
    asker.join(WAIT_S)
    assert out["r"].status_code == 200, out["r"].json
    assert app.extensions["omninav"].runtimes.warm_idle(WAIT_S)
    assert built.count("lab") == 1 and built.count("lab2") == 1


def test_a_venue_that_fails_to_load_does_not_stop_the_others_warming(
    data: Path, monkeypatch: pytest.MonkeyPatch, caplog: pytest.LogCaptureFixture
) -> None:
    real = Runtimes._load

    def load(self: Runtimes, venue_id: str, *a: Any) -> Runtime:
        if venue_id == "lab":
            raise RuntimeError("cannot read lab today")
        return real(self, venue_id, *a)

    monkeypatch.setattr(Runtimes, "_load", load)
    app = make_app(data, WARM_VENUES=True)
    runtimes = app.extensions["omninav"].runtimes
    assert runtimes.warm_idle(WAIT_S)
    assert "lab" not in runtimes._rt and "cannot read lab today" in caplog.text
    other = runtimes._rt.get("lab2")
    assert other is not None and other._walk is not None


def test_edits_in_a_row_queue_builds_on_one_thread_and_build_only_the_current_runtime(
    data: Path, record: bytes, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Each catalogue edit followed by a request loads a new runtime; their builds queue on the
    worker's one warm-up thread, and a runtime replaced before its turn is not built at all."""
    app = make_app(data, WARM_VENUES=True)
    runtimes = app.extensions["omninav"].runtimes
    assert runtimes.warm_idle(WAIT_S)
    gate = threading.Event()
    built: list[int] = []
    real = Locator.new_tracker

    def held(self: Locator, *a: Any, **kw: Any) -> Any:
        built.append(threading.get_ident())
        gate.wait(WAIT_S)
        return real(self, *a, **kw)

    monkeypatch.setattr(Locator, "new_tracker", held)
    runtimes_seen = []
    for _ in range(4):
        edit_lab(app)
        assert locate(app, record).status_code == 200  # untracked: loads the new revision
        runtimes_seen.append(runtime(app))
    warm_threads = [t for t in threading.enumerate() if t.name.startswith("omninav-warm")]
    assert len(warm_threads) == 1
    gate.set()
    assert runtimes.warm_idle(WAIT_S)
    # the build held when the edits came and then the latest runtime's: none of those between. The
    # held one is of the runtime current when the thread looked (the first, or a later one when
    # the thread started late on a busy machine: CI once saw the second)
    assert len(built) <= 2 and len(set(built)) == 1
    assert runtimes_seen[-1] is runtime(app) and runtime(app)._walk is not None
    assert sum(rt._walk is not None for rt in runtimes_seen[:-1]) <= 1
