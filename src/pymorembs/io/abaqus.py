"""Read the global matrices Abaqus/Standard writes with its matrix generation procedure.

Export: add a matrix generation step to the input file (after the steps that define the state of
the body, with the boundary conditions of the body as it will be reduced, usually none)::

    *STEP
    *MATRIX GENERATE, STIFFNESS, MASS, VISCOUS DAMPING
    *MATRIX OUTPUT, STIFFNESS, MASS, VISCOUS DAMPING, FORMAT=MATRIX INPUT
    *END STEP

Abaqus writes ``jobname_STIFn.mtx``, ``jobname_MASSn.mtx`` and ``jobname_DMPVn.mtx`` (``n`` is the
step number). ``FORMAT=MATRIX INPUT`` is the default and the layout to prefer. Read them with
:func:`read_abaqus` (``pymorembs`` format ``abaqus``); the node coordinates come from the input
file (``inp``). Write the input file without parts and assemblies (Abaqus/CAE: *Model > Edit
Attributes > Do not use parts and assemblies in input files*) so that node labels are global.

Layouts (told apart by the number of fields on the first data line):

matrix input (``FORMAT=MATRIX INPUT``, default)
    One entry per line, comma separated: ``row node, row dof, column node, column dof, value``.
    Abaqus writes one triangle of a symmetric matrix (in its own equation order, so in terms of
    node labels an entry may lie on either side of the diagonal); a file holding both triangles
    (square format: some position given in both orientations) must be symmetric. Dofs 1-6 are
    ux uy uz rx ry rz. Other Abaqus dofs (7 warping, 8 pore or acoustic pressure, 9 electric
    potential, 11 temperature, ...) are rejected. Negative node labels are internal nodes that
    Abaqus creates, e.g. for the Lagrange multipliers of hybrid or connector elements and of
    constraints; their dofs are not nodal displacements, so such a matrix is rejected (use
    formulations without Lagrange multipliers).
coordinate (``FORMAT=COORDINATE``)
    ``row, column, value`` with equation numbers from 1, comma or blank separated. These files
    hold no node labels, so the dof of every equation must come from a ``dofs.csv`` (header
    ``node,direction``, one row per equation in order; argument ``dofs``). Exporting with
    ``FORMAT=MATRIX INPUT`` is simpler and safer.

Stiffness, mass and damping may cover different (node, dof) sets: the dof table is their union,
sorted by node and then dof, and a matrix is zero where its file has no entry (a dof only in the
stiffness file is massless; a dof only in the mass file has no stiffness). Blank lines, ``**``
comments and Fortran ``D`` exponents are accepted. Identical repeated entries are read once; the
same position with two different values is an error naming both lines. Every mistake is a
:class:`~pymorembs.errors.UserError` ``file:line: problem``.

Structural (hysteretic) damping ``jobname_DMPSn.mtx`` is not a viscous damping matrix and is
refused; use damping models of pymorembs instead.
"""

from __future__ import annotations

import io
import os
import re
import warnings
from dataclasses import dataclass, field
from pathlib import Path
from typing import Literal

import numpy as np

from pymorembs.body import DIRECTIONS, DofTable, ElasticBody
from pymorembs.errors import UserError
from pymorembs.io.formats import assemble_symmetric, collect_nodes, is_nodes_csv, read_text
from pymorembs.io.matrix_market import _fail, _read_dofs, _read_nodes

__all__ = ["read_abaqus", "read_inp_nodes"]

PathLike = str | os.PathLike[str]

#: Abaqus degrees of freedom beyond 1-6 (Abaqus Analysis User's Guide, "Conventions").
_OTHER_DOFS = {
    7: "the warping amplitude of open-section beams",
    8: "a pore, hydrostatic fluid or acoustic pressure",
    9: "an electric potential",
    10: "a connector material flow",
    11: "a temperature (or normalized concentration)",
}
_MAX_LABEL = 2**31 - 1  # largest Abaqus node label (32-bit)
_KEYWORD_LINE = re.compile(r"(?m)^[ \t]*\*(?!\*)")
_MATRIX_INPUT = ("row node", "row dof", "column node", "column dof", "value")
_COORDINATE = ("row", "column", "value")
_KIND = "an Abaqus *MATRIX OUTPUT file"


