"""The built-in demo venue, set up through the same catalogue and job queue as any other.

First start: render the synthetic venue (synth/), create venue 'demo' with its floor plan, places
and lens, register the modelling video and queue its modelling job; the server answers for the
demo as soon as the job is done (its progress shows in the admin API like any job's).
"""

from __future__ import annotations

import json
import os
import shutil
from pathlib import Path
from typing import Any

from ..synth import make_dataset
from ..synth.scene import build_scene
from .catalog import Catalog
from .jobs import Jobs

VENUE = "demo"
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


def ensure_demo(cat: Catalog, jobs: Jobs, quick: bool = False, log: Any = print) -> str | None:
    """Set the demo venue up if it is not there; returns the id of its modelling job, if one was queued."""
    if cat.db.one("SELECT id FROM venues WHERE id = :id", id=VENUE):
        return None
    layout = "small" if quick else "default"
    src = source_dir(cat.data, quick)
    if not (src / "model.mp4").exists():
        log(f"rendering the synthetic demo venue into {src} (first start only) ...")
        make_dataset(src, seed=0, layout=layout, scale=0.5 if quick else 1.0)
    cat.create_venue(VENUE, "Synthetic demo venue", "default")
    cat.put_floor(VENUE, "1", {"name": "Ground floor", "px_per_m": 20.0})
    cat.set_plan(VENUE, "1", (src / "floorplan.png").read_bytes())
    cat.add_places(VENUE, demo_places(build_scene(0, layout).places, layout), replace=True)
    cat.put_lens(VENUE, "donut", json.loads((src / "model_lens.json").read_text()))
    track = json.loads((src / "model_track.json").read_text())
    size = (src / "model.mp4").stat().st_size
    cat.create_video(VENUE, {"name": "model.mp4", "floor": "1", "size": size, "track": track, "lens": "donut"}, size)
    d = cat.video_dir(VENUE)
    d.mkdir(parents=True, exist_ok=True)
    try:  # a hard link costs nothing; copy across file systems
        os.link(src / "model.mp4", d / "model.mp4")
    except OSError:
        shutil.copyfile(src / "model.mp4", d / "model.mp4")
    cat.db.run("UPDATE videos SET received = size, status = 'ready' WHERE venue = :v AND name = 'model.mp4'", v=VENUE)
    job = jobs.submit(VENUE, ["model.mp4"])
    log(f"demo venue created; modelling job {job['id']} queued")
    return str(job["id"])
