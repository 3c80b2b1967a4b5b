// The agents_core UI page: plain JavaScript over the JSON / WebSocket API (see docs/ui.md).
"use strict";

const $ = (sel, root = document) => root.querySelector(sel);
const el = (tag, attrs = {}, ...children) => {
  const node = document.createElement(tag);
  for (const [k, v] of Object.entries(attrs)) {
    if (k === "class") node.className = v; else if (k.startsWith("on")) node.addEventListener(k.slice(2), v);
    else node.setAttribute(k, v);
  }
  for (const c of children) node.append(c);
  return node;
};
const BOX_COLOURS = ["#ff1744", "#00e676", "#2979ff", "#ffea00", "#d500f9", "#00e5ff"];
const streaming = {};   // topic -> the chat bubble being written
let socket = null;

function toast(text) {
  const t = $("#toast"); t.textContent = text; t.classList.add("show");
  clearTimeout(toast.timer); toast.timer = setTimeout(() => t.classList.remove("show"), 4000);
}

async function api(path, options = {}) {
  const response = await fetch(path, { credentials: "same-origin", ...options });
  let body = null;
  try { body = await response.json(); } catch (e) { body = { error: response.statusText }; }
  if (!response.ok) { const err = new Error(body.error || response.statusText); err.status = response.status; throw err; }
  return body;
}
const postJSON = (path, doc) => api(path, { method: "POST", headers: { "Content-Type": "application/json" },
                                            body: JSON.stringify(doc) });

// -- chat -------------------------------------------------------------------------------------
function bubble(kind, text, topic) {
  const b = el("div", { class: `msg ${kind}`, "data-topic": topic || "" });
  if (topic) b.append(el("span", { class: "topic" }, topic));
  const body = el("span", { class: "text" }, text);
  b.append(body);
  $("#chat").append(b); $("#chat").scrollTop = $("#chat").scrollHeight;
  return b;
}

function onText(frame) { bubble("agent", frame.text, frame.topic); }

function onStream(frame) {
  let b = streaming[frame.topic];
  if (!b) { b = streaming[frame.topic] = bubble("agent streaming", "", frame.topic); b.dataset.chunks = "0"; }
  $(".text", b).textContent += frame.text;
  b.dataset.chunks = String(Number(b.dataset.chunks) + 1);
  $("#chat").scrollTop = $("#chat").scrollHeight;
  if (frame.done) { b.classList.remove("streaming"); b.dataset.done = "true"; delete streaming[frame.topic]; }
}

// -- output panels ----------------------------------------------------------------------------
function panel(topic, msgType) {
  let p = document.querySelector(`.panel[data-topic="${CSS.escape(topic)}"]`);
  if (!p) {
    p = el("div", { class: "panel", "data-topic": topic }, el("h3", {}, `${topic} (${msgType})`));
    $("#panels").append(p);
  }
  return p;
}

function loadImage(image) {
  return new Promise((resolve, reject) => {
    const img = new Image();
    img.onload = () => resolve(img); img.onerror = reject;
    img.src = `data:${image.mime};base64,${image.data}`;
  });
}

function onImage(frame) {
  const p = panel(frame.topic, frame.msg_type);
  let img = $("img", p);
  if (!img) { img = el("img", { alt: frame.topic }); p.append(img); }
  img.src = `data:${frame.mime};base64,${frame.data}`;
  p.dataset.frames = String(Number(p.dataset.frames || 0) + 1);
}

