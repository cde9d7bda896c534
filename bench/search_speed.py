"""Search speed, the paper's Fig. 8 experiment: one 10-frame clip against N venue frames.

For N = 1,000 ... 8,000, then 100,000 and 1,000,000, it times
  - `batched`: omninav's index (stage-1 magnitude GEMM + top-k, stage-2 phase verification),
    each frame verifying its own candidates (as before shared candidates),
  - `shared`: the same with the clip's candidates shared (each frame verified against every
    frame's; what `omninav locate` searches), for a clip of one place (its frames a little noisy,
    so that their candidates differ as a real clip's do: `union` rows verified a frame) and for
    the worst case, ten frames from ten places (10 x the shortlist rows a frame),
  - `locate`: the shared search plus clip aggregation (what `omninav locate` does after extraction),
  - `loop`: the paper's sequential CPU search, a per-frame Python loop (N <= 8,000 only);
    `speed-up` is loop against locate (since shared candidates, the shared search's locate),
in the same run on the same data, and prints the machine it ran on. Venue spectra are synthetic
(a smooth random walk in the Fourier domain), which costs the same to search as real ones.

    python -m bench.search_speed [--sizes 1000,8000] [--device cpu|gpu] [--repeat 30] [--curves 12,14]
                                 [--shortlists 16,32] [--threads 1] [--baseline REV]

`--threads`: the BLAS threads (default 1, as a server worker runs; 0: the library's default).
`--baseline REV`: also times git revision REV's index and aggregation (imported from a worktree
beside this one) on the same data, each repeat of the two interleaved, and checks that they give
the same candidates (ids equal where the stage-1 scores do not tie, scores within float32
rounding): `shared` and `locate` rows of the baseline printed as `base`. And `scan ms`: one pass
that sums the first pass's keys, what the memory bandwidth allows stage 1 at that size.

`--curves`: curves a frame (each with the default's 16 harmonics), one table row per size and
count in the same run; by default the default preset's (14 since the five bands of intensity).
`--shortlists`: stage 1's shortlist a frame in the shared search (index.py, "The shortlist"), one
row each in the same run; by default the default preset's (32; 16 is the search before it).
"""

from __future__ import annotations

import argparse
from typing import Any

import numpy as np

from bench.common import baseline_package, machine, pin_threads, random_spectra, same_matches, timeit, timeit_ab
from omninav.aggregate import sequence
from omninav.index import Index, sequential_search
from omninav.presets import n_curves, resolve


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--sizes", default="1000,2000,4000,8000,100000,1000000")
    ap.add_argument("--device", default="cpu")
    ap.add_argument("--repeat", type=int, default=30)
    ap.add_argument("--curves", help="curves a frame, comma-separated (default: the default preset's)")
    ap.add_argument("--shortlists", help="stage 1's shortlists a frame, comma-separated (default: the preset's)")
    ap.add_argument("--threads", type=int, default=1, help="BLAS threads (0: the library's default)")
    ap.add_argument("--baseline", help="git revision to time beside the working tree, in the same run")
    a = ap.parse_args()
    pools = pin_threads(a.threads) if a.threads > 0 else "library default threads"
    global BASE
    if a.baseline:
        import importlib

        baseline_package(a.baseline)
        BASE = (importlib.import_module("omninav_base.index"), importlib.import_module("omninav_base.aggregate"))
    conf = resolve("default")
    curves = [int(c) for c in a.curves.split(",")] if a.curves else [n_curves(conf)]
    shortlists = [int(s) for s in a.shortlists.split(",")] if a.shortlists else [conf["shortlist"]]
    print(f"machine: {machine()}; device {a.device}; BLAS: {pools}; baseline: {a.baseline or 'none'}")
    cols = ["batched ms", "p90", "shared ms", "p90", "union", "worst ms", "locate ms", "p90", "loop ms", "speed-up"]
    widths = [11, 7, 10, 7, 6, 9, 10, 7, 9, 9]
    if a.baseline:
        cols, widths = [*cols, "base shared", "base locate", "scan ms", "same"], [*widths, 11, 11, 8, 6]
    head = f"{'frames':>9} {'curves':>6} {'dims':>5} {'list':>4} "
    print(head + " ".join(f"{c:>{w}}" for c, w in zip(cols, widths, strict=True)))
    for n in [int(s) for s in a.sizes.split(",")]:
        for c in curves:
            for sl in shortlists:
                print(bench_size(n, a.device, a.repeat, conf, c, sl), flush=True)


