"""Nastran bulk data: grid points, coordinate systems, scalar points and the analysis set.

One reader (:func:`read_bulk`) for every Nastran reader of pymorembs: the coordinates of the grids
of a DMIG punch or an OP4 file, the displacement coordinate systems (``CD``) in which their
matrices are written, and the dof table (row order) of the matrices of an external superelement.

Files read
    * an input deck (``.bdf``, ``.dat``; executive and case control up to ``BEGIN BULK`` are
      skipped when the deck has a ``CEND``), an include file, or any file of bulk data cards;
    * the EXTBULK punch (``.pch``) that ``EXTSEOUT(ASMBULK,EXTBULK,EXTID=n,...)`` writes:
      ``BEGIN SUPER n``, ``CORD2R``, ``EXTRN``, boundary ``GRID`` cards, ``ASET``, ``QSET1``,
      ``SPOINT`` and ``DTI`` tables;
    * the ASMBULK file (``.asm``): ``SEBULK``, ``SECONCT``, ``GRID``, ``SPOINT``;
    * an ``.f06`` listing with the bulk data echo (case control ``ECHO=SORT`` -- the default --
      or ``ECHO=UNSORT``): the cards are taken from the lines of the ``S O R T E D   B U L K
      D A T A   E C H O`` (``<count>-        <card>``) or, without a sorted echo, from the
      ``I N P U T   B U L K   D A T A   E C H O``. The sorted echo holds the included files too.

Card format
    Small field (8 columns), large field (name ending in ``*``, 16 columns, continuation lines
    starting with ``*``), free field (commas; a large-field name ``GRID*,`` takes 4 fields per
    line); columns 73-80 (continuation labels) are ignored; continuation lines start with ``+``,
    ``*``, ``,`` or a blank; tabs are expanded to columns of 8; ``$`` starts a comment.
    ``INCLUDE 'file'`` (the quoted name may go over several lines) is read relative to the
    including file. ``BEGIN SUPER n`` / ``BEGIN SUPER=n`` starts the cards of superelement
    ``n`` and ``BEGIN BULK`` those of the main bulk data; identical cards may appear in several
    sections (the EXTBULK punch repeats ``GRID`` and ``CORD2R`` for the assembly run), a card
    that defines the same grid or coordinate system differently is an error. Reals may use
    ``E`` or ``D`` exponents or Nastran's short form (``1.5+3``, ``-.5-2``); a blank real is 0.

Cards read
    ``GRID ID CP X1 X2 X3 CD PS SEID`` (with ``GRDSET`` defaults for blank CP, CD, PS);
    ``CORD2R/CORD2C/CORD2S CID RID A B C`` (points in the reference system ``RID``, chains of
    any length) and ``CORD1R/CORD1C/CORD1S CID G1 G2 G3`` (two systems per card); ``SPOINT``
    and ``EPOINT`` (with ``THRU``); the sets ``ASET``, ``BSET``, ``CSET``, ``QSET``, ``OMIT``
    (pairs ``ID C``), their list forms ``ASET1`` ... (``C ID ID ...`` or ``C ID1 THRU ID2``) and
    the NX names ``BNDFIX``/``BNDFRE``; ``EXTRN`` (pairs ``ID C``, ``C = 0`` for scalar points);
    ``SECONCT``, ``SEBULK``; ``SEQGP`` and ``PARAM,OLDSEQ`` (resequencing); ``SUPORT``.
    ``CTETRA``, ``CHEXA``, ``PSOLID``, ``MAT1``: the solid elements and their isotropic
    material (:func:`bulk_solid_blocks`, for geometric stiffening); ``CPENTA``, ``CPYRAM``, the
    shells ``CTRIA3/6``, ``CTRIAR``, ``CQUAD4/8``, ``CQUADR``, ``CSHEAR`` and the line elements
    ``CBAR``, ``CBEAM``, ``CROD``, ``CONROD``, ``CTUBE`` (with the solids: the body's surface,
    :func:`bulk_surface_elements`). Every other card is counted (for messages and the surface's
    note) and skipped without being parsed.

Coordinates
    A grid's ``X1 X2 X3`` are in its system ``CP``: rectangular ``(x, y, z)``, cylindrical
    ``(r, theta, z)``, spherical ``(r, theta, phi)`` with angles in degrees, theta of the
    spherical system measured from its z axis and phi about it; they are converted to the basic
    system. The displacement components of a grid are along the axes of its system ``CD``
    at the grid: ``(u_x, u_y, u_z)``, ``(u_r, u_theta, u_z)`` or ``(u_r, u_theta, u_phi)``; on
    the z axis of a cylindrical system and on the polar axis of a spherical one, where these
    directions are undefined, the system's own rectangular axes are used (as Nastran does).

The GRID cards of fixed-format files are converted with numpy in one pass (a million grids take
about a second); other cards are few and parsed one by one. Every problem raises
:class:`~pymorembs.errors.UserError` with one line ``file:line: problem``.
"""

from __future__ import annotations

import os
import re
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from pymorembs.errors import located_error
from pymorembs.io.compressed import original_path
from pymorembs.io.element_surface import SurfaceElements
from pymorembs.io.line_blocks import UTF8_BOM
from pymorembs.io.matrix_market import encoding_note
from pymorembs.io.solid_mesh import SolidBlock

__all__ = [
    "CHEXA20_TO_HEX20",
    "AnalysisSet",
    "BulkData",
    "Card",
    "CoordinateSystem",
    "bulk_solid_blocks",
    "bulk_surface_elements",
    "line_fields",
    "parse_int",
    "parse_real",
    "read_bulk",
    "read_card_file",
    "reals_of_fields",
    "significant_digits",
]

PathLike = str | os.PathLike[str]

#: Largest Nastran id or integer field (32-bit).
MAX_ID = 2**31 - 1
#: Largest THRU range expanded (ids), to keep a damaged card from allocating gigabytes.
MAX_RANGE = 10_000_000
_EAGER_RANGE = 1_000_000  # THRU ranges beyond the matrix size but below this are expanded

_WIDTH = 72  # columns 1-72 hold field 1 and the eight data fields; 73-80 are ignored
_SPACE, _STAR, _PLUS, _COMMA = (ord(c) for c in " *+,")
_SHORT_EXPONENT = re.compile(r"^([+-]?(?:\d+\.?\d*|\.\d+))([+-]\d+)$")
_SORTED_ECHO = re.compile(rb"S O R T E D   B U L K   D A T A   E C H O")
_INPUT_ECHO = re.compile(rb"I N P U T   B U L K   D A T A   E C H O")
_ECHO_SUPER = re.compile(rb"SUPER\s*=\s*(\d+)")
_ECHO_LINE = re.compile(rb"^ {0,30}\d+- {8}(.*)$")
_RESULTS = re.compile(rb"(?m)^\$(TITLE|SUBTITLE|LABEL|EIGENVECTOR|DISPLACEMENTS|EIGENVALUE)\b")
_BEGIN = re.compile(r"^\s*BEGIN\s*(BULK|SUPER)?\s*(?:=\s*)?(\d+)?", re.IGNORECASE)

#: Set cards in pair form (``ID C ID C ...``) and list form (``C ID ID ...``), by the set.
PAIR_SETS = {
    "ASET": "a",
    "BSET": "b",
    "CSET": "c",
    "QSET": "q",
    "OMIT": "o",
    "BNDFIX": "b",
    "BNDFRE": "c",
    "EXTRN": "x",
}
LIST_SETS = {
    "ASET1": "a",
    "BSET1": "b",
    "CSET1": "c",
    "QSET1": "q",
    "OMIT1": "o",
    "BNDFIX1": "b",
    "BNDFRE1": "c",
}
_SYSTEMS = {"CORD1R", "CORD1C", "CORD1S", "CORD2R", "CORD2C", "CORD2S"}
#: Element cards whose grids lie in the first line (field from 0 = EID, number of grids): in
#: small field on one line they are converted at once (:attr:`BulkData.element_grids`).
_FAST_ELEMENTS = {
    "CTRIA3": (2, 3), "CTRIAR": (2, 3), "CQUAD4": (2, 4), "CQUADR": (2, 4), "CSHEAR": (2, 4),
    "CBAR": (2, 2), "CBEAM": (2, 2), "CROD": (2, 2), "CTUBE": (2, 2), "CONROD": (1, 2),
}  # fmt: skip
_WANTED = {
    "GRID",
    "GRDSET",
    "SPOINT",
    "EPOINT",
    "SEQGP",
    "PARAM",
    "SUPORT",
    "SUPORT1",
    "SEBULK",
    "SECONCT",
    "CTETRA",
    "CHEXA",
    "PSOLID",
    *("CPENTA", "CPYRAM", "CTRIA3", "CTRIA6", "CTRIAR", "CQUAD4", "CQUAD8", "CQUADR"),
    *("CSHEAR", "CBAR", "CBEAM", "CROD", "CONROD", "CTUBE"),  # the surface's elements
    "MAT1",
    *_SYSTEMS,
    *PAIR_SETS,
    *LIST_SETS,
}