async function onDetections(frame) {
  const p = panel(frame.topic, frame.msg_type);
  let canvas = $("canvas", p), list = $("ul", p);
  if (!canvas) { canvas = el("canvas", { "data-topic": frame.topic }); list = el("ul"); p.append(canvas, list); }
  const ctx = canvas.getContext("2d");
  if (frame.image) {
    const img = await loadImage(frame.image);
    // width / height are the image's own (boxes are in its pixels), even when it was sent downscaled
    canvas.width = frame.image.width || img.naturalWidth; canvas.height = frame.image.height || img.naturalHeight;
    ctx.drawImage(img, 0, 0, canvas.width, canvas.height);
  } else if (!canvas.width) { canvas.width = 640; canvas.height = 480; }
  ctx.lineWidth = Math.max(2, canvas.width / 200);
  ctx.font = `${Math.max(12, canvas.width / 40)}px sans-serif`;
  list.replaceChildren();
  frame.boxes.forEach((box, i) => {
    const colour = BOX_COLOURS[i % BOX_COLOURS.length];
    const [x1, y1, x2, y2] = box;
    ctx.strokeStyle = colour; ctx.strokeRect(x1, y1, x2 - x1, y2 - y1);
    const label = `${frame.ids ? "#" + frame.ids[i] + " " : ""}${frame.labels[i] || ""} ${frame.scores[i] !== undefined ? frame.scores[i].toFixed(2) : ""}`;
    ctx.fillStyle = colour; ctx.fillText(label, x1 + 3, Math.max(y1 - 4, 12));
    list.append(el("li", { class: "detection" }, label));
  });
  canvas.dataset.boxes = String(frame.boxes.length);
  canvas.dataset.boxList = JSON.stringify(frame.boxes);
  p.dataset.frames = String(Number(p.dataset.frames || 0) + 1);
}

function onAudio(frame) {
  const p = panel(frame.topic, frame.msg_type);
  const audio = el("audio", { controls: "", src: `data:${frame.mime};base64,${frame.data}` });
  const old = $("audio", p); if (old) old.replaceWith(audio); else p.append(audio);
  audio.play().catch(() => {});  // autoplay may be refused until the user clicks somewhere
}

function onValue(frame) {
  const p = panel(frame.topic, frame.msg_type);
  let pre = $("pre", p); if (!pre) { pre = el("pre"); p.append(pre); }
  pre.textContent = JSON.stringify(frame.value, null, 1);
}

function onError(frame) {
  const p = panel(frame.topic, frame.msg_type);
  let note = $(".error", p); if (!note) { note = el("div", { class: "error" }); p.append(note); }
  note.textContent = frame.message;
}

function onStatus(frame) {
  const card = document.querySelector(`.component[data-name="${CSS.escape(frame.component)}"]`);
  if (!card) return;
  const state = $(".state", card), health = $(".health", card);
  state.textContent = frame.state; state.className = `state ${frame.state}`;
  health.textContent = frame.health; health.className = `health ${frame.health}`;
  card.dataset.state = frame.state;
}

const HANDLERS = { text: onText, stream: onStream, image: onImage, detections: onDetections, audio: onAudio,
                   status: onStatus, value: onValue, error: onError };

// -- binary image frames (docs/ui.md, "Binary frames") -----------------------------------------
// Latest-wins per topic: a frame that arrives while the previous one of its topic waits to be drawn
// replaces it, and drawing happens once per display refresh, so a camera faster than the screen
// costs skipped frames, never a growing backlog.
const HEADER_BYTES = 24, MIMES = { 1: "image/jpeg", 2: "image/png" };
const outputNames = {};   // topic_id -> output topic name (from /api/interfaces)
const pendingImages = new Map();   // topic_id -> the newest frame not drawn yet
const decoding = new Set();        // topic_ids with a decode in flight
window.uiStats = { received: 0, drawn: 0, skipped: 0, bad: 0 };
let drawScheduled = false;

function onBinary(buffer) {
  if (buffer.byteLength < HEADER_BYTES) { window.uiStats.bad++; return; }
  const v = new DataView(buffer);
  const frame = { version: v.getUint8(0), encoding: v.getUint8(1), topicId: v.getUint16(2, true),
                  width: v.getUint32(4, true), height: v.getUint32(8, true), size: v.getUint32(12, true) };
  if (frame.version !== 1 || frame.size !== buffer.byteLength - HEADER_BYTES || !(frame.topicId in outputNames)) {
    window.uiStats.bad++; return;
  }
  frame.payload = new Uint8Array(buffer, HEADER_BYTES);
  window.uiStats.received++;
  if (pendingImages.has(frame.topicId)) window.uiStats.skipped++;
  pendingImages.set(frame.topicId, frame);
  if (!drawScheduled) { drawScheduled = true; requestAnimationFrame(drawPending); }
}

