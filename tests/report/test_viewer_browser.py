"""viewer.js in a real headless Chromium (software WebGL): it draws, picks and animates.

The pages are built here from scenes of built-in bodies; the report's own 3D view is checked
by a screenshot in tests/job/test_report_view.py.
"""

from __future__ import annotations

import json
import re
import shutil
import subprocess
from dataclasses import replace

import numpy as np
import pytest

from pymorembs.examples import build_example
from pymorembs.report.scene import body_scene, viewer_script

CHROMIUM = shutil.which("chromium")
pytestmark = pytest.mark.skipif(CHROMIUM is None, reason="chromium not installed")

# Flags of a headless, offline, software-rendered Chromium (SwiftShader's WebGL).
FLAGS = [
    "--headless",
    "--no-sandbox",
    "--disable-gpu",
    "--use-gl=swiftshader",
    "--enable-unsafe-swiftshader",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
    "--disable-quic",
    "--no-first-run",
]

# Runs in the page: draws, reads the canvas back, picks the node nearest to the eye at its
# projected place (undeformed and deformed), animates, then shows a points-only scene. The
# results go to the title as JSON.
READBACK = """
const canvas = document.getElementById("view");
const out = {};
function eachPixel(v, visit) {  // draws, reads the canvas back and visits every pixel's rgb
  v.render();
  const gl = v.gl, w = canvas.width, h = canvas.height, data = new Uint8Array(4 * w * h);
  gl.readPixels(0, 0, w, h, gl.RGBA, gl.UNSIGNED_BYTE, data);
  for (let i = 0; i < data.length; i += 4) visit(data[i], data[i + 1], data[i + 2]);
  return w * h;
}
function pixelAt(v, p) {  // the colour drawn where the world point p projects
  const m = v._matrices().pv, [x, y, z] = p;
  const w = m[3] * x + m[7] * y + m[11] * z + m[15];
  const nx = (m[0] * x + m[4] * y + m[8] * z + m[12]) / w;
  const ny = (m[1] * x + m[5] * y + m[9] * z + m[13]) / w;
  const px = Math.round((nx + 1) / 2 * canvas.width), py = Math.round((ny + 1) / 2 * canvas.height);
  const data = new Uint8Array(4);
  v.render();
  v.gl.readPixels(px, py, 1, 1, v.gl.RGBA, v.gl.UNSIGNED_BYTE, data);
  return Array.from(data.slice(0, 3));
}
"""

