"""Inertia loads of the frame motion as inputs (issue #15 item 1), checked by dense algebra."""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
import scipy.linalg as sla

from conftest import space_truss
from pymorembs.analysis.error import error_blocks, relative_error
from pymorembs.analysis.transfer import transfer_function
from pymorembs.body import Damping
from pymorembs.errors import UserError
from pymorembs.io.matrix_market import write_matrix_files
from pymorembs.job.cli import main
from pymorembs.job.run import inertia_warning
from pymorembs.job.schema import parse_job
from pymorembs.preparation import (
    INERTIA_LOAD_CASES,
    Frame,
    Port,
    prepare,
    with_inertia_loads,
)
from pymorembs.preparation.inertia_loads import acceleration_fields
from pymorembs.reduction.krylov import krylov_reduction
from pymorembs.reduction.modal_family import craig_bampton
from pymorembs.reduction.projection import reduced_model

PORT = [Port.parse(24, "ux uy uz")]  # the far corner of the 4 x 3 x 2 truss


def clamped_truss():
    """The space truss held at its three nodes 1, 2, 4 (statically determinate and more)."""
    body = space_truss().with_damping(Damping("modal", ratio=0.02))
    fixed = np.concatenate([body.dofs.of_node(node) for node in (1, 2, 7)])
    return replace(body, fixed=np.sort(fixed))


def node_xyz(body, field):
    """A field on the translational dofs of a 3-dof-per-node body as (n_nodes, 3)."""
    return field.reshape(-1, 3)


def test_acceleration_fields_are_the_kinematics_of_the_frame():
    body = space_truss()
    xyz = body.coordinates
    a = acceleration_fields(body)
    rng = np.random.default_rng(3)
    lin, alpha, omega = rng.normal(size=(3, 3))
    np.testing.assert_allclose(node_xyz(body, a[:, :3] @ lin), np.tile(lin, (len(xyz), 1)))
    np.testing.assert_allclose(node_xyz(body, a[:, 3:6] @ alpha), np.cross(alpha, xyz), atol=1e-15)
    wx, wy, wz = omega
    products = np.array([wx * wx, wy * wy, wz * wz, wx * wy, wy * wz, wx * wz])
    expected = np.cross(omega, np.cross(omega, xyz))  # centripetal acceleration
    np.testing.assert_allclose(node_xyz(body, a[:, 6:] @ products), expected, atol=1e-14)


def test_a_clamped_body_keeps_all_load_cases_scaled_to_the_ports_compliance():
    prepared = with_inertia_loads(prepare(clamped_truss(), Frame("none"), PORT, PORT))
    loads = prepared.inertia
    assert loads.cases == INERTIA_LOAD_CASES and loads.dropped == ()
    system = prepared.system
    k = system.stiffness.toarray()
    ports = system.input_matrix
    compliance = lambda b: np.einsum("ij,ij->j", b, np.linalg.solve(k, b))  # noqa: E731
    np.testing.assert_allclose(
        compliance(loads.input_matrix), np.median(compliance(ports)), rtol=1e-10
    )
    # the loads themselves: -M a on the independent dofs, up to the scale
    raw = -(clamped_truss().mass @ acceleration_fields(clamped_truss()))
    raw = prepared.elimination.inputs(raw)
    np.testing.assert_allclose(loads.input_matrix, raw * loads.scales, rtol=1e-12, atol=1e-14)
    augmented = prepared.reduction_system
    assert augmented.input_labels[3:] == tuple(f"inertia:{c}" for c in INERTIA_LOAD_CASES)
    np.testing.assert_array_equal(augmented.output_matrix[3:], loads.input_matrix.T)


def test_buckens_frame_keeps_the_centrifugal_loads_only_self_equilibrated():
    prepared = with_inertia_loads(prepare(space_truss(), Frame("buckens"), PORT, PORT))
    loads = prepared.inertia
    assert loads.cases == ("wxx", "wyy", "wzz", "wxy", "wyz", "wxz")
    assert [d.split()[0] for d in loads.dropped] == ["ax", "ay", "az", "alx", "aly", "alz"]
    assert all("balanced by the rigid-body motion" in d for d in loads.dropped)
    rigid = prepared.system.rigid_modes
    resultant = rigid.T @ loads.input_matrix
    assert np.abs(resultant).max() < 1e-12 * np.abs(loads.input_matrix).max()


