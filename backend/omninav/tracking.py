"""Tracking while walking: a filter over the walk graph's nodes, fed clip after clip.

An HMM over the nodes of the venue's walk graph (walkgraph.py), run forward (the belief after
each clip; no smoothing: the answer is the pose now, from the evidence up to now). Why an HMM and
not a particle filter: the walkable space *is* the graph (nodes ~1 m apart along the modelling
walks), so a belief over its few hundred to few thousand nodes is exact where particles would be a
sample of it. Every node keeps its probability, so a look-alike corridor 40 m away keeps what it
is owed until the walk rules it out: a particle filter loses such a mode when no particle happens
to sit there. And the per-update cost is fixed and small (a sparse transition and a sparse
emission), with a state of a few hundred bytes (at most ~21 KB) that a server can keep per phone.

- **Transition** (walking): from node i to node j in dt seconds with probability by their graph
  distance d: any d up to `track_max_mps` * dt + `track_slack_m` (0-1.8 m/s; a stop is d = 0),
  falling off beyond. With the phone's step count the distance walked is about steps *
  `track_step_m`: a d near it counts up to 1 / (1 - `track_step_trust`) times as much as any other
  d within reach. The steps sharpen, never forbid: a count that is wrong (a phone held steady, a
  slow walker or a wheelchair counting no steps, a stalled sensor feed; a person who turned back
  walked more than d) costs a few answers, since clips that agree win against it (one clip moves
  the odds by up to 1 / `track_outlier`, more). A count of none while the clip is best
  `track_zero_steps_m` or more from where the last clip was best is read as no count at all: the
  phone is held steady, or rolls, while its user moves on (each such zero pulled the belief back
  towards standing still, and a walk fell behind by a door or two; chosen on the tuning families'
  walks, docs/benchlog.md). A phone whose counter counted STEPS_WORK_N steps in one update
  within the last STEPS_WORK_S works, and keeps its zeros: it is standing (at a stop in a
  corridor of identical doors its clip is now and then best a door on, and dropping those zeros
  cost answers there). A blank clip (best nowhere) and a change of floor (a lift's ride counts
  no steps, truly) keep the zero too. A little of a uniform belief is mixed in at every update
  (`track_uniform`), so that a wrong lock-in is undone by evidence, never by luck.
- **Emission** (the clip): each query frame's verified candidate matches (index.Matches, with
  scores), the best one within `track_radius_m` of a node counting for that node; a node without
  one counts the frame's worst kept score (it was not among the best). The mean over the clip's
  last second, tempered by `track_beta`, is the log-likelihood: exp(beta * (E - max E)), mixed
  with `track_outlier` of "this clip says nothing" so one bad clip cannot overturn a track.
- **A longer clip** (`update_clip`): the emission reads a second, so a clip of several seconds
  (what the phone filmed since its last request: the app's guided walk sends 2 s) is walked
  second by second, in parts of about a second, the phone's steps and turn shared among them by
  time. Answered from its last second alone, the seconds before it would be lost, as if the
  phone had not filmed them (on the held-out families, updates every 2.5 s from 1 s clips were
  right 3.6 points less often than every 1 s; 2 s clips get 2.4 of them back).
- **Look-alikes** (`track_alike_cost`): the clips' evidence is not independent from one second
  to the next. In a corridor of identical doors, the query's light or its camera makes a wrong
  door score a little better than the right one for many seconds running, and compounded clip
  after clip that made the belief as sure of the wrong door as of a right one. So the venue's
  own model says which places look alike: each node's nearest modelling frame is searched in
  the venue's index like a query frame, and a node whose frames it matches (3 m or more away)
  is its look-alike, as alike as the score (1 = the same panorama). A second belief runs beside
  the first, the same in every way but that a look-alike b of a node a never gets less
  log-likelihood than a's less `track_alike_cost` * (1 - score): in it, a clip cannot tell two
  places apart by more than the model can, and only the walk (and places the model finds
  distinct) can. The answer is the first belief's (its small differences between look-alikes
  are right more often than not); its confidence is the lower of the two beliefs' at that
  answer, and it is ambiguous when either is split. Why two beliefs and not one: one belief
  with the look-alikes' floor said "not sure" in the right places but also chose among tied
  look-alikes by chance, and lost a tenth of the answers within 2 m on a repetitive corridor.
  The cost is a second transition per update and a second belief in the state.
- **Clips that match poorly** (`track_beta_ref`): a clip whose best node scores well below what
  a clip in the model's own conditions does (another hour's daylight on glass, people, a tilted
  phone) differs from every place by its conditions about as much as by place, and the same
  conditions favour the same wrong spot for many seconds running (an open hall's other side). In
  the second belief such a clip counts (1 - ref) / (1 - best) as much (ref: the tuning families'
  median best score): the main belief, and so the answer, is unchanged; its confidence is not
  stood by until the walk and clips that match well agree. The second belief runs for this
  alone where a venue has no look-alikes.
- **A phone held still** (`track_still_cap`): an HMM takes each clip as new evidence, but a
  phone held on one spot films the same view again and again, and compounded every second a
  moderate match to a place the user is not at (a room nobody filmed, another floor built like
  the modelled one) became a sure answer within seconds: on the families' walks filmed where
  the venue was never modelled, held still with the phone's sensors on, 90 of 246 spots ended
  sure of a wrong place, 29 of 54 in a building like the modelled one (bench/elsewhere.py).
  Held still, the walk adds nothing the clip does not say, so the answer is no surer than the
  clip alone: the confidence a locate without a session gives it (ClipAnswer.alone, the venue's
  own model; the rules' older model of the clip, which the cap first read, said more than the
  user would hear from "Where am I?" for the same clip when it matched well, and less when it
  matched poorly).
  Held still: the phone's sensors say it has not moved since the last update (no step, a turn
  under STILL_TURN_DEG) *and* the clip is best at the node the last one was. The node is the
  guard: a wheelchair, or a phone whose step counter has stalled while its user walks, counts
  no steps either, but each of its clips is best somewhere new. Without sensors, or where they
  do not say the phone moved (no step counted and no gyroscope, say), the clip says it
  (`track_still_seen`): best at the node the last one was *and* facing there as the last clip
  did, within STILL_TURN_DEG (the clip's own heading standing in for the gyroscope). A user
  walking along a corridor faces alike from one second to the next, but is best at the next
  node; one who turns where they stand faces another way. Sensors that say it moved (a step, a
  turn) overrule the clip. The belief itself still gathers the repeated clips:
  the first update that is not held (a step, a turn, another best node) answers with its full
  confidence again. Tried first, and not kept: counting a held clip's
  evidence a fifth as much; on the held-out families a fresh start held still inside the venue
  then said "not sure" 21 % of the time instead of 8 % (docs/benchlog.md).
- **Facing**: the clip also says where the phone faces at each node (its best match's heading
  there). A move that walks backwards from that counts less (`track_backward`): people walk the
  way they hold the phone, and a corridor of repeating doors no longer lets the track slide back
  a door. With the gyroscope's turn, a move i -> j whose facing changed by other than the turn
  counts less: checked per hypothesis, against the facing the last clip gave *that* node (one
  global "previous heading" would lock in a wrong answer, whose heading is wrong too).
- **Pose**: the node whose 1.5 m neighbourhood holds the most belief; position and heading from
  aggregate.sequence on the clip's matches near that node only (those facing the gyroscope's way,
  if the others face elsewhere), so the answer is as precise as a single clip's where it is right.
  Without a match near that node the heading is the gyroscope's (the last answer's plus the turn
  since); without a gyroscope it is unknown and the answer "not sure" (confidence held below 0.5).
- **Confidence**: logistic on the belief's mass within 2 m of the answer and its mass 3 m or more
  away (`track_confidence_features`/`_coef` in presets.py, fit by bench/tracking.py on the tuning
  families' walks only). `ambiguous` when at least `track_ambiguous` of the belief lies 3 m or
  more from the answer: the answer says "not sure" (confidence held below 0.5) and the walk that
  follows resolves it.
- **The clip's own answer** (`ClipAnswer`: what the same clip answers alone). The beliefs'
  confidence says how far the walk has ruled the other places out; it cannot see the clips
  themselves doubt it. The answer is not stood by (its confidence held at `track_doubt_cap`,
  below the app's "sure", 0.8) when:
  - *recent clips are unsure* (`track_recent_min`): the clips' own confidence, averaged over
    about the last `track_recent_s` seconds, is below `track_recent_min`. The clips have stopped
    matching the model anywhere well (an open hall in another light, a bare corridor), which is
    when a belief drifts with the conditions' favourite wrong spot while staying sure;
  - *a sure clip says elsewhere*: the clip alone is sure (aggregate.SURE, the app's 0.8) of a place
    FAR_M or more from the answer (or on another floor). Two calibrated sources that disagree
    are the split evidence the answer must not be sure of; the walk settles it in a few seconds.
  Chosen on the tuning families' walks (docs/benchlog.md, "Recent clips" and "A sure clip
  elsewhere"), with the single clip's confidence model of then (support and margin): the clip's
  confidence here is `track_clip_confidence_*`, not the venue's `confidence_*`, which was refit
  since and gives other numbers to the same clips.
  And where the answer is (`track_clip_tie`, `Tracker.tie_node`): when a sure clip says
  elsewhere and the belief holds the clip's place at least `track_clip_tie` times as likely as
  the answer's (1.5 m neighbourhoods), the answer is the clip's place, held below sure all the
  same. In a corridor of identical doors the belief splits between two doors 4 m apart for
  seconds at a time, and the walk's slightly likelier door was the wrong one about as often as
  not, while the sure clip of the moment, which reads how its frames follow one another, was
  mostly right. A sure clip of a place the walk has all but ruled out (a look-alike corridor
  20 m away) moves nothing: ruling those out is what the walk is for. Chosen on the tuning
  families' walks (docs/benchlog.md, "A sure clip breaks a split belief").
"""

