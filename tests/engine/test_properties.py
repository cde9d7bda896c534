"""Hypothesis properties of everything that decodes what a client sends: the feature record (binary
and JSON), lens profiles, modelling walk paths and places.

Each decoder either gives back what was encoded (within the record's float16/int16 quantisation) or
refuses the input with OmninavError whose message is one line:
never another exception, which the server would answer with a 500. Inputs are valid values, the same
values with one field broken, and arbitrary JSON or bytes. Derandomized, so CI runs the same cases.
"""

from __future__ import annotations

import json
import math
import struct
from typing import Any

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from omninav.errors import OmninavError
from omninav.lens import Catadioptric, Equirectangular, lens_from_dict
from omninav.presets import n_curves, resolve
from omninav.server import create_app
from omninav.spectrum import MAGIC, RECORD_VERSION, decode_binary, decode_json, encode_binary, encode_json, quantise
from omninav.walk_path import parse_walk_path
from server_helpers import TOKEN

FAST = settings(max_examples=150, derandomize=True, deadline=None, database=None)
CONF = resolve("default")
HEADER = struct.Struct("<3sBHHHII2x")  # the record's header, as docs/formats.md and spectrum.py define it

finite = st.floats(min_value=-1e6, max_value=1e6, allow_nan=False, allow_infinity=False)
# JSON as a client may send it, with the numbers that break naive float conversion
NASTY = [10**400, -(10**400), 1e308, -0.0, 5e-324, 1.0, 2**63]
scalars = (
    st.none()
    | st.booleans()
    | st.integers()
    | st.floats(allow_nan=False, allow_infinity=False)
    | st.sampled_from(NASTY)
    | st.text(max_size=12)
)
nasty_numbers = st.tuples(st.sampled_from(NASTY), st.sampled_from([0, 1, 3])).map(
    lambda vd: json.loads("[" * vd[1] + json.dumps(vd[0]) + "]" * vd[1])
)
json_values = st.recursive(
    scalars,
    lambda inner: st.lists(inner, max_size=4) | st.dictionaries(st.text(max_size=8), inner, max_size=4),
    max_leaves=16,
)


def refused_in_one_line(err: Exception) -> None:
    """What a user reads: a non-empty message on one line (the CLI prints it, the server sends it)."""
    msg = str(err)
    assert msg.strip() and "\n" not in msg and "\r" not in msg, repr(msg)


def decodes_or_refuses(fn: Any, *args: Any) -> Any:
    """fn(*args), or None when it refused with a one-line OmninavError; any other exception
    fails the test."""
    try:
        return fn(*args)
    except OmninavError as e:
        refused_in_one_line(e)
        return None


def broken(valid: st.SearchStrategy[dict[str, Any]]) -> st.SearchStrategy[Any]:
    """A valid object with one field replaced by arbitrary JSON, or dropped."""

    @st.composite
    def one_field(draw: Any) -> Any:
        d = dict(draw(valid))
        key = draw(st.sampled_from(sorted(d)))
        if draw(st.booleans()):
            del d[key]
        else:  # often a nasty number, bare or nested as deep as an array field expects
            d[key] = draw(nasty_numbers | json_values)
        return d

    return one_field()


# ---- the feature record --------------------------------------------------------------------------
@st.composite
def spectra(draw: Any) -> np.ndarray:
    """(F, C, K) complex64 spectra as the extractor makes them: each frame at unit energy (or, a
    frame without texture, at none), any phase."""
    f, c, k = draw(st.integers(1, 4)), draw(st.integers(1, 12)), draw(st.integers(1, 16))
    mag = np.reshape(draw(st.lists(st.floats(0, 1), min_size=f * c * k, max_size=f * c * k)), (f, c, k))
    e = np.sqrt((mag**2).sum(axis=(1, 2), keepdims=True))
    mag = np.where(e > 1e-6, mag / np.maximum(e, 1e-6), 0.0)
    ph = draw(st.lists(st.floats(-math.pi, math.pi), min_size=f * c * k, max_size=f * c * k))
    return (mag * np.exp(1j * np.reshape(ph, (f, c, k)))).astype(np.complex64)


