"""The walkable space of a venue as a graph: where a person can walk, and how far it is.

Built from the venue's modelling walks (a modelling walk path's positions in time order, one walk per
video, with its floor): every walk is cut at its corners (Douglas-Peucker) and resampled every
~`spacing_m` along each straight stretch, so that corners and junctions are nodes and a route's
turns fall where the corridor turns. A point within half a spacing of a node already made on its
floor is that node (a corridor walked twice is one chain of nodes, not two). Consecutive nodes of
a walk are joined; so are any two nodes of one floor within `join_m` (where walks cross), which,
with 1 m spacing and a 1 m join, always joins two walks that cross (their nearest nodes are at
most 0.71 m apart). A `lift` or `stairs` place with the same name on two floors joins those
floors at the nodes nearest to it, at a cost in metres (a lift ride is not free, but it is not a
walk of its length either).

Shortest paths are scipy.sparse.csgraph's Dijkstra over the symmetric sparse adjacency: the
tracking filter (tracking.py) asks for graph distances within a walking radius, the routes
(route.py) for the path to a place. Pure data: a WalkGraph never changes once built, and its
`key` fingerprints nodes and edges so that a state saved against one graph is refused by another.
"""

from __future__ import annotations

import hashlib
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import scipy.sparse  # type: ignore[import-untyped]
from scipy.sparse.csgraph import dijkstra  # type: ignore[import-untyped]
from scipy.spatial import cKDTree  # type: ignore[import-untyped]

LIFT_COST_M = 15.0  # a floor change by lift counts as this many metres in route lengths
STAIRS_COST_M = 20.0
FLOOR_COST_M = {"lift": LIFT_COST_M, "stairs": STAIRS_COST_M}
CORNER_M = 0.25  # a walk's position that strays less than this from a straight stretch is on it
ATTACH_M = 5.0  # a place further than this from every node of its floor is not on the graph
MERGE = 0.5  # of spacing_m: a walk's point this close to an existing node of its floor is that node
_TINY = 1e-6  # an edge of zero length still is an edge (csgraph drops explicit zeros)


@dataclass(frozen=True, eq=False)
class WalkGraph:
    xy: np.ndarray  # (N, 2) float64 plan metres, nodes ~spacing_m apart along each walk
    floor: np.ndarray  # (N,) str, the node's floor id
    adj: Any  # scipy.sparse.csr_matrix (N, N) symmetric; edge weight = metres (floor changes: *_COST_M)
    via: dict[tuple[int, int], str]  # floor-changing edges (i < j) -> "lift" | "stairs"
    key: str  # stable fingerprint of nodes + edges (hex)

    def __len__(self) -> int:
        return len(self.xy)

    def nearest(self, x: float, y: float, floor: str | None = None) -> int:
        """The node nearest to (x, y), on `floor` when given (any floor when the floor has no node)."""
        d = np.hypot(self.xy[:, 0] - x, self.xy[:, 1] - y)
        if floor is not None:
            on = self.floor == str(floor)
            if on.any():
                d = np.where(on, d, np.inf)
        return int(np.argmin(d))

    def snap(self, xy: np.ndarray, floor: np.ndarray | None = None) -> np.ndarray:
        """(M, 2) plan points [and (M,) floors] -> (M,) int64 nearest nodes (on the point's floor
        where that floor has nodes): `nearest` for many points at once."""
        pts = np.asarray(xy, np.float64).reshape(-1, 2)
        if floor is None:
            return np.asarray(_tree(self.xy).query(pts)[1], np.int64) if len(pts) else np.zeros(0, np.int64)
        return nearest_on_floor(pts, floor, self.xy, self.floor)

    def distances(self, sources: int | Sequence[int] | np.ndarray, limit: float = np.inf) -> np.ndarray:
        """(S, N) float64 graph metres from each source node; inf where unreachable or beyond limit."""
        src = np.atleast_1d(np.asarray(sources, np.int64))
        if len(src) == 0:
            return np.zeros((0, len(self.xy)))
        d = dijkstra(self.adj, directed=False, indices=src, limit=limit)
        return np.asarray(d, np.float64).reshape(len(src), len(self.xy))

    def path(self, a: int, b: int) -> list[int]:
        """The shortest path a -> b as node ids, both ends included; [] if b cannot be reached."""
        if a == b:
            return [int(a)]
        d, pred = dijkstra(self.adj, directed=False, indices=int(a), return_predecessors=True)
        if not np.isfinite(d[b]):
            return []
        out = [int(b)]
        while out[-1] != a:
            out.append(int(pred[out[-1]]))
        return out[::-1]

    def edge_m(self, i: int, j: int) -> float:
        """The weight of edge i-j (metres, or a floor change's cost); inf if there is none."""
        w = self.adj[int(i), int(j)]
        return float(w) if w else math.inf


