"""A venue's settings, typed: one frozen dataclass per stage that reads them, validated once.

Every venue stores the settings it was modelled with (`settings.json` of each generation) and
answers with them, so a later release may change a preset without breaking venues modelled
today. The settings are a flat JSON object; here each key is a field of the stage that owns it:

- `FeatureSettings`: what a frame's record contains (unwarp, level, curves, spectrum); a record
  made with other values cannot be compared with the venue's frames (`presets.settings_id`);
- `SearchSettings`: how the index searches (index.py), built once per Locator and passed to the
  index, as faiss passes its search parameters;
- `AggregationSettings`: how a clip's matches become an answer and its confidence (aggregate.py);
- `ModellingSettings`: how a walk video is sampled (model_venue.py);
- `TrackingSettings`: the tracking filter (tracking.py).

Each field's metadata says its meaning, unit and range; `check` validates a whole settings dict
against them (and what relates fields: one channel list per band, a weight per confidence input)
and refuses unknown keys, with a message that names the key. settings_upgrade.py brings the
settings of a venue modelled by an earlier release to today's format by numbered migrations,
once, where `settings.json` is read (store.py). docs/settings.md is generated from the fields
(settings_doc.py; tests/engine/test_settings.py keeps it current).

Notes
-----
The dataclasses are the schema, not the carrier: the rest of the engine passes the flat dict
(what `presets.resolve` returns and `settings.json` holds), because the feature record's id is a
CRC of its canonical JSON and the phone reads the same keys.
"""

from __future__ import annotations

import copy
import math
from collections.abc import Callable, Mapping
from dataclasses import MISSING, dataclass, field, fields
from typing import Any, TypeVar, cast

from .errors import OmninavError


@dataclass(frozen=True)
class Rule:
    """What a field accepts: `kind` (bool, int, number, choice, list), its bounds (`lo`, `hi`,
    open or closed), whether null means "off", the choices; `unit` and `doc` for docs/settings.md."""

    kind: str
    doc: str
    unit: str = ""
    lo: float | None = None
    hi: float | None = None
    lo_open: bool = False
    hi_open: bool = False
    optional: bool = False  # null is accepted (the feature is off)
    choices: tuple[str, ...] = ()
    item: Callable[[Any], bool] | None = None  # a list's test of its items
    item_doc: str = ""  # ... said in words

    def range_text(self) -> str:
        """The accepted values in words, for messages and docs/settings.md."""
        if self.kind == "bool":
            text = "true or false"
        elif self.kind == "choice":
            text = " or ".join(f'"{c}"' for c in self.choices)
        elif self.kind == "list":
            text = f"a list of {self.item_doc}" if self.item_doc else "a list"
        else:
            what = "a whole number" if self.kind == "int" else "a number"
            lo = "" if self.lo is None else f"{'>' if self.lo_open else '>='} {_num(self.lo)}"
            hi = "" if self.hi is None else f"{'<' if self.hi_open else '<='} {_num(self.hi)}"
            text = f"{what} {lo}{', ' if lo and hi else ''}{hi}".strip()
        return text + (", or null (off)" if self.optional else "")

    def accepts(self, v: Any) -> bool:
        if v is None:
            return self.optional
        if self.kind == "bool":
            return isinstance(v, bool)
        if self.kind == "choice":
            return v in self.choices
        if self.kind == "list":
            return isinstance(v, (list, tuple)) and (self.item is None or all(self.item(x) for x in v))
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
            return False
        if self.kind == "int" and not isinstance(v, int):
            return False
        if self.lo is not None and (v <= self.lo if self.lo_open else v < self.lo):
            return False
        return not (self.hi is not None and (v >= self.hi if self.hi_open else v > self.hi))


def _num(v: float) -> str:
    return str(int(v)) if float(v).is_integer() else str(v)


def _is_number(x: Any) -> bool:
    return isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x)


