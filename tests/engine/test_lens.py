import json

import numpy as np
import pytest

from omninav.errors import OmninavError
from omninav.lens import (
    Catadioptric,
    direction_to_pixel,
    lens_from_dict,
    load_lens,
    pixel_to_direction,
)
from omninav.synth import donut_lens, equirect_lens


@pytest.mark.parametrize(
    "lens",
    [
        donut_lens(),
        donut_lens(0.5),
        equirect_lens(),
        Catadioptric((640, 480), (320, 240), 50, 200, (-60.0, 0.4), 0.0, False),
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


def test_load_lens_errors(tmp_path):
    with pytest.raises(OmninavError, match="not found"):
        load_lens(tmp_path / "nope.json")
    p = tmp_path / "bad.json"
    p.write_text("{not json")
    with pytest.raises(OmninavError, match="not readable JSON"):
        load_lens(p)
    p.write_text(json.dumps(equirect_lens().to_dict()))
    assert load_lens(p).model == "equirectangular"
