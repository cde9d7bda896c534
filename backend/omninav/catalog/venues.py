"""Venues: id, name, feature preset, and the revision every edit of the venue bumps.

The revision is how each server worker notices that its cached copy of a venue is stale, so every
write to a venue's floors, places, lenses or videos calls `bump` in its own transaction: the one
way to bump it.
"""

from __future__ import annotations

import time
from typing import TYPE_CHECKING, Any

from sqlalchemy import Connection, text

from ..errors import Conflict, NotFound, OmninavError
from ..presets import PRESETS, resolve
from ..store import check_id

if TYPE_CHECKING:
    from . import Catalog

DEFAULT_FLOOR = "1"


def bump(c: Connection, venue_id: str) -> None:
    """Mark the venue edited, in the caller's transaction."""
    c.execute(text("UPDATE venues SET revision = revision + 1 WHERE id = :id"), {"id": venue_id})


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
        """Bump the revision on its own (the venue's frames changed: a job committed)."""
        with self.db.tx() as c:
            bump(c, venue_id)

    def settings(self, venue_id: str) -> dict[str, Any]:
        """The venue's feature settings: its live generation's, else its preset's (a venue
        always answers with the settings it was modelled with)."""
        row = self.get(venue_id)
        return self.cat.store.settings(venue_id) or resolve(row["preset"])
