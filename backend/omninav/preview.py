"""One frame of a video, for a person to look at: as the camera saw it, or unwrapped.

The admin page shows the frame at the time being tagged; the panorama is the engine's own unwarp
(unwarp.py) of that frame with the video's lens, over the lens's whole elevation range, with the
lens's forward direction (the walking direction) at the centre column. Pure: a file in, JPEG bytes
out; the catalogue (catalog/videos.py) finds the file and the lens.
"""

from __future__ import annotations

from functools import lru_cache

import cv2
import numpy as np

from .errors import OmninavError, Unusable
from .lens import Lens
from .unwarp import UnwarpMap, build_map, panorama_elevations, unwarp

VIEWS = ("raw", "panorama")
RAW_WIDTH = 960  # default width of the frame as seen; never enlarged
RAW_MAX_WIDTH = 1920  # a wider request gets this: the frame is "at most `width` wide"
PANO_WIDTH = 1440  # default width of the panorama (360 degrees)
MIN_WIDTH = 16
MAX_WIDTH = 2880
JPEG_QUALITY = 85


def check_view(view: str, width: int | None) -> int:
    """The width to render `view` at (default by view), or an error naming the bounds."""
    if view not in VIEWS:
        raise OmninavError(f"view must be one of {', '.join(VIEWS)}, got {view!r}")
    if width is None:
        return RAW_WIDTH if view == "raw" else PANO_WIDTH
    if not MIN_WIDTH <= width <= MAX_WIDTH:
        raise OmninavError(f"width must be {MIN_WIDTH} to {MAX_WIDTH} pixels, got {width}")
    return min(width, RAW_MAX_WIDTH) if view == "raw" else width


def read_frame(path: str, t: float, fps: float, frames: int) -> np.ndarray:
    """The BGR frame shown at `t` seconds (the frame whose display interval holds t; t at the very
    end is the last frame). Unusable for t outside [0, duration]."""
    duration = frames / fps if fps > 0 and frames > 0 else 0.0
    if not 0.0 <= t <= duration:
        raise Unusable(f"t must be within the video's 0 to {duration:.3f} s, got {t:g}")
    index = min(int(t * fps), frames - 1)
    cap = cv2.VideoCapture(path)
    try:
        if index:
            cap.set(cv2.CAP_PROP_POS_FRAMES, index)
        ok, frame = cap.read()
    finally:
        cap.release()
    if not ok or frame is None:
        raise OmninavError(f"the frame at {t:g} s does not decode")
    return np.asarray(frame)


@lru_cache(maxsize=8)
def _pano_map(lens: Lens, width: int) -> UnwarpMap:
    lo, hi = lens.elevation_range()
    el = panorama_elevations(hi, lo, 360.0 / width)  # square pixels: as many degrees a row as a column
    m = build_map(lens, el, width)
    shift = width // 2  # column 0 looks forward: roll it to the centre
    return UnwarpMap(
        np.roll(m.map_x, shift, axis=1),
        np.roll(m.map_y, shift, axis=1),
        m.elevations,
        np.roll(m.valid, shift, axis=1),
        m.border,
    )


def panorama(frame: np.ndarray, lens: Lens, width: int) -> np.ndarray:
    """The frame unwrapped by the engine's unwarp: `width` columns for 360 degrees clockwise,
    forward at column width // 2, rows from the highest elevation the lens sees down."""
    w, h = lens.image_size
    if frame.shape[:2] != (h, w):
        raise OmninavError(f"the frame is {frame.shape[1]}x{frame.shape[0]} but the lens is for {w}x{h}")
    return unwarp(frame, _pano_map(lens, width))


def downscale(frame: np.ndarray, width: int) -> np.ndarray:
    """The frame at most `width` wide, its aspect kept (never enlarged)."""
    h, w = frame.shape[:2]
    if w <= width:
        return frame
    return cv2.resize(frame, (width, max(1, round(h * width / w))), interpolation=cv2.INTER_AREA)


def jpeg(img: np.ndarray, quality: int = JPEG_QUALITY) -> bytes:
    ok, buf = cv2.imencode(".jpg", img, [cv2.IMWRITE_JPEG_QUALITY, quality])
    if not ok:
        raise OmninavError("the frame could not be encoded as JPEG")
    return bytes(buf.tobytes())


def frame_jpeg(path: str, lens: Lens, t: float, fps: float, frames: int, view: str, width: int | None) -> bytes:
    """The frame at t as a JPEG: 'raw' (at most `width` wide) or 'panorama' (`width` wide)."""
    width = check_view(view, width)
    frame = read_frame(path, t, fps, frames)
    return jpeg(downscale(frame, width) if view == "raw" else panorama(frame, lens, width))