from __future__ import annotations

import functools
import struct
import zlib
from collections.abc import Callable, Mapping
from dataclasses import dataclass, fields, replace
from typing import TYPE_CHECKING, Any

import numpy as np
import scipy.sparse  # type: ignore[import-untyped]
from scipy.spatial import cKDTree  # type: ignore[import-untyped]

from .aggregate import (
    SPAN_S,
    SURE,
    TRACK_CONFIDENCE_INPUTS,
    Estimate,
    confidence,
    confidence_inputs,
    logistic,
    reach_m,
    sequence,
)
from .heading import wrap_deg
from .index import Matches
from .presets import setting
from .walkgraph import nearest_on_floor

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
MAX_STORED = 1500  # nodes a serialised state keeps one by one (the most probable) ...
STORE_REL = 1e-6  # ... those with at least this share of the most probable's belief; a broader
# belief (a young one on a big graph) is kept whole instead, never cut to the lowest-numbered
ALIKE_K = 64  # candidates of each node's frame searched for its look-alikes (a corridor's doors)
ALIKE_CELLS = 1 << 24  # node frames x venue frames scored per pass of that search (64 MB of float32)
ALIKE_FRAMES = 128  # and at most this many node frames a pass (each re-ranks 8 x ALIKE_K full keys)
ALIKE_MAX_NATS = 8.0  # a look-alike this far below (in log-likelihood) can never matter: not kept
MAGIC = b"ONT2"  # the nodes kept one by one
MAGIC_ALL = b"ONTA"  # every node's belief and facing (zlib: a flat or broad belief packs small)
ALIKE, ALIKE_ALL = b"AS", b"AW"  # then the second belief: its nodes one by one, or whole
RECENT = b"RC"  # then the recent clips' mean confidence (float64)
BEST = b"BN"  # then the node the last clip matched best (uint32)
STEPPED = b"ST"  # then when the phone last counted a step (float64 seconds)
# a step counter that counted a step this recently (s) works, and its count of none is a stop:
# kept whatever the clips say (track_zero_steps_m is for a phone that counts nothing while its
# user moves on). Longer than a stop at a door or a junction, shorter than a walk along a corridor.
STEPS_WORK_S = 30.0
# ... counted this many in one update: a walker's second holds one or two, a few seconds' more;
# a phone held steady (or a wheelchair over a threshold) counts the odd false step, one at a time
STEPS_WORK_N = 2
HEADER = "<4sdIfIB"  # magic, t, updates, heading (NaN: none), nodes of the graph, length of its key


