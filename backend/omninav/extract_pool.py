"""Extraction on worker processes: a modelling walk's frames, decoded here, extracted there.

Two extraction threads in one process extract little faster than one (docs/decisions.md,
"Modelling's threads"): levelling and the curves allocate NumPy temporaries of up to half a
megabyte, glibc maps and unmaps them, and the threads wait on each other's page faults. Processes
share no allocator, so a long video's frames are extracted on `workers` processes: each decoded
frame is copied into a slot of one shared memory block (`multiprocessing.shared_memory`), a worker
reads it there (a 960x720 frame is 2 MB: no pickle through a pipe), and its spectrum (1.8 KB) comes
back as a future. The worker runs the same `Extractor` on the same bytes, so the spectra are the
bits this process would make (tests/engine/test_extract_pool.py).

The workers are forks of a fork server, a fresh interpreter that has imported the extractor: never
forks of this process, whose other threads (the decoder, a job's heartbeat) may hold locks. Each runs
one BLAS and one OpenCV thread (the processes are the parallelism), ignores Ctrl-C (the parent
stops them), inherits the parent's niceness (a job runner's modelling stays behind the answers),
and exits when the parent does, however it ends: a job runner killed for memory leaves no workers,
and the fork server and the resource tracker, whose pipes they held, then exit and free the shared
memory too. Where all of them were killed at once, the next pool made frees the block (`sweep`);
multiprocessing's own named semaphores (32 bytes each) are left then.

The shared memory is a block of `slots` frames of one size (20 MB for 960x720), kept for the next
run: frames of a new size free the blocks none of whose frames are out. `fits` says whether frames
can come: the pool has their block, or the shared memory file system (64 MB in a default Docker
container) has room for one (`room`); else modelling stays on threads.

`shared(workers)` is the process's pool, started once and kept: the fork server and its workers
take ~0.2 s to start, which a job runner pays once at its start, not per job (`warm`). As in every
program that uses multiprocessing, a script that models a long walk keeps its work under
`if __name__ == "__main__":`: each worker imports the script's main module.
"""

from __future__ import annotations

import atexit
import contextlib
import fcntl
import multiprocessing
import multiprocessing.util
import os
import secrets
import select
import signal
import threading
import time
from collections.abc import Callable
from concurrent.futures import Future, ProcessPoolExecutor
from concurrent.futures.process import BrokenProcessPool
from multiprocessing import shared_memory
from typing import Any

import numpy as np

from .calib.correct import FIRST
from .lens import Lens


class _Slots:
    """`count` frames of `nbytes` in one shared memory block, each lent to one task at a time."""

    def __init__(self, nbytes: int, count: int):
        self.nbytes = nbytes
        self.count = count
        self.takers = 0  # callers between ExtractPool._slots and their slot (under the pool's lock)
        self.shm = shared_memory.SharedMemory(name=PREFIX + secrets.token_hex(8), create=True, size=nbytes * count)
        self._held = _hold(self.shm.name)
        self._free = list(range(count))
        self._cond = threading.Condition()

    def take(self) -> int:
        """A free slot (waits for a task to give one back: at most `count` frames are out)."""
        with self._cond:
            self._cond.wait_for(lambda: bool(self._free))
            return self._free.pop()

    def give(self, slot: int) -> None:
        with self._cond:
            self._free.append(slot)
            self._cond.notify()

    def view(self, slot: int, shape: tuple[int, ...]) -> np.ndarray:
        return np.ndarray(shape, np.uint8, buffer=self.shm.buf, offset=slot * self.nbytes)

    @property
    def idle(self) -> bool:
        """No frame of this block is out."""
        with self._cond:
            return len(self._free) == self.count

    def close(self) -> None:
        with contextlib.suppress(BufferError):  # a frame still being copied at exit: the mapping goes with the process
            self.shm.close()
        with contextlib.suppress(FileNotFoundError):
            self.shm.unlink()
        if self._held is not None:
            os.close(self._held)
            self._held = None


PREFIX = "omninav_"  # a block's name: PREFIX and 16 random hex digits (31 characters at most)
SHM = "/dev/shm"  # where Linux keeps the blocks as files
STALE_S = 60.0  # a block unheld this long after it was made is a leftover


def _hold(name: str, root: str = SHM) -> int | None:
    """A shared lock on the block's file for as long as its owner lives (the kernel drops it when
    the owner ends, however): what `sweep` asks. None where blocks are not files (not Linux)."""
    try:
        fd = os.open(os.path.join(root, name), os.O_RDONLY)
    except OSError:
        return None
    fcntl.flock(fd, fcntl.LOCK_SH)
    return fd


