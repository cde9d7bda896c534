"""`locate` over HTTP under load: the server as `npm start` runs it, an open-loop load generator.

Builds (once) a data directory with an 8,000-frame venue: the synthetic demo venue's 1,501 real
modelled frames plus 6,499 synthetic ones (search costs the same), starts `omninav serve` on it
(gunicorn, the default workers and threads), and sends requests at fixed rates from a Python
client: each request has a scheduled send time and its latency counts from then, so a server
that falls behind is charged for the queue it causes (no coordinated omission).

  1. `GET /api/health` and `POST /api/venues/bench8k/locate` (a real 10-frame clip's binary
     record, 7.7 kB) at 200 requests/s: p50, p90, p99, max.
  2. The highest rate each sustains with p99 under 50 ms (rates stepped up until it breaks).
  3. (first, or alone with --video-only) the same 10 frames sent as an MP4 video body (video/mp4,
     at 10 frames/s, so the server extracts all ten): one request at a time, median and p90, on
     the idle machine and with one core kept busy by another process (a server's other worker).

The per-client rate limit is switched off (OMNINAV_LOCATE_RATE=0): the load comes from one
address. The client runs on the same machine and takes some of its cores.

    python -m bench.server_load [--seconds 20] [--rate 200] [--workers N] [--video-only]
"""

from __future__ import annotations

import argparse
import http.client
import json
import multiprocessing
import tempfile
import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager
from multiprocessing.synchronize import Event
from pathlib import Path

import numpy as np

from bench.common import machine
from bench.common import random_spectra as venue
from omninav.devserver import ServeProcess  # noqa: E402
from omninav.extract import Extractor  # noqa: E402
from omninav.lens import load_lens  # noqa: E402
from omninav.presets import resolve, settings_id  # noqa: E402
from omninav.spectrum import encode_binary  # noqa: E402
from omninav.store import FRAME_DTYPE, Generation, Store  # noqa: E402
from omninav.video import VideoInfo, iter_video  # noqa: E402

REPO = Path(__file__).resolve().parents[1]
N_FRAMES = 8000


def build(data: Path, n_frames: int = 10) -> bytes:
    """-> the query record (`n_frames` of the demo's query walk); makes the bench venue on first use."""
    return encode_binary(*query_spectra(data, n_frames))


def query_spectra(data: Path, n_frames: int = 10) -> tuple[np.ndarray, dict]:
    """-> (spectra of `n_frames` of the demo's query walk, their settings); makes the bench venue
    on first use (a record of the first k of them: encode_binary(spectra[:k], settings))."""
    from omninav.catalog import Catalog
    from omninav.config import DEFAULTS
    from omninav.synth import make_dataset

    src = REPO / "data" / "demo-src"
    if not (src / "model.mp4").exists():
        make_dataset(src, seed=0, layout="default")
    demo = Store(REPO / "data")
    if demo.generation("demo") is None:
        raise SystemExit("model the demo venue first: npm start (or omninav demo)")
    g = demo.load("demo", mmap=False)
    # today's search settings (a demo venue modelled by an older omninav may predate some)
    conf = resolve("default")
    if settings_id(conf) != settings_id(g.settings):
        raise SystemExit("the demo venue was modelled with other feature settings; model it again")
    cat = Catalog.open({**DEFAULTS, "DATA": str(data)})
    if not cat.db.one("SELECT id FROM venues WHERE id = 'bench8k'"):
        cat.venues.create("bench8k", "8,000-frame bench venue")
        extra = N_FRAMES - len(g.frames)
        fr = np.zeros(extra, FRAME_DTYPE)
        fr["x"], fr["y"] = 200.0 + np.arange(extra) * 0.1, 500.0  # far from the real frames
        fr["video"] = 1
        spec = venue(extra, g.spectra.shape[1], g.spectra.shape[2], seed=5)
        cat.store.commit(
            "bench8k",
            Generation(
                conf,
                g.lens,
                np.concatenate([g.frames, fr]),
                np.concatenate([g.spectra, spec]),
                [*g.videos, "synthetic"],
            ),
        )
    return Extractor(load_lens(src / "lens.json"), conf).spectra(query_frames(n_frames)), conf


