"""What the Nastran readers share: matrix names, coordinates, CD transforms, notes, the body.

Matrix names
    Nastran names its matrices after the role and the set: ``KAAX``/``MAAX`` (EXTOUT,DMIGPCH),
    ``KAA``/``MAA`` (MSC EXTSEOUT), ``KXX``/``MXX`` (NX EXTSEOUT), ``KGG``/``MGG`` (DMAP
    output). :func:`choose_matrices` pairs a stiffness ``K<suffix>`` with the mass
    ``M<suffix>`` of the same suffix among the square matrices of a file (1 x 1 zero
    placeholders, which EXTSEOUT writes for empty matrices, do not count), takes ``B<suffix>``
    as the viscous damping when present and notes a ``K4<suffix>`` (structural damping, not a
    viscous damping matrix). Given names override; several pairs are refused with the list.

Coordinates and displacement systems
    :func:`build_body` takes the coordinates of the grids of the dof table from a ``nodes.csv``
    or from Nastran bulk data (:mod:`pymorembs.io.nastran_bulk`: GRID cards with their CP
    systems). The components of a grid with a displacement coordinate system ``CD`` other than
    basic are those of its local axes; the matrices are rotated to the basic system,
    ``K_basic = T K_local T^T`` with ``T`` block diagonal (the 3 x 3 direction cosines for the
    translations and for the rotations of each such grid), so that the body's ``ux .. rz`` are
    global. A grid with only some components in the matrices can be rotated only when its
    local axes of those components are basic axes (a permutation, possibly with signs);
    otherwise it is refused. Every reader notes what it did; when coordinates are known, the
    rigid-body check (:meth:`~pymorembs.body.ElasticBody.rigid_body_residuals`) is noted too,
    and for a CD transform the check without it, which proves that it was needed.
"""

from __future__ import annotations

import os
from collections.abc import Mapping
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
import scipy.sparse as sp

from pymorembs.body import SCALAR, DofTable, ElasticBody
from pymorembs.errors import UserError, located_error
from pymorembs.io.checks import make_body
from pymorembs.io.element_surface import attach_surface
from pymorembs.io.matrix_market import check_symmetric
from pymorembs.io.nastran_bulk import (
    AnalysisSet,
    BulkData,
    bulk_solid_blocks,
    bulk_surface_elements,
    read_bulk,
)
from pymorembs.io.node_files import node_file_kind, read_node_file
from pymorembs.io.solid_mesh import attach_mesh
from pymorembs.sparse_rows import abs_row_sums

__all__ = [
    "Choice",
    "MatrixInfo",
    "NodeSource",
    "build_body",
    "choose_matrices",
    "describe_set",
    "digits_histogram_note",
    "digits_note",
    "explain_file",
    "modal_block_notes",
    "node_source",
    "scalar_range",
    "symmetric_matrix",
]

PathLike = str | os.PathLike[str]

#: Largest rigid-body residual reported as "passed" (files hold >= 7 significant digits).
RIGID_PASS = 1e-6
_ZERO = 1e-12  # direction cosines below this are zero when a CD rotation must be a permutation


# ============================================================================ matrix names
@dataclass(frozen=True)
class MatrixInfo:
    """A matrix of a file: name (upper case), shape if known, whether it may be K, M or B.

    ``square`` is true for symmetric or square forms; ``placeholder`` for the 1 x 1 zero
    matrices EXTSEOUT writes in place of empty ones.
    """

    name: str
    shape: tuple[int, int] | None
    square: bool
    placeholder: bool = False

    def describe(self) -> str:
        role = _role(self.name) if self.square and not self.placeholder else ""
        parts = [role] if role else []
        if self.shape is not None:
            parts.append(f"{self.shape[0]} x {self.shape[1]}")
        if self.placeholder:
            parts.append("empty placeholder")
        return f"{self.name} ({', '.join(parts)})" if parts else self.name


@dataclass(frozen=True)
class Choice:
    """The matrices chosen for stiffness, mass and damping, and what was noted."""

    stiffness: str
    mass: str
    damping: str | None
    notes: tuple[str, ...]


def _role(name: str) -> str:
    if name.startswith("K4"):
        return "structural damping"
    return {"K": "stiffness", "M": "mass", "B": "viscous damping"}.get(name[:1], "")


