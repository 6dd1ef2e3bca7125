// linerwatch dashboard: hash routes  #/  (crusher list)  and  #/c/CRUSHER[/SENSOR]  (one crusher).
import { api, paths, allReadings, subscribe, setToken, getToken, promptForToken, ApiError } from './api.js';
import { h, fmt, fmtDate, fmtDateTime, ago, parseTime, thicknessColor, rgb, flash } from './util.js';
import { UnwrappedMap, drawLegend } from './map.js';
import { LinerView } from './liner3d.js';
import { renderSeries } from './series.js';
import { renderDiagnosis } from './diagnosis.js';
import { alarmsPanel } from './alarms.js';
import { campaignsPanel } from './campaigns.js';

const app = document.getElementById('app');
const crumbs = document.getElementById('crumbs');
let page = null; // the current page's teardown

function setLive(state) {
  const el = document.getElementById('live');
  el.dataset.state = state;
  document.getElementById('live-text').textContent =
    { live: 'live', connecting: 'connecting…', lost: 'reconnecting…', off: 'offline' }[state] || state;
}

function pulseLive() {
  const el = document.getElementById('live');
  el.classList.remove('flash');
  void el.offsetWidth;
  el.classList.add('flash');
}

function showError(err) {
  app.replaceChildren(h('div', { class: 'error-box', 'data-testid': 'error' }, String(err.message || err)));
}

// ---------------------------------------------------------------- crusher list
async function listPage() {
  crumbs.replaceChildren('Crushers');
  app.replaceChildren(h('div', { class: 'empty' }, 'Loading crushers…'));
  const { crushers } = await api.get(paths.crushers());
  const cards = crushers.map((c) => {
    // The thinnest area the data support (docs/wear.md); the sensors' own reading where none is.
    const area = c.thinnest_area;
    const min = area ? (area.supported ? area.thickness_mm : area.sensor_fallback?.thickness_mm ?? null) : c.min_thickness_mm;
    const span = c.thickness_new_mm - 0;
    const pct = min == null ? 0 : Math.max(0, Math.min(100, (min / span) * 100));
    return h('a', { class: 'card crusher-card', href: `#/c/${encodeURIComponent(c.crusher_id)}`, 'data-testid': 'crusher-card', 'data-crusher': c.crusher_id },
      h('div', { class: 'card-head' }, h('h2', {}, c.crusher_id), h('span', { class: 'sub' }, `${c.sensor_count} sensors · ${c.rows.length} rows`)),
      h('div', { class: 'sub' }, area && !area.supported ? 'thinnest sensor reading (the map supports no area number)' : 'thinnest area remaining'),
      h('div', { class: 'big', style: { color: min != null && min < c.thickness_min_mm + 10 ? 'var(--bad)' : 'inherit' } },
        min == null ? '–' : `${fmt(min)} `,
        h('small', {}, min != null ? `mm of ${c.thickness_new_mm}` : c.pending ? 'starting up: wear not computed yet' : 'no readings yet')),
      h('div', { class: 'gauge', title: `minimum ${c.thickness_min_mm} mm` },
        h('span', { style: { width: `${pct}%`, background: rgb(thicknessColor(min, c.thickness_min_mm, c.thickness_new_mm)) } }),
        h('i', { style: { left: `${(c.thickness_min_mm / span) * 100}%` } })),
      h('dl', { class: 'meta' }, ...[
        ['installed', fmtDate(c.installed_at)],
        ['latest reading', c.latest_reading_time ? `${fmtDateTime(c.latest_reading_time)} (${ago(c.latest_reading_time)})` : '–'],
        ['rows', c.rows.map((r) => r.name).join(' · ')],
        ['wear map', `${c.face_count} faces · ${String(c.map_sha256 || '').slice(0, 12)}`],
      ].flatMap(([k, v]) => [h('dt', {}, k), h('dd', {}, v)])));
  });
  app.replaceChildren(
    h('h1', {}, 'Crushers'),
    h('div', { class: 'sub' }, 'Remaining concave liner thickness, from the wear sensors and the DEM wear map'),
    crushers.length ? h('div', { class: 'crusher-grid' }, cards) : h('div', { class: 'empty' }, 'No crushers configured on this server (see --crusher-dir).'));
  return () => {};
}

// ---------------------------------------------------------------- crusher page
// The sensors with a previous liner's latest reading (marked by the server after a reline) shown as
// having no reading of this liner yet.
function ofThisLiner(sensors) {
  return sensors.map((x) => (x.latest?.previous_liner ? { ...x, latest: null } : x));
}

