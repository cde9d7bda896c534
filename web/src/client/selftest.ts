/**
 * Self-test page: runs reference frames through the real feature worker (the same path as camera
 * frames: ImageBitmap -> OffscreenCanvas -> opencv.js) and reports the spectra and the timing.
 * The end-to-end tests feed it the engine's golden files and compare; anyone can open it on a phone
 * to time extraction there: `selftest.html?golden=<url of golden.json>`.
 */
import { ExtractorClient, type FrameResult } from './bridge';
import type { Lens } from '../shared/lens';
import type { FeatureSettings } from '../shared/settings';

interface Case {
  name: string;
  lens: Lens;
  settings: FeatureSettings;
  frames: { stem: string }[];
}

/** A golden frame's local features as the engine made them (e2e/fixtures.py `_local_case`). */
interface LocalCase {
  name: string;
  lens: Lens;
  n_features: number;
  frames: { stem: string; rgba: string }[];
}

export interface SelfTestResult {
  loadMs: number;
  /** Each golden frame's local features from the worker, and their timing on the donut frames. */
  local: {
    frames: { stem: string; az: number[]; el: number[]; desc: number[]; ms: number }[];
    timing: { frames: number; medianMs: number; p90Ms: number };
  };
  cases: { name: string; frames: { stem: string; mag: number[]; phase: number[]; curves: number[]; ms: number }[] }[];
  timing: { frames: number; medianMs: number; p90Ms: number; width: number; height: number };
}

declare global {
  interface Window {
    selftest?: Promise<SelfTestResult>;
  }
}

async function bitmap(url: string): Promise<ImageBitmap> {
  const blob = await (await fetch(url)).blob();
  // no colour management: the pixels must be the file's bytes, as the engine reads them
  return createImageBitmap(blob, { colorSpaceConversion: 'none', premultiplyAlpha: 'none' });
}

async function run(base: string, repeats: number): Promise<SelfTestResult> {
  const golden = await (await fetch(`${base}/golden.json`)).json();
  const cases: Case[] = golden.cases;
  const ext = new ExtractorClient();
  const out: SelfTestResult = {
    loadMs: 0,
    local: { frames: [], timing: { frames: 0, medianMs: 0, p90Ms: 0 } },
    cases: [],
    timing: { frames: 0, medianMs: 0, p90Ms: 0, width: 0, height: 0 },
  };
  for (const c of cases) {
    const loadMs = await ext.configure(c.lens, c.settings);
    out.loadMs ||= loadMs;
    const frames = [];
    for (const f of c.frames) {
      const r: FrameResult = await ext.extract(await bitmap(`${base}/${f.stem}.png`), true);
      frames.push({
        stem: f.stem,
        mag: Array.from(r.mag),
        phase: Array.from(r.phase),
        curves: Array.from(r.curves ?? []),
        ms: r.ms,
      });
    }
    out.cases.push({ name: c.name, frames });
  }
  // timing: the first case's lens (960x720 donut), its frames over and over, as a camera would
  const c = cases[0];
  await ext.configure(c.lens, c.settings);
  const bms = await Promise.all(c.frames.map((f) => bitmap(`${base}/${f.stem}.png`)));
  const ms: number[] = [];
  for await (const bm of camera(bms, repeats)) ms.push((await ext.extract(bm)).ms);
  out.local = await local(ext, base, golden.local ?? [], cases, repeats);
  out.timing = { ...spread(ms), width: bms[0].width, height: bms[0].height };
  return out;
}

/** `bms` in turn, `repeats` frames, each a fresh bitmap (extract() takes and closes its own), as a camera gives them. */
async function* camera(bms: ImageBitmap[], repeats: number): AsyncGenerator<ImageBitmap> {
  const canvas = new OffscreenCanvas(bms[0].width, bms[0].height);
  const cx = canvas.getContext('2d')!;
  for (let i = 0; i < repeats; i++) {
    cx.drawImage(bms[i % bms.length], 0, 0);
    yield await createImageBitmap(canvas);
  }
}

/** Times in ms -> their count, median and 90th percentile. */
function spread(ms: number[]): { frames: number; medianMs: number; p90Ms: number } {
  const s = ms.slice().sort((a, b) => a - b);
  return { frames: s.length, medianMs: s[s.length >> 1] ?? 0, p90Ms: s[Math.floor(s.length * 0.9)] ?? 0 };
}

/**
 * The local features of each golden frame (extracted first: the worker takes them of the last
 * frame it extracted), then their time on the donut frames, `repeats` times in turn.
 */
async function local(
  ext: ExtractorClient,
  base: string,
  lcases: LocalCase[],
  cases: Case[],
  repeats: number,
): Promise<SelfTestResult['local']> {
  const frames = [];
  const ms: number[] = [];
  for (const lc of lcases) {
    await ext.configure(lc.lens, cases[0].settings);
    await ext.prepareLocal(lc.n_features);
    for (const f of lc.frames) {
      const fr = await ext.extract(await bitmap(`${base}/${f.rgba}.png`));
      const r = await ext.local(fr.id!);
      frames.push({ stem: f.stem, az: Array.from(r.az), el: Array.from(r.el), desc: Array.from(r.desc), ms: r.ms });
    }
  }
  const lc = lcases[0];
  if (lc) {
    await ext.configure(lc.lens, cases[0].settings);
    await ext.prepareLocal(lc.n_features); // the detector made here, not in the first timed frame
    const bms = await Promise.all(lc.frames.map((f) => bitmap(`${base}/${f.rgba}.png`)));
    for await (const bm of camera(bms, repeats)) ms.push((await ext.local((await ext.extract(bm)).id!)).ms);
  }
  return { frames, timing: spread(ms) };
}

const params = new URLSearchParams(location.search);
const golden = params.get('golden');
const el = document.getElementById('result')!;
if (golden) {
  window.selftest = run(golden.replace(/\/golden\.json$/, ''), Number(params.get('repeats') ?? 60));
  window.selftest.then(
    (r) =>
      (el.textContent =
        `Done: extraction ${r.timing.medianMs.toFixed(1)} ms per ${r.timing.width}x${r.timing.height} frame ` +
        `(median of ${r.timing.frames}); local features ${r.local.timing.medianMs.toFixed(1)} ms a frame.`),
    (e) => (el.textContent = `Failed: ${e}`),
  );
} else {
  el.textContent = 'Give the reference data with ?golden=<url of golden.json>.';
}
