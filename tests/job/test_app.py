"""The server of ``pymorembs app`` without a browser: its JSON API, the job it writes, the
selections it makes from a picked surface patch, and the command line around it."""

from __future__ import annotations

import dataclasses
import http.client
import json
import os
import signal
import socket
import sys
import tempfile
import threading
import time
import tomllib
import urllib.error
import urllib.request
from pathlib import Path

import numpy as np
import pytest

from pymorembs import METHODS, example, method_options, select_nodes
from pymorembs.body import DofTable, ElasticBody
from pymorembs.errors import UserError
from pymorembs.job.app import App, make_server
from pymorembs.job.app.editor import check_job_text, job_text
from pymorembs.job.app.runner import Run, start_run
from pymorembs.job.app.selection import hole_selection
from pymorembs.job.cli import main
from pymorembs.job.schema import DEFAULT_EXPORTS, EXPORT_KINDS
from pymorembs.methods import OptionError, option_fields
from pymorembs.surface import outer_surface, smooth_patch


@pytest.fixture(scope="module")
def rack():
    return example("rack-solid", dofs=10000, interface="none")


@pytest.fixture
def server(tmp_path):
    app = App(tmp_path / "work")
    http = make_server(app, 0)
    threading.Thread(target=http.serve_forever, daemon=True).start()
    yield app, f"http://127.0.0.1:{http.server_address[1]}"
    if app.runs.run is not None:
        app.runs.run.cancel()
    http.shutdown()
    http.server_close()


def call(
    base: str, path: str, body: dict | None = None, headers: dict | None = None
) -> tuple[int, dict]:
    data = None if body is None else json.dumps(body).encode()
    headers = {"Content-Type": "application/json", **(headers or {})}
    request = urllib.request.Request(
        base + path, data=data, method="GET" if data is None else "POST", headers=headers
    )
    try:
        with urllib.request.urlopen(request, timeout=60) as response:
            return response.status, json.loads(response.read())
    except urllib.error.HTTPError as exc:
        return exc.code, json.loads(exc.read())


def run_to_the_end(base: str, job: dict, seconds: float = 120.0) -> dict:
    """Send ``job``, run it and wait for its end: the last status (asserted ``"done"``)."""
    assert call(base, "/api/job", {"job": job})[1]["error"] == ""
    assert call(base, "/api/run", {})[0] == 200
    deadline = time.time() + seconds
    while call(base, "/api/status")[1]["state"] == "running" and time.time() < deadline:
        time.sleep(0.2)
    done = call(base, "/api/status")[1]
    assert done["state"] == "done", done
    return done


def wall_triangle(body: ElasticBody) -> int:
    """A surface triangle of the upper hole's wall (Ø 30 mm, 204 <= z <= 221 mm)."""
    corners = body.coordinates[np.searchsorted(body.node_ids, body.surface.triangles)]
    radius = np.hypot(corners[..., 0], corners[..., 1])
    on_wall = (np.abs(radius - 0.015) < 1e-6).all(axis=1) & (corners[..., 2] > 0.2039).all(axis=1)
    return int(np.flatnonzero(on_wall)[0])


def hole(body: ElasticBody) -> np.ndarray:
    return select_nodes(
        body,
        cylinder=((0.0, 0.0, 0.2125), (0.0, 0.0, 1.0), 0.015, 1e-6),
        box=((-0.02, -0.02, 0.2039), (0.02, 0.02, 0.2211)),
    )


# -- the form of every method comes from the registry ---------------------------------------------
@pytest.mark.parametrize("method", list(METHODS))
def test_option_fields_are_the_dataclass_fields(method):
    fields = option_fields(method)
    assert sorted(f["name"] for f in fields) == sorted(
        f.name for f in dataclasses.fields(METHODS[method])
    )
    for field in fields:
        if field["required"]:  # leaving it out must be refused by the options class itself
            values = {f["name"]: f["default"] for f in fields if f["default"] not in (None, [])}
            values.pop(field["name"], None)
            with pytest.raises(OptionError):
                method_options(method, values)


