// Feature extraction in headless Chromium (the app's own worker: ImageBitmap -> OffscreenCanvas ->
// the worker's extractor -> record) per 960x720 donut frame, against the Python engine's extractor
// on the same frames in the same run (the baseline); and the local features of a frame (a verifying
// venue's keypoints) beside the engine's. Prints the machine it ran on.
//   node bench/web_extract.mjs [repeats] [--baseline DIR]
// With --baseline, an older version is timed beside this one, frame by frame in turns (ABBA), so
// that a busy machine slows both alike: DIR/web is its web app built (`npx vite build --outDir
// DIR/web` in web/ of that version), DIR/engine a copy of its backend/omninav package. The current
// web app is the one `npm run build` left in web/dist.
import { execFileSync } from 'node:child_process';
import { readdirSync } from 'node:fs';
import { cpus, totalmem } from 'node:os';
import { resolve } from 'node:path';
import { chromium } from 'playwright-core';
import { startServer } from '../e2e/server.cjs';

const ROOT = resolve(import.meta.dirname, '..');
const WORK = resolve(ROOT, 'data/bench-web');
const GOLDEN = resolve(WORK, 'golden');
const PY = resolve(ROOT, '.venv/bin/python');
const args = process.argv.slice(2);
const at = args.indexOf('--baseline');
const BASE = at >= 0 ? resolve(args.splice(at, 2)[1]) : null;
const repeats = Number(args[0] ?? 200);
const WARM = 10;
const pct = (xs, q) => xs.slice().sort((a, b) => a - b)[Math.floor((xs.length - 1) * q)];
const fmt = (xs) => `median ${pct(xs, 0.5).toFixed(2)} ms, p90 ${pct(xs, 0.9).toFixed(2)} ms`;
const workerOf = (dist) => readdirSync(resolve(dist, 'assets')).find((f) => /^worker-.*\.js$/.test(f));

execFileSync(PY, [resolve(ROOT, 'e2e/fixtures.py'), 'golden', GOLDEN], { stdio: 'inherit' });

// the engine: its Extractor on the same three frames, single-threaded, same count (and the
// baseline's, in turns, when given)
const { ms: engine, local: engineLocal } = JSON.parse(
  execFileSync(PY, [
    '-c',
    `
import importlib.util, json, time, cv2, sys
from threadpoolctl import threadpool_limits
from omninav.extract import Extractor
from omninav.lens import lens_from_dict
from omninav.presets import resolve
cv2.setNumThreads(1)
g = json.load(open(sys.argv[1] + "/golden.json"))["cases"][0]
exts = [Extractor(lens_from_dict(g["lens"]), resolve("default"))]
if sys.argv[3]:
    spec = importlib.util.spec_from_file_location("omninav_base", sys.argv[3] + "/__init__.py", submodule_search_locations=[sys.argv[3]])
    sys.modules["omninav_base"] = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(sys.modules["omninav_base"])
    from omninav_base.extract import Extractor as Base
    from omninav_base.lens import lens_from_dict as base_lens
    exts.append(Base(base_lens(g["lens"]), resolve("default")))
frames = [cv2.imread(sys.argv[1] + "/" + f["stem"] + ".png") for f in g["frames"]]
ms = [[] for _ in exts]
with threadpool_limits(1):
    for i in range(${WARM} + int(sys.argv[2])):
        order = range(len(exts)) if i % 2 == 0 else reversed(range(len(exts)))
        for k in order:
            t = time.perf_counter(); exts[k].spectrum(frames[i % len(frames)]); dt = (time.perf_counter() - t) * 1e3
            if i >= ${WARM}: ms[k].append(dt)
from omninav.verify import detect
lens = lens_from_dict(g["lens"])
local = []
for i in range(${WARM} + int(sys.argv[2])):
    t = time.perf_counter(); detect(frames[i % len(frames)], lens, 900); dt = (time.perf_counter() - t) * 1e3
    if i >= ${WARM}: local.append(dt)
print(json.dumps({"ms": ms, "local": local}))
`,
    GOLDEN,
    String(repeats),
    BASE ? resolve(BASE, 'engine') : '',
  ]).toString(),
);

