"""Reader for Nastran OUTPUT4 (OP4) matrix files.

An OP4 file holds named matrices only -- no node numbers, no dof labels, no coordinates. The dof
table of the matrices therefore comes from a second file (``dofs``):

``dofs.csv``
    Header ``node,direction``, one row per matrix equation in matrix order (the layout of
    :mod:`pymorembs.io.matrix_market`).
Nastran bulk data (``.asm``, ``.pch``, ``.bdf``, ``.dat``)
    The ``ASET``/``ASET1`` cards (and their synonyms ``BNDFIX``/``BNDFIX1``, and
    ``CSET``/``CSET1``/``BNDFRE``/``BNDFRE1``, which also belong to the a-set) that define the
    a-set of the exported matrices ``KAAX``/``MAAX``/``BAAX``. Nastran orders the a-set by
    internal sequence -- ascending grid id, components 1 to 6 -- which is the order used here; a
    file that resequences grids (``SEQGP`` or ``PARAM,OLDSEQ`` other than -1) is refused. ``GRID``
    cards in the same file give the coordinates (basic system ``CP`` = 0 only) when no ``nodes``
    file is given; a grid of the a-set with a displacement coordinate system ``CD`` other than 0
    is refused because its dofs are not along the basic axes.

Every mistake raises :class:`~pymorembs.errors.UserError` with one line ``file: problem`` or
``file:line: problem``; no exception of pyNastran escapes.
"""

from __future__ import annotations

import io
import math
import mmap
import os
import re
import struct
import warnings
from bisect import bisect_left, bisect_right
from collections.abc import Iterable, Iterator
from contextlib import redirect_stderr, redirect_stdout
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import scipy.sparse as sp

from pymorembs.body import DofTable, ElasticBody
from pymorembs.errors import UserError
from pymorembs.io.ansys import _check_no_empty_dofs, _make_body, _node_table, _reason
from pymorembs.io.matrix_market import _fail, _read_dofs, _read_lines, check_symmetric

__all__ = ["read_op4"]

PathLike = str | os.PathLike[str]

#: Bulk data cards whose points belong to the a-set: (pairs form, list form).
_ASET_CARDS = {"ASET", "BNDFIX", "CSET", "BNDFRE"}
_ASET1_CARDS = {"ASET1", "BNDFIX1", "CSET1", "BNDFRE1"}
_MAX_ID = 2**31 - 1  # largest Nastran id (32-bit)
_EAGER_RANGE = 1_000_000  # THRU ranges with more dofs than this are checked against the size
_NASTRAN_REAL = re.compile(r"^([+-]?(?:\d+\.\d*|\.\d+|\d+))(?:[eEdD]?([+-]\d+)|[eEdD](\d+))?$")


