"""One self-contained HTML page per job: facts, settings, plots, the table of methods, files.

The plots are embedded as base64 PNG data URIs, so the page can be mailed or archived alone. The
page is plain HTML5 with a small inline style sheet. With a scene
(:mod:`pymorembs.report.scene`) it gets the section "Body and shapes": the 3D viewer
(``viewer.js``) and the scene as JSON, both inline, so the page still needs no other file and
no network; without one it has no scripts.
"""

from __future__ import annotations

import base64
import html
import json
import math
from pathlib import Path
from typing import Any

from pymorembs.io.atomic import write_text
from pymorembs.report.scene import viewer_script
from pymorembs.report.stress_table import stress_modes_table

_STYLE = """
body { font-family: system-ui, sans-serif; margin: 2em auto; max-width: 68em; color: #222; }
h1 { font-size: 1.5em; } h2 { font-size: 1.2em; margin-top: 1.6em; }
table { border-collapse: collapse; margin: 0.5em 0; }
th, td { border: 1px solid #bbb; padding: 0.25em 0.6em; text-align: right; }
th { background: #eee; } td.text, th.text { text-align: left; }
figure { margin: 1em 0; } figcaption { font-size: 0.9em; color: #555; }
img { max-width: 100%; border: 1px solid #ddd; }
pre { background: #f6f6f6; padding: 0.8em; overflow-x: auto; font-size: 0.85em; }
.warning { color: #a40; }
.inaccurate { color: #fff; background: #b00020; padding: 0.5em 0.8em; font-weight: 600; }
td.inaccurate { padding: 0.25em 0.6em; }
.viewer { width: 100%; height: 32em; border: 1px solid #ddd; }
.viewer canvas { width: 100%; height: 100%; display: block; cursor: grab; }
.controls { margin: 0.4em 0; font-size: 0.9em; } .controls label { margin-right: 1em; }
"""

# Starts the viewer on the page; the address's fragment may choose what it shows first, e.g.
# report.html#shape=none or #shape=2&amplitude=0.1&animate=0 (for screenshots).
_START = """
(function () {
  const canvas = document.getElementById("pymorembs-view");
  try {
    const scene = JSON.parse(document.getElementById("pymorembs-scene").textContent);
    const viewer = new PymorembsViewer(canvas, scene);
    PymorembsViewer.controls(viewer, document.getElementById("pymorembs-controls"));
    const ask = new URLSearchParams(window.location.hash.slice(1));
    const shape = ask.has("shape") ? ask.get("shape") : (scene.shapes.length ? "0" : "none");
    viewer.setShape(shape === "none" ? null : Number(shape));
    if (ask.has("amplitude")) viewer.setAmplitude(Number(ask.get("amplitude")));
    viewer.animate(viewer.shape !== null && ask.get("animate") !== "0");
    viewer.render();
    window.pymorembsViewer = viewer;
  } catch (error) {
    const note = document.createElement("p");
    note.className = "warning";
    note.textContent = "The 3D view needs WebGL, which this browser lacks: " + error.message;
    canvas.replaceWith(note);
  }
})();
"""


