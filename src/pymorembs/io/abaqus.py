"""Read the global matrices Abaqus/Standard writes with its matrix generation procedure.

Export: add a matrix generation step to the input file (after the steps that define the state of
the body, with the boundary conditions of the body as it will be reduced, usually none)::

    *STEP
    *MATRIX GENERATE, STIFFNESS, MASS, VISCOUS DAMPING
    *MATRIX OUTPUT, STIFFNESS, MASS, VISCOUS DAMPING, FORMAT=MATRIX INPUT
    *END STEP

Abaqus writes ``jobname_STIFn.mtx``, ``jobname_MASSn.mtx`` and ``jobname_DMPVn.mtx`` (``n`` is the
step number). Read them with :func:`read_abaqus` (``pymorembs`` format ``abaqus``), with the
input file (``inp``) for the node coordinates; :func:`read_abaqus_stiffness` reads a stiffness
file alone (a body without mass, for checks).

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
    formulations without Lagrange multipliers). With an input file written with parts and
    assemblies (the Abaqus/CAE default) the node labels are taken as those of the part of its
    single instance; the coordinates (the instance placement applied) are then proved by the
    rigid-body check below. Several instances are refused: how Abaqus labels their nodes in
    this layout is not documented where pymorembs could verify it.
coordinate (``FORMAT=COORDINATE``)
    ``row column value`` with equation numbers from 1, blank or comma separated; both triangles
    are stored. The files hold no node labels. The dof of every equation comes from a
    ``dofs.csv`` (header ``node,direction``, one row per equation in order; argument ``dofs``)
    or, without it, is derived from the input file (:mod:`pymorembs.io.abaqus_inp`): the nodes
    in the order Abaqus numbers them, each with the dofs its elements activate (solids,
    membranes, trusses: ux uy uz; beams and shells: ux..rz; planar elements: ux uy (rz));
    nodes that no element uses have none. Element types whose equations cannot be derived
    (hybrid, modified, connector, coupled-field, user elements, ...) are refused.

The rigid-body check
    An equation order or a set of coordinates the reader derived is used only where it fits
    the matrices: the six rigid-body motions of the nodes must give no force,
    ``|K r| / (|K|_inf |r|) <= 1e-6`` for each (:meth:`~pymorembs.body.ElasticBody.
    rigid_body_residuals`, over the rows of dofs that are not fixed). Consistent files give
    1e-17 to 1e-12; a wrong order or wrong coordinates give 1e-4 and more. The reader uses it
    to choose the one order that fits and to refuse the files where none does (or two do); a
    model whose stiffness is tied to the ground (springs to ground, elastic foundations)
    cannot pass it: give ``dofs.csv`` or a model without parts then. The notes of the body say
    what was derived; the proof of the map, with its residual, is the consistency check's
    (:func:`~pymorembs.preparation.consistency.check_map`), as for every model.

Boundary conditions of the matrix step (``*BOUNDARY``)
    Abaqus keeps the rows and columns of constrained dofs and writes a penalty diagonal of
    1e36. Every diagonal of at least 1e30 is read as a fixed dof (``ElasticBody.fixed``). Its
    couplings are kept as Abaqus wrote them, and its diagonal is rebuilt from the rest of its
    row: the value for which a rigid translation along the dof (a rigid rotation about the
    node, for a rotational dof) gives no force in that row. ``K`` is then the stiffness of the
    free body and the fixed dofs clamp it; without coordinates, or where the rebuilt value is
    not positive, the sum of the row's absolute couplings is used (the clamped model is the
    same whatever the diagonal of a fixed dof).

Stiffness, mass and damping may cover different (node, dof) sets in the matrix-input layout:
the dof table is their union, sorted by node and then dof, and a matrix is zero where its file
has no entry (a dof only in the stiffness file is massless; a dof only in the mass file has no
stiffness). Blank lines, ``**`` comments and Fortran ``D`` exponents are accepted. Identical
repeated entries are read once; the same position with two different values is an error naming
both lines. Every mistake is a :class:`~pymorembs.errors.UserError` ``file:line: problem``.

Structural (hysteretic) damping ``jobname_DMPSn.mtx`` is not a viscous damping matrix and is
refused; use damping models of pymorembs instead.
"""

from __future__ import annotations

import io
import os
import re
import warnings
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Literal

import numpy as np
import scipy.sparse as sp

from pymorembs.arrays import sorted_unique
from pymorembs.body import DIRECTIONS, DofTable, ElasticBody
from pymorembs.errors import UserError, located_error
from pymorembs.io.abaqus_inp import (
    ABAQUS_DOF_NAMES,
    MAX_LABEL,
    InpModel,
    ascii_data,
    derive_dof_table,
    integer_field,
    named_node_sets,
    read_inp,
    solid_blocks,
    surface_elements,
)
from pymorembs.io.element_surface import attach_surface
from pymorembs.io.matrix_market import SYMMETRY_TOLERANCE, read_dofs_csv
from pymorembs.io.node_files import NodeFile, read_node_file
from pymorembs.io.reader_support import assemble_symmetric, grown_csr, read_text
from pymorembs.io.solid_mesh import attach_mesh
from pymorembs.io.symmetric_assembly import half_of_entries, symmetric_from_half

