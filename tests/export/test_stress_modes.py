"""Stress and strain modes in every output (issue #29 item 2): the recovery file, the VTU, the
Exudyn body; bodies without solids.

References built here, apart from the writers: the stress operator of the full model applied to
the basis in the test (``pymorembs.stress``, verified in tests/stress against CalculiX and
analytic cases), the analytic stress ``D eps`` of an exact linear displacement field, SciPy's
sparse LU of the full model under a load, and von Mises written out by hand.
"""

from __future__ import annotations

import h5py
import meshio
import numpy as np
import pytest
import scipy.sparse.linalg as spla

import pymorembs as pm
from pymorembs.examples import build_example
from pymorembs.export import write_outputs
from pymorembs.export.exudyn_body import load_exudyn_body
from pymorembs.export.recovery import write_stress_recovery
from pymorembs.export.stress_modes import StressModes, stress_modes
from pymorembs.stress import stress_operator

#: The blade's steel (pymorembs.examples.blade).
E, NU = 2.1e11, 0.3


def mises(s: np.ndarray) -> np.ndarray:
    """Von Mises of (..., 6) in the order xx yy zz xy xz yz."""
    xx, yy, zz, xy, xz, yz = np.moveaxis(s, -1, 0)
    return np.sqrt(0.5 * ((xx - yy) ** 2 + (yy - zz) ** 2 + (zz - xx) ** 2)
                   + 3 * (xy**2 + xz**2 + yz**2))  # fmt: skip


@pytest.fixture(scope="module")
def blade() -> pm.ReducedBody:
    """hex20 blade (783 dofs) clamped at its root, Krylov at 0 Hz for forces at the tip."""
    body = build_example("blade", elements=8)
    prepared = pm.prepare(body, "none", inputs=[(1, "uy uz")])
    return pm.reduce(prepared, "krylov", expansion_points_hz=[0, 20], order=6)


@pytest.fixture(scope="module")
def written(blade, tmp_path_factory):
    folder = tmp_path_factory.mktemp("modes")
    names = write_outputs(blade.model, blade.prepared, "k", ["stress_recovery", "vtu",
                                    "exudyn"], [1], folder)  # fmt: skip
    return folder, names


def linear_fields(body) -> tuple[np.ndarray, np.ndarray]:
    """Two exact linear displacement fields over all dofs and their (constant) stresses.

    u = eps x with eps = (a) uniaxial strain xx, (b) a shear xy plus a strain zz: the stress
    is D eps at every point, for every element kind, with Lame's constants of (E, nu).
    """
    lam = E * NU / ((1 + NU) * (1 - 2 * NU))
    mu = E / (2 * (1 + NU))
    cases = [np.diag([1e-3, 0, 0]), np.array([[0, 2e-4, 0], [2e-4, 0, 0], [0, 0, -5e-4]])]
    columns, stresses = [], []
    for eps in cases:
        u = np.zeros(body.n_dof)
        rows = body.dofs.directions < 3
        xyz = body.coordinates[body.node_rows(body.dofs.nodes[rows])]
        u[rows] = (xyz @ eps.T)[np.arange(rows.sum()), body.dofs.directions[rows]]
        sigma = 2 * mu * eps + lam * np.trace(eps) * np.eye(3)
        columns.append(u)
        stresses.append(sigma[[0, 1, 2, 0, 0, 1], [0, 1, 2, 1, 2, 2]])
    return np.column_stack(columns), np.array(stresses)