def write_report(
    path: str | Path,
    summary: dict[str, Any],
    figures: list[tuple[Path, str]],
    job_text: str = "",
    scene: dict[str, Any] | None = None,
) -> Path:
    """Write the HTML report of a job.

    Parameters
    ----------
    path : path
        The ``.html`` file to write (atomically).
    summary : dict
        The job summary (the content of ``summary.json``).
    figures : list of (path, caption)
        PNG files to embed, in order.
    job_text : str
        The job file as given, shown verbatim.
    scene : dict, optional
        The body and its shapes for the 3D view (:func:`pymorembs.report.scene.
        reductions_scene`); None: no view.
    """
    e = html.escape
    model = summary["model"]
    title = summary.get("title") or f"Reduction of {model['name']}"
    parts = [
        "<!DOCTYPE html>",
        '<html lang="en">',
        "<head>",
        '<meta charset="utf-8">',
        f"<title>{e(title)}</title>",
        f"<style>{_STYLE}</style>",
        "</head>",
        "<body>",
        f"<h1>{e(title)}</h1>",
        f"<p>pymorembs {e(str(summary.get('pymorembs_version', '')))}, job "
        f"<code>{e(str(summary.get('job', '')))}</code>.</p>",
        "<h2>Model</h2>",
        _facts_table(model, summary.get("units")),
        "<h2>Settings</h2>",
        _settings_table(summary),
    ]
    banner = _accuracy_banner(summary["reductions"])
    if banner:
        parts.insert(parts.index("<h2>Model</h2>"), banner)
    if job_text:
        parts += ["<details><summary>Job file</summary>", f"<pre>{e(job_text)}</pre>", "</details>"]
    warnings = summary.get("warnings") or []
    if warnings:
        parts.append("<h2>Warnings</h2><ul>")
        parts += [f'<li class="warning">{e(w)}</li>' for w in warnings]
        parts.append("</ul>")
    parts += ["<h2>Reductions</h2>", _methods_table(summary["reductions"]), _covers(summary)]
    if scene is not None:
        parts += ["<h2>Body and shapes</h2>", *_view(scene)]
        if scene.get("stress_modes"):
            parts += ["<h3>Stress modes</h3>", stress_modes_table(scene["stress_modes"])]
    time_domain = summary.get("time_domain")
    if time_domain:
        parts += ["<h2>Time domain (paper section 5.1)</h2>", _time_table(time_domain)]
    large_motion = summary.get("large_motion")
    if large_motion:
        parts += ["<h2>Large motions in Exudyn</h2>", _large_motion_table(large_motion)]
    if figures:
        parts.append("<h2>Figures</h2>")
    for figure, caption in figures:
        data = base64.b64encode(Path(figure).read_bytes()).decode("ascii")
        parts += [
            "<figure>",
            f'<img src="data:image/png;base64,{data}" alt="{e(caption)}">',
            f"<figcaption>{e(caption)}</figcaption>",
            "</figure>",
        ]
    parts += ["<h2>Files written</h2>", _files_list(summary), "</body>", "</html>"]
    return write_text(path, "\n".join(parts) + "\n")


def _view(scene: dict[str, Any]) -> list[str]:
    """The 3D view: what it shows, the canvas, its controls and the inline scripts."""
    n_nodes = len(scene["node_ids"])
    drawn = [f"{n_nodes:,} nodes"]
    if scene["triangles"]:
        drawn.append(f"{len(scene['triangles']) // 3:,} surface triangles")
    if scene["lines"]:
        drawn.append(f"{len(scene['lines']) // 2:,} line segments")
    text = "The body as the reductions see it (coordinates from the frame's origin): " + ", ".join(
        drawn
    )
    if scene.get("frame"):
        text += "; the frame's axes x, y, z in red, green, blue"
    if scene.get("interfaces"):
        text += "; interface nodes as large points, their coupled nodes in the same colour"
    text += (
        ". A shape function is drawn with its largest translation at the chosen fraction of the "
        "body's size, coloured by the translation. Drag to rotate, wheel to zoom, right-drag "
        "or shift-drag to pan."
    )
    notes = "".join(f'<p class="warning">{html.escape(n)}.</p>' for n in scene.get("notes", []))
    # No "<" inside the script element (no "</script>", no "<!--"): JSON's escape of it.
    data = json.dumps(scene, separators=(",", ":"), allow_nan=False).replace("<", "\\u003c")
    script = viewer_script()
    return [
        f"<p>{html.escape(text)}</p>",
        notes,
        '<div class="viewer"><canvas id="pymorembs-view"></canvas></div>',
        '<div class="controls" id="pymorembs-controls"></div>',
        f'<script type="application/json" id="pymorembs-scene">{data}</script>',
        f"<script>{script}</script>",
        f"<script>{_START}</script>",
    ]


