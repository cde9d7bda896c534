"""Modelling (`omninav model`): a panoramic video + its track -> the venue's frames and spectra.

Frames are sampled at the preset's `model_fps` (from a 30 fps video, every third), placed by
linear interpolation of the track's waypoints and headed along the direction of travel. The result
joins the frames of the venue's other modelling videos in a new generation (store.py), atomically.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .errors import OmninavError
from .extract import Extractor
from .lens import Lens
from .store import FRAME_DTYPE, Generation, Store
from .track import Track
from .video import VideoInfo, iter_video

Progress = Callable[[int, int, float], None]  # frames done, frames expected, seconds elapsed


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


def model_video(
    store: Store, venue_id: str, video: Path, track: Track, lens: Lens, progress: Progress | None = None
) -> ModelResult:
    store.require(venue_id)
    settings = store.settings(venue_id)
    info = VideoInfo(video)
    w, h = lens.image_size
    if (info.width, info.height) != (w, h):
        raise OmninavError(f"{video}: frames are {info.width}x{info.height} but the lens profile is for {w}x{h}")
    vfps = info.fps if info.fps > 0 else track.fps
    stride = max(1, int(round(vfps / settings["model_fps"])))
    first = max(0, int(np.ceil(track.times[0] * track.fps - 1e-6)))
    last = int(np.floor(track.times[-1] * track.fps + 1e-6))
    if info.frames and first >= info.frames:
        raise OmninavError(f"{video}: the track starts after the video ends ({info.frames} frames)")
    expected = (min(last, info.frames - 1 if info.frames else last) - first) // stride + 1
    ext = Extractor(lens, settings)
    rows, specs = [], []
    t0 = time.perf_counter()
    for i, frame in iter_video(info, stride=stride, start=first):
        if i > last:
            break
        t = i / track.fps
        xy, hd, ok = track.pose_at(np.array([t]))
        if not ok[0]:
            continue
        specs.append(ext.spectrum(frame))
        rows.append((xy[0, 0], xy[0, 1], hd[0], t, i))
        if progress:
            progress(len(rows), expected, time.perf_counter() - t0)
    if not rows:
        raise OmninavError(f"{video}: no frame of the video lies between the track's first and last waypoint")
    name = video.name
    try:
        old = store.load(venue_id, mmap=False)
    except OmninavError:
        old = None
    videos = list(old.videos) if old else []
    keep_f = old.frames if old is not None else np.zeros(0, FRAME_DTYPE)
    keep_s = old.spectra if old is not None else np.zeros((0,) + specs[0].shape, np.complex64)
    if name in videos:  # re-modelling a video replaces its frames
        vid = videos.index(name)
        m = keep_f["video"] != vid
        keep_f, keep_s = keep_f[m], keep_s[m]
    else:
        videos.append(name)
        vid = len(videos) - 1
    new = np.zeros(len(rows), FRAME_DTYPE)
    arr = np.array(rows, np.float64)
    new["x"], new["y"], new["heading"], new["t"] = arr[:, 0], arr[:, 1], arr[:, 2], arr[:, 3]
    new["frame"] = arr[:, 4].astype(np.int32)
    new["video"] = vid
    frames = np.concatenate([keep_f, new])
    spectra = np.concatenate([keep_s, np.stack(specs)])
    store.commit(venue_id, Generation(settings, lens, frames, spectra, videos))
    secs = time.perf_counter() - t0
    vid_secs = ((rows[-1][4] - first) + 1) / vfps
    return ModelResult(venue_id, name, len(rows), len(frames), secs, vid_secs)
