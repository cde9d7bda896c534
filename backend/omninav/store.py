"""Frame storage: one directory per venue, modelled frames in atomically swapped generations.

    <data>/venues/<id>/CURRENT          name of the live generation (replaced with os.replace)
    <data>/venues/<id>/gen-000003/      settings.json, lens.json, frames.npy, spectra.npy, videos.json,
                                        keys.npy[, first.npy, basis.npy] (the index's arrays,
                                        index.py), keys_t.npy (for the release before `first`)
                                        [, local_places.npy, local_bearings.npy,
                                        local_descriptors.npy] (local features, verify.py)

A modelling run writes a complete new generation beside the live one and only then swaps CURRENT,
so a run that is interrupted (Ctrl-C, crash, power) leaves the venue answering as before.
Everything else about a venue (name, floors, plans, places, lenses, videos) is in the catalogue
(catalog/), which the CLI and the server share.
"""

from __future__ import annotations

import fcntl
import json
import os
import re
import shutil
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any, Literal

import numpy as np

from .errors import Conflict, OmninavError
from .index import first_keys, index_arrays
from .lens import Lens, lens_from_dict
from .settings import SearchSettings
from .settings_upgrade import upgrade

if TYPE_CHECKING:
    from .verify import LocalFeatures

INDEX_ARRAYS = ("keys", "first", "basis", "keys_t")  # keys_t: generations before `first` (index.first_keys)
LOCAL_ARRAYS = ("places", "bearings", "descriptors")  # verify.LocalFeatures' fields, in order
VENUE_ID = re.compile(r"^[A-Za-z0-9][A-Za-z0-9_-]{0,63}$")

# One row per modelled frame; `video` names the modelling video it came from.
FRAME_DTYPE = np.dtype(
    [("x", "<f4"), ("y", "<f4"), ("heading", "<f4"), ("t", "<f4"), ("frame", "<i4"), ("video", "<i4")]
)


def check_id(venue_id: str) -> str:
    if not isinstance(venue_id, str) or not VENUE_ID.fullmatch(venue_id):  # match lets "a\n" through
        raise OmninavError(
            f"invalid venue id {venue_id!r}: use 1-64 letters, digits, '-' or '_', starting with a letter or digit"
        )
    return venue_id


def write_beside(path: Path, text: str) -> Path:
    """Write `text` to a new hidden file beside `path`, fsynced; renamed over `path`, it appears
    whole. -> the new file (the caller renames it, or deletes it if it must not appear)."""
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.")
    with os.fdopen(fd, "w") as f:
        f.write(text)
        f.flush()
        os.fsync(f.fileno())
    return Path(tmp)


def _write_atomic(path: Path, text: str) -> None:
    """Write beside, fsync, rename over: readers see the old file or the new one, never half."""
    os.replace(write_beside(path, text), path)


@dataclass
class Generation:
    """The frames a venue answers with: poses, spectra, and the settings they were made with."""

    settings: dict[str, Any]
    lens: Lens
    frames: np.ndarray  # (N,) FRAME_DTYPE
    spectra: np.ndarray  # (N, C, K) complex64
    videos: list[str]
    arrays: dict[str, np.ndarray] | None = None  # index_arrays(): memory-mapped by every reader
    local: LocalFeatures | None = None  # verify.py: a venue modelled with `local_features`


def key_dims_for(settings: dict[str, Any], n_frames: int) -> int:
    """Projected stage-1 keys only pay off on large venues (settings.SearchSettings)."""
    return SearchSettings.of(settings).key_dims_for(n_frames)


def _read_settings(g: Path) -> dict[str, Any]:
    """A generation's settings.json as every reader takes it: in today's format, checked
    (settings_upgrade.upgrade: a venue modelled by an earlier release read through the migrations; the
    file, and the frames, stay as they were modelled)."""
    return upgrade(json.loads((g / "settings.json").read_text()))


