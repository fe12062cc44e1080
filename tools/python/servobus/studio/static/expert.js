// Servo Studio, the expert panels (issue 29): wire console, plot of any register, all
// servos at once, trajectory editor, configuration files. Uses studio.js's helpers
// ($, el, S, post, say, ask, download, selected, servo). Every action goes through the
// server's checks; a setting that locks a servo out asks first (post() does it).
"use strict";

const X = {
  frames: [], conPaused: false, conDirty: false, copied: null,
  traces: [], scope: { t: [], v: {} }, scopePaused: false, scopeChart: null, scopeDirty: false,
  scopeInfo: null, scopeWindow: 10, cursor: null,
  dash: null, dashOn: false,
  te: { points: [[120, 90], [200, 90], [90, 45]], plan: [], measured: [], runAt: null,
        chart: null, drag: null, planTimer: null },
  file: null,
};
S.expert = X;  // for the browser tests

// ---- wire console -----------------------------------------------------------------

const INS = ["PING", "READ", "WRITE", "REG WRITE", "ACTION", "RESET", "START/END",
  "TRAJECTORY WRITE", "TRAJECTORY ACTION", "SYNC WRITE", "CUSTOM", "status", "garbage"];
$("con-ins").append(...INS.map((n) => el("option", { value: n }, n)));

function conShown(f) {
  const id = $("con-id").value.trim();
  if (id !== "" && String(f.id) !== id) return false;
  const ins = $("con-ins").value;
  if (ins && !(f.name === ins || (ins === "status" && f.dir === "rx" && f.name.startsWith("status")))) return false;
  if ($("con-err").checked && !f.error) return false;
  return true;
}

function errText(f) {
  return f.dir === "rx" ? f.err_words.join(", ") : "";
}

function conRow(f) {
  const copy = f.cmd ? el("button", { class: "copy", title: f.cmd, onclick: () => copyCmd(f.cmd) },
    "copy as servoctl") : el("span", { class: "hint" }, f.dir === "tx" ? "no servoctl command" : "");
  return el("tr", { class: (f.error ? "bad " : "") + f.dir, "data-n": f.n },
    el("td", {}, f.n), el("td", {}, f.t.toFixed(4)), el("td", {}, f.dir === "tx" ? "\u2192" : "\u2190"),
    el("td", {}, f.id === null ? "" : f.id), el("td", {}, f.name),
    el("td", { class: "decoded", title: f.hex }, f.summary), el("td", {}, errText(f)),
    el("td", {}, f.answers ? "#" + f.answers : ""), el("td", {}, copy));
}

function copyCmd(cmd) {
  X.copied = cmd;
  $("con-copied").textContent = "Copied: " + cmd;
  if (navigator.clipboard) navigator.clipboard.writeText(cmd).catch(() => { /* shown above */ });
}

function drawConsole() {
  if (!X.conDirty || !$("panel-console").classList.contains("active")) return;
  X.conDirty = false;
  const shown = X.frames.filter(conShown).slice(-300).reverse();
  $("con-table").tBodies[0].replaceChildren(...shown.map(conRow));
  $("con-info").textContent = X.frames.length + " frames" + (X.conPaused ? " (paused: new frames are kept, not shown)" : "");
}
setInterval(drawConsole, 250);

function onFrames(list) {
  if (X.conPaused) { X.held = (X.held || []).concat(list); return; }
  const last = X.frames.length ? X.frames[X.frames.length - 1].n : 0;
  if (list.length && list[0].n <= last) {  // the record fetched at start, after pushes
    const seen = new Set(X.frames.map((f) => f.n));
    X.frames.push(...list.filter((f) => !seen.has(f.n)));
    X.frames.sort((a, b) => a.n - b.n);
  } else X.frames.push(...list);
  if (X.frames.length > 4000) X.frames.splice(0, X.frames.length - 4000);
  X.conDirty = true;
}
for (const id of ["con-id", "con-ins", "con-err"])
  $(id).addEventListener(id === "con-id" ? "input" : "change", () => { X.conDirty = true; });
