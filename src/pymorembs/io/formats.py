"""Which reader reads a model file: format detection and one entry point for every format.

:func:`read_body` reads a body in any supported format; :func:`detect_format` tells the format of a
file from its content (the file name is only a hint for the error message). The formats
(:data:`FORMATS`) and what FE program writes them:

``native``
    The HDF5 file of :mod:`pymorembs.io.native` (``pymorembs`` writes it).
``matrix-market``
    ``K.mtx``, ``M.mtx`` plus CSV tables (:mod:`pymorembs.io.matrix_market`).
``ansys-full``
    The Ansys Mechanical APDL ``.full`` file of a modal analysis (:mod:`pymorembs.io.ansys`).
``ansys-mmf``
    Matrix Market files exported by APDL Math ``*EXPORT,...,MMF`` with the mapping file of
    ``*SMAT,...,FULL`` (:mod:`pymorembs.io.ansys`).
``abaqus``
    ``*MATRIX GENERATE`` + ``*MATRIX OUTPUT`` text files ``jobname_STIFn.mtx``,
    ``jobname_MASSn.mtx`` (:mod:`pymorembs.io.abaqus`).
``nastran-dmig``
    DMIG cards of a punch file written by ``PARAM,EXTOUT,DMIGPCH``
    (:mod:`pymorembs.io.nastran_dmig`).
``nastran-op4``
    OUTPUT4 files, ASCII or binary (:mod:`pymorembs.io.nastran_op4`).
``nastran-op2``
    OUTPUT2 files with matrices and their dof table (:mod:`pymorembs.io.nastran_op2`).
``abaqus-substructure``
    The ``.mtx`` file of ``*SUBSTRUCTURE MATRIX OUTPUT`` (``*USER ELEMENT`` with ``*MATRIX``
    blocks; :mod:`pymorembs.io.abaqus_substructure`).
``matlab``
    MATLAB ``.mat`` files (v5 and v7.3) with ``M``, ``K`` and optionally ``D``, ``B``, ``C``
    (:mod:`pymorembs.io.matlab`).
``calculix``
    The ``job.sti``, ``job.mas`` and ``job.dof`` files of a CalculiX ``*FREQUENCY,
    SOLVER=MATRIXSTORAGE`` step, with the input deck ``job.inp`` (:mod:`pymorembs.io.calculix`):
    ``job.sti`` is given, the others are found beside it.

Compressed files (gzip, bzip2, xz; :mod:`pymorembs.io.compressed`) are read as the file they
hold, every option of every format: the detection looks at the decompressed content and at the
name without the ``.gz``/``.bz2``/``.xz`` suffix, and each reader gets a decompressed copy.

Detection rules (:func:`detect_format`), applied to the first bytes of the file in this order:

1. a directory holding ``K.mtx`` -> ``matrix-market``;
2. the HDF5 signature ``\\x89HDF\\r\\n\\x1a\\n`` at offset 0, 512, 1024, ... -> ``native``;
3. an Ansys binary file: the first Fortran record holds 100 words (int32 ``100`` at offset 0,
   either byte order) and the file number at offset 8 is 4 -> ``ansys-full`` (another file number,
   e.g. 12 for a ``.rst`` result file, is an error naming the Ansys file type);
4. a binary OUTPUT4 header record: int32 ``24`` at offsets 0 and 28 (or ``48`` at 0 and 52) with
   a printable matrix name -> ``nastran-op4``;
5. first line ``%%MatrixMarket ...`` -> ``matrix-market`` (:func:`read_body` turns it into
   ``ansys-mmf`` when a ``mapping`` file is given);
6. first line of an ASCII OUTPUT4 file: four 8-character integers (columns, rows, form, type), the
   matrix name and a Fortran format such as ``1P,3E23.16`` -> ``nastran-op4``;
7. a line starting with ``DMIG`` (small, large ``DMIG*`` or free field ``DMIG,``) in the first
   16 MB -> ``nastran-dmig``;
8. an Abaqus ``*USER ELEMENT`` or ``*MATRIX, TYPE=`` keyword line -> ``abaqus-substructure``;
9. the header lines of a results punch (``$TITLE``, ``$EIGENVECTOR``, ...) or Nastran bulk data
   cards (``GRID``, ``EXTRN``, ``ASET``, ``DTI``, ``BEGIN SUPER`` ...) -> ``nastran-dmig``, whose
   reader then says what the file holds instead of DMIG matrices;
10. a file named ``.sti`` or ``.mas`` whose first data line holds 3 blank-separated numbers
    (``row column value``), or one named ``.dof`` whose first line is ``node.direction`` ->
    ``calculix`` (the reader asks for the ``.sti`` if given another of the files);
11. the first data line (blank lines and ``**`` comments skipped) holds 5 comma-separated numbers
    (``node, dof, node, dof, value``) or 3 numbers (``row, column, value``) -> ``abaqus``.

Before rule 2, a MATLAB header (``MATLAB 5.0 MAT-file`` for v5 to v7, ``MATLAB 7.3 MAT-file`` or
``MATLAB 7.0 MAT-file`` for the HDF5-based v7.3) -> ``matlab``; after it, the OP2 label
``NASTRAN FORT TAPE ID CODE`` in the first 512 bytes -> ``nastran-op2``.

Anything else is a :class:`~pymorembs.errors.UserError`
``path: cannot tell the file format; give --format (format= in Python; one of ...)``.

The helpers the readers share (reading a text file, the checked assembly of a symmetric matrix
from entries) are in :mod:`pymorembs.io.reader_support`, so that no reader imports this module.
"""

