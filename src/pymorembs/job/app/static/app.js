// The page of `pymorembs app`: a job editor. `job` is the job file as an object (the same
// tables and keys as the TOML); every change is sent to the server, which writes the TOML and
// checks it with the job parser of `pymorembs reduce`. Every list of kinds and every form comes
// from the job's schema the server serves (GET /api/schema): none is written here.
"use strict";
const $ = (id) => document.getElementById(id);
const app = { job: null, schema: null, methods: {}, exports: { kinds: [], default: [] }, scene: null,
  viewer: null, picking: false, selection: null, results: null, shapeCache: {} };
window.app = app;

async function api(path, body) {
  const init = body === undefined ? {} : { method: "POST", body: JSON.stringify(body),
    headers: { "Content-Type": "application/json" } };
  const response = await fetch(path, init);
  const data = await response.json();
  if (!response.ok) throw new Error(data.error || response.statusText);
  return data;
}
function el(tag, attrs, ...children) {
  const node = document.createElement(tag);
  for (const [k, v] of Object.entries(attrs || {})) {
    if (k.startsWith("on")) node.addEventListener(k.slice(2), v);
    else if (k === "text") node.textContent = v;
    else node.setAttribute(k, v);
  }
  for (const c of children) node.append(c);
  return node;
}
const numbers = (text) => String(text).split(/[\s,;]+/).filter((s) => s !== "").map(Number);
const fmt = (x) => (x === null || x === undefined) ? "–" : Number(x).toPrecision(4);
// the schema's parameters of a kind (interface, damping, frame ...), and a table key's default
const kindParameters = (list, kind) => (app.schema.kinds[list][kind] || []);
const tableDefault = (table, key) => app.schema.tables[table].find((k) => k.name === key).default;
function kindOptions(id, list) {
  const kinds = Object.keys(app.schema.kinds[list]).map((k) => el("option", { value: k, text: k }));
  $(id).append(...kinds);
}
function parameterInputs(box, list, kind, attrs) {
  for (const p of kindParameters(list, kind)) {
    const title = `${p.meaning}${p.unit ? ` [${p.unit}]` : ""}${p.required ? ", required" : ""}`;
    box.append(el("label", { title }, ` ${p.name} `, el("input", { "data-key": p.name, ...attrs })), " ");
  }
}
function busy(text) { $("busy").textContent = text || ""; }
function fail(error) { $("job-error").textContent = String(error.message || error); busy(""); }

// ---- the job, sent and shown ----------------------------------------------------------------
let pending = null;
function changed() {
  clearTimeout(pending);
  pending = setTimeout(async () => {
    try { show(await api("/api/job", { job: app.job })); } catch (e) { fail(e); }
  }, 120);
}
function show(state, redraw = true) {  // redraw false: a new scene comes, decorated then
  app.job = state.job;
  if (state.decorations) { app.decorations = state.decorations; if (redraw) decorate(); }
  $("toml").textContent = state.toml;
  $("job-error").textContent = state.error;
  $("run").disabled = Boolean(state.error) || (state.run && state.run.state === "running");
  renderLists();
}

function renderLists() {
  const job = app.job;
  const list = $("interfaces"); list.replaceChildren();
  (job.interface || []).forEach((item, k) => {
    const how = item.cylinder ? `cylinder r = ${item.cylinder.radius}` :
      item.box ? "box" : `${(item.nodes || []).length} nodes`;
    list.append(el("li", {}, `node ${item.node}: ${item.kind}, ${how} `,
      el("button", { text: "remove", onclick: () => { job.interface.splice(k, 1); changed(); } })));
  });
  const ports = $("ports"); ports.replaceChildren();
  for (const key of ["inputs", "outputs"]) {
    (job[key] || []).forEach((p, k) => ports.append(el("li", {}, `${key.slice(0, -1)} node ${p.node}: ${p.directions} `,
      el("button", { text: "remove", onclick: () => { job[key].splice(k, 1); changed(); } }))));
  }
  const frame = job.frame || {};
  $("frame-type").value = frame.type || tableDefault("frame", "type");
  $("frame-node").value = frame.node ?? "";
  const band = job.band || {};
  $("band-fmin").value = band.f_min_hz ?? 0; $("band-fmax").value = band.f_max_hz ?? "";
  $("band-points").value = band.points ?? tableDefault("band", "points");
  $("band-reference").value = band.reference || tableDefault("band", "reference");
  renderReductions();
  renderExports();
}

