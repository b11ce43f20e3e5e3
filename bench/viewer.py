"""The 3D viewer (``pymorembs/report/viewer.js``) on large bodies, in headless Chromium.

Two bodies:

``rack-solid``
    the built-in rack at ``--dofs`` (its hex20 skin), the scene made by
    ``pymorembs.report.scene.body_scene`` with ``--shapes`` smooth shapes (translations
    ``sin``/``cos`` of the coordinates: their rounded numbers print as long as real shapes'),
``torus``
    a closed triangulated torus of ``--nodes`` surface nodes (two triangles per node) with the
    same kind of shapes, as many as the report's cap lets through (``SCENE_VALUES`` numbers),
    built here as a scene dict: the 100,000+ surface nodes the viewer is meant to handle,
    which the rack reaches only at millions of dofs.

Measured: the scene's size (nodes, triangles, JSON bytes) and the time to build and encode it in
Python; in Chromium (``--use-gl=swiftshader``: software WebGL on the CPU, slower than any GPU)
the time to parse the JSON, to set the scene up (typed arrays, normals, feature edges, buffers)
and draw the first frame, to show a shape (its per-triangle normal terms and buffer uploads),
one frame while rotating (mean of 10, each finished with a one-pixel ``readPixels``) and one
``pickNode`` (a ray against every triangle). Times in the page come from ``performance.now()``.

Usage::

    .venv/bin/python bench/viewer.py --dofs 35000 --nodes 150000 [--shapes 12]
"""

from __future__ import annotations

import argparse
import json
import re
import shutil
import subprocess
import tempfile
import time
from pathlib import Path

import numpy as np
from _common import fmt_s, machine_facts, markdown_table, update_results

from pymorembs.examples import build_example
from pymorembs.report.scene import SCENE_VALUES, body_scene, viewer_script

PROBE = """
const canvas = document.getElementById("view");
const text = document.getElementById("scene").textContent;
function finish(v) {  // wait for the drawing
  v.gl.readPixels(0, 0, 1, 1, v.gl.RGBA, v.gl.UNSIGNED_BYTE, new Uint8Array(4));
}
try {
  const out = {};
  let t = performance.now();
  const scene = JSON.parse(text);
  out.parse = performance.now() - t;
  t = performance.now();
  const v = new PymorembsViewer(canvas, scene);
  v.render(); finish(v);
  out.setup = performance.now() - t;
  t = performance.now();
  v.setShape(0); v.render(); finish(v);
  out.shape = performance.now() - t;
  t = performance.now();
  for (let k = 0; k < 10; k++) {
    const c = Math.cos(0.05), s = Math.sin(0.05), R = v._R;
    v._R = [c * R[0] + s * R[6], c * R[1] + s * R[7], c * R[2] + s * R[8], R[3], R[4], R[5],
      -s * R[0] + c * R[6], -s * R[1] + c * R[7], -s * R[2] + c * R[8]];
    v.render(); finish(v);
  }
  out.frame = (performance.now() - t) / 10;
  const r = canvas.getBoundingClientRect();
  t = performance.now();
  out.picked = v.pickNode(r.left + r.width / 2, r.top + r.height / 2);
  out.pick = performance.now() - t;
  out.frames = v.frames;
  document.title = "bench " + JSON.stringify(out);
} catch (error) {
  document.title = "bench " + JSON.stringify({ error: String(error) });
}
"""


def smooth_shapes(points: np.ndarray, count: int) -> list[np.ndarray]:
    """``count`` smooth translation fields over ``points`` (n, 3), flat (3 n) each."""
    span = np.ptp(points, axis=0).max() or 1.0
    x = points / span
    return [
        np.column_stack(
            [np.sin((k + 1) * np.pi * x[:, 2]), np.cos((k + 1) * np.pi * x[:, 0]), x[:, 1] ** 2]
        ).ravel()
        for k in range(count)
    ]


def rack_scene(dofs: int, shapes: int) -> tuple[dict, float]:
    body = build_example("rack-solid", dofs=dofs)
    basis = np.zeros((body.n_dof, shapes))
    rows = body.node_rows(body.dofs.nodes)
    fields = np.stack(smooth_shapes(body.coordinates, shapes), axis=1).reshape(-1, 3, shapes)
    translation = body.dofs.directions < 3
    basis[translation] = fields[rows[translation], body.dofs.directions[translation]]
    tick = time.perf_counter()
    scene = body_scene(body, basis=basis)
    return scene, time.perf_counter() - tick