def nearest_on_floor(pts: np.ndarray, floor: np.ndarray, to_xy: np.ndarray, to_floor: np.ndarray) -> np.ndarray:
    """(M, 2) points on (M,) floors -> (M,) int64 index of the nearest of `to_xy` on the point's
    floor (or of any floor, where that floor has none)."""
    pts = np.asarray(pts, np.float64).reshape(-1, 2)
    to_xy = np.asarray(to_xy, np.float64)
    out = np.zeros(len(pts), np.int64)
    fl = np.asarray(floor).astype(str).reshape(-1)
    tf = np.asarray(to_floor).astype(str)
    for f in np.unique(fl):
        rows = fl == f
        ids = np.flatnonzero(tf == f)
        if len(ids) == 0:
            ids = np.arange(len(to_xy))
        out[rows] = ids[_tree(to_xy[ids]).query(pts[rows])[1]]
    return out


def _tree(xy: np.ndarray) -> Any:
    return cKDTree(xy)


def simplify(xy: np.ndarray, tol: float) -> np.ndarray:
    """Douglas-Peucker: (T, 2) polyline -> increasing indices of the points kept (ends always),
    so that no dropped point is further than `tol` from the kept polyline. Distances are to the
    segment, not its line, so a walk that turns back (a dead end) keeps its turning point."""
    p = np.asarray(xy, np.float64).reshape(-1, 2)
    n = len(p)
    if n <= 2:
        return np.arange(n)
    keep = np.zeros(n, bool)
    keep[0] = keep[-1] = True
    stack = [(0, n - 1)]
    while stack:
        i, j = stack.pop()
        if j - i < 2:
            continue
        a, b = p[i], p[j]
        seg = b - a
        q = p[i + 1 : j] - a
        L2 = float(seg @ seg)
        t = np.clip(q @ seg / L2, 0.0, 1.0) if L2 > 0 else np.zeros(len(q))
        d = np.hypot(*(q - t[:, None] * seg).T)
        k = int(np.argmax(d))
        if d[k] > tol:
            m = i + 1 + k
            keep[m] = True
            stack += [(i, m), (m, j)]
    return np.flatnonzero(keep)


def resample(xy: np.ndarray, spacing_m: float = 1.0, corner_m: float = CORNER_M) -> np.ndarray:
    """A walk's positions (T, 2) -> (M, 2) nodes: its corners, and points at most spacing_m apart
    (evenly) along each straight stretch between them. Standing still adds nothing."""
    p = np.asarray(xy, np.float64).reshape(-1, 2)
    p = p[np.all(np.isfinite(p), axis=1)]
    if len(p) == 0:
        return np.zeros((0, 2))
    moved = np.r_[True, np.hypot(*np.diff(p, axis=0).T) > 1e-9]
    p = p[moved]
    corners = p[simplify(p, corner_m)]
    out = [corners[:1]]
    for a, b in zip(corners[:-1], corners[1:], strict=True):
        n = max(1, math.ceil(float(np.hypot(*(b - a))) / spacing_m - 1e-9))
        s = np.arange(1, n + 1)[:, None] / n
        out.append(a + s * (b - a))
    return np.concatenate(out)


def _fingerprint(xy: np.ndarray, floor: np.ndarray, i: np.ndarray, j: np.ndarray, w: np.ndarray) -> str:
    h = hashlib.sha256()
    h.update(np.round(xy, 3).astype("<f8").tobytes())
    h.update("\x00".join(floor.tolist()).encode())
    h.update(i.astype("<i8").tobytes() + j.astype("<i8").tobytes())
    h.update(np.round(w, 3).astype("<f8").tobytes())
    return h.hexdigest()[:16]


