"""Calibration boards (chessboard, ChArUco) and their corners in donut frames.

`parse_board` reads the `--board SPEC` of `omninav calib lens`; `detect_board` finds the board's
corners in one donut frame without knowing the lens's elevation polynomial (it is what the fit is
for): only the ring (centre, inner and outer radius) is needed.

How (each choice measured on `synth.calibration` renders through four lens geometries):
1. Unwrap the ring into a panorama-like view: rows linear in radius (outer edge on top), columns
   the image angle, about the raw resolution of the outer edge. A board there looks nearly as it
   would through a normal camera: OpenCV's detectors work unchanged (no local views needed).
2. Chessboard: X-junctions (saddles of the grey surface) are grouped by their spacing; each group
   is cropped, magnified to >= 14 px squares and given to `findChessboardCorners` (then the
   slower `findChessboardCornersSB`). The view runs on 90 degrees past 360 so that a board
   across the seam is whole once. The grid must follow a smooth model, every corner must be a
   saddle and one step beyond each side must be plain paper: a spec smaller or larger than the
   print finds nothing rather than wrong corners.
   ChArUco: `CharucoDetector` in a 1.5x view, in both mirror senses (a mirror lens flips the
   picture and markers read only one way round), and turned by 180 degrees when markers touch
   the seam. Partial boards are kept. A spec of other columns or dictionary finds nothing; one
   with more rows than printed sees the print as a partial board (its corners are right).
3. Corners are refined by cornerSubPix in the view and mapped back exactly (the view's formula);
   cornerSubPix in the raw frame then checks each (moved > 1.5 px, or off the ring: dropped).
"""

from __future__ import annotations

import dataclasses
import math
import re
from collections.abc import Iterator
from dataclasses import dataclass
from typing import Protocol

import cv2
import numpy as np

from ..errors import OmninavError

DEFAULT_DICT = "DICT_5X5_100"
CHESS_FORMAT = "chess:COLSxROWS:SQUARE_M (inner corners, as OpenCV's patternSize, e.g. chess:9x6:0.03)"
CHARUCO_FORMAT = (
    "charuco:SQUARESXxSQUARESY:SQUARE_M:MARKER_M[:DICT] (squares, e.g. charuco:7x5:0.04:0.03:DICT_5X5_100; "
    f"DICT defaults to {DEFAULT_DICT})"
)
BOARD_FORMAT = f"expected {CHESS_FORMAT} or {CHARUCO_FORMAT}, sizes in metres"
MAX_COUNT = 64  # corners or squares a side: far more than any printed board, bounds the work


@dataclass(frozen=True)
class BoardSpec:
    """A printed board. Chess: `cols` x `rows` inner corners. ChArUco: `cols` x `rows` squares.

    Board coordinates (metres, z = 0, y down the printed page): a chessboard's origin is its first
    inner corner (OpenCV's usual object points); a ChArUco board's is the outer corner of its first
    square, as `cv2.aruco.CharucoBoard` has it. Chessboards print with a black top-left square.
    """

    kind: str  # "chess" | "charuco"
    cols: int
    rows: int
    square_m: float
    marker_m: float | None = None
    dictionary: str | None = None

    @property
    def corner_grid(self) -> tuple[int, int]:
        """(columns, rows) of inner corners: OpenCV's patternSize."""
        return (self.cols, self.rows) if self.kind == "chess" else (self.cols - 1, self.rows - 1)

    @property
    def n_corners(self) -> int:
        c, r = self.corner_grid
        return c * r

    @property
    def squares(self) -> tuple[int, int]:
        """(columns, rows) of squares on the printed board."""
        return (self.cols + 1, self.rows + 1) if self.kind == "chess" else (self.cols, self.rows)

    def object_points(self) -> np.ndarray:
        """(N, 3) float64 board corners in metres, z = 0, in OpenCV's order (row by row, x fastest);
        for ChArUco the chessboard corner ids of `cv2.aruco.CharucoBoard`."""
        if self.kind == "charuco":
            return np.asarray(self.charuco_board().getChessboardCorners(), np.float64).reshape(-1, 3)
        c, r = self.corner_grid
        jj, ii = np.mgrid[0:r, 0:c]
        return np.stack([ii.ravel(), jj.ravel(), np.zeros(c * r)], -1).astype(np.float64) * self.square_m

    def outline(self) -> tuple[float, float, float, float]:
        """(u0, v0, u1, v1): the squares' extent in board coordinates (metres)."""
        sx, sy = self.squares
        if self.kind == "chess":
            return -self.square_m, -self.square_m, (sx - 1) * self.square_m, (sy - 1) * self.square_m
        return 0.0, 0.0, sx * self.square_m, sy * self.square_m

    def charuco_board(self) -> cv2.aruco.CharucoBoard:
        if self.kind != "charuco" or self.marker_m is None or self.dictionary is None:
            raise ValueError("not a ChArUco board")
        return _charuco(self.cols, self.rows, self.square_m, self.marker_m, self.dictionary)


_BOARDS: dict[tuple[int, int, float, float, str], cv2.aruco.CharucoBoard] = {}


