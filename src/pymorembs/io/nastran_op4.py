"""Reader for Nastran OUTPUT4 (OP4) matrix files.

An OP4 file holds named matrices only -- no node numbers, no dof labels, no coordinates. The dof
table (the row order) of the matrices comes from a second file, ``dofs``:

the EXTBULK punch of the superelement (``.pch``)
    ``EXTSEOUT(ASMBULK,EXTBULK,EXTID=n,MATOP4=30)`` writes the matrices (MSC: ``KAA``, ``MAA``;
    NX: ``KXX``, ``MXX``) to the OP4 file of unit 30 and the bulk data of superelement ``n`` to
    the punch: ``EXTRN``/``ASET`` (boundary grids and their components, the q-set scalar
    points with component 0), ``QSET1``, ``SPOINT``, the boundary ``GRID`` cards with their
    coordinate systems. The rows are the a-set in Nastran's internal sequence: point ids
    ascending (grids and scalar points together), components 1 to 6 -- verified on NX 9 and
    MSC 2017 exports by the rigid-body check and by the identity mass block of the modal
    coordinates. A Craig-Bampton superelement is read as such: boundary grid dofs plus modal
    coordinates (scalar coordinates, direction ``q``).
the ASMBULK file (``.asm``)
    ``SECONCT`` lists the boundary points but not their components: all six are taken for
    every grid, and a size that does not fit is refused (give the ``.pch`` then).
any bulk data (``.bdf``, ``.dat``) or the ``.f06`` echo
    The a-set cards ``ASET``/``ASET1``, ``BSET``, ``CSET``, ``QSET`` (and ``BNDFIX``,
    ``BNDFRE``) in the same order. A file that resequences (``SEQGP``, ``PARAM,OLDSEQ`` other
    than -1) is refused.
``dofs.csv``
    Header ``node,direction``, one row per matrix equation in matrix order (the layout of
    :mod:`pymorembs.io.matrix_market`), for any other OP4 export.
no dofs
    The equations become scalar coordinates 1..n (frequencies can still be computed; there
    are no grids, coordinates or interface nodes).

Coordinates come from ``nodes`` (bulk data, ``.f06`` or ``nodes.csv``) or from the GRID cards of
the ``dofs`` bulk data; grids with a displacement coordinate system ``CD`` are rotated to basic
(:mod:`pymorembs.io.nastran_matrices`), e.g. grid 11 of the pyyeti NX example, whose CORD2R
permutes the axes.

An ASCII file with real matrices is read by the vectorised reader of
:mod:`pymorembs.io.op4_ascii` (streamed, one conversion per block, as fast as parsing its numbers);
binary files, complex matrices and any layout that reader does not read exactly as pyNastran does
are read by pyNastran.

Matrix names are found automatically (:func:`pymorembs.io.nastran_matrices.choose_matrices`):
one pair ``K<s>``/``M<s>`` among the file's matrices, the 1 x 1 placeholders of EXTSEOUT aside;
``B<s>`` is the viscous damping. Every mistake raises :class:`~pymorembs.errors.UserError` with
one line ``file: problem`` or ``file:line: problem``; no exception of pyNastran escapes.
"""

from __future__ import annotations

import io
import mmap
import os
import re
import struct
import warnings
from collections.abc import Iterable
from contextlib import redirect_stderr, redirect_stdout
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
import scipy.sparse as sp

from pymorembs.body import SCALAR, DofTable, ElasticBody
from pymorembs.errors import UserError, located_error
from pymorembs.io.checks import reason, require_file
from pymorembs.io.matrix_market import read_dofs_csv, read_text_lines
from pymorembs.io.nastran_bulk import BulkData, read_bulk
from pymorembs.io.nastran_matrices import (
    MatrixInfo,
    build_body,
    choose_matrices,
    describe_set,
    modal_block_notes,
    node_source,
    symmetric_matrix,
)
from pymorembs.io.op4_ascii import read_ascii_op4

__all__ = ["read_op4"]

