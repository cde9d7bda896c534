"""The `omninav` command line: venues, modelling, locating, evaluation and the demo.

Every user mistake ends as one line `omninav: error: ...` on stderr and a non-zero exit, never
a traceback (OmninavError carries the message).
"""

from __future__ import annotations

import json
import logging
import os
import sys
import time
from pathlib import Path
from typing import TYPE_CHECKING, Any

import click

from .calib.commands import calib
from .cli_context import catalog_of, renamed_path_option
from .cli_server import SERVER_COMMANDS
from .errors import OmninavError, read_json

if TYPE_CHECKING:
    from .catalog import Catalog


def _locator(ctx: click.Context, venue_id: str, device: str | None = None) -> Any:
    """A venue's frames loaded for answering, its answers naming its places."""
    from .locate import Locator

    cat = catalog_of(ctx)
    cat.venues.get(venue_id)
    floors = cat.floors.all(venue_id)
    return Locator(cat.store, venue_id, device, cat.places.all(venue_id), floors[0]["id"] if floors else None)


def _track_locator(ctx: click.Context, venue_id: str) -> Any:
    """A venue's Locator for tracking: its walk graph with each modelling video on its own floor
    (the catalogue's) and the venue's places (lifts and stairs join floors), as the server builds
    it (server/runtimes.py), so that walks of two floors at the same x, y stay apart."""
    from .walkgraph import from_frames

    loc = _locator(ctx, venue_id)
    video_floor = catalog_of(ctx).videos.floor_list(venue_id, loc.gen.videos)
    loc.use_floors(video_floor, from_frames(loc.gen.frames, video_floor, loc.places))
    return loc


class Progress:
    """A one-line progress bar with frames/s and ETA, drawn only on a terminal."""

    def __init__(self, label: str, stream: Any = None):
        self.label = label
        self.stream = stream or sys.stderr
        self.tty = self.stream.isatty()
        self.last = 0.0

    def __call__(self, done: int, total: int, elapsed: float) -> None:
        if not self.tty or (time.monotonic() - self.last < 0.1 and done < total):
            return
        self.last = time.monotonic()
        rate = done / elapsed if elapsed > 0 else 0.0
        eta = (total - done) / rate if rate > 0 else 0.0
        frac = min(1.0, done / max(total, 1))
        bar = "#" * int(frac * 30)
        self.stream.write(
            f"\r{self.label} [{bar:<30}] {done}/{total} frames  {rate:6.1f} frames/s"
            f"  ETA {int(eta) // 60}:{int(eta) % 60:02d} "
        )
        self.stream.flush()

    def close(self) -> None:
        if self.tty:
            self.stream.write("\n")


@click.group()
@click.option(
    "--data",
    type=click.Path(file_okay=False),
    help="Data folder (default: $OMNINAV_DATA, else ./data; settings: config.py).",
)
@click.pass_context
def cli(ctx: click.Context, data: str | None) -> None:
    """omninav: indoor localisation from panoramic vision."""
    from .config import load_config

    ctx.ensure_object(dict)
    ctx.obj["overrides"] = {"DATA": data}
    ctx.obj["load"] = load_config


@cli.group()
def venue() -> None:
    """Create and inspect venues."""


