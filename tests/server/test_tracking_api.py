"""Tracking sessions and route guidance through the server (Flask test client, every response
checked against openapi.yaml): a walk's clips located with ?session= continue one filter whose
state lives in the database; unknown, expired, older-generation and clock-confused sessions start
over and say why; bad parameters are 400s, an unknown destination a 404 naming the list; guidance
comes with ?to=; the destinations are listed by floor."""

from __future__ import annotations

import shutil
import threading
from collections.abc import Iterator
from typing import Any

import numpy as np
import pytest

from conftest import db_url_for
from omninav.describe import guidance_sentence
from omninav.server import create_app
from omninav.server.venues_api import filing_name
from omninav.spectrum import encode_binary
from omninav.tracking import FORGET_S
from server_helpers import ADMIN, TOKEN, Api, clip_spectra, query_clip

FPS = 10.0  # the small venue's query walk
STARTS = tuple(range(0, 200, 20))  # a 1 s clip every 2 s of the query walk (its first 20 s), as the app films
SESSION = "walk0001aaaa"


def make_app(data: Any, **over: Any) -> Any:
    conf = {"DATA": str(data), "ADMIN_TOKEN": TOKEN, "LOCATE_RATE": 0.0, "VENUE_CACHE_S": 0.0, "JOB_RUNNER": False}
    if url := db_url_for(data):  # OMNINAV_TEST_DB=postgres: the data folder's own PostgreSQL database
        conf["DATABASE_URL"] = url
    conf.update(over)
    return create_app(conf)


@pytest.fixture(scope="module")
def lab(small_ds: Any, modelled: Any, tmp_path_factory: pytest.TempPathFactory) -> Iterator[tuple[Any, Api]]:
    """Venue 'lab' (plan, scale, places, a second floor) made through the admin API, its frames
    those of the shared modelled store (a copy): no modelling job to wait for."""
    data = tmp_path_factory.mktemp("tracking") / "data"
    app = make_app(data)
    api = Api(app.test_client())
    assert api.post("/api/admin/venues", json={"id": "lab", "name": "Lab"}, headers=ADMIN).status_code == 201
    plan = small_ds.floorplan.read_bytes()
    r = api.put("/api/admin/venues/lab/floors/1/plan", data=plan, headers=ADMIN, content_type="image/png")
    assert r.status_code == 200
    assert (
        api.put("/api/admin/venues/lab/floors/1", json={"name": "Ground", "px_per_m": 20}, headers=ADMIN).status_code
        == 200
    )
    assert api.put("/api/admin/venues/lab/floors/2", json={"name": "First"}, headers=ADMIN).status_code == 200
    places = [{**p, "floor": "1"} for p in small_ds.scene.places] + [
        {"name": "Room 1", "x": 11.0, "y": 2.5, "kind": "room", "say": "The door is on your left."},
        {"name": "the lifts", "x": 20.0, "y": 11.0, "kind": "lift"},
        {"name": "Far store", "x": 2.0, "y": 14.0, "kind": "other"},  # 12 m from any walk: not a destination
        {"name": "the lifts", "floor": "2", "x": 20.0, "y": 11.0, "kind": "lift"},  # no walk on floor 2
    ]
    assert api.put("/api/admin/venues/lab/places", json=places, headers=ADMIN).status_code == 200
    st, vid = modelled
    shutil.copytree(st.venue_dir(vid), data / "venues" / "lab")
    yield app, api
    app.extensions["omninav"].db.engine.dispose()  # its pooled connections close before PostgreSQL stops


@pytest.fixture(scope="module")
def walk(small_ds: Any, lab: Any) -> list[tuple[bytes, float, tuple[float, float, float]]]:
    """The query walk as the app sends it: (binary record, t of its last frame, true pose) per clip."""
    conf = lab[0].extensions["omninav"].catalog.venues.settings("lab")
    out = []
    for s in STARTS:
        frames, truth = query_clip(small_ds, s)
        out.append((encode_binary(clip_spectra(small_ds, frames, conf), conf), (s + len(frames) - 1) / FPS, truth))
    return out


def locate(api: Api, record: bytes, **params: Any) -> Any:
    q = "&".join(f"{k}={v}" for k, v in params.items())
    return api.post(f"/api/venues/lab/locate?{q}", data=record, content_type="application/octet-stream")


