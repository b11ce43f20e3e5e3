// The job being edited: `app.job` is the job file as an object (the same tables and keys as
// the TOML); every change is sent to the server, which writes the TOML and checks it with the
// job parser of `pymorembs reduce`. The forms of the frame, ports, band, damping, reductions
// and exports.
import { $, api, app, el, fail, numbers } from "./api.js";
import { kindParameters, parameterInputs, tableDefault } from "./schema.js";
import { decorate } from "./view.js";

// ---- the job, sent and shown ----------------------------------------------------------------
let pending = null;
export function changed() {
  clearTimeout(pending);
  pending = setTimeout(async () => {
    try { show(await api("/api/job", { job: app.job })); } catch (e) { fail(e); }
  }, 120);
}
export function show(state, redraw = true) {  // redraw false: a new scene comes, decorated then
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
