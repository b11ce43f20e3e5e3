// The 3D view: the shared viewer of the HTML report (viewer.js, window.PymorembsViewer), the
// job's decorations in it and the highlighted selection.
import { $, app } from "./api.js";

// ---- 3D view ----------------------------------------------------------------------------------
export function startViewer() {
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
export function decorate() {
  const d = app.decorations;
  if (!app.viewer || !d) return;
  app.viewer.setDecorations({ frame: d.frame, interfaces: d.interfaces });
  $("viewer-note").textContent = (d.notes || []).join(" ");
  $("canvas").dataset.decorations = `${d.frame ? 1 : 0},${d.interfaces.length}`;
}
export function highlight(rows) {
  if (!app.viewer) return;
  app.selectionRows = rows || [];
  app.viewer.clearHighlight();
  if (app.selectionRows.length) app.viewer.highlight(app.selectionRows, [1.0, 0.45, 0.0]);
  // the last run's hot spots (stress.js), magenta
  const spots = app.hotSpots && app.hotSpots.rows ? app.hotSpots.rows : [];
  if (spots.length) app.viewer.highlight(spots, [0.85, 0.1, 0.75]);
  app.viewer.render();
}
// Redraw the marks (after the hot spots changed), keeping the selection.
export function remark() { highlight(app.selectionRows); }
$("reset-view").onclick = () => { if (app.viewer) { app.viewer.resetView(); app.viewer.render(); } };
