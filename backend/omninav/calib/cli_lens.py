"""`omninav calib lens`: a lens profile (lens.json) from a video, or still images, of a calibration
board moved round the donut (calib/README.md tells how to film it).

The stages: frames (read as untrusted media: headers checked before decoding, a video sampled
evenly, `cli_ring.read_frames`), the ring (`ring.find_ring`), the board's corners in each frame
(`board.detect_board`), Scaramuzza's model fitted to them (`ocam.fit_ocam`), forward and sense of
rotation from the protocol (`ocam.orientation`), the profile (`ocam.to_profile`), and the
report PNG (`report.write_report`).
"""

from __future__ import annotations

import json
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import click
import numpy as np

from ..errors import OmninavError, read_json
from ..lens import Catadioptric, lens_from_dict
from .cli_ring import max_frames_option

MIN_VIEWS = 4  # usable board frames: 3 to fit (OCamCalib's minimum) and one held out to score
MIN_SIDE = 240  # px: below this a board's squares are a few pixels and corners cannot be refined


@dataclass
class LensCalibration:
    """Everything `calib lens` found, for printing, the report and the tests."""

    profile: Catadioptric
    elevation_residual_deg: float
    fit: Any  # ocam.OcamFit
    orientation: Any  # ocam.Orientation
    ring: Any  # ring.Ring
    detections: list[Any]  # board.Detection, the frames the board was found in
    n_frames: int
    handedness: str  # the fit's handedness against the protocol's ccw, in words


def _spec_hint(frames: Sequence[np.ndarray], spec: Any, ring: Any) -> str | None:
    """A chessboard of another size than `spec` that some frame shows (a spec that does not match
    the print), as a --board value; None when none is found. Tried only after the spec found nothing."""
    from .board import BoardSpec, detect_board

    if spec.kind != "chess":
        return None
    picks = [frames[i] for i in np.linspace(0, len(frames) - 1, min(3, len(frames))).round().astype(int)]
    for dc, dr in ((-1, 0), (1, 0), (0, -1), (0, 1)):  # the usual slip: squares counted, not inner corners
        c, r = spec.cols + dc, spec.rows + dr
        if c < 3 or r < 3:
            continue
        other = BoardSpec("chess", c, r, spec.square_m)
        if any(detect_board(f, other, ring) is not None for f in picks):
            return f"chess:{c}x{r}:{spec.square_m:g}"
    return None


