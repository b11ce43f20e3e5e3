"""Read the ``.mtx`` file of Abaqus ``*SUBSTRUCTURE MATRIX OUTPUT`` (a reduced body).

Export (Abaqus/Standard; the substructure procedure does not support models defined as an
assembly of part instances, so the input file is written without parts)::

    *STEP
    *SUBSTRUCTURE GENERATE, TYPE=Z1, MASS MATRIX=YES
    *RETAINED NODAL DOFS
    interface, 1, 6
    *SUBSTRUCTURE MATRIX OUTPUT, FILE NAME=body, OUTPUT FILE=USER DEFINED, STIFFNESS=YES, MASS=YES
    *END STEP

Abaqus writes ``body.mtx`` as a linear user element (``*USER ELEMENT, LINEAR``); this is the
layout of the files read here, checked on the genuine files shipped with abaqus-mtx-parser
1.1.4::

    ** GENERATION OF SUBSTRUCTURE Z1
    *USER ELEMENT, NODES=         6, LINEAR[, UNSYM]
    ** ELEMENT NODES
    **          2,          3,          4,          5,          6,          7
              1,          2,          3,          4,          5,          6
    *MATRIX,TYPE=STIFFNESS
      291719.31783334    , -.82099915102221E-11, ...
    *MATRIX,TYPE=MASS
    ...

What the reader assumes
    The comment lines after ``** ELEMENT NODES`` list the labels of the retained nodes, in the
    order of the element's connectivity (without that list the nodes are numbered 1..N). The
    first data line lists the retained dofs of the first node, which hold for the following
    nodes until a data line ``position, dof, dof, ...`` changes them from the node at that
    position (1-based) on; this is the ``*USER ELEMENT`` convention. The equations are the
    nodes in order, each with its dofs in the listed order. Dofs 1-6 are ux uy uz rx ry rz;
    other dofs and node labels below 1 (internal nodes, which would carry e.g. generalized
    coordinates) are refused, since pymorembs cannot place them.
Matrix storage
    Each ``*MATRIX`` block holds comma separated values, any number per line: the lower
    triangle row by row ``(1,1), (2,1), (2,2), (3,1), ...`` (symmetric storage), or, for an
    ``UNSYM`` element, the full matrix row by row (Abaqus stores the mass of an ``UNSYM``
    substructure as a triangle all the same; the count of values tells the two apart). A full
    matrix is accepted when it is symmetric to a relative
    :data:`~pymorembs.io.matrix_market.SYMMETRY_TOLERANCE` of its largest entry (then the mean
    of both triangles is used and a note gives the asymmetry); pymorembs needs symmetric
    ``K`` and ``M``, so anything else is refused. ``D`` exponents and Fortran exponents without
    ``E`` (``0.12345-100``) are accepted.
Coordinates
    From ``inp`` (the model's ``.inp``, or a ``nodes.csv``); without it every node lies at the
    origin and ``has_coordinates`` is false. The rigid-body residuals are given in a note (with
    coordinates all six; without, the three translations, which still check the dof map).

A file without a ``TYPE=MASS`` block is refused in one line (it holds only the stiffness).
"""

from __future__ import annotations

import os
import re
import warnings
from pathlib import Path

import numpy as np
import scipy.sparse as sp

from pymorembs.body import DofTable, ElasticBody
from pymorembs.errors import UserError, located_error
from pymorembs.io.abaqus_inp import (
    ABAQUS_DOF_NAMES,
    ascii_data,
    integer_field,
    keyword_blocks,
    parse_keyword,
)
from pymorembs.io.matrix_market import SYMMETRY_TOLERANCE
from pymorembs.io.node_files import read_node_file
from pymorembs.io.reader_support import read_text

__all__ = ["read_abaqus_substructure"]

PathLike = str | os.PathLike[str]

_KIND = "an Abaqus substructure matrix file (*SUBSTRUCTURE MATRIX OUTPUT)"
_ROLES = {"STIFFNESS": "stiffness", "MASS": "mass"}
_COMMENT_LINE = re.compile(r"(?m)^[ \t]*\*\*.*$")
_FORTRAN_EXPONENT = re.compile(r"(?<=[0-9.])([+-][0-9]{1,3})\b")


