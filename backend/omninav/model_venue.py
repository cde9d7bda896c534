"""Modelling (`omninav model`): panoramic videos + their walk paths -> the venue's frames and spectra.

Frames are sampled at the preset's `model_fps` (from a 30 fps video, every third), placed by
linear interpolation of the walk path's waypoints and headed along the direction of travel. The result
joins the frames of the venue's other modelling videos in a new generation (store.py), atomically:
one generation for all videos of a run, so a run that stops half way (error, cancel, kill) leaves
the venue exactly as it was.
"""

from __future__ import annotations

import contextlib
import logging
import time
from collections.abc import Callable, Iterator
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from . import extract_pool
from .calib.correct import ClipLens
from .errors import OmninavError
from .extract import Extractors
from .lens import Lens
from .presets import resolve
from .store import FRAME_DTYPE, Generation, Store
from .verify import SPACING_M, LocalFeatures, concat, detect, one_place
from .video import VideoInfo, extract_threads, in_order, iter_video, on_pool
from .walk_path import WalkPath

log = logging.getLogger("omninav.calib")
POSE_BLOCK = 1024  # sampled frames whose poses are looked up in one call
# a run of this many sampled frames or more extracts on worker processes (extract_pool.py), fewer
# on threads of this process: starting the processes (~0.2 s, once a process) is worth it from here
# (and where the shared memory has room for their frames)
PROCESSES_FROM = 100

# frames done, frames expected, seconds elapsed; it may raise to stop the run (nothing is written)
Progress = Callable[[int, int, float], None]


@dataclass
class VideoSource:
    video: Path  # its file name is the video's name in the venue
    walk_path: WalkPath
    lens: Lens


@dataclass
class ModelResult:
    venue: str
    video: str
    frames: int
    total_frames: int
    seconds: float
    video_seconds: float

    @property
    def speed_x_realtime(self) -> float:
        return self.video_seconds / max(self.seconds, 1e-9)


@dataclass
class _Plan:
    src: VideoSource
    info: VideoInfo
    vfps: float
    stride: int
    first: int
    last: int
    expected: int


def _plan(src: VideoSource, settings: dict[str, Any]) -> _Plan:
    """Check a video against its lens and walk path before any work: errors come first, not last."""
    info = VideoInfo(src.video, label=src.video.name)
    w, h = src.lens.image_size
    if (info.width, info.height) != (w, h):
        raise OmninavError(
            f"{src.video.name}: frames are {info.width}x{info.height} but the lens profile is for {w}x{h}"
        )
    walk_path = src.walk_path
    # a frame's time is its number over the VIDEO's rate: a walk path's `fps` only says what its own
    # `frame` numbers count in (docs/formats.md), and a walk path tagged in seconds may not give one
    vfps = info.fps if info.fps > 0 else walk_path.fps
    stride = max(1, int(round(vfps / settings["model_fps"])))
    first = max(0, int(np.ceil(walk_path.times[0] * vfps - 1e-6)))
    last = int(np.floor(walk_path.times[-1] * vfps + 1e-6))
    if info.frames and first >= info.frames:
        raise OmninavError(f"{src.video.name}: the walk path starts after the video ends ({info.frames} frames)")
    expected = (min(last, info.frames - 1 if info.frames else last) - first) // stride + 1
    return _Plan(src, info, vfps, stride, first, last, expected)


# a lens -> the function that hands a frame to threads or processes and gives its spectrum's future
Submit = Callable[[Lens], Callable[[np.ndarray], Future[np.ndarray]]]