from __future__ import annotations

import importlib
import os
import re
import struct
from dataclasses import replace
from pathlib import Path
from typing import Any, BinaryIO

from pymorembs.body import ElasticBody
from pymorembs.errors import UserError
from pymorembs.io.compressed import (
    DECOMPRESSION_ERRORS,
    PlainCopies,
    compression,
    damaged_file_error,
    open_plain,
    plain_path,
)
from pymorembs.io.line_blocks import UTF8_BOM
from pymorembs.io.matrix_market import encoding_note

__all__ = [
    "FORMATS",
    "detect_format",
    "model_files",
    "read_body",
]

PathLike = str | os.PathLike[str]

#: Every input format :func:`read_body` reads.
FORMATS: tuple[str, ...] = (
    "native",
    "matrix-market",
    "ansys-full",
    "ansys-mmf",
    "abaqus",
    "abaqus-substructure",
    "nastran-dmig",
    "nastran-op4",
    "nastran-op2",
    "matlab",
    "calculix",
)

#: Options of :func:`read_body` each format takes (``format`` itself aside).
_OPTIONS: dict[str, frozenset[str]] = {
    "native": frozenset({"file", "constraints", "fixed", "name"}),
    "matrix-market": frozenset(
        {"file", "stiffness", "mass", "damping", "dofs", "nodes", "constraints", "fixed", "name"}
    ),
    "ansys-full": frozenset({"file", "nodes", "constraints", "fixed", "name"}),
    "ansys-mmf": frozenset(
        {"stiffness", "mass", "mapping", "damping", "nodes", "constraints", "fixed", "name"}
    ),
    "abaqus": frozenset(
        {"stiffness", "mass", "damping", "dofs", "inp", "nodes", "constraints", "fixed", "name"}
    ),
    "abaqus-substructure": frozenset({"file", "inp", "nodes", "constraints", "fixed", "name"}),
    "nastran-dmig": frozenset(
        {
            "file",
            "damping",
            "nodes",
            "stiffness_name",
            "mass_name",
            "damping_name",
            "constraints",
            "fixed",
            "name",
        }
    ),
    "nastran-op4": frozenset(
        {
            "file",
            "damping",
            "dofs",
            "nodes",
            "stiffness_name",
            "mass_name",
            "damping_name",
            "constraints",
            "fixed",
            "name",
        }
    ),
    "nastran-op2": frozenset(
        {
            "file",
            "nodes",
            "stiffness_name",
            "mass_name",
            "damping_name",
            "constraints",
            "fixed",
            "name",
        }
    ),
    "matlab": frozenset(
        {
            "file",
            "dofs",
            "nodes",
            "stiffness_name",
            "mass_name",
            "damping_name",
            "constraints",
            "fixed",
            "name",
        }
    ),
    "calculix": frozenset(
        {"file", "stiffness", "mass", "dofs", "inp", "nodes", "constraints", "fixed", "name"}
    ),
}
#: The options that name files (a compressed one is read through a plain copy); ``damping``
#: names a file only in the formats of :data:`_DAMPING_FILES`.
_FILE_OPTIONS = ("file", "stiffness", "mass", "dofs", "nodes", "constraints", "fixed", "mapping")
_DAMPING_FILES = frozenset({"matrix-market", "ansys-mmf", "abaqus"})

#: What each format needs, as a readable hint for the "missing" error.
_NEEDS: dict[str, str] = {
    "native": "file (the .h5 file)",
    "matrix-market": "stiffness and mass (the .mtx files), or file (a directory holding K.mtx)",
    "ansys-full": "file (the .full file)",
    "ansys-mmf": "stiffness, mass (the exported .mtx files) and mapping (the mapping file)",
    "abaqus": "stiffness and mass (the jobname_STIFn.mtx and jobname_MASSn.mtx files)",
    "abaqus-substructure": "file (the .mtx file of *SUBSTRUCTURE MATRIX OUTPUT)",
    "nastran-dmig": "file (the .pch punch file)",
    "nastran-op4": "file (the .op4 file)",
    "nastran-op2": "file (the .op2 file)",
    "matlab": "file (the .mat file)",
    "calculix": "file (the job.sti of *FREQUENCY, SOLVER=MATRIXSTORAGE)",
}