// A thinnest area's size in words: the square patch, the band of that height all around (a ring),
// or the whole row.
function areaSize(a) {
  if (a.whole_row) return `the whole row ${a.row}`;
  return a.shape === 'ring' ? `${fmt(a.patch_m, 2)} m band all around` : `${fmt(a.patch_m, 1)} m patch`;
}

// Where it is: a ring or a row has a height and no angle.
function hasAngle(a) {
  return !a.whole_row && a.shape !== 'ring' && a.theta_deg != null;
}

function areaWhere(a) {
  if (a.whole_row) return `row ${a.row}`;
  return hasAngle(a) ? `${a.row}, z ${fmt(a.z_m, 2)} m, θ ${fmt(a.theta_deg, 0)}°` : `${a.row}, z ${fmt(a.z_m, 2)} m, all around`;
}

function extrapolatedText(a) {
  return a.nearest_sensor_m == null ? 'extrapolated from the DEM map, no sensor reports'
    : `extrapolated from the DEM map, nearest sensor ${fmt(a.nearest_sensor_m, 2)} m away`;
}

// A row's date that its thinnest sensor's own readings set (the area's estimate would be later).
function setBy(f) {
  return f.reach_set_by_sensor ? h('div', { class: 'band', 'data-testid': `reach-set-by-${f.row}` }, `set by sensor ${f.reach_set_by_sensor}'s own readings`) : null;
}

