/**
 * A background job (quality map, evaluation) followed on a screen: a labelled progress bar with
 * frames done, frames per second and time left, read from the job's event stream, and a Cancel
 * button. `follow` resolves with the job's final state.
 */
import { AdminError, type AdminApi } from './api';
import type { Job } from './types';

export const FINAL = new Set<Job['state']>(['done', 'failed', 'cancelled']);

/** The parts of the admin API that following a job needs (a fake in the unit tests). */
type JobReader = Pick<AdminApi, 'get' | 'stream'>;

/**
 * Follow a job to its final state: its event stream while the server keeps one open, else a read of
 * the job every `pollMs`. The server bounds the streams open at once (503 over the bound, and the
 * page polls from then on) and a stream may drop (it is read again after a poll), so a ninth
 * followed upload still shows its progress. Calls `onJob` with each new state; resolves with the final one (or the last
 * seen when `signal` aborts). Other refusals (401, 404) are thrown.
 */
export async function followJob(
  api: JobReader,
  job: Job,
  onJob: (j: Job) => void,
  signal?: AbortSignal,
  pollMs = 1000,
): Promise<Job> {
  const path = `/api/admin/jobs/${encodeURIComponent(job.id)}`;
  let last = job;
  let streams = true;
  while (!FINAL.has(last.state) && !signal?.aborted) {
    if (streams) {
      try {
        await api.stream(
          `${path}/events`,
          (e) => {
            if (e.event === 'message' || !e.data) return;
            last = JSON.parse(e.data) as Job;
            onJob(last);
          },
          signal,
        );
      } catch (e) {
        if (signal?.aborted) break;
        if (!(e instanceof AdminError)) throw e;
        if (e.status === 503)
          streams = false; // over the bound: poll from now on
        else if (e.status !== 0) throw e;
      }
    }
    if (!FINAL.has(last.state) && !signal?.aborted) {
      await new Promise((r) => setTimeout(r, pollMs));
      last = await api.get<Job>(path, signal);
      onJob(last);
    }
  }
  return last;
}

/** "120 of 234 frames, 41 frames/s, about 3 s left" (or "waiting to start"). */
export function progressText(job: Job): string {
  if (job.state === 'queued') return 'waiting to start';
  if (job.state === 'done') return `done: ${job.frames_total} frames`;
  if (job.state === 'failed') return `failed: ${job.error ?? 'no reason given'}`;
  if (job.state === 'cancelled') return 'cancelled';
  if (job.frames_total <= 0) return 'starting';
  const parts = [`${job.frames_done} of ${job.frames_total} frames`];
  if (job.frames_per_s > 0) parts.push(`${job.frames_per_s.toFixed(job.frames_per_s < 10 ? 1 : 0)} frames/s`);
  if (job.eta_s !== null) parts.push(`about ${Math.max(0, Math.round(job.eta_s))} s left`);
  return parts.join(', ');
}

/** 0..100 */
export const progressPercent = (job: Job): number =>
  job.state === 'done' ? 100 : job.frames_total > 0 ? Math.round((100 * job.frames_done) / job.frames_total) : 0;

export class JobProgress {
  readonly el: HTMLElement;
  private readonly bar: HTMLProgressElement;
  private readonly text: HTMLElement;
  private readonly cancel: HTMLButtonElement;
  private job: Job | null = null;
  /** A job is being followed (the screen keeps its start button disabled meanwhile). */
  busy = false;

  /** `label` names the bar ("Quality map progress"); `api` cancels. */
  constructor(
    private readonly api: AdminApi,
    label: string,
  ) {
    this.el = document.createElement('div');
    this.el.className = 'job';
    this.el.hidden = true;
    const id = `job-${Math.random().toString(36).slice(2)}`;
    const lab = document.createElement('label');
    lab.htmlFor = id;
    lab.textContent = label;
    this.bar = document.createElement('progress');
    this.bar.id = id;
    this.bar.max = 100;
    this.bar.value = 0;
    this.text = document.createElement('span');
    this.text.className = 'job-text';
    this.cancel = document.createElement('button');
    this.cancel.type = 'button';
    this.cancel.textContent = 'Cancel';
    this.cancel.addEventListener('click', () => void this.stop());
    this.el.append(lab, ' ', this.bar, ' ', this.text, ' ', this.cancel);
  }

  show(job: Job): void {
    this.job = job;
    this.el.hidden = false;
    this.bar.value = progressPercent(job);
    this.bar.setAttribute('aria-valuetext', `${progressPercent(job)} %`);
    this.text.textContent = progressText(job);
    this.cancel.hidden = FINAL.has(job.state);
  }

  private async stop(): Promise<void> {
    if (!this.job) return;
    try {
      this.show(await this.api.post<Job>(`/api/admin/jobs/${encodeURIComponent(this.job.id)}/cancel`));
    } catch (e) {
      this.text.textContent = e instanceof Error ? e.message : String(e);
    }
  }

  /** Follow `job` to its end (followJob), showing each step; resolves with the final job. */
  follow(job: Job, signal: AbortSignal): Promise<Job> {
    this.show(job);
    return followJob(this.api, job, (j) => this.show(j), signal);
  }
}