PROBE = (
    READBACK
    + """
function pixels(v) {
  let blue = 0, other = 0;
  const total = eachPixel(v, (r, g, b) => {
    if (r > 240 && g > 240 && b > 240) return;  // background
    if (b > r + 25 && b > g) blue++; else other++;
  });
  return { blue, other, total };
}
function screen(v, i) {  // client coordinates of node i as drawn
  const m = v._matrices(), X = v._current();
  const x = X[3 * i], y = X[3 * i + 1], z = X[3 * i + 2], p = m.pv;
  const w = p[3] * x + p[7] * y + p[11] * z + p[15];
  const nx = (p[0] * x + p[4] * y + p[8] * z + p[12]) / w;
  const ny = (p[1] * x + p[5] * y + p[9] * z + p[13]) / w;
  const nz = (p[2] * x + p[6] * y + p[10] * z + p[14]) / w;
  const r = canvas.getBoundingClientRect();
  return [r.left + (nx + 1) / 2 * r.width, r.top + (1 - ny) / 2 * r.height, nz];
}
function front(v) {  // the node nearest to the eye
  let best = 0, depth = Infinity;
  for (let i = 0; i < v._n; i++) {
    const z = screen(v, i)[2];
    if (z < depth) { depth = z; best = i; }
  }
  return best;
}
function trianglesOf(v, j) { return Array.from(v._tri.slice(3 * j, 3 * j + 3)); }
try {
  const scene = JSON.parse(document.getElementById("scene").textContent);
  const v = new PymorembsViewer(canvas, scene);
  out.plain = pixels(v);
  let i = front(v), [x, y] = screen(v, i);
  out.pick = { node: i, picked: v.pickNode(x, y), triangle: v.pickTriangle(x, y) };
  out.pick.cornerOf = out.pick.triangle === null ? false :
    trianglesOf(v, out.pick.triangle).includes(i);
  const r = canvas.getBoundingClientRect();
  out.miss = [v.pickNode(r.left + 1, r.top + 1), v.pickTriangle(r.left + 1, r.top + 1)];
  // The mouse: left drag rotates, right drag pans, the wheel zooms.
  const mouse = (type, x, y, button, target) => (target || canvas).dispatchEvent(
    new MouseEvent(type, { clientX: x, clientY: y, button, bubbles: true }));
  const [R0, c0, d0] = [v._R.slice(), v._center.slice(), v._distance];
  mouse("mousedown", 300, 200, 0); mouse("mousemove", 340, 210, 0, window);
  mouse("mouseup", 340, 210, 0, window);
  out.rotated = v._R.some((x, k) => Math.abs(x - R0[k]) > 1e-3) &&
    v._center.every((x, k) => x === c0[k]);
  const R1 = v._R.slice();
  mouse("mousedown", 300, 200, 2); mouse("mousemove", 320, 200, 2, window);
  mouse("mouseup", 320, 200, 2, window);
  out.panned = v._center.some((x, k) => x !== c0[k]) && v._R.every((x, k) => x === R1[k]);
  canvas.dispatchEvent(new WheelEvent("wheel", { deltaY: 100, bubbles: true, cancelable: true }));
  out.zoomed = v._distance > d0;
  v.resetView();
  v.setShape(0);
  v.setAmplitude(0.2);
  out.shape = pixels(v);
  i = front(v); [x, y] = screen(v, i);
  out.deformed = { node: i, picked: v.pickNode(x, y), tip: v._current()[3 * i] };
  v.highlight([0, 1, 2], [255, 0, 0]);
  v.clearHighlight();
  v.animate(true);
  const before = v.frames;
  const started = performance.now();
  const finish = () => {
    // a loaded machine draws few frames: wait for two (at most 3 s of the 4 s budget)
    if (v.frames - before < 2 && performance.now() - started < 3000) {
      setTimeout(finish, 100);
      return;
    }
    out.animated = v.frames - before;
    v.animate(false);
    v.setScene(JSON.parse(document.getElementById("points").textContent));
    out.points = pixels(v);
    out.pointPick = v.pickNode(...screen(v, 5).slice(0, 2));
    v.setShape(Number("none"));  // not a shape: the undeformed body
    out.notShape = v.shape;
    v.setScene({ positions: [], node_ids: [], triangles: [], lines: [], frame: null,
      interfaces: [], shapes: [], size: 1 });  // an empty scene draws nothing, and no error
    v.render();
    out.empty = v.pickNode(r.left + 100, r.top + 100);
    document.title = "probe " + JSON.stringify(out);
  };
  setTimeout(finish, 600);
} catch (error) {
  document.title = "probe " + JSON.stringify({ error: String(error) });
}
"""
)


# Runs in the page: counts the pixels of the frame triad's red and green axes and of the first
# interface colour (orange) before and after setDecorations, checks that the view and the shape
# stay, reads the pixel where the marker of a node the scene lacks must be, and takes the
# decorations away again.
DECORATIONS = (
    READBACK
    + """
function count(v) {
  let red = 0, green = 0, orange = 0;
  eachPixel(v, (r, g, b) => {
    if (r > 180 && g < 60 && b < 60) red++;
    if (g > 120 && r < 70 && b < 70) green++;
    if (r > 200 && g > 90 && g < 140 && b < 40) orange++;
  });
  return { red, green, orange };
}
try {
  const scene = JSON.parse(document.getElementById("scene").textContent);
  const d = JSON.parse(document.getElementById("points").textContent);
  const v = new PymorembsViewer(canvas, scene);
  v.setShape(0); v.setContour(false); v.setAmplitude(0.02);
  const mouse = (type, x, y, target) => (target || canvas).dispatchEvent(
    new MouseEvent(type, { clientX: x, clientY: y, button: 0, bubbles: true }));
  mouse("mousedown", 300, 200); mouse("mousemove", 330, 215, window);
  mouse("mouseup", 330, 215, window);
  const view = JSON.stringify([v._R, v._center, v._distance]);
  out.before = count(v);
  v.setDecorations(d);
  out.after = count(v);
  out.sameView = JSON.stringify([v._R, v._center, v._distance]) === view;
  out.shape = v.shape;
  out.legend = document.querySelector(".pymorembs-legend").textContent;
  v.setAmplitude(0);
  out.marker = pixelAt(v, d.interfaces[0].position);
  v.setDecorations({ frame: null, interfaces: [] });
  out.removed = count(v);
  document.title = "probe " + JSON.stringify(out);
} catch (error) {
  document.title = "probe " + JSON.stringify({ error: String(error) });
}
"""
)


