// Golden files come from the Python engine at test time (nothing binary is committed).
import { execFileSync } from 'node:child_process';
import { fileURLToPath } from 'node:url';
import { resolve } from 'node:path';

export const ROOT = resolve(fileURLToPath(import.meta.url), '../../..');
export const GOLDEN = resolve(ROOT, 'web/test-data/golden');

export default function setup(): void {
  execFileSync(resolve(ROOT, '.venv/bin/python'), [resolve(ROOT, 'e2e/fixtures.py'), 'golden', GOLDEN], {
    stdio: 'inherit',
  });
}
