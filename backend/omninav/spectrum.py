"""Fourier spectra of the curves and the compact per-frame record the phone sends.

FFT magnitudes are invariant to the circular shift that a rotation of the camera causes, so they
key the search; the phases carry the rotation, which heading.py recovers (the paper's Eq. 6-7).

The record (version 1) holds the leading K harmonics of each of the C curves:
magnitudes as float16 and phases as int16 (2*pi / 65536 rad steps, far finer than the heading
needs), so 4*C*K bytes plus a 20-byte header that names the settings the record was made with
(`presets.settings_id`): 14 curves x 16 harmonics (the default preset) = 916 bytes for one frame.
"""

from __future__ import annotations

import math
import struct
from typing import Any

import numpy as np

from .errors import OmninavError
from .presets import n_curves, settings_id

RECORD_VERSION = 1
MAGIC = b"ONV"
# magic, version, n_curves, n_harmonics, pano_width, n_frames, settings id
_HEADER = struct.Struct("<3sBHHHII2x")
HEADER_BYTES = _HEADER.size
MAX_RECORD_BYTES = 1024
# Every frame of a record is at unit energy (spectrum()), or at none: a frame without texture (a
# lens cap, a blank wall) has flat curves. float16 magnitudes keep a unit frame's sum of squares
# within about 0.1 % of 1. A frame far from both is not a record's: its phase correlation is no
# longer a cosine, so a broken client's frames would score up to sqrt(C*K) times a perfect match
# and be answered as sure.
ENERGY_TOL = 0.01
NO_ENERGY = 1e-4


def spectrum(curves: np.ndarray, n_harmonics: int) -> np.ndarray:
    """(..., C, W) float32 curves -> (..., C, K) complex64 harmonics 1..K, unit total energy.

    Scaling each frame to unit energy makes the phase correlation of two frames a cosine in
    [-1, 1] (Parseval), comparable across frames and venues.
    """
    w = curves.shape[-1]
    if not 1 <= n_harmonics <= w // 2:
        raise ValueError(f"n_harmonics must be in [1, {w // 2}], got {n_harmonics}")
    f = np.fft.rfft(curves.astype(np.float32), axis=-1)[..., 1 : n_harmonics + 1]
    e = np.sqrt((np.abs(f) ** 2).sum(axis=(-2, -1), keepdims=True))
    out: np.ndarray = (f / np.maximum(e, 1e-12)).astype(np.complex64)
    return out


def quantise(spec: np.ndarray) -> np.ndarray:
    """The spectrum as the record carries it: float16 magnitudes, int16 phases, back to complex64.

    The server quantises modelled frames the same way, so phone and venue compare like with like.
    """
    mag, ph = _split(spec)
    return _join(mag, ph)


