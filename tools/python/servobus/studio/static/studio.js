// Servo Studio, the page. The server owns the bus; this page shows its state (pushed over
// /ws) and posts actions to /api/*. Every tab shows the same state.
"use strict";

const $ = (id) => document.getElementById(id);
const S = {
  state: null, regs: [], bauds: [], values: {}, resolution: 10, sample: null,
  plot: { t: [], position: [], goal: [], speed: [], temperature: [], load: [] },
  paused: false, samples: 0, chart: null, plotDirty: false, msgTimer: null,
  traj: [[90, 60], [180, 90], [120, 45]],
};
window.studio = S;  // for the browser tests and the curious

// ---- helpers ----------------------------------------------------------------------

function el(tag, attrs, ...kids) {
  const e = document.createElement(tag);
  for (const [k, v] of Object.entries(attrs || {})) {
    if (k === "class") e.className = v;
    else if (k.startsWith("on")) e.addEventListener(k.slice(2), v);
    else e.setAttribute(k, v);
  }
  for (const k of kids) e.append(k instanceof Node ? k : document.createTextNode(String(k)));
  return e;
}

function say(text, kind) {
  const m = $("message");
  m.textContent = text;
  m.className = "message show " + (kind || "");
  clearTimeout(S.msgTimer);
  if (kind === "ok") S.msgTimer = setTimeout(() => { m.className = "message"; }, 6000);
}

// Every action: JSON (or, for an image, octet-stream: a type no other site may send
// here without the studio's consent). The server checks every value (servobus/values.py)
// and answers a sentence; a setting that would lock the servo out comes back with
// "confirm", and is sent again only if the user says so.
// Actions on one servo name it: the one selected when the user acted. The selection is
// shared by every tab, so without its ID a confirmed write (or anything clicked while
// another tab, or a scan, changed the selection) would go to another servo.
const TARGETED = new Set(["/api/write", "/api/move", "/api/speed", "/api/home", "/api/traj",
  "/api/setid", "/api/reset", "/api/plan", "/api/config/save", "/api/config/restore"]);
async function post(path, body, raw) {
  if (!raw && TARGETED.has(path) && body && !("id" in body) && selected() !== null)
    body = Object.assign({ id: selected() }, body);
  let r;
  try {
    r = await fetch(path, raw ?
      { method: "POST", headers: { "Content-Type": "application/octet-stream" }, body: raw } :
      { method: "POST", headers: { "Content-Type": "application/json" },
        body: JSON.stringify(body || {}) });
  } catch (e) {
    say("The studio does not answer (was it stopped?): " + e, "error");
    return null;
  }
  let j = null;
  try { j = await r.json(); } catch (e) { j = null; }
  if (!j) {
    say("The studio answered HTTP " + r.status + " " + r.statusText + " without a sentence.", "error");
    return null;
  }
  if (j.ok) return j;
  if (j.confirm && !raw) {
    if (await ask("Write it anyway?", j.confirm, "Write it anyway"))
      return post(path, Object.assign({}, body, { confirm: true }));
    say("Not written: " + j.confirm, "");
    return null;
  }
  say(j.error, "error");
  return null;
}

// The dialog: title, text, the button that says yes. Resolves true for yes.
function ask(title, text, yes) {
  $("confirm-title").textContent = title;
  $("confirm-text").textContent = text;
  $("confirm-yes").textContent = yes;
  $("confirm").classList.remove("hidden");
  return new Promise((resolve) => { S.answer = resolve; });
}
function answer(yes) {
  $("confirm").classList.add("hidden");
  if (S.answer) { const r = S.answer; S.answer = null; r(yes); }
}

function selected() { return S.state ? S.state.selected : null; }
function servo(id) { return S.state ? S.state.servos.find((s) => s.id === id) : null; }
function variantName() { const s = servo(selected()); return s ? s.variant : null; }
function who() {
  const s = servo(selected());
  return s ? "ID " + s.id + " (" + s.variant + ")" : "no servo selected";
}

