"""Modelling videos: registered with their floor, lens, role and (now or later) walk path, uploaded
in resumable pieces, checked when the last byte is in, modelled by jobs (server/jobs.py), deleted
with their frames.

A video's role is 'model' (a walk the venue is modelled from) or 'evaluation' (a walk that checks
the modelled venue, never modelled itself). Its walk path may come after its bytes: the admin tags it
on the plan, helped by the waypoints a suggest job found (`suggestions`); until then it is
without a walk path (its `walk_path` column holds the JSON null) and is not modelled.

The only module that writes the `videos` table. An upload has one writer at a time: a request
claims the video (a lease in its row, renewed while bytes flow, lapsing if its process dies), and
every write it makes names its claim, so two uploads of one video cannot interleave their bytes.

    uploading --(last byte in, decodes, fits its lens)--> ready --(job)--> modelled
"""

from __future__ import annotations

import errno
import json
import os
import re
import time
import uuid
from collections.abc import Iterator, Sequence
from contextlib import contextmanager, suppress
from pathlib import Path
from typing import IO, TYPE_CHECKING, Any

from sqlalchemy import Connection, text

from ..errors import Conflict, NoRoom, NotFound, OmninavError, TooLarge, Unusable
from ..model_venue import ModelResult, VideoSource
from ..preview import frame_jpeg
from ..video import VideoInfo
from ..walk_path import WalkPath, parse_walk_path
from .lenses import DEFAULT_LENS
from .venues import bump

if TYPE_CHECKING:
    from . import Catalog

VIDEO_NAME = re.compile(r"^[A-Za-z0-9][A-Za-z0-9_-]*(\.[A-Za-z0-9_-]+)*$")
CHUNK = 1 << 20
WRITER_LEASE_S = 60.0  # an upload whose request died frees the video for another after this long
ACTIVE_JOB = "('queued', 'running')"
ROLES = ("model", "evaluation")


def check_video_name(name: Any) -> str:
    if not isinstance(name, str) or len(name) > 128 or not VIDEO_NAME.fullmatch(name) or name.endswith(".part"):
        raise OmninavError(
            f"invalid video name {name!r}: use up to 128 letters, digits, '-', '_' and dots between them"
        )
    return name


def check_role(role: Any) -> str:
    if role not in ROLES:
        raise OmninavError(f"'role' must be one of {', '.join(ROLES)}, got {role!r}")
    return str(role)


def check_size(size: Any, max_bytes: int) -> int:
    if isinstance(size, float) and size.is_integer():  # 1.0 is a JSON integer too
        size = int(size)
    if isinstance(size, bool) or not isinstance(size, int) or size <= 0:
        raise OmninavError("'size' must be the video's length in bytes (a positive integer)")
    if size > max_bytes:
        raise TooLarge(f"the video is {size} bytes; the limit is {max_bytes}")
    return size


def body_walk_path(body: dict[str, Any]) -> Any:
    """A registration's walk path: `walk_path`, or `track`, its name until the rename (accepted for
    one release; docs/decisions.md). Both at once is refused: which one is meant is not clear."""
    if "walk_path" in body and "track" in body:
        raise OmninavError("give 'walk_path' only ('track' is its old name)")
    return body.get("walk_path", body.get("track"))


