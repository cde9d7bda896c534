"""The confidence model: what it reads, and that a venue keeps the model it was modelled with."""

import numpy as np
import pytest

from omninav.aggregate import CONFIDENCE_INPUTS, Estimate, confidence, confidence_inputs
from omninav.presets import resolve
from omninav.settings_upgrade import upgrade


def _est(support: float, rival: float, agree: float = 1.0) -> Estimate:
    return Estimate(0.0, 0.0, 0.0, 0, support, rival, agree)


def test_a_venue_modelled_before_the_features_were_named_reads_its_model() -> None:
    """settings.json of an older venue has confidence_coef for (support, margin) and no
    confidence_features: the model reads those two inputs."""
    old = {"confidence_coef": [-6.68, 10.731, 10.215]}
    e = _est(0.7, 0.5)
    z = -6.68 + 10.731 * 0.7 + 10.215 * (0.7 - 0.5)
    assert confidence(e, old) == pytest.approx(1 / (1 + np.exp(-z)))


def test_a_superseded_default_model_is_refreshed_and_any_other_kept() -> None:
    """A venue modelled when the default model was the one refit since answers with today's (the
    confidence reads no feature: nothing to extract again); an admin's own model stays. Read as
    the store reads a generation's settings.json (settings_upgrade.upgrade, migration 1)."""
    today = resolve("default")
    base = {k: v for k, v in today.items() if not k.startswith("confidence_") and k != "version"}
    for old in (
        {"confidence_coef": [-6.68, 10.731, 10.215]},  # before confidence_features was a key
        {"confidence_features": ["support", "margin"], "confidence_coef": [-6.68, 10.731, 10.215]},
        {"confidence_features": ["support", "margin"], "confidence_coef": [-3.45, 5.677, 9.197]},
    ):
        stored = {**base, **old}
        coef = list(old["confidence_coef"])
        new = upgrade(stored)
        assert new["confidence_coef"] == today["confidence_coef"] != old["confidence_coef"]
        assert new["confidence_features"] == today["confidence_features"] and new["bands"] == base["bands"]
        assert stored["confidence_coef"] == coef  # the venue's own dict untouched
    own = {**base, "confidence_features": ["support", "margin"], "confidence_coef": [-6.0, 10.0, 10.0]}
    assert upgrade(own)["confidence_coef"] == [-6.0, 10.0, 10.0]
    # the old default's weights on other inputs: an own model
    other = {**base, "confidence_features": ["support", "agree"], "confidence_coef": [-3.45, 5.677, 9.197]}
    assert upgrade(other)["confidence_coef"] == [-3.45, 5.677, 9.197]
    # an own model from before the key was named reads the inputs it was fit on
    unnamed = upgrade({**base, "confidence_coef": [-6.0, 10.0, 10.0]})
    assert unnamed["confidence_features"] == ["support", "margin"]
    assert upgrade(today) == today


def test_the_default_model_grows_with_every_input_and_a_clip_of_one_matching_frame_is_not_sure() -> None:
    """Weights of one sign: more support, a wider margin or more frames agreeing never lowers the
    confidence. A refit that gave the agreement a negative weight (and read the relative margin)
    answered a clip whose one frame in ten matched, the rest blank or noise, as sure (0.89)."""
    conf = resolve("default")
    grid = np.linspace(0.0, 1.0, 11)
    for s in grid:
        for r in grid[grid <= s]:
            c = [confidence(_est(s, r, a), conf) for a in grid]
            assert c == sorted(c)
        c = [confidence(_est(s, r), conf) for r in grid[grid <= s][::-1]]  # the rival falling: margin up
        assert c == sorted(c)
    c = [confidence(_est(s, 0.0), conf) for s in grid]
    assert c == sorted(c)
    assert confidence(_est(0.095, 0.03, 0.1), conf) < 0.5  # one frame of ten at 0.95, no rival to speak of