def choose_matrices(
    infos: Mapping[str, MatrixInfo],
    path: Path,
    what: str,
    stiffness: str | None = None,
    mass: str | None = None,
    damping: str | None = None,
) -> Choice:
    """Stiffness, mass and damping among the matrices ``infos`` of a file (module docstring).

    Pairs are formed by name among the square matrices that are not placeholders (a matrix of
    unknown shape, as in a DMIG punch, counts as square); the reader then checks the form and
    size of the chosen ones, so a damaged pair is reported as such rather than as missing.

    ``what`` names the matrices in messages (``"DMIG matrix"``, ``"matrix"``). Given names
    (any case) must exist; a missing one is an error listing the file's matrices.
    """
    held = ", ".join(infos) or "no matrices"

    def present(name: str, role: str) -> str:
        key = name.strip().upper()
        if key not in infos:
            raise located_error(
                path, None, f"no {what} named {key} ({role}); the file holds: {held}"
            )
        return key

    usable = {k: v for k, v in infos.items() if not v.placeholder and (v.shape is None or v.square)}
    pairs = [
        (k, "M" + k[1:])
        for k in usable
        if k.startswith("K") and not k.startswith("K4") and "M" + k[1:] in usable
    ]
    notes: list[str] = []
    if stiffness is not None or mass is not None:
        k_name = present(stiffness, "stiffness") if stiffness is not None else None
        m_name = present(mass, "mass") if mass is not None else None
        if k_name is None:
            k_name = present("K" + m_name[1:], "stiffness")  # type: ignore[index]
        if m_name is None:
            m_name = present("M" + k_name[1:], "mass")
    else:
        if not pairs:
            raise located_error(path, None, _no_pair(infos, usable, what))
        if len(pairs) > 1:
            listed = ", ".join(f"{k}/{m}" + _shape_text(usable[k]) for k, m in pairs)
            raise located_error(
                path,
                None,
                f"holds several stiffness/mass pairs: {listed}; choose one with --stiffness-name "
                "and --mass-name",
            )
        k_name, m_name = pairs[0]
        notes.append(f"matrices {k_name} (stiffness) and {m_name} (mass) found by their names")
    suffix = k_name[1:] if k_name.startswith("K") else None
    d_name = None
    if damping is not None:
        d_name = present(damping, "damping")
    elif suffix is not None and "B" + suffix in usable:
        d_name = "B" + suffix
        notes.append(f"{d_name} read as the viscous damping matrix")
    if suffix is not None and "K4" + suffix in usable:
        notes.append(
            f"K4{suffix} (structural damping) is not read: it is not a viscous damping matrix"
        )
    return Choice(k_name, m_name, d_name, tuple(notes))


def _shape_text(info: MatrixInfo) -> str:
    return f" ({info.shape[0]} x {info.shape[1]})" if info.shape is not None else ""


def _no_pair(infos: Mapping[str, MatrixInfo], usable: Mapping[str, MatrixInfo], what: str) -> str:
    """One line: the file holds no stiffness/mass pair, and what it does hold."""
    stiff = [k for k in usable if k.startswith("K") and not k.startswith("K4")]
    others = [info for key, info in infos.items() if key not in stiff[:1]]
    listed = ", ".join(info.describe() for info in others[:12])
    if len(others) > 12:
        listed += f", and {len(others) - 12} more"
    if stiff:
        names = ", ".join(f"M{k[1:]}" for k in stiff)
        tail = f"; the file also holds {listed}" if listed else ""
        return (
            f"holds {usable[stiff[0]].describe()} but no mass matrix (no {names}){tail}; export "
            "the mass matrix too or name it with --mass-name"
        )
    plural = what[:-1] + "ces" if what.endswith("matrix") else what
    return f"holds no stiffness and mass {plural}: {listed}"


