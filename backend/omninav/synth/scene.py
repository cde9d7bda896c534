"""Synthetic venue geometry and textures: corridors with doors, boards, windows, pillars, tiles, lights.

The free space is a union of axis-aligned corridor rectangles on a 0.1 m grid; walls are the
boundary runs of that grid, merged into segments, each with a strip of a texture atlas painted with
OpenCV. Floor and ceiling are plan-aligned images. Everything is deterministic by seed.
Institutional and repetitive on purpose: doors of two colours at regular spacing, as real
corridors have, with the occasional board, window or pillar that makes a place unique.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import cv2
import numpy as np

GRID = 0.1  # m per free-space cell
TEX_PPM = 40  # texture pixels per metre on walls
PLAN_PPM = 20  # floor/ceiling texture pixels per metre
WALL_H = 2.8  # m, ceiling height

Point = tuple[float, float]  # plan metres
Rect = tuple[float, float, float, float]  # x0, y0, x1, y1 (plan metres)
Layout = tuple[Point, list[Rect], list[list[Point]]]  # plan size, corridor rectangles, centre lines


@dataclass
class Scene:
    size_m: tuple[float, float]  # plan width, height (m)
    free: np.ndarray  # (rows, cols) bool grid, GRID m cells
    seg: np.ndarray  # (S, 4) float64 x0, y0, x1, y1 (m)
    seg_off: np.ndarray  # (S,) atlas column where each segment's texture starts
    atlas: np.ndarray  # (WALL_H*TEX_PPM, total, 3) uint8 RGB
    floor: np.ndarray  # (H, W, 3) uint8 RGB, PLAN_PPM
    ceiling: np.ndarray  # (H, W, 3) uint8 RGB, PLAN_PPM
    centerlines: list[list[tuple[float, float]]]  # corridor centre polylines
    places: list[dict[str, Any]] = field(default_factory=list)  # named places {name, x, y, area}
    corridor_width: float = 2.4
    # the layout's own (modelling, query) routes, where the default ones of walks.py do not fit
    routes: tuple[list[Point], list[Point]] | None = None


@dataclass
class Person:
    x: float
    y: float
    radius: float
    height: float
    shirt: tuple[int, int, int]
    trousers: tuple[int, int, int]


# --- layout ---------------------------------------------------------------------------------


def _ring(x0: float, y0: float, x1: float, y1: float, xm: float, w: float) -> tuple[list[Rect], list[list[Point]]]:
    """A rectangular ring of corridors w wide with a north-south cross corridor at x = xm:
    rectangles (north, south, west, east, middle) and their centre lines."""
    rects = [
        (x0 - w / 2, y0 - w / 2, x1 + w / 2, y0 + w / 2),  # north
        (x0 - w / 2, y1 - w / 2, x1 + w / 2, y1 + w / 2),  # south
        (x0 - w / 2, y0 - w / 2, x0 + w / 2, y1 + w / 2),  # west
        (x1 - w / 2, y0 - w / 2, x1 + w / 2, y1 + w / 2),  # east
        (xm - w / 2, y0 - w / 2, xm + w / 2, y1 + w / 2),  # middle
    ]
    lines = [
        [(x0, y0), (x1, y0)],
        [(x0, y1), (x1, y1)],
        [(x0, y0), (x0, y1)],
        [(x1, y0), (x1, y1)],
        [(xm, y0), (xm, y1)],
    ]
    return rects, lines


def default_layout() -> Layout:
    """A rectangular ring of corridors with a cross corridor: 48 x 20 m between centre lines."""
    x0, y0, x1, y1, xm = 3.0, 3.0, 51.0, 23.0, 27.0
    rects, lines = _ring(x0, y0, x1, y1, xm, 2.4)
    return (x1 + 3.0, y1 + 3.0), rects, lines


def small_layout() -> Layout:
    """An L of two corridors (18 m and 10 m): small enough for fast unit tests."""
    w = 2.4
    rects = [
        (2.0 - w / 2, 2.0 - w / 2, 20.0 + w / 2, 2.0 + w / 2),
        (20.0 - w / 2, 2.0 - w / 2, 20.0 + w / 2, 12.0 + w / 2),
    ]
    lines = [[(2.0, 2.0), (20.0, 2.0)], [(20.0, 2.0), (20.0, 12.0)]]
    return (23.0, 15.0), rects, lines


# The twin layout: a ring of corridors whose west and east sides are twins (the east side is the
# west side turned half round about the ring's centre: the same walls, doors, boards and floor),
# a unique middle corridor, and a dead-end stairwell off the north corridor that no route enters.
TWIN_RING = (3.0, 8.0, 27.0, 20.0)  # x0, y0, x1, y1 of the ring's centre lines
TWIN_MIDDLE_X = 15.0
TWIN_STAIRS = ((9.0, 8.0), (9.0, 2.0))
TWINS = (2, 3)  # rectangles: the original, and its copy turned half round


def twin_layout() -> Layout:
    """A 24 x 12 m ring whose west and east corridors are identical, a middle corridor and a
    6 m stairwell: the venue of the quality map's tests (a deliberately repeated stretch)."""
    w = 2.4
    x0, y0, x1, y1 = TWIN_RING
    xm = TWIN_MIDDLE_X
    (sx, sy0), (_, sy1) = TWIN_STAIRS
    rects, lines = _ring(x0, y0, x1, y1, xm, w)  # the east corridor: the west one turned half round
    rects.append((sx - w / 2, sy1 - w / 2, sx + w / 2, sy0 - w / 2))  # stairwell, ending at the north corridor
    lines.append([TWIN_STAIRS[0], TWIN_STAIRS[1]])
    return (x1 + 3.0, y1 + 3.0), rects, lines