// ---- model ------------------------------------------------------------------------------------
async function openModel(request) {
  busy("opening…");
  try {
    const state = await api("/api/open", request);
    $("model-name").textContent = `${state.model.name}: ${state.model.n_dof.toLocaleString()} dofs, ${state.model.n_nodes.toLocaleString()} nodes`;
    show(state, false);
    app.selection = null; $("selection").textContent = "Nothing selected."; $("add-interface").disabled = true;
    app.scene = await api("/api/scene");
    startViewer();
    busy("");
    loadFacts();
  } catch (e) { fail(e); }
}
async function loadFacts() {
  $("facts").textContent = "computing the lowest eigenfrequencies…";
  try {
    const f = await api("/api/facts");
    if (f.error) { $("facts").textContent = f.error; return; }
    const hz = f.eigenfrequencies_hz.slice(f.rigid_body_modes, f.rigid_body_modes + 8).map((x) => x.toFixed(1)).join(", ");
    $("facts").replaceChildren(el("table", {},
      el("tr", {}, el("td", { text: "dofs" }), el("td", { text: `${f.n_dof} (${f.n_independent} independent, ${f.n_dependent} dependent, ${f.n_fixed} fixed)` })),
      el("tr", {}, el("td", { text: "nodes" }), el("td", { text: String(f.n_nodes) })),
      el("tr", {}, el("td", { text: "rigid-body modes" }), el("td", { text: String(f.rigid_body_modes) })),
      el("tr", {}, el("td", { text: "first modes [Hz]" }), el("td", { id: "first-modes", text: hz })),
      el("tr", {}, el("td", { text: "surface" }), el("td", { text: f.surface || "none (points)" }))));
  } catch (e) { $("facts").textContent = String(e.message); }
}

