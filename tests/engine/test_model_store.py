"""Modelling and venue storage: frames placed by the walk path, atomic generations, interruptions."""

import json

import numpy as np
import pytest

from omninav.errors import OmninavError
from omninav.lens import load_lens
from omninav.model_venue import model_video
from omninav.presets import n_curves, resolve
from omninav.store import Store, check_id
from omninav.walk_path import load_walk_path, parse_walk_path


def test_modelled_frames_follow_the_walk_path(modelled, small_ds):
    st, vid = modelled
    g = st.load(vid)
    tr = load_walk_path(small_ds.model_walk_path)
    conf = resolve("default")
    assert g.spectra.shape[1:] == (n_curves(conf), conf["n_harmonics"]) == (14, 16)
    assert len(g.frames) == len(g.spectra) > 100
    xy, hd, _ = tr.pose_at(g.frames["t"].astype(np.float64))
    assert np.allclose(g.frames["x"], xy[:, 0], atol=1e-3)
    assert np.allclose(g.frames["heading"], hd, atol=1e-3)
    # sampled at the preset's 10 fps from a 10 fps video: every frame, in order
    assert np.all(np.diff(g.frames["frame"]) == 1)
    assert g.videos == ["model.mp4"]


def test_a_walk_path_in_seconds_is_timed_by_the_videos_own_rate(copy_store, modelled, small_ds):
    # the admin page tags waypoints in seconds and sends no fps (docs/formats.md: fps only counts
    # `frame` numbers); a frame's time is its number over the VIDEO's rate (10 fps here), never the
    # walk path's default 30, which would put every frame a third of the way along the walk
    reference = modelled[0].load(modelled[1]).frames
    st, vid = copy_store
    d = json.loads(small_ds.model_walk_path.read_text())
    assert d["fps"] == 10 and all("t" in w for w in d["waypoints"])
    del d["fps"]
    model_video(st, vid, small_ds.model_video, parse_walk_path(d), load_lens(small_ds.root / "model_lens.json"))
    got = st.load(vid).frames
    assert len(got) == len(reference)
    np.testing.assert_array_equal(got["frame"], reference["frame"])
    np.testing.assert_allclose(got["t"], reference["t"], atol=1e-5)
    np.testing.assert_allclose(got["x"], reference["x"], atol=1e-3)
    np.testing.assert_allclose(got["y"], reference["y"], atol=1e-3)


def test_remodelling_a_video_replaces_its_frames(copy_store, small_ds):
    st, vid = copy_store
    n = len(st.load(vid).frames)
    model_video(
        st,
        vid,
        small_ds.model_video,
        load_walk_path(small_ds.model_walk_path),
        load_lens(small_ds.root / "model_lens.json"),
    )
    assert len(st.load(vid).frames) == n


def test_interrupted_modelling_leaves_the_venue_as_it_was(copy_store, small_ds):
    st, vid = copy_store
    before = st.load(vid, mmap=False)

    def boom(done, total, elapsed):
        if done == 40:
            raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        model_video(
            st,
            vid,
            small_ds.query_video,
            load_walk_path(small_ds.query_walk_path),
            load_lens(small_ds.lens),
            progress=boom,
        )
    after = st.load(vid, mmap=False)
    assert np.array_equal(before.frames, after.frames)
    assert np.array_equal(before.spectra, after.spectra)
    assert after.videos == before.videos


def test_a_second_video_adds_frames(copy_store, small_ds):
    st, vid = copy_store
    n = len(st.load(vid).frames)
    model_video(st, vid, small_ds.query_video, load_walk_path(small_ds.query_walk_path), load_lens(small_ds.lens))
    g = st.load(vid)
    assert g.videos == ["model.mp4", "query.mp4"] and len(g.frames) > n
    assert set(np.unique(g.frames["video"])) == {0, 1}
    assert len(list((st.venue_dir(vid)).glob("gen-*"))) <= 2  # old generations are pruned


@pytest.mark.parametrize("bad", ["../x", "a/b", "", "x" * 65, "-lead", "a b", "é"])
def test_venue_ids_with_path_characters_are_refused(bad):
    with pytest.raises(OmninavError, match="invalid venue id"):
        check_id(bad)


def test_store_errors(store: Store, small_ds, tmp_path):
    with pytest.raises(OmninavError, match="no modelled frames"):
        store.load("nowhere")
    assert store.settings("nowhere") is None and store.generation("nowhere") is None
    assert store.frame_count("nowhere") == 0 and store.list() == []  # nothing written by looking
    with pytest.raises(OmninavError, match="lens profile is for"):
        from omninav.synth import donut_lens

        model_video(store, "v1", small_ds.model_video, load_walk_path(small_ds.model_walk_path), donut_lens(1.0))
