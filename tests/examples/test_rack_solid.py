"""The solid rack: 20-node hexahedra, structured mesh, rod ties, interface node, frequencies."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp
import scipy.sparse.linalg as sla
from scipy.spatial import cKDTree

from pymorembs.body import ElasticBody
from pymorembs.elements.hex20 import (
    GAUSS_WEIGHTS,
    HEX20_NODES,
    hex20_geometry,
    hex20_matrices,
    hex20_shape_functions,
)
from pymorembs.errors import UserError
from pymorembs.examples import EXAMPLES
from pymorembs.examples.rack_beams import STEEL_E, STEEL_NU, STEEL_RHO, RackDesign
from pymorembs.examples.rack_solid import (
    INTERFACES,
    PARTS,
    SolidMesh,
    mesh_rack,
    plan_mesh,
    rack_solid,
)

SMALL = 8_000
DESIGN = RackDesign()
Z_NODE1 = -DESIGN.lower_plate.thickness / 2.0
NODE2 = np.array([0.0, 0.0, DESIGN.node2_height])
#: Lowest frequencies (Hz) of rack-beams clamped at node 2: sway (y, x) and torsion.
BEAM_HZ = np.array([41.57, 41.62, 100.93])
#: Corner nodes of the six faces of a 20-node element (xi = -1, +1, eta = -1, +1, zeta = ...).
FACES = [np.flatnonzero(HEX20_NODES[:, k] == s) for k in range(3) for s in (-1, 1)]


@pytest.fixture(scope="module")
def mesh() -> SolidMesh:
    return mesh_rack(plan_mesh(SMALL))


@pytest.fixture(scope="module")
def body() -> ElasticBody:
    return rack_solid(SMALL, interface="none")


def _part_dofs(mesh: SolidMesh, parts: list[int]) -> np.ndarray:
    """Equation indices of the nodes of some parts (3 per node, node-major)."""
    rows = np.flatnonzero(np.isin(mesh.node_parts, parts))
    return (3 * rows[:, None] + np.arange(3)).ravel()


def _eliminated(body: ElasticBody, drop: np.ndarray | None = None) -> tuple:
    """``T^T K T`` and ``T^T M T`` for q = T q_i (q_d = G q), optionally without some dofs."""
    constraints = body.constraints
    g = constraints.matrix.tocsc()
    assert np.allclose(constraints.offset, 0.0)
    assert g[:, constraints.dependent].nnz == 0, "rod ties should need no chained constraints"
    keep = np.ones(body.n_dof, dtype=bool)
    keep[constraints.dependent] = False
    if drop is not None:
        keep[drop] = False
    independent = np.flatnonzero(keep)
    n, n_i, n_d = body.n_dof, independent.size, constraints.dependent.size
    eye = sp.csr_matrix((np.ones(n_i), (independent, np.arange(n_i))), shape=(n, n_i))
    place = sp.csr_matrix((np.ones(n_d), (constraints.dependent, np.arange(n_d))), shape=(n, n_d))
    t = (eye + place @ g[:, independent]).tocsr()
    return (t.T @ body.stiffness @ t).tocsc(), (t.T @ body.mass @ t).tocsc()


def _frequencies(body: ElasticBody, n: int, drop: np.ndarray | None = None) -> np.ndarray:
    """Lowest n frequencies (Hz, negative for negative eigenvalues) by shift-invert."""
    k, m = _eliminated(body, drop)
    omega2 = np.sort(sla.eigsh(k, k=n, M=m, sigma=-100.0, return_eigenvectors=False))
    return np.sign(omega2) * np.sqrt(np.abs(omega2)) / (2.0 * np.pi)


# --------------------------------------------------------------------------------- the element
def test_shape_functions_interpolate_and_sum_to_one() -> None:
    values, derivatives = hex20_shape_functions(HEX20_NODES)
    np.testing.assert_allclose(values, np.eye(20), atol=1e-15)
    points = np.random.default_rng(1).uniform(-1.0, 1.0, size=(50, 3))
    values, derivatives = hex20_shape_functions(points)
    np.testing.assert_allclose(values.sum(axis=1), 1.0, rtol=1e-14)
    np.testing.assert_allclose(values @ HEX20_NODES, points, atol=1e-14)  # isoparametric
    step = 1e-6
    for k in range(3):
        shifted = points + step * np.eye(3)[k]
        numeric = (hex20_shape_functions(shifted)[0] - values) / step
        np.testing.assert_allclose(derivatives[:, :, k], numeric, atol=1e-5)


def test_element_matrices_match_scikit_fem() -> None:
    """Two sheared bricks: stiffness and consistent mass equal scikit-fem's ElementHexS2."""
    skfem = pytest.importorskip("skfem")
    from skfem.helpers import dot
    from skfem.models.elasticity import lame_parameters, linear_elasticity

    shear = 0.01 * np.array([[1.0, 0.2, 0.1], [0.0, 0.8, 0.3], [0.0, 0.0, 1.2]])  # m
    grid = skfem.MeshHex.init_tensor(np.linspace(0, 2, 3), np.linspace(0, 1, 2), [0.0, 1.0])
    basis = skfem.Basis(
        skfem.MeshHex(shear @ grid.p, grid.t), skfem.ElementVector(skfem.ElementHexS2()),
        intorder=6,
    )  # fmt: skip
    k_ref = skfem.asm(linear_elasticity(*lame_parameters(STEEL_E, STEEL_NU)), basis).toarray()

    @skfem.BilinearForm
    def mass_form(u, v, w):
        return STEEL_RHO * dot(u, v)

    m_ref = skfem.asm(mass_form, basis).toarray()
    component = np.empty(basis.N, dtype=np.int64)
    for c in range(3):
        component[basis.nodal_dofs[c]] = c
        component[basis.edge_dofs[c]] = c
    nodes = (np.array([[0.0, 0, 0], [1.0, 0, 0]])[:, None] + (HEX20_NODES + 1) / 2) @ shear.T
    distance, where = cKDTree(basis.doflocs.T).query(nodes.reshape(-1, 3), k=3)
    assert np.max(distance) < 1e-12  # three dofs (components) at each node position
    order = np.take_along_axis(where, np.argsort(component[where], axis=1), axis=1)
    index = order.reshape(2, 60)  # skfem dof of (node a, direction i) -> 3 a + i
    k_e, m_e = hex20_matrices(nodes, STEEL_E, STEEL_NU, STEEL_RHO)
    k, m = np.zeros_like(k_ref), np.zeros_like(m_ref)
    for e in range(2):
        k[np.ix_(index[e], index[e])] += k_e[e]
        m[np.ix_(index[e], index[e])] += np.kron(m_e[e], np.eye(3))
    np.testing.assert_allclose(k, k_ref, atol=1e-10 * np.abs(k_ref).max())
    np.testing.assert_allclose(m, m_ref, atol=1e-12 * np.abs(m_ref).max())


