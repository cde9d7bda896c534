"""The venue catalogue: the one record of venues, floors and plans, places, lenses and videos.

The CLI and the server both go through it, so a venue made with `omninav venue create` is served,
and one made on the admin API is modelled and located from the command line. Metadata lives in
the database (db.py: SQLite by default, PostgreSQL by DATABASE_URL); a venue's modelled frames in
its store folder (store.py, generations only); floor plans and modelling videos as files under
the data folder.

Each resource has one owner module, which validates what it is given and persists it:

    venues.py   venues, their feature settings, and the revision every edit bumps
    floors.py   floors, their plans (checked before decoding) and scales
    places.py   named places and areas, in metres
    lenses.py   lens profiles, by name
    videos.py   modelling videos: registration, the resumable upload, their state
    sessions.py tracking sessions: a phone's walk, as the filter and the route guide remember it

Errors are OmninavError subclasses (errors.py); the server's blueprints alone turn them into
status codes. `Catalog.open` also imports, once, the venues an older omninav kept in
`venues/<id>/venue.json` (legacy.py).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from ..store import Store
from .db import Db
from .floors import Floors
from .lenses import Lenses
from .places import Places
from .sessions import Sessions
from .venues import Venues
from .videos import Videos


class Catalog:
    def __init__(self, db: Db, data: str | Path):
        self.db = db
        self.data = Path(data)
        self.store = Store(self.data)
        self.venues = Venues(self)
        self.floors = Floors(self)
        self.places = Places(self)
        self.lenses = Lenses(self)
        self.videos = Videos(self)
        self.sessions = Sessions(self)

    @classmethod
    def open(cls, conf: dict[str, Any]) -> Catalog:
        """The catalogue of a configuration (config.py): its database migrated, legacy venues in."""
        from ..config import database_url
        from .legacy import import_legacy

        data = Path(conf["DATA"])
        data.mkdir(parents=True, exist_ok=True)
        db = Db(database_url(conf))
        db.migrate()
        cat = cls(db, data)
        import_legacy(cat)
        return cat
