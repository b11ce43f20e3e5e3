"""Node coordinates and element connectivity from an Ansys Mechanical APDL archive (``.cdb``).

Write the archive of the model in ``/PREP7`` (or from Mechanical: *Tools > Write Input File*)::

    CDWRITE,DB,Jobname,cdb

:func:`read_cdb` reads the two blocks a body needs and nothing else:

``NBLOCK``
    ``NBLOCK,NUMFIELD,SOLID,NDMAX,NDSEL``, a Fortran format line such as ``(3i9,6e21.13e3)``, then
    one fixed-width line per node: node number (plus the solid-model entity and line location
    when the key ``SOLID`` is given), then up to ``NUMFIELD`` reals ``x y z thxy thyz thzx``;
    trailing zero reals are left out. The block ends with ``N,R5.3,LOC,-1,`` (or ``-1``).
    Coordinates are global Cartesian; ``thxy thyz thzx`` are the rotation angles (degrees) of
    the nodal coordinate system, in which Ansys writes the dofs of that node.
``EBLOCK``
    ``EBLOCK,NUMFIELD,SOLID,NEMAX,NESEL``, a format line such as ``(19i10)``, then per element
    the fields ``mat type real secnum esys death solidm shape nnodes 0 number`` and the
    ``nnodes`` node numbers, wrapped after ``NUMFIELD`` fields per line; the block ends with
    ``-1``. Only the ``SOLID`` layout is read; blocks in another layout (contact and surface
    elements written without the key) are skipped.

``ET``, ``KEYOPT`` and ``MPDATA`` commands
    The element types and the material properties (:func:`cdb_solid_blocks`: the solid
    elements and isotropic material for geometric stiffening).
``CMBLOCK``
    ``CMBLOCK,Cname,NODE,NUMITEMS``, a format line such as ``(8i10)``, then ``NUMITEMS``
    integers: node numbers, where a negative ``-k`` after ``j`` means the range ``j .. k``.
    Node components become :attr:`AnsysArchive.node_components` (names upper case, as Ansys
    keeps them); components of elements and other entities are skipped.

Everything else in the file (commands, loads) is ignored. The parse is
vectorised (fixed-width fields read by NumPy); a slow pass over the lines runs only to name the
first bad line in an error message.

This module deliberately does not use ``ansys.mapdl.reader.Archive``: its C parser crashes the
interpreter (segmentation fault or abort) on damaged archives -- 11 of 60 randomly mutated copies
of the genuine ``HexBeam.cdb`` in a trial -- and a reader must refuse such files with a message.
The tests compare :func:`read_cdb` with ``Archive`` on the genuine archives that ship with
ansys-mapdl-reader.
"""

from __future__ import annotations

import os
import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from pymorembs.errors import located_error
from pymorembs.io.element_surface import SurfaceElements
from pymorembs.io.matrix_market import read_text_lines
from pymorembs.io.solid_mesh import SolidBlock

__all__ = [
    "ANSYS_SOLID_TYPES",
    "ANSYS_SURFACE_TYPES",
    "AnsysArchive",
    "cdb_solid_blocks",
    "cdb_surface_elements",
    "looks_like_cdb",
    "read_cdb",
]

PathLike = str | os.PathLike[str]

#: Fortran format of the NBLOCK lines, e.g. ``(3i9,6e21.13e3)`` or ``(1i8,6e20.13)``.
_NBLOCK_FORMAT = re.compile(
    r"^\(\s*(\d+)\s*i\s*(\d+)\s*,\s*(\d+)\s*e\s*(\d+)\s*\.\s*\d+\s*(?:e\s*\d+)?\s*\)$", re.I
)
#: Fortran format of the EBLOCK lines, e.g. ``(19i10)``.
_EBLOCK_FORMAT = re.compile(r"^\(\s*(\d+)\s*i\s*(\d+)\s*\)$", re.I)
_ELEMENT_FIELDS = 11  # mat type real secnum esys death solidm shape nnodes 0 number
_NODE_LIMIT = 2**31  # Ansys node and element numbers are 32-bit integers