def query_frames(n_frames: int = 10) -> list[np.ndarray]:
    """`n_frames` BGR frames of the demo's query walk from its frame 300: the bench's clip."""
    info = VideoInfo(REPO / "data" / "demo-src" / "query.mp4")
    return [f for i, f in iter_video(info, start=300) if i < 300 + n_frames]


def video_body(n_frames: int = 10) -> bytes:
    """The bench's clip as an MP4 at 10 frames/s, what a client without WebAssembly sends: the
    venue's modelling rate is 10 frames/s, so the server extracts every one of its frames."""
    from omninav.synth.walks import write_video

    frames = query_frames(n_frames)
    with tempfile.TemporaryDirectory() as d:
        p = Path(d) / "clip.mp4"
        write_video(p, iter(frames), 10.0, (frames[0].shape[1], frames[0].shape[0]))
        return p.read_bytes()


def one_at_a_time(port: int, path: str, body: bytes, content_type: str, n: int = 20, warm: int = 8) -> dict:
    """`n` requests sent one after another (after `warm` that reach every worker): latency p50, p90,
    p99, max (ms)."""
    c = http.client.HTTPConnection("127.0.0.1", port, timeout=60)
    lat = []
    for i in range(n + warm):
        t = time.perf_counter()
        c.request("POST", path, body=body, headers={"Content-Type": content_type})
        r = c.getresponse()
        r.read()
        if r.status != 200:
            raise SystemExit(f"POST {path} ({content_type}): {r.status}")
        if i >= warm:
            lat.append(time.perf_counter() - t)
    c.close()
    return summary(np.array(lat) * 1e3)


def _spin(stop: Event) -> None:
    while not stop.is_set():
        pass


@contextmanager
def one_core_busy() -> Iterator[None]:
    """A process spinning on one core for the duration: what a server's other busy worker takes."""
    stop = multiprocessing.Event()
    p = multiprocessing.Process(target=_spin, args=(stop,), daemon=True)
    p.start()
    try:
        yield
    finally:
        stop.set()
        p.join()


def video_rows(port: int, path: str, n: int = 20) -> dict[str, dict]:
    """The 10-frame video body's latency, one request at a time: idle, then with one core busy."""
    body = video_body()
    out = {"idle": one_at_a_time(port, path, body, "video/mp4", n)}
    with one_core_busy():
        out["one core busy"] = one_at_a_time(port, path, body, "video/mp4", n)
    return out


def load(port: int, method: str, path: str, body: bytes | None, rate: float, seconds: float, conns: int = 16):
    """Open-loop: request i is due at t0 + i/rate; latency = completion - due time."""
    n = int(rate * seconds)
    lat = np.full(n, np.nan)
    nxt = [0]
    lock = threading.Lock()
    t0 = time.perf_counter() + 0.2
    headers = {"Content-Type": "application/octet-stream"} if body else {}

    def worker() -> None:
        c = http.client.HTTPConnection("127.0.0.1", port, timeout=30)
        while True:
            with lock:
                i = nxt[0]
                nxt[0] += 1
            if i >= n:
                break
            due = t0 + i / rate
            wait = due - time.perf_counter()
            if wait > 0:
                time.sleep(wait)
            c.request(method, path, body=body, headers=headers)
            r = c.getresponse()
            r.read()
            if r.status != 200:
                raise SystemExit(f"{method} {path}: {r.status}")
            lat[i] = time.perf_counter() - due
        c.close()

    ts = [threading.Thread(target=worker) for _ in range(conns)]
    for t in ts:
        t.start()
    for t in ts:
        t.join()
    took = time.perf_counter() - t0
    return {"rate": rate, "achieved": round(n / took, 1), **summary(lat * 1e3)}


def summary(ms: np.ndarray) -> dict:
    """Latencies in ms -> p50, p90, p99 and max, rounded for printing."""
    return {
        "p50": round(float(np.percentile(ms, 50)), 2),
        "p90": round(float(np.percentile(ms, 90)), 2),
        "p99": round(float(np.percentile(ms, 99)), 2),
        "max": round(float(ms.max()), 2),
    }


