"""The venue catalogue on its own (catalog/): the one record the CLI and the server share.

What each resource refuses, and as which kind of error (the blueprints turn kinds into status
codes); one revision bump per edit; the busy-video lookup; and the import, once, of the venues an
older omninav kept in venue.json.
"""

from __future__ import annotations

import json
import shutil
import time
from pathlib import Path

import pytest

from omninav.catalog import Catalog
from omninav.errors import Conflict, NotFound, OmninavError, Unusable
from omninav.store import Store


@pytest.fixture
def cat(tmp_path: Path) -> Catalog:
    return Catalog.open({"DATA": str(tmp_path / "data"), "DATABASE_URL": ""})


def test_each_refusal_is_of_the_kind_the_server_maps_to_its_status(cat: Catalog) -> None:
    cat.venues.create("v", "V")
    cases = [
        (lambda: cat.venues.get("nowhere"), NotFound, "unknown venue 'nowhere'"),
        (lambda: cat.venues.create("v"), Conflict, "already exists"),
        (lambda: cat.venues.create("../x"), OmninavError, "invalid venue id"),
        (lambda: cat.venues.create("w", preset="nope"), OmninavError, "unknown preset"),
        (lambda: cat.floors.get("v", "9"), NotFound, "has no floor '9'"),
        (lambda: cat.floors.put("v", "1", {"px_per_m": -1}), OmninavError, "positive"),
        (lambda: cat.floors.set_plan("v", "1", b"not a png"), Unusable, "not a readable PNG or JPEG"),
        (lambda: cat.places.delete("v", "nope"), NotFound, "has no place"),
        (lambda: cat.places.add("v", [{"name": "A", "x": 1, "y": 1, "floor": "9"}]), OmninavError, "no floor '9'"),
        (lambda: cat.lenses.get("v", "donut"), NotFound, "no lens profile 'donut'"),
        (lambda: cat.lenses.put("v", "a b", {}), OmninavError, "invalid lens name"),
        (lambda: cat.videos.get("v", "walk.mp4"), NotFound, "has no video 'walk.mp4'"),
        (lambda: cat.store.load("v"), Conflict, "no modelled frames"),
    ]
    for call, kind, msg in cases:
        with pytest.raises(OmninavError) as e:
            call()
        assert type(e.value) is kind and msg in str(e.value), (kind, str(e.value))


def test_every_edit_bumps_the_revision_once(cat: Catalog, small_ds) -> None:
    cat.venues.create("v", "V")
    rev = [cat.venues.get("v")["revision"]]

    def bumped() -> None:
        rev.append(cat.venues.get("v")["revision"])
        assert rev[-1] == rev[-2] + 1, rev

    cat.venues.rename("v", "W")
    bumped()
    cat.floors.put("v", "1", {"px_per_m": 20.0})
    bumped()
    cat.floors.set_plan("v", "1", small_ds.floorplan.read_bytes())
    bumped()
    [p] = cat.places.add("v", [{"name": "A", "x": 1, "y": 1}])
    bumped()
    cat.places.delete("v", p["id"])
    bumped()
    cat.lenses.put("v", "donut", json.loads(small_ds.lens.read_text()))
    bumped()
    with pytest.raises(OmninavError):  # a refused edit bumps nothing
        cat.places.add("v", [{"name": "B", "x": "far", "y": 1}])
    assert cat.venues.get("v")["revision"] == rev[-1]


