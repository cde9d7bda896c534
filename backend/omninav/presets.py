"""Named feature presets: the parameters that travel together, stored with every venue.

A venue always answers with the settings it was modelled with (its `settings.json`), so a preset
may change in a later release without breaking venues modelled today. `resolve` merges a preset
over the defaults, as hloc's `confs` do.
"""

from __future__ import annotations

import copy
import math
from collections.abc import Mapping
from typing import Any

from .errors import OmninavError

DEFAULTS: dict[str, Any] = {
    # Panorama: columns are azimuth clockwise from the lens's forward; rows are elevations.
    "pano_width": 360,  # output columns (1 deg each): the curves' length
    "oversample": 4,  # remap at 4x the columns, then average: anti-aliasing at the donut's rim
    "row_step_deg": 1.0,
    # Elevation bands (deg) over which each channel is summed column-wise (the paper's Eq. 3).
    "bands": [[-20.0, 20.0]],
    # Channels per band. H, S, I and their horizontal gradients are the paper's six curves;
    # O1/O2 are opponent colours, added because hue is unstable at low saturation.
    "channels": ["H", "S", "I", "dH", "dS", "dI"],
    "gray_world": False,  # divide each colour channel by its frame mean: removes casts and gain
    # after normalising, each curve becomes sd * tanh(curve / sd) (curves.soft_clip); None: off
    "soft_clip_sd": None,
    "band_channels": None,  # per band, its own channels (None: every band has `channels`)
    # passes of level.py's tilt estimate from the frame's own upright edges, each frame unwarped
    # through it (None or 0: as the lens sees it, every venue modelled before levelling)
    "level_iters": None,
    "n_harmonics": 32,  # leading FFT harmonics kept (1..K; the DC term carries no shape)
    # Search
    "candidates": 16,  # venue frames kept per query frame by the magnitude stage, then verified
    # each frame of a clip's second verified against every candidate the magnitude stage kept for
    # any frame of that second, keeping its `candidates` best (index.py, "Shared candidates"); a
    # search setting, not a feature one: a venue modelled before it reads this default
    "shared_candidates": True,
    # with shared candidates, stage 1 shortlists this many a frame, every one of a second's
    # shortlists verified, and each frame keeps its `candidates` best (index.py, "The shortlist";
    # docs/benchlog.md): a search setting too, which a venue modelled before it reads as this
    "shortlist": 32,
    # Above `key_project_above` frames, stage 1 first shortlists with keys projected to
    # `key_dims` dims (less memory traffic), then re-ranks the shortlist with all C*K magnitudes
    "key_dims": 32,
    "key_project_above": 2000,
    "aggregate": "sequence",
    # Frames of a 1 s clip come from places this close to each other and face within this of each
    # other; frames further apart in time, as much more per second (aggregate.reach_m, gate_deg).
    # How long a clip may be is the engine's (locate.MAX_CLIP_S), not a venue's: the
    # "max_clip_frames" that venues modelled before clips of 5 s still store is not read.
    "clip_radius_m": 1.5,
    "heading_gate_deg": 35.0,
    # logistic(w0 + w . inputs) -> P(within 2 m), inputs named in aggregate.CONFIDENCE_INPUTS;
    # fit by bench/calibrate.py on the tuning families' answers (ring-bare's identical doors with
    # them, seven seeds of it) and, weighing 3 % of them, their clips filmed where the venue was
    # never modelled (all wrong: `--elsewhere-weight`, the least that calls no more of those sure
    # than the model before), its intercept then moved to answer as many of the venue's own sure
    # as the model before (`--cover preset`). The square root of the margin: a near tie between
    # two places is not sure unless both match almost perfectly (docs/benchlog.md, "Ties").
    # Models before it: SUPERSEDED_CONFIDENCE. Both weights positive: fits that gave an input a
    # negative weight, or read the relative margin, answered a clip of one matching frame as sure
    "confidence_features": ["support", "sqrt_margin"],
    "confidence_coef": [-7.67, 9.761, 7.692],
    # Modelling
    "model_fps": 10.0,  # modelling frames sampled at this rate from the video
    # Tracking while walking (tracking.py), read with these defaults by a venue modelled before:
    # a venue frame's verified match counts for the walk graph's nodes within track_radius_m,
    # track_dist_penalty less a metre away; a clip's mean best score near a node, times
    # track_beta, is its log-likelihood, mixed with track_outlier of "this clip says nothing";
    # walking is 0-track_max_mps along the graph (+ track_slack_m); when the phone counts steps,
    # track_step_trust of the weight goes to about track_step_m a step (give or take
    # track_step_sigma_m + 12 %), the rest to anywhere the steps could reach; track_uniform of a
    # uniform belief is mixed in at every update; a move walking backwards from where the clip
    # says the phone faces counts track_backward as much, one whose facing changed by more than
    # track_turn_gate_deg other than the gyroscope says counts less; a lift's or stairs' node
    # passes track_floor_change of its belief to the other floor an update; track_ambiguous:
    # belief >= 3 m from the answer at which it says "not sure".
    "track_radius_m": 1.5,
    "track_dist_penalty": 0.05,
    "track_beta": 25.0,
    # in the second (cautious) belief, a clip whose best node scores below track_beta_ref counts
    # (1 - ref) / (1 - best) as much: 0.85 is the tuning families' median best score; None: off
    "track_beta_ref": 0.85,
    "track_outlier": 0.02,
    "track_max_mps": 1.8,
    "track_slack_m": 1.0,
    "track_step_m": 0.7,
    "track_step_sigma_m": 0.5,
    "track_step_trust": 0.9,
    # a count of no steps is read as no count at all when the clip is best this far (m) from
    # where the last clip was best: the phone counts none while its user moves on; None: off
    # (on the tuning families' walks 1 m was one answer better than 2 m, 4 m worse; 2 m kept:
    # the answer's own "near", and a phone held still is best a node away now and then)
    "track_zero_steps_m": 2.0,
    # a phone held still (its sensors: no step, little turn) whose clip is best where the last was
    # films the same view again: the answer is no surer than that clip alone (tracking.py)
    "track_still_cap": True,
    # and without the sensors (or where they do not say the phone moved), a clip best where the
    # last was and facing as it did there is taken as held still too (tracking.py)
    "track_still_seen": True,
    "track_uniform": 1e-3,
    "track_backward": 0.3,
    "track_turn_gate_deg": 45.0,
    "track_floor_change": 0.05,
    "track_ambiguous": 0.35,
    # a place the venue's own model finds alike to another (its node's frame matches there with
    # score s) keeps at least the other's log-likelihood less track_alike_cost * (1 - s) in the
    # second (cautious) belief, whose confidence caps the answer's (tracking.py); None: off
    "track_alike_cost": 10.0,
    # logistic(w0 + w . inputs) -> P(filtered pose within 2 m), inputs named in
    # aggregate.TRACK_CONFIDENCE_INPUTS; fit by bench/tracking.py on the tuning families' walks
    "track_confidence_features": ["mass", "far", "young"],
    "track_confidence_coef": [-0.436, 5.367, -2.68, 1.883],
    # the answer is not "sure" (confidence held at track_doubt_cap) while the clips' own
    # confidence, averaged over about the last track_recent_s seconds, is below track_recent_min
    # (track_recent_min None: off), or when the clip alone is sure of another place (tracking.py,
    # "The clip's own answer")
    "track_recent_s": 1.0,
    "track_recent_min": 0.5,
    "track_doubt_cap": 0.79,
    # when the clip alone is sure of another place and the belief holds that place at least
    # track_clip_tie times as likely as the answer's, the answer is the clip's place (still not
    # "sure": the two disagreed); None: off (tracking.py, "The clip's own answer"; chosen on the
    # tuning families' walks among 0.25, 0.5 and 0.75)
    "track_clip_tie": 0.5,
    # the clip's own confidence as those two rules read it: the single clip's model they were
    # chosen with, kept apart from confidence_* so that a refit of the single answers' model (it
    # was refit with ring-bare) does not move the rules under them
    "track_clip_confidence_features": ["support", "margin"],
    "track_clip_confidence_coef": [-6.68, 10.731, 10.215],
}

