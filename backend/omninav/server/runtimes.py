"""Each worker's loaded venues (`Runtimes`): a venue's Locator, floors and places as one
worker answers for it, reloaded when the catalogue's revision or the live generation changes,
and its walk graph and tracker built once per generation and revision (in the background with
WARM_VENUES). The app keeps one `Runtimes` (server/__init__.py); the blueprints read it.
"""

from __future__ import annotations

import logging
import threading
import time
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from ..catalog import Catalog
from ..errors import Conflict, NotFound
from ..locate import Locator, frame_floors
from ..tracking import Tracker
from ..walkgraph import WalkGraph, attach, from_frames

log = logging.getLogger("omninav.server")


@dataclass(frozen=True)
class Walk:
    """A venue's walkable space as a worker tracks and guides on it."""

    graph: WalkGraph
    tracker: Tracker
    nodes: dict[str, int]  # place id -> its node, for the places on the graph (the destinations)


@dataclass
class Runtime:
    """One venue as a worker answers for it."""

    locator: Locator
    revision: int
    generation: str | None
    floors: dict[str, dict[str, Any]]
    places: dict[str, list[dict[str, Any]]]  # by floor
    video_floor: list[str]  # floor of each modelling video, by its index in the generation
    checked: float = field(default_factory=time.monotonic)
    _walk: Walk | None = field(default=None, repr=False)
    _walk_lock: threading.Lock = field(default_factory=threading.Lock, repr=False)

    def walk(self) -> Walk:
        """The walk graph of this generation and revision (its places join floors), and its
        tracker: built once, by a warm-up thread (WARM_VENUES) or else by the first request
        that tracks or guides; whoever comes meanwhile waits for that build."""
        if self._walk is None:
            with self._walk_lock:
                if self._walk is None:
                    loc = self.locator  # shared with the runtime of the last revision: not changed here
                    places = [p for ps in self.places.values() for p in ps]
                    graph = from_frames(loc.gen.frames, self.video_floor, places)
                    floor = frame_floors(loc.gen.frames, self.video_floor)
                    # (the search, kept on the Locator, is shared with the runtimes of later revisions)
                    self._walk = Walk(graph, loc.new_tracker(graph, floor), attach(graph, places))
        return self._walk

    def destinations(self, key: str) -> list[dict[str, Any]]:
        """The places on the walk graph that `key` names: the one of that id, else those of that
        exact name (a lift's name on each floor it serves)."""
        nodes = self.walk().nodes
        every = [p for ps in self.places.values() for p in ps if p["id"] in nodes]
        return [p for p in every if p["id"] == key] or [p for p in every if p["name"] == key]


