"""Accuracy on the foreign pack: venues from a renderer nobody on the team wrote.

Each venue of the pack (`../shared/foreign/` by default; docs/formats.md's formats, its README says
what each holds) is modelled from its walk with each configuration through the same path as
`omninav model` (model_venue.model_video), and each 1 s query clip is located as `omninav locate`
does (the clip's frames, the pack's phone lens, the ring corrected per clip). Scores, as the pack's
README asks (scoring.summary): within 1 m / 2 m of truth.json, the median heading error of the
answers within 2 m, the share answered sure (confidence >= 0.8), and the share of clips answered
sure and more than 2 m off.

Venues are cached under data/foreign/<venue>/ by what is modelled (a changed default is another
venue, never a stale one), answers with their confidence inputs by venue and search, so a
confidence refit is judged without running anything again (bench/calibrate.py reads the rows).

    python -m bench.foreign [--pack DIR] [--venues inst21,var22h] [--configs default,paper]
                            [--set KEY=JSON ...] [--json OUT]
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import Any

import numpy as np

from bench.ablation import CONFIGS, elevation_off
from bench.common import machine
from bench.scoring import conf_of, scores, summary
from bench.venues import cached_venue, search_tag, settings
from omninav.calib.correct import FIRST
from omninav.heading import wrap_deg
from omninav.lens import load_lens
from omninav.locate import Locator, clip_frames

PACK = Path(__file__).resolve().parents[1].parent / "shared" / "foreign"
DATA = Path("data") / "foreign"


def pack_venues(pack: Path) -> list[str]:
    return sorted(p.name for p in pack.iterdir() if (p / "model.mp4").is_file() and (p / "truth.json").is_file())


def chosen_venues(pack: Path, spec: str) -> list[str]:
    """A bench's `--venues`: "all" (the pack's), or names, comma-separated."""
    return pack_venues(pack) if spec == "all" else [v for v in spec.split(",") if v]


def modelled(pack: Path, venue: str, tag: str, conf: dict[str, Any]) -> Locator:
    """The pack venue's walk modelled with `conf` (as `omninav model` does), once per settings."""
    src = pack / venue
    lens = "model_lens.json" if (src / "model_lens.json").is_file() else "lens.json"
    return cached_venue(src, tag, conf, lens=lens, walk_path="track.json", store=DATA / venue / "bench-data")


def query_spectra(
    pack: Path, venue: str, loc: Locator, elev: float = 0.0
) -> list[tuple[dict[str, Any], np.ndarray, float]]:
    """Each query clip's truth, spectra and frame rate, extracted as `omninav locate` does (the
    pack's phone lens, `elev` degrees off in elevation, the ring corrected per clip); cached by
    the venue's feature settings."""
    src = pack / venue
    truths = json.loads((src / "truth.json").read_text())
    cache = DATA / venue / f"queries-{loc.venue_id}{_elev_tag(elev)}.npz"
    if cache.exists():
        z = np.load(cache)
        return [(t, z[t["clip"]], float(z["fps"][i])) for i, t in enumerate(truths)]
    lens = elevation_off(load_lens(src / "lens.json"), elev)
    out = []
    for t in truths:
        frames, fps = clip_frames(src / "queries" / t["clip"], loc.conf["model_fps"])
        loc.extractor(lens).check_frame(frames[0], t["clip"])
        spec = np.stack(list(loc.clip_lens(lens).spectra(frames)))
        out.append((t, spec, fps))
    np.savez(cache, fps=np.array([f for _, _, f in out]), **{t["clip"]: s for t, s, _ in out})
    return out


def _elev_tag(elev: float) -> str:
    return f"-elev{elev:+g}" if elev else ""