def _number(v: Any) -> bool:
    """A finite real number (not a bool, not a string that looks like one)."""
    return isinstance(v, (int, float)) and not isinstance(v, bool) and bool(np.isfinite(v))


@dataclass(frozen=True)
class ClipAnswer:
    """What the clip of an update answers alone (Locator.track: its aggregate Estimate): its
    calibrated confidence as the rules read it, and where (x, y and the venue frame row, whose
    floor it is; None: not given, the "sure clip elsewhere" rule then does not apply); `alone`,
    the confidence a locate without a session answers for it (None: not given, `confidence`
    stands in)."""

    confidence: float
    x: float | None = None
    y: float | None = None
    row: int | None = None
    alone: float | None = None

    @staticmethod
    def of(e: Estimate, conf: dict[str, Any]) -> ClipAnswer:
        """What a clip's aggregate Estimate answers, with its calibrated confidence as the rules
        read it: `track_clip_confidence_*`, the single clip's model they were chosen with (the
        venue's own `confidence_*` answers the single clip, and may be a later refit: `alone`)."""
        names = setting(conf, "track_clip_confidence_features")
        c = logistic(setting(conf, "track_clip_confidence_coef"), confidence_inputs(e, names))
        return ClipAnswer(c, e.x, e.y, e.venue_row, confidence(e, conf))

    @property
    def said(self) -> float:
        """The clip's confidence as the user would hear it alone ("Where am I?")."""
        return self.confidence if self.alone is None else self.alone


@dataclass(frozen=True)
class Motion:
    """The phone's own sensors between the previous update and this one."""

    steps: int | None = None  # steps detected (DeviceMotion), None = unknown
    turn_deg: float | None = None  # gyroscope yaw change, clockwise +, None = unknown


STILL_TURN_DEG = 10.0  # a phone that counted no step and turned less than this has not moved


def _still(motion: Motion) -> bool:
    """Whether the phone's sensors say it has not moved since the last update (no step, little
    turn); unknown (no sensors) is not still."""
    return motion.steps == 0 and motion.turn_deg is not None and abs(motion.turn_deg) < STILL_TURN_DEG


def _moved(motion: Motion) -> bool:
    """Whether the phone's sensors say it moved since the last update (a step, or a turn of
    STILL_TURN_DEG or more); unknown is not moved."""
    return bool(motion.steps) or (motion.turn_deg is not None and abs(motion.turn_deg) >= STILL_TURN_DEG)


def _faces_as_before(facing: np.ndarray, before: np.ndarray | None, node: int) -> bool:
    """Whether the clip faces at `node` as the last clip did there, within STILL_TURN_DEG (what
    the clip says of a turn where no gyroscope does)."""
    if before is None or len(before) != len(facing) or not (np.isfinite(facing[node]) and np.isfinite(before[node])):
        return False
    return abs(float(wrap_deg(facing[node] - before[node]))) < STILL_TURN_DEG


