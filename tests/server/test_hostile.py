"""Hostile input on public routes costs bounded memory and time (issue 9).

Each hostile request runs in a fresh child process that builds the real app on a prepared data
directory and sends the request through the Flask test client. The child measures the request's
own peak memory: it resets the kernel's high-water mark (`/proc/self/clear_refs`, "5") just before
the request and reads `VmHWM` right after, so what the app loaded before (the venue, the decoders,
a warm-up request) does not count. A guard on the child's address space keeps a bomb that gets
through from taking the machine down with it: the request then fails, and so does the test.

The bombs are built at test time and are small on the wire: a 1-bit PNG of 30,000 x 30,000 is
about 110 KB and decodes to 2.7 GB of BGR pixels.
"""

from __future__ import annotations

import json
import shutil
import struct
import subprocess
import sys
import zlib
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import pytest

from omninav.server import create_app
from omninav.spectrum import encode_binary
from omninav.store import Store
from server_helpers import ADMIN, TOKEN, clip_spectra, query_clip

MAX_EXTRA_MB = 150  # a hostile request may cost this much memory beyond what the worker held
MAX_WALL_S = 2.0  # and this long
GUARD_MB = 3000  # the child's address space may grow by this much before allocations fail
LENS_WH = (480, 360)  # the small venue's donut frames
PANO_WH = (3840, 1920)  # a 360-camera lens profile: big frames, the case that decoding all at once hurts

# The child: the app on a prepared data directory, warm-up requests, then the measured ones.
CHILD = r"""
import io, json, resource, sys, time
from werkzeug.test import EnvironBuilder
from omninav.server import create_app

def status_kb(key):
    with open("/proc/self/status") as f:
        for line in f:
            if line.startswith(key + ":"):
                return int(line.split()[1])
    raise KeyError(key)

def environ(req):
    data = None
    if "body" in req:
        with open(req["body"], "rb") as f:
            data = f.read()
    if "files" in req:
        data = {}
        for field, paths in req["files"].items():
            data[field] = [(io.BytesIO(open(p, "rb").read()), p.rsplit("/", 1)[-1]) for p in paths]
    b = EnvironBuilder(path=req["path"], method=req.get("method", "POST"), data=data,
                       content_type=req.get("content_type"), headers=req.get("headers", {}))
    try:
        return b.get_environ()
    finally:
        b.close()

spec = json.load(sys.stdin)
app = create_app(spec["config"])
client = app.test_client()
for req in spec["warmup"]:
    r = client.open(environ(req))
    assert r.status_code == 200, (req["path"], r.status_code, r.get_data()[:300])
vm = status_kb("VmSize") * 1024
resource.setrlimit(resource.RLIMIT_AS, (vm + spec["guard_mb"] * 2**20, resource.RLIM_INFINITY))
out = []
for req in spec["requests"]:
    env = environ(req)  # the body is read and the request built before measuring
    with open("/proc/self/clear_refs", "w") as f:
        f.write("5")  # VmHWM := VmRSS
    base = status_kb("VmRSS")
    t0 = time.perf_counter()
    r = client.open(env)
    wall = time.perf_counter() - t0
    peak = status_kb("VmHWM")
    out.append({"status": r.status_code, "json": r.get_json(silent=True), "extra_mb": (peak - base) / 1024,
                "wall_s": wall, "size": len(r.get_data())})
print("RESULT " + json.dumps(out))
"""


