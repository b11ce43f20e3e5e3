"""The native file format: one HDF5 file that holds a whole :class:`ElasticBody` losslessly.

Layout (format version 2)::

    /                      attributes format="pymorembs-body", version=2, name,
                           has_coordinates, notes (list of str), precision (NaN: unknown)
                           (the last three from version 2 on)
    /nodes/ids             int64 (n_nodes,)
    /nodes/coordinates     float64 (n_nodes, 3)
    /dofs/nodes            int64 (n_dof,)
    /dofs/directions       int64 (n_dof,) direction codes 0..6 = ux uy uz rx ry rz q
    /mass, /stiffness      CSR groups: data float64, indices int64, indptr int64,
                           attribute shape = (rows, columns)
    /damping_matrix        CSR group, only if the body has an explicit damping matrix
    /constraints/dependent int64 (n_d,)
    /constraints/offset    float64 (n_d,)
    /constraints/matrix    CSR group of G, shape (n_d, n_dof)
    /fixed                 int64 (n_c,)
    /damping               empty group, attributes kind, alpha, beta, ratio
    /ports/inputs          CSR group of B (n_dof, p), only if the model has its own ports;
                           attribute labels (list of str)
    /ports/outputs         CSR group of C (r, n_dof), optional; attribute labels
    /mesh/connectivity     int64 (n_el, nodes per element) node ids, only if the body has its
                           elements (built-in models, solid meshes of imported models);
                           attributes element, young, poisson (what geometric stiffening
                           needs); young and poisson are datasets (n_el,) instead when the
                           elements have several materials
    /surface/triangles     int64 (n_t, 3), /surface/lines int64 (n_l, 2): node ids of what a
                           viewer draws (outer faces, line elements), only if the body has a
                           surface; attribute source

Version 1 files (no coordinates flag, notes or ports) are read as well.

Arrays are stored exactly as they are in memory (floats bit for bit, sparsity structure as is);
arrays of more than :data:`COMPRESS_FROM` elements are gzip-compressed, which is lossless.
"""

from __future__ import annotations

import os
from dataclasses import asdict, fields
from pathlib import Path
from typing import Any

import h5py
import numpy as np
import scipy.sparse as sp

from pymorembs.body import (
    ConstraintEquations,
    Damping,
    DofTable,
    ElasticBody,
    ElementMesh,
    ModelPorts,
)
from pymorembs.elements.beam import BeamSection
from pymorembs.errors import UserError
from pymorembs.io.atomic import atomic_path
from pymorembs.surface import Surface

__all__ = ["COMPRESS_FROM", "FORMAT", "VERSION", "read_body_h5", "write_body_h5"]

#: Value of the root attribute ``format``.
FORMAT = "pymorembs-body"
#: Format version written (and the newest one read).
VERSION = 2
#: Arrays with at least this many elements are stored gzip-compressed.
COMPRESS_FROM = 4096

_INT = "iu"  # dtype kinds accepted for integer arrays
_FLOAT = "f"


def write_body_h5(body: ElasticBody, path: str | os.PathLike[str]) -> Path:
    """Write ``body`` to the HDF5 file ``path`` (atomically; layout in the module docstring).

    Parameters
    ----------
    body : ElasticBody
        The body.
    path : path-like
        Target file, conventionally ``*.h5``.

    Returns
    -------
    Path
        ``path``.
    """
    path = Path(path)
    with atomic_path(path) as tmp, h5py.File(tmp, "w") as f:
        f.attrs["format"] = FORMAT
        f.attrs["version"] = VERSION
        f.attrs["name"] = str(body.name)
        f.attrs["has_coordinates"] = bool(body.has_coordinates)
        f.attrs["notes"] = [str(note) for note in body.notes]
        f.attrs["precision"] = np.nan if body.precision is None else float(body.precision)
        _put(f, "nodes/ids", body.node_ids, np.int64)
        _put(f, "nodes/coordinates", body.coordinates, np.float64)
        _put(f, "dofs/nodes", body.dofs.nodes, np.int64)
        _put(f, "dofs/directions", body.dofs.directions, np.int64)
        _put_csr(f, "mass", body.mass)
        _put_csr(f, "stiffness", body.stiffness)
        if body.damping_matrix is not None:
            _put_csr(f, "damping_matrix", body.damping_matrix)
        _put(f, "constraints/dependent", body.constraints.dependent, np.int64)
        _put(f, "constraints/offset", body.constraints.offset, np.float64)
        _put_csr(f, "constraints/matrix", body.constraints.matrix)
        _put(f, "fixed", body.fixed, np.int64)
        damping = f.create_group("damping")
        damping.attrs["kind"] = body.damping.kind
        for key in ("alpha", "beta", "ratio"):
            damping.attrs[key] = np.float64(getattr(body.damping, key))
        if body.mesh is not None:
            _put(f, "mesh/connectivity", body.mesh.connectivity, np.int64)
            f["mesh"].attrs["element"] = body.mesh.element
            for key in ("young", "poisson"):
                value = getattr(body.mesh, key)
                if isinstance(value, np.ndarray):  # one per element
                    _put(f, f"mesh/{key}", value, np.float64)
                else:
                    f["mesh"].attrs[key] = value
            if body.mesh.section is not None:
                for key, value in asdict(body.mesh.section).items():
                    f["mesh"].attrs[f"section_{key}"] = float(value)
            if body.mesh.up is not None:
                f["mesh"].attrs["up"] = np.asarray(body.mesh.up, dtype=float)
        if body.surface is not None:
            _put(f, "surface/triangles", body.surface.triangles, np.int64)
            _put(f, "surface/lines", body.surface.lines, np.int64)
            f["surface"].attrs["source"] = body.surface.source
        if body.ports is not None:
            for key, labels in (
                ("inputs", body.ports.input_labels),
                ("outputs", body.ports.output_labels),
            ):
                matrix = getattr(body.ports, key)
                if matrix is not None:
                    _put_csr(f, f"ports/{key}", matrix)
                    f[f"ports/{key}"].attrs["labels"] = [str(label) for label in labels]
    return path


