"""Tracking sessions: what the filter and the route guide remember of one phone's walk.

A phone that tracks sends an opaque session id it made (random per walk) with each locate; the
server keeps, per venue and id, the filter's state (tracking_state.TrackState.to_bytes: a few KB), the
route guide's state (a small JSON dict, route.guide) and the live generation they were made on.
They live in the catalogue database, not in a worker's memory, so the next request continues the
walk whichever worker answers it, and after a restart; nothing else is kept (no address, no
device: the id is the phone's own random number).

A session ends `TRACK_SESSION_S` (config.py) after its last request; expired rows are deleted now
and then by whichever request writes one (at most once every PURGE_EVERY_S per process), so no
sweeper process is needed. Writes are upserts: two requests of one session at once both succeed,
the last write wins.

The state is stored as bytes: BLOB on SQLite, BYTEA on PostgreSQL (the migration picks the type by
dialect; both drivers take and give Python bytes), not base64 text, which would cost a third more
on every request of every walk for nothing.
"""

from __future__ import annotations

import json
import re
import threading
import time
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from sqlalchemy.exc import IntegrityError

from ..errors import OmninavError

if TYPE_CHECKING:
    from . import Catalog

SESSION_ID = re.compile(r"[A-Za-z0-9_-]{8,64}")  # what the app makes: a UUID's hex, or base64url
PURGE_EVERY_S = 60.0  # expired rows are deleted at most this often per process


def check_session_id(s: str) -> str:
    if not SESSION_ID.fullmatch(s):
        raise OmninavError(
            f"session {s[:80]!r} is not a session id: 8 to 64 letters, digits, '-' or '_' (make one per walk)"
        )
    return s


@dataclass(frozen=True)
class Session:
    id: str
    venue: str
    generation: str
    state: bytes
    guide: dict[str, Any] | None
    updated: float  # server time (Unix seconds) of the last write
    expires: float  # server time after which it is expired

    def expired(self, now: float) -> bool:
        return now >= self.expires


class Sessions:
    def __init__(self, cat: Catalog):
        self.db = cat.db
        self._purged = -float("inf")
        self._lock = threading.Lock()

    def get(self, venue_id: str, session_id: str) -> Session | None:
        """The session as last written, expired or not (the caller says which), or None."""
        row = self.db.one(
            "SELECT id, venue, generation, state, guide, updated, expires FROM tracking_sessions "
            "WHERE venue = :v AND id = :s",
            v=venue_id,
            s=session_id,
        )
        if row is None:
            return None
        guide = json.loads(row["guide"]) if row["guide"] else None
        return Session(
            row["id"],
            row["venue"],
            row["generation"],
            bytes(row["state"]),  # psycopg: bytes; other drivers may give a memoryview
            guide if isinstance(guide, dict) else None,
            float(row["updated"]),
            float(row["expires"]),
        )

    def put(
        self,
        venue_id: str,
        session_id: str,
        generation: str,
        state: bytes,
        guide: dict[str, Any] | None,
        life_s: float,
        now: float | None = None,
    ) -> None:
        """Write a session (insert or replace: the last write wins); it expires life_s from now."""
        now = time.time() if now is None else now
        try:
            self._upsert(venue_id, session_id, generation, state, guide, now, now + life_s)
        except IntegrityError:  # the venue was deleted while this request was answered: nothing to keep
            return
        self.purge(now)

    def _upsert(
        self, venue_id: str, session_id: str, generation: str, state: bytes, guide: Any, now: float, exp: float
    ) -> None:
        self.db.run(
            "INSERT INTO tracking_sessions (id, venue, generation, state, guide, updated, expires) "
            "VALUES (:s, :v, :g, :state, :guide, :now, :exp) "
            "ON CONFLICT (venue, id) DO UPDATE SET generation = excluded.generation, state = excluded.state, "
            "guide = excluded.guide, updated = excluded.updated, expires = excluded.expires",
            s=session_id,
            v=venue_id,
            g=generation,
            state=state,
            guide=json.dumps(guide, separators=(",", ":")) if guide is not None else None,
            now=now,
            exp=exp,
        )

    def purge(self, now: float | None = None, force: bool = False) -> int:
        """Delete the expired sessions (every venue's), at most once every PURGE_EVERY_S unless
        forced; returns how many went."""
        now = time.time() if now is None else now
        with self._lock:
            if not force and now - self._purged < PURGE_EVERY_S:
                return 0
            self._purged = now
        return self.db.run("DELETE FROM tracking_sessions WHERE expires <= :now", now=now)
