// Start and stop a real `omninav serve` (the command `npm start` runs): the one such helper on the
// JavaScript side, for the e2e suite (TypeScript, loaded by Playwright) and bench/web_extract.mjs (a
// Node ES module). It is CommonJS with JSDoc types because that is the one form both load as it is:
// Playwright compiles the e2e files to CommonJS (and breaks an .mjs on the way), Node 20 cannot run
// .ts, and an ES module imports CommonJS. tsc checks it like the .ts files (checkJs in tsconfig.json).
// The Python side has its own: backend/omninav/devserver.py.
'use strict';
const { spawn } = require('node:child_process');
const { mkdirSync, rmSync } = require('node:fs');
const { createServer } = require('node:net');
const { resolve } = require('node:path');

/** The `omninav` command that scripts/setup.sh installs into .venv. */
const OMNINAV = resolve(__dirname, '..', '.venv/bin/omninav');

/** @returns {Promise<number>} a TCP port on 127.0.0.1 that nothing listens on right now */
function freePort() {
  return new Promise((res, rej) => {
    const s = createServer();
    s.listen(0, '127.0.0.1', () => {
      const port = /** @type {import('node:net').AddressInfo} */ (s.address()).port;
      s.close(() => res(port));
    });
    s.on('error', rej);
  });
}

/**
 * @typedef {object} Server
 * @property {string} url e.g. `http://127.0.0.1:41234`
 * @property {number} port
 * @property {import('node:child_process').ChildProcess} proc `omninav serve`, leader of its own process group
 * @property {() => string} log what the server has written so far (stdout and stderr)
 * @property {() => Promise<void>} stop SIGTERM to the whole process group, SIGKILL after 10 s; once stopped, nothing
 */

/**
 * @typedef {object} StartOptions
 * @property {string[]} [args] after `omninav serve --port PORT`, e.g. `['--demo', 'none']`
 * @property {Record<string, string>} [env] laid over this process's environment and `OMNINAV_DATA`
 * @property {boolean} [fresh] delete `data` first
 * @property {number} [timeoutMs] for `/api/health` to answer (default 3 minutes: `--demo quick` renders first)
 */

/**
 * `omninav serve` on the data directory `data`, in a process group of its own (so that `stop` ends
 * gunicorn's workers and the job runner too); resolves once `/api/health` answers, and rejects
 * with the server's log when it exits or does not answer in time.
 * @param {string} data
 * @param {StartOptions} [opts]
 * @returns {Promise<Server>}
 */
async function startServer(data, { args = [], env = {}, fresh = false, timeoutMs = 180_000 } = {}) {
  if (fresh) rmSync(data, { recursive: true, force: true });
  mkdirSync(data, { recursive: true });
  const port = await freePort();
  const proc = spawn(OMNINAV, ['serve', '--port', String(port), ...args], {
    cwd: resolve(__dirname, '..'),
    env: { ...process.env, OMNINAV_DATA: data, ...env },
    stdio: ['ignore', 'pipe', 'pipe'],
    detached: true, // its own process group
  });
  let out = '';
  proc.stdout.on('data', (d) => (out += d));
  proc.stderr.on('data', (d) => (out += d));
  const exited = () => proc.exitCode !== null || proc.signalCode !== null;
  const gone = new Promise((r) => proc.once('exit', r));
  /** @param {NodeJS.Signals} sig */
  const signalGroup = (sig) => {
    try {
      process.kill(-(/** @type {number} */ (proc.pid)), sig);
    } catch {
      // the group is gone already
    }
  };
  const stop = async () => {
    if (exited()) return;
    signalGroup('SIGTERM');
    await Promise.race([gone, new Promise((r) => setTimeout(r, 10_000))]);
    if (!exited()) {
      signalGroup('SIGKILL');
      await gone;
    }
  };
  const url = `http://127.0.0.1:${port}`;
  const deadline = Date.now() + timeoutMs;
  for (;;) {
    if (exited()) throw new Error(`omninav serve exited (${proc.exitCode ?? proc.signalCode}):\n${out}`);
    try {
      if ((await fetch(`${url}/api/health`)).ok) break;
    } catch {
      // not listening yet
    }
    if (Date.now() > deadline) {
      await stop();
      throw new Error(`omninav serve did not answer within ${timeoutMs / 1000} s:\n${out}`);
    }
    await new Promise((r) => setTimeout(r, 300));
  }
  return { url, port, proc, log: () => out, stop };
}

/**
 * Wait until a venue has modelled frames (its modelling job is done).
 * @param {string} url the server's address
 * @param {string} venue
 * @param {number} [timeoutMs]
 * @returns {Promise<void>}
 */
async function waitModelled(url, venue, timeoutMs = 600_000) {
  const deadline = Date.now() + timeoutMs;
  while (Date.now() < deadline) {
    const r = await fetch(`${url}/api/venues/${venue}`);
    if (r.ok && (await r.json()).modelled) return;
    await new Promise((r) => setTimeout(r, 1000));
  }
  throw new Error(`venue ${venue} was not modelled within ${timeoutMs / 1000} s`);
}

module.exports = { OMNINAV, freePort, startServer, waitModelled };
