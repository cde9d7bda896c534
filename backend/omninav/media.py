"""Untrusted images and videos: their size and length from the header, before any pixel is decoded.

A PNG of 30,000 x 30,000 black pixels is 110 KB on the wire and 2.7 GB decoded; a 786 KB video
of four 8000 x 8000 frames is 1.5 GB decoded, and a 5 MB one of 3000 small frames as much again.
So what a public request sends is read in two steps: the header says the format, the size and,
for a video, the length, and the caller refuses what it did not expect; only then are pixels
decoded, one frame at a time, each turned into what the caller keeps before the next.

A public request may send only PNG and JPEG images and MP4/QuickTime videos (`WEB_IMAGES`): they
are what phones and browsers make, and every other format that OpenCV or FFmpeg would try is one
more parser exposed to the public. The admin's own files on the command line (a lens calibration
set) may also be PGM, PPM or PBM, BMP or TIFF (`STILL_IMAGES`), the formats calibration sets come
in. The image sizes come from Pillow's own header readers of each format; the MP4 box walk
(track size, frame count, duration) is written here, a few dozen lines, because the library
alternative (PyAV) reads a file by opening it with FFmpeg's demuxer and stream probe, the very
exposure this step must come before.
"""

from __future__ import annotations

import io
import struct
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np
from PIL import BmpImagePlugin, ImageFile, JpegImagePlugin, PngImagePlugin, PpmImagePlugin, TiffImagePlugin

PNG_MAGIC = b"\x89PNG\r\n\x1a\n"
JPEG_MAGIC = b"\xff\xd8\xff"
# Each still format read: its names in messages, the magic bytes that open it, Pillow's header reader
_STILLS: dict[str, tuple[str, tuple[bytes, ...], type[ImageFile.ImageFile]]] = {
    "PNG": ("PNG", (PNG_MAGIC,), PngImagePlugin.PngImageFile),
    "JPEG": ("JPEG", (JPEG_MAGIC,), JpegImagePlugin.JpegImageFile),
    "PPM": ("PGM/PPM/PBM", (b"P1", b"P2", b"P3", b"P4", b"P5", b"P6"), PpmImagePlugin.PpmImageFile),
    "BMP": ("BMP", (b"BM",), BmpImagePlugin.BmpImageFile),
    "TIFF": ("TIFF", (b"II*\x00", b"MM\x00*"), TiffImagePlugin.TiffImageFile),
}
WEB_IMAGES = ("PNG", "JPEG")  # what a public request may send
STILL_IMAGES = ("PNG", "JPEG", "PPM", "BMP", "TIFF")  # what the command line reads from the admin's files
# Boxes that may open an MP4/QuickTime file (old QuickTime files have no 'ftyp')
MP4_FIRST_BOXES = {b"ftyp", b"moov", b"mdat", b"free", b"skip", b"wide", b"pnot"}


@dataclass(frozen=True)
class ImageHeader:
    format: str  # one of STILL_IMAGES
    width: int
    height: int


def image_formats(formats: tuple[str, ...] = WEB_IMAGES) -> str:
    """The formats, as a message names them ("PNG or JPEG")."""
    names = [_STILLS[f][0] for f in formats]
    return names[0] if len(names) == 1 else f"{', '.join(names[:-1])} or {names[-1]}"


def still_format(head: bytes, formats: tuple[str, ...] = WEB_IMAGES) -> str | None:
    """Which of `formats` a file that begins with `head` (its first bytes) says it is, by its magic
    bytes alone; None: none of them. (A TIFF's header may lie at its end: probe_image reads all.)"""
    return next((f for f in formats if head.startswith(_STILLS[f][1])), None)


def probe_image(data: bytes, formats: tuple[str, ...] = WEB_IMAGES) -> ImageHeader | None:
    """The format and size that an image of one of `formats` says it has, from its header alone;
    None for any other format or a header that does not parse.

    Pillow's image classes read the header when constructed and decode nothing until asked; they
    are used directly rather than through `Image.open`, whose decompression-bomb check raises
    before the size can be reported and warns (a process-wide filter) below that.
    """
    fmt = still_format(data, formats)
    if fmt is None:
        return None
    cls = _STILLS[fmt][2]
    try:
        with cls(io.BytesIO(data)) as im:
            w, h = im.size
    except Exception:  # noqa: BLE001 - whatever a hostile header breaks, it is not a readable image
        return None
    return ImageHeader(fmt, int(w), int(h))


def decode_image(data: bytes, formats: tuple[str, ...] = WEB_IMAGES) -> np.ndarray | None:
    """(H, W, 3) uint8 BGR pixels of an image of one of `formats` whose header has been checked
    (a grey or 16-bit one made 8-bit BGR); None if they do not decode. OpenCV applies a JPEG's
    EXIF orientation, so width and height may come swapped."""
    if probe_image(data, formats) is None:  # never hand OpenCV a format other than these
        return None
    img = cv2.imdecode(np.frombuffer(data, np.uint8), cv2.IMREAD_COLOR)
    return img if img is not None and img.ndim == 3 else None


def same_size(w: int, h: int, want: tuple[int, int]) -> bool:
    """Is (w, h) the size `want`, either way round (a rotated JPEG or video is turned upright when
    decoded, and then checked exactly)?"""
    return (w, h) == tuple(want) or (h, w) == tuple(want)


