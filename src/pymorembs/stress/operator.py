"""The sparse linear map from a body's displacements to stresses or strains at points.

:func:`stress_operator` builds a :class:`StressOperator` from the body's solid elements and
material (:class:`~pymorembs.body.ElementMesh`): one row per point and tensor component, one
column per equation of the body. Where the points lie (``location``):

``"integration"``
    The integration points of each element, in the element's own rule and CalculiX's numbering
    (:mod:`pymorembs.elements.solid`: tet4 1 point, tet10 4, hex8 2 x 2 x 2, hex20 3 x 3 x 3,
    hex20r 2 x 2 x 2).
``"element_nodes"``
    Every node of each element, the element's own values extrapolated from its integration
    points (:mod:`pymorembs.stress.extrapolation`).
``"nodes"``
    The mesh's nodes: the unweighted mean of the ``"element_nodes"`` values of the elements that
    share the node.

The operator is assembled element chunk by element chunk with NumPy (no loop over elements);
a subset of elements or nodes builds only the rows asked for, at a cost in proportion to the
elements involved.
"""

from __future__ import annotations

from collections.abc import Iterable, Iterator
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from pymorembs.body import ElasticBody, ElementMesh, mesh_problem
from pymorembs.elements.solid import (
    SOLID_KINDS,
    TENSOR_COMPONENTS,
    solid_kind,
    solid_point_matrices,
)
from pymorembs.errors import UserError
from pymorembs.stress.extrapolation import extrapolation_matrix

__all__ = [
    "COMPONENTS",
    "LOCATIONS",
    "QUANTITIES",
    "StressOperator",
    "stress_operator",
    "von_mises",
]

#: The six tensor components of every point, in this order (CalculiX/Abaqus S11 S22 S33 S12
#: S13 S23).
COMPONENTS = ("xx", "yy", "zz", "xy", "xz", "yz")
#: Where the points of an operator lie (module docstring).
LOCATIONS = ("integration", "nodes", "element_nodes")
#: What an operator gives: ``"stress"`` (Cauchy stress, small strains, model stress unit) or
#: ``"strain"`` (tensor components: the shear entries are ``eps_xy = gamma_xy / 2``, as CalculiX
#: prints ``E``).
QUANTITIES = ("stress", "strain")
_ENTRIES_PER_CHUNK = 4_000_000  # floats of element point matrices per batch
_NODAL_ENTRIES_PER_BLOCK = 16_000_000  # the same for the elements of a block of nodes


@dataclass(frozen=True, eq=False)
class StressOperator:
    """Linear map from the body's dofs to stress (or strain) components at points.

    Attributes
    ----------
    matrix : scipy.sparse.csr_matrix, shape (6 n_points, n_dof)
        Rows point-major, components in the order :data:`COMPONENTS`; columns the equations of
        the body (all of them: a field with fixed and dependent dofs filled in).
    quantity : str
        ``"stress"`` (model stress unit) or ``"strain"`` (tensor shear components).
    location : str
        ``"integration"``, ``"nodes"`` or ``"element_nodes"``.
    coordinates : ndarray, shape (n_points, 3)
        Where each point lies in the undeformed body (model length unit).
    element_ids : ndarray of int, shape (n_points,)
        The element of each point; -1 at an averaged node.
    node_ids : ndarray of int, shape (n_points,)
        The node of each point; -1 at an integration point.
    point_numbers : ndarray of int, shape (n_points,)
        The integration point's number in its element (1-based, CalculiX's order); 0 at nodes.
    """

    matrix: sp.csr_matrix
    quantity: str
    location: str
    coordinates: np.ndarray
    element_ids: np.ndarray
    node_ids: np.ndarray
    point_numbers: np.ndarray

    @property
    def n_points(self) -> int:
        """Number of points (the matrix has six rows per point)."""
        return int(self.coordinates.shape[0])

    def __repr__(self) -> str:
        return (
            f"<StressOperator {self.quantity} at {self.n_points} points ({self.location}), "
            f"{self.matrix.shape[1]} dofs, {self.matrix.nnz} entries>"
        )

    def labels(self) -> tuple[str, ...]:
        """One label per matrix row: ``"e1234.ip3:sxx"``, ``"e12.n17:syy"``, ``"n17:sxy"``
        (``e`` instead of ``s`` for strains)."""
        letter = "s" if self.quantity == "stress" else "e"
        points = []
        for element, node, number in zip(
            self.element_ids.tolist(),
            self.node_ids.tolist(),
            self.point_numbers.tolist(),
            strict=True,
        ):
            if node < 0:
                points.append(f"e{element}.ip{number}")
            elif element < 0:
                points.append(f"n{node}")
            else:
                points.append(f"e{element}.n{node}")
        return tuple(f"{p}:{letter}{c}" for p in points for c in COMPONENTS)

    def __call__(self, u: np.ndarray) -> np.ndarray:
        """Components at the points of one or several displacement fields.

        Parameters
        ----------
        u : ndarray, shape (n_dof,) or (n_dof, k)
            Displacements over all equations of the body (model length unit).

        Returns
        -------
        ndarray, shape (n_points, 6) or (n_points, 6, k)
        """
        u = np.asarray(u)
        if u.ndim not in (1, 2) or u.shape[0] != self.matrix.shape[1]:
            raise UserError(
                f"stress operator: displacements of shape {u.shape}, expected "
                f"({self.matrix.shape[1]},) or ({self.matrix.shape[1]}, k)"
            )
        values = self.matrix @ u
        return values.reshape(self.n_points, 6, *u.shape[1:])


