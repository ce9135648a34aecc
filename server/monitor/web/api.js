// Calls to the coordinator's JSON API. The client token (when the farm has one) is kept in
// sessionStorage (gone with the tab) and sent as `Authorization: Bearer` on every call; images
// are fetched the same way and shown through blob: URLs, since an <img src> cannot carry it.
const KEY = 'tessera-token';

export class Unauthenticated extends Error {}

export function setToken(token) { sessionStorage.setItem(KEY, token); }
export function clearToken() { sessionStorage.removeItem(KEY); }

async function call(path, options = {}) {
  const headers = new Headers(options.headers || {});
  const token = sessionStorage.getItem(KEY);
  if (token) headers.set('Authorization', 'Bearer ' + token);
  const response = await fetch(path, { ...options, headers, cache: 'no-store' });
  if (response.status === 401) throw new Unauthenticated((await response.json()).error);
  if (!response.ok) {
    let message = response.statusText;
    try { message = (await response.json()).error; } catch (e) { /* not JSON */ }
    throw new Error(message);
  }
  return response;
}

export async function getJson(path) { return (await call(path)).json(); }

export async function postJson(path, body) {
  const response = await call(path, {
    method: 'POST', headers: { 'Content-Type': 'application/json' }, body: JSON.stringify(body),
  });
  return response.json();
}

export async function getBlob(path) { return (await call(path)).blob(); }
