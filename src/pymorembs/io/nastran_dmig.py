"""Read stiffness, mass and damping matrices from Nastran DMIG cards (punch files).

Export: MSC or Simcenter (NX) Nastran, normal modes (SOL 103), with every dof the reduction in
pymorembs needs in the analysis set (``ASET``/``ASET1``), and in the bulk data::

    PARAM,EXTOUT,DMIGPCH

(or the case control command ``EXTSEOUT(STIFFNESS,MASS,DMIGPCH)``). Nastran punches the a-set
matrices to ``jobname.pch`` as DMIG matrices ``KAAX`` (stiffness), ``MAAX`` (mass), ``BAAX``
(viscous damping) and ``K4AAX`` (structural damping), besides rectangular ones (``VAX``,
``MUG1T``, ...) and ``DTI`` tables, which are skipped. With a ``QSET`` (component modes) the
punch is a Craig-Bampton superelement: its modal coordinates are scalar points (component 0)
and become scalar coordinates (direction ``q``). Read with :func:`read_dmig` (``pymorembs``
format ``nastran-dmig``). The matrices are those of the a-set after multipoint constraints
(RBE2, MPC) were applied and after ``ASET`` reduction.

Matrix names
    Found automatically when the file holds one stiffness/mass pair ``K<s>``/``M<s>``
    (``KAAX``/``MAAX``, ``KGG``/``MGG``, ``KXX``/``MXX`` ...), with ``B<s>`` as viscous damping
    (:func:`pymorembs.io.nastran_matrices.choose_matrices`); other writers (e.g. OptiStruct
    after its ``DMIGNAME``) or files with several pairs need the names
    (``--stiffness-name``, ``--mass-name``, ``--damping-name``). A file without DMIG cards
    is described in the error (a results punch, the EXTBULK of a superelement, an f06 ...).

Card layout (Nastran Quick Reference Guide, DMIG)::

    DMIG  NAME  "0"  IFO  TIN  TOUT  POLAR        NCOL      header
    DMIG  NAME  GJ   CJ         G1    C1    A1    B1        column GJ, component CJ
          G2    C2   A2    B2   G3    C3    A3    B3        continuation: more rows

``IFO`` 6 is a symmetric matrix (one triangle given, or both if equal), 1 a square one (must be
symmetric); ``TIN`` 1 or 2 is real single or double precision (complex 3, 4 is refused).
Small field (8 characters), large field (``DMIG*``, 16 characters, ``*`` continuation lines) and
free field (commas) are read; columns 73-80 (continuation labels) are ignored; tabs are expanded
to columns of 8. Numbers may use ``E`` or ``D`` exponents or Nastran's short form ``1.5+3``; the
number of significant digits of the values is noted on the body (it bounds the rounding of the
export). Components 1-6 are T1 T2 T3 R1 R2 R3 in the displacement coordinate system of the
grid; component 0 (or blank) is a scalar point.

Coordinates
    From ``nodes``: Nastran bulk data with the GRID cards (the input deck, an include file,
    the EXTBULK ``.pch`` or ASMBULK ``.asm`` of a superelement) or the ``.f06`` of the run
    (its sorted bulk data echo), read by :mod:`pymorembs.io.nastran_bulk` with the ``CP``
    coordinate systems (CORD1R/C/S, CORD2R/C/S); or a ``nodes.csv``. Without ``nodes``, GRID
    cards in the punch itself are used; otherwise every grid lies at the origin
    (``has_coordinates`` false). Grids with a displacement coordinate system ``CD`` have their
    matrix rows rotated to the basic system (:mod:`pymorembs.io.nastran_matrices`).

Matrix names are compared without regard to case. Stiffness, mass and damping may cover different
(grid, component) sets: the dof table is their union sorted by point id and component, and a
matrix is zero where it has no entry (a dof without mass is massless). Identical repeated entries
are read once; the same position with two values is an error naming both lines.

Large files are parsed with numpy. The layout Nastran punches (large-field ``DMIG*`` column
cards, one ``*`` line per entry, fixed columns) is streamed in blocks of a few megabytes, never
held whole: a first pass keeps the card lines (and checks them as a file of their own), a second
converts the entry lines of the chosen matrices block by block and writes the full symmetric
matrix straight from the stored triangle; reading takes about as long as parsing the numbers
and at most twice the memory of the matrices. Every other file (small or free field, tabs, a bad
field, a repeated entry, any error) is read by the strict pass: the lines are classified by their
first byte, the fixed-width fields of all entry lines are cut out as one array and converted at
once; only free-field lines, and lines whose numbers need Nastran's short exponent form, go
through the line-by-line parser, and every message names its line.
"""

from __future__ import annotations

import itertools
import os
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Literal

import numpy as np
import scipy.sparse as sp

from pymorembs.arrays import sorted_unique
from pymorembs.body import SCALAR, DofTable, ElasticBody
from pymorembs.errors import located_error
from pymorembs.io.line_blocks import IrregularText, iter_line_blocks, line_starts
from pymorembs.io.nastran_bulk import (
    MAX_ID,
    line_fields,
    parse_int,
    parse_real,
    read_card_file,
    significant_digits,
)
from pymorembs.io.nastran_matrices import (
    MatrixInfo,
    build_body,
    choose_matrices,
    digits_histogram_note,
    explain_file,
    modal_block_notes,
    node_source,
)
from pymorembs.io.reader_support import assemble_symmetric

__all__ = ["read_dmig"]

PathLike = str | os.PathLike[str]

_WIDTH = 72  # columns 1-72 hold field 1 and the eight data fields; 73-80 are ignored
_SPACE, _STAR, _PLUS, _COMMA, _DOLLAR, _E = (ord(c) for c in " *+,$E")


