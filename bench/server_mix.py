"""`locate` under the real mix: phones in continuous mode, presses, a video upload, a modelling job,
and slow clients, against `omninav serve` as `npm start` runs it (issue 9).

Uses server_load.py's 8,000-frame venue, server start and latency summary. Phases, one server, one
run, each `--seconds` long (latency counts from each request's scheduled send time: open loop):

  (a)  the mix alone: 100 phones in continuous mode, each its own keep-alive connection and a locate
       every 3 s (random phase), plus 20 presses per second (Poisson arrivals, each press a new
       connection, as a phone that was not connected);
  (b)  the mix while a 10-minute 960x720 30 fps video uploads through the admin API in 8 MiB
       Content-Range pieces at full speed (again and again) and a modelling job runs (the demo
       venue's real walk, registered under several names, so it models real frames for the whole
       phase); the job's frames/s over the phase;
  (c)  the mix with 50 slow clients (a locate head, then its body one byte a second), 50 idle
       connections (nothing sent) held open, each reconnecting as soon as the server drops it, and
       8 job-event streams of the admin page (`--streams`) open on a job held queued;
  (a') the mix alone again: the noise band of (a), and (c)'s neighbour in time.

`--tracked` makes the phones what the app's phones are since tracking (issue 14): in "Keep telling
me", each in its own tracking session (`?session=&t=&steps=&turn_deg=`), a 1 s record first and a
2 s one (20 frames, ~15 KB) every `--period` (4 s: a turn films 2 s, then waits) after it;
`--guided` more phones guided to a place (`&to=`, the route guide too), a 2 s record every 2.5 s.
The presses stay plain 1 s clips. A first phase, (p), runs the plain mix of before on the same
server, as the baseline of the same run. What it does not imitate: every phone sends the same
clip (it never moves, while its steps say it walks), and no phone ever turns.

Every phone connects from a loopback address of its own (127.1.x.y), each press from another
(127.2.x.y), the slow and idle clients from ten addresses each (127.3.x.y, 127.4.x.y), as phones on
a building's Wi-Fi have addresses of their own: nginx limits requests in progress per address
(CLIENT_REQUESTS). The per-client locate limit is off (OMNINAV_LOCATE_RATE=0): a phone's tracked
requests stay under it, but the presses' addresses are reused across phases. The client runs on the
same machine.

    python -m bench.server_mix [--seconds 40] [--phones 100] [--presses 20] [--slow 50] [--idle 50]
                               [--streams 8] [--tracked [--period 4] [--guided 20]]
"""

from __future__ import annotations

import argparse
import http.client
import json
import math
import os
import select
import socket
import threading
import time
from collections import Counter
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from bench.common import machine
from bench.server_load import REPO, load, query_spectra, start_server, summary
from omninav.spectrum import encode_binary
from omninav.store import Store
from omninav.synth import upgrade_names

LOCATE = "/api/venues/bench8k/locate"
GOAL = "Goal"  # the place guided phones walk to (set on the bench venue by `main`)
PLAIN_PERIOD = 3.0  # s between a plain continuous-mode phone's locates (the app before tracking)
KEEP_PERIOD = 4.0  # s between "Keep telling me"'s tracked locates (2 s filmed, then 2 s waited)
GUIDED_PERIOD = 2.5  # s between a guided phone's locates (2 s filmed, the answer, the next)
RUN = f"mix{os.getpid():x}{int(time.time()) % 100000:05d}"  # this run's session ids' prefix
STEP_HZ = 1.8  # a walker's steps a second, sent with each tracked request as the app sends its count
JOB_VENUE = "mixjob"
AUTH = {"Authorization": "Bearer bench"}
PIECE = 8 << 20  # upload piece, as bench/model_speed.py
SRC = REPO / "data" / "demo-src"


# ---- the mix: phones and presses ----------------------------------------------------------------
class Record:
    """The outcome of every locate in one phase: latency (ms, from the scheduled time) or failure."""

    def __init__(self) -> None:
        self.lock = threading.Lock()
        self.ms: list[float] = []
        self.due: list[float] = []  # when each of them was due (perf_counter)
        self.failures: Counter[str] = Counter()
        self.first_error: dict[int, str] = {}  # status: the first answer's error of that status

    def done(self, due: float, answer: tuple[int, bytes]) -> None:
        status, body = answer
        with self.lock:
            if status == 200:
                self.ms.append((time.perf_counter() - due) * 1e3)
                self.due.append(due)
            else:
                self.failures[f"HTTP {status}"] += 1
                self.first_error.setdefault(status, body[:300].decode("utf-8", "replace"))

    def failed(self, why: str) -> None:
        with self.lock:
            self.failures[why] += 1