$("con-pause").addEventListener("click", () => {
  X.conPaused = !X.conPaused;
  $("con-pause").textContent = X.conPaused ? "Resume" : "Pause";
  if (!X.conPaused && X.held) { const h = X.held; X.held = null; onFrames(h); }
  X.conDirty = true;
});
function csvField(s) { s = String(s ?? ""); return /[",\n]/.test(s) ? '"' + s.replace(/"/g, '""') + '"' : s; }
$("con-csv").addEventListener("click", () => {
  const rows = ["n,t_s,direction,id,instruction,decoded,err,answers,hex,servoctl"];
  for (const f of X.frames.filter(conShown))
    rows.push([f.n, f.t, f.dir, f.id ?? "", f.name, f.summary, errText(f), f.answers ?? "", f.hex, f.cmd ?? ""].map(csvField).join(","));
  download("wire-" + Date.now() + ".csv", URL.createObjectURL(new Blob([rows.join("\n") + "\n"], { type: "text/csv" })));
});
$("con-hex").addEventListener("click", () => {
  const rows = X.frames.filter(conShown).map((f) => f.t.toFixed(4) + " " + (f.dir === "tx" ? ">" : "<") + " " + f.hex);
  download("wire-" + Date.now() + ".hex.txt", URL.createObjectURL(new Blob([rows.join("\n") + "\n"], { type: "text/plain" })));
});
async function conSend() {
  const text = $("con-entry").value;
  $("con-answer").textContent = "";
  const r = await post("/api/console", { text });
  if (!r) { $("con-answer").textContent = "Refused: " + $("message").textContent; return; }
  const lines = r.frames.map((f) => (f.dir === "tx" ? "\u2192 " : "\u2190 ") + "#" + f.n + " ID " + f.id + " " + f.name +
    (f.answers ? " (answers #" + f.answers + ")" : "") + ": " + f.summary + (f.dir === "rx" ? " \u2014 ERR: " + errText(f) : ""));
  $("con-answer").textContent = (r.output ? r.output.trim() + "\n" : "") + lines.join("\n") + (r.error ? "\n" + r.error : "");
}
$("con-send").addEventListener("click", conSend);
$("con-entry").addEventListener("keydown", (e) => { if (e.key === "Enter") conSend(); });

// ---- plot any register --------------------------------------------------------------

const UNITS = { position: "deg", speed: "deg/s", dir_speed: "deg/s", accel: "deg/s\u00b2",
  delay: "ms", current: "A", temperature: "\u00b0C", resolution: "deg/unit" };
function regUnit(name) { const r = S.regs.find((x) => x.name === name); return (r && UNITS[r.unit]) || "value"; }
const COLORS = ["#1f77b4", "#d62728", "#2ca02c", "#ff7f0e", "#9467bd", "#8c564b", "#e377c2",
  "#7f7f7f", "#bcbd22", "#17becf", "#000000", "#aa6600"];

function renderScopePicker() {
  if (!S.state) return;
  const want = S.state.servos.map((s) => s.id).join(",");
  const box = $("scope-servos");
  if (box.dataset.list === want) return;
  box.dataset.list = want;
  box.replaceChildren("Servos ", ...S.state.servos.map((s) => el("label", {},
    el("input", { type: "checkbox", class: "scope-id", value: s.id }), " " + s.id + " ")));
}

async function applyTraces() {
  const r = await post("/api/scope", { tab: S.tab, picks: X.traces.map((k) => ({ id: Number(k.split(".")[0]), register: k.split(".")[1] })) });
  if (!r) return;
  X.scope = { t: [], v: {} };
  X.scopeInfo = null;
  makeScopeChart();
  $("scope-traces").replaceChildren(...X.traces.map((k) => el("li", {}, "ID " + k.replace(".", ": ") +
    " (" + regUnit(k.split(".")[1]) + ") ", el("button", { onclick: () => { X.traces = X.traces.filter((x) => x !== k); applyTraces(); } }, "remove"))));
  say(X.traces.length ? X.traces.length + " traces in " + r.reads.length + " READ" + (r.reads.length > 1 ? "s" : "") + " per cycle." : "No traces: the register plot reads nothing.", "ok");
}
$("scope-add").addEventListener("click", () => {
  const ids = [...document.querySelectorAll(".scope-id:checked")].map((b) => b.value);
  if (!ids.length) { say("Tick one or more servos first.", "error"); return; }
  for (const id of ids) { const k = id + "." + $("scope-reg").value; if (!X.traces.includes(k)) X.traces.push(k); }
  applyTraces();
});
$("scope-clear").addEventListener("click", () => { X.traces = []; applyTraces(); });

function makeScopeChart() {
  if (typeof Chart === "undefined") return;
  if (X.scopeChart) X.scopeChart.destroy();
  const units = [...new Set(X.traces.map((k) => regUnit(k.split(".")[1])))];
  const scales = { x: { type: "linear", title: { display: true, text: "time (s)" } } };
  units.forEach((u, i) => { scales["y" + i] = { type: "linear", position: i % 2 ? "right" : "left", title: { display: true, text: u } }; });
  X.scopeChart = new Chart($("scope-chart"), {
    type: "line",
    data: { datasets: X.traces.map((k, i) => ({ label: "ID " + k.replace(".", " "), data: [], borderColor: COLORS[i % 12],
      pointRadius: 0, borderWidth: 1.5, yAxisID: "y" + units.indexOf(regUnit(k.split(".")[1])) })) },
    options: { animation: false, responsive: true, maintainAspectRatio: false, parsing: false, scales },
  });
  X.scopeDirty = true;
}

function onScope(m) {
  X.scopeInfo = m;
  if (X.scopePaused) return;
  X.scope.t.push(m.t);
  for (const k of X.traces) (X.scope.v[k] = X.scope.v[k] || []).push(k in m.v ? m.v[k] : null);
  X.scopeDirty = true;
}

function scopeRange() {
  const t = X.scope.t;
  const t1 = X.viewEnd ?? (t.length ? t[t.length - 1] : 0);
  return [X.scopeWindow ? Math.max(t.length ? t[0] : 0, t1 - X.scopeWindow) : (t.length ? t[0] : 0), t1];
}

function drawScope() {
  const i = X.scopeInfo;
  $("scope-info").textContent = X.traces.length ? X.scope.t.length + " samples \u00b7 " + (i ? i.rate : 0) +
    " Hz achieved \u00b7 wire limit " + (i ? i.wire_hz : "?") + " Hz for " + (i ? i.reads : "?") + " READs a cycle" +
    (X.scopePaused ? " \u00b7 paused" : "") : "Pick servos and a register, then Add trace.";
  if (!X.scopeDirty || !X.scopeChart || !$("panel-scope").classList.contains("active")) return;
  X.scopeDirty = false;
  const [a, b] = scopeRange();
  X.traces.forEach((k, j) => {
    const d = [];
    const v = X.scope.v[k] || [];
    for (let n = 0; n < X.scope.t.length; n++) if (X.scope.t[n] >= a && X.scope.t[n] <= b && v[n] !== null && v[n] !== undefined) d.push({ x: X.scope.t[n], y: v[n] });
    if (X.scopeChart.data.datasets[j]) X.scopeChart.data.datasets[j].data = d;
  });
  X.scopeChart.options.scales.x.min = a;
  X.scopeChart.options.scales.x.max = Math.max(b, a + 0.1);
  X.scopeChart.update("none");
}
setInterval(drawScope, 100);

$("scope-pause").addEventListener("click", () => {
  X.scopePaused = !X.scopePaused;
  if (!X.scopePaused) X.viewEnd = null;
  $("scope-pause").textContent = X.scopePaused ? "Resume" : "Pause";
  X.scopeDirty = true;
});
$("scope-window").addEventListener("change", () => { X.scopeWindow = Number($("scope-window").value); X.scopeDirty = true; });
$("scope-chart").addEventListener("wheel", (e) => {
  e.preventDefault();
  X.scopeWindow = Math.max(0.5, (X.scopeWindow || 60) * (e.deltaY > 0 ? 1.25 : 0.8));
  X.scopeDirty = true;
}, { passive: false });
$("scope-chart").addEventListener("mousemove", (e) => {
  if (!X.scopeChart || !X.scope.t.length) return;
  const t = X.scopeChart.scales.x.getValueForPixel(e.offsetX);
  let n = X.scope.t.findIndex((x) => x >= t);
  if (n < 0) n = X.scope.t.length - 1;
  X.cursor = { t: X.scope.t[n], values: Object.fromEntries(X.traces.map((k) => [k, (X.scope.v[k] || [])[n]])) };
  $("scope-cursor").textContent = "t = " + X.scope.t[n].toFixed(3) + " s: " + X.traces.map((k) =>
    "ID " + k.replace(".", " ") + " = " + ((X.scope.v[k] || [])[n] ?? "\u2013") + " " + regUnit(k.split(".")[1])).join(", ");
});
$("scope-csv").addEventListener("click", () => {
  const rows = ["t_s," + X.traces.map((k) => "id" + k.replace(".", "_") + "_" + regUnit(k.split(".")[1]).replace(/[^a-z]/gi, "")).join(",")];
  for (let n = 0; n < X.scope.t.length; n++) rows.push([X.scope.t[n], ...X.traces.map((k) => (X.scope.v[k] || [])[n] ?? "")].join(","));
  download("registers-" + Date.now() + ".csv", URL.createObjectURL(new Blob([rows.join("\n") + "\n"], { type: "text/csv" })));
});
$("scope-png").addEventListener("click", () => { if (X.scopeChart) download("registers-" + Date.now() + ".png", X.scopeChart.toBase64Image("image/png", 1)); });

// ---- all servos -----------------------------------------------------------------------

function onDash(m) {
  X.dash = m;
  $("dash-info").textContent = m.rows.length + " servos \u00b7 " + m.rate + " Hz achieved \u00b7 wire limit " + m.wire_hz + " Hz for one READ of each";
  const body = $("dash-table").tBodies[0];
  for (const r of m.rows) {
    let tr = body.querySelector("tr[data-id='" + r.id + "']");
    if (!tr) {
      tr = el("tr", { "data-id": r.id }, el("td", {}, el("input", { type: "checkbox", class: "dash-pick", value: r.id })),
        ...["id", "variant", "position", "speed", "temperature", "err", "moving", "mode"].map((k) => el("td", { class: "d-" + k })),
        el("td", {}, el("input", { type: "number", class: "dash-goal", id: "dash-goal-" + r.id, step: "any", size: 6 })));
      body.append(tr);
    }
    const cell = (k, v) => { tr.querySelector(".d-" + k).textContent = v; };
    cell("id", r.id);
    if (r.error) {  // no answer this cycle: no value shown as if it were live
      for (const k of ["position", "speed", "temperature", "moving", "mode"]) cell(k, "\u2013");
      cell("err", r.error); tr.classList.add("bad"); continue;
    }
    cell("variant", r.variant); cell("position", r.position + " deg"); cell("speed", r.speed + " deg/s");
    cell("temperature", r.temperature + " \u00b0C"); cell("err", r.err_words.join(", "));
    cell("moving", r.moving ? "moving" : "still"); cell("mode", r.mode);
    tr.classList.toggle("bad", r.err !== 0);
  }
  for (const tr of [...body.rows]) if (!m.rows.some((r) => String(r.id) === tr.dataset.id)) tr.remove();
}
$("dash-go").addEventListener("click", async () => {
  const goals = {};
  for (const b of document.querySelectorAll(".dash-pick:checked")) goals[b.value] = $("dash-goal-" + b.value).value;
  const r = await post("/api/group", { goals, speed: $("dash-speed").value, how: $("dash-how").value });
  if (r) say("IDs " + r.ids.join(", ") + " started together." + (r.note ? " " + r.note : ""), r.note ? "" : "ok");
});

// ---- trajectory editor ------------------------------------------------------------------

function teArrivals() {
  // when the plan reaches each point (the first time after the previous one's)
  const out = [];
  let n = 0;
  for (const [a] of X.te.points) {
    while (n < X.te.plan.length - 1 && Math.abs(X.te.plan[n][1] - a) > 0.6) n++;
    out.push(X.te.plan.length ? X.te.plan[n][0] : out.length);
  }
  return out;
}

function drawTe() {
  if (!X.te.chart) return;
  const arr = teArrivals();
  X.te.chart.data.datasets[0].data = X.te.points.map((p, i) => ({ x: arr[i], y: p[0] }));
  X.te.chart.data.datasets[1].data = X.te.plan.map(([t, p]) => ({ x: t, y: p }));
  X.te.chart.data.datasets[2].data = X.te.measured.map(([t, p]) => ({ x: t, y: p }));
  X.te.chart.update("none");
  $("te-table").tBodies[0].replaceChildren(...X.te.points.map((p, i) => el("tr", {}, el("td", {}, i + 1),
    el("td", {}, el("input", { type: "number", value: p[0], step: "any", class: "te-angle", onchange: (e) => { p[0] = Number(e.target.value); plan(); } })),
    el("td", {}, el("input", { type: "number", value: p[1], step: "any", class: "te-speed", onchange: (e) => { p[1] = Number(e.target.value); plan(); } })),
    el("td", {}, el("button", { onclick: () => { X.te.points.splice(i, 1); plan(); } }, "remove")))));
}

function plan() {
  clearTimeout(X.te.planTimer);
  X.te.planTimer = setTimeout(async () => {
    if (!X.te.points.length || selected() === null) { X.te.plan = []; drawTe(); return; }
    const r = await post("/api/plan", { points: X.te.points });
    if (r) { X.te.plan = r.profile; $("te-info").textContent = "planned: " + r.duration.toFixed(2) + " s" + (r.note ? ". " + r.note : ""); }
    drawTe();
  }, 150);
}

function makeTeChart() {
  if (typeof Chart === "undefined") return;
  X.te.chart = new Chart($("te-chart"), {
    type: "scatter",
    data: { datasets: [
      { label: "points", data: [], pointRadius: 7, backgroundColor: "#d62728" },
      { label: "planned", data: [], showLine: true, pointRadius: 0, borderColor: "#1f77b4", borderWidth: 2 },
      { label: "measured", data: [], showLine: true, pointRadius: 0, borderColor: "#2ca02c", borderWidth: 1.5 }] },
    options: { animation: false, responsive: true, maintainAspectRatio: false, parsing: false,
      scales: { x: { type: "linear", title: { display: true, text: "time (s)" } },
        y: { type: "linear", title: { display: true, text: "position (deg)" } } } },
  });
  const c = $("te-chart");
  c.addEventListener("mousedown", (e) => {
    const arr = teArrivals();
    const ch = X.te.chart;
    const i = X.te.points.findIndex((p, k) => Math.hypot(ch.scales.x.getPixelForValue(arr[k]) - e.offsetX,
      ch.scales.y.getPixelForValue(p[0]) - e.offsetY) < 10);
    if (i >= 0) { X.te.drag = i; return; }
    const angle = Math.round(ch.scales.y.getValueForPixel(e.offsetY));
    const t = ch.scales.x.getValueForPixel(e.offsetX);
    let at = arr.findIndex((x) => x > t);
    if (at < 0) at = X.te.points.length;
    X.te.points.splice(at, 0, [Math.max(0, angle), Number($("te-speed").value) || 90]);
    plan();
  });
  c.addEventListener("mousemove", (e) => {
    if (X.te.drag === null) return;
    X.te.points[X.te.drag][0] = Math.max(0, Math.round(X.te.chart.scales.y.getValueForPixel(e.offsetY)));
    drawTe();
  });
  window.addEventListener("mouseup", () => { if (X.te.drag !== null) { X.te.drag = null; plan(); } });
}
$("te-clear").addEventListener("click", () => { X.te.points = []; X.te.measured = []; plan(); });
$("te-run").addEventListener("click", async () => {
  await new Promise((res) => { plan(); setTimeout(res, 400); });
  X.te.measured = [];
  X.te.runAt = null;
  const r = await post("/api/traj", { points: X.te.points });
  if (r) { X.te.runAt = "next"; say("Trajectory of " + X.te.points.length + " points sent and running." + (r.note ? " " + r.note : ""), r.note ? "" : "ok"); }
});
function onSampleTe(m) {
  if (X.te.runAt === null || m.id !== selected()) return;
  if (X.te.runAt === "next") X.te.runAt = m.t;
  const t = m.t - X.te.runAt;
  if (t > (X.te.plan.length ? X.te.plan[X.te.plan.length - 1][0] + 2 : 10)) { X.te.runAt = null; return; }
  X.te.measured.push([t, m.position]);
  if ($("panel-trajed").classList.contains("active")) drawTe();
}

// ---- configuration files ------------------------------------------------------------------

function renderCfgSources() {
  if (!S.state) return;
  const want = S.state.servos.map((s) => s.id).join(",") + (X.file ? ",file" : "");
  for (const id of ["cfg-a", "cfg-b"]) {
    const sel = $(id);
    if (sel.dataset.list === want) continue;
    const keep = sel.value;
    sel.dataset.list = want;
    sel.replaceChildren(...S.state.servos.map((s) => el("option", { value: s.id }, "ID " + s.id + " (" + s.variant + ")")),
      ...(X.file ? [el("option", { value: "file" }, "file " + X.file.name)] : []));
    if (keep) sel.value = keep;
  }
}
$("cfg-save").addEventListener("click", async () => {
  const r = await post("/api/config/save", {});
  if (!r) return;
  X.saved = r.config;
  download("servo-" + r.config.saved_from_id + "-" + r.config.variant + ".json",
    URL.createObjectURL(new Blob([JSON.stringify(r.config, null, 2) + "\n"], { type: "application/json" })));
  $("cfg-result").textContent = "Saved ID " + r.config.saved_from_id + " (" + r.config.variant + ", firmware " +
    r.config.firmware_version + "): " + Object.keys(r.config.settings).length + " settings.";
});
$("cfg-file").addEventListener("change", async () => {
  const f = $("cfg-file").files[0];
  if (!f) return;
  try { X.file = { name: f.name, doc: JSON.parse(await f.text()) }; } catch (e) { say(f.name + " is not JSON: " + e, "error"); X.file = null; }
  renderCfgSources();
});
$("cfg-restore").addEventListener("click", async () => {
  if (!X.file) { say("Choose a configuration file first.", "error"); return; }
  const r = await post("/api/config/restore", { config: X.file.doc, with_id: $("cfg-with-id").checked, with_baud: $("cfg-with-baud").checked });
  if (!r) return;
  const n = Object.keys(r.changes).length;
  $("cfg-result").textContent = n ? "Restored " + n + " settings in " + r.writes + " WRITEs: " + Object.entries(r.changes).map(([k, v]) => k + " = " + v).join(", ") + "." :
    "ID " + selected() + " already has these settings: nothing written.";
  say($("cfg-result").textContent, "ok");
});
$("cfg-diff").addEventListener("click", async () => {
  const side = (v) => v === "file" ? X.file.doc : Number(v);
  const r = await post("/api/config/diff", { a: side($("cfg-a").value), b: side($("cfg-b").value) });
  if (!r) return;
  $("cfg-ha").textContent = $("cfg-a").selectedOptions[0].textContent;
  $("cfg-hb").textContent = $("cfg-b").selectedOptions[0].textContent;
  $("cfg-table").tBodies[0].replaceChildren(...r.rows.map(([k, a, b]) => el("tr", {}, el("td", {}, k), el("td", {}, a ?? "\u2013"), el("td", {}, b ?? "\u2013"))));
  $("cfg-result").textContent = r.rows.length ? r.rows.length + " differences." : "The same settings.";
});

// ---- wiring ---------------------------------------------------------------------------

window.expert = (m) => {
  if (m.type === "frames") onFrames(m.frames);
  else if (m.type === "scope") onScope(m);
  else if (m.type === "dash") onDash(m);
  else if (m.type === "sample") onSampleTe(m);
  else if (m.type === "state") {
    renderScopePicker(); renderCfgSources();
    for (const id of ["trajed-who", "config-who"]) $(id).textContent = who();
    if (m.state.selected !== X.lastSel) { X.lastSel = m.state.selected; plan(); }
  }
};
window.expertShow = (panel) => {
  const on = panel === "dash";
  if (on !== X.dashOn) { X.dashOn = on; post("/api/dashboard", { on, tab: S.tab }); }
  if (panel === "console") X.conDirty = true;
  if (panel === "scope") { if (X.scopeChart) X.scopeChart.resize(); X.scopeDirty = true; }
  if (panel === "trajed") { if (X.te.chart) X.te.chart.resize(); plan(); }
};
// The WebSocket (re)opened: the server forgot this tab's traces and dashboard when the
// old one closed, so they are asked for again (nothing to ask for on the first open).
window.expertConnected = () => {
  if (X.connectedOnce) {
    if (X.traces.length) post("/api/scope", { tab: S.tab, picks: X.traces.map((k) => ({ id: Number(k.split(".")[0]), register: k.split(".")[1] })) });
    if (X.dashOn) post("/api/dashboard", { on: true, tab: S.tab });
  }
  X.connectedOnce = true;
};
(async function startExpert() {
  const r = await fetch("/api/frames");
  if (r.ok) onFrames((await r.json()).frames);
  const wait = () => new Promise((res) => setTimeout(res, 50));
  while (!S.regs.length) await wait();
  $("scope-reg").replaceChildren(...S.regs.filter((x) => x.access.includes("R")).map((x) => el("option", { value: x.name }, x.address + " " + x.name)));
  makeScopeChart();
  makeTeChart();
  drawTe();
})();