def _charuco(cols: int, rows: int, square: float, marker: float, dictionary: str) -> cv2.aruco.CharucoBoard:
    key = (cols, rows, square, marker, dictionary)
    if key not in _BOARDS:
        d = cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, dictionary))
        _BOARDS[key] = cv2.aruco.CharucoBoard((cols, rows), square, marker, d)
    return _BOARDS[key]


def _bad(spec: str, what: str) -> OmninavError:
    """The one-line error: what was wrong, then the format of the kind of board the spec names."""
    kind = spec.split(":")[0].strip().lower()
    fmt = {"chess": CHESS_FORMAT, "charuco": CHARUCO_FORMAT}.get(kind)
    return OmninavError(
        f"board spec {spec!r}: {what}; " + (f"expected {fmt}, sizes in metres" if fmt else BOARD_FORMAT)
    )


def _metres(spec: str, text: str, name: str) -> float:
    try:
        v = float(text)
    except ValueError:
        raise _bad(spec, f"{name} {text!r} is not a number") from None
    if not math.isfinite(v) or v <= 0:
        raise _bad(spec, f"{name} must be a positive size in metres, got {text}")
    if v >= 2.0:
        raise _bad(spec, f"{name} {text} is in metres (did you mean {v / 1000:g}?)")
    return v


def _counts(spec: str, text: str, what: str, least: int) -> tuple[int, int]:
    m = re.fullmatch(r"\s*(\d+)\s*[xX×]\s*(\d+)\s*", text)
    if not m:
        raise _bad(spec, f"{what} {text!r} must be two whole numbers like 9x6")
    a, b = int(m.group(1)), int(m.group(2))
    if min(a, b) < least or max(a, b) > MAX_COUNT:
        raise _bad(spec, f"{what} {a}x{b} must each be {least} to {MAX_COUNT}")
    return a, b


def _dictionary(spec: str, name: str) -> str:
    name = name.strip().upper()
    if not name.startswith("DICT_"):
        name = "DICT_" + name
    if not re.fullmatch(r"DICT_\w+", name) or not isinstance(getattr(cv2.aruco, name, None), int):
        raise _bad(spec, f"unknown ArUco dictionary {name!r} (e.g. DICT_4X4_50, DICT_5X5_100, DICT_6X6_250)")
    return name


def parse_board(spec: str) -> BoardSpec:
    """`chess:9x6:0.03` or `charuco:7x5:0.04:0.03[:DICT_5X5_100]` -> BoardSpec; OmninavError with
    the expected format and an example on any mistake."""
    if not isinstance(spec, str) or len(spec) > 200:
        raise OmninavError(f"board spec must be a short text; {BOARD_FORMAT}")
    parts = spec.strip().split(":")
    kind = parts[0].strip().lower()
    if kind in ("chess", "chessboard", "checkerboard"):
        if len(parts) != 3:
            raise _bad(spec, "a chessboard takes 3 fields (chess, inner corners, square size)")
        cols, rows = _counts(spec, parts[1], "inner corners", 3)
        if cols == rows:
            raise _bad(spec, f"a square chessboard ({cols}x{rows}) has no orientation, use e.g. 9x6")
        return BoardSpec("chess", cols, rows, _metres(spec, parts[2], "square size"))
    if kind == "charuco":
        if len(parts) not in (4, 5):
            raise _bad(spec, "a ChArUco board takes 4 or 5 fields (charuco, squares, square, marker[, dict])")
        cols, rows = _counts(spec, parts[1], "squares", 3)
        square = _metres(spec, parts[2], "square size")
        marker = _metres(spec, parts[3], "marker size")
        if marker >= square:
            raise _bad(spec, f"the marker ({marker:g} m) must be smaller than the square ({square:g} m)")
        dictionary = _dictionary(spec, parts[4]) if len(parts) == 5 else DEFAULT_DICT
        n_markers = cols * rows // 2
        size = _charuco_dict_size(dictionary)
        if n_markers > size:
            raise _bad(spec, f"{cols}x{rows} squares need {n_markers} markers, {dictionary} has {size}")
        return BoardSpec("charuco", cols, rows, square, marker, dictionary)
    raise _bad(spec, f"unknown board kind {parts[0]!r}")


def _charuco_dict_size(name: str) -> int:
    d = cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, name))
    return int(d.bytesList.shape[0])


def board_image(spec: BoardSpec, px_per_square: int = 100, margin_squares: float = 1.0) -> tuple[np.ndarray, float]:
    """(H, W) uint8 printable picture of the board on white paper, and the pixel (x = y) where
    board coordinate 0 lies (pixel-centre convention: board point (u, v) metres sits at pixel
    `offset + (u, v) * px_per_square / square_m`)."""
    sx, sy = spec.squares
    m = int(round(margin_squares * px_per_square))
    w, h = sx * px_per_square + 2 * m, sy * px_per_square + 2 * m
    if spec.kind == "charuco":
        img = spec.charuco_board().generateImage((w, h), marginSize=m, borderBits=1)
        return np.asarray(img, np.uint8), m - 0.5
    img = np.full((h, w), 255, np.uint8)
    for j in range(sy):
        for i in range(sx):
            if (i + j) % 2 == 0:  # black top-left square, as OpenCV's pattern.png
                y0, x0 = m + j * px_per_square, m + i * px_per_square
                img[y0 : y0 + px_per_square, x0 : x0 + px_per_square] = 0
    return img, m + px_per_square - 0.5


