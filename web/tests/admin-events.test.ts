// The job event stream as the admin page reads it (fetch + the token header, so not EventSource):
// the text/event-stream format, cut into pieces anywhere, as the server's /jobs/{id}/events sends it.
import { describe, expect, it } from 'vitest';
import { EventParser, type StreamEvent } from '../src/admin/api';

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
