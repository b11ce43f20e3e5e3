"""The finite-element description of one elastic body.

An :class:`ElasticBody` holds what an FE program knows about a body: the nodes, the dof table that
maps (node id, direction) to an equation index, the sparse symmetric mass, stiffness and optional
damping matrices, the constraint equations ``q_d = G q + g`` (paper eq. 9) and the fixed dofs
``q_c = 0`` (paper eq. 10). It is immutable: every transformation returns a new body.

Besides the six nodal directions a dof may be a *scalar* coordinate (direction ``q``): a point
without a position, such as a Nastran scalar point, a modal coordinate of a Craig-Bampton
superelement, or an equation of matrices that come without dof labels. Scalar coordinates do
not move in a rigid-body motion and have no node in the node list.

The mass matrix may be singular: massless dofs (beam rotations without rotary inertia, nodes of
rigid elements, point masses without rotary inertia) are normal; see
:mod:`pymorembs.linalg.mass_split`.

Units are those of the FE model (the rack examples use SI: m, kg, s, N).
"""

from __future__ import annotations

import copy
from dataclasses import dataclass, field, replace
from functools import cached_property

import numpy as np
import scipy.sparse as sp

from pymorembs.arguments import described, plain
from pymorembs.arrays import first_duplicate, missing_from, sorted_unique
from pymorembs.display import html_table, one_line, port_labels
from pymorembs.elements.beam import BeamSection
from pymorembs.errors import UserError
from pymorembs.kinds import DampingKind, choices
from pymorembs.sparse_rows import abs_row_sums
from pymorembs.surface import Surface

#: The six nodal directions and the scalar coordinate ``q``, in the order of the codes 0..6.
DIRECTIONS: tuple[str, ...] = ("ux", "uy", "uz", "rx", "ry", "rz", "q")
#: Direction code of a scalar coordinate (a point without a position, see the module docstring).
SCALAR = 6
_DIRECTION_CODE = {name: code for code, name in enumerate(DIRECTIONS)}


def direction_code(name: str) -> int:
    """Code 0..6 of a direction name (``"ux"`` ... ``"rz"``, ``"q"``; case-insensitive)."""
    code = _DIRECTION_CODE.get(str(name).strip().lower())
    if code is None:
        raise UserError(f"unknown direction {name!r}; expected one of {', '.join(DIRECTIONS)}")
    return code