// Physical value of a register's value, as the SDK's Register.format does.
const SCALE = {
  position: [1, "deg"], speed: [1, "deg/s"], dir_speed: [1, "deg/s"],
  accel: [10, "deg/s\u00b2"], delay: [0.5, "ms"], current: [0.1, "A"],
  temperature: [1, "\u00b0C"], resolution: [0.1, "deg/unit"],
};
function physical(reg, v) {
  if (reg.name === "baud_rate" && v !== null && v !== undefined) {
    const s = servo(selected());
    return v === 0 ? " (the variant's default" + (s ? ": " + s.baud + " baud)" : ")") :
      S.bauds[v - 1] ? " (" + S.bauds[v - 1] + " baud)" : "";
  }
  const sc = SCALE[reg.unit];
  if (!sc || v === null || v === undefined) return "";
  let f = sc[0];
  if (["position", "speed", "dir_speed"].includes(reg.unit)) f = S.resolution * 0.1;
  const p = v * f;
  return " (" + (Number.isInteger(p) ? p : p.toFixed(2).replace(/\.?0+$/, "")) + " " + sc[1] + ")";
}

// ---- navigation -------------------------------------------------------------------

function show(panel) {
  for (const b of document.querySelectorAll("nav button"))
    b.classList.toggle("active", b.dataset.panel === panel);
  for (const p of document.querySelectorAll(".panel"))
    p.classList.toggle("active", p.id === "panel-" + panel);
  if (panel === "plot" && S.chart) { S.chart.resize(); S.plotDirty = true; }
  if (window.expertShow) window.expertShow(panel);
  location.hash = panel;
}
for (const b of document.querySelectorAll("nav button"))
  b.addEventListener("click", () => show(b.dataset.panel));

// ---- state from the server ----------------------------------------------------------

function onState(st) {
  const prevSel = S.state ? S.state.selected : undefined;
  S.state = st;
  $("bus-port").textContent = st.port + " \u00b7 " + st.baud + " baud";
  const link = $("link");
  link.textContent = st.link_ok ? "connected" : "disconnected";
  link.className = "link" + (st.link_ok ? "" : " bad");
  if (!st.link_ok) say(st.link, "error");
  else if ($("message").textContent.includes("reconnecting")) say("Connected again to " + st.port + ".", "ok");
  // The selected servo stopped answering its live READs (unplugged, status return level
  // 0, ...): say so, and show no value as if it were live.
  const serr = st.link_ok ? (st.sample_error || "") : "";
  if (serr !== (S.sampleError || "")) {
    S.sampleError = serr;
    if (serr) {
      staleReadouts();
      say("Live values of ID " + st.selected + " stopped: " + serr, "error");
    } else if ($("message").textContent.startsWith("Live values of")) say("Live values again.", "ok");
  }
  // servo picker
  const pick = $("servo-pick");
  const want = st.servos.map((s) => s.id + ":" + s.variant).join(",");
  if (pick.dataset.list !== want) {
    pick.dataset.list = want;
    pick.replaceChildren(el("option", { value: "" }, "(none)"),
      ...st.servos.map((s) => el("option", { value: s.id }, "ID " + s.id + " \u2013 " + s.variant)));
  }
  pick.value = st.selected === null ? "" : String(st.selected);
  const s = servo(st.selected);
  $("servo-summary").textContent = s ? s.variant + ", model " + s.model_hex + ", firmware " +
    s.firmware + ", " + s.baud + " baud" + (st.busy ? " \u00b7 busy: " + st.busy : "") :
    (st.busy ? "busy: " + st.busy : "");
  if (prevSel !== st.selected) {
    S.values = {};
    for (const k of Object.keys(S.plot)) S.plot[k] = [];
    S.samples = 0; S.plotDirty = true;
    renderTable();
  }
  for (const id of ["table-who", "motion-who", "plot-who", "safety-who", "ident-who"])
    $(id).textContent = who();
  if (!$("scan-baud").dataset.set && S.bauds.length) {
    $("scan-baud").value = String(st.baud);
    $("scan-baud").dataset.set = "1";
  }
  renderScan(st);
  renderIds(st);
  if (S.lastUpdate && S.lastUpdate.running && !st.update.running)
    say(st.update.error ? st.update.error : "ID " + st.update.id + " now runs firmware version " +
        st.update.after + " (was " + st.update.before + ").", st.update.error ? "error" : "ok");
  S.lastUpdate = st.update;
  renderFirmware(st);
  const v = S.variants[variantName()];
  const homes = !v || v.photo_switches;
  for (const b of ["home-go", "home-stop"]) $(b).disabled = !homes;
  $("home-note").textContent = homes ? "The arm, wrist and finger move only once homed." :
    "The " + variantName() + " has no photo switches: homing does not apply to it.";
  renderLog(st);
  $("id-new").dispatchEvent(new Event("input"));
}

