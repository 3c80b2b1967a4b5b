// The approval panel (docs/mcp.md, "Approve from the web UI"): the calls held by an action's
// approval=True guardrail, listed live with their time left, each settled by Approve or Deny through
// the components' approvals service. Uses app.js's helpers (api, postJSON, el, toast, $).
"use strict";

const APPROVAL_POLL_MS = 1000;
const heldCalls = new Map();   // id -> { call, deadline (ms, this page's clock) }

function approvalCard(call) {
  const args = el("pre", { class: "arguments" }, JSON.stringify(call.arguments, null, 1));
  const card = el("div", { class: "approval", "data-id": call.id, "data-component": call.component,
                           "data-action": call.action },
    el("div", { class: "what" }, `${call.component}.${call.action}`),
    args,
    el("div", { class: "who" }, `asked by ${call.caller}`),
    el("div", {}, "time left ", el("span", { class: "left" }, "")),
    el("button", { "data-decide": "approve", onclick: () => decideApproval(call.id, true) }, "Approve"),
    el("button", { "data-decide": "deny", onclick: () => decideApproval(call.id, false) }, "Deny"));
  return card;
}

async function decideApproval(id, approve) {
  const card = document.querySelector(`.approval[data-id="${CSS.escape(id)}"]`);
  if (card) card.querySelectorAll("button").forEach(b => { b.disabled = true; });
  try {
    const r = await postJSON(`/api/approvals/${encodeURIComponent(id)}`, { approve });
    toast(`${approve ? "approved" : "denied"} ${id}`);
    if (card) card.dataset.decided = r.approved ? "approved" : "denied";
  } catch (e) { toast(e.message); if (card) card.querySelectorAll("button").forEach(b => { b.disabled = false; }); }
  pollApprovals();
}

function renderApprovals() {
  const list = $("#approvals");
  for (const card of [...list.children]) if (!heldCalls.has(card.dataset.id)) card.remove();
  for (const [id, held] of heldCalls) {
    let card = list.querySelector(`.approval[data-id="${CSS.escape(id)}"]`);
    if (!card) { card = approvalCard(held.call); list.append(card); }
    const left = Math.max(0, (held.deadline - Date.now()) / 1000);
    $(".left", card).textContent = `${left.toFixed(0)} s`;
  }
  $("#approvals-panel").hidden = heldCalls.size === 0;
  document.body.dataset.approvals = String(heldCalls.size);
}

let approvalsInFlight = false;   // one poll at a time: a slow answer never piles requests up

async function pollApprovals() {
  if ($("#main").hidden || approvalsInFlight) return;   // not signed in yet, or still waiting
  let reply;
  approvalsInFlight = true;
  try { reply = await api("/api/approvals"); } catch (e) { return; } finally { approvalsInFlight = false; }
  const now = Date.now(), seen = new Set();
  for (const call of reply.pending || []) {
    seen.add(call.id);
    heldCalls.set(call.id, { call, deadline: now + 1000 * Number(call.expires_in_s || 0) });
  }
  for (const id of [...heldCalls.keys()]) if (!seen.has(id)) heldCalls.delete(id);
  renderApprovals();
}

setInterval(pollApprovals, APPROVAL_POLL_MS);
setInterval(renderApprovals, 250);   // the countdown between polls
