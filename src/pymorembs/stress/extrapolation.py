"""From the integration points of a solid element to its nodes.

The values at the integration points of one element are interpolated by the polynomial that
passes through them, and that polynomial is evaluated at the element's nodes:

=========  ======  ===========================================================================
kind       points  interpolant through the integration points
=========  ======  ===========================================================================
tet4       1       constant (every node gets the point's value)
tet10      4       linear in ``(r, s, t)``
hex8       8       trilinear ``{1, xi} x {1, eta} x {1, zeta}``
hex20r     8       trilinear
hex20      27      triquadratic ``{1, xi, xi²} x {1, eta, eta²} x {1, zeta, zeta²}``
=========  ======  ===========================================================================

For the linear and trilinear interpolants the value at a mid-side node is the mean of the values
at the corners of its edge. The matrices are exact inverses of the interpolation (a field the
interpolant can represent is reproduced at the nodes to rounding).
"""

from __future__ import annotations

from functools import cache

import numpy as np

from pymorembs.elements.hex20 import HEX20_NODES
from pymorembs.elements.solid import solid_kind

__all__ = ["NODE_COORDINATES", "extrapolation_matrix"]

_TET_CORNERS = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]])
_TET_EDGES = np.array([[0, 1], [1, 2], [2, 0], [0, 3], [1, 3], [2, 3]])

#: Natural coordinates of the nodes of each solid kind, shape (nodes, 3), in the kind's node order.
NODE_COORDINATES: dict[str, np.ndarray] = {
    "tet4": _TET_CORNERS,
    "tet10": np.concatenate([_TET_CORNERS, _TET_CORNERS[_TET_EDGES].mean(axis=1)]),
    "hex8": HEX20_NODES[:8],
    "hex20": HEX20_NODES,
    "hex20r": HEX20_NODES,
}


def _monomials(points: np.ndarray, degree: int, cube: bool) -> np.ndarray:
    """The interpolation basis at ``points`` (p, 3): shape (p, m).

    ``cube``: the tensor products of ``1, x, .., x**degree`` in each direction; otherwise the
    complete polynomials of degree 0 or 1.
    """
    p = np.asarray(points, dtype=float)
    if not cube:
        return np.ones((p.shape[0], 1)) if degree == 0 else np.column_stack([np.ones(len(p)), p])
    powers = np.arange(degree + 1)
    per_axis = p[:, :, None] ** powers  # (p, 3, degree + 1)
    return np.einsum("pi,pj,pk->pijk", per_axis[:, 0], per_axis[:, 1], per_axis[:, 2]).reshape(
        p.shape[0], -1
    )


@cache
def extrapolation_matrix(kind: str) -> np.ndarray:
    """Nodal values of an element from its integration-point values: ``nodes = X @ points``.

    Parameters
    ----------
    kind : str
        A solid element kind (:data:`pymorembs.elements.solid.SOLID_KINDS`).

    Returns
    -------
    ndarray, shape (nodes of the kind, integration points of the kind)
        Rows in the kind's node order, columns in its integration-point order (read-only).
    """
    spec = solid_kind(kind)
    q = spec.points.shape[0]
    cube = kind.startswith("hex")
    degree = {1: 0, 4: 1, 8: 1, 27: 2}[q]
    at_points = _monomials(spec.points, degree, cube)  # (q, q), square
    at_nodes = _monomials(NODE_COORDINATES[kind], degree, cube)
    matrix = np.linalg.solve(at_points.T, at_nodes.T).T
    matrix.setflags(write=False)
    return matrix
