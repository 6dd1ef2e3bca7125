// Shared helpers: the thickness colour scale, formatting, DOM building.

// Red (at or below the minimum thickness) through yellow to blue (as new): thin is hot.
const STOPS = [
  [0.0, [165, 0, 38]],
  [0.12, [215, 48, 39]],
  [0.28, [244, 109, 67]],
  [0.42, [253, 174, 97]],
  [0.56, [254, 224, 144]],
  [0.68, [224, 243, 248]],
  [0.8, [145, 191, 219]],
  [0.9, [69, 117, 180]],
  [1.0, [49, 54, 149]],
];
const BELOW_MIN = [90, 0, 60];

export function thicknessColor(mm, minMm, newMm) {
  if (mm == null || !Number.isFinite(mm)) return [150, 156, 164];
  if (mm < minMm) return BELOW_MIN;
  const t = Math.max(0, Math.min(1, (mm - minMm) / (newMm - minMm)));
  for (let i = 1; i < STOPS.length; i++) {
    if (t <= STOPS[i][0]) {
      const [t0, c0] = STOPS[i - 1];
      const [t1, c1] = STOPS[i];
      const f = (t - t0) / (t1 - t0);
      return [0, 1, 2].map((k) => Math.round(c0[k] + f * (c1[k] - c0[k])));
    }
  }
  return STOPS[STOPS.length - 1][1];
}

export const rgb = (c) => `rgb(${c[0]},${c[1]},${c[2]})`;

export function fmt(x, digits = 1) {
  return x == null || !Number.isFinite(x) ? '–' : x.toFixed(digits);
}

export function parseTime(t) {
  return t ? Date.parse(t) : NaN;
}

export function fmtDate(t) {
  const ms = typeof t === 'number' ? t : parseTime(t);
  if (!Number.isFinite(ms)) return '–';
  return new Date(ms).toISOString().slice(0, 10);
}

export function fmtDateTime(t) {
  const ms = typeof t === 'number' ? t : parseTime(t);
  if (!Number.isFinite(ms)) return '–';
  return new Date(ms).toISOString().slice(0, 16).replace('T', ' ') + ' UTC';
}

export function ago(t) {
  const ms = parseTime(t);
  if (!Number.isFinite(ms)) return '–';
  const s = (Date.now() - ms) / 1000;
  if (s < 0) return fmtDateTime(ms);
  if (s < 90) return `${Math.round(s)} s ago`;
  if (s < 5400) return `${Math.round(s / 60)} min ago`;
  if (s < 48 * 3600) return `${Math.round(s / 3600)} h ago`;
  return `${Math.round(s / 86400)} d ago`;
}

export function daysBetween(a, b) {
  return (b - a) / 86400000;
}

// h('div', {class: 'x', onclick: fn}, child, 'text', ...)
export function h(tag, attrs, ...children) {
  const el = document.createElement(tag);
  for (const [k, v] of Object.entries(attrs || {})) {
    if (v == null || v === false) continue;
    if (k.startsWith('on')) el.addEventListener(k.slice(2), v);
    else if (k === 'style' && typeof v === 'object') Object.assign(el.style, v);
    else el.setAttribute(k, v === true ? '' : String(v));
  }
  for (const c of children.flat()) {
    if (c == null || c === false) continue;
    el.append(c instanceof Node ? c : document.createTextNode(String(c)));
  }
  return el;
}

const SVGNS = 'http://www.w3.org/2000/svg';
export function s(tag, attrs, ...children) {
  const el = document.createElementNS(SVGNS, tag);
  for (const [k, v] of Object.entries(attrs || {})) {
    if (v == null || v === false) continue;
    if (k.startsWith('on')) el.addEventListener(k.slice(2), v);
    else el.setAttribute(k, String(v));
  }
  for (const c of children.flat()) {
    if (c == null || c === false) continue;
    el.append(c instanceof Node ? c : document.createTextNode(String(c)));
  }
  return el;
}

// "Nice" tick values covering [lo, hi].
export function ticks(lo, hi, count = 6) {
  if (!(hi > lo)) return [lo];
  const raw = (hi - lo) / count;
  const mag = 10 ** Math.floor(Math.log10(raw));
  const step = [1, 2, 2.5, 5, 10].map((m) => m * mag).find((st) => st >= raw) || raw;
  const out = [];
  for (let v = Math.ceil(lo / step) * step; v <= hi + step * 1e-9; v += step) out.push(+v.toFixed(10));
  return out;
}

export function timeTicks(t0, t1, count = 6) {
  const day = 86400000;
  const span = (t1 - t0) / day;
  const steps = [1, 2, 5, 7, 14, 30, 60, 90, 180, 365];
  const step = (steps.find((st) => span / st <= count) || 365) * day;
  const out = [];
  for (let v = Math.ceil(t0 / step) * step; v <= t1; v += step) out.push(v);
  return out;
}

const tip = () => document.getElementById('tooltip');
// The tooltip's content is DOM nodes and strings (strings become text, never markup): sensor ids,
// row names and anything else from the server are shown, not interpreted.
export function showTip(ev, ...content) {
  const el = tip();
  el.replaceChildren(...content.flat().filter((c) => c != null && c !== false)
    .map((c) => (c instanceof Node ? c : document.createTextNode(String(c)))));
  el.hidden = false;
  const x = Math.min(ev.clientX + 14, window.innerWidth - el.offsetWidth - 8);
  el.style.left = `${x}px`;
  el.style.top = `${ev.clientY + 14}px`;
}
export function hideTip() { tip().hidden = true; }

export function flash(el) {
  if (!el) return;
  el.classList.remove('updated');
  void el.offsetWidth;
  el.classList.add('updated');
}
