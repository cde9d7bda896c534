"""`omninav backup DIR` / `omninav restore DIR`: the catalogue and the venues, consistent while serving.

A backup is a folder:

    manifest.json        written last: format, schema version, venues, and size + sha256 of every file
    db.jsonl             every catalogue row, one JSON object a line ({"table": ..., "row": {...}})
    venues/<id>/         CURRENT and the live generation (gen-NNNNNN/)
    plans/<id>/<floor>.png
    videos/<id>/<name>   the modelling videos (ready or modelled; none with --no-videos)
    results/<id>/<job>.json  what the venue's done analysis jobs found (jobs.result)

It does not depend on the database: the rows are read through SQLAlchemy in one snapshot
transaction (REPEATABLE READ on PostgreSQL, one read transaction on SQLite's WAL) and restored into
any empty database after `Db.migrate()`, so a backup also moves a deployment from SQLite to
PostgreSQL. A backup never migrates the database it reads (a server may be using it): it refuses
one whose schema version is not this omninav's. It is written into `DIR.tmp` and renamed to DIR
only once its manifest is in, so a half-written backup is never taken for a good one; restore
checks every file against the manifest before it touches anything.

Consistency with a modelling job that runs meanwhile: each venue's generation is read and linked
under the venue's write lock (store.py), so a commit cannot delete it under us; generations, plans,
videos and venue files are never changed in place (always replaced by a rename), so a hard link is
a stable copy. A job commits its generation first and updates its rows after, so the row snapshot
and the generation may straddle that step: the backup makes the rows describe the generation it
holds (each video's frame count is taken from the generation; a job still active is recorded as
failed, to be started again, as after a server crash).
"""

from __future__ import annotations

import hashlib
import json
import os
import shutil
import struct
import tempfile
import time
from collections.abc import Iterator
from pathlib import Path, PurePosixPath
from typing import Any

import numpy as np
from sqlalchemy import Connection, inspect, text

from ..catalog.db import SCHEMA_VERSION, Db
from ..config import database_url
from ..errors import OmninavError
from ..store import Store, check_id

FORMAT = "omninav-backup"
FORMAT_VERSION = 1
MANIFEST = "manifest.json"
ROWS = "db.jsonl"
# parents before children, so that rows insert in this order and delete in the reverse
TABLES = ("meta", "venues", "floors", "places", "lenses", "videos", "jobs", "job_videos")
TREES = ("venues", "plans", "videos", "results")  # the data folders a backup holds
JOB_INTERRUPTED = (
    "this job had not finished when the backup was taken; the restored venue has the frames it had "
    "then. Start the job again."
)
Rows = dict[str, list[dict[str, Any]]]


# ---- files --------------------------------------------------------------------------------------
def _place(src: Path, dst: Path) -> None:
    """Hard-link src at dst (instant, no space: the file is never changed in place), or copy it
    where a link cannot be made (another file system)."""
    dst.parent.mkdir(parents=True, exist_ok=True)
    try:
        os.link(src, dst)
    except OSError:
        shutil.copyfile(src, dst)
        _fsync(dst)


def _fsync(path: Path) -> None:
    fd = os.open(path, os.O_RDONLY)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)


def _write(path: Path, data: bytes) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    with open(path, "wb") as f:
        f.write(data)
        f.flush()
        os.fsync(f.fileno())


def _sha256(path: Path) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as f:
        while chunk := f.read(1 << 20):
            h.update(chunk)
    return h.hexdigest()


def _files(root: Path) -> Iterator[Path]:
    """Every plain file under root, sorted, as paths relative to it."""
    for p in sorted(root.rglob("*")):
        if p.is_file():
            yield p.relative_to(root)


def _png_size(path: Path) -> tuple[int, int] | None:
    """Width and height from a PNG's header (IHDR), without decoding the image."""
    with open(path, "rb") as f:
        head = f.read(24)
    if len(head) < 24 or head[:8] != b"\x89PNG\r\n\x1a\n" or head[12:16] != b"IHDR":
        return None
    w, h = struct.unpack(">II", head[16:24])
    return int(w), int(h)


