"""One frame of a video, for a person to look at: as the camera saw it, or unwrapped.

The admin page shows the frame at the time being tagged; the panorama is the engine's own unwarp
(unwarp.py) of that frame with the video's lens, over the lens's whole elevation range, with the
lens's forward direction (the walking direction) at the centre column. A file in, JPEG bytes out;
the catalogue (catalog/videos.py) finds the file and the lens.

A preview is the heaviest thing a worker does for one request: decoding a frame holds about 12
bytes a pixel at its peak (22 MB for 1920x960, 85 MB for 3840x1920). So a process makes one at a
time (`PREVIEWS`, a gate.Gate: one more may wait, others are told to ask again), decodes on one
thread, builds a panorama's remap a block of rows at a time, and keeps the maps for the next
request within a byte budget (`MAPS`). Measured in docs/decisions.md, "Preview memory".
"""

from __future__ import annotations

import threading
from collections import OrderedDict
from collections.abc import Iterator

import cv2
import numpy as np

from .errors import OmninavError, Unusable
from .gate import Gate
from .lens import Lens
from .unwarp import UnwarpMap, build_map, panorama_elevations, unwarp

VIEWS = ("raw", "panorama")
RAW_WIDTH = 960  # default width of the frame as seen; never enlarged
RAW_MAX_WIDTH = 1920  # a wider request gets this: the frame is "at most `width` wide"
PANO_WIDTH = 1440  # default width of the panorama (360 degrees)
MIN_WIDTH = 16
MAX_WIDTH = 2880
JPEG_QUALITY = 85