class Store:
    """The modelled frames of every venue, as generations; what a venue *is* (its name, floors,
    places, lenses) is the catalogue's (catalog/). A venue's folder appears with its first commit."""

    def __init__(self, root: str | Path):
        self.root = Path(root)
        self.venues = self.root / "venues"

    def venue_dir(self, venue_id: str) -> Path:
        return self.venues / check_id(venue_id)

    def settings(self, venue_id: str) -> dict[str, Any] | None:
        """The feature settings of the live generation (None: not modelled yet)."""
        g = self._current(self.venue_dir(venue_id))
        return _read_settings(g) if g else None

    def _current(self, d: Path) -> Path | None:
        cur = d / "CURRENT"
        if not cur.is_file():
            return None
        g = d / cur.read_text().strip()
        return g if g.is_dir() else None

    def load(self, venue_id: str, mmap: bool = True) -> Generation:
        d = self.venue_dir(venue_id)
        g = self._current(d)
        if g is None:
            raise Conflict(f"venue {venue_id!r} has no modelled frames yet (model it: 'omninav model', or a job)")
        mode: Literal["r"] | None = "r" if mmap else None
        settings = _read_settings(g)
        lens = lens_from_dict(json.loads((g / "lens.json").read_text()), where=f"{venue_id} lens")
        frames = np.load(g / "frames.npy", mmap_mode=mode)
        if len(frames) == 0:  # every video was removed
            raise Conflict(f"venue {venue_id!r} has no modelled frames (its videos were removed)")
        spectra = np.load(g / "spectra.npy", mmap_mode=mode)
        videos = json.loads((g / "videos.json").read_text())
        arrays = {k: np.load(g / f"{k}.npy", mmap_mode=mode) for k in INDEX_ARRAYS if (g / f"{k}.npy").is_file()}
        local = None
        if (g / "local_places.npy").is_file():
            from .verify import LocalFeatures  # (OpenCV: imported where a venue has local features)

            local = LocalFeatures(*(np.load(g / f"local_{k}.npy", mmap_mode=mode) for k in LOCAL_ARRAYS))
        return Generation(settings, lens, frames, spectra, videos, arrays if "keys" in arrays else None, local)

    def frame_count(self, venue_id: str) -> int:
        """Frames of the live generation, from the array's header alone (no index, no spectra)."""
        g = self._current(self.venue_dir(venue_id))
        return len(np.load(g / "frames.npy", mmap_mode="r")) if g else 0

    def modelled_videos(self, venue_id: str) -> list[str]:
        """The videos that have frames in the live generation (its frames' video column, mapped)."""
        g = self._current(self.venue_dir(venue_id))
        if g is None:
            return []
        names = json.loads((g / "videos.json").read_text())
        used = np.unique(np.load(g / "frames.npy", mmap_mode="r")["video"])
        return [names[int(i)] for i in used]

    def generation(self, venue_id: str) -> str | None:
        """Name of the live generation (cheap: one small file), to notice a new one."""
        g = self._current(self.venue_dir(venue_id))
        return g.name if g else None

    @contextmanager
    def lock(self, venue_id: str) -> Iterator[None]:
        """Hold the venue's write lock: one reader-modify-commit of its generations at a time,
        across threads, worker processes and server instances on this data directory (flock)."""
        d = self.venue_dir(venue_id)
        d.mkdir(parents=True, exist_ok=True)
        fd = os.open(d / ".lock", os.O_RDWR | os.O_CREAT, 0o644)
        try:
            fcntl.flock(fd, fcntl.LOCK_EX)
            yield
        finally:
            os.close(fd)  # closing releases the lock

    def recover(self, venue_id: str) -> list[str]:
        """Drop what an interrupted commit left: temporary folders, and generations newer than
        CURRENT (written, never made live: a crash between the rename and the switch). Returns
        their names. Call it holding the lock."""
        d = self.venue_dir(venue_id)
        cur = self._current(d)
        live = int(cur.name.split("-")[1]) if cur else 0
        gone = []
        for p in sorted(d.glob(".tmp-gen-*")) + sorted(d.glob("gen-*")):
            if p.name.startswith("gen-"):
                try:
                    if int(p.name.split("-")[1]) <= live:
                        continue
                except ValueError:
                    continue
            shutil.rmtree(p, ignore_errors=True)
            gone.append(p.name)
        return gone

    def recover_all(self) -> dict[str, list[str]]:
        """recover() every venue (at server start): venue -> what was dropped."""
        out = {}
        for v in self.list():
            with self.lock(v):
                if gone := self.recover(v):
                    out[v] = gone
        return out

    def commit(self, venue_id: str, gen: Generation) -> Path:
        """Write a new generation completely, then make it live in one atomic rename.

        Callers that read the live generation to build the next one hold lock() around both."""
        d = self.venue_dir(venue_id)
        d.mkdir(parents=True, exist_ok=True)
        self.recover(venue_id)  # a crash of an earlier commit must not block this one
        cur = self._current(d)
        n = int(cur.name.split("-")[1]) + 1 if cur else 1
        name = f"gen-{n:06d}"
        tmp = Path(tempfile.mkdtemp(dir=d, prefix=".tmp-gen-"))
        np.save(tmp / "frames.npy", np.ascontiguousarray(gen.frames))
        np.save(tmp / "spectra.npy", np.ascontiguousarray(gen.spectra))
        if len(gen.frames):
            arrays = index_arrays(np.asarray(gen.spectra), key_dims_for(gen.settings, len(gen.frames)))
            # keys_t, the first pass's keys as releases before `first` read them: written for one
            # release more, so that going back to the last one finds every venue searchable
            arrays["keys_t"] = np.ascontiguousarray(first_keys(arrays).T)
            for k, a in arrays.items():
                np.save(tmp / f"{k}.npy", a)
        if gen.local is not None:
            for k in LOCAL_ARRAYS:
                np.save(tmp / f"local_{k}.npy", np.ascontiguousarray(getattr(gen.local, k)))
        (tmp / "settings.json").write_text(json.dumps(gen.settings, indent=1))
        (tmp / "lens.json").write_text(json.dumps(gen.lens.to_dict(), indent=1))
        (tmp / "videos.json").write_text(json.dumps(gen.videos))
        for written in tmp.iterdir():
            with open(written, "rb") as fh:
                os.fsync(fh.fileno())
        os.replace(tmp, d / name)
        _write_atomic(d / "CURRENT", name)
        # Older generations are kept one step back (a server may still have them mapped).
        for old in sorted(d.glob("gen-*"))[:-2]:
            shutil.rmtree(old, ignore_errors=True)
        return d / name

    def list(self) -> list[str]:
        """The venues that have a folder here (modelled, or being modelled)."""
        if not self.venues.is_dir():
            return []
        return sorted(p.name for p in self.venues.iterdir() if p.is_dir() and VENUE_ID.fullmatch(p.name))
