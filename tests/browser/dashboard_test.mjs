// Browser test of the web dashboard against the real linerwatch-server: a demo campaign from
// linerwatch-sim, a real mosquitto, readings loaded over REST, then headless chromium (Playwright)
// checks the page, a live update and the token prompt. Screenshots go to --artifacts.
//
// node dashboard_test.mjs --bin BUILD/bin --web BUILD/web --modules NODE_MODULES --artifacts DIR
//                         [--chromium /usr/bin/chromium] [--mosquitto /usr/sbin/mosquitto]
import { createRequire } from 'node:module';
import { spawn, execFileSync } from 'node:child_process';
import crypto from 'node:crypto';
import fs from 'node:fs';
import net from 'node:net';
import os from 'node:os';
import path from 'node:path';

const opt = { chromium: '/usr/bin/chromium', mosquitto: 'mosquitto' };
const argv = process.argv.slice(2);
for (let i = 0; i < argv.length; i += 2) {
  if (!argv[i].startsWith('--') || argv[i + 1] === undefined) fail(`bad argument '${argv[i]}'`);
  opt[argv[i].slice(2)] = argv[i + 1];
}
for (const k of ['bin', 'web', 'modules', 'artifacts']) if (!opt[k]) fail(`--${k} is required`);
const { chromium } = createRequire(path.join(path.resolve(opt.modules), 'noop.js'))('playwright-core');

function fail(msg) {
  console.error(`dashboard_test: ${msg}`);
  process.exit(1);
}
function check(cond, msg) {
  if (!cond) throw new Error(`check failed: ${msg}`);
  console.log(`ok: ${msg}`);
}

const work = fs.mkdtempSync(path.join(os.tmpdir(), 'lw-browser-'));
const artifacts = path.resolve(opt.artifacts);
fs.mkdirSync(artifacts, { recursive: true });
for (const f of fs.readdirSync(artifacts)) if (/\.(png|log)$/.test(f)) fs.rmSync(path.join(artifacts, f));
const children = [];
let browser = null;
const pages = [];

function freePort() {
  return new Promise((resolve, reject) => {
    const srv = net.createServer();
    srv.on('error', reject);
    srv.listen(0, '127.0.0.1', () => { const { port } = srv.address(); srv.close(() => resolve(port)); });
  });
}

function start(name, cmd, args) {
  const log = fs.openSync(path.join(artifacts, `${name}.log`), 'a');
  const child = spawn(cmd, args, { stdio: ['ignore', log, log] });
  child.name = name;
  children.push(child);
  child.on('exit', (code, sig) => { child.exited = { code, sig }; });
  return child;
}

async function stop(child) {
  if (!child || child.exited) return;
  child.kill('SIGTERM');
  for (let i = 0; i < 50 && !child.exited; i++) await sleep(100);
  if (!child.exited) child.kill('SIGKILL');
}

const sleep = (ms) => new Promise((r) => setTimeout(r, ms));

// Waits are bounds only a real failure reaches (90 s for the server's start-up, which builds the
// map model, and its reconstructions; 60 s for the page): both take seconds on a loaded machine.
const kPageWaitMs = 60000;

async function waitFor(what, fn, ms = 90000) {
  const end = Date.now() + ms;
  let last;
  while (Date.now() < end) {
    try { if (await fn()) return; } catch (e) { last = e; }
    await sleep(200);
  }
  throw new Error(`timed out waiting for ${what}${last ? `: ${last.message}` : ''}`);
}

async function http(base, method, p, body, token) {
  const headers = { 'Content-Type': 'application/json' };
  if (token) headers.Authorization = `Bearer ${token}`;
  const res = await fetch(base + p, { method, headers, body: body === undefined ? undefined : JSON.stringify(body) });
  const text = await res.text();
  let json = null;
  try { json = JSON.parse(text); } catch { /* not JSON */ }
  return { status: res.status, json, text };
}