def start_server(data: Path, workers: int | None = None, threads: int | None = None) -> ServeProcess:
    """`omninav serve` as npm start runs it, on `data`, with the per-client locate limit off (all
    load comes from one address) and admin token "bench"; returns once it answers /api/health."""
    args = ["--demo", "none"]
    if workers:
        args += ["--workers", str(workers)]
    if threads:
        args += ["--threads", str(threads)]
    return ServeProcess(data, *args, env={"OMNINAV_LOCATE_RATE": "0", "OMNINAV_ADMIN_TOKEN": "bench"})


def max_rate(port: int, method: str, path: str, body: bytes | None, seconds: float) -> dict:
    best = None
    for rate in (200, 300, 400, 500, 600, 800, 1000, 1200, 1500, 2000, 2500, 3000):
        r = load(port, method, path, body, rate, seconds)
        ok = r["p99"] < 50 and r["achieved"] >= 0.95 * rate
        print(f"    {method} {path} at {rate}/s: p50 {r['p50']} ms, p99 {r['p99']} ms {'ok' if ok else 'breaks'}")
        if not ok:
            break
        best = r
    return best or {"rate": 0}


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--seconds", type=float, default=20.0)
    ap.add_argument("--rate", type=float, default=200.0)
    ap.add_argument("--workers", type=int, default=None, help="server worker processes (default: as npm start)")
    ap.add_argument("--threads", type=int, default=None, help="threads per worker (default: as npm start)")
    ap.add_argument("--no-max", action="store_true", help="skip the search for the highest rate")
    ap.add_argument("--video-only", action="store_true", help="only the video body's rows (3)")
    a = ap.parse_args()
    data = REPO / "data" / "bench-server"
    record = build(data)
    srv = start_server(data, a.workers, a.threads)
    port = srv.port
    try:
        loc = "/api/venues/bench8k/locate"
        c = http.client.HTTPConnection("127.0.0.1", port)
        c.request("POST", loc, body=record, headers={"Content-Type": "application/octet-stream"})
        ans = json.loads(c.getresponse().read())
        print(f"machine: {machine()}")
        print(
            f"venue: 8,000 frames; query: 10 frames, {len(record)} bytes; answer: x {ans['x']} y {ans['y']} "
            f"confidence {ans['confidence']}"
        )
        video = video_rows(port, loc)
        print(f"POST locate, the same 10 frames as an MP4 body ({len(video_body())} bytes), one at a time (ms):")
        for name, r in video.items():
            print(f"  {name:14s} p50 {r['p50']:7.2f}  p90 {r['p90']:7.2f}  p99 {r['p99']:7.2f}  max {r['max']:7.2f}")
        if a.video_only:
            return
        load(port, "POST", loc, record, 100, 3)  # warm every worker
        h = load(port, "GET", "/api/health", None, a.rate, a.seconds)
        lo = load(port, "POST", loc, record, a.rate, a.seconds)
        print(f"at {a.rate:g} requests/s for {a.seconds:g} s (ms):")
        for name, r in (("GET /api/health", h), ("POST locate", lo)):
            print(
                f"  {name:16s} p50 {r['p50']:6.2f}  p90 {r['p90']:6.2f}  p99 {r['p99']:6.2f}  max {r['max']:7.2f}"
                f"  achieved {r['achieved']}/s"
            )
        print(f"  locate / health: p50 x{lo['p50'] / h['p50']:.2f}, p99 x{lo['p99'] / h['p99']:.2f}")
        if a.no_max:
            return
        print("highest rate with p99 < 50 ms (10 s per step):")
        mh = max_rate(port, "GET", "/api/health", None, 10)
        ml = max_rate(port, "POST", loc, record, 10)
        share = ml["rate"] / max(mh["rate"], 1)
        print(f"  health {mh['rate']}/s, locate {ml['rate']}/s: locate sustains {share:.2f} of health's rate")
    finally:
        srv.stop()


if __name__ == "__main__":
    main()