def twin_routes() -> tuple[list[Point], list[Point]]:
    """Each corridor of the ring and the middle one walked once, the stairwell never: the
    modelling walk goes east along the north corridor, south along the east twin, west, north
    along the west twin and down the middle; the query walk is the same the other way round."""
    x0, y0, x1, y1 = TWIN_RING
    xm = TWIN_MIDDLE_X
    model = [(xm, y0), (x1, y0), (x1, y1), (xm, y1), (x0, y1), (x0, y0), (xm, y0), (xm, y1)]
    return model, model[::-1]


def _half_turn(x: float, y: float) -> Point:
    """The twin layout's symmetry: half a turn about the ring's centre."""
    x0, y0, x1, y1 = TWIN_RING
    return x0 + x1 - x, y0 + y1 - y


def _copy_twin(
    rects: list[Rect],
    segs: list[tuple[float, float, float, float]],
    offs: list[int],
    floor: np.ndarray,
) -> int:
    """Make the second twin show the first one's walls and floor: every wall segment of the copy
    takes the atlas strip of the segment it is the half turn of (a segment runs with free space on
    its left, which a turn keeps). Returns how many segments were shared."""
    a, b = rects[TWINS[0]], rects[TWINS[1]]
    src = {
        tuple(round(v, 3) for v in (*_half_turn(x0, y0), *_half_turn(x1, y1))): i
        for i, (x0, y0, x1, y1) in enumerate(segs)
    }
    shared = 0
    for i, (x0, y0, x1, y1) in enumerate(segs):
        mx, my = (x0 + x1) / 2, (y0 + y1) / 2
        if b[0] - 0.05 <= mx <= b[2] + 0.05 and b[1] - 0.05 <= my <= b[3] + 0.05:
            j = src.get(tuple(round(v, 3) for v in (x0, y0, x1, y1)))
            if j is not None and j != i:
                offs[i] = offs[j]
                shared += 1
    # the floor tiles too (the ceiling's lights are symmetric already)
    ra = [int(round(v * PLAN_PPM)) for v in a]
    rb = [int(round(v * PLAN_PPM)) for v in b]
    floor[rb[1] : rb[3], rb[0] : rb[2]] = floor[ra[1] : ra[3], ra[0] : ra[2]][::-1, ::-1]
    return shared


