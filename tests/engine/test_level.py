"""Levelling (level.py): a tilted lens found from the frame's own upright edges, and undone."""

import math

import numpy as np
import pytest

from omninav.errors import OmninavError
from omninav.extract import Extractor
from omninav.heading import relative_heading
from omninav.lens import Catadioptric, direction_to_pixel
from omninav.level import (
    ANCHOR_DEG,
    anchor_step,
    edge_lean,
    estimate_map,
    intensity,
    level_map,
    tilt_rotation,
    tilted_map,
)
from omninav.presets import TWO_BANDS, resolve, settings_id
from omninav.synth import build_scene, donut_lens, equirect_lens
from omninav.synth.render import CameraModel, camera_frame, world_panorama
from omninav.synth.render import tilt_rotation as render_tilt
from omninav.synth.walks import grid_for
from omninav.unwarp import band_map, unwarp

PLACES = [(8.0, 2.2, 30.0), (4.0, 1.8, 200.0), (11.0, 2.5, 95.0)]  # x, y, heading in the small venue


@pytest.fixture(scope="module")
def venue():
    scene = build_scene(5, "small")
    lens = donut_lens(0.5)
    grid = grid_for(lens, 1440)
    return scene, lens, grid, CameraModel.create(lens)


def shot(venue, place, tilt=0.0, toward=0.0):
    scene, lens, grid, cam = venue
    pano = world_panorama(scene, place[0], place[1], 1.35, grid)
    rot = render_tilt(tilt, toward) if tilt else None
    return camera_frame(cam, pano, grid, place[2], rot)[..., ::-1].copy()


def level(frame, lens, iters=2):
    """level_map with the default preset's maps: (the levelling remap, the tilt, its azimuth)."""
    conf = resolve("default")
    return level_map(frame, lens, band_map(lens, conf), estimate_map(lens, conf), iters)


def vec(tilt, toward):
    return np.array([tilt * math.cos(math.radians(toward)), tilt * math.sin(math.radians(toward))])


def test_the_rotation_is_the_renderers():
    for tilt, toward in [(0.0, 0.0), (3.0, 10.0), (8.0, 250.0), (12.5, -40.0)]:
        assert np.allclose(tilt_rotation(tilt, toward), render_tilt(tilt, toward), atol=1e-12)


@pytest.mark.parametrize("tilt,toward", [(3.0, 40.0), (5.0, 160.0), (8.0, 290.0)])
def test_a_tilt_is_found_from_the_frame_and_undone(venue, tilt, toward):
    _, lens, _, _ = venue
    ext = Extractor(lens, {**resolve("default"), "level_iters": None})
    lev = Extractor(lens, {**resolve("default"), "level_iters": 2})
    for place in PLACES:
        frame = shot(venue, place, tilt, toward)
        _, t, d = level(frame, lens)
        assert np.hypot(*(vec(t, d) - vec(tilt, toward))) < 0.35 * tilt + 0.5, (place, t, d)
        upright = ext.spectrum(shot(venue, place))
        as_is = relative_heading(ext.spectrum(frame), upright)[1]
        levelled = relative_heading(lev.spectrum(frame), upright)[1]
        # the levelled frame is (nearly) the upright one; as it is, the tilt costs its score
        assert levelled > 0.99 and levelled > as_is + 0.5 * (1.0 - as_is), (place, as_is, levelled)


def test_one_pass_finds_most_of_the_tilt_and_a_second_most_of_the_rest(venue):
    _, lens, _, _ = venue
    truth = vec(6.0, 120.0)
    frame = shot(venue, PLACES[0], 6.0, 120.0)
    left = [np.hypot(*(vec(*level(frame, lens, n)[1:]) - truth)) for n in (0, 1, 2)]
    assert left[0] == pytest.approx(6.0) and left[1] < 0.5 * left[0] and left[2] < left[1]


def test_an_upright_frame_stays_nearly_as_it_is(venue):
    _, lens, _, _ = venue
    ext = Extractor(lens, {**resolve("default"), "level_iters": None})
    lev = Extractor(lens, {**resolve("default"), "level_iters": 2})
    for place in PLACES:
        frame = shot(venue, place)
        assert level(frame, lens)[1] < 1.0
        assert relative_heading(lev.spectrum(frame), ext.spectrum(frame))[1] > 0.995


def test_a_frame_without_edges_keeps_the_upright_map(venue):
    _, lens, _, _ = venue
    upright = band_map(lens, resolve("default"))
    grey = np.full((lens.image_size[1], lens.image_size[0], 3), 128, np.uint8)
    m, t, _ = level_map(grey, lens, upright, estimate_map(lens, resolve("default")), 2)
    assert m is upright and t == 0.0
    assert edge_lean(intensity(unwarp(grey, upright)), upright.elevations, upright.valid)[2] == 0


