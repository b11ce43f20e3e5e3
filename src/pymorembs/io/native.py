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
    /mesh/element_ids      int64 (n_el,) the elements' numbers (absent in older files: 1 .. n_el)
    /surface/triangles     int64 (n_t, 3), /surface/lines int64 (n_l, 2): node ids of what a
                           viewer draws (outer faces, line elements), only if the body has a
                           surface; attribute source
    /node_sets/members     int64: the node ids of every named node set, one set after the
    /node_sets/offsets     other; int64 (n_sets + 1,) where each set starts; attribute names
                           (list of str, upper case); only if the body has node sets

Version 1 files (no coordinates flag, notes or ports) are read as well.

Arrays are stored exactly as they are in memory (floats bit for bit, sparsity structure as is);
arrays of more than :data:`COMPRESS_FROM` elements are gzip-compressed, which is lossless. Every
array carries a Fletcher-32 checksum (HDF5's ``fletcher32`` filter; files written before it are
read as well), so a file damaged after it was written is refused instead of read wrong.

The same layout may sit in a group of another file: a reduced body saved by ``ReducedBody.save``
(:mod:`pymorembs.io.reduced_file`) keeps its body in ``/body`` (:func:`write_body_group`,
:func:`read_body_group`); :func:`read_body_h5` of such a file says to load it with
``pymorembs.load``.
"""

from __future__ import annotations

import os
from collections.abc import Callable
from dataclasses import asdict, fields
from pathlib import Path
from typing import Any, TypeVar

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

__all__ = [
    "COMPRESS_FROM",
    "FLOAT_KINDS",
    "FORMAT",
    "INTEGER_KINDS",
    "REDUCED_BODY_FORMAT",
    "VERSION",
    "attribute_text",
    "get_array",
    "get_csr",
    "put_array",
    "put_csr",
    "read_body_group",
    "read_body_h5",
    "read_hdf5",
    "write_body_group",
    "write_body_h5",
]

#: Value of the root attribute ``format``.
FORMAT = "pymorembs-body"
#: Format version written (and the newest one read).
VERSION = 2
#: Arrays with at least this many elements are stored gzip-compressed.
COMPRESS_FROM = 4096

T = TypeVar("T")

#: The ``format`` attribute of a reduced body saved by ``ReducedBody.save``
#: (:mod:`pymorembs.io.reduced_file`), which holds a body in this layout in its group ``/body``.
REDUCED_BODY_FORMAT = "pymorembs-reduced-body"
#: dtype kinds accepted for integer and for float arrays (:func:`get_array`).
INTEGER_KINDS = "iu"
FLOAT_KINDS = "f"


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
        write_body_group(f, body)
    return path


def write_body_group(f: h5py.Group, body: ElasticBody) -> None:
    """Write ``body`` into an open HDF5 file or group ``f`` (the layout of the module
    docstring below ``f``; :func:`write_body_h5` writes it at the root of a file)."""
    f.attrs["format"] = FORMAT
    f.attrs["version"] = VERSION
    f.attrs["name"] = str(body.name)
    f.attrs["has_coordinates"] = bool(body.has_coordinates)
    f.attrs["notes"] = [str(note) for note in body.notes]
    f.attrs["precision"] = np.nan if body.precision is None else float(body.precision)
    put_array(f, "nodes/ids", body.node_ids, np.int64)
    put_array(f, "nodes/coordinates", body.coordinates, np.float64)
    put_array(f, "dofs/nodes", body.dofs.nodes, np.int64)
    put_array(f, "dofs/directions", body.dofs.directions, np.int64)
    put_csr(f, "mass", body.mass)
    put_csr(f, "stiffness", body.stiffness)
    if body.damping_matrix is not None:
        put_csr(f, "damping_matrix", body.damping_matrix)
    put_array(f, "constraints/dependent", body.constraints.dependent, np.int64)
    put_array(f, "constraints/offset", body.constraints.offset, np.float64)
    put_csr(f, "constraints/matrix", body.constraints.matrix)
    put_array(f, "fixed", body.fixed, np.int64)
    damping = f.create_group("damping")
    damping.attrs["kind"] = body.damping.kind.value  # h5py takes a plain str only
    for key in ("alpha", "beta", "ratio"):
        damping.attrs[key] = np.float64(getattr(body.damping, key))
    if body.mesh is not None:
        put_array(f, "mesh/connectivity", body.mesh.connectivity, np.int64)
        f["mesh"].attrs["element"] = body.mesh.element
        for key in ("young", "poisson"):
            value = getattr(body.mesh, key)
            if isinstance(value, np.ndarray):  # one per element
                put_array(f, f"mesh/{key}", value, np.float64)
            else:
                f["mesh"].attrs[key] = value
        if body.mesh.section is not None:
            for key, value in asdict(body.mesh.section).items():
                f["mesh"].attrs[f"section_{key}"] = float(value)
        if body.mesh.up is not None:
            f["mesh"].attrs["up"] = np.asarray(body.mesh.up, dtype=float)
        put_array(f, "mesh/element_ids", body.mesh.element_ids, np.int64)
    if body.surface is not None:
        put_array(f, "surface/triangles", body.surface.triangles, np.int64)
        put_array(f, "surface/lines", body.surface.lines, np.int64)
        f["surface"].attrs["source"] = body.surface.source
    if body.node_sets:
        sets = list(body.node_sets.values())
        offsets = np.cumsum([0] + [members.size for members in sets])
        put_array(f, "node_sets/members", np.concatenate(sets), np.int64)
        put_array(f, "node_sets/offsets", offsets, np.int64)
        f["node_sets"].attrs["names"] = list(body.node_sets)
    if body.ports is not None:
        for key, labels in (
            ("inputs", body.ports.input_labels),
            ("outputs", body.ports.output_labels),
        ):
            matrix = getattr(body.ports, key)
            if matrix is not None:
                put_csr(f, f"ports/{key}", matrix)
                f[f"ports/{key}"].attrs["labels"] = [str(label) for label in labels]


def read_body_h5(path: str | os.PathLike[str]) -> ElasticBody:
    """Read a body written by :func:`write_body_h5`.

    Raises
    ------
    UserError
        The file is missing, not HDF5, not a pymorembs body file, of a newer format version,
        or incomplete or inconsistent; the message names the file.
    """
    return read_hdf5(path, read_body_group, "a pymorembs body .h5 file", "the body")


def read_hdf5(
    path: str | os.PathLike[str], reader: Callable[[h5py.File], T], expected: str, what: str
) -> T:
    """Open an HDF5 file and build a value from it with ``reader``, every failure one line.

    Parameters
    ----------
    path : path-like
        The file.
    reader : callable
        Builds the value from the open file; raises :class:`UserError` without the file name.
    expected, what : str
        For the messages: what the file should be (``"a pymorembs body .h5 file"``) and what
        is read from it (``"the body"``).

    Raises
    ------
    UserError
        ``path: ...``: a missing file, a directory, not HDF5, an error of ``reader``, or a file
        HDF5 cannot read (truncated, damaged: a checksum that does not match).
    """
    path = Path(path)
    if not path.exists():
        raise UserError(f"{path}: file not found (expected {expected})")
    if path.is_dir():
        raise UserError(f"{path}: is a directory, expected {expected}")
    try:
        is_hdf5 = h5py.is_hdf5(path)
    except OSError as err:
        raise UserError(f"{path}: cannot read: {_one_line(err)}") from None
    if not is_hdf5:
        raise UserError(f"{path}: not an HDF5 file (expected {expected})")
    try:
        with h5py.File(path, "r") as f:
            return reader(f)
    except UserError as err:
        raise UserError(f"{path}: {err}") from None
    except (OSError, KeyError, ValueError, TypeError, RuntimeError) as err:
        reason = _one_line(err)
        if "filter returned failure" in reason:  # HDF5's words for a failed checksum
            reason = f"the file is damaged: an array fails its checksum ({reason})"
        raise UserError(f"{path}: cannot read {what}: {reason}") from None


def check_format_version(f: h5py.Group, newest: int) -> int:
    """The ``version`` attribute of a pymorembs file, checked to be ``1 .. newest``.

    Raises
    ------
    UserError
        Not a whole number >= 1, or newer than this pymorembs reads (without the file name,
        which the caller prepends).
    """
    version = f.attrs.get("version")
    if not isinstance(version, int | np.integer) or int(version) < 1:
        raise UserError(f"invalid format version {version!r}")
    if int(version) > newest:
        raise UserError(
            f"format version {int(version)} is newer than this pymorembs reads "
            f"(version {newest}); update pymorembs"
        )
    return int(version)


def read_body_group(f: h5py.Group) -> ElasticBody:
    """Check the format marker and build the body from an open file or group.

    Errors are :class:`UserError` without the file name, which the caller prepends.
    """
    marker = attribute_text(f.attrs.get("format"))
    if marker == REDUCED_BODY_FORMAT:
        raise UserError(
            "a reduced body saved by ReducedBody.save, not an FE model; open it with "
            "pymorembs.load(path)"
        )
    if marker != FORMAT:
        raise UserError(f"HDF5 file without the format marker {FORMAT!r}; not a pymorembs body")
    check_format_version(f, VERSION)
    dofs = DofTable(
        get_array(f, "dofs/nodes", INTEGER_KINDS), get_array(f, "dofs/directions", INTEGER_KINDS)
    )
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
                    get_csr(f, f"ports/{key}", n_dof) if key == "outputs" else _get_csr_any(f, key)
                )
                labels = f[f"ports/{key}"].attrs.get("labels", [])
                parts[key] = matrix
                parts["input_labels" if key == "inputs" else "output_labels"] = tuple(
                    attribute_text(label) for label in labels
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
            key: get_array(f, f"mesh/{key}", FLOAT_KINDS)
            if key in f["mesh"]
            else float(attrs.get(key, np.nan))
            for key in ("young", "poisson")
        }
        mesh = ElementMesh(
            attribute_text(attrs.get("element", "")),
            get_array(f, "mesh/connectivity", INTEGER_KINDS, ndim=2),
            material["young"],
            material["poisson"],
            section,
            None if up is None else tuple(float(x) for x in np.ravel(up)),
            get_array(f, "mesh/element_ids", INTEGER_KINDS) if "element_ids" in f["mesh"] else None,
        )
    surface = None
    if "surface" in f:
        surface = Surface(
            get_array(f, "surface/triangles", INTEGER_KINDS, ndim=2),
            get_array(f, "surface/lines", INTEGER_KINDS, ndim=2),
            attribute_text(f["surface"].attrs.get("source", "")),
        )
    node_sets = {}
    if "node_sets" in f:
        members = get_array(f, "node_sets/members", INTEGER_KINDS)
        offsets = get_array(f, "node_sets/offsets", INTEGER_KINDS)
        names = [attribute_text(name) for name in f["node_sets"].attrs.get("names", [])]
        if (
            offsets.size != len(names) + 1
            or np.any(np.diff(offsets) < 0)
            or (offsets[0] != 0 or offsets[-1] != members.size)
        ):
            raise UserError("node_sets: offsets do not fit the names and members")
        node_sets = {
            name: members[start:end]
            for name, start, end in zip(names, offsets[:-1], offsets[1:], strict=True)
        }
    return ElasticBody(
        node_ids=get_array(f, "nodes/ids", INTEGER_KINDS),
        coordinates=get_array(f, "nodes/coordinates", FLOAT_KINDS, ndim=2),
        dofs=dofs,
        mass=get_csr(f, "mass", n_dof),
        stiffness=get_csr(f, "stiffness", n_dof),
        damping_matrix=get_csr(f, "damping_matrix", n_dof) if "damping_matrix" in f else None,
        constraints=ConstraintEquations(
            get_array(f, "constraints/dependent", INTEGER_KINDS),
            get_csr(f, "constraints/matrix", n_dof),
            get_array(f, "constraints/offset", FLOAT_KINDS),
        ),
        fixed=get_array(f, "fixed", INTEGER_KINDS),
        damping=Damping(
            kind=attribute_text(damping.attrs.get("kind")),  # type: ignore[arg-type]
            alpha=float(damping.attrs.get("alpha", 0.0)),
            beta=float(damping.attrs.get("beta", 0.0)),
            ratio=float(damping.attrs.get("ratio", 0.0)),
        ),
        name=attribute_text(f.attrs.get("name", "body")),
        has_coordinates=bool(f.attrs.get("has_coordinates", True)),
        notes=tuple(attribute_text(note) for note in np.atleast_1d(notes)),
        ports=ports,
        precision=None if np.isnan(precision) else precision,
        mesh=mesh,
        surface=surface,
        node_sets=node_sets,
    )


def _get_csr_any(f: h5py.Group, key: str) -> sp.csr_matrix:
    """The input matrix ``ports/<key>`` (its row count is checked by the body)."""
    group = f.get(f"ports/{key}")
    shape = np.asarray(group.attrs.get("shape", ())) if isinstance(group, h5py.Group) else ()
    columns = int(shape[1]) if np.shape(shape) == (2,) else -1
    return get_csr(f, f"ports/{key}", columns)


def put_array(f: h5py.Group, key: str, values: np.ndarray, dtype: type) -> None:
    """Store an array (at least 1-d) with a Fletcher-32 checksum, so that a damaged file is
    refused when it is read, and gzip-compressed from :data:`COMPRESS_FROM` elements on."""
    values = np.ascontiguousarray(values, dtype=dtype)
    options: dict[str, Any] = {"fletcher32": True}
    if values.size >= COMPRESS_FROM:
        options.update(compression="gzip", shuffle=True)
    f.create_dataset(key, data=values, **options)


def put_csr(f: h5py.Group, key: str, matrix: sp.spmatrix | sp.sparray) -> None:
    """Store a sparse matrix as its CSR arrays (:func:`put_array`) and shape."""
    csr = sp.csr_matrix(matrix)
    group = f.require_group(key)
    group.attrs["shape"] = np.array(csr.shape, dtype=np.int64)
    put_array(group, "data", csr.data, np.float64)
    put_array(group, "indices", csr.indices, np.int64)
    put_array(group, "indptr", csr.indptr, np.int64)


def get_array(f: h5py.Group, key: str, kinds: str, ndim: int = 1) -> np.ndarray:
    """Read a dataset and check its element kind and number of dimensions."""
    node = f.get(key)
    if not isinstance(node, h5py.Dataset):
        raise UserError(f"/{_key(f, key)} is missing")
    values = np.asarray(node[()])
    if values.dtype.kind not in kinds or values.ndim != ndim:
        what = "integer" if kinds == INTEGER_KINDS else "float"
        raise UserError(
            f"/{_key(f, key)} must be a {ndim}-d {what} array, not {values.ndim}-d {values.dtype}"
        )
    return values.astype(np.int64 if kinds == INTEGER_KINDS else np.float64, copy=False)


def get_csr(f: h5py.Group, key: str, columns: int) -> sp.csr_matrix:
    """Read and validate a CSR group with ``columns`` columns."""
    group = f.get(key)
    if not isinstance(group, h5py.Group):
        raise UserError(f"/{_key(f, key)} is missing")
    shape = np.asarray(group.attrs.get("shape", ()))
    if shape.shape != (2,) or shape.dtype.kind not in INTEGER_KINDS or shape.min() < 0:
        raise UserError(f"/{_key(f, key)} has no valid shape attribute")
    rows, cols = (int(s) for s in shape)
    data = get_array(group, "data", FLOAT_KINDS)
    indices = get_array(group, "indices", INTEGER_KINDS)
    indptr = get_array(group, "indptr", INTEGER_KINDS)
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


def attribute_text(value: object) -> str:
    """An HDF5 string attribute or string as str (h5py may give bytes)."""
    if isinstance(value, bytes):
        return value.decode("utf-8", errors="replace")
    return "" if value is None else str(value)


def _one_line(err: BaseException) -> str:
    return " ".join(str(err).split()) or type(err).__name__
