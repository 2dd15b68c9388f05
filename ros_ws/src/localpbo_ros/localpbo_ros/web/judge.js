// The judge's page: takes the state the judge pushes (server-sent events on api/events; a
// slow poll of api/state only if the stream cannot be opened), shows the current duel,
// replays the two episodes in sync (slowed down when short, looped, at a chosen speed), and
// posts answers to api/answer and undos to api/undo. No framework, no network access
// beyond this server.
"use strict";

const $ = (id) => document.getElementById(id);
const params = new URLSearchParams(window.location.search);
const POLL_MS = Math.max(200, Number(params.get("refresh")) || 1000); // fallback only
const SETTLE_MS = 250; // an answer this soon after the previous one is a double press: refused
const MIN_SCREEN_S = 1.5; // a shorter episode is slowed down to last this long on screen
const LOOP_PAUSE_S = 0.8; // the last frame stays this long before the loop starts again
const SPEEDS = [0.25, 0.5, 1, 2, 4];
const COLORS = { a: "#1f6fb2", b: "#c0561b" };
const store = (() => { try { return window.localStorage; } catch (e) { return null; } })();

let state = null;
let shownKey = "";
let lastAnswerAt = -1e9; // when the previous answer (key or click) was sent
let inFlight = false;
let stream = null;
let streamOpen = false;
let pollTimer = null;
let review = null; // { duel_id, a, b, answer }: a past duel replayed from the history
const answeredIds = new Set(); // duels this page answered: never offered again unless undone
// visible time of the current duel (Page Visibility API): counted only while the page shows
const watch = { key: "", visibleMs: 0, since: null, hidden: false };
const replay = { a: null, b: null, start: performance.now(), offset: 0, playing: true };
let speed = Number(store && store.getItem("localpbo.speed")) || 1;
if (!SPEEDS.includes(speed)) speed = 1;

function fmt(v) {
  if (v === null || v === undefined) return "–";
  const a = Math.abs(v);
  if (a !== 0 && (a < 1e-3 || a >= 1e5)) return v.toExponential(3);
  return v.toFixed(4).replace(/0+$/, "").replace(/\.$/, "");
}

function text(el, value) { if (el.textContent !== value) el.textContent = value; }

let refusedTimer = null;
// A key or click that was not taken: said in its own line (kept 5 s), so the reply to the
// answer that was taken does not cover it.
function refuse(message) {
  text($("refused"), message);
  clearTimeout(refusedTimer);
  refusedTimer = setTimeout(() => text($("refused"), ""), 5000);
}

function say(message, kind) {
  const reply = $("reply");
  text(reply, message);
  reply.className = "reply" + (kind ? " " + kind : "");
}

// ------------------------------------------------------------------ state from the judge
function accept(fresh) {
  state = fresh; // one stream delivers states in order; a resumed judge starts a new one
  render();
}

function connect() {
  // ?push=0: no stream, a poll every ?refresh= ms (a second tab that should not update)
  if (!window.EventSource || params.get("push") === "0") { stream = null; poll(); return; }
  stream = new EventSource("api/events");
  stream.onopen = () => { streamOpen = true; clearTimeout(pollTimer); };
  stream.onmessage = (e) => {
    try { accept(JSON.parse(e.data)); } catch (err) { /* a cut-off event: the next follows */ }
  };
  stream.onerror = () => {
    streamOpen = false;
    lostContact("reconnecting");
    if (stream.readyState === EventSource.CLOSED) { stream = null; poll(); }
  };
}

async function refresh() {
  try {
    const r = await fetch("api/state", { cache: "no-store" });
    if (!r.ok) throw new Error("HTTP " + r.status);
    state = await r.json();
    render();
    return true;
  } catch (e) {
    lostContact(e.message);
    return false;
  }
}

async function poll() {
  clearTimeout(pollTimer);
  await refresh();
  if (!stream) {
    pollTimer = setTimeout(() => {
      if (params.get("push") === "0") poll(); else { connect(); if (!stream) poll(); }
    }, POLL_MS);
  }
}