def sessions(app: Any) -> Any:
    return app.extensions["omninav"].catalog.sessions


def test_a_tracked_walk_continues_one_filter_whose_state_is_in_the_database(lab: Any, walk: Any) -> None:
    app, api = lab
    plain = locate(api, walk[0][0]).json
    assert "tracking" not in plain and "guidance" not in plain  # without a session: as before
    answers = []
    for record, t, _ in walk:
        r = locate(api, record, session=SESSION, t=t, steps=2, turn_deg=0)
        assert r.status_code == 200, r.json
        answers.append(r.json)
    first, last = answers[0]["tracking"], answers[-1]["tracking"]
    assert first["restarted"] and first["reason"] == "new" and first["session"] == SESSION
    assert [a["tracking"]["updates"] for a in answers] == list(range(1, len(walk) + 1))
    assert not any(a["tracking"]["restarted"] for a in answers[1:]) and last["reason"] is None
    # the single clip's own estimate beside the filtered pose; the words are the filtered pose's
    assert set(last["single"]) == {"x", "y", "heading_deg", "confidence"}
    x, y, _ = walk[-1][2]
    assert np.hypot(answers[-1]["x"] - x, answers[-1]["y"] - y) <= 2.0, (answers[-1], walk[-1][2])
    assert answers[-1]["sentence"] and answers[-1]["floor"] == "1"
    row = sessions(app).get("lab", SESSION)
    assert row is not None and row.generation == app.extensions["omninav"].catalog.store.generation("lab")
    assert row.guide is None and len(row.state) > 0 and row.expires > row.updated
    # the state carries the clips' own confidence, as the answers gave it (the recent clips' rule)
    from omninav.tracking_state import TrackState

    walk_graph = app.extensions["omninav"].runtimes.get("lab").walk().graph
    state = TrackState.from_bytes(row.state, walk_graph)
    assert state is not None and state.recent is not None
    said = [a["tracking"]["single"]["confidence"] for a in answers]
    assert min(said) - 1e-3 <= state.recent <= max(said) + 1e-3  # a mean of them


def test_a_walk_filmed_throughout_is_walked_second_by_second(small_ds: Any, lab: Any) -> None:
    """The app's guided walk films ~2 s a request, everything between two answers: the filter
    walks each record second by second (`updates` counts the seconds), a session goes on across
    them (not 'expired' for having counted more than one), and the answer is the walk's."""
    app, api = lab
    conf = app.extensions["omninav"].catalog.venues.settings("lab")
    got = []
    for s in range(0, 120, 20):  # the first 12 s of the query walk, 2 s a request, no second unseen
        frames, truth = query_clip(small_ds, s, 20)
        record = encode_binary(clip_spectra(small_ds, frames, conf), conf)
        r = locate(api, record, session="filmed001", t=(s + 19) / FPS, steps=3, turn_deg=0)
        assert r.status_code == 200, r.json
        got.append((r.json, truth))
    tracking = [a["tracking"] for a, _ in got]
    assert [t["updates"] for t in tracking] == [2, 4, 6, 8, 10, 12]
    assert tracking[0]["reason"] == "new" and not any(t["restarted"] for t in tracking[1:])
    (a, (x, y, _)) = got[-1]
    assert np.hypot(a["x"] - x, a["y"] - y) <= 2.0, (a, got[-1][1])


def test_the_session_table_keeps_nothing_personal(lab: Any) -> None:
    app, _ = lab
    db = app.extensions["omninav"].db
    from sqlalchemy import inspect

    cols = {c["name"] for c in inspect(db.engine).get_columns("tracking_sessions")}
    assert cols == {"id", "venue", "generation", "state", "guide", "updated", "expires"}


