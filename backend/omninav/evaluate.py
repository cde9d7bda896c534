"""Evaluate a venue against an independently recorded walk (`omninav evaluate`).

The walk is cut into consecutive 1 s clips; each is located and compared with the walk's own
track at the clip's last frame. The plot follows the paper's Fig. 6c: query frame against matched
venue frame, with the ground truth and the band of venue frames within 2 m of it.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from .aggregate import confidence
from .errors import OmninavError
from .heading import wrap_deg
from .lens import Lens
from .locate import Locator
from .model_venue import Progress
from .quality import AMBIGUOUS_MARGIN, RADIUS_M
from .track import Track
from .video import VideoInfo, iter_video


@dataclass
class Evaluation:
    rows: list[dict[str, Any]] = field(default_factory=list)

    def summary(self) -> dict[str, Any]:
        if not self.rows:
            return {"clips": 0}
        err = np.array([r["err_m"] for r in self.rows])
        herr = np.array([abs(r["heading_err_deg"]) for r in self.rows])
        conf = np.array([r["confidence"] for r in self.rows])
        hi = conf >= 0.8
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
    loc: Locator, video: Path, track: Track, lens: Lens | None, progress: Progress | None = None
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Sampled frames of a walk -> spectra (F, C, K), times, true xy, true heading, frame index."""
    info = VideoInfo(video)
    vfps = info.fps if info.fps > 0 else track.fps
    stride = max(1, int(round(vfps / loc.conf["model_fps"])))
    ext = loc.extractor(lens)
    # the walk's lens as it sits in this walk: the ring is measured on its first frames
    clip = loc.clip_lens(lens, lambda f: ext.check_frame(f, str(video)))
    specs: list[np.ndarray] = []
    idx: list[int] = []
    total = max(1, -(-info.frames // stride))
    t0 = time.perf_counter()
    for i, frame in iter_video(info, stride=stride):
        specs.extend(clip.feed(frame))
        idx.append(i)
        if progress:
            progress(len(idx), max(total, len(idx)), time.perf_counter() - t0)
    specs.extend(clip.flush())
    t = np.array(idx) / vfps  # the video's rate: a track's fps only counts its own frame numbers
    xy, hd, ok = track.pose_at(t)
    if not ok.any():
        raise OmninavError(f"{video}: no frame lies within the track's waypoints")
    return np.stack(specs)[ok], t[ok], xy[ok], hd[ok], np.array(idx)[ok]


def evaluate(
    loc: Locator,
    video: Path,
    track: Track,
    lens: Lens | None = None,
    aggregate: str | None = None,
    clip_s: float = 1.0,
    progress: Progress | None = None,
) -> Evaluation:
    spec, t, xy, hd, idx = query_spectra(loc, video, track, lens, progress)
    return evaluate_spectra(loc, spec, t, xy, hd, idx, aggregate, clip_s)


def evaluate_spectra(
    loc: Locator,
    spec: np.ndarray,
    t: np.ndarray,
    xy: np.ndarray,
    hd: np.ndarray,
    idx: np.ndarray,
    aggregate: str | None = None,
    clip_s: float = 1.0,
) -> Evaluation:
    """evaluate() on a walk's spectra already extracted (query_spectra's output): consecutive
    clips of `clip_s`, each answered at its last frame. Several clip lengths or aggregations of one
    walk then cost one extraction."""
    n = max(1, int(round(clip_s * loc.conf["model_fps"])))
    ev = Evaluation()
    for s in range(0, len(t) - n + 1, n):
        w = slice(s, s + n)
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
                "confidence": confidence(e, loc.conf),
                "support": e.support,
                "rival": e.rival,
                "agree": e.agree,
                "frames": n,
            }
        )
    return ev


LOW_CONFIDENCE = 0.5  # config.py's default: below it the app says "not sure"


def evaluate_walk(
    loc: Locator,
    video: Path,
    track: Track,
    lens: Lens,
    progress: Progress | None = None,
    low_confidence: float = LOW_CONFIDENCE,
) -> dict[str, Any]:
    """An evaluation walk for the admin page: every 1 s clip's truth and answer, and the summary.

    A clip's truth and answer are at its last frame; `heading_error_deg` is absolute, in [0, 180].
    Each answer also carries `margin` ((support - rival) / support, as the quality map's), and the
    summary `share_green`: the share of clips within 2 m with a margin of at least
    AMBIGUOUS_MARGIN, the quality map's green measured on an independent walk."""
    return walk_result(evaluate(loc, video, track, lens, progress=progress), low_confidence)


def walk_result(ev: Evaluation, low_confidence: float = LOW_CONFIDENCE) -> dict[str, Any]:
    """evaluate()'s rows -> evaluate_walk's document."""
    clips = []
    for r in ev.rows:
        margin = (r["support"] - r["rival"]) / r["support"] if r["support"] > 0 else 0.0
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
                    "confidence": round(r["confidence"], 3),
                    "low_confidence": bool(r["confidence"] < low_confidence),
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
