"""Sizing a deployment: a server worker's memory, a venue's disk, and the time to its first answers.

For each venue size it builds a data folder holding one venue, `demo`: the real modelled demo venue
(`real`: `data/venues/demo`, made by `npm start`; skipped with a note when missing) and made-up venues
of N frames (bench/tracking.py's serpentine of 100 m corridors 5 m apart, spectra a smooth random
walk as bench/search_speed.py's, today's default settings and the demo's lens), written with
`Store.commit` like a modelling job. Then it runs `omninav serve` on it (a free port, its process
group stopped at the end) and reads /proc/PID/smaps_rollup and /proc/PID/smaps of its processes:

  - one worker (`--workers 1`, `OMNINAV_WARM_VENUES=false`, so the venue loads on the first request):
    its RSS, PSS, the RSS of the venue's memory-mapped arrays, anonymous memory and peak RSS (VmHWM)
    idle, after 5 locates and after 5 tracked locates (which build the walk graph and tracker), and
    the time of each request: the first locate and the first tracked locate pay for the building;
  - N workers (N > 1 in `--workers`, the default warm-up at start) on the first and the last venue
    of `--frames`: whether the mapped arrays are shared (their PSS against their RSS in each worker), the
    whole server's PSS, and when the workers' warm-up ended (their CPU time still for 3 s);
  - disk: the live generation's files, in MiB per 1,000 frames and bytes per frame;
  - a least-squares fit over the made-up venues: worker RSS = a + b MiB per 1,000 frames.

The feature record located is the e2e clip (`data/e2e/clip/clip.y4m`, 20 frames, made by the e2e
tests; extracted with `omninav features` and the e2e quick demo's lens); without it, a synthetic
record of 20 frames of the first venue's own spectra with noise (it costs the same to locate).

    python -m bench.sizing [--frames real,1500,8000,20000] [--workers 1,2] [--repeat 1] [--json OUT] [--work DIR]

Run from the repository root. `--work DIR` keeps the venues and the record there (its `v-*` folders
are made anew on every run); by default they go to a temporary folder, removed at the end. About 40 s
on 2 cores.
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
import urllib.error
import urllib.request
from pathlib import Path

import numpy as np

from bench.common import machine, random_spectra
from bench.server_mix import cpu_s, descendants, gunicorn_workers
from bench.tracking import serpentine
from omninav.devserver import ServeProcess  # noqa: E402
from omninav.presets import n_curves, resolve  # noqa: E402
from omninav.spectrum import encode_binary  # noqa: E402
from omninav.store import FRAME_DTYPE, Generation, Store  # noqa: E402
from omninav.synth import donut_lens  # noqa: E402

REPO = Path(__file__).resolve().parents[1]
OMNINAV = str(Path(sys.executable).with_name("omninav"))
REAL = REPO / "data"  # the data folder whose venue `demo` npm start models
E2E_CLIP = REPO / "data" / "e2e" / "clip" / "clip.y4m"
E2E_LENS = REPO / "data" / "e2e" / "server" / "demo-src-quick" / "lens.json"  # the lens the clip was filmed with
VENUE = "demo"
MIB = 1024.0  # /proc reports kB
ROLLUP = ("Rss", "Pss", "Anonymous")


# --- venues ---------------------------------------------------------------------------------------


def made_up(n: int) -> Generation:
    conf = resolve("default")
    xy, _ = serpentine(n)  # bench/tracking.py's made-up venue: corridors 100 m long, 5 m apart
    frames = np.zeros(n, FRAME_DTYPE)
    frames["x"], frames["y"] = xy[:, 0], xy[:, 1]
    frames["heading"] = np.random.default_rng(n).uniform(0, 360, n)
    frames["t"], frames["frame"] = np.arange(n) / 10.0, np.arange(n) * 3
    spec = random_spectra(n, n_curves(conf), conf["n_harmonics"])
    return Generation(conf, donut_lens(), frames, spec, ["model.mp4"])


def generation(what: str) -> Generation | None:
    """The venue to size: `real` (None if npm start never modelled it) or a made-up one of N frames."""
    if what != "real":
        return made_up(int(what))
    real = Store(REAL)
    return real.load(VENUE, mmap=False) if real.generation(VENUE) is not None else None


def build(data: Path, gen: Generation) -> None:
    """A data folder holding venue `demo` with `gen` as its live generation, made as an admin would."""
    shutil.rmtree(data, ignore_errors=True)  # a leftover of an older run must not be measured
    subprocess.run(
        [OMNINAV, "--data", str(data), "venue", "create", VENUE, "--name", "Sizing"],
        check=True,
        stdout=subprocess.DEVNULL,
    )
    Store(data).commit(VENUE, gen)


def disk(data: Path) -> dict[str, int]:
    """Bytes of each file of the live generation."""
    g = Store(data).venue_dir(VENUE) / Store(data).generation(VENUE)
    return {p.name: p.stat().st_size for p in sorted(g.iterdir())}


# --- the feature record -----------------------------------------------------------------------------


def feature_record(data: Path, out: Path) -> tuple[bytes, str]:
    """(binary record, where it came from): the e2e clip if the e2e tests made it, else synthetic."""
    if E2E_CLIP.is_file() and E2E_LENS.is_file():
        cmd = [OMNINAV, "--data", str(data), "features", VENUE, str(E2E_CLIP), "--lens", str(E2E_LENS), "-o", str(out)]
        subprocess.run(cmd, check=True)
        return out.read_bytes(), f"the e2e clip ({E2E_CLIP.relative_to(REPO)}), 20 frames"
    g = Store(data).load(VENUE, mmap=False)
    rng = np.random.default_rng(1)
    q = g.spectra[100:120]
    q = q + 0.03 * (rng.normal(size=q.shape) + 1j * rng.normal(size=q.shape))  # not exactly the venue's frames
    q = (q / np.sqrt((np.abs(q) ** 2).sum(axis=(1, 2), keepdims=True))).astype(np.complex64)
    out.write_bytes(encode_binary(q, g.settings))
    return out.read_bytes(), f"synthetic, 20 frames of the venue's own spectra with noise ({E2E_CLIP} is missing)"


# --- /proc ------------------------------------------------------------------------------------------


def rollup(pid: int) -> dict[str, int]:
    out = {}
    for line in Path(f"/proc/{pid}/smaps_rollup").read_text().splitlines():
        parts = line.split()
        if len(parts) == 3 and parts[0].rstrip(":") in ROLLUP:
            out[parts[0].rstrip(":")] = int(parts[1])
    return out


def venue_maps(pid: int, data: Path) -> dict[str, int]:
    """Rss and Pss (kB) of the mappings of files under the venue folder: the memory-mapped arrays."""
    prefix = str(data.resolve() / "venues") + "/"
    rss = pss = 0
    ours = False
    for line in Path(f"/proc/{pid}/smaps").read_text().splitlines():
        head = line.split()
        if head and not head[0].endswith(":"):  # a mapping's first line: address perms offset dev inode [path]
            ours = len(head) >= 6 and head[5].startswith(prefix)
        elif ours and head[0] == "Rss:":
            rss += int(head[1])
        elif ours and head[0] == "Pss:":
            pss += int(head[1])
    return {"map_rss": rss, "map_pss": pss}


def status(pid: int, key: str) -> int:
    for line in Path(f"/proc/{pid}/status").read_text().splitlines():
        if line.startswith(key + ":"):
            return int(line.split()[1])
    return 0


def snapshot(server: int, data: Path) -> dict[int, dict[str, int]]:
    """pid -> Rss, Pss, Anonymous, map_rss, map_pss, VmHWM (kB) of every process of the server."""
    out = {}
    for pid in descendants(server):
        try:
            out[pid] = {**rollup(pid), **venue_maps(pid, data), "VmHWM": status(pid, "VmHWM")}
        except OSError:  # a process that ended meanwhile
            pass
    return out


# --- the server -------------------------------------------------------------------------------------


def serve(data: Path, nworkers: int, warm: bool) -> ServeProcess:
    env = {"OMNINAV_WARM_VENUES": "true" if warm else "false", "OMNINAV_LOCATE_RATE": "0"}
    return ServeProcess(data, "--demo", "none", "--workers", str(nworkers), env=env, timeout=120.0)


def wait_workers(server: int, n: int, timeout: float = 60.0) -> list[int]:
    deadline = time.monotonic() + timeout
    while len(ws := gunicorn_workers(server)) < n:
        if time.monotonic() > deadline:
            raise RuntimeError(f"{n} workers did not start within {timeout:g} s (found {ws})")
        time.sleep(0.2)
    return ws


def post(base: str, record: bytes, query: str = "") -> float:
    """One locate: -> its wall time in ms."""
    req = urllib.request.Request(
        f"{base}/api/venues/{VENUE}/locate{query}",
        data=record,
        headers={"Content-Type": "application/octet-stream"},
        method="POST",
    )
    t0 = time.perf_counter()
    try:
        with urllib.request.urlopen(req, timeout=300) as r:
            r.read()
    except urllib.error.HTTPError as e:
        raise RuntimeError(f"locate{query}: {e.code} {e.read()[:300]!r}") from None
    return (time.perf_counter() - t0) * 1e3


def walk(i: int) -> str:
    """The query of a walk's i-th tracked locate: one session, moving on 2 s a request."""
    return f"?session=sizing-walk-0001&t={2.0 * (i + 1)}"


