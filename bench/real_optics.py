"""Real optics: what a real donut photo shows that the renderer does not, and whether the curves
behave on real pictures as on synthetic ones.

The real imagery (fetched with pip into --cache, nothing committed):
- the donut photo of the MIT-licensed PyPI package pyomniunwarp 0.2.5 (data/example.jpg, 1920x1080,
  a convex mirror seen from below by a phone, an office and a chessboard around it) and the
  OCamCalib model shipped beside it (the lens profile, as tests/calib/test_calib_real.py converts it);
- the real city panorama in the MIT-licensed PyPI package FisheyeWarping 1.0.1's sdist
  (doc/101-panorama.jpg, 1000x307), re-projected through the synthetic donut lens: real textures,
  noise and compression, a real place, seen through an ideal lens.
Searched and not usable: FisheyeWarping's other images (a drawn mesh; a "little planet" made from
the same panorama), pyfisheye, fish2pano (no images); npm: pannellum (a screenshot of its viewer),
marzipano (a 293x207 flat demo photo), photo-sphere-viewer, panolens (no images).

The photo is held out: nothing in the engine is tuned on it; fitting `optics.REAL` to it is
measuring. Printed: (1) the photo's statistics next to a synthetic frame's, clean and through
`OpticsSim(REAL)`; (2) the vignetting on the photo's white board cells against REAL's; (3) the
phase-correlation score (what the index verifies with) between a frame and the same frame at
another exposure (gain, tone curve, white balance, highlight clipping, noise, JPEG), real against
synthetic, per preset.

    python -m bench.real_optics [--cache data/cache/real-optics] [--frames 12]
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import tarfile
import zipfile
from pathlib import Path
from types import SimpleNamespace
from typing import Any

import cv2
import numpy as np

from bench.common import machine
from omninav.calib import ocam as oc
from omninav.calib import ocam_file as ocf
from omninav.extract import Extractor
from omninav.heading import relative_heading, wrap_deg
from omninav.lens import Catadioptric
from omninav.presets import resolve
from omninav.synth import build_scene, donut_lens
from omninav.synth.optics import (
    REAL,
    OpticsSim,
    edge_sigma,
    noise_sigma,
    radial_shift,
    reexpose,
    rim_gain,
    rim_profile,
    ring_of,
)
from omninav.synth.render import CameraModel, PanoGrid, camera_frame, world_panorama
from omninav.synth.walks import default_routes, grid_for

PHOTO = "pyomniunwarp==0.2.5"
PANO = "FisheyeWarping==1.0.1"

# The second exposures: what another shot of the same place could look like from a phone.
EXPOSURES: list[tuple[str, dict[str, Any]]] = [
    ("darker 1 EV", {"gain": 0.5, "noise": 2.0, "jpeg": 90}),
    ("brighter 1 EV, highlights clip", {"gain": 2.0, "noise": 1.0, "jpeg": 90}),
    ("tone curve (gamma x1.25)", {"tone": 1.25, "jpeg": 90}),
    ("white balance (R x1.15, B x0.85)", {"wb": (1.15, 1.0, 0.85), "jpeg": 90}),
    ("noise 4 + JPEG q40", {"noise": 4.0, "jpeg": 40}),
    (
        "all: -0.7 EV, gamma x0.8, WB, noise 3, q60",
        {"gain": 0.6, "tone": 0.8, "wb": (0.9, 1.0, 1.12), "noise": 3.0, "jpeg": 60},
    ),
]


def fetch(spec: str, cache: Path, sdist: bool = False) -> Path:
    """The wheel (or sdist) of `spec`, downloaded once into `cache` with pip."""
    name, ver = spec.split("==")
    pat = f"{name}-{ver}{'.tar.gz' if sdist else '-*.whl'}"
    have = sorted(cache.glob(pat)) or sorted(cache.glob(pat.lower()))
    if not have:
        cache.mkdir(parents=True, exist_ok=True)
        cmd = [sys.executable, "-m", "pip", "download", "--no-deps", "--disable-pip-version-check", "-q"]
        cmd += ["--no-binary", ":all:"] if sdist else []
        subprocess.run([*cmd, spec, "-d", str(cache)], check=True, timeout=300)
        have = sorted(cache.glob(pat)) or sorted(cache.glob(pat.lower()))
    return have[0]


def _decode(data: bytes) -> np.ndarray:
    img = cv2.imdecode(np.frombuffer(data, np.uint8), cv2.IMREAD_COLOR)
    if img is None:
        raise OSError("not a readable JPEG")
    out: np.ndarray = img
    return out


def real_photo(cache: Path) -> tuple[np.ndarray, Catadioptric, np.ndarray, float]:
    """(RGB photo, its lens profile, the chessboard's inner corners (6, 9, 2), its JPEG quality)."""
    from omninav.calib.board import detect_board, parse_board

    with zipfile.ZipFile(fetch(PHOTO, cache)) as z:
        data = z.read("pyomniunwarp/data/example.jpg")
        img = _decode(data)
        (cache / "calib_results.txt").write_bytes(z.read("pyomniunwarp/data/calib_results.txt"))
    cal = ocf.read_ocamcalib_file(cache / "calib_results.txt")
    assert cal.roi is not None and cal.crop_lr is not None
    model = ocf.read_ocamcalib(cache / "calib_results.txt", offset=(cal.crop_lr[0], 0), image_size=(1920, 1080))
    ring = SimpleNamespace(center=model.center, r_inner=cal.roi[1], r_outer=cal.roi[0])
    prof, _ = oc.to_profile(model, ring, 0, True)
    det = detect_board(img, parse_board("chess:9x6:0.03"), ring)
    assert det is not None and det.whole
    return cv2.cvtColor(img, cv2.COLOR_BGR2RGB), prof, det.image_points.reshape(6, 9, 2), jpeg_quality(data)


def real_panorama(cache: Path) -> np.ndarray:
    """FisheyeWarping's city panorama (RGB)."""
    with tarfile.open(fetch(PANO, cache, sdist=True)) as t:
        member = next(m for m in t.getmembers() if m.name.endswith("doc/101-panorama.jpg"))
        f = t.extractfile(member)
        assert f is not None
        return cv2.cvtColor(_decode(f.read()), cv2.COLOR_BGR2RGB)


def pano_through_donut(pano: np.ndarray, lens: Catadioptric, heading: float = 0.0) -> np.ndarray:
    """A panorama photographed through the donut lens: columns taken as 360 degrees of azimuth
    and rows as equal steps of elevation, the horizon at the skyline (70 % down)."""
    h, w = pano.shape[:2]
    step = 360.0 / w
    top = 0.70 * h * step
    grid = PanoGrid(w, top, top - (h - 1) * step, h)
    out: np.ndarray = camera_frame(CameraModel.create(lens), pano, grid, heading)
    return out


def synthetic_frames(n: int, seed: int = 0) -> tuple[Catadioptric, list[np.ndarray]]:
    """n clean frames (RGB, no noise) of the default venue along its query route."""
    lens = donut_lens()
    scene = build_scene(seed)
    _, route = default_routes(scene)
    grid = grid_for(lens)
    cam = CameraModel.create(lens)
    rng = np.random.default_rng(seed)
    pts = np.asarray(route, float)
    seg = np.hypot(*np.diff(pts, axis=0).T)
    at = np.linspace(0, seg.sum(), n, endpoint=False) + 2.0
    frames = []
    for s in at:
        i = min(int(np.searchsorted(np.cumsum(seg), s)), len(seg) - 1)
        f = (s - np.concatenate([[0], np.cumsum(seg)])[i]) / seg[i]
        x, y = pts[i] + f * (pts[i + 1] - pts[i])
        pano = world_panorama(scene, float(x), float(y), 1.35, grid)
        frames.append(camera_frame(cam, pano, grid, float(rng.uniform(0, 360))))
    return lens, frames


def through(lens: Catadioptric, rgb: np.ndarray, seed: int = 0) -> np.ndarray:
    out = OpticsSim(lens, REAL, np.random.default_rng(seed))(rgb.astype(np.float32))
    res: np.ndarray = np.round(out).astype(np.uint8)
    return res


# ---- statistics -------------------------------------------------------------------------------
def phone_reach(rgb: np.ndarray, ring: tuple[float, float, float, float]) -> tuple[float, float]:
    """How far (u) the phone's tan reflection reaches into the ring, at its sides and corners.

    Along each ray (1 degree apart) the reach is where a run of tan pixels that starts near the
    inner edge (u < 0.06: the dark camera lens may show first) ends, 0 when none starts; sides: the
    median over rays within 10 degrees of the frame's axes, corners: the median of the four
    diagonals' furthest rays within 10 degrees."""
    cx, cy, r_in, r_out = ring
    hsv = cv2.cvtColor(rgb, cv2.COLOR_RGB2HSV).astype(np.float32)
    uu = np.linspace(0.0, 0.4, 161, dtype=np.float32)
    phi = np.radians(np.arange(360, dtype=np.float32))
    rr = r_in + uu[:, None] * (r_out - r_in)
    mx = (cx + rr * np.cos(phi)[None, :]).astype(np.float32)
    my = (cy + rr * np.sin(phi)[None, :]).astype(np.float32)
    s = cv2.remap(hsv, mx, my, cv2.INTER_NEAREST)
    tan = (s[..., 0] >= 8) & (s[..., 0] <= 22) & (s[..., 1] > 50) & (s[..., 2] > 90)
    reach = np.zeros(360)
    for j in range(360):
        start = np.flatnonzero(tan[: int(np.searchsorted(uu, 0.06)), j])
        if start.size:
            run = tan[start[0] :, j]
            end = start[0] + (int(np.argmin(run)) if not run.all() else len(run))
            reach[j] = uu[end - 1]

    def near(a: float) -> np.ndarray:
        d = (np.arange(360) - a + 180) % 360 - 180
        out: np.ndarray = reach[np.abs(d) <= 10]
        return out

    sides = float(np.median(np.concatenate([near(a) for a in (0, 90, 180, 270)])))
    corners = float(np.median([near(a).max() for a in (45, 135, 225, 315)]))
    return sides, corners


def jpeg_quality(data: bytes) -> float:
    """The IJG quality a JPEG's luminance table was made with (the standard table scaled)."""
    std = np.array([16, 11, 10, 16, 24, 40, 51, 61, 12, 12, 14, 19, 26, 58, 60, 55, 14, 13, 16, 24, 40, 57, 69, 56,
                    14, 17, 22, 29, 51, 87, 80, 62, 18, 22, 37, 56, 68, 109, 103, 77, 24, 35, 55, 64, 81, 104, 113,
                    92, 49, 64, 78, 87, 103, 121, 120, 101, 72, 92, 95, 98, 112, 100, 103, 99])  # fmt: skip
    i = 2
    while i + 4 <= len(data) and data[i] == 0xFF:
        marker, n = data[i + 1], int.from_bytes(data[i + 2 : i + 4], "big")
        if marker == 0xDB and data[i + 4] & 0x0F == 0 and data[i + 4] >> 4 == 0:
            table = np.frombuffer(data[i + 5 : i + 69], np.uint8).astype(float)
            scale = 100.0 * table.sum() / std.sum()
            return float((200.0 - scale) / 2.0 if scale <= 100 else 5000.0 / scale)
        i += 2 + n
    return float("nan")


def stats(rgb: np.ndarray, lens: Catadioptric) -> dict[str, float | tuple[float, ...]]:
    ring = ring_of(lens)
    cx, cy, r_in, r_out = ring
    h, w = rgb.shape[:2]
    ys, xs = np.mgrid[0:h, 0:w]
    r = np.hypot(xs - cx, ys - cy)
    inner = (r >= r_in) & (r <= r_out)
    px = rgb[inner].astype(np.float32)
    grey = px.mean(-1)
    hsv = cv2.cvtColor(rgb, cv2.COLOR_RGB2HSV)[inner]
    mean = px.mean(0)
    rim = rim_profile(rgb, ring)
    sig = edge_sigma(rgb, ring, 3)
    mids = r_in + (np.arange(3) + 0.5) / 3 * (r_out - r_in)
    shift = radial_shift(rgb, ring, 3)
    side, corner = phone_reach(rgb, ring)
    return {
        "ring mean grey": float(grey.mean()),
        "R/G, B/G (grey world)": (float(mean[0] / mean[1]), float(mean[2] / mean[1])),
        "grey p1 / p50 / p99": tuple(float(x) for x in np.percentile(grey, [1, 50, 99])),
        "share clipped (>= 250)": float((px.max(-1) >= 250).mean()),
        "mean saturation": float(hsv[:, 1].mean() / 255),
        "rim: 10-90 % width (rings)": rim["width"],
        "rim: level at r_outer": rim["level"],
        "rim: B/G excess at r_outer": rim["blue"],
        "phone reach u (sides, corners)": (side, corner),
        "edge blur sigma px (in, mid, out)": tuple(float(x) for x in sig),
        "edge blur sigma, deg of azimuth": tuple(float(x) for x in np.degrees(sig / mids)),
        "lateral chroma R, B px (outer third)": tuple(float(x) for x in shift[-1]),
        "noise sigma (grey levels)": noise_sigma(rgb, inner),
    }


def fmt(v: float | tuple[float, ...]) -> str:
    if isinstance(v, tuple):
        return " / ".join(fmt(x) for x in v)
    if isinstance(v, float | np.floating):
        return f"{v:.3f}" if abs(v) < 10 else f"{v:.1f}"
    return str(v)


def board_vignetting(rgb: np.ndarray, lens: Catadioptric, corners: np.ndarray) -> list[tuple[float, float]]:
    """(u, level / mean level) of the chessboard's white cells: a flat, evenly lit white target
    spanning part of the ring."""
    cx, cy, r_in, r_out = ring_of(lens)
    grey = rgb.astype(np.float32).mean(-1)
    cells = []
    for i in range(corners.shape[0] - 1):
        for j in range(corners.shape[1] - 1):
            q = np.array([corners[i, j], corners[i, j + 1], corners[i + 1, j + 1], corners[i + 1, j]])
            c = q.mean(0)
            mask = np.zeros(grey.shape, np.uint8)
            cv2.fillConvexPoly(mask, np.round(c + 0.5 * (q - c)).astype(np.int32), 1)
            cells.append(((np.hypot(c[0] - cx, c[1] - cy) - r_in) / (r_out - r_in), float(grey[mask > 0].mean())))
    arr = np.array(cells)
    white = arr[arr[:, 1] > arr[:, 1].mean()]
    white = white[np.argsort(white[:, 0])]
    return [(float(u), float(v / white[:, 1].mean())) for u, v in white]


def desaturate(rgb: np.ndarray, k: float) -> np.ndarray:
    """The frame's colours k times as far from grey (per pixel, about its channels' mean)."""
    f = rgb.astype(np.float32)
    g = f.mean(axis=-1, keepdims=True)
    out: np.ndarray = np.clip(np.round(g + k * (f - g)), 0, 255).astype(np.uint8)
    return out


# ---- exposure pairs -----------------------------------------------------------------------------
def score(ext: Extractor, a: np.ndarray, b: np.ndarray) -> tuple[float, float]:
    """(verification score, heading deg in (-180, 180]) of frame b against frame a (RGB uint8), as
    the index verifies a candidate: the phase correlation's peak over all rotations."""
    fa = ext.spectrum(a[..., ::-1].copy())
    fb = ext.spectrum(b[..., ::-1].copy())
    rel, val = relative_heading(fb, fa, n_shifts=max(64, 8 * fa.shape[-1]))
    return float(val), float(wrap_deg(rel))


Groups = dict[str, tuple[Catadioptric, list[np.ndarray]]]


def pair_rows(groups: Groups, preset: str) -> list[tuple[str, list[np.ndarray]]]:
    """Per second exposure, per group: (score, |heading error|) of every frame against itself so."""
    conf = resolve(preset)
    exts = {g: Extractor(lens, conf) for g, (lens, _) in groups.items()}
    rows = []
    for label, kw in EXPOSURES:
        cells = []
        for g, (_, frames) in groups.items():
            rng = np.random.default_rng(7)
            res = np.array([score(exts[g], f, reexpose(f, rng=rng, **kw)) for f in frames])
            cells.append(np.column_stack([res[:, 0], np.abs(res[:, 1])]))
        rows.append((label, cells))
    return rows


def other_place(groups: Groups, preset: str) -> list[str]:
    """The score between neighbouring frames of the synthetic route (other places, 10+ m apart):
    what an unrelated frame scores, the scale the scores above are read against."""
    cells = []
    for name, (lens, frames) in groups.items():
        if not name.startswith("synthetic"):
            cells.append("-")
            continue
        ext = Extractor(lens, resolve(preset))
        sc = [score(ext, frames[i], frames[(i + 1) % len(frames)])[0] for i in range(len(frames))]
        cells.append(f"{np.mean(sc):.3f} (max {np.max(sc):.3f})")
    return cells


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--cache", type=Path, default=Path("data/cache/real-optics"))
    ap.add_argument("--frames", type=int, default=12)
    a = ap.parse_args()
    print(f"# real optics -- {machine()}")
    photo, plens, corners, quality = real_photo(a.cache)
    slens, synth = synthetic_frames(a.frames)
    opt = [through(slens, f, i) for i, f in enumerate(synth)]
    lo, hi = plens.elevation_range()
    print(
        f"\nreal photo: {PHOTO} data/example.jpg, {photo.shape[1]}x{photo.shape[0]}, JPEG quality ~{quality:.0f}, "
        f"ring {plens.r_inner:.0f}-{plens.r_outer:.0f} px ({lo:.0f}..{hi:.0f} deg)"
    )
    lo, hi = slens.elevation_range()
    print(
        f"synthetic: default venue, {len(synth)} clean frames along the query route, {slens.image_size[0]}x"
        f"{slens.image_size[1]}, ring {slens.r_inner:.0f}-{slens.r_outer:.0f} px ({lo:.0f}..{hi:.0f} deg)"
    )

    print("\n## The real photo next to synthetic frames, clean and through OpticsSim(REAL)\n")
    cols = {
        "real photo": [stats(photo, plens)],
        "synthetic, clean": [stats(f, slens) for f in synth[:4]],
        "synthetic + OpticsSim(REAL)": [stats(f, slens) for f in opt[:4]],
    }
    print("| statistic | " + " | ".join(cols) + " |")
    print("|" + " --- |" * (1 + len(cols)))
    for key in cols["real photo"][0]:
        vals = []
        for rows in cols.values():
            xs = [r[key] for r in rows]
            v = tuple(np.mean(np.array(xs, float), axis=0)) if isinstance(xs[0], tuple) else float(np.mean(xs))
            vals.append(fmt(v))
        print(f"| {key} | " + " | ".join(vals) + " |")
    print("\n(synthetic columns: means over 4 frames; u is the position across the ring, 0 inner, 1 outer)")

    print("\n## Vignetting: the photo's white board cells against REAL on a flat field\n")
    cells = board_vignetting(photo, plens, corners)
    us = np.array([u for u, _ in cells], np.float32)
    model = rim_gain(us, REAL)[:, 1]
    model = model / model.mean()
    print("| u | " + " | ".join(f"{u:.2f}" for u in us) + " |")
    print("|" + " --- |" * (1 + len(us)))
    print("| board (level / mean) | " + " | ".join(f"{v:.3f}" for _, v in cells) + " |")
    print("| REAL | " + " | ".join(f"{v:.3f}" for v in model) + " |")
    rms = float(np.sqrt(np.mean((np.array([v for _, v in cells]) - model) ** 2)))
    print(f"\nRMS difference {rms:.3f}")

    # every frame stored as the phone stored the photo (JPEG at its quality): the panorama already is
    q = int(round(quality))
    groups: Groups = {"real photo": (plens, [photo])}
    pano_ok = True
    try:
        pano = real_panorama(a.cache)
        groups["real panorama via donut"] = (slens, [pano_through_donut(pano, slens, h) for h in (0.0, 120.0, 240.0)])
    except (subprocess.SubprocessError, OSError, StopIteration) as e:
        pano_ok = False
        print(f"\n(no {PANO}: {e})")
    groups[f"synthetic (JPEG q{q})"] = (slens, [reexpose(f, jpeg=q) for f in synth])
    groups[f"synthetic + REAL (JPEG q{q})"] = (slens, [reexpose(f, jpeg=q) for f in opt])
    # the office is greyer than the renderer's world: the same frames with their colour scaled down
    # to the photo's mean saturation tell the scene's part from the camera's
    sat = {name: np.mean([c["mean saturation"] for c in rows]) for name, rows in cols.items()}
    k = float(sat["real photo"] / sat["synthetic, clean"])
    groups[f"synthetic at the photo's saturation (x{k:.2f}, JPEG q{q})"] = (
        slens,
        [reexpose(desaturate(f, k), jpeg=q) for f in synth],
    )
    print("\n## The same place at two exposures: the verification score\n")
    print(
        "Phase correlation peak (a cosine; what the index verifies candidates with) of each frame's record "
        "against the record of the same frame re-exposed; mean over frames (min), and the worst heading "
        "error (should be 0).\n"
    )
    for preset in ("default", "paper"):
        print(f"\npreset `{preset}`\n")
        print("| second exposure | " + " | ".join(groups) + " |")
        print("|" + " --- |" * (1 + len(groups)))
        pairs = pair_rows(groups, preset)
        for label, cells_ in pairs:
            out = [f"{c[:, 0].mean():.3f} ({c[:, 0].min():.3f}) {c[:, 1].max():.2f} deg" for c in cells_]
            print(f"| {label} | " + " | ".join(out) + " |")
        means = [np.mean([r[1][k][:, 0].mean() for r in pairs]) for k in range(len(groups))]
        print("| mean over the changes | " + " | ".join(f"**{m:.3f}**" for m in means) + " |")
        print("| another place, same exposure | " + " | ".join(other_place(groups, preset)) + " |")
        if pano_ok:
            lens, frames = groups["real panorama via donut"]
            ext = Extractor(lens, resolve(preset))
            turned = [score(ext, frames[0], f) for f in frames[1:]]
            print(
                "\nthe real panorama turned by 120 and 240 deg: scores "
                + ", ".join(f"{v:.3f} (heading {h % 360:.2f} deg)" for v, h in turned)
            )


if __name__ == "__main__":
    main()