def symmetric_matrix(data: object, form: object, where: str) -> sp.csr_matrix:
    """A finite, square, symmetric CSR matrix from pyNastran's matrix data (dense or sparse).

    A matrix of form 6 (symmetric) stored as one triangle is mirrored; any other must be
    symmetric to :data:`~pymorembs.io.matrix_market.SYMMETRY_TOLERANCE` (``where`` starts the
    message).
    """
    if np.iscomplexobj(data.data if sp.issparse(data) else np.asarray(data)):  # type: ignore[union-attr]
        raise UserError(f"{where} is complex; pymorembs needs real matrices")
    a = sp.csr_matrix(data, dtype=float)
    if a.shape[0] != a.shape[1]:
        raise UserError(f"{where} is {a.shape[0]} x {a.shape[1]}, not square")
    a.sum_duplicates()
    if not np.all(np.isfinite(a.data)):
        raise UserError(f"{where} has NaN or infinite entries")
    a.eliminate_zeros()
    below, above = _triangle_counts(a)
    if form == 6 and (below == 0) != (above == 0):  # symmetric, one triangle stored
        strict = sp.tril(a, -1) if below else sp.triu(a, 1)
        a = sp.csr_matrix(sp.diags(a.diagonal()) + strict + strict.T)
    check_symmetric(a, where)
    a.sort_indices()
    return a