@dataclass(frozen=True, eq=False)
class AnsysArchive:
    """Nodes and (optionally) elements of an Ansys archive.

    Parameters
    ----------
    node_ids : ndarray of int, shape (n_nodes,)
        Node numbers in the order of the NBLOCK.
    coordinates : ndarray, shape (n_nodes, 3)
        Global Cartesian coordinates (model length unit).
    angles : ndarray, shape (n_nodes, 3)
        Rotation angles ``thxy thyz thzx`` (degrees) of the nodal coordinate systems.
    element_ids : ndarray of int, shape (n_elements,)
        Element numbers (empty without a readable EBLOCK).
    element_offsets : ndarray of int, shape (n_elements + 1,)
        Element ``k`` has the nodes ``element_nodes[element_offsets[k]:element_offsets[k + 1]]``.
    element_nodes : ndarray of int
        Node numbers of all elements, concatenated (zeros of dropped midside nodes removed).
    element_materials, element_types : ndarray of int, shape (n_elements,)
        Material and element type numbers of each element (EBLOCK fields 1 and 2).
    element_type_names : dict of int -> int
        ``ET,itype,number``: the Ansys element number (186 for SOLID186) of each type.
    keyopts : dict of (int, int) -> int
        ``KEYOPT,itype,knum,value``.
    materials : dict of int -> dict of str -> tuple of float
        ``MPDATA`` values by material number and property label (``EX``, ``PRXY``, ...), one
        value per temperature.
    node_components : dict of str -> ndarray of int
        The node numbers of each ``CMBLOCK`` node component, by upper-case name, sorted.
    """

    node_ids: np.ndarray
    coordinates: np.ndarray
    angles: np.ndarray
    element_ids: np.ndarray
    element_offsets: np.ndarray
    element_nodes: np.ndarray
    element_materials: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    element_types: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    element_type_names: dict[int, int] = field(default_factory=dict)
    keyopts: dict[tuple[int, int], int] = field(default_factory=dict)
    materials: dict[int, dict[str, tuple[float, ...]]] = field(default_factory=dict)
    node_components: dict[str, np.ndarray] = field(default_factory=dict)

    @property
    def has_elements(self) -> bool:
        """Whether the archive gave element connectivity."""
        return bool(self.element_ids.size)

    def neighbours(self, nodes: np.ndarray) -> np.ndarray:
        """The nodes that share an element with one of ``nodes`` (``nodes`` included), sorted."""
        nodes = np.unique(np.asarray(nodes, dtype=np.int64))
        counts = np.diff(self.element_offsets)
        hit = np.isin(self.element_nodes, nodes).astype(np.int64)
        touched = np.zeros(counts.size, dtype=bool)
        filled = counts > 0
        touched[filled] = np.add.reduceat(hit, self.element_offsets[:-1][filled]) > 0
        near = self.element_nodes[np.repeat(touched, counts)]
        return np.union1d(near, nodes)


def looks_like_cdb(path: Path, limit: int = 1 << 26) -> bool:
    """Whether ``path`` holds an ``NBLOCK`` line in its first ``limit`` bytes (an Ansys archive)."""
    pattern = re.compile(rb"(?im)^\s*NBLOCK\s*,")
    tail = b""
    try:
        with open(path, "rb") as f:
            for _ in range(limit >> 20):
                chunk = f.read(1 << 20)
                if not chunk:
                    return False
                block = tail + chunk
                if pattern.search(block):
                    return True
                tail = block[block.rfind(b"\n") + 1 :][-256:]
    except OSError:
        return False
    return False


