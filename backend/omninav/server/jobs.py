"""Background jobs: queued in the database, run by a job runner (a background thread of a server
process, or a dedicated process that calls `run_forever`). Each job has a kind (model, suggest,
quality, evaluate); what each kind takes and runs is job_kinds.py's, the queue is this module's.

A modelling job commits a generation; the others write a result, one JSON file per job
(DATA/results/<venue>/<job id>.json, named in jobs.result), renamed into place in the job's final
transaction, so that only the runner that owns the job publishes it.

One active job per venue, kind and target (one modelling job per venue; one suggest job per
video...) is a database constraint (the partial unique index `jobs_one_active`): `submit` inserts
and turns the constraint's refusal into a 409, so two simultaneous requests cannot both create
one. Any runner may claim a queued job (one atomic UPDATE decides who); its progress, heartbeat
and cancel flag live in the job's row, so every process can report on it and cancel it.

Jobs recover by themselves. A job whose runner died (the server was killed: a dead pid on this
host, a stale heartbeat from another) is queued again with a backoff, and so is one that met a
fault of its surroundings (a full disk); after MAX_ATTEMPTS it fails. A job that fails on its
input (OmninavError: a video that does not fit its lens...) fails at once: retrying cannot help.
Modelling commits one new generation at the very end (model_venue.py), so a job that dies, fails
or is cancelled leaves the venue answering as before.

A runner can be taken over while it still runs (its heartbeat stopped reaching the database for
stale_s: a paused machine, a network cut). So every write a runner makes to its job names it as
the owner (`Jobs._MINE`), and it checks again under the venue's lock just before its commit; where
a write finds the job no longer its own, it stops (Lost) and writes nothing more: the job, its
progress and the venue's next generation (or the job's result) are the new owner's.
"""

from __future__ import annotations

import errno
import json
import logging
import os
import socket
import threading
import time
import uuid
from pathlib import Path
from typing import Any

from sqlalchemy import text
from sqlalchemy.exc import IntegrityError

from ..catalog import Catalog
from ..catalog.venues import RESULTS
from ..catalog.videos import Videos
from ..errors import Conflict, NotFound, OmninavError
from ..model_venue import Progress, model_videos
from ..store import write_beside
from .job_kinds import analyse, check_analysis, doing, plain, videos_to_model

log = logging.getLogger("omninav.jobs")
ACTIVE = ("queued", "running")
FINAL = ("done", "failed", "cancelled")
PROGRESS_EVERY_S = 0.5
HEARTBEAT_EVERY_S = 2.0
POLL_S = 1.0  # how often an idle runner looks for work (and for jobs whose runner died)
MAX_ATTEMPTS = 3  # a job is claimed at most this often
BACKOFF_S = 2.0  # wait before attempt n+1: BACKOFF_S * 2**(n-1), i.e. 2 s, 4 s, 8 s...
DISK_FULL = (errno.ENOSPC, errno.EDQUOT)
STOPPED = "the server stopped while this job ran; the venue kept its previous frames"


class Cancelled(Exception):
    pass


class Lost(Exception):
    """This runner no longer owns its job (another runner took it over): stop, write nothing."""


def backoff_s(attempts: int) -> float:
    """The wait before the next attempt of a job that has been claimed `attempts` times."""
    return float(BACKOFF_S * 2 ** max(0, attempts - 1))


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


def result_file(venue_id: str, job_id: str) -> str:
    """Where a job's result lies, relative to the data folder (jobs.result)."""
    return f"{RESULTS}/{venue_id}/{job_id}.json"


