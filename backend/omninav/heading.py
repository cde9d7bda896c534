"""Heading by circular cross-correlation of the curves in the Fourier domain (the paper's Eq. 6-7).

If a query panorama is a venue panorama turned by s columns, q(j) = v(j + s), its harmonics are
Q_k = V_k exp(i 2 pi k s / W). The correlation of the two, summed over all curves (one camera, one
rotation), r(s') = sum_k Re(Q_k conj(V_k) exp(-i 2 pi k s' / W)), peaks at s' = s. We sample r at
`n_shifts` points with one inverse FFT and refine the peak by a parabola: sub-degree headings
from the few harmonics the record carries. The peak value is also the match score (a cosine).
"""

from __future__ import annotations

from typing import Any

from .arrays import namespace_of


def correlation(fq: Any, fv: Any, n_shifts: int = 256) -> Any:
    """fq, fv: (..., C, K) complex spectra (broadcast) -> (..., n_shifts) correlation over shifts.

    Sample m is the shift m * 360 / n_shifts degrees; values are cosines in [-1, 1].
    """
    xp = namespace_of(fq)
    x = (fq * xp.conj(fv)).sum(axis=-2)  # (..., K) cross-power, summed over curves
    k = x.shape[-1]
    if n_shifts < 2 * k + 2:
        raise ValueError(f"n_shifts must be at least {2 * k + 2} for {k} harmonics")
    pad = xp.zeros(x.shape[:-1] + (n_shifts // 2 + 1,), dtype=x.dtype)
    pad[..., 1 : k + 1] = xp.conj(x)
    # irfft computes (1/n)(Y0 + 2 sum Re(Y_k e^{+i...})); undo both factors.
    return xp.fft.irfft(pad, n=n_shifts, axis=-1) * (n_shifts / 2.0)


def peak(r: Any) -> tuple[Any, Any]:
    """(..., n) correlation -> (shift in degrees [0, 360), peak value), parabolic sub-sample peak."""
    xp = namespace_of(r)
    n = r.shape[-1]
    i = xp.argmax(r, axis=-1)
    y0 = xp.take_along_axis(r, i[..., None], axis=-1)[..., 0]
    ym = xp.take_along_axis(r, ((i - 1) % n)[..., None], axis=-1)[..., 0]
    yp = xp.take_along_axis(r, ((i + 1) % n)[..., None], axis=-1)[..., 0]
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