def address(group: int, i: int) -> str:
    """The i-th loopback address of a group of clients (Linux routes all of 127/8 to loopback)."""
    return f"127.{group}.{i // 250}.{i % 250 + 1}"


def connect(port: int, source: str, timeout: float = 30) -> http.client.HTTPConnection:
    return http.client.HTTPConnection("127.0.0.1", port, timeout=timeout, source_address=(source, 0))


def _locate(c: http.client.HTTPConnection, body: bytes, close: bool = False, query: str = "") -> tuple[int, bytes]:
    headers = {"Content-Type": "application/octet-stream"}
    if close:
        headers["Connection"] = "close"
    c.request("POST", LOCATE + query, body=body, headers=headers)
    r = c.getresponse()
    return r.status, r.read()


@dataclass(frozen=True)
class Bodies:
    """The records a phase sends: a press's (and a plain phone's) 1 s clip, a tracked phone's 2 s."""

    one: bytes
    two: bytes
    tracked: bool = False  # the phones track (Keep telling me), each in its own session
    guided: int = 0  # phones guided to GOAL besides


def _sleep_until(due: float) -> None:
    wait = due - time.perf_counter()
    if wait > 0:
        time.sleep(wait)


def _phone(
    port: int, source: str, bodies: list[bytes], dues: list[float], rec: Record, session: str = "", to: str = ""
) -> None:
    """One phone in continuous mode: its own address and keep-alive connection, a locate at each
    due time. With a `session`, it tracks (the app's "Keep telling me", or guided `to` a place): `t`
    is its clock; the first request sends bodies[0], the rest bodies[-1]."""
    c = connect(port, source)
    for k, due in enumerate(dues):
        _sleep_until(due)
        query = ""
        if session:
            # the app's motion since its last request too: steps at ~1.8 a second, no turn
            steps = round(STEP_HZ * (due - dues[k - 1])) if k else 0
            query = f"?session={session}&t={due - dues[0] + 1.0:.2f}&steps={steps}&turn_deg=0" + (
                f"&to={to}" if to else ""
            )
        try:
            rec.done(due, _locate(c, bodies[min(k, len(bodies) - 1)], query=query))
        except (OSError, http.client.HTTPException) as e:
            rec.failed(type(e).__name__)
            c.close()  # the next request connects again
    c.close()


def _presser(port: int, body: bytes, dues: list[float], nxt: list[int], lock: threading.Lock, rec: Record) -> None:
    """Takes the next due press from the shared schedule; each press is a new connection."""
    while True:
        with lock:
            i = nxt[0]
            nxt[0] += 1
        if i >= len(dues):
            return
        _sleep_until(dues[i])
        c = connect(port, address(2, i % 5000))
        try:
            rec.done(dues[i], _locate(c, body, close=True))
        except (OSError, http.client.HTTPException) as e:
            rec.failed(type(e).__name__)
        finally:
            c.close()


def run_mix(port: int, b: Bodies, a: argparse.Namespace, seed: int) -> dict[str, Any]:
    """One phase of the mix, open loop; -> latency summary, counts and failures."""
    rng = np.random.default_rng(seed)
    t0 = time.perf_counter() + 0.5
    end = t0 + a.seconds
    period = a.period or (KEEP_PERIOD if b.tracked else PLAIN_PERIOD)

    def dues(every: float) -> list[float]:
        return [float(t) for t in np.arange(t0 + rng.uniform(0, every), end, every)]

    phones = [dues(period) for _ in range(a.phones)]
    guided = [dues(GUIDED_PERIOD) for _ in range(b.guided)]
    gaps = rng.exponential(1.0 / a.presses, int(a.presses * a.seconds * 1.5) + 10) if a.presses else []
    presses = [float(t) for t in t0 + np.cumsum(gaps) if t < end]
    rec = Record()
    lock, nxt = threading.Lock(), [0]
    # a session id per phone, phase and run: every phase's phones are new walks (a session of an
    # earlier run, still alive in the database, would be resumed with its clock gone back)
    keep = [b.one, b.two] if b.tracked else [b.one]
    run = f"{RUN}-{seed}"
    ts = [
        threading.Thread(
            target=_phone, args=(port, address(1, i), keep, d, rec, f"{run}-keep-{i:04d}" if b.tracked else "")
        )
        for i, d in enumerate(phones)
    ]
    ts += [
        threading.Thread(
            target=_phone, args=(port, address(1, len(phones) + i), [b.two], d, rec, f"{run}-guided-{i:04d}", GOAL)
        )
        for i, d in enumerate(guided)
    ]
    ts += [threading.Thread(target=_presser, args=(port, b.one, presses, nxt, lock, rec)) for _ in range(8)]
    for t in ts:
        t.start()
    for t in ts:
        t.join()
    n = sum(map(len, phones)) + sum(map(len, guided)) + len(presses)
    ms = np.array(rec.ms) if rec.ms else np.array([math.nan])
    worst = np.argsort(ms)[::-1][:5] if rec.ms else []
    return {
        "n": n,
        "ok": len(rec.ms),
        "failures": dict(rec.failures),
        "first_error": rec.first_error,
        **summary(ms),
        "load": os.getloadavg()[0],
        "t0": t0,
        "slowest": [(round(rec.due[i] - t0, 1), round(float(ms[i]))) for i in worst],  # (s into the phase, ms)
    }