# --------------------------------------------------------------------------- recovery file
def test_the_recovery_file_read_with_h5py_holds_the_operator_times_the_basis(blade, written):
    folder, names = written
    assert names == ["k.vtu", "k.stress.h5", "k_exudyn.npz"]
    body = blade.prepared.body
    basis = blade.basis
    with h5py.File(folder / "k.stress.h5", "r") as f:
        assert f.attrs["format"] == "pymorembs-stress-recovery" and f.attrs["version"] == 1
        assert f.attrs["components"] == "xx yy zz xy xz yz" and f.attrs["note"] == ""
        assert f.attrs["method"] == "krylov" and f.attrs["name"] == "k"
        m = int(f["columns"].attrs["n_shapes"])
        labels = [label.decode() for label in f["columns/labels"][()]]
        assert m == 6 and labels == ["1", "2", "3", "4", "5", "6", "1:uy", "1:uz"]
        assert np.array_equal(f["columns/eigenfrequencies_hz"][()], blade.eigenfrequencies_hz)
        ip = {key: f["integration_points"][key][()] for key in f["integration_points"]}
        nodes = {key: f["nodes"][key][()] for key in f["nodes"]}
    # 8 x 2 x 2 hex20 with 27 points each; the nodes are the mesh's
    assert ip["stress"].shape == ip["strain"].shape == (8, 32 * 27, 6)
    assert np.array_equal(np.unique(ip["element_ids"]), np.arange(1, 33))
    assert np.array_equal(np.unique(ip["point_numbers"]), np.arange(1, 28))
    assert np.array_equal(nodes["node_ids"], np.unique(body.mesh.connectivity))
    assert np.array_equal(nodes["coordinates"], body.coordinates[body.node_rows(nodes["node_ids"])])
    # recomputed from the full model's operator, in the file's point order
    for location, data in (("integration", ip), ("nodes", nodes)):
        for quantity in ("stress", "strain"):
            op = stress_operator(body, location=location, quantity=quantity)
            assert np.array_equal(op.coordinates, data["coordinates"])
            # the file's strains are its stresses through the compliance (one material), the
            # operator's assembled ones: both sum large element terms of a smooth field to a
            # small strain, rounded apart by up to 5e-11 of the largest strain (measured)
            tolerance = 1e-12 if quantity == "stress" else 1e-10
            for j in (0, 5):
                expected = (op.matrix @ basis[:, j]).reshape(-1, 6)
                assert np.allclose(data[quantity][j], expected, rtol=0,
                                   atol=tolerance * np.abs(expected).max())  # fmt: skip
    # a static column is the stress of the static response to its unit input
    column = spla.spsolve(blade.prepared.system.stiffness.tocsc(),
                          blade.prepared.system.input_matrix[:, 0])  # fmt: skip
    u = blade.prepared.expand(column[:, None])[:, 0]
    op = stress_operator(body, location="integration")
    expected = (op.matrix @ u).reshape(-1, 6)
    assert np.abs(ip["stress"][6] - expected).max() < 1e-8 * np.abs(expected).max()


def test_the_recovery_file_of_exact_linear_fields_holds_d_eps_everywhere(blade, tmp_path):
    body = blade.prepared.body
    columns, sigma = linear_fields(body)
    modes = StressModes(body, columns, ["a", "b"], 2)
    path = write_stress_recovery(tmp_path / "lin.stress.h5", modes, name="lin", body_name="b",
                                 method="test", labels=modes.labels, n_shapes=2,
                                 eigenfrequencies_hz=np.zeros(2))  # fmt: skip
    with h5py.File(path, "r") as f:
        for group in ("integration_points", "nodes"):
            values = f[group]["stress"][()]
            for j in range(2):
                assert np.abs(values[j] - sigma[j]).max() < 1e-9 * np.abs(sigma[j]).max()


# --------------------------------------------------------------------------------- VTU
def test_the_vtu_holds_nodal_tensors_in_vtk_order_and_von_mises(blade, written):
    folder, _ = written
    body = blade.prepared.body
    mesh = meshio.read(folder / "k.vtu")
    op = stress_operator(body, location="nodes")
    rows = body.node_rows(op.node_ids)
    for name, column in (("shape_001", blade.basis[:, 0]), ("static_1_uz", None)):
        if column is None:
            with h5py.File(folder / "k.stress.h5", "r") as f:
                expected = f["nodes/stress"][7]
        else:
            expected = (op.matrix @ column).reshape(-1, 6)
        tensor = mesh.point_data[f"{name}_stress"][rows]
        scale = np.abs(expected).max()
        # VTK's symmetric tensor: xx yy zz xy yz xz
        assert np.allclose(tensor, expected[:, [0, 1, 2, 3, 5, 4]], rtol=0, atol=1e-12 * scale)
        assert np.allclose(mesh.point_data[f"{name}_von_mises"][rows], mises(expected), rtol=0,
                           atol=1e-12 * scale)  # fmt: skip
        assert mesh.point_data[f"{name}_strain"].shape == (body.n_nodes, 6)