def test_without_coordinates_only_translational_loads():
    body = replace(clamped_truss(), has_coordinates=False)
    prepared = with_inertia_loads(prepare(body, Frame("none"), PORT, PORT))
    assert prepared.inertia.cases == ("ax", "ay", "az")
    assert len(prepared.inertia.dropped) == 9
    assert all("no coordinates" in d for d in prepared.inertia.dropped)


def _static(system):
    """H(0) by a dense solve, shape (r, p)."""
    k = system.stiffness.toarray() if hasattr(system.stiffness, "toarray") else system.stiffness
    return system.output_matrix @ np.linalg.solve(k, system.input_matrix)


def test_a_port_only_body_misses_the_inertia_loads_and_an_inertia_aware_one_does_not():
    prepared = with_inertia_loads(prepare(clamped_truss(), Frame("none"), PORT, PORT))
    full = prepared.reduction_system
    ports, inertia = error_blocks(full)
    reference = _static(full)[None] / (1.0 + 1j * full.loss_factor)  # modal damping: K (1 + i eta)
    frequencies = np.array([0.0, 50.0, 400.0])
    h_full = transfer_function(full, frequencies)
    np.testing.assert_allclose(
        h_full[:1], reference, rtol=1e-9, atol=1e-12 * np.abs(reference).max()
    )
    errors = {}
    for name, system in (("ports only", prepared.system), ("with inertia", full)):
        projection = krylov_reduction(system, [0.0], order=15)
        model = reduced_model(full, projection)
        h = transfer_function(model.system, frequencies)
        errors[name] = (relative_error(h_full, h, ports), relative_error(h_full, h, inertia))
    # 15 columns at 0 Hz with the 15 inputs: the static response is exact for all of them
    assert errors["with inertia"][1][0] < 1e-9
    assert errors["with inertia"][0][0] < 1e-9
    # the port-only Krylov space (5 moments of 3 forces) does not hold the inertia responses
    assert errors["ports only"][1][0] > 1e-3
    assert errors["ports only"][0][0] < 1e-9


def test_craig_bampton_adds_the_static_inertia_modes():
    prepared = with_inertia_loads(prepare(clamped_truss(), Frame("none"), PORT, PORT))
    full = prepared.reduction_system
    boundary = np.flatnonzero(np.any(prepared.system.input_matrix != 0, axis=1))
    loads = prepared.inertia.input_matrix
    plain = craig_bampton(full, boundary, 4)
    augmented = craig_bampton(full, boundary, 4, static_loads=loads)
    assert plain.order == 3 + 4
    assert augmented.parameters["static_load_modes"] == augmented.order - 7 > 0
    # the boundary coordinates keep their meaning
    np.testing.assert_array_equal(augmented.V[boundary][:, :3], np.eye(3))
    np.testing.assert_array_equal(augmented.V[boundary][:, 3:], 0.0)
    reference = _static(full)
    for projection, exact in ((plain, False), (augmented, True)):
        static = _static(reduced_model(full, projection).system)
        error = np.abs(static - reference)[:, 3:].max() / np.abs(reference[:, 3:]).max()
        assert (error < 1e-9) == exact, error


def test_job_switch_and_cases(tmp_path):
    base = {
        "model": {"example": "rack-beams"},
        "frame": {"type": "tangent", "node": 2},
        "inputs": [{"node": 1, "directions": "ux"}],
        "band": {"f_max_hz": 100.0},
        "reduction": [{"name": "m", "method": "modal", "order": 5}],
    }
    path = tmp_path / "job.toml"
    assert not parse_job(base, path).inertia_loads.active(("npz",))
    assert parse_job(base, path).inertia_loads.active(("npz", "sid"))
    off = parse_job({**base, "inertia_loads": {"enabled": False}}, path).inertia_loads
    assert not off.active(("sid",))
    some = parse_job({**base, "inertia_loads": {"cases": ["wzz", "az"]}}, path).inertia_loads
    assert some.cases == ("wzz", "az")
    with pytest.raises(UserError, match=r"\[inertia_loads\]\.cases: unknown load case 'wz'; did"):
        parse_job({**base, "inertia_loads": {"cases": ["wz"]}}, path)
    with pytest.raises(UserError, match=r"\[inertia_loads\]\.enabled: must be true or false"):
        parse_job({**base, "inertia_loads": {"enabled": "yes"}}, path)
    with pytest.raises(UserError, match=r"\[inertia_loads\]: unknown key 'case'"):
        parse_job({**base, "inertia_loads": {"case": ["ax"]}}, path)


