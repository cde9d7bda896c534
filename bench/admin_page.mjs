// Upload throughput through the admin page (the videos screen's resumable upload in pieces, in
// headless Chromium) against curl's one PUT of the same file to the same server, both ending when
// the server has checked the whole file. The file is a real walk video (the admin e2e fixture's
// walk, its frames repeated up to the size asked), since the server refuses what does not decode.
// The page's pieces are sent at its own size (about 4 pieces) and, in turn, at the size it used
// before (about 16 pieces: the page's ?piece= for tests and benchmarks), for a before and after on
// one machine at one time; the same pieces from Node's fetch separate their cost from the browser's.
// Prints the machine it ran on. (ES module, like bench/web_extract.mjs: Node 20 runs no .ts.)
//   node bench/admin_page.mjs [MB] [repeats] [LINK_MB_S]
// LINK_MB_S: a link of that many MB/s for both (curl --limit-rate; Chromium's network emulation),
// as over Wi-Fi; without it, loopback, where the machine's CPU is the limit.
import { execFileSync } from 'node:child_process';
import { existsSync, readFileSync, statSync } from 'node:fs';
import { cpus, totalmem } from 'node:os';
import { resolve } from 'node:path';
import { chromium } from 'playwright-core';
import { startServer } from '../e2e/server.cjs';

const ROOT = resolve(import.meta.dirname, '..');
const WORK = resolve(ROOT, 'data/bench-admin');
const FIX = resolve(WORK, 'fixture');
const PY = resolve(ROOT, '.venv/bin/python');
const TOKEN = 'bench-admin-token-0123456789';
const MB = Number(process.argv[2] ?? 100);
const repeats = Number(process.argv[3] ?? 3);
const link = process.argv[4] ? Number(process.argv[4]) : null;
const median = (xs) => xs.slice().sort((a, b) => a - b)[Math.floor((xs.length - 1) / 2)];

execFileSync(PY, [resolve(ROOT, 'e2e/fixtures.py'), 'admin', FIX], { stdio: 'inherit' });
const big = resolve(WORK, `walk-${MB}MB.mp4`);
if (!existsSync(big))
  execFileSync(PY, [
    '-c',
    `
import sys, cv2
src, out, want = sys.argv[1], sys.argv[2], int(sys.argv[3]) * 1_000_000
cap = cv2.VideoCapture(src); frames = []
while True:
    ok, f = cap.read()
    if not ok: break
    frames.append(f)
h, w = frames[0].shape[:2]
vw = cv2.VideoWriter(out, cv2.VideoWriter.fourcc(*"mp4v"), 10.0, (w, h))
# the walk forwards and back, again and again, until the file is about as big as asked
import os
need = want * len(frames) // os.path.getsize(src)
loop = frames + frames[::-1]
for n in range(need):
    vw.write(loop[n % len(loop)])
vw.release()
`,
    resolve(FIX, 'walk.mp4'),
    big,
    String(MB),
  ]);
const size = statSync(big).size;