# ============================================================================ fields and numbers
def parse_int(text: str, path: Path, line: int | None, what: str) -> int:
    """A Nastran integer field (within +-(2**31 - 1)); :class:`UserError` naming ``what``."""
    text = text.strip()
    try:
        if "_" in text or not text.isascii():
            raise ValueError
        value = int(text)
    except ValueError:
        problem = "is missing" if not text else f"{text!r} is not an integer"
        raise located_error(path, line, f"{what} {problem}") from None
    if abs(value) > MAX_ID:
        raise located_error(
            path, line, f"{what} {text!r} is out of range (Nastran ids are below 2**31)"
        )
    return value


def parse_real(text: str, path: Path, line: int | None, what: str, blank: float | None = None):
    """A Nastran real: ``1.5E+3``, ``1.5D+3``, ``1.5+3``, ``-.5``, ``3.``; finite.

    ``blank`` is the value of an empty field (``None``: an empty field is an error).
    """
    shown = text.strip()
    text = shown.upper().replace("D", "E")
    if not text and blank is not None:
        return blank
    value = None
    if "_" not in text and text.isascii():
        try:
            value = float(text)
        except ValueError:
            match = _SHORT_EXPONENT.match(text)
            if match:
                value = float(f"{match.group(1)}E{match.group(2)}")
    if value is None:
        problem = "is missing" if not text else f"{shown!r} is not a number"
        raise located_error(path, line, f"{what} {problem}")
    if not np.isfinite(value):
        raise located_error(path, line, f"{what} {shown!r} is not a finite number")
    return value


def line_fields(text: str, large: bool, free: bool, path: Path, line: int) -> list[str]:
    """The data fields (8 small, 4 large) of one line, stripped; missing ones are ``""``.

    A free-field line may hold one more field, the continuation marker (blank or ``+...``);
    more fields would be lost, so they are an error.
    """
    count = 4 if large else 8
    if free:
        parts = [p.strip() for p in text.split(",")][1:]
        fields = parts[:count]
        extra = parts[count:]
        if len(extra) > 1 or (extra and extra[0] and extra[0][0] not in "+*"):
            raise located_error(
                path,
                line,
                f"free-field line with more than {count} data fields; continue the card on the "
                "next line",
            )
    else:
        width = 16 if large else 8
        fields = [text[8 + k * width : 8 + (k + 1) * width].strip() for k in range(count)]
    return fields + [""] * (count - len(fields))


def read_card_file(path: Path, kind: str) -> bytes:
    """The bytes of a Nastran text file (byte order mark removed); one-line errors.

    ``kind`` says what the file should be, e.g. ``"a Nastran punch file"``; a missing file, a
    directory, an unreadable or a binary file (UTF-16 named as such) is a :class:`UserError`.
    """
    try:
        raw = path.read_bytes()
    except FileNotFoundError:
        raise located_error(path, None, f"file not found (expected {kind})") from None
    except IsADirectoryError:
        raise located_error(path, None, f"is a directory, expected {kind}") from None
    except OSError as err:
        raise located_error(path, None, f"cannot read: {err.strerror or err}") from None
    raw = raw.removeprefix(UTF8_BOM)
    if b"\x00" in raw:
        raise located_error(path, None, f"a binary file, expected {kind}{encoding_note(raw[:512])}")
    return raw


def _insert_short_exponent(block: np.ndarray) -> np.ndarray:
    """Fixed-width byte fields (m, w) with Nastran's short exponent ``1.5+3`` as ``1.5E+3``.

    A sign that follows a digit or a decimal point starts the exponent; an ``E`` is put in front
    of it (the field grows by one byte).
    """
    m, w = block.shape
    sign = (block == ord("+")) | (block == ord("-"))
    before = np.zeros_like(sign)
    prev = block[:, :-1]
    before[:, 1:] = ((prev >= ord("0")) & (prev <= ord("9"))) | (prev == ord("."))
    start = sign & before
    has = start.any(axis=1)
    at = np.where(has, np.argmax(start, axis=1), w + 1)
    out = np.full((m, w + 1), _SPACE, dtype=np.uint8)
    column = np.arange(w + 1)
    source = np.where(column[None, :] <= at[:, None], column[None, :], column[None, :] - 1)
    source = np.minimum(source, w - 1)
    out[:] = np.take_along_axis(block, source, axis=1)
    out[column[None, :] == at[:, None]] = ord("E")
    out[:, w][~has] = _SPACE
    return out


def reals_of_fields(
    block: np.ndarray, lines: np.ndarray, path: Path, what: str, blank: float | None = 0.0
) -> np.ndarray:
    """Reals of fixed-width byte fields, shape (m, w), vectorised; a bad one raises at its line.

    ``lines`` (m,) are the line numbers (from 1) for the message. ``E``, ``D`` and short
    exponents are read; a blank field is ``blank`` (``None``: an error); NaN and infinity are
    errors.
    """
    block = np.ascontiguousarray(block, dtype=np.uint8)
    m, w = block.shape
    if m == 0:
        return np.zeros(0)
    empty = (block == _SPACE).all(axis=1)
    work = block.copy()
    work[(work == ord("D")) | (work == ord("d"))] = ord("E")
    if empty.any():
        if blank is None:
            k = int(np.flatnonzero(empty)[0])
            raise located_error(path, int(lines[k]), f"{what} is missing")
        work[empty, w - 1] = ord("0")
    values = None
    try:
        values = work.view(f"S{w}").ravel().astype(np.float64)
    except ValueError:
        try:
            values = _insert_short_exponent(work).view(f"S{w + 1}").ravel().astype(np.float64)
        except ValueError:
            values = None
    if values is None or not np.isfinite(values).all():  # Python's parse, and its message
        values = np.array(
            [
                parse_real(bytes(block[k]).decode("latin-1"), path, int(lines[k]), what, blank)
                for k in range(m)
            ]
        )
    if empty.any():
        values[empty] = blank
    return values


def significant_digits(block: np.ndarray) -> np.ndarray:
    """Significant digits of the numbers in fixed-width byte fields (m, w); 0 for a zero.

    The digits of the mantissa from the first non-zero one (trailing zeros count: a writer
    that prints ``1.556000000D+02`` gives 10 digits), before the exponent (``E``, ``D`` or the
    sign of a short exponent).
    """
    block = np.asarray(block, dtype=np.uint8)
    m, w = block.shape
    if m == 0:
        return np.zeros(0, dtype=np.int64)
    upper = block & 0xDF
    letter = (upper == ord("E")) | (upper == ord("D"))
    sign = (block == ord("+")) | (block == ord("-"))
    digit = (block >= ord("0")) & (block <= ord("9"))
    before = np.zeros_like(sign)
    before[:, 1:] = digit[:, :-1] | (block[:, :-1] == ord("."))
    exponent = letter | (sign & before)
    end = np.where(exponent.any(axis=1), np.argmax(exponent, axis=1), w)
    column = np.arange(w)[None, :]
    mantissa = digit & (column < end[:, None])
    nonzero = mantissa & (block != ord("0"))
    start = np.where(nonzero.any(axis=1), np.argmax(nonzero, axis=1), w)
    return (mantissa & (column >= start[:, None])).sum(axis=1).astype(np.int64)


def _ints_of_fields(
    block: np.ndarray, lines: np.ndarray, path: Path, what: str
) -> tuple[np.ndarray, np.ndarray]:
    """Integers of fixed-width byte fields (m, w) and the mask of blank fields (value 0)."""
    block = np.ascontiguousarray(block, dtype=np.uint8)
    m, w = block.shape
    empty = (block == _SPACE).all(axis=1)
    values = np.zeros(m, dtype=np.int64)
    given = np.flatnonzero(~empty)
    ok = not (block == ord("_")).any()  # numpy, as int(), would read 1_000
    if given.size and ok:
        try:
            values[given] = (
                np.ascontiguousarray(block[given]).view(f"S{w}").ravel().astype(np.int64)
            )
            ok = bool(np.all(np.abs(values) <= MAX_ID))
        except (ValueError, OverflowError):
            ok = False
    if not ok:  # Python's parse, and its message
        for k in np.flatnonzero(~empty).tolist():
            values[k] = parse_int(bytes(block[k]).decode("latin-1"), path, int(lines[k]), what)
    return values, empty


def _components(text: str, path: Path, line: int, card: str) -> int:
    """A component field ``123456`` as a bit mask (bit c-1 for component c); 0 or blank is 0."""
    text = text.strip()
    if text in ("", "0"):
        return 0
    if not text.isdigit() or not set(text) <= set("123456") or len(set(text)) != len(text):
        raise located_error(
            path, line, f"{card}: component {text!r} is not 0 or digits 1-6 without repeats"
        )
    mask = 0
    for c in text:
        mask |= 1 << (int(c) - 1)
    return mask


# ============================================================================ the data
@dataclass(frozen=True)
class Card:
    """One bulk data card: name (upper case, without ``*``), data fields 2..., where it is."""

    name: str
    fields: tuple[str, ...]
    path: Path
    line: int
    section: int

    def field(self, k: int) -> str:
        """Data field ``k`` (from 0 for field 2), ``""`` if absent."""
        return self.fields[k] if k < len(self.fields) else ""

    @property
    def where(self) -> str:
        return f"{self.path}:{self.line}"