def one_worker(data: Path, record: bytes) -> dict:
    t0 = time.perf_counter()
    with serve(data, 1, warm=False) as srv:
        res: dict = {"t_up_s": time.perf_counter() - t0}
        res["workers"] = wait_workers(srv.pid, 1)
        time.sleep(3.0)  # the worker's own start (imports, app) settles before the idle reading
        res["idle"] = snapshot(srv.pid, data)
        res["locate_ms"] = [post(srv.base, record) for _ in range(5)]
        res["located"] = snapshot(srv.pid, data)
        res["tracked_ms"] = [post(srv.base, record, walk(i)) for i in range(5)]
        res["tracked"] = snapshot(srv.pid, data)
    return res


def wait_warm(ws: list[int], t0: float, timeout: float = 600.0) -> float:
    """Seconds from t0 until the workers' CPU time stopped growing (for 3 s, read every 0.5 s):
    the server says nothing when its warm-up ends."""
    last, still_since = None, None
    while time.perf_counter() - t0 < timeout:
        now = sum(cpu_s(w) for w in ws)
        if last is not None and now - last < 0.02:
            still_since = still_since or time.perf_counter()
            if time.perf_counter() - still_since >= 3.0:
                return still_since - t0
        else:
            still_since = None
        last = now
        time.sleep(0.5)
    return float("nan")


