"""VTU export: read back with meshio and compared with the basis and with static solves done here.

The references are built independently of the writer: the node fields from the dof table row by
row, the static responses by SciPy's own sparse LU (tangent frame) or by the two conditions that
define the inertia-relief solution of a free body (Buckens frame).
"""

from __future__ import annotations

from dataclasses import replace

import meshio
import numpy as np
import pytest
import scipy.sparse.linalg as spla

import pymorembs as pm
from conftest import spring_lattice
from pymorembs.errors import UserError
from pymorembs.examples import build_example
from pymorembs.export.vtu import shape_names, write_reduced_vtu, write_vtu


def rows_of(body) -> dict[tuple[int, int], int]:
    """(node id, direction code) -> row of the dof table, by hand."""
    pairs = zip(body.dofs.nodes.tolist(), body.dofs.directions.tolist(), strict=True)
    return {pair: row for row, pair in enumerate(pairs)}


def expected_fields(body, vectors: np.ndarray) -> np.ndarray:
    """Translations and rotations (n_nodes, 6, k) of the columns, from the dof table."""
    row_of = rows_of(body)
    out = np.zeros((body.n_nodes, 6, vectors.shape[1]))
    for i, node in enumerate(body.node_ids):
        for direction in range(6):
            row = row_of.get((int(node), direction))
            if row is not None:
                out[i, direction] = vectors[row]
    return out


def read_back(path, body):
    """The file read by meshio; checks that its points are the body's nodes in the frame."""
    mesh = meshio.read(path)
    assert np.array_equal(mesh.point_data["node_id"], body.node_ids)
    assert np.array_equal(mesh.points, body.coordinates)
    return mesh


def cell_node_ids(mesh, kind: str) -> np.ndarray:
    """The node ids of the cells of one VTK kind (all blocks of that kind)."""
    blocks = [block.data for block in mesh.cells if block.type == kind]
    assert blocks, kind
    return mesh.point_data["node_id"][np.concatenate(blocks)]


def relative(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.abs(a - b).max() / np.abs(b).max())


@pytest.fixture(scope="module")
def rack_tangent():
    """Beam rack, tangent frame at node 2, a force and a moment at node 1, two inertia loads."""
    body = build_example("rack-beams")
    prepared = pm.prepare(
        body, pm.Frame("tangent", 2), inputs=[(1, "ux uy uz"), (1, "rz")],
        inertia_loads=["ax", "wzz"],
    )  # fmt: skip
    return body, pm.reduce(prepared, "krylov", expansion_points_hz=[0, 400], order=14)


def test_rack_vtu_holds_the_lines_every_shape_and_the_static_responses(rack_tangent, tmp_path):
    body, reduced = rack_tangent
    prepared = reduced.prepared
    framed = prepared.body
    path = reduced.to_vtu(tmp_path / "rack.vtu")
    mesh = read_back(path, framed)
    assert np.allclose(framed.coordinates + body.node_position(2), body.coordinates, atol=1e-15)
    assert [block.type for block in mesh.cells] == ["line"]
    assert np.array_equal(cell_node_ids(mesh, "line"), body.surface.lines)

    basis = reduced.basis
    want = expected_fields(framed, basis)
    names = shape_names(reduced.order)
    assert names[0] == "shape_001" and len(names) == 14
    for k, name in enumerate(names):
        assert np.array_equal(mesh.point_data[name], want[:, :3, k]), name
        assert np.array_equal(mesh.point_data[name + "_rotation"], want[:, 3:, k]), name
    assert np.abs(mesh.point_data["shape_003"]).max() > 0
    # V^T K V = diag(omega^2) in the order of the eigenfrequencies: shape k goes with f_k
    system = prepared.reduction_system
    v = reduced.projection.V
    omega = 2 * np.pi * reduced.eigenfrequencies_hz
    assert np.allclose(np.diag(v.T @ (system.stiffness @ v)), omega**2, rtol=1e-8)

    # Static responses: SciPy's LU of the independent stiffness, loads built here
    transform = prepared.elimination.transform
    loads = {label: system.input_matrix[:, j] for j, label in enumerate(system.input_labels[:4])}
    d = framed.dofs.directions
    x, y = framed.dof_positions()[:, 0], framed.dof_positions()[:, 1]
    accel_ax = (d == 0).astype(float)  # unit frame acceleration along x
    accel_wzz = np.where(d == 0, -x, 0.0) + np.where(d == 1, -y, 0.0)  # w~ w~ c for w = e_z
    loads["inertia:ax"] = transform.T @ (framed.mass @ -accel_ax)
    loads["inertia:wzz"] = transform.T @ (framed.mass @ -accel_wzz)
    lu = spla.splu(system.stiffness.tocsc())
    expected_names = {"1:ux": "static_1_ux", "1:uy": "static_1_uy", "1:uz": "static_1_uz",
                      "1:rz": "static_1_rz", "inertia:ax": "static_inertia_ax",
                      "inertia:wzz": "static_inertia_wzz"}  # fmt: skip
    assert set(expected_names) == set(system.input_labels)
    for label, name in expected_names.items():
        reference = expected_fields(framed, transform @ lu.solve(loads[label])[:, None])[:, :, 0]
        # beam stiffness, cond ~1e11: plain LU and the refined solve differ by 3.8e-9 (1:ux)
        # (rack about 1 m: m and rad of one field compared together)
        field = np.hstack([mesh.point_data[name], mesh.point_data[name + "_rotation"]])
        assert relative(field, reference) < 1e-7, label
    # the frame node is held: no motion there in any field
    at_frame = np.flatnonzero(framed.node_ids == 2)[0]
    assert not np.any(mesh.point_data["static_1_ux"][at_frame])
    assert len(mesh.point_data) == 1 + 2 * (14 + 6)


