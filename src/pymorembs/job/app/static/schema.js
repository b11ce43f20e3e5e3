// Lists of kinds and parameter inputs built from the job's schema the server serves
// (GET /api/schema, held in app.schema): no list of kinds is written in the page.
import { $, app, el } from "./api.js";

// the schema's parameters of a kind (interface, damping, frame ...), and a table key's default
export const kindParameters = (list, kind) => (app.schema.kinds[list][kind] || []);
export const tableDefault = (table, key) => app.schema.tables[table].find((k) => k.name === key).default;
export function kindOptions(id, list) {
  const kinds = Object.keys(app.schema.kinds[list]).map((k) => el("option", { value: k, text: k }));
  $(id).append(...kinds);
}
export function parameterInputs(box, list, kind, attrs) {
  for (const p of kindParameters(list, kind)) {
    const title = `${p.meaning}${p.unit ? ` [${p.unit}]` : ""}${p.required ? ", required" : ""}`;
    box.append(el("label", { title }, ` ${p.name} `, el("input", { "data-key": p.name, ...attrs })), " ");
  }
}