def read_cdb(path: PathLike) -> AnsysArchive:
    """Read nodes and element connectivity from an Ansys archive (``CDWRITE``).

    Parameters
    ----------
    path : path-like
        The ``.cdb`` file (layout in the module docstring).

    Returns
    -------
    AnsysArchive

    Raises
    ------
    UserError
        No NBLOCK, an unreadable format line, a field that is not a number, a node listed twice,
        fewer nodes than the NBLOCK header announces, an element that names a node the NBLOCK
        does not define; one line ``file:line: problem``.
    """
    path = Path(path)
    lines = read_text_lines(path, "an Ansys archive (.cdb)")
    heads = _block_starts(lines)
    if "NBLOCK" not in heads:
        raise located_error(
            path, None, "no NBLOCK (node block) in the file; write the archive with CDWRITE,DB"
        )
    node_ids, coordinates, angles = _read_nblock(path, lines, heads["NBLOCK"])
    element_ids = np.zeros(0, dtype=np.int64)
    offsets = np.zeros(1, dtype=np.int64)
    element_nodes = np.zeros(0, dtype=np.int64)
    materials = types = np.zeros(0, dtype=np.int64)
    if "EBLOCK" in heads:
        read = _read_eblock(path, lines, heads["EBLOCK"])
        if read is not None:
            element_ids, offsets, element_nodes, materials, types = read
            unknown = ~np.isin(element_nodes, node_ids)
            if unknown.any():
                k = int(np.searchsorted(offsets, np.flatnonzero(unknown)[0], side="right")) - 1
                raise located_error(
                    path,
                    heads["EBLOCK"] + 1,
                    f"EBLOCK: element {int(element_ids[k])} names node "
                    f"{int(element_nodes[unknown][0])}, which the NBLOCK does not define",
                )
    names, keyopts, properties = _element_types_and_materials(lines)
    return AnsysArchive(
        node_ids,
        coordinates,
        angles,
        element_ids,
        offsets,
        element_nodes,
        materials,
        types,
        names,
        keyopts,
        properties,
        _node_components(path, lines),
    )


_CMBLOCK = re.compile(r"^\s*CMBLOCK\s*,", re.I)