def read_op4(
    path: PathLike,
    stiffness: str = "KAAX",
    mass: str = "MAAX",
    damping: str | None = None,
    dofs: PathLike | None = None,
    nodes: PathLike | None = None,
    name: str | None = None,
) -> ElasticBody:
    """Read a body from a Nastran OUTPUT4 file (ASCII or binary) and a dof table.

    MSC Nastran writes the a-set matrices ``KAAX``, ``MAAX`` and ``BAAX`` of an external
    superelement to an OP4 file with, for example (SOL 103)::

        ASSIGN OUTPUT4='body.op4',UNIT=30,FORM=FORMATTED   $ file management section
        ...
        EXTSEOUT(ASMBULK,EXTID=100,MATOP4=30)              $ case control
        ...
        ASET1,123456,1,THRU,200                            $ a-set = the whole body (beams, shells)
        ASET1,123,201,THRU,999                             $ solid-element grids: translations

    Give the bulk data file that defines the a-set (the input deck, or a file holding just its
    ``ASET``/``ASET1`` and ``GRID`` cards) as ``dofs``. Put every grid dof of the body in the
    a-set and no ``QSET``: generalized (modal) coordinates cannot be read. ``FORM=UNFORMATTED``
    writes a binary OP4 file. Any other OP4 export (e.g. a DMAP ``OUTPUT4`` of a symmetric pair
    of matrices) works together with a ``dofs.csv`` that lists the equations in matrix order.

    Parameters
    ----------
    path : path-like
        The OP4 file, ASCII or binary, dense or sparse format, real single or double precision.
        Dense-format matrices are held as dense arrays while reading (``8 n^2`` bytes); use the
        sparse format (negative ``OUTPUT4`` unit) for large models.
    stiffness, mass : str
        Names of ``K`` and ``M`` in the file (case-insensitive); defaults ``KAAX`` and ``MAAX``.
    damping : str, optional
        Name of an explicit viscous damping matrix. Default: ``BAAX`` if the file has it, else no
        damping matrix. A name given explicitly must exist. Structural-damping matrices are not
        read.
    dofs : path-like
        The dof table of the matrices: ``dofs.csv`` (header ``node,direction``, one row per
        equation) or a Nastran bulk data file with the ``ASET``/``ASET1`` cards (see the module
        documentation for the order and the cards read). Required.
    nodes : path-like, optional
        ``nodes.csv`` (header ``id,x,y,z``) listing every node of the dof table. Default: the
        ``GRID`` cards of a bulk data ``dofs`` file, else all nodes at the origin (fine for
        frequencies, but Buckens frames, rigid-body modes and the search for interface nodes by
        position need coordinates).
    name : str, optional
        Label of the body; default: the OP4 file name without extension.

    Returns
    -------
    ElasticBody
        Equations in the order of the matrices; no fixed dofs (the a-set holds no constrained
        dofs). A matrix of form 6 (symmetric) stored as one triangle is mirrored.

    Raises
    ------
    UserError
        Unreadable or truncated file, a missing matrix name (the message lists the names in the
        file), complex, non-square, non-finite or non-symmetric matrices, matrices of different
        sizes, a dof table of another size; one line naming the file (and line).
    """
    path = Path(path)
    matrices = _read_op4_file(path)
    k_matrix = _pick(matrices, stiffness, path)
    m_matrix = _pick(matrices, mass, path)
    d_name = "BAAX" if damping is None else damping
    d_matrix = _pick(matrices, d_name, path) if damping is not None or d_name in matrices else None
    n = k_matrix.shape[0]
    if n == 0:
        raise _fail(path, None, f"matrix {stiffness.upper()} is 0 x 0: the model has no dofs")
    for label, matrix in ((mass, m_matrix), (d_name, d_matrix)):
        if matrix is not None and matrix.shape[0] != n:
            raise _fail(
                path,
                None,
                f"matrix {label.upper()} is {matrix.shape[0]} x {matrix.shape[0]} but "
                f"{stiffness.upper()} is {n} x {n}",
            )
    if dofs is None:
        raise _fail(
            path,
            None,
            "an OP4 file has no dof labels; give dofs (dofs.csv or the Nastran file with the "
            "ASET/ASET1 cards)",
        )
    dofs_path = Path(dofs)
    table, grids = _read_dof_source(dofs_path, expected=n)
    if len(table) != n:
        raise _fail(
            dofs_path,
            None,
            f"{len(table)} dofs but matrix {stiffness.upper()} in {path} is {n} x {n}",
        )
    _check_no_empty_dofs(k_matrix, m_matrix, table, np.zeros(0, dtype=np.int64), path)
    if nodes is None and grids:
        node_ids, coordinates = _grid_coordinates(table, grids, dofs_path)
    else:
        node_ids, coordinates = _node_table(table, nodes, dofs_path)
    return _make_body(
        path,
        node_ids=node_ids,
        coordinates=coordinates,
        dofs=table,
        mass=m_matrix,
        stiffness=k_matrix,
        damping_matrix=d_matrix,
        name=path.stem if name is None else name,
    )


# ============================================================================ OP4 matrices
@dataclass(frozen=True)
class _Op4Matrix:
    name: str
    form: object
    data: object


