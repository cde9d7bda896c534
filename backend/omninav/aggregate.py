"""Clip aggregation: from per-frame candidate matches to one pose at the clip's last frame.

`median` is the paper's: each frame's best venue frame, the median of their indices.
`sequence` (default) uses what a clip is: frames in time order, taken from places close together
while facing roughly the same way. Every verified match of the clip's last second is a hypothesis
of where the clip ends; it is supported, per query frame, by that frame's best match that lies
within reach in the time between the two frames and faces within a gate. The best-supported
hypothesis wins, and a weighted straight-line fit of its supporters over the last second gives the
pose at the last frame.

A clip may be 0.3-5 s long. Within a second the reach and the gate are the 1 s clip's
(`clip_radius_m`, `heading_gate_deg`); further apart in time they grow by as much per second (a
steady walk, a slow turn), so that every frame of a long clip still counts for the right place.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from .heading import wrap_deg
from .index import Matches

WALK_MPS = 1.8  # fastest walking pace we allow between two frames of a clip
NEAR_M = 0.45  # slack on top: matching granularity and the walk path's own error
ALT_M = 3.0  # a rival hypothesis this far away is a different place
# "Sure": the confidence from which an answer is one a user may trust (the app's TRUSTED_CONFIDENCE,
# the accuracy circle's 2 m, the figures' "conf >= 0.8", issue 13's target)
SURE = 0.8
# The span clip_radius_m and heading_gate_deg are for (a 1 s clip), and the part of a longer clip
# that places the answer: its hypotheses and the fit. Earlier frames only add support: anchored
# on them, a hypothesis on the user's own way there would be a "rival" of where they are now.
SPAN_S = 1.0


@dataclass
class Estimate:
    x: float
    y: float
    heading: float
    venue_row: int  # venue frame that best matches the last supported query frame
    support: float  # mean over frames of the best supporting score, in [-1, 1]
    rival: float  # the same for the best hypothesis >= ALT_M away
    agree: float  # fraction of frames with a supporting match


def reach_m(dt: np.ndarray, conf: dict[str, Any]) -> np.ndarray:
    """How far apart two frames `dt` seconds apart may have been filmed: a fast walk, at most
    clip_radius_m within SPAN_S and clip_radius_m per SPAN_S beyond (a steady walk); plus NEAR_M."""
    r = float(conf.get("clip_radius_m", 1.5))
    # written as the 1 s cap plus the growth beyond it: within SPAN_S the same float32 numbers as before
    return np.minimum(NEAR_M + WALK_MPS * dt, r + NEAR_M + r * np.maximum(dt / SPAN_S - 1.0, 0.0))


def gate_deg(dt: np.ndarray, conf: dict[str, Any]) -> np.ndarray:
    """How far apart the headings of two frames `dt` seconds apart may be: heading_gate_deg within
    SPAN_S, and heading_gate_deg per SPAN_S beyond (a slow turn), at most all the way round."""
    g = float(conf["heading_gate_deg"])
    return np.minimum(g + g * np.maximum(dt / SPAN_S - 1.0, 0.0), 180.0)


def sequence(m: Matches, xy: np.ndarray, times: np.ndarray, conf: dict[str, Any]) -> Estimate:
    """m: (Q, k) matches; xy: (N, 2) venue frame positions; times: (Q,) seconds of the frames, in order."""
    q, k = m.index.shape
    pos = xy[m.index.ravel()].astype(np.float64)  # (P, 2)
    hd = m.heading.ravel().astype(np.float64)
    sc = np.maximum(m.score.ravel().astype(np.float64), 0.0)
    row = np.repeat(np.arange(q), k)
    times = np.asarray(times, np.float64)
    t = times[row]
    t_last = float(times[-1])
    # hypotheses: the matches of the last SPAN_S, pairs h0.. (all of them, in a clip of a second)
    h0 = int(np.searchsorted(t, t_last - SPAN_S - 1e-6))
    hyp = slice(h0, None)
    # hypotheses a x pairs p, float32: 25k-650k entries, so memory traffic is the cost. The
    # hypotheses are whole frames' matches (h0 is a multiple of k), so what depends on time only
    # (reach, gate) is made per pair of frames and broadcast: (A/k, 1, Q, 1) against (A/k, k, Q, k)
    qa = q - h0 // k
    p32 = pos.astype(np.float32)
    x, y = p32[:, 0], p32[:, 1]
    d2 = ((x[hyp, None] - x[None, :]) ** 2 + (y[hyp, None] - y[None, :]) ** 2).reshape(qa, k, q, k)
    t32 = times.astype(np.float32)
    dt = np.abs(t32[q - qa :, None] - t32[None, :])[:, None, :, None]
    reach = reach_m(dt, conf)
    # heading gate as a dot product of unit vectors: cos(ha - hp) >= cos(gate), no modulo
    hr = np.deg2rad(hd).astype(np.float32)
    u, v = np.cos(hr), np.sin(hr)
    span = float(np.ptp(times))
    cos_gate: np.ndarray | float = np.cos(np.deg2rad(conf["heading_gate_deg"]))
    if span > SPAN_S:  # a gate per pair; within a second one number, as it always was
        cos_gate = np.cos(np.deg2rad(gate_deg(dt, conf))).astype(np.float32)
    facing = (u[hyp, None] * u[None, :] + v[hyp, None] * v[None, :]).reshape(qa, k, q, k)
    ok = (d2 <= reach * reach) & (facing >= cos_gate)
    sup = np.where(ok, sc.astype(np.float32).reshape(q, k), np.float32(0)).reshape(len(sc) - h0, q, k)
    best_k = sup.argmax(axis=2)  # (A, Q): each frame's best supporter of each hypothesis
    best_v = np.take_along_axis(sup, best_k[..., None], axis=2)[..., 0]
    total = best_v.sum(axis=1) / q
    i = int(np.argmax(total))
    a = h0 + i
    far = np.hypot(pos[hyp, 0] - pos[a, 0], pos[hyp, 1] - pos[a, 1]) >= ALT_M
    rival = float(total[far].max()) if far.any() else 0.0
    rows = np.flatnonzero(best_v[i] > 0)
    picks = rows * k + best_k[i, rows]
    if rows.size == 0:  # no match scored above 0 (a blank frame, a lens cap): hypothesis a, unsupported
        rows, picks = np.array([a // k]), np.array([a])
    agree = len(rows) / q
    # the pose where the clip ends: fit on the supporters of its last SPAN_S (on all, if too few)
    recent = times[rows] >= t_last - SPAN_S - 1e-6
    if recent.sum() >= 3:
        rows, picks = rows[recent], picks[recent]
    w = sc[picks]
    tr = times[rows]
    p = pos[picks]
    dh = wrap_deg(hd[picks] - hd[a])
    if len(rows) >= 3 and np.ptp(tr) > 0:
        x = _fit_at(tr, p[:, 0], w, t_last)
        y = _fit_at(tr, p[:, 1], w, t_last)
        h = hd[a] + _fit_at(tr, dh, w, t_last)
        # never extrapolate beyond what a walker covers: stay near the last supporter
        lx, ly = p[-1]
        d = np.hypot(x - lx, y - ly)
        lim = NEAR_M + WALK_MPS * (t_last - tr[-1])
        if d > lim:
            x, y = lx + (x - lx) * lim / d, ly + (y - ly) * lim / d
    else:
        x, y = p[-1]
        h = hd[picks[-1]]
    return Estimate(
        float(x), float(y), float(h % 360.0), int(m.index.ravel()[picks[-1]]), float(total[i]), rival, agree
    )


def _fit_at(t: np.ndarray, v: np.ndarray, w: np.ndarray, at: float) -> float:
    """Weighted least-squares line v(t), evaluated at `at`."""
    w = np.maximum(w, 1e-6)
    sw = w.sum()
    tm = (w * t).sum() / sw
    vm = (w * v).sum() / sw
    dt = t - tm
    var = (w * dt * dt).sum()
    slope = (w * dt * (v - vm)).sum() / var if var > 1e-12 * sw else 0.0
    return float(vm + slope * (at - tm))


def median(m: Matches, xy: np.ndarray, times: np.ndarray, conf: dict[str, Any]) -> Estimate:
    """The paper's aggregation: the median of each frame's best venue index (stage-1 ranking).

    Its support and rival are measured like `sequence`'s (verified scores near the answer, and
    at least ALT_M away from it) so that the one calibrated confidence model applies to both.
    """
    best = m.index[:, 0]
    med = int(np.sort(best)[(len(best) - 1) // 2])
    # the heading of the last frame against the median frame, if it was a candidate of that frame
    last = m.index[-1]
    j = np.flatnonzero(last == med)
    h = float(m.heading[-1, j[0]]) if j.size else float(m.heading[-1, 0])
    d = np.hypot(*(xy[m.index] - xy[med]).transpose(2, 0, 1))  # (Q, k) distance to the answer
    sc = np.maximum(m.score, 0.0)
    support = float(np.where(d <= 2.0, sc, 0.0).max(axis=1).mean())
    rival = float(np.where(d >= ALT_M, sc, 0.0).max(axis=1).mean())
    agree = float(np.mean(np.hypot(*(xy[best] - xy[med]).T) <= 2.0))
    return Estimate(float(xy[med, 0]), float(xy[med, 1]), h % 360.0, med, support, rival, agree)


def field_of(e: Any, name: str) -> float:
    """A field of an answer (an object with it as an attribute, or an evaluation row with the key)."""
    return float(e[name] if isinstance(e, Mapping) else getattr(e, name))


def logistic(coef: Sequence[float], inputs: Sequence[float]) -> float:
    """logistic(w0 + w . inputs): the calibrated confidence models' form (this one's, tracking's)."""
    z = coef[0] + sum(wi * xi for wi, xi in zip(coef[1:], inputs, strict=True))
    return float(1.0 / (1.0 + np.exp(-z)))


