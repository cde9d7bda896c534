"""The unwarp (unwarp.py, the paper's Eq. 1): a rendered panorama recovered, bad frames refused."""

import numpy as np
import pytest

from conftest import smooth_pano
from omninav.synth import donut_lens, equirect_lens
from omninav.synth.render import CameraModel, PanoGrid, camera_frame
from omninav.unwarp import build_map, unwarp


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
