// Paths and settings the e2e suite shares (config, setup and specs).
import { existsSync } from 'node:fs';
import { resolve } from 'node:path';

export const ROOT = resolve(__dirname, '..');
export const WORK = resolve(ROOT, 'data/e2e');
export const GOLDEN = resolve(WORK, 'golden');
export const CLIP = resolve(WORK, 'clip/clip.y4m');
/** A clip filmed in another building, which the demo venue has never seen. */
export const ELSEWHERE = resolve(WORK, 'elsewhere/clip.y4m');
/** The lens check's clips (e2e/fixtures.py `lens`): the lens 6 px off, no lens, the ring cut by the edge. */
export const LENS_KINDS = ['shifted', 'nolens', 'cut'] as const;
export const lensClip = (kind: (typeof LENS_KINDS)[number]): string => resolve(WORK, `lens-${kind}/lens.y4m`);
/** Walks to the stairs for route guidance (e2e/fixtures.py `walk`): right, and the wrong way first. */
export const WALKS = ['to-stairs', 'wrong-way'] as const;
export const walkClip = (name: (typeof WALKS)[number]): string => resolve(WORK, `walk/${name}.y4m`);
export const TOKEN = 'e2e-admin-token-0123456789';
export const PYTHON = resolve(ROOT, '.venv/bin/python');

export function chromiumPath(): string {
  const p = process.env.CHROMIUM ?? '/usr/bin/chromium';
  if (!existsSync(p))
    throw new Error(`no Chromium at ${p}: run scripts/chromium.sh (apt-get install chromium) or set CHROMIUM`);
  return p;
}

/** Flags for a closed network (no Google lookups) and a fake camera playing `clip`. */
export function chromiumArgs(clip: string): string[] {
  return [
    '--use-fake-device-for-media-stream',
    `--use-file-for-fake-video-capture=${clip}`,
    '--disable-gpu',
    '--disable-quic',
    '--no-first-run',
    '--disable-background-networking',
    '--disable-component-update',
    '--disable-sync',
  ];
}

/** The running server's address (set by global-setup.ts). */
export const base = (): string => {
  const u = process.env.OMNINAV_E2E_URL;
  if (!u) throw new Error('OMNINAV_E2E_URL is not set: run through playwright.config.ts');
  return u;
};