# What the confidence model may read from an answer (an Estimate, or an evaluation row with the
# same fields). Support: how well the clip's frames agree with the place; margin: how much better
# it is than the best other place >= ALT_M away (repetitive corridors make that rival close);
# sqrt_margin: its square root (0 for the median's negative margins), steep where two places
# nearly tie: a margin of 0.01 counts half of one of 0.04. A tie between two doors of a corridor
# of identical doors is a coin toss, however well both match (docs/benchlog.md, "Ties").
def _margin(e: Estimate | Mapping[str, Any]) -> float:
    return field_of(e, "support") - field_of(e, "rival")


CONFIDENCE_INPUTS: dict[str, Callable[[Estimate | Mapping[str, Any]], float]] = {
    "support": lambda e: field_of(e, "support"),
    "margin": _margin,
    "sqrt_margin": lambda e: float(np.sqrt(max(_margin(e), 0.0))),
    "rel_margin": lambda e: _margin(e) / max(field_of(e, "support"), 1e-6),
    "agree": lambda e: field_of(e, "agree"),
}


# What the tracking filter's confidence model may read from a pose (tracking_state.TrackPose, or a row
# of bench/tracking.py with its fields); here, beside the clip's, so that checking a venue's
# settings (settings.py) does not load the filter
TRACK_CONFIDENCE_INPUTS: dict[str, Callable[[Any], float]] = {
    "mass": lambda p: field_of(p, "mass"),
    "far": lambda p: field_of(p, "far"),
    "spread": lambda p: min(field_of(p, "spread_m"), 20.0) / 10.0,
    # a belief of one or two clips is as sure as those clips: a young track is less reliable
    "young": lambda p: 1.0 / max(1.0, field_of(p, "updates")),
}


def confidence_inputs(e: Estimate | Mapping[str, Any], names: list[str]) -> list[float]:
    return [CONFIDENCE_INPUTS[n](e) for n in names]


def confidence(e: Estimate | Mapping[str, Any], conf: dict[str, Any]) -> float:
    """Calibrated probability that the answer is within 2 m: logistic on the inputs named by
    `confidence_features` (a venue modelled before that key existed used support and margin).

    Coefficients are fit on the tuning families' answers (bench/calibrate.py) and stored in the
    preset, so a venue keeps the model it was modelled with.
    """
    names = conf.get("confidence_features", ["support", "margin"])
    return logistic(conf["confidence_coef"], confidence_inputs(e, names))


AGGREGATORS = {"sequence": sequence, "median": median}