# ---- admin calls ---------------------------------------------------------------------------------
class Admin:
    """The admin API over one keep-alive connection; an error answer raises with its one line."""

    def __init__(self, port: int):
        self.port = port
        self.c = http.client.HTTPConnection("127.0.0.1", port, timeout=120)
        self.status = 0  # of the last answer

    def call(self, method: str, path: str, body: Any = None, headers: dict | None = None, ok=(200, 201, 202)) -> Any:
        h = {**AUTH, **(headers or {})}
        if isinstance(body, dict | list):
            body, h["Content-Type"] = json.dumps(body).encode(), "application/json"
        for again in (True, False):
            try:
                self.c.request(method, path, body=body, headers=h)
                r = self.c.getresponse()
                raw = r.read()
                break
            except (http.client.RemoteDisconnected, BrokenPipeError, ConnectionResetError):
                self.c.close()  # a kept-alive connection the server closed while it sat idle: once more
                if not again:
                    raise
            except (OSError, http.client.HTTPException):
                self.c.close()
                raise
        self.status = r.status
        doc = json.loads(raw) if raw else {}
        if r.status not in ok:
            raise RuntimeError(f"{method} {path}: {r.status} {doc.get('error', raw[:200])}")
        return doc

    def upload(self, venue: str, name: str, video: Path, walk_path: dict, stop: threading.Event | None = None) -> int:
        """Announce the video and send it in Content-Range pieces; -> bytes sent (less when stopped)."""
        size = video.stat().st_size
        v = self.call("POST", f"/api/admin/venues/{venue}/videos", {"name": name, "size": size, "walk_path": walk_path})
        sent = 0
        with open(video, "rb") as f:
            while sent < size and not (stop and stop.is_set()):
                piece = f.read(PIECE)
                rng = f"bytes {sent}-{sent + len(piece) - 1}/{size}"
                self.call(
                    "PUT", v["upload_url"], piece, {"Content-Range": rng, "Content-Type": "application/octet-stream"}
                )
                sent += len(piece)
        return sent


def job_venue(adm: Admin, copies: int) -> list[str]:
    """The venue the modelling job works on (made once): the demo's plan, lens and `copies` uploads
    of its real modelling walk under different names; -> their names."""
    adm.call("POST", "/api/admin/venues", {"id": JOB_VENUE, "name": "bench: modelling job"}, ok=(201, 409))
    if adm.status == 201:
        adm.call("PUT", f"/api/admin/venues/{JOB_VENUE}/floors/1/plan", (SRC / "floorplan.png").read_bytes(),
                 {"Content-Type": "image/png"})  # fmt: skip
        adm.call("PUT", f"/api/admin/venues/{JOB_VENUE}/floors/1", {"px_per_m": 20.0})
        adm.call(
            "PUT", f"/api/admin/venues/{JOB_VENUE}/lenses/default", json.loads((SRC / "model_lens.json").read_text())
        )
    have = {v["name"]: v["status"] for v in adm.call("GET", f"/api/admin/venues/{JOB_VENUE}/videos")["videos"]}
    walk_path = json.loads((upgrade_names(SRC) / "model_walk_path.json").read_text())
    names = [f"walk{k}.mp4" for k in range(1, copies + 1)]
    for n in names:
        if have.get(n) not in ("ready", "modelled"):
            if n in have:
                adm.call("DELETE", f"/api/admin/venues/{JOB_VENUE}/videos/{n}")
            adm.upload(JOB_VENUE, n, SRC / "model.mp4", walk_path)
    for j in adm.call("GET", f"/api/admin/venues/{JOB_VENUE}/jobs")["jobs"]:  # a run cut short left one?
        if j["state"] in ("queued", "running"):
            adm.call("POST", f"/api/admin/jobs/{j['id']}/cancel")
    return names


