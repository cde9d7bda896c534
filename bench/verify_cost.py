"""What the `verified` venue option costs (verify.py): modelling, storage and locating a clip.

On each foreign pack venue (or any pack folder with model.mp4, track.json, lens.json and queries/),
modelled once as `default` and once as `verified` in the same run (fresh stores, so both model
times are measured here), then every query clip located from its frames as `omninav locate`
does (Locator.locate_frames: extraction, search, aggregation and, for `verified`, verification),
alternating the two venues clip by clip; and located from the record a phone sends (what the
server does with a request: the record decoded, searched, aggregated and, for `verified`, a
version-2 record's keypoints verified; HTTP and nginx, ~1-3 ms, not included). Printed per venue:
the model time of each, the local features' bytes per 1,000 modelled frames, and each locate
time's median and p90.

    python -m bench.verify_cost [--pack DIR] [--venues inst21] [--clips 30]
"""

from __future__ import annotations

import tempfile
import time
from pathlib import Path

import numpy as np

from bench.common import machine
from bench.foreign import chosen_venues, pack_parser
from omninav.calib.correct import clip_spectra
from omninav.extract import Extractors
from omninav.lens import Lens, load_lens
from omninav.locate import Locator, clip_frames
from omninav.model_venue import model_video
from omninav.presets import resolve
from omninav.spectrum import decode_binary_local, encode_binary
from omninav.store import Store
from omninav.walk_path import load_walk_path


def phone_records(
    locs: dict[str, Locator], extractors: Extractors, lens: Lens, frames: list[np.ndarray], name: str
) -> dict[str, bytes]:
    """A clip's record as the phone sends it to each venue: version 1 (the curves) to one without
    local features, 2 (and the last frame's keypoints, through the clip's ring-corrected lens) to
    a `verified` one; `extractors` make the curves (both presets' are the default's)."""
    spec, c = clip_spectra(lens, frames, extractors.spectrum, clip=name)
    return {
        p: encode_binary(spec, loc.conf, loc.local_features(frames[-1], c.lens) if loc.verifies else None)
        for p, loc in locs.items()
    }


def run(pack: Path, venue: str, clips: int) -> None:
    src = pack / venue
    model_lens = load_lens(src / ("model_lens.json" if (src / "model_lens.json").is_file() else "lens.json"))
    lens = load_lens(src / "lens.json")
    walk = load_walk_path(src / "track.json")
    with tempfile.TemporaryDirectory(prefix="omninav-verify-cost-") as d:
        locs, model_s = {}, {}
        for preset in ("default", "verified"):
            st = Store(Path(d) / preset)
            t = time.perf_counter()
            model_video(st, venue, src / "model.mp4", walk, model_lens, settings=resolve(preset))
            model_s[preset] = time.perf_counter() - t
            locs[preset] = Locator(st, venue, device="cpu")
        local = locs["verified"].gen.local
        assert local is not None
        n_frames = len(locs["verified"].gen.frames)
        names = sorted(p.name for p in (src / "queries").iterdir())[:clips]
        ms: dict[str, list[float]] = {p: [] for p in locs}
        extractors = Extractors(locs["default"].conf)  # both presets' curves are the default's
        rec_ms: dict[str, list[float]] = {p: [] for p in locs}
        rec_bytes: dict[str, list[int]] = {p: [] for p in locs}
        for name in names:
            frames, fps = clip_frames(src / "queries" / name, locs["default"].conf["model_fps"])
            for preset, loc in locs.items():
                t = time.perf_counter()
                loc.locate_frames(frames, name, lens, fps)
                ms[preset].append(1e3 * (time.perf_counter() - t))
            recs = phone_records(locs, extractors, lens, frames, name)
            for preset, loc in locs.items():
                rec = recs[preset]
                rec_bytes[preset].append(len(rec))
                t = time.perf_counter()
                got, lq = decode_binary_local(rec, loc.conf)
                loc.locate_spectra(got, name, fps, local=lq)
                rec_ms[preset].append(1e3 * (time.perf_counter() - t))
    print(
        f"{venue}: {n_frames} modelled frames, {len(local.places)} places with local features, "
        f"{local.nbytes() / n_frames * 1000 / 1e6:.1f} MB per 1,000 frames"
    )
    for preset in locs:
        a = np.array(ms[preset])
        print(
            f"  {preset:<9} modelled in {model_s[preset]:5.1f} s; locate a clip from its frames "
            f"median {np.median(a):6.1f} ms, p90 {np.percentile(a, 90):6.1f} ms ({len(a)} clips)"
        )
        r = np.array(rec_ms[preset])
        print(
            f"  {'':<9} from its record ({np.median(rec_bytes[preset]) / 1024:.1f} KB): "
            f"median {np.median(r):6.1f} ms, p90 {np.percentile(r, 90):6.1f} ms"
        )


def main() -> None:
    ap = pack_parser(__doc__, venues="inst21")
    ap.add_argument("--clips", type=int, default=30)
    a = ap.parse_args()
    print(f"machine: {machine()}")
    for venue in chosen_venues(a.pack, a.venues):
        run(a.pack, venue, a.clips)


if __name__ == "__main__":
    main()
