"""Heading by circular cross-correlation of the curves in the Fourier domain (the paper's Eq. 6-7).

If a query panorama is a venue panorama turned by s columns, q(j) = v(j + s), its harmonics are
Q_k = V_k exp(i 2 pi k s / W). The correlation of the two, summed over all curves (one camera, one
rotation), r(s') = sum_k Re(Q_k conj(V_k) exp(-i 2 pi k s' / W)), peaks at s' = s. We sample r at
`n_shifts` points (one real matrix product, cross_correlation) and refine the peak by a parabola: sub-degree headings
from the few harmonics the record carries. The peak value is also the match score (a cosine).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from .arrays import namespace_of


def correlation(fq: Any, fv: Any, n_shifts: int = 256) -> Any:
    """fq, fv: (..., C, K) complex spectra (broadcast) -> (..., n_shifts) correlation over shifts.

    Sample m is the shift m * 360 / n_shifts degrees; values are cosines in [-1, 1].
    """
    xp = namespace_of(fq)
    return cross_correlation((fq * xp.conj(fv)).sum(axis=-2), n_shifts)  # cross-power, summed over curves


def cross_correlation(x: Any, n_shifts: int = 256) -> Any:
    """(..., K) cross-power of two frames' harmonics 1..K, summed over curves -> (..., n_shifts)
    correlation over shifts (correlation()'s, for callers that form the cross-power otherwise).

    r(m) = sum_k Re(conj(X_k) e^{i 2 pi k m / n}) = sum_k Re X_k cos + Im X_k sin: one real matrix
    product with a (2K, n) basis. It is the inverse real FFT of the conjugated, zero-padded
    cross-power, but the search samples 8 shifts a harmonic (16 harmonics: 128 shifts from 65
    bins, 49 of them zeros): the product is 4x faster there (stage 2 of a shared search,
    index.py). Complex64 in, float32 out; complex128, float64."""
    xp = namespace_of(x)
    k = x.shape[-1]
    if n_shifts < 2 * k + 2:
        raise ValueError(f"n_shifts must be at least {2 * k + 2} for {k} harmonics")
    real = x.real.dtype
    basis = _shift_basis(xp, k, n_shifts, real)
    # the harmonics' real and imaginary parts as they lie in memory (re, im, re, im, ...): no copy
    return xp.ascontiguousarray(x).view(real) @ basis


_BASES: dict[tuple[str, int, int, str], Any] = {}  # (two threads may build one at once: harmless)


def _shift_basis(xp: Any, k: int, n: int, dtype: Any) -> Any:
    """(2K, n): cos and sin of 2 pi k m / n for k = 1..K and shifts m (columns), rows interleaved
    (cos k=1, sin k=1, cos k=2, ...) as a complex array's real and imaginary parts are; kept per
    array module, size and precision (a few KB each)."""
    # (a CuPy basis lives on one device: each device its own)
    key = (xp.__name__ if xp is np else f"{xp.__name__}:{xp.cuda.Device().id}", k, n, str(dtype))
    b = _BASES.get(key)
    if b is None:
        theta = 2.0 * np.pi * np.outer(np.arange(1, k + 1), np.arange(n)) / n
        b = _BASES[key] = xp.asarray(np.stack([np.cos(theta), np.sin(theta)], axis=1).reshape(2 * k, n).astype(dtype))
    return b


def peak(r: Any) -> tuple[Any, Any]:
    """(..., n) correlation -> (shift in degrees [0, 360), peak value), parabolic sub-sample peak."""
    xp = namespace_of(r)
    n = r.shape[-1]
    i = xp.argmax(r, axis=-1)
    # the three samples by flat index (three take_along_axis cost as much as the argmax)
    flat = r.reshape(-1)
    base = (xp.arange(i.size) * n).reshape(i.shape)
    y0 = flat[base + i]
    ym = flat[base + (i - 1) % n]
    yp = flat[base + (i + 1) % n]
    den = ym - 2.0 * y0 + yp
    safe = xp.where(xp.abs(den) > 1e-12, den, -1.0)
    d = xp.where(xp.abs(den) > 1e-12, 0.5 * (ym - yp) / safe, 0.0)
    d = xp.clip(d, -0.5, 0.5)
    val = y0 - 0.25 * (ym - yp) * d
    return ((i + d) * (360.0 / n)) % 360.0, val


def relative_heading(fq: Any, fv: Any, n_shifts: int = 256) -> tuple[Any, Any]:
    """Rotation (deg, clockwise) of query relative to venue frame, and the correlation score."""
    return peak(correlation(fq, fv, n_shifts))


def wrap_deg(a: Any) -> Any:
    """Angle difference wrapped to (-180, 180]."""
    return -((-a + 180.0) % 360.0 - 180.0)
