"""Read the stiffness and mass matrices CalculiX writes in a ``*FREQUENCY, SOLVER=MATRIXSTORAGE``
step, with the dof file and the input deck beside them.

Export: a step in the CalculiX input deck ``job.inp`` (after the model data, with the supports
of the body as it will be reduced, usually none)::

    *STEP
    *FREQUENCY, SOLVER=MATRIXSTORAGE
    *END STEP

``ccx -i job`` then writes, instead of solving the eigenproblem (checked with CalculiX 2.20):

``job.sti``, ``job.mas``
    The stiffness and the mass matrix, one entry per line ``row column value`` (equations from
    1, blank separated, the value with 14 significant digits): the upper triangle column by
    column (``row <= column``), every diagonal entry included.
``job.dof``
    One line ``node.direction`` per equation, in the order of the equations (``103.2`` is uy of
    node 103; directions 1-3 for the nodes of solid elements). The dofs that ``*BOUNDARY`` fixes
    have no equation: CalculiX removes them.

:func:`read_calculix` (format ``calculix``) reads ``job.sti`` and finds ``job.mas``, ``job.dof``
and ``job.inp`` beside it (also compressed, ``job.mas.gz`` ...: :func:`calculix_files`); each may
be given instead. The deck is read with the Abaqus input reader
(:func:`pymorembs.io.abaqus_inp.read_inp`: CalculiX decks are Abaqus syntax): node coordinates,
the elements (the body's surface and, with ``*SOLID SECTION`` and ``*ELASTIC``, the solid mesh for
geometric stiffening), node sets and the ``*BOUNDARY`` blocks up to the matrix storage step.

What is checked before the matrices are parsed (each a one-line :class:`~pymorembs.errors.
UserError` naming file and line):

* every line of the ``.dof`` file is ``node.direction``, direction 1-3, no dof twice;
* every node of the ``.dof`` is a node of an element of the deck (CalculiX adds nodes of its
  own when it expands shells, beams, plane elements or ``C3D8I`` into solids; those exports are
  refused: only solid elements ``C3D4 C3D6 C3D8 C3D8R C3D10 C3D15 C3D20 C3D20R`` and point
  masses or axial springs, ``MASS``, ``SPRINGA``, ``DASHPOTA``, are read);
* the dofs of the deck's element nodes that have no equation are exactly those ``*BOUNDARY``
  fixes (a dof without equation that no ``*BOUNDARY`` fixes is the dependent dof of an
  ``*EQUATION``, ``*MPC``, ``*RIGID BODY`` or ``*TIE``, which cannot be restored; a fixed dof with
  an equation means the ``.dof`` is not of this deck).

Then the matrices: entries within the equations of the ``.dof``, finite, each position once, a
diagonal entry for every equation (a file of a smaller model has none for the last ones), the
triangle mirrored exactly (a file that stores both triangles must be symmetric). The dofs fixed
by ``*BOUNDARY`` are added to the dof table as fixed dofs (``ElasticBody.fixed``) with empty rows
and columns, as the Ansys ``.full`` reader records the dofs Ansys constrains.

The equation order is the ``.dof`` file's, never derived. What only the deck knows goes with the
body: the dofs ``*BOUNDARY`` fixes are its fixed dofs, and the nodes that share an element with
a node that has one are its ``nodes_near_supports`` (CalculiX drops the couplings to the fixed
dofs, so their rows carry the reactions). The one proof of the map is the consistency check
(:func:`~pymorembs.preparation.consistency.check_map`, run by
:func:`~pymorembs.preparation.validation.validate_body` for ``pymorembs info`` and every job):
the rigid-body fields on every other equation; a map they refute is refused there (exit 2).

Speed: a matrix file of 16 MiB or more is parsed and checked in one compiled pass over a memory
map (:func:`pymorembs.io.fast_text.parse_coordinate_lines`, on both cores; the zeros off the
diagonal are left out as they are read) into arrays where the triangle is completed to the full
matrix (:class:`pymorembs.io.fast_text.SymmetricRoom`);
smaller files, and any file with a line of another form, are parsed by NumPy's ``loadtxt``
behind the strict pass that names a bad line.
"""

