// The stress at a hot spot over time (issue #29): the last run's hot spots marked in the 3D view,
// a click on the body (picking off) or a choice in the list takes the nearest hot spot, and its
// von Mises stress over time is plotted for every body of every time check, with peak and range.
import { $, api, app, COLORS, el, fmt } from "./api.js";
import { remark } from "./view.js";

export async function loadHotSpots() {
  const spots = await api("/api/hot_spots");
  app.hotSpots = spots;
  $("hot-spot").replaceChildren(...spots.points.map((p) => el("option", { value: p, text: p })));
  $("stress-plot").replaceChildren(); $("stress-table").replaceChildren();
  $("stress-note").textContent = spots.available ?
    `${spots.points.length} hot spots (magenta in the view): click one on the body, or choose it here.` : spots.note;
  $("stress-note").dataset.available = spots.available ? "1" : "0";
  remark();
  if (spots.available && spots.points.length) showHistory(`point=${encodeURIComponent(spots.points[0])}`);
}
async function showHistory(query) {
  const components = $("stress-components").checked;
  let h;
  try { h = await api(`/api/stress_history?${query}${components ? "&components=1" : ""}`); }
  catch (e) { $("stress-note").textContent = e.message; return; }
  if (!h.available) { $("stress-note").textContent = h.note; return; }
  $("hot-spot").value = h.point;
  $("stress-note").textContent = `hot spot ${h.point} at ${h.position.map((x) => +x.toPrecision(5)).join(", ")}` +
    (components ? ": the six components of the reference body (solid) and the first reduced body (dashed)" :
      ": von Mises stress; reference solid, reduced bodies dashed");
  $("stress-plot").replaceChildren(...h.histories.map((c) => plot(c, components)));
  $("stress-plot").dataset.point = h.point;
  const rows = [el("tr", {}, ...["check", "case", "body", "peak σ_vM", "range σ_vM", "range |σ₁|max"].map((t) => el("th", { text: t })))];
  for (const c of h.histories) for (const b of c.bodies) {
    rows.push(el("tr", { "data-body": b.name, "data-case": c.case }, el("td", { text: c.check }), el("td", { text: c.case }),
      el("td", { text: b.name }), el("td", { class: "peak", text: fmt(b.peak_von_mises) }),
      el("td", { class: "range", text: fmt(b.range_von_mises) }), el("td", { text: fmt(b.range_abs_max_principal) })));
  }
  $("stress-table").replaceChildren(...rows);
}
// One SVG plot of a check's case: σ_vM(t) of every body, or the six components of the first two.
function plot(history, components) {
  const W = 400, H = 200, L = 60, B = 30, T = 16, R = 10;
  const lines = [];
  if (components) {
    const names = ["xx", "yy", "zz", "xy", "xz", "yz"];
    history.bodies.slice(0, 2).forEach((b, j) => names.forEach((n, i) =>
      lines.push({ name: `${b.name} σ_${n}`, v: b.stress.map((s) => s[i]), color: COLORS[i], dash: j ? "5,3" : "" })));
  } else {
    history.bodies.forEach((b, k) => lines.push({ name: b.name, v: b.von_mises, color: COLORS[k % COLORS.length], dash: k ? "5,3" : "" }));
  }
  const t = history.times, t0 = t[0], t1 = t[t.length - 1] > t0 ? t[t.length - 1] : t0 + 1;
  let lo = Math.min(0, ...lines.map((l) => Math.min(...l.v))), hi = Math.max(...lines.map((l) => Math.max(...l.v)));
  if (!(hi > lo)) hi = lo + 1;
  const x = (s) => L + (s - t0) / (t1 - t0) * (W - L - R), y = (v) => T + (hi - v) / (hi - lo) * (H - T - B);
  let svg = `<svg xmlns="http://www.w3.org/2000/svg" width="${W}" height="${H + 14 * lines.length}" font-size="10">`;
  svg += `<text x="${L}" y="11">${history.check}: ${history.case}, ${components ? "σ components" : "σ_vM"} (model stress unit)</text>`;
  svg += `<rect x="${L}" y="${T}" width="${W - L - R}" height="${H - T - B}" fill="none" stroke="#999"/>`;
  for (const v of [lo, (lo + hi) / 2, hi]) svg += `<text x="${L - 4}" y="${y(v) + 3}" text-anchor="end">${fmt(v)}</text>`;
  for (const s of [t0, (t0 + t1) / 2, t1]) svg += `<text x="${x(s)}" y="${H - B + 12}" text-anchor="middle">${+s.toPrecision(3)}</text>`;
  svg += `<text x="${(L + W) / 2}" y="${H - 4}" text-anchor="middle">time [s]</text>`;
  lines.forEach((l, k) => {
    const pts = l.v.map((v, i) => `${x(t[i]).toFixed(1)},${y(v).toFixed(1)}`).join(" ");
    svg += `<polyline points="${pts}" fill="none" stroke="${l.color}" stroke-dasharray="${l.dash}" stroke-width="1.3" data-body="${l.name}"/>`;
    svg += `<line x1="${L}" x2="${L + 20}" y1="${H + 6 + 14 * k}" y2="${H + 6 + 14 * k}" stroke="${l.color}" stroke-dasharray="${l.dash}" stroke-width="2"/><text x="${L + 26}" y="${H + 10 + 14 * k}">${l.name}</text>`;
  });
  const div = el("div", { class: "stress-history" });
  div.innerHTML = svg + "</svg>";
  return div;
}
$("hot-spot").onchange = () => showHistory(`point=${encodeURIComponent($("hot-spot").value)}`);
$("stress-components").onchange = () => { if ($("hot-spot").value) $("hot-spot").onchange(); };
// a click (not a drag) on the body while not picking interfaces: the nearest hot spot
let down = null;
$("canvas").addEventListener("mousedown", (e) => { down = [e.clientX, e.clientY]; });
$("canvas").addEventListener("mouseup", (e) => {
  if (app.picking || !down || !app.viewer || e.button !== 0 || !(app.hotSpots && app.hotSpots.available)) return;
  if (Math.hypot(e.clientX - down[0], e.clientY - down[1]) > 4) return;
  const node = app.viewer.pickNode(e.clientX, e.clientY);
  if (node !== null) showHistory(`node=${node}`);
});
