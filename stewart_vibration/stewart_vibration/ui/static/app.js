// Planning UI page (plain JS, no libraries): commands over the WebSocket, live frames drawn on <canvas>.
// The server checks every command again with the core's checks; this page only shows what it says.
"use strict";

const $ = (id) => document.getElementById(id);
const POSE = ["x_mm", "y_mm", "z_mm", "roll_deg", "pitch_deg", "yaw_deg"];
const VIB = ["dir_x", "dir_y", "dir_z", "frame", "mode", "acceleration_g", "amplitude_um", "frequency_hz", "phase_deg",
  "duration_s", "ramp_s"];
const COLORS = ["#dc2626", "#ea580c", "#16a34a", "#0891b2", "#2563eb", "#9333ea"];
const PLOT_WINDOW_S = 2.0;

const params = new URLSearchParams(location.search);
const token = params.get("token") || "";
if (token) history.replaceState(null, "", location.pathname);  // the cookie carries it from here on

const ui = {
  ws: null, nextId: 1, pending: new Map(), hello: null, frame: null, lastFrameWall: 0,
  stats: { frames: 0, plotDraws: 0, vibSamples: 0, forceSamples: 0, replies: 0 },
  series: { joints: [], forces: [] }, lastStart: null, preview: null, reach: null,
};
window.ui = ui;

// ---- connection -------------------------------------------------------------------------------------
function connect() {
  const proto = location.protocol === "https:" ? "wss:" : "ws:";
  const ws = new WebSocket(`${proto}//${location.host}/ws${token ? "?token=" + encodeURIComponent(token) : ""}`);
  ui.ws = ws;
  ws.onmessage = (ev) => {
    const msg = JSON.parse(ev.data);
    if (msg.type === "hello") onHello(msg);
    else if (msg.type === "frame") onFrame(msg);
    else if (msg.type === "reply") onReply(msg);
  };
  ws.onclose = () => { setLink("disconnected: reconnecting...", "error"); setTimeout(connect, 1000); };
  ws.onopen = () => setLink("connected", "ok");
}

function setLink(text, cls) { const el = $("link"); el.textContent = text; el.className = "badge " + cls; }

function send(cmd, args) {
  return new Promise((resolve) => {
    if (!ui.ws || ui.ws.readyState !== WebSocket.OPEN) {
      resolve({ ok: false, refused_by: "page", message: "not connected to the planning_ui node" });
      return;
    }
    const id = ui.nextId++;
    ui.pending.set(id, resolve);
    ui.ws.send(JSON.stringify({ id, cmd, args: args || {} }));
  });
}

function onReply(msg) {
  ui.stats.replies++;
  const resolve = ui.pending.get(msg.id);
  ui.pending.delete(msg.id);
  if (resolve) resolve(msg);
  else if (!msg.ok) toast(`${msg.cmd || "command"} refused: ${msg.message}`);
}

function toast(text) {
  const el = $("toast");
  el.textContent = text;
  el.classList.remove("hidden");
  clearTimeout(toast.timer);
  toast.timer = setTimeout(() => el.classList.add("hidden"), 6000);
}

// ---- helpers -----------------------------------------------------------------------------------------
const fmt = (v, d = 3) => (v === null || v === undefined || Number.isNaN(v) ? "-" : Number(v).toFixed(d));
function esc(text) { const d = document.createElement("div"); d.textContent = String(text ?? ""); return d.innerHTML; }
function badge(el, text, cls) { el.textContent = text; el.className = "badge " + cls; }
function refusal(reply) {
  const who = (reply.refused_by ? `refused by ${reply.refused_by}: ` : "") + (reply.outcome ? `${reply.outcome}: ` : "");
  return `<span class="refusal">${esc(who + reply.message)}</span>`;
}
function readNumber(id) { const v = $(id).value.trim(); return v === "" ? NaN : Number(v); }
function poseArgs() { const a = {}; for (const k of POSE) a[k] = readNumber(k); return a; }
function setPose(fields) { for (const k of POSE) $(k).value = Number(fields[k]).toFixed(4).replace(/\.?0+$/, ""); }
function vibArgs() {
  return {
    direction: [readNumber("dir_x"), readNumber("dir_y"), readNumber("dir_z")], frame: $("frame").value,
    mode: $("mode").value, acceleration_g: readNumber("acceleration_g"), amplitude_um: readNumber("amplitude_um"),
    frequency_hz: readNumber("frequency_hz"), phase_deg: readNumber("phase_deg"), duration_s: readNumber("duration_s"),
    ramp_s: readNumber("ramp_s"),
  };
}
function debounce(fn, ms) { let t; return () => { clearTimeout(t); t = setTimeout(fn, ms); }; }

