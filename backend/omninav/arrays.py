"""The array namespace: NumPy, or CuPy when asked for (OMNINAV_DEVICE=gpu) or found (auto).

Search code is written once against `xp`; arrays convert to NumPy only at the edges (storage, HTTP).
"""

from __future__ import annotations

import os
from types import ModuleType
from typing import Any

import numpy as np

from .errors import OmninavError


def _cupy() -> ModuleType | None:
    try:
        import cupy

        if cupy.cuda.runtime.getDeviceCount() > 0:
            cp: ModuleType = cupy  # untyped (mypy.ini): Any until named
            return cp
    except Exception:  # no CuPy, no driver or no device: the CPU path serves
        return None
    return None


def device_namespace(device: str | None = None) -> ModuleType:
    """`cpu`, `gpu` or `auto` (default: OMNINAV_DEVICE, else auto) -> numpy or cupy."""
    choice = (device or os.environ.get("OMNINAV_DEVICE") or "auto").lower()
    if choice == "cpu":
        return np
    if choice not in ("gpu", "auto"):
        raise OmninavError(f"OMNINAV_DEVICE must be cpu, gpu or auto, not {choice!r}")
    cp = _cupy()
    if cp is None and choice == "gpu":
        raise OmninavError("OMNINAV_DEVICE=gpu but no CuPy with a CUDA device is available")
    return cp if cp is not None else np


def namespace_of(x: Any) -> ModuleType:
    """numpy or cupy, whichever owns array x."""
    mod = type(x).__module__.split(".")[0]
    if mod == "cupy":
        import cupy

        cp: ModuleType = cupy
        return cp
    return np


def to_numpy(x: Any) -> np.ndarray:
    return x.get() if namespace_of(x) is not np else np.asarray(x)
