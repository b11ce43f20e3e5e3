"""The app's 3D view in headless Chromium: time from opening a model to a rotating view, and
frames per second while rotating (issue #17 item 5).

The app's server (``pymorembs.job.app``) runs in this process on a free port; Debian's
Chromium (software WebGL: SwiftShader) opens the page, and for each model the script

1. sets the built-in ``rack-solid`` with ``--dofs`` in the page and clicks "Open example",
   the way a person opens it (the server builds the model, sends its scene, the page draws it);
2. waits for the first frame of the body (``viewer.frames``), then drags the mouse across the
   view for ``--seconds`` with the left button held (rotation) and counts the frames the viewer
   drew and the mouse events the page handled.

Reported: open -> first frame (s), open -> first rotated frame (s), the share of it in the
server's open and scene requests, frames drawn per second while rotating, mouse events per
second (how promptly the page answers), the scene's nodes and triangles. The baseline, measured
in the same run and page, is the smallest rack-solid (``--baseline-dofs``): what the page, the
browser and the software renderer cost without a large model. The eigenfrequencies the page
asks for after opening are computed by the server at the same time, as they are for a user.

Usage::

    .venv/bin/python bench/app_view.py --dofs 35000 300000
    .venv/bin/python bench/app_view.py --dofs 35000 --no-results
"""

from __future__ import annotations

import argparse
import os
import re
import shutil
import sys
import tempfile
import threading
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

from _common import fmt_s, machine_facts, markdown_table, update_results

from pymorembs.job.app import App, make_server

CHROMIUM_ARGS = [
    "--no-sandbox", "--disable-gpu", "--disable-background-networking",
    "--disable-component-update", "--disable-sync", "--no-first-run",
    "--use-gl=swiftshader", "--use-angle=swiftshader", "--enable-unsafe-swiftshader",
]  # fmt: skip
SECTION = "App 3D view (headless Chromium)"


def measure(browser, dofs: int, seconds: float) -> dict:
    """A new server and page; open rack-solid with ``dofs`` there; the times and rates."""
    server = make_server(App(Path(tempfile.mkdtemp(prefix="app-view-"))), 0)
    threading.Thread(target=server.serve_forever, daemon=True).start()
    page = browser.new_page(viewport={"width": 1500, "height": 950})
    try:
        page.goto(f"http://127.0.0.1:{server.server_address[1]}/")
        return _measure(page, dofs, seconds)
    finally:
        page.close()
        server.shutdown()
        server.server_close()


