"""``pymorembs app`` driven by a real headless Chromium, as a person would use it (issue #17).

Open the built-in rack, pick the upper hole's wall as a rigid interface, choose the tangent
frame there, add a Krylov and a modal reduction, run, read the errors off the page, save the
job, and check that ``pymorembs reduce`` on the saved job gives the same numbers. Screenshots
of each step go to ``out/test-artifacts/app/`` (kept by CI as artefacts).

Needs Debian's ``chromium`` (or ``PYMOREMBS_CHROMIUM``) and the ``playwright`` package; skipped
without them. Playwright drives the system browser: no browser download.
"""

from __future__ import annotations

import json
import os
import shutil
import threading
from pathlib import Path

import numpy as np
import pytest
from test_app_stress_history import JOB

from pymorembs import example, select_nodes
from pymorembs.job.app import App, make_server
from pymorembs.job.cli import main
from pymorembs.job.schema import EXPORT_KINDS

ARTIFACTS = Path(__file__).resolve().parents[2] / "out" / "test-artifacts" / "app"
CHROMIUM_ARGS = [
    "--no-sandbox", "--disable-gpu", "--disable-background-networking",
    "--disable-component-update", "--disable-sync", "--no-first-run",
    "--use-gl=swiftshader", "--use-angle=swiftshader", "--enable-unsafe-swiftshader",
]  # fmt: skip
DOFS = 10000  # the rack-solid generator at 10,359 dofs: the same mesh family, a shorter run


def chromium() -> str | None:
    return os.environ.get("PYMOREMBS_CHROMIUM") or shutil.which("chromium")


@pytest.fixture
def browser():
    sync_api = pytest.importorskip("playwright.sync_api")
    path = chromium()
    if path is None:
        pytest.skip("no chromium on this machine (set PYMOREMBS_CHROMIUM)")
    with sync_api.sync_playwright() as p:
        launched = p.chromium.launch(executable_path=path, args=CHROMIUM_ARGS)
        yield launched
        launched.close()


@pytest.fixture
def served(tmp_path):
    app = App(tmp_path / "work")
    server = make_server(app, 0)
    thread = threading.Thread(target=server.serve_forever, daemon=True)
    thread.start()
    yield app, f"http://127.0.0.1:{server.server_address[1]}/"
    if app.runs.run is not None:
        app.runs.run.cancel()
    server.shutdown()
    server.server_close()


def hole_nodes() -> np.ndarray:
    """The wall of the upper plate's hole by the numbers of the rack's drawing (Ø 30 mm,
    204 <= z <= 221 mm): the reference for what a click on it must select."""
    body = example("rack-solid", dofs=DOFS, interface="none")
    return select_nodes(
        body,
        cylinder=((0.0, 0.0, 0.2125), (0.0, 0.0, 1.0), 0.015, 1e-6),
        box=((-0.02, -0.02, 0.2039), (0.02, 0.02, 0.2211)),
    )


#: In the page: a canvas point whose pick is a triangle of the hole's wall (from the scene's
#: positions), scanning the canvas on a grid; null if none is visible.
FIND_HOLE = """() => {
  const v = window.app.viewer, s = window.app.scene, r = v.canvas.getBoundingClientRect();
  for (let y = r.top + 4; y < r.bottom; y += 4) for (let x = r.left + 4; x < r.right; x += 4) {
    const t = v.pickTriangle(x, y);
    if (t === null) continue;
    let wall = true;
    for (let c = 0; c < 3; c++) {
      const i = s.triangles[3 * t + c], p = s.positions.slice(3 * i, 3 * i + 3);
      if (Math.abs(Math.hypot(p[0], p[1]) - 0.015) > 1e-5 || p[2] < 0.204 - 1e-6) wall = false;
    }
    if (wall) return [x, y];
  }
  return null;
}"""


