// Route guidance (issue 14): the time from pressing Start to the first spoken instruction, in
// headless Chromium against a real `omninav serve` with the quick demo venue. The fake camera plays
// the e2e walk to the stairs (e2e/fixtures.py `walk`), standing at the entrance: the app is opened,
// the Go to screen shows the places, "the stairs" is chosen (the app opens the camera, locates once
// in a new tracking session and says the route's preview), then Start is pressed and timed, in the
// page's own clock, to the first instruction handed to the speech synthesiser. The parts: Start to
// the locate request (the second filmed and its features extracted), the request (the server's
// filter and guide, over loopback), the answer to the words spoken; and, before it, from choosing
// the place to its preview spoken (the camera opened and the lens checked first). Each run is a new
// browser (a new fake camera, a new session), the server stays up. Prints the machine it ran on.
// (ES module, like bench/admin_page.mjs: Node 20 runs no .ts.)
//   node bench/guide_start.mjs [runs]
import { execFileSync } from 'node:child_process';
import { cpus, totalmem } from 'node:os';
import { resolve } from 'node:path';
import { chromium } from 'playwright-core';
import { startServer, waitModelled } from '../e2e/server.cjs';

const ROOT = resolve(import.meta.dirname, '..');
const WORK = resolve(ROOT, 'data/bench-guide');
const PY = resolve(ROOT, '.venv/bin/python');
const runs = Number(process.argv[2] ?? 5);
const median = (xs) => xs.slice().sort((a, b) => a - b)[Math.floor((xs.length - 1) / 2)];
// an instruction in any style (directions.ts guidanceSentence), not the preview nor a passing word
const INSTRUCTION =
  /^(In \d+ metres?, )?(walk straight ahead|turn|bear|keep going|you are off the route|you have arrived)/i;

execFileSync(PY, [resolve(ROOT, 'e2e/fixtures.py'), 'walk', resolve(WORK, 'walk'), 'to-stairs'], { stdio: 'inherit' });
const clip = resolve(WORK, 'walk/to-stairs.y4m');

const srv = await startServer(resolve(WORK, 'server'), { args: ['--demo', 'quick', '--workers', '2'], fresh: true });
const out = { total: [], film: [], request: [], speak: [], preview: [] };
let version = '';
try {
  await waitModelled(srv.url, 'demo');
  for (let i = 0; i < runs; i++) {
    const browser = await chromium.launch({
      executablePath: process.env.CHROMIUM ?? '/usr/bin/chromium',
      args: [
        '--use-fake-device-for-media-stream',
        `--use-file-for-fake-video-capture=${clip}`,
        '--disable-gpu',
        '--no-first-run',
        '--disable-background-networking',
      ],
    });
    version = browser.version();
    try {
      const ctx = await browser.newContext({ permissions: ['camera'] });
      const page = await ctx.newPage();
      // the page's clock: Start's click, each locate request sent and answered, each sentence spoken
      await page.addInitScript(() => {
        const b = (window.__bench = { chose: null, start: null, said: [], sent: [], got: [] });
        document.addEventListener(
          'click',
          (e) => {
            if (!(e.target instanceof Element)) return;
            if (e.target.closest('#goto-start')) b.start = performance.now();
            if (e.target.closest('#goto-list button')) b.chose = performance.now();
          },
          true,
        );
        const speak = speechSynthesis.speak.bind(speechSynthesis);
        speechSynthesis.speak = (u) => {
          if (u.text.trim()) b.said.push({ t: performance.now(), text: u.text });
          speak(u);
        };
        const f = window.fetch.bind(window);
        window.fetch = async (input, init) => {
          const url = input instanceof Request ? input.url : String(input);
          if (!url.includes('/locate')) return f(input, init);
          b.sent.push(performance.now());
          const r = await f(input, init);
          b.got.push(performance.now());
          return r;
        };
      });
      await page.goto(`${srv.url}/?venue=demo`);
      await page.locator('#venue-line').filter({ hasText: 'Ready' }).waitFor({ timeout: 60_000 });
      await page.getByRole('button', { name: 'Go to', exact: true }).click();
      await page.getByRole('button', { name: 'the stairs', exact: true }).click();
      await page.waitForFunction(() => window.__bench.said.some((s) => s.text.startsWith('The stairs:')), null, {
        timeout: 60_000,
      });
      await page.getByRole('button', { name: 'Start' }).waitFor();
      await page.waitForFunction(() => !document.querySelector('#goto-start').disabled);
      await page.getByRole('button', { name: 'Start' }).click();
      const first = await page.waitForFunction(
        ([re, flags]) => {
          const b = window.__bench;
          const s = b.start === null ? null : b.said.find((x) => x.t >= b.start && new RegExp(re, flags).test(x.text));
          if (!s) return null;
          const sent = b.sent.find((t) => t >= b.start);
          const got = b.got.find((t) => t >= sent);
          const preview = b.said.find((x) => x.text.startsWith('The stairs:')).t;
          return { chose: b.chose, preview, start: b.start, said: s.t, text: s.text, sent, got };
        },
        [INSTRUCTION.source, INSTRUCTION.flags],
        { timeout: 60_000 },
      );
      const r = await first.jsonValue();
      out.total.push(r.said - r.start);
      out.film.push(r.sent - r.start);
      out.request.push(r.got - r.sent);
      out.speak.push(r.said - r.got);
      out.preview.push(r.preview - r.chose);
      console.log(`run ${i + 1}: ${(r.said - r.start).toFixed(0)} ms to “${r.text}”`);
    } finally {
      await browser.close();
    }
  }
} finally {
  await srv.stop();
}

const ms = (xs) => `median ${median(xs).toFixed(0)} ms  [${xs.map((x) => x.toFixed(0)).join(', ')}]`;
console.log(
  `machine: ${cpus().length} x ${cpus()[0].model}, ${(totalmem() / 2 ** 30).toFixed(0)} GiB, node ${process.version}, Chromium ${version} (headless)`,
);
console.log(`${runs} runs, each a new browser; the quick demo venue on one omninav serve (2 workers), loopback`);
console.log(`Start -> first instruction spoken:        ${ms(out.total)}`);
console.log(`  Start -> locate request (film, extract): ${ms(out.film)}`);
console.log(`  request -> answer (track, guide):        ${ms(out.request)}`);
console.log(`  answer -> spoken:                        ${ms(out.speak)}`);
console.log(`(before it: the place chosen -> its preview spoken, the camera opened: ${ms(out.preview)})`);