function lostContact(why) {
  const p = state && state.progress;
  const ended = p && !state.duel && (state.finished || p.evaluations >= p.budget);
  text($("phase"), ended ? "The run has ended and the judge has stopped. Thank you."
    : "Lost contact with the judge (" + why + "); it reconnects by itself…");
  setButtons(false, false, false);
  $("undo").disabled = true;
}

// ------------------------------------------------------------------ rendering
function setButtons(answer, tie, skip) {
  $("answer-a").disabled = !answer;
  $("answer-b").disabled = !answer;
  $("answer-tie").disabled = !(answer && tie);
  $("answer-skip").disabled = !skip;
}

function settled() { return performance.now() - lastAnswerAt >= SETTLE_MS; }

function render() {
  const run = state.run;
  if (!run) { text($("phase"), "Waiting for the run to start…"); return; }
  text($("run"), `run ${run.run_id} · ${run.task} · ${run.algorithm} · seed ${run.seed}`);
  $("goal").hidden = !run.goal;
  text($("goal"), run.goal || "");
  const nameBox = $("judge-name");
  if (!nameBox.value && document.activeElement !== nameBox) {
    nameBox.value = (store && store.getItem("localpbo.judge")) || run.judge || "";
  }
  const p = state.progress;
  $("progress-bar").style.width = Math.min(100, 100 * p.evaluations / p.budget) + "%";
  text($("progress-text"), `${p.evaluations} of ${p.budget} evaluations · you answered ` +
    `${p.answered} duel${p.answered === 1 ? "" : "s"} · the optimizer counted ${p.optimizer_duels}` +
    (p.open > 1 ? ` · ${p.open} duels waiting` : ""));
  $("answer-tie").title = run.ties ? "can't tell (t or ↓)"
    : "this run does not take can't-tell answers (no tie_threshold)";
  $("notice").hidden = !state.notice;
  text($("notice"), state.notice || "");
  for (const id of state.retracting || []) answeredIds.delete(id);
  renderIncumbent(run);
  renderHistory();
  renderUndo();
  if (review) { renderReview(); return; }
  const d = state.duel;
  const mine = d && answeredIds.has(d.duel_id);
  const waiting = !d || mine || !d.ready;
  if (!d) {
    // the layout keeps its place: the last duel stays, dimmed, while the next is prepared
    dim(shownKey !== "" && !state.finished, state.finished ? "" : "preparing the next duel…");
    if (shownKey === "") $("duel").hidden = true;
    text($("phase"), state.finished ? "Run complete: thank you. You may close this page."
      : "No duel waiting: the optimizer is proposing the next candidates…");
    setButtons(false, false, false);
    return;
  }
  $("duel").hidden = false;
  const key = `${d.duel_id}:${d.a.id}:${d.b.id}`;
  if (key !== shownKey && !mine) newDuel(run, d, key);
  else if (key === shownKey && $("params").dataset.complete !== "yes" && d.a.theta && d.b.theta) {
    renderParams(run, d);
  }
  if (key === shownKey && run.simulated) maybeLoad(d, key);
  if (key === shownKey) {
    for (const side of ["a", "b"]) {
      const s = d[side];
      text($("cid-" + side), `candidate ${s.id}`);
      const badge = $("state-" + side);
      const label = { done: "result in", evaluating: "being evaluated", queued: "queued",
        unknown: "waiting" }[s.result];
      text(badge, label);
      badge.className = "badge " + s.result;
      $("side-" + side).classList.toggle("evaluating", d.evaluating === side.toUpperCase());
    }
  }
  dim(waiting, mine ? "preparing the next duel…" : (d.ready ? "" : "evaluating…"));
  if (mine) {
    text($("phase"), `Duel ${d.duel_id} is recorded; the next duel is on its way…`);
  } else if (d.ready) {
    let phase = `Duel ${d.duel_id}: which was better, A or B?`;
    if (d.skips > 0 && d.others_open === 0) phase += " (asked again: no other duel is waiting)";
    text($("phase"), phase);
  } else if (d.evaluating) {
    const cid = d.evaluating === "A" ? d.a.id : d.b.id;
    text($("phase"), `Evaluating ${d.evaluating} (candidate ${cid}) now… ` +
      "the answers open once both results are in.");
  } else {
    text($("phase"), "Waiting for the results of A and B…");
  }
  trackVisible(d.ready && !mine ? key : "");
  setButtons(d.ready && !mine && !inFlight, run.ties, !mine && !inFlight);
}