# Confidence models once shipped as the default and refit since: a venue whose settings carry one
# answers with the default's model now (current_confidence). The confidence reads no feature, so
# nothing has to be extracted again; a model set otherwise (an admin's own fit) is kept.
SUPERSEDED_CONFIDENCE: tuple[tuple[tuple[str, ...], tuple[float, ...]], ...] = (
    (("support", "margin"), (-6.68, 10.731, 10.215)),  # before ring-bare
    (("support", "margin"), (-3.45, 5.677, 9.197)),  # before the square root of the margin
)


def setting(conf: Mapping[str, Any], key: str) -> Any:
    """A venue's search or tracking setting: its own, else today's default (a venue modelled
    before the key existed answers with the default, as DEFAULTS' comments say)."""
    return conf.get(key, DEFAULTS[key])


def current_confidence(conf: dict[str, Any]) -> dict[str, Any]:
    """A venue's settings with a superseded default confidence model replaced by today's (the
    venue's own dict is not changed)."""
    names = tuple(conf.get("confidence_features", ("support", "margin")))  # before the key: these
    coef = tuple(float(c) for c in conf.get("confidence_coef", ()))
    for old_names, old_coef in SUPERSEDED_CONFIDENCE:
        if names == old_names and coef == old_coef:
            return {
                **conf,
                "confidence_features": list(DEFAULTS["confidence_features"]),
                "confidence_coef": list(DEFAULTS["confidence_coef"]),
            }
    return conf


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


