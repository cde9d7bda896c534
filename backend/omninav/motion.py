"""The phone's motion between two updates of the tracking filter, and a longer clip cut into its
seconds.

The phone sends, with each request, the steps its pedometer counted and the gyroscope's turn
since its last request (`Motion`); a walk's recorded sensors come as an `imu.json`
(docs/formats.md; `Imu`, `parse_imu`). A clip of several seconds is walked by the filter second by
second (`parts`), the request's one motion reading shared among its parts by time (`share`).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from .aggregate import SPAN_S
from .errors import OmninavError, read_json
from .heading import wrap_deg


@dataclass(frozen=True)
class Motion:
    """The phone's own sensors between the previous update and this one."""

    steps: int | None = None  # steps detected (DeviceMotion), None = unknown
    turn_deg: float | None = None  # gyroscope yaw change, clockwise +, None = unknown


STILL_TURN_DEG = 10.0  # a phone that counted no step and turned less than this has not moved


def sensors_still(motion: Motion) -> bool:
    """Whether the phone's sensors say it has not moved since the last update (no step, little
    turn); unknown (no sensors) is not still."""
    return motion.steps == 0 and motion.turn_deg is not None and abs(motion.turn_deg) < STILL_TURN_DEG


def sensors_moved(motion: Motion) -> bool:
    """Whether the phone's sensors say it moved since the last update (a step, or a turn of
    STILL_TURN_DEG or more); unknown is not moved."""
    return bool(motion.steps) or (motion.turn_deg is not None and abs(motion.turn_deg) >= STILL_TURN_DEG)


def faces_as_before(facing: np.ndarray, before: np.ndarray | None, node: int) -> bool:
    """Whether the clip faces at `node` as the last clip did there, within STILL_TURN_DEG (what
    the clip says of a turn where no gyroscope does)."""
    if before is None or len(before) != len(facing) or not (np.isfinite(facing[node]) and np.isfinite(before[node])):
        return False
    return abs(float(wrap_deg(facing[node] - before[node]))) < STILL_TURN_DEG


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
    return parse_imu(read_json(path, "imu file"), where=str(path))