def _split(spec: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    mag = np.abs(spec).astype(np.float16)
    ph = np.round(np.angle(spec) * (32768.0 / math.pi))
    ph = np.where(ph >= 32768, ph - 65536, ph).astype(np.int16)
    return mag, ph


def _join(mag: np.ndarray, ph: np.ndarray) -> np.ndarray:
    a = ph.astype(np.float32) * np.float32(math.pi / 32768.0)
    out: np.ndarray = (mag.astype(np.float32) * np.exp(1j * a)).astype(np.complex64)
    return out


def encode_binary(spec: np.ndarray, conf: dict[str, Any]) -> bytes:
    """(F, C, K) or (C, K) complex spectra -> the version-1 binary record (little endian)."""
    s = spec[None] if spec.ndim == 2 else spec
    f, c, k = s.shape
    mag, ph = _split(s)
    head = _HEADER.pack(MAGIC, RECORD_VERSION, c, k, conf["pano_width"], f, settings_id(conf))
    return head + mag.astype("<f2").tobytes() + ph.astype("<i2").tobytes()


def decode_binary(buf: bytes, expect: dict[str, Any] | None = None) -> np.ndarray:
    """Binary record -> (F, C, K) complex64; every malformation raises OmninavError naming it."""
    if len(buf) < _HEADER.size:
        raise OmninavError(f"feature record too short: {len(buf)} bytes, header is {_HEADER.size}")
    magic, ver, c, k, w, f, sid = _HEADER.unpack_from(buf)
    if magic != MAGIC:
        raise OmninavError("not an omninav feature record (bad magic)")
    if ver != RECORD_VERSION:
        raise OmninavError(f"feature record version {ver} is not supported (expected 1)")
    n = f * c * k
    if c == 0 or k == 0 or f == 0:
        raise OmninavError("feature record holds no frames, curves or harmonics")
    want = _HEADER.size + n * 4
    if len(buf) != want:
        # what the header claims, so a truncated record and a header of garbage both read plainly
        raise OmninavError(
            f"feature record is {len(buf)} bytes, but its header says {f} x {c} x {k} (frames x curves x "
            f"harmonics), which take {want} bytes"
        )
    mag = np.frombuffer(buf, "<f2", n, _HEADER.size).reshape(f, c, k)
    ph = np.frombuffer(buf, "<i2", n, _HEADER.size + 2 * n).reshape(f, c, k)
    _check(mag, c, k, w, sid, expect)
    return _join(mag, ph)


def encode_json(spec: np.ndarray, conf: dict[str, Any]) -> dict[str, Any]:
    s = spec[None] if spec.ndim == 2 else spec
    mag, ph = _split(s)
    return {
        "version": RECORD_VERSION,
        "preset": conf.get("preset", "default"),
        "settings_id": settings_id(conf),
        "pano_width": conf["pano_width"],
        "n_curves": int(s.shape[1]),
        "n_harmonics": int(s.shape[2]),
        "mag": mag.astype(np.float64).tolist(),  # float16 values print exactly
        "phase": ph.astype(int).tolist(),
    }


def decode_json(obj: Any, expect: dict[str, Any] | None = None) -> np.ndarray:
    if not isinstance(obj, dict):
        raise OmninavError("feature record must be a JSON object")
    if "version" not in obj:
        raise OmninavError("not an omninav feature record (it has no 'version')")
    if obj.get("version") != RECORD_VERSION:
        raise OmninavError(f"feature record version {obj.get('version')!r} is not supported")
    try:
        mag = np.asarray(obj["mag"], dtype=np.float64)
        ph = np.asarray(obj["phase"], dtype=np.float64)
    except KeyError as e:
        raise OmninavError(f"feature record is missing {e.args[0]!r}") from None
    except (TypeError, ValueError, OverflowError):  # ragged, not numbers, or an integer past float64
        raise OmninavError("feature record 'mag' and 'phase' must be arrays of numbers") from None
    if mag.ndim != 3 or mag.shape != ph.shape:
        raise OmninavError(
            f"'mag' and 'phase' must both be [frames][curves][harmonics]; got {mag.shape} and {ph.shape}"
        )
    if not (np.isfinite(mag).all() and np.isfinite(ph).all()):
        raise OmninavError("feature record contains NaN or Inf")
    if (ph < -32768).any() or (ph > 32767).any() or (ph != np.round(ph)).any():
        raise OmninavError("feature record phases must be integers in [-32768, 32767]")
    _, c, k = mag.shape
    sid = _whole(obj.get("settings_id"))
    if sid is None:
        raise OmninavError("feature record 'settings_id' must be an integer")
    w = _whole(obj.get("pano_width"))
    if w is None:
        raise OmninavError("feature record 'pano_width' must be an integer")
    _check(mag, c, k, w, sid, expect)
    return _join(mag.astype(np.float16), ph.astype(np.int16))


def _whole(v: Any) -> int | None:
    """A JSON integer (42, or 42.0 as some encoders write it) as int, else None."""
    if isinstance(v, float) and v.is_integer():
        return int(v)
    return v if isinstance(v, int) and not isinstance(v, bool) else None


def _check(mag: np.ndarray, c: int, k: int, w: int, sid: int, expect: dict[str, Any] | None) -> None:
    m = np.asarray(mag, np.float32)
    if not np.isfinite(m).all():
        raise OmninavError("feature record contains NaN or Inf")
    if (m < 0).any() or (m > 1.0001).any():
        raise OmninavError("feature record magnitudes must lie in [0, 1]")
    if expect is not None:
        # the settings id first: a phone that read the venue before it was modelled anew sends the
        # old id, and maybe the old number of curves too; told so (venue_settings_id), it reads
        # the venue again and says that the map was updated
        if sid != settings_id(expect):
            raise OmninavError(
                f"features were made with other settings (id {sid}) than this venue's "
                f"({settings_id(expect)}); extract them with the venue's feature settings",
                venue_settings_id=settings_id(expect),
            )
        want = (n_curves(expect), expect["n_harmonics"], expect["pano_width"])
        if (c, k, w) != want:
            older = ""
            if expect.get("band_channels") is not None and c == n_curves({**expect, "band_channels": None}):
                # an app from before per-band channels read the venue's settings without them
                older = "; this app is older than the server: close it and open it again"
            raise OmninavError(
                f"features have {c} curves x {k} harmonics (width {w}); this venue needs "
                f"{want[0]} x {want[1]} (width {want[2]}){older}"
            )
    e = (m.astype(np.float64) ** 2).sum(axis=(1, 2))
    off = np.flatnonzero((np.abs(e - 1.0) > ENERGY_TOL) & (e > NO_ENERGY))
    if off.size:
        raise OmninavError(
            f"feature record frame {int(off[0])} is not at unit energy: the squares of its magnitudes "
            f"sum to {float(e[off[0]]):.3g}, not 1 ({off.size} of {len(e)} frames are off; each frame's "
            "harmonics are scaled together to unit energy, docs/formats.md, 'Feature record')"
        )


def record_bytes_per_frame(conf: dict[str, Any]) -> int:
    return 4 * n_curves(conf) * int(conf["n_harmonics"])