# ------------------------------------------------------------------------------- Exudyn
def set_modal_coordinates(model, q: np.ndarray) -> None:
    import exudyn

    data = model.mbs.systemData
    c = np.array(data.GetODE2Coordinates())
    c[np.array(data.GetObjectLTGODE2(model.object_index))[-q.size :]] = q
    data.SetODE2Coordinates(list(c), exudyn.ConfigurationType.Current)


def exudyn_stress(model, mesh_node: int) -> np.ndarray:
    """Exudyn's StressLocal of a mesh node, back in the order xx yy zz xy xz yz."""
    import exudyn

    value = model.mbs.GetObjectOutputSuperElement(
        model.object_index, exudyn.OutputVariableType.StressLocal, mesh_node,
        configuration=exudyn.ConfigurationType.Current,
    )  # fmt: skip
    return np.asarray(value)[[0, 1, 2, 5, 4, 3]]  # Exudyn: xx yy zz yz xz xy


def test_exudyns_stress_local_equals_the_recovery_files_nodal_stress(blade, written):
    from pymorembs.analysis.exudyn_model import build_exudyn_model

    folder, _ = written
    arrays = load_exudyn_body(folder / "k_exudyn.npz")
    assert str(arrays["outputVariableTypeModeBasis"]) == "StressLocal"
    with h5py.File(folder / "k.stress.h5", "r") as f:
        node_ids = f["nodes/node_ids"][()]
        modes = f["nodes/stress"][:6]
    q = np.array([0.3, -1.2, 0.7, 2.0, -0.4, 0.1])
    recovered = np.einsum("j,jpc->pc", q, modes)
    model = build_exudyn_model(arrays)
    set_modal_coordinates(model, q)
    mesh_ids = arrays["meshNodeIds"]
    checked = 0
    for i in range(mesh_ids.size):
        found = np.flatnonzero(node_ids == mesh_ids[i])
        expected = recovered[found[0]] if found.size else np.zeros(6)
        got = exudyn_stress(model, i)
        assert np.allclose(got, expected, rtol=0, atol=1e-12 * np.abs(recovered).max())
        checked += bool(found.size)
    assert checked > 100  # the surface nodes of the blade


def test_exudyn_static_stress_under_a_tip_force_equals_the_full_models(blade, written):
    """Exudyn's static solution under a tip force (frame fixed: the blade is clamped at its
    root) against the full FE model's under the same force, at every surface node: the
    Krylov basis holds the static response to the tip forces (0 Hz), so the difference is
    rounding -- of a slender blade's stiffness matrix of condition 3e10, where two direct
    solves of the same K u = f (SciPy's sparse LU, NumPy's dense LU) differ by 2e-7 relative:
    bound 1e-6 of the largest nodal stress (measured 1.6e-7)."""
    import exudyn

    from pymorembs.analysis.exudyn_model import build_exudyn_model

    folder, _ = written
    arrays = load_exudyn_body(folder / "k_exudyn.npz")
    force = np.array([0.0, 3.0, -10.0])  # N at node 1 (the tip centre)
    model = build_exudyn_model(arrays, loads=[(1, force)])
    settings = exudyn.SimulationSettings()
    settings.solution.file.write = False
    settings.solution.restart.write = False
    settings.show.computationTime = False
    newton = settings.staticSolver.newton  # Newton to rounding: its Jacobian is numerical
    newton.relativeTolerance = newton.absoluteTolerance = 1e-14
    newton.maxIterations = 10
    assert model.mbs.SolveStatic(settings, storeSolver=False)
    # the full model: K u = f at the tip (the root clamped), by SciPy's sparse LU
    prepared = blade.prepared
    system = prepared.system
    f = system.input_matrix @ force[1:]
    u = prepared.expand(spla.spsolve(system.stiffness.tocsc(), f)[:, None])[:, 0]
    body = prepared.body
    mesh_ids = arrays["meshNodeIds"]
    surface = np.unique(mesh_ids)
    op = stress_operator(
        body, location="nodes", nodes=np.intersect1d(surface, body.mesh.connectivity)
    )
    full = (op.matrix @ u).reshape(-1, 6)
    scale = np.abs(full).max()
    worst = 0.0
    for k, node in enumerate(op.node_ids):
        i = int(np.flatnonzero(mesh_ids == node)[0])
        worst = max(worst, np.abs(exudyn_stress(model, i) - full[k]).max() / scale)
    assert worst < 1e-6