@dataclass(frozen=True)
class CoordinateSystem:
    """A coordinate system resolved to the basic system.

    ``kind`` is ``"R"``, ``"C"`` or ``"S"``; ``axes`` (3, 3) holds the unit vectors of the
    system's rectangular x, y, z axes in its columns (basic components); ``origin`` (3,) basic.
    """

    cid: int
    kind: str
    origin: np.ndarray
    axes: np.ndarray

    def to_basic(self, x: np.ndarray) -> np.ndarray:
        """Basic coordinates (n, 3) of points with coordinates ``x`` (n, 3) in this system."""
        x = np.asarray(x, dtype=float).reshape(-1, 3)
        if self.kind == "C":
            t = np.radians(x[:, 1])
            x = np.column_stack([x[:, 0] * np.cos(t), x[:, 0] * np.sin(t), x[:, 2]])
        elif self.kind == "S":
            t, p = np.radians(x[:, 1]), np.radians(x[:, 2])
            r = x[:, 0]
            x = np.column_stack(
                [r * np.sin(t) * np.cos(p), r * np.sin(t) * np.sin(p), r * np.cos(t)]
            )
        return self.origin + x @ self.axes.T

    def displacement_axes(self, basic: np.ndarray) -> np.ndarray:
        """Displacement directions (n, 3, 3) at points ``basic`` (n, 3): columns = unit vectors.

        Rectangular: the axes. Cylindrical: ``e_r, e_theta, e_z``; spherical: ``e_r, e_theta,
        e_phi``. On the z (polar) axis the rectangular axes of the system.
        """
        basic = np.asarray(basic, dtype=float).reshape(-1, 3)
        n = basic.shape[0]
        local = np.broadcast_to(np.eye(3), (n, 3, 3)).copy()
        if self.kind != "R":
            x = (basic - self.origin) @ self.axes
            rho = np.hypot(x[:, 0], x[:, 1])
            scale = np.maximum(np.linalg.norm(x, axis=1), 1e-300)
            off = rho > 1e-12 * scale
            c = np.where(off, x[:, 0] / np.where(off, rho, 1.0), 1.0)
            s = np.where(off, x[:, 1] / np.where(off, rho, 1.0), 0.0)
            if self.kind == "C":
                local[:, :, 0] = np.column_stack([c, s, np.zeros(n)])
                local[:, :, 1] = np.column_stack([-s, c, np.zeros(n)])
            else:
                r = np.linalg.norm(x, axis=1)
                st = np.where(off, rho / np.where(r > 0, r, 1.0), 0.0)
                ct = np.where(off, x[:, 2] / np.where(r > 0, r, 1.0), 1.0)
                e_r = np.column_stack([st * c, st * s, ct])
                e_t = np.column_stack([ct * c, ct * s, -st])
                e_p = np.column_stack([-s, c, np.zeros(n)])
                polar = ~off
                e_r[polar], e_t[polar], e_p[polar] = np.eye(3)[0], np.eye(3)[1], np.eye(3)[2]
                local[:, :, 0], local[:, :, 1], local[:, :, 2] = e_r, e_t, e_p
        return np.einsum("ij,njk->nik", self.axes, local)


BASIC = CoordinateSystem(0, "R", np.zeros(3), np.eye(3))


@dataclass(frozen=True)
class AnalysisSet:
    """The rows of the matrices of an external superelement (or of an a-set), in order.

    ``ids`` and ``directions`` (codes 0..5, 6 for scalar points) in matrix order; ``source``
    names the cards; ``boundary_grids`` the grids, ``scalars`` the scalar points (the modal
    coordinates of a Craig-Bampton superelement when ``modal``); ``assumed`` is True when the
    components were not listed (ASMBULK ``SECONCT``) but taken as all six.
    """

    ids: np.ndarray
    directions: np.ndarray
    source: str
    boundary_grids: np.ndarray
    scalars: np.ndarray
    modal: bool
    assumed: bool
    superelement: int | None
    where: str


@dataclass
class _Grids:
    """GRID cards as arrays (one row per card, file order)."""

    ids: list[np.ndarray] = field(default_factory=list)
    cp: list[np.ndarray] = field(default_factory=list)
    cp_blank: list[np.ndarray] = field(default_factory=list)
    xyz: list[np.ndarray] = field(default_factory=list)
    cd: list[np.ndarray] = field(default_factory=list)
    cd_blank: list[np.ndarray] = field(default_factory=list)
    line: list[np.ndarray] = field(default_factory=list)
    path: list[np.ndarray] = field(default_factory=list)
    section: list[np.ndarray] = field(default_factory=list)

    def add(self, ids, cp, cp_blank, xyz, cd, cd_blank, line, path_index, section) -> None:
        n = np.asarray(ids).size
        self.ids.append(np.asarray(ids, dtype=np.int64))
        self.cp.append(np.asarray(cp, dtype=np.int64))
        self.cp_blank.append(np.asarray(cp_blank, dtype=bool))
        self.xyz.append(np.asarray(xyz, dtype=float).reshape(n, 3))
        self.cd.append(np.asarray(cd, dtype=np.int64))
        self.cd_blank.append(np.asarray(cd_blank, dtype=bool))
        self.line.append(np.asarray(line, dtype=np.int64))
        self.path.append(np.full(n, path_index, dtype=np.int64))
        self.section.append(np.asarray(section, dtype=np.int64))

    def joined(self) -> dict[str, np.ndarray]:
        keys = ("ids", "cp", "cp_blank", "xyz", "cd", "cd_blank", "line", "path", "section")
        out = {}
        for key in keys:
            parts = getattr(self, key)
            if parts:
                out[key] = np.concatenate(parts)
            elif key == "xyz":
                out[key] = np.zeros((0, 3))
            else:
                out[key] = np.zeros(0, dtype=bool if key.endswith("blank") else np.int64)
        return out


# ============================================================================ reading
def read_bulk(path: PathLike) -> BulkData:
    """Read the bulk data of a Nastran input file, punch, ASMBULK or f06 echo (module docstring).

    Raises
    ------
    UserError
        An unreadable file, an include loop, a malformed card that is read (GRID, CORDxx, the
        sets), a grid or coordinate system defined twice with different data; one line
        ``file:line: problem``.
    """
    bulk = BulkData(Path(path))
    bulk._read_file(Path(path), (), 0)
    bulk._finish()
    return bulk


