// The top page: every component's status figures, live, over the UI's WebSocket (docs/observability.md).
"use strict";
const HISTORY = 60;  // points per plot (one status a second: a minute)
const rows = new Map();  // component -> {frame, rate: [], p99: []}
let sortKey = "component";

function cell(text) { const td = document.createElement("td"); td.textContent = text; return td; }

function spark(values) {
  const svgNS = "http://www.w3.org/2000/svg";
  const svg = document.createElementNS(svgNS, "svg");
  svg.setAttribute("viewBox", `0 0 ${HISTORY} 24`);
  svg.setAttribute("preserveAspectRatio", "none");
  const top = Math.max(...values, 1e-9);
  const line = document.createElementNS(svgNS, "polyline");
  line.setAttribute("points", values.map((v, i) => `${i + HISTORY - values.length},${(23 - 22 * v / top).toFixed(1)}`).join(" "));
  svg.append(line);
  return svg;
}

function shown(value) {
  if (value === undefined || value === null) return "-";
  if (typeof value !== "number" || Number.isInteger(value)) return String(value);
  return Math.abs(value) >= 10 ? value.toFixed(1) : value.toFixed(2);
}

function render() {
  const body = document.querySelector("#top tbody");
  const entries = [...rows.values()];
  entries.sort((a, b) => {
    const x = a.frame[sortKey] ?? a.frame.stats?.[sortKey], y = b.frame[sortKey] ?? b.frame.stats?.[sortKey];
    if (sortKey === "component") return String(x).localeCompare(String(y));
    return (y ?? -Infinity) - (x ?? -Infinity);
  });
  body.replaceChildren(...entries.map(({ frame, rate, p99 }) => {
    const s = frame.stats || {};
    const tr = document.createElement("tr");
    tr.dataset.component = frame.component;
    tr.append(cell(frame.component), cell(frame.state), cell(frame.health), cell(shown(s.rate_hz)));
    const rateCell = document.createElement("td"); rateCell.append(spark(rate)); tr.append(rateCell);
    tr.append(cell(shown(s.p50_ms)), cell(shown(s.p99_ms)));
    const p99Cell = document.createElement("td"); p99Cell.append(spark(p99)); tr.append(p99Cell);
    for (const key of ["model_ms", "drops", "restarts", "cpu_pct", "rss_mb", "pid"]) tr.append(cell(shown(s[key])));
    return tr;
  }));
  for (const th of document.querySelectorAll("#top th[data-key]")) th.classList.toggle("sorted", th.dataset.key === sortKey);
}

function onStatus(frame) {
  const row = rows.get(frame.component) || { rate: [], p99: [] };
  row.frame = frame;
  const s = frame.stats || {};
  if (typeof s.rate_hz === "number") { row.rate.push(s.rate_hz); if (row.rate.length > HISTORY) row.rate.shift(); }
  if (typeof s.p99_ms === "number") { row.p99.push(s.p99_ms); if (row.p99.length > HISTORY) row.p99.shift(); }
  rows.set(frame.component, row);
}

function connect() {
  const scheme = location.protocol === "https:" ? "wss" : "ws";
  const socket = new WebSocket(`${scheme}://${location.host}/api/outputs`);
  const badge = document.querySelector("#connection");
  socket.onopen = () => { badge.textContent = "live"; badge.className = "badge ok"; };
  socket.onmessage = (ev) => {
    if (typeof ev.data !== "string") return;
    const frame = JSON.parse(ev.data);
    if (frame.kind === "status") onStatus(frame);
  };
  socket.onclose = (ev) => {
    badge.textContent = ev.code === 1008 ? "sign in on the recipe page first" : `disconnected (${ev.code})`;
    badge.className = "badge bad";
    setTimeout(connect, 2000);
  };
}

for (const th of document.querySelectorAll("#top th[data-key]")) th.onclick = () => { sortKey = th.dataset.key; render(); };
setInterval(render, 1000);
connect();