# ----------------------------------------------------------------------- bodies without solids
def test_a_beam_body_writes_every_file_without_stress_and_says_why(tmp_path):
    beams = build_example("rack-beams")
    reduced = pm.reduce(pm.prepare(beams, "tangent", node=2, inputs=[(1, "ux")]), "modal", order=4)
    assert stress_modes(reduced.prepared.body, reduced.basis) is None
    kinds = ["vtu", "exudyn", "stress_recovery"]
    names = write_outputs(reduced.model, reduced.prepared, "b", kinds, [1], tmp_path)
    assert sorted(names) == ["b.stress.h5", "b.vtu", "b_exudyn.npz"]
    assert not any(key.endswith("_stress") for key in meshio.read(tmp_path / "b.vtu").point_data)
    assert "outputVariableModeBasis" not in load_exudyn_body(tmp_path / "b_exudyn.npz")
    with h5py.File(tmp_path / "b.stress.h5", "r") as f:
        assert "beam2" in f.attrs["note"]
        assert f["nodes/stress"].shape == (5, 0, 6)  # 4 shapes and the static response
        assert [label.decode() for label in f["columns/labels"][()]] == ["1", "2", "3", "4",
                                                                          "1:ux"]  # fmt: skip


# ----------------------------------------------------------------------------------- report
def test_the_report_lists_the_largest_von_mises_of_the_first_shapes(blade):
    from pymorembs.report.stress_table import stress_mode_maxima, stress_modes_table

    prepared = blade.prepared
    maxima = stress_mode_maxima(prepared, {"k": blade.model}, count=3)
    op = stress_operator(prepared.body, location="nodes")
    assert maxima["note"] is None and len(maxima["rows"]) == 3
    for row in maxima["rows"]:
        j = row["shape"] - 1
        values = mises((op.matrix @ blade.basis[:, j]).reshape(-1, 6))
        assert row["max_von_mises"] == pytest.approx(values.max(), rel=1e-12)
        assert row["node"] == op.node_ids[np.argmax(values)]
        assert row["frequency_hz"] == blade.eigenfrequencies_hz[j]
    table = stress_modes_table(maxima)
    assert table.count("<tr>") == 4 and f"{maxima['rows'][0]['max_von_mises']:.4g}" in table
    beams = pm.prepare(build_example("rack-beams"), "tangent", node=2, inputs=[(1, "ux")])
    note = stress_mode_maxima(beams, {})
    assert note["rows"] == [] and "beam2" in stress_modes_table(note)