def sweep(root: str = SHM) -> list[str]:
    """Unlink the blocks that no owner holds any more (-> their names). An owner, its workers and
    the resource tracker all killed at once (SIGKILL to their process group) leave their block
    behind; the next pool made on the machine frees it. A live owner holds its block's lock, in
    whatever container or pid namespace it runs, so no live block is taken; one made in the last
    STALE_S seconds is left to its owner, who locks it just after making it."""
    gone = []
    with contextlib.suppress(OSError):
        for name in os.listdir(root):
            path = os.path.join(root, name)
            if not name.startswith(PREFIX):
                continue
            with contextlib.suppress(OSError):
                fd = os.open(path, os.O_RDONLY)
                try:
                    if time.time() - os.fstat(fd).st_mtime < STALE_S:
                        continue
                    fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)  # BlockingIOError (an OSError): held
                    os.unlink(path)
                    gone.append(name)
                finally:
                    os.close(fd)
    return gone


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


def fits(workers: int, shape: tuple[int, ...]) -> bool:
    """Whether frames of `shape` can go to the shared pool of `workers`: it has their block
    already, or the shared memory has room for one."""
    with _SHARED_LOCK:
        pool = _SHARED.get(workers)
        if pool is not None and shape in pool._by_size:
            return True
    return room(int(np.prod(shape)) * slots_for(workers))


def room(nbytes: int) -> bool:
    """Whether the shared memory file system has `nbytes` free, with as much again to spare (a
    block written past it would end the process with SIGBUS, not an error)."""
    try:
        st = os.statvfs(SHM)
    except OSError:
        return True  # not Linux: shared memory is not a small file system there
    return st.f_bavail * st.f_frsize >= 2 * nbytes


def slots_for(workers: int) -> int:
    """Frames out at a time: what modelling keeps in flight (two a worker, and the frames a clip's
    ring is measured on) and three more, so that a slot handed back late never stalls it."""
    return 2 * workers + FIRST + 3


class ExtractPool:
    """`workers` processes that extract frames handed over through shared memory.

    `extract(settings)` is a ClipLens `extract` (calib/correct.py): for a lens, the function that
    submits a (H, W, 3) uint8 frame and returns its spectrum's future. At most `slots` frames of one
    size are out at a time; a caller that submits more waits for one to come back."""

    def __init__(self, workers: int, slots: int | None = None):
        ctx = multiprocessing.get_context(
            "forkserver" if "forkserver" in multiprocessing.get_all_start_methods() else "spawn"
        )
        if ctx.get_start_method() == "forkserver":
            ctx.set_forkserver_preload([__name__, "omninav.extract"])
        sweep()
        self.workers = workers
        self.slots = slots or slots_for(workers)
        self._ex = ProcessPoolExecutor(workers, mp_context=ctx, initializer=_start_worker, initargs=(os.getpid(),))
        self._by_size: dict[tuple[int, ...], _Slots] = {}
        self._lock = threading.Lock()

    @property
    def broken(self) -> bool:
        return bool(getattr(self._ex, "_broken", False))

    def warm(self) -> None:
        """Start every worker now, rather than at the first frames."""
        for f in [self._ex.submit(_ready) for _ in range(self.workers)]:
            f.result()

    def extract(self, settings: dict[str, Any]) -> Callable[[Lens], Callable[[np.ndarray], Future[np.ndarray]]]:
        def for_lens(lens: Lens) -> Callable[[np.ndarray], Future[np.ndarray]]:
            return lambda frame: self.submit(settings, lens, frame)

        return for_lens

    def submit(self, settings: dict[str, Any], lens: Lens, frame: np.ndarray) -> Future[np.ndarray]:
        """One frame's spectrum, extracted by a worker with `settings` through `lens`."""
        if frame.dtype != np.uint8:
            raise ValueError(f"frames are uint8, not {frame.dtype}")
        slots = self._slots(frame.shape)
        try:
            slot = slots.take()
        finally:
            with self._lock:
                slots.takers -= 1
        try:
            np.copyto(slots.view(slot, frame.shape), frame)
            fut = self._ex.submit(_spectrum, slots.shm.name, slot * slots.nbytes, frame.shape, settings, lens)
        except BaseException:
            slots.give(slot)
            raise
        fut.add_done_callback(lambda _: slots.give(slot))  # run, failed or cancelled: the slot is free
        return fut

    def _slots(self, shape: tuple[int, ...]) -> _Slots:
        """The block for frames of `shape`, counted as taken from until the caller has its slot;
        blocks of other shapes that no frame or caller uses are freed."""
        with self._lock:
            s = self._by_size.get(shape)
            if s is None:
                for other in [k for k, b in self._by_size.items() if b.idle and not b.takers]:
                    self._by_size.pop(other).close()
                s = self._by_size[shape] = _Slots(int(np.prod(shape)), self.slots)
            s.takers += 1
            return s

    def close(self, wait: bool = True) -> None:
        """Stop the workers (what is queued is cancelled) and free the shared memory."""
        self._ex.shutdown(wait=wait, cancel_futures=True)
        with self._lock:
            for s in self._by_size.values():
                s.close()
            self._by_size.clear()


