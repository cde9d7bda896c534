"""Places: named points on a floor, in metres, and areas ([x0, y0, x1, y1]) one can be in."""

from __future__ import annotations

import json
import uuid
from typing import TYPE_CHECKING, Any

from sqlalchemy import text

from ..errors import NotFound, OmninavError
from .floors import number
from .venues import bump

if TYPE_CHECKING:
    from . import Catalog

KINDS = ("room", "door", "lift", "stairs", "exit", "toilet", "desk", "other")  # docs/formats.md


def check_place(p: Any, i: int, floors: set[str]) -> dict[str, Any]:
    """One place as sent -> its row's fields (without id and venue), or an error naming it."""
    where = f"place {i}"
    if not isinstance(p, dict):
        raise OmninavError(f"{where} must be an object")
    name = p.get("name")
    if not isinstance(name, str) or not name.strip() or len(name) > 200:
        raise OmninavError(f"{where}: 'name' must be a non-empty string")
    floor = str(p.get("floor", min(floors) if len(floors) == 1 else "1"))
    if floor not in floors:
        raise OmninavError(f"{where} ({name}): venue has no floor {floor!r}")
    x, y = number(p.get("x"), f"{where} 'x'"), number(p.get("y"), f"{where} 'y'")
    area = p.get("area")
    if area is not None:
        if not isinstance(area, list) or len(area) != 4:
            raise OmninavError(f"{where}: 'area' must be [x0, y0, x1, y1] in metres")
        area = [number(v, f"{where} 'area'") for v in area]
        if area[2] <= area[0] or area[3] <= area[1]:
            raise OmninavError(f"{where}: 'area' needs x0 < x1 and y0 < y1")
    kind = p.get("kind")
    if kind is not None and kind not in KINDS:
        raise OmninavError(f"{where} ({name}): 'kind' must be one of {', '.join(KINDS)}")
    say = p.get("say")
    if say is not None and (not isinstance(say, str) or len(say) > 500):
        raise OmninavError(f"{where} ({name}): 'say' must be a sentence of at most 500 characters")
    return {
        "floor": floor,
        "name": name.strip(),
        "x": x,
        "y": y,
        "area": json.dumps(area) if area else None,
        "kind": kind,
        "say": say.strip() or None if say else None,
    }


class Places:
    def __init__(self, cat: Catalog):
        self.cat = cat
        self.db = cat.db

    def all(self, venue_id: str) -> list[dict[str, Any]]:
        out = []
        for r in self.db.all("SELECT * FROM places WHERE venue = :v ORDER BY floor, name, id", v=venue_id):
            p = {"id": r["id"], "floor": r["floor"], "name": r["name"], "x": r["x"], "y": r["y"]}
            if r["area"]:
                p["area"] = json.loads(r["area"])
            for k in ("kind", "say"):
                if r[k]:
                    p[k] = r[k]
            out.append(p)
        return out

    def add(self, venue_id: str, items: Any, replace: bool = False) -> list[dict[str, Any]]:
        """Add places (or replace them all); every one is checked before any is written."""
        self.cat.venues.get(venue_id)
        if not isinstance(items, list):
            raise OmninavError("places must be a JSON list of {name, floor, x, y[, area, kind, say]}")
        floors = {f["id"] for f in self.cat.floors.all(venue_id)}
        rows = [
            {**check_place(p, i, floors), "id": uuid.uuid4().hex[:12], "venue": venue_id} for i, p in enumerate(items)
        ]
        with self.db.tx() as c:
            if replace:
                c.execute(text("DELETE FROM places WHERE venue = :v"), {"v": venue_id})
            for r in rows:
                c.execute(
                    text(
                        "INSERT INTO places (id, venue, floor, name, x, y, area, kind, say) "
                        "VALUES (:id, :venue, :floor, :name, :x, :y, :area, :kind, :say)"
                    ),
                    r,
                )
            bump(c, venue_id)
        return self.all(venue_id)

    def delete(self, venue_id: str, place_id: str) -> None:
        self.cat.venues.get(venue_id)
        with self.db.tx() as c:
            gone = c.execute(text("DELETE FROM places WHERE venue = :v AND id = :p"), {"v": venue_id, "p": place_id})
            if not gone.rowcount:
                raise NotFound(f"venue {venue_id!r} has no place {place_id!r}")
            bump(c, venue_id)