def assert_within_quantisation(got: np.ndarray, spec: np.ndarray) -> None:
    """float16 magnitudes (11 significant bits) and int16 phases (2*pi / 65536 steps)."""
    assert got.dtype == np.complex64 and got.shape == spec.shape
    assert np.allclose(np.abs(got), np.abs(spec), rtol=2**-11, atol=2**-24)
    dphi = np.angle(got * np.conj(spec))  # the phase difference, wrapped
    big = np.abs(spec) > 1e-3  # the phase of a near-zero harmonic is noise either way
    assert np.all(np.abs(dphi[big]) <= math.pi / 32768 + 1e-3)


@FAST
@given(spectra())
def test_binary_record_decodes_to_what_was_encoded(spec: np.ndarray) -> None:
    buf = encode_binary(spec, CONF)
    assert len(buf) == HEADER.size + 4 * spec.size
    got = decode_binary(buf)
    assert np.array_equal(got, quantise(spec))  # exactly what the server itself would keep
    assert_within_quantisation(got, spec)


@FAST
@given(spectra())
def test_json_record_decodes_to_what_was_encoded(spec: np.ndarray) -> None:
    obj = json.loads(json.dumps(encode_json(spec, CONF)))  # through the wire
    got = decode_json(obj)
    assert np.array_equal(got, quantise(spec)) and np.array_equal(got, decode_binary(encode_binary(spec, CONF)))
    assert_within_quantisation(got, spec)


@FAST
@given(spectra())
def test_a_record_for_other_settings_is_refused_by_the_venue(spec: np.ndarray) -> None:
    """Checked against a venue's settings, only a record of its own shape and settings id passes."""
    fits = spec.shape[1:] == (n_curves(CONF), CONF["n_harmonics"])
    for decode, record in ((decode_binary, encode_binary(spec, CONF)), (decode_json, encode_json(spec, CONF))):
        got = decodes_or_refuses(decode, record, CONF)
        assert (got is not None) == fits


@FAST
@given(spectra(), st.floats(0.0, 1.0), st.booleans(), st.data())
def test_a_frame_off_unit_energy_is_refused(spec: np.ndarray, u: float, up: bool, data: Any) -> None:
    """A frame scaled away from unit energy (a broken client: its scores would no longer be
    cosines, and nonsense would be answered as sure) is refused, naming the frame."""
    i = data.draw(st.integers(0, len(spec) - 1))
    assume(float((np.abs(spec[i]) ** 2).sum()) > 0.5)  # not a frame without texture
    top = min(60.0, 1.0 / float(np.abs(spec[i]).max()))  # magnitudes stay in [0, 1]
    gain = 1.03 + u * (top - 1.03) if up and top > 1.03 else 0.02 + u * 0.95
    bad = spec.copy()
    bad[i] *= gain
    for decode, record in ((decode_binary, encode_binary(bad, CONF)), (decode_json, encode_json(bad, CONF))):
        with pytest.raises(OmninavError, match=f"frame {i} is not at unit energy"):
            decode(record)


@st.composite
def record_bytes(draw: Any) -> bytes:
    """Bytes that get past the magic: a header with any sizes, then any payload (right or wrong
    length, NaN and huge float16 values included)."""
    c, k, f = draw(st.integers(0, 4)), draw(st.integers(0, 4)), draw(st.integers(0, 3))
    ver = draw(st.sampled_from([RECORD_VERSION, RECORD_VERSION, 2]))
    head = HEADER.pack(MAGIC, ver, c, k, draw(st.integers(0, 65535)), f, draw(st.integers(0, 2**32 - 1)))
    n = 4 * c * k * f + draw(st.sampled_from([0, 0, 0, -2, 1, 7]))
    return head + draw(st.binary(min_size=max(n, 0), max_size=max(n, 0)))