// ---- hello -------------------------------------------------------------------------------------------
function onHello(msg) {
  ui.hello = msg;
  $("convention").textContent = "Target pose of the distal fragment (platform frame) relative to the base: " +
    msg.convention + ".";
  $("namespace").textContent = msg.namespace;
  const lim = msg.robot.unit;
  $("vib-limits").textContent = `vibration unit limits: peak acceleration ${fmt(lim.acceleration_max_g, 2)} g, ` +
    `amplitude ${fmt(lim.amplitude_max_um, 0)} um, band ${lim.frequency_band_hz[0]}-${lim.frequency_band_hz[1]} Hz`;
  checkPose();
}

// ---- 1. reduction ------------------------------------------------------------------------------------
async function checkPose() {
  const reply = await send("check_pose", poseArgs());
  ui.reach = reply;
  const body = $("reach-table").tBodies[0];
  body.innerHTML = "";
  if (!reply.ok) {
    badge($("reach-status"), "invalid", "error");
    $("reach-reason").innerHTML = refusal(reply);
    $("reach-cond").textContent = "";
    return;
  }
  badge($("reach-status"), reply.reachable ? "reachable" : "unreachable", reply.reachable ? "ok" : "error");
  $("reach-reason").innerHTML = reply.reachable ? "" :
    `<span class="reason">first violated limit: ${esc(reply.error.type)}: ${esc(reply.error.message)}</span>`;
  const [smin, smax] = reply.stroke_mm;
  for (let i = 0; i < 6; i++) {
    const tr = body.insertRow();
    const l = reply.leg_lengths_mm[i], m = reply.stroke_margin_mm[i];
    const u = reply.universal_deg[i], s = reply.spherical_deg[i];
    tr.innerHTML = `<td>${i + 1}</td><td>${fmt(l, 3)}</td><td class="${m < 0 ? "bad" : ""}">${fmt(m, 3)}</td>` +
      `<td class="${u > reply.universal_max_deg ? "bad" : ""}">${fmt(u, 2)}</td>` +
      `<td class="${s > reply.spherical_max_deg ? "bad" : ""}">${fmt(s, 2)}</td>`;
  }
  const c = reply.condition_number;
  $("reach-cond").innerHTML = `stroke [${fmt(smin, 1)}, ${fmt(smax, 1)}] mm; joints <= ${fmt(reply.universal_max_deg, 1)} ` +
    `deg (universal), <= ${fmt(reply.spherical_max_deg, 1)} deg (spherical); Jacobian condition number ` +
    `<b>${c === null ? "inf" : fmt(c, 2)}</b> (limit ${fmt(reply.condition_number_max, 1)})`;
}

async function planPath() {
  $("path-result").textContent = "asking kinematics/plan_path...";
  const reply = await send("plan_path", poseArgs());
  if (!reply.ok) { $("path-result").innerHTML = "path: " + refusal(reply); return; }
  const p = reply.path;
  $("path-result").innerHTML = `path from the current estimate: <b>${p.waypoints}</b> waypoints; worst margin ` +
    `<b>${esc(p.worst.limit)} ${fmt(p.worst.margin, 3)} ${esc(p.worst.unit)}</b> (stroke ${fmt(p.stroke_margin_mm, 3)} mm, ` +
    `universal ${fmt(p.universal_margin_deg, 2)} deg, spherical ${fmt(p.spherical_margin_deg, 2)} deg, ` +
    `condition number <= ${fmt(p.condition_number_max, 2)})`;
}

async function move() {
  $("move-result").textContent = "sending...";
  const reply = await send("move", poseArgs());
  if (reply.ok) { $("move-result").textContent = reply.message; return; }
  let html = "move " + refusal(reply);
  if (reply.node_reason) html += `<br>kinematics says: <span class="reason">${esc(reply.node_reason)}</span>`;
  $("move-result").innerHTML = html;
}

// ---- 2. vibration ------------------------------------------------------------------------------------
async function previewVibration() {
  const reply = await send("preview_vibration", vibArgs());
  showPreview(reply);
}