def test_option_kinds_and_choices():
    modal = {f["name"]: f for f in option_fields("modal")}
    assert modal["select"]["kind"] == "choice"
    assert modal["select"]["choices"] == ["lowest", "best"]
    assert modal["frm_hz"]["kind"] == "floats"
    assert modal["order"]["kind"] == "int" and modal["order"]["required"]
    krylov = {f["name"]: f for f in option_fields("krylov")}
    assert krylov["two_sided"]["kind"] == "bool" and krylov["moments"]["kind"] == "ints"
    assert (
        "rational-krylov"
        in {f["name"]: f for f in option_fields("gramian")}["first_stage"]["choices"]
    )
    with pytest.raises(OptionError, match="did you mean 'krylov'"):
        option_fields("krylow")


# -- picking: smooth patches and the selections written for them ---------------------------------
def cube() -> tuple[ElasticBody, object]:
    """One hex8 cube: 6 faces of 2 triangles, at right angles to each other."""
    corners = np.array([[x, y, z] for z in (0, 1) for y in (0, 1) for x in (0, 1)], float)
    corners = corners[[0, 1, 3, 2, 4, 5, 7, 6]]
    ids = np.arange(1, 9)
    surface = outer_surface([("hex8", ids[None, :])], ids, corners)
    return ids, corners, surface


def test_smooth_patch_stops_at_sharp_edges():
    ids, corners, surface = cube()
    assert len(smooth_patch(surface, ids, corners, 0, 30.0)) == 2  # one face
    assert len(smooth_patch(surface, ids, corners, 0, 95.0)) == 12  # the whole cube


def test_a_click_on_the_hole_selects_its_wall(rack):
    seed = wall_triangle(rack)
    nodes = np.unique(rack.surface.triangles[smooth_patch(rack.surface, rack.node_ids,
                                                          rack.coordinates, seed)])  # fmt: skip
    assert np.array_equal(nodes, np.sort(hole(rack)))
    chosen = hole_selection(rack, nodes)
    assert chosen["kind"] == "cylinder"
    assert chosen["position"] == pytest.approx([0.0, 0.0, 0.2125], abs=1e-9)
    assert chosen["radius"] == pytest.approx(0.015, rel=1e-9)
    cyl, box = chosen["selection"]["cylinder"], chosen["selection"]["box"]
    again = select_nodes(
        rack,
        cylinder=(cyl["point"], cyl["direction"], cyl["radius"], cyl["tolerance"]),
        box=(box["min"], box["max"]),
    )
    assert np.array_equal(np.sort(again), nodes)


def test_a_flat_face_is_written_as_node_ids(rack):
    top = rack.coordinates[:, 2] > 0.221 - 1e-9
    chosen = hole_selection(rack, rack.node_ids[top])
    assert chosen["kind"] == "nodes"
    assert chosen["selection"]["nodes"] == sorted(rack.node_ids[top].tolist())


# -- the job text ---------------------------------------------------------------------------------
def test_job_text_is_the_job_in_toml():
    job = {
        "title": "a \"quoted\" title",
        "model": {"example": "rack-solid", "dofs": 10000, "interface": "none"},
        "interface": [{"node": 2, "position": [0.0, 0.0, 0.2125], "kind": "rigid",
                       "cylinder": {"point": [0, 0, 0.2125], "direction": [0, 0, 1],
                                    "radius": 0.015, "tolerance": 1e-6}}],
        "frame": {"type": "tangent", "node": 2},
        "inputs": [{"node": 1, "directions": "ux uy uz"}],
        "band": {"f_min_hz": 0, "f_max_hz": 1000.0, "points": 200},
        "reduction": [{"name": "k", "method": "krylov", "expansion_points_hz": [0, 500],
                       "order": 12, "two_sided": False}],
        "export": {"outputs": ["npz", "sid"]},
    }  # fmt: skip
    text = job_text(job)
    assert tomllib.loads(text) == job
    assert text.index("[model]") < text.index("[[interface]]") < text.index("[frame]")
    parsed = check_job_text(text, Path("job.toml"))
    assert parsed.frame.node == 2 and parsed.reductions[0].options.expansion_points_hz == (0, 500)