function renderScan(st) {
  const sc = st.scan;
  $("scan-progress").classList.toggle("show", sc.running || sc.total > 1);
  $("scan-bar").max = Math.max(sc.total, 1);
  $("scan-bar").value = sc.running ? sc.done + 0.5 : sc.total;  // half: this baud under way
  $("scan-text").textContent = sc.running ?
    "scanning at " + sc.baud + " baud (" + (sc.done + 1) + " of " + sc.total + ")\u2026" :
    (sc.total ? "done: " + sc.total + " baud rate" + (sc.total > 1 ? "s" : "") + " scanned" : "");
  $("scan-warning").textContent = sc.warning;
  $("scan-warning").classList.toggle("show", !!sc.warning);
  $("scan-message").textContent = sc.running ? "Scanning\u2026" : sc.message;
  $("scan-notes").replaceChildren(...sc.notes.map((n) => el("li", {}, "note: " + n)));
  for (const b of ["scan-again", "scan-one", "scan-all"]) $(b).disabled = !!st.busy;
  const body = $("scan-table").tBodies[0];
  body.replaceChildren(...st.servos.map((s) => {
    const healthy = s.err === 0;
    const tr = el("tr", { class: s.id === st.selected ? "selected" : "", "data-id": s.id },
      el("td", {}, s.id), el("td", {}, s.variant), el("td", {}, s.model_hex),
      el("td", {}, s.firmware === null ? "?" : s.firmware), el("td", {}, s.baud),
      el("td", { class: healthy ? "health-ok" : "health-bad" }, s.health.join(", ")),
      el("td", {}, el("button", { onclick: () => choose(s.id) },
        s.id === st.selected ? "Selected" : "Select")));
    return tr;
  }));
}

function renderIds(st) {
  const ids = st.ids;
  $("ids-message").textContent = ids.message;
  for (const b of ["ids-list", "ids-separate", "adopt-go"]) $(b).disabled = !!st.busy;
  $("ids-table").tBodies[0].replaceChildren(...ids.rows.map((r) =>
    el("tr", { class: r.duplicate ? "duplicate" : "", "data-uid": r.uid },
      el("td", {}, r.uid), el("td", {}, r.id), el("td", {}, r.variant),
      el("td", {}, "0x" + r.model.toString(16).toUpperCase().padStart(4, "0")),
      el("td", {}, r.baud),
      el("td", { class: r.duplicate ? "health-bad" : "health-ok" },
        r.duplicate ? "DUPLICATE ID" : "ok"))));
}

function renderFirmware(st) {
  const up = st.update;
  const s = servo(st.selected);
  $("fw-id").textContent = s ? s.id : "\u2013";
  $("fw-now").textContent = s ? s.firmware : "\u2013";
  const pct = up.bytes_total ? Math.round(100 * up.bytes / up.bytes_total) : 0;
  $("fw-bar").value = pct;
  $("fw-pct").textContent = pct + " %";
  $("fw-text").textContent = up.id === null ? "No update yet." :
    (up.running ? "Updating ID " + up.id + ": " : "ID " + up.id + ": ") + up.done + "/" +
    up.total + " blocks, " + up.bytes + "/" + up.bytes_total + " bytes of " + up.file +
    (up.running ? "" : up.error ? " \u2014 failed" : up.after !== null ? " \u2014 done" : "");
  $("fw-before").textContent = up.before === null ? "\u2013" : up.before;
  $("fw-after").textContent = up.after === null ? "\u2013" : up.after;
  $("fw-note").textContent = up.note ? "note: " + up.note : "";
  $("fw-error").textContent = up.error;
  for (const b of ["fw-go", "rc-go"]) $(b).disabled = !!st.busy;
}