LAYOUTS = {"default": default_layout, "small": small_layout, "twin": twin_layout}
_RING = ["North corridor", "South corridor", "West corridor", "East corridor", "Middle corridor"]
NAMES = {"default": _RING, "twin": [*_RING, "Stairwell"]}  # of the layouts' corridors (else numbered)


def _grid(size_m: Point, rects: list[Rect]) -> np.ndarray:
    rows, cols = int(round(size_m[1] / GRID)), int(round(size_m[0] / GRID))
    free = np.zeros((rows, cols), bool)
    for ax, ay, bx, by in rects:
        free[int(round(ay / GRID)) : int(round(by / GRID)), int(round(ax / GRID)) : int(round(bx / GRID))] = True
    return free


def _pillars(free: np.ndarray, rng: np.random.Generator, every_m: float = 9.0) -> np.ndarray:
    """Pillars half-embedded in the walls: 0.4 m wide, 0.3 m deep, at irregular spacing."""
    pill = np.zeros_like(free)
    rows, cols = free.shape
    # Wall cells adjacent to free space along horizontal corridors (north-facing/south-facing).
    for r in range(1, rows - 1):
        run = free[r] & ~free[r - 1]  # free cell with a wall above: a wall runs along row r-1
        pos = 0.0
        for c in map(int, np.flatnonzero(run)):
            if c * GRID < pos:
                continue
            if rng.random() < 0.12 and run[c : c + 5].all():
                pill[r : r + 3, c : c + 4] = True
                pos = c * GRID + every_m * rng.uniform(0.6, 1.4)
    for c in range(1, cols - 1):
        run = free[:, c] & ~free[:, c - 1]
        pos = 0.0
        for r in map(int, np.flatnonzero(run)):
            if r * GRID < pos:
                continue
            if rng.random() < 0.12 and run[r : r + 5].all():
                pill[r : r + 4, c : c + 3] = True
                pos = r * GRID + every_m * rng.uniform(0.6, 1.4)
    out: np.ndarray = pill & free
    return out


def _segments(free: np.ndarray) -> list[tuple[float, float, float, float, int, int]]:
    """Boundary runs of the free grid as segments, oriented so the free side is on the left.

    Returns (x0, y0, x1, y1, normal_dir, cell_index) with the normal pointing into free space.
    """
    segs = []
    rows, cols = free.shape
    pad = np.pad(free, 1)
    # horizontal edges between row r-1 and r (in padded coordinates)
    for r in range(1, rows + 2):
        up, dn = pad[r - 1, 1:-1], pad[r, 1:-1]
        for kind, mask in (("down", dn & ~up), ("up", up & ~dn)):
            c = 0
            while c < cols:
                if mask[c]:
                    s = c
                    while c < cols and mask[c]:
                        c += 1
                    y = (r - 1) * GRID
                    if kind == "down":  # free below, wall above: normal +y
                        segs.append((c * GRID, y, s * GRID, y, 0, r - 1))
                    else:  # free above, wall below: normal -y
                        segs.append((s * GRID, y, c * GRID, y, 1, r - 1))
                else:
                    c += 1
    for c in range(1, cols + 2):
        lf, rt = pad[1:-1, c - 1], pad[1:-1, c]
        for kind, mask in (("right", rt & ~lf), ("left", lf & ~rt)):
            r = 0
            while r < rows:
                if mask[r]:
                    s = r
                    while r < rows and mask[r]:
                        r += 1
                    x = (c - 1) * GRID
                    if kind == "right":  # free to the right: normal +x
                        segs.append((x, s * GRID, x, r * GRID, 2, c - 1))
                    else:
                        segs.append((x, r * GRID, x, s * GRID, 3, c - 1))
                else:
                    r += 1
    return segs