def _merge(walks: list[tuple[np.ndarray, str]], merge_m: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Resampled walks -> (nodes (N, 2), floors (N,), walk edges (E, 2)): a point within merge_m
    of a node already made on its floor *is* that node, so that a corridor walked twice (or
    there and back) has one chain of nodes, not two side by side, and the tracking filter's
    prior over nodes is not doubled where the recorder passed twice."""
    cell: dict[tuple[str, int, int], list[int]] = {}
    xy: list[tuple[float, float]] = []
    fl: list[str] = []
    edges: list[tuple[int, int]] = []
    for pts, f in walks:
        prev = -1
        for x, y in pts.tolist():
            cx, cy = math.floor(x / merge_m), math.floor(y / merge_m)
            best, bd = -1, merge_m
            for dx in (-1, 0, 1):
                for dy in (-1, 0, 1):
                    for k in cell.get((f, cx + dx, cy + dy), ()):
                        d = math.hypot(xy[k][0] - x, xy[k][1] - y)
                        if d <= bd:
                            best, bd = k, d
            if best < 0:
                best = len(xy)
                xy.append((x, y))
                fl.append(f)
                cell.setdefault((f, cx, cy), []).append(best)
            if prev >= 0 and prev != best:
                edges.append((prev, best))
            prev = best
    return (
        np.asarray(xy, np.float64).reshape(-1, 2),
        np.asarray(fl, dtype=str) if fl else np.zeros(0, dtype="<U1"),
        np.asarray(edges, np.int64).reshape(-1, 2),
    )


def build(
    walks: Sequence[tuple[np.ndarray, str]],
    places: Sequence[Mapping[str, Any]] = (),
    spacing_m: float = 1.0,
    join_m: float = 1.0,
) -> WalkGraph:
    """Walks [(T, 2) positions in time order, floor id] [+ places] -> the walk graph (module doc).

    Lift/stairs places with the same name on several floors join every pair of those floors (a
    lift serves them all; a stair between floors 1 and 3 counts as one flight, a simplification),
    each at the node of the floor nearest to the place, when one is within ATTACH_M."""
    if spacing_m <= 0 or join_m < 0:
        raise ValueError("spacing_m must be > 0 and join_m >= 0")
    xy_all, floor_all, chain = _merge([(resample(xy, spacing_m), str(f)) for xy, f in walks], spacing_m * MERGE)
    pairs = [chain] if len(chain) else []
    # nodes of one floor within join_m: crossings, and corridors walked more than once
    for f in np.unique(floor_all):
        ids = np.flatnonzero(floor_all == f)
        if len(ids) > 1 and join_m > 0:
            near = _tree(xy_all[ids]).query_pairs(join_m, output_type="ndarray")
            if len(near):
                pairs.append(ids[near])
    e = np.concatenate(pairs).astype(np.int64) if pairs else np.zeros((0, 2), np.int64)
    w = np.maximum(np.hypot(*(xy_all[e[:, 0]] - xy_all[e[:, 1]]).T), _TINY) if len(e) else np.zeros(0)
    # floors joined by lifts and stairs
    via: dict[tuple[int, int], str] = {}
    groups: dict[tuple[str, str], list[Mapping[str, Any]]] = {}
    for p in places:
        kind = p.get("kind")
        if kind in FLOOR_COST_M:
            groups.setdefault((str(kind), str(p["name"])), []).append(p)
    extra: list[tuple[int, int, float]] = []
    for (kind, _), ps in sorted(groups.items()):
        ends: dict[str, int] = {}
        for p in ps:
            f = str(p["floor"]) if p.get("floor") is not None else None
            on = np.flatnonzero(floor_all == f) if f is not None else np.zeros(0, np.int64)
            if f is None or f in ends or len(on) == 0:
                continue
            d = np.hypot(xy_all[on, 0] - float(p["x"]), xy_all[on, 1] - float(p["y"]))
            if d.min() <= ATTACH_M:
                ends[f] = int(on[np.argmin(d)])
        nodes = sorted(ends.values())
        for a_i, a in enumerate(nodes):
            for b in nodes[a_i + 1 :]:
                extra.append((a, b, FLOOR_COST_M[kind]))
                via.setdefault((a, b), kind)
    if extra:
        e = np.concatenate([e, np.asarray([(a, b) for a, b, _ in extra], np.int64)])
        w = np.concatenate([w, np.asarray([c for _, _, c in extra])])
    # one undirected edge per pair, the shortest
    if len(e):
        e = np.sort(e, axis=1)
        keep = e[:, 0] != e[:, 1]
        e, w = e[keep], w[keep]
        order = np.lexsort((w, e[:, 1], e[:, 0]))
        e, w = e[order], w[order]
        first = np.r_[True, np.any(np.diff(e, axis=0) != 0, axis=1)]
        e, w = e[first], w[first]
    n = len(xy_all)
    i, j = e[:, 0], e[:, 1]
    adj = scipy.sparse.csr_matrix((np.r_[w, w], (np.r_[i, j], np.r_[j, i])), shape=(n, n))
    return WalkGraph(xy_all, floor_all, adj, via, _fingerprint(xy_all, floor_all, i, j, w))


def from_frames(frames: np.ndarray, video_floor: Sequence[str], places: Sequence[Mapping[str, Any]] = ()) -> WalkGraph:
    """A venue generation's frames (structured array with x, y, t, video, as store.load().frames)
    and each modelling video's floor (by the video's index) -> the walk graph: one walk per
    video, its frames in time order."""
    if len(video_floor) == 0:
        raise ValueError("from_frames needs each modelling video's floor (video_floor is empty)")
    walks: list[tuple[np.ndarray, str]] = []
    vids = np.asarray(frames["video"])
    for v in np.unique(vids):
        rows = np.asarray(frames[vids == v])
        rows = rows[np.argsort(rows["t"], kind="stable")]
        xy = np.stack([rows["x"], rows["y"]], axis=1).astype(np.float64)
        floor = video_floor[int(v)] if 0 <= int(v) < len(video_floor) else video_floor[0]
        walks.append((xy, str(floor)))
    return build(walks, places)


def place_key(p: Mapping[str, Any]) -> str:
    """How a place is named in `attach`: its id, or its name when it has no id."""
    return str(p.get("id") or p["name"])


def attach(graph: WalkGraph, places: Sequence[Mapping[str, Any]], max_m: float = ATTACH_M) -> dict[str, int]:
    """Place id (or name when there is no id) -> the nearest node on the place's floor (any floor
    when the place has none); places further than max_m from every such node are left out."""
    out: dict[str, int] = {}
    for p in places:
        f = p.get("floor")
        on = np.flatnonzero(graph.floor == str(f)) if f is not None else np.arange(len(graph.xy))
        if len(on) == 0:
            continue
        d = np.hypot(graph.xy[on, 0] - float(p["x"]), graph.xy[on, 1] - float(p["y"]))
        k = int(np.argmin(d))
        if d[k] <= max_m:
            out[place_key(p)] = int(on[k])
    return out


def pairs_within(a: np.ndarray, b: np.ndarray, r: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(i, j, distance) for every point a[i] within r of b[j]."""
    if len(a) == 0 or len(b) == 0:
        return np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros(0)
    m = cKDTree(a).sparse_distance_matrix(cKDTree(b), r, output_type="coo_matrix")
    return m.row.astype(np.int64), m.col.astype(np.int64), m.data.astype(np.float64)


def csr_spans(indptr: np.ndarray, rows: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The positions of rows' entries in a CSR layout (`indptr`), row after row in their order,
    and how many each row has."""
    lo = indptr[rows]
    count = indptr[rows + 1] - lo
    return np.arange(int(count.sum())) + np.repeat(lo - (np.cumsum(count) - count), count), count


def csr_rows(m: scipy.sparse.csr_matrix, rows: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The entries of some rows of a CSR matrix, as m[rows] holds them: each entry's position in
    `rows`, its column and its value (a gather by the matrix's own arrays: SciPy's row indexing
    builds a matrix, at 10x the cost, for the three arrays read from it)."""
    at, count = csr_spans(m.indptr, rows)
    return np.repeat(np.arange(len(rows)), count), m.indices[at], m.data[at]