def job_doc(r: dict[str, Any]) -> dict[str, Any]:
    done, total, fps = r["frames_done"], r["frames_total"], r["fps"]
    eta = (total - done) / fps if r["state"] == "running" and fps > 0 and total >= done else None
    retry_at = r["not_before"] if r["state"] == "queued" and r["not_before"] else None
    return {
        "id": r["id"],
        "venue": r["venue"],
        "kind": r["kind"],
        "target": r["target"],  # the video of a suggest or evaluate job
        "anew": bool(r["anew"]),  # a modelling anew: every modelling video, the preset's settings now
        "videos": json.loads(r["videos"]),
        "state": r["state"],
        "frames_done": done,
        "frames_total": total,
        "frames_per_s": round(fps, 2),
        "eta_s": round(eta, 1) if eta is not None else None,
        "created": r["created"],
        "started": r["started"],
        "finished": r["finished"],
        "attempts": r["attempts"],
        "max_attempts": MAX_ATTEMPTS,
        "retry_at": retry_at,
        "error": r["error"],  # the last error: on a job queued again, why its last attempt ended
        "result_url": f"/api/admin/jobs/{r['id']}/result" if r["state"] == "done" and r["result"] else None,
    }


def _write_beside(path: Path, text: str) -> Path:
    """A job's result written beside its place (store.write_beside), its folder made first."""
    path.parent.mkdir(parents=True, exist_ok=True)
    return write_beside(path, text)


def failure(e: BaseException, kind: str = "model") -> tuple[str, bool]:
    """A job's error line for an exception, and whether another attempt may succeed.

    Bad input (OmninavError) fails at once; a full disk and other faults of the
    machine (OSError) are worth another attempt; anything else is a bug, which would only repeat."""
    if isinstance(e, OmninavError):
        return str(e), False
    if isinstance(e, OSError) and e.errno in DISK_FULL:
        what = os.strerror(e.errno).lower()
        if kind != "model":
            return f"disk full ({what}) while writing the job's result", True
        return f"disk full ({what}) while writing the venue's new frames; the venue kept its previous frames", True
    # the admin sees the kind of fault, never a path on the server (the log has the whole exception)
    if isinstance(e, OSError):
        return f"could not read or write the venue's files ({e.strerror or type(e).__name__})", True
    return f"internal error ({type(e).__name__}); it has been logged", False


