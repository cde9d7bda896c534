"""Decoding: modelling videos and query clips (a video file or a directory of frame images), and
their frames' features extracted on several threads (a long walk's on processes: extract_pool.py) in
the order they were decoded.

OpenCV's FFmpeg backend reads every common container and codec. Frames we do not need are
`grab`bed (demuxed and decoded, never converted), and none past the last one wanted is decoded.
"""

from __future__ import annotations

import os
import threading
from collections import deque
from collections.abc import Callable, Generator, Iterable, Iterator
from concurrent.futures import Executor, Future
from pathlib import Path
from queue import Queue
from typing import Any, TypeVar

import cv2
import numpy as np

from .calib.correct import ClipLens
from .errors import OmninavError
from .lens import Lens

T = TypeVar("T")

IMAGE_EXT = {".png", ".jpg", ".jpeg", ".bmp", ".tif", ".tiff", ".webp"}


class VideoInfo:
    def __init__(self, path: Path, label: str | None = None):
        """`label` names the video in errors (the server names a video, never a path on its disk)."""
        label = label or str(path)
        if not path.exists():
            raise OmninavError(f"{label}: video not found")
        if path.is_dir():
            raise OmninavError(f"{label}: is a directory, expected a video file")
        self.path = path
        cap = cv2.VideoCapture(str(path))
        ok = cap.isOpened()
        first = cap.read()[0] if ok else False
        self.fps = float(cap.get(cv2.CAP_PROP_FPS) or 0.0) if ok else 0.0
        self.frames = int(cap.get(cv2.CAP_PROP_FRAME_COUNT) or 0) if ok else 0
        self.width = int(cap.get(cv2.CAP_PROP_FRAME_WIDTH) or 0)
        self.height = int(cap.get(cv2.CAP_PROP_FRAME_HEIGHT) or 0)
        cap.release()
        if not ok or not first:
            raise OmninavError(f"{label}: not a readable video (no decodable frames)")


def iter_video(
    info: VideoInfo, stride: int = 1, start: int = 0, last: int | None = None
) -> Iterator[tuple[int, np.ndarray]]:
    """Yield (frame index, BGR frame) for every `stride`-th frame from `start`, up to frame `last`
    (None: to the end), decoding on a second thread.

    Takes a VideoInfo, so the video has been checked (once) before the thread starts. The reader
    thread overlaps decoding with the caller's feature extraction (OpenCV releases the GIL), and
    stops at `last` rather than decoding a queue's worth of frames the caller would throw away.
    """
    return read_ahead(_frames(info.path, stride, start, last), 32)


def _frames(path: Path, stride: int, start: int, last: int | None) -> Iterator[tuple[int, np.ndarray]]:
    """(index, BGR frame) of every `stride`-th frame from `start` to `last`; the others are only
    `grab`bed. FFmpeg decodes on this one thread: the extraction threads or processes keep the
    cores busy, and its frame threads would only add hand-offs (measured: bench/model_speed.py,
    docs/decisions.md)."""
    cap = cv2.VideoCapture(str(path), cv2.CAP_FFMPEG, [cv2.CAP_PROP_N_THREADS, 1])
    try:
        i = 0
        while last is None or i <= last:
            if i >= start and (i - start) % stride == 0:
                ok, f = cap.read()
                if not ok:
                    return
                yield i, f
            elif not cap.grab():
                return
            i += 1
    finally:
        cap.release()


_END = object()


