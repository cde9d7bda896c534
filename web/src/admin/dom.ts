/** Small DOM helpers the admin screens share. */
import type { AdminContext } from './context';

/** An element with properties and children: el('button', { type: 'button' }, 'Save'). */
export function el<K extends keyof HTMLElementTagNameMap>(
  tag: K,
  props: Partial<HTMLElementTagNameMap[K]> & { dataset?: Record<string, string> } = {},
  ...kids: (Node | string | null | undefined | false)[]
): HTMLElementTagNameMap[K] {
  const { dataset, ...rest } = props;
  const e = Object.assign(document.createElement(tag), rest);
  if (dataset) Object.assign(e.dataset, dataset);
  for (const k of kids) if (k) e.append(k);
  return e;
}

let ids = 0;
/** A unique id for a label's `for` or an aria reference. */
export const uid = (prefix: string): string => `${prefix}-${++ids}`;

/** A labelled field: <div class="field"><label for>…</label><input id></div>; returns both. */
export function field<T extends HTMLInputElement | HTMLSelectElement | HTMLTextAreaElement>(
  label: string,
  control: T,
  hint?: string,
): { wrap: HTMLElement; control: T } {
  control.id ||= uid('f');
  const wrap = el('div', { className: 'field' }, el('label', { htmlFor: control.id, textContent: label }));
  wrap.append(control);
  if (hint) {
    const h = el('p', { className: 'hint', id: uid('hint'), textContent: hint });
    control.setAttribute('aria-describedby', h.id);
    wrap.append(h);
  }
  return { wrap, control };
}

/**
 * A number input (metres, pixels, seconds). Its step is 'any': a browser's step check would block the
 * form without a word a screen reader hears; the screens check values themselves and say what is wrong.
 */
export function numberInput(value: number | null, min?: number): HTMLInputElement {
  const i = el('input', { type: 'number', step: 'any', inputMode: 'decimal' });
  if (min !== undefined) i.min = String(min);
  if (value !== null && Number.isFinite(value)) i.value = String(value);
  return i;
}

/**
 * Enable again a button that was disabled while its action ran. A focused button that is disabled
 * drops the focus to the page, where a keyboard or screen reader user is left nowhere: the focus
 * comes back to the button when nothing else took it meanwhile.
 */
export function enable(btn: HTMLButtonElement): void {
  btn.disabled = false;
  if (btn.isConnected && (!document.activeElement || document.activeElement === document.body)) btn.focus();
}

/** A button; `onClick` gets the event. */
export function button(text: string, onClick: (e: MouseEvent) => void, className = ''): HTMLButtonElement {
  const b = el('button', { type: 'button', textContent: text, className });
  b.addEventListener('click', onClick);
  return b;
}

/** A number parsed from an input; NaN when empty or not a number. */
export const num = (i: HTMLInputElement): number => (i.value.trim() === '' ? NaN : Number(i.value));

/** A data table with a caption and column headings; its rows go into `body`. */
export function dataTable(
  caption: string,
  columns: readonly string[],
  props: { id?: string; className?: string } = {},
): { table: HTMLTableElement; body: HTMLTableSectionElement } {
  const body = el('tbody');
  const table = el(
    'table',
    props,
    el('caption', { textContent: caption }),
    el('thead', {}, el('tr', {}, ...columns.map((h) => el('th', { scope: 'col', textContent: h })))),
    body,
  );
  return { table, body };
}

/**
 * A screen's status line: `say` shows a message and announces it; `fail` keeps a failure's
 * message there while the shell says it (an alert; on a stale venue, a banner with "Reload the
 * venue"). Nothing is said once the screen has gone (`signal` aborted).
 */
export function statusLine(
  ctx: AdminContext,
  status: HTMLElement,
  signal: AbortSignal,
): { say: (text: string, assertive?: boolean) => void; fail: (e: unknown, doing?: string) => void } {
  return {
    say: (text, assertive = false) => {
      status.textContent = text;
      ctx.announce(text, assertive);
    },
    fail: (e, doing) => {
      if (signal.aborted) return;
      status.textContent = e instanceof Error ? e.message : String(e);
      ctx.fail(e, doing);
    },
  };
}

/** A field refused: marked invalid for assistive technology and focused, so the next key fixes it. */
export function markInvalid(input: HTMLElement): void {
  input.setAttribute('aria-invalid', 'true');
  input.focus();
}
