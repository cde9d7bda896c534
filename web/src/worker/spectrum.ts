/**
 * Fourier spectra of the curves (the engine's spectrum.py): harmonics 1..K of each curve at unit
 * total energy, then quantised as the record carries them. The DFT itself is cv.dft (extract.ts).
 */
import { toHalf, type FrameSpectrum } from '../shared/record';

/**
 * DFT rows (interleaved re, im; `width` complex values per curve, as cv.dft with DFT_ROWS |
 * DFT_COMPLEX_OUTPUT gives them) -> harmonics 1..K scaled to unit total energy, as float64 re/im.
 */
export function harmonics(
  dft: Float32Array | Float64Array,
  nCurves: number,
  width: number,
  k: number,
): { re: Float64Array; im: Float64Array } {
  if (k < 1 || k > width >> 1) throw new Error(`n_harmonics must be in [1, ${width >> 1}], got ${k}`);
  const re = new Float64Array(nCurves * k);
  const im = new Float64Array(nCurves * k);
  let e = 0;
  for (let c = 0; c < nCurves; c++) {
    for (let h = 0; h < k; h++) {
      const p = 2 * (c * width + h + 1);
      re[c * k + h] = dft[p];
      im[c * k + h] = dft[p + 1];
      e += dft[p] ** 2 + dft[p + 1] ** 2;
    }
  }
  const s = 1 / Math.max(Math.sqrt(e), 1e-12);
  for (let i = 0; i < re.length; i++) {
    re[i] *= s;
    im[i] *= s;
  }
  return { re, im };
}

/** Round half to even (numpy.round). */
function roundEven(v: number): number {
  const r = Math.round(v);
  return Math.abs(v % 1) === 0.5 && r % 2 !== 0 ? r - 1 : r;
}

/** Unit-energy harmonics -> the record's quantised magnitudes and phases. */
export function quantise(re: Float64Array, im: Float64Array): FrameSpectrum {
  const n = re.length;
  const mag = new Uint16Array(n);
  const phase = new Int16Array(n);
  for (let i = 0; i < n; i++) {
    // the engine takes |f| and angle(f) of complex64 values: round to float32 first, as it does
    const a = Math.fround(re[i]);
    const b = Math.fround(im[i]);
    mag[i] = toHalf(Math.fround(Math.hypot(a, b)));
    let p = roundEven(Math.atan2(b, a) * (32768 / Math.PI));
    if (p >= 32768) p -= 65536;
    phase[i] = p;
  }
  return { mag, phase };
}