def read_body_h5(path: str | os.PathLike[str]) -> ElasticBody:
    """Read a body written by :func:`write_body_h5`.

    Raises
    ------
    UserError
        The file is missing, not HDF5, not a pymorembs body file, of a newer format version,
        or incomplete or inconsistent; the message names the file.
    """
    path = Path(path)
    if not path.exists():
        raise UserError(f"{path}: file not found (expected a pymorembs body .h5 file)")
    if path.is_dir():
        raise UserError(f"{path}: is a directory, expected a pymorembs body .h5 file")
    try:
        is_hdf5 = h5py.is_hdf5(path)
    except OSError as err:
        raise UserError(f"{path}: cannot read: {_one_line(err)}") from None
    if not is_hdf5:
        raise UserError(f"{path}: not an HDF5 file (expected a pymorembs body .h5 file)")
    try:
        with h5py.File(path, "r") as f:
            return _read_body(f)
    except UserError as err:
        raise UserError(f"{path}: {err}") from None
    except (OSError, KeyError, ValueError, TypeError, RuntimeError) as err:
        raise UserError(f"{path}: cannot read the body: {_one_line(err)}") from None


def _read_body(f: h5py.File) -> ElasticBody:
    """Check the format marker and build the body from an open file.

    Errors are :class:`UserError` without the file name, which the caller prepends.
    """
    if _text(f.attrs.get("format")) != FORMAT:
        raise UserError(f"HDF5 file without the format marker {FORMAT!r}; not a pymorembs body")
    version = f.attrs.get("version")
    if not isinstance(version, int | np.integer) or int(version) < 1:
        raise UserError(f"invalid format version {version!r}")
    if int(version) > VERSION:
        raise UserError(
            f"format version {int(version)} is newer than this pymorembs reads "
            f"(version {VERSION}); update pymorembs"
        )
    dofs = DofTable(_get(f, "dofs/nodes", _INT), _get(f, "dofs/directions", _INT))
    n_dof = len(dofs)
    damping = f.get("damping")
    if not isinstance(damping, h5py.Group):
        raise UserError("/damping is missing")
    ports = None
    if "ports" in f:
        parts: dict[str, Any] = {}
        for key in ("inputs", "outputs"):
            if f"ports/{key}" in f:
                matrix = (
                    _get_csr(f, f"ports/{key}", n_dof) if key == "outputs" else _get_csr_any(f, key)
                )
                labels = f[f"ports/{key}"].attrs.get("labels", [])
                parts[key] = matrix
                parts["input_labels" if key == "inputs" else "output_labels"] = tuple(
                    _text(label) for label in labels
                )
        ports = ModelPorts(**parts)
    notes = f.attrs.get("notes", [])
    precision = float(f.attrs.get("precision", np.nan))
    mesh = None
    if "mesh" in f:
        attrs = f["mesh"].attrs
        names = [field.name for field in fields(BeamSection)]
        section = None
        if all(f"section_{name}" in attrs for name in names):
            section = BeamSection(**{name: float(attrs[f"section_{name}"]) for name in names})
        up = attrs.get("up")
        material = {
            key: _get(f, f"mesh/{key}", _FLOAT)
            if key in f["mesh"]
            else float(attrs.get(key, np.nan))
            for key in ("young", "poisson")
        }
        mesh = ElementMesh(
            _text(attrs.get("element", "")),
            _get(f, "mesh/connectivity", _INT, ndim=2),
            material["young"],
            material["poisson"],
            section,
            None if up is None else tuple(float(x) for x in np.ravel(up)),
        )
    surface = None
    if "surface" in f:
        surface = Surface(
            _get(f, "surface/triangles", _INT, ndim=2),
            _get(f, "surface/lines", _INT, ndim=2),
            _text(f["surface"].attrs.get("source", "")),
        )
    return ElasticBody(
        node_ids=_get(f, "nodes/ids", _INT),
        coordinates=_get(f, "nodes/coordinates", _FLOAT, ndim=2),
        dofs=dofs,
        mass=_get_csr(f, "mass", n_dof),
        stiffness=_get_csr(f, "stiffness", n_dof),
        damping_matrix=_get_csr(f, "damping_matrix", n_dof) if "damping_matrix" in f else None,
        constraints=ConstraintEquations(
            _get(f, "constraints/dependent", _INT),
            _get_csr(f, "constraints/matrix", n_dof),
            _get(f, "constraints/offset", _FLOAT),
        ),
        fixed=_get(f, "fixed", _INT),
        damping=Damping(
            kind=_text(damping.attrs.get("kind")),  # type: ignore[arg-type]
            alpha=float(damping.attrs.get("alpha", 0.0)),
            beta=float(damping.attrs.get("beta", 0.0)),
            ratio=float(damping.attrs.get("ratio", 0.0)),
        ),
        name=_text(f.attrs.get("name", "body")),
        has_coordinates=bool(f.attrs.get("has_coordinates", True)),
        notes=tuple(_text(note) for note in np.atleast_1d(notes)),
        ports=ports,
        precision=None if np.isnan(precision) else precision,
        mesh=mesh,
        surface=surface,
    )


