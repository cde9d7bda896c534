"""The spectrum and the feature record (spectrum.py): unit energy, the record's round trip and size,
malformed records and records made with other settings refused."""

import numpy as np
import pytest

from omninav.curves import normalise
from omninav.errors import OmninavError
from omninav.presets import TWO_BANDS, n_curves, resolve, settings_id
from omninav.spectrum import (
    HEADER_BYTES,
    LOCAL_MAX_BYTES,
    MAX_LOCAL_KEYPOINTS,
    MAX_RECORD_BYTES,
    decode_binary,
    decode_binary_local,
    decode_json,
    decode_json_local,
    encode_binary,
    encode_json,
    quantise,
    record_bytes_per_frame,
    spectrum,
)


def test_spectrum_is_unit_energy_and_shift_invariant_in_magnitude():
    rng = np.random.default_rng(2)
    c = normalise(rng.normal(size=(6, 360)).astype(np.float32))
    f = spectrum(c, 32)
    assert f.shape == (6, 32) and f.dtype == np.complex64
    assert np.sum(np.abs(f) ** 2) == pytest.approx(1.0, rel=1e-5)
    g = spectrum(np.roll(c, 77, axis=1), 32)
    assert np.allclose(np.abs(f), np.abs(g), atol=1e-6)


def unit_spec(conf, frames):
    """A record's spectra: every harmonic alike, each frame at unit energy (as spectrum() scales it)."""
    c, k = n_curves(conf), conf["n_harmonics"]
    return np.full((frames, c, k), 1 / np.sqrt(c * k) + 0j, np.complex64)


def test_record_round_trip_and_size():
    conf = resolve("default")
    assert record_bytes_per_frame(conf) + HEADER_BYTES <= MAX_RECORD_BYTES
    rng = np.random.default_rng(4)
    spec = quantise(
        spectrum(normalise(rng.normal(size=(3, n_curves(conf), 360)).astype(np.float32)), conf["n_harmonics"])
    )
    buf = encode_binary(spec, conf)
    assert len(buf) == HEADER_BYTES + 3 * record_bytes_per_frame(conf)
    assert np.array_equal(decode_binary(buf, conf), spec)
    assert np.array_equal(decode_json(encode_json(spec, conf), conf), spec)


@pytest.mark.parametrize(
    "mutate,msg",
    [
        (lambda b: b[:10], "too short"),
        (
            lambda b: b[:-2],
            r"is 914 bytes, but its header says 1 x 14 x 16 \(frames x curves x harmonics\), which take 916",
        ),
        (lambda b: b"XXX" + b[3:], "bad magic"),
        (lambda b: b[:3] + bytes([9]) + b[4:], "version 9"),
        (lambda b: b[:20] + b"\x00\x7e" + b[22:], "NaN or Inf"),  # float16 NaN bits
    ],
)
def test_malformed_binary_records(mutate, msg):
    conf = resolve("default")
    spec = unit_spec(conf, 1)
    with pytest.raises(OmninavError, match=msg):
        decode_binary(mutate(encode_binary(spec, conf)), conf)


def test_malformed_json_records():
    conf = resolve("default")
    spec = unit_spec(conf, 2)
    good = encode_json(spec, conf)
    with pytest.raises(OmninavError, match="NaN"):
        decode_json({**good, "mag": [[[float("nan")] * conf["n_harmonics"]] * n_curves(conf)] * 2}, conf)
    with pytest.raises(OmninavError, match="this venue needs"):
        decode_json({**good, "mag": [m[:-1] for m in good["mag"]], "phase": [p[:-1] for p in good["phase"]]}, conf)
    with pytest.raises(OmninavError, match="missing"):
        decode_json({"version": 1}, conf)
    with pytest.raises(OmninavError, match="version"):
        decode_json({**good, "version": 3}, conf)
    half = np.concatenate([spec, spec * 0.5])  # the third frame at a quarter of the energy
    for decode, record in ((decode_json, encode_json(half, conf)), (decode_binary, encode_binary(half, conf))):
        with pytest.raises(OmninavError, match="frame 2 is not at unit energy.*sum to 0.25"):
            decode(record, conf)
    assert decode_json(encode_json(np.concatenate([spec, 0 * spec]), conf), conf).shape == (4, *spec.shape[1:])


def _local(n: int, seed: int = 5) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    b = rng.normal(size=(n, 3))
    return b / np.linalg.norm(b, axis=1, keepdims=True), rng.integers(0, 256, (n, 32), dtype=np.uint8)