def read_dmig(
    path: PathLike,
    stiffness: str | None = None,
    mass: str | None = None,
    damping: str | None = None,
    nodes: PathLike | None = None,
    name: str | None = None,
) -> ElasticBody:
    """Read a body from the DMIG matrices of a Nastran punch file.

    Export with ``PARAM,EXTOUT,DMIGPCH`` in the bulk data of a SOL 103 run (details and the
    accepted card layouts in the module docstring).

    Parameters
    ----------
    path : path-like
        The punch file (``.pch``) or any bulk data file with DMIG cards.
    stiffness, mass : str, optional
        Names of the stiffness and mass matrices (any case); default: the one pair
        ``K<s>``/``M<s>`` of the file (``KAAX``/``MAAX`` for ``PARAM,EXTOUT,DMIGPCH``).
    damping : str, optional
        Name of a viscous damping matrix; default ``B<s>`` (e.g. ``BAAX``) if the file has it.
    nodes : path-like, optional
        Coordinates: Nastran bulk data, the superelement ``.pch``/``.asm``, the ``.f06`` with
        its bulk data echo, or a ``nodes.csv`` (header ``id,x,y,z``).
    name : str, optional
        Label of the body; default: the file name without extension.

    Returns
    -------
    ElasticBody
        Equations sorted by point id and component, in the basic coordinate system; scalar
        points as scalar coordinates; notes on what was found and checked.

    Raises
    ------
    UserError
        No DMIG matrices (the message says what the file holds), a missing or ambiguous matrix
        name (the message lists the matrices), a malformed card, a complex or rectangular
        matrix, a non-symmetric matrix, conflicting duplicate entries, a grid missing in
        ``nodes``; one line ``file:line: ...``.
    """
    path = Path(path)
    try:
        body = _read_streamed(path, stiffness, mass, damping, nodes, name)
    except Exception:  # a UserError, _SlowPath or anything else: the strict pass below decides
        body = None
    if body is not None:
        return body
    punch = _Punch(path)
    choice = choose_matrices(
        punch.infos(), path, "DMIG matrix", stiffness=stiffness, mass=mass, damping=damping
    )
    wanted = _wanted(choice)
    punch.check_present(wanted)
    names = list(dict.fromkeys(wanted.values()))
    entries = punch.entries(names)
    all_keys = np.unique(np.concatenate([entries.row_key, entries.col_key]))
    if all_keys.size == 0:
        raise located_error(path, None, f"DMIG {', '.join(names)}: header cards but no entries")
    table = DofTable(all_keys // 8, all_keys % 8)
    n = len(table)
    matrices = {}
    for role, matrix in wanted.items():
        mine = np.flatnonzero(entries.matrix == names.index(matrix))
        lines = entries.line[mine]
        matrices[role] = assemble_symmetric(
            np.searchsorted(all_keys, entries.row_key[mine]),
            np.searchsorted(all_keys, entries.col_key[mine]),
            entries.value[mine],
            n,
            path=path,
            line_of=lambda k, lines=lines: int(lines[k]) + 1,
            label=table.label,
            storage=_storage(punch.headers[matrix][0]),
        )

    def where_grid(grid: int) -> int:
        candidates = [int(entries.line[k]) for k in np.flatnonzero(entries.grid == grid)[:1]]
        column = punch.column_line(grid)
        candidates += [] if column is None else [column]
        return min(candidates) + 1

    digits = entries.digits[entries.digits > 0]
    return _finish(
        path,
        choice.notes,
        names,
        table,
        matrices,
        np.bincount(digits) if digits.size else np.zeros(1, dtype=np.int64),
        (nodes, punch.has_grid, name),
        where_grid,
    )


def _wanted(choice) -> dict[str, str]:
    """Role -> matrix name of the chosen matrices (damping only when there is one)."""
    wanted = {"stiffness": choice.stiffness, "mass": choice.mass}
    if choice.damping is not None:
        wanted["damping"] = choice.damping
    return wanted


def _storage(ifo: int) -> Literal["symmetric", "square"]:
    return "symmetric" if ifo == 6 else "square"


def _finish(
    path: Path,
    choice_notes,
    names: list[str],
    table: DofTable,
    matrices: dict[str, sp.csr_matrix],
    digit_counts: np.ndarray,
    given: tuple[PathLike | None, bool, str | None],
    where_grid,
) -> ElasticBody:
    """The body from the assembled matrices: notes, coordinates, precision.

    ``digit_counts[d]`` is the number of values with ``d`` significant digits (``d`` >= 1);
    ``given`` is (``nodes`` of :func:`read_dmig`, whether the punch has GRID cards, ``name``):
    without ``nodes`` the punch's own GRID cards give the coordinates.
    """
    nodes, has_grid, name = given
    source = nodes if nodes is not None or not has_grid else path
    notes = list(choice_notes)
    notes.append(f"dof table from the DMIG labels: {table.describe()}")
    digits = digits_histogram_note(digit_counts, ", ".join(names))
    if digits is not None:
        notes.append(digits)
    notes += modal_block_notes(table, matrices["stiffness"], matrices["mass"])
    body = build_body(
        path,
        table,
        matrices,
        node_source(source),
        notes,
        path.stem if name is None else name,
        where_grid=where_grid,
    )
    counts = np.asarray(digit_counts).copy()
    counts[:1] = 0
    if not counts.any():
        return body
    common = int(counts.argmax())  # the digits the punch writes
    return replace(body, precision=0.5 * 10.0 ** (1 - common))


# ============================================================================ punch file
@dataclass
class _Entries:
    """Matrix entries in file order."""

    matrix: np.ndarray  # index of the matrix (in the list given to _Punch.entries)
    line: np.ndarray  # line index (from 0)
    value: np.ndarray
    grid: np.ndarray  # row grid
    row_key: np.ndarray  # grid * 8 + direction code (SCALAR for component 0)
    col_key: np.ndarray
    digits: np.ndarray  # significant digits of each value


_OTHER, _COLUMN, _HEADER = 0, 1, 2


class _Punch:
    """The lines of a punch file, classified, and its DMIG cards.

    A card starts on every line whose first character is a letter (or that is neither a comment,
    blank, nor a continuation); continuation lines start with ``+``, ``*``, ``,`` or a blank.
    Card ``k`` spans lines ``card_first[k]`` to ``card_end[k]`` (exclusive).
    """

    def __init__(self, path: Path, raw: bytes | None = None) -> None:
        self.path = path
        if raw is None:
            raw = read_card_file(path, "a Nastran punch file with DMIG cards")
        lines = raw.splitlines()
        if b"\t" in raw:
            lines = [line.expandtabs(8) if b"\t" in line else line for line in lines]
        self.lines = lines
        n = len(lines)
        u = np.array(lines, dtype=f"S{_WIDTH}") if n else np.zeros(0, dtype=f"S{_WIDTH}")
        self.u = u.view(np.uint8).reshape(n, _WIDTH).copy()
        self.u[self.u == 0] = _SPACE
        first = self.u[:, 0]
        self.free = np.zeros(n, dtype=bool)
        if b"," in raw:
            self.free = np.fromiter((b"," in line for line in lines), dtype=bool, count=n)
        blank = (self.u == _SPACE).all(axis=1) & ~self.free
        self.skip = blank | (first == _DOLLAR)
        upper = first & 0xDF  # ASCII letters to upper case
        letter = (upper >= ord("A")) & (upper <= ord("Z"))
        continuation = (first == _STAR) | (first == _PLUS) | (first == _SPACE) | (first == _COMMA)
        self.start = ~self.skip & (letter | ~continuation)  # other lines start a foreign card
        self.large_line = first == _STAR
        self.card_of_line = np.cumsum(self.start) - 1
        self.card_first = np.flatnonzero(self.start)
        self.card_end = np.append(self.card_first[1:], n)
        cards = self.card_first.size
        self.card_kind = np.zeros(cards, dtype=np.int8)
        self.card_matrix = np.full(cards, -1, dtype=np.int64)
        self.card_large = np.zeros(cards, dtype=bool)
        self.card_gj = np.zeros(cards, dtype=np.int64)
        self.card_cj = np.zeros(cards, dtype=np.int64)
        self.names: list[str] = []  # DMIG matrix names in order of appearance
        self.header_cards: dict[str, list[int]] = {}  # matrix -> its header cards
        self.headers: dict[str, tuple[int, int]] = {}  # checked: matrix -> (IFO, line index)
        self._read_cards(letter[self.card_first])

    # ---------------------------------------------------------------- cards
    def _read_cards(self, letter: np.ndarray) -> None:
        """Kind, matrix, column grid and component of every card (vectorised for fixed format)."""
        starts = self.card_first
        names = np.empty(starts.size, dtype=object)
        fixed = np.flatnonzero(letter & ~self.free[starts])
        word = np.char.upper(np.char.strip(self.u[starts[fixed], :8].copy().view("S8").ravel()))
        self.has_grid = bool(np.any(np.char.startswith(word, b"GRID")))
        for large in (False, True):
            cards = fixed[word == (b"DMIG*" if large else b"DMIG")]
            rows = starts[cards]
            w = 16 if large else 8
            name = np.char.strip(self.u[rows, 8 : 8 + w].copy().view(f"S{w}").ravel())
            names[cards] = np.char.decode(np.char.upper(name), "latin-1")
            gj_field = self.u[rows, 8 + w : 8 + 2 * w]
            header = (gj_field == ord("0")).sum(axis=1) == 1
            header &= ((gj_field == _SPACE) | (gj_field == ord("0"))).all(axis=1)
            self.card_kind[cards] = np.where(header, _HEADER, _COLUMN)
            column = cards[~header]
            self.card_gj[column] = self._integers(
                gj_field[~header], rows[~header], "column grid GJ (field 3)"
            )
            cj_field = self.u[rows[~header], 8 + 2 * w : 8 + 3 * w].copy()
            cj_field[(cj_field == _SPACE).all(axis=1), w - 1] = ord("0")  # blank: scalar point
            self.card_cj[column] = self._integers(
                cj_field, rows[~header], "column component CJ (field 4)"
            )
            self.card_large[cards] = large
        for k in np.flatnonzero(letter & self.free[starts]).tolist():  # free field: slow path
            text = self.lines[starts[k]].decode("latin-1")
            word_k = text.split(",", 1)[0].strip().upper()
            self.has_grid |= word_k.rstrip("*") == "GRID"
            if word_k.rstrip("*") != "DMIG":
                continue
            number = int(starts[k]) + 1
            fields = line_fields(text, word_k.endswith("*"), True, self.path, number)
            names[k] = fields[0].upper()
            gj = parse_int(fields[1], self.path, number, "column grid GJ (field 3)")
            self.card_kind[k] = _HEADER if gj == 0 else _COLUMN
            self.card_gj[k] = gj
            self.card_cj[k] = parse_int(fields[2] or "0", self.path, number, "column component CJ")
            self.card_large[k] = word_k.endswith("*")
        dmig = np.flatnonzero(self.card_kind != _OTHER)
        codes: dict[str, int] = {}
        for k in dmig.tolist():
            name_k = names[k]
            if not name_k:
                raise located_error(
                    self.path, int(starts[k]) + 1, "DMIG card without a matrix name"
                )
            self.card_matrix[k] = codes.setdefault(name_k, len(codes))
        self.names = list(codes)
        # a line that is neither a card nor a continuation must not end a DMIG card silently
        foreign = np.flatnonzero(~letter[1:] & (self.card_kind[:-1] != _OTHER)) + 1
        if foreign.size:
            raise located_error(
                self.path,
                int(starts[foreign[0]]) + 1,
                "line is neither a card nor a continuation (continuation lines start with '+', "
                "'*', ',' or a blank) after a DMIG card",
            )
        for k in np.flatnonzero(self.card_kind == _HEADER).tolist():
            self.header_cards.setdefault(self.names[self.card_matrix[k]], []).append(k)

    def _header(self, matrix: str) -> None:
        """Check the header card ``DMIG NAME 0 IFO TIN TOUT POLAR - NCOL`` of a matrix."""
        cards = self.header_cards[matrix]
        first = int(self.card_first[cards[0]])
        if len(cards) > 1:
            raise located_error(
                self.path,
                int(self.card_first[cards[1]]) + 1,
                f"second header card of DMIG matrix {matrix} (the first is on line {first + 1})",
            )
        fields = self._card_fields(cards[0])
        number = first + 1
        ifo = parse_int(fields[2], self.path, number, f"form IFO (field 4) of DMIG {matrix}")
        tin = parse_int(fields[3], self.path, number, f"type TIN (field 5) of DMIG {matrix}")
        if tin in (3, 4):
            raise located_error(
                self.path, number, f"DMIG {matrix} is complex (TIN={tin}); a real matrix is needed"
            )
        if tin not in (1, 2):
            raise located_error(
                self.path, number, f"DMIG {matrix} has type TIN={tin}; expected 1 or 2 (real)"
            )
        if ifo not in (1, 6):
            kind = "rectangular" if ifo in (2, 9) else "of unknown form"
            raise located_error(
                self.path,
                number,
                f"DMIG {matrix} is {kind} (IFO={ifo}); a square symmetric matrix (IFO=6 or 1) "
                "is needed",
            )
        self.headers[matrix] = (ifo, first)

    def _card_fields(self, card: int) -> list[str]:
        """Data fields 2... of a card (slow path, for header cards)."""
        fields: list[str] = []
        first, end = int(self.card_first[card]), int(self.card_end[card])
        for i in range(first, end):
            if self.skip[i]:
                continue
            text = self.lines[i].decode("latin-1")
            large = bool(self.card_large[card]) if i == first else bool(self.large_line[i])
            fields.extend(line_fields(text, large, bool(self.free[i]), self.path, i + 1))
        return fields

    def infos(self) -> dict[str, MatrixInfo]:
        """The DMIG matrices of the file (``square`` from the header's IFO when it reads).

        A file without DMIG cards raises :class:`UserError` saying what it holds instead.
        """
        if not self.names:
            raise located_error(
                self.path, None, f"holds no DMIG matrices: {explain_file(self.path)}"
            )
        out = {}
        for name in self.names:
            square = True
            cards = self.header_cards.get(name)
            if cards:
                field = self._card_fields(cards[0])[2] if cards else ""
                square = field.strip() not in ("2", "9")
            out[name] = MatrixInfo(name, None, square)
        return out

    def check_present(self, wanted: dict[str, str]) -> None:
        """Raise :class:`UserError` if a wanted matrix has no cards or no header."""
        for role, matrix in wanted.items():
            if matrix not in self.names:
                present = ", ".join(self.names) if self.names else "no DMIG cards at all"
                raise located_error(
                    self.path,
                    None,
                    f"no DMIG matrix named {matrix} ({role}); the file holds: {present}",
                )
            if matrix not in self.header_cards:
                code = self.names.index(matrix)
                k = int(np.flatnonzero(self.card_matrix == code)[0])
                raise located_error(
                    self.path,
                    int(self.card_first[k]) + 1,
                    f"DMIG {matrix} has column cards but no header card "
                    f"(DMIG {matrix} 0 IFO TIN ...)",
                )
            self._header(matrix)

    def column_line(self, grid: int) -> int | None:
        """Line index of the first column card of ``grid``, if any."""
        hit = np.flatnonzero((self.card_kind == _COLUMN) & (self.card_gj == grid))
        return int(self.card_first[hit[0]]) if hit.size else None

    # ---------------------------------------------------------------- entries
    def entries(self, matrices: list[str]) -> _Entries:
        """All (row, column, value) entries of the given matrices, in file order."""
        n = len(self.lines)
        codes = [self.names.index(m) for m in matrices]
        want = (self.card_kind == _COLUMN) & np.isin(self.card_matrix, codes)
        gj, cj = self.card_gj, self.card_cj
        bad = np.flatnonzero(want & ((gj <= 0) | (cj < 0) | (cj > 6)))
        if bad.size:
            k = int(bad[0])
            _check_dof(self.path, int(self.card_first[k]) + 1, "column", int(gj[k]), int(cj[k]))
        line_card = self.card_of_line
        inside = line_card >= 0
        mine = np.zeros(n, dtype=bool)
        mine[inside] = want[line_card[inside]]
        mine &= ~self.skip
        fixed = mine & ~self.free
        start_large = np.zeros(n, dtype=bool)
        start_large[inside] = self.card_large[line_card[inside]]

        # fixed format: every group of four fields (G, C, A, B) as 4 x 16 bytes
        groups, line_index, slot = [], [], []
        small_first = np.flatnonzero(fixed & self.start & ~start_large)
        small_next = np.flatnonzero(fixed & ~self.start & ~self.large_line)
        large_next = np.flatnonzero(fixed & ~self.start & self.large_line)
        for rows, cols, k in (
            (small_first, slice(40, 72), 1),
            (small_next, slice(8, 40), 0),
            (small_next, slice(40, 72), 1),
        ):
            block = np.full((rows.size, 4, 16), _SPACE, dtype=np.uint8)
            block[:, :, 8:] = self.u[rows, cols].reshape(rows.size, 4, 8)  # right-aligned
            groups.append(block)
            line_index.append(rows)
            slot.append(np.full(rows.size, k, dtype=np.int64))
        groups.append(self.u[large_next, 8:72].reshape(large_next.size, 4, 16))
        line_index.append(large_next)
        slot.append(np.zeros(large_next.size, dtype=np.int64))
        fields = np.concatenate(groups)
        lines = np.concatenate(line_index).astype(np.int64)
        slots = np.concatenate(slot)
        used = ~(fields == _SPACE).all(axis=(1, 2))
        fields, lines, slots = fields[used], lines[used], slots[used]
        grid, component, value = self._convert(fields, lines)
        digits = significant_digits(fields[:, 2])

        free_lines = np.flatnonzero(mine & self.free)  # free field: slow path
        if free_lines.size:
            extra = self._free_entries(free_lines, start_large)
            lines = np.concatenate([lines, extra[0]])
            slots = np.concatenate([slots, extra[1]])
            grid = np.concatenate([grid, extra[2]])
            component = np.concatenate([component, extra[3]])
            value = np.concatenate([value, extra[4]])
            digits = np.concatenate([digits, extra[5]])

        order = np.argsort(lines * 8 + slots, kind="stable")
        lines, grid, component, value = lines[order], grid[order], component[order], value[order]
        bad = np.flatnonzero((grid <= 0) | (component < 0) | (component > 6))
        if bad.size:
            k = int(bad[0])
            _check_dof(self.path, int(lines[k]) + 1, "row", int(grid[k]), int(component[k]))
        card = line_card[lines]
        lookup = np.full(max(len(self.names), 1), -1, dtype=np.int64)
        lookup[codes] = np.arange(len(codes))
        matrix = lookup[self.card_matrix[card]]
        col_key = self.card_gj[card] * 8 + _direction(self.card_cj[card])
        row_key = grid * 8 + _direction(component)
        return _Entries(matrix, lines, value, grid, row_key, col_key, digits[order])

    def _convert(
        self, fields: np.ndarray, lines: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Grid, component and value of fixed-format entry groups (vectorised)."""
        blank = (fields == _SPACE).all(axis=2)  # (m, 4)
        for column, what in ((0, "row grid"), (2, "value")):
            missing = np.flatnonzero(blank[:, column])
            if missing.size:
                k = int(missing[0])
                shown = " ".join(repr(_text(fields[k, j])) for j in range(3))
                raise located_error(
                    self.path,
                    int(lines[k]) + 1,
                    f"entry without a {what} (fields: {shown}); is the line cut?",
                )
        grid = self._integers(fields[:, 0], lines, "row grid")
        comp_bytes = fields[:, 1].copy()
        comp_bytes[blank[:, 1], 15] = ord("0")  # blank component: scalar point
        component = self._integers(comp_bytes, lines, "row component")
        values = fields[:, 2].copy()
        values[(values == ord("D")) | (values == ord("d"))] = ord("E")
        try:
            value = values.view("S16").ravel().astype(np.float64)
        except ValueError:  # Nastran short exponents (1.5+3) or a bad field
            value = np.array(
                [
                    parse_real(_text(values[k]), self.path, int(lines[k]) + 1, "value")
                    for k in range(values.shape[0])
                ],
                dtype=np.float64,
            )
        return grid, component, value

    def _integers(self, field: np.ndarray, lines: np.ndarray, what: str) -> np.ndarray:
        """Integers of fixed-width byte fields, shape (m, width); a bad one raises at its line."""
        width = field.shape[1] if field.ndim == 2 else 1
        try:
            values = np.ascontiguousarray(field).view(f"S{width}").ravel().astype(np.int64)
        except (ValueError, OverflowError):  # a bad field, or one only Python reads
            values = np.array(
                [
                    parse_int(_text(field[k]), self.path, int(lines[k]) + 1, what)
                    for k in range(field.shape[0])
                ],
                dtype=np.int64,
            )
        outside = np.flatnonzero(np.abs(values) > MAX_ID)
        if outside.size:
            k = int(outside[0])
            parse_int(_text(field[k]), self.path, int(lines[k]) + 1, what)
        return values

    def _free_entries(self, free_lines: np.ndarray, start_large: np.ndarray) -> tuple:
        """Entries of free-field lines: (lines, slots, grids, components, values)."""
        out: list[list] = [[], [], [], [], [], []]
        for i in free_lines.tolist():
            text = self.lines[i].decode("latin-1")
            number = i + 1
            if self.start[i]:
                fields = line_fields(text, bool(start_large[i]), True, self.path, number)[4:]
            else:
                fields = line_fields(text, bool(self.large_line[i]), True, self.path, number)
            for slot in range(len(fields) // 4):
                g, c, a, _ = fields[4 * slot : 4 * slot + 4]
                if not (g or c or a):
                    continue
                if not g or not a:
                    what = "row grid" if not g else "value"
                    raise located_error(
                        self.path, number, f"entry without a {what}; is the line cut?"
                    )
                out[0].append(i)
                out[1].append(slot + (1 if self.start[i] else 0))
                out[2].append(parse_int(g, self.path, number, "row grid"))
                out[3].append(parse_int(c or "0", self.path, number, "row component"))
                out[4].append(parse_real(a, self.path, number, "value"))
                out[5].append(a.encode("latin-1")[:24])
        return (
            np.array(out[0], dtype=np.int64),
            np.array(out[1], dtype=np.int64),
            np.array(out[2], dtype=np.int64),
            np.array(out[3], dtype=np.int64),
            np.array(out[4], dtype=np.float64),
            significant_digits(
                np.array(out[5], dtype="S24").view(np.uint8).reshape(-1, 24)
                if out[5]
                else np.zeros((0, 24), dtype=np.uint8)
            ),
        )


# ============================================================================ fields and numbers
def _text(field: np.ndarray) -> str:
    return bytes(field).decode("latin-1").strip()


def _check_dof(path: Path, line: int, what: str, grid: int, component: int) -> None:
    if grid <= 0:
        raise located_error(path, line, f"{what} grid {grid} is not a valid grid id")
    if not 0 <= component <= 6:
        raise located_error(path, line, f"{what} component {component} of grid {grid} is not 0-6")


def _direction(component: np.ndarray) -> np.ndarray:
    """Direction codes of DMIG components: 1..6 -> 0..5, 0 (scalar point) -> ``SCALAR``."""
    component = np.asarray(component, dtype=np.int64)
    return np.where(component == 0, SCALAR, component - 1)


# ============================================================================ streamed fast path
class _SlowPath(Exception):
    """The streamed reader meets something only the strict pass reads (or rejects) exactly."""


#: Lines padded to 72 columns at a time where a block's lines differ in length.
_PAD_LINES = 1 << 16
#: Bytes that may occur only in comment lines for the streamed reader: NUL, tab, comma (free
#: field) and every non-ASCII byte; a file with them elsewhere goes to the strict pass.
_SPECIAL = bytes([0, 9, ord(",")]) + bytes(range(128, 256))
_PLAIN = bytes(b for b in range(256) if b not in _SPECIAL)
_TO_E = np.arange(256, dtype=np.uint8)
_TO_E[[ord("D"), ord("d")]] = ord("E")
_COLUMNS = np.arange(_WIDTH)


def _read_streamed(
    path: Path,
    stiffness: str | None,
    mass: str | None,
    damping: str | None,
    nodes: PathLike | None,
    name: str | None,
) -> ElasticBody | None:
    """:func:`read_dmig` in two streamed passes over the file, for the large-field layout
    Nastran punches (``DMIG*`` column cards, one ``*`` line per entry).

    The first pass keeps only the card lines (headers, column cards, GRID ...), which are
    checked by :class:`_Punch` like a whole file; the second converts the entry lines of the
    chosen matrices block by block. Anything else -- small-field or free-field entries, tabs,
    lone carriage returns, a bad field, duplicate entries, a matrix not stored as one triangle
    column by column -- raises :class:`_SlowPath` (or a :class:`UserError`), and the caller
    runs the strict pass, which reads it or names the bad line.
    """
    cards, card_line, others = _scan_cards(path)
    mini = _Punch(path, cards)
    choice = choose_matrices(
        mini.infos(), path, "DMIG matrix", stiffness=stiffness, mass=mass, damping=damping
    )
    wanted = _wanted(choice)
    mini.check_present(wanted)
    names = list(dict.fromkeys(wanted.values()))
    codes = [mini.names.index(m) for m in names]
    want = (mini.card_kind == _COLUMN) & np.isin(mini.card_matrix, codes)
    gj, cj = mini.card_gj, mini.card_cj
    if np.any(want & ((gj <= 0) | (cj < 0) | (cj > 6) | ~mini.card_large)):
        raise _SlowPath  # a bad column, or small-field cards (entries on their first line)
    if others.size:  # small-field continuation lines of a chosen matrix
        owner = np.searchsorted(card_line, others, side="right") - 1
        if np.any(want[owner[owner >= 0]]):
            raise _SlowPath
    pieces, digit_counts = _scan_entries(path, card_line, want, mini.card_matrix, codes)
    ifo = {matrix: mini.headers[matrix][0] for matrix in names}
    has_grid = mini.has_grid
    del mini, cards, card_line
    col_key_of_card = gj * 8 + _direction(cj)
    stored = []
    for piece in pieces:
        row_key, card, value = (_join(part, kind) for part, kind in zip(piece, _KINDS, strict=True))
        stored.append((row_key, col_key_of_card[card], value))
        del card
    all_keys = _unique_keys([k for entries in stored for k in entries[:2]])
    if all_keys.size == 0:
        raise _SlowPath
    table = DofTable(all_keys // 8, all_keys % 8)
    n = len(table)
    index = np.int32 if n < 2**31 - 1 else np.int64
    by_name: dict[str, tuple[np.ndarray, np.ndarray, np.ndarray]] = {}
    for matrix, (row_key, col_key, value) in zip(names, stored, strict=True):
        rows = np.searchsorted(all_keys, row_key).astype(index)
        del row_key
        cols = np.searchsorted(all_keys, col_key).astype(index)
        del col_key
        by_name[matrix] = (rows, cols, value)
    del stored
    matrices = {}
    uses = [list(wanted.values()).count(m) for m in names]
    for role, matrix in wanted.items():
        entries = list(by_name[matrix])
        uses[names.index(matrix)] -= 1
        if uses[names.index(matrix)] == 0:
            del by_name[matrix]  # the only reference left is ``entries``
        matrices[role] = _assemble_one_triangle(entries, n, ifo[matrix])
        if matrices[role] is None:
            matrices[role] = assemble_symmetric(
                *entries,
                n,
                path=path,
                line_of=_no_line,
                label=table.label,
                storage=_storage(ifo[matrix]),
            )
    del by_name
    return _finish(
        path,
        choice.notes,
        names,
        table,
        matrices,
        digit_counts,
        (nodes, has_grid, name),
        _no_line,
    )


_KINDS = (np.int64, np.int32, np.float64)


def _unique_keys(keys: list[np.ndarray]) -> np.ndarray:
    """The distinct values of non-negative integer arrays, ascending (marks in a boolean
    array where the largest key is small enough, else by sorting)."""
    top = max((int(k.max()) for k in keys if k.size), default=-1)
    if top < 0:
        return np.zeros(0, dtype=np.int64)
    if top < 1 << 28:
        seen = np.zeros(top + 1, dtype=bool)
        for k in keys:
            seen[k] = True
        return np.flatnonzero(seen)
    return sorted_unique(np.concatenate(keys))


def _join(parts: list[np.ndarray], kind) -> np.ndarray:
    """The concatenation of ``parts``, which is emptied (so that each part is freed)."""
    out = np.concatenate(parts) if parts else np.zeros(0, dtype=kind)
    parts.clear()
    return out


def _no_line(_: int) -> int:
    """The streamed reader keeps no line numbers: a message needing one comes from the strict
    pass."""
    raise _SlowPath


def _blocks(path: Path):
    """:func:`~pymorembs.io.line_blocks.iter_line_blocks` of the punch; :class:`_SlowPath`
    for an irregular file or special bytes (tab, comma, NUL, non-ASCII) outside comments."""
    try:
        for arr, ends, line0 in iter_line_blocks(path):
            if arr.tobytes().translate(None, _PLAIN):  # special bytes: only in comment lines
                special = np.flatnonzero(np.isin(arr, np.frombuffer(_SPECIAL, np.uint8)))
                if np.any(arr[special] == 0):
                    raise _SlowPath
                line = np.searchsorted(ends, special)
                if np.any(arr[line_starts(ends)[line]] != _DOLLAR):
                    raise _SlowPath
            yield arr, ends, line0
    except IrregularText:
        raise _SlowPath from None


def _line_matrix(arr: np.ndarray, ends: np.ndarray) -> np.ndarray:
    """The lines of a block as rows of at least 56 (at most 72) columns, blank-padded: a view
    when every line has the same length of 56 or more, else a copy of 72 columns (runs of lines
    of the common length copied as blocks, the other lines padded one by one)."""
    m = ends.size
    starts = line_starts(ends)
    lengths = ends - starts
    common = int(np.median(lengths)) if m else 0
    odd = np.flatnonzero(lengths != common)
    if common >= 56 and odd.size == 0:
        return arr[: m * (common + 1)].reshape(m, common + 1)[:, : min(common, _WIDTH)]
    out = np.full((m, _WIDTH), _SPACE, dtype=np.uint8)
    if common >= 56 and odd.size <= m // 100:
        width = min(common, _WIDTH)
        edges = [-1, *odd.tolist(), m]
        for before, after in itertools.pairwise(edges):
            first, count = before + 1, after - before - 1
            if count:
                at = int(starts[first])
                run = arr[at : at + count * (common + 1)].reshape(count, common + 1)
                out[first:after, :width] = run[:, :width]
        rows = odd
    else:
        rows = np.arange(m)
    last = arr.size - 1
    for a in range(0, rows.size, _PAD_LINES):
        chosen = rows[a : a + _PAD_LINES]
        inside = _COLUMNS[None, :] < lengths[chosen, None]
        taken = arr[np.minimum(starts[chosen, None] + _COLUMNS[None, :], last)]
        out[chosen] = np.where(inside, taken, _SPACE)
    return out


def _widen(rows: np.ndarray) -> np.ndarray:
    """Rows of a line matrix padded to 72 columns."""
    if rows.shape[1] == _WIDTH:
        return np.ascontiguousarray(rows)
    out = np.full((rows.shape[0], _WIDTH), _SPACE, dtype=np.uint8)
    out[:, : rows.shape[1]] = rows
    return out


def _classify(u: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(entry lines ``*``, other continuation lines ``+``/blank-led, card lines) of a block,
    as in :class:`_Punch` (comments ``$`` and blank lines are none of them)."""
    first = u[:, 0]
    led = np.flatnonzero(first == _SPACE)
    blank_led = np.zeros(first.size, dtype=bool)
    if led.size:
        blank_led[led[~(u[led] == _SPACE).all(axis=1)]] = True
    entry = first == _STAR
    other = (first == _PLUS) | blank_led
    card = ~entry & ~other & (first != _DOLLAR) & (first != _SPACE)
    return entry, other, card


def _scan_cards(path: Path) -> tuple[bytes, np.ndarray, np.ndarray]:
    """First pass: the card lines (72 columns each, as the text of a file), their line indices,
    and the indices of ``+``/blank-led continuation lines."""
    cards, card_lines, others = [], [], []
    for arr, ends, line0 in _blocks(path):
        u = _line_matrix(arr, ends)
        _, other, card = _classify(u)
        rows = np.flatnonzero(card)
        cards.append(_widen(u[rows]))
        card_lines.append(line0 + rows)
        others.append(line0 + np.flatnonzero(other))
    if not cards:
        raise _SlowPath
    text = np.concatenate(cards)
    text = np.hstack([text, np.full((text.shape[0], 1), 10, dtype=np.uint8)]).tobytes()
    return text, np.concatenate(card_lines), np.concatenate(others)


def _scan_entries(
    path: Path, card_line: np.ndarray, want: np.ndarray, card_matrix: np.ndarray, codes: list
) -> tuple[list, np.ndarray]:
    """Second pass: per chosen matrix, lists of (row keys, card indices, values) in file order,
    and the histogram of the values' significant digits."""
    pieces: list[list[list[np.ndarray]]] = [[[], [], []] for _ in codes]
    counts = np.zeros(_DIGIT_BINS, dtype=np.int64)
    slot = np.full(max(int(card_matrix.max(initial=-1)) + 1, 1), -1, dtype=np.int64)
    slot[codes] = np.arange(len(codes))
    for arr, ends, line0 in _blocks(path):
        u = _line_matrix(arr, ends)
        entry = np.flatnonzero(u[:, 0] == _STAR)
        card = np.searchsorted(card_line, line0 + entry, side="right") - 1
        mine = card >= 0
        mine[mine] = want[card[mine]]
        entry, card = entry[mine], card[mine]
        if entry.size == 0:
            continue
        fields = u[entry]
        del u
        grid, component, value, digits = _convert_entries(fields)
        counts += digits
        row_key = grid * 8 + _direction(component)
        which = slot[card_matrix[card]]
        for k in range(len(codes)):
            take = which == k
            if not take.any():
                continue
            all_taken = bool(take.all())
            pieces[k][0].append(row_key if all_taken else row_key[take])
            pieces[k][1].append((card if all_taken else card[take]).astype(np.int32))
            pieces[k][2].append(value if all_taken else value[take])
    return pieces, counts


def _convert_entries(
    lines: np.ndarray,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Grid, component, value and the digit histogram of ``*`` entry lines (rows of 56 to 72
    columns: G 9-24, C 25-40, A 41-56, B 57-72); :class:`_SlowPath` for anything the strict
    pass reads otherwise. (A blank grid or value, e.g. a blank entry line, which the strict pass
    skips or names, fails the conversion; field B is not read there either.)"""
    g, a = lines[:, 8:24], _TO_E[lines[:, 40:56]]
    component = _components(lines[:, 24:40])
    try:
        grid = np.ascontiguousarray(g).view("S16").ravel().astype(np.int64)
        value = a.view("S16").ravel().astype(np.float64)
    except (ValueError, OverflowError):
        raise _SlowPath from None
    if np.any((grid <= 0) | (grid > MAX_ID)) or not np.isfinite(value).all():
        raise _SlowPath
    return grid, component, value, _digit_histogram(a)


def _components(c: np.ndarray) -> np.ndarray:
    """Components 0-6 of 16-byte fields; blank is 0 (a scalar point). Right-aligned single
    digits are read directly, anything else by ``astype`` like the strict pass."""
    last = c[:, 15].astype(np.int64) - ord("0")
    blank = last == _SPACE - ord("0")
    if (c[:, :15] == _SPACE).all() and np.all(blank | ((last >= 0) & (last <= 6))):
        return np.where(blank, 0, last)
    c = np.ascontiguousarray(c)
    c[(c == _SPACE).all(axis=1), 15] = ord("0")
    try:
        component = c.view("S16").ravel().astype(np.int64)
    except (ValueError, OverflowError):
        raise _SlowPath from None
    if np.any((component < 0) | (component > 6)):
        raise _SlowPath
    return component


_DIGIT_BINS = 17


def _digit_tables() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Lookup tables over 16-bit column masks (bit 15 = first column): the columns before the
    first set bit, the columns from the first set bit on, and the number of set bits."""
    masks = np.arange(1 << 16, dtype=np.int64)
    top = np.where(masks > 0, np.floor(np.log2(np.maximum(masks, 1))).astype(np.int64), -1)
    # bit b set at top: columns before it are the bits above b
    before = np.where(masks > 0, (0xFFFF << (top + 1)) & 0xFFFF, 0xFFFF)
    from_first = np.where(masks > 0, (1 << (top + 1)) - 1, 0)
    popcount = np.zeros(1 << 16, dtype=np.int64)
    for b in range(16):
        popcount += (masks >> b) & 1
    return before.astype(np.uint16), from_first.astype(np.uint16), popcount.astype(np.uint8)


_TABLES: list[tuple[np.ndarray, np.ndarray, np.ndarray]] = []


def _digit_histogram(a: np.ndarray) -> np.ndarray:
    """Histogram of :func:`~pymorembs.io.nastran_bulk.significant_digits` of 16-byte number
    fields whose exponents use ``E``: the digits of the mantissa from the first non-zero one.

    Nastran punches every value as ``-d.dddddddddE+dd``: with the point and the ``E`` in the
    same columns of every field and one digit before the point, a field has ``E - point``
    digits unless that digit is 0; only the other fields are counted digit by digit (by column
    bit masks and lookup tables).
    """
    counts = np.zeros(_DIGIT_BINS, dtype=np.int64)
    if a.shape[0] == 0:
        return counts
    point, exponent = int(np.argmax(a[0] == ord("."))), int(np.argmax(a[0] == _E))
    if 2 <= point < exponent and (
        np.all(a[:, point] == ord("."))
        and np.all(a[:, exponent] == _E)
        and not np.any((a[:, point - 2] - np.uint8(48)) < 10)  # one digit before the point
    ):
        lead = a[:, point - 1] != ord("0")  # a digit (the conversion succeeded)
        counts[exponent - point] = np.count_nonzero(lead)
        rest = a[~lead]
        if rest.shape[0] == 0:
            return counts
        return counts + _digit_histogram_by_masks(rest)
    return _digit_histogram_by_masks(a)


def _digit_histogram_by_masks(a: np.ndarray) -> np.ndarray:
    """:func:`_digit_histogram` for any layout, by column bit masks and lookup tables."""
    if not _TABLES:
        _TABLES.append(_digit_tables())
    before, from_first, popcount = _TABLES[0]
    digit = (a - np.uint8(48)) < 10
    nonzero = digit & (a != ord("0"))

    def mask(bits: np.ndarray) -> np.ndarray:
        return np.packbits(bits, axis=1).view(">u2").ravel()

    mantissa = before[mask((a | 0x20) == ord("e"))]
    counted = mask(digit) & mantissa & from_first[mask(nonzero) & mantissa]
    return np.bincount(popcount[counted], minlength=_DIGIT_BINS)


def _assemble_one_triangle(entries: list[np.ndarray], n: int, ifo: int) -> sp.csr_matrix | None:
    """The full symmetric matrix of a form-6 DMIG whose entries ``[rows, cols, values]`` give
    every position of one triangle once; None for anything else (the general
    :func:`~pymorembs.io.reader_support.assemble_symmetric` then, with ``entries`` untouched).
    ``entries`` is emptied when the matrix is built, to free its memory early.

    Nastran punches the upper triangle column by column: that is built directly. Entries of
    either triangle in another order are sorted into the lower triangle by SciPy's counting
    sort (COO to CSR) first.
    """
    rows, cols, values = entries
    if ifo != 6 or rows.size == 0:
        return None
    if not np.any(rows > cols) and _column_major(rows, cols):  # Nastran's layout
        entries.clear()
        return _full_from_upper(rows, cols, values, n)
    high, low = np.maximum(rows, cols), np.minimum(rows, cols)
    lower = sp.coo_matrix((values, (high, low)), shape=(n, n)).tocsr()  # sums repeats
    del high, low
    if lower.nnz != rows.size:  # a position given twice (or in both triangles)
        return None
    entries.clear()
    del rows, cols, values
    high = np.repeat(np.arange(n, dtype=lower.indices.dtype), np.diff(lower.indptr))
    low, data = lower.indices, lower.data
    del lower
    return _full_from_upper(low, high, data, n)


#: Entries handled at a time when the full matrix is built from its upper triangle.
_ENTRY_CHUNK = 1 << 20


def _column_major(rows: np.ndarray, cols: np.ndarray) -> bool:
    """Whether the entries are in strictly increasing (column, row) order."""
    for a in range(0, rows.size - 1, _ENTRY_CHUNK):
        r, c = rows[a : a + _ENTRY_CHUNK + 1], cols[a : a + _ENTRY_CHUNK + 1]
        if not np.all((c[1:] > c[:-1]) | ((c[1:] == c[:-1]) & (r[1:] > r[:-1]))):
            return False
    return True


def _full_from_upper(
    rows: np.ndarray, cols: np.ndarray, values: np.ndarray, n: int
) -> sp.csr_matrix:
    """The full symmetric CSR matrix of upper-triangle entries given column by column with
    increasing rows, written straight into its arrays (no triangle matrices, no sums): column
    ``j`` of the file is the part of row ``j`` up to the diagonal, and the entries above the
    diagonal go, in file order, to the rows they name (a counting sort, chunk by chunk)."""
    if not values.all():  # explicit zeros are dropped, as assemble_symmetric drops them
        keep = values != 0
        rows, cols, values = rows[keep], cols[keep], values[keep]
        del keep
    strict = rows != cols
    lower_count = np.bincount(cols, minlength=n)
    upper_count = np.bincount(rows[strict], minlength=n)
    indptr = np.zeros(n + 1, dtype=np.int64)
    np.cumsum(lower_count + upper_count, out=indptr[1:])
    index = np.int32 if indptr[-1] < 2**31 - 1 else np.int64
    indices = np.empty(int(indptr[-1]), dtype=index)
    data = np.empty(int(indptr[-1]))
    first_of_column = np.zeros(n, dtype=np.int64)
    np.cumsum(lower_count[:-1], out=first_of_column[1:])
    fill = indptr[:-1] + lower_count  # next free place of the part above the diagonal
    for a in range(0, rows.size, _ENTRY_CHUNK):
        part = slice(a, a + _ENTRY_CHUNK)
        r, c, v = rows[part], cols[part], values[part]
        at = indptr[c] + (np.arange(a, a + r.size) - first_of_column[c])
        indices[at] = r
        data[at] = v
        above = strict[part]
        r, c, v = r[above], c[above], v[above]
        if r.size == 0:
            continue
        order = np.argsort(r, kind="stable")
        r = r[order]
        start = np.flatnonzero(np.concatenate([[True], r[1:] != r[:-1]]))
        size = np.diff(np.append(start, r.size))
        rank = np.arange(r.size) - np.repeat(start, size)
        at = fill[r] + rank
        indices[at] = c[order]
        data[at] = v[order]
        fill[r[start]] += size
    full = sp.csr_matrix((data, indices, indptr.astype(index)), shape=(n, n), copy=False)
    full.has_sorted_indices = True
    return full
