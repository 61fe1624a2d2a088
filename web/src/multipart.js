// SPDX-License-Identifier: Apache-2.0
// Incremental parser of a multipart/x-mixed-replace body (the cameras' live
// view, GET /api/v1/cameras/{name}/stream.mjpg): the page reads the stream
// with fetch() to send the bearer token, which an <img> cannot, and so splits
// it into parts itself. Bytes in, parts out; no DOM, so that node can test it.
//
// A part is `--BOUNDARY CRLF headers CRLF CRLF body CRLF`; the stream ends
// with `--BOUNDARY--`. A part with a Content-Length is cut by its length (a
// JPEG may hold any bytes); one without it ends at the next CRLF--BOUNDARY.

const LF = 0x0a;
const CR = 0x0d;
const DASH = 0x2d;

// The boundary parameter of a Content-Type (quoted or not), or null.
export function boundaryOf(contentType) {
  if (typeof contentType !== 'string') return null;
  const match = /;\s*boundary\s*=\s*(?:"([^"]+)"|([^\s;]+))/i.exec(contentType);
  if (!match) return null;
  return match[1] ?? match[2];
}

function concat(a, b) {
  if (a.length === 0) return b;
  const out = new Uint8Array(a.length + b.length);
  out.set(a, 0);
  out.set(b, a.length);
  return out;
}

// First index >= from of `needle` in `haystack`, or -1.
function indexOf(haystack, needle, from = 0) {
  const first = needle[0];
  const last = haystack.length - needle.length;
  outer: for (let i = Math.max(0, from); i <= last; i++) {
    if (haystack[i] !== first) continue;
    for (let j = 1; j < needle.length; j++) {
      if (haystack[i + j] !== needle[j]) continue outer;
    }
    return i;
  }
  return -1;
}

const decoder = new TextDecoder('latin1');

export class MultipartError extends Error {}

export class MultipartParser {
  // `maxHeaderBytes` and `maxPartBytes` bound what a broken or hostile stream
  // can make the page hold: past them push() throws MultipartError.
  constructor(boundary, { maxHeaderBytes = 16 * 1024, maxPartBytes = 64 * 1024 * 1024 } = {}) {
    if (!boundary) throw new MultipartError('multipart: no boundary');
    this.delimiter = new TextEncoder().encode(`--${boundary}`);
    this.maxHeaderBytes = maxHeaderBytes;
    this.maxPartBytes = maxPartBytes;
    this.buffer = new Uint8Array(0);
    this.state = 'delimiter'; // 'delimiter' | 'headers' | 'body'
    this.lineStart = true; // whether buffer[0] starts a line
    this.searchFrom = 0; // where the next search for a delimiter resumes
    this.headers = null;
    this.length = -1;
    this.closed = false; // the closing delimiter was seen
  }

  // Feeds bytes (a Uint8Array); returns the parts they complete, in order:
  // {headers: {lower-case name: value}, body: Uint8Array}. Bytes after the
  // closing delimiter are ignored.
  push(chunk) {
    if (this.closed) return [];
    this.buffer = concat(this.buffer, chunk instanceof Uint8Array ? chunk : new Uint8Array(chunk));
    const parts = [];
    for (;;) {
      if (this.state === 'delimiter' && !this.readDelimiter()) break;
      if (this.closed) break;
      if (this.state === 'headers' && !this.readHeaders()) break;
      if (this.state === 'body') {
        const part = this.readBody();
        if (!part) break;
        parts.push(part);
      }
    }
    return parts;
  }

  // Finds the next delimiter line that starts a line (anything before it is
  // preamble or the CRLF ending the previous part); true once past it.
  readDelimiter() {
    const buffer = this.buffer;
    let at = this.searchFrom;
    for (;;) {
      at = indexOf(buffer, this.delimiter, at);
      if (at < 0 || (at === 0 ? this.lineStart : buffer[at - 1] === LF)) break;
      at++;
    }
    if (at < 0) {
      // Keep what may be the start of a delimiter, and the byte before it.
      const keep = this.delimiter.length;
      if (buffer.length > keep) {
        const cut = buffer.length - keep;
        this.lineStart = buffer[cut - 1] === LF;
        this.buffer = buffer.subarray(cut);
      }
      this.searchFrom = 0;
      return false;
    }
    const after = at + this.delimiter.length;
    if (buffer.length < after + 2) return this.keepFrom(at);
    if (buffer[after] === DASH && buffer[after + 1] === DASH) {
      this.closed = true;
      this.buffer = new Uint8Array(0);
      return true;
    }
    // The rest of the delimiter line (transport padding) up to its LF.
    const eol = buffer.indexOf(LF, after);
    if (eol < 0) {
      if (buffer.length - after > this.maxHeaderBytes) throw new MultipartError('multipart: delimiter line too long');
      return this.keepFrom(at);
    }
    this.buffer = buffer.subarray(eol + 1);
    this.lineStart = true;
    this.searchFrom = 0;
    this.state = 'headers';
    return true;
  }

  keepFrom(at) {
    this.buffer = this.buffer.subarray(at);
    this.lineStart = true;
    this.searchFrom = 0;
    return false;
  }

  // The header lines up to the blank line; true once past it.
  readHeaders() {
    const buffer = this.buffer;
    const headers = {};
    let at = 0;
    for (;;) {
      const eol = buffer.indexOf(LF, at);
      if (eol < 0) {
        if (buffer.length > this.maxHeaderBytes) throw new MultipartError('multipart: part headers too long');
        return false;
      }
      const end = eol > at && buffer[eol - 1] === CR ? eol - 1 : eol;
      const line = decoder.decode(buffer.subarray(at, end));
      at = eol + 1;
      if (line === '') break;
      const colon = line.indexOf(':');
      if (colon > 0) headers[line.slice(0, colon).trim().toLowerCase()] = line.slice(colon + 1).trim();
    }
    this.buffer = buffer.subarray(at);
    this.headers = headers;
    const length = headers['content-length'];
    this.length = length !== undefined && /^\d+$/.test(length) ? Number(length) : -1;
    if (this.length > this.maxPartBytes) throw new MultipartError(`multipart: a part of ${this.length} bytes is too large`);
    this.searchFrom = 0;
    this.state = 'body';
    return true;
  }

  // The body, by its Content-Length or up to the next CRLF--BOUNDARY.
  readBody() {
    const buffer = this.buffer;
    let end;
    let next;
    if (this.length >= 0) {
      if (buffer.length < this.length) return null;
      end = this.length;
      next = this.length;
    } else {
      let at = this.searchFrom;
      for (;;) {
        at = indexOf(buffer, this.delimiter, at);
        if (at < 0 || (at > 0 && buffer[at - 1] === LF)) break;
        at++;
      }
      if (at < 0) {
        if (buffer.length > this.maxPartBytes) throw new MultipartError('multipart: a part is too large');
        this.searchFrom = Math.max(0, buffer.length - this.delimiter.length);
        return null;
      }
      // The CRLF (or LF) before the delimiter belongs to it, not to the body.
      end = at - 1;
      if (end > 0 && buffer[end - 1] === CR) end--;
      next = at;
    }
    const part = { headers: this.headers, body: buffer.slice(0, end) };
    this.buffer = buffer.subarray(next);
    // What follows a body is a delimiter, after the CRLF that ends the body
    // (cut by length) or at once (cut at the delimiter): a line start either way.
    this.lineStart = true;
    this.searchFrom = 0;
    this.headers = null;
    this.length = -1;
    this.state = 'delimiter';
    return part;
  }
}