def _measure(page, dofs: int, seconds: float) -> dict:
    page.wait_for_selector("body[data-ready='1']")
    page.evaluate(
        "window.__raf = 0; (function f() { window.__raf++; requestAnimationFrame(f); })()"
    )
    page.select_option("#example-name", "rack-solid")
    page.fill("#example-dofs", str(dofs))
    start = time.perf_counter()
    page.click("#open-example")
    page.wait_for_function(
        "document.getElementById('job-error').textContent.startsWith('rack-solid') || "
        "(window.app.viewer && window.app.scene && window.app.viewer.scene === window.app.scene "
        "&& window.app.viewer.frames > 0)",
        timeout=600_000,
        polling=10,
    )
    drawn = time.perf_counter() - start
    if page.text_content("#job-error").startswith("rack-solid"):
        raise SystemExit(f"app_view: {page.text_content('#job-error')}")
    box = page.locator("#canvas").bounding_box()
    cx, cy = box["x"] + box["width"] / 2, box["y"] + box["height"] / 2
    before = page.evaluate("window.app.viewer.frames")
    page.mouse.move(cx, cy)
    page.mouse.down()
    page.mouse.move(cx + 10, cy + 5)
    page.wait_for_function(f"window.app.viewer.frames > {before}", polling=5)
    rotating = time.perf_counter() - start
    frames0, raf0 = page.evaluate("[window.app.viewer.frames, window.__raf]")
    tick, moves = time.perf_counter(), 0
    while time.perf_counter() - tick < seconds:
        moves += 1
        page.mouse.move(cx + 150 * ((moves % 40) / 20 - 1), cy + 40 * ((moves % 14) / 7 - 1))
    frames1, raf1 = page.evaluate("[window.app.viewer.frames, window.__raf]")
    elapsed = time.perf_counter() - tick
    page.mouse.up()
    timing = page.evaluate(
        "Object.fromEntries(performance.getEntriesByType('resource')"
        ".filter(e => e.name.includes('/api/open') || e.name.includes('/api/scene'))"
        ".map(e => [new URL(e.name).pathname, e.duration / 1000]))"
    )
    scene = page.evaluate(
        "[window.app.scene.node_ids.length, window.app.scene.triangles.length / 3, "
        "window.app.scene.positions.length]"
    )
    draw_ms = page.evaluate(
        """() => {
      const v = window.app.viewer, gl = v.gl, pixel = new Uint8Array(4);
      v.render(); gl.readPixels(0, 0, 1, 1, gl.RGBA, gl.UNSIGNED_BYTE, pixel);
      const t = performance.now();
      for (let k = 0; k < 20; k++) {
        v.render(); gl.readPixels(0, 0, 1, 1, gl.RGBA, gl.UNSIGNED_BYTE, pixel);
      }
      return (performance.now() - t) / 20;
    }"""
    )
    return {
        "draw_ms": draw_ms,
        "model_dofs": int(
            re.sub(r"\D", "", page.text_content("#model-name").split(":")[1].split("dofs")[0])
        ),
        "nodes": scene[0],
        "triangles": int(scene[1]),
        "drawn_s": drawn,
        "rotating_s": rotating,
        "open_s": timing.get("/api/open", float("nan")),
        "scene_s": timing.get("/api/scene", float("nan")),
        "fps": (frames1 - frames0) / elapsed,
        "raf_per_s": (raf1 - raf0) / elapsed,
        "events_per_s": moves / elapsed,
    }


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--dofs", type=int, nargs="+", default=[35000])
    parser.add_argument("--baseline-dofs", type=int, default=7365, help="the coarsest mesh")
    parser.add_argument("--seconds", type=float, default=4.0, help="rotation time per model")
    parser.add_argument("--repeat", type=int, default=2, help="runs per model (best kept)")
    parser.add_argument("--no-results", action="store_true", help="do not write RESULTS.md")
    args = parser.parse_args()
    chromium = os.environ.get("PYMOREMBS_CHROMIUM") or shutil.which("chromium")
    if chromium is None:
        sys.stderr.write("app_view: no chromium (set PYMOREMBS_CHROMIUM)\n")
        return 2
    from playwright.sync_api import sync_playwright

    rows, results = [], []
    with sync_playwright() as p:
        browser = p.chromium.launch(executable_path=chromium, args=CHROMIUM_ARGS)
        for label, dofs in [("baseline", args.baseline_dofs)] + [("model", d) for d in args.dofs]:
            runs = [measure(browser, dofs, args.seconds) for _ in range(args.repeat)]
            best = min(runs, key=lambda r: r["rotating_s"])
            best["fps"] = max(r["fps"] for r in runs)
            best["events_per_s"] = max(r["events_per_s"] for r in runs)
            best["draw_ms"] = min(r["draw_ms"] for r in runs)
            best["label"] = label
            results.append(best)
            row = [
                label, f"{best['model_dofs']:,}", f"{best['nodes']:,}", f"{best['triangles']:,}",
                fmt_s(best["open_s"]), fmt_s(best["scene_s"]), fmt_s(best["drawn_s"]),
                fmt_s(best["rotating_s"]), f"{best['fps']:.0f}", f"{best['events_per_s']:.0f}",
                f"{best['draw_ms']:.1f}", f"{1000 / best['draw_ms']:.0f}",
            ]  # fmt: skip
            rows.append(row)
            print(" | ".join(row), flush=True)
        browser.close()
    headers = [
        "", "dofs", "scene nodes", "triangles", "open request [s]", "scene request [s]",
        "open -> first frame [s]", "open -> rotating [s]", "frames/s rotating",
        "mouse events/s", "one frame [ms]", "frames/s possible",
    ]  # fmt: skip
    table = markdown_table(headers, rows)
    print(table)
    if not args.no_results:
        body = (
            "`pymorembs app` in headless Chromium (Debian's package, software WebGL: "
            "SwiftShader, `--disable-gpu`), 1500 × 950 px page: rack-solid opened from the "
            "page's 'Open example' (server builds the model and its scene, the page draws it); "
            f"then {args.seconds:g} s of left-button drag (rotation); best of {args.repeat}. "
            "'open -> rotating': from the click to the first frame drawn after the drag "
            "began. Frames/s: frames the viewer drew while rotating; mouse events/s: how "
            "many drag events the page handled (Playwright waits for each; the viewer "
            "draws once per event, so these two are the input rate); one frame: the time "
            "of `render()` plus a one-pixel read-back (which waits for the drawing), 20 in "
            "a row, and the frame rate that allows. Baseline: the smallest rack-solid, in a "
            "new page of a new server like every run. The server computes the model's "
            "eigenfrequencies for the page at the same time (2 cores).\n\n" + table
        )
        print(f"written: {update_results(SECTION, body, machine_facts())}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
