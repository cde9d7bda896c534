"""Each pipeline stage against known answers: unwarp, curves, spectrum record, heading."""

import numpy as np
import pytest

from omninav.curves import channel_images, circular_diff, extract_curves, gray_world, normalise, soft_clip
from omninav.errors import OmninavError
from omninav.extract import Extractor
from omninav.heading import correlation, peak, relative_heading, wrap_deg
from omninav.presets import TWO_BANDS, feature_keys, n_curves, resolve, settings_id
from omninav.spectrum import (
    HEADER_BYTES,
    MAX_RECORD_BYTES,
    decode_binary,
    decode_json,
    encode_binary,
    encode_json,
    quantise,
    record_bytes_per_frame,
    spectrum,
)
from omninav.synth import build_scene, donut_lens, equirect_lens
from omninav.synth.render import CameraModel, PanoGrid, camera_frame, world_panorama
from omninav.unwarp import build_map, unwarp


def smooth_pano(rows: int, width: int, seed: int = 0) -> np.ndarray:
    """A random but smooth colour panorama (low harmonics in azimuth and elevation), uint8."""
    rng = np.random.default_rng(seed)
    a = np.linspace(0, 2 * np.pi, width, endpoint=False)
    e = np.linspace(0, 1, rows)[:, None]
    img = np.zeros((rows, width, 3))
    for c in range(3):
        for k in range(1, 9):
            img[..., c] += rng.normal() * np.cos(k * a + rng.uniform(0, 6.3))[None, :] * (1 + e * rng.normal())
    img = (img - img.min()) / (img.max() - img.min())
    return (40 + 180 * img).astype(np.uint8)


@pytest.mark.parametrize("lens", [donut_lens(), equirect_lens(1440)], ids=["donut", "equirect"])
def test_unwarp_recovers_the_panorama(lens):
    """A frame rendered from a known panorama unwarps back to that panorama."""
    grid = PanoGrid(1440, 50.0, -60.0, 1101)
    pano = smooth_pano(grid.rows, grid.width)
    frame = camera_frame(CameraModel.create(lens), pano, grid, heading_deg=0.0)
    el = np.linspace(30, -40, 71)
    m = build_map(lens, el, 720)
    out = unwarp(frame, m).astype(np.float32)
    # expected: the panorama at the same elevations, columns at the same azimuths
    rows = np.round((grid.el_top - el) / grid.step).astype(int)
    cols = (np.arange(720) * 2 + 1) % grid.width  # column j of 720 = azimuth (j+.5)/2 deg
    exp = pano[rows][:, cols].astype(np.float32)
    err = np.abs(out - exp)
    assert np.median(err) < 3.0 and np.percentile(err, 99) < 12.0


def test_unwarp_rejects_grey_frames():
    m = build_map(donut_lens(0.5), np.array([0.0]), 360)
    with pytest.raises(ValueError, match="colour frame"):
        unwarp(np.zeros((360, 480), np.uint8), m)


def test_curves_shift_with_rotation_and_ignore_gain():
    conf = resolve("six")
    pano = smooth_pano(41, 1440)
    el = np.linspace(20, -20, 41)
    c0 = extract_curves(pano, el, conf)
    c1 = extract_curves(np.roll(pano, -40, axis=1), el, conf)  # 40 of 1440 cols = 10 of 360
    assert c0.shape == (6, 360)
    assert np.allclose(np.roll(c0, -10, axis=1), c1, atol=1e-4)
    dim = (pano.astype(np.float32) * 0.6).astype(np.uint8)
    c2 = extract_curves(dim, el, conf)
    i = conf["channels"].index("I")
    assert np.corrcoef(c0[i], c2[i])[0, 1] > 0.999


def test_gray_world_removes_a_colour_cast():
    rng = np.random.default_rng(1)
    rgb = rng.uniform(0.2, 0.8, (20, 50, 3)).astype(np.float32)
    cast = rgb * np.array([1.2, 0.9, 0.7], np.float32)
    assert np.allclose(gray_world(rgb), gray_world(cast), atol=1e-5)


def test_the_gray_world_means_are_numpys_and_the_phones():
    # one channel at a time in float64: a panorama's k / 255 values sum exactly in any order
    rng = np.random.default_rng(2)
    pano = rng.integers(0, 256, (51, 1440, 3)).astype(np.float32) * np.float32(1.0 / 255.0)
    valid = rng.uniform(size=(51, 1440)) > 0.1
    for v in (None, valid):
        px = pano.reshape(-1, 3) if v is None else pano[v]
        gain = (0.5 / np.maximum(px.mean(axis=0, dtype=np.float64).astype(np.float32), 1e-6)).astype(np.float32)
        assert np.array_equal(gray_world(pano, v), pano * gain)


