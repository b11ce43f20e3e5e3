"""Stress and strain modes of a reduced body: the stress of every column it carries.

A reduced body moves its nodes by ``u = V q`` (eq. 18: ``V`` on all dofs of the prepared body);
the stress at a point is a sparse row of the mesh's stress operator times ``u``
(:func:`pymorembs.stress.stress_operator`), so the stress of the body is ``S V q``: column ``j``
of ``S V`` is the *stress mode* of modal coordinate ``q_j``, and ``S u_static`` the stress of a
static response to a unit input. :class:`StressModes` holds the body, the columns (the shape
functions, then the static responses) and the sparse operators, and forms ``S`` times a block of
columns when a writer asks for it, so that no dense array larger than what is written is held:

* the VTU writes the nodal stress and strain tensors and the von Mises stress of every column
  (:func:`~pymorembs.export.vtu.write_vtu`);
* the Exudyn body holds the nodal stresses of its mesh nodes as ``outputVariableModeBasis``
  (:func:`exudyn_stress_basis`);
* the recovery file holds everything at integration points and nodes
  (:mod:`pymorembs.export.recovery`);
* the report and the app show the von Mises stress of the first modes.

Units are those of the FE model: a stress mode is a stress per unit modal coordinate (``q`` of
the exported bodies, for the mass-normalised basis of ``docs/bodies.md``), a static column a
stress per unit input (per N, per N m, per unit frame acceleration, as for the static responses
of :func:`~pymorembs.export.vtu.static_fields`). Components come in the operator's order
(``xx yy zz xy xz yz``, CalculiX's S11 S22 S33 S12 S13 S23); strains as tensor components
(``eps_xy = gamma_xy / 2``), as the operator gives them.

A body without solid elements (beams, plain matrices) has no stress modes:
:func:`stress_modes` returns None and :func:`stress_modes_note` says why (with the reader's reason
where it gave one). The VTU and the Exudyn body are then written without stresses, the recovery
file without points and with the note; nothing fails for it.
"""

from __future__ import annotations

import dataclasses
import hashlib
import weakref
from collections.abc import Iterator, Mapping, Sequence

import numpy as np
import scipy.sparse as sp

from pymorembs.arrays import sorted_unique
from pymorembs.body import ElasticBody, mesh_problem
from pymorembs.elements.solid import SOLID_KINDS
from pymorembs.stress import StressOperator, stress_operator, von_mises

__all__ = [
    "EXUDYN_ORDER",
    "VTK_ORDER",
    "StressModes",
    "exudyn_stress_basis",
    "node_points",
    "nodes_operator",
    "strain_operator",
    "stress_modes",
    "stress_modes_note",
    "von_mises_at",
]

#: Nodal operators built for a body's node sets, kept while the body lives: a job writes an
#: Exudyn body (and a VTU) per reduction, all on the same prepared body and the same nodes.
_NODE_OPERATORS: weakref.WeakKeyDictionary[ElasticBody, dict[tuple[str, str], StressOperator]] = (
    weakref.WeakKeyDictionary()
)

#: Columns of the operator's order (xx yy zz xy xz yz) in Exudyn's (xx yy zz yz xz xy).
EXUDYN_ORDER = np.array([0, 1, 2, 5, 4, 3])
#: Columns of the operator's order in VTK's order of a symmetric tensor (xx yy zz xy yz xz).
VTK_ORDER = np.array([0, 1, 2, 3, 5, 4])
#: Columns of ``S V`` formed at once (memory: 6 x points x block floats).
BLOCK = 8


def stress_modes_note(body: ElasticBody) -> str | None:
    """Why ``body`` has no stress modes, or None if it has (solid elements with a material)."""
    if body.mesh is None:
        why = mesh_problem(body)
        return (
            f"body {body.name!r} has no element mesh" + (f" ({why})" if why else "")
            + ": no stress or strain modes are written"
        )  # fmt: skip
    if body.mesh.element not in SOLID_KINDS:
        return (
            f"body {body.name!r}: stresses are not supported for {body.mesh.element} elements: "
            "no stress or strain modes are written"
        )
    return None


