"""The 3-D beam element against analytic Euler–Bernoulli, bar and torsion results."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp
import scipy.sparse.linalg as sla

from pymorembs.body import DofTable, ElasticBody
from pymorembs.elements.beam import BeamSection, assemble_beams, element_matrices
from pymorembs.errors import UserError

E, NU, RHO = 2.1e11, 0.3, 7850.0
G = E / (2 * (1 + NU))
LENGTH = 0.5
N_EL = 40
BETA_L = np.array([1.875104, 4.694091, 7.854757])  # clamped-free roots of cos cosh = -1
SKEW_AXIS = np.array([0.48, -0.6, 0.64])  # unit vector, not along any global axis


def _beam_line(axis: np.ndarray, n_el: int, origin: np.ndarray) -> tuple[np.ndarray, ...]:
    """Ids (non-contiguous), coordinates and elements of a straight line of n_el elements."""
    ids = 10 + 3 * np.arange(n_el + 1)
    xyz = origin + np.linspace(0.0, LENGTH, n_el + 1)[:, None] * axis
    return ids, xyz, np.stack([ids[:-1], ids[1:]], axis=1)


def _cantilever_modes(
    section: BeamSection, axis: np.ndarray, n_modes: int, up: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """Frequencies (Hz) and mode shapes (n_free_nodes, 6, n_modes) of a clamped-free beam."""
    ids, xyz, elements = _beam_line(axis, N_EL, origin=np.array([0.3, -0.2, 1.1]))
    dof_index = 6 * np.arange(ids.size)[::-1, None] + np.arange(6)  # not the node order
    k, m = assemble_beams(ids, xyz, elements, section, dof_index, up=up)
    free = dof_index[1:].ravel()  # clamp the first node
    kf, mf = k[free][:, free].tocsc(), m[free][:, free].tocsc()
    w2, vectors = sla.eigsh(kf, k=n_modes, M=mf, sigma=0.0)
    order = np.argsort(w2)
    return np.sqrt(w2[order]) / (2 * np.pi), vectors[:, order].reshape(N_EL, 6, n_modes)


def _frame(axis: np.ndarray, up: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Local y and z axes for the documented convention (z in the plane of axis and up)."""
    ez = up - (up @ axis) * axis
    ez /= np.linalg.norm(ez)
    return np.cross(ez, axis), ez


def _classify(
    shapes: np.ndarray, axis: np.ndarray, ey: np.ndarray, ez: np.ndarray, split_planes: bool
) -> np.ndarray:
    """Name the motion of each mode: axial, torsion, bend-y / bend-z (or bending if not split)."""

    def content(field: np.ndarray, direction: np.ndarray) -> np.ndarray:
        return np.sum(np.einsum("nkm,k->nm", field, direction) ** 2, axis=0)

    u, theta = shapes[:, :3], shapes[:, 3:]
    energy = {
        "axial": content(u, axis),
        "torsion": LENGTH**2 * content(theta, axis),
        "bend-y": content(u, ey),
        "bend-z": content(u, ez),
    }
    if not split_planes:
        energy["bending"] = energy.pop("bend-y") + energy.pop("bend-z")
    share = np.array(list(energy.values()))
    share /= share.sum(axis=0)
    assert np.all(share.max(axis=0) > 0.999), "a mode mixes motions that should decouple"
    return np.array(list(energy))[np.argmax(share, axis=0)]


def _bending_frequencies(section: BeamSection, inertia: float) -> np.ndarray:
    return BETA_L**2 / (2 * np.pi * LENGTH**2) * np.sqrt(section.E * inertia / (RHO * section.area))


def test_skew_cantilever_circular_matches_analytic_frequencies() -> None:
    section = BeamSection.circular(0.010, E=E, nu=NU, rho=RHO)
    freqs, shapes = _cantilever_modes(section, SKEW_AXIS, n_modes=14)
    ey, ez = _frame(SKEW_AXIS, np.array([0.0, 0.0, 1.0]))
    kinds = _classify(shapes, SKEW_AXIS, ey, ez, split_planes=False)  # planes degenerate
    bending = freqs[kinds == "bending"]
    expected = np.repeat(_bending_frequencies(section, section.Iy), 2)  # both planes
    np.testing.assert_allclose(bending[:6], expected, rtol=5e-3)
    bar = 1 / (4 * LENGTH)
    np.testing.assert_allclose(freqs[kinds == "axial"][0], bar * np.sqrt(E / RHO), rtol=5e-3)
    np.testing.assert_allclose(freqs[kinds == "torsion"][0], bar * np.sqrt(G / RHO), rtol=5e-3)


@pytest.mark.parametrize("explicit_up", [True, False])
def test_rectangular_section_bends_in_its_own_planes(explicit_up: bool) -> None:
    # width 6 mm along local y, height 15 mm along local z: E Iz is (6/15)^2 = 0.16 of E Iy
    section = BeamSection.rectangular(0.006, 0.015, E=E, nu=NU, rho=RHO)
    axis = SKEW_AXIS if explicit_up else np.array([0.0, 0.0, -1.0])
    up = np.array([1.0, 2.0, -0.5]) if explicit_up else None
    # documented default for an element along z: local z = global y
    ey, ez = _frame(axis, up if explicit_up else np.array([0.0, 1.0, 0.0]))
    freqs, shapes = _cantilever_modes(section, axis, n_modes=6, up=up)
    kinds = _classify(shapes, axis, ey, ez, split_planes=True)
    # bending in the local x-y plane (displacement along y) uses Iz, in x-z plane uses Iy
    np.testing.assert_allclose(
        freqs[kinds == "bend-y"][:2], _bending_frequencies(section, section.Iz)[:2], rtol=5e-3
    )
    np.testing.assert_allclose(
        freqs[kinds == "bend-z"][:2], _bending_frequencies(section, section.Iy)[:2], rtol=5e-3
    )


