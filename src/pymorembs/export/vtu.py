"""The shapes of a reduced body as a VTU file (VTK unstructured grid) for ParaView and others.

Written with meshio (binary, zlib-compressed, VTK XML format 0.1). The file holds

* **points**: every node of the prepared body, at its coordinates in the reference frame (those
  of the exported bodies: measured from the frame origin), in the order of ``body.node_ids``;
* **cells**: the body's surface (:class:`~pymorembs.surface.Surface`): its triangles as VTK
  ``triangle`` cells and its line segments (beams) as ``line`` cells. A body without a surface
  (a bare matrix export) gets one ``vertex`` cell per node instead, so that a viewer shows the
  nodes as points;
* **point data** (one array per field, one row per point):

  =============================  ===========  ==============================================
  name                           shape        content
  =============================  ===========  ==============================================
  ``node_id``                    (n,) int64   the FE node id of the point
  ``shape_001`` ...              (n, 3)       column k of the basis ``V`` on all dofs
                                              (eq. 18): ``ux uy uz`` of the node
  ``shape_001_rotation`` ...     (n, 3)       its ``rx ry rz`` (only if the body has
                                              rotational dofs)
  ``static_<input>``             (n, 3)       static deformation ``K^+ b`` under a unit input
  ``static_<input>_rotation``    (n, 3)       its rotations (as above)
  ``<field>_stress``             (n, 6)       for a body with solid elements: the stress of
                                              the field (a shape or a static response),
                                              averaged at the nodes, as a VTK symmetric tensor
                                              ``xx yy zz xy yz xz``
  ``<field>_strain``             (n, 6)       its strain, likewise
  ``<field>_von_mises``          (n,)         the von Mises stress of ``<field>_stress``
  =============================  ===========  ==============================================

  A direction a node does not have is 0 (:func:`~pymorembs.export.nodal.node_fields`); fixed
  dofs (the tangent frame's node) are 0, dependent dofs carry the motion the constraint
  equations give them. The stress arrays
  (:mod:`~pymorembs.export.stress_modes`: the mesh's nodal stresses, extrapolated from the
  integration points and averaged over the elements at a node, :mod:`pymorembs.stress`) are NaN
  at a node of no solid element (a reference node of a rigid coupling); a body without solid
  elements (beams, plain matrices) has no stress arrays. The VTU has no cell data: its cells are
  the surface's triangles, not the elements, so the integration-point values are in the
  recovery file (``stress_recovery``, :mod:`pymorembs.export.recovery`).

Shape ``k`` goes with entry ``k`` of the reduction's ``eigenfrequencies_hz`` (``summary.json``,
:attr:`~pymorembs.api.ReducedBody.eigenfrequencies_hz`): the columns of ``V`` are the
eigenvectors of the reduced model. (meshio 5.3 writes no VTK field data, so the file does not
repeat them.)

Shape numbers start at 1 and have at least three digits (``shape_001``; more when the basis has
1,000 columns or more). ``<input>`` is the input's label with every character other than letters,
digits and ``_ . + -`` replaced by ``_``: ``static_1_ux`` for a force ``1:ux``, ``static_1_rz``
for a moment, ``static_inertia_ax`` for the inertia load of the frame's acceleration ``ax``.

Units are those of the FE model. The basis is mass-normalised (``V^T M V = I``; ``W^T M V = I``
for a two-sided projection), so a shape is a length per unit modal coordinate (m kg^-1/2 in SI)
and a rotation a radian per unit modal coordinate. A stress array is a stress per unit of what
its field is per unit of (modal coordinate, force, moment, acceleration). A static response is
the deformation under a unit force (m/N) or moment (m/(N m)); for an inertia load, under a unit
frame acceleration: m per m/s² (``ax ay az``), per rad/s² (``alx aly alz``), per (rad/s)²
(``wxx`` ...). The static solve is the one the reduction used: the frame's fixed dofs held,
and for a free body in the Buckens frame the deformation mass-orthogonal to the rigid-body
modes (inertia relief).
"""

from __future__ import annotations

import os
import re
from collections.abc import Mapping
from pathlib import Path

import numpy as np

