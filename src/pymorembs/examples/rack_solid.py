"""The rack of paper section 2 as a solid model: 20-node hexahedra, three dofs per node.

The same rack as :mod:`pymorembs.examples.rack_beams` (same dimensions, positions and steel,
``z`` vertical, lower plate at the bottom), meshed as the paper's FE model: quadratic solid
elements with three translational dofs per node, about 35,000 dofs by default (paper section 2).
Coordinates in m (SI units throughout):

* lower plate 64 × 50 × 8 mm, ``-4 <= z <= 4`` mm, centred on the z axis;
* rods 1..4, Ø 4 mm, ``4 <= z <= 204`` mm, axes at ``(+25, +20)``, ``(-25, +20)``, ``(-25, -20)``,
  ``(+25, -20)`` mm (rack-beams' order);
* upper plate 100 × 90 × 17 mm, ``204 <= z <= 221`` mm, central hole Ø 30 mm.

Elements. 20-node serendipity hexahedra (node order of Abaqus C3D20 / Ansys SOLID186, see
:data:`HEX20_NODES`), isoparametric, isotropic linear elasticity (E = 2.1e11 N/m², nu = 0.3,
rho = 7850 kg/m³), full 3 × 3 × 3 Gauss integration, consistent mass. The element matrices are
computed here, vectorised over elements (batched ``X = B^T B`` products, :func:`hex20_matrices`),
and assembled in chunks (:func:`assemble_hex20`); the tests check them against scikit-fem's
``ElementHexS2``.

Mesh (:func:`mesh_rack`), structured blocks without an external mesher. Each block is a map of
the unit cube, built by linear transfinite blending between two curves and swept along z; the
mid-edge nodes are placed by the map, so they lie on the circles (quadratic arcs in between).

* Lower plate: one block, ``nx × ny × nz`` elements (``nx``, ``ny`` even, so a vertex lies in
  the centre of the bottom face: node 1).
* Rods: O-grid cylinders: a centre square (half-side 0.45 r, ``n_s × n_s`` elements) and four
  ring blocks (``n_s × n_r``) between its sides and the circle, swept in ``n_z`` layers. At least
  ``n_s = 2``: the circle is drawn by eight quadratic arcs (area error 0.08 %; four arcs would
  lose 1.2 %).
* Upper plate: O-grid around the hole: four blocks between the hole and the four sides, with
  straight block edges from the circle to the plate corners, element layers graded
  geometrically from the hole (last/first = 3), ``n_t`` layers through the thickness.

Nodes are merged within each part (coordinates rounded to 1 nm, ``np.unique``); the parts share
no nodes. The rods are tied to the plates instead (bonded contact, like Abaqus ``*TIE`` or an
Ansys bonded-contact MPC): every node of a rod's end face is a dependent node whose translations
follow the shape functions of the plate face it lies on, ``u_d = sum_a N_a(xi, eta) u_a``
(eq. 9, ``q_d = G q``, offset 0); ``(xi, eta)`` come from a vectorised Newton solve on the
8-node face map (:func:`tie_rods`). The face functions reproduce linear fields, so rigid-body
motion passes the ties exactly.

Node ids: node 1 is the centre of the lower plate's bottom face, ``(0, 0, -0.004)``; the other
mesh nodes are numbered 1001, 1002, ... in the order lower plate, rods 1..4, upper plate, and
within a part by z, then y, then x (ascending). Node 2 is no mesh node: the interface node in
the centre of the hole, ``(0, 0, 0.2125)`` (mid-plane of the upper plate, as in rack-beams),
coupled to all nodes on the hole's surface by
:func:`pymorembs.preparation.interface.add_interface_node`
(paper section 2.2, :data:`INTERFACES`):

=================  ==========================================================================
``interface``      coupling of node 2 to the hole's nodes
=================  ==========================================================================
``rigid``          RBE2-like: the hole nodes follow node 2 rigidly
``distributing``   RBE3-like: node 2 follows the hole nodes' mean motion
``steel-beams``    a spider of steel beams, Ø 1 mm (the paper's steel beams: frequency 4326 Hz
                   scales with d, 433 Hz at 0.1 mm); adds 0.052 kg at 35,000 dofs (528 beams)
                   and makes node 2 a soft support: clamped there, the rack rocks on the spider
                   at 27.3, 27.5 and 91 Hz
``light-beams``    the paper's light stiff beams, E = 1e18 N/m², rho = 100 kg/m³, Ø 1 mm
                   (the default; adds 0.6 g at 35,000 dofs)
``springs``        spring-dampers along x, y, z to each hole node: 1e9 N/m and 1e4 N s/m in
                   total (each divided by the number of hole nodes)
``none``           the bare mesh, no node 2
=================  ==========================================================================

Sizes (:func:`plan_mesh` picks the nominal element size whose mesh comes closest to ``dofs``;
rods at half that size across and twice along the axis). Mesh dofs (``3 × nodes``); the beam
interfaces add ``6 + 3 ×`` hole nodes (1,590 at 35,000), the others 6 or 3:

=========  ============  ===============  ===============  ========  ========  ========
target     lower plate   rod (n_s, n_r,   upper (around     elements  nodes     dofs
           nx × ny × nz  n_z), each       x/y sides, n_r,
                                          n_t)
=========  ============  ===============  ===============  ========  ========  ========
10,000     6 × 4 × 1     2, 1, 9          5/5, 3, 2           576     3,453    10,359
35,000     14 × 10 × 2   2, 1, 20         11/13, 6, 3       2,104    11,725    35,175
100,000    20 × 16 × 3   2, 1, 32         18/20, 10, 5      6,296    32,091    96,273
300,000    32 × 26 × 4   2, 1, 50         28/31, 15, 9     21,658   101,661   304,983
=========  ============  ===============  ===============  ========  ========  ========

Masses at 35,000 dofs (rack-beams in brackets, i.e. volume × density): upper plate with hole
1.10672 kg (1.10672), four rods 0.07885 kg (0.07892; -0.08 % from the arcs), lower plate
0.20096 kg (0.20096), total 1.38653 kg (1.38660).

Eigenfrequencies (Hz) at 35,000 dofs with the six dofs of node 2 clamped, ties eliminated:

====  ===========  ===========  ==========  ==============================================
mode  rigid        light-beams  rack-beams  shape
====  ===========  ===========  ==========  ==============================================
1     41.54        41.54        41.57       sway of the lower plate along x
2     41.56        41.56        41.62       sway along y
3     100.78       100.78       100.93      torsion of the lower plate about z
4-8   457.96 ...   457.96 ...   460.43      local bending of the rods, lower plate at rest
      459.97       459.97
9     471.98       471.98       471.96      local rod bending with lower plate sway
10    472.01       472.01       472.95
11    485.06       485.06       486.15      local rod bending with lower plate torsion
12    1261.27      1261.27      1269.20     second local bending of the rods
====  ===========  ===========  ==========  ==============================================

Rigid and light-beam coupling differ by less than 1e-5 relatively. The free body has six
rigid-body modes and its first elastic mode at 105.2 Hz (rack-beams: 105 Hz). With all nodes of
the upper plate held instead of node 2: 41.68, 41.69, 100.94 Hz; on the coarse 8,000-dof mesh of
the tests 42.35, 42.40, 101.42 Hz.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from pymorembs.body import ConstraintEquations, Damping, DofTable, ElasticBody, ElementMesh
from pymorembs.elements.hex20 import (
    FACE_NODES,
    HEX20_NODES,
    MIRROR_XI,
    assemble_hex20,
    hex20_geometry,
    hex20_shape_functions,
)
from pymorembs.errors import UserError
from pymorembs.examples.rack_beams import STEEL_E, STEEL_NU, STEEL_RHO, RackDesign
from pymorembs.surface import outer_surface

# -------------------------------------------------------------------------- structured blocks
#: Half-side of the centre square of a rod's O-grid, as a fraction of the rod radius.
ROD_SQUARE = 0.45
#: A block mapping: parameters (s, t, u) in [0, 1]³, arrays of equal shape -> points (..., 3).
Mapping = Callable[[np.ndarray, np.ndarray, np.ndarray], np.ndarray]
#: A mapping of the plane: (s, t) -> (x, y), each an array of the shape of s.
Section = Callable[[np.ndarray, np.ndarray], tuple[np.ndarray, np.ndarray]]


def _lattice(n: int, grading: Callable[[np.ndarray], np.ndarray] | None = None) -> np.ndarray:
    """Parameters of the vertices and mid-edge points of n elements along a direction.

    Vertices at ``grading(i / n)``, mid-edge points halfway between (in parameter space), so each
    element is an affine image of the reference element in parameter space.
    """
    vertices = np.linspace(0.0, 1.0, n + 1)
    if grading is not None:
        vertices = grading(vertices)
    params = np.empty(2 * n + 1)
    params[0::2] = vertices
    params[1::2] = 0.5 * (vertices[:-1] + vertices[1:])
    return params


def structured_block(
    mapping: Mapping,
    counts: tuple[int, int, int],
    radial_grading: Callable[[np.ndarray], np.ndarray] | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Points and 20-node elements of one structured block.

    Parameters
    ----------
    mapping : Mapping
        The block's geometry; mid-edge nodes are placed by it, so curved block edges stay exact
        at the nodes (isoparametric quadratic approximation in between).
    counts : tuple of int
        Elements along s, t and u.
    radial_grading : callable, optional
        Vertex distribution along t, a monotonic map of [0, 1] onto itself.

    Returns
    -------
    points : ndarray, shape (n_points, 3)
        All lattice points (some used by no element; :func:`merge_blocks` drops those).
    elements : ndarray of int, shape (n_el, 20)
        Rows of ``points``, ordered so that every element is right-handed.
    """
    params = [_lattice(counts[0]), _lattice(counts[1], radial_grading), _lattice(counts[2])]
    grid = np.meshgrid(*params, indexing="ij")
    points = mapping(*grid).reshape(-1, 3)
    shape = tuple(p.size for p in params)
    first = np.meshgrid(*[2 * np.arange(n) for n in counts], indexing="ij")
    offsets = (HEX20_NODES + 1).astype(np.int64)
    elements = np.ravel_multi_index(
        tuple(f.reshape(-1, 1) + offsets[:, k] for k, f in enumerate(first)), shape
    )
    centre, _ = hex20_geometry(points[elements[:1]])
    if centre[0, 13] < 0:  # the mapping is left-handed
        elements = elements[:, MIRROR_XI]
    return points, elements


