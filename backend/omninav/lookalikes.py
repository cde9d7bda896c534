"""Which places of a venue look alike to its own model: each walk graph node's nearest modelling
frame searched in the venue's index like a query frame. The tracking filter's second belief reads
the table (tracking.py, `track_alike_cost`); the Locator keeps it per venue generation.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import fields
from typing import TYPE_CHECKING, Any

import numpy as np

from .index import Matches
from .presets import setting
from .walkgraph import nearest_on_floor

if TYPE_CHECKING:
    from .walkgraph import WalkGraph

ALIKE_K = 64  # candidates of each node's frame searched for its look-alikes (a corridor's doors)
ALIKE_CELLS = 1 << 24  # node frames x venue frames scored per pass of that search (64 MB of float32)
ALIKE_FRAMES = 128  # and at most this many node frames a pass (each re-ranks 8 x ALIKE_K full keys)


def node_frames(graph: WalkGraph, venue_xy: np.ndarray, venue_floor: np.ndarray) -> np.ndarray:
    """(N,) int64: each node's nearest venue frame on its floor (any floor's, if its has none)."""
    return nearest_on_floor(graph.xy, graph.floor, venue_xy, venue_floor)


def frame_search(
    search: Callable[[np.ndarray, int], Matches], spectra: np.ndarray
) -> Callable[[np.ndarray, int], Matches]:
    """Venue frame rows -> their matches in the venue's own index (`search`: index.Index.search),
    searched in passes of at most ALIKE_FRAMES rows and ALIKE_CELLS row x venue frame scores:
    bounded memory on any venue."""
    spec = np.asarray(spectra)

    def run(rows: np.ndarray, k: int) -> Matches:
        step = max(1, min(ALIKE_FRAMES, ALIKE_CELLS // max(1, len(spec))))
        parts = [search(spec[rows[s : s + step]], k) for s in range(0, len(rows), step)]
        return Matches(*(np.concatenate([getattr(p, f.name) for p in parts]) for f in fields(Matches)))

    return run


def look_alikes(
    search_rows: Callable[[np.ndarray, int], Matches],
    graph: WalkGraph,
    venue_xy: np.ndarray,
    venue_floor: np.ndarray,
    conf: Mapping[str, Any],
    k: int = ALIKE_K,
) -> Matches | None:
    """(N, k) matches of each node's nearest modelling frame searched in the venue's own index
    (`search_rows`: frame_search, or Locator.frame_matches, which keeps them): what the Tracker
    takes as `alike`. None when the venue's settings turn look-alikes off, or without nodes."""
    if setting(conf, "track_alike_cost") is None or len(graph.xy) == 0:
        return None
    return search_rows(node_frames(graph, venue_xy, venue_floor), k)
