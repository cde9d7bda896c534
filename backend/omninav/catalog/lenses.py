"""Lens profiles of a venue, by name (the lens.json format: docs/formats.md).

A profile sent inline with a video, or given to `omninav model` as a file, is named by its content
(`lens-<hash>`): the same profile is one lens, and no video or file name leaks into the public
venue document, which lists the lens names.
"""

from __future__ import annotations

import hashlib
import json
from typing import TYPE_CHECKING, Any

from sqlalchemy import text

from ..errors import NotFound, OmninavError
from ..lens import Lens, lens_from_dict
from ..store import check_id
from .venues import bump

if TYPE_CHECKING:
    from . import Catalog

DEFAULT_LENS = "default"


def inline_lens_name(profile: dict[str, Any]) -> str:
    """The name of a profile that came without one: from its content, never its video."""
    return "lens-" + hashlib.sha256(json.dumps(profile, sort_keys=True).encode()).hexdigest()[:12]


def check_lens_name(name: Any) -> str:
    try:
        return check_id(name)
    except OmninavError:  # check_id speaks of venue ids: say which name was wrong
        raise OmninavError(f"invalid lens name {name!r}: use 1-64 letters, digits, '-' or '_'") from None


class Lenses:
    def __init__(self, cat: Catalog):
        self.cat = cat
        self.db = cat.db

    def profiles(self, venue_id: str) -> dict[str, dict[str, Any]]:
        rows = self.db.all("SELECT name, profile FROM lenses WHERE venue = :v ORDER BY name", v=venue_id)
        return {r["name"]: json.loads(r["profile"]) for r in rows}

    def get(self, venue_id: str, name: str) -> Lens:
        row = self.db.one("SELECT profile FROM lenses WHERE venue = :v AND name = :n", v=venue_id, n=name)
        if row is None:
            raise NotFound(f"venue {venue_id!r} has no lens profile {name!r}")
        return lens_from_dict(json.loads(row["profile"]), where=f"lens {name!r}")

    def put(self, venue_id: str, name: str, profile: Any) -> dict[str, Any]:
        """Add or replace a named profile; returns it normalised."""
        self.cat.venues.get(venue_id)
        check_lens_name(name)
        doc = lens_from_dict(profile, where=f"lens {name!r}").to_dict()
        with self.db.tx() as c:
            c.execute(
                text(
                    "INSERT INTO lenses (venue, name, profile) VALUES (:v, :n, :p) "
                    "ON CONFLICT (venue, name) DO UPDATE SET profile = excluded.profile"
                ),
                {"v": venue_id, "n": name, "p": json.dumps(doc)},
            )
            bump(c, venue_id)
        return doc

    def put_inline(self, venue_id: str, profile: Any, where: str = "the video's lens") -> str:
        """Add a profile that has no name (named by its content); returns the name."""
        doc = lens_from_dict(profile, where=where).to_dict()
        name = inline_lens_name(doc)
        self.put(venue_id, name, doc)
        return name
