"""The PNG `omninav calib lens --report` writes: is the fit to be trusted, at a glance.

Three panels and a bar chart: the ring (the median frame) with the fitted circles and the optical
centre, the detected corners with their residual vectors magnified; the elevation curve against the
radius with the ring's range; the reprojection RMS per image (fitted and held out).
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np


def magnification(residuals: np.ndarray, frame_px: float) -> float:
    """A round factor (1, 2, 5 x 10^k) that draws the 90th-percentile residual ~2 % of the frame."""
    big = float(np.percentile(np.hypot(residuals[:, 0], residuals[:, 1]), 90)) if len(residuals) else 0.0
    if big <= 0:
        return 1.0
    want = 0.02 * frame_px / big
    k = 10.0 ** np.floor(np.log10(want))
    return float(max(m * k for m in (1, 2, 5) if m * k <= want) if want >= 1 else 1.0)


def median_frame(frames: Sequence[np.ndarray], most: int = 15) -> np.ndarray:
    """(H, W) uint8: the median grey of up to `most` frames spread over the set (the board moves, the
    ring stays)."""
    import cv2

    pick = np.linspace(0, len(frames) - 1, min(most, len(frames))).round().astype(int)
    grey = [cv2.cvtColor(frames[i], cv2.COLOR_BGR2GRAY) if frames[i].ndim == 3 else frames[i] for i in pick]
    out: np.ndarray = np.median(np.stack(grey), axis=0).astype(np.uint8)
    return out


def write_report(path: Path, frames: Sequence[np.ndarray], cal: Any) -> float:
    """Draw `cal` (cli_lens.LensCalibration) to a PNG at `path`; returns the residual magnification."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.patches import Circle

    fit, ring, prof = cal.fit, cal.ring, cal.profile
    img = median_frame(frames)
    h, w = img.shape
    det = {d.frame: d for d in cal.detections}
    res_all = np.concatenate([v.residuals for v in fit.views]) if fit.views else np.zeros((0, 2))
    mag = magnification(res_all, float(max(w, h)))

    fig = plt.figure(figsize=(13, 8.5), dpi=100)
    gs = fig.add_gridspec(2, 2, width_ratios=[1.35, 1], height_ratios=[1.6, 1])
    ax = fig.add_subplot(gs[:, 0])
    ax.imshow(img, cmap="gray", vmin=0, vmax=255)
    for r, style in ((ring.r_inner, "--"), (ring.r_outer, "-")):
        ax.add_patch(Circle(ring.center, r, fill=False, color="tab:orange", lw=1.2, ls=style))
    ax.plot(*ring.center, "+", color="tab:orange", ms=10, label="ring centre")
    ax.plot(*fit.ocam.center, "x", color="tab:cyan", ms=10, label="optical centre")
    for v in fit.views:
        d = det.get(v.frame)
        if d is None:
            continue
        p = np.asarray(d.image_points)
        colour = "tab:red" if v.held_out else "tab:green"
        ax.plot(p[:, 0], p[:, 1], ".", color=colour, ms=2)
        q = p - v.residuals * mag
        ax.plot(np.stack([p[:, 0], q[:, 0]]), np.stack([p[:, 1], q[:, 1]]), "-", color="yellow", lw=0.6)
    ax.set_xlim(0, w)
    ax.set_ylim(h, 0)
    ax.set_title(
        f"ring and corners (green fitted, red held out); residuals x{mag:g} (yellow)\n"
        f"RMS {fit.rms_fit:.2f} px fitted" + (f", {fit.rms_held:.2f} px held out" if fit.rms_held is not None else ""),
        fontsize=10,
    )
    ax.legend(loc="lower right", fontsize=8)
    ax.axis("off")

    ax2 = fig.add_subplot(gs[0, 1])
    r = np.linspace(0.0, 1.1 * prof.r_outer, 400)
    ax2.plot(r, fit.ocam.elevation(r), color="0.6", lw=1, label="model atan2(f(rho), rho)")
    rr = np.linspace(prof.r_inner, prof.r_outer, 200)
    ax2.plot(rr, prof.elevation(rr), color="tab:blue", lw=2, label="lens.json elevation_poly")
    ax2.axvspan(prof.r_inner, prof.r_outer, color="tab:orange", alpha=0.12, label="the ring")
    ax2.axvspan(*fit.support, color="tab:green", alpha=0.10, label="corners' reach (beyond: extrapolated)")
    ax2.axhline(0, color="0.8", lw=0.8)
    lo, hi = prof.elevation(np.array([prof.r_inner, prof.r_outer]))
    ax2.set_ylim(min(lo, hi) - 15, max(lo, hi) + 15)
    ax2.set_xlabel("radius from the optical centre (px)")
    ax2.set_ylabel("elevation (deg)")
    ax2.set_title(f"elevation: {lo:+.1f} to {hi:+.1f} deg over the ring", fontsize=10)
    ax2.legend(fontsize=8)
    ax2.grid(alpha=0.3)

    ax3 = fig.add_subplot(gs[1, 1])
    x = np.arange(len(fit.views))
    ax3.bar(x, [v.rms for v in fit.views], color=["tab:red" if v.held_out else "tab:green" for v in fit.views])
    ax3.set_xticks(x, [str(v.frame) for v in fit.views], fontsize=7, rotation=90)
    ax3.set_xlabel("frame (red: held out)")
    ax3.set_ylabel("RMS (px)")
    ax3.set_title("reprojection RMS per image", fontsize=10)
    ax3.grid(axis="y", alpha=0.3)
    fig.suptitle(
        f"omninav calib lens: centre {prof.center[0]:.1f}, {prof.center[1]:.1f} px, "
        f"forward {prof.forward_deg:.1f} deg, ccw {str(prof.ccw).lower()}",
        fontsize=11,
    )
    try:
        fig.tight_layout()
        fig.savefig(path)
    finally:
        plt.close(fig)
    return mag
