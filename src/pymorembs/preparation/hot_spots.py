"""Hot spots: the points of a body whose stresses become outputs of the reduction.

A stress at a point is a sparse row of the mesh's stress operator times the displacements
(:mod:`pymorembs.stress`), so the six components at each hot spot are six further outputs
``y_s = C_s q`` of the prepared system (:attr:`~pymorembs.system.SecondOrderSystem.stress_matrix`,
sparse, on the independent dofs: ``C_s = S T`` with the elimination map ``T``). The transfer
function, the error of eq. 27 (``eps_s``), SOAGA's estimator and, when the stresses are targeted,
the reduction methods then see them like the ports.

Hot spots are given (node ids, element ids, a box, node sets of the model file) or found: the
``count`` points of highest von Mises stress in the static responses to every input (ports and
inertia loads), from one factorization of the stiffness. Each input's von Mises field is taken
relative to its own largest value over the body, so a moment input (N mm) and a force (N) count
alike; a point's score is its largest relative value over the inputs.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Any

import numpy as np
import scipy.sparse as sp

from pymorembs.arrays import missing_from
from pymorembs.body import ElasticBody
from pymorembs.errors import UserError
from pymorembs.stress import StressOperator, stress_operator, von_mises

#: Where the stresses of hot spots are taken (:func:`pymorembs.stress.stress_operator`).
LOCATIONS = ("integration", "nodes")
#: How messages name the spec: the job's table, whose keys are the spec's fields.
WHERE = "[stress]"
#: Hot spots found when none are given.
DEFAULT_COUNT = 10
#: Elements (nodes) per block when every point of the mesh is scored: the memory of one
#: block's stress rows.
BLOCK_SIZE = 20_000


@dataclass(frozen=True)
class StressSpec:
    """Which hot spots get stress outputs, and whether the reduction aims at them.

    Attributes
    ----------
    nodes : tuple of int
        Node ids: the stresses averaged at these nodes (``location = "nodes"``), or at the
        integration points of the elements around them (``"integration"``).
    elements : tuple of int
        Element ids (``body.mesh.element_ids``): their integration points, or their nodes.
    box : ((x, y, z), (x, y, z)) or None
        Lower and upper corner (model length unit): the elements whose centroid lies inside,
        or the nodes inside.
    sets : tuple of str
        Names of node sets of the body (:attr:`~pymorembs.body.ElasticBody.node_sets`, the deck's
        ``*NSET`` or Ansys node components; any case): their nodes, taken like ``nodes``.
    count : int
        With none of the above: this many points of highest von Mises stress in the static
        responses to every input (module docstring).
    location : {"integration", "nodes"}
        Integration points of the elements, or nodes (extrapolated and averaged).
    target : bool
        Aim the reductions at the stress outputs too
        (:attr:`~pymorembs.system.SecondOrderSystem.stress_targeted`): SOAGA's stopping estimate,
        the Gramians' own stress block, the POD's outputs, the best modes' eq. 26; Krylov, the
        lowest modes and Craig-Bampton leave their basis as it is
        (:func:`~pymorembs.reduction.aims_at_stresses`).
    """

    nodes: tuple[int, ...] = ()
    elements: tuple[int, ...] = ()
    box: tuple[tuple[float, float, float], tuple[float, float, float]] | None = None
    count: int = DEFAULT_COUNT
    location: str = "integration"
    target: bool = False
    sets: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        if self.location not in LOCATIONS:
            raise UserError(
                f"{WHERE}.location: must be one of {', '.join(LOCATIONS)}, got {self.location!r}"
            )
        if isinstance(self.count, bool) or not isinstance(self.count, int) or self.count < 1:
            raise UserError(f"{WHERE}.count: must be a whole number >= 1, got {self.count!r}")
        sets = (self.sets,) if isinstance(self.sets, str) else tuple(self.sets)
        if not all(isinstance(name, str) and name.strip() for name in sets):
            raise UserError(f"{WHERE}.sets: must be a list of node set names, got {self.sets!r}")
        object.__setattr__(self, "sets", tuple(name.strip().upper() for name in sets))

    @property
    def automatic(self) -> bool:
        """No hot spots given: they are found (:data:`DEFAULT_COUNT` or ``count``)."""
        return not self.nodes and not self.elements and self.box is None and not self.sets


@dataclass(frozen=True, eq=False)
class HotSpots:
    """The hot spots of a prepared model and how they were chosen.

    Attributes
    ----------
    operator : StressOperator
        The stress rows at the hot spots, on all dofs of the body.
    chosen : str
        ``"given"`` or ``"highest von Mises"``.
    target : bool
        Whether the reductions aim at them.
    weight : float
        :attr:`~pymorembs.system.SecondOrderSystem.stress_weight`.
    """

    operator: StressOperator
    chosen: str
    target: bool
    weight: float

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready description for the summary (``model.stress``)."""
        op = self.operator
        return {
            "points": int(op.n_points),
            "outputs": int(6 * op.n_points),
            "location": op.location,
            "quantity": op.quantity,
            "chosen": self.chosen,
            "targeted": self.target,
            "weight": self.weight,
            "element_ids": op.element_ids.tolist(),
            "node_ids": op.node_ids.tolist(),
            "point_numbers": op.point_numbers.tolist(),
            "coordinates": op.coordinates.tolist(),
        }


