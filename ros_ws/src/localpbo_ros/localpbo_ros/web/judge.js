// The judge's page: polls api/state, shows the current duel, replays the two episodes in
// sync, and posts answers to api/answer. No framework, no network access beyond this server.
"use strict";

const $ = (id) => document.getElementById(id);
const params = new URLSearchParams(window.location.search);
const REFRESH_MS = Math.max(200, Number(params.get("refresh")) || 700);
// After an answer the next duel is usually ready within milliseconds (the optimizer prepared
// it while you watched): look often until it is, for at most FAST_FOR_MS.
const FAST_MS = 25;
const FAST_FOR_MS = 5000;
const SETTLE_MS = 400; // answers are ignored this long after a new duel appears
const COLORS = { a: "#1f6fb2", b: "#c0561b" };

let state = null;
let shownKey = "";
let shownAt = 0;
let inFlight = false;
let timer = null;
let answered = null; // { id, at }: the duel just answered, until the next one is ready
const answeredIds = new Set(); // duels this page answered: never offered again
let replies = 0; // answers the judge replied to; a state fetched before the latest one is stale
const replay = { a: null, b: null, start: performance.now(), offset: 0, playing: true };

function fmt(v) {
  if (v === null || v === undefined) return "–";
  const a = Math.abs(v);
  if (a !== 0 && (a < 1e-3 || a >= 1e5)) return v.toExponential(3);
  return v.toFixed(4).replace(/0+$/, "").replace(/\.$/, "");
}

function text(el, value) { if (el.textContent !== value) el.textContent = value; }

async function refresh() {
  clearTimeout(timer);
  const asked = replies;
  try {
    const r = await fetch("api/state", { cache: "no-store" });
    if (!r.ok) throw new Error("HTTP " + r.status);
    const fresh = await r.json();
    if (asked !== replies) return; // fetched before an answer landed: the answer's refresh follows
    state = fresh;
    render();
  } catch (e) {
    const p = state && state.progress;
    const ended = p && !state.duel && (state.finished || p.evaluations >= p.budget);
    text($("phase"), ended ? "The run has ended and the judge has stopped. Thank you."
      : "Lost contact with the judge (" + e.message + "); retrying…");
    setButtons(false, false, false);
  }
  timer = setTimeout(refresh, waitingForNext() ? FAST_MS : REFRESH_MS);
}

function waitingForNext() {
  if (!answered) return false;
  const d = state && state.duel;
  const next = d && d.ready && d.duel_id !== answered.id;
  const ended = state && !d && state.finished;
  if (next || ended || performance.now() - answered.at > FAST_FOR_MS) answered = null;
  return answered !== null;
}

function setButtons(answer, tie, skip) {
  $("answer-a").disabled = !answer;
  $("answer-b").disabled = !answer;
  $("answer-tie").disabled = !(answer && tie);
  $("answer-skip").disabled = !skip;
}

function render() {
  const run = state.run;
  if (!run) { text($("phase"), "Waiting for the run to start…"); $("duel").hidden = true; return; }
  text($("run"), `run ${run.run_id} · ${run.task} · ${run.algorithm} · seed ${run.seed}`);
  const p = state.progress;
  $("progress-bar").style.width = Math.min(100, 100 * p.evaluations / p.budget) + "%";
  text($("progress-text"), `${p.evaluations} of ${p.budget} evaluations · you answered ` +
    `${p.answered} duel${p.answered === 1 ? "" : "s"} · the optimizer counted ${p.optimizer_duels}` +
    (p.open > 1 ? ` · ${p.open} duels waiting` : ""));
  $("answer-tie").title = run.ties ? "can't tell (t or ↓)"
    : "this run does not take can't-tell answers (no tie_threshold)";
  renderIncumbent(run);
  renderHistory();
  const d = state.duel;
  if (!d) {
    $("duel").hidden = true;
    text($("phase"), state.finished ? "Run complete: thank you. You may close this page."
      : "No duel waiting: the optimizer is proposing the next candidates…");
    shownKey = "";
    return;
  }
  $("duel").hidden = false;
  const key = `${d.duel_id}:${d.a.id}:${d.b.id}`;
  if (key !== shownKey) newDuel(run, d, key);
  else if ($("params").dataset.complete !== "yes" && d.a.theta && d.b.theta) renderParams(run, d);
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
  const mine = answeredIds.has(d.duel_id);
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
  const settled = performance.now() - shownAt >= SETTLE_MS;
  setButtons(d.ready && !mine && !inFlight && settled, run.ties, !mine && !inFlight && settled);
  if (!settled) setTimeout(render, SETTLE_MS);
}

function newDuel(run, d, key) {
  shownKey = key;
  shownAt = performance.now();
  renderParams(run, d);
  replay.a = replay.b = null;
  for (const side of ["a", "b"]) { $("canvas-" + side).hidden = true; text($("note-" + side), ""); }
  $("player").hidden = true;
  if (run.simulated) {
    for (const side of ["a", "b"]) loadRollout(side, d[side].id, key);
  }
}

