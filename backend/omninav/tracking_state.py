"""What the tracking filter keeps between updates (`TrackState`, in a few KB of bytes that a
server stores per phone) and what it answers (`TrackPose`, and `ClipAnswer`: what the same clip
answers alone, which the filter's rules read).

The byte format (`TrackState.to_bytes`): a header with the walk graph's key, the belief and facing
(nodes one by one, or every node zlib-compressed for a broad belief), tagged optional parts, and a
CRC-32; a state saved against another graph, or corrupt, reads as None and the filter starts over.
"""

from __future__ import annotations

import struct
import zlib
from collections.abc import Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from .aggregate import TRACK_CONFIDENCE_INPUTS, Estimate, confidence, confidence_inputs, logistic
from .presets import setting

if TYPE_CHECKING:
    from .walkgraph import WalkGraph

MAX_STORED = 1500  # nodes a serialised state keeps one by one (the most probable) ...
STORE_REL = 1e-6  # ... those with at least this share of the most probable's belief; a broader
# belief (a young one on a big graph) is kept whole instead, never cut to the lowest-numbered
MAGIC = b"ONT2"  # the nodes kept one by one
MAGIC_ALL = b"ONTA"  # every node's belief and facing (zlib: a flat or broad belief packs small)
ALIKE, ALIKE_ALL = b"AS", b"AW"  # then the second belief: its nodes one by one, or whole
RECENT = b"RC"  # then the recent clips' mean confidence (float64)
BEST = b"BN"  # then the node the last clip matched best (uint32)
STEPPED = b"ST"  # then when the phone last counted a step (float64 seconds)
HEADER = "<4sdIfIB"  # magic, t, updates, heading (NaN: none), nodes of the graph, length of its key


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