function imageCanvas(topic) {
  const p = panel(topic, "Image");
  let canvas = $("canvas.image", p);
  if (!canvas) { canvas = el("canvas", { class: "image", "data-topic": topic }); p.append(canvas); }
  return [p, canvas];
}

async function drawFrame(frame) {
  const [p, canvas] = imageCanvas(outputNames[frame.topicId]);
  const ctx = canvas.getContext("2d");
  if (frame.encoding === 3) {   // raw rgb8 -> RGBA
    const n = frame.width * frame.height;
    if (!n || frame.payload.length !== n * 3) { window.uiStats.bad++; return; }
    const rgba = new Uint8ClampedArray(n * 4), rgb = frame.payload;
    for (let i = 0, j = 0; i < n * 3; i += 3, j += 4) { rgba[j] = rgb[i]; rgba[j + 1] = rgb[i + 1]; rgba[j + 2] = rgb[i + 2]; rgba[j + 3] = 255; }
    if (canvas.width !== frame.width || canvas.height !== frame.height) { canvas.width = frame.width; canvas.height = frame.height; }
    ctx.putImageData(new ImageData(rgba, frame.width, frame.height), 0, 0);
  } else if (MIMES[frame.encoding]) {
    const bitmap = await createImageBitmap(new Blob([frame.payload], { type: MIMES[frame.encoding] }));
    // width / height are the image's own (it may have been sent downscaled)
    const w = frame.width || bitmap.width, h = frame.height || bitmap.height;
    if (canvas.width !== w || canvas.height !== h) { canvas.width = w; canvas.height = h; }
    ctx.drawImage(bitmap, 0, 0, w, h);
    bitmap.close();
  } else { window.uiStats.bad++; return; }
  window.uiStats.drawn++;
  p.dataset.frames = String(Number(p.dataset.frames || 0) + 1);
}

function drawPending() {
  drawScheduled = false;
  for (const [topicId, frame] of [...pendingImages]) {
    if (decoding.has(topicId)) continue;   // the next refresh takes the newest
    pendingImages.delete(topicId);
    decoding.add(topicId);
    drawFrame(frame).catch(() => { window.uiStats.bad++; }).finally(() => {
      decoding.delete(topicId);
      if (pendingImages.size && !drawScheduled) { drawScheduled = true; requestAnimationFrame(drawPending); }
    });
  }
}

// -- components -------------------------------------------------------------------------------
async function transition(name, which) {
  try { const r = await postJSON(`/api/components/${name}/transition`, { transition: which }); toast(`${name}: ${r.state}`); }
  catch (e) { toast(e.message); }
}

// The action's parameters come from its JSON Schema (agents_core.action_schema): one question per
// parameter, its type, description and default shown; the answers are sent by name.
function parseParameter(text, schema) {
  const kinds = [].concat(schema.type || []);
  if (text === "" && "default" in schema) return { value: schema.default };
  if (kinds.includes("integer") || kinds.includes("number")) {
    const n = Number(text);
    if (text.trim() === "" || Number.isNaN(n)) return { error: "a number" };
    if (kinds.includes("integer") && !kinds.includes("number") && !Number.isInteger(n)) return { error: "an integer" };
    return { value: n };
  }
  if (kinds.includes("boolean")) {
    if (["true", "yes", "1"].includes(text.trim().toLowerCase())) return { value: true };
    if (["false", "no", "0"].includes(text.trim().toLowerCase())) return { value: false };
    return { error: "true or false" };
  }
  if (kinds.includes("array") || kinds.includes("object")) {
    try { return { value: JSON.parse(text) }; } catch (e) { return { error: "JSON" }; }
  }
  if (kinds.length === 0) { try { return { value: JSON.parse(text) }; } catch (e) { return { value: text }; } }
  return { value: text };
}