def page(scene: dict, points: dict, probe: str = PROBE) -> str:
    data = json.dumps(scene).replace("<", "\\u003c")
    bare = json.dumps(points).replace("<", "\\u003c")
    return (
        '<!DOCTYPE html><html><head><meta charset="utf-8"><title>wait</title><style>'
        "body{margin:0} div{width:640px;height:400px} canvas{width:100%;height:100%}</style>"
        '</head><body><div><canvas id="view"></canvas></div>'
        f'<script type="application/json" id="scene">{data}</script>'
        f'<script type="application/json" id="points">{bare}</script>'
        f"<script>{viewer_script()}</script><script>{probe}</script></body></html>"
    )


def run_probe(tmp_path, scene: dict, points: dict, probe: str = PROBE) -> dict:
    path = tmp_path / "probe.html"
    path.write_text(page(scene, points, probe))
    result = subprocess.run(
        [CHROMIUM, *FLAGS, f"--user-data-dir={tmp_path / 'profile'}", "--window-size=800,600",
         "--virtual-time-budget=4000", "--dump-dom", path.as_uri()],
        capture_output=True, text=True, timeout=120,
    )  # fmt: skip
    found = re.search(r"<title>probe (.*)</title>", result.stdout)
    assert found, result.stderr[-2000:]
    return json.loads(found.group(1).replace("&quot;", '"').replace("&amp;", "&"))


def bent_blade() -> tuple:
    """The blade and its scene with one shape: a flapwise bending field by hand, u_z = x^2 on
    every node (the blade lies along x: the tip moves most)."""
    body = build_example("blade", elements=8)
    basis = np.zeros((body.n_dof, 1))
    rows = body.node_rows(body.dofs.nodes)
    uz = body.dofs.directions == 2
    basis[uz, 0] = body.coordinates[rows[uz], 0] ** 2
    return body, body_scene(body, basis=basis)


@pytest.mark.slow
def test_viewer_draws_picks_and_animates_in_chromium(tmp_path):
    body, scene = bent_blade()
    points = body_scene(replace(body, surface=None))
    out = run_probe(tmp_path, scene, points)
    assert "error" not in out, out
    # The blade covers a good part of the canvas in its blue, and little else is drawn.
    assert out["plain"]["blue"] > 0.03 * out["plain"]["total"], out
    assert out["plain"]["other"] < out["plain"]["blue"], out
    # The node nearest to the eye is picked where it is drawn, on a triangle it is a corner of;
    # nothing is picked in the canvas's corner.
    assert out["pick"]["picked"] == out["pick"]["node"], out
    assert out["pick"]["cornerOf"], out
    assert out["miss"] == [None, None], out
    assert out["rotated"] and out["panned"] and out["zoomed"], out
    # Deformed (20 % of the size at the tip): coloured by the translation, picked where drawn.
    assert out["shape"]["blue"] + out["shape"]["other"] > 0.03 * out["shape"]["total"], out
    assert out["shape"]["other"] > 0.1 * out["shape"]["blue"], out  # red-grey contour too
    assert out["deformed"]["picked"] == out["deformed"]["node"], out
    assert out["animated"] >= 2, out
    # Without a surface the nodes are drawn as points, and a node is picked within 10 px.
    assert out["points"]["blue"] > 200, out
    assert out["pointPick"] is not None, out
    assert out["notShape"] is None and out["empty"] is None, out


