"""Modelling walk paths (`walk_path.json`, docs/formats.md): where the recorder was at each video frame.

Positions between waypoints are linear in time; the heading is the direction of travel plus
`heading_offset_deg`. Frames outside the first and last waypoint have no pose and are not used.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from .errors import OmninavError, finite, read_json


@dataclass(frozen=True)
class WalkPath:
    fps: float
    times: np.ndarray  # (N,) seconds, strictly increasing
    xy: np.ndarray  # (N, 2) plan metres
    heading_offset: float

    def pose_at(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Times (s) -> positions (T, 2), headings (T,) in [0, 360), and a mask of covered times.

        The heading of a time is the direction of the leg it lies on; at a waypoint, of the leg that
        starts there (the recorder has turned), and at the last one, of the last leg.
        """
        t = np.asarray(t, np.float64)
        ok = (t >= self.times[0] - 1e-9) & (t <= self.times[-1] + 1e-9)
        x = np.interp(t, self.times, self.xy[:, 0])
        y = np.interp(t, self.times, self.xy[:, 1])
        leg = np.clip(np.searchsorted(self.times, t, side="right") - 1, 0, len(self.times) - 2)
        h = np.mod(self.leg_headings()[leg] + self.heading_offset, 360.0)
        h[h >= 360.0] = 0.0  # mod of a tiny negative number rounds to 360.0
        return np.stack([x, y], -1), h, ok

    def leg_headings(self) -> np.ndarray:
        """(N-1,) the direction of travel of each leg, degrees clockwise from up.

        A leg that goes nowhere (the same point tagged twice: the recorder stood still) keeps the
        heading of the leg before it (or, at the start, of the first leg that moves): standing
        still does not turn anyone round, while atan2(0, -0) would say 180.
        """
        d = np.diff(self.xy, axis=0)
        h = np.degrees(np.arctan2(d[:, 0], -d[:, 1]))  # heading h points along (sin h, -cos h)
        moving = np.hypot(d[:, 0], d[:, 1]) > 1e-6
        if not moving.any():
            return np.zeros(len(d))
        idx = np.where(moving, np.arange(len(d)), -1)
        idx = np.maximum.accumulate(idx)  # the last moving leg at or before each leg
        idx[idx < 0] = int(np.argmax(moving))  # before the first move: the first moving leg
        return h[idx]


def parse_walk_path(d: Any, where: str = "walk path") -> WalkPath:
    if not isinstance(d, dict):
        raise OmninavError(f"{where}: a walk path must be a JSON object")
    fps = finite(d.get("fps", 30), "'fps'", where)
    if fps <= 0:
        raise OmninavError(f"{where}: 'fps' must be positive")
    wps = d.get("waypoints")
    if not isinstance(wps, list) or len(wps) < 2:
        raise OmninavError(f"{where}: 'waypoints' must be a list of at least two waypoints")
    times, xy = [], []
    for i, w in enumerate(wps):
        if not isinstance(w, dict):
            raise OmninavError(f"{where}: waypoint {i} is not an object")
        if "t" in w:
            t = finite(w["t"], f"waypoint {i} 't'", where)
        elif "frame" in w:
            t = finite(w["frame"], f"waypoint {i} 'frame'", where) / fps
            if not np.isfinite(t):  # a huge frame number over a tiny fps
                raise OmninavError(f"{where}: waypoint {i} 'frame' / 'fps' is not a finite time")
        else:
            raise OmninavError(f"{where}: waypoint {i} needs 'frame' or 't'")
        for k in ("x", "y"):
            if k not in w:
                raise OmninavError(f"{where}: waypoint {i} is missing '{k}'")
        times.append(t)
        xy.append((finite(w["x"], f"waypoint {i} 'x'", where), finite(w["y"], f"waypoint {i} 'y'", where)))
    tt = np.array(times)
    bad = np.flatnonzero(np.diff(tt) <= 0)
    if bad.size:
        i = int(bad[0]) + 1
        raise OmninavError(f"{where}: waypoints must be in increasing time; waypoint {i} is not after waypoint {i - 1}")
    if tt[0] < 0:
        raise OmninavError(f"{where}: waypoint times must not be negative")
    off = finite(d.get("heading_offset_deg", 0.0), "'heading_offset_deg'", where)
    return WalkPath(fps, tt, np.array(xy, np.float64), off)


def load_walk_path(path: str | Path) -> WalkPath:
    return parse_walk_path(read_json(path, "walk path file"), where=str(path))
