"""Decoding: modelling videos and query clips (a video file or a directory of frame images).

OpenCV's FFmpeg backend reads every common container and codec. Frames we do not need are
`grab`bed (demuxed and decoded, never converted), which is what keeps modelling fast.
"""

from __future__ import annotations

import threading
from collections.abc import Iterator
from pathlib import Path
from queue import Queue

import cv2
import numpy as np

from .errors import OmninavError

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


def iter_video(info: VideoInfo, stride: int = 1, start: int = 0) -> Iterator[tuple[int, np.ndarray]]:
    """Yield (frame index, BGR frame) for every `stride`-th frame, decoding on a second thread.

    Takes a VideoInfo, so the video has been checked (once) before the thread starts. The reader
    thread overlaps decoding with the caller's feature extraction (OpenCV releases the GIL), so
    the two cores both work.
    """
    path = info.path
    q: Queue[tuple[int, np.ndarray] | None] = Queue(maxsize=32)
    stop = threading.Event()

    def reader() -> None:
        cap = cv2.VideoCapture(str(path))
        i = 0
        try:
            while not stop.is_set():
                if i >= start and (i - start) % stride == 0:
                    ok, f = cap.read()
                    if not ok:
                        break
                    q.put((i, f))
                elif not cap.grab():
                    break
                i += 1
        finally:
            cap.release()
            q.put(None)

    th = threading.Thread(target=reader, daemon=True)
    th.start()
    try:
        while (item := q.get()) is not None:
            yield item
    finally:
        stop.set()
        while th.is_alive():  # drain so the reader can finish its put and exit
            try:
                q.get(timeout=0.05)
            except Exception:  # noqa: BLE001 - queue.Empty: nothing left to drain
                pass


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
