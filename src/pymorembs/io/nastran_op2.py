"""Read stiffness and mass matrices from a Nastran OUTPUT2 (OP2) file, through pyNastran.

Export (MSC or Simcenter/NX Nastran, any solution sequence), with DMAP in the executive::

    COMPILE SEMG                              $ MSC; NX: the same with MALTER
    ALTER 'MGG' $
    OUTPUT2 KGG,MGG,BGG,,//0/12 $             $ the g-set matrices to unit 12 (.op2)

and ``PARAM,POST,-1`` (or ``-2``) in the bulk data, which writes the geometry tables ``EQEXIN``
(the internal sequence of the points) and ``BGPDT`` (their basic coordinates) to the same file.
The g-set matrices ``KGG``/``MGG`` (and ``BGG``) are read with that dof table: the points sorted
by their internal sequence number, six rows per grid (components 1-6 in the grid's displacement
coordinate system) and one per scalar point (direction ``q``); extra points are not in the
g-set. Matrix names are found as for OP4 and DMIG files
(:func:`pymorembs.io.nastran_matrices.choose_matrices`), ``--stiffness-name`` and
``--mass-name`` override. Matrices of a reduced set (``KAA``, ``KLL``) need the ``USET`` table
to label their rows, which pyNastran does not read: they are refused unless they have the size of
the g-set.

Coordinates come from ``BGPDT`` (basic system), or from ``nodes`` (Nastran bulk data or
``nodes.csv``). Grids with a displacement coordinate system (``CD`` in ``BGPDT``) need the
bulk data as ``nodes``: the OP2 has the system ids but pymorembs takes the systems from the
``CORDxx`` cards, and rotates those grids' rows to basic (:mod:`pymorembs.io.nastran_matrices`).

Element matrices (``KELM``/``MELM`` with the dictionaries ``KDICT``/``MDICT``) are not assembled:
a file that holds ``KGG`` and ``MELM`` but no ``MGG`` is refused with a message naming what it
holds. Every problem raises :class:`~pymorembs.errors.UserError` with one line; no exception of
pyNastran escapes.
"""

from __future__ import annotations

import io
import mmap
import os
import struct
import warnings
from contextlib import redirect_stderr, redirect_stdout
from pathlib import Path
from typing import Any

import numpy as np

from pymorembs.body import SCALAR, DofTable, ElasticBody
from pymorembs.errors import UserError, located_error
from pymorembs.io.checks import reason, require_file
from pymorembs.io.nastran_matrices import (
    MatrixInfo,
    NodeSource,
    build_body,
    choose_matrices,
    node_source,
    symmetric_matrix,
)
from pymorembs.io.pynastran_compat import numpy_with_in1d, op2_class, quiet_logger

__all__ = ["read_op2"]

PathLike = str | os.PathLike[str]

_GRID, _SCALAR_POINT, _EXTRA_POINT = 1, 2, 3  # EQEXIN point types