function dim(on, label) {
  $("duel").querySelector(".stage").classList.toggle("dim", on);
  $("preparing").hidden = !on || !label;
  text($("preparing"), label || "");
}

function newDuel(run, d, key) {
  shownKey = key;
  renderParams(run, d);
  for (const side of ["a", "b"]) {
    text($("cid-" + side), `candidate ${d[side].id}`);
    text($("note-" + side), "");
  }
  $("answer-note").value = "";
  loading = { key: "", tries: 0 };
  if (run.simulated) {
    maybeLoad(d, key);
  } else {
    replay.a = replay.b = null;
    for (const side of ["a", "b"]) $("canvas-" + side).hidden = true;
    $("player").hidden = true;
    text($("rate"), "");
  }
}

// The episodes load once the judge knows both candidates (a duel request may come before
// its candidates), and again if a load failed (at most 3 times per duel).
let loading = { key: "", tries: 0 };
function maybeLoad(d, key) {
  if (review || !d.a.theta || !d.b.theta) return;
  if (replay.a && replay.b && replay.a.candidate_id === d.a.id && replay.b.candidate_id === d.b.id) return;
  if (loading.key === key && (loading.busy || loading.tries >= 3)) return;
  loading = { key, tries: loading.key === key ? loading.tries + 1 : 1, busy: true };
  loadPair(d.a.id, d.b.id, key).finally(() => { if (loading.key === key) loading.busy = false; });
}

// The two episodes load together and start together: the old pair stays on screen (dimmed)
// until both new ones are in, so the layout never jumps.
async function loadPair(aId, bId, key) {
  for (const side of ["a", "b"]) text($("note-" + side), "loading the episode…");
  const got = await Promise.all([aId, bId].map(async (cid) => {
    try {
      const r = await fetch(`api/rollout/${cid}`, { cache: "no-store" });
      if (!r.ok) throw new Error("HTTP " + r.status);
      return await r.json();
    } catch (e) { return { error: e.message }; }
  }));
  if (key !== currentKey()) return;
  ["a", "b"].forEach((side, i) => {
    const rollout = got[i];
    if (rollout.error) {
      replay[side] = null;
      text($("note-" + side), "no replay (" + rollout.error + ")");
      return;
    }
    replay[side] = rollout;
    $("canvas-" + side).hidden = false;
    const secs = episodeSeconds(rollout).toFixed(2);
    text($("note-" + side), rollout.terminated ? `fell after ${secs} s` : `episode of ${secs} s`);
  });
  $("player").hidden = !(replay.a || replay.b);
  restart();
}

function currentKey() { return review ? `review:${review.duel_id}` : shownKey; }

function renderParams(run, d) {
  const body = $("params").tBodies[0];
  body.replaceChildren();
  const a = d.a.theta || [], b = d.b.theta || [];
  $("params").dataset.complete = d.a.theta && d.b.theta ? "yes" : "no";
  run.names.forEach((name, i) => {
    const tr = document.createElement("tr");
    const unit = run.units[i] ? ` [${run.units[i]}]` : "";
    const diff = (a[i] !== undefined && b[i] !== undefined) ? b[i] - a[i] : null;
    if (diff !== null && diff !== 0) tr.className = "differs";
    for (const [v, cls] of [[name + unit, ""], [fmt(a[i]), "num"], [fmt(b[i]), "num"],
      [fmt(diff), "num"]]) {
      const td = document.createElement("td");
      td.textContent = v;
      if (cls) td.className = cls;
      tr.appendChild(td);
    }
    body.appendChild(tr);
  });
}

function describe(run, theta) {
  if (!theta) return "";
  const values = theta.slice(0, 6).map((v, i) => `${run.names[i]} = ${fmt(v)}`).join(", ");
  return ": " + values + (theta.length > 6 ? `, … (${theta.length} parameters)` : "");
}