def test_a_tie_between_two_places_is_not_sure_unless_both_match_almost_perfectly() -> None:
    """Two places >= ALT_M apart that explain a clip equally well are a coin toss: the model before
    the square root of the margin said 0.80-0.86 to such ties at support 0.85-0.93, and on the
    held-out corridor of identical doors one in six of them was the wrong door. Now a tie is not
    sure up to a support of 0.92 (a margin of 0.001, up to 0.9); above, both places match the clip
    almost perfectly (the model is also fit on clips filmed elsewhere, which match moderately,
    and so weighs the support more). A clear margin still is sure."""
    conf = resolve("default")
    old = {"confidence_features": ["support", "margin"], "confidence_coef": [-3.45, 5.677, 9.197]}
    for s in (0.6, 0.8, 0.86, 0.9, 0.92):
        assert confidence(_est(s, s), conf) < 0.8
    for s in (0.6, 0.8, 0.86, 0.9):
        assert confidence(_est(s, s - 0.001), conf) < 0.8
    for s in (0.86, 0.9, 0.92):
        assert confidence(_est(s, s), old) >= 0.8  # what a venue modelled before said (refreshed since)
    assert confidence(_est(0.9, 0.8), conf) >= 0.95
    assert confidence(_est(0.7, 0.5), conf) >= 0.9  # a clear margin at moderate support


def test_the_refit_keeps_the_share_it_is_told_and_never_fits_a_held_out_family(monkeypatch: pytest.MonkeyPatch) -> None:
    """bench/calibrate.py: --cover moves the intercept to the share of answers called sure (the
    preset's boldness), and --extra takes more seeds of tuning families only."""
    from bench.scoring import cover
    from bench.venues import extra_seeds

    rng = np.random.default_rng(0)
    x = np.c_[np.ones(500), rng.uniform(0, 1, 500), rng.uniform(0, 0.3, 500)]
    for share in (0.5, 0.85, 0.95):
        w = cover(x, np.array([0.0, 7.0, 9.0]), share)
        assert np.mean(1 / (1 + np.exp(-(x @ w))) >= 0.8) == pytest.approx(share, abs=0.005)
        assert list(w[1:]) == [7.0, 9.0]  # only the intercept moves
    assert extra_seeds(["ring-bare:3,4"], [0, 1, 2]) == [("ring-bare", 3), ("ring-bare", 4)]
    for bad in ("long-bare:5", "ring-bare:2", "ring-bare", "nope:3", "ring-bare:x"):
        with pytest.raises(SystemExit):
            extra_seeds([bad], [0, 1, 2])


def test_inputs_of_the_square_root_of_the_margin() -> None:
    assert confidence_inputs(_est(0.9, 0.81), ["sqrt_margin"]) == pytest.approx([0.3])
    assert confidence_inputs(_est(0.5, 0.7), ["sqrt_margin"]) == [0.0]  # the median's rival may beat it


def test_an_evaluation_row_scores_as_its_estimate() -> None:
    conf = resolve("default")
    e = _est(0.8, 0.3, 0.9)
    row = {"support": 0.8, "rival": 0.3, "agree": 0.9, "err_m": 0.1}
    assert confidence(row, conf) == confidence(e, conf)
    assert set(conf["confidence_features"]) <= set(CONFIDENCE_INPUTS)
    assert len(conf["confidence_coef"]) == 1 + len(conf["confidence_features"])


def test_inputs() -> None:
    e = _est(0.8, 0.6, 0.7)
    assert confidence_inputs(e, ["support", "margin", "rel_margin", "agree"]) == pytest.approx([0.8, 0.2, 0.25, 0.7])
    assert confidence_inputs(_est(0.0, 0.0), ["rel_margin"]) == [0.0]  # no support: no division by zero


def test_confidence_grows_with_the_margin_over_the_rival() -> None:
    conf = resolve("default")
    c = [confidence(_est(0.9, r), conf) for r in (0.9, 0.8, 0.6, 0.3)]
    assert c == sorted(c)
    assert c[-1] >= 0.95  # a clear answer is trusted


def test_a_confidence_model_that_cannot_be_evaluated_is_refused_up_front() -> None:
    from omninav.errors import OmninavError

    with pytest.raises(OmninavError, match="unknown confidence inputs"):
        resolve("default", {"confidence_features": ["support", "luck"], "confidence_coef": [0, 1, 1]})
    with pytest.raises(OmninavError, match=f"needs {1 + len(resolve()['confidence_features'])} weights"):
        resolve("default", {"confidence_coef": [0, 1]})