PathLike = str | os.PathLike[str]

_PRECISION = {1: "single", 2: "double", 3: "single", 4: "double"}


def read_op4(
    path: PathLike,
    stiffness: str | None = None,
    mass: str | None = None,
    damping: str | None = None,
    dofs: PathLike | None = None,
    nodes: PathLike | None = None,
    name: str | None = None,
) -> ElasticBody:
    """Read a body from a Nastran OUTPUT4 file (ASCII or binary) and its dof table.

    An external superelement (SOL 103, any Nastran)::

        ASSIGN OUTPUT4='body.op4',UNIT=30,FORM=UNFORMATTED   $ file management section
        ...
        EXTSEOUT(ASMBULK,EXTBULK,EXTID=100,MATOP4=30)        $ case control
        ...
        ASET1,123456,1,THRU,200                              $ boundary grids (b-set)
        QSET1,0,1000001,THRU,1000020                         $ modal coordinates
        SPOINT,1000001,THRU,1000020

    writes ``body.op4`` and the punch ``body.pch``; read them with ``read_op4("body.op4",
    dofs="body.pch")``. Without ``QSET`` the matrices are the statically reduced a-set.
    ``FORM=FORMATTED`` writes an ASCII OP4 file.

    Parameters
    ----------
    path : path-like
        The OP4 file, ASCII or binary, dense or sparse format, real single or double precision.
        Dense-format matrices are held as dense arrays while reading (``8 n^2`` bytes); use the
        sparse format (negative ``OUTPUT4`` unit) for large models.
    stiffness, mass : str, optional
        Names of ``K`` and ``M`` in the file (case-insensitive); default: the one pair
        ``K<s>``/``M<s>`` of the file (``KAA``/``MAA``, ``KXX``/``MXX``, ``KAAX``/``MAAX`` ...).
    damping : str, optional
        Name of a viscous damping matrix. Default: ``B<s>`` if the file has it (not a 1 x 1
        placeholder). Structural-damping matrices (``K4<s>``) are not read.
    dofs : path-like, optional
        The dof table of the matrices: the EXTBULK ``.pch`` / ASMBULK ``.asm`` of the
        superelement, other bulk data with the a-set cards, or ``dofs.csv`` (header
        ``node,direction``, one row per equation). Without it the equations are scalar
        coordinates 1..n.
    nodes : path-like, optional
        Coordinates: bulk data, the ``.f06`` or ``nodes.csv`` (header ``id,x,y,z``) listing
        every grid of the dof table. Default: the ``GRID`` cards of a bulk data ``dofs`` file.
    name : str, optional
        Label of the body; default: the OP4 file name without extension.

    Returns
    -------
    ElasticBody
        Equations in the order of the matrices, grid components in the basic system; no fixed
        dofs. A matrix of form 6 (symmetric) stored as one triangle is mirrored.

    Raises
    ------
    UserError
        Unreadable or truncated file, a missing or ambiguous matrix name (the message lists the
        names in the file), a file without a mass matrix (it says what it holds), complex,
        non-square, non-finite or non-symmetric matrices, matrices of different sizes, a dof
        table of another size; one line naming the file (and line).
    """
    path = Path(path)
    matrices = _read_op4_file(path)
    choice = choose_matrices(
        {key: _info(entry) for key, entry in matrices.items()},
        path,
        "matrix",
        stiffness=stiffness,
        mass=mass,
        damping=damping,
    )
    k_matrix = _pick(matrices, choice.stiffness, path)
    m_matrix = _pick(matrices, choice.mass, path)
    d_matrix = _pick(matrices, choice.damping, path) if choice.damping is not None else None
    n = k_matrix.shape[0]
    if n == 0:
        raise located_error(
            path, None, f"matrix {choice.stiffness} is 0 x 0: the model has no dofs"
        )
    for label, matrix in ((choice.mass, m_matrix), (choice.damping, d_matrix)):
        if matrix is not None and matrix.shape[0] != n:
            raise located_error(
                path,
                None,
                f"matrix {label} is {matrix.shape[0]} x {matrix.shape[0]} but "
                f"{choice.stiffness} is {n} x {n}",
            )
    notes = list(choice.notes)
    used = [choice.stiffness, choice.mass] + ([choice.damping] if choice.damping else [])
    tin = {matrices[key].tin for key in used}
    precision = " and ".join(sorted({_PRECISION.get(t, f"type {t}") for t in tin}))
    types = ", ".join(str(t) for t in sorted(tin))
    notes.append(f"{', '.join(used)}: real {precision} precision (OP4 type {types})")
    bulk = None
    if dofs is None:
        table = DofTable(np.arange(1, n + 1), np.full(n, SCALAR))
        notes.append(
            f"no dof table: the {n} equations are scalar coordinates 1..{n} (give the "
            "superelement's .pch/.asm or a dofs.csv as dofs for grids and coordinates)"
        )
    else:
        dofs_path = Path(dofs)
        table, bulk, dof_notes = _read_dof_source(dofs_path, n, choice.stiffness, path)
        notes += dof_notes
    matrices_out = {"stiffness": k_matrix, "mass": m_matrix}
    if d_matrix is not None:
        matrices_out["damping"] = d_matrix
    notes += modal_block_notes(table, k_matrix, m_matrix)
    if nodes is not None:
        grids = node_source(nodes)
    elif bulk is not None and bulk.grid["ids"].size:
        grids = node_source(bulk.path, bulk)
    else:
        grids = None
    body = build_body(path, table, matrices_out, grids, notes, path.stem if name is None else name)
    single = bool(tin & {1, 3})  # real or complex single precision: 24-bit mantissas
    return replace(body, precision=2.0**-24) if single else body


