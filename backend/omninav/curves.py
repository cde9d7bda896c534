"""Omni-projection curves (the paper's Eq. 3): column sums of colour channels over elevation bands.

A panorama's columns are azimuths, so summing each column over a band around the horizon gives a
1-D curve per channel whose circular shift is the camera's rotation. The paper's six curves are
the column sums of H, S, I and of their horizontal gradients; we can add opponent colours and more
bands, and give each band its own channels (`band_channels`, see presets.py: the default preset
sums intensity over five narrow bands, since where in elevation a corridor's lights and edges sit
is what tells identical doors apart, and the colours over one wide band). Each curve is
normalised to zero mean and unit variance, which removes brightness gain and offset, and then, in
the default preset, softly clipped (`soft_clip`): a few columns far from the curve's mean (a window
in the sun, one strong door edge) no longer carry most of its variance, so a change of light on
them moves the spectrum less.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from .presets import band_channels

CHANNELS = ("H", "S", "I", "dH", "dS", "dI", "O1", "O2", "dO1", "dO2")
_EPS = 1e-6


def hsi(rgb: np.ndarray) -> dict[str, np.ndarray]:
    """(rows, cols, 3) float32 RGB in [0, 1] -> hue (turns, [0, 1)), saturation and intensity.

    The HSI model of Gonzalez & Woods, which the paper uses; hue is an angle, kept in turns.
    """
    r, g, b = rgb[..., 0], rgb[..., 1], rgb[..., 2]
    s3 = r + g + b
    i = s3 / 3.0
    s = 1.0 - 3.0 * np.minimum(np.minimum(r, g), b) / np.maximum(s3, _EPS)
    num = 0.5 * ((r - g) + (r - b))
    den = np.sqrt((r - g) ** 2 + (r - b) * (g - b)) + _EPS
    theta = np.arccos(np.clip(num / den, -1.0, 1.0))
    h = np.where(b > g, 2.0 * np.pi - theta, theta) / (2.0 * np.pi)
    return {"H": h.astype(np.float32), "S": s.astype(np.float32), "I": i.astype(np.float32)}


def gray_world(rgb: np.ndarray, valid: np.ndarray | None = None) -> np.ndarray:
    """Divide each channel by its mean (over valid pixels): undoes a global cast and gain.

    Under a colour cast hue shifts non-linearly and saturation with it; the paper's H and S curves
    then stop matching the venue's. Gray-world constancy fixes the cast before they are computed.
    """
    # Accumulate in float64: numpy sums an axis-0 float32 reduction sequentially, whose error (1e-5
    # relative) the opponent channels' cancellation amplifies; the phone's extractor sums in doubles.
    # One channel at a time (a strided column, six times faster than mean(axis=0) of the pixels):
    # a panorama's float32 k / 255 values sum exactly in float64 in any order (below 2^20 pixels),
    # so the means are the phone's to the last bit.
    px = rgb.reshape(-1, 3) if valid is None or valid.all() else rgb[valid]
    if len(px):
        mean = np.array([np.add.reduce(px[:, c], dtype=np.float64) for c in range(3)]) / len(px)
    else:
        mean = np.ones(3)
    out: np.ndarray = rgb * (0.5 / np.maximum(mean.astype(np.float32), _EPS)).astype(np.float32)
    return out


def _hgrad(x: np.ndarray, circular_unit: bool = False) -> np.ndarray:
    """|d/dx| along the columns (azimuth), circular because the panorama wraps around."""
    d = circular_diff(x)
    if circular_unit:  # hue is an angle in turns: 0.99 and 0.01 are close
        d = (d + 0.5) % 1.0 - 0.5
    out: np.ndarray = np.abs(d) * 0.5
    return out


def circular_diff(x: np.ndarray) -> np.ndarray:
    """x[..., j + 1] - x[..., j - 1] along the last axis, wrapping: np.roll's values, without its copies."""
    d = np.empty_like(x)
    n = x.shape[-1]
    if n < 3:  # the two neighbours overlap: as np.roll has them
        rolled: np.ndarray = np.roll(x, -1, axis=-1) - np.roll(x, 1, axis=-1)
        return rolled
    np.subtract(x[..., 2:], x[..., :-2], out=d[..., 1:-1])
    np.subtract(x[..., 1], x[..., -1], out=d[..., 0])
    np.subtract(x[..., 0], x[..., -2], out=d[..., -1])
    return d