# ---- the rows -----------------------------------------------------------------------------------
def _snapshot_tx(c: Connection) -> None:
    """Make every following read on c see one moment of the database."""
    if c.dialect.name == "sqlite":
        # pysqlite opens no transaction for reads: each SELECT would see its own moment. An
        # explicit BEGIN holds one WAL read snapshot from the first read to the rollback.
        c.exec_driver_sql("BEGIN")
    else:
        c.execution_options(isolation_level="REPEATABLE READ")


def dump_rows(db: Db) -> Rows:
    """Every row of every catalogue table, read in one snapshot transaction."""
    out: Rows = {}
    with db.engine.connect() as c:
        _snapshot_tx(c)
        for t in TABLES:
            out[t] = [dict(r._mapping) for r in c.execute(text(f"SELECT * FROM {t}"))]
        c.rollback()
    return out


def _dump(conf: dict[str, Any]) -> Rows:
    db = Db(database_url(conf))
    try:
        _check_schema(db)
        return dump_rows(db)
    finally:
        db.engine.dispose()


def _check_schema(db: Db) -> None:
    """A backup reads the live database and never migrates it: a server of another omninav may
    be using it (a newer CLI beside an older server would change the schema under it). So it
    backs up only a database of this omninav's schema version, and says which omninav can."""
    path = db.engine.url.database if db.engine.dialect.name == "sqlite" else None
    have = 0 if path and not Path(path).is_file() else db.version()  # (a look would create the file)
    if have == 0:
        raise OmninavError(f"the database {db.engine.url!r} holds no omninav catalogue: nothing to back up")
    if have != SCHEMA_VERSION:
        raise OmninavError(
            f"the database {db.engine.url!r} has catalogue schema version {have}, this omninav {SCHEMA_VERSION}: "
            "back it up with the omninav that serves it (a backup never migrates a live database)"
        )


def _schema_version(rows: Rows) -> int:
    return int(next((r["value"] for r in rows["meta"] if r["key"] == "schema_version"), 0))


# ---- backup -------------------------------------------------------------------------------------
def _link_venue(store: Store, venue_id: str, dst: Path) -> str | None:
    """Link the venue's live generation into dst/venues/<id>; returns the generation's name
    (None: not modelled). Under the venue's lock: a commit cannot swap CURRENT
    or delete the generation (commit keeps one step back) between reading and linking it."""
    src = store.venue_dir(venue_id)
    out = dst / "venues" / venue_id
    with store.lock(venue_id):
        gen = store.generation(venue_id)
        if gen is not None:
            for f in sorted((src / gen).iterdir()):
                _place(f, out / gen / f.name)
            _write(out / "CURRENT", gen.encode())
    return gen


def _frames_by_video(gen_dir: Path) -> dict[str, int]:
    """How many frames of each modelling video a generation holds (frames.npy's `video` column)."""
    names = json.loads((gen_dir / "videos.json").read_text())
    which = np.load(gen_dir / "frames.npy", mmap_mode="r")["video"]
    counts = np.bincount(np.asarray(which, np.int64), minlength=len(names))
    return {n: int(counts[i]) for i, n in enumerate(names)}


def _agree_with_generations(rows: Rows, dst: Path, gens: dict[str, str | None]) -> None:
    """Make the video rows describe the generations the backup holds: a job commits its
    generation before it updates its rows, and the snapshot may fall between the two."""
    counts = {v: _frames_by_video(dst / "venues" / v / g) if g else {} for v, g in gens.items()}
    for r in rows["videos"]:
        r["frames"] = counts.get(r["venue"], {}).get(r["name"], 0)


def _stop_active_jobs(rows: Rows, now: float) -> None:
    """A job still queued or running is recorded as failed: the restored server starts with no
    half-done job (its process is not there), and the venue has the frames it had."""
    for r in rows["jobs"]:
        if r["state"] in ("queued", "running"):
            r.update(state="failed", finished=now, error=JOB_INTERRUPTED, owner=None)


