"""The catalogue database: venues, floors, places, lenses, videos, jobs (SQLite by default).

Feature arrays are not here: they are files (store.py), memory-mapped by every worker. The SQL is
plain and portable (SQLite and PostgreSQL) and goes through SQLAlchemy Core, so a deployment
switches databases with DATABASE_URL alone.

Migrations are numbered lists of statements, applied in order inside one transaction each; the
database records the last one applied. A database newer than this code is refused rather than
guessed at.
"""

from __future__ import annotations

import json
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

from sqlalchemy import Connection, create_engine, event, inspect, text
from sqlalchemy.engine import Engine, make_url

from ..errors import OmninavError


def _rename_inline_lenses(c: Connection) -> None:
    """Inline lens profiles were named after their video ('video-<name>'), and the public venue
    document lists lens names: name them by their content instead, so no video name leaks."""
    from .lenses import inline_lens_name

    rows = c.execute(text("SELECT venue, name, profile FROM lenses WHERE name LIKE 'video-%'")).all()
    for venue, name, profile in rows:
        p = {"v": venue, "n": inline_lens_name(json.loads(profile)), "o": name}
        if c.execute(text("SELECT 1 FROM lenses WHERE venue = :v AND name = :n"), p).first():
            c.execute(text("DELETE FROM lenses WHERE venue = :v AND name = :o"), p)
        else:
            c.execute(text("UPDATE lenses SET name = :n WHERE venue = :v AND name = :o"), p)
        c.execute(text("UPDATE videos SET lens = :n WHERE venue = :v AND lens = :o"), p)


def _job_videos(c: Connection) -> None:
    """Fill job_videos from the jobs' JSON lists of video names."""
    for job, venue, videos in c.execute(text("SELECT id, venue, videos FROM jobs")).all():
        for name in dict.fromkeys(json.loads(videos)):
            c.execute(
                text("INSERT INTO job_videos (job, venue, video) VALUES (:j, :v, :n)"),
                {"j": job, "v": venue, "n": name},
            )


def _tracking_sessions(c: Connection) -> None:
    """The tracking sessions (catalog/sessions.py); their filter state is bytes, whose column type
    each database names its own way."""
    blob = "BYTEA" if c.dialect.name == "postgresql" else "BLOB"
    c.execute(
        text(
            f"""CREATE TABLE tracking_sessions (
            id TEXT NOT NULL, venue TEXT NOT NULL REFERENCES venues(id) ON DELETE CASCADE,
            generation TEXT NOT NULL, state {blob} NOT NULL, guide TEXT,
            updated DOUBLE PRECISION NOT NULL, expires DOUBLE PRECISION NOT NULL,
            PRIMARY KEY (venue, id))"""
        )
    )
    c.execute(text("CREATE INDEX tracking_sessions_expires ON tracking_sessions (expires)"))