def read_op2(
    path: PathLike,
    stiffness: str | None = None,
    mass: str | None = None,
    damping: str | None = None,
    nodes: PathLike | None = None,
    name: str | None = None,
) -> ElasticBody:
    """Read a body from the matrices of a Nastran OP2 file (module docstring).

    Parameters
    ----------
    path : path-like
        The ``.op2`` file.
    stiffness, mass, damping : str, optional
        Matrix names (any case); default: the one pair ``K<s>``/``M<s>`` (e.g. ``KGG``/``MGG``)
        and ``B<s>`` as viscous damping if present.
    nodes : path-like, optional
        Coordinates (and displacement systems): Nastran bulk data or ``nodes.csv``. Default:
        the ``BGPDT`` table of the file.
    name : str, optional
        Label of the body; default: the file name without extension.

    Returns
    -------
    ElasticBody
        The g-set body (all grid components, scalar points as scalar coordinates), grid
        components in the basic system.

    Raises
    ------
    UserError
        An unreadable file, no stiffness/mass pair (the message says what the file holds), no
        ``EQEXIN`` table, matrices of another size than the g-set, a grid with a displacement
        coordinate system but no bulk data given; one line naming the file.
    """
    path = Path(path)
    op2 = _read(path)
    found = {str(key).strip().upper(): matrix for key, matrix in op2.matrices.items()}
    if not found:
        tables = ", ".join(t.decode("latin-1") for t in getattr(op2, "table_names", []))
        raise located_error(
            path,
            None,
            f"holds no matrices (tables: {tables or 'none'}); write KGG and MGG with the DMAP "
            "statement OUTPUT2, or use PARAM,EXTOUT,DMIGPCH",
        )
    infos = {key: _info(key, matrix) for key, matrix in found.items()}
    try:
        choice = choose_matrices(infos, path, "matrix", stiffness, mass, damping)
    except UserError as err:
        if "MELM" in found and "MGG" not in found:
            raise UserError(
                f"{err} (MELM and MDICT hold element mass matrices; pymorembs does not assemble "
                "them into MGG)"
            ) from None
        raise
    used = [choice.stiffness, choice.mass] + ([choice.damping] if choice.damping else [])
    matrices = {}
    for role, key in zip(("stiffness", "mass", "damping"), used, strict=False):
        entry = found[key]
        matrices[role] = symmetric_matrix(entry.data, entry.form, f"{path}: matrix {key}")
    n = matrices["stiffness"].shape[0]
    for key, matrix in zip(used, matrices.values(), strict=True):
        if matrix.shape[0] != n:
            raise located_error(
                path,
                None,
                f"matrix {key} is {matrix.shape[0]} x {matrix.shape[0]} but {choice.stiffness} "
                f"is {n} x {n}",
            )
    table, grid_rows = _gset(op2, path, n, choice.stiffness)
    notes = [*choice.notes, f"dof table from the EQEXIN table: {table.describe()}"]
    source = _coordinates(op2, path, table, grid_rows, nodes, notes)
    return build_body(path, table, matrices, source, notes, path.stem if name is None else name)


def _read(path: Path) -> Any:
    """The pyNastran OP2 object with every matrix and the geometry tables of the file."""
    require_file(path, "a Nastran OP2 file")
    _check_records(path)
    try:
        op2_type = op2_class()
        log = quiet_logger()
    except ImportError as err:
        raise located_error(path, None, f"reading OP2 files needs pyNastran ({err})") from None
    chatter = io.StringIO()  # pyNastran prints diagnostics of damaged files
    try:
        with (
            numpy_with_in1d(),
            warnings.catch_warnings(),
            redirect_stdout(chatter),
            redirect_stderr(chatter),
        ):
            warnings.simplefilter("ignore")
            op2 = op2_type(debug=None, log=log)
            op2.read_op2(str(path), build_dataframe=False, skip_undefined_matrices=False)
    except Exception as err:  # pyNastran's own errors (and MemoryError) become one line
        problem = "cannot read the OP2 file (truncated, damaged or not an OP2 file)"
        raise located_error(path, None, f"{problem}: {reason(err)}") from None
    return op2


def _check_records(path: Path) -> None:
    """Refuse a file that is not a sequence of Fortran blocks ``[n, n bytes, n]`` to its end.

    An OP2 file is written as such blocks (the length markers are 4-byte integers whatever the
    word size); pyNastran trusts the leading marker only, so a damaged file can make it loop or
    allocate without end. Walking the markers (without reading the data) finds the damage first.
    """
    try:
        with open(path, "rb") as f, mmap.mmap(f.fileno(), 0, access=mmap.ACCESS_READ) as data:
            size = len(data)
            for endian in "<>":
                at = 0
                while at + 8 <= size:
                    (n,) = struct.unpack_from(endian + "i", data, at)
                    end = at + 4 + n
                    if (
                        n < 0
                        or end + 4 > size
                        or struct.unpack_from(endian + "i", data, end)[0] != n
                    ):
                        break
                    at = end + 4
                if at == size:
                    return
                if endian == "<":
                    first_failure = at
    except (OSError, ValueError) as err:
        raise located_error(path, None, f"cannot read: {reason(err)}") from None
    raise located_error(
        path,
        None,
        "cannot read the OP2 file (truncated, damaged or not an OP2 file): the Fortran block "
        f"at byte {first_failure} is broken",
    )


def _info(key: str, matrix: Any) -> MatrixInfo:
    shape = tuple(int(x) for x in np.shape(matrix.data))
    square = len(shape) == 2 and shape[0] == shape[1]
    return MatrixInfo(key, shape if len(shape) == 2 else None, square)  # type: ignore[arg-type]