# -- the HTTP API ---------------------------------------------------------------------------------
def test_api_open_pick_select_and_check(server):
    app, base = server
    status, methods = call(base, "/api/methods")
    assert status == 200 and set(methods) == set(METHODS)
    opened = {"example": "rack-solid", "options": {"dofs": 10000, "interface": "none"}}
    status, reply = call(base, "/api/open", opened)
    assert status == 200 and reply["model"]["n_dof"] == 10359
    assert reply["error"] == "job.toml: job: missing key 'reduction'"
    status, scene = call(base, "/api/scene")
    assert len(scene["triangles"]) == 3 * app.model.body.surface.triangles.shape[0]
    reference = hole(app.model.body)
    status, picked = call(base, "/api/pick", {"triangle": wall_triangle(app.model.body)})
    assert status == 200 and picked["count"] == reference.size and picked["free_id"] == 2
    ids = np.asarray(scene["node_ids"])[picked["rows"]]
    assert np.array_equal(np.sort(ids), np.sort(reference))  # the rows index the scene's nodes
    status, chosen = call(base, "/api/select", {"cylinder": {"point": [0, 0, 0.2125],
                          "direction": [0, 0, 1], "radius": 0.015, "tolerance": 1e-6},
                          "box": {"min": [-1, -1, 0.2039], "max": [1, 1, 0.2211]}})  # fmt: skip
    assert chosen["count"] == reference.size
    job = reply["job"] | {
        "frame": {"type": "tangent", "node": 2},
        "interface": [{"node": 2, "position": picked["position"], "kind": "rigid",
                       **picked["selection"]}],
        "inputs": [{"node": 1, "directions": "ux uy uz"}],
        "reduction": [{"name": "m", "method": "modal", "order": "twelve"}],
    }  # fmt: skip
    status, state = call(base, "/api/job", {"job": job})
    assert (
        state["error"] == "job.toml: [[reduction]] #1.order: must be a whole number, got 'twelve'"
    )
    job["reduction"][0]["order"] = 12
    status, state = call(base, "/api/job", {"job": job})
    assert state["error"] == "" and 'kind = "rigid"' in state["toml"]


def test_the_view_draws_the_jobs_frame_and_interfaces(server):
    """The decorations of the 3D view follow the job: Buckens at the centre of gravity, then
    the picked hole's interface node at the hole's centre with its coupled nodes and the
    tangent frame there; what cannot be drawn is said in one line."""
    app, base = server
    opened = {"example": "rack-solid", "options": {"dofs": 10000, "interface": "none"}}
    state = call(base, "/api/open", opened)[1]
    body = app.model.body
    # Buckens (the new job's frame): the centre of gravity, independently from the lumped
    # masses of the x translations (row sums of M, exact for consistent element masses)
    x = body.dofs.directions == 0
    lumped = np.asarray(body.mass[x][:, x].sum(axis=1)).ravel()
    centre = lumped @ body.coordinates[body.node_rows(body.dofs.nodes[x])] / lumped.sum()
    frame = state["decorations"]["frame"]
    assert np.allclose(frame["origin"], centre, atol=1e-9) and frame["axes"] == np.eye(3).tolist()
    assert state["decorations"]["interfaces"] == []
    picked = call(base, "/api/pick", {"triangle": wall_triangle(body)})[1]
    job = state["job"] | {
        "frame": {"type": "tangent", "node": 2},
        "interface": [{"node": 2, "position": picked["position"], "kind": "rigid",
                       **picked["selection"]},
                      {"node": 3, "position": [0, 0, 9], "kind": "rigid",
                       "box": {"min": [5, 5, 5], "max": [6, 6, 6]}}],
    }  # fmt: skip
    state = call(base, "/api/job", {"job": job})[1]
    drawn = state["decorations"]
    assert drawn["frame"]["origin"] == picked["position"] == [0.0, 0.0, 0.2125]
    (interface,) = drawn["interfaces"]
    assert interface["name"] == "interface 2 (rigid)" and interface["node"] is None
    assert interface["position"] == picked["position"]
    assert sorted(interface["coupled"]) == sorted(picked["rows"])
    ids = np.asarray(call(base, "/api/scene")[1]["node_ids"])[interface["coupled"]]
    assert np.array_equal(np.sort(ids), hole(body))
    (note,) = drawn["notes"]
    assert note.startswith("[[interface]] #2 is not drawn:") and "\n" not in note
    job["frame"] = {"type": "tangent", "node": 99999}
    drawn = call(base, "/api/job", {"job": job})[1]["decorations"]
    assert drawn["frame"] is None and "[frame] node 99999" in drawn["notes"][-1]
    job["frame"] = {"type": "tangent", "node": int(body.node_ids[7])}
    drawn = call(base, "/api/job", {"job": job})[1]["decorations"]
    assert drawn["frame"]["origin"] == body.coordinates[7].tolist()
    job["frame"] = {"type": "none"}
    assert call(base, "/api/job", {"job": job})[1]["decorations"]["frame"] is None


