// Unwrapped concave map: theta 0-360 deg across, z up, faces coloured by remaining thickness.
import { thicknessColor, rgb, fmt, ticks, showTip, hideTip, h as node } from './util.js';

const M = { left: 52, right: 64, top: 14, bottom: 34 };

// Each face as a triangle in (theta_deg, z_m); faces that straddle theta = 0/360 are unwrapped so
// their vertices are contiguous, and drawn twice (shifted by 360) so both edges of the map are full.
function unwrap(mesh) {
  const { points, faces } = mesh;
  const n = faces.length / 3;
  const tri = new Float64Array(n * 6);
  const wraps = new Uint8Array(n);
  for (let f = 0; f < n; f++) {
    let ths = [0, 1, 2].map((k) => {
      const i = faces[3 * f + k];
      const th = (Math.atan2(points[3 * i + 1], points[3 * i]) * 180) / Math.PI;
      return th < 0 ? th + 360 : th;
    });
    if (Math.max(...ths) - Math.min(...ths) > 180) {
      ths = ths.map((t) => (t < 180 ? t + 360 : t));
      wraps[f] = 1;
    }
    for (let k = 0; k < 3; k++) {
      const i = faces[3 * f + k];
      tri[6 * f + 2 * k] = ths[k];
      tri[6 * f + 2 * k + 1] = points[3 * i + 2];
    }
  }
  let zmin = Infinity;
  let zmax = -Infinity;
  for (let i = 2; i < points.length; i += 3) {
    zmin = Math.min(zmin, points[i]);
    zmax = Math.max(zmax, points[i]);
  }
  return { tri, wraps, n, zmin, zmax };
}

export class UnwrappedMap {
  constructor(container, { onSelectSensor }) {
    this.container = container;
    this.onSelectSensor = onSelectSensor;
    this.canvas = document.createElement('canvas');
    this.canvas.setAttribute('data-testid', 'wear-map');
    this.canvas.setAttribute('role', 'img');
    container.append(this.canvas);
    this.geom = null;
    this.state = null;
    this.canvas.addEventListener('mousemove', (ev) => this.hover(ev));
    this.canvas.addEventListener('mouseleave', hideTip);
    this.canvas.addEventListener('click', (ev) => this.click(ev));
    this.resizeObserver = new ResizeObserver(() => this.draw());
    this.resizeObserver.observe(container);
  }

  destroy() { this.resizeObserver.disconnect(); }

  // state: {mesh, remaining (per face or null), thicknessMin, thicknessNew, rows, sensors
  //         [{id,z_m,theta_deg,thickness}], min {z_m,theta_deg,thickness}, selected, regions}
  update(state) {
    if (!this.geom || this.geom.mesh !== state.mesh) this.geom = { mesh: state.mesh, ...unwrap(state.mesh) };
    this.state = state;
    const c = this.canvas;
    c.dataset.minMm = state.min ? String(state.min.thickness) : '';
    c.dataset.faces = String(this.geom.n);
    c.setAttribute('aria-label', state.min?.theta_deg != null
      ? `Unwrapped concave map; thinnest area ${fmt(state.min.thickness)} mm at theta ${fmt(state.min.theta_deg, 0)} deg, z ${fmt(state.min.z_m, 2)} m`
      : 'Unwrapped concave map; no readings yet');
    this.draw();
  }

  layout() {
    const w = this.container.clientWidth || 800;
    const h = Math.round(Math.max(260, Math.min(520, w * 0.42)));
    const g = this.geom;
    const pw = w - M.left - M.right;
    const ph = h - M.top - M.bottom;
    const zspan = g.zmax - g.zmin || 1;
    return {
      w, h, pw, ph,
      x: (th) => M.left + (th / 360) * pw,
      y: (z) => M.top + ph - ((z - g.zmin) / zspan) * ph,
      th: (px) => ((px - M.left) / pw) * 360,
      z: (py) => g.zmin + ((M.top + ph - py) / ph) * zspan,
    };
  }

