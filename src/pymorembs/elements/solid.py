"""Isoparametric solid elements of imported meshes: tet4, tet10, hex8, hex20 (full and reduced).

Element kinematics for the geometric stiffening of a body read from an FE program (SID_NOTES
§4.6): shape functions in the node order of the program, the Gauss rule of its element, the
stresses of a displacement field at the Gauss points and the initial-stress matrix
``g[a, b] = int dN_a/dx_k sigma_kl dN_b/dx_l dV`` (with ``K_G[a i, b j] = g[a, b] delta_ij``).
The stiffness ``K`` of the same kinematics (:func:`solid_stiffness`) is what proves node order,
rule and material against the matrices the program wrote (tests/io/test_solid_meshes.py).

Element kinds (:data:`SOLID_KINDS`)

``"tet4"``
    Linear tetrahedron, 1 point (Abaqus C3D4, Nastran CTETRA with 4 grids, Ansys SOLID285).
``"tet10"``
    Quadratic tetrahedron, 4 points (C3D10, CTETRA with 10 grids, SOLID187). Corners 1-4, then
    the mid-edge nodes of edges 1-2, 2-3, 3-1, 1-4, 2-4, 3-4 (the same order in all three).
``"hex8"``
    Trilinear hexahedron, 2 x 2 x 2 points (C3D8, CHEXA with 8 grids, SOLID185). Corners 1-4
    around one face, 5-8 opposite them.
``"hex20"``
    Serendipity hexahedron, 3 x 3 x 3 points (C3D20), Abaqus/Ansys node order
    (:data:`pymorembs.elements.hex20.HEX20_NODES`: corners, mid-edges of the face of 1-4, of the
    face of 5-8, then of the edges 1-5 .. 4-8). Nastran's CHEXA lists the edges 1-5 .. 4-8
    before those of the face 5-8; the Nastran reader reorders them.
``"hex20r"``
    The same element with the reduced 2 x 2 x 2 rule (C3D20R, SOLID186 by default).

Integration points are numbered as CalculiX and Abaqus number them: the 4-point tetrahedron rule
from the point nearest node 1 on (volume coordinates ``(a, b, b, b)``, ``(b, a, b, b)`` ...), the
cube rules with ``xi`` running fastest, then ``eta``, then ``zeta``.

Natural coordinates: tetrahedra ``(r, s, t)`` in the unit tetrahedron with node 1 at the
origin and nodes 2, 3, 4 at the unit points; hexahedra ``(xi, eta, zeta)`` in ``[-1, 1]³``.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from pymorembs.elements.hex20 import HEX20_NODES, hex20_shape_functions
from pymorembs.errors import UserError

__all__ = [
    "SOLID_KINDS",
    "TENSOR_COMPONENTS",
    "SolidKind",
    "assemble_solid_geometric",
    "assemble_solid_stiffness",
    "lame_parameters",
    "part",
    "solid_forces",
    "solid_geometric_matrices",
    "solid_geometry",
    "solid_kind",
    "solid_point_matrices",
    "solid_stiffness",
    "solid_stresses",
    "solid_volumes",
]

ShapeFunctions = Callable[[np.ndarray], tuple[np.ndarray, np.ndarray]]

# corner nodes of each mid-edge node of the 10-node tetrahedron (0-based)
_TET10_EDGES = np.array([[0, 1], [1, 2], [2, 0], [0, 3], [1, 3], [2, 3]])
# d(L1, L2, L3, L4) / d(r, s, t) of the volume coordinates L1 = 1 - r - s - t, L2 = r, ...
_DL = np.array([[-1.0, -1.0, -1.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]])


def _volume_coordinates(points: np.ndarray) -> np.ndarray:
    p = np.asarray(points, dtype=float)
    return np.column_stack([1.0 - p.sum(axis=1), p])


def tet4_shape_functions(points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Linear tetrahedron ``N_a = L_a`` (volume coordinates).

    Returns values (q, 4) and natural derivatives (q, 4, 3).
    """
    values = _volume_coordinates(points)
    return values, np.broadcast_to(_DL, (values.shape[0], 4, 3)).copy()


