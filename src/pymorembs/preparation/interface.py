"""Interface nodes (paper section 2.2).

Forces and joints act on areas, not on single nodes. An interface node -- e.g. in the centre of a
hole -- is added to the FE model and coupled to the nodes of the area in one of four ways (paper
Fig. 5):

* ``"rigid"`` (RBE2-like): the coupled nodes follow the interface node rigidly; their dofs become
  dependent, ``u_s = u_m + theta_m x (r_s - r_m)``, ``theta_s = theta_m`` (eq. 9).
* ``"distributing"`` (RBE3-like): the interface node follows the coupled nodes on average; its
  dofs become dependent: the translation of the weighted centroid plus the least-squares rotation
  of the coupled nodes, carried to the interface node's position. Loads on it are distributed
  to the coupled nodes without stiffening the area.
* ``"beams"``: a spider of 3-D beams from the interface node to each coupled node, steel or the
  paper's light stiff beams (``E = 1e18 N/m^2``, ``rho = 100 kg/m^3``). Coupled nodes without
  rotational dofs get them (pinned beam ends, stiffness from the beams only).
* ``"springs"``: spring-dampers from the interface node to each coupled node, one along each of
  x, y and z with the given stiffness and damping. The interface node then has translational
  dofs only.

The interface node of the first three kinds has six dofs (ux uy uz rx ry rz).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np
import scipy.sparse as sp

from pymorembs.body import ConstraintEquations, DofTable, ElasticBody
from pymorembs.elements.beam import BeamSection, assemble_beams
from pymorembs.elements.rigid import skew
from pymorembs.errors import UserError
from pymorembs.kinds import InterfaceKind

KINDS = InterfaceKind.names()

#: The paper's light stiff beams: Young's modulus (N/m^2) and density (kg/m^3).
LIGHT_STIFF_BEAM = {"youngs_modulus": 1e18, "density": 100.0}


@dataclass(frozen=True)
class InterfaceSpec:
    """An interface node and how it is coupled.

    Parameters
    ----------
    node : int
        Id of the new node (must not exist yet).
    position : tuple of 3 floats
        Its coordinates (model length unit).
    coupled : tuple of int
        Ids of the nodes it is coupled to (see :func:`select_nodes`).
    kind : InterfaceKind
        ``"rigid"``, ``"distributing"``, ``"beams"`` or ``"springs"``
        (:class:`~pymorembs.kinds.InterfaceKind`; its name is taken and stored as the kind).
    youngs_modulus, density, diameter, poisson : float
        Beams: material (N/m^2, kg/m^3), circular cross-section diameter (m), Poisson's ratio.
    stiffness, damping : float
        Springs: stiffness (N/m) and viscous damping (N s/m) of each spring.
    """

    node: int
    position: tuple[float, float, float]
    coupled: tuple[int, ...]
    kind: InterfaceKind = InterfaceKind.RIGID
    youngs_modulus: float = 2.1e11
    density: float = 7850.0
    diameter: float = 1e-3
    poisson: float = 0.3
    stiffness: float = 0.0
    damping: float = 0.0

    def __post_init__(self) -> None:
        kind = InterfaceKind.lookup(self.kind)
        if kind is None:
            raise UserError(f"interface kind {self.kind!r} is unknown; use one of {KINDS}")
        object.__setattr__(self, "kind", kind)
        if len(self.position) != 3 or not np.all(np.isfinite(self.position)):
            raise UserError(f"interface node {self.node}: position must be 3 finite numbers")
        if len(self.coupled) == 0:
            raise UserError(f"interface node {self.node}: no nodes to couple to")
        if len(set(self.coupled)) != len(self.coupled):
            raise UserError(f"interface node {self.node}: a coupled node is listed twice")
        if self.kind == "springs" and not self.stiffness > 0:
            raise UserError(f"interface node {self.node}: springs need a stiffness > 0 (N/m)")
        if self.kind == "springs" and self.damping < 0:
            raise UserError(f"interface node {self.node}: spring damping must be >= 0 (N s/m)")


def select_nodes(
    body: ElasticBody,
    ids: Sequence[int] | None = None,
    cylinder: tuple | None = None,
    box: tuple | None = None,
) -> np.ndarray:
    """Ids of the nodes that meet every given criterion.

    Parameters
    ----------
    ids : sequence of int, optional
        Explicit node ids (each must exist).
    cylinder : (point, direction, radius[, tolerance]), optional
        Nodes around the axis through ``point`` along ``direction``: with ``tolerance``, those
        whose distance from the axis is ``radius +- tolerance`` (the surface of a hole); without
        it, those within ``radius`` of the axis. Combine with ``box`` to limit the axial extent.
    box : (lower corner, upper corner), optional
        Nodes with ``lower <= x <= upper`` componentwise.
    """
    if ids is None and cylinder is None and box is None:
        raise UserError("node selection: give node ids, a cylinder or a box")
    chosen = np.ones(body.n_nodes, dtype=bool)
    if ids is not None:
        wanted = np.asarray(ids, dtype=np.int64)
        missing = np.setdiff1d(wanted, body.node_ids)
        if missing.size:
            raise UserError(f"node selection: node {missing[0]} does not exist in the model")
        chosen &= np.isin(body.node_ids, wanted)
    if cylinder is not None:
        if len(cylinder) not in (3, 4):
            raise UserError("node selection: cylinder is (point, direction, radius[, tolerance])")
        point = np.asarray(cylinder[0], dtype=float)
        axis = np.asarray(cylinder[1], dtype=float)
        if point.shape != (3,) or axis.shape != (3,) or not np.linalg.norm(axis) > 0:
            raise UserError("node selection: cylinder point and direction must be 3-vectors")
        axis = axis / np.linalg.norm(axis)
        rel = body.coordinates - point
        distance = np.linalg.norm(rel - np.outer(rel @ axis, axis), axis=1)
        radius = float(cylinder[2])
        if len(cylinder) == 4:
            chosen &= np.abs(distance - radius) <= float(cylinder[3])
        else:
            chosen &= distance <= radius
    if box is not None:
        lower, upper = (np.asarray(corner, dtype=float) for corner in box)
        chosen &= np.all((body.coordinates >= lower) & (body.coordinates <= upper), axis=1)
    found = body.node_ids[chosen]
    if found.size == 0:
        raise UserError("node selection: no node of the model meets the criteria")
    return found


def add_interface_node(body: ElasticBody, spec: InterfaceSpec) -> ElasticBody:
    """The body with the interface node ``spec.node`` added and coupled (paper section 2.2)."""
    if int(spec.node) in body.node_index:
        raise UserError(f"interface node {spec.node} exists already in the model")
    missing = [n for n in spec.coupled if int(n) not in body.node_index]
    if missing:
        raise UserError(f"interface node {spec.node}: coupled node {missing[0]} does not exist")
    directions = (0, 1, 2) if spec.kind == "springs" else tuple(range(6))
    grown = _with_node(body, spec.node, spec.position, directions)
    if spec.kind == "rigid":
        return _couple_rigid(grown, spec)
    if spec.kind == "distributing":
        return _couple_distributing(grown, spec)
    if spec.kind == "beams":
        return _couple_beams(grown, spec)
    return _couple_springs(grown, spec)


# ----------------------------------------------------------------------------- growing a body
def _with_node(
    body: ElasticBody, node: int, position: Sequence[float], directions: Sequence[int]
) -> ElasticBody:
    """The body with one more node carrying the given dofs (zero rows in M, K, D)."""
    node_ids = np.append(body.node_ids, int(node))
    coordinates = np.vstack([body.coordinates, np.asarray(position, dtype=float)])
    grown = replace(body, node_ids=node_ids, coordinates=coordinates)
    return _with_dofs(grown, [(int(node), d) for d in directions])


def _with_dofs(body: ElasticBody, new: list[tuple[int, int]]) -> ElasticBody:
    """The body with further (node, direction) dofs appended, without mass or stiffness."""
    if not new:
        return body
    n_old, n_new = body.n_dof, body.n_dof + len(new)
    nodes = np.append(body.dofs.nodes, [n for n, _ in new])
    directions = np.append(body.dofs.directions, [d for _, d in new])

    def pad(matrix: sp.spmatrix | None) -> sp.csr_matrix | None:
        """The matrix with empty rows and columns appended; a CSR matrix keeps its data and
        indices arrays (no copy: at 2,000,000 dofs a copy of K is gigabytes)."""
        if matrix is None:
            return None
        matrix = sp.csr_matrix(matrix)
        indptr = np.concatenate([matrix.indptr, np.full(len(new), matrix.indptr[-1])])
        padded = sp.csr_matrix(
            (matrix.data, matrix.indices, indptr.astype(matrix.indptr.dtype)),
            shape=(n_new, n_new),
            copy=False,
        )
        padded.has_canonical_format = matrix.has_canonical_format
        return padded

    constraints = body.constraints
    constraints = ConstraintEquations(
        constraints.dependent,
        sp.hstack([constraints.matrix, sp.csr_matrix((len(constraints), n_new - n_old))]),
        constraints.offset,
    )
    ports = body.ports
    if ports is not None:  # the model's own B and C act on the old dofs only
        extra = len(new)
        ports = replace(
            ports,
            inputs=None
            if ports.inputs is None
            else sp.vstack([ports.inputs, sp.csr_matrix((extra, ports.inputs.shape[1]))]),
            outputs=None
            if ports.outputs is None
            else sp.hstack([ports.outputs, sp.csr_matrix((ports.outputs.shape[0], extra))]),
        )
    return replace(
        body,
        dofs=DofTable(nodes, directions),
        mass=pad(body.mass),
        stiffness=pad(body.stiffness),
        damping_matrix=pad(body.damping_matrix),
        constraints=constraints,
        ports=ports,
    )


def _with_equations(body: ElasticBody, dependent: np.ndarray, matrix: sp.spmatrix) -> ElasticBody:
    """The body with further constraint equations ``q_dependent = matrix q`` (offset 0)."""
    taken = np.intersect1d(dependent, body.constraints.dependent)
    if taken.size:
        raise UserError(
            f"interface: dof {body.dofs.label(taken[0])} is already dependent in another "
            "constraint equation"
        )
    fixed = np.intersect1d(dependent, body.fixed)
    if fixed.size:
        raise UserError(f"interface: dof {body.dofs.label(fixed[0])} is fixed")
    old = body.constraints
    return replace(
        body,
        constraints=ConstraintEquations(
            np.concatenate([old.dependent, dependent]),
            sp.vstack([old.matrix, sp.csr_matrix(matrix)]),
            np.concatenate([old.offset, np.zeros(len(dependent))]),
        ),
    )


def _rows(body: ElasticBody, nodes: Sequence[int], directions: Sequence[int]) -> np.ndarray:
    """Equation indices, shape (len(nodes), len(directions)); -1 where a node lacks the dof."""
    out = np.full((len(nodes), len(directions)), -1, dtype=np.int64)
    lookup = {
        (int(n), int(d)): i
        for i, (n, d) in enumerate(zip(body.dofs.nodes, body.dofs.directions, strict=True))
    }
    for a, node in enumerate(nodes):
        for b, d in enumerate(directions):
            out[a, b] = lookup.get((int(node), int(d)), -1)
    return out


# ---------------------------------------------------------------------------------- couplings
def rigid_links(body: ElasticBody, master: int, slaves: Sequence[int]) -> ElasticBody:
    """Tie the nodes ``slaves`` rigidly to the 6-dof node ``master`` (eq. 9).

    Translations: ``u_s = u_m - [r_s - r_m]x theta_m``; rotational dofs a slave has follow
    ``theta_s = theta_m``. Works for slaves with 3 or 6 dofs.
    """
    master_rows = _rows(body, [master], range(6))[0]
    if np.any(master_rows < 0):
        raise UserError(f"rigid link: node {master} needs all six dofs")
    arms = np.array([body.node_position(s) for s in slaves]) - body.node_position(master)
    slave_rows = _rows(body, slaves, range(6))
    blocks = np.zeros((len(slaves), 6, 6))
    blocks[:, :3, :3] = np.eye(3)
    blocks[:, :3, 3:] = -skew(arms)
    blocks[:, 3:, 3:] = np.eye(3)
    present = slave_rows >= 0
    if not np.all(present[:, :3]):
        bad = slaves[int(np.flatnonzero(~np.all(present[:, :3], axis=1))[0])]
        raise UserError(f"rigid link: node {bad} lacks translational dofs")
    rows = blocks[present]  # (n_eq, 6) coefficients on the master's dofs
    matrix = sp.csr_matrix(
        (
            rows.ravel(),
            (np.repeat(np.arange(rows.shape[0]), 6), np.tile(master_rows, rows.shape[0])),
        ),
        shape=(rows.shape[0], body.n_dof),
    )
    return _with_equations(body, slave_rows[present], matrix)


def _couple_rigid(body: ElasticBody, spec: InterfaceSpec) -> ElasticBody:
    return rigid_links(body, spec.node, list(spec.coupled))


def _couple_distributing(body: ElasticBody, spec: InterfaceSpec) -> ElasticBody:
    """RBE3-like: the interface node's dofs from the coupled nodes' translations (equal weights).

    With ``c`` the centroid of the coupled nodes, ``rho_i = r_i - c`` and
    ``J = sum_i (|rho_i|^2 I - rho_i rho_i^T)``, the least-squares rigid fit of the coupled
    translations is ``theta = J^-1 sum_i rho_i x u_i``, ``u_c = mean_i u_i``; the interface node
    at ``r_m`` moves with it: ``u_m = u_c + theta x (r_m - c)``, ``theta_m = theta``.
    """
    coupled = list(spec.coupled)
    if len(coupled) < 3:
        raise UserError(
            f"interface node {spec.node}: a distributing coupling needs 3 nodes or more"
        )
    positions = np.array([body.node_position(n) for n in coupled])
    centroid = positions.mean(axis=0)
    rho = positions - centroid
    inertia = np.sum(np.einsum("ij,ij->i", rho, rho))[None, None] * np.eye(3) - rho.T @ rho
    if np.linalg.cond(inertia) > 1e12:
        raise UserError(
            f"interface node {spec.node}: the coupled nodes lie on a line; a distributing "
            "coupling cannot carry moments"
        )
    rows = _rows(body, coupled, (0, 1, 2))
    if np.any(rows < 0):
        bad = coupled[int(np.flatnonzero(np.any(rows < 0, axis=1))[0])]
        raise UserError(f"interface node {spec.node}: coupled node {bad} lacks translations")
    n = len(coupled)
    rotation = np.linalg.solve(inertia, skew(rho).transpose(1, 0, 2).reshape(3, 3 * n))
    translation = np.tile(np.eye(3) / n, (1, n))
    arm = np.asarray(spec.position, dtype=float) - centroid
    translation = translation - skew(arm) @ rotation  # u_m = u_c + theta x arm
    coefficients = np.vstack([translation, rotation])  # (6, 3n)
    master_rows = _rows(body, [spec.node], range(6))[0]
    matrix = sp.csr_matrix(
        (coefficients.ravel(), (np.repeat(np.arange(6), 3 * n), np.tile(rows.ravel(), 6))),
        shape=(6, body.n_dof),
    )
    return _with_equations(body, master_rows, matrix)


def _couple_beams(body: ElasticBody, spec: InterfaceSpec) -> ElasticBody:
    coupled = list(spec.coupled)
    rotations = _rows(body, coupled, (3, 4, 5))
    missing = [
        (int(n), d + 3)
        for n, row in zip(coupled, rotations, strict=True)
        for d in range(3)
        if row[d] < 0
    ]
    body = _with_dofs(body, missing)
    section = BeamSection.circular(
        spec.diameter, E=spec.youngs_modulus, nu=spec.poisson, rho=spec.density
    )
    nodes = np.array([spec.node, *coupled], dtype=np.int64)
    coordinates = np.array([body.node_position(n) for n in nodes])
    elements = np.column_stack(
        [np.zeros(len(coupled), dtype=np.int64), np.arange(1, len(coupled) + 1)]
    )
    spokes = coordinates[1:] - coordinates[0]
    if np.any(np.linalg.norm(spokes, axis=1) == 0):
        raise UserError(f"interface node {spec.node}: a coupled node lies at its position")
    stiffness, mass = assemble_beams(
        nodes,
        coordinates,
        nodes[elements],
        section,
        _rows(body, nodes, range(6)),
        up=_up_vector(spokes),
        n_dof=body.n_dof,
    )
    return replace(
        body,
        stiffness=sp.csr_matrix(body.stiffness + stiffness),
        mass=sp.csr_matrix(body.mass + mass),
    )


def _up_vector(spokes: np.ndarray) -> np.ndarray:
    """An orientation vector not parallel to any spoke (circular sections: any will do)."""
    directions = spokes / np.linalg.norm(spokes, axis=1, keepdims=True)
    for candidate in np.eye(3)[[2, 1, 0]]:
        if np.max(np.abs(directions @ candidate)) < 0.999:
            return candidate
    return np.array([1.0, 2.0, 3.0]) / np.sqrt(14.0)


def _couple_springs(body: ElasticBody, spec: InterfaceSpec) -> ElasticBody:
    coupled = list(spec.coupled)
    slave = _rows(body, coupled, (0, 1, 2))
    if np.any(slave < 0):
        bad = coupled[int(np.flatnonzero(np.any(slave < 0, axis=1))[0])]
        raise UserError(f"interface node {spec.node}: coupled node {bad} lacks translations")
    master = np.broadcast_to(_rows(body, [spec.node], (0, 1, 2))[0], slave.shape)
    a, b = master.ravel(), slave.ravel()
    rows = np.concatenate([a, b, a, b])
    cols = np.concatenate([a, b, b, a])
    signs = np.concatenate([np.ones(2 * a.size), -np.ones(2 * a.size)])
    unit = sp.csr_matrix((signs, (rows, cols)), shape=(body.n_dof, body.n_dof))
    damping = None
    if spec.damping > 0:
        damping = spec.damping * unit
        if body.damping_matrix is not None:
            damping = body.damping_matrix + damping
    else:
        damping = body.damping_matrix
    return replace(
        body,
        stiffness=sp.csr_matrix(body.stiffness + spec.stiffness * unit),
        damping_matrix=None if damping is None else sp.csr_matrix(damping),
    )
