"""Readers for matrices exported by Ansys Mechanical APDL.

Two routes lead from an Ansys model to an :class:`~pymorembs.body.ElasticBody`:

:func:`read_ansys_full`
    The binary ``Jobname.full`` file written by a modal analysis (``WRFULL``), read with
    ``ansys-mapdl-reader`` after a bounds-checked scan of every record the library's C code
    touches. The file holds ``K``, ``M`` (and ``D`` of a damped analysis) over all equations, the
    node and dof label of every equation and the constrained dofs, which become fixed dofs of the
    body. It holds no node coordinates: give them as ``nodes.csv`` or as the model's archive
    (``CDWRITE,DB``, a ``.cdb`` file, read by :mod:`pymorembs.io.ansys_cdb`).
:func:`read_ansys_mmf`
    Matrix Market files written by APDL Math (``*SMAT`` ... ``*EXPORT,...,MMF``) plus the dof
    mapping file written by ``HBMAT`` with ``Mapping = YES``. These matrices are in the solver
    ordering with the constrained dofs removed; that the mapping file lists the equations in the
    same order is proved by the rigid-body check (see the function).

Compressed records: Ansys 19 and later may write records of a binary file "sparsified" (flag byte
= high byte of the second word of the record header, little endian: bit 3 bit-coded sparse, bit 4
windowed sparse, bit 5 zlib, bit 6 single precision or 16-bit integers, bit 7 integers). The scan
decodes the two sparse forms exactly as ``ansys-mapdl-reader``'s ``binary_reader.cpp`` does, for
the records the library decodes too (standard and ``.full`` headers, dof record, nodal
equivalence table, dofs per node, dof information), and refuses what the library would misread:
zlib records, 16-bit integer records, and compressed records in the matrix blocks (which the
library reads raw).

The rigid-body check of the ``ansys-mmf`` equation order: for a body without constraints, ``K``
maps each of the six rigid-body fields to zero
(:meth:`~pymorembs.body.ElasticBody.rigid_body_residuals`); the three translations need no
coordinates, the rotations need the right coordinates. Residuals up to
:data:`RIGID_BODY_TOLERANCE` count as zero. The dof table and coordinates of a ``.full`` body
are proved as every model's are, by the consistency check
(:func:`~pymorembs.preparation.consistency.check_map`); the reader hands over what only the
``.cdb`` tells: an Ansys ``.full`` file of a constrained model has zero couplings between the
constrained and the free dofs, so the nodes that share an element with a constrained node are
the body's ``nodes_near_supports``, whose rows carry the reactions.

Every mistake raises :class:`~pymorembs.errors.UserError` with one line ``file: problem`` or
``file:line: problem``; no exception of ``ansys-mapdl-reader`` escapes.
"""

from __future__ import annotations

import io
import os
import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import scipy.sparse as sp

from pymorembs.body import DIRECTIONS, DofTable, ElasticBody
from pymorembs.errors import UserError, located_error
from pymorembs.io.ansys_cdb import (
    AnsysArchive,
    cdb_solid_blocks,
    cdb_surface_elements,
    read_cdb,
)
from pymorembs.io.checks import make_body, reason
from pymorembs.io.element_surface import attach_surface
from pymorembs.io.fast_text import all_distinct
from pymorembs.io.matrix_market import (
    check_symmetric,
    parse_int,
    read_matrix_market_with_storage,
    read_text_lines,
)
from pymorembs.io.node_files import node_file_kind, read_node_file
from pymorembs.io.solid_mesh import attach_mesh
from pymorembs.sparse_rows import abs_row_sums

__all__ = ["ANSYS_DOF_LABELS", "RIGID_BODY_TOLERANCE", "read_ansys_full", "read_ansys_mmf"]

PathLike = str | os.PathLike[str]

#: Ansys structural dof labels and their direction codes (0..5 = ux uy uz rx ry rz).
ANSYS_DOF_LABELS: dict[str, int] = {"UX": 0, "UY": 1, "UZ": 2, "ROTX": 3, "ROTY": 4, "ROTZ": 5}

#: Largest rigid-body residual ``|K r| / (|K|_inf |r|)`` that counts as zero. Matrices, dof
#: table and coordinates that belong together give 1e-16 .. 1e-9; a wrong equation order or wrong
#: coordinates give 1e-4 and more.
RIGID_BODY_TOLERANCE = 1e-6

#: Ansys dof reference numbers (``fdfull``/``fdresu`` DOF record) and their labels.
_ANSYS_DOF_NUMBERS: dict[int, str] = {
    1: "UX",
    2: "UY",
    3: "UZ",
    4: "ROTX",
    5: "ROTY",
    6: "ROTZ",
    7: "AX",
    8: "AY",
    9: "AZ",
    10: "VX",
    11: "VY",
    12: "VZ",
    19: "PRES",
    20: "TEMP",
    21: "VOLT",
    22: "MAG",
    23: "ENKE",
    24: "ENDS",
    25: "EMF",
    26: "CURR",
    **{26 + k: f"SP0{k}" for k in range(1, 7)},
}
#: Other dof labels Ansys writes into mapping files (not structural).
_OTHER_ANSYS_LABELS = {
    *(_ANSYS_DOF_NUMBERS.values()),
    "TBOT",
    "TE2",
    "TTOP",
    "CONC",
    "HDSP",
    "WARP",
    "PRES",
}.difference(ANSYS_DOF_LABELS)

#: Analysis types (header item ``kan``, the ANTYPE number).
_ANALYSES = {
    0: "a static analysis (ANTYPE,STATIC)",
    1: "a buckling analysis (ANTYPE,BUCKLE)",
    2: "a modal analysis (ANTYPE,MODAL)",
    3: "a harmonic analysis (ANTYPE,HARMIC)",
    4: "a transient analysis (ANTYPE,TRANS)",
    7: "a substructure analysis (ANTYPE,SUBSTR)",
    8: "a spectrum analysis (ANTYPE,SPECTR)",
}
_BUCKLING = 1

_STRUCTURAL = "UX UY UZ ROTX ROTY ROTZ"
_FULL_FILE_TYPE = 4  # item 1 of the standard header of a .full file
_HEADER_WORDS = 100  # length of the standard header record
_VERSION_WORD = 9  # item 10 of the standard header: the release, e.g. "15.0"