function renderLog(st) {
  $("log-count").textContent = st.commands;
  $("log-list").replaceChildren(...st.log.slice().reverse().map((e) =>
    el("li", { class: e.ok ? "" : "bad" }, e.t.toFixed(1) + " s  " + e.text)));
}

async function choose(id) {
  if (id === "" || id === null) return;
  const r = await post("/api/select", { id: Number(id) });
  if (r) say("Selected ID " + id + " (" + r.variant + ").", "ok");
}
$("servo-pick").addEventListener("change", (e) => choose(e.target.value));

// ---- scan -------------------------------------------------------------------------

$("scan-again").addEventListener("click", () => post("/api/scan", {}));
$("scan-one").addEventListener("click", () => post("/api/scan", { baud: Number($("scan-baud").value) }));
$("scan-all").addEventListener("click", () => post("/api/scan", { all: true }));

$("ids-list").addEventListener("click", async () => {
  const r = await post("/api/ids", {});
  if (r) say("Listed " + r.count + " servo" + (r.count === 1 ? "" : "s") + " by UID.", "ok");
});
$("ids-separate").addEventListener("click", async () => {
  const r = await post("/api/separate", {});
  if (r) say(r.moves.length ? "Separated: " + r.moves.map((m) => "ID " + m[1] + " \u2192 " +
    m[2]).join(", ") + "." : "Every ID was single: nothing to separate.", "ok");
});
$("adopt-go").addEventListener("click", async () => {
  const text = $("adopt-expect").value.trim();
  const parts = text ? text.split(/[\s,]+/).filter((x) => x) : [];
  if (!parts.length || parts.some((x) => !/^\d+$/.test(x))) {
    say("Give the expected IDs as whole numbers, e.g. 1, 2, 3, 4. Nothing was sent.", "error");
    return;
  }
  const r = await post("/api/adopt", { expect: parts.map(Number) });
  if (r) say("Adopted: UID " + r.uid + " is now ID " + r.id + ".", "ok");
});

// ---- control table ----------------------------------------------------------------

function rangeText(r) {
  return r.min + " \u2026 " + r.max;
}

function renderTable() {
  const body = $("reg-table").tBodies[0];
  const v = variantName();
  body.replaceChildren(...S.regs.map((r) => {
    const applies = !v || r.variants.includes(v);
    const cells = [
      el("td", {}, r.address),
      el("td", { title: r.doc }, r.name),
      el("td", {}, el("span", { class: r.area === "EEPROM" ? "ee" : "ram" }, r.area)),
      el("td", {}, r.access),
      el("td", { title: r.unit_text }, r.unit ? r.unit_text || r.unit : "\u2013"),
      el("td", { class: "range" }, rangeText(r)),
      el("td", { class: "value", id: "val-" + r.name }, applies ? "\u2026" : "n/a on the " + v),
    ];
    const edit = el("td", { class: "edit" });
    if (r.access.includes("W") && applies) {
      const inp = el("input", { id: "in-" + r.name, type: "text", placeholder: String(r.min) });
      const btn = el("button", { id: "set-" + r.name }, "Set");
      const msg = el("div", { class: "msg", id: "msg-" + r.name });
      const go = () => writeReg(r, inp.value, msg);
      btn.addEventListener("click", go);
      inp.addEventListener("keydown", (e) => { if (e.key === "Enter") go(); });
      edit.append(inp, " ", btn, msg);
    }
    cells.push(edit);
    return el("tr", { class: applies ? "" : "na", id: "reg-" + r.name }, ...cells);
  }));
  showValues();
}

function showValues() {
  const vn = variantName();
  for (const r of S.regs) {
    const cell = $("val-" + r.name);
    if (!cell || !(r.name in S.values) || (vn && !r.variants.includes(vn))) continue;
    const v = S.values[r.name];
    cell.textContent = v === null ? (r.access.includes("R") ? "\u2013" : "write-only") :
      v + physical(r, v);
  }
}

// The server checks the value (the SDK's one validator, as servoctl does) before it
// sends anything, and says why it refuses.
async function writeReg(r, text, msg) {
  msg.textContent = "";
  const res = await post("/api/write", { name: r.name, value: text });
  if (!res) { msg.textContent = $("message").textContent; return; }
  S.values[r.name] = res.value;
  showValues();
  say("ID " + selected() + ": " + r.name + " = " + res.value + physical(r, res.value) +
      (r.area === "EEPROM" ? " (kept in flash)" : ""), "ok");
}

