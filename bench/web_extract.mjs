// Feature extraction in headless Chromium (the app's own worker: ImageBitmap -> OffscreenCanvas ->
// opencv.js WebAssembly -> record) per 960x720 donut frame, against the Python engine's extractor
// on the same frames in the same run (the baseline). Prints the machine it ran on.
//   node bench/web_extract.mjs [repeats]
import { execFileSync } from 'node:child_process';
import { cpus, totalmem } from 'node:os';
import { resolve } from 'node:path';
import { chromium } from 'playwright-core';
import { startServer } from '../e2e/server.cjs';

const ROOT = resolve(import.meta.dirname, '..');
const WORK = resolve(ROOT, 'data/bench-web');
const GOLDEN = resolve(WORK, 'golden');
const PY = resolve(ROOT, '.venv/bin/python');
const repeats = Number(process.argv[2] ?? 200);
const pct = (xs, q) => xs.slice().sort((a, b) => a - b)[Math.floor((xs.length - 1) * q)];

execFileSync(PY, [resolve(ROOT, 'e2e/fixtures.py'), 'golden', GOLDEN], { stdio: 'inherit' });

// baseline: the engine's Extractor on the same three frames, single-threaded, same count
const py = JSON.parse(
  execFileSync(PY, [
    '-c',
    `
import json, time, cv2, sys
from threadpoolctl import threadpool_limits
from omninav.extract import Extractor
from omninav.lens import lens_from_dict
from omninav.presets import resolve
cv2.setNumThreads(1)
g = json.load(open(sys.argv[1] + "/golden.json"))["cases"][0]
ext = Extractor(lens_from_dict(g["lens"]), resolve("default"))
frames = [cv2.imread(sys.argv[1] + "/" + f["stem"] + ".png") for f in g["frames"]]
ms = []
with threadpool_limits(1):
    for i in range(int(sys.argv[2])):
        t = time.perf_counter(); ext.spectrum(frames[i % len(frames)]); ms.append((time.perf_counter() - t) * 1e3)
print(json.dumps(ms))
`,
    GOLDEN,
    String(repeats),
  ]).toString(),
);

// the browser: the server serves web/dist as `npm start` does; the golden files are routed in
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
  await page.goto(`http://127.0.0.1:${port}/selftest.html?golden=/golden/golden.json&repeats=${repeats}`);
  const t0 = Date.now();
  const r = await page.evaluate(() => window.selftest);
  const version = browser.version();
  await browser.close();
  const rec = r.cases[0].frames[0].mag.length * 4;
  console.log(
    `machine: ${cpus()[0].model}, ${cpus().length} cores, ${(totalmem() / 2 ** 30).toFixed(0)} GiB; Chromium ${version} headless, no GPU`,
  );
  console.log(
    `frames: ${r.timing.width}x${r.timing.height} donut, preset default; ${r.timing.frames} frames each side (after ${r.cases.reduce((n, c) => n + c.frames.length, 0)} warm-up)`,
  );
  console.log(
    `opencv.js load + init in the worker: ${r.loadMs.toFixed(0)} ms; self-test wall ${((Date.now() - t0) / 1000).toFixed(1)} s`,
  );
  console.log(
    `browser worker, per frame (draw + getImageData + remap + curves + dft + quantise): median ${r.timing.medianMs.toFixed(2)} ms, p90 ${r.timing.p90Ms.toFixed(2)} ms`,
  );
  console.log(
    `engine (Python, NumPy + OpenCV, 1 thread), per frame: median ${pct(py, 0.5).toFixed(2)} ms, p90 ${pct(py, 0.9).toFixed(2)} ms`,
  );
  console.log(`ratio browser / engine (median): ${(r.timing.medianMs / pct(py, 0.5)).toFixed(2)}`);
  console.log(`record: ${rec} bytes per frame + 20-byte header; a 10-frame clip sends ${20 + 10 * rec} bytes`);
} finally {
  await srv.stop();
}
