"""extract_pool.py: frames extracted on worker processes through shared memory give this process's
spectra, the shared memory is lent a bounded number of frames at a time, and a pool whose worker
died says so and is replaced."""

from __future__ import annotations

import os
import signal
from concurrent.futures.process import BrokenProcessPool

import numpy as np
import pytest

from omninav import extract_pool, model_venue
from omninav.calib.correct import ClipLens, clip_spectra
from omninav.extract import Extractors
from omninav.lens import load_lens
from omninav.model_venue import VideoSource, model_videos
from omninav.presets import resolve
from omninav.store import Store
from omninav.video import VideoInfo, in_order, iter_video
from omninav.walk_path import load_walk_path


@pytest.fixture(scope="module")
def pool():
    p = extract_pool.ExtractPool(2, slots=3)
    yield p
    p.close()


@pytest.fixture(scope="module")
def frames(small_ds):
    return [f for _, f in iter_video(VideoInfo(small_ds.model_video), stride=3, last=35)]


def test_the_workers_give_this_process_spectra(pool, frames, small_ds):
    """Through ClipLens and in_order as modelling runs them: the serial loop's spectra, to the bit,
    in frame order, through the lens fitted to the clip's ring."""
    lens = load_lens(small_ds.root / "model_lens.json")
    conf = resolve("default")
    want, serial = clip_spectra(lens, frames, Extractors(conf).spectrum)
    clip = ClipLens(lens, pool.extract(conf))
    got = list(in_order(clip, enumerate(frames), 4))  # more in flight than the pool has slots
    assert [i for i, _ in got] == list(range(len(frames)))
    assert np.array_equal(np.stack([s for _, s in got]), want)
    assert repr(clip.lens) == repr(serial.lens)


def test_frames_of_another_size_and_other_settings(pool, frames, small_ds):
    lens = load_lens(small_ds.root / "model_lens.json")
    conf = {**resolve("default"), "level_iters": 0}
    small = np.ascontiguousarray(frames[0][::2, ::2])
    for f in (small, frames[1], small):
        assert np.array_equal(pool.submit(conf, lens, f).result(), Extractors(conf).spectrum(lens)(f))
    with pytest.raises(ValueError, match="uint8"):
        pool.submit(conf, lens, frames[0].astype(np.float32))


def test_cancelled_frames_give_their_slots_back(pool, frames, small_ds):
    """Three slots: thirty frames, most of them cancelled before they ran, never wait for a slot
    that no task holds."""
    lens = load_lens(small_ds.root / "model_lens.json")
    conf = resolve("default")
    futs = []
    for f in frames * 3:
        futs.append(pool.submit(conf, lens, f))
        futs[-1].cancel()
    last = pool.submit(conf, lens, frames[0])
    assert np.array_equal(last.result(timeout=60), Extractors(conf).spectrum(lens)(frames[0]))
    slots = pool._by_size[frames[0].shape]
    assert sorted(slots._free) == [0, 1, 2]


def test_a_killed_worker_fails_its_frames_and_the_pool_is_replaced(frames, small_ds):
    lens = load_lens(small_ds.root / "model_lens.json")
    conf = resolve("default")
    first = extract_pool.shared(2)
    os.kill(next(iter(first._ex._processes)), signal.SIGKILL)
    with pytest.raises(BrokenProcessPool):
        for _ in range(20):
            first.submit(conf, lens, frames[0]).result(timeout=60)
    again = extract_pool.shared(2)
    assert again is not first and first.broken
    want = Extractors(conf).spectrum(lens)(frames[0])
    assert np.array_equal(again.submit(conf, lens, frames[0]).result(timeout=60), want)


def test_modelling_on_processes_is_modelling_on_threads(small_ds, tmp_path, monkeypatch):
    """The same walk modelled with its frames on processes and on threads: the same generation."""
    src = VideoSource(
        small_ds.model_video, load_walk_path(small_ds.model_walk_path), load_lens(small_ds.root / "model_lens.json")
    )
    monkeypatch.setattr(model_venue, "extract_threads", lambda: 2)
    got = {}
    for name, start in (("processes", 0), ("threads", 10**9)):
        monkeypatch.setattr(model_venue, "PROCESSES_FROM", start)
        st = Store(tmp_path / name)
        model_videos(st, "lab", [src], settings=resolve("default"))
        got[name] = st.load("lab", mmap=False)
    assert len(got["processes"].frames) > 50
    assert np.array_equal(got["processes"].frames, got["threads"].frames)
    assert np.array_equal(got["processes"].spectra, got["threads"].spectra)