def _is_band(x: Any) -> bool:
    return isinstance(x, (list, tuple)) and len(x) == 2 and all(_is_number(v) for v in x) and x[0] < x[1]


def _is_name(x: Any) -> bool:
    return isinstance(x, str) and len(x) > 0


def _is_names(x: Any) -> bool:
    return isinstance(x, (list, tuple)) and all(_is_name(v) for v in x)


def _field(default: Any, rule: Rule) -> Any:
    """A dataclass field: its default (lists copied per instance) and its Rule."""
    if isinstance(default, list):
        return field(default_factory=lambda: copy.deepcopy(default), metadata={"rule": rule})
    return field(default=default, metadata={"rule": rule})


def _b(doc: str) -> Rule:
    return Rule("bool", doc)


@dataclass(frozen=True)
class FeatureSettings:
    """What a frame's feature record contains: the phone and the server must agree on every one
    (unwarp.py, level.py, curves.py, spectrum.py; the record carries their CRC)."""

    pano_width: int = _field(
        360, Rule("int", "Panorama columns, one per degree of azimuth: the curves' length.", "columns", lo=8, hi=4096)
    )
    oversample: int = _field(
        4,
        Rule(
            "int",
            ("The unwarp samples this many times the columns, then averages: anti-aliasing at the donut's rim."),
            "x",
            lo=1,
            hi=16,
        ),
    )
    row_step_deg: float = _field(
        1.0, Rule("number", "Elevation between the panorama's rows.", "degrees", lo=0, hi=10, lo_open=True)
    )
    bands: list[list[float]] = _field(
        [[-20.0, 20.0]],
        Rule(
            "list",
            ("Elevation bands over which each channel is summed column-wise (the paper's Eq. 3), 0 at the horizon."),
            "degrees",
            item=_is_band,
            item_doc="[low, high] pairs, low < high",
        ),
    )
    channels: list[str] = _field(
        ["H", "S", "I", "dH", "dS", "dI"],
        Rule(
            "list",
            (
                "Channels of every band (with `band_channels`, their union). H, S, I and their "
                "horizontal gradients are the paper's; O1, O2 are opponent colours (R-G, R+G-2B),"
                " stable where hue is not."
            ),
            item=_is_name,
            item_doc="channel names",
        ),
    )
    gray_world: bool = _field(
        False,
        _b("Divide each colour channel by its frame's mean first: removes a colour cast and the camera's gain."),
    )
    soft_clip_sd: float | None = _field(
        None,
        Rule(
            "number",
            (
                "After normalising, each curve becomes sd * tanh(curve / sd): a sunlit window or "
                "one strong edge weighs less."
            ),
            "standard deviations",
            lo=0,
            lo_open=True,
            optional=True,
        ),
    )
    band_channels: list[list[str]] | None = _field(
        None,
        Rule(
            "list",
            "Each band's own channels, one list per band (null: every band has `channels`).",
            item=_is_names,
            item_doc="channel lists, one per band",
            optional=True,
        ),
    )
    level_iters: int | None = _field(
        None,
        Rule(
            "int",
            (
                "Passes of the tilt estimate from the frame's own upright edges, each frame "
                "unwarped through it (level.py; null or 0: as the lens sees it)."
            ),
            "passes",
            lo=0,
            hi=4,
            optional=True,
        ),
    )
    n_harmonics: int = _field(
        32,
        Rule(
            "int",
            "Leading FFT harmonics kept of each curve (1..K; the DC term carries no shape).",
            "harmonics",
            lo=1,
            hi=256,
        ),
    )


MAX_SHORTLIST = 256  # the second's verification grows with it: 10 frames x 256 rows a clip at most


