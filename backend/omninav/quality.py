"""The quality map: where would the venue answer right? (leave-one-out, `omninav quality`)

The modelling walks are cut into 1 s segments; each segment's frames form a clip, located with
the search and the aggregation that answer a phone (index.py, aggregate.py), every frame searched
*without itself*: without the frames of its own video within `LEAVE_OUT_M` of it along the walk
(at walking pace the frame alone; at a stop, the whole stop). What answers it was then filmed a
step away, as an independent walk's frames are, while a look-alike elsewhere keeps every frame:
a repeated stretch shows up as a wrong or an ambiguous answer.

Why so narrow a window: a walk filmed once has no other frames of its stretch, and a corridor's
panorama changes within a stride (a door beside the walker turns by 40 degrees in 1 m). Leaving
out the whole 1 s segment and 0.5 s either side made 7 % of the twin venue's walk green where an
independent query walk was answered within 2 m 96 % of the time (73 % also unambiguously); 0.13 m
gave 61 %, 0.4 m 33 %; 0.1 m gives 77 % (docs/benchlog.md, "Quality map").

A segment is
  green  answered within `RADIUS_M` of where the walk was (its last frame), unambiguously;
  amber  within `RADIUS_M`, but a look-alike scored close: margin = (support - rival) / support
         below `AMBIGUOUS_MARGIN` (support: the answer's mean per-frame score, rival: the same
         for the best hypothesis at least aggregate.ALT_M = 3 m away; 1 = no rival at all,
         0 = a rival as good as the answer);
  red    more than `RADIUS_M` away (wrong).

Corridors are the places with an `area`: their long axis is cut into `BIN_M` bins, and the walk's
steps inside the area mark which bins were walked, and in which sense along the axis. All clips
are searched in one batched pass (in chunks bounded in memory), on the CPU or the GPU as the
index is; only the per-clip aggregation is a loop.
"""

from __future__ import annotations

import time
from typing import Any

import cv2
import numpy as np

from .aggregate import AGGREGATORS
from .index import Index, Matches
from .model_venue import Progress
from .settings import SearchSettings
from .store import Generation

RADIUS_M = 2.0  # an answer this close to the walk is right
CLIP_S = 1.0  # a segment: the frames of 1 s of the walk, located as one clip
LEAVE_OUT_M = 0.1  # every frame is searched without itself and its video's frames this close
AMBIGUOUS_MARGIN = 0.1  # a right answer whose rival scored within 10 % of it is amber
BIN_M = 0.5  # corridor axis resolution for coverage
COVERED_MIN = 0.3  # a corridor with less of its axis walked is grey (not covered)
DIRECTION_MIN = 0.5  # a sense counts as filmed over at least half of the walked axis
VERDICT_SHARE = 0.25  # a corridor takes the worst colour that a quarter of its segments have
STEP_MAX_M = 3.0  # consecutive frames further apart than this are not one step (a cut)
CHUNK_CELLS = 1 << 25  # query frames x venue frames scored per pass (128 MB of float32)
CHUNK_FRAMES = 512  # and at most this many query frames (the re-ranking gathers 128 keys each)


def _walked(xy: np.ndarray, vid: np.ndarray) -> np.ndarray:
    """(N,) path length walked, frame to frame (rows sorted by video, then time), with a gap of
    more than any window between videos: a window of rows around a frame stays in its video."""
    step = np.hypot(*np.diff(xy, axis=0).T)
    step[np.diff(vid) != 0] = 1.0 + 2 * LEAVE_OUT_M
    return np.concatenate([[0.0], np.cumsum(step)])


