"""The built-in beam rack, checked with a constraint elimination written here independently."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp
import scipy.sparse.linalg as sla

from pymorembs.body import ElasticBody
from pymorembs.elements.rigid import rigid_body_mass_matrix, skew
from pymorembs.errors import UserError
from pymorembs.examples import EXAMPLES, build_example
from pymorembs.examples.rack_beams import Plate, RackDesign

DESIGN = RackDesign()
NODE2 = np.array([0.0, 0.0, 0.004 + 0.200 + 0.0085])
#: First 12 eigenfrequencies (Hz) clamped at node 2, as documented in the module docstring.
DOCUMENTED_HZ = np.array(
    [41.568, 41.624, 100.932, 460.431, 460.431, 460.431, 460.431, 460.431, 471.964, 472.951,
     486.153, 1269.196]
)  # fmt: skip


@pytest.fixture(scope="module")
def body() -> ElasticBody:
    return build_example("rack-beams")


def _eliminated(body: ElasticBody, clamp_node: int | None) -> tuple[sp.csc_matrix, sp.csc_matrix]:
    """``T^T K T`` and ``T^T M T`` for q = T q_i (q_d = G q), optionally dropping a node's dofs."""
    dependent = body.constraints.dependent
    g = body.constraints.matrix.tocsc()
    assert np.allclose(body.constraints.offset, 0.0)
    assert g[:, dependent].nnz == 0, "the rack should need no chained constraints"
    independent = np.setdiff1d(np.arange(body.n_dof), dependent)
    if clamp_node is not None:
        independent = independent[body.dofs.nodes[independent] != clamp_node]
    n = body.n_dof
    eye = sp.csr_matrix(
        (np.ones(independent.size), (independent, np.arange(independent.size))),
        shape=(n, independent.size),
    )
    rows = sp.csr_matrix((np.ones(dependent.size), (dependent, np.arange(dependent.size))),
                         shape=(n, dependent.size))  # fmt: skip
    t = (eye + rows @ g[:, independent]).tocsr()
    return (t.T @ body.stiffness @ t).tocsc(), (t.T @ body.mass @ t).tocsc()


def _frequencies(k: sp.csc_matrix, m: sp.csc_matrix, n: int, shift: float) -> np.ndarray:
    """Lowest n eigenvalues ``omega²`` (1/s²) by shift-invert."""
    return np.sort(sla.eigsh(k, k=n, M=m, sigma=shift, return_eigenvectors=False))


def test_size_nodes_and_metadata(body: ElasticBody) -> None:
    assert 3500 <= body.n_dof <= 4500
    assert body.name == "rack-beams" and body.damping.kind == "none" and body.fixed.size == 0
    np.testing.assert_allclose(body.node_position(1), [0.0, 0.0, 0.0], atol=1e-15)
    np.testing.assert_allclose(body.node_position(2), NODE2, atol=1e-15)
    assert {1001, 1166, 4001, 4166} <= set(body.node_ids.tolist())
    assert np.all(np.bincount(np.unique(body.dofs.nodes, return_inverse=True)[1]) == 6)
    k = body.stiffness
    for node in (1, 2):  # the rigid plates have no stiffness of their own
        assert k[body.dofs.of_node(node)].nnz == 0
    assert abs(k - k.T).max() < 1e-9 * abs(k).max() and abs(body.mass - body.mass.T).max() < 1e-15


def test_masses(body: ElasticBody) -> None:
    ux = (body.dofs.directions == 0).astype(float)  # rigid x translation, consistent with G
    total = ux @ body.mass @ ux
    assert total == pytest.approx(1.4, rel=0.1)
    assert total == pytest.approx(1.3866, rel=1e-4)
    assert body.total_mass() == pytest.approx(total, rel=1e-12)
    lower, upper = (body.mass[np.ix_(body.dofs.of_node(n), body.dofs.of_node(n))] for n in (1, 2))
    assert lower[0, 0] == pytest.approx(0.2010, rel=1e-3)
    assert upper[0, 0] == pytest.approx(1.1067, rel=1e-3)
    assert upper[0, 0] + 4 * DESIGN.rod_mass == pytest.approx(1.2, rel=0.05)  # "upper part"
    for block, plate in ((lower, DESIGN.lower_plate), (upper, DESIGN.upper_plate)):
        np.testing.assert_allclose(block.toarray()[3:, 3:], plate.inertia(), rtol=1e-12)
        assert np.all(np.linalg.eigvalsh(block.toarray()) > 0)