def torus_scene(nodes: int, shapes: int) -> tuple[dict, float]:
    tick = time.perf_counter()
    nv = max(8, round(np.sqrt(nodes / 3)))
    nu = max(8, nodes // nv)
    angles = (np.arange(nu) * 2 * np.pi / nu, np.arange(nv) * 2 * np.pi / nv)
    u, v = np.meshgrid(*angles, indexing="ij")
    major, minor = 1.0, 0.3
    points = np.column_stack(
        [
            ((major + minor * np.cos(v)) * np.cos(u)).ravel(),
            ((major + minor * np.cos(v)) * np.sin(u)).ravel(),
            (minor * np.sin(v)).ravel(),
        ]
    )
    i, j = np.meshgrid(np.arange(nu), np.arange(nv), indexing="ij")
    a = (i * nv + j).ravel()
    b = (((i + 1) % nu) * nv + j).ravel()
    c = (((i + 1) % nu) * nv + (j + 1) % nv).ravel()
    d = (i * nv + (j + 1) % nv).ravel()
    triangles = np.column_stack([a, b, c, a, c, d]).reshape(-1, 3)
    shapes = max(1, min(shapes, SCENE_VALUES // points.size))
    scene = {
        "positions": np.round(points.astype(np.float32).astype(float), 6).ravel().tolist(),
        "node_ids": list(range(1, len(points) + 1)),
        "triangles": triangles.ravel().tolist(),
        "lines": [],
        "frame": {"origin": [0.0, 0.0, 0.0], "axes": np.eye(3).tolist()},
        "interfaces": [],
        "shapes": [
            {"name": f"shape {k + 1}", "values": np.round(values, 4).tolist()}
            for k, values in enumerate(smooth_shapes(points, shapes))
        ],
        "size": float(np.linalg.norm(np.ptp(points, axis=0))),
    }
    return scene, time.perf_counter() - tick


def in_chromium(scene: dict, folder: Path) -> tuple[dict, int, float]:
    tick = time.perf_counter()
    data = json.dumps(scene, separators=(",", ":")).replace("<", "\\u003c")
    encode = time.perf_counter() - tick
    page = folder / "bench.html"
    page.write_text(
        '<!DOCTYPE html><html><head><meta charset="utf-8"><title>wait</title><style>'
        "body{margin:0} div{width:1000px;height:700px} canvas{width:100%;height:100%}</style>"
        '</head><body><div><canvas id="view"></canvas></div>'
        f'<script type="application/json" id="scene">{data}</script>'
        f"<script>{viewer_script()}</script><script>{PROBE}</script></body></html>"
    )
    chromium = shutil.which("chromium")
    if chromium is None:
        raise SystemExit("bench/viewer.py needs chromium (Debian's package)")
    result = subprocess.run(
        [chromium, "--headless", "--no-sandbox", "--disable-gpu", "--use-gl=swiftshader",
         "--enable-unsafe-swiftshader", "--disable-background-networking",
         "--disable-component-update", "--disable-sync", "--disable-quic", "--no-first-run",
         f"--user-data-dir={folder / 'profile'}", "--window-size=1100,800", "--dump-dom",
         page.as_uri()],
        capture_output=True, text=True, timeout=900,
    )  # fmt: skip
    found = re.search(r"<title>bench (.*)</title>", result.stdout)
    if not found:
        raise SystemExit("no result from chromium:\n" + result.stderr[-2000:])
    out = json.loads(found.group(1).replace("&quot;", '"'))
    if "error" in out:
        raise SystemExit(f"viewer error: {out['error']}")
    return out, len(data), encode


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--dofs", type=int, nargs="*", default=[35000])
    parser.add_argument("--nodes", type=int, nargs="*", default=[150000])
    parser.add_argument("--shapes", type=int, default=12)
    parser.add_argument("--no-results", action="store_true")
    args = parser.parse_args()
    rows = []
    shapes = args.shapes
    cases = [("rack-solid", f"{d:,} dofs", lambda d=d: rack_scene(d, shapes)) for d in args.dofs]
    cases += [("torus", f"{n:,} nodes", lambda n=n: torus_scene(n, shapes)) for n in args.nodes]
    for name, size, make in cases:
        scene, build = make()
        with tempfile.TemporaryDirectory() as folder:
            out, length, encode = in_chromium(scene, Path(folder))
        n_nodes = len(scene["positions"]) // 3
        n_triangles = len(scene["triangles"]) // 3
        row = [
            name, size, f"{n_nodes:,}", f"{n_triangles:,}", len(scene["shapes"]),
            f"{length / 1e6:.1f}", fmt_s(build + encode), f"{out['parse']:.0f}",
            f"{out['setup']:.0f}", f"{out['shape']:.0f}", f"{out['frame']:.0f}",
            f"{1000 / out['frame']:.1f}", f"{out['pick']:.0f}",
        ]  # fmt: skip
        rows.append(row)
        print(" | ".join(map(str, row)), flush=True)
    headers = [
        "body", "size", "scene nodes", "triangles", "shapes", "JSON [MB]",
        "scene + JSON in Python [s]", "JSON.parse [ms]", "set up + first frame [ms]",
        "show a shape [ms]", "one frame [ms]", "frames/s", "pickNode [ms]",
    ]  # fmt: skip
    table = markdown_table(headers, rows)
    print(table)
    if not args.no_results:
        note = (
            "Headless Chromium with SwiftShader (software WebGL on the CPU cores the other work "
            "shares; a GPU draws far faster), canvas 1000 × 700 CSS px. Animating a shape costs "
            "one frame each and writes no buffer: the deformed positions are formed in the vertex "
            "shader from two node buffers (the shape's written once when it is chosen), the "
            "normals come from the drawn triangles."
        )
        update_results("3D viewer (report and app)", table + "\n\n" + note, machine_facts())


if __name__ == "__main__":
    main()
