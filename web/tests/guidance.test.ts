// The words of route guidance, against the table that the engine's describe.py is held to as well
// (tests/data/guidance.json, run by tests/engine/test_guidance_words.py): the app says each instruction in
// the user's style; the server's `guidance.sentence` is the same sentence in the default style.
import { readFileSync } from 'node:fs';
import { resolve } from 'node:path';
import { describe as group, expect, it } from 'vitest';
import type { RoutePreview } from '../src/shared/api-types';
import {
  GUIDE_NOT_HERE,
  GUIDE_UNSURE,
  SECTOR_DEG,
  STRAIGHT_DEG,
  AROUND_DEG,
  direction,
  guidanceSentence,
  previewSentence,
  sector,
  turnPhrase,
  type Guided,
  type Style,
} from '../src/client/directions';
import { ROOT } from './global-setup';

interface Case {
  case: string;
  guidance: Guided;
  say: Record<Style, string>;
}

interface Preview {
  case: string;
  preview: RoutePreview;
  to: { name: string };
  say: string;
}

const table = JSON.parse(readFileSync(resolve(ROOT, 'tests/data/guidance.json'), 'utf8')) as {
  straight_deg: number;
  around_deg: number;
  sector_deg: number[];
  unsure: string;
  not_here: string;
  cases: Case[];
  previews: Preview[];
};

group('the guidance table', () => {
  it('holds the threshold and the words the app uses', () => {
    expect(STRAIGHT_DEG).toBe(table.straight_deg);
    expect(AROUND_DEG).toBe(table.around_deg);
    expect([...SECTOR_DEG]).toEqual(table.sector_deg);
    expect(GUIDE_UNSURE).toBe(table.unsure);
    expect(GUIDE_NOT_HERE).toBe(table.not_here);
  });
  it.each(['clock', 'sides', 'degrees'] as Style[])('turns and directions share the sectors [%s]', (style) => {
    for (let b = -180; b <= 180; b += 0.5) {
      const k = sector(b);
      expect(turnPhrase(b, style) === null, String(b)).toBe(k === 0);
      if (style === 'sides') {
        // (a turn beyond AROUND_DEG is around, though a place there is behind on a side)
        const turn = Math.abs(b) > AROUND_DEG ? 'Turn around' : ['', 'Bear', 'Turn', 'Turn sharp', 'Turn around'][k];
        expect(turnPhrase(b, style) ?? '').toMatch(new RegExp(`^${turn}`));
        expect(direction(b, style)).toMatch(
          new RegExp(`^${['straight ahead', 'ahead on your', 'to your', 'behind you on your', 'behind you'][k]}`),
        );
      }
    }
  });
  const rows = table.cases.flatMap((c) =>
    (Object.entries(c.say) as [Style, string][]).map(([style, said]) => ({ c, style, said })),
  );
  it.each(rows)('$c.case [$style]', ({ c, style, said }) => {
    expect(guidanceSentence(c.guidance, style)).toBe(said);
  });
  it.each(table.previews)('preview: $case', (p) => {
    expect(previewSentence(p.preview, p.to)).toBe(p.say);
  });
});
