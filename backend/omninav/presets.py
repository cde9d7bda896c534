"""Named feature presets: the parameters that travel together, stored with every venue.

A venue always answers with the settings it was modelled with (its `settings.json`), so a preset
may change in a later release without breaking venues modelled today. `resolve` merges a preset
over the defaults, as hloc's `confs` do.
"""

from __future__ import annotations

import copy
from collections.abc import Mapping
from typing import Any

from . import settings
from .errors import OmninavError
from .settings import check
from .settings_upgrade import LATER_FEATURE_KEYS, VERSION

# Every key's default: the stages' typed settings' (settings.py, docs/settings.md).
DEFAULTS: dict[str, Any] = settings.DEFAULTS


def setting(conf: Mapping[str, Any], key: str) -> Any:
    """A venue's setting: its own, else today's default (a copy: a caller that changes a list it
    was given changes no other venue's defaults). Settings read from a venue
    (settings_upgrade.upgrade) and made by `resolve` carry every key; a dict made by hand may not."""
    if key in conf:
        return conf[key]
    return copy.deepcopy(DEFAULTS[key])


PRESETS: dict[str, dict[str, Any]] = {
    # The paper's method as published: the intensity curve of one band, median of best indices.
    "paper": {
        "channels": ["I"],
        "bands": [[-20.0, 20.0]],
        "n_harmonics": 32,
        "aggregate": "median",
        "shared_candidates": False,
    },
    # The paper's six curves (H, S, I and their gradients), one band, with our aggregation.
    "six": {"n_harmonics": 32},
    # Our default. Each change over "six" is measured in docs/benchlog.md:
    # - gray-world colour constancy: a colour cast no longer moves hue and saturation;
    # - opponent colours (R-G, R+G-2B) instead of hue and saturation: stable at low saturation;
    # - two bands, below and above the horizon: doors and floor vs. boards, windows and lights
    #   (TWO_BANDS: 16 harmonics x 12 curves, the same 768 bytes a frame as "six");
    # - curves softly clipped at 1.25 sd: a sunlit window or one strong edge weighs less;
    # - intensity and its gradient in five 10-degree bands, the colours over the whole band:
    #   where along a corridor of identical doors the camera is shows in how the corridor's
    #   light and edges are spread in elevation, which a 25-degree band's column sums average
    #   away (docs/benchlog.md, "Five bands of intensity"); 14 curves, 896 bytes a frame.
    #   `channels` is then the union the bands use: with `band_channels` set it does not choose
    #   the curves (it still counts in the settings id);
    # - levelled: each frame unwarped through the tilt its own upright edges show (level.py), two
    #   passes: five narrow bands feel a phone held a few degrees off vertical (docs/benchlog.md,
    #   "Levelling").
    "default": {
        "gray_world": True,
        "channels": ["I", "O1", "O2", "dI", "dO1", "dO2"],
        "bands": [[-25.0, -15.0], [-15.0, -5.0], [-5.0, 5.0], [5.0, 15.0], [15.0, 25.0], [-25.0, 25.0]],
        "band_channels": [["I", "dI"] for _ in range(5)] + [["O1", "O2", "dO1", "dO2"]],
        "n_harmonics": 16,
        "candidates": 16,
        "soft_clip_sd": 1.25,
        "level_iters": 2,
    },
    # A venue option for buildings where the default's narrow bands do not hold (docs/benchlog.md,
    # "Three sources"): the six curves of "six" with gray world and opponent colours over one wide
    # band, softly clipped and levelled, searched as the default searches. Where along the wall a
    # row lands moves with the phone's height, its tilt and the user's place across the corridor;
    # a 40-degree band's column means barely move with it, five 10-degree bands' do. It gives up
    # part of the narrow bands' hold on look-alike doors for that. A building's evaluation walk
    # says which preset it needs (`omninav choose-preset`, choose.py). 768 bytes a frame.
    "wide": {
        "gray_world": True,
        "channels": ["I", "O1", "O2", "dI", "dO1", "dO2"],
        "bands": [[-20.0, 20.0]],
        "n_harmonics": 32,
        "soft_clip_sd": 1.25,
        "level_iters": 2,
    },
}

# A venue option (issue 43): the default's features, and ORB keypoints stored for a modelled frame
# every half metre (verify.py, ~34 KB each); a clip located from its frames (a video, frames, the
# CLI) has its candidate places checked by them, and the answer moves where the geometry says so.
# Not the default: the phone sends no local features yet, and real imagery with positions to judge
# it on is still missing (docs/decisions.md, "Local features").
PRESETS["verified"] = {**PRESETS["default"], "local_features": 900}


# The default preset's bands before per-band channels (two bands, every channel in each: 12 curves,
# 768 bytes a frame), and without levelling (it came later): venues modelled then keep them; what
# was measured on them pins them.
TWO_BANDS: dict[str, Any] = {"bands": [[-25.0, 0.0], [0.0, 25.0]], "band_channels": None, "level_iters": None}


def resolve(name: str = "default", overrides: dict[str, Any] | None = None) -> dict[str, Any]:
    """A preset over the defaults, with `overrides` over both, checked (settings.check) and
    stamped with the preset's name and the settings' format version."""
    if name not in PRESETS:
        raise OmninavError(f"unknown preset {name!r} (known: {', '.join(sorted(PRESETS))})")
    conf = copy.deepcopy(DEFAULTS)
    conf.update(copy.deepcopy(PRESETS[name]))
    conf.update(copy.deepcopy(overrides or {}))
    conf["preset"] = name
    conf["version"] = VERSION
    check(conf)
    return conf


# The settings that change what a feature record contains: a record made with other values of
# these cannot be compared with a venue's frames.
FEATURE_KEYS = (
    "pano_width", "oversample", "row_step_deg", "bands", "channels", "gray_world", "n_harmonics", "soft_clip_sd",
    "band_channels", "level_iters",
)  # fmt: skip


def feature_keys(conf: dict[str, Any]) -> list[str]:
    """The FEATURE_KEYS a record for a venue with `conf` depends on, sorted: a key added after
    venues were modelled without it (settings.LATER_FEATURE_KEYS) counts only where set, so a
    record for such a venue keeps the id it had."""
    return sorted(k for k in FEATURE_KEYS if k not in LATER_FEATURE_KEYS or conf.get(k) is not None)


def settings_id(conf: dict[str, Any]) -> int:
    """CRC-32 of the feature settings: carried in every record, checked against the venue's."""
    import json
    import zlib

    canon = json.dumps({k: conf[k] for k in feature_keys(conf)}, sort_keys=True, separators=(",", ":"))
    return zlib.crc32(canon.encode())


def band_channels(conf: dict[str, Any]) -> list[list[str]]:
    """Each band's channels, in the record's order: `band_channels` where set, else `channels`
    for every band (what every venue modelled before `band_channels` has)."""
    per = conf.get("band_channels")
    if per is None:
        return [list(conf["channels"]) for _ in conf["bands"]]
    return [list(c) for c in per]


def n_curves(conf: dict[str, Any]) -> int:
    return sum(len(c) for c in band_channels(conf))