def merge_blocks(
    blocks: list[tuple[np.ndarray, np.ndarray]], tolerance: float = 1e-9
) -> tuple[np.ndarray, np.ndarray]:
    """One mesh from blocks: coincident nodes merged, unused lattice points dropped.

    Points are identified by their coordinates rounded to ``tolerance`` (m). The merged nodes are
    sorted by z, then y, then x.

    Returns
    -------
    coordinates : ndarray, shape (n_nodes, 3)
    elements : ndarray of int, shape (n_el, 20)
    """
    offsets = np.cumsum([0] + [points.shape[0] for points, _ in blocks[:-1]])
    points = np.concatenate([p for p, _ in blocks])
    elements = np.concatenate([e + o for (_, e), o in zip(blocks, offsets, strict=True)])
    used = np.unique(elements)
    keys = np.rint(points[used] / tolerance).astype(np.int64)[:, ::-1]  # sort by z, y, x
    _, first, inverse = np.unique(keys, axis=0, return_index=True, return_inverse=True)
    renumber = np.empty(points.shape[0], dtype=np.int64)
    renumber[used] = inverse.ravel()
    return points[used[first]], renumber[elements]


def _extruded(section: Section, z_bottom: float, height: float) -> Mapping:
    """A prism block: the plane mapping ``section`` swept from ``z_bottom`` up by ``height``."""

    def mapping(s: np.ndarray, t: np.ndarray, u: np.ndarray) -> np.ndarray:
        x, y = section(s, t)
        return np.stack([x, y, z_bottom + height * u], axis=-1)

    return mapping