@venue.command("create")
@click.argument("venue_id", metavar="VENUE")
@click.option("--name", help="Human name of the venue.")
@click.option("--floor", default="1", show_default=True, help="Id of its first floor, given in answers.")
@click.option("--floorplan", type=click.Path(path_type=Path), help="Floor plan image (PNG/JPEG).")
@click.option("--px-per-m", type=float, help="Floor plan scale, pixels per metre.")
@click.option(
    "--preset", default="default", show_default=True, help="Feature preset: default, wide (choose-preset), paper, six."
)
@click.option("--places", type=click.Path(path_type=Path), help="JSON list of {name, x, y[, area]} in metres.")
@click.pass_context
def venue_create(
    ctx: click.Context,
    venue_id: str,
    name: str | None,
    floor: str,
    floorplan: Path | None,
    px_per_m: float | None,
    preset: str,
    places: Path | None,
) -> None:
    """Create VENUE (an id of letters, digits, '-' and '_') in the catalogue the server serves."""
    from .catalog.floors import decode_plan
    from .catalog.places import check_place
    from .server.venues_api import venue_doc

    # every input is checked before anything is written: a refused venue leaves nothing behind
    plan = None
    if floorplan is not None:
        if not floorplan.is_file():
            raise OmninavError(f"{floorplan}: floor plan not found")
        plan = floorplan.read_bytes()
        try:
            decode_plan(plan)
        except OmninavError as e:
            raise OmninavError(f"{floorplan}: {e}") from None
        if px_per_m is None:
            raise OmninavError("a floor plan needs its scale: --px-per-m, a positive number")
    pl = read_json(places, "places file") if places else None
    if pl is not None:
        if not isinstance(pl, list):
            raise OmninavError(f'{places}: places must be a list of {{"name", "x", "y"}} objects')
        try:
            for i, p in enumerate(pl):
                check_place(p, i, {floor})
        except OmninavError as e:
            raise OmninavError(f"{places}: {e}") from None
    cat = catalog_of(ctx)
    cat.venues.create(venue_id, name, preset, floor, px_per_m=px_per_m)
    if plan is not None:
        cat.floors.set_plan(venue_id, floor, plan)
    if pl:
        cat.places.add(venue_id, pl)
    click.echo(json.dumps(venue_doc(cat, venue_id)))


@venue.command("list")
@click.pass_context
def venue_list(ctx: click.Context) -> None:
    """List venues, one JSON object per line."""
    cat = catalog_of(ctx)
    for v in cat.venues.all():
        click.echo(json.dumps({"id": v["id"], "name": v["name"], "frames": cat.store.frame_count(v["id"])}))


@venue.command("delete")
@click.argument("venue_id", metavar="VENUE")
@click.option("--yes", is_flag=True, help="Do not ask for confirmation.")
@click.pass_context
def venue_delete(ctx: click.Context, venue_id: str, yes: bool) -> None:
    """Delete a venue and everything of it: its jobs (cancelled), modelled frames, floor plans,
    places, lenses, videos and job results. Prints what went, as JSON."""
    cat = catalog_of(ctx)
    v = cat.venues.get(venue_id)  # (unknown venue: refused before the question)
    if not yes:
        n = len(cat.videos.all(venue_id))
        click.confirm(
            f"Delete venue {venue_id!r} ({v['name']}): {cat.store.frame_count(venue_id)} modelled frames, "
            f"{n} videos, its plans and places?",
            abort=True,
        )
    click.echo(json.dumps(cat.venues.delete(venue_id)))


@cli.command()
@click.argument("venue_id", metavar="VENUE")
@click.argument("video", type=click.Path(path_type=Path))
@renamed_path_option("--walk-path", "--track", "walk_path_file", help="walk_path.json")
@click.option("--lens", "lens_path", required=True, type=click.Path(path_type=Path), help="lens.json")
@click.option(
    "--anew",
    is_flag=True,
    help="Model the venue anew from this walk with its preset's settings as they are now (a venue "
    "modelled before the preset improved): its frames replace all the venue's.",
)
@click.pass_context
def model(ctx: click.Context, venue_id: str, video: Path, walk_path_file: Path, lens_path: Path, anew: bool) -> None:
    """Model VENUE from a panoramic VIDEO and its walk path (where the recorder was, and when)."""
    from .lens import load_lens
    from .model_venue import VideoSource, model_videos
    from .walk_path import load_walk_path

    cat = catalog_of(ctx)
    # (unknown venue: refused here, before any work)
    settings = cat.venues.preset_settings(venue_id) if anew else cat.venues.settings(venue_id)
    check = (lambda: _check_anew(cat, venue_id, video.name)) if anew else None
    if check:
        check()
    walk_path, lens = load_walk_path(walk_path_file), load_lens(lens_path)
    bar = Progress(f"modelling {video.name}{' anew' if anew else ''}")
    try:
        sources = [VideoSource(video, walk_path, lens)]
        (r,) = model_videos(cat.store, venue_id, sources, bar, before_commit=check, settings=settings, anew=anew)
    finally:
        bar.close()
    cat.lenses.put_inline(venue_id, lens.to_dict(), where=str(lens_path))  # the server can name it too
    cat.venues.touch(venue_id)
    click.echo(
        json.dumps(
            {
                "venue": r.venue,
                "video": r.video,
                "frames_added": r.frames,
                "venue_frames": r.total_frames,
                "seconds": round(r.seconds, 2),
                "x_realtime": round(r.speed_x_realtime, 1),
            }
        )
    )


