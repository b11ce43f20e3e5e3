// The model: open an example or a file, its facts, and the interfaces picked on its surface or
// selected by numbers.
import { $, api, app, busy, el, fail, numbers } from "./api.js";
import { changed, show } from "./job.js";
import { parameterInputs } from "./schema.js";
import { highlight, startViewer } from "./view.js";

// ---- model ------------------------------------------------------------------------------------
async function openModel(request) {
  busy("opening…");
  try {
    const state = await api("/api/open", request);
    $("model-name").textContent = `${state.model.name}: ${state.model.n_dof.toLocaleString()} dofs, ${state.model.n_nodes.toLocaleString()} nodes`;
    show(state, false);
    app.selection = null; app.hotSpots = null; $("selection").textContent = "Nothing selected."; $("add-interface").disabled = true;
    app.scene = await api("/api/scene");
    startViewer();
    busy("");
    loadFacts();
  } catch (e) { fail(e); }
}
export async function loadFacts() {
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

$("open-example").onclick = () => {
  const name = $("example-name").value, options = {};
  if (name === "rack-solid") { options.dofs = Number($("example-dofs").value) || 35000; options.interface = "none"; }
  openModel({ example: name, options });
};
$("open-path").onclick = () => openModel({ path: $("model-path").value });
