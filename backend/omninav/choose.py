"""Which preset answers this building best (`omninav choose-preset`): the modelling walk modelled
with each candidate preset, an evaluation walk located against each, the preset that places more of
its clips within 2 m chosen.

No one preset wins everywhere (docs/benchmarks.md, "Three sources"): the default's five narrow
bands of intensity tell identical doors apart where the modelling walk and the users' phones see
the walls alike, and lose where they do not (another height, tilt, place across the corridor, lens
calibration); "wide" holds there and gives up some of the doors. A building says which it is: with
half of each venue's query clips as its evaluation walk, the default was chosen on all twelve of
our held-out venues and "wide" on both foreign ones, so the other halves were answered as well as
the better fixed preset answers each source (bench/choose.py). The walks are modelled into a
scratch store, so the catalogue is not touched: the admin then creates the venue with the preset
chosen.
"""

from __future__ import annotations

import tempfile
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

from .errors import OmninavError
from .evaluate import evaluate
from .lens import Lens
from .locate import Locator
from .model_venue import model_video
from .presets import PRESETS, resolve
from .store import Store
from .track import Track

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


def pick(results: Sequence[dict[str, Any]]) -> str:
    """The preset with the most clips within 2 m, then the most answered sure; the first on a tie
    (the default, listed first, stays unless another does better)."""
    best = max(
        range(len(results)),
        key=lambda i: (results[i]["within_2m"], results[i]["confident_share"], -i),
    )
    return str(results[best]["preset"])


def compare_presets(
    walk: Path,
    track: Track,
    lens: Lens,
    eval_video: Path,
    eval_track: Track,
    eval_lens: Lens | None,
    presets: Sequence[str] = CANDIDATES,
    progress: Callable[[str], None] | None = None,
) -> list[dict[str, Any]]:
    """Each preset's evaluation summary (evaluate.Evaluation.summary, with "preset" and the
    modelled frames), the walk modelled with it into a scratch store."""
    names = check_presets(presets)
    out = []
    with tempfile.TemporaryDirectory(prefix="omninav-choose-") as tmp:
        st = Store(Path(tmp))
        for name in names:
            if progress:
                progress(f"modelling {walk.name} with the {name} preset")
            r = model_video(st, name, walk, track, lens, settings=resolve(name))
            if progress:
                progress(f"locating {eval_video.name} against it")
            s = evaluate(Locator(st, name, device="cpu"), eval_video, eval_track, eval_lens).summary()
            if not s.get("clips"):
                raise OmninavError(f"{eval_video}: no clip of the evaluation walk lies within its track")
            out.append({"preset": name, "venue_frames": r.total_frames, **s})
    return out