def _check_anew(cat: Catalog, venue_id: str, name: str) -> None:
    """A modelling anew from the command line replaces every frame with one walk's: refused where
    frames of another walk would be lost, or where the venue's modelling walks were uploaded (the
    admin page's modelling anew models every one of them, from the uploads). Checked before the
    work and again under the venue's lock before the commit (a job may have added a walk since)."""
    uploaded = [v["name"] for v in cat.videos.all(venue_id) if v["role"] == "model"]
    if uploaded:
        raise OmninavError(
            f"venue {venue_id!r} has uploaded modelling videos ({', '.join(map(repr, uploaded))}): model it anew "
            f'on the admin page (or POST /api/admin/venues/{venue_id}/jobs with {{"anew": true}}), which models '
            "every one of them"
        )
    lost = [v for v in cat.store.modelled_videos(venue_id) if v != name]
    if lost:
        raise OmninavError(
            f"modelling venue {venue_id!r} anew from {name!r} alone would drop the frames of "
            f"{', '.join(map(repr, lost))}; model each walk into a new venue instead (omninav venue create, "
            "then omninav model for every walk), or upload the walks and model them anew on the admin page"
        )


@cli.command()
@click.argument("venue_id", metavar="VENUE")
@click.argument("clips", nargs=-1, required=True, type=click.Path(path_type=Path))
@click.option(
    "--lens",
    "lens_path",
    type=click.Path(path_type=Path),
    help="Lens of the clips (default: the venue's modelling lens).",
)
@click.option("--aggregate", type=click.Choice(["median", "sequence"]), help="Clip aggregation.")
@click.option("--device", type=click.Choice(["auto", "cpu", "gpu"]), help="Search device.")
@click.pass_context
def locate(
    ctx: click.Context,
    venue_id: str,
    clips: tuple[Path, ...],
    lens_path: Path | None,
    aggregate: str | None,
    device: str | None,
) -> None:
    """Locate each CLIP (a video, a directory of frames, or a feature record .onv/.json)."""
    from .lens import load_lens
    from .locate import RECORD_SUFFIXES, clip_frames, read_record

    lens = load_lens(lens_path) if lens_path else None
    loc = _locator(ctx, venue_id, device)
    for c in clips:  # check every path first: fail before printing half the answers
        if not c.exists():
            raise OmninavError(f"{c}: clip not found")
    for c in clips:
        if c.suffix.lower() in RECORD_SUFFIXES:  # features extracted elsewhere (a phone)
            spec, local = read_record(c, loc.conf)
            answer = loc.locate_spectra(spec, c.name, None, aggregate, local)
        else:
            frames, fps = clip_frames(c, loc.conf["model_fps"])
            answer = loc.locate_frames(frames, c.name, lens, fps, aggregate)
        click.echo(json.dumps(answer))