// ---- 3D view ----------------------------------------------------------------------------------
function startViewer() {
  const canvas = $("canvas");
  if (typeof window.PymorembsViewer !== "function") {
    $("viewer-note").textContent = "3D viewer not available (viewer.js missing).";
    return;
  }
  if (app.viewer) app.viewer.setScene(app.scene);
  else app.viewer = new window.PymorembsViewer(canvas, app.scene);
  decorate();
  app.viewer.render();
}
// The job's frame triad and interface nodes (with their coupled nodes) in the 3D view, as the
// server places them (state.decorations); the view, the shape and a selection stay.
function decorate() {
  const d = app.decorations;
  if (!app.viewer || !d) return;
  app.viewer.setDecorations({ frame: d.frame, interfaces: d.interfaces });
  $("viewer-note").textContent = (d.notes || []).join(" ");
  $("canvas").dataset.decorations = `${d.frame ? 1 : 0},${d.interfaces.length}`;
}
function highlight(rows) {
  if (!app.viewer) return;
  app.viewer.clearHighlight();
  if (rows && rows.length) app.viewer.highlight(rows, [1.0, 0.45, 0.0]);
  app.viewer.render();
}
let down = null;
$("canvas").addEventListener("mousedown", (e) => { down = [e.clientX, e.clientY]; });
$("canvas").addEventListener("mouseup", async (e) => {
  if (!app.picking || !down || !app.viewer || e.button !== 0) return;
  const moved = Math.hypot(e.clientX - down[0], e.clientY - down[1]);
  if (moved > 4) return; // a drag rotates, a click picks
  const triangle = app.viewer.pickTriangle(e.clientX, e.clientY);
  const node = triangle === null ? app.viewer.pickNode(e.clientX, e.clientY) : null;
  if (triangle === null && node === null) return;
  try {
    const picked = await api("/api/pick", { triangle, node, max_angle_deg: Number($("pick-angle").value) || 30 });
    selected(picked, "picked");
  } catch (err) { $("selection").textContent = err.message; }
});
function selected(sel, how) {
  app.selection = sel;
  const where = sel.radius ? `a round hole, radius ${sel.radius}, centre ${sel.position.map((x) => +x.toPrecision(6)).join(", ")}` :
    sel.position ? `centroid ${sel.position.map((x) => +x.toPrecision(6)).join(", ")}` : "";
  $("selection").textContent = `${how}: ${sel.count} nodes ${where}`;
  $("selection").dataset.count = sel.count;
  if (!$("iface-node").value) $("iface-node").value = sel.free_id;
  $("add-interface").disabled = false;
  highlight(sel.rows);
}
$("pick-mode").onclick = () => {
  app.picking = !app.picking;
  $("pick-mode").classList.toggle("on", app.picking);
  $("canvas").classList.toggle("picking", app.picking);
};
$("select-numbers").onclick = async () => {
  const request = {};
  if ($("cyl-point").value) {
    request.cylinder = { point: numbers($("cyl-point").value), direction: numbers($("cyl-direction").value || "0 0 1"),
      radius: Number($("cyl-radius").value) };
    if ($("cyl-tolerance").value) request.cylinder.tolerance = Number($("cyl-tolerance").value);
  }
  if ($("box-min").value) request.box = { min: numbers($("box-min").value), max: numbers($("box-max").value) };
  if ($("sel-nodes").value) request.nodes = numbers($("sel-nodes").value);
  try {
    const sel = await api("/api/select", request);
    const selection = {};
    if (request.nodes) selection.nodes = request.nodes;
    if (request.cylinder) selection.cylinder = request.cylinder;
    if (request.box) selection.box = request.box;
    const pos = app.scene.positions, rows = sel.rows, c = [0, 0, 0];
    for (const r of rows) for (let k = 0; k < 3; k++) c[k] += pos[3 * r + k] / rows.length;
    selected({ ...sel, selection, position: request.cylinder ? request.cylinder.point : c, radius: null }, "selected");
  } catch (e) { $("selection").textContent = e.message; }
};
$("iface-kind").onchange = () => {
  const box = $("iface-params"); box.replaceChildren();
  parameterInputs(box, "interface", $("iface-kind").value, { size: 7 });
};
$("add-interface").onclick = () => {
  const sel = app.selection; if (!sel) return;
  const node = Number($("iface-node").value);
  const item = { node, position: sel.position, kind: $("iface-kind").value, ...sel.selection };
  for (const input of $("iface-params").querySelectorAll("input")) if (input.value) item[input.dataset.key] = Number(input.value);
  app.job.interface = [...(app.job.interface || []), item];
  $("frame-node").value = node; $("port-node").value = node;
  $("iface-node").value = "";
  // the interface now shows in its own colour, with its node: the selection is done
  app.selection = null; $("add-interface").disabled = true; highlight([]);
  $("selection").textContent = `Added interface node ${node}.`;
  changed();
};

// ---- frame, ports, band, damping --------------------------------------------------------------
function frameChanged() {
  const type = $("frame-type").value;
  const takesNode = kindParameters("frame", type).some((p) => p.name === "node");
  app.job.frame = takesNode ? { type, node: Number($("frame-node").value) } : { type };
  changed();
}
$("frame-type").onchange = frameChanged; $("frame-node").onchange = frameChanged;
function addPort(key) {
  app.job[key] = [...(app.job[key] || []), { node: Number($("port-node").value), directions: $("port-directions").value }];
  changed();
}
$("add-input").onclick = () => addPort("inputs"); $("add-output").onclick = () => addPort("outputs");
for (const id of ["band-fmin", "band-fmax", "band-points", "band-reference"]) {
  $(id).onchange = () => {
    const band = { f_min_hz: Number($("band-fmin").value), f_max_hz: Number($("band-fmax").value), points: Number($("band-points").value) };
    if ($("band-reference").value !== tableDefault("band", "reference")) band.reference = $("band-reference").value;
    app.job.band = band; changed();
  };
}
$("damping-kind").onchange = () => {
  const kind = $("damping-kind").value, box = $("damping-values"); box.replaceChildren();
  parameterInputs(box, "damping", kind, { size: 6, onchange: dampingChanged });
  dampingChanged();
};
function dampingChanged() {
  const kind = $("damping-kind").value;
  if (!kind) delete app.job.damping;
  else {
    app.job.damping = { kind };
    for (const input of $("damping-values").querySelectorAll("input")) if (input.value) app.job.damping[input.dataset.key] = Number(input.value);
  }
  changed();
}