  draw() {
    if (!this.geom || !this.state) return;
    const st = this.state;
    const g = this.geom;
    const L = this.layout();
    this.L = L;
    const dpr = window.devicePixelRatio || 1;
    const c = this.canvas;
    c.width = Math.round(L.w * dpr);
    c.height = Math.round(L.h * dpr);
    c.style.height = `${L.h}px`;
    const ctx = c.getContext('2d');
    ctx.setTransform(dpr, 0, 0, dpr, 0, 0);
    ctx.clearRect(0, 0, L.w, L.h);

    ctx.save();
    ctx.beginPath();
    ctx.rect(M.left, M.top, L.pw, L.ph);
    ctx.clip();
    ctx.fillStyle = '#e9edf2';
    ctx.fillRect(M.left, M.top, L.pw, L.ph);
    const stroke = g.n < 200000;
    ctx.lineWidth = 0.6;
    for (let f = 0; f < g.n; f++) {
      const col = rgb(thicknessColor(st.remaining ? st.remaining[f] : null, st.thicknessMin, st.thicknessNew));
      ctx.fillStyle = col;
      if (stroke) ctx.strokeStyle = col;
      for (const shift of g.wraps[f] ? [0, -360] : [0]) {
        ctx.beginPath();
        ctx.moveTo(L.x(g.tri[6 * f] + shift), L.y(g.tri[6 * f + 1]));
        ctx.lineTo(L.x(g.tri[6 * f + 2] + shift), L.y(g.tri[6 * f + 3]));
        ctx.lineTo(L.x(g.tri[6 * f + 4] + shift), L.y(g.tri[6 * f + 5]));
        ctx.closePath();
        ctx.fill();
        if (stroke) ctx.stroke();
      }
    }

    // Row boundaries.
    ctx.setLineDash([5, 4]);
    ctx.strokeStyle = 'rgba(20,30,40,.55)';
    ctx.lineWidth = 1;
    for (const r of st.rows.slice(1)) {
      ctx.beginPath();
      ctx.moveTo(M.left, L.y(r.z_min_m));
      ctx.lineTo(M.left + L.pw, L.y(r.z_min_m));
      ctx.stroke();
    }
    ctx.setLineDash([]);

    // Diagnosis mismatch regions.
    for (const r of st.regions || []) {
      ctx.strokeStyle = r.sign === 'over' ? '#6a1b9a' : '#00695c';
      ctx.lineWidth = 2;
      ctx.setLineDash([6, 3]);
      const x0 = L.x(r.theta_min_deg);
      const x1 = L.x(r.theta_max_deg);
      ctx.strokeRect(x0, L.y(r.z_max_m), x1 - x0, L.y(r.z_min_m) - L.y(r.z_max_m));
      ctx.setLineDash([]);
    }

    // Sensors.
    ctx.font = '11px system-ui, sans-serif';
    for (const sn of st.sensors) {
      const x = L.x(sn.theta_deg);
      const y = L.y(sn.z_m);
      const sel = sn.id === st.selected;
      ctx.beginPath();
      ctx.arc(x, y, sel ? 8 : 6, 0, 2 * Math.PI);
      ctx.fillStyle = rgb(thicknessColor(sn.thickness, st.thicknessMin, st.thicknessNew));
      ctx.fill();
      ctx.lineWidth = sel ? 3 : 2;
      ctx.strokeStyle = sel ? '#111' : '#fff';
      ctx.stroke();
      ctx.lineWidth = 1;
      ctx.strokeStyle = '#111';
      if (!sel) ctx.stroke();
      const label = sn.thickness == null ? String(sn.id) : `${sn.id} · ${sn.thickness}`;
      ctx.lineWidth = 3;
      ctx.strokeStyle = 'rgba(255,255,255,.85)';
      ctx.strokeText(label, x + 10, y + 4);
      ctx.fillStyle = '#111';
      ctx.fillText(label, x + 10, y + 4);
    }

    // Thinnest spot: a target.
    if (st.min && st.min.theta_deg != null) {
      const x = L.x(st.min.theta_deg);
      const y = L.y(st.min.z_m);
      ctx.strokeStyle = '#fff';
      ctx.lineWidth = 4;
      ctx.beginPath(); ctx.arc(x, y, 11, 0, 2 * Math.PI); ctx.stroke();
      ctx.strokeStyle = '#000';
      ctx.lineWidth = 2;
      ctx.beginPath(); ctx.arc(x, y, 11, 0, 2 * Math.PI); ctx.stroke();
      ctx.beginPath();
      ctx.moveTo(x - 17, y); ctx.lineTo(x - 6, y); ctx.moveTo(x + 6, y); ctx.lineTo(x + 17, y);
      ctx.moveTo(x, y - 17); ctx.lineTo(x, y - 6); ctx.moveTo(x, y + 6); ctx.lineTo(x, y + 17);
      ctx.stroke();
      const label = st.min.patch_m ? `thinnest ${fmt(st.min.patch_m, 1)} m area ${fmt(st.min.thickness)} mm${st.min.extrapolated ? ' (map)' : ''}`
        : `thinnest ${fmt(st.min.thickness)} mm`;
      ctx.font = 'bold 12px system-ui, sans-serif';
      const tx = x + 16 + ctx.measureText(label).width > M.left + L.pw ? x - 16 - ctx.measureText(label).width : x + 16;
      ctx.lineWidth = 3;
      ctx.strokeStyle = '#fff';
      ctx.strokeText(label, tx, y - 14);
      ctx.fillStyle = '#000';
      ctx.fillText(label, tx, y - 14);
    }
    ctx.restore();

    // Axes.
    ctx.strokeStyle = '#9aa6b2';
    ctx.lineWidth = 1;
    ctx.strokeRect(M.left + 0.5, M.top + 0.5, L.pw, L.ph);
    ctx.fillStyle = '#4a5868';
    ctx.font = '11px system-ui, sans-serif';
    ctx.textAlign = 'center';
    // Ticks as dense as their labels allow (a phone: every 90 or 180 degrees), and a title that fits.
    const tickW = ctx.measureText('360°').width + 10;
    const step = [45, 90, 180].find((d) => (L.pw * d) / 360 >= tickW) || 360;
    this.canvas.dataset.thetaTickPx = String(Math.round((L.pw * step) / 360));  // checked by the browser test
    this.canvas.dataset.thetaLabelPx = String(Math.ceil(tickW - 10));
    for (let th = 0; th <= 360; th += step) {
      const x = L.x(th);
      ctx.fillRect(x, M.top + L.ph, 1, 4);
      ctx.fillText(`${th}°`, x, M.top + L.ph + 16);
    }
    const titles = ['θ (deg, counter-clockwise from +x, seen from above)', 'θ (deg, counter-clockwise from above)', 'θ (deg)'];
    ctx.fillText(titles.find((t) => ctx.measureText(t).width <= L.pw) || titles[2], M.left + L.pw / 2, L.h - 3);
    ctx.textAlign = 'right';
    for (const z of ticks(g.zmin, g.zmax, 5)) {
      const y = L.y(z);
      ctx.fillRect(M.left - 4, y, 4, 1);
      ctx.fillText(z.toFixed(1), M.left - 7, y + 4);
    }
    ctx.save();
    ctx.translate(13, M.top + L.ph / 2);
    ctx.rotate(-Math.PI / 2);
    ctx.textAlign = 'center';
    ctx.fillText('z (m)', 0, 0);
    ctx.restore();
    ctx.textAlign = 'left';
    ctx.font = '600 11px system-ui, sans-serif';
    for (const r of st.rows) {
      const y = (L.y(r.z_min_m) + L.y(r.z_max_m)) / 2;
      ctx.fillText(r.name, M.left + L.pw + 8, y + 4);
    }
  }

