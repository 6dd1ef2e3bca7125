// Sensor time series (SVG): readings as a step line with their [n, n+1) mm band, the forecast with
// its band, the minimum-thickness line and the window in which the minimum is reached.
import { s, h, fmt, fmtDate, fmtDateTime, parseTime, ticks, timeTicks, showTip, hideTip } from './util.js';

const M = { left: 48, right: 16, top: 14, bottom: 30 };

export function renderSeries(container, { sensor, readings, forecast, thicknessMin, thicknessNew, installedAt }) {
  container.replaceChildren();
  const w = container.clientWidth || 700;
  const hgt = 300;
  const pts = readings.map((r) => ({ t: parseTime(r.time), v: r.thickness_mm })).filter((p) => Number.isFinite(p.t));
  const curve = (forecast?.curve || []).map((c) => ({ t: parseTime(c.time), v: c.thickness_mm, lo: c.lo_mm, hi: c.hi_mm }));
  const reach = { d: parseTime(forecast?.reach_date), lo: parseTime(forecast?.reach_earliest), hi: parseTime(forecast?.reach_latest) };

  const ts = [...pts.map((p) => p.t), ...curve.map((c) => c.t), reach.hi, reach.d].filter(Number.isFinite);
  const install = parseTime(installedAt);
  if (Number.isFinite(install)) ts.push(install);
  if (!ts.length) {
    container.append(Object.assign(document.createElement('div'), { className: 'empty', textContent: 'No readings for this sensor yet.' }));
    return;
  }
  let t0 = Math.min(...ts);
  let t1 = Math.max(...ts);
  if (t1 - t0 < 86400000) { t1 = t0 + 86400000; }
  const pad = (t1 - t0) * 0.02;
  t0 -= pad; t1 += pad;
  const yHi = Math.ceil((thicknessNew + 5) / 10) * 10;
  const pw = w - M.left - M.right;
  const ph = hgt - M.top - M.bottom;
  const X = (t) => M.left + ((t - t0) / (t1 - t0)) * pw;
  const Y = (v) => M.top + ph - (Math.max(0, Math.min(yHi, v)) / yHi) * ph;

  const svg = s('svg', { viewBox: `0 0 ${w} ${hgt}`, height: hgt, 'data-testid': 'sensor-series', 'data-sensor': sensor.id,
    'data-points': pts.length, 'data-last-mm': pts.length ? pts[pts.length - 1].v : '', role: 'img',
    'aria-label': `Thickness of sensor ${sensor.id} over time` });

  // grid
  for (const v of ticks(0, yHi, 6)) {
    svg.append(s('line', { x1: M.left, x2: M.left + pw, y1: Y(v), y2: Y(v), stroke: '#edf0f4' }));
    svg.append(s('text', { x: M.left - 6, y: Y(v) + 4, 'text-anchor': 'end', 'font-size': 11, fill: '#4a5868' }, String(v)));
  }
  for (const t of timeTicks(t0, t1, 7)) {
    svg.append(s('line', { x1: X(t), x2: X(t), y1: M.top, y2: M.top + ph, stroke: '#f3f5f8' }));
    svg.append(s('text', { x: X(t), y: M.top + ph + 16, 'text-anchor': 'middle', 'font-size': 11, fill: '#4a5868' }, fmtDate(t).slice(5)));
  }
  svg.append(s('text', { x: 12, y: M.top + ph / 2, transform: `rotate(-90 12 ${M.top + ph / 2})`, 'text-anchor': 'middle', 'font-size': 11, fill: '#4a5868' }, 'thickness (mm)'));

  // reach window
  if (Number.isFinite(reach.lo) && Number.isFinite(reach.hi)) {
    svg.append(s('rect', { x: X(reach.lo), y: M.top, width: Math.max(1, X(reach.hi) - X(reach.lo)), height: ph, fill: 'rgba(198,40,40,.08)' }));
  }
  if (Number.isFinite(reach.d)) {
    svg.append(s('line', { x1: X(reach.d), x2: X(reach.d), y1: M.top, y2: M.top + ph, stroke: '#c62828', 'stroke-dasharray': '2 3' }));
    svg.append(s('text', { x: X(reach.d) - 4, y: M.top + 12, 'text-anchor': 'end', 'font-size': 11, fill: '#c62828' }, `reline ${fmtDate(reach.d)}`));
  }

  // forecast band and curve
  if (curve.length) {
    const band = curve.filter((c) => Number.isFinite(c.lo) && Number.isFinite(c.hi));
    if (band.length) {
      const d = band.map((c, i) => `${i ? 'L' : 'M'}${X(c.t)},${Y(c.hi)}`).join('') +
        band.slice().reverse().map((c) => `L${X(c.t)},${Y(c.lo)}`).join('') + 'Z';
      svg.append(s('path', { d, fill: 'rgba(239,143,0,.18)', stroke: 'none', 'data-testid': 'forecast-band' }));
    }
    svg.append(s('path', { d: curve.map((c, i) => `${i ? 'L' : 'M'}${X(c.t)},${Y(c.v)}`).join(''), fill: 'none', stroke: '#ef8f00', 'stroke-width': 2, 'stroke-dasharray': '6 4' }));
  }

  // minimum thickness
  svg.append(s('line', { x1: M.left, x2: M.left + pw, y1: Y(thicknessMin), y2: Y(thicknessMin), stroke: '#c62828', 'stroke-width': 1.5, 'stroke-dasharray': '8 4', 'data-testid': 'min-line' }));
  svg.append(s('text', { x: M.left + 4, y: Y(thicknessMin) - 5, 'font-size': 11, fill: '#c62828' }, `minimum ${thicknessMin} mm`));

  // readings: a reading n means [n, n+1) mm, so draw the band and the step at n + 0.5
  if (pts.length) {
    let band = '';
    let line = '';
    pts.forEach((p, i) => {
      const next = i + 1 < pts.length ? pts[i + 1].t : p.t;
      band += `M${X(p.t)},${Y(p.v + 1)}L${X(next)},${Y(p.v + 1)}L${X(next)},${Y(p.v)}L${X(p.t)},${Y(p.v)}Z`;
      line += `${i ? 'L' : 'M'}${X(p.t)},${Y(p.v + 0.5)}L${X(next)},${Y(p.v + 0.5)}`;
    });
    svg.append(s('path', { d: band, fill: 'rgba(21,101,192,.18)', stroke: 'none' }));
    svg.append(s('path', { d: line, fill: 'none', stroke: '#1565c0', 'stroke-width': 2 }));
    const last = pts[pts.length - 1];
    svg.append(s('circle', { cx: X(last.t), cy: Y(last.v + 0.5), r: 4, fill: '#1565c0', stroke: '#fff', 'stroke-width': 1.5 }));
  }
  svg.append(s('rect', { x: M.left, y: M.top, width: pw, height: ph, fill: 'none', stroke: '#c3cbd5' }));

  // hover readout
  const cursor = s('line', { y1: M.top, y2: M.top + ph, stroke: '#4a5868', 'stroke-width': 1, visibility: 'hidden' });
  svg.append(cursor);
  svg.addEventListener('mousemove', (ev) => {
    const r = svg.getBoundingClientRect();
    const px = ((ev.clientX - r.left) / r.width) * w;
    if (px < M.left || px > M.left + pw) { hideTip(); cursor.setAttribute('visibility', 'hidden'); return; }
    const t = t0 + ((px - M.left) / pw) * (t1 - t0);
    cursor.setAttribute('x1', px); cursor.setAttribute('x2', px); cursor.setAttribute('visibility', 'visible');
    const tipText = [fmtDateTime(t)];
    const before = pts.filter((p) => p.t <= t);
    if (before.length && t <= pts[pts.length - 1].t + 86400000) {
      const p = before[before.length - 1];
      tipText.push(h('br'), 'reading ', h('b', {}, `${p.v} mm`), ` (in [${p.v}, ${p.v + 1}))`);
    }
    const c = curve.find((q) => q.t >= t);
    if (c) tipText.push(h('br'), `forecast ${fmt(c.v)} mm (${fmt(c.lo)}–${fmt(c.hi)})`);
    showTip(ev, tipText);
  });
  svg.addEventListener('mouseleave', () => { hideTip(); cursor.setAttribute('visibility', 'hidden'); });
  container.append(svg);
}