from __future__ import annotations

import io
import os
import re
import warnings
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import scipy.sparse as sp

from pymorembs.body import DIRECTIONS, DofTable, ElasticBody
from pymorembs.errors import located_error
from pymorembs.io.abaqus_inp import (
    MAX_LABEL,
    InpModel,
    boundary_dofs,
    named_node_sets,
    read_inp,
    solid_blocks,
    surface_elements,
)
from pymorembs.io.compressed import COMPRESSIONS, plain_path
from pymorembs.io.element_surface import attach_surface
from pymorembs.io.fast_text import (
    SymmetricRoom,
    compiled_checks,
    compiled_worthwhile,
    count_line_ends,
    csr_from_sorted_coo,
    full_from_triangle,
    parse_coordinate_lines,
    triangle_sides,
)
from pymorembs.io.matrix_market import SYMMETRY_TOLERANCE, DataLines, read_text_lines
from pymorembs.io.reader_support import assemble_symmetric, grown_csr, read_text
from pymorembs.io.solid_mesh import attach_mesh
from pymorembs.io.symmetric_assembly import half_of_entries, symmetric_from_half

__all__ = [
    "CALCULIX_ELEMENT_TYPES",
    "COMPILED_FROM_BYTES",
    "DofFile",
    "calculix_files",
    "read_calculix",
    "read_calculix_matrix",
    "read_dof_file",
]

PathLike = str | os.PathLike[str]

#: Element types whose nodes keep their own equations (ux uy uz) in CalculiX; other types are
#: expanded by CalculiX into solids with nodes of their own.
CALCULIX_ELEMENT_TYPES = re.compile(
    r"C3D(4|6|8|8R|10|15|20|20R)|MASS|SPRINGA|DASHPOTA", re.IGNORECASE
)
#: Matrix files from this size on are parsed by the compiled kernel (below it, loading the
#: compiled code costs more than NumPy's parse).
COMPILED_FROM_BYTES = 1 << 24

_SUFFIXES = {"mass": ".mas", "dofs": ".dof", "inp": ".inp"}
_WHAT = {
    "mass": "the mass matrix",
    "dofs": "the dof of every equation",
    "inp": "the input deck (nodes, elements, *BOUNDARY)",
}
_MATRIX_KIND = "a CalculiX matrix file (row column value)"
_DOF_KIND = "a CalculiX dof file (one node.direction per line)"
_DOF_TEXT = re.compile(r"(?:\d+\.\d+\n)*\d+\.\d+")
_DOF_LINE = re.compile(r"\s*(\d+)\.(\d+)\s*")
_CONTENT_LINE = re.compile(r"(?m)^[ \t\r\f\v]*\S")
_TRANSLATIONS = 3


# ============================================================================ the files
def calculix_files(
    stiffness: PathLike,
    mass: PathLike | None = None,
    dofs: PathLike | None = None,
    inp: PathLike | None = None,
) -> dict[str, Path]:
    """The files of a CalculiX export: those given, the others found beside ``job.sti``.

    Parameters
    ----------
    stiffness : path-like
        ``job.sti`` (or a compressed ``job.sti.gz``, ``.bz2``, ``.xz``).
    mass, dofs, inp : path-like, optional
        ``job.mas``, ``job.dof`` and the input deck; default: beside ``job.sti``, the plain file
        if it exists, else the first compressed one that does (``job.mas.gz``, ...).

    Returns
    -------
    dict of str -> Path
        ``"stiffness"``, ``"mass"``, ``"dofs"``, ``"inp"``.

    Raises
    ------
    UserError
        ``job.sti`` is the ``.mas`` or ``.dof`` of an export, or a file is missing (one line
        naming it and how to export it).
    """
    k_path = Path(stiffness)
    plain = plain_path(k_path)
    if plain.suffix.lower() in (".mas", ".dof"):
        role = "mass matrix" if plain.suffix.lower() == ".mas" else "dof file"
        raise located_error(
            k_path,
            None,
            f"the {role} of a CalculiX export; give the stiffness file {plain.stem}.sti (its "
            ".mas, .dof and .inp are found beside it)",
        )
    given = {"mass": mass, "dofs": dofs, "inp": inp}
    found = {"stiffness": k_path}
    for role, suffix in _SUFFIXES.items():
        if given[role] is not None:
            path = Path(given[role])
        else:
            base = plain.with_suffix(suffix)
            candidates = [base] + [Path(f"{base}{s}") for s, _ in COMPRESSIONS.values()]
            path = next((c for c in candidates if c.is_file()), base)
        if not path.is_file():
            where = "" if given[role] is not None else f" beside {k_path.name}"
            raise located_error(
                path,
                None,
                f"not found{where}: {_WHAT[role]} of the CalculiX export (ccx writes job.sti, "
                f"job.mas and job.dof with *FREQUENCY, SOLVER=MATRIXSTORAGE; give it as {role})",
            )
        found[role] = path
    return found