def _clip_times(matches: Matches, times: np.ndarray) -> np.ndarray:
    """A clip's frame times as float64, checked against its matches (one time a query frame)."""
    times = np.asarray(times, np.float64)
    if len(times) != matches.index.shape[0] or len(times) == 0:
        raise ValueError(f"{matches.index.shape[0]} frames of matches need as many frame times, got {len(times)}")
    return times


def parts(times: np.ndarray, span: float = SPAN_S) -> list[np.ndarray]:
    """A clip's frame times (ascending) -> its frames cut into consecutive parts of about `span` s
    each (index arrays, in time order; the last part ends with the clip's last frame).

    The filter's evidence is a second of clip (its emission reads the last SPAN_S of an update), so
    a longer clip, everything a phone filmed since its previous request, is walked second by
    second rather than answered from its last second alone: the seconds before count, as they
    would had the phone asked every second. Parts of equal length (a 2 s clip: two of 1 s; 1.5 s:
    two of 0.75 s; 1.4 s: one, whose update reads its last second) rather than whole seconds and
    a sliver of a few frames."""
    t = np.asarray(times, np.float64)
    if len(t) < 2 or not np.isfinite(t).all():  # (times not numbers: one part, as a short clip)
        return [np.arange(len(t))]
    dt = float(np.median(np.diff(t)))
    length = float(t[-1] - t[0]) + max(dt, 0.0)  # each frame stands for a frame interval
    # parts of 0.67-1.33 spans: never a sliver (every update counts as a whole clip's evidence, so
    # many short parts would count the same seconds more than once)
    k = max(1, int(np.floor(length / span + 0.5)))
    if k == 1:
        return [np.arange(len(t))]
    # the part of each frame: by its time from the clip's end, k equal parts
    which = np.clip(k - 1 - np.floor((t[-1] - t) * k / length + 1e-9).astype(np.int64), 0, k - 1)
    cut = [idx for idx in (np.flatnonzero(which == i) for i in range(k)) if len(idx)]
    # frames far apart in time (a gap in a video's timestamps) can leave a part of a frame or two:
    # it joins the part after it (the last part, the one before), never an update of its own
    big = max(len(c) for c in cut)
    out: list[np.ndarray] = []
    carry = np.zeros(0, np.int64)
    for c in cut:
        c = np.concatenate([carry, c])
        carry = c if 2 * len(c) < big else np.zeros(0, np.int64)
        if not len(carry):
            out.append(c)
    if len(carry):
        out = [*out[:-1], np.concatenate([out[-1], carry])] if out else [carry]
    return out


def share(motion: Motion, dts: list[float]) -> list[Motion]:
    """The phone's motion over several updates, dts apart, shared among them in proportion to
    time: steps as whole steps (the rounding carried), the turn as a share of it. A phone sends
    one reading per request; the sensors' own timing within it is not sent (a turn made in the
    request's last half second is spread over its parts: the filter's turn gate is soft, 20° a
    step, for that reason among others)."""
    w = np.maximum(np.asarray(dts, np.float64), 0.0)
    frac = w / w.sum() if w.sum() > 0 else np.full(len(w), 1.0 / max(len(w), 1))
    steps: list[int | None] = [None] * len(w)
    if motion.steps is not None:
        cum = np.round(np.cumsum(frac) * max(int(motion.steps), 0)).astype(np.int64)
        steps = [int(v) for v in np.diff(np.r_[0, cum])]
    turns: list[float | None] = [None] * len(w)
    if motion.turn_deg is not None:
        turns = [float(motion.turn_deg) * float(f) for f in frac]
    return [Motion(s, d) for s, d in zip(steps, turns, strict=True)]