def _read_dof_source(
    path: Path, n: int, stiffness: str, op4: Path
) -> tuple[DofTable, BulkData | None, list[str]]:
    """Dof table from ``dofs.csv`` or from the a-set of Nastran bulk data, checked against n."""
    lines = read_text_lines(path, "a dofs.csv or Nastran bulk data file")
    first = next((t.strip() for t in lines if t.strip() and not t.lstrip().startswith("#")), "")
    if path.suffix.lower() == ".csv" or first.replace(" ", "").lower() == "node,direction":
        table, _ = read_dofs_csv(path)
        bulk, notes = None, [f"dof table from {path.name}: {table.describe()}"]
        hint = ""
    else:
        bulk = read_bulk(path)
        aset = bulk.analysis_set(limit=n)
        if aset is None:
            raise located_error(
                path,
                None,
                f"defines no a-set (no ASET/ASET1, BSET, QSET, EXTRN or SECONCT cards) for the "
                f"rows of {op4.name}; it holds {bulk.describe()}; give the superelement's .pch "
                "or a dofs.csv",
            )
        table = DofTable(aset.ids, aset.directions)
        notes = describe_set(aset, table, path)
        hint = (
            " (the .asm does not list the components of its grids; give the EXTBULK .pch)"
            if aset.assumed
            else ""
        )
    if len(table) != n:
        raise located_error(
            path, None, f"{len(table)} dofs but matrix {stiffness} in {op4} is {n} x {n}{hint}"
        )
    return table, bulk, notes


def _info(entry: _Op4Matrix) -> MatrixInfo:
    """Name, shape and kind of an OP4 matrix for the name choice."""
    shape = (
        tuple(int(x) for x in np.shape(entry.data)) if not isinstance(entry.form, list) else None
    )
    square = shape is not None and len(shape) == 2 and shape[0] == shape[1]
    placeholder = False
    if shape == (1, 1):
        data = entry.data
        value = data.toarray() if sp.issparse(data) else np.asarray(data)
        placeholder = not np.any(value)
    return MatrixInfo(entry.name.upper(), shape, square, placeholder)  # type: ignore[arg-type]


# ============================================================================ OP4 matrices
@dataclass(frozen=True)
class _Op4Matrix:
    name: str
    form: object
    data: object
    tin: int


