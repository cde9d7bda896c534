"""Modelling speed: `omninav model` on a 30 fps 960x720 video, as a multiple of real time.

Renders (once, cached) 40 s of a modelling walk through the default synthetic venue at 30 fps,
then runs the real CLI on it (decoding every frame, extracting features at the preset's 10 fps)
and, in the same run, a decode-only pass as the floor any modelling run sits on.

    python bench/model_speed.py [--seconds 40]
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

from omninav.synth import MODELLING, build_scene, donut_lens
from omninav.synth.walks import (
    default_routes,
    poses_from_track,
    render_frames,
    track_for,
    write_json,
    write_video,
)

sys.path.insert(0, str(Path(__file__).parent))
from search_speed import machine  # noqa: E402


def render(root: Path, seconds: float) -> None:
    if (root / "model30.mp4").exists():
        return
    root.mkdir(parents=True, exist_ok=True)
    scene = build_scene(0)
    route, _ = default_routes(scene)
    track = track_for(route, [1.2], 30.0)
    track["waypoints"] = [w for w in track["waypoints"] if w["t"] <= seconds + 25]
    poses = poses_from_track(track, MODELLING, np.random.default_rng(0))[: int(seconds * 30)]
    lens = donut_lens()
    write_json(root / "track30.json", track)
    write_json(root / "lens.json", lens.to_dict())
    frames = (f for _, f in render_frames(scene, lens, poses, MODELLING, 1))
    write_video(root / "model30.mp4", frames, 30.0, lens.image_size)


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--seconds", type=float, default=40.0)
    ap.add_argument("--root", type=Path, default=Path("data") / "bench-model-speed")
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
                "--track",
                str(a.root / "track30.json"),
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
        f"{out['frames_added']} frames modelled"
    )


if __name__ == "__main__":
    main()
