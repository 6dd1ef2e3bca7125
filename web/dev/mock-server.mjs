// Development mock of linerwatch-server's REST API (shapes as in docs/dashboard.md and the server's
// OpenAPI document), serving a synthetic crusher so the dashboard can be worked on without the
// real server. Not used by the tests: those run against the real linerwatch-server.
// Usage: node dev/mock-server.mjs [--port 8090] [--web DIR] [--token SECRET] [--tick SECONDS]
import http from 'node:http';
import fs from 'node:fs';
import path from 'node:path';

const args = Object.fromEntries(process.argv.slice(2).reduce((acc, a, i, all) => (a.startsWith('--') ? [...acc, [a.slice(2), all[i + 1]]] : acc), []));
const port = Number(args.port || 8090);
const webDir = path.resolve(args.web || '../build/web');
const token = args.token || null;
const tick = Number(args.tick || 5) * 1000;

// --- geometry: a truncated cone, 72 x 36 quads, like linerwatch-sim's default concave
const H = 3.0; const R0 = 1.6; const R1 = 2.6; const NT = 72; const NZ = 36;
const points = [];
for (let j = 0; j <= NZ; j++) for (let i = 0; i < NT; i++) {
  const z = (j / NZ) * H; const r = R0 + (R1 - R0) * (z / H); const th = (i / NT) * 2 * Math.PI;
  points.push(r * Math.cos(th), r * Math.sin(th), z);
}
const faces = []; const faceZ = []; const faceTh = []; const intensity = [];
for (let j = 0; j < NZ; j++) for (let i = 0; i < NT; i++) {
  const a = j * NT + i; const b = j * NT + ((i + 1) % NT); const c = a + NT; const d = b + NT;
  for (const tri of [[a, b, d], [a, d, c]]) {
    faces.push(...tri);
    const z = tri.reduce((s, k) => s + points[3 * k + 2], 0) / 3;
    const th = ((i + 0.5) / NT) * 360;
    faceZ.push(z); faceTh.push(th);
    const zeta = z / H;
    intensity.push((0.06 + (1 - zeta) ** 1.5) * (1 + 0.12 * Math.cos(((th - 20) * Math.PI) / 180)) * (1 + 0.05 * Math.sin(i * 1.7 + j)));
  }
}
const rows = [{ name: 'LDWN', z_min_m: 0, z_max_m: 1 }, { name: 'LMID', z_min_m: 1, z_max_m: 2 }, { name: 'LUP', z_min_m: 2, z_max_m: 3 }];
const sensorDefs = [[1001, 'LUP', 30], [1002, 'LUP', 210], [1003, 'LMID', 0], [1004, 'LMID', 90], [1005, 'LMID', 180], [1006, 'LMID', 270],
  [1007, 'LDWN', 45], [1008, 'LDWN', 135], [1009, 'LDWN', 225], [1010, 'LDWN', 315]]
  .map(([id, row, th]) => { const r = rows.find((x) => x.name === row); return { id: String(id), row, z_m: (r.z_min_m + r.z_max_m) / 2, theta_deg: th, thickness_new_mm: 120 }; });
const NEW = 120; const MIN = 30;
const installed = Date.parse('2026-08-01T00:00:00Z');
const day = 86400000;
const rateAt = (z, th) => 0.9 * (0.06 + (1 - z / H) ** 1.5) * (1 + 0.12 * Math.cos(((th - 20) * Math.PI) / 180));

// readings: whole-mm ladder values every 6 h up to "now" (day 60)
const readings = new Map(sensorDefs.map((s) => [s.id, []]));
let clock = installed + 60 * day;
for (const s of sensorDefs) {
  let seq = 0;
  for (let t = installed; t <= clock; t += 6 * 3600000) {
    const d = (t - installed) / day;
    readings.get(s.id).push({ time: iso(t), seq: seq++, thickness_mm: Math.floor(NEW - rateAt(s.z_m, s.theta_deg) * d * (1 + d / 200)), loops_intact: 0, flags: 0, battery_mv: 3600 - Math.round(d * 2), received: iso(t + 5000) });
  }
}
function iso(t) { return new Date(t).toISOString().replace(/\.\d{3}Z$/, 'Z'); }
const latest = (id) => { const l = readings.get(id); return l.length ? l[l.length - 1] : null; };