# flag bits of a record (high byte of the second header word), as binary_reader.cpp reads them
_BIT_SPARSE = 1 << 3
_WINDOWED = 1 << 4
_ZLIB = 1 << 5
_SHORT = 1 << 6  # 16-bit integers or single precision reals
_INTEGER = 1 << 7
_FLAG_MASK = 0xF8  # the bits the library looks at
_BIT_SPARSE_ITEMS = 32  # a bit-coded record holds at most 32 items (one bit each)


# ============================================================================ .full
def read_ansys_full(
    path: PathLike, nodes: PathLike | None = None, name: str | None = None
) -> ElasticBody:
    """Read a body from an Ansys Mechanical APDL ``Jobname.full`` file.

    Write the file with a modal analysis that stops after assembly (no eigensolution needed)::

        /SOLU
        ANTYPE,MODAL
        MODOPT,LANB,1      ! any eigensolver that uses the sparse assembly
        LUMPM,OFF          ! consistent mass; a lumped-mass .full file cannot be read
        WRFULL,1           ! write Jobname.full and stop
        SOLVE
        FINISH

    and the node coordinates with the archive of the model (read by
    :func:`~pymorembs.io.ansys_cdb.read_cdb`)::

        /PREP7
        CDWRITE,DB,Jobname,cdb

    Apply the displacement constraints (``D``) that belong to the body, usually none; constraint
    equations (``CE``, ``CP``, MPC contact) cannot be read from a ``.full`` file -- use
    :func:`read_ansys_mmf` for such models. Instead of the archive the coordinates may come as
    ``nodes.csv`` (header ``id,x,y,z``), written for instance with::

        *GET,nnode,NODE,0,COUNT
        *CFOPEN,nodes,csv
        *VWRITE
        ('id,x,y,z')
        node = 0
        *DO,i,1,nnode
        node = NDNEXT(node)
        x = NX(node)
        y = NY(node)
        z = NZ(node)
        *VWRITE,node,x,y,z
        %I,%22.15E,%22.15E,%22.15E
        *ENDDO
        *CFCLOS

    Parameters
    ----------
    path : path-like
        The ``.full`` file (symmetric matrices from the sparse (symbolic) assembly, written on a
        little-endian machine; records may be compressed in the sparse forms Ansys 19+ writes).
    nodes : path-like, optional
        ``nodes.csv`` or the Ansys archive (``.cdb``), listing at least every node that has dofs.
        The coordinates are checked with the rigid-body check (module docstring) where the model
        allows it: an unconstrained model, or a constrained one with the element connectivity of
        the archive. Without ``nodes`` all nodes lie at the origin (``has_coordinates`` false):
        frequencies and frequency responses are right, but Buckens frames, rigid-body modes and
        the search for interface nodes by position need coordinates.
    name : str, optional
        Label of the body; default: the file name without extension.

    Returns
    -------
    ElasticBody
        Equations in the order of the file. ``K`` and ``M`` are the full symmetric matrices (the
        file stores one triangle). Dofs constrained in Ansys become the fixed dofs of the body
        (``ElasticBody.fixed``); their rows and columns are zero. A damped modal analysis also
        gives the explicit damping matrix. ``notes`` say how the dof table was built and how the
        coordinates were checked.

    Raises
    ------
    UserError
        The file is missing, truncated, not a ``.full`` file, or holds something pymorembs cannot
        use (non-structural dofs such as ``TEMP``, lumped or unsymmetric matrices, constraint
        equations, no mass matrix, the stress-stiffening matrix of a buckling analysis, records
        ansys-mapdl-reader cannot decode); coordinates that fail the rigid-body check; the
        message is one line starting with the file name.
    """
    path = Path(path)
    info = _scan_full_file(path)
    try:
        from ansys.mapdl.reader import _binary_reader, read_binary
    except ImportError as err:  # pragma: no cover - a declared dependency
        raise located_error(
            path, None, f"reading .full files needs ansys-mapdl-reader ({err})"
        ) from None
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            full = read_binary(path)
            dof_ref, k_upper, m_upper = full.load_km(as_sparse=True, sort=False)
            d_upper = None
            if info.damping is not None:
                pointer, n_terms = info.damping
                rows, cols, values = _binary_reader.read_array(
                    str(path), pointer, n_terms, info.neqn, info.const
                )
                keep = (info.const[rows] > 0) & (info.const[cols] > 0)
                d_upper = sp.csc_matrix(
                    (values[keep], (rows[keep], cols[keep])), shape=(info.neqn, info.neqn)
                )
    except UserError:
        raise
    except Exception as err:  # the reader's own errors (and MemoryError) become one line
        raise located_error(path, None, f"cannot read the .full file: {reason(err)}") from None

    dof_ref = np.asarray(dof_ref)
    if dof_ref.shape != (info.neqn, 2) or k_upper is None or m_upper is None:
        raise located_error(path, None, "ansys-mapdl-reader returned an incomplete model")
    try:
        table = DofTable(dof_ref[:, 0], info.directions)
    except UserError as err:
        raise located_error(path, None, str(err)) from None
    stiffness = _mirror(k_upper, path, "stiffness")
    mass = _mirror(m_upper, path, "mass")
    damping = None if d_upper is None else _mirror(d_upper, path, "damping")
    fixed = np.flatnonzero(info.const < 0)
    _check_no_empty_dofs(stiffness, mass, table, fixed, path)
    geometry = _coordinates(table, nodes, path)
    coordinates_note, near_supports = _supports(table, fixed, geometry)
    notes = [_full_note(path, info, table, fixed.size), coordinates_note]
    body = make_body(
        path,
        node_ids=geometry.node_ids,
        coordinates=geometry.coordinates,
        dofs=table,
        mass=mass,
        stiffness=stiffness,
        damping_matrix=damping,
        fixed=fixed,
        name=path.stem if name is None else name,
        has_coordinates=geometry.source is not None,
        notes=tuple(notes),
        nodes_near_supports=near_supports,
    )
    return _with_mesh(body, geometry)


def _full_note(path: Path, info: _FullInfo, table: DofTable, n_fixed: int) -> str:
    """The note that tells where the dof table of a ``.full`` file came from."""
    release = f"Ansys MAPDL {info.release}, " if info.release else ""
    text = (
        f"dof table: {table.describe()} from the nodal equivalence table and the dof records of "
        f"{path.name} ({release}{_ANALYSES.get(info.analysis, 'analysis type unknown')})"
    )
    if n_fixed:
        text += f"; {n_fixed} dofs constrained in Ansys are fixed dofs"
    if info.decoded:
        text += f"; compressed records decoded: {', '.join(info.decoded)}"
    return text


