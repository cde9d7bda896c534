// Before the suite: the engine makes the golden files and the fake camera's clips (the walks of
// guide.spec.ts rendered once, kept while their recipe holds); a real server starts with the quick
// demo venue and models it through its job queue.
import { execFileSync } from 'node:child_process';
import { resolve } from 'node:path';
import { GOLDEN, LENS_KINDS, PYTHON, ROOT, TOKEN, WORK, lensClip } from './env';
import { startServer, waitModelled } from './server.cjs';

export default async function globalSetup(): Promise<() => Promise<void>> {
  const fixtures = resolve(ROOT, 'e2e/fixtures.py');
  execFileSync(PYTHON, [fixtures, 'golden', GOLDEN], { stdio: 'inherit' });
  execFileSync(PYTHON, [fixtures, 'clip', resolve(WORK, 'clip')], { stdio: 'inherit' });
  execFileSync(PYTHON, [fixtures, 'clip', resolve(WORK, 'elsewhere'), '13'], { stdio: 'inherit' });
  for (const kind of LENS_KINDS)
    execFileSync(PYTHON, [fixtures, 'lens', resolve(lensClip(kind), '..'), kind], { stdio: 'inherit' });
  // the admin page's walks and the guidance walks (WORK/admin, WORK/walk: env.ts), kept while their
  // recipe holds; `npm test` has made them beside other suites
  execFileSync(PYTHON, [fixtures, 'renders', WORK], { stdio: 'inherit' });
  const srv = await startServer(resolve(WORK, 'server'), {
    args: ['--demo', 'quick', '--workers', '2'],
    env: { OMNINAV_ADMIN_TOKEN: TOKEN },
    fresh: true,
  });
  try {
    await waitModelled(srv.url, 'demo');
  } catch (e) {
    await srv.stop();
    throw new Error(`${e}\n${srv.log()}`);
  }
  process.env.OMNINAV_E2E_URL = srv.url;
  return async () => srv.stop();
}
