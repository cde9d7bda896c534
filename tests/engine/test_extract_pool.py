"""extract_pool.py: frames extracted on worker processes through shared memory give this process's
spectra, the shared memory is lent a bounded number of frames at a time, and a pool whose worker
died says so and is replaced."""

from __future__ import annotations

import os
import select
import signal
import subprocess
import sys
import textwrap
import time
from concurrent.futures.process import BrokenProcessPool
from pathlib import Path

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


@pytest.fixture
def own_shared(monkeypatch):
    """extract_pool.shared's pools for this test alone (the process's own are others' to use)."""
    mine: dict[int, extract_pool.ExtractPool] = {}
    monkeypatch.setattr(extract_pool, "_SHARED", mine)
    yield mine
    for p in mine.values():
        p.close()


def _eventually(check, timeout_s: float = 10.0) -> bool:
    t0 = time.monotonic()
    while not check():
        if time.monotonic() - t0 > timeout_s:
            return False
        time.sleep(0.02)
    return True


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
    """Each size has its block of slots while its frames are out; a block no frame uses is freed
    when frames of another size come."""
    lens = load_lens(small_ds.root / "model_lens.json")
    conf = {**resolve("default"), "level_iters": 0}
    small = np.ascontiguousarray(frames[0][::2, ::2])
    for f in (small, frames[1], small):
        assert np.array_equal(pool.submit(conf, lens, f).result(), Extractors(conf).spectrum(lens)(f))
        assert _eventually(lambda f=f: list(pool._by_size) == [f.shape] and pool._by_size[f.shape].idle)
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
    assert _eventually(lambda: sorted(slots._free) == [0, 1, 2])


def test_a_killed_worker_fails_its_frames_and_the_pool_is_replaced(frames, small_ds, own_shared):
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


def test_the_workers_end_with_a_killed_owner_and_free_the_shared_memory(tmp_path):
    """An owner killed without its exit handlers (SIGKILL, out of memory) leaves no worker behind,
    and its shared memory goes too."""
    script = tmp_path / "owner.py"
    script.write_text(
        textwrap.dedent(
            """
            import sys, time
            import numpy as np
            from omninav import extract_pool
            if __name__ == "__main__":
                p = extract_pool.ExtractPool(2)
                p.warm()
                p._slots((8, 8, 3))
                print(" ".join(str(w) for w in p._ex._processes), p._by_size[(8, 8, 3)].shm.name, flush=True)
                time.sleep(600)
            """
        )
    )
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(sys.path)}
    owner = subprocess.Popen([sys.executable, str(script)], stdout=subprocess.PIPE, text=True, env=env)
    try:
        assert select.select([owner.stdout], [], [], 60)[0], "the owner did not start its pool"
        *workers, name = owner.stdout.readline().split()
        assert len(workers) == 2 and Path("/dev/shm", name).exists()
    finally:
        owner.kill()
        owner.wait()
        owner.stdout.close()

    def gone(pid: int) -> bool:
        try:
            os.kill(pid, 0)
        except ProcessLookupError:
            return True
        return Path(f"/proc/{pid}/stat").exists() and Path(f"/proc/{pid}/stat").read_text().split()[2] == "Z"

    assert _eventually(lambda: all(gone(int(w)) for w in workers), 20)
    assert _eventually(lambda: not Path("/dev/shm", name).exists(), 20)


def test_a_multiprocessing_child_that_started_workers_ends(tmp_path):
    """The server's job runner is a multiprocessing child: it ends without atexit, joining its
    children first, and the workers must be stopped before that join (or it waits for good)."""
    script = tmp_path / "runner.py"
    script.write_text(
        textwrap.dedent(
            """
            import multiprocessing, time
            def child():
                from omninav import extract_pool
                extract_pool.shared(2)
            if __name__ == "__main__":
                p = multiprocessing.get_context("spawn").Process(target=child)
                t = time.monotonic()
                p.start()
                p.join(60)
                print(p.exitcode, time.monotonic() - t)
                if p.exitcode is None:
                    p.kill()
            """
        )
    )
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(sys.path)}
    out = subprocess.run([sys.executable, str(script)], capture_output=True, text=True, env=env, timeout=120)
    code, _took = out.stdout.split()
    assert code == "0", out  # None: still joining its workers after a minute


def test_blocks_no_owner_holds_are_swept(tmp_path):
    """What a process group killed at once leaves behind: a block nobody holds goes; a held one,
    one just made (its owner locks it next), and other files stay."""
    old_t = time.time() - 2 * extract_pool.STALE_S
    files = ["omninav_00ff00ff00ff00ff", "omninav_11ee11ee11ee11ee", "omninav_22dd22dd22dd22dd", "psm_1234"]
    for f in files:
        (tmp_path / f).write_bytes(b"x")
        os.utime(tmp_path / f, (old_t, old_t))
    os.utime(tmp_path / files[2])  # just made
    held = extract_pool._hold(files[1], str(tmp_path))
    try:
        assert extract_pool.sweep(str(tmp_path)) == [files[0]]
        assert sorted(p.name for p in tmp_path.iterdir()) == sorted(files[1:])
    finally:
        os.close(held)
    assert extract_pool.sweep(str(tmp_path)) == [files[1]]  # its owner ended


def test_room_asks_for_twice_the_block_the_shared_memory_would_hold(monkeypatch, own_shared):
    monkeypatch.setattr(os, "statvfs", lambda _: os.statvfs_result((4096, 4096, 0, 0, 10_000, 0, 0, 0, 0, 255)))
    assert extract_pool.room(20_000_000)  # 41 MB free: twice the block
    assert not extract_pool.room(21_000_000)
    shape = (2000, 2000, 3)  # a block of 12 MB a frame: no room
    assert not extract_pool.fits(2, shape)
    own_shared[2] = pool = extract_pool.ExtractPool(2, slots=1)
    pool._slots(shape).takers -= 1  # the pool has a block for these frames already: it fits
    assert extract_pool.fits(2, shape)


def test_modelling_on_processes_is_modelling_on_threads(small_ds, tmp_path, monkeypatch):
    """The same walk modelled with its frames on processes and on threads: the same generation."""
    src = VideoSource(
        small_ds.model_video, load_walk_path(small_ds.model_walk_path), load_lens(small_ds.root / "model_lens.json")
    )
    monkeypatch.setattr(model_venue, "extract_threads", lambda: 2)
    calls = []
    shared = extract_pool.shared
    monkeypatch.setattr(extract_pool, "shared", lambda n: calls.append(n) or shared(n))
    got = {}
    for name, start in (("processes", 0), ("threads", 10**9)):
        monkeypatch.setattr(model_venue, "PROCESSES_FROM", start)
        st = Store(tmp_path / name)
        model_videos(st, "lab", [src], settings=resolve("default"))
        got[name] = st.load("lab", mmap=False)
    assert calls == [2]  # the first on processes, the second on threads
    assert len(got["processes"].frames) > 50
    assert np.array_equal(got["processes"].frames, got["threads"].frames)
    assert np.array_equal(got["processes"].spectra, got["threads"].spectra)