async function startServer(http_port, broker_port, tokensFile) {
  const args = ['--broker', `tcp://127.0.0.1:${broker_port}`, '--db', path.join(work, 'db.sqlite'),
    '--http', `127.0.0.1:${http_port}`, '--crusher-dir', path.join(work, 'crushers'), '--web-dir', path.resolve(opt.web)];
  if (tokensFile) args.push('--tokens', tokensFile);
  const server = start('linerwatch-server', path.join(opt.bin, 'linerwatch-server'), args);
  const base = `http://127.0.0.1:${http_port}`;
  await waitFor('linerwatch-server /healthz', async () => {
    if (server.exited) throw new Error(`linerwatch-server exited (${JSON.stringify(server.exited)}), see ${artifacts}/linerwatch-server.log`);
    const r = await http(base, 'GET', '/healthz');
    return r.status === 200 && r.json?.status === 'ok';
  });
  return { server, base };
}

// The bundle's readings.csv as the REST body: per sensor in time order, seq counting from 0.
function campaignReadings(bundle) {
  const lines = fs.readFileSync(path.join(bundle, 'readings.csv'), 'utf8').trim().split('\n').slice(1);
  const bySensor = new Map();
  for (const line of lines) {
    const [time, sensor, thickness] = line.split(',');
    if (!bySensor.has(sensor)) bySensor.set(sensor, []);
    bySensor.get(sensor).push({ time, thickness_mm: Number(thickness) });
  }
  const out = [];
  for (const [sensor, list] of bySensor) {
    list.sort((a, b) => a.time.localeCompare(b.time));
    list.forEach((r, seq) => out.push({ sensor, seq, time: r.time, thickness_mm: r.thickness_mm, loops_intact: r.thickness_mm, flags: 0, battery_mv: 3600 }));
  }
  return out;
}

async function newPage() {
  const context = await browser.newContext({ viewport: { width: 1500, height: 1500 } });
  const page = await context.newPage();
  page.setDefaultTimeout(kPageWaitMs);
  page.errors = [];
  page.on('pageerror', (e) => page.errors.push(e.message));
  page.on('console', (m) => { if (m.type() === 'error') console.log(`browser console: ${m.text()}`); });
  page.on('response', (r) => { if (r.status() >= 400) console.log(`browser: ${r.status()} ${r.url()}`); });
  pages.push(page);
  return page;
}

