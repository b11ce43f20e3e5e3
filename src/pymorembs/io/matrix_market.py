"""An elastic body as Matrix Market matrices plus CSV tables.

One directory holds one body (:func:`write_matrix_files`, :func:`read_matrix_files`,
:func:`read_matrix_directory`):

``K.mtx``, ``M.mtx``
    Stiffness and mass matrix, Matrix Market ``coordinate real``. Written with ``symmetric``
    storage (lower triangle) when the matrix is exactly symmetric, otherwise ``general``. Values
    are written as the shortest decimal that reads back to the same float, so a round trip is
    bit-exact.
``D.mtx``
    Viscous damping matrix (only if the body has one): the explicit damping matrix plus the
    Rayleigh part, ``body.viscous_damping()``. It reads back as the explicit damping matrix of a
    body without damping model; modal damping ratios are not kept (the HDF5 format of
    :mod:`pymorembs.io.native` keeps the damping model itself).
``dofs.csv``
    Header ``node,direction``; one row per equation in matrix order; direction ``ux uy uz rx ry
    rz``.
``nodes.csv``
    Header ``id,x,y,z``; coordinates in full precision.
``constraints.csv`` (only if the body has constraint equations ``q_d = G q + g``)
    Header ``dependent_node,dependent_direction,offset,node,direction,coefficient``. One row per
    non-zero term ``G[d, j]``: the dependent dof ``d``, its offset ``g_d`` (repeated, identical on
    every row of the same equation), the dof ``j`` and the coefficient. A dependent dof whose row
    of ``G`` is empty (``q_d = g_d``) is one row with empty ``node``, ``direction`` and
    ``coefficient``::

        dependent_node,dependent_direction,offset,node,direction,coefficient
        12,uz,0.0,7,uz,0.5
        12,uz,0.0,9,uz,0.5
        15,rx,0.001,,,

    The equations keep the order of first appearance of their dependent dof.
``fixed.csv`` (only if the body has fixed dofs ``q_c = 0``)
    Header ``node,direction``.

Reading CSV files tolerates blank lines, lines starting with ``#``, whitespace around fields and
upper-case directions; the header line is required. Reading Matrix Market accepts ``coordinate``
and ``array`` files with ``real``/``integer`` values and ``general``/``symmetric`` storage; a
symmetric coordinate file may store either triangle (not both). Every mistake raises
:class:`~pymorembs.errors.UserError` with one line ``file:line: what is wrong``.

Speed: the numbers of a coordinate file are parsed by fast_matrix_market (``scipy.io.mmread``,
multi-threaded) and those of a CSV table by NumPy's ``loadtxt``, each behind checks of the raw
bytes that prove the result is the one of the strict line-by-line pass
(:class:`pymorembs.io.fast_text.PlainNumberScan`, run on the bytes while fast_matrix_market
reads them, so the file is read once); a file that fails a check (a comment after the size line,
an integer-valued matrix, any mistake such as ``1.0.5`` or ``1 1.5 2.0``) is read by the strict
pass, which names the line.
"""

from __future__ import annotations

import csv
import io
import itertools
import math
import os
import warnings
from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path
from typing import Literal

import numpy as np
import scipy.io
import scipy.sparse as sp

from pymorembs.body import DIRECTIONS, ConstraintEquations, DofTable, ElasticBody, direction_code
from pymorembs.errors import UserError, located_error
from pymorembs.io.atomic import atomic_open, write_text
from pymorembs.io.compressed import COMPRESSIONS
from pymorembs.io.fast_text import (
    CheckedReader,
    PlainNumberScan,
    SymmetricRoom,
    all_distinct,
    canonical_csr,
    compiled_worthwhile,
    csr_from_sorted_coo,
    full_from_triangle,
    parse_coordinate_lines,
    transpose_gap,
    triangle_sides,
)

__all__ = [
    "FILE_NAMES",
    "MAX_EQUATIONS",
    "SYMMETRY_TOLERANCE",
    "DataLines",
    "check_symmetric",
    "directory_files",
    "encoding_note",
    "read_matrix_directory",
    "read_matrix_files",
    "read_matrix_market",
    "read_matrix_market_with_storage",
    "write_matrix_files",
    "write_matrix_market",
]

PathLike = str | os.PathLike[str]

#: File name of each part of a body in a directory, keyed like the arguments of
#: :func:`read_matrix_files`.
FILE_NAMES: dict[str, str] = {
    "stiffness": "K.mtx",
    "mass": "M.mtx",
    "damping": "D.mtx",
    "dofs": "dofs.csv",
    "nodes": "nodes.csv",
    "constraints": "constraints.csv",
    "fixed": "fixed.csv",
}

#: Largest accepted ``|A[i, j] - A[j, i]|`` relative to the largest ``|A[i, j]|``.
SYMMETRY_TOLERANCE = 1e-10

_DOF_HEADER = ("node", "direction")
_NODE_HEADER = ("id", "x", "y", "z")
_CONSTRAINT_HEADER = (
    "dependent_node",
    "dependent_direction",
    "offset",
    "node",
    "direction",
    "coefficient",
)
_INT64_MAX = 2**63 - 1
_NODE_LIMIT = 2**60  # node ids are keyed as node * 8 + direction in int64
#: Largest matrix size read (32-bit equation indices, as in the sparse solvers).
MAX_EQUATIONS = 2**31 - 1
#: From this size on, a coordinate file whose entries leave most rows empty is refused: its size
#: line is surely wrong, and the empty rows alone would take gigabytes.
_MOSTLY_EMPTY_FROM = 1 << 24


# ============================================================================ body <-> directory
def write_matrix_files(body: ElasticBody, directory: PathLike) -> dict[str, Path]:
    """Write ``body`` as Matrix Market and CSV files into ``directory`` (created if needed).

    Parameters
    ----------
    body : ElasticBody
        The body; its mass, stiffness and damping matrices must be symmetric (see
        :func:`check_symmetric`).
    directory : path-like
        Target directory. Optional files of an earlier write (``D.mtx``, ``constraints.csv``,
        ``fixed.csv``) that this body does not need are removed, so the directory always
        describes exactly this body.

    Returns
    -------
    dict of str to Path
        The written files keyed like the arguments of :func:`read_matrix_files` (``"stiffness"``,
        ``"mass"``, ``"damping"``, ``"dofs"``, ``"nodes"``, ``"constraints"``, ``"fixed"``), so
        ``read_matrix_files(**write_matrix_files(body, d))`` reads the body back.
    """
    directory = Path(directory)
    damping = body.viscous_damping()
    matrices = {"stiffness": body.stiffness, "mass": body.mass}
    if damping is not None:
        matrices["damping"] = damping
    for key, matrix in matrices.items():
        check_symmetric(matrix, f"body {body.name!r}: {key} matrix")
    try:
        directory.mkdir(parents=True, exist_ok=True)
    except OSError as err:
        raise UserError(f"{directory}: cannot create the directory: {err.strerror}") from None

    paths: dict[str, Path] = {}
    label = " ".join(str(body.name).split())
    for key, matrix in matrices.items():
        paths[key] = write_matrix_market(
            directory / FILE_NAMES[key], matrix, comment=f"pymorembs body {label}: {key} matrix"
        )
    table = body.dofs
    paths["dofs"] = _write_csv(directory / FILE_NAMES["dofs"], _DOF_HEADER, _dof_rows(table))
    paths["nodes"] = _write_csv(
        directory / FILE_NAMES["nodes"],
        _NODE_HEADER,
        (
            f"{node},{x!r},{y!r},{z!r}"
            for node, (x, y, z) in zip(
                body.node_ids.tolist(), body.coordinates.tolist(), strict=True
            )
        ),
    )
    if len(body.constraints):
        paths["constraints"] = _write_csv(
            directory / FILE_NAMES["constraints"],
            _CONSTRAINT_HEADER,
            _constraint_rows(body.constraints, table),
        )
    if body.fixed.size:
        paths["fixed"] = _write_csv(
            directory / FILE_NAMES["fixed"], _DOF_HEADER, _dof_rows(table, body.fixed)
        )
    for key in ("damping", "constraints", "fixed"):
        if key not in paths:
            (directory / FILE_NAMES[key]).unlink(missing_ok=True)
    return paths


