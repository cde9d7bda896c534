"""A venue's settings as an earlier release stored them, read as today's: numbered migrations.

`settings.json` carries a `version` (none: 0, every venue modelled before it). `upgrade` applies
each migration after the stored version, in order, then the rules of every read (a superseded
default confidence model read as today's: `current_confidence`), then checks the result
(settings.check); the stored file is never rewritten, so a venue modelled today and one modelled a
year ago read the same way. A change to the settings' meaning adds a migration and raises
VERSION; a refit of the default confidence model adds the model it replaces to
SUPERSEDED_CONFIDENCE, which reaches venues of every version.
"""

from __future__ import annotations

import copy
from collections.abc import Callable, Mapping
from dataclasses import fields
from typing import Any

from .errors import Conflict, OmninavError
from .settings import (
    DEFAULTS,
    AggregationSettings,
    ModellingSettings,
    SearchSettings,
    TrackingSettings,
    VerifySettings,
    check,
)

VERSION = 4  # the settings' format today


# Confidence models once shipped as the default and refit since: a venue whose settings carry one
# answers with today's, whatever its version (`current_confidence`, on every read: a refit adds
# the model it replaces here, and every venue modelled with that one follows). The confidence reads
# no feature, so nothing has to be extracted again; a model set otherwise (an own fit) is kept.
SUPERSEDED_CONFIDENCE: tuple[tuple[tuple[str, ...], tuple[float, ...]], ...] = (
    (("support", "margin", "agree"), (-6.0, 6.0, 25.0, 2.0)),  # the first release's
    (("support", "margin"), (-6.68, 10.731, 10.215)),  # before ring-bare
    (("support", "margin"), (-3.45, 5.677, 9.197)),  # before the square root of the margin
)
# Feature keys added after venues were modelled without them: such a venue's features were made
# with the key off, and its records keep the settings id they had (presets.settings_id counts a
# key only when it is set).
LATER_FEATURE_KEYS = ("soft_clip_sd", "band_channels", "level_iters")
# Keys a venue stored that nothing reads any more: a clip's length is the engine's
# (locate.MAX_CLIP_S) since clips of 5 s.
RETIRED_KEYS = ("max_clip_frames",)
RENAMED_KEYS = {"track_recent_cap": "track_doubt_cap"}  # old name: new name


def _to_1_confidence(conf: dict[str, Any]) -> dict[str, Any]:
    """1: a confidence model without `confidence_features` reads the inputs it was fit on:
    (support, margin), or with a fourth weight (the first release's) (support, margin, agree)."""
    if "confidence_coef" in conf and "confidence_features" not in conf:
        first = len(conf["confidence_coef"]) == 4
        conf["confidence_features"] = ["support", "margin", "agree"] if first else ["support", "margin"]
    return conf


def current_confidence(conf: dict[str, Any]) -> dict[str, Any]:
    """On every read, after the migrations: a superseded default confidence model is read as
    today's (SUPERSEDED_CONFIDENCE)."""
    names = tuple(conf.get("confidence_features", ()))
    coef = tuple(float(c) for c in conf.get("confidence_coef", ()))
    if (names, coef) in SUPERSEDED_CONFIDENCE:
        conf["confidence_features"] = list(DEFAULTS["confidence_features"])
        conf["confidence_coef"] = list(DEFAULTS["confidence_coef"])
    return conf


def _to_2_later_features(conf: dict[str, Any]) -> dict[str, Any]:
    """2: feature keys added later are null (off) where the venue's features were made without
    them; keys nothing reads are dropped, renamed keys take their new names."""
    for k in LATER_FEATURE_KEYS:
        conf.setdefault(k, None)
    for k in RETIRED_KEYS:
        conf.pop(k, None)
    for old, new in RENAMED_KEYS.items():
        if old in conf:
            conf.setdefault(new, conf.pop(old))
    return conf


def _to_3_search_and_tracking(conf: dict[str, Any]) -> dict[str, Any]:
    """3: search, aggregation and tracking keys a venue modelled before them lacks take today's
    defaults (they change no feature: the venue answers as a new one searches and tracks), but
    for `key_dims`, 0: a venue without it searched with whole keys, and still does."""
    conf.setdefault("key_dims", 0)
    for cls in (SearchSettings, AggregationSettings, ModellingSettings, TrackingSettings):
        for f in fields(cls):
            conf.setdefault(f.name, copy.deepcopy(DEFAULTS[f.name]))
    return conf


def _to_4_verify(conf: dict[str, Any]) -> dict[str, Any]:
    """4: a venue modelled before local features has none stored (`local_features` null) and
    today's margin."""
    for f in fields(VerifySettings):
        conf.setdefault(f.name, copy.deepcopy(DEFAULTS[f.name]))
    return conf


MIGRATIONS: tuple[Callable[[dict[str, Any]], dict[str, Any]], ...] = (
    _to_1_confidence,
    _to_2_later_features,
    _to_3_search_and_tracking,
    _to_4_verify,
)
assert len(MIGRATIONS) == VERSION


def upgrade(stored: Mapping[str, Any]) -> dict[str, Any]:
    """A generation's stored settings -> today's format (VERSION), checked: each migration after
    the stored `version` (none: 0), in order, then `current_confidence`. The stored file is not
    changed."""
    conf = copy.deepcopy(dict(stored))
    v = conf.get("version", 0)
    if not isinstance(v, int) or isinstance(v, bool) or v < 0:
        raise OmninavError(f"settings version {v!r}: not a version (this release reads 0-{VERSION})")
    if v > VERSION:  # modelled by a later release, then read by this one (a server rolled back)
        raise Conflict(
            f"the venue's settings are of version {v}, from a later release of omninav; this release "
            f"reads versions 0-{VERSION}: run the later release, or model the venue anew with this one"
        )
    for step in MIGRATIONS[v:]:
        conf = step(conf)
    conf = current_confidence(conf)
    conf["version"] = VERSION
    check(conf)
    return conf
