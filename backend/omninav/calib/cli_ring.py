"""`omninav calib ring` (where is the donut ring?) and `omninav calib check` (does a video fit a
lens profile?), on a video (MP4/QuickTime) or a set of still images (PNG, JPEG, PGM/PPM/PBM,
BMP or TIFF: media.STILL_IMAGES, the formats calibration sets come in).

Inputs are read as media.py reads untrusted files: the header's size and length are checked before
a pixel is decoded, a video's frames are sampled evenly over it, one at a time.
"""

from __future__ import annotations

import json
import mmap
import sys
from collections.abc import Iterator
from pathlib import Path
from typing import Any, cast

import click
import numpy as np

from ..errors import OmninavError

MAX_SIDE = 8192  # px: a frame larger than 8K is no phone video
MAX_IMAGES = 500
MAX_IMAGE_BYTES = 64 * 1024 * 1024
SURROUND_WORDS = {
    "darker": "darker than the ring's outer edge",
    "brighter": "brighter than the ring's outer edge (a bright housing or wall)",
}
MAX_FRAMES = 500  # --max-frames: far more frames than a ring or a calibration needs
MAX_PIXELS = 600_000_000  # decoded pixels held at once: 1.8 GB (300 frames of 1920x1080)
MAX_DECODED = 200_000  # frames a video may make us decode (skipped frames are decoded too)


def _video_header(path: Path) -> tuple[int, int, int] | None:
    """(width, height, frames) of an MP4/QuickTime file's first video track, from its boxes; None
    if it is not one (frames 0: the file does not say)."""
    from ..media import probe_mp4

    with path.open("rb") as fh:
        if path.stat().st_size == 0:
            return None
        with mmap.mmap(fh.fileno(), 0, access=mmap.ACCESS_READ) as mm:
            tracks = probe_mp4(cast(bytes, mm))  # the box walk slices and unpacks: an mmap does both
    if not tracks:
        return None
    t = tracks[0]
    return t.width, t.height, t.frames


def _sampled(path: Path, frames: int, k: int) -> Iterator[np.ndarray]:
    """k BGR frames spread evenly over a video of `frames` frames (its declared count; 0: unknown,
    then its first k), the first and the last included: a calibration video's protocol starts at
    its first frames (the board held straight ahead)."""
    from ..media import iter_picked

    if frames <= 0:
        return iter_picked(path, lambda i: i < k, min(k, MAX_DECODED))
    want = set(np.linspace(0, frames - 1, min(k, frames)).round().astype(int).tolist())
    return iter_picked(path, want.__contains__, min(max(want) + 1, MAX_DECODED))


max_frames_option = click.option(
    "--max-frames",
    type=click.IntRange(1, MAX_FRAMES),
    default=40,
    show_default=True,
    help="Frames used, spread over a video.",
)


def _check_pixels(n: int) -> None:
    """What the frames held at once cost (3 bytes a pixel), before any is decoded."""
    if n > MAX_PIXELS:
        raise OmninavError(
            f"{n / 1e6:.0f} megapixels of frames at once; at most {MAX_PIXELS / 1e6:.0f}: "
            "give fewer or smaller images (or a smaller --max-frames)"
        )


def _check_size(w: int, h: int, what: str) -> None:
    if w > MAX_SIDE or h > MAX_SIDE:
        raise OmninavError(f"{what} is {w}x{h} pixels; frames of at most {MAX_SIDE} a side are read")


