"""Evaluate a venue against an independently recorded walk (`omninav evaluate`).

The walk is cut into consecutive 1 s clips; each is located and compared with the walk's own
walk path at the clip's last frame. The plot follows the paper's Fig. 6c: query frame against matched
venue frame, with the ground truth and the band of venue frames within 2 m of it.
"""

from __future__ import annotations

import time
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from .aggregate import SURE, Estimate, confidence
from .calib.correct import FIRST
from .errors import OmninavError
from .heading import wrap_deg
from .lens import Lens
from .locate import DEFAULT_CLIP_FPS, MAX_CLIP_S, Locator
from .model_venue import Progress
from .motion import Imu
from .quality import AMBIGUOUS_MARGIN, RADIUS_M
from .spectrum import LocalQuery
from .tracking_state import TrackPose, TrackState
from .verify import Outcome
from .video import IMAGE_EXT, VideoInfo, iter_video
from .walk_path import WalkPath


@dataclass
class Evaluation:
    rows: list[dict[str, Any]] = field(default_factory=list)

    def summary(self) -> dict[str, Any]:
        if not self.rows:
            return {"clips": 0}
        err = np.array([r["err_m"] for r in self.rows])
        herr = np.array([abs(r["heading_err_deg"]) for r in self.rows])
        conf = np.array([r["confidence"] for r in self.rows])
        hi = conf >= SURE
        return {
            "clips": len(self.rows),
            "within_1m": float(np.mean(err <= 1.0)),
            "within_2m": float(np.mean(err <= 2.0)),
            "median_err_m": float(np.median(err)),
            "median_heading_err_deg": float(np.median(herr)),
            "heading_err_p90_deg": float(np.percentile(herr, 90)),
            "confident_share": float(hi.mean()),
            "confident_within_2m": float(np.mean(err[hi] <= 2.0)) if hi.any() else None,
        }