_HDF5_SIGNATURE = b"\x89HDF\r\n\x1a\n"
_ANSYS_FILE_TYPES = {
    2: "element matrix file (.emat)",
    3: "element saved data file (.esav)",
    8: "substructure matrices file (.sub)",
    9: "modal results file (.mode)",
    10: "reduced displacement file (.rdsp)",
    12: "result file (.rst)",
    16: "database file (.db)",
    45: "component mode synthesis file (.cms)",
}
_DMIG_LINE = re.compile(rb"(?im)^DMIG[ *,]")
#: Header lines of a results punch (eigenvectors, displacements, ...): a punch without matrices.
_PUNCH_RESULTS = re.compile(rb"(?m)^\$(TITLE|SUBTITLE|LABEL|EIGENVECTOR|DISPLACEMENTS)\b")
#: Cards of Nastran bulk data (the EXTBULK/ASMBULK punch of a superelement, a .bdf/.dat deck).
_BULK_CARD = re.compile(
    rb"(?im)^(GRID\*?|CORD2[RCS]\*?|EXTRN|SEBULK|SECONCT|ASET1?|QSET1?|BSET1?|SPOINT|DTI|"
    rb"BEGIN\s+(BULK|SUPER))[ ,*\t\r\n]"
)
#: Keyword lines of an Abaqus substructure matrix file (*SUBSTRUCTURE MATRIX OUTPUT).
_SUBSTRUCTURE = re.compile(rb"(?im)^\s*\*(USER\s+ELEMENT|MATRIX\s*,\s*TYPE\s*=)")
#: The text header of a MAT-file: "MATLAB 5.0 MAT-file" (v5 to v7), "MATLAB 7.3 MAT-file" (HDF5),
#: and "MATLAB 7.0 MAT-file" of the HDF5 files written by MATLAB 7.4 (scipy's test data).
_MATLAB_HEADER = re.compile(rb"MATLAB \d+\.\d+ MAT-file")
_OP2_LABEL = b"NASTRAN FORT TAPE ID CODE"
_OP4_FORMAT = re.compile(r"\d+\s*[ED]\s*\d+\.\d+", re.IGNORECASE)
_HEAD_BYTES = 1 << 16
_DMIG_SCAN_BYTES = 16 << 20
_EXTENSION_HINTS = {
    ".h5": "native",
    ".hdf5": "native",
    ".mtx": "matrix-market or abaqus",
    ".full": "ansys-full",
    ".pch": "nastran-dmig",
    ".bdf": "nastran-dmig",
    ".dat": "nastran-dmig",
    ".op4": "nastran-op4",
    ".op2": "nastran-op2",
    ".mat": "matlab",
    ".f06": "nastran-dmig",
    ".sti": "calculix",
    ".mas": "calculix",
    ".dof": "calculix",
}
_CALCULIX_MATRIX = (".sti", ".mas")
_COMPRESSION_SUFFIXES = ("", ".gz", ".bz2", ".xz")
_CALCULIX_DOF = re.compile(r"\s*\d+\.\d+\s*")


# ============================================================================ detection
def detect_format(path: PathLike) -> str:
    """The format of a model file (one of :data:`FORMATS`), told from its content.

    Parameters
    ----------
    path : path-like
        The model file (for ``native``, ``ansys-full``, ``nastran-dmig``, ``nastran-op4``), the
        stiffness file (``matrix-market``, ``abaqus``, ``calculix``) or a directory holding
        ``K.mtx``; a compressed file (gzip, bzip2, xz) by its decompressed content and its name
        without the compression suffix.

    Returns
    -------
    str
        The format name. A Matrix Market file is ``"matrix-market"``; whether it is an Ansys
        export (``"ansys-mmf"``) depends on a mapping file and is decided by :func:`read_body`.

    Raises
    ------
    UserError
        The file does not exist or its content matches no format (rules in the module docstring).
    """
    path = Path(path)
    if path.is_dir():
        if any((path / f"K.mtx{suffix}").is_file() for suffix in _COMPRESSION_SUFFIXES):
            return "matrix-market"
        raise UserError(
            f"{path}: a directory without K.mtx; cannot tell the file format; {_give_format()}"
        )
    plain = plain_path(path) if compression(path) is not None else path
    try:
        with open_plain(path) as f:
            try:
                head = f.read(_HEAD_BYTES)
                found = _detect_head(path, head, plain.suffix.lower())
                if found is None and len(head) == _HEAD_BYTES:
                    found = _scan_for_dmig(f, head)
            except DECOMPRESSION_ERRORS as err:
                if plain is path:
                    raise
                raise damaged_file_error(path, err) from None
    except FileNotFoundError:
        raise UserError(f"{path}: file not found") from None
    except OSError as err:
        raise UserError(f"{path}: cannot read: {err.strerror or err}") from None
    if found is not None:
        return found
    if encoding_note(head):
        raise UserError(f"{path}: the file is UTF-16 encoded; save it as UTF-8 or ASCII text")
    raise UserError(f"{path}: cannot tell the file format{_hint(plain, head)}; {_give_format()}")