def calibrate(
    frames: Sequence[np.ndarray], spec: Any, holdout: int = 4, outer_down: bool = False, ring: Any | None = None
) -> LensCalibration:
    """The whole calibration on decoded frames (BGR uint8, in the protocol's order). `ring`: the
    lens ring as given (`--ring`: marked by hand where the finder cannot see it), else found."""
    from .board import detect_board
    from .ocam import fit_ocam, orientation, to_profile
    from .ring import NoRing, find_ring

    if not frames:
        raise OmninavError("no frames to calibrate from")
    h, w = frames[0].shape[:2]
    if min(w, h) < MIN_SIDE:
        raise OmninavError(
            f"the frames are {w}x{h} pixels: too small to calibrate a lens on (at least {MIN_SIDE} a side); "
            "film at the resolution the lens will be used at"
        )
    if ring is None:
        try:
            ring = find_ring(frames)  # also refuses frames of different sizes and frames without a ring
        except NoRing as e:
            raise NoRing(
                f"{e} Where the lens's edge is hard to see (a white wall all round it), mark the ring by hand "
                "in a ring.json and give --ring (calib/README.md)"
            ) from e
    elif ring.image_size != (w, h) or any(f.shape[:2] != (h, w) for f in frames):
        raise OmninavError(f"the ring is for {ring.image_size[0]}x{ring.image_size[1]} frames; these are {w}x{h}")
    found = [d for i, f in enumerate(frames) if (d := detect_board(f, spec, ring, i)) is not None]
    name = f"{spec.kind} {spec.cols}x{spec.rows}"
    if not found:
        hint = _spec_hint(frames, spec, ring)
        if hint is not None:
            raise OmninavError(f"the board in the frames is not {name} but looks like {hint}: give --board {hint}")
        raise OmninavError(
            f"no {name} board found in any of {len(frames)} frames: film the board whole inside the ring "
            "(no part past its inner or outer edge), well lit, or check --board (inner corners for chess)"
        )
    if spec.kind == "chess" and not any(d.whole for d in found):
        raise OmninavError(
            f"the chessboard was never seen whole (in {len(found)} frames only part of it): "
            "keep every square inside the ring, or use a ChArUco board"
        )
    usable = [d for d in found if len(d.image_points) >= 6]
    if len(usable) < MIN_VIEWS:
        raise OmninavError(
            f"the board was found in only {len(usable)} of {len(frames)} frames; at least {MIN_VIEWS} are needed: "
            "film it in more places round the ring (more frames: --max-frames)"
        )
    fit = fit_ocam(usable, (w, h), ring, holdout=holdout, outer_down=outer_down)
    orient = orientation(usable, fit.ocam)
    profile, resid = to_profile(fit.ocam, ring, orient.forward_deg, orient.ccw, support=fit.support)
    lens_from_dict(profile.to_dict(), "calibrated lens")  # what we write must load
    if spec.kind == "chess":
        hand = "not checked (a chessboard's corner labels fix its handedness by convention)"
    elif fit.ccw_fit is None:
        hand = "unknown (the views disagree)"
    elif fit.ccw_fit == orient.ccw:
        hand = "agrees with the board's handedness"
    else:
        hand = (
            f"DISAGREES with the board's handedness (which says ccw {str(fit.ccw_fit).lower()}): "
            "was the board moved to the phone's left after the start?"
        )
    return LensCalibration(
        profile=profile,
        elevation_residual_deg=resid,
        fit=fit,
        orientation=orient,
        ring=ring,
        detections=usable,
        n_frames=len(frames),
        handedness=hand,
    )


def coverage_warning(support: tuple[float, float], r_inner: float, r_outer: float, share: float = 0.1) -> str | None:
    """A line when the corners left more than `share` of the ring's width uncovered at an edge:
    elevations there are extrapolated (on our renders ~0.1 deg at 20 % of the width, 1 deg at 25 %)."""
    gap_in, gap_out = support[0] - r_inner, r_outer - support[1]
    if max(gap_in, gap_out) <= share * (r_outer - r_inner):
        return None
    return (
        f"the board's corners reached radii {support[0]:.0f}-{support[1]:.0f} px of the ring's {r_inner:.0f}-"
        f"{r_outer:.0f}: elevations nearer the {'inner' if gap_in >= gap_out else 'outer'} edge are extrapolated; "
        "film the board closer to that edge for a better profile"
    )