  sensorAt(px, py) {
    const L = this.L;
    let best = null;
    let bestD = 12;
    for (const sn of this.state.sensors) {
      const d = Math.hypot(L.x(sn.theta_deg) - px, L.y(sn.z_m) - py);
      if (d < bestD) { bestD = d; best = sn; }
    }
    return best;
  }

  faceAt(th, z) {
    const g = this.geom;
    const inside = (f, shift) => {
      const t = g.tri;
      const ax = t[6 * f] + shift; const ay = t[6 * f + 1];
      const bx = t[6 * f + 2] + shift; const by = t[6 * f + 3];
      const cx = t[6 * f + 4] + shift; const cy = t[6 * f + 5];
      const d1 = (th - bx) * (ay - by) - (ax - bx) * (z - by);
      const d2 = (th - cx) * (by - cy) - (bx - cx) * (z - cy);
      const d3 = (th - ax) * (cy - ay) - (cx - ax) * (z - ay);
      return !((d1 < 0 || d2 < 0 || d3 < 0) && (d1 > 0 || d2 > 0 || d3 > 0));
    };
    for (let f = 0; f < g.n; f++) {
      if (inside(f, 0) || (g.wraps[f] && inside(f, -360))) return f;
    }
    return -1;
  }

  hover(ev) {
    if (!this.L) return;
    const r = this.canvas.getBoundingClientRect();
    const px = ev.clientX - r.left;
    const py = ev.clientY - r.top;
    const sn = this.sensorAt(px, py);
    this.canvas.style.cursor = sn ? 'pointer' : 'crosshair';
    if (sn) {
      showTip(ev, node('b', {}, `sensor ${sn.id}`), ` (${sn.row})`, node('br'),
        sn.thickness == null ? 'no reading' : `${sn.thickness} mm: in [${sn.thickness}, ${sn.thickness + 1}) mm`, node('br'),
        `θ ${fmt(sn.theta_deg, 0)}°, z ${fmt(sn.z_m, 2)} m`, node('br'), node('i', {}, 'click for its time series'));
      return;
    }
    const th = this.L.th(px);
    const z = this.L.z(py);
    if (th < 0 || th > 360 || z < this.geom.zmin || z > this.geom.zmax || this.geom.n > 300000) { hideTip(); return; }
    const f = this.faceAt(th, z);
    if (f < 0) { hideTip(); return; }
    const rem = this.state.remaining ? this.state.remaining[f] : null;
    showTip(ev, `θ ${fmt(th, 0)}°, z ${fmt(z, 2)} m`, node('br'), 'remaining ', node('b', {}, `${fmt(rem)} mm`),
      rem != null ? ` (worn ${fmt(this.state.thicknessNew - rem)} mm)` : '');
  }