def von_mises(components: np.ndarray, axis: int = -1) -> np.ndarray:
    """Von Mises equivalent of stress tensors given by their six components.

    ``sqrt(((xx - yy)² + (yy - zz)² + (zz - xx)²) / 2 + 3 (xy² + xz² + yz²))``.

    Parameters
    ----------
    components : ndarray, shape (..., 6, ...)
        The components in the order :data:`COMPONENTS` along ``axis``.
    axis : int
        The axis of the six components (default the last; ``1`` for the ``(n_points, 6, k)``
        output of :class:`StressOperator`).

    Returns
    -------
    ndarray
        ``components``' shape without ``axis`` (stress unit).
    """
    c = np.moveaxis(np.asarray(components, dtype=float), axis, 0)
    if c.shape[0] != 6:
        raise UserError(f"von Mises: {c.shape[0]} components along axis {axis}, expected 6")
    xx, yy, zz, xy, xz, yz = c
    normal = (xx - yy) ** 2 + (yy - zz) ** 2 + (zz - xx) ** 2
    return np.sqrt(0.5 * normal + 3.0 * (xy**2 + xz**2 + yz**2))


def _solid_mesh(body: ElasticBody) -> ElementMesh:
    mesh = body.mesh
    if mesh is None:
        why = mesh_problem(body)
        raise UserError(
            f"stresses of {body.name}: the body has no element mesh (its solid elements and "
            "material)" + (f": {why}" if why else "")
        )
    if mesh.element not in SOLID_KINDS:
        raise UserError(f"stresses are not supported for {mesh.element} elements")
    return mesh


def _element_rows(mesh: ElementMesh, elements: np.ndarray | None) -> np.ndarray:
    """Rows of the mesh of the element ids (sorted, mesh order); all rows for None."""
    ids = np.asarray(mesh.element_ids)
    if elements is None:
        return np.arange(ids.size)
    wanted = np.unique(np.asarray(elements, dtype=np.int64).ravel())
    order = np.argsort(ids, kind="stable")
    at = np.minimum(np.searchsorted(ids, wanted, sorter=order), ids.size - 1)
    rows = order[at]
    missing = ids[rows] != wanted
    if np.any(missing):
        first = int(wanted[missing][0])
        raise UserError(f"stresses: element {first} is not an element of the mesh")
    return np.sort(rows)


def _material(value: float | np.ndarray, rows: np.ndarray) -> float | np.ndarray:
    return value[rows] if isinstance(value, np.ndarray) else value


