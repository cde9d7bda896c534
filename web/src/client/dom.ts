/** The few DOM helpers the screens share. */

/** An element of index.html by id; the page's ids are fixed, so a missing one is a bug, not a state. */
export const byId = <T extends HTMLElement = HTMLElement>(id: string): T => document.getElementById(id) as T;

/** Fill a select with [value, label] items, `value` selected. */
export function fillSelect(sel: HTMLSelectElement, items: [string, string][], value: string): void {
  sel.replaceChildren(...items.map(([v, label]) => new Option(label, v, false, v === value)));
}

/** Fill a description list with [term, description] rows. */
export function facts(dl: HTMLElement, rows: [string, string][]): void {
  dl.replaceChildren(
    ...rows.flatMap(([k, v]) => {
      const dt = document.createElement('dt');
      dt.textContent = k;
      const dd = document.createElement('dd');
      dd.textContent = v;
      return [dt, dd];
    }),
  );
}