@FAST
@given(st.binary(max_size=64) | record_bytes())
def test_any_bytes_decode_to_a_record_or_one_line_refusal(buf: bytes) -> None:
    got = decodes_or_refuses(decode_binary, buf)
    if got is not None:
        _, _, c, k, _, f, _ = HEADER.unpack_from(buf)
        assert got.shape == (f, c, k) and got.dtype == np.complex64
        assert np.isfinite(got).all() and (np.abs(got) <= 1.0001).all()
        e = (np.abs(got).astype(np.float64) ** 2).sum(axis=(1, 2))
        assert np.all((np.abs(e - 1) <= 0.01) | (e <= 1e-4))  # each frame at unit energy, or at none


@FAST
@given(json_values | broken(spectra().map(lambda s: encode_json(s, CONF))))
def test_any_json_decodes_to_a_record_or_one_line_refusal(obj: Any) -> None:
    got = decodes_or_refuses(decode_json, obj)
    if got is not None:
        assert got.ndim == 3 and got.dtype == np.complex64 and np.isfinite(got).all()


# ---- lens profiles --------------------------------------------------------------------------------
sizes = st.tuples(st.integers(1, 8000), st.integers(1, 8000))


@st.composite
def donut_profiles(draw: Any) -> dict[str, Any]:
    """A catadioptric profile whose elevation is monotonic over its ring (a linear polynomial)."""
    r_in = draw(st.floats(0, 1000))
    r_out = r_in + draw(st.floats(1, 1000))
    slope = draw(st.floats(0.01, 2)) * draw(st.sampled_from([-1, 1]))
    return {
        "model": "catadioptric",
        "image_size": list(draw(sizes)),
        "center": [draw(finite), draw(finite)],
        "r_inner": r_in,
        "r_outer": r_out,
        "elevation_poly": [draw(st.floats(-90, 90)), slope],
        "forward_deg": draw(st.floats(-720, 720)),
        "ccw": draw(st.booleans()),
    }


equirect_profiles = st.builds(
    lambda size, fx, ccw: {"model": "equirectangular", "image_size": list(size), "forward_x": fx, "ccw": ccw},
    sizes,
    finite,
    st.booleans(),
)
lens_profiles = donut_profiles() | equirect_profiles


@FAST
@given(lens_profiles)
def test_lens_profile_round_trips(d: dict[str, Any]) -> None:
    lens = lens_from_dict(d)
    assert isinstance(lens, Catadioptric if d["model"] == "catadioptric" else Equirectangular)
    assert lens.to_dict() == d  # every field kept, nothing added
    assert lens_from_dict(json.loads(json.dumps(lens.to_dict()))) == lens


@FAST
@given(json_values | broken(lens_profiles))
def test_any_json_is_a_lens_profile_or_one_line_refusal(d: Any) -> None:
    lens = decodes_or_refuses(lens_from_dict, d)
    if lens is not None:
        assert lens_from_dict(lens.to_dict()) == lens


def test_a_lens_polynomial_that_overflows_is_refused() -> None:
    """Found by the API fuzzer: huge coefficients overflowed inside numpy (a 500 under warnings as
    errors, and an unusable profile otherwise)."""
    d = {"model": "catadioptric", "image_size": [284, 284], "center": [0.0, 0.0], "r_inner": 0.0}
    d |= {"r_outer": 9.2e307, "elevation_poly": [0.0, 2.6e43, 0.0, -7.4e15]}
    with pytest.raises(OmninavError, match="overflows"):
        lens_from_dict(d)


def test_lens_flags_are_booleans() -> None:
    """ccw "false" used to read as true (bool("false")); now it is refused."""
    with pytest.raises(OmninavError, match="'ccw' must be true or false"):
        lens_from_dict({"model": "equirectangular", "image_size": [720, 360], "forward_x": 360, "ccw": "false"})
    assert lens_from_dict({"model": "equirectangular", "image_size": [720.0, 360.0], "forward_x": 360}).image_size == (
        720,
        360,
    )


