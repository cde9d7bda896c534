"""video.py: decoding ahead on a thread, and frames extracted on a pool in their own order, the
same spectra as one frame after another."""

from __future__ import annotations

import threading
import time
from collections.abc import Iterator
from concurrent.futures import ThreadPoolExecutor

import cv2
import numpy as np
import pytest

from omninav.calib.correct import ClipLens, clip_spectra
from omninav.extract import Extractors
from omninav.lens import load_lens
from omninav.model_venue import VideoSource, _plan
from omninav.presets import resolve
from omninav.video import VideoInfo, in_order, iter_video, on_pool, read_ahead
from omninav.walk_path import load_walk_path


def test_read_ahead_keeps_the_order_and_raises_the_readers_error():
    assert list(read_ahead(iter(range(100)), 3)) == list(range(100))

    def broken() -> Iterator[int]:
        yield 1
        raise ValueError("bad frame")

    got = []
    with pytest.raises(ValueError, match="bad frame"):
        for x in read_ahead(broken(), 2):
            got.append(x)
    assert got == [1]


def test_read_ahead_stopped_early_closes_what_it_reads():
    closed = threading.Event()

    def endless() -> Iterator[int]:
        try:
            i = 0
            while True:
                yield i
                i += 1
        finally:
            closed.set()  # where a decoder is released

    it = read_ahead(endless(), 2)
    assert [next(it) for _ in range(5)] == [0, 1, 2, 3, 4]
    it.close()
    assert closed.wait(5)


def test_iter_video_stops_at_last(small_ds):
    info = VideoInfo(small_ds.model_video)
    every = [(i, f) for i, f in iter_video(info, stride=3, start=2) if i <= 20]
    upto = list(iter_video(info, stride=3, start=2, last=20))
    assert [i for i, _ in upto] == [2, 5, 8, 11, 14, 17, 20]
    assert all(i == j and np.array_equal(f, g) for (i, f), (j, g) in zip(every, upto, strict=True))


@pytest.mark.parametrize("n", [1, 2, 3, 12])  # shorter than the frames ClipLens holds, and longer
def test_in_order_gives_the_serial_spectra(small_ds, n):
    lens = load_lens(small_ds.root / "model_lens.json")
    frames = [f for _, f in iter_video(VideoInfo(small_ds.model_video), stride=3, last=3 * n - 1)]
    ext = Extractors(resolve("default"))
    want, serial = clip_spectra(lens, frames, ext.spectrum)
    with ThreadPoolExecutor(2) as pool:
        clip = ClipLens(lens, on_pool(pool, ext.spectrum))
        got = list(in_order(clip, ((f"f{i}", f) for i, f in enumerate(frames)), 2))
    assert [t for t, _ in got] == [f"f{i}" for i in range(n)]
    assert np.array_equal(np.stack([s for _, s in got]), want)
    assert repr(clip.lens) == repr(serial.lens)


def test_in_order_cancels_what_is_pending_when_the_frames_fail(small_ds):
    lens = load_lens(small_ds.root / "model_lens.json")
    frames = [f for _, f in iter_video(VideoInfo(small_ds.model_video), stride=3, last=29)]
    started = []

    def slow(lz):
        fn = Extractors(resolve("default")).spectrum(lz)

        def one(f):
            started.append(1)
            time.sleep(0.05)
            return fn(f)

        return one

    def failing() -> Iterator[tuple[int, np.ndarray]]:
        yield from enumerate(frames[:6])
        raise ValueError("frame 6 is the wrong size")

    with ThreadPoolExecutor(1) as pool:
        with pytest.raises(ValueError, match="wrong size"):
            list(in_order(ClipLens(lens, on_pool(pool, slow)), failing(), 8))
    assert len(started) < 6  # the frames not begun when it failed were never extracted


def test_modelling_extracts_the_frames_one_after_another_would(modelled, small_ds):
    """The pool and the poses looked up in blocks change nothing: the same frames, each the same
    spectrum as the clip's frames extracted in a plain loop through ClipLens."""
    st, venue = modelled
    g = st.load(venue, mmap=False)
    src = VideoSource(
        small_ds.model_video, load_walk_path(small_ds.model_walk_path), load_lens(small_ds.root / "model_lens.json")
    )
    p = _plan(src, g.settings)
    cap = cv2.VideoCapture(str(small_ds.model_video))
    frames, numbers = [], []
    for i in range(p.last + 1):
        ok, f = cap.read()
        if not ok:
            break
        if i >= p.first and (i - p.first) % p.stride == 0 and src.walk_path.pose_at(np.array([i / p.vfps]))[2][0]:
            frames.append(f)
            numbers.append(i)
    cap.release()
    want, _ = clip_spectra(src.lens, frames, Extractors(g.settings).spectrum)
    assert g.frames["frame"].tolist() == numbers
    assert np.array_equal(g.spectra, want)