def _read_op4_file(path: Path) -> dict[str, _Op4Matrix]:
    """All matrices of an OP4 file, keyed by upper-case name."""
    require_file(path, "a Nastran OP4 file")
    raw = _read_ascii(path)
    if raw is None:
        raw = _read_with_pynastran(path)
    matrices: dict[str, _Op4Matrix] = {}
    for key, entry in raw.items():
        upper = str(key).strip().upper()
        if upper in matrices:
            raise located_error(
                path, None, f"matrix names {matrices[upper].name} and {key} differ only in case"
            )
        tin = int(getattr(entry, "tin", 0) or 0)
        matrices[upper] = _Op4Matrix(str(key), entry.form, entry.data, int(tin))
    return matrices


def _read_ascii(path: Path) -> dict | None:
    """The matrices of an ASCII OP4 file by the vectorised reader, or None (a binary file, or
    one that reader leaves to pyNastran)."""
    try:
        with open(path, "rb") as f:
            if b"\x00" in f.read(4096):
                return None
    except OSError:
        return None
    return read_ascii_op4(path)


def _read_with_pynastran(path: Path) -> dict:
    """pyNastran's matrices of an OP4 file; its errors become one line."""
    _check_dense_sizes(path)
    try:
        from pyNastran.op4.op4 import OP4
    except ImportError as err:
        raise located_error(path, None, f"reading OP4 files needs pyNastran ({err})") from None
    try:
        chatter = io.StringIO()  # pyNastran prints diagnostics of damaged files
        with warnings.catch_warnings(), redirect_stdout(chatter), redirect_stderr(chatter):
            warnings.simplefilter("ignore")
            raw = OP4(debug=None).read_op4(str(path))
    except Exception as err:  # pyNastran's own errors (and MemoryError) become one line
        problem = "cannot read the OP4 file (truncated, damaged or not an OP4 file)"
        raise located_error(path, None, f"{problem}: {reason(err)}") from None
    return raw


def _check_dense_sizes(path: Path) -> None:
    """Refuse dense-format matrices too large to hold before pyNastran allocates them.

    pyNastran holds a dense-format matrix as a dense array of the size in its header, however
    few columns the file holds; an absurd size (a damaged header, or a large model written in
    dense format) would allocate gigabytes. The headers are found without reading the values.
    """
    try:
        with open(path, "rb") as f:
            binary = b"\x00" in f.read(4096)
            f.seek(0)
            if binary:  # memory-mapped: the values are never read
                with mmap.mmap(f.fileno(), 0, access=mmap.ACCESS_READ) as data:
                    headers = _binary_headers(data)
            else:
                headers = _ascii_headers(f)
    except (OSError, ValueError) as err:
        raise located_error(path, None, f"cannot read: {reason(err)}") from None
    for name, nrows, ncols, kind, dense, line in headers:
        size = abs(nrows) * ncols * (16 if kind in (3, 4) else 8)
        if dense and size > DENSE_LIMIT_BYTES:
            raise located_error(
                path,
                line,
                f"matrix {name} is {abs(nrows)} x {ncols} in dense format, {size / 2**30:.1f} GiB "
                "in memory; write it in sparse format (negative OUTPUT4 unit) or check the "
                "header",
            )


#: Largest dense-format OP4 matrix read (bytes of the dense array).
DENSE_LIMIT_BYTES = 4 << 30

_ASCII_HEADER = re.compile(rb"^\s*(-?\d+)\s+(-?\d+)\s+(-?\d+)\s+(-?\d+)(\S.{0,7})")