function showPreview(reply) {
  const body = $("vib-table").tBodies[0];
  body.innerHTML = "";
  if (!reply.ok && !reply.preview) {
    badge($("vib-feasible"), "invalid", "error");
    $("vib-reason").innerHTML = refusal(reply);
    $("vib-platform").textContent = "";
    return;
  }
  const p = reply.preview;
  ui.preview = p;
  badge($("vib-feasible"), p.feasible ? "feasible" : "infeasible", p.feasible ? "ok" : "error");
  $("vib-reason").innerHTML = p.feasible ? "" : `<span class="reason">${esc(p.reason)}</span>`;
  if (p.amplitude_um === undefined) { $("vib-platform").textContent = ""; return; }
  const d = p.direction_base;
  $("vib-platform").innerHTML = `at the current pose estimate: platform <b>${fmt(p.amplitude_um, 3)} um</b> ` +
    `(${fmt(p.acceleration_g, 3)} g) at ${fmt(p.frequency_hz, 2)} Hz along [${fmt(d[0], 4)}, ${fmt(d[1], 4)}, ` +
    `${fmt(d[2], 4)}] (base frame), phase ${fmt(p.phase_rad, 4)} rad`;
  const planner = ui.lastStart && ui.lastStart.plan ? ui.lastStart.plan.leg_amplitudes_m.map((v) => v * 1e6) : null;
  const accMax = p.limits.acceleration_max_g;
  for (let i = 0; i < 6; i++) {
    const tr = body.insertRow();
    const acc = p.peak_leg_acceleration_g[i];
    tr.innerHTML = `<td>${i + 1}</td><td>${fmt(p.gains[i], 4)}</td><td class="amp">${fmt(p.leg_amplitudes_um[i], 3)}</td>` +
      `<td>${Math.abs(p.leg_phases_rad[i]) < 1e-9 ? "0" : fmt(p.leg_phases_rad[i], 4) + " (pi)"}</td>` +
      `<td class="${acc > accMax ? "bad" : ""}">${fmt(acc, 3)} / ${fmt(accMax, 2)}</td>` +
      `<td class="planner">${planner ? fmt(planner[i], 3) : "-"}</td>`;
  }
}

async function startVibration() {
  $("start-result").textContent = "sending the vibration goal...";
  const reply = await send("start", vibArgs());
  ui.lastStart = reply;
  if (reply.preview) showPreview({ ok: true, preview: reply.preview });
  if (!reply.ok) { $("start-result").innerHTML = "start " + refusal(reply); return; }
  const a = reply.plan;
  $("start-result").innerHTML = `<b>started</b> (vibration_planner): t0 = ${fmt(a.t0_s, 3)} s; planner leg amplitudes ` +
    `[${a.leg_amplitudes_m.map((v) => fmt(v * 1e6, 3)).join(", ")}] um; phases [${a.leg_phases_rad.map((v) => fmt(v, 4)).join(", ")}] rad; ` +
    `gains [${a.gains.map((v) => fmt(v, 4)).join(", ")}]; preview vs planner: <b id="preview-match">` +
    `${fmt(reply.preview_vs_plan_um, 4)} um</b> max difference` +
    `<div class="dim mono">${esc(reply.message)}</div>`;
}

async function trigger(cmd, label) {
  const reply = await send(cmd, {});
  const text = reply.ok ? `${label}: ${reply.message}` : `${label} ` + reply.message;
  if (!reply.ok) toast(`${label} refused${reply.refused_by ? " by " + reply.refused_by : ""}: ${reply.message}`);
  else toast(text);
  $("start-result").innerHTML = reply.ok ? esc(text) : `${esc(label)} ${refusal(reply)}`;
  return reply;
}

// ---- 3. live frames ----------------------------------------------------------------------------------
function onFrame(f) {
  ui.frame = f;
  ui.lastFrameWall = performance.now();
  ui.stats.frames++;
  addSamples("joints", f.plots.joints);
  addSamples("forces", f.plots.forces);
  ui.stats.vibSamples += f.plots.joints.length;
  ui.stats.forceSamples += f.plots.forces.length;
  showStale(f);
  showPoses(f);
  showVibrationStatus(f.vibration);
  showMove(f.move);
  showNodes(f.nodes);
  $("mcap-path").textContent = f.mcap.path ? `${f.mcap.path} (${f.mcap.state})` : "- (no recorder log seen yet)";
  showEvents(f.events);
  showSummary(f.summary, f.report);
  requestDraw();
}

