"""The confidence model: what it reads, and that a venue keeps the model it was modelled with."""

import numpy as np
import pytest

from omninav.aggregate import CONFIDENCE_INPUTS, Estimate, confidence, confidence_inputs
from omninav.presets import resolve


def _est(support: float, rival: float, agree: float = 1.0) -> Estimate:
    return Estimate(0.0, 0.0, 0.0, 0, support, rival, agree)


def test_a_venue_modelled_before_the_features_were_named_keeps_its_model() -> None:
    """settings.json of an older venue has confidence_coef for (support, margin) and no
    confidence_features: it answers as it did."""
    old = {"confidence_coef": [-6.68, 10.731, 10.215]}
    e = _est(0.7, 0.5)
    z = -6.68 + 10.731 * 0.7 + 10.215 * (0.7 - 0.5)
    assert confidence(e, old) == pytest.approx(1 / (1 + np.exp(-z)))


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