@cli.command()
@click.argument("venue_id", metavar="VENUE")
@click.argument("walk", type=click.Path(path_type=Path))
@click.option("--lens", "lens_path", type=click.Path(path_type=Path), help="Lens of the walk (default: the venue's).")
@click.option(
    "--every", type=click.FloatRange(0.1, 60.0), default=1.0, show_default=True, help="Seconds between answers."
)
@click.option("--imu", "imu_path", type=click.Path(path_type=Path), help="The phone's steps and yaw (imu.json).")
@click.option(
    "--fps",
    type=click.FloatRange(0.1, 240.0, min_open=True),
    default=10.0,
    show_default=True,
    help="Frame rate of a directory of frames (a video carries its own).",
)
@click.pass_context
def track(
    ctx: click.Context,
    venue_id: str,
    walk: Path,
    lens_path: Path | None,
    every: float,
    imu_path: Path | None,
    fps: float,
) -> None:
    """Track a WALK (a video or a directory of frames) through VENUE: one JSON answer per --every
    seconds, the pose at that moment from only the walk up to it (the walk since the last answer,
    at least its last second, and the filter's memory of the walk before)."""
    from .evaluate import track_walk, walk_spectra
    from .lens import load_lens
    from .motion import load_imu

    lens = load_lens(lens_path) if lens_path else None
    imu = load_imu(imu_path) if imu_path is not None else None
    if not walk.exists():
        raise OmninavError(f"{walk}: walk not found")
    loc = _track_locator(ctx, venue_id)
    bar = Progress(f"reading {walk.name}")
    try:
        spec, t, _ = walk_spectra(loc, walk, lens, bar, fps)
    finally:
        bar.close()
    for e, pose, _est, _n in track_walk(loc, spec, t, every, imu):
        click.echo(json.dumps(loc.track_answer(pose, walk.name, float(t[e]))))


@cli.command()
@click.argument("venue_id", metavar="VENUE")
@click.argument("clip", type=click.Path(path_type=Path))
@click.option("--lens", "lens_path", type=click.Path(path_type=Path), help="Lens of the clip (default: the venue's).")
@click.option("-o", "--out", type=click.Path(path_type=Path), help="Write here; .onv is binary, else JSON.")
def features(venue_id: str, clip: Path, lens_path: Path | None, out: Path | None) -> None:
    """Extract CLIP's feature record with VENUE's settings: what a phone sends instead of images
    (for a venue with local features, its last frame's too: a version-2 record)."""
    from .calib.correct import clip_spectra
    from .extract import Extractors
    from .lens import load_lens
    from .locate import clip_frames
    from .spectrum import encode_binary, encode_json

    ctx = click.get_current_context()
    cat = catalog_of(ctx)
    conf = cat.venues.settings(venue_id)
    if lens_path:
        lens = load_lens(lens_path)  # its own errors name the file and the field
    else:
        try:
            lens = cat.store.load(venue_id).lens
        except OmninavError:
            raise OmninavError("give --lens: the venue has no modelled frames, so no lens of its own") from None
    exts = Extractors(conf)
    frames, _ = clip_frames(clip, conf["model_fps"])
    exts.get(lens).check_frame(frames[0], str(clip))
    spec, c = clip_spectra(lens, frames, exts.spectrum, clip=str(clip))
    local = None
    if conf.get("local_features"):  # a venue that verifies: its last frame's local features too
        from .verify import detect

        local = detect(frames[-1], c.lens, int(conf["local_features"]))
    if out is not None and out.suffix.lower() == ".onv":
        out.write_bytes(encode_binary(spec, conf, local))
    else:
        text = json.dumps(encode_json(spec, conf, local), separators=(",", ":"))
        if out is None:
            click.echo(text)
        else:
            out.write_text(text)