def rows_for(pack: Path, venue: str, tag: str, conf: dict[str, Any], elev: float = 0.0) -> list[dict[str, Any]]:
    """Every query clip's answer, its error and its confidence inputs (cached beside the venue);
    `elev`: the phone's lens profile that many degrees off in elevation."""
    loc = modelled(pack, venue, tag, conf)
    name = f"rows-{loc.venue_id}{search_tag(loc.conf)}-{loc.conf['aggregate']}{_elev_tag(elev)}.json"
    cache = DATA / venue / name
    if cache.exists():
        return list(json.loads(cache.read_text()))
    rows = []
    for truth, spec, fps in query_spectra(pack, venue, loc, elev):
        local = None
        if loc.verifies:  # as `omninav locate` verifies the clip's frames (Locator.locate_frames)
            frames, _ = clip_frames(pack / venue / "queries" / truth["clip"], loc.conf["model_fps"])
            c = loc.clip_lens(elevation_off(load_lens(pack / venue / "lens.json"), elev))
            list(c.spectra(frames[:FIRST]))  # (the clip's lens is decided on its first frames)
            local = loc.local_features(frames[-1], c.lens)
        e, outcome = loc.estimate_local(spec, np.arange(len(spec)) / fps, None, local)
        rows.append(
            {
                "clip": truth["clip"],
                "x": e.x,
                "y": e.y,
                "err_m": float(np.hypot(e.x - truth["x"], e.y - truth["y"])),
                "heading_err_deg": float(wrap_deg(e.heading - truth["heading_deg"])),
                "confidence": loc.confidence(e, outcome),
                "support": e.support,
                "rival": e.rival,
                "agree": e.agree,
                **({"verified": outcome} if outcome is not None else {}),
            }
        )
    cache.write_text(json.dumps(rows))
    return rows


HEAD = f"{'venue':<10}{'config':<26}{'clips':>6}{'<=1 m':>8}{'<=2 m':>8}{'hdg med':>9}{'sure':>7}{'sure>2m':>9}"


def line(venue: str, config: str, s: dict[str, Any]) -> str:
    return (
        f"{venue:<10}{config:<26}{int(s['clips']):>6}{s['within_1m']:>8.1%}{s['within_2m']:>8.1%}"
        f"{s['heading_deg']:>8.2f}°{s['sure']:>7.0%}{s['sure_far']:>9.1%}"
    )


def pack_parser(doc: str, venues: str = "all") -> argparse.ArgumentParser:
    """A pack benchmark's command line: its docstring's first line, --pack and --venues (default
    `venues`: "all" or names, chosen_venues)."""
    ap = argparse.ArgumentParser(description=doc.splitlines()[0])
    ap.add_argument("--pack", type=Path, default=PACK)
    ap.add_argument("--venues", default=venues)
    return ap


def main() -> None:
    ap = pack_parser(__doc__)
    ap.add_argument("--configs", default="default,paper", help=f"of: {', '.join(CONFIGS)}")
    ap.add_argument("--set", action="append", default=[], metavar="KEY=JSON", help="a setting over every configuration")
    ap.add_argument("--elev", default="0", help="the phone's lens profile off by these degrees (comma-separated)")
    ap.add_argument("--json", type=Path, help="write every summary here")
    a = ap.parse_args()
    if not a.pack.is_dir():
        raise SystemExit(f"{a.pack}: no foreign pack there (--pack)")
    venues = chosen_venues(a.pack, a.venues)
    over = settings(a.set)
    print(f"machine: {machine()}")
    if over:
        print(f"settings over the configurations: {over}")
    print(HEAD)
    out = []
    for config in a.configs.split(","):
        conf = {**conf_of(config), **over}
        for venue in venues:
            for elev in (float(e) for e in a.elev.split(",")):
                s = summary(scores(rows_for(a.pack, venue, config, conf, elev), conf))
                label = f"{config} {elev:+g}°" if elev else config
                print(line(venue, label, s), flush=True)
                out.append({"venue": venue, "config": config, "elev_deg": elev, **s})
    if a.json:
        a.json.write_text(json.dumps(out, indent=1))


if __name__ == "__main__":
    main()
