/** Small DOM helpers the admin screens share. */

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

/** A button; `onClick` gets the event. */
export function button(text: string, onClick: (e: MouseEvent) => void, className = ''): HTMLButtonElement {
  const b = el('button', { type: 'button', textContent: text, className });
  b.addEventListener('click', onClick);
  return b;
}

/** A number parsed from an input; NaN when empty or not a number. */
export const num = (i: HTMLInputElement): number => (i.value.trim() === '' ? NaN : Number(i.value));