function wear(withFaces) {
  const d = (clock - installed) / day;
  const rem = intensity.map((w, f) => NEW - rateAt(faceZ[f], faceTh[f]) * d * (1 + d / 200) * (w / ((0.06 + (1 - faceZ[f] / H) ** 1.5) * (1 + 0.12 * Math.cos(((faceTh[f] - 20) * Math.PI) / 180)))));
  let mi = 0; rem.forEach((v, f) => { if (v < rem[mi]) mi = f; });
  const rowOf = (z) => rows.find((r) => z >= r.z_min_m && z <= r.z_max_m).name;
  const rowSummary = rows.map((r) => {
    let best = -1; let sum = 0; let n = 0;
    rem.forEach((v, f) => { if (faceZ[f] >= r.z_min_m && faceZ[f] < r.z_max_m) { n++; sum += NEW - v; if (best < 0 || v < rem[best]) best = f; } });
    return { row: r.name, scale_mm_per_unit: 40, min_thickness_mm: rem[best], min_z_m: faceZ[best], min_theta_deg: faceTh[best], mean_wear_mm: sum / n, sensors_used: sensorDefs.filter((s) => s.row === r.name).length,
      thinnest_area: mockArea(r.name, rem[best] + 8, faceZ[best], faceTh[best]) };
  });
  const out = { crusher_id: 'demo', time: iso(clock), map_sha256: 'f00dfeed1234567890', thickness_new_mm: NEW, thickness_min_mm: MIN, min_thickness_mm: rem[mi],
    min: { face: mi, z_m: faceZ[mi], theta_deg: faceTh[mi], row: rowOf(faceZ[mi]) }, rows: rowSummary,
    thinnest_area: mockArea(rowOf(faceZ[mi]), rem[mi] + 8, faceZ[mi], faceTh[mi]),
    readings_used: sensorDefs.map((s) => ({ sensor: s.id, ...latest(s.id) })), note: 'a reading n means thickness in [n, n+1) mm; estimates use n + 0.5' };
  if (withFaces) out.remaining_mm = rem;
  return out;
}

function forecast() {
  const d0 = (clock - installed) / day;
  const sensors = sensorDefs.map((s) => {
    const r = rateAt(s.z_m, s.theta_deg);
    const curve = [];
    let reach = null;
    for (let d = Math.floor(d0); d < d0 + 400; d++) {
      const v = NEW - r * d * (1 + d / 200); const spread = 0.04 * (d - d0) * r + 1;
      curve.push({ time: iso(installed + d * day), thickness_mm: v, lo_mm: v - spread, hi_mm: v + spread });
      if (v <= MIN) { reach = d; break; }
    }
    return { id: s.id, rate_mm_per_day: r * (1 + 2 * d0 / 200), reach_date: reach ? iso(installed + reach * day) : null,
      reach_earliest: reach ? iso(installed + (reach - 6) * day) : null, reach_latest: reach ? iso(installed + (reach + 9) * day) : null, curve };
  });
  const w = wear(false);
  const rowsF = rows.map((r) => {
    const ss = sensors.filter((s) => sensorDefs.find((x) => x.id === s.id).row === r.name);
    const first = ss.filter((s) => s.reach_date).sort((a, b) => a.reach_date.localeCompare(b.reach_date))[0];
    return { row: r.name, min_thickness_mm: w.rows.find((x) => x.row === r.name).min_thickness_mm, rate_mm_per_day: Math.max(...ss.map((s) => s.rate_mm_per_day)),
      reach_date: first?.reach_date ?? null, reach_earliest: first?.reach_earliest ?? null, reach_latest: first?.reach_latest ?? null };
  });
  return { crusher_id: 'demo', time: iso(clock), thickness_min_mm: MIN, rows: rowsF, sensors };
}

let diagnosis = { status: 'none', time: null, result: null };
const diagResult = {
  baseline: { rmse_mm: 3.1, max_abs_mm: 6.8, holdout_rmse_mm: 3.6 },
  mismatch: { detected: true, regions: [{ z_min_m: 0.6, z_max_m: 1.4, theta_min_deg: 0, theta_max_deg: 360, from: iso(installed), to: iso(clock), sign: 'over', size_mm: 4.2 }] },
  findings: [{ effect: 'work_hardening', confidence: 0.82, explanation: 'Steep first days then flatter where normal stress is high; the DEM over-predicts there.', parameters: { h: 0.43, tau_days: 5.8 }, evidence: {} },
    { effect: 'feed_segregation', confidence: 0.31, explanation: 'Sensors at theta 0 and 180 diverge in a fixed ratio.', parameters: { amplitude: 0.08, theta_deg: 12 }, evidence: {} }],
  improved: { rmse_mm: 1.2, max_abs_mm: 2.9, holdout_rmse_mm: 1.5 },
  data_quality: [{ sensor_id: '1006', issue: 'flicker', from: iso(installed + 20 * day), to: iso(installed + 22 * day) }],
};

const sseClients = new Set();
function send(res, code, body) {
  res.writeHead(code, { 'Content-Type': 'application/json' });
  res.end(JSON.stringify(body));
}
function authorised(req, url) {
  if (!token) return true;
  return req.headers.authorization === `Bearer ${token}` || url.searchParams.get('access_token') === token;
}
function addReading(id, r) {
  readings.get(id).push({ ...r, received: iso(Date.now()) });
  clock = Math.max(clock, Date.parse(r.time));
  for (const c of sseClients) {
    c.write(`event: reading\ndata: ${JSON.stringify({ sensor: id, ...r })}\n\n`);
    c.write(`event: wear\ndata: ${JSON.stringify(wear(false))}\n\n`);
  }
}