// ---- reductions: forms generated from the method registry ------------------------------------
function parseOption(field, text) {
  if (text === "" || text === undefined) return undefined;
  const number = Number(text);
  switch (field.kind) {
    case "int": case "float": return Number.isFinite(number) ? number : text;
    case "floats": return numbers(text).some(Number.isNaN) ? text : numbers(text);
    case "ints": return /[,\s]/.test(text.trim()) ? numbers(text) : (Number.isFinite(number) ? number : text);
    default: return text;
  }
}
function shown(value) { return Array.isArray(value) ? value.join(", ") : (value ?? ""); }
function renderReductions() {
  const box = $("reductions"); box.replaceChildren();
  (app.job.reduction || []).forEach((red, k) => {
    const fields = app.methods[red.method] || [];
    const card = el("div", { class: "reduction", "data-name": red.name },
      el("label", {}, "name ", el("input", { class: "red-name", value: red.name, size: 12,
        onchange: (e) => { red.name = e.target.value; changed(); } })),
      el("b", { text: red.method }), " ",
      el("button", { text: "remove", onclick: () => { app.job.reduction.splice(k, 1); changed(); } }), el("br"));
    for (const f of fields) {
      const title = `${f.meaning}${f.default !== null && f.default !== undefined && !(Array.isArray(f.default) && !f.default.length) ? ` (default ${shown(f.default)})` : ""}`;
      let input;
      if (f.kind === "bool") {
        input = el("input", { type: "checkbox", "data-option": f.name });
        input.checked = Boolean(red[f.name] ?? f.default);
        input.onchange = () => { if (input.checked === Boolean(f.default)) delete red[f.name]; else red[f.name] = input.checked; changed(); };
      } else if (f.kind === "choice") {
        input = el("select", { "data-option": f.name }, el("option", { value: "", text: f.default ? `(${f.default})` : "(default)" }),
          ...f.choices.map((c) => el("option", { value: c, text: c })));
        input.value = red[f.name] ?? "";
        input.onchange = () => { if (input.value) red[f.name] = input.value; else delete red[f.name]; changed(); };
      } else {
        input = el("input", { "data-option": f.name, size: f.kind === "floats" ? 14 : 6, value: shown(red[f.name]),
          placeholder: f.required ? "required" : shown(f.default) });
        input.onchange = () => { const v = parseOption(f, input.value.trim()); if (v === undefined) delete red[f.name]; else red[f.name] = v; changed(); };
      }
      card.append(el("label", { title }, `${f.name} `, input));
    }
    // a job key of every reduction, not a method option: write the body even if inaccurate
    const inaccurate = el("input", { type: "checkbox", "data-option": "export_inaccurate" });
    inaccurate.checked = Boolean(red.export_inaccurate);
    inaccurate.onchange = () => { if (inaccurate.checked) red.export_inaccurate = true; else delete red.export_inaccurate; changed(); };
    card.append(el("label", { title: "write the body files even when the reduction misses its accuracy limit (they are marked)" },
      "export_inaccurate ", inaccurate));
    box.append(card);
  });
}
$("add-reduction").onclick = () => {
  const method = $("method").value;
  const names = new Set((app.job.reduction || []).map((r) => r.name));
  let name = method, k = 2;
  while (names.has(name)) name = `${method}-${k++}`;
  app.job.reduction = [...(app.job.reduction || []), { name, method }];
  changed();
};
// the files a job can write and its default ones: the export registry's (GET /api/exports)
function renderExports() {
  const box = $("exports"); box.replaceChildren("export ");
  const outputs = new Set(((app.job.export || {}).outputs) || app.exports.default);
  for (const kind of app.exports.kinds) {
    const input = el("input", { type: "checkbox", "data-export": kind });
    input.checked = outputs.has(kind);
    if (kind === "npz") { input.checked = true; input.disabled = true; } // the page reads reduced.npz
    input.onchange = () => {
      const next = app.exports.kinds.filter((k) => k === "npz" || box.querySelector(`[data-export=${k}]`).checked);
      app.job.export = { ...(app.job.export || {}), outputs: next }; changed();
    };
    box.append(el("label", {}, input, kind), " ");
  }
}

