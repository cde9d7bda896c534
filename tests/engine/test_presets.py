"""Named presets (presets.py): the "wide" venue option makes the record the phone can make, and
holds a place where the default's narrow bands let go (docs/benchmarks.md, "Accuracy on three sources")."""

from __future__ import annotations

import numpy as np
import pytest

from omninav.errors import OmninavError
from omninav.extract import Extractor
from omninav.heading import relative_heading
from omninav.presets import DEFAULTS, PRESETS, n_curves, resolve, setting, settings_id
from omninav.synth import build_scene, donut_lens
from omninav.synth.render import CameraModel, camera_frame, world_panorama
from omninav.synth.walks import grid_for

PLACES = [(8.0, 2.2, 30.0), (4.0, 1.8, 200.0), (11.0, 2.5, 95.0)]  # x, y, heading in the small venue


def test_wide_is_a_venue_option_with_a_record_of_its_own() -> None:
    wide, default = resolve("wide"), resolve("default")
    assert "wide" in PRESETS and wide["preset"] == "wide"
    assert wide["bands"] == [[-20.0, 20.0]] and wide["band_channels"] is None
    assert n_curves(wide) * wide["n_harmonics"] * 4 == 768  # bytes a frame: half-float complex
    assert wide["level_iters"] == 2 and wide["soft_clip_sd"] == 1.25 and wide["gray_world"]
    # searched as the default searches, with features of its own: another settings id in every record
    assert all(wide[k] == default[k] for k in ("shared_candidates", "shortlist", "candidates", "aggregate"))
    assert settings_id(wide) not in (settings_id(default), settings_id(resolve("six")))
    with pytest.raises(OmninavError, match="unknown preset"):
        resolve("robust")


def _shot(v, place, height=1.35, dx=0.0):
    scene, lens, grid, cam = v
    pano = world_panorama(scene, place[0] + dx, place[1], height, grid)
    return camera_frame(cam, pano, grid, place[2])[..., ::-1].copy()


def test_wide_holds_a_place_that_a_lens_off_in_elevation_or_another_height_moves(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """The same place, read through a lens profile 2 degrees off or filmed 0.2 m lower, loses a
    fraction of what it loses with the default's five narrow bands; another place 3 m on scores as
    low with either (what is given up is the narrow bands' hold on look-alikes, not all of it)."""
    from bench.ablation import elevation_off

    lens = donut_lens(0.5)
    v = (build_scene(5, "small"), lens, grid_for(lens, 1440), CameraModel.create(lens))
    lost: dict[str, list[float]] = {}
    other: dict[str, list[float]] = {}
    for name in ("default", "wide"):
        conf = resolve(name)
        ext, off = Extractor(lens, conf), Extractor(elevation_off(lens, 2.0), conf)
        for p in PLACES:
            ref = ext.spectrum(_shot(v, p))
            lost.setdefault(name, []).append(1.0 - float(relative_heading(off.spectrum(_shot(v, p)), ref)[1]))
            lost[name].append(1.0 - float(relative_heading(ext.spectrum(_shot(v, p, height=1.15)), ref)[1]))
            other.setdefault(name, []).append(float(relative_heading(ext.spectrum(_shot(v, p, dx=3.0)), ref)[1]))
    assert all(w < d / 2 for w, d in zip(lost["wide"], lost["default"], strict=True)), lost
    assert max(other["wide"]) < 0.5 and np.mean(other["wide"]) <= np.mean(other["default"]) + 0.05, other


def test_a_default_handed_out_is_a_copy_and_a_venues_own_setting_is_its_own():
    # a hand-made settings dict without the key gets today's default; changing what it was given
    # changes no other venue's defaults
    key = next(k for k, v in DEFAULTS.items() if isinstance(v, list))
    got = setting({}, key)
    assert got == DEFAULTS[key]
    got.append("changed")
    assert "changed" not in DEFAULTS[key] and setting({}, key) == DEFAULTS[key]
    own = [1, 2]
    assert setting({key: own}, key) is own
