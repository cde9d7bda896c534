"""Typed venue settings (settings.py): every key owned by a stage, documented, checked once; an
older venue's settings read through numbered migrations; docs/settings.md generated from them."""

from __future__ import annotations

from dataclasses import fields
from pathlib import Path

import pytest

from omninav.errors import Conflict, OmninavError
from omninav.presets import DEFAULTS, PRESETS, feature_keys, resolve, settings_id
from omninav.settings import STAGES, Rule, SearchSettings, TrackingSettings, check, defaults, rules
from omninav.settings_doc import markdown
from omninav.settings_upgrade import SUPERSEDED_CONFIDENCE, VERSION, upgrade

ROOT = Path(__file__).resolve().parents[2]


def test_the_settings_page_is_generated_from_the_fields_and_current() -> None:
    """docs/settings.md is what `python -m omninav.settings_doc` writes today."""
    assert (ROOT / "docs" / "settings.md").read_text() == markdown(PRESETS)


def test_every_key_belongs_to_one_stage_with_its_meaning_and_a_default_it_accepts() -> None:
    owners: dict[str, type] = {}
    for cls, _ in STAGES:
        for f in fields(cls):
            assert f.name not in owners, f"{f.name} in two stages"
            owners[f.name] = cls
            rule = f.metadata["rule"]
            assert isinstance(rule, Rule) and len(rule.doc) > 10
            assert rule.accepts(DEFAULTS[f.name]), f.name
    assert set(owners) == set(DEFAULTS) == set(defaults())
    for name in PRESETS:
        check(resolve(name))


@pytest.mark.parametrize("key", sorted(DEFAULTS))
def test_a_value_of_the_wrong_kind_is_refused_naming_its_key(key: str) -> None:
    rule, _ = rules()[key]
    bad = "1" if rule.kind != "choice" else "nearest"
    with pytest.raises(OmninavError, match=key):
        resolve("default", {key: bad})
    if rule.kind in ("int", "number") and rule.hi is not None:
        with pytest.raises(OmninavError, match=key):
            resolve("default", {key: rule.hi + 1})


def test_an_unknown_key_is_refused_not_ignored() -> None:
    """A typo would otherwise do nothing, silently."""
    with pytest.raises(OmninavError, match="shortlst"):
        resolve("default", {"shortlst": 16})


def _venue_of_the_first_release() -> dict:
    """settings.json as the first releases wrote it: no version, no keys added since, a clip
    length of its own, the doubt cap under its old name, the confidence model of then."""
    six = resolve("six")
    later = ("soft_clip_sd", "band_channels", "level_iters", "shared_candidates", "shortlist", "key_dims")
    old = {k: v for k, v in six.items() if k not in later and k != "version" and not k.startswith("track_")}
    old.pop("confidence_features")
    old["confidence_coef"] = [-6.68, 10.731, 10.215]
    old["max_clip_frames"] = 30
    old["track_recent_cap"] = 0.7
    return old


def test_a_venue_of_an_earlier_release_is_read_through_the_migrations() -> None:
    old = _venue_of_the_first_release()
    new = upgrade(old)
    assert new["version"] == VERSION and "version" not in old  # the stored dict untouched
    assert settings_id(new) == settings_id(old)  # its records still match its frames
    assert new["soft_clip_sd"] is None and new["band_channels"] is None and new["level_iters"] is None
    assert new["key_dims"] == 0  # it searched with whole keys and still does
    assert new["shortlist"] == DEFAULTS["shortlist"] and new["shared_candidates"] is True
    assert new["track_doubt_cap"] == 0.7 and "track_recent_cap" not in new and "max_clip_frames" not in new
    assert new["confidence_coef"] == DEFAULTS["confidence_coef"]  # the superseded default model refreshed
    assert upgrade(new) == new  # once is enough


def test_each_migration_starts_from_the_version_it_is_stored_with() -> None:
    """A venue stored at version 1 skips migration 1: its model of named inputs stays its own;
    one of version 0 without the inputs named reads the ones it was fit on."""
    today = resolve("default")
    own = {**today, "version": 1, "confidence_features": ["support", "margin"], "confidence_coef": [-6.0, 9.0, 9.0]}
    assert upgrade(own)["confidence_coef"] == [-6.0, 9.0, 9.0]
    unnamed = {k: v for k, v in today.items() if k not in ("version", "confidence_features")}
    assert upgrade({**unnamed, "confidence_coef": [-6.0, 9.0, 9.0]})["confidence_features"] == ["support", "margin"]
    first = upgrade({**unnamed, "confidence_coef": [-5.0, 6.0, 20.0, 2.0]})  # the first release's own shape
    assert first["confidence_features"] == ["support", "margin", "agree"]


