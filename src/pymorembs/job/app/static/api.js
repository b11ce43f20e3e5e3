// The page's shared pieces: the state object `app` (also window.app, which the browser tests
// read), the JSON fetch helper (a reply with `error` becomes an exception), DOM helpers, number
// parsing and formatting, and the busy/failure lines.
export const $ = (id) => document.getElementById(id);
export const app = { job: null, schema: null, methods: {}, exports: { kinds: [], default: [] }, scene: null,
  viewer: null, picking: false, selection: null, results: null, shapeCache: {}, hotSpots: null,
  selectionRows: [] };
window.app = app;

export async function api(path, body) {
  const init = body === undefined ? {} : { method: "POST", body: JSON.stringify(body),
    headers: { "Content-Type": "application/json" } };
  const response = await fetch(path, init);
  const data = await response.json();
  if (!response.ok) throw new Error(data.error || response.statusText);
  return data;
}
export function el(tag, attrs, ...children) {
  const node = document.createElement(tag);
  for (const [k, v] of Object.entries(attrs || {})) {
    if (k.startsWith("on")) node.addEventListener(k.slice(2), v);
    else if (k === "text") node.textContent = v;
    else node.setAttribute(k, v);
  }
  for (const c of children) node.append(c);
  return node;
}
export const numbers = (text) => String(text).split(/[\s,;]+/).filter((s) => s !== "").map(Number);
// The curves' colours of the plots (one per reduction or body).
export const COLORS = ["#1f77b4", "#d62728", "#2ca02c", "#9467bd", "#ff7f0e", "#8c564b", "#17becf"];
export const fmt = (x) => (x === null || x === undefined) ? "–" : Number(x).toPrecision(4);
export function busy(text) { $("busy").textContent = text || ""; }
export function fail(error) { $("job-error").textContent = String(error.message || error); busy(""); }