function renderIncumbent(run) {
  const rec = state.recommended;
  text($("recommended"), rec ? `candidate ${rec.id}${describe(run, rec.theta)}`
    : "not computed yet (the optimizer computes it while you judge)");
  const inc = state.incumbent;
  if (!inc) { text($("incumbent"), "none yet"); return; }
  text($("incumbent"), `candidate ${inc.id} after ${inc.duels} duels${describe(run, inc.theta)}`);
}

function renderHistory() {
  const body = $("history").tBodies[0];
  const sig = JSON.stringify(state.history) + (state.run.simulated ? "s" : "");
  if (body.dataset.sig === sig) return;
  body.dataset.sig = sig;
  body.replaceChildren(...state.history.map((h) => {
    const tr = document.createElement("tr");
    if (h.undone) tr.className = "undone";
    const seconds = h.seconds === null ? "–" : h.seconds.toFixed(1) + " s" + (h.hidden ? "*" : "");
    const cells = [h.duel_id, h.a, h.b, h.undone ? `${h.answer} (undone)` : h.answer, seconds,
      h.note || "", h.judge || ""];
    cells.forEach((c, i) => {
      const td = document.createElement("td");
      td.textContent = c;
      if (i === 5) { td.className = "notecell"; td.title = h.note || ""; }
      if (i === 4 && h.hidden) td.title = "the page was hidden meanwhile: visible time only";
      tr.appendChild(td);
    });
    const td = document.createElement("td");
    if (state.run.simulated) {
      const b = document.createElement("button");
      b.type = "button";
      b.textContent = "replay";
      b.className = "history-replay";
      b.tabIndex = -1;
      b.addEventListener("click", () => startReview(h));
      td.appendChild(b);
    }
    tr.appendChild(td);
    return tr;
  }));
}

function renderUndo() {
  const u = state.undo;
  const b = $("undo");
  b.disabled = !u || inFlight;
  b.title = u ? `take back your answer to duel ${u.duel_id} (${u.answer}); u or Ctrl+Z`
    : (state.retracting && state.retracting.length ? "an undo is on its way" : "nothing to undo");
}

// ------------------------------------------------------------------ review of past duels
function startReview(h) {
  review = { duel_id: h.duel_id, a: h.a, b: h.b, answer: h.answer };
  $("duel").hidden = false;
  dim(false, "");
  renderReview();
  for (const side of ["a", "b"]) {
    text($("cid-" + side), `candidate ${review[side]}`);
    text($("state-" + side), "");
    $("state-" + side).className = "badge";
    $("side-" + side).classList.remove("evaluating");
  }
  loadPair(h.a, h.b, currentKey());
}

function renderReview() {
  $("review").hidden = false;
  text($("review-text"), `Reviewing duel ${review.duel_id}: you said ${review.answer}.`);
  text($("phase"), `Reviewing duel ${review.duel_id} (answers are off while you review).`);
  setButtons(false, false, false);
}

function endReview() {
  if (!review) return;
  review = null;
  $("review").hidden = true;
  const d = state && state.duel;
  shownKey = "";
  if (d && !answeredIds.has(d.duel_id)) render();
  else if (state) render();
}

// ------------------------------------------------------------------ visible time
function trackVisible(key) {
  if (key !== watch.key) {
    watch.key = key;
    watch.visibleMs = 0;
    watch.hidden = document.visibilityState !== "visible";
    watch.since = key && document.visibilityState === "visible" ? performance.now() : null;
  }
}

function visibleSeconds() {
  let ms = watch.visibleMs;
  if (watch.since !== null) ms += performance.now() - watch.since;
  return ms / 1000;
}

document.addEventListener("visibilitychange", () => {
  if (document.visibilityState === "visible") {
    if (watch.key && watch.since === null) watch.since = performance.now();
  } else {
    if (watch.since !== null) watch.visibleMs += performance.now() - watch.since;
    watch.since = null;
    if (watch.key) watch.hidden = true;
  }
});