def test_a_busy_video_is_found_by_its_exact_name(cat: Catalog, small_ds) -> None:
    """Which videos a job models are rows: 'a_b.mp4' being modelled does not make 'axb.mp4' busy
    (as a LIKE over the job's JSON list did: '_' matches any character)."""
    cat.venues.create("v", "V", px_per_m=20.0)
    cat.floors.set_plan("v", "1", small_ds.floorplan.read_bytes())
    cat.lenses.put("v", "default", json.loads(small_ds.lens.read_text()))
    walk_path = json.loads(small_ds.model_walk_path.read_text())
    for name in ("a_b.mp4", "axb.mp4"):
        cat.videos.create("v", {"name": name, "size": 10, "walk_path": walk_path}, 100)
    from omninav.server.jobs import Jobs

    cat.db.run("UPDATE videos SET status = 'ready', received = size WHERE venue = 'v'")
    job = Jobs(cat).submit("v", ["a_b.mp4"])
    assert cat.videos.busy_job("v", "a_b.mp4") == job["id"]
    assert cat.videos.busy_job("v", "axb.mp4") is None
    with pytest.raises(Conflict, match=f"being modelled by job {job['id']}"):
        cat.videos.delete("v", "a_b.mp4")
    assert cat.videos.delete("v", "axb.mp4") == 0
    Jobs(cat).cancel(job["id"])
    assert cat.videos.busy_job("v", "a_b.mp4") is None


def _old_venue(data: Path, modelled, small_ds) -> None:
    """A venue as an older `omninav venue create` + `omninav model` left it: venue.json,
    settings.json and floorplan.png beside the generations, nothing in any database."""
    st, vid = modelled
    d = data / "venues" / "old"
    shutil.copytree(st.venue_dir(vid), d)
    shutil.copyfile(small_ds.floorplan, d / "floorplan.png")
    (d / "settings.json").write_text(json.dumps(st.settings(vid)))
    meta = {
        "id": "old",
        "name": "Old wing",
        "floor": "2",
        "px_per_m": 20.0,
        "floorplan": "floorplan.png",
        "preset": "default",
        "places": small_ds.scene.places,
    }
    (d / "venue.json").write_text(json.dumps(meta))


def test_a_venue_of_an_older_omninav_is_imported_once_and_served(tmp_path: Path, modelled, small_ds) -> None:
    from omninav.server import create_app

    data = tmp_path / "data"
    _old_venue(data, modelled, small_ds)
    frames = Store(data).frame_count("old")
    app = create_app({"DATA": str(data), "ADMIN_TOKEN": "t" * 32, "JOB_RUNNER": False})
    c = app.test_client()
    assert [v["id"] for v in c.get("/api/venues").get_json()["venues"]] == ["old"]
    doc = c.get("/api/venues/old").get_json()
    assert doc["name"] == "Old wing" and doc["frames"] == frames and doc["modelled"]
    [floor] = doc["floors"]
    assert floor["id"] == "2" and floor["px_per_m"] == 20.0 and floor["plan_url"]
    assert sorted(p["name"] for p in doc["places"]) == sorted(p["name"] for p in small_ds.scene.places)
    assert all(p["floor"] == "2" for p in doc["places"])
    assert len(doc["lenses"]) == 1  # the lens it was modelled with, named by its content
    d = data / "venues" / "old"
    assert not (d / "venue.json").exists() and (d / "venue.json.imported").is_file()
    assert not (d / "settings.json").exists()

    # once: an edit made since survives the next open
    cat = app.extensions["omninav"].catalog
    cat.venues.rename("old", "East wing")
    again = Catalog.open({"DATA": str(data), "DATABASE_URL": ""})
    assert again.venues.get("old")["name"] == "East wing" and len(again.places.all("old")) == len(doc["places"])


def test_an_imported_venue_that_the_catalogue_has_already_keeps_the_catalogues(tmp_path, modelled, small_ds) -> None:
    data = tmp_path / "data"
    cat = Catalog.open({"DATA": str(data), "DATABASE_URL": ""})
    cat.venues.create("old", "Made on the server")
    _old_venue(data, modelled, small_ds)
    t0 = time.time()
    again = Catalog.open({"DATA": str(data), "DATABASE_URL": ""})
    assert again.venues.get("old")["name"] == "Made on the server" and again.places.all("old") == []
    assert (data / "venues" / "old" / "venue.json.imported").stat().st_mtime >= t0 - 1