def many_workers(data: Path, record: bytes, n: int) -> dict:
    t0 = time.perf_counter()
    with serve(data, n, warm=True) as srv:
        res: dict = {"t_up_s": time.perf_counter() - t0, "workers": wait_workers(srv.pid, n)}
        res["t_warmed_s"] = wait_warm(res["workers"], t0)
        res["locate_ms"] = [post(srv.base, record) for _ in range(5)]
        res["tracked_ms"] = [post(srv.base, record, walk(i)) for i in range(5)]
        res["used"] = snapshot(srv.pid, data)
    return res


# --- tables -----------------------------------------------------------------------------------------


def label(what: str, frames: int) -> str:
    return f"real demo, {frames:,} frames" if what == "real" else f"made-up, {frames:,} frames"


def span(xs: list[float], fmt: str = ".0f") -> str:
    """One figure, or the range of the runs' figures."""
    lo, hi = min(xs), max(xs)
    return f"{lo:{fmt}}" if f"{lo:{fmt}}" == f"{hi:{fmt}}" else f"{lo:{fmt}}–{hi:{fmt}}"


def mib(runs: list[dict], snap: str, key: str) -> float:
    """Median over the runs of the one worker's figure, MiB."""
    return statistics.median(r[snap][r["workers"][0]][key] / MIB for r in runs)