class Videos:
    def __init__(self, cat: Catalog):
        self.cat = cat
        self.db = cat.db

    def dir(self, venue_id: str) -> Path:
        return self.cat.data / "videos" / venue_id

    def all(self, venue_id: str) -> list[dict[str, Any]]:
        self.cat.venues.get(venue_id)
        return self.db.all("SELECT * FROM videos WHERE venue = :v ORDER BY created, name", v=venue_id)

    def get(self, venue_id: str, name: str) -> dict[str, Any]:
        self.cat.venues.get(venue_id)
        row = self.db.one("SELECT * FROM videos WHERE venue = :v AND name = :n", v=venue_id, n=check_video_name(name))
        if row is None:
            raise NotFound(f"venue {venue_id!r} has no video {name!r}")
        return row

    def floors(self, venue_id: str) -> dict[str, str]:
        """Each video's floor, by name: which floor a modelled frame is on."""
        return {
            r["name"]: r["floor"] for r in self.db.all("SELECT name, floor FROM videos WHERE venue = :v", v=venue_id)
        }

    def floor_list(self, venue_id: str, names: Sequence[str], floor_ids: Sequence[str] | None = None) -> list[str]:
        """The floor of each of these videos (a generation's, by their index in it); a video the
        catalogue no longer lists is on the venue's first floor ("1" when it has none).
        `floor_ids`: the venue's floors, when the caller has them already."""
        vf = self.floors(venue_id)
        ids = [str(f["id"]) for f in self.cat.floors.all(venue_id)] if floor_ids is None else list(floor_ids)
        first = min(ids) if ids else "1"
        return [str(vf.get(n, first)) for n in names] or [first]

    def check_walk_path(self, venue_id: str, floor: str, walk_path: Any) -> WalkPath:
        """A walk path as sent, parsed, and on the floor's plan."""
        f = self.cat.floors.get(venue_id, floor)
        t = parse_walk_path(walk_path, where="walk path")
        w, h = self.cat.floors.extent_m(f)
        for i, (x, y) in enumerate(t.xy):
            if not (0 <= x <= w and 0 <= y <= h):
                raise Unusable(
                    f"walk path waypoint {i} ({x:.2f}, {y:.2f}) m lies outside the floor plan of floor {floor!r} "
                    f"({w:.1f} x {h:.1f} m)"
                )
        return t

    def busy_job(self, venue_id: str, name: str) -> str | None:
        """The id of the queued or running job that models this video, if any."""
        row = self.db.one(
            "SELECT j.id FROM job_videos jv JOIN jobs j ON j.id = jv.job "
            f"WHERE jv.venue = :v AND jv.video = :n AND j.state IN {ACTIVE_JOB}",
            v=venue_id,
            n=name,
        )
        return row["id"] if row else None

    def _check_not_modelling(self, venue_id: str, name: str) -> None:
        if job := self.busy_job(venue_id, name):
            raise Conflict(f"video {name!r} is being modelled by job {job}; cancel it first")

    def create(self, venue_id: str, body: dict[str, Any], max_bytes: int) -> dict[str, Any]:
        """Register a video before its bytes: name, floor, size, walk path, lens (a name or a profile).
        A video registered again under its name is replaced when the new upload completes."""
        self.cat.venues.get(venue_id)
        name = check_video_name(body.get("name"))
        floor = str(body.get("floor", "1"))
        size = check_size(body.get("size"), max_bytes)
        role = check_role(body.get("role", "model"))
        walk_path = body_walk_path(body)
        if walk_path is None:  # without a walk path: tagged later (PUT .../walk-path)
            self.cat.floors.get(venue_id, floor)
        else:
            self.check_walk_path(venue_id, floor, walk_path)
        lens = body.get("lens", DEFAULT_LENS)
        if isinstance(lens, dict):  # an inline profile becomes a lens named by its content
            lens = self.cat.lenses.put_inline(venue_id, lens)
        if not isinstance(lens, str):
            raise OmninavError("'lens' must be a lens profile name or a lens profile object")
        self.cat.lenses.get(venue_id, lens)
        self._check_not_modelling(venue_id, name)
        old = self.db.one("SELECT * FROM videos WHERE venue = :v AND name = :n", v=venue_id, n=name)
        if old is not None and old["writer"] and (old["writer_until"] or 0) > time.time():
            raise Conflict(
                f"video {name!r} is being uploaded right now; wait for that upload to end, then send it again"
            )
        with self.db.tx() as c:
            bump(c, venue_id)  # first: a writer's stale revision refuses before anything changes
            c.execute(text("DELETE FROM videos WHERE venue = :v AND name = :n"), {"v": venue_id, "n": name})
            c.execute(
                text(
                    "INSERT INTO videos (venue, name, floor, lens, walk_path, size, received, status, frames, created, "
                    "role) VALUES (:v, :n, :f, :l, :t, :s, 0, 'uploading', :fr, :c, :r)"
                ),
                {
                    "v": venue_id,
                    "n": name,
                    "f": floor,
                    "l": lens,
                    "t": json.dumps(walk_path),
                    "s": size,
                    "fr": old["frames"] if old else 0,
                    "c": time.time(),
                    "r": role,
                },
            )
        (self.dir(venue_id) / f"{name}.part").unlink(missing_ok=True)
        return self.get(venue_id, name)

    def add_file(
        self, venue_id: str, path: Path, floor: str, lens: str, walk_path: Any, role: str = "model"
    ) -> dict[str, Any]:
        """Register a video file that is already on this machine (the demo): linked, not copied
        where the file system allows, and ready to model."""
        size = path.stat().st_size
        info = VideoInfo(path)
        body = {"name": path.name, "floor": floor, "size": size, "walk_path": walk_path, "lens": lens, "role": role}
        self.create(venue_id, body, size)
        d = self.dir(venue_id)
        d.mkdir(parents=True, exist_ok=True)
        (d / path.name).unlink(missing_ok=True)
        try:  # a hard link costs nothing; copy across file systems
            os.link(path, d / path.name)
        except OSError:
            import shutil

            shutil.copyfile(path, d / path.name)
        self.db.run(
            "UPDATE videos SET received = size, status = 'ready', " + _INFO + " WHERE venue = :v AND name = :n",
            v=venue_id,
            n=path.name,
            **_info(info),
        )
        return self.get(venue_id, path.name)

    def delete(self, venue_id: str, name: str) -> int:
        """Delete a video, its file and its frames (the venue answers from its other videos' frames);
        returns how many frames went."""
        from ..model_venue import remove_video

        v = self.get(venue_id, name)
        self._check_not_modelling(venue_id, v["name"])
        self.cat.venues.touch(venue_id)  # a writer's stale revision refuses here, before any frame goes
        removed = remove_video(self.cat.store, venue_id, v["name"])
        d = self.dir(venue_id)
        for p in (d / v["name"], d / f"{v['name']}.part"):
            p.unlink(missing_ok=True)
        with self.db.tx() as c:
            c.execute(text("DELETE FROM videos WHERE venue = :v AND name = :n"), {"v": venue_id, "n": v["name"]})
            bump(c, venue_id)
        return removed

    # ---- modelling ----------------------------------------------------------------------------
    def sources(self, venue_id: str, names: list[str]) -> list[VideoSource]:
        """What modelling reads of each named video: its file, walk path and lens."""
        out = []
        for name in names:
            v = self.db.one("SELECT * FROM videos WHERE venue = :v AND name = :n", v=venue_id, n=name)
            if v is None:
                raise OmninavError(f"video {name!r} was deleted before it was modelled")
            path = self.dir(venue_id) / name
            if not path.is_file():
                raise OmninavError(f"video {name!r} has no uploaded file")
            walk_path = json.loads(v["walk_path"])
            if walk_path is None:
                raise OmninavError(f"video {name!r} has no walk path yet")
            out.append(VideoSource(path, parse_walk_path(walk_path), self.cat.lenses.get(venue_id, v["lens"])))
        return out

    @staticmethod
    def forget_frames(c: Connection, venue_id: str) -> None:
        """No video of the venue has frames (a modelling anew commits a generation of its own
        videos, mark_modelled next), in the caller's (the job's) transaction."""
        c.execute(
            text(
                "UPDATE videos SET frames = 0, status = CASE WHEN status = 'modelled' THEN 'ready' ELSE status END "
                "WHERE venue = :v"
            ),
            {"v": venue_id},
        )

    @staticmethod
    def mark_modelled(c: Connection, venue_id: str, results: list[ModelResult]) -> None:
        """Record modelled videos and their frame counts, in the caller's (the job's) transaction."""
        for r in results:
            c.execute(
                text("UPDATE videos SET status = 'modelled', frames = :f WHERE venue = :v AND name = :n"),
                {"f": r.frames, "v": venue_id, "n": r.video},
            )

    # ---- walk paths, suggestions, frames --------------------------------------------------------
    def walk_path(self, venue_id: str, name: str) -> dict[str, Any]:
        """The video's walk path as stored (walk_path.json), NotFound while it has none."""
        walk_path = json.loads(self.get(venue_id, name)["walk_path"])
        if walk_path is None:
            raise NotFound(f"video {name!r} has no walk path yet")
        return dict(walk_path)

    def set_walk_path(self, venue_id: str, name: str, walk_path: Any) -> dict[str, Any]:
        """Give a video its walk path (or a new one). A modelled video is ready to be modelled again:
        its frames in the venue have the poses of its old walk path until then."""
        v = self.get(venue_id, name)
        try:
            self.check_walk_path(venue_id, v["floor"], walk_path)
        except (Unusable, NotFound, Conflict):
            raise
        except OmninavError as e:  # the walk path as sent is unusable: 422 like one off the plan
            raise Unusable(str(e)) from None
        self._check_not_modelling(venue_id, v["name"])
        with self.db.tx() as c:
            bump(c, venue_id)
            c.execute(
                text(
                    "UPDATE videos SET walk_path = :t, "
                    "status = CASE WHEN status = 'modelled' THEN 'ready' ELSE status END WHERE venue = :v AND name = :n"
                ),
                {"t": json.dumps(walk_path), "v": venue_id, "n": v["name"]},
            )
        return self.get(venue_id, v["name"])

    def set_suggestions(
        self, venue_id: str, name: str, result: dict[str, Any] | None, c: Connection | None = None
    ) -> None:
        """Keep the latest waypoint suggestions of a video (a suggest job's result), shown with it.
        Not an edit of the venue: no revision bump. A video deleted meanwhile is left alone. With
        `c`, inside that transaction (the job's own "done", so a job that is not done writes none)."""
        sql = "UPDATE videos SET suggestions = :s WHERE venue = :v AND name = :n"
        params = {"s": json.dumps(result) if result is not None else None, "v": venue_id, "n": name}
        if c is not None:
            c.execute(text(sql), params)
        else:
            self.db.run(sql, **params)

    def frame(self, venue_id: str, name: str, t: float, view: str, width: int | None) -> bytes:
        """The video's frame at t seconds as a JPEG: as filmed ('raw') or unwrapped with the
        video's lens ('panorama'). Conflict while the video is not uploaded; Busy while this
        process makes other previews (preview.py)."""
        v = self.get(venue_id, name)
        path = self.dir(venue_id) / v["name"]
        if v["status"] == "uploading" or not path.is_file():
            raise Conflict(f"video {name!r} is not uploaded yet ({v['received']} of {v['size']} bytes)")
        fps, frames = v["fps"], None
        if not fps or v["duration_s"] is None:  # uploaded before its facts were kept: read them now
            info = VideoInfo(path, label=v["name"])
            fps, frames = info.fps, info.frames
            self.db.run(
                "UPDATE videos SET " + _INFO + " WHERE venue = :v AND name = :n", v=venue_id, n=v["name"], **_info(info)
            )
        else:
            frames = round(float(v["duration_s"]) * float(fps))
        lens = self.cat.lenses.get(venue_id, v["lens"])
        return frame_jpeg(str(path), lens, t, float(fps or 0.0), int(frames), view, width)

    # ---- the upload ---------------------------------------------------------------------------
    def upload(self, venue_id: str, name: str, body: IO[bytes], start: int, end: int | None) -> dict[str, Any]:
        """Write bytes [start, end) of the video (end None: to the end of `body`), resuming where
        the upload stands; the last piece checks the file. One writer at a time."""
        v = self.get(venue_id, name)
        if v["status"] != "uploading":
            raise Conflict(f"video {name!r} is already uploaded ({v['status']}); POST it again to replace it")
        size = int(v["size"])
        with self._writer(venue_id, name) as lease:
            received = int(self.get(venue_id, name)["received"])  # read under the lease: nobody else moves it
            if start != received:
                raise Conflict(
                    f"upload of {name!r} stands at byte {received}; send the piece that starts there", received=received
                )
            limit = (end if end is not None else size) - start
            d = self.dir(venue_id)
            d.mkdir(parents=True, exist_ok=True)
            part = d / f"{name}.part"
            got = _receive(body, part, start, limit, size, lease)
            received = start + got  # a dropped connection keeps what arrived: resume from there
            lease.update("received = :r", r=received)
            if received < size:
                return self.get(venue_id, name)
            return self._finish(venue_id, name, part, lease)

    @contextmanager
    def _writer(self, venue_id: str, name: str) -> Iterator[_Lease]:
        lease = _Lease(self, venue_id, name)
        if not lease.claim():
            v = self.get(venue_id, name)
            if v["status"] != "uploading":
                raise Conflict(f"video {name!r} is already uploaded ({v['status']}); POST it again to replace it")
            raise Conflict(
                f"another upload of {name!r} is in progress; resume from byte {v['received']} when it stops",
                received=v["received"],
            )
        try:
            yield lease
        finally:
            lease.release()

    def _finish(self, venue_id: str, name: str, part: Path, lease: _Lease) -> dict[str, Any]:
        """The last byte is in: the file must be a video the video's lens can read, else it goes."""
        v = self.get(venue_id, name)
        try:
            info = VideoInfo(part, label=name)
            w, h = self.cat.lenses.get(venue_id, v["lens"]).image_size
            if (info.width, info.height) != (w, h):
                raise OmninavError(f"frames are {info.width}x{info.height} but lens {v['lens']!r} is for {w}x{h}")
        except OmninavError as e:
            part.unlink(missing_ok=True)
            why = f"video {name!r} was not accepted: {e}; upload it again"
            lease.update("received = 0, error = :e", e=why)
            raise Unusable(why, received=0) from None
        part.replace(part.with_name(name))
        lease.update("status = 'ready', " + _INFO, **_info(info))
        return self.get(venue_id, name)