def test_unknown_expired_and_clock_confused_sessions_start_over_and_say_why(lab: Any, walk: Any) -> None:
    app, api = lab
    db = app.extensions["omninav"].db
    (r0, t0, _), (r1, t1, _) = walk[0], walk[1]

    def step(record: bytes, t: float, sid: str = "again0001") -> dict[str, Any]:
        r = locate(api, record, session=sid, t=t)
        assert r.status_code == 200, r.json
        return r.json["tracking"]  # type: ignore[no-any-return]

    assert step(r0, t0)["reason"] == "new"
    tr = step(r1, t1)
    assert tr["updates"] == 2 and tr["reason"] is None and not tr["restarted"]
    # idle longer than TRACK_SESSION_S: the row says expired
    db.run("UPDATE tracking_sessions SET expires = 1 WHERE id = 'again0001'")
    tr = step(r0, t1 + 1)
    assert tr["restarted"] and tr["reason"] == "expired" and tr["updates"] == 1
    # the phone's clock jumped ahead by more than a session's life
    tr = step(r1, t1 + 1 + app.config["TRACK_SESSION_S"] + 5)
    assert tr["reason"] == "expired" and tr["updates"] == 1
    # ... or by less, but by more than the filter remembers a walk (FORGET_S): the filter starts over
    base = t1 + 1 + app.config["TRACK_SESSION_S"] + 5
    tr = step(r0, base + FORGET_S + 60)
    assert tr["restarted"] and tr["reason"] == "expired" and tr["updates"] == 1
    # ... or went back
    assert step(r1, 5.0)["reason"] == "clock"
    # an unknown session of a well-formed id
    assert step(r0, t0, "never-seen-before")["reason"] == "new"


def test_a_session_of_an_older_model_or_an_unreadable_state_starts_over(lab: Any, walk: Any) -> None:
    app, api = lab
    db = app.extensions["omninav"].db
    (r0, t0, _), (r1, t1, _) = walk[0], walk[1]
    assert locate(api, r0, session="oldgen0001", t=t0).json["tracking"]["updates"] == 1
    db.run("UPDATE tracking_sessions SET generation = 'g-older' WHERE id = 'oldgen0001'")
    tr = locate(api, r1, session="oldgen0001", t=t1).json["tracking"]
    assert tr["restarted"] and tr["reason"] == "venue changed" and tr["updates"] == 1
    # a state that does not decode (another walk graph, or damaged): never a 500
    db.run("UPDATE tracking_sessions SET state = :b WHERE id = 'oldgen0001'", b=b"not a state")
    r = locate(api, r0, session="oldgen0001", t=t1 + 2)
    assert r.status_code == 200 and r.json["tracking"]["reason"] == "venue changed"


def test_concurrent_requests_of_one_session_all_answer(lab: Any, walk: Any) -> None:
    app, _ = lab
    record, t, _ = walk[2]
    codes: list[int] = []

    def go(k: int) -> None:
        c = Api(app.test_client())
        for i in range(2):
            r = locate(c, record, session="together01", t=t + 0.01 * (2 * k + i))
            codes.append(r.status_code)

    threads = [threading.Thread(target=go, args=(k,)) for k in range(3)]
    for th in threads:
        th.start()
    for th in threads:
        th.join()
    assert codes == [200] * 6
    row = sessions(app).get("lab", "together01")
    assert row is not None  # the last write won


@pytest.mark.parametrize(
    ("query", "says"),
    [
        ("session=short", "session"),
        ("session=has%20spaces%20in%20it", "session"),
        ("session=" + "x" * 65, "session"),
        ("session=okay00001&t=-1", "'t'"),
        ("session=okay00001&t=nan", "'t'"),
        ("session=okay00001&t=soon", "'t'"),
        ("session=okay00001&steps=1.5", "'steps'"),
        ("session=okay00001&steps=-1", "'steps'"),
        ("session=okay00001&steps=10001", "'steps'"),
        ("session=okay00001&turn_deg=36001", "'turn_deg'"),
        ("session=okay00001&turn_deg=inf", "'turn_deg'"),
        ("session=okay00001&style=loud", "'style'"),
        ("to=Room%201", "'to' needs a tracking 'session'"),
        ("session=okay00001&to=", "'to'"),
    ],
)
def test_bad_tracking_parameters_are_400s_that_say_which(lab: Any, walk: Any, query: str, says: str) -> None:
    _, api = lab
    r = api.post(f"/api/venues/lab/locate?{query}", data=walk[0][0], content_type="application/octet-stream")
    assert r.status_code == 400 and says in r.json["error"], r.json