def test_buckens_static_responses_are_the_inertia_relief_deformations(tmp_path):
    """Free rack in the Buckens frame: K u = (I - M R R^T) b and R^T M u = 0 for every input."""
    body = build_example("rack-beams")
    prepared = pm.prepare(body, "buckens", inputs=[(1, "ux uy uz")])
    reduced = pm.reduce(prepared, "krylov", expansion_points_hz=[0, 300], order=8)
    mesh = read_back(reduced.to_vtu(tmp_path / "free.vtu"), prepared.body)
    system = prepared.system
    framed = prepared.body
    rigid = framed.rigid_body_modes()[prepared.elimination.independent]
    mass, stiffness = system.mass, system.stiffness
    gram = rigid.T @ (mass @ rigid)
    row_of = rows_of(framed)
    for j, label in enumerate(system.input_labels):
        field = mesh.point_data[f"static_{label.replace(':', '_')}"]
        rotation = mesh.point_data[f"static_{label.replace(':', '_')}_rotation"]
        # back to the independent dofs through the dof table
        u = np.zeros(framed.n_dof)
        for i, node in enumerate(framed.node_ids):
            for a in range(6):
                if (int(node), a) in row_of:
                    u[row_of[int(node), a]] = (field if a < 3 else rotation)[i, a % 3]
        u = u[prepared.elimination.independent]
        b = np.zeros(framed.n_dof)
        b[row_of[1, j]] = 1.0
        b = b[prepared.elimination.independent]
        balanced = b - mass @ (rigid @ np.linalg.solve(gram, rigid.T @ b))
        assert np.linalg.norm(stiffness @ u - balanced) < 1e-7 * np.linalg.norm(balanced)
        rigid_part = np.linalg.solve(gram, rigid.T @ (mass @ u))
        assert np.abs(rigid @ rigid_part).max() < 1e-9 * np.abs(u).max(), label
        assert np.abs(u).max() > 0


def test_solid_blade_triangles_are_its_surface_and_it_has_no_rotation_arrays(tmp_path):
    body = build_example("blade", elements=8)
    tip = int(body.node_ids.max())
    prepared = pm.prepare(body, "none", inputs=[(tip, "uy uz")])
    reduced = pm.reduce(prepared, "modal", order=6)
    mesh = read_back(reduced.to_vtu(tmp_path / "blade.vtu"), body)
    assert [block.type for block in mesh.cells] == ["triangle"]
    assert np.array_equal(cell_node_ids(mesh, "triangle"), body.surface.triangles)
    fields = [*shape_names(6), f"static_{tip}_uy", f"static_{tip}_uz"]
    stresses = [f"{name}_{kind}" for name in fields for kind in ("stress", "strain", "von_mises")]
    assert sorted(mesh.point_data) == sorted(["node_id", *fields, *stresses])  # issue #29
    want = expected_fields(body, reduced.basis)
    for k, name in enumerate(shape_names(6)):
        assert np.array_equal(mesh.point_data[name], want[:, :3, k])
    clamped = body.dofs.nodes[body.fixed]
    assert not np.any(mesh.point_data["shape_001"][np.isin(body.node_ids, clamped)])


def test_a_body_without_surface_is_its_nodes_as_vertices_with_dependent_dofs_moving(tmp_path):
    body = spring_lattice()  # no elements; the last node's dofs depend on two other nodes
    assert body.surface is None
    prepared = pm.prepare(body, pm.Frame("tangent", 10), inputs=[(60, "ux uy")])
    reduced = pm.reduce(prepared, "modal", order=4)
    mesh = read_back(reduced.to_vtu(tmp_path / "lattice.vtu"), prepared.body)
    assert [block.type for block in mesh.cells] == ["vertex"]
    assert np.array_equal(mesh.cells[0].data.ravel(), np.arange(body.n_nodes))
    dependent = body.dofs.nodes[body.constraints.dependent]
    last = np.isin(body.node_ids, dependent)
    assert np.abs(mesh.point_data["shape_001"][last]).max() > 0  # from the constraint equations
    want = expected_fields(prepared.body, reduced.basis)
    assert np.array_equal(mesh.point_data["shape_004"], want[:, :3, 3])


def test_bad_arrays_are_refused_and_an_old_file_survives(rack_tangent, tmp_path):
    _, reduced = rack_tangent
    path = tmp_path / "rack.vtu"
    path.write_text("old")
    framed = reduced.prepared.body
    with pytest.raises(UserError, match="shapes have shape"):
        write_vtu(path, framed, reduced.basis[:-1])
    column = np.zeros(framed.n_dof)
    with pytest.raises(UserError, match="same array name"):
        write_vtu(path, framed, reduced.basis, static={"1:ux": column, "1_ux": column})
    nowhere = replace(framed, has_coordinates=False)
    with pytest.raises(UserError, match="no node coordinates"):
        write_vtu(path, nowhere, reduced.basis)
    assert path.read_text() == "old"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["rack.vtu"]
    write_reduced_vtu(path, reduced.model, reduced.prepared)
    assert meshio.read(path).points.shape == (framed.n_nodes, 3)


def test_the_same_reduction_writes_the_same_bytes(rack_tangent, tmp_path):
    _, reduced = rack_tangent
    first = reduced.to_vtu(tmp_path / "a.vtu").read_bytes()
    assert reduced.to_vtu(tmp_path / "b.vtu").read_bytes() == first
