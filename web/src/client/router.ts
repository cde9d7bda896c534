/**
 * Tab routing: the tabs in the header show one screen at a time. The shown screen's heading takes
 * the focus, so that a screen reader starts reading there.
 */

/** Show screen `name` (`#screen-<name>`) and mark its tab as the current page. */
export function showScreen(name: string): void {
  for (const b of document.querySelectorAll<HTMLButtonElement>('.tab')) {
    if (b.dataset.screen === name) b.setAttribute('aria-current', 'page');
    else b.removeAttribute('aria-current');
  }
  for (const s of document.querySelectorAll<HTMLElement>('.screen')) s.hidden = s.id !== `screen-${name}`;
  document.querySelector<HTMLElement>(`#screen-${name} h2`)?.focus();
}

/**
 * Each tab (`.tab[data-screen]`) shows its screen; the screens' headings can take the focus.
 * `shown`: told each screen a tab shows.
 */
export function routeTabs(shown?: (name: string) => void): void {
  for (const b of document.querySelectorAll<HTMLButtonElement>('.tab'))
    b.addEventListener('click', () => {
      showScreen(b.dataset.screen!);
      shown?.(b.dataset.screen!);
    });
  for (const h of document.querySelectorAll<HTMLElement>('.screen h2')) h.tabIndex = -1;
}
