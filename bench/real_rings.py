"""The ring finder on real frames that cannot live in the repository (their licences), and the
files for the phone's port to be held to the engine on them.

For each image (any format OpenCV reads; frames of one video share its size): the engine's
`find_ring_frame`, printed, and written with the frame's RGBA pixels into OUT, where the Vitest
golden reads them when told (`OMNINAV_REAL_RINGS=OUT`, web/tests/ring.test.ts: the phone's
ring within 0.5 px of the engine's on every frame, or no ring on both). Then, per folder of
frames, `find_ring` over them (what `omninav calib ring` reports for a video's frames).

    python -m bench.real_rings IMAGE... -o OUT
    cd web && OMNINAV_REAL_RINGS=OUT npx vitest run tests/ring.test.ts

The real lenses tried and where their pictures are: calib/README.md.
"""

from __future__ import annotations

import argparse
import json
from collections import defaultdict
from pathlib import Path

import cv2

from bench.common import machine
from omninav.calib.ring import NoRing, find_ring, find_ring_frame


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("images", nargs="+", type=Path)
    ap.add_argument("-o", "--out", type=Path, required=True)
    a = ap.parse_args()
    print(f"machine: {machine()}")
    a.out.mkdir(parents=True, exist_ok=True)
    items, folders = [], defaultdict(list)
    for i, path in enumerate(a.images):
        bgr = cv2.imread(str(path), cv2.IMREAD_COLOR)
        if bgr is None:
            raise SystemExit(f"not an image OpenCV reads: {path}")
        stem = f"real-{i:03d}"
        (a.out / f"{stem}.rgba").write_bytes(cv2.cvtColor(bgr, cv2.COLOR_BGR2RGBA).tobytes())
        ring = find_ring_frame(bgr)
        items.append(
            {"stem": stem, "src": str(path), "size": [bgr.shape[1], bgr.shape[0]], "engine": ring and ring.to_dict()}
        )
        folders[path.parent].append(bgr)
        got = "no ring"
        if ring is not None:
            got = f"centre {ring.center[0]:.2f}, {ring.center[1]:.2f}; r_inner {ring.r_inner:.2f}; "
            got += f"r_outer {ring.r_outer:.2f}"
        print(f"{path.name:>28} {bgr.shape[1]}x{bgr.shape[0]}: {got}")
    (a.out / "ring.json").write_text(json.dumps({"frames": items}, indent=1))
    for folder, frames in folders.items():
        if len(frames) < 2 or len({f.shape for f in frames}) > 1:
            continue
        try:
            r = find_ring(frames)
            print(
                f"{folder}: a ring in {r.frames_used} of {r.frames_total} frames; centre {r.center[0]:.2f}, "
                f"{r.center[1]:.2f}; r_inner {r.r_inner:.2f}; r_outer {r.r_outer:.2f}; spread {r.spread}"
            )
        except NoRing as e:
            print(f"{folder}: {e}")
    print(f"wrote {len(items)} frames to {a.out}")


if __name__ == "__main__":
    main()
