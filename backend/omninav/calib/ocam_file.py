"""OCamCalib's `calib_results.txt` (Scaramuzza's toolbox, and pyomniunwarp's variant): read into
our model (`read_ocamcalib`: an `Ocam`) and its inverse polynomial applied as OCamCalib applies it
(`world2cam_invpol`), for lenses calibrated with that toolbox and for checking our fit against it.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import OmninavError
from .ocam import Ocam


@dataclass(frozen=True)
class OcamCalibFile:
    """The fields of OCamCalib's `calib_results.txt` (pyomniunwarp adds the last two)."""

    ss: tuple[float, ...]
    invpol: tuple[float, ...]
    center_rc: tuple[float, float]  # row, column (0-based)
    cde: tuple[float, float, float]
    size_hw: tuple[int, int]
    roi: tuple[float, float] | None = None  # (max, min) radius of the ring, pyomniunwarp
    crop_lr: tuple[int, int] | None = None  # pixels cropped on the left and right, pyomniunwarp


def read_ocamcalib_file(path: Path) -> OcamCalibFile:
    """Parse `calib_results.txt`: comment lines start with '#', then one line per field."""
    try:
        lines = [ln.split() for ln in Path(path).read_text().splitlines()]
    except (OSError, UnicodeDecodeError) as e:
        raise OmninavError(f"{path}: not a readable OCamCalib calib_results.txt ({e})") from None
    rows = [[float(x) for x in ln] for ln in lines if ln and not ln[0].startswith("#")]
    if len(rows) < 5 or len(rows[0]) < 2 or int(rows[0][0]) != len(rows[0]) - 1 or int(rows[1][0]) != len(rows[1]) - 1:
        raise OmninavError(f"{path}: not OCamCalib's calib_results.txt (ss, invpol, centre, c d e, size)")
    return OcamCalibFile(
        ss=tuple(rows[0][1:]),
        invpol=tuple(rows[1][1:]),
        center_rc=(rows[2][0], rows[2][1]),
        cde=(rows[3][0], rows[3][1], rows[3][2]),
        size_hw=(int(rows[4][0]), int(rows[4][1])),
        roi=(rows[5][0], rows[5][1]) if len(rows) > 5 and len(rows[5]) >= 2 else None,
        crop_lr=(int(rows[6][0]), int(rows[6][1])) if len(rows) > 6 and len(rows[6]) >= 2 else None,
    )


def read_ocamcalib(path: Path, offset: tuple[float, float] = (0, 0), image_size: tuple[int, int] | None = None) -> Ocam:
    """An `Ocam` from OCamCalib's `calib_results.txt`. `offset` (x, y): where the calibrated
    image's top-left corner lies in the frames it is used on (a crop); `image_size` (w, h) of those
    frames (default: the file's, grown by `offset` and a right crop the file names)."""
    cal = read_ocamcalib_file(path)
    h, w = cal.size_hw
    if image_size is None:
        right = cal.crop_lr[1] if cal.crop_lr else 0
        image_size = (int(w + offset[0] + right), int(h + offset[1]))
    return Ocam(
        center=(cal.center_rc[1] + offset[0], cal.center_rc[0] + offset[1]),
        stretch=cal.cde,
        poly=cal.ss,
        image_size=image_size,
    )


def world2cam_invpol(cal: OcamCalibFile, xyz: np.ndarray, offset: tuple[float, float] = (0, 0)) -> np.ndarray:
    """OCamCalib's own world2cam (its inverse polynomial in theta = atan(z / n)): a check on ours."""
    xyz = np.asarray(xyz, np.float64).reshape(-1, 3)
    n = np.hypot(xyz[:, 0], xyz[:, 1])
    rho = np.polynomial.polynomial.polyval(np.arctan2(xyz[:, 2], n), np.asarray(cal.invpol))
    x, y = xyz[:, 0] / n * rho, xyz[:, 1] / n * rho
    c, d, e = cal.cde
    row = x * c + y * d + cal.center_rc[0] + offset[1]
    col = x * e + y + cal.center_rc[1] + offset[0]
    return np.stack([col, row], -1)
