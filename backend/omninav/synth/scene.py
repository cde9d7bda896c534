"""Synthetic venue geometry and textures: corridors with doors, boards, windows, pillars, tiles, lights.

The free space is a union of axis-aligned corridor rectangles on a 0.1 m grid; walls are the
boundary runs of that grid, merged into segments, each with a strip of a texture atlas painted with
OpenCV. Floor and ceiling are plan-aligned images. Everything is deterministic by seed.
Institutional and repetitive on purpose: doors of two colours at regular spacing, as real
corridors have, with the occasional board, window or pillar that makes a place unique.

The venue families (synth/families.py) add layouts (layouts.py `PLANS`: junctions, a hall, long corridors,
a comb of side corridors, an atrium, an irregular loop), a `Decor` (materials, how busy the walls
are, glass, stairs, ceiling height and lights) and a `Lighting` baked into the textures (lamp
colours, dark stretches, daylight by the hour). Without them a venue is what it always was.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import cv2
import numpy as np

from .layouts import LAYOUTS, NAMES, PLANS, TWINS, Point, Rect, half_turn, twin_routes

GRID = 0.1  # m per free-space cell
TEX_PPM = 40  # texture pixels per metre on walls
PLAN_PPM = 20  # floor/ceiling texture pixels per metre
WALL_H = 2.8  # m, ceiling height


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
    wall_h: float = WALL_H  # m, floor to ceiling (a hall or an atrium is taller)


@dataclass
class Person:
    x: float
    y: float
    radius: float
    height: float
    shirt: tuple[int, int, int]
    trousers: tuple[int, int, int]


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
        tuple(round(v, 3) for v in (*half_turn(x0, y0), *half_turn(x1, y1))): i
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


def _inside(mx: float, my: float, rects: list[Rect]) -> bool:
    return any(x0 <= mx <= x1 and y0 <= my <= y1 for x0, y0, x1, y1 in rects)


def _grid(size_m: Point, rects: list[Rect]) -> np.ndarray:
    rows, cols = int(round(size_m[1] / GRID)), int(round(size_m[0] / GRID))
    free = np.zeros((rows, cols), bool)
    for ax, ay, bx, by in rects:
        free[int(round(ay / GRID)) : int(round(by / GRID)), int(round(ax / GRID)) : int(round(bx / GRID))] = True
    return free


def _pillars(free: np.ndarray, rng: np.random.Generator, every_m: float = 9.0, p: float = 0.12) -> np.ndarray:
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
            if rng.random() < p and run[c : c + 5].all():
                pill[r : r + 3, c : c + 4] = True
                pos = c * GRID + every_m * rng.uniform(0.6, 1.4)
    for c in range(1, cols - 1):
        run = free[:, c] & ~free[:, c - 1]
        pos = 0.0
        for r in map(int, np.flatnonzero(run)):
            if r * GRID < pos:
                continue
            if rng.random() < p and run[r : r + 5].all():
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


@dataclass(frozen=True)
class Decor:
    """What a building's walls, floor and ceiling are made of and how busy they are. The defaults
    are the original venue's (scene textures bit for bit as before); venue families vary them."""

    wall_colours: tuple[tuple[int, int, int], ...] = tuple(WALL_COLOURS)  # one per wing (plan quarter)
    door_colours: tuple[tuple[int, int, int], ...] = tuple(DOOR_COLOURS)
    alternate_p: float = 0.6  # share of walls whose doors alternate two colours (else 2 of 3 alike)
    door_spacing: float = 4.0  # m between door starts along a wall
    door_phase: tuple[float, float] = (0.4, 3.5)  # where a wall's first door starts (m, drawn)
    glazed_p: float = 0.35  # share of doors with a glass panel
    windows: bool = True  # a window between doors on outer walls
    board_every_m: float = 7.0  # mean wall length per board, poster or sign (Poisson)
    signs_every_m: float = 0.0  # extra: mean wall length per direction sign / exit sign (0: none)
    plaster: float = 3.0  # sigma of the walls' column-to-column shade variation
    pillar_p: float = 0.12  # chance a wall cell starts a pillar (then none for ~9 m)
    wall_h: float = WALL_H  # m, floor to ceiling
    tile_m: float = 0.6  # floor tile size
    floor_shades: tuple[int, int] = (150, 185)
    floor_tint: tuple[float, float, float] = (1.0, 0.97, 0.92)
    grout: bool = True  # dark lines between floor tiles (carpet: none)
    lights: str = "panels"  # ceiling lights: "panels" (fluorescent rows), "downlights", "strips"
    light_spacing: float = 2.4  # m between lights along a corridor