def _give_format() -> str:
    """The remedy of an unknown format, for the command line and for Python."""
    return f"give --format (format= in Python; one of {', '.join(FORMATS)})"


def _hint(path: Path, head: bytes) -> str:
    """A parenthesised remark for the "cannot tell" error."""
    if not head:
        return " (the file is empty)"
    first = _first_content_line(head.decode("latin-1"))
    if first is not None and first.lstrip().startswith("*") and not first.lstrip().startswith("**"):
        if path.with_suffix(".sti").is_file():
            return (
                f" (it looks like the input deck of a CalculiX export; give its stiffness file "
                f"{path.with_suffix('.sti').name}, beside which the deck, .mas and .dof are found)"
            )
        return (
            " (it looks like an Abaqus input file; give it as the inp option next to the "
            "*MATRIX OUTPUT files jobname_STIFn.mtx and jobname_MASSn.mtx)"
        )
    if path.suffix.lower() == ".npz":  # e.g. the reduced.npz of to_matrices
        return (" (a .npz holds arrays, not an FE model; a reduced body saved by "
                "ReducedBody.save is opened with pymorembs.load)")  # fmt: skip
    hint = _EXTENSION_HINTS.get(path.suffix.lower())
    if hint:
        return f" (the name suggests {hint}, but the content does not match)"
    return ""


def _detect_head(path: Path, head: bytes, suffix: str) -> str | None:
    """The format from the first bytes of a file, or None; ``suffix``: the file's (of the plain
    name of a compressed file), lower case."""
    if _MATLAB_HEADER.match(head):
        return "matlab"  # v7.3 files are HDF5 with a MATLAB user block: test them first
    for offset in [0] + [512 << k for k in range(8)]:
        if head[offset : offset + 8] == _HDF5_SIGNATURE:
            return "native"
    if _OP2_LABEL in head[:512]:
        return "nastran-op2"
    binary = _detect_binary(path, head)
    if binary is not None:
        return binary
    if b"\x00" in head:
        return None
    head = head.removeprefix(UTF8_BOM)  # a text file saved by a Windows editor
    text = head.decode("latin-1")
    first = _first_content_line(text, skip_abaqus_comments=False)
    if first is None:
        return None
    if first.lstrip().lower().startswith("%%matrixmarket"):
        return "matrix-market"
    if _is_op4_ascii_header(first):
        return "nastran-op4"
    if _DMIG_LINE.search(head):
        return "nastran-dmig"
    if _SUBSTRUCTURE.search(head):
        return "abaqus-substructure"
    if _PUNCH_RESULTS.search(head) or _BULK_CARD.search(head):
        return "nastran-dmig"  # its reader names what the file holds instead of matrices
    data = _first_content_line(text)
    if data is not None and _is_calculix(suffix, data):
        return "calculix"
    if data is not None and _is_abaqus_entry(data):
        return "abaqus"
    return None


def _is_calculix(suffix: str, line: str) -> bool:
    """A CalculiX ``.sti``/``.mas`` entry ``row column value`` or a ``.dof`` line."""
    if suffix == ".dof":
        return _CALCULIX_DOF.fullmatch(line) is not None
    return suffix in _CALCULIX_MATRIX and "," not in line and _is_abaqus_entry(line)


def _detect_binary(path: Path, head: bytes) -> str | None:
    """Ansys ``.full`` or binary OUTPUT4 from the first record, or None."""
    for endian in "<>":
        if len(head) >= 12:
            first, _, number = struct.unpack_from(endian + "3i", head)
            if first == 100:
                if number == 4:
                    return "ansys-full"
                kind = _ANSYS_FILE_TYPES.get(number, f"binary file with file number {number}")
                raise UserError(
                    f"{path}: an Ansys {kind}, not the .full file of a modal analysis; "
                    "pymorembs reads the .full file (or its *EXPORT Matrix Market files)"
                )
        for length in (24, 48):
            if len(head) >= length + 8:
                (lead,) = struct.unpack_from(endian + "i", head)
                (trail,) = struct.unpack_from(endian + "i", head, 4 + length)
                name = head[4 + length - (8 if length == 24 else 16) : 4 + length]
                if lead == length and trail == length and _printable(name):
                    return "nastran-op4"
    return None


