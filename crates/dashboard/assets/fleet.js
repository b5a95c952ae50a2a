// Cetratus dashboard, the fleet page: every PLC on the broker (GET /api/fleet, once a second)
// and the rollout of one package across them, whose changes come as `rollout` events on a
// stream of their own. Start, Pause, Resume and Abort are POSTs to /api/rollout/<action>.
'use strict';
(() => {
  const $ = (id) => document.getElementById(id);
  let report = null;
  let rows = [];
  let status = { enabled: false };

  function cell(tr, text, step) {
    const td = document.createElement('td');
    td.textContent = text === undefined || text === null ? '–' : String(text);
    if (step) td.dataset.step = step;
    tr.append(td);
  }

  function summary(r) {
    const counts = {};
    for (const p of Object.values(r.plcs || {})) counts[p.step] = (counts[p.step] || 0) + 1;
    const steps = Object.keys(counts).sort().map((s) => `${counts[s]} ${s}`).join(', ');
    const paused = r.paused ? ' (paused)' : '';
    return `${r.outcome}${paused} · stage ${r.stage}/${r.stages} · ${steps} · ${r.update}`;
  }

  function render() {
    const r = report;
    $('rollout-progress').textContent = !status.enabled
      ? 'rollouts are off: start the dashboard with --plans DIR'
      : r ? summary(r) : 'no rollout';
    const why = (r && r.reason) || status.error || '';
    $('rollout-reason').hidden = !why;
    $('rollout-reason').textContent = (r && r.alarm ? 'ALARM: ' : '') + why;
    const ids = new Set(rows.map((p) => p.id));
    for (const id of Object.keys((r && r.plcs) || {})) if (!ids.has(id)) rows.push({ id, online: false });
    const body = $('fleet-table').tBodies[0];
    body.replaceChildren();
    for (const p of rows) {
      const tr = document.createElement('tr');
      tr.dataset.plc = p.id;
      const at = (r && r.plcs && r.plcs[p.id]) || {};
      cell(tr, p.id);
      cell(tr, p.program);
      cell(tr, p.online ? p.primary : 'offline');
      cell(tr, p.status);
      cell(tr, at.stage);
      cell(tr, at.step, at.step);
      cell(tr, at.reason || '');
      body.append(tr);
    }
    const running = !!status.running;
    $('rollout-start').disabled = !status.enabled || running || !$('rollout-plan').value;
    $('rollout-pause').disabled = !running || (r && r.paused);
    $('rollout-resume').disabled = !status.enabled || !r || ['done', 'aborted'].includes(r.outcome) ||
      (running && !r.paused);
    $('rollout-abort').disabled = !status.enabled || !r || ['done', 'aborted'].includes(r.outcome);
  }

  function setPlans(plans) {
    const sel = $('rollout-plan');
    const chosen = sel.value;
    const have = [...sel.options].map((o) => o.value).join('\n');
    if (have === plans.join('\n')) return;
    sel.replaceChildren(...plans.map((p) => {
      const o = document.createElement('option');
      o.value = p;
      o.textContent = p;
      return o;
    }));
    if (plans.includes(chosen)) sel.value = chosen;
  }

  async function refresh() {
    try {
      const r = await fetch('/api/fleet');
      if (!r.ok) return;
      const j = await r.json();
      rows = j.plcs || [];
      status = j.rollout || { enabled: false };
      if (status.report) report = status.report;
      setPlans(status.plans || []);
      render();
    } catch (_) { /* the next second tries again */ }
  }

  async function act(action, body) {
    const r = await fetch(`/api/rollout/${action}`, {
      method: 'POST', headers: { 'Content-Type': 'application/json' }, body: JSON.stringify(body || {}),
    });
    const j = await r.json().catch(() => ({}));
    status.error = j.ok ? null : (j.error ? j.error.message : `HTTP ${r.status}`);
    refresh();
  }

  const ask = (text, action) => (window.cetratusAsk ? window.cetratusAsk(text, action) : action());
  $('rollout-start').addEventListener('click', () => {
    const plan = $('rollout-plan').value;
    ask(`Start the rollout of ${plan}? Its canary is loaded first; each stage waits for the ` +
      `one before it to pass quarantine and probation.`, () => act('start', { plan }));
  });
  $('rollout-pause').addEventListener('click', () => act('pause'));
  $('rollout-resume').addEventListener('click', () => act('resume'));
  $('rollout-abort').addEventListener('click', () => ask('Abort the rollout? The PLCs mid-update ' +
    'are removed from quarantine or reverted in probation; PLCs already done stay.', () => act('abort')));
  $('rollout-plan').addEventListener('change', render);

  const stream = new EventSource('/api/stream');
  stream.addEventListener('rollout', (e) => { report = JSON.parse(e.data); render(); });
  stream.addEventListener('rollout_ended', () => refresh());
  setInterval(refresh, 1000);
  refresh();
})();