def test_the_channel_images_are_the_plain_numpy_ones():
    # intensity as (r + g) + b over 3 is rgb.mean(axis=-1) to the bit; gradients as np.roll has them
    rng = np.random.default_rng(3)
    rgb = rng.uniform(0.0, 1.0, (7, 40, 3)).astype(np.float32)
    imgs = channel_images(rgb, ["I", "dI", "dO1"])
    assert np.array_equal(imgs["I"], rgb.mean(axis=-1))
    for ch, x in (("dI", rgb.mean(axis=-1)), ("dO1", (rgb[..., 0] - rgb[..., 1]) * 0.5)):
        assert np.array_equal(imgs[ch], np.abs(np.roll(x, -1, axis=-1) - np.roll(x, 1, axis=-1)) * 0.5)
    for n in (1, 2, 3):
        assert np.array_equal(circular_diff(rgb[0, :n, 0]), np.roll(rgb[0, :n, 0], -1) - np.roll(rgb[0, :n, 0], 1))


def test_soft_clip_bounds_outlying_columns_and_keeps_their_order():
    rng = np.random.default_rng(3)
    raw = rng.normal(size=(2, 360)).astype(np.float32)
    raw[0, 100:104] += 12.0  # a sunlit window: four columns far out
    z = normalise(raw)
    out = soft_clip(z, 1.25)
    assert np.allclose(out.mean(axis=1), 0, atol=1e-5) and np.allclose(out.std(axis=1), 1, atol=1e-4)
    # the window carried most of the first curve's variance; clipped, about its share of columns
    share = lambda c: float((c[0, 100:104] ** 2).sum() / (c[0] ** 2).sum())  # noqa: E731
    assert share(z) > 0.3 and share(out) < 0.1
    # monotonic: where the edges are (the columns' order) is kept, so is a rotation's shift
    assert np.array_equal(np.argsort(z, axis=1, kind="stable"), np.argsort(out, axis=1, kind="stable"))
    assert np.allclose(soft_clip(np.roll(z, 7, axis=1), 1.25), np.roll(out, 7, axis=1), atol=1e-5)


def test_soft_clip_is_the_default_and_venues_modelled_before_it_keep_their_curves_and_id():
    conf = resolve("default")
    assert conf["soft_clip_sd"] == 1.25 and resolve("paper")["soft_clip_sd"] is None
    pano = smooth_pano(41, 1440)
    el = np.linspace(20, -20, 41)
    # a settings.json from before soft clipping (and so before per-band channels)
    old = {k: v for k, v in {**conf, **TWO_BANDS}.items() if k not in ("soft_clip_sd", "band_channels")}
    assert np.array_equal(extract_curves(pano, el, old), extract_curves(pano, el, {**old, "soft_clip_sd": None}))
    clipped = {**old, "soft_clip_sd": 1.25}
    assert np.allclose(extract_curves(pano, el, clipped), soft_clip(extract_curves(pano, el, old), 1.25), atol=1e-6)
    # records carry the settings id: the one phones made for such a venue before this release
    assert settings_id(old) == settings_id({**old, "soft_clip_sd": None}) == 2019879380
    assert settings_id(conf) != settings_id(old)


def test_per_band_channels_are_the_default_and_venues_modelled_before_them_keep_their_id():
    conf = resolve("default")
    assert n_curves(conf) == 14 and conf["band_channels"][-1] == ["O1", "O2", "dO1", "dO2"]
    assert all(c == ["I", "dI"] for c in conf["band_channels"][:5])
    before = {k: v for k, v in {**conf, **TWO_BANDS}.items() if k != "band_channels"}  # its settings.json
    assert n_curves(before) == 12
    # the id phones made for such a venue before this release, with or without the key written as null
    assert settings_id(before) == settings_id({**before, "band_channels": None}) == 4043377008
    assert settings_id(conf) != settings_id(before)


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


def test_band_channels_give_each_band_its_own_curves_in_the_records_order():
    pano = smooth_pano(41, 1440)
    el = np.linspace(20, -20, 41)
    base = {**resolve("six"), "bands": [[-20.0, 0.0], [0.0, 20.0]], "channels": ["I", "dI", "O1"]}
    plain = extract_curves(pano, el, base)
    # the same lists per band: the curves of `channels` x `bands`, the record (and its id) as before
    same = {**base, "band_channels": [["I", "dI", "O1"], ["I", "dI", "O1"]]}
    assert np.array_equal(extract_curves(pano, el, same), plain)
    assert settings_id({**base, "band_channels": None}) == settings_id(base) != settings_id(same)
    # each band its own list, in its order: band-major, the band's channels as listed
    own = {**base, "band_channels": [["O1"], ["dI", "I"]]}
    got = extract_curves(pano, el, own)
    assert got.shape == (3, 360) and n_curves(own) == 3 and n_curves(base) == 6
    assert np.array_equal(got, plain[[2, 4, 3]])
    wide = {**base, "bands": [[-20.0, 20.0]], "band_channels": [["O2"]]}  # a channel `channels` lacks
    assert extract_curves(pano, el, wide).shape == (1, 360)


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