# --- detection -------------------------------------------------------------------------------

MAX_SIDE = 8000  # px: a frame larger than this is no phone video frame (and would cost minutes)
UNWRAP_MAX_PX = 8_000_000  # pixels of one unwrapped view: bounds time and memory on huge rings
ROWS_PER_COLUMN = 0.22  # unwrapped rows per column over 360 deg: a ring spanning ~80 deg of
# elevation then looks about as wide as tall near its middle, like a panorama (the lens's real
# span is unknown before the fit; squares 1.5x off square still detect)
SEAM_OVERLAP_DEG = 90.0  # a chessboard view runs on past 360 deg, so a board across the seam is whole
CHARUCO_OVERSAMPLE = 1.5  # markers' cells are a few raw pixels: the detector reads them better upsampled
MAX_MOVE_PX = 1.5  # a raw-frame refinement that moves a corner further than this lost it
MIN_SQUARE_PX = 14.0  # a detector's crop is magnified until the board's squares are this large
SADDLE_MIN = 100.0  # Hessian determinant of an X-junction of ~25 grey levels at half resolution
SADDLE_OVER_NOISE = 3.0  # ... and this many times the 99th percentile of the view's (noise) response
MIN_FILL = 0.03  # a group's saddles x spacing^2 over its extent's area: a board's 0.06-0.8, an edge's chain ~0.02
MIN_SPACING_PX = 5.0  # saddles closer than this in a view are noise, not a board's corners
MAX_SADDLES = 1500  # saddles clustered per view (the strongest): bounds the O(n^2) grouping
MAX_CANDIDATES = 4  # saddle groups tried per view


class RingLike(Protocol):
    """What detection needs of `calib.ring.Ring`: the ring's centre and radii (raw pixels)."""

    @property
    def center(self) -> tuple[float, float]: ...
    @property
    def r_inner(self) -> float: ...
    @property
    def r_outer(self) -> float: ...


@dataclass(frozen=True)
class Detection:
    """A board's corners found in one frame.

    `ids[k]` is the row of `spec.object_points()` that `image_points[k]` sees. For ChArUco the ids
    come from the markers: exact. A chessboard has no markers, so its labels are fixed by
    convention, the same in every frame of a video:
    - handedness: labelled as the board looks through a mirror lens (the raw picture is the
      board's mirror image: `ccw` true with the ring's outer edge looking up, as most clip-ons and
      `synth.donut_lens`). Through a lens of the other sense every frame's labels are the board's
      mirror image (`flip_chess_ids` turns them round); a fit with a free f(rho) sign absorbs it.
    - 180 degrees: settled by the colours when COLS + ROWS is odd (e.g. 9x6, black top-left
      square as OpenCV's pattern). When it is even (e.g. 8x6) a board turned by 180 degrees looks
      the same: labels may be reversed (id -> N - 1 - id) in some frames; the fit tries both.
    """

    frame: int
    image_points: np.ndarray  # (n, 2) float64 raw-image pixels (cornerSubPix-refined, see _raw_check)
    object_points: np.ndarray  # (n, 3) float64, the same order
    ids: np.ndarray  # (n,) int64: corner index in spec.object_points()
    whole: bool  # every corner of the board was found


def flip_chess_ids(spec: BoardSpec, ids: np.ndarray) -> np.ndarray:
    """A chessboard's labels mirrored, the other handedness (see Detection): rows reversed when
    ROWS is even (the colours still agree), else columns."""
    c, r = spec.corner_grid
    i, j = ids % c, ids // c
    if r % 2 == 0:
        j = r - 1 - j
    else:
        i = c - 1 - i
    out: np.ndarray = (j * c + i).astype(np.int64)
    return out


@dataclass(frozen=True)
class _View:
    """An unwrapped view of the ring: column j looks at image angle th0 + sense * j * dth, row i
    at radius r_outer - i * dr (the outer edge on top, as a panorama)."""

    cx: float
    cy: float
    r_outer: float
    th0: float
    dth: float
    sense: int
    dr: float
    width: int
    height: int

    def to_raw(self, pts: np.ndarray) -> np.ndarray:
        """(n, 2) view pixels -> (n, 2) raw-image pixels. The same formula as the remap tables,
        evaluated at the fractional position (exact, where reading the tables back would be
        bilinear)."""
        th = self.th0 + self.sense * pts[:, 0] * self.dth
        r = self.r_outer - pts[:, 1] * self.dr
        return np.stack([self.cx + r * np.cos(th), self.cy + r * np.sin(th)], -1)

    def render(self, grey: np.ndarray) -> np.ndarray:
        j = np.arange(self.width, dtype=np.float64)
        i = np.arange(self.height, dtype=np.float64)
        th = self.th0 + self.sense * j * self.dth
        r = self.r_outer - i * self.dr
        mx = (self.cx + r[:, None] * np.cos(th)[None, :]).astype(np.float32)
        my = (self.cy + r[:, None] * np.sin(th)[None, :]).astype(np.float32)
        out: np.ndarray = cv2.remap(grey, mx, my, cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT, borderValue=0)
        return out