#: In the page: pixels of the frame triad's red axis and of the first interface colour
#: (orange) in the 3D view, and the colour drawn where the world point p projects.
PIXELS = """(p) => {
  const v = window.app.viewer, gl = v.gl;
  v.render();
  const w = gl.drawingBufferWidth, h = gl.drawingBufferHeight, data = new Uint8Array(4 * w * h);
  gl.readPixels(0, 0, w, h, gl.RGBA, gl.UNSIGNED_BYTE, data);
  let red = 0, orange = 0;
  for (let i = 0; i < data.length; i += 4) {
    const [r, g, b] = [data[i], data[i + 1], data[i + 2]];
    if (r > 180 && g < 60 && b < 60) red++;
    if (r > 200 && g > 90 && g < 140 && b < 40) orange++;
  }
  const m = v._matrices().pv, [x, y, z] = p;
  const q = m[3] * x + m[7] * y + m[11] * z + m[15];
  const px = Math.round(((m[0] * x + m[4] * y + m[8] * z + m[12]) / q + 1) / 2 * w);
  const py = Math.round(((m[1] * x + m[5] * y + m[9] * z + m[13]) / q + 1) / 2 * h);
  const at = Array.from(data.slice(4 * (py * w + px), 4 * (py * w + px) + 3));
  return { red, orange, at };
}"""
HOLE_CENTRE = [0.0, 0.0, 0.2125]  # the upper hole's axis, halfway along the hole


def orange(rgb: list[int]) -> bool:
    r, g, b = rgb
    return r > 200 and 90 < g < 140 and b < 40