class Runtimes:
    def __init__(self, catalog: Catalog, cache_s: float, device: str | None, warm: bool = False):
        self.cat = catalog
        self.cache_s = cache_s
        self.device = device
        # build each loaded venue's walk in the background (WARM_VENUES): its look-alike search
        # costs seconds of CPU on a big venue, which the first person tracked would otherwise wait
        # for. One thread a worker, fed venue ids: edits in a row queue builds, never pile up
        # threads, and a build is always of the venue's current runtime (a replaced one is skipped)
        self.warm = warm
        self.warmer: threading.Thread | None = None  # the latest warm-up thread
        self._warm_q: deque[str | None] = deque()  # venue ids; None: every modelled venue
        self._warm_lock = threading.Lock()
        self._warming = False
        self._rt: dict[str, Runtime] = {}
        self._lock = threading.Lock()

    def get(self, venue_id: str) -> Runtime:
        rt, loaded = self._get(venue_id)
        if loaded and self.warm:
            self._queue_warm(venue_id)
        return rt

    def warm_all(self) -> None:
        """Load every venue that has modelled frames and build its walk, in the background (at
        app start: the first request after a restart finds them ready)."""
        self._queue_warm(None)

    def warm_idle(self, timeout: float) -> bool:
        """Wait (up to `timeout` s) until no warm-up is queued or running: True if none is."""
        end = time.monotonic() + timeout
        while True:
            with self._warm_lock:
                if not self._warming:
                    return True
                t = self.warmer
            if t is None or time.monotonic() >= end:
                return False
            t.join(max(0.0, end - time.monotonic()))

    def _queue_warm(self, item: str | None) -> None:
        with self._warm_lock:
            self._warm_q.append(item)
            if not self._warming:  # the thread takes the lock to look for work, so none is lost
                self._warming = True
                self.warmer = _start_thread("omninav-warm", self._warm_loop)

    def _warm_loop(self) -> None:
        try:
            while True:
                with self._warm_lock:
                    if not self._warm_q:
                        self._warming = False
                        return
                    item = self._warm_q.popleft()
                for venue_id in self._to_warm(item):
                    self._warm_one(venue_id)
        except BaseException:  # (each venue's errors are caught below) a later load starts a new thread
            with self._warm_lock:
                self._warming = False
            raise

    def _to_warm(self, item: str | None) -> list[str]:
        if item is not None:
            return [item]
        try:
            return [v["id"] for v in self.cat.venues.all()]
        except Exception:  # e.g. the database unreachable: each request then loads its venue itself
            log.exception("warming venues: listing them")
            return []

    def _warm_one(self, venue_id: str) -> None:
        """The venue's current runtime (loaded if need be), its walk and, where it verifies, its
        places for verification. A failure is only logged: the request that needs the walk then
        builds it itself and answers with its own error."""
        try:
            rt, _ = self._get(venue_id)  # not get(): it would queue this venue again
            rt.walk()
            if rt.locator.verifies:  # its places for verification, and the RANSAC's compiled loops
                rt.locator.verification_places()
        except (Conflict, NotFound):  # no modelled frames yet, or deleted meanwhile
            pass
        except Exception:  # the venue's own requests will report it; the others still warm
            log.exception("warming venue %r: its runtime, walk graph, tracker and places for verification", venue_id)

    def _get(self, venue_id: str) -> tuple[Runtime, bool]:
        """The venue's runtime, and whether this call loaded it."""
        rt = self._rt.get(venue_id)
        now = time.monotonic()
        if rt is not None and now - rt.checked < self.cache_s:
            return rt, False
        v = self.cat.venues.get(venue_id)  # 404 for an unknown venue
        gen = self.cat.store.generation(venue_id)
        if gen is None:
            raise Conflict(f"venue {venue_id!r} has no modelled frames yet; upload a video and model it first")
        if rt is not None and rt.revision == v["revision"] and rt.generation == gen:
            rt.checked = now
            return rt, False
        with self._lock:  # one load per venue, however many requests wait for it
            rt = self._rt.get(venue_id)
            if rt is not None and rt.revision == v["revision"] and rt.generation == gen:
                return rt, False  # another thread loaded it while this one waited
            rt = self._load(venue_id, v["revision"], gen, rt)
            self._rt[venue_id] = rt
        return rt, True

    def _load(self, venue_id: str, revision: int, gen: str, old: Runtime | None) -> Runtime:
        if old is not None and old.generation == gen:
            loc = old.locator  # only the catalogue changed: keep the loaded index
        else:
            loc = Locator(self.cat.store, venue_id, device=self.device)  # Conflict if no frames
        floors = {f["id"]: f for f in self.cat.floors.all(venue_id)}
        places: dict[str, list[dict[str, Any]]] = {}
        for p in self.cat.places.all(venue_id):
            places.setdefault(p["floor"], []).append(p)
        video_floor = self.cat.videos.floor_list(venue_id, loc.gen.videos, list(floors))
        return Runtime(loc, revision, loc.generation, floors, places, video_floor)


def _start_thread(name: str, target: Callable[..., None], *args: Any) -> threading.Thread:
    # a daemon: a warm-up still running must not keep a stopping server (or a test run) alive
    t = threading.Thread(target=target, args=args, name=name, daemon=True)
    t.start()
    return t
