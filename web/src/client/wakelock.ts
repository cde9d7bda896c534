/**
 * Keeps the screen on while guiding (the Screen Wake Lock API): a phone that locks its screen
 * stops the camera and slows the page's timers, and guidance would go quiet. The browser drops
 * the lock whenever the page is hidden (another app, the power button), so it is asked for again
 * each time the page comes back while it is still wanted. Where the API is missing or refuses,
 * `hold()` says so and the user keeps the screen on themselves (docs/app.md, "Going to a place").
 */

/** The part of a WakeLockSentinel used here (a fake in tests). */
export interface Sentinel {
  readonly released: boolean;
  release(): Promise<void>;
  addEventListener(type: 'release', fn: () => void): void;
}

/** Where the lock comes from and when the page is shown: navigator and document, or fakes. */
export interface WakeLockHost {
  wakeLock?: { request(type: 'screen'): Promise<Sentinel> };
  readonly visibilityState: DocumentVisibilityState;
  addEventListener(type: 'visibilitychange', fn: () => void): void;
  removeEventListener(type: 'visibilitychange', fn: () => void): void;
}

/** The page's own: navigator.wakeLock with the document's visibility. */
function pageHost(): WakeLockHost {
  const nav = globalThis.navigator as unknown as Pick<WakeLockHost, 'wakeLock'> | undefined;
  return {
    wakeLock: nav?.wakeLock,
    get visibilityState() {
      return document.visibilityState;
    },
    addEventListener: (t, fn) => document.addEventListener(t, fn),
    removeEventListener: (t, fn) => document.removeEventListener(t, fn),
  };
}

export class ScreenLock {
  private sentinel: Sentinel | null = null;
  private wanted = false;
  private host: WakeLockHost | null;

  constructor(host?: WakeLockHost) {
    this.host = host ?? null;
  }

  private get h(): WakeLockHost {
    return (this.host ??= pageHost());
  }

  /** This browser has the API at all. */
  get supported(): boolean {
    return typeof this.h.wakeLock?.request === 'function';
  }

  /** The screen is being kept on now. */
  get held(): boolean {
    return this.sentinel !== null && !this.sentinel.released;
  }

  /** Keep the screen on until `release()`; resolves true when the browser granted it. */
  async hold(): Promise<boolean> {
    if (!this.wanted) {
      this.wanted = true;
      this.h.addEventListener('visibilitychange', this.again);
    }
    return this.request();
  }

  /** Let the screen lock again (guidance stopped or arrived). */
  async release(): Promise<void> {
    if (!this.wanted) return;
    this.wanted = false;
    this.h.removeEventListener('visibilitychange', this.again);
    const s = this.sentinel;
    this.sentinel = null;
    if (s && !s.released) await s.release().catch(() => undefined);
  }

  private readonly again = (): void => {
    if (this.wanted && this.h.visibilityState === 'visible' && !this.held) void this.request();
  };

  private async request(): Promise<boolean> {
    if (this.held) return true;
    if (!this.supported || this.h.visibilityState !== 'visible') return false;
    try {
      const s = await this.h.wakeLock!.request('screen');
      // released meanwhile (Stop pressed while the browser was deciding): give it straight back
      if (!this.wanted) {
        await s.release().catch(() => undefined);
        return false;
      }
      this.sentinel = s;
      s.addEventListener('release', () => {
        if (this.sentinel === s) this.sentinel = null;
      });
      return true;
    } catch {
      // refused: battery saver, a policy, a page not focused
      return false;
    }
  }
}
