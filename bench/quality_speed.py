"""Quality-map speed: seconds per 1,000 modelled frames, against locating the same clips one by one.

For each venue size N it times, in the same run on the same generation:
  - `quality`: omninav.quality.quality_map (every 1 s clip of the walk, each frame searched
    without itself, all clips in one batched search, then aggregated and scored),
  - `locate`: the plain Locator.estimate of the same N/10 clips, one call per clip (what the
    server would do answering them as phone requests; no exclusion, no scoring).
The venue is synthetic: the spectra of a smooth random walk (common.random_spectra), placed along a
serpentine walk at 1.2 m/s and 10 fps, cut into 5-minute videos, written and loaded through the
store as a modelled venue is (so the index arrays are precomputed and memory-mapped).

    python -m bench.quality_speed [--sizes 1000,5000,20000] [--device cpu|gpu] [--shortlists 16,32]

`--shortlists`: the search's stage-1 shortlist a frame (index.py, "The shortlist"), one row each in
the same run; by default the default preset's.
"""

from __future__ import annotations

import argparse
import tempfile
import time

import numpy as np

from bench.common import machine
from bench.common import random_spectra as venue
from omninav.locate import Locator  # noqa: E402
from omninav.presets import n_curves, resolve  # noqa: E402
from omninav.quality import CLIP_S, quality_map  # noqa: E402
from omninav.store import FRAME_DTYPE, Generation, Store  # noqa: E402
from omninav.synth import donut_lens  # noqa: E402

FPS = 10.0
SPEED = 1.2
VIDEO_FRAMES = 3000  # 5 minutes at 10 fps


def generation(n: int, shortlist: int | None = None) -> Generation:
    """N frames of a serpentine walk: 60 m legs 4 m apart, videos of VIDEO_FRAMES frames."""
    conf = resolve("default", {"shortlist": shortlist} if shortlist else None)
    spec = venue(n, n_curves(conf), conf["n_harmonics"])
    s = np.arange(n) * SPEED / FPS  # metres walked
    leg, along = np.divmod(s, 60.0)
    frames = np.zeros(n, FRAME_DTYPE)
    forward = leg % 2 == 0
    frames["x"] = 2.0 + np.where(forward, along, 60.0 - along)
    frames["y"] = 2.0 + 4.0 * leg
    frames["heading"] = np.where(forward, 90.0, 270.0)
    frames["video"] = np.arange(n) // VIDEO_FRAMES
    frames["t"] = (np.arange(n) % VIDEO_FRAMES) / FPS
    frames["frame"] = np.arange(n) % VIDEO_FRAMES
    videos = [f"walk{v}.mp4" for v in range(int(frames["video"].max()) + 1)]
    return Generation(conf, donut_lens(0.5), frames, spec, videos)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--sizes", default="1000,5000,20000")
    ap.add_argument("--device", default="cpu", choices=["cpu", "gpu"])
    ap.add_argument("--shortlists", help="stage 1's shortlists a frame, comma-separated (default: the preset's)")
    args = ap.parse_args()
    shortlists = [int(v) for v in args.shortlists.split(",")] if args.shortlists else [resolve("default")["shortlist"]]
    print(f"machine: {machine()}, device {args.device}")
    head = f"{'frames':>8}{'list':>5}{'clips':>7}{'quality s':>11}{'s / 1k frames':>15}"
    head += f"{'locate s':>10}{'s / 1k':>8}{'ratio':>7}"
    print(head)
    print("-" * len(head))
    for n, shortlist in ((int(v), sl) for v in args.sizes.split(",") for sl in shortlists):
        with tempfile.TemporaryDirectory() as tmp:
            st = Store(tmp)
            st.commit("bench", generation(n, shortlist))
            gen = st.load("bench")
            t0 = time.perf_counter()
            r = quality_map(gen, [], {}, device=args.device)
            tq = time.perf_counter() - t0
            loc = Locator(st, "bench", device=args.device)
            clip = int(round(CLIP_S * gen.settings["model_fps"]))
            t = np.asarray(gen.frames["t"], np.float64)
            t0 = time.perf_counter()
            for s in range(0, n - clip + 1, clip):
                loc.estimate(np.asarray(gen.spectra[s : s + clip]), t[s : s + clip] - t[s])
            tl = time.perf_counter() - t0
            clips = len(r["segments"])
            quality = f"{n:>8}{shortlist:>5}{clips:>7}{tq:>11.2f}{1000 * tq / n:>15.3f}"
            print(f"{quality}{tl:>10.2f}{1000 * tl / n:>8.3f}{tl / tq:>6.1f}x")


if __name__ == "__main__":
    main()