// ------------------------------------------------------------------ answers
async function post(path, payload) {
  const r = await fetch(path, {
    method: "POST",
    headers: { "Content-Type": "application/json" },
    body: JSON.stringify(payload),
  });
  const body = await r.json().catch(() => ({ detail: "unreadable reply" }));
  return [r, body];
}

async function answer(choice, keyName) {
  const d = state && state.duel;
  const button = { a: "answer-a", b: "answer-b", tie: "answer-tie", skip: "answer-skip" }[choice];
  if (!d || inFlight || $(button).disabled) return;
  if (!settled()) {
    const label = { a: "A better", b: "B better", tie: "can't tell", skip: "skip" }[choice];
    refuse(`${keyName ? "Key " + keyName : "Click"} (${label}) not taken: it came ` +
      `${Math.round(performance.now() - lastAnswerAt)} ms after your previous answer ` +
      `(a double press?); answer duel ${d.duel_id} again if you meant it.`);
    return;
  }
  lastAnswerAt = performance.now();
  inFlight = true;
  setButtons(false, false, false);
  say("sending…");
  const payload = { duel_id: d.duel_id, first_id: d.a.id, second_id: d.b.id, choice };
  if (choice !== "skip") {
    const note = $("answer-note").value.trim();
    const name = $("judge-name").value.trim();
    if (note) payload.note = note.slice(0, 1000);
    if (name) payload.judge = name.slice(0, 80);
    if (watch.key === `${d.duel_id}:${d.a.id}:${d.b.id}`) {
      payload.visible_seconds = Math.round(visibleSeconds() * 1000) / 1000;
      payload.hidden = watch.hidden;
    }
  }
  try {
    const [r, body] = await post("api/answer", payload);
    if (r.ok && body.skipped !== undefined) {
      say(body.alone ? `Skipped duel ${d.duel_id}; no other duel is waiting, so it comes back.`
        : `Skipped duel ${d.duel_id}; it comes back later.`, "ok");
      shownKey = "";
    } else if (r.ok) {
      answeredIds.add(d.duel_id);
      $("answer-note").value = "";
      say(`Recorded: duel ${d.duel_id}, ${body.answer}.`, "ok");
    } else {
      say(`Not recorded (HTTP ${r.status}, ${body.field || "?"}: ${body.reason || "?"}): ` +
        `${body.detail || ""}`, "err");
    }
  } catch (e) {
    say("Not recorded: the judge did not answer (" + e.message + "). Try again.", "err");
  }
  inFlight = false;
  if (!streamOpen) refresh(); else render();
}

async function undo() {
  const u = state && state.undo;
  if (!u || inFlight) {
    if (!inFlight) refuse("Nothing to undo" + (state && state.retracting && state.retracting.length
      ? ": an undo is already on its way." : "."));
    return;
  }
  inFlight = true;
  $("undo").disabled = true;
  try {
    const [r, body] = await post("api/undo", { duel_id: u.duel_id });
    if (r.ok) {
      answeredIds.delete(u.duel_id);
      say(`Undone: duel ${u.duel_id} (${body.answer}); it comes back once the optimizer asks again.`,
        "ok");
    } else {
      say(`Not undone (HTTP ${r.status}, ${body.reason || "?"}): ${body.detail || ""}`, "err");
    }
  } catch (e) {
    say("Not undone: the judge did not answer (" + e.message + ").", "err");
  }
  inFlight = false;
  if (!streamOpen) refresh(); else render();
}

// A key that cannot be taken is refused where the person looks, never dropped silently.
function tryAnswer(choice, keyName) {
  if (review) { refuse(`Key ${keyName} not taken: you are reviewing a past duel (Esc goes back).`); return; }
  const d = state && state.duel;
  const label = { a: "A better", b: "B better", tie: "can't tell", skip: "skip" }[choice];
  let why = "";
  if (inFlight) why = "the previous answer is still being sent";
  else if (!d || answeredIds.has(d.duel_id)) why = "no duel is ready yet (the next one is being prepared)";
  else if (choice !== "skip" && !d.ready) why = `duel ${d.duel_id} is waiting for its episode results`;
  else if (choice === "tie" && !state.run.ties) why = "this run does not take can't-tell answers";
  if (why) { refuse(`Key ${keyName} (${label}) not taken: ${why}.`); return; }
  answer(choice, keyName);
}