class _Lease:
    """This request's claim on writing one video (videos.writer): every write of the row names it,
    so a request that lost its claim (it stalled past WRITER_LEASE_S and another took over) changes
    nothing."""

    def __init__(self, videos: Videos, venue_id: str, name: str):
        self.db, self.venue, self.name = videos.db, venue_id, name
        self.me = uuid.uuid4().hex
        self.renewed = 0.0

    def claim(self) -> bool:
        now = time.time()
        self.renewed = now
        return bool(
            self.db.run(
                "UPDATE videos SET writer = :w, writer_until = :u WHERE venue = :v AND name = :n "
                "AND status = 'uploading' AND (writer IS NULL OR writer_until < :now)",
                w=self.me,
                u=now + WRITER_LEASE_S,
                now=now,
                v=self.venue,
                n=self.name,
            )
        )

    def update(self, assignments: str, **params: Any) -> None:
        got = self.db.run(
            f"UPDATE videos SET {assignments} WHERE venue = :v AND name = :n AND writer = :w",
            v=self.venue,
            n=self.name,
            w=self.me,
            **params,
        )
        if not got:
            raise Conflict(f"the upload of {self.name!r} was taken over by another request; resume from there")

    def renew(self) -> None:
        """Called while bytes flow: keeps the claim alive (a dead writer's claim lapses by itself)."""
        now = time.time()
        if now - self.renewed > WRITER_LEASE_S / 4:
            self.update("writer_until = :u", u=now + WRITER_LEASE_S)
            self.renewed = now

    def release(self) -> None:
        self.db.run(
            "UPDATE videos SET writer = NULL, writer_until = NULL WHERE venue = :v AND name = :n AND writer = :w",
            v=self.venue,
            n=self.name,
            w=self.me,
        )