@dataclass
class TrackState:
    """Everything the filter remembers between updates: small, serialisable (to_bytes)."""

    t: float  # seconds (the caller's clock) of the last update
    belief: np.ndarray  # (N,) float64 over the graph's nodes, sums to 1
    graph_key: str
    updates: int
    heading: float | None = None  # the last answer's heading
    # (N,) where the last clip says the phone faced at each node (NaN: it did not say): the
    # gyroscope's turn is checked against it node by node, never against one global heading
    facing: np.ndarray | None = None

    # (N,) the second, cautious belief (look-alikes: Tracker.with_alikes; poor clips tempered:
    # Tracker.beta; the answer's confidence is also read from it); None when the venue has no
    # look-alikes and its settings turn the tempering off
    alike: np.ndarray | None = None
    # the clips' own confidence, averaged over about the last track_recent_s seconds (None: no
    # clip said, or a state saved before it existed: the next clip's starts it)
    recent: float | None = None
    # the node the last clip's evidence was best at (None: a state saved before it existed)
    best: int | None = None
    # when the phone last counted STEPS_WORK_N or more steps in one update (None: not in this
    # belief's life, or a state saved before it existed): its counter works, and its zeros are
    # stops (Tracker.zero_read_as_none)
    stepped: float | None = None

    def to_bytes(self) -> bytes:
        """A header with the graph's key, the belief (float16 relative to the largest) and facing
        (float16 degrees), then the second (cautious) belief if any (b"AS" or b"AW" and the same, without
        facing), the recent clips' mean if any (b"RC", float64), the node the last clip was best at
        if any (b"BN", uint32), when the phone last counted a step if it did (b"ST", float64), in
        that order, and a CRC-32. A belief's nodes with at least
        STORE_REL of the largest, when there are at most MAX_STORED of them: each one's index
        (uint32), belief and facing, 8 bytes a node (6 without facing); more than that (a young
        belief, flat over much of a big graph): every node's, zlib-compressed, so that the state
        says as much of every part of the building as of the one that happens to be numbered
        first."""
        p = np.asarray(self.belief, np.float64)
        face = np.full(len(p), np.nan) if self.facing is None else np.asarray(self.facing, np.float64)
        key = self.graph_key.encode()
        # the last clip's best node keeps its facing even where the belief there is too small to
        # keep: the next update compares its clip's facing with it (track_still_seen)
        whole, part = _pack(p, face, self.best)
        head = struct.pack(
            HEADER,
            MAGIC_ALL if whole else MAGIC,
            self.t,
            self.updates,
            np.nan if self.heading is None else self.heading,
            len(p),
            len(key),
        )
        body = head + key + part
        if self.alike is not None:
            whole, part = _pack(np.asarray(self.alike, np.float64), None)
            body += (ALIKE_ALL if whole else ALIKE) + part
        if self.recent is not None:
            body += RECENT + struct.pack("<d", self.recent)
        if self.best is not None:
            body += BEST + struct.pack("<I", self.best)
        if self.stepped is not None:
            body += STEPPED + struct.pack("<d", self.stepped)
        return body + struct.pack("<I", zlib.crc32(body))

    @staticmethod
    def from_bytes(b: bytes, graph: WalkGraph) -> TrackState | None:
        """A state saved by to_bytes, or None: corrupt, or saved against another graph. A state
        saved without the second belief (or before it existed) reads with `alike` None (the
        next update starts it as the belief); one without the recent clips' confidence with
        `recent` None; one without the last clip's best node with `best` None; one without the
        time of the last step counted with `stepped` None."""
        try:
            if len(b) < 4 or zlib.crc32(b[:-4]) != struct.unpack("<I", b[-4:])[0]:
                return None
            b = b[:-4]
            magic, t, updates, heading, n, klen = struct.unpack_from(HEADER, b, 0)
            off = struct.calcsize(HEADER)
            key = b[off : off + klen].decode()
            off += klen
            if magic not in (MAGIC, MAGIC_ALL) or key != graph.key or n != len(graph.xy) or not np.isfinite(t):
                return None
            got = _unpack(b, off, n, magic == MAGIC_ALL, True)
            if got is None:
                return None
            belief, facing, off = got
            alike, recent = None, None
            if b[off : off + len(ALIKE)] in (ALIKE, ALIKE_ALL):
                tag = b[off : off + len(ALIKE)]
                got = _unpack(b, off + len(tag), n, tag == ALIKE_ALL, False)
                if got is None:
                    return None
                alike, off = got[0], got[2]
            if b[off : off + len(RECENT)] == RECENT:
                (recent,) = struct.unpack_from("<d", b, off + len(RECENT))
                off += len(RECENT) + 8
                if not 0.0 <= recent <= 1.0:
                    return None
            best = None
            if b[off : off + len(BEST)] == BEST:
                (best,) = struct.unpack_from("<I", b, off + len(BEST))
                off += len(BEST) + 4
                if best >= n:
                    return None
            stepped = None
            if b[off : off + len(STEPPED)] == STEPPED:
                (stepped,) = struct.unpack_from("<d", b, off + len(STEPPED))
                off += len(STEPPED) + 8
                if not np.isfinite(stepped):
                    return None
            if off != len(b):
                return None
        except (struct.error, UnicodeDecodeError, ValueError, zlib.error):
            return None
        h = float(heading) if np.isfinite(heading) else None
        return TrackState(float(t), belief, key, int(updates), h, facing, alike, recent, best, stepped)


def _pack(p: np.ndarray, face: np.ndarray | None, also: int | None = None) -> tuple[bool, bytes]:
    """A belief (and facing): whether it is kept whole, and its bytes (TrackState.to_bytes);
    node `also` is kept whatever its belief."""
    big = max(float(p.max()), 1e-300) if len(p) else 1.0
    keep = np.flatnonzero(p >= STORE_REL * big)
    if also is not None and 0 <= also < len(p):
        keep = np.union1d(keep, [also])
    if len(keep) > MAX_STORED:
        rel = np.where(p >= STORE_REL * big, p / big, 0.0).astype("<f2")
        raw = rel.tobytes() + (b"" if face is None else face.astype("<f2").tobytes())
        return True, zlib.compress(raw)  # (its end: where the zlib stream ends)
    out = struct.pack("<I", len(keep)) + keep.astype("<u4").tobytes() + (p[keep] / big).astype("<f2").tobytes()
    return False, out + (b"" if face is None else face[keep].astype("<f2").tobytes())


