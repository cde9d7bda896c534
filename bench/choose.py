"""A venue that chooses its preset from an evaluation walk of its own, against one fixed default.

No fixed configuration wins on every source (docs/benchmarks.md, "Accuracy on three sources"): the five
narrow bands of intensity tell our renderer's identical doors apart and lose on the foreign pack,
one wide band does the opposite. A building can say which it is: the admin films an evaluation
walk (the admin page's evaluation walks, `omninav evaluate`), and the venue is answered with the
configuration that locates that walk best. Measured here without running anything again (the
answers of bench/venues.py and bench/foreign.py): each venue's queries in time order, the first
half is the evaluation walk that chooses (choose.pick, as `omninav choose-preset` does: the first
configuration unless another places clearly more of the half within 2 m), the second half is
scored; beside them, each configuration fixed for every venue, on the same second halves.
`one-band-levelled` has the settings of the `wide` preset.

    python -m bench.choose [--configs default,one-band-levelled] [--seeds 0,1,2]
"""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

import numpy as np

from bench import foreign
from bench.common import machine
from bench.scoring import conf_of, scores, summary
from bench.venues import rows_for
from omninav.choose import pick
from omninav.synth.families import FAMILIES


def halves(s: dict[str, np.ndarray]) -> tuple[dict[str, np.ndarray], dict[str, np.ndarray]]:
    n = len(s["near"]) // 2
    return {k: v[:n] for k, v in s.items()}, {k: v[n:] for k, v in s.items()}


def choose(per_config: dict[str, dict[str, np.ndarray]]) -> str:
    """The configuration the evaluation halves choose, by the engine's rule."""
    return pick({c: halves(s)[0]["near"] for c, s in per_config.items()})


def pooled(parts: list[dict[str, np.ndarray]]) -> dict[str, Any]:
    return summary({k: np.concatenate([p[k] for p in parts]) for k in parts[0]})


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--configs", default="default,one-band-levelled", help="the one kept first")
    ap.add_argument("--seeds", default="0")
    ap.add_argument("--pack", type=Path, default=foreign.PACK)
    a = ap.parse_args()
    configs = a.configs.split(",")
    print(f"machine: {machine()}")
    venues: dict[str, tuple[str, dict[str, dict[str, np.ndarray]]]] = {}
    for name, fam in FAMILIES.items():
        if fam.split != "held-out":
            continue
        for seed in (int(s) for s in a.seeds.split(",")):
            per = {c: scores(rows_for(name, seed, c, [1.0])[1.0], conf_of(c)) for c in configs}
            venues[f"{name}/{seed}"] = ("own", per)
    for v in foreign.pack_venues(a.pack) if a.pack.is_dir() else []:
        per = {c: scores(foreign.rows_for(a.pack, v, c, conf_of(c)), conf_of(c)) for c in configs}
        venues[v] = ("foreign", per)
    print("\nwithin 2 m: the evaluation half / the scored half")
    print(f"{'venue':<22}{'source':<9}" + "".join(f"{c:>22}" for c in configs) + "  picks")
    scored: dict[tuple[str, str], list[dict[str, np.ndarray]]] = {}
    for label, (source, per) in venues.items():
        pick = choose(per)
        cells = "".join(
            f"{halves(per[c])[0]['near'].mean():>14.1%} / {halves(per[c])[1]['near'].mean():>5.1%}" for c in configs
        )
        print(f"{label:<22}{source:<9}{cells}  {pick}")
        for c in configs:
            scored.setdefault((source, c), []).append(halves(per[c])[1])
        scored.setdefault((source, "chosen per venue"), []).append(halves(per[pick])[1])
    print("\nscored halves, pooled per source (within 2 m / 1 m, sure, sure and > 2 m off of all clips)")
    for source in ("own", "foreign"):
        for c in [*configs, "chosen per venue"]:
            if (source, c) in scored:
                s = pooled(scored[(source, c)])
                print(
                    f"  {source:<8}{c:<20}{int(s['clips']):>6}{s['within_2m']:>8.1%}{s['within_1m']:>8.1%}"
                    f"{s['sure']:>7.0%}{s['sure_far']:>8.1%}"
                )


if __name__ == "__main__":
    main()