def memory_table(venues: list[dict]) -> None:
    print("\n## One worker: memory after 5 locates and 5 tracked locates (MiB)\n")
    print(
        "| venue | worker RSS | PSS | mapped arrays (RSS) | mapped after plain locates | anonymous | peak RSS (VmHWM) |"
    )
    print("| --- | ---: | ---: | ---: | ---: | ---: | ---: |")
    first = venues[0]["one"]
    cells = [mib(first, "idle", k) for k in ("Rss", "Pss", "map_rss")] + [0.0]
    cells += [mib(first, "idle", k) for k in ("Anonymous", "VmHWM")]
    print("| idle, no venue loaded | " + " | ".join(f"{c:.1f}" for c in cells) + " |")
    for v in venues:
        runs = v["one"]
        cells = [mib(runs, "tracked", k) for k in ("Rss", "Pss", "map_rss")] + [mib(runs, "located", "map_rss")]
        cells += [mib(runs, "tracked", k) for k in ("Anonymous", "VmHWM")]
        print(f"| {label(v['what'], v['frames'])} | " + " | ".join(f"{c:.1f}" for c in cells) + " |")


def sharing_table(venues: list[dict]) -> None:
    rows = [(v, r) for v in venues for r in v.get("many", [])]
    if not rows:
        return
    print(
        "\n## Several workers, default warm-up, then 5 + 5 locates: are the mapped arrays shared? (MiB, one a worker)\n"
    )
    print(
        "| venue | workers | warmed after (s) | worker RSS | worker PSS | mapped RSS | mapped PSS | server PSS (all) |"
    )
    print("| --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: |")
    for v, r in rows:
        snap, ws = r["used"], r["workers"]

        def each(key: str, snap: dict = snap, ws: list[int] = ws) -> str:
            return " / ".join(f"{snap[w][key] / MIB:.1f}" for w in ws)

        total = sum(p["Pss"] for p in snap.values()) / MIB
        print(
            f"| {label(v['what'], v['frames'])} | {len(ws)} | {r['t_warmed_s']:.1f} | {each('Rss')} | {each('Pss')} "
            f"| {each('map_rss')} | {each('map_pss')} | {total:.0f} |"
        )
    print("\nthe first tracked locate once warmed: " + ", ".join(f"{r['tracked_ms'][0]:.0f} ms" for _, r in rows))


def disk_table(venues: list[dict]) -> None:
    print("\n## Disk: the live generation (`<data>/venues/<id>/gen-NNNNNN/`)\n")
    print("| venue | MiB | MiB per 1,000 frames | B/frame spectra | keys | first | frames | basis (KiB) |")
    print("| --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: |")
    for v in venues:
        files, n = v["disk"], v["frames"]
        total = sum(files.values()) / 2**20

        def per(name: str, files: dict = files, n: int = n) -> str:
            return f"{files.get(name, 0) / n:.0f}"

        sizes = " | ".join(per(f"{k}.npy") for k in ("spectra", "keys", "first", "frames"))
        basis = files.get("basis.npy", 0) / 1024
        print(f"| {label(v['what'], n)} | {total:.2f} | {total / n * 1000:.2f} | {sizes} | {basis:.0f} |")


def time_table(venues: list[dict]) -> None:
    print("\n## Time to a venue's first answers, one worker, venue loaded on demand (ms)\n")
    print("| venue | server up (s) | first locate | next locates | first tracked locate | next tracked |")
    print("| --- | ---: | ---: | ---: | ---: | ---: |")
    for v in venues:
        runs = v["one"]
        up = span([r["t_up_s"] for r in runs], ".1f")
        first = span([r["locate_ms"][0] for r in runs])
        nxt = span([x for r in runs for x in r["locate_ms"][1:]])
        tfirst = span([r["tracked_ms"][0] for r in runs])
        tnext = span([x for r in runs for x in r["tracked_ms"][1:]])
        print(f"| {label(v['what'], v['frames'])} | {up} | {first} | {nxt} | {tfirst} | {tnext} |")