# ------------------------------------------------------------------------------------ the mesh
@pytest.mark.parametrize("target", [SMALL, 20_000])
def test_dof_count_follows_the_target(target: int) -> None:
    plan = plan_mesh(target)
    assert abs(3 * plan.n_nodes - target) <= 0.15 * target
    assert mesh_rack(plan).coordinates.shape[0] == plan.n_nodes  # the count formula holds


def test_body_size_numbering_and_node1(body: ElasticBody, mesh: SolidMesh) -> None:
    assert abs(body.n_dof - SMALL) <= 0.15 * SMALL
    assert body.name == "rack-solid" and body.fixed.size == 0 and body.damping.kind == "none"
    assert body.n_dof == 3 * body.n_nodes and 2 not in body.node_index
    np.testing.assert_array_equal(body.dofs.nodes, np.repeat(body.node_ids, 3))
    np.testing.assert_array_equal(body.dofs.directions, np.tile([0, 1, 2], body.n_nodes))
    np.testing.assert_array_equal(body.node_position(1), [0.0, 0.0, Z_NODE1])  # exactly
    row = body.node_index[1]
    assert mesh.node_parts[row] == 0
    others = np.delete(body.node_ids, row)
    np.testing.assert_array_equal(others, 1001 + np.arange(body.n_nodes - 1))
    # rows by part, then z, y, x (to 1 nm)
    xyz = np.round(mesh.coordinates, 9)
    order = np.lexsort((xyz[:, 0], xyz[:, 1], xyz[:, 2], mesh.node_parts))
    np.testing.assert_array_equal(order, np.arange(body.n_nodes))