def read_abaqus_substructure(
    file: PathLike, inp: PathLike | None = None, name: str | None = None
) -> ElasticBody:
    """Read a substructure written by ``*SUBSTRUCTURE MATRIX OUTPUT, OUTPUT FILE=USER DEFINED``.

    Parameters
    ----------
    file : path-like
        The ``.mtx`` file (layout and assumptions in the module docstring).
    inp : path-like, optional
        Coordinates of the retained nodes: the Abaqus input file of the model, or a
        ``nodes.csv`` (header ``id,x,y,z``).
    name : str, optional
        Label of the body; default: the file name without extension.

    Returns
    -------
    ElasticBody
        The retained nodes and dofs with the reduced stiffness and mass; notes say what was
        read and how it was checked.

    Raises
    ------
    UserError
        ``file:line: problem`` for a malformed file, an unsupported dof or node, a block cut
        short, an unsymmetric matrix or a missing mass matrix; a node missing in ``inp``.
    """
    path = Path(file)
    text = read_text(path, _KIND)
    blocks = list(keyword_blocks(text))
    if not blocks:
        raise located_error(
            path, None, "no keyword lines: not a *SUBSTRUCTURE MATRIX OUTPUT file (*USER ELEMENT)"
        )
    line, keyword_text, data, data_line = blocks[0]
    keyword, params = parse_keyword(keyword_text)
    if keyword != "USERELEMENT":
        raise located_error(
            path,
            line,
            f"first keyword *{keyword}: a substructure matrix file starts with *USER ELEMENT",
        )
    unsym = "UNSYM" in params
    table, node_ids, structure = _dof_table(path, line, params, data, data_line)
    notes = [
        f"dof table: {table.describe()} from the *USER ELEMENT lines of {path.name}{structure}"
    ]
    matrices: dict[str, sp.csr_matrix] = {}
    ignored = []
    for line, keyword_text, data, data_line in blocks[1:]:
        keyword, params = parse_keyword(keyword_text)
        kind = " ".join(params.get("TYPE", "").upper().split())
        if keyword != "MATRIX":
            ignored.append(f"*{keyword} (line {line})")
            continue
        if kind not in _ROLES:
            raise located_error(
                path, line, f"*MATRIX, TYPE={kind or '?'}: expected TYPE=STIFFNESS or TYPE=MASS"
            )
        role = _ROLES[kind]
        if role in matrices:
            raise located_error(path, line, f"a second *MATRIX, TYPE={kind} block")
        matrix, note = _matrix(path, line, kind, data, data_line, table)
        matrices[role] = matrix
        if note:
            notes.append(note)
    if "stiffness" not in matrices:
        raise located_error(path, None, "no *MATRIX, TYPE=STIFFNESS block: the file holds no K")
    if "mass" not in matrices:
        raise located_error(
            path,
            None,
            "the file holds only the stiffness matrix (no *MATRIX, TYPE=MASS block); generate "
            "the substructure with *SUBSTRUCTURE GENERATE, MASS MATRIX=YES and write it with "
            "*SUBSTRUCTURE MATRIX OUTPUT, MASS=YES",
        )
    if ignored:
        notes.append(f"ignored blocks of {path.name}: {', '.join(ignored)}")
    if unsym:
        notes.append(f"{path.name} is written as UNSYM; its matrices are symmetric (see above)")
    coordinates, has_coordinates, where = _coordinates(path, node_ids, inp)
    notes.append(where)
    try:
        body = ElasticBody(
            node_ids=node_ids,
            coordinates=coordinates,
            dofs=table,
            mass=matrices["mass"],
            stiffness=matrices["stiffness"],
            name=name if name is not None else path.stem,
            has_coordinates=has_coordinates,
            notes=tuple(notes),
        )
    except UserError as err:
        raise UserError(f"{path}: {err}") from None
    residuals = body.rigid_body_residuals()
    fields = residuals if has_coordinates else residuals[:3]
    finite = fields[np.isfinite(fields)]
    if finite.size:
        which = "six rigid-body motions" if has_coordinates else "three rigid translations"
        check = f"rigid-body check of the {which}: max residual {finite.max():.0e}"
        body = body.with_notes(check)
    return body