def _unpack(b: bytes, off: int, n: int, whole: bool, facing: bool) -> tuple[np.ndarray, np.ndarray, int] | None:
    """_pack's bytes at `off` -> (belief (N,) summing to 1, facing (N,) NaN where unsaid, the
    offset after them), or None where they do not make a belief of n nodes."""
    per = 4 if facing else 2
    if whole:
        z = zlib.decompressobj()
        raw = z.decompress(b[off:], per * n + 1)
        if len(raw) != per * n or not z.eof:
            return None
        m, idx, off = n, np.arange(n), len(b) - len(z.unused_data)
        rel = np.frombuffer(raw, "<f2", n, 0).astype(np.float64)
        face = np.frombuffer(raw, "<f2", n, 2 * n).astype(np.float64) if facing else np.full(n, np.nan)
    else:
        (m,) = struct.unpack_from("<I", b, off)
        off += 4
        size = (4 + per) * m
        if len(b) < off + size:  # (what follows, if anything, is the caller's to read)
            return None
        idx = np.frombuffer(b, "<u4", m, off).astype(np.int64)
        rel = np.frombuffer(b, "<f2", m, off + 4 * m).astype(np.float64)
        face = np.frombuffer(b, "<f2", m, off + 6 * m).astype(np.float64) if facing else np.full(m, np.nan)
        off += size
    if m == 0 or (idx >= n).any() or not np.isfinite(rel).all() or (rel < 0).any() or rel.sum() <= 0:
        return None
    belief = np.zeros(n)
    belief[idx] = rel
    out = np.full(n, np.nan)
    out[idx] = face
    return belief / belief.sum(), out, off


@dataclass(frozen=True)
class TrackPose:
    """The filtered pose at the update's time."""

    x: float
    y: float
    floor: str
    heading: float  # degrees clockwise from plan up, [0, 360)
    confidence: float  # P(within 2 m): the lower of the two beliefs' (track_confidence of each)
    node: int
    ambiguous: bool  # a belief is split between places >= 3 m apart: say "not sure"
    spread_m: float  # RMS distance of the belief from the answer (other floors count 50 m)
    mass: float = 0.0  # belief within NEAR_M of the answer
    far: float = 0.0  # belief FAR_M or more from it
    updates: int = 1  # clips (seconds of a longer clip: update_clip) the belief has seen since it (re)started
    # False: no match near the answer said where the phone faces, nor the gyroscope (heading is a
    # stand-in: the last answer's, else 0; confidence held below 0.5 as an ambiguous answer's)
    heading_known: bool = True
    # the second (cautious) belief's mass within NEAR_M of the answer and FAR_M or more from it
    # (None: the tracker runs no second belief)
    alike_mass: float | None = None
    alike_far: float | None = None
    restarted: bool = False  # the belief started over in this update (no state, or one it cannot go on from)


def track_confidence(pose: Any, conf: Mapping[str, Any]) -> float:
    """Calibrated P(within 2 m) of a filtered pose: logistic on `track_confidence_features`."""
    names = setting(conf, "track_confidence_features")
    w = setting(conf, "track_confidence_coef")
    return logistic(w, [TRACK_CONFIDENCE_INPUTS[n](pose) for n in names])


