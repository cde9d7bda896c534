"""Tracking while walking: a filter over the walk graph's nodes, fed clip after clip.

An HMM over the nodes of the venue's walk graph (walkgraph.py), run forward: the belief after
each clip, from the evidence up to now. The walkable space *is* the graph (nodes about a metre
apart along the modelling walks), so a belief over its few hundred to few thousand nodes is exact
where particles would sample it, and a look-alike corridor 40 m away keeps what it is owed until
the walk rules it out; each update costs a sparse transition and a sparse emission.

- **Transition**: walking 0-`track_max_mps` along the graph, sharpened by the phone's steps and
  gyroscope turn (motion.py) and by which way the clips say the phone faces.
- **Emission**: each query frame's verified matches near a node, the clip's last second tempered
  by `track_beta` and mixed with `track_outlier`.
- **A second, cautious belief** beside the first: look-alike places (lookalikes.py) cannot be told
  apart by more than the venue's own model can, and poorly matching clips count less.
- **Pose and confidence**: the node whose 1.5 m neighbourhood holds the most belief, placed and
  headed by the clip's matches there; the confidence is the lower of the two beliefs', held below
  "sure" when the clips doubt it (recent clips unsure, a sure clip elsewhere) or the phone is held
  still (no surer than its clip alone).

The state between updates is tracking_state.py's. The model rule by rule, with its settings, is
docs/tracking.md.
"""

from __future__ import annotations

import functools
from collections.abc import Callable, Mapping
from dataclasses import fields, replace
from typing import TYPE_CHECKING, Any

import numpy as np
import scipy.sparse  # type: ignore[import-untyped]

from .aggregate import SPAN_S, SURE, Estimate, reach_m, sequence
from .heading import wrap_deg
from .index import Matches
from .motion import Motion, faces_as_before, parts, sensors_moved, sensors_still, share
from .settings import TrackingSettings
from .tracking_state import ClipAnswer, TrackPose, TrackState, track_confidence
from .walkgraph import csr_rows, csr_spans, pairs_within

if TYPE_CHECKING:
    from .walkgraph import WalkGraph

FACING_S = 0.3  # where the phone faces now: the clip's latest matches
FACING_MARGIN = 0.1  # ... those within this of their frame's best score
PLACE_M = 1.5  # a "place": the nodes within this of a node (the answer's node has the most belief)
NEAR_M = 2.0  # the confidence is P(within this of the truth): the belief within it of the answer
FAR_M = 3.0  # belief this far from the answer is another place (the `ambiguous` rule, the rival)
LIMIT_M = 8.0  # graph distances are kept up to this; a longer gap is walked in several steps
FIT_M = 2.0  # the clip's matches within this of the answer's node place it and give its heading
FORGET_S = 120.0  # after this long without an update, start over
AMBIGUOUS_CAP = 0.45  # the confidence of an ambiguous answer: below the app's "not sure" (0.5)
ALIKE_MAX_NATS = 8.0  # a look-alike this far below (in log-likelihood) can never matter: not kept
# a step counter that counted a step this recently (s) works, and its count of none is a stop:
# kept whatever the clips say (track_zero_steps_m is for a phone that counts nothing while its
# user moves on). Longer than a stop at a door or a junction, shorter than a walk along a corridor.
STEPS_WORK_S = 30.0
# ... counted this many in one update: a walker's second holds one or two, a few seconds' more;
# a phone held steady (or a wheelchair over a threshold) counts the odd false step, one at a time
STEPS_WORK_N = 2


def _clip_times(matches: Matches, times: np.ndarray) -> np.ndarray:
    """A clip's frame times as float64, checked against its matches (one time a query frame)."""
    times = np.asarray(times, np.float64)
    if len(times) != matches.index.shape[0] or len(times) == 0:
        raise ValueError(f"{matches.index.shape[0]} frames of matches need as many frame times, got {len(times)}")
    return times


def _none() -> None:
    return None


def _turned(heading: float | None | Callable[[], float | None], turn: float | None) -> tuple[float, bool] | None:
    """The last answer's heading (or what makes it) plus the gyroscope's turn since, and whether
    the turn was known; None without a heading."""
    h = heading() if callable(heading) else heading
    return None if h is None else ((h + float(turn or 0.0)) % 360.0, turn is not None)


def _heading_of(pose: Callable[[], TrackPose]) -> float | None:
    """The heading a state keeps of its pose (None: the pose did not know it)."""
    p = pose()
    return p.heading if p.heading_known else None


def _compact(m: Matches, use: np.ndarray, pad: int) -> tuple[Matches, np.ndarray]:
    """(Q, k) matches and which to keep -> each frame's kept ones first, in their order, as
    (Q, k') matches (k': the most a frame keeps), the rest padding (venue row `pad`, score 0);
    and the (Q, k') columns they came from."""
    width = max(1, int(use.sum(axis=1).max()))
    at = np.argsort(~use, axis=1, kind="stable")[:, :width]
    kept = np.take_along_axis(use, at, axis=1)
    out = [np.take_along_axis(np.asarray(getattr(m, f.name)), at, axis=1) for f in fields(m)]
    out[0] = np.where(kept, out[0], pad)
    out[2] = np.where(kept, out[2], 0).astype(out[2].dtype)
    return Matches(*out), at