@pytest.mark.slow
def test_decorations_replace_frame_and_interfaces_and_keep_the_view(tmp_path):
    body = build_example("blade", elements=8)
    basis = np.zeros((body.n_dof, 1))
    basis[body.dofs.directions == 2, 0] = 1.0
    scene = body_scene(body, basis=basis)
    assert scene["frame"] is None and scene["interfaces"] == []
    # A node the scene lacks (an interface node being added) in front of the blade's root,
    # coupled to the nodes of the root (x smallest), and a triad at the middle of the blade.
    positions = np.asarray(scene["positions"]).reshape(-1, 3)
    root = np.flatnonzero(positions[:, 0] < positions[:, 0].min() + 1e-9)
    middle = 0.5 * (positions.min(axis=0) + positions.max(axis=0))
    marker = [float(positions[:, 0].min()) - 0.05 * scene["size"], *middle[1:].tolist()]
    decorations = {
        "frame": {"origin": middle.tolist(), "axes": np.eye(3).tolist()},
        "interfaces": [{"name": "interface 9 (rigid)", "node": None, "position": marker,
                        "coupled": root.tolist()}],
    }  # fmt: skip
    out = run_probe(tmp_path, scene, decorations, DECORATIONS)
    assert "error" not in out, out
    assert out["before"] == {"red": 0, "green": 0, "orange": 0}, out
    assert out["after"]["red"] > 30 and out["after"]["green"] > 10, out  # the triad's x and y
    assert out["after"]["orange"] > 50, out  # the interface marker and its coupled nodes
    assert out["sameView"] and out["shape"] == 0, out  # camera and shape kept
    assert "interface 9 (rigid) and its" in out["legend"] and "frame" in out["legend"], out
    r, g, b = out["marker"]  # the marker is drawn at its position
    assert r > 200 and 90 < g < 140 and b < 40, out
    assert out["removed"] == {"red": 0, "green": 0, "orange": 0}, out


# Runs in the page: the colour drawn at two nodes (their indices in the title's input) with a
# shape shown undeformed, coloured by its translation and then by its per-node scalars.
SCALARS = (
    READBACK
    + """
try {
  const scene = JSON.parse(document.getElementById("scene").textContent);
  const probe = JSON.parse(document.getElementById("points").textContent);
  const v = new PymorembsViewer(canvas, scene);
  const at = (i) => pixelAt(v, Array.from(v._P.slice(3 * i, 3 * i + 3)));
  v.render();  // sizes the canvas
  v.setShape(0); v.setAmplitude(0);
  out.translation = probe.nodes.map(at);
  scene.shapes[0].scalars = probe.scalars;
  v.setShape(0); v.setAmplitude(0);
  out.scalars = probe.nodes.map(at);
  document.title = "probe " + JSON.stringify(out);
} catch (error) {
  document.title = "probe " + JSON.stringify({ error: String(error) });
}
"""
)


@pytest.mark.slow
def test_a_shape_with_scalars_is_coloured_by_them(tmp_path):
    """Issue #29: the app colours a shape by its von Mises stress (``scalars`` per node)."""
    _, scene = bent_blade()
    xyz = np.asarray(scene["positions"]).reshape(-1, 3)
    top = np.flatnonzero((np.abs(xyz[:, 1]) < 1e-9) & np.isclose(xyz[:, 2], xyz[:, 2].max()))
    root, tip = (int(top[np.argmin(np.abs(xyz[top, 0] - x))]) for x in (0.25, 0.95))
    scalars = np.where(xyz[:, 0] < 0.5, 3e8, 0.0).tolist()  # the root half stressed
    out = run_probe(tmp_path, scene, {"nodes": [root, tip], "scalars": scalars}, SCALARS)
    assert "error" not in out, out
    red = lambda rgb: rgb[0] > rgb[2] + 40  # noqa: E731
    blue = lambda rgb: rgb[2] > rgb[0] + 40  # noqa: E731
    assert blue(out["translation"][0]) and red(out["translation"][1]), out
    assert red(out["scalars"][0]) and blue(out["scalars"][1]), out