def parse_directions(spec: str | list[str] | tuple[str, ...]) -> list[int]:
    """Direction codes from ``"ux uy uz"``, ``"ux,uy"`` or ``["ux", "uy"]``.

    Three shorthands are accepted: ``"translations"`` (ux uy uz), ``"rotations"`` (rx ry rz)
    and ``"all"`` (the six nodal directions). ``"q"`` is the scalar coordinate of a point without
    a position (see the module docstring).
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
        Direction code 0..6 (ux uy uz rx ry rz, q for a scalar coordinate) of each equation.
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
        if directions.size and (directions.min() < 0 or directions.max() > SCALAR):
            raise UserError("dof table: direction codes must be 0..6 (ux uy uz rx ry rz q)")
        key = nodes * 8 + directions
        dup = first_duplicate(key)
        if dup is not None:
            raise UserError(
                f"dof table: (node {dup // 8}, {DIRECTIONS[dup % 8]}) appears more than once"
            )
        object.__setattr__(self, "nodes", nodes)
        object.__setattr__(self, "directions", directions)

    def __len__(self) -> int:
        return int(self.nodes.size)

    def __repr__(self) -> str:
        return one_line("DofTable", [("dofs", f"{len(self)} ({self.describe()})")])

    @cached_property
    def _lookup(self) -> dict[tuple[int, int], int]:
        return {
            (int(n), int(d)): i
            for i, (n, d) in enumerate(zip(self.nodes, self.directions, strict=True))
        }

    @cached_property
    def _sorted_keys(self) -> tuple[np.ndarray, np.ndarray]:
        keys = self.nodes * 8 + self.directions
        order = np.argsort(keys, kind="stable")
        return keys[order], order

    def positions(self, nodes: np.ndarray, directions: np.ndarray | int) -> np.ndarray:
        """Equation indices of many ``(node, direction code)`` pairs at once, -1 where the model
        has no such dof; ``nodes`` and ``directions`` broadcast, the result has their shape."""
        nodes, directions = np.broadcast_arrays(
            np.asarray(nodes, dtype=np.int64), np.asarray(directions, dtype=np.int64)
        )
        keys, order = self._sorted_keys
        wanted = nodes * 8 + directions
        if keys.size == 0:
            return np.full(wanted.shape, -1, dtype=np.int64)
        at = np.minimum(np.searchsorted(keys, wanted), keys.size - 1)
        return np.where(keys[at] == wanted, order[at], -1)

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

    @property
    def scalar(self) -> np.ndarray:
        """Boolean mask, shape (n_dof,): the scalar coordinates (direction ``q``)."""
        return self.directions == SCALAR

    def describe(self) -> str:
        """A one-line summary, e.g. ``"214 nodes x ux uy uz"`` or ``"4 nodes x 6 + 8 scalar"``.

        Nodes are grouped by their set of directions, largest group first.
        """
        geometric = ~self.scalar
        groups: dict[tuple[int, ...], int] = {}
        if geometric.any():
            nodes, inverse = np.unique(self.nodes[geometric], return_inverse=True)
            masks = np.zeros(nodes.size, dtype=np.int64)
            np.bitwise_or.at(masks, inverse, 1 << self.directions[geometric])
            for mask, count in zip(*np.unique(masks, return_counts=True), strict=True):
                key = tuple(d for d in range(6) if int(mask) >> d & 1)
                groups[key] = int(count)
        parts = []
        for key, count in sorted(groups.items(), key=lambda item: (-item[1], item[0])):
            names = " ".join(DIRECTIONS[d] for d in key)
            parts.append(f"{count} node{'s' if count != 1 else ''} x {names}")
        n_scalar = int(self.scalar.sum())
        if n_scalar:
            parts.append(f"{n_scalar} scalar coordinate{'s' if n_scalar != 1 else ''} (q)")
        return " + ".join(parts) if parts else "no dofs"


@dataclass(frozen=True, eq=False)
class ConstraintEquations:
    """Linear constraint equations ``q_d = G q + g`` (paper eq. 9).

    Parameters
    ----------
    dependent : ndarray of int, shape (n_d,)
        Equation indices of the dependent dofs ``q_d``.
    matrix : sparse matrix, shape (n_d, n_dof)
        ``G`` over all equations of the body. A column of a dependent dof may be non-zero
        (chained constraints); :func:`pymorembs.preparation.elimination` resolves such chains.
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
        twice = first_duplicate(dependent)
        if twice is not None:
            raise UserError(
                f"constraint equations: dof {twice} is dependent in more than one equation"
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

    def __repr__(self) -> str:
        rows = [("dependent dofs", str(len(self))), ("of dofs", str(self.matrix.shape[1])),
                ("coefficients", str(self.matrix.nnz))]  # fmt: skip
        return one_line("ConstraintEquations", rows)


#: The values each damping kind takes (the keys of a job's ``[damping]`` table besides ``kind``).
#: Written once, in :class:`~pymorembs.kinds.DampingKind`.
DAMPING_KEYS: dict[str, tuple[str, ...]] = {kind.value: kind.keys for kind in DampingKind}


@dataclass(frozen=True)
class Damping:
    """Damping model of the body.

    ``kind``, a :class:`~pymorembs.kinds.DampingKind` (its name is taken too:
    ``Damping("modal", ratio=0.02).kind is DampingKind.MODAL``):

    * ``"none"`` -- undamped (or only the explicit damping matrix of the body, if any);
    * ``"rayleigh"`` -- ``D = alpha M + beta K`` (alpha in 1/s, beta in s);
    * ``"modal"`` -- every mode gets the damping ratio ``ratio`` (dimensionless). The reduced model
      receives the viscous modal damping ``diag(2 ratio omega_i)`` in its eigenbasis; frequency
      responses of full and reduced models use the equivalent loss factor ``eta = 2 ratio`` on the
      stiffness (as FE programs do for a constant damping ratio in a full harmonic analysis),
      which equals the modal damping at every resonance.
    """

    kind: DampingKind = DampingKind.NONE
    alpha: float = 0.0
    beta: float = 0.0
    ratio: float = 0.0

    def __post_init__(self) -> None:
        name = plain(self.kind)
        kind = DampingKind.lookup(name)  # a name ("modal") is stored as its kind
        if kind is None:
            raise UserError(
                f"damping kind {described(name)} is unknown; use {choices(DampingKind)}"
            )
        object.__setattr__(self, "kind", kind)
        for name in ("alpha", "beta", "ratio"):
            value = plain(getattr(self, name))
            if isinstance(value, bool) or not isinstance(value, int | float):
                raise UserError(f"damping {name} must be a number, got {described(value)}")
            if not np.isfinite(value) or value < 0:
                raise UserError(f"damping {name} must be a finite number >= 0, got {value!r}")
            object.__setattr__(self, name, float(value))
        unused = [key for key in ("alpha", "beta", "ratio")
                  if getattr(self, key) and key not in DAMPING_KEYS[self.kind]]  # fmt: skip
        if unused:
            takes = " and ".join(DAMPING_KEYS[self.kind]) or "no values"
            raise UserError(
                f"damping {unused[0]} does not belong to kind {self.kind.value!r}, "
                f"which takes {takes}"
            )
        if self.kind == "modal" and not 0 < self.ratio < 1:
            raise UserError(f"modal damping ratio must lie in (0, 1), got {self.ratio!r}")

    def describe(self, matrix: bool = False) -> str:
        """One phrase, e.g. ``"modal, ratio 0.02"`` or ``"rayleigh, alpha 2 1/s, beta 1e-05 s"``;
        with ``matrix``, a body's explicit damping matrix is named too."""
        if self.kind is DampingKind.MODAL:
            text = f"modal, ratio {self.ratio:g}"
        elif self.kind is DampingKind.RAYLEIGH:
            text = f"rayleigh, alpha {self.alpha:g} 1/s, beta {self.beta:g} s"
        else:
            return "damping matrix" if matrix else "none"
        return f"{text} + damping matrix" if matrix else text


@dataclass(frozen=True, eq=False)
class ModelPorts:
    """Inputs and outputs that come with the model file (e.g. ``B`` and ``C`` of a ``.mat`` file).

    Parameters
    ----------
    inputs : sparse matrix, shape (n_dof, p), optional
        The input matrix ``B_e`` over all equations of the body (paper eq. 4).
    outputs : sparse matrix, shape (r, n_dof), optional
        The output matrix ``C_e``. ``None`` with ``inputs`` given means ``C = B^T``.
    input_labels, output_labels : tuple of str
        Names of the columns of ``B`` and the rows of ``C`` (default ``u1 ...``, ``y1 ...``).
    """

    inputs: sp.csr_matrix | None = None
    outputs: sp.csr_matrix | None = None
    input_labels: tuple[str, ...] = ()
    output_labels: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        for key, prefix, axis in (("inputs", "u", 1), ("outputs", "y", 0)):
            matrix = getattr(self, key)
            labels_key = "input_labels" if key == "inputs" else "output_labels"
            if matrix is None:
                if getattr(self, labels_key):
                    raise UserError(f"model ports: {labels_key} given without {key}")
                continue
            matrix = sp.csr_matrix(matrix, dtype=float)
            if not np.all(np.isfinite(matrix.data)):
                raise UserError(f"model ports: the {key} matrix has NaN or infinite entries")
            if matrix.shape[axis] == 0:
                raise UserError(f"model ports: the {key} matrix has no columns")
            labels = tuple(str(x) for x in getattr(self, labels_key))
            if not labels:
                labels = tuple(f"{prefix}{k + 1}" for k in range(matrix.shape[axis]))
            if len(labels) != matrix.shape[axis]:
                raise UserError(f"model ports: {len(labels)} labels for {matrix.shape[axis]} {key}")
            object.__setattr__(self, key, matrix)
            object.__setattr__(self, labels_key, labels)
        if self.inputs is None and self.outputs is not None:
            raise UserError("model ports: an output matrix C needs an input matrix B")

    def __repr__(self) -> str:
        rows = [("inputs", port_labels(self.input_labels))]
        if self.outputs is not None:
            rows.append(("outputs", port_labels(self.output_labels)))
        return one_line("ModelPorts", rows)

    def check(self, n_dof: int) -> None:
        """Raise :class:`UserError` unless the matrices fit a body of ``n_dof`` equations."""
        if self.inputs is not None and self.inputs.shape[0] != n_dof:
            raise UserError(
                f"model ports: B has {self.inputs.shape[0]} rows but the model has {n_dof} dofs"
            )
        if self.outputs is not None and self.outputs.shape[1] != n_dof:
            raise UserError(
                f"model ports: C has {self.outputs.shape[1]} columns but the model has {n_dof} dofs"
            )


#: Element types an :class:`ElementMesh` can hold, with their number of nodes (the solid kinds
#: of :mod:`pymorembs.elements.solid` and the two-node beam).
ELEMENT_NODES = {"hex20": 20, "hex20r": 20, "hex8": 8, "tet10": 10, "tet4": 4, "beam2": 2}
#: The note of a body whose file's elements give no :class:`ElementMesh` starts with this
#: (the readers write it, :func:`mesh_problem` finds it).
NO_MESH = "no element mesh for geometric stiffening: "


@dataclass(frozen=True, eq=False)
class ElementMesh:
    """Solid elements of a body and their isotropic linear-elastic material.

    What the geometric stiffening of the body needs (the stresses of a load case and the
    initial-stress matrix of each element); the body's own matrices are not rebuilt from it.

    Attributes
    ----------
    element : str
        Element type, a key of :data:`ELEMENT_NODES`: a solid kind of
        :mod:`pymorembs.elements.solid` (``"hex20"``: 20-node hexahedra in the node order of
        :data:`pymorembs.elements.hex20.HEX20_NODES`, 27 Gauss points; ``"hex20r"``: the same
        with 8; ``"hex8"``, ``"tet4"``, ``"tet10"``), or ``"beam2"``: the two-node beams of
        :mod:`pymorembs.elements.beam`, nodes with all six dofs.
    connectivity : ndarray of int, shape (n_el, nodes per element)
        Node ids of each element.
    young, poisson : float or ndarray, shape (n_el,)
        Young's modulus (model stress unit, N/m² in SI) and Poisson's ratio: one material, or
        one per element (solids of several materials).
    section : BeamSection, optional
        The cross-section of ``"beam2"`` elements (required for them).
    up : (3,) float, optional
        The beams' orientation vector (default that of :mod:`pymorembs.elements.beam`).
    element_ids : ndarray of int, shape (n_el,), optional
        The element numbers of the FE program (distinct), in the order of ``connectivity``;
        default ``1 .. n_el`` (readers fill them where the file numbers its elements). Stress
        outputs name their points by them (:mod:`pymorembs.stress`).
    """

    element: str
    connectivity: np.ndarray
    young: float | np.ndarray
    poisson: float | np.ndarray
    section: BeamSection | None = None
    up: tuple[float, float, float] | None = None
    element_ids: np.ndarray | None = None

    def __repr__(self) -> str:
        materials = "one material" if np.ndim(self.young) == 0 else "a material per element"
        rows = [("elements", f"{self.connectivity.shape[0]} x {self.element}"),
                ("nodes", str(sorted_unique(self.connectivity).size)),
                ("material", materials)]  # fmt: skip
        return one_line("ElementMesh", rows)

    def __post_init__(self) -> None:
        if self.element not in ELEMENT_NODES:
            raise UserError(
                f"element mesh: unknown element type {self.element!r}; "
                f"known: {', '.join(ELEMENT_NODES)}"
            )
        connectivity = np.asarray(self.connectivity, dtype=np.int64)
        if connectivity.ndim != 2 or connectivity.shape[1] != ELEMENT_NODES[self.element]:
            raise UserError(
                f"element mesh: {self.element} connectivity must have "
                f"{ELEMENT_NODES[self.element]} columns, got shape {connectivity.shape}"
            )
        for key in ("young", "poisson"):
            value = np.asarray(getattr(self, key), dtype=float)
            if value.ndim == 0:
                object.__setattr__(self, key, float(value))
            elif value.shape == (connectivity.shape[0],) and self.element != "beam2":
                object.__setattr__(self, key, value.copy())
            else:
                raise UserError(
                    f"element mesh: {key} must be one number or one per element "
                    f"({connectivity.shape[0]}), got shape {value.shape}"
                )
        young, poisson = np.asarray(self.young), np.asarray(self.poisson)
        bad = ~(np.isfinite(young) & (young > 0)) | ~(
            np.isfinite(poisson) & (-1.0 < poisson) & (poisson < 0.5)
        )
        if np.any(bad):
            k = np.unravel_index(int(np.flatnonzero(bad)[0]), np.shape(bad)) if bad.ndim else ()
            raise UserError(
                f"element mesh: material E = {np.broadcast_to(young, bad.shape)[k]!r}, nu = "
                f"{np.broadcast_to(poisson, bad.shape)[k]!r} is not an isotropic elastic "
                "material (E > 0, -1 < nu < 0.5)"
            )
        if self.element == "beam2" and self.section is None:
            raise UserError("element mesh: beam2 elements need their cross-section")
        object.__setattr__(self, "connectivity", connectivity)
        n_el = connectivity.shape[0]
        if self.element_ids is None:
            ids = np.arange(1, n_el + 1, dtype=np.int64)
        else:
            ids = np.array(self.element_ids, dtype=np.int64).ravel()
            if ids.shape != (n_el,) or np.unique(ids).size != n_el:
                raise UserError(
                    f"element mesh: element_ids must be {n_el} distinct numbers, one per "
                    f"element, got {ids.size} ({np.unique(ids).size} distinct)"
                )
        object.__setattr__(self, "element_ids", ids)


def set_names(sets: dict[str, np.ndarray], first: int = 5) -> str:
    """``"3 (CLAMP, TIP, ALL)"``: how many sets and the names of the first few."""
    names = list(sets)
    listed = ", ".join(names[:first]) + (", ..." if len(names) > first else "")
    return f"{len(names)} ({listed})"


def _checked_node_sets(sets: dict[str, np.ndarray], node_ids: np.ndarray) -> dict[str, np.ndarray]:
    """The node sets keyed by upper-case name, each sorted and without repeats.

    Raises
    ------
    UserError
        A name given twice (in any case), or a set that holds an id which is not a node.
    """
    out: dict[str, np.ndarray] = {}
    for name, members in dict(sets).items():
        key = str(name).strip().upper()
        if not key or key in out:
            raise UserError(f"node sets: the name {name!r} is empty or given twice")
        ids = sorted_unique(np.asarray(members, dtype=np.int64).ravel())
        missing = missing_from(ids, node_ids)
        if missing.size:
            raise UserError(f"node set {key}: node {missing[0]} is not in the node list")
        out[key] = ids
    return out


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
    has_coordinates : bool
        Whether ``coordinates`` are the model's (``False``: the file gave none and every node
        lies at the origin, so geometry -- rigid-body fields, Buckens frame, interface search,
        unit detection -- is not available).
    notes : tuple of str
        What the reader assumed or derived, one sentence each (e.g. how it built the dof
        table); shown by ``pymorembs info``.
    ports : ModelPorts, optional
        Inputs and outputs that came with the model file.
    mesh : ElementMesh, optional
        The solid elements (built-in solid models), for geometric stiffening.
    surface : Surface, optional
        What a viewer draws of the body (outer faces and line elements,
        :func:`pymorembs.surface.outer_surface`); ``None``: the file held no elements, the
        nodes are drawn as points.
    precision : float, optional
        Relative rounding of the matrix entries as the file stores them, when the reader knows
        it (single-precision binary ``2^-24``, decimal text of ``d`` digits ``0.5 * 10^(1 - d)``;
        entries transformed after reading, e.g. rotated to the basic system, no longer show
        it). ``None``: told from the values (:func:`pymorembs.linalg.rounding.relative_rounding`).
    nodes_near_supports : ndarray of int, optional
        What only a reader of an FE program's element assembly knows: the ids of the support
        nodes (with fixed dofs) and of the nodes that share an element with one (empty for a
        free body). Their rows carry the supports' reactions; every other row of such a
        stiffness (no prestress, no spring that resists rigid rotation) must fit the rigid-body
        fields, so the consistency check refuses a map they refute there
        (:func:`pymorembs.preparation.consistency.check_map`). ``None``: the supports' reach is
        judged by distance and rows that only the rotations fail are a warning.
    node_sets : dict of str -> ndarray of int, optional
        Named sets of node ids that came with the model file (Abaqus/CalculiX ``*NSET``, Ansys
        node components), keyed by upper-case name (the FE programs treat set names without
        case); each set sorted, every id a node of the body. Hot spots may name them
        (:class:`pymorembs.preparation.StressSpec`). Empty: the file gave none.
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
    has_coordinates: bool = True
    notes: tuple[str, ...] = ()
    ports: ModelPorts | None = None
    precision: float | None = None
    mesh: ElementMesh | None = None
    surface: Surface | None = None
    nodes_near_supports: np.ndarray | None = None
    node_sets: dict[str, np.ndarray] = field(default_factory=dict)

    def __post_init__(self) -> None:
        node_ids = np.asarray(self.node_ids, dtype=np.int64).ravel()
        coordinates = np.asarray(self.coordinates, dtype=float)
        if coordinates.shape != (node_ids.size, 3):
            raise UserError(
                f"nodes: {node_ids.size} ids but coordinates of shape {coordinates.shape}, "
                f"expected ({node_ids.size}, 3)"
            )
        twice = first_duplicate(node_ids)
        if twice is not None:
            raise UserError(f"nodes: node id {twice} appears more than once")
        if not np.all(np.isfinite(coordinates)):
            raise UserError("nodes: coordinates must be finite")
        n = len(self.dofs)
        scalar = self.dofs.scalar
        missing = missing_from(self.dofs.nodes[~scalar], node_ids)
        if missing.size:
            raise UserError(f"dof table names node {missing[0]} which is not in the node list")
        clash = sorted_unique(self.dofs.nodes[scalar][np.isin(self.dofs.nodes[scalar], node_ids)])
        if clash.size:
            raise UserError(
                f"dof table: scalar coordinate {clash[0]} has the id of a node; scalar points "
                "and nodes need distinct ids"
            )
        if self.ports is not None:
            self.ports.check(n)
        if self.mesh is not None:
            translational = self.dofs.nodes[self.dofs.directions < 3]
            missing = missing_from(sorted_unique(self.mesh.connectivity.ravel()), translational)
            if missing.size:
                raise UserError(
                    f"element mesh: node {missing[0]} of an element has no translational dofs "
                    "in the dof table"
                )
        if self.surface is not None:
            self.surface.check_nodes(node_ids)
        if self.precision is not None and not (
            np.isfinite(self.precision) and 0 < self.precision < 1
        ):
            raise UserError(f"precision of the entries must lie in (0, 1), got {self.precision!r}")
        matrices = {"mass": self.mass, "stiffness": self.stiffness}
        if self.damping_matrix is not None:
            matrices["damping"] = self.damping_matrix
        for label, matrix in matrices.items():
            matrix = sp.csr_matrix(matrix, dtype=float)
            if matrix.shape != (n, n):
                raise UserError(
                    f"{label} matrix has shape {matrix.shape} but the dof table has {n} rows"
                )
            with np.errstate(over="ignore", invalid="ignore"):
                total = np.sum(matrix.data)  # finite only if every entry is (no temporary)
            if not np.isfinite(total) and not np.all(np.isfinite(matrix.data)):
                raise UserError(f"{label} matrix has NaN or infinite entries")
            if not matrix.has_canonical_format:  # on a copy: the caller's arrays stay as given
                matrix = matrix.copy()
                matrix.sum_duplicates()
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
        fixed = sorted_unique(np.asarray(self.fixed, dtype=np.int64))
        if fixed.size and (fixed[0] < 0 or fixed[-1] >= n):
            raise UserError("fixed dofs: an index lies outside the dof table")
        object.__setattr__(self, "node_ids", node_ids)
        object.__setattr__(self, "coordinates", coordinates)
        object.__setattr__(self, "constraints", constraints)
        object.__setattr__(self, "fixed", fixed)
        if self.nodes_near_supports is not None:
            near = sorted_unique(np.asarray(self.nodes_near_supports, dtype=np.int64).ravel())
            object.__setattr__(self, "nodes_near_supports", near)
        object.__setattr__(self, "notes", tuple(str(note) for note in self.notes))
        object.__setattr__(self, "node_sets", _checked_node_sets(self.node_sets, node_ids))

    # ----------------------------------------------------------------- facts
    def summary(self) -> list[tuple[str, str]]:
        """The facts ``repr`` and a notebook show, as (label, text) rows: nodes, dofs,
        dependent and fixed dofs, damping, elements, surface, ports and notes of the file."""
        nodes = f"{self.n_nodes}" + ("" if self.has_coordinates else " (no coordinates)")
        damping = self.damping.describe(matrix=self.damping_matrix is not None)
        rows = [
            ("nodes", nodes),
            ("dofs", f"{self.n_dof} ({self.dofs.describe()})"),
            ("dependent", str(len(self.constraints))),
            ("fixed", str(self.fixed.size)),
            ("damping", damping),
        ]
        if self.mesh is not None:
            rows.append(("elements", f"{self.mesh.connectivity.shape[0]} x {self.mesh.element}"))
        if self.surface is not None:
            rows.append(("surface", f"{self.surface.triangles.shape[0]} triangles, "
                                    f"{self.surface.lines.shape[0]} lines"))  # fmt: skip
        if self.node_sets:
            rows.append(("node sets", set_names(self.node_sets)))
        if self.ports is not None:
            rows.append(("ports of the file", port_labels(self.ports.input_labels) + " inputs"))
        if self.notes:
            rows.append(("notes", str(len(self.notes))))
        return rows

    def __repr__(self) -> str:
        return one_line(f"ElasticBody {self.name!r}", self.summary())

    def _repr_html_(self) -> str:
        return html_table(f"ElasticBody {self.name!r}", self.summary())

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

    @cached_property
    def _node_order(self) -> np.ndarray:
        return np.argsort(self.node_ids)

    def node_rows(self, ids: np.ndarray) -> np.ndarray:
        """Rows in :attr:`coordinates` of node ids (any shape; all must be nodes of the body)."""
        order = self._node_order
        return order[np.searchsorted(self.node_ids, np.asarray(ids), sorter=order)]

    def dof_positions(self) -> np.ndarray:
        """The position of the node of each equation, shape (n_dof, 3); scalar coordinates: 0."""
        out = np.zeros((self.n_dof, 3))
        geometric = ~self.dofs.scalar
        if geometric.any():
            out[geometric] = self.coordinates[self.node_rows(self.dofs.nodes[geometric])]
        return out

    def rigid_body_modes(self, origin: np.ndarray | None = None) -> np.ndarray:
        """The six rigid-body displacement fields over all equations, shape (n_dof, 6).

        Columns: translations x, y, z, then rotations about x, y, z through ``origin``
        (default: the coordinate origin). For a rotation ``theta`` the translation of a node at
        ``r`` is ``theta x (r - origin)`` and its rotational dofs equal ``theta``. Scalar
        coordinates do not take part (their rows are zero). Without coordinates
        (``has_coordinates`` false) the rotation columns are not the body's rotations.
        """
        origin = np.zeros(3) if origin is None else np.asarray(origin, dtype=float)
        geometric = ~self.dofs.scalar
        r = self.dof_positions()
        r[geometric] -= origin
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

    def rigid_body_residuals(self) -> np.ndarray:
        """How far the geometric rigid-body fields are from the null space of ``K``, shape (6,).

        ``|K r_j| / (|K|_inf |r_j|)`` for the six fields of :meth:`rigid_body_modes` about the
        centroid of the nodes, over the rows of the dofs that are not fixed (all columns: a
        file that keeps the couplings of fixed dofs, such as Abaqus with its penalty diagonals,
        is checked as it stands). NaN for a field without entries, e.g. rotations of a model
        without rotational dofs and without coordinates. A dof table and coordinates that
        belong to the matrices give values at the rounding level of the file (1e-16 to 1e-9);
        a wrong equation order or wrong coordinates give values of 1e-4 and more. This is the
        check the readers use to prove an equation order they derived.
        """
        centre = self.coordinates.mean(axis=0) if self.n_nodes else np.zeros(3)
        modes = self.rigid_body_modes(centre)
        rows = np.ones(self.n_dof, dtype=bool)
        rows[self.fixed] = False
        stiffness = self.stiffness if rows.all() else self.stiffness[rows]  # no copy if all
        scale = float(abs_row_sums(stiffness).max()) if stiffness.nnz else 0.0
        norms = np.linalg.norm(modes, axis=0)
        out = np.full(6, np.nan)
        if scale == 0.0:
            return out
        present = norms > 0
        residual = np.linalg.norm(stiffness @ modes[:, present], axis=0)
        out[present] = residual / (scale * norms[present])
        return out

    def total_mass(self) -> float:
        """Mass of the body (model unit), from rigid translations: mean of ``t_i^T M t_i``."""
        modes = self.rigid_body_modes()[:, :3]
        masses = np.einsum("ij,ij->j", modes, self.mass @ modes)
        return float(np.mean(masses))

    def with_node_sets(self, sets: dict[str, np.ndarray]) -> ElasticBody:
        """The body with the named node sets of its file (:attr:`node_sets`), each keeping the
        ids that are nodes of the body (a deck's set may name nodes the matrices left out)."""
        kept = {name: ids[np.isin(ids, self.node_ids)] for name, ids in sets.items()}
        return replace(self, node_sets={**self.node_sets, **kept})

    # -------------------------------------------------------- transformations
    def translated(self, origin: np.ndarray) -> ElasticBody:
        """The same body with coordinates measured from ``origin`` (shape (3,))."""
        return replace(self, coordinates=self.coordinates - np.asarray(origin, dtype=float))

    def with_notes(self, *notes: str) -> ElasticBody:
        """The same body with more notes (nothing else changes, so nothing is checked again:
        the checks of a large body cost more than reading a note)."""
        out = copy.copy(self)
        object.__setattr__(out, "notes", (*self.notes, *(str(note) for note in notes)))
        return out

    def with_surface(self, surface: Surface | None) -> ElasticBody:
        """The same body with another surface (only the surface's nodes are checked)."""
        if surface is not None:
            surface.check_nodes(self.node_ids)
        out = copy.copy(self)
        object.__setattr__(out, "surface", surface)
        return out

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


def mesh_problem(body: ElasticBody) -> str | None:
    """The reason a reader noted why the body has no :class:`ElementMesh` (after
    :data:`NO_MESH`), or None."""
    for note in body.notes:
        if note.startswith(NO_MESH):
            return note[len(NO_MESH) :]
    return None
