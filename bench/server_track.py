"""What a tracked locate costs the server, beside an untracked one, in the same run.

The bench venue (bench/accuracy.py's default venue, `data/bench-venue-0`: 1,501 modelled frames of
the 54 x 26 m ring, rendered and modelled on first use) served by the real Flask app in this
process (SQLite catalogue, CPU search). Its query walk is cut as the phone films while guiding: a
1 s clip every 2 s. Each clip is located three times, interleaved so that the machine's load falls
on all alike:

  plain    POST /locate                         the one-clip answer (issue 13's)
  tracked  POST /locate?session=A&t=&steps=     + the filter's update, its state read and written
  guided   POST /locate?session=B&t=&to=Goal    + the route guide (plan, instruction, its state)

and, interleaved with them, the walk cut as the app films it now once Start's instruction was said
(2 s a request, one every 2.5 s: everything but the answer's time), plain and tracked (the filter
walks each record second by second: two updates):

  plain 2 s, tracked 2 s                        the same, of 2 s records in their own session

per request: wall time and CPU time of this process (the search, the filter, the database, the
JSON), median and 90th percentile; how long after the venue's first request its walk graph and
tracker are ready (built in the background, WARM_VENUES) and the first tracked request after
that, on its own; the stored state's size; and the share of the filtered answers within
2 m against the single-clip ones on the same clips.

The same again on the venue padded with `--pad` synthetic frames (default 8,000: a serpentine
walk of 0.25 m steps far from the real frames, random spectra) so that the filter runs over a walk
graph of ~2,000 more nodes, as a large building's: what a tracked update costs grows with the
graph, not with the clip.

    python -m bench.server_track [--root data/bench-venue-0] [--clips 40] [--pad 8000] [--threads 1]

`--threads`: BLAS threads of this process (default 1, what `omninav serve` gives each worker;
0: the library's default).
"""

from __future__ import annotations

import argparse
import json
import shutil
import statistics
import tempfile
import time
from pathlib import Path

import numpy as np

from bench.accuracy import dataset, run
from bench.common import machine, pin_threads, random_spectra
from omninav.calib.correct import clip_spectra  # noqa: E402
from omninav.extract import Extractor  # noqa: E402
from omninav.lens import load_lens  # noqa: E402
from omninav.server import create_app  # noqa: E402
from omninav.spectrum import encode_binary  # noqa: E402
from omninav.store import FRAME_DTYPE, Generation, Store  # noqa: E402
from omninav.video import VideoInfo, iter_video  # noqa: E402
from omninav.walk_path import load_walk_path  # noqa: E402

TOKEN = "bench-token"
ADMIN = {"Authorization": f"Bearer {TOKEN}"}
CLIP_FRAMES = 10  # 1 s at the walk's 10 frames/s
EVERY = 20  # a clip every 2 s
WALK_FRAMES, WALK_EVERY = 20, 25  # the app's guided walk once under way: 2 s filmed every 2.5 s


def venue_store(root: Path) -> tuple[Store, str]:
    """The bench venue's store and venue id (modelled on first use, as bench/accuracy.py does)."""
    st = Store(root / "bench-data")
    ids = [v for v in st.list() if v.startswith("v-") and st.generation(v) is not None]
    if not ids:
        run(root, "default", "default", {}, "sequence", "v")
        ids = [v for v in st.list() if v.startswith("v-")]
    return st, sorted(ids)[0]