// the browser: the server serves web/dist as `npm start` does; the golden files (and the baseline's
// build) are routed in
const srv = await startServer(resolve(WORK, 'server'), {
  args: ['--demo', 'none', '--workers', '1'],
  env: { OMNINAV_ADMIN_TOKEN: 'bench-token-0123456789' },
});
const port = srv.port;
try {
  const browser = await chromium.launch({
    executablePath: process.env.CHROMIUM ?? '/usr/bin/chromium',
    args: [
      '--disable-gpu',
      '--no-first-run',
      '--disable-background-networking',
      '--disable-component-update',
      '--disable-sync',
    ],
  });
  const page = await browser.newPage();
  await page.route(
    (u) => u.pathname.startsWith('/golden/'),
    (r) => r.fulfill({ path: resolve(GOLDEN, new URL(r.request().url()).pathname.split('/').pop()) }),
  );
  if (BASE)
    await page.route(
      (u) => u.pathname.startsWith('/baseline/'),
      (r) => r.fulfill({ path: resolve(BASE, 'web', new URL(r.request().url()).pathname.slice('/baseline/'.length)) }),
    );
  const t0 = Date.now();
  let r;
  let browserMs;
  if (!BASE) {
    await page.goto(`http://127.0.0.1:${port}/selftest.html?golden=/golden/golden.json&repeats=${repeats}`);
    r = await page.evaluate(() => window.selftest);
    browserMs = [null];
  } else {
    await page.goto(`http://127.0.0.1:${port}/selftest.html`);
    const urls = [
      `/assets/${workerOf(resolve(ROOT, 'web/dist'))}`,
      `/baseline/assets/${workerOf(resolve(BASE, 'web'))}`,
    ];
    browserMs = await page.evaluate(turns, { urls, repeats, warm: WARM });
  }
  const version = browser.version();
  await browser.close();
  console.log(
    `machine: ${cpus()[0].model}, ${cpus().length} cores, ${(totalmem() / 2 ** 30).toFixed(0)} GiB; Chromium ${version} headless, no GPU`,
  );
  if (r) {
    const rec = r.cases[0].frames[0].mag.length * 4;
    console.log(
      `frames: ${r.timing.width}x${r.timing.height} donut, preset default; ${r.timing.frames} frames each side (after ${r.cases.reduce((n, c) => n + c.frames.length, 0)} warm-up)`,
    );
    console.log(
      `opencv.js load + init in the worker: ${r.loadMs.toFixed(0)} ms; self-test wall ${((Date.now() - t0) / 1000).toFixed(1)} s`,
    );
    console.log(
      `browser worker, per frame (draw + getImageData + extraction + quantise): median ${r.timing.medianMs.toFixed(2)} ms, p90 ${r.timing.p90Ms.toFixed(2)} ms`,
    );
    console.log(`engine (Python, NumPy + OpenCV, 1 thread), per frame: ${fmt(engine[0])}`);
    console.log(`ratio browser / engine (median): ${(r.timing.medianMs / pct(engine[0], 0.5)).toFixed(2)}`);
    console.log(`record: ${rec} bytes per frame + 20-byte header; a 10-frame clip sends ${20 + 10 * rec} bytes`);
    console.log(
      `local features (worker/local.ts: grey, remap, ORB 900), the last frame of a press: browser ${r.local.timing.frames} frames median ${r.local.timing.medianMs.toFixed(2)} ms, p90 ${r.local.timing.p90Ms.toFixed(2)} ms; engine (verify.detect, 1 thread) ${fmt(engineLocal)}`,
    );
  } else {
    console.log(
      `960x720 donut frames, preset default; ${repeats} frames each, in turns (after ${WARM} warm-up each); wall ${((Date.now() - t0) / 1000).toFixed(1)} s`,
    );
    console.log(`browser worker, per frame (draw + getImageData + extraction + quantise):`);
    console.log(`  this version: ${fmt(browserMs[0])}`);
    console.log(`  baseline:     ${fmt(browserMs[1])}`);
    console.log(`engine (Python, NumPy + OpenCV, 1 thread), per frame:`);
    console.log(`  this version: ${fmt(engine[0])}`);
    console.log(`  baseline:     ${fmt(engine[1])}`);
  }
} finally {
  await srv.stop();
}

/**
 * In the page: a feature worker per URL, each fed the first golden case's frames in turns (ABBA),
 * as the self-test feeds its one; -> each worker's own per-frame times (the `ms` it reports).
 * @param {{ urls: string[]; repeats: number; warm: number }} o
 */
async function turns({ urls, repeats, warm }) {
  const { cases } = await (await fetch('/golden/golden.json')).json();
  const c = cases[0];
  const bms = await Promise.all(
    c.frames.map(async (f) =>
      createImageBitmap(await (await fetch(`/golden/${f.stem}.png`)).blob(), {
        colorSpaceConversion: 'none',
        premultiplyAlpha: 'none',
      }),
    ),
  );
  const call = (w, m, transfer = []) =>
    new Promise((res, rej) => {
      w.onmessage = (e) => (e.data.type === 'error' ? rej(new Error(e.data.message)) : res(e.data));
      w.postMessage(m, transfer);
    });
  const workers = urls.map((u) => new Worker(u, { type: 'module' }));
  for (const w of workers) await call(w, { type: 'init', id: 0, lens: c.lens, settings: c.settings });
  const canvas = new OffscreenCanvas(bms[0].width, bms[0].height);
  const cx = canvas.getContext('2d');
  const ms = workers.map(() => []);
  for (let i = 0; i < warm + repeats; i++) {
    const order = i % 2 ? [...workers.keys()].reverse() : [...workers.keys()];
    for (const k of order) {
      cx.drawImage(bms[i % bms.length], 0, 0);
      const bm = await createImageBitmap(canvas);
      const r = await call(workers[k], { type: 'frame', id: i + 1, bitmap: bm }, [bm]);
      if (i >= warm) ms[k].push(r.ms);
    }
  }
  for (const w of workers) w.terminate();
  return ms;
}