@dataclass(frozen=True)
class _FullInfo:
    """What :func:`_scan_full_file` learnt about a valid ``.full`` file."""

    neqn: int
    const: np.ndarray  # per equation: dof number, negative if constrained (file order)
    directions: np.ndarray  # per equation: direction code 0..5
    damping: tuple[int, int] | None  # (pointer, number of terms) of the damping matrix
    analysis: int = -1  # header item kan (ANTYPE number)
    release: str = ""  # e.g. "15.0"
    decoded: tuple[str, ...] = ()  # records that were stored compressed, e.g. "dofs per node"


def _scan_full_file(path: Path) -> _FullInfo:
    """Check the structure of a ``.full`` file before the C reader of the library touches it.

    ``ansys-mapdl-reader`` trusts the record lengths and pointers in the file; a truncated or
    corrupt file can crash the interpreter. This walks every record the reader will use (header,
    dof, nodal equivalence and constraint records and the matrix blocks), decodes compressed
    records like the library does and checks lengths, trailers and index ranges.
    """
    try:
        from ansys.mapdl.reader.common import ANSYS_BINARY_FILE_TYPES
        from ansys.mapdl.reader.full import SYMBOLIC_FULL_HEADER_KEYS
    except ImportError as err:  # pragma: no cover - a declared dependency
        raise located_error(
            path, None, f"reading .full files needs ansys-mapdl-reader ({err})"
        ) from None
    words = _map_words(path)
    records = _Records(path, words)

    first = int(words[0]) if words.size else None
    if first != _HEADER_WORDS:
        if words.size and int(words[:1].byteswap()[0]) == _HEADER_WORDS:
            raise located_error(path, None, "big-endian Ansys files are not supported")
        raise located_error(path, None, "not an Ansys binary file (expected a Jobname.full file)")
    header, after = records.read(0, "standard header", expect=_HEADER_WORDS)
    file_type = int(header[0])
    if file_type != _FULL_FILE_TYPE:
        kind = ANSYS_BINARY_FILE_TYPES.get(file_type, f"file of type {file_type}")
        raise located_error(path, None, f"this is an Ansys {kind}, not a .full file")
    release = header[_VERSION_WORD : _VERSION_WORD + 1].astype("<i4").tobytes()[::-1]
    release_text = release.decode("latin-1").strip() if release.isascii() else ""

    values, after = records.read(after, ".full header", limit=4 * _HEADER_WORDS)
    if values.size < 40:
        raise located_error(
            path, None, f".full header has {values.size} words; the file is damaged"
        )
    # the first occurrence of every key; the library's parse_header fails on a low word of a
    # 64-bit pointer that is negative as int32 (struct.error), so the items are read here
    h = {}
    for index, key in enumerate(SYMBOLIC_FULL_HEADER_KEYS[: values.size]):
        h.setdefault(key, int(values[index]))

    def item(key: str) -> int:
        return int(h.get(key, 0))

    def long_item(key: str) -> int:
        return (item(key + "h") << 32) | (item(key + "l") & 0xFFFFFFFF)

    neqn, n_nodes, numdof = item("neqn"), item("nNodes"), item("numdof")
    analysis = item("kan")
    if item("fun04") >= 0:
        raise located_error(path, None, "frontal-assembly .full files are not supported")
    if item("extopt") in (3, 4):
        raise located_error(
            path, None, f"extraction option {item('extopt')} has another file layout"
        )
    if item("keyuns"):
        raise located_error(
            path, None, "the matrices are unsymmetric; pymorembs needs symmetric K and M"
        )
    if item("lumpm"):
        raise located_error(
            path,
            None,
            "lumped mass matrix (LUMPM,ON) cannot be read; write the file with LUMPM,OFF or "
            "export the matrices with *SMAT/*EXPORT,...,MMF (read_ansys_mmf)",
        )
    if item("ncefull") or item("nceGprime"):
        raise located_error(
            path,
            None,
            "the model has constraint equations (CE, CP or MPC contact) that a .full file does "
            "not apply; export the matrices with *SMAT/*EXPORT,...,MMF (read_ansys_mmf)",
        )
    if neqn <= 0 or n_nodes <= 0 or not 0 < numdof <= 32:
        raise located_error(path, None, f"implausible .full header (neqn={neqn}, nodes={n_nodes})")
    end = long_item("ptrEND")
    if end > words.size:
        raise located_error(
            path, None, f"file is truncated: {4 * words.size} bytes, need {4 * end}"
        )
    for key in SYMBOLIC_FULL_HEADER_KEYS:
        if key.startswith("ptr") and key.endswith("h") and not 0 <= long_item(key[:-1]) <= end:
            raise located_error(
                path,
                None,
                f".full header: pointer {key[:-1]} = {long_item(key[:-1])} lies outside the file "
                f"({end} words); the file is damaged",
            )

    curdof, after = records.read(after, "dof record", expect=numdof)
    if np.any((curdof < 1) | (curdof > 32)):
        raise located_error(path, None, "dof record holds unknown dof numbers; the file is damaged")
    back, _ = records.read(after, "nodal equivalence table", limit=n_nodes + words.size)
    if back.size < n_nodes or np.any(back[:n_nodes] <= 0):
        raise located_error(path, None, "nodal equivalence table is damaged")
    if long_item("ptrDOF") <= 0:
        raise located_error(
            path, None, "the .full header has no dof information; the file is damaged"
        )
    ndof, after = records.read(long_item("ptrDOF"), "dofs per node", expect=n_nodes)
    const, _ = records.read(after, "dof information", expect=neqn)
    if np.any((ndof < 1) | (ndof > numdof)) or int(ndof.sum()) != neqn:
        raise located_error(path, None, "dofs per node do not add up to the number of equations")
    if np.unique(back[:n_nodes]).size != n_nodes:
        raise located_error(
            path, None, "nodal equivalence table lists a node twice; the file is damaged"
        )
    const = np.array(const, dtype=np.int32)

    n_stiffness, n_mass = long_item("ntermK"), long_item("ntermM")
    n_damping, damping_pointer = long_item("ntermD"), long_item("ptrDMP")
    if n_stiffness <= 0 or n_mass <= 0:
        raise located_error(path, None, _what_it_holds(neqn, n_stiffness, n_damping, analysis, h))
    if analysis == _BUCKLING:
        raise located_error(
            path,
            None,
            f"the file was written by {_ANALYSES[_BUCKLING]}: its second matrix is the "
            "stress-stiffening matrix, not a mass matrix; write the .full file from a modal "
            "analysis (ANTYPE,MODAL with WRFULL,1)",
        )
    records.matrix(long_item("ptrSTF"), neqn, n_stiffness, "stiffness matrix")
    records.matrix(long_item("ptrMAS"), neqn, n_mass, "mass matrix")
    damping = None
    if n_damping > 0 and damping_pointer > 0:
        records.matrix(damping_pointer, neqn, n_damping, "damping matrix")
        damping = (damping_pointer, n_damping)
    directions = _full_directions(path, np.asarray(curdof), const, np.repeat(back[:n_nodes], ndof))
    return _FullInfo(
        neqn=neqn,
        const=const,
        directions=directions,
        damping=damping,
        analysis=analysis,
        release=release_text,
        decoded=tuple(records.decoded),
    )