def _read_op4_file(path: Path) -> dict[str, _Op4Matrix]:
    """All matrices of an OP4 file, keyed by upper-case name."""
    try:
        if not path.is_file():
            what = "is a directory" if path.is_dir() else "file not found"
            raise _fail(path, None, f"{what} (expected a Nastran OP4 file)")
        if path.stat().st_size == 0:
            raise _fail(path, None, "empty file (expected a Nastran OP4 file)")
    except OSError as err:
        raise _fail(path, None, f"cannot read: {_reason(err)}") from None
    _check_dense_sizes(path)
    try:
        from pyNastran.op4.op4 import OP4
    except ImportError as err:
        raise _fail(path, None, f"reading OP4 files needs pyNastran ({err})") from None
    try:
        chatter = io.StringIO()  # pyNastran prints diagnostics of damaged files
        with warnings.catch_warnings(), redirect_stdout(chatter), redirect_stderr(chatter):
            warnings.simplefilter("ignore")
            raw = OP4(debug=None).read_op4(str(path))
    except Exception as err:  # pyNastran's own errors (and MemoryError) become one line
        problem = "cannot read the OP4 file (truncated, damaged or not an OP4 file)"
        raise _fail(path, None, f"{problem}: {_reason(err)}") from None
    matrices: dict[str, _Op4Matrix] = {}
    for key, entry in raw.items():
        upper = str(key).strip().upper()
        if upper in matrices:
            raise _fail(
                path, None, f"matrix names {matrices[upper].name} and {key} differ only in case"
            )
        matrices[upper] = _Op4Matrix(str(key), entry.form, entry.data)
    return matrices


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
        raise _fail(path, None, f"cannot read: {_reason(err)}") from None
    for name, nrows, ncols, kind, dense, line in headers:
        size = abs(nrows) * ncols * (16 if kind in (3, 4) else 8)
        if dense and size > DENSE_LIMIT_BYTES:
            raise _fail(
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
    """The named matrix as a finite, square, symmetric sparse matrix."""
    entry = matrices.get(str(wanted).strip().upper())
    if entry is None:
        held = ", ".join(sorted(m.name for m in matrices.values())) or "no matrices"
        raise _fail(path, None, f"no matrix named {wanted!r}; the file holds {held}")
    where = f"{path}: matrix {entry.name}"
    if isinstance(entry.form, list):
        raise UserError(f"{where} appears {len(entry.form)} times")
    data = entry.data
    if np.iscomplexobj(data.data if sp.issparse(data) else np.asarray(data)):
        raise UserError(f"{where} is complex; pymorembs needs real matrices")
    a = sp.csr_matrix(data, dtype=float)
    if a.shape[0] != a.shape[1]:
        raise UserError(f"{where} is {a.shape[0]} x {a.shape[1]}, not square")
    a.sum_duplicates()
    if not np.all(np.isfinite(a.data)):
        raise UserError(f"{where} has NaN or infinite entries")
    a.eliminate_zeros()
    below, above = sp.tril(a, -1), sp.triu(a, 1)
    if entry.form == 6 and (below.nnz == 0) != (above.nnz == 0):  # symmetric, one triangle stored
        strict = below if below.nnz else above
        a = sp.csr_matrix(sp.diags(a.diagonal()) + strict + strict.T)
    check_symmetric(a, where)
    a.sort_indices()
    return a


# ============================================================================ dof table
def _read_dof_source(path: Path, expected: int | None = None) -> tuple[DofTable, dict[int, _Grid]]:
    """Dof table from ``dofs.csv`` or from the a-set cards of a Nastran bulk data file."""
    lines = _read_lines(path, "a dofs.csv or Nastran bulk data file")
    first = next((t.strip() for t in lines if t.strip() and not t.lstrip().startswith("#")), "")
    if path.suffix.lower() == ".csv" or first.replace(" ", "").lower() == "node,direction":
        table, _ = _read_dofs(path)
        return table, {}
    return _read_aset(path, lines, expected)


@dataclass
class _Card:
    name: str
    line: int
    fields: list[str] = field(default_factory=list)


@dataclass
class _Grid:
    line: int
    cp: int | None
    cd: int | None
    xyz: tuple[float, float, float]


def _bulk_cards(path: Path, lines: list[str]) -> Iterator[_Card]:
    """The cards of the bulk data section (small, large and free field, with continuations)."""
    upper = [t.upper() for t in lines]
    start = next((i + 1 for i, t in enumerate(upper) if re.match(r"\s*BEGIN\s+(BULK|SUPER)", t)), 0)
    card: _Card | None = None
    for index in range(start, len(lines)):
        raw = lines[index].expandtabs(8).rstrip()
        number = index + 1
        head = raw.lstrip()
        if not head or head.startswith("$"):
            continue
        if re.match(r"\s*(BEGIN\s|ENDDATA)", upper[index]):
            if upper[index].lstrip().startswith("ENDDATA"):
                break
            continue
        text = raw.split("$", 1)[0].rstrip()
        continuation = text.lstrip()[0] in "+*," or not text[:8].strip()
        if continuation:
            if card is None:
                raise _fail(path, number, "continuation line without a card")
            card.fields.extend(_line_fields(text, path, number, continuation=True))
            continue
        if card is not None:
            yield card
        name_text = text.split(",", 1)[0] if "," in text else text[:8]
        name = name_text.strip().upper()
        if name.startswith("INCLUDE"):
            raise _fail(path, number, "INCLUDE is not followed; merge the included file")
        card = _Card(name.rstrip("*"), number, _line_fields(text, path, number, False))
    if card is not None:
        yield card


def _line_fields(text: str, path: Path, number: int, continuation: bool) -> list[str]:
    """The data fields (2 to 9) of one bulk data line."""
    if "," in text:  # free field
        fields = [f.strip() for f in text.split(",")]
        if len(fields) > 10:
            raise _fail(path, number, f"{len(fields)} fields; a free-field line holds at most 10")
        return (fields[1:9] + [""] * 8)[:8]
    if text[:8].strip().endswith("*") or (continuation and text.startswith("*")):  # large field
        return [text[8 + 16 * k : 24 + 16 * k].strip() for k in range(4)]
    return [text[8 + 8 * k : 16 + 8 * k].strip() for k in range(8)]


def _read_aset(
    path: Path, lines: list[str], expected: int | None = None
) -> tuple[DofTable, dict[int, _Grid]]:
    """The a-set (ascending grid id, components 1..6) and the GRID cards of a bulk data file.

    ``expected`` (the size of the matrices) bounds the work on ``THRU`` ranges.
    """
    members: dict[tuple[int, int], int] = {}  # (grid, component 1..6) -> line
    ranges: list[tuple[int, int, str, int]] = []  # THRU ranges: (first, last, components, line)
    grids: dict[int, _Grid] = {}
    grdset: tuple[int | None, int | None] = (None, None)
    for card in _bulk_cards(path, lines):
        f, number = card.fields, card.line
        if card.name in _ASET_CARDS:
            for k in range(0, len(f) - 1, 2):
                if f[k] or f[k + 1]:
                    grid = _int_field(f[k], path, number, "grid id")
                    for c in _components(f[k + 1], path, number, card.name):
                        members.setdefault((grid, c), number)
        elif card.name in _ASET1_CARDS:
            components, ids = f[0], [x for x in f[1:] if x]
            k = 0
            while k < len(ids):
                first = _int_field(ids[k], path, number, "grid id")
                if k + 2 < len(ids) and ids[k + 1].upper() == "THRU":
                    last = _int_field(ids[k + 2], path, number, "grid id")
                    if last < first:
                        raise _fail(path, number, f"{first} THRU {last}: the range is empty")
                    ranges.append((first, last, components, number))
                    k += 3
                    continue
                for c in _components(components, path, number, card.name):
                    members.setdefault((first, c), number)
                k += 1
            _components(components, path, number, card.name)
        elif card.name in ("QSET", "QSET1"):
            raise _fail(
                path,
                number,
                f"{card.name}: generalized (modal) coordinates have no direction; export the "
                "physical a-set without QSET",
            )
        elif card.name == "SEQGP":
            raise _fail(path, number, "SEQGP resequences the grids, so the a-set order is unknown")
        elif card.name == "PARAM" and f[0].upper() == "OLDSEQ" and f[1] not in ("", "-1"):
            raise _fail(path, number, "PARAM,OLDSEQ resequences the grids; use -1")
        elif card.name == "GRDSET":
            grdset = (_opt_int(f[1], path, number, "CP"), _opt_int(f[5], path, number, "CD"))
        elif card.name == "GRID":
            grid = _int_field(f[0], path, number, "grid id")
            if grid in grids:
                first_line = grids[grid].line
                raise _fail(
                    path, number, f"GRID {grid} is defined twice (first on line {first_line})"
                )
            xyz = tuple(_real_field(f[k], path, number) for k in (2, 3, 4))
            grids[grid] = _Grid(
                number,
                _opt_int(f[1], path, number, "CP"),
                _opt_int(f[5], path, number, "CD"),
                xyz,  # type: ignore[arg-type]
            )
    known = sorted(grids)
    for first, last, components, number in ranges:
        if known:  # with GRID cards, points of a THRU range that do not exist are skipped
            ids: list[int] | range = known[bisect_left(known, first) : bisect_right(known, last)]
        elif last - first >= 10_000_000:
            raise _fail(path, number, f"{first} THRU {last} spans too many ids without GRID cards")
        else:
            ids = range(first, last + 1)
        codes = _components(components, path, number, "ASET1")
        count = len(ids) * len(codes)
        # distinct dofs: a range far beyond the matrix size is refused before it is built
        if expected is not None and count > max(expected, _EAGER_RANGE):
            raise _fail(
                path,
                number,
                f"{first} THRU {last} puts {count} dofs in the a-set, more than the {expected} "
                "equations of the matrices",
            )
        for grid in ids:
            for c in codes:
                members.setdefault((grid, c), number)
    if not members:
        raise _fail(path, None, "no ASET/ASET1 (or BNDFIX, CSET) cards; cannot build the a-set")
    for grid_card in grids.values():
        grid_card.cp = grdset[0] if grid_card.cp is None else grid_card.cp
        grid_card.cd = grdset[1] if grid_card.cd is None else grid_card.cd
    for grid in sorted({g for g, _ in members}):
        card = grids.get(grid)
        if card is not None and card.cd:
            raise _fail(
                path,
                card.line,
                f"GRID {grid} has displacement coordinate system CD={card.cd}; pymorembs needs "
                "dofs along the basic axes (CD blank or 0)",
            )
    keys = sorted(members)
    table = DofTable(
        np.array([g for g, _ in keys], dtype=np.int64),
        np.array([c - 1 for _, c in keys], dtype=np.int64),
    )
    return table, grids


def _grid_coordinates(
    table: DofTable, grids: dict[int, _Grid], path: Path
) -> tuple[np.ndarray, np.ndarray]:
    """Coordinates of the a-set grids from their GRID cards (basic system only)."""
    _, first = np.unique(table.nodes, return_index=True)
    node_ids = table.nodes[np.sort(first)]
    coordinates = np.zeros((node_ids.size, 3))
    for row, grid in enumerate(node_ids.tolist()):
        card = grids.get(grid)
        if card is None:
            raise _fail(path, None, f"grid {grid} of the a-set has no GRID card; give nodes.csv")
        if card.cp:
            raise _fail(
                path,
                card.line,
                f"GRID {grid} is located in coordinate system CP={card.cp}; give nodes.csv with "
                "basic coordinates",
            )
        coordinates[row] = card.xyz
    return node_ids, coordinates


def _components(text: str, path: Path, line: int, card: str) -> list[int]:
    """Grid components ``1``..``6`` of a component field such as ``123456``."""
    text = text.strip()
    if text in ("", "0"):
        raise _fail(path, line, f"{card}: scalar point (component 0 or blank) has no direction")
    if not text.isdigit() or not set(text) <= set("123456") or len(set(text)) != len(text):
        raise _fail(path, line, f"{card}: component {text!r} is not digits 1-6 without repeats")
    return sorted(int(c) for c in text)


def _int_field(text: str, path: Path, line: int, what: str) -> int:
    try:
        value = int(text)
    except ValueError:
        raise _fail(path, line, f"{what} {text!r} is not an integer") from None
    if value <= 0:
        raise _fail(path, line, f"{what} {text!r} must be positive")
    if value > _MAX_ID:
        raise _fail(path, line, f"{what} {text!r} is out of range (Nastran ids are below 2**31)")
    return value


def _opt_int(text: str, path: Path, line: int, what: str) -> int | None:
    if not text.strip():
        return None
    try:
        value = int(text)
    except ValueError:
        raise _fail(path, line, f"{what} {text!r} is not an integer") from None
    if abs(value) > _MAX_ID:
        raise _fail(path, line, f"{what} {text!r} is out of range (Nastran ids are below 2**31)")
    return value


def _real_field(text: str, path: Path, line: int) -> float:
    """A Nastran real: ``1.5``, ``1.5E3``, ``1.5+3``, ``-.5-2``, ``1.D0``; blank is 0."""
    text = text.strip()
    if not text:
        return 0.0
    match = _NASTRAN_REAL.match(text)
    if match is None:
        raise _fail(path, line, f"coordinate {text!r} is not a number")
    exponent = match.group(2) or match.group(3) or "0"
    value = float(f"{match.group(1)}e{exponent}")
    if not math.isfinite(value):
        raise _fail(path, line, f"coordinate {text!r} is not a finite number")
    return value
