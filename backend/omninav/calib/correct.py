"""Every clip through the lens as it sits now: a re-clipped donut lens corrected per clip.

A clip-on lens never sits where it sat when its profile was made; a few pixels of centre turn into
heading error and, past a few more, wrong places. The engine's own extraction paths (`omninav
locate`/`features`/`evaluate` on frames or videos, modelling, and the server's frames/video locate)
find the ring in a clip's first frames (`lens_fit.corrected_lens`) and extract every frame of the clip
through the profile moved to that ring. The phone does the same in its worker (web/src/worker/ring.ts).

The first `FIRST` frames are held back until the ring is known, so a clip still costs one decoded
frame at a time after them: what bounds a request's memory (server/locate_api.py) is kept.
"""

from __future__ import annotations

import logging
from collections.abc import Callable, Iterable, Iterator, Sequence
from typing import Any, Generic, TypeVar

import numpy as np

from ..lens import Catadioptric, Lens
from .lens_fit import TOO_FAR_SHARE, LensFit, corrected_lens, scaled_lens

log = logging.getLogger("omninav.calib")

FIRST = 3  # frames the ring is measured on: a median of three rides over one frame's clutter

Spectrum = TypeVar("Spectrum")  # what the per-frame function gives: a spectrum, or a future of one


class ClipLens(Generic[Spectrum]):
    """Frames of one clip -> their spectra through the lens corrected for this clip.

    `extract(lens)` gives the per-frame function for a lens (a cached Extractor's `spectrum`, or
    one that hands each frame to a pool: video.on_pool), whose results pass through untouched;
    `check(frame)` refuses a frame of the wrong size before anything looks at it. After the
    first `FIRST` frames (or `flush`), `fit` says what was found and `lens` is the lens used.
    """

    def __init__(
        self,
        lens: Lens,
        extract: Callable[[Lens], Callable[[np.ndarray], Spectrum]],
        check: Callable[[np.ndarray], None] | None = None,
        first: int = FIRST,
    ):
        self.profile = lens
        self.lens: Lens = lens
        self.fit: LensFit | None = None
        self._extract = extract
        self._check = check
        self._first = first
        self._held: list[np.ndarray] = []
        self._fn: Callable[[np.ndarray], Spectrum] | None = None

    def feed(self, frame: np.ndarray) -> list[Spectrum]:
        """One frame in; the spectra that are ready out (none while the first frames are held)."""
        if self._check is not None and self._fn is None and not self._held:
            self._check(frame)
        if self._fn is not None:
            return [self._fn(frame)]
        self._held.append(frame)
        return self.flush() if len(self._held) >= self._first else []

    def flush(self) -> list[Spectrum]:
        """Decide the lens on what is held (a clip shorter than FIRST frames) and extract it."""
        if self._fn is None:
            if isinstance(self.profile, Catadioptric) and self._held:
                self.fit = f = corrected_lens(self.profile, self._held)
                self.lens = f.lens
                near = (
                    f.moved_px <= TOO_FAR_SHARE * self.profile.reference_ring()[3] and abs(f.scale - 1) <= TOO_FAR_SHARE
                )
                if f.verdict == "cut" and near:
                    # the phone asks for the lens to be clipped on again; here nobody can, and the
                    # ring found (cut by the edge) still says where the lens sits
                    self.lens = scaled_lens(self.profile, (f.dx, f.dy), f.scale)
            self._fn = self._extract(self.lens)
        held, self._held = self._held, []
        return [self._fn(f) for f in held]

    def spectra(self, frames: Iterable[np.ndarray]) -> Iterator[Spectrum]:
        for f in frames:
            yield from self.feed(f)
        yield from self.flush()

    def warning(self, clip: str) -> str | None:
        """A line for the log when the clip's ring was not usable (the profile was used as is)."""
        if self.fit is None or self.fit.verdict in ("same", "corrected"):
            return None
        used = "corrected for where it sits" if self.lens is not self.profile else "used as it is"
        return f"{clip}: {self.fit.message}; the lens profile was {used}"


def clip_spectra(
    lens: Lens,
    frames: Iterable[np.ndarray],
    extract: Callable[[Lens], Callable[[np.ndarray], np.ndarray]],
    check: Callable[[np.ndarray], None] | None = None,
    clip: str = "clip",
) -> tuple[np.ndarray, ClipLens[np.ndarray]]:
    """All of a clip's frames -> ((F, C, K) spectra, what was corrected); an unusable ring is
    logged (the CLI also prints `ClipLens.warning`)."""
    c = ClipLens(lens, extract, check)
    spec = np.stack(list(c.spectra(frames)))
    w = c.warning(clip)
    if w:
        log.warning(w)
    return spec, c


def lens_check(lens: Lens, frames: Sequence[np.ndarray]) -> dict[str, Any] | None:
    """Does a video (its first frames) fit its lens profile? `LensFit.to_dict` without the lens,
    for the admin page; None for a lens without a ring (a 360 camera)."""
    if not isinstance(lens, Catadioptric) or not frames:
        return None
    d = corrected_lens(lens, frames).to_dict()
    del d["lens"]
    return d