def read_frames(paths: list[Path], max_frames: int = 40) -> list[np.ndarray]:
    """BGR frames of one video (up to `max_frames`, spread evenly over it) or of still images
    (media.STILL_IMAGES, all of one size; grey ones made BGR). Every header is checked before any
    pixel is decoded."""
    from ..media import STILL_IMAGES, decode_image, image_formats, probe_image, still_format

    stills = image_formats(STILL_IMAGES)

    if not paths:
        raise OmninavError("give a video or some images")
    for p in paths:
        if not p.is_file():
            raise OmninavError(f"{p}: not found" if not p.exists() else f"{p}: not a file")
    if not 1 <= max_frames <= MAX_FRAMES:
        raise OmninavError(f"--max-frames must be 1 to {MAX_FRAMES}")
    with paths[0].open("rb") as fh:  # (by its magic bytes: the whole file's header is read below)
        is_image = still_format(fh.read(16), STILL_IMAGES) is not None
    if len(paths) == 1 and not is_image:
        head = _video_header(paths[0])
        if head is None:
            raise OmninavError(f"{paths[0]}: not an MP4/QuickTime video nor an image of these formats: {stills}")
        w, h, n = head
        _check_size(w, h, str(paths[0]))
        _check_pixels(w * h * min(max_frames, n or max_frames))
        frames = list(_sampled(paths[0], n, max_frames))
        if not frames:
            raise OmninavError(f"{paths[0]}: the video does not decode (no readable frames)")
        return frames
    if len(paths) > MAX_IMAGES:
        raise OmninavError(f"{len(paths)} images; give at most {MAX_IMAGES}")
    size = None
    for p in paths:
        if p.stat().st_size > MAX_IMAGE_BYTES:
            raise OmninavError(f"{p}: over {MAX_IMAGE_BYTES // 2**20} MB; not a frame of a phone video")
        im = probe_image(p.read_bytes(), STILL_IMAGES)
        if im is None:
            raise OmninavError(f"{p}: not a readable image of these formats: {stills} (give one video, or images)")
        _check_size(im.width, im.height, str(p))
        if size is not None and (im.width, im.height) != size:
            raise OmninavError(
                f"{p} is {im.width}x{im.height} but {paths[0]} is {size[0]}x{size[1]}: "
                "give frames of one camera at one resolution"
            )
        size = (im.width, im.height)
    assert size is not None
    _check_pixels(size[0] * size[1] * len(paths))
    out = []
    for p in paths:
        img = decode_image(p.read_bytes(), STILL_IMAGES)
        if img is None:
            raise OmninavError(f"{p}: not a readable image of these formats: {stills}")
        out.append(img)
    return out


def _ring_text(ring: Any) -> str:
    """The ring in words: centre, radii and their spreads, how much shows, how many frames."""
    sp = ring.spread or {}
    lines = [
        f"centre   {ring.center[0]:.2f}, {ring.center[1]:.2f} px  (spread {sp.get('center_px', 0.0):.2f} px)",
        f"r_outer  {ring.r_outer:.2f} px  (spread {sp.get('r_outer_px', 0.0):.2f} px)",
        (
            f"r_inner  {ring.r_inner:.2f} px  (spread {sp.get('r_inner_px', 0.0):.2f} px)"
            if ring.r_inner > 0
            else "r_inner  0 (no dark centre: a fisheye-like lens)"
        ),
        f"visible  {100 * ring.visible:.1f} % of the outer circle is inside the {ring.image_size[0]}x"
        f"{ring.image_size[1]} picture",
        f"frames   the ring showed in {ring.frames_used} of {ring.frames_total}",
        "surround " + SURROUND_WORDS.get(ring.surround, ring.surround),
    ]
    if ring.housing > 0:
        lines.append(
            f"housing  a complete circle at {ring.housing:.2f} px lies outside the scene: taken for the housing"
        )
    if ring.texture_ratio > 0:
        from .ring import SURE_TEXTURE

        sure = ring.texture_ratio >= SURE_TEXTURE
        lines.append(
            f"{'sure' if sure else 'unsure':<8} the scene's annulus has {ring.texture_ratio:.1f}x the texture of "
            "its surround" + ("" if sure else ": check the ring on a picture before trusting it")
        )
    if ring.ellipse_ratio > 1.01:
        lines.append(
            f"ellipse  the outer edge is an ellipse ({ring.ellipse_ratio:.3f}:1): the camera stretches the "
            "picture; `calib lens` fits the stretch (the profile's sensor), a ring alone cannot"
        )
    return "\n".join(lines)