def run_child(data: Path, requests: list[dict[str, Any]], warmup: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """Send `requests` to a fresh app on `data` after `warmup`; each result has status, json,
    extra_mb (the request's own peak memory) and wall_s."""
    spec = {
        "config": {"DATA": str(data), "ADMIN_TOKEN": TOKEN, "LOCATE_RATE": 0.0, "JOB_RUNNER": False},
        "warmup": warmup,
        "requests": requests,
        "guard_mb": GUARD_MB,
    }
    p = subprocess.run(
        [sys.executable, "-c", CHILD], input=json.dumps(spec), capture_output=True, text=True, timeout=300
    )
    lines = [ln for ln in p.stdout.splitlines() if ln.startswith("RESULT ")]
    assert p.returncode == 0 and lines, f"child failed (rc {p.returncode}): {p.stderr[-3000:]}"
    results = json.loads(lines[-1][len("RESULT ") :])
    for q, r in zip(requests, results, strict=True):  # shown with -rP, and with a failure
        print(f"{q['path']}: {r['status']} in {r['wall_s']:.3f} s, {r['extra_mb']:.1f} MB extra")
    return results


def assert_bounded(res: dict[str, Any], status: int, *words: str, mb: float = MAX_EXTRA_MB) -> None:
    """The answer is `status` with an error naming `words`, and it cost at most `mb` and MAX_WALL_S."""
    body = res["json"] or {}
    assert res["status"] == status, res
    for w in words:
        assert w in body.get("error", ""), (w, body)
    assert res["extra_mb"] < mb, f"the request took {res['extra_mb']:.0f} MB extra (limit {mb}): {body}"
    assert res["wall_s"] < MAX_WALL_S, f"the request took {res['wall_s']:.2f} s: {body}"


# ---- hostile inputs, built at test time --------------------------------------------------------
def png_1bit(w: int, h: int) -> bytes:
    """A black 1-bit greyscale PNG: tiny on the wire, w*h*3 bytes once decoded to BGR."""

    def chunk(kind: bytes, payload: bytes) -> bytes:
        return struct.pack(">I", len(payload)) + kind + payload + struct.pack(">I", zlib.crc32(kind + payload))

    z = zlib.compressobj(9)
    row = bytes(1 + (w + 7) // 8)  # filter byte 0, then the packed row
    idat = b"".join(z.compress(row) for _ in range(h)) + z.flush()
    ihdr = struct.pack(">IIBBBBB", w, h, 1, 0, 0, 0, 0)
    return b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", ihdr) + chunk(b"IDAT", idat) + chunk(b"IEND", b"")


def flat_video(path: Path, wh: tuple[int, int], n: int, fps: float = 10.0, fourcc: str = "mp4v") -> Path:
    """n frames of one grey: cheap to encode at any size, and every frame still decodes in full."""
    vw = cv2.VideoWriter(str(path), cv2.VideoWriter.fourcc(*fourcc), fps, wh)
    assert vw.isOpened(), f"cannot write {path}"
    frame = np.full((wh[1], wh[0], 3), 128, np.uint8)
    for _ in range(n):
        vw.write(frame)
    vw.release()
    return path


def req(path: str, body: Path | None = None, content_type: str | None = None, **kw: Any) -> dict[str, Any]:
    r: dict[str, Any] = {"path": path, **kw}
    if body is not None:
        r["body"] = str(body)
    if content_type:
        r["content_type"] = content_type
    return r


# ---- the venue --------------------------------------------------------------------------------
def build_data(root: Path, modelled: Any, small_ds: Any, plan: bytes) -> Path:
    """A data directory with venue 'lab' (the small venue, modelled), its plan at 20 px/m and two
    lens profiles: 'donut' (the query clips' lens) and 'pano' (a 3840x1920 360-camera)."""
    st, _ = modelled
    shutil.copytree(st.root, root)
    app = create_app({"DATA": str(root), "ADMIN_TOKEN": TOKEN, "JOB_RUNNER": False})
    cat = app.extensions["omninav"].catalog
    cat.venues.create("lab", "Lab")
    cat.floors.set_plan("lab", "1", plan)
    cat.floors.put("lab", "1", {"px_per_m": 20.0})
    cat.lenses.put("lab", "donut", json.loads((small_ds.root / "model_lens.json").read_text()))
    pano = {"model": "equirectangular", "image_size": list(PANO_WH), "forward_x": PANO_WH[0] / 2, "ccw": False}
    cat.lenses.put("lab", "pano", pano)
    app.extensions["omninav"].db.engine.dispose()
    return root


@pytest.fixture(scope="module")
def lab(modelled, small_ds, tmp_path_factory) -> dict[str, Any]:
    """The venue's data directory and the files of a valid clip (record, frame, video) to warm up with."""
    d = tmp_path_factory.mktemp("hostile")
    data = build_data(d / "data", modelled, small_ds, small_ds.floorplan.read_bytes())
    frames, _ = query_clip(small_ds, 100)
    conf = Store(data).settings("lab")
    rec = d / "clip.onv"
    rec.write_bytes(encode_binary(clip_spectra(small_ds, frames, conf), conf))
    png = d / "frame.png"
    png.write_bytes(cv2.imencode(".png", frames[-1])[1].tobytes())
    vid = d / "clip.mp4"
    vw = cv2.VideoWriter(str(vid), cv2.VideoWriter.fourcc(*"mp4v"), 10.0, LENS_WH)
    for f in frames:
        vw.write(f)
    vw.release()
    warm = [
        req("/api/venues/lab/locate", rec, "application/octet-stream"),
        req("/api/venues/lab/locate?lens=donut", png, "image/png"),
        req("/api/venues/lab/locate", vid, "video/mp4"),
    ]
    return {"data": data, "dir": d, "warmup": warm, "png": png}


LOCATE = "/api/venues/lab/locate"


# ---- 1: image bombs ---------------------------------------------------------------------------
def test_a_png_bomb_is_refused_from_its_header(lab):
    bomb = lab["dir"] / "bomb.png"
    bomb.write_bytes(png_1bit(30000, 30000))
    assert bomb.stat().st_size < 200_000  # small on the wire, 2.7 GB decoded
    (res,) = run_child(lab["data"], [req(f"{LOCATE}?lens=donut", bomb, "image/png")], lab["warmup"])
    assert_bounded(res, 422, "30000x30000", "480x360", "'donut'")


def test_bomb_frames_in_a_multipart_request_are_refused_before_any_is_decoded(lab):
    bomb = lab["dir"] / "bomb12k.png"
    bomb.write_bytes(png_1bit(12000, 12000))  # ~17 KB, 430 MB decoded
    files = {"frame": [str(lab["png"])] + [str(bomb)] * 4}
    (res,) = run_child(lab["data"], [req(LOCATE, files=files, content_type="multipart/form-data")], lab["warmup"])
    assert_bounded(res, 422, "frame 1", "12000x12000", "480x360")


def test_only_png_and_jpeg_frames_are_decoded(lab):
    bmp = lab["dir"] / "frame.bmp"
    bmp.write_bytes(cv2.imencode(".bmp", np.zeros((LENS_WH[1], LENS_WH[0], 3), np.uint8))[1].tobytes())
    (res,) = run_child(lab["data"], [req(f"{LOCATE}?lens=donut", bmp, "image/png")], lab["warmup"])
    assert_bounded(res, 422, "not a readable JPEG or PNG")


def test_a_blank_clip_is_not_sure_rather_than_an_error(lab):
    """A lens cap or a dark room: nothing matches above 0, which used to be a 500 (IndexError)."""
    from omninav.spectrum import decode_binary

    conf = Store(lab["data"]).settings("lab")
    zeros = np.zeros_like(decode_binary(Path(lab["warmup"][0]["body"]).read_bytes(), conf))
    (lab["dir"] / "zeros.onv").write_bytes(encode_binary(zeros, conf))
    black = lab["dir"] / "black.png"
    black.write_bytes(cv2.imencode(".png", np.zeros((LENS_WH[1], LENS_WH[0], 3), np.uint8))[1].tobytes())
    res = run_child(
        lab["data"],
        [
            req(LOCATE, lab["dir"] / "zeros.onv", "application/octet-stream"),
            req(f"{LOCATE}?lens=donut", black, "image/png"),
        ],
        lab["warmup"],
    )
    for r in res:
        assert r["status"] == 200 and r["json"]["low_confidence"], r
        assert r["json"]["sentence"].startswith("Not sure where you are")


def test_frames_are_decoded_one_at_a_time(lab):
    """Sixteen 3840x1920 frames of a 360-camera are 350 MB decoded: the request may hold one."""
    rng = np.random.default_rng(1)
    frame = rng.integers(0, 255, (PANO_WH[1] // 8, PANO_WH[0] // 8, 3), np.uint8)
    frame = cv2.resize(frame, PANO_WH, interpolation=cv2.INTER_NEAREST)  # blocks: real pixels, small JPEG
    jpg = lab["dir"] / "pano.jpg"
    jpg.write_bytes(cv2.imencode(".jpg", frame, [cv2.IMWRITE_JPEG_QUALITY, 60])[1].tobytes())
    files = {"frame": [str(jpg)] * 16}
    warm = [*lab["warmup"], req(f"{LOCATE}?lens=pano", jpg, "image/jpeg")]  # builds the pano remap
    (res,) = run_child(lab["data"], [req(f"{LOCATE}?lens=pano", files=files, content_type="multipart/form-data")], warm)
    assert res["status"] == 200 and res["json"]["frames"] == 16, res
    assert res["extra_mb"] < 100, f"{res['extra_mb']:.0f} MB for 16 frames of 22 MB each"
    assert res["wall_s"] < 4 * MAX_WALL_S, res["wall_s"]  # 16 big frames of real work, on a shared core


# ---- 2: video bombs ---------------------------------------------------------------------------
def test_a_huge_video_is_refused_from_its_container(lab):
    vid = flat_video(lab["dir"] / "huge.mp4", (4000, 4000), 2)
    (res,) = run_child(lab["data"], [req(LOCATE, vid, "video/mp4")], lab["warmup"])
    assert_bounded(res, 422, "the video is 4000x4000", "480x360")


def test_a_long_video_is_refused_before_it_is_decoded(lab):
    vid = flat_video(lab["dir"] / "long.mp4", LENS_WH, 1000)  # 100 s at 10 fps: 520 MB decoded
    files = {"video": [str(vid)]}
    res = run_child(
        lab["data"],
        [req(LOCATE, vid, "video/mp4"), req(LOCATE, files=files, content_type="multipart/form-data")],
        lab["warmup"],
    )
    for r in res:
        assert_bounded(r, 413, "the video is 100 s long", "at most 5 s")


def test_other_containers_are_refused_by_name(lab):
    vid = flat_video(lab["dir"] / "clip.avi", LENS_WH, 5, fourcc="MJPG")
    (res,) = run_child(lab["data"], [req(LOCATE, vid, "video/x-msvideo")], lab["warmup"])
    assert_bounded(res, 422, "MP4")


# ---- feature records: what they cost is parsing them ------------------------------------------
def test_an_oversized_feature_record_is_refused_before_it_is_parsed(lab):
    """31 MB of JSON numbers took 410 MB and 6 s to parse and refuse; as 4 M one-number frames, 1.2 GB and 43 s."""
    d = lab["dir"]
    n = 31 * 2**20 // 8
    (d / "numbers.json").write_text('{"version": 1, "mag": [' + ",".join(["[[0.5]]"] * n) + '], "phase": []}')
    (d / "frames.onv").write_bytes(b"ONV" + bytes(31 * 2**20))
    res = run_child(
        lab["data"],
        [
            req(LOCATE, d / "numbers.json", "application/json"),
            req(LOCATE, d / "frames.onv", "application/octet-stream"),
        ],
        lab["warmup"],
    )
    assert_bounded(res[0], 413, "JSON feature record is", "at most 60 frames")
    assert_bounded(res[1], 413, "too many frames", "at most 60")


# ---- 4: floor plans ---------------------------------------------------------------------------
def test_a_plan_bomb_is_refused_from_its_header(lab):
    big = lab["dir"] / "plan16k.png"
    big.write_bytes(png_1bit(16384, 16384))
    wide = lab["dir"] / "plan48mp.png"
    wide.write_bytes(png_1bit(8000, 6000))
    put = {"method": "PUT", "headers": ADMIN}
    res = run_child(
        lab["data"],
        [
            req("/api/admin/venues/lab/floors/1/plan", big, "image/png", **put),
            req("/api/admin/venues/lab/floors/1/plan", wide, "image/png", **put),
        ],
        lab["warmup"],
    )
    assert_bounded(res[0], 422, "16384x16384", "at most 8192")
    assert_bounded(res[1], 422, "8000x6000", "48.0 megapixels", "at most 40")


@pytest.fixture(scope="module")
def big_plan(lab, modelled, small_ds) -> Path:
    """The venue with a 40-megapixel floor plan (8000x5000, the largest accepted)."""
    plan = np.full((5000, 8000, 3), 255, np.uint8)
    plan[::200] = 0  # a grid, so the image is not all one colour
    plan[:, ::200] = 0
    return build_data(lab["dir"] / "bigplan", modelled, small_ds, cv2.imencode(".png", plan)[1].tobytes())


def test_the_annotated_plan_is_drawn_on_a_cached_small_copy(lab, big_plan):
    import base64

    def plan_image(answer: dict[str, Any]) -> np.ndarray:
        png = base64.b64decode(answer["plan_png"].split(",")[1])
        return cv2.imdecode(np.frombuffer(png, np.uint8), cv2.IMREAD_COLOR)

    small = lab["dir"] / "plan800.png"
    small.write_bytes(cv2.imencode(".png", np.full((500, 800, 3), 255, np.uint8))[1].tobytes())
    locate = {**lab["warmup"][0], "path": f"{LOCATE}?plan=1"}
    res = run_child(
        big_plan,
        [
            locate,
            locate,
            req("/api/admin/venues/lab/floors/1/plan", small, "image/png", method="PUT", headers=ADMIN),
            locate,  # a new plan is a new file: prepared again
            req("/api/venues/lab/floors/1/plan.png", method="GET"),
        ],
        [*lab["warmup"], locate],  # the first ?plan=1 prepares the 40 MP plan (120 MB, once)
    )
    assert all(r["status"] == 200 for r in res), res
    for r in res[:2]:
        assert r["extra_mb"] < 60 and r["wall_s"] < 1.0, r  # drawing on the 40 MP plan itself: 120 MB, 1.5 s
    img = plan_image(res[1]["json"])
    assert img.shape[:2] == (1000, 1600)  # 8000x5000 scaled to 1600 px on its long side
    x, y = int(res[1]["json"]["x"] * 20 / 5), int(res[1]["json"]["y"] * 20 / 5)
    b, g, r_ = img[y, x].astype(int)
    assert r_ > 180 and g < 60 and b < 60  # the position dot, at the scaled position
    assert plan_image(res[3]["json"]).shape[:2] == (500, 800)
    assert res[4]["size"] == (big_plan / "plans" / "lab" / "1.png").stat().st_size  # the new plan, streamed


# ---- 5: JSON that the parser or the database chokes on ----------------------------------------
def test_deep_json_and_lone_surrogates_are_400_and_leave_nothing_behind(lab):
    d = lab["dir"]
    bodies = {
        "deep.json": b"[" * 1000,
        "deep5000.json": b"[" * 5000,  # issue 10: RecursionError in the parser itself
        "deep_obj.json": b'{"a":' * 5000 + b"1" + b"}" * 5000,
        "deep100.json": b'{"mag": ' + b"[" * 100 + b"]" * 100 + b"}",  # parses: later code would recurse
        "escaped.json": b'{"id": "x", "name": "\\ud800"}',
        "raw.json": b'{"id": "x", "name": "\xed\xa0\x80"}',  # a surrogate encoded as UTF-8
        "key.json": b'{"id": "x", "\\udfff": 1}',
        "ok.json": b'{"id": "x", "name": "\\ud83d\\ude00 ok"}',  # a proper pair is a proper character
    }
    for name, body in bodies.items():
        (d / name).write_bytes(body)
    post = {"headers": ADMIN}
    res = run_child(
        lab["data"],
        [
            req(LOCATE, d / "deep.json", "application/json"),
            req(LOCATE, d / "deep5000.json", "application/json"),
            req(LOCATE, d / "deep_obj.json", "application/json"),
            req(LOCATE, d / "deep100.json", "application/json"),
            req("/api/admin/venues", d / "escaped.json", "application/json", **post),
            req("/api/admin/venues", d / "raw.json", "application/json", **post),
            req("/api/admin/venues", d / "key.json", "application/json", **post),
            req("/api/admin/venues", d / "ok.json", "application/json", **post),
        ],
        lab["warmup"],
    )
    for r in (res[0], res[2], res[3]):
        assert_bounded(r, 400, "nests too deeply")
    # 5,000 arrays are more than any record of 60 frames has: refused before it is parsed
    assert_bounded(res[1], 413, "more arrays")
    assert_bounded(res[4], 400, "surrogate")
    assert_bounded(res[5], 400, "not valid JSON", "utf-8")  # JSON text is UTF-8, and this is not
    assert_bounded(res[6], 400, "surrogate")
    # nothing of the refused venue was left: the same id is then created, with its emoji
    assert res[7]["status"] == 201 and res[7]["json"]["name"] == "\U0001f600 ok", res[7]


def test_a_venue_whose_insert_fails_leaves_nothing(tmp_path):
    app = create_app({"DATA": str(tmp_path), "ADMIN_TOKEN": TOKEN, "JOB_RUNNER": False})
    cat = app.extensions["omninav"].catalog
    with pytest.raises(Exception):  # noqa: B017 - the database refuses the name; which error is the driver's
        cat.venues.create("x", "\ud800")
    assert not (tmp_path / "venues" / "x").exists() and not cat.venues.exists("x")
    assert cat.venues.create("x", "X")["name"] == "X"