__all__ = [
    "PENALTY",
    "RIGID_BODY_TOLERANCE",
    "read_abaqus",
    "read_abaqus_stiffness",
    "read_inp_nodes",
    "release_penalties",
]

PathLike = str | os.PathLike[str]

#: A stiffness diagonal of at least this value is a dof fixed by a penalty (Abaqus writes 1e36).
PENALTY = 1e30
#: Largest rigid-body residual that proves a derived equation order or coordinate system.
RIGID_BODY_TOLERANCE = 1e-6

_KEYWORD_LINE = re.compile(r"(?m)^[ \t]*\*(?!\*)")
_KEYWORD_BYTES = re.compile(rb"(?m)^[ \t]*\*(?!\*)")
#: Bytes of a matrix file checked at a time before the parse on the path.
_SCAN_CHUNK = 1 << 24
#: Entries converted at a time (temporary arrays stay small).
_BLOCK = 1 << 20
_MATRIX_INPUT = ("row node", "row dof", "column node", "column dof", "value")
_COORDINATE = ("row", "column", "value")
_KIND = "an Abaqus *MATRIX OUTPUT file"
_GIVE_DOFS = "give the dof of every equation as dofs (a dofs.csv with header node,direction)"


@dataclass
class _MatrixFile:
    """Entries of one ``.mtx`` file, in file order.

    ``columns`` and ``values`` may be released once the matrix is assembled (to save memory);
    they are then parsed again, strictly, when an error message needs them.
    """

    path: Path
    layout: Literal["input", "coordinate"]
    _columns: tuple[np.ndarray, ...] | None  # (node_i, dof_i, node_j, dof_j) or (row, col)
    _values: np.ndarray | None
    _span: tuple[int, int] = (0, 0)  # smallest and largest equation number (coordinate)
    #: the matrix assembled at once from a coordinate file (equations from 0, size: the largest
    #: equation number), or None
    assembled: sp.csr_matrix | None = field(default=None, repr=False)
    _numbers: np.ndarray | None = field(default=None, repr=False)

    @property
    def columns(self) -> tuple[np.ndarray, ...]:
        if self._columns is None:
            self._columns, self._values = _parse_strictly(self.path)
        return self._columns

    @property
    def values(self) -> np.ndarray:
        if self._values is None:
            self._columns, self._values = _parse_strictly(self.path)
        return self._values

    def release(self) -> None:
        """Drop the parsed entries (they are parsed again if a message needs them)."""
        self._columns = self._values = None

    def line_of(self, entry: int) -> int:
        """Line number of entry ``entry`` (from 0); reads the file again, for messages only."""
        if self._numbers is None:
            text = read_text(self.path, _KIND)
            self._numbers = np.array([n for n, _ in _content_lines(text)], dtype=np.int64)
        return int(self._numbers[entry])

    def size(self) -> int:
        """Largest equation number of a coordinate file."""
        return self._span[1]

    def within(self, n: int) -> bool:
        """Whether every equation number of a coordinate file lies in ``1..n``."""
        return self._span[0] >= 1 and self._span[1] <= n


@dataclass
class _Nodes:
    """Node coordinates from an input file or ``nodes.csv``, and what they are."""

    path: Path
    ids: np.ndarray
    xyz: np.ndarray
    model: InpModel | None  # None for other node files
    source: NodeFile

    def note(self) -> str:
        if self.model is None:
            return f"coordinates: {self.source.describe()} ({self.ids.size} nodes)"
        placed = self.model.placements_note()
        return placed if placed is not None else f"coordinates: the *NODE data of {self.path.name}"