@dataclass
class _MatrixFile:
    """Entries of one ``.mtx`` file, in file order."""

    path: Path
    layout: Literal["input", "coordinate"]
    columns: tuple[np.ndarray, ...]  # (node_i, dof_i, node_j, dof_j) or (row, col)
    values: np.ndarray
    _numbers: np.ndarray | None = field(default=None, repr=False)

    def line_of(self, entry: int) -> int:
        """Line number of entry ``entry`` (from 0); reads the file again, for messages only."""
        if self._numbers is None:
            text = read_text(self.path, _KIND)
            self._numbers = np.array([n for n, _ in _content_lines(text)], dtype=np.int64)
        return int(self._numbers[entry])

    def keys(self) -> tuple[np.ndarray, np.ndarray]:
        """``node * 8 + direction`` of the row and column dof of every entry (matrix input)."""
        node_i, dof_i, node_j, dof_j = self.columns
        return node_i * 8 + (dof_i - 1), node_j * 8 + (dof_j - 1)


def read_abaqus(
    stiffness: PathLike,
    mass: PathLike,
    inp: PathLike | None = None,
    damping: PathLike | None = None,
    name: str | None = None,
    dofs: PathLike | None = None,
) -> ElasticBody:
    """Read a body from the ``.mtx`` files of Abaqus ``*MATRIX GENERATE`` / ``*MATRIX OUTPUT``.

    Export with (Abaqus/Standard input file)::

        *STEP
        *MATRIX GENERATE, STIFFNESS, MASS
        *MATRIX OUTPUT, STIFFNESS, MASS, FORMAT=MATRIX INPUT
        *END STEP

    which writes ``jobname_STIFn.mtx`` and ``jobname_MASSn.mtx`` (add ``VISCOUS DAMPING`` to both
    keywords for ``jobname_DMPVn.mtx``). Layouts and rules are described in the module docstring.

    Parameters
    ----------
    stiffness, mass : path-like
        ``jobname_STIFn.mtx`` and ``jobname_MASSn.mtx``.
    inp : path-like, optional
        The Abaqus input file (``.inp``) whose ``*NODE`` blocks give the coordinates of every
        node of the matrices (:func:`read_inp_nodes`), or a ``nodes.csv`` (header ``id,x,y,z``).
        Without it every node lies at the origin.
    damping : path-like, optional
        ``jobname_DMPVn.mtx``, the viscous damping matrix.
    name : str, optional
        Label of the body; default: the stiffness file name without ``_STIFn.mtx``.
    dofs : path-like, optional
        ``dofs.csv`` (header ``node,direction``) with the dof of every equation; required for
        ``FORMAT=COORDINATE`` files and refused for matrix-input files, which label every entry.

    Returns
    -------
    ElasticBody
        Nodes: those of the dof table (in the order of first appearance there); dof table: the
        union of the dofs of all matrices sorted by node and dof (matrix input) or ``dofs``
        (coordinate).

    Raises
    ------
    UserError
        A missing or malformed file, an unsupported dof or internal node, a non-symmetric matrix,
        conflicting duplicate entries, or a node missing in ``inp``; one line ``file:line: ...``.
    """
    paths = {"stiffness": Path(stiffness), "mass": Path(mass)}
    if damping is not None:
        paths["damping"] = Path(damping)
        if re.search(r"_DMPS\d*\.mtx$", paths["damping"].name, re.IGNORECASE):
            raise _fail(
                paths["damping"],
                None,
                "a structural damping matrix (DMPS); pymorembs needs the viscous damping matrix "
                "(*MATRIX OUTPUT, VISCOUS DAMPING writes jobname_DMPVn.mtx)",
            )
    files = {role: _read_matrix_file(path) for role, path in paths.items()}
    k_file = files["stiffness"]
    for role, f in files.items():
        if f.layout != k_file.layout:
            raise _fail(
                f.path,
                None,
                f"{_layout_name(f.layout)} layout, but {k_file.path} has the "
                f"{_layout_name(k_file.layout)} layout; export all matrices with the same FORMAT "
                f"({role} file)",
            )

    dof_lines: list[int] | None = None
    indices: dict[str, tuple[np.ndarray, np.ndarray]] = {}
    if k_file.layout == "input":
        if dofs is not None:
            raise _fail(
                Path(dofs),
                None,
                "a dofs table is only used with FORMAT=COORDINATE files; the matrix-input files "
                "label every entry with node and dof",
            )
        for f in files.values():
            _check_labels(f)
        all_keys = {role: f.keys() for role, f in files.items()}
        keys = np.unique(np.concatenate([k for pair in all_keys.values() for k in pair]))
        table = DofTable(keys // 8, keys % 8)
        for role, (key_i, key_j) in all_keys.items():
            indices[role] = (np.searchsorted(keys, key_i), np.searchsorted(keys, key_j))

        def label(i: int) -> str:
            return table.label(i)

    else:
        if dofs is None:
            raise _fail(
                k_file.path,
                None,
                "FORMAT=COORDINATE files number the equations without node labels; give the dof "
                "of every equation as dofs (a dofs.csv with header node,direction) or export "
                "with FORMAT=MATRIX INPUT (the default)",
            )
        table, dof_lines = _read_dofs(Path(dofs))
        for role, f in files.items():
            indices[role] = _check_equations(f, len(table), Path(dofs))

        def label(i: int) -> str:
            return f"{i + 1} = {table.label(i)}"

    n = len(table)
    matrices = {
        role: assemble_symmetric(
            *indices[role], f.values, n, path=f.path, line_of=f.line_of, label=label
        )
        for role, f in files.items()
    }

    _, first = np.unique(table.nodes, return_index=True)
    node_ids = table.nodes[np.sort(first)]
    if inp is None:
        coordinates = np.zeros((node_ids.size, 3))
    else:
        coordinates = _coordinates(Path(inp), node_ids, files, table, dofs, dof_lines)
    if name is None:
        name = re.sub(r"_STIF\d*$", "", k_file.path.stem, flags=re.IGNORECASE) or "body"
    try:
        return ElasticBody(
            node_ids=node_ids,
            coordinates=coordinates,
            dofs=table,
            mass=matrices["mass"],
            stiffness=matrices["stiffness"],
            damping_matrix=matrices.get("damping"),
            name=name,
        )
    except UserError as err:
        raise UserError(f"{k_file.path}: {err}") from None


# ============================================================================ .mtx files
def _layout_name(layout: str) -> str:
    if layout == "input":
        return "matrix-input (node, dof, node, dof, value)"
    return "FORMAT=COORDINATE (row, column, value)"


def _content_lines(text: str) -> list[tuple[int, str]]:
    """(line number, text before any ``*``) of every line holding data.

    Keyword lines are refused before, so a ``*`` can only start a ``**`` comment.
    """
    out = []
    for number, line in enumerate(text.split("\n"), start=1):
        data = line.split("*", 1)[0]
        if data.strip():
            out.append((number, data))
    return out


def _first_data_line(text: str) -> tuple[str, int] | None:
    """The first line holding data and its number, without splitting the whole text."""
    start, number = 0, 1
    while start <= len(text):
        end = text.find("\n", start)
        if end < 0:
            end = len(text)
        data = text[start:end].split("*", 1)[0]
        if data.strip():
            return data, number
        start, number = end + 1, number + 1
    return None


def _split(data: str, delimiter: str | None) -> list[str]:
    return [f.strip() for f in data.split(",")] if delimiter == "," else data.split()


def _read_matrix_file(path: Path) -> _MatrixFile:
    """Parse one ``.mtx`` file (vectorised; a bad line is located in a second pass)."""
    text = read_text(path, _KIND)
    keyword = _KEYWORD_LINE.search(text)
    if keyword is not None:
        number = text.count("\n", 0, keyword.start()) + 1
        word = text[keyword.start() :].split("\n", 1)[0].strip().split(",")[0]
        raise _fail(
            path,
            number,
            f"keyword line {word!r}: not a matrix file of *MATRIX OUTPUT (a *SUBSTRUCTURE or "
            "*ELEMENT MATRIX OUTPUT file, or an input file?); export with *MATRIX GENERATE and "
            "*MATRIX OUTPUT",
        )
    first = _first_data_line(text)
    if first is None:
        raise _fail(path, None, "no matrix entries (the file is empty or holds only comments)")
    data, number = first
    delimiter = "," if "," in data else None
    count = len(_split(data, delimiter))
    if count == 5:
        layout: Literal["input", "coordinate"] = "input"
        names = _MATRIX_INPUT
    elif count == 3:
        layout, names = "coordinate", _COORDINATE
    else:
        raise _fail(
            path,
            number,
            f"{count} fields; expected 5 (node, dof, node, dof, value: FORMAT=MATRIX INPUT) or 3 "
            "(row, column, value: FORMAT=COORDINATE)",
        )
    if "D" in text or "d" in text:
        text = text.replace("D", "E").replace("d", "e")
    dtype = [(f"c{i}", np.int64) for i in range(count - 1)] + [("value", np.float64)]
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # "input contained no data"
            table = np.loadtxt(
                io.StringIO(text), dtype=dtype, delimiter=delimiter, comments="*", ndmin=1
            )
    except ValueError as err:
        _locate_bad_line(path, delimiter, names)
        raise _fail(path, None, f"cannot read the entries: {err}") from None
    del text
    columns = tuple(np.ascontiguousarray(table[f"c{i}"]) for i in range(count - 1))
    return _MatrixFile(path, layout, columns, np.ascontiguousarray(table["value"]))


def _locate_bad_line(path: Path, delimiter: str | None, names: tuple[str, ...]) -> None:
    """Raise :class:`UserError` at the first malformed entry line (after a failed fast parse)."""
    separator = "comma-separated" if delimiter == "," else "blank-separated"
    for number, data in _content_lines(read_text(path, _KIND)):
        fields = _split(data, delimiter)
        if len(fields) != len(names):
            raise _fail(
                path,
                number,
                f"{len(fields)} {separator} fields, expected {len(names)} ({', '.join(names)}); "
                "is the line cut?",
            )
        for text, what in zip(fields[:-1], names[:-1], strict=True):
            try:
                value = int(text)
            except ValueError:
                raise _fail(path, number, f"{what} {text!r} is not an integer") from None
            if abs(value) > _MAX_LABEL:
                raise _fail(path, number, f"{what} {text!r} is out of range (at most 2**31 - 1)")
        try:
            float(fields[-1].replace("D", "E").replace("d", "e"))
        except ValueError:
            raise _fail(path, number, f"value {fields[-1]!r} is not a number") from None


def _check_labels(f: _MatrixFile) -> None:
    """Node labels positive and dofs 1..6 in a matrix-input file."""
    node_i, dof_i, node_j, dof_j = f.columns
    huge = np.flatnonzero((node_i > _MAX_LABEL) | (node_j > _MAX_LABEL))
    if huge.size:
        k = int(huge[0])
        node = int(max(node_i[k], node_j[k]))
        raise _fail(
            f.path,
            f.line_of(k),
            f"node label {node} is out of range (Abaqus labels are below 2**31); damaged file?",
        )
    bad_node = np.flatnonzero((node_i <= 0) | (node_j <= 0))
    bad_dof = np.flatnonzero((dof_i < 1) | (dof_i > 6) | (dof_j < 1) | (dof_j > 6))
    k_node = int(bad_node[0]) if bad_node.size else None
    k_dof = int(bad_dof[0]) if bad_dof.size else None
    if k_node is not None and (k_dof is None or k_node <= k_dof):
        node = int(node_i[k_node]) if node_i[k_node] <= 0 else int(node_j[k_node])
        if node < 0:
            raise _fail(
                f.path,
                f.line_of(k_node),
                f"node {node} is an internal node (Abaqus labels internal nodes negative, e.g. "
                "the Lagrange multipliers of hybrid or connector elements or of constraints); its "
                "dofs are not nodal displacements, so pymorembs cannot use this matrix: model "
                "without Lagrange multipliers or reduce the body in Abaqus",
            )
        raise _fail(f.path, f.line_of(k_node), "node label 0 is not a valid Abaqus node")
    if k_dof is not None:
        if 1 <= dof_i[k_dof] <= 6:
            node, dof = int(node_j[k_dof]), int(dof_j[k_dof])
        else:
            node, dof = int(node_i[k_dof]), int(dof_i[k_dof])
        what = _OTHER_DOFS.get(dof, "not a displacement or rotation")
        raise _fail(
            f.path,
            f.line_of(k_dof),
            f"dof {dof} of node {node} is {what}; pymorembs reads structural dofs only (Abaqus "
            f"dofs 1-6 = {' '.join(DIRECTIONS)})",
        )


def _check_equations(f: _MatrixFile, n: int, dofs: Path) -> tuple[np.ndarray, np.ndarray]:
    """Equation indices (from 0) of a coordinate file, checked against the ``n`` dofs."""
    rows, cols = f.columns
    bad = np.flatnonzero((rows < 1) | (rows > n) | (cols < 1) | (cols > n))
    if bad.size:
        k = int(bad[0])
        raise _fail(
            f.path,
            f.line_of(k),
            f"entry ({rows[k]}, {cols[k]}) lies outside the {n} equations of {dofs} "
            "(equations count from 1)",
        )
    return rows - 1, cols - 1


def _coordinates(
    inp: Path,
    node_ids: np.ndarray,
    files: dict[str, _MatrixFile],
    table: DofTable,
    dofs: PathLike | None,
    dof_lines: list[int] | None,
) -> np.ndarray:
    """Coordinates of ``node_ids`` from an input file or ``nodes.csv``."""
    csv = is_nodes_csv(inp)
    ids, xyz = _read_nodes(inp) if csv else read_inp_nodes(inp)
    order = np.argsort(ids, kind="stable")
    sorted_ids = ids[order]
    pos = np.searchsorted(sorted_ids, node_ids)
    found = np.zeros(node_ids.size, dtype=bool)
    inside = pos < sorted_ids.size
    found[inside] = sorted_ids[pos[inside]] == node_ids[inside]
    if not found.all():
        node = int(node_ids[np.flatnonzero(~found)[0]])
        problem = f"node {node} is not defined in {inp} (no {'row' if csv else '*NODE data line'})"
        if dof_lines is not None and dofs is not None:
            raise _fail(Path(dofs), dof_lines[int(np.flatnonzero(table.nodes == node)[0])], problem)
        for f in files.values():
            node_i, _, node_j, _ = f.columns
            hit = np.flatnonzero((node_i == node) | (node_j == node))
            if hit.size:
                raise _fail(f.path, f.line_of(int(hit[0])), problem)
    return xyz[order[pos]]


# ============================================================================ .inp files
#: Keywords that make *NODE coordinates or matrix dof directions differ from what is read.
_UNSUPPORTED = {
    "PART": "parts and instances: node labels of a part are local to it, so they cannot be "
    "matched with the matrix output; write the input file without parts and assemblies "
    "(Abaqus/CAE: Model > Edit Attributes > Do not use parts and assemblies in input files)",
    "INSTANCE": "parts and instances: node labels of a part are local to it, so they cannot be "
    "matched with the matrix output; write the input file without parts and assemblies "
    "(Abaqus/CAE: Model > Edit Attributes > Do not use parts and assemblies in input files)",
    "SYSTEM": "*SYSTEM gives node coordinates in a local system, which pymorembs does not "
    "convert; give the nodes in the global system",
    "TRANSFORM": "*TRANSFORM puts the dofs of nodes in local directions, so the matrices are not "
    "in global ux..rz; remove the transformation before generating the matrices",
    "NMAP": "*NMAP moves nodes, which pymorembs does not do; write the final coordinates",
    "NGEN": "nodes generated by *NGEN are not read; write every node in a *NODE block",
    "NFILL": "nodes generated by *NFILL are not read; write every node in a *NODE block",
    "NCOPY": "nodes generated by *NCOPY are not read; write every node in a *NODE block",
}


def read_inp_nodes(path: PathLike) -> tuple[np.ndarray, np.ndarray]:
    """Node labels and coordinates of the ``*NODE`` blocks of an Abaqus input file.

    Reads ``*NODE`` (any parameters such as ``NSET``; ``SYSTEM=R`` only; data lines
    ``label, x[, y[, z[, ...]]]``, missing coordinates are 0; ``INPUT=file`` is followed) and
    follows ``*INCLUDE, INPUT=file`` (relative to the including file). Keyword lines ending in a
    comma continue on the next line; ``**`` comments and blank lines are skipped; ``D`` exponents
    are accepted. ``*PART``/``*INSTANCE``, ``*SYSTEM``, ``*TRANSFORM``, ``*NMAP``, ``*NGEN``,
    ``*NFILL`` and ``*NCOPY`` are refused with an explanation, since node labels, coordinates
    or dof directions would not be those of the matrix output.

    Returns
    -------
    ids : ndarray of int, shape (n_nodes,)
    coordinates : ndarray, shape (n_nodes, 3)

    Raises
    ------
    UserError
        ``file:line: problem`` for malformed or repeated nodes and unsupported keywords.
    """
    return collect_nodes(_scan_inp, path)


def _scan_inp(
    path: Path,
    ids: list[int],
    xyz: list[tuple[float, float, float]],
    seen: dict[int, tuple[Path, int]],
    stack: tuple[Path, ...],
) -> None:
    resolved = path.resolve()
    if resolved in stack:
        raise _fail(path, None, "*INCLUDE loop: the file includes itself")
    lines = read_text(path, "an Abaqus input file").split("\n")
    in_node = False
    k = 0
    while k < len(lines):
        number, stripped = k + 1, lines[k].strip()
        k += 1
        if not stripped or stripped.startswith("**"):
            continue
        if stripped.startswith("*"):
            while stripped.endswith(",") and k < len(lines):  # continued keyword line
                stripped += lines[k].strip()
                k += 1
            keyword, params = _parse_keyword(stripped)
            in_node = False
            if keyword in _UNSUPPORTED:
                raise _fail(path, number, _UNSUPPORTED[keyword])
            if keyword == "NODE":
                system = params.get("SYSTEM", "R").upper()
                if system != "R":
                    raise _fail(
                        path,
                        number,
                        f"*NODE, SYSTEM={system}: only rectangular coordinates (SYSTEM=R) are "
                        "supported",
                    )
                if "INPUT" in params:
                    node_file = path.parent / params["INPUT"]
                    node_lines = read_text(node_file, "a file of *NODE data lines").split("\n")
                    for j, line in enumerate(node_lines, start=1):
                        text = line.strip()
                        if text and not text.startswith("**"):
                            _node_line(node_file, j, text, ids, xyz, seen)
                else:
                    in_node = True
            elif keyword == "INCLUDE":
                if "INPUT" not in params:
                    raise _fail(path, number, "*INCLUDE without INPUT=file")
                _scan_inp(path.parent / params["INPUT"], ids, xyz, seen, (*stack, resolved))
            continue
        if in_node:
            _node_line(path, number, stripped, ids, xyz, seen)


def _parse_keyword(text: str) -> tuple[str, dict[str, str]]:
    """Keyword name (upper case, blanks removed) and parameters of a keyword line."""
    parts = text[1:].split(",")
    keyword = "".join(parts[0].upper().split())
    params: dict[str, str] = {}
    for part in parts[1:]:
        key, _, value = part.partition("=")
        key = "".join(key.upper().split())
        if key:
            params[key] = value.strip().strip('"').strip("'")
    return keyword, params


def _node_line(
    path: Path,
    number: int,
    text: str,
    ids: list[int],
    xyz: list[tuple[float, float, float]],
    seen: dict[int, tuple[Path, int]],
) -> None:
    """One ``*NODE`` data line: ``label, x, y, z`` (missing coordinates are 0)."""
    fields = [f.strip() for f in text.split(",")]
    try:
        node = int(fields[0])
    except ValueError:
        raise _fail(path, number, f"node label {fields[0]!r} is not an integer") from None
    if abs(node) > _MAX_LABEL:
        raise _fail(
            path, number, f"node label {node} is out of range (Abaqus labels are below 2**31)"
        )
    coords = [0.0, 0.0, 0.0]
    for axis, field_text in enumerate(fields[1:4]):
        if not field_text:
            continue
        try:
            coords[axis] = float(field_text.replace("D", "E").replace("d", "e"))
        except ValueError:
            raise _fail(
                path, number, f"coordinate {'xyz'[axis]} {field_text!r} is not a number"
            ) from None
        if not np.isfinite(coords[axis]):
            raise _fail(path, number, f"coordinate {'xyz'[axis]} {field_text!r} is not finite")
    if node in seen:
        first_path, first_line = seen[node]
        raise _fail(
            path, number, f"node {node} is defined twice (first in {first_path}:{first_line})"
        )
    seen[node] = (path, number)
    ids.append(node)
    xyz.append((coords[0], coords[1], coords[2]))
