"""Modelling jobs: queued in the database, run by a background thread in each server process.

Any process may claim a queued job (one atomic UPDATE decides who); its progress, heartbeat and
cancel flag live in the job's row, so every worker can report on it and cancel it. A job whose
process died (the server was killed) is seen as failed: at start-up for dead processes on this
host, and by a stale heartbeat otherwise. Modelling commits one new generation at the very end
(model_venue.py), so a job that dies or is cancelled leaves the venue answering as before.
"""

from __future__ import annotations

import json
import logging
import os
import socket
import threading
import time
import uuid
from pathlib import Path
from typing import Any

from ..errors import OmninavError
from ..model_venue import VideoSource, model_videos
from ..track import parse_track
from .catalog import Catalog
from .http import ApiError

log = logging.getLogger("omninav.jobs")
ACTIVE = ("queued", "running")
FINAL = ("done", "failed", "cancelled")
PROGRESS_EVERY_S = 0.5
HEARTBEAT_EVERY_S = 2.0


class Cancelled(Exception):
    pass


def _start_time(pid: int) -> str | None:
    """The kernel's start time of a process: with the pid, it names one process for ever."""
    try:
        fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    except (OSError, IndexError):
        return None
    if fields[0] in ("Z", "X"):  # a killed process nobody has reaped yet is dead all the same
        return None
    return fields[19]


def this_process() -> str:
    pid = os.getpid()
    return f"{socket.gethostname()}:{pid}:{_start_time(pid) or '?'}"


def owner_alive(owner: str) -> bool | None:
    """True/False for an owner on this host; None when it is another host's (ask the heartbeat)."""
    try:
        host, pid_s, start = owner.rsplit(":", 2)
        pid = int(pid_s)
    except ValueError:
        return False
    if host != socket.gethostname():
        return None
    now_start = _start_time(pid)
    if now_start is None:
        try:
            os.kill(pid, 0)
        except ProcessLookupError:
            return False
        except PermissionError:
            return True
        return start == "?"
    return now_start == start


def job_doc(r: dict[str, Any]) -> dict[str, Any]:
    done, total, fps = r["frames_done"], r["frames_total"], r["fps"]
    eta = (total - done) / fps if r["state"] == "running" and fps > 0 and total >= done else None
    return {
        "id": r["id"],
        "venue": r["venue"],
        "videos": json.loads(r["videos"]),
        "state": r["state"],
        "frames_done": done,
        "frames_total": total,
        "frames_per_s": round(fps, 2),
        "eta_s": round(eta, 1) if eta is not None else None,
        "created": r["created"],
        "started": r["started"],
        "finished": r["finished"],
        "error": r["error"],
    }