def test_the_export_kinds_are_the_job_parsers(server):
    _, base = server
    status, reply = call(base, "/api/exports")
    assert status == 200
    assert reply == {"kinds": list(EXPORT_KINDS), "default": list(DEFAULT_EXPORTS)}
    assert "vtu" in reply["kinds"]  # the page's own list had no vtu


def test_the_schema_is_the_job_parsers(server):
    """Issue #28: the page builds its forms and lists of kinds from the served schema; its
    kinds are the job parser's, each with the parameters the parser takes."""
    from pymorembs.kinds import DampingKind, FrameType, InterfaceKind, ReferenceKind

    _, base = server
    status, schema = call(base, "/api/schema")
    assert status == 200
    kinds = schema["kinds"]
    for name, kind in [("frame", FrameType), ("damping", DampingKind),
                       ("interface", InterfaceKind), ("reference", ReferenceKind)]:  # fmt: skip
        assert list(kinds[name]) == list(kind.names())
    assert [p["name"] for p in kinds["interface"]["springs"]] == ["stiffness", "damping"]
    assert [p["name"] for p in kinds["damping"]["rayleigh"]] == ["alpha", "beta"]
    assert list(kinds["export"]) == list(EXPORT_KINDS)
    assert schema["default_exports"] == list(DEFAULT_EXPORTS)
    assert list(kinds["method"]) == list(call(base, "/api/methods")[1])
    band = {key["name"]: key for key in schema["tables"]["band"]}
    assert band["points"]["default"] == 400 and band["f_max_hz"]["required"]


def test_api_refusals_are_one_line(server, tmp_path):
    _, base = server
    for path, body, message in [
        ("/api/open", {"example": "rack"}, "unknown example 'rack'"),
        ("/api/open", {"path": str(tmp_path / "no.h5")}, "no such file"),
        ("/api/pick", {"triangle": 0}, "no model is open"),
        ("/api/run", {}, "the job is not valid yet"),
        ("/api/save", {"path": "job.txt"}, "not valid yet"),
        ("/api/results", None, "no finished run yet"),
    ]:
        status, reply = call(base, path, body)
        assert status == 400 and message in reply["error"] and "\n" not in reply["error"]
    status, _ = call(base, "/api/nothing")
    assert status == 404


def test_a_pick_outside_the_views_nodes_is_refused(server):
    app, base = server
    call(base, "/api/open", {"example": "rack-solid", "options": {"dofs": 10000}})
    count = len(app.model.scene["node_ids"])
    for row in (count, -1):  # past the end; not the last node either
        status, reply = call(base, "/api/pick", {"node": row})
        assert status == 400 and reply["error"] == (
            f"pick: no node {row} in the view (it has {count})"
        )