@cli.command()
@click.argument("venue_id", metavar="VENUE")
@click.argument("video", type=click.Path(path_type=Path))
@renamed_path_option("--walk-path", "--track", "walk_path_file", help="walk_path.json")
@click.option("--lens", "lens_path", required=True, type=click.Path(path_type=Path))
@click.option("--aggregate", type=click.Choice(["median", "sequence"]))
@click.option("--plot", "plot_path", type=click.Path(path_type=Path), help="PNG (default: VIDEO.eval.png).")
@click.option("--json", "as_json", is_flag=True, help="Print the summary as JSON.")
@click.option("--clips", is_flag=True, help="Print every clip's truth and answer as JSON (what the admin page shows).")
@click.option(
    "--clip-s",
    type=click.FloatRange(0.3, 5.0, min_open=True),
    default=1.0,
    show_default=True,
    help="Clip length in seconds: the app films 1 s, and up to 3 s when unsure.",
)
@click.option(
    "--track-mode",
    is_flag=True,
    help="Also track along the walk (one answer per --every s): filtered accuracy beside the single clips'.",
)
@click.option(
    "--every",
    type=click.FloatRange(0.1, 60.0),
    default=1.0,
    show_default=True,
    help="With --track-mode: seconds between answers (the app: every 2-3 s), each from the walk since the last.",
)
@click.option("--imu", "imu_path", type=click.Path(path_type=Path), help="With --track-mode: the walk's imu.json.")
@click.pass_context
def evaluate(
    ctx: click.Context,
    venue_id: str,
    video: Path,
    walk_path_file: Path,
    lens_path: Path,
    aggregate: str | None,
    plot_path: Path | None,
    as_json: bool,
    clips: bool,
    clip_s: float,
    track_mode: bool,
    every: float,
    imu_path: Path | None,
) -> None:
    """Cut a second walk into clips (1 s unless --clip-s), locate each, report accuracy against its walk path."""
    from .evaluate import evaluate as run
    from .evaluate import plot, walk_result
    from .lens import load_lens
    from .walk_path import load_walk_path

    walk_path, lens = load_walk_path(walk_path_file), load_lens(lens_path)
    out = plot_path or video.with_suffix(".eval.png")
    if not out.parent.is_dir():  # fail before the work, not after
        raise OmninavError(f"{out.parent}: folder for the plot does not exist")
    if (imu_path is not None or every != 1.0) and not track_mode:
        raise OmninavError("--every and --imu go with --track-mode")
    if track_mode:
        if clips or clip_s != 1.0 or aggregate is not None:
            raise OmninavError(
                "--track-mode answers the walk since the last answer (at least 1 s) with the venue's "
                "aggregation: no --clips, --clip-s, --aggregate"
            )
        _evaluate_track(ctx, venue_id, video, walk_path, lens, out, as_json, every, imu_path)
        return
    loc = _locator(ctx, venue_id)
    ev = run(loc, video, walk_path, lens, aggregate, clip_s)
    s = ev.summary()
    plot(ev, loc, out)
    s["plot"] = str(out)
    if clips:
        click.echo(json.dumps(walk_result(ev)))
    elif as_json:
        click.echo(json.dumps(s))
    else:
        click.echo(_table([(aggregate or loc.conf["aggregate"], s)]))


@cli.command()
@click.argument("venue_id", metavar="VENUE")
@click.option("-o", "--out", type=click.Path(path_type=Path), help="Write the quality map's JSON here.")
@click.option("--png", "png_path", type=click.Path(path_type=Path), help="Draw it on a floor's plan, as a PNG.")
@click.option("--floor", help="The floor to draw (default: the venue's first).")
@click.option("--device", type=click.Choice(["auto", "cpu", "gpu"]), help="Search device.")
@click.pass_context
def quality(
    ctx: click.Context, venue_id: str, out: Path | None, png_path: Path | None, floor: str | None, device: str | None
) -> None:
    """Where would VENUE answer right? Locate every second of its modelling walks without itself,
    colour the walk and the corridors, print the summary sentence."""
    import cv2

    from .catalog.floors import decode_plan
    from .quality import quality_map, quality_png

    cat = catalog_of(ctx)
    cat.venues.get(venue_id)
    floors = {f["id"]: f for f in cat.floors.all(venue_id)}
    first = min(floors) if floors else "1"
    floor = floor or first
    plan = cat.floors.plan_path(venue_id, floor)
    for path in (out, png_path):  # fail before the work, not after
        if path is not None and not path.parent.is_dir():
            raise OmninavError(f"{path.parent}: folder does not exist")
    if png_path is not None and (floor not in floors or not plan.is_file()):
        raise OmninavError(f"floor {floor!r} of {venue_id} has no plan to draw on")
    live = cat.store.generation(venue_id)  # read first: a newer load is only ever refreshed again
    gen = cat.store.load(venue_id)
    vf = cat.videos.floors(venue_id)
    bar = Progress(f"quality map of {venue_id}")
    try:
        result = quality_map(
            gen,
            cat.places.all(venue_id),
            {name: vf.get(name, first) for name in gen.videos},
            device or os.environ.get("OMNINAV_DEVICE") or "auto",
            progress=bar,
        )
    finally:
        bar.close()
    result["generation"] = int(live.split("-")[1]) if live else None
    if out is not None:
        out.write_text(json.dumps(result))
    if png_path is not None:
        rgb = cv2.cvtColor(decode_plan(plan.read_bytes()), cv2.COLOR_BGR2RGB)
        png_path.write_bytes(quality_png(result, rgb, floors[floor]["px_per_m"] or 1.0, floor))
    click.echo(result["sentence"])


