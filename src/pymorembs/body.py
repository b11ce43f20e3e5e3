"""The finite-element description of one elastic body.

An :class:`ElasticBody` holds what an FE program knows about a body: the nodes, the dof table that
maps (node id, direction) to an equation index, the sparse symmetric mass, stiffness and optional
damping matrices, the constraint equations ``q_d = G q + g`` (paper eq. 9) and the fixed dofs
``q_c = 0`` (paper eq. 10). It is immutable: every transformation returns a new body.

Units are those of the FE model (the rack examples use SI: m, kg, s, N).
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from functools import cached_property
from typing import Literal

import numpy as np
import scipy.sparse as sp

from pymorembs.errors import UserError

#: The six nodal directions, in the order of the direction codes 0..5.
DIRECTIONS: tuple[str, ...] = ("ux", "uy", "uz", "rx", "ry", "rz")
_DIRECTION_CODE = {name: code for code, name in enumerate(DIRECTIONS)}


def direction_code(name: str) -> int:
    """Code 0..5 of a direction name (``"ux"`` ... ``"rz"``, case-insensitive)."""
    code = _DIRECTION_CODE.get(str(name).strip().lower())
    if code is None:
        raise UserError(f"unknown direction {name!r}; expected one of {', '.join(DIRECTIONS)}")
    return code


def parse_directions(spec: str | list[str] | tuple[str, ...]) -> list[int]:
    """Direction codes from ``"ux uy uz"``, ``"ux,uy"`` or ``["ux", "uy"]``.

    Two shorthands are accepted: ``"translations"`` (ux uy uz) and ``"rotations"`` (rx ry rz).
    """
    if isinstance(spec, str):
        words = spec.replace(",", " ").split()
    else:
        words = [str(w) for w in spec]
    codes: list[int] = []
    for word in words:
        low = word.lower()
        if low in ("translations", "all_translations"):
            codes.extend((0, 1, 2))
        elif low in ("rotations", "all_rotations"):
            codes.extend((3, 4, 5))
        elif low == "all":
            codes.extend(range(6))
        else:
            codes.append(direction_code(word))
    if not codes:
        raise UserError(f"no direction given in {spec!r}")
    if len(set(codes)) != len(codes):
        raise UserError(f"direction repeated in {spec!r}")
    return codes


@dataclass(frozen=True, eq=False)
class DofTable:
    """Map between equation indices and (node id, direction).

    Parameters
    ----------
    nodes : ndarray of int, shape (n_dof,)
        Node id of each equation, in matrix order.
    directions : ndarray of int, shape (n_dof,)
        Direction code 0..5 (ux uy uz rx ry rz) of each equation.
    """

    nodes: np.ndarray
    directions: np.ndarray

    def __post_init__(self) -> None:
        nodes = np.asarray(self.nodes, dtype=np.int64).ravel()
        directions = np.asarray(self.directions, dtype=np.int64).ravel()
        if nodes.shape != directions.shape:
            raise UserError(
                f"dof table: {nodes.size} node entries but {directions.size} direction entries"
            )
        if directions.size and (directions.min() < 0 or directions.max() > 5):
            raise UserError("dof table: direction codes must be 0..5 (ux uy uz rx ry rz)")
        key = nodes * 8 + directions
        if np.unique(key).size != key.size:
            dup = _first_duplicate(key)
            raise UserError(
                f"dof table: (node {dup // 8}, {DIRECTIONS[dup % 8]}) appears more than once"
            )
        object.__setattr__(self, "nodes", nodes)
        object.__setattr__(self, "directions", directions)

    def __len__(self) -> int:
        return int(self.nodes.size)

    @cached_property
    def _lookup(self) -> dict[tuple[int, int], int]:
        return {
            (int(n), int(d)): i
            for i, (n, d) in enumerate(zip(self.nodes, self.directions, strict=True))
        }

    def index(self, node: int, direction: int | str) -> int:
        """Equation index of one dof; :class:`UserError` if the model has no such dof."""
        code = direction if isinstance(direction, int | np.integer) else direction_code(direction)
        try:
            return self._lookup[(int(node), int(code))]
        except KeyError:
            if not np.any(self.nodes == int(node)):
                raise UserError(f"node {node} has no dofs in the model") from None
            raise UserError(f"node {node} has no dof {DIRECTIONS[int(code)]}") from None

    def indices(self, node: int, directions: list[int] | str) -> np.ndarray:
        """Equation indices of several directions of one node, in the order given."""
        codes = parse_directions(directions) if isinstance(directions, str) else directions
        return np.array([self.index(node, c) for c in codes], dtype=np.int64)

    def of_node(self, node: int) -> np.ndarray:
        """All equation indices of one node (possibly empty)."""
        return np.flatnonzero(self.nodes == int(node))

    def label(self, index: int) -> str:
        """Readable name of an equation, e.g. ``"12:uz"``."""
        return f"{int(self.nodes[index])}:{DIRECTIONS[int(self.directions[index])]}"

    def subset(self, indices: np.ndarray) -> DofTable:
        """The table restricted to the given equations, in that order."""
        return DofTable(self.nodes[indices], self.directions[indices])


@dataclass(frozen=True, eq=False)
class ConstraintEquations:
    """Linear constraint equations ``q_d = G q + g`` (paper eq. 9).

    Parameters
    ----------
    dependent : ndarray of int, shape (n_d,)
        Equation indices of the dependent dofs ``q_d``.
    matrix : sparse matrix, shape (n_d, n_dof)
        ``G`` over all equations of the body. A column of a dependent dof may be non-zero
        (chained constraints); :func:`pymorembs.prepare.elimination` resolves such chains.
    offset : ndarray, shape (n_d,)
        The constant part ``g`` (same unit as the dependent dof).
    """

    dependent: np.ndarray
    matrix: sp.csr_matrix
    offset: np.ndarray

    def __post_init__(self) -> None:
        dependent = np.asarray(self.dependent, dtype=np.int64).ravel()
        matrix = sp.csr_matrix(self.matrix, dtype=float)
        offset = np.asarray(self.offset, dtype=float).ravel()
        if matrix.shape[0] != dependent.size or offset.size != dependent.size:
            raise UserError(
                f"constraint equations: {dependent.size} dependent dofs, "
                f"{matrix.shape[0]} rows of G and {offset.size} offsets"
            )
        if np.unique(dependent).size != dependent.size:
            raise UserError(
                f"constraint equations: dof {_first_duplicate(dependent)} is dependent "
                "in more than one equation"
            )
        if not (np.all(np.isfinite(matrix.data)) and np.all(np.isfinite(offset))):
            raise UserError("constraint equations: coefficients must be finite")
        object.__setattr__(self, "dependent", dependent)
        object.__setattr__(self, "matrix", matrix)
        object.__setattr__(self, "offset", offset)

    @classmethod
    def empty(cls, n_dof: int) -> ConstraintEquations:
        """No constraint equations for a body with ``n_dof`` equations."""
        return cls(np.zeros(0, dtype=np.int64), sp.csr_matrix((0, n_dof)), np.zeros(0))

    def __len__(self) -> int:
        return int(self.dependent.size)


@dataclass(frozen=True)
class Damping:
    """Damping model of the body.

    ``kind``:

    * ``"none"`` -- undamped (or only the explicit damping matrix of the body, if any);
    * ``"rayleigh"`` -- ``D = alpha M + beta K`` (alpha in 1/s, beta in s);
    * ``"modal"`` -- every mode gets the damping ratio ``ratio`` (dimensionless). The reduced model
      receives the viscous modal damping ``diag(2 ratio omega_i)`` in its eigenbasis; frequency
      responses of full and reduced models use the equivalent loss factor ``eta = 2 ratio`` on the
      stiffness (as FE programs do for a constant damping ratio in a full harmonic analysis),
      which equals the modal damping at every resonance.
    """

    kind: Literal["none", "rayleigh", "modal"] = "none"
    alpha: float = 0.0
    beta: float = 0.0
    ratio: float = 0.0

    def __post_init__(self) -> None:
        if self.kind not in ("none", "rayleigh", "modal"):
            raise UserError(
                f"damping kind {self.kind!r} is unknown; use 'none', 'rayleigh' or 'modal'"
            )
        for name in ("alpha", "beta", "ratio"):
            value = getattr(self, name)
            if not np.isfinite(value) or value < 0:
                raise UserError(f"damping {name} must be a finite number >= 0, got {value!r}")
        if self.kind == "modal" and not 0 < self.ratio < 1:
            raise UserError(f"modal damping ratio must lie in (0, 1), got {self.ratio!r}")


@dataclass(frozen=True, eq=False)
class ElasticBody:
    """FE model of one elastic body.

    Parameters
    ----------
    node_ids : ndarray of int, shape (n_nodes,)
        Node ids as in the FE program.
    coordinates : ndarray, shape (n_nodes, 3)
        Undeformed node positions (model length unit, m for the built-in examples).
    dofs : DofTable
        (node, direction) of every equation, length ``n_dof``.
    mass, stiffness : sparse matrix, shape (n_dof, n_dof)
        Symmetric mass and stiffness matrices over all equations (dependent and fixed ones
        included).
    damping_matrix : sparse matrix, shape (n_dof, n_dof), optional
        Explicit viscous damping matrix from the FE program; added to the :class:`Damping` model.
    constraints : ConstraintEquations, optional
        ``q_d = G q + g`` (eq. 9).
    fixed : ndarray of int, shape (n_c,), optional
        Equation indices with ``q_c = 0`` (eq. 10).
    damping : Damping
        Damping model (none, Rayleigh or modal ratio).
    name : str
        A label for reports.
    """

    node_ids: np.ndarray
    coordinates: np.ndarray
    dofs: DofTable
    mass: sp.csr_matrix
    stiffness: sp.csr_matrix
    damping_matrix: sp.csr_matrix | None = None
    constraints: ConstraintEquations | None = None
    fixed: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    damping: Damping = field(default_factory=Damping)
    name: str = "body"

    def __post_init__(self) -> None:
        node_ids = np.asarray(self.node_ids, dtype=np.int64).ravel()
        coordinates = np.asarray(self.coordinates, dtype=float)
        if coordinates.shape != (node_ids.size, 3):
            raise UserError(
                f"nodes: {node_ids.size} ids but coordinates of shape {coordinates.shape}, "
                f"expected ({node_ids.size}, 3)"
            )
        if np.unique(node_ids).size != node_ids.size:
            raise UserError(f"nodes: node id {_first_duplicate(node_ids)} appears more than once")
        if not np.all(np.isfinite(coordinates)):
            raise UserError("nodes: coordinates must be finite")
        n = len(self.dofs)
        missing = np.setdiff1d(self.dofs.nodes, node_ids)
        if missing.size:
            raise UserError(f"dof table names node {missing[0]} which is not in the node list")
        matrices = {"mass": self.mass, "stiffness": self.stiffness}
        if self.damping_matrix is not None:
            matrices["damping"] = self.damping_matrix
        for label, matrix in matrices.items():
            matrix = sp.csr_matrix(matrix, dtype=float)
            if matrix.shape != (n, n):
                raise UserError(
                    f"{label} matrix has shape {matrix.shape} but the dof table has {n} rows"
                )
            if not np.all(np.isfinite(matrix.data)):
                raise UserError(f"{label} matrix has NaN or infinite entries")
            matrix.sum_duplicates()
            matrix.sort_indices()
            object.__setattr__(self, label if label != "damping" else "damping_matrix", matrix)
        constraints = self.constraints or ConstraintEquations.empty(n)
        if constraints.matrix.shape[1] != n:
            raise UserError(
                f"constraint equations have {constraints.matrix.shape[1]} columns, expected {n}"
            )
        if constraints.dependent.size and (
            constraints.dependent.min() < 0 or constraints.dependent.max() >= n
        ):
            raise UserError("constraint equations name a dependent dof outside the dof table")
        fixed = np.unique(np.asarray(self.fixed, dtype=np.int64).ravel())
        if fixed.size and (fixed[0] < 0 or fixed[-1] >= n):
            raise UserError("fixed dofs: an index lies outside the dof table")
        object.__setattr__(self, "node_ids", node_ids)
        object.__setattr__(self, "coordinates", coordinates)
        object.__setattr__(self, "constraints", constraints)
        object.__setattr__(self, "fixed", fixed)

    # ----------------------------------------------------------------- facts
    @property
    def n_dof(self) -> int:
        """Number of equations of the FE model."""
        return len(self.dofs)

    @property
    def n_nodes(self) -> int:
        return int(self.node_ids.size)

    @cached_property
    def node_index(self) -> dict[int, int]:
        """Row in :attr:`coordinates` of each node id."""
        return {int(n): i for i, n in enumerate(self.node_ids)}

    def node_position(self, node: int) -> np.ndarray:
        """Coordinates, shape (3,), of a node; :class:`UserError` if it does not exist."""
        try:
            return self.coordinates[self.node_index[int(node)]]
        except KeyError:
            raise UserError(f"node {node} does not exist in the model") from None

    def rigid_body_modes(self, origin: np.ndarray | None = None) -> np.ndarray:
        """The six rigid-body displacement fields over all equations, shape (n_dof, 6).

        Columns: translations x, y, z, then rotations about x, y, z through ``origin``
        (default: the coordinate origin). For a rotation ``theta`` the translation of a node at
        ``r`` is ``theta x (r - origin)`` and its rotational dofs equal ``theta``.
        """
        origin = np.zeros(3) if origin is None else np.asarray(origin, dtype=float)
        rows = np.array([self.node_index[int(n)] for n in self.dofs.nodes], dtype=np.int64)
        r = self.coordinates[rows] - origin
        d = self.dofs.directions
        modes = np.zeros((self.n_dof, 6))
        for axis in range(3):
            modes[d == axis, axis] = 1.0  # translations
            modes[d == axis + 3, axis + 3] = 1.0  # rotational dofs follow the rotation
        # translation u = theta x r: u_x = th_y r_z - th_z r_y, etc.
        tx, ty, tz = d == 0, d == 1, d == 2
        modes[tx, 4], modes[tx, 5] = r[tx, 2], -r[tx, 1]
        modes[ty, 3], modes[ty, 5] = -r[ty, 2], r[ty, 0]
        modes[tz, 3], modes[tz, 4] = r[tz, 1], -r[tz, 0]
        return modes

    def total_mass(self) -> float:
        """Mass of the body (model unit), from rigid translations: mean of ``t_i^T M t_i``."""
        modes = self.rigid_body_modes()[:, :3]
        masses = np.einsum("ij,ij->j", modes, self.mass @ modes)
        return float(np.mean(masses))

    # -------------------------------------------------------- transformations
    def translated(self, origin: np.ndarray) -> ElasticBody:
        """The same body with coordinates measured from ``origin`` (shape (3,))."""
        return replace(self, coordinates=self.coordinates - np.asarray(origin, dtype=float))

    def with_fixed(self, indices: np.ndarray) -> ElasticBody:
        """The body with further fixed dofs (eq. 10)."""
        return replace(self, fixed=np.union1d(self.fixed, np.asarray(indices, dtype=np.int64)))

    def with_damping(self, damping: Damping) -> ElasticBody:
        """The body with another damping model."""
        return replace(self, damping=damping)

    def viscous_damping(self) -> sp.csr_matrix | None:
        """The viscous damping matrix: explicit ``D`` plus Rayleigh ``alpha M + beta K``.

        ``None`` when the body has no viscous damping. Modal damping is not a matrix of the full
        model; see :class:`Damping`.
        """
        parts = []
        if self.damping_matrix is not None:
            parts.append(self.damping_matrix)
        if self.damping.kind == "rayleigh" and (self.damping.alpha or self.damping.beta):
            parts.append(self.damping.alpha * self.mass + self.damping.beta * self.stiffness)
        if not parts:
            return None
        return sp.csr_matrix(sum(parts[1:], parts[0]))


def _first_duplicate(values: np.ndarray) -> int:
    seen: set[int] = set()
    for v in np.asarray(values).ravel():
        if int(v) in seen:
            return int(v)
        seen.add(int(v))
    raise ValueError("no duplicate")
