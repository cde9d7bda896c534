"""Admission of heavy work in one process: at most so many at once, a few more waiting briefly,
the rest refused with `Busy` (the server's 503 with Retry-After) rather than queued.

The frame previews of the admin page (preview.py) go through one: each decodes a whole video
frame, and a worker process's memory is what they would otherwise multiply.
"""

from __future__ import annotations

import os
import threading
from collections.abc import Callable, Iterator
from concurrent.futures import ThreadPoolExecutor
from contextlib import contextmanager
from typing import TypeVar

from .errors import Busy

T = TypeVar("T")


class Gate:
    """Runs work on its own `slots` threads, at most `slots` pieces at once. While they are all
    at work, at most `waiting` more wait for a place, each at most `wait_s`; any other is refused
    at once with Busy, which says to ask again after `retry_after_s`.

    Notes
    -----
    The wait is short and for few because a waiting request holds a thread of its gthread worker
    (THREADS, 4 by default), and the threads left free are what keep the rest of the server
    (/api/health, a locate) answering while the gate is full. A queue without bound would hold
    every thread, and do work for requests whose page has moved on.

    The work runs on the gate's threads, not the request's, because of how glibc's malloc keeps
    memory: each thread allocates from an arena of its own, and an arena keeps the free memory at
    its top up to twice the largest block freed lately (tens of MB after a video frame), which
    `malloc_trim` does not reach in a thread's arena. Made on the request threads, a burst of
    heavy work would leave that much in every thread's arena; on the gate's threads it stays in
    `slots` arenas, where the next piece of work reuses it.
    """

    def __init__(self, slots: int, waiting: int, wait_s: float, retry_after_s: float):
        self.slots, self.waiting, self.wait_s, self.retry_after_s = slots, waiting, wait_s, retry_after_s
        self.busy = 0  # at work
        self.queued = 0  # waiting for a place
        self._cond = threading.Condition()
        self._pool: tuple[int, ThreadPoolExecutor] | None = None  # (the process they belong to, the threads)

    def run(self, what: str, work: Callable[[], T]) -> T:
        """work() on one of the gate's threads once admitted; Busy (naming `what`) if not."""
        with self.admit(what):
            return self._threads().submit(work).result()

    @contextmanager
    def admit(self, what: str) -> Iterator[None]:
        """Hold a place while the block runs, or raise Busy."""
        with self._cond:
            if self.busy >= self.slots:
                if self.queued >= self.waiting:
                    raise self._busy(what)
                self.queued += 1
                try:
                    if not self._cond.wait_for(lambda: self.busy < self.slots, timeout=self.wait_s):
                        raise self._busy(what)
                finally:
                    self.queued -= 1
            self.busy += 1
        try:
            yield
        finally:
            with self._cond:
                self.busy -= 1
                self._cond.notify()

    def _busy(self, what: str) -> Busy:
        return Busy(
            f"the server is busy making {what}s (at most {self.slots} at once): ask again in a moment",
            retry_after_s=self.retry_after_s,
        )

    def _threads(self) -> ThreadPoolExecutor:
        with self._cond:
            if self._pool is None or self._pool[0] != os.getpid():  # a forked child has none of its parent's threads
                self._pool = (os.getpid(), ThreadPoolExecutor(self.slots, thread_name_prefix="omninav-gate"))
            return self._pool[1]
