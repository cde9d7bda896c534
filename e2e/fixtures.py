"""Test data for the web app, made by the Python engine at test time (nothing binary is committed).

    python e2e/fixtures.py golden OUT   # frames + the engine's panoramas, curves and records
    python e2e/fixtures.py clip OUT [SCENE]  # a Y4M clip for Chromium's fake camera, at a known pose
                                             # (SCENE: another venue's seed; the demo's is 0)

Golden files: a few frames of the synthetic venue through the engine's stages, so that the
TypeScript extractor (in Node and in Chromium) can be checked against them stage by stage.
"""

from __future__ import annotations

import json
import sys
from dataclasses import replace
from pathlib import Path

import cv2
import numpy as np

from omninav.extract import Extractor
from omninav.presets import FEATURE_KEYS, resolve, settings_id
from omninav.spectrum import encode_binary
from omninav.synth import QUERY, donut_lens, equirect_lens
from omninav.synth.scene import build_scene
from omninav.synth.walks import Perturb, Pose, render_frames
from omninav.unwarp import unwarp

# poses in the small synthetic layout (scene.py): corridor points, headings all round
POSES = [Pose(0.0, 6.0, 2.0, 30.0), Pose(0.1, 14.5, 2.2, 200.0), Pose(0.2, 20.0, 8.0, 300.0)]


def _case(out: Path, name: str, lens, preset: str, frames: list[np.ndarray]) -> dict:
    conf = resolve(preset)
    ext = Extractor(lens, conf)
    items = []
    specs = []
    for i, bgr in enumerate(frames):
        stem = f"{name}-{i}"
        cv2.imwrite(str(out / f"{stem}.png"), bgr)
        rgb = cv2.cvtColor(bgr, cv2.COLOR_BGR2RGB)
        rgba = np.dstack([rgb, np.full(rgb.shape[:2], 255, np.uint8)])
        (out / f"{stem}.rgba").write_bytes(rgba.tobytes())
        pano = cv2.cvtColor(unwarp(bgr, ext.map), cv2.COLOR_BGR2RGB)
        (out / f"{stem}.pano").write_bytes(pano.tobytes())
        (out / f"{stem}.curves").write_bytes(ext.curves(bgr).astype("<f4").tobytes())
        spec = ext.spectrum(bgr)
        specs.append(spec)
        (out / f"{stem}.rec").write_bytes(encode_binary(spec, conf))
        items.append({"stem": stem})
    (out / f"{name}.rec").write_bytes(encode_binary(np.stack(specs), conf))
    return {
        "name": name,
        "lens": lens.to_dict(),
        "settings": {k: conf[k] for k in FEATURE_KEYS},
        "settings_id": settings_id(conf),
        "pano_shape": [int(ext.map.map_x.shape[0]), int(ext.map.map_x.shape[1]), 3],
        "frames": items,
    }


def golden(out: Path) -> None:
    out.mkdir(parents=True, exist_ok=True)
    scene = build_scene(0, "small")
    donut = donut_lens(1.0)
    look = replace(QUERY, people=0, lateral_m=0.0)  # a colour cast, gain, tilt and noise, as a phone sees
    dframes = [f for _, f in render_frames(scene, donut, POSES, look, seed=7)]
    eq = equirect_lens(1440)
    eframes = [f for _, f in render_frames(scene, eq, POSES[:1], look, seed=8)]
    cases = [
        _case(out, "donut-default", donut, "default", dframes),
        _case(out, "donut-six", donut, "six", dframes[:1]),
        _case(out, "equirect-default", eq, "default", eframes),
    ]
    (out / "golden.json").write_text(json.dumps({"cases": cases}, indent=1))


def write_y4m(path: Path, frames: list[np.ndarray], fps: int) -> None:
    """BGR frames -> a YUV 4:2:0 Y4M file, the format Chromium's fake camera plays."""
    h, w = frames[0].shape[:2]
    with path.open("wb") as f:
        f.write(f"YUV4MPEG2 W{w} H{h} F{fps}:1 Ip A1:1 C420jpeg\n".encode())
        for bgr in frames:
            f.write(b"FRAME\n")
            f.write(cv2.cvtColor(bgr, cv2.COLOR_BGR2YUV_I420).tobytes())


def clip(out: Path, scene_seed: int = 0, scale: float = 0.5, frames: int = 20, fps: int = 10) -> None:
    """A user standing still in the quick demo venue (small layout), the phone turned away from the
    corridor: `frames` frames with sensor noise, a cast and a lens shift, and the truth. Another
    `scene_seed` films another building instead, one the demo venue has never seen."""
    out.mkdir(parents=True, exist_ok=True)
    scene = build_scene(scene_seed, "small")
    lens = donut_lens(scale)
    truth = {"x": 14.0, "y": 2.3, "heading_deg": 250.0}
    poses = [Pose(i / fps, truth["x"], truth["y"], truth["heading_deg"]) for i in range(frames)]
    look = Perturb(height_m=(1.3, 1.3), light=(0.9, 0.9), cast=0.05, lens_shift_px=1.0, noise=2.0)
    bgr = [f for _, f in render_frames(scene, lens, poses, look, seed=11)]
    write_y4m(out / "clip.y4m", bgr, fps)
    (out / "clip.json").write_text(json.dumps({**truth, "fps": fps, "frames": frames, "size": list(lens.image_size)}))


if __name__ == "__main__":
    if len(sys.argv) not in (3, 4) or sys.argv[1] not in ("golden", "clip"):
        sys.exit(__doc__)
    if sys.argv[1] == "golden":
        golden(Path(sys.argv[2]))
    else:
        clip(Path(sys.argv[2]), int(sys.argv[3]) if len(sys.argv) == 4 else 0)