def _pairs_within(a: np.ndarray, b: np.ndarray, r: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(i, j, distance) for every point a[i] within r of b[j]."""
    if len(a) == 0 or len(b) == 0:
        return np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros(0)
    m = cKDTree(a).sparse_distance_matrix(cKDTree(b), r, output_type="coo_matrix")
    return m.row.astype(np.int64), m.col.astype(np.int64), m.data.astype(np.float64)


def _spans(indptr: np.ndarray, rows: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The positions of rows' entries in a CSR layout (`indptr`), row after row in their order,
    and how many each row has."""
    lo = indptr[rows]
    count = indptr[rows + 1] - lo
    return np.arange(int(count.sum())) + np.repeat(lo - (np.cumsum(count) - count), count), count


def _rows_of(m: scipy.sparse.csr_matrix, rows: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The entries of some rows of a CSR matrix, as m[rows] holds them: each entry's position in
    `rows`, its column and its value (a gather by the matrix's own arrays: SciPy's row indexing
    builds a matrix, at 10x the cost, for the three arrays read from it)."""
    at, count = _spans(m.indptr, rows)
    return np.repeat(np.arange(len(rows)), count), m.indices[at], m.data[at]


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


def node_frames(graph: WalkGraph, venue_xy: np.ndarray, venue_floor: np.ndarray) -> np.ndarray:
    """(N,) int64: each node's nearest venue frame on its floor (any floor's, if its has none)."""
    return nearest_on_floor(graph.xy, graph.floor, venue_xy, venue_floor)


def frame_search(
    search: Callable[[np.ndarray, int], Matches], spectra: np.ndarray
) -> Callable[[np.ndarray, int], Matches]:
    """Venue frame rows -> their matches in the venue's own index (`search`: index.Index.search),
    searched in passes of at most ALIKE_FRAMES rows and ALIKE_CELLS row x venue frame scores:
    bounded memory on any venue."""
    spec = np.asarray(spectra)

    def run(rows: np.ndarray, k: int) -> Matches:
        step = max(1, min(ALIKE_FRAMES, ALIKE_CELLS // max(1, len(spec))))
        parts = [search(spec[rows[s : s + step]], k) for s in range(0, len(rows), step)]
        return Matches(*(np.concatenate([getattr(p, f.name) for p in parts]) for f in fields(Matches)))

    return run


def look_alikes(
    search_rows: Callable[[np.ndarray, int], Matches],
    graph: WalkGraph,
    venue_xy: np.ndarray,
    venue_floor: np.ndarray,
    conf: Mapping[str, Any],
    k: int = ALIKE_K,
) -> Matches | None:
    """(N, k) matches of each node's nearest modelling frame searched in the venue's own index
    (`search_rows`: frame_search, or Locator.frame_matches, which keeps them): what the Tracker
    takes as `alike`. None when the venue's settings turn look-alikes off, or without nodes."""
    if setting(conf, "track_alike_cost") is None or len(graph.xy) == 0:
        return None
    return search_rows(node_frames(graph, venue_xy, venue_floor), k)


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
        rows); conf: the venue's settings (tracking keys read with presets.py's defaults);
        alike: look_alikes() of this graph and venue (without it, no place is a look-alike)."""
        self.graph = graph
        self.conf = dict(conf)
        self.n = n = len(graph.xy)
        if n == 0:
            raise ValueError("a walk graph without nodes cannot be tracked on")
        ref = setting(conf, "track_beta_ref")
        if ref is not None and not 0.0 <= float(ref) < 1.0:  # 1 or more would turn the evidence over
            raise ValueError(f"track_beta_ref must be in [0, 1) or None, got {ref!r}")
        self.beta_ref = None if ref is None else float(ref)  # (beta; None: no tempering)
        # the rules of the clip's own answer: a bad value would fail every tracked locate, or write
        # states that cannot be read back (a mean outside [0, 1]): refused here, like track_beta_ref
        tau, low, cap = (setting(conf, k) for k in ("track_recent_s", "track_recent_min", "track_doubt_cap"))
        if not (_number(tau) and float(tau) > 0):
            raise ValueError(f"track_recent_s must be a number of seconds > 0, got {tau!r}")
        if low is not None and not (_number(low) and 0.0 <= float(low) <= 1.0):
            raise ValueError(f"track_recent_min must be in [0, 1] or None (off), got {low!r}")
        if not (_number(cap) and 0.0 <= float(cap) <= 1.0):
            raise ValueError(f"track_doubt_cap must be in [0, 1], got {cap!r}")
        self.recent_s = float(tau)
        self.recent_min = None if low is None else float(low)
        self.doubt_cap = float(cap)
        tie = setting(conf, "track_clip_tie")
        # (above 1 it could never hold: the answer's neighbourhood is the one with the most belief)
        if tie is not None and not (_number(tie) and 0.0 < float(tie) <= 1.0):
            raise ValueError(f"track_clip_tie must be in (0, 1] or None (off), got {tie!r}")
        self.clip_tie = None if tie is None else float(tie)
        zero = setting(conf, "track_zero_steps_m")
        if zero is not None and not (_number(zero) and float(zero) > 0):
            raise ValueError(f"track_zero_steps_m must be a number of metres > 0 or None (off), got {zero!r}")
        self.zero_steps_m = None if zero is None else float(zero)
        self.xy = np.asarray(graph.xy, np.float64)
        self.floor = np.asarray(graph.floor).astype(str)
        vxy = np.asarray(venue_xy, np.float64)
        vfl = np.asarray(venue_floor).astype(str)
        self.venue_xy = vxy
        self.venue_floor = vfl
        radius = float(setting(conf, "track_radius_m"))
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
        cost = setting(self.conf, "track_alike_cost")
        if alike is None or cost is None:
            return none, none, np.zeros(0), none
        if float(cost) < 0 or len(alike.index) != self.n:
            raise ValueError(f"look-alikes need a cost >= 0 and {self.n} nodes' matches (of this graph)")
        k = alike.index.shape[1]
        # a matched frame is its nearest node's look-alike only (not every node within reach: the
        # score says how alike *that* spot is, and a step away the panorama is another one)
        node = self.graph.snap(self.venue_xy, self.venue_floor)  # every venue frame's, once
        near = np.hypot(*(self.xy[node] - self.venue_xy).T) <= float(setting(self.conf, "track_radius_m"))
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
            i, j, d = _pairs_within(a[ia], b[ib], r)
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
        vmax = float(setting(self.conf, "track_max_mps"))
        slack = float(setting(self.conf, "track_slack_m"))
        step_m = float(setting(self.conf, "track_step_m"))
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
            sig = 0.12 * walked + float(setting(self.conf, "track_step_sigma_m"))
            trust = float(setting(self.conf, "track_step_trust"))
            g = np.subtract(d, walked)
            g /= sig
            g *= g
            g *= -0.5
            np.exp(g, out=g)
            g *= trust
            g += 1 - trust
            k *= g
        np.maximum(k, 1e-12, out=k)
        k[self._via] = float(setting(self.conf, "track_floor_change"))
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
            back = float(setting(self.conf, "track_backward")) ** (parts == 1)
            kk = k.copy()
            sel = e[fwd < -1.0 * parts]
            kk[sel] = k[sel] * back
            if turn is not None:
                b = np.deg2rad(turn[0] + turn[1])
                rows = self.t_row[e]
                cos_off = fc * np.cos(b)[rows] + fs * np.sin(b)[rows]
                gate = float(setting(self.conf, "track_turn_gate_deg"))
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
        into: np.ndarray = self.t_rev[_spans(self.t_indptr, nodes)[0]]
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
        r, nodes, dist = _rows_of(self.f2n, idx.ravel())
        # a match counts for a node less the further it is from it: the emission peaks where it is
        val = sc.ravel()[r] - float(setting(self.conf, "track_dist_penalty")) * (dist - 1.0)
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
        beta = float(setting(self.conf, "track_beta"))
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
            eps = float(setting(self.conf, "track_uniform"))
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
        rho = float(setting(self.conf, "track_outlier"))
        # held still: the clip is best at the node the last one was (a wheelchair, or a phone that
        # counts no steps while its user walks, reaches other nodes' views), and the sensors
        # counted no step and little turn, or, where they do not say it moved, the clip faces as
        # the last one did there: "A phone held still" above
        held = False
        still_cap = setting(self.conf, "track_still_cap")
        if still_cap and not fresh and state is not None and best is not None and state.best == best:
            # the sensors say so; or, where they do not say it moved (none, or none that
            # answered), the clip does: best where the last was and facing as it did there
            seen = setting(self.conf, "track_still_seen") and not _moved(motion)
            held = _still(motion) or bool(seen and _faces_as_before(facing, state.facing, best))
        log_lik = float(setting(self.conf, "track_beta")) * (e - e.max())
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
        ambiguous = max(far, alike_far or 0.0) >= float(setting(self.conf, "track_ambiguous"))
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
            gate = float(setting(self.conf, "track_turn_gate_deg"))
            ok = near & (np.abs(wrap_deg(m.heading - predicted)) <= gate)
            if abs(wrap_deg(e.heading - predicted)) > gate and (ok & (m.score > 0)).any():
                e = fit(ok)
        x, y = e.x, e.y
        dd = float(np.hypot(x - nx, y - ny))
        if dd > FIT_M:  # never further from the node than its neighbourhood
            x, y = nx + (x - nx) * FIT_M / dd, ny + (y - ny) * FIT_M / dd
        return float(x), float(y), float(e.heading % 360.0), True


@dataclass(frozen=True)
class Imu:
    """A walk's phone motion (imu.json, docs/formats.md): each detected step's time, and the
    gyroscope's yaw integrated since the start, clockwise + (degrees), at its sample times."""

    steps: np.ndarray  # (S,) seconds, increasing
    yaw_t: np.ndarray  # (Y,) seconds, increasing
    yaw_deg: np.ndarray  # (Y,)

    def motion(self, t0: float, t1: float) -> Motion:
        """What the phone measured between two moments: steps in (t0, t1], the yaw change."""
        steps = int(np.count_nonzero((self.steps > t0) & (self.steps <= t1)))
        turn = None
        if len(self.yaw_t):
            turn = float(np.interp(t1, self.yaw_t, self.yaw_deg) - np.interp(t0, self.yaw_t, self.yaw_deg))
        return Motion(steps, turn)