def read_abaqus(
    stiffness: PathLike,
    mass: PathLike | None = None,
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
    keywords for ``jobname_DMPVn.mtx``). ``FORMAT=COORDINATE`` files are read too. Layouts and
    rules are described in the module docstring.

    Parameters
    ----------
    stiffness, mass : path-like
        ``jobname_STIFn.mtx`` and ``jobname_MASSn.mtx``. Without ``mass`` the reader stops with
        a one-line message (use :func:`read_abaqus_stiffness` for a stiffness file alone).
    inp : path-like, optional
        The Abaqus input file (``.inp``) of the model (:func:`pymorembs.io.abaqus_inp.read_inp`),
        or a ``nodes.csv`` (header ``id,x,y,z``): the node coordinates and, for
        ``FORMAT=COORDINATE`` files without ``dofs``, the equation order. Without it every node
        lies at the origin (``has_coordinates`` false).
    damping : path-like, optional
        ``jobname_DMPVn.mtx``, the viscous damping matrix.
    name : str, optional
        Label of the body; default: the stiffness file name without ``_STIFn.mtx``.
    dofs : path-like, optional
        ``dofs.csv`` (header ``node,direction``) with the dof of every equation of a
        ``FORMAT=COORDINATE`` file (refused for matrix-input files, which label every entry).

    Returns
    -------
    ElasticBody
        Nodes: those of the dof table (in the order of first appearance there); dof table: the
        union of the dofs of all matrices sorted by node and dof (matrix input), ``dofs``, or
        derived from ``inp`` (coordinate); fixed: the dofs with a penalty diagonal; notes: what
        was assumed, derived and proved.

    Raises
    ------
    UserError
        A missing or malformed file, an unsupported dof or internal node, a non-symmetric matrix,
        conflicting duplicate entries, a node missing in ``inp``, or an equation order or
        coordinates that cannot be derived or proved; one line ``file:line: ...``.
    """
    if mass is None:
        raise located_error(
            Path(stiffness),
            None,
            "no mass file given: this file holds only the stiffness; give jobname_MASSn.mtx "
            "(export with *MATRIX GENERATE, STIFFNESS, MASS and *MATRIX OUTPUT, STIFFNESS, MASS)",
        )
    return _read(Path(stiffness), Path(mass), inp, damping, name, dofs)


def read_abaqus_stiffness(
    stiffness: PathLike,
    inp: PathLike | None = None,
    name: str | None = None,
    dofs: PathLike | None = None,
) -> ElasticBody:
    """Read an Abaqus stiffness file alone, as a body with a zero mass matrix.

    For files exported without mass (``*MATRIX GENERATE, STIFFNESS``): the dof table,
    coordinates, fixed dofs and the rigid-body check are those of :func:`read_abaqus`; a note
    says that the mass is missing. Parameters as for :func:`read_abaqus`.
    """
    return _read(Path(stiffness), None, inp, None, name, dofs)


def read_inp_nodes(path: PathLike) -> tuple[np.ndarray, np.ndarray]:
    """Node ids and global coordinates of an Abaqus input file.

    Reads the ``*NODE`` blocks with parts, instances and includes as
    :func:`pymorembs.io.abaqus_inp.read_inp` does (ids and placements are described there).

    Returns
    -------
    ids : ndarray of int, shape (n_nodes,)
    coordinates : ndarray, shape (n_nodes, 3)

    Raises
    ------
    UserError
        ``file:line: problem`` for malformed or repeated nodes and unsupported keywords.
    """
    model = read_inp(path)
    return model.node_ids, model.coordinates


def _read_node_source(path: Path) -> _Nodes:
    """The nodes of the ``inp`` option: an Abaqus input file, or any other node file
    (:func:`pymorembs.io.node_files.read_node_file`), which gives coordinates only."""
    node_file = read_node_file(path)
    return _Nodes(path, node_file.ids, node_file.coordinates, node_file.inp, node_file)


# ============================================================================ reading
def _read(
    k_path: Path,
    m_path: Path | None,
    inp: PathLike | None,
    damping: PathLike | None,
    name: str | None,
    dofs: PathLike | None,
) -> ElasticBody:
    paths = {"stiffness": k_path}
    if m_path is not None:
        paths["mass"] = m_path
    if damping is not None:
        paths["damping"] = Path(damping)
        if re.search(r"_DMPS\d*\.mtx$", paths["damping"].name, re.IGNORECASE):
            raise located_error(
                paths["damping"],
                None,
                "a structural damping matrix (DMPS); pymorembs needs the viscous damping matrix "
                "(*MATRIX OUTPUT, VISCOUS DAMPING writes jobname_DMPVn.mtx)",
            )
    files = {role: _read_matrix_file(path) for role, path in paths.items()}
    k_file = files["stiffness"]
    for role, f in files.items():
        if f.layout != k_file.layout:
            raise located_error(
                f.path,
                None,
                f"{_layout_name(f.layout)} layout, but {k_file.path} has the "
                f"{_layout_name(k_file.layout)} layout; export all matrices with the same FORMAT "
                f"({role} file)",
            )
    nodes = _read_node_source(Path(inp)) if inp is not None else None
    if name is None:
        name = re.sub(r"_STIF\d*$", "", k_file.path.stem, flags=re.IGNORECASE) or "body"
    if k_file.layout == "input":
        if dofs is not None:
            raise located_error(
                Path(dofs),
                None,
                "a dofs table is only used with FORMAT=COORDINATE files; the matrix-input files "
                "label every entry with node and dof",
            )
        body = _matrix_input_body(files, nodes, name)
    else:
        body = _coordinate_body(files, nodes, name, None if dofs is None else Path(dofs))
    if m_path is None:
        body = replace(
            body,
            notes=(
                *body.notes,
                f"no mass matrix: {k_file.path.name} was read alone, the mass is zero",
            ),
        )
    if nodes is not None and nodes.model is not None:  # every element for the surface, the
        body = attach_surface(body, surface_elements(nodes.model))  # solids for stiffening
        body = body.with_node_sets(named_node_sets(nodes.model))
        body = attach_mesh(body, solid_blocks(nodes.model))
    return body


def _assemble(
    files: dict[str, _MatrixFile],
    indices: Callable[[str], tuple[np.ndarray, np.ndarray] | None],
    n: int,
    label: Callable[[int], str],
) -> dict[str, sp.csr_matrix]:
    """The ``n x n`` matrices of the files, one after the other.

    ``indices(role)``: the equation indices (from 0) of the row and column of every entry, or
    None when ``f.assembled`` is the matrix. Entries in the layouts FE programs write are
    assembled in compiled code (:mod:`pymorembs.io.symmetric_assembly`), others (and every
    file with a mistake, which is then named) by ``assemble_symmetric``. The parsed entries of
    a file are released once its matrix is built (and parsed again if a message needs them).
    """
    matrices = {}
    for role, f in files.items():
        pair = indices(role)
        if pair is None:
            matrix = grown_csr(f.assembled, n)
        else:
            half = half_of_entries(*pair, f.values, n, SYMMETRY_TOLERANCE)
            del pair
            f.release()
            matrix = None if half is None else symmetric_from_half(half)
            del half
            if matrix is None:
                rows, cols = indices(role)
                matrix = assemble_symmetric(
                    rows, cols, f.values, n, path=f.path, line_of=f.line_of, label=label
                )
        f.release()
        f.assembled = None
        matrices[role] = matrix
    matrices.setdefault("mass", sp.csr_matrix((n, n)))
    return matrices


def _equation_indices(
    files: dict[str, _MatrixFile],
) -> tuple[np.ndarray, Callable[[str], tuple[np.ndarray, np.ndarray]]]:
    """The sorted ``node * 8 + direction`` keys of all dofs of matrix-input files, and a
    function giving the equation indices (int32) of the row and column dof of every entry of
    a file (computed when asked, so that only one file's indices exist at a time).

    Keys within a range of a few times the number of entries are looked up in a table (linear
    time); other (sparse) labels through a sort.
    """

    def pairs(f: _MatrixFile) -> tuple[tuple[np.ndarray, np.ndarray], ...]:
        node_i, dof_i, node_j, dof_j = f.columns
        return (node_i, dof_i), (node_j, dof_j)

    nodes = [node for f in files.values() for node, _ in pairs(f)]
    low = min(int(node.min(initial=MAX_LABEL)) for node in nodes)
    high = max(int(node.max(initial=0)) for node in nodes)
    del nodes
    entries = sum(f.values.size for f in files.values())
    span = (high - low + 1) * 8
    if span > 4 * entries + (1 << 20):  # sparse labels: a sort
        keys = sorted_unique(
            np.concatenate([_keys(n, d) for f in files.values() for n, d in pairs(f)])
        )

        def found(role: str) -> tuple[np.ndarray, np.ndarray]:
            (ni, di), (nj, dj) = pairs(files[role])
            return (
                np.searchsorted(keys, _keys(ni, di)).astype(np.int32),
                np.searchsorted(keys, _keys(nj, dj)).astype(np.int32),
            )

        return keys, found
    present = np.zeros(span, dtype=bool)
    for f in files.values():
        for node, dof in pairs(f):
            for start in range(0, node.size, _BLOCK):
                present[_keys(node[start : start + _BLOCK], dof[start : start + _BLOCK], low)] = 1
    lookup = np.cumsum(present, dtype=np.int32) - 1

    def looked_up(role: str) -> tuple[np.ndarray, np.ndarray]:
        out = []
        for node, dof in pairs(files[role]):
            index = np.empty(node.size, dtype=np.int32)
            for start in range(0, node.size, _BLOCK):
                stop = start + _BLOCK
                index[start:stop] = lookup[_keys(node[start:stop], dof[start:stop], low)]
            out.append(index)
        return out[0], out[1]

    return np.flatnonzero(present) + low * 8, looked_up


def _keys(node: np.ndarray, dof: np.ndarray, low: int = 0) -> np.ndarray:
    """``(node - low) * 8 + dof - 1`` as int64."""
    key = node.astype(np.int64)
    key -= low
    key *= 8
    key += dof
    key -= 1
    return key


def _make_body(
    files: dict[str, _MatrixFile],
    matrices: dict[str, sp.csr_matrix],
    table: DofTable,
    nodes: _Nodes | None,
    name: str,
    notes: list[str],
) -> ElasticBody:
    """The body, its coordinates looked up in ``nodes``; the stiffness keeps its penalties."""
    _, first = np.unique(table.nodes, return_index=True)
    node_ids = table.nodes[np.sort(first)]
    if nodes is None:
        coordinates = np.zeros((node_ids.size, 3))
        notes = [*notes, "no coordinates: no inp given, every node lies at the origin"]
    else:
        coordinates = _coordinates(nodes, node_ids, files, table)
        notes = [*notes, nodes.note()]
    k_file = files["stiffness"]
    fixed = np.flatnonzero(matrices["stiffness"].diagonal() >= PENALTY)
    try:
        return ElasticBody(
            node_ids=node_ids,
            coordinates=coordinates,
            dofs=table,
            mass=matrices["mass"],
            stiffness=matrices["stiffness"],
            damping_matrix=matrices.get("damping"),
            fixed=fixed,
            name=name,
            has_coordinates=nodes is not None,
            notes=tuple(notes),
        )
    except UserError as err:
        raise UserError(f"{k_file.path}: {err}") from None


def _matrix_input_body(
    files: dict[str, _MatrixFile], nodes: _Nodes | None, name: str
) -> ElasticBody:
    for f in files.values():
        _check_labels(f)
    keys, indices = _equation_indices(files)
    table = DofTable(keys // 8, keys % 8)
    k_file = files["stiffness"]
    matrices = _assemble(files, indices, len(table), table.label)
    notes = [
        f"dof table: {table.describe()} from the node and dof labels of {k_file.path.name} "
        "(FORMAT=MATRIX INPUT)"
    ]
    model = nodes.model if nodes is not None else None
    holding = sorted_unique(model.node_scope) if model is not None else np.zeros(0, dtype=np.int64)
    if model is None or not model.uses_parts or not holding.size:
        return release_penalties(_make_body(files, matrices, table, nodes, name, notes))
    if holding.size != 1 or model.scopes[int(holding[0])].kind != "instance":
        names = ", ".join(model.scopes[int(k)].describe() for k in holding)
        raise located_error(
            model.path,
            None,
            f"nodes in {holding.size} places ({names}): which labels Abaqus writes into "
            "FORMAT=MATRIX INPUT files for such a model is not known to pymorembs; export with "
            "FORMAT=COORDINATE (the equation order is then derived from the input file and "
            "proved) or write the input file without parts and assemblies",
        )
    scope = model.scopes[int(holding[0])]
    body = _make_body(files, matrices, table, nodes, name, notes)
    worst = _worst_residual(body)
    if not worst <= RIGID_BODY_TOLERANCE:
        raise located_error(
            k_file.path,
            None,
            f"the node labels of {scope.describe()} in {model.path.name} "
            f"({scope.placement.describe()}) do not fit the matrices: rigid-body residual "
            f"{worst:.1e} (at most {RIGID_BODY_TOLERANCE:g} when labels and coordinates belong to "
            "the matrices); give "
            "the coordinates as a nodes.csv or write the input file without parts and assemblies",
        )
    # the labels fit the matrices (the check above refuses them otherwise); the one proof of the
    # map and its note are the consistency check's (preparation.consistency.check_map)
    return release_penalties(body.with_notes(f"node labels = the labels of {scope.describe()}"))


def _coordinate_body(
    files: dict[str, _MatrixFile], nodes: _Nodes | None, name: str, dofs: Path | None
) -> ElasticBody:
    k_file = files["stiffness"]
    if dofs is not None:
        table, dof_lines = read_dofs_csv(dofs)
        where = f"the {len(table)} equations of {dofs}"
        checked = {role: _check_equations(f, len(table), where) for role, f in files.items()}
        indices = checked.get

        def label(i: int) -> str:
            return f"{i + 1} = {table.label(i)}"

        matrices = _assemble(files, indices, len(table), label)
        notes = [f"dof table: {table.describe()} from {dofs.name}"]
        try:
            body = _make_body(files, matrices, table, nodes, name, notes)
        except _MissingNode as missing:
            raise located_error(dofs, dof_lines[missing.equation], missing.problem) from None
        return release_penalties(body)
    if nodes is None or nodes.model is None:
        given = "" if nodes is None else f" ({nodes.path.name} gives no elements)"
        raise located_error(
            k_file.path,
            None,
            "FORMAT=COORDINATE files number the equations without node labels; give the Abaqus "
            f"input file as inp (the equation order is then derived from it){given}, or "
            f"{_GIVE_DOFS}, or export with FORMAT=MATRIX INPUT (the default)",
        )
    model = nodes.model
    n = max(f.size() for f in files.values())
    tables = []
    for order in ("file", "label"):
        table, types = derive_dof_table(model, order)
        if len(table) != n:  # (checked before any n-sized allocation)
            raise located_error(
                k_file.path,
                None,
                f"the equation order derived from {model.path.name} gives {len(table)} "
                f"equations ({table.describe()} from elements {types}) but the matrices have {n}; "
                f"{_GIVE_DOFS}",
            )
        if not tables or not np.array_equal(table.nodes, tables[0][0].nodes):
            tables.append((table, order))
    checked = {role: _check_equations(f, n, f"equations 1..{n}") for role, f in files.items()}
    matrices = _assemble(files, checked.get, n, lambda i: f"equation {i + 1}")
    candidates = []
    for table, order in tables:
        where = "the *NODE order" if order == "file" else "the order of labels in each instance"
        note = f"dof table: {table.describe()} in {where} of {model.path.name} (elements {types})"
        body = _make_body(files, matrices, table, nodes, name, [note])
        candidates.append((_worst_residual(body), body, note))
    proved = [c for c in candidates if c[0] <= RIGID_BODY_TOLERANCE]
    if len(proved) != 1:
        worst = min(c[0] for c in candidates)
        problem = (
            f"does not fit the matrices: rigid-body residual {worst:.1e} (at most "
            f"{RIGID_BODY_TOLERANCE:g} when order and coordinates belong to the matrices)"
            if not proved
            else "is ambiguous: the nodes in file order and in label order both pass the "
            "rigid-body check"
        )
        raise located_error(
            k_file.path,
            None,
            f"the equation order derived from {model.path.name} {problem}; {_GIVE_DOFS}",
        )
    # the one order that fits is taken; the consistency check proves the map and says so
    return release_penalties(proved[0][1])


def _worst_residual(body: ElasticBody) -> float:
    """The largest rigid-body residual (NaN fields skipped); inf when there is none."""
    residuals = body.rigid_body_residuals()
    finite = residuals[np.isfinite(residuals)]
    return float(finite.max()) if finite.size else float("inf")


# ============================================================================ penalties
def release_penalties(body: ElasticBody) -> ElasticBody:
    """The body with its penalty diagonals (>= :data:`PENALTY`) replaced, those dofs fixed.

    The diagonal of a fixed dof is rebuilt from the rest of its row so that a rigid translation
    along the dof (for a rotational dof: a rigid rotation about its node) gives no force in the
    row; without coordinates for a rotational dof, or where that value is not positive, the sum
    of the absolute off-diagonal entries of the row is used. The off-diagonal entries stay as
    they are. A note says how many dofs were fixed and how their diagonal was set.
    """
    k = body.stiffness
    diagonal = k.diagonal()
    fixed = np.flatnonzero(diagonal >= PENALTY)
    if not fixed.size:
        return body
    penalties = sp.csr_matrix((diagonal[fixed], (fixed, fixed)), shape=k.shape)
    rows = sp.csr_matrix((k - penalties)[fixed])
    rows.eliminate_zeros()
    forces = np.asarray(rows @ body.rigid_body_modes(np.zeros(3)))  # each row times each field
    direction = body.dofs.directions[fixed]
    rebuilt = np.full(fixed.size, np.nan)
    along = np.flatnonzero(direction < 3)
    rebuilt[along] = -forces[along, direction[along]]
    about = np.flatnonzero((direction >= 3) & (direction < 6))
    if body.has_coordinates and about.size:
        where = body.node_rows(body.dofs.nodes[fixed[about]])
        axis = np.eye(3)[direction[about] - 3]
        lever = np.cross(axis, body.coordinates[where])  # the node's own motion in the field
        own = np.einsum("ij,ij->i", lever, forces[about, :3])
        rebuilt[about] = -(forces[about, direction[about]] - own)
    bound = np.asarray(abs(rows).sum(axis=1)).ravel()
    fallback = ~(rebuilt > 0.0)
    rebuilt[fallback] = bound[fallback]
    stiffness = sp.csr_matrix(
        k - penalties + sp.csr_matrix((rebuilt, (fixed, fixed)), shape=k.shape)
    )
    stiffness.eliminate_zeros()
    values = np.unique(diagonal[fixed])
    ends = values[:1] if values.size == 1 else values[[0, -1]]
    value = " to ".join(f"{v:.0e}".replace("e+", "e") for v in ends)
    n_nodes = np.unique(body.dofs.nodes[fixed]).size
    note = (
        f"{fixed.size} dofs of {n_nodes} node{'s' if n_nodes != 1 else ''} fixed in the matrix "
        f"step (*BOUNDARY, {value} penalty diagonal); their stiffness diagonal was rebuilt from "
        "the rest of the row (a rigid motion gives no force there)"
    )
    if fallback.any():
        note += f", for {int(fallback.sum())} of them as the sum of the row's absolute couplings"
    return replace(
        body,
        stiffness=stiffness,
        fixed=np.union1d(body.fixed, fixed),
        notes=(*body.notes, note),
    )


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
    """Parse one ``.mtx`` file: :func:`_parse_plain` when the file is plain ASCII numbers, else
    (or when that parse fails) :func:`_parse_strictly`, which names the bad line."""
    fast = _parse_plain(path)
    if fast is None:
        columns, values = _parse_strictly(path)
        layout: Literal["input", "coordinate"] = "input" if len(columns) == 4 else "coordinate"
    else:
        layout, columns, values = fast
        del fast
    f = _MatrixFile(path, layout, columns, values)
    if layout == "coordinate":
        rows, cols = columns
        low = min(int(rows.min(initial=1)), int(cols.min(initial=1)))
        f._span = (low, int(max(rows.max(initial=0), cols.max(initial=0))))
        if low >= 1 and f._span[1] < 2**31 - 1:  # assembled at once: the entries can go
            half = half_of_entries(rows, cols, values, f._span[1], SYMMETRY_TOLERANCE, base=1)
            if half is not None:
                del rows, cols, columns, values
                f.release()
                f.assembled = symmetric_from_half(half)
    return f


def _parse_plain(
    path: Path,
) -> tuple[Literal["input", "coordinate"], tuple[np.ndarray, ...], np.ndarray] | None:
    """Layout, columns and values of a file of plain ASCII numbers, parsed by ``np.loadtxt`` on
    the path (at C speed, without the text in memory), or None.

    The result is allocated once, for at most as many rows as the file has line ends
    (``max_rows``; NumPy counts only data rows towards it, so every row is read).

    None when a chunk of the file holds a byte that is not ASCII, a NUL byte, a ``D`` exponent
    or a keyword line, when the first chunk holds no data line of 3 or 5 fields, or when the
    parse fails: :func:`_parse_strictly` then reads the file (and names the bad line). Node
    labels and equation numbers are parsed as int32 and dofs as int8 (memory): a value beyond
    their range fails the parse, and the strict pass then reports it.
    """
    head, chunks, lines = "", 0, 0
    buffer = bytearray(_SCAN_CHUNK)  # reused: no fresh pages for every chunk
    try:
        with open(path, "rb", buffering=0) as stream:
            while size := stream.readinto(buffer):
                chunk = buffer if size == len(buffer) else bytes(buffer[:size])
                if not chunk.isascii() or any(b in chunk for b in (b"\0", b"D", b"d")):
                    return None
                if b"*" in chunk and _KEYWORD_BYTES.search(chunk) is not None:
                    return None
                if not chunks:
                    head = chunk.decode("ascii").replace("\r", "\n")
                chunks += 1
                lines += chunk.count(b"\n") + chunk.count(b"\r")
    except OSError:
        return None
    del buffer
    if chunks > 1:  # the first chunk may end inside a line
        head = head[: head.rfind("\n") + 1]
    first = _first_data_line(head)
    if first is None:
        return None
    delimiter = "," if "," in first[0] else None
    count = len(_split(first[0], delimiter))
    if count == 5:
        layout: Literal["input", "coordinate"] = "input"
        kinds = (np.int32, np.int8, np.int32, np.int8)
    elif count == 3:
        layout, kinds = "coordinate", (np.int32, np.int32)
    else:
        return None
    dtype = [(f"c{i}", kind) for i, kind in enumerate(kinds)] + [("value", np.float64)]
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            table = np.loadtxt(  # max_rows: one allocation of the result, no regrowth
                path, dtype=dtype, delimiter=delimiter, comments="*", ndmin=1, max_rows=lines + 1
            )
    except (ValueError, OverflowError, OSError):
        return None
    columns = tuple(table[f"c{i}"] for i in range(len(kinds)))
    return layout, columns, table["value"]


def _parse_strictly(path: Path) -> tuple[tuple[np.ndarray, ...], np.ndarray]:
    """Columns (int64) and values of one ``.mtx`` file from its decoded text (D exponents,
    ``**`` comments, keyword lines and non-ASCII text are handled; a bad line is named)."""
    text = read_text(path, _KIND)
    keyword = _KEYWORD_LINE.search(text)
    if keyword is not None:
        number = text.count("\n", 0, keyword.start()) + 1
        word = text[keyword.start() :].split("\n", 1)[0].strip().split(",")[0]
        raise located_error(
            path,
            number,
            f"keyword line {word!r}: not a matrix file of *MATRIX OUTPUT (a *SUBSTRUCTURE or "
            "*ELEMENT MATRIX OUTPUT file, or an input file?); export with *MATRIX GENERATE and "
            "*MATRIX OUTPUT",
        )
    text = ascii_data(path, text, 1, comment="*")
    first = _first_data_line(text)
    if first is None:
        raise located_error(
            path, None, "no matrix entries (the file is empty or holds only comments)"
        )
    data, number = first
    delimiter = "," if "," in data else None
    count = len(_split(data, delimiter))
    if count == 5:
        names = _MATRIX_INPUT
    elif count == 3:
        names = _COORDINATE
    else:
        raise located_error(
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
        raise located_error(path, None, f"cannot read the entries: {err}") from None
    del text
    columns = tuple(np.ascontiguousarray(table[f"c{i}"]) for i in range(count - 1))
    return columns, np.ascontiguousarray(table["value"])


def _locate_bad_line(path: Path, delimiter: str | None, names: tuple[str, ...]) -> None:
    """Raise :class:`UserError` at the first malformed entry line (after a failed fast parse)."""
    separator = "comma-separated" if delimiter == "," else "blank-separated"
    for number, data in _content_lines(read_text(path, _KIND)):
        fields = _split(data, delimiter)
        if len(fields) != len(names):
            raise located_error(
                path,
                number,
                f"{len(fields)} {separator} fields, expected {len(names)} ({', '.join(names)}); "
                "is the line cut?",
            )
        for text, what in zip(fields[:-1], names[:-1], strict=True):
            integer_field(path, number, text, what)
        try:
            float(fields[-1].replace("D", "E").replace("d", "e"))
        except ValueError:
            raise located_error(path, number, f"value {fields[-1]!r} is not a number") from None


def _check_labels(f: _MatrixFile) -> None:
    """Node labels positive and dofs 1..6 in a matrix-input file."""
    node_i, dof_i, node_j, dof_j = f.columns
    huge = np.flatnonzero((node_i > MAX_LABEL) | (node_j > MAX_LABEL))
    if huge.size:
        k = int(huge[0])
        node = int(max(node_i[k], node_j[k]))
        raise located_error(
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
            raise located_error(
                f.path,
                f.line_of(k_node),
                f"node {node} is an internal node (Abaqus labels internal nodes negative, e.g. "
                "the Lagrange multipliers of hybrid or connector elements or of constraints); its "
                "dofs are not nodal displacements, so pymorembs cannot use this matrix: model "
                "without Lagrange multipliers or reduce the body in Abaqus",
            )
        raise located_error(f.path, f.line_of(k_node), "node label 0 is not a valid Abaqus node")
    if k_dof is not None:
        if 1 <= dof_i[k_dof] <= 6:
            node, dof = int(node_j[k_dof]), int(dof_j[k_dof])
        else:
            node, dof = int(node_i[k_dof]), int(dof_i[k_dof])
        what = ABAQUS_DOF_NAMES.get(dof, "not a displacement or rotation")
        raise located_error(
            f.path,
            f.line_of(k_dof),
            f"dof {dof} of node {node} is {what}; pymorembs reads structural dofs only (Abaqus "
            f"dofs 1-6 = {' '.join(DIRECTIONS)})",
        )


def _check_equations(f: _MatrixFile, n: int, where: str) -> tuple[np.ndarray, np.ndarray] | None:
    """Equation indices (from 0) of a coordinate file, checked against the ``n`` dofs; None
    when the file's matrix is assembled already (``f.assembled``) and fits."""
    if f.assembled is not None and f.within(n):
        return None
    f.assembled = None
    rows, cols = f.columns
    bad = np.flatnonzero((rows < 1) | (rows > n) | (cols < 1) | (cols > n))
    if bad.size:
        k = int(bad[0])
        raise located_error(
            f.path,
            f.line_of(k),
            f"entry ({rows[k]}, {cols[k]}) lies outside {where} (equations count from 1)",
        )
    return rows - 1, cols - 1


class _MissingNode(Exception):
    """A node of a dofs.csv that the coordinates lack (raised at the dofs.csv line)."""

    def __init__(self, equation: int, problem: str) -> None:
        super().__init__(problem)
        self.equation, self.problem = equation, problem


def _coordinates(
    nodes: _Nodes, node_ids: np.ndarray, files: dict[str, _MatrixFile], table: DofTable
) -> np.ndarray:
    """Coordinates of ``node_ids``; a missing node is an error at its first use."""
    order = np.argsort(nodes.ids, kind="stable")
    sorted_ids = nodes.ids[order]
    pos = np.searchsorted(sorted_ids, node_ids)
    found = np.zeros(node_ids.size, dtype=bool)
    inside = pos < sorted_ids.size
    found[inside] = sorted_ids[pos[inside]] == node_ids[inside]
    if not found.all():
        node = int(node_ids[np.flatnonzero(~found)[0]])
        kind = "row" if nodes.model is None else "*NODE data line"
        problem = f"node {node} is not defined in {nodes.path} (no {kind})"
        if nodes.model is not None and nodes.model.uses_parts:
            problem += f"; {nodes.model.id_rule}"
        for f in files.values():
            if f.layout == "input":
                node_i, _, node_j, _ = f.columns
                hit = np.flatnonzero((node_i == node) | (node_j == node))
                if hit.size:
                    raise located_error(f.path, f.line_of(int(hit[0])), problem)
        raise _MissingNode(int(np.flatnonzero(table.nodes == node)[0]), problem)
    return nodes.xyz[order[pos]]
