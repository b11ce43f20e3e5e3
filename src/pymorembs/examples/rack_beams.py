"""The rack of paper section 2 as a beam model: two rigid plates joined by four steel rods.

The lower plate hangs below the upper plate on four vertical rods (``z`` axis vertical, lower
plate at the bottom). Each rod is a line of 3-D Euler–Bernoulli beam elements
(:mod:`pymorembs.elements.beam`). The plates are rigid bodies: each is represented by its
reference node, which carries the plate's 6×6 rigid-body mass matrix and no stiffness; the rod end
nodes are dependent dofs tied rigidly to the reference node by constraint equations
``q_d = G q`` (paper eq. 9, offset ``g = 0``)::

    u_end = u_ref + theta_ref x (r_end - r_ref),    theta_end = theta_ref

Nodes (coordinates in m):

* node 1 -- reference node of the lower plate, in its centre ``(0, 0, 0)``;
* node 2 -- interface node in the centre of the hole of the upper plate (mid-plane), also the
  reference node of the upper plate, ``(0, 0, 0.2125)``;
* rod ``j`` = 1..4, node ``i`` = 1..166 from bottom to top: id ``1000 j + i``. Rod 1 stands at
  ``(+25, +20) mm``, rod 2 at ``(-25, +20)``, rod 3 at ``(-25, -20)``, rod 4 at ``(+25, -20)``.

Both reference nodes lie in the centre of gravity of their plate, so the coupling terms of the
rigid-body mass matrix (:func:`rigid_body_mass_matrix`) vanish here.

Dimensions and masses (all parts steel, E = 2.1e11 N/m², nu = 0.3, rho = 7850 kg/m³):

=================  ====================================================  ==========
part               dimensions                                            mass
=================  ====================================================  ==========
upper plate        100 × 90 × 17 mm (x × y × z), central hole Ø 30 mm    1.1067 kg
4 rods             Ø 4 mm, free length 200 mm, at the corners of a        0.0790 kg
                   50 × 40 mm rectangle; 165 elements each
upper part         upper plate + rods                                    1.1856 kg
lower plate        64 × 50 × 8 mm                                        0.2010 kg
total                                                                    1.3866 kg
=================  ====================================================  ==========

The model has 666 nodes and 3996 dofs (6 per node); 48 are dependent (the 8 rod end nodes),
leaving 3948 independent dofs, 3942 with node 2 clamped.

Eigenfrequencies with all six dofs of node 2 clamped and the constraints eliminated:

=====  ==========  ===================================================================
mode   f (Hz)      shape
=====  ==========  ===================================================================
1      41.57       sway of the lower plate along y (rods bent guided–guided)
2      41.62       sway along x: slightly stiffer, as the plate's rocking about y is held
                   by the rods' axial stiffness on the wider lever arm (50 mm vs 40 mm)
3      100.93      torsion of the lower plate about z
4-8    460.43      local bending of the rods with the lower plate at rest (5 modes)
9      471.96      local rod bending coupled with the lower plate's y motion (the 3
10     472.95      remaining of the 8 local modes: 4 rods × 2 planes), with x motion,
11     486.15      and with rotation about z
12     1269.20     second local bending of the rods (followed by 3 more at 1269.20)
=====  ==========  ===================================================================

Hand check of modes 1-2: four guided–guided rods, ``k = 4·12 E I / L³ = 15.8 kN/m``, effective
mass ``m_plate + 4·(13/35) m_rod = 0.230 kg`` give 41.7 Hz. A single clamped–clamped rod bends
at ``22.37 / (2 pi L²) sqrt(E I / (rho A)) = 460.4 Hz``. The free rack (no node clamped) has six
rigid-body modes; its first elastic mode lies at 105 Hz.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp

from pymorembs.body import Damping, DofTable, ElasticBody, ElementMesh
from pymorembs.elements.beam import BeamSection, assemble_beams
from pymorembs.elements.rigid import rigid_body_mass_matrix
from pymorembs.preparation.interface import rigid_links
from pymorembs.surface import outer_surface

#: Steel of rods and plates: Young's modulus (N/m²), Poisson's ratio, density (kg/m³).
STEEL_E = 2.1e11
STEEL_NU = 0.3
STEEL_RHO = 7850.0


@dataclass(frozen=True)
class Plate:
    """A rectangular rigid plate with an optional central circular hole.

    Parameters
    ----------
    length, width, thickness : float
        Extent along ``x``, ``y`` and ``z`` (m).
    hole_diameter : float
        Diameter of the central hole along ``z`` (m); 0 for none.
    density : float
        Density (kg/m³).
    """

    length: float
    width: float
    thickness: float
    hole_diameter: float = 0.0
    density: float = STEEL_RHO

    def _parts(self) -> tuple[float, float]:
        """Masses (kg) of the full block and of the material of the hole."""
        block = self.density * self.length * self.width * self.thickness
        hole = self.density * np.pi * self.hole_diameter**2 / 4.0 * self.thickness
        return block, hole

    @property
    def mass(self) -> float:
        """Mass (kg)."""
        block, hole = self._parts()
        return block - hole

    def inertia(self) -> np.ndarray:
        """Inertia tensor about the centre of gravity (kg·m²), shape (3, 3), diagonal."""
        block, hole = self._parts()
        a, b, t, r = self.length, self.width, self.thickness, self.hole_diameter / 2.0
        j_block = block / 12.0 * np.array([b**2 + t**2, a**2 + t**2, a**2 + b**2])
        j_hole = hole * np.array([(3 * r**2 + t**2) / 12.0, (3 * r**2 + t**2) / 12.0, r**2 / 2])
        return np.diag(j_block - j_hole)


@dataclass(frozen=True)
class RackDesign:
    """Dimensions of the beam rack (m); the defaults are those of the module docstring.

    Parameters
    ----------
    rod_diameter, rod_length : float
        Diameter and free length between the plates of each rod (m).
    rod_spacing : tuple of float
        Sides (x, y) of the rectangle at whose corners the rods stand (m).
    elements_per_rod : int
        Beam elements along each rod.
    lower_plate, upper_plate : Plate
        The two rigid plates; the upper plate's hole is centred on node 2.
    """

    rod_diameter: float = 0.004
    rod_length: float = 0.200
    rod_spacing: tuple[float, float] = (0.050, 0.040)
    elements_per_rod: int = 165
    lower_plate: Plate = field(default_factory=lambda: Plate(0.064, 0.050, 0.008))
    upper_plate: Plate = field(default_factory=lambda: Plate(0.100, 0.090, 0.017, 0.030))

    @property
    def rod_section(self) -> BeamSection:
        return BeamSection.circular(self.rod_diameter, E=STEEL_E, nu=STEEL_NU, rho=STEEL_RHO)

    @property
    def rod_mass(self) -> float:
        """Mass of one rod (kg)."""
        return STEEL_RHO * self.rod_section.area * self.rod_length

    @property
    def rod_positions(self) -> np.ndarray:
        """(x, y) of rods 1..4 (m), shape (4, 2)."""
        half = np.asarray(self.rod_spacing) / 2.0
        return half * np.array([[1.0, 1.0], [-1.0, 1.0], [-1.0, -1.0], [1.0, -1.0]])

    @property
    def node2_height(self) -> float:
        """``z`` of node 2 (m); node 1 is at the origin."""
        return self.lower_plate.thickness / 2.0 + self.rod_length + self.upper_plate.thickness / 2.0


def block_matrix(
    row_starts: np.ndarray, col_starts: np.ndarray, blocks: np.ndarray, shape: tuple[int, int]
) -> sp.csr_matrix:
    """Sparse matrix with 6×6 blocks placed at given (row, column) offsets.

    Parameters
    ----------
    row_starts, col_starts : ndarray of int, shape (n,)
        First row and first column of each block.
    blocks : ndarray, shape (n, 6, 6)
        The blocks; overlapping blocks are added.
    shape : tuple of int
        Shape of the result.

    Returns
    -------
    scipy.sparse.csr_matrix
        The assembled matrix, explicit zeros removed.
    """
    offsets = np.arange(6)
    i = np.asarray(row_starts)[:, None, None] + offsets[None, :, None]
    j = np.asarray(col_starts)[:, None, None] + offsets[None, None, :]
    i, j = np.broadcast_arrays(i, j)
    matrix = sp.csr_matrix((np.ravel(blocks), (i.ravel(), j.ravel())), shape=shape)
    matrix.eliminate_zeros()
    return matrix


def rack_beams(design: RackDesign | None = None) -> ElasticBody:
    """The rack of paper section 2 as a beam model (about 4,000 dofs, SI units).

    Parameters
    ----------
    design : RackDesign, optional
        Dimensions; default: those of the module docstring.

    Returns
    -------
    ElasticBody
        Named ``"rack-beams"``, undamped, no fixed dofs; rod end nodes are dependent on the plate
        reference nodes 1 (lower plate) and 2 (upper plate, interface node).
    """
    d = design or RackDesign()
    n_per_rod = d.elements_per_rod + 1
    z_bottom = d.lower_plate.thickness / 2.0
    heights = z_bottom + np.linspace(0.0, d.rod_length, n_per_rod)
    rod_numbers = np.arange(1, 5)
    rod_ids = 1000 * rod_numbers[:, None] + np.arange(1, n_per_rod + 1)  # (4, n_per_rod)
    rod_xyz = np.concatenate(
        [
            np.broadcast_to(d.rod_positions[:, None, :], (4, n_per_rod, 2)),
            np.broadcast_to(heights, (4, n_per_rod))[..., None],
        ],
        axis=2,
    )
    references = np.array([[0.0, 0.0, 0.0], [0.0, 0.0, d.node2_height]])
    node_ids = np.concatenate([[1, 2], rod_ids.ravel()])
    coordinates = np.concatenate([references, rod_xyz.reshape(-1, 3)])
    n_dof = 6 * node_ids.size
    first_dof = 6 * np.arange(node_ids.size)
    dofs = DofTable(np.repeat(node_ids, 6), np.tile(np.arange(6), node_ids.size))

    elements = np.stack([rod_ids[:, :-1], rod_ids[:, 1:]], axis=-1).reshape(-1, 2)
    stiffness, mass = assemble_beams(
        node_ids, coordinates, elements, d.rod_section, first_dof[:, None] + np.arange(6),
        n_dof=n_dof,
    )  # fmt: skip
    # Rigid plates: 6x6 mass at the reference nodes (rows 0 and 1); CG offset zero (see above).
    plate_blocks = np.stack(
        [
            rigid_body_mass_matrix(plate.mass, plate.inertia(), np.zeros(3))
            for plate in (d.lower_plate, d.upper_plate)
        ]
    )
    mass = mass + block_matrix(first_dof[:2], first_dof[:2], plate_blocks, (n_dof, n_dof))

    body = ElasticBody(
        node_ids=node_ids,
        coordinates=coordinates,
        dofs=dofs,
        mass=mass,
        stiffness=stiffness,
        damping=Damping(),
        name="rack-beams",
        mesh=ElementMesh("beam2", elements, STEEL_E, STEEL_NU, section=d.rod_section),
        surface=outer_surface([("beam2", elements)], node_ids, coordinates),
    )
    # Rod end nodes (first and last node of each rod) follow the plates rigidly (eq. 9).
    body = rigid_links(body, 1, rod_ids[:, 0].tolist())
    return rigid_links(body, 2, rod_ids[:, -1].tolist())