from pymorembs.body import ElasticBody
from pymorembs.errors import UserError
from pymorembs.export.nodal import node_fields
from pymorembs.export.stress_modes import VTK_ORDER, StressModes, stress_modes
from pymorembs.io.atomic import atomic_path
from pymorembs.preparation import PreparedModel
from pymorembs.reduction.projection import ReducedModel
from pymorembs.stress import von_mises

__all__ = [
    "ROTATION_SUFFIX",
    "SHAPE_PREFIX",
    "STATIC_PREFIX",
    "array_name",
    "require_coordinates",
    "shape_names",
    "static_fields",
    "stress_point_data",
    "write_reduced_vtu",
    "write_vtu",
]

#: Prefix of the point-data arrays of the shape functions (``shape_001``, ...).
SHAPE_PREFIX = "shape_"
#: Prefix of the point-data arrays of the static responses (``static_1_ux``, ...).
STATIC_PREFIX = "static_"
#: Suffix of the rotational part of a field (``shape_001_rotation``).
ROTATION_SUFFIX = "_rotation"
_UNSAFE = re.compile(r"[^A-Za-z0-9_.+-]")


def array_name(prefix: str, label: str) -> str:
    """``prefix`` + ``label`` with characters other than ``A-Z a-z 0-9 _ . + -`` as ``_``."""
    return prefix + _UNSAFE.sub("_", str(label))


def shape_names(count: int) -> list[str]:
    """The array names of ``count`` shape functions: ``shape_001`` ... (at least 3 digits)."""
    width = max(3, len(str(count)))
    return [f"{SHAPE_PREFIX}{k:0{width}d}" for k in range(1, count + 1)]


def static_fields(prepared: PreparedModel) -> dict[str, np.ndarray]:
    """The static response to each input of the reduction, on all dofs of the prepared body.

    Parameters
    ----------
    prepared : PreparedModel
        Its :attr:`~pymorembs.preparation.PreparedModel.static_response` (``K^+ B`` of the ports
        and the inertia loads, one factorization kept with the model).

    Returns
    -------
    dict of str to ndarray (n_dof,)
        Input label (``"1:ux"``, ``"inertia:ax"``) -> deformation under a unit input: per N
        (per N m for a moment) for a port, per unit of the frame's acceleration for an inertia
        load (the column's scale divided out).
    """
    system = prepared.reduction_system
    response = np.array(prepared.static_response, dtype=float)
    if prepared.inertia is not None:
        n_inertia = len(prepared.inertia.cases)
        response[:, system.n_inputs - n_inertia :] /= prepared.inertia.scales
    expanded = prepared.expand(response)
    return {label: expanded[:, j] for j, label in enumerate(system.input_labels)}