def read_calculix(
    stiffness: PathLike,
    mass: PathLike | None = None,
    dofs: PathLike | None = None,
    inp: PathLike | None = None,
    name: str | None = None,
) -> ElasticBody:
    """Read a body from the files of a CalculiX ``*FREQUENCY, SOLVER=MATRIXSTORAGE`` step.

    Parameters
    ----------
    stiffness : path-like
        ``job.sti``.
    mass, dofs, inp : path-like, optional
        ``job.mas``, ``job.dof`` and the input deck ``job.inp``; default: beside ``job.sti``
        (:func:`calculix_files`).
    name : str, optional
        Label of the body; default: the job name (``job``).

    Returns
    -------
    ElasticBody
        Dof table: the equations of the ``.dof`` file in their order, then the dofs fixed by
        ``*BOUNDARY`` (fixed dofs, empty rows and columns); coordinates, surface, solid mesh
        and node sets (``*NSET``) from the deck; notes: the files read and the supports.

    Raises
    ------
    UserError
        A missing file, a ``.dof``, deck or matrix that does not fit the others, an element type
        whose equations CalculiX renumbers, or a dof that CalculiX eliminated by a constraint;
        one line ``file[:line]: problem`` (module docstring).
    """
    paths = calculix_files(stiffness, mass, dofs, inp)
    k_path = paths["stiffness"]
    equations = read_dof_file(paths["dofs"])
    model = read_inp(paths["inp"])
    layout = _layout(equations, model, paths["inp"])
    n = len(equations.nodes)
    stiffness_matrix = read_calculix_matrix(k_path, n, equations)
    mass_matrix = read_calculix_matrix(paths["mass"], n, equations)
    total = len(layout.table)
    body = ElasticBody(
        node_ids=layout.node_ids,
        coordinates=model.coordinates[layout.node_rows],
        dofs=layout.table,
        mass=grown_csr(mass_matrix, total),
        stiffness=grown_csr(stiffness_matrix, total),
        fixed=np.arange(n, total),
        name=name if name is not None else plain_path(k_path).stem,
        notes=tuple(layout.notes(k_path, paths)),
        nodes_near_supports=layout.near_supports,
    )
    body = attach_surface(body, surface_elements(model)).with_node_sets(named_node_sets(model))
    return attach_mesh(body, solid_blocks(model))


# ============================================================================ the dof file
@dataclass(frozen=True, eq=False)
class DofFile:
    """The equations of a CalculiX ``.dof`` file (:func:`read_dof_file`)."""

    path: Path
    nodes: np.ndarray  # node label of every equation, shape (n,)
    directions: np.ndarray  # direction 0-5 of every equation, shape (n,)
    text: str

    def line_of(self, equation: int) -> int:
        """Line number of an equation (from 0); for messages only."""
        numbers = self.__dict__.get("_numbers")
        if numbers is None:
            lines = self.text.split("\n")
            numbers = np.flatnonzero([bool(line.strip()) for line in lines]) + 1
            object.__setattr__(self, "_numbers", numbers)
        return int(numbers[equation])

    def label(self, equation: int) -> str:
        """``equation 12 (node 103 uz)`` for messages."""
        node, direction = self.nodes[equation], self.directions[equation]
        return f"equation {equation + 1} (node {node} {DIRECTIONS[direction]})"


