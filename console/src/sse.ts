// Server-sent events over fetch (EventSource cannot send an Authorization header): a
// ReadableStream parser of `id:`, `event:`, `data:` and `retry:` lines, resuming with
// Last-Event-ID after a dropped connection.

import { errorOf, token } from './api';

export interface SseEvent { id: string; event: string; data: string }

export interface SseOptions {
  onEvent: (e: SseEvent) => void;
  /** Whether the stream is over for good (e.g. after a final state): no reconnect. */
  done?: () => boolean;
  onError?: (e: unknown) => void;
  onOpen?: () => void;
}

/** Feeds text chunks, calls `emit` per complete event (WHATWG parsing rules). */
export class SseParser {
  private buf = '';
  private data: string[] = [];
  private event = '';
  lastId = '';
  retry: number | null = null;

  constructor(private emit: (e: SseEvent) => void) {}

  push(chunk: string): void {
    this.buf += chunk;
    let i: number;
    // Lines end with CRLF, LF or CR; a lone CR at the end may be half of a CRLF.
    while ((i = this.buf.search(/\r\n|\n|\r(?!$)/)) >= 0) {
      const line = this.buf.slice(0, i);
      const eol = this.buf.startsWith('\r\n', i) ? 2 : 1;
      this.buf = this.buf.slice(i + eol);
      this.line(line);
    }
  }

  private line(line: string): void {
    if (line === '') {
      if (this.data.length) {
        this.emit({ id: this.lastId, event: this.event || 'message', data: this.data.join('\n') });
      }
      this.data = [];
      this.event = '';
      return;
    }
    if (line.startsWith(':')) return;
    const c = line.indexOf(':');
    const name = c < 0 ? line : line.slice(0, c);
    let value = c < 0 ? '' : line.slice(c + 1);
    if (value.startsWith(' ')) value = value.slice(1);
    if (name === 'data') this.data.push(value);
    else if (name === 'event') this.event = value;
    else if (name === 'id') {
      if (!value.includes('\0')) this.lastId = value;
    } else if (name === 'retry' && /^\d+$/.test(value)) this.retry = +value;
  }
}

/** Reads `url` as an event stream until `done()` or `stop()`; reconnects with Last-Event-ID. */
export function stream(url: string, opts: SseOptions): { stop: () => void } {
  const abort = new AbortController();
  let stopped = false;
  let lastId = '';
  let delay = 1000;
  const run = async () => {
    while (!stopped) {
      const parser = new SseParser((e) => {
        lastId = e.id || lastId;
        opts.onEvent(e);
      });
      parser.lastId = lastId;
      try {
        const headers: Record<string, string> = { Accept: 'text/event-stream' };
        const t = token();
        if (t) headers.Authorization = `Bearer ${t}`;
        if (lastId) headers['Last-Event-ID'] = lastId;
        const res = await fetch(url, { headers, signal: abort.signal, cache: 'no-store' });
        if (!res.ok) {
          const err = await errorOf(res);
          if (res.status !== 429 && res.status !== 503) throw Object.assign(err, { fatal: true });
          throw err;
        }
        opts.onOpen?.();
        delay = 1000;
        const reader = res.body!.pipeThrough(new TextDecoderStream()).getReader();
        for (;;) {
          const { value, done } = await reader.read();
          if (done) break;
          parser.push(value);
        }
      } catch (e) {
        if (stopped || (e as Error).name === 'AbortError') return;
        opts.onError?.(e);
        if ((e as { fatal?: boolean }).fatal) return;
      }
      if (stopped || opts.done?.()) return;
      if (parser.retry !== null) delay = parser.retry;
      await new Promise((r) => setTimeout(r, delay));
      delay = Math.min(delay * 2, 15000);
    }
  };
  void run();
  return {
    stop: () => {
      stopped = true;
      abort.abort();
    },
  };
}