def _ascii_headers(lines: Iterable[bytes]) -> list[tuple[str, int, int, int, bool, int]]:
    """(name, rows, columns, type, dense, line) of the matrix headers of an ASCII OP4 file.

    A header line (``%8i%8i%8i%8i%-8s`` and a Fortran format) is followed by the first column
    line ``column row words``; row 0 there marks the sparse format.
    """
    out = []
    previous: bytes | None = None
    for number, line in enumerate(lines, start=1):
        if previous is not None and len(previous) >= 42 and _ASCII_HEADER.match(previous[:40]):
            try:
                ncols, nrows, _, kind = (int(previous[k : k + 8]) for k in range(0, 32, 8))
                _, irow = (int(w) for w in line.split()[:2])
            except ValueError:
                pass
            else:
                name = previous[32:40].decode("latin-1").strip()
                out.append((name, nrows, ncols, kind, irow != 0, number - 1))
        previous = line
    return out


def _binary_headers(data: bytes | mmap.mmap) -> list[tuple[str, int, int, int, bool, None]]:
    """(name, rows, columns, type, dense, None) of the matrices of a binary OP4 file.

    Walks the Fortran records ``[n, payload, n]``: a header record (24 bytes: columns, rows,
    form, type, name), its column records (column, row, words, values) up to the closing
    column ``columns + 1``, then the next header. Stops quietly where the layout is not met
    (pyNastran reports damaged files).
    """
    out: list[tuple[str, int, int, int, bool, None]] = []
    for endian in "<>":
        p = 0
        while (head := _record_at(data, p, endian)) is not None and head[1] == 24:
            ncols, nrows, _, kind = struct.unpack_from(endian + "4i", data, head[0])
            name = data[head[0] + 16 : head[0] + 24].decode("latin-1").strip()
            p = head[0] + 24 + 4
            first = _record_at(data, p, endian)
            if first is None or first[1] < 12:
                break
            irow = struct.unpack_from(endian + "i", data, first[0] + 4)[0]
            out.append((name, nrows, ncols, kind, irow != 0, None))
            while (column := _record_at(data, p, endian)) is not None and column[1] >= 12:
                p = column[0] + column[1] + 4
                if struct.unpack_from(endian + "i", data, column[0])[0] > ncols:
                    break
        if out:
            return out
    return out


def _record_at(data: bytes | mmap.mmap, at: int, endian: str) -> tuple[int, int] | None:
    """(payload start, payload length) of the Fortran record at ``at``, or None."""
    if at < 0 or at + 4 > len(data):
        return None
    (n,) = struct.unpack_from(endian + "i", data, at)
    if n < 0 or at + 8 + n > len(data):
        return None
    if struct.unpack_from(endian + "i", data, at + 4 + n)[0] != n:
        return None
    return at + 4, n


def _pick(matrices: dict[str, _Op4Matrix], wanted: str, path: Path) -> sp.csr_matrix:
    """The named matrix as a finite, square, symmetric sparse matrix.

    The file's copy of a sparse matrix is dropped from ``matrices`` once converted (the result
    is kept there instead), so that a large matrix is not held twice.
    """
    key = str(wanted).strip().upper()
    entry = matrices.get(key)
    if entry is None:
        held = ", ".join(sorted(m.name for m in matrices.values())) or "no matrices"
        raise located_error(path, None, f"no matrix named {wanted!r}; the file holds {held}")
    where = f"{path}: matrix {entry.name}"
    if isinstance(entry.form, list):
        raise UserError(f"{where} appears {len(entry.form)} times")
    if isinstance(entry.data, _Picked):
        return entry.data.matrix
    data, form = entry.data, entry.form
    if sp.issparse(data) and not np.iscomplexobj(data.data):  # type: ignore[union-attr]
        matrices[key] = replace(entry, data=None)
        del entry
        data = data.tocsr()  # the file's copy is freed here
        data = sp.csr_matrix(  # float64 values, the index arrays shared
            (data.data.astype(np.float64), data.indices, data.indptr), shape=data.shape
        )
    matrix = symmetric_matrix(data, form, where)
    matrices[key] = replace(matrices[key], data=_Picked(matrix))
    return matrix


@dataclass(frozen=True)
class _Picked:
    """A matrix already converted by :func:`_pick`."""

    matrix: sp.csr_matrix
