"""Modelling speed: `omninav model` on a 30 fps 960x720 video, as a multiple of real time, and the
same video modelled through the server's upload API as a background job.

Renders (once, cached) 40 s of a modelling walk through the default synthetic venue at 30 fps,
then runs the real CLI on it (decoding every frame, extracting features at the preset's 10 fps;
wall clock with the interpreter's start, and the modelling alone as the CLI reports it), a
decode-only pass as the floor any modelling run sits on, and, in the same run, `omninav serve`
(as `npm start` runs it), up 3 s as a server an admin uploads to is, with the video uploaded in
8 MiB pieces and modelled by a job. Also in the same run: the video modelled in this process with
the default preset and with it unlevelled (`level_iters` off: what levelling, level.py, costs a
modelled frame), and with the default preset while another process keeps one core busy (a
server's other worker). Walks this long extract on a process a core (extract_pool.py).

    python -m bench.model_speed [--seconds 40] [--no-api]
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import cv2
import numpy as np

from bench.common import machine
from bench.server_load import one_core_busy
from omninav.lens import load_lens
from omninav.model_venue import model_video, start_workers
from omninav.presets import resolve
from omninav.store import Store
from omninav.synth import MODELLING, build_scene, donut_lens, upgrade_names
from omninav.synth.walks import (
    default_routes,
    poses_from_walk_path,
    render_frames,
    walk_path_for,
    write_json,
    write_video,
)
from omninav.video import extract_threads
from omninav.walk_path import load_walk_path


def render(root: Path, seconds: float) -> None:
    if (upgrade_names(root) / "model30.mp4").exists():
        return
    root.mkdir(parents=True, exist_ok=True)
    scene = build_scene(0)
    route, _ = default_routes(scene)
    walk_path = walk_path_for(route, [1.2], 30.0)
    walk_path["waypoints"] = [w for w in walk_path["waypoints"] if w["t"] <= seconds + 25]
    poses = poses_from_walk_path(walk_path, MODELLING, np.random.default_rng(0))[: int(seconds * 30)]
    lens = donut_lens()
    write_json(root / "walk_path30.json", walk_path)
    write_json(root / "lens.json", lens.to_dict())
    frames = (f for _, f in render_frames(scene, lens, poses, MODELLING, 1))
    write_video(root / "model30.mp4", frames, 30.0, lens.image_size)


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--seconds", type=float, default=40.0)
    ap.add_argument("--root", type=Path, default=Path("data") / "bench-model-speed")
    ap.add_argument("--no-api", action="store_true", help="only the CLI")
    a = ap.parse_args()
    render(a.root, a.seconds)
    video = a.root / "model30.mp4"
    cap = cv2.VideoCapture(str(video))
    n = int(cap.get(cv2.CAP_PROP_FRAME_COUNT))
    fps = cap.get(cv2.CAP_PROP_FPS)
    t = time.perf_counter()
    while cap.grab():
        pass
    decode = time.perf_counter() - t
    cap.release()
    omninav = str(Path(sys.executable).with_name("omninav"))
    with tempfile.TemporaryDirectory() as d:
        subprocess.run([omninav, "--data", d, "venue", "create", "speed"], check=True, capture_output=True)
        t = time.perf_counter()
        p = subprocess.run(
            [
                omninav,
                "--data",
                d,
                "model",
                "speed",
                str(video),
                "--walk-path",
                str(a.root / "walk_path30.json"),
                "--lens",
                str(a.root / "lens.json"),
            ],
            check=True,
            capture_output=True,
            text=True,
        )
        wall = time.perf_counter() - t
    out = json.loads(p.stdout)
    dur = n / fps
    print(f"machine: {machine()}")
    print(f"video: {n} frames, {fps:.0f} fps, 960x720 MPEG-4, {dur:.1f} s")
    print(f"decode only (grab every frame): {decode:.2f} s = {dur / decode:.1f}x real time")
    print(
        f"omninav model (CLI, wall clock incl. start-up): {wall:.2f} s = {dur / wall:.1f}x real time, "
        f"{out['frames_added']} frames modelled, {out['frames_added'] / wall:.1f} frames/s; its modelling alone "
        f"{out['seconds']:.2f} s = {dur / out['seconds']:.1f}x"
    )
    with tempfile.TemporaryDirectory() as d:
        st, walk_path, lens = (
            Store(Path(d)),
            load_walk_path(a.root / "walk_path30.json"),
            load_lens(a.root / "lens.json"),
        )
        took = {}
        start_workers()  # as a job runner has them: each run below times its modelling, not their start
        for tag, over in (("unlevelled", {"level_iters": None}), ("default (levelled)", {})):
            t = time.perf_counter()
            model_video(st, tag.split()[0], video, walk_path, lens, settings=resolve("default", over))
            took[tag] = time.perf_counter() - t
        with one_core_busy():
            t = time.perf_counter()
            model_video(st, "busy", video, walk_path, lens, settings=resolve("default"))
            took["default, one core busy"] = time.perf_counter() - t
        extra = 1000 * (took["default (levelled)"] - took["unlevelled"]) / out["frames_added"]
        each = ", ".join(f"{k} {v:.2f} s = {dur / v:.1f}x real time" for k, v in took.items())
        print(f"in process ({extract_threads()} extraction processes): {each}; levelling adds {extra:.1f} ms a frame")
    if not a.no_api:
        api = through_api(a.root, video, omninav)
        print(
            f"upload API: {api['upload_s']:.2f} s to upload {video.stat().st_size / 1e6:.1f} MB in 8 MiB pieces; "
            f"job {api['job_s']:.2f} s = {dur / api['job_s']:.1f}x real time, {api['frames']} frames, "
            f"{api['frames'] / api['job_s']:.1f} frames/s"
        )
        print(f"API job / CLI frames per second: {(api['frames'] / api['job_s']) / (out['frames_added'] / wall):.2f}")


def through_api(root: Path, video: Path, omninav: str) -> dict:
    """Upload and model the video through a running server; time the job as the API reports it."""
    import urllib.request

    from omninav.devserver import ServeProcess
    from omninav.synth.scene import floorplan_image

    auth = {"Authorization": "Bearer bench"}

    with (
        tempfile.TemporaryDirectory() as d,
        ServeProcess(d, "--demo", "none", env={"OMNINAV_ADMIN_TOKEN": "bench"}, executable=omninav) as srv,
    ):

        def call(method: str, path: str, body=None, headers=None) -> dict:
            h = {**auth, **(headers or {})}
            if isinstance(body, dict):
                body, h["Content-Type"] = json.dumps(body).encode(), "application/json"
            req = urllib.request.Request(srv.base + path, body, h, method=method)
            with urllib.request.urlopen(req, timeout=120) as r:
                return json.loads(r.read())

        # a server up a few seconds, as one that an admin uploads to is: its workers have loaded
        # and its job runner has started its extraction processes (extract_pool.py)
        time.sleep(3.0)
        call("POST", "/api/admin/venues", {"id": "speed"})
        plan = cv2.imencode(".png", floorplan_image(build_scene(0, "default"), 20.0))[1].tobytes()
        call("PUT", "/api/admin/venues/speed/floors/1/plan", plan, {"Content-Type": "image/png"})
        call("PUT", "/api/admin/venues/speed/floors/1", {"px_per_m": 20.0})
        call("PUT", "/api/admin/venues/speed/lenses/default", json.loads((root / "lens.json").read_text()))
        data = video.read_bytes()
        walk_path = json.loads((root / "walk_path30.json").read_text())
        v = call(
            "POST", "/api/admin/venues/speed/videos", {"name": video.name, "size": len(data), "walk_path": walk_path}
        )
        t = time.perf_counter()
        piece = 8 << 20
        for a in range(0, len(data), piece):
            b = min(len(data), a + piece) - 1
            rng = {"Content-Range": f"bytes {a}-{b}/{len(data)}", "Content-Type": "application/octet-stream"}
            call("PUT", v["upload_url"], data[a : b + 1], rng)
        upload_s = time.perf_counter() - t
        job = call("POST", "/api/admin/venues/speed/jobs")
        while job["state"] in ("queued", "running"):
            time.sleep(0.2)
            job = call("GET", f"/api/admin/jobs/{job['id']}")
        if job["state"] != "done":
            raise SystemExit(f"job {job['state']}: {job['error']}")
        return {"upload_s": upload_s, "job_s": job["finished"] - job["started"], "frames": job["frames_done"]}


if __name__ == "__main__":
    main()