class BulkData:
    """The bulk data of one file and its includes (see :func:`read_bulk`)."""

    def __init__(self, path: Path) -> None:
        self.path = path
        self.kind = "bulk data"  # or "f06 bulk data echo", "results punch"
        self.results: str | None = None  # a results punch: what it holds
        self.counts: Counter[str] = Counter()  # every card name
        self.cards: dict[str, list[Card]] = {}
        # grid fields of one-line small-field element cards of _FAST_ELEMENTS, converted at
        # once (blank: 0), shape (n, grids); the other cards of these names are in ``cards``
        self.element_grids: dict[str, list[np.ndarray]] = {}
        self.paths: list[Path] = []
        self._grids = _Grids()
        self.sections: set[int] = set()
        self._resolved: dict[int, CoordinateSystem] = {0: BASIC}
        self._resolving: list[int] = []
        self.grid: dict[str, np.ndarray] = {}

    # ---------------------------------------------------------------- files
    def _read_file(self, path: Path, stack: tuple[Path, ...], section: int) -> None:
        where = f", included from {stack[-1]}" if stack else ""
        raw = read_card_file(path, f"Nastran bulk data{where}")
        index = len(self.paths)
        self.paths.append(path)
        if not stack and _RESULTS.search(raw[: 1 << 16]):
            self.kind = "results punch"
            self.results = _describe_results(raw)
            return
        if not stack and (_SORTED_ECHO.search(raw) or _INPUT_ECHO.search(raw)):
            self.kind = "f06 bulk data echo"
            lines, numbers, sections = _echo_lines(raw)
        else:
            lines = raw.splitlines()
            numbers = np.arange(1, len(lines) + 1, dtype=np.int64)
            sections = None
        if b"\t" in raw:
            lines = [t.expandtabs(8) if b"\t" in t else t for t in lines]
        _Parser(self, path, index, lines, numbers, sections, stack, section, b"$" in raw).run()

    def _finish(self) -> None:
        grids = self._grids.joined()
        # GRDSET defaults for blank CP and CD (per section; the last GRDSET of a section wins)
        for card in self.cards.get("GRDSET", []):
            cp = card.field(1)
            cd = card.field(5)
            mine = grids["section"] == card.section
            if cp:
                value = parse_int(cp, card.path, card.line, "GRDSET CP")
                grids["cp"][mine & grids["cp_blank"]] = value
            if cd:
                value = parse_int(cd, card.path, card.line, "GRDSET CD")
                grids["cd"][mine & grids["cd_blank"]] = value
        order = np.argsort(grids["ids"], kind="stable")
        ids = grids["ids"][order]
        same = np.flatnonzero(ids[1:] == ids[:-1])
        keep = np.ones(ids.size, dtype=bool)
        if same.size:
            a, b = order[same], order[same + 1]
            equal = (
                (grids["cp"][a] == grids["cp"][b])
                & (grids["cd"][a] == grids["cd"][b])
                & (grids["xyz"][a] == grids["xyz"][b]).all(axis=1)
            )
            if not equal.all():
                k = int(np.flatnonzero(~equal)[0])
                first, second = sorted((int(a[k]), int(b[k])))
                raise located_error(
                    self.paths[grids["path"][second]],
                    int(grids["line"][second]),
                    f"GRID {int(grids['ids'][second])} is defined twice with different data "
                    f"(first in {self.paths[grids['path'][first]]}:{int(grids['line'][first])})",
                )
            keep[order[same + 1]] = False
        self.grid = {key: value[keep] for key, value in grids.items()}
        order = np.argsort(self.grid["ids"], kind="stable")
        self.grid = {key: value[order] for key, value in self.grid.items()}
        self._systems = self._system_cards()

    # ---------------------------------------------------------------- facts
    def has(self, *names: str) -> bool:
        """Whether any card of these names was read."""
        return any(self.counts.get(name) for name in names)

    def describe(self) -> str:
        """What the file holds, e.g. ``"Nastran bulk data (EXTRN, 4 GRID, ASET, SPOINT, DTI)"``."""
        if self.results is not None:
            return self.results
        if not self.counts:
            return f"no Nastran bulk data cards ({self.kind})"
        names = [f"{count} {name}" if count > 1 else name for name, count in self.counts.items()]
        tail = f", and {len(names) - 8} other card types" if len(names) > 8 else ""
        names = names[:8]
        what = "Nastran bulk data" if self.kind == "bulk data" else f"a Nastran {self.kind}"
        return f"{what} ({', '.join(names)}{tail})"

    def superelement(self) -> int | None:
        """Id of the external superelement the file belongs to (``BEGIN SUPER`` or ``SEBULK``)."""
        supers = sorted(s for s in self.sections if s > 0)
        if len(supers) == 1:
            return supers[0]
        sebulk = self.cards.get("SEBULK", [])
        if len(sebulk) == 1:
            return parse_int(sebulk[0].field(0), sebulk[0].path, sebulk[0].line, "SEBULK SEID")
        return None

    def scalar_points(self) -> np.ndarray:
        """Ids of the SPOINT (and EPOINT) cards, sorted."""
        ids = [self._point_list(card) for card in self.cards.get("SPOINT", [])]
        ids += [self._point_list(card) for card in self.cards.get("EPOINT", [])]
        if not ids:
            return np.zeros(0, dtype=np.int64)
        return np.unique(np.concatenate(ids))

    def _point_list(self, card: Card) -> np.ndarray:
        """Ids of a ``SPOINT ID ID ...`` / ``SPOINT ID1 THRU ID2`` card (every id of a range)."""
        return self._ids(card, card.fields, lambda first, last: self._range(first, last, card))

    def _ids(self, card: Card, fields, thru) -> np.ndarray:
        """Ids of ``ID ID ... ID1 THRU ID2 ...`` fields; ``thru(first, last)`` gives a range."""
        out: list[np.ndarray] = []
        words = [f for f in fields if f]
        k = 0
        while k < len(words):
            first = self._id(words[k], card, "point id")
            if k + 2 < len(words) and words[k + 1].upper() == "THRU":
                last = self._id(words[k + 2], card, "point id")
                if last < first:
                    raise located_error(
                        card.path, card.line, f"{card.name}: {first} THRU {last} is empty"
                    )
                out.append(thru(first, last))
                k += 3
            else:
                out.append(np.array([first], dtype=np.int64))
                k += 1
        return np.concatenate(out) if out else np.zeros(0, dtype=np.int64)

    @staticmethod
    def _id(text: str, card: Card, what: str) -> int:
        value = parse_int(text, card.path, card.line, f"{card.name} {what}")
        if value <= 0:
            raise located_error(
                card.path, card.line, f"{card.name} {what} {value} must be positive"
            )
        return value

    @staticmethod
    def _range(first: int, last: int, card: Card) -> np.ndarray:
        if last < first:
            raise located_error(card.path, card.line, f"{card.name}: {first} THRU {last} is empty")
        if last - first >= MAX_RANGE:
            raise located_error(
                card.path, card.line, f"{card.name}: {first} THRU {last} spans too many ids"
            )
        return np.arange(first, last + 1, dtype=np.int64)

    # ---------------------------------------------------------------- grids
    def grid_rows(self, ids: np.ndarray) -> np.ndarray:
        """Row of each id in the grid arrays; -1 where the file has no GRID card for it."""
        ids = np.asarray(ids, dtype=np.int64)
        known = self.grid["ids"]
        if known.size == 0:
            return np.full(ids.shape, -1, dtype=np.int64)
        pos = np.minimum(np.searchsorted(known, ids), known.size - 1)
        return np.where(known[pos] == ids, pos, -1).astype(np.int64)

    def basic_coordinates(self, rows: np.ndarray | None = None) -> np.ndarray:
        """Basic coordinates (n, 3) of the grids at ``rows`` (default: all grids)."""
        rows = np.arange(self.grid["ids"].size) if rows is None else np.asarray(rows)
        out = np.zeros((rows.size, 3))
        cps = self.grid["cp"][rows]
        for cp in np.unique(cps).tolist():
            mine = cps == cp
            if cp == 0:
                out[mine] = self.grid["xyz"][rows[mine]]
                continue
            first = int(rows[np.flatnonzero(mine)[0]])
            system = self.coordinate_system(
                cp, self._grid_where(first), f"CP of GRID {self.grid['ids'][first]}"
            )
            out[mine] = system.to_basic(self.grid["xyz"][rows[mine]])
        return out

    def displacement_axes(
        self, rows: np.ndarray, basic: np.ndarray, cd: np.ndarray | None = None
    ) -> np.ndarray:
        """Displacement directions (n, 3, 3) of the grids at ``rows`` located at ``basic``.

        ``cd`` overrides the grids' displacement systems (default: their CD fields).
        """
        rows = np.asarray(rows)
        out = np.broadcast_to(np.eye(3), (rows.size, 3, 3)).copy()
        cds = self.grid["cd"][rows] if cd is None else np.asarray(cd)
        for cd in np.unique(cds).tolist():
            if cd == 0:
                continue
            mine = cds == cd
            first = int(rows[np.flatnonzero(mine)[0]])
            gid = int(self.grid["ids"][first])
            if cd < 0:
                raise located_error(
                    *self._grid_where(first),
                    f"GRID {gid} has CD={cd}: a fluid grid point, not a structural one",
                )
            system = self.coordinate_system(cd, self._grid_where(first), f"CD of GRID {gid}")
            out[mine] = system.displacement_axes(basic[mine])
        return out

    def _grid_where(self, row: int) -> tuple[Path, int]:
        return self.paths[int(self.grid["path"][row])], int(self.grid["line"][row])

    # ---------------------------------------------------------------- coordinate systems
    def _system_cards(self) -> dict[int, tuple[str, int, Card, list[str]]]:
        """cid -> (type, form, card, the fields of that system)."""
        systems: dict[int, tuple[str, int, Card, list[str]]] = {}
        for name in sorted(_SYSTEMS):
            for card in self.cards.get(name, []):
                form = int(name[4])
                if form == 1:
                    groups = [[card.field(k) for k in range(4)]]
                    if any(card.field(k) for k in range(4, 8)):
                        groups.append([card.field(k) for k in range(4, 8)])
                else:
                    groups = [[card.field(k) for k in range(11)]]
                for group in groups:
                    cid = self._id(group[0], card, "CID")
                    entry = (name[5], form, card, group)
                    if cid in systems:
                        old = systems[cid]
                        if (old[0], old[1], old[3]) != (entry[0], entry[1], entry[3]):
                            raise located_error(
                                card.path,
                                card.line,
                                f"coordinate system {cid} is defined twice with different data "
                                f"(first in {old[2].where})",
                            )
                        continue
                    systems[cid] = entry
        return systems

    def coordinate_system(self, cid: int, where: tuple[Path, int], what: str) -> CoordinateSystem:
        """The coordinate system ``cid`` resolved to basic; ``where``/``what`` for messages."""
        if cid in self._resolved:
            return self._resolved[cid]
        entry = self._systems.get(cid)
        if entry is None:
            raise located_error(
                *where, f"{what}: coordinate system {cid} is not defined in the file"
            )
        kind, form, card, fields = entry
        if cid in self._resolving:
            chain = " -> ".join(str(c) for c in [*self._resolving, cid])
            raise located_error(
                card.path, card.line, f"coordinate systems refer to each other: {chain}"
            )
        self._resolving.append(cid)
        try:
            if form == 2:
                rid = parse_int(fields[1] or "0", card.path, card.line, f"CORD2{kind} RID")
                ref = self.coordinate_system(
                    rid, (card.path, card.line), f"RID of coordinate system {cid}"
                )
                values = [
                    parse_real(fields[2 + k], card.path, card.line, f"CORD2{kind} {cid} field", 0.0)
                    for k in range(9)
                ]
                points = ref.to_basic(np.array(values).reshape(3, 3))
            else:
                gids = [self._id(fields[1 + k], card, f"G{k + 1}") for k in range(3)]
                rows = self.grid_rows(np.array(gids))
                if (rows < 0).any():
                    gid = gids[int(np.flatnonzero(rows < 0)[0])]
                    raise located_error(
                        card.path, card.line, f"CORD1{kind} {cid}: grid {gid} has no GRID card"
                    )
                points = self.basic_coordinates(rows)
            system = _system_from_points(cid, kind, points, card)
        finally:
            self._resolving.pop()
        self._resolved[cid] = system
        return system

    # ---------------------------------------------------------------- sets
    def analysis_set(self, limit: int | None = None) -> AnalysisSet | None:
        """The dof table of the matrices of the superelement or a-set the file defines.

        The a-set is the union of the ``ASET``, ``BSET``, ``CSET``, ``QSET`` (and ``...1``,
        ``BNDFIX``, ``BNDFRE``) and ``EXTRN`` members; without them, the ``SECONCT`` points of
        an ASMBULK file (grids with all six components, scalar points). Nastran orders the rows
        by internal sequence: grid and scalar points by ascending id, the components of a grid
        1 to 6. A file that resequences (``SEQGP``, ``PARAM,OLDSEQ`` other than -1) is refused.
        ``None`` when the file defines no such set. ``limit`` (the size of the matrices) bounds
        the ``THRU`` ranges of a file without the points they name.
        """
        members: list[tuple[np.ndarray, np.ndarray, str, Card]] = []  # ids, masks, set, card
        for name, letter in PAIR_SETS.items():
            for card in self.cards.get(name, []):
                ids, masks = [], []
                for k in range(0, len(card.fields) - 1, 2):
                    g, c = card.fields[k], card.fields[k + 1]
                    if not g and not c:
                        continue
                    ids.append(self._id(g, card, "point id"))
                    masks.append(_components(c, card.path, card.line, card.name))
                members.append((np.array(ids, dtype=np.int64), np.array(masks), letter, card))
        for name, letter in LIST_SETS.items():
            for card in self.cards.get(name, []):
                mask = _components(card.field(0), card.path, card.line, card.name)
                rest = Card(card.name, card.fields[1:], card.path, card.line, card.section)
                ids = self._set_list(rest, mask, limit)
                members.append((ids, np.full(ids.size, mask), letter, card))
        if any(letter == "o" for _, _, letter, _ in members) and not any(
            letter != "o" for _, _, letter, _ in members
        ):
            card = next(c for _, _, letter, c in members if letter == "o")
            raise located_error(
                card.path,
                card.line,
                f"{card.name} defines the a-set as the dofs not omitted, which needs the whole "
                "model; list the a-set with ASET/ASET1 instead",
            )
        members = [m for m in members if m[2] != "o"]
        assumed = False
        if not members:
            members = self._seconct_members()
            if not members:
                return None
            assumed = True
        self._check_sequence()
        spoints = self.scalar_points()
        keys_parts, card_parts = [], []
        q_set = False
        for number, (ids, masks, letter, card) in enumerate(members):
            masks = masks.astype(np.int64)
            is_grid = self.grid_rows(ids) >= 0
            bad = np.flatnonzero((masks == 0) & is_grid)
            if bad.size:
                raise located_error(
                    card.path,
                    card.line,
                    f"{card.name}: {int(ids[bad[0]])} is a GRID; component 0 (or blank) is for "
                    "scalar points",
                )
            bad = np.flatnonzero((masks != 0) & np.isin(ids, spoints))
            if bad.size:
                raise located_error(
                    card.path,
                    card.line,
                    f"{card.name}: {int(ids[bad[0]])} is a scalar point (SPOINT); give it with "
                    "component 0",
                )
            parts = [ids[masks == 0] * 8 + 6]
            parts += [ids[(masks >> c & 1) == 1] * 8 + c for c in range(6)]
            keys = np.concatenate(parts)
            keys_parts.append(keys)
            card_parts.append(np.full(keys.size, number))
            q_set |= letter == "q"
        all_keys = np.concatenate(keys_parts)
        table, first_of = np.unique(all_keys, return_index=True)
        owners = np.concatenate(card_parts)[first_of]
        if table.size == 0:
            return None
        ids, directions = table // 8, table % 8
        scalar = directions == 6
        scalars = np.unique(ids[scalar])
        boundary = np.unique(ids[~scalar])
        extseout = self.has("EXTRN", "SEBULK", "SECONCT")
        modal = bool(scalars.size) and (extseout or q_set)
        used = [members[k][3] for k in np.unique(owners).tolist()]
        cards = sorted({card.name for card in used})
        first = min(used, key=lambda c: (str(c.path), c.line))
        return AnalysisSet(
            ids=ids,
            directions=directions,
            source=", ".join(cards),
            boundary_grids=boundary,
            scalars=scalars,
            modal=modal,
            assumed=assumed,
            superelement=self.superelement(),
            where=first.where,
        )

    def _set_list(self, card: Card, mask: int, limit: int | None = None) -> np.ndarray:
        """Ids of ``ID ID ...`` / ``ID1 THRU ID2`` of a list-form set card.

        In a THRU range only the points that exist are members: grids for components 1-6,
        scalar points for component 0 (every id when the file has no such points at all).
        """
        known = self.scalar_points() if mask == 0 else self.grid["ids"]

        def thru(first: int, last: int) -> np.ndarray:
            if known.size:
                return known[(known >= first) & (known <= last)]
            count = (last - first + 1) * max(bin(mask).count("1"), 1)
            if limit is not None and count > max(limit, _EAGER_RANGE):
                raise located_error(
                    card.path,
                    card.line,
                    f"{first} THRU {last} puts {count} dofs in the a-set, more than the {limit} "
                    "rows of the matrices",
                )
            return self._range(first, last, card)

        return self._ids(card, card.fields, thru)

    def _seconct_members(self) -> list[tuple[np.ndarray, np.ndarray, str, Card]]:
        """Points of the superelement on ``SECONCT`` cards (ASMBULK): grids x 123456, scalars.

        ``SECONCT SEIDA SEIDB TOL LOC`` is followed by pairs ``GIDA GIDB`` or by ranges
        ``GIDA1 THRU GIDA2 GIDB1 THRU GIDB2``; the points of superelement ``SEIDA`` are read.
        """
        out = []
        spoints = self.scalar_points()
        for card in self.cards.get("SECONCT", []):
            words = [f for f in card.fields[8:] if f]
            points: list[np.ndarray] = []
            k = 0
            while k < len(words):
                if k + 1 < len(words) and words[k + 1].upper() == "THRU":
                    if k + 5 >= len(words) or words[k + 4].upper() != "THRU":
                        raise located_error(
                            card.path,
                            card.line,
                            "SECONCT: a range is 'GIDA1 THRU GIDA2 GIDB1 THRU GIDB2'",
                        )
                    first = self._id(words[k], card, "point id")
                    last = self._id(words[k + 2], card, "point id")
                    points.append(self._range(first, last, card))
                    k += 6
                else:
                    points.append(np.array([self._id(words[k], card, "point id")]))
                    k += 2
            ids = np.unique(np.concatenate(points)) if points else np.zeros(0, dtype=np.int64)
            masks = np.where(np.isin(ids, spoints), 0, 63)
            out.append((ids, masks, "s", card))
        return out

    def _check_sequence(self) -> None:
        for card in self.cards.get("SEQGP", []):
            raise located_error(
                card.path,
                card.line,
                "SEQGP resequences the points, so the row order of the matrices is not the "
                "ascending ids; export without SEQGP",
            )
        for card in self.cards.get("PARAM", []):
            if card.field(0).upper() == "OLDSEQ" and card.field(1) not in ("", "-1"):
                raise located_error(
                    card.path,
                    card.line,
                    f"PARAM,OLDSEQ,{card.field(1)} resequences the points, so the row order of "
                    "the matrices is not the ascending ids; use PARAM,OLDSEQ,-1",
                )