def _segments(frames: np.ndarray, n: int) -> list[np.ndarray]:
    """Rows of each video, in time order, cut into runs of n frames (a last short run of at least
    half a clip is kept)."""
    out = []
    for v in np.unique(frames["video"]):
        rows = np.flatnonzero(frames["video"] == v)
        rows = rows[np.argsort(frames["t"][rows], kind="stable")]
        for s in range(0, len(rows), n):
            r = rows[s : s + n]
            if len(r) >= max(2, (n + 1) // 2):
                out.append(r)
    return out


def quality_map(
    gen: Generation,
    places: list[dict[str, Any]],
    video_floors: dict[str, str],
    device: str = "cpu",
    progress: Progress | None = None,
) -> dict[str, Any]:
    """A generation's quality map (the module's header says how); `places`: the venue's places
    (those with an `area` are its corridors); `video_floors`: video name -> floor id."""
    t0 = time.perf_counter()
    conf = gen.settings
    frames = np.asarray(gen.frames)
    n_frames = len(frames)
    # leave-one-out excludes a contiguous range of rows: rows sorted by video, then time
    order = np.lexsort((frames["t"], frames["video"]))
    arrays = gen.arrays
    spectra: np.ndarray = gen.spectra
    if not np.array_equal(order, np.arange(n_frames)):
        frames, spectra, arrays = frames[order], np.asarray(spectra)[order], None
    search = SearchSettings.of(conf)
    index = Index(spectra, frames["heading"], device=device, key_dims=search.key_dims_for(n_frames), arrays=arrays)
    xy = np.stack([frames["x"], frames["y"]], -1).astype(np.float64)
    t = frames["t"].astype(np.float64)
    vid = frames["video"]
    n = max(2, int(round(CLIP_S * conf["model_fps"])))
    segs = _segments(frames, n)
    walked = _walked(xy, vid)
    aggregate = AGGREGATORS[conf["aggregate"]]
    k, shared, shortlist = search.candidates, search.shared_candidates, search.shortlist
    chunk = max(n, min(CHUNK_FRAMES, CHUNK_CELLS // max(n_frames, 1)))
    total = sum(len(r) for r in segs)
    out: list[dict[str, Any]] = []
    done = 0
    i = 0
    while i < len(segs):
        group = [segs[i]]
        size = len(segs[i])
        i += 1
        while i < len(segs) and size + len(segs[i]) <= chunk:
            group.append(segs[i])
            size += len(segs[i])
            i += 1
        rows = np.concatenate(group)
        # each frame's exclusion [lo, hi): the rows of its video within LEAVE_OUT_M along the walk
        lo = np.searchsorted(walked, walked[rows] - LEAVE_OUT_M, side="left")
        hi = np.searchsorted(walked, walked[rows] + LEAVE_OUT_M, side="right")
        # each segment a clip: its frames share their candidates, as a locate's second does
        groups = np.repeat(np.arange(len(group)), [len(r) for r in group]) if shared else None
        m = index.search(np.asarray(spectra[rows]), k, exclude=(lo, hi), groups=groups, shortlist=shortlist)
        at = 0
        for r in group:
            w = slice(at, at + len(r))
            sub = Matches(m.index[w], m.coarse[w], m.score[w], m.heading[w])
            at += len(r)
            e = aggregate(sub, xy, t[r] - t[r[0]], conf)
            out.append(_segment(gen, frames, xy, r, e, video_floors, places))
        done += len(rows)
        if progress:
            progress(done, total, time.perf_counter() - t0)
    floors = np.array([_floor_of(v, video_floors, places) for v in gen.videos] or [""])
    frame_floor = floors[frames["video"]]
    corridors = [c for p in places if (c := _corridor(p, frames, xy, frame_floor, places, out))]
    return _result(n_frames, out, corridors)


def _floor_of(video: str, video_floors: dict[str, str], places: list[dict[str, Any]]) -> str:
    """A video's floor; one not named (or a place without a floor) is on the lowest floor id that
    the places name, as the server puts a video without a floor on the venue's first floor."""
    if video in video_floors:
        return str(video_floors[video])
    return min((str(p["floor"]) for p in places if p.get("floor") is not None), default="1")


def _segment(
    gen: Generation,
    frames: np.ndarray,
    xy: np.ndarray,
    rows: np.ndarray,
    e: Any,
    video_floors: dict[str, str],
    places: list[dict[str, Any]],
) -> dict[str, Any]:
    last = int(rows[-1])
    err = float(np.hypot(e.x - xy[last, 0], e.y - xy[last, 1]))
    margin = (e.support - e.rival) / e.support if e.support > 0 else 0.0
    verdict = "red" if err > RADIUS_M else "amber" if margin < AMBIGUOUS_MARGIN else "green"
    video = gen.videos[int(frames["video"][last])]
    mv = gen.videos[int(frames["video"][e.venue_row])]
    return {
        "video": video,
        "floor": _floor_of(video, video_floors, places),
        "t0": round(float(frames["t"][rows[0]]), 3),
        "t1": round(float(frames["t"][last]), 3),
        "points": [[round(float(x), 2), round(float(y), 2)] for x, y in xy[rows]],
        "verdict": verdict,
        "error_m": round(err, 3),
        "margin": round(float(margin), 3),
        "query": {"video": video, "t": round(float(frames["t"][last]), 3)},
        "match": {
            "video": mv,
            "t": round(float(frames["t"][e.venue_row]), 3),
            "x": round(e.x, 3),
            "y": round(e.y, 3),
        },
    }


def axis_coverage(area: list[float], xy: np.ndarray, cut: np.ndarray, bin_m: float = BIN_M) -> dict[str, float]:
    """How much of an area's long axis a walk covers, and in which senses.

    area: [x0, y0, x1, y1]; xy: (N, 2) the walk's positions in time order; cut: (N,) bool, True
    where a frame does not continue the one before (another video, a jump). A step between two
    consecutive frames inside the area marks the axis bins it spans; it moves `forward` (towards
    larger x or y) or `backward` when it moves more along the axis than across it.
    Returns shares of the axis's bins: covered, forward, backward (each 0..1).
    """
    x0, y0, x1, y1 = area
    long_x = (x1 - x0) >= (y1 - y0)
    u0, u1 = (x0, x1) if long_x else (y0, y1)
    nb = max(1, int(np.ceil((u1 - u0) / bin_m - 1e-9)))
    inside = (xy[:, 0] >= x0) & (xy[:, 0] <= x1) & (xy[:, 1] >= y0) & (xy[:, 1] <= y1)
    u = xy[:, 0] if long_x else xy[:, 1]
    w = xy[:, 1] if long_x else xy[:, 0]
    f = (u - u0) / bin_m  # axis position in bins
    b = np.clip(np.floor(f).astype(np.int64), 0, nb - 1)
    shares = {}
    step = np.zeros(0, bool)
    if len(xy) >= 2:
        du, dw = np.diff(u), np.diff(w)
        step = inside[1:] & inside[:-1] & ~cut[1:] & (np.hypot(du, dw) <= STEP_MAX_M)
        lone = inside & ~np.concatenate([[False], step]) & ~np.concatenate([step, [False]])
    else:
        du = dw = np.zeros(0)
        lone = inside
    along = np.abs(du) >= np.abs(dw)
    for name, sel in (("covered", step), ("forward", step & along & (du > 0)), ("backward", step & along & (du < 0))):
        mark = np.zeros(nb + 1, np.int64)
        i = np.flatnonzero(sel)
        # the bins the step passes over (its end on a bin's edge does not enter that bin)
        lo, hi = np.minimum(f[i], f[i + 1]), np.maximum(f[i], f[i + 1])
        a = np.clip(np.floor(lo).astype(np.int64), 0, nb - 1)
        c = np.clip(np.maximum(a, np.ceil(hi).astype(np.int64) - 1), 0, nb - 1)
        np.add.at(mark, a, 1)
        np.add.at(mark, c + 1, -1)
        hit = np.cumsum(mark)[:nb] > 0
        if name == "covered":
            hit[b[lone]] = True  # a frame standing alone inside still covers its bin
        shares[name] = float(hit.mean())
    return shares


def directions(shares: dict[str, float]) -> dict[str, bool]:
    """Which senses along the axis were filmed: over at least DIRECTION_MIN of the walked axis."""
    c = shares["covered"]
    return {d: c > 0 and shares[d] >= DIRECTION_MIN * c for d in ("forward", "backward")}


def verdict_of(colours: list[str]) -> str:
    """A corridor's colour: the worst one that at least VERDICT_SHARE of its segments have."""
    if not colours:
        return "grey"
    n = len(colours)
    red = colours.count("red") / n
    amber = colours.count("amber") / n
    if red >= VERDICT_SHARE:
        return "red"
    return "amber" if red + amber >= VERDICT_SHARE else "green"


def _corridor(
    place: dict[str, Any],
    frames: np.ndarray,
    xy: np.ndarray,
    frame_floor: np.ndarray,
    places: list[dict[str, Any]],
    segs: list[dict[str, Any]],
) -> dict[str, Any] | None:
    area = place.get("area")
    if not area:
        return None
    floor = str(place["floor"]) if place.get("floor") is not None else _floor_of("", {}, places)
    rows = np.flatnonzero(frame_floor == floor)
    pts = xy[rows]
    cut = np.ones(len(rows), bool)
    if len(rows) > 1:
        cut[1:] = (np.diff(rows) != 1) | (np.diff(frames["video"][rows]) != 0)
    shares = axis_coverage(area, pts, cut)
    x0, y0, x1, y1 = area
    mine = [
        s["verdict"]
        for s in segs
        if s["floor"] == floor and x0 <= s["points"][-1][0] <= x1 and y0 <= s["points"][-1][1] <= y1
    ]
    covered = shares["covered"] >= COVERED_MIN and bool(mine)
    return {
        "place": place["name"],
        "floor": floor,
        "area": [float(v) for v in area],
        "covered": round(shares["covered"], 3),
        "verdict": verdict_of(mine) if covered else "grey",
        "share_green": round(mine.count("green") / len(mine), 3) if covered else None,
        "directions": directions(shares),
    }


def _runs(segs: list[dict[str, Any]], colour: str) -> int:
    """Stretches of that colour: runs of consecutive segments of one video."""
    n, prev = 0, ("", False)
    for s in segs:
        now = (s["video"], s["verdict"] == colour)
        n += now[1] and now != prev
        prev = now
    return n


def _the(name: str) -> str:
    """'Stairwell' -> 'the Stairwell' (as the app names an area); 'Corridor 1', 'the hall' stay."""
    words = name.split()
    last = words[-1] if words else ""
    if name.lower().startswith("the ") or last[:1].isdigit() or (len(last) == 1 and last.isupper()):
        return name
    return f"the {name}"


def _names(names: list[str]) -> str:
    named = [_the(n) for n in names]
    return named[0] if len(named) == 1 else ", ".join(named[:-1]) + " and " + named[-1]


def sentence(summary: dict[str, Any]) -> str:
    """'92 % of the walked corridors answer within 2 m; 3 ambiguous stretches; the Stairwell is
    not covered'."""
    parts = [f"{round(100 * summary['share_green'])} % of the walked corridors answer within {RADIUS_M:g} m"]
    a, w = summary["ambiguous"], summary["wrong"]
    parts.append(f"{a or 'no'} ambiguous stretch{'' if a == 1 else 'es'}")
    if w:
        parts.append(f"{w} wrong stretch{'' if w == 1 else 'es'}")
    for key, verb in (("uncovered", "not covered"), ("one_direction", "filmed in one direction only")):
        if names := summary[key]:
            parts.append(f"{_names(names)} {'is' if len(names) == 1 else 'are'} {verb}")
    return "; ".join(parts)


def _result(n_frames: int, segs: list[dict[str, Any]], corridors: list[dict[str, Any]]) -> dict[str, Any]:
    green = sum(s["verdict"] == "green" for s in segs)
    summary = {
        "share_green": round(green / len(segs), 3) if segs else 0.0,
        "ambiguous": _runs(segs, "amber"),
        "wrong": _runs(segs, "red"),
        "uncovered": [c["place"] for c in corridors if c["verdict"] == "grey"],
        "one_direction": [
            c["place"] for c in corridors if c["verdict"] != "grey" and sum(c["directions"].values()) == 1
        ],
    }
    return {
        "generation": None,
        "frames": n_frames,
        "radius_m": RADIUS_M,
        "segments": segs,
        "corridors": corridors,
        "summary": summary,
        "sentence": sentence(summary),
    }


COLOURS = {"green": (46, 160, 67), "amber": (240, 160, 20), "red": (214, 39, 40), "grey": (140, 140, 140)}


def quality_png(result: dict[str, Any], plan_rgb: np.ndarray, px_per_m: float, floor: str) -> bytes:
    """The quality map drawn on a floor's plan (H, W, 3) uint8 RGB -> PNG bytes of the same size:
    uncovered corridors shaded grey, every corridor outlined in its colour, every segment of the
    walk as a line in its colour."""
    if plan_rgb.ndim != 3 or plan_rgb.shape[2] != 3:
        raise ValueError(f"plan must be (H, W, 3) RGB, not {plan_rgb.shape}")
    img = (plan_rgb.astype(np.float32) * 0.55 + 255 * 0.45).astype(np.uint8)  # pale: colours read
    s = float(px_per_m)

    def px(x: float, y: float) -> tuple[int, int]:
        return int(round(x * s)), int(round(y * s))

    shade = img.copy()
    for c in result["corridors"]:
        if c["floor"] != floor:
            continue
        x0, y0, x1, y1 = c["area"]
        if c["verdict"] == "grey":
            cv2.rectangle(shade, px(x0, y0), px(x1, y1), COLOURS["grey"], -1)
    img = np.ascontiguousarray(cv2.addWeighted(shade, 0.5, img, 0.5, 0), np.uint8)
    h, w = img.shape[:2]
    for c in result["corridors"]:  # and hatched: no data, rather than a colour
        if c["floor"] == floor and c["verdict"] == "grey":
            (a, b), (e, f) = px(*c["area"][:2]), px(*c["area"][2:])
            a, b, e, f = max(a, 0), max(b, 0), min(e, w), min(f, h)
            yy, xx = np.mgrid[b:f, a:e]
            img[b:f, a:e][(xx + yy) % max(6, int(0.4 * s)) < max(1, int(0.06 * s))] = COLOURS["grey"]
    for c in result["corridors"]:
        if c["floor"] == floor:
            x0, y0, x1, y1 = c["area"]
            cv2.rectangle(img, px(x0, y0), px(x1, y1), COLOURS[c["verdict"]], max(1, int(round(0.1 * s))))
    width = max(2, int(round(0.5 * s)))
    for seg in result["segments"]:
        if seg["floor"] != floor or not seg["points"]:
            continue
        pts = np.array([px(x, y) for x, y in seg["points"]], np.int32).reshape(-1, 1, 2)
        cv2.polylines(img, [pts], False, COLOURS[seg["verdict"]], width, cv2.LINE_AA)
    ok, buf = cv2.imencode(".png", cv2.cvtColor(img, cv2.COLOR_RGB2BGR))
    if not ok:
        raise ValueError("could not encode the quality map as PNG")
    return bytes(buf.tobytes())