def _link_plans(cat_data: Path, rows: Rows, dst: Path) -> None:
    """Link each floor's plan; its size in the row is read from the file the backup holds (a plan
    is replaced file first, row second)."""
    for r in rows["floors"]:
        if not r["plan_file"]:
            continue
        src = cat_data / "plans" / r["venue"] / r["plan_file"]
        if not src.is_file():  # gone meanwhile: the floor has no plan
            r.update(plan_file=None, plan_w=None, plan_h=None)
            continue
        out = dst / "plans" / r["venue"] / r["plan_file"]
        _place(src, out)
        if size := _png_size(out):
            r["plan_w"], r["plan_h"] = size


def _link_videos(data: Path, rows: Rows, dst: Path, videos: bool) -> None:
    """Link the uploaded videos (not the ones still uploading: their bytes are not all there)."""
    for r in rows["videos"]:
        if r["status"] == "uploading":  # its .part is not backed up: the upload starts again
            r.update(received=0, writer=None, writer_until=None)
            continue
        if not videos:
            continue
        src = data / "videos" / r["venue"] / r["name"]
        if src.is_file():
            _place(src, dst / "videos" / r["venue"] / r["name"])
        else:  # deleted or being replaced meanwhile: it must be uploaded again
            r.update(status="uploading", received=0, writer=None, writer_until=None)


def _link_results(data: Path, rows: Rows, dst: Path) -> None:
    """Link each job's result file (written once, renamed into place); a job whose file is gone
    (its venue or video deleted meanwhile) keeps no result."""
    for r in rows["jobs"]:
        if not r.get("result"):
            continue
        rel = PurePosixPath(r["result"])
        src = data / rel
        if rel.is_absolute() or ".." in rel.parts or rel.parts[0] != "results" or not src.is_file():
            r["result"] = None
            continue
        _place(src, dst / rel)


def _write_rows(rows: Rows, path: Path) -> None:
    lines = [json.dumps({"table": t, "row": r}, separators=(",", ":")) for t in TABLES for r in rows[t]]
    _write(path, ("\n".join(lines) + "\n").encode())


def _file_entry(path: Path) -> dict[str, Any]:
    return {"size": path.stat().st_size, "sha256": _sha256(path)}


def _manifest(
    tmp: Path, rows: Rows, gens: dict[str, str | None], frames: dict[str, int], videos: bool
) -> dict[str, Any]:
    files = {str(PurePosixPath(*p.parts)): _file_entry(tmp / p) for p in _files(tmp)}
    return {
        "format": FORMAT,
        "format_version": FORMAT_VERSION,
        "schema_version": _schema_version(rows),
        "created": time.time(),
        "videos": videos,
        "venues": {v: {"generation": gens[v], "frames": frames[v]} for v in sorted(gens)},
        "rows": {t: len(rows[t]) for t in TABLES},
        "files": files,
    }


def _target_dir(dest: Path) -> None:
    """A backup goes into a new folder (an empty one is taken): never over another backup."""
    if dest.exists() and (not dest.is_dir() or any(dest.iterdir())):
        raise OmninavError(f"{dest} exists and is not empty: back up into a new folder")