def pad(st: Store, src: str, dst: Store, vid: str, n: int) -> None:
    """Venue `vid` in `dst`: `src`'s generation plus n synthetic frames on a serpentine walk of
    0.25 m steps, rows of 100 m 4 m apart, 300 m from the real frames (another 'video')."""
    g = st.load(src, mmap=False)
    fr = np.zeros(n, FRAME_DTYPE)
    s = np.arange(n) * 0.25
    row, along = (s // 100.0).astype(np.int64), s % 100.0
    fr["x"] = 300.0 + np.where(row % 2 == 0, along, 100.0 - along)
    fr["y"] = 300.0 + 4.0 * row
    fr["heading"] = np.where(row % 2 == 0, 90.0, 270.0)
    fr["t"], fr["frame"], fr["video"] = s, np.arange(n), len(g.videos)
    spec = random_spectra(n, g.spectra.shape[1], g.spectra.shape[2], seed=5)
    frames = np.concatenate([g.frames, fr])
    dst.commit(vid, Generation(g.settings, g.lens, frames, np.concatenate([g.spectra, spec]), [*g.videos, "pad"]))


def clips(
    root: Path, conf: dict, n: int, clip_frames: int = CLIP_FRAMES, every: int = EVERY
) -> list[tuple[bytes, float, np.ndarray]]:
    """(binary record, t of the last frame, true xy) of a 1 s clip every 2 s of the query walk
    (clip_frames every `every` frames)."""
    info = VideoInfo(root / "query.mp4")
    lens = load_lens(root / "lens.json")
    tr = load_walk_path(root / "query_walk_path.json")
    frames: list[np.ndarray] = []
    out = []
    for i, f in iter_video(info):
        frames.append(f)
        if i % every == every - 1 and len(frames) >= clip_frames:
            spec = clip_spectra(lens, frames[-clip_frames:], lambda lz: Extractor(lz, conf).spectrum)[0]
            t = i / tr.fps
            xy, _, _ = tr.pose_at(np.array([t]))
            out.append((encode_binary(spec, conf), t, xy[0]))
            frames = []
            if len(out) >= n:
                break
    return out


def pct(xs: list[float], q: float) -> float:
    return float(np.percentile(np.asarray(xs), q))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--root", type=Path, default=Path("data") / "bench-venue-0")
    ap.add_argument("--clips", type=int, default=40)
    ap.add_argument("--pad", type=int, default=8000)
    ap.add_argument("--threads", type=int, default=1, help="BLAS threads (0: the library's default)")
    a = ap.parse_args()
    pools = pin_threads(a.threads) if a.threads > 0 else "library default threads"
    print(f"machine: {machine()}; BLAS: {pools}")
    root = dataset(a.root, 0)
    st, src = venue_store(root)
    tmp = Path(tempfile.mkdtemp(prefix="omninav-track-bench-"))
    try:
        data = tmp / "data"
        app = create_app(
            {
                "DATA": str(data),
                "ADMIN_TOKEN": TOKEN,
                "LOCATE_RATE": 0.0,
                "JOB_RUNNER": False,
                "DEVICE": "cpu",
                "WARM_VENUES": True,
            }
        )
        c = app.test_client()
        goal = json.loads((root / "query_walk_path.json").read_text())["waypoints"][-1]
        places = [{"name": "Goal", "x": goal["x"], "y": goal["y"], "kind": "room"}]
        for vid in ("bench", "big"):
            assert c.post("/api/admin/venues", json={"id": vid, "name": vid}, headers=ADMIN).status_code == 201
            assert c.put(f"/api/admin/venues/{vid}/places", json=places, headers=ADMIN).status_code == 200
        shutil.copytree(st.venue_dir(src), data / "venues" / "bench")
        pad(st, src, app.extensions["omninav"].catalog.store, "big", a.pad)
        conf = app.extensions["omninav"].catalog.venues.settings("bench")
        walk = clips(root, conf, a.clips)
        walk2 = clips(root, conf, a.clips, WALK_FRAMES, WALK_EVERY)
        print(
            f"venue: {src} of {root}; {len(walk)} clips of 1 s, one every 2 s of its query walk; "
            f"{len(walk2)} of 2 s, one every 2.5 s"
        )
        for vid in ("bench", "big"):
            measure(app, vid, walk, walk2)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


def measure(
    app: object, vid: str, walk: list[tuple[bytes, float, np.ndarray]], walk2: list[tuple[bytes, float, np.ndarray]]
) -> None:
    c = app.test_client()  # type: ignore[attr-defined]
    octet = "application/octet-stream"

    def post(record: bytes, query: str) -> tuple[dict, float, float]:
        w0, c0 = time.perf_counter(), time.process_time()
        r = c.post(f"/api/venues/{vid}/locate?{query}", data=record, content_type=octet)
        w1, c1 = time.perf_counter(), time.process_time()
        assert r.status_code == 200, r.get_json()
        return r.get_json(), (w1 - w0) * 1e3, (c1 - c0) * 1e3

    post(walk[0][0], "")  # loads the venue (index, memory maps); WARM_VENUES builds its walk meanwhile
    runtimes = app.extensions["omninav"].runtimes  # type: ignore[attr-defined]
    w0 = time.perf_counter()
    assert runtimes.warm_idle(300.0), "the background build did not end"  # as a phone would wait
    warm_wall = (time.perf_counter() - w0) * 1e3
    rt = runtimes.get(vid)
    _, first_wall, first_cpu = post(walk[0][0], "session=warmupwalk&t=0")  # the walk graph and tracker ready
    frames, nodes = len(rt.locator.gen.frames), len(rt.walk().graph.xy)
    kinds_all = ("plain", "tracked", "guided", "plain 2 s", "tracked 2 s")
    times: dict[str, tuple[list[float], list[float]]] = {k: ([], []) for k in kinds_all}
    near = {"single": 0, "tracked": 0, "tracked 2 s": 0}
    kinds: list[str] = []
    for i, (record, t, xy) in enumerate(walk):
        steps = []
        if i < len(walk2):
            r2, t2, xy2 = walk2[i]
            steps = [("plain 2 s", "", r2), ("tracked 2 s", f"session=benchwalkC&t={t2}&steps=4", r2)]
        for kind, query, rec in (
            ("plain", "", record),
            ("tracked", f"session=benchwalkA&t={t}&steps=3", record),
            ("guided", f"session=benchwalkB&t={t}&steps=3&to=Goal", record),
            *steps,
        ):
            ans, wall, cpu = post(rec, query)
            times[kind][0].append(wall)
            times[kind][1].append(cpu)
            if kind == "tracked" and i >= 3:  # after the first few seconds of the walk
                near["tracked"] += np.hypot(ans["x"] - xy[0], ans["y"] - xy[1]) <= 2.0
                s = ans["tracking"]["single"]
                near["single"] += np.hypot(s["x"] - xy[0], s["y"] - xy[1]) <= 2.0
            if kind == "tracked 2 s" and i >= 3:
                near[kind] += np.hypot(ans["x"] - xy2[0], ans["y"] - xy2[1]) <= 2.0
                assert ans["tracking"]["updates"] == 2 * (i + 1), ans["tracking"]  # walked second by second
            if kind == "guided":
                kinds.append(ans["guidance"]["kind"])
    row = app.extensions["omninav"].catalog.sessions.get(vid, "benchwalkA")  # type: ignore[attr-defined]
    print(f"\n## venue '{vid}': {frames} frames, a walk graph of {nodes} nodes")
    print(
        f"walk graph and tracker built in the background (WARM_VENUES) within {warm_wall:.0f} ms of the venue's "
        f"first request; the first tracked request then: {first_wall:.0f} ms wall, {first_cpu:.0f} ms CPU"
    )
    print("\n| request | wall p50 (ms) | wall p90 (ms) | CPU p50 (ms) | CPU p90 (ms) |")
    print("| --- | --- | --- | --- | --- |")
    for kind, (wall, cpu) in times.items():
        print(f"| {kind} | {pct(wall, 50):.1f} | {pct(wall, 90):.1f} | {pct(cpu, 50):.1f} | {pct(cpu, 90):.1f} |")
    for kind, base in (("tracked", "plain"), ("guided", "plain"), ("tracked 2 s", "plain 2 s")):
        n = min(len(times[kind][1]), len(times[base][1]))
        extra = statistics.median(np.subtract(times[kind][1][:n], times[base][1][:n]))
        print(f"{kind} - {base}, CPU per request (median of the pairs): {extra:.1f} ms")
    print(f"stored filter state: {len(row.state) if row else 0} bytes")
    if row is not None:  # the session's share: one read and one write of its row, as a request does
        cat = app.extensions["omninav"].catalog  # type: ignore[attr-defined]
        w0, c0 = time.perf_counter(), time.process_time()
        for _ in range(200):
            got = cat.sessions.get(vid, "benchwalkB")
            cat.sessions.put(vid, "benchwalkB", got.generation, got.state, got.guide, 900.0)
        w1, c1 = time.perf_counter(), time.process_time()
        print(f"the session's database read + write: {(w1 - w0) * 5:.2f} ms wall, {(c1 - c0) * 5:.2f} ms CPU")
    m = max(1, len(walk) - 3)
    print(f"within 2 m after the first 3 clips: tracked {near['tracked']}/{m}, single clip {near['single']}/{m}")
    m2 = max(1, len(walk2) - 3)
    print(f"within 2 m after the first 3 records of 2 s: tracked {near['tracked 2 s']}/{m2}")
    print(f"guidance kinds: {' '.join(kinds)}")


if __name__ == "__main__":
    main()