DEFAULT_DECOR = Decor()


def _z(zm: float, wall_h: float = WALL_H) -> int:
    """Texture row of height zm (row 0 is the ceiling)."""
    return int(round((wall_h - zm) * TEX_PPM))


def _paint_wall(
    length: float,
    rng: np.random.Generator,
    base: tuple[int, int, int],
    door_phase: float,
    door_pattern: list[int],
    outer: bool,
    label: int,
    decor: Decor = DEFAULT_DECOR,
    glass: np.ndarray | None = None,
) -> np.ndarray:
    """One wall's texture strip. `glass` (rows, w) bool, when given, is set where the strip shows
    the outside (windows), which a daylight `Lighting` repaints by the hour."""
    wall_h = decor.wall_h

    def z(zm: float) -> int:
        return _z(zm, wall_h)

    w = max(1, int(round(length * TEX_PPM)))
    tex = np.empty((int(wall_h * TEX_PPM), w, 3), np.uint8)
    tex[:] = base
    # Subtle plaster variation so that blank walls are not perfectly flat.
    tex[:] = np.clip(tex.astype(np.int16) + rng.normal(0, decor.plaster, (1, w, 1)).astype(np.int16), 0, 255)
    cv2.rectangle(tex, (0, z(0.12)), (w - 1, z(0.0)), (70, 70, 75), -1)  # skirting
    cv2.line(tex, (0, z(0.9)), (w - 1, z(0.9)), tuple(int(v * 0.85) for v in base), 2)  # rail

    def px(u: float) -> int:
        return int(round(u * TEX_PPM))

    spacing = decor.door_spacing
    u = door_phase
    k = 0
    while u + 1.1 < length - 0.3:
        if u > 0.3:
            if outer and k % 2 == 1 and decor.windows:
                # a window between doors on outer walls
                x0, x1 = px(u - 0.2), px(u + 1.3)
                cv2.rectangle(tex, (x0, z(2.2)), (x1, z(0.95)), (235, 235, 235), -1)
                for j, zz in enumerate(np.linspace(2.15, 1.0, 12)):
                    sky = (150 + 6 * j, 190 + 4 * j, 235)
                    cv2.rectangle(tex, (x0 + 4, z(zz)), (x1 - 4, z(zz - 0.1)), sky, -1)
                cv2.line(tex, ((x0 + x1) // 2, z(2.2)), ((x0 + x1) // 2, z(0.95)), (235, 235, 235), 3)
                if glass is not None:
                    glass[z(2.15) : z(1.0) + 1, x0 + 4 : x1 - 3] = True
                    glass[:, (x0 + x1) // 2 - 1 : (x0 + x1) // 2 + 2] = False
            else:
                col = decor.door_colours[door_pattern[k % len(door_pattern)] % len(decor.door_colours)]
                x0, x1 = px(u), px(u + 0.95)
                cv2.rectangle(tex, (x0 - 3, z(2.15)), (x1 + 3, z(0.0)), (60, 60, 60), -1)
                cv2.rectangle(tex, (x0, z(2.1)), (x1, z(0.0)), col, -1)
                if rng.random() < decor.glazed_p:  # glazed door
                    cv2.rectangle(tex, (x0 + 8, z(1.9)), (x0 + 16, z(1.2)), (200, 220, 230), -1)
                hx = x1 - 6
                cv2.rectangle(tex, (hx - 4, z(1.05)), (hx, z(0.98)), (210, 210, 210), -1)
                # room plate with a number, beside the door
                cv2.rectangle(tex, (x1 + 6, z(1.65)), (x1 + 26, z(1.45)), (245, 245, 245), -1)
                cv2.putText(
                    tex, str(label + k), (x1 + 7, z(1.5)), cv2.FONT_HERSHEY_PLAIN, 0.6, (20, 20, 20), 1, cv2.LINE_AA
                )
        k += 1
        u += spacing
    # boards and posters at irregular places: what makes a spot unique
    n_items = rng.poisson(length / decor.board_every_m)
    for _ in range(n_items):
        width = rng.uniform(0.5, 1.4)
        uc = rng.uniform(0.2, max(0.3, length - width - 0.2))
        z0, z1 = rng.uniform(0.95, 1.3), rng.uniform(1.6, 2.0)
        x0, x1 = px(uc), px(uc + width)
        kind = rng.integers(3)
        if kind == 0:  # cork notice board with papers
            cv2.rectangle(tex, (x0, z(z1)), (x1, z(z0)), (170, 130, 80), -1)
            for _ in range(rng.integers(3, 9)):
                a = rng.uniform(uc, uc + width - 0.2)
                b = rng.uniform(z0, z1 - 0.25)
                c = tuple(int(v) for v in rng.integers(120, 256, 3))
                cv2.rectangle(tex, (px(a), z(b + 0.25)), (px(a + 0.18), z(b)), c, -1)
        elif kind == 1:  # poster: bold colour blocks
            c1 = tuple(int(v) for v in rng.integers(0, 256, 3))
            c2 = tuple(int(v) for v in rng.integers(0, 256, 3))
            cv2.rectangle(tex, (x0, z(z1)), (x1, z(z0)), c1, -1)
            cv2.rectangle(tex, (x0 + 4, z(z1 - 0.1)), ((x0 + x1) // 2, z(z0 + 0.1)), c2, -1)
        else:  # fire extinguisher or sign: small, saturated
            c = (200, 30, 30) if rng.random() < 0.5 else (30, 140, 60)
            cv2.rectangle(tex, (x0, z(1.2)), (x0 + 10, z(0.5)), c, -1)
    if decor.signs_every_m > 0:  # drawn after everything else: the defaults' draws stay as they were
        _paint_signs(tex, length, rng, decor, label)
    return tex


def _paint_signs(tex: np.ndarray, length: float, rng: np.random.Generator, decor: Decor, label: int) -> None:
    """Wayfinding: direction signs (white on a colour, an arrow and a word), green exit signs high
    up, and framed floor maps: the dense signage of a building with many junctions."""
    wall_h = decor.wall_h

    def px(u: float) -> int:
        return int(round(u * TEX_PPM))

    def zr(zm: float) -> int:
        return _z(zm, wall_h)

    for _ in range(rng.poisson(length / decor.signs_every_m)):
        uc = rng.uniform(0.1, max(0.2, length - 1.0))
        kind = rng.integers(3)
        if kind == 0:  # direction sign at eye height
            bg = ((20, 60, 140), (10, 110, 70), (140, 30, 30), (40, 40, 40))[int(rng.integers(4))]
            x0, x1 = px(uc), px(uc + rng.uniform(0.5, 0.9))
            z = rng.uniform(1.5, 1.9)
            cv2.rectangle(tex, (x0, zr(z + 0.25)), (x1, zr(z)), bg, -1)
            ym = (zr(z + 0.25) + zr(z)) // 2
            d = 1 if rng.random() < 0.5 else -1
            xa = x0 + 8 if d > 0 else x1 - 8
            cv2.arrowedLine(tex, (xa, ym), (xa + 14 * d, ym), (255, 255, 255), 2, tipLength=0.5)
            word = ("LAB", "EXIT", "WC", "LIFT", "OFFICE", "HALL")[int(rng.integers(6))]
            cv2.putText(tex, word, (x0 + 22, ym + 4), cv2.FONT_HERSHEY_PLAIN, 0.7, (255, 255, 255), 1, cv2.LINE_AA)
        elif kind == 1:  # exit sign near the ceiling
            x0 = px(uc)
            cv2.rectangle(tex, (x0, zr(wall_h - 0.15)), (x0 + px(0.4), zr(wall_h - 0.35)), (20, 170, 60), -1)
            cv2.rectangle(tex, (x0 + 3, zr(wall_h - 0.2)), (x0 + 9, zr(wall_h - 0.3)), (255, 255, 255), -1)
        else:  # framed floor map / directory board
            x0, x1 = px(uc), px(uc + rng.uniform(0.6, 1.0))
            cv2.rectangle(tex, (x0, zr(1.9)), (x1, zr(1.1)), (30, 30, 30), -1)
            cv2.rectangle(tex, (x0 + 3, zr(1.87)), (x1 - 3, zr(1.13)), (240, 240, 230), -1)
            for _ in range(int(rng.integers(3, 7))):
                a, b = int(rng.integers(x0 + 4, max(x0 + 5, x1 - 12))), int(rng.integers(zr(1.85), zr(1.2)))
                c = tuple(int(v) for v in rng.integers(60, 230, 3))
                cv2.rectangle(tex, (a, b), (a + 8, b + 5), c, -1)


def _paint_glass(tex: np.ndarray, glass: np.ndarray, wall_h: float, start_m: float) -> None:
    """A glass curtain wall: glazing from 0.1 m above the floor to 0.15 m below the ceiling,
    mullions every 1.5 m along the plan (`start_m`: where the strip starts on its wall) and a
    transom at 1.0 m."""
    w = tex.shape[1]
    top, bottom = int(round(0.15 * TEX_PPM)), int(round((wall_h - 0.1) * TEX_PPM))
    rows = np.arange(top, bottom)
    sky = np.stack([150 + 60 * rows / bottom, 185 + 40 * rows / bottom, np.full(len(rows), 235.0)], -1)
    tex[top:bottom] = sky[:, None, :].astype(np.uint8)
    glass[top:bottom] = True
    frame = (95, 100, 105)
    for m in np.arange(-(start_m % 1.5), w / TEX_PPM, 1.5):
        c = int(round(m * TEX_PPM))
        if -3 < c < w:
            tex[:, max(0, c) : c + 3] = frame
            glass[:, max(0, c) : c + 3] = False
    z1 = int(round((wall_h - 1.0) * TEX_PPM))
    tex[z1 : z1 + 3], glass[z1 : z1 + 3] = frame, False
    tex[:top], tex[bottom:] = frame, (70, 70, 75)
    glass[:top], glass[bottom:] = False, False


def _paint_stairs(tex: np.ndarray, wall_h: float, start_m: float, end_wall: bool) -> None:
    """A stairwell's wall: concrete grey, the flight's stringer rising along side walls (steps
    0.17 m by 0.28 m), a handrail, and stripes of step nosings where the stairs face the walker."""
    h, w = tex.shape[:2]
    tex[:] = (168, 166, 160)
    step_rows = int(round(0.17 * TEX_PPM))
    if end_wall:  # the flight seen head-on: nosings one above another
        for k in range(12):
            z = 0.17 * (k + 1)
            r = int(round((wall_h - z) * TEX_PPM))
            if 0 <= r < h:
                tex[max(0, r - step_rows) : r] = (120, 118, 112) if k % 2 else (190, 188, 180)
                tex[r : r + 2] = (230, 200, 40)  # the nosing's yellow edge
        return
    us = (np.arange(w) / TEX_PPM + start_m) % 6.0  # a flight every 6 m of wall
    rise = np.floor(us / 0.28) * 0.17
    for c in range(w):
        top = int(round((wall_h - rise[c]) * TEX_PPM))
        tex[max(0, top) :, c] = (96, 94, 90)  # the stringer and the steps below it
    rail = np.clip(((wall_h - rise - 0.9) * TEX_PPM).astype(int), 0, h - 3)
    for c in range(w):
        tex[rail[c] : rail[c] + 3, c] = (60, 60, 64)


def _floor_and_ceiling(
    free: np.ndarray,
    rng: np.random.Generator,
    lines: list[list[Point]],
    decor: Decor = DEFAULT_DECOR,
    halls: list[Rect] | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Floor tiles and a ceiling with lights along the centre lines (and in rows over `halls`,
    rooms too wide for one row of lights)."""
    h, w = free.shape
    fh, fw = int(h * GRID * PLAN_PPM), int(w * GRID * PLAN_PPM)
    tile = int(decor.tile_m * PLAN_PPM)
    ny, nx = fh // tile + 1, fw // tile + 1
    shades = rng.integers(*decor.floor_shades, (ny, nx)).astype(np.uint8)
    floor = np.repeat(np.repeat(shades, tile, 0), tile, 1)[:fh, :fw]
    tr, tg, tb = decor.floor_tint
    floor = np.stack([(floor * tr).astype(np.uint8), (floor * tg).astype(np.uint8), (floor * tb).astype(np.uint8)], -1)
    if decor.grout:
        floor[::tile, :] = (110, 110, 110)
        floor[:, ::tile] = (110, 110, 110)
    ceiling = np.full((fh, fw, 3), 225, np.uint8)

    def light(cx: float, cy: float, horiz: bool) -> None:
        if decor.lights == "downlights":  # small round warm-white discs
            cv2.circle(ceiling, (int(cx * PLAN_PPM), int(cy * PLAN_PPM)), int(0.15 * PLAN_PPM), (255, 246, 225), -1)
            return
        hw, hh = (0.6, 0.3) if horiz else (0.3, 0.6)
        if decor.lights == "strips":  # long thin tubes, almost continuous
            hw, hh = (decor.light_spacing * 0.45, 0.08) if horiz else (0.08, decor.light_spacing * 0.45)
        cv2.rectangle(
            ceiling,
            (int((cx - hw) * PLAN_PPM), int((cy - hh) * PLAN_PPM)),
            (int((cx + hw) * PLAN_PPM), int((cy + hh) * PLAN_PPM)),
            (255, 255, 250),
            -1,
        )

    for line in lines:
        (ax, ay), (bx, by) = line
        n = int(np.hypot(bx - ax, by - ay) / decor.light_spacing) + 1
        for t in np.linspace(0, 1, n):
            cx, cy = ax + t * (bx - ax), ay + t * (by - ay)
            horiz = abs(bx - ax) > abs(by - ay)
            light(cx, cy, horiz)
    for x0, y0, x1, y1 in halls or []:
        for cy in np.arange(y0 + 2.0, y1 - 1.0, 3.0):
            for cx in np.arange(x0 + 2.0, x1 - 1.0, decor.light_spacing):
                light(float(cx), float(cy), True)
    return floor, ceiling


@dataclass(frozen=True)
class Lighting:
    """How a venue is lit, baked into its textures: lamps of a colour per wing, stretches with
    the lights off, and daylight through glass and windows at an hour of the day. Build the same
    venue (seed, layout, decor) at two hours and the walls, doors and boards stay; only the light
    changes, as between a morning's modelling walk and an afternoon's visit."""

    tints: tuple[tuple[float, float, float], ...] = ((1.0, 1.0, 1.0),)  # lamp colour per wing (cycled)
    level: float = 1.0  # lamp light
    dim_p: float = 0.0  # share of ~10 m corridor stretches with their lights off
    dim: float = 0.45  # light left there
    hour: float | None = None  # daylight at this hour (6-18); None: no daylight
    daylight: float = 0.8  # daylight beside a sunlit window at noon, relative to the lamps


WARM, NEUTRAL, COOL = (1.04, 0.9, 0.72), (1.0, 1.0, 1.0), (0.88, 0.97, 1.1)  # 3000 K, 4000 K, 6500 K lamps


def _sun(hour: float) -> tuple[float, np.ndarray, float]:
    """(elevation 0..1, daylight colour, azimuth in plan degrees) of the sun at `hour`."""
    e = float(np.clip(np.sin(np.pi * (hour - 6.0) / 12.0), 0.0, 1.0))
    tint = np.array([1.0, 0.78 + 0.22 * e, 0.55 + 0.45 * e], np.float32)  # low sun: orange
    return e, tint, 90.0 + 180.0 * (hour - 6.0) / 12.0  # rises east, sets west


def _outside(rows: int, cols: int, wall_h: float, hour: float, rng: np.random.Generator) -> np.ndarray:
    """(rows, cols, 3) float32: what a glass wall shows outside (sky over a skyline of buildings
    and trees), lit for `hour`."""
    e, tint, _ = _sun(hour)
    z = wall_h - (np.arange(rows) + 0.5) / TEX_PPM  # height of each row (m)
    top = np.array([70 + 110 * e, 120 + 100 * e, 190 + 50 * e], np.float32)
    low = np.array([255, 170 + 70 * e, 120 + 120 * e], np.float32)  # the horizon glows at dusk
    f = np.clip((z - 0.8) / max(wall_h - 0.8, 1e-3), 0, 1)[:, None]
    sky = (low * (1 - f) + top * f) * (0.55 + 0.45 * e)
    # skyline: buildings and trees, a height per 0.5 m, blocky
    heights = np.repeat(rng.uniform(0.8, 2.4, cols // 20 + 2), 20)[:cols]
    facade = np.repeat(rng.uniform(60, 150, (cols // 20 + 2, 3)), 20, axis=0)[:cols].astype(np.float32)
    out = np.repeat(sky[:, None, :], cols, axis=1)
    below = z[:, None] < heights[None, :]
    lit = facade * tint * (0.3 + 0.7 * e)
    out[below] = np.broadcast_to(lit[None, :, :], out.shape)[below]
    return out


def _relight(
    lighting: Lighting,
    seed: int,
    size: Point,
    free: np.ndarray,
    lines: list[list[Point]],
    segs: list[tuple[float, float, float, float]],
    normals: list[int],
    offs: list[int],
    atlas: np.ndarray,
    glass: np.ndarray,
    floor: np.ndarray,
    ceiling: np.ndarray,
    wall_h: float,
) -> None:
    """Bake `lighting` into the textures in place (see `Lighting`). Its own generator: the
    venue's walls, doors and boards are those of the same seed without it."""
    rng = np.random.default_rng(seed + 7919)
    rows, cols = free.shape
    ys, xs = (np.mgrid[0:rows, 0:cols] + 0.5) * GRID
    wing = (xs > size[0] / 2).astype(int) + 2 * (ys > size[1] / 2).astype(int)
    tints = np.array(lighting.tints, np.float32)
    lamp = tints[wing % len(tints)] * lighting.level  # (rows, cols, 3)
    on = np.ones((rows, cols), np.float32)
    for (ax, ay), (bx, by) in lines:  # lights off along some ~10 m stretches
        length = float(np.hypot(bx - ax, by - ay))
        n = max(1, int(round(length / 10.0)))
        for k in range(n):
            if rng.random() >= lighting.dim_p:
                continue
            t0, t1 = k / n, (k + 1) / n
            x0, x1 = sorted((ax + t0 * (bx - ax), ax + t1 * (bx - ax)))
            y0, y1 = sorted((ay + t0 * (by - ay), ay + t1 * (by - ay)))
            r0, r1 = int(max(0, (y0 - 2.0) / GRID)), int(min(rows, (y1 + 2.0) / GRID))
            c0, c1 = int(max(0, (x0 - 2.0) / GRID)), int(min(cols, (x1 + 2.0) / GRID))
            on[r0:r1, c0:c1] = lighting.dim
    soft: np.ndarray = cv2.GaussianBlur(on, (0, 0), 8.0)  # light fades over a metre or so
    field = lamp * soft[..., None]
    if lighting.hour is not None:  # daylight falling in through glass, strongest where the sun shines in
        outside = _outside(atlas.shape[0], atlas.shape[1], wall_h, lighting.hour, rng)
        e, tint, sun_az = _sun(lighting.hour)
        src = np.zeros((rows, cols), np.float32)
        for (x0, y0, x1, y1), nd, off in zip(segs, normals, offs, strict=True):
            length = float(np.hypot(x1 - x0, y1 - y0))
            w = max(1, int(round(length * TEX_PPM)))
            share = glass[:, off : off + w].mean(axis=0)  # of each column
            if share.max() <= 0:
                continue
            out_az = (0.0, 180.0, 270.0, 90.0)[nd]  # the wall's outward direction
            direct = max(0.0, float(np.cos(np.deg2rad(out_az - sun_az)))) * (1.0 - 0.5 * e)
            nx, ny = ((0.0, 1.0), (0.0, -1.0), (1.0, 0.0), (-1.0, 0.0))[nd]
            u = (np.arange(w) + 0.5) / w
            px, py = x0 + u * (x1 - x0) + 0.15 * nx, y0 + u * (y1 - y0) + 0.15 * ny
            r = np.clip((py / GRID).astype(int), 0, rows - 1)
            c = np.clip((px / GRID).astype(int), 0, cols - 1)
            np.maximum.at(src, (r, c), share * (1.0 + 2.0 * direct))
            atlas_sun = 1.0 + 1.2 * direct  # glass facing the sun glares
            cols_ = slice(off, off + w)
            m = glass[:, cols_]
            strip = atlas[:, cols_].astype(np.float32)
            strip[m] = np.clip(outside[:, cols_][m] * atlas_sun, 0, 255)
            atlas[:, cols_] = strip.astype(np.uint8)
        # spread: light from a window falls off over a few metres into the room
        spread = cv2.GaussianBlur(src, (0, 0), 12.0) * 2 * np.pi * 12.0**2 / 60.0
        field = field + (lighting.daylight * (0.25 + 0.75 * e) * np.clip(spread, 0, 3))[..., None] * tint
    # walls: each column lit by the light just in front of it
    for (x0, y0, x1, y1), nd, off in zip(segs, normals, offs, strict=True):
        length = float(np.hypot(x1 - x0, y1 - y0))
        w = max(1, int(round(length * TEX_PPM)))
        nx, ny = ((0.0, 1.0), (0.0, -1.0), (1.0, 0.0), (-1.0, 0.0))[nd]
        u = (np.arange(w) + 0.5) / w
        r = np.clip(((y0 + u * (y1 - y0) + 0.15 * ny) / GRID).astype(int), 0, rows - 1)
        c = np.clip(((x0 + u * (x1 - x0) + 0.15 * nx) / GRID).astype(int), 0, cols - 1)
        g = field[r, c]  # (w, 3)
        strip = atlas[:, off : off + w]
        keep = glass[:, off : off + w]
        lit = np.clip(strip.astype(np.float32) * g[None, :, :], 0, 255).astype(np.uint8)
        atlas[:, off : off + w] = np.where(keep[..., None], strip, lit)
    big = cv2.resize(field, (floor.shape[1], floor.shape[0]), interpolation=cv2.INTER_LINEAR)
    floor[:] = np.clip(floor.astype(np.float32) * big, 0, 255).astype(np.uint8)
    ceiling[:] = np.clip(ceiling.astype(np.float32) * big, 0, 255).astype(np.uint8)


def build_scene(
    seed: int = 0, layout: str = "default", decor: Decor | None = None, lighting: Lighting | None = None
) -> Scene:
    """The synthetic venue for a seed: geometry, textures and named places.

    `decor` and `lighting` (synth/families.py) change what the walls, floor and ceiling look like
    and how they are lit; left out, the venue is the original one, bit for bit.
    """
    rng = np.random.default_rng(seed)
    if layout not in LAYOUTS:
        raise ValueError(f"unknown layout {layout!r} (known: {', '.join(LAYOUTS)})")
    decor = decor or DEFAULT_DECOR
    plan = PLANS[layout]() if layout in PLANS else None
    size, rects, lines = LAYOUTS[layout]()
    free = _grid(size, rects)
    pill = _pillars(free, rng, p=decor.pillar_p)
    if layout == "twin":  # no pillar in either twin: the same walls, run for run
        pill &= ~_grid(size, [rects[i] for i in TWINS])
    if plan is not None and plan.alike:  # nor in look-alike corridors
        pill &= ~_grid(size, plan.alike)
    free_final = free & ~pill
    raw = _segments(free_final)
    segs, offs, strips, masks, normals = [], [], [], [], []
    off = 0
    tex_h = int(decor.wall_h * TEX_PPM)
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
        w = max(1, int(round(length * TEX_PPM)))
        glass = np.zeros((tex_h, w), bool)
        along = min(x0, x1) if abs(y1 - y0) < 1e-9 else min(y0, y1)  # where the wall starts, on its axis
        if is_pillar:
            tex = np.empty((tex_h, w, 3), np.uint8)
            tex[:] = (150, 150, 148)
            tex[:, :2] = (120, 120, 118)
        elif plan is not None and _inside(mx, my, plan.stairs):
            sx0, sy0, sx1, sy1 = next(r for r in plan.stairs if _inside(mx, my, [r]))
            tex = np.empty((tex_h, w, 3), np.uint8)
            # the flight runs along the stairwell's long side: walls across it face the walker
            _paint_stairs(tex, decor.wall_h, along, end_wall=(abs(y1 - y0) < 1e-9) == (sy1 - sy0 > sx1 - sx0))
        elif plan is not None and _inside(mx, my, plan.glass):
            tex = np.empty((tex_h, w, 3), np.uint8)
            _paint_glass(tex, glass, decor.wall_h, along)
        else:
            outer = my < 2.0 or my > size[1] - 2.0 or mx < 1.5 or mx > size[0] - 1.5
            wrng = rng
            alike = next((r for r in plan.alike if _inside(mx, my, [r])), None) if plan is not None else None
            if alike is not None:  # drawn from where the wall is in its look-alike corridor
                rel = [int(round((v - o) * 10)) + 1000 for v, o in zip((x0, y0, x1, y1), alike[:2] * 2, strict=True)]
                wrng, wing = np.random.default_rng([seed, *rel]), 0
            pattern = [0, 1] if wrng.random() < decor.alternate_p else [0, 0, 1]
            base = decor.wall_colours[wing % len(decor.wall_colours)]
            tex = _paint_wall(length, wrng, base, wrng.uniform(*decor.door_phase), pattern, outer, label, decor, glass)
            label += 20
        segs.append((x0, y0, x1, y1))
        normals.append(nd)
        offs.append(off)
        strips.append(tex)
        masks.append(glass)
        off += tex.shape[1]
    atlas = np.concatenate(strips, axis=1)
    halls = [rects[i] for i in plan.halls] if plan is not None else None
    floor, ceiling = _floor_and_ceiling(free_final, rng, lines, decor, halls)
    if lighting is not None:
        _relight(
            lighting, seed, size, free_final, lines, segs, normals, offs, atlas,
            np.concatenate(masks, axis=1), floor, ceiling, decor.wall_h,
        )  # fmt: skip
    routes = None
    if layout == "twin":
        _copy_twin(rects, segs, offs, floor)
        routes = twin_routes()
    elif plan is not None:
        routes = (plan.model, plan.query)
    places = []
    for i, line in enumerate(lines):
        (ax, ay), (bx, by) = line
        names = NAMES.get(layout) or (plan.names if plan is not None else None)
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
        wall_h=decor.wall_h,
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