// ---- motion -----------------------------------------------------------------------

$("stop").addEventListener("click", async () => {
  if (await post("/api/stop", {})) say("STOP sent: moving speed 0 to every servo.", "ok");
});
// The boxes' text as typed: an empty box is refused by the server, never sent as 0.
$("mv-go").addEventListener("click", async () => {
  const r = await post("/api/move", { goal: $("mv-goal").value, speed: $("mv-speed").value,
    acc: $("mv-acc").value, dec: $("mv-dec").value });
  // a goal outside the angle limits is clamped by the servo: the server says so
  if (r) say(r.note || "Moving ID " + selected() + " to " + $("mv-goal").value + " deg.", r.note ? "" : "ok");
});
$("sp-go").addEventListener("click", async () => {
  if (await post("/api/speed", { speed: $("sp-speed").value }))
    say("ID " + selected() + " turns at " + $("sp-speed").value + " deg/s.", "ok");
});
$("home-go").addEventListener("click", () => post("/api/home", { start: true }));
$("home-stop").addEventListener("click", () => post("/api/home", { start: false }));

function renderTraj() {
  $("traj-table").tBodies[0].replaceChildren(...S.traj.map((p, i) => el("tr", {},
    el("td", {}, i + 1),
    el("td", {}, el("input", { type: "number", value: p[0], step: "any",
      onchange: (e) => { S.traj[i][0] = e.target.value; } })),
    el("td", {}, el("input", { type: "number", value: p[1], step: "any",
      onchange: (e) => { S.traj[i][1] = e.target.value; } })),
    el("td", {}, el("button", { onclick: () => { S.traj.splice(i, 1); renderTraj(); } }, "Remove")))));
}
$("traj-add").addEventListener("click", () => { S.traj.push([0, 60]); renderTraj(); });
$("traj-run").addEventListener("click", async () => {
  const r = await post("/api/traj", { points: S.traj });
  if (r) say("Trajectory of " + S.traj.length + " points written and running." + (r.note ? " " + r.note : ""), r.note ? "" : "ok");
});

// ---- live samples and the plot ----------------------------------------------------

function onSample(m) {
  if (m.id !== selected()) return;
  S.sample = m;
  $("ro-pos").textContent = m.position.toFixed(1) + " deg";
  $("ro-goal").textContent = m.goal.toFixed(1) + " deg";
  $("ro-speed").textContent = m.speed.toFixed(1) + " deg/s";
  $("moving").textContent = m.moving ? "moving" : "still";
  $("ro-homing").textContent = m.homing;
  $("home-status").textContent = m.homing;
  $("home-photo").textContent = "switch 1 " + (m.photo & 1 ? "high" : "low") +
    ", switch 2 " + (m.photo & 2 ? "high" : "low");
  renderFlags(m);
  Object.assign(S.values, m.regs);
  if ($("panel-table").classList.contains("active")) showValues();
  if (!S.paused) {
    S.samples++;
    const P = S.plot;
    P.t.push(m.t); P.position.push(m.position); P.goal.push(m.goal);
    P.speed.push(m.speed); P.temperature.push(m.temperature); P.load.push(m.load);
    if (P.t.length > 1500) for (const k of Object.keys(P)) P[k].shift();
    S.plotDirty = true;
  }
}

function staleReadouts() {
  for (const id of ["ro-pos", "ro-goal", "ro-speed", "moving", "ro-homing", "home-status"])
    $(id).textContent = "\u2013";
  $("safety-flags").replaceChildren(el("li", { class: "health-bad" }, "no live answer"));
  if (S.sample) S.sample = Object.assign({}, S.sample, { rate: 0 });
}

function renderFlags(m) {
  const ok = m.err === 0;
  $("safety-flags").replaceChildren(...(ok ? [el("li", { class: "health-ok" },
    "no protection active")] : m.err_words.map((w) => el("li", { class: "health-bad" }, w))),
    el("li", {}, "temperature now " + (m.temperature === null ? "?" : m.temperature + " \u00b0C")),
    el("li", {}, "brake " + (m.brake ? "on" : "off") + ", sleep " + (m.sleep ? "on" : "off")));
}