class StressModes:
    """The stress and strain of each column of a reduced body, formed block by block.

    Parameters
    ----------
    body : ElasticBody
        The prepared body (coordinates in the reference frame) with its solid mesh.
    columns : ndarray, shape (n_dof, k)
        The shape functions on all dofs (eq. 18), then the static responses.
    labels : sequence of str
        One per column: ``"1"`` ... ``"m"`` for the shape functions (the modal coordinates of
        the exported bodies, in their order), the input label (``"1:ux"``, ``"inertia:ax"``)
        for a static response.
    n_shapes : int
        How many of the columns are shape functions (the first ones).

    Attributes
    ----------
    body, columns, labels, n_shapes
        As given.
    """

    def __init__(
        self, body: ElasticBody, columns: np.ndarray, labels: Sequence[str], n_shapes: int
    ) -> None:
        self.body = body
        self.columns = np.asarray(columns, dtype=float)
        self.labels = tuple(str(label) for label in labels)
        self.n_shapes = int(n_shapes)
        if self.columns.shape != (body.n_dof, len(self.labels)):
            raise ValueError(
                f"stress modes: columns of shape {self.columns.shape} for {len(self.labels)} "
                f"labels over {body.n_dof} dofs"
            )
        self._operators: dict[tuple[str, str], StressOperator] = {}

    @property
    def count(self) -> int:
        """The number of columns ``k``."""
        return len(self.labels)

    def operator(self, location: str, quantity: str = "stress") -> StressOperator:
        """The sparse operator of the whole mesh at ``location`` (``"integration"`` or
        ``"nodes"``) for ``quantity`` (``"stress"`` or ``"strain"``), built once.

        The strains of a body of one material are its stresses through the compliance,
        point by point (:func:`strain_operator`), which costs a sparse product instead of a
        second assembly; with a material per element they are assembled.
        """
        key = (location, quantity)
        if key not in self._operators:
            mesh = self.body.mesh
            if quantity == "strain" and np.ndim(mesh.young) == 0 and np.ndim(mesh.poisson) == 0:
                stress = self.operator(location, "stress")
                operator = strain_operator(stress, float(mesh.young), float(mesh.poisson))
            else:
                operator = stress_operator(self.body, location=location, quantity=quantity)
            self._operators[key] = operator
        return self._operators[key]

    def node_operator(self, nodes: np.ndarray, quantity: str = "stress") -> StressOperator:
        """The nodal operator on the mesh nodes among ``nodes``: the rows of the whole mesh's
        when that is built already, else built for them alone (cost in proportion to them)."""
        ids = np.intersect1d(np.asarray(nodes, dtype=np.int64), self.mesh_nodes)
        whole = self._operators.get(("nodes", quantity))
        if whole is None:
            return nodal_operator(self.body, ids, quantity)
        points = np.flatnonzero(np.isin(whole.node_ids, ids))
        rows = (6 * points[:, None] + np.arange(6)).ravel()
        return dataclasses.replace(
            whole,
            matrix=whole.matrix[rows],
            coordinates=whole.coordinates[points],
            element_ids=whole.element_ids[points],
            node_ids=whole.node_ids[points],
            point_numbers=whole.point_numbers[points],
        )

    @property
    def mesh_nodes(self) -> np.ndarray:
        """The node ids of the solid elements, sorted."""
        return sorted_unique(self.body.mesh.connectivity.ravel())

    def blocks(
        self, operator: StressOperator, columns: Sequence[int] | None = None
    ) -> Iterator[tuple[np.ndarray, np.ndarray]]:
        """``(indices, values)`` per block of at most :data:`BLOCK` columns, one block formed at
        a time: ``values`` of shape (len(indices), n_points, 6), the operator applied to those
        columns."""
        chosen = np.arange(self.count) if columns is None else np.asarray(columns, dtype=np.int64)
        for part in np.array_split(chosen, max(1, -(-chosen.size // BLOCK))):
            if part.size:
                yield part, self.values(operator, part)

    def values(self, operator: StressOperator, columns: Sequence[int]) -> np.ndarray:
        """The operator applied to ``columns``: shape (len(columns), n_points, 6)."""
        part = self.columns[:, np.asarray(columns, dtype=np.int64)]
        return np.moveaxis(operator(part), 2, 0)


def nodal_operator(
    body: ElasticBody, nodes: np.ndarray, quantity: str = "stress"
) -> StressOperator:
    """The nodal operator of ``body`` on the mesh nodes ``nodes`` (sorted ids), built once per
    body and node set (the body's later calls get the same operator; do not modify it)."""
    ids = np.ascontiguousarray(nodes, dtype=np.int64)
    key = (quantity, hashlib.sha1(ids.tobytes()).hexdigest())
    built = _NODE_OPERATORS.setdefault(body, {})
    if key not in built:
        built[key] = stress_operator(body, location="nodes", quantity=quantity, nodes=ids)
    return built[key]


def strain_operator(stress: StressOperator, young: float, poisson: float) -> StressOperator:
    """The strain operator of a body of one isotropic material from its stress operator.

    Point by point ``eps = C^-1 sigma``: ``eps_xx = (s_xx - nu (s_yy + s_zz)) / E`` (likewise
    yy, zz) and the tensor shear ``eps_xy = s_xy (1 + nu) / E`` (the operator's convention,
    :mod:`pymorembs.stress`), as a block-diagonal sparse product: exact for the integration
    points and for the nodes' averages alike (both are linear in the stresses).

    Parameters
    ----------
    stress : StressOperator
        Of ``quantity`` ``"stress"``.
    young, poisson : float
        The material (model stress unit, -).

    Returns
    -------
    StressOperator
        The same points, ``quantity`` ``"strain"``.
    """
    compliance = np.zeros((6, 6))
    compliance[:3, :3] = -poisson / young
    compliance[np.arange(3), np.arange(3)] = 1.0 / young
    compliance[np.arange(3, 6), np.arange(3, 6)] = (1.0 + poisson) / young
    blocks = sp.kron(sp.identity(stress.n_points, format="csr"), sp.csr_matrix(compliance))
    return dataclasses.replace(stress, matrix=sp.csr_matrix(blocks @ stress.matrix),
                               quantity="strain")  # fmt: skip


def stress_modes(
    body: ElasticBody, shapes: np.ndarray, static: Mapping[str, np.ndarray] | None = None
) -> StressModes | None:
    """The stress and strain modes of a reduced body, or None for a body without solids.

    Parameters
    ----------
    body : ElasticBody
        The prepared body.
    shapes : ndarray, shape (n_dof, m)
        The basis ``V`` on all dofs (eq. 18).
    static : dict of str to ndarray (n_dof,), optional
        Input label -> static response to a unit input
        (:func:`~pymorembs.export.vtu.static_fields`).

    Returns
    -------
    StressModes or None
        None when :func:`stress_modes_note` has a note for ``body``.
    """
    if stress_modes_note(body) is not None:
        return None
    shapes = np.asarray(shapes, dtype=float)
    static = dict(static or {})
    columns = np.column_stack([shapes, *static.values()]) if static else shapes
    labels = [str(k) for k in range(1, shapes.shape[1] + 1)] + list(static)
    return StressModes(body, columns, labels, shapes.shape[1])


def exudyn_stress_basis(modes: StressModes, mesh_node_ids: np.ndarray) -> np.ndarray:
    """Exudyn's ``outputVariableModeBasis`` of ``StressLocal``: the nodal stress modes.

    Parameters
    ----------
    modes : StressModes
        Its shape functions (the first ``n_shapes`` columns) are the body's modes.
    mesh_node_ids : ndarray of int, shape (n_mesh,)
        The node each Exudyn mesh node belongs to (``meshNodeIds`` of the archive). A mesh node
        whose node has no solid element (a reference node, a satellite point) gets 0.

    Returns
    -------
    ndarray, shape (n_mesh, 6 * n_shapes)
        Row i: mesh node i; column ``6 j + c``: component c of mode j in Exudyn's order
        ``xx yy zz yz xz xy`` (:data:`EXUDYN_ORDER`), so that Exudyn's ``StressLocal`` of a
        mesh node is ``sum_j q_j X[i, 6 j : 6 j + 6]``. A satellite point of a frame node
        (a point of a rigid cross, not of the body) gets 0 too.
    """
    ids = np.asarray(mesh_node_ids, dtype=np.int64)
    operator = modes.node_operator(sorted_unique(ids))
    basis = np.zeros((ids.size, 6 * modes.n_shapes))
    if operator.n_points == 0 or modes.n_shapes == 0:
        return basis
    # the first occurrence of each node id: the node itself (satellites follow their node)
    _, first = np.unique(ids, return_index=True)
    have, point = node_points(operator, ids[first])
    rows = first[have]
    for part, values in modes.blocks(operator, range(modes.n_shapes)):
        # values (c, n_points, 6) -> rows, columns 6 j + comp
        block = values[:, point][:, :, EXUDYN_ORDER]  # (c, rows, 6)
        for j, column in enumerate(part):
            basis[rows, 6 * column : 6 * column + 6] = block[j]
    return basis


def nodes_operator(body: ElasticBody, nodes: np.ndarray) -> StressOperator | None:
    """The nodal stress operator on the mesh nodes among ``nodes`` (cost in proportion to them),
    e.g. those a view draws; None for a body without solid elements (:func:`stress_modes_note`).
    """
    if stress_modes_note(body) is not None:
        return None
    wanted = np.intersect1d(np.asarray(nodes, dtype=np.int64), body.mesh.connectivity)
    return stress_operator(body, location="nodes", nodes=wanted)


def node_points(operator: StressOperator, nodes: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Where ``nodes`` are among the points of a nodal ``operator``: a mask over ``nodes`` (the
    node is a point) and, for those, the point indices."""
    ids = np.asarray(nodes, dtype=np.int64)
    have = np.isin(ids, operator.node_ids)
    order = np.argsort(operator.node_ids)
    return have, order[np.searchsorted(operator.node_ids, ids[have], sorter=order)]


def von_mises_at(operator: StressOperator, vectors: np.ndarray, nodes: np.ndarray) -> np.ndarray:
    """The von Mises stress of displacement fields at ``nodes`` (averaged nodal stresses).

    Parameters
    ----------
    operator : StressOperator
        A nodal stress operator (:func:`nodes_operator`).
    vectors : ndarray, shape (n_dof, k)
        Displacement fields over the body's dofs (a basis column: per unit modal coordinate).
    nodes : ndarray of int, shape (n,)
        Node ids.

    Returns
    -------
    ndarray, shape (n, k)
        In the model's stress unit; 0 at a node that is not a point of ``operator`` (a node of
        no solid element).
    """
    vectors = np.asarray(vectors, dtype=float)
    have, points = node_points(operator, nodes)
    out = np.zeros((have.size, vectors.shape[1]))
    if points.size:
        out[have] = von_mises(operator(vectors), axis=1)[points]
    return out