def _printable(name: bytes) -> bool:
    return bool(name.strip()) and all(32 <= b < 127 for b in name)


def _is_op4_ascii_header(line: str) -> bool:
    """First line of an ASCII OUTPUT4 matrix: ``%8i%8i%8i%8i%-8s`` plus a Fortran format."""
    if len(line) < 42:
        return False
    try:
        for start in range(0, 32, 8):
            int(line[start : start + 8])
    except ValueError:
        return False
    return bool(line[32:40].strip()) and bool(_OP4_FORMAT.search(line[40:]))


def _is_abaqus_entry(line: str) -> bool:
    """``node, dof, node, dof, value`` or ``row, column, value`` (comma or blank separated)."""
    line = line.split("**", 1)[0]
    fields = [f.strip() for f in line.split(",")] if "," in line else line.split()
    if len(fields) not in (3, 5):
        return False
    try:
        for field in fields[:-1]:
            int(field)
        float(fields[-1].replace("D", "E").replace("d", "e"))
    except ValueError:
        return False
    return True


def _scan_for_dmig(f: BinaryIO, head: bytes) -> str | None:
    """Look for DMIG cards further into a large text file (after other punch output)."""
    if b"\x00" in head:
        return None
    tail = head[head.rfind(b"\n") + 1 :]
    read = len(head)
    while read < _DMIG_SCAN_BYTES:
        chunk = f.read(_HEAD_BYTES)
        if not chunk:
            return None
        read += len(chunk)
        block = tail + chunk
        if _DMIG_LINE.search(block):
            return "nastran-dmig"
        tail = block[block.rfind(b"\n") + 1 :]
    return None


def _first_content_line(text: str, skip_abaqus_comments: bool = True) -> str | None:
    """The first non-blank line (and, by default, not an Abaqus ``**`` comment)."""
    for line in text.splitlines():
        stripped = line.strip()
        if not stripped or (skip_abaqus_comments and stripped.startswith("**")):
            continue
        return line
    return None