def write_vtu(
    path: str | os.PathLike[str],
    body: ElasticBody,
    shapes: np.ndarray,
    *,
    static: Mapping[str, np.ndarray] | None = None,
    stress: StressModes | None = None,
) -> Path:
    """Write the body's surface with shape functions and static responses as a VTU file.

    The content is described in the module docstring. The file is written to a temporary name
    and renamed, so a failed write leaves no half file.

    Parameters
    ----------
    path : path-like
        Target file (written as given; ParaView expects the extension ``.vtu``).
    body : ElasticBody
        The body the columns belong to (the prepared body: coordinates in the reference frame).
    shapes : ndarray, shape (n_dof, k)
        Shape functions over all equations of ``body`` (length per unit modal coordinate).
    static : dict of str to ndarray (n_dof,), optional
        Input label -> static deformation over all equations (:func:`static_fields`).
    stress : StressModes, optional
        The stress modes of the same columns (``shapes`` then ``static``,
        :func:`~pymorembs.export.stress_modes.stress_modes`): their nodal stress, strain and von
        Mises stress join each field.

    Returns
    -------
    Path
        The written file.

    Raises
    ------
    UserError
        The body has no node coordinates, an array has the wrong shape, or two input labels
        give the same array name.
    """
    import meshio

    require_coordinates(body, path)
    shapes = np.asarray(shapes, dtype=float)
    if shapes.ndim != 2 or shapes.shape[0] != body.n_dof:
        raise UserError(f"vtu {path}: shapes have shape {shapes.shape}, expected ({body.n_dof}, k)")
    labels = list(static or {})
    columns = [np.asarray(static[label], dtype=float) for label in labels] if static else []
    for label, column in zip(labels, columns, strict=True):
        if column.shape != (body.n_dof,):
            raise UserError(
                f"vtu {path}: static response {label!r} has shape {column.shape}, "
                f"expected ({body.n_dof},)"
            )
    names = shape_names(shapes.shape[1]) + [array_name(STATIC_PREFIX, label) for label in labels]
    if len(set(names)) != len(names):
        twice = next(name for name in names if names.count(name) > 1)
        raise UserError(f"vtu {path}: two inputs give the same array name {twice!r}")

    vectors = np.column_stack([shapes, *columns]) if columns else shapes
    fields = node_fields(body, vectors)
    point_data: dict[str, np.ndarray] = {"node_id": body.node_ids.astype(np.int64)}
    for j, name in enumerate(names):
        point_data[name] = np.ascontiguousarray(fields.translations[:, :, j])
        if fields.rotations is not None:
            point_data[name + ROTATION_SUFFIX] = np.ascontiguousarray(fields.rotations[:, :, j])
    if stress is not None:
        if stress.count != len(names):
            raise UserError(
                f"vtu {path}: stress modes of {stress.count} columns for {len(names)} fields"
            )
        point_data.update(stress_point_data(body, stress, names))
    mesh = meshio.Mesh(np.asarray(body.coordinates, dtype=float), _cells(body), point_data)
    target = Path(path)
    with atomic_path(target) as tmp:
        meshio.write(tmp, mesh, file_format="vtu")
    return target


def write_reduced_vtu(
    path: str | os.PathLike[str], model: ReducedModel, prepared: PreparedModel
) -> Path:
    """:func:`write_vtu` of a reduction: its basis ``V`` on all dofs (eq. 18) and the static
    response to every input of the prepared model (:func:`static_fields`)."""
    require_coordinates(prepared.body, path)  # before the static solve
    basis = prepared.expand(model.projection.V)
    static = static_fields(prepared)
    modes = stress_modes(prepared.body, basis, static)
    return write_vtu(path, prepared.body, basis, static=static, stress=modes)


def stress_point_data(
    body: ElasticBody, stress: StressModes, names: list[str]
) -> dict[str, np.ndarray]:
    """The arrays ``<name>_stress``, ``<name>_strain`` (VTK tensor order) and
    ``<name>_von_mises`` of every column of ``stress`` on the points of the VTU (every node of
    ``body``; NaN at a node of no solid element)."""
    out: dict[str, np.ndarray] = {}
    for quantity in ("stress", "strain"):
        operator = stress.operator("nodes", quantity)
        rows = body.node_rows(operator.node_ids)
        for part, values in stress.blocks(operator):
            for j, column in enumerate(part):
                tensor = np.full((body.n_nodes, 6), np.nan)
                tensor[rows] = values[j][:, VTK_ORDER]
                out[f"{names[column]}_{quantity}"] = tensor
                if quantity == "stress":
                    mises = np.full(body.n_nodes, np.nan)
                    mises[rows] = von_mises(values[j])
                    out[f"{names[column]}_von_mises"] = mises
    return out


def require_coordinates(body: ElasticBody, path: str | os.PathLike[str]) -> None:
    if not body.has_coordinates:
        raise UserError(
            f"vtu {path}: the model has no node coordinates, which a VTU file needs; give the "
            "nodes (nodes = nodes.csv or the FE input file)"
        )


def _cells(body: ElasticBody) -> list[tuple[str, np.ndarray]]:
    """VTK cells over the rows of ``body.coordinates``: the surface, or a vertex per node."""
    surface = body.surface
    cells = []
    if surface is not None:
        for kind, ids in (("triangle", surface.triangles), ("line", surface.lines)):
            if ids.size:
                cells.append((kind, body.node_rows(ids).astype(np.int64)))
    if not cells:
        cells.append(("vertex", np.arange(body.n_nodes, dtype=np.int64)[:, None]))
    return cells
