// The screen is kept on while guiding: asked for at Start, asked for again when the page comes
// back after the browser dropped it, given back at Stop; a browser without the API says no.
import { describe, expect, it } from 'vitest';
import { ScreenLock, type Sentinel, type WakeLockHost } from '../src/client/wakelock';

class FakeSentinel implements Sentinel {
  released = false;
  private fns: (() => void)[] = [];
  async release(): Promise<void> {
    if (this.released) return;
    this.released = true;
    for (const fn of this.fns) fn();
  }
  addEventListener(_: 'release', fn: () => void): void {
    this.fns.push(fn);
  }
}

class FakeHost implements WakeLockHost {
  visibilityState: DocumentVisibilityState = 'visible';
  requests = 0;
  refuse = false;
  sentinels: FakeSentinel[] = [];
  private fns = new Set<() => void>();
  wakeLock? = {
    request: async (): Promise<Sentinel> => {
      this.requests++;
      if (this.refuse) throw new DOMException('battery saver', 'NotAllowedError');
      const s = new FakeSentinel();
      this.sentinels.push(s);
      return s;
    },
  };
  addEventListener(_: 'visibilitychange', fn: () => void): void {
    this.fns.add(fn);
  }
  removeEventListener(_: 'visibilitychange', fn: () => void): void {
    this.fns.delete(fn);
  }
  /** The page hidden (the browser drops the lock) or shown again. */
  async show(v: DocumentVisibilityState): Promise<void> {
    this.visibilityState = v;
    if (v === 'hidden') for (const s of this.sentinels) await s.release();
    for (const fn of this.fns) fn();
    await Promise.resolve();
  }
  get listeners(): number {
    return this.fns.size;
  }
}

describe('ScreenLock', () => {
  it('holds the screen on, asks again when the page comes back, and lets go at release', async () => {
    const host = new FakeHost();
    const lock = new ScreenLock(host);
    expect(await lock.hold()).toBe(true);
    expect(lock.held).toBe(true);
    await host.show('hidden');
    expect(lock.held).toBe(false);
    expect(host.requests).toBe(1); // not while hidden
    await host.show('visible');
    expect(host.requests).toBe(2);
    expect(lock.held).toBe(true);
    await lock.release();
    expect(lock.held).toBe(false);
    expect(host.sentinels.every((s) => s.released)).toBe(true);
    expect(host.listeners).toBe(0);
    await host.show('visible');
    expect(host.requests).toBe(2); // released: not asked for again
  });

  it('a second hold while held asks nothing more', async () => {
    const host = new FakeHost();
    const lock = new ScreenLock(host);
    await lock.hold();
    expect(await lock.hold()).toBe(true);
    expect(host.requests).toBe(1);
    expect(host.listeners).toBe(1);
  });

  it('says false where the browser refuses or has no Wake Lock API', async () => {
    const refusing = new FakeHost();
    refusing.refuse = true;
    expect(await new ScreenLock(refusing).hold()).toBe(false);
    const none = new FakeHost();
    delete none.wakeLock;
    const lock = new ScreenLock(none);
    expect(lock.supported).toBe(false);
    expect(await lock.hold()).toBe(false);
    await lock.release();
  });

  it('a lock granted after release is given straight back', async () => {
    const host = new FakeHost();
    const lock = new ScreenLock(host);
    const pending = lock.hold();
    await lock.release();
    expect(await pending).toBe(false);
    expect(host.sentinels[0].released).toBe(true);
  });
});