def _what_it_holds(
    neqn: int, n_stiffness: int, n_damping: int, analysis: int, header: dict[str, int]
) -> str:
    """The one-line refusal of a ``.full`` file without K or M, naming what it holds."""
    held = []
    if n_stiffness > 0:
        held.append(f"a stiffness matrix ({neqn} equations)")
    if n_damping > 0:
        held.append("a damping matrix")
    pointer = (header.get("ptrRHSh", 0) << 32) | (header.get("ptrRHSl", 0) & 0xFFFFFFFF)
    if pointer > 0:
        held.append("a load vector")
    holds = " and ".join(held) if held else "no matrices"
    missing = "no mass matrix" if n_stiffness > 0 else "neither stiffness nor mass matrix"
    source = _ANALYSES.get(analysis, f"an analysis of type {analysis}")
    return (
        f"the file holds {missing}, only {holds}: it was written by {source}; write the .full "
        "file from a modal analysis (ANTYPE,MODAL with WRFULL,1)"
    )


def _full_directions(
    path: Path, curdof: np.ndarray, const: np.ndarray, node_of: np.ndarray
) -> np.ndarray:
    """Direction code of every equation from the dof record and the per-equation dof numbers.

    ``|const|`` is either the position in the dof record (1-based) or the Ansys dof number itself
    (``UX`` = 1 ... ``ROTZ`` = 6). For structural models both readings agree or only one is
    possible; an ambiguous file is refused rather than guessed.
    """
    number = np.abs(const.astype(np.int64))
    if np.any(number == 0):
        raise located_error(path, None, "dof information has a zero entry; the file is damaged")
    as_position = curdof[number - 1] if number.max() <= curdof.size else None
    as_number = number if np.all(np.isin(number, curdof)) else None
    if as_position is not None and as_number is not None:
        if not np.array_equal(as_position, as_number):
            raise located_error(
                path, None, "cannot tell the dof label of the equations unambiguously"
            )
    labels = as_position if as_position is not None else as_number
    if labels is None:
        raise located_error(
            path, None, "dof information does not match the dof record; file damaged"
        )
    other = np.flatnonzero(labels > 6)
    if other.size:
        names = sorted({_ANSYS_DOF_NUMBERS.get(int(n), f"#{n}") for n in labels[other]})
        first = int(other[0])
        raise located_error(
            path,
            None,
            f"the model has non-structural dofs ({' '.join(names)}; first: node "
            f"{int(node_of[first])}); pymorembs reads {_STRUCTURAL} only",
        )
    return (labels - 1).astype(np.int64)


class _Records:
    """Bounds-checked access to the records ``[n, flags, n words, n]`` of an Ansys file.

    ``n`` is the number of words stored; the flag byte (module docstring) tells how they encode
    the record. The last word repeats ``n`` (Ansys' ``fddesc.inc``).
    """

    def __init__(self, path: Path, words: np.ndarray) -> None:
        self.path = path
        self.words = words
        self.decoded: list[str] = []

    def read(
        self, pointer: int, what: str, expect: int | None = None, limit: int | None = None
    ) -> tuple[np.ndarray, int]:
        """The (decoded) data of the integer record at ``pointer`` and the next record's pointer.

        ``expect`` is the number of items the record must hold, ``limit`` an upper bound of
        that number for records without a known size (checked before anything is allocated).
        """
        words = self.words
        if pointer < 0 or pointer + 2 > words.size:
            raise self._truncated(what)
        stored = int(words[pointer])
        end = pointer + 2 + stored
        if stored < 0 or end >= words.size:
            raise self._truncated(what)
        flags = (int(words[pointer + 1]) >> 24) & 0xFF
        if int(words[end]) != stored or not flags & _INTEGER:
            raise located_error(self.path, None, f"{what}: unexpected record layout (damaged file)")
        if flags & _ZLIB:
            raise located_error(
                self.path,
                None,
                f"{what}: the record is zlib-compressed, which ansys-mapdl-reader cannot read; "
                "write the file without zlib compression (/FCOMP)",
            )
        if flags & _SHORT:
            raise located_error(
                self.path,
                None,
                f"{what}: the record holds 16-bit integers, which ansys-mapdl-reader cannot use",
            )
        raw = np.asarray(words[pointer + 2 : end])
        bound = expect if expect is not None else limit
        if flags & _BIT_SPARSE:
            values = _decode_bit_sparse(raw, bound, lambda why: self._bad_record(what, why))
            self.decoded.append(f"{what} (bit-coded)")
        elif flags & _WINDOWED:
            values = _decode_windowed(raw, bound, lambda why: self._bad_record(what, why))
            self.decoded.append(f"{what} (windowed)")
        else:
            values = raw
            if bound is not None and values.size > bound and expect is None:
                raise self._bad_record(what, f"{values.size} items, at most {bound} expected")
        if expect is not None and values.size != expect:
            raise located_error(
                self.path, None, f"{what}: {values.size} entries, expected {expect}; file damaged"
            )
        return values, end + 1

    def matrix(self, pointer: int, neqn: int, n_terms: int, what: str) -> None:
        """Check the block of one matrix: per equation an index and a value record.

        ``ansys-mapdl-reader`` reads these records raw (no decompression), so they must be
        uncompressed int32 index and float64 value records.
        """
        words = self.words
        extent = 6 * neqn + 3 * n_terms
        if pointer <= 0 or pointer + extent > words.size:
            raise self._truncated(what)
        block = memoryview(np.ascontiguousarray(words[pointer : pointer + extent]))
        starts = np.empty(neqn, dtype=np.int64)
        counts = np.empty(neqn, dtype=np.int64)
        p = 0
        for i in range(neqn):
            n = block[p]
            if not 0 <= n <= neqn or p + 3 * n + 6 > extent:
                raise self._bad(what, i, block, p)
            q = p + n + 3
            if block[q - 1] != n or block[q] != 2 * n or block[q + 2 * n + 2] != 2 * n:
                raise self._bad(what, i, block, p)
            starts[i], counts[i] = p + 2, n
            p = q + 2 * n + 3
        if p != extent:
            raise located_error(self.path, None, f"{what}: term count does not match the header")
        array = np.asarray(block)
        index_flags = (array[starts - 1] >> 24) & _FLAG_MASK
        value_flags = (array[starts + counts + 2] >> 24) & _FLAG_MASK
        odd = np.flatnonzero((index_flags != _INTEGER) | (value_flags != 0))
        if odd.size:
            i = int(odd[0])
            raise self._odd_flags(what, i, int(index_flags[i]) | int(value_flags[i]))
        total = int(counts.sum())
        offsets = np.repeat(starts - (np.cumsum(counts) - counts), counts)
        rows = array[offsets + np.arange(total)]
        if total and (rows.min() < 1 or rows.max() > neqn):
            raise located_error(
                self.path, None, f"{what}: row index out of range; the file is damaged"
            )

    def _truncated(self, what: str) -> UserError:
        return located_error(
            self.path, None, f"file is truncated or damaged (cannot read the {what})"
        )

    def _bad(self, what: str, equation: int, block: memoryview, p: int) -> UserError:
        """A damaged matrix record; compressed flags (if they are the cause) are named."""
        flags = (block[p + 1] >> 24) & _FLAG_MASK if p + 1 < len(block) else _INTEGER
        if flags != _INTEGER:
            return self._odd_flags(what, equation, flags)
        return located_error(
            self.path,
            None,
            f"{what}: damaged record at equation {equation + 1} (truncated or corrupt file)",
        )

    def _odd_flags(self, what: str, equation: int, flags: int) -> UserError:
        """Matrix records that are not plain int32 index / float64 value records."""
        kind = "compressed" if flags & (_BIT_SPARSE | _WINDOWED | _ZLIB) else "unexpected"
        return located_error(
            self.path,
            None,
            f"{what}: {kind} records (first at equation {equation + 1}), which "
            "ansys-mapdl-reader reads as plain int32/float64 records; write the file without "
            "compression (/FCOMP)",
        )

    def _bad_record(self, what: str, why: str) -> UserError:
        return located_error(self.path, None, f"{what}: damaged compressed record ({why})")


