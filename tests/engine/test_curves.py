"""The curves (curves.py, the paper's Eq. 3): shifts with rotation, colour constancy, soft clipping, each
band's own channels, and the venues modelled before each keeping their curves and settings id."""

import numpy as np

from conftest import smooth_pano
from omninav.curves import channel_images, circular_diff, extract_curves, gray_world, normalise, soft_clip
from omninav.presets import TWO_BANDS, n_curves, resolve, settings_id


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


def test_normalise_flat_curve_stays_zero():
    out = normalise(np.ones((2, 360), np.float32))
    assert np.all(out == 0)