# One preview at a time per process, and one more waiting: the admin page asks for a frame and its
# panorama together. Of a worker's THREADS (4 by default), two stay free for the rest.
PREVIEWS_AT_ONCE = 1
PREVIEWS_WAITING = 1
PREVIEW_WAIT_S = 2.0  # a preview takes 0.02-0.2 s (a 3840x1920 frame's panorama about 0.4 s)
RETRY_AFTER_S = 1.0  # a refused preview asks again after this
MAP_CACHE_BUDGET = 12 << 20  # bytes of panorama maps kept for the next request: the default 1440-wide map of any lens
MAP_BYTES_PER_PX = 9  # map_x and map_y float32, valid bool
MAP_BLOCK_PX = 1 << 16  # a map is built this many pixels at a time: bounds its float64 temporaries


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
    end is the last frame). Unusable for t outside [0, duration].

    FFmpeg decodes on one thread: its frame threads would each hold frames of their own (one per
    core), and the decoder is released before the frame is returned.
    """
    duration = frames / fps if fps > 0 and frames > 0 else 0.0
    if not 0.0 <= t <= duration:
        raise Unusable(f"t must be within the video's 0 to {duration:.3f} s, got {t:g}")
    index = min(int(t * fps), frames - 1)
    cap = cv2.VideoCapture(path, cv2.CAP_FFMPEG, [cv2.CAP_PROP_N_THREADS, 1])
    try:
        if index:
            cap.set(cv2.CAP_PROP_POS_FRAMES, index)
        ok, frame = cap.read()
    finally:
        cap.release()
    if not ok or frame is None:
        raise OmninavError(f"the frame at {t:g} s does not decode")
    return np.asarray(frame)


def pano_elevations(lens: Lens, width: int) -> np.ndarray:
    """(rows,) elevations of a `width`-column panorama: square pixels, as many degrees a row as a
    column, from the highest elevation the lens sees down."""
    lo, hi = lens.elevation_range()
    return panorama_elevations(hi, lo, 360.0 / width)


def pano_blocks(lens: Lens, width: int) -> Iterator[tuple[slice, UnwarpMap]]:
    """The remap of a `width`-column panorama with forward at column width // 2, a block of rows
    at a time: (its rows, its map). `build_map`'s float64 grids and temporaries (about 100 bytes a
    pixel) then exist for one block, never for the whole panorama."""
    el = pano_elevations(lens, width)
    step, shift = max(1, MAP_BLOCK_PX // width), width // 2  # column 0 looks forward: to the centre
    for r in range(0, len(el), step):
        m = build_map(lens, el[r : r + step], width)
        x, y, valid = (np.roll(a, shift, axis=1) for a in (m.map_x, m.map_y, m.valid))
        yield slice(r, r + len(m.elevations)), UnwarpMap(x, y, m.elevations, valid, m.border)


def pano_map(lens: Lens, width: int) -> UnwarpMap:
    """The whole remap of a `width`-column panorama (as `pano_blocks`), float32, for keeping."""
    el = pano_elevations(lens, width)
    map_x, map_y = np.empty((2, len(el), width), np.float32)
    valid = np.empty((len(el), width), bool)
    border = cv2.BORDER_CONSTANT
    for rows, m in pano_blocks(lens, width):
        map_x[rows], map_y[rows], valid[rows], border = m.map_x, m.map_y, m.valid, m.border
    return UnwarpMap(map_x, map_y, el.astype(np.float32), valid, border)


def pano_map_bytes(lens: Lens, width: int) -> int:
    """The bytes of `pano_map(lens, width)`, without making it."""
    rows = len(pano_elevations(lens, width))
    return rows * (MAP_BYTES_PER_PX * width + 4)  # and the rows' float32 elevations


def map_bytes(m: UnwarpMap) -> int:
    return m.map_x.nbytes + m.map_y.nbytes + m.valid.nbytes + m.elevations.nbytes


class MapCache:
    """The panorama maps last used, by (lens, width), within `budget` bytes together, the least
    recently used going first. A map larger than the budget is never built whole."""

    def __init__(self, budget: int):
        self.budget = budget
        self._maps: OrderedDict[tuple[Lens, int], UnwarpMap] = OrderedDict()
        self._lock = threading.Lock()

    def get(self, lens: Lens, width: int) -> UnwarpMap | None:
        """The whole map, built now if it is not kept; None if it is larger than the budget."""
        key = (lens, width)
        with self._lock:
            if (hit := self._maps.get(key)) is not None:
                self._maps.move_to_end(key)
                return hit
        if pano_map_bytes(lens, width) > self.budget:
            return None
        m = pano_map(lens, width)  # outside the lock: two first requests may both build it
        with self._lock:
            self._maps[key] = m
            while sum(map(map_bytes, self._maps.values())) > self.budget:
                self._maps.popitem(last=False)
        return m

    def bytes(self) -> int:
        with self._lock:
            return sum(map_bytes(v) for v in self._maps.values())


PREVIEWS = Gate(PREVIEWS_AT_ONCE, PREVIEWS_WAITING, PREVIEW_WAIT_S, RETRY_AFTER_S)
MAPS = MapCache(MAP_CACHE_BUDGET)


def panorama(frame: np.ndarray, lens: Lens, width: int) -> np.ndarray:
    """The frame unwrapped by the engine's unwarp: `width` columns for 360 degrees clockwise,
    forward at column width // 2, rows from the highest elevation the lens sees down."""
    w, h = lens.image_size
    if frame.shape[:2] != (h, w):
        raise OmninavError(f"the frame is {frame.shape[1]}x{frame.shape[0]} but the lens is for {w}x{h}")
    m = MAPS.get(lens, width)
    if m is not None:
        return unwarp(frame, m)
    out = np.empty((len(pano_elevations(lens, width)), width, 3), frame.dtype)
    for rows, block in pano_blocks(lens, width):
        out[rows] = unwarp(frame, block)
    return out


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
    """The frame at t as a JPEG: 'raw' (at most `width` wide) or 'panorama' (`width` wide), made
    on the gate's thread; Busy while this process makes a preview and another waits already."""
    width = check_view(view, width)
    return PREVIEWS.run("preview", lambda: render(path, lens, t, fps, frames, view, width))


def render(path: str, lens: Lens, t: float, fps: float, frames: int, view: str, width: int) -> bytes:
    """The JPEG of `frame_jpeg`, made here and now; the decoded frame goes before it is encoded."""
    frame = read_frame(path, t, fps, frames)
    img = downscale(frame, width) if view == "raw" else panorama(frame, lens, width)
    del frame
    return jpeg(img)
