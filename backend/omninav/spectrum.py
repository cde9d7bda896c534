"""Fourier spectra of the curves and the compact per-frame record the phone sends.

FFT magnitudes are invariant to the circular shift that a rotation of the camera causes, so they
key the search; the phases carry the rotation, which heading.py recovers (the paper's Eq. 6-7).

The record (version 1) holds the leading K harmonics of each of the C curves:
magnitudes as float16 and phases as int16 (2*pi / 65536 rad steps, far finer than the heading
needs), so 4*C*K bytes plus a 20-byte header that names the settings the record was made with
(`presets.settings_id`): 14 curves x 16 harmonics (the default preset) = 916 bytes for one frame.
Version 2 adds the clip's last frame's local features after the phases (verify.py: at most 880
ORB keypoints, 36 bytes each), for a venue that verifies; version 1 stays what it was.
"""

from __future__ import annotations

import base64
import binascii
import math
import struct
from typing import Any

import numpy as np

from .errors import OmninavError
from .presets import n_curves, settings_id

LocalQuery = tuple[np.ndarray, np.ndarray]  # a frame's local features: (N, 3) bearings, (N, 32) descriptors
RECORD_VERSION = 1
LOCAL_VERSION = 2  # a record with a local block (docs/formats.md, "Local block")
VERSIONS = (RECORD_VERSION, LOCAL_VERSION)
MAGIC = b"ONV"
LOCAL_MAGIC = b"LOC"
_LOCAL_HEAD = struct.Struct("<3sBI")  # magic, keypoints N; then N uint16 az, N int16 el, N x 32 bytes
LOCAL_HEAD_BYTES = _LOCAL_HEAD.size
LOCAL_BYTES_PER_KEYPOINT = 2 + 2 + 32
MAX_LOCAL_KEYPOINTS = 880  # 8 + 36 x 880 = 31,688 bytes: a request's local features within 32 KB
LOCAL_MAX_BYTES = LOCAL_HEAD_BYTES + LOCAL_BYTES_PER_KEYPOINT * MAX_LOCAL_KEYPOINTS
# a JSON local block at most: per keypoint two integers (6 bytes and a comma each) and 44 base64
# characters of descriptor, and the keys
LOCAL_JSON_BYTES = 256 + MAX_LOCAL_KEYPOINTS * (2 * 7 + 44)
AZ_STEP = 360.0 / 65536.0  # degrees a unit of a keypoint's azimuth
EL_STEP = 0.01  # ... and of its elevation
EL_MAX = 9000  # 90 degrees
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


def encode_binary(spec: np.ndarray, conf: dict[str, Any], local: LocalQuery | None = None) -> bytes:
    """(F, C, K) or (C, K) complex spectra -> the binary record (little endian): version 1, or 2
    with the clip's last frame's local features (`local`: (N, 3) unit bearings, (N, 32) ORB
    descriptors; the first MAX_LOCAL_KEYPOINTS kept)."""
    s = spec[None] if spec.ndim == 2 else spec
    f, c, k = s.shape
    mag, ph = _split(s)
    ver = RECORD_VERSION if local is None else LOCAL_VERSION
    head = _HEADER.pack(MAGIC, ver, c, k, conf["pano_width"], f, settings_id(conf))
    body = head + mag.astype("<f2").tobytes() + ph.astype("<i2").tobytes()
    return body if local is None else body + encode_local(local)


def encode_local(local: LocalQuery) -> bytes:
    """(N, 3) unit bearings and (N, 32) ORB descriptors -> a version-2 record's local block (the
    first MAX_LOCAL_KEYPOINTS kept)."""
    az, el, desc = _local_units(*local)
    return _LOCAL_HEAD.pack(LOCAL_MAGIC, 0, len(az)) + az.tobytes() + el.tobytes() + desc.tobytes()


def bearing_vectors(az_deg: np.ndarray, el_deg: np.ndarray) -> np.ndarray:
    """Azimuths (clockwise from the lens's forward direction) and elevations, degrees -> (N, 3)
    float32 unit bearings, x = cos e sin a, y = cos e cos a, z = sin e: a keypoint's direction, in
    the record and in a venue's local features (verify.py)."""
    a, e = np.radians(np.asarray(az_deg, np.float64)), np.radians(np.asarray(el_deg, np.float64))
    return np.stack([np.cos(e) * np.sin(a), np.cos(e) * np.cos(a), np.sin(e)], 1).astype(np.float32)


