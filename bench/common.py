"""What every benchmark shares: the machine it ran on, the BLAS threads it runs with, the
previous commit's package beside this tree's, timings taken in turns, and synthetic spectra.

Every benchmark prints `machine()` and times against a baseline from the same run
(`baseline_package`, `timeit_ab`): the machines are shared and noisy.
"""

from __future__ import annotations

import os
import platform
import statistics
import sys
import time
from typing import Any

import numpy as np


def pin_threads(n: int) -> str:
    """Sets the BLAS (and OpenMP) pools of this process to n threads, after NumPy has loaded its
    BLAS (a limit set before that finds nothing to limit) -> what was set, for the report. One
    thread is what a server worker runs with (server/serve.py): with the default pool, another
    process busy on one of two cores made a small search 4x slower (its threads wait for each
    other)."""
    from threadpoolctl import threadpool_info, threadpool_limits  # type: ignore[import-untyped]

    threadpool_limits(n)
    pools = [f"{p['internal_api']} {p['num_threads']}" for p in threadpool_info()]
    return ", ".join(pools) or "no thread pools"


def baseline_package(rev: str, name: str = "omninav_base") -> Any:
    """The omninav package of git revision `rev`, imported beside the working tree's as `name`
    (from a detached worktree in the temp folder, made once): the same run times both."""
    import importlib.util
    import subprocess
    import tempfile
    from pathlib import Path

    repo = Path(__file__).resolve().parent.parent
    sha = subprocess.run(["git", "rev-parse", rev], cwd=repo, check=True, capture_output=True, text=True).stdout.strip()
    tree = Path(tempfile.gettempdir()) / f"omninav-base-{sha[:10]}"
    if not tree.exists():
        subprocess.run(
            ["git", "worktree", "add", "--detach", str(tree), sha], cwd=repo, check=True, capture_output=True
        )
    pkg = tree / "backend" / "omninav"
    spec = importlib.util.spec_from_file_location(name, pkg / "__init__.py", submodule_search_locations=[str(pkg)])
    assert spec is not None and spec.loader is not None
    mod = importlib.util.module_from_spec(spec)
    sys.modules[name] = mod
    spec.loader.exec_module(mod)
    return mod


def machine() -> str:
    cpu = platform.processor() or ""
    try:
        with open("/proc/cpuinfo") as f:
            cpu = next(line.split(":", 1)[1].strip() for line in f if line.startswith("model name"))
    except (OSError, StopIteration):
        pass
    return f"{cpu}, {os.cpu_count()} cores, numpy {np.__version__}, python {platform.python_version()}"


def random_spectra(n: int, c: int = 12, k: int = 16, seed: int = 0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    out = np.empty((n, c, k), np.complex64)
    block = 50_000
    state = (rng.normal(size=(c, k)) + 1j * rng.normal(size=(c, k))).astype(np.complex64)
    for s in range(0, n, block):
        m = min(block, n - s)
        steps = (rng.normal(size=(m, c, k)) + 1j * rng.normal(size=(m, c, k))).astype(np.complex64) * 0.2
        walk = state + np.cumsum(steps, axis=0)
        state = walk[-1]
        walk /= 1.0 + np.arange(1, k + 1, dtype=np.float32)  # energy falls with frequency, as in curves
        walk /= np.sqrt((np.abs(walk) ** 2).sum(axis=(1, 2), keepdims=True))
        out[s : s + m] = walk
    return out


def timeit(fn, repeat: int, sync=lambda: None) -> tuple[float, float]:
    fn()
    sync()
    ts = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        sync()
        ts.append(time.perf_counter() - t0)
    ts.sort()
    return statistics.median(ts) * 1e3, ts[int(0.9 * (len(ts) - 1))] * 1e3


def timeit_ab(fns: list, repeat: int, sync=lambda: None) -> list[tuple[float, float]]:
    """timeit() of several functions, each repeat running all of them in turn (the machine's load
    falls on all alike) -> (median, p90) ms of each."""
    for fn in fns:
        fn()
    sync()
    ts: list[list[float]] = [[] for _ in fns]
    for _ in range(repeat):
        for fn, t in zip(fns, ts, strict=True):
            t0 = time.perf_counter()
            fn()
            sync()
            t.append(time.perf_counter() - t0)
    out = []
    for t in ts:
        t.sort()
        out.append((statistics.median(t) * 1e3, t[int(0.9 * (len(t) - 1))] * 1e3))
    return out


def same_matches(a: Any, b: Any, tol: float = 1e-5) -> bool:
    """Whether two searches' matches agree: scores, stage-1 scores and headings within float32
    rounding where the ids agree, and where they differ, a tie (the baseline's score there
    equals this one's within tol: two candidates that tie may trade places)."""
    same = a.index == b.index
    dh = np.abs((a.heading - b.heading + 180.0) % 360.0 - 180.0)
    close = np.allclose(a.score[same], b.score[same], atol=tol) and np.allclose(
        a.coarse[same], b.coarse[same], atol=tol
    )
    ties = np.allclose(a.score[~same], b.score[~same], atol=tol) or np.allclose(
        np.sort(a.coarse[~same]), np.sort(b.coarse[~same]), atol=tol
    )
    return bool(close and (dh[same] < 1e-3).all() and ties)