def check_stress_spec(body: ElasticBody, spec: StressSpec) -> None:
    """The cheap checks of a spec on a body, before anything expensive: a mesh, known ids.

    Raises
    ------
    UserError
        One line naming the key of ``[stress]`` and the first unknown id or missing mesh.
    """
    try:  # a solid mesh with its material: the operator of one element, which costs nothing
        first = None if body.mesh is None else body.mesh.element_ids[:1]
        stress_operator(body, elements=first)
    except UserError as exc:
        raise UserError(f"{WHERE}: {exc}") from None
    unknown = np.setdiff1d(np.asarray(spec.nodes, dtype=np.int64), body.node_ids)
    if unknown.size:
        raise UserError(f"{WHERE}.nodes: node {unknown[0]} is not in the model")
    _check_sets(body, spec.sets)
    ids = body.mesh.element_ids
    unknown = np.setdiff1d(np.asarray(spec.elements, dtype=np.int64), ids)
    if unknown.size:
        raise UserError(f"{WHERE}.elements: element {unknown[0]} is not in the mesh")
    if spec.box is not None:
        low, high = (np.asarray(corner, dtype=float) for corner in spec.box)
        if not np.all(low <= high):
            raise UserError(f"{WHERE}.box: the lower corner {low.tolist()} is not below "
                            f"the upper corner {high.tolist()}")  # fmt: skip


def _check_sets(body: ElasticBody, names: tuple[str, ...]) -> None:
    """Every named set is a node set of the body, and its nodes are nodes of the elements."""
    for name in names:
        members = body.node_sets.get(name)
        if members is None:
            names = list(body.node_sets)
            listed = ", ".join(names[:5]) + (", ..." if len(names) > 5 else "")
            known = f"known: {listed}" if names else "it has none"
            raise UserError(f"{WHERE}.sets: {name} is not a node set of the model ({known})")
        if not members.size:
            raise UserError(f"{WHERE}.sets: set {name} holds no node of the model")
        alone = missing_from(members, body.mesh.connectivity)
        if alone.size:
            raise UserError(
                f"{WHERE}.sets: node {alone[0]} of set {name} is not a node of the mesh's elements"
            )


def hot_spot_operator(
    body: ElasticBody, spec: StressSpec, responses: np.ndarray | None = None
) -> StressOperator:
    """The stress rows at the hot spots of ``spec`` on all dofs of ``body``.

    Parameters
    ----------
    body : ElasticBody
        The body in its frame, with its mesh.
    spec : StressSpec
    responses : ndarray, shape (n_dof, k), optional
        Static responses to the inputs on all dofs; needed when the hot spots are found.
    """
    check_stress_spec(body, spec)
    try:
        if spec.automatic:
            return _highest_von_mises(body, spec, responses)
        elements, nodes = _given(body, spec)
        return stress_operator(body, location=spec.location, elements=elements, nodes=nodes)
    except UserError as exc:
        raise UserError(f"{WHERE}: {exc}") from None