def read_dof_file(path: PathLike) -> DofFile:
    """The equations of a CalculiX ``.dof`` file: one ``node.direction`` per line.

    Parameters
    ----------
    path : path-like
        ``job.dof``.

    Returns
    -------
    DofFile
        Node label and direction (0-5 for CalculiX's 1-6) of every equation, in file order.

    Raises
    ------
    UserError
        ``file:line: ...`` for a line of another form, a direction outside 1-6, a node label out
        of range, a dof given twice, or a file without equations.
    """
    path = Path(path)
    text = read_text(path, _DOF_KIND)
    joined = "\n".join(text.split())  # one token per line when the file is well formed
    rows = len(_CONTENT_LINE.findall(text))
    if not joined:
        raise located_error(path, None, "no equations (the file is empty)")
    table = None
    if rows == joined.count("\n") + 1 and _DOF_TEXT.fullmatch(joined):
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                table = np.loadtxt(io.StringIO(joined), delimiter=".", dtype=np.int64, ndmin=2)
        except (ValueError, OverflowError):
            table = None
    if table is None or table.shape[1] != 2:
        _locate_bad_dof_line(path, text)
        raise located_error(path, None, "cannot read the equations")  # pragma: no cover
    dofs = DofFile(path, table[:, 0].copy(), table[:, 1] - 1, text)
    bad = np.flatnonzero((dofs.nodes < 1) | (dofs.nodes > MAX_LABEL))
    if bad.size:
        k = int(bad[0])
        raise located_error(
            path, dofs.line_of(k), f"node label {dofs.nodes[k]} is out of range (1 to 2**31 - 1)"
        )
    bad = np.flatnonzero((dofs.directions < 0) | (dofs.directions > 5))
    if bad.size:
        k = int(bad[0])
        raise located_error(
            path,
            dofs.line_of(k),
            f"direction {dofs.directions[k] + 1} of node {dofs.nodes[k]} is not a displacement "
            f"or rotation (CalculiX directions 1-6 = {' '.join(DIRECTIONS)})",
        )
    keys = dofs.nodes * 8 + dofs.directions
    order = np.argsort(keys, kind="stable")
    twice = np.flatnonzero(keys[order][1:] == keys[order][:-1])
    if twice.size:
        first, second = sorted((int(order[twice[0]]), int(order[twice[0] + 1])))
        raise located_error(
            path,
            dofs.line_of(second),
            f"node {dofs.nodes[second]} {DIRECTIONS[dofs.directions[second]]} is listed again "
            f"(first on line {dofs.line_of(first)})",
        )
    return dofs


def _locate_bad_dof_line(path: Path, text: str) -> None:
    """Raise :class:`UserError` at the first line that is not ``node.direction``."""
    for number, line in enumerate(text.split("\n"), start=1):
        if line.strip() and not _DOF_LINE.fullmatch(line):
            shown = line.strip() if len(line.strip()) <= 40 else line.strip()[:40] + "..."
            raise located_error(
                path,
                number,
                f"{shown!r} is not node.direction (CalculiX writes one node.direction per "
                "equation, e.g. 103.2)",
            )
        match = _DOF_LINE.fullmatch(line)
        if match is not None and len(match.group(1)) > 10:
            raise located_error(path, number, f"node label {match.group(1)} is out of range")