def _decode_bit_sparse(raw: np.ndarray, bound: int | None, fail) -> np.ndarray:
    """A bit-coded sparse integer record: ``size, bit code``, then the values whose bit is set.

    Bit ``i`` of the 32-bit code tells whether item ``i`` is stored (else it is 0).
    """
    if raw.size < 2:
        raise fail("shorter than its size and bit code")
    size = int(raw[0])
    if not 0 <= size <= _BIT_SPARSE_ITEMS:
        raise fail(f"bit-coded record of {size} items; at most {_BIT_SPARSE_ITEMS} are possible")
    if bound is not None and size > bound:
        raise fail(f"{size} items, at most {bound} expected")
    stored = ((int(raw[1]) & 0xFFFFFFFF) >> np.arange(size)) & 1 == 1
    count = int(stored.sum())
    if 2 + count > raw.size:
        raise fail(f"the bit code announces {count} values but {raw.size - 2} are stored")
    values = np.zeros(size, dtype=np.int32)
    values[stored] = raw[2 : 2 + count]
    return values


def _decode_windowed(raw: np.ndarray, bound: int | None, fail) -> np.ndarray:
    """A windowed sparse integer record: ``size, number of windows``, then the windows.

    Each window starts with a location ``loc``: ``loc > 0`` is one isolated value at index
    ``loc``; otherwise a window starts at index ``-loc`` and a length ``len`` follows: ``len > 0``
    values, or (``len <= 0``) one value repeated ``max(-len, 1)`` times. Items not covered are 0.
    """
    if raw.size < 2:
        raise fail("shorter than its size and window count")
    size, n_windows = int(raw[0]), int(raw[1])
    if size < 0:
        raise fail(f"negative size {size}")
    if bound is not None and size > bound:
        raise fail(f"{size} items, at most {bound} expected")
    values = np.zeros(size, dtype=np.int32)
    k = 2
    for window in range(max(n_windows, 0)):
        if k >= raw.size:
            raise fail(f"window {window + 1} of {n_windows} is missing")
        location = int(raw[k])
        k += 1
        if location > 0:
            if location >= size or k >= raw.size:
                raise fail(f"isolated value at {location} outside {size} items")
            values[location] = raw[k]
            k += 1
            continue
        if k >= raw.size:
            raise fail(f"window {window + 1} has no length")
        start, length = -location, int(raw[k])
        k += 1
        count = length if length > 0 else max(-length, 1)
        if start + count > size or k + (length if length > 0 else 1) > raw.size:
            raise fail(f"window {window + 1} ({count} items from {start}) overruns the record")
        if length > 0:
            values[start : start + count] = raw[k : k + count]
            k += count
        else:
            values[start : start + count] = raw[k]
            k += 1
    return values