def _gset(op2: Any, path: Path, n: int, stiffness: str) -> tuple[DofTable, np.ndarray]:
    """The g-set dof table from EQEXIN, and the internal-sequence row of each grid."""
    eqexin = getattr(getattr(op2, "op2_results", None), "eqexin", None)
    if eqexin is None:
        raise located_error(
            path,
            None,
            f"has no EQEXIN table, so the rows of {stiffness} cannot be labelled; write the "
            "geometry with PARAM,POST,-1 (or -2)",
        )
    nid = np.asarray(eqexin.nid, dtype=np.int64)
    sil = np.asarray(eqexin.dof, dtype=np.int64)
    kind = np.asarray(eqexin.doftype, dtype=np.int64)
    order = np.argsort(sil, kind="stable")
    nid, sil, kind = nid[order], sil[order], kind[order]
    unknown = ~np.isin(kind, [_GRID, _SCALAR_POINT, _EXTRA_POINT])
    if unknown.any():
        k = int(np.flatnonzero(unknown)[0])
        raise located_error(
            path, None, f"EQEXIN: point {nid[k]} has an unknown type code {kind[k]}"
        )
    in_g = kind != _EXTRA_POINT
    size = np.where(kind == _GRID, 6, 1)
    expected = np.concatenate([[1], 1 + np.cumsum(size[in_g])[:-1]]) if in_g.any() else sil[:0]
    if not np.array_equal(sil[in_g], expected):
        raise located_error(path, None, "EQEXIN: the internal sequence numbers are not contiguous")
    total = int(size[in_g].sum())
    if total != n:
        raise located_error(
            path,
            None,
            f"matrix {stiffness} is {n} x {n} but the g-set of EQEXIN has {total} dofs; the rows "
            "of a reduced set (a-set, l-set) need the USET table, which is not read: write the "
            "g-set matrices (KGG, MGG)",
        )
    grids = in_g & (kind == _GRID)
    ids = np.repeat(nid[in_g], size[in_g])
    directions = np.concatenate(
        [np.arange(6) if k == _GRID else [SCALAR] for k in kind[in_g].tolist()]
    ).astype(np.int64)
    grid_order = np.flatnonzero(grids)  # rows of BGPDT are the points in internal sequence
    return DofTable(ids, directions), grid_order


def _coordinates(
    op2: Any,
    path: Path,
    table: DofTable,
    grid_rows: np.ndarray,
    nodes: PathLike | None,
    notes: list[str],
) -> NodeSource | None:
    """Coordinates from ``nodes`` or BGPDT; grids with CD need bulk data."""
    bgpdt = getattr(getattr(op2, "op2_results", None), "bgpdt", None)
    cd = None
    xyz = None
    if bgpdt is not None:
        xyz = np.asarray(bgpdt.xyz, dtype=float)
        codes = np.asarray(bgpdt.nid_cp_cd_ps)
        if codes.ndim == 2 and codes.shape[1] >= 4:
            cd = codes[:, 2]
        elif codes.ndim == 2 and codes.shape[1] == 1:
            cd = codes[:, 0]
        elif codes.ndim == 1:
            cd = codes
    if nodes is not None:
        return node_source(nodes)
    if xyz is None:
        notes.append("the OP2 has no BGPDT table")
        return None
    points = int(grid_rows.max()) + 1 if grid_rows.size else 0
    if xyz.shape[0] == points or xyz.shape[0] == grid_rows.size:
        rows = grid_rows if xyz.shape[0] == points else np.arange(grid_rows.size)
    else:
        raise located_error(path, None, f"BGPDT has {xyz.shape[0]} points but EQEXIN {points}")
    if cd is not None and cd.size == xyz.shape[0] and np.any(cd[rows] > 0):
        systems = ", ".join(str(c) for c in np.unique(cd[rows][cd[rows] > 0]).tolist())
        raise located_error(
            path,
            None,
            f"grids have displacement coordinate systems (CD = {systems}), so the rows of the "
            "matrices are not along the basic axes; give the bulk data (input deck) as nodes",
        )
    _, first = np.unique(table.nodes[~table.scalar], return_index=True)
    ids = table.nodes[~table.scalar][np.sort(first)]
    notes.append("coordinates from the BGPDT table (basic system)")
    return NodeSource(path, None, (ids, xyz[rows]))
