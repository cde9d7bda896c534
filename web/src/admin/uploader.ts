/**
 * The page's video uploads: each file checked here first (probe.ts), registered (POST .../videos),
 * then sent in pieces (PUT .../content with Content-Range, by XMLHttpRequest for its progress
 * events) from wherever the server says it stands. The uploads live as long as the page, not the
 * screen: the admin may tag one video while the next uploads. Which File goes with which video is
 * kept in memory only; after a reload the admin chooses the file again and it resumes from the
 * server's `received` (upload.ts).
 */
import { AdminError, UNREACHABLE, venuePath, type AdminApi } from './api';
import { followJob } from './jobprogress';
import { formatBytes, formatDuration } from './format';
import { probeFile, type VideoProbe } from './probe';
import type { Job, Video } from './types';
import { RateMeter, contentRange, lensMismatch, nextPiece, pieceOverride, pieceSize, videoName } from './upload';

export type UploadState =
  | 'checking' // probing the file here
  | 'waiting' // in the queue behind another upload
  | 'exists' // a finished video has this name: the admin chooses to replace it or not
  | 'sending'
  | 'paused'
  | 'offline' // the connection dropped: retrying by itself
  | 'retrying' // the server is busy with this video (its last piece): retrying by itself
  | 'refused' // the file cannot be used (here or by the server): the reason says why
  | 'failed' // something else went wrong: Resume tries again
  | 'done';

export interface UploadOptions {
  venue: string;
  floor: string;
  lens: string;
  role: 'model' | 'evaluation';
  /** The lens's frame size, [width, height], for the check before sending. */
  imageSize?: [number, number];
}

type Listener = (u: Upload) => void;

/** Retry waits after a dropped connection (seconds), the last one repeated. */
const BACKOFF_S = [1, 2, 4, 8, 15, 30];

export class Upload {
  readonly name: string;
  state: UploadState = 'checking';
  /** Bytes the server holds (its `received`). */
  received = 0;
  /** Bytes of the piece in flight that have left the browser. */
  sending = 0;
  /** Why it was refused or failed, in the server's (or the check's) words. */
  reason = '';
  probe: VideoProbe | null = null;
  video: Video | null = null;
  /** The suggest job started after the upload (finding turns and stops). */
  suggest: Job | null = null;
  readonly meter = new RateMeter();
  private xhr: XMLHttpRequest | null = null;
  private retries = 0;
  private retryTimer: ReturnType<typeof setTimeout> | null = null;
  private replace = false;

  constructor(
    readonly file: File,
    readonly opts: UploadOptions,
    private readonly api: AdminApi,
    private readonly changed: Listener,
  ) {
    this.name = videoName(file.name);
  }

  get size(): number {
    return this.file.size;
  }

  /** Bytes counted for the progress bar: the server's plus what is on the wire. */
  get shown(): number {
    return Math.min(this.size, this.received + this.sending);
  }

  get active(): boolean {
    return ['sending', 'checking', 'offline', 'retrying'].includes(this.state);
  }

  /** One line on where it stands: "3.2 MB of 12 MB, 1.4 MB/s, 6 s left". */
  describe(): string {
    const of = `${formatBytes(this.shown)} of ${formatBytes(this.size)}`;
    switch (this.state) {
      case 'checking':
        return 'checking the file…';
      case 'waiting':
        return this.received > 0 ? `waiting; will continue from ${formatBytes(this.received)}` : 'waiting its turn';
      case 'exists':
        return `a finished video named ${this.name} is already on the server`;
      case 'sending': {
        const v = this.meter.speed();
        const eta = this.meter.eta(this.size - this.shown);
        const parts = [of];
        if (v !== null) parts.push(`${formatBytes(v)}/s`);
        if (eta !== null) parts.push(`${formatDuration(eta)} left`);
        return parts.join(', ');
      }
      case 'paused':
        return `paused at ${of}`;
      case 'offline':
        return `connection lost at ${of}; trying again…`;
      case 'retrying':
        return `waiting at ${of}: ${this.reason}; trying again…`;
      case 'refused':
        return `refused: ${this.reason}`;
      case 'failed':
        return `stopped at ${of}: ${this.reason}`;
      case 'done':
        return `uploaded (${formatBytes(this.size)})`;
    }
  }

  private set(state: UploadState, reason = ''): void {
    this.state = state;
    this.reason = reason;
    this.changed(this);
  }

  /** Check the file here: refuse at once a frame size the lens cannot read. -> whether it may go. */
  async check(): Promise<boolean> {
    this.set('checking');
    this.probe = await probeFile(this.file);
    const why = lensMismatch(this.probe, this.opts.imageSize, this.opts.lens);
    if (why) {
      this.set('refused', `${why}; choose the lens it was filmed with, or another file`);
      return false;
    }
    this.set('waiting');
    return true;
  }

