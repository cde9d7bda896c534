import json
from dataclasses import replace

import numpy as np
import pytest

from omninav.calib.lens_fit import scaled_lens
from omninav.errors import OmninavError
from omninav.lens import (
    Catadioptric,
    direction_to_pixel,
    lens_from_dict,
    load_lens,
    pixel_to_direction,
)
from omninav.synth import donut_lens, equirect_lens
from omninav.synth.clipon import REAL_MIRROR_SENSOR


@pytest.mark.parametrize(
    "lens",
    [
        donut_lens(),
        donut_lens(0.5),
        equirect_lens(),
        Catadioptric((640, 480), (320, 240), 50, 200, (-60.0, 0.4), 0.0, False),
        replace(donut_lens(), sensor=REAL_MIRROR_SENSOR),
    ],
)
def test_direction_pixel_round_trip(lens):
    rng = np.random.default_rng(0)
    lo, hi = lens.elevation_range()
    az = rng.uniform(0, 360, 500)
    el = rng.uniform(max(lo, -80) + 0.5, min(hi, 80) - 0.5, 500)
    x, y = direction_to_pixel(lens, az, el)
    az2, el2 = pixel_to_direction(lens, x, y)
    assert np.allclose(np.mod(az2 - az + 180, 360) - 180, 0, atol=1e-6)
    assert np.allclose(el2, el, atol=1e-3)


def test_conventions_forward_and_ccw():
    """forward_deg is the image angle that looks ahead; ccw: azimuth turns the other way."""
    lens = donut_lens()  # forward_deg 90 (image down), ccw
    x, y = direction_to_pixel(lens, np.array([0.0, 90.0]), np.array([0.0, 0.0]))
    cx, cy = lens.center
    assert x[0] == pytest.approx(cx, abs=1e-6) and y[0] > cy  # forward: straight down the image
    # clockwise 90 deg (to the right) with ccw=True is image angle 90 - 90 = 0: +x
    assert x[1] > cx and y[1] == pytest.approx(cy, abs=1e-6)
    eq = equirect_lens(1440)
    xe, _ = direction_to_pixel(eq, np.array([0.0, 90.0]), np.array([0.0, 0.0]))
    assert xe[0] == pytest.approx(720) and xe[1] == pytest.approx(1080)


@pytest.mark.parametrize("field", ["model", "image_size", "center", "r_inner", "r_outer", "elevation_poly"])
def test_missing_field_names_it(field):
    d = donut_lens().to_dict()
    del d[field]
    with pytest.raises(OmninavError, match=field if field != "model" else "model"):
        lens_from_dict(d)


@pytest.mark.parametrize(
    "patch,msg",
    [
        ({"r_inner": 400.0}, "r_inner < r_outer"),
        ({"elevation_poly": [-40.0, 0.4, -0.001]}, "monotonic"),
        ({"center": [1, "a"]}, "finite number"),
        ({"image_size": [960]}, "image_size"),
        ({"model": "fisheye"}, "unknown lens model"),
    ],
)
def test_bad_profiles(patch, msg):
    d = {**donut_lens().to_dict(), **patch}
    with pytest.raises(OmninavError, match=msg):
        lens_from_dict(d)


def test_a_sensor_moves_the_pixels_as_its_matrix_and_decentring_say():
    """lens.json's `sensor`: the symmetric offset o is seen at center + M (o + s t(o / s))."""
    plain = donut_lens()
    lens = replace(plain, sensor=REAL_MIRROR_SENSOR)
    az, el = np.array([0.0, 90.0, 200.0]), np.array([-20.0, 0.0, 10.0])
    x0, y0 = direction_to_pixel(plain, az, el)
    ox, oy = x0 - plain.center[0], y0 - plain.center[1]
    p1, p2 = REAL_MIRROR_SENSOR.tangential
    xn, yn = ox / 340.0, oy / 340.0
    q = xn**2 + yn**2
    ux = ox + 340.0 * (2 * p1 * xn * yn + p2 * (q + 2 * xn**2))
    uy = oy + 340.0 * (p1 * (q + 2 * yn**2) + 2 * p2 * xn * yn)
    m = np.array(REAL_MIRROR_SENSOR.matrix).reshape(2, 2)
    x, y = direction_to_pixel(lens, az, el)
    assert np.allclose(x - plain.center[0], m[0, 0] * ux + m[0, 1] * uy)
    assert np.allclose(y - plain.center[1], m[1, 0] * ux + m[1, 1] * uy)
    assert np.hypot(x - x0, y - y0).max() > 3.0  # a real mirror's departure is pixels, not noise
    assert lens_from_dict(json.loads(json.dumps(lens.to_dict()))) == lens


def test_a_scaled_profile_scales_its_sensor_with_the_picture():
    """A re-clipped lens whose picture is 5 % larger sees each direction 5 % farther out."""
    lens = replace(donut_lens(), sensor=REAL_MIRROR_SENSOR)
    big = scaled_lens(lens, (3.0, -2.0), 1.05)
    az, el = np.linspace(0, 350, 36), np.full(36, 5.0)
    x, y = direction_to_pixel(lens, az, el)
    xb, yb = direction_to_pixel(big, az, el)
    assert np.allclose(xb - big.center[0], 1.05 * (x - lens.center[0]), atol=1e-6)
    assert np.allclose(yb - big.center[1], 1.05 * (y - lens.center[1]), atol=1e-6)


@pytest.mark.parametrize(
    "sensor",
    [
        {"matrix": [[1, 0], [0, 1]], "tangential": [0.3, 0], "scale": 340},  # no small decentring
        {"matrix": [[1, 0.9], [0, 1]], "tangential": [0, 0], "scale": 340},  # no skew that large
        {"matrix": [[1, 0], [0, 1]], "tangential": [0, 0], "scale": 0},
        {"matrix": [1, 0, 0, 1], "tangential": [0, 0], "scale": 340},
        {"matrix": [[1, 0], [0, "a"]], "tangential": [0, 0], "scale": 340},
        "flat",
    ],
)
def test_a_sensor_out_of_shape_is_refused_by_name(sensor):
    with pytest.raises(OmninavError, match="sensor"):
        lens_from_dict({**donut_lens().to_dict(), "sensor": sensor})


def test_load_lens_errors(tmp_path):
    with pytest.raises(OmninavError, match="not found"):
        load_lens(tmp_path / "nope.json")
    p = tmp_path / "bad.json"
    p.write_text("{not json")
    with pytest.raises(OmninavError, match="not readable JSON"):
        load_lens(p)
    p.write_text(json.dumps(equirect_lens().to_dict()))
    assert load_lens(p).model == "equirectangular"
