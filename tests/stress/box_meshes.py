"""Structured solid meshes of a box, built in Python, and bodies made of them.

The nodes lie on a grid of half the element size: element ``(i, j, k)`` of an ``nx x ny x nz``
box has its corners at the even grid points ``2 (i, j, k) + 2 c`` and its mid-side nodes at the
odd ones between, so every kind (hex8, hex20, hex20r, tet4, tet10) shares one construction.
Tetrahedra: each hexahedron cut into six along its diagonal from corner 1 to corner 7.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from pymorembs.body import DofTable, ElasticBody, ElementMesh
from pymorembs.elements.hex20 import HEX20_NODES
from pymorembs.elements.solid import assemble_solid_stiffness, solid_volumes

# the six tetrahedra of a hexahedron (its corner numbers, 0-based) around the diagonal 0-6
_KUHN = np.array(
    [[0, 1, 2, 6], [0, 2, 3, 6], [0, 3, 7, 6], [0, 7, 4, 6], [0, 4, 5, 6], [0, 5, 1, 6]]
)
_TET_EDGES = np.array([[0, 1], [1, 2], [2, 0], [0, 3], [1, 3], [2, 3]])


def box_mesh(
    kind: str, counts: tuple[int, int, int], size: tuple[float, float, float], origin=(0, 0, 0)
) -> tuple[np.ndarray, np.ndarray]:
    """Coordinates (n_nodes, 3) and connectivity (rows, 0-based) of a box of ``kind``."""
    counts = np.asarray(counts)
    cells = np.stack(np.meshgrid(*[np.arange(n) for n in counts], indexing="ij"), -1).reshape(-1, 3)
    corners = 2 * cells[:, None, :] + 1 + HEX20_NODES[None, :8].astype(int)  # doubled grid
    if kind in ("hex8", "hex20", "hex20r"):
        local = HEX20_NODES[: 8 if kind == "hex8" else 20].astype(int)
        grid = 2 * cells[:, None, :] + 1 + local[None]
    else:
        tets = corners[:, _KUHN].reshape(-1, 4, 3)
        if kind == "tet10":
            mids = tets[:, _TET_EDGES].sum(axis=2) // 2
            tets = np.concatenate([tets, mids], axis=1)
        grid = tets
    shape = 2 * counts + 1
    flat = np.ravel_multi_index(tuple(np.moveaxis(grid, -1, 0)), shape)
    used, connectivity = np.unique(flat, return_inverse=True)
    connectivity = connectivity.reshape(flat.shape)
    points = np.stack(np.unravel_index(used, shape), -1) * (np.asarray(size) / (2 * counts))
    points = points + np.asarray(origin, dtype=float)
    if kind.startswith("tet"):  # make every tetrahedron right-handed
        a, b, c, d = (points[connectivity[:, k]] for k in range(4))
        flip = np.einsum("ij,ij->i", np.cross(b - a, c - a), d - a) < 0
        swap = [0, 2, 1, 3] + ([6, 5, 4, 7, 9, 8] if kind == "tet10" else [])
        keep = list(range(connectivity.shape[1]))
        connectivity[flip] = connectivity[flip][:, swap if kind == "tet10" else swap + keep[4:]]
    assert np.all(solid_volumes(kind, points[connectivity]) > 0)
    return points, connectivity


def solid_body(
    kind: str, points: np.ndarray, connectivity: np.ndarray, young: float, poisson: float
) -> ElasticBody:
    """A free body of the elements: ``K`` assembled from them, unit lumped mass, node ids
    ``1 .. n`` and element ids ``101, 102, ...``."""
    n = points.shape[0]
    ids = np.arange(1, n + 1)
    stiffness = assemble_solid_stiffness(kind, points, connectivity, young, poisson)
    mesh = ElementMesh(
        kind, ids[connectivity], young, poisson,
        element_ids=100 + np.arange(1, connectivity.shape[0] + 1),
    )  # fmt: skip
    return ElasticBody(
        node_ids=ids,
        coordinates=points,
        dofs=DofTable(np.repeat(ids, 3), np.tile(np.arange(3), n)),
        mass=sp.identity(3 * n, format="csr"),
        stiffness=stiffness,
        mesh=mesh,
    )