def _system_from_points(cid: int, kind: str, points: np.ndarray, card: Card) -> CoordinateSystem:
    """The system with origin A, z axis towards B and x-z plane through C (basic points)."""
    a, b, c = points
    z = b - a
    scale = max(np.linalg.norm(z), np.linalg.norm(c - a), 1e-300)
    if np.linalg.norm(z) <= 1e-12 * scale:
        raise located_error(
            card.path, card.line, f"coordinate system {cid}: points A and B coincide"
        )
    z = z / np.linalg.norm(z)
    y = np.cross(z, c - a)
    if np.linalg.norm(y) <= 1e-10 * scale:
        raise located_error(
            card.path, card.line, f"coordinate system {cid}: points A, B and C are collinear"
        )
    y = y / np.linalg.norm(y)
    x = np.cross(y, z)
    return CoordinateSystem(cid, kind, a.copy(), np.column_stack([x, y, z]))


def _describe_results(raw: bytes) -> str:
    """One line on a results punch: what it holds (e.g. 10 complex eigenvectors)."""
    head = raw.decode("latin-1")
    kinds = []
    for title in ("EIGENVECTOR", "DISPLACEMENTS", "VELOCITY", "ACCELERATION", "SPCF", "FORCES"):
        count = len(re.findall(rf"(?m)^\${title}\b", head))
        if count:
            kinds.append((title, count))
    if not kinds:
        return "a Nastran results punch"
    title, count = kinds[0]
    modes = len(re.findall(r"(?m)^\$EIGENVALUE\b", head))
    complex_ = "REAL-IMAGINARY" in head or "MAGNITUDE-PHASE" in head
    what = f"${title}"
    if title == "EIGENVECTOR":
        analysis = "a complex eigenvalue analysis" if complex_ else "a normal modes analysis"
        what += f", {modes or count} modes of {analysis}"
    else:
        what += f", {count} blocks"
    return f"a results punch ({what})"