# ============================================================================ the deck
@dataclass(frozen=True, eq=False)
class _Layout:
    """The dof table of the body and what the deck says about it."""

    table: DofTable  # the .dof equations, then the fixed dofs
    node_ids: np.ndarray
    node_rows: np.ndarray  # row of each node in the deck's arrays
    types: str  # the element types of the deck
    near_supports: np.ndarray  # ids of the nodes with fixed dofs and of their element neighbours
    n_fixed: int
    boundary_note: str

    def notes(self, k_path: Path, paths: dict[str, Path]) -> list[str]:
        n = len(self.table) - self.n_fixed
        notes = [
            f"CalculiX export: K from {k_path.name}, M from {paths['mass'].name} (upper "
            f"triangles), the {n} equations from {paths['dofs'].name}; dof table "
            f"{self.table.describe()}",
            f"coordinates and elements ({self.types}) from {paths['inp'].name}",
        ]
        if self.n_fixed:
            notes.append(self.boundary_note)
        return notes


def _layout(dofs: DofFile, model: InpModel, deck: Path) -> _Layout:
    """Check the ``.dof`` file against the deck and build the body's dof table (module
    docstring: the checks before the matrices are parsed)."""
    if model.uses_parts:
        raise located_error(
            deck,
            None,
            "the deck defines parts and an assembly, which CalculiX does not read; give the "
            "input deck ccx ran",
        )
    elements, types = _element_rows(model, deck)
    used = np.zeros(model.node_ids.size, dtype=bool)
    for rows in elements:
        used[rows.ravel()] = True
    index = model.index_of(np.zeros(dofs.nodes.size, dtype=np.int64), dofs.nodes)
    missing = np.flatnonzero(index < 0)
    if missing.size:
        k = int(missing[0])
        raise located_error(
            dofs.path,
            dofs.line_of(k),
            f"node {dofs.nodes[k]} is not defined in {deck.name}: the .dof is of another deck, "
            "or CalculiX added the node (it expands shells, beams and plane elements into "
            "solids, and *RIGID BODY adds nodes)",
        )
    stray = np.flatnonzero(~used[index] | (dofs.directions >= _TRANSLATIONS))
    if stray.size:
        k = int(stray[0])
        what = (
            "belongs to no element of the deck"
            if not used[index[k]]
            else "is a rotation, but the deck's elements give their nodes ux uy uz only"
        )
        raise located_error(
            dofs.path,
            dofs.line_of(k),
            f"node {dofs.nodes[k]} {DIRECTIONS[dofs.directions[k]]} {what}; is the .dof of "
            f"{deck.name}?",
        )
    active = np.zeros((model.node_ids.size, _TRANSLATIONS), dtype=bool)
    active[used] = True
    has_equation = np.zeros_like(active)
    has_equation[index, dofs.directions] = True
    fixed = boundary_dofs(model, model.matrix_storage_step)
    structural = used[fixed.nodes] & (fixed.directions < _TRANSLATIONS)
    fixed_nodes, fixed_directions = fixed.nodes[structural], fixed.directions[structural]
    positions = np.flatnonzero(structural)
    clash = np.flatnonzero(has_equation[fixed_nodes, fixed_directions])
    if clash.size:
        k = int(clash[0])
        node = model.node_ids[fixed_nodes[k]]
        direction = int(fixed_directions[k])
        equation = int(np.flatnonzero((dofs.nodes == node) & (dofs.directions == direction))[0])
        raise located_error(
            dofs.path,
            dofs.line_of(equation),
            f"node {node} {DIRECTIONS[direction]} has an equation, but *BOUNDARY "
            f"({fixed.where(int(positions[k]))}) fixes it and CalculiX removes fixed dofs: the "
            f".dof is not of {deck.name} (or of a step with other boundary conditions)",
        )
    free = active & ~has_equation
    free[fixed_nodes, fixed_directions] = False
    lost = np.argwhere(free)
    if lost.size:
        node, direction = model.node_ids[lost[0, 0]], int(lost[0, 1])
        count = lost.shape[0]
        which = f"{count} dofs of the elements of {deck.name} (node {node} "
        which += f"{DIRECTIONS[direction]}{', ...' if count > 1 else ''}) have"
        them = "them"
        if count == 1:
            which = f"node {node} {DIRECTIONS[direction]} of the elements of {deck.name} has"
            them = "it"
        raise located_error(
            dofs.path,
            None,
            f"{which} no equation, and no *BOUNDARY fixes {them}: CalculiX eliminated {them} "
            "by a constraint (*EQUATION, *MPC, *RIGID BODY, *TIE ...), whose dependent dofs "
            "pymorembs cannot restore, or the .dof is of another deck; export the body without "
            "such constraints",
        )
    order = np.lexsort((fixed_directions, model.node_ids[fixed_nodes]))
    fixed_nodes, fixed_directions = fixed_nodes[order], fixed_directions[order]
    table = DofTable(
        np.concatenate([dofs.nodes, model.node_ids[fixed_nodes]]),
        np.concatenate([dofs.directions, fixed_directions]),
    )
    _, first = np.unique(table.nodes, return_index=True)
    node_ids = table.nodes[np.sort(first)]
    node_rows = model.index_of(np.zeros(node_ids.size, dtype=np.int64), node_ids)
    count = np.unique(fixed_nodes).size
    lines = sorted({fixed.where(int(k)) for k in positions})
    shown = ", ".join(lines[:3]) + (f" and {len(lines) - 3} more lines" if len(lines) > 3 else "")
    note = (
        f"{fixed_nodes.size} dofs of {count} node{'s' if count != 1 else ''} fixed by *BOUNDARY "
        f"({shown}): CalculiX removed them from the equations; they are fixed dofs here, with "
        "empty rows and columns"
    )
    supported = np.zeros(model.node_ids.size, dtype=bool)
    supported[fixed_nodes] = True
    near = supported.copy()
    for block in elements:
        near[block[supported[block].any(axis=1)].ravel()] = True
    near_ids = model.node_ids[near]
    return _Layout(table, node_ids, node_rows, types, near_ids, int(fixed_nodes.size), note)


