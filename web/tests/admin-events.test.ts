// The job event stream as the admin page reads it (fetch + the token header, so not EventSource):
// the text/event-stream format, cut into pieces anywhere, as the server's /jobs/{id}/events sends it.
import { describe, expect, it } from 'vitest';
import { AdminError, EventParser, type StreamEvent } from '../src/admin/api';
import { followJob } from '../src/admin/jobprogress';
import type { Job } from '../src/admin/types';

function parse(pieces: string[]): StreamEvent[] {
  const out: StreamEvent[] = [];
  const p = new EventParser((e) => out.push(e));
  for (const s of pieces) p.push(s);
  return out;
}

const job = (state: string, done: number) => JSON.stringify({ id: 'j1', state, frames_done: done, frames_total: 10 });
const stream =
  `event: progress\ndata: ${job('running', 3)}\n\n` +
  ': still running\n\n' +
  `event: progress\ndata: ${job('running', 7)}\n\n` +
  `event: done\ndata: ${job('done', 10)}\n\n`;

describe('job events', () => {
  it('progress, a keep-alive comment, then the final state', () => {
    const evs = parse([stream]);
    expect(evs.map((e) => e.event)).toEqual(['progress', 'progress', 'done']);
    expect(evs.map((e) => JSON.parse(e.data).frames_done)).toEqual([3, 7, 10]);
  });
  it('the same events however the network cuts the bytes', () => {
    const whole = parse([stream]);
    for (let cut = 1; cut < stream.length; cut += 7) {
      expect(parse([stream.slice(0, cut), stream.slice(cut)])).toEqual(whole);
    }
    expect(parse(stream.split(''))).toEqual(whole);
  });
  it('CRLF and CR line ends, a CRLF cut between its two characters', () => {
    const crlf = stream.replace(/\n/g, '\r\n');
    expect(parse([crlf])).toEqual(parse([stream]));
    const at = crlf.indexOf('\r\n') + 1;
    expect(parse([crlf.slice(0, at), crlf.slice(at)])).toEqual(parse([stream]));
    // a CR last in what has arrived may be half a CRLF: it waits for the next bytes (or the end)
    expect(parse([stream.replace(/\n/g, '\r'), '\n\n'])).toEqual(parse([stream]));
  });
  it('several data lines join with a newline; one space after the colon is dropped; no event name is a message', () => {
    expect(parse(['data: a\ndata:b\ndata:  c\n\n'])).toEqual([{ event: 'message', data: 'a\nb\n c' }]);
  });
  it('an event without data is not dispatched; an unfinished one waits for its blank line', () => {
    expect(parse(['event: progress\n\n'])).toEqual([]);
    expect(parse(['event: done\ndata: x\n'])).toEqual([]);
  });
});

describe('following a job', () => {
  const j = (state: string, done: number): Job => ({ id: 'j1', state, frames_done: done, frames_total: 10 }) as Job;
  const asApi = (api: unknown) => api as Parameters<typeof followJob>[0];

  it('polls when the server refuses one more stream (503), and does not open another', async () => {
    let streams = 0;
    const reads = [j('running', 4), j('running', 8), j('done', 10)];
    const api = {
      stream: async () => {
        streams += 1;
        throw new AdminError('the server is busy; try again in a moment', 503);
      },
      get: async <T>() => reads.shift() as T,
    };
    const seen: number[] = [];
    const last = await followJob(asApi(api), j('queued', 0), (x) => seen.push(x.frames_done), undefined, 1);
    expect(last.state).toBe('done');
    expect(seen).toEqual([4, 8, 10]);
    expect(streams).toBe(1);
  });

  it('a stream that ends early is read again after a poll; a 404 is thrown', async () => {
    let streams = 0;
    const api = {
      stream: async (_p: string, on: (e: StreamEvent) => void) => {
        streams += 1;
        on({ event: 'progress', data: JSON.stringify(j('running', 5)) });
        if (streams === 2) on({ event: 'done', data: JSON.stringify(j('done', 10)) });
      },
      get: async <T>() => j('running', 6) as T,
    };
    const last = await followJob(asApi(api), j('queued', 0), () => {}, undefined, 1);
    expect(last.state).toBe('done');
    expect(streams).toBe(2);
    const gone = {
      stream: async () => {
        throw new AdminError('no such job', 404);
      },
      get: async <T>() => j('running', 1) as T,
    };
    await expect(followJob(asApi(gone), j('queued', 0), () => {}, undefined, 1)).rejects.toThrow('no such job');
  });
});

describe('an image the server is busy making', () => {
  it('is asked for again after a 503, up to twice more, and a 404 is not', async () => {
    const { AdminApi } = await import('../src/admin/api');
    const statuses = [503, 503, 200];
    const asked: string[] = [];
    const realFetch = globalThis.fetch;
    const realUrl = URL.createObjectURL;
    globalThis.fetch = (async (path: string) => {
      asked.push(path);
      const status = statuses.shift() ?? 404;
      const body = status === 200 ? 'jpeg' : JSON.stringify({ error: 'the server is busy', status });
      return new Response(body, { status, headers: { 'Content-Type': 'application/json' } });
    }) as typeof fetch;
    URL.createObjectURL = () => 'blob:frame';
    try {
      const api = new AdminApi('t');
      expect(await api.blobUrl('/api/admin/x/frame', undefined, 1)).toBe('blob:frame');
      expect(asked).toHaveLength(3);
      await expect(api.blobUrl('/api/admin/x/frame', undefined, 1)).rejects.toMatchObject({ status: 404 });
      expect(asked).toHaveLength(4);
    } finally {
      globalThis.fetch = realFetch;
      URL.createObjectURL = realUrl;
    }
  });
});