async function crusherPage(crusherId, initialSensor) {
  crumbs.replaceChildren(h('a', { href: '#/' }, 'Crushers'), ' / ', crusherId);
  app.replaceChildren(h('div', { class: 'empty' }, `Loading ${crusherId}…`));
  const st = {
    id: crusherId, detail: null, mesh: null, wear: null, forecast: null, sensors: [], diag: null,
    selected: initialSensor, readings: new Map(), canWrite: null, runError: null,
  };
  const [detail, mesh, sensors] = await Promise.all([
    api.get(paths.crusher(crusherId)), api.get(paths.mesh(crusherId)), api.get(paths.sensors(crusherId))]);
  st.detail = detail;
  st.mesh = mesh;
  st.sensors = ofThisLiner(sensors.sensors);
  const concave = detail.concave;
  if (!st.selected || !st.sensors.some((x) => x.id === st.selected)) {
    // Default: the sensor with the thinnest latest reading.
    const withLatest = st.sensors.filter((x) => x.latest);
    withLatest.sort((a, b) => a.latest.thickness_mm - b.latest.thickness_mm);
    st.selected = (withLatest[0] || st.sensors[0])?.id;
  }

  // layout
  const kpis = h('div', { class: 'kpis', 'data-testid': 'kpis' });
  const mapBox = h('div', { class: 'map-wrap' });
  const legend = h('canvas', { 'aria-label': 'colour legend, remaining thickness in mm' });
  const view3d = h('div', { class: 'view3d' });
  const chips = h('div', { class: 'sensor-chips', 'data-testid': 'sensor-chips' });
  const seriesBox = h('div', { class: 'series' });
  const seriesFoot = h('div', { class: 'series-foot' });
  const seriesTitle = h('h2', {}, 'Sensor');
  const table = h('tbody');
  const diagBox = h('div', { class: 'card', 'data-testid': 'diagnosis' });
  const mapSub = h('span', { class: 'sub' });
  const warnings = h('div');
  const alarms = alarmsPanel(crusherId, showInlineError);
  const campaigns = campaignsPanel(crusherId, showInlineError);
  // The liner in service: a reline or a void changes it (the detail is read again on each refresh).
  const headline = h('div', { class: 'sub', 'data-testid': 'liner-line' });
  const drawHeadline = () => {
    const d = st.detail;
    headline.textContent = `installed ${fmtDate(d.installed_at)} · new ${d.concave.thickness_new_mm} mm, minimum ${d.concave.thickness_min_mm} mm · ${d.sensors.length} sensors · wear map ${d.map.face_count} faces (${String(d.map.sha256).slice(0, 12)})`;
  };
  drawHeadline();
  app.replaceChildren(
    h('h1', {}, crusherId),
    headline,
    alarms.banner,
    warnings,
    kpis,
    alarms.card,
    h('div', { class: 'grid-2' },
      h('section', { class: 'card' },
        h('div', { class: 'card-head' }, h('h2', {}, 'Unwrapped concave: remaining thickness'), mapSub),
        mapBox,
        h('div', { class: 'legend' }, h('span', {}, 'mm remaining'), legend,
          h('span', {}, h('span', { style: { color: 'var(--bad)' } }, '┃'), ` minimum ${concave.thickness_min_mm} mm · ◎ thinnest · ● sensor (reading)`))),
      h('section', { class: 'card' },
        h('div', { class: 'card-head' }, h('h2', {}, '3D liner'), h('span', { class: 'sub' }, 'inner surface, same colours')),
        view3d)),
    h('div', { class: 'grid-2b' },
      h('section', { class: 'card' },
        h('div', { class: 'card-head' }, seriesTitle, h('span', { class: 'sub' }, 'click a sensor on the map or below')),
        chips, seriesBox, seriesFoot),
      h('section', { class: 'card' },
        h('div', { class: 'card-head' }, h('h2', {}, 'Per row'), h('span', { class: 'sub', 'data-testid': 'wear-time' })),
        h('div', { class: 'table-wrap' }, h('table', { class: 'summary', 'data-testid': 'row-summary' },
          h('thead', {}, h('tr', {}, [['Row'], ['Thinnest (mm)', 'num'], ['Area', 'where'], ['Wear rate', 'num rate'], ['Reline (band)', 'reline'], ['Sensors', 'num sensors']].map(([t, c]) => h('th', { class: c }, t)))),
          table)),
        h('p', { class: 'sub', 'data-testid': 'wear-note' }))),
    campaigns.card,
    diagBox);
  if (detail.map.warnings?.length) {
    warnings.append(h('div', { class: 'error-box' }, `Wear map warnings: ${detail.map.warnings.join('; ')}`));
  }

  const map = new UnwrappedMap(mapBox, { onSelectSensor: (id) => selectSensor(id) });
  const liner = new LinerView(view3d);

  function sensorState() {
    return st.sensors.map((x) => ({ ...x, thickness: x.latest ? x.latest.thickness_mm : null }));
  }

  function drawViews() {
    const w = st.wear;
    const state = {
      mesh: st.mesh,
      remaining: w?.remaining_mm || null,
      thicknessMin: concave.thickness_min_mm,
      thicknessNew: concave.thickness_new_mm,
      rows: concave.rows,
      sensors: sensorState(),
      // The thinnest area the data support, drawn where it has a place (a whole row has no angle).
      min: w?.thinnest_area && w.thinnest_area.thickness_mm != null
        ? { z_m: w.thinnest_area.z_m, theta_deg: hasAngle(w.thinnest_area) ? w.thinnest_area.theta_deg : null,
          thickness: w.thinnest_area.thickness_mm, patch_m: w.thinnest_area.patch_m, extrapolated: w.thinnest_area.extrapolated }
        : null,
      selected: st.selected,
      regions: st.diag?.result?.mismatch?.regions || [],
    };
    map.update(state);
    liner.update(state);
    drawLegend(legend, concave.thickness_min_mm, concave.thickness_new_mm);
    mapSub.textContent = w ? `from readings up to ${fmtDateTime(w.time)}` : 'no readings yet: as new';
  }

  function drawKpis() {
    const w = st.wear;
    const f = st.forecast;
    const frows = f?.rows || [];
    const overdue = frows.filter((r) => r.below_minimum_since).sort((a, b) => parseTime(a.below_minimum_since) - parseTime(b.below_minimum_since));
    const rowsWithDate = frows.filter((r) => r.reach_date || r.reach_earliest);
    const when = (r) => parseTime(r.reach_date || r.reach_earliest);
    rowsWithDate.sort((a, b) => when(a) - when(b));
    const next = rowsWithDate[0];
    const fastest = frows.reduce((m, r) => (r.rate_mm_per_day > (m?.rate_mm_per_day ?? -Infinity) ? r : m), null);
    const latest = st.sensors.map((x) => x.latest?.time).filter(Boolean).sort().pop();
    // The headline is the thinnest area the data support (docs/wear.md, thinnest area): its band,
    // its patch, whether a sensor is near it; the sensors' own reading where no area is supported.
    const a = w?.thinnest_area;
    const scaled = w && w.status !== 'no_sensors' && a && a.thickness_mm != null;
    const fb = a?.sensor_fallback;
    const shown = !scaled ? null : a.supported ? a.thickness_mm : fb ? fb.thickness_mm : null;
    const left = scaled ? (a.supported ? a.band_mm[0] : shown ?? a.band_mm[0]) - concave.thickness_min_mm : null;
    // Sensors that stopped reporting set no row scale (docs/wear.md, Global wear).
    const stale = [
      w?.sensors_stale?.length ? `not reporting, left out: ${w.sensors_stale.join(', ')}` : null,
      w?.sensors_stuck?.length ? `stuck (value not moving while its row wears), left out: ${w.sensors_stuck.join(', ')}` : null];
    const lines = !w ? ['no readings yet'] : !scaled ? [`cannot be estimated: ${w.status_detail || 'no row scale'}`] : [
      a.supported ? `band ${fmt(a.band_mm[0])}–${fmt(a.band_mm[1])} mm over a ${areaSize(a)}`
        : `no area is supported (band ${fmt(a.band_mm[0])}–${fmt(a.band_mm[1])} mm even over the whole row): ${fb ? `sensor ${fb.sensor} reads ${fmt(fb.thickness_mm, 0)} mm (${fmtDate(fb.time)})` : 'no sensor reading'}`,
      a.supported ? areaWhere(a) : null,
      a.extrapolated ? extrapolatedText(a) : null,
      left != null ? `${left >= 0 ? `${fmt(left)} mm above` : `${fmt(-left)} mm below`} the minimum` : null,
      a.worn_through ? 'worn through: the whole band is at 0 mm' : null,
      ...stale];
    const reline = overdue.length
      ? { value: 'overdue', lines: overdue.map((r) => `${r.row}: below minimum since ${fmtDate(r.below_minimum_since)}`) }
      : next ? { value: next.reach_date ? fmtDate(next.reach_date) : `not before ${fmtDate(next.reach_earliest)}`, lines: [
        `${next.row}: band ${fmtDate(next.reach_earliest)} – ${next.reach_latest ? fmtDate(next.reach_latest) : 'beyond forecast'}`,
        next.reach_date ? `${fmt((parseTime(next.reach_date) - parseTime(f.time)) / 86400000, 0)} days after the latest reading` : null,
        next.reach_note || null] }
        : { value: '–', lines: [frows.find((r) => r.reach_note)?.reach_note || 'no forecast yet'] };
    const detail = (testid, ls) => h('div', { class: 'detail', 'data-testid': testid }, ls.filter(Boolean).map((t) => h('div', {}, t)));
    kpis.replaceChildren(
      h('div', { class: `card kpi${left != null && left < 10 ? ' alarm' : ''}`, 'data-testid': 'kpi-min' },
        h('div', { class: 'label' }, scaled && !a.supported ? 'Thinnest sensor reading' : 'Thinnest area'),
        h('div', { class: 'value', 'data-value': shown ?? '' }, shown != null ? fmt(shown) : '–', ' ', h('small', {}, 'mm')),
        detail('kpi-min-band', lines)),
      h('div', { class: `card kpi${overdue.length ? ' alarm' : ''}`, 'data-testid': 'kpi-reline' },
        h('div', { class: 'label' }, 'Next reline'),
        h('div', { class: 'value' }, reline.value),
        detail('kpi-reline-detail', reline.lines)),
      h('div', { class: 'card kpi', 'data-testid': 'kpi-rate' },
        h('div', { class: 'label' }, 'Fastest wear'),
        h('div', { class: 'value' }, fastest ? fmt(fastest.rate_mm_per_day, 2) : '–', ' ', h('small', {}, 'mm/day')),
        detail('kpi-rate-detail', [fastest ? `row ${fastest.row}` : '', settingText(w?.setting)])),
      h('div', { class: 'card kpi', 'data-testid': 'kpi-latest' },
        h('div', { class: 'label' }, 'Latest reading'),
        h('div', { class: 'value', style: { fontSize: '20px' } }, latest ? fmtDateTime(latest) : '–'),
        detail('kpi-latest-detail', [`${st.detail.counters?.readings_stored ?? '–'} readings stored`, `${st.detail.counters?.duplicates ?? 0} duplicates · ${st.detail.counters?.rejected ?? 0} rejected${st.detail.counters?.conflicts ? ` · ${st.detail.counters.conflicts} conflicts` : ''}`])));
  }

  // The closed-side setting's opening by the concave's wear at the discharge ring (docs/wear.md,
  // Setting): the mantle's wear is not in it, and an unsupported band says so.
  function settingText(s) {
    if (!s || s.opening_mm == null) return null;
    if (!s.supported) return `setting: not supported (band half-width ${fmt(s.half_width_mm)} mm); mantle not included`;
    const band = `${fmt(s.opening_band_mm[0])}–${fmt(s.opening_band_mm[1])}`;
    const css = s.css_mm != null ? `: CSS ≈ ${fmt(s.css_mm, 0)} mm (set ${fmt(s.css_set_mm, 0)})` : '';
    return `setting opened ${fmt(s.opening_mm)} mm (band ${band}) at the discharge${css}; mantle not included`;
  }

  function drawTable() {
    const w = st.wear;
    const frows = new Map((st.forecast?.rows || []).map((r) => [r.row, r]));
    const wrows = w?.rows || [];
    const thick = (r) => r?.thinnest_area?.thickness_mm ?? r?.min_thickness_mm;
    const worst = wrows.reduce((m, r) => (m == null || thick(r) < thick(m) ? r : m), null);
    const now = Number.isFinite(parseTime(st.forecast?.time)) ? parseTime(st.forecast.time) : Date.now();
    const dates = [...frows.values()].flatMap((r) => [r.reach_earliest, r.reach_latest, r.reach_date]).map(parseTime).filter(Number.isFinite);
    const hi = Math.max(now, ...dates);
    const X = (t) => `${Math.max(0, Math.min(100, ((t - now) / (hi - now || 1)) * 100))}%`;
    const names = concave.rows.map((r) => r.name).reverse(); // top row first, like the liner
    table.replaceChildren(...names.map((name) => {
      const r = wrows.find((x) => x.row === name);
      const a = r?.thinnest_area;
      const f = frows.get(name);
      const mm = a ? (a.supported ? a.thickness_mm : a.sensor_fallback?.thickness_mm ?? null) : null;
      const colour = mm != null ? rgb(thicknessColor(mm, concave.thickness_min_mm, concave.thickness_new_mm)) : '#ccc';
      const pct = mm != null ? (mm / concave.thickness_new_mm) * 100 : 0;
      return h('tr', { class: r && r === worst ? 'worst' : null, 'data-row': name },
        h('td', { 'data-label': 'Row' }, h('b', {}, name)),
        h('td', { class: 'num', 'data-label': 'Thinnest (mm)', 'data-testid': `row-min-${name}` }, mm != null ? fmt(mm) : '–',
          h('span', { class: 'minbar' }, h('span', { style: { width: `${pct}%`, background: colour } })),
          a && a.band_mm?.[0] != null
            ? h('div', { class: 'band' }, a.supported ? `${fmt(a.band_mm[0])}–${fmt(a.band_mm[1])} mm` : `sensor ${a.sensor_fallback?.sensor ?? '–'}; map band ${fmt(a.band_mm[0])}–${fmt(a.band_mm[1])} mm`,
              a.worn_through ? ' · worn through' : '') : null),
        h('td', { class: 'where', 'data-label': 'Area' }, a ? [h('div', {}, a.supported ? areaSize(a) : 'no area supported'),
          a.supported && !a.whole_row ? h('div', { class: 'band' }, hasAngle(a) ? `z ${fmt(a.z_m, 2)} m, θ ${fmt(a.theta_deg, 0)}°` : `z ${fmt(a.z_m, 2)} m, all around`) : null,
          a.extrapolated ? h('div', { class: 'band', 'data-testid': `row-extrapolated-${name}` }, extrapolatedText(a)) : null] : '–'),
        h('td', { class: 'num rate', 'data-label': 'Wear rate' }, f ? `${fmt(f.rate_mm_per_day, 2)} mm/d` : '–', r ? h('div', { class: 'band' }, `worn ${fmt(r.mean_wear_mm)} mm mean`) : null),
        h('td', { class: 'reline', 'data-label': 'Reline (band)', 'data-testid': `row-reline-${name}` }, f?.below_minimum_since
          ? h('span', {}, h('b', { class: 'overdue' }, 'below minimum'), h('div', { class: 'band' }, `since ${fmtDate(f.below_minimum_since)}`), setBy(f))
          : f?.reach_date ? h('span', {}, h('b', {}, fmtDate(f.reach_date)), setBy(f),
            h('div', { class: 'band' }, `${fmtDate(f.reach_earliest)} – ${f.reach_latest ? fmtDate(f.reach_latest) : 'beyond forecast'}`),
            h('div', { class: 'reline-bar', title: 'from the latest reading to the latest reline date of any row' },
              Number.isFinite(parseTime(f.reach_earliest)) ? h('span', { class: 'rng', style: { left: X(parseTime(f.reach_earliest)), width: `calc(${X(parseTime(f.reach_latest) || hi)} - ${X(parseTime(f.reach_earliest))})` } }) : null,
              h('span', { class: 'pt', style: { left: X(parseTime(f.reach_date)) } })))
          : f ? h('span', {}, h('b', {}, f.reach_earliest ? `not before ${fmtDate(f.reach_earliest)}` : 'beyond forecast'),
            h('div', { class: 'band' }, f.reach_note || f.note || '')) : '–'),
        h('td', { class: 'num sensors', 'data-label': 'Sensors' }, r ? String(r.sensors_used ?? '–') : '–'));
    }));
    app.querySelector('[data-testid="wear-time"]').textContent = w ? `as of ${fmtDateTime(w.time)}` : '';
    app.querySelector('[data-testid="wear-note"]').textContent = w
      ? `${w.note || ''}. Map ${String(w.map_sha256 || '').slice(0, 12)}, ${w.readings_used?.length ?? 0} readings used.`
      : 'No readings yet.';
  }

  function drawChips() {
    chips.replaceChildren(...st.sensors.map((x) => h('button', {
      type: 'button', class: 'chip', 'aria-pressed': String(x.id === st.selected), 'data-sensor': x.id,
      onclick: () => selectSensor(x.id),
    }, h('span', { class: 'sw', style: { background: rgb(thicknessColor(x.latest?.thickness_mm, concave.thickness_min_mm, concave.thickness_new_mm)) } }),
    `${x.id} · ${x.row}${x.latest ? ` · ${x.latest.thickness_mm} mm` : ''}`)));
  }

  async function drawSeries() {
    const sensor = st.sensors.find((x) => x.id === st.selected);
    if (!sensor) { seriesBox.replaceChildren(h('div', { class: 'empty' }, 'No sensors.')); return; }
    if (!st.readings.has(sensor.id)) st.readings.set(sensor.id, await allReadings(crusherId, sensor.id, detail.liner_start));
    // A previous liner's last reports (worn, in the day before installed_at) are history: not drawn.
    const readings = st.readings.get(sensor.id).filter((r) => !r.previous_liner);
    const fc = (st.forecast?.sensors || []).find((x) => String(x.id) === String(sensor.id));
    seriesTitle.textContent = `Sensor ${sensor.id}: ${sensor.row}, θ ${fmt(sensor.theta_deg, 0)}°, z ${fmt(sensor.z_m, 2)} m`;
    renderSeries(seriesBox, { sensor, readings, forecast: fc, thicknessMin: concave.thickness_min_mm, thicknessNew: concave.thickness_new_mm, installedAt: detail.installed_at });
    const last = readings[readings.length - 1];
    seriesFoot.replaceChildren(
      h('span', { class: 'key' }, h('i', { style: { background: '#1565c0' } }), 'reading n = thickness in [n, n+1) mm'),
      h('span', { class: 'key' }, h('i', { style: { background: '#ef8f00' } }), 'forecast and band'),
      h('span', { class: 'key' }, h('i', { style: { background: '#c62828' } }), 'minimum thickness'),
      h('span', {}, 'latest ', h('b', { 'data-testid': 'series-latest' }, last ? `${last.thickness_mm} mm` : '–'), last ? ` (${fmtDateTime(last.time)}, battery ${last.battery_mv ?? '–'} mV)` : ''),
      h('span', {}, 'rate ', h('b', {}, fc ? `${fmt(fc.rate_mm_per_day, 2)} mm/day` : '–')),
      h('span', {}, 'reaches minimum ', h('b', {}, fc?.reach_date ? fmtDate(fc.reach_date) : '–'), fc?.reach_earliest ? ` (${fmtDate(fc.reach_earliest)} – ${fmtDate(fc.reach_latest)})` : ''),
      h('span', {}, `${readings.length} readings`),
      ...(fc?.note ? [h('span', {}, `forecast: ${fc.note}`)] : []));
  }

  function selectSensor(id) {
    st.selected = id;
    history.replaceState(null, '', `#/c/${encodeURIComponent(crusherId)}/${encodeURIComponent(id)}`);
    drawChips();
    drawViews();
    drawSeries().catch(showInlineError);
  }

  function showInlineError(err) {
    warnings.replaceChildren(h('div', { class: 'error-box' }, String(err.message || err)));
  }

  async function loadWear() {
    const [wear, forecast] = await Promise.all([
      api.get(paths.wear(crusherId)).catch((e) => { if (e.status === 404) return null; throw e; }),
      api.get(paths.forecast(crusherId)).catch((e) => { if (e.status === 404) return null; throw e; }),
    ]);
    st.wear = wear;
    st.forecast = forecast;
  }

  async function loadDiagnosis() {
    st.diag = await api.get(paths.diagnosis(crusherId)).catch((e) => (e.status === 404 ? null : Promise.reject(e)));
  }

  let diagTimer = null;
  function drawDiagnosis() {
    renderDiagnosis(diagBox, st.diag, { canWrite: st.canWrite, runError: st.runError, onRun: runDiagnosis });
    clearTimeout(diagTimer);
    if (st.diag?.status === 'running') {
      diagTimer = setTimeout(() => loadDiagnosis().then(() => { drawDiagnosis(); drawViews(); }).catch(showInlineError), 3000);
    }
  }

  async function runDiagnosis() {
    st.runError = null;
    try {
      await api.post(paths.diagnosis(crusherId), {});
      st.canWrite = true;
    } catch (e) {
      if (e instanceof ApiError && e.status === 403) st.canWrite = false;
      else st.runError = e.message;
    }
    await loadDiagnosis().catch(showInlineError);
    drawDiagnosis();
  }

  await Promise.all([loadWear(), loadDiagnosis()]);
  drawKpis();
  drawTable();
  drawChips();
  drawViews();
  drawDiagnosis();
  await drawSeries();

  // Live: a reading is appended at once; the wear, forecast and counters are refetched (debounced).
  let refreshTimer = null;
  let refreshing = false;
  const refresh = () => {
    clearTimeout(refreshTimer);
    refreshTimer = setTimeout(async () => {
      if (refreshing) { refresh(); return; }
      refreshing = true;
      try {
        const [sensorsRes, detailRes] = await Promise.all([api.get(paths.sensors(crusherId)), api.get(paths.crusher(crusherId)), loadWear()]);
        st.sensors = ofThisLiner(sensorsRes.sensors);
        st.detail = detailRes;
        drawHeadline();
        drawKpis();
        drawTable();
        drawChips();
        drawViews();
        await drawSeries();
        flash(kpis);
      } catch (e) {
        showInlineError(e);
      } finally {
        refreshing = false;
      }
    }, 500);
  };
  const stop = subscribe(crusherId, {
    reading: (r) => {
      pulseLive();
      const sensor = st.sensors.find((x) => String(x.id) === String(r.sensor));
      if (sensor) sensor.latest = { ...r };
      const list = st.readings.get(sensor?.id);
      if (list && !list.some((x) => x.seq === r.seq)) {
        list.push(r);
        list.sort((a, b) => parseTime(a.time) - parseTime(b.time));
      }
      if (sensor && sensor.id === st.selected) drawSeries().catch(showInlineError);
      drawChips();
      refresh();
    },
    wear: () => { pulseLive(); refresh(); },
    alarm: () => { pulseLive(); alarms.load(); },
    // A reline or a void: the list, and the liner's wear, forecast and sensors, read again.
    campaign: () => { pulseLive(); campaigns.load(); refresh(); },
  }, setLive);
  alarms.load();
  campaigns.load();

  return () => {
    stop();
    clearTimeout(refreshTimer);
    clearTimeout(diagTimer);
    map.destroy();
    liner.destroy();
  };
}

// ---------------------------------------------------------------- router
async function route() {
  if (page) { page(); page = null; }
  setLive('off');
  const parts = location.hash.replace(/^#\/?/, '').split('/').filter(Boolean).map(decodeURIComponent);
  try {
    if (parts[0] === 'c' && parts[1]) page = await crusherPage(parts[1], parts[2]);
    else page = await listPage();
  } catch (e) {
    showError(e);
  }
}

document.getElementById('token-button').addEventListener('click', async () => {
  if (getToken() && !confirm('Forget the stored token for this tab?')) return;
  setToken('');
  await promptForToken('Enter an access token for this linerwatch server.');
  route();
});
window.addEventListener('hashchange', route);
route();