@dataclass(frozen=True)
class SearchSettings:
    """How a clip is searched in the venue's index (index.py): a search setting may change for a
    venue without modelling it again; a venue modelled before one existed reads its default."""

    candidates: int = _field(
        16,
        Rule(
            "int",
            ("Venue frames kept per query frame by the magnitude stage, then verified by phase correlation."),
            "frames",
            lo=1,
            hi=256,
        ),
    )
    shared_candidates: bool = _field(
        True,
        _b(
            "Each frame of a clip's second is verified against every candidate any frame of "
            "that second kept, and keeps its `candidates` best (index.py, shared candidates)."
        ),
    )
    shortlist: int = _field(
        32,
        Rule(
            "int",
            (
                "With shared candidates, stage 1 shortlists this many a frame; each frame keeps "
                "its `candidates` best of the second's shortlists."
            ),
            "frames",
            lo=1,
            hi=MAX_SHORTLIST,
        ),
    )
    key_dims: int = _field(
        32,
        Rule(
            "int",
            (
                "Above `key_project_above` frames, stage 1 first shortlists with keys projected "
                "to this many dimensions, then re-ranks with all magnitudes."
            ),
            "dimensions",
            lo=0,
            hi=4096,
        ),
    )
    key_project_above: int = _field(
        2000, Rule("int", "Venue size above which the projected keys are used.", "frames", lo=0)
    )

    @staticmethod
    def of(conf: Mapping[str, Any]) -> SearchSettings:
        """A venue's search settings (its own, else the defaults), checked."""
        return _of(SearchSettings, conf)

    def key_dims_for(self, n_frames: int) -> int:
        """Projected stage-1 keys pay off only on large venues: 0 (none) below key_project_above."""
        return int(self.key_dims) if n_frames > self.key_project_above else 0


@dataclass(frozen=True)
class AggregationSettings:
    """How a clip's verified matches become one answer and its confidence (aggregate.py)."""

    aggregate: str = _field(
        "sequence",
        Rule(
            "choice",
            (
                "How a clip's frames are combined: `sequence` (frames must agree in place, time "
                "and facing) or `median` (the paper's, of each frame's best)."
            ),
            choices=("sequence", "median"),
        ),
    )
    clip_radius_m: float = _field(
        1.5,
        Rule(
            "number",
            (
                "Frames of a 1 s clip come from places this close to each other; further apart in"
                " time, as much more a second (aggregate.reach_m)."
            ),
            "metres",
            lo=0,
            lo_open=True,
        ),
    )
    heading_gate_deg: float = _field(
        35.0,
        Rule(
            "number",
            "... and face within this of each other (aggregate.gate_deg).",
            "degrees",
            lo=0,
            hi=180,
            lo_open=True,
        ),
    )
    confidence_features: list[str] = _field(
        ["support", "sqrt_margin"],
        Rule(
            "list",
            (
                "Inputs of the clip's confidence model, P(within 2 m) = logistic(w0 + w . "
                "inputs), named in aggregate.CONFIDENCE_INPUTS; fit by bench/calibrate.py on the "
                "tuning families."
            ),
            item=_is_name,
            item_doc="input names",
        ),
    )
    confidence_coef: list[float] = _field(
        [-7.67, 9.761, 7.692],
        Rule("list", "The model's intercept, then one weight per input.", item=_is_number, item_doc="numbers"),
    )


@dataclass(frozen=True)
class ModellingSettings:
    """How a walk video becomes a venue's frames (model_venue.py)."""

    model_fps: float = _field(
        10.0,
        Rule(
            "number",
            "Modelling frames sampled from each walk video at this rate.",
            "frames a second",
            lo=0,
            hi=120,
            lo_open=True,
        ),
    )


@dataclass(frozen=True)
class VerifySettings:
    """Local features that verify a clip's candidate places (verify.py): stored when the venue is
    modelled, read when a clip is located from its frames."""

    local_features: int | None = _field(
        None,
        Rule(
            "int",
            (
                "ORB keypoints kept of each panorama, stored for a modelled frame every half metre "
                "and found in a clip's last frame; null: no local features (fixed when modelled)."
            ),
            "keypoints",
            lo=100,
            hi=5000,
            optional=True,
        ),
    )
    local_margin: float = _field(
        2.0,
        Rule(
            "number",
            "The answer moves to another candidate place only with this many times the inliers of its own.",
            "x",
            lo=1,
        ),
    )