# ============================================================================ the dof table
def _dof_table(
    path: Path, line: int, params: dict[str, str], data: str, data_line: int
) -> tuple[DofTable, np.ndarray, str]:
    """The retained dofs of ``*USER ELEMENT``: table, node ids, and a note fragment."""
    try:
        count = int(params.get("NODES", ""))
    except ValueError:
        raise located_error(path, line, "*USER ELEMENT needs NODES=number of nodes") from None
    if not 0 < count <= 10**7:
        raise located_error(path, line, f"*USER ELEMENT, NODES={count}: out of range")
    if "LINEAR" not in params:
        raise located_error(
            path,
            line,
            "*USER ELEMENT without LINEAR: a general user element has no matrices to read",
        )
    node_list: list[int] = []
    listing = False
    changes: list[tuple[int, list[int]]] = []
    for offset, raw in enumerate(data.split("\n")):
        number = data_line + offset
        stripped = raw.strip()
        if not stripped:
            continue
        if stripped.startswith("**"):
            comment = stripped[2:].strip()
            if comment.upper().startswith("ELEMENT NODES"):
                listing = True
            elif listing:
                node_list.extend(_integers(path, number, comment, "node label"))
            continue
        listing = False
        values = _integers(path, number, stripped, "dof")
        if changes:
            if len(values) < 2:
                raise located_error(
                    path, number, "expected 'node position, dof, dof, ...' (a change of dofs)"
                )
            changes.append((number, values))
        else:
            changes.append((number, [1, *values]))
    if not changes:
        raise located_error(path, line, "*USER ELEMENT without the data line of retained dofs")
    ids = _node_ids(path, line, count, node_list)
    per_node = np.zeros(count, dtype=np.int64)
    dof_lists: list[list[int]] = []
    previous = 0
    for number, (position, *dofs) in changes:
        if not previous < position <= count:
            raise located_error(
                path,
                number,
                f"node position {position}: expected {previous + 1}..{count} (positions "
                f"increase; the element has NODES={count})",
            )
        _check_dofs(path, number, dofs)
        per_node[position - 1 :] = len(dof_lists)
        dof_lists.append(dofs)
        previous = position
    nodes = np.repeat(ids, [len(dof_lists[k]) for k in per_node])
    directions = np.concatenate([np.array(dof_lists[k]) - 1 for k in per_node])
    structure = "" if node_list else " (no ELEMENT NODES list: nodes numbered 1..N)"
    return DofTable(nodes, directions), ids, structure


def _integers(path: Path, number: int, text: str, what: str) -> list[int]:
    out = []
    for field_text in text.split(","):
        field_text = field_text.strip()
        if not field_text:
            continue
        out.append(integer_field(path, number, field_text, what))
    return out


def _node_ids(path: Path, line: int, count: int, node_list: list[int]) -> np.ndarray:
    if not node_list:
        return np.arange(1, count + 1, dtype=np.int64)
    if len(node_list) != count:
        raise located_error(
            path,
            line,
            f"the ELEMENT NODES list names {len(node_list)} nodes but NODES={count}",
        )
    ids = np.array(node_list, dtype=np.int64)
    if np.any(ids < 1):
        bad = int(ids[ids < 1][0])
        raise located_error(
            path,
            line,
            f"node {bad} in the ELEMENT NODES list: an Abaqus internal node (such as one that "
            "carries generalized coordinates); pymorembs cannot place its dofs",
        )
    values, counts = np.unique(ids, return_counts=True)
    if np.any(counts > 1):
        raise located_error(
            path, line, f"node {int(values[counts > 1][0])} appears twice in the ELEMENT NODES list"
        )
    return ids


def _check_dofs(path: Path, number: int, dofs: list[int]) -> None:
    if not dofs:
        raise located_error(path, number, "a node with no retained dof")
    for dof in dofs:
        if not 1 <= dof <= 6:
            what = ABAQUS_DOF_NAMES.get(dof, "not a displacement or rotation")
            raise located_error(
                path,
                number,
                f"dof {dof} is {what}; pymorembs reads structural dofs only (1-6 = ux uy uz rx "
                "ry rz)",
            )
    if len(set(dofs)) != len(dofs):
        raise located_error(path, number, "a dof is listed twice")