def _view(ring: RingLike, sense: int, th0: float = 0.0, span_deg: float = 360.0, over: float = 1.0) -> _View:
    """The unwrapped view at about `over` times the raw image's resolution on the outer edge
    (more on small rings, so squares there reach ~12 px; less on huge ones, within
    UNWRAP_MAX_PX)."""
    cx, cy = (float(c) for c in ring.center)
    ri, ro = float(ring.r_inner), float(ring.r_outer)
    full = 2 * math.pi * ro * over * min(max(2400.0 / (2 * math.pi * ro), 1.0), 2.0)
    rows = full * ROWS_PER_COLUMN
    shrink = min(1.0, math.sqrt(UNWRAP_MAX_PX / (full * rows * span_deg / 360.0)))
    full, rows = full * shrink, max(rows * shrink, 16.0)
    width = int(math.ceil(full * span_deg / 360.0))
    height = int(math.ceil(rows))
    return _View(cx, cy, ro, th0, 2 * math.pi / full, sense, (ro - ri) / (height - 1), width, height)


def _grey(frame: np.ndarray) -> np.ndarray:
    """A frame as (H, W) uint8 grey; one-line errors for what is no picture or far too large."""
    if not isinstance(frame, np.ndarray) or frame.ndim not in (2, 3) or frame.size == 0:
        raise OmninavError("board detection needs an image: (H, W) grey or (H, W, 3) BGR pixels")
    h, w = frame.shape[:2]
    if max(h, w) > MAX_SIDE:
        raise OmninavError(f"frame {w}x{h} is larger than {MAX_SIDE} px a side: scale the video down first")
    if min(h, w) < 32:
        raise OmninavError(f"frame {w}x{h} is too small to hold a calibration board: use the camera's video")
    img = frame
    if img.dtype != np.uint8:
        if not np.issubdtype(img.dtype, np.number):
            raise OmninavError(f"frame pixels must be numbers, got {img.dtype}")
        img = np.clip(np.nan_to_num(img.astype(np.float64)), 0, 255).astype(np.uint8)
    if img.ndim == 3:
        if img.shape[2] == 1:
            img = img[:, :, 0]
        elif img.shape[2] in (3, 4):
            img = cv2.cvtColor(img, cv2.COLOR_BGR2GRAY if img.shape[2] == 3 else cv2.COLOR_BGRA2GRAY)
        else:
            raise OmninavError(f"frame has {img.shape[2]} channels: expected grey, BGR or BGRA")
    return np.ascontiguousarray(img)


def _check_ring(ring: RingLike, size: tuple[int, int]) -> None:
    cx, cy = ring.center
    ri, ro = ring.r_inner, ring.r_outer
    w, h = size
    vals = (cx, cy, ri, ro)
    if not all(math.isfinite(float(v)) for v in vals) or not 0 <= ri < ro or ro - ri < 8:
        raise OmninavError(f"ring {vals} is no usable ring: run `omninav calib ring` on the video first")
    if not (-ro < cx < w + ro and -ro < cy < h + ro) or ro > 2 * max(w, h):
        raise OmninavError(f"ring centre {cx:.0f}, {cy:.0f} radius {ro:.0f} does not fit a {w}x{h} frame")


def _sample(img: np.ndarray, pts: np.ndarray) -> np.ndarray:
    """Bilinear grey values at (..., 2) float positions (0 outside the image)."""
    flat = pts.reshape(-1, 2).astype(np.float32)
    n = len(flat)
    pad = (-n) % 1024  # remap wants maps under 32767 wide: fold them into rows
    mx = np.concatenate([flat[:, 0], np.zeros(pad, np.float32)]).reshape(-1, 1024)
    my = np.concatenate([flat[:, 1], np.zeros(pad, np.float32)]).reshape(-1, 1024)
    s = cv2.remap(img, mx, my, cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT, borderValue=0)
    out: np.ndarray = s.ravel()[:n].astype(np.float64).reshape(pts.shape[:-1])
    return out


_FRAC = np.array([0.3, 0.5, 0.7])