// ---- run --------------------------------------------------------------------------------------
$("run").onclick = async () => {
  try {
    await api("/api/run", {});
    $("cancel").disabled = false; $("run").disabled = true;
    poll();
  } catch (e) { fail(e); }
};
$("cancel").onclick = async () => { await api("/api/cancel", {}); };
async function poll() {
  const s = await api("/api/status");
  $("progress").value = s.fraction || 0;
  $("stage").textContent = s.state === "running" ? s.stage : s.state + (s.error ? `: ${s.error}` : "");
  $("stage").dataset.state = s.state;
  $("log").textContent = (s.lines || []).join("\n");
  if (s.state === "running") { setTimeout(poll, 300); return; }
  $("cancel").disabled = true; $("run").disabled = false;
  if (s.state === "done") loadResults();
}
$("save").onclick = async () => {
  try {
    const saved = await api("/api/save", { path: $("save-path").value });
    $("saved").textContent = `saved ${saved.path}`; $("saved").dataset.path = saved.path;
  } catch (e) { $("saved").textContent = e.message; }
};

// ---- results ----------------------------------------------------------------------------------
async function loadResults() {
  const res = await api("/api/results");
  app.results = res; app.shapeCache = {};
  const body = $("results-table").querySelector("tbody"); body.replaceChildren();
  for (const r of res.reductions) {
    const a = r.accuracy, met = !a || a.met;
    body.append(el("tr", { "data-name": r.name, "data-accuracy": met ? "met" : "not-met", class: met ? "" : "inaccurate" },
      el("td", { text: r.name }), el("td", { text: r.method }),
      el("td", { class: "order", text: String(r.order) }), el("td", { class: "max-error", text: fmt(r.max_rel_error) }),
      el("td", { class: "static-error", text: fmt(r.static_rel_error) }), el("td", { text: fmt(r.error_estimate) }),
      el("td", { text: fmt(r.error_bound) }),
      el("td", { class: "accuracy", text: !a ? "" : met ? `met (≤ ${fmt(a.limit)})` :
        `NOT MET: ${fmt(a.max)} > ${fmt(a.limit)}, ${a.exported ? "written anyway" : "body not written"}` })));
  }
  const missed = res.reductions.filter((r) => r.accuracy && !r.accuracy.met).map((r) => r.name);
  $("accuracy").textContent = missed.length ? `Accuracy not met: ${missed.join(", ")} (see the table; ε over the ports and the inertia loads)` : "";
  plotErrors(res);
  eigenTable(res);
  const names = res.reductions.map((r) => r.name);
  for (const id of ["shape-reduction", "mac-a", "mac-b"]) $(id).replaceChildren(...names.map((n) => el("option", { value: n, text: n })));
  if (names.length > 1) $("mac-b").value = names[1];
  shapeReductionChanged(); drawMac();
  $("files").replaceChildren(...res.reductions.flatMap((r) => r.files).concat(["summary.json", "error.png"])
    .map((f) => el("li", {}, el("a", { href: `/files/${f}`, text: f }))));
}
const COLORS = ["#1f77b4", "#d62728", "#2ca02c", "#9467bd", "#ff7f0e", "#8c564b", "#17becf"];
function plotErrors(res) {
  const W = 400, H = 260, L = 50, B = 30, T = 10, R = 22;
  const curves = [];
  res.reductions.forEach((r, k) => {
    curves.push({ name: r.name, f: r.curve.frequency_hz, e: r.curve.relative, color: COLORS[k % COLORS.length], dash: "" });
    if (r.curve.inertia) curves.push({ name: `${r.name} (inertia loads)`, f: r.curve.frequency_hz, e: r.curve.inertia, color: COLORS[k % COLORS.length], dash: "1,3" });
    if (r.curve.estimate) curves.push({ name: `${r.name} estimate`, f: r.curve.estimate.frequency_hz, e: r.curve.estimate.relative, color: COLORS[k % COLORS.length], dash: "5,3" });
  });
  let fmin = Infinity, fmax = 0, emin = Infinity, emax = 0;
  for (const c of curves) c.f.forEach((f, i) => { const e = c.e[i]; if (f > 0 && e > 0) { fmin = Math.min(fmin, f); fmax = Math.max(fmax, f); emin = Math.min(emin, e); emax = Math.max(emax, e); } });
  if (!(fmax > fmin)) { $("plot").textContent = ""; return; }
  const lx0 = Math.log10(fmin), lx1 = Math.log10(fmax), ly0 = Math.floor(Math.log10(emin)), ly1 = Math.ceil(Math.log10(emax));
  const x = (f) => L + (Math.log10(f) - lx0) / (lx1 - lx0) * (W - L - R);
  const y = (e) => T + (ly1 - Math.log10(e)) / Math.max(ly1 - ly0, 1) * (H - T - B);
  let svg = `<svg xmlns="http://www.w3.org/2000/svg" width="${W}" height="${H + 16 * curves.length}" font-size="10">`;
  svg += `<rect x="${L}" y="${T}" width="${W - L - R}" height="${H - T - B}" fill="none" stroke="#999"/>`;
  const step = Math.max(1, Math.ceil((ly1 - ly0) / 8));
  for (let d = ly0; d <= ly1; d += step) svg += `<line x1="${L}" x2="${W - R}" y1="${y(10 ** d)}" y2="${y(10 ** d)}" stroke="#eee"/><text x="${L - 4}" y="${y(10 ** d) + 3}" text-anchor="end">1e${d}</text>`;
  for (let d = Math.ceil(lx0); d <= Math.floor(lx1); d++) svg += `<line y1="${T}" y2="${H - B}" x1="${x(10 ** d)}" x2="${x(10 ** d)}" stroke="#eee"/><text x="${x(10 ** d)}" y="${H - B + 12}" text-anchor="middle">${10 ** d}</text>`;
  svg += `<text x="${(L + W) / 2}" y="${H - 4}" text-anchor="middle">frequency [Hz]</text><text x="10" y="${T + 8}">ε</text>`;
  curves.forEach((c, k) => {
    const pts = c.f.map((f, i) => (f > 0 && c.e[i] > 0) ? `${x(f).toFixed(1)},${y(c.e[i]).toFixed(1)}` : null).filter(Boolean).join(" ");
    svg += `<polyline points="${pts}" fill="none" stroke="${c.color}" stroke-dasharray="${c.dash}" stroke-width="1.5" data-curve="${c.name}"/>`;
    svg += `<line x1="${L}" x2="${L + 20}" y1="${H + 8 + 16 * k}" y2="${H + 8 + 16 * k}" stroke="${c.color}" stroke-dasharray="${c.dash}" stroke-width="2"/><text x="${L + 26}" y="${H + 12 + 16 * k}">${c.name}</text>`;
  });
  $("plot").innerHTML = svg + "</svg>";
}
function eigenTable(res) {
  const n = Math.min(12, Math.max(...res.reductions.map((r) => r.eigenfrequencies_hz.length)));
  const table = el("table", { id: "eigen-table" }, el("tr", {}, el("th", { text: "#" }), ...res.reductions.map((r) => el("th", { text: r.name }))));
  for (let i = 0; i < n; i++) table.append(el("tr", {}, el("td", { text: String(i + 1) }), ...res.reductions.map((r) => el("td", { text: r.eigenfrequencies_hz[i] === undefined ? "" : r.eigenfrequencies_hz[i].toFixed(2) }))));
  $("eigen").replaceChildren(table);
}
async function drawMac() {
  const a = $("mac-a").value, b = $("mac-b").value;
  if (!a || !b) return;
  const mac = await api(`/api/mac?a=${encodeURIComponent(a)}&b=${encodeURIComponent(b)}`);
  const m = mac.matrix.slice(0, 40).map((row) => row.slice(0, 40));
  const c = $("mac"), g = c.getContext("2d"), n = m.length, k = m[0] ? m[0].length : 0;
  g.fillStyle = "#fff"; g.fillRect(0, 0, c.width, c.height);
  const s = Math.min((c.width - 20) / Math.max(k, 1), (c.height - 20) / Math.max(n, 1));
  for (let i = 0; i < n; i++) for (let j = 0; j < k; j++) {
    const v = Math.round(255 * (1 - m[i][j])); g.fillStyle = `rgb(${v},${v},${v})`; g.fillRect(20 + j * s, 20 + i * s, s, s);
  }
  g.fillStyle = "#000"; g.font = "10px sans-serif"; g.fillText(`${b} →`, 22, 12); g.save(); g.translate(10, 22); g.rotate(Math.PI / 2); g.fillText(`${a} →`, 0, 0); g.restore();
  c.dataset.diagonal = m.map((row, i) => row[i] ?? 0).slice(0, 6).map((v) => v.toFixed(3)).join(",");
  $("mac-note").textContent = mac.weighting === "mass" ?
    "mass-weighted: (vᵢᵀM wⱼ)² / ((vᵢᵀM vᵢ)(wⱼᵀM wⱼ)), M the body's mass matrix; white 0, black 1" :
    "plain: (vᵢᵀwⱼ)² / ((vᵢᵀvᵢ)(wⱼᵀwⱼ)) over all dofs; white 0, black 1";
  $("mac-note").dataset.weighting = mac.weighting;
}
$("mac-a").onchange = drawMac; $("mac-b").onchange = drawMac;
async function shapeReductionChanged() {
  const name = $("shape-reduction").value, r = app.results.reductions.find((x) => x.name === name);
  if (!r) return;
  $("shape-k").replaceChildren(el("option", { value: "", text: "undeformed" }),
    ...r.eigenfrequencies_hz.map((f, k) => el("option", { value: k, text: `${k + 1}: ${f.toFixed(1)} Hz` })));
}
async function shapeChanged() {
  const name = $("shape-reduction").value, k = $("shape-k").value;
  if (!app.viewer) return;
  if (k === "") { app.viewer.setShape(null); app.viewer.render(); return; }
  const shape = await api(`/api/shape?reduction=${encodeURIComponent(name)}&k=${k}`);
  $("shape-hz").textContent = `${shape.frequency_hz.toFixed(2)} Hz`;
  app.viewer.scene.shapes = [{ name: `${name} ${Number(k) + 1}`, values: shape.values }];
  app.viewer.setShape(0);
  app.viewer.setAmplitude(Number($("shape-amplitude").value));
  app.viewer.animate($("shape-animate").checked);
  app.viewer.render();
}
$("shape-reduction").onchange = () => { shapeReductionChanged(); shapeChanged(); };
$("shape-k").onchange = shapeChanged;
$("shape-amplitude").oninput = () => { if (app.viewer) { app.viewer.setAmplitude(Number($("shape-amplitude").value)); app.viewer.render(); } };
$("shape-animate").onchange = () => { if (app.viewer) app.viewer.animate($("shape-animate").checked); };
$("reset-view").onclick = () => { if (app.viewer) { app.viewer.resetView(); app.viewer.render(); } };