def _echo_lines(raw: bytes) -> tuple[list[bytes], np.ndarray, np.ndarray]:
    """The card lines of the bulk data echo of an f06, their line numbers and sections.

    The sorted echo is used when there is one (it holds the included files); the unsorted
    echo's cards start in column 31.
    """
    lines = raw.splitlines()
    sorted_echo = bool(_SORTED_ECHO.search(raw))
    header = _SORTED_ECHO if sorted_echo else _INPUT_ECHO
    out: list[bytes] = []
    numbers: list[int] = []
    sections: list[int] = []
    inside = False
    section = 0
    for number, line in enumerate(lines, 1):
        if header.search(line):
            inside = True
            found = _ECHO_SUPER.search(line)
            section = int(found.group(1)) if found else 0
            continue
        if not inside:
            continue
        if line[:1] in (b"1", b"0") or b"TOTAL COUNT=" in line:
            if line[:1] == b"1" or b"TOTAL COUNT=" in line:
                inside = False  # page break or end: the next header reopens
            continue
        stripped = line.strip()
        if stripped.upper().startswith(b"ENDDATA"):
            inside = False
            continue
        if not stripped or stripped.startswith((b"ENTRY", b"COUNT")):
            continue
        if sorted_echo:
            match = _ECHO_LINE.match(line)
            if match is None:
                continue
            text = match.group(1)
        else:
            if len(line) <= 30 or line[:30].strip():
                continue
            text = line[30:]
        out.append(text.rstrip())
        numbers.append(number)
        sections.append(section)
    return out, np.array(numbers, dtype=np.int64), np.array(sections, dtype=np.int64)


# ============================================================================ the parser
class _Parser:
    """Cards of one file: lines classified with numpy, GRIDs converted vectorised."""

    def __init__(
        self,
        bulk: BulkData,
        path: Path,
        index: int,
        lines: list[bytes],
        numbers: np.ndarray,
        sections: np.ndarray | None,
        stack: tuple[Path, ...],
        section: int,
        has_dollar: bool = True,
    ) -> None:
        self.bulk, self.path, self.index = bulk, path, index
        self.lines, self.numbers = lines, numbers
        self.stack = (*stack, path.resolve())
        n = len(lines)
        u = np.array(lines, dtype=f"S{_WIDTH}") if n else np.zeros(0, dtype=f"S{_WIDTH}")
        self.u = u.view(np.uint8).reshape(n, _WIDTH).copy()
        self.u[self.u == 0] = _SPACE
        comment = np.zeros(n, dtype=bool)
        if has_dollar:
            for i, t in enumerate(lines):
                at = t.find(b"$")
                if at >= 0:
                    lines[i] = t[:at]
                    if at < _WIDTH:
                        self.u[i, at:] = _SPACE
                    comment[i] = not lines[i].strip()
        self.free = (self.u == _COMMA).any(axis=1)
        self.sections = (
            np.full(n, section, dtype=np.int64) if sections is None else sections.astype(np.int64)
        )
        self.blank = (self.u == _SPACE).all(axis=1) & ~self.free
        self.blank |= comment

    def _names(self) -> np.ndarray:
        """Field 1 of every line, upper case, without blanks and ``*``, as ``S8`` (vectorised).

        A free-field line's name ends at its first comma.
        """
        head = self.u[:, :8].copy()
        comma = head == _COMMA
        head[np.maximum.accumulate(comma, axis=1)] = 0
        head[(head == _SPACE) | (head == _STAR)] = 0
        lower = (head >= ord("a")) & (head <= ord("z"))
        head[lower] -= 32
        return np.ascontiguousarray(head).view("S8").ravel()

    def run(self) -> None:
        n = len(self.lines)
        if n == 0:
            return
        first = self.u[:, 0]
        upper = first & 0xDF
        letter = (upper >= ord("A")) & (upper <= ord("Z"))
        names = self._names()
        head = names.view(np.uint8).reshape(n, 8)
        control = letter & (
            (head[:, :5] == np.frombuffer(b"BEGIN", np.uint8)).all(axis=1)
            | (head[:, :7] == np.frombuffer(b"INCLUDE", np.uint8)).all(axis=1)
            | (head[:, :7] == np.frombuffer(b"ENDDATA", np.uint8)).all(axis=1)
            | (names == b"CEND")
        )
        active = ~self.blank
        self._controls(np.flatnonzero(control & active), active)
        start = active & letter & ~control
        cont = active & ~letter & ~control
        bad_first = cont & ~np.isin(first, [_STAR, _PLUS, _SPACE, _COMMA])
        if bad_first.any():
            i = int(np.flatnonzero(bad_first)[0])
            raise located_error(
                self.path,
                int(self.numbers[i]),
                "line is neither a card nor a continuation (cards start with a letter, "
                "continuation lines with '+', '*', ',' or a blank)",
            )
        breaker = start | (control & active)
        breakers = np.flatnonzero(breaker)
        owner = np.cumsum(breaker) - 1  # the last card start or control line before each line
        orphan = cont & (owner < 0)
        inside = cont & (owner >= 0)
        orphan[inside] = control[breakers[owner[inside]]]
        if orphan.any():
            i = int(np.flatnonzero(orphan)[0])
            raise located_error(self.path, int(self.numbers[i]), "continuation line without a card")
        starts = np.flatnonzero(start)
        if starts.size == 0:
            return
        unique, first_of, code = np.unique(names[starts], return_index=True, return_inverse=True)
        counts = np.bincount(code, minlength=unique.size)
        texts = [bytes(name).replace(b"\0", b"").decode("latin-1") for name in unique]
        for k in np.argsort(first_of, kind="stable").tolist():
            self.bulk.counts[texts[k]] += int(counts[k])
        member = start | cont
        member_rows = np.flatnonzero(member)
        first_member = np.searchsorted(member_rows, starts)
        n_lines = np.diff(np.append(first_member, member_rows.size))
        grid_code = texts.index("GRID") if "GRID" in texts else -1
        grid_cards = np.flatnonzero(code == grid_code)
        done = self._fast_grids(starts, grid_cards, n_lines, member_rows, first_member)
        done = np.concatenate([done, self._fast_elements(starts, code, texts, n_lines)])
        wanted_codes = [k for k, text in enumerate(texts) if text in _WANTED]
        wanted = np.flatnonzero(np.isin(code, wanted_codes))
        wanted = wanted[~np.isin(wanted, done)]
        for k in wanted.tolist():
            rows = member_rows[first_member[k] : first_member[k] + n_lines[k]].tolist()
            self._slow_card(texts[code[k]], rows)

    # ---------------------------------------------------------------- control lines
    def _controls(self, rows: np.ndarray, active: np.ndarray) -> None:
        """BEGIN, INCLUDE, ENDDATA and CEND: sections, includes, the end of the bulk data."""
        lines = self.lines
        cend = None
        for i in rows.tolist():
            word = lines[i].decode("latin-1").strip().upper()
            if word == "CEND":
                cend = i
                break
        if cend is not None:
            begin = next(
                (
                    i
                    for i in rows.tolist()
                    if i > cend and lines[i].decode("latin-1").strip().upper().startswith("BEGIN")
                ),
                len(lines),
            )
            active[:begin] = False  # executive and case control
            self.blank[:begin] = True
        includes: list[tuple[int, str, int]] = []
        for i in rows.tolist():
            if not active[i]:
                continue
            text = lines[i].decode("latin-1")
            word = text.strip().upper()
            if word.startswith("ENDDATA"):
                active[i:] = False
                self.blank[i:] = True
                break
            if word.startswith("BEGIN"):
                match = _BEGIN.match(text)
                kind = (match.group(1) or "").upper() if match else ""
                if kind == "SUPER" and match.group(2):
                    value = parse_int(match.group(2), self.path, int(self.numbers[i]), "SEID")
                elif kind == "BULK":
                    value = 0
                else:
                    value = -1  # BEGIN AUXMODEL, TRMC, ...: kept apart
                self.sections[i:] = value
                if value > 0:
                    self.bulk.sections.add(value)
                continue
            if word.startswith("INCLUDE"):
                name, last = self._include_name(i)
                active[i : last + 1] = False
                self.blank[i : last + 1] = True
                includes.append((i, name, int(self.sections[i])))
        for i, name, section in includes:
            target = (
                (original_path(self.path).parent / name).resolve()
                if not Path(name).is_absolute()
                else Path(name)
            )
            if target.resolve() in self.stack:
                raise located_error(
                    self.path, int(self.numbers[i]), "INCLUDE loop: the file includes itself"
                )
            self.bulk._read_file(target, self.stack, section)

    def _include_name(self, i: int) -> tuple[str, int]:
        """The quoted file name of an INCLUDE statement and its last line."""
        text = self.lines[i].decode("latin-1")
        quote = text.find("'")
        if quote < 0:
            raise located_error(
                self.path, int(self.numbers[i]), "INCLUDE without a quoted file name"
            )
        parts = [text[quote + 1 :]]
        last = i
        while "'" not in parts[-1]:
            last += 1
            if last >= len(self.lines):
                raise located_error(
                    self.path, int(self.numbers[i]), "INCLUDE: the quoted file name is not closed"
                )
            parts.append(self.lines[last].decode("latin-1").strip())
        name = "".join(p.strip() for p in parts)
        name = name[: name.index("'")].strip()
        if not name:
            raise located_error(self.path, int(self.numbers[i]), "INCLUDE with an empty file name")
        return name, last

    # ---------------------------------------------------------------- cards
    def _slow_card(self, name: str, rows: list[int]) -> None:
        fields: list[str] = []
        first = rows[0]
        start_large = b"*" in self._name_bytes(first)
        for i in rows:
            text = self.lines[i].decode("latin-1")
            large = start_large if i == first else text[:1] == "*"
            fields.extend(
                line_fields(text, large, bool(self.free[i]), self.path, int(self.numbers[i]))
            )
        while fields and not fields[-1]:
            fields.pop()
        card = Card(
            name, tuple(fields), self.path, int(self.numbers[first]), int(self.sections[first])
        )
        if name == "GRID":
            self._grid_card(card)
            return
        self.bulk.cards.setdefault(name, []).append(card)

    def _name_bytes(self, i: int) -> bytes:
        if self.free[i]:
            return self.lines[i].split(b",", 1)[0]
        return bytes(self.u[i, :8])

    def _grid_card(self, card: Card) -> None:
        """One GRID card (slow path: free field or unusual layout)."""
        f = card.field
        gid = self.bulk._id(f(0), card, "ID")
        cp = f(1)
        cd = f(5)
        xyz = [
            parse_real(f(2 + a), card.path, card.line, f"GRID {gid} X{a + 1}", 0.0)
            for a in range(3)
        ]
        self.bulk._grids.add(
            [gid],
            [parse_int(cp, card.path, card.line, f"GRID {gid} CP") if cp else 0],
            [not cp],
            [xyz],
            [parse_int(cd, card.path, card.line, f"GRID {gid} CD") if cd else 0],
            [not cd],
            [card.line],
            self.index,
            [card.section],
        )

    def _fast_grids(
        self,
        starts: np.ndarray,
        grid_cards: np.ndarray,
        n_lines: np.ndarray,
        member_rows: np.ndarray,
        first_member: np.ndarray,
    ) -> np.ndarray:
        """GRID cards converted with numpy; returns the cards done (others take the slow path).

        Small field in one line, large field in two lines, free field in one line with fields
        of at most 16 characters.
        """
        if grid_cards.size == 0:
            return grid_cards
        rows = starts[grid_cards]
        count = n_lines[grid_cards]
        large = (self.u[rows, :8] == _STAR).any(axis=1)
        free = self.free[rows]
        second = member_rows[np.minimum(first_member[grid_cards] + 1, member_rows.size - 1)]
        small_ok = ~free & ~large & (count == 1)
        large_ok = ~free & large & (count == 2)
        large_ok &= ~self.free[second] & (self.u[second, 0] == _STAR)
        blocks, lines, picked = [], [], []
        if small_ok.any():
            r = rows[small_ok]
            blocks.append(self.u[r, 8:72].reshape(r.size, 8, 8))
            lines.append(r)
            picked.append(grid_cards[small_ok])
        if large_ok.any():
            r, s = rows[large_ok], second[large_ok]
            block = np.empty((r.size, 8, 16), dtype=np.uint8)
            block[:, :4] = self.u[r, 8:72].reshape(r.size, 4, 16)
            block[:, 4:] = self.u[s, 8:72].reshape(r.size, 4, 16)
            blocks.append(block)
            lines.append(r)
            picked.append(grid_cards[large_ok])
        free_ok = free & ~large & (count == 1)
        if free_ok.any():
            r = rows[free_ok]
            block, ok = self._free_fields(r)
            blocks.append(block[ok])
            lines.append(r[ok])
            picked.append(grid_cards[free_ok][ok])
        for block, r in zip(blocks, lines, strict=True):
            self._add_grids(block, r)
        return np.concatenate(picked) if picked else np.zeros(0, dtype=np.int64)

    def _fast_elements(
        self, starts: np.ndarray, code: np.ndarray, texts: list[str], n_lines: np.ndarray
    ) -> np.ndarray:
        """The grid fields of one-line small-field element cards of :data:`_FAST_ELEMENTS`,
        converted with numpy into :attr:`BulkData.element_grids`; returns the cards done."""
        picked = []
        for name, (first, count) in _FAST_ELEMENTS.items():
            if name not in texts:
                continue
            cards = np.flatnonzero(code == texts.index(name))
            rows = starts[cards]
            ok = ~self.free[rows] & ~(self.u[rows, :8] == _STAR).any(axis=1) & (n_lines[cards] == 1)
            if not ok.any():
                continue
            r = rows[ok]
            block = self.u[r, 8:72].reshape(r.size, 8, 8)
            numbers = self.numbers[r]
            ids = [_ints_of_fields(block[:, first + k], numbers, self.path, f"{name} grid")[0]
                   for k in range(count)]  # fmt: skip
            self.bulk.element_grids.setdefault(name, []).append(np.column_stack(ids))
            picked.append(cards[ok])
        return np.concatenate(picked) if picked else np.zeros(0, dtype=np.int64)

    def _add_grids(self, block: np.ndarray, at: np.ndarray) -> None:
        """Convert the fields (m, 8, w) of GRID cards starting on lines ``at``; add them."""
        numbers = self.numbers[at]
        path = self.path
        ids, id_blank = _ints_of_fields(block[:, 0], numbers, path, "GRID ID")
        bad = np.flatnonzero(id_blank | (ids <= 0))
        if bad.size:
            k = int(bad[0])
            problem = "is missing" if id_blank[k] else f"{int(ids[k])} must be positive"
            raise located_error(path, int(numbers[k]), f"GRID ID {problem}")
        cp, cp_blank = _ints_of_fields(block[:, 1], numbers, path, "GRID CP")
        cd, cd_blank = _ints_of_fields(block[:, 5], numbers, path, "GRID CD")
        xyz = np.column_stack(
            [reals_of_fields(block[:, 2 + a], numbers, path, f"GRID X{a + 1}") for a in range(3)]
        )
        self.bulk._grids.add(
            ids, cp, cp_blank, xyz, cd, cd_blank, numbers, self.index, self.sections[at]
        )

    def _free_fields(self, rows: np.ndarray, width: int = 96) -> tuple[np.ndarray, np.ndarray]:
        """Fields ID, CP, X1, X2, X3, CD of one-line free-field GRIDs as (m, 8, 16) bytes.

        Returns the fields and which lines fit: a line longer than ``width``, with more than 9
        commas or with one of these fields longer than 16 characters is left to the slow path
        (``ok`` false). PS and SEID are not read (blank).
        """
        text = [self.lines[i] for i in rows.tolist()]
        m = len(text)
        length = np.fromiter((len(t) for t in text), dtype=np.int64, count=m)
        w = int(min(width, max(int(length.max()), 1)))
        a = np.array(text, dtype=f"S{w}").view(np.uint8).reshape(m, w)
        where = np.flatnonzero(a == _COMMA)  # row-major: by line, then by column
        row, col = where // w, where % w
        total = np.bincount(row, minlength=m)
        first = np.cumsum(total) - total
        ok = (length <= w) & (total <= 9)
        last = max(col.size - 1, 0)
        bounds = []
        for k in range(7):
            has = total > k
            bounds.append(np.where(has, col[np.minimum(first + k, last)], length))
        block = np.full((m, 8, 16), _SPACE, dtype=np.uint8)
        flat = a.ravel()
        base = np.arange(m, dtype=np.int64)[:, None] * w
        column = np.arange(16)[None, :]
        for k in range(6):
            begin, end = bounds[k] + 1, bounds[k + 1]
            size = np.maximum(end - begin, 0)
            ok &= size <= 16
            if not size.any():
                continue
            index = base + np.minimum(begin[:, None] + column, w - 1)
            taken = flat[index]
            block[:, k] = np.where((column < size[:, None]) & (taken != 0), taken, _SPACE)
        return block, ok


