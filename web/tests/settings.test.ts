// The settings controls are one table: each control's change sets its preference, parsed, and the
// preferences are shown back in the controls. Fake controls stand in for the page's.
import { afterEach, describe, expect, it, vi } from 'vitest';
import { DEFAULTS, loadPrefs, savePrefs, type Prefs } from '../src/client/prefs';
import { bindSettings, showAppVoiceControls, type Control } from '../src/client/screens/settings';

class FakeControl implements Control {
  checked?: boolean;
  disabled = false;
  private fns = new Map<string, () => void>();
  constructor(
    public value: string,
    checkable = false,
  ) {
    if (checkable) this.checked = false;
  }
  addEventListener(type: string, fn: () => void): void {
    this.fns.set(type, fn);
  }
  fire(type: string): void {
    this.fns.get(type)?.();
  }
}

function page() {
  const c = {
    venue: new FakeControl('demo'),
    lens: new FakeControl('donut'),
    clock: new FakeControl('clock', true),
    sides: new FakeControl('sides', true),
    app: new FakeControl('app', true),
    reader: new FakeControl('screen-reader', true),
    rate: new FakeControl('1'),
    voice: new FakeControl(''),
    vibrate: new FakeControl('on', true),
    interval: new FakeControl('3'),
  };
  const bySelector: Record<string, FakeControl[]> = {
    '#venue': [c.venue],
    '#lens': [c.lens],
    'input[name=style]': [c.clock, c.sides],
    'input[name=read-by]': [c.app, c.reader],
    '#rate': [c.rate],
    '#voice': [c.voice],
    '#vibrate': [c.vibrate],
    '#interval': [c.interval],
  };
  const prefs: Prefs = { ...DEFAULTS };
  const set = vi.fn(<K extends keyof Prefs>(k: K, v: Prefs[K]) => void (prefs[k] = v));
  const root = { querySelectorAll: (sel: string) => bySelector[sel] ?? [] };
  const show = bindSettings(root, prefs, set);
  return { c, prefs, set, show, root };
}

describe('the settings binding', () => {
  it('each control sets its preference, parsed, on its own event', () => {
    const { c, set } = page();
    c.rate.value = '1.5';
    c.rate.fire('change'); // a slider reports while it moves: `input`, not `change`
    expect(set).not.toHaveBeenCalled();
    c.rate.fire('input');
    c.venue.value = 'other';
    c.venue.fire('change');
    c.lens.value = 'theta';
    c.lens.fire('change');
    c.sides.fire('change');
    c.reader.fire('change');
    c.voice.value = 'Samantha';
    c.voice.fire('change');
    c.vibrate.checked = false;
    c.vibrate.fire('change');
    c.interval.value = '10';
    c.interval.fire('change');
    expect(set.mock.calls).toEqual([
      ['rate', 1.5],
      ['venue', 'other'],
      ['lens', 'theta'],
      ['style', 'sides'],
      ['readBy', 'screen-reader'],
      ['voice', 'Samantha'],
      ['vibrate', false],
      ['interval', 10],
    ]);
  });

  it('shows the preferences in the controls whose options it owns', () => {
    const { c, prefs, show } = page();
    Object.assign(prefs, { style: 'sides', rate: 0.7, vibrate: true, interval: 5, venue: 'x', voice: 'y' });
    show();
    expect([c.clock.checked, c.sides.checked, c.rate.value, c.vibrate.checked, c.interval.value]).toEqual([
      false,
      true,
      '0.7',
      true,
      '5',
    ]);
    // venue, lens and voice lists are filled elsewhere, with their choice
    expect([c.venue.value, c.voice.value]).toEqual(['demo', '']);
  });

  it('who reads the answers: the app by default; the screen reader shown and the app voice controls off', () => {
    const { c, prefs, show, root, set } = page();
    expect(prefs.readBy).toBe('app');
    show();
    showAppVoiceControls(root, prefs);
    expect([c.app.checked, c.reader.checked, c.rate.disabled, c.voice.disabled]).toEqual([true, false, false, false]);
    c.reader.fire('change');
    expect(set).toHaveBeenLastCalledWith('readBy', 'screen-reader');
    show();
    showAppVoiceControls(root, prefs);
    // rate and voice tune only the app's own voice, which is silent now
    expect([c.app.checked, c.reader.checked, c.rate.disabled, c.voice.disabled]).toEqual([false, true, true, true]);
    expect([c.vibrate.disabled, c.interval.disabled]).toEqual([false, false]);
    c.app.fire('change');
    showAppVoiceControls(root, prefs);
    expect([c.rate.disabled, c.voice.disabled]).toEqual([false, false]);
  });
});

describe('the saved preferences', () => {
  afterEach(() => vi.unstubAllGlobals());

  it('keep who reads the answers across a reload, the app voice by default', () => {
    const stored = new Map<string, string>();
    vi.stubGlobal('localStorage', {
      getItem: (k: string) => stored.get(k) ?? null,
      setItem: (k: string, v: string) => void stored.set(k, v),
    });
    expect(loadPrefs().readBy).toBe('app'); // nothing saved yet
    stored.set('omninav.prefs', JSON.stringify({ style: 'sides' })); // saved before the setting existed
    expect(loadPrefs().readBy).toBe('app');
    savePrefs({ ...loadPrefs(), readBy: 'screen-reader' });
    expect(loadPrefs()).toMatchObject({ readBy: 'screen-reader', style: 'sides' });
  });
});
