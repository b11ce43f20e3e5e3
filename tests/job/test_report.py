"""The HTML report: valid HTML5, self-contained, every figure and table present."""

from __future__ import annotations

import base64
import json
import re

import html5lib
import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt

from pymorembs.report.html_report import write_report

SUMMARY = {
    "pymorembs_version": "0.1.0",
    "job": "examples/x.toml",
    "title": "A <test> & job",
    "model": {
        "name": "rack",
        "n_dof": 100,
        "n_independent": 90,
        "n_nodes": 34,
        "n_dependent": 4,
        "n_fixed": 6,
        "total_mass": 1.3866,
        "frame": {"type": "tangent", "node": 2},
        "damping": {"kind": "rayleigh", "alpha": 0.0, "beta": 1e-6, "ratio": 0.0},
        "inputs": ["1:ux"],
        "outputs": ["1:ux"],
    },
    "band_hz": [0.0, 1000.0],
    "n_frequencies": 201,
    "timings_s": {"prepare_s": 0.5, "total_s": 3.0},
    "warnings": ["something to know"],
    "reductions": [
        {
            "name": "kg",
            "method": "gramian",
            "order": 35,
            "max_rel_error": 1.06e-8,
            "static_rel_error": 1.0e-9,
            "error_estimate": None,
            "error_bound": 2e-7,
            "time_s": 11.2,
            "files": ["kg/reduced.npz", "kg/kg.SID_FEM"],
        }
    ],
    "time_domain": {
        "settings": {"step_s": 5e-5},
        "cases": [
            {
                "name": "step",
                "reductions": [
                    {"name": "kg", "max_rel_deviation": 1e-4, "speedup": 80.0, "time_s": 0.1}
                ],
            }
        ],
    },
    "files": ["summary.json", "error.png", "report.html"],
}


def figure(path, label):
    fig, ax = plt.subplots(figsize=(2, 1.5))
    ax.plot([0, 1], [1, 0], label=label)
    fig.savefig(path)
    plt.close(fig)
    return path


def test_report_is_valid_self_contained_html(tmp_path):
    figures = [
        (figure(tmp_path / "a.png", "a"), "error"),
        (figure(tmp_path / "b.png", "b"), "decay"),
    ]
    path = write_report(tmp_path / "report.html", SUMMARY, figures, job_text="[model]\nx = '<y>'\n")
    text = path.read_text()
    parser = html5lib.HTMLParser(strict=True)  # raises on any parse error
    document = parser.parse(text)
    images = document.findall(".//{http://www.w3.org/1999/xhtml}img")
    assert len(images) == 2
    for (png, _), image in zip(figures, images, strict=True):
        src = image.get("src")
        assert src.startswith("data:image/png;base64,")
        assert base64.b64decode(src.split(",", 1)[1]) == png.read_bytes()
    assert "A &lt;test&gt; &amp; job" in text  # escaped title
    assert "x = &#x27;&lt;y&gt;&#x27;" in text or "x = '&lt;y&gt;'" in text
    assert "kg/kg.SID_FEM" in text and "1.06e-08" in text and "something to know" in text
    assert not re.search(r"<script", text)  # no scripts, nothing fetched from elsewhere
    assert not re.search(r'src="(?!data:)', text)


def test_report_with_a_scene_carries_it_and_the_viewer_inline(tmp_path):
    """The 3D view: the scene as JSON and viewer.js inside the page, nothing fetched; a name
    with "</script>" in it cannot end the script early."""
    scene = {
        "positions": [0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0],
        "node_ids": [1, 2, 3],
        "triangles": [0, 1, 2],
        "lines": [],
        "frame": {"origin": [0.0, 0.0, 0.0], "axes": [[1, 0, 0], [0, 1, 0], [0, 0, 1]]},
        "interfaces": [{"name": "pin </script><!--", "node": 0, "coupled": [1, 2]}],
        "shapes": [{"name": "kg #1: 10 Hz", "values": [0.0] * 6 + [0.0, 0.0, 1.0]}],
        "size": 1.4142,
        "shapes_total": 40,
        "notes": ["1 of the 40 shape functions shown"],
    }
    path = write_report(tmp_path / "report.html", SUMMARY, [], scene=scene)
    text = path.read_text()
    document = html5lib.HTMLParser(strict=True).parse(text)
    namespace = "{http://www.w3.org/1999/xhtml}"
    scripts = document.findall(f".//{namespace}script")
    assert len(scripts) == 3 and not any(s.get("src") for s in scripts)
    data = [s for s in scripts if s.get("type") == "application/json"]
    assert json.loads(data[0].text) == scene
    assert "PymorembsViewer" in scripts[1].text
    assert "Body and shapes" in text and "1 of the 40 shape functions shown" in text
    assert document.find(f".//{namespace}canvas") is not None
    assert not re.search(r'src="(?!data:)', text) and "http" not in scripts[1].text
