"""Venues: id, name, feature preset, and the revision every edit of the venue bumps.

The revision is how each server worker notices that its cached copy of a venue is stale, so every
write to a venue's floors, places, lenses or videos calls `bump` in its own transaction: the one
way to bump it.

It is also how a writer says which venue it edited (optimistic concurrency: the admin page's
If-Match). A writer that names the revision it read (`expecting`) has its first bump made
conditional on it, in the same transaction as its change: of two writers that read revision 5,
one bumps 5 to 6 and commits, the other finds 6, and its transaction (its change with it) is
rolled back as Stale. So a check-then-write race cannot let both through.
"""

from __future__ import annotations

import contextvars
import shutil
import time
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from sqlalchemy import Connection, text

from ..errors import Conflict, NotFound, OmninavError, Stale
from ..presets import PRESETS, resolve
from ..store import check_id

if TYPE_CHECKING:
    from . import Catalog

DEFAULT_FLOOR = "1"
RESULTS = "results"  # DATA/results/<venue>/: what analysis jobs found (server/jobs.py)
DELETE_WAIT_S = 10.0  # how long deleting a venue waits for its running jobs to stop


@dataclass
class WriteCheck:
    """One writer's view of one venue: the revision it read (None: it did not say) and the
    revision its last bump made (the ETag of its answer)."""

    venue: str
    expected: int | None
    checked: bool = False
    revision: int | None = None


_write: contextvars.ContextVar[WriteCheck | None] = contextvars.ContextVar("omninav_write", default=None)


@contextmanager
def expecting(venue_id: str, revision: int | None) -> Iterator[WriteCheck]:
    """Within the block, the first bump of `venue_id` succeeds only if the venue is still at
    `revision` (None: any revision); the WriteCheck says the revision the block's writes made."""
    w = WriteCheck(venue_id, revision)
    token = _write.set(w)
    try:
        yield w
    finally:
        _write.reset(token)


def begin_write(venue_id: str, revision: int | None) -> tuple[WriteCheck, contextvars.Token[WriteCheck | None]]:
    """`expecting` for a caller that cannot hold a block open (a request's before and teardown
    hooks): end it with end_write(token)."""
    w = WriteCheck(venue_id, revision)
    return w, _write.set(w)


def end_write(token: contextvars.Token[WriteCheck | None]) -> None:
    _write.reset(token)


def stale_message(have: int, had: int) -> str:
    return f"the venue changed since you opened it (revision {have} now, you had {had}); reload it"


def bump(c: Connection, venue_id: str) -> None:
    """Mark the venue edited, in the caller's transaction; the first bump of a writer that named
    the revision it read (`expecting`) raises Stale, rolling the transaction back, if the venue
    moved on since."""
    w = _write.get()
    mine = w is not None and w.venue == venue_id
    if w is not None and mine and w.expected is not None and not w.checked:
        got = c.execute(
            text("UPDATE venues SET revision = revision + 1 WHERE id = :id AND revision = :e"),
            {"id": venue_id, "e": w.expected},
        ).rowcount
        if not got:
            row = c.execute(text("SELECT revision FROM venues WHERE id = :id"), {"id": venue_id}).first()
            if row is not None:
                have = int(row[0])  # the client's next If-Match: `revision` (as `received` for uploads)
                raise Stale(stale_message(have, w.expected), revision=have, details={"revision": have})
        w.checked = True
    else:
        c.execute(text("UPDATE venues SET revision = revision + 1 WHERE id = :id"), {"id": venue_id})
    if w is not None and mine:
        row = c.execute(text("SELECT revision FROM venues WHERE id = :id"), {"id": venue_id}).first()
        w.revision = int(row[0]) if row is not None else None


def check_name(name: Any, what: str = "venue") -> str:
    if not isinstance(name, str) or not name.strip() or len(name) > 200:
        raise OmninavError(f"{what} name must be a non-empty string of at most 200 characters")
    return name.strip()