def _evaluate_track(
    ctx: click.Context,
    venue_id: str,
    video: Path,
    walk_path: Any,
    lens: Any,
    out: Path,
    as_json: bool,
    every: float,
    imu_path: Path | None,
) -> None:
    """evaluate --track-mode: the walk answered every `every` s alone and through the filter."""
    from .evaluate import evaluate_track, plot, query_spectra, track_summary
    from .motion import load_imu

    imu = load_imu(imu_path) if imu_path is not None else None
    loc = _track_locator(ctx, venue_id)
    bar = Progress(f"reading {video.name}")
    try:
        spec = query_spectra(loc, video, walk_path, lens, bar)
    finally:
        bar.close()
    single, tracked = evaluate_track(loc, *spec, every=every, imu=imu)
    plot(tracked, loc, out, title="tracking: filtered answers")
    s1, s2 = track_summary(single), track_summary(tracked)
    if as_json:
        click.echo(json.dumps({"single": s1, "track": s2, "every_s": every, "imu": imu is not None, "plot": str(out)}))
        return
    click.echo(f"answers every {every:g} s, after the first {s2['skip_s']:g} s{' (with IMU)' if imu else ''}")
    rows = [(f"single clip ({loc.conf['aggregate']})", s1), ("tracking (filter)", s2)]
    click.echo(_table(rows, confident=True))


def _table(rows: list[tuple[str, dict[str, Any]]], confident: bool = False) -> str:
    head = f"{'method':<28}{'clips':>6}{'<=1 m':>8}{'<=2 m':>8}{'median m':>10}{'heading med':>13}"
    if confident:  # track mode: the trusted answers (>= 0.8) that were far off
        head += f"{'conf>=.8':>10}{'>5 m':>6}{'>2 m':>6}"
    lines = [head, "-" * len(head)]
    for name, s in rows:
        lines.append(
            f"{name:<28}{s['clips']:>6}{s['within_1m']:>8.1%}{s['within_2m']:>8.1%}"
            f"{s['median_err_m']:>10.2f}{s['median_heading_err_deg']:>12.2f}°"
            + (
                f"{s['confident_share']:>10.1%}{s['confident_over_5m']:>6}{s['confident_over_2m']:>6}"
                if confident
                else ""
            )
        )
    return "\n".join(lines)


