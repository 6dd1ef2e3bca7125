// Diagnosis panel: before/after fit numbers as paired bars, findings, mismatch regions, data quality.
import { h, s, fmt, fmtDate, fmtDateTime } from './util.js';

const LABELS = {
  work_hardening: 'Work hardening',
  hardness_gradient: 'Hardness gradient',
  squeeze_wear: 'Squeeze wear',
  profile_evolution: 'Profile evolution',
  feed_segregation: 'Feed segregation',
  throughput_variation: 'Throughput variation',
  material_loss: 'Material loss',
  unexplained: 'Unexplained mismatch',
};

// `found`: the "after" is a model with findings. Without, it is a refit of the same Eq. 9 to the same
// readings: its bar is grey and its change is not coloured as an improvement.
function metricChart(title, before, after, found) {
  const w = 220;
  const hgt = 96;
  const max = Math.max(before ?? 0, after ?? 0, 1e-9) * 1.15;
  const bar = (y, v, color, label) => {
    const len = v == null ? 0 : (v / max) * (w - 90);
    return [
      s('text', { x: 0, y: y + 13, 'font-size': 11, fill: '#4a5868' }, label),
      s('rect', { x: 46, y, width: Math.max(1, len), height: 18, rx: 3, fill: color }),
      s('text', { x: 50 + len, y: y + 13, 'font-size': 12, 'font-weight': 600, fill: '#1b2633' }, v == null ? '–' : `${fmt(v, 2)} mm`),
    ];
  };
  const change = before && after != null ? ((after - before) / before) * 100 : null;
  return h('div', { class: 'diag-metric card' },
    h('div', { class: 'sub' }, title),
    s('svg', { viewBox: `0 0 ${w} ${hgt}`, height: hgt, preserveAspectRatio: 'xMinYMid meet' },
      bar(14, before, '#9aa6b2', 'before'),
      bar(44, after, found ? '#1565c0' : '#c3cad2', found ? 'after' : 'refit'),
      s('text', { x: 0, y: 88, 'font-size': 11, fill: !found ? '#4a5868' : change != null && change < 0 ? '#2e7d32' : '#c62828' },
        change == null ? '' : found ? `${change < 0 ? '' : '+'}${fmt(change, 0)} %` : 'refit to the same data: not an improvement')));
}

function predictionChart(pred, model) {
  const base = pred?.baseline?.sensors || {};
  const impr = pred?.improved?.sensors || {};
  const ids = Object.keys(base).filter((k) => k in impr);
  if (!ids.length) return null;
  const w = 640;
  const rowH = 22;
  const hgt = ids.length * rowH + 30;
  const max = Math.max(...ids.flatMap((k) => [base[k], impr[k]])) * 1.1;
  const X = (v) => 60 + (v / max) * (w - 130);
  const svg = s('svg', { viewBox: `0 0 ${w} ${hgt}`, height: hgt, style: 'width:100%' });
  ids.forEach((k, i) => {
    const y = 8 + i * rowH;
    svg.append(s('text', { x: 0, y: y + 12, 'font-size': 11, fill: '#4a5868' }, k));
    svg.append(s('rect', { x: 60, y, width: X(base[k]) - 60, height: 8, fill: '#9aa6b2' }));
    svg.append(s('rect', { x: 60, y: y + 9, width: X(impr[k]) - 60, height: 8, fill: '#1565c0' }));
    svg.append(s('text', { x: X(Math.max(base[k], impr[k])) + 4, y: y + 13, 'font-size': 11, fill: '#1b2633' }, `${fmt(base[k])} → ${fmt(impr[k])} mm`));
  });
  return h('div', { style: { marginTop: '10px' } },
    h('div', { class: 'sub' }, `Predicted thickness at ${fmtDateTime(pred.time)}: grey = DEM alone (Eq. 9), blue = ${model === 'refit_baseline' ? 'no findings: the map recalibrated at the sensors' : 'with findings modelled'}`), svg);
}

