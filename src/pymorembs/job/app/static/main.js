// The page of `pymorembs app`: a job editor. Every list of kinds and every form comes from the
// job's schema the server serves (GET /api/schema): none is written here. This module starts
// the page; the others attach their controls when they are imported.
import { $, api, app, el } from "./api.js";
import { show } from "./job.js";
import { loadFacts } from "./model.js";
import "./results.js";
import "./run.js";
import { kindOptions } from "./schema.js";
import { startViewer } from "./view.js";

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