def _quadrants(img: np.ndarray, q: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(n, 4) mean grey of the four squares around corners q (n, 2) with grid steps a, b (n, 2),
    in cyclic order (+a+b, +a-b, -a-b, -a+b): a chessboard corner alternates dark and light."""
    fa, fb = np.meshgrid(_FRAC, _FRAC)
    out = []
    for sa, sb in ((1, 1), (1, -1), (-1, -1), (-1, 1)):
        p = (
            q[:, None, :]
            + sa * fa.ravel()[None, :, None] * a[:, None, :]
            + sb * fb.ravel()[None, :, None] * b[:, None, :]
        )
        out.append(_sample(img, p).mean(1))
    return np.stack(out, 1)


def _saddle_score(quads: np.ndarray) -> np.ndarray:
    """(n,) how much the four squares alternate: the smallest step between cyclic neighbours."""
    out: np.ndarray = np.min(np.abs(quads - np.roll(quads, 1, axis=1)), axis=1)
    return out


def _steps(grid: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A smooth model of a (R, C, 2) grid (cubic in the corner indices, refitted without corners
    off it): (fitted grid, step along columns a, step along rows b), each (R, C, 2). One corner
    a detector put on the paper's edge bends neither the model nor its neighbours' steps."""
    rows, cols = grid.shape[:2]
    jj, ii = np.mgrid[0:rows, 0:cols]
    u, v = (ii.ravel() - (cols - 1) / 2) / max(cols - 1, 1), (jj.ravel() - (rows - 1) / 2) / max(rows - 1, 1)
    powers = [(p, q) for p in range(4) for q in range(4 - p)]
    basis = np.stack([u**p * v**q for p, q in powers], 1)
    du = np.stack([p * u ** max(p - 1, 0) * v**q for p, q in powers], 1) / max(cols - 1, 1)
    dv = np.stack([q * u**p * v ** max(q - 1, 0) for p, q in powers], 1) / max(rows - 1, 1)
    xy = grid.reshape(-1, 2)
    use = np.ones(len(xy), bool)
    for _ in range(3):
        coef = np.linalg.lstsq(basis[use], xy[use], rcond=None)[0]
        res = np.hypot(*(basis @ coef - xy).T)
        use = res <= max(3.0 * float(np.median(res)), 0.5)
    return (basis @ coef).reshape(grid.shape), (du @ coef).reshape(grid.shape), (dv @ coef).reshape(grid.shape)


def _board_size_check(img: np.ndarray, grid: np.ndarray) -> str:
    """Is the detected (R, C, 2) grid the whole board? One step beyond each side must be the
    paper's plain margin, not more corners. "ok"; "bigger": part of a larger board (a spec that
    does not match the print) or no chessboard contrast; "seam": it runs out of the view's left or
    right end (look again in a view turned by 180 degrees); "edge": out of the ring, so its size
    cannot be checked. Every corner found must itself alternate dark and light like its
    neighbours: a detector asked for one more column than printed puts it on the paper's edge."""
    model, a, b = _steps(grid)
    inner = _quadrants(img, grid.reshape(-1, 2), a.reshape(-1, 2), b.reshape(-1, 2))
    scores = _saddle_score(inner)
    contrast = float(np.median(scores))
    step = float(np.median(np.minimum(np.hypot(*a.reshape(-1, 2).T), np.hypot(*b.reshape(-1, 2).T))))
    off = np.hypot(*(model - grid).reshape(-1, 2).T) > max(1.0, 0.15 * step)
    if contrast < 10 or int(((scores < 0.5 * contrast) | off).sum()) > 0:
        return "bigger"  # no chessboard, or "corners" on the paper's edge (a larger spec)
    h, w = img.shape
    for q, sa, sb in (
        (2 * grid[:, 0] - grid[:, 1], a[:, 0], b[:, 0]),
        (2 * grid[:, -1] - grid[:, -2], a[:, -1], b[:, -1]),
        (2 * grid[0] - grid[1], a[0], b[0]),
        (2 * grid[-1] - grid[-2], a[-1], b[-1]),
    ):
        reach = np.abs(sa) + np.abs(sb)
        if ((q[:, 0] - reach[:, 0] < 0) | (q[:, 0] + reach[:, 0] > w - 1)).mean() > 0.5:
            return "seam"
        inside = (q[:, 1] - reach[:, 1] >= 0) & (q[:, 1] + reach[:, 1] <= h - 1)
        inside &= (q[:, 0] - reach[:, 0] >= 0) & (q[:, 0] + reach[:, 0] <= w - 1)
        if inside.mean() < 0.5:
            return "edge"
        score = _saddle_score(_quadrants(img, q[inside], sa[inside], sb[inside]))
        if float(np.median(score)) > 0.5 * contrast:
            return "bigger"
    return "ok"


def _saddles(img: np.ndarray) -> np.ndarray:
    """(n, 2) X-junction candidates of a view: strong negative Hessian determinant (a saddle of
    the grey surface) at half resolution, local maxima only, the ring's edge rows left out."""
    small = cv2.GaussianBlur(cv2.pyrDown(img).astype(np.float32), (0, 0), 1.0)
    ixx = cv2.Sobel(small, cv2.CV_32F, 2, 0, ksize=3)
    iyy = cv2.Sobel(small, cv2.CV_32F, 0, 2, ksize=3)
    ixy = cv2.Sobel(small, cv2.CV_32F, 1, 1, ksize=3)
    resp = ixy * ixy - ixx * iyy
    resp[:4] = 0
    resp[-4:] = 0
    # above the sensor noise's own saddles (most of a view is plain): a board's are far stronger
    floor = max(SADDLE_MIN, SADDLE_OVER_NOISE * float(np.percentile(resp[::4, ::4], 99)))
    peak = (resp == cv2.dilate(resp, np.ones((5, 5), np.uint8))) & (resp > floor)
    ys, xs = np.nonzero(peak)
    if len(xs) > MAX_SADDLES:  # the strongest: a board's corners are among the strongest saddles
        keep = np.argsort(resp[ys, xs])[-MAX_SADDLES:]
        ys, xs = ys[keep], xs[keep]
    return np.stack([xs, ys], -1).astype(np.float64) * 2.0


def _clusters(pts: np.ndarray, least: int) -> list[tuple[np.ndarray, float]]:
    """Groups of saddles spaced like a board's corners: each linked to the others within 1.6x its
    nearest-neighbour distance; (members (m, 2), median spacing) of groups of `least` or more
    that fill their area like a grid (not a chain along an edge), largest first."""
    n = len(pts)
    if n < least:
        return []
    d = np.hypot(pts[:, None, 0] - pts[None, :, 0], pts[:, None, 1] - pts[None, :, 1]).astype(np.float32)
    np.fill_diagonal(d, np.inf)
    nn = d.min(1)
    link = d <= 1.6 * np.maximum(nn[:, None], nn[None, :])
    label = np.full(n, -1)
    groups = []
    for start in range(n):
        if label[start] >= 0:
            continue
        label[start] = start
        stack, members = [start], [start]
        while stack:
            i = stack.pop()
            for j in np.flatnonzero(link[i] & (label < 0)):
                label[j] = start
                stack.append(int(j))
                members.append(int(j))
        if len(members) < least:
            continue
        m = pts[members]
        spacing = float(np.median(nn[members]))
        axes = np.linalg.eigh(np.cov((m - m.mean(0)).T))[1]
        extent = np.ptp((m - m.mean(0)) @ axes, axis=0)
        fill = len(m) * spacing**2 / max(float(extent[0] * extent[1]), 1.0)
        if spacing >= MIN_SPACING_PX and fill >= MIN_FILL:
            groups.append((m, spacing))
    groups.sort(key=lambda g: -len(g[0]))
    return groups


def _chess_in(crop: np.ndarray, zoom: float, pattern: tuple[int, int], sector: bool) -> Iterator[np.ndarray]:
    """(n, 2) corners of a `pattern` chessboard in a crop, in the crop's pixels: OpenCV's
    classic detector on the crop magnified by `zoom` first (measured: it finds these boards in
    the unwrapped views, 30x faster than the sector-based one), then the sector-based one on
    the crop as it is (it wants no magnification and costs 4x more with it), if `sector`: it
    takes ~0.3 s to give up, so only the likeliest group gets it."""
    big = cv2.resize(crop, None, fx=zoom, fy=zoom, interpolation=cv2.INTER_CUBIC) if zoom > 1 else crop
    ok, c = cv2.findChessboardCorners(big, pattern, flags=cv2.CALIB_CB_ADAPTIVE_THRESH | cv2.CALIB_CB_NORMALIZE_IMAGE)
    if ok and c is not None:
        # pixel centres: x_crop = (x_zoomed + 0.5) / zoom - 0.5
        yield (np.asarray(c, np.float64).reshape(-1, 2) + 0.5) / zoom - 0.5
    if not sector:
        return
    ok, c = cv2.findChessboardCornersSB(crop, pattern, flags=cv2.CALIB_CB_NORMALIZE_IMAGE)
    if ok and c is not None:
        yield np.asarray(c, np.float64).reshape(-1, 2)


def _find_chess(img: np.ndarray, spec: BoardSpec) -> Iterator[np.ndarray]:
    """(R, C, 2) chessboard grids (OpenCV's order) in one unwrapped view, refined there, best
    guesses first: the detectors run on crops around groups of saddles, each magnified so that
    its squares are at least ~12 px."""
    pattern = spec.corner_grid
    h, w = img.shape
    crit = (cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_MAX_ITER, 40, 0.01)
    groups = _clusters(_saddles(img), max(4, int(0.6 * spec.n_corners)))
    for k, (members, spacing) in enumerate(groups[:MAX_CANDIDATES]):
        pad = 2.5 * spacing + 8
        x0, y0 = (int(max(v, 0)) for v in members.min(0) - pad)
        x1, y1 = int(min(members[:, 0].max() + pad, w)), int(min(members[:, 1].max() + pad, h))
        zoom = float(np.clip(MIN_SQUARE_PX / max(spacing, 1.0), 1.0, 4.0))
        for c in _chess_in(img[y0:y1, x0:x1], zoom, pattern, sector=k == 0):
            grid = (c + np.array([x0, y0])).reshape(pattern[1], pattern[0], 2)
            _, a, b = _steps(grid)
            step = float(np.median(np.minimum(np.hypot(*a.reshape(-1, 2).T), np.hypot(*b.reshape(-1, 2).T))))
            half = int(np.clip(round(0.4 * step), 2, 15))
            pts = cv2.cornerSubPix(img, grid.reshape(-1, 1, 2).astype(np.float32), (half, half), (-1, -1), crit)
            yield np.asarray(pts, np.float64).reshape(grid.shape)


def _handedness(grid: np.ndarray) -> float:
    """Sign of the picture's orientation: > 0 when the labels run as the printed board seen
    directly (columns to the right, rows down), < 0 for its mirror image."""
    a = grid[:-1, 1:] - grid[:-1, :-1]
    b = grid[1:, :-1] - grid[:-1, :-1]
    return float(np.sign(np.nanmean(a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0])))