export function renderDiagnosis(container, diag, { canWrite, onRun, runError }) {
  container.replaceChildren();
  const status = diag?.status || 'none';
  const head = h('div', { class: 'card-head' },
    h('div', {}, h('h2', {}, 'Diagnosis: where the DEM map and the sensors disagree'),
      h('div', { class: 'sub' }, 'Physics the simulation left out, modelled and checked against the recordings')),
    h('div', {},
      h('span', { class: 'status-pill', 'data-status': status, 'data-testid': 'diagnosis-status' }, status === 'none' ? 'not run' : status),
      diag?.time ? h('span', { class: 'sub' }, ` ${fmtDateTime(diag.time)} `) : null,
      canWrite !== false
        ? h('button', { type: 'button', class: 'primary', 'data-testid': 'run-diagnosis', disabled: status === 'running', onclick: onRun, style: { marginLeft: '8px' } },
          status === 'running' ? 'Running…' : 'Run diagnosis')
        : h('span', { class: 'sub', style: { marginLeft: '8px' } }, 'read-only token: cannot start a diagnosis')));
  container.append(head);
  if (runError) container.append(h('div', { class: 'error-box' }, runError));
  const res = diag?.result;
  if (!res) {
    container.append(h('div', { class: 'empty' }, status === 'failed'
      ? 'The last diagnosis failed.'
      : status === 'running' ? 'Diagnosis running on the stored readings…' : 'No diagnosis yet.'));
    return;
  }
  const b = res.baseline || {};
  const a = res.improved || {};
  const found = a.model === 'findings';
  container.append(h('div', { class: 'diag-metrics' },
    metricChart('RMSE on fitted readings', b.rmse_mm, a.rmse_mm, found),
    metricChart('Largest error', b.max_abs_mm, a.max_abs_mm, found),
    metricChart('RMSE on held-out data', b.holdout_rmse_mm, a.holdout_rmse_mm, found)));
  if (!found && a.what) container.append(h('p', { class: 'sub', 'data-testid': 'diagnosis-after' }, `Before: the DEM map alone (Eq. 9). After: ${a.what}.`));
  const pred = predictionChart(res.prediction, a.model);
  if (pred) container.append(pred);

  const mm = res.mismatch || {};
  const nRegions = mm.regions?.length || 0;
  const noise = res.noise || {};
  // The diagnosis' own verdict (what was found, or what was not tested) when it has one.
  container.append(h('p', { class: 'sub', 'data-testid': 'diagnosis-mismatch' }, !mm.detected
    ? res.verdict?.headline ? `${res.verdict.headline}: ${res.verdict.detail}` : (noise.mismatch_test_blind
      ? `No mismatch detected, but the test could not have seen one: ${noise.mismatch_test_blind_detail || 'the noise is as large as the wear'}. Not testable with this map.`
      : noise.model_fits === false
        ? `No mismatch beyond the noise; the noise model is wider than these data scatter (${noise.model_fit_detail || ''}).`
        : 'No mismatch between the DEM map and the sensors beyond the noise.')
    : nRegions
      ? `Mismatch found in ${nRegions} region(s), outlined on the map (purple: DEM predicts more wear than measured, green: less).`
      : 'Mismatch detected across the sensors as a whole, not confined to one region.'));
  if (mm.regions?.length) {
    container.append(h('ul', { class: 'dq' }, mm.regions.map((r) =>
      h('li', {}, `${r.sign === 'over' ? 'over-predicted' : 'under-predicted'} by ${fmt(r.size_mm)} mm: z ${fmt(r.z_min_m, 2)}–${fmt(r.z_max_m, 2)} m, θ ${fmt(r.theta_min_deg, 0)}–${fmt(r.theta_max_deg, 0)}°, ${fmtDate(r.from)} to ${fmtDate(r.to)}`))));
  }
  const findings = res.findings || [];
  container.append(h('ul', { class: 'findings', 'data-testid': 'findings' }, findings.map((f) =>
    h('li', {},
      h('span', { class: 'conf' }, `confidence ${fmt((f.confidence ?? 0) * 100, 0)} %`),
      h('span', { class: 'name' }, LABELS[f.effect] || f.effect),
      h('div', { class: 'confbar' }, h('span', { style: { width: `${Math.round((f.confidence ?? 0) * 100)}%` } })),
      h('div', { class: 'expl' }, f.explanation || ''),
      f.parameters && Object.keys(f.parameters).length
        ? h('div', { class: 'params' }, Object.entries(f.parameters).map(([k, v]) => `${k} = ${typeof v === 'number' ? +v.toPrecision(4) : JSON.stringify(v)}`).join('   '))
        : null))));
  const excluded = res.excluded_sensors || [];
  if (excluded.length) {
    container.append(h('h2', { style: { marginTop: '12px' } }, 'Sensors not used by the diagnosis'));
    container.append(h('ul', { class: 'dq', 'data-testid': 'excluded-sensors' }, excluded.map((x) => h('li', {}, `sensor ${x.sensor_id}: ${x.reason}`))));
  }
  const dq = res.data_quality || [];
  if (dq.length) {
    container.append(h('h2', { style: { marginTop: '12px' } }, 'Data quality (sensor faults, not wear)'));
    container.append(h('ul', { class: 'dq' }, dq.map((d) => h('li', {}, `sensor ${d.sensor_id}: ${d.issue} (${fmtDate(d.from)} – ${fmtDate(d.to)})`))));
  }
}