def _blend(
    inner: tuple[np.ndarray, np.ndarray], outer: tuple[np.ndarray, np.ndarray], t: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Linear (transfinite) blend between two plane curves: ``(1 - t) inner + t outer``."""
    return tuple((1.0 - t) * a + t * b for a, b in zip(inner, outer, strict=True))


def _disc_sections(radius: float, centre: np.ndarray) -> list[Section]:
    """O-grid of a disc: a centre square and four blended ring blocks (:data:`ROD_SQUARE`)."""
    half = ROD_SQUARE * radius
    cx, cy = centre

    def square(s: np.ndarray, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        return cx + half * (2.0 * s - 1.0), cy + half * (2.0 * t - 1.0)

    def ring(k: int) -> Section:
        cos_k, sin_k = [(1, 0), (0, 1), (-1, 0), (0, -1)][k]  # exact quarter turns

        def section(s: np.ndarray, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
            a, b = half, half * (2.0 * s - 1.0)  # side x = half of the square, turned by k/4
            inner = (cos_k * a - sin_k * b, sin_k * a + cos_k * b)
            theta = 0.5 * np.pi * (k + s - 0.5)
            outer = (radius * np.cos(theta), radius * np.sin(theta))
            x, y = _blend(inner, outer, t)
            return cx + x, cy + y

        return section

    return [square] + [ring(k) for k in range(4)]


def _holed_rectangle_sections(half_x: float, half_y: float, hole_radius: float) -> list[Section]:
    """O-grid of a rectangle with a central hole: four blocks from the circle to the sides.

    Block k spans the rectangle side between corners k and k + 1 (counter-clockwise from
    ``(+half_x, -half_y)``) and the arc between the same polar angles; the radial block edges
    are straight lines from the circle to the corners.
    """
    corners = np.array([[1, -1], [1, 1], [-1, 1], [-1, -1]]) * [half_x, half_y]
    angles = np.unwrap(np.arctan2(corners[:, 1], corners[:, 0]))
    angles = np.append(angles, angles[0] + 2.0 * np.pi)

    def block(k: int) -> Section:
        start, end = corners[k], corners[(k + 1) % 4]

        def section(s: np.ndarray, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
            theta = angles[k] + s * (angles[k + 1] - angles[k])
            inner = (hole_radius * np.cos(theta), hole_radius * np.sin(theta))
            outer = (start[0] + s * (end[0] - start[0]), start[1] + s * (end[1] - start[1]))
            return _blend(inner, outer, t)

        return section

    return [block(k) for k in range(4)]


def _rectangle_section(half_x: float, half_y: float) -> Section:
    def section(s: np.ndarray, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        return half_x * (2.0 * s - 1.0), half_y * (2.0 * t - 1.0)

    return section


# ---------------------------------------------------------------------------------- the rack
#: Names of the mesh parts, in the order of their node numbers.
PARTS = ("lower plate", "rod 1", "rod 2", "rod 3", "rod 4", "upper plate")
#: Size ratio of the last to the first element layer around the hole (geometric grading).
HOLE_GRADING = 3.0


def _hole_grading(t: np.ndarray) -> np.ndarray:
    return (HOLE_GRADING**t - 1.0) / (HOLE_GRADING - 1.0)


@dataclass(frozen=True)
class MeshPlan:
    """Element counts of the solid rack.

    Parameters
    ----------
    lower : tuple of int
        Lower plate: elements along x, y (both even, so a vertex lies in the centre) and z.
    rod : tuple of int
        Each rod: elements along a side of the centre square, radially in the ring, along z.
    upper : tuple of int
        Upper plate: elements around the hole in the blocks at the sides x = +-a and y = +-b,
        radially from the hole to the sides, through the thickness.
    """

    lower: tuple[int, int, int]
    rod: tuple[int, int, int]
    upper: tuple[int, int, int, int]

    @property
    def n_elements(self) -> tuple[int, int, int]:
        """Elements of the lower plate, of one rod and of the upper plate."""
        nx, ny, nz = self.lower
        square, ring, along = self.rod
        around_x, around_y, radial, thick = self.upper
        return (
            nx * ny * nz,
            (square**2 + 4 * square * ring) * along,
            2 * (around_x + around_y) * radial * thick,
        )

    @property
    def n_nodes(self) -> int:
        """Number of nodes (all parts; rods and plates do not share nodes)."""
        nx, ny, nz = self.lower
        vertices = (nx + 1) * (ny + 1) * (nz + 1)
        edges = nx * (ny + 1) * (nz + 1) + (nx + 1) * ny * (nz + 1) + (nx + 1) * (ny + 1) * nz
        square, ring, along = self.rod
        rod_v = (square + 1) ** 2 + 4 * square * ring
        rod_f = square**2 + 4 * square * ring
        around_x, around_y, radial, thick = self.upper
        around = 2 * (around_x + around_y)
        upper_v, upper_f = around * (radial + 1), around * radial
        return (
            vertices + edges
            + 4 * _extruded_count(rod_v, rod_v + rod_f - 1, along)
            + _extruded_count(upper_v, upper_v + upper_f, thick)
        )  # fmt: skip


def _extruded_count(vertices: int, edges: int, layers: int) -> int:
    """Nodes of a 20-node mesh swept from a plane quad mesh (vertices, edges) in ``layers``."""
    return (layers + 1) * (vertices + edges) + layers * vertices


def plan_for_size(size: float, design: RackDesign | None = None) -> MeshPlan:
    """Element counts for a nominal element edge length ``size`` (m).

    Plates: about ``size`` along each edge (at least two elements around each hole block,
    radially and through the upper plate; the lower plate's counts in x and y even). Rods: the
    cross-section at half that size (at least two elements along the side of the centre square,
    so the circle is drawn by eight quadratic arcs), along the axis twice that size (at least
    8 elements).
    """
    d = design or RackDesign()
    lower, upper, r = d.lower_plate, d.upper_plate, d.rod_diameter / 2.0

    def count(length: float, minimum: int = 1) -> int:
        return max(minimum, round(length / size))

    hole = upper.hole_diameter / 2.0
    # around: mean of the arc at the hole and the plate side; radially: mid-side distance
    arc_x = 2.0 * hole * np.arctan2(upper.width, upper.length)
    arc_y = np.pi * hole - arc_x
    radial = 0.5 * min(upper.length, upper.width) - hole
    return MeshPlan(
        lower=(2 * count(lower.length / 2.0), 2 * count(lower.width / 2.0),
               count(lower.thickness)),
        rod=(count(4.0 * ROD_SQUARE * r, 2), count(2.0 * (1.0 - ROD_SQUARE) * r),
             count(d.rod_length / 2.0, 8)),
        upper=(count(0.5 * (arc_x + upper.width), 2), count(0.5 * (arc_y + upper.length), 2),
               count(radial, 2), count(upper.thickness, 2)),
    )  # fmt: skip


def plan_mesh(dofs: int, design: RackDesign | None = None) -> MeshPlan:
    """The element counts whose number of dofs (3 per node) lies closest to ``dofs``.

    Raises
    ------
    UserError
        If no plan comes within 15 % of ``dofs`` (below about 6,500 dofs).
    """
    sizes = np.geomspace(0.03, 2e-4, 600)
    plans = [plan_for_size(h, design) for h in sizes]
    counts = np.array([3 * p.n_nodes for p in plans])
    best = int(np.argmin(np.abs(counts - dofs)))
    if abs(counts[best] - dofs) > 0.15 * dofs:
        raise UserError(
            f"rack-solid: no mesh has about {dofs} dofs (the coarsest has {counts.min()}, "
            "the target must lie within 15 %)"
        )
    return plans[best]


@dataclass(frozen=True, eq=False)
class SolidMesh:
    """The 20-node hexahedron mesh of the rack.

    Parameters
    ----------
    coordinates : ndarray, shape (n_nodes, 3)
        Node positions (m).
    node_ids : ndarray of int, shape (n_nodes,)
        Node ids: 1 for the centre of the lower plate's bottom face, 1001, 1002, ... for the
        others in row order.
    elements : ndarray of int, shape (n_el, 20)
        Rows of ``coordinates`` of each element's nodes (order of :data:`HEX20_NODES`).
    node_parts, element_parts : ndarray of int, shapes (n_nodes,), (n_el,)
        Index into :data:`PARTS` of each node and element.
    """

    coordinates: np.ndarray
    node_ids: np.ndarray
    elements: np.ndarray
    node_parts: np.ndarray
    element_parts: np.ndarray


def mesh_rack(plan: MeshPlan, design: RackDesign | None = None) -> SolidMesh:
    """Mesh the rack with 20-node hexahedra.

    Parts, in the order of :data:`PARTS` (each meshed on its own, nodes merged within a part
    only; the rods are tied to the plates by :func:`tie_rods`): the lower plate as one block,
    rods 1..4 as O-grid cylinders (centre square and four ring blocks, swept along z), the upper
    plate as an O-grid of four blocks around the hole, swept through the thickness.

    Returns
    -------
    SolidMesh
        Rows sorted by part, then z, y, x; node 1 is the centre of the lower plate's bottom face.
    """
    d = design or RackDesign()
    lower, upper = d.lower_plate, d.upper_plate
    z_rods = lower.thickness / 2.0  # bottom of the rods; node 1 of rack-beams is at z = 0
    z_upper = z_rods + d.rod_length
    nx, ny, nz = plan.lower
    square, ring, along = plan.rod
    around_x, around_y, radial, thick = plan.upper
    parts = [
        [structured_block(_extruded(_rectangle_section(lower.length / 2, lower.width / 2), -z_rods,
                          lower.thickness), (nx, ny, nz))],
        *[
            [structured_block(_extruded(sec, z_rods, d.rod_length), (square, n_t, along))
             for sec, n_t in zip(_disc_sections(d.rod_diameter / 2, xy), (square, *4 * [ring]),
                                 strict=True)]
            for xy in d.rod_positions
        ],
        [structured_block(_extruded(sec, z_upper, upper.thickness), (n_s, radial, thick),
                          _hole_grading)
         for sec, n_s in zip(
             _holed_rectangle_sections(upper.length / 2, upper.width / 2,
                                       upper.hole_diameter / 2),
             (around_x, around_y, around_x, around_y), strict=True)],
    ]  # fmt: skip
    merged = [merge_blocks(blocks) for blocks in parts]
    sizes = [c.shape[0] for c, _ in merged]
    offsets = np.cumsum([0, *sizes[:-1]])
    coordinates = np.concatenate([c for c, _ in merged])
    elements = np.concatenate([e + o for (_, e), o in zip(merged, offsets, strict=True)])
    node_parts = np.repeat(np.arange(len(PARTS)), sizes)
    element_parts = np.repeat(np.arange(len(PARTS)), [e.shape[0] for _, e in merged])
    if coordinates.shape[0] != plan.n_nodes:  # a merging failure would leave open seams
        raise UserError(f"solid mesh: {coordinates.shape[0]} nodes, expected {plan.n_nodes}")
    node1 = np.array([0.0, 0.0, -z_rods])
    centre = np.flatnonzero(np.all(np.abs(coordinates - node1) < 1e-12, axis=1))
    if centre.size != 1 or node_parts[centre[0]] != 0:
        raise UserError("solid mesh: no node in the centre of the lower plate's bottom face")
    coordinates[centre[0]] = node1  # exactly, not to round-off
    node_ids = np.empty(coordinates.shape[0], dtype=np.int64)
    others = np.arange(coordinates.shape[0]) != centre[0]
    node_ids[centre[0]] = 1
    node_ids[others] = 1001 + np.arange(coordinates.shape[0] - 1)
    return SolidMesh(coordinates, node_ids, elements, node_parts, element_parts)


def face_coordinates(
    points: np.ndarray, nodes: np.ndarray, side: int, iterations: int = 30
) -> tuple[np.ndarray, np.ndarray]:
    """Local coordinates of points on the faces ``zeta = side`` of 20-node elements (Newton).

    Solves ``sum_a N_a(xi, eta, side) x_a = p`` for ``(xi, eta)`` by Gauss-Newton on the face's
    quadratic (8-node serendipity) mapping, all point-face pairs at once.

    Parameters
    ----------
    points : ndarray, shape (n, 3)
        Points (m), one per pair.
    nodes : ndarray, shape (n, 20, 3)
        Node coordinates of the element of each pair (m).
    side : int
        -1 or +1: the face ``zeta = side``.
    iterations : int
        Newton steps (the iteration stops early when all pairs have converged).

    Returns
    -------
    local : ndarray, shape (n, 3)
        ``(xi, eta, side)``.
    distance : ndarray, shape (n,)
        ``|x(xi, eta) - p|`` (m): zero where the point lies on the face's surface.
    """
    local = np.zeros((points.shape[0], 3))
    local[:, 2] = side
    for _ in range(iterations):
        values, derivatives = hex20_shape_functions(local)
        residual = np.einsum("na,nai->ni", values, nodes) - points
        jacobian = np.einsum("nak,nai->nik", derivatives[:, :, :2], nodes)  # (n, 3, 2)
        normal = np.einsum("nik,nil->nkl", jacobian, jacobian)
        step = np.linalg.solve(normal, np.einsum("nik,ni->nk", jacobian, residual)[..., None])
        local[:, :2] = np.clip(local[:, :2] - step[..., 0], -2.0, 2.0)
        if np.max(np.abs(step)) < 1e-14:
            break
    values, _ = hex20_shape_functions(local)
    distance = np.linalg.norm(np.einsum("na,nai->ni", values, nodes) - points, axis=1)
    return local, distance


def tie_to_faces(
    coordinates: np.ndarray, dependent: np.ndarray, elements: np.ndarray, side: int, n_dof: int
) -> ConstraintEquations:
    """Tie nodes to element faces: ``u_d = sum_a N_a(xi, eta) u_a`` (bonded contact, eq. 9).

    Each dependent node is located on the face ``zeta = side`` of one of ``elements`` (the
    most interior one where it lies on an edge shared by several), and its three translations
    follow the face's interpolation there, as an Abaqus ``*TIE`` or an Ansys bonded-contact MPC.
    The face shape functions reproduce linear fields, so rigid-body motion is kept exactly.

    Parameters
    ----------
    coordinates : ndarray, shape (n_nodes, 3)
        Node positions (m); equation ``3 r + i`` is direction ``i`` of row ``r``.
    dependent : ndarray of int, shape (n,)
        Rows of the nodes to tie.
    elements : ndarray of int, shape (n_el, 20)
        Candidate elements; their faces ``zeta = side`` form the target surface.
    side : int
        -1 or +1.
    n_dof : int
        Number of equations of the body.

    Raises
    ------
    UserError
        If a node lies on none of the faces.
    """
    points = coordinates[dependent]
    faces = coordinates[elements[:, FACE_NODES[side]]]  # (n_el, 8, 3)
    low, high = faces.min(axis=1), faces.max(axis=1)
    margin = 0.1 * np.max(high - low, axis=1, keepdims=True) + 1e-12
    candidate = np.all(
        (points[:, None] >= low - margin) & (points[:, None] <= high + margin), axis=-1
    )
    point, element = np.nonzero(candidate)
    local, distance = face_coordinates(points[point], coordinates[elements[element]], side)
    outside = np.max(np.abs(local[:, :2]), axis=1)
    size = np.max(high - low, axis=1)[element]
    inside = (outside <= 1.0 + 1e-9) & (distance <= 1e-9 * size)
    # per point, the candidate with the smallest max(|xi|, |eta|)
    order = np.lexsort((outside, ~inside, point))
    first = order[np.r_[True, point[order][1:] != point[order][:-1]]]
    chosen = first[inside[first]]
    if chosen.size != dependent.size:
        lost = np.setdiff1d(np.arange(dependent.size), point[chosen])[0]
        raise UserError(f"tie: the node at {points[lost]} lies on no face of the target surface")
    values, _ = hex20_shape_functions(local[chosen])
    weights = values[:, FACE_NODES[side]]  # (n, 8)
    masters = elements[element[chosen]][:, FACE_NODES[side]]  # (n, 8)
    directions = np.arange(3)[None, :, None]
    values, rows, cols = np.broadcast_arrays(
        weights[:, None, :],  # (n, 1, 8)
        3 * np.arange(dependent.size)[:, None, None] + directions,  # (n, 3, 1)
        3 * masters[:, None, :] + directions,  # (n, 3, 8)
    )
    matrix = sp.csr_matrix(
        (values.ravel(), (rows.ravel(), cols.ravel())), shape=(3 * dependent.size, n_dof)
    )
    return ConstraintEquations(
        dependent=(3 * dependent[:, None] + np.arange(3)).ravel(),
        matrix=matrix,
        offset=np.zeros(3 * dependent.size),
    )


def tie_rods(mesh: SolidMesh, design: RackDesign | None = None) -> ConstraintEquations:
    """Tie the end faces of the rods to the plates (:func:`tie_to_faces`).

    All rod nodes on ``z = t_lower / 2`` are tied to the top face of the lower plate, all on
    ``z = t_lower / 2 + L`` to the bottom face of the upper plate.
    """
    d = design or RackDesign()
    z_bottom = d.lower_plate.thickness / 2.0
    z_ends = (z_bottom, z_bottom + d.rod_length)
    z = mesh.coordinates[:, 2]
    rod_nodes = (mesh.node_parts >= 1) & (mesh.node_parts <= 4)
    n_dof = 3 * mesh.coordinates.shape[0]
    equations = []
    for z_end, part, side in zip(z_ends, (0, 5), (1, -1), strict=True):
        dependent = np.flatnonzero(rod_nodes & (np.abs(z - z_end) < 1e-12))
        faces = z[mesh.elements[:, FACE_NODES[side]]]
        on_surface = np.all(np.abs(faces - z_end) < 1e-12, axis=1)
        targets = mesh.elements[on_surface & (mesh.element_parts == part)]
        equations.append(tie_to_faces(mesh.coordinates, dependent, targets, side, n_dof))
    return ConstraintEquations(
        dependent=np.concatenate([e.dependent for e in equations]),
        matrix=sp.vstack([e.matrix for e in equations]),
        offset=np.concatenate([e.offset for e in equations]),
    )


#: Interface variants of :func:`rack_solid`: keyword arguments of ``InterfaceSpec`` (the spring
#: values are totals over all coupled nodes, divided among them when the spec is made).
INTERFACES: dict[str, dict[str, str | float]] = {
    "rigid": {"kind": "rigid"},
    "distributing": {"kind": "distributing"},
    "steel-beams": {"kind": "beams", "youngs_modulus": STEEL_E, "density": STEEL_RHO,
                    "diameter": 1e-3, "poisson": STEEL_NU},
    "light-beams": {"kind": "beams", "youngs_modulus": 1e18, "density": 100.0,
                    "diameter": 1e-3, "poisson": STEEL_NU},
    "springs": {"kind": "springs", "stiffness": 1e9, "damping": 1e4},
}  # fmt: skip


def rack_solid(dofs: int = 35_000, interface: str = "light-beams") -> ElasticBody:
    """The rack of paper section 2 meshed with 20-node hexahedra (SI units).

    Parameters
    ----------
    dofs : int
        Wanted number of mesh dofs; the element counts are chosen so the mesh has that many
        within 15 % (:func:`plan_mesh`). The interface adds a few more.
    interface : str
        Coupling of interface node 2 in the centre of the hole to the nodes of the hole's
        surface: one of :data:`INTERFACES`, or ``"none"`` for the bare mesh without node 2.

    Returns
    -------
    ElasticBody
        Named ``"rack-solid"``, undamped (except the dampers of ``"springs"``), no fixed dofs;
        the rod end nodes are dependent on the plate faces (:func:`tie_rods`).
    """
    if interface != "none" and interface not in INTERFACES:
        raise UserError(
            f"rack-solid: unknown interface {interface!r}; use 'none' or one of "
            + ", ".join(INTERFACES)
        )
    design = RackDesign()
    mesh = mesh_rack(plan_mesh(dofs, design), design)
    stiffness, mass = assemble_hex20(mesh.coordinates, mesh.elements, STEEL_E, STEEL_NU, STEEL_RHO)
    connectivity = mesh.node_ids[mesh.elements]
    n_nodes = mesh.coordinates.shape[0]
    body = ElasticBody(
        node_ids=mesh.node_ids,
        coordinates=mesh.coordinates,
        dofs=DofTable(np.repeat(mesh.node_ids, 3), np.tile(np.arange(3), n_nodes)),
        mass=mass,
        stiffness=stiffness,
        constraints=tie_rods(mesh, design),
        damping=Damping(),
        name="rack-solid",
        mesh=ElementMesh("hex20", connectivity, STEEL_E, STEEL_NU),
        surface=outer_surface([("hex20", connectivity)], mesh.node_ids, mesh.coordinates),
    )
    if interface == "none":
        return body
    return _with_interface(body, design, INTERFACES[interface])


def _with_interface(
    body: ElasticBody, design: RackDesign, parameters: dict[str, str | float]
) -> ElasticBody:
    """Add node 2 in the centre of the hole, coupled to all nodes of the hole's surface."""
    from pymorembs.preparation.interface import InterfaceSpec, add_interface_node, select_nodes

    plate = design.upper_plate
    z_mid = design.node2_height
    half = np.array([plate.length, plate.width, plate.thickness]) / 2.0 + 1e-6
    centre = np.array([0.0, 0.0, z_mid])
    nodes = select_nodes(
        body,
        cylinder=(centre, (0.0, 0.0, 1.0), plate.hole_diameter / 2.0, 1e-6),
        box=(centre - half, centre + half),
    )
    params = dict(parameters)
    if params["kind"] == "springs":
        params["stiffness"] = float(params["stiffness"]) / len(nodes)
        params["damping"] = float(params["damping"]) / len(nodes)
    spec = InterfaceSpec(
        node=2, position=(0.0, 0.0, z_mid), coupled=tuple(int(n) for n in nodes), **params
    )
    return add_interface_node(body, spec)
