"""Which preset answers this building best (`omninav choose-preset`): the modelling walk modelled
with each candidate preset, an evaluation walk of the same building located against each, and the
first preset kept unless another places clearly more of its clips within 2 m.

No one preset wins everywhere (docs/benchmarks.md, "Accuracy on three sources"): the default's five narrow
bands of intensity tell identical doors apart where the modelling walk and the users' phones see
the walls alike, and lose where they do not (another height, tilt, place across the corridor);
"wide" holds there and gives up some of the doors. A building's own evaluation walk says which it
is (bench/choose.py measures the choice). "Clearly" is the adoption rule's noise
(docs/benchlog.md): more than twice the paired standard error of the difference, the clips being
the same for every preset. The walks are modelled into a scratch store, so the catalogue is not
touched: the admin then creates the venue with the preset chosen.
"""

from __future__ import annotations

import math
import tempfile
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from .errors import OmninavError
from .evaluate import evaluate
from .lens import Lens
from .locate import Locator
from .model_venue import model_video
from .presets import PRESETS, resolve
from .store import Store
from .walk_path import WalkPath

CANDIDATES = ("default", "wide")


def check_presets(presets: Sequence[str]) -> list[str]:
    """Two or more distinct known presets, in the order given (the first wins a tie)."""
    names = list(presets)
    unknown = [p for p in names if p not in PRESETS]
    if unknown:
        raise OmninavError(f"unknown presets {unknown} (known: {', '.join(PRESETS)})")
    if len(names) < 2 or len(set(names)) != len(names):
        raise OmninavError(f"give two or more different presets to choose among; got {names}")
    return names


def paired_se(a: np.ndarray, b: np.ndarray) -> float:
    """(n,) booleans of two methods on the same n clips -> the standard error of mean(b) - mean(a).

    The Wald form of McNemar's test: only the clips the two answer differently carry information,
    sqrt(b + c - (b - c)^2 / n) / n for b clips only `a` gets right and c only `b` does."""
    n = len(a)
    if n == 0 or len(b) != n:
        raise ValueError(f"paired outcomes need the same clips: {len(a)} and {len(b)}")
    only_a, only_b = int(np.sum(a & ~b)), int(np.sum(b & ~a))
    return math.sqrt(max(only_a + only_b - (only_b - only_a) ** 2 / n, 0.0)) / n


def pick(near: Mapping[str, np.ndarray]) -> str:
    """Each preset's (n,) within-2-m outcomes on the same clips, the first listed first -> the first
    preset, unless another places more clips within 2 m by more than twice the paired standard
    error (then the one of those that places the most)."""
    names = list(near)
    first = np.asarray(near[names[0]], bool)
    clear = [
        n for n in names[1:] if float(near[n].mean() - first.mean()) > 2 * paired_se(first, np.asarray(near[n], bool))
    ]
    return max(clear, key=lambda n: (float(near[n].mean()), -names.index(n))) if clear else names[0]


def compare_presets(
    walk: Path,
    walk_path: WalkPath,
    lens: Lens,
    eval_video: Path,
    eval_walk_path: WalkPath,
    eval_lens: Lens | None,
    presets: Sequence[str] = CANDIDATES,
    progress: Callable[[str], None] | None = None,
) -> tuple[list[dict[str, Any]], str]:
    """(each preset's evaluation summary, evaluate.Evaluation.summary with "preset" and the
    modelled frames; the preset chosen), the walk modelled with each into a scratch store."""
    names = check_presets(presets)
    out, near = [], {}
    with tempfile.TemporaryDirectory(prefix="omninav-choose-") as tmp:
        st = Store(Path(tmp))
        for name in names:
            if progress:
                progress(f"modelling {walk.name} with the {name} preset")
            r = model_video(st, name, walk, walk_path, lens, settings=resolve(name))
            if progress:
                progress(f"locating {eval_video.name} against it")
            ev = evaluate(Locator(st, name), eval_video, eval_walk_path, eval_lens)
            s = ev.summary()
            if not s.get("clips"):
                raise OmninavError(f"{eval_video}: no clip of the evaluation walk lies within its walk path")
            near[name] = np.array([row["err_m"] <= 2.0 for row in ev.rows])
            out.append({"preset": name, "venue_frames": r.total_frames, **s})
    return out, pick(near)