async function main() {
  // 1. demo crusher
  const bundle = path.join(work, 'crushers', 'demo');
  execFileSync(path.join(opt.bin, 'linerwatch-sim'), ['campaign', '--out', bundle, '--days', '40', '--seed', '3', '--no-scan', '--no-operations'], { stdio: 'inherit' });
  const crusher = JSON.parse(fs.readFileSync(path.join(bundle, 'crusher.json'), 'utf8')).crusher_id;
  const readings = campaignReadings(bundle);

  // 2. broker and server
  const brokerPort = await freePort();
  fs.writeFileSync(path.join(work, 'mosquitto.conf'), `listener ${brokerPort} 127.0.0.1\nallow_anonymous true\npersistence false\n`);
  start('mosquitto', opt.mosquitto, ['-c', path.join(work, 'mosquitto.conf')]);
  const httpPort = await freePort();
  let { server, base } = await startServer(httpPort, brokerPort, null);

  // 3. load the campaign
  let stored = 0;
  for (let i = 0; i < readings.length; i += 1000) {
    const r = await http(base, 'POST', `/api/v1/crushers/${crusher}/readings`, { readings: readings.slice(i, i + 1000) });
    check(r.status === 200, `POST readings batch ${i / 1000} -> ${r.status} ${r.text.slice(0, 200)}`);
    stored += r.json.stored;
  }
  check(stored === readings.length, `stored all ${readings.length} campaign readings (server said ${stored})`);
  // The previous liner's boards' last reports, worn, half a day before installed_at (a reline): stored,
  // marked previous_liner by the server, and not drawn in a sensor's series.
  const config = JSON.parse(fs.readFileSync(path.join(bundle, 'crusher.json'), 'utf8'));
  const oldTime = new Date(Date.parse(config.installed_at) - 12 * 3600000).toISOString().replace(/\.\d{3}Z$/, 'Z');
  const old = config.sensors.map((x) => ({ sensor: String(x.id), seq: 900000, time: oldTime, thickness_mm: x.thickness_new_mm - 60,
    loops_intact: x.thickness_new_mm - 60, flags: 0, battery_mv: 3100 }));
  const oldPost = await http(base, 'POST', `/api/v1/crushers/${crusher}/readings`, { readings: old });
  check(oldPost.status === 200 && oldPost.json.stored === old.length, `stored ${old.length} readings of a previous liner (${oldPost.text.slice(0, 200)})`);
  // The server reconstructs the wear in the background after a commit.
  await waitFor('the server\'s first wear reconstruction', async () => (await http(base, 'GET', `/api/v1/crushers/${crusher}/wear?faces=false`)).status === 200);
  check(true, 'wear reconstructed from the loaded readings');

  browser = await chromium.launch({
    executablePath: opt.chromium,
    args: ['--no-sandbox', '--disable-gpu', '--enable-unsafe-swiftshader', '--disable-quic', '--no-first-run',
      '--disable-background-networking', '--disable-component-update', '--disable-sync'],
  });

  // 4. the page: list -> crusher -> map, 3D, series, summary
  const page = await newPage();
  await page.goto(base + '/');
  await page.locator(`[data-testid="crusher-card"][data-crusher="${crusher}"]`).click();
  const map = page.locator('[data-testid="wear-map"]');
  await map.waitFor();
  await page.waitForFunction(() => document.querySelector('[data-testid="wear-map"]')?.dataset.minMm);
  const faces = Number(await map.getAttribute('data-faces'));
  check(faces === 5184, `map draws all ${faces} faces of the wear map`);
  const mapMin0 = Number(await map.getAttribute('data-min-mm'));
  check(mapMin0 > 0 && mapMin0 < 120, `map shows a thinnest spot (${mapMin0} mm)`);
  // The map is really painted: count distinct colours in the plot area.
  const colours = await page.evaluate(() => {
    const c = document.querySelector('[data-testid="wear-map"]');
    const d = c.getContext('2d').getImageData(0, 0, c.width, c.height).data;
    const seen = new Set();
    for (let i = 0; i < d.length; i += 4 * 97) seen.add((d[i] << 16) | (d[i + 1] << 8) | d[i + 2]);
    return seen.size;
  });
  check(colours > 20, `map is painted with a colour scale (${colours} distinct colours sampled)`);
  const series = page.locator('[data-testid="sensor-series"]');
  await series.waitFor();
  const sensor = await series.getAttribute('data-sensor');
  const points0 = Number(await series.getAttribute('data-points'));
  const expected = readings.filter((r) => r.sensor === sensor).length;
  check(points0 === expected, `series of sensor ${sensor} shows its ${expected} readings of this liner, not the previous liner's (${points0})`);
  check(await page.locator('[data-testid="min-line"]').count() === 1, 'series shows the minimum-thickness line');
  check(await page.locator('[data-testid="liner-3d"]').count() === 1, '3D liner view is present');
  const row = readings.length && JSON.parse(fs.readFileSync(path.join(bundle, 'crusher.json'), 'utf8')).sensors.find((x) => String(x.id) === sensor).row;
  const rowCell = page.locator(`[data-testid="row-min-${row}"]`);
  const rowMin0 = parseFloat(await rowCell.textContent());
  check(Number.isFinite(rowMin0), `summary shows row ${row} minimum ${rowMin0} mm`);
  await page.waitForFunction(() => document.getElementById('live').dataset.state === 'live', null, { timeout: kPageWaitMs });
  check(true, 'live updates connected (SSE)');
  // 4a. alarms (docs/alarms.md): the campaign's boards last reported weeks ago, so sensor_silent
  // alarms are active: the banner counts them; acknowledging one from the list moves it to
  // acknowledged (by "anonymous" on this open server) and out of the banner's count.
  const banner = page.locator('[data-testid="alarm-banner"]:not([hidden])');
  await banner.waitFor({ timeout: kPageWaitMs });
  const active0 = Number(await banner.getAttribute('data-count'));
  check(active0 > 0, `alarm banner shows ${active0} active alarms`);
  const ackButton = page.locator('[data-testid^="alarm-ack-"]').first();
  const ackId = (await ackButton.getAttribute('data-testid')).slice('alarm-ack-'.length);
  await ackButton.click();
  await page.waitForFunction((id) => document.querySelector(`[data-testid="alarm-${id}"]`)?.dataset.state === 'acknowledged', ackId, { timeout: kPageWaitMs });
  const active1 = Number(await page.locator('[data-testid="alarm-banner"]').getAttribute('data-count'));
  check(active1 === active0 - 1, `acknowledged alarm ${ackId} from the page: banner ${active0} -> ${active1}`);
  const listed = (await http(base, 'GET', `/api/v1/crushers/${crusher}/alarms?state=acknowledged`)).json.alarms;
  check(listed.some((a) => String(a.id) === ackId && a.acknowledged_by === 'anonymous'), 'the server has it acknowledged by anonymous');
  await page.screenshot({ path: path.join(artifacts, '1-crusher.png'), fullPage: true });

  // 4b. the headline is the thinnest area the data support, labelled; never single faces "worn through"
  const headline = await page.locator('[data-testid="kpi-min"]').textContent();
  check(/Thinnest (area|sensor reading)/.test(headline) && !/faces? worn through/.test(headline), `headline: ${headline}`);
  const served = (await http(base, 'GET', `/api/v1/crushers/${crusher}/wear?faces=false`)).json;
  if (served.thinnest_area.extrapolated)
    check(headline.includes('extrapolated from the DEM map, nearest sensor'), 'headline says the area is extrapolated from the DEM map');
  // The setting's opening at the discharge ring, as served, with the mantle said to be left out.
  const rate = await page.locator('[data-testid="kpi-rate-detail"]').textContent();
  check(served.setting && /setting opened \d+\.\d mm \(band \d+\.\d–\d+\.\d\) at the discharge/.test(rate) && rate.includes('mantle not included'),
    `setting line: ${rate}`);
  // Both sizes: the page and the per-row table fit without scrolling sideways, the reline column
  // shows, and the map's angle labels keep apart.
  for (const [vw, vh] of [[1400, 1000], [390, 844]]) {
    const context = await browser.newContext({ viewport: { width: vw, height: vh } });
    const p = await context.newPage();
    p.setDefaultTimeout(kPageWaitMs);
    pages.push(p);
    await p.goto(base + '/');
    await p.locator('[data-testid="crusher-card"] dl.meta dt').first().waitFor();
    const listFits = await p.evaluate(() => document.documentElement.scrollWidth <= window.innerWidth);
    check(listFits, `${vw} px: crusher list fits the width; card labels and values are separate (dt/dd)`);
    await p.locator(`[data-testid="crusher-card"][data-crusher="${crusher}"]`).click();
    await p.waitForFunction(() => document.querySelector('[data-testid="wear-map"]')?.dataset.thetaTickPx);
    const m = await p.evaluate((rowName) => {
      const wrap = document.querySelector('.table-wrap');
      const reline = document.querySelector(`[data-testid="row-reline-${rowName}"]`).getBoundingClientRect();
      const c = document.querySelector('[data-testid="wear-map"]');
      return { page: document.documentElement.scrollWidth, inner: window.innerWidth, wrap: wrap.scrollWidth, wrapClient: wrap.clientWidth,
        relineRight: reline.right, relineWidth: reline.width, wrapRight: wrap.getBoundingClientRect().right,
        tickPx: Number(c.dataset.thetaTickPx), labelPx: Number(c.dataset.thetaLabelPx) };
    }, row);
    check(m.page <= m.inner, `${vw} px: page fits (${m.page} <= ${m.inner})`);
    check(m.wrap <= m.wrapClient, `${vw} px: per-row table fits its card (${m.wrap} <= ${m.wrapClient})`);
    check(m.relineWidth > 0 && m.relineRight <= m.wrapRight + 1, `${vw} px: reline column visible (right ${m.relineRight} <= ${m.wrapRight})`);
    check(m.tickPx > m.labelPx + 4, `${vw} px: map angle labels (${m.labelPx} px wide) are ${m.tickPx} px apart`);
    await p.screenshot({ path: path.join(artifacts, `1-crusher-${vw}px.png`), fullPage: true });
    check(p.errors === undefined || p.errors.length === 0, `${vw} px: no page errors`);
    await context.close();
  }

  // 5. live: one more, thinner reading for the shown sensor; the page changes without a reload
  await page.evaluate(() => { window.__noReload = true; });
  const mine = readings.filter((r) => r.sensor === sensor);
  const last = mine[mine.length - 1];
  const injected = { sensor, seq: last.seq + 1, time: new Date(Date.parse(last.time) + 3600000).toISOString().replace(/\.\d{3}Z$/, 'Z'),
    thickness_mm: last.thickness_mm - 3, loops_intact: last.thickness_mm - 3, flags: 0, battery_mv: 3590 };
  const inj = await http(base, 'POST', `/api/v1/crushers/${crusher}/readings`, { readings: [injected] });
  check(inj.status === 200 && inj.json.stored === 1, `injected reading ${injected.thickness_mm} mm for sensor ${sensor}`);
  await page.waitForFunction(([n]) => Number(document.querySelector('[data-testid="sensor-series"]')?.dataset.points) === n, [points0 + 1], { timeout: kPageWaitMs });
  check(Number(await series.getAttribute('data-last-mm')) === injected.thickness_mm, 'series gained the injected reading live');
  await page.waitForFunction(([m]) => Number(document.querySelector('[data-testid="wear-map"]').dataset.minMm) !== m, [mapMin0], { timeout: kPageWaitMs });
  const mapMin1 = Number(await map.getAttribute('data-min-mm'));
  check(mapMin1 < mapMin0, `map's thinnest spot updated live: ${mapMin0} -> ${mapMin1} mm`);
  await page.waitForFunction(([id, v]) => parseFloat(document.querySelector(`[data-testid="row-min-${id}"]`).textContent) !== v, [row, rowMin0], { timeout: kPageWaitMs });
  const rowMin1 = parseFloat(await rowCell.textContent());
  check(rowMin1 < rowMin0, `summary row ${row} minimum updated live: ${rowMin0} -> ${rowMin1} mm`);
  check(await page.evaluate(() => window.__noReload === true), 'no page reload');
  check(page.errors.length === 0, `no page errors (${page.errors.join('; ')})`);
  await page.screenshot({ path: path.join(artifacts, '2-after-live-reading.png'), fullPage: true });

  // 5a. liner campaigns (docs/campaigns.md): the panel lists crusher.json's one campaign; a reline
  // posted over REST shows at once (SSE `campaign`), the old campaign ended; voiding it shows it
  // voided by anonymous and the first campaign running again. No reload.
  const campaignRow = (i) => page.locator(`[data-testid="campaign-${i}"]`);
  await campaignRow(0).waitFor();
  check(await page.locator('[data-testid="campaigns"]').getAttribute('data-count') === '1' && await campaignRow(0).getAttribute('data-state') === 'running',
    'campaign panel lists one running campaign');
  const relineTime = new Date(Date.parse(config.installed_at) + 20 * 86400000).toISOString().replace(/\.\d{3}Z$/, 'Z');
  const fresh = config.concave.thickness_new_mm + 5;
  const relined = await http(base, 'POST', `/api/v1/crushers/${crusher}/relines`, { time: relineTime, thickness_new_mm: fresh });
  check(relined.status === 201, `reline at ${relineTime} with ${fresh} mm posted over REST (${relined.status} ${relined.text.slice(0, 200)})`);
  await page.waitForFunction(() => document.querySelector('[data-testid="campaigns"]')?.dataset.count === '2', null, { timeout: kPageWaitMs });
  check(await campaignRow(0).getAttribute('data-state') === 'ended' && await campaignRow(1).getAttribute('data-state') === 'running',
    'after the reline the panel shows the first campaign ended and the new one running');
  check(await campaignRow(1).getAttribute('data-start') === relineTime && parseFloat(await page.locator('[data-testid="campaign-thickness-1"]').textContent()) === fresh,
    `the new campaign starts ${relineTime} at ${fresh} mm`);
  await page.waitForFunction((mm) => document.querySelector('[data-testid="liner-line"]')?.textContent.includes(`new ${mm} mm`), fresh, { timeout: kPageWaitMs });
  check(true, `the page's liner line says new ${fresh} mm`);
  await page.screenshot({ path: path.join(artifacts, '2a-after-reline.png'), fullPage: true });
  const voided = await http(base, 'POST', `/api/v1/crushers/${crusher}/relines/${relineTime}/void`, { reason: 'posted by mistake' });
  check(voided.status === 200 && voided.json.voided === true, `reline voided over REST (${voided.status} ${voided.text.slice(0, 200)})`);
  await page.waitForFunction(() => document.querySelector('[data-testid="campaign-1"]')?.dataset.state === 'voided', null, { timeout: kPageWaitMs });
  const voidText = await page.locator('[data-testid="campaign-state-1"]').textContent();
  check(/voided by anonymous/.test(voidText) && voidText.includes('posted by mistake') && await campaignRow(0).getAttribute('data-state') === 'running',
    `the panel shows the reline voided (${voidText}) and the first campaign running again`);
  check(await page.evaluate(() => window.__noReload === true), 'no page reload');
  check(page.errors.length === 0, `no page errors (${page.errors.join('; ')})`);

  // 6. token-protected server: the page asks for the token, then works
  await page.context().close();
  await stop(server);
  const token = crypto.randomBytes(16).toString('hex');
  const tokensFile = path.join(work, 'tokens.json');
  fs.writeFileSync(tokensFile, JSON.stringify({ tokens: [{ name: 'ops', sha256: crypto.createHash('sha256').update(token).digest('hex'), scopes: ['read', 'write'] }] }));
  ({ server, base } = await startServer(await freePort(), brokerPort, tokensFile));
  check((await http(base, 'GET', '/api/v1/crushers')).status === 401, 'API without a token answers 401');
  const page2 = await newPage();
  await page2.goto(base + '/');
  const dialog = page2.locator('#token-dialog');
  await dialog.waitFor({ state: 'visible', timeout: kPageWaitMs });
  check(true, 'token prompt shown');
  await page2.screenshot({ path: path.join(artifacts, '3-token-prompt.png') });
  await page2.fill('#token-input', token);
  await page2.click('#token-submit');
  await page2.locator(`[data-testid="crusher-card"][data-crusher="${crusher}"]`).waitFor({ timeout: kPageWaitMs });
  check(await page2.evaluate(() => sessionStorage.getItem('linerwatch.token')) === token, 'token kept in sessionStorage; crusher list loads');
  await page2.locator(`[data-testid="crusher-card"][data-crusher="${crusher}"]`).click();
  await page2.waitForFunction(() => document.getElementById('live').dataset.state === 'live', null, { timeout: kPageWaitMs });
  check(true, 'live updates connect with the token (access_token)');
  // A write-scope token may start a diagnosis from the page (its result is not waited for).
  await page2.click('[data-testid="run-diagnosis"]');
  await page2.waitForFunction(() => ['running', 'done'].includes(document.querySelector('[data-testid="diagnosis-status"]')?.dataset.status), null, { timeout: kPageWaitMs });
  check(true, 'Run diagnosis started one with the write-scope token');
  await page2.screenshot({ path: path.join(artifacts, '4-with-token.png'), fullPage: true });
  check(page2.errors.length === 0, `no page errors (${page2.errors.join('; ')})`);
}

let status = 0;
try {
  await main();
  console.log(`dashboard_test: passed; screenshots in ${artifacts}`);
} catch (e) {
  status = 1;
  console.error(`dashboard_test: FAILED: ${e.message}`);
  for (const [i, p] of pages.entries()) await p.screenshot({ path: path.join(artifacts, `failure-page${i + 1}.png`), fullPage: true }).catch(() => {});
  console.error(`  logs and screenshots in ${artifacts}`);
} finally {
  if (browser) await browser.close().catch(() => {});
  for (const c of children.reverse()) await stop(c);
  fs.rmSync(work, { recursive: true, force: true });
}
process.exit(status);