# ============================================================================ reading
def read_body(
    file: PathLike | None = None,
    *,
    format: str | None = None,
    stiffness: PathLike | None = None,
    mass: PathLike | None = None,
    damping: PathLike | str | None = None,
    dofs: PathLike | None = None,
    nodes: PathLike | None = None,
    constraints: PathLike | None = None,
    fixed: PathLike | None = None,
    mapping: PathLike | None = None,
    inp: PathLike | None = None,
    stiffness_name: str | None = None,
    mass_name: str | None = None,
    damping_name: str | None = None,
    name: str | None = None,
) -> ElasticBody:
    """Read the FE model of a body from the files an FE program wrote, in any supported format.

    :func:`pymorembs.read` is this function: ``pm.read("model.h5")``,
    ``pm.read("K.mtx", mass="M.mtx", dofs="dofs.csv")``.

    Parameters
    ----------
    file : path-like, optional
        The one model file of ``native`` (``.h5``), ``ansys-full`` (``.full``), ``nastran-dmig``
        (``.pch``), ``nastran-op4`` (``.op4``), ``nastran-op2``, ``matlab``,
        ``abaqus-substructure`` and ``calculix`` (``job.sti``); for ``matrix-market`` it may be a
        directory written by :func:`~pymorembs.io.matrix_market.write_matrix_files`. Given with
        ``mass`` but without ``stiffness``, for a format that reads the stiffness from a file of
        its own (``matrix-market``, ``ansys-mmf``, ``abaqus``), it is that stiffness file.
    format : str, optional
        One of :data:`FORMATS` (``_`` may stand for ``-``, any case). Default: told from the
        content of ``file`` or, without it, of ``stiffness`` (:func:`detect_format`); a Matrix
        Market file with a ``mapping`` file is ``ansys-mmf``.
    stiffness, mass : path-like, optional
        The stiffness and mass files of ``matrix-market``, ``ansys-mmf`` and ``abaqus``; for
        ``calculix`` ``job.sti`` (as ``file``) and ``job.mas`` (default: beside it).
    damping : path-like or str, optional
        The viscous damping matrix file (``matrix-market``, ``ansys-mmf``, ``abaqus``); for
        ``nastran-dmig`` and ``nastran-op4`` the *name* of the damping matrix in ``file``
        (e.g. ``BAAX``).
    dofs : path-like, optional
        ``dofs.csv`` (header ``node,direction``): the dof of every equation, for
        ``matrix-market``, ``abaqus`` with ``FORMAT=COORDINATE`` files and ``nastran-op4``; for
        ``calculix`` the ``job.dof`` file (default: beside ``job.sti``).
    nodes : path-like, optional
        Node coordinates, for every format but ``native``: ``nodes.csv`` (header ``id,x,y,z``),
        an Abaqus or CalculiX input deck, an Ansys archive (``.cdb``), Nastran bulk data or an
        ``.f06`` (:func:`pymorembs.io.node_files.read_node_file`). For ``abaqus``,
        ``abaqus-substructure`` and ``calculix`` it is the same option as ``inp``.
    constraints, fixed : path-like, optional
        ``constraints.csv`` and ``fixed.csv`` (layout in :mod:`pymorembs.io.matrix_market`);
        accepted by every format and applied to the body read.
    mapping : path-like, optional
        The Ansys mapping file of ``ansys-mmf``.
    inp : path-like, optional
        The Abaqus input file with the ``*NODE`` coordinates (``abaqus``,
        ``abaqus-substructure``), the CalculiX input deck (``calculix``; default: ``job.inp``
        beside ``job.sti``).
    stiffness_name, mass_name, damping_name : str, optional
        Matrix (or variable) names in the file of ``nastran-dmig``, ``nastran-op4``,
        ``nastran-op2`` and ``matlab``. Default: found by the reader when the choice is
        unambiguous (e.g. ``KAAX``/``MAAX``, ``KAA``/``MAA``, ``KGG``/``MGG``; ``K``/``M``).
    name : str, optional
        Label of the body.

    Returns
    -------
    ElasticBody

    Raises
    ------
    UserError
        Unknown format, content of no known format, an option that does not apply to the format,
        a missing required file, or any error of the format's reader, naming the file (and line)
        and the problem.
    """
    fmt = _format_of(format, file if file is not None else stiffness, mapping)
    if (
        file is not None
        and stiffness is None
        and mass is not None
        and "stiffness" in _OPTIONS[fmt]
        and not Path(file).is_dir()
    ):
        file, stiffness = None, file  # read("K.mtx", mass="M.mtx", ...)
    options = {
        "file": file,
        "stiffness": stiffness,
        "mass": mass,
        "damping": damping,
        "dofs": dofs,
        "nodes": nodes,
        "constraints": constraints,
        "fixed": fixed,
        "mapping": mapping,
        "inp": inp,
        "stiffness_name": stiffness_name,
        "mass_name": mass_name,
        "damping_name": damping_name,
        "name": name,
    }
    given = {key: value for key, value in options.items() if value is not None}
    extra = sorted(set(given) - _OPTIONS[fmt])
    if extra and format is None and "file" in extra:
        raise UserError(
            f"{file}: the content looks like {fmt}, whose matrices come as separate files; give "
            f"them as stiffness and mass, or {_give_format()}"
        )
    if extra:
        plural = "s" if len(extra) > 1 else ""
        verb = "do" if len(extra) > 1 else "does"
        source = file if file is not None else stiffness
        detected = f"{source}: the content looks like {fmt}: " if format is None else ""
        raise UserError(
            f"{detected}option{plural} {', '.join(extra)} {verb} not apply to format {fmt}; "
            f"it takes {', '.join(sorted(_OPTIONS[fmt]))}"
        )
    _check_distinct_matrices(given)
    if fmt == "calculix":
        given = _calculix_files(given)
    if fmt == "matrix-market" and "file" in given and Path(given["file"]).is_dir():
        given = _directory_files(given)  # (its files may be compressed)
    files = [key for key in (*_FILE_OPTIONS, "inp") if key in given]
    if "damping" in given and fmt in _DAMPING_FILES:
        files.append("damping")
    with PlainCopies({key: given[key] for key in files}) as copies:
        plain = {**given, **copies.paths}
        body, applied = _dispatch(fmt, plain)
        body = _finish(body, plain, applied)
        if copies.compressed:
            body = replace(body, notes=tuple(copies.named(note) for note in body.notes))
    return body


def _format_of(format: str | None, source: PathLike | None, mapping: PathLike | None) -> str:
    """The format of a read: ``format`` checked, or told from the content of ``source`` (the
    model file or the stiffness file); a Matrix Market file with a ``mapping`` is ansys-mmf."""
    if format is not None:
        fmt = str(format).strip().lower().replace("_", "-")
        if fmt not in FORMATS:
            raise UserError(f"unknown format {format!r}; expected one of {', '.join(FORMATS)}")
        return fmt
    if source is None:
        raise UserError(
            "no model given: give the model file (file) or the stiffness file (stiffness)"
        )
    fmt = detect_format(source)
    return "ansys-mmf" if fmt == "matrix-market" and mapping is not None else fmt