def test_constraints_are_rigid_links(body: ElasticBody) -> None:
    c = body.constraints
    ends = np.unique(body.dofs.nodes[c.dependent])
    expected = [1000 * j + i for j in range(1, 5) for i in (1, 166)]
    np.testing.assert_array_equal(ends, sorted(expected))
    assert c.matrix.shape == (48, body.n_dof)
    referenced = np.unique(body.dofs.nodes[c.matrix.indices])
    np.testing.assert_array_equal(referenced, [1, 2])
    # every rigid motion of the whole body (any origin) fulfils q_d = G q
    rigid = body.rigid_body_modes(origin=np.array([0.3, -0.1, 0.05]))
    np.testing.assert_allclose(c.matrix @ rigid, rigid[c.dependent], atol=1e-14)
    assert np.abs(body.stiffness @ rigid).max() < 1e-6 * abs(body.stiffness).max()


def test_clamped_eigenfrequencies(body: ElasticBody) -> None:
    k, m = _eliminated(body, clamp_node=2)
    assert k.shape[0] == body.n_dof - 48 - 6
    hz = np.sqrt(_frequencies(k, m, 12, shift=0.0)) / (2 * np.pi)
    assert hz[0] > 1.0 and np.sum(hz < 1000.0) >= 4
    np.testing.assert_allclose(hz, DOCUMENTED_HZ, rtol=1e-4)
    # Hand check of the sway of the lower plate: four guided-guided rods, k = 4 * 12 E I / L^3,
    # effective mass = plate + 13/35 of each rod (Rayleigh). The rods' end rotations are held by
    # the plates only through the rods' axial stiffness, and the Rayleigh mass factor is an
    # approximation: 5 % covers both with margin (the model differs by about 0.4 %).
    section, length = DESIGN.rod_section, DESIGN.rod_length
    stiffness = 4 * 12 * section.E * section.Iz / length**3
    mass = DESIGN.lower_plate.mass + 4 * 13 / 35 * DESIGN.rod_mass
    sway = np.sqrt(stiffness / mass) / (2 * np.pi)
    np.testing.assert_allclose(hz[:2], sway, rtol=0.05)


def test_free_rack_has_six_rigid_body_modes(body: ElasticBody) -> None:
    k, m = _eliminated(body, clamp_node=None)
    omega2 = _frequencies(k, m, 9, shift=-10.0)
    first_elastic = (2 * np.pi * 30.0) ** 2  # the first elastic mode lies at 105 Hz
    assert np.sum(np.abs(omega2) < 1e-3 * first_elastic) == 6
    assert omega2[6] > first_elastic


def test_rigid_body_mass_matrix_equals_a_cloud_of_point_masses() -> None:
    rng = np.random.default_rng(7)
    masses = rng.uniform(0.1, 1.0, 20)
    points = rng.normal(size=(20, 3)) + np.array([0.3, -0.2, 0.5])  # relative to the reference node
    links = np.concatenate([np.broadcast_to(np.eye(3), (20, 3, 3)), -skew(points)], axis=2)
    expected = np.einsum("p,pki,pkj->ij", masses, links, links)  # u_p = u - [r_p]x theta
    total = masses.sum()
    cg = masses @ points / total
    s = points - cg
    inertia = np.einsum("p,pk,pk->", masses, s, s) * np.eye(3) - np.einsum(
        "p,pi,pj->ij", masses, s, s
    )
    np.testing.assert_allclose(rigid_body_mass_matrix(total, inertia, cg), expected, atol=1e-12)


def test_plate_mass_and_inertia_by_quadrature() -> None:
    plate = Plate(0.100, 0.090, 0.017, hole_diameter=0.030)
    h = 0.0005
    axes = [np.arange(-e / 2 + h / 2, e / 2, h) for e in (0.100, 0.090, 0.017)]
    x, y, z = (a.ravel() for a in np.meshgrid(*axes, indexing="ij"))
    solid = x**2 + y**2 > 0.015**2
    p = np.stack([x[solid], y[solid], z[solid]], axis=1)
    dm = plate.density * h**3
    inertia = dm * (np.sum(p**2) * np.eye(3) - p.T @ p)
    assert plate.mass == pytest.approx(dm * p.shape[0], rel=5e-3)
    np.testing.assert_allclose(plate.inertia(), inertia, rtol=5e-3, atol=1e-9)


def test_example_registry() -> None:
    assert "rack-beams" in EXAMPLES
    with pytest.raises(UserError, match="'rack-solid2'; available: blade, rack-beams, rack-solid"):
        build_example("rack-solid2")