def test_guidance_to_an_unknown_place_is_a_404_naming_the_list(lab: Any, walk: Any) -> None:
    _, api = lab
    for to in ("Nowhere", "Far%20store"):  # no such place; a place away from every walk
        r = locate(api, walk[0][0], session="lost00001", to=to)
        assert r.status_code == 404, r.json
        assert "/api/venues/lab/destinations" in r.json["error"] and "no place" in r.json["error"]


def test_guidance_comes_with_to_and_its_state_is_kept(lab: Any, walk: Any) -> None:
    """The query walk goes from the lifts' end of the L round its corner past Room 1: guided
    there, the walk hears the start with its preview, the turn before the corner, and the arrival."""
    app, api = lab
    guided = []
    for record, t, _ in walk:
        r = locate(api, record, session="guided0001", t=t, to="Room%201")
        assert r.status_code == 200, r.json
        guided.append(r.json["guidance"])
    kinds = [g["kind"] for g in guided]
    assert kinds[0] == "start" and guided[0]["preview"]["turns"] == 1 and guided[0]["speak"]
    # the turn, before the arrival: at the start already where the corner is near enough (route.py,
    # turn_ahead_m: in time to be heard before it at the walker's pace)
    turned = guided[0]["in_m"] is not None or ("turn" in kinds and kinds.index("turn") < kinds.index("arrived"))
    assert turned and "arrived" in kinds, [(g["kind"], g["sentence"]) for g in guided]
    assert all("preview" not in g for g in guided[1:])
    arrived = guided[kinds.index("arrived")]
    assert arrived["urgent"] and arrived["sentence"].startswith("You have arrived at Room 1")
    assert all(g["to"]["name"] == "Room 1" and g["sentence"] for g in guided)
    row = sessions(app).get("lab", "guided0001")
    assert row is not None and row.guide is not None and row.guide["to"] == guided[0]["to"]["id"]
    # by id, and in another style: the same guide, its sentence in that style
    record, t, _ = walk[-1]
    r = locate(api, record, session="guided0001", t=t + 2, to=guided[0]["to"]["id"], style="sides")
    g = r.json["guidance"]
    assert r.status_code == 200 and g["sentence"] == guidance_sentence(g, "sides")


def test_a_name_on_two_floors_guides_to_the_one_on_the_users_floor(lab: Any, walk: Any) -> None:
    _, api = lab
    record, t, _ = walk[0]
    g = locate(api, record, session="lifts0001", t=t, to="the%20lifts").json["guidance"]
    assert g["to"]["name"] == "the lifts" and g["to"]["floor"] == "1"


def test_destinations_are_the_places_on_the_walk_graph_by_floor(lab: Any) -> None:
    _, api = lab
    r = api.get("/api/venues/lab/destinations")
    assert r.status_code == 200
    doc = r.json
    assert doc["venue"] == "lab" and [f["id"] for f in doc["floors"]] == ["1"]  # nothing walked on floor 2
    (ground,) = doc["floors"]
    names = [p["name"] for p in ground["places"]]
    assert ground["name"] == "Ground" and names == sorted(names, key=filing_name)
    assert names.index("the lifts") < names.index("Room 1")  # under L, not under T
    assert "Room 1" in names and "the lifts" in names and "Far store" not in names
    room = next(p for p in ground["places"] if p["name"] == "Room 1")
    assert room["kind"] == "room" and (room["x"], room["y"]) == (11.0, 2.5)
    assert api.get("/api/venues/nope/destinations").status_code == 404


def test_a_venue_without_frames_has_no_destinations_yet(lab: Any) -> None:
    _, api = lab
    assert api.post("/api/admin/venues", json={"id": "empty", "name": "Empty"}, headers=ADMIN).status_code == 201
    r = api.get("/api/venues/empty/destinations")
    assert r.status_code == 409 and "model" in r.json["error"]


def test_expired_sessions_are_deleted_by_later_writes(lab: Any) -> None:
    app, _ = lab
    s = sessions(app)
    s.put("lab", "stale0001", "g", b"x", None, life_s=10.0, now=1000.0)
    assert s.get("lab", "stale0001") is not None and s.get("lab", "stale0001").expired(1010.0)  # type: ignore[union-attr]
    s._purged = float("-inf")  # as in a process that has not purged for PURGE_EVERY_S
    s.put("lab", "fresh0001", "g", b"y", {"to": "p"}, life_s=900.0)  # a write now purges what expired
    assert s.get("lab", "stale0001") is None and s.get("lab", "fresh0001").guide == {"to": "p"}  # type: ignore[union-attr]