# The default preset's bands before per-band channels (two bands, every channel in each: 12 curves,
# 768 bytes a frame), and without levelling (it came later): venues modelled then keep them; what
# was measured on them pins them.
TWO_BANDS: dict[str, Any] = {"bands": [[-25.0, 0.0], [0.0, 25.0]], "band_channels": None, "level_iters": None}


def resolve(name: str = "default", overrides: dict[str, Any] | None = None) -> dict[str, Any]:
    if name not in PRESETS:
        raise OmninavError(f"unknown preset {name!r} (known: {', '.join(sorted(PRESETS))})")
    conf = copy.deepcopy(DEFAULTS)
    conf.update(copy.deepcopy(PRESETS[name]))
    conf.update(copy.deepcopy(overrides or {}))
    conf["preset"] = name
    _check_confidence(conf)
    _check_switches(conf)
    _check_soft_clip(conf)
    _check_band_channels(conf)
    _check_level(conf)
    _check_shortlist(conf)
    return conf


SWITCHES = ("shared_candidates", "track_still_cap", "track_still_seen")  # settings that are true or false


def _check_switches(conf: dict[str, Any]) -> None:
    """true or false: a string such as "false" would read as true."""
    for key in SWITCHES:
        v = conf.get(key)
        if not isinstance(v, bool):
            raise OmninavError(f"{key} must be true or false; got {v!r}")


MAX_SHORTLIST = 256  # the second's verification grows with it: 10 frames x 256 rows a clip at most


def _check_shortlist(conf: dict[str, Any]) -> None:
    """A whole number of venue frames, 1-MAX_SHORTLIST (one below `candidates` is `candidates`)."""
    v = conf.get("shortlist")
    if isinstance(v, bool) or not isinstance(v, int) or not 1 <= v <= MAX_SHORTLIST:
        raise OmninavError(f"shortlist must be a whole number of venue frames, 1-{MAX_SHORTLIST}; got {v!r}")


