// The results of the last run: the table, the ε(f) plot, the eigenfrequencies, the MAC and
// the shape functions in the 3D view.
import { $, api, app, COLORS, el, fmt } from "./api.js";
import { loadHotSpots } from "./stress.js";

// ---- results ----------------------------------------------------------------------------------
export async function loadResults() {
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
  $("accuracy").textContent = missed.length ? `Accuracy not met: ${missed.join(", ")} (see the table; ε over the ports, the inertia loads and the stresses)` : "";
  plotErrors(res);
  eigenTable(res);
  const names = res.reductions.map((r) => r.name);
  for (const id of ["shape-reduction", "mac-a", "mac-b"]) $(id).replaceChildren(...names.map((n) => el("option", { value: n, text: n })));
  if (names.length > 1) $("mac-b").value = names[1];
  shapeReductionChanged(); drawMac();
  $("files").replaceChildren(...res.reductions.flatMap((r) => r.files).concat(["summary.json", "error.png"])
    .map((f) => el("li", {}, el("a", { href: `/files/${f}`, text: f }))));
  loadHotSpots();
}
function plotErrors(res) {
  const W = 400, H = 260, L = 50, B = 30, T = 10, R = 22;
  const curves = [];
  res.reductions.forEach((r, k) => {
    curves.push({ name: r.name, f: r.curve.frequency_hz, e: r.curve.relative, color: COLORS[k % COLORS.length], dash: "" });
    if (r.curve.inertia) curves.push({ name: `${r.name} (inertia loads)`, f: r.curve.frequency_hz, e: r.curve.inertia, color: COLORS[k % COLORS.length], dash: "1,3" });
    if (r.curve.stress) curves.push({ name: `${r.name} (stresses)`, f: r.curve.frequency_hz, e: r.curve.stress, color: COLORS[k % COLORS.length], dash: "8,2,1,2" });
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
  // a body with solid elements: the surface coloured by the shape's von Mises stress
  app.viewer.scene.shapes = [{ name: `${name} ${Number(k) + 1}`, values: shape.values, scalars: shape.von_mises }];
  $("shape-hz").dataset.vonMises = shape.von_mises ? "1" : "0";
  if (shape.von_mises) $("shape-hz").textContent += `, coloured by von Mises (max ${fmt(shape.von_mises.reduce((a, b) => Math.max(a, b), 0))} per unit q)`;
  app.viewer.setShape(0);
  app.viewer.setAmplitude(Number($("shape-amplitude").value));
  app.viewer.animate($("shape-animate").checked);
  app.viewer.render();
}
$("shape-reduction").onchange = () => { shapeReductionChanged(); shapeChanged(); };
$("shape-k").onchange = shapeChanged;
$("shape-amplitude").oninput = () => { if (app.viewer) { app.viewer.setAmplitude(Number($("shape-amplitude").value)); app.viewer.render(); } };
$("shape-animate").onchange = () => { if (app.viewer) app.viewer.animate($("shape-animate").checked); };