def _element_rows(model: InpModel, deck: Path) -> tuple[list[np.ndarray], str]:
    """The node rows of every element block (shape (elements, nodes)) and the types read."""
    if model.generated_elements is not None:
        path, line = model.generated_elements
        raise located_error(path, line, "elements generated by *ELGEN are not read")
    if not model.elements:
        raise located_error(
            deck,
            None,
            "no *ELEMENT data: not the input deck of the CalculiX export (give job.inp as inp)",
        )
    blocks, types = [], []
    for block in model.elements:
        if not CALCULIX_ELEMENT_TYPES.fullmatch(block.type):
            raise located_error(
                block.path,
                block.line,
                f"element type {block.type}: CalculiX expands shell, beam, plane and truss "
                "elements (and C3D8I) into solids with nodes and constraints of its own, so its "
                "equations are not the deck's; pymorembs reads CalculiX exports of solid "
                "elements (C3D4, C3D6, C3D8, C3D8R, C3D10, C3D15, C3D20, C3D20R), MASS, SPRINGA "
                "and DASHPOTA",
            )
        labels = block.element_labels(model.scopes)
        if not labels.size:
            continue
        blocks.append(model.element_rows(block))
        if block.type.upper() not in types:
            types.append(block.type.upper())
    return blocks, " ".join(types)


# ============================================================================ the matrices
def read_calculix_matrix(path: PathLike, n: int, dofs: DofFile) -> sp.csr_matrix:
    """The full symmetric matrix of a CalculiX ``.sti`` or ``.mas`` file.

    Parameters
    ----------
    path : path-like
        The file: ``row column value`` lines, equations 1..``n``.
    n : int
        The number of equations (of the ``.dof`` file).
    dofs : DofFile
        The equations, for messages.

    Returns
    -------
    scipy.sparse.csr_matrix, shape (n, n)
        Canonical, exactly symmetric, without explicit zeros.

    Raises
    ------
    UserError
        ``file:line: ...`` for a malformed line, an equation outside ``1..n``, a value that is
        not finite, a position given twice with different values, mirror entries that differ;
        ``file: ...`` for an equation without a diagonal entry.
    """
    path = Path(path)
    matrix = _parse_compiled(path, n)
    if matrix is None:
        matrix = _parse_strictly(path, n, dofs)
    matrix.eliminate_zeros()
    return matrix


