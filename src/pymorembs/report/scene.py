"""The body as a scene for the 3D viewer (``viewer.js``): nodes, surface, frame, shapes.

:func:`body_scene` turns an :class:`~pymorembs.body.ElasticBody` (and optionally a basis of
shape functions over its dofs, its reference frame and its interface nodes) into a plain,
JSON-serialisable dict that ``viewer.js`` draws. The HTML report embeds it; the local web app
sends it to the page.

The scene holds only the nodes a viewer shows: those of the surface (plus the frame node, the
interface nodes and their coupled nodes), or every node when the body has no surface. Numbers
are rounded so that the JSON stays small: positions to 6 significant digits of the model's
size, shape values to 4 significant digits of each shape's largest translation (single
precision and below: what a picture needs, not what a computation needs).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import scipy.sparse as sp

from pymorembs.body import SCALAR, ElasticBody
from pymorembs.errors import UserError
from pymorembs.export.nodal import node_fields
from pymorembs.export.stress_modes import nodes_operator, von_mises_at
from pymorembs.preparation import Frame, PreparedModel, centre_of_gravity
from pymorembs.preparation.interface import InterfaceSpec
from pymorembs.reduction.projection import ReducedModel
from pymorembs.report.stress_table import stress_mode_maxima

__all__ = [
    "POSITION_DIGITS",
    "SCENE_SHAPES_EACH",
    "SCENE_VALUES",
    "SHAPE_DIGITS",
    "attached_nodes",
    "body_scene",
    "reductions_scene",
    "viewer_script",
]

#: Significant digits of the positions, relative to the model's size.
POSITION_DIGITS = 6
#: Significant digits of the shape values, relative to each shape's largest translation.
SHAPE_DIGITS = 4

_CHUNK = 30_000  # rows of K looked at together by attached_nodes

#: Shapes of each reduction that :func:`reductions_scene` keeps at most.
SCENE_SHAPES_EACH = 12
#: Shape values (3 per node and shape) that :func:`reductions_scene` keeps at most: about 7 MB
#: of JSON.
SCENE_VALUES = 1_000_000

InterfaceLike = InterfaceSpec | Mapping[str, Any] | tuple[str, int, Sequence[int]]
FrameLike = Frame | Mapping[str, Any] | tuple[Any, Any]


def viewer_script() -> str:
    """The text of ``viewer.js``, the dependency-free WebGL viewer of a scene."""
    return (Path(__file__).with_name("viewer.js")).read_text(encoding="utf-8")


def body_scene(
    body: ElasticBody,
    *,
    basis: np.ndarray | None = None,
    shape_names: Sequence[str] | None = None,
    frame: FrameLike | None = None,
    interfaces: Sequence[InterfaceLike] | None = None,
    max_shapes: int | None = None,
    max_values: int | None = None,
    all_nodes: bool = False,
) -> dict[str, Any]:
    """The scene of a body for ``viewer.js``, as a JSON-serialisable dict.

    Parameters
    ----------
    body : ElasticBody
        The body; its coordinates (model length unit) are the positions.
    basis : ndarray, shape (n_dof, k), optional
        Shape functions over the body's dofs (e.g. ``ReducedBody.basis`` with the body
        ``ReducedBody.prepared.body``); their translations (ux uy uz) at the scene's nodes
        become the shapes, dofs the body lacks count as zero.
    shape_names : sequence of str, optional
        One name per column of ``basis`` (default ``"shape 1"``, ...).
    frame : Frame, mapping or (origin, axes), optional
        The reference frame drawn as an axis triad: a :class:`pymorembs.preparation.Frame`
        (tangent: at its node; Buckens: at the centre of gravity; none: no triad), a mapping
        ``{"origin": [3], "axes": [[3], [3], [3]]}`` or a pair ``(origin, axes)``; axes are the
        rows, default the model's axes.
    interfaces : sequence, optional
        Interface nodes with their coupled nodes: :class:`~pymorembs.preparation.interface.
        InterfaceSpec`, mappings ``{"name", "node", "coupled"}`` or tuples
        ``(name, node, coupled)``, node ids of the body.
    max_shapes : int, optional
        Keep at most this many shapes (the first ones).
    max_values : int, optional
        Keep at most as many shapes as fit ``3 n`` values each into this many numbers.
    all_nodes : bool
        Keep every node of the body. By default the scene's n nodes are those a viewer shows:
        the surface's, the tangent frame's node and the interface nodes with their coupled
        nodes (every node for a body without a surface).

    Returns
    -------
    dict
        ``positions`` (flat, 3 n, model length unit), ``node_ids`` (n), ``triangles`` (flat,
        3 t, indices into the nodes), ``lines`` (flat, 2 l), ``frame`` (``{"origin", "axes"}``
        or None), ``interfaces`` (``{"name", "node", "coupled"}`` with indices into the nodes),
        ``shapes`` (``{"name", "values"}``, values flat, 3 n translations), ``size`` (diagonal
        of the nodes' bounding box, model length unit), ``shapes_total`` (columns of ``basis``
        before capping) and ``notes`` (str each: what the viewer should say).

    Raises
    ------
    UserError
        A basis of the wrong height, names of the wrong number, an unknown node.
    """
    notes: list[str] = []
    triad = _frame(body, frame)
    couplings = [_interface(body, item) for item in interfaces or ()]
    surface = body.surface
    if all_nodes or surface is None:
        rows = np.arange(body.n_nodes)
    else:
        wanted = [surface.node_ids]
        for _, node, coupled in couplings:
            wanted += [np.array([node]), coupled]
        if isinstance(frame, Frame) and frame.kind == "tangent" and frame.node is not None:
            wanted.append(np.array([int(frame.node)]))
        rows = np.unique(body.node_rows(np.concatenate(wanted)))
    ids = body.node_ids[rows]
    order = np.argsort(ids, kind="stable")
    if surface is None:
        notes.append("no surface: the nodes are drawn as points")
    if not body.has_coordinates:
        notes.append("the model file gave no coordinates: every node lies at the origin")
    coordinates = body.coordinates[rows]
    size = _size(coordinates)

    def index(node_ids: np.ndarray) -> list[int]:
        return order[np.searchsorted(ids, node_ids, sorter=order)].tolist()

    triangles: list[int] = []
    lines: list[int] = []
    if surface is not None:
        triangles = index(surface.triangles.ravel())
        lines = index(surface.lines.ravel())
    shapes, total = _shapes(body, ids, basis, shape_names, max_shapes, max_values)
    if len(shapes) < total:
        notes.append(f"{len(shapes)} of {total} shapes kept, to keep the page small")
    return {
        "positions": _rounded(coordinates.ravel(), size, POSITION_DIGITS),
        "node_ids": ids.tolist(),
        "triangles": triangles,
        "lines": lines,
        "frame": triad,
        "interfaces": [
            {"name": name, "node": index(np.array([node]))[0], "coupled": index(coupled)}
            for name, node, coupled in couplings
        ],
        "shapes": shapes,
        "size": size,
        "shapes_total": total,
        "notes": notes,
    }


def reductions_scene(
    prepared: PreparedModel,
    reductions: Mapping[str, ReducedModel],
    *,
    interfaces: Sequence[InterfaceLike] | None = None,
    max_shapes_each: int = SCENE_SHAPES_EACH,
    max_values: int = SCENE_VALUES,
    model_interfaces: bool = True,
) -> dict[str, Any]:
    """The scene of a prepared body with the shape functions of its reductions.

    The shapes are the columns of each reduction's exported basis ``V`` (in the reduced
    model's eigenbasis, lowest frequency first), expanded to all dofs (eq. 18), named
    ``"<reduction> #k: f Hz"``. Each reduction keeps its first ``max_shapes_each`` and all
    together at most ``max_values`` numbers (3 per node and shape); the scene's ``notes`` say
    so where that left shapes out.

    Parameters
    ----------
    prepared : PreparedModel
        The body in its reference frame (coordinates measured from the frame's origin) and the
        map to all dofs; its frame is drawn.
    reductions : mapping of str to ReducedModel
        The reductions by name, in the order the selector lists them.
    interfaces : sequence, optional
        As for :func:`body_scene`, node ids of ``prepared.body``.
    max_shapes_each, max_values : int
        The caps.
    model_interfaces : bool
        Add the interface nodes the model carries (:func:`attached_nodes`) that
        ``interfaces`` does not name.

    Returns
    -------
    dict
        The scene of :func:`body_scene`, with ``stress_modes``: the largest von Mises stress
        of each reduction's first shapes (:func:`~pymorembs.report.stress_table.
        stress_mode_maxima`), which the report shows as a table; for a body with solid
        elements each shape also has ``scalars``, its nodal von Mises stress at the scene's
        nodes (per unit modal coordinate), by which the viewer colours it.
    """
    body = prepared.body
    frame = prepared.frame
    interfaces = list(interfaces or ())
    if model_interfaces:
        named = {_interface(body, item)[1] for item in interfaces}
        interfaces += [item for item in attached_nodes(body) if item[1] not in named]
    plain = body_scene(body, frame=frame, interfaces=interfaces)
    plain["stress_modes"] = stress_mode_maxima(prepared, reductions)
    n_nodes = max(1, len(plain["node_ids"]))
    count = max(1, len(reductions))
    fits = max(1, int(max_values) // (3 * n_nodes * count))
    names: list[str] = []
    columns: list[np.ndarray] = []
    total = 0
    for name, model in reductions.items():
        order = model.projection.order
        total += order
        keep = min(order, max(0, int(max_shapes_each)), fits)
        if keep == 0:
            continue
        columns.append(prepared.expand(model.projection.V[:, :keep]))
        names += [
            f"{name} #{k + 1}: {f:.4g} Hz" for k, f in enumerate(model.eigenfrequencies_hz[:keep])
        ]
    if not columns:
        return plain
    scene = body_scene(
        body,
        basis=np.hstack(columns),
        shape_names=names,
        frame=frame,
        interfaces=interfaces,
    )
    scene["shapes_total"] = total
    scene["stress_modes"] = plain["stress_modes"]
    operator = nodes_operator(body, np.asarray(scene["node_ids"]))
    if operator is not None:  # a solid body: each shape coloured by its von Mises stress
        basis = np.hstack(columns)[:, : len(scene["shapes"])]
        mises = von_mises_at(operator, basis, np.asarray(scene["node_ids"]))
        for k, shape in enumerate(scene["shapes"]):
            shape["scalars"] = [float(f"{v:.4g}") for v in mises[:, k]]
    if len(names) < total:
        scene["notes"].append(
            f"{len(names)} of the {total} shape functions shown (at most "
            f"{min(int(max_shapes_each), fits)} of each reduction), to keep the page small"
        )
    return scene


def attached_nodes(body: ElasticBody) -> list[tuple[str, int, np.ndarray]]:
    """Interface nodes the model carries: nodes off the surface coupled only to surface nodes.

    A node the surface does not use (no element face or line element has it) whose every
    coupling -- a stiffness entry (beams, springs) or a constraint equation (rigid, RBE2- or
    RBE3-like) with another node's dofs -- goes to nodes of the surface is an interface node
    of the model, e.g. ``rack-solid``'s node 2 in its hole or a Nastran RBE2's independent
    node. A node inside a solid couples to other inner nodes and is not one.

    Returns
    -------
    list of (name, node id, coupled node ids)
        In the order of the node ids; empty for a body without a surface.
    """
    surface = body.surface
    if surface is None or body.n_dof == 0:
        return []
    n = body.n_nodes
    drawn = np.zeros(n, dtype=bool)
    drawn[body.node_rows(surface.node_ids)] = True
    geometric = body.dofs.directions != SCALAR
    row_of_dof = np.full(body.n_dof, -1, dtype=np.int64)
    row_of_dof[geometric] = body.node_rows(body.dofs.nodes[geometric])
    candidates = np.flatnonzero(geometric & ~drawn[np.maximum(row_of_dof, 0)])
    if candidates.size == 0:
        return []
    # Node pairs (row, other row) coupled by a stiffness entry, rows taken in chunks so that a
    # large solid's inner nodes never need more than a slice of K at once.
    pairs = []
    stiffness = sp.csr_matrix(body.stiffness)
    for start in range(0, candidates.size, _CHUNK):
        part = candidates[start : start + _CHUNK]
        block = stiffness[part].tocoo()
        pairs.append(_node_pairs(row_of_dof[part[block.row]], row_of_dof[block.col], n))
    constraints = body.constraints
    if constraints is not None and len(constraints):  # both ways: either side may be the node
        g = constraints.matrix.tocoo()
        a, b = row_of_dof[constraints.dependent[g.row]], row_of_dof[g.col]
        pairs += [_node_pairs(a, b, n), _node_pairs(b, a, n)]
    pair = np.unique(np.concatenate(pairs))
    rows, other = pair // n, pair % n
    keep = ~drawn[rows]
    rows, other = rows[keep], other[keep]
    bad = np.unique(rows[~drawn[other]])  # coupled to a node off the surface: an inner node
    good = ~np.isin(rows, bad)
    rows, other = rows[good], other[good]
    if rows.size == 0:
        return []
    starts = np.flatnonzero(np.r_[True, rows[1:] != rows[:-1]])  # pairs are sorted by row
    out = []
    for first, last in zip(starts, [*starts[1:].tolist(), rows.size], strict=True):
        node = int(body.node_ids[rows[first]])
        out.append((f"node {node} (the model's)", node, body.node_ids[other[first:last]]))
    return sorted(out, key=lambda item: item[1])


def _node_pairs(rows: np.ndarray, other: np.ndarray, n: int) -> np.ndarray:
    """Unique codes ``row * n + other`` of node pairs, without scalar dofs and self pairs."""
    keep = (rows >= 0) & (other >= 0) & (rows != other)
    return np.unique(rows[keep] * n + other[keep])


def _size(coordinates: np.ndarray) -> float:
    """Diagonal of the bounding box; 1 for a body without extent."""
    if coordinates.size == 0:
        return 1.0
    diagonal = float(np.linalg.norm(coordinates.max(axis=0) - coordinates.min(axis=0)))
    return diagonal if diagonal > 0 else 1.0


def _rounded(values: np.ndarray, scale: float, digits: int) -> list[float]:
    """``values`` in single precision, rounded to ``digits`` significant digits of ``scale``.

    Rounding to a whole number of decimals (``np.round``) divides by an exact power of ten, so
    every number prints in its shortest form in JSON.
    """
    values = np.asarray(values, dtype=np.float32).astype(float)
    if not scale > 0 or not math.isfinite(scale):
        return [0.0] * values.size
    decimals = digits - 1 - math.floor(math.log10(scale))
    if decimals > 22:  # 10**d no longer exact; such tiny numbers are zero for a picture
        return [0.0] * values.size
    return (np.round(values, decimals) + 0.0).tolist()  # + 0.0: no negative zeros


def _shapes(
    body: ElasticBody,
    ids: np.ndarray,
    basis: np.ndarray | None,
    names: Sequence[str] | None,
    max_shapes: int | None,
    max_values: int | None,
) -> tuple[list[dict[str, Any]], int]:
    """The shapes (name, translations at the nodes ``ids``) and the number of columns given."""
    if basis is None:
        if names:
            raise UserError("scene: shape names given without a basis")
        return [], 0
    basis = np.asarray(basis)
    if basis.ndim == 1:
        basis = basis[:, None]
    if basis.ndim != 2 or basis.shape[0] != body.n_dof:
        raise UserError(
            f"scene: the basis has shape {basis.shape}, expected ({body.n_dof}, k) for the "
            "body's dofs"
        )
    total = basis.shape[1]
    if names is None:
        names = [f"shape {k + 1}" for k in range(total)]
    if len(names) != total:
        raise UserError(f"scene: {len(names)} shape names for {total} shapes")
    keep = total
    if max_shapes is not None:
        keep = min(keep, max(0, int(max_shapes)))
    if max_values is not None and ids.size:
        keep = min(keep, max(1, int(max_values) // (3 * ids.size)))
    translations = node_fields(body, np.real(basis[:, :keep]), nodes=ids).translations
    shapes = []
    for k in range(keep):
        values = translations[:, :, k].ravel()  # ux uy uz of each node in turn, 0 where none
        peak = float(np.max(np.abs(values), initial=0.0))
        shapes.append({"name": str(names[k]), "values": _rounded(values, peak, SHAPE_DIGITS)})
    return shapes, total


def _frame(body: ElasticBody, frame: FrameLike | None) -> dict[str, list] | None:
    """Origin and axes (rows) of the frame's triad, or None."""
    if frame is None:
        return None
    if isinstance(frame, Frame):
        if frame.kind == "none":
            return None
        if frame.kind == "tangent":
            if frame.node is None or int(frame.node) not in body.node_index:
                raise UserError(f"scene: the frame node {frame.node} is not a node of the body")
            origin = body.node_position(int(frame.node))
        elif frame.kind == "buckens":
            origin = centre_of_gravity(body)
        else:
            raise UserError(f"scene: frame kind {frame.kind!r} is unknown")
        axes = np.eye(3)
    elif isinstance(frame, Mapping):
        origin, axes = frame.get("origin"), frame.get("axes", np.eye(3))
    else:
        origin, axes = frame
    origin = np.asarray(origin, dtype=float)
    axes = np.asarray(np.eye(3) if axes is None else axes, dtype=float)
    if origin.shape != (3,) or axes.shape != (3, 3) or not np.all(np.isfinite(axes)):
        raise UserError("scene: the frame needs an origin of 3 numbers and 3 axes of 3 numbers")
    if not np.all(np.isfinite(origin)):
        raise UserError("scene: the frame's origin is not finite")
    lengths = np.linalg.norm(axes, axis=1, keepdims=True)
    if not np.all(lengths > 0):
        raise UserError("scene: a frame axis has zero length")
    return {"origin": origin.tolist(), "axes": (axes / lengths).tolist()}


def _interface(body: ElasticBody, item: InterfaceLike) -> tuple[str, int, np.ndarray]:
    """(name, node id, coupled node ids) of an interface, checked against the body."""
    if isinstance(item, InterfaceSpec):
        name, node, coupled = f"interface {item.node} ({item.kind})", item.node, item.coupled
    elif isinstance(item, Mapping):
        node, coupled = item["node"], item.get("coupled", ())
        name = str(item.get("name") or f"interface {node}")
    else:
        name, node, coupled = item
    node = int(node)
    coupled = np.asarray(coupled, dtype=np.int64).ravel()
    known = body.node_index
    for n in (node, *coupled.tolist()):
        if int(n) not in known:
            raise UserError(f"scene: interface node {node}: node {n} is not a node of the body")
    return str(name), node, coupled