@click.command("ring")
@click.argument("media", nargs=-1, required=True, type=click.Path(path_type=Path), metavar="VIDEO|IMAGES...")
@click.option("-o", "--out", type=click.Path(path_type=Path), help="Write the ring here (ring.json).")
@max_frames_option
def ring_cmd(media: tuple[Path, ...], out: Path | None, max_frames: int) -> None:
    """Find the donut ring (centre, inner and outer radius) in ordinary frames, without a target."""
    from .ring import find_ring

    ring = find_ring(read_frames(list(media), max_frames))
    click.echo(_ring_text(ring))
    if out is not None:
        out.write_text(json.dumps(ring.to_dict(), indent=1) + "\n")
        click.echo(f"wrote {out}")


def _profile(ctx: click.Context, target: str, lens_name: str | None) -> tuple[Any, str]:
    """The lens profile to check against: a lens.json file, or a venue's (its modelling lens, or
    its one lens profile, or the one named)."""
    from ..lens import load_lens

    p = Path(target)
    if p.suffix.lower() == ".json" or p.is_file():
        return load_lens(p), str(p)
    from ..cli_context import catalog_of

    cat = catalog_of(ctx)
    cat.venues.get(target)  # NotFound: names the venue
    if lens_name is not None:
        return cat.lenses.get(target, lens_name), f"{target}'s lens {lens_name!r}"
    try:
        return cat.store.load(target).lens, f"{target}'s modelling lens"
    except OmninavError:
        pass
    names = list(cat.lenses.profiles(target))
    if "default" in names:
        return cat.lenses.get(target, "default"), f"{target}'s lens 'default'"
    if len(names) == 1:
        return cat.lenses.get(target, names[0]), f"{target}'s lens {names[0]!r}"
    if not names:
        raise OmninavError(f"venue {target!r} has no lens profile yet: give a lens.json instead")
    raise OmninavError(f"venue {target!r} has {len(names)} lens profiles ({', '.join(names)}): name one with --lens")


@click.command("check")
@click.argument("target", metavar="VENUE|LENS.JSON")
@click.argument("media", nargs=-1, required=True, type=click.Path(path_type=Path), metavar="VIDEO|IMAGES...")
@click.option("--lens", "lens_name", help="Which of the venue's lens profiles (default: its modelling lens).")
@max_frames_option
@click.option("--json", "as_json", is_flag=True, help="Print the verdict as JSON.")
@click.pass_context
def check_cmd(
    ctx: click.Context, target: str, media: tuple[Path, ...], lens_name: str | None, max_frames: int, as_json: bool
) -> None:
    """Does this video fit this lens profile? Exit 0: it fits (perhaps once corrected), 1: it does not."""
    from ..lens import Catadioptric
    from .lens_fit import fit_lens
    from .ring import NoRing, find_ring

    lens, what = _profile(ctx, target, lens_name)
    frames = read_frames(list(media), max_frames)
    if not isinstance(lens, Catadioptric):
        doc: dict[str, Any] = {"verdict": "same", "fits": True, "message": "an equirectangular camera has no ring"}
        click.echo(json.dumps(doc) if as_json else f"{what}: {doc['message']}")
        return
    try:
        ring = find_ring(frames)
    except NoRing as e:
        fit = fit_lens(lens, None)
        doc = {**fit.to_dict(), "ring": None, "why": str(e)}
        click.echo(json.dumps(doc) if as_json else f"{fit.message} ({e})")
        sys.exit(1)
    fit = fit_lens(lens, ring)
    doc = {**fit.to_dict(), "ring": ring.to_dict()}
    if as_json:
        click.echo(json.dumps(doc))
    else:
        rx, ry, _, ro = lens.reference_ring()
        click.echo(f"profile  {what}: ring at {rx:.2f}, {ry:.2f} px, r_outer {ro:.2f} px")
        click.echo(_ring_text(ring))
        fits = {
            "same": "fits",
            "corrected": "fits once corrected (centre moved, radii scaled)",
            "too_far": "does not fit",
            "cut": "does not fit",
        }[fit.verdict]
        click.echo(f"verdict  {fit.verdict}: {fits}")
        click.echo(fit.message)
    if fit.verdict not in ("same", "corrected"):
        sys.exit(1)
