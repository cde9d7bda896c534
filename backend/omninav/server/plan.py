"""The floor plan annotated with an answer: the matched modelling path, an accuracy circle, the
position and a heading arrow. For sighted helpers and for reports; the user hears the answer."""

from __future__ import annotations

import math
from pathlib import Path

import cv2
import numpy as np

PATH_BGR = (200, 120, 0)  # the matched modelling path
DOT_BGR = (0, 0, 220)
CIRCLE_BGR = (0, 140, 255)


def annotate(
    plan: Path,
    px_per_m: float,
    x: float,
    y: float,
    heading_deg: float,
    accuracy_m: float | None,
    path_xy: np.ndarray,
) -> bytes:
    """-> PNG bytes. `path_xy` (N, 2) metres: the modelling frames around the match."""
    img = cv2.imread(str(plan), cv2.IMREAD_COLOR)
    if img is None:
        raise OSError(f"{plan}: floor plan image is missing or unreadable")
    s = float(px_per_m)
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