const WINDOW_S = 10;
function makeChart() {
  if (typeof Chart === "undefined") {
    $("plot-info").textContent = window.CHART_MISSING || "Chart.js did not load.";
    return;
  }
  const ds = (label, color, axis, dash) => ({ label, borderColor: color, backgroundColor: color,
    data: [], yAxisID: axis, pointRadius: 0, borderWidth: 2, borderDash: dash || [] });
  S.chart = new Chart($("chart"), {
    type: "line",
    data: { datasets: [ds("position (deg)", "#1565c0", "y"), ds("goal (deg)", "#90caf9", "y", [6, 4]),
      ds("speed (deg/s)", "#ef6c00", "y1"), ds("temperature (\u00b0C)", "#c62828", "y2"),
      ds("load (no register)", "#7b1fa2", "y2")] },
    options: {
      animation: false, parsing: false, normalized: true, maintainAspectRatio: false,
      scales: {
        x: { type: "linear", title: { display: true, text: "time (s)" } },
        y: { position: "left", title: { display: true, text: "deg" } },
        y1: { position: "right", title: { display: true, text: "deg/s" }, grid: { drawOnChartArea: false } },
        y2: { position: "right", title: { display: true, text: "\u00b0C" }, grid: { drawOnChartArea: false },
              suggestedMin: 0, suggestedMax: 80 },
      },
      plugins: { legend: { position: "top" } },
    },
  });
}

function drawPlot() {
  const P = S.plot;
  const n = P.t.length;
  const rate = S.sample ? S.sample.rate : 0;
  $("plot-info").textContent = (S.paused ? "paused \u00b7 " : "") + S.samples + " samples \u00b7 " +
    rate.toFixed(1) + " Hz" + (n ? " \u00b7 position " + P.position[n - 1].toFixed(1) + " deg" : "");
  if (!S.chart || !S.plotDirty || !$("panel-plot").classList.contains("active")) return;
  S.plotDirty = false;
  const t1 = n ? P.t[n - 1] : 0;
  let i0 = 0;
  while (i0 < n && P.t[i0] < t1 - WINDOW_S) i0++;
  const keys = ["position", "goal", "speed", "temperature", "load"];
  keys.forEach((k, j) => {
    const d = [];
    for (let i = i0; i < n; i++) if (P[k][i] !== null) d.push({ x: P.t[i], y: P[k][i] });
    S.chart.data.datasets[j].data = d;
  });
  S.chart.options.scales.x.min = Math.max(0, t1 - WINDOW_S);
  S.chart.options.scales.x.max = Math.max(WINDOW_S, t1);
  S.chart.update("none");
}
setInterval(drawPlot, 50);

$("plot-pause").addEventListener("click", () => {
  S.paused = !S.paused;
  $("plot-pause").textContent = S.paused ? "Resume" : "Pause";
  S.plotDirty = true;
});

function download(name, href) {
  const a = el("a", { href, download: name });
  document.body.append(a); a.click(); a.remove();
}
function stamp() { return "servo-" + (selected() ?? "none") + "-" + new Date().toISOString().replace(/[:.]/g, "-"); }
$("plot-csv").addEventListener("click", () => {
  const P = S.plot;
  const rows = ["t_s,position_deg,goal_deg,speed_deg_s,temperature_c,load"];
  for (let i = 0; i < P.t.length; i++)
    rows.push([P.t[i], P.position[i], P.goal[i], P.speed[i], P.temperature[i] ?? "", P.load[i] ?? ""].join(","));
  download(stamp() + ".csv", URL.createObjectURL(new Blob([rows.join("\n") + "\n"], { type: "text/csv" })));
});
$("plot-png").addEventListener("click", () => {
  if (S.chart) download(stamp() + ".png", S.chart.toBase64Image("image/png", 1));
});

// ---- table values -----------------------------------------------------------------