class Jobs:
    # the WHERE of every write a runner makes to its job: 0 rows means it was taken over (Lost)
    _MINE = "id = :id AND owner = :o AND state = 'running'"

    def __init__(self, catalog: Catalog, stale_s: float = 30.0, device: str | None = None):
        self.cat = catalog
        self.db = catalog.db
        self.stale_s = stale_s
        self.device = device  # the search's array device for quality and evaluate jobs (config DEVICE)
        self.me = this_process()
        self.wake = threading.Event()
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None

    # ---- API side -----------------------------------------------------------------------------
    def get(self, job_id: str) -> dict[str, Any]:
        self.reap()
        row = self.db.one("SELECT * FROM jobs WHERE id = :id", id=job_id)
        if row is None:
            raise NotFound(f"unknown job {job_id!r}")
        return row

    def for_venue(self, venue_id: str) -> list[dict[str, Any]]:
        self.cat.venues.get(venue_id)
        self.reap()
        return self.db.all("SELECT * FROM jobs WHERE venue = :v ORDER BY created DESC", v=venue_id)

    def submit(self, venue_id: str, names: Any, anew: bool = False) -> dict[str, Any]:
        """Queue a modelling job (`anew`: every modelling video, with the venue's preset as this
        server defines it now; see model_venue.model_videos). The database's
        one-active-job-per-venue index decides between simultaneous submissions: checking first
        and inserting after would let two through."""
        self.cat.venues.get(venue_id)
        self.reap()
        names = videos_to_model(self.cat, venue_id, names, anew)
        job_id = uuid.uuid4().hex[:16]
        for _ in range(3):
            try:
                with self.db.tx() as c:  # the job and the rows that say which videos it models
                    c.execute(
                        text(
                            "INSERT INTO jobs (id, venue, videos, state, created, anew) "
                            "VALUES (:id, :v, :vs, 'queued', :t, :a)"
                        ),
                        {"id": job_id, "v": venue_id, "vs": json.dumps(names), "t": time.time(), "a": int(anew)},
                    )
                    c.execute(
                        text("INSERT INTO job_videos (job, venue, video) VALUES (:j, :v, :n)"),
                        [{"j": job_id, "v": venue_id, "n": n} for n in names],
                    )
                break
            except IntegrityError:
                self._busy(venue_id, "model", None)
                # the active job ended between our insert and this look: try again
        else:
            raise Conflict(f"venue {venue_id!r} is busy with other modelling jobs; try again")
        self.wake.set()
        return self.get(job_id)

    def submit_analysis(self, venue_id: str, kind: str, target: str | None = None) -> dict[str, Any]:
        """Queue a suggest, quality or evaluate job (on video `target` for suggest and evaluate),
        once what it needs is there: the video uploaded (and, to evaluate, an evaluation walk with
        a walk path), the venue modelled (quality, evaluate)."""
        self.cat.venues.get(venue_id)
        self.reap()
        check_analysis(self.cat, venue_id, kind, target)
        job_id = uuid.uuid4().hex[:16]
        row = {
            "id": job_id,
            "v": venue_id,
            "vs": json.dumps([target] if target else []),
            "t": time.time(),
            "k": kind,
            "g": target,
        }
        for _ in range(3):
            try:
                self.db.run(
                    "INSERT INTO jobs (id, venue, videos, state, created, kind, target) "
                    "VALUES (:id, :v, :vs, 'queued', :t, :k, :g)",
                    **row,
                )
                break
            except IntegrityError:
                self._busy(venue_id, kind, target)
        else:
            raise Conflict(f"venue {venue_id!r} is busy with other jobs; try again")
        self.wake.set()
        return self.get(job_id)

    def _busy(self, venue_id: str, kind: str, target: str | None) -> None:
        """After the one-active-job indexes refused an insert: say which job is in the way (the
        same kind on the same target first). Returns when it has ended meanwhile."""
        rows = self.db.all(
            "SELECT id, kind, target FROM jobs WHERE venue = :v AND state IN ('queued', 'running') ORDER BY created",
            v=venue_id,
        )
        same = [r for r in rows if r["kind"] == kind and (kind == "model" or r["target"] == target)]
        for r in same or rows:
            if r["kind"] == "model" and kind == "model":
                raise Conflict(f"venue {venue_id!r} is already being modelled by job {r['id']}")
            raise Conflict(
                f"venue {venue_id!r} is busy {doing(r['kind'], r['target'])} (job {r['id']}); "
                "try again when that job has ended",
                job=r["id"],
            )

    def cancel(self, job_id: str) -> dict[str, Any]:
        row = self.get(job_id)
        if row["state"] in FINAL:
            raise Conflict(f"job {job_id} has already ended ({row['state']})")
        now = time.time()
        # a queued job ends here; a running one is stopped by its runner at its next frame
        self.db.run(
            "UPDATE jobs SET state = 'cancelled', finished = :t, cancel = 1 WHERE id = :id AND state = 'queued'",
            id=job_id,
            t=now,
        )
        self.db.run("UPDATE jobs SET cancel = 1 WHERE id = :id AND state = 'running'", id=job_id)
        return self.get(job_id)

    def latest_done(self, venue_id: str, kind: str, target: str | None = None) -> dict[str, Any] | None:
        """The venue's most recently finished job of `kind` (on video `target`) that has a result.
        On a video: only a job started since the video was registered (a video deleted and
        registered again under its name is another walk, and the old one's results are not its)."""
        self.cat.venues.get(venue_id)
        on = (
            "AND target = :g AND created >= (SELECT created FROM videos WHERE venue = :v AND name = :g)"
            if target is not None
            else ""
        )
        return self.db.one(
            f"SELECT * FROM jobs WHERE venue = :v AND kind = :k {on} AND state = 'done' AND result IS NOT NULL "
            "ORDER BY finished DESC, created DESC LIMIT 1",
            v=venue_id,
            k=kind,
            g=target,
        )

    def result_path(self, row: dict[str, Any]) -> Path:
        """The result file of a job: NotFound for a modelling job (its result is the venue's
        frames) and where it is gone, Conflict while the job has not ended well."""
        if row["kind"] == "model":
            raise NotFound(f"job {row['id']} is a modelling job: its result is the venue's frames, not a file")
        if row["state"] != "done":
            raise Conflict(f"job {row['id']} is {row['state']}: a result comes once it is done")
        path = self.cat.data / (row["result"] or "")
        if not row["result"] or not path.is_file():
            raise NotFound(f"the result of job {row['id']} is gone (its venue or video was deleted)")
        return path

    def reap(self) -> int:
        """Take back the jobs whose runner died: queue them again (after a backoff) or, after
        MAX_ATTEMPTS, fail them. Returns how many. Safe to run in many processes at once: each
        update names the owner it saw, so a job another runner has claimed since is left alone."""
        n = 0
        now = time.time()
        for r in self.db.all("SELECT id, kind, owner, heartbeat, attempts, cancel FROM jobs WHERE state = 'running'"):
            alive = owner_alive(r["owner"] or "")
            if alive is None:
                alive = (r["heartbeat"] or 0) > now - self.stale_s
            if alive:
                continue
            if r["cancel"]:  # cancelled while it ran: its runner's death ends it as asked
                n += self.db.run(
                    "UPDATE jobs SET state = 'cancelled', finished = :t WHERE id = :id AND state = 'running' "
                    "AND owner = :o",
                    t=now,
                    id=r["id"],
                    o=r["owner"],
                )
            else:
                why = STOPPED if r["kind"] == "model" else "the server stopped while this job ran"
                n += self._end_attempt(r["id"], r["owner"], r["attempts"], why, retry=True)
        return n

    def _end_attempt(self, job_id: str, owner: str | None, attempts: int, error: str, retry: bool) -> int:
        """Queue the job again with a backoff, or fail it when it may not be retried; only while
        it is still running under `owner`. Returns 1 if this call changed it."""
        now = time.time()
        if retry and attempts < MAX_ATTEMPTS:
            wait = backoff_s(attempts)
            line = f"{error} (attempt {attempts} of {MAX_ATTEMPTS}; trying again in {wait:g} s)"
            sql = "UPDATE jobs SET state = 'queued', owner = NULL, not_before = :nb, error = :e"
            params: dict[str, Any] = {"nb": now + wait}
        else:
            line = f"{error} (attempt {attempts} of {MAX_ATTEMPTS})" if retry else error
            sql = "UPDATE jobs SET state = 'failed', finished = :t, error = :e"
            params = {"t": now}
            if retry:
                line += ". Start the job again."
        owner_is = "owner = :o" if owner is not None else "owner IS NULL"
        got = self.db.run(
            f"{sql} WHERE id = :id AND state = 'running' AND {owner_is}",
            id=job_id,
            o=owner,
            e=line,
            **params,
        )
        if got:
            log.warning("job %s: %s", job_id, line)
        return got

    # ---- runner side --------------------------------------------------------------------------
    def start(self) -> None:
        """Run jobs in a background thread of this process (create_app with JOB_RUNNER); again
        after stop()."""
        self._stop.clear()
        self.reap()
        self._thread = threading.Thread(target=self._loop, name="omninav-jobs", daemon=True)
        self._thread.start()

    def run_forever(self) -> None:
        """Run jobs in the calling thread until stop() (a dedicated job-runner process)."""
        self.reap()
        self._loop()

    def stop(self, wait_s: float = 0.0) -> None:
        """Stop the runner after its current job; wait up to wait_s for the thread to end."""
        self._stop.set()
        self.wake.set()
        t = self._thread
        if wait_s > 0 and t is not None and t is not threading.current_thread():
            t.join(wait_s)

    def _loop(self) -> None:
        while not self._stop.is_set():
            try:
                self.reap()  # a job whose runner died is taken over here, by whichever runner looks
                while self.run_next() and not self._stop.is_set():
                    pass
            except Exception:  # the runner must outlive any one job's bug, and a database outage
                log.exception("job runner")
            self.wake.wait(POLL_S)
            self.wake.clear()

    def claim(self) -> dict[str, Any] | None:
        """Take the oldest queued job that is due; the UPDATE's state check makes it ours alone."""
        now = time.time()
        due = self.db.all(
            "SELECT id FROM jobs WHERE state = 'queued' AND (not_before IS NULL OR not_before <= :t) ORDER BY created",
            t=now,
        )
        for r in due:
            t = time.time()
            got = self.db.run(
                "UPDATE jobs SET state = 'running', owner = :o, started = :t, heartbeat = :t, "
                "attempts = attempts + 1, not_before = NULL, frames_done = 0, fps = 0 "
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
                try:
                    self.db.run(
                        f"UPDATE jobs SET heartbeat = :t WHERE {self._MINE}",
                        t=time.time(),
                        id=job["id"],
                        o=self.me,
                    )
                except Exception:  # a database hiccup: the next beat tries again
                    log.exception("job %s heartbeat", job["id"])

        hb = threading.Thread(target=beat, daemon=True)
        hb.start()
        try:
            self._run(job)
        finally:
            beat_stop.set()
        return True

    def _progress(self, jid: str) -> Progress:
        """The engine's progress callback for job `jid`: writes frames done/total and the rate
        (at most every PROGRESS_EVERY_S), and stops the work where the job was cancelled
        (Cancelled) or taken over by another runner (Lost)."""
        last = 0.0

        def progress(done: int, total: int, elapsed: float) -> None:
            nonlocal last
            now = time.monotonic()
            if now - last < PROGRESS_EVERY_S and done < total:
                return
            last = now
            got = self.db.run(
                f"UPDATE jobs SET frames_done = :d, frames_total = :n, fps = :f, heartbeat = :t WHERE {self._MINE}",
                d=done,
                n=total,
                f=done / max(elapsed, 1e-9),
                t=time.time(),
                id=jid,
                o=self.me,
            )
            if not got:  # taken over: the row and its heartbeat are the new owner's now
                raise Lost
            self._check_cancel(jid)

        return progress

    def _check_cancel(self, jid: str) -> None:
        row = self.db.one("SELECT cancel FROM jobs WHERE id = :id", id=jid)
        if row is None:
            raise Lost
        if row["cancel"]:
            raise Cancelled

    def _run(self, job: dict[str, Any]) -> None:
        if job["kind"] == "model":
            self._run_model(job)
        else:
            self._run_analysis(job)

    def _run_model(self, job: dict[str, Any]) -> None:
        jid, venue = job["id"], job["venue"]
        progress = self._progress(jid)

        def still_mine() -> None:  # under the venue's lock, just before the commit
            if self.db.one(f"SELECT id FROM jobs WHERE {self._MINE}", id=jid, o=self.me) is None:
                raise Lost

        results = None
        try:
            sources = self.cat.videos.sources(venue, json.loads(job["videos"]))
            anew = bool(job["anew"])
            # anew: the preset as this server defines it now, not the live generation's settings
            settings = self.cat.venues.preset_settings(venue) if anew else self.cat.venues.settings(venue)
            results = model_videos(self.cat.store, venue, sources, progress, still_mine, settings, anew)
            self._done(jid, venue, results, anew)
        except Lost:
            log.warning("job %s was taken over by another runner; this one stops", jid)
            if results is not None:  # lost after its commit: the venue did change, say so to caches
                self.cat.venues.touch(venue)
            return
        except Cancelled:
            self._finish(jid, "cancelled")
        except Exception as e:
            error, retry = failure(e)
            if not isinstance(e, OmninavError):
                log.exception("job %s", jid)  # a fault or a bug: the admin gets a line, the log the rest
            if isinstance(e, OSError):
                self._drop_leftovers(venue)
            self._end_attempt(jid, self.me, job["attempts"], error, retry)  # a retry: the loop's poll finds it
        self.cat.venues.touch(venue)

    def _run_analysis(self, job: dict[str, Any]) -> None:
        """A suggest, quality or evaluate job: the engine's function, then its result written
        beside its final place and renamed there in the transaction that marks the job done."""
        jid, venue, kind = job["id"], job["venue"], job["kind"]
        tmp: Path | None = None
        try:
            result = analyse(self.cat, job, self._progress(jid), self.device)
            self._check_cancel(jid)  # a cancel that came after the engine's last progress call
            rel = result_file(venue, jid)
            result = plain(result)
            tmp = _write_beside(self.cat.data / rel, json.dumps(result, allow_nan=False))
            self._done_analysis(job, rel, tmp, result)
        except Lost:
            log.warning("job %s was taken over by another runner; this one stops", jid)
        except Cancelled:
            self._finish(jid, "cancelled")
        except Exception as e:
            error, retry = failure(e, kind)
            if not isinstance(e, OmninavError):
                log.exception("job %s", jid)
            self._end_attempt(jid, self.me, job["attempts"], error, retry)
        finally:
            if tmp is not None:  # not renamed into place: this attempt publishes nothing
                tmp.unlink(missing_ok=True)

    def _done_analysis(self, job: dict[str, Any], rel: str, tmp: Path, result: dict[str, Any]) -> None:
        """The job done with its result, in one transaction that is also the last ownership check:
        the file is renamed into place only while this runner still owns the job (a takeover's
        UPDATE waits for this transaction), so a runner taken over publishes nothing."""
        mine = {"t": time.time(), "id": job["id"], "o": self.me, "r": rel}
        with self.db.tx() as c:
            # done is all of it, whether or not the engine's last progress call said so; a cancel
            # that came after the engine's last progress call still wins (the admin was told 202)
            sql = (
                "UPDATE jobs SET state = 'done', finished = :t, result = :r, frames_done = frames_total "
                f"WHERE {self._MINE} AND cancel = 0"
            )
            if not c.execute(text(sql), mine).rowcount:
                # leaving the block this way rolls the transaction back
                owned = c.execute(text(f"SELECT id FROM jobs WHERE {self._MINE}"), mine).first()
                raise Cancelled if owned is not None else Lost
            if job["kind"] == "suggest":  # on the video in the same transaction as "done"
                self.cat.videos.set_suggestions(job["venue"], job["target"], result, c)
            os.replace(tmp, self.cat.data / rel)
        log.info("job %s done", job["id"])

    def _done(self, jid: str, venue: str, results: list[Any], anew: bool = False) -> None:
        """Record a committed job: the job done and its videos modelled, in one transaction that
        is also the last ownership check (a runner taken over after its commit writes no row;
        the new owner models the videos again and records them). After a modelling anew, a video
        that was modelled and is not in the new generation has no frames any more."""
        mine = {"t": time.time(), "id": jid, "o": self.me}
        with self.db.tx() as c:
            if not c.execute(text(f"UPDATE jobs SET state = 'done', finished = :t WHERE {self._MINE}"), mine).rowcount:
                raise Lost  # leaving the block this way rolls the transaction back
            if anew:  # the new generation holds the job's videos only
                Videos.forget_frames(c, venue)
            Videos.mark_modelled(c, venue, results)
        log.info("job %s done", jid)

    def _finish(self, jid: str, state: str) -> None:
        """The job's end, recorded only while this runner still owns it. It keeps the error of an
        earlier attempt: the admin sees why it needed more than one."""
        self.db.run(
            f"UPDATE jobs SET state = :s, finished = :t WHERE {self._MINE}", s=state, t=time.time(), id=jid, o=self.me
        )
        log.info("job %s %s", jid, state)

    def _drop_leftovers(self, venue: str) -> None:
        """A commit that failed half-way (a full disk) left a temporary generation: remove it now,
        so the space comes back before the retry, not at the next commit."""
        try:
            with self.cat.store.lock(venue):
                if gone := self.cat.store.recover(venue):
                    log.info("job on %s: dropped %s", venue, ", ".join(gone))
        except OSError:
            log.exception("dropping what a failed commit left in %s", venue)