  /** Register the video (or find its unfinished upload), then send it piece by piece. */
  async run(): Promise<void> {
    if (this.state === 'refused' || this.state === 'done') return;
    this.set('sending');
    try {
      await this.register();
      if (this.state !== 'sending') return;
      await this.send();
    } catch (e) {
      this.fail(e);
    }
  }

  /** Where the server stands on this video: resume an unfinished upload of this file, or register it. */
  private async register(): Promise<void> {
    const path = venuePath(this.opts.venue, `/videos/${encodeURIComponent(this.name)}`);
    let v: Video | null = null;
    try {
      v = await this.api.get<Video>(path);
    } catch (e) {
      if (!(e instanceof AdminError && e.status === 404)) throw e;
    }
    if (v && v.status === 'uploading' && v.size === this.size) {
      this.video = v;
      this.received = v.received;
      return; // resume where the server stands
    }
    if (v && v.status !== 'uploading' && !this.replace) {
      this.video = v;
      this.set('exists');
      return;
    }
    this.video = await this.api.post<Video>(venuePath(this.opts.venue, '/videos'), {
      name: this.name,
      floor: this.opts.floor,
      lens: this.opts.lens,
      role: this.opts.role,
      size: this.size,
    });
    this.received = this.video.received;
  }

  /** Replace the finished video of the same name with this file. */
  replaceExisting(): Promise<void> {
    this.replace = true;
    return this.run();
  }

  private async send(): Promise<void> {
    const piece = pieceOverride(location.search) ?? pieceSize(this.size);
    this.meter.reset();
    this.meter.add(this.received, performance.now());
    for (let p = nextPiece(this.received, this.size, piece); p; p = nextPiece(this.received, this.size, piece)) {
      if (this.state !== 'sending') return;
      const v = await this.put(p.start, p.end);
      this.retries = 0;
      this.video = v;
      this.received = v.received;
      this.sending = 0;
      this.meter.add(this.received, performance.now());
      this.changed(this);
      if (v.status !== 'uploading') break;
    }
    if (this.state !== 'sending') return;
    if (this.video && this.video.status !== 'uploading') {
      this.set('done');
      void this.findTurns();
    }
  }

  /** After the upload: the server finds the turns and stops (a suggest job), followed to its end. */
  async findTurns(): Promise<void> {
    const base = venuePath(this.opts.venue, `/videos/${encodeURIComponent(this.name)}`);
    try {
      let job = await this.api.post<Job>(`${base}/suggest`, undefined, { ifMatch: false });
      this.suggest = job;
      this.changed(this);
      job = await followJob(this.api, job, (j) => {
        if (j.state === 'done') return; // told once the video's document carries what it found
        this.suggest = j;
        this.changed(this);
      });
      if (job.state === 'done') this.video = await this.api.get<Video>(base);
      this.suggest = job;
      this.changed(this);
    } catch (e) {
      this.suggestError = e instanceof Error ? e.message : String(e);
      this.changed(this);
    }
  }

  /** Why the turns and stops could not be found (the video can still be tagged by hand). */
  suggestError = '';

  /** One piece, bytes [start, end): the video as the server then stands. */
  private put(start: number, end: number): Promise<Video> {
    const url =
      this.video?.upload_url ?? venuePath(this.opts.venue, `/videos/${encodeURIComponent(this.name)}/content`);
    return new Promise((resolve, reject) => {
      const xhr = new XMLHttpRequest();
      this.xhr = xhr;
      xhr.open('PUT', url);
      xhr.setRequestHeader('Authorization', `Bearer ${this.api.token}`);
      xhr.setRequestHeader('Content-Range', contentRange({ start, end }, this.size));
      xhr.setRequestHeader('Content-Type', 'application/octet-stream');
      xhr.responseType = 'text';
      xhr.upload.onprogress = (e) => {
        this.sending = Math.min(e.loaded, end - start);
        this.meter.add(this.received + this.sending, performance.now());
        this.changed(this);
      };
      xhr.onload = () => {
        this.xhr = null;
        let body: Record<string, unknown> = {};
        try {
          body = JSON.parse(xhr.responseText || '{}') as Record<string, unknown>;
        } catch {
          // not JSON (a proxy's page): the status says enough
        }
        if (xhr.status >= 200 && xhr.status < 300) return resolve(body as unknown as Video);
        const details = (typeof body.details === 'object' && body.details) || body;
        const msg = typeof body.error === 'string' ? body.error : `the server answered ${xhr.status}`;
        reject(new AdminError(msg, xhr.status, details as Record<string, unknown>));
      };
      xhr.onerror = () => {
        this.xhr = null;
        reject(new AdminError(UNREACHABLE, 0));
      };
      xhr.onabort = () => {
        this.xhr = null;
        reject(new DOMException('paused', 'AbortError'));
      };
      xhr.send(this.file.slice(start, end));
    });
  }

