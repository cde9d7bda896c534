"""The built-in demo venue, set up through the catalogue like any other: one set-up for the server
(`omninav serve --demo`, which queues its modelling job) and the CLI (`omninav demo`, which models
it at once and prints the accuracy table).

First use: render the synthetic venue (synth/) into `<data>/demo-src[-quick]`, create the venue
with its floor plan, places and lens, and register the modelling video, ready to model.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from .catalog import Catalog
from .errors import Conflict
from .model_venue import Progress, model_videos
from .synth import make_dataset, upgrade_names
from .synth.scene import build_scene

VENUE = "demo"
VIDEO = "model.mp4"
NAME = "Synthetic demo venue"
# named landmarks along the synthetic corridors (scene.py layouts); the corridors are the areas
LANDMARKS = {
    "default": [
        ("the reception desk", 3.0, 3.0), ("Room 101", 15.0, 3.0), ("the lifts", 27.0, 3.0),
        ("Room 102", 39.0, 3.0), ("the café", 51.0, 3.0), ("the main entrance", 3.0, 13.0),
        ("the notice board", 27.0, 13.0), ("the fire exit", 51.0, 13.0), ("the library", 3.0, 23.0),
        ("Room 201", 15.0, 23.0), ("the stairs", 27.0, 23.0), ("Room 202", 39.0, 23.0), ("the toilets", 51.0, 23.0),
    ],
    "small": [("the entrance", 2.0, 2.0), ("Room 1", 11.0, 2.0), ("the lifts", 20.0, 2.0), ("the stairs", 20.0, 12.0)],
}  # fmt: skip


def demo_places(scene_places: list[dict[str, Any]], layout: str) -> list[dict[str, Any]]:
    areas = [{**p, "floor": "1"} for p in scene_places if p.get("area")]
    return areas + [{"name": n, "floor": "1", "x": x, "y": y} for n, x, y in LANDMARKS[layout]]


def source_dir(data: Path, quick: bool) -> Path:
    return data / ("demo-src-quick" if quick else "demo-src")


def render(data: Path, quick: bool, log: Any = print) -> Path:
    """The rendered synthetic venue (rendered on first use): videos, walk paths, lenses, plan."""
    src = source_dir(data, quick)
    if not (src / "query.mp4").exists():
        log(f"rendering the synthetic demo venue into {src} (first use only) ...")
        make_dataset(src, seed=0, layout="small" if quick else "default", scale=0.5 if quick else 1.0)
    return upgrade_names(src)


def ensure_demo(
    cat: Catalog, quick: bool = False, log: Any = print, venue_id: str = VENUE, preset: str = "default"
) -> bool:
    """Set the demo venue up if it is not there; True when it was, and its video waits to be
    modelled. An existing venue of that id made from the other layout is refused: the quick and
    the full demo must never answer for each other."""
    layout = "small" if quick else "default"
    if cat.venues.exists(venue_id):
        # which layout it holds: its first landmark is there (the two layouts share none)
        if LANDMARKS[layout][0][0] not in {p["name"] for p in cat.places.all(venue_id)}:
            raise Conflict(
                f"venue {venue_id!r} holds the {'full' if quick else 'quick'} demo; "
                f"name another venue (--venue) or use another data folder"
            )
        return False
    src = render(cat.data, quick, log)
    cat.venues.create(venue_id, NAME, preset, "1", "Ground floor", px_per_m=20.0)
    cat.floors.set_plan(venue_id, "1", (src / "floorplan.png").read_bytes())
    cat.places.add(venue_id, demo_places(build_scene(0, layout).places, layout), replace=True)
    cat.lenses.put(venue_id, "donut", json.loads((src / "model_lens.json").read_text()))
    walk_path = json.loads((src / "model_walk_path.json").read_text())
    cat.videos.add_file(venue_id, src / VIDEO, "1", "donut", walk_path)
    return True


def model_now(cat: Catalog, venue_id: str, progress: Progress | None = None) -> None:
    """Model the venue's waiting videos in this process (the CLI; the server queues a job)."""
    names = [v["name"] for v in cat.videos.all(venue_id) if v["status"] == "ready"]
    if not names:
        return
    results = model_videos(
        cat.store, venue_id, cat.videos.sources(venue_id, names), progress, settings=cat.venues.settings(venue_id)
    )
    from .catalog.venues import bump

    with cat.db.tx() as c:
        cat.videos.mark_modelled(c, venue_id, results)
        bump(c, venue_id)