def _expected_dark(ids: np.ndarray, cols: int) -> np.ndarray:
    """(R-1, C-1) True where a grid cell should be black under labels `ids` (R, C): the cell whose
    corners are board corners (i0..i0+1, j0..j0+1) is square (i0 + 1, j0 + 1) of the print, black
    when i0 + j0 is even (OpenCV's pattern: black top-left square)."""
    quad = np.stack([ids[:-1, :-1], ids[:-1, 1:], ids[1:, :-1], ids[1:, 1:]])
    i0, j0 = (quad % cols).min(0), (quad // cols).min(0)
    out: np.ndarray = (i0 + j0) % 2 == 0
    return out


def _label_chess(view_grid: np.ndarray, raw_grid: np.ndarray, img: np.ndarray) -> np.ndarray:
    """(R, C) ids for a detected grid: the handedness of a mirror lens's picture, then the
    colours choose between the two 180-degree turns (see Detection); where they cannot (COLS +
    ROWS even), OpenCV's order is kept."""
    rows, cols = raw_grid.shape[:2]
    ids = np.arange(rows * cols).reshape(rows, cols)
    if _handedness(raw_grid) > 0:
        ids = ids[:, ::-1]  # a mirror lens shows the board mirrored (handedness < 0): label so
    if (rows + cols) % 2 == 1:
        centres = 0.25 * (view_grid[:-1, :-1] + view_grid[:-1, 1:] + view_grid[1:, :-1] + view_grid[1:, 1:])
        g = _sample(img, centres)
        g -= g.mean()
        turned = ids[::-1, ::-1]
        agree = float(np.sum(np.where(_expected_dark(ids, cols), -g, g)))
        agree_turned = float(np.sum(np.where(_expected_dark(turned, cols), -g, g)))
        if agree_turned > agree:
            ids = turned
    return ids


def _raw_check(grey: np.ndarray, pts: np.ndarray, half: np.ndarray, ring: RingLike) -> np.ndarray:
    """(n,) bool: which corners (n, 2) hold in the raw frame. Each is refined there with
    cornerSubPix (half-window `half` (n,) px, scaled to its local square size); one that moves
    further than MAX_MOVE_PX, or lies off the ring, was no corner (a marker's edge, a cut
    square). The refined positions are not kept: measured on rendered boards, the corner refined
    in the oversampled unwrapped view and mapped back exactly is twice as close to the truth
    (median 0.02-0.03 px against 0.04-0.06 px: lines curve less there, and a ChArUco corner's
    window there keeps clear of the markers)."""
    out = pts.copy()
    crit = (cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_MAX_ITER, 40, 0.01)
    h, w = grey.shape
    inside = (
        (pts[:, 0] >= half + 1) & (pts[:, 0] <= w - half - 2) & (pts[:, 1] >= half + 1) & (pts[:, 1] <= h - half - 2)
    )
    for hw in np.unique(half):
        m = (half == hw) & inside
        if m.any():
            p = cv2.cornerSubPix(grey, pts[m].reshape(-1, 1, 2).astype(np.float32), (int(hw), int(hw)), (-1, -1), crit)
            out[m] = np.asarray(p, np.float64).reshape(-1, 2)
    r = np.hypot(pts[:, 0] - ring.center[0], pts[:, 1] - ring.center[1])
    kept: np.ndarray = inside & (np.hypot(*(out - pts).T) <= MAX_MOVE_PX) & (r >= ring.r_inner) & (r <= ring.r_outer)
    return kept


def _grid_spacing(grid: np.ndarray) -> np.ndarray:
    """(R, C) distance to the nearest grid neighbour of every corner (px)."""
    d = np.full(grid.shape[:2], np.inf)
    dx = np.hypot(*(grid[:, 1:] - grid[:, :-1]).transpose(2, 0, 1))
    dy = np.hypot(*(grid[1:] - grid[:-1]).transpose(2, 0, 1))
    d[:, 1:] = np.minimum(d[:, 1:], dx)
    d[:, :-1] = np.minimum(d[:, :-1], dx)
    d[1:] = np.minimum(d[1:], dy)
    d[:-1] = np.minimum(d[:-1], dy)
    return d


def _detect_chess(grey: np.ndarray, spec: BoardSpec, ring: RingLike, index: int) -> Detection | None:
    grid = None
    for th0 in (0.0, math.pi):  # the second view only for a board found across the first's end
        view = _view(ring, -1, th0, 360.0 + SEAM_OVERLAP_DEG)
        img = view.render(grey)
        seam = False
        for g in _find_chess(img, spec):
            check = _board_size_check(img, g)
            seam |= check == "seam"
            if check == "ok":
                grid = g
                break
        if grid is not None or not seam:
            break
    if grid is None:
        return None
    rows, cols = grid.shape[:2]
    raw = view.to_raw(grid.reshape(-1, 2)).reshape(rows, cols, 2)
    ids = _label_chess(grid, raw, img).ravel()
    pts = raw.reshape(-1, 2)
    half = np.clip(np.round(0.3 * _grid_spacing(raw).ravel()), 2, 15).astype(np.int64)
    kept = _raw_check(grey, pts, half, ring)
    if kept.sum() < 4:
        return None
    obj = spec.object_points()
    order = np.argsort(ids[kept])
    sel_ids = ids[kept][order].astype(np.int64)
    return Detection(index, pts[kept][order], obj[sel_ids], sel_ids, bool(kept.all()))


def _charuco_detector(spec: BoardSpec) -> cv2.aruco.CharucoDetector:
    params = cv2.aruco.DetectorParameters()
    params.cornerRefinementMethod = cv2.aruco.CORNER_REFINE_NONE  # corners are refined in the raw frame
    # the defaults are relative to the picture's larger side: an unwrapped ring is 2000-4000 px
    # wide, where a marker of 20 px is normal, not noise
    params.minMarkerPerimeterRate = 0.004
    params.adaptiveThreshWinSizeMin = 5
    params.adaptiveThreshWinSizeMax = 35
    params.adaptiveThreshWinSizeStep = 6
    params.perspectiveRemovePixelPerCell = 8
    cp = cv2.aruco.CharucoParameters()
    cp.minMarkers = 2  # a corner needs both its neighbouring markers: no guessing from one
    cp.tryRefineMarkers = True  # the board's layout finds the markers missed: twice the corners at 960x720
    return cv2.aruco.CharucoDetector(spec.charuco_board(), cp, params)


def _charuco_in(
    view: _View, grey: np.ndarray, det: cv2.aruco.CharucoDetector
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(corners (n, 2) view px, ids (n,), marker corners (m, 2) view px) in one unwrapped view."""
    img = view.render(grey)
    cc, ci, mc, mi = det.detectBoard(img)
    marks = np.concatenate([np.asarray(m, np.float64).reshape(-1, 2) for m in mc]) if mc else np.zeros((0, 2))
    if ci is None or cc is None or len(ci) == 0:
        return np.zeros((0, 2)), np.zeros(0, np.int64), marks
    return np.asarray(cc, np.float64).reshape(-1, 2), np.asarray(ci, np.int64).ravel(), marks


def _detect_charuco(grey: np.ndarray, spec: BoardSpec, ring: RingLike, index: int) -> Detection | None:
    det = _charuco_detector(spec)
    best: tuple[_View, np.ndarray, np.ndarray] | None = None
    for sense in (-1, 1):  # the donut may show the board mirrored: markers read only one way round
        view = _view(ring, sense, over=CHARUCO_OVERSAMPLE)
        cc, ci, marks = _charuco_in(view, grey, det)
        near_seam = len(marks) > 0 and bool(
            ((marks[:, 0] < 0.03 * view.width) | (marks[:, 0] > 0.97 * view.width)).any()
        )
        if near_seam:  # a board across the seam: look again with the seam on the other side
            turned = dataclasses.replace(view, th0=math.pi)
            cc2, ci2, _ = _charuco_in(turned, grey, det)
            if len(ci2) > len(ci):
                view, cc, ci = turned, cc2, ci2
        if len(ci) and (best is None or len(ci) > len(best[2])):
            best = (view, cc, ci)
        if len(ci) >= 4:
            break  # the board read in this sense: the other is its mirror image
    if best is None:
        return None
    view, cc, ci = best
    raw = view.to_raw(cc)
    obj = spec.object_points()
    # local square size in the raw frame: the nearest other detected corner, in board squares
    d = np.hypot(*(raw[:, None] - raw[None]).transpose(2, 0, 1))
    o = np.hypot(*(obj[ci][:, None, :2] - obj[ci][None, :, :2]).transpose(2, 0, 1)) / spec.square_m
    np.fill_diagonal(d, np.inf)
    spacing = np.min(np.where(o > 0, d / np.maximum(o, 1e-9), np.inf), axis=1)
    spacing = np.where(np.isfinite(spacing), spacing, 8.0)
    # the window stays inside the white gap between the corner and the markers
    gap = 0.5 * (1.0 - (spec.marker_m or 0.0) / spec.square_m)
    half = np.clip(np.round(gap * spacing), 2, 15).astype(np.int64)
    kept = _raw_check(grey, raw, half, ring)
    pts = raw
    if kept.sum() < 4:
        return None
    order = np.argsort(ci[kept])
    ids = ci[kept][order]
    return Detection(index, pts[kept][order], obj[ids], ids, bool(kept.sum() == spec.n_corners))


def detect_board(frame: np.ndarray, spec: BoardSpec, ring: RingLike, index: int = 0) -> Detection | None:
    """The board's corners in one donut frame (H, W[, 3]) uint8, or None where there is none.

    Works in unwrapped views of the ring (rows linear in radius between `ring.r_inner` and
    `ring.r_outer`, columns the image angle; both mirror senses for ChArUco, whose markers read
    only one way round; a view rotated by 180 degrees or run on past 360 for a board across the
    seam), so it needs no elevation polynomial. Corners are mapped back to the raw frame and
    refined there with cornerSubPix. A chessboard must be seen whole and exactly the spec's size
    (a larger board's part is refused); a ChArUco board may be partial.
    """
    grey = _grey(frame)
    _check_ring(ring, (grey.shape[1], grey.shape[0]))
    if spec.kind == "charuco":
        return _detect_charuco(grey, spec, ring, index)
    return _detect_chess(grey, spec, ring, index)