def _map_words(path: Path) -> np.ndarray:
    """The file as little-endian 32-bit words (memory-mapped, read-only)."""
    try:
        size = path.stat().st_size
        if not path.is_file():
            raise IsADirectoryError
        if size < 4:
            if size == 0:
                raise located_error(path, None, "empty file (expected a Jobname.full file)")
            raise located_error(
                path, None, "not an Ansys binary file (expected a Jobname.full file)"
            )
        return np.memmap(path, dtype="<i4", mode="r", shape=(size // 4,))
    except UserError:
        raise
    except FileNotFoundError:
        raise located_error(path, None, "file not found (expected a Jobname.full file)") from None
    except IsADirectoryError:
        raise located_error(path, None, "is a directory, expected a Jobname.full file") from None
    except (OSError, ValueError) as err:
        raise located_error(path, None, f"cannot read: {reason(err)}") from None


def _mirror(upper: sp.spmatrix, path: Path, what: str) -> sp.csr_matrix:
    """The full symmetric matrix ``A + A^T - diag(A)`` from one stored triangle."""
    a = sp.csr_matrix(upper, dtype=float)
    a.sum_duplicates()
    if not np.all(np.isfinite(a.data)):
        raise located_error(path, None, f"{what} matrix has NaN or infinite entries")
    below, above = sp.tril(a, -1), sp.triu(a, 1)
    if below.nnz and above.nnz:
        raise located_error(path, None, f"{what} matrix: both triangles are stored")
    strict = below if below.nnz else above
    full = sp.csr_matrix(sp.diags(a.diagonal()) + strict + strict.T)
    full.eliminate_zeros()
    full.sort_indices()
    return full


# ============================================================================ Matrix Market
def read_ansys_mmf(
    stiffness: PathLike,
    mass: PathLike,
    mapping: PathLike,
    damping: PathLike | None = None,
    nodes: PathLike | None = None,
    name: str | None = None,
) -> ElasticBody:
    """Read a body from Matrix Market files exported by APDL Math plus the dof mapping file.

    After a modal analysis of the *unconstrained* body that wrote ``Jobname.full`` (``WRFULL,1``,
    see :func:`read_ansys_full`), export the matrices in the solver ordering with::

        *SMAT,MatK,D,IMPORT,FULL,Jobname.full,STIFF
        *SMAT,MatM,D,IMPORT,FULL,Jobname.full,MASS
        *EXPORT,MatK,MMF,K.mtx
        *EXPORT,MatM,MMF,M.mtx
        ! optional damping matrix of a damped modal analysis:
        ! *SMAT,MatD,D,IMPORT,FULL,Jobname.full,DAMP
        ! *EXPORT,MatD,MMF,D.mtx

    and the dof mapping of these equations with ``HBMAT`` (the Harwell-Boeing file itself is not
    needed)::

        /AUX2
        FILE,Jobname,full
        HBMAT,model,txt,,ASCII,STIFF,NO,YES   ! Mapping = YES writes model.mapping
        FINISH

    plus the coordinates (``CDWRITE,DB,Jobname,cdb`` in ``/PREP7``, or ``nodes.csv``). Couplings
    and constraint equations (``CP``, ``CE``, rigid MPC contact) are applied in these matrices.

    Ansys documents neither that ``HBMAT`` numbers the equations as ``*SMAT`` does nor how it
    treats constrained dofs, and APDL Math cannot export its own mapping vector (``NOD2BCS``).
    The reader therefore proves the equation order with the rigid-body check: ``K`` of a body
    without constraints to ground maps the three rigid translations (which need no
    coordinates) and, with coordinates, the three rotations to zero; a residual above
    :data:`RIGID_BODY_TOLERANCE` refuses the files. This requires the export of the free body
    (constrain it later with ``fixed.csv``); a constrained model can be read from its ``.full``
    file instead. Equations that have only a diagonal stiffness entry and no mass or damping (the
    way Ansys keeps a constrained dof in a ``.full`` file) become fixed dofs.

    Mapping file layout (``Fname.mapping``, as HBMAT writes it): a header line
    ``Matrix Eqn   Node   DOF``, then one row per equation, ``equation node label`` in
    columns of 14, 14 and 8 characters, e.g. ``             1             1    UX``. The reader
    accepts any blank- or comma-separated form: equation numbers count from 1 and must cover
    ``1 .. n`` exactly once (any order); labels are ``UX UY UZ ROTX ROTY ROTZ`` (any case).
    Blank lines and lines starting with ``!``, ``#`` or ``%`` are ignored.

    Parameters
    ----------
    stiffness, mass : path-like
        Matrix Market files of ``K`` and ``M`` (``coordinate`` or ``array``, ``general`` or
        ``symmetric`` storage with one triangle); square, of the size of the mapping, finite and
        symmetric to :data:`~pymorembs.io.matrix_market.SYMMETRY_TOLERANCE`.
    mapping : path-like
        The ``.mapping`` file.
    damping : path-like, optional
        Matrix Market file of an explicit viscous damping matrix.
    nodes : path-like, optional
        ``nodes.csv`` (header ``id,x,y,z``) or the Ansys archive (``.cdb``) listing every node of
        the mapping. Without it all nodes lie at the origin and only the translations are
        checked.
    name : str, optional
        Label of the body; default: the name of the mapping file without extension.

    Returns
    -------
    ElasticBody
        Equations in the order of the matrices (equation ``i`` is mapping row ``i``); the
        consistency check proves the map (``pymorembs info``: ``dof map``).

    Raises
    ------
    UserError
        A malformed, non-symmetric or non-finite matrix, matrices of different sizes, a mapping
        with the wrong number of rows, a repeated equation or (node, dof), an unknown or
        non-structural dof label, an equation order the rigid-body check does not prove; the
        message is one line ``file:line: problem``.
    """
    k_path, m_path, map_path = Path(stiffness), Path(mass), Path(mapping)
    table = _read_mapping(map_path)
    n = len(table)
    k_matrix = _read_mmf_matrix(k_path, n, map_path)
    m_matrix = _read_mmf_matrix(m_path, n, map_path)
    d_matrix = None if damping is None else _read_mmf_matrix(Path(damping), n, map_path)
    fixed = _lone_diagonals(k_matrix, m_matrix, d_matrix)
    _check_no_empty_dofs(k_matrix, m_matrix, table, fixed, k_path)
    geometry = _coordinates(table, nodes, map_path)
    notes = [f"dof table: {table.describe()} in the order of the mapping file {map_path.name}"]
    if fixed.size:
        notes.append(
            f"{fixed.size} equations with only a diagonal stiffness entry and no mass (Ansys' "
            "form of a constrained dof) are fixed dofs"
        )
    if geometry.source is None:
        notes.append("no coordinates (nodes not given): all nodes lie at the origin")
    else:
        notes.append(f"coordinates from {geometry.source.name}")
    body = make_body(
        k_path,
        node_ids=geometry.node_ids,
        coordinates=geometry.coordinates,
        dofs=table,
        mass=m_matrix,
        stiffness=k_matrix,
        damping_matrix=d_matrix,
        fixed=fixed,
        name=map_path.stem if name is None else name,
        has_coordinates=geometry.source is not None,
        notes=tuple(notes),
        # the export of a free body: no support, every row is judged (lone diagonals: unknown)
        nodes_near_supports=None if fixed.size else np.zeros(0, dtype=np.int64),
    )
    _refuse_unproved_order(body, map_path, geometry)
    return _with_mesh(body, geometry)


def _lone_diagonals(
    stiffness: sp.csr_matrix, mass: sp.csr_matrix, damping: sp.csr_matrix | None
) -> np.ndarray:
    """Equations with a diagonal stiffness entry, no other stiffness term and no mass/damping."""
    k = sp.csr_matrix(stiffness)
    k.sum_duplicates()  # (no copy if canonical)
    alone = np.zeros(k.shape[0], dtype=bool)
    single = np.flatnonzero(np.diff(k.indptr) == 1)  # rows of one entry: is it the diagonal?
    first = k.indptr[single]
    alone[single] = (k.indices[first] == single) & (k.data[first] != 0)
    for matrix in (mass, damping):
        if matrix is not None:
            alone &= np.diff(sp.csr_matrix(matrix).indptr) == 0
    return np.flatnonzero(alone)


def _refuse_unproved_order(body: ElasticBody, mapping: Path, geometry: _Geometry) -> None:
    """Refuse an MMF export whose equation order the rigid-body check does not prove (the
    mapping is of other matrices, or the model is constrained). The proof of a map that fits,
    with its note, is the consistency check's
    (:func:`~pymorembs.preparation.consistency.check_map`), as for every model."""
    residuals = body.rigid_body_residuals()
    names = _FIELD_NAMES
    checked = range(6) if body.has_coordinates else range(3)
    present = [j for j in checked if np.isfinite(residuals[j])]
    if not present:
        raise located_error(
            mapping,
            None,
            "the equation order cannot be proved: the model has no translational dofs"
            + ("" if body.has_coordinates else " and no coordinates are given (nodes)"),
        )
    worst = max(present, key=lambda j: residuals[j])
    largest = float(residuals[worst])
    if largest > RIGID_BODY_TOLERANCE:
        if worst < 3:
            why = (
                "the mapping does not list the equations of these matrices, or the model is "
                "constrained; export the matrices of the free body (no D, CP or CE to ground) or "
                "read the .full file (format ansys-full)"
            )
        else:
            why = (
                f"the node order of the mapping or the coordinates of {geometry.source} do not "
                "belong to these matrices"
            )
        raise located_error(
            mapping,
            None,
            f"the equation order is not proved: K maps the rigid-body {names[worst]} to a "
            f"residual of {largest:.1e} (at most {RIGID_BODY_TOLERANCE:g} for a free body); {why}",
        )


def _read_mmf_matrix(path: Path, n: int, mapping: Path) -> sp.csr_matrix:
    """A symmetric Matrix Market matrix of the size given by the mapping file (a file with
    symmetric storage is mirrored exactly and needs no symmetry check)."""
    matrix, mirrored = read_matrix_market_with_storage(path)
    if matrix.shape[0] != n:
        size = matrix.shape[0]
        raise located_error(
            path, None, f"matrix is {size} x {size} but {mapping} maps {n} equations"
        )
    if not mirrored:
        check_symmetric(matrix, str(path))
    return matrix


def _read_mapping(path: Path) -> DofTable:
    """Dof table from an Ansys ``.mapping`` file (layout in :func:`read_ansys_mmf`)."""
    fast = _read_mapping_fast(path)
    if fast is not None:
        return fast
    lines = read_text_lines(path, "an Ansys dof mapping file")
    equations: dict[int, tuple[int, int, int]] = {}  # equation -> (node, code, line)
    dofs: dict[tuple[int, int], int] = {}  # (node, code) -> line
    started = False
    for number, text in enumerate(lines, start=1):
        stripped = text.strip()
        if not stripped or stripped[0] in "!#%":
            continue
        words = stripped.replace(",", " ").split()
        if not words or not words[0].lstrip("+-").isdigit():
            if started:
                raise located_error(path, number, f"expected 'equation node dof', got {stripped!r}")
            continue  # a header line before the first equation
        started = True
        if len(words) != 3:
            raise located_error(
                path, number, f"{len(words)} fields, expected 3 (equation node dof)"
            )
        equation = parse_int(words[0], path, number, "equation number", minimum=1)
        node = parse_int(words[1], path, number, "node number")
        code = _ansys_label(words[2], path, number)
        if equation in equations:
            first = equations[equation][2]
            raise located_error(
                path, number, f"equation {equation} is listed twice (first on line {first})"
            )
        if (node, code) in dofs:
            label = f"{node}:{words[2].upper()}"
            raise located_error(
                path, number, f"dof {label} is listed twice (first on line {dofs[node, code]})"
            )
        equations[equation] = (node, code, number)
        dofs[node, code] = number
    if not equations:
        raise located_error(path, None, "no equation rows (expected lines 'equation node dof')")
    n = len(equations)
    if max(equations) != n:
        missing = min(set(range(1, n + 1)).difference(equations))
        raise located_error(
            path, None, f"equation {missing} is missing (the rows must number equations 1..{n})"
        )
    ordered = [equations[k] for k in range(1, n + 1)]
    return DofTable(
        np.array([node for node, _, _ in ordered], dtype=np.int64),
        np.array([code for _, code, _ in ordered], dtype=np.int64),
    )


#: Label field of the mapping fast path; a label of this length or longer may have been cut by
#: NumPy and goes to the strict pass.
_LABEL_WIDTH = 8


def _read_mapping_fast(path: Path) -> DofTable | None:
    """The dof table of a plain mapping file parsed by NumPy's ``loadtxt``, or None to leave
    the file to the line-by-line pass (which names the bad line).

    Plain: ASCII (no other bytes reach NumPy's parser), no comment lines, no commas, at most one
    header line, three fields per row, known labels, equations ``1 .. n`` once each and no
    (node, dof) twice.
    """
    try:
        data = path.read_bytes()
    except OSError:
        return None
    if not data.isascii() or any(mark in data for mark in (b"!", b"#", b"%", b",", b"\x00")):
        return None
    first, _, rest = data.partition(b"\n")
    words = first.split()
    header = not words or not words[0].lstrip(b"+-").isdigit()
    if header:
        second = rest.lstrip().split(None, 1)
        if not second or not second[0].lstrip(b"+-").isdigit():
            return None  # blank lines or more header lines: the strict pass decides
    dtype = [("equation", np.int64), ("node", np.int64), ("label", f"U{_LABEL_WIDTH}")]
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # "input contained no data"
            rows = np.loadtxt(
                io.BytesIO(data), dtype=dtype, skiprows=int(header), comments=None, ndmin=1
            )
    except (ValueError, OverflowError):
        return None
    n = rows.size
    if n == 0 or np.max(np.strings.str_len(rows["label"])) >= _LABEL_WIDTH:
        return None
    labels, inverse = np.unique(rows["label"], return_inverse=True)  # upper case: per label
    codes = [ANSYS_DOF_LABELS.get(str(label).upper()) for label in labels]
    if None in codes:
        return None
    code = np.asarray(codes, dtype=np.int64)[inverse.reshape(-1)]
    equation, node = rows["equation"], rows["node"]
    if equation.min() < 1 or equation.max() != n or np.max(np.abs(node)) >= 2**59:
        return None
    if np.any(np.bincount(equation - 1, minlength=n) != 1):
        return None  # an equation twice (and another missing)
    order = np.empty(n, dtype=np.int64)
    order[equation - 1] = np.arange(n)
    node, code = node[order], code[order]
    if not all_distinct(node * 8 + code):
        return None  # a (node, dof) twice
    return DofTable(node, code)


def _ansys_label(text: str, path: Path, line: int) -> int:
    """Direction code of an Ansys dof label."""
    label = text.strip().upper()
    code = ANSYS_DOF_LABELS.get(label)
    if code is not None:
        return code
    if label in _OTHER_ANSYS_LABELS:
        raise located_error(
            path, line, f"dof {label} is not structural; pymorembs reads {_STRUCTURAL}"
        )
    raise located_error(path, line, f"unknown dof label {text!r}, expected one of {_STRUCTURAL}")


# ============================================================================ coordinates
_FIELD_NAMES = (
    "translation in x",
    "translation in y",
    "translation in z",
    "rotation about x",
    "rotation about y",
    "rotation about z",
)


@dataclass(frozen=True, eq=False)
class _Geometry:
    """Nodes of a body and where their coordinates came from."""

    node_ids: np.ndarray
    coordinates: np.ndarray
    source: Path | None = None  # nodes.csv or the archive; None: all nodes at the origin
    archive: AnsysArchive | None = None


def _coordinates(table: DofTable, nodes: PathLike | None, source: Path) -> _Geometry:
    """Node ids and coordinates from an Ansys archive or another node file (``nodes.csv``, an
    Abaqus/CalculiX deck, Nastran bulk data), or all at the origin."""
    if nodes is None:
        node_ids, coordinates = _node_table(table, None, source)
        return _Geometry(node_ids, coordinates)
    path = Path(nodes)
    if not path.is_file() or node_file_kind(path) != "ansys":
        node_ids, coordinates = _node_table(table, path, source)
        return _Geometry(node_ids, coordinates, path)
    archive = read_cdb(path)
    missing = np.unique(table.nodes[~np.isin(table.nodes, archive.node_ids)])
    if missing.size:
        more = f" and {missing.size - 1} more" if missing.size > 1 else ""
        raise located_error(
            path, None, f"node {int(missing[0])}{more} of {source} is not in the NBLOCK"
        )
    rotated = np.isin(archive.node_ids, table.nodes) & np.any(archive.angles != 0.0, axis=1)
    if rotated.any():
        k = int(np.flatnonzero(rotated)[0])
        raise located_error(
            path,
            None,
            f"node {int(archive.node_ids[k])} has a rotated nodal coordinate system (angles "
            f"{', '.join(f'{a:g}' for a in archive.angles[k])} degrees); Ansys writes the dofs "
            "of such nodes along the rotated axes, pymorembs reads global directions",
        )
    return _Geometry(archive.node_ids, archive.coordinates, path, archive)


def _supports(
    table: DofTable, fixed: np.ndarray, geometry: _Geometry
) -> tuple[str, np.ndarray | None]:
    """The note on the coordinates of a ``.full`` body and what only the archive tells of its
    supports: the ids of the constrained nodes and of the nodes that share an element with one
    (``ElasticBody.nodes_near_supports``; Ansys removes their couplings, so their rows carry
    the reactions), empty for a free body; None where no elements name them. The consistency
    check proves the coordinates with them (module docstring)."""
    if geometry.source is None:
        return "no coordinates (nodes not given): all nodes lie at the origin", None
    note = f"coordinates from {geometry.source.name}"
    if not fixed.size:
        return note, np.zeros(0, dtype=np.int64)
    archive = geometry.archive
    if archive is None or not archive.has_elements:
        return (
            f"{note}; the model has constrained dofs and no element connectivity, so the rows "
            "next to the supports are judged by distance (give the .cdb archive to name them)",
            None,
        )
    return note, archive.neighbours(table.nodes[fixed])


def _with_mesh(body: ElasticBody, geometry: _Geometry) -> ElasticBody:
    """The body with the surface of every element of its archive, its node components (as node
    sets) and its solid elements (or a note why it has none)."""
    if geometry.archive is None or geometry.source is None:
        return body
    body = attach_surface(body, cdb_surface_elements(geometry.archive))
    body = body.with_node_sets(geometry.archive.node_components)
    return attach_mesh(body, cdb_solid_blocks(geometry.archive, geometry.source))


# ============================================================================ shared helpers
def _node_table(
    table: DofTable, nodes: PathLike | None, source: Path
) -> tuple[np.ndarray, np.ndarray]:
    """Node ids and coordinates: from a node file (:func:`pymorembs.io.node_files.
    read_node_file`) or, without it, the dof nodes at the origin."""
    if nodes is None:
        _, first = np.unique(table.nodes, return_index=True)
        node_ids = table.nodes[np.sort(first)]
        return node_ids, np.zeros((node_ids.size, 3))
    nodes_path = Path(nodes)
    node_file = read_node_file(nodes_path)
    node_ids, coordinates = node_file.ids, node_file.coordinates
    missing = np.unique(table.nodes[~np.isin(table.nodes, node_ids)])
    if missing.size:
        more = f" and {missing.size - 1} more" if missing.size > 1 else ""
        raise located_error(
            nodes_path, None, f"node {int(missing[0])}{more} of {source} is not listed"
        )
    return node_ids, coordinates


def _check_no_empty_dofs(
    stiffness: sp.csr_matrix,
    mass: sp.csr_matrix,
    table: DofTable,
    fixed: np.ndarray,
    where: Path,
) -> None:
    """Refuse equations with neither stiffness nor mass (e.g. rotations of solid-element nodes)."""
    empty = ~(_rows_with_entries(stiffness) | _rows_with_entries(mass))
    empty[np.asarray(fixed, dtype=np.int64)] = False
    bad = np.flatnonzero(empty)
    if bad.size:
        more = f" (and {bad.size - 1} more)" if bad.size > 1 else ""
        first = int(bad[0])
        raise located_error(
            where,
            None,
            f"equation {first + 1} ({table.nodes[first]}:{DIRECTIONS[table.directions[first]]})"
            f"{more} has neither stiffness nor mass; remove such dofs from the export",
        )


def _rows_with_entries(matrix: sp.csr_matrix) -> np.ndarray:
    """Which rows of a CSR matrix hold a non-zero (or NaN) value, from the sums of the absolute
    values (zero only for a row of zeros; no temporary of the matrix's size)."""
    return ~(abs_row_sums(matrix) == 0)
