"""Suggested waypoints (`omninav suggest-waypoints`): where a walk video turned and stopped.

Tagging a walk path means clicking the plan at the moments that matter: the corners and the places the
walker stood. This module finds those moments in the video alone, so the admin page can offer them.

Turns. The rotation between consecutive sampled frames is a circular shift of their curves (the
paper's Eq. 3), which the phase correlation (Eq. 6-7, heading.py) measures. Over the whole circle,
though, walking forward biases it: the walls beside the walker slide backwards (parallax), the
left wall one way and the right the other, and whichever side carries more texture wins, a few
degrees a frame, tens of degrees of drift a minute. So the whole-circle correlation only gives a
first guess (with the frame before's rotation and "none" as the others: a corridor looks much the
same both ways round); the rotation is the *median* of the shifts of twelve 60-degree sectors,
found near the guess they match best. Parallax moves the sectors on one side of the walking
direction one way and those on the other side the other way, while a rotation moves them all
alike: the median keeps the rotation. Their sum over time is the cumulative heading; a turn is a
stretch where its smoothed rate stays high, reported at the moment half of its angle is done (its
middle), with the signed angle (+ clockwise, a right turn).

Stops. A frame and the one half a second later barely differ when the walker stands (whatever way
the lens points: the phase correlation's peak ignores rotation); walking changes them many times
more. A stretch of such pairs, long enough, is a stop, reported at its start with its duration.

The signal processing is pure functions over arrays; `suggest_waypoints` reads the video.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from .calib.correct import FIRST, lens_check
from .errors import OmninavError
from .extract import Extractor
from .heading import correlation, peak, wrap_deg
from .lens import Lens
from .model_venue import Progress
from .presets import TWO_BANDS, resolve
from .spectrum import spectrum
from .video import VideoInfo, iter_video

DEFAULTS: dict[str, Any] = {
    "sample_fps": 10.0,  # frames a second read from the video (every k-th frame of a 30 fps video)
    "preset": "default",  # feature preset of the curves (presets.py)
    # rotation between consecutive frames
    "sectors": 12,  # azimuth sectors whose shifts' median is the rotation
    "sector_half_deg": 30.0,  # half width of each sector's (Hann) window
    "max_parallax_deg": 20.0,  # sector shifts searched this far either side of the global guess
    "min_sector_peak": 0.5,  # a sector whose best correlation is below this is not trusted
    # turns
    "smooth_s": 0.3,  # Gaussian smoothing (sigma) of the cumulative heading
    "turn_rate_deg_s": 15.0,  # a turn is where the heading turns faster than this ...
    "min_turn_deg": 30.0,  # ... by at least this in all
    "merge_gap_s": 0.6,  # stretches of one turn's direction this close are one turn
    # stops
    "stop_lag_s": 0.5,  # a frame is compared with the one this much later
    "stop_change": 0.05,  # below this (1 - correlation peak) the two are the same view ...
    "stop_change_rel": 0.25,  # ... and below this fraction of a walking pair's (75th percentile)
    "min_stop_s": 1.0,  # shorter stands are not stops
    "heading_hz": 2.0,  # samples a second of the returned heading curve
}


def settings_for(settings: dict[str, Any] | None = None) -> dict[str, Any]:
    """DEFAULTS with `settings` merged over them; an unknown key is refused (a typo would not act)."""
    s = dict(DEFAULTS)
    for k, v in (settings or {}).items():
        if k not in DEFAULTS:
            raise OmninavError(f"unknown suggestion setting {k!r} (known: {', '.join(sorted(DEFAULTS))})")
        s[k] = v
    if not float(s["sample_fps"]) > 0:
        raise OmninavError("suggestion setting 'sample_fps' must be positive")
    return s


# --- signal processing: arrays in, arrays out ------------------------------------------------------


@dataclass(frozen=True)
class Sectors:
    """The same Hann window at K centres around the panorama: where the shifts are measured."""

    centres: np.ndarray  # (K,) int columns
    kernel: np.ndarray  # (W,) float64 window centred on column 0 (circular: column W-1 is -1)
    matrix: np.ndarray  # (W, K) the windows as columns


def sector_windows(width: int, n_sectors: int, half_deg: float) -> Sectors:
    """Hann windows `half_deg` either side of azimuths k * 360 / n_sectors (to a column)."""
    d = (np.arange(width) + width // 2) % width - width // 2
    half = half_deg * width / 360.0
    kernel = np.where(np.abs(d) <= half, 0.5 + 0.5 * np.cos(np.pi * d / (half + 1.0)), 0.0)
    centres = np.round(np.arange(n_sectors) * width / n_sectors).astype(np.int64) % width
    return Sectors(centres, kernel, np.stack([np.roll(kernel, int(c)) for c in centres], axis=1))


def sector_shifts(
    a: np.ndarray, b: np.ndarray, sectors: Sectors, guess_deg: float = 0.0, max_deg: float = 20.0
) -> tuple[np.ndarray, np.ndarray]:
    """Curves a, b (C, W) of a frame and the one before -> per sector (K,): the rotation (deg,
    + clockwise) of a relative to b, i.e. a(j) = b(j + s), and its correlation.

    Searched within `max_deg` of `guess_deg`: the normalised cross-correlation of each sector,
    pooled over the curves, refined by a parabola to a fraction of a column. The windowed sums of
    b, shifted, are one circular correlation with the window (an FFT), read at centre + shift.
    """
    w = sectors.kernel.shape[0]
    if a.ndim != 2 or a.shape != b.shape or a.shape[1] != w:
        raise ValueError(f"curves {a.shape} and {b.shape} do not match windows of width {w}")
    col = 360.0 / w
    m = max(2, int(np.ceil(max_deg / col)))
    shifts = int(round(guess_deg / col)) + np.arange(-m, m + 1)
    a64, b64 = a.astype(np.float64), b.astype(np.float64)
    kf = np.conj(np.fft.rfft(sectors.kernel))

    def wsum(x: np.ndarray) -> np.ndarray:  # (C, W) -> windowed sums centred on every column
        out: np.ndarray = np.fft.irfft(np.fft.rfft(x, axis=-1) * kf, n=w, axis=-1)
        return out

    cen = sectors.centres
    at = (cen[None, :] + shifts[:, None]) % w  # (shifts, K): the window of b that meets sector k
    sw = float(sectors.kernel.sum())
    sa, sa2 = wsum(a64)[:, cen], wsum(a64 * a64)[:, cen]  # (C, K)
    sb, sb2 = wsum(b64)[:, at], wsum(b64 * b64)[:, at]  # (C, shifts, K)
    idx = (np.arange(w)[None, :] + shifts[:, None]) % w
    prod = np.einsum("cj,csj->sj", a64, b64[:, idx])  # (shifts, W): sum over curves of a(j) b(j + s)
    cov = prod @ sectors.matrix - np.einsum("ck,csk->sk", sa, sb) / sw  # (shifts, K)
    va = (sa2 - sa * sa / sw).sum(axis=0)  # (K,)
    vb = (sb2 - sb * sb / sw).sum(axis=0)  # (shifts, K)
    ncc = cov / np.sqrt(np.maximum(va[None] * vb, 1e-12))
    i = np.clip(ncc.argmax(axis=0), 1, len(shifts) - 2)
    k = np.arange(ncc.shape[1])
    y0, ym, yp = ncc[i, k], ncc[i - 1, k], ncc[i + 1, k]
    den = ym - 2.0 * y0 + yp
    ok = np.abs(den) > 1e-12
    d = np.clip(np.where(ok, 0.5 * (ym - yp) / np.where(ok, den, 1.0), 0.0), -0.5, 0.5)
    return (shifts[i] + d) * col, y0 - 0.25 * (ym - yp) * d


def robust_rotation(shifts: np.ndarray, peaks: np.ndarray, min_peak: float, fallback: float) -> float:
    """The median of the trusted sectors' shifts; `fallback` when fewer than a quarter are trusted."""
    ok = peaks >= min_peak
    if ok.sum() < max(3, len(shifts) // 4):
        return fallback
    return float(np.median(shifts[ok]))


def frame_rotation(
    a: np.ndarray, b: np.ndarray, sectors: Sectors, guesses: list[float], max_deg: float, min_peak: float
) -> float:
    """Curves a, b (C, W) of a frame and the one before -> a's rotation (deg, + clockwise).

    Each guess (the whole-circle phase correlation's, the frame before's rotation, none) is refined
    by the sectors, and the one whose sectors match best (highest median correlation) wins: a
    corridor looks much the same both ways, so the whole-circle peak is now and then 180 deg out.
    """
    best: tuple[float, float] | None = None
    tried: list[float] = []
    for g in guesses:
        if any(abs(float(wrap_deg(g - u))) < max_deg / 2 for u in tried):
            continue  # within the search range of one already tried
        tried.append(g)
        sh, pk = sector_shifts(a, b, sectors, g, max_deg)
        score = float(np.median(pk))
        if best is None or score > best[0]:
            best = (score, robust_rotation(sh, pk, min_peak, g))
    if best is None:
        raise ValueError("frame_rotation needs at least one guess")
    return best[1]


def change_signal(spectra: np.ndarray, lag: int) -> np.ndarray:
    """(F, C, K) spectra -> (F - lag,) 1 - peak phase correlation of frame i with frame i + lag.

    The peak over all rotations, so turning on the spot is no change; 0 for identical views.
    """
    if spectra.ndim != 3 or lag < 1:
        raise ValueError(f"want (F, C, K) spectra and lag >= 1, got {spectra.shape} and {lag}")
    if len(spectra) <= lag:
        return np.zeros(0)
    n = max(64, 8 * spectra.shape[-1])
    _, val = peak(correlation(spectra[lag:], spectra[:-lag], n_shifts=n))
    out: np.ndarray = np.clip(1.0 - np.asarray(val, np.float64), 0.0, 2.0)
    return out


def gaussian_smooth(x: np.ndarray, sigma: float) -> np.ndarray:
    """(N,) -> (N,) Gaussian smoothing with sigma in samples; the ends are extended, not zeroed."""
    x = np.asarray(x, np.float64)
    if sigma <= 0 or len(x) < 2:
        return x.copy()
    r = int(np.ceil(3 * sigma))
    k = np.exp(-0.5 * (np.arange(-r, r + 1) / sigma) ** 2)
    k /= k.sum()
    out: np.ndarray = np.convolve(np.pad(x, r, mode="edge"), k, mode="valid")
    return out


def _runs(mask: np.ndarray) -> list[tuple[int, int]]:
    """Index runs [a, b] (inclusive) where mask is True."""
    d = np.diff(np.concatenate([[0], mask.astype(np.int8), [0]]))
    return list(zip(np.flatnonzero(d == 1).tolist(), (np.flatnonzero(d == -1) - 1).tolist(), strict=True))


def find_turns(
    t: np.ndarray,
    heading: np.ndarray,
    rate_deg_s: float = 15.0,
    min_turn_deg: float = 30.0,
    merge_gap_s: float = 0.6,
    settle_s: float = 0.5,
) -> list[tuple[float, float]]:
    """Sample times (N,) and the smoothed cumulative heading (N,) deg -> [(t, signed deg)] turns.

    A turn is a run of samples turning one way faster than `rate_deg_s` (runs of one sign less
    than `merge_gap_s` apart joined), widened to where the turning falls below a third of that
    rate, turning `min_turn_deg` or more in all, measured from `settle_s` before to `settle_s`
    after (the smoothing spreads a turn). Its time is when half its angle is done.
    """
    t, h = np.asarray(t, np.float64), np.asarray(heading, np.float64)
    if t.shape != h.shape or t.ndim != 1:
        raise ValueError(f"times {t.shape} and heading {h.shape} must be equal 1-D arrays")
    if len(t) < 3:
        return []
    rate = np.gradient(h, t)
    spans: list[tuple[int, int, int]] = []  # (first, last, sign)
    for sign in (1, -1):
        for a, b in _runs(sign * rate > rate_deg_s):
            # widen to where the walker has (nearly) stopped turning this way
            while a > 0 and sign * rate[a - 1] > rate_deg_s / 3:
                a -= 1
            while b < len(t) - 1 and sign * rate[b + 1] > rate_deg_s / 3:
                b += 1
            if spans and spans[-1][2] == sign and t[a] - t[spans[-1][1]] <= merge_gap_s:
                spans[-1] = (spans[-1][0], max(b, spans[-1][1]), sign)
            else:
                spans.append((a, b, sign))
    spans.sort()
    turns = []
    for n, (a, b, _) in enumerate(spans):
        # the angle from where the heading had settled before to where it settles after
        lo = spans[n - 1][1] if n > 0 else 0
        hi = spans[n + 1][0] if n + 1 < len(spans) else len(t) - 1
        a0 = max(lo, int(np.searchsorted(t, t[a] - settle_s)) - 1, 0)
        b1 = min(hi, int(np.searchsorted(t, t[b] + settle_s)))
        total = h[b1] - h[a0]
        if abs(total) < min_turn_deg:
            continue
        seg_h, seg_t = h[a0 : b1 + 1], t[a0 : b1 + 1]
        half = h[a0] + total / 2
        # the heading is monotonic enough over a turn: the first crossing of the half-way angle
        j = max(int(np.argmax((seg_h - half) * np.sign(total) >= 0)), 1)
        f = (half - seg_h[j - 1]) / (seg_h[j] - seg_h[j - 1]) if seg_h[j] != seg_h[j - 1] else 1.0
        turns.append((float(seg_t[j - 1] + np.clip(f, 0, 1) * (seg_t[j] - seg_t[j - 1])), float(total)))
    return sorted(turns)


def find_stops(
    t: np.ndarray, change: np.ndarray, lag_s: float, threshold: float, min_s: float
) -> list[tuple[float, float]]:
    """Times (N,) and the change (N,) between each sample and the one `lag_s` later -> [(t, s)].

    A stop runs from the first sample of a run of still pairs to the later frame of its last pair.
    Runs at most `lag_s` apart are one stop: one sudden change (someone stepping into view) spoils
    only the pairs that straddle it, while walking away spoils every pair for longer than that.
    """
    t, c = np.asarray(t, np.float64), np.asarray(change, np.float64)
    if t.shape != c.shape or t.ndim != 1:
        raise ValueError(f"times {t.shape} and change {c.shape} must be equal 1-D arrays")
    dt = float(np.median(np.diff(t))) if len(t) > 1 else 0.0
    runs: list[tuple[float, float]] = []
    for a, b in _runs(c < threshold):
        if runs and t[a] - runs[-1][1] <= lag_s + dt + 1e-9:
            runs[-1] = (runs[-1][0], float(t[b]))
        else:
            runs.append((float(t[a]), float(t[b])))
    return [(t0, t1 + lag_s - t0) for t0, t1 in runs if t1 + lag_s - t0 >= min_s]


def stop_threshold(change: np.ndarray, absolute: float, relative: float) -> float:
    """The change below which a pair counts as still: `absolute`, or lower for a video whose
    walking pairs change little (`relative` times the 75th percentile)."""
    if len(change) == 0:
        return absolute
    return float(min(absolute, relative * np.percentile(change, 75)))


def suggest_from_signals(
    t: np.ndarray, rel_deg: np.ndarray, change: np.ndarray, end_t: float, settings: dict[str, Any] | None = None
) -> dict[str, Any]:
    """The pure core: sample times (N,), rotation of each sample from the one before (N-1,) and the
    change to the sample `stop_lag_s` later (N - lag,) -> the suggestions and the heading curve."""
    s = settings_for(settings)
    t = np.asarray(t, np.float64)
    if len(t) < 1 or len(rel_deg) != len(t) - 1 or len(change) > len(t):
        raise ValueError(f"{len(t)} times need {len(t) - 1} rotations and at most {len(t)} changes")
    heading = np.concatenate([[0.0], np.cumsum(rel_deg)])
    dt = float(np.median(np.diff(t))) if len(t) > 1 else 1.0
    smooth = gaussian_smooth(heading, s["smooth_s"] / dt)
    turns = find_turns(t, smooth, s["turn_rate_deg_s"], s["min_turn_deg"], s["merge_gap_s"])
    thr = stop_threshold(change, s["stop_change"], s["stop_change_rel"])
    lag_s = round(s["stop_lag_s"] / dt) * dt
    stops = find_stops(t[: len(change)], change, lag_s, thr, s["min_stop_s"])
    sug: list[dict[str, Any]] = [{"t": float(t[0]), "kind": "start", "turn_deg": None, "duration_s": None}]
    events: list[tuple[float, str, float | None, float | None]] = [(tt, "turn", round(d, 1), None) for tt, d in turns]
    events += [(tt, "stop", None, round(d, 2)) for tt, d in stops]
    for tt, kind, deg, dur in sorted(events, key=lambda e: e[0]):
        sug.append({"t": round(tt, 2), "kind": kind, "turn_deg": deg, "duration_s": dur})
    sug.append({"t": round(float(end_t), 2), "kind": "end", "turn_deg": None, "duration_s": None})
    grid = np.arange(t[0], t[-1] + 1e-9, 1.0 / s["heading_hz"])
    curve = np.interp(grid, t, smooth)
    return {
        "suggestions": sug,
        "heading": [[round(float(a), 2), round(float(b), 1)] for a, b in zip(grid, curve, strict=True)],
    }


# --- the edge: reading the video ------------------------------------------------------------------


def suggest_waypoints(
    video: Path, lens: Lens, settings: dict[str, Any] | None = None, progress: Progress | None = None
) -> dict[str, Any]:
    """A walk video and its lens -> {"duration_s", "fps", "frames", "sample_fps", "suggestions":
    [{"t", "kind": start|turn|stop|end, "turn_deg" (+ clockwise) or None, "duration_s" or None}],
    "heading": [[t, cumulative heading deg], ...] (`heading_hz` a second)}.

    `progress(done, total, elapsed_s)` after every sampled frame; it may raise to stop the work.
    """
    s = settings_for(settings)
    # the heading track's thresholds (min_sector_peak, the tolerances in docs/benchlog.md) were
    # measured on unclipped curves, in two bands for the default: the suggestions keep them whatever
    # the preset clips or however it bands its channels
    conf = resolve(s["preset"], {"soft_clip_sd": None})
    if conf.get("band_channels") is not None:
        conf = resolve(s["preset"], {"soft_clip_sd": None, **TWO_BANDS})
    info = VideoInfo(video, label=video.name)
    w, h = lens.image_size
    if (info.width, info.height) != (w, h):
        raise OmninavError(f"{video.name}: frames are {info.width}x{info.height} but the lens profile is for {w}x{h}")
    vfps = info.fps if info.fps > 0 else 30.0
    stride = max(1, int(round(vfps / s["sample_fps"])))
    expected = (info.frames - 1) // stride + 1 if info.frames else 0
    ext = Extractor(lens, conf)
    sectors = sector_windows(conf["pano_width"], int(s["sectors"]), float(s["sector_half_deg"]))
    n_shifts = max(64, 8 * int(conf["n_harmonics"]))
    max_deg, min_peak = float(s["max_parallax_deg"]), float(s["min_sector_peak"])
    times: list[float] = []
    rel: list[float] = []
    specs: list[np.ndarray] = []
    prev: np.ndarray | None = None
    t0 = time.perf_counter()
    last = 0
    held: list[np.ndarray] = []  # the first frames: does the video fit the lens? (calib/correct.py)
    for i, frame in iter_video(info, stride=stride):
        if len(held) < FIRST:
            held.append(frame)
        cur = ext.curves(frame)
        spec = spectrum(cur, conf["n_harmonics"])
        if prev is not None:
            guess, _ = peak(correlation(spec, specs[-1], n_shifts))
            guesses = [float(wrap_deg(float(guess))), rel[-1] if rel else 0.0, 0.0]
            rel.append(frame_rotation(cur, prev, sectors, guesses, max_deg, min_peak))
        prev = cur
        specs.append(spec)
        times.append(i / vfps)
        last = i
        if progress:
            progress(len(times), max(expected, len(times)), time.perf_counter() - t0)
    if not times:
        raise OmninavError(f"{video.name}: not a readable video (no decodable frames)")
    lag = max(1, int(round(s["stop_lag_s"] * vfps / stride)))
    change = change_signal(np.stack(specs), lag)
    frames = max(info.frames, last + 1)
    out = suggest_from_signals(np.array(times), np.array(rel), change, last / vfps, s)
    return {
        "duration_s": round(frames / vfps, 3),
        "fps": vfps,
        "frames": frames,
        "sample_fps": round(vfps / stride, 3),
        "lens_check": lens_check(lens, held),
        **out,
    }