@dataclass(frozen=True)
class TrackingSettings:
    """The tracking filter (tracking.py, docs/tracking.md): a venue modelled before a key existed
    reads its default."""

    track_radius_m: float = _field(
        1.5,
        Rule(
            "number",
            "A venue frame's verified match counts for the walk graph's nodes within this.",
            "metres",
            lo=0,
            lo_open=True,
        ),
    )
    track_dist_penalty: float = _field(
        0.05, Rule("number", "... less this much for a node a metre away.", "score a metre", lo=0)
    )
    track_beta: float = _field(
        25.0,
        Rule(
            "number",
            "A clip's mean best score near a node times this is its log-likelihood.",
            "1 / score",
            lo=0,
            lo_open=True,
        ),
    )
    track_beta_ref: float | None = _field(
        0.85,
        Rule(
            "number",
            (
                "In the second, cautious belief, a clip whose best node scores below this counts "
                "(1 - ref) / (1 - best) as much (0.85: the tuning families' median best score)."
            ),
            "score",
            lo=0,
            hi=1,
            hi_open=True,
            optional=True,
        ),
    )
    track_outlier: float = _field(
        0.02,
        Rule(
            "number",
            (
                'Share of "this clip says nothing" mixed into every clip\'s likelihood: one clip'
                " moves the odds by at most 1 / this."
            ),
            "share",
            lo=0,
            hi=1,
            lo_open=True,
        ),
    )
    track_max_mps: float = _field(
        1.8,
        Rule(
            "number",
            "Walking speed along the graph reachable at full probability.",
            "metres a second",
            lo=0,
            lo_open=True,
        ),
    )
    track_slack_m: float = _field(1.0, Rule("number", "... plus this distance.", "metres", lo=0))
    track_step_m: float = _field(
        0.7, Rule("number", "The length of a step the phone counts.", "metres", lo=0, lo_open=True)
    )
    track_step_sigma_m: float = _field(
        0.5, Rule("number", "... give or take this (+ 12 %).", "metres", lo=0, lo_open=True)
    )
    track_step_trust: float = _field(
        0.9,
        Rule(
            "number",
            ("Share of the move's weight given to the distance the steps say; the rest to anywhere within reach."),
            "share",
            lo=0,
            hi=1,
            hi_open=True,
        ),
    )
    track_zero_steps_m: float | None = _field(
        2.0,
        Rule(
            "number",
            (
                "A count of no steps is read as no count at all when the clip is best this far "
                "from where the last clip was best (the phone counts none while its user moves "
                "on)."
            ),
            "metres",
            lo=0,
            lo_open=True,
            optional=True,
        ),
    )
    track_still_cap: bool = _field(
        True,
        _b(
            "A phone held still (no step, little turn) whose clip is best where the last was:"
            " the answer is no surer than that clip alone."
        ),
    )
    track_still_seen: bool = _field(
        True,
        _b(
            "Without sensors that say it moved, a clip best where the last was and facing as "
            "it did there is taken as held still too."
        ),
    )
    track_uniform: float = _field(
        1e-3,
        Rule(
            "number",
            ("Share of a uniform belief mixed in at every update: a wrong lock-in is undone by evidence."),
            "share",
            lo=0,
            hi=1,
        ),
    )
    track_backward: float = _field(
        0.3,
        Rule(
            "number",
            ("A move walking backwards from where the clip says the phone faces counts this much."),
            "factor",
            lo=0,
            hi=1,
        ),
    )
    track_turn_gate_deg: float = _field(
        45.0,
        Rule(
            "number",
            ("A move whose facing changed by more than this other than the gyroscope says counts less."),
            "degrees",
            lo=0,
            hi=180,
            lo_open=True,
        ),
    )
    track_floor_change: float = _field(
        0.05,
        Rule("number", "Belief a lift's or stairs' node passes to the other floor an update.", "share", lo=0, hi=1),
    )
    track_ambiguous: float = _field(
        0.35,
        Rule(
            "number",
            'Belief 3 m or more from the answer at which it says "not sure".',
            "share",
            lo=0,
            hi=1,
            lo_open=True,
        ),
    )
    track_alike_cost: float | None = _field(
        10.0,
        Rule(
            "number",
            (
                "A place the venue's own model finds alike to another (score s) keeps at least "
                "the other's log-likelihood less this * (1 - s) in the second belief."
            ),
            "nats",
            lo=0,
            optional=True,
        ),
    )
    track_confidence_features: list[str] = _field(
        ["mass", "far", "young"],
        Rule(
            "list",
            (
                "Inputs of the filtered pose's confidence model, named in "
                "aggregate.TRACK_CONFIDENCE_INPUTS; fit by bench/tracking.py on the tuning "
                "families' walks."
            ),
            item=_is_name,
            item_doc="input names",
        ),
    )
    track_confidence_coef: list[float] = _field(
        [-0.436, 5.367, -2.68, 1.883],
        Rule("list", "Its intercept, then one weight per input.", item=_is_number, item_doc="numbers"),
    )
    track_recent_s: float = _field(
        1.0,
        Rule("number", "The clips' own confidence is averaged over about this long.", "seconds", lo=0, lo_open=True),
    )
    track_recent_min: float | None = _field(
        0.5,
        Rule(
            "number",
            'While that average is below this, the answer is held below "sure".',
            "confidence",
            lo=0,
            hi=1,
            optional=True,
        ),
    )
    track_doubt_cap: float = _field(
        0.79,
        Rule(
            "number",
            ('The confidence an answer is held at when the clips doubt it (below the app\'s "sure", 0.8).'),
            "confidence",
            lo=0,
            hi=1,
        ),
    )
    track_clip_tie: float | None = _field(
        0.5,
        Rule(
            "number",
            (
                "When the clip alone is sure of another place and the belief holds it at least "
                "this times as likely as the answer's, the answer is the clip's place (still not "
                '"sure").'
            ),
            "ratio",
            lo=0,
            hi=1,
            lo_open=True,
            optional=True,
        ),
    )
    track_clip_confidence_features: list[str] = _field(
        ["support", "margin"],
        Rule(
            "list",
            (
                "The clip's own confidence as the two rules above read it: the single clip's "
                "model they were chosen with, kept apart from `confidence_*`."
            ),
            item=_is_name,
            item_doc="input names",
        ),
    )
    track_clip_confidence_coef: list[float] = _field(
        [-6.68, 10.731, 10.215],
        Rule("list", "Its intercept, then one weight per input.", item=_is_number, item_doc="numbers"),
    )

    @staticmethod
    def of(conf: Mapping[str, Any]) -> TrackingSettings:
        """A venue's tracking settings (its own, else the defaults), checked."""
        return _of(TrackingSettings, conf)