def test_parts_lie_where_rack_beams_puts_them(mesh: SolidMesh) -> None:
    z_rods = DESIGN.lower_plate.thickness / 2.0
    top = NODE2[2] + DESIGN.upper_plate.thickness / 2.0
    spans = {0: (-z_rods, z_rods), 5: (z_rods + DESIGN.rod_length, top)}
    for part in range(len(PARTS)):
        xyz = mesh.coordinates[mesh.node_parts == part]
        if part in spans:
            np.testing.assert_allclose([xyz[:, 2].min(), xyz[:, 2].max()], spans[part])
            continue
        axis = DESIGN.rod_positions[part - 1]
        radius = np.linalg.norm(xyz[:, :2] - axis, axis=1)
        assert radius.max() == pytest.approx(DESIGN.rod_diameter / 2.0, rel=1e-12)
        np.testing.assert_allclose([xyz[:, 2].min(), xyz[:, 2].max()],
                                   [z_rods, z_rods + DESIGN.rod_length])  # fmt: skip


def test_nodes_are_merged_within_each_part(mesh: SolidMesh) -> None:
    for part in range(len(PARTS)):
        xyz = mesh.coordinates[mesh.node_parts == part]
        assert not cKDTree(xyz).query_pairs(1e-7), f"{PARTS[part]}: coincident nodes"
        used = np.unique(mesh.elements[mesh.element_parts == part])
        np.testing.assert_array_equal(used, np.flatnonzero(mesh.node_parts == part))


def test_every_element_has_positive_jacobian(mesh: SolidMesh) -> None:
    determinants, _ = hex20_geometry(mesh.coordinates[mesh.elements])
    assert np.all(determinants > 0.0)


def test_masses_of_the_parts(body: ElasticBody, mesh: SolidMesh) -> None:
    """Within 1 % of volume x density; the curved surfaces are quadratic arcs."""
    expected = [DESIGN.lower_plate.mass, *4 * [DESIGN.rod_mass], DESIGN.upper_plate.mass]
    for part, mass in enumerate(expected):
        shift = np.zeros(body.n_dof)
        shift[_part_dofs(mesh, [part])[0::3]] = 1.0  # rigid x translation of the part
        assert shift @ body.mass @ shift == pytest.approx(mass, rel=1e-2), PARTS[part]
    assert body.total_mass() == pytest.approx(sum(expected), rel=1e-3)


def test_patch_test_linear_field(body: ElasticBody, mesh: SolidMesh) -> None:
    """A linear displacement field: no force on interior nodes, ``u^T K u = V sigma:eps``."""
    gradient = 1e-4 * np.array([[1.0, 0.3, -0.2], [0.5, -0.7, 0.1], [0.2, 0.4, 0.9]])
    u = (mesh.coordinates @ gradient.T + [1e-5, -2e-5, 5e-6]).ravel()
    force = (body.stiffness @ u).reshape(-1, 3)
    faces = np.concatenate([mesh.elements[:, f] for f in FACES])  # (6 n_el, 8)
    _, inverse, counts = np.unique(
        np.sort(faces, axis=1), axis=0, return_inverse=True, return_counts=True
    )
    surface = np.unique(faces[counts[inverse.ravel()] == 1])  # faces of one element only
    interior = np.setdiff1d(np.arange(body.n_nodes), surface)
    assert interior.size > 0.1 * body.n_nodes
    assert np.max(np.abs(force[interior])) < 1e-9 * np.max(np.abs(force))
    np.testing.assert_allclose(force.sum(axis=0), 0.0, atol=1e-9 * np.max(np.abs(force)))
    strain = 0.5 * (gradient + gradient.T)
    lam = STEEL_E * STEEL_NU / ((1 + STEEL_NU) * (1 - 2 * STEEL_NU))
    mu = STEEL_E / (2 * (1 + STEEL_NU))
    density = lam * np.trace(strain) ** 2 + 2 * mu * np.sum(strain**2)  # 2 x energy density
    determinants, _ = hex20_geometry(mesh.coordinates[mesh.elements])
    volume = np.sum(determinants * GAUSS_WEIGHTS)
    assert u @ body.stiffness @ u == pytest.approx(density * volume, rel=1e-10)