def backup(conf: dict[str, Any], dest: Path, videos: bool = True) -> dict[str, Any]:
    """Back up the server whose settings are conf into the new folder dest; returns a summary."""
    t0 = time.monotonic()
    dest = Path(dest)
    _target_dir(dest)
    data = Path(conf["DATA"])
    if not data.is_dir():  # a mistyped --data must not back up (and create) an empty deployment
        raise OmninavError(f"{data}: no such data folder")
    tmp = dest.with_name(dest.name + ".tmp")
    shutil.rmtree(tmp, ignore_errors=True)  # what an interrupted backup left
    tmp.mkdir(parents=True)
    try:
        rows = _dump(conf)
        store = Store(data)
        ids = sorted({r["id"] for r in rows["venues"]} | set(store.list()))
        gens = {v: _link_venue(store, v, tmp) for v in ids}
        _agree_with_generations(rows, tmp, gens)
        _stop_active_jobs(rows, time.time())
        _link_plans(data, rows, tmp)
        _link_videos(data, rows, tmp, videos)
        _link_results(data, rows, tmp)
        _write_rows(rows, tmp / ROWS)
        frames = {v: _gen_frames(tmp / "venues" / v, g) for v, g in gens.items()}
        man = _manifest(tmp, rows, gens, frames, videos)
        _write(tmp / MANIFEST, json.dumps(man, indent=1).encode())  # last: it vouches for the rest
        if dest.exists():
            dest.rmdir()
        os.rename(tmp, dest)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    return _summary("backup", dest, man, time.monotonic() - t0)


def _gen_frames(venue_dir: Path, gen: str | None) -> int:
    return len(np.load(venue_dir / gen / "frames.npy", mmap_mode="r")) if gen else 0


def _summary(what: str, path: Path, man: dict[str, Any], seconds: float) -> dict[str, Any]:
    return {
        what: str(path),
        "venues": len(man["venues"]),
        "frames": sum(v["frames"] for v in man["venues"].values()),
        "rows": sum(man["rows"].values()),
        "files": len(man["files"]),
        "bytes": sum(f["size"] for f in man["files"].values()),
        "videos": man["videos"],
        "seconds": round(seconds, 2),
    }


# ---- restore ------------------------------------------------------------------------------------
def _safe_rel(name: str) -> PurePosixPath:
    """A manifest path must stay inside the backup: relative, no '..', under a known folder."""
    p = PurePosixPath(name)
    if p.is_absolute() or ".." in p.parts or not (p.parts[0] in TREES or name == ROWS):
        raise OmninavError(f"backup manifest names an unexpected file {name!r}")
    return p


def verify(src: Path) -> dict[str, Any]:
    """Read the backup's manifest and check every file against it; returns the manifest."""
    src = Path(src)
    try:
        man = json.loads((src / MANIFEST).read_text())
    except FileNotFoundError:
        raise OmninavError(f"{src} is not a complete omninav backup (no {MANIFEST})") from None
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as e:
        raise OmninavError(f"{src}/{MANIFEST} is damaged ({e})") from None
    if not isinstance(man, dict) or man.get("format") != FORMAT or not isinstance(man.get("files"), dict):
        raise OmninavError(f"{src} is not an omninav backup ({MANIFEST} is not one)")
    if not all(isinstance(man.get(k), dict) for k in ("venues", "rows")) or "schema_version" not in man:
        raise OmninavError(f"backup {src} is damaged: {MANIFEST} lacks its venues, rows or schema version")
    if man.get("format_version") != FORMAT_VERSION:
        raise OmninavError(f"{src} has backup format {man.get('format_version')}; this omninav reads {FORMAT_VERSION}")
    if ROWS not in man["files"]:
        raise OmninavError(f"backup {src} is damaged: {MANIFEST} lists no {ROWS}")
    for name, want in man["files"].items():
        p = src / _safe_rel(name)
        if not p.is_file():
            raise OmninavError(f"backup {src} is damaged: {name} is missing")
        if p.stat().st_size != want["size"]:
            raise OmninavError(
                f"backup {src} is damaged: {name} has {p.stat().st_size} bytes, the manifest says {want['size']}"
            )
        if _sha256(p) != want["sha256"]:
            raise OmninavError(f"backup {src} is damaged: {name} differs from the manifest (sha256)")
    return man


def _read_rows(path: Path) -> Rows:
    rows: Rows = {t: [] for t in TABLES}
    for i, line in enumerate(path.read_text().splitlines(), 1):
        try:
            item = json.loads(line)
            rows[item["table"]].append(dict(item["row"]))
        except (json.JSONDecodeError, KeyError, TypeError, ValueError) as e:
            raise OmninavError(f"{path}, line {i}: not a catalogue row ({type(e).__name__}: {e})") from None
    return rows


