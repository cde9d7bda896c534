"""User-facing errors, and the two checks every input file needs.

OmninavError is for everything a user can get wrong; the CLI prints its message as one line, never
a traceback. Its subclasses say what kind of wrong it is (nothing there, in the way, unusable,
too large, changed meanwhile, no room, busy), so that the server's blueprints alone turn them into
HTTP status codes (server/http.py): the catalogue and the engine know nothing of HTTP.
"""

from __future__ import annotations

import json
import math
import reprlib
import sys
from pathlib import Path
from typing import Any


class OmninavError(Exception):
    """Bad input or state that the user can fix: the message says what was wrong. `details` are
    facts a client can act on (e.g. `received`: where a resumable upload stands)."""

    def __init__(self, message: str, **details: Any):
        super().__init__(message)
        self.details = details


class NotFound(OmninavError):
    """What was named does not exist (a venue, floor, place, lens, video, job)."""


class Conflict(OmninavError):
    """The request is sound but the state is in its way (exists already, busy, not uploaded yet)."""


class Unusable(OmninavError):
    """Well-formed but unusable content: a plan that is no image, a walk path off the plan."""


class TooLarge(OmninavError):
    """More than a limit allows (bytes, frames, seconds)."""


class OutOfRange(OmninavError):
    """A byte range outside what it ranges over."""


class Stale(OmninavError):
    """The writer read an older revision of what it writes (another tab or client changed it
    since): nothing was written; it reloads and tries again."""


class NoRoom(OmninavError):
    """The disk is full: nothing was lost, and the same request succeeds once there is room."""


class Busy(OmninavError):
    """This process does as much of this work at once as it may: nothing was done, and the same
    request succeeds in a moment (`retry_after_s` in its details)."""


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