def query_spectra(
    loc: Locator, video: Path, walk_path: WalkPath, lens: Lens | None, progress: Progress | None = None
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Sampled frames of a walk -> spectra (F, C, K), times, true xy, true heading, frame index."""
    spec, t, idx = walk_spectra(loc, video, lens, progress, walk_path.fps)
    xy, hd, ok = walk_path.pose_at(t)
    if not ok.any():
        raise OmninavError(f"{video}: no frame lies within the walk path's waypoints")
    return spec[ok], t[ok], xy[ok], hd[ok], idx[ok]


def _sampled(
    loc: Locator, video: Path, fps: float, last: int | None = None
) -> tuple[Iterator[tuple[int, np.ndarray]], int, float]:
    """A walk's frames sampled at the venue's model_fps (up to frame `last`), how many there will
    be, and the walk's frame rate (a directory of images is filmed at `fps`)."""
    if video.is_dir():
        files = sorted(f for f in video.iterdir() if f.suffix.lower() in IMAGE_EXT)
        if not files:
            raise OmninavError(f"{video}: directory holds no frame images ({', '.join(sorted(IMAGE_EXT))})")
        vfps, n_frames = fps, len(files)
    else:
        info = VideoInfo(video)
        vfps, n_frames = (info.fps if info.fps > 0 else fps), info.frames
    stride = max(1, int(round(vfps / loc.conf["model_fps"])))
    end = n_frames if last is None or video.is_dir() and last >= n_frames else last + 1
    frames: Iterator[tuple[int, np.ndarray]]
    if video.is_dir():
        frames = ((i, _image(files[i])) for i in range(0, end, stride))
    else:
        frames = iter_video(info, stride=stride, last=last)
    return frames, max(1, -(-n_frames // stride)), vfps


def walk_spectra(
    loc: Locator, video: Path, lens: Lens | None, progress: Progress | None = None, fps: float = DEFAULT_CLIP_FPS
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A walk (a video, or a directory of frame images filmed at `fps`) sampled at the venue's
    model_fps -> spectra (F, C, K), times (s, the video's clock), frame index."""
    frames, total, vfps = _sampled(loc, video, fps)
    ext = loc.extractor(lens)
    # the walk's lens as it sits in this walk: the ring is measured on its first frames
    clip = loc.clip_lens(lens, lambda f: ext.check_frame(f, str(video)))
    specs: list[np.ndarray] = []
    idx: list[int] = []
    t0 = time.perf_counter()
    for i, frame in frames:
        specs.extend(clip.feed(frame))
        idx.append(i)
        if progress:
            progress(len(idx), max(total, len(idx)), time.perf_counter() - t0)
    specs.extend(clip.flush())
    if not specs:
        raise OmninavError(f"{video}: no frames")
    t = np.array(idx) / vfps  # the video's rate: a walk path's fps only counts its own frame numbers
    return np.stack(specs), t, np.array(idx)


def walk_local(
    loc: Locator, video: Path, lens: Lens | None, wanted: set[int], fps: float = DEFAULT_CLIP_FPS
) -> dict[int, LocalQuery]:
    """The local features of the walk's sampled frames of index `wanted` (each clip's last frame),
    through the walk's lens as walk_spectra corrects it (on the same first sampled frames), in a
    second decoding pass: only the features are kept (~34 KB a frame), never the frames."""
    frames, _, _ = _sampled(loc, video, fps, max(wanted, default=0))
    clip = loc.clip_lens(lens)
    out: dict[int, LocalQuery] = {}
    for n, (i, frame) in enumerate(frames):
        if n < FIRST:
            clip.feed(frame)  # (decides the lens on the first FIRST frames)
        if i in wanted:
            clip.flush()
            if (q := loc.local_features(frame, clip.lens)) is not None:
                out[i] = q
    return out


def _image(path: Path) -> np.ndarray:
    import cv2

    img = cv2.imread(str(path), cv2.IMREAD_COLOR)
    if img is None:
        raise OmninavError(f"{path}: not a readable image")
    return img


def evaluate(
    loc: Locator,
    video: Path,
    walk_path: WalkPath,
    lens: Lens | None = None,
    aggregate: str | None = None,
    clip_s: float = 1.0,
    progress: Progress | None = None,
    tail: bool = False,
) -> Evaluation:
    spec, t, xy, hd, idx = query_spectra(loc, video, walk_path, lens, progress)
    ends = walk_local(loc, video, lens, clip_ends(loc, idx, clip_s, tail), walk_path.fps) if loc.verifies else None
    return evaluate_spectra(loc, spec, t, xy, hd, idx, aggregate, clip_s, tail, ends)


def clip_frames_of(loc: Locator, clip_s: float) -> int:
    """Sampled frames in a clip of `clip_s` seconds."""
    return max(1, int(round(clip_s * loc.conf["model_fps"])))


def clip_starts(frames: int, n: int, tail: bool) -> list[int]:
    """The first sampled frame of each clip of `n` of a walk of `frames` (evaluate_spectra's)."""
    starts = list(range(0, frames - n + 1, n))
    if tail and starts and starts[-1] + n < frames:
        starts.append(frames - n)
    return starts


def clip_ends(loc: Locator, idx: np.ndarray, clip_s: float, tail: bool) -> set[int]:
    """The frame index of each clip's last frame, as evaluate_spectra cuts the walk's frames `idx`."""
    n = clip_frames_of(loc, clip_s)
    return {int(idx[s + n - 1]) for s in clip_starts(len(idx), n, tail)}


def evaluate_spectra(
    loc: Locator,
    spec: np.ndarray,
    t: np.ndarray,
    xy: np.ndarray,
    hd: np.ndarray,
    idx: np.ndarray,
    aggregate: str | None = None,
    clip_s: float = 1.0,
    tail: bool = False,
    ends: dict[int, LocalQuery] | None = None,
) -> Evaluation:
    """evaluate() on a walk's spectra already extracted (query_spectra's output): consecutive
    clips of `clip_s`, each answered at its last frame. Several clip lengths or aggregations of one
    walk then cost one extraction. `tail`: the frames after the last whole clip are scored too, as
    a clip ending at the walk's last frame (it overlaps the one before): every second of an
    admin's evaluation walk is scored (the benchmarks' clips stay as they were measured). `ends`:
    the local features of the clips' last frames (walk_local), with which a venue that has its own
    verifies each clip as `locate` does (its row's `verified` says what that made of it)."""
    n = clip_frames_of(loc, clip_s)
    ev = Evaluation()
    for s in clip_starts(len(t), n, tail):
        w = slice(s, s + n)
        outcome: Outcome | None = None
        if ends is not None and int(idx[s + n - 1]) in ends:
            e, outcome = loc.estimate_local(spec[w], t[w], aggregate, ends[int(idx[s + n - 1])])
        else:
            e = loc.estimate(spec[w], t[w], aggregate)
        tx, ty = xy[s + n - 1]
        ev.rows.append(
            {
                "frame": int(idx[s + n - 1]),
                "t": float(t[s + n - 1]),
                "x": e.x,
                "y": e.y,
                "heading": e.heading,
                "true_x": float(tx),
                "true_y": float(ty),
                "true_heading": float(hd[s + n - 1]),
                "err_m": float(np.hypot(e.x - tx, e.y - ty)),
                "heading_err_deg": float(wrap_deg(e.heading - hd[s + n - 1])),
                "venue_row": e.venue_row,
                "confidence": loc.confidence(e, outcome),
                "support": e.support,
                "rival": e.rival,
                "agree": e.agree,
                "frames": n,
                **({"verified": outcome} if outcome is not None else {}),
            }
        )
    return ev


LOW_CONFIDENCE = 0.5  # config.py's default: below it the app says "not sure"


def evaluate_walk(
    loc: Locator,
    video: Path,
    walk_path: WalkPath,
    lens: Lens,
    progress: Progress | None = None,
    low_confidence: float = LOW_CONFIDENCE,
) -> dict[str, Any]:
    """An evaluation walk for the admin page: every 1 s clip's truth and answer, and the summary.

    A clip's truth and answer are at its last frame (where the walk path puts the walker then), and the
    walk's last part-second is a clip too (`tail`); `heading_error_deg` is absolute, in [0, 180].
    Each answer also carries `margin` ((support - rival) / support, as the quality map's), and the
    summary `share_green`: the share of clips within 2 m with a margin of at least
    AMBIGUOUS_MARGIN, the quality map's green measured on an independent walk."""
    return walk_result(evaluate(loc, video, walk_path, lens, progress=progress, tail=True), low_confidence)


def walk_result(ev: Evaluation, low_confidence: float = LOW_CONFIDENCE) -> dict[str, Any]:
    """evaluate()'s rows -> evaluate_walk's document."""
    clips = []
    for r in ev.rows:
        margin = (r["support"] - r["rival"]) / r["support"] if r["support"] > 0 else 0.0
        conf = round(r["confidence"], 3)  # as a locate answers it, and decides "not sure" on it
        clips.append(
            {
                "t": round(r["t"], 3),
                "truth": {
                    "x": round(r["true_x"], 3),
                    "y": round(r["true_y"], 3),
                    "heading_deg": round(r["true_heading"] % 360.0, 2),
                },
                "answer": {
                    "x": round(r["x"], 3),
                    "y": round(r["y"], 3),
                    "heading_deg": round(r["heading"] % 360.0, 2),
                    "confidence": conf,
                    "low_confidence": bool(conf < low_confidence),
                    "margin": round(margin, 3),
                },
                "error_m": round(r["err_m"], 3),
                "heading_error_deg": round(abs(r["heading_err_deg"]), 2),
            }
        )
    err = np.array([c["error_m"] for c in clips])
    herr = np.array([c["heading_error_deg"] for c in clips])
    n = len(clips)
    green = sum(c["error_m"] <= RADIUS_M and c["answer"]["margin"] >= AMBIGUOUS_MARGIN for c in clips)
    summary = {
        "clips": n,
        "within_1m": round(float(np.mean(err <= 1.0)), 4) if n else 0.0,
        "within_2m": round(float(np.mean(err <= 2.0)), 4) if n else 0.0,
        "median_error_m": round(float(np.median(err)), 3) if n else 0.0,
        "median_heading_error_deg": round(float(np.median(herr)), 2) if n else 0.0,
        "not_sure": sum(c["answer"]["low_confidence"] for c in clips),
        # said as "You are probably ...": a place, not "not sure", under the sure line
        "probably": sum(not c["answer"]["low_confidence"] and c["answer"]["confidence"] < SURE for c in clips),
        # what a user would trust and be misled by: said as sure, further than 2 m
        "sure_over_2m": sum(c["answer"]["confidence"] >= SURE and c["error_m"] > RADIUS_M for c in clips),
        "share_green": round(green / n, 4) if n else 0.0,
    }
    return {"clips": clips, "summary": summary}


def plot(ev: Evaluation, loc: Locator, path: Path, title: str = "") -> None:
    """The paper's Fig. 6c: matched venue frame per query clip, truth, and the 2 m band."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(9, 5), dpi=110)
    vx, vy = loc.xy[:, 0], loc.xy[:, 1]
    for i, r in enumerate(ev.rows):
        band = np.flatnonzero(np.hypot(vx - r["true_x"], vy - r["true_y"]) <= 2.0)
        ax.scatter(np.full(band.size, i), band, s=2, c="#bbbbbb", marker="s", linewidths=0)
        true_row = int(np.argmin(np.hypot(vx - r["true_x"], vy - r["true_y"])))
        ax.scatter([i], [true_row], s=8, c="black", marker="_")
    good = np.array([r["err_m"] <= 2.0 for r in ev.rows])
    xs = np.arange(len(ev.rows))
    vr = np.array([r["venue_row"] for r in ev.rows])
    ax.scatter(xs[good], vr[good], s=10, c="#1f77b4", label="matched (within 2 m)")
    ax.scatter(xs[~good], vr[~good], s=18, c="#d62728", marker="x", label="matched (wrong)")
    ax.scatter([], [], s=8, c="black", marker="_", label="ground truth (nearest venue frame)")
    ax.scatter([], [], s=8, c="#bbbbbb", marker="s", label="venue frames within 2 m")
    ax.set_xlabel("query clip (1 s, in walk order)")
    ax.set_ylabel("venue frame")
    s = ev.summary()
    ax.set_title(title or f"{s['clips']} clips: {s['within_2m']:.1%} within 2 m, {s['within_1m']:.1%} within 1 m")
    ax.legend(loc="upper left", fontsize=8, markerscale=2)
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)


# ---- tracking while walking (tracking.py): `omninav track`, `evaluate --track-mode` ---------------
SKIP_S = 5.0  # track-mode figures count the seconds after the first 5 (the filter's start)


def track_ends(t: np.ndarray, every: float = 1.0, clip_s: float = 1.0) -> list[int]:
    """Frames at which a walk is answered: every `every` s, the first a clip_s after its start."""
    ends: list[int] = []
    dt = float(np.median(np.diff(t))) if len(t) > 1 else 0.1
    at = float(t[0]) + clip_s - dt / 2
    while at <= float(t[-1]) + 1e-6:
        e = int(np.searchsorted(t, at - 1e-6))
        if not ends or e > ends[-1]:
            ends.append(e)
        at += every
    return ends


def track_walk(
    loc: Locator,
    spec: np.ndarray,
    t: np.ndarray,
    every: float = 1.0,
    imu: Imu | None = None,
    clip_s: float = 1.0,
) -> Iterator[tuple[int, TrackPose, Estimate, int]]:
    """A walk's spectra -> at every answer (track_ends), the filter's pose and the single clip's
    Estimate, each from the clip ending there and (the filter) the walk before it, and the clip's
    frames. The clip is
    everything since the last answer (as the phone films it: Locator.track walks it second by
    second), at least the last clip_s and at most MAX_CLIP_S: every frame of the walk is
    evidence, however far apart the answers."""
    state: TrackState | None = None
    t_prev: float | None = None
    for e in track_ends(t, every, clip_s):
        since = t[e] - clip_s if t_prev is None else min(t_prev, t[e] - clip_s)
        since = max(since, t[e] - MAX_CLIP_S)
        w = np.flatnonzero((t > since + 1e-6) & (t <= t[e] + 1e-9))
        motion = imu.motion(t_prev, float(t[e])) if imu is not None and t_prev is not None else None
        state, pose, est = loc.track(loc.tracker, spec[w], t[w], state, float(t[e]), motion)
        t_prev = float(t[e])
        yield e, pose, est, len(w)


def evaluate_track(
    loc: Locator,
    spec: np.ndarray,
    t: np.ndarray,
    xy: np.ndarray,
    hd: np.ndarray,
    idx: np.ndarray,
    every: float = 1.0,
    imu: Imu | None = None,
) -> tuple[Evaluation, Evaluation]:
    """(single clips, the filter) on the same seconds of a walk: rows as evaluate_spectra's."""
    single, tracked = Evaluation(), Evaluation()
    for e, pose, est, n in track_walk(loc, spec, t, every, imu):
        tx, ty = xy[e]
        base = {"frame": int(idx[e]), "t": float(t[e] - t[0]), "true_x": float(tx), "true_y": float(ty)}
        base["true_heading"] = float(hd[e])
        for ev, x, y, h, c, extra in (
            (
                single,
                est.x,
                est.y,
                est.heading,
                confidence(est, loc.conf),
                {"support": est.support, "rival": est.rival},
            ),
            (tracked, pose.x, pose.y, pose.heading, pose.confidence, {"ambiguous": pose.ambiguous, "mass": pose.mass}),
        ):
            row = int(np.argmin(np.hypot(loc.xy[:, 0] - x, loc.xy[:, 1] - y)))
            ev.rows.append(
                {
                    **base,
                    "x": x,
                    "y": y,
                    "heading": h,
                    "err_m": float(np.hypot(x - tx, y - ty)),
                    "heading_err_deg": float(wrap_deg(h - hd[e])),
                    "venue_row": row,
                    "confidence": c,
                    "frames": n,
                    **extra,
                }
            )
    return single, tracked


def track_summary(ev: Evaluation, skip_s: float = SKIP_S) -> dict[str, Any]:
    """Evaluation.summary() over the answers after the first skip_s seconds, with the answers
    given with confidence >= 0.8 that were further than 5 m and than 2 m from the truth."""
    kept = Evaluation([r for r in ev.rows if r["t"] >= skip_s])
    s = kept.summary()
    err = np.array([r["err_m"] for r in kept.rows])
    hi = np.array([r["confidence"] >= SURE for r in kept.rows], bool)
    s["confident_over_5m"] = int(np.sum(hi & (err > 5.0))) if len(err) else 0
    s["confident_over_2m"] = int(np.sum(hi & (err > 2.0))) if len(err) else 0
    s["skip_s"] = skip_s
    return s