def _get_csr_any(f: h5py.Group, key: str) -> sp.csr_matrix:
    """The input matrix ``ports/<key>`` (its row count is checked by the body)."""
    group = f.get(f"ports/{key}")
    shape = np.asarray(group.attrs.get("shape", ())) if isinstance(group, h5py.Group) else ()
    columns = int(shape[1]) if np.shape(shape) == (2,) else -1
    return _get_csr(f, f"ports/{key}", columns)


def _put(f: h5py.Group, key: str, values: np.ndarray, dtype: type) -> None:
    """Store an array, compressed if large."""
    values = np.ascontiguousarray(values, dtype=dtype)
    options: dict[str, Any] = {}
    if values.size >= COMPRESS_FROM:
        options = {"compression": "gzip", "shuffle": True}
    f.create_dataset(key, data=values, **options)


def _put_csr(f: h5py.Group, key: str, matrix: sp.spmatrix | sp.sparray) -> None:
    """Store a sparse matrix as its CSR arrays and shape."""
    csr = sp.csr_matrix(matrix)
    group = f.require_group(key)
    group.attrs["shape"] = np.array(csr.shape, dtype=np.int64)
    _put(group, "data", csr.data, np.float64)
    _put(group, "indices", csr.indices, np.int64)
    _put(group, "indptr", csr.indptr, np.int64)


def _get(f: h5py.Group, key: str, kinds: str, ndim: int = 1) -> np.ndarray:
    """Read a dataset and check its element kind and number of dimensions."""
    node = f.get(key)
    if not isinstance(node, h5py.Dataset):
        raise UserError(f"/{_key(f, key)} is missing")
    values = np.asarray(node[()])
    if values.dtype.kind not in kinds or values.ndim != ndim:
        what = "integer" if kinds == _INT else "float"
        raise UserError(
            f"/{_key(f, key)} must be a {ndim}-d {what} array, not {values.ndim}-d {values.dtype}"
        )
    return values.astype(np.int64 if kinds == _INT else np.float64, copy=False)


def _get_csr(f: h5py.Group, key: str, columns: int) -> sp.csr_matrix:
    """Read and validate a CSR group with ``columns`` columns."""
    group = f.get(key)
    if not isinstance(group, h5py.Group):
        raise UserError(f"/{_key(f, key)} is missing")
    shape = np.asarray(group.attrs.get("shape", ()))
    if shape.shape != (2,) or shape.dtype.kind not in _INT or shape.min() < 0:
        raise UserError(f"/{_key(f, key)} has no valid shape attribute")
    rows, cols = (int(s) for s in shape)
    data = _get(group, "data", _FLOAT)
    indices = _get(group, "indices", _INT)
    indptr = _get(group, "indptr", _INT)
    valid = (
        cols == columns
        and indptr.size == rows + 1
        and indptr[0] == 0
        and indptr[-1] == data.size == indices.size
        and np.all(np.diff(indptr) >= 0)
        and (indices.size == 0 or (indices.min() >= 0 and indices.max() < cols))
    )
    if not valid:
        raise UserError(f"/{_key(f, key)} is not a valid CSR matrix with {columns} columns")
    return sp.csr_matrix((data, indices, indptr), shape=(rows, cols))


def _key(group: h5py.Group, key: str) -> str:
    """Full HDF5 name of ``key`` below ``group``, without the leading slash."""
    return f"{group.name.strip('/')}/{key}".strip("/")


def _text(value: object) -> str:
    """An HDF5 string attribute as str (h5py may give bytes)."""
    if isinstance(value, bytes):
        return value.decode("utf-8", errors="replace")
    return "" if value is None else str(value)


def _one_line(err: BaseException) -> str:
    return " ".join(str(err).split()) or type(err).__name__