def _row(
    cells: list[str], header: bool = False, text_columns: int = 1, marked: int | None = None
) -> str:
    """A table row; the cell ``marked`` (an index) gets the class ``inaccurate``."""
    tag = "th" if header else "td"
    out = []
    for k, cell in enumerate(cells):
        classes = ["text"] if k < text_columns else []
        if k == marked:
            classes.append("inaccurate")
        css = f' class="{" ".join(classes)}"' if classes else ""
        out.append(f"<{tag}{css}>{html.escape(cell)}</{tag}>")
    return "<tr>" + "".join(out) + "</tr>"


def _accuracy_banner(reductions: list[dict[str, Any]]) -> str:
    """A paragraph on top of the page naming the reductions that missed their accuracy limit
    ("" when every one met it)."""
    missed = [r for r in reductions if not (r.get("accuracy") or {}).get("met", True)]
    if not missed:
        return ""
    parts = []
    for r in missed:
        accuracy = r["accuracy"]
        written = (
            "its body files are written (export_inaccurate = true)"
            if accuracy["exported"]
            else "its body files were not written"
        )
        parts.append(
            f"'{r['name']}': max rel. error {_number(accuracy['max'])} above its limit "
            f"{_number(accuracy['limit'])}; {written}"
        )
    text = "Accuracy not met. " + "; ".join(parts) + "."
    return f'<p class="inaccurate" id="accuracy-not-met">{html.escape(text)}</p>'


def _accuracy_cell(accuracy: dict[str, Any] | None) -> str:
    """The table's accuracy column: the limit, and whether the body met it and was written."""
    if not accuracy:
        return "–"
    if accuracy["met"]:
        return f"met (≤ {_number(accuracy['limit'])})"
    written = "written anyway" if accuracy["exported"] else "not written"
    return f"NOT MET (> {_number(accuracy['limit'])}), {written}"


def _covers(summary: dict[str, Any]) -> str:
    """What the error columns cover (loads and outputs), one paragraph."""
    text = (
        "max rel. error, at 0 Hz: ε(f) of eq. 27 over the band, from the port inputs to the "
        "port outputs."
    )
    loads = summary["model"].get("inertia_loads")
    if loads:
        text += (
            " inertia loads: ε(f) over the inertia loads of the frame motion ("
            + " ".join(loads["cases"])
            + ") to the port outputs and to their collocated outputs (the coordinates the "
            "frame's equations see), and from the port inputs to those: a body accurate for "
            "the ports but missing a direction the frame motion excites shows a large value here."
        )
    else:
        text += (
            " The inertia loads of the frame motion were not inputs ([inertia_loads]): the "
            "error says nothing about the body under the loads of a multibody run."
        )
    stress = summary["model"].get("stress")
    if stress:
        text += (
            f" stresses: ε(f) over the six stress components at {stress['points']} hot spots "
            f"({stress['chosen']}, at {stress['location']} points) under every input, against "
            "the full model; estimate: SOAGA's estimate of it"
            + (" (the reductions aimed at them, [stress] target)." if stress["targeted"] else ".")
        )
    return f"<p>{html.escape(text)}</p>"


def _number(value: Any, digits: int = 3) -> str:
    if value is None:
        return "–"
    if isinstance(value, float):
        if not math.isfinite(value):
            return str(value)
        if abs(value) >= 10**digits:
            return f"{value:.0f}"
        if abs(value) >= 1e-3 or value == 0:
            return f"{value:.{digits}g}"
        return f"{value:.{digits - 1}e}"
    return str(value)