def _node_components(path: Path, lines: list[str]) -> dict[str, np.ndarray]:
    """The ``CMBLOCK`` node components (module docstring), by upper-case name."""
    components: dict[str, np.ndarray] = {}
    for index, text in enumerate(lines):
        if not _CMBLOCK.match(text):
            continue
        fields = _header_fields(path, lines, index)
        if len(fields) < 4 or fields[2].upper() != "NODE":
            continue
        count = _header_int(path, index + 1, fields[3], "CMBLOCK item count") or 0
        match = _format_line(path, lines, index, "CMBLOCK", _EBLOCK_FORMAT, "(8i10)")
        per_line, width = int(match.group(1)), int(match.group(2))
        rows = lines[index + 2 : index + 2 + -(-count // per_line)]
        table = _fixed_width(path, rows, index + 3, [width] * per_line, int, "CMBLOCK")
        items = table.ravel()[:count]
        if items.size < count:
            raise located_error(
                path, index + 1, f"CMBLOCK {fields[1]}: {items.size} of {count} items present"
            )
        components[fields[1].upper()] = _expand_ranges(path, index + 1, fields[1], items)
    return components


def _expand_ranges(path: Path, line: int, name: str, items: np.ndarray) -> np.ndarray:
    """The numbers of a component's items, ``j, -k`` meaning ``j .. k``; sorted, each once."""
    ranged = np.flatnonzero(items < 0)
    if ranged.size and (ranged[0] == 0 or np.any(items[ranged - 1] <= 0)):
        raise located_error(path, line, f"CMBLOCK {name}: a range -k follows no number")
    parts = [items[items > 0]]
    parts += [np.arange(items[k - 1], -items[k] + 1, dtype=np.int64) for k in ranged]
    return np.unique(np.concatenate(parts).astype(np.int64))


def _element_types_and_materials(
    lines: list[str],
) -> tuple[dict[int, int], dict[tuple[int, int], int], dict[int, dict[str, tuple[float, ...]]]]:
    """``ET``, ``KEYOPT`` and ``MPDATA`` commands of the archive (malformed ones are skipped:
    the stiffening that needs them then says what is missing)."""
    names: dict[int, int] = {}
    keyopts: dict[tuple[int, int], int] = {}
    materials: dict[int, dict[str, tuple[float, ...]]] = {}
    for line in lines:
        head = line[:7].upper()
        if not head.startswith(("ET,", "KEYOPT,", "MPDATA,")):
            continue
        fields = [f.strip() for f in line.split(",")]
        try:
            if head.startswith("ET,") and len(fields) >= 3:
                names[int(fields[1])] = int(float(fields[2]))
            elif head.startswith("KEYOPT,") and len(fields) >= 4:
                keyopts[(int(fields[1]), int(fields[2]))] = int(float(fields[3]))
            elif head.startswith("MPDATA,") and len(fields) >= 7:
                # MPDATA,R5.0,count,label,mat,first location,values...
                count, label, mat = int(fields[2]), fields[3].upper(), int(fields[4])
                values = tuple(float(v) for v in fields[6 : 6 + count] if v)
                materials.setdefault(mat, {})[label] = values
        except ValueError:
            continue
    return names, keyopts, materials


def _block_starts(lines: list[str]) -> dict[str, int]:
    """Index of the first ``NBLOCK`` and ``EBLOCK`` header lines."""
    starts: dict[str, int] = {}
    for index, text in enumerate(lines):
        word = text.lstrip()[:6].upper()
        if word in ("NBLOCK", "EBLOCK") and word not in starts:
            starts[word] = index
            if len(starts) == 2:
                break
    return starts


def _header_fields(path: Path, lines: list[str], index: int) -> list[str]:
    fields = [field.strip() for field in lines[index].split("!", 1)[0].split(",")]
    if len(fields) < 2:
        raise located_error(path, index + 1, f"{fields[0]} header has no field count")
    return fields


def _format_line(
    path: Path, lines: list[str], index: int, block: str, form: re.Pattern[str], example: str
) -> re.Match[str]:
    """The Fortran format line after the block header at ``index``, matched by ``form``."""
    if index + 1 >= len(lines):
        raise located_error(path, index + 1, f"{block}: the format line is missing")
    text = lines[index + 1].strip()
    match = form.match(text)
    if match is None:
        raise located_error(
            path, index + 2, f"{block}: format {text!r} is not of the form {example}"
        )
    return match


def _header_int(path: Path, line: int, text: str, what: str) -> int | None:
    """An optional integer field of a block header (None when blank)."""
    if not text:
        return None
    try:
        value = int(text)
    except ValueError:
        raise located_error(path, line, f"{what} {text!r} is not an integer") from None
    if not 0 <= value < _NODE_LIMIT:
        raise located_error(path, line, f"{what} {value} is out of range")
    return value


def _block_lines(lines: list[str], first: int, end: re.Pattern[str]) -> list[str]:
    """The data lines from ``first`` up to (not including) the first line matching ``end``."""
    stop = first
    while stop < len(lines) and not end.match(lines[stop]):
        stop += 1
    return lines[first:stop]


_NBLOCK_END = re.compile(r"^\s*(N\s*,\s*R5\.3\s*,\s*LOC\s*,|-1\s*$)", re.I)
_EBLOCK_END = re.compile(r"^\s*-1\s*$")


def _fixed_width(
    path: Path,
    rows: list[str],
    first_line: int,
    widths: list[int],
    kind: type,
    what: str,
    names: tuple[str, ...] = (),
) -> np.ndarray:
    """Fixed-width fields of ``rows`` as an array (n_rows, len(widths)); blank fields are 0.

    ``names`` label the fields in messages (default: ``field 1``, ``field 2``, ...).
    """
    total = sum(widths)
    if not rows:
        return np.zeros((0, len(widths)), dtype=kind)
    try:
        raw = "".join(row[:total].ljust(total) for row in rows).encode("ascii")
    except UnicodeEncodeError:
        bad = next(k for k, row in enumerate(rows) if not row.isascii())
        raise located_error(path, first_line + bad, f"{what}: non-ASCII character") from None
    chars = np.frombuffer(raw, dtype="S1").reshape(len(rows), total)
    out = np.empty((len(rows), len(widths)), dtype=kind)
    start = 0
    for j, width in enumerate(widths):
        field = np.ascontiguousarray(chars[:, start : start + width]).view(f"S{width}")[:, 0]
        field = np.where(np.char.strip(field) == b"", b"0", field)
        try:
            out[:, j] = field.astype(kind)
        except (ValueError, OverflowError):
            bad = _first_bad(field, kind)
            text = field[bad].decode("ascii").strip()
            label = names[j] if j < len(names) else f"field {j + 1}"
            raise located_error(
                path, first_line + bad, f"{what}: {label} {text!r} is not a number"
            ) from None
        start += width
    if kind is float and not np.all(np.isfinite(out)):
        bad = int(np.flatnonzero(~np.all(np.isfinite(out), axis=1))[0])
        raise located_error(path, first_line + bad, f"{what}: a value is not a finite number")
    return out


def _check_width(path: Path, rows: list[str], first_line: int, total: int, what: str) -> None:
    """Refuse a line longer than the format (another layout than the format line says)."""
    long = next((k for k, row in enumerate(rows) if len(row.rstrip()) > total), None)
    if long is not None:
        raise located_error(
            path, first_line + long, f"{what}: line is longer than its format ({total} characters)"
        )


def _first_bad(field: np.ndarray, kind: type) -> int:
    """Index of the first field that does not convert (the slow pass for the message)."""
    for k, text in enumerate(field.tolist()):
        try:
            value = kind(text)
            if kind is int and not -_NODE_LIMIT < value < _NODE_LIMIT:
                return k
        except ValueError:
            return k
    return 0


def _read_nblock(
    path: Path, lines: list[str], index: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    fields = _header_fields(path, lines, index)
    line = index + 1
    n_real = _header_int(path, line, fields[1], "NBLOCK field count")
    announced = _header_int(path, line, fields[4], "NBLOCK node count") if len(fields) > 4 else None
    match = _format_line(path, lines, index, "NBLOCK", _NBLOCK_FORMAT, "(3i9,6e21.13e3)")
    n_int, int_width, n_float, float_width = (int(g) for g in match.groups())
    if not (1 <= n_int <= 3 and 1 <= int_width <= 20 and 3 <= n_float <= 6 and float_width <= 40):
        raise located_error(
            path, index + 2, f"NBLOCK: unexpected format {lines[index + 1].strip()!r}"
        )
    if n_real is not None and n_real < n_float:
        n_float = max(3, n_real)
    rows = _block_lines(lines, index + 2, _NBLOCK_END)
    first = index + 3
    _check_width(path, rows, first, n_int * int_width + n_float * float_width, "NBLOCK")
    numbers = _fixed_width(
        path, rows, first, [int_width] * n_int, int, "NBLOCK", ("node number", "field 2", "field 3")
    )
    reals = _fixed_width(
        path,
        [row[n_int * int_width :] for row in rows],
        first,
        [float_width] * n_float,
        float,
        "NBLOCK",
        ("x", "y", "z", "thxy", "thyz", "thzx"),
    )
    ids = numbers[:, 0].astype(np.int64)
    if ids.size == 0:
        raise located_error(path, line, "NBLOCK holds no nodes")
    bad = np.flatnonzero(ids <= 0)
    if bad.size:
        raise located_error(
            path, first + int(bad[0]), f"NBLOCK: node number {ids[bad[0]]} must be positive"
        )
    order = np.argsort(ids, kind="stable")
    repeat = np.flatnonzero(ids[order][1:] == ids[order][:-1])
    if repeat.size:
        a, b = sorted((int(order[repeat[0]]), int(order[repeat[0] + 1])))
        raise located_error(
            path, first + b, f"NBLOCK: node {ids[a]} is listed twice (first on line {first + a})"
        )
    if announced is not None and announced != ids.size:
        raise located_error(path, line, f"NBLOCK announces {announced} nodes but holds {ids.size}")
    angles = np.zeros((ids.size, 3))
    angles[:, : max(0, n_float - 3)] = reals[:, 3:6]
    return ids, reals[:, :3].copy(), angles


def _read_eblock(
    path: Path, lines: list[str], index: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray] | None:
    fields = _header_fields(path, lines, index)
    if len(fields) < 3 or fields[2].upper() != "SOLID":
        return None  # another layout (contact, surface elements): no connectivity
    match = _format_line(path, lines, index, "EBLOCK", _EBLOCK_FORMAT, "(19i10)")
    per_line, width = int(match.group(1)), int(match.group(2))
    if not (_ELEMENT_FIELDS + 1 <= per_line <= 40 and 1 <= width <= 20):
        raise located_error(
            path, index + 2, f"EBLOCK: unexpected format {lines[index + 1].strip()!r}"
        )
    rows = _block_lines(lines, index + 2, _EBLOCK_END)
    first = index + 3
    _check_width(path, rows, first, per_line * width, "EBLOCK")
    table = _fixed_width(path, rows, first, [width] * per_line, int, "EBLOCK")
    flat = table.astype(np.int64).ravel()
    starts: list[int] = []
    counts: list[int] = []
    row = 0
    while row < len(rows):
        n_nodes = int(table[row, 8])
        if not 1 <= n_nodes <= 64:
            raise located_error(
                path, first + row, f"EBLOCK: {n_nodes} nodes per element (field 9) is not plausible"
            )
        starts.append(row * per_line + _ELEMENT_FIELDS)
        counts.append(n_nodes)
        row += -(-(_ELEMENT_FIELDS + n_nodes) // per_line)
    if row > len(rows):
        raise located_error(path, first + len(rows) - 1, "EBLOCK: the last element is cut short")
    start = np.array(starts, dtype=np.int64)
    count = np.array(counts, dtype=np.int64)
    element_ids = flat[start - 1]
    index_of = np.repeat(start - np.cumsum(count) + count, count) + np.arange(int(count.sum()))
    nodes = flat[index_of]
    keep = nodes != 0  # a dropped midside node is written as 0
    count = (
        np.add.reduceat(keep.astype(np.int64), np.cumsum(count) - count) if count.size else count
    )
    offsets = np.concatenate([[0], np.cumsum(count)]).astype(np.int64)
    return element_ids, offsets, nodes[keep], flat[start - 11], flat[start - 10]


#: Ansys element numbers with solid kinematics in :mod:`pymorembs.elements.solid`: SOLID186
#: (KEYOPT(2) = 0, the default: uniform reduced 2 x 2 x 2 integration; 1: full 3 x 3 x 3) and
#: SOLID187 (4 points).
ANSYS_SOLID_TYPES = (186, 187)


def cdb_solid_blocks(archive: AnsysArchive, path: PathLike) -> list[SolidBlock] | str:
    """The SOLID186/187 elements of an archive with their material, or why there are none.

    Every element must be of a type ``ET,itype,186`` or ``187`` (other element types, also
    surface effect or contact elements, make the mesh unusable: their stiffening would be
    missing), with all its nodes (no dropped midside node, no degenerate shape), and its
    material must have ``MPDATA`` ``EX`` and ``PRXY`` (or ``NUXY``) at one temperature and no
    other elastic constants (``EY``, ``EZ``, ``GXY`` ... : anisotropy).

    Parameters
    ----------
    archive : AnsysArchive
    path : path-like
        The archive, for messages.

    Returns
    -------
    list of SolidBlock, or str
    """
    name = Path(path).name
    if not archive.has_elements:
        return f"{name} has no EBLOCK of elements"
    counts = np.diff(archive.element_offsets)
    blocks: list[SolidBlock] = []
    for itype in np.unique(archive.element_types).tolist():
        number = archive.element_type_names.get(int(itype))
        if number not in ANSYS_SOLID_TYPES:
            what = f"SOLID{number}" if number is not None else f"type {itype} (no ET command)"
            return (
                f"{name}: elements of {what} (ET {itype}), whose geometric stiffness is not "
                "implemented (read: SOLID186, SOLID187)"
            )
        keyopt = archive.keyopts.get((int(itype), 2), 0)
        if number == 186 and keyopt not in (0, 1):
            return f"{name}: SOLID186 with KEYOPT(2) = {keyopt} is not read (0 or 1 are)"
        kind, nodes = ("hex20r" if keyopt == 0 else "hex20", 20) if number == 186 else ("tet10", 10)
        of_type = archive.element_types == itype
        if np.any(counts[of_type] != nodes):
            return f"{name}: SOLID{number} elements with dropped midside nodes are not read"
        starts = archive.element_offsets[:-1][of_type]
        connectivity = archive.element_nodes[starts[:, None] + np.arange(nodes)]
        if number == 187 and connectivity.shape[0] == 0:
            continue
        ordered = np.sort(connectivity, axis=1)
        if np.any(ordered[:, 1:] == ordered[:, :-1]):
            return f"{name}: degenerate SOLID{number} elements (repeated nodes) are not read"
        for mat in np.unique(archive.element_materials[of_type]).tolist():
            properties = archive.materials.get(int(mat), {})
            young = properties.get("EX", ())
            poisson = properties.get("PRXY", properties.get("NUXY", ()))
            others = sorted(set(properties) & {"EY", "EZ", "GXY", "GYZ", "GXZ", "PRYZ", "PRXZ",
                                                 "NUYZ", "NUXZ"})  # fmt: skip
            if len(young) != 1 or len(poisson) > 1 or others:
                return (
                    f"{name}: material {mat} is not isotropic linear elastic at one temperature "
                    "(MPDATA EX and PRXY, one value each)"
                )
            chosen = of_type & (archive.element_materials == mat)
            blocks.append(
                SolidBlock(
                    kind,
                    connectivity[chosen[of_type]],
                    young[0],
                    poisson[0] if poisson else 0.0,
                    f"{name}: SOLID{number}, material {mat}",
                    archive.element_ids[chosen],
                )
            )
    return blocks


# ============================================================================ surface elements
#: Ansys element types drawn on the body's surface: number -> (name, family). Families:
#: ``hex8`` (8 nodes I..P; wedge, pyramid and tetrahedron as repeated nodes), ``hex20`` (20
#: nodes, the same degenerate forms), ``tet10``, ``quad4`` (4 nodes; K = L a triangle),
#: ``quad8`` (8 nodes; K = L = O a triangle), ``line2`` (I, J, an orientation node after them)
#: and ``line3`` (I, J, the middle node K, an orientation node L).
ANSYS_SURFACE_TYPES: dict[int, tuple[str, str]] = {
    185: ("SOLID185", "hex8"),
    45: ("SOLID45", "hex8"),
    190: ("SOLSH190", "hex8"),
    186: ("SOLID186", "hex20"),
    95: ("SOLID95", "hex20"),
    187: ("SOLID187", "tet10"),
    92: ("SOLID92", "tet10"),
    181: ("SHELL181", "quad4"),
    63: ("SHELL63", "quad4"),
    281: ("SHELL281", "quad8"),
    93: ("SHELL93", "quad8"),
    188: ("BEAM188", "line2"),
    4: ("BEAM4", "line2"),
    180: ("LINK180", "line2"),
    8: ("LINK8", "line2"),
    288: ("PIPE288", "line2"),
    189: ("BEAM189", "line3"),
    289: ("PIPE289", "line3"),
}
#: Names of common element types the surface leaves out (springs, masses, constraints, contact).
_UNDRAWN_NAMES = {
    14: "COMBIN14", 21: "MASS21", 39: "COMBIN39", 40: "COMBIN40", 170: "TARGE170",
    173: "CONTA173", 174: "CONTA174", 175: "CONTA175", 184: "MPC184", 250: "COMBIN250",
    154: "SURF154",
}  # fmt: skip
# Degenerate forms of the 8- and 20-node solids: the corner pattern (which corner equals which)
# and the nodes, in the order of the kind, that make it.
_WEDGE8 = [0, 1, 2, 4, 5, 6]
_PYRAMID8 = [0, 1, 2, 3, 4]
_TET8 = [0, 1, 2, 4]
_WEDGE20 = [0, 1, 2, 4, 5, 6, 8, 9, 11, 12, 13, 15, 16, 17, 18]
_PYRAMID20 = [0, 1, 2, 3, 4, 8, 9, 10, 11, 16, 17, 18, 19]
_TET20 = [0, 1, 2, 4, 8, 9, 11, 16, 17, 18]


def cdb_surface_elements(archive: AnsysArchive) -> SurfaceElements:
    """Every element of the archive for the body's surface, whatever its material.

    The types of :data:`ANSYS_SURFACE_TYPES` are drawn: the 8- and 20-node solids also in their
    degenerate forms (K = L and O = P a wedge, M = N = O = P a pyramid, both a tetrahedron; the
    midside nodes of the collapsed edges dropped), a quadratic solid or shell with dropped
    midside nodes through its corners, SHELL181 with K = L and SHELL281 with K = L = O as
    triangles, BEAM189 through its middle node. Other types (``COMBIN14``, ``MASS21``,
    ``CONTA174`` ...), an element type without an ``ET`` command and elements with fewer nodes
    than their type has corners are counted as not drawn.

    Returns
    -------
    SurfaceElements
        Connectivity in node numbers, in the node order of :mod:`pymorembs.surface`.
    """
    elements = SurfaceElements()
    if not archive.has_elements:
        return elements
    counts = np.diff(archive.element_offsets)
    starts = archive.element_offsets[:-1]
    for itype in np.unique(archive.element_types).tolist():
        of_type = archive.element_types == itype
        number = archive.element_type_names.get(int(itype))
        name, family = ANSYS_SURFACE_TYPES.get(number, ("", "")) if number is not None else ("", "")
        if not family:
            label = _UNDRAWN_NAMES.get(number, f"element type {number}") if number else None
            elements.skip(label or f"type {itype} (no ET)", int(of_type.sum()))
            continue
        full = {"hex8": 8, "hex20": 20, "tet10": 10, "quad4": 4, "quad8": 8}.get(family)
        corners = {"hex20": 8, "tet10": 4, "quad8": 4, "line2": 2, "line3": 2}.get(family, full)
        need = {"line2": 2, "line3": 3}.get(family, full)
        n = counts[of_type]
        first = starts[of_type]
        complete = n >= need if family.startswith("line") else n == full
        partial = ~complete & (n >= corners) & (family in ("hex20", "tet10", "quad8"))
        elements.skip(name, int((~complete & ~partial).sum()))
        if complete.any():
            nodes = archive.element_nodes[first[complete][:, None] + np.arange(need)]
            _add_ansys(elements, name, family, nodes)
        if partial.any():  # midside nodes dropped: the corners come first
            nodes = archive.element_nodes[first[partial][:, None] + np.arange(corners)]
            linear = {"hex20": "hex8", "tet10": "tet4", "quad8": "quad4"}[family]
            _add_ansys(elements, name, linear, nodes)
    return elements


def _add_ansys(elements: SurfaceElements, name: str, family: str, nodes: np.ndarray) -> None:
    """Add elements of an Ansys node layout, their degenerate forms split off."""
    if family == "line3":
        elements.add("line3", nodes[:, [0, 2, 1]])
    elif family in ("line2", "tet4", "tet10"):
        elements.add(family, nodes)
    elif family in ("quad4", "quad8"):
        triangle = nodes[:, 2] == nodes[:, 3]
        elements.add(family, nodes[~triangle])
        elements.add(*(("tri3", nodes[triangle][:, :3]) if family == "quad4" else
                       ("tri6", nodes[triangle][:, [0, 1, 2, 4, 5, 7]])))  # fmt: skip
    else:  # hex8 or hex20
        c = nodes[:, :8]
        wedge = (c[:, 2] == c[:, 3]) & (c[:, 6] == c[:, 7])
        top = (c[:, 4] == c[:, 5]) & (c[:, 5] == c[:, 6]) & (c[:, 6] == c[:, 7])
        tet = (c[:, 2] == c[:, 3]) & top
        pyramid = top & ~tet
        wedge &= ~top
        ordered = np.sort(c, axis=1)
        brick = ~(wedge | top) & np.all(ordered[:, 1:] != ordered[:, :-1], axis=1)
        elements.skip(name, int((~(wedge | top | brick)).sum()))  # another degenerate form
        quadratic = family == "hex20"
        elements.add(family, nodes[brick])
        elements.add("wedge15" if quadratic else "wedge6",
                     nodes[wedge][:, _WEDGE20 if quadratic else _WEDGE8])  # fmt: skip
        elements.add("pyramid13" if quadratic else "pyramid5",
                     nodes[pyramid][:, _PYRAMID20 if quadratic else _PYRAMID8])  # fmt: skip
        elements.add("tet10" if quadratic else "tet4",
                     nodes[tet][:, _TET20 if quadratic else _TET8])  # fmt: skip
