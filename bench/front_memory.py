"""nginx's memory under unfinished huge bodies (issue 39, break 2): 16 connections from 4 addresses,
each sending all but the last byte of a 32 MB locate body, four rounds, against `omninav serve` as
`npm start` runs it. Prints nginx's resident memory (master and worker) before, at each round's
peak and 60 s after, the disk the bodies took, and another client's locate latency meanwhile.

    python -m bench.front_memory [--rounds 4] [--after 60]
"""

from __future__ import annotations

import argparse
import os
import tempfile
import time
import urllib.error
import urllib.request
from pathlib import Path

from bench.common import machine
from omninav.devserver import ServeProcess, unfinished_bodies

MB = 1 << 20


def free_bytes() -> int:
    st = os.statvfs(tempfile.gettempdir())
    return st.f_bavail * st.f_frsize


def locate_ms(base: str) -> float:
    t = time.perf_counter()
    req = urllib.request.Request(
        base + "/api/venues/lab/locate", b'{"mag": []}', {"Content-Type": "application/json"}, method="POST"
    )
    try:
        urllib.request.urlopen(req, timeout=10).read()
    except urllib.error.HTTPError as e:  # 409: 'lab' is not modelled; the answer is what is timed
        e.read()
    return (time.perf_counter() - t) * 1000


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--rounds", type=int, default=4)
    ap.add_argument("--after", type=float, default=60.0, help="seconds to wait before the last reading")
    a = ap.parse_args()
    print(f"machine: {machine()}")
    with (
        tempfile.TemporaryDirectory() as d,
        ServeProcess(Path(d) / "data", "--demo", "none", "--workers", "2", env={"OMNINAV_ADMIN_TOKEN": "bench"}) as srv,
    ):
        req = urllib.request.Request(
            srv.base + "/api/admin/venues",
            b'{"id": "lab"}',
            {"Authorization": "Bearer bench", "Content-Type": "application/json"},
            method="POST",
        )
        urllib.request.urlopen(req).read()
        print(f"nginx before: {srv.rss_mb('nginx'):.1f} MB (all of the server: {srv.rss_mb():.0f} MB)")
        for k in range(a.rounds):
            free0, t0 = free_bytes(), time.perf_counter()
            socks = unfinished_bodies(srv.port, [f"127.0.0.{i}" for i in range(2, 6)], 4, 32, "/api/venues/lab/locate")
            sent_s = time.perf_counter() - t0
            time.sleep(0.5)
            worst = max(locate_ms(srv.base) for _ in range(10))
            print(
                f"round {k + 1}: 16 x 32 MB sent (all but a byte) in {sent_s:.1f} s; nginx "
                f"{srv.rss_mb('nginx'):.1f} MB; disk taken {(free0 - free_bytes()) / MB:.0f} MB; "
                f"another client's locate: slowest of 10 {worst:.0f} ms"
            )
            for s in socks:
                s.close()
        time.sleep(a.after)
        print(f"nginx {a.after:g} s after: {srv.rss_mb('nginx'):.1f} MB (all of the server: {srv.rss_mb():.0f} MB)")


if __name__ == "__main__":
    main()