function addSamples(key, rows) {
  const s = ui.series[key];
  for (const r of rows) s.push(r);
  if (s.length) {
    const cut = s[s.length - 1][0] - PLOT_WINDOW_S;
    let i = 0;
    while (i < s.length && s[i][0] < cut) i++;
    if (i) s.splice(0, i);
  }
}

function showStale(f) {
  for (const el of document.querySelectorAll("[data-stream]")) {
    const age = f.ages[el.dataset.stream];
    const stale = age === undefined || age > f.stale_after_s;
    el.classList.toggle("stale", stale);
    for (const label of el.querySelectorAll(":scope .stale-label, :scope > .caption .stale-label")) {
      label.textContent = stale ? (age === undefined ? "no data yet" : `stale: ${fmt(age, 1)} s old`) : "";
    }
  }
}

function poseText(p) {
  const v = p.fields;
  return `x ${fmt(v.x_mm, 4)} y ${fmt(v.y_mm, 4)} z ${fmt(v.z_mm, 4)} mm; roll ${fmt(v.roll_deg, 4)} ` +
    `pitch ${fmt(v.pitch_deg, 4)} yaw ${fmt(v.yaw_deg, 4)} deg (t = ${fmt(p.stamp, 3)} s)`;
}

function showPoses(f) {
  if (f.estimate) $("pose-estimate").textContent = poseText(f.estimate);
  if (f.legs) {
    $("legs").textContent = f.legs.length_mm.map((l, i) => `${i + 1}: ${fmt(l, 3)} mm ${fmt(f.legs.vib_um[i], 2)} um`)
      .join("  ");
  }
}

function showVibrationStatus(v) {
  if (!v) return;
  const cls = v.state === "estopped" ? "error" : v.level === "ok" ? "ok" : v.level === "warn" ? "warn" : "error";
  badge($("vib-state"), v.state, cls);
  $("vib-status-reason").textContent = v.reason;
  $("vib-status-detail").textContent = `amplitudes [${v.amplitude_um.map((a) => fmt(a, 2)).join(", ")}] um; ` +
    `since ${fmt(v.since_s, 3)} s; windows accepted ${v.accepted}, refused ${v.refused}` +
    (v.event ? `; last event: ${v.event}` : "") + (v.planner_message ? `; planner: ${v.planner_message}` : "");
  const latched = v.estopped;
  $("estop-banner").classList.toggle("hidden", !latched);
  $("btn-reset").classList.toggle("hidden", !latched);
}

function showMove(m) {
  if (!m) return;
  const settle = ui.hello ? ui.hello.settle : { position_um: 10, angle_deg: 0.01 };
  const state = m.status === "settled" ? `<span class="badge ok">settled</span> after ${fmt(m.settled_after_s, 1)} s` :
    `<span class="badge warn">${esc(m.status)}</span> ${fmt(m.elapsed_s, 1)} s` +
    (m.progress !== undefined ? `, progress ${fmt(100 * m.progress, 0)} %` : "");
  $("move-follow").innerHTML = `move: ${state}; <span class="truth">estimated</span> error ` +
    `<b id="move-error">${fmt(m.error_um, 3)} um</b>, ${fmt(m.error_deg, 5)} deg ` +
    `(settled = within ${settle.position_um} um / ${settle.angle_deg} deg for 0.5 s) <span class="stale-label"></span>` +
    (m.reason ? `<br><span class="refusal">${esc(m.reason)}</span>` : "") +
    (ui.frame && ui.frame.vibration && ["ramping_in", "running", "ramping_out"].includes(ui.frame.vibration.state) ?
      " <span class=\"dim\">(the platform is vibrating)</span>" : "");
}

function showNodes(nodes) {
  const body = $("nodes").tBodies[0];
  body.innerHTML = "";
  for (const n of nodes) {
    const tr = body.insertRow();
    const cls = { OK: "ok", WARN: "warn", ERROR: "error", STALE: "stale" }[n.level] || "error";
    const old = n.age_s > 5;
    tr.innerHTML = `<td>${esc(n.name)}</td><td><span class="badge ${old ? "stale" : cls}">${esc(n.level)}</span></td>` +
      `<td>${esc(n.message)}</td><td class="dim">${old ? "stale: " : ""}${fmt(n.age_s, 1)} s ago</td>`;
  }
}

function showEvents(events) {
  const list = $("events");
  const last = list.dataset.last ? Number(list.dataset.last) : 0;
  for (const e of events) {
    if (e.seq <= last) continue;
    const li = document.createElement("li");
    li.className = e.level;
    li.textContent = `${new Date(e.wall * 1000).toLocaleTimeString()} ${e.source}: ${e.text}`;
    list.prepend(li);
    list.dataset.last = e.seq;
  }
}