def channel_images(rgb: np.ndarray, channels: list[str] | tuple[str, ...]) -> dict[str, np.ndarray]:
    """The per-pixel channel images that the curves sum: (rows, cols) float32 each."""
    out: dict[str, np.ndarray] = {}
    need_hsi = any(c in ("H", "S", "I", "dH", "dS", "dI") for c in channels)
    if need_hsi and not any(c in ("H", "S", "dH", "dS") for c in channels):
        # intensity alone needs no hue; (r + g) + b, then / 3, is rgb.mean(axis=-1)'s float32 sum
        # and quotient, bit for bit, without its slow three-element reduction
        base = {"I": (rgb[..., 0] + rgb[..., 1] + rgb[..., 2]) / np.float32(3.0)}
    else:
        base = hsi(rgb) if need_hsi else {}
    r, g, b = rgb[..., 0], rgb[..., 1], rgb[..., 2]
    o1 = o2 = r  # opponent colours cost two full-frame passes: only made when a channel needs them
    if any(c.endswith(("O1", "O2")) for c in channels):
        o1 = (r - g) * 0.5
        o2 = (r + g - 2.0 * b) * 0.25
    for ch in channels:
        if ch in base:
            out[ch] = base[ch]
        elif ch == "dH":
            out[ch] = _hgrad(base["H"], circular_unit=True)
        elif ch in ("dS", "dI"):
            out[ch] = _hgrad(base[ch[1]])
        elif ch == "O1":
            out[ch] = o1
        elif ch == "O2":
            out[ch] = o2
        elif ch == "dO1":
            out[ch] = _hgrad(o1)
        elif ch == "dO2":
            out[ch] = _hgrad(o2)
        else:
            raise ValueError(f"unknown channel {ch!r}; known: {CHANNELS}")
    return out


def normalise(curves: np.ndarray) -> np.ndarray:
    """Zero mean, unit standard deviation per curve (last axis); a flat curve stays zero."""
    c = curves - curves.mean(axis=-1, keepdims=True)
    sd = c.std(axis=-1, keepdims=True)
    out: np.ndarray = (c / np.maximum(sd, 1e-4)).astype(np.float32)
    return out


def soft_clip(curves: np.ndarray, sd: float) -> np.ndarray:
    """Normalised curves -> sd * tanh(curve / sd), normalised again.

    A daylit window or one high-contrast edge makes a few columns several standard deviations
    out; they then dominate the curve's low harmonics and change with the hour or the exposure.
    tanh keeps the order of the columns (where the edges are) and bounds how much any one can
    weigh. Measured on the tuning families only (docs/benchlog.md, "Softly clipped curves").
    """
    out: np.ndarray = normalise(np.float32(sd) * np.tanh(curves / np.float32(sd)))
    return out


def extract_curves(
    pano: np.ndarray, elevations: np.ndarray, conf: dict[str, Any], valid: np.ndarray | None = None
) -> np.ndarray:
    """(rows, cols*oversample, 3) panorama (uint8 or float in [0, 1]) -> (n_curves, cols) float32.

    Curves are ordered band-major: for each band, its channels in `conf["channels"]` order (or
    the band's own list, `conf["band_channels"]`: presets.band_channels). Column sums are means
    over the band's rows so that the band height does not scale them.
    """
    per = band_channels(conf)
    if pano.ndim != 3 or pano.shape[2] != 3 or pano.shape[0] != len(elevations):
        raise ValueError(f"panorama shape {pano.shape} does not match {len(elevations)} rows x 3")
    rgb = pano.astype(np.float32)
    if pano.dtype == np.uint8:
        rgb *= 1.0 / 255.0
    if conf.get("gray_world"):
        rgb = gray_world(rgb, valid)
    imgs = channel_images(rgb, list(dict.fromkeys(c for chs in per for c in chs)))
    width = conf["pano_width"]
    os_ = pano.shape[1] // width
    out = np.empty((sum(len(c) for c in per), width), np.float32)
    k = 0
    for (lo, hi), chs in zip(conf["bands"], per, strict=True):
        rows = np.flatnonzero((elevations >= lo - 1e-6) & (elevations <= hi + 1e-6))
        # the band's rows are consecutive (elevations descend): a view, not a copy, the same sums
        band = slice(rows[0], rows[-1] + 1) if len(rows) and rows[-1] - rows[0] + 1 == len(rows) else rows
        for ch in chs:
            col = imgs[ch][band].mean(axis=0)
            out[k] = col.reshape(width, os_).mean(axis=1)
            k += 1
    out = normalise(out)
    if conf.get("soft_clip_sd"):  # absent in venues modelled before it: their curves as they were
        out = soft_clip(out, float(conf["soft_clip_sd"]))
    return out