# ============================================================================ solid elements
#: Nastran CHEXA (20 grids) lists the edges G1-G5 .. G4-G8 (G13-G16) before those of the face
#: G5-G8 (G17-G20); the hex20 kinematics take the face first (Abaqus/Ansys order).
CHEXA20_TO_HEX20 = np.r_[0:12, 16:20, 12:16]
_SOLID_CARDS = {"CTETRA": {4: "tet4", 10: "tet10"}, "CHEXA": {8: "hex8", 20: "hex20"}}
#: Element cards whose stiffening is not implemented (their presence makes the mesh unusable).
_OTHER_ELEMENTS = (
    "CPENTA", "CPYRAM", "CQUAD4", "CQUAD8", "CTRIA3", "CTRIA6", "CQUADR", "CTRIAR", "CSHEAR",
    "CBAR", "CBEAM", "CROD", "CONROD", "CTUBE", "CBUSH", "CELAS1", "CELAS2", "CELAS3", "CELAS4",
    "CGAP", "RBE2", "RBE3", "RBAR", "MPC",
)  # fmt: skip


def bulk_solid_blocks(bulk: BulkData) -> list[SolidBlock] | str:
    """The CTETRA/CHEXA elements of the bulk data with their MAT1 material, or why not.

    ``CTETRA EID PID G1 .. G4 [G5 .. G10]`` and ``CHEXA EID PID G1 .. G8 [G9 .. G20]`` (all edge
    grids or none), ``PSOLID PID MID ...`` and ``MAT1 MID E G NU`` (E and NU; a blank one from
    ``G = E / (2 (1 + NU))``, a G beside both is ignored, as Nastran does for solids). Other
    element cards (shells, beams, springs, rigid elements, pentahedra ...) make the mesh
    unusable. The card list is read with :func:`read_bulk` (these cards are kept for it).

    Returns
    -------
    list of SolidBlock, or str
        Blocks per card kind and material (CHEXA connectivity in the hex20 node order), or the
        reason there is no usable mesh.
    """
    name = bulk.path.name
    others = [card for card in _OTHER_ELEMENTS if bulk.counts.get(card)]
    if others:
        return (
            f"{name} has {', '.join(others)} elements, whose geometric stiffness is not "
            "implemented (solid cards read: CTETRA, CHEXA)"
        )
    properties = {}
    for card in bulk.cards.get("PSOLID", []):
        pid = parse_int(card.field(0), card.path, card.line, "PSOLID PID")
        properties[pid] = parse_int(card.field(1), card.path, card.line, "PSOLID MID")
    materials: dict[int, tuple[float, float] | str] = {}
    for card in bulk.cards.get("MAT1", []):
        mid = parse_int(card.field(0), card.path, card.line, "MAT1 MID")
        materials[mid] = _mat1(card)
    groups: dict[tuple[str, int], list[np.ndarray]] = {}
    numbers: dict[tuple[str, int], list[int]] = {}
    for card_name, kinds in _SOLID_CARDS.items():
        for card in bulk.cards.get(card_name, []):
            grids = [f for f in card.fields[2:22] if f.strip()]
            kind = kinds.get(len(grids))
            if kind is None:
                return (
                    f"{card.where}: {card_name} with {len(grids)} grids (read: "
                    f"{' or '.join(map(str, kinds))}, all edge grids or none)"
                )
            ids = np.array([parse_int(g, card.path, card.line, f"{card_name} grid") for g in grids])
            pid = parse_int(card.field(1) or card.field(0), card.path, card.line, "PID")
            if pid not in properties:
                return f"{card.where}: {card_name} names PSOLID {pid}, which is not defined"
            if kind == "hex20":
                ids = ids[CHEXA20_TO_HEX20]
            groups.setdefault((kind, properties[pid]), []).append(ids)
            numbers.setdefault((kind, properties[pid]), []).append(
                parse_int(card.field(0), card.path, card.line, f"{card_name} EID")
            )
    if not groups:
        return f"{name} has no CTETRA or CHEXA elements"
    blocks = []
    known = bulk.grid.get("ids", np.zeros(0, dtype=np.int64))
    for (kind, mid), rows in groups.items():
        material = materials.get(mid)
        if material is None:
            return f"{name}: material {mid} of the solid elements is not a MAT1 card"
        if isinstance(material, str):
            return material
        connectivity = np.array(rows, dtype=np.int64)
        missing = connectivity[~np.isin(connectivity, known)]
        if missing.size:
            raise located_error(
                bulk.path, None, f"a solid element names grid {int(missing[0])}, which has no GRID"
            )
        blocks.append(
            SolidBlock(
                kind,
                connectivity,
                *material,
                f"{name}: MAT1 {mid}",
                np.array(numbers[(kind, mid)], dtype=np.int64),
            )
        )
    return blocks


