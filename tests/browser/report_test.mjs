// Browser test of the diagnosis' HTML report (docs/diagnosis.md, "Reading the report"), read in
// headless chromium at 1400 px as an engineer reads it: a linerwatch-sim campaign with one sensor
// cut to its first two readings, `linerwatch diagnose --json --html`, then checks that the page fits
// the window, that the verdict's words hold where their condition holds (no green "no mismatch" when
// the noise model does not fit or the test was blind; "within the noise" with the noise's size and
// the map's own standard error at a sensor; a refit "after" said to be one), that every sensor the
// fit left out says why and every rejected hypothesis which test it failed. Screenshots go to
// --artifacts.
//
// node report_test.mjs --bin BUILD/bin --modules NODE_MODULES --artifacts DIR [--chromium /usr/bin/chromium]
import { createRequire } from 'node:module';
import { execFileSync } from 'node:child_process';
import fs from 'node:fs';
import os from 'node:os';
import path from 'node:path';

const opt = { chromium: '/usr/bin/chromium' };
const argv = process.argv.slice(2);
for (let i = 0; i < argv.length; i += 2) {
  if (!argv[i].startsWith('--') || argv[i + 1] === undefined) fail(`bad argument '${argv[i]}'`);
  opt[argv[i].slice(2)] = argv[i + 1];
}
for (const k of ['bin', 'modules', 'artifacts']) if (!opt[k]) fail(`--${k} is required`);
const { chromium } = createRequire(path.join(path.resolve(opt.modules), 'noop.js'))('playwright-core');

function fail(msg) {
  console.error(`report_test: ${msg}`);
  process.exit(1);
}
function check(cond, msg) {
  if (!cond) throw new Error(`check failed: ${msg}`);
  console.log(`ok: ${msg}`);
}

const work = fs.mkdtempSync(path.join(os.tmpdir(), 'lw-report-'));
const artifacts = path.resolve(opt.artifacts);
fs.mkdirSync(artifacts, { recursive: true });
let browser = null;