// ------------------------------------------------------------------ replay
function episodeSeconds(r) { return r.steps * r.dt; }

function duration() {
  let t = 0;
  for (const r of [replay.a, replay.b]) if (r) t = Math.max(t, episodeSeconds(r));
  return t;
}

// Episode seconds per screen second: the chosen speed, lowered so that the episodes last at
// least MIN_SCREEN_S on screen.
function effectiveRate() {
  const total = duration();
  if (total <= 0) return speed;
  return Math.min(speed, total / MIN_SCREEN_S);
}

function now() {
  const t = replay.playing
    ? replay.offset + effectiveRate() * (performance.now() - replay.start) / 1000 : replay.offset;
  return Math.min(t, duration());
}

function restart() { replay.offset = 0; replay.start = performance.now(); setPlaying(true); }

function setPlaying(on) {
  replay.offset = now();
  replay.start = performance.now();
  replay.playing = on;
  text($("play"), on ? "Pause" : "Play");
}

function setSpeed(value) {
  const t = now();
  speed = value;
  replay.offset = t;
  replay.start = performance.now();
  $("speed").value = String(value);
  if (store) store.setItem("localpbo.speed", String(value));
}

function frameAt(r, t) {
  const n = r.frames.length;
  const x = Math.min(t / r.dt / r.stride, n - 1);
  const i = Math.floor(x), f = x - i;
  const a = r.frames[i], b = r.frames[Math.min(i + 1, n - 1)];
  if (f === 0 || a === b) return a;
  return a.map((s, k) => s.map((v, j) => v + f * (b[k][j] - v)));
}

function draw(side, t) {
  const r = replay[side];
  const canvas = $("canvas-" + side);
  if (!r || canvas.hidden) return;
  const ctx = canvas.getContext("2d");
  const W = canvas.width, H = canvas.height;
  const end = episodeSeconds(r);
  const segs = frameAt(r, Math.min(t, end));
  const topView = r.axes[1] !== "z";
  let cu = 0, cv = 0;
  for (const s of segs) { cu += (s[0] + s[2]) / 2; cv += (s[1] + s[3]) / 2; }
  cu /= segs.length; cv /= segs.length;
  const ppm = topView ? H / 3 : H / 2.6;
  const ox = W / 2 - cu * ppm;
  const oy = topView ? H / 2 + cv * ppm : H - 24;
  const X = (u) => ox + u * ppm, Y = (v) => oy - v * ppm;
  ctx.clearRect(0, 0, W, H);
  ctx.strokeStyle = "#c9d3df"; ctx.fillStyle = "#7a8594"; ctx.lineWidth = 1;
  ctx.font = "11px sans-serif";
  const left = Math.floor((0 - ox) / ppm), right = Math.ceil((W - ox) / ppm);
  for (let m = left; m <= right; m += 0.5) {
    ctx.beginPath();
    if (topView) { ctx.moveTo(X(m), 0); ctx.lineTo(X(m), H); } else { ctx.moveTo(X(m), oy); ctx.lineTo(X(m), oy + 6); }
    ctx.stroke();
    if (Number.isInteger(m)) ctx.fillText(`${m} m`, X(m) + 2, topView ? 12 : oy + 18);
  }
  if (!topView) { ctx.strokeStyle = "#8a96a6"; ctx.beginPath(); ctx.moveTo(0, oy); ctx.lineTo(W, oy); ctx.stroke(); }
  ctx.strokeStyle = COLORS[side]; ctx.lineCap = "round";
  segs.forEach((s, i) => {
    ctx.lineWidth = Math.max(2, 2 * r.radii[i] * ppm);
    ctx.beginPath(); ctx.moveTo(X(s[0]), Y(s[1])); ctx.lineTo(X(s[2]), Y(s[3])); ctx.stroke();
  });
  ctx.fillStyle = "#333";
  ctx.font = "13px sans-serif";
  ctx.fillText(`t = ${Math.min(t, end).toFixed(2)} s   x = ${cu.toFixed(2)} m`, 8, 16);
  if (t >= end && r.terminated) {
    ctx.fillStyle = "#b00020";
    ctx.fillText(`fell at ${end.toFixed(2)} s`, 8, 34);
  }
}

