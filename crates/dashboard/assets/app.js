// Cetratus dashboard: plain JS, no build step. Everything arrives on one EventSource
// (/api/stream?plc=ID); commands are POSTs whose response is the PLC's reply.
'use strict';
(() => {
  const $ = (id) => document.getElementById(id);
  const WINDOW_MS = 60000;
  const MAX_EVENTS = 200;

  let plc = null;
  let source = null;
  let plcList = [];
  let view = fresh();
  let pendingAction = null;
  // The events that end each verb (`hello.endings`, from the protocol), and the command whose
  // outcome the page waits for: a reply only says the PLC accepted it.
  let endings = {};
  let awaiting = null;

  function fresh() {
    return { state: null, exec: null, io: [], firings: { A: {}, B: {} }, clock: null };
  }

  // ---- latency: MQTT message at the dashboard (recv_ms, Unix ms) -> DOM updated --------------
  // `dom` is measured right after the DOM change, `frame` at the next animation frame (when it is
  // painted), `publish` from the publisher's own `unix_ms` when the payload carries one.
  const latency = { dom: [], frame: [], publish: [] };
  window.cetratusLatency = latency;
  const nowMs = () => performance.timeOrigin + performance.now();
  function record(list, v) {
    if (Number.isFinite(v)) {
      list.push(v);
      if (list.length > 5000) list.shift();
    }
  }
  function measured(msg) {
    const t = nowMs();
    record(latency.dom, t - msg.recv_ms);
    const d = msg.data;
    if (d && typeof d === 'object' && typeof d.unix_ms === 'number') record(latency.publish, t - d.unix_ms);
    requestAnimationFrame(() => record(latency.frame, nowMs() - msg.recv_ms));
  }
  function quantile(xs, q) {
    if (!xs.length) return NaN;
    const s = xs.slice(-500).sort((a, b) => a - b);
    return s[Math.min(s.length - 1, Math.floor(q * s.length))];
  }
  setInterval(() => {
    const d = latency.dom;
    if (!d.length) return;
    $('latency').textContent =
      `median ${quantile(d, 0.5).toFixed(2)} ms, p95 ${quantile(d, 0.95).toFixed(2)} ms ` +
      `(to next frame: median ${quantile(latency.frame, 0.5).toFixed(1)} ms; ${d.length} messages)`;
  }, 1000);

  // ---- stream ---------------------------------------------------------------------------------
  function connect() {
    if (source) source.close();
    const url = '/api/stream' + (plc ? '?plc=' + encodeURIComponent(plc) : '');
    source = new EventSource(url);
    source.addEventListener('hello', (e) => onHello(JSON.parse(e.data)));
    source.addEventListener('plcs', (e) => setPlcs(JSON.parse(e.data)));
    source.addEventListener('broker', (e) => setBroker(JSON.parse(e.data)));
    for (const kind of ['state', 'exec_info', 'io', 'event', 'net']) {
      source.addEventListener(kind, (e) => onMessage(kind, JSON.parse(e.data)));
    }
    source.onerror = () => setBroker(null);
  }

  function onHello(h) {
    endings = h.endings || {};
    setBroker(h.broker);
    setPlcs(h.plcs);
    const s = h.snapshot;
    if (!s || s.plc !== plc) return;
    // A (re)connection: start from the snapshot, so nothing is drawn twice.
    view = fresh();
    $('events').textContent = '';
    if (s.state) renderState(s.state.data);
    if (s.net) renderNets(s.net.data);
    if (s.exec_info) { view.exec = s.exec_info.data; renderExec(); updateTokens(); }
    for (const x of s.io) addIo(x);
    renderTiming();
    for (const e of s.events) addEvent(e);
  }

  function onMessage(kind, msg) {
    if (msg.plc !== plc) return;
    switch (kind) {
      case 'state': renderState(msg.data); break;
      case 'net': renderNets(msg.data); updateTokens(); break;
      case 'exec_info': view.exec = msg.data; renderExec(); updateTokens(); break;
      case 'io': addIo(msg); renderTiming(); break;
      case 'event': addEvent(msg); settle(msg.data || {}); break;
    }
    measured(msg);
  }

  function setBroker(b) {
    const el = $('broker');
    if (!b) { el.textContent = 'dashboard: reconnecting…'; el.className = 'badge down'; return; }
    el.textContent = `broker ${b.url}: ${b.connected ? 'connected' : 'disconnected'}`;
    el.className = 'badge ' + (b.connected ? 'up' : 'down');
  }

  function setPlcs(list) {
    plcList = Array.isArray(list) ? list : [];
    const sel = $('plc-select');
    sel.textContent = '';
    for (const p of plcList) {
      const o = document.createElement('option');
      o.value = p.id;
      o.textContent = p.id + (p.online ? '' : ' (offline)');
      sel.appendChild(o);
    }
    if (plc === null && plcList.length) { choose(plcList[0].id); return; }
    if (plc !== null) sel.value = plc;
    const me = plcList.find((p) => p.id === plc);
    const badge = $('online');
    badge.textContent = me ? (me.online ? 'online' : 'offline') : (plc ? 'not seen' : 'no PLC yet');
    badge.className = 'badge ' + (me && me.online ? 'up' : 'down');
  }

  function choose(id) {
    plc = id;
    history.replaceState(null, '', '#plc=' + encodeURIComponent(id));
    view = fresh();
    $('primary').textContent = '?';
    $('status').textContent = '?';
    $('events').textContent = '';
    renderNets(null);
    renderTiming();
    connect();
    setPlcs(plcList);
  }

  $('plc-select').addEventListener('change', (e) => choose(e.target.value));

  // ---- state -----------------------------------------------------------------------------------
  function programText(p) {
    return p ? `${p.name} ${p.version} (${String(p.hash || '').slice(0, 12)})` : 'empty';
  }

  function renderState(s) {
    if (!s) return;
    view.state = Object.assign({}, view.state || {}, s);
    const st = view.state;
    const online = st.online !== false;
    const me = plcList.find((p) => p.id === plc);
    if (me) me.online = online;
    $('online').textContent = online ? 'online' : 'offline';
    $('online').className = 'badge ' + (online ? 'up' : 'down');
    if (st.primary) $('primary').textContent = st.primary;
    if (st.status) {
      $('status').textContent = st.status;
      $('status').dataset.status = st.status;
    }
    // A complete state: a fault it no longer carries is over.
    st.persist_fault = s.persist_fault;
    renderPersistFault(st.persist_fault);
    const progs = st.programs || {};
    $('program-A').textContent = programText(progs.A);
    $('program-B').textContent = programText(progs.B);
    const dl = $('cycle');
    dl.textContent = '';
    for (const [k, v] of Object.entries(st.cycle || {})) {
      if (v === null || v === undefined) continue;
      let text;
      if (typeof v === 'object' && 'mean_ns' in v) {
        // A timing summary (scan, cycle, latency as OpenPLC names them): the figures that matter.
        text = `mean ${us(v.mean_ns)}, p99 ${us(v.p99_ns)}, max ${us(v.max_ns)} µs`;
      } else if (typeof v === 'object') {
        text = flatten(v, '').map(([a, b]) => `${a} ${fmt(b)}`).join(', ');
      } else {
        text = fmt(v);
      }
      const dt = document.createElement('dt');
      dt.textContent = k;
      const dd = document.createElement('dd');
      dd.textContent = text;
      dl.append(dt, dd);
    }
    for (const x of ['A', 'B']) {
      const box = $('net-' + x);
      const role = st.primary === x ? 'primary' : (progs[x] ? 'candidate' : '');
      box.classList.toggle('primary', role === 'primary');
      box.classList.toggle('candidate', role === 'candidate');
      box.querySelector('.role').textContent = role ? `(${role})` : '';
    }
    enableButtons();
  }

  // The state directory cannot be written (docs/persistence.md, "When the disk fails").
  function renderPersistFault(f) {
    const box = $('persist-fault');
    box.hidden = !f;
    if (!f) return;
    const saved = f.saved_cycle === undefined ? 'the state saved before this run' : `cycle ${f.saved_cycle}`;
    box.textContent = `The state directory cannot be written since cycle ${f.since_cycle}: ${f.error}. ` +
      `The PLC runs on and tries again at every snapshot; a restart now would start from ${saved}.`;
  }

  function fmt(v) {
    return typeof v === 'number' && !Number.isInteger(v) ? v.toFixed(2) : String(v);
  }

  function flatten(o, prefix) {
    const out = [];
    for (const [k, v] of Object.entries(o)) {
      if (v && typeof v === 'object' && !Array.isArray(v)) out.push(...flatten(v, prefix + k + '.'));
      else out.push([prefix + k, v]);
    }
    return out;
  }

  function enableButtons() {
    const st = view.state || {};
    const up = plc !== null && st.online !== false;
    const s = st.status;
    $('load').disabled = !(up && s === 'idle');
    $('substitute').disabled = !(up && s === 'quarantine');
    $('remove').disabled = !(up && s === 'quarantine');
    $('abort').disabled = !(up && (s === 'setup' || s === 'quarantine'));
    $('reset').disabled = !(up && s === 'fault');
    $('accept').disabled = !(up && s === 'probation');
    $('revert').disabled = !(up && s === 'probation');
  }

  // ---- nets ------------------------------------------------------------------------------------
  // The drawing comes from the broker, which anyone on the cell network may publish to. It is
  // never put into the page: it is read (by an inert parser) as a list of shapes, and the page
  // draws those shapes itself, element by element, from an allow-list of SVG shapes and of
  // attributes whose values are checked (numbers, path data, class names, the ids the net's
  // export writes). No style, script, link, foreign content or event handler can get through,
  // because nothing that is not on the list is ever created (docs/dashboard.md).
  const SVGNS = 'http://www.w3.org/2000/svg';
  const NUM = /^-?(\d+\.?\d*|\.\d+)([eE][-+]?\d+)?(px|%)?$/;
  const NUMS = /^[-+0-9.eE ,]{0,20000}$/;
  const PATH = /^[MmLlHhVvCcSsQqTtAaZz0-9.eE ,+-]{0,20000}$/;
  const CLASS = /^[A-Za-z0-9 _-]{0,100}$/;
  const ID = /^(place|trans|arc|cetratus)-[A-Za-z0-9_.:-]{1,200}$/;
  const COLOUR = /^(#[0-9A-Fa-f]{3,8}|none|[a-z]{3,20})$/;
  const MARKER = /^url\(#cetratus-[A-Za-z0-9_-]{1,60}\)$/;
  const TEXT = /^[ -~]{0,200}$/;
  const check = (re) => (v) => re.test(v);
  const ATTRS = {
    x: check(NUM), y: check(NUM), cx: check(NUM), cy: check(NUM), r: check(NUM),
    rx: check(NUM), ry: check(NUM), x1: check(NUM), y1: check(NUM), x2: check(NUM), y2: check(NUM),
    width: check(NUM), height: check(NUM), 'stroke-width': check(NUM),
    refX: check(NUM), refY: check(NUM), markerWidth: check(NUM), markerHeight: check(NUM),
    viewBox: check(NUMS), points: check(NUMS), d: check(PATH),
    orient: (v) => v === 'auto' || NUM.test(v),
    class: check(CLASS), id: check(ID), fill: check(COLOUR), stroke: check(COLOUR),
    'marker-end': check(MARKER), 'marker-start': check(MARKER),
    'text-anchor': (v) => v === 'start' || v === 'middle' || v === 'end',
    'data-tokens': check(/^\d{1,10}$/), 'data-net': check(TEXT),
  };
  const SHAPES = new Set(['svg', 'g', 'defs', 'marker', 'path', 'circle', 'rect', 'ellipse', 'line',
    'polyline', 'polygon', 'text', 'tspan', 'title']);
  const HAS_TEXT = new Set(['text', 'tspan', 'title']);
  const MAX_SHAPES = 200000;

  function drawNet(text) {
    const doc = new DOMParser().parseFromString(text, 'image/svg+xml');
    const root = doc.documentElement;
    if (!root || root.namespaceURI !== SVGNS || root.localName !== 'svg' ||
        doc.getElementsByTagName('parsererror').length) return null;
    let budget = MAX_SHAPES;
    const copy = (from) => {
      const to = document.createElementNS(SVGNS, from.localName);
      for (const a of from.attributes) {
        const ok = a.namespaceURI === null && Object.prototype.hasOwnProperty.call(ATTRS, a.name);
        if (ok && ATTRS[a.name](a.value)) to.setAttribute(a.name, a.value);
      }
      for (const c of from.childNodes) {
        if (c.nodeType === Node.TEXT_NODE && HAS_TEXT.has(from.localName)) {
          to.appendChild(document.createTextNode(c.data));
        } else if (c.nodeType === Node.ELEMENT_NODE && c.namespaceURI === SVGNS &&
                   SHAPES.has(c.localName) && c.localName !== 'svg' && --budget > 0) {
          to.appendChild(copy(c));
        }
      }
      return to;
    };
    return copy(root);
  }

  function renderNets(n) {
    for (const x of ['A', 'B']) {
      const box = $('net-' + x).querySelector('.net');
      const text = n && typeof n[x] === 'string' ? n[x] : null;
      const svg = text ? drawNet(text) : null;
      box.textContent = svg ? '' : 'empty';
      if (svg) box.appendChild(svg);
    }
    view.firings = { A: {}, B: {} };
  }

  // Dice patterns of cetratus_net::export, so a redrawn place looks like a freshly exported one.
  const D = 6.5;
  const DICE = [[], [[0, 0]], [[-D, 0], [D, 0]], [[0, -D], [-D, D * 0.8], [D, D * 0.8]],
    [[-D, -D], [D, -D], [-D, D], [D, D]], [[-D, -D], [D, -D], [0, 0], [-D, D], [D, D]]];

  function drawTokens(g, n) {
    const c = g.querySelector('circle.node');
    if (!c) return;
    const cx = parseFloat(c.getAttribute('cx'));
    const cy = parseFloat(c.getAttribute('cy'));
    let tg = g.querySelector('.tokens');
    if (!tg) {
      tg = document.createElementNS(SVGNS, 'g');
      tg.setAttribute('class', 'tokens');
      c.after(tg);
    }
    tg.textContent = '';
    if (n <= 5) {
      for (const [dx, dy] of DICE[n]) {
        const dot = document.createElementNS(SVGNS, 'circle');
        dot.setAttribute('cx', cx + dx);
        dot.setAttribute('cy', cy + dy);
        dot.setAttribute('r', '3.5');
        tg.appendChild(dot);
      }
    } else {
      const t = document.createElementNS(SVGNS, 'text');
      t.setAttribute('class', 'count');
      t.setAttribute('x', cx);
      t.setAttribute('y', cy + 4);
      t.textContent = String(n);
      tg.appendChild(t);
    }
  }

  function updateTokens() {
    if (!view.exec) return;
    // exec_info is the protocol's pair: [A | null, B | null].
    for (const [i, x] of [[0, 'A'], [1, 'B']]) {
      const info = view.exec[i];
      const box = $('net-' + x);
      if (!info || !info.marking) continue;
      for (const [pid, n] of Object.entries(info.marking)) {
        const g = box.querySelector('#' + CSS.escape('place-' + pid));
        if (!g || g.getAttribute('data-tokens') === String(n)) continue;
        g.setAttribute('data-tokens', String(n));
        drawTokens(g, Math.max(0, Number(n) | 0));
      }
      // Flash the transitions that fired since the last exec_info.
      const prev = view.firings[x] || {};
      for (const [tid, count] of Object.entries(info.firings || {})) {
        if (prev[tid] !== undefined && count !== prev[tid]) {
          const t = box.querySelector('#' + CSS.escape('trans-' + tid));
          if (t) {
            t.classList.add('fired');
            setTimeout(() => t.classList.remove('fired'), 400);
          }
        }
      }
      view.firings[x] = Object.assign({}, info.firings || {});
    }
  }

  // ---- exec info table ---------------------------------------------------------------------
  const us = (ns) => (typeof ns === 'number' ? (ns / 1000).toFixed(1) : '–');

  function renderExec() {
    const e = view.exec || [];
    const a = e[0] || null;
    const b = e[1] || null;
    const rows = [];
    const row = (label, f, cls) => rows.push([label, a ? f(a) : '–', b ? f(b) : '–', cls]);
    row('role', (x) => x.role ?? '');
    row('program', (x) => programText(x.program));
    row('cycles', (x) => x.cycles, 'num');
    for (const k of ['last', 'min', 'mean', 'p50', 'p99', 'max']) {
      row(`scan ${k} (µs)`, (x) => us(x.scan && x.scan[k + '_ns']), 'num');
    }
    row('firings', (x) => Object.values(x.firings || {}).reduce((s, v) => s + (Number(v) || 0), 0), 'num');
    row('drift', (x) => x.drift, 'num');
    row('max drift', (x) => x.max_drift, 'num');
    row('deadlock', (x) => (x.deadlock ? 'yes' : 'no'));
    row('stall', (x) => (x.stall ? 'yes' : 'no'));
    // Field I/O: the quality of each device's inputs (docs/io.md, Quality), the same for both.
    const devices = new Set([...((a && a.input_quality) || []), ...((b && b.input_quality) || [])]
      .map((q) => q.device));
    for (const d of [...devices].sort()) {
      row(`input quality ${d}`, (x) => {
        const q = (x.input_quality || []).find((y) => y.device === d);
        return q ? `${q.quality} (link ${q.link}, ${q.missed_cycles} missed)` : '–';
      });
    }
    const signals = new Set([...Object.keys((a && a.divergence) || {}), ...Object.keys((b && b.divergence) || {})]);
    for (const s of [...signals].sort()) row(`divergence ${s} (cycles)`, (x) => (x.divergence || {})[s] ?? 0, 'num');
    row('first cause', (x) => x.first_cause ?? '–');
    row('last cause', (x) => x.last_cause ?? '–');
    row('declared changes', (x) => {
      const c = x.changes;
      if (!c) return '–';
      const parts = [];
      if ((c.outputs || []).length) parts.push(`outputs ${c.outputs.join(', ')}`);
      if (c.throughput_share != null) parts.push(`production may drop to ${Math.round(c.throughput_share * 100)} %`);
      return parts.join('; ');
    });
    row('quarantine coverage', (x) => x.coverage
      ? `${x.coverage.cycles} cycles; ${x.coverage.outputs_covered} of ${x.coverage.outputs_expected} outputs the twin showed diverging; ${x.coverage.unexplained} unexplained`
      : '–');
    // A verdict is {kind, result, reasons, figures} (docs/mqtt.md).
    row('verdicts', (x) => (x.verdicts || []).map((v) =>
      `${v.kind} ${v.result}${(v.reasons || []).length ? ': ' + v.reasons.join(', ') : ''}`).join('; ') || '–');

    const table = $('exec-info');
    table.textContent = '';
    const head = table.createTHead().insertRow();
    for (const h of ['', 'A', 'B']) {
      const th = document.createElement('th');
      th.textContent = h;
      head.appendChild(th);
    }
    const body = table.createTBody();
    for (const [label, va, vb, cls] of rows) {
      const tr = body.insertRow();
      const th = document.createElement('th');
      th.textContent = label;
      tr.appendChild(th);
      for (const v of [va, vb]) {
        const td = tr.insertCell();
        td.textContent = String(v);
        if (cls) td.className = cls;
        if (label.startsWith('divergence') && Number(v) > 0) td.classList.add('bad');
      }
    }
  }

  // ---- timing diagram (the paper's Fig. 7) -----------------------------------------------------
  const esc = (s) => String(s).replace(/[&<>"']/g, (c) => `&#${c.charCodeAt(0)};`);
  const high = (v) => v === true || v === 'true' || (typeof v === 'number' && v !== 0);
  const GROUPS = [
    ['inputs', 'inputs', (p) => p.inputs],
    ['A', 'outputs A', (p) => p.A],
    ['B', 'outputs B', (p) => p.B],
    ['dispatched', 'dispatched', (p) => p.d],
  ];

  // `io` comes in two shapes: the runtime's, with the Monitor's ring buffer since the last publish
  // (`samples`: [time_ms, primary, status, inputs, outputs A, outputs B, dispatched] as bit masks
  // over `names`), and the plain one of docs/mqtt.md (one sample: inputs, outputs {A, B},
  // dispatched). Both become points {t, inputs, A, B, d}; t is PLC time in ms when the message has
  // it, so the diagram shows the plant's timing whatever the network did.
  // A mask is a number while every set bit is below bit 53 (exact in a double), otherwise an
  // array of 32-bit words, the first signals' word first: any number of signals has a bit.
  function bits(v, names) {
    const o = {};
    if (typeof v === 'number') {
      names.forEach((n, i) => { o[n] = i < 53 && Math.floor(v / 2 ** i) % 2 === 1; });
    } else if (Array.isArray(v)) {
      names.forEach((n, i) => {
        const w = v[i >> 5];
        o[n] = typeof w === 'number' && ((w >>> (i & 31)) & 1) === 1;
      });
    } else {
      return null;
    }
    return o;
  }
  function points(d) {
    const names = d.names;
    if (Array.isArray(d.samples) && names && Array.isArray(names.inputs) && Array.isArray(names.outputs)) {
      return d.samples.filter((x) => Array.isArray(x) && typeof x[0] === 'number').map((x) => ({
        t: x[0], inputs: bits(x[3], names.inputs), A: bits(x[4], names.outputs),
        B: bits(x[5], names.outputs), d: bits(x[6], names.outputs),
      }));
    }
    const t = typeof d.time_ms === 'number' ? d.time_ms : typeof d.time_us === 'number' ? d.time_us / 1000 : null;
    const outs = d.outputs || {};
    return [{
      t, inputs: d.inputs, A: 'outputs_a' in d ? d.outputs_a : outs.A,
      B: 'outputs_b' in d ? d.outputs_b : outs.B, d: d.dispatched,
    }];
  }
  // Maps PLC time to the wall clock (speed = PLC ms per wall ms, smoothed), so the diagram keeps
  // scrolling between messages at the plant's pace.
  function addIo(msg) {
    const d = msg.data || {};
    let pts = points(d);
    const plcTime = pts.length && pts[pts.length - 1].t !== null;
    if (!plcTime) pts = pts.map((p) => Object.assign(p, { t: msg.recv_ms }));
    if (!pts.length) return;
    const last = pts[pts.length - 1].t;
    const c = view.clock;
    if (!c || c.plcTime !== plcTime || last < c.t) {
      view.io = [];
      view.clock = { plcTime, t: last, wall: msg.recv_ms, speed: plcTime ? null : 1 };
    } else {
      const dw = msg.recv_ms - c.wall;
      if (plcTime && dw > 20) {
        const inst = (last - c.t) / dw;
        c.speed = c.speed === null ? inst : 0.7 * c.speed + 0.3 * inst;
      }
      c.t = last;
      c.wall = msg.recv_ms;
    }
    for (const p of pts) view.io.push(p);
  }
  function axisNow() {
    const c = view.clock;
    if (!c) return nowMs();
    if (!c.plcTime) return nowMs();
    const ahead = Math.max(0, nowMs() - c.wall) * (c.speed || 0);
    // Never run more than two publish periods' worth ahead of the last sample.
    return c.t + Math.min(ahead, 2000 * Math.max(1, c.speed || 1));
  }

  function renderTiming() {
    const svg = $('timing');
    const now = axisNow();
    const t0 = now - WINDOW_MS;
    // Keep one sample from before the window: it gives the levels at the left edge.
    let first = 0;
    while (first + 1 < view.io.length && view.io[first + 1].t < t0) first++;
    if (first > 0) view.io.splice(0, first);
    const samples = view.io;

    const width = Math.max(400, svg.clientWidth || 900);
    const labelW = 130;
    const plotW = width - labelW - 10;
    const laneH = 15;
    const xOf = (t) => labelW + Math.max(0, (t - t0) / WINDOW_MS) * plotW;
    let y = 14;
    const out = [];
    // Grid: a line every 10 s, labelled in seconds before now.
    for (let k = 0; k <= 6; k++) {
      const x = xOf(now - k * 10000);
      out.push(`<line class="grid" x1="${x}" x2="${x}" y1="12" y2="100%"/>`);
      out.push(`<text class="tick" x="${x - 2}" y="10" text-anchor="end">${k ? '−' + k * 10 + ' s' : (view.clock && view.clock.plcTime ? 'PLC time' : 'now')}</text>`);
    }
    let signalCount = 0;
    for (const [key, title, get] of GROUPS) {
      const names = [];
      for (const s of samples) {
        const g = get(s);
        if (g && typeof g === 'object') for (const n of Object.keys(g)) if (!names.includes(n)) names.push(n);
      }
      y += 14;
      out.push(`<g class="g-${key}"><text class="group-label" x="4" y="${y - 2}">${esc(title)}</text>`);
      if (!names.length) {
        out.push(`<text class="lane-label" x="${labelW}" y="${y - 2}">(none)</text></g>`);
        continue;
      }
      for (const name of names) {
        signalCount++;
        const top = y + 2;
        const bottom = y + laneH - 2;
        out.push(`<text class="lane-label" x="10" y="${bottom}">${esc(name)}</text>`);
        out.push(`<line class="grid" x1="${labelW}" x2="${labelW + plotW}" y1="${bottom}" y2="${bottom}"/>`);
        let d = '';
        let open = false;
        let level = null;
        let shadeFrom = null;
        const shades = [];
        for (let i = 0; i < samples.length; i++) {
          const g = get(samples[i]);
          const x = xOf(samples[i].t);
          if (!g || !(name in g)) {
            if (open) d += ` H${x.toFixed(1)}`;
            open = false;
            continue;
          }
          const v = high(g[name]) ? top : bottom;
          // Only level changes make path segments: thousands of samples stay a short path.
          if (!open) { d += ` M${x.toFixed(1)},${v}`; level = v; }
          else if (v !== level) { d += ` H${x.toFixed(1)} V${v}`; level = v; }
          open = true;
          // Where the candidate's output differs from the primary's, shade its lane (Fig. 7).
          const ga = samples[i].A;
          const diff = key === 'B' && ga && name in ga && high(ga[name]) !== high(g[name]);
          if (diff && shadeFrom === null) shadeFrom = x;
          if (!diff && shadeFrom !== null) { shades.push([shadeFrom, x]); shadeFrom = null; }
        }
        if (open) d += ` H${xOf(now).toFixed(1)}`;
        if (shadeFrom !== null) shades.push([shadeFrom, xOf(now)]);
        for (const [a, b] of shades) {
          out.push(`<rect class="diverge" x="${a.toFixed(1)}" y="${y}" width="${Math.max(1, b - a).toFixed(1)}" height="${laneH}"/>`);
        }
        // data-level: the level at the right edge, for whoever reads the page (tests, tools).
        if (d) out.push(`<path class="sig" data-signal="${esc(name)}" data-level="${level === top ? 1 : 0}" d="${d.trim()}"/>`);
        y += laneH;
      }
      out.push('</g>');
    }
    svg.setAttribute('height', String(y + 8));
    svg.setAttribute('viewBox', `0 0 ${width} ${y + 8}`);
    svg.innerHTML = out.join('');
    svg.dataset.samples = String(samples.length);
    svg.dataset.signals = String(signalCount);
    const last = samples[samples.length - 1];
    svg.dataset.lastTime = last ? String(last.t) : '';
    svg.dataset.axis = view.clock && view.clock.plcTime ? 'plc' : 'wall';
  }
  // Scroll even when no sample arrives, so a silent PLC is visible as a flat, ageing trace.
  setInterval(renderTiming, 500);
  window.addEventListener('resize', renderTiming);

  // ---- events ----------------------------------------------------------------------------------
  function addEvent(msg) {
    const e = msg.data || {};
    const li = document.createElement('li');
    const time = document.createElement('span');
    time.className = 'time';
    time.textContent = new Date(msg.recv_ms).toLocaleTimeString() + (e.cycle !== undefined ? ` #${e.cycle}` : '');
    const kind = document.createElement('span');
    kind.className = 'kind';
    kind.textContent = e.kind || 'event';
    li.append(time, kind, document.createTextNode(' ' + (e.message || '')));
    if (e.detail) li.title = JSON.stringify(e.detail);
    li.dataset.kind = e.kind || '';
    const list = $('events');
    list.insertBefore(li, list.firstChild);
    while (list.children.length > MAX_EVENTS) list.lastChild.remove();
  }

  // ---- commands ---------------------------------------------------------------------------------
  function ask(text, action) {
    $('confirm-text').textContent = text;
    pendingAction = action;
    $('confirm').hidden = false;
    $('confirm-yes').focus();
  }
  // The fleet page (fleet.js) asks through the same dialog.
  window.cetratusAsk = ask;
  function closeDialog() {
    $('confirm').hidden = true;
    pendingAction = null;
  }
  $('confirm-yes').addEventListener('click', () => {
    const a = pendingAction;
    closeDialog();
    if (a) a();
  });
  $('confirm-no').addEventListener('click', () => { closeDialog(); showReply('cancelled', null); });
  document.addEventListener('keydown', (e) => { if (e.key === 'Escape' && !$('confirm').hidden) closeDialog(); });

  function showReply(text, ok) {
    const r = $('reply');
    r.textContent = text;
    r.className = ok === true ? 'ok' : ok === false ? 'err' : '';
    r.dataset.ok = ok === null ? '' : String(ok);
  }

  // Shows how the awaited command ended, once its reply and an event that ends it are both in
  // (the event may come first).
  function settle(e) {
    const a = awaiting;
    if (!a || a.plc !== plc) return;
    const how = (endings[a.verb] || {})[e.kind];
    if (how && !a.event) a.event = Object.assign({ how }, e);
    if (!a.replied || !a.event) return;
    awaiting = null;
    const done = a.event.how === 'done';
    const what = `${a.event.kind}: ${a.event.message || ''}`;
    showReply(done ? `${a.verb}: ${what}` : `${a.verb} failed: ${what}`, done);
  }

  async function send(verb, body, contentType) {
    const target = plc;
    const follow = Object.keys(endings[verb] || {}).length > 0;
    awaiting = follow ? { verb, plc: target, replied: false, event: null } : null;
    showReply(`${verb}: sent to ${target}, waiting for the reply…`, null);
    try {
      const r = await fetch(`/api/${encodeURIComponent(target)}/${verb}`, {
        method: 'POST', headers: { 'Content-Type': contentType }, body,
      });
      const j = await r.json();
      if (!j.ok) {
        if (awaiting && awaiting.verb === verb) awaiting = null;
        showReply(`${verb} refused: ` + (j.error ? `${j.error.code}: ${j.error.message}` : `HTTP ${r.status}`), false);
      } else if (follow && awaiting && awaiting.verb === verb) {
        awaiting.replied = true;
        showReply(`${verb}: accepted, waiting for its outcome…`, null);
        settle({});
      } else {
        showReply(`${verb}: ok` + (j.result !== undefined ? ' ' + JSON.stringify(j.result) : ''), true);
      }
    } catch (err) {
      awaiting = null;
      showReply(`${verb} failed: ${err}`, false);
    }
  }

  $('load').addEventListener('click', () => {
    const f = $('package-file').files[0];
    if (!f) { showReply('choose an update package file (.cpkg) first', false); return; }
    ask(`Load ${f.name} (${f.size} bytes) on ${plc}? The new program runs in quarantine beside ` +
      `PRIMARY, with its outputs withheld.`, () => send('load', f, 'application/octet-stream'));
  });
  $('substitute').addEventListener('click', () => {
    const mode = $('substitute-mode').value;
    ask(`Substitute on ${plc} (mode ${mode})? The candidate becomes PRIMARY and drives the ` +
      `outputs; the old program stays as a shadow for the probation window, if one is configured.`,
      () => send('substitute', JSON.stringify({ mode }), 'application/json'));
  });
  $('accept').addEventListener('click', () => ask(`Accept the update on ${plc}? Probation ends and ` +
    `the old program stops: it can no longer take over.`, () => send('accept', '{}', 'application/json')));
  $('revert').addEventListener('click', () => ask(`Revert ${plc} to the old program? It drives the ` +
    `outputs again at the next cycle.`, () => send('revert', '{}', 'application/json')));
  $('remove').addEventListener('click', () => ask(`Remove the candidate from ${plc}? PRIMARY keeps running.`,
    () => send('remove', '{}', 'application/json')));
  $('abort').addEventListener('click', () => ask(`Abort the update under way on ${plc}?`,
    () => send('abort', '{}', 'application/json')));
  $('reset').addEventListener('click', () => ask(`Reset ${plc} out of the fault state? Outputs leave their safe values.`,
    () => send('reset', '{}', 'application/json')));

  // ---- start -----------------------------------------------------------------------------------
  const m = /^#plc=(.+)$/.exec(location.hash);
  if (m) plc = decodeURIComponent(m[1]);
  enableButtons();
  renderTiming();
  connect();
})();