async function runAction(name, action, description) {
  const schema = description.parameters || description.function?.parameters || {};
  const params = schema.properties || {};
  const required = schema.required || [];
  const kwargs = {};
  for (const [param, spec] of Object.entries(params)) {
    const kind = [].concat(spec.type || "any").join(" | ");
    const about = spec.description ? ` — ${spec.description}` : "";
    const optional = required.includes(param) ? "" : " (optional)";
    const shown = "default" in spec ? JSON.stringify(spec.default) : "";
    const answer = prompt(`${action}: ${param} (${kind})${optional}${about}`, shown === '""' ? "" : shown);
    if (answer === null) return;
    if (answer === "" && !required.includes(param)) continue;
    const parsed = parseParameter(answer, spec);
    if ("error" in parsed) { toast(`${action}: ${param} must be ${parsed.error}`); return; }
    kwargs[param] = parsed.value;
  }
  try { const r = await postJSON(`/api/components/${name}/actions/${action}`, { kwargs });
        toast(`${name}.${action} → ${JSON.stringify(r.result)}`); }
  catch (e) { toast(e.message); }
}

function componentCard(c) {
  const card = el("div", { class: "component", "data-name": c.name, "data-state": c.state || "" },
    el("div", {}, el("span", { class: "name" }, c.name), " ", el("span", { class: "type" }, c.component_type || "")),
    el("div", {}, "state ", el("span", { class: `state ${c.state}` }, c.state || "?"),
       " · health ", el("span", { class: `health ${c.health}` }, c.health || "?")));
  if (c.error) card.append(el("div", { class: "error" }, c.error));
  const io = (c.inputs || []).map(t => `← ${t.name}: ${t.msg_type}`).concat((c.outputs || []).map(t => `→ ${t.name}: ${t.msg_type}`));
  card.append(el("div", { class: "type" }, io.join("\n")));
  const buttons = el("div");
  for (const t of ["configure", "activate", "deactivate", "cleanup"]) {
    buttons.append(el("button", { "data-transition": t, onclick: () => transition(c.name, t) }, t));
  }
  for (const [action, description] of Object.entries(c.actions || {})) {
    const text = (description.description || description.function?.description || action);
    buttons.append(el("button", { class: "action", "data-action": action, title: text,
                                  onclick: () => runAction(c.name, action, description) }, action));
  }
  card.append(buttons);
  return card;
}

// -- inputs -----------------------------------------------------------------------------------
async function sendValue(topic, value) {
  try { await postJSON(`/api/inputs/${topic}`, { value }); } catch (e) { toast(e.message); }
}

async function sendFile(topic, blob, filename) {
  const form = new FormData(); form.append("file", blob, filename);
  try { await api(`/api/inputs/${topic}`, { method: "POST", body: form }); toast(`sent ${filename} to ${topic}`); }
  catch (e) { toast(e.message); }
}

function wav16(samples, rate) {   // Float32 mono samples -> a 16-bit PCM WAV blob
  const view = new DataView(new ArrayBuffer(44 + samples.length * 2));
  const text = (o, s) => [...s].forEach((ch, i) => view.setUint8(o + i, ch.charCodeAt(0)));
  text(0, "RIFF"); view.setUint32(4, 36 + samples.length * 2, true); text(8, "WAVEfmt ");
  view.setUint32(16, 16, true); view.setUint16(20, 1, true); view.setUint16(22, 1, true);
  view.setUint32(24, rate, true); view.setUint32(28, rate * 2, true); view.setUint16(32, 2, true);
  view.setUint16(34, 16, true); text(36, "data"); view.setUint32(40, samples.length * 2, true);
  samples.forEach((s, i) => view.setInt16(44 + i * 2, Math.max(-1, Math.min(1, s)) * 32767, true));
  return new Blob([view], { type: "audio/wav" });
}