def read_matrix_files(
    stiffness: PathLike,
    mass: PathLike,
    damping: PathLike | None = None,
    dofs: PathLike | None = None,
    nodes: PathLike | None = None,
    constraints: PathLike | None = None,
    fixed: PathLike | None = None,
    name: str | None = None,
) -> ElasticBody:
    """Read a body from Matrix Market matrices and CSV tables (layout in the module docstring).

    Parameters
    ----------
    stiffness, mass : path-like
        Matrix Market files of ``K`` and ``M``; square, real, of equal size and symmetric to a
        relative tolerance of :data:`SYMMETRY_TOLERANCE`.
    damping : path-like, optional
        Matrix Market file of an explicit viscous damping matrix (becomes
        ``ElasticBody.damping_matrix``); symmetric like ``K`` and ``M``.
    dofs : path-like, optional
        ``dofs.csv``. Without it the dof table is generic: equation ``i`` (from 0) is direction
        ``ux`` of node ``i + 1``.
    nodes : path-like, optional
        ``nodes.csv``, or the input deck of an FE program (an Abaqus or CalculiX ``.inp``, an
        Ansys ``.cdb``, Nastran bulk data or ``.f06``: :func:`pymorembs.io.node_files.
        read_node_file`); it must hold every node of the dof table. Without it, every node of
        the dof table lies at the origin.
    constraints, fixed : path-like, optional
        ``constraints.csv`` and ``fixed.csv``.
    name : str, optional
        Label of the body; default: the name of the directory holding the stiffness file.

    Returns
    -------
    ElasticBody

    Raises
    ------
    UserError
        Any missing, malformed or inconsistent file, with file and line in one line.
    """
    k_path, m_path = Path(stiffness), Path(mass)
    k_matrix = _read_symmetric(k_path)
    n = k_matrix.shape[0]
    if n == 0:
        raise located_error(k_path, None, "a 0 x 0 matrix: the model has no dofs")
    m_matrix = _read_symmetric(m_path, like=(k_path, n))
    d_matrix = None if damping is None else _read_symmetric(Path(damping), like=(k_path, n))

    dof_lines: list[int] | None = None
    if dofs is None:
        table = DofTable(np.arange(1, n + 1), np.zeros(n, dtype=np.int64))
    else:
        dofs_path = Path(dofs)
        table, dof_lines = read_dofs_csv(dofs_path)
        if len(table) != n:
            raise located_error(
                dofs_path, None, f"{len(table)} dofs but {k_path} is a {n} x {n} matrix"
            )

    notes: list[str] = []
    if nodes is None:
        _, first = np.unique(table.nodes, return_index=True)
        node_ids = table.nodes[np.sort(first)]
        coordinates = np.zeros((node_ids.size, 3))
    else:
        # (imported here: the node file readers import this module)
        from pymorembs.io.node_files import read_node_file

        node_file = read_node_file(nodes)
        nodes_path, node_ids, coordinates = node_file.path, node_file.ids, node_file.coordinates
        if node_file.kind != "csv":
            notes.append(f"coordinates: {node_file.describe()}")
        missing = np.flatnonzero(~np.isin(table.nodes, node_ids))
        if missing.size:
            first_missing = int(missing[0])
            node = int(table.nodes[first_missing])
            if dof_lines is None:  # the missing file is the dof table, not nodes.csv
                raise located_error(
                    k_path,
                    None,
                    f"no dof table (dofs.csv) given: without it equation {first_missing + 1} "
                    f"is ux of node {node}, which {nodes_path} does not list",
                )
            raise located_error(
                Path(dofs), dof_lines[first_missing], f"node {node} is not listed in {nodes_path}"
            )

    equations = None if constraints is None else read_constraints_csv(Path(constraints), table)
    fixed_dofs = (
        np.zeros(0, dtype=np.int64) if fixed is None else read_fixed_csv(Path(fixed), table)
    )
    if name is None:
        name = k_path.resolve().parent.name or "body"
    try:
        return ElasticBody(
            node_ids=node_ids,
            coordinates=coordinates,
            dofs=table,
            mass=m_matrix,
            stiffness=k_matrix,
            damping_matrix=d_matrix,
            constraints=equations,
            fixed=fixed_dofs,
            name=name,
            notes=tuple(notes),
        )
    except UserError as err:
        raise UserError(f"{k_path}: {err}") from None


def read_matrix_directory(directory: PathLike, name: str | None = None) -> ElasticBody:
    """Read a body written by :func:`write_matrix_files` from ``directory``.

    ``K.mtx`` and ``M.mtx`` are required; ``D.mtx``, ``dofs.csv``, ``nodes.csv``,
    ``constraints.csv`` and ``fixed.csv`` are read when present (see :func:`read_matrix_files`
    for what their absence means). ``name`` defaults to the directory name.
    """
    paths = directory_files(directory)
    return read_matrix_files(name=name, **paths)


def directory_files(directory: PathLike) -> dict[str, Path]:
    """The files of a body in ``directory`` (:data:`FILE_NAMES`), each plain or compressed.

    Returns
    -------
    dict of str -> Path
        Keyed like the arguments of :func:`read_matrix_files`: ``stiffness`` and ``mass``
        always (``K.mtx``, ``M.mtx`` or a compressed ``K.mtx.gz``, ``.bz2``, ``.xz``; the plain
        name when neither exists, so that the reader says it is missing), the others when
        present.

    Raises
    ------
    UserError
        ``directory`` is not a directory.
    """
    directory = Path(directory)
    if not directory.is_dir():
        raise UserError(f"{directory}: not a directory of Matrix Market and CSV files")
    found = {}
    for key, file in FILE_NAMES.items():
        candidates = [directory / file] + [
            directory / f"{file}{suffix}" for suffix, _ in COMPRESSIONS.values()
        ]
        path = next((c for c in candidates if c.is_file()), None)
        if path is not None or key in ("stiffness", "mass"):
            found[key] = path if path is not None else candidates[0]
    return found