@pytest.mark.slow
def test_pick_run_save_and_reduce_again(browser, served, tmp_path):
    app, url = served
    ARTIFACTS.mkdir(parents=True, exist_ok=True)
    page = browser.new_page(viewport={"width": 1500, "height": 1150})
    errors: list[str] = []
    page.on("pageerror", lambda exc: errors.append(str(exc)))
    step = iter(range(1, 100))

    def shot(name: str) -> None:
        page.screenshot(path=str(ARTIFACTS / f"{next(step):02d}-{name}.png"))

    page.goto(url)
    page.wait_for_selector("body[data-ready='1']")
    page.select_option("#example-name", "rack-solid")
    page.fill("#example-dofs", str(DOFS))
    page.click("#open-example")
    page.wait_for_function("window.app.viewer && window.app.viewer.frames > 0")
    page.wait_for_selector("#first-modes", timeout=120_000)
    shot("opened")
    assert app.model.body.n_dof == 10359
    # the new job's Buckens frame is drawn at the centre of gravity, no interface yet
    page.wait_for_selector("#canvas[data-decorations='1,0']")
    opened = page.evaluate(PIXELS, HOLE_CENTRE)
    assert opened["red"] > 10 and opened["orange"] == 0 and not orange(opened["at"]), opened

    # pick the hole: a click on its wall in pick mode
    page.click("#pick-mode")
    point = page.evaluate(FIND_HOLE)
    assert point is not None, "the hole's wall is not visible in the default view"
    page.mouse.click(*point)
    page.wait_for_selector("#selection[data-count]")
    reference = hole_nodes()
    assert int(page.get_attribute("#selection", "data-count")) == reference.size
    assert "round hole, radius 0.015" in page.text_content("#selection")
    shot("hole-picked")
    page.select_option("#iface-kind", "rigid")
    page.fill("#iface-node", "2")
    page.click("#add-interface")
    page.click("#pick-mode")  # picking off

    # tangent frame at the new node, forces at node 1 and 2, band 0-1000 Hz
    page.select_option("#frame-type", "tangent")
    page.fill("#frame-node", "2")
    page.dispatch_event("#frame-node", "change")
    for node in ("1", "2"):
        page.fill("#port-node", node)
        page.fill("#port-directions", "ux uy uz")
        page.click("#add-input")
    page.wait_for_function("document.getElementById('toml').textContent.includes('[[inputs]]')")
    # the view draws the new interface node at the hole's centre, its coupled nodes and the
    # tangent frame's triad there, without a new scene (the view stays where it was turned)
    page.wait_for_selector("#canvas[data-decorations='1,1']")  # the interface, a triad
    page.wait_for_function(  # the triad moved from the centre of gravity to the tangent frame
        "(p) => JSON.stringify(window.app.viewer.scene.frame.origin) === JSON.stringify(p)",
        arg=HOLE_CENTRE,
    )
    drawn = page.evaluate(PIXELS, HOLE_CENTRE)
    assert drawn["red"] > 10 and drawn["orange"] > 50 and orange(drawn["at"]), drawn
    shot("interface-and-frame")

    # a Krylov and a modal reduction, options in the forms made from the registry
    page.select_option("#method", "krylov")
    page.click("#add-reduction")
    card = page.locator(".reduction[data-name='krylov']")
    card.locator("[data-option='expansion_points_hz']").fill("0, 500")
    card.locator("[data-option='expansion_points_hz']").dispatch_event("change")
    card.locator("[data-option='order']").fill("12")
    card.locator("[data-option='order']").dispatch_event("change")
    page.select_option("#method", "modal")
    page.click("#add-reduction")
    card = page.locator(".reduction[data-name='modal']")
    card.locator("[data-option='order']").fill("12")
    card.locator("[data-option='order']").dispatch_event("change")
    # 12 modes miss the accuracy limit 1e-2 (issue #27): written only when the job says so
    card.locator("[data-option='export_inaccurate']").check()
    page.wait_for_function(
        "document.getElementById('toml').textContent.includes('method = \"modal\"') && "
        "document.getElementById('toml').textContent.includes('order = 12') && "
        "document.getElementById('job-error').textContent === ''"
    )
    page.wait_for_function(
        "document.getElementById('toml').textContent.includes('export_inaccurate = true')"
    )
    text = page.text_content("#toml")
    assert 'kind = "rigid"' in text and "cylinder = {" in text
    assert '[frame]\ntype = "tangent"\nnode = 2' in text
    shot("job-ready")

    # run, with the progress bar, and read the errors off the page
    page.click("#run")
    page.wait_for_selector("#stage[data-state='running']")
    shot("running")
    page.wait_for_selector("#stage[data-state='done']", timeout=600_000)
    page.wait_for_selector("#results-table tr[data-name='modal'] td.max-error")
    page.wait_for_function("document.querySelector('#plot polyline')")
    shot("results")
    shown = {
        name: (
            int(page.text_content(f"#results-table tr[data-name='{name}'] td.order")),
            page.text_content(f"#results-table tr[data-name='{name}'] td.max-error"),
        )
        for name in ("krylov", "modal")
    }
    # the modal body missed its accuracy and says so; the Krylov body met it
    assert page.get_attribute("#results-table tr[data-name='modal']", "data-accuracy") == "not-met"
    assert page.get_attribute("#results-table tr[data-name='krylov']", "data-accuracy") == "met"
    # a shape function in the 3D view, and the MAC between the bases
    page.select_option("#shape-reduction", "krylov")
    page.select_option("#shape-k", "0")
    page.wait_for_function("document.getElementById('shape-hz').textContent.includes('Hz')")
    page.wait_for_function("document.getElementById('mac').dataset.diagonal")
    assert page.get_attribute("#mac-note", "data-weighting") == "mass"
    assert page.text_content("#mac-note").startswith("mass-weighted")
    shot("shape")

    # save the job and reduce it again from the command line
    saved = tmp_path / "saved.toml"
    page.fill("#save-path", str(saved))
    page.click("#save")
    page.wait_for_selector("#saved[data-path]")
    assert saved.read_text(encoding="utf-8") == text
    # exit 0: the modal body misses its accuracy, but the job asks for it (export_inaccurate)
    assert main(["reduce", str(saved), "--out", str(tmp_path / "again"), "--quiet"]) == 0
    summary = json.loads((tmp_path / "again" / "summary.json").read_text(encoding="utf-8"))
    again = {r["name"]: (r["order"], f"{r['max_rel_error']:.3e}") for r in summary["reductions"]}
    for name, (order, error) in shown.items():
        assert again[name][0] == order
        assert float(error) == pytest.approx(float(again[name][1]), rel=1e-3)
    # the Krylov basis reaches far below modal truncation of the same order (paper section 5)
    assert float(shown["krylov"][1]) < 0.1 * float(shown["modal"][1])
    assert errors == []


