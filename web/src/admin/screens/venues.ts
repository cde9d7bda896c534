/**
 * Step 2, venues: the list (each opens its floor screen), create, rename, and delete after a
 * confirmation that names what will be lost (its modelled frames, videos and places). Rename and
 * delete send the revision read when the admin started them, so a change made meanwhile in another
 * tab is refused ("changed since you opened it") rather than overwritten.
 */
import { AdminError, venuePath } from '../api';
import type { AdminContext } from '../context';
import { button, el, field, markInvalid } from '../dom';
import type { AdminVenue, Video } from '../types';

interface VenueItem {
  id: string;
  name: string;
}

const ID = /^[A-Za-z0-9][A-Za-z0-9_-]{0,63}$/;

const plural = (n: number, one: string, many = `${one}s`): string => `${n} ${n === 1 ? one : many}`;

export function mount(root: HTMLElement, ctx: AdminContext): () => void {
  const abort = new AbortController();
  const list = el('ul', { className: 'venue-list', id: 'venue-list' });
  const listStatus = el('p', { textContent: 'Loading the venues…' });

  // ---- create
  const idIn = el('input', { name: 'id', required: true, pattern: ID.source, autocomplete: 'off', spellcheck: false });
  const nameIn = el('input', { name: 'name', autocomplete: 'off' });
  const preset = el('select', { name: 'preset' });
  for (const [v, label] of [
    ['default', 'default (recommended)'],
    ['wide', 'wide (one wide band: for a building where the default’s evaluation walk misses)'],
    ['verified', 'verified (the default, and local features that check clips sent as video or frames)'],
    ['paper', 'paper (as published)'],
    ['six', 'six (the paper’s six curves over one band)'],
  ])
    preset.append(new Option(label, v));
  const create = el(
    'form',
    { noValidate: true, className: 'create-venue' },
    field('Venue id', idIn, 'Letters, digits, - and _; it is in the venue’s address and cannot change later.').wrap,
    field('Name', nameIn, 'What the app shows and says, e.g. “Science Library”. Changeable later.').wrap,
    field('Feature preset', preset).wrap,
    el('button', { type: 'submit', textContent: 'Create the venue' }),
  );
  create.addEventListener('submit', (e) => {
    e.preventDefault();
    const id = idIn.value.trim();
    if (!ID.test(id)) {
      ctx.announce('The venue id must start with a letter or digit and have only letters, digits, - and _.', true);
      markInvalid(idIn);
      return;
    }
    idIn.removeAttribute('aria-invalid');
    const body = { id, name: nameIn.value.trim() || id, preset: preset.value };
    ctx.api
      .post<AdminVenue>('/api/admin/venues', body)
      .then((v) => {
        ctx.announce(`Created venue ${v.name}.`);
        location.hash = `#/v/${encodeURIComponent(v.id)}/floor`;
      })
      .catch((err: unknown) => {
        ctx.fail(err, `Creating venue ${id}`);
        if (err instanceof AdminError && err.status === 409) {
          markInvalid(idIn); // the id is taken
        }
      });
  });

  // ---- one row: open, rename, delete
  const row = (v: VenueItem): HTMLElement => {
    const li = el('li', { className: 'venue' });
    const open = el('a', { href: `#/v/${encodeURIComponent(v.id)}/floor`, textContent: v.name });
    const idText = el('span', { className: 'venue-id', textContent: ` (${v.id})` });
    const panel = el('div', { className: 'venue-panel' });
    const renameBtn = button('Rename', () => void startRename());
    renameBtn.setAttribute('aria-label', `Rename ${v.name}`);
    const deleteBtn = button('Delete…', () => void startDelete(), 'danger');
    deleteBtn.setAttribute('aria-label', `Delete ${v.name}…`);
    li.append(el('p', { className: 'venue-line' }, open, idText, ' ', renameBtn, ' ', deleteBtn), panel);

    const startRename = async (): Promise<void> => {
      let doc: AdminVenue;
      try {
        doc = await ctx.api.get<AdminVenue>(venuePath(v.id), abort.signal);
      } catch (err) {
        return ctx.fail(err, `Reading venue ${v.id}`);
      }
      const input = el('input', { value: doc.name, required: true, maxLength: 200 });
      const form = el(
        'form',
        { noValidate: true, className: 'inline-form' },
        field(`New name for ${v.id}`, input).wrap,
        el('button', { type: 'submit', textContent: 'Save the name' }),
        button('Cancel', () => {
          panel.replaceChildren();
          renameBtn.focus();
        }),
      );
      form.addEventListener('submit', (e) => {
        e.preventDefault();
        const name = input.value.trim();
        if (!name) return ctx.announce('A name is needed.', true);
        ctx.api
          .patch<AdminVenue>(venuePath(v.id), { name }, { ifMatch: doc.revision })
          .then((nv) => {
            ctx.announce(`Renamed ${v.id} to ${nv.name}.`);
            void load(v.id);
          })
          .catch((err: unknown) => ctx.fail(err, `Renaming ${v.id}`));
      });
      panel.replaceChildren(form);
      input.focus();
      input.select();
    };

    const startDelete = async (): Promise<void> => {
      let doc: AdminVenue;
      let vids: Video[] = [];
      try {
        doc = await ctx.api.get<AdminVenue>(venuePath(v.id), abort.signal);
        vids = (await ctx.api.get<{ videos: Video[] }>(venuePath(v.id, '/videos'), abort.signal)).videos;
      } catch (err) {
        return ctx.fail(err, `Reading venue ${v.id}`);
      }
      const lost =
        `${plural(doc.frames, 'modelled frame')}, ${plural(vids.length, 'video')}, ` +
        `${plural(doc.places.length, 'place')}, ${plural(doc.floors.filter((f) => f.plan_url).length, 'floor plan')} ` +
        `and ${plural(Object.keys(doc.lenses).length, 'lens profile')}`;
      const text = el('p', {
        id: `delete-what-${v.id}`,
        textContent: `Delete ${doc.name} (${v.id})? Its ${lost} will be lost. This cannot be undone.`,
      });
      const yes = button(
        `Delete ${doc.name} for good`,
        () => {
          ctx.api
            .del<{ deleted: string; frames_removed: number; videos_removed: number }>(venuePath(v.id), {
              ifMatch: doc.revision,
            })
            .then((r) => {
              ctx.announce(
                `Deleted ${doc.name}: ${plural(r.frames_removed, 'frame')} and ${plural(r.videos_removed, 'video')} removed.`,
              );
              void load();
            })
            .catch((err: unknown) => ctx.fail(err, `Deleting ${v.id}`));
        },
        'danger',
      );
      const no = button('Keep it', () => {
        panel.replaceChildren();
        deleteBtn.focus();
      });
      const box = el('div', { className: 'confirm', role: 'group' }, text, yes, ' ', no);
      box.setAttribute('aria-labelledby', text.id);
      panel.replaceChildren(box);
      ctx.announce(text.textContent ?? '');
      no.focus();
    };
    return li;
  };

  const load = async (focusId?: string): Promise<void> => {
    try {
      const r = await fetch('/api/venues', { cache: 'no-store', signal: abort.signal });
      const { venues } = (await r.json()) as { venues: VenueItem[] };
      list.replaceChildren(...venues.map(row));
      listStatus.textContent = venues.length
        ? `${plural(venues.length, 'venue')}.`
        : 'No venue yet: create the first one below.';
      if (focusId) list.querySelector<HTMLElement>(`a[href="#/v/${encodeURIComponent(focusId)}/floor"]`)?.focus();
    } catch (err) {
      if (!abort.signal.aborted) {
        listStatus.textContent = 'The venues could not be read.';
        ctx.fail(err, 'Reading the venues');
      }
    }
  };

  root.append(
    el('h1', { textContent: 'Venues' }),
    listStatus,
    list,
    el('h2', { textContent: 'Create a venue' }),
    create,
  );
  void load();
  return () => abort.abort();
}
