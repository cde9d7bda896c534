"""Our lens fit (calib/ocam.py: Scaramuzza's model, OCamCalib's method, SciPy) against the closest
maintained alternative that runs here, on the same board corners: OpenCV-contrib's `cv2.omnidir`
(Mei's unified model, `omnidir.calibrate`).

Not compared: mrcal (on PyPI only as cp312 wheels, and this venv is CPython 3.11; it also has no
model for a donut ring: its lens models are pinhole-family and splined projections around one
forward axis, not a ring seeing 360 degrees round it). OCamCalib itself is MATLAB.

opencv-contrib cannot share a venv with the project's opencv (both own the `cv2` package), so it
runs in a throwaway venv of its own, fed the corners through an .npz:

    python3.11 -m venv /tmp/contrib-venv
    /tmp/contrib-venv/bin/pip install opencv-contrib-python-headless numpy scipy
    .venv/bin/python -m bench.calib_compare                 # boards rendered and detected (board.py)
    .venv/bin/python -m bench.calib_compare --corners       # corners projected, 0.3 px noise, 40 views

Both fits see the same views and hold out the same ones (every 4th). Printed per lens geometry:
the largest and median elevation error over the true ring (deg), the centre error (px), the held-out
reprojection RMS (px) and the time, with the machine.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import platform
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from types import SimpleNamespace
from typing import Any

import numpy as np

from omninav.calib import ocam as oc
from omninav.calib.board import detect_board, parse_board
from omninav.lens import Catadioptric
from omninav.synth.calibration import LENS_GEOMETRIES, board_video

CONTRIB = Path(os.environ.get("CONTRIB_PYTHON", "/tmp/contrib-venv/bin/python"))

# Runs in the contrib venv: Mei's model by cv2.omnidir.calibrate on the fitted views; held-out
# views posed with the model fixed (lifted to rays, a local perspective solvePnP, then least squares
# on omnidir.projectPoints); the elevation of the ray each evaluation pixel sees.
OMNIDIR = r"""
import json, sys, time, numpy as np, cv2
from scipy.optimize import least_squares
d = np.load(sys.argv[1])
views = [(d[f"obj{i}"], d[f"img{i}"]) for i in range(int(d["n"]))]
held = d["held"].astype(bool)
size = tuple(int(x) for x in d["size"])
fit = [v for v, h in zip(views, held) if not h]
t0 = time.perf_counter()
obj = [o.reshape(1, -1, 3).astype(np.float64) for o, _ in fit]
img = [p.reshape(1, -1, 2).astype(np.float64) for _, p in fit]
crit = (cv2.TERM_CRITERIA_COUNT + cv2.TERM_CRITERIA_EPS, 300, 1e-10)
try:
    flags = cv2.omnidir.CALIB_FIX_SKEW
    rms, K, xi, D, rv, tv, idx = cv2.omnidir.calibrate(obj, img, size, None, None, None, flags, crit)
except cv2.error as e:
    print(json.dumps({"error": str(e).splitlines()[-1][:200], "seconds": time.perf_counter() - t0}))
    sys.exit(0)
secs = time.perf_counter() - t0
xi = float(np.ravel(xi)[0]); D = np.ravel(D)

def lift(px):
    m = cv2.undistortPoints(px.reshape(-1, 1, 2).astype(np.float64), K, D).reshape(-1, 2)
    r2 = np.sum(m * m, 1)
    lam = (xi + np.sqrt(1 + (1 - xi * xi) * r2)) / (r2 + 1)
    return np.column_stack([lam[:, None] * m, lam - xi])

def project(o, rvec, tvec):
    p, _ = cv2.omnidir.projectPoints(o.reshape(1, -1, 3), rvec, tvec, K, xi, D)
    return p.reshape(-1, 2)

def pose(o, p):
    ray = lift(p)
    z = ray.mean(0); z /= np.linalg.norm(z)
    x = np.cross([0.0, 1.0, 0.0] if abs(z[1]) < 0.9 else [1.0, 0.0, 0.0], z); x /= np.linalg.norm(x)
    R = np.stack([x, np.cross(z, x), z])
    q = ray @ R.T
    ok, rvec, tvec = cv2.solvePnP(o.astype(np.float64), (q[:, :2] / q[:, 2:]).astype(np.float64), np.eye(3), None)
    Rb = R.T @ cv2.Rodrigues(rvec)[0]
    x0 = np.concatenate([cv2.Rodrigues(Rb)[0].ravel(), R.T @ tvec.ravel()])
    sol = least_squares(lambda x: (project(o, x[:3], x[3:]) - p).ravel(), x0)
    return sol.x

per = []
for (o, p), h in zip(views, held):
    if not h:
        continue
    x = pose(o, p)
    r = project(o, x[:3], x[3:]) - p
    per.append(float(np.sqrt(np.mean(np.sum(r * r, 1)))))
allres = []
for (o, p), h in zip(views, held):
    if h:
        x = pose(o, p); allres.append(project(o, x[:3], x[3:]) - p)
held_rms = float(np.sqrt(np.mean(np.sum(np.concatenate(allres) ** 2, 1)))) if allres else None
ray = lift(d["eval_px"])
print(json.dumps({"rms": float(rms), "K": K.tolist(), "xi": xi, "D": D.tolist(), "used": int(np.size(idx)),
                  "held_rms": held_rms, "seconds": secs, "ray_z": ray[:, 2].tolist(),
                  "ray_n": np.hypot(ray[:, 0], ray[:, 1]).tolist()}))