  private fail(e: unknown): void {
    this.sending = 0;
    if (e instanceof DOMException && e.name === 'AbortError') return; // paused: pause() set the state
    if (!(e instanceof AdminError)) return this.set('failed', e instanceof Error ? e.message : String(e));
    const received = Number(e.details.received);
    if (e.status === 409 && Number.isFinite(received)) {
      // the server stands elsewhere (another tab sent pieces, or a piece half arrived): go on from
      // there; standing where we asked, it is still writing the last piece (its request has not
      // noticed the dropped connection yet): wait for it
      const moved = received !== this.received;
      this.received = received;
      if (moved && this.retries++ < 5) {
        void this.run();
        return;
      }
      return this.later('retrying', e.message);
    }
    if (e.status === 422) {
      this.received = Number.isFinite(received) ? received : 0;
      this.meter.reset();
      return this.set('refused', e.message);
    }
    if (e.status === 0 || e.status === 502 || e.status === 503 || e.status === 504)
      return this.later('offline', e.message);
    this.set('failed', e.message);
  }

  /** Try again by itself after a wait that grows with each failed try. */
  private later(state: 'offline' | 'retrying', reason: string): void {
    this.set(state, reason);
    const wait = BACKOFF_S[Math.min(this.retries++, BACKOFF_S.length - 1)];
    this.retryTimer = setTimeout(() => {
      this.retryTimer = null;
      if (this.state === state) void this.run();
    }, wait * 1000);
  }

  /** Stop sending; what reached the server stays there. */
  pause(): void {
    if (this.retryTimer) clearTimeout(this.retryTimer);
    this.retryTimer = null;
    this.set('paused');
    this.xhr?.abort();
  }

  /** Continue from where the server stands (it is asked again: never from a count kept here). */
  resume(): Promise<void> {
    if (this.retryTimer) clearTimeout(this.retryTimer);
    this.retryTimer = null;
    this.retries = 0;
    return this.run();
  }

  /** The connection is back (the browser's `online` event): retry now rather than after the wait. */
  online(): void {
    if (this.state === 'offline' || this.state === 'retrying') void this.resume();
  }

  /** Forget this upload (the page is done with it); an unfinished one can be resumed later. */
  drop(): void {
    if (this.retryTimer) clearTimeout(this.retryTimer);
    this.state = 'paused';
    this.xhr?.abort();
  }
}

/** All uploads of the page, in the order they were chosen; one sends at a time. */
export class Uploads {
  readonly list: Upload[] = [];
  private listeners = new Set<Listener>();
  private pumping = false;

  constructor() {
    addEventListener('online', () => this.list.forEach((u) => u.online()));
  }

  /** Be told of every change (returns the unsubscription). */
  listen(cb: Listener): () => void {
    this.listeners.add(cb);
    return () => this.listeners.delete(cb);
  }

  private emit = (u: Upload): void => {
    for (const cb of this.listeners) cb(u);
    if (u.state !== 'sending' && u.state !== 'checking') void this.pump();
  };

  /** Add files: each is checked at once, then queued. */
  add(files: readonly File[], opts: UploadOptions, api: AdminApi): Upload[] {
    const added: Upload[] = [];
    for (const f of files) {
      // the same file chosen again (after a reload, or twice) continues its upload, not a second one
      const old = this.list.find((u) => u.opts.venue === opts.venue && u.name === videoName(f.name));
      if (old && old.state !== 'done' && old.state !== 'refused') {
        if (old.state === 'paused' || old.state === 'failed') void old.resume();
        added.push(old);
        continue;
      }
      if (old) this.list.splice(this.list.indexOf(old), 1);
      const u = new Upload(f, opts, api, this.emit);
      this.list.push(u);
      added.push(u);
      void u.check().then(() => this.pump());
    }
    return added;
  }

  remove(u: Upload): void {
    u.drop();
    const i = this.list.indexOf(u);
    if (i >= 0) this.list.splice(i, 1);
    for (const cb of this.listeners) cb(u);
  }

  /** Start the next waiting upload when none is sending. */
  private async pump(): Promise<void> {
    if (this.pumping) return;
    if (this.list.some((u) => u.state === 'sending' || u.state === 'offline' || u.state === 'retrying')) return;
    const next = this.list.find((u) => u.state === 'waiting');
    if (!next) return;
    this.pumping = true;
    try {
      await next.run();
    } finally {
      this.pumping = false;
    }
    void this.pump();
  }
}

/** The page's one upload queue (it outlives the screens). */
export const uploads = new Uploads();
