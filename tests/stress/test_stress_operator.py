"""The stress operator on box meshes built in Python (issue #29 item 1).

Exact cases: a displacement field linear in x is a uniform strain, which every element kind
represents exactly, so every location (integration points, element nodes, averaged nodes) must
give Hooke's law of it to rounding. Reference: the closed form of isotropic elasticity.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from box_meshes import box_mesh, solid_body

from pymorembs.body import NO_MESH, ElasticBody, ElementMesh
from pymorembs.elements.beam import BeamSection
from pymorembs.errors import UserError
from pymorembs.stress import extrapolation_matrix, stress_operator, von_mises

E, NU = 2.0e5, 0.3
KINDS = ("tet4", "tet10", "hex8", "hex20", "hex20r")
GRADIENT = 1e-3 * np.array([[1.0, 0.3, -0.2], [0.5, -0.4, 0.7], [0.1, 0.2, 0.6]])


def voigt(tensor: np.ndarray) -> np.ndarray:
    return tensor[[0, 1, 2, 0, 0, 1], [0, 1, 2, 1, 2, 2]]


def uniform_case(body: ElasticBody) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Displacement ``u = A x``, its strain and its stress (Hooke, closed form)."""
    strain = 0.5 * (GRADIENT + GRADIENT.T)
    stress = E / (1 + NU) * (strain + NU / (1 - 2 * NU) * np.trace(strain) * np.eye(3))
    return (body.coordinates @ GRADIENT.T).ravel(), voigt(strain), voigt(stress)


@pytest.fixture(scope="module", params=KINDS)
def box(request) -> ElasticBody:
    points, connectivity = box_mesh(request.param, (3, 2, 2), (3.0, 1.0, 2.0), (0.5, -1.0, 0.2))
    return solid_body(request.param, points, connectivity, E, NU)


@pytest.mark.parametrize("location", ["integration", "element_nodes", "nodes"])
def test_uniform_strain_is_exact_everywhere(box, location):
    u, strain, stress = uniform_case(box)
    op = stress_operator(box, location=location)
    assert op.matrix.shape == (6 * op.n_points, box.n_dof)
    assert np.abs(op(u) - stress).max() <= 1e-12 * np.abs(stress).max()
    strains = stress_operator(box, location=location, quantity="strain")
    assert np.abs(strains(u) - strain).max() <= 1e-12 * np.abs(strain).max()
    several = op(np.column_stack([u, 2 * u]))
    assert several.shape == (op.n_points, 6, 2)
    assert np.allclose(several[..., 1], 2 * op(u), rtol=1e-14, atol=1e-9)


def test_pure_tension_of_a_bar():
    """u_x = eps x, u_y = -nu eps y, u_z = -nu eps z: sigma_xx = E eps, the rest zero."""
    points, connectivity = box_mesh("tet10", (4, 1, 1), (4.0, 1.0, 1.0))
    body = solid_body("tet10", points, connectivity, E, NU)
    x, y, z = body.coordinates.T
    u = 1e-3 * np.column_stack([x, -NU * y, -NU * z]).ravel()
    for location in ("integration", "nodes"):
        s = stress_operator(body, location=location)(u)
        assert np.allclose(s, [E * 1e-3, 0, 0, 0, 0, 0], rtol=0, atol=1e-12 * E * 1e-3)
        assert np.allclose(von_mises(s), E * 1e-3, rtol=1e-13)


def test_points_are_named_and_placed(box):
    op = stress_operator(box)
    mesh = box.mesh
    q = op.n_points // mesh.connectivity.shape[0]
    assert op.element_ids[: 2 * q].tolist() == [101] * q + [102] * q
    assert op.point_numbers[:q].tolist() == list(range(1, q + 1))
    assert np.all(op.node_ids == -1)
    assert op.labels()[:2] == ("e101.ip1:sxx", "e101.ip1:syy")
    # every integration point lies inside its element's bounding box
    xyz = box.coordinates[box.node_rows(mesh.connectivity)]
    lo, hi = np.repeat(xyz.min(axis=1), q, axis=0), np.repeat(xyz.max(axis=1), q, axis=0)
    assert np.all((op.coordinates > lo) & (op.coordinates < hi))
    nodal = stress_operator(box, location="nodes")
    assert np.array_equal(nodal.node_ids, np.unique(mesh.connectivity))
    assert nodal.labels()[6] == f"n{nodal.node_ids[1]}:sxx"
    assert np.array_equal(nodal.coordinates, box.coordinates[box.node_rows(nodal.node_ids)])