def test_the_report_view_colours_each_shape_by_its_von_mises(blade):
    """Issue #29: in the report's 3D view a mode shows its von Mises field (``scalars`` per
    scene node, by which viewer.js colours the surface), the operator's nodal values."""
    from pymorembs.report.scene import reductions_scene

    prepared = blade.prepared
    scene = reductions_scene(prepared, {"k": blade.model}, max_shapes_each=3)
    op = stress_operator(prepared.body, location="nodes")
    rows = np.searchsorted(op.node_ids, scene["node_ids"])
    assert len(scene["shapes"]) == 3
    for j, shape in enumerate(scene["shapes"]):
        values = mises((op.matrix @ blade.basis[:, j]).reshape(-1, 6))[rows]
        np.testing.assert_allclose(shape["scalars"], values, rtol=1e-3)
    beams = pm.prepare(build_example("rack-beams"), "tangent", node=2, inputs=[(1, "ux")])
    bare = reductions_scene(beams, {"m": pm.reduce(beams, "modal", order=2).model})
    assert bare["shapes"] and all("scalars" not in shape for shape in bare["shapes"])


def test_an_exudyn_body_alone_builds_the_same_stress_rows(blade, written, tmp_path):
    """Written with the VTU the Exudyn rows are sliced from the whole mesh's nodal operator;
    alone they are assembled for the mesh nodes only: the same numbers."""
    folder, _ = written
    together = load_exudyn_body(folder / "k_exudyn.npz")["outputVariableModeBasis"]
    alone = load_exudyn_body(blade.to_exudyn(tmp_path / "alone.npz", nodes=[1]))
    assert np.allclose(alone["outputVariableModeBasis"], together, rtol=0,
                       atol=1e-12 * np.abs(together).max())  # fmt: skip


@pytest.mark.slow
def test_a_reference_node_has_no_stress_nan_in_the_vtu_and_zero_rows_in_exudyn(tmp_path):
    """rack-solid with a rigid coupling at its reference node 2 (all six dofs, no solid element
    at it): NaN in the VTU, rows of 0 for it and its six satellites in the Exudyn body."""
    body = build_example("rack-solid", dofs=7365, interface="rigid")
    prepared = pm.prepare(body, pm.Frame("tangent", 2), inputs=[(1, "ux uy uz")])
    reduced = pm.reduce(prepared, "krylov", expansion_points_hz=[0, 300], order=8)
    write_outputs(reduced.model, reduced.prepared, "r", ["vtu", "exudyn"], [1, 2], tmp_path)
    mesh = meshio.read(tmp_path / "r.vtu")
    at = int(np.flatnonzero(mesh.point_data["node_id"] == 2)[0])
    assert np.all(np.isnan(mesh.point_data["shape_001_stress"][at]))
    assert np.isnan(mesh.point_data["shape_001_von_mises"][at])
    assert np.isfinite(np.delete(mesh.point_data["shape_001_von_mises"], at)).all()
    arrays = load_exudyn_body(tmp_path / "r_exudyn.npz")
    basis = arrays["outputVariableModeBasis"]
    node = int(arrays["nodeMeshIndices"][list(arrays["nodeIds"]).index(2)])
    satellites = arrays["satelliteMeshIndices"][list(arrays["nodeIds"]).index(2)]
    assert satellites.min() >= 0 and not basis[[node, *satellites]].any()
    assert np.abs(basis).max(axis=1)[arrays["meshNodeIds"] != 2].min() > 0


def test_bodies_of_one_prepared_model_build_the_nodal_operator_once(blade):
    """Every reduction of a job writes its Exudyn body from the same prepared body: the nodal
    operator of a node set is built once and is the operator ``stress_operator`` builds."""
    body = blade.prepared.body
    nodes = np.unique(body.mesh.connectivity)[::3]
    first = StressModes(body, np.eye(body.n_dof)[:, :2], ["1", "2"], 2).node_operator(nodes)
    second = StressModes(body, np.eye(body.n_dof)[:, :3], ["1", "2", "3"], 3).node_operator(nodes)
    assert second is first
    fresh = stress_operator(body, location="nodes", nodes=nodes)
    np.testing.assert_array_equal(first.node_ids, fresh.node_ids)
    assert abs(first.matrix - fresh.matrix).max() == 0.0
    other = StressModes(body, np.eye(body.n_dof)[:, :1], ["1"], 1).node_operator(nodes[:5])
    assert other is not first and other.n_points == 5