class JobDriver(threading.Thread):
    """Keeps a modelling job running on JOB_VENUE (a new one when one ends) and samples its progress:
    (time, frames modelled so far by all its jobs)."""

    def __init__(self, port: int, videos: list[str]):
        super().__init__(daemon=True)
        self.adm, self.videos = Admin(port), videos
        self.stop = threading.Event()
        self.samples: list[tuple[float, int]] = []
        self.jobs = 0
        self.errors: list[str] = []
        self.job: dict = {}

    def submit(self) -> None:
        self.job = self.adm.call("POST", f"/api/admin/venues/{JOB_VENUE}/jobs", {"videos": self.videos})
        self.jobs += 1

    def run(self) -> None:
        try:
            self._drive()
        except (OSError, http.client.HTTPException, RuntimeError) as e:
            self.errors.append(f"driving the job: {e}")

    def _drive(self) -> None:
        base = 0
        while not self.stop.is_set():
            j = self.adm.call("GET", f"/api/admin/jobs/{self.job['id']}")
            self.samples.append((time.perf_counter(), base + j["frames_done"]))
            if j["state"] not in ("queued", "running"):
                if j["state"] != "done":
                    self.errors.append(f"job {j['state']}: {j['error']}")
                base += j["frames_done"]
                self.submit()
            self.stop.wait(0.5)
        j = self.adm.call("POST", f"/api/admin/jobs/{self.job['id']}/cancel", ok=(202, 409))
        for _ in range(120):  # a running job stops at its next frame
            if j["state"] not in ("queued", "running"):
                break
            time.sleep(0.25)
            j = self.adm.call("GET", f"/api/admin/jobs/{self.job['id']}")

    def started(self, timeout: float = 120.0) -> None:
        """Wait until the job models frames, so the phase measures a job at work, not one opening."""
        t = time.perf_counter()
        while not (self.samples and self.samples[-1][1] > 0):
            if time.perf_counter() - t > timeout or not self.is_alive():
                raise SystemExit(f"the modelling job did not start: {'; '.join(self.errors) or 'in 2 minutes'}")
            time.sleep(0.2)

    def frames_between(self, t0: float, t1: float) -> float:
        ts, fs = zip(*self.samples, strict=True)
        return float(np.interp(t1, ts, fs) - np.interp(t0, ts, fs))


class Uploader(threading.Thread):
    """The 10-minute video, uploaded again and again at full speed until stopped (each copy deleted
    once complete, the last, partial one at the end)."""

    def __init__(self, port: int, video: Path):
        super().__init__(daemon=True)
        self.adm, self.video = Admin(port), video
        self.walk_path = json.loads((upgrade_names(SRC) / "model_walk_path.json").read_text())
        self.stop = threading.Event()
        self.sent = 0
        self.complete = 0
        self.errors: list[str] = []
        self.took = 0.0

    def run(self) -> None:
        t, k = time.perf_counter(), 0
        while not self.stop.is_set():
            name = f"upload-{os.getpid()}-{k}.mp4"
            try:
                got = self.adm.upload(JOB_VENUE, name, self.video, self.walk_path, self.stop)
                self.sent += got
                self.complete += got == self.video.stat().st_size
            except (OSError, http.client.HTTPException, RuntimeError) as e:
                self.errors.append(str(e))
                self.adm = Admin(self.adm.port)
            finally:
                self.took = time.perf_counter() - t
                try:
                    self.adm.call("DELETE", f"/api/admin/venues/{JOB_VENUE}/videos/{name}", ok=(200, 404))
                except (OSError, http.client.HTTPException, RuntimeError) as e:
                    self.errors.append(str(e))
            k += 1