function onTable(m) {
  if (m.id !== selected()) return;
  S.values = m.values;
  S.resolution = m.resolution;
  showValues();
  const v = m.values;
  $("hb-state").textContent = v.heartbeat_enable === null ? "\u2013" : v.heartbeat_enable ? "on" : "off";
  const tl = S.regs.find((r) => r.name === "temperature_limit");
  const cl = S.regs.find((r) => r.name === "current_limit");
  if (tl) $("lim-temp").textContent = v.temperature_limit + physical(tl, v.temperature_limit);
  if (cl) $("lim-cur").textContent = v.current_limit + physical(cl, v.current_limit);
  const bits = $("unload-bits");
  if (!bits.dataset.edited && v.unload_conditions !== null)
    for (const b of bits.querySelectorAll("input")) b.checked = !!(v.unload_conditions & (1 << b.dataset.bit));
}

// ---- safety -----------------------------------------------------------------------

const UNLOAD_BITS = [[0, "over-temperature"], [1, "over-current"], [2, "over-voltage"],
  [3, "under-voltage"], [6, "stall"]];
$("unload-bits").append(...UNLOAD_BITS.map(([b, name]) => el("label", {},
  el("input", { type: "checkbox", "data-bit": b, onchange: () => { $("unload-bits").dataset.edited = "1"; } }),
  " " + name)));
$("unload-save").addEventListener("click", async () => {
  let v = 0;
  for (const b of $("unload-bits").querySelectorAll("input")) if (b.checked) v |= 1 << b.dataset.bit;
  delete $("unload-bits").dataset.edited;
  const r = await post("/api/write", { name: "unload_conditions", value: String(v) });
  if (r) say("Unload conditions saved (" + r.value + ").", "ok");
});
$("clear-unload").addEventListener("click", async () => {
  say("Clearing the unload\u2026 A servo can still see the cause for up to 2 s after it is " +
      "gone: the studio tries again for that long.", "");
  const r = await post("/api/write", { name: "clear_unload", value: "1" });
  if (r) say("Unload cleared" + (r.took > 0.2 ? " after " + r.took + " s (the servo still saw " +
    "the cause until then)." : "."), "ok");
});
async function heartbeat(on) {
  const r = await post("/api/write", { name: "heartbeat_enable", value: on ? "1" : "0" });
  if (r) say(on ? "Heartbeat on: the servo stops 500 ms after the last packet." :
    "Heartbeat off: a motion keeps going if the host goes away.", on ? "ok" : "");
}
$("hb-on").addEventListener("click", () => heartbeat(true));
$("hb-off").addEventListener("click", () => heartbeat(false));

// ---- firmware ---------------------------------------------------------------------

async function sendImage(id, input) {
  const f = input.files[0];
  if (!f) { say("Choose a firmware image file first.", "error"); return; }
  const data = await f.arrayBuffer();
  if (await post("/api/update?id=" + encodeURIComponent(id) + "&file=" + encodeURIComponent(f.name), null, data))
    say("Updating ID " + id + " from " + f.name + "\u2026", "ok");
}
// What the chosen file says it is: the image's info block (docs/update.md: "SRVI",
// length, CRC-32, model, version at 0x100). The server checks it whole before sending.
async function describeImage(input, out, expectModel) {
  const f = input.files[0];
  if (!f) { out.textContent = ""; return; }
  const b = new DataView(await f.slice(0, 0x110).arrayBuffer());
  const magic = b.byteLength >= 0x10C ? String.fromCharCode(b.getUint8(0x100), b.getUint8(0x101),
    b.getUint8(0x102), b.getUint8(0x103)) : "";
  if (magic !== "SRVI") {
    out.textContent = f.name + " is not a firmware image (no SRVI info block at 0x100).";
    out.className = "error";
    return;
  }
  const model = b.getUint16(0x10C, true), version = b.getUint8(0x10E);
  const name = Object.keys(S.variants).find((k) => S.variants[k].model === model);
  let text = f.name + ": " + f.size + " bytes, model 0x" + model.toString(16).toUpperCase().padStart(4, "0") +
    " (" + (name || "unknown") + "), version " + version + ".";
  const bad = expectModel && expectModel !== model;
  if (bad) text += " The selected servo is model 0x" + expectModel.toString(16).toUpperCase() + ": the update will be refused.";
  out.textContent = text;
  out.className = bad ? "error" : "hint";
}
$("fw-file").addEventListener("change", () => {
  const s = servo(selected());
  describeImage($("fw-file"), $("fw-info"), s ? s.model : null);
});
$("rc-file").addEventListener("change", () => describeImage($("rc-file"), $("rc-info"), null));
$("fw-go").addEventListener("click", () => sendImage(selected(), $("fw-file")));
$("rc-go").addEventListener("click", () => sendImage($("rc-id").value, $("rc-file")));

