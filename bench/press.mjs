// "Where am I?" pressed -> the first word spoken, as a user meets it: a fresh Chromium with a fake
// camera playing a 960x720 donut clip of the demo venue, the app served by a real `omninav serve`,
// the button clicked `--presses` times. The first press finds the camera closed; the later ones find
// it open (the locate screen stays open between them). Measured in the page from the click to the
// first `speechSynthesis.speak` of words, and to the spoken answer ("You are ..."). Prints the
// machine it ran on.
//
//   node bench/press.mjs [--presses 5] [--baseline REV] [--busy] [--gap-ms 3000]
//
// `--baseline REV`: the web app built from commit REV (a git worktree under /tmp) is measured in
// the same run, against the same server, each press of one beside the other's; the pages are
// routed to each build's files, so that only the app differs. `--busy`: one process spins on one
// of the cores all along (a server's other worker or the job runner, as on a loaded machine).
import { execFileSync, spawn } from 'node:child_process';
import { existsSync, readFileSync, symlinkSync } from 'node:fs';
import { cpus, totalmem } from 'node:os';
import { extname, join, resolve } from 'node:path';
import { chromium } from 'playwright-core';
import { startServer, waitModelled } from '../e2e/server.cjs';

const ROOT = resolve(import.meta.dirname, '..');
const WORK = resolve(ROOT, 'data/bench-press');
const PY = resolve(ROOT, '.venv/bin/python');
const arg = (name, dflt) => {
  const i = process.argv.indexOf(`--${name}`);
  return i < 0 ? dflt : process.argv[i + 1];
};
const presses = Number(arg('presses', 5));
const gapMs = Number(arg('gap-ms', 3000));
const baseline = arg('baseline', null);
const busy = process.argv.includes('--busy');
const median = (xs) => xs.slice().sort((a, b) => a - b)[xs.length >> 1];

/** web/dist of commit `rev`, built once in a worktree of its own (this checkout's node_modules). */
function baselineDist(rev) {
  const sha = execFileSync('git', ['rev-parse', '--short', rev], { cwd: ROOT }).toString().trim();
  const dir = `/tmp/omninav-press-${sha}`;
  if (!existsSync(join(dir, 'web/dist/index.html'))) {
    if (!existsSync(dir)) execFileSync('git', ['worktree', 'add', '-f', dir, sha], { cwd: ROOT, stdio: 'inherit' });
    if (!existsSync(join(dir, 'node_modules'))) symlinkSync(join(ROOT, 'node_modules'), join(dir, 'node_modules'));
    execFileSync('npm', ['run', 'build', '-w', 'web'], { cwd: dir, stdio: 'inherit' });
  }
  return { name: `baseline ${sha}`, dist: join(dir, 'web/dist') };
}

const TYPES = {
  '.html': 'text/html',
  '.js': 'text/javascript',
  '.css': 'text/css',
  '.json': 'application/json',
  '.webmanifest': 'application/manifest+json',
  '.svg': 'image/svg+xml',
  '.png': 'image/png',
  '.wasm': 'application/wasm',
};