function showSummary(s, report) {
  const el = $("summary");
  if (s && s.error) el.innerHTML = `vibration from t0 = ${fmt(s.t0_s, 3)} s: <span class="reason">${esc(s.error)}</span>`;
  else if (s) {
    el.className = "";
    el.innerHTML = `vibration t0 = ${fmt(s.t0_s, 3)} s to ${fmt(s.ended_s, 3)} s (started by ${esc(s.source)}), ` +
      `${fmt(s.frequency_hz, 2)} Hz: platform amplitude <b>${fmt(s.measured_amplitude_um, 3)} um</b> ` +
      `(planned ${fmt(s.planned_amplitude_um, 3)} um, error ${fmt(s.amplitude_error_pct, 3)} %), direction error ` +
      `<b>${fmt(s.direction_error_deg, 4)} deg</b> (the controller's estimate); leg phase error <= ` +
      `${fmt(Math.max(...s.leg_phase_error_deg), 3)} deg; leg amplitudes [${s.leg_amplitude_um.map((v) => fmt(v, 2)).join(", ")}] um ` +
      `(planned [${s.leg_amplitude_expected_um.map((v) => fmt(v, 2)).join(", ")}]); force model error (worst leg's RMS / ` +
      `the largest leg's amplitude) <b>${fmt(s.force_error_worst_leg_pct, 3)} %</b>; active ${fmt(s.active_duration_s, 2)} s`;
  }
  const links = (report || []).map((n) => `<a href="/files/report/${encodeURIComponent(n)}" target="_blank">${esc(n)}</a>`);
  $("report").innerHTML = links.length ? `report of the last finished run (beside the MCAP): ${links.join(" ")}` : "";
}

// ---- drawing -----------------------------------------------------------------------------------------
let drawQueued = false;
function requestDraw() { if (!drawQueued) { drawQueued = true; requestAnimationFrame(draw); } }
function draw() {
  drawQueued = false;
  ui.stats.plotDraws++;
  plot($("plot-vib"), [{ rows: ui.series.joints, cols: [1, 2, 3, 4, 5, 6], dash: [] }], "um");
  plot($("plot-force"), [{ rows: ui.series.joints, cols: [7, 8, 9, 10, 11, 12], dash: [] },
    { rows: ui.series.forces, cols: [1, 2, 3, 4, 5, 6], dash: [5, 4] }], "N");
  drawRobot();
}

function plot(canvas, sets, unit) {
  const ctx = canvas.getContext("2d");
  const W = canvas.width, H = canvas.height, L = 52, R = 6, T = 6, B = 18;
  ctx.clearRect(0, 0, W, H);
  let tmax = -Infinity, lo = Infinity, hi = -Infinity;
  for (const s of sets) {
    if (!s.rows.length) continue;
    tmax = Math.max(tmax, s.rows[s.rows.length - 1][0]);
    for (const r of s.rows) for (const c of s.cols) { lo = Math.min(lo, r[c]); hi = Math.max(hi, r[c]); }
  }
  ctx.font = "11px sans-serif";
  ctx.fillStyle = "#6b7280";
  if (!Number.isFinite(tmax)) { ctx.fillText("no data", L + 10, H / 2); return; }
  if (hi - lo < 1e-9) { hi += 1; lo -= 1; }
  const pad = 0.05 * (hi - lo); hi += pad; lo -= pad;
  const t0 = tmax - PLOT_WINDOW_S;
  const x = (t) => L + ((t - t0) / PLOT_WINDOW_S) * (W - L - R);
  const y = (v) => T + (1 - (v - lo) / (hi - lo)) * (H - T - B);
  ctx.strokeStyle = "#e5e7eb";
  ctx.beginPath(); ctx.moveTo(L, y(0)); ctx.lineTo(W - R, y(0)); ctx.stroke();
  ctx.fillText(`${hi.toPrecision(4)} ${unit}`, 2, T + 9);
  ctx.fillText(`${lo.toPrecision(4)} ${unit}`, 2, H - B);
  ctx.fillText(`t = ${tmax.toFixed(2)} s (sim); window ${PLOT_WINDOW_S} s`, L, H - 4);
  for (const s of sets) {
    ctx.setLineDash(s.dash);
    s.cols.forEach((c, k) => {
      ctx.strokeStyle = COLORS[k];
      ctx.lineWidth = 1;
      ctx.beginPath();
      s.rows.forEach((r, i) => (i ? ctx.lineTo(x(r[0]), y(r[c])) : ctx.moveTo(x(r[0]), y(r[c]))));
      ctx.stroke();
    });
  }
  ctx.setLineDash([]);
}

