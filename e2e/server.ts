// Start and stop a real `omninav serve` for the tests (the same command `npm start` runs).
import { spawn, type ChildProcess } from 'node:child_process';
import { mkdirSync, rmSync } from 'node:fs';
import { createServer } from 'node:net';
import { OMNINAV, ROOT, TOKEN } from './env';

export function freePort(): Promise<number> {
  return new Promise((res, rej) => {
    const s = createServer();
    s.listen(0, '127.0.0.1', () => {
      const port = (s.address() as { port: number }).port;
      s.close(() => res(port));
    });
    s.on('error', rej);
  });
}

export interface Server {
  url: string;
  proc: ChildProcess;
  log: () => string;
  stop: () => Promise<void>;
}

export async function startServer(data: string, demo: 'quick' | 'none', fresh = true): Promise<Server> {
  if (fresh) rmSync(data, { recursive: true, force: true });
  mkdirSync(data, { recursive: true });
  const port = await freePort();
  const proc = spawn(OMNINAV, ['serve', '--port', String(port), '--demo', demo, '--workers', '2'], {
    cwd: ROOT,
    env: { ...process.env, OMNINAV_DATA: data, OMNINAV_ADMIN_TOKEN: TOKEN },
    stdio: ['ignore', 'pipe', 'pipe'],
    detached: true, // its own process group: stop() ends gunicorn's workers too
  });
  let out = '';
  proc.stdout!.on('data', (d) => (out += d));
  proc.stderr!.on('data', (d) => (out += d));
  const url = `http://127.0.0.1:${port}`;
  const stop = async () => {
    if (proc.exitCode !== null) return;
    const gone = new Promise((r) => proc.once('exit', r));
    try {
      process.kill(-proc.pid!, 'SIGTERM');
    } catch {
      return;
    }
    await Promise.race([gone, new Promise((r) => setTimeout(r, 10_000))]);
    if (proc.exitCode === null) process.kill(-proc.pid!, 'SIGKILL');
  };
  const deadline = Date.now() + 180_000;
  for (;;) {
    if (proc.exitCode !== null) throw new Error(`omninav serve exited (${proc.exitCode}):\n${out}`);
    try {
      if ((await fetch(`${url}/api/health`)).ok) break;
    } catch {
      // not listening yet
    }
    if (Date.now() > deadline) {
      await stop();
      throw new Error(`omninav serve did not answer within 3 minutes:\n${out}`);
    }
    await new Promise((r) => setTimeout(r, 300));
  }
  return { url, proc, log: () => out, stop };
}

/** Wait until a venue has modelled frames (its modelling job is done). */
export async function waitModelled(url: string, venue: string, timeoutMs = 600_000): Promise<void> {
  const deadline = Date.now() + timeoutMs;
  while (Date.now() < deadline) {
    const r = await fetch(`${url}/api/venues/${venue}`);
    if (r.ok && (await r.json()).modelled) return;
    await new Promise((r) => setTimeout(r, 1000));
  }
  throw new Error(`venue ${venue} was not modelled within ${timeoutMs / 1000} s`);
}