def test_saving_under_a_file_is_refused_in_one_line(server, tmp_path):
    _, base = server
    state = call(base, "/api/open", {"example": "rack-beams"})[1]
    job = state["job"] | {
        "frame": {"type": "none"},
        "reduction": [{"name": "m", "method": "modal", "order": 4}],
    }
    assert call(base, "/api/job", {"job": job})[1]["error"] == ""
    (tmp_path / "notes.txt").write_text("a file, not a folder\n", encoding="utf-8")
    target = tmp_path / "notes.txt" / "job.toml"
    status, reply = call(base, "/api/save", {"path": str(target)})
    assert status == 400 and reply["error"].startswith(f"save: {target}: cannot create its folder")
    assert "\n" not in reply["error"]


def test_a_job_with_tables_of_the_wrong_type_is_shown(server):
    """The job being edited need not be valid: tables of the wrong type are the parser's
    message and a note under the view, never a dropped request (the page would stay broken,
    the server holding that job)."""
    app, base = server
    opened = {"example": "rack-solid", "options": {"dofs": 10000, "interface": "none"}}
    state = call(base, "/api/open", opened)[1]
    job = state["job"] | {"frame": [1], "interface": 5}
    status, state = call(base, "/api/job", {"job": job})
    assert status == 200 and state["error"].startswith("job.toml:")
    assert state["decorations"]["notes"] == [
        "[[interface]] is not drawn: expected a list of tables",
        "[frame] is not drawn: it must be a table",
    ]
    assert call(base, "/api/state")[0] == 200
    job |= {"frame": {"type": "none"}, "interface": ["x", {"node": "two"}, {"node": 1}]}
    assert call(base, "/api/job", {"job": job})[0] == 200
    status, picked = call(base, "/api/pick", {"triangle": wall_triangle(app.model.body)})
    assert status == 200 and picked["free_id"] == 2  # node 1 taken by the model


def test_other_web_sites_cannot_drive_the_app(server):
    app, base = server
    status, reply = call(
        base, "/api/open", {"example": "rack-beams"}, {"Content-Type": "text/plain"}
    )
    assert status == 415 and reply["error"] == "send JSON"
    assert status == 415 and app.model.body is None  # a cross-site 'simple' POST
    status, _ = call(base, "/api/state", None, {"Host": "evil.example:80"})
    assert status == 403  # DNS rebinding
    status, reply = call(
        base, "/api/state", None, {"Host": base.split("//")[1].replace("127.0.0.1", "localhost")}
    )
    assert status == 200 and reply["model"] is None


def post_raw(base: str, path: str, data: bytes, headers: dict | None = None) -> tuple[int, dict]:
    """POST ``data`` as it is (not necessarily JSON) with a JSON content type."""
    connection = http.client.HTTPConnection(*base.split("//")[1].split(":"), timeout=60)
    try:
        connection.request(
            "POST", path, body=data, headers={"Content-Type": "application/json", **(headers or {})}
        )
        response = connection.getresponse()
        return response.status, json.loads(response.read())
    finally:
        connection.close()


@pytest.mark.parametrize(
    ("data", "headers", "message"),
    [
        (b'"rack-beams"', {}, "bad JSON: expected an object, got str"),
        (b"[1, 2]", {}, "bad JSON: expected an object, got list"),
        (b"\xff\xfe{", {}, "bad JSON:"),
        (b'{"job": {"band": {"f_max_hz": NaN}}}', {}, "bad JSON: NaN is not a number in JSON"),
        (b"{}", {"Content-Length": "two"}, "Content-Length is not a number"),
    ],
)
def test_a_body_that_is_not_a_json_object_is_refused_in_one_line(server, data, headers, message):
    _, base = server
    status, reply = post_raw(base, "/api/job", data, headers)
    assert status == 400 and message in reply["error"] and "\n" not in reply["error"]
    assert call(base, "/api/state")[0] == 200  # the job was not replaced (NaN: not sendable)


def test_an_unexpected_error_is_answered(server, monkeypatch, capsys):
    app, base = server

    def broken():
        raise RuntimeError("a bug\nin two lines")

    monkeypatch.setattr(app.runs, "status", broken)
    status, reply = call(base, "/api/status")
    assert status == 500 and reply["error"] == "internal error: a bug in two lines"
    assert "RuntimeError" in capsys.readouterr().err  # the traceback for the bug report


