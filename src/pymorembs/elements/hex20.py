"""The 20-node serendipity hexahedron: shape functions, element matrices, assembly.

Isoparametric, isotropic linear elasticity, full 3 x 3 x 3 Gauss integration, consistent mass.
Node order of Abaqus C3D20 / Ansys SOLID186 (:data:`HEX20_NODES`); the tests check the matrices
against scikit-fem's ``ElementHexS2``. Used by the built-in solid models
(:mod:`pymorembs.examples.rack_solid`, :mod:`pymorembs.examples.blade`); the stresses and the
geometric (initial-stress) stiffness of a prestressed state are those of the kind ``"hex20"``
of :mod:`pymorembs.elements.solid`.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from pymorembs.elements.assembly import NodePattern
from pymorembs.errors import UserError

#: Natural coordinates (xi, eta, zeta) of the 20 nodes, in the order of Abaqus C3D20 / Ansys
#: SOLID186: corners of the face zeta = -1 and of zeta = +1 (counter-clockwise seen from +zeta),
#: mid-edge nodes of zeta = -1, of zeta = +1, then of the four edges along zeta.
HEX20_NODES = np.array(
    [[-1, -1, -1], [1, -1, -1], [1, 1, -1], [-1, 1, -1],
     [-1, -1, 1], [1, -1, 1], [1, 1, 1], [-1, 1, 1],
     [0, -1, -1], [1, 0, -1], [0, 1, -1], [-1, 0, -1],
     [0, -1, 1], [1, 0, 1], [0, 1, 1], [-1, 0, 1],
     [-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]],
    dtype=float,
)  # fmt: skip
#: The eight nodes of the faces zeta = -1 and zeta = +1 (corners first).
FACE_NODES = {side: np.flatnonzero(HEX20_NODES[:, 2] == side) for side in (-1, 1)}
# Node a of an element mirrored in xi (a left-handed block mapping is made right-handed).
MIRROR_XI = np.array(
    [int(np.flatnonzero(np.all(HEX20_NODES == c * [-1, 1, 1], axis=1))[0]) for c in HEX20_NODES]
)
# 3 x 3 x 3 Gauss-Legendre rule: exact for mass and stiffness of an affine element.
_GAUSS_1D = np.array([-np.sqrt(0.6), 0.0, np.sqrt(0.6)])
_WEIGHTS_1D = np.array([5.0, 8.0, 5.0]) / 9.0
GAUSS_POINTS = np.stack(np.meshgrid(*3 * [_GAUSS_1D], indexing="ij"), -1).reshape(-1, 3)
GAUSS_WEIGHTS = np.einsum("i,j,k->ijk", *3 * [_WEIGHTS_1D]).ravel()


def hex20_shape_functions(points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Serendipity shape functions of the 20-node hexahedron and their natural derivatives.

    Corner node ``a`` at ``c`` (all ``|c_k| = 1``): ``N = (1 + xi c_1)(1 + eta c_2)(1 + zeta c_3)
    (xi c_1 + eta c_2 + zeta c_3 - 2) / 8``; mid-edge node with ``c_k = 0``: the factor of that
    direction is ``1 - xi_k²``, the others ``1 + xi_j c_j``, times 1/4.

    Parameters
    ----------
    points : ndarray, shape (q, 3)
        Natural coordinates in ``[-1, 1]³``.

    Returns
    -------
    values : ndarray, shape (q, 20)
    derivatives : ndarray, shape (q, 20, 3)
        ``dN_a / dxi_k``.
    """
    x = np.asarray(points, dtype=float)[:, None, :]
    c = HEX20_NODES[None]
    along = c != 0
    factors = np.where(along, 1.0 + x * c, 1.0 - x**2)  # (q, 20, 3)
    slopes = np.where(along, c, -2.0 * x)
    corner = np.all(along, axis=-1)[0]  # (20,)
    extra = np.where(corner, np.sum(x * c, axis=-1) - 2.0, 1.0)  # (q, 20)
    scale = np.where(corner, 0.125, 0.25)
    product = np.prod(factors, axis=-1)
    others = np.stack(
        [factors[..., 1] * factors[..., 2], factors[..., 0] * factors[..., 2],
         factors[..., 0] * factors[..., 1]],
        axis=-1,
    )  # fmt: skip
    values = scale * product * extra
    derivatives = scale[:, None] * (
        others * slopes * extra[..., None] + product[..., None] * np.where(corner[:, None], c, 0.0)
    )
    return values, derivatives


_N_GAUSS, _DN_GAUSS = hex20_shape_functions(GAUSS_POINTS)