@cli.command("choose-preset")
@click.argument("walk", type=click.Path(path_type=Path))
@renamed_path_option("--walk-path", "--track", "walk_path_file", help="The walk's waypoints (walk_path.json).")
@click.option("--lens", "lens_path", required=True, type=click.Path(path_type=Path), help="The walk's lens.json.")
@click.option("--eval", "eval_path", required=True, type=click.Path(path_type=Path), help="An evaluation walk (video).")
@renamed_path_option("--eval-walk-path", "--eval-track", "eval_walk_path_file", help="Its waypoints (walk_path.json).")
@click.option("--eval-lens", "eval_lens_path", type=click.Path(path_type=Path), help="Its lens (default: --lens).")
@click.option(
    "--presets", help="Presets to choose among, comma-separated, the one to keep first (default: default,wide)."
)
@click.option("--json", "as_json", is_flag=True, help="Print each preset's summary and the choice as JSON.")
def choose_preset(
    walk: Path,
    walk_path_file: Path,
    lens_path: Path,
    eval_path: Path,
    eval_walk_path_file: Path,
    eval_lens_path: Path | None,
    presets: str | None,
    as_json: bool,
) -> None:
    """Model WALK with each preset, locate an evaluation walk against each, and say which preset to
    create the building's venue with (nothing is written to the catalogue)."""
    import numpy as np

    from .choose import CANDIDATES, check_presets, compare_presets
    from .lens import load_lens
    from .video import VideoInfo
    from .walk_path import load_walk_path

    asked = [p.strip() for p in presets.split(",") if p.strip()] if presets is not None else list(CANDIDATES)
    names = check_presets(asked)  # every check before the minutes of modelling
    if walk.resolve() == eval_path.resolve():
        raise OmninavError("--eval must be another walk than the one modelled: a walk finds itself anywhere")
    VideoInfo(walk)
    info = VideoInfo(eval_path)
    walk_path, lens, eval_walk_path = (
        load_walk_path(walk_path_file),
        load_lens(lens_path),
        load_walk_path(eval_walk_path_file),
    )
    eval_lens = load_lens(eval_lens_path) if eval_lens_path else lens
    # the walk path's times are its frames over its fps, as `evaluate` reads them
    if not eval_walk_path.pose_at(np.arange(max(info.frames, 1)) / eval_walk_path.fps)[2].any():
        raise OmninavError(f"{eval_path}: no frame lies within the times of {eval_walk_path_file}")
    say = None if as_json else (lambda m: click.echo(m, err=True))
    results, chosen = compare_presets(walk, walk_path, lens, eval_path, eval_walk_path, eval_lens, names, say)
    if as_json:
        click.echo(json.dumps({"presets": results, "chosen": chosen}))
        return
    click.echo(_table([(r["preset"], r) for r in results]))
    click.echo(
        f"chosen: {chosen} (the first unless another places clearly more clips within 2 m): "
        f"omninav venue create VENUE --preset {chosen}"
    )


@cli.command("suggest-waypoints")
@click.argument("video", type=click.Path(path_type=Path))
@click.option("--lens", "lens_path", required=True, type=click.Path(path_type=Path), help="lens.json")
@click.option("-o", "--out", type=click.Path(path_type=Path), help="Write the suggestions here as JSON.")
def suggest_waypoints_cmd(video: Path, lens_path: Path, out: Path | None) -> None:
    """Find where the walk in VIDEO turned and stopped: the moments worth a waypoint."""
    from .lens import load_lens
    from .suggest import suggest_waypoints

    lens = load_lens(lens_path)
    if out is not None and not out.parent.is_dir():  # fail before the work, not after
        raise OmninavError(f"{out.parent}: folder for the suggestions does not exist")
    bar = Progress(f"reading {video.name}")
    try:
        r = suggest_waypoints(video, lens, progress=bar)
    finally:
        bar.close()
    if out is not None:
        out.write_text(json.dumps(r))
    click.echo(_suggestion_table(r))


def _suggestion_table(r: dict[str, Any]) -> str:
    """The suggestions as a table a person reads: time (m:ss.s), what happened, how much."""
    lines = [f"{'time':>8}  {'what':<6}{'':>14}", "-" * 30]
    for s in r["suggestions"]:
        t = s["t"]
        what = ""
        if s["kind"] == "turn":
            what = f"{abs(s['turn_deg']):.0f}° {'right' if s['turn_deg'] > 0 else 'left'}"
        elif s["kind"] == "stop":
            what = f"{s['duration_s']:.1f} s"
        stamp = f"{int(t // 60)}:{t % 60:04.1f}"
        lines.append(f"{stamp:>8}  {s['kind']:<6}{what:>14}")
    turns = sum(s["kind"] == "turn" for s in r["suggestions"])
    stops = sum(s["kind"] == "stop" for s in r["suggestions"])
    lines.append(f"{turns} turn(s) and {stops} stop(s) in {r['duration_s']:.1f} s of video")
    return "\n".join(lines)