@pytest.mark.slow
def test_run_results_shapes_mac_save_and_cancel(server, tmp_path):
    app, base = server
    status, reply = call(base, "/api/open", {"example": "rack-beams"})
    job = reply["job"] | {
        "frame": {"type": "tangent", "node": 2},
        "inputs": [{"node": 1, "directions": "ux uy uz"}, {"node": 2, "directions": "ux uy uz"}],
        "band": {"f_min_hz": 0, "f_max_hz": 1000, "points": 200},
        "damping": {"kind": "modal", "ratio": 0.01},
        "reduction": [{"name": "modal", "method": "modal", "order": 20},
                      {"name": "krylov", "method": "krylov", "expansion_points_hz": [0, 500],
                       "order": 24}],
    }  # fmt: skip
    assert call(base, "/api/job", {"job": job})[1]["error"] == ""
    status, run = call(base, "/api/run", {})
    assert status == 200 and run["state"] == "running"
    status, busy = call(base, "/api/run", {})
    assert status == 400 and "cancel it first" in busy["error"]
    deadline = time.time() + 120
    while call(base, "/api/status")[1]["state"] == "running" and time.time() < deadline:
        time.sleep(0.2)
    status, done = call(base, "/api/status")
    assert done["state"] == "done" and done["fraction"] == 1.0
    status, results = call(base, "/api/results")
    summary = json.loads((Path(done["out"]) / "summary.json").read_text(encoding="utf-8"))
    for row, entry in zip(results["reductions"], summary["reductions"], strict=True):
        assert row["max_rel_error"] == entry["max_rel_error"]
        assert max(row["curve"]["relative"]) == pytest.approx(entry["max_rel_error"], rel=1e-12)
    # shape 0 on the scene's nodes, from reduced.npz
    status, shape = call(base, "/api/shape?reduction=modal&k=0")
    with np.load(Path(done["out"]) / "modal" / "reduced.npz") as data:
        V, nodes, dirs = data["V"], data["dof_nodes"], data["dof_directions"]
    scene_ids = np.asarray(call(base, "/api/scene")[1]["node_ids"])
    values = np.asarray(shape["values"]).reshape(-1, 3)
    k = np.flatnonzero((nodes == scene_ids[5]) & (dirs == 1))[0]
    shown = (dirs < 3) & np.isin(nodes, scene_ids)
    assert values[5, 1] == pytest.approx(V[k, 0] / np.abs(V[shown, 0]).max(), abs=2e-6)
    # a Krylov eigenfrequency equal to a modal one (the modes the ports see) is the same shape:
    # MAC 1 there; a basis against itself: 1 on the diagonal, symmetric
    reply = call(base, "/api/mac?a=modal&b=krylov")[1]
    mac, fa, fb = (np.asarray(reply[k]) for k in ("matrix", "a_hz", "b_hz"))
    same = np.abs(fa[:, None] - fb[None, :]) < 1e-6 * fa[:, None]
    assert same.sum() >= 2 and np.all(mac[same] > 0.999)
    assert reply["weighting"] == "mass"
    itself = np.asarray(call(base, "/api/mac?a=modal&b=modal")[1]["matrix"])
    assert np.allclose(np.diag(itself), 1.0) and np.allclose(itself, itself.T, atol=1e-4)
    # weighted by the body's M, the modes are orthogonal: the identity (the plain MAC over
    # all dofs of the same modes is not, translations and rotations weigh alike there)
    assert np.abs(itself - np.eye(itself.shape[0])).max() <= 1e-4
    plain = (V.T @ V) ** 2 / np.outer((V * V).sum(axis=0), (V * V).sum(axis=0))
    assert np.abs(plain - np.eye(V.shape[1])).max() > 1e-2
    status, saved = call(base, "/api/save", {"path": str(tmp_path / "saved.toml")})
    assert (tmp_path / "saved.toml").read_text(encoding="utf-8") == saved["toml"]
    with urllib.request.urlopen(f"{base}/files/modal/reduced.npz", timeout=30) as response:
        assert response.read() == (Path(done["out"]) / "modal" / "reduced.npz").read_bytes()
    status, _ = call(base, "/files/../../etc/passwd")
    assert status == 404
    # Cancel in the middle of a reduction (its temporary output folder exists then): the
    # child process ends, and neither the output nor the temporary folder is left
    job["reduction"].append({"name": "big", "method": "modal", "order": 800})  # seconds
    assert call(base, "/api/job", {"job": job})[1]["error"] == ""
    status, run = call(base, "/api/run", {})
    deadline = time.time() + 60
    while "reduction 'big'" not in call(base, "/api/status")[1]["stage"]:
        assert time.time() < deadline and app.runs.run.state == "running"
        time.sleep(0.05)
    call(base, "/api/cancel", {})
    deadline = time.time() + 30
    while app.runs.run.process.poll() is None and time.time() < deadline:
        time.sleep(0.1)
    time.sleep(0.3)
    assert call(base, "/api/status")[1]["state"] == "cancelled"
    assert not Path(run["out"]).exists()
    assert not [p.name for p in Path(run["out"]).parent.iterdir() if p.name.startswith(".run-")]


