/**
 * The admin API client (backend/omninav/server/openapi.yaml, /api/admin): the token in an
 * `Authorization: Bearer` header, JSON in and out, the server's refusals as AdminError with its own
 * message, and optimistic concurrency: every write under /api/admin/venues/<id> sends
 * `If-Match: "<revision>"` with the revision the page last saw of that venue, and each answer's
 * `ETag` is that venue's new revision (reported through `onRevision`).
 */

/** The server refused (or could not be reached: status 0); `message` is the server's own sentence. */
export class AdminError extends Error {
  constructor(
    message: string,
    readonly status: number,
    readonly details: Record<string, unknown> = {},
  ) {
    super(message);
    this.name = 'AdminError';
  }

  /** 412: the venue changed (another tab, another admin) since this page read it. */
  get stale(): boolean {
    return this.status === 412;
  }

  /** 401/403: no token or a wrong one. */
  get unauthorised(): boolean {
    return this.status === 401 || this.status === 403;
  }
}

export const UNREACHABLE = 'Cannot reach the omninav server: check that it runs and that this computer is online.';

/** What a stale write says to the admin (the page offers a reload beside it). */
export const STALE = 'This venue changed since you opened it (in another tab or by another admin).';

export interface RequestOptions {
  /** A JSON body (sent with Content-Type: application/json). */
  json?: unknown;
  /** A raw body (a file, bytes) with its content type. */
  body?: BodyInit;
  contentType?: string;
  /**
   * If-Match: true (the default for writes under a venue) sends the venue's last seen revision,
   * a number sends that revision, false sends none (e.g. a resumed upload's later pieces).
   */
  ifMatch?: boolean | number;
  headers?: Record<string, string>;
  signal?: AbortSignal;
}

/** One server-sent event: its `event:` name ('message' when none) and its `data:` lines joined. */
export interface StreamEvent {
  event: string;
  data: string;
}

