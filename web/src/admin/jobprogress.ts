/**
 * A background job (quality map, evaluation) followed on a screen: a labelled progress bar with
 * frames done, frames per second and time left, read from the job's event stream, and a Cancel
 * button. The stream ends with the job's final state, which `follow` resolves with.
 */
import { AdminError, type AdminApi } from './api';
import type { Job } from './types';

const FINAL = new Set<Job['state']>(['done', 'failed', 'cancelled']);

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

  /**
   * Follow `job` to its end through its event stream, showing each step; resolves with the final
   * job. A dropped stream is re-opened (after a read of the job) until the job ends or `signal` aborts.
   */
  async follow(job: Job, signal: AbortSignal): Promise<Job> {
    this.show(job);
    let last = job;
    while (!FINAL.has(last.state) && !signal.aborted) {
      try {
        await this.api.stream(
          `/api/admin/jobs/${encodeURIComponent(job.id)}/events`,
          (e) => {
            if (e.event === 'message' || !e.data) return;
            last = JSON.parse(e.data) as Job;
            this.show(last);
          },
          signal,
        );
      } catch (e) {
        if (signal.aborted) break;
        if (e instanceof AdminError && e.status !== 0) throw e;
      }
      if (!FINAL.has(last.state) && !signal.aborted) {
        await new Promise((r) => setTimeout(r, 1000));
        last = await this.api.get<Job>(`/api/admin/jobs/${encodeURIComponent(job.id)}`, signal);
        this.show(last);
      }
    }
    return last;
  }
}