class Venues:
    def __init__(self, cat: Catalog):
        self.cat = cat
        self.db = cat.db

    def get(self, venue_id: str) -> dict[str, Any]:
        row = self.db.one("SELECT * FROM venues WHERE id = :id", id=check_id(venue_id))
        if row is None:
            raise NotFound(f"unknown venue {venue_id!r}")
        return row

    def exists(self, venue_id: str) -> bool:
        return self.db.one("SELECT id FROM venues WHERE id = :id", id=check_id(venue_id)) is not None

    def all(self) -> list[dict[str, Any]]:
        return self.db.all("SELECT * FROM venues ORDER BY id")

    def create(
        self,
        venue_id: str,
        name: str | None = None,
        preset: str = "default",
        floor: str = DEFAULT_FLOOR,
        floor_name: str | None = None,
        px_per_m: float | None = None,
    ) -> dict[str, Any]:
        """A new venue with its first floor, in one transaction. Nothing is written on disk: the
        store makes the venue's folder when its first frames are committed."""
        from .floors import check_floor_id, check_scale, insert_floor

        check_id(venue_id)
        name = check_name(name if name is not None else venue_id)
        if preset not in PRESETS:
            raise OmninavError(f"unknown preset {preset!r} (use one of {', '.join(PRESETS)})")
        check_floor_id(floor)
        if px_per_m is not None:
            check_scale(px_per_m)
        if self.exists(venue_id):
            raise Conflict(f"venue {venue_id!r} already exists")
        with self.db.tx() as c:
            c.execute(
                text("INSERT INTO venues (id, name, preset, created, revision) VALUES (:id, :n, :p, :t, 1)"),
                {"id": venue_id, "n": name, "p": preset, "t": time.time()},
            )
            insert_floor(c, venue_id, floor, floor_name or f"Floor {floor}", px_per_m)
        return self.get(venue_id)

    def rename(self, venue_id: str, name: str) -> dict[str, Any]:
        self.get(venue_id)
        name = check_name(name)
        with self.db.tx() as c:
            c.execute(text("UPDATE venues SET name = :n WHERE id = :id"), {"n": name, "id": venue_id})
            bump(c, venue_id)
        return self.get(venue_id)

    def touch(self, venue_id: str) -> None:
        """Bump the revision on its own (the venue's frames changed: a job committed; or a writer
        checks the revision it read before a change that cannot wait for its transaction)."""
        with self.db.tx() as c:
            bump(c, venue_id)

    def modelled(self, venue_id: str) -> tuple[int | None, float | None]:
        """The live generation's number and when it was made live (None, None: never modelled)."""
        gen = self.cat.store.generation(venue_id)
        if gen is None:
            return None, None
        try:
            number = int(gen.split("-")[1])
            at = (self.cat.store.venue_dir(venue_id) / "CURRENT").stat().st_mtime
        except (ValueError, IndexError, OSError):
            return None, None
        return number, at

    def delete(self, venue_id: str, wait_s: float = DELETE_WAIT_S) -> dict[str, Any]:
        """Delete a venue and everything of it: its jobs (cancelled first), rows, modelled
        frames, plans, videos and job results. Returns {"deleted", "frames_removed",
        "videos_removed"}.

        The first transaction checks the writer's revision (`expecting`) and cancels the jobs;
        running jobs stop at their next frame, and are waited for (up to wait_s) so that none
        commits frames after the folder went. A job that commits later all the same finds its row
        gone and commits nothing (jobs.py checks ownership under the venue's lock)."""
        self.get(venue_id)
        now = time.time()
        with self.db.tx() as c:
            bump(c, venue_id)
            c.execute(
                text(
                    "UPDATE jobs SET state = 'cancelled', finished = :t, cancel = 1 "
                    "WHERE venue = :v AND state = 'queued'"
                ),
                {"v": venue_id, "t": now},
            )
            c.execute(text("UPDATE jobs SET cancel = 1 WHERE venue = :v AND state = 'running'"), {"v": venue_id})
        deadline = time.monotonic() + wait_s
        while self.db.one("SELECT id FROM jobs WHERE venue = :v AND state = 'running'", v=venue_id):
            if time.monotonic() > deadline:
                break  # a runner that died: its job goes with the venue's rows
            time.sleep(0.1)
        frames = self.cat.store.frame_count(venue_id)
        videos = int((self.db.one("SELECT COUNT(*) AS n FROM videos WHERE venue = :v", v=venue_id) or {"n": 0})["n"])
        with self.db.tx() as c:
            c.execute(text("DELETE FROM job_videos WHERE venue = :v"), {"v": venue_id})
            c.execute(text("DELETE FROM jobs WHERE venue = :v"), {"v": venue_id})
            for table in ("places", "lenses", "videos", "floors"):
                c.execute(text(f"DELETE FROM {table} WHERE venue = :v"), {"v": venue_id})
            c.execute(text("DELETE FROM venues WHERE id = :v"), {"v": venue_id})
        data = self.cat.data
        with self.cat.store.lock(venue_id):  # a commit in progress ends before its folder goes
            shutil.rmtree(self.cat.store.venue_dir(venue_id), ignore_errors=True)
        for tree in ("plans", "videos", RESULTS):
            shutil.rmtree(data / tree / venue_id, ignore_errors=True)
        return {"deleted": venue_id, "frames_removed": frames, "videos_removed": videos}

    def settings(self, venue_id: str) -> dict[str, Any]:
        """The venue's feature settings: its live generation's, else its preset's (a venue
        always answers with the settings it was modelled with)."""
        row = self.get(venue_id)
        return self.cat.store.settings(venue_id) or resolve(row["preset"])

    def preset_settings(self, venue_id: str) -> dict[str, Any]:
        """The venue's preset as this omninav defines it now: what a new venue gets, and what a
        modelling anew gives a venue modelled before the preset improved."""
        return resolve(self.get(venue_id)["preset"])