def _extract(
    p: _Plan, tick: Callable[[], None], submit: Submit, ahead: int, n_local: int | None = None
) -> tuple[np.ndarray, np.ndarray, LocalFeatures | None]:
    """One video's sampled frames -> (rows FRAME_DTYPE without `video`, spectra, local features or
    None).

    Each frame is decoded once (on the reader thread, up to the walk path's last frame) and handed
    to `submit`'s threads or processes, at most `ahead` frames in flight; the spectra come back in
    frame order. With `n_local` keypoints, a frame every verify.SPACING_M of the walk also gets its
    local features (verify.detect, on a thread of its own, through the lens as it sat)."""
    # the lens as it sat in this video: a walk filmed after the lens was clipped on again is
    # extracted through the profile moved to its ring, as every query clip is (calib/correct.py)
    clip = ClipLens(p.src.lens, submit)
    rows, specs = [], []
    seen = -1
    spaced: list[tuple[int, np.ndarray]] = []  # (frame number, frame) waiting for the clip's lens
    last_xy: np.ndarray | None = None
    local: list[tuple[int, Future[tuple[np.ndarray, np.ndarray]]]] = []
    orb = ThreadPoolExecutor(1, thread_name_prefix="omninav-local") if n_local else None

    def posed() -> Iterator[tuple[tuple[float, float, float, float, int], np.ndarray]]:
        """The sampled frames that the walk path covers, each with its row (x, y, heading, t, frame);
        the poses are looked up POSE_BLOCK sampled frames a call, not frame by frame."""
        nonlocal seen, last_xy
        at = -POSE_BLOCK  # the first sampled frame (counted from p.first) of the block looked up
        for i, frame in iter_video(p.info, stride=p.stride, start=p.first, last=p.last):
            seen = i
            k = (i - p.first) // p.stride
            if not at <= k < at + POSE_BLOCK:
                at = k
                t = (p.first + p.stride * np.arange(at, at + POSE_BLOCK)) / p.vfps
                xy, hd, ok = p.src.walk_path.pose_at(t)
            if ok[k - at]:
                if orb is not None and (last_xy is None or np.hypot(*(xy[k - at] - last_xy)) >= SPACING_M):
                    last_xy = xy[k - at].copy()
                    spaced.append((i, frame))
                yield (xy[k - at, 0], xy[k - at, 1], hd[k - at], t[k - at], i), frame

    found: list[LocalFeatures] = []

    def detect_spaced() -> None:
        """Hand the spaced frames to the ORB thread, once the clip's lens is decided, and collect
        what it found; at most `ahead` frames wait there (each holds a decoded frame)."""
        assert orb is not None and n_local is not None
        while spaced:
            i, frame = spaced.pop(0)
            local.append((i, orb.submit(detect, frame, clip.lens, n_local)))
        while local and (local[0][1].done() or len(local) > ahead):
            i, f = local.pop(0)
            found.append(one_place(-1, i, *f.result()))

    try:
        for row, spec in in_order(clip, posed(), ahead):
            rows.append(row)
            specs.append(spec)
            if orb is not None:
                detect_spaced()
            tick()
        if orb is not None:
            detect_spaced()
            found.extend(one_place(-1, i, *f.result()) for i, f in local)
    finally:
        if orb is not None:
            orb.shutdown(cancel_futures=True)
    if (w := clip.warning(p.src.video.name)) is not None:
        log.warning(w)
    _check_complete(p, seen)
    if not rows:
        raise OmninavError(
            f"{p.src.video.name}: no frame of the video lies between the walk path's first and last waypoint"
        )
    new = np.zeros(len(rows), FRAME_DTYPE)
    arr = np.array(rows, np.float64)
    new["x"], new["y"], new["heading"], new["t"] = arr[:, 0], arr[:, 1], arr[:, 2], arr[:, 3]
    new["frame"] = arr[:, 4].astype(np.int32)
    return new, np.stack(specs), (concat(found) if orb is not None else None)


def _check_complete(p: _Plan, seen: int) -> None:
    """A damaged file decodes up to the damage and then ends as if it were shorter: the container
    still says how many frames it holds. Modelling what came before would model part of the walk."""
    want = min(p.last, p.info.frames - 1) if p.info.frames else p.last
    want -= (want - p.first) % p.stride  # the last frame the sampling would reach
    if p.info.frames and seen < want - p.stride:
        at = max(seen, p.first) / p.vfps
        raise OmninavError(
            f"{p.src.video.name}: the video stops decoding at {int(at // 60)}:{at % 60:04.1f} "
            f"(frame {max(seen, 0)} of {p.info.frames}): the file is damaged; upload it again"
        )


def _current(store: Store, venue_id: str) -> Generation | None:
    try:
        return store.load(venue_id, mmap=False)
    except OmninavError:
        return None


