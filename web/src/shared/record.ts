/**
 * The compact feature record the phone sends (the engine's spectrum.py): version 1, the curves;
 * version 2, the curves and one frame's local features (docs/formats.md). Magnitudes travel as
 * float16, phases as int16 steps of 2*pi/65536: 4 bytes per harmonic.
 */
import { KNOWN_FEATURE_KEYS, nCurves, type FeatureSettings, type VenueFeatures } from './settings';

export const RECORD_VERSION = 1;
/** A record with a local block after its phases. */
export const LOCAL_VERSION = 2;
/** Degrees a unit of a keypoint's azimuth (uint16) and of its elevation (int16). */
export const AZ_STEP_DEG = 360 / 65536;
export const EL_STEP_DEG = 0.01;
/** The local block: "LOC", a zero byte, uint32 N; then N uint16 azimuths, N int16 elevations, N x 32 descriptor bytes. */
export const LOCAL_HEAD_BYTES = 8;
export const LOCAL_BYTES_PER_KEYPOINT = 2 + 2 + 32;
/** 8 + 36 x 880 = 31,688 bytes: a request's local features within 32 KB (the server refuses more). */
export const MAX_LOCAL_KEYPOINTS = 880;

/** How many of `n` keypoints a record carries: the first MAX_LOCAL_KEYPOINTS. */
export const keptKeypoints = (n: number): number => Math.min(n, MAX_LOCAL_KEYPOINTS);

/** The bytes of a local block that carries `n` keypoints (keptKeypoints of them), its head included. */
export const localBlockBytes = (n: number): number => LOCAL_HEAD_BYTES + LOCAL_BYTES_PER_KEYPOINT * keptKeypoints(n);

/** One frame's local features, in the record's units (worker/local.ts makes them). */
export interface LocalBlock {
  az: Uint16Array;
  el: Int16Array;
  /** N x 32 ORB descriptor bytes */
  desc: Uint8Array;
}

/**
 * The version-1 header, field by field, in the engine's order (spectrum.py's struct `<3sBHHHII2x`,
 * little-endian): the byte sizes here are the only place its length is written down.
 */
const HEADER_FIELDS = [
  ['magic', 3], // "ONV"
  ['version', 1],
  ['curves', 2],
  ['harmonics', 2],
  ['pano_width', 2],
  ['frames', 4],
  ['settings_id', 4],
  ['pad', 2], // keeps the body 4-byte aligned
] as const;

type HeaderField = (typeof HEADER_FIELDS)[number][0];

/** Each header field's byte offset, derived from the layout above. */
export const HEADER_AT = Object.fromEntries(
  HEADER_FIELDS.map(([name], i) => [name, HEADER_FIELDS.slice(0, i).reduce((o, [, n]) => o + n, 0)]),
) as Readonly<Record<HeaderField, number>>;

/** The header's size in bytes (20), derived from the layout above. */
export const HEADER_BYTES: number = HEADER_FIELDS.reduce((o, [, n]) => o + n, 0);

/** A float16 magnitude and an int16 phase per harmonic. */
export const BYTES_PER_HARMONIC = 4;

/**
 * Why records made here would not be the ones the venue's server reads, or null. The venue
 * document states its record's sizes; an app cached offline may be older than its server.
 */
export function recordMismatch(f: VenueFeatures): string | null {
  // a setting this app cannot apply (a newer server's): the sizes below could all agree and the
  // curves still differ, as levelling's did for the apps before it
  const unknown = unknownFeatureKeys(f);
  if (unknown.length) return `the venue's map needs settings this app does not know: ${unknown.join(', ')}`;
  if (f.record_header_bytes !== HEADER_BYTES)
    return `the server expects a ${f.record_header_bytes}-byte record header, this app makes ${HEADER_BYTES}`;
  // settings this app reads otherwise than the server (a key it does not know: per-band channels
  // before `band_channels`) make other curves than the server counts
  const made = nCurves(f.settings);
  if (made !== f.n_curves)
    return `the server's venue needs ${f.n_curves} curves a frame, this app makes ${made} from its settings`;
  const perFrame = BYTES_PER_HARMONIC * f.n_curves * f.n_harmonics;
  if (f.record_bytes_per_frame !== perFrame)
    return `the server expects ${f.record_bytes_per_frame} bytes per frame, this app makes ${perFrame}`;
  return null;
}