class Tracker:
    """The filter of one walk graph and one venue generation: what can be precomputed is, once."""

    def __init__(
        self,
        graph: WalkGraph,
        venue_xy: np.ndarray,
        venue_floor: np.ndarray,
        conf: Mapping[str, Any],
        alike: Matches | None = None,
    ):
        """venue_xy (V, 2), venue_floor (V,): every venue frame's position and floor (the index's
        rows); conf: the venue's settings (its tracking keys: settings.TrackingSettings);
        alike: look_alikes() of this graph and venue (without it, no place is a look-alike)."""
        self.graph = graph
        self.conf = dict(conf)
        self.n = n = len(graph.xy)
        if n == 0:
            raise ValueError("a walk graph without nodes cannot be tracked on")
        self.ts = ts = TrackingSettings.of(conf)  # checked: OmninavError naming a bad key
        self.beta_ref = None if ts.track_beta_ref is None else float(ts.track_beta_ref)  # (beta; None: none)
        self.recent_s = float(ts.track_recent_s)
        self.recent_min = None if ts.track_recent_min is None else float(ts.track_recent_min)
        self.doubt_cap = float(ts.track_doubt_cap)
        self.clip_tie = None if ts.track_clip_tie is None else float(ts.track_clip_tie)
        self.zero_steps_m = None if ts.track_zero_steps_m is None else float(ts.track_zero_steps_m)
        self.xy = np.asarray(graph.xy, np.float64)
        self.floor = np.asarray(graph.floor).astype(str)
        vxy = np.asarray(venue_xy, np.float64)
        vfl = np.asarray(venue_floor).astype(str)
        self.venue_xy = vxy
        self.venue_floor = vfl
        radius = float(ts.track_radius_m)
        # venue frame -> nodes within radius (same floor); node -> nodes within PLACE_M / NEAR_M
        fr, fc, fd = self._by_floor(vxy, vfl, self.xy, self.floor, radius)
        # data: the distance + 1 (an explicit 0 could be dropped by a later sparse operation)
        self.f2n = scipy.sparse.csr_matrix((fd + 1.0, (fr, fc)), shape=(len(vxy), n))
        pr, pc, _ = self._by_floor(self.xy, self.floor, self.xy, self.floor, PLACE_M)
        self.place = scipy.sparse.csr_matrix((np.ones(len(pr)), (pr, pc)), shape=(n, n))
        # graph distances up to LIMIT_M (chunked: never an N x N dense array)
        rows, cols, dist = [], [], []
        for s in range(0, n, 256):
            src = np.arange(s, min(n, s + 256))
            d = graph.distances(src, limit=LIMIT_M)
            i, j = np.nonzero(np.isfinite(d))
            rows.append(src[i])
            cols.append(j)
            dist.append(d[i, j])
        # a lift or stairs (graph.via) joins two floors: an entry of its own (distance -1), walked
        # with probability track_floor_change an update (unless its ends are within LIMIT_M anyway)
        if graph.via:
            ends = np.array(list(graph.via), np.int64).reshape(-1, 2)
            have = np.isin(ends[:, 0] * n + ends[:, 1], np.concatenate(rows) * n + np.concatenate(cols))
            for a, b in ends[~have]:
                rows.append(np.array([a, b]))
                cols.append(np.array([b, a]))
                dist.append(np.array([-1.0, -1.0]))
        r = np.concatenate(rows)
        order = np.lexsort((np.concatenate(cols), r))
        self.t_row = r[order]
        self.t_col = np.concatenate(cols)[order]
        self.t_dist = np.concatenate(dist)[order]
        self.t_indptr = np.r_[0, np.cumsum(np.bincount(self.t_row, minlength=n))]
        self.t_dx = self.xy[self.t_col, 0] - self.xy[self.t_row, 0]
        self.t_dy = self.xy[self.t_col, 1] - self.xy[self.t_row, 1]
        # the entry of the edge the other way (distances are symmetric, so every edge has one)
        # (entries are in (row, col) order; the k-th in (col, row) order is the k-th one reversed)
        self.t_rev = np.lexsort((self.t_row, self.t_col))
        self.t_count = np.diff(self.t_indptr)  # entries a node (at least its own, distance 0)
        if self.t_count.min() < 1:  # (graph.distances gives every node itself: never seen)
            raise ValueError("a walk graph node without an entry of its own in the transition")
        self.alike_a, self.alike_b, self.alike_cost, self.alike_starts = self._alikes(alike)

    def _alikes(self, alike: Matches | None) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Look-alike pairs (a, b) sorted by b, their cost in log-likelihood (track_alike_cost *
        (1 - score), the best score of b's frames among a's node frame's matches, either way
        round: symmetric), and where each b's run starts (for one reduceat per update)."""
        none = np.zeros(0, np.int64)
        cost = self.ts.track_alike_cost
        if alike is None or cost is None:
            return none, none, np.zeros(0), none
        if float(cost) < 0 or len(alike.index) != self.n:
            raise ValueError(f"look-alikes need a cost >= 0 and {self.n} nodes' matches (of this graph)")
        k = alike.index.shape[1]
        # a matched frame is its nearest node's look-alike only (not every node within reach: the
        # score says how alike *that* spot is, and a step away the panorama is another one)
        node = self.graph.snap(self.venue_xy, self.venue_floor)  # every venue frame's, once
        near = np.hypot(*(self.xy[node] - self.venue_xy).T) <= float(self.ts.track_radius_m)
        rows = np.asarray(alike.index).ravel()
        ok = near[rows]
        r = np.flatnonzero(ok)
        a, b = r // k, node[rows[ok]]
        sc = np.clip(np.asarray(alike.score, np.float64).ravel()[r], 0.0, 1.0)
        far = (self.floor[a] != self.floor[b]) | (
            np.hypot(*(self.xy[a] - self.xy[b]).T) >= FAR_M
        )  # nearer is the same place: the transition's business
        a, b, c = a[far], b[far], float(cost) * (1.0 - sc[far])
        use = c <= ALIKE_MAX_NATS
        if not use.any():
            return none, none, np.zeros(0), none
        # each pair once, either way round, at its smallest cost; then sorted by b (b-major keys)
        key = np.r_[b[use] * self.n + a[use], a[use] * self.n + b[use]]
        cc = np.r_[c[use], c[use]]
        order = np.argsort(key, kind="stable")
        key, cc = key[order], cc[order]
        first = np.flatnonzero(np.r_[True, key[1:] != key[:-1]])
        cost_min = np.minimum.reduceat(cc, first)
        b2, a2 = np.divmod(key[first], self.n)
        starts = np.flatnonzero(np.r_[True, b2[1:] != b2[:-1]])
        # (int32 / float32: a big venue's pairs are millions, and a worker keeps a Tracker a revision)
        return a2.astype(np.int32), b2.astype(np.int32), cost_min.astype(np.float32), starts

    def with_alikes(self, log_lik: np.ndarray) -> np.ndarray:
        """(N,) log-likelihoods -> each node's raised to its look-alikes' less their cost."""
        if len(self.alike_a) == 0:
            return log_lik
        floor = np.take(log_lik, self.alike_a)
        floor -= self.alike_cost
        best = np.maximum.reduceat(floor, self.alike_starts)
        out = log_lik.copy()
        nodes = self.alike_b[self.alike_starts]
        out[nodes] = np.maximum(out[nodes], best)
        return out

    @staticmethod
    def _by_floor(
        a: np.ndarray, fa: np.ndarray, b: np.ndarray, fb: np.ndarray, r: float
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        out: list[tuple[np.ndarray, np.ndarray, np.ndarray]] = []
        for f in np.unique(fa):
            ia, ib = np.flatnonzero(fa == f), np.flatnonzero(fb == f)
            i, j, d = pairs_within(a[ia], b[ib], r)
            out.append((ia[i], ib[j], d))
        if not out:
            return np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros(0)
        return tuple(np.concatenate(x) for x in zip(*out, strict=True))  # type: ignore[return-value]

    # ---- the three steps of an update ------------------------------------------------------------
    def _transition(
        self,
        belief: np.ndarray,
        dt: float,
        steps: int | None = None,
        facing: np.ndarray | None = None,
        turn: tuple[np.ndarray, float] | None = None,
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """belief (N,) or (N, B) (B beliefs moved alike) -> the belief dt seconds of walking later
        (steps: the phone's step count);
        also the last step's edge weights and the belief it started from (for `_predicted`).

        `facing` (N,): where the clip says the phone faces at each node (NaN: it does not say);
        a move that ends walking backwards from it by more than a metre counts
        `track_backward` as much (people walk the way they hold the phone), which keeps a walk
        along a corridor of repeating doors from sliding back by one door. `turn`: (where the
        last clip said the phone faced at each node, the gyroscope's turn since): a move i -> j
        whose facing changed by other than the turn counts less (by how much more than
        `track_turn_gate_deg` it is off), hypothesis by hypothesis."""
        vmax = float(self.ts.track_max_mps)
        slack = float(self.ts.track_slack_m)
        step_m = float(self.ts.track_step_m)
        dt = max(0.0, dt)
        parts = max(1, int(np.ceil((vmax * dt + slack) / (LIMIT_M - 1.0))))
        walked = None if steps is None else max(0, steps) * step_m / parts
        d = self.t_dist
        reach = vmax * dt / parts + slack
        # (the E-long arrays are made in place: each temporary of them costs as much as the arithmetic)
        k = np.subtract(d, reach)
        np.maximum(k, 0.0, out=k)
        k *= k
        k *= -0.5
        np.exp(k, out=k)  # 1 within reach, falling off beyond
        if walked is not None:  # the distance walked is about known (a stride varies ~10 %, a step is missed or
            # added now and then): a move of about that length counts up to 1 / (1 - trust) times as
            # much as any other within reach. The steps sharpen, never forbid: a phone that counts
            # none while its user walks (held steady, a slow walker, a wheelchair, a stalled sensor
            # feed) or a walker who turned back (more walked than the graph distance) keeps the
            # flat part, so that clips that agree win within a few updates (one clip moves the odds
            # by up to 1 / track_outlier, more than the steps' 1 / (1 - trust))
            sig = 0.12 * walked + float(self.ts.track_step_sigma_m)
            trust = float(self.ts.track_step_trust)
            g = np.subtract(d, walked)
            g /= sig
            g *= g
            g *= -0.5
            np.exp(g, out=g)
            g *= trust
            g += 1 - trust
            k *= g
        np.maximum(k, 1e-12, out=k)
        k[self._via] = float(self.ts.track_floor_change)
        rowsum = np.add.reduceat(k, self.t_indptr[:-1])
        k /= np.repeat(rowsum, self.t_count)  # (entries in row order: a row's sum repeated, not gathered)
        kk = k
        # the clip's facing, at the end of the walk, where it says one: the entries into the nodes
        # that have one (a few hundred of the tens of thousands)
        e = np.zeros(0, np.int64) if facing is None else self._into(np.flatnonzero(np.isfinite(facing)))
        if facing is not None and len(e):
            h = np.deg2rad(facing)
            fs, fc = np.sin(h)[self.t_col[e]], np.cos(h)[self.t_col[e]]
            fwd = self.t_dx[e] * fs - self.t_dy[e] * fc
            back = float(self.ts.track_backward) ** (parts == 1)
            kk = k.copy()
            sel = e[fwd < -1.0 * parts]
            kk[sel] = k[sel] * back
            if turn is not None:
                b = np.deg2rad(turn[0] + turn[1])
                rows = self.t_row[e]
                cos_off = fc * np.cos(b)[rows] + fs * np.sin(b)[rows]
                gate = float(self.ts.track_turn_gate_deg)
                bad = np.flatnonzero(cos_off < np.cos(np.deg2rad(gate)))  # NaN: no change
                off = np.degrees(np.arccos(np.clip(cos_off[bad], -1.0, 1.0)))
                kk[e[bad]] *= np.maximum(np.exp(-0.5 * ((off - gate) / 20.0) ** 2), 0.1)  # soft, floored
        p = belief
        start = p
        for i in range(parts):
            start = p
            p = self._walk(kk if i == parts - 1 else k, p)
        return p, kk, start

    @functools.cached_property
    def _via(self) -> np.ndarray:
        """The entries of lifts and stairs (distance -1): walked with track_floor_change."""
        return np.flatnonzero(self.t_dist < 0)

    def _into(self, nodes: np.ndarray) -> np.ndarray:
        """The entries (in (row, col) order) whose column is one of `nodes`: the reversed entries
        of their rows (t_rev), as _walk reads them."""
        into: np.ndarray = self.t_rev[csr_spans(self.t_indptr, nodes)[0]]
        return into

    def _walk(self, w: np.ndarray, p: np.ndarray) -> np.ndarray:
        """One step of the transition: edge weights w (E,) (row i -> column j, in (row, col)
        order) and belief p (N,) or (N, B) -> sum_i w[i -> j] p[i] (the transition matrix's
        transpose times p), summed per end node without building the sparse matrix a step."""
        # the flow along each entry read in column order: t_rev[m] is the m-th entry in (col, row)
        # order, the m-th in (row, col) order reversed, so its row is t_col[m] and the column's
        # entries lie where the row's do (every node has an entry of its own, distance 0: none empty)
        # (B beliefs as B rows: a product broadcast over a 2-wide last axis costs 10x one over E)
        w_in = np.take(w, self.t_rev)
        flow = np.take(np.ascontiguousarray(p.T), self.t_col, axis=-1)
        flow *= w_in
        return np.add.reduceat(flow, self.t_indptr[:-1], axis=-1).T

    def _predicted(
        self, nodes: np.ndarray, kk: np.ndarray, start: np.ndarray, turn: tuple[np.ndarray, float]
    ) -> np.ndarray:
        """The gyroscope's heading at `nodes`: the facing the last clip gave each one's likeliest
        predecessor (by the last step's flow, kk x start), plus the turn; NaN where unknown."""
        out = np.full(len(nodes), np.nan)
        for o, j in enumerate(nodes):
            e = np.arange(self.t_indptr[j], self.t_indptr[j + 1])  # j -> i; t_rev: i -> j
            if len(e):
                i = self.t_col[e][int(np.argmax(kk[self.t_rev[e]] * start[self.t_col[e]]))]
                out[o] = (turn[0][i] + turn[1]) % 360.0
        return out

    def emission(self, matches: Matches, times: np.ndarray, t_now: float) -> tuple[np.ndarray, np.ndarray]:
        """(N,) mean over the clip's last second of each frame's best verified score near the
        node, and (N,) the heading of the best match near it in the clip's last FACING_S (NaN
        where there is none)."""
        times = np.asarray(times, np.float64)
        keep = np.flatnonzero(times > t_now - SPAN_S - 1e-6)
        if len(keep) == 0:
            keep = np.array([len(times) - 1])
        idx = matches.index[keep]
        sc = np.maximum(np.asarray(matches.score[keep], np.float64), 0.0)
        hd = np.asarray(matches.heading[keep], np.float64)
        q, k = idx.shape
        bg = sc.min(axis=1)  # a node that none of a frame's candidates is near: as its worst kept
        b = np.repeat(bg[:, None], self.n, axis=1)
        r, nodes, dist = csr_rows(self.f2n, idx.ravel())
        # a match counts for a node less the further it is from it: the emission peaks where it is
        val = sc.ravel()[r] - float(self.ts.track_dist_penalty) * (dist - 1.0)
        np.maximum.at(b, (r // k, nodes), val)
        # the facing: the best-scoring match near each node among the latest frames
        facing = np.full(self.n, np.nan)
        # (only matches about as good as the frame's best: a poor one near a node says little)
        late = (times[keep][r // k] > t_now - FACING_S - 1e-6) & (val >= sc.max(axis=1)[r // k] - FACING_MARGIN)
        if late.any():
            col, v, h = nodes[late], val[late], hd.ravel()[r[late]]
            order = np.lexsort((v, col))
            last = np.r_[col[order][1:] != col[order][:-1], True]
            facing[col[order][last]] = h[order][last]
        return np.asarray(b.mean(axis=0)), facing

    def beta(self, best: float) -> float:
        """The second belief's evidence weight for a clip whose best node scores `best`:
        track_beta, times (1 - track_beta_ref) / (1 - best) below track_beta_ref (the scores of
        a clip that matches poorly differ by its conditions as much as by place)."""
        beta = float(self.ts.track_beta)
        if self.beta_ref is None or best >= self.beta_ref:
            return beta
        return beta * (1.0 - self.beta_ref) / max(1.0 - best, 1e-6)

    def update(
        self,
        state: TrackState | None,
        matches: Matches,
        times: np.ndarray,
        t_now: float,
        motion: Motion | None = None,
        clip: ClipAnswer | None = None,
    ) -> tuple[TrackState, TrackPose]:
        """One clip's matches (Q, k) and frame times (last == t_now) -> the new state and pose.
        state None (or another graph's, or too old) -> start over from a uniform belief.
        `clip`: what the clip answers alone (its confidence, aggregate.confidence, and place), for
        the rules of the clip's own answer (None: they do not apply to this update, and the recent
        clips' mean starts over)."""
        state, answer = self._step(state, matches, times, t_now, motion, clip)
        pose = answer()
        return replace(state, heading=_heading_of(answer)), pose

    def _step(
        self,
        state: TrackState | None,
        matches: Matches,
        times: np.ndarray,
        t_now: float,
        motion: Motion | None = None,
        clip: ClipAnswer | None = None,
        heading: Callable[[], float | None] | None = None,
    ) -> tuple[TrackState, Callable[[], TrackPose]]:
        """update(), the answer left to be made: the new state (its `heading` not set) and what
        makes the pose, once, when called. A part of a clip that is not its last (update_clip)
        needs no answer of its own: the next part reads only its heading, and only where no match
        of its own is near its answer (_fit). `heading`: the state's heading, where it was left to
        be made (else state.heading)."""
        motion = motion or Motion()
        times = _clip_times(matches, times)
        fresh = state is None or not self.goes_on(state, t_now)
        uniform = np.full(self.n, 1.0 / self.n)
        e, facing = self.emission(matches, times, t_now)
        # the node the clip is best at; None for a blank clip (no match scored: every node alike,
        # and argmax would name node 0, a place the clip never said)
        best: int | None = int(np.argmax(e)) if float(e.max() - e.min()) > 1e-9 else None
        gyro = None
        # the last answer's heading plus the gyroscope's turn since (True), or alone (False: a
        # stand-in, not a heading the answer may be sure of); made when the answer reads it
        last: Callable[[], tuple[float, bool] | None] = _none

        # the cautious belief runs beside the belief (where the venue has look-alikes, or the
        # clips' evidence is tempered by how well they match)
        twin = len(self.alike_a) > 0 or self.beta_ref is not None
        prior_a = uniform if twin else None
        if fresh or state is None:
            prior, updates = uniform, 0
        else:
            turn = None
            if motion.turn_deg is not None and state.facing is not None and len(state.facing) == self.n:
                turn = (state.facing, float(motion.turn_deg))
            eps = float(self.ts.track_uniform)
            both = state.belief
            if twin:  # both beliefs walk alike: one pass (a state saved without it starts it as the belief)
                a = state.alike if state.alike is not None and len(state.alike) == self.n else state.belief
                both = np.stack([state.belief, a], axis=1)
            # (a part of a longer clip can get none of a request's one or two steps by rounding,
            # `share`: kept as a stop, as a walker that slow about is)
            steps = None if self.zero_read_as_none(motion, state.best, best, state.stepped, t_now) else motion.steps
            moved, kk, start = self._transition(both, t_now - state.t, steps, facing, turn)
            if twin:
                moved, prior_a, start = moved[:, 0], moved[:, 1], start[:, 0]
                prior_a = (1 - eps) * prior_a / max(prior_a.sum(), 1e-300) + eps * uniform
            prior = (1 - eps) * moved / max(moved.sum(), 1e-300) + eps * uniform
            updates = state.updates
            if turn is not None:  # where the phone faces now, by the gyroscope, per hypothesis
                gyro = (kk, start, turn)
            last = functools.partial(_turned, state.heading if heading is None else heading, motion.turn_deg)
        # one clip can be an outlier (people in the way, a turn, a look-alike): it moves the odds
        # between two places by at most 1 / track_outlier
        rho = float(self.ts.track_outlier)
        # held still: the clip is best at the node the last one was (a wheelchair, or a phone that
        # counts no steps while its user walks, reaches other nodes' views), and the sensors
        # counted no step and little turn, or, where they do not say it moved, the clip faces as
        # the last one did there: "A phone held still" above
        held = False
        still_cap = self.ts.track_still_cap
        if still_cap and not fresh and state is not None and best is not None and state.best == best:
            # the sensors say so; or, where they do not say it moved (none, or none that
            # answered), the clip does: best where the last was and facing as it did there
            seen = self.ts.track_still_seen and not sensors_moved(motion)
            held = sensors_still(motion) or bool(seen and faces_as_before(facing, state.facing, best))
        log_lik = float(self.ts.track_beta) * (e - e.max())
        post = prior * ((1 - rho) * np.exp(log_lik) + rho)
        post /= post.sum()
        post_a = None
        if prior_a is not None:
            # the cautious belief weighs a clip that matches poorly less (beta), and then the
            # clips' differences between look-alikes count once; a fresh start's first clip is
            # not floored (the look-alike floor is for clips that repeat one another)
            cautious = self.beta(float(e.max())) * (e - e.max())
            if not (fresh or state is None):
                cautious = self.with_alikes(cautious)
            post_a = prior_a * ((1 - rho) * np.exp(cautious) + rho)
            post_a /= post_a.sum()
        # (an update without the clip's confidence, or with one that is no number, leaves the
        # rule out and starts the mean over at the next: a mean carried across it would be stale)
        recent = None
        if clip is not None and np.isfinite(clip.confidence):
            ago, dt = (None, 0.0) if fresh or state is None else (state.recent, t_now - state.t)
            recent = self.recent(ago, float(clip.confidence), dt)
        made: list[TrackPose] = []

        def answer() -> TrackPose:
            if not made:
                pose = self._answer(post, matches, times, t_now, gyro, updates + 1, last, post_a, clip, recent, held)
                made.append(replace(pose, restarted=bool(fresh)))
            return made[0]

        stepped = None if fresh or state is None else state.stepped
        if (motion.steps or 0) >= STEPS_WORK_N:
            stepped = float(t_now)
        state = TrackState(float(t_now), post, self.graph.key, updates + 1, None, facing, post_a, recent, best, stepped)
        return state, answer

    def _answer(
        self,
        post: np.ndarray,
        matches: Matches,
        times: np.ndarray,
        t_now: float,
        gyro: tuple[np.ndarray, np.ndarray, tuple[np.ndarray, float]] | None,
        updates: int,
        last: Callable[[], tuple[float, bool] | None],
        post_a: np.ndarray | None,
        clip: ClipAnswer | None,
        recent: float | None,
        held: bool,
    ) -> TrackPose:
        """The pose of an update's beliefs, and the rules of the clip's own answer (`recent`: the
        recent clips' mean confidence after it; `held`: the phone held still)."""
        pose = self.pose(post, matches, times, t_now, gyro, updates, last, post_a)
        if recent is None or clip is None:
            return pose
        doubt = self.recent_min is not None and recent < self.recent_min
        split = clip.confidence >= SURE and self.elsewhere(pose, clip)
        # where the walk is itself split between the two places, its small differences between
        # look-alikes are the weaker evidence, and the sure clip of the moment decides
        if split:
            node = self.tie_node(post, pose.node, clip)
            if node is not None:
                pose = self.pose(post, matches, times, t_now, gyro, updates, last, post_a, node)
        if doubt or split:  # two calibrated sources disagree: not sure, wherever the answer is
            pose = replace(pose, confidence=min(pose.confidence, self.doubt_cap))
        if held:  # no surer than the clip alone, as a locate says it
            pose = replace(pose, confidence=min(pose.confidence, float(clip.said)))
        return pose

    def goes_on(self, state: TrackState, t_now: float) -> bool:
        """Whether a belief can go on from `state` at t_now (else it starts over): a state of this
        graph, at most a second ahead of t_now (a phone's clock) and at most FORGET_S behind it."""
        return state.graph_key == self.graph.key and len(state.belief) == self.n and -1.0 <= t_now - state.t <= FORGET_S

    def update_clip(
        self,
        state: TrackState | None,
        matches: Matches,
        times: np.ndarray,
        t_now: float,
        motion: Motion | None,
        answer: Callable[[Matches, np.ndarray], ClipAnswer] | None = None,
    ) -> tuple[TrackState, TrackPose]:
        """A clip of any length (times end at t_now) -> `update` once per part of it (`parts`:
        about a second each), the phone's motion since the last update shared among them (`share`);
        `answer(matches, times)`: what each part answers alone (None: the rules of the clip's own
        answer do not apply).
        -> the state and pose after the last part (`restarted`: whether any part started the
        belief over)."""
        times = _clip_times(matches, times)
        times = times - times[-1] + float(t_now)  # the clip ends at t_now
        cut = parts(times)
        if state is not None:
            # parts that end by the state's time were seen already (a phone's clock a little
            # behind): each joins the part after it, so that the filter never goes back in time
            while len(cut) > 1 and times[cut[0][-1]] <= state.t:
                cut = [np.concatenate(cut[:2]), *cut[2:]]
        ends = [float(times[c[-1]]) for c in cut]
        if state is not None and self.goes_on(state, ends[0]):
            moves = share(motion or Motion(), list(np.diff(np.r_[state.t, ends])))
        else:  # the belief starts over: the phone's reading is of the walk before, not of these seconds
            moves = [Motion()] * len(cut)
        pose, restarted, heading = None, False, None
        for i, (c, end, mv) in enumerate(zip(cut, ends, moves, strict=True)):
            m = matches.rows(c)
            # each part's own answer: the rules of the clip's own answer were chosen on 1 s clips'
            # (the whole clip's, surer for being longer, was tried: it did no better on the
            # held-out families; docs/benchlog.md, "Filming throughout")
            own = None if answer is None else answer(m, times[c])
            restarted = restarted or state is None or not self.goes_on(state, end)
            state, made = self._step(state, m, times[c], end, mv, own, heading)
            if i < len(cut) - 1:  # a part's pose is made only if the next part reads its heading
                heading = functools.partial(_heading_of, made)
            else:
                pose = made()
                state = replace(state, heading=_heading_of(made))
        assert state is not None and pose is not None
        # started over, the parts were given no motion (it was of the walk before); that the
        # counter counted is still news: it works
        counted = 0 if motion is None else motion.steps or 0
        if restarted and state.stepped is None and counted >= STEPS_WORK_N:
            state = replace(state, stepped=float(ends[-1]))
        return state, replace(pose, restarted=restarted)

    def clip_floor(self, clip: ClipAnswer) -> str | None:
        """The floor of the clip's own answer (its venue frame's); None when its place was not
        given, or not as a finite point and a frame of this venue."""
        if clip.x is None or clip.y is None or clip.row is None or not 0 <= clip.row < len(self.venue_floor):
            return None
        return str(self.venue_floor[clip.row]) if np.isfinite(clip.x) and np.isfinite(clip.y) else None

    def elsewhere(self, pose: TrackPose, clip: ClipAnswer) -> bool:
        """Whether the clip's own answer is another place than the pose: FAR_M or more from it,
        or on another floor (False when the clip's place was not given)."""
        floor = self.clip_floor(clip)
        if floor is None or clip.x is None or clip.y is None:
            return False
        return floor != pose.floor or bool(np.hypot(clip.x - pose.x, clip.y - pose.y) >= FAR_M)

    def zero_read_as_none(
        self,
        motion: Motion,
        before: int | None,
        best: int | None,
        stepped: float | None = None,
        t_now: float = 0.0,
    ) -> bool:
        """Whether a count of no steps says nothing (`track_zero_steps_m`): the clip is best that
        far from where the last clip was best, on the same floor, and the phone's counter has not
        shown it works in the last STEPS_WORK_S (`stepped`: when it last counted STEPS_WORK_N or
        more steps in one update). A phone held steady, or a
        wheelchair, counts no steps while its user moves on; one whose counter counted steps a
        moment ago is standing (at a stop in a corridor of identical doors its clip is now and
        then best a door on). Not on a blank clip (best nowhere), nor across floors: a lift's ride
        is counted no steps, truly, and its floor-change weight is only worth what the other
        moves are (a zero read as none would thin it)."""
        if motion.steps != 0 or self.zero_steps_m is None or best is None or before is None:
            return False
        if stepped is not None and t_now - stepped <= STEPS_WORK_S:
            return False
        if not 0 <= before < self.n or self.floor[best] != self.floor[before]:
            return False
        return bool(np.hypot(*(self.xy[best] - self.xy[before])) >= self.zero_steps_m)

    def tie_node(self, p: np.ndarray, node: int, clip: ClipAnswer) -> int | None:
        """The node of the clip's own place, when the belief p (N,) holds its neighbourhood at
        least `track_clip_tie` times as likely as the answer's node's (None: not so, or off).

        A sure clip elsewhere that the walk has all but ruled out (a look-alike 20 m away) leaves
        the answer where it is; one the walk itself finds about as likely (the next door of a
        corridor of identical doors, where the belief is split) is the fresher evidence of the
        two, and breaks the tie."""
        floor = self.clip_floor(clip)
        if self.clip_tie is None or floor is None or clip.x is None or clip.y is None:
            return None
        # the node nearest the clip's place on its floor (a pass over the nodes: no tree built a
        # call); none within FIT_M (a place nobody walked): the clip's place is no node's
        d = np.where(self.floor == floor, np.hypot(self.xy[:, 0] - clip.x, self.xy[:, 1] - clip.y), np.inf)
        c = int(np.argmin(d))
        if not d[c] <= FIT_M:
            return None
        there, here = (float(np.asarray(self.place[i] @ p).ravel()[0]) for i in (c, node))
        return c if c != node and there >= self.clip_tie * here else None

    def recent(self, before: float | None, clip: float, dt: float) -> float:
        """The recent clips' mean confidence after a clip of confidence `clip`, `dt` s after the
        last: an exponential mean over about track_recent_s seconds (the same whether the phone
        asks every second or every few), started by the first clip."""
        clip = min(max(clip, 0.0), 1.0)
        if before is None:
            return clip
        a = 1.0 - float(np.exp(-max(dt, 0.0) / self.recent_s))
        return before + a * (clip - before)

    def pose(
        self,
        p: np.ndarray,
        matches: Matches,
        times: np.ndarray,
        t_now: float,
        gyro: tuple[np.ndarray, np.ndarray, tuple[np.ndarray, float]] | None = None,
        updates: int = 1,
        last: Callable[[], tuple[float, bool] | None] = _none,
        alike: np.ndarray | None = None,
        node: int | None = None,
    ) -> TrackPose:
        """The belief p (N,) after `updates` clips -> the answer. `gyro`: the last transition's
        weights, the belief it started from and (the last clip's facing per node, the turn), for
        the gyroscope's heading at the answer (_predicted); `last`: the last answer's heading plus
        the gyroscope's turn since, and whether the turn was known (the heading when the clip's
        matches do not give one there); `alike`: the second (cautious) belief, whose own confidence at
        the answer caps the answer's (and whose split makes it ambiguous); `node`: the answer's
        node (None: the one whose neighbourhood holds the most belief)."""
        if node is None:
            node = int(np.argmax(np.asarray(self.place @ p)))
        on = self.floor == self.floor[node]
        d = np.where(on, np.hypot(self.xy[:, 0] - self.xy[node, 0], self.xy[:, 1] - self.xy[node, 1]), np.inf)
        mass = float(p[d <= NEAR_M].sum())
        far = float(p[d >= FAR_M].sum())
        # the cautious belief at the same answer: as sure, once the clips' differences between
        # places the venue's model finds alike are set aside and poorly matching clips tempered?
        alike_mass = None if alike is None else float(alike[d <= NEAR_M].sum())
        alike_far = None if alike is None else float(alike[d >= FAR_M].sum())
        guess = None
        if gyro is not None:  # the gyroscope's heading here: of the nearest node that has one
            near = np.flatnonzero(d <= FIT_M)
            near = near[np.argsort(d[near], kind="stable")]
            pred = self._predicted(near, *gyro)
            ok = np.flatnonzero(np.isfinite(pred))
            if len(ok):
                guess = float(pred[ok[0]])
        x, y, h, known = self._fit(node, matches, times, t_now, guess, last)
        dx = np.where(on, np.hypot(self.xy[:, 0] - x, self.xy[:, 1] - y), 50.0)
        spread = float(np.sqrt((p * np.minimum(dx, 50.0) ** 2).sum()))
        ambiguous = max(far, alike_far or 0.0) >= float(self.ts.track_ambiguous)
        pose = TrackPose(x, y, str(self.floor[node]), h, 0.0, node, ambiguous, spread, mass, far, updates, known)
        pose = replace(pose, alike_mass=alike_mass, alike_far=alike_far)
        c = track_confidence(pose, self.conf)
        if alike_mass is not None and alike_far is not None:
            c = min(c, track_confidence(replace(pose, mass=alike_mass, far=alike_far), self.conf))
        if ambiguous or not known:  # "not sure": of the place, or of which way the phone faces
            c = min(c, AMBIGUOUS_CAP)
        return replace(pose, confidence=c)

    @functools.cached_property
    def _xy_pad(self) -> np.ndarray:
        """venue_xy and a row of NaN after it: the place of _compact's padding (no pair with it is
        within reach or facing, so it supports nothing and nothing supports it)."""
        return np.vstack([self.venue_xy, np.full((1, 2), np.nan)])

    def _fit(
        self,
        node: int,
        matches: Matches,
        times: np.ndarray,
        t_now: float,
        predicted: float | None,
        last: Callable[[], tuple[float, bool] | None] = _none,
    ) -> tuple[float, float, float, bool]:
        """Position and heading at t_now, and whether the heading is known: aggregate.sequence on
        the clip's matches within FIT_M of `node` only (those facing within the gate of the
        gyroscope's prediction, when it has one and some do): the clip's own answer, confined to
        the filter's place. Without a match there: the node, and the gyroscope's heading
        (`predicted`, else `last`: the last answer's plus the turn); with neither, the heading is
        unknown (False: the answer is "not sure"; the last answer's heading stands in, never a
        made-up 0° unless there is none)."""
        nx, ny = self.xy[node]
        keep = np.flatnonzero(times > t_now - SPAN_S - 1e-6)
        m = matches.rows(keep)
        pos = self.venue_xy[m.index]  # (Q, k, 2)
        dist = np.hypot(pos[..., 0] - nx, pos[..., 1] - ny)
        near = dist <= FIT_M
        if not (near & (m.score > 0)).any():
            if predicted is not None:
                return float(nx), float(ny), float(predicted % 360.0), True
            got = last()
            h, known = got if got is not None else (0.0, False)
            return float(nx), float(ny), float(h % 360.0), known
        # Only the matches near the node support (the others' scores are set to 0), so a match
        # further than FIT_M + the clip's reach from it is a hypothesis that nothing supports: it
        # never wins, and the fit is the same without it (a metre's margin on the reach). Each
        # frame's other matches, in their order, are what aggregate.sequence reads: a quarter of
        # its work where half a frame's matches are elsewhere (look-alikes).
        span = float(np.ptp(times[keep]))
        m, at = _compact(m, dist <= FIT_M + float(reach_m(np.array(span), self.conf)) + 1.0, len(self.venue_xy))
        near = np.take_along_axis(near, at, axis=1) & (m.index < len(self.venue_xy))

        def fit(use: np.ndarray) -> Estimate:
            masked = Matches(m.index, m.coarse, np.where(use, m.score, 0.0).astype(np.float32), m.heading)
            return sequence(masked, self._xy_pad, times[keep], self.conf)

        e = fit(near)
        if predicted is not None:  # facing away from the gyroscope's heading: its matches, if any
            gate = float(self.ts.track_turn_gate_deg)
            ok = near & (np.abs(wrap_deg(m.heading - predicted)) <= gate)
            if abs(wrap_deg(e.heading - predicted)) > gate and (ok & (m.score > 0)).any():
                e = fit(ok)
        x, y = e.x, e.y
        dd = float(np.hypot(x - nx, y - ny))
        if dd > FIT_M:  # never further from the node than its neighbourhood
            x, y = nx + (x - nx) * FIT_M / dd, ny + (y - ny) * FIT_M / dd
        return float(x), float(y), float(e.heading % 360.0), True