"""


def eval_pixels(lens: Catadioptric) -> tuple[np.ndarray, np.ndarray]:
    """(n, 2) pixels over the true ring and their true elevations (deg)."""
    r = np.linspace(lens.r_inner, lens.r_outer, 60)
    phi = np.linspace(0, 2 * np.pi, 48, endpoint=False)
    rr, pp = np.meshgrid(r, phi)
    px = np.stack([lens.center[0] + rr * np.cos(pp), lens.center[1] + rr * np.sin(pp)], -1).reshape(-1, 2)
    return px, lens.elevation(rr.ravel())


def views_for(name: str, corners: bool, seed: int) -> tuple[list[Any], Any, float]:
    """The views, the ring, and the azimuth (deg) the board was held at straight ahead."""
    lens = LENS_GEOMETRIES[name]
    spec = parse_board("chess:9x6:0.03")
    if corners:
        ring = SimpleNamespace(center=lens.center, r_inner=lens.r_inner, r_outer=lens.r_outer)
        return oc.synthetic_views(lens, spec.object_points(), 40, 0.3, seed), ring, 0.0
    from omninav.calib.ring import find_ring

    cs = board_video(lens, spec, n_frames=24, seed=seed)
    ring = find_ring(cs.frames)
    dets = [d for i, f in enumerate(cs.frames) if (d := detect_board(f, spec, ring, i)) is not None]
    held = float(np.mean([(d[0] + 180) % 360 - 180 for d in cs.board_dirs[:3]]))  # the renderer's +-2 deg
    return dets, ring, held


def ours(lens: Catadioptric, views: list[Any], ring: Any, held_az: float) -> dict[str, Any]:
    t0 = time.perf_counter()
    fit = oc.fit_ocam(views, lens.image_size, ring)
    o = oc.orientation(views, fit.ocam)
    prof, _ = oc.to_profile(fit.ocam, ring, o.forward_deg, o.ccw, support=fit.support)
    secs = time.perf_counter() - t0
    px, truth = eval_pixels(lens)
    err = np.abs(prof.elevation(np.hypot(px[:, 0] - prof.center[0], px[:, 1] - prof.center[1])) - truth)
    want = lens.forward_deg + (-held_az if lens.ccw else held_az)  # where the board was held
    fwd = (prof.forward_deg - want + 180) % 360 - 180
    return {
        "el_max": float(err.max()),
        "el_med": float(np.median(err)),
        "centre": math.dist(prof.center, lens.center),
        "held": fit.rms_held,
        "seconds": secs,
        "extra": f"deg {fit.degree}, fwd {fwd:+.2f}, ccw {'ok' if prof.ccw == lens.ccw else 'WRONG'}",
    }


def omnidir(lens: Catadioptric, views: list[Any]) -> dict[str, Any]:
    held = [i % 4 == 3 for i in range(len(views))]
    px, truth = eval_pixels(lens)
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "views.npz"
        arrays: dict[str, Any] = {f"obj{i}": np.asarray(v.object_points) for i, v in enumerate(views)}
        arrays |= {f"img{i}": np.asarray(v.image_points) for i, v in enumerate(views)}
        np.savez(path, n=len(views), held=np.array(held), size=np.array(lens.image_size), eval_px=px, **arrays)
        p = subprocess.run([str(CONTRIB), "-c", OMNIDIR, str(path)], capture_output=True, text=True, timeout=600)
    if p.returncode != 0:
        return {"error": (p.stderr.strip().splitlines() or ["failed"])[-1][:160]}
    out = json.loads(p.stdout)
    if "error" in out:
        return out
    z, n = np.array(out["ray_z"]), np.array(out["ray_n"])
    # Mei's axis points into the mirror or away: take the sign that makes the outer edge look up, as ours
    el = np.degrees(np.arctan2(z, n))
    r = np.hypot(px[:, 0] - lens.center[0], px[:, 1] - lens.center[1])
    if np.corrcoef(el, r)[0, 1] < 0:
        el = -el
    err = np.abs(el - truth)
    K = np.array(out["K"])
    return {
        "el_max": float(np.nanmax(err)),
        "el_med": float(np.nanmedian(err)),
        "centre": math.dist((K[0, 2], K[1, 2]), lens.center),
        "held": out["held_rms"],
        "seconds": out["seconds"],
        "extra": f"xi {out['xi']:.3f}, fit RMS {out['rms']:.3f} px, {out['used']} views used",
    }


def row(name: str, who: str, r: dict[str, Any]) -> str:
    if "error" in r:
        return f"{name:10s} {who:8s} failed: {r['error']}"
    held = f"{r['held']:.3f}" if r["held"] is not None else "-"
    return (
        f"{name:10s} {who:8s} {r['el_max']:8.3f} {r['el_med']:8.3f} {r['centre']:8.2f} {held:>8s} "
        f"{r['seconds']:7.1f}  {r['extra']}"
    )


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--corners", action="store_true", help="projected corners (0.3 px noise) instead of renders")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--geometries", default=",".join(LENS_GEOMETRIES))
    a = ap.parse_args()
    print(f"machine: {platform.platform()}, {platform.processor() or platform.machine()}, {os.cpu_count()} CPUs")
    print(f"data: {'projected corners, 0.3 px noise, 40 views' if a.corners else 'rendered board videos, 24 frames'}")
    print(f"{'geometry':10s} {'fit':8s} {'el max':>8s} {'el med':>8s} {'centre':>8s} {'held':>8s} {'time s':>7s}")
    have = CONTRIB.exists()
    for name in a.geometries.split(","):
        lens = LENS_GEOMETRIES[name]
        views, ring, held_az = views_for(name, a.corners, a.seed)
        print(row(name, "ours", ours(lens, views, ring, held_az)))
        print(row(name, "omnidir", omnidir(lens, views) if have else {"error": f"no {CONTRIB} (see docstring)"}))
        sys.stdout.flush()


if __name__ == "__main__":
    main()