_SHARED: dict[int, ExtractPool] = {}
_SHARED_LOCK = threading.Lock()


def shared(workers: int) -> ExtractPool:
    """The process's pool of `workers` processes, started (and warmed) on the first call and closed
    at exit; one whose worker died (killed, out of memory) is replaced."""
    with _SHARED_LOCK:
        pool = _SHARED.get(workers)
        if pool is None or pool.broken:
            if pool is not None:
                pool.close(wait=False)
            pool = _SHARED[workers] = ExtractPool(workers)
            try:
                pool.warm()
            except BrokenProcessPool:
                pool.close(wait=False)
                del _SHARED[workers]
                raise
        return pool


def _close_shared() -> None:
    """At exit: the workers stopped and the shared memory freed."""
    with _SHARED_LOCK:
        for pool in _SHARED.values():
            pool.close()
        _SHARED.clear()


# Both exits: a plain program's (atexit), and a multiprocessing child's, such as the server's job
# runner, which ends without atexit or concurrent.futures' own shutdown and joins its children
# first, which would wait on the workers for good. Its finalizers of priority >= 0 run before that
# join, highest first: this one before the pool's queues close theirs (priority 10), or the
# workers' stop signal would never be sent.
atexit.register(_close_shared)
multiprocessing.util.Finalize(None, _close_shared, exitpriority=100)


# the worker's side: what it attached and built, kept between tasks

_ATTACHED: dict[str, shared_memory.SharedMemory] = {}
_EXTRACTORS: dict[str, Any] = {}


def _start_worker(owner: int) -> None:
    import cv2
    from threadpoolctl import threadpool_limits  # type: ignore[import-untyped]

    signal.signal(signal.SIGINT, signal.SIG_IGN)
    cv2.setNumThreads(1)
    threadpool_limits(1)
    threading.Thread(target=_exit_with, args=(owner,), name="omninav-owner", daemon=True).start()


def _exit_with(owner: int) -> None:
    """Wait for the process that owns the pool to end, then end this worker. A worker's parent is
    the fork server, not the owner, and the worker holds pipes that would otherwise keep it, the fork
    server and the resource tracker alive after an owner killed without its exit handlers."""
    try:
        fd = os.pidfd_open(owner)  # Linux: readable once the owner has ended
        poll = select.poll()
        poll.register(fd, select.POLLIN)
        while not poll.poll():
            pass
    except (AttributeError, OSError):  # elsewhere: look every second
        while _alive(owner):
            time.sleep(1.0)
    os._exit(0)


def _ready() -> bool:
    return True


def _spectrum(name: str, offset: int, shape: tuple[int, ...], settings: dict[str, Any], lens: Lens) -> np.ndarray:
    from .extract import Extractors

    shm = _ATTACHED.get(name)
    if shm is None:
        for old in _ATTACHED.values():  # a block the owner has freed: its memory goes when we let go
            with contextlib.suppress(BufferError):
                old.close()
        _ATTACHED.clear()
        shm = _ATTACHED[name] = shared_memory.SharedMemory(name=name)
    key = repr(sorted(settings.items()))
    ex = _EXTRACTORS.get(key)
    if ex is None:
        if len(_EXTRACTORS) >= 4:  # a long-lived job runner's workers see a venue's settings at a time
            _EXTRACTORS.clear()
        ex = _EXTRACTORS[key] = Extractors(settings, size=2)
    frame = np.ndarray(shape, np.uint8, buffer=shm.buf, offset=offset)
    return ex.get(lens).spectrum(frame)
