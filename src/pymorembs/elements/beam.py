"""Three-dimensional Euler–Bernoulli beam element with consistent mass.

Each element has two nodes with six dofs each, in the order ``ux uy uz rx ry rz`` of node 1, then
of node 2. In its local frame (``x`` along the axis from node 1 to node 2) the element combines

* an axial bar (``E A``, mass ``rho A``, linear shape functions);
* St-Venant torsion (``G J``, rotational mass ``rho Ip``, linear shape functions);
* bending in the local ``x-y`` plane (``E Iz``, displacement ``v`` and rotation ``rz``) and in the
  local ``x-z`` plane (``E Iy``, displacement ``w`` and rotation ``ry = -w'``), each with cubic
  Hermite shape functions and the consistent mass ``rho A`` (no rotary inertia of the section,
  no shear deformation).

The local frame follows an orientation vector ``up``: the local ``z`` axis is the part of ``up``
perpendicular to the element axis, the local ``y`` axis completes a right-handed frame
(``y = z x x``). The default ``up`` is the global ``z`` axis; for an element parallel to it the
global ``y`` axis is used instead (an element along ``+z`` then has local ``y`` = global ``x`` and
local ``z`` = global ``y``).

Linear shape functions reproduce rigid translations and rotations exactly, so the stiffness has
the six rigid-body modes in its null space and the translational mass of an element is ``rho A L``.
Units are SI in the built-in examples (m, kg, s, N), but any consistent set works.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, fields

import numpy as np
import scipy.sparse as sp

from pymorembs.errors import UserError

#: Default orientation vector and its fallback for elements parallel to it.
DEFAULT_UP = np.array([0.0, 0.0, 1.0])
FALLBACK_UP = np.array([0.0, 1.0, 0.0])

# Relative size of the part of ``up`` perpendicular to the axis below which they count as parallel.
_PARALLEL_TOL = 1e-6

# Cubic Hermite bending matrices in the x-y plane, dofs (v1, rz1, v2, rz2), with the lengths
# factored out: K = E I / L^3 * D K_HAT D and M = rho A L / 420 * D M_HAT D, D = diag(1, L, 1, L).
_K_HAT = np.array(
    [
        [12.0, 6.0, -12.0, 6.0],
        [6.0, 4.0, -6.0, 2.0],
        [-12.0, -6.0, 12.0, -6.0],
        [6.0, 2.0, -6.0, 4.0],
    ]
)
_M_HAT = np.array(
    [
        [156.0, 22.0, 54.0, -13.0],
        [22.0, 4.0, 13.0, -3.0],
        [54.0, 13.0, 156.0, -22.0],
        [-13.0, -3.0, -22.0, 4.0],
    ]
)
# In the x-z plane the rotation ry = -w' has the opposite sign: S K S with S = diag(1, -1, 1, -1).
_PLANE_XZ_SIGN = np.array([1.0, -1.0, 1.0, -1.0])
# Two-node bar (axial and torsion): K = k / L * BAR_K, M = m L * BAR_M.
_BAR_K = np.array([[1.0, -1.0], [-1.0, 1.0]])
_BAR_M = np.array([[2.0, 1.0], [1.0, 2.0]]) / 6.0


@dataclass(frozen=True)
class BeamSection:
    """Cross-section and material of a beam.

    Parameters
    ----------
    E : float
        Young's modulus (N/m²).
    G : float
        Shear modulus (N/m²).
    rho : float
        Density (kg/m³).
    area : float
        Cross-section area ``A`` (m²).
    Iy : float
        Second moment of area about the local ``y`` axis (m⁴): bending in the local ``x-z`` plane.
    Iz : float
        Second moment of area about the local ``z`` axis (m⁴): bending in the local ``x-y`` plane.
    J : float
        St-Venant torsion constant (m⁴); equals ``Ip`` for a circular section.
    Ip : float
        Polar moment of area ``Iy + Iz`` (m⁴), for the rotational mass ``rho Ip`` per length.
    """

    E: float
    G: float
    rho: float
    area: float
    Iy: float
    Iz: float
    J: float
    Ip: float

    def __post_init__(self) -> None:
        for f in fields(self):
            value = getattr(self, f.name)
            if not (np.isfinite(value) and value > 0):
                raise UserError(f"beam section: {f.name} must be finite and > 0, got {value!r}")

    @classmethod
    def circular(cls, diameter: float, *, E: float, nu: float, rho: float) -> BeamSection:
        """Solid circular section of the given diameter (m); ``nu`` is Poisson's ratio."""
        area = np.pi * diameter**2 / 4.0
        inertia = np.pi * diameter**4 / 64.0
        return cls(
            E=E, G=_shear_modulus(E, nu), rho=rho, area=area, Iy=inertia, Iz=inertia,
            J=2.0 * inertia, Ip=2.0 * inertia,
        )  # fmt: skip

    @classmethod
    def rectangular(
        cls, width: float, height: float, *, E: float, nu: float, rho: float
    ) -> BeamSection:
        """Solid rectangle, ``width`` (m) along the local ``y`` axis, ``height`` (m) along ``z``.

        The torsion constant uses Roark's approximation ``J = a b³ (1/3 - 0.21 (b/a)
        (1 - b⁴/(12 a⁴)))`` with ``a >= b`` the side lengths (error below 1 %).
        """
        a, b = max(width, height), min(width, height)
        torsion = a * b**3 * (1.0 / 3.0 - 0.21 * (b / a) * (1.0 - (b / a) ** 4 / 12.0))
        iy = width * height**3 / 12.0
        iz = height * width**3 / 12.0
        return cls(
            E=E, G=_shear_modulus(E, nu), rho=rho, area=width * height, Iy=iy, Iz=iz,
            J=torsion, Ip=iy + iz,
        )  # fmt: skip