// ---- ID and reset -----------------------------------------------------------------

$("id-new").addEventListener("input", () => {
  const t = $("id-new").value;
  const n = Number(t);
  let text = "";
  if (t === "") text = "IDs are 0\u2013253; the studio PINGs the new ID at every baud the port reaches before it changes anything.";
  else if (!Number.isFinite(n)) text = "'" + t + "' is not a number: IDs are 0\u2013253.";
  else if (!Number.isInteger(n)) text = "ID " + t + " is not a whole number: IDs are 0\u2013253.";
  else if (n < 0 || n > 253) text = "ID " + t + " is outside 0\u2013253.";
  else if (n === selected()) text = "That is its ID already.";
  else {
    const other = servo(n);
    text = other ? "ID " + n + " is taken by the " + other.variant + ": choose another." : "ID " + n + " is free on the last scan.";
  }
  $("id-check").textContent = text;
});
$("id-go").addEventListener("click", async () => {
  const r = await post("/api/setid", { new_id: $("id-new").value });
  if (r) say("The servo answers at ID " + r.id + " now.", "ok");
});
$("reset-go").addEventListener("click", async () => {
  const s = servo(selected());
  if (!s) { say("No servo selected: scan, then pick one.", "error"); return; }
  const one = s.id !== 1 && servo(1);
  const yes = await ask("Factory reset ID " + s.id + " (" + s.variant + ")?",
    "Every setting of this servo goes back to its factory value and its ID becomes 1." +
    (one ? " ID 1 is already used by the " + one.variant + ", so the studio will refuse: " +
      "give that servo another ID first." : ""), "Reset to factory values");
  // the ID asked about, even if the selection changed while the dialog was open
  if (yes && await post("/api/reset", { yes: true, id: s.id })) say("Factory reset done; scanning again.", "ok");
});
$("confirm-no").addEventListener("click", () => answer(false));
$("confirm-yes").addEventListener("click", () => answer(true));
$("log-clear").addEventListener("click", () => post("/api/clear", {}));

// ---- start ------------------------------------------------------------------------

// This tab's name: its register plot traces and its dashboard are its own (another tab
// adding traces or leaving the dashboard does not change this one's).
S.tab = Math.random().toString(36).slice(2, 12) + Date.now().toString(36);
function connect() {
  const ws = new WebSocket((location.protocol === "https:" ? "wss://" : "ws://") + location.host +
    "/ws?tab=" + encodeURIComponent(S.tab));
  ws.onmessage = (e) => {
    const m = JSON.parse(e.data);
    if (m.type === "state") onState(m.state);
    else if (m.type === "sample") onSample(m);
    else if (m.type === "table") onTable(m);
    if (window.expert) window.expert(m);  // console, dashboard, register plot (expert.js)
  };
  ws.onclose = async () => {
    $("link").textContent = "studio stopped";
    $("link").className = "link bad";
    let why = "The studio server stopped or restarted; reconnecting\u2026";
    try {  // a restarted studio has a new token: its answer says where to go
      const r = await fetch("/api/state");
      if (r.status === 403) why = (await r.json()).error;
    } catch (e) { /* stopped: keep trying */ }
    say(why, "error");
    setTimeout(connect, 1000);
  };
  ws.onopen = () => {
    if ($("message").textContent.startsWith("The studio server")) say("", "ok");
    if (window.expertConnected) window.expertConnected();  // a closed socket dropped them
  };
}

(async function start() {
  const reply = await fetch("/api/registers");
  if (!reply.ok) { say((await reply.json()).error, "error"); return; }
  const r = await reply.json();
  S.regs = r.registers;
  S.bauds = r.bauds;
  S.variants = r.variants;
  $("scan-baud").replaceChildren(...S.bauds.map((b) => el("option", { value: b }, b)));
  renderTable();
  renderTraj();
  makeChart();
  connect();
  const h = location.hash.slice(1);
  if (h && $("panel-" + h)) show(h);
})();