  click(ev) {
    if (!this.L) return;
    const r = this.canvas.getBoundingClientRect();
    const sn = this.sensorAt(ev.clientX - r.left, ev.clientY - r.top);
    if (sn) this.onSelectSensor(sn.id);
  }
}

// Horizontal colour bar in mm, with the minimum thickness marked.
export function drawLegend(canvas, minMm, newMm) {
  const w = canvas.clientWidth || 400;
  const hgt = 34;
  const dpr = window.devicePixelRatio || 1;
  canvas.width = Math.round(w * dpr);
  canvas.height = Math.round(hgt * dpr);
  const ctx = canvas.getContext('2d');
  ctx.setTransform(dpr, 0, 0, dpr, 0, 0);
  const lo = Math.max(0, minMm - 0.12 * (newMm - minMm));
  const x = (mm) => 6 + ((mm - lo) / (newMm - lo)) * (w - 12);
  for (let px = 6; px < w - 6; px++) {
    const mm = lo + ((px - 6) / (w - 12)) * (newMm - lo);
    ctx.fillStyle = rgb(thicknessColor(mm, minMm, newMm));
    ctx.fillRect(px, 2, 1, 12);
  }
  ctx.fillStyle = '#4a5868';
  ctx.font = '11px system-ui, sans-serif';
  ctx.textAlign = 'center';
  for (const mm of ticks(lo, newMm, 8)) {
    ctx.fillRect(x(mm), 14, 1, 4);
    ctx.fillText(String(mm), x(mm), 30);
  }
  ctx.fillStyle = '#c62828';
  ctx.fillRect(x(minMm) - 1, 0, 2, 18);
}
