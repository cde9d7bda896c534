"""Extraction on worker processes: a modelling walk's frames, decoded here, extracted there.

Two extraction threads in one process extract little faster than one (docs/decisions.md,
"Modelling's threads"): levelling and the curves allocate NumPy temporaries of up to half a
megabyte, glibc maps and unmaps them, and the threads wait on each other's page faults. Processes
share no allocator, so a long video's frames are extracted on `workers` processes: each decoded
frame is copied into a slot of one shared memory block (`multiprocessing.shared_memory`), a worker
reads it there (a 960x720 frame is 2 MB: no pickle through a pipe), and its spectrum (1.8 KB) comes
back as a future. The worker runs the same `Extractor` on the same bytes, so the spectra are the
bits this process would make (tests/test_extract_pool.py).

The workers are forks of a fork server, a fresh interpreter that has imported the extractor: never
forks of this process, whose other threads (the decoder, a job's heartbeat) may hold locks. Each runs
one BLAS and one OpenCV thread (the processes are the parallelism), ignores Ctrl-C (the parent
stops them), and inherits the parent's niceness (a job runner's modelling stays behind the answers).

`shared(workers)` is the process's pool, started once and kept: the fork server and its workers
take ~0.2 s to start, which a job runner pays once at its start, not per job (`warm`). As in every program that
uses multiprocessing, a script that models a long walk keeps its work under
`if __name__ == "__main__":`: each worker imports the script's main module.
"""

from __future__ import annotations

import atexit
import multiprocessing
import signal
import threading
from collections.abc import Callable
from concurrent.futures import Future, ProcessPoolExecutor
from concurrent.futures.process import BrokenProcessPool
from multiprocessing import shared_memory
from typing import Any

import numpy as np

from .lens import Lens


class _Slots:
    """`count` frames of `nbytes` in one shared memory block, each lent to one task at a time."""

    def __init__(self, nbytes: int, count: int):
        self.nbytes = nbytes
        self.shm = shared_memory.SharedMemory(create=True, size=nbytes * count)
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

    def close(self) -> None:
        self.shm.close()
        self.shm.unlink()


class ExtractPool:
    """`workers` processes that extract frames handed over through shared memory.

    `extract(settings)` is a ClipLens `extract` (calib/correct.py): for a lens, the function that
    submits a (H, W, 3) uint8 frame and returns its spectrum's future. At most `slots` frames of one
    size are out at a time; a caller that submits more waits for one to come back."""

    def __init__(self, workers: int, slots: int = 10):
        ctx = multiprocessing.get_context(
            "forkserver" if "forkserver" in multiprocessing.get_all_start_methods() else "spawn"
        )
        if ctx.get_start_method() == "forkserver":
            ctx.set_forkserver_preload([__name__, "omninav.extract"])
        self.workers = workers
        self.slots = slots
        self._ex = ProcessPoolExecutor(workers, mp_context=ctx, initializer=_start_worker)
        self._by_size: dict[tuple[int, ...], _Slots] = {}
        self._lock = threading.Lock()

    @property
    def broken(self) -> bool:
        return bool(getattr(self._ex, "_broken", False))

    def warm(self) -> None:
        """Start every worker now (each imports nothing more: the fork server has)."""
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
        slot = slots.take()
        try:
            np.copyto(slots.view(slot, frame.shape), frame)
            fut = self._ex.submit(_spectrum, slots.shm.name, slot * slots.nbytes, frame.shape, settings, lens)
        except BaseException:
            slots.give(slot)
            raise
        fut.add_done_callback(lambda _: slots.give(slot))  # run, failed or cancelled: the slot is free
        return fut

    def _slots(self, shape: tuple[int, ...]) -> _Slots:
        with self._lock:
            s = self._by_size.get(shape)
            if s is None:
                s = self._by_size[shape] = _Slots(int(np.prod(shape)), self.slots)
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


@atexit.register
def _close_shared() -> None:
    """At exit (concurrent.futures has stopped the workers by then): the shared memory freed."""
    with _SHARED_LOCK:
        for pool in _SHARED.values():
            pool.close()
        _SHARED.clear()


# the worker's side: what it attached and built, kept between tasks

_ATTACHED: dict[str, shared_memory.SharedMemory] = {}
_EXTRACTORS: dict[str, Any] = {}


def _start_worker() -> None:
    import cv2
    from threadpoolctl import threadpool_limits  # type: ignore[import-untyped]

    signal.signal(signal.SIGINT, signal.SIG_IGN)
    cv2.setNumThreads(1)
    threadpool_limits(1)


def _ready() -> bool:
    return True


def _spectrum(name: str, offset: int, shape: tuple[int, ...], settings: dict[str, Any], lens: Lens) -> np.ndarray:
    from .extract import Extractors

    shm = _ATTACHED.get(name)
    if shm is None:
        shm = _ATTACHED[name] = shared_memory.SharedMemory(name=name)
    key = repr(sorted(settings.items()))
    ex = _EXTRACTORS.get(key)
    if ex is None:
        if len(_EXTRACTORS) >= 4:  # a long-lived job runner's workers see a venue's settings at a time
            _EXTRACTORS.clear()
        ex = _EXTRACTORS[key] = Extractors(settings, size=2)
    frame = np.ndarray(shape, np.uint8, buffer=shm.buf, offset=offset)
    return ex.get(lens).spectrum(frame)
