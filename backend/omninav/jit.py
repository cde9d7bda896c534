"""Jit: numba's compiler as the engine's compiled loops use it (essential.py, hamming.py).

Imported only by those modules, which their callers import where they are needed (numba's import
costs ~0.4 s, paid by the commands and requests that verify with local features only).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, TypeVar

import numba

F = TypeVar("F", bound=Callable[..., Any])


def compiled(f: F) -> F:
    """f compiled by numba (nopython; without the GIL, so that the server's request threads run it
    side by side), its machine code cached beside its module for the next process (loaded in
    ~0.5 s with numba's import, where compiling takes seconds) and made for this machine's CPU.
    Where neither that folder nor the user's cache folder can be written, numba raises
    RuntimeError at the import: NUMBA_CACHE_DIR names another."""
    out: F = numba.njit(cache=True, nogil=True)(f)  # type: ignore[assignment]  # (a Dispatcher, called as f)
    return out
