"""Unwarp a camera frame to a cylindrical panorama (the paper's Eq. 1), via a precomputed remap.

Rows of the panorama are *elevation angles* (top row highest), columns are azimuths clockwise from
the lens's forward direction. Because rows are angles, not pixels, a donut frame and a 360-camera
frame give comparable panoramas, and so comparable curves.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import cv2
import numpy as np

from .lens import Lens, direction_to_pixel


@dataclass(frozen=True)
class UnwarpMap:
    """cv2.remap tables (float32, shape (rows, cols)) and the elevations of the rows."""

    map_x: np.ndarray
    map_y: np.ndarray
    elevations: np.ndarray  # (rows,) degrees, descending
    valid: np.ndarray  # (rows, cols) bool: the lens sees this direction
    border: int  # cv2 border mode: wrap for the 360-camera's seam, constant for the donut


def panorama_elevations(el_top: float, el_bottom: float, step: float) -> np.ndarray:
    n = int(round((el_top - el_bottom) / step)) + 1
    return np.linspace(el_top, el_bottom, n)


def build_map(lens: Lens, elevations: np.ndarray, width: int) -> UnwarpMap:
    """Remap tables for a panorama of `width` columns at the given row elevations.

    Column j looks at azimuth (j + 0.5) * 360 / width: the column's centre, so that averaging
    `oversample` sub-columns lands on the same azimuths as a direct render.
    """
    az = (np.arange(width, dtype=np.float64) + 0.5) * 360.0 / width
    el = np.asarray(elevations, np.float64)
    azg, elg = np.meshgrid(az, el)
    x, y = direction_to_pixel(lens, azg, elg)
    valid = np.isfinite(x) & np.isfinite(y)
    # Unseen directions read a pixel outside the image; BORDER_CONSTANT turns it into 0.
    x = np.where(valid, x, -10.0).astype(np.float32)
    y = np.where(valid, y, -10.0).astype(np.float32)
    border = cv2.BORDER_CONSTANT if lens.model == "catadioptric" else cv2.BORDER_WRAP
    return UnwarpMap(x, y, el.astype(np.float32), valid, border)


def band_map(lens: Lens, conf: dict[str, Any]) -> UnwarpMap:
    """The remap that a feature preset needs: the rows of all its bands, oversampled columns."""
    lo = min(b[0] for b in conf["bands"])
    hi = max(b[1] for b in conf["bands"])
    el = panorama_elevations(hi, lo, conf["row_step_deg"])
    return build_map(lens, el, conf["pano_width"] * conf["oversample"])


def unwarp(frame: np.ndarray, m: UnwarpMap) -> np.ndarray:
    """(H, W, 3) uint8 or float32 frame -> (rows, cols, 3) panorama of the same dtype.

    Bilinear remap: the band is narrow, so this costs ~0.2 ms per 960x720 frame.
    """
    if frame.ndim != 3 or frame.shape[2] != 3:
        raise ValueError(f"unwarp expects an (H, W, 3) colour frame, got shape {frame.shape}")
    return cv2.remap(frame, m.map_x, m.map_y, cv2.INTER_LINEAR, borderMode=m.border)