def _data_in_use(data: Path) -> bool:
    return bool(Store(data).list()) or any(
        (data / d).is_dir() and any((data / d).iterdir()) for d in TREES if d != "venues"
    )


def _check_empty(db: Db, data: Path, force: bool) -> None:
    if force:
        return
    n = int(db.one("SELECT COUNT(*) AS n FROM venues")["n"])  # type: ignore[index]
    if n:
        raise OmninavError(f"the database {db.engine.url!r} has {n} venue(s): restore into an empty one, or --force")
    if _data_in_use(data):
        raise OmninavError(f"{data} holds venues, plans or videos: restore into an empty data folder, or --force")


def _insert_rows(c: Connection, rows: Rows, force: bool) -> None:
    """Replace the catalogue by the backup's rows, in the caller's transaction."""
    if force:
        for t in reversed(TABLES):
            c.execute(text(f"DELETE FROM {t}"))
        c.execute(text("INSERT INTO meta (key, value) VALUES ('schema_version', :v)"), {"v": str(SCHEMA_VERSION)})
    have = {t: {col["name"] for col in inspect(c).get_columns(t)} for t in TABLES}
    for t in TABLES:
        todo = [r for r in rows[t] if not (t == "meta" and r["key"] == "schema_version")]
        for cols in sorted({tuple(sorted(r)) for r in todo}):  # one statement per column set
            if unknown := set(cols) - have[t]:
                raise OmninavError(f"the backup has column(s) {sorted(unknown)} in table {t} that this database lacks")
            names = ", ".join(cols)
            values = ", ".join(f":{k}" for k in cols)
            upsert = " ON CONFLICT (key) DO UPDATE SET value = excluded.value" if t == "meta" else ""
            sql = f"INSERT INTO {t} ({names}) VALUES ({values}){upsert}"  # names checked against the table
            c.execute(text(sql), [r for r in todo if tuple(sorted(r)) == cols])


def _stage(src: Path, man: dict[str, Any], data: Path) -> Path:
    """Link the backup's files into a folder beside the data's folders (same file system, so
    they can be renamed into place)."""
    stage = Path(tempfile.mkdtemp(dir=data, prefix=".restore-"))
    for name in man["files"]:
        rel = _safe_rel(name)
        if rel.parts[0] in TREES:
            _place(src / rel, stage / rel)
    return stage


def _swap_in(stage: Path, data: Path) -> None:
    """Put the staged folders in place of the data's (renames), then drop the old ones."""
    old = stage / ".old"
    old.mkdir()
    for d in TREES:
        if (data / d).exists():
            os.rename(data / d, old / d)
        if (stage / d).exists():
            os.rename(stage / d, data / d)
    shutil.rmtree(stage)


def restore(conf: dict[str, Any], src: Path, force: bool = False) -> dict[str, Any]:
    """Restore the backup in src into the server whose settings are conf (stopped); returns a summary.

    Refuses a damaged backup, one of another schema version, and a target that has venues
    (unless force, which replaces them)."""
    t0 = time.monotonic()
    src = Path(src)
    man = verify(src)
    if man["schema_version"] != SCHEMA_VERSION:
        raise OmninavError(
            f"the backup has catalogue schema version {man['schema_version']}, this omninav {SCHEMA_VERSION}: "
            "restore it with the omninav that made it"
        )
    for v in man["venues"]:
        check_id(v)
    data = Path(conf["DATA"])
    data.mkdir(parents=True, exist_ok=True)
    db = Db(database_url(conf))
    try:
        db.migrate()
        _check_empty(db, data, force)
        rows = _read_rows(src / ROWS)
        stage = _stage(src, man, data)
        try:
            with db.tx() as c:  # all rows or none
                _insert_rows(c, rows, force)
        except BaseException:
            shutil.rmtree(stage, ignore_errors=True)
            raise
    finally:
        db.engine.dispose()
    _swap_in(stage, data)
    return _summary("restore", src, man, time.monotonic() - t0)
