"""The heading (heading.py, the paper's Eq. 6-7): circular cross-correlation of rotated panoramas."""

import numpy as np
import pytest

from omninav.curves import normalise
from omninav.extract import Extractor
from omninav.heading import correlation, peak, relative_heading, wrap_deg
from omninav.presets import resolve
from omninav.spectrum import (
    quantise,
    spectrum,
)
from omninav.synth import build_scene, donut_lens
from omninav.synth.render import CameraModel, PanoGrid, camera_frame, world_panorama


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