async function loadRollout(side, cid, key) {
  text($("note-" + side), "loading the episode…");
  try {
    const r = await fetch(`api/rollout/${cid}`, { cache: "no-store" });
    if (!r.ok) throw new Error("HTTP " + r.status);
    const rollout = await r.json();
    if (key !== shownKey) return;
    replay[side] = rollout;
    $("canvas-" + side).hidden = false;
    $("player").hidden = false;
    const secs = (rollout.steps * rollout.dt).toFixed(1);
    text($("note-" + side), rollout.terminated ? `fell after ${secs} s` : `episode of ${secs} s`);
    restart();
  } catch (e) {
    text($("note-" + side), "no replay (" + e.message + ")");
  }
}

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
  const rows = state.history.map((h) =>
    [h.duel_id, h.a, h.b, h.answer, h.seconds === null ? "–" : h.seconds.toFixed(1) + " s"]);
  const sig = JSON.stringify(rows);
  if (body.dataset.sig === sig) return;
  body.dataset.sig = sig;
  body.replaceChildren(...rows.map((cells) => {
    const tr = document.createElement("tr");
    for (const c of cells) { const td = document.createElement("td"); td.textContent = c; tr.appendChild(td); }
    return tr;
  }));
}

async function answer(choice) {
  const d = state && state.duel;
  const button = { a: "answer-a", b: "answer-b", tie: "answer-tie", skip: "answer-skip" }[choice];
  if (!d || inFlight || $(button).disabled) return;
  inFlight = true;
  setButtons(false, false, false);
  const reply = $("reply");
  text(reply, "sending…");
  reply.className = "reply";
  try {
    const r = await fetch("api/answer", {
      method: "POST",
      headers: { "Content-Type": "application/json" },
      body: JSON.stringify({ duel_id: d.duel_id, first_id: d.a.id, second_id: d.b.id, choice }),
    });
    const body = await r.json().catch(() => ({ detail: "unreadable reply" }));
    if (r.ok && body.skipped !== undefined) {
      text(reply, body.alone ? `Skipped duel ${d.duel_id}; no other duel is waiting, so it comes back.`
        : `Skipped duel ${d.duel_id}; it comes back later.`);
      reply.className = "reply ok";
    } else if (r.ok) {
      answered = { id: d.duel_id, at: performance.now() };
      answeredIds.add(d.duel_id);
      text(reply, `Recorded: duel ${d.duel_id}, ${body.answer}.`);
      reply.className = "reply ok";
    } else {
      text(reply, `Not recorded (HTTP ${r.status}, ${body.field || "?"}: ${body.reason || "?"}): ` +
        `${body.detail || ""}`);
      reply.className = "reply err";
    }
  } catch (e) {
    text(reply, "Not recorded: the judge did not answer (" + e.message + "). Try again.");
    reply.className = "reply err";
  }
  inFlight = false;
  replies += 1;
  refresh();
}

// ------------------------------------------------------------------ replay
function duration() {
  let t = 0;
  for (const r of [replay.a, replay.b]) if (r) t = Math.max(t, r.steps * r.dt);
  return t;
}

function now() {
  const t = replay.playing ? replay.offset + (performance.now() - replay.start) / 1000 : replay.offset;
  return Math.min(t, duration());
}

function restart() { replay.offset = 0; replay.start = performance.now(); setPlaying(true); }

function setPlaying(on) {
  replay.offset = now();
  replay.start = performance.now();
  replay.playing = on;
  text($("play"), on ? "Pause" : "Play");
}

function draw(side, t) {
  const r = replay[side];
  const canvas = $("canvas-" + side);
  if (!r || canvas.hidden) return;
  const ctx = canvas.getContext("2d");
  const W = canvas.width, H = canvas.height;
  const n = r.frames.length;
  const idx = Math.min(Math.floor(t / r.dt / r.stride), n - 1);
  const segs = r.frames[idx];
  const topView = r.axes[1] !== "z";
  let cu = 0, cv = 0;
  for (const s of segs) { cu += (s[0] + s[2]) / 2; cv += (s[1] + s[3]) / 2; }
  cu /= segs.length; cv /= segs.length;
  const ppm = topView ? H / 3 : H / 2.1;
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
  ctx.fillText(`t = ${Math.min(t, r.steps * r.dt).toFixed(2)} s   x = ${cu.toFixed(2)} m`, 8, 14);
}

function tick() {
  const total = duration();
  if (total > 0) {
    const t = now();
    if (replay.playing && t >= total) setPlaying(false);
    draw("a", t); draw("b", t);
    $("scrub").value = String(Math.round(1000 * t / total));
    text($("clock"), `${t.toFixed(1)} / ${total.toFixed(1)} s`);
  }
  requestAnimationFrame(tick);
}

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
for (const b of document.querySelectorAll(".answer")) {
  b.addEventListener("click", () => answer(b.dataset.choice));
}
document.addEventListener("keydown", (e) => {
  if (e.ctrlKey || e.metaKey || e.altKey || e.target.tagName === "INPUT") return;
  const choice = { ArrowLeft: "a", a: "a", ArrowRight: "b", b: "b", ArrowDown: "tie", t: "tie",
    s: "skip" }[e.key];
  if (choice) { e.preventDefault(); answer(choice); return; }
  if (e.key === " ") { e.preventDefault(); $("play").click(); }
  if (e.key === "r") restart();
});

refresh();
requestAnimationFrame(tick);
