// Paths the unit tests share, and the golden files, which the Python engine makes at test time
// (nothing binary is committed). Not a Vitest globalSetup any more: only the tests that read the
// golden files make them (golden.test.ts calls makeGoldens()), so the others start at once.
import { execFileSync } from 'node:child_process';
import { fileURLToPath } from 'node:url';
import { resolve } from 'node:path';

export const ROOT = resolve(fileURLToPath(import.meta.url), '../../..');
export const GOLDEN = resolve(ROOT, 'web/test-data/golden');

/** Run the engine's golden generator (e2e/fixtures.py, about a second) into GOLDEN; -> GOLDEN. */
export function makeGoldens(): string {
  execFileSync(resolve(ROOT, '.venv/bin/python'), [resolve(ROOT, 'e2e/fixtures.py'), 'golden', GOLDEN], {
    stdio: 'inherit',
  });
  return GOLDEN;
}