def _free_frame() -> tuple[ElasticBody, BeamSection]:
    """A free spatial frame: a skew member, a vertical one and a horizontal one."""
    section = BeamSection.rectangular(0.008, 0.012, E=E, nu=NU, rho=RHO)
    node_ids = np.array([7, 3, 11, 5])
    xyz = np.array([[0.0, 0.0, 0.0], [0.2, 0.1, 0.3], [0.2, 0.1, 0.0], [0.5, 0.1, 0.0]])
    elements = np.array([[7, 3], [3, 11], [11, 5]])
    dofs = DofTable(np.repeat(node_ids, 6), np.tile(np.arange(6), node_ids.size))
    k, m = assemble_beams(
        node_ids, xyz, elements, section, lambda n: dofs.indices(n, "all"), n_dof=len(dofs)
    )
    return ElasticBody(node_ids, xyz, dofs, m, k), section


def test_free_frame_rigid_body_modes_are_exact() -> None:
    body, section = _free_frame()
    rigid = body.rigid_body_modes(origin=np.array([0.1, -0.3, 0.2]))
    k = body.stiffness.toarray()
    assert np.abs(k @ rigid).max() < 1e-9 * np.abs(k).max()
    total_length = 0.2 * np.sqrt(3.5) + 0.3 + 0.3  # |(0.2, 0.1, 0.3)| = 0.1 sqrt(14)
    translation_mass = np.einsum("ij,ij->j", rigid[:, :3], body.mass @ rigid[:, :3])
    np.testing.assert_allclose(translation_mass, RHO * section.area * total_length, rtol=1e-12)
    # six and only six zero-energy modes
    eigenvalues = np.linalg.eigvalsh(k)
    assert np.sum(np.abs(eigenvalues) < 1e-9 * eigenvalues[-1]) == 6


def test_single_element_rigid_rotation_inertia() -> None:
    section = BeamSection.circular(0.01, E=E, nu=NU, rho=RHO)
    p1, p2 = np.array([0.1, 0.2, 0.3]), np.array([0.4, -0.2, 0.3])  # L = 0.5, in the x-y plane
    axis = (p2 - p1) / 0.5
    k, m = element_matrices(p1, p2, section)
    np.testing.assert_allclose(k, k.T, atol=1e-9 * np.abs(k).max())
    np.testing.assert_allclose(m, m.T, atol=1e-15)
    # spin about the own axis: rho Ip L; about the vertical through the midpoint: rho A L^3/12
    spin = np.concatenate([np.zeros(3), axis, np.zeros(3), axis])
    np.testing.assert_allclose(spin @ m @ spin, RHO * section.Ip * 0.5, rtol=1e-12)
    arm = np.cross([0.0, 0.0, 1.0], axis) * 0.25
    turn = np.concatenate([-arm, [0.0, 0.0, 1.0], arm, [0.0, 0.0, 1.0]])
    np.testing.assert_allclose(turn @ m @ turn, RHO * section.area * 0.5**3 / 12, rtol=1e-12)
    assert np.abs(k @ turn).max() < 1e-9 * np.abs(k).max()


def test_bad_input_is_a_user_error() -> None:
    section = BeamSection.circular(0.01, E=E, nu=NU, rho=RHO)
    p1, p2 = np.zeros(3), np.array([0.0, 0.0, 1.0])
    with pytest.raises(UserError, match="parallel"):
        element_matrices(p1, p2, section, up=np.array([0.0, 0.0, 2.0]))
    with pytest.raises(UserError, match="zero length"):
        element_matrices(p1, p1, section)
    with pytest.raises(UserError, match="node 9"):
        assemble_beams([1, 2], [p1, p2], [[1, 9]], section, np.arange(12).reshape(2, 6))
    with pytest.raises(UserError, match="area"):
        BeamSection.circular(0.0, E=E, nu=NU, rho=RHO)


def test_assembly_matches_a_dense_loop_over_elements() -> None:
    body, section = _free_frame()
    assert sp.issparse(body.stiffness) and sp.issparse(body.mass)
    k_ref, m_ref = np.zeros((2, body.n_dof, body.n_dof))
    for a, b in ((7, 3), (3, 11), (11, 5)):
        k_el, m_el = element_matrices(body.node_position(a), body.node_position(b), section)
        eq = np.concatenate([body.dofs.indices(a, "all"), body.dofs.indices(b, "all")])
        k_ref[np.ix_(eq, eq)] += k_el
        m_ref[np.ix_(eq, eq)] += m_el
    np.testing.assert_allclose(body.stiffness.toarray(), k_ref, rtol=1e-12, atol=1e-6)
    np.testing.assert_allclose(body.mass.toarray(), m_ref, rtol=1e-12, atol=1e-15)