// ---- start ------------------------------------------------------------------------------------
$("open-example").onclick = () => {
  const name = $("example-name").value, options = {};
  if (name === "rack-solid") { options.dofs = Number($("example-dofs").value) || 35000; options.interface = "none"; }
  openModel({ example: name, options });
};
$("open-path").onclick = () => openModel({ path: $("model-path").value });
(async function start() {
  app.schema = await api("/api/schema");
  app.methods = app.schema.kinds.method;
  $("method").replaceChildren(...Object.keys(app.methods).map((m) => el("option", { value: m, text: m })));
  app.exports = { kinds: Object.keys(app.schema.kinds.export), default: app.schema.default_exports };
  kindOptions("iface-kind", "interface"); kindOptions("frame-type", "frame");
  kindOptions("band-reference", "reference"); kindOptions("damping-kind", "damping");
  const examples = await api("/api/examples");
  $("example-name").replaceChildren(...Object.keys(examples).map((m) => el("option", { value: m, text: m })));
  $("example-name").value = "rack-solid";
  const state = await api("/api/state");
  if (state.model) {
    $("model-name").textContent = `${state.model.name}: ${state.model.n_dof.toLocaleString()} dofs, ${state.model.n_nodes.toLocaleString()} nodes`;
    show(state);
    app.scene = await api("/api/scene");
    startViewer();
    loadFacts();
  }
  document.body.dataset.ready = "1";
})();