# ============================================================================ surface elements
#: CPENTA with 15 grids lists the edges G1-G4 .. G3-G6 (G10-G12) before those of the face
#: G4-G6 (G13-G15); :mod:`pymorembs.surface` takes the face first (Abaqus C3D15 order).
CPENTA15_TO_WEDGE15 = np.r_[0:9, 12:15, 9:12]
#: Element cards drawn on the body's surface: (first grid field from 0 = EID, number of corner
#: grids, number of all grids, linear kind, kind with all edge grids, reordering of those).
_SURFACE_CARDS: dict[str, tuple[int, int, int, str, str, np.ndarray | None]] = {
    "CTETRA": (2, 4, 10, "tet4", "tet10", None),
    "CHEXA": (2, 8, 20, "hex8", "hex20", CHEXA20_TO_HEX20),
    "CPENTA": (2, 6, 15, "wedge6", "wedge15", CPENTA15_TO_WEDGE15),
    "CPYRAM": (2, 5, 13, "pyramid5", "pyramid13", None),
    "CTRIA3": (2, 3, 3, "tri3", "tri3", None),
    "CTRIAR": (2, 3, 3, "tri3", "tri3", None),
    "CTRIA6": (2, 3, 6, "tri3", "tri6", None),
    "CQUAD4": (2, 4, 4, "quad4", "quad4", None),
    "CQUADR": (2, 4, 4, "quad4", "quad4", None),
    "CSHEAR": (2, 4, 4, "quad4", "quad4", None),
    "CQUAD8": (2, 4, 8, "quad4", "quad8", None),
    "CBAR": (2, 2, 2, "line2", "line2", None),
    "CBEAM": (2, 2, 2, "line2", "line2", None),
    "CROD": (2, 2, 2, "line2", "line2", None),
    "CTUBE": (2, 2, 2, "line2", "line2", None),
    "CONROD": (1, 2, 2, "line2", "line2", None),
}
#: Element cards the surface leaves out (counted in its note): springs, dampers, gaps, bushes,
#: welds, rigid elements, point masses, and elements of kinds :mod:`pymorembs.surface` lacks.
UNDRAWN_ELEMENT_CARDS = (
    "CBUSH", "CBUSH1D", "CBUSH2D", "CELAS1", "CELAS2", "CELAS3", "CELAS4", "CDAMP1", "CDAMP2",
    "CDAMP3", "CDAMP4", "CDAMP5", "CVISC", "CGAP", "CFAST", "CWELD", "CSEAM", "RBE1", "RBE2",
    "RBE3", "RBAR", "RBAR1", "RROD", "RTRPLT", "RSPLINE", "CONM1", "CONM2", "CMASS1", "CMASS2",
    "CMASS3", "CMASS4", "CBEAM3", "CBEND", "CQUAD", "CTRIAX", "CTRIAX6", "CQUADX", "CPLSTN3",
    "CPLSTN4", "CPLSTS3", "CPLSTS4",
)  # fmt: skip


def bulk_surface_elements(bulk: BulkData) -> SurfaceElements:
    """Every drawn element card of the bulk data for the body's surface, whatever its property.

    Solids (CTETRA, CHEXA, CPENTA, CPYRAM), shells (CTRIA3/6, CTRIAR, CQUAD4/8, CQUADR, CSHEAR)
    and line elements (CBAR, CBEAM, CROD, CONROD, CTUBE) by their grids; a quadratic card with
    some edge grids blank (or 0) is drawn through its corners. The cards of
    :data:`UNDRAWN_ELEMENT_CARDS` are counted as not drawn, as is a card whose corner grids are
    incomplete.

    Returns
    -------
    SurfaceElements
        Connectivity in grid ids, in the node order of :mod:`pymorembs.surface`.
    """
    elements = SurfaceElements()
    for card_name, (first, corners, full, linear, quadratic, order) in _SURFACE_CARDS.items():
        cards = bulk.cards.get(card_name, [])
        parts = list(bulk.element_grids.get(card_name, []))
        if cards:
            parts.append(_grid_fields(cards, first, full, card_name))
        if not parts:
            continue
        ids = np.concatenate(parts)
        incomplete = (ids[:, :corners] == 0).any(axis=1)
        elements.skip(card_name, int(incomplete.sum()))
        every = ~incomplete & (ids != 0).all(axis=1) if full > corners else ~incomplete
        some = ~incomplete & ~every
        if full > corners:
            elements.add(quadratic, ids[every][:, order] if order is not None else ids[every])
            elements.add(linear, ids[some][:, :corners])
        else:
            elements.add(linear, ids[every])
    for card_name in UNDRAWN_ELEMENT_CARDS:
        elements.skip(card_name, bulk.counts.get(card_name, 0))
    return elements


def _grid_fields(cards: list[Card], first: int, count: int, name: str) -> np.ndarray:
    """Integer fields ``first .. first + count - 1`` of the cards (blank: 0), shape (n, count);
    converted at once, card by card (naming the card) where that fails."""
    text = np.array(
        [[card.field(first + k).strip() or "0" for k in range(count)] for card in cards], dtype=str
    )
    ids = None
    if not (np.char.find(text, "_") >= 0).any():  # int() would read 1_000
        try:
            ids = text.astype(np.int64)
        except (ValueError, OverflowError):
            pass
    if ids is None or np.abs(ids).max(initial=0) > MAX_ID:
        ids = np.array(
            [[parse_int(f, card.path, card.line, f"{name} grid") for f in row]
             for card, row in zip(cards, text.tolist(), strict=True)],
            dtype=np.int64,
        )  # fmt: skip
    return ids


def _mat1(card: Card) -> tuple[float, float] | str:
    """(E, nu) of a MAT1 card, or why it is not an isotropic material.

    Solid elements take ``E`` and ``NU`` when both are given (a ``G`` beside them is for shells
    and beams; NX Nastran's CTETRA stiffness in tests/data has E and NU with G ignored); with
    one of them blank it follows from ``G = E / (2 (1 + NU))``.
    """
    values = []
    for k, what in ((1, "E"), (2, "G"), (3, "NU")):
        text = card.field(k)
        values.append(parse_real(text, card.path, card.line, f"MAT1 {what}") if text else None)
    young, shear, poisson = values
    if young is None and shear is not None and poisson is not None:
        young = 2.0 * shear * (1.0 + poisson)
    if poisson is None and young is not None and shear is not None:
        poisson = young / (2.0 * shear) - 1.0
    if young is None or poisson is None:
        return f"{card.where}: MAT1 needs two of E, G, NU"
    return float(young), float(poisson)