def summary(cal: LensCalibration) -> list[str]:
    """The lines `calib lens` prints."""
    fit, ring, p, o = cal.fit, cal.ring, cal.profile, cal.orientation
    n_held = sum(v.held_out for v in fit.views)
    lo, hi = p.elevation(np.array([p.r_inner, p.r_outer]))
    c, d, e = fit.ocam.stretch
    held = f"{fit.rms_held:.3f} px ({n_held} frames)" if fit.rms_held is not None else "none held out"
    lines = [
        f"ring         centre {ring.center[0]:.2f}, {ring.center[1]:.2f} px, r_inner {ring.r_inner:.2f}, "
        f"r_outer {ring.r_outer:.2f} px "
        + (f"(in {ring.frames_used} of {ring.frames_total} frames)" if ring.frames_total else "(given: --ring)"),
        f"board        found in {len(cal.detections)} of {cal.n_frames} frames: {len(fit.views) - n_held} fitted, "
        f"{n_held} held out",
        f"model        centre {fit.ocam.center[0]:.2f}, {fit.ocam.center[1]:.2f} px; f of degree {fit.degree}; "
        f"stretch c d e = {c:.5f} {d:.5f} {e:.5f} ({100 * fit.ocam.anisotropy():.2f} % anisotropic); "
        f"decentring p1 p2 = {fit.ocam.tangential[0]:.5f} {fit.ocam.tangential[1]:.5f}"
        f"{' (in lens.json: sensor)' if p.sensor is not None else ''}; "
        f"{fit.seconds:.1f} s",
        f"reprojection RMS  fitted {fit.rms_fit:.3f} px, held out {held}",
        "per image    "
        + ", ".join(f"{v.frame}{'*' if v.held_out else ''} {v.rms:.2f}" for v in fit.views)
        + "  (px; * held out)",
        f"elevation    {lo:+.1f} deg at r_inner to {hi:+.1f} deg at r_outer; the profile's polynomial is within "
        f"{cal.elevation_residual_deg:.3f} deg of the model over radii {fit.support[0]:.0f}-{fit.support[1]:.0f} px "
        "(the corners' reach; carried on to the edges)",
        f"forward      {p.forward_deg:.2f} deg (image angle of the board held straight ahead, {o.ahead_views} frames)",
        f"ccw          {str(p.ccw).lower()} (moved left, the board's image angle went {o.turn_deg:+.1f} deg); "
        f"the fit {cal.handedness}",
    ]
    if (cov := coverage_warning(fit.support, p.r_inner, p.r_outer)) is not None:
        lines.append(f"warning      {cov}")
    lines.extend(f"note         {n}" for n in fit.notes)
    return lines


@click.command("lens")
@click.argument("inputs", nargs=-1, required=True, type=click.Path(path_type=Path))
@click.option("--board", "board", required=True, help="The board: chess:COLSxROWS:SQUARE_M or charuco:...")
@click.option("-o", "--output", "output", required=True, type=click.Path(path_type=Path), help="lens.json to write.")
@click.option("--report", type=click.Path(path_type=Path), default=None, help="Write a PNG of the fit here.")
@max_frames_option
@click.option("--outer-down", is_flag=True, help="The ring's outer edge looks DOWN (rare; default: up).")
@click.option(
    "--ring",
    "ring_path",
    type=click.Path(path_type=Path),
    default=None,
    help="Use this ring.json (marked by hand, or from `calib ring`) instead of finding the ring.",
)
def lens_cmd(
    inputs: tuple[Path, ...],
    board: str,
    output: Path,
    report: Path | None,
    max_frames: int,
    outer_down: bool,
    ring_path: Path | None,
) -> None:
    """Fit a lens profile to a VIDEO (or still IMAGES, in filming order) of a calibration board held
    straight ahead of the phone, then moved to its left and on round the ring (calib/README.md)."""
    from .board import parse_board
    from .cli_ring import read_frames

    spec = parse_board(board)
    for p in (output, report):
        if p is not None and not p.resolve().parent.is_dir():
            raise OmninavError(f"{p.parent}: folder does not exist")
    if report is not None and report.suffix.lower() != ".png":
        raise OmninavError(f"{report}: the report is a PNG: name it something.png")
    given = None
    if ring_path is not None:
        from .ring import ring_from_dict

        given = ring_from_dict(read_json(ring_path, "ring"), where=str(ring_path))
    frames = read_frames(list(inputs), max_frames)
    cal = calibrate(frames, spec, outer_down=outer_down, ring=given)
    output.write_text(json.dumps(cal.profile.to_dict(), indent=2) + "\n")
    for line in summary(cal):
        click.echo(line)
    if report is not None:
        from .report import write_report

        scale = write_report(report, frames, cal)
        click.echo(f"report       {report} (residual vectors magnified x{scale:g})")
    click.echo(f"written      {output}")