# ============================================================================ matrices
def _matrix(
    path: Path, line: int, kind: str, data: str, data_line: int, table: DofTable
) -> tuple[sp.csr_matrix, str | None]:
    """One ``*MATRIX`` block as a symmetric sparse matrix, and a note for full storage."""
    n = len(table)
    values = _values(path, line, kind, data, data_line)
    triangle, full = n * (n + 1) // 2, n * n
    if values.size not in (triangle, full):
        last = data_line + max(len(data.rstrip().split("\n")) - 1, 0)
        if values.size < triangle:
            problem = (
                f"holds {values.size} of the {triangle} values of the lower triangle of "
                f"{n} equations; is the file cut?"
            )
        else:
            problem = (
                f"holds {values.size} values; expected {triangle} (the lower triangle of {n} "
                f"equations) or {full} (the full matrix, UNSYM)"
            )
        raise located_error(path, last, f"*MATRIX, TYPE={kind} block {problem}")
    bad = np.flatnonzero(~np.isfinite(values))
    if bad.size:
        raise located_error(
            path,
            _line_of_value(data, data_line, int(bad[0])),
            f"value {float(values[bad[0]])!r} is not a finite number",
        )
    if values.size == triangle:  # (for n = 1 both storages are one value)
        rows = np.repeat(np.arange(n), np.arange(1, n + 1))
        cols = np.arange(triangle) - np.repeat(np.cumsum(np.arange(n)), np.arange(1, n + 1))
        keep = values != 0.0
        rows, cols, values = rows[keep], cols[keep], values[keep]
        off = rows != cols
        matrix = sp.csr_matrix(
            (
                np.concatenate([values, values[off]]),
                (np.concatenate([rows, cols[off]]), np.concatenate([cols, rows[off]])),
            ),
            shape=(n, n),
        )
        return matrix, None
    dense = values.reshape(n, n)
    gap = np.abs(dense - dense.T)
    scale = float(np.max(np.abs(dense))) or 1.0
    worst = np.unravel_index(int(np.argmax(gap)), gap.shape)
    if gap[worst] > SYMMETRY_TOLERANCE * scale:
        i, j = int(worst[0]), int(worst[1])
        raise located_error(
            path,
            _line_of_value(data, data_line, i * n + j),
            f"*MATRIX, TYPE={kind} (stored full) is not symmetric: entry ({table.label(i)}, "
            f"{table.label(j)}) = {float(dense[i, j])!r} but ({table.label(j)}, "
            f"{table.label(i)}) = {float(dense[j, i])!r}; pymorembs needs symmetric stiffness "
            "and mass matrices",
        )
    matrix = sp.csr_matrix(0.5 * (dense + dense.T))
    matrix.eliminate_zeros()
    note = (
        f"{kind.lower()} matrix stored full; symmetric to {gap[worst] / scale:.0e} of its "
        "largest entry, the mean of both triangles is used"
    )
    return matrix, note


def _values(path: Path, line: int, kind: str, data: str, data_line: int) -> np.ndarray:
    """The numbers of a ``*MATRIX`` block (C-speed parse; a bad token is located on error)."""
    text = ascii_data(path, _COMMENT_LINE.sub("", data), data_line).replace(",", " ")
    if "D" in text or "d" in text:
        text = text.replace("D", "E").replace("d", "e")
    text = _FORTRAN_EXPONENT.sub(r"E\1", text)
    if not text.strip():
        return np.zeros(0)
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            return np.fromstring(text, dtype=float, sep=" ")
    except (ValueError, DeprecationWarning):
        pass
    for offset, raw in enumerate(data.split("\n")):
        if raw.strip().startswith("**"):
            continue
        for token in raw.replace(",", " ").split():
            try:
                float(_FORTRAN_EXPONENT.sub(r"E\1", token.replace("D", "E").replace("d", "e")))
            except ValueError:
                raise located_error(
                    path, data_line + offset, f"value {token!r} is not a number"
                ) from None
    raise located_error(path, line, f"cannot read the values of *MATRIX, TYPE={kind}")


def _line_of_value(data: str, data_line: int, index: int) -> int:
    """Line number of the ``index``-th value of a block (for messages only)."""
    seen = 0
    for offset, raw in enumerate(data.split("\n")):
        if raw.strip().startswith("**"):
            continue
        seen += len(raw.replace(",", " ").split())
        if seen > index:
            return data_line + offset
    return data_line


# ============================================================================ coordinates
def _coordinates(
    path: Path, node_ids: np.ndarray, inp: PathLike | None
) -> tuple[np.ndarray, bool, str]:
    """Coordinates of the retained nodes, whether known, and a note."""
    if inp is None:
        return (
            np.zeros((node_ids.size, 3)),
            False,
            "no coordinates: give the model's .inp or a nodes.csv as inp; the nodes lie at the "
            "origin",
        )
    node_file = read_node_file(inp)
    ids, xyz = node_file.ids, node_file.coordinates
    note = f"coordinates: {node_file.describe()} ({ids.size} nodes)"
    order = np.argsort(ids, kind="stable")
    pos = np.minimum(np.searchsorted(ids[order], node_ids), max(ids.size - 1, 0))
    found = ids.size > 0 and np.asarray(ids[order][pos] == node_ids)
    if ids.size == 0 or not np.all(found):
        missing = node_ids if ids.size == 0 else node_ids[~found]
        raise located_error(
            path,
            None,
            f"retained node {int(missing[0])} is not defined in {inp}; give the input file of "
            "the model the substructure was generated from",
        )
    return xyz[order[pos]], True, note