def long_video(minutes: float) -> Path:
    """A `minutes`-long 960x720 30 fps MPEG-4 video (made once): the demo's modelling walk, decoded
    again and again and encoded at 30 fps, so its bytes are a real video's, not a repeated frame's."""
    out = REPO / "data" / "bench-server" / f"upload-{minutes:g}min.mp4"
    if out.exists():
        return out
    from omninav.synth.walks import write_video

    n, t = int(minutes * 60 * 30), time.perf_counter()

    def frames():
        made = 0
        while True:
            cap = cv2.VideoCapture(str(SRC / "model.mp4"))
            while made < n:
                ok, f = cap.read()
                if not ok:
                    break
                made += 1
                yield f
            cap.release()
            if made >= n:
                return

    tmp = out.with_suffix(".tmp.mp4")
    write_video(tmp, frames(), 30.0, (960, 720))
    tmp.replace(out)
    print(f"made {out.name}: {n} frames, {out.stat().st_size / 1e6:.0f} MB in {time.perf_counter() - t:.0f} s")
    return out


# ---- clients held open: slow ones, idle ones, job-event streams -----------------------------------
class HeldClients:
    """Threads that each hold a connection open until `finish`, counting how many are open twice a
    second; a subclass gives the threads' work."""

    def __init__(self) -> None:
        self.stop = threading.Event()
        self.lock = threading.Lock()
        self.open = 0
        self.counts: list[int] = []  # connections open, sampled twice a second
        self.threads = [threading.Thread(target=self._count, daemon=True)]

    def start(self) -> None:
        for t in self.threads:
            t.start()

    def finish(self) -> None:
        self.stop.set()
        for t in self.threads:
            t.join()

    def _count(self) -> None:
        while not self.stop.wait(0.5):
            self.counts.append(self.open)


class SlowClients(HeldClients):
    """`slow` connections that send a locate's head and then one byte of its body a second, and `idle`
    ones that send nothing; each opens again as soon as the server drops it (what an attacker does)."""

    def __init__(self, port: int, slow: int, idle: int):
        super().__init__()
        self.port = port
        self.head = (
            f"POST {LOCATE} HTTP/1.1\r\nHost: 127.0.0.1\r\nContent-Type: application/octet-stream\r\n"
            "Content-Length: 7700\r\n\r\n"
        ).encode()
        self.answers: Counter[str] = Counter()  # how the server ended each connection
        self.held: list[float] = []  # seconds each connection was held open by the server
        self.ended: list[float] = []  # when (perf_counter)
        self.threads += [threading.Thread(target=self._client, args=(True, k), daemon=True) for k in range(slow)]
        self.threads += [threading.Thread(target=self._client, args=(False, k), daemon=True) for k in range(idle)]

    @staticmethod
    def source(slow: bool, k: int) -> str:
        return address(3 if slow else 4, k % 10)  # ten addresses each: five connections an address

    def _client(self, slow: bool, k: int) -> None:
        self.stop.wait(k / 50)  # spread the starts over a second or two
        while not self.stop.is_set():
            try:
                s = socket.create_connection(("127.0.0.1", self.port), 5, (self.source(slow, k), 0))
            except OSError as e:
                with self.lock:
                    self.answers[f"connect: {type(e).__name__}"] += 1
                self.stop.wait(0.5)
                continue
            with self.lock:
                self.open += 1
            t = time.perf_counter()
            why = self._hold(s, slow)
            with self.lock:
                self.open -= 1
                if why:
                    self.answers[f"{'slow' if slow else 'idle'}: {why}"] += 1
                    self.held.append(time.perf_counter() - t)
                    self.ended.append(time.perf_counter())
            s.close()

    def _hold(self, s: socket.socket, slow: bool) -> str | None:
        """Trickle (or stay silent) until the server answers or hangs up -> how it ended (None: we stopped)."""
        try:
            if slow:
                s.sendall(self.head)
            while not self.stop.is_set():
                if select.select([s], [], [], 1.0)[0]:
                    data = s.recv(4096)
                    return data.split(b"\r\n", 1)[0].decode("latin-1")[9:] if data else "closed"
                if slow:
                    s.sendall(b"\0")
        except OSError as e:
            return type(e).__name__
        return None


# ---- the admin page's job-event streams -----------------------------------------------------------
def held_job(data: Path, venue: str) -> str:
    """A quality job on `venue` that the job runner leaves queued for an hour (its not_before ahead,
    as a retry's backoff sets it), written straight into the server's database: streams on it stay
    open with no modelling running. -> its id (cancelled through the API afterwards)."""
    from omninav.catalog.db import Db
    from omninav.config import database_url

    job = f"held{os.getpid():x}"
    db = Db(database_url({"DATA": str(data), "DATABASE_URL": ""}))
    db.run("DELETE FROM jobs WHERE venue = :v AND id LIKE 'held%' AND state = 'queued'", v=venue)  # a run cut short
    db.run(
        "INSERT INTO jobs (id, venue, videos, state, created, kind, not_before) "
        "VALUES (:id, :v, '[]', 'queued', :t, 'quality', :nb)",
        id=job, v=venue, t=time.time(), nb=time.time() + 3600,
    )  # fmt: skip
    db.engine.dispose()
    return job