// One campaign (`seed`, `days`); its second sensor keeps only its first two readings (no loop crossing).
async function runCase(name, seed, days) {
  const bundle = path.join(work, name);
  execFileSync(path.join(opt.bin, 'linerwatch-sim'), ['campaign', '--out', bundle, '--seed', String(seed), '--days', String(days), '--no-scan'], { stdio: 'inherit' });
  const crusher = JSON.parse(fs.readFileSync(path.join(bundle, 'crusher.json'), 'utf8'));
  const cut = crusher.sensors[1].id;
  const lines = fs.readFileSync(path.join(bundle, 'readings.csv'), 'utf8').split('\n');
  const header = lines[0].split(',');
  const col = header.indexOf('sensor_id');
  let seen = 0;
  const kept = [lines[0], ...lines.slice(1).filter((l) => !l || l.split(',')[col] !== cut || seen++ < 2)];
  fs.writeFileSync(path.join(bundle, 'readings.csv'), kept.join('\n'));
  const json = path.join(work, `${name}.json`);
  const html = path.join(work, `${name}.html`);
  execFileSync(path.join(opt.bin, 'linerwatch'), ['diagnose', bundle, '--json', json, '--html', html, '--no-pairs'], { stdio: 'inherit' });
  const d = JSON.parse(fs.readFileSync(json, 'utf8'));

  console.log(`case ${name}: ${d.findings.length} finding(s), improved.model ${d.improved.model}, test blind ${d.noise.mismatch_test_blind}`);
  const page = await browser.newPage({ viewport: { width: 1400, height: 1000 } });
  await page.goto(`file://${html}`);
  await page.screenshot({ path: path.join(artifacts, `${name}-1400-top.png`) });
  await page.screenshot({ path: path.join(artifacts, `${name}-1400-full.png`), fullPage: true });

  // Fits the window: nothing wider than 1400 px (the before/after pair scrolls inside itself).
  const width = await page.evaluate(() => document.documentElement.scrollWidth);
  check(width <= 1400, `the page fits 1400 px (scroll width ${width})`);
  // The verdict is on the first screen.
  const summary = page.locator('div.summary');
  const box = await summary.boundingBox();
  check(box && box.y + 40 < 1000, 'the verdict is on the first screen');
  const verdict = await page.locator('div.summary > p').first().innerText();
  const verdictHtml = await page.locator('div.summary > p').first().innerHTML();

  check(d.verdict && d.verdict.kind && d.verdict.headline, `the JSON has the verdict (${d.verdict?.kind})`);
  check(verdict.startsWith(d.verdict.headline), 'the report leads with the JSON verdict\'s headline');
  if (d.findings.length === 0) {
    if (d.verdict.kind === 'no_mismatch') {
      check(/No mismatch beyond the noise/.test(verdict) && d.noise.model_fits && !d.noise.mismatch_test_blind, 'a tested "no mismatch" says so');
    } else {
      check(!/class="good"/.test(verdictHtml), `an untested "no mismatch" (${d.verdict.kind}) is not shown in green`);
      if (d.verdict.kind === 'noise_model_does_not_fit')
        check(!d.noise.model_fits && verdict.includes('Not tested') && verdict.includes('no evidence that the DEM-based prediction agrees'),
          'a noise model that does not fit is said to test nothing');
      else
        check(verdict.includes('could not have seen one') && verdict.includes('not testable with this map'), 'a blind test says so');
    }
    if (d.noise.detection_limit)
      check(verdict.includes(`rise by about ${d.noise.detection_limit.chi2_to_detect.toFixed(0)}`), 'the verdict says what the test could have seen');
    const used = d.sensors.filter((s) => s.used && s.residual_mm !== undefined);
    used.sort((a, b) => Math.abs(b.residual_mm) - Math.abs(a.residual_mm));
    if (used.length) {
      const top = used[0];
      const text = await summary.innerText();
      check(text.includes(`sensor ${top.sensor_id} is off by`) && text.includes(`the mismatch test allows ${top.noise_sd_mm.toFixed(1)} mm`) &&
        text.includes(`the map's own standard error at sensor ${top.sensor_id} is ${top.map_sd_mm.toFixed(1)} mm`),
      `"within the noise" names sensor ${top.sensor_id}'s residual, the noise the test allowed (${top.noise_sd_mm.toFixed(1)} mm) and the map's own standard error there (${top.map_sd_mm.toFixed(1)} mm)`);
    }
  }
  if (d.improved.model !== 'findings') {
    check((await summary.innerText()).includes('a refit, not a finding'), 'the "after" of a campaign without findings is said to be a refit');
    check(!(await page.locator('body').innerText()).includes('with the findings'), 'no "with the findings" without findings');
  }
  // Every sensor the fit left out says why, in the sensor table.
  const excluded = d.sensors.filter((s) => !s.used);
  check(excluded.some((s) => s.sensor_id === cut), `the cut sensor ${cut} is not used`);
  for (const s of excluded) {
    check(s.excluded_because && s.excluded_because.length > 0, `sensor ${s.sensor_id}: JSON says why it is not used`);
    const row = page.locator('#sensor-noise + p + table tr', { hasText: s.excluded_because });
    check((await row.count()) === 1 && (await row.innerText()).startsWith(s.sensor_id), `sensor ${s.sensor_id}: the report says why it is not used`);
  }
  // Every rejected hypothesis says which test failed and by how much.
  const rejected = d.hypotheses.filter((hy) => !hy.accepted);
  const table = await page.locator('#hypotheses + p + table').innerText();
  for (const hy of rejected) {
    check(hy.rejected_because && /\(needs /.test(hy.rejected_because), `${hy.model}: JSON names the failed test`);
    check(table.includes(`rejected: ${hy.rejected_because.slice(0, 40)}`), `${hy.model}: the report names the failed test`);
  }
  check(!table.includes('not convincing'), 'no bare "not convincing"');
  await page.locator('#sensor-noise').scrollIntoViewIfNeeded();
  await page.screenshot({ path: path.join(artifacts, `${name}-1400-sensors.png`) });
  await page.close();
  return d;
}

async function main() {
  browser = await chromium.launch({ executablePath: opt.chromium, args: ['--no-sandbox', '--disable-gpu', '--no-first-run'] });
  // Two campaigns of the reference concave: at these seeds one has no finding (the "after" a
  // refit), one a finding; the checks above hold for whichever each gives.
  const results = [await runCase('quiet', 1, 95), await runCase('found', 7, 60)];
  console.log(`report_test: cases without a finding: ${results.filter((d) => d.findings.length === 0).length} of ${results.length}`);
}

try {
  await main();
  console.log('report_test: all checks passed');
} catch (e) {
  console.error(`report_test: ${e.stack || e}`);
  process.exitCode = 1;
} finally {
  if (browser) await browser.close();
  fs.rmSync(work, { recursive: true, force: true });
}