def _given(body: ElasticBody, spec: StressSpec) -> tuple[np.ndarray | None, np.ndarray | None]:
    """Element and node ids of the given hot spots: integration points of elements, or nodes."""
    mesh = body.mesh
    ids = body.mesh.element_ids
    nodes = np.asarray(spec.nodes, dtype=np.int64)
    for name in spec.sets:
        nodes = np.union1d(nodes, body.node_sets[name])
    elements = np.asarray(spec.elements, dtype=np.int64)
    if spec.box is not None:
        low, high = (np.asarray(corner, dtype=float) for corner in spec.box)
        index = body.node_rows(mesh.connectivity)  # node ids need not be sorted
        if spec.location == "nodes":
            inside = np.all((body.coordinates >= low) & (body.coordinates <= high), axis=1)
            nodes = np.union1d(nodes, body.node_ids[inside])
        else:
            centroids = body.coordinates[index].mean(axis=1)
            inside = np.all((centroids >= low) & (centroids <= high), axis=1)
            elements = np.union1d(elements, ids[inside])
        if not inside.any():
            raise UserError(f"box: no {'node' if spec.location == 'nodes' else 'element centroid'}"
                            " lies inside")  # fmt: skip
    if spec.location == "nodes":
        if elements.size:  # the nodes of the given elements
            rows = np.isin(ids, elements)
            nodes = np.union1d(nodes, mesh.connectivity[rows].ravel())
        return None, nodes
    if nodes.size:  # the elements around the given nodes
        around = np.any(np.isin(mesh.connectivity, nodes), axis=1)
        elements = np.union1d(elements, ids[around])
    return elements, None


def _highest_von_mises(
    body: ElasticBody, spec: StressSpec, responses: np.ndarray | None
) -> StressOperator:
    """The ``spec.count`` points of highest relative von Mises stress (module docstring).

    The points are scored a block of elements (nodes) at a time, keeping only their von Mises
    values (n_points, k): the operator of the whole mesh never exists at once. The operator of
    the chosen points is built again from their own elements (nodes).
    """
    if responses is None or responses.shape[1] == 0:
        raise UserError("no inputs: hot spots are found from the static responses to the inputs")
    nodal = spec.location == "nodes"
    ids = body.node_ids if nodal else body.mesh.element_ids
    key = "nodes" if nodal else "elements"
    fields, owners, numbers = [], [], []
    for first in range(0, ids.size, BLOCK_SIZE):
        block = ids[first : first + BLOCK_SIZE]
        if nodal:  # the nodes of the elements only: a node without an element has no stress
            block = block[np.isin(block, body.mesh.connectivity)]
        operator = stress_operator(body, location=spec.location, **{key: block})
        fields.append(von_mises(operator(responses), axis=1))  # (n_points, k)
        owners.append(operator.node_ids if nodal else operator.element_ids)
        numbers.append(operator.point_numbers)
    values = np.vstack(fields)
    largest = values.max(axis=0)
    relative = values[:, largest > 0] / largest[largest > 0]
    score = relative.max(axis=1) if relative.shape[1] else np.zeros(values.shape[0])
    chosen = np.argsort(-score, kind="stable")[: spec.count]
    wanted = set(zip(np.concatenate(owners)[chosen], np.concatenate(numbers)[chosen], strict=True))
    operator = stress_operator(
        body, location=spec.location, **{key: np.unique([owner for owner, _ in wanted])}
    )
    own = operator.node_ids if nodal else operator.element_ids
    keep = [i for i, pair in enumerate(zip(own, operator.point_numbers, strict=True))
            if pair in wanted]  # fmt: skip
    return _points_of(operator, np.asarray(keep))


def _points_of(operator: StressOperator, points: np.ndarray) -> StressOperator:
    """The operator at some of its points (indices, in their order)."""
    rows = (6 * points[:, None] + np.arange(6)).ravel()
    return replace(
        operator,
        matrix=sp.csr_matrix(operator.matrix[rows]),
        coordinates=operator.coordinates[points],
        element_ids=operator.element_ids[points],
        node_ids=operator.node_ids[points],
        point_numbers=operator.point_numbers[points],
    )