def tet10_shape_functions(points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Quadratic tetrahedron: corners ``L_a (2 L_a - 1)``, mid-edge nodes ``4 L_a L_b``.

    Returns values (q, 10) and natural derivatives (q, 10, 3).
    """
    lam = _volume_coordinates(points)  # (q, 4)
    a, b = _TET10_EDGES.T
    values = np.concatenate([lam * (2.0 * lam - 1.0), 4.0 * lam[:, a] * lam[:, b]], axis=1)
    corner = (4.0 * lam - 1.0)[:, :, None] * _DL[None]
    edge = 4.0 * (lam[:, a, None] * _DL[b][None] + lam[:, b, None] * _DL[a][None])
    return values, np.concatenate([corner, edge], axis=1)


_HEX8_NODES = HEX20_NODES[:8]


def hex8_shape_functions(points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Trilinear hexahedron ``N_a = (1 + xi c_1)(1 + eta c_2)(1 + zeta c_3) / 8``.

    Returns values (q, 8) and natural derivatives (q, 8, 3).
    """
    x = np.asarray(points, dtype=float)[:, None, :]
    factors = 1.0 + x * _HEX8_NODES[None]  # (q, 8, 3)
    values = 0.125 * np.prod(factors, axis=-1)
    derivatives = np.stack(
        [
            0.125 * _HEX8_NODES[None, :, k] * np.prod(np.delete(factors, k, axis=-1), axis=-1)
            for k in range(3)
        ],
        axis=-1,
    )
    return values, derivatives


def _gauss_cube(order: int) -> tuple[np.ndarray, np.ndarray]:
    """Gauss-Legendre points of the cube, xi running fastest, then eta, then zeta (the point
    numbers of CalculiX and Abaqus)."""
    x, w = np.polynomial.legendre.leggauss(order)
    points = np.stack(np.meshgrid(x, x, x, indexing="ij"), -1).reshape(-1, 3)[:, ::-1]
    return np.ascontiguousarray(points), np.einsum("i,j,k->ijk", w, w, w).ravel()


def _tet_rule(points: int) -> tuple[np.ndarray, np.ndarray]:
    if points == 1:
        return np.full((1, 3), 0.25), np.array([1.0 / 6.0])
    # the symmetric 4-point rule of degree 2 (volume coordinates (a, b, b, b) permuted)
    a, b = (5.0 + 3.0 * np.sqrt(5.0)) / 20.0, (5.0 - np.sqrt(5.0)) / 20.0
    lam = np.full((4, 4), b) + np.eye(4) * (a - b)
    return lam[:, 1:], np.full(4, 1.0 / 24.0)


@dataclass(frozen=True, eq=False)
class SolidKind:
    """One element kind: node count, shape functions and Gauss rule (points, weights)."""

    name: str
    nodes: int
    shape_functions: ShapeFunctions
    points: np.ndarray
    weights: np.ndarray

    def __post_init__(self) -> None:
        values, derivatives = self.shape_functions(self.points)
        object.__setattr__(self, "values", values)  # (q, n)
        object.__setattr__(self, "derivatives", derivatives)  # (q, n, 3)


#: The solid element kinds by name (see the module docstring).
SOLID_KINDS: dict[str, SolidKind] = {
    "tet4": SolidKind("tet4", 4, tet4_shape_functions, *_tet_rule(1)),
    "tet10": SolidKind("tet10", 10, tet10_shape_functions, *_tet_rule(4)),
    "hex8": SolidKind("hex8", 8, hex8_shape_functions, *_gauss_cube(2)),
    "hex20": SolidKind("hex20", 20, hex20_shape_functions, *_gauss_cube(3)),
    "hex20r": SolidKind("hex20r", 20, hex20_shape_functions, *_gauss_cube(2)),
}


def solid_kind(name: str) -> SolidKind:
    """The :class:`SolidKind` of ``name``; :class:`UserError` for an unknown one."""
    try:
        return SOLID_KINDS[name]
    except KeyError:
        raise UserError(
            f"solid element kind {name!r} is not known; known: {', '.join(SOLID_KINDS)}"
        ) from None


def solid_geometry(kind: str, nodes: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Integration weights times Jacobian determinants and shape-function gradients.

    Parameters
    ----------
    kind : str
        A key of :data:`SOLID_KINDS`.
    nodes : ndarray, shape (n_el, n, 3)
        Node coordinates of each element (model length unit).

    Returns
    -------
    weights : ndarray, shape (n_el, q)
        ``w_q det(dx/dxi)`` (volume unit): the volume each Gauss point stands for.
    gradients : ndarray, shape (n_el, q, n, 3)
        ``dN_a / dx_i`` (1 / length).

    Raises
    ------
    UserError
        An element with a non-positive Jacobian determinant (inverted or degenerate; for
        example nodes in another program's order).
    """
    spec, jacobians, determinants = _jacobians(kind, nodes)
    gradients = np.einsum("qak,eqki->eqai", spec.derivatives, np.linalg.inv(jacobians))
    return determinants * spec.weights, gradients


def solid_volumes(kind: str, nodes: np.ndarray) -> np.ndarray:
    """Volume of each element by the kind's Gauss rule, shape (n_el,) (length unit cubed).

    Exact for the straight-edged elements of meshes and for curved ones to the accuracy of
    the rule. ``nodes`` and the errors as :func:`solid_geometry`.
    """
    spec, _, determinants = _jacobians(kind, nodes)
    return determinants @ spec.weights


def _jacobians(kind: str, nodes: np.ndarray) -> tuple[SolidKind, np.ndarray, np.ndarray]:
    """The kind, ``dx_i / dxi_k`` at its Gauss points (n_el, q, 3, 3) and their determinants;
    :class:`UserError` for a non-positive determinant."""
    spec = solid_kind(kind)
    jacobians = np.einsum("qak,eai->eqik", spec.derivatives, nodes)  # dx_i / dxi_k
    determinants = np.linalg.det(jacobians)
    if np.any(determinants <= 0.0):
        bad = int(np.flatnonzero(np.any(determinants <= 0.0, axis=1))[0])
        raise UserError(
            f"solid mesh: {kind} element {bad + 1} of its block has a non-positive Jacobian "
            "determinant (inverted, degenerate or nodes in another order)"
        )
    return spec, jacobians, determinants


def lame_parameters(
    young: float | np.ndarray, poisson: float | np.ndarray, ndim: int
) -> tuple[np.ndarray, np.ndarray]:
    """Lame's lambda and mu (stress unit), one per element shaped ``(n_el or 1, 1 x ndim)`` for
    broadcasting against arrays of ``1 + ndim`` axes whose first is the element."""
    e = np.asarray(young, dtype=float).reshape(-1, *(1,) * ndim)
    nu = np.asarray(poisson, dtype=float).reshape(-1, *(1,) * ndim)
    return e * nu / ((1.0 + nu) * (1.0 - 2.0 * nu)), e / (2.0 * (1.0 + nu))


def solid_stiffness(
    kind: str, nodes: np.ndarray, young: float | np.ndarray, poisson: float | np.ndarray
) -> np.ndarray:
    """Element stiffness matrices of isotropic linear elasticity with the kind's Gauss rule.

    ``K[a i, b j] = sum_q w_q (lambda G_ai G_bj + mu G_aj G_bi + mu delta_ij G_ak G_bk)`` with
    ``G = dN/dx`` at the Gauss points.

    Parameters
    ----------
    kind : str
    nodes : ndarray, shape (n_el, n, 3)
    young, poisson : float or ndarray, shape (n_el,)
        Young's modulus (model stress unit) and Poisson's ratio (one, or one per element).

    Returns
    -------
    ndarray, shape (n_el, 3 n, 3 n)
        Element dof order ``(node a, direction i) -> 3 a + i`` (force / length).
    """
    weights, gradients = solid_geometry(kind, nodes)
    lam, mu = lame_parameters(young, poisson, 4)
    n_el, _, n, _ = gradients.shape
    x = np.einsum("eq,eqai,eqbj->eaibj", weights, gradients, gradients)
    trace = np.einsum("eakbk->eab", x)
    k = lam * x + mu * x.transpose(0, 1, 4, 3, 2)
    k = k + mu * trace[:, :, None, :, None] * np.eye(3)[None, None, :, None, :]
    k = k.reshape(n_el, 3 * n, 3 * n)
    return 0.5 * (k + k.transpose(0, 2, 1))


def solid_forces(
    kind: str,
    nodes: np.ndarray,
    fields: np.ndarray,
    young: float | np.ndarray,
    poisson: float | np.ndarray,
) -> np.ndarray:
    """The element stiffness matrices of :func:`solid_stiffness` times displacement fields,
    ``K_e u``, without forming ``K_e``.

    ``(K_e u)_ai = sum_q w_q sum_k G_ak sigma_ik`` with ``sigma = lambda tr(grad u) I +
    mu (grad u + grad u^T)`` at the Gauss points: the nodal forces of the stresses of ``u``,
    the same sum as ``K_e`` times ``u`` (to rounding) at a tenth of its operations.

    Parameters
    ----------
    kind : str
    nodes : ndarray, shape (n_el, n, 3)
        Node coordinates (length unit).
    fields : ndarray, shape (n_el, n, 3, m)
        ``m`` nodal displacement fields of each element (length unit).
    young, poisson : float or ndarray, shape (n_el,)

    Returns
    -------
    ndarray, shape (n_el, 3 n, m)
        Element dof order ``(node a, direction i) -> 3 a + i`` (force unit).
    """
    weights, gradients = solid_geometry(kind, nodes)
    n_el, q, n, _ = gradients.shape
    m = fields.shape[-1]
    # du_i / dx_k at the Gauss points, axes (element, point, k, i, field)
    by_point = gradients.transpose(0, 1, 3, 2).reshape(n_el, q * 3, n)
    grad = (by_point @ fields.reshape(n_el, n, 3 * m)).reshape(n_el, q, 3, 3, m)
    lam, mu = lame_parameters(young, poisson, 4)
    sigma = mu * (grad + grad.transpose(0, 1, 3, 2, 4))
    trace = grad[:, :, 0, 0] + grad[:, :, 1, 1] + grad[:, :, 2, 2]  # (element, point, field)
    trace *= lam.reshape(-1, 1, 1)
    for i in range(3):
        sigma[:, :, i, i] += trace
    sigma *= weights[:, :, None, None, None]
    by_node = gradients.transpose(0, 2, 1, 3).reshape(n_el, n, q * 3)
    return (by_node @ sigma.reshape(n_el, q * 3, 3 * m)).reshape(n_el, 3 * n, m)


def solid_stresses(
    kind: str,
    nodes: np.ndarray,
    displacements: np.ndarray,
    young: float | np.ndarray,
    poisson: float | np.ndarray,
) -> np.ndarray:
    """Cauchy stresses of a small displacement field at the Gauss points of each element.

    ``sigma = lambda tr(eps) I + 2 mu eps``, ``eps = sym(grad u)``.

    Parameters
    ----------
    kind : str
    nodes : ndarray, shape (n_el, n, 3)
        Node coordinates (length unit).
    displacements : ndarray, shape (n_el, n, 3)
        Nodal displacements (length unit).
    young, poisson : float or ndarray, shape (n_el,)

    Returns
    -------
    ndarray, shape (n_el, q, 3, 3)
        Stress tensors (stress unit of ``young``).
    """
    _, gradients = solid_geometry(kind, nodes)
    grad = np.einsum("eai,eqak->eqik", displacements, gradients)  # du_i / dx_k
    strain = 0.5 * (grad + grad.transpose(0, 1, 3, 2))
    lam, mu = lame_parameters(young, poisson, 3)
    trace = np.trace(strain, axis1=2, axis2=3)
    return lam * trace[..., None, None] * np.eye(3) + 2.0 * mu * strain


#: The six components of a symmetric tensor, in the order of the point matrices and of
#: CalculiX/Abaqus (S11 S22 S33 S12 S13 S23): ``(i, j)`` index pairs.
TENSOR_COMPONENTS = ((0, 0), (1, 1), (2, 2), (0, 1), (0, 2), (1, 2))


def solid_point_matrices(
    kind: str,
    nodes: np.ndarray,
    young: float | np.ndarray | None = None,
    poisson: float | np.ndarray | None = None,
) -> np.ndarray:
    """Strain (or stress) of the nodal displacements at the Gauss points of each element.

    ``eps_ij = (du_i/dx_j + du_j/dx_i) / 2`` (tensor shear components), and with the material
    ``sigma = lambda tr(eps) I + 2 mu eps``; components in the order of
    :data:`TENSOR_COMPONENTS`.

    Parameters
    ----------
    kind : str
    nodes : ndarray, shape (n_el, n, 3)
        Node coordinates (length unit).
    young, poisson : float or ndarray, shape (n_el,), optional
        The material; without it the strains.

    Returns
    -------
    ndarray, shape (n_el, q, 6, n, 3)
        ``[e, p, c, a, i]``: component ``c`` at point ``p`` per unit displacement of node ``a``
        in direction ``i`` (1 / length for strains, stress / length for stresses).
    """
    _, gradients = solid_geometry(kind, nodes)  # (n_el, q, n, 3)
    out = np.zeros((*gradients.shape[:2], 6, *gradients.shape[2:]))
    for c, (i, j) in enumerate(TENSOR_COMPONENTS):
        out[:, :, c, :, i] += 0.5 * gradients[..., j]
        out[:, :, c, :, j] += 0.5 * gradients[..., i]
    if young is None or poisson is None:
        return out
    lam, mu = lame_parameters(young, poisson, 4)
    out *= 2.0 * mu
    out[:, :, :3] += lam * gradients[:, :, None]
    return out


def solid_geometric_matrices(kind: str, nodes: np.ndarray, stresses: np.ndarray) -> np.ndarray:
    """Scalar initial-stress matrices ``g[a, b] = int dN_a/dx_k sigma_kl dN_b/dx_l dV``.

    The element's geometric stiffness is ``K_G[a i, b j] = g[a, b] delta_ij`` (the second
    variation of ``int sigma : E_GL dV`` with the Green-Lagrange strain ``E_GL``).

    Parameters
    ----------
    kind : str
    nodes : ndarray, shape (n_el, n, 3)
    stresses : ndarray, shape (n_el, q, 3, 3)
        At the Gauss points of the kind (:func:`solid_stresses`).

    Returns
    -------
    ndarray, shape (n_el, n, n)
        ``g`` (force / length).
    """
    weights, gradients = solid_geometry(kind, nodes)
    g = np.einsum("eq,eqak,eqkl,eqbl->eab", weights, gradients, stresses, gradients)
    return 0.5 * (g + g.transpose(0, 2, 1))


def part(value: float | np.ndarray, start: int, count: int) -> float | np.ndarray:
    """``value[start : start + count]`` of a per-element material array; a scalar as it is."""
    return value[start : start + count] if isinstance(value, np.ndarray) else value


def assemble_solid_stiffness(
    kind: str,
    coordinates: np.ndarray,
    elements: np.ndarray,
    young: float | np.ndarray,
    poisson: float | np.ndarray,
    chunk: int = 2048,
) -> sp.csr_matrix:
    """Global stiffness of a mesh of one kind, equation ``3 r + i`` = direction ``i`` of row ``r``.

    Parameters
    ----------
    kind : str
    coordinates : ndarray, shape (n_nodes, 3)
    elements : ndarray of int, shape (n_el, n)
        Rows of ``coordinates`` of each element's nodes.
    young, poisson : float or ndarray, shape (n_el,)
    chunk : int
        Elements per batch (memory stays proportional to the matrix).

    Returns
    -------
    scipy.sparse.csr_matrix, shape (3 n_nodes, 3 n_nodes)
    """
    n = 3 * coordinates.shape[0]
    elements = np.asarray(elements, dtype=np.int64)
    rows, cols, values = [], [], []
    for start in range(0, elements.shape[0], chunk):
        conn = elements[start : start + chunk]
        k_e = solid_stiffness(
            kind, coordinates[conn], part(young, start, chunk), part(poisson, start, chunk)
        )
        dofs = (3 * conn[:, :, None] + np.arange(3)).reshape(conn.shape[0], -1)
        rows.append(np.broadcast_to(dofs[:, :, None], k_e.shape).ravel())
        cols.append(np.broadcast_to(dofs[:, None, :], k_e.shape).ravel())
        values.append(k_e.ravel())
    if not rows:
        return sp.csr_matrix((n, n))
    return sp.csr_matrix(
        (np.concatenate(values), (np.concatenate(rows), np.concatenate(cols))), shape=(n, n)
    )


def assemble_solid_geometric(
    kind: str,
    coordinates: np.ndarray,
    elements: np.ndarray,
    displacement: np.ndarray,
    young: float | np.ndarray,
    poisson: float | np.ndarray,
    chunk: int = 2048,
) -> sp.csr_matrix:
    """Global geometric stiffness ``K_G`` of a mesh of one kind under a displacement field.

    The stresses of the linear displacement field (its prestress, :func:`solid_stresses`) give
    the initial-stress matrix of every element (:func:`solid_geometric_matrices`), the same in
    each direction. A tensile prestress makes ``K_G`` positive semidefinite: it stiffens
    transverse motion (a rotating blade, a string under tension).

    Parameters
    ----------
    kind : str
    coordinates : ndarray, shape (n_nodes, 3)
    elements : ndarray of int, shape (n_el, n)
        Rows of ``coordinates`` of each element's nodes.
    displacement : ndarray, shape (3 n_nodes,)
        Equation ``3 r + i`` = direction ``i`` of the node in row ``r`` (length unit).
    young, poisson : float or ndarray, shape (n_el,)
        The material of the prestressed state.
    chunk : int
        Elements per batch.

    Returns
    -------
    scipy.sparse.csr_matrix, shape (3 n_nodes, 3 n_nodes)
    """
    n = 3 * coordinates.shape[0]
    u = np.asarray(displacement, dtype=float).reshape(-1, 3)
    elements = np.asarray(elements, dtype=np.int64)
    rows, cols, values = [], [], []
    for start in range(0, elements.shape[0], chunk):
        conn = elements[start : start + chunk]
        nodes = coordinates[conn]
        stresses = solid_stresses(
            kind, nodes, u[conn], part(young, start, chunk), part(poisson, start, chunk)
        )
        g = solid_geometric_matrices(kind, nodes, stresses)[..., None]  # (n_el, n, n, 1)
        shape = (*g.shape[:3], 3)
        rows.append(np.broadcast_to(3 * conn[:, :, None, None] + np.arange(3), shape).ravel())
        cols.append(np.broadcast_to(3 * conn[:, None, :, None] + np.arange(3), shape).ravel())
        values.append(np.broadcast_to(g, shape).ravel())
    if not rows:
        return sp.csr_matrix((n, n))
    return sp.csr_matrix(
        (np.concatenate(values), (np.concatenate(rows), np.concatenate(cols))), shape=(n, n)
    )