def test_normalise_flat_curve_stays_zero():
    out = normalise(np.ones((2, 360), np.float32))
    assert np.all(out == 0)


def test_spectrum_is_unit_energy_and_shift_invariant_in_magnitude():
    rng = np.random.default_rng(2)
    c = normalise(rng.normal(size=(6, 360)).astype(np.float32))
    f = spectrum(c, 32)
    assert f.shape == (6, 32) and f.dtype == np.complex64
    assert np.sum(np.abs(f) ** 2) == pytest.approx(1.0, rel=1e-5)
    g = spectrum(np.roll(c, 77, axis=1), 32)
    assert np.allclose(np.abs(f), np.abs(g), atol=1e-6)


@pytest.mark.parametrize("shift_deg", [0.0, 12.5, 91.3, 180.0, 271.75, 359.4])
def test_heading_of_a_rotated_panorama(shift_deg):
    """Rotating the curves by a known (sub-degree) angle gives that heading back."""
    rng = np.random.default_rng(3)
    base = normalise(rng.normal(size=(6, 360)).astype(np.float32))
    # sub-column rotation by Fourier shift: q(j) = v(j + s)
    f = np.fft.rfft(base, axis=1)
    k = np.arange(f.shape[1])
    rot = np.fft.irfft(f * np.exp(2j * np.pi * k * shift_deg / 360.0), n=360, axis=1)
    fv, fq = quantise(spectrum(base, 32)), quantise(spectrum(rot.astype(np.float32), 32))
    rel, score = relative_heading(fq, fv)
    assert abs(wrap_deg(rel - shift_deg)) < 0.15
    assert score > 0.99


def test_heading_of_rendered_frames():
    """Two donut frames at one place, headings 10 and 47.3 degrees: rotation 37.3 recovered."""
    scene = build_scene(5, "small")
    lens = donut_lens(0.5)
    grid = PanoGrid(1440, 43.0, -53.0, 385)
    pano = world_panorama(scene, 8.0, 2.2, 1.35, grid)
    cam = CameraModel.create(lens)
    ext = Extractor(lens, resolve("default"))
    a = ext.spectrum(camera_frame(cam, pano, grid, 10.0)[..., ::-1].copy())
    b = ext.spectrum(camera_frame(cam, pano, grid, 47.3)[..., ::-1].copy())
    rel, score = relative_heading(b, a)
    assert abs(wrap_deg(rel - 37.3)) < 0.5
    assert score > 0.9


def test_correlation_peak_values():
    r = np.cos(np.deg2rad(np.arange(256) * 360 / 256 - 100.0))
    s, v = peak(r)
    assert abs(s - 100.0) < 0.2 and v == pytest.approx(1.0, abs=1e-3)
    with pytest.raises(ValueError):
        correlation(np.ones((6, 32), complex), np.ones((6, 32), complex), n_shifts=32)


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


def unit_spec(conf, frames):
    """A record's spectra: every harmonic alike, each frame at unit energy (as spectrum() scales it)."""
    c, k = n_curves(conf), conf["n_harmonics"]
    return np.full((frames, c, k), 1 / np.sqrt(c * k) + 0j, np.complex64)


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
        decode_json({**good, "version": 2}, conf)
    half = np.concatenate([spec, spec * 0.5])  # the third frame at a quarter of the energy
    for decode, record in ((decode_json, encode_json(half, conf)), (decode_binary, encode_binary(half, conf))):
        with pytest.raises(OmninavError, match="frame 2 is not at unit energy.*sum to 0.25"):
            decode(record, conf)
    assert decode_json(encode_json(np.concatenate([spec, 0 * spec]), conf), conf).shape == (4, *spec.shape[1:])


def test_records_made_with_other_settings_are_refused():
    conf = resolve("default")
    spec = unit_spec(conf, 1)
    other = {**conf, "gray_world": False}  # same shape, different features
    with pytest.raises(OmninavError, match="other settings"):
        decode_binary(encode_binary(spec, other), conf)
    with pytest.raises(OmninavError, match="other settings"):
        decode_json(encode_json(spec, other), conf)