def _facts_table(model: dict[str, Any], units: dict[str, Any] | None = None) -> str:
    frame = model.get("frame", {})
    frame_text = frame.get("type", "")
    if frame.get("node") is not None:
        frame_text += f" at node {frame['node']}"
    damping = model.get("damping", {})
    kind = damping.get("kind", "none")
    damping_text = {
        "rayleigh": f"Rayleigh, alpha = {damping.get('alpha')} 1/s, beta = {damping.get('beta')} s",
        "modal": f"modal, ratio {damping.get('ratio')}",
    }.get(kind, kind)
    rows = [
        ("model", str(model.get("name", ""))),
        ("dofs (all / independent)", f"{model.get('n_dof')} / {model.get('n_independent')}"),
        ("nodes", str(model.get("n_nodes"))),
        ("dependent / fixed dofs", f"{model.get('n_dependent')} / {model.get('n_fixed')}"),
        ("total mass", f"{_number(model.get('total_mass'), 6)} (model unit, kg in SI)"),
        ("reference frame", frame_text),
        ("damping", damping_text),
        ("inputs", ", ".join(model.get("inputs", []))),
        ("outputs", ", ".join(model.get("outputs", []))),
    ]
    if units:  # the unit system the model's numbers point to (pymorembs.units)
        text = str(units.get("system", "unknown"))
        if units.get("length"):
            text += (
                f" ({units['length']}, {units['mass']}, {units['time']}, {units['force']}; "
                f"frequencies in {units.get('frequency_unit')}; assumed from the numbers"
                f"{'' if units.get('plausible') else ', implausible'})"
            )
        rows.append(("unit system", text))
    body = "".join(_row([a, b], text_columns=2) for a, b in rows)
    return f"<table>{body}</table>"


def _settings_table(summary: dict[str, Any]) -> str:
    band = summary.get("band_hz", [None, None])
    rows = [
        ("frequency band", f"{band[0]} – {band[1]} Hz, {summary.get('n_frequencies')} points"),
        ("error measured against", _reference_text(summary.get("reference") or {})),
    ]
    timings = summary.get("timings_s", {})
    for key, value in timings.items():
        rows.append((key.removesuffix("_s").replace("_", " ") + " [s]", _number(value)))
    body = "".join(_row([a, b], text_columns=2) for a, b in rows)
    return f"<table>{body}</table>"


def _reference_text(reference: dict[str, Any]) -> str:
    """One line on the reference of the error curves (:mod:`pymorembs.analysis.reference`)."""
    if reference.get("kind") != "surrogate":
        return "the full model at every frequency"
    return (
        f"a reference model of order {reference.get('order')} (SOAGA), checked against the "
        f"full model at {reference.get('exact_frequencies')} frequencies, where it deviated "
        f"by at most {_number(reference.get('accuracy'))}; the maximum of every error curve is "
        "measured against the full model"
    )


def _methods_table(reductions: list[dict[str, Any]]) -> str:
    stress = any(r.get("stress") for r in reductions)  # the columns only with [stress]
    names = ["reduction", "method", "order", "max rel. error", "at 0 Hz", "inertia loads"]
    names += ["stresses", "stress estimate"] if stress else []
    names += ["estimate", "H2 bound (absolute)", "highest f [Hz]", "explicit step [s]",
              "time [s]", "accuracy"]  # fmt: skip
    header = _row(names, header=True, text_columns=2)
    rows = []
    for r in reductions:
        cells = [
            r["name"],
            r["method"],
            str(r["order"]),
            _number(r.get("max_rel_error")),
            _number(r.get("static_rel_error")),
            _number((r.get("inertia_loads") or {}).get("max_rel_error")),
        ]
        if stress:
            errors = r.get("stress") or {}
            cells += [_number(errors.get("max_rel_error")), _number(errors.get("estimate"))]
        cells += [
            _number(r.get("error_estimate")),
            _number(r.get("error_bound")),
            _number(r.get("highest_frequency_hz")),
            _number(r.get("explicit_step_s")),
            _number(r.get("time_s")),
            _accuracy_cell(r.get("accuracy")),
        ]
        met = (r.get("accuracy") or {}).get("met", True)
        rows.append(_row(cells, text_columns=2, marked=None if met else len(cells) - 1))
    return "<table>" + header + "".join(rows) + "</table>"


#: The columns of a check's table with hot spots.
STRESS_HEADER = ["stress: max rel. deviation", "worst hot spot"]


def _stress_cells(check: dict[str, Any], entry: dict[str, Any]) -> list[str]:
    """The stress cells of a check's row: its deviation at the hot spots and the worst one
    (none when the check has no hot spots)."""
    if "stress" not in check:
        return []
    stress = entry.get("stress") or {}
    return [_number(stress.get("max_rel_deviation")), str(stress.get("worst_point", "–"))]


