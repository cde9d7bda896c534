"""The floor plan annotated with an answer: the matched modelling path, an accuracy circle, the
position and a heading arrow. For sighted helpers and for reports; the user hears the answer.

`?plan=1` is a public request, so its cost must not grow with the plan an admin uploaded: each
worker decodes a plan once per version of its file, scaled down to VIEW_MAX_PX on its long side,
and a request then draws on a copy of that small image and encodes it.
"""

from __future__ import annotations

import math
import threading
from collections import OrderedDict
from pathlib import Path

import cv2
import numpy as np

PATH_BGR = (200, 120, 0)  # the matched modelling path
DOT_BGR = (0, 0, 220)
CIRCLE_BGR = (0, 140, 255)
VIEW_MAX_PX = 1600  # the annotated plan's long side: a phone or a report shows no more
CACHED_PLANS = 8  # prepared plans a worker keeps (at most 7.7 MB each)

_plans: OrderedDict[tuple[str, int, int, int], tuple[np.ndarray, float]] = OrderedDict()
_plans_lock = threading.Lock()


def prepared_plan(plan: Path) -> tuple[np.ndarray, float]:
    """(BGR image of at most VIEW_MAX_PX a side, its scale to the plan's pixels), decoded once per
    version of the file (a new upload replaces the file: a new inode and time) and kept per worker."""
    st = plan.stat()  # FileNotFoundError is an OSError, as an unreadable plan is
    key = (str(plan), st.st_ino, st.st_mtime_ns, st.st_size)
    with _plans_lock:
        hit = _plans.get(key)
        if hit is not None:
            _plans.move_to_end(key)
            return hit
    img = cv2.imread(str(plan), cv2.IMREAD_COLOR)  # outside the lock: other requests keep drawing
    if img is None:
        raise OSError(f"{plan}: floor plan image is missing or unreadable")
    f = min(1.0, VIEW_MAX_PX / max(img.shape[:2]))
    if f < 1.0:
        size = (max(1, round(img.shape[1] * f)), max(1, round(img.shape[0] * f)))
        img = cv2.resize(img, size, interpolation=cv2.INTER_AREA)
    img.setflags(write=False)  # shared by every request of this worker: each draws on a copy
    with _plans_lock:
        for k in [k for k in _plans if k[0] == key[0]]:  # older versions of this plan
            del _plans[k]
        _plans[key] = (img, f)
        while len(_plans) > CACHED_PLANS:
            _plans.popitem(last=False)
    return img, f


def annotate(
    plan: Path,
    px_per_m: float,
    x: float,
    y: float,
    heading_deg: float,
    accuracy_m: float | None,
    path_xy: np.ndarray,
) -> bytes:
    """-> PNG bytes of the plan at most VIEW_MAX_PX a side. `path_xy` (N, 2) metres: the modelling
    frames around the match."""
    base, f = prepared_plan(plan)
    img = base.copy()
    s = float(px_per_m) * f  # pixels a metre on the image drawn
    pts = np.round(np.asarray(path_xy, np.float64) * s).astype(np.int32)
    if len(pts) > 1:
        cv2.polylines(img, [pts.reshape(-1, 1, 2)], False, PATH_BGR, max(2, int(s * 0.15)), cv2.LINE_AA)
    c = (int(round(x * s)), int(round(y * s)))
    if accuracy_m:
        cv2.circle(img, c, max(3, int(round(accuracy_m * s))), CIRCLE_BGR, max(1, int(s * 0.08)), cv2.LINE_AA)
    h = math.radians(heading_deg)  # plan heading: (sin h, -cos h)
    tip = (int(round(c[0] + math.sin(h) * 1.5 * s)), int(round(c[1] - math.cos(h) * 1.5 * s)))
    cv2.arrowedLine(img, c, tip, DOT_BGR, max(2, int(s * 0.12)), cv2.LINE_AA, tipLength=0.35)
    cv2.circle(img, c, max(3, int(s * 0.3)), DOT_BGR, -1, cv2.LINE_AA)
    ok, buf = cv2.imencode(".png", img)
    return bytes(buf) if ok else b""
