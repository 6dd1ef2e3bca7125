// The crusher page's liner campaigns (docs/campaigns.md): one row per campaign, oldest first, with
// its start, end, new thickness, life, whether its end-of-life scan is kept, and whether it runs,
// ended or was voided (a reline posted by mistake: kept, never counted). The list is read again
// from REST at each SSE `campaign` event (a reline or a void).
import { api, ApiError, paths } from './api.js';
import { fmt, fmtDateTime, h } from './util.js';

export function campaignsPanel(crusherId, onError) {
  const list = h('tbody');
  const sub = h('span', { class: 'sub' }, 'oldest first');
  const card = h('section', { class: 'card', 'data-testid': 'campaigns' },
    h('div', { class: 'card-head' }, h('h2', {}, 'Liner campaigns'), sub),
    h('div', { class: 'alarm-wrap' }, h('table', { class: 'campaigns' },
      h('thead', {}, h('tr', {}, h('th', {}, 'Start'), h('th', {}, 'End'), h('th', { class: 'num' }, 'New (mm)'),
        h('th', { class: 'num' }, 'Life (days)'), h('th', {}, 'End-of-life scan'), h('th', {}, 'State'))),
      list)));

  const state = (c) => (c.voided ? 'voided' : c.running ? 'running' : 'ended');
  const stateText = (c) => {
    if (c.voided) return `voided by ${c.voided_by} ${fmtDateTime(c.voided_at)}${c.void_reason ? `: ${c.void_reason}` : ''}`;
    return c.running ? 'running' : 'ended';
  };

  const draw = (campaigns) => {
    const counted = campaigns.filter((c) => !c.voided).length;
    sub.textContent = `${counted} campaign${counted === 1 ? '' : 's'}, oldest first`;
    card.dataset.count = String(campaigns.length);
    list.replaceChildren(...campaigns.map((c, i) => h('tr', {
      'data-testid': `campaign-${i}`, 'data-start': c.start, 'data-state': state(c), class: `campaign-${state(c)}` },
    h('td', {}, fmtDateTime(c.start)),
    h('td', {}, c.end ? fmtDateTime(c.end) : '–'),
    h('td', { class: 'num', 'data-testid': `campaign-thickness-${i}` }, fmt(c.thickness_new_mm, 0)),
    h('td', { class: 'num' }, c.life_days == null ? '–' : fmt(c.life_days, 1)),
    h('td', {}, c.has_scan ? 'kept' : 'none'),
    h('td', { 'data-testid': `campaign-state-${i}` }, stateText(c)))));
  };

  async function load() {
    try {
      const res = await api.get(paths.campaigns(crusherId));
      draw(res.campaigns || []);
    } catch (e) {
      if (e instanceof ApiError && e.status === 503) { card.hidden = true; return; }  // a server that keeps no campaigns
      onError(e);
    }
  }

  return { card, load };
}
