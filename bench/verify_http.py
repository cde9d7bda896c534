"""What a phone waits for on a `verified` venue: `POST /locate` of its record over HTTP.

Each foreign pack venue (or any pack folder with model.mp4, track.json, lens.json and queries/)
is set up twice in one server's catalogue, as the admin page would (its walk video, walk path and
lens): once with the `default` preset, once with `verified`, both modelled in this process. Then
`omninav serve` runs on that data as `npm start` does (nginx in front, gunicorn behind, the
per-client locate limit off) and each query clip's phone record is posted one request at a
time, alternating the venues: version 1 (the curves) to the default venue, version 2 (the curves
and the last frame's keypoints) to the verified one. Printed per venue: each one's latency
median and p90 and their ratio (the issue's bar: within 2x).

    python -m bench.verify_http [--pack DIR] [--venues inst21] [--clips 30]
"""

from __future__ import annotations

import http.client
import json
import tempfile
import time
from collections import Counter
from pathlib import Path

import cv2
import numpy as np

from bench.common import machine
from bench.foreign import chosen_venues, pack_parser
from bench.verify_cost import phone_records
from omninav.catalog import Catalog
from omninav.config import load_config
from omninav.demo import model_now
from omninav.devserver import ServeProcess
from omninav.extract import Extractors
from omninav.lens import load_lens
from omninav.locate import Locator, clip_frames

PRESETS = ("default", "verified")


def set_up(cat: Catalog, src: Path, venue: str) -> None:
    """The pack venue as two venues of the catalogue, `<venue>-default` and `<venue>-verified`,
    modelled."""
    model_lens = src / ("model_lens.json" if (src / "model_lens.json").is_file() else "lens.json")
    walk = json.loads((src / "track.json").read_text())
    # a blank plan that holds the walk (the catalogue checks a walk path against its floor)
    far = max(max(w["x"], w["y"]) for w in walk["waypoints"]) + 5.0
    plan = cv2.imencode(".png", np.full((int(far * 20), int(far * 20)), 255, np.uint8))[1].tobytes()
    for preset in PRESETS:
        vid = f"{venue}-{preset}"
        cat.venues.create(vid, vid, preset, "1", "Ground floor", px_per_m=20.0)
        cat.floors.set_plan(vid, "1", plan)
        cat.lenses.put(vid, "lens", json.loads(model_lens.read_text()))
        cat.videos.add_file(vid, src / "model.mp4", "1", "lens", walk)
        model_now(cat, vid)


def records(cat: Catalog, src: Path, venue: str, clips: int) -> list[dict[str, bytes]]:
    """Each query clip's phone record for each venue (verify_cost.phone_records)."""
    lens = load_lens(src / "lens.json")
    locs = {p: Locator(cat.store, f"{venue}-{p}", device="cpu") for p in PRESETS}
    extractors = Extractors(locs["default"].conf)
    out = []
    for name in sorted(p.name for p in (src / "queries").iterdir())[:clips]:
        frames, _ = clip_frames(src / "queries" / name, locs["default"].conf["model_fps"])
        out.append(phone_records(locs, extractors, lens, frames, name))
    return out


def post(conn: http.client.HTTPConnection, venue_id: str, body: bytes) -> tuple[float, dict]:
    t = time.perf_counter()
    octets = {"Content-Type": "application/octet-stream"}
    conn.request("POST", f"/api/venues/{venue_id}/locate", body=body, headers=octets)
    r = conn.getresponse()
    text = r.read()
    ms = 1e3 * (time.perf_counter() - t)
    if r.status != 200:
        raise SystemExit(f"POST {venue_id}: {r.status} {text[:200]!r}")
    return ms, json.loads(text)


def main() -> None:
    ap = pack_parser(__doc__)
    ap.add_argument("--clips", type=int, default=30)
    a = ap.parse_args()
    print(f"machine: {machine()}")
    with tempfile.TemporaryDirectory(prefix="omninav-verify-http-") as d:
        cat = Catalog.open(load_config({"DATA": d}))
        venues = chosen_venues(a.pack, a.venues)
        bodies = {}
        for venue in venues:
            set_up(cat, a.pack / venue, venue)
            bodies[venue] = records(cat, a.pack / venue, venue, a.clips)
        with ServeProcess(d, "--demo", "none", env={"OMNINAV_LOCATE_RATE": "0"}) as srv:
            conn = http.client.HTTPConnection("127.0.0.1", srv.port, timeout=60)
            for venue in venues:
                for rec in bodies[venue][:4]:  # warm: every worker loads both venues
                    for p in PRESETS:
                        post(conn, f"{venue}-{p}", rec[p])
                ms: dict[str, list[float]] = {p: [] for p in PRESETS}
                said: Counter[str] = Counter()
                for rec in bodies[venue]:
                    for p in PRESETS:
                        t, ans = post(conn, f"{venue}-{p}", rec[p])
                        ms[p].append(t)
                    said[ans.get("verified", "not verified")] += 1  # (the verified venue's answer)
                med = {p: float(np.median(ms[p])) for p in PRESETS}
                for p in PRESETS:
                    kb = np.median([len(r[p]) for r in bodies[venue]]) / 1024
                    print(
                        f"{venue:<8} {p:<9} ({kb:4.1f} KB) median {med[p]:6.1f} ms, "
                        f"p90 {np.percentile(ms[p], 90):6.1f} ms ({len(ms[p])} clips)"
                    )
                print(f"{venue:<8} verified / default, median: {med['verified'] / med['default']:.1f}x; {dict(said)}")
            conn.close()


if __name__ == "__main__":
    main()