def _receive(body: IO[bytes], part: Path, start: int, limit: int, size: int, lease: _Lease) -> int:
    """The body into `part` from byte `start`: -> bytes written. A full disk keeps what was written
    and says so; the client resumes once there is room."""
    got = 0
    with open(part, "r+b" if part.exists() else "wb") as f:
        f.seek(start)
        f.truncate()
        try:
            while True:
                chunk = body.read(min(CHUNK, limit - got + 1))
                if not chunk:
                    break
                got += len(chunk)
                if got > limit:  # more bytes than declared: nothing of this piece is kept
                    f.truncate(start)
                    raise TooLarge(
                        f"the body is larger than the {limit} bytes this piece should have (video size {size})"
                    )
                f.write(chunk)
                lease.renew()
            f.flush()
        except OSError as e:
            if e.errno not in (errno.ENOSPC, errno.EDQUOT):
                raise
            kept = _keep_written(f, start)
            lease.update("received = :r", r=start + kept)
            raise NoRoom(
                f"disk full: the server has no room for the rest of {part.name[:-5]!r}; {start + kept} of "
                f"{size} bytes are kept. Free space on the server, then resume from there",
                received=start + kept,
            ) from None
    return got


def _keep_written(f: Any, start: int) -> int:
    """After a failed write: how much of this piece is really on disk (flush what can be)."""
    with suppress(OSError):
        f.flush()
    on_disk = max(start, os.fstat(f.fileno()).st_size)
    with suppress(OSError):
        f.truncate(on_disk)
    return on_disk - start


_INFO = "duration_s = :dur, fps = :fps, width = :width, height = :height, error = NULL"


def _info(info: VideoInfo) -> dict[str, Any]:
    """What the upload check read of a video, as _INFO's parameters."""
    dur = info.frames / info.fps if info.fps > 0 and info.frames > 0 else None
    return {"dur": dur, "fps": info.fps or None, "width": info.width or None, "height": info.height or None}