def read_ahead(items: Iterator[T], size: int) -> Generator[T, None, None]:
    """`items` pulled on a thread of their own, at most `size` ahead of the caller: decoding
    (OpenCV releases the GIL) overlaps whatever the caller does with each item.

    An error on that thread is raised here. When the caller stops early, the thread stops after
    the item it is on and closes `items` (a generator's `finally` releases its decoder there).
    """
    q: Queue[tuple[Any, BaseException | None]] = Queue(maxsize=size)
    stop = threading.Event()

    def reader() -> None:
        err: BaseException | None = None
        try:
            for x in items:
                if stop.is_set():
                    break
                q.put((x, None))
        except Exception as e:  # noqa: BLE001 - handed to the caller, who raises it
            err = e
        finally:
            close = getattr(items, "close", None)
            if close is not None:
                close()
            q.put((_END, err))

    th = threading.Thread(target=reader, daemon=True)
    th.start()
    try:
        while True:
            x, err = q.get()
            if x is _END:
                if err is not None:
                    raise err
                return
            yield x
    finally:
        stop.set()
        while th.is_alive():  # drain so the reader can finish its put and exit
            try:
                q.get(timeout=0.05)
            except Exception:  # noqa: BLE001 - queue.Empty: nothing left to drain
                pass


def extract_threads() -> int:
    """Threads (or processes) that extract a video's frames: one a core this process may run on."""
    return len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count() or 1


def on_pool(
    pool: Executor, extract: Callable[[Lens], Callable[[np.ndarray], np.ndarray]]
) -> Callable[[Lens], Callable[[np.ndarray], Future[np.ndarray]]]:
    """A ClipLens `extract` that hands each frame to `pool` rather than extracting it: the clip's
    spectra come out as futures, in frame order, for `in_order` to collect (the frames held while
    the ring is measured are extracted in parallel too)."""

    def submitting(lens: Lens) -> Callable[[np.ndarray], Future[np.ndarray]]:
        fn = extract(lens)
        return lambda frame: pool.submit(fn, frame)

    return submitting


def in_order(
    clip: ClipLens[Future[np.ndarray]], frames: Iterable[tuple[T, np.ndarray]], ahead: int
) -> Iterator[tuple[T, np.ndarray]]:
    """(tag, frame) pairs -> (tag, spectrum) pairs in the same order, through `clip` built with
    `on_pool`: at most `ahead` frames are submitted and not yet collected (each holds its decoded
    frame). When the caller stops early, or `frames` or an extraction raises, what is pending is
    cancelled and `frames` closed (a decoder on a read_ahead thread stops there and then)."""
    tags: deque[T] = deque()  # the frames fed and not handed out yet, oldest first
    pending: deque[Future[np.ndarray]] = deque()
    try:
        for tag, frame in frames:
            tags.append(tag)
            pending.extend(clip.feed(frame))
            while len(pending) > ahead:
                yield tags.popleft(), pending.popleft().result()
        pending.extend(clip.flush())
        while pending:
            yield tags.popleft(), pending.popleft().result()
    finally:
        for f in pending:
            f.cancel()
        close = getattr(frames, "close", None)
        if close is not None:
            close()


def read_clip(path: Path, max_frames: int = 600) -> tuple[list[np.ndarray], float | None]:
    """All frames of a query clip and its frame rate: a video file, or a directory of images
    (sorted by name; no frame rate)."""
    if not path.exists():
        raise OmninavError(f"{path}: clip not found")
    if path.is_dir():
        files = sorted(p for p in path.iterdir() if p.suffix.lower() in IMAGE_EXT)
        if not files:
            raise OmninavError(f"{path}: directory holds no frame images ({', '.join(sorted(IMAGE_EXT))})")
        if len(files) > max_frames:
            raise OmninavError(f"{path}: {len(files)} frames; a clip may hold at most {max_frames}")
        frames = []
        for f in files:
            img = cv2.imread(str(f), cv2.IMREAD_COLOR)
            if img is None:
                raise OmninavError(f"{f}: not a readable image")
            frames.append(img)
        if len({fr.shape for fr in frames}) != 1:
            raise OmninavError(f"{path}: frames have different sizes")
        return frames, None
    info = VideoInfo(path)
    frames = [f for _, f in iter_video(info)]
    if len(frames) > max_frames:
        raise OmninavError(f"{path}: {len(frames)} frames; a clip may hold at most {max_frames}")
    return frames, info.fps or None