@pytest.mark.slow
def test_the_export_boxes_are_the_job_parsers_and_keep_the_jobs_outputs(browser, served, tmp_path):
    """A job file that writes VTU files keeps them when another box is ticked (the page's own
    list of exports had no ``vtu`` and dropped it)."""
    app, url = served
    job = tmp_path / "job.toml"
    job.write_text(
        '[model]\nexample = "rack-beams"\n[frame]\ntype = "none"\n[band]\nf_max_hz = 100\n'
        '[[reduction]]\nmethod = "modal"\norder = 4\n[export]\noutputs = ["sid", "vtu"]\n',
        encoding="utf-8",
    )
    app.open({"path": str(job)})
    page = browser.new_page()
    errors: list[str] = []
    page.on("pageerror", lambda exc: errors.append(str(exc)))
    page.goto(url)
    page.wait_for_selector("body[data-ready='1']")
    boxes = page.eval_on_selector_all("[data-export]", "(els) => els.map((e) => e.dataset.export)")
    assert boxes == list(EXPORT_KINDS)
    assert page.is_checked("[data-export='vtu']") and not page.is_checked("[data-export='mtx']")
    page.check("[data-export='mtx']")
    page.wait_for_function("document.getElementById('toml').textContent.includes('\"mtx\"')")
    assert app.editor.draft["export"]["outputs"] == ["npz", "mtx", "sid", "vtu"]
    assert errors == []


#: In the page: a hot spot's marker that a click hits (the pick under its pixel is its own scene
#: node), other than the hot spot shown first: its client coordinates and scene row, or null.
FIND_MARKER = """() => {
  const v = window.app.viewer, spots = window.app.hotSpots, r = v.canvas.getBoundingClientRect();
  const m = v._matrices().pv, X = window.app.scene.positions, shown = spots.rows[0];
  for (const row of spots.rows) {
    if (row === shown) continue;
    const [x, y, z] = X.slice(3 * row, 3 * row + 3), q = m[3] * x + m[7] * y + m[11] * z + m[15];
    const cx = r.left + ((m[0] * x + m[4] * y + m[8] * z + m[12]) / q + 1) / 2 * r.width;
    const cy = r.top + (1 - (m[1] * x + m[5] * y + m[9] * z + m[13]) / q) / 2 * r.height;
    if (v.pickNode(cx, cy) === row) return { x: cx, y: cy, row };
  }
  return null;
}"""


@pytest.mark.slow
def test_a_click_on_a_hot_spot_plots_its_stress_over_time(browser, served, tmp_path):
    """Issue #29 item 2: after a run with ``[stress]`` and ``[time_domain]`` the hot spots are
    marked; a click on one plots sigma_vM(t) of the full model and the reduced body."""
    app, url = served
    ARTIFACTS.mkdir(parents=True, exist_ok=True)
    assert app.open({"example": "blade", "options": {"elements": 4}})["model"] is not None
    app.edit(app.editor.draft | JOB)
    page = browser.new_page(viewport={"width": 1500, "height": 1150})
    errors: list[str] = []
    page.on("pageerror", lambda exc: errors.append(str(exc)))
    page.goto(url)
    page.wait_for_selector("body[data-ready='1']")
    page.wait_for_function("window.app.viewer && window.app.viewer.frames > 0")
    page.click("#run")
    page.wait_for_selector("#stage[data-state='done']", timeout=600_000)
    page.wait_for_selector("#stress-note[data-available='1']")
    page.wait_for_selector("#stress-plot[data-point]")
    first = page.get_attribute("#stress-plot", "data-point")
    marker = page.evaluate(FIND_MARKER)
    assert marker is not None, "no hot spot's marker is visible in the default view"
    page.mouse.click(marker["x"], marker["y"])
    page.wait_for_function(
        "(p) => document.getElementById('stress-plot').dataset.point !== p", arg=first
    )
    shown = page.get_attribute("#stress-plot", "data-point")
    spots = page.evaluate("window.app.hotSpots")
    assert spots["rows"][spots["points"].index(shown)] == marker["row"]  # the clicked one's
    bodies = page.eval_on_selector_all(
        "#stress-plot polyline", "(els) => els.map((e) => e.dataset.body)"
    )
    assert bodies == ["full", "krylov", "full", "krylov"]  # step and harmonic
    assert page.locator("#stress-table tr[data-body='krylov'] td.peak").count() == 2
    page.screenshot(path=str(ARTIFACTS / "hot-spot-marked.png"))
    page.locator("#stress-plot").screenshot(path=str(ARTIFACTS / "hot-spot-stress.png"))
    assert errors == []
