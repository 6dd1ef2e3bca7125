// The crusher page's alarms (docs/alarms.md): a banner while any alarm is active and nobody has
// acknowledged it, and the list of open and recently cleared alarms with an acknowledge button.
// The list is read again from REST at each SSE `alarm` event.
import { api, ApiError, paths } from './api.js';
import { ago, fmtDateTime, h } from './util.js';

export function alarmsPanel(crusherId, onError) {
  const banner = h('div', { class: 'alarm-banner', 'data-testid': 'alarm-banner', role: 'alert', hidden: true });
  const list = h('tbody');
  const card = h('section', { class: 'card', 'data-testid': 'alarms' },
    h('div', { class: 'card-head' }, h('h2', {}, 'Alarms'), h('span', { class: 'sub' }, 'open, and cleared in the last 7 days')),
    h('div', { class: 'alarm-wrap' }, h('table', {},
      h('thead', {}, h('tr', {}, h('th', {}, 'Severity'), h('th', {}, 'Rule'), h('th', {}, 'What'), h('th', {}, 'Since'),
        h('th', {}, 'State'), h('th', {}, ''))),
      list)));

  const acknowledge = async (alarm, button) => {
    button.disabled = true;
    try {
      await api.post(paths.ack(crusherId, alarm.id));
    } catch (e) {
      // A cleared alarm (409) needs no acknowledgement: the list shows it cleared.
      if (!(e instanceof ApiError && e.status === 409)) onError(e);
    }
    await load();
  };

  const stateText = (a) => {
    if (a.state === 'acknowledged') return `acknowledged by ${a.acknowledged_by} ${ago(a.acknowledged_at)}`;
    if (a.state === 'cleared') return `cleared ${fmtDateTime(a.cleared_at)}`;
    return 'active';
  };

  const draw = (alarms) => {
    const active = alarms.filter((a) => a.state === 'active');
    banner.hidden = active.length === 0;
    banner.dataset.count = String(active.length);
    const worst = active.some((a) => a.severity === 'critical') ? 'critical' : 'warning';
    banner.dataset.severity = worst;
    banner.replaceChildren(
      h('strong', {}, `${active.length} active alarm${active.length === 1 ? '' : 's'} not acknowledged`),
      active.length ? ` · ${active[0].detail}` : '');
    list.replaceChildren(...(alarms.length ? alarms.map((a) => {
      const button = a.state === 'active'
        ? h('button', { type: 'button', class: 'ghost', 'data-testid': `alarm-ack-${a.id}`, onclick: (ev) => acknowledge(a, ev.target) }, 'Acknowledge')
        : '';
      return h('tr', { 'data-testid': `alarm-${a.id}`, 'data-state': a.state, 'data-rule': a.rule, class: `alarm-${a.severity}` },
        h('td', {}, a.severity), h('td', {}, a.rule), h('td', {}, a.detail), h('td', {}, fmtDateTime(a.since)),
        h('td', { 'data-testid': `alarm-state-${a.id}` }, stateText(a)), h('td', {}, button));
    }) : [h('tr', {}, h('td', { colspan: 6 }, 'No alarms.'))]));
  };

  async function load() {
    try {
      const res = await api.get(paths.alarms(crusherId));
      draw(res.alarms || []);
    } catch (e) {
      if (e instanceof ApiError && e.status === 503) return;  // a server that keeps no alarms
      onError(e);
    }
  }

  return { banner, card, load };
}