# ------------------------------------------------------------------------------------ the ties
def _rod_end_dofs(mesh: SolidMesh) -> np.ndarray:
    """Equation indices of the nodes on the end faces of the rods."""
    ends = np.isin(mesh.node_parts, [1, 2, 3, 4]) & np.isin(
        mesh.coordinates[:, 2], [-Z_NODE1, -Z_NODE1 + DESIGN.rod_length]
    )
    return (3 * np.flatnonzero(ends)[:, None] + [0, 1, 2]).ravel()


def test_ties_reproduce_rigid_body_motion(body: ElasticBody, mesh: SolidMesh) -> None:
    constraints = body.constraints
    np.testing.assert_array_equal(np.sort(constraints.dependent), _rod_end_dofs(mesh))
    masters = np.unique(constraints.matrix.tocoo().col // 3)
    assert set(mesh.node_parts[masters]) == {0, 5}  # rods hang on the plates only
    modes = body.rigid_body_modes(origin=np.array([0.01, -0.02, 0.1]))
    residual = modes[constraints.dependent] - constraints.matrix @ modes
    assert np.max(np.abs(residual)) < 1e-13 * np.max(np.abs(modes))


def test_free_body_has_six_rigid_body_modes(body: ElasticBody) -> None:
    frequencies = _frequencies(body, 8)
    assert np.all(np.abs(frequencies[:6]) < 0.1)
    assert frequencies[6] > 90.0  # rack-beams: first elastic mode of the free rack at 105 Hz


def test_sway_with_upper_plate_held_matches_rack_beams(body: ElasticBody, mesh: SolidMesh) -> None:
    """First sway and torsion of the lower plate within 10 % of rack-beams.

    The coarse test mesh gives about +1.5 % (41.8 / 41.8 / 100.3 Hz at 8,000 dofs): the solid
    rods are a little stiffer at their ends than beams; the ties to elastic plates are a little
    softer than the rigid plates of rack-beams.
    """
    frequencies = _frequencies(body, 3, drop=_part_dofs(mesh, [5]))
    np.testing.assert_allclose(frequencies, BEAM_HZ, rtol=0.10)


# ------------------------------------------------------------------------------ the interface
@pytest.mark.parametrize("interface", sorted(INTERFACES))
def test_interface_node2_couples_the_hole_surface(interface: str, mesh: SolidMesh) -> None:
    coupled = rack_solid(SMALL, interface=interface)
    np.testing.assert_allclose(coupled.node_position(2), NODE2, atol=1e-15)
    expected_dofs = 3 if interface == "springs" else 6
    assert coupled.dofs.of_node(2).size == expected_dofs
    hole = (mesh.node_parts == 5) & np.isclose(
        np.linalg.norm(mesh.coordinates[:, :2], axis=1), DESIGN.upper_plate.hole_diameter / 2
    )
    if interface == "rigid":  # the hole nodes' translations follow node 2
        new = np.setdiff1d(coupled.constraints.dependent, _rod_end_dofs(mesh))
        np.testing.assert_array_equal(new, (3 * np.flatnonzero(hole)[:, None] + [0, 1, 2]).ravel())
    if interface.endswith("beams"):  # a spider: rotations added at each hole node
        assert coupled.n_dof == 3 * mesh.coordinates.shape[0] + 6 + 3 * hole.sum()


def test_bad_arguments_and_registry() -> None:
    with pytest.raises(UserError, match="interface"):
        rack_solid(SMALL, interface="glue")
    with pytest.raises(UserError, match="dofs"):
        rack_solid(1_000)
    assert EXAMPLES["rack-solid"] is rack_solid and "rack-beams" in EXAMPLES