# ---- walk paths ---------------------------------------------------------------------------------------
@st.composite
def walk_paths(draw: Any) -> dict[str, Any]:
    """Waypoints in increasing time, each given by frame or by seconds."""
    fps = draw(st.floats(1, 120))
    steps = draw(st.lists(st.floats(0.05, 100), min_size=1, max_size=6))
    times = np.cumsum([draw(st.floats(0, 100))] + steps)
    wps = []
    for t in times:
        when = {"t": float(t)} if draw(st.booleans()) else {"frame": float(t) * fps}
        wps.append({**when, "x": draw(finite), "y": draw(finite)})
    return {"fps": fps, "waypoints": wps, "heading_offset_deg": draw(st.floats(-360, 360))}


@FAST
@given(walk_paths())
def test_walk_path_decodes_to_what_was_encoded(d: dict[str, Any]) -> None:
    tr = parse_walk_path(json.loads(json.dumps(d)))
    want_t = [w["t"] if "t" in w else w["frame"] / d["fps"] for w in d["waypoints"]]
    assert tr.fps == d["fps"] and tr.heading_offset == d["heading_offset_deg"]
    assert np.allclose(tr.times, want_t, rtol=1e-12) and np.all(np.diff(tr.times) > 0)
    assert np.array_equal(tr.xy, [[w["x"], w["y"]] for w in d["waypoints"]])
    xy, h, ok = tr.pose_at(tr.times)  # at its own waypoints, the walk path is where they say
    assert ok.all() and np.allclose(xy, tr.xy, atol=1e-6) and ((h >= 0) & (h < 360)).all()


@FAST
@given(json_values | broken(walk_paths()))
def test_any_json_is_a_walk_path_or_one_line_refusal(d: Any) -> None:
    tr = decodes_or_refuses(parse_walk_path, d)
    if tr is not None:
        assert len(tr.times) >= 2 and np.all(np.diff(tr.times) > 0) and np.isfinite(tr.xy).all()


# ---- places (the server's validation, on a real database) -----------------------------------------
@pytest.fixture(scope="module")
def catalog(tmp_path_factory: pytest.TempPathFactory) -> Any:
    """The server's catalogue on SQLite, with venue 'v' and floors 1 and 2."""
    data = tmp_path_factory.mktemp("places")
    app = create_app({"DATA": str(data), "ADMIN_TOKEN": TOKEN, "JOB_RUNNER": False})
    cat = app.extensions["omninav"].catalog
    cat.venues.create("v", "V")
    cat.floors.put("v", "2", {"name": "Two"})
    return cat


names = st.text(min_size=1, max_size=200).filter(lambda s: s.strip())


@st.composite
def places(draw: Any) -> dict[str, Any]:
    p: dict[str, Any] = {"name": draw(names), "x": draw(finite), "y": draw(finite)}
    if draw(st.booleans()):
        p["floor"] = draw(st.sampled_from(["1", "2"]))
    if draw(st.booleans()):
        x0, y0 = draw(finite), draw(finite)
        p["area"] = [x0, y0, x0 + draw(st.floats(0.01, 100)), y0 + draw(st.floats(0.01, 100))]
    return p


def _key(p: dict[str, Any]) -> tuple:
    # the area as text: a place without one (None) and one with one must still sort
    return (p.get("floor", "1"), p["name"].strip(), p["x"], p["y"], json.dumps(p.get("area")))


@FAST
@given(st.lists(places(), max_size=4))
def test_places_are_stored_as_sent(catalog: Any, items: list[dict[str, Any]]) -> None:
    stored = catalog.places.add("v", json.loads(json.dumps(items)), replace=True)
    assert sorted(map(_key, stored)) == sorted(map(_key, items))
    assert stored == catalog.places.all("v")  # what the venue document shows


@FAST
@given(st.lists(json_values | broken(places()), min_size=1, max_size=3) | json_values)
def test_any_json_is_places_or_one_line_refusal(catalog: Any, items: Any) -> None:
    try:
        stored = catalog.places.add("v", items, replace=True)
    except OmninavError as e:
        assert type(e) is OmninavError  # a 400: bad input, not a missing or busy thing
        refused_in_one_line(e)
    else:
        assert len(stored) == len(items)