def model_videos(
    store: Store,
    venue_id: str,
    sources: list[VideoSource],
    progress: Progress | None = None,
    before_commit: Callable[[], None] | None = None,
    settings: dict[str, Any] | None = None,
    anew: bool = False,
) -> list[ModelResult]:
    """Model several videos into one new generation; a video already in the venue is replaced.

    The feature settings are the live generation's (frames made with other settings could not be
    searched together); a venue's first videos use `settings` (the catalogue passes the venue's
    preset), else the default preset. `anew`: the new generation holds these videos only, made
    with `settings` (a venue modelled before its preset improved, modelled again with the preset
    as it is now: every one of its modelling videos, so that none is lost). `before_commit` runs
    under the venue's lock just before the commit; it may raise to commit nothing (a job runner
    checks there that the job is still its own: see server/jobs.py)."""
    if anew:
        if settings is None:
            raise ValueError("modelling anew needs the settings to model with")
    else:
        settings = store.settings(venue_id) or settings or resolve("default")
    plans = [_plan(s, settings) for s in sources]
    expected = sum(p.expected for p in plans)
    t0 = time.perf_counter()
    done = 0

    def tick() -> None:
        nonlocal done
        done += 1
        if progress:
            progress(done, expected, time.perf_counter() - t0)

    extracted = []
    workers = extract_threads()
    shapes = {(p.info.height, p.info.width, 3) for p in plans}
    with contextlib.ExitStack() as stack:
        if workers > 1 and expected >= PROCESSES_FROM and all(extract_pool.fits(workers, s) for s in shapes):
            submit: Submit = extract_pool.shared(workers).extract(settings)
        else:
            threads = stack.enter_context(ThreadPoolExecutor(workers, thread_name_prefix="omninav-extract"))
            submit = on_pool(threads, Extractors(settings, size=2).spectrum)
        for p in plans:
            ts = time.perf_counter()
            rows, specs, local = _extract(p, tick, submit, ahead=2 * workers, n_local=settings.get("local_features"))
            extracted.append((p, rows, specs, local, time.perf_counter() - ts))
    with store.lock(venue_id):  # read the live generation and commit the next as one step
        return _merge_commit(store, venue_id, settings, sources[-1].lens, extracted, before_commit, anew)


def start_workers() -> None:
    """Start the processes that a long walk's frames are extracted on (extract_pool.shared), ~0.2 s,
    now rather than at the first modelling: a job runner does at its start. Nothing on one core,
    where modelling extracts on this process."""
    workers = extract_threads()
    if workers > 1:
        extract_pool.shared(workers)


def _merge_commit(
    store: Store,
    venue_id: str,
    settings: dict[str, Any],
    lens: Lens,
    extracted: list[tuple[_Plan, np.ndarray, np.ndarray, LocalFeatures | None, float]],
    before_commit: Callable[[], None] | None = None,
    anew: bool = False,
) -> list[ModelResult]:
    old = None if anew else _current(store, venue_id)
    videos = list(old.videos) if old else []
    frames = old.frames if old is not None else np.zeros(0, FRAME_DTYPE)
    spectra = old.spectra if old is not None else np.zeros((0,) + extracted[0][2].shape[1:], np.complex64)
    local = old.local if old is not None else None
    if local is None and settings.get("local_features"):
        local = LocalFeatures.empty()
    results = []
    for p, rows, specs, found, secs in extracted:
        name = p.src.video.name
        if name in videos:  # re-modelling a video replaces its frames
            vid = videos.index(name)
            keep = frames["video"] != vid
            frames, spectra = frames[keep], spectra[keep]
            if local is not None:
                local = local.keep(local.places["video"] != vid)
        else:
            videos.append(name)
            vid = len(videos) - 1
        rows["video"] = vid
        frames = np.concatenate([frames, rows])
        spectra = np.concatenate([spectra, specs])
        if local is not None and found is not None:
            found.places["video"] = vid
            local = local + found
        vid_secs = (int(rows["frame"][-1]) - p.first + 1) / p.vfps
        results.append(ModelResult(venue_id, name, len(rows), 0, secs, vid_secs))
    if before_commit:
        before_commit()
    # the lens of the last video is the venue's default query lens (for clients that send frames)
    store.commit(venue_id, Generation(settings, lens, frames, spectra, videos, local=local))
    for r in results:
        r.total_frames = len(frames)
    return results


def model_video(
    store: Store,
    venue_id: str,
    video: Path,
    walk_path: WalkPath,
    lens: Lens,
    progress: Progress | None = None,
    settings: dict[str, Any] | None = None,
) -> ModelResult:
    return model_videos(store, venue_id, [VideoSource(video, walk_path, lens)], progress, settings=settings)[0]


def remove_video(store: Store, venue_id: str, name: str) -> int:
    """Drop one modelling video's frames in a new generation; returns how many frames went.

    Removing the last video leaves a venue with no frames (it answers 'not modelled yet').
    """
    with store.lock(venue_id):
        return _remove(store, venue_id, name)


def _remove(store: Store, venue_id: str, name: str) -> int:
    old = _current(store, venue_id)
    if old is None or name not in old.videos:
        return 0
    vid = old.videos.index(name)
    keep = old.frames["video"] != vid
    frames = old.frames[keep].copy()
    frames["video"] -= (frames["video"] > vid).astype(np.int32)  # renumber: videos.json loses one entry
    videos = [v for v in old.videos if v != name]
    local = old.local
    if local is not None:
        local = local.keep(local.places["video"] != vid)
        local.places["video"] -= (local.places["video"] > vid).astype(np.int32)
    store.commit(venue_id, Generation(old.settings, old.lens, frames, old.spectra[keep], videos, local=local))
    return int((~keep).sum())