def test_a_version_2_record_carries_its_last_frames_local_features_within_32_kb():
    conf = resolve("verified")
    spec = unit_spec(conf, 10)
    b, d = _local(1000)
    for decode, record in (
        (decode_binary_local, encode_binary(spec, conf, (b, d))),
        (decode_json_local, encode_json(spec, conf, (b, d))),
    ):
        got, local = decode(record, conf)
        assert np.array_equal(got, decode_binary(encode_binary(spec, conf), conf))
        assert local is not None and len(local[0]) == MAX_LOCAL_KEYPOINTS  # the first 880 kept
        angle = np.degrees(np.linalg.norm(local[0] - b[:MAX_LOCAL_KEYPOINTS], axis=1))  # (small angles)
        assert angle.max() < 0.01 and np.array_equal(local[1], d[:MAX_LOCAL_KEYPOINTS])
    block = len(encode_binary(spec, conf, (b, d))) - len(encode_binary(spec, conf))
    assert block == LOCAL_MAX_BYTES <= 32 * 1024
    assert decode_binary_local(encode_binary(spec, conf), conf)[1] is None  # version 1: none
    assert decode_binary_local(encode_binary(spec, conf, _local(0)), conf)[1][0].shape == (0, 3)


def test_malformed_local_blocks_are_refused():
    conf = resolve("verified")
    spec = unit_spec(conf, 1)
    good = encode_binary(spec, conf, _local(10))
    at = len(encode_binary(spec, conf))
    for bad, msg in (
        (good[:-1], "headers say"),
        (good[:at], "no local block"),
        (good[:at] + b"XYZ" + good[at + 3 :], "'LOC'"),
        (good[: at + 3] + b"\x01" + good[at + 4 :], "zero byte"),
        (good[: at + 4] + (881).to_bytes(4, "little") + good[at + 8 :], "at most 880"),
        (good[: at + 8 + 20] + (9001).to_bytes(2, "little") + good[at + 30 :], r"\[-90, 90\]"),
    ):
        with pytest.raises(OmninavError, match=msg):
            decode_binary_local(bad, conf)
    j = encode_json(spec, conf, _local(10))
    for local, msg in (
        (None, "needs 'local'"),
        ({**j["local"], "descriptors": "!!!" + j["local"]["descriptors"][3:]}, "base64"),
        ({**j["local"], "el": j["local"]["el"][:-1]}, "as many elevations"),
        ({**j["local"], "az": [70000] * 10}, "azimuths must be integers"),
        ({**j["local"], "el": [True] * 10}, "elevations must be integers"),
        ({**j["local"], "el": [9001] * 10}, r"\[-90, 90\]"),
        ({**j["local"], "el": [10**30] * 10}, r"\[-90, 90\]"),
        ({**j["local"], "descriptors": "é" * len(j["local"]["descriptors"])}, "base64"),
        ({"az": [0] * 881, "el": [0] * 881, "descriptors": ""}, "at most 880"),
        ({"az": [0], "el": [0], "descriptors": "A" * 44}, "hold 33 bytes"),  # (no padding)
    ):
        with pytest.raises(OmninavError, match=msg):
            decode_json_local({**j, "local": local}, conf)
    with pytest.raises(OmninavError, match="is version 2"):
        decode_json_local({**j, "version": 1}, conf)


def test_records_made_with_other_settings_are_refused():
    conf = resolve("default")
    spec = unit_spec(conf, 1)
    other = {**conf, "gray_world": False}  # same shape, different features
    with pytest.raises(OmninavError, match="other settings"):
        decode_binary(encode_binary(spec, other), conf)
    with pytest.raises(OmninavError, match="other settings"):
        decode_json(encode_json(spec, other), conf)


def test_a_record_from_an_app_older_than_per_band_channels_is_refused_and_says_so():
    conf = resolve("default")
    # an app from before reads the venue's settings without band_channels: every channel in every band
    c = len(conf["bands"]) * len(conf["channels"])
    rng = np.random.default_rng(0)
    spec = rng.normal(size=(2, c, 16)) + 1j * rng.normal(size=(2, c, 16))
    spec /= np.linalg.norm(spec.reshape(2, -1), axis=1)[:, None, None]
    old_app = encode_binary(spec.astype(np.complex64), {**conf, "band_channels": None})
    old_app = old_app[:14] + settings_id(conf).to_bytes(4, "little") + old_app[18:]  # the venue's id, as it read it
    with pytest.raises(OmninavError, match=f"have {c} curves .* needs 14 .* this app is older than the server"):
        decode_binary(old_app, expect=conf)
    # a phone that read the venue before it was modelled anew: the settings, named first (with the id now)
    with pytest.raises(OmninavError, match="other settings") as e:
        decode_binary(encode_binary(spec.astype(np.complex64), {**conf, **TWO_BANDS}), expect=conf)
    assert e.value.details["venue_settings_id"] == settings_id(conf)