def test_migration_5_adds_the_sessions_to_a_version_4_catalogue(tmp_path: Any) -> None:
    from sqlalchemy import text

    from omninav.catalog import db as db_mod

    old = db_mod.Db(f"sqlite:///{tmp_path / 'c.db'}")
    migrations = db_mod.MIGRATIONS
    try:
        db_mod.MIGRATIONS, db_mod.SCHEMA_VERSION = migrations[:4], 4
        old.migrate()
    finally:
        db_mod.MIGRATIONS, db_mod.SCHEMA_VERSION = migrations, len(migrations)
    with old.tx() as c:
        c.execute(text("INSERT INTO venues (id, name, preset, created, revision) VALUES ('v', 'V', 'default', 0, 3)"))
    # migration 5 and every later one run; the sessions table of 5 is what this test reads
    assert old.version() == 4 and old.migrate() == db_mod.SCHEMA_VERSION - 4
    assert old.version() == db_mod.SCHEMA_VERSION
    from omninav.catalog import Catalog

    s = Catalog(old, tmp_path).sessions
    state = bytes(range(256)) * 3  # every byte value, as bytes come back
    s.put("v", "migrated01", "gen-000001", state, {"to": "p1", "nodes": [1, 2]}, life_s=900.0)
    got = s.get("v", "migrated01")
    assert got is not None and got.state == state and got.guide == {"to": "p1", "nodes": [1, 2]}
    old.run("DELETE FROM venues WHERE id = 'v'")  # a deleted venue takes its sessions with it
    assert s.get("v", "migrated01") is None
    old.engine.dispose()


def test_a_tracked_answers_plan_is_drawn_around_the_filtered_pose(lab: Any, walk: Any) -> None:
    from omninav.server.locate_api import _row_near

    app, api = lab
    for record, t, _ in walk[:4]:
        r = locate(api, record, session="planwalk01", t=t, plan=1)
        assert r.status_code == 200, r.json
    a = r.json
    assert a["plan_png"].startswith("data:image/png;base64,")
    rt = app.extensions["omninav"].runtimes.get("lab")
    fr = rt.locator.gen.frames
    row = _row_near(rt, a["x"], a["y"], a["floor"])
    assert np.hypot(fr["x"][row] - a["x"], fr["y"][row] - a["y"]) <= 1.0  # a modelled frame at the pose drawn


def test_a_list_of_places_is_filed_without_case_or_a_leading_article_and_numbers_by_value() -> None:
    names = ["the café", "Room 2", "an office", "The Lifts", "A", "the", "atrium", "Room 10", "A Wing", "A 4"]
    assert sorted(names, key=filing_name) == [
        "A",
        "A 4",
        "A Wing",
        "atrium",
        "the café",
        "The Lifts",
        "an office",
        "Room 2",
        "Room 10",
        "the",
    ]
    # a digit that is not a number is text, never an error
    assert sorted(["Room 1²", "Room 1", "Room 12"], key=filing_name) == ["Room 1", "Room 1²", "Room 12"]


def test_the_same_clip_again_and_again_without_sensors_is_no_surer_than_alone(lab: Any, walk: Any) -> None:
    """A phone held on one spot, its sensors refused: the same record sent every second in one
    session. From the second answer on, the tracked confidence is no more than the clip's own
    (track_still_seen): the view filmed again is not new evidence. The sentence says "probably"
    exactly when the confidence is under 0.8."""
    _, api = lab
    record = walk[3][0]
    out = [locate(api, record, session="heldstill0001", t=float(i + 1)).json for i in range(8)]
    assert [a["tracking"]["updates"] for a in out] == list(range(1, 9))
    for a in out[1:]:
        assert a["confidence"] <= a["tracking"]["single"]["confidence"] + 1e-3
    for a in out:
        if not a["low_confidence"]:
            assert a["sentence"].startswith("You are probably ") == (a["confidence"] < 0.8)