# --- textures -------------------------------------------------------------------------------

DOOR_COLOURS = [(139, 90, 50), (58, 95, 138)]  # wood, blue-grey: the two door colours
WALL_COLOURS = [(226, 220, 200), (205, 222, 205), (222, 212, 222), (214, 222, 232)]


def _z(zm: float) -> int:
    """Texture row of height zm (row 0 is the ceiling)."""
    return int(round((WALL_H - zm) * TEX_PPM))


def _paint_wall(
    length: float,
    rng: np.random.Generator,
    base: tuple[int, int, int],
    door_phase: float,
    door_pattern: list[int],
    outer: bool,
    label: int,
) -> np.ndarray:
    w = max(1, int(round(length * TEX_PPM)))
    tex = np.empty((int(WALL_H * TEX_PPM), w, 3), np.uint8)
    tex[:] = base
    # Subtle plaster variation so that blank walls are not perfectly flat.
    tex[:] = np.clip(tex.astype(np.int16) + rng.normal(0, 3, (1, w, 1)).astype(np.int16), 0, 255)
    cv2.rectangle(tex, (0, _z(0.12)), (w - 1, _z(0.0)), (70, 70, 75), -1)  # skirting
    cv2.line(tex, (0, _z(0.9)), (w - 1, _z(0.9)), tuple(int(v * 0.85) for v in base), 2)  # rail

    def px(u: float) -> int:
        return int(round(u * TEX_PPM))

    spacing = 4.0
    u = door_phase
    k = 0
    while u + 1.1 < length - 0.3:
        if u > 0.3:
            if outer and k % 2 == 1:
                # a window between doors on outer walls
                x0, x1 = px(u - 0.2), px(u + 1.3)
                cv2.rectangle(tex, (x0, _z(2.2)), (x1, _z(0.95)), (235, 235, 235), -1)
                for j, zz in enumerate(np.linspace(2.15, 1.0, 12)):
                    sky = (150 + 6 * j, 190 + 4 * j, 235)
                    cv2.rectangle(tex, (x0 + 4, _z(zz)), (x1 - 4, _z(zz - 0.1)), sky, -1)
                cv2.line(tex, ((x0 + x1) // 2, _z(2.2)), ((x0 + x1) // 2, _z(0.95)), (235, 235, 235), 3)
            else:
                col = DOOR_COLOURS[door_pattern[k % len(door_pattern)]]
                x0, x1 = px(u), px(u + 0.95)
                cv2.rectangle(tex, (x0 - 3, _z(2.15)), (x1 + 3, _z(0.0)), (60, 60, 60), -1)
                cv2.rectangle(tex, (x0, _z(2.1)), (x1, _z(0.0)), col, -1)
                if rng.random() < 0.35:  # glazed door
                    cv2.rectangle(tex, (x0 + 8, _z(1.9)), (x0 + 16, _z(1.2)), (200, 220, 230), -1)
                hx = x1 - 6
                cv2.rectangle(tex, (hx - 4, _z(1.05)), (hx, _z(0.98)), (210, 210, 210), -1)
                # room plate with a number, beside the door
                cv2.rectangle(tex, (x1 + 6, _z(1.65)), (x1 + 26, _z(1.45)), (245, 245, 245), -1)
                cv2.putText(
                    tex, str(label + k), (x1 + 7, _z(1.5)), cv2.FONT_HERSHEY_PLAIN, 0.6, (20, 20, 20), 1, cv2.LINE_AA
                )
        k += 1
        u += spacing
    # boards and posters at irregular places: what makes a spot unique
    n_items = rng.poisson(length / 7.0)
    for _ in range(n_items):
        width = rng.uniform(0.5, 1.4)
        uc = rng.uniform(0.2, max(0.3, length - width - 0.2))
        z0, z1 = rng.uniform(0.95, 1.3), rng.uniform(1.6, 2.0)
        x0, x1 = px(uc), px(uc + width)
        kind = rng.integers(3)
        if kind == 0:  # cork notice board with papers
            cv2.rectangle(tex, (x0, _z(z1)), (x1, _z(z0)), (170, 130, 80), -1)
            for _ in range(rng.integers(3, 9)):
                a = rng.uniform(uc, uc + width - 0.2)
                b = rng.uniform(z0, z1 - 0.25)
                c = tuple(int(v) for v in rng.integers(120, 256, 3))
                cv2.rectangle(tex, (px(a), _z(b + 0.25)), (px(a + 0.18), _z(b)), c, -1)
        elif kind == 1:  # poster: bold colour blocks
            c1 = tuple(int(v) for v in rng.integers(0, 256, 3))
            c2 = tuple(int(v) for v in rng.integers(0, 256, 3))
            cv2.rectangle(tex, (x0, _z(z1)), (x1, _z(z0)), c1, -1)
            cv2.rectangle(tex, (x0 + 4, _z(z1 - 0.1)), ((x0 + x1) // 2, _z(z0 + 0.1)), c2, -1)
        else:  # fire extinguisher or sign: small, saturated
            c = (200, 30, 30) if rng.random() < 0.5 else (30, 140, 60)
            cv2.rectangle(tex, (x0, _z(1.2)), (x0 + 10, _z(0.5)), c, -1)
    return tex


def _floor_and_ceiling(
    free: np.ndarray, rng: np.random.Generator, lines: list[list[Point]]
) -> tuple[np.ndarray, np.ndarray]:
    h, w = free.shape
    fh, fw = int(h * GRID * PLAN_PPM), int(w * GRID * PLAN_PPM)
    tile = int(0.6 * PLAN_PPM)
    ny, nx = fh // tile + 1, fw // tile + 1
    shades = rng.integers(150, 185, (ny, nx)).astype(np.uint8)
    floor = np.repeat(np.repeat(shades, tile, 0), tile, 1)[:fh, :fw]
    floor = np.stack([floor, (floor * 0.97).astype(np.uint8), (floor * 0.92).astype(np.uint8)], -1)
    floor[::tile, :] = (110, 110, 110)
    floor[:, ::tile] = (110, 110, 110)
    ceiling = np.full((fh, fw, 3), 225, np.uint8)
    for line in lines:
        (ax, ay), (bx, by) = line
        n = int(np.hypot(bx - ax, by - ay) / 2.4) + 1
        for t in np.linspace(0, 1, n):
            cx, cy = ax + t * (bx - ax), ay + t * (by - ay)
            horiz = abs(bx - ax) > abs(by - ay)
            hw, hh = (0.6, 0.3) if horiz else (0.3, 0.6)
            cv2.rectangle(
                ceiling,
                (int((cx - hw) * PLAN_PPM), int((cy - hh) * PLAN_PPM)),
                (int((cx + hw) * PLAN_PPM), int((cy + hh) * PLAN_PPM)),
                (255, 255, 250),
                -1,
            )
    return floor, ceiling


def build_scene(seed: int = 0, layout: str = "default") -> Scene:
    """The synthetic venue for a seed: geometry, textures and named places."""
    rng = np.random.default_rng(seed)
    if layout not in LAYOUTS:
        raise ValueError(f"unknown layout {layout!r} (known: {', '.join(LAYOUTS)})")
    size, rects, lines = LAYOUTS[layout]()
    free = _grid(size, rects)
    pill = _pillars(free, rng)
    if layout == "twin":  # no pillar in either twin: the same walls, run for run
        pill &= ~_grid(size, [rects[i] for i in TWINS])
    free_final = free & ~pill
    raw = _segments(free_final)
    segs, offs, strips = [], [], []
    off = 0
    # wall colour per wing: by which quarter of the plan the segment lies in
    label = 100
    for x0, y0, x1, y1, nd, _cell in raw:
        length = float(np.hypot(x1 - x0, y1 - y0))
        mx, my = (x0 + x1) / 2, (y0 + y1) / 2
        wing = int(mx > size[0] / 2) + 2 * int(my > size[1] / 2)
        # a short segment next to a pillar cell is pillar face: concrete, undecorated
        cx = int(np.clip((mx + (0.05 if nd == 3 else -0.05 if nd == 2 else 0)) / GRID, 0, free.shape[1] - 1))
        cy = int(np.clip((my + (0.05 if nd == 1 else -0.05 if nd == 0 else 0)) / GRID, 0, free.shape[0] - 1))
        is_pillar = bool(pill[cy, cx]) or length < 0.45
        if is_pillar:
            tex = np.empty((int(WALL_H * TEX_PPM), max(1, int(round(length * TEX_PPM))), 3), np.uint8)
            tex[:] = (150, 150, 148)
            tex[:, :2] = (120, 120, 118)
        else:
            outer = my < 2.0 or my > size[1] - 2.0 or mx < 1.5 or mx > size[0] - 1.5
            pattern = [0, 1] if rng.random() < 0.6 else [0, 0, 1]
            tex = _paint_wall(
                length, rng, WALL_COLOURS[wing % len(WALL_COLOURS)], rng.uniform(0.4, 3.5), pattern, outer, label
            )
            label += 20
        segs.append((x0, y0, x1, y1))
        offs.append(off)
        strips.append(tex)
        off += tex.shape[1]
    atlas = np.concatenate(strips, axis=1)
    floor, ceiling = _floor_and_ceiling(free_final, rng, lines)
    routes = None
    if layout == "twin":
        _copy_twin(rects, segs, offs, floor)
        routes = twin_routes()
    places = []
    for i, line in enumerate(lines):
        (ax, ay), (bx, by) = line
        names = NAMES.get(layout)
        places.append(
            {
                "name": names[i] if names else f"Corridor {i + 1}",
                "x": (ax + bx) / 2,
                "y": (ay + by) / 2,
                "area": [round(float(v), 3) for v in rects[i]],  # the corridor's floor: x0, y0, x1, y1
            }
        )
    return Scene(
        size,
        free_final,
        np.array(segs, np.float64),
        np.array(offs, np.int64),
        atlas,
        floor,
        ceiling,
        lines,
        places,
        routes=routes,
    )


def floorplan_image(scene: Scene, px_per_m: float = 20.0) -> np.ndarray:
    """A plain floor plan (white free space, dark walls) as an RGB image, for the venue's plan."""
    h, w = int(scene.size_m[1] * px_per_m), int(scene.size_m[0] * px_per_m)
    img = np.full((h, w, 3), 60, np.uint8)
    free = cv2.resize(scene.free.astype(np.uint8) * 255, (w, h), interpolation=cv2.INTER_NEAREST)
    img[free > 0] = (250, 250, 250)
    return img


def _rgb(rng: np.random.Generator, lo: int, hi: int) -> tuple[int, int, int]:
    r, g, b = (int(v) for v in rng.integers(lo, hi, 3))
    return r, g, b


def random_people(
    scene: Scene, rng: np.random.Generator, near: tuple[float, float], n: int, radius_m: float = 5.0
) -> list[Person]:
    """Up to n passers-by in free space within radius_m of `near`."""
    out: list[Person] = []
    tries = 0
    while len(out) < n and tries < 200:
        tries += 1
        x = near[0] + rng.uniform(-radius_m, radius_m)
        y = near[1] + rng.uniform(-radius_m, radius_m)
        if np.hypot(x - near[0], y - near[1]) < 0.8:
            continue
        r, c = int(y / GRID), int(x / GRID)
        if not (0 <= r < scene.free.shape[0] and 0 <= c < scene.free.shape[1]) or not scene.free[r, c]:
            continue
        out.append(
            Person(
                x,
                y,
                0.22,
                float(rng.uniform(1.6, 1.9)),
                _rgb(rng, 0, 256),
                _rgb(rng, 20, 120),
            )
        )
    return out