def fit(venues: list[dict], snap: str, key: str) -> dict | None:
    """Least squares over the made-up venues: MiB = a + b per 1,000 frames, and its largest miss."""
    pts = [(v["frames"] / 1000, mib(v["one"], snap, key)) for v in venues if v["what"] != "real" and v.get("one")]
    if len(pts) < 2:
        return None
    x, y = np.array(pts).T
    b, a = np.polyfit(x, y, 1)
    return {"a": float(a), "b": float(b), "miss": float(np.abs(y - (a + b * x)).max()), "n": len(pts)}


def fit_lines(venues: list[dict]) -> dict:
    out = {}
    for name, snap, key in (("worker RSS", "tracked", "Rss"), ("mapped arrays", "tracked", "map_rss")):
        f = fit(venues, snap, key)
        if f is None:
            print("\nno fit: it needs 2 made-up venues or more")
            break
        out[name] = f
        print(
            f"\n{name} = {f['a']:.1f} + {f['b']:.2f} MiB per 1,000 frames "
            f"(least squares over {f['n']} made-up venues; largest miss {f['miss']:.1f} MiB)"
        )
    return out


# --- main -------------------------------------------------------------------------------------------


def measure(what: str, work: Path, worker_counts: list[int], repeat: int, record: dict, share: bool) -> dict | None:
    gen = generation(what)
    if gen is None:
        print(f"note: skipped `real`: {REAL / 'venues' / VENUE} is missing (npm start or `omninav demo` makes it)")
        return None
    data = work / f"v-{what}"
    t0 = time.perf_counter()
    build(data, gen)
    v: dict = {"what": what, "frames": len(gen.frames), "build_s": time.perf_counter() - t0, "disk": disk(data)}
    del gen
    if "bytes" not in record:
        record["bytes"], record["source"] = feature_record(data, work / "record.onv")
    if 1 in worker_counts:
        v["one"] = [one_worker(data, record["bytes"]) for _ in range(repeat)]
    if share:
        v["many"] = [many_workers(data, record["bytes"], n) for n in worker_counts if n > 1]
    print(f"measured {what}: {v['frames']} frames (built in {v['build_s']:.1f} s)", file=sys.stderr, flush=True)
    return v


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--frames", default="real,1500,8000,20000", help="venues: `real` and/or frame counts")
    ap.add_argument("--workers", default="1,2", help="1: the one-worker tables; N > 1: the sharing check")
    ap.add_argument("--repeat", type=int, default=1, help="one-worker runs a venue")
    ap.add_argument("--json", type=Path, help="write every reading here")
    ap.add_argument("--work", type=Path, help="keep the venues here (default: a temporary folder)")
    a = ap.parse_args()
    whats = a.frames.split(",")
    counts = [int(n) for n in a.workers.split(",")]
    work = a.work or Path(tempfile.mkdtemp(prefix="omninav-sizing-"))
    work.mkdir(parents=True, exist_ok=True)
    print(f"machine: {machine()}; load average {os.getloadavg()[0]:.1f}")
    t0 = time.perf_counter()
    try:
        record: dict = {}
        venues = []
        for i, what in enumerate(whats):
            # the sharing check on the smallest and the largest venue only: it adds little between
            v = measure(what, work, counts, a.repeat, record, share=i in (0, len(whats) - 1) or not venues)
            if v is not None:
                venues.append(v)
    finally:
        if a.work is None:
            shutil.rmtree(work, ignore_errors=True)
    if not venues:
        raise SystemExit("no venue measured")
    print(f"record: {record['source']}, {len(record['bytes'])} bytes")
    if 1 in counts:
        memory_table(venues)
    sharing_table(venues)
    disk_table(venues)
    fits: dict = {}
    if 1 in counts:
        time_table(venues)
        fits = fit_lines(venues)
    took = time.perf_counter() - t0
    print(f"\ntook {took:.0f} s; load average {os.getloadavg()[0]:.1f}")
    if a.json:
        a.json.parent.mkdir(parents=True, exist_ok=True)
        out = {"machine": machine(), "record": record["source"], "venues": venues, "fits": fits, "took_s": took}
        a.json.write_text(json.dumps(out, indent=1, default=str))


if __name__ == "__main__":
    main()