def _parse_compiled(path: Path, n: int) -> sp.csr_matrix | None:
    """The matrix of a well-formed file by the compiled kernel, or None (no Numba, a small file,
    a line of another form, a line out of CalculiX's order or below the diagonal, an equation
    without diagonal: the strict pass then reads the file and names the problem).

    The entries off the diagonal that are zero are left out as they are parsed (a tet10 mass
    matrix has two zeros for every entry: the couplings of different directions), so that the
    room of the full matrix touches the memory of the entries kept only.
    """
    try:
        size = path.stat().st_size
    except OSError:
        return None
    if size < COMPILED_FROM_BYTES and not compiled_worthwhile(size):
        return None  # (without loading the compiled code)
    if not compiled_checks():
        return None
    entries = count_line_ends(path)
    if not entries or not SymmetricRoom.fits(entries):
        return None
    room = SymmetricRoom(entries)
    # the file's (row <= column) entries, column by column, are the lower triangle (column,
    # row) row by row: the row numbers go to the room's columns and the reverse
    out = (room.cols, room.rows, room.values)
    parsed = parse_coordinate_lines(path, 0, n, entries, out, upper_columns=True)
    if parsed is None:
        return None
    stored = parsed[0].size
    del parsed
    lower = csr_from_sorted_coo(room.rows[:stored], room.cols[:stored], room.values[:stored], n)
    if lower is None or triangle_sides(lower)[1] or not _all_diagonals(lower):
        return None
    full = room.full(lower)
    return full if full is not None else full_from_triangle(lower)


def _all_diagonals(lower: sp.csr_matrix) -> bool:
    """Whether every row of a canonical lower triangle ends with its diagonal entry."""
    indptr = lower.indptr
    if np.any(indptr[1:] == indptr[:-1]):
        return False
    return bool(np.all(lower.indices[indptr[1:] - 1] == np.arange(lower.shape[0])))


def _parse_strictly(path: Path, n: int, dofs: DofFile) -> sp.csr_matrix:
    """The matrix from the decoded text, every problem named by its line."""
    data = DataLines(path, read_text_lines(path, _MATRIX_KIND), 0)
    table = data.parse((("row", int), ("column", int), ("value", float)))
    if table.size == 0:
        raise located_error(path, None, "no matrix entries (the file is empty)")
    rows, cols, values = table["row"] - 1, table["column"] - 1, table["value"]
    del table
    outside = np.flatnonzero((rows < 0) | (rows >= n) | (cols < 0) | (cols >= n))
    if outside.size:
        k = int(outside[0])
        data.fail(
            k,
            f"entry ({rows[k] + 1}, {cols[k] + 1}) lies outside the {n} equations of "
            f"{dofs.path.name}: the files are of different runs",
        )
    data.require_finite(values)
    diagonal = np.zeros(n, dtype=bool)
    diagonal[rows[rows == cols]] = True
    if not diagonal.all():
        first = int(np.flatnonzero(~diagonal)[0])
        raise located_error(
            path,
            None,
            f"no diagonal entry for {dofs.label(first)} of {dofs.path.name} ({n} equations): "
            "CalculiX writes every diagonal entry, so the matrix is of a run with fewer "
            "equations",
        )
    half = half_of_entries(rows, cols, values, n, SYMMETRY_TOLERANCE)
    matrix = None if half is None else symmetric_from_half(half)
    if matrix is None:
        matrix = assemble_symmetric(
            rows, cols, values, n, path=path, line_of=data.line_of, label=_label(dofs)
        )
    return matrix


def _label(dofs: DofFile) -> Callable[[int], str]:
    def label(equation: int) -> str:
        return f"{equation + 1} = {dofs.nodes[equation]}:{DIRECTIONS[dofs.directions[equation]]}"

    return label
