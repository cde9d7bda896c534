/**
 * Step 1, sign in: the admin token (printed by `omninav serve` at first start) is checked with an
 * admin call and kept in sessionStorage only: it goes when the tab closes, and never reaches
 * localStorage, a cookie or the URL.
 */
import { AdminApi, AdminError } from '../api';
import { el, field } from '../dom';

const KEY = 'omninav-admin-token';

export const savedToken = (): string | null => {
  try {
    return sessionStorage.getItem(KEY);
  } catch {
    return null;
  }
};

export const clearToken = (): void => {
  try {
    sessionStorage.removeItem(KEY);
  } catch {
    // storage disabled: nothing was kept
  }
};

/**
 * Whether the server takes this token: an admin GET that needs it. A job id that cannot exist
 * answers 404 to a good token and 401/403 to a wrong one (the token is checked first).
 */
export async function checkToken(api: AdminApi): Promise<void> {
  try {
    await api.get('/api/admin/jobs/token-check');
  } catch (e) {
    if (e instanceof AdminError && e.status === 404) return;
    throw e;
  }
}

export interface SignInOptions {
  /** Why the admin is asked to sign in again (a refused token), if so. */
  message?: string;
  announce: (msg: string, assertive?: boolean) => void;
  signedIn: (api: AdminApi) => void;
}

export function mountSignIn(root: HTMLElement, opts: SignInOptions): () => void {
  const input = el('input', {
    type: 'password',
    name: 'token',
    autocomplete: 'current-password',
    required: true,
    spellcheck: false,
  });
  const f = field(
    'Admin token',
    input,
    'Printed by omninav serve when it first started (or set by OMNINAV_ADMIN_TOKEN).',
  );
  const problem = el('p', { className: 'problem', id: 'signin-problem', hidden: !opts.message });
  problem.textContent = opts.message ?? '';
  const submit = el('button', { type: 'submit', textContent: 'Sign in' });
  const form = el('form', { noValidate: true, className: 'signin' }, f.wrap, problem, submit);
  root.append(
    el('h1', { textContent: 'Sign in to omninav admin' }),
    el('p', {
      textContent: 'The token is kept in this browser tab only, and forgotten when the tab closes or you sign out.',
    }),
    form,
  );
  const say = (msg: string): void => {
    problem.textContent = msg;
    problem.hidden = false;
    input.setAttribute('aria-invalid', 'true');
    const described = (input.getAttribute('aria-describedby') ?? '')
      .split(/\s+/)
      .filter((id) => id && id !== problem.id);
    input.setAttribute('aria-describedby', [problem.id, ...described].join(' '));
    opts.announce(msg, true);
    input.focus();
    input.select();
  };
  form.addEventListener('submit', (e) => {
    e.preventDefault();
    const token = input.value.trim();
    if (!token) return say('Type the admin token.');
    submit.disabled = true;
    const api = new AdminApi(token);
    checkToken(api)
      .then(() => {
        try {
          sessionStorage.setItem(KEY, token);
        } catch {
          // storage disabled: signed in for this page only
        }
        opts.signedIn(api);
      })
      .catch((err: unknown) => {
        if (err instanceof AdminError && err.unauthorised)
          say('Wrong admin token: the server refused it. Check it and type it again.');
        else say(err instanceof Error ? err.message : String(err));
      })
      .finally(() => {
        submit.disabled = false;
      });
  });
  input.focus();
  return () => {};
}