function drawRobot() {
  const f = ui.frame, h = ui.hello;
  const canvas = $("robot"), ctx = canvas.getContext("2d");
  ctx.clearRect(0, 0, canvas.width, canvas.height);
  if (!f || !h) return;
  const pose = f.estimate;
  if (!pose) return;
  const base = h.robot.base_points_mm, top = pose.points_mm;
  const views = [{ name: "top (x-y)", a: 0, b: 1, ox: 110, oy: 118, s: 1.1, flip: true },
    { name: "side (x-z)", a: 0, b: 2, ox: 330, oy: 205, s: 0.95, flip: true }];
  ctx.font = "11px sans-serif";
  for (const v of views) {
    const px = (p) => v.ox + p[v.a] * v.s, py = (p) => v.oy - p[v.b] * v.s;
    ctx.fillStyle = "#6b7280";
    ctx.fillText(v.name, v.ox - 40, 12);
    poly(ctx, base.map((p) => [px(p), py(p)]), "#9ca3af");
    poly(ctx, top.map((p) => [px(p), py(p)]), "#2563eb");
    for (let i = 0; i < 6; i++) {
      ctx.strokeStyle = COLORS[i];
      ctx.lineWidth = 2;
      ctx.beginPath(); ctx.moveTo(px(base[i]), py(base[i])); ctx.lineTo(px(top[i]), py(top[i])); ctx.stroke();
    }
  }
  ctx.lineWidth = 1;
}

function poly(ctx, pts, color) {
  ctx.strokeStyle = color;
  ctx.lineWidth = 1.5;
  ctx.beginPath();
  pts.forEach((p, i) => (i ? ctx.lineTo(p[0], p[1]) : ctx.moveTo(p[0], p[1])));
  ctx.closePath();
  ctx.stroke();
}

function legend() {
  $("legend").innerHTML = COLORS.map((c, i) => `<span style="color:${c}">&#9632; leg ${i + 1}</span>`).join("") +
    `<span class="dim">solid: measured / vib; dashed: estimated</span>`;
}

// ---- watchdog: no frame for 2 s = everything stale ---------------------------------------------------
setInterval(() => {
  if (ui.lastFrameWall && performance.now() - ui.lastFrameWall > 2000) {
    const age = (performance.now() - ui.lastFrameWall) / 1000;
    setLink(`no data for ${age.toFixed(1)} s`, "error");
    for (const el of document.querySelectorAll("[data-stream]")) el.classList.add("stale");
  }
}, 500);

// ---- wiring ------------------------------------------------------------------------------------------
function wire() {
  const checkSoon = debounce(checkPose, 150);
  for (const k of POSE) $(k).addEventListener("input", checkSoon);
  const previewSoon = debounce(previewVibration, 250);
  for (const k of VIB) $(k).addEventListener(k === "frame" || k === "mode" ? "change" : "input", previewSoon);
  $("mode").addEventListener("change", () => {
    $("lbl-acc").classList.toggle("hidden", $("mode").value !== "acceleration");
    $("lbl-amp").classList.toggle("hidden", $("mode").value !== "amplitude");
  });
  $("btn-paper").onclick = () => { setPose(ui.hello.paper_pose); checkPose(); };
  $("btn-home").onclick = () => { setPose(ui.hello.robot.home); checkPose(); };
  $("paste").addEventListener("change", () => {
    const v = $("paste").value.trim().split(/[\s,;]+/).map(Number);
    if (v.length === 6 && v.every(Number.isFinite)) { POSE.forEach((k, i) => ($(k).value = v[i])); checkPose(); }
    else toast("paste 6 numbers: x y z (mm) roll pitch yaw (deg)");
  });
  $("btn-plan").onclick = planPath;
  $("btn-move").onclick = move;
  $("btn-preview").onclick = previewVibration;
  $("btn-start").onclick = startVibration;
  $("btn-stop").onclick = () => trigger("stop", "stop");
  $("btn-estop").onclick = () => trigger("estop", "EMERGENCY STOP");  // never behind a dialog
  $("btn-reset").onclick = () => trigger("reset", "reset");
  legend();
}

wire();
connect();