STAGES: tuple[tuple[type, str], ...] = (
    (FeatureSettings, "features (unwarp.py, level.py, curves.py, spectrum.py)"),
    (SearchSettings, "search (index.py)"),
    (AggregationSettings, "aggregation and confidence (aggregate.py)"),
    (ModellingSettings, "modelling (model_venue.py)"),
    (TrackingSettings, "tracking (tracking.py)"),
    (VerifySettings, "verification by local features (verify.py)"),
)
OWN_KEYS = ("preset", "version")  # besides the stages' fields: the preset's name, the format


def field_default(f: Any) -> Any:
    """A field's default (a list's factory called)."""
    return f.default if f.default is not MISSING else f.default_factory()


# Every key's Rule and stage, and every key's default as one flat dict (presets.DEFAULTS): made
# once, read by every check (a venue's settings are checked on every read of settings.json).
RULES: dict[str, tuple[Rule, type]] = {f.name: (f.metadata["rule"], cls) for cls, _ in STAGES for f in fields(cls)}
DEFAULTS: dict[str, Any] = {f.name: field_default(f) for cls, _ in STAGES for f in fields(cls)}


def rules() -> dict[str, tuple[Rule, type]]:
    """Every key, its Rule and the stage that owns it."""
    return dict(RULES)


def defaults() -> dict[str, Any]:
    """Every stage's defaults as one flat dict, a copy the caller may change."""
    return copy.deepcopy(DEFAULTS)