def test_directions_the_lens_does_not_see_read_what_they_read_upright():
    # this donut sees up to +25 degrees, where the default's bands end: tilted, their top rows on
    # one side look above the ring, and read the upright cell instead of black
    lens = donut_lens(0.5)
    conf = {**resolve("default"), "bands": [[-25.0, lens.elevation_range()[1]]], "band_channels": None}
    upright = Extractor(lens, conf).map
    m = tilted_map(lens, upright, tilt_rotation(8.0, 0.0))
    seen = np.isfinite(m.map_x) & (m.map_x >= 0)
    assert seen[upright.valid].all()
    same = (m.map_x == upright.map_x) & (m.map_y == upright.map_y)
    assert same[0].any() and not same[len(same) // 2].any()


@pytest.mark.parametrize("oversample", [1, 4])
@pytest.mark.parametrize("make", [lambda: donut_lens(0.5), lambda: equirect_lens(1440)], ids=["donut", "360"])
def test_the_tilted_map_is_direction_to_pixel_of_the_turned_directions(make, oversample):
    # tilted_map takes a donut's pixel from the turned direction's horizontal components, without
    # arctan2, cos and sin: the same float32 tables as the azimuth and elevation give at every
    # anchor column (ANCHOR_DEG apart), and within 0.08 px of them between (the 360 camera's seam
    # included, where the anchors' columns jump across the frame)
    lens = make()
    upright = Extractor(lens, {**resolve("default"), "oversample": oversample}).map
    rows, cols = upright.map_x.shape
    step = anchor_step(cols)
    assert step == round(ANCHOR_DEG * oversample) > 1
    anchor = np.arange(cols) % step == 0
    el = np.repeat(upright.elevations.astype(np.float64)[:, None], cols, 1)
    az = np.repeat(((np.arange(cols) + 0.5) * 360.0 / cols)[None], rows, 0)
    w = np.stack(
        [
            np.cos(np.radians(el)) * np.cos(np.radians(az)),
            np.cos(np.radians(el)) * np.sin(np.radians(az)),
            np.sin(np.radians(el)),
        ],
        -1,
    )
    for tilt, toward in [(2.0, 10.0), (6.0, 135.0), (12.0, 260.0)]:
        rot = tilt_rotation(tilt, toward)
        c = w @ rot
        x, y = direction_to_pixel(
            lens,
            np.mod(np.degrees(np.arctan2(c[..., 1], c[..., 0])), 360.0),
            np.degrees(np.arcsin(np.clip(c[..., 2], -1, 1))),
        )
        ok = np.isfinite(x) & np.isfinite(y)
        m = tilted_map(lens, upright, rot)
        off = np.maximum(np.abs(m.map_x - x), np.abs(m.map_y - y))
        assert off[ok & anchor].max() < 1e-3
        assert off[ok].max() < 0.08
        if isinstance(lens, Catadioptric):  # the ring's bend between anchors shows
            assert off[ok & ~anchor].max() > 5e-3
        assert (m.map_x[~ok] == upright.map_x[~ok]).all()


def test_a_360_camera_is_levelled_too():
    scene = build_scene(5, "small")
    lens = equirect_lens(1440)
    grid = grid_for(lens, 1440)
    cam = CameraModel.create(lens)
    pano = world_panorama(scene, 8.0, 2.2, 1.35, grid)
    frame = camera_frame(cam, pano, grid, 30.0, render_tilt(5.0, 200.0))[..., ::-1].copy()
    _, t, d = level(frame, lens)
    assert np.hypot(*(vec(t, d) - vec(5.0, 200.0))) < 1.5


def test_levelling_is_the_default_and_venues_modelled_before_it_keep_their_id():
    conf = resolve("default")
    assert conf["level_iters"] == 2 and resolve("paper")["level_iters"] is None
    before = {k: v for k, v in conf.items() if k != "level_iters"}  # a settings.json from before it
    assert settings_id(before) == settings_id({**before, "level_iters": None}) == 1368376577
    assert settings_id(conf) != settings_id(before)
    assert TWO_BANDS["level_iters"] is None  # the default before per-band channels had no levelling


@pytest.mark.parametrize("bad", [-1, 5, 1.5, "2", True, [2]])
def test_level_settings_are_refused_unless_a_small_whole_number_or_null(bad):
    with pytest.raises(OmninavError, match="level_iters"):
        resolve("default", {"level_iters": bad})


def test_intensity_is_the_float64_mean_of_the_first_three_channels_to_the_bit():
    # the phone's worker sums the three bytes and divides by 3 in doubles: the same bits
    pano = np.random.default_rng(3).integers(0, 256, (7, 11, 4), dtype=np.uint8)
    pano[0, :3] = 255
    want = pano[..., :3].astype(np.float64).sum(axis=-1) / 3.0
    for p in (pano, pano[..., :3], pano.astype(np.float32)):  # (a float panorama: summed as floats)
        got = intensity(p)
        assert got.dtype == np.float64 and got.tobytes() == want.tobytes()