Migration = list[str | Callable[[Connection], None]]
MIGRATIONS: list[Migration] = [
    # 1: the first schema
    [
        "CREATE TABLE meta (key TEXT PRIMARY KEY, value TEXT NOT NULL)",
        """CREATE TABLE venues (
            id TEXT PRIMARY KEY, name TEXT NOT NULL, preset TEXT NOT NULL,
            created DOUBLE PRECISION NOT NULL, revision INTEGER NOT NULL DEFAULT 0)""",
        """CREATE TABLE floors (
            venue TEXT NOT NULL REFERENCES venues(id) ON DELETE CASCADE, id TEXT NOT NULL,
            name TEXT NOT NULL, plan_file TEXT, plan_w INTEGER, plan_h INTEGER, px_per_m DOUBLE PRECISION,
            PRIMARY KEY (venue, id))""",
        """CREATE TABLE places (
            id TEXT PRIMARY KEY, venue TEXT NOT NULL REFERENCES venues(id) ON DELETE CASCADE,
            floor TEXT NOT NULL, name TEXT NOT NULL, x DOUBLE PRECISION NOT NULL, y DOUBLE PRECISION NOT NULL,
            area TEXT)""",
        """CREATE TABLE lenses (
            venue TEXT NOT NULL REFERENCES venues(id) ON DELETE CASCADE, name TEXT NOT NULL,
            profile TEXT NOT NULL, PRIMARY KEY (venue, name))""",
        """CREATE TABLE videos (
            venue TEXT NOT NULL REFERENCES venues(id) ON DELETE CASCADE, name TEXT NOT NULL,
            floor TEXT NOT NULL, lens TEXT NOT NULL, track TEXT NOT NULL, size BIGINT NOT NULL,
            received BIGINT NOT NULL DEFAULT 0, status TEXT NOT NULL, frames INTEGER NOT NULL DEFAULT 0,
            created DOUBLE PRECISION NOT NULL, PRIMARY KEY (venue, name))""",
        """CREATE TABLE jobs (
            id TEXT PRIMARY KEY, venue TEXT NOT NULL REFERENCES venues(id) ON DELETE CASCADE,
            videos TEXT NOT NULL, state TEXT NOT NULL, frames_done INTEGER NOT NULL DEFAULT 0,
            frames_total INTEGER NOT NULL DEFAULT 0, fps DOUBLE PRECISION NOT NULL DEFAULT 0,
            created DOUBLE PRECISION NOT NULL, started DOUBLE PRECISION, finished DOUBLE PRECISION,
            heartbeat DOUBLE PRECISION, owner TEXT, cancel INTEGER NOT NULL DEFAULT 0, error TEXT)""",
        "CREATE INDEX jobs_venue_state ON jobs (venue, state)",
        "CREATE INDEX places_venue ON places (venue)",
    ],
    # 2: one active job per venue (a constraint, not check-then-insert); job retries; one writer
    # per video upload (a lease that expires if its process dies); inline lenses named by content
    [
        """UPDATE jobs SET state = 'failed', finished = created,
                error = 'another modelling job of this venue was active at the same time'
            WHERE state IN ('queued', 'running') AND EXISTS (
                SELECT 1 FROM jobs j2 WHERE j2.venue = jobs.venue AND j2.state IN ('queued', 'running')
                AND (j2.created < jobs.created OR (j2.created = jobs.created AND j2.id < jobs.id)))""",
        "CREATE UNIQUE INDEX jobs_one_active ON jobs (venue) WHERE state IN ('queued', 'running')",
        "ALTER TABLE jobs ADD COLUMN attempts INTEGER NOT NULL DEFAULT 0",
        "ALTER TABLE jobs ADD COLUMN not_before DOUBLE PRECISION",
        "ALTER TABLE videos ADD COLUMN writer TEXT",
        "ALTER TABLE videos ADD COLUMN writer_until DOUBLE PRECISION",
        _rename_inline_lenses,
    ],
    # 3: which videos each job models, as rows: "is this video being modelled?" is an indexed
    # lookup, not a LIKE over the jobs' JSON lists
    [
        """CREATE TABLE job_videos (
            job TEXT NOT NULL REFERENCES jobs(id) ON DELETE CASCADE, venue TEXT NOT NULL,
            video TEXT NOT NULL, PRIMARY KEY (job, video))""",
        "CREATE INDEX job_videos_video ON job_videos (venue, video)",
        _job_videos,
    ],
    # 4: the admin page. Videos have a role (modelling or evaluation walk), may be registered
    # before their track (track is the JSON `null` until then; `walk_path` since 7), keep what the upload check read
    # of them (or why it refused them) and the latest waypoint suggestions; jobs have a kind, a
    # target video (suggest, evaluate) and the path of their result JSON (relative to DATA). One
    # active job per venue, kind and target: a venue can be modelled while a video's waypoints
    # are suggested. Places keep their kind and the sentence to say on arrival (docs/formats.md).
    [
        "ALTER TABLE places ADD COLUMN kind TEXT",
        "ALTER TABLE places ADD COLUMN say TEXT",
        "ALTER TABLE videos ADD COLUMN role TEXT NOT NULL DEFAULT 'model'",
        "ALTER TABLE videos ADD COLUMN duration_s DOUBLE PRECISION",
        "ALTER TABLE videos ADD COLUMN fps DOUBLE PRECISION",
        "ALTER TABLE videos ADD COLUMN width INTEGER",
        "ALTER TABLE videos ADD COLUMN height INTEGER",
        "ALTER TABLE videos ADD COLUMN error TEXT",
        "ALTER TABLE videos ADD COLUMN suggestions TEXT",
        "ALTER TABLE jobs ADD COLUMN kind TEXT NOT NULL DEFAULT 'model'",
        "ALTER TABLE jobs ADD COLUMN target TEXT",
        "ALTER TABLE jobs ADD COLUMN result TEXT",
        "DROP INDEX jobs_one_active",
        "CREATE UNIQUE INDEX jobs_one_active ON jobs (venue, kind, (COALESCE(target, ''))) "
        "WHERE state IN ('queued', 'running')",
    ],
    # 5: tracking sessions (issue 14): a phone's walk continues on any worker and after a restart
    [_tracking_sessions],
    # 6: a modelling job may model the venue anew, with its preset's current feature settings
    ["ALTER TABLE jobs ADD COLUMN anew INTEGER NOT NULL DEFAULT 0"],
    # 7: a video's waypoints are its walk path ("track" named the tracking filter too)
    ["ALTER TABLE videos RENAME COLUMN track TO walk_path"],
]
SCHEMA_VERSION = len(MIGRATIONS)
MIGRATION_LOCK = 0x6F6D6E69  # 'omni': the advisory lock id migrations hold on PostgreSQL