class EventStreams(HeldClients):
    """`n` job-event streams as the admin page opens them (the token in a header, one connection
    each, from the admin's one address), on one job: each reads what the server sends and opens
    again when the server ends it."""

    def __init__(self, port: int, job: str, n: int):
        super().__init__()
        self.port = port
        self.head = (
            f"GET /api/admin/jobs/{job}/events HTTP/1.1\r\nHost: 127.0.0.1\r\nAccept: text/event-stream\r\n"
            f"Authorization: {AUTH['Authorization']}\r\n\r\n"
        ).encode()
        self.answers: Counter[str] = Counter()  # the status line of each stream's answer
        self.threads += [threading.Thread(target=self._stream, daemon=True) for _ in range(n)]

    def _stream(self) -> None:
        while not self.stop.is_set():
            try:
                with socket.create_connection(("127.0.0.1", self.port), timeout=5) as s:
                    s.sendall(self.head)
                    first = s.recv(4096)
                    with self.lock:
                        self.answers[first.split(b"\r\n", 1)[0].decode("latin-1")[9:]] += 1
                        self.open += 1
                    try:
                        while not self.stop.is_set():
                            if select.select([s], [], [], 1.0)[0] and not s.recv(4096):
                                break
                    finally:
                        with self.lock:
                            self.open -= 1
            except OSError as e:
                with self.lock:
                    self.answers[type(e).__name__] += 1
                self.stop.wait(0.5)


# ---- the run ------------------------------------------------------------------------------------
def process_children() -> dict[int, list[int]]:
    """pid -> its children, of every process (Linux /proc)."""
    kids: dict[int, list[int]] = {}
    for d in Path("/proc").iterdir():
        if d.name.isdigit():
            try:
                ppid = int((d / "stat").read_text().rsplit(")", 1)[1].split()[1])
            except (OSError, IndexError, ValueError):
                continue
            kids.setdefault(ppid, []).append(int(d.name))
    return kids


def cpu_s(pid: int) -> float:
    try:
        f = (Path("/proc") / str(pid) / "stat").read_text().rsplit(")", 1)[1].split()
    except OSError:
        return 0.0
    return (int(f[11]) + int(f[12])) / os.sysconf("SC_CLK_TCK")


def roles(server: int) -> dict[str, list[int]]:
    """The server's processes by role (the children of `omninav serve`): nginx (master and worker),
    the app's gunicorn (arbiter and workers), the events gunicorn (arbiter and worker), and the rest,
    the job runner. The two gunicorns are told apart by start order: serve starts the app's first."""
    kids = process_children()
    mine = sorted(kids.get(server, []))
    nginx = [p for p in mine if _comm(p) == "nginx"]
    pools = [p for p in mine if p not in nginx and kids.get(p)]
    return {
        "nginx": [q for p in nginx for q in (p, *kids.get(p, []))],
        "workers": [pools[0], *kids[pools[0]]] if pools else [],
        "events": [pools[1], *kids[pools[1]]] if len(pools) > 1 else [],
        "job runner": [p for p in mine if p not in nginx and p not in pools],
    }


def _comm(pid: int) -> str:
    try:
        return (Path("/proc") / str(pid) / "comm").read_text().strip()
    except OSError:
        return ""


def cpu_by_role(server: int) -> dict[str, float]:
    """CPU seconds used so far by each role of the server's processes, and by this client (Linux
    /proc; a process that ended is not counted)."""
    return {
        **{role: sum(map(cpu_s, pids), 0.0) for role, pids in roles(server).items()},
        "client": cpu_s(os.getpid()),
    }


def gunicorn_workers(server: int) -> list[int]:
    """The server's app workers: the children of the app's gunicorn arbiter; [] until it has forked them."""
    return sorted(roles(server)["workers"][1:])


def descendants(pid: int) -> list[int]:
    """pid and every process under it."""
    kids, out, todo = process_children(), [], [pid]
    while todo:
        out.append(todo.pop())
        todo += kids.get(out[-1], [])
    return out


def cpu_line(before: dict[str, float], after: dict[str, float], seconds: float) -> str:
    return ", ".join(f"{k} {(after[k] - before[k]) / seconds:.2f}" for k in before)