execFileSync(PY, [resolve(ROOT, 'e2e/fixtures.py'), 'clip', resolve(WORK, 'clip')], { stdio: 'inherit' });
const builds = [{ name: 'this tree', dist: resolve(ROOT, 'web/dist') }];
if (baseline) builds.push(baselineDist(baseline));
const srv = await startServer(resolve(WORK, 'server'), {
  args: ['--demo', 'quick', '--workers', '2'],
  env: { OMNINAV_ADMIN_TOKEN: 'bench-token-0123456789' },
});
const spinner = busy ? spawn(process.execPath, ['-e', 'for(;;){}'], { stdio: 'ignore' }) : null;
const results = builds.map(() => ({ first: [], word: [], answer: [], said: [], marks: [], duty: [], extract: [] }));
try {
  await waitModelled(srv.url, 'demo');
  const browser = await chromium.launch({
    executablePath: process.env.CHROMIUM ?? '/usr/bin/chromium',
    args: [
      '--use-fake-device-for-media-stream',
      `--use-file-for-fake-video-capture=${resolve(WORK, 'clip/clip.y4m')}`,
      '--disable-gpu',
      '--no-first-run',
      '--disable-background-networking',
      '--disable-component-update',
      '--disable-sync',
    ],
  });
  // each round: every build in a fresh context (its own worker and camera), one after the other
  for (let round = 0; round < 2; round++) {
    for (const [b, build] of builds.entries()) {
      const ctx = await browser.newContext({ permissions: ['camera'], serviceWorkers: 'block' });
      const page = await ctx.newPage();
      await page.route(`${srv.url}/**`, async (route) => {
        const path = new URL(route.request().url()).pathname;
        if (path.startsWith('/api/')) return route.continue();
        const file = join(build.dist, path === '/' ? 'index.html' : path);
        if (!existsSync(file)) return route.continue();
        return route.fulfill({
          body: readFileSync(file),
          contentType: TYPES[extname(file)] ?? 'application/octet-stream',
        });
      });
      await page.addInitScript(() => {
        window.__said = [];
        const speak = speechSynthesis.speak.bind(speechSynthesis);
        speechSynthesis.speak = (u) => {
          if (u.text.trim()) window.__said.push({ t: performance.now(), text: u.text });
          speak(u);
        };
      });
      await page.goto(`${srv.url}/?venue=demo`);
      await page.locator('#venue-line').getByText('Ready').waitFor({ timeout: 60_000 });
      await page.waitForTimeout(1500); // the worker's WebAssembly compiled, as when a user opens the app
      const where = page.locator('#where');
      for (let i = 0; i < presses; i++) {
        await page.locator('#where:not([aria-busy])', { hasText: 'Where am I?' }).waitFor();
        await page.waitForTimeout(i ? gapMs : 0);
        const t0 = await page.evaluate(() => {
          window.__said = [];
          performance.clearMarks();
          return performance.now();
        });
        await where.click();
        const said = await page.waitForFunction(
          () => window.__said.find((s) => /^You are|^Not sure where/.test(s.text)) && window.__said,
          null,
          { timeout: 30_000 },
        );
        const list = await said.jsonValue();
        const answer = list.find((s) => /^You are|^Not sure where/.test(s.text));
        // the app's own marks (session.ts): where the press's time went
        const marks = await page.evaluate(() =>
          performance.getEntriesByType('mark').map((m) => [m.name.replace('omninav: ', ''), m.startTime]),
        );
        const r = results[b];
        if (i === presses - 1) {
          const facts = (await page.locator('#debug-facts').textContent()) ?? '';
          const duty = /the worker busy (\d+) %/.exec(facts);
          if (duty) r.duty.push(Number(duty[1]));
          const ext = /([\d.]+) ms per frame \(median\)/.exec(facts);
          if (ext) r.extract.push(Number(ext[1]));
        }
        if (!i) r.marks.push(marks.map(([name, t]) => `${name} ${((t - t0) / 1000).toFixed(2)}`).join(', '));
        (i ? r.word : r.first).push(list[0].t - t0);
        if (i) r.answer.push(answer.t - t0);
        r.said.push(answer.text.slice(0, 40));
      }
      await ctx.close();
    }
  }
  await browser.close();
} finally {
  spinner?.kill();
  await srv.stop();
}

const cpu = cpus()[0]?.model ?? 'unknown CPU';
console.log(
  `\n${cpu}, ${cpus().length} cores, ${(totalmem() / 2 ** 30).toFixed(0)} GiB; Chromium (headless), ` +
    `fake 960x720 camera, the quick demo venue, ${presses} presses x 2 fresh pages per build, ` +
    `${gapMs} ms between presses${busy ? ', one core kept busy' : ''}`,
);
console.log(
  '| build | first press (camera closed): first word | later presses: first word, median (range) | later: the answer, median |',
);
console.log('| --- | ---: | ---: | ---: |');
for (const [b, build] of builds.entries()) {
  const r = results[b];
  const s = (x) => `${(x / 1000).toFixed(2)} s`;
  for (const m of r.marks) console.error(`${build.name}, a first press: ${m || '(no marks)'}`);
  if (r.duty.length)
    console.error(
      `${build.name}: standing by, the worker busy ${r.duty.join(', ')} % of the time; extraction ${r.extract.join(', ')} ms a frame (median)`,
    );
  console.log(
    `| ${build.name} | ${r.first.map(s).join(', ')} | ${s(median(r.word))} (${s(Math.min(...r.word))}-${s(Math.max(...r.word))}) | ${s(median(r.answer))} |`,
  );
}