def bench_size(n: int, device: str, repeat: int, conf: dict, curves: int, shortlist: int) -> str:
    rng = np.random.default_rng(n)
    spec = random_spectra(n, c=curves, k=conf["n_harmonics"])
    heads = rng.uniform(0, 360, n).astype(np.float32)
    xy = np.cumsum(rng.normal(size=(n, 2)) * 0.1, axis=0)
    dims = conf["key_dims"] if n > conf["key_project_above"] else 0
    ix = Index(spec, heads, device=device, key_dims=dims)
    sync = (lambda: ix.xp.cuda.Device().synchronize()) if ix.xp is not np else (lambda: None)
    row = int(rng.integers(0, n - 10))
    noise = rng.normal(size=(10, *spec.shape[1:])) + 1j * rng.normal(size=(10, *spec.shape[1:]))
    q = spec[row : row + 10] * np.exp(1j * 0.7) + 0.03 * noise  # each frame ~0.3 of its energy in noise
    q = (q / np.sqrt((np.abs(q) ** 2).sum(axis=(1, 2), keepdims=True))).astype(np.complex64)
    apart = spec[rng.choice(n, 10, replace=False)]  # the worst case: ten places, 10 x shortlist rows to verify
    times = np.arange(10) / 10.0
    one = np.zeros(10, np.int64)  # a 1 s clip: one group (locate.clip_groups)
    k = conf["candidates"]
    rep = repeat if n <= 100_000 else max(5, repeat // 6)
    b50, b90 = timeit(lambda: ix.search(q, k), rep, sync)
    extra = ""
    if BASE is not None:  # the baseline's shared search and locate, interleaved with this tree's
        old_index, old_aggregate = BASE
        arrays = {"keys": ix.keys, "keys_t": np.ascontiguousarray(ix.first.T)}  # the layout before `first`
        if ix.basis is not None:
            arrays["basis"] = ix.basis
        old = old_index.Index(spec, heads, device=device, key_dims=dims, arrays=arrays)
        pair = [
            lambda: ix.search(q, k, groups=one, shortlist=shortlist),
            lambda: old.search(q, k, groups=one, shortlist=shortlist),
        ]
        (s50, s90), (o50, _) = timeit_ab(pair, rep, sync)
        pair = [
            lambda: sequence(ix.search(q, k, groups=one, shortlist=shortlist), xy, times, conf),
            lambda: old_aggregate.sequence(old.search(q, k, groups=one, shortlist=shortlist), xy, times, conf),
        ]
        (l50, l90), (ol50, _) = timeit_ab(pair, rep, sync)
        first = ix.first
        scan, _ = timeit(lambda: first.sum(), max(3, rep // 3), sync)
        same = all(
            same_matches(
                ix.search(x, k, groups=one, shortlist=shortlist), old.search(x, k, groups=one, shortlist=shortlist)
            )
            for x in (q, apart)
        )
        extra = f" {o50:11.3f} {ol50:11.3f} {scan:8.2f} {'yes' if same else 'NO':>6}"
    else:
        s50, s90 = timeit(lambda: ix.search(q, k, groups=one, shortlist=shortlist), rep, sync)
        l50, l90 = timeit(
            lambda: sequence(ix.search(q, k, groups=one, shortlist=shortlist), xy, times, conf), rep, sync
        )
    union = len(np.unique(ix.shortlisted(q, k, shortlist)[0]))
    w50, _ = timeit(lambda: ix.search(apart, k, groups=one, shortlist=shortlist), rep, sync)
    if n <= 8000:
        lp, _ = timeit(lambda: sequential_search(q, spec), 1)
        loop = f"{lp:9.1f} {lp / l50:8.0f}x"
    else:
        loop = f"{'-':>9} {'-':>9}"
    size = f"{n:>9} {curves:>6} {dims or spec.shape[1] * spec.shape[2]:>5} {shortlist:>4}"
    shared = f"{s50:10.3f} {s90:7.3f} {union:6d} {w50:9.3f}"
    return f"{size} {b50:11.3f} {b90:7.3f} {shared} {l50:10.3f} {l90:7.3f} {loop}{extra}"


BASE: Any = None  # (index, aggregate) modules of --baseline's revision


if __name__ == "__main__":
    main()