def _version(c: Connection) -> int:
    if not inspect(c).has_table("meta"):
        return 0
    row = c.execute(text("SELECT value FROM meta WHERE key = 'schema_version'")).first()
    return int(row[0]) if row else 0


def _sqlite_pragmas(dbapi_conn: Any, _record: Any) -> None:
    # WAL: readers (every worker's locate) never wait for the job runner's writes
    cur = dbapi_conn.cursor()
    cur.execute("PRAGMA journal_mode=WAL")
    cur.execute("PRAGMA foreign_keys=ON")
    cur.execute("PRAGMA busy_timeout=30000")
    cur.execute("PRAGMA synchronous=NORMAL")
    cur.close()


class Db:
    def __init__(self, url: str):
        self.url = url
        if url.startswith("sqlite"):
            path = make_url(url).database
            if path and path != ":memory:":
                Path(path).parent.mkdir(parents=True, exist_ok=True)
            self.engine: Engine = create_engine(url, connect_args={"timeout": 30, "check_same_thread": False})
            event.listen(self.engine, "connect", _sqlite_pragmas)
        else:
            self.engine = create_engine(url, pool_pre_ping=True)

    @contextmanager
    def tx(self) -> Iterator[Connection]:
        with self.engine.begin() as c:
            yield c

    def all(self, sql: str, **params: Any) -> list[dict[str, Any]]:
        with self.engine.connect() as c:
            return [dict(r._mapping) for r in c.execute(text(sql), params)]

    def one(self, sql: str, **params: Any) -> dict[str, Any] | None:
        rows = self.all(sql, **params)
        return rows[0] if rows else None

    def run(self, sql: str, **params: Any) -> int:
        """Execute one statement in its own transaction; returns the rows it touched."""
        with self.tx() as c:
            return int(c.execute(text(sql), params).rowcount or 0)

    def version(self) -> int:
        if not inspect(self.engine).has_table("meta"):  # a new database
            return 0
        row = self.one("SELECT value FROM meta WHERE key = 'schema_version'")
        return int(row["value"]) if row else 0

    def migrate(self) -> int:
        """Bring the schema up to SCHEMA_VERSION; returns how many migrations ran.

        Several servers may start at once on one PostgreSQL: each migration takes a transaction
        lock and reads the version again under it, so each runs exactly once."""
        have = self.version()
        if have > SCHEMA_VERSION:
            raise OmninavError(
                f"the database {self.url} has schema version {have}, newer than this omninav ({SCHEMA_VERSION}); "
                "upgrade omninav"
            )
        ran = 0
        for n in range(have, SCHEMA_VERSION):
            with self.tx() as c:
                if self.engine.dialect.name == "postgresql":
                    c.execute(text("SELECT pg_advisory_xact_lock(:k)"), {"k": MIGRATION_LOCK})
                    if _version(c) > n:  # another server ran it while this one waited
                        continue
                for stmt in MIGRATIONS[n]:
                    if callable(stmt):  # a data migration that SQL alone cannot express
                        stmt(c)
                    else:
                        c.execute(text(stmt))
                c.execute(
                    text(
                        "INSERT INTO meta (key, value) VALUES ('schema_version', :v) "
                        "ON CONFLICT (key) DO UPDATE SET value = excluded.value"
                    ),
                    {"v": str(n + 1)},
                )
                ran += 1
        return ran

    def get_meta(self, key: str) -> str | None:
        row = self.one("SELECT value FROM meta WHERE key = :k", k=key)
        return row["value"] if row else None

    def set_meta(self, key: str, value: str) -> None:
        self.run(
            "INSERT INTO meta (key, value) VALUES (:k, :v) ON CONFLICT (key) DO UPDATE SET value = excluded.value",
            k=key,
            v=value,
        )
