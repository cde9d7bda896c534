"""The accuracy changes since the paper's method, as named configurations the benches share.

Each is a preset and the settings over it; the ladder adds one change a rung, in the order the
changes were made (docs/benchlog.md), so a table over the ladder is the ablation the accuracy
issue asks for. bench/foreign.py and bench/sources.py take these names.
"""

from __future__ import annotations

import dataclasses
from typing import Any

from omninav.lens import Catadioptric, Lens
from omninav.presets import TWO_BANDS

O = ["I", "O1", "O2", "dI", "dO1", "dO2"]
FIVE = {"level_iters": None}  # the five bands of intensity before levelling
NO_SHARED = {"shared_candidates": False}  # shared candidates came after levelling
CONFIGS: dict[str, tuple[str, dict[str, Any]]] = {
    "paper": ("paper", {}),
    "paper-sequence": ("paper", {"aggregate": "sequence"}),
    "six": ("six", {"aggregate": "median", **NO_SHARED}),
    "six-sequence": ("six", NO_SHARED),
    "gray-world": ("six", {"gray_world": True, **NO_SHARED}),
    "opponent": ("six", {"gray_world": True, "channels": O, **NO_SHARED}),
    "two-bands": ("default", {"soft_clip_sd": None, **TWO_BANDS, **NO_SHARED}),
    "soft-clip": ("default", {**TWO_BANDS, **NO_SHARED}),
    "five-bands": ("default", {**FIVE, **NO_SHARED}),
    "levelled": ("default", NO_SHARED),
    "shared": ("default", {"shortlist": 16}),
    "default": ("default", {}),
}

# the ladder's rungs in the order the changes were made (the rest of CONFIGS are candidates)
LADDER = tuple(CONFIGS)

# Candidates for a default that holds beyond our renderer (docs/benchmarks.md, "Accuracy on three sources")
CONFIGS.update(
    {
        "two-bands-shared": ("default", {**TWO_BANDS}),
        # one band of the six curves (the "opponent" rung) with today's search, and with each of
        # the later feature changes that do not place curves in elevation
        "one-band-shared": ("six", {"gray_world": True, "channels": O}),
        "one-band-soft": ("six", {"gray_world": True, "channels": O, "soft_clip_sd": 1.25}),
        # the venue option presets.py calls "wide" (the same settings: the benches' cached runs)
        "one-band-levelled": ("six", {"gray_world": True, "channels": O, "soft_clip_sd": 1.25, "level_iters": 2}),
        "two-bands-levelled": ("default", {**TWO_BANDS, "level_iters": 2}),
        "three-bands": (
            "default",
            {
                "bands": [[-25.0, -8.0], [-8.0, 8.0], [8.0, 25.0], [-25.0, 25.0]],
                "band_channels": [["I", "dI"]] * 3 + [["O1", "O2", "dO1", "dO2"]],
            },
        ),
        # the venue option presets.py calls "verified": the default, its candidates checked by
        # local features (verify.py) where a clip is located from its frames
        "verified": ("verified", {}),
        "overlap-bands": (
            "default",
            {
                "bands": [[-25.0, -5.0], [-15.0, 5.0], [-5.0, 15.0], [5.0, 25.0], [-25.0, 25.0]],
                "band_channels": [["I", "dI"]] * 4 + [["O1", "O2", "dO1", "dO2"]],
            },
        ),
    }
)


def elevation_off(lens: Lens, deg: float) -> Lens:
    """`lens` with its elevation calibration off by `deg` (every ring radius read `deg` higher):
    a profile made for another phone, or a calibration a little wrong. A 360 camera's lens has no
    elevation profile and comes back as it is."""
    if not deg or not isinstance(lens, Catadioptric):
        return lens
    poly = list(lens.elevation_poly)
    poly[0] += deg
    return dataclasses.replace(lens, elevation_poly=tuple(poly))


# Mixes: the robust wide band's six curves and narrow bands of intensity in one record, the
# verification summing over both (the narrow bands weigh as many curves as they have)
WIDE = [-25.0, 25.0]
NARROW = [[-25.0, -15.0], [-15.0, -5.0], [-5.0, 5.0], [5.0, 15.0], [15.0, 25.0]]
CONFIGS.update(
    {
        "mix-i-di": (
            "default",
            {"bands": [WIDE, *NARROW], "band_channels": [O] + [["I", "dI"]] * 5},
        ),
        "mix-i": ("default", {"bands": [WIDE, *NARROW], "band_channels": [O] + [["I"]] * 5}),
    }
)