class Jobs:
    def __init__(self, catalog: Catalog, stale_s: float = 30.0):
        self.cat = catalog
        self.db = catalog.db
        self.stale_s = stale_s
        self.me = this_process()
        self.wake = threading.Event()
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None

    # ---- API side -----------------------------------------------------------------------------
    def get(self, job_id: str) -> dict[str, Any]:
        self.reap()
        row = self.db.one("SELECT * FROM jobs WHERE id = :id", id=job_id)
        if row is None:
            raise ApiError(404, f"unknown job {job_id!r}")
        return row

    def for_venue(self, venue_id: str) -> list[dict[str, Any]]:
        self.cat.venue(venue_id)
        self.reap()
        return self.db.all("SELECT * FROM jobs WHERE venue = :v ORDER BY created DESC", v=venue_id)

    def submit(self, venue_id: str, names: Any) -> dict[str, Any]:
        self.cat.venue(venue_id)
        self.reap()
        vids = self.cat.videos(venue_id)
        if names is None:  # default: every uploaded video not modelled yet
            names = [v["name"] for v in vids if v["status"] == "ready"]
            if not names:
                raise ApiError(409, f"venue {venue_id!r} has no uploaded video waiting to be modelled")
        if not isinstance(names, list) or not names or not all(isinstance(n, str) for n in names):
            raise ApiError(400, "'videos' must be a non-empty list of video names")
        by_name = {v["name"]: v for v in vids}
        for n in names:
            if n not in by_name:
                raise ApiError(404, f"venue {venue_id!r} has no video {n!r}")
            if by_name[n]["status"] not in ("ready", "modelled"):
                raise ApiError(
                    409,
                    f"video {n!r} is not completely uploaded ({by_name[n]['received']} of {by_name[n]['size']} bytes)",
                )
        busy = self.db.one("SELECT id FROM jobs WHERE venue = :v AND state IN ('queued', 'running')", v=venue_id)
        if busy:
            raise ApiError(409, f"venue {venue_id!r} is already being modelled by job {busy['id']}")
        job_id = uuid.uuid4().hex[:16]
        self.db.run(
            "INSERT INTO jobs (id, venue, videos, state, created) VALUES (:id, :v, :vs, 'queued', :t)",
            id=job_id,
            v=venue_id,
            vs=json.dumps(list(dict.fromkeys(names))),
            t=time.time(),
        )
        self.wake.set()
        return self.get(job_id)

    def cancel(self, job_id: str) -> dict[str, Any]:
        row = self.get(job_id)
        if row["state"] in FINAL:
            raise ApiError(409, f"job {job_id} has already ended ({row['state']})")
        now = time.time()
        # a queued job ends here; a running one is stopped by its runner at its next frame
        self.db.run(
            "UPDATE jobs SET state = 'cancelled', finished = :t, cancel = 1 WHERE id = :id AND state = 'queued'",
            id=job_id,
            t=now,
        )
        self.db.run("UPDATE jobs SET cancel = 1 WHERE id = :id AND state = 'running'", id=job_id)
        return self.get(job_id)

    def reap(self) -> int:
        """Mark jobs whose process died as failed; returns how many."""
        n = 0
        now = time.time()
        for r in self.db.all("SELECT id, owner, heartbeat FROM jobs WHERE state = 'running'"):
            alive = owner_alive(r["owner"] or "")
            if alive is None:
                alive = (r["heartbeat"] or 0) > now - self.stale_s
            if not alive:
                n += self.db.run(
                    "UPDATE jobs SET state = 'failed', finished = :t, error = :e WHERE id = :id AND state = 'running'",
                    id=r["id"],
                    t=now,
                    e="the server stopped while this job ran; the venue kept its previous frames. Start the job again.",
                )
        return n

    # ---- runner side --------------------------------------------------------------------------
    def start(self) -> None:
        self.reap()
        self._thread = threading.Thread(target=self._loop, name="omninav-jobs", daemon=True)
        self._thread.start()

    def stop(self) -> None:
        self._stop.set()
        self.wake.set()

    def _loop(self) -> None:
        while not self._stop.is_set():
            try:
                self.run_next()
            except Exception:  # the runner must outlive any one job's bug
                log.exception("job runner")
            self.wake.wait(1.0)
            self.wake.clear()

    def claim(self) -> dict[str, Any] | None:
        for r in self.db.all("SELECT id FROM jobs WHERE state = 'queued' ORDER BY created"):
            t = time.time()
            got = self.db.run(
                "UPDATE jobs SET state = 'running', owner = :o, started = :t, heartbeat = :t "
                "WHERE id = :id AND state = 'queued'",
                o=self.me,
                t=t,
                id=r["id"],
            )
            if got:
                return self.db.one("SELECT * FROM jobs WHERE id = :id", id=r["id"])
        return None

    def run_next(self) -> bool:
        job = self.claim()
        if job is None:
            return False
        beat_stop = threading.Event()

        def beat() -> None:  # a heartbeat independent of progress: opening or committing may be slow
            while not beat_stop.wait(HEARTBEAT_EVERY_S):
                self.db.run("UPDATE jobs SET heartbeat = :t WHERE id = :id", t=time.time(), id=job["id"])

        hb = threading.Thread(target=beat, daemon=True)
        hb.start()
        try:
            self._run(job)
        finally:
            beat_stop.set()
        return True

    def _sources(self, job: dict[str, Any]) -> list[VideoSource]:
        out = []
        for name in json.loads(job["videos"]):
            v = self.db.one("SELECT * FROM videos WHERE venue = :v AND name = :n", v=job["venue"], n=name)
            if v is None:
                raise OmninavError(f"video {name!r} was deleted before it was modelled")
            path = self.cat.video_dir(job["venue"]) / name
            if not path.is_file():
                raise OmninavError(f"video {name!r} has no uploaded file")
            out.append(VideoSource(path, parse_track(json.loads(v["track"])), self.cat.lens(job["venue"], v["lens"])))
        return out

    def _run(self, job: dict[str, Any]) -> None:
        jid = job["id"]
        last = 0.0

        def progress(done: int, total: int, elapsed: float) -> None:
            nonlocal last
            now = time.monotonic()
            if now - last < PROGRESS_EVERY_S and done < total:
                return
            last = now
            self.db.run(
                "UPDATE jobs SET frames_done = :d, frames_total = :n, fps = :f, heartbeat = :t WHERE id = :id",
                d=done,
                n=total,
                f=done / max(elapsed, 1e-9),
                t=time.time(),
                id=jid,
            )
            if self.db.one("SELECT cancel FROM jobs WHERE id = :id", id=jid)["cancel"]:  # type: ignore[index]
                raise Cancelled

        state, error = "done", None
        try:
            results = model_videos(self.cat.store, job["venue"], self._sources(job), progress)
            for r in results:
                self.db.run(
                    "UPDATE videos SET status = 'modelled', frames = :f WHERE venue = :v AND name = :n",
                    f=r.frames,
                    v=job["venue"],
                    n=r.video,
                )
        except Cancelled:
            state = "cancelled"
        except (OmninavError, ApiError) as e:
            state, error = "failed", str(e)
        except Exception as e:  # a bug: the job fails with a line, the log has the rest
            log.exception("job %s", jid)
            state, error = "failed", f"internal error ({type(e).__name__}: {e})"
        self.db.run(
            "UPDATE jobs SET state = :s, error = :e, finished = :t WHERE id = :id",
            s=state,
            e=error,
            t=time.time(),
            id=jid,
        )
        self.cat.bump(job["venue"])
        log.info("job %s %s%s", jid, state, f": {error}" if error else "")