let loopWait = null;
function tick() {
  const total = duration();
  if (total > 0) {
    const t = now();
    if (replay.playing && t >= total) {
      if (!$("loop").checked) setPlaying(false);
      else if (loopWait === null) loopWait = performance.now();
      else if (performance.now() - loopWait > LOOP_PAUSE_S * 1000) { loopWait = null; restart(); }
    }
    draw("a", t); draw("b", t);
    $("scrub").value = String(Math.round(1000 * t / total));
    text($("clock"), `${t.toFixed(2)} / ${total.toFixed(2)} s`);
    const rate = effectiveRate();
    text($("rate"), rate < speed
      ? `slowed to ${rate.toFixed(2)}×: the longer episode lasts ${total.toFixed(2)} s, so it ` +
        `plays over ${(total / rate).toFixed(1)} s`
      : `playing at ${rate}×`);
  }
  requestAnimationFrame(tick);
}

// ------------------------------------------------------------------ controls and keys
$("speed").value = String(speed);
$("speed").addEventListener("change", (e) => { setSpeed(Number(e.target.value)); e.target.blur(); });
$("loop").addEventListener("change", (e) => e.target.blur());
$("play").addEventListener("click", () => {
  if (!replay.playing && now() >= duration()) restart(); else setPlaying(!replay.playing);
});
$("replay").addEventListener("click", restart);
$("scrub").addEventListener("input", (e) => {
  replay.offset = duration() * Number(e.target.value) / 1000;
  replay.start = performance.now();
  replay.playing = false;
  text($("play"), "Play");
});
$("scrub").addEventListener("change", (e) => e.target.blur());
for (const b of document.querySelectorAll(".answer")) {
  b.addEventListener("click", () => answer(b.dataset.choice));
}
$("undo").addEventListener("click", undo);
$("review-back").addEventListener("click", endReview);
$("judge-name").addEventListener("change", (e) => {
  if (store) store.setItem("localpbo.judge", e.target.value.trim());
});

const ANSWER_KEYS = { ArrowLeft: "a", a: "a", ArrowRight: "b", b: "b", ArrowDown: "tie",
  t: "tie", s: "skip" };

// Capture phase: the keys answer whatever has the focus (a slider, a button, a checkbox);
// only a text box keeps its typing (Esc leaves it).
window.addEventListener("keydown", (e) => {
  const el = e.target;
  const typing = el && (el.tagName === "TEXTAREA" ||
    (el.tagName === "INPUT" && el.type === "text"));
  if (typing) {
    if (e.key === "Escape") { el.blur(); e.preventDefault(); }
    return;
  }
  if (e.altKey || e.metaKey) return;
  if (e.ctrlKey) {
    if (e.key === "z" || e.key === "Z") { e.preventDefault(); e.stopPropagation(); undo(); }
    return;
  }
  const choice = ANSWER_KEYS[e.key];
  if (choice) {
    e.preventDefault(); e.stopPropagation();
    if (!e.repeat) tryAnswer(choice, e.key.replace("Arrow", "").toLowerCase());
    return;
  }
  const handled = () => { e.preventDefault(); e.stopPropagation(); };
  if (e.key === " ") { handled(); $("play").click(); }
  else if (e.key === "r") { handled(); restart(); }
  else if (e.key === "u") { handled(); undo(); }
  else if (e.key === "Escape") { handled(); endReview(); }
  else if (e.key === "+" || e.key === "=" || e.key === "-") {
    handled();
    const i = SPEEDS.indexOf(speed) + (e.key === "-" ? -1 : 1);
    setSpeed(SPEEDS[Math.max(0, Math.min(SPEEDS.length - 1, i))]);
  }
}, true);

connect();
requestAnimationFrame(tick);