const VENUE_PATH = /^\/api\/admin\/venues\/([^/?#]+)/;

export class AdminApi {
  /** The revision the page last saw of a venue (null: none known, no If-Match is sent). */
  revisionOf: (venueId: string) => number | null = () => null;
  /** A write answered a venue's new revision (its ETag). */
  onRevision: (venueId: string, revision: number) => void = () => {};
  /** Any call was refused for its token (the shell signs out). */
  onUnauthorised: (e: AdminError) => void = () => {};

  constructor(readonly token: string) {}

  /** The call as fetch() makes it, with the token; a refusal throws AdminError. */
  async request(method: string, path: string, opts: RequestOptions = {}): Promise<Response> {
    const headers: Record<string, string> = { Authorization: `Bearer ${this.token}`, ...opts.headers };
    let body = opts.body;
    if (opts.json !== undefined) {
      body = JSON.stringify(opts.json);
      headers['Content-Type'] = 'application/json';
    } else if (opts.contentType) headers['Content-Type'] = opts.contentType;
    const venue = VENUE_PATH.exec(path)?.[1];
    const write = method !== 'GET' && method !== 'HEAD';
    if (write && venue && opts.ifMatch !== false) {
      const rev = typeof opts.ifMatch === 'number' ? opts.ifMatch : this.revisionOf(decodeURIComponent(venue));
      if (rev !== null) headers['If-Match'] = `"${rev}"`;
    }
    let res: Response;
    try {
      res = await fetch(path, { method, headers, body, cache: 'no-store', signal: opts.signal });
    } catch (e) {
      if (e instanceof DOMException && e.name === 'AbortError') throw e;
      throw new AdminError(UNREACHABLE, 0);
    }
    if (!res.ok) throw await this.refusal(res);
    // only a write's ETag is the revision this tab now holds; a read's (the venue as listed) comes
    // without the contents this tab shows, and taking it would hide another tab's edits
    const etag = write ? res.headers.get('ETag') : null;
    if (venue && etag) {
      const rev = Number(etag.replace(/^W\//, '').replace(/"/g, ''));
      if (Number.isInteger(rev)) this.onRevision(decodeURIComponent(venue), rev);
    }
    return res;
  }

  private async refusal(res: Response): Promise<AdminError> {
    type ErrorBody = { error?: unknown; details?: unknown } | null;
    let body: ErrorBody = null;
    try {
      body = (await res.json()) as ErrorBody;
    } catch {
      // a proxy's HTML page: the status alone
    }
    const message = typeof body?.error === 'string' ? body.error : `the server answered ${res.status}`;
    const details = body?.details && typeof body.details === 'object' ? (body.details as Record<string, unknown>) : {};
    const err = new AdminError(res.status === 412 ? `${STALE} ${message}` : message, res.status, details);
    if (err.unauthorised) this.onUnauthorised(err);
    return err;
  }

  /** A JSON call; 204 answers null. */
  async json<T>(method: string, path: string, opts: RequestOptions = {}): Promise<T> {
    const res = await this.request(method, path, opts);
    if (res.status === 204) return null as T;
    return (await res.json()) as T;
  }

  get<T>(path: string, signal?: AbortSignal): Promise<T> {
    return this.json<T>('GET', path, { signal });
  }

  post<T>(path: string, json?: unknown, opts: RequestOptions = {}): Promise<T> {
    return this.json<T>('POST', path, { ...opts, json });
  }

  put<T>(path: string, json: unknown, opts: RequestOptions = {}): Promise<T> {
    return this.json<T>('PUT', path, { ...opts, json });
  }

  patch<T>(path: string, json: unknown, opts: RequestOptions = {}): Promise<T> {
    return this.json<T>('PATCH', path, { ...opts, json });
  }

  del<T>(path: string, opts: RequestOptions = {}): Promise<T> {
    return this.json<T>('DELETE', path, opts);
  }

  /** PUT/POST a file or bytes as `contentType`; answers the JSON reply. */
  upload<T>(method: string, path: string, body: BodyInit, contentType: string, opts: RequestOptions = {}): Promise<T> {
    return this.json<T>(method, path, { ...opts, body, contentType });
  }

  /**
   * An image (or any file) the server sends only with the token, as an object URL for <img src>.
   * The caller revokes it (URL.revokeObjectURL) when the image goes.
   */
  async blobUrl(path: string, signal?: AbortSignal, waitMs = 1000): Promise<string> {
    // a worker makes one frame preview at a time and answers 503 to more (Retry-After: 1): ask
    // again, twice, `waitMs` apart, so scrubbing a video shows the frame a moment later
    for (let tries = 0; ; tries++) {
      try {
        const res = await this.request('GET', path, { signal });
        return URL.createObjectURL(await res.blob());
      } catch (e) {
        if (!(e instanceof AdminError && e.status === 503) || tries >= 2 || signal?.aborted) throw e;
        await new Promise((r) => setTimeout(r, waitMs));
      }
    }
  }

  /**
   * Server-sent events through fetch (EventSource cannot send the token header): calls `onEvent`
   * for each event until the server ends the stream or `signal` aborts; resolves when it ends.
   */
  async stream(path: string, onEvent: (e: StreamEvent) => void, signal?: AbortSignal): Promise<void> {
    const res = await this.request('GET', path, { signal, headers: { Accept: 'text/event-stream' } });
    if (!res.body) throw new AdminError('the server sent no event stream', res.status);
    const reader = res.body.pipeThrough(new TextDecoderStream()).getReader();
    const parser = new EventParser(onEvent);
    try {
      for (;;) {
        const { value, done } = await reader.read();
        if (done) break;
        parser.push(value);
      }
      parser.push('\n\n');
    } finally {
      reader.releaseLock();
    }
  }
}

/** The text/event-stream format, fed in arbitrary pieces (exported for its unit test). */
export class EventParser {
  private buf = '';
  private event = '';
  private data: string[] = [];

  constructor(private readonly onEvent: (e: StreamEvent) => void) {}

  push(text: string): void {
    this.buf += text;
    let nl: number;
    while ((nl = this.buf.search(/\r\n|\r|\n/)) >= 0) {
      if (this.buf[nl] === '\r' && nl === this.buf.length - 1) break; // a "\r\n" cut in two
      const line = this.buf.slice(0, nl);
      this.buf = this.buf.slice(nl + (this.buf.startsWith('\r\n', nl) ? 2 : 1));
      this.line(line);
    }
  }

  private line(line: string): void {
    if (line === '') {
      if (this.data.length) this.onEvent({ event: this.event || 'message', data: this.data.join('\n') });
      this.event = '';
      this.data = [];
      return;
    }
    if (line.startsWith(':')) return; // a comment (keep-alive)
    const colon = line.indexOf(':');
    const field = colon < 0 ? line : line.slice(0, colon);
    let value = colon < 0 ? '' : line.slice(colon + 1);
    if (value.startsWith(' ')) value = value.slice(1);
    if (field === 'event') this.event = value;
    else if (field === 'data') this.data.push(value);
  }
}

/** `/api/admin/venues/<id>` + the rest, with the id escaped. */
export const venuePath = (venueId: string, rest = ''): string =>
  `/api/admin/venues/${encodeURIComponent(venueId)}${rest}`;