def test_the_progress_counts_each_stage_once(tmp_path):
    """One step per stage of the job (model, reference, two reductions, time domain, large
    motion): the time domain and large-motion checks print a line per reduction, one stage."""
    run = Run(job=tmp_path / "job.toml", out=tmp_path / "run-1", stages=6)
    printed = [
        "loading the model, interfaces, frame, constraint elimination, inputs and outputs",
        "frequency response of the full model at 200 frequencies",
        "reduction 'a' (modal)",
        "warning: reduction 'a': order 4 instead of 6: the Krylov space is exhausted",
        "reduction 'b' (krylov)",
        "time domain: full model (3996 dofs), 2 load case(s), 0.1 s",
        "time domain: reduction 'a'",
        "time domain: reduction 'b'",
        "large motion 'swing' in Exudyn: reference (modal 20) and each body",
        "large motion 'spin' in Exudyn: reference (modal 20) and each body",
    ]
    begun = []
    for k, text in enumerate(printed):
        run.read_line(f"[{k:7.2f} s] {text}\n")
        begun.append(run.done_stages)
    assert begun == [1, 2, 3, 3, 4, 5, 5, 5, 6, 6]
    assert run.stage == printed[-1] and len(run.lines) == len(printed)
    assert run.fraction == pytest.approx(5.5 / 6)


@pytest.fixture
def stubborn_child(tmp_path, monkeypatch):
    """``python -m pymorembs.job.cli reduce JOB --out OUT`` replaced by a child that makes the
    job layer's temporary folder next to OUT, prints its first stage and ignores SIGTERM and
    SIGINT (a run that does not end within the grace time)."""
    script = tmp_path / "stubborn-python"
    script.write_text(
        "#!/bin/sh\n"
        "trap '' INT TERM\n"
        'mkdir -p "$(dirname "$6")/.$(basename "$6").staging"\n'
        'echo "[   0.01 s] loading the model"\n'
        "exec sleep 60\n",
        encoding="utf-8",
    )
    script.chmod(0o755)
    monkeypatch.setattr(sys, "executable", str(script))
    started = []
    yield started
    for run in started:
        if run.alive:
            os.killpg(run.process.pid, signal.SIGKILL)


def wait_for(condition, seconds: float = 20.0) -> None:
    deadline = time.time() + seconds
    while not condition():
        assert time.time() < deadline
        time.sleep(0.05)


def test_a_run_killed_after_the_grace_time_leaves_no_temporary_folder(stubborn_child, tmp_path):
    out = tmp_path / "run-1"
    run = start_run(tmp_path / "job.toml", out, stages=3)
    stubborn_child.append(run)
    wait_for(lambda: run.stage == "loading the model")
    assert [p.name for p in tmp_path.iterdir() if p.name.startswith(".run-1.")]
    run.cancel(grace_s=0.2)
    assert run.state == "cancelled"
    wait_for(lambda: run.ended is not None)
    assert run.stage == "cancelled" and not out.exists()
    assert not [p.name for p in tmp_path.iterdir() if p.name.startswith(".run-1.")]


