"""Clip aggregation: from per-frame candidate matches to one pose at the clip's last frame.

`median` is the paper's: each frame's best venue frame, the median of their indices.
`sequence` (default) uses what a clip is: frames in time order, taken from places close together
while facing roughly the same way. Every verified match is a hypothesis of where the clip ends;
it is supported, per query frame, by that frame's best match that lies within reach in the time
between the two frames and faces within a gate. The best-supported hypothesis wins, and a
weighted straight-line fit of its supporters over time gives the pose at the last frame.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from .heading import wrap_deg
from .index import Matches

WALK_MPS = 1.8  # fastest walking pace we allow between two frames of a clip
NEAR_M = 0.45  # slack on top: matching granularity and the modelling track's own error
ALT_M = 3.0  # a rival hypothesis this far away is a different place


@dataclass
class Estimate:
    x: float
    y: float
    heading: float
    venue_row: int  # venue frame that best matches the last supported query frame
    support: float  # mean over frames of the best supporting score, in [-1, 1]
    rival: float  # the same for the best hypothesis >= ALT_M away
    agree: float  # fraction of frames with a supporting match


def sequence(m: Matches, xy: np.ndarray, times: np.ndarray, conf: dict[str, Any]) -> Estimate:
    """m: (Q, k) matches; xy: (N, 2) venue frame positions; times: (Q,) seconds of the frames."""
    q, k = m.index.shape
    pos = xy[m.index.ravel()].astype(np.float64)  # (P, 2)
    hd = m.heading.ravel().astype(np.float64)
    sc = np.maximum(m.score.ravel().astype(np.float64), 0.0)
    row = np.repeat(np.arange(q), k)
    t = np.asarray(times, np.float64)[row]
    # hypotheses a x pairs p, float32: 25k-100k entries, so memory traffic is the cost
    p32 = pos.astype(np.float32)
    d2 = (p32[:, None, 0] - p32[None, :, 0]) ** 2 + (p32[:, None, 1] - p32[None, :, 1]) ** 2
    t32 = t.astype(np.float32)
    reach = np.minimum(NEAR_M + WALK_MPS * np.abs(t32[:, None] - t32[None, :]), conf.get("clip_radius_m", 1.5) + NEAR_M)
    # heading gate as a dot product of unit vectors: cos(ha - hp) >= cos(gate), no modulo
    hr = np.deg2rad(hd).astype(np.float32)
    u, v = np.cos(hr), np.sin(hr)
    ok = (d2 <= reach * reach) & (
        u[:, None] * u[None, :] + v[:, None] * v[None, :] >= np.cos(np.deg2rad(conf["heading_gate_deg"]))
    )
    sup = np.where(ok, sc.astype(np.float32)[None, :], np.float32(0)).reshape(len(sc), q, k)
    best_k = sup.argmax(axis=2)  # (A, Q): each frame's best supporter of each hypothesis
    best_v = np.take_along_axis(sup, best_k[..., None], axis=2)[..., 0]
    total = best_v.sum(axis=1) / q
    a = int(np.argmax(total))
    far = np.hypot(pos[:, 0] - pos[a, 0], pos[:, 1] - pos[a, 1]) >= ALT_M
    rival = float(total[far].max()) if far.any() else 0.0
    rows = np.flatnonzero(best_v[a] > 0)
    picks = rows * k + best_k[a, rows]
    if rows.size == 0:  # no match scored above 0 (a blank frame, a lens cap): hypothesis a, unsupported
        rows, picks = np.array([a // k]), np.array([a])
    w = sc[picks]
    tr = np.asarray(times, np.float64)[rows]
    t_last = float(np.asarray(times, np.float64)[-1])
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
        float(x), float(y), float(h % 360.0), int(m.index.ravel()[picks[-1]]), float(total[a]), rival, len(rows) / q
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


def confidence(e: Estimate, conf: dict[str, Any]) -> float:
    """Calibrated probability that the answer is within 2 m (logistic on support and margin).

    Support: how well the clip's frames agree with the place; margin: how much better it is than
    the best other place >= 3 m away (repetitive corridors make that rival close).

    Coefficients are fit on synthetic venues (bench/calibrate.py) and stored in the preset.
    """
    w0, w_sup, w_margin = conf["confidence_coef"]
    z = w0 + w_sup * e.support + w_margin * (e.support - e.rival)
    return float(1.0 / (1.0 + np.exp(-z)))


AGGREGATORS = {"sequence": sequence, "median": median}