def _shear_modulus(E: float, nu: float) -> float:
    if not -1.0 < nu < 0.5:
        raise UserError(f"beam section: Poisson's ratio must lie in (-1, 0.5), got {nu!r}")
    return E / (2.0 * (1.0 + nu))


def element_matrices(
    p1: np.ndarray, p2: np.ndarray, section: BeamSection, up: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """Global stiffness and mass matrices of one beam element.

    Parameters
    ----------
    p1, p2 : ndarray, shape (3,)
        Positions of node 1 and node 2 (m).
    section : BeamSection
        Section and material.
    up : ndarray, shape (3,), optional
        Orientation vector: the local ``z`` axis lies in the plane of the axis and ``up``.
        Default: global ``z``, or global ``y`` for an element parallel to ``z``.

    Returns
    -------
    K, M : ndarray, shape (12, 12)
        Stiffness (N/m, N, N·m) and mass (kg, kg·m, kg·m²) in global directions, dofs
        ``ux uy uz rx ry rz`` of node 1, then node 2.
    """
    k, m = batch_element_matrices(
        np.asarray(p1, dtype=float)[None], np.asarray(p2, dtype=float)[None], section, up
    )
    return k[0], m[0]


def batch_element_matrices(
    p1: np.ndarray, p2: np.ndarray, section: BeamSection, up: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """Global stiffness and mass matrices of many elements at once.

    Parameters
    ----------
    p1, p2 : ndarray, shape (n_el, 3)
        Node positions (m).
    section : BeamSection
        Section and material, the same for all elements.
    up : ndarray, shape (3,) or (n_el, 3), optional
        Orientation vector(s); see :func:`element_matrices`.

    Returns
    -------
    K, M : ndarray, shape (n_el, 12, 12)
        Element matrices in global directions.
    """
    length, rotation = element_frames(p1, p2, up)
    k_local, m_local = _local_matrices(length, section)
    return _to_global(k_local, rotation), _to_global(m_local, rotation)


def element_frames(
    p1: np.ndarray, p2: np.ndarray, up: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """Lengths and local frames of elements.

    Parameters
    ----------
    p1, p2 : ndarray, shape (n_el, 3)
        Node positions (m).
    up : ndarray, shape (3,) or (n_el, 3), optional
        Orientation vector(s); see :func:`element_matrices`.

    Returns
    -------
    length : ndarray, shape (n_el,)
        Element lengths (m).
    rotation : ndarray, shape (n_el, 3, 3)
        Rows are the local ``x, y, z`` axes in global coordinates (local = rotation @ global).
    """
    axis = np.asarray(p2, dtype=float) - np.asarray(p1, dtype=float)
    length = np.linalg.norm(axis, axis=1)
    if np.any(length == 0.0):
        raise UserError(f"beam: element {int(np.argmin(length))} has zero length")
    ex = axis / length[:, None]
    explicit = up is not None
    up_vec = np.broadcast_to(DEFAULT_UP if up is None else np.asarray(up, dtype=float), ex.shape)
    up_vec = up_vec / np.linalg.norm(up_vec, axis=1, keepdims=True)
    ez = up_vec - np.einsum("ij,ij->i", up_vec, ex)[:, None] * ex
    parallel = np.linalg.norm(ez, axis=1) < _PARALLEL_TOL
    if np.any(parallel):
        if explicit:
            raise UserError(
                f"beam: orientation vector parallel to the axis of element {np.argmax(parallel)}"
            )
        fallback = FALLBACK_UP - (ex[parallel] @ FALLBACK_UP)[:, None] * ex[parallel]
        ez[parallel] = fallback
    ez /= np.linalg.norm(ez, axis=1, keepdims=True)
    ey = np.cross(ez, ex)
    return length, np.stack([ex, ey, ez], axis=1)


def _local_matrices(length: np.ndarray, s: BeamSection) -> tuple[np.ndarray, np.ndarray]:
    """Local stiffness and mass, shape (n_el, 12, 12) each, for element lengths (n_el,)."""
    n = length.size
    big_l = length[:, None, None]
    k = np.zeros((n, 12, 12))
    m = np.zeros((n, 12, 12))
    # (dofs, stiffness/length, mass*length) of the two bars: axial, torsion
    for dofs, stiff, inertia in (
        ((0, 6), s.E * s.area, s.rho * s.area),
        ((3, 9), s.G * s.J, s.rho * s.Ip),
    ):
        idx = np.array(dofs)
        k[:, idx[:, None], idx] = stiff / big_l * _BAR_K
        m[:, idx[:, None], idx] = inertia * big_l * _BAR_M
    scale = np.stack([np.ones(n), length, np.ones(n), length], axis=1)
    scale = scale[:, :, None] * scale[:, None, :]
    for dofs, bending, sign in (
        ((1, 5, 7, 11), s.E * s.Iz, np.ones(4)),  # x-y plane: v, rz
        ((2, 4, 8, 10), s.E * s.Iy, _PLANE_XZ_SIGN),  # x-z plane: w, ry = -w'
    ):
        idx = np.array(dofs)
        signs = np.outer(sign, sign)
        k[:, idx[:, None], idx] = bending / big_l**3 * scale * (signs * _K_HAT)
        m[:, idx[:, None], idx] = s.rho * s.area * big_l / 420.0 * scale * (signs * _M_HAT)
    return k, m


#: Gauss points (on [0, 1]) and weights that integrate the products of two element fields
#: (cubic Hermite times cubic, degree 6) exactly.
GAUSS_POINTS = 0.5 * (1.0 + np.polynomial.legendre.leggauss(4)[0])
GAUSS_WEIGHTS = 0.5 * np.polynomial.legendre.leggauss(4)[1]


def beam_kinematics(
    p1: np.ndarray, p2: np.ndarray, points: np.ndarray, up: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The element fields behind the consistent mass: centreline displacement and twist.

    A point of the cross-section at ``x(xi) + s`` (``s`` in the section plane) moves by
    ``u(xi) + theta_x(xi) e_x x s``: the centreline displacement ``u`` (linear axial, cubic
    Hermite transverse shape functions) and the torsion angle ``theta_x`` (linear); the bending
    rotations of the section carry no mass (no rotary inertia of bending). With these fields
    ``int rho (A u.u + Ip theta_x²) dx`` is the element's consistent mass.

    Parameters
    ----------
    p1, p2 : ndarray, shape (n_el, 3)
        Node positions (m).
    points : ndarray, shape (n_pts,)
        Positions ``xi`` along the elements, 0 at node 1 and 1 at node 2.
    up : ndarray, shape (3,) or (n_el, 3), optional
        Orientation vector(s); see :func:`element_matrices`.

    Returns
    -------
    length : ndarray, shape (n_el,)
        Element lengths (m).
    rotation : ndarray, shape (n_el, 3, 3)
        Rows: the local axes ``e_x, e_y, e_z`` in global coordinates.
    displacement : ndarray, shape (n_el, n_pts, 3, 12)
        Global centreline displacement at each point from the 12 global element dofs.
    twist : ndarray, shape (n_el, n_pts, 12)
        Torsion angle ``theta_x`` (rad) at each point from the global element dofs.
    """
    length, rotation = element_frames(p1, p2, up)
    xi = np.asarray(points, dtype=float).ravel()
    n_el, n_pts = length.size, xi.size
    linear = np.stack([1.0 - xi, xi], axis=1)  # (n_pts, 2)
    hermite = np.stack(
        [1 - 3 * xi**2 + 2 * xi**3, xi - 2 * xi**2 + xi**3, 3 * xi**2 - 2 * xi**3, xi**3 - xi**2],
        axis=1,
    )  # (n_pts, 4), the rotation columns per unit length
    scale = np.stack([np.ones(n_el), length, np.ones(n_el), length], axis=1)[:, None, :]
    local = np.zeros((n_el, n_pts, 4, 12))  # rows u v w theta_x, columns local dofs
    local[:, :, 0, [0, 6]] = linear
    local[:, :, 3, [3, 9]] = linear
    local[:, :, 1, [1, 5, 7, 11]] = hermite * scale
    local[:, :, 2, [2, 4, 8, 10]] = hermite * scale * _PLANE_XZ_SIGN
    # global element dofs -> local: blockdiag(R, R, R, R); local centreline -> global: R^T
    blocks = local.reshape(n_el, n_pts, 4, 4, 3)
    to_local = np.einsum("npqbk,nkj->npqbj", blocks, rotation).reshape(n_el, n_pts, 4, 12)
    displacement = np.einsum("nqa,npqj->npaj", rotation, to_local[:, :, :3])
    return length, rotation, displacement, to_local[:, :, 3]


def _to_global(local: np.ndarray, rotation: np.ndarray) -> np.ndarray:
    """``T^T A T`` for T = blockdiag(R, R, R, R); ``local`` (n, 12, 12), ``rotation`` (n, 3, 3)."""
    n = local.shape[0]
    blocks = local.reshape(n, 4, 3, 4, 3)
    out = np.einsum("nki,nakbl,nlj->naibj", rotation, blocks, rotation, optimize=True)
    return out.reshape(n, 12, 12)


def assemble_beams(
    node_ids: np.ndarray,
    coordinates: np.ndarray,
    elements: np.ndarray,
    section: BeamSection,
    dof_index: np.ndarray | Callable[[int], np.ndarray],
    *,
    up: np.ndarray | None = None,
    n_dof: int | None = None,
) -> tuple[sp.csr_matrix, sp.csr_matrix]:
    """Assemble the stiffness and mass matrices of a set of beam elements.

    Parameters
    ----------
    node_ids : ndarray of int, shape (n_nodes,)
        Node ids.
    coordinates : ndarray, shape (n_nodes, 3)
        Node positions (m), in the order of ``node_ids``.
    elements : ndarray of int, shape (n_el, 2)
        Node ids of the two nodes of each element.
    section : BeamSection
        Section and material of all elements.
    dof_index : ndarray of int, shape (n_nodes, 6), or callable
        Equation index of ``ux uy uz rx ry rz`` of each node (rows in the order of
        ``node_ids``), or a function of one node id returning its six equation indices
        (called once for each node used by an element).
    up : ndarray, shape (3,) or (n_el, 3), optional
        Orientation vector(s); see :func:`element_matrices`.
    n_dof : int, optional
        Size of the matrices; default: the largest equation index used plus one.

    Returns
    -------
    K, M : scipy.sparse.csr_matrix, shape (n_dof, n_dof)
        Assembled stiffness and mass matrices.
    """
    node_ids = np.asarray(node_ids, dtype=np.int64).ravel()
    coordinates = np.asarray(coordinates, dtype=float)
    elements = np.asarray(elements, dtype=np.int64).reshape(-1, 2)
    order = np.argsort(node_ids)
    pos = np.minimum(np.searchsorted(node_ids, elements, sorter=order), node_ids.size - 1)
    rows = order[pos]
    unknown = node_ids[rows] != elements
    if np.any(unknown):
        raise UserError(f"beam elements name node {elements[unknown][0]} which is not defined")
    if callable(dof_index):
        used = np.unique(rows)
        table = np.full((node_ids.size, 6), -1, dtype=np.int64)
        given = [np.asarray(dof_index(int(node_ids[r])), dtype=np.int64) for r in used]
        table[used] = np.reshape(given, (used.size, 6))
    else:
        table = np.asarray(dof_index, dtype=np.int64)
        if table.shape != (node_ids.size, 6):
            raise UserError(f"dof_index has shape {table.shape}, expected ({node_ids.size}, 6)")
    eq = table[rows].reshape(-1, 12)  # (n_el, 12): node 1 dofs, then node 2 dofs
    if eq.size and eq.min() < 0:
        raise UserError("beam elements: a node has a negative equation index")
    size = int(eq.max(initial=-1)) + 1 if n_dof is None else int(n_dof)
    k, m = batch_element_matrices(coordinates[rows[:, 0]], coordinates[rows[:, 1]], section, up)
    i = np.broadcast_to(eq[:, :, None], k.shape).ravel()
    j = np.broadcast_to(eq[:, None, :], k.shape).ravel()
    stiffness = sp.coo_matrix((k.ravel(), (i, j)), shape=(size, size)).tocsr()
    mass = sp.coo_matrix((m.ravel(), (i, j)), shape=(size, size)).tocsr()
    return stiffness, mass


# Geometric stiffness of the cubic Hermite bending in the x-y plane, dofs (v1, rz1, v2, rz2),
# lengths factored out like _K_HAT: K_G = N / (30 L) * D G_HAT D.
_G_HAT = np.array(
    [
        [36.0, 3.0, -36.0, 3.0],
        [3.0, 4.0, -3.0, -1.0],
        [-36.0, -3.0, 36.0, -3.0],
        [3.0, -1.0, -3.0, 4.0],
    ]
)


def batch_geometric_matrices(
    p1: np.ndarray,
    p2: np.ndarray,
    section: BeamSection,
    displacements: np.ndarray,
    up: np.ndarray | None = None,
) -> np.ndarray:
    """Geometric stiffness of beam elements under the axial force of a displacement field.

    The axial force ``N = E A (u2 - u1) . e_x / L`` (tension positive) of each element's nodal
    displacements gives the consistent initial-stress matrix of the element's shape functions:
    ``N / L`` on the axial bar, ``N Ip / (A L)`` on the torsion (Wagner term, linear twist) and
    ``N / (30 L) [36, 3L, -36, 3L; ...]`` on each bending plane. A tensile force stiffens.

    Parameters
    ----------
    p1, p2 : ndarray, shape (n_el, 3)
        Node positions (m).
    section : BeamSection
    displacements : ndarray, shape (n_el, 12)
        Nodal displacements and rotations of each element in global directions (m, rad).
    up : ndarray, shape (3,) or (n_el, 3), optional
        Orientation vector(s), as for :func:`batch_element_matrices`.

    Returns
    -------
    ndarray, shape (n_el, 12, 12)
        ``K_G`` in global directions (N/m, N, N m).
    """
    length, rotation = element_frames(p1, p2, up)
    n = length.size
    local = np.einsum("nij,nbj->nbi", rotation, np.asarray(displacements).reshape(n, 4, 3))
    force = section.E * section.area * (local[:, 2, 0] - local[:, 0, 0]) / length
    scaled = (force / length)[:, None, None]
    k_g = np.zeros((n, 12, 12))
    for dofs, factor in (((0, 6), 1.0), ((3, 9), section.Ip / section.area)):
        idx = np.array(dofs)
        k_g[:, idx[:, None], idx] = factor * scaled * _BAR_K
    scale = np.stack([np.ones(n), length, np.ones(n), length], axis=1)
    scale = scale[:, :, None] * scale[:, None, :]
    for dofs, sign in (((1, 5, 7, 11), np.ones(4)), ((2, 4, 8, 10), _PLANE_XZ_SIGN)):
        idx = np.array(dofs)
        signs = np.outer(sign, sign)
        k_g[:, idx[:, None], idx] = scaled / 30.0 * scale * (signs * _G_HAT)
    return _to_global(k_g, rotation)