# ============================================================================ Matrix Market
def write_matrix_market(
    path: PathLike,
    matrix: sp.spmatrix | sp.sparray | np.ndarray,
    *,
    symmetry: Literal["auto", "general", "symmetric"] = "auto",
    comment: str | None = None,
) -> Path:
    """Write a real matrix atomically as Matrix Market ``coordinate real``.

    Parameters
    ----------
    path : path-like
        Target file.
    matrix : sparse matrix or ndarray
        Finite real matrix. Duplicate entries are summed; explicit zeros are kept.
    symmetry : {"auto", "general", "symmetric"}
        ``"symmetric"`` stores the lower triangle and requires an exactly symmetric matrix;
        ``"auto"`` (default) does so whenever the matrix is exactly symmetric.
    comment : str, optional
        One comment line after the header.

    Returns
    -------
    Path
        ``path``.
    """
    path = Path(path)
    if symmetry not in ("auto", "general", "symmetric"):
        raise ValueError(f"symmetry must be 'auto', 'general' or 'symmetric', not {symmetry!r}")
    if np.iscomplexobj(matrix.data if sp.issparse(matrix) else np.asarray(matrix)):
        raise UserError(f"{path}: cannot write a complex matrix")
    a = sp.csr_matrix(matrix, dtype=float, copy=True)
    a.sum_duplicates()
    if not np.all(np.isfinite(a.data)):
        raise UserError(f"{path}: cannot write a matrix with NaN or infinite entries")
    exact = _exactly_symmetric(a)
    if symmetry == "symmetric" and not exact:
        raise UserError(f"{path}: symmetric storage requested but the matrix is not symmetric")
    symmetric = exact and symmetry != "general"
    coo = sp.tril(a, format="coo") if symmetric else a.tocoo()
    header = [f"%%MatrixMarket matrix coordinate real {'symmetric' if symmetric else 'general'}"]
    if comment:
        header.append("% " + " ".join(comment.split()))
    header.append(f"{a.shape[0]} {a.shape[1]} {coo.nnz}")
    with atomic_open(path, "w") as out:
        out.write("\n".join(header) + "\n")
        for start in range(0, coo.nnz, _WRITE_BLOCK):  # in blocks: memory stays small
            block = slice(start, start + _WRITE_BLOCK)
            out.write(
                "".join(
                    f"{i} {j} {v!r}\n"
                    for i, j, v in zip(
                        (coo.row[block] + 1).tolist(),
                        (coo.col[block] + 1).tolist(),
                        coo.data[block].tolist(),
                        strict=True,
                    )
                )
            )
    return path


#: Entries formatted at a time by :func:`write_matrix_market`.
_WRITE_BLOCK = 1 << 16


def read_matrix_market(path: PathLike) -> sp.csr_matrix:
    """Read a real Matrix Market file (coordinate or array; general or symmetric storage).

    Parameters
    ----------
    path : path-like
        The file.

    Returns
    -------
    scipy.sparse.csr_matrix
        The full matrix (a symmetric file is mirrored), canonical (sorted, no duplicates).

    Raises
    ------
    UserError
        Not a Matrix Market file, complex or pattern-only values, skew/hermitian storage, an
        entry out of range, duplicated or non-finite, both triangles in a symmetric file, a
        wrong number of entries, a size beyond :data:`MAX_EQUATIONS`, or (from 2**24 equations
        on) a coordinate file whose entries would leave most rows empty; the message names file
        and line.
    """
    return _read_matrix_market(Path(path))[0]


def read_matrix_market_with_storage(path: PathLike) -> tuple[sp.csr_matrix, bool]:
    """Read a Matrix Market file as :func:`read_matrix_market` does, and tell its storage.

    Returns
    -------
    matrix : scipy.sparse.csr_matrix
        As :func:`read_matrix_market`.
    mirrored : bool
        True for ``symmetric`` storage: the stored triangle was mirrored exactly, so the matrix
        is symmetric by construction and needs no :func:`check_symmetric`.
    """
    return _read_matrix_market(Path(path))


def _read_matrix_market(path: Path) -> tuple[sp.csr_matrix, bool]:
    """The matrix of :func:`read_matrix_market` and whether the file had symmetric storage."""
    fast = _read_coordinate_fast(path)
    if fast is not None:
        return fast
    lines = read_text_lines(path, "a Matrix Market file")
    header = _parse_header(path, lines)
    n, size_line = header.n, header.size_line
    data = DataLines(path, lines, header.data_index)
    if header.layout == "coordinate":
        table = data.parse((("row", int), ("column", int), ("value", float)))
        if table.size != header.entries:
            raise located_error(
                path,
                size_line,
                f"size line announces {header.entries} entries but the file holds {table.size}",
            )
        if n > _MOSTLY_EMPTY_FROM and n > 2 * table.size:
            raise located_error(
                path,
                size_line,
                f"size line announces a {n} x {n} matrix but the file holds only {table.size} "
                "entries, so most rows would be empty; is the size line right?",
            )
        matrix = _coordinate_matrix(
            data, table["row"] - 1, table["column"] - 1, table["value"], n, header.symmetric
        )
        return matrix, header.symmetric

    values = data.parse((("value", float),))["value"]
    expected = n * (n + 1) // 2 if header.symmetric else n * n
    if values.size != expected:
        raise located_error(
            path, size_line, f"{n} x {n} array needs {expected} values, found {values.size}"
        )
    data.require_finite(values)
    dense = np.zeros((n, n))
    if header.symmetric:  # lower triangle, column by column
        cols, rows = np.triu_indices(n)
        dense[rows, cols] = values
        dense[cols, rows] = values
    else:
        dense[:] = values.reshape((n, n), order="F")
    return sp.csr_matrix(dense), header.symmetric


@dataclass(frozen=True)
class _Header:
    """The banner and size line of a Matrix Market file."""

    layout: str  # "coordinate" or "array"
    field: str  # "real", "double" or "integer"
    symmetric: bool
    n: int
    entries: int  # announced entries of a coordinate file (0 for an array file)
    size_line: int  # line number of the size line (from 1)
    data_index: int  # index in the lines of the first line after the size line
    banner_storage: tuple[int, int]  # character span of the storage word in the banner


