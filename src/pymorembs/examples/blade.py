"""A rotating blade: a slender steel cantilever of 20-node hexahedra on a hub (SI units).

The test body for rotating and preloaded bodies (geometric stiffening, issue #15): a straight
blade of rectangular cross-section clamped at its root to a rigid hub that turns about the z
axis. The body frame is the hub's: origin on the axis of rotation, x along the blade, y along
the chord (in the plane of rotation), z along the thickness (out of the plane of rotation).

* Blade: ``hub_radius <= x <= hub_radius + length``, ``-chord/2 <= y <= chord/2``,
  ``-thickness/2 <= z <= thickness/2``; default 1 m × 40 mm × 10 mm, ``hub_radius`` 0.
* Steel as in the rack (E = 2.1e11 N/m², nu = 0.3, rho = 7850 kg/m³), 20-node serendipity
  hexahedra with full integration and consistent mass (:func:`~pymorembs.examples.rack_solid.
  assemble_hex20`), ``elements`` along the length, 2 across the chord, 2 through the thickness.
* Root: every node of the face ``x = hub_radius`` is fixed (the clamping to the hub). Use the
  frame ``type = "none"``: the coordinates are then measured from the axis of rotation.
* Node ids: node 1 is the centre of the tip face ``(hub_radius + length, 0, 0)``, node 2 the
  centre of the root face; the other nodes are 1001, 1002, ... (sorted by z, y, x).

Euler-Bernoulli values of the default blade (clamped-free, no rotation): first flapwise (out of
plane, bending about y) ``1.8751² / (2 pi L²) sqrt(E I_y / (rho A)) = 8.355 Hz``, first
edgewise (in plane, about z) four times that, 33.42 Hz. The solid model (40 elements) gives
8.387 Hz and 33.45 Hz: 0.4 % and 0.1 % above (the Poisson effect stiffens the flat section in
flapwise bending); the tests check within 1 %.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pymorembs.body import Damping, DofTable, ElasticBody, ElementMesh
from pymorembs.elements.hex20 import assemble_hex20
from pymorembs.errors import UserError
from pymorembs.examples.rack_beams import STEEL_E, STEEL_NU, STEEL_RHO
from pymorembs.examples.rack_solid import merge_blocks, structured_block
from pymorembs.surface import outer_surface

__all__ = ["BladeMesh", "blade", "blade_mesh"]

#: Node ids of the tip and root centres; mesh nodes from :data:`FIRST_MESH_ID` on.
TIP_NODE, ROOT_NODE, FIRST_MESH_ID = 1, 2, 1001


@dataclass(frozen=True, eq=False)
class BladeMesh:
    """The blade's nodes and elements.

    Attributes
    ----------
    node_ids : ndarray of int, shape (n_nodes,)
        Ascending (1, 2, then 1001, ...).
    coordinates : ndarray, shape (n_nodes, 3)
        In the order of ``node_ids`` (m).
    elements : ndarray of int, shape (n_el, 20)
        Rows of ``coordinates`` of each 20-node hexahedron (order of
        :data:`~pymorembs.examples.rack_solid.HEX20_NODES`).
    root : ndarray of int
        Rows of the nodes of the root face.
    """

    node_ids: np.ndarray
    coordinates: np.ndarray
    elements: np.ndarray
    root: np.ndarray


def blade_mesh(
    hub_radius: float = 0.0,
    length: float = 1.0,
    chord: float = 0.04,
    thickness: float = 0.01,
    elements: int = 40,
) -> BladeMesh:
    """The mesh of :func:`blade` (same parameters)."""
    for label, value in (("length", length), ("chord", chord), ("thickness", thickness)):
        if not (np.isfinite(value) and value > 0):
            raise UserError(f"blade: {label} must be a length > 0 (m), got {value!r}")
    if not (np.isfinite(hub_radius) and hub_radius >= 0):
        raise UserError(f"blade: hub_radius must be >= 0 (m), got {hub_radius!r}")
    if isinstance(elements, bool) or not isinstance(elements, int | np.integer) or elements < 4:
        raise UserError(f"blade: elements must be a whole number >= 4, got {elements!r}")

    def box(s: np.ndarray, t: np.ndarray, u: np.ndarray) -> np.ndarray:
        return np.stack(
            [hub_radius + length * s, chord * (t - 0.5), thickness * (u - 0.5)], axis=-1
        )

    coordinates, connectivity = merge_blocks([structured_block(box, (int(elements), 2, 2))])
    ids = FIRST_MESH_ID + np.arange(coordinates.shape[0])
    scale = max(length, chord, thickness)
    for node, x in ((TIP_NODE, hub_radius + length), (ROOT_NODE, hub_radius)):
        centre = np.flatnonzero(np.linalg.norm(coordinates - [x, 0.0, 0.0], axis=1) < 1e-9 * scale)
        ids[centre[0]] = node
    order = np.argsort(ids)
    rows = np.empty_like(order)
    rows[order] = np.arange(order.size)  # mesh row -> sorted row
    root = np.flatnonzero(np.abs(coordinates[order, 0] - hub_radius) < 1e-9 * scale)
    return BladeMesh(ids[order], coordinates[order], rows[connectivity], root)


def blade(
    hub_radius: float = 0.0,
    length: float = 1.0,
    chord: float = 0.04,
    thickness: float = 0.01,
    elements: int = 40,
) -> ElasticBody:
    """The blade (module docstring), clamped at its root.

    Parameters
    ----------
    hub_radius : float
        Distance of the root from the axis of rotation (m), >= 0.
    length, chord, thickness : float
        Blade dimensions (m), each > 0.
    elements : int
        Elements along the length (>= 4); 2 across the chord and 2 through the thickness.

    Returns
    -------
    ElasticBody
        Named ``"blade"``, undamped, root nodes fixed; equation ``3 r + i`` is direction ``i``
        of the node in row ``r`` of :func:`blade_mesh`.
    """
    mesh = blade_mesh(hub_radius, length, chord, thickness, elements)
    stiffness, mass = assemble_hex20(mesh.coordinates, mesh.elements, STEEL_E, STEEL_NU, STEEL_RHO)
    connectivity = mesh.node_ids[mesh.elements]
    n_nodes = mesh.node_ids.size
    return ElasticBody(
        node_ids=mesh.node_ids,
        coordinates=mesh.coordinates,
        dofs=DofTable(np.repeat(mesh.node_ids, 3), np.tile(np.arange(3), n_nodes)),
        mass=mass,
        stiffness=stiffness,
        fixed=(3 * mesh.root[:, None] + np.arange(3)).ravel(),
        damping=Damping(),
        name="blade",
        mesh=ElementMesh("hex20", connectivity, STEEL_E, STEEL_NU),
        surface=outer_surface([("hex20", connectivity)], mesh.node_ids, mesh.coordinates),
    )