def hex20_geometry(nodes: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Jacobian determinants and shape-function gradients at the 27 Gauss points.

    Parameters
    ----------
    nodes : ndarray, shape (n_el, 20, 3)
        Node coordinates of each element (m).

    Returns
    -------
    determinants : ndarray, shape (n_el, 27)
        ``det(dx/dxi)`` (m³); positive for a valid element.
    gradients : ndarray, shape (n_el, 27, 20, 3)
        ``dN_a / dx_i`` (1/m).
    """
    jacobians = np.einsum("qak,eai->eqik", _DN_GAUSS, nodes)  # dx_i / dxi_k
    determinants = np.linalg.det(jacobians)
    gradients = np.einsum("qak,eqki->eqai", _DN_GAUSS, np.linalg.inv(jacobians))
    return determinants, gradients


def hex20_matrices(
    nodes: np.ndarray, young: float, poisson: float, density: float
) -> tuple[np.ndarray, np.ndarray]:
    """Stiffness and consistent mass matrices of isotropic linear-elastic 20-node hexahedra.

    Full 27-point integration. With ``X[a,i,b,j] = int dN_a/dx_i dN_b/dx_j dV`` the stiffness is
    ``K[a,i,b,j] = lambda X[a,i,b,j] + mu X[a,j,b,i] + mu delta_ij sum_k X[a,k,b,k]``.

    Parameters
    ----------
    nodes : ndarray, shape (n_el, 20, 3)
        Node coordinates (m).
    young, poisson, density : float
        Young's modulus (N/m²), Poisson's ratio, density (kg/m³).

    Returns
    -------
    stiffness : ndarray, shape (n_el, 60, 60)
        In the element dof order ``(node a, direction i) -> 3 a + i`` (N/m).
    mass : ndarray, shape (n_el, 20, 20)
        Scalar consistent mass ``rho int N_a N_b dV`` (kg); the same for each direction.
    """
    determinants, gradients = hex20_geometry(nodes)
    if np.any(determinants <= 0.0):
        raise UserError("solid mesh: an element has a non-positive Jacobian determinant")
    lam = young * poisson / ((1.0 + poisson) * (1.0 - 2.0 * poisson))
    mu = young / (2.0 * (1.0 + poisson))
    weights = determinants * GAUSS_WEIGHTS  # (n_el, 27)
    n_el = nodes.shape[0]
    scaled = (gradients * np.sqrt(weights)[..., None, None]).reshape(n_el, 27, 60)
    x = (scaled.transpose(0, 2, 1) @ scaled).reshape(n_el, 20, 3, 20, 3)
    trace = np.einsum("eakbk->eab", x)
    stiffness = lam * x + mu * x.transpose(0, 1, 4, 3, 2)
    stiffness += mu * trace[:, :, None, :, None] * np.eye(3)[None, None, :, None, :]
    stiffness = stiffness.reshape(n_el, 60, 60)
    mass = density * ((weights[:, :, None] * _N_GAUSS).transpose(0, 2, 1) @ _N_GAUSS)
    return (
        0.5 * (stiffness + stiffness.transpose(0, 2, 1)),
        0.5 * (mass + mass.transpose(0, 2, 1)),
    )


def assemble_hex20(
    coordinates: np.ndarray,
    elements: np.ndarray,
    young: float,
    poisson: float,
    density: float,
    chunk: int = 2048,
) -> tuple[sp.csr_matrix, sp.csr_matrix]:
    """Global stiffness and mass matrices of a 20-node hexahedron mesh (3 dofs per node).

    Elements are processed in chunks of ``chunk``, added in place into matrices on the pattern
    of the mesh (:class:`~pymorembs.elements.assembly.NodePattern`): the memory is that of the
    final matrices and one chunk.

    Parameters
    ----------
    coordinates : ndarray, shape (n_nodes, 3)
        Node positions (m).
    elements : ndarray of int, shape (n_el, 20)
        Rows of ``coordinates`` of each element's nodes (order of :data:`HEX20_NODES`).
    young, poisson, density : float
        Material (N/m², -, kg/m³).
    chunk : int
        Elements per chunk.

    Returns
    -------
    stiffness, mass : scipy.sparse.csr_matrix, shape (3 n_nodes, 3 n_nodes)
        Equation ``3 r + i`` is direction ``i`` (x, y, z) of the node in row ``r``.
    """
    pattern = NodePattern(elements, coordinates.shape[0])
    stiffness, mass = pattern.empty(blocks=True), pattern.empty(blocks=False)
    for start in range(0, elements.shape[0], chunk):
        conn = elements[start : start + chunk]
        k_e, m_e = hex20_matrices(coordinates[conn], young, poisson, density)
        pattern.add_blocks(stiffness, k_e, conn)
        pattern.add_diagonal_blocks(mass, m_e, conn)
    return stiffness, mass