setInterval(() => {
  const s = sensorDefs[Math.floor(Math.random() * sensorDefs.length)];
  const l = latest(s.id);
  clock += 3600000;
  addReading(s.id, { seq: l.seq + 1, time: iso(clock), thickness_mm: Math.max(0, l.thickness_mm - 1), loops_intact: 0, flags: 0, battery_mv: l.battery_mv });
}, tick);

const server = http.createServer(async (req, res) => {
  const url = new URL(req.url, 'http://x');
  const p = url.pathname.split('/').filter(Boolean).map(decodeURIComponent);
  if (url.pathname === '/healthz') return send(res, 200, { status: 'ok', broker: 'connected', db: 'ok', version: '0.1.0' });
  if (p[0] === 'api') {
    if (!authorised(req, url)) return send(res, 401, { error: 'missing or invalid token' });
    const c = p[3];
    if (p.length === 3 && p[2] === 'crushers') {
      const w = wear(false);
      return send(res, 200, { crushers: [{ crusher_id: 'demo', installed_at: iso(installed), thickness_new_mm: NEW, thickness_min_mm: MIN, rows, sensor_count: sensorDefs.length, map_sha256: w.map_sha256, face_count: faces.length / 3, latest_reading_time: iso(clock), min_thickness_mm: w.min_thickness_mm, thinnest_area: w.thinnest_area }] });
    }
    if (c !== 'demo') return send(res, 404, { error: `unknown crusher '${c}'` });
    const sub = p[4];
    if (!sub) return send(res, 200, { crusher_id: 'demo', installed_at: iso(installed), concave: { thickness_new_mm: NEW, thickness_min_mm: MIN, rows }, sensors: sensorDefs, map: { sha256: 'f00dfeed1234567890', face_count: faces.length / 3, warnings: [] }, counters: { readings_stored: [...readings.values()].reduce((s, l) => s + l.length, 0), duplicates: 0, rejected: 0 } });
    if (sub === 'sensors' && !p[5]) return send(res, 200, { sensors: sensorDefs.map((s) => ({ ...s, reading_count: readings.get(s.id).length, latest: latest(s.id) })) });
    if (sub === 'sensors' && p[6] === 'readings') {
      const l = readings.get(p[5]);
      if (!l) return send(res, 404, { error: `unknown sensor '${p[5]}'` });
      const start = Number(url.searchParams.get('cursor') || 0);
      const limit = Math.min(5000, Number(url.searchParams.get('limit') || 500));
      return send(res, 200, { readings: l.slice(start, start + limit), next_cursor: start + limit < l.length ? String(start + limit) : null });
    }
    if (sub === 'readings' && req.method === 'POST') {
      let body = ''; for await (const chunk of req) body += chunk;
      const list = JSON.parse(body).readings || [];
      for (const r of list) addReading(String(r.sensor), r);
      return send(res, 200, { stored: list.length, duplicates: 0 });
    }
    if (sub === 'mesh') return send(res, 200, { points, faces, face_z_m: faceZ, face_theta_deg: faceTh });
    if (sub === 'wear') return send(res, 200, wear(url.searchParams.get('faces') !== 'false'));
    if (sub === 'forecast') return send(res, 200, forecast());
    if (sub === 'diagnosis') {
      if (req.method === 'POST') {
        diagnosis = { status: 'running', time: iso(Date.now()), result: null };
        setTimeout(() => { diagnosis = { status: 'done', time: iso(Date.now()), result: diagResult }; }, 4000);
        return send(res, 202, diagnosis);
      }
      return send(res, 200, diagnosis);
    }
    if (sub === 'events') {
      res.writeHead(200, { 'Content-Type': 'text/event-stream', 'Cache-Control': 'no-cache', Connection: 'keep-alive' });
      res.write(': hello\n\n');
      sseClients.add(res);
      req.on('close', () => sseClients.delete(res));
      return undefined;
    }
    return send(res, 404, { error: 'no such endpoint' });
  }
  const file = path.join(webDir, url.pathname === '/' ? 'index.html' : path.normalize(url.pathname));
  if (!file.startsWith(webDir) || !fs.existsSync(file) || fs.statSync(file).isDirectory()) return send(res, 404, { error: 'not found' });
  const types = { '.html': 'text/html', '.js': 'text/javascript', '.css': 'text/css', '.map': 'application/json' };
  res.writeHead(200, { 'Content-Type': types[path.extname(file)] || 'application/octet-stream' });
  fs.createReadStream(file).pipe(res);
});
server.listen(port, '127.0.0.1', () => console.log(`mock linerwatch-server on http://127.0.0.1:${port}/ (web ${webDir}${token ? ', token required' : ''})`));

// A thinnest area in the server's shape (docs/server.md): a 0.4 m patch, 6 mm band, 0.6 m from a sensor.
function mockArea(row, mm, z, th) {
  return { thickness_mm: mm, band_mm: [mm - 6, mm + 6], patch_m: 0.4, z_m: z, theta_deg: th, supported: true, extrapolated: true,
    nearest_sensor_m: 0.6, row, whole_row: false, worn_through: false, detail: 'extrapolated from the DEM map, nearest sensor 0.60 m away' };
}
