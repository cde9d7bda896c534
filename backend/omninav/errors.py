"""User-facing errors, and the two checks every input file needs.

OmninavError is for everything a user can get wrong; the CLI (and later the server) prints its
message as one line, never a traceback.
"""

from __future__ import annotations

import json
import math
import reprlib
import sys
from pathlib import Path
from typing import Any


class OmninavError(Exception):
    """Bad input or state that the user can fix: the message says what was wrong."""


def read_json(path: str | Path, what: str) -> Any:
    """Parse a JSON input file; a missing or unreadable file becomes one clear OmninavError."""
    p = Path(path)
    try:
        return json.loads(p.read_text())
    except FileNotFoundError:
        raise OmninavError(f"{p}: {what} not found") from None
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as e:
        raise OmninavError(f"{p}: {what} is not readable JSON ({e})") from None


def is_finite_number(v: Any) -> bool:
    """A JSON number that a float holds: not a bool, NaN or Inf, nor an integer past 1.8e308
    (JSON integers have no limit, and math.isfinite raises OverflowError on those)."""
    if isinstance(v, float):
        return math.isfinite(v)
    return isinstance(v, int) and not isinstance(v, bool) and abs(v) <= sys.float_info.max


def finite(v: Any, what: str, where: str) -> float:
    """A finite JSON number as float, else an error naming the field (and a short form of the value)."""
    if not is_finite_number(v):
        raise OmninavError(f"{where}: {what} must be a finite number, got {reprlib.repr(v)}")
    return float(v)