/** The settings the venue's records depend on that this app does not know how to apply. */
export const unknownFeatureKeys = (f: VenueFeatures): string[] =>
  (f.feature_keys ?? []).filter((k) => !(KNOWN_FEATURE_KEYS as readonly string[]).includes(k));

/** One frame's quantised spectrum: C*K float16 magnitude bits and int16 phases, curve-major. */
export interface FrameSpectrum {
  mag: Uint16Array;
  phase: Int16Array;
}

const f32buf = new Float32Array(1);
const u32buf = new Uint32Array(f32buf.buffer);

/** float32 -> IEEE half bits, round to nearest even (numpy's astype(float16)). */
export function toHalf(v: number): number {
  f32buf[0] = v;
  const x = u32buf[0];
  const sign = (x >>> 16) & 0x8000;
  const exp = (x >>> 23) & 0xff;
  let mant = x & 0x7fffff;
  if (exp === 0xff) return sign | 0x7c00 | (mant ? 0x200 : 0);
  let e = exp - 127 + 15;
  if (e >= 0x1f) return sign | 0x7c00;
  if (e <= 0) {
    if (e < -10) return sign;
    mant |= 0x800000;
    const shift = 14 - e;
    let half = mant >>> shift;
    const rem = mant & ((1 << shift) - 1);
    const mid = 1 << (shift - 1);
    if (rem > mid || (rem === mid && half & 1)) half++;
    return sign | half;
  }
  let half = (e << 10) | (mant >>> 13);
  const rem = mant & 0x1fff;
  if (rem > 0x1000 || (rem === 0x1000 && half & 1)) half++; // a carry into the exponent is still right
  return sign | half;
}

/** IEEE half bits -> number. */
export function fromHalf(h: number): number {
  const s = h & 0x8000 ? -1 : 1;
  const e = (h >>> 10) & 0x1f;
  const m = h & 0x3ff;
  if (e === 0) return s * m * 2 ** -24;
  if (e === 0x1f) return m ? NaN : s * Infinity;
  return s * (1 + m / 1024) * 2 ** (e - 15);
}

/** Quantised spectrum -> complex values (re, im), as the server decodes them. */
export function dequantise(s: FrameSpectrum): { re: Float64Array; im: Float64Array } {
  const n = s.mag.length;
  const re = new Float64Array(n);
  const im = new Float64Array(n);
  for (let i = 0; i < n; i++) {
    const m = fromHalf(s.mag[i]);
    const a = (s.phase[i] * Math.PI) / 32768;
    re[i] = m * Math.cos(a);
    im[i] = m * Math.sin(a);
  }
  return { re, im };
}

/**
 * Frames -> the binary record: the header (HEADER_FIELDS), then all magnitudes, then all phases;
 * with `local`, version 2 and its local block after the phases (the first MAX_LOCAL_KEYPOINTS).
 */
export function encodeRecord(
  frames: FrameSpectrum[],
  s: FeatureSettings,
  settingsId: number,
  local?: LocalBlock | null,
): Uint8Array {
  if (!frames.length) throw new Error('a record needs at least one frame');
  const ck = frames[0].mag.length;
  const n = local ? keptKeypoints(local.az.length) : 0;
  const curves = HEADER_BYTES + BYTES_PER_HARMONIC * ck * frames.length;
  const out = new Uint8Array(curves + (local ? localBlockBytes(n) : 0));
  const dv = new DataView(out.buffer);
  out.set([0x4f, 0x4e, 0x56], HEADER_AT.magic); // "ONV"
  dv.setUint8(HEADER_AT.version, local ? LOCAL_VERSION : RECORD_VERSION);
  dv.setUint16(HEADER_AT.curves, nCurves(s), true);
  dv.setUint16(HEADER_AT.harmonics, s.n_harmonics, true);
  dv.setUint16(HEADER_AT.pano_width, s.pano_width, true);
  dv.setUint32(HEADER_AT.frames, frames.length, true);
  dv.setUint32(HEADER_AT.settings_id, settingsId >>> 0, true);
  let o = HEADER_BYTES;
  for (const f of frames) for (const m of f.mag) (dv.setUint16(o, m, true), (o += 2));
  for (const f of frames) for (const p of f.phase) (dv.setInt16(o, p, true), (o += 2));
  if (local) {
    out.set([0x4c, 0x4f, 0x43, 0], o); // "LOC", a zero byte
    dv.setUint32(o + 4, n, true);
    o += LOCAL_HEAD_BYTES;
    for (let i = 0; i < n; i++) dv.setUint16(o + 2 * i, local.az[i], true);
    for (let i = 0; i < n; i++) dv.setInt16(o + 2 * n + 2 * i, local.el[i], true);
    out.set(local.desc.subarray(0, 32 * n), o + 4 * n);
  }
  return out;
}