def test_a_superseded_default_model_is_refreshed_whatever_the_version() -> None:
    """A refit adds the model it replaces to SUPERSEDED_CONFIDENCE: venues modelled with it, of
    today's version too, answer with the new one (the first release's included)."""
    today = resolve("default")
    for names, coef in SUPERSEDED_CONFIDENCE:
        for version in (0, VERSION):
            stored = {**today, "version": version, "confidence_features": list(names), "confidence_coef": list(coef)}
            assert upgrade(stored)["confidence_coef"] == DEFAULTS["confidence_coef"]
    first = {k: v for k, v in today.items() if k not in ("version", "confidence_features")}
    assert (
        upgrade({**first, "confidence_coef": [-6.0, 6.0, 25.0, 2.0]})["confidence_coef"] == DEFAULTS["confidence_coef"]
    )


@pytest.mark.parametrize("version", [VERSION + 1, -1, "3", True])
def test_settings_of_a_later_release_or_no_version_number_are_refused(version: object) -> None:
    with pytest.raises(OmninavError, match="version"):
        upgrade({**resolve("default"), "version": version})


def test_a_venue_of_a_later_release_is_a_conflict_that_says_what_to_do() -> None:
    """A server rolled back after modelling: the venue's answer is a 409 naming the way out."""
    with pytest.raises(Conflict, match="later release.*model the venue anew"):
        upgrade({**resolve("default"), "version": VERSION + 1})


def test_the_search_parameters_are_read_once_and_project_keys_only_on_large_venues() -> None:
    s = SearchSettings.of(resolve("default"))
    assert (s.candidates, s.shortlist, s.shared_candidates) == (16, 32, True)
    assert s.key_dims_for(2000) == 0 and s.key_dims_for(2001) == 32
    assert SearchSettings.of(resolve("paper")).shared_candidates is False
    with pytest.raises(OmninavError, match="shortlist"):
        SearchSettings.of({"shortlist": 0})


def test_the_tracking_settings_fill_what_a_venue_lacks_with_todays_defaults() -> None:
    t = TrackingSettings.of({"track_beta": 30.0})
    assert t.track_beta == 30.0 and t.track_outlier == DEFAULTS["track_outlier"]
    with pytest.raises(OmninavError, match="track_beta_ref"):
        TrackingSettings.of({"track_beta_ref": 1.0})


@pytest.mark.parametrize("bad", [0, 0.0, -1.0, False, True, "1.25", float("nan"), float("inf")])
def test_soft_clip_settings_are_refused_unless_a_positive_number_or_null(bad):
    with pytest.raises(OmninavError, match="soft_clip_sd"):
        resolve("default", {"soft_clip_sd": bad})
    assert resolve("default", {"soft_clip_sd": None})["soft_clip_sd"] is None
    assert resolve("default", {"soft_clip_sd": 2})["soft_clip_sd"] == 2


@pytest.mark.parametrize("bad", [None, 0, 1, "false", "true"])
def test_shared_candidates_is_true_or_false_and_not_a_feature_setting(bad):
    with pytest.raises(OmninavError, match="shared_candidates"):
        resolve("default", {"shared_candidates": bad})
    on, off = resolve("default"), resolve("default", {"shared_candidates": False})
    assert on["shared_candidates"] is True and resolve("paper")["shared_candidates"] is False
    # how a clip is searched is the server's: the phone's features, and their settings id, are the same
    assert settings_id(on) == settings_id(off) and "shared_candidates" not in feature_keys(on)


@pytest.mark.parametrize("bad", [None, 0, 257, 32.0, "32", True])
def test_the_shortlist_is_a_whole_number_of_frames_and_not_a_feature_setting(bad):
    with pytest.raises(OmninavError, match="shortlist"):
        resolve("default", {"shortlist": bad})
    wide, narrow = resolve("default"), resolve("default", {"shortlist": 16})
    assert wide["shortlist"] == 32 and narrow["shortlist"] == 16
    assert settings_id(wide) == settings_id(narrow) and "shortlist" not in feature_keys(wide)


@pytest.mark.parametrize("key", ["track_still_cap", "track_still_seen"])
@pytest.mark.parametrize("bad", [None, 0, 1, "false"])
def test_the_held_still_rules_are_true_or_false_and_not_feature_settings(key, bad):
    with pytest.raises(OmninavError, match=key):
        resolve("default", {key: bad})
    on, off = resolve("default"), resolve("default", {key: False})
    assert on[key] is True and settings_id(on) == settings_id(off)


@pytest.mark.parametrize(
    "bad",
    [
        [["I"]],
        [["I"], []],
        [["I"], ["I", "I"]],
        [["I"], ["X"]],
        "I",
        [["I"], "dI"],
        [["I"], ["dI"], ["O1"]],
        [[["I"]], ["dI"]],
    ],
)
def test_band_channels_are_refused_unless_one_list_of_known_distinct_channels_per_band(bad):
    with pytest.raises(OmninavError, match="band_channels"):
        resolve("six", {"bands": [[-20.0, 0.0], [0.0, 20.0]], "band_channels": bad})