def parse_imu(d: Any, where: str = "imu") -> Imu:
    from .errors import OmninavError

    if not isinstance(d, dict):
        raise OmninavError(f"{where}: an imu file must be a JSON object")
    try:
        steps = np.asarray(d.get("steps", []), np.float64).reshape(-1)
        yaw = d.get("yaw") or {"t": [], "deg": []}
        yt = np.asarray(yaw["t"], np.float64).reshape(-1)
        yd = np.asarray(yaw["deg"], np.float64).reshape(-1)
    except (TypeError, ValueError, KeyError) as e:
        shape = "'steps' must be a list of times, 'yaw' {'t': [...], 'deg': [...]}"
        raise OmninavError(f"{where}: {shape} ({e})") from None
    if len(yt) != len(yd):
        raise OmninavError(f"{where}: 'yaw' needs as many 'deg' as 't' ({len(yd)} and {len(yt)})")
    if not (np.isfinite(steps).all() and np.isfinite(yt).all() and np.isfinite(yd).all()):
        raise OmninavError(f"{where}: times and angles must be finite numbers")
    if (np.diff(steps) < 0).any() or (np.diff(yt) <= 0).any():
        raise OmninavError(f"{where}: step and yaw times must be increasing")
    return Imu(steps, yt, yd)


def load_imu(path: Any) -> Imu:
    from .errors import read_json

    return parse_imu(read_json(path, "imu file"), where=str(path))
