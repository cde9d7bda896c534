// The words the user hears, against the table that the engine's describe.py is held to as well
// (tests/data/sentences.json, run by tests/engine/test_describe.py): the app phrases an answer in the
// user's style; the server's `sentence` is the same sentence in the default style.
import { readFileSync } from 'node:fs';
import { resolve } from 'node:path';
import { describe as group, expect, it } from 'vitest';
import { DEFAULT_STYLE, NEAR_M, SURE, UNSURE, describe, type Said, type Style } from '../src/client/directions';
import { ROOT } from './global-setup';

interface Case {
  case: string;
  answer: Said;
  floor_name: string | null;
  say: Partial<Record<Style, string>>;
}

const table = JSON.parse(readFileSync(resolve(ROOT, 'tests/data/sentences.json'), 'utf8')) as {
  near_m: number;
  unsure: string;
  sure: number;
  default_style: Style;
  cases: Case[];
};

group('the sentence table', () => {
  it('holds the thresholds and the words the app uses', () => {
    expect(NEAR_M).toBe(table.near_m);
    expect(UNSURE).toBe(table.unsure);
    expect(SURE).toBe(table.sure);
    expect(DEFAULT_STYLE).toBe(table.default_style);
  });
  const rows = table.cases.flatMap((c) =>
    (Object.entries(c.say) as [Style, string][]).map(([style, said]) => ({ c, style, said })),
  );
  it.each(rows)('$c.case [$style]', ({ c, style, said }) => {
    expect(describe(c.answer, style, c.floor_name)).toBe(said);
  });
});