Stage = TypeVar("Stage")


def _of(cls: type[Stage], conf: Mapping[str, Any]) -> Stage:
    """The stage's settings of `conf` (its own, else the defaults), each checked against its Rule."""
    kw = {}
    for f in fields(cast(Any, cls)):
        rule = f.metadata["rule"]
        if f.name in conf:
            v = conf[f.name]
            if not rule.accepts(v):
                raise OmninavError(f"{f.name} must be {rule.range_text()}; got {v!r}")
            kw[f.name] = v
    return cls(**kw)


def check(conf: Mapping[str, Any]) -> None:
    """Every key known and within its range, and what relates keys consistent; an OmninavError
    that names the key otherwise. A settings dict that passes answers every locate."""
    unknown = sorted(k for k in conf if k not in RULES and k not in OWN_KEYS)
    if unknown:
        raise OmninavError(f"unknown settings {unknown} (known: docs/settings.md)")
    for cls, _ in STAGES:
        _of(cls, conf)
    _check_band_channels(conf)
    _check_confidence(conf)


def _check_band_channels(conf: Mapping[str, Any]) -> None:
    """Known channels, distinct; and with `band_channels`, one non-empty list per band: anything
    else would make curves here that the phone cannot make, or a record whose curves do not say
    which is which."""
    from .curves import CHANNELS

    def names(c: Any) -> bool:
        return len(c) > 0 and len(set(c)) == len(c) and set(c) <= set(CHANNELS)

    channels = conf.get("channels", [])
    if not names(channels):
        raise OmninavError(f"channels must be distinct channels of {', '.join(CHANNELS)}; got {channels!r}")
    per = conf.get("band_channels")
    bands = conf.get("bands", DEFAULTS["bands"])
    if per is not None and not (len(per) == len(bands) and all(names(c) for c in per)):
        raise OmninavError(
            f"band_channels must be null or one list of distinct channels ({', '.join(CHANNELS)}) per band "
            f"({len(bands)}); got {per!r}"
        )


def _check_confidence(conf: Mapping[str, Any]) -> None:
    """A confidence model that could not be evaluated would fail every locate: refused here."""
    from .aggregate import CONFIDENCE_INPUTS, TRACK_CONFIDENCE_INPUTS

    d = DEFAULTS
    for prefix, known, what in (
        ("confidence", CONFIDENCE_INPUTS, "confidence inputs"),
        ("track_confidence", TRACK_CONFIDENCE_INPUTS, "tracking confidence inputs"),
        ("track_clip_confidence", CONFIDENCE_INPUTS, "confidence inputs (track_clip_confidence)"),
    ):
        names = conf.get(f"{prefix}_features", d[f"{prefix}_features"])
        unknown = [n for n in names if n not in known]
        if unknown:
            raise OmninavError(f"unknown {what} {unknown} (known: {', '.join(known)})")
        if len(conf.get(f"{prefix}_coef", d[f"{prefix}_coef"])) != 1 + len(names):
            raise OmninavError(f"{prefix}_coef needs {1 + len(names)} weights (an intercept and one per input)")