def test_cube_points_run_xi_fastest():
    """CalculiX's numbering: point 2 lies at larger x than point 1 in an axis-aligned hex."""
    points, connectivity = box_mesh("hex20", (1, 1, 1), (1.0, 1.0, 1.0))
    op = stress_operator(solid_body("hex20", points, connectivity, E, NU))
    x = op.coordinates
    assert x[1, 0] > x[0, 0] and np.allclose(x[1, 1:], x[0, 1:], rtol=1e-14)
    assert x[3, 1] > x[0, 1] and np.allclose(x[3, [0, 2]], x[0, [0, 2]], rtol=1e-14)
    assert x[9, 2] > x[0, 2] and np.allclose(x[9, :2], x[0, :2], rtol=1e-14)


def test_subsets_are_rows_of_the_whole(box):
    u = np.random.default_rng(1).standard_normal(box.n_dof)
    for location in ("integration", "element_nodes", "nodes"):
        whole = stress_operator(box, location=location)
        nodes = box.mesh.connectivity[[0, 2], :2].ravel()  # nodes of elements 101 and 103
        some = stress_operator(box, location=location, elements=[103, 101], nodes=nodes)
        assert some.n_points > 0
        keys = list(zip(whole.element_ids, whole.node_ids, whole.point_numbers, strict=True))
        at = [keys.index(k) for k in zip(some.element_ids, some.node_ids, some.point_numbers,
                                         strict=True)]  # fmt: skip
        assert np.allclose(some(u), whole(u)[at], rtol=1e-13, atol=1e-9)
        assert set(some.element_ids.tolist()) <= {101, 103, -1}


def test_extrapolation_reproduces_its_interpolants():
    """A field the interpolant holds (linear for tet10, triquadratic for hex20) comes back at
    the nodes exactly; the values at the points are those of the field there."""
    from pymorembs.elements.solid import SOLID_KINDS
    from pymorembs.stress.extrapolation import NODE_COORDINATES

    def field(x):
        return 1.0 + 2.0 * x[:, 0] - 3.0 * x[:, 1] + 0.5 * x[:, 2]

    for kind in KINDS:
        at_points = field(SOLID_KINDS[kind].points)
        expected = field(NODE_COORDINATES[kind]) if kind != "tet4" else at_points[0]
        assert np.allclose(extrapolation_matrix(kind) @ at_points, expected, atol=1e-13)
    quadratic = lambda x: x[:, 0] ** 2 * x[:, 1] - x[:, 2] ** 2 * x[:, 0] + x[:, 1]  # noqa: E731
    assert np.allclose(
        extrapolation_matrix("hex20") @ quadratic(SOLID_KINDS["hex20"].points),
        quadratic(NODE_COORDINATES["hex20"]),
        atol=1e-13,
    )


def test_von_mises_of_known_states():
    assert von_mises(np.array([1.0, 0, 0, 0, 0, 0])) == pytest.approx(1.0)
    assert von_mises(np.array([0, 0, 0, 1.0, 0, 0])) == pytest.approx(np.sqrt(3.0))
    assert von_mises(np.array([2.0, 2.0, 2.0, 0, 0, 0])) == pytest.approx(0.0)
    stacked = np.zeros((4, 6, 3))
    stacked[:, 0, :] = 5.0
    assert np.allclose(von_mises(stacked, axis=1), 5.0)


def test_refusals(box):
    with pytest.raises(UserError, match="element 7 is not an element"):
        stress_operator(box, elements=[7])
    with pytest.raises(UserError, match="node 999999 is not a node"):
        stress_operator(box, nodes=[999999])
    with pytest.raises(UserError, match="location 'gauss' is not one of"):
        stress_operator(box, location="gauss")
    with pytest.raises(UserError, match="expected"):
        stress_operator(box)(np.zeros(box.n_dof + 1))
    section = BeamSection.circular(0.01, E=E, nu=NU, rho=7850.0)
    beams = ElementMesh("beam2", [[1, 2]], E, NU, section=section)
    with pytest.raises(UserError, match="stresses are not supported for beam2 elements"):
        stress_operator(_with(box, beams))
    with pytest.raises(UserError, match="has no element mesh"):
        stress_operator(_with(box, None))
    shells = replace(box, mesh=None, notes=(NO_MESH + "a.inp has elements of type S4R",))
    with pytest.raises(UserError, match=r"has no element mesh .*: a\.inp has elements of type S4R"):
        stress_operator(shells)


def _with(body: ElasticBody, mesh: ElementMesh | None) -> ElasticBody:
    return replace(body, mesh=mesh)


def test_element_ids_default_and_checked():
    mesh = ElementMesh("tet4", [[1, 2, 3, 4], [2, 3, 4, 5]], E, NU)
    assert mesh.element_ids.tolist() == [1, 2]
    with pytest.raises(UserError, match="element_ids must be 2 distinct numbers"):
        ElementMesh("tet4", [[1, 2, 3, 4], [2, 3, 4, 5]], E, NU, element_ids=[3, 3])