def model_files(files: dict[str, PathLike], format: str | None = None) -> dict[str, Path]:
    """Every file a read of these model files opens, also those found beside the given ones.

    A CalculiX ``job.sti`` brings its ``job.mas``, ``job.dof`` and deck ``job.inp``; a Matrix
    Market directory its ``K.mtx``, ``M.mtx`` ...; other formats read only the files given.
    This is what a job's provenance hashes.

    Parameters
    ----------
    files : dict of str -> path-like
        The file options of :func:`read_body` (``file``, ``stiffness``, ``mass``, ``nodes`` ...).
    format : str, optional
        One of :data:`FORMATS`; default: told from ``file`` or ``stiffness``
        (:func:`detect_format`).

    Returns
    -------
    dict of str -> Path
        The given files and those found, by role (``"mass"``, ``"dofs"``, ``"inp"`` ...).
        A file that cannot be found is left out: reading the model says what is missing.
    """
    from pymorembs.io.calculix import calculix_files
    from pymorembs.io.matrix_market import directory_files

    found = {key: Path(value) for key, value in files.items()}
    main = found.get("file", found.get("stiffness"))
    if main is None:
        return found
    try:
        fmt = format or detect_format(main)
        if fmt == "calculix":
            deck = found.get("nodes", found.get("inp"))
            found.update(calculix_files(main, found.get("mass"), found.get("dofs"), deck))
        elif fmt == "matrix-market" and main.is_dir():
            found.update(directory_files(main))
    except UserError:
        pass
    return found


def _directory_files(given: dict[str, Any]) -> dict[str, Any]:
    """The options of a Matrix Market directory (``file``) as its single files (plain or
    compressed), the body named after the directory."""
    from pymorembs.io.matrix_market import directory_files

    clash = sorted({"stiffness", "mass", "damping", "dofs", "nodes"} & set(given))
    if clash:
        raise UserError(
            f"format matrix-market: give either a directory (file) or the single files, "
            f"not both (file and {', '.join(clash)})"
        )
    given = dict(given)
    directory = Path(given.pop("file"))
    given.setdefault("name", directory.resolve().name or "body")
    return {**given, **directory_files(directory)}


def _calculix_files(given: dict[str, Any]) -> dict[str, Any]:
    """The options of a CalculiX export with its files found beside ``job.sti`` (before any
    compressed file is decompressed, so that the files are found beside the original)."""
    from pymorembs.io.calculix import calculix_files

    for first, second in (("file", "stiffness"), ("inp", "nodes")):
        if first in given and second in given:
            raise UserError(
                f"format calculix: give {first} or {second}, not both (the "
                f"{'job.sti' if first == 'file' else 'input deck'} once)"
            )
    given = dict(given)
    stiffness = given.pop("file", None) or given.pop("stiffness", None)
    if stiffness is None:
        _require("calculix", given, "file")
    deck = given.pop("nodes", None) or given.get("inp")
    found = calculix_files(stiffness, given.get("mass"), given.get("dofs"), deck)
    return {**given, **found}


def _check_distinct_matrices(given: dict[str, Any]) -> None:
    """A :class:`UserError` if one file (or one matrix name) is given as both K and M."""
    for first, second in (("stiffness", "mass"), ("stiffness_name", "mass_name")):
        if first not in given or second not in given:
            continue
        a, b = given[first], given[second]
        if first == "stiffness":
            same = Path(a).resolve() == Path(b).resolve()
        else:
            same = str(a).strip() == str(b).strip()
        if same:
            raise UserError(
                f"{b}: given as both the {first.replace('_', ' ')} and the "
                f"{second.replace('_', ' ')}; the mass matrix must be its own"
            )


def _require(fmt: str, given: dict[str, Any], *keys: str) -> None:
    """Raise :class:`UserError` if one of ``keys`` is missing."""
    missing = [key for key in keys if key not in given]
    if missing:
        raise UserError(f"format {fmt} needs {_NEEDS[fmt]}; missing: {', '.join(missing)}")