# ---- MP4 / QuickTime (ISO/IEC 14496-12 boxes) -------------------------------------------------
@dataclass(frozen=True)
class VideoTrack:
    width: int  # the sample description's coded size
    height: int
    frames: int  # samples in the track; 0 when the file does not say (fragmented MP4)
    duration_s: float  # 0 when the file does not say

    @property
    def fps(self) -> float:
        return self.frames / self.duration_s if self.frames and self.duration_s > 0 else 0.0


def _boxes(data: bytes, start: int, end: int) -> Iterator[tuple[bytes, int, int]]:
    """(type, payload start, box end) for each box in data[start:end]; stops at a truncated box."""
    i = start
    while i + 8 <= end:
        size, kind = struct.unpack_from(">I4s", data, i)
        head = 8
        if size == 1 and i + 16 <= end:
            (size,) = struct.unpack_from(">Q", data, i + 8)
            head = 16
        elif size == 0:  # the last box runs to the end
            size = end - i
        if size < head or i + size > end:
            return
        yield kind, i + head, i + size
        i += size


def _child(data: bytes, start: int, end: int, *path: bytes) -> tuple[int, int] | None:
    """The payload span of the first box at `path` below data[start:end]."""
    for kind, a, b in _boxes(data, start, end):
        if kind == path[0]:
            return (a, b) if len(path) == 1 else _child(data, a, b, *path[1:])
    return None


def _video_track(data: bytes, a: int, b: int) -> VideoTrack | None:
    """A 'trak' box's size and length if it is a video track (handler 'vide'), else None."""
    hdlr = _child(data, a, b, b"mdia", b"hdlr")
    if hdlr is None or hdlr[1] - hdlr[0] < 12 or data[hdlr[0] + 8 : hdlr[0] + 12] != b"vide":
        return None
    w = h = frames = 0
    duration_s = 0.0
    stsd = _child(data, a, b, b"mdia", b"minf", b"stbl", b"stsd")
    # stsd: version/flags, entry count, then the first sample entry: size, format, 6 reserved,
    # data reference index, 16 bytes of visual entry fields, then width and height (16 bit each)
    if stsd is not None and stsd[1] - stsd[0] >= 8 + 8 + 8 + 16 + 4:
        w, h = struct.unpack_from(">HH", data, stsd[0] + 8 + 8 + 8 + 16)
    stsz = _child(data, a, b, b"mdia", b"minf", b"stbl", b"stsz") or _child(
        data, a, b, b"mdia", b"minf", b"stbl", b"stz2"
    )
    if stsz is not None and stsz[1] - stsz[0] >= 12:
        (frames,) = struct.unpack_from(">I", data, stsz[0] + 8)
    mdhd = _child(data, a, b, b"mdia", b"mdhd")
    if mdhd is not None and mdhd[1] - mdhd[0] >= 24:
        if data[mdhd[0]] == 1 and mdhd[1] - mdhd[0] >= 36:  # version 1: 64-bit times
            scale, dur = struct.unpack_from(">IQ", data, mdhd[0] + 20)
        else:
            scale, dur = struct.unpack_from(">II", data, mdhd[0] + 12)
        duration_s = dur / scale if scale else 0.0
    return VideoTrack(int(w), int(h), int(frames), float(duration_s))


def probe_mp4(data: bytes) -> list[VideoTrack] | None:
    """The video tracks of an MP4/QuickTime file, from its boxes alone (nothing is decoded); None
    if `data` is not such a file or has no video track."""
    first = next(_boxes(data, 0, len(data)), None)
    if first is None or first[0] not in MP4_FIRST_BOXES:
        return None
    moov = _child(data, 0, len(data), b"moov")
    if moov is None:
        return None
    tracks = [_video_track(data, a, b) for kind, a, b in _boxes(data, *moov) if kind == b"trak"]
    found = [t for t in tracks if t is not None]
    return found or None


def sampled_count(frames: int, stride: int) -> int:
    """How many of `frames` frames are kept when every `stride`-th is, ending at the last."""
    return 0 if frames <= 0 else (frames - 1) // stride + 1


def iter_sampled(path: Path, frames: int, stride: int, max_decoded: int) -> Iterator[np.ndarray]:
    """Every `stride`-th BGR frame of the video at `path`, ending at its last frame, one at a time.

    `frames` is the count that the container declared (0: unknown, and then the sampling starts at
    the first frame); no frame beyond it, nor beyond `max_decoded`, is decoded, whatever the stream
    holds.
    """
    limit = min(frames, max_decoded) if frames > 0 else max_decoded
    phase = (frames - 1) % stride if frames > 0 else 0
    return iter_picked(path, lambda i: i % stride == phase, limit)


def iter_picked(path: Path, keep: Callable[[int], bool], limit: int) -> Iterator[np.ndarray]:
    """The BGR frames i < `limit` of the video at `path` for which keep(i), one at a time.

    Skipped frames are only `grab`bed (decoded, never converted). FFmpeg decodes on one thread:
    its frame threads would each hold a frame, and a request is one of many in a worker.
    """
    cap = cv2.VideoCapture(str(path), cv2.CAP_FFMPEG, [cv2.CAP_PROP_N_THREADS, 1])
    try:
        if not cap.isOpened():
            return
        for i in range(limit):
            if keep(i):
                ok, frame = cap.read()
                if not ok:
                    return
                yield frame
            elif not cap.grab():
                return
    finally:
        cap.release()
