"""The report's 3D view ("Body and shapes"): a job run through the command line, its page
opened in headless Chromium (software WebGL) and the screenshot checked for the body."""

from __future__ import annotations

import json
import re
import shutil
import subprocess

import matplotlib.image
import numpy as np
import pytest

from pymorembs.examples import build_example
from pymorembs.job.cli import main

CHROMIUM = shutil.which("chromium")

JOB = """
title = "blade with a rigid interface at its tip"
[model]
example = "blade"
elements = 4
[frame]
type = "none"
[[interface]]
node = 9
position = [1.0, 0.0, 0.0]
kind = "rigid"
box = { min = [0.9999, -1.0, -1.0], max = [1.0001, 1.0, 1.0] }
[[inputs]]
node = 9
directions = "ux uy uz"
[band]
f_min_hz = 0
f_max_hz = 100
points = 200
[[reduction]]
name = "modal"
method = "modal"
order = 5
export_inaccurate = true  # five modes up to 100 Hz: a small body for the view, on purpose
[export]
outputs = ["report"]
"""

BACKGROUND = (247, 249, 250)  # the canvas's clear colour (viewer.js COLORS.background)


@pytest.fixture(scope="module")
def report(tmp_path_factory):
    folder = tmp_path_factory.mktemp("view")
    (folder / "job.toml").write_text(JOB)
    assert main(["reduce", str(folder / "job.toml"), "--out", str(folder / "out"), "--quiet"]) == 0
    return folder / "out" / "report.html"


def scene_of(path):
    found = re.search(r'<script type="application/json" id="pymorembs-scene">(.*?)</script>',
                      path.read_text(), re.S)  # fmt: skip
    return json.loads(found.group(1))


@pytest.mark.slow
def test_report_scene_holds_the_shapes_and_the_interface(report):
    scene = scene_of(report)
    summary = json.loads((report.parent / "summary.json").read_text())
    (entry,) = summary["reductions"]
    names = [shape["name"] for shape in scene["shapes"]]
    assert names == [
        f"modal #{k + 1}: {f:.4g} Hz" for k, f in enumerate(entry["eigenfrequencies_hz"])
    ]
    body = build_example("blade", elements=4)
    tip = set(body.node_ids[np.isclose(body.coordinates[:, 0], 1.0)].tolist())
    (interface,) = scene["interfaces"]
    ids = np.array(scene["node_ids"])
    assert ids[interface["node"]] == 9 and set(ids[interface["coupled"]].tolist()) == tip
    assert scene["frame"] is None  # type = "none"


@pytest.mark.slow
@pytest.mark.skipif(CHROMIUM is None, reason="chromium not installed")
def test_report_view_renders_the_body_in_headless_chromium(report, tmp_path):
    shot = tmp_path / "view.png"
    result = subprocess.run(
        [CHROMIUM, "--headless", "--no-sandbox", "--disable-gpu", "--use-gl=swiftshader",
         "--enable-unsafe-swiftshader", "--disable-background-networking",
         "--disable-component-update", "--disable-sync", "--disable-quic", "--no-first-run",
         f"--user-data-dir={tmp_path / 'profile'}", "--window-size=1000,2400",
         "--virtual-time-budget=3000", f"--screenshot={shot}",
         report.as_uri() + "#shape=none"],
        capture_output=True, text=True, timeout=120,
    )  # fmt: skip
    assert shot.is_file(), result.stderr[-2000:]
    image = np.round(255 * matplotlib.image.imread(shot)[..., :3]).astype(int)  # PNG: 0..1
    # The canvas is where its clear colour is; the body is drawn inside it.
    canvas = np.all(image == BACKGROUND, axis=2)
    rows, columns = np.nonzero(canvas)
    assert rows.size > 100_000, "no canvas in the screenshot"
    inside = image[rows.min() : rows.max() + 1, columns.min() : columns.max() + 1]
    r, g, b = inside[..., 0], inside[..., 1], inside[..., 2]
    body = (b > r + 25) & (b > g)  # the surface's blue, shaded
    orange = (r > 180) & (g > 70) & (g < 160) & (b < 60)  # interface 1's colour
    assert body.sum() > 0.01 * body.size, f"{body.sum()} body pixels of {body.size}"
    assert orange.sum() > 30, f"{orange.sum()} pixels of the interface's colour"
