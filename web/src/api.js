// SPDX-License-Identifier: Apache-2.0
// Requests to cylscand's API (docs/http-api.md), same origin, with the
// bearer token of this tab when the head asks for one.

const TOKEN_KEY = 'cylscan.token';

export class ApiError extends Error {
  constructor(status, message) {
    super(message);
    this.status = status;
  }
}

let authNeeded = () => {};

// `handler` is called whenever the daemon answers 401.
// Whether `error` is the head's answer with HTTP `status`.
export function isStatus(error, status) {
  return error instanceof ApiError && error.status === status;
}

export function onAuthNeeded(handler) {
  authNeeded = handler;
}

export function token() {
  return sessionStorage.getItem(TOKEN_KEY) || '';
}

export function setToken(value) {
  if (value) sessionStorage.setItem(TOKEN_KEY, value);
  else sessionStorage.removeItem(TOKEN_KEY);
}

// URL of an API path, relative to the page (so a proxy prefix keeps working).
export function apiUrl(path) {
  return new URL(`api/v1/${path}`, document.baseURI).toString();
}

export function authHeaders(extra = {}) {
  const headers = { ...extra };
  const t = token();
  if (t) headers.Authorization = `Bearer ${t}`;
  return headers;
}

async function errorOf(response) {
  let message = `${response.status} ${response.statusText}`;
  try {
    const body = await response.json();
    if (body && typeof body.error === 'string') message = body.error;
  } catch {
    // not JSON: keep the status line
  }
  return new ApiError(response.status, message);
}

// fetch() of an API path; throws ApiError (with the daemon's message) unless 2xx.
export async function request(path, { method = 'GET', json, headers = {}, signal, cache } = {}) {
  const init = { method, headers: authHeaders(headers), signal };
  if (cache) init.cache = cache;
  if (json !== undefined) {
    init.headers['Content-Type'] = 'application/json';
    init.body = JSON.stringify(json);
  }
  const response = await fetch(apiUrl(path), init);
  if (response.status === 401) authNeeded();
  if (!response.ok) throw await errorOf(response);
  return response;
}

export async function getJson(path) {
  return (await request(path, { headers: { Accept: 'application/json' } })).json();
}

export async function postJson(path, body) {
  return (await request(path, { method: 'POST', json: body })).json();
}

export async function patchJson(path, body) {
  return (await request(path, { method: 'PATCH', json: body })).json();
}

export async function getBytes(path, signal) {
  return (await request(path, { signal })).arrayBuffer();
}

export async function getBlob(path, signal) {
  return (await request(path, { signal })).blob();
}

export async function remove(path) {
  await request(path, { method: 'DELETE' });
}

// What a call made by newestOnly() gives when a later call has answered first.
export const STALE = Symbol('a stale answer');

// Wraps an async function whose calls overlap so that an answer is never
// taken after that of a call made later: such a call resolves to STALE.
// Answers of requests can come back out of order (the daemon serves them on
// several threads), and what is shown must not go back to an older state.
export function newestOnly(fn) {
  let asked = 0;
  let answered = 0;
  return async (...args) => {
    const call = ++asked;
    const answer = await fn(...args);
    if (call < answered) return STALE;
    answered = call;
    return answer;
  };
}
