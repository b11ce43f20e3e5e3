"""A tet10 steel box with a consistent mass, prepared like the rack (for ``floor_ratio.py``).

The mesh is the structured box of ``bench/stress_modes.py`` (``tests/stress/box_meshes.py``:
4 x 2 x 1.2 m, cells cut into six quadratic tetrahedra), its stiffness assembled from the
elements (steel, E = 210 GPa, nu = 0.3). The mass is the consistent one,
``rho int N_a N_b dV`` (rho = 7850 kg/m^3), which has the stiffness's sparsity pattern, as a
CalculiX or Abaqus export of a tet10 part has. The elements of the box are affine (straight
edges, mid-side nodes at the midpoints), so every element's scalar mass is its volume times
one reference matrix, integrated exactly here by a collapsed Gauss rule (4^3 points, exact
for the degree-4 products ``N_a N_b`` times the degree-3 Jacobian of the collapse).

Interfaces as on a real part: the nodes of the face x = 0 are tied rigidly to an interface
node at the face's centre (tangent frame there), those of the face x = 4 m to another one
whose three forces are the inputs and three displacements the outputs (``ux uy uz``).
"""

from __future__ import annotations

import time
from dataclasses import replace

import numpy as np
import scipy.sparse as sp
from _common import prepare_damped
from stress_modes import SIZE, counts_for  # also puts tests/stress on the path

YOUNG, POISSON, DENSITY = 2.1e11, 0.3, 7850.0


def reference_mass() -> np.ndarray:
    """``int N_a N_b dV`` over the reference tetrahedron (volume 1/6), shape (10, 10).

    The shape functions are pymorembs' own (:func:`pymorembs.elements.solid.tet10_shape_functions`);
    the integral is a collapsed (Duffy) Gauss-Legendre rule of 4 points per direction on the
    unit cube: ``r = u, s = v (1 - u), t = w (1 - u)(1 - v)``, Jacobian ``(1 - u)^2 (1 - v)``.
    """
    from pymorembs.elements.solid import tet10_shape_functions

    x, w = np.polynomial.legendre.leggauss(4)
    x, w = 0.5 * (x + 1.0), 0.5 * w
    u, v, t = (a.ravel() for a in np.meshgrid(x, x, x, indexing="ij"))
    weights = np.einsum("i,j,k->ijk", w, w, w).ravel() * (1.0 - u) ** 2 * (1.0 - v)
    points = np.column_stack([u, v * (1.0 - u), t * (1.0 - u) * (1.0 - v)])
    values, _ = tet10_shape_functions(points)
    return np.einsum("q,qa,qb->ab", weights, values, values)


def consistent_mass(points: np.ndarray, connectivity: np.ndarray) -> sp.csr_matrix:
    """The consistent mass of affine tet10 elements, dof ``3 node + direction``, kg."""
    from pymorembs.elements.solid import solid_volumes

    corners = points[connectivity[:, :4]]
    volumes = solid_volumes("tet4", corners)  # the affine element's volume
    scalar = reference_mass() * 6.0  # per unit volume
    n_el, n_nodes = connectivity.shape[0], points.shape[0]
    rows = np.repeat(connectivity, 10, axis=1).ravel()
    cols = np.tile(connectivity, (1, 10)).ravel()
    values = (DENSITY * volumes[:, None] * scalar.ravel()[None]).ravel()
    nodal = sp.csr_matrix((values, (rows, cols)), shape=(n_nodes, n_nodes))
    del rows, cols, values
    assert n_el > 0
    return sp.kron(nodal, sp.identity(3), format="csr")


def tet10_box_body(dofs: int):
    """The free steel box of about ``dofs`` dofs with its consistent mass (an ElasticBody)."""
    from box_meshes import box_mesh, solid_body

    points, connectivity = box_mesh("tet10", counts_for(dofs), SIZE)
    body = solid_body("tet10", points, connectivity, YOUNG, POISSON)
    return replace(body, mass=consistent_mass(points, connectivity))


def tet10_box_prepared(dofs: int, damping: str = "modal"):
    """The prepared box (frame and ports as in the module docstring) and its build time, s."""
    from pymorembs.preparation.interface import InterfaceSpec, add_interface_node, select_nodes

    tick = time.perf_counter()
    body = tet10_box_body(dofs)
    frame_node, port_node = body.n_nodes + 1, body.n_nodes + 2
    for node, x in ((frame_node, 0.0), (port_node, SIZE[0])):
        face = select_nodes(body, box=((x - 1e-9, -1.0, -1.0), (x + 1e-9, 3.0, 3.0)))
        centre = (x, SIZE[1] / 2, SIZE[2] / 2)
        body = add_interface_node(body, InterfaceSpec(node, centre, tuple(int(i) for i in face)))
    build_s = time.perf_counter() - tick
    return prepare_damped(body, frame_node, port_node, damping), build_s