def _stress_note(check: dict[str, Any]) -> str:
    """What the stress columns of a check compare, or nothing."""
    stress = check.get("stress")
    if not stress:
        return ""
    return (f" Stresses at the hot spots {', '.join(stress.get('points', []))} against "
            f"{stress.get('reference', '')}: {stress.get('covers', '')}.")  # fmt: skip


def _large_motion_table(large_motion: dict[str, Any]) -> str:
    header = _row(
        ["motion", "body", "frame ω: max rel. deviation", "deflection: max rel. deviation",
         "Exudyn time [s]", *(STRESS_HEADER if "stress" in large_motion else [])],
        header=True,
        text_columns=2,
    )  # fmt: skip
    rows, notes = [], []
    for case in large_motion.get("cases", []):
        for entry in case.get("reductions", []):
            rows.append(
                _row(
                    [
                        case["name"],
                        entry["name"],
                        _number(entry.get("frame_max_rel_deviation")),
                        _number(entry.get("deflection_max_rel_deviation")),
                        _number(entry.get("wall_time_s")),
                        *_stress_cells(large_motion, entry),
                    ],
                    text_columns=2,
                )
            )
        convergence = case.get("reference_convergence", {})
        notes.append(
            f"{case['name']}: swing {case.get('swing_deg', 0.0):.0f}°, peak |ω| "
            f"{case.get('reference_peak_angular_velocity_rad_s', 0.0):.3g} rad/s; the reference "
            "against the modal body of half its order: frame "
            f"{_number(convergence.get('frame_max_rel_deviation'))}, deflection "
            f"{_number(convergence.get('deflection_max_rel_deviation'))}"
        )
    reference = large_motion.get("reference", {})
    explain = (
        f"Hinged at node {large_motion.get('joint_node')}; reference: modal body of order "
        f"{reference.get('order')}; compared: {large_motion.get('covers', '')}; nodes "
        f"{large_motion.get('nodes')} (node {large_motion.get('off_axis_node')} lies off every "
        "symmetry axis). " + "; ".join(notes) + "." + _stress_note(large_motion)
    )
    return "<table>" + header + "".join(rows) + "</table>" + f"<p>{html.escape(explain)}</p>"


def _time_table(time_domain: dict[str, Any]) -> str:
    header = _row(
        [
            "load case",
            "reduction",
            "max rel. deviation",
            "speed-up",
            "time [s]",
            "Exudyn: deviation",
            "Exudyn: at small load",
            *(STRESS_HEADER if "stress" in time_domain else []),
        ],
        header=True,
        text_columns=2,
    )
    rows = []
    for case in time_domain.get("cases", []):
        for entry in case.get("reductions", []):
            rows.append(
                _row(
                    [
                        case["name"],
                        entry["name"],
                        _number(entry.get("max_rel_deviation")),
                        _number(entry.get("speedup")),
                        _number(entry.get("time_s")),
                        _number(entry.get("exudyn_max_rel_deviation")),
                        _number(entry.get("exudyn_small_load_max_rel_deviation")),
                        *_stress_cells(time_domain, entry),
                    ],
                    text_columns=2,
                )
            )
    note = ""
    settings = time_domain.get("settings")
    if settings:
        note = (
            "<p>"
            + html.escape(", ".join(f"{key} = {value}" for key, value in settings.items()))
            + "</p>"
        )
    explain = (
        "<p>Deviation: max over time and components of |u_red − u_full| ÷ max |u_full| at the "
        "load node. Exudyn: the exported body as a nonlinear flexible multibody model, against "
        "the linear reduced model, at the job's load and at 1/10,000 of it (scaled back)."
        + html.escape(_stress_note(time_domain))
        + "</p>"
    )
    return note + "<table>" + header + "".join(rows) + "</table>" + explain


def _files_list(summary: dict[str, Any]) -> str:
    names = list(summary.get("files", []))
    for r in summary.get("reductions", []):
        names += r.get("files", [])
    items = "".join(
        f'<li><a href="{html.escape(name)}">{html.escape(name)}</a></li>' for name in names
    )
    return f"<ul>{items}</ul>"


__all__ = ["write_report"]