def _kept_entries(n: int, quantity: str) -> np.ndarray:
    """The entries of a (6, n, 3) point matrix that are not zero by structure (flat indices): a
    normal strain sees one direction, a shear strain two, a normal stress all three."""
    used = np.zeros((6, n, 3), dtype=bool)
    for c, (i, j) in enumerate(TENSOR_COMPONENTS):
        used[c, :, [i, j]] = True
        if quantity == "stress" and c < 3:
            used[c] = True
    return np.flatnonzero(used.ravel())


def _point_blocks(body: ElasticBody, mesh: ElementMesh, rows: np.ndarray, quantity: str):
    """For chunks of the element rows: the equation of each kept entry (e, m) and the values
    (e, q, m) (kept: :func:`_kept_entries`)."""
    kind = mesh.element
    spec = solid_kind(kind)
    n, q = spec.nodes, spec.points.shape[0]
    kept = _kept_entries(n, quantity)
    chunk = max(1, _ENTRIES_PER_CHUNK // (q * 18 * n))
    for start in range(0, rows.size, chunk):
        part = rows[start : start + chunk]
        conn = mesh.connectivity[part]
        equations = np.stack([body.dofs.positions(conn, d) for d in range(3)], axis=-1)
        if np.any(equations < 0):
            e, a = np.argwhere(np.any(equations < 0, axis=-1))[0]
            raise UserError(
                f"stresses: node {int(conn[e, a])} of element {int(mesh.element_ids[part[e]])} "
                "has no translational dofs in the body's dof table"
            )
        xyz = body.coordinates[body.node_rows(conn)]
        material = (
            (_material(mesh.young, part), _material(mesh.poisson, part))
            if quantity == "stress"
            else (None, None)
        )
        values = solid_point_matrices(kind, xyz, *material).reshape(part.size, q, -1)[..., kept]
        yield equations.reshape(part.size, 3 * n)[:, kept % (3 * n)], values


def _index_type(entries: int, n_cols: int) -> type:
    return np.int32 if max(entries, n_cols) < 2**31 - 1 else np.int64


def _stacked(
    blocks: Iterable[sp.csr_matrix], n_rows: int, n_cols: int, capacity: int
) -> sp.csr_matrix:
    """The blocks one below the other (``n_rows`` rows in all), copied as they come into arrays
    of ``capacity`` entries that grow by half when full and are cut to size at the end (in
    place): the result plus one block in memory."""
    index_type = _index_type(2 * capacity, n_cols)
    data = np.empty(capacity)
    indices = np.empty(capacity, dtype=index_type)
    indptr = np.zeros(n_rows + 1, dtype=np.int64)
    at = row = 0
    for block in blocks:
        end = at + block.nnz
        if end > data.size:
            size = max(end, data.size + data.size // 2)
            if size >= 2**31 - 1 and index_type is np.int32:
                indices, index_type = indices.astype(np.int64), np.int64
            data.resize(size, refcheck=False)
            indices.resize(size, refcheck=False)
        data[at:end] = block.data
        indices[at:end] = block.indices
        indptr[row + 1 : row + 1 + block.shape[0]] = block.indptr[1:] + at
        at, row = end, row + block.shape[0]
    data.resize(at, refcheck=False)
    indices.resize(at, refcheck=False)
    return sp.csr_matrix((data, indices, indptr.astype(index_type)), shape=(n_rows, n_cols))


def stress_operator(
    body: ElasticBody,
    *,
    location: str = "integration",
    quantity: str = "stress",
    elements: np.ndarray | list[int] | None = None,
    nodes: np.ndarray | list[int] | None = None,
) -> StressOperator:
    """The operator from the body's displacements to stresses or strains at points.

    Parameters
    ----------
    body : ElasticBody
        With a solid :class:`~pymorembs.body.ElementMesh` (``body.mesh``: tet4, tet10, hex8,
        hex20, hex20r) and its material.
    location : str
        ``"integration"``, ``"element_nodes"`` or ``"nodes"`` (module docstring).
    quantity : str
        ``"stress"`` or ``"strain"`` (:data:`QUANTITIES`).
    elements : array of int, optional
        Element ids: only the points of these elements (``"nodes"``: only the nodes of these
        elements, each still averaged over all elements that share it).
    nodes : array of int, optional
        Node ids: only these nodes (``"nodes"``), the element nodes at these nodes
        (``"element_nodes"``) or the integration points of the elements that hold one of them
        (``"integration"``). With ``elements`` too: the points both select.

    Returns
    -------
    StressOperator
        Points in the mesh's element order (``"nodes"``: ascending node id).

    Raises
    ------
    UserError
        No mesh, shells or beams (``stresses are not supported for beam2 elements``), an unknown
        location, quantity, element or node.
    """
    if location not in LOCATIONS:
        raise UserError(f"stresses: location {location!r} is not one of {', '.join(LOCATIONS)}")
    if quantity not in QUANTITIES:
        raise UserError(f"stresses: quantity {quantity!r} is not one of {', '.join(QUANTITIES)}")
    mesh = _solid_mesh(body)
    rows = _element_rows(mesh, elements)
    wanted_nodes = None
    if nodes is not None:
        wanted_nodes = np.unique(np.asarray(nodes, dtype=np.int64).ravel())
        known = np.isin(wanted_nodes, mesh.connectivity[rows])
        if not np.all(known):
            raise UserError(
                f"stresses: node {int(wanted_nodes[~known][0])} is not a node of the "
                + ("selected elements" if elements is not None else "mesh's elements")
            )
        rows = rows[np.any(np.isin(mesh.connectivity[rows], wanted_nodes), axis=1)]
    if location == "nodes":
        return _nodal_operator(body, mesh, rows, quantity, wanted_nodes)
    spec = solid_kind(mesh.element)
    extrapolate = extrapolation_matrix(mesh.element) if location == "element_nodes" else None
    matrix = _point_matrix(body, mesh, rows, quantity, extrapolate)
    conn = mesh.connectivity[rows]
    xyz = body.coordinates[body.node_rows(conn)]  # (e, n, 3)
    if extrapolate is None:
        q = spec.points.shape[0]
        coordinates = np.einsum("pa,eai->epi", spec.values, xyz).reshape(-1, 3)
        element_ids = np.repeat(mesh.element_ids[rows], q)
        node_ids = np.full(element_ids.size, -1, dtype=np.int64)
        numbers = np.tile(np.arange(1, q + 1), rows.size)
    else:
        coordinates = xyz.reshape(-1, 3)
        element_ids = np.repeat(mesh.element_ids[rows], spec.nodes)
        node_ids = conn.ravel()
        numbers = np.zeros(element_ids.size, dtype=np.int64)
    operator = StressOperator(
        matrix, quantity, location, coordinates, element_ids, node_ids, numbers
    )
    if location == "element_nodes" and wanted_nodes is not None:
        return _points_subset(operator, np.flatnonzero(np.isin(node_ids, wanted_nodes)))
    return operator


def _points_subset(operator: StressOperator, points: np.ndarray) -> StressOperator:
    """The operator restricted to some of its points (in their order)."""
    rows = (6 * points[:, None] + np.arange(6)).ravel()
    return StressOperator(
        sp.csr_matrix(operator.matrix[rows]),
        operator.quantity,
        operator.location,
        operator.coordinates[points],
        operator.element_ids[points],
        operator.node_ids[points],
        operator.point_numbers[points],
    )


def _nodal_operator(
    body: ElasticBody,
    mesh: ElementMesh,
    rows: np.ndarray,
    quantity: str,
    wanted_nodes: np.ndarray | None,
) -> StressOperator:
    """Averaged nodal values: ``A X S`` with ``S`` the integration-point operator of the elements
    at the nodes, ``X`` their extrapolation and ``A`` the unweighted mean over the elements;
    formed for blocks of nodes (each block with the elements at its nodes only)."""
    node_ids = np.unique(mesh.connectivity[rows]) if wanted_nodes is None else wanted_nodes
    spec = solid_kind(mesh.element)
    q, n = spec.points.shape[0], spec.nodes
    # elements at each node: the element slots sorted by node id
    flat = mesh.connectivity.ravel()
    order = np.argsort(flat, kind="stable")
    by_node = flat[order]
    mesh_nodes = max(1, np.unique(by_node).size)
    per_node = flat.size / mesh_nodes  # elements at a node, on average
    block = max(1, int(_NODAL_ENTRIES_PER_BLOCK / (per_node * q * 18 * n)))
    extrapolate = extrapolation_matrix(mesh.element)  # (n, q)
    comp = np.arange(6)

    def node_blocks() -> Iterator[sp.csr_matrix]:
        for start in range(0, node_ids.size, block):
            nodes = node_ids[start : start + block]
            lo = np.searchsorted(by_node, nodes[0], side="left")
            hi = np.searchsorted(by_node, nodes[-1], side="right")
            slots = order[lo:hi][np.isin(by_node[lo:hi], nodes)]
            involved = np.unique(slots // n)
            conn = mesh.connectivity[involved]
            slot = np.minimum(np.searchsorted(nodes, conn), nodes.size - 1)
            hit = nodes[slot] == conn  # (e, n): which element nodes are nodes of the block
            count = np.bincount(slot[hit], minlength=nodes.size).astype(float)
            e, a = np.nonzero(hit)
            r = np.repeat(slot[e, a], q)
            c = (e[:, None] * q + np.arange(q)).ravel()
            v = (extrapolate[a] / count[slot[e, a], None]).ravel()
            mean = sp.csr_matrix(
                (
                    np.repeat(v, 6),
                    ((6 * r[:, None] + comp).ravel(), (6 * c[:, None] + comp).ravel()),
                ),
                shape=(6 * nodes.size, 6 * q * involved.size),
            )
            yield sp.csr_matrix(mean @ _point_matrix(body, mesh, involved, quantity))

    # the integration points' entries of the elements: about the size of the result
    entries = q * _kept_entries(n, quantity).size * mesh.connectivity.shape[0]
    capacity = max(1024, int(entries * node_ids.size / mesh_nodes))
    matrix = _stacked(node_blocks(), 6 * node_ids.size, body.n_dof, capacity)
    return StressOperator(
        matrix,
        quantity,
        "nodes",
        body.coordinates[body.node_rows(node_ids)],
        np.full(node_ids.size, -1, dtype=np.int64),
        node_ids.astype(np.int64),
        np.zeros(node_ids.size, dtype=np.int64),
    )


def _point_matrix(
    body: ElasticBody,
    mesh: ElementMesh,
    rows: np.ndarray,
    quantity: str,
    extrapolate: np.ndarray | None = None,
) -> sp.csr_matrix:
    """The matrix (6 q len(rows), n_dof) of the integration points of the mesh's element rows;
    with ``extrapolate`` (n, q) that of the element nodes (6 n len(rows), n_dof).

    Written chunk by chunk into arrays of the final size (the result plus one chunk in memory).
    """
    spec = solid_kind(mesh.element)
    per_element = spec.points.shape[0] if extrapolate is None else spec.nodes
    kept = _kept_entries(spec.nodes, quantity)
    counts = np.bincount(kept // (3 * spec.nodes), minlength=6)
    n_rows = 6 * per_element * rows.size
    nnz = per_element * kept.size * rows.size
    index_type = _index_type(nnz, body.n_dof)
    data = np.empty(nnz)
    indices = np.empty(nnz, dtype=index_type)
    indptr = np.zeros(n_rows + 1, dtype=index_type)
    np.cumsum(np.tile(counts, per_element * rows.size), out=indptr[1:])
    at = 0
    for equations, values in _point_blocks(body, mesh, rows, quantity):
        if extrapolate is not None:
            values = np.einsum("kp,epm->ekm", extrapolate, values)
        size = values.size
        data[at : at + size] = values.reshape(-1)
        indices[at : at + size].reshape(values.shape)[...] = equations[:, None, :]
        at += size
    return sp.csr_matrix((data, indices, indptr), shape=(n_rows, body.n_dof))