/** The local block of a version-2 record (the checks are the server's; this trusts the record), or null. */
export function recordLocal(rec: Uint8Array): LocalBlock | null {
  const dv = new DataView(rec.buffer, rec.byteOffset, rec.byteLength);
  if (dv.getUint8(HEADER_AT.version) !== LOCAL_VERSION) return null;
  const ck = dv.getUint16(HEADER_AT.curves, true) * dv.getUint16(HEADER_AT.harmonics, true);
  return localBlock(rec.subarray(HEADER_BYTES + BYTES_PER_HARMONIC * ck * dv.getUint32(HEADER_AT.frames, true)));
}

/**
 * The share of `want`'s keypoints that `got` holds alike: within a unit of bearing (a rounding
 * tie) and with the same descriptor, in any order. How the phone's keypoints are held to the
 * engine's (the golden tests, in Node and in Chromium).
 */
export function keypointsAlike(got: LocalBlock, want: LocalBlock): number {
  let same = 0;
  for (let i = 0; i < want.az.length; i++) {
    let hit = false;
    for (let j = 0; j < got.az.length && !hit; j++)
      hit =
        Math.abs(got.az[j] - want.az[i]) <= 1 &&
        Math.abs(got.el[j] - want.el[i]) <= 1 &&
        want.desc.subarray(32 * i, 32 * i + 32).every((b, k) => b === got.desc[32 * j + k]);
    same += hit ? 1 : 0;
  }
  return want.az.length ? same / want.az.length : 1;
}

/** A local block's bytes (its head first) -> its keypoints. */
export function localBlock(b: Uint8Array): LocalBlock {
  const dv = new DataView(b.buffer, b.byteOffset, b.byteLength);
  const n = dv.getUint32(4, true);
  const o = LOCAL_HEAD_BYTES;
  const az = new Uint16Array(n);
  const el = new Int16Array(n);
  for (let i = 0; i < n; i++) {
    az[i] = dv.getUint16(o + 2 * i, true);
    el[i] = dv.getInt16(o + 2 * n + 2 * i, true);
  }
  return { az, el, desc: b.slice(o + 4 * n, o + 4 * n + 32 * n) };
}

/** One frame's spectrum out of a binary record (the checks are the server's; this trusts the record). */
export function recordFrame(rec: Uint8Array, frame = 0): FrameSpectrum {
  const dv = new DataView(rec.buffer, rec.byteOffset, rec.byteLength);
  const ck = dv.getUint16(HEADER_AT.curves, true) * dv.getUint16(HEADER_AT.harmonics, true);
  const nf = dv.getUint32(HEADER_AT.frames, true);
  const mag = new Uint16Array(ck);
  const phase = new Int16Array(ck);
  for (let i = 0; i < ck; i++) {
    mag[i] = dv.getUint16(HEADER_BYTES + 2 * (frame * ck + i), true);
    phase[i] = dv.getInt16(HEADER_BYTES + 2 * nf * ck + 2 * (frame * ck + i), true);
  }
  return { mag, phase };
}

/** Relative error ||a - b|| / ||b|| of two quantised spectra (as complex vectors). */
export function relativeError(a: FrameSpectrum, b: FrameSpectrum): number {
  const x = dequantise(a);
  const y = dequantise(b);
  let num = 0;
  let den = 0;
  for (let i = 0; i < x.re.length; i++) {
    num += (x.re[i] - y.re[i]) ** 2 + (x.im[i] - y.im[i]) ** 2;
    den += y.re[i] ** 2 + y.im[i] ** 2;
  }
  return Math.sqrt(num / Math.max(den, 1e-30));
}