def _parse_header(path: Path, lines: list[str]) -> _Header:
    """Check the banner and the size line; :class:`UserError` names the line."""
    banner = lines[0].split()
    if not banner or banner[0].lower() != "%%matrixmarket":
        raise located_error(
            path, 1, "not a Matrix Market file (the first line must be %%MatrixMarket ...)"
        )
    if len(banner) != 5:
        raise located_error(
            path,
            1,
            "header must read %%MatrixMarket matrix coordinate|array real general|symmetric",
        )
    obj, layout, field, storage = (word.lower() for word in banner[1:])
    if obj != "matrix":
        raise located_error(path, 1, f"object {banner[1]!r} is not supported, expected 'matrix'")
    if layout not in ("coordinate", "array"):
        raise located_error(
            path, 1, f"format {banner[2]!r} is unknown, expected coordinate or array"
        )
    if field == "complex":
        raise located_error(path, 1, "complex matrix; mass, stiffness and damping must be real")
    if field == "pattern":
        raise located_error(path, 1, "pattern-only matrix: the file holds positions but no values")
    if field not in ("real", "double", "integer"):
        raise located_error(
            path, 1, f"value type {banner[3]!r} is unknown, expected real or integer"
        )
    if storage not in ("general", "symmetric"):
        raise located_error(
            path, 1, f"{banner[4]!r} storage is not supported, expected general or symmetric"
        )

    size_index = next(
        (k for k in range(1, len(lines)) if lines[k].split("%", 1)[0].strip()),
        None,
    )
    if size_index is None:
        raise located_error(path, None, "no size line after the header")
    size_line = size_index + 1
    size_words = lines[size_index].split()
    expected_words = 3 if layout == "coordinate" else 2
    if len(size_words) != expected_words:
        what = "rows columns entries" if layout == "coordinate" else "rows columns"
        raise located_error(
            path, size_line, f"size line must hold {expected_words} integers ({what})"
        )
    sizes = [parse_int(w, path, size_line, "size", minimum=0) for w in size_words]
    n_rows, n_cols = sizes[0], sizes[1]
    if n_rows != n_cols:
        raise located_error(path, size_line, f"matrix is {n_rows} x {n_cols}, not square")
    if n_rows > MAX_EQUATIONS:
        raise located_error(
            path,
            size_line,
            f"matrix size {n_rows} exceeds the {MAX_EQUATIONS} equations pymorembs reads; is the "
            "size line right?",
        )
    return _Header(
        layout=layout,
        field=field,
        symmetric=storage == "symmetric",
        n=n_rows,
        entries=sizes[2] if layout == "coordinate" else 0,
        size_line=size_line,
        data_index=size_index + 1,
        banner_storage=(lines[0].rstrip().rfind(banner[4]), len(lines[0].rstrip())),
    )


# ---------------------------------------------------------------------------- the fast path
#: Bytes read to find the banner and the size line of the fast path (a longer header is read by
#: the strict pass).
_HEAD_BYTES = 1 << 16
#: The shortest entry line, ``1 1 1`` and its line feed.
_MIN_ENTRY_BYTES = 6
#: Entry bytes from which the fast path is tried (a smaller file is read by the strict pass in
#: well under a millisecond per kilobyte; thread start-up would cost more).
_FAST_FROM_BYTES = 1 << 16


def _read_coordinate_fast(path: Path) -> tuple[sp.csr_matrix, bool] | None:
    """The matrix of a well-formed coordinate file and whether its storage is symmetric, or None
    to leave the file to the strict pass.

    The numbers are parsed by fast_matrix_market (``scipy.io.mmread``, multi-threaded) while the
    bytes it reads pass the checks of :class:`~pymorembs.io.fast_text.PlainNumberScan` (the file
    is read once). Its result is taken only when the header passes :func:`_parse_header`; the
    entry lines hold only plain numbers, three fields on every non-blank line of which the first
    two are unsigned integers, one line per announced entry; the values are finite; a symmetric
    file stores one triangle; no entry is given twice. Then every field was read whole and the
    result equals the one of the strict pass. Anything else (a bad or unusual line, an integer
    file, a comment after the size line, an error of the parser) returns None, and the strict
    pass reads the file again and names the problem.
    """
    head = _fast_head(path)
    if head is None:
        return None
    header, offset = head
    n, entries = header.n, header.entries
    if header.layout != "coordinate" or header.field == "integer":
        return None
    try:
        data_bytes = path.stat().st_size - offset
    except OSError:
        return None
    if data_bytes < _FAST_FROM_BYTES:
        return None  # the strict pass is quicker than starting the parser's threads
    if entries * _MIN_ENTRY_BYTES > data_bytes + 1 or (n > _MOSTLY_EMPTY_FROM and n > 2 * entries):
        return None
    compiled = _parse_compiled(path, offset, header, data_bytes)
    parsed, room = (_parse_checked(path, offset, header), None) if compiled is None else compiled
    if parsed is None:
        return None
    matrix = _general_csr(*parsed, n)
    del parsed
    if matrix is None:
        return None
    if not header.symmetric:
        return matrix, False
    below, above = triangle_sides(matrix)
    if below and above:
        return None  # both triangles: the strict pass names the entry
    full = None if room is None else room.full(matrix)
    return (_mirrored(matrix, below) if full is None else full), True


def _parse_compiled(
    path: Path, offset: int, header: _Header, data_bytes: int
) -> tuple[tuple[np.ndarray, np.ndarray, np.ndarray], SymmetricRoom | None] | None:
    """The entries of a large file parsed and checked in one pass by the compiled kernel
    (:func:`~pymorembs.io.fast_text.parse_coordinate_lines`), and the room they were put in,
    or None (no Numba, a small file while the kernels are not loaded, or a line the kernel does
    not take). A symmetric file's entries go into a
    :class:`~pymorembs.io.fast_text.SymmetricRoom`, where the triangle is completed without a
    second copy of the matrix."""
    if not compiled_worthwhile(data_bytes):
        return None  # loading the compiled code would cost more than it saves
    entries = header.entries
    room = SymmetricRoom(entries) if header.symmetric and SymmetricRoom.fits(entries) else None
    out = None if room is None else (room.rows, room.cols, room.values)
    parsed = parse_coordinate_lines(path, offset, header.n, entries, out)
    return None if parsed is None else (parsed, room)


def _parse_checked(
    path: Path, offset: int, header: _Header
) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
    """The entries parsed by fast_matrix_market while the bytes pass the checks of
    :class:`~pymorembs.io.fast_text.PlainNumberScan`, or None."""
    n, entries = header.n, header.entries
    # a symmetric file is read as stored: scipy.io.mmread mirrors a symmetric file in Python
    # with array copies that take longer than the parse itself (and twice the memory of the
    # result); _mirrored completes the stored triangle in CSR form
    start, stop = header.banner_storage
    patch = (start, b"general".ljust(stop - start)) if header.symmetric else None
    scan = PlainNumberScan(fields_per_line=3, integer_fields=2)
    try:
        raw = CheckedReader(path, offset, scan, patch)
        with io.BufferedReader(raw, 1 << 20) as stream:
            coo = scipy.io.mmread(stream, spmatrix=False)
            fields = raw.fields
    except Exception:  # any complaint of the parser or the checks: the strict pass explains it
        return None
    if fields != 3 * entries:
        return None
    if not sp.issparse(coo) or coo.shape != (n, n) or coo.nnz != entries:
        return None
    if not np.all(np.isfinite(coo.data)):
        return None
    return coo.row, coo.col, coo.data


