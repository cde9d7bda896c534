"""Frame -> features: unwarp (Eq. 1), curves (Eq. 3), spectrum; the per-frame pipeline composed."""

from __future__ import annotations

import threading
from collections import OrderedDict
from collections.abc import Callable
from typing import Any

import cv2
import numpy as np

from .curves import extract_curves
from .errors import OmninavError
from .lens import Lens
from .level import estimate_map, level_map
from .spectrum import quantise, spectrum
from .unwarp import UnwarpMap, band_map, unwarp


class Extractor:
    """Holds the remap for one (lens, preset) pair; `spectra` is then pure per frame."""

    def __init__(self, lens: Lens, conf: dict[str, Any]):
        self.lens = lens
        self.conf = conf
        self.map = band_map(lens, conf)
        # what levelling estimates each frame's tilt through (level.estimate_map), with level_iters
        self.coarse = estimate_map(lens, conf) if conf.get("level_iters") else None

    def check_frame(self, frame: np.ndarray, where: str = "frame") -> None:
        w, h = self.lens.image_size
        if frame.shape[:2] != (h, w):
            raise OmninavError(
                f"{where}: frame is {frame.shape[1]}x{frame.shape[0]} but the lens profile is for "
                f"{w}x{h} images (wrong lens profile?)"
            )

    def frame_map(self, frame_bgr: np.ndarray) -> UnwarpMap:
        """The remap this frame is read through: the lens's, or (`level_iters`) the one that
        levels the frame's tilt (level.py)."""
        if self.coarse is None:
            return self.map
        return level_map(frame_bgr, self.lens, self.map, self.coarse, int(self.conf["level_iters"]))[0]

    def curves(self, frame_bgr: np.ndarray, m: UnwarpMap | None = None) -> np.ndarray:
        """(H, W, 3) uint8 BGR frame -> (C, W) float32 normalised curves, read through `m` (default:
        frame_map's). The bands are summed over `self.map`'s rows, whatever directions `m` reads."""
        m = self.frame_map(frame_bgr) if m is None else m
        pano = cv2.cvtColor(unwarp(frame_bgr, m), cv2.COLOR_BGR2RGB)
        return extract_curves(pano, self.map.elevations, self.conf, m.valid)

    def spectrum(self, frame_bgr: np.ndarray, m: UnwarpMap | None = None) -> np.ndarray:
        """(H, W, 3) uint8 BGR frame -> (C, K) complex64, quantised as the record carries it."""
        return quantise(spectrum(self.curves(frame_bgr, m), self.conf["n_harmonics"]))

    def spectra(self, frames: list[np.ndarray]) -> np.ndarray:
        """(F, C, K) for F >= 1 frames (a clip always has frames: readers refuse empty ones)."""
        return np.stack([self.spectrum(f) for f in frames])


class Extractors:
    """Extractors by lens, the last `size` kept (a remap is ~1 MB and ~10 ms to build): clips
    corrected for a re-clipped lens (calib/correct.py) each bring a lens of their own. Safe to share
    between a server worker's threads."""

    def __init__(self, conf: dict[str, Any], size: int = 8):
        self.conf = conf
        self.size = size
        self._by_lens: OrderedDict[str, Extractor] = OrderedDict()
        self._lock = threading.Lock()

    def get(self, lens: Lens) -> Extractor:
        key = repr(lens)
        with self._lock:
            ext = self._by_lens.pop(key, None)
            if ext is None:
                ext = Extractor(lens, self.conf)
            self._by_lens[key] = ext  # the newest at the end
            while len(self._by_lens) > self.size:
                self._by_lens.popitem(last=False)
            return ext

    def spectrum(self, lens: Lens) -> Callable[[np.ndarray], np.ndarray]:
        """The per-frame function of a lens: what `calib.correct.ClipLens` takes."""
        return self.get(lens).spectrum
