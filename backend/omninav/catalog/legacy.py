"""Venues that an older omninav kept beside their frames, imported into the catalogue once.

Before the catalogue was the only one, `omninav venue create` wrote `venues/<id>/venue.json`
(name, preset, one floor with its plan and scale, places) and `settings.json`; the server never saw
them. On the first open of such a data folder each one becomes catalogue rows: the venue, its
floor and plan, its places, and the lens of its live generation (named by content). The file is
then renamed `venue.json.imported`, so the import happens once and what it read stays on disk.
"""

from __future__ import annotations

import json
import logging
from typing import TYPE_CHECKING, Any

from ..errors import OmninavError
from ..store import check_id

if TYPE_CHECKING:
    from . import Catalog

log = logging.getLogger("omninav.catalog")


def import_legacy(cat: Catalog) -> list[str]:
    """Import every venue.json under the data folder; returns the ids imported."""
    root = cat.store.venues
    if not root.is_dir():
        return []
    done = []
    for meta_file in sorted(root.glob("*/venue.json")):
        venue_id = meta_file.parent.name
        try:
            check_id(venue_id)
        except OmninavError:
            continue
        with cat.store.lock(venue_id):  # several server processes may open the folder at once
            if not meta_file.is_file():  # another process imported it while this one waited
                continue
            if not cat.venues.exists(venue_id):
                _import(cat, venue_id, json.loads(meta_file.read_text()))
                done.append(venue_id)
            meta_file.rename(meta_file.with_name("venue.json.imported"))
            (meta_file.parent / "settings.json").unlink(missing_ok=True)  # the preset's, as the row says
    for v in done:
        log.info("imported venue %r from its venue.json into the catalogue", v)
    return done


def _import(cat: Catalog, venue_id: str, meta: dict[str, Any]) -> None:
    d = cat.store.venue_dir(venue_id)
    floor = str(meta.get("floor") or "1")
    cat.venues.create(
        venue_id, meta.get("name") or venue_id, meta.get("preset") or "default", floor, px_per_m=meta.get("px_per_m")
    )
    try:
        plan = d / str(meta.get("floorplan") or "")
        if meta.get("floorplan") and plan.is_file():
            cat.floors.set_plan(venue_id, floor, plan.read_bytes())
        if meta.get("places"):
            cat.places.add(venue_id, [{**p, "floor": floor} for p in meta["places"]])
        lens = d / (cat.store.generation(venue_id) or "-") / "lens.json"
        if lens.is_file():
            cat.lenses.put_inline(venue_id, json.loads(lens.read_text()), where=f"{venue_id}'s lens")
    except OmninavError as e:  # a file it could not take: the venue is there, without that part
        log.warning("venue %r imported without part of its venue.json: %s", venue_id, e)