def _triangle_counts(a: sp.csr_matrix) -> tuple[int, int]:
    """Stored entries strictly below and strictly above the diagonal of a CSR matrix (by blocks
    of rows, without copies of the matrix)."""
    below = above = 0
    step = max(1, (1 << 20) * a.shape[0] // max(a.nnz, 1))
    for first in range(0, a.shape[0], step):
        last = min(first + step, a.shape[0])
        lo, hi = a.indptr[first], a.indptr[last]
        rows = np.repeat(np.arange(first, last), np.diff(a.indptr[first : last + 1]))
        columns = a.indices[lo:hi]
        below += int(np.count_nonzero(columns < rows))
        above += int(np.count_nonzero(columns > rows))
    return below, above


# ============================================================================ other files
def explain_file(path: Path) -> str:
    """What a Nastran text file without matrices holds, and what to do with it (one line)."""
    try:
        bulk = read_bulk(path)
    except UserError:
        return "no Nastran cards could be read; give the punch file of PARAM,EXTOUT,DMIGPCH"
    what = bulk.describe()
    if bulk.results is not None:
        return f"{what}; write the matrices with PARAM,EXTOUT,DMIGPCH"
    se = bulk.superelement()
    if bulk.kind != "bulk data":
        return f"{what}; give it as nodes next to the DMIG punch or OP4 file of the run"
    if se is not None and bulk.has("EXTRN", "ASET", "QSET1", "QSET"):
        return (
            f"{what}: the EXTBULK of external superelement {se}; its matrices are in the OP4 "
            "file of MATOP4 (or the punch of EXTSEOUT(DMIGPCH)): give that file with this one as "
            "dofs"
        )
    if se is not None and bulk.has("SECONCT", "SEBULK"):
        return (
            f"{what}: the ASMBULK of external superelement {se}; its matrices are in the OP4 "
            "file of MATOP4: give that file with the EXTBULK .pch as dofs"
        )
    if bulk.has("GRID"):
        return f"{what}; give it as nodes next to the DMIG punch or OP4 file"
    return f"{what}; give the punch file of PARAM,EXTOUT,DMIGPCH"


# ============================================================================ notes
def digits_note(counts: np.ndarray, names: str) -> str | None:
    """``"KAAX, MAAX: values with 10 significant digits"`` from per-value digit counts."""
    counts = np.asarray(counts)
    counts = counts[counts > 0]
    return digits_histogram_note(np.bincount(counts) if counts.size else np.zeros(1), names)


def digits_histogram_note(histogram: np.ndarray, names: str) -> str | None:
    """The note of :func:`digits_note` from ``histogram[d]``, the number of values with ``d``
    significant digits (``histogram[0]``, the zeros, is ignored)."""
    histogram = np.asarray(histogram).copy()
    histogram[:1] = 0
    present = np.flatnonzero(histogram)
    if present.size == 0:
        return None
    low, high = int(present[0]), int(present[-1])
    if low == high:
        return f"{names}: values with {high} significant digit{'s' if high != 1 else ''}"
    common = int(histogram.argmax())
    return f"{names}: values with {low} to {high} significant digits (most with {common})"


def scalar_range(ids: np.ndarray) -> str:
    """``"SPOINT 2995001-2995008"`` (or a short list) for scalar point ids."""
    ids = np.unique(np.asarray(ids, dtype=np.int64))
    if ids.size == 0:
        return "no SPOINT"
    if ids.size == 1:
        return f"SPOINT {ids[0]}"
    if ids[-1] - ids[0] + 1 == ids.size:
        return f"SPOINT {ids[0]}-{ids[-1]}"
    return f"SPOINT {ids[0]} ... {ids[-1]}, {ids.size} points"


def describe_set(aset: AnalysisSet, table: DofTable, file: Path) -> list[str]:
    """Notes on a dof table derived from a superelement's bulk data."""
    scalar = table.scalar
    n_b = int((~scalar).sum())
    boundary = DofTable(table.nodes[~scalar], table.directions[~scalar]).describe()
    notes = []
    se = f" {aset.superelement}" if aset.superelement is not None else ""
    if aset.modal:
        notes.append(
            f"Craig-Bampton superelement{se}: {boundary} ({n_b} boundary dofs) + "
            f"{aset.scalars.size} modal coordinates ({scalar_range(aset.scalars)})"
        )
    elif aset.scalars.size:
        notes.append(f"a-set{se}: {boundary} + {aset.scalars.size} scalar points")
    else:
        notes.append(f"a-set{se}: {boundary} ({n_b} dofs)")
    order = (
        f"rows in Nastran's internal sequence: point ids ascending, components 1-6, from the "
        f"{aset.source} cards of {file.name}"
    )
    if aset.assumed:
        order += " (components not listed there: all six taken for every grid)"
    notes.append(order)
    return notes


def modal_block_notes(
    table: DofTable, stiffness: sp.csr_matrix, mass: sp.csr_matrix, show: int = 8
) -> list[str]:
    """Notes on the scalar (modal) block of a Craig-Bampton superelement's matrices.

    Mass-normalised fixed-interface modes give ``M_qq = I``, ``K_qq = diag(omega^2)`` and no
    stiffness coupling to the boundary; when that holds, it confirms that the scalar rows are
    where the dof table puts them, and the fixed-interface frequencies are noted.
    """
    q = np.flatnonzero(table.scalar)
    if q.size == 0 or q.size == len(table):
        return []
    m_qq = mass[q][:, q].toarray()
    k_qq = stiffness[q][:, q].toarray()
    deviation = float(np.abs(m_qq - np.eye(q.size)).max())
    if deviation > 1e-6:
        return []
    notes = [
        f"modal block of the mass matrix is the identity (max deviation {deviation:.1e}): "
        "mass-normalised modal coordinates"
    ]
    diagonal = np.diag(k_qq)
    off = np.abs(k_qq - np.diag(diagonal)).max() if q.size > 1 else 0.0
    b = np.flatnonzero(~table.scalar)
    coupling = stiffness[b][:, q]
    off = max(off, float(abs(coupling).max()) if coupling.nnz else 0.0)
    if diagonal.size and off <= 1e-9 * max(float(np.abs(diagonal).max()), 1e-300):
        freq = np.sqrt(np.abs(diagonal)) / (2 * np.pi)
        shown = ", ".join(f"{f:.7g}" for f in np.sort(freq)[:show])
        more = ", ..." if freq.size > show else ""
        notes.append(
            f"fixed-interface frequencies from the modal block K_qq = diag(omega^2): "
            f"{shown}{more} Hz"
        )
    return notes


# ============================================================================ coordinates
@dataclass(frozen=True)
class NodeSource:
    """Where coordinates come from: a ``nodes.csv`` or Nastran bulk data."""

    path: Path
    bulk: BulkData | None
    csv: tuple[np.ndarray, np.ndarray] | None


def node_source(path: PathLike | None, bulk: BulkData | None = None) -> NodeSource | None:
    """Read ``path`` as bulk data (reusing ``bulk`` if already read), or as another node file
    (``nodes.csv``, an Abaqus/CalculiX deck, an Ansys archive: :func:`pymorembs.io.node_files.
    read_node_file`), whose nodes are grids in the basic system."""
    if path is None:
        return None
    path = Path(path)
    if bulk is not None and bulk.path == path:
        return NodeSource(path, bulk, None)
    if path.is_file() and node_file_kind(path) != "nastran":
        node_file = read_node_file(path)
        return NodeSource(path, None, (node_file.ids, node_file.coordinates))
    return NodeSource(path, read_bulk(path), None)


def build_body(
    source: Path,
    table: DofTable,
    matrices: dict[str, sp.csr_matrix],
    nodes: NodeSource | None,
    notes: list[str],
    name: str,
    where_grid=None,
) -> ElasticBody:
    """The body of the matrices, with coordinates, CD transform, checks and notes.

    Parameters
    ----------
    source : Path
        The matrix file (for messages).
    table : DofTable
        The dof table of the matrices (grid components in the grid's CD system).
    matrices : dict
        ``"stiffness"``, ``"mass"`` and optionally ``"damping"``, sparse (n, n).
    nodes : NodeSource, optional
        Coordinates; ``None``: every grid at the origin (``has_coordinates`` false).
    notes : list of str
        Notes so far; the coordinate, transform and check notes are appended.
    where_grid : callable, optional
        ``where_grid(grid) -> line`` in ``source`` for the message of a grid without
        coordinates.
    """
    notes = list(notes)
    fixed = _empty_rows(matrices, table, notes)
    geometric = ~table.scalar
    _, first = np.unique(table.nodes[geometric], return_index=True)
    node_ids = table.nodes[geometric][np.sort(first)]
    scalar_ids = np.unique(table.nodes[table.scalar])
    clash = np.intersect1d(scalar_ids, node_ids)
    if clash.size:
        raise located_error(
            source,
            None,
            f"point {int(clash[0])} appears as a scalar point (component 0) and as a grid "
            "(components 1-6)",
        )
    if nodes is None:
        coordinates = np.zeros((node_ids.size, 3))
        if node_ids.size:
            notes.append(
                "no coordinates: every grid at the origin (give the bulk data with the GRID "
                "cards, the .pch/.asm or the .f06 as nodes)"
            )
        model = _Model(source, node_ids, coordinates, table, matrices, name, fixed)
        return _body(model, notes, False)
    if not node_ids.size:  # coordinates asked for, but no equation belongs to a grid
        raise located_error(
            source,
            None,
            f"node coordinates given ({nodes.path.name}), but no equation of the matrices "
            "belongs to a grid (scalar coordinates only): give the dof table as well (the "
            "superelement's .pch/.asm or a dofs.csv)",
        )
    if nodes.csv is not None:
        ids, xyz = nodes.csv
        order = np.argsort(ids, kind="stable")
        pos = np.minimum(np.searchsorted(ids[order], node_ids), max(ids.size - 1, 0))
        found = ids.size > 0 and np.all(ids[order][pos] == node_ids)
        if not found:
            missing = node_ids[ids[order][pos] != node_ids] if ids.size else node_ids
            raise _grid_missing(source, int(missing[0]), nodes.path, "row", where_grid)
        coordinates = xyz[order[pos]]
        notes.append(f"coordinates of {_grids(node_ids.size)} from {nodes.path.name}")
        return _body(_Model(source, node_ids, coordinates, table, matrices, name, fixed), notes)
    bulk = nodes.bulk
    assert bulk is not None
    rows = bulk.grid_rows(node_ids)
    if (rows < 0).any():
        grid = int(node_ids[np.flatnonzero(rows < 0)[0]])
        raise _grid_missing(source, grid, nodes.path, "GRID card", where_grid)
    coordinates = bulk.basic_coordinates(rows)
    cp = bulk.grid["cp"][rows]
    where = f"the {bulk.kind} {nodes.path.name}" if bulk.kind != "bulk data" else nodes.path.name
    text = f"coordinates of {_grids(node_ids.size)} from the GRID cards of {where}"
    if (cp != 0).any():
        systems = ", ".join(str(c) for c in np.unique(cp[cp != 0]).tolist())
        text += f" ({int((cp != 0).sum())} located in coordinate systems {systems}, converted)"
    notes.append(text)
    cd = bulk.grid["cd"][rows]
    model = _Model(source, node_ids, coordinates, table, matrices, name, fixed)
    body = _rotated_body(model, notes, bulk, rows, cd) if (cd != 0).any() else _body(model, notes)
    return _with_solid_mesh(_with_cd_reading(body, model, notes, bulk, rows, cp, cd), bulk)


def _with_solid_mesh(body: ElasticBody, bulk: BulkData) -> ElasticBody:
    """The body with the surface of every element of its bulk data and the CTETRA/CHEXA mesh,
    when the data has solids; a CHEXA with 20 grids takes the Gauss rule (3 x 3 x 3, else
    2 x 2 x 2) that reproduces K."""
    body = attach_surface(body, bulk_surface_elements(bulk))
    if not bulk.has("CTETRA", "CHEXA"):
        return body
    blocks = bulk_solid_blocks(bulk)
    full = attach_mesh(body, blocks)
    if (
        full.mesh is not None
        or isinstance(blocks, str)
        or not any(b.kind == "hex20" for b in blocks)
    ):
        return full
    reduced = attach_mesh(body, [replace(b, kind="hex20r") if b.kind == "hex20" else b
                                 for b in blocks])  # fmt: skip
    return reduced if reduced.mesh is not None else full


def _with_cd_reading(
    body: ElasticBody,
    model: _Model,
    notes: list[str],
    bulk: BulkData,
    rows: np.ndarray,
    cp: np.ndarray,
    cd: np.ndarray,
) -> ElasticBody:
    """``body``, or the reading of blank CD fields as CD = CP when only that one passes."""
    node_ids = model.node_ids
    # an EXTBULK punch of MSC Nastran leaves CD blank where it equals CP (se_test_n11): when
    # only that reading passes the rigid-body check, it is the one
    blank = bulk.grid["cd_blank"][rows] & (cp != 0)
    if blank.any() and not _passed(body):
        other = cd.copy()
        other[blank] = cp[blank]
        try:
            alternative = _rotated_body(model, notes, bulk, rows, other)
        except UserError:  # that reading cannot even be expressed: the standard one stands
            return body
        if _passed(alternative):
            shown = ", ".join(str(g) for g in node_ids[blank][:6].tolist())
            worst = float(np.nanmax(body.rigid_body_residuals()))
            text = (
                f"grids {shown} have a blank CD: their components are taken along their CP "
                f"system (CD = CP), the only reading that passes the rigid-body check (with CD = "
                f"0 its residual is {worst:.1e})"
            )
            return replace(alternative, notes=(*alternative.notes, text))
    return body


def _passed(body: ElasticBody) -> bool:
    residuals = body.rigid_body_residuals()
    return bool(np.isfinite(residuals).any() and np.nanmax(residuals) <= RIGID_PASS)


def _rotated_body(
    model: _Model, notes: list[str], bulk: BulkData, rows: np.ndarray, cd: np.ndarray
) -> ElasticBody:
    """The body with the grids of ``cd != 0`` rotated to basic, noted and checked."""
    notes = list(notes)
    axes = bulk.displacement_axes(rows, model.coordinates, cd)
    local = _body(model, [], check=False)
    rotated, table = _to_basic(model.matrices, model.table, model.node_ids, axes, cd, model.source)
    systems = ", ".join(str(c) for c in np.unique(cd[cd != 0]).tolist())
    count = int((cd != 0).sum())
    notes.append(
        f"{count} grid{' has its' if count == 1 else 's have their'} components in displacement "
        f"coordinate system{'s' if len(systems.split(',')) > 1 else ''} CD = {systems}; the "
        "matrices were rotated to the basic system"
    )
    body = _body(replace(model, table=table, matrices=rotated), notes)
    before = local.rigid_body_residuals()
    if np.isfinite(before).any():
        worst = float(np.nanmax(before))
        body = replace(
            body,
            notes=(
                *body.notes,
                f"without the CD rotation the rigid-body residual would be {worst:.1e}",
            ),
        )
    return body


def _empty_rows(
    matrices: dict[str, sp.csr_matrix], table: DofTable, notes: list[str]
) -> np.ndarray:
    """Equations with neither stiffness nor mass (nothing touches them): fixed, with a note.

    Nastran keeps such dofs in an a-set (e.g. the rotations of a grid joined only by solid
    elements or translational springs) where ``PARAM,AUTOSPC`` would constrain them in the
    solution; they are fixed here for the same reason.
    """
    touched = np.zeros(len(table), dtype=bool)
    for role in ("stiffness", "mass"):
        a = matrices[role]
        touched |= abs_row_sums(a) != 0
    empty = np.flatnonzero(~touched)
    if empty.size:
        shown = ", ".join(table.label(int(i)) for i in empty[:6])
        more = ", ..." if empty.size > 6 else ""
        notes.append(
            f"{empty.size} dofs have neither stiffness nor mass ({shown}{more}): fixed, as "
            "Nastran's AUTOSPC would"
        )
    return empty


@dataclass(frozen=True)
class _Model:
    """What every body of one file shares (for the candidate readings of its CD fields)."""

    source: Path
    node_ids: np.ndarray
    coordinates: np.ndarray
    table: DofTable
    matrices: dict[str, sp.csr_matrix]
    name: str
    fixed: np.ndarray


def _grids(count: int) -> str:
    return f"{count} grid{'s' if count != 1 else ''}"


def _grid_missing(source: Path, grid: int, nodes: Path, what: str, where_grid) -> UserError:
    line = where_grid(grid) if where_grid is not None else None
    return located_error(source, line, f"grid {grid} has no {what} in {nodes}")


def _body(
    model: _Model, notes: list[str], has_coordinates: bool = True, check: bool = True
) -> ElasticBody:
    """The body of ``model``; with coordinates and ``check``, the rigid-body check noted."""
    body = make_body(
        model.source,
        node_ids=model.node_ids,
        coordinates=model.coordinates,
        dofs=model.table,
        stiffness=model.matrices["stiffness"],
        mass=model.matrices["mass"],
        damping_matrix=model.matrices.get("damping"),
        fixed=model.fixed,
        name=model.name,
        has_coordinates=has_coordinates,
        notes=tuple(notes),
    )
    if has_coordinates and check:
        residuals = body.rigid_body_residuals()
        if np.isfinite(residuals).any():
            worst = float(np.nanmax(residuals))
            verdict = (
                "passed: dof table, coordinates and matrices belong together"
                if worst <= RIGID_PASS
                else "not passed: the body is held (SPC, springs to ground), or the coordinates "
                "or the dof order do not belong to the matrices"
            )
            text = f"rigid-body check (max |K r|/(|K| |r|) of 6 fields) {worst:.1e}, {verdict}"
            body = body.with_notes(text)
    return body


def _to_basic(
    matrices: dict[str, sp.csr_matrix],
    table: DofTable,
    node_ids: np.ndarray,
    axes: np.ndarray,
    cd: np.ndarray,
    source: Path,
) -> tuple[dict[str, sp.csr_matrix], DofTable]:
    """Rotate the components of the grids with ``cd != 0`` to basic: ``T A T^T``."""
    n = len(table)
    rows_t, cols_t, vals_t = [], [], []
    directions = table.directions.copy()
    touched = np.zeros(n, dtype=bool)
    for k in np.flatnonzero(cd != 0).tolist():
        grid = int(node_ids[k])
        mine = np.flatnonzero((table.nodes == grid) & ~table.scalar)
        r = axes[k]
        for base in (0, 3):
            block = mine[(table.directions[mine] >= base) & (table.directions[mine] < base + 3)]
            if block.size == 0:
                continue
            local = table.directions[block] - base
            columns = r[:, local]  # basic components of the local axes present
            if block.size == 3:
                targets = np.arange(3)
            else:
                used = np.flatnonzero((np.abs(columns) > _ZERO).any(axis=1))
                if used.size != block.size:
                    kind = "translations" if base == 0 else "rotations"
                    present = " ".join(str(c + base + 1) for c in local.tolist())
                    raise located_error(
                        source,
                        None,
                        f"grid {grid} has CD={int(cd[k])} and only components {present} of its "
                        f"{kind} in the matrices; its local axes mix the basic directions, so "
                        "they cannot be expressed along ux..rz (export all three components)",
                    )
                targets = used
            sub = r[np.ix_(targets, local)]
            for a, target in enumerate(targets.tolist()):
                for b, row in enumerate(block.tolist()):
                    if sub[a, b] != 0.0:
                        rows_t.append(int(block[a]))
                        cols_t.append(row)
                        vals_t.append(float(sub[a, b]))
                directions[block[a]] = base + target
            touched[block] = True
    keep = np.flatnonzero(~touched)
    rows_t += keep.tolist()
    cols_t += keep.tolist()
    vals_t += [1.0] * keep.size
    t = sp.csr_matrix((vals_t, (rows_t, cols_t)), shape=(n, n))
    out = {}
    for role, a in matrices.items():
        b = sp.csr_matrix(t @ a @ t.T)
        b = sp.csr_matrix(0.5 * (b + b.T))
        b.eliminate_zeros()
        out[role] = b
    if np.any(directions[~table.scalar] == SCALAR):
        raise AssertionError("a grid component became scalar")
    return out, DofTable(table.nodes, directions)