def _check_level(conf: dict[str, Any]) -> None:
    """None (off) or a whole number of passes 0-4: more buys nothing (docs/benchlog.md) and
    costs an unwarp each, on the phone too."""
    n = conf.get("level_iters")
    if n is None:
        return
    if not (isinstance(n, int) and not isinstance(n, bool) and 0 <= n <= 4):
        raise OmninavError(f"level_iters must be a whole number of passes from 0 to 4, or null (off); got {n!r}")


def _check_soft_clip(conf: dict[str, Any]) -> None:
    """None (off) or a finite number of standard deviations > 0: anything else would clip one way
    here and another on the phone, or give the same features two settings ids."""
    sd = conf.get("soft_clip_sd")
    if sd is None:
        return
    ok = isinstance(sd, (int, float)) and not isinstance(sd, bool) and math.isfinite(sd) and sd > 0
    if not ok:
        raise OmninavError(f"soft_clip_sd must be a number of standard deviations > 0, or null (off); got {sd!r}")


def _check_band_channels(conf: dict[str, Any]) -> None:
    """None, or one non-empty list of distinct known channels per band: anything else would make
    curves here that the phone cannot make, or a record whose curves do not say which is which."""
    from .curves import CHANNELS

    per = conf.get("band_channels")
    if per is None:
        return

    def band(c: Any) -> bool:
        names = isinstance(c, (list, tuple)) and all(isinstance(x, str) for x in c)
        return names and len(c) > 0 and len(set(c)) == len(c) and set(c) <= set(CHANNELS)

    ok = isinstance(per, (list, tuple)) and len(per) == len(conf["bands"]) and all(band(c) for c in per)
    if not ok:
        raise OmninavError(
            f"band_channels must be null or one list of distinct channels ({', '.join(CHANNELS)}) per band "
            f"({len(conf['bands'])}); got {per!r}"
        )


def _check_confidence(conf: dict[str, Any]) -> None:
    """A confidence model that could not be evaluated would fail every locate: refuse it here."""
    from .aggregate import CONFIDENCE_INPUTS, TRACK_CONFIDENCE_INPUTS

    _check_model(conf, "confidence", CONFIDENCE_INPUTS, "confidence inputs")
    _check_model(conf, "track_confidence", TRACK_CONFIDENCE_INPUTS, "tracking confidence inputs")
    _check_model(conf, "track_clip_confidence", CONFIDENCE_INPUTS, "confidence inputs (track_clip_confidence)")


def _check_model(conf: dict[str, Any], prefix: str, known: Mapping[str, Any], what: str) -> None:
    """`<prefix>_features` all in `known`, and `<prefix>_coef` an intercept and one weight each."""
    names = conf[f"{prefix}_features"]
    unknown = [n for n in names if n not in known]
    if unknown:
        raise OmninavError(f"unknown {what} {unknown} (known: {', '.join(known)})")
    if len(conf[f"{prefix}_coef"]) != 1 + len(names):
        raise OmninavError(f"{prefix}_coef needs {1 + len(names)} weights (an intercept and one per input)")


# The settings that change what a feature record contains: a record made with other values of
# these cannot be compared with a venue's frames.
FEATURE_KEYS = (
    "pano_width", "oversample", "row_step_deg", "bands", "channels", "gray_world", "n_harmonics", "soft_clip_sd",
    "band_channels", "level_iters",
)  # fmt: skip
# Keys added after venues were modelled without them: they count in the settings id only when set,
# so a record for such a venue keeps the id it had (and a venue's settings need not carry them).
_LATER_KEYS = ("soft_clip_sd", "band_channels", "level_iters")


def feature_keys(conf: dict[str, Any]) -> list[str]:
    """The FEATURE_KEYS a record for a venue with `conf` depends on (a later key only where set), sorted."""
    return sorted(k for k in FEATURE_KEYS if k not in _LATER_KEYS or conf.get(k) is not None)


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