def test_no_second_run_while_a_cancelled_one_is_ending(stubborn_child, tmp_path):
    app = App(tmp_path / "work")
    state = app.open({"example": "rack-beams"})
    app.edit(
        state["job"]
        | {"frame": {"type": "none"}, "reduction": [{"name": "m", "method": "modal", "order": 4}]}
    )
    first = app.start()
    stubborn_child.append(app.runs.run)
    assert first["state"] == "running"
    wait_for(lambda: app.runs.run.stage == "loading the model")  # SIGTERM ignored from here on
    assert app.runs.cancel()["state"] == "cancelled" and app.runs.run.alive
    with pytest.raises(UserError, match="the cancelled run is still ending"):
        app.start()
    os.killpg(app.runs.run.process.pid, signal.SIGKILL)
    wait_for(lambda: app.runs.run.ended is not None)
    assert app.start()["out"].endswith("run-2")  # ended: the next run may start
    stubborn_child.append(app.runs.run)


def test_cli_app_refuses_a_bad_model_and_a_busy_port(tmp_path, capsys, monkeypatch):
    temporary = tmp_path / "temporary"
    temporary.mkdir()
    monkeypatch.setattr(tempfile, "tempdir", str(temporary))
    assert main(["app", str(tmp_path / "missing.h5"), "--no-browser"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "missing.h5: no such file" in err
    text = tmp_path / "notes.txt"
    text.write_text("no model\n", encoding="utf-8")
    assert main(["app", str(text), "--format", "native", "--no-browser", "--port", "0"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "notes.txt: not an HDF5 file" in err
    with socket.socket() as busy:
        busy.bind(("127.0.0.1", 0))
        busy.listen()
        port = busy.getsockname()[1]
        assert main(["app", "--port", str(port), "--no-browser"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and f"port {port} is in use" in err
    assert list(temporary.iterdir()) == []  # no empty run folder left behind


def test_the_body_without_surface_cannot_be_picked(tmp_path):
    body = ElasticBody(
        node_ids=np.array([1, 2]),
        coordinates=np.array([[0.0, 0, 0], [1.0, 0, 0]]),
        dofs=DofTable(np.array([1, 2]), np.array([0, 0])),
        mass=np.eye(2),
        stiffness=np.array([[1.0, -1.0], [-1.0, 1.0]]),
    )
    app = App(tmp_path)
    app.model.body = body
    with pytest.raises(Exception, match="no surface to pick on"):
        app.model.pick({"triangle": 0})


def test_a_job_file_opens_in_the_editor(tmp_path):
    job = tmp_path / "job.toml"
    job.write_text(
        '[model]\nfile = "model.h5"\n[frame]\nnode = 2\n[band]\nf_max_hz = 100\n'
        '[[reduction]]\nmethod = "modal"\norder = 4\n[export]\noutputs = ["sid"]\n',
        encoding="utf-8",
    )
    assert main(["example", "rack-beams", "--out", str(tmp_path)]) == 0
    app = App(tmp_path / "work")
    state = app.open({"path": str(job)})
    assert state["model"]["n_dof"] == 3996
    # the model file becomes absolute (the saved job runs from anywhere), npz is added (the
    # page reads the bases from reduced.npz), the rest is the file's
    assert state["job"]["model"] == {"file": str(tmp_path / "model.h5")}
    assert state["job"]["export"] == {"outputs": ["npz", "sid"]}
    assert state["error"] == "" and 'outputs = ["npz", "sid"]' in state["toml"]


def test_the_page_gets_the_viewer_of_the_html_report(server):
    """The app serves the same viewer.js as the report embeds (report.viewer_script)."""
    from pymorembs.report import viewer_script

    _, base = server
    with urllib.request.urlopen(base + "/viewer.js", timeout=30) as response:
        assert response.headers["Content-Type"] == "text/javascript"
        text = response.read().decode("utf-8")
    assert text == viewer_script() and "PymorembsViewer" in text