def _local_units(bearings: np.ndarray, desc: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Bearings and descriptors -> the record's (N,) uint16 azimuths, (N,) int16 elevations and
    (N, 32) uint8 descriptors, at most MAX_LOCAL_KEYPOINTS."""
    b = np.asarray(bearings, np.float64)[:MAX_LOCAL_KEYPOINTS]
    az = np.degrees(np.arctan2(b[:, 0], b[:, 1])) % 360.0
    el = np.degrees(np.arctan2(b[:, 2], np.hypot(b[:, 0], b[:, 1])))
    az_u = (np.round(az / AZ_STEP).astype(np.int64) % 65536).astype("<u2")
    el_u = np.round(el / EL_STEP).astype("<i2")
    return az_u, el_u, np.ascontiguousarray(desc[:MAX_LOCAL_KEYPOINTS], np.uint8)


def _bearings(az_u: np.ndarray, el_u: np.ndarray) -> np.ndarray:
    """The record's azimuth and elevation units -> (N, 3) float32 unit bearings."""
    return bearing_vectors(az_u.astype(np.float64) * AZ_STEP, el_u.astype(np.float64) * EL_STEP)


def _local_block(buf: bytes, at: int) -> LocalQuery:
    """The local block of a version-2 binary record at byte `at` -> (bearings, descriptors)."""
    if len(buf) < at + LOCAL_HEAD_BYTES:
        raise OmninavError(
            f"feature record version 2 has no local block after its phases ({len(buf)} bytes, the block starts at {at})"
        )
    magic, pad, n = _LOCAL_HEAD.unpack_from(buf, at)
    if magic != LOCAL_MAGIC or pad != 0:
        raise OmninavError("feature record's local block does not start with 'LOC' and a zero byte")
    if n > MAX_LOCAL_KEYPOINTS:
        raise OmninavError(f"feature record's local block has {n} keypoints; at most {MAX_LOCAL_KEYPOINTS}")
    want = at + LOCAL_HEAD_BYTES + LOCAL_BYTES_PER_KEYPOINT * n
    if len(buf) != want:
        raise OmninavError(
            f"feature record is {len(buf)} bytes, but its headers say {want} (its local block: {n} keypoints)"
        )
    at += LOCAL_HEAD_BYTES
    az = np.frombuffer(buf, "<u2", n, at)
    el = np.frombuffer(buf, "<i2", n, at + 2 * n)
    _check_elevations(el)
    desc = np.frombuffer(buf, np.uint8, 32 * n, at + 4 * n).reshape(n, 32)
    return _bearings(az, el), desc


def _check_elevations(el: np.ndarray) -> None:
    if el.size and (np.abs(el.astype(np.int64)) > EL_MAX).any():
        raise OmninavError("feature record's local elevations must lie in [-90, 90] degrees")


def decode_binary(buf: bytes, expect: dict[str, Any] | None = None) -> np.ndarray:
    """Binary record -> (F, C, K) complex64; every malformation raises OmninavError naming it."""
    return decode_binary_local(buf, expect)[0]


def decode_binary_local(buf: bytes, expect: dict[str, Any] | None = None) -> tuple[np.ndarray, LocalQuery | None]:
    """Binary record -> ((F, C, K) complex64, its local features or None (version 1))."""
    if len(buf) < _HEADER.size:
        raise OmninavError(f"feature record too short: {len(buf)} bytes, header is {_HEADER.size}")
    magic, ver, c, k, w, f, sid = _HEADER.unpack_from(buf)
    if magic != MAGIC:
        raise OmninavError("not an omninav feature record (bad magic)")
    if ver not in VERSIONS:
        raise OmninavError(f"feature record version {ver} is not supported (expected 1 or 2)")
    n = f * c * k
    if c == 0 or k == 0 or f == 0:
        raise OmninavError("feature record holds no frames, curves or harmonics")
    want = _HEADER.size + n * 4
    if len(buf) != want and (ver == RECORD_VERSION or len(buf) < want):
        # what the header claims, so a truncated record and a header of garbage both read plainly
        raise OmninavError(
            f"feature record is {len(buf)} bytes, but its header says {f} x {c} x {k} (frames x curves x "
            f"harmonics), which take {want} bytes"
        )
    local = _local_block(buf, want) if ver == LOCAL_VERSION else None
    mag = np.frombuffer(buf, "<f2", n, _HEADER.size).reshape(f, c, k)
    ph = np.frombuffer(buf, "<i2", n, _HEADER.size + 2 * n).reshape(f, c, k)
    _check(mag, c, k, w, sid, expect)
    return _join(mag, ph), local


def encode_json(spec: np.ndarray, conf: dict[str, Any], local: LocalQuery | None = None) -> dict[str, Any]:
    s = spec[None] if spec.ndim == 2 else spec
    mag, ph = _split(s)
    extra: dict[str, Any] = {}
    if local is not None:
        az, el, desc = _local_units(*local)
        extra["local"] = {
            "az": az.astype(int).tolist(),
            "el": el.astype(int).tolist(),
            "descriptors": base64.b64encode(desc.tobytes()).decode(),
        }
    return {
        "version": RECORD_VERSION if local is None else LOCAL_VERSION,
        "preset": conf.get("preset", "default"),
        "settings_id": settings_id(conf),
        "pano_width": conf["pano_width"],
        "n_curves": int(s.shape[1]),
        "n_harmonics": int(s.shape[2]),
        "mag": mag.astype(np.float64).tolist(),  # float16 values print exactly
        "phase": ph.astype(int).tolist(),
        **extra,
    }


def decode_json(obj: Any, expect: dict[str, Any] | None = None) -> np.ndarray:
    return decode_json_local(obj, expect)[0]


def _json_local(obj: Any) -> LocalQuery:
    """A version-2 JSON record's 'local' -> (bearings, descriptors)."""
    if not isinstance(obj, dict):
        raise OmninavError("feature record version 2 needs 'local': {'az', 'el', 'descriptors'}")
    az, el, d = obj.get("az"), obj.get("el"), obj.get("descriptors")
    if not isinstance(az, list) or not isinstance(el, list) or not isinstance(d, str):
        raise OmninavError("'local' needs 'az' and 'el' (lists of integers) and 'descriptors' (base64)")
    n = len(az)
    if n > MAX_LOCAL_KEYPOINTS or len(el) != n or len(d) != 4 * -(-32 * n // 3):
        raise OmninavError(
            f"'local' must hold at most {MAX_LOCAL_KEYPOINTS} keypoints, as many elevations as azimuths "
            "and 32 bytes of descriptor each"
        )
    if not all(type(v) is int and 0 <= v < 65536 for v in az):
        raise OmninavError("'local' azimuths must be integers in [0, 65535]")
    if not all(type(v) is int and abs(v) <= EL_MAX for v in el):
        raise OmninavError(f"'local' elevations must be integers in [-{EL_MAX}, {EL_MAX}] ([-90, 90] degrees)")
    try:
        raw = base64.b64decode(d, validate=True)
    except (binascii.Error, ValueError):  # (a non-ASCII string is a ValueError)
        raise OmninavError("'local' descriptors are not base64") from None
    if len(raw) != 32 * n:
        raise OmninavError(f"'local' descriptors hold {len(raw)} bytes; {n} keypoints take {32 * n}")
    return _bearings(np.asarray(az), np.asarray(el)), np.frombuffer(raw, np.uint8).reshape(n, 32)


def decode_json_local(obj: Any, expect: dict[str, Any] | None = None) -> tuple[np.ndarray, LocalQuery | None]:
    """JSON record -> ((F, C, K) complex64, its local features or None (version 1))."""
    if not isinstance(obj, dict):
        raise OmninavError("feature record must be a JSON object")
    if "version" not in obj:
        raise OmninavError("not an omninav feature record (it has no 'version')")
    if obj.get("version") not in VERSIONS or isinstance(obj.get("version"), bool):
        raise OmninavError(f"feature record version {obj.get('version')!r} is not supported")
    if obj["version"] == RECORD_VERSION and "local" in obj:
        raise OmninavError("a feature record with 'local' is version 2")
    local = _json_local(obj.get("local")) if obj["version"] == LOCAL_VERSION else None
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
    return _join(mag.astype(np.float16), ph.astype(np.int16)), local


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
