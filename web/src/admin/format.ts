/** Numbers as the admin reads them: sizes, rates, durations and video times. */

/** 1234567 -> "1.2 MB" (decimal units, as file managers show sizes). */
export function formatBytes(n: number): string {
  if (!Number.isFinite(n) || n < 0) return '?';
  if (n < 1000) return `${Math.round(n)} B`;
  const units = ['kB', 'MB', 'GB', 'TB'];
  let v = n / 1000;
  let i = 0;
  while (v >= 1000 && i < units.length - 1) {
    v /= 1000;
    i++;
  }
  return `${v >= 100 ? Math.round(v) : v.toFixed(1)} ${units[i]}`;
}

/** A duration in words for a status line: "45 s", "3 min 20 s", "2 h 5 min". */
export function formatDuration(s: number): string {
  if (!Number.isFinite(s) || s < 0) return 'unknown';
  const r = Math.round(s);
  if (r < 60) return `${r} s`;
  if (r < 3600) {
    const m = Math.floor(r / 60);
    const sec = r % 60;
    return sec ? `${m} min ${sec} s` : `${m} min`;
  }
  const h = Math.floor(r / 3600);
  const m = Math.round((r % 3600) / 60);
  return m ? `${h} h ${m} min` : `${h} h`;
}

/** A moment of a video: 62.46 -> "1:02.5" (tenths, as the scrubber moves in frames). */
export function formatTime(t: number): string {
  if (!Number.isFinite(t) || t < 0) return '?';
  const tenths = Math.round(t * 10);
  const m = Math.floor(tenths / 600);
  const s = (tenths % 600) / 10;
  return `${m}:${s < 10 ? '0' : ''}${s.toFixed(1)}`;
}