@cli.command()
@click.argument("out", type=click.Path(path_type=Path))
@click.option("--seed", default=0, show_default=True)
@click.option("--layout", type=click.Choice(["default", "small", "twin"]), default="default", show_default=True)
@click.option("--scale", default=1.0, show_default=True, help="Donut image scale (1 = 960x720).")
@click.option("--fps", default=10.0, show_default=True)
@click.option("--model-lens", type=click.Choice(["donut", "equirect"]), default="donut", show_default=True)
def synth(out: Path, seed: int, layout: str, scale: float, fps: float, model_lens: str) -> None:
    """Render a synthetic venue into OUT: modelling and query videos, walk paths, lens, floor plan."""
    from .synth import equirect_lens, make_dataset

    ml = equirect_lens() if model_lens == "equirect" else None
    ds = make_dataset(out, seed=seed, layout=layout, fps=fps, scale=scale, model_lens=ml)
    (out / "places.json").write_text(json.dumps(ds.scene.places))
    click.echo(json.dumps({"dir": str(out), "px_per_m": ds.px_per_m}))


@cli.command()
@click.option("--quick", is_flag=True, help="A small venue at half resolution (about a minute).")
@click.option("--venue", "venue_id", help="Venue id (default: demo, or demo-quick with --quick).")
@click.pass_context
def demo(ctx: click.Context, quick: bool, venue_id: str | None) -> None:
    """Set up the built-in synthetic venue (as `omninav serve` does), model it, evaluate it, print the table."""
    from .demo import ensure_demo, model_now, render
    from .evaluate import evaluate as run
    from .evaluate import plot
    from .lens import load_lens
    from .walk_path import load_walk_path

    cat = catalog_of(ctx)
    # the quick and the full demo are different venues: never let one answer for the other
    venue_id = venue_id or ("demo-quick" if quick else "demo")
    src = render(cat.data, quick, log=lambda m: click.echo(m, err=True))
    rows = []
    for vid, preset, agg in ((venue_id, "default", "sequence"), (f"{venue_id}-paper", "paper", "median")):
        ensure_demo(cat, quick, log=lambda m: click.echo(m, err=True), venue_id=vid, preset=preset)
        if cat.store.generation(vid) is None:
            bar = Progress(f"modelling {vid}")
            try:
                model_now(cat, vid, bar)
            finally:
                bar.close()
        loc = _locator(ctx, vid)
        ev = run(
            loc, src / "query.mp4", load_walk_path(src / "query_walk_path.json"), load_lens(src / "lens.json"), agg
        )
        plot(ev, loc, src / f"{vid}.eval.png")
        label = "omninav (sequence)" if preset == "default" else "paper (I curve, median)"
        rows.append((label, ev.summary()))
    click.echo(_table(rows))
    click.echo(f"plots: {src}/*.eval.png")


cli.add_command(calib)
for command in SERVER_COMMANDS:
    cli.add_command(command)


def _say_warnings() -> None:
    """The engine's warnings (a clip whose lens ring was unusable) as one line each on stderr."""
    h = logging.StreamHandler(sys.stderr)
    h.setFormatter(logging.Formatter("omninav: warning: %(message)s"))
    lg = logging.getLogger("omninav.calib")
    lg.addHandler(h)
    lg.propagate = False


def main() -> None:
    _say_warnings()
    try:
        cli.main(standalone_mode=False, prog_name="omninav")
    except OmninavError as e:
        click.echo(f"omninav: error: {e}", err=True)
        sys.exit(2)
    except click.exceptions.Abort:
        click.echo("omninav: interrupted; nothing was changed", err=True)
        sys.exit(130)
    except click.ClickException as e:
        e.show()
        sys.exit(e.exit_code)
    except KeyboardInterrupt:
        click.echo("omninav: interrupted; nothing was changed", err=True)
        sys.exit(130)
    except BrokenPipeError:
        os._exit(0)
    except OSError as e:  # the file system said no: permissions, a full disk, a path that is a dir
        click.echo(f"omninav: error: {e.filename or ''}: {e.strerror or e}".replace(": :", ":"), err=True)
        sys.exit(2)
    except Exception as e:  # a bug: still one line for the user, the traceback on request
        if os.environ.get("OMNINAV_DEBUG"):
            raise
        click.echo(f"omninav: internal error: {type(e).__name__}: {e} (OMNINAV_DEBUG=1 shows the traceback)", err=True)
        sys.exit(70)