def _mirrored(stored: sp.csr_matrix, lower_stored: bool) -> sp.csr_matrix:
    """The full symmetric matrix of a canonical CSR matrix holding one triangle (the lower one
    if ``lower_stored``).

    Row ``i`` of the result is row ``i`` of the lower triangle followed by row ``i`` of the
    upper triangle without its diagonal entry; one of the two triangles is ``stored``, the other
    its transpose (one conversion in C, sorted). The rows are placed in blocks, so that no
    temporary of the size of the matrix is made besides the transpose; explicit zeros are kept.
    With Numba, :func:`~pymorembs.io.fast_text.full_from_triangle` does it in one pass.
    """
    full = full_from_triangle(stored)
    if full is not None:
        return full
    n = stored.shape[0]
    other = stored.T.tocsr()  # csr_tocsc: sorted rows
    lower, upper = (stored, other) if lower_stored else (other, stored)
    index = stored.indices.dtype
    low_ptr, up_ptr = lower.indptr, upper.indptr
    low_count, up_count = np.diff(low_ptr), np.diff(up_ptr)
    first = up_ptr[:-1]  # the diagonal entry leads a row of the upper triangle (sorted)
    diagonal = up_count > 0
    diagonal[diagonal] = upper.indices[first[diagonal]] == np.flatnonzero(diagonal)
    up_count = up_count - diagonal
    indptr = np.zeros(n + 1, dtype=index)
    np.cumsum(low_count + up_count, out=indptr[1:])
    indices = np.empty(int(indptr[-1]), dtype=index)
    data = np.empty(int(indptr[-1]), dtype=stored.data.dtype)
    step = max(1, (n << 20) // max(indices.size, 1))  # about 2**20 entries a block
    sides = np.tile(np.array([True, False]), min(step, n))
    not_sides = ~sides
    for lo in range(0, n, step):
        hi = min(lo + step, n)
        counts = np.empty(2 * (hi - lo), dtype=np.int64)
        counts[0::2], counts[1::2] = low_count[lo:hi], up_count[lo:hi]
        from_lower = np.repeat(sides[: counts.size], counts)
        counts[0::2] = diagonal[lo:hi]
        keep = np.repeat(not_sides[: counts.size], counts)  # the upper rows without diagonal
        from_upper = ~from_lower
        target = slice(indptr[lo], indptr[hi])
        low, up = slice(low_ptr[lo], low_ptr[hi]), slice(up_ptr[lo], up_ptr[hi])
        for out, a, b in ((indices, lower.indices, upper.indices), (data, lower.data, upper.data)):
            segment = out[target]
            segment[from_lower] = a[low]
            segment[from_upper] = b[up][keep]
    return canonical_csr(data, indices, indptr, (n, n))


def _fast_head(path: Path) -> tuple[_Header, int] | None:
    """Header of a plain UTF-8 file with LF or CR LF line ends and the byte offset of its first
    entry line, or None (unreadable, odd or too long a header: the strict pass)."""
    try:
        with open(path, "rb") as stream:
            head = stream.read(_HEAD_BYTES)
            complete = not stream.read(1)
    except OSError:
        return None
    if not head.startswith(b"%%") or b"\x00" in head:
        return None
    raw = head.split(b"\n")
    if not complete:
        raw.pop()  # a partial last line
    if any(b"\r" in line[:-1] for line in raw):
        return None  # a carriage return that does not end a line
    try:
        lines = [line.decode("utf-8").rstrip("\r") for line in raw]
    except UnicodeDecodeError:
        return None
    try:
        header = _parse_header(path, lines)
    except UserError:
        return None
    if header.data_index > len(raw) - (0 if complete else 1) or not raw[0].isascii():
        return None  # the size line may be cut; or character and byte offsets differ
    offset = sum(len(line) + 1 for line in raw[: header.data_index])
    return header, offset


def _general_csr(rows: np.ndarray, cols: np.ndarray, values: np.ndarray, n: int):
    """CSR of a general file's entries, or None if an entry is given twice."""
    matrix = csr_from_sorted_coo(rows, cols, values, n)
    if matrix is None:
        matrix = sp.csr_matrix((values, (rows, cols)), shape=(n, n))
        matrix.sum_duplicates()
        if matrix.nnz != values.size:
            return None
    return matrix


def check_symmetric(
    matrix: sp.spmatrix | sp.sparray, where: str, tolerance: float = SYMMETRY_TOLERANCE
) -> None:
    """Raise :class:`UserError` if ``matrix`` is not symmetric to ``tolerance``.

    The test is ``max |A - A^T| <= tolerance * max |A|``. The message starts with ``where`` and
    names the worst entry (rows and columns counted from 1).
    """
    a = sp.csr_matrix(matrix)
    if a.shape[0] != a.shape[1]:
        raise UserError(f"{where}: matrix is {a.shape[0]} x {a.shape[1]}, not square")
    gap = _transpose_gap(a)
    largest = max(-float(np.min(a.data)), float(np.max(a.data))) if a.nnz else 0.0  # no |A| copy
    if gap is not None and gap <= tolerance * largest:
        return
    if gap is None and _exactly_symmetric(a):
        return
    diff = (a - a.T).tocoo()
    worst = int(np.argmax(np.abs(diff.data)))
    gap = float(abs(diff.data[worst]))
    largest = float(np.max(np.abs(a.data)))
    if gap <= tolerance * largest:
        return
    r, c = int(diff.row[worst]), int(diff.col[worst])
    raise UserError(
        f"{where}: matrix is not symmetric: entry ({r + 1}, {c + 1}) = {float(a[r, c])!r} but "
        f"({c + 1}, {r + 1}) = {float(a[c, r])!r}; the difference {gap:.3g} exceeds {tolerance:g} "
        f"times the largest entry {largest:.3g} (rows and columns count from 1)"
    )


def _exactly_symmetric(a: sp.csr_matrix) -> bool:
    if a.shape[0] != a.shape[1]:
        return False
    gap = _transpose_gap(a)
    if gap is not None:
        return gap == 0.0
    return (a != a.T).nnz == 0


def _transpose_gap(a: sp.csr_matrix) -> float | None:
    """``max |A - A^T|`` of a canonical square CSR matrix (NaN if it holds NaN), or None if it
    is not canonical.

    One transposition; when the pattern is symmetric (as in most FE matrices) the value arrays
    of ``A`` and ``A^T`` are compared directly, else by sparse subtraction; both in blocks of
    rows, so that no temporary of the size of ``A`` is made besides ``A^T``.
    """
    if not a.has_canonical_format:
        return None
    gap = transpose_gap(a)  # compiled, one pass (None without Numba)
    if gap is not None:
        return gap
    t = a.T.tocsr()
    t.sort_indices()
    gap = np.float64(0.0)
    if np.array_equal(a.indptr, t.indptr) and np.array_equal(a.indices, t.indices):
        for start in range(0, a.nnz, _BLOCK):
            block = a.data[start : start + _BLOCK] - t.data[start : start + _BLOCK]
            gap = np.maximum(gap, np.max(np.abs(block)))
        return float(gap)
    bounds = np.searchsorted(a.indptr, np.arange(0, a.nnz + _BLOCK, _BLOCK))
    for first, last in itertools.pairwise(np.minimum(bounds, a.shape[0])):
        if last > first:
            block = (_row_block(a, first, last) - _row_block(t, first, last)).data
            if block.size:
                gap = np.maximum(gap, np.max(np.abs(block)))
    return float(gap)


def _row_block(a: sp.csr_matrix, first: int, last: int) -> sp.csr_matrix:
    """Rows ``first:last`` of a canonical CSR matrix, sharing its index and value arrays."""
    lo, hi = a.indptr[first], a.indptr[last]
    return canonical_csr(
        a.data[lo:hi], a.indices[lo:hi], a.indptr[first : last + 1] - lo, (last - first, a.shape[1])
    )


#: Entries compared at a time by :func:`_transpose_gap`.
_BLOCK = 1 << 20


def _read_symmetric(path: Path, like: tuple[Path, int] | None = None) -> sp.csr_matrix:
    """Read a Matrix Market file, check symmetry and, with ``like``, its size."""
    matrix, mirrored = _read_matrix_market(path)
    if like is not None and matrix.shape[0] != like[1]:
        n = matrix.shape[0]
        raise located_error(
            path, None, f"matrix is {n} x {n} but {like[0]} is {like[1]} x {like[1]}"
        )
    if not mirrored:  # a symmetric file is mirrored exactly
        check_symmetric(matrix, str(path))
    return matrix


def _coordinate_matrix(
    data: DataLines,
    rows: np.ndarray,
    cols: np.ndarray,
    values: np.ndarray,
    n: int,
    symmetric: bool,
) -> sp.csr_matrix:
    """Check the entries of a coordinate file and assemble the full matrix."""
    outside = np.flatnonzero((rows < 0) | (rows >= n) | (cols < 0) | (cols >= n))
    if outside.size:
        k = int(outside[0])
        data.fail(k, f"entry {_entry(rows, cols, k)} lies outside the {n} x {n} matrix")
    data.require_finite(values)
    if symmetric:
        below, above = np.flatnonzero(rows > cols), np.flatnonzero(rows < cols)
        if below.size and above.size:
            k = int(max(below[0], above[0]))
            side = "above" if rows[k] < cols[k] else "below"
            data.fail(
                k,
                f"entry {_entry(rows, cols, k)} lies {side} the diagonal but earlier "
                "entries lie on the other side; a symmetric file stores one triangle only",
            )
    if symmetric:
        key = np.minimum(rows, cols) * (n + 1) + np.maximum(rows, cols)
    else:
        key = rows * (n + 1) + cols
    order = np.argsort(key, kind="stable")
    repeated = np.flatnonzero(key[order][1:] == key[order][:-1])
    if repeated.size:
        second = order[repeated + 1]
        k = int(second.min())
        first = int(order[repeated[np.argmin(second)]])
        data.fail(
            k,
            f"entry {_entry(rows, cols, k)} is given twice (first on line {data.line_of(first)})",
        )
    if symmetric:
        off = rows != cols
        rows, cols = np.concatenate([rows, cols[off]]), np.concatenate([cols, rows[off]])
        values = np.concatenate([values, values[off]])
    matrix = sp.csr_matrix((values, (rows, cols)), shape=(n, n))
    matrix.sum_duplicates()
    matrix.sort_indices()
    return matrix


def _entry(rows: np.ndarray, cols: np.ndarray, k: int) -> str:
    """``(row, column)`` of entry ``k`` as in the file (indices from 0 in the arrays; an index
    of the file near the int64 limits wrapped around when 1 was subtracted, and wraps back)."""
    with np.errstate(over="ignore"):
        return f"({rows[k] + 1}, {cols[k] + 1})"


class DataLines:
    """The entry lines of a text file of numbers, with their line numbers: a Matrix Market file
    after its size line, or a CalculiX matrix file (:mod:`pymorembs.io.calculix`) from its first
    line. ``%`` starts a comment; blank lines are skipped.

    Parameters
    ----------
    path : Path
        The file, for messages.
    lines : list of str
        Every line of the file (:func:`read_text_lines`).
    start : int
        Index in ``lines`` of the first entry line.
    """

    def __init__(self, path: Path, lines: list[str], start: int) -> None:
        self.path = path
        self.lines = lines
        self.start = start  # index in ``lines`` of the first line after the size line
        self._numbers: np.ndarray | None = None

    def parse(self, columns: tuple[tuple[str, type], ...]) -> np.ndarray:
        """Structured array of the entries; a malformed line raises :class:`UserError`."""
        dtype = [(name, np.int64 if kind is int else np.float64) for name, kind in columns]
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")  # "input contained no data"
                return np.loadtxt(self.lines[self.start :], dtype=dtype, comments="%", ndmin=1)
        except ValueError as err:
            self._locate_bad_line(columns)
            raise located_error(self.path, None, f"cannot read the entries: {err}") from None

    def _locate_bad_line(self, columns: tuple[tuple[str, type], ...]) -> None:
        names = " ".join(name for name, _ in columns)
        for number, text in self._content():
            words = text.split()
            if len(words) != len(columns):
                raise located_error(
                    self.path, number, f"{len(words)} values, expected {len(columns)} ({names})"
                )
            for word, (name, kind) in zip(words, columns, strict=True):
                if kind is int:
                    parse_int(word, self.path, number, name)
                else:
                    _to_float(word, self.path, number, name, finite=False)

    def _content(self) -> list[tuple[int, str]]:
        """(line number, text without comment) of every non-blank line."""
        out = []
        for index in range(self.start, len(self.lines)):
            text = self.lines[index].split("%", 1)[0]
            if text.strip():
                out.append((index + 1, text))
        return out

    def line_of(self, entry: int) -> int:
        """Line number of entry ``entry`` (counted from 0)."""
        if self._numbers is None:
            self._numbers = np.array([number for number, _ in self._content()], dtype=np.int64)
        return int(self._numbers[entry])

    def fail(self, entry: int, message: str) -> None:
        """Raise :class:`UserError` about entry ``entry``."""
        raise located_error(self.path, self.line_of(entry), message)

    def require_finite(self, values: np.ndarray) -> None:
        """Raise :class:`UserError` at the first NaN or infinite value."""
        bad = np.flatnonzero(~np.isfinite(values))
        if bad.size:
            k = int(bad[0])
            self.fail(k, f"value {float(values[k])!r} is not a finite number")


# ============================================================================ CSV tables
def _write_csv(path: Path, header: tuple[str, ...], rows: Iterable[str]) -> Path:
    """Write a header and pre-formatted rows atomically."""
    return write_text(path, "\n".join([",".join(header), *rows]) + "\n")


def _dof_fields(table: DofTable, index: int) -> str:
    """``node,direction`` of equation ``index``."""
    return f"{table.nodes[index]},{DIRECTIONS[table.directions[index]]}"


def _dof_rows(table: DofTable, indices: np.ndarray | None = None) -> list[str]:
    """``node,direction`` rows of the equations ``indices`` (default: all)."""
    if indices is None:
        indices = np.arange(len(table))
    return [_dof_fields(table, index) for index in indices.tolist()]


def _constraint_rows(equations: ConstraintEquations, table: DofTable) -> list[str]:
    """Rows of ``constraints.csv`` (layout in the module docstring)."""
    g = equations.matrix.copy()
    g.sum_duplicates()
    g.sort_indices()
    rows = []
    for k, (dependent, offset) in enumerate(
        zip(equations.dependent.tolist(), equations.offset.tolist(), strict=True)
    ):
        prefix = f"{_dof_fields(table, dependent)},{offset!r}"
        start, stop = g.indptr[k], g.indptr[k + 1]
        if start == stop:
            rows.append(f"{prefix},,,")
        for j, coefficient in zip(
            g.indices[start:stop].tolist(), g.data[start:stop].tolist(), strict=True
        ):
            rows.append(f"{prefix},{_dof_fields(table, j)},{coefficient!r}")
    return rows


def _read_csv(path: Path, header: tuple[str, ...]) -> list[tuple[int, list[str]]]:
    """Rows (line number, stripped fields) of a CSV file after its required header."""
    lines = read_text_lines(path, "a CSV file")
    content = [
        (number, text)
        for number, text in enumerate(lines, start=1)
        if text.strip() and not text.lstrip().startswith("#")
    ]
    expected = ",".join(header)
    if not content:
        raise located_error(path, None, f"empty file; expected the header line {expected!r}")
    reader = csv.reader(text for _, text in content)
    rows: list[tuple[int, list[str]]] = []
    try:
        for fields in reader:
            rows.append((content[reader.line_num - 1][0], [field.strip() for field in fields]))
    except csv.Error as err:
        raise located_error(
            path, content[reader.line_num - 1][0], f"malformed CSV: {err}"
        ) from None
    (header_line, header_fields), *body = rows
    if [field.lower() for field in header_fields] != list(header):
        raise located_error(
            path, header_line, f"header {','.join(header_fields)!r}, expected {expected!r}"
        )
    for number, fields in body:
        if len(fields) != len(header):
            raise located_error(
                path, number, f"{len(fields)} fields, expected {len(header)} ({expected})"
            )
    return body


def read_dofs_csv(path: Path) -> tuple[DofTable, list[int]]:
    """Dof table from ``dofs.csv`` and the line number of each equation."""
    fast = _csv_fast(path, _DOF_HEADER, (np.int64, _TEXT))
    if fast is not None:
        (nodes, names), numbers = fast
        codes = _direction_codes(names)
        if codes is not None and _plain_nodes(nodes) and _distinct(nodes * 8 + codes):
            return DofTable(nodes, codes), numbers.tolist()
    seen: dict[tuple[int, int], int] = {}
    for number, (node_text, direction_text) in _read_csv(path, _DOF_HEADER):
        dof = (
            _to_node(node_text, path, number),
            _to_direction(direction_text, path, number),
        )
        if dof in seen:
            raise located_error(
                path,
                number,
                f"dof {dof[0]}:{DIRECTIONS[dof[1]]} is listed twice (first on line {seen[dof]})",
            )
        seen[dof] = number
    nodes = np.array([node for node, _ in seen], dtype=np.int64)
    directions = np.array([code for _, code in seen], dtype=np.int64)
    return DofTable(nodes, directions), list(seen.values())


def read_nodes_csv(path: Path) -> tuple[np.ndarray, np.ndarray]:
    """Node ids and coordinates from ``nodes.csv``."""
    fast = _csv_fast(path, _NODE_HEADER, (np.int64, float, float, float))
    if fast is not None:
        (ids, x, y, z), _ = fast
        coordinates = np.column_stack([x, y, z])
        if _plain_nodes(ids) and _distinct(ids) and np.all(np.isfinite(coordinates)):
            return ids, coordinates
    seen: dict[int, int] = {}
    coordinates = []
    for number, (id_text, *xyz) in _read_csv(path, _NODE_HEADER):
        node = _to_node(id_text, path, number)
        if node in seen:
            raise located_error(
                path, number, f"node {node} is listed twice (first on line {seen[node]})"
            )
        seen[node] = number
        coordinates.append(
            [_to_float(text, path, number, axis) for text, axis in zip(xyz, "xyz", strict=True)]
        )
    return np.array(list(seen), dtype=np.int64), np.array(coordinates, dtype=float).reshape(-1, 3)


def read_fixed_csv(path: Path, table: DofTable) -> np.ndarray:
    """Equation indices of the dofs in ``fixed.csv``."""
    fast = _csv_fast(path, _DOF_HEADER, (np.int64, _TEXT))
    if fast is not None:
        (nodes, names), _ = fast
        indices = _dof_indices(table, nodes, names)
        if indices is not None:
            return indices
    return np.array(
        [
            _to_dof(node, direction, table, path, number)
            for number, (node, direction) in _read_csv(path, _DOF_HEADER)
        ],
        dtype=np.int64,
    )


def read_constraints_csv(path: Path, table: DofTable) -> ConstraintEquations:
    """Constraint equations from ``constraints.csv`` (layout in the module docstring)."""
    fast = _constraints_fast(path, table)
    if fast is not None:
        return fast
    equations: dict[int, tuple[float, int]] = {}  # dependent -> (offset, line)
    terms: dict[tuple[int, int], tuple[float, int]] = {}  # (dependent, dof) -> (coefficient, line)
    for number, fields in _read_csv(path, _CONSTRAINT_HEADER):
        dependent = _to_dof(fields[0], fields[1], table, path, number)
        offset = _to_float(fields[2], path, number, "offset")
        if dependent not in equations:
            equations[dependent] = (offset, number)
        elif equations[dependent][0] != offset:
            first_offset, first_line = equations[dependent]
            raise located_error(
                path,
                number,
                f"offset {offset!r} of {table.label(dependent)} differs from {first_offset!r} "
                f"on line {first_line}",
            )
        term = fields[3:]
        if not any(term):
            continue
        if not all(term):
            raise located_error(
                path,
                number,
                "node, direction and coefficient must be all given or all empty (q_d = offset)",
            )
        column = _to_dof(term[0], term[1], table, path, number)
        if (dependent, column) in terms:
            raise located_error(
                path,
                number,
                f"term {table.label(column)} of {table.label(dependent)} is given twice "
                f"(first on line {terms[dependent, column][1]})",
            )
        terms[dependent, column] = (_to_float(term[2], path, number, "coefficient"), number)
    row_of = {dependent: k for k, dependent in enumerate(equations)}
    rows = np.array([row_of[d] for d, _ in terms], dtype=np.int64)
    cols = np.array([c for _, c in terms], dtype=np.int64)
    values = np.array([v for v, _ in terms.values()], dtype=float)
    matrix = sp.csr_matrix((values, (rows, cols)), shape=(len(equations), len(table)))
    matrix.sort_indices()
    return ConstraintEquations(
        np.array(list(equations), dtype=np.int64),
        matrix,
        np.array([offset for offset, _ in equations.values()], dtype=float),
    )


# ---------------------------------------------------------------------------- CSV fast path
#: Text fields of the CSV fast path (directions); a field of this length or longer may have
#: been cut by NumPy and goes to the strict pass.
_TEXT = "U8"
_TEXT_WIDTH = 8
_CODE_OF = {name: code for code, name in enumerate(DIRECTIONS)}


def _csv_fast(
    path: Path, header: tuple[str, ...], kinds: tuple[type | str, ...]
) -> tuple[list[np.ndarray], np.ndarray] | None:
    """Columns of a plain CSV table parsed by NumPy's ``loadtxt`` and the line numbers of its
    rows, or None to leave the file to the strict pass (:func:`_read_csv`).

    Plain: UTF-8, the header on the first line, no quotes, no comment lines, no lines of blanks.
    Text columns come stripped and in lower case.
    """
    try:
        text = path.read_text(encoding="utf-8-sig")
    except (OSError, UnicodeDecodeError):
        return None
    text = text.replace("\r\n", "\n")
    if any(mark in text for mark in ('"', "#", "\r", "\x00")):
        return None
    lines = text.split("\n")
    if [field.strip().lower() for field in lines[0].split(",")] != list(header):
        return None
    body = lines[1:]
    dtype = [(f"f{k}", kind) for k, kind in enumerate(kinds)]
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # "input contained no data"
            table = np.loadtxt(body, delimiter=",", dtype=dtype, comments=None, ndmin=1)
    except (ValueError, OverflowError):
        return None
    if "" in body[:-1]:  # loadtxt skips empty lines
        numbers = np.flatnonzero([line != "" for line in body]) + 2
    else:
        numbers = np.arange(2, table.size + 2)
    columns = []
    for name, kind in zip(table.dtype.names, kinds, strict=True):
        column = table[name]
        if kind == _TEXT:
            if column.size and np.max(np.strings.str_len(column)) >= _TEXT_WIDTH:
                return None
            column = np.strings.lower(np.strings.strip(column))
        columns.append(column)
    return columns, numbers


def _direction_codes(names: np.ndarray) -> np.ndarray | None:
    """Direction codes of stripped lower-case names, or None if one is unknown."""
    unique, inverse = np.unique(names, return_inverse=True)
    codes = [_CODE_OF.get(str(name)) for name in unique]
    if None in codes:
        return None
    return np.asarray(codes, dtype=np.int64)[inverse].reshape(-1)


def _plain_nodes(ids: np.ndarray) -> bool:
    """Whether every node id is within +-2**60 (see :func:`_to_node`)."""
    return not ids.size or bool(np.max(np.abs(ids)) < _NODE_LIMIT)


def _distinct(keys: np.ndarray) -> bool:
    return all_distinct(keys)


def _dof_indices(table: DofTable, nodes: np.ndarray, names: np.ndarray) -> np.ndarray | None:
    """Equation indices of the dofs (node ids, direction names), or None if one is unknown."""
    codes = _direction_codes(names)
    if codes is None or not _plain_nodes(nodes):
        return None
    position = table.positions(nodes, codes)
    return None if np.any(position < 0) else position


def _constraints_fast(path: Path, table: DofTable) -> ConstraintEquations | None:
    """Constraint equations of a plain ``constraints.csv`` whose rows all hold a term, or None
    to leave the file to the strict pass (which also reads rows ``q_d = offset``)."""
    kinds = (np.int64, _TEXT, float, np.int64, _TEXT, float)
    fast = _csv_fast(path, _CONSTRAINT_HEADER, kinds)
    if fast is None:
        return None
    (dep_nodes, dep_names, offsets, nodes, names, coefficients), _ = fast
    if not (np.all(np.isfinite(offsets)) and np.all(np.isfinite(coefficients))):
        return None
    dependent = _dof_indices(table, dep_nodes, dep_names)
    columns = _dof_indices(table, nodes, names)
    if dependent is None or columns is None:
        return None
    if not _distinct(dependent * (len(table) + 1) + columns):
        return None  # a term given twice
    unique, first, row = np.unique(dependent, return_index=True, return_inverse=True)
    if np.any(offsets != offsets[first][row]):
        return None  # offsets of one equation differ
    rank = np.empty(unique.size, dtype=np.int64)  # equations in the order of first appearance
    rank[np.argsort(first, kind="stable")] = np.arange(unique.size)
    matrix = sp.csr_matrix((coefficients, (rank[row], columns)), shape=(unique.size, len(table)))
    matrix.sort_indices()
    appearance = np.sort(first)
    return ConstraintEquations(dependent[appearance], matrix, offsets[appearance])


# ============================================================================ small helpers
def read_text_lines(path: Path, kind: str) -> list[str]:
    """The lines of a text file (at least one); :class:`UserError` if it cannot be read."""
    try:
        text = path.read_text(encoding="utf-8-sig")
    except FileNotFoundError:
        raise located_error(path, None, f"file not found (expected {kind})") from None
    except IsADirectoryError:
        raise located_error(path, None, f"is a directory, expected {kind}") from None
    except UnicodeDecodeError:
        note = encoding_note(_head(path))
        raise located_error(path, None, f"not a text file (expected {kind}){note}") from None
    except OSError as err:
        raise located_error(path, None, f"cannot read: {err.strerror or err}") from None
    if "\x00" in text:
        note = encoding_note(_head(path))
        raise located_error(path, None, f"a binary file, expected {kind}{note}")
    return text.replace("\r\n", "\n").replace("\r", "\n").split("\n")


def _head(path: Path, size: int = 512) -> bytes:
    """The first bytes of a file (empty if it cannot be read)."""
    try:
        with open(path, "rb") as f:
            return f.read(size)
    except OSError:
        return b""


def encoding_note(head: bytes) -> str:
    """``"; it is UTF-16 encoded ..."`` for the first bytes of a UTF-16 text file, else ``""``.

    Windows editors save "Unicode" text as UTF-16: a byte order mark, or a zero byte next to every
    ASCII character.
    """
    if head.startswith((b"\xff\xfe", b"\xfe\xff")):
        return "; it is UTF-16 encoded: save it as UTF-8 or ASCII text"
    pairs = head[: len(head) - len(head) % 2]
    if len(pairs) >= 8:
        even, odd = pairs[0::2], pairs[1::2]
        for zeros, chars in ((odd, even), (even, odd)):
            if zeros.count(0) == len(zeros) and all(32 <= c < 127 or c in b"\t\r\n" for c in chars):
                return "; it is UTF-16 encoded: save it as UTF-8 or ASCII text"
    return ""


def parse_int(text: str, path: Path, line: int, what: str, minimum: int | None = None) -> int:
    """An integer field (within int64)."""
    try:
        if "_" in text:
            raise ValueError
        value = int(text)
    except ValueError:
        raise located_error(path, line, f"{what} {text!r} is not an integer") from None
    if not -_INT64_MAX <= value <= _INT64_MAX:
        raise located_error(path, line, f"{what} {text!r} is out of range")
    if minimum is not None and value < minimum:
        raise located_error(path, line, f"{what} {text!r} must be at least {minimum}")
    return value


def _to_node(text: str, path: Path, line: int) -> int:
    """A node id field (within +-2**60, so that node * 8 + direction stays exact in int64)."""
    node = parse_int(text, path, line, "node id")
    if abs(node) >= _NODE_LIMIT:
        raise located_error(path, line, f"node id {text!r} is out of range (at most 2**60 - 1)")
    return node


def _to_float(text: str, path: Path, line: int, what: str, finite: bool = True) -> float:
    """A real-number field; with ``finite``, NaN and infinity are rejected."""
    try:
        if "_" in text:
            raise ValueError
        value = float(text)
    except ValueError:
        raise located_error(path, line, f"{what} {text!r} is not a number") from None
    if finite and not math.isfinite(value):
        raise located_error(path, line, f"{what} {text!r} is not a finite number")
    return value


def _to_direction(text: str, path: Path, line: int) -> int:
    """A direction field (``ux`` ... ``rz``, any case)."""
    try:
        return direction_code(text)
    except UserError:
        raise located_error(
            path, line, f"unknown direction {text!r}, expected one of {' '.join(DIRECTIONS)}"
        ) from None


def _to_dof(node_text: str, direction_text: str, table: DofTable, path: Path, line: int) -> int:
    """Equation index of the dof named by a node field and a direction field."""
    node = _to_node(node_text, path, line)
    code = _to_direction(direction_text, path, line)
    try:
        return table.index(node, code)
    except UserError as err:
        raise located_error(path, line, str(err)) from None