def line(name: str, r: dict[str, Any]) -> str:
    fails = sum(r["failures"].values())
    why = f" ({', '.join(f'{k}: {v}' for k, v in r['failures'].items())})" if fails else ""
    why += "".join(f"\n      first {k}: {v}" for k, v in r["first_error"].items())
    return (
        f"  {name:30s} {r['n']:5d} {r['p50']:7.2f} {r['p90']:7.2f} {r['p99']:7.2f} {r['max']:8.2f} "
        f"{fails:5d}  {r['load']:5.2f}{why}"
    )


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--seconds", type=float, default=40.0, help="length of each of the four phases")
    ap.add_argument("--phones", type=int, default=100, help="phones in continuous mode")
    ap.add_argument(
        "--period", type=float, default=None, help="seconds between a phone's locates (default 3, 4 with --tracked)"
    )
    ap.add_argument("--tracked", action="store_true", help="the phones track, 2 s records (the app since issue 14)")
    ap.add_argument("--guided", type=int, default=0, help="with --tracked: phones guided to a place besides")
    ap.add_argument("--presses", type=float, default=20.0, help="presses per second")
    ap.add_argument("--slow", type=int, default=50, help="clients trickling a body at one byte a second")
    ap.add_argument("--idle", type=int, default=50, help="connections that send nothing")
    ap.add_argument("--streams", type=int, default=8, help="job-event streams of the admin page open in (c)")
    ap.add_argument("--upload-minutes", type=float, default=10.0, help="length of the uploaded video")
    ap.add_argument("--workers", type=int, default=None, help="server worker processes (default: as npm start)")
    a = ap.parse_args()
    if a.guided and not a.tracked:
        ap.error("--guided needs --tracked (a guided phone tracks)")
    load_before = os.getloadavg()
    spec, conf = query_spectra(REPO / "data" / "bench-server", 20)  # the walk decoded once: 2 s, and its first 1 s
    record = encode_binary(spec[:10], conf)
    plain = Bodies(record, record)
    mix = Bodies(record, encode_binary(spec, conf), a.tracked, a.guided if a.tracked else 0)
    video = long_video(a.upload_minutes)
    srv = start_server(REPO / "data" / "bench-server", a.workers)
    port = srv.port
    try:
        adm = Admin(port)
        # enough copies of the 1,501-frame walk that the job outlasts the phase at ~150 frames/s
        walks = job_venue(adm, copies=max(2, math.ceil(a.seconds * 150 / 1501) + 1))
        load(port, "POST", LOCATE, record, 100, 3)  # warm every worker
        print(f"machine: {machine()}")
        print(f"load average before: {' '.join(f'{x:.2f}' for x in load_before)} (other work on the machine)")
        period = a.period or (KEEP_PERIOD if a.tracked else PLAIN_PERIOD)
        rate = a.phones / period + mix.guided / GUIDED_PERIOD + a.presses
        what = "tracked (Keep telling me: 1 s, then 2 s records)" if a.tracked else "plain"
        print(
            f"mix: {a.phones} {what} phones, a locate every {period:g} s each (own keep-alive connection)"
            + (f" + {mix.guided} guided phones, a 2 s record every {GUIDED_PERIOD:g} s" if mix.guided else "")
            + f" + {a.presses:g} presses/s (Poisson, new connection each) = {rate:.1f} locates/s; records "
            f"{len(record)} bytes (1 s), {len(mix.two)} bytes (2 s), against 8,000 frames; {a.seconds:g} s per "
            "phase; a loopback address per phone; OMNINAV_LOCATE_RATE=0"
        )
        res: dict[str, Any] = {}
        cpu = {"start": cpu_by_role(srv.pid)}
        if a.tracked:  # the baseline of the same run: the plain mix of before, on this server
            far = Store(REPO / "data").load("demo", mmap=False).frames[800]  # a place along the demo's walk
            goal = [{"name": GOAL, "x": float(far["x"]), "y": float(far["y"]), "kind": "room"}]
            adm.call("PUT", "/api/admin/venues/bench8k/places", goal)
            res["p"] = run_mix(port, plain, argparse.Namespace(**{**vars(a), "period": PLAIN_PERIOD}), seed=0)
            cpu["p0"] = cpu["start"]
            cpu["p"] = cpu["start"] = cpu_by_role(srv.pid)
        res["a"] = run_mix(port, mix, a, seed=1)
        cpu["a"] = cpu_by_role(srv.pid)

        job, up = JobDriver(port, walks), Uploader(port, video)
        job.submit()
        job.start()
        job.started()
        up.start()
        time.sleep(1.0)  # the upload under way
        t0, cpu["b0"] = time.perf_counter(), cpu_by_role(srv.pid)
        res["b"] = run_mix(port, mix, a, seed=2)
        t1, cpu["b"] = time.perf_counter(), cpu_by_role(srv.pid)
        up.stop.set()
        job.stop.set()
        up.join()
        job.join()
        fps = job.frames_between(t0, t1) / (t1 - t0)

        slow = SlowClients(port, a.slow, a.idle)
        held_id = held_job(REPO / "data" / "bench-server", "bench8k")
        streams = EventStreams(port, held_id, a.streams)
        slow.start()
        streams.start()
        time.sleep(2.0)  # all connected
        cpu["c0"] = cpu_by_role(srv.pid)
        res["c"] = run_mix(port, mix, a, seed=3)
        cpu["c"] = cpu_by_role(srv.pid)
        slow.finish()
        streams.finish()
        adm.call("POST", f"/api/admin/jobs/{held_id}/cancel", ok=(202, 409))
        res["a2"] = run_mix(port, mix, a, seed=4)
        cpu["a2"] = cpu_by_role(srv.pid)

        print("locate latency from the scheduled send time (ms):")
        print(f"  {'phase':30s} {'n':>5s} {'p50':>7s} {'p90':>7s} {'p99':>7s} {'max':>8s} {'fails':>5s}  load1")
        if "p" in res:
            print(line("(p) the plain mix of before", res["p"]))
        print(line("(a) mix alone", res["a"]))
        print(line("(b) mix + upload + job", res["b"]))
        print(line(f"(c) + {a.slow} slow, {a.idle} idle, {a.streams} streams", res["c"]))
        print(line("(a') mix alone, again", res["a2"]))
        print(
            f"(b) modelling job: {fps:.1f} frames/s over the phase ({job.jobs} job(s) of {len(walks)} x 1,501 frames"
            f"{'; ' + '; '.join(job.errors) if job.errors else ''}); upload: {up.sent / 1e6:.0f} MB in {up.took:.1f} s "
            f"= {up.sent / 1e6 / max(up.took, 1e-9):.0f} MB/s, {up.complete} complete copies of "
            f"{video.stat().st_size / 1e6:.0f} MB, {len(up.errors)} failed pieces"
            + (f" (first: {up.errors[0]})" if up.errors else "")
        )
        held = np.array(slow.held) if slow.held else np.array([math.nan])
        print(
            f"(c) connections held open: {np.mean(slow.counts):.0f} on average (min {min(slow.counts)}) of "
            f"{a.slow + a.idle}; the server ended {len(slow.held)}, after {np.median(held):.1f} s median: "
            + ", ".join(f"{k} x{v}" for k, v in sorted(slow.answers.items()))
        )
        print(
            f"(c) job-event streams open: {np.mean(streams.counts):.1f} on average (min {min(streams.counts)}) of "
            f"{a.streams}; answers: " + ", ".join(f"{k} x{v}" for k, v in sorted(streams.answers.items()))
        )
        print("CPU used, in cores (CPU seconds per second of the phase):")
        phases = [("a", "(a)", "start"), ("b", "(b)", "b0"), ("c", "(c)", "c0"), ("a2", "(a')", "c")]
        if "p" in res:
            phases.insert(0, ("p", "(p)", "p0"))
        for k, name, start in phases:
            print(f"  {name:4s} {cpu_line(cpu[start], cpu[k], a.seconds + 0.5)}")
        for k, name, _ in phases:
            print(f"{name} slowest (s into the phase, ms): {res[k]['slowest']}")
        drops = np.array(slow.ended) - res["c"]["t0"]
        bursts = sorted({round(float(t)) for t in drops if 0 <= t <= a.seconds})
        print(f"(c) seconds into the phase at which the server dropped slow or idle connections: {bursts}")
        ok = [
            f"({k.replace('2', chr(39))}) {'yes' if r['p99'] < 50 and not r['failures'] else 'NO'}"
            for k, r in res.items()
        ]
        print(f"p99 < 50 ms and no failed request: {', '.join(ok)}")
    finally:
        srv.stop()
    print(f"load average after: {' '.join(f'{x:.2f}' for x in os.getloadavg())}")


if __name__ == "__main__":
    main()