def _dispatch(fmt: str, given: dict[str, Any]) -> tuple[ElasticBody, set[str]]:
    """Call the reader of ``fmt``; return the body and the options it already applied."""
    g = given.get
    if fmt == "native":
        _require(fmt, given, "file")
        from pymorembs.io.native import read_body_h5

        return read_body_h5(g("file")), set()
    if fmt == "matrix-market":
        from pymorembs.io.matrix_market import read_matrix_files

        if "file" in given:  # (read_body turned a directory into its files)
            raise UserError(
                f"{g('file')}: format matrix-market reads a directory (file) or the files "
                "stiffness and mass, not a single file"
            )
        _require(fmt, given, "stiffness")
        if "mass" not in given:
            raise UserError(
                f"{given['stiffness']}: no mass file given: this is the stiffness only; "
                "pymorembs needs the mass matrix too (mass, --mass)"
            )
        keys = ("stiffness", "mass", "damping", "dofs", "nodes", "constraints", "fixed", "name")
        return read_matrix_files(**{k: given[k] for k in keys if k in given}), set(keys)
    if fmt == "ansys-full":
        _require(fmt, given, "file")
        ansys = importlib.import_module("pymorembs.io.ansys")
        body = ansys.read_ansys_full(g("file"), nodes=g("nodes"), name=g("name"))
        return body, {"name"}
    if fmt == "ansys-mmf":
        _require(fmt, given, "stiffness", "mass", "mapping")
        ansys = importlib.import_module("pymorembs.io.ansys")
        body = ansys.read_ansys_mmf(
            g("stiffness"),
            g("mass"),
            g("mapping"),
            damping=g("damping"),
            nodes=g("nodes"),
            name=g("name"),
        )
        return body, {"name"}
    if fmt == "abaqus":
        _require(fmt, given, "stiffness")  # without mass the reader says what the file holds
        from pymorembs.io.abaqus import read_abaqus

        body = read_abaqus(
            g("stiffness"),
            g("mass"),
            inp=_deck(fmt, given),
            damping=g("damping"),
            name=g("name"),
            dofs=g("dofs"),
        )
        return body, {"name"}
    if fmt == "abaqus-substructure":
        _require(fmt, given, "file")
        substructure = importlib.import_module("pymorembs.io.abaqus_substructure")
        body = substructure.read_abaqus_substructure(
            g("file"), inp=_deck(fmt, given), name=g("name")
        )
        return body, {"name"}
    if fmt == "calculix":
        calculix = importlib.import_module("pymorembs.io.calculix")
        body = calculix.read_calculix(
            g("stiffness"), g("mass"), dofs=g("dofs"), inp=g("inp"), name=g("name")
        )
        return body, {"name"}
    _require(fmt, given, "file")
    names = _matrix_names(given)
    if fmt == "nastran-dmig":
        from pymorembs.io.nastran_dmig import read_dmig

        body = read_dmig(g("file"), nodes=g("nodes"), name=g("name"), **names)
        return body, {"name"}
    if fmt == "nastran-op4":
        op4 = importlib.import_module("pymorembs.io.nastran_op4")
        body = op4.read_op4(g("file"), dofs=g("dofs"), nodes=g("nodes"), name=g("name"), **names)
        return body, {"name"}
    if fmt == "nastran-op2":
        op2 = importlib.import_module("pymorembs.io.nastran_op2")
        body = op2.read_op2(g("file"), nodes=g("nodes"), name=g("name"), **names)
        return body, {"name"}
    # matlab
    matlab = importlib.import_module("pymorembs.io.matlab")
    body = matlab.read_matlab(g("file"), dofs=g("dofs"), nodes=g("nodes"), name=g("name"), **names)
    return body, {"name"}


def _deck(fmt: str, given: dict[str, Any]) -> Any:
    """The ``inp`` option of the Abaqus formats, which ``nodes`` may give instead."""
    if "inp" in given and "nodes" in given:
        raise UserError(f"format {fmt}: give inp or nodes, not both (the node file once)")
    return given.get("inp", given.get("nodes"))


def _matrix_names(given: dict[str, Any]) -> dict[str, str]:
    """The matrix names given (``stiffness``, ``mass``, ``damping``) for the named-matrix readers.

    A Nastran damping matrix may also be named by the ``damping`` option (the name, not a file).
    """
    names = {
        key: str(given[option]).strip()
        for key, option in (
            ("stiffness", "stiffness_name"),
            ("mass", "mass_name"),
            ("damping", "damping_name"),
        )
        if option in given
    }
    if "damping" in given and "damping" not in names:
        names["damping"] = Path(str(given["damping"])).name.strip()
    return names


def _finish(body: ElasticBody, given: dict[str, Any], applied: set[str]) -> ElasticBody:
    """Apply ``constraints``, ``fixed`` and ``name`` where the reader did not."""
    from pymorembs.io.matrix_market import read_constraints_csv, read_fixed_csv

    if "constraints" in given and "constraints" not in applied:
        path = Path(given["constraints"])
        if len(body.constraints):
            raise UserError(
                f"{path}: the model already holds {len(body.constraints)} constraint equations; "
                "give them in one place"
            )
        body = replace(body, constraints=read_constraints_csv(path, body.dofs))
    if "fixed" in given and "fixed" not in applied:
        body = body.with_fixed(read_fixed_csv(Path(given["fixed"]), body.dofs))
    if "name" in given and "name" not in applied:
        body = replace(body, name=str(given["name"]))
    return body
