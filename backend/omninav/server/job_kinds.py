"""What each kind of job is (jobs.py runs them all alike: queue, claim, heartbeat, retries,
ownership): which videos a modelling job takes, what an analysis job needs before it is queued,
and the engine's function each analysis kind runs, its result as plain JSON.

    model      model videos into the venue's next generation (model_venue.py)
    suggest    suggested waypoints of one video: where the walker turned or stopped (suggest.py)
    quality    the quality map of the venue's live generation (quality.py)
    evaluate   an evaluation walk located against the live generation (evaluate.py)
"""

from __future__ import annotations

import json
import math
from typing import Any

from ..catalog import Catalog
from ..errors import Conflict, NotFound, OmninavError
from ..model_venue import Progress
from ..walk_path import parse_walk_path

KINDS = ("model", "suggest", "quality", "evaluate")


def doing(kind: str, target: str | None) -> str:
    """What a job of this kind does, for the messages that name a busy job."""
    return {
        "model": "modelling",
        "suggest": f"suggesting waypoints for video {target!r}",
        "quality": "making the quality map",
        "evaluate": f"evaluating video {target!r}",
    }.get(kind, kind)


def has_walk_path(v: dict[str, Any]) -> bool:
    return bool(v["walk_path"] != "null")  # the column holds the JSON null until the walk path is tagged


def check_uploaded(v: dict[str, Any]) -> None:
    if v["status"] not in ("ready", "modelled"):
        raise Conflict(f"video {v['name']!r} is not completely uploaded ({v['received']} of {v['size']} bytes)")


def plain(x: Any) -> Any:
    """The engine's result as plain JSON values: NumPy scalars and arrays as numbers and lists,
    a number that is not finite (no JSON number) as null."""
    if isinstance(x, dict):
        return {str(k): plain(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [plain(v) for v in x]
    if hasattr(x, "tolist"):  # a NumPy array or scalar
        return plain(x.tolist())
    if isinstance(x, float) and not math.isfinite(x):
        return None
    return x


def videos_to_model(cat: Catalog, venue_id: str, names: Any, anew: bool = False) -> list[str]:
    """The names of the videos to model (default: every uploaded modelling walk with a walk path,
    not modelled yet; `anew`: every one, modelled or not, and no other choice: the new
    generation holds only the job's videos)."""
    vids = cat.videos.all(venue_id)
    if anew:
        walks = [v for v in vids if v["role"] == "model" and v["status"] in ("ready", "modelled")]
        every: list[str] = [v["name"] for v in walks if has_walk_path(v)]
        if not every:
            known = {v["name"] for v in vids}
            by_cli = [n for n in cat.store.modelled_videos(venue_id) if n not in known]
            how = (
                f"its frames are from {', '.join(map(repr, by_cli))}, modelled by the command line: "
                "omninav model ... --anew"
                if by_cli
                else "upload a modelling walk and tag its walk path first"
            )
            raise Conflict(f"venue {venue_id!r} has no uploaded modelling video with a walk path to model anew ({how})")
        # the new generation holds only these: refuse rather than drop another walk's frames
        # (modelled by the command line, or registered again and still uploading)
        if lost := [n for n in cat.store.modelled_videos(venue_id) if n not in every]:
            raise Conflict(
                f"modelling anew would drop the frames of {', '.join(map(repr, lost))}: it models only "
                "uploaded modelling videos with a walk path; upload and tag them first"
            )
        if gone := [n for n in every if not (cat.videos.dir(venue_id) / n).is_file()]:
            raise Conflict(
                f"video {gone[0]!r} has no uploaded file here (a backup restored without videos?): "
                "upload it again before modelling anew"
            )
        return every
    if names is None:
        ready = [v for v in vids if v["status"] == "ready" and v["role"] == "model"]
        names = [v["name"] for v in ready if has_walk_path(v)]
        if not names:
            untagged = [v["name"] for v in ready if not has_walk_path(v)]
            why = f" (video {untagged[0]!r} has no walk path yet)" if untagged else ""
            raise Conflict(f"venue {venue_id!r} has no uploaded video waiting to be modelled{why}")
    if not isinstance(names, list) or not names or not all(isinstance(n, str) for n in names):
        raise OmninavError("'videos' must be a non-empty list of video names")
    by_name = {v["name"]: v for v in vids}
    for n in names:
        if n not in by_name:
            raise NotFound(f"venue {venue_id!r} has no video {n!r}")
        check_uploaded(by_name[n])
        if by_name[n]["role"] != "model":
            raise Conflict(f"video {n!r} is an evaluation walk: it is evaluated, not modelled")
        if not has_walk_path(by_name[n]):
            raise Conflict(f"video {n!r} has no walk path yet")
    return list(dict.fromkeys(names))


def check_analysis(cat: Catalog, venue_id: str, kind: str, target: str | None) -> None:
    """What a suggest, quality or evaluate job needs, there before it is queued."""
    if kind not in KINDS or kind == "model":
        raise OmninavError(f"unknown kind of analysis job {kind!r}")
    if kind in ("suggest", "evaluate"):
        if target is None:
            raise OmninavError(f"a {kind} job needs a video")
        v = cat.videos.get(venue_id, target)
        check_uploaded(v)
        if kind == "evaluate":
            if v["role"] != "evaluation":
                raise Conflict(f"video {target!r} is a modelling walk; evaluate a walk uploaded with role 'evaluation'")
            if not has_walk_path(v):
                raise Conflict(f"video {target!r} has no walk path yet: tag its waypoints first")
    if kind in ("quality", "evaluate") and cat.store.generation(venue_id) is None:
        raise Conflict(f"venue {venue_id!r} has no modelled frames yet: model the venue first")


def analyse(cat: Catalog, job: dict[str, Any], progress: Progress, device: str | None) -> dict[str, Any]:
    """Run the engine's function of the job's kind; its result (JSON-able)."""
    venue, target = job["venue"], job["target"]
    if job["kind"] == "quality":
        from ..quality import quality_map

        number, _ = cat.venues.modelled(venue)  # read first: a newer load is only ever refreshed again
        gen = cat.store.load(venue)  # the live generation (Conflict: not modelled)
        q = quality_map(gen, cat.places.all(venue), cat.videos.floors(venue), device=device or "cpu", progress=progress)
        if q.get("generation") is None:  # the engine sees frames, not which generation they are
            q["generation"] = number
        return q
    v = cat.videos.get(venue, target)
    path = cat.videos.dir(venue) / v["name"]
    if v["status"] not in ("ready", "modelled") or not path.is_file():
        raise OmninavError(f"video {target!r} has no uploaded file")
    lens = cat.lenses.get(venue, v["lens"])
    if job["kind"] == "suggest":
        from ..suggest import suggest_waypoints

        return suggest_waypoints(path, lens, progress=progress)
    if job["kind"] == "evaluate":
        from ..evaluate import evaluate_walk
        from ..locate import Locator

        if not has_walk_path(v):
            raise OmninavError(f"video {target!r} has no walk path")
        places = [p for p in cat.places.all(venue) if p["floor"] == v["floor"]]
        loc = Locator(cat.store, venue, device=device, places=places, floor=v["floor"])
        return evaluate_walk(loc, path, parse_walk_path(json.loads(v["walk_path"])), lens, progress=progress)
    raise OmninavError(f"job {job['id']} is of an unknown kind {job['kind']!r}")
