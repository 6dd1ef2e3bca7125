// REST client for linerwatch-server. A 401 opens the token prompt and retries with the new token;
// the token lives in sessionStorage (this tab only).
const TOKEN_KEY = 'linerwatch.token';

export class ApiError extends Error {
  constructor(status, message) {
    super(message);
    this.status = status;
  }
}

export function getToken() {
  return sessionStorage.getItem(TOKEN_KEY) || '';
}

export function setToken(token) {
  if (token) sessionStorage.setItem(TOKEN_KEY, token);
  else sessionStorage.removeItem(TOKEN_KEY);
}

let pendingPrompt = null;

// Opens the token dialog once even when several requests fail together; resolves with the token.
export function promptForToken(reason) {
  if (pendingPrompt) return pendingPrompt;
  const dialog = document.getElementById('token-dialog');
  const input = document.getElementById('token-input');
  document.getElementById('token-reason').textContent = reason;
  input.value = '';
  pendingPrompt = new Promise((resolve) => {
    const form = document.getElementById('token-form');
    const onSubmit = (ev) => {
      ev.preventDefault();
      const token = input.value.trim();
      if (!token) return;
      form.removeEventListener('submit', onSubmit);
      dialog.close();
      setToken(token);
      pendingPrompt = null;
      resolve(token);
    };
    form.addEventListener('submit', onSubmit);
    dialog.addEventListener('cancel', (ev) => ev.preventDefault(), { once: true });
  });
  dialog.showModal();
  input.focus();
  return pendingPrompt;
}

async function request(method, path, body) {
  for (let attempt = 0; attempt < 4; attempt++) {
    const headers = { Accept: 'application/json' };
    const token = getToken();
    if (token) headers.Authorization = `Bearer ${token}`;
    if (body !== undefined) headers['Content-Type'] = 'application/json';
    const res = await fetch(path, { method, headers, body: body === undefined ? undefined : JSON.stringify(body) });
    if (res.status === 401) {
      await promptForToken(token
        ? 'The server refused this token. Enter a valid access token.'
        : 'This linerwatch server is protected. Enter your access token.');
      continue;
    }
    let data = null;
    const text = await res.text();
    try { data = text ? JSON.parse(text) : null; } catch { data = null; }
    if (!res.ok) {
      const msg = (data && data.error) || `${res.status} ${res.statusText}`;
      throw new ApiError(res.status, `${method} ${path}: ${msg}`);
    }
    return data;
  }
  throw new ApiError(401, `${method} ${path}: not authorised`);
}

export const api = {
  get: (path) => request('GET', path),
  post: (path, body) => request('POST', path, body ?? {}),
};

const enc = encodeURIComponent;
export const paths = {
  crushers: () => '/api/v1/crushers',
  crusher: (c) => `/api/v1/crushers/${enc(c)}`,
  sensors: (c) => `/api/v1/crushers/${enc(c)}/sensors`,
  readings: (c, s, params) => `/api/v1/crushers/${enc(c)}/sensors/${enc(s)}/readings?${new URLSearchParams(params)}`,
  mesh: (c) => `/api/v1/crushers/${enc(c)}/mesh`,
  wear: (c, faces = true) => `/api/v1/crushers/${enc(c)}/wear${faces ? '' : '?faces=false'}`,
  forecast: (c) => `/api/v1/crushers/${enc(c)}/forecast`,
  diagnosis: (c) => `/api/v1/crushers/${enc(c)}/diagnosis`,
  events: (c) => `/api/v1/crushers/${enc(c)}/events`,
  alarms: (c) => `/api/v1/crushers/${enc(c)}/alarms`,
  ack: (c, id) => `/api/v1/crushers/${enc(c)}/alarms/${enc(id)}/ack`,
  campaigns: (c) => `/api/v1/crushers/${enc(c)}/campaigns`,
};

// Reads every page of a sensor's readings (oldest first), from `from` (ISO time) when given.
export async function allReadings(crusher, sensor, from) {
  const out = [];
  let cursor = null;
  for (let page = 0; page < 200; page++) {
    const params = { limit: '5000' };
    if (from) params.from = from;
    if (cursor) params.cursor = cursor;
    const res = await api.get(paths.readings(crusher, sensor, params));
    out.push(...(res.readings || []));
    cursor = res.next_cursor;
    if (!cursor) break;
  }
  return out;
}

// Server-sent events with our own reconnect (EventSource gives up for good on an HTTP error).
export function subscribe(crusher, handlers, onState) {
  let source = null;
  let closed = false;
  let delay = 1000;
  let timer = null;
  const open = () => {
    if (closed) return;
    onState('connecting');
    const token = getToken();
    const url = paths.events(crusher) + (token ? `?access_token=${enc(token)}` : '');
    source = new EventSource(url);
    source.onopen = () => { delay = 1000; onState('live'); };
    for (const [name, fn] of Object.entries(handlers)) {
      source.addEventListener(name, (ev) => {
        let data;
        try { data = JSON.parse(ev.data); } catch { return; }
        fn(data);
      });
    }
    source.onerror = () => {
      if (closed) return;
      if (source.readyState === EventSource.CLOSED) {
        onState('lost');
        clearTimeout(timer);
        timer = setTimeout(open, delay);
        delay = Math.min(delay * 2, 30000);
      } else {
        onState('connecting');
      }
    };
  };
  open();
  return () => { closed = true; clearTimeout(timer); if (source) source.close(); onState('off'); };
}
