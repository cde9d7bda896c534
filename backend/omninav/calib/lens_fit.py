"""Does a lens profile fit the ring the frames show? A clip-on lens never sits where it sat when
its profile was made: `fit_lens` compares the ring found (ring.py) with the profile's and says
"same", "corrected" (the profile moved and scaled to the ring: `scaled_lens`), "too_far", "cut"
or "no_ring", in words a user can act on. The phone's worker keeps the same rule and thresholds
(web/src/worker/ring.ts, `fitLens`).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..errors import OmninavError
from ..lens import Catadioptric, Lens
from .ring import CONSTANTS, NoRing, Ring, find_ring, visible_share

# fit_lens thresholds, read with the phone's port (ring.ts) from ring_constants.json
STILL_PX = float(CONSTANTS["STILL_PX"])
STILL_SCALE = float(CONSTANTS["STILL_SCALE"])
TOO_FAR_SHARE = float(CONSTANTS["TOO_FAR_SHARE"])
CUT_MARGIN = float(CONSTANTS["CUT_MARGIN"])


@dataclass(frozen=True)
class LensFit:
    verdict: str  # "same" | "corrected" | "too_far" | "cut" | "no_ring"
    lens: Lens  # corrected when "corrected", else the profile unchanged (equirectangular: itself)
    dx: float
    dy: float
    scale: float
    moved_px: float
    message: str  # the verdict in words, one line

    def to_dict(self) -> dict[str, Any]:
        return {
            "verdict": self.verdict,
            "fits": self.verdict in ("same", "corrected"),
            "dx": round(self.dx, 3),
            "dy": round(self.dy, 3),
            "scale": round(self.scale, 5),
            "moved_px": round(self.moved_px, 3),
            "message": self.message,
            "lens": self.lens.to_dict(),
        }


def _moved_words(dx: float, dy: float, s: float) -> str:
    """'moved 6.2 px (right 5.0, down 3.7) and is 0.4 % larger'."""
    parts = []
    if abs(dx) >= 0.05:
        parts.append(f"{'right' if dx > 0 else 'left'} {abs(dx):.1f}")
    if abs(dy) >= 0.05:
        parts.append(f"{'down' if dy > 0 else 'up'} {abs(dy):.1f}")
    where = f" ({', '.join(parts)})" if parts else ""
    pct = (s - 1.0) * 100.0
    size = "the same size" if abs(pct) < 0.05 else f"{abs(pct):.1f} % {'larger' if pct > 0 else 'smaller'}"
    return f"moved {math.hypot(dx, dy):.1f} px{where} and is {size}"


def scaled_lens(lens: Catadioptric, d: tuple[float, float], s: float) -> Catadioptric:
    """The profile for a ring moved by d and s times larger: centre and ring moved, radii scaled,
    elevation(r) -> elevation(r / s), a sensor's unit scaled with them (its matrix and decentring
    act on the picture's shape, which a larger picture keeps)."""
    ring = lens.ring
    if ring is not None:
        ring = (ring[0] + d[0], ring[1] + d[1], ring[2] * s, ring[3] * s)
    sensor = lens.sensor if lens.sensor is None else dataclasses.replace(lens.sensor, scale=lens.sensor.scale * s)
    return dataclasses.replace(
        lens,
        center=(lens.center[0] + d[0], lens.center[1] + d[1]),
        r_inner=lens.r_inner * s,
        r_outer=lens.r_outer * s,
        elevation_poly=tuple(c / s**k for k, c in enumerate(lens.elevation_poly)),
        ring=ring,
        sensor=sensor,
    )


def fit_lens(lens: Catadioptric, ring: Ring | None) -> LensFit:
    """Does the profile fit the ring the frames show? Corrects it when the lens moved a little.

    With ref = lens.reference_ring(): d = ring.center - ref.center, s = ring.r_outer / ref.r_outer.
    The verdicts, checked in this order: "no_ring" (ring None); "cut" when the profile's usable circle
    (lens.r_outer around lens.center), moved by d and scaled by s as the correction would, is more
    than CUT_MARGIN (0.02) less visible than as it is (a ring cut by design, the same in both, is
    not cut); "too_far" when
    |d| > TOO_FAR_SHARE (0.10) * ref.r_outer or |s - 1| > 0.10; "same" when |d| < STILL_PX (0.25)
    and |s - 1| < STILL_SCALE (0.002): the profile itself is returned; else "corrected":
    `scaled_lens(lens, d, s)`.
    """
    if ring is None:
        return LensFit("no_ring", lens, 0.0, 0.0, 1.0, 0.0, "The panoramic lens does not seem to be attached")
    if tuple(ring.image_size) != tuple(lens.image_size):
        raise OmninavError(
            f"the frames are {ring.image_size[0]}x{ring.image_size[1]} but the lens profile is for "
            f"{lens.image_size[0]}x{lens.image_size[1]}: film at the profile's resolution"
        )
    rx, ry, _, ro = lens.reference_ring()
    dx, dy = ring.center[0] - rx, ring.center[1] - ry
    s = ring.r_outer / ro
    moved = math.hypot(dx, dy)
    words = _moved_words(dx, dy, s)
    # the profile's usable circle as it is, and as the correction would move and scale it
    vis_ref = visible_share(lens.center, lens.r_outer, lens.image_size)
    c_now = (lens.center[0] + dx, lens.center[1] + dy)
    vis_now = visible_share(c_now, lens.r_outer * s, lens.image_size)
    if vis_now < vis_ref - CUT_MARGIN:
        return LensFit(
            "cut", lens, dx, dy, s, moved, f"The lens is not centred over the camera; clip it on again (ring {words})"
        )
    if moved > TOO_FAR_SHARE * ro or abs(s - 1.0) > TOO_FAR_SHARE:
        return LensFit(
            "too_far",
            lens,
            dx,
            dy,
            s,
            moved,
            f"The lens ring {words}: too far from the profile to correct; clip the lens on again "
            "or calibrate it (omninav calib lens)",
        )
    if moved < STILL_PX and abs(s - 1.0) < STILL_SCALE:
        return LensFit("same", lens, dx, dy, s, moved, f"The lens ring is where the profile expects it ({words})")
    return LensFit("corrected", scaled_lens(lens, (dx, dy), s), dx, dy, s, moved, f"The lens ring {words}: corrected")


def corrected_lens(lens: Lens, frames: Sequence[np.ndarray]) -> LensFit:
    """`fit_lens` on the ring of `frames`; an equirectangular profile has no ring: "same"."""
    if not isinstance(lens, Catadioptric):
        return LensFit("same", lens, 0.0, 0.0, 1.0, 0.0, "An equirectangular camera has no lens ring to check")
    try:
        ring: Ring | None = find_ring(frames)
    except NoRing:
        ring = None
    except OmninavError as e:  # frames too small to look for a ring in: the profile as it is
        return LensFit("no_ring", lens, 0.0, 0.0, 1.0, 0.0, str(e))
    return fit_lens(lens, ring)