function recorder(topic) {
  let stream = null, context = null, node = null, chunks = [];
  const button = el("button", { "data-record": topic }, "● record");
  button.onclick = async () => {
    if (!stream) {
      try { stream = await navigator.mediaDevices.getUserMedia({ audio: true }); }
      catch (e) { toast(`no microphone: ${e.message}`); return; }
      context = new AudioContext(); chunks = [];
      const source = context.createMediaStreamSource(stream);
      node = context.createScriptProcessor(4096, 1, 1);
      node.onaudioprocess = (ev) => chunks.push(new Float32Array(ev.inputBuffer.getChannelData(0)));
      source.connect(node); node.connect(context.destination);
      button.textContent = "■ stop";
    } else {
      node.disconnect(); stream.getTracks().forEach(t => t.stop());
      const all = new Float32Array(chunks.reduce((n, c) => n + c.length, 0));
      let at = 0; for (const c of chunks) { all.set(c, at); at += c.length; }
      const rate = context.sampleRate; await context.close(); stream = null;
      button.textContent = "● record";
      await sendFile(topic, wav16(all, rate), "recording.wav");
    }
  };
  return button;
}

function inputControl(t) {
  const row = el("div", { class: "input", "data-topic": t.name }, el("label", {}, `${t.name}`));
  if (t.widget === "text") {
    const box = el("input", { type: "text", "data-topic": t.name, placeholder: `${t.msg_type} on ${t.name}` });
    const send = () => { if (!box.value) return; bubble("user", box.value, t.name); sendValue(t.name, box.value); box.value = ""; };
    box.addEventListener("keydown", (ev) => { if (ev.key === "Enter") send(); });
    row.append(box, el("button", { onclick: send }, "Send"));
  } else if (t.widget === "image" || t.widget === "audio") {
    const file = el("input", { type: "file", "data-topic": t.name,
                               accept: t.widget === "image" ? "image/png,image/jpeg" : "audio/wav,.wav" });
    file.addEventListener("change", () => { if (file.files[0]) sendFile(t.name, file.files[0], file.files[0].name); });
    row.append(file);
    if (t.widget === "audio") row.append(recorder(t.name));
  } else {
    const box = el("input", { type: "text", "data-topic": t.name, placeholder: t.widget === "bool" ? "true / false" : `${t.msg_type} (JSON)` });
    const send = () => { let v; try { v = JSON.parse(box.value); } catch (e) { toast("not JSON"); return; } sendValue(t.name, v); };
    row.append(box, el("button", { onclick: send }, "Publish"));
  }
  return row;
}

// -- start ------------------------------------------------------------------------------------
function connect() {
  const scheme = location.protocol === "https:" ? "wss" : "ws";
  socket = new WebSocket(`${scheme}://${location.host}/api/outputs?frames=binary`);
  socket.binaryType = "arraybuffer";
  socket.onopen = () => { $("#connection").textContent = "live"; $("#connection").className = "badge ok"; };
  socket.onmessage = (ev) => {
    if (typeof ev.data !== "string") { onBinary(ev.data); return; }
    const frame = JSON.parse(ev.data); const h = HANDLERS[frame.kind]; if (h) h(frame);
  };
  socket.onclose = (ev) => {
    $("#connection").textContent = `disconnected (${ev.code})`; $("#connection").className = "badge bad";
    setTimeout(connect, 2000);
  };
}

async function start() {
  try { await api("/api/health"); }
  catch (e) { if (e.status === 401) { $("#login").hidden = false; return; } toast(e.message); return; }
  $("#login").hidden = true;
  const info = await api("/api/interfaces");
  $("#transport").textContent = `transport: ${info.transport}`;
  $("#components").replaceChildren(...info.components.map(componentCard));
  $("#inputs").replaceChildren(...info.inputs.map(inputControl));
  for (const o of info.outputs) outputNames[o.id] = o.name;
  $("#main").hidden = false;
  document.body.dataset.ready = "true";
  connect();
}

$("#login-form").addEventListener("submit", async (ev) => {
  ev.preventDefault();
  try { await postJSON("/api/login", { token: $("#token").value }); $("#token").value = ""; start(); }
  catch (e) { $("#login-error").textContent = e.message; }
});
start();
