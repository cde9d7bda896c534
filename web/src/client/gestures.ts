/**
 * Hands-free triggers for "Where am I?": a shake, or a two-finger double tap anywhere. (With a
 * screen reader on, taps go to the reader; the button and the shake still work.)
 */

export function onShake(fire: () => void, threshold = 24, windowMs = 900): () => void {
  let peaks: number[] = [];
  let quietUntil = 0;
  const handler = (e: DeviceMotionEvent) => {
    const g = e.accelerationIncludingGravity;
    if (!g || g.x === null || g.y === null || g.z === null) return;
    const now = performance.now();
    if (now < quietUntil) return;
    if (Math.hypot(g.x, g.y, g.z) < threshold) return;
    peaks = peaks.filter((t) => now - t < windowMs);
    peaks.push(now);
    if (peaks.length >= 3) {
      peaks = [];
      quietUntil = now + 2000; // one shake, one question
      fire();
    }
  };
  addEventListener('devicemotion', handler);
  return () => removeEventListener('devicemotion', handler);
}

/** iOS asks for motion access inside a gesture; elsewhere this resolves at once. */
export async function askMotion(): Promise<void> {
  const DME = globalThis.DeviceMotionEvent as unknown as { requestPermission?: () => Promise<string> } | undefined;
  if (DME?.requestPermission) await DME.requestPermission().catch(() => 'denied');
}

export function onTwoFingerDoubleTap(target: HTMLElement, fire: () => void, gapMs = 450): () => void {
  let last = 0;
  const handler = (e: TouchEvent) => {
    if (e.touches.length !== 2) return;
    const now = performance.now();
    if (now - last < gapMs) {
      last = 0;
      e.preventDefault();
      fire();
    } else last = now;
  };
  target.addEventListener('touchstart', handler, { passive: false });
  return () => target.removeEventListener('touchstart', handler);
}