JOB = """
[model]
stiffness = "model/K.mtx"
mass = "model/M.mtx"
dofs = "model/dofs.csv"
nodes = "model/nodes.csv"

[damping]
kind = "modal"
ratio = 0.02

[frame]
type = "buckens"

[[inputs]]
node = 24
directions = "ux uy uz"

[band]
f_max_hz = 2000
points = 200

[[reduction]]
name = "krylov"
method = "krylov"
expansion_points_hz = [0]
order = 12
export_inaccurate = true  # one point up to 2000 Hz: poor, on purpose (both errors are reported)

[export]
outputs = ["npz", "sid"]
"""


def run(job: Path, out: Path) -> dict:
    assert main(["reduce", str(job), "--out", str(out), "--quiet"]) == 0
    return json.loads((out / "summary.json").read_text())


def test_a_multibody_job_reports_both_errors(tmp_path):
    write_matrix_files(space_truss(), tmp_path / "model")
    (tmp_path / "job.toml").write_text(JOB)
    assert (
        main(["reduce", str(tmp_path / "job.toml"), "--out", str(tmp_path / "out"), "--quiet"]) == 0
    )
    summary = json.loads((tmp_path / "out" / "summary.json").read_text())
    model = summary["model"]
    assert model["inputs"] == ["24:ux", "24:uy", "24:uz"]
    assert model["inertia_loads"]["cases"] == ["wxx", "wyy", "wzz", "wxy", "wyz", "wxz"]
    entry = summary["reductions"][0]
    assert entry["inertia_loads"]["max_rel_error"] > 0
    assert entry["inertia_loads"]["static_rel_error"] < 1e-12  # 12 columns at 0 Hz, 9 inputs
    assert "inertia loads" in entry["inertia_loads"]["covers"]
    table = np.loadtxt(tmp_path / "out" / "krylov" / "error.csv", delimiter=",", skiprows=1)
    assert table.shape[1] == 3
    np.testing.assert_allclose(table[:, 1].max(), entry["max_rel_error"], rtol=1e-12)
    np.testing.assert_allclose(table[:, 2].max(), entry["inertia_loads"]["max_rel_error"])
    # switched off: the ports only, as before
    (tmp_path / "off.toml").write_text(JOB + "\n[inertia_loads]\nenabled = false\n")
    assert (
        main(["reduce", str(tmp_path / "off.toml"), "--out", str(tmp_path / "off"), "--quiet"]) == 0
    )
    off = json.loads((tmp_path / "off" / "summary.json").read_text())
    assert off["model"]["inertia_loads"] is None
    assert "inertia_loads" not in off["reductions"][0]


def test_a_body_accurate_only_at_its_ports_is_named():
    tiny, large = np.full(5, 1e-9), np.array([1e-9, 0.3, 1.2, 0.1, 0.0])
    message = inertia_warning("krylov-30", tiny, large)
    assert message.startswith("reduction 'krylov-30': max error 1.0e-09 over the ports but 1.2e+00")
    assert inertia_warning("k", tiny, np.full(5, 5e-3)) is None  # small in absolute terms
    assert inertia_warning("k", np.full(5, 0.1), np.full(5, 0.5)) is None  # both poor alike
    assert inertia_warning("k", tiny, None) is None


def test_static_solve_reference_is_independent():
    """The compliance scaling against scipy's dense solve of the same free truss (Buckens)."""
    prepared = with_inertia_loads(prepare(space_truss(), Frame("buckens"), PORT, PORT))
    system = prepared.system
    k, m = system.stiffness.toarray(), system.mass.toarray()
    rigid = system.rigid_modes
    # K^+ on the M-orthogonal complement: the pseudo-inverse of the projected stiffness
    p = np.eye(k.shape[0]) - rigid @ rigid.T @ m
    k_plus = p @ sla.pinv(k) @ p.T
    comp = lambda b: np.einsum("ij,ij->j", b, k_plus @ b)  # noqa: E731
    np.testing.assert_allclose(
        comp(prepared.inertia.input_matrix),
        np.median(comp(system.input_matrix)),
        rtol=1e-7,
    )