const srv = await startServer(resolve(WORK, 'server'), {
  args: ['--demo', 'none', '--workers', '2'],
  env: { OMNINAV_ADMIN_TOKEN: TOKEN },
  fresh: true,
});
const H = { Authorization: `Bearer ${TOKEN}`, 'Content-Type': 'application/json' };
const call = async (method, path, body) => {
  const r = await fetch(`${srv.url}${path}`, { method, headers: H, body: body && JSON.stringify(body) });
  if (!r.ok) throw new Error(`${method} ${path}: ${r.status} ${await r.text()}`);
  return r.json();
};
const V = '/api/admin/venues/bench';
// the page's piece size (web/src/admin/upload.ts pieceSize): about 4 pieces, 1 MiB to 64 MiB; and
// the one it had before (about 16 pieces, 256 KiB to 8 MiB), sent by the same page with ?piece=
const piece = Math.min(64 << 20, Math.max(1 << 20, Math.ceil(size / 4 / 65536) * 65536));
const oldPiece = Math.min(8 << 20, Math.max(256 << 10, Math.ceil(size / 16 / 65536) * 65536));
const kinds = [
  ['old', oldPiece],
  ['new', piece],
];
const out = { curl: [], pieces: { old: [], new: [] }, page: { old: [], new: [] } };
let browser;
try {
  await call('POST', '/api/admin/venues', { id: 'bench', name: 'Upload bench' });
  const lens = JSON.parse(readFileSync(resolve(FIX, 'lens.json'), 'utf8'));
  await call('PUT', `${V}/lenses/donut`, lens);
  const bytes = readFileSync(big);
  browser = await chromium.launch({
    executablePath: process.env.CHROMIUM ?? '/usr/bin/chromium',
    args: ['--disable-gpu'],
  });

  // after each upload: no job left running (the page starts one to find the turns and stops, which
  // reads the whole video), the video deleted and the disk synced: no upload pays for the one before
  const quiet = async (name) => {
    for (let t = 0; t < 600; t++) {
      const { jobs } = await call('GET', `${V}/jobs`);
      const active = jobs.filter((j) => j.state === 'queued' || j.state === 'running');
      if (!active.length) break;
      for (const j of active) await call('POST', `/api/admin/jobs/${j.id}/cancel`).catch(() => {});
      await new Promise((r) => setTimeout(r, 100));
    }
    await call('DELETE', `${V}/videos/${name}`);
    execFileSync('sync');
  };

  // curl: one PUT of the whole file, as the README's API example does
  const curl = async (i) => {
    const name = `curl-${i}.mp4`;
    await call('POST', `${V}/videos`, { name, size, lens: 'donut' });
    const t = execFileSync('curl', [
      ...(link ? ['--limit-rate', `${Math.round(link * 1e6)}`] : []),
      ...['-sS', '-o', '/dev/null', '-w', '%{time_total}', '-X', 'PUT', '--data-binary', `@${big}`],
      ...['-H', `Authorization: Bearer ${TOKEN}`, '-H', 'Content-Type: application/octet-stream'],
      ...['-H', `Content-Range: bytes 0-${size - 1}/${size}`, `${srv.url}${V}/videos/${name}/content`],
    ]);
    out.curl.push(Number(String(t)));
    await quiet(name);
  };

  // the same pieces from Node's fetch (one keep-alive connection, no browser; loopback only: fetch
  // has no rate limit): what the pieces themselves cost, apart from the browser
  const pieces = async (i, kind, piece) => {
    const name = `pieces-${kind}-${i}.mp4`;
    await call('POST', `${V}/videos`, { name, size, lens: 'donut' });
    const t0 = performance.now();
    for (let start = 0; start < size; start += piece) {
      const end = Math.min(size, start + piece);
      const r = await fetch(`${srv.url}${V}/videos/${name}/content`, {
        method: 'PUT',
        headers: {
          Authorization: `Bearer ${TOKEN}`,
          'Content-Type': 'application/octet-stream',
          'Content-Range': `bytes ${start}-${end - 1}/${size}`,
        },
        body: bytes.subarray(start, end),
      });
      if (!r.ok) throw new Error(`piece at ${start}: ${r.status} ${await r.text()}`);
      await r.arrayBuffer();
    }
    out.pieces[kind].push((performance.now() - t0) / 1000);
    await quiet(name);
  };

  // the page: sign in (the token in sessionStorage, as the sign-in screen keeps it), the videos
  // screen, the file chosen; from the first piece sent to the answer to the last
  const viaPage = async (i, kind, piece) => {
    const ctx = await browser.newContext();
    await ctx.addInitScript((t) => sessionStorage.setItem('omninav-admin-token', t), TOKEN);
    const page = await ctx.newPage();
    if (link) {
      const cdp = await ctx.newCDPSession(page);
      await cdp.send('Network.enable');
      await cdp.send('Network.emulateNetworkConditions', {
        offline: false,
        latency: 0,
        downloadThroughput: link * 1e6,
        uploadThroughput: link * 1e6,
      });
    }
    let first = 0;
    page.on('request', (r) => {
      if (r.method() === 'PUT' && r.url().endsWith('/content') && !first) first = performance.now();
    });
    const done = page.waitForResponse(
      (r) =>
        r.request().method() === 'PUT' &&
        r.url().endsWith('/content') &&
        (r.request().headers()['content-range'] ?? '').endsWith(`-${size - 1}/${size}`),
      { timeout: 600_000 },
    );
    await page.goto(`${srv.url}/admin${kind === 'old' ? `?piece=${piece}` : ''}#/v/bench/videos`);
    const input = page.getByLabel('Walk video files');
    await input.waitFor();
    // a distinct name per upload: the page names the video after the file
    const named = resolve(WORK, `page-${kind}-${i}.mp4`);
    execFileSync('ln', ['-sf', big, named]);
    await input.setInputFiles(named);
    const res = await done;
    const last = performance.now();
    if (!res.ok()) throw new Error(`the page's last piece: ${res.status()} ${await res.text()}`);
    out.page[kind].push((last - first) / 1000);
    await ctx.close();
    await quiet(`page-${kind}-${i}.mp4`);
  };

  // in turn, repeat after repeat: a machine that slows down as the run goes on (another process)
  // weighs on every kind alike
  execFileSync('sync');
  for (let i = 0; i < repeats; i++) {
    await curl(i);
    for (const [kind, piece] of kinds) {
      if (!link) await pieces(i, kind, piece);
      await viaPage(i, kind, piece);
    }
  }
} finally {
  await browser?.close();
  await srv.stop();
}

const mbps = (s) => size / 1e6 / s;
const c = median(out.curl);
const list = (xs) => `[${xs.map((s) => s.toFixed(2)).join(', ')}]`;
const line = (what, xs) =>
  console.log(`${what.padEnd(40)} median ${median(xs).toFixed(2)} s, ${mbps(median(xs)).toFixed(0)} MB/s  ${list(xs)}`);
console.log(
  `machine: ${cpus().length} x ${cpus()[0].model}, ${(totalmem() / 2 ** 30).toFixed(0)} GiB, node ${process.version}`,
);
console.log(
  `file: ${(size / 1e6).toFixed(1)} MB walk video, ${repeats} uploads each, to one omninav serve over ` +
    (link ? `a ${link} MB/s link (emulated)` : 'loopback'),
);
line('curl (one PUT):', out.curl);
for (const [kind, piece] of kinds) {
  const n = `${Math.ceil(size / piece)} PUTs of ${(piece / 2 ** 20).toFixed(2)} MiB`;
  if (out.pieces[kind].length) line(`fetch (${n}):`, out.pieces[kind]);
  line(`page, ${kind === 'old' ? 'before (?piece=)' : 'now'} (${n}):`, out.page[kind]);
}
for (const [kind] of kinds)
  console.log(
    `page / curl throughput, ${kind === 'old' ? 'before' : 'now'}: ${((100 * c) / median(out.page[kind])).toFixed(0)} % (target: at least 80 %)`,
  );
