"""Property-based tests: every FE file reader either reads a file or raises one-line UserError.

For each reader (Matrix Market and its CSV tables, Ansys ``.full`` (plain and with compressed
records), its ``.cdb`` archive and MMF/mapping, MATLAB ``.mat`` (v5 and v7.3), Abaqus
``.mtx``/``.inp`` (matrix input; coordinate with dofs.csv or with an ``.inp`` of parts and
instances; penalty diagonals) and substructure files, Nastran DMIG/GRID, OP4 ASCII/binary with
dofs.csv or ASET cards, the native HDF5 file, and format detection through
:func:`pymorembs.io.formats.read_body`) two kinds of input are tried: random bytes/text, and
mutations of a small valid file (lines deleted, duplicated or swapped, numbers replaced by
garbage, NaN or huge values, header counts changed, truncation, byte flips). The property: the
reader returns a body whose matrices are finite, symmetric and of the size of the dof table, or
raises :class:`~pymorembs.errors.UserError` whose message is a single line naming the fuzzed
file. Any other exception fails the test.

The targets are also used by the long-run harness ``fuzz/fuzz_readers.py``.
"""

from __future__ import annotations

import functools
import re
import struct
import tempfile
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest
import scipy.sparse as sp
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from abaqus_models import (
    coordinate_text,
    cube,
    element_lines,
    node_lines,
    rotate,
    solid_matrices,
    substructure_text,
)
from pymorembs.body import ElasticBody
from pymorembs.errors import UserError
from pymorembs.io import matrix_market
from pymorembs.io.abaqus import read_abaqus
from pymorembs.io.abaqus_substructure import read_abaqus_substructure
from pymorembs.io.ansys import read_ansys_full, read_ansys_mmf
from pymorembs.io.formats import detect_format, read_body
from pymorembs.io.matlab import read_matlab
from pymorembs.io.matrix_market import read_matrix_files, read_matrix_market
from pymorembs.io.nastran_dmig import read_dmig
from pymorembs.io.nastran_op2 import read_op2
from pymorembs.io.nastran_op4 import read_op4
from pymorembs.io.native import read_body_h5, write_body_h5

# ============================================================================ valid seed files
MM_K = """%%MatrixMarket matrix coordinate real symmetric
% a 3-dof chain
3 3 5
1 1 2.0e3
2 1 -1.0e3
2 2 2.0e3
3 2 -1.0e3
3 3 1.0e3
"""
MM_M = """%%MatrixMarket matrix array real symmetric
3 3
1.0
0.1
0.0
2.0
0.0
1.5
"""
DOFS_CSV = "node,direction\n# three dofs\n1,ux\n1,uy\n2,rz\n"
NODES_CSV = "id,x,y,z\n1,0.0,0.0,0.0\n2,1.5,-2.0,0.25\n"
CONSTRAINTS_CSV = (
    "dependent_node,dependent_direction,offset,node,direction,coefficient\n"
    "2,rz,0.0,1,ux,0.5\n2,rz,0.0,1,uy,0.25\n"
)
FIXED_CSV = "node,direction\n1,uy\n"
# The Ansys MMF seed is a free body (a bar along x), so that its equation order is proved by the
# rigid-body check the reader applies.
MAPPING = "Matrix Eqn   Node   DOF\n1   1   UX\n2   1   UY\n3   2   UX\n4   2   UY\n"
ANSYS_K = """%%MatrixMarket matrix coordinate real symmetric
% a bar from node 1 to node 2 (UX couplings only)
4 4 3
1 1 1.0e3
3 1 -1.0e3
3 3 1.0e3
"""
ANSYS_M = (
    "%%MatrixMarket matrix coordinate real symmetric\n4 4 4\n1 1 1.0\n2 2 1.0\n3 3 1.0\n4 4 1.0\n"
)
ANSYS_NODES = "id,x,y,z\n1,0.0,0.0,0.0\n2,2.0,0.0,0.0\n"

ABAQUS_K = """** stiffness, matrix input layout
1,1, 1,1, 2.0E+06
1,1, 2,1, -1.0E+06
2,1, 2,1, 2.0D+06
2,1, 3,2, -1.0E+06
3,2, 3,2, 1.0E+06
"""
ABAQUS_M = "1,1, 1,1, 1.0\n2,1, 2,1, 1.0\n3,2, 3,2, 0.5\n2,1, 1,1, 0.1\n"
ABAQUS_COORD_K = "1 1 2.0e6\n2 1 -1.0e6\n2 2 2.0e6\n3 3 1.0e6\n3 2 -1.0\n"
ABAQUS_COORD_M = "1,1,1.0\n2,2,1.0\n3,3,0.5\n"
ABAQUS_INP = """*HEADING
chain
** nodes
*NODE, NSET=ALL
1, 0.0, 0.0, 0.0
2, 1.0, 0.0, 0.0
3, 2.0, 0.5
*ELEMENT, TYPE=B31
1, 1, 2
"""


def _dmig_small(name: str, entries: dict[int, list[tuple[int, int, float]]]) -> list[str]:
    """Small-field DMIG cards: header plus one card per column (grid GJ, component 1)."""
    lines = [f"DMIG    {name:<8}{0:>8}{6:>8}{2:>8}{0:>8}{'':8}{'':8}{len(entries):>8}"]
    for (gj, cj), rows in entries.items():
        lines.append(f"DMIG    {name:<8}{gj:>8}{cj:>8}")
        for g, c, a in rows:
            lines.append(f"        {g:>8}{c:>8}{a:>8.3g}")
    return lines


DMIG_PCH = "\n".join(
    [
        "$ punch file of a three-grid chain",
        *_dmig_small(
            "KAAX",
            {
                (101, 1): [(101, 1, 2.0e3)],
                (102, 1): [(101, 1, -1.0e3), (102, 1, 2.0e3)],
                (205, 3): [(102, 1, -5.0e2), (205, 3, 1.0e3)],
            },
        ),
        "DMIG,MAAX,0,6,1,0,,,3",
        "DMIG,MAAX,101,1,,101,1,1.0,",
        "DMIG,MAAX,102,1,,102,1,1.5+0,",
        "DMIG*   MAAX                         205               3",
        "*            205               3         0.5D+00",
    ]
)
GRIDS_BDF = """$ grids
GRID         101       0     0.0     0.0     0.0
GRID,102,,1.0,2.0,3.0
GRID*                205               0             1.5             2.5
*                    3.5
"""

K_OP4 = np.array([[2.0e3, -1.0e3, 0.0], [-1.0e3, 2.0e3, -1.0e3], [0.0, -1.0e3, 1.0e3]])
M_OP4 = np.diag([1.0, 2.0, 0.5])
OP4_DOFS_CSV = "node,direction\n2,ux\n5,ux\n7,uz\n"
OP4_ASET = """BEGIN BULK
ASET1,1,2,5
ASET          7       3
GRID           2       0     0.0     0.0     0.0
GRID,5,,1.0,0.0,0.0
GRID           7             2.0     0.0     0.0
ENDDATA
"""

# Nastran bulk data with coordinate systems: grid 101 in a CORD2R defined in a CORD2C (a RID
# chain), 102 in and along the cylindrical system (at theta = 0, so u_r = basic x), 205 in a
# CORD1S at phi = 90 degrees with CD = that system (u_phi = -basic x); the DMIG_PCH grids.
SYSTEMS_BDF = """$ coordinate systems
BEGIN BULK
CORD2C,2,,0.,0.,0.,0.,0.,1.,+C2
+C2,1.,0.,0.
CORD2R*                1               2             1.0            90.0
*                    0.0             1.0            90.0             1.0
*                    2.0            90.0             0.0
CORD1S,3,301,302,303
GRID         101       1     0.5    -.25   1.5+0
GRID,102,2,2.,0.,1.,2
GRID*                205               3             1.0            90.0
*                   90.0               3
GRID         301              0.      0.      0.
GRID         302              0.      0.      1.
GRID         303              1.      0.      0.
ENDDATA
"""
F06_ECHO = """1    TEST                                                                  PAGE     3
0                                                 S O R T E D   B U L K   D A T A   E C H O
                 ENTRY
                 COUNT        .   1  ..   2  ..   3  ..   4  ..   5  ..   6  ..   7  ..   8  ..
                    1-        CORD2R  7               0.      0.      0.      0.      0.      1.
                    2-        +       1.      0.      0.
                    3-        GRID    101             0.      0.      0.
                    4-        GRID    102     7       1.      2.      3.
                    5-        GRID*   205                             1.5             2.5
                    6-        *       3.5
                              ENDDATA
0                       TOTAL COUNT=         6
"""
# the EXTBULK punch of a Craig-Bampton superelement: grid 11 x 123456 (CD = 10, permuted axes)
# and modal coordinates 9001, 9002; its matrices are SE_K, SE_M (8 x 8) in se.op4
SE_PCH = """$ EXTBULK
BEGIN SUPER       10
CORD2R*               10               0 0.000000000E+00 0.000000000E+00
*        0.000000000E+00 0.100000000E+01 0.000000000E+00 0.000000000E+00
*        0.000000000E+00 0.100000000E+01 0.000000000E+00
EXTRN         11  123456    9001       0    9002       0
GRID*                 11               0 0.600000000E+03 0.300000000E+03
*        0.300000000E+03              10               0               0
ASET          11  123456
QSET1          0    9001    THRU    9002
SPOINT      9001    9002
DTI     TUG1    0       36      32      32767   0       7       0
        PHIP            7                       REAL           1ENDREC
"""
SE_K = np.diag([4.0e3, 4.0e3, 4.0e3, 1.0e2, 1.0e2, 1.0e2, 9.0e4, 1.6e5])
SE_K[0, 4] = SE_K[4, 0] = 5.0
SE_M = np.diag([2.0, 2.0, 2.0, 0.1, 0.1, 0.1, 1.0, 1.0])
SE_M[0, 6] = SE_M[6, 0] = 0.3
# a DMIG punch with generic names (KGG/MGG, BGG damping, K4GG structural) and a scalar point
NAMES_PCH = "\n".join(
    [
        "$ names found by their suffix; 9001 is a scalar point",
        *_dmig_small(
            "KGG",
            {
                (101, 1): [(101, 1, 2.0e3)],
                (9001, 0): [(101, 1, -1.0e3), (9001, 0, 2.0e3)],
            },
        ),
        *_dmig_small("MGG", {(101, 1): [(101, 1, 1.0)], (9001, 0): [(9001, 0, 1.0)]}),
        *_dmig_small("BGG", {(101, 1): [(101, 1, 0.5)]}),
        *_dmig_small("K4GG", {(101, 1): [(101, 1, 0.01)]}),
    ]
)
OP2_FILE = Path(__file__).parents[1] / "data" / "pynastran" / "op2_kgg_kelm"
OP2_FILE = OP2_FILE / "static_solid_shell_bar_kelm.op2"


def _record(payload: bytes) -> bytes:
    """A Fortran unformatted sequential record."""
    return struct.pack("<i", len(payload)) + payload + struct.pack("<i", len(payload))


@functools.cache
def binary_op4() -> bytes:
    """Binary OUTPUT4 (dense columns, real double) of KAAX and MAAX, written record by record."""
    return _op4_records({"KAAX": (6, K_OP4), "MAAX": (6, M_OP4)})


@functools.cache
def se_op4() -> bytes:
    """The NX EXTSEOUT matrices of SE_PCH (KXX, MXX and a 1 x 1 zero placeholder BXX1)."""
    return _op4_records({"KXX": (6, SE_K), "MXX": (6, SE_M), "BXX1": (6, np.zeros((1, 1)))})


def _op4_records(matrices: dict) -> bytes:
    out = b""
    for name, (form, a) in matrices.items():
        n = a.shape[0]
        out += _record(struct.pack("<4i", n, n, form, 2) + name.ljust(8).encode())
        for j in range(n):
            nonzero = np.flatnonzero(a[:, j])
            if nonzero.size == 0:
                continue
            first, last = nonzero[0], nonzero[-1] + 1
            values = a[first:last, j].astype("<f8")
            out += _record(struct.pack("<3i", j + 1, first + 1, 2 * values.size) + values.tobytes())
        out += _record(struct.pack("<3i", n + 1, 1, 2) + struct.pack("<d", 1.0))
    return out


@functools.cache
def ascii_op4() -> bytes:
    """ASCII OUTPUT4 of KAAX (dense) and MAAX (sparse) written by pyNastran."""
    from pyNastran.op2.result_objects.matrix import Matrix
    from pyNastran.op4.op4 import OP4

    with tempfile.TemporaryDirectory() as d:
        path = Path(d) / "body.op4"
        OP4(debug=None).write_op4(
            str(path),
            {"KAAX": Matrix("KAAX", 6, K_OP4), "MAAX": Matrix("MAAX", 6, sp.coo_matrix(M_OP4))},
            name_order=["KAAX", "MAAX"],
            is_binary=False,
        )
        return path.read_bytes()


@functools.cache
def ansys_full() -> bytes:
    """The example ``.full`` file shipped with ansys-mapdl-reader."""
    from ansys.mapdl.reader import examples

    return Path(examples.fullfile).read_bytes()


@functools.cache
def compressed_full() -> bytes:
    """The example ``.full`` with records in the compressed forms of Ansys 19+ (windowed dofs per
    node and dof information, bit-coded dof record), as built by ``test_readers_ansys``."""
    from test_readers_ansys import BIT_SPARSE, WINDOWED, bit_sparse, rewrite_full, windowed

    with tempfile.TemporaryDirectory() as d:
        path = Path(d) / "file.full"
        encode = {
            "ndof": (windowed, WINDOWED),
            "const": (windowed, WINDOWED),
            "dof": (bit_sparse, BIT_SPARSE),
        }
        source = Path(d) / "source.full"
        source.write_bytes(ansys_full())
        return rewrite_full(source, path, encode).read_bytes()


@functools.cache
def hexbeam_cdb() -> bytes:
    """The genuine archive of the example's mesh (tests/data/pymapdl_reader_hexbeam)."""
    return (
        Path(__file__).parents[1] / "data" / "pymapdl_reader_hexbeam" / "HexBeam.cdb"
    ).read_bytes()


#: The genuine CalculiX export of a *BOUNDARY-constrained block (tests/data).
CALCULIX = Path(__file__).parents[1] / "data" / "calculix_c3d20_block"


def _calculix_file(suffix: str) -> Callable[[], bytes]:
    return lambda: (CALCULIX / f"fixed.{suffix}").read_bytes()


CALCULIX_COMPANIONS = tuple((f"job.{s}", _calculix_file(s)) for s in ("sti", "mas", "dof", "inp"))


def _read_calculix(d: Path) -> ElasticBody:
    return read_body(file=d / "job.sti")


@functools.cache
def gzipped_mm_k() -> bytes:
    """The Matrix Market stiffness of the plain-file targets, gzip-compressed."""
    import gzip

    return gzip.compress(MM_K.encode(), mtime=0)


def _read_compressed_mm(d: Path) -> ElasticBody:
    return read_body(stiffness=d / "K.mtx.gz", mass=d / "M.mtx", dofs=d / "dofs.csv")


def _matlab_model() -> dict[str, object]:
    k = sp.csc_matrix(np.array([[2.0e3, -1.0e3, 0.0], [-1.0e3, 2.0e3, -1.0e3], [0, -1.0e3, 1.0e3]]))
    return {"K": k, "M": np.diag([1.0, 2.0, 0.5]), "E": 1e-3 * k, "B": np.eye(3)[:, :1]}


@functools.cache
def matlab_v5() -> bytes:
    """A small v5 MAT-file (scipy.io.savemat) with K (sparse), M, E, B."""
    import io

    import scipy.io

    buffer = io.BytesIO()
    scipy.io.savemat(buffer, _matlab_model(), do_compression=False)
    return buffer.getvalue()


@functools.cache
def matlab_v73() -> bytes:
    """The same model as a v7.3 (HDF5) MAT-file in MATLAB's layout."""
    from test_readers_matlab import save_v73

    with tempfile.TemporaryDirectory() as d:
        return save_v73(Path(d) / "model.mat", _matlab_model()).read_bytes()


@functools.cache
def native_h5() -> bytes:
    """A small native body file (with constraints, fixed dofs and damping matrix)."""
    with tempfile.TemporaryDirectory() as d:
        directory = Path(d)
        for name, text in {
            "K.mtx": MM_K,
            "M.mtx": MM_M,
            "D.mtx": MM_K,
            "dofs.csv": DOFS_CSV,
            "nodes.csv": NODES_CSV,
            "constraints.csv": CONSTRAINTS_CSV,
            "fixed.csv": FIXED_CSV,
        }.items():
            (directory / name).write_text(text)
        from pymorembs.io.matrix_market import read_matrix_directory

        body = read_matrix_directory(directory)
        write_body_h5(body, directory / "model.h5")
        return (directory / "model.h5").read_bytes()


# ============================================================================ targets
@dataclass(frozen=True)
class Target:
    """One reader fed with one fuzzed file.

    ``companions`` are valid files written next to the fuzzed file ``name``; ``read(directory)``
    calls the reader on them; ``seed()`` is the valid content of the fuzzed file.
    """

    key: str
    name: str
    seed: Callable[[], bytes]
    read: Callable[[Path], object]
    companions: tuple[tuple[str, str | Callable[[], bytes]], ...] = ()
    binary: bool = False


def _text(value: str) -> Callable[[], bytes]:
    return lambda: value.encode()


def _mm_files(d: Path, **extra: str) -> ElasticBody:
    names = {"dofs": "dofs.csv", "nodes": "nodes.csv", "constraints": "constraints.csv"}
    names.update(fixed="fixed.csv")
    return read_matrix_files(d / "K.mtx", d / "M.mtx", **{k: d / v for k, v in names.items()})


MM_COMPANIONS = (
    ("K.mtx", MM_K),
    ("M.mtx", MM_M),
    ("dofs.csv", DOFS_CSV),
    ("nodes.csv", NODES_CSV),
    ("constraints.csv", CONSTRAINTS_CSV),
    ("fixed.csv", FIXED_CSV),
)
MMF_COMPANIONS = (
    ("K.mtx", ANSYS_K),
    ("M.mtx", ANSYS_M),
    ("model.mapping", MAPPING),
    ("nodes.csv", ANSYS_NODES),
)
ABQ_COMPANIONS = (("job_STIF1.mtx", ABAQUS_K), ("job_MASS1.mtx", ABAQUS_M), ("job.inp", ABAQUS_INP))
ABQ_COORD = (
    ("c_STIF1.mtx", ABAQUS_COORD_K),
    ("c_MASS1.mtx", ABAQUS_COORD_M),
    ("dofs.csv", DOFS_CSV),
)
OP4_COMPANIONS = (("dofs.csv", OP4_DOFS_CSV), ("aset.bdf", OP4_ASET), ("body.op4", binary_op4))


def _read_mmf(d: Path) -> ElasticBody:
    return read_ansys_mmf(d / "K.mtx", d / "M.mtx", d / "model.mapping", nodes=d / "nodes.csv")


def _read_abaqus(d: Path) -> ElasticBody:
    return read_abaqus(d / "job_STIF1.mtx", d / "job_MASS1.mtx", inp=d / "job.inp")


def _read_abaqus_coord(d: Path) -> ElasticBody:
    return read_abaqus(d / "c_STIF1.mtx", d / "c_MASS1.mtx", dofs=d / "dofs.csv")


@functools.cache
def abaqus_assembly() -> dict[str, str]:
    """A C3D4 cube as part "cube" in a rotated instance, with FORMAT=COORDINATE K and M.

    ``pen_STIF1.mtx`` is K with the dofs of node 1 fixed by 1e36 penalty diagonals.
    """
    xyz, tets = cube()
    a, b = np.array([0.0, 0.0, 0.0]), np.array([0.0, 1.0, 1.0])
    placed = rotate(xyz + np.array([1.0, 0.0, 0.0]), a, b, 30.0)
    k, m = solid_matrices(placed, tets)
    penalty = k.copy()
    penalty[[0, 1, 2], [0, 1, 2]] = 1e36
    part = ["*Part, name=cube", "*Node", *node_lines(range(1, 9), xyz), "*Element, type=C3D4"]
    part += [*element_lines(tets + 1), "*End Part"]
    assembly = ["*Assembly, name=Assembly", "*Instance, name=cube-1, part=cube", "1., 0., 0."]
    assembly += ["0., 0., 0., 0., 1., 1., 30.", "*End Instance", "*End Assembly"]
    inp = "\n".join(["*Heading", *part, *assembly])
    return {
        "cube_STIF1.mtx": coordinate_text(k),
        "cube_MASS1.mtx": coordinate_text(m),
        "pen_STIF1.mtx": coordinate_text(penalty),
        "cube.inp": inp + "\n",
    }


def _assembly_file(name: str) -> Callable[[], bytes]:
    return lambda: abaqus_assembly()[name].encode()


ABQ_ASSEMBLY = tuple(
    (name, _assembly_file(name))
    for name in ("cube_STIF1.mtx", "cube_MASS1.mtx", "pen_STIF1.mtx", "cube.inp")
)
SUBSTRUCTURE = substructure_text(
    [7, 9],
    ["          1,          2", "          2,          3"],
    {
        "STIFFNESS": np.array([[4.0, -1.0, 0.5], [-1.0, 3.0, -0.25], [0.5, -0.25, 2.0]]) * 1e3,
        "MASS": np.diag([1.0, 2.0, 3.0]),
    },
)
SUBSTRUCTURE_NODES = "id,x,y,z\n7,0.0,0.0,0.0\n9,1.0,0.5,0.0\n"


def _read_abaqus_assembly(d: Path) -> ElasticBody:
    return read_abaqus(d / "cube_STIF1.mtx", d / "cube_MASS1.mtx", inp=d / "cube.inp")


def _read_abaqus_penalty(d: Path) -> ElasticBody:
    return read_abaqus(d / "pen_STIF1.mtx", d / "cube_MASS1.mtx", inp=d / "cube.inp")


def _read_substructure(d: Path) -> ElasticBody:
    return read_abaqus_substructure(d / "sub.mtx", inp=d / "nodes.csv")


def _read_dmig(d: Path) -> ElasticBody:
    return read_dmig(d / "model.pch", nodes=d / "grids.bdf")


def _read_op4_csv(d: Path) -> ElasticBody:
    return read_op4(d / "body.op4", dofs=d / "dofs.csv")


def _read_op4_aset(d: Path) -> ElasticBody:
    return read_op4(d / "body.op4", dofs=d / "aset.bdf")


def _read_dmig_systems(d: Path) -> ElasticBody:
    return read_dmig(d / "model.pch", nodes=d / "systems.bdf")


def _read_dmig_f06(d: Path) -> ElasticBody:
    return read_dmig(d / "model.pch", nodes=d / "run.f06")


def _read_dmig_names(d: Path) -> ElasticBody:
    return read_dmig(d / "names.pch")


def _read_op4_extbulk(d: Path) -> ElasticBody:
    return read_op4(d / "se.op4", dofs=d / "se.pch")


def _read_op2(d: Path) -> ElasticBody:
    return read_op2(d / "model.op2", mass="KGG")


def _op2_seed() -> bytes:
    return OP2_FILE.read_bytes()


def _read_any(d: Path) -> ElasticBody:
    """Format detection plus the detected reader, as ``pymorembs info FILE`` does."""
    path = d / "model.dat"
    extra = {"dofs": d / "dofs.csv"} if detect_format(path) == "nastran-op4" else {}
    return read_body(file=path, **extra)


def _mm_fast_path(d: Path) -> sp.csr_matrix:
    """The fast path of read_matrix_market tried on every size: its matrix, if any, must equal
    the strict pass's result, and whenever the strict pass refuses the file it must decline."""
    path = d / "K.mtx"
    threshold, fast_reader = matrix_market._FAST_FROM_BYTES, matrix_market._read_coordinate_fast
    try:
        matrix_market._FAST_FROM_BYTES = 0
        fast = fast_reader(path)
        fast = None if fast is None else fast[0]
        matrix_market._read_coordinate_fast = lambda path: None
        try:
            strict = read_matrix_market(path)
        except UserError:
            assert fast is None, "the fast path read a file the strict pass refuses"
            raise
    finally:
        matrix_market._FAST_FROM_BYTES = threshold
        matrix_market._read_coordinate_fast = fast_reader
    if fast is not None:
        assert (fast != strict).nnz == 0 and fast.nnz == strict.nnz, "fast and strict differ"
    return strict


TARGETS: dict[str, Target] = {
    t.key: t
    for t in [
        Target("mm-stiffness", "K.mtx", _text(MM_K), _mm_files, MM_COMPANIONS),
        Target("mm-array", "M.mtx", _text(MM_M), _mm_files, MM_COMPANIONS),
        Target("mm-dofs", "dofs.csv", _text(DOFS_CSV), _mm_files, MM_COMPANIONS),
        Target("mm-nodes", "nodes.csv", _text(NODES_CSV), _mm_files, MM_COMPANIONS),
        Target(
            "mm-constraints", "constraints.csv", _text(CONSTRAINTS_CSV), _mm_files, MM_COMPANIONS
        ),
        Target("mm-fixed", "fixed.csv", _text(FIXED_CSV), _mm_files, MM_COMPANIONS),
        Target("mm-single", "K.mtx", _text(MM_K), lambda d: read_matrix_market(d / "K.mtx"), ()),
        Target("mm-fast-path", "K.mtx", _text(MM_K), _mm_fast_path, ()),
        Target("ansys-mapping", "model.mapping", _text(MAPPING), _read_mmf, MMF_COMPANIONS),
        Target("ansys-mmf-matrix", "K.mtx", _text(ANSYS_K), _read_mmf, MMF_COMPANIONS),
        Target("ansys-mmf-nodes", "nodes.csv", _text(ANSYS_NODES), _read_mmf, MMF_COMPANIONS),
        Target(
            "ansys-full-compressed",
            "file.full",
            compressed_full,
            lambda d: read_ansys_full(d / "file.full"),
            binary=True,
        ),
        Target(
            "ansys-cdb",
            "model.cdb",
            hexbeam_cdb,
            lambda d: read_ansys_full(d / "file.full", nodes=d / "model.cdb"),
            (("file.full", ansys_full),),
        ),
        Target(
            "matlab-v5", "model.mat", matlab_v5, lambda d: read_matlab(d / "model.mat"), (), True
        ),
        Target(
            "matlab-v73", "model.mat", matlab_v73, lambda d: read_matlab(d / "model.mat"), (), True
        ),
        Target("detect-matlab", "model.dat", matlab_v5, _read_any, (), binary=True),
        Target(
            "ansys-full",
            "file.full",
            ansys_full,
            lambda d: read_ansys_full(d / "file.full"),
            binary=True,
        ),
        Target("abaqus-stiffness", "job_STIF1.mtx", _text(ABAQUS_K), _read_abaqus, ABQ_COMPANIONS),
        Target("abaqus-mass", "job_MASS1.mtx", _text(ABAQUS_M), _read_abaqus, ABQ_COMPANIONS),
        Target("abaqus-inp", "job.inp", _text(ABAQUS_INP), _read_abaqus, ABQ_COMPANIONS),
        Target(
            "abaqus-coordinate",
            "c_STIF1.mtx",
            _text(ABAQUS_COORD_K),
            _read_abaqus_coord,
            ABQ_COORD,
        ),
        Target(
            "abaqus-coordinate-inp",
            "cube.inp",
            _assembly_file("cube.inp"),
            _read_abaqus_assembly,
            ABQ_ASSEMBLY,
        ),
        Target(
            "abaqus-coordinate-stiffness",
            "cube_STIF1.mtx",
            _assembly_file("cube_STIF1.mtx"),
            _read_abaqus_assembly,
            ABQ_ASSEMBLY,
        ),
        Target(
            "abaqus-penalty",
            "pen_STIF1.mtx",
            _assembly_file("pen_STIF1.mtx"),
            _read_abaqus_penalty,
            ABQ_ASSEMBLY,
        ),
        Target(
            "abaqus-substructure",
            "sub.mtx",
            _text(SUBSTRUCTURE),
            _read_substructure,
            (("nodes.csv", SUBSTRUCTURE_NODES),),
        ),
        Target(
            "dmig-punch",
            "model.pch",
            _text(DMIG_PCH),
            _read_dmig,
            (("model.pch", DMIG_PCH), ("grids.bdf", GRIDS_BDF)),
        ),
        Target(
            "dmig-grids",
            "grids.bdf",
            _text(GRIDS_BDF),
            _read_dmig,
            (("model.pch", DMIG_PCH), ("grids.bdf", GRIDS_BDF)),
        ),
        Target("op4-ascii", "body.op4", ascii_op4, _read_op4_csv, OP4_COMPANIONS),
        Target("op4-binary", "body.op4", binary_op4, _read_op4_csv, OP4_COMPANIONS, binary=True),
        Target("op4-aset", "aset.bdf", _text(OP4_ASET), _read_op4_aset, OP4_COMPANIONS),
        Target(
            "bulk-systems",
            "systems.bdf",
            _text(SYSTEMS_BDF),
            _read_dmig_systems,
            (("model.pch", DMIG_PCH), ("systems.bdf", SYSTEMS_BDF)),
        ),
        Target(
            "bulk-f06-echo",
            "run.f06",
            _text(F06_ECHO),
            _read_dmig_f06,
            (("model.pch", DMIG_PCH), ("run.f06", F06_ECHO)),
        ),
        Target("dmig-names-scalar", "names.pch", _text(NAMES_PCH), _read_dmig_names),
        Target(
            "op4-extbulk",
            "se.pch",
            _text(SE_PCH),
            _read_op4_extbulk,
            (("se.op4", se_op4), ("se.pch", SE_PCH)),
        ),
        Target(
            "op4-names",
            "se.op4",
            se_op4,
            _read_op4_extbulk,
            (("se.op4", se_op4), ("se.pch", SE_PCH)),
            binary=True,
        ),
        Target("op2", "model.op2", _op2_seed, _read_op2, binary=True),
        Target("native", "model.h5", native_h5, lambda d: read_body_h5(d / "model.h5"), (), True),
        Target("detect-text", "model.dat", _text(DMIG_PCH), _read_any, OP4_COMPANIONS),
        Target("detect-binary", "model.dat", binary_op4, _read_any, OP4_COMPANIONS, binary=True),
        Target("detect-op4-ascii", "model.dat", ascii_op4, _read_any, OP4_COMPANIONS),
        Target("detect-full", "model.dat", ansys_full, _read_any, (), binary=True),
        Target(
            "calculix-sti", "job.sti", _calculix_file("sti"), _read_calculix, CALCULIX_COMPANIONS
        ),
        Target(
            "calculix-dof", "job.dof", _calculix_file("dof"), _read_calculix, CALCULIX_COMPANIONS
        ),
        Target(
            "calculix-inp", "job.inp", _calculix_file("inp"), _read_calculix, CALCULIX_COMPANIONS
        ),
        Target(
            "compressed-mm",
            "K.mtx.gz",
            gzipped_mm_k,
            _read_compressed_mm,
            (("M.mtx", MM_M), ("dofs.csv", DOFS_CSV)),
            binary=True,
        ),
    ]
}


# ============================================================================ the property
def check_body(body: object) -> None:
    """A body that was read must be consistent: finite, symmetric, sized like its dof table."""
    assert isinstance(body, ElasticBody | sp.spmatrix | sp.sparray), type(body)
    if not isinstance(body, ElasticBody):
        a = sp.csr_matrix(body)
        assert a.shape[0] == a.shape[1]
        assert np.all(np.isfinite(a.data))
        return
    n = len(body.dofs)
    assert n > 0, "a body without dofs"
    for matrix in (body.stiffness, body.mass, body.damping_matrix):
        if matrix is None:
            continue
        a = sp.csr_matrix(matrix)
        assert a.shape == (n, n)
        assert np.all(np.isfinite(a.data))
        if a.nnz:
            assert abs(a - a.T).max() <= 1e-10 * max(abs(a).max(), 1e-300)
    assert np.all(np.isfinite(body.coordinates))
    assert np.unique(body.node_ids).size == body.node_ids.size


def run_target(target: Target, content: bytes, directory: Path) -> str:
    """Write the companions and the fuzzed file, call the reader, check the outcome.

    Returns ``"ok"`` or the one-line message of the :class:`UserError`. Anything else raises
    (an ``AssertionError`` for a malformed message or an inconsistent body).
    """
    for name, text in target.companions:
        if callable(text):
            (directory / name).write_bytes(text())
        else:
            (directory / name).write_text(text)
    path = directory / target.name
    path.write_bytes(content)
    try:
        body = target.read(directory)
    except UserError as err:
        message = str(err)
        assert "\n" not in message and "\r" not in message, repr(message)
        # the fuzzed file, or a companion the fuzzed file now contradicts
        names = {target.name, *(name for name, _ in target.companions)}
        assert any(str(directory / name) in message for name in names), (
            f"the message does not name {target.name}: {message!r}"
        )
        return message
    check_body(body)
    return "ok"


# ============================================================================ strategies
GARBAGE_NUMBERS = [
    "nan",
    "NaN",
    "inf",
    "-inf",
    "1e400",
    "-1e400",
    "1e-400",
    "9" * 40,
    "-9223372036854775809",
    "9223372036854775807",
    "2147483648",
    "-2147483649",
    "0",
    "-1",
    "1.5+3",
    "1D5",
    "1_000",
    "0x10",
    "",
    " ",
    "x",
    "+",
    ".",
    "e",
    "\u00e9",
    "\u00a0",
    "1,2",
    "*",
    "**",
    "$",
    "%",
    "#",
    "THRU",
    "1e",
    "--1",
    "1.0.5",
    "1..0",
    "1e5e3",
    "1e5.0",
    ".e5",
    "1.5",
    "1e0",
]
HUGE_COUNTS = [2**24 + 1, 10**7, 2**31 - 1, 2**31, 2**60, 2**63 - 1, 2**63, 10**30, -(2**63)]
NUMBER = re.compile(rb"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eEdD][-+]?\d+)?")


@st.composite
def mutated_text(draw: st.DrawFn, seed: bytes) -> bytes:
    """A valid text file with a few line- and token-level mutations."""
    lines = seed.split(b"\n")
    for _ in range(draw(st.integers(1, 4))):
        op = draw(
            st.sampled_from(
                ["delete", "duplicate", "swap", "number", "count", "insert", "truncate", "byte"]
            )
        )
        if not lines:
            lines = [b""]
        i = draw(st.integers(0, len(lines) - 1))
        if op == "delete":
            del lines[i]
        elif op == "duplicate":
            lines.insert(i, lines[i])
        elif op == "swap":
            j = draw(st.integers(0, len(lines) - 1))
            lines[i], lines[j] = lines[j], lines[i]
        elif op in ("number", "count"):
            spans = [m.span() for m in NUMBER.finditer(lines[i])]
            if spans:
                a, b = draw(st.sampled_from(spans))
                if op == "number":
                    new = draw(st.sampled_from(GARBAGE_NUMBERS)).encode()
                else:
                    big = st.sampled_from(HUGE_COUNTS)
                    new = str(draw(st.integers(-3, 10**12) | big)).encode()
                lines[i] = lines[i][:a] + new + lines[i][b:]
        elif op == "insert":
            lines.insert(i, draw(st.binary(max_size=40)) if draw(st.booleans()) else lines[i][:8])
        elif op == "truncate":
            lines[i] = lines[i][: draw(st.integers(0, max(len(lines[i]), 0)))]
            del lines[i + 1 :]
        else:
            line = bytearray(lines[i])
            if line:
                k = draw(st.integers(0, len(line) - 1))
                line[k] = draw(st.integers(0, 255))
            lines[i] = bytes(line)
    return b"\n".join(lines)


INTERESTING_WORDS = [0, 1, -1, 2, 4, 6, 24, 100, 2**31 - 1, -(2**31), 2**30, 65536, 10**9]


@st.composite
def mutated_binary(draw: st.DrawFn, seed: bytes) -> bytes:
    """A valid binary file with words overwritten, bytes flipped, or cut short."""
    data = bytearray(seed)
    # most structure sits in the first few kilobytes: bias positions there
    head = min(len(data), 4096)
    for _ in range(draw(st.integers(1, 4))):
        op = draw(st.sampled_from(["word", "byte", "truncate", "delete", "duplicate"]))
        if not data:
            break
        limit = head if draw(st.booleans()) else len(data)
        at = draw(st.integers(0, max(min(limit, len(data)) - 1, 0)))
        if op == "word":
            at -= at % 4
            value = draw(st.sampled_from(INTERESTING_WORDS) | st.integers(-(2**31), 2**31 - 1))
            data[at : at + 4] = struct.pack("<i", value)[: len(data) - at]
        elif op == "byte":
            data[at] = draw(st.integers(0, 255))
        elif op == "truncate":
            del data[at:]
        elif op == "delete":
            del data[at : at + draw(st.integers(1, 64))]
        else:
            data[at:at] = data[at : at + draw(st.integers(1, 64))]
    return bytes(data)


def random_input(binary: bool) -> st.SearchStrategy[bytes]:
    """Random bytes, or random text (printable and otherwise) in a few encodings."""
    text = st.text(max_size=300).map(lambda s: s.encode("utf-8", "surrogatepass"))
    lines = st.lists(
        st.text(alphabet="0123456789 .,-+eEdD*%$#\tKAXMGRIDUMTHRuxyz", max_size=40), max_size=12
    ).map(lambda ls: "\n".join(ls).encode())
    base = st.binary(max_size=400) | text | lines
    return base if not binary else st.binary(max_size=400) | base


def mutations(target: Target) -> st.SearchStrategy[bytes]:
    seed = target.seed()
    return mutated_binary(seed) if target.binary else mutated_text(seed)


# ============================================================================ tests
FAST = settings(
    max_examples=40,
    deadline=None,
    derandomize=True,
    database=None,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large],
)
SLOW_TARGETS = {
    "ansys-full",
    "ansys-full-compressed",
    "ansys-cdb",
    "matlab-v5",
    "matlab-v73",
    "detect-matlab",
    "native",
    "op4-ascii",
    "op4-binary",
    "detect-binary",
    "detect-op4-ascii",
    "detect-full",
    "op4-names",
    "op4-extbulk",
    "calculix-sti",
    "calculix-dof",
    "calculix-inp",
}


VERY_SLOW_TARGETS = {"op2"}  # pyNastran's OP2 reader: about 0.3 s per file


def _examples(key: str) -> int:
    if key in VERY_SLOW_TARGETS:
        return 4
    return 15 if key in SLOW_TARGETS else 40


@pytest.mark.parametrize("key", sorted(TARGETS))
def test_seed_file_is_valid(key: str, tmp_path: Path) -> None:
    """The unmutated seed reads without error (so mutations start from a valid file)."""
    target = TARGETS[key]
    assert run_target(target, target.seed(), tmp_path) == "ok"


@pytest.mark.parametrize("key", sorted(TARGETS))
def test_random_input(key: str) -> None:
    """Random bytes and text: read, or refused in one line naming the file."""
    target = TARGETS[key]

    @settings(FAST, max_examples=_examples(key))
    @given(content=random_input(target.binary))
    def check(content: bytes) -> None:
        with tempfile.TemporaryDirectory() as d:
            run_target(target, content, Path(d))

    check()


@pytest.mark.parametrize(
    "key",  # the Abaqus COORDINATE case takes ~8 s: in the slow set
    [
        pytest.param(k, marks=pytest.mark.slow) if k == "abaqus-coordinate" else k
        for k in sorted(TARGETS)
    ],
)
def test_mutated_valid_file(key: str) -> None:
    """A valid file with lines, numbers, counts or bytes broken: the same property."""
    target = TARGETS[key]

    @settings(FAST, max_examples=2 * _examples(key))
    @given(content=mutations(target))
    def check(content: bytes) -> None:
        with tempfile.TemporaryDirectory() as d:
            run_target(target, content, Path(d))

    check()


# ============================================================================ regressions
# Each input below made a reader raise something other than a one-line UserError (or read a
# wrong model) before it was fixed; the docstring names the old behaviour.
def _error(key: str, content: bytes) -> str:
    """The one-line message of reading ``content`` as target ``key`` (which must fail)."""
    with tempfile.TemporaryDirectory() as d:
        message = run_target(TARGETS[key], content, Path(d))
    assert message != "ok", "the input was read without error"
    return message


def _pch(*cards: str) -> bytes:
    return "\n".join(cards).encode()


GOOD_MAAX = ("DMIG,MAAX,0,6,1,0,,,1", "DMIG,MAAX,101,1,,101,1,1.0")


def test_dmig_free_field_grid_beyond_int64() -> None:
    """Was OverflowError (Python int too large to convert to C long)."""
    content = _pch(
        "DMIG,KAAX,0,6,1,0,,,1",
        "DMIG,KAAX,99999999999999999999,1,,101,1,1.0",
        *GOOD_MAAX,
    )
    message = _error("dmig-punch", content)
    assert re.search(r"model\.pch:2: column grid GJ \(field 3\) '9+' is out of range", message)


def test_dmig_large_field_grid_beyond_32_bits() -> None:
    """Was accepted: a 16-digit grid id that no Nastran writes (ids are 32-bit)."""
    content = _pch(
        f"DMIG    {'KAAX':<8}{0:>8}{6:>8}{1:>8}{0:>8}{'':8}{'':8}{1:>8}",
        f"DMIG*   {'KAAX':<16}{101:>16}{1:>16}",
        f"*       {'9' * 16:>16}{1:>16}{1.0:>16}",
        *GOOD_MAAX,
    )
    message = _error("dmig-punch", content)
    assert re.search(r"model\.pch:3: row grid '9{16}' is out of range", message), message


def test_dmig_grid_field_with_a_non_ascii_blank() -> None:
    """Was ValueError: numpy rejects a no-break space (0xA0) that Python's int() skips."""
    content = (
        _pch(
            f"DMIG    {'KAAX':<8}{0:>8}{6:>8}{1:>8}{0:>8}{'':8}{'':8}{1:>8}",
            f"DMIG    {'KAAX':<8}{101:>8}{1:>8}",
        )
        + b"\n        \xa0    101       1     1.0\n"
        + _pch(*GOOD_MAAX)
    )
    with tempfile.TemporaryDirectory() as d:
        outcome = run_target(TARGETS["dmig-punch"], content, Path(d))
    assert outcome == "ok" or "model.pch" in outcome


def test_ansys_mapping_line_of_commas() -> None:
    """Was IndexError: list index out of range."""
    content = MAPPING.replace("2   1   UY", ",\n2   1   UY").encode()
    message = _error("ansys-mapping", content)
    assert re.search(r"model\.mapping:3: expected 'equation node dof', got ','$", message)
    assert _error("ansys-mapping", b",").endswith(
        "no equation rows (expected lines 'equation node dof')"
    )


def test_ansys_full_header_with_negative_low_word() -> None:
    """Was struct.error (argument out of range) from ansys-mapdl-reader's parse_header."""
    from ansys.mapdl.reader.full import SYMBOLIC_FULL_HEADER_KEYS

    words = np.frombuffer(ansys_full(), dtype="<i4").copy()
    header = 103 + 2  # the .full header record follows the 100-word standard header record
    words[header + SYMBOLIC_FULL_HEADER_KEYS.index("ptrCEl")] = -1
    message = _error("ansys-full", words.tobytes())
    assert message.endswith(
        "file.full: .full header: pointer ptrCE = 4294967295 lies outside the file (200399 "
        "words); the file is damaged"
    )


def test_mat_v5_sparse_with_a_cut_dimension_element() -> None:
    """Was a segmentation fault inside scipy.io.loadmat (its compiled v5 reader): the dimension
    element of the sparse K cut from 8 to 4 bytes. pymorembs now reads v5 files itself."""
    data = bytearray(matlab_v5())
    assert struct.unpack_from("<2I", data, 152) == (5, 8)  # K's dimensions: miINT32, 8 bytes
    data[156:160] = struct.pack("<I", 4)
    message = _error("matlab-v5", bytes(data))
    assert message.endswith(
        "model.mat: damaged MAT-file: dimensions must be 2 or more non-negative int32 numbers"
    )


def test_matrix_market_size_beyond_int64_and_absurd_sizes() -> None:
    """Was OverflowError (size 2**63 - 1) and MemoryError (7 TiB for a size of 10**12)."""
    for size in (2**63 - 1, 10**12):
        content = MM_K.replace("3 3 5", f"{size} {size} 5").encode()
        message = _error("mm-single", content)
        assert re.search(rf"K\.mtx:3: matrix size {size} exceeds the 2147483647 equations", message)
    content = MM_K.replace("3 3 5", "100000000 100000000 5").encode()
    message = _error("mm-single", content)
    assert (
        "K.mtx:3: size line announces a 100000000 x 100000000 matrix but the file holds only 5"
        in (message)
    )


def test_abaqus_node_labels_that_overflow_the_dof_keys() -> None:
    """Was a wrong model: node * 8 wrapped around in int64, so label 2**61 + 1 became node 1."""
    content = (ABAQUS_K + f"{2**61 + 1},1, {2**61 + 1},1, 5.0\n").encode()
    message = _error("abaqus-stiffness", content)
    assert re.search(r"job_STIF1\.mtx:7: node label 2305843009213693953 is out of range", message)
    content = (ABAQUS_K + "99999999999999999999,1, 1,1, 5.0\n").encode()  # beyond int64
    message = _error("abaqus-stiffness", content)
    assert re.search(r"job_STIF1\.mtx:7: row node '9+' is out of range", message), message


def test_abaqus_inp_node_label_beyond_int64() -> None:
    """Was OverflowError when the node list became an int64 array."""
    content = ABAQUS_INP.replace("2, 1.0, 0.0, 0.0", "99999999999999999999, 1.0").encode()
    message = _error("abaqus-inp", content)
    assert re.search(r"job\.inp:6: node label '9+' is out of range", message), message


def test_op4_aset_grid_beyond_int64() -> None:
    """Was OverflowError when the a-set became an int64 dof table."""
    content = OP4_ASET.replace("ASET1,1,2,5", "ASET1,1,2,99999999999999999999").encode()
    message = _error("op4-aset", content)
    assert re.search(r"aset\.bdf:2: ASET1 point id '9+' is out of range", message), message


def test_csv_node_ids_that_overflow_the_dof_keys() -> None:
    """Was a bogus 'appears more than once': node * 8 wrapped around for ids near 2**63."""
    content = DOFS_CSV.replace("2,rz", f"{2**62},rz").encode()
    message = _error("mm-dofs", content)
    assert re.search(r"dofs\.csv:5: node id '4611686018427387904' is out of range", message)


def test_nan_is_named_plainly_and_utf16_is_recognised() -> None:
    """Messages were 'value np.float64(nan) ...' and 'cannot tell the file format'."""
    message = _error("mm-single", MM_K.replace("2.0e3", "NaN", 1).encode())
    assert message.endswith("K.mtx:4: value nan is not a finite number")
    message = _error("detect-text", MM_K.encode("utf-16"))
    assert message.endswith("model.dat: the file is UTF-16 encoded; save it as UTF-8 or ASCII text")
    message = _error("mm-single", MM_K.encode("utf-16-le"))
    assert message.endswith(
        "a binary file, expected a Matrix Market file; it is UTF-16 encoded: "
        "save it as UTF-8 or ASCII text"
    )


def test_op4_thru_range_without_grids_is_bounded_by_the_matrix_size() -> None:
    """Was minutes and gigabytes: 1 THRU 9999999 without GRID cards built 60 million dofs."""
    content = b"ASET1,123456,1,THRU,9999999\n"
    message = _error("op4-aset", content)
    assert re.search(
        r"aset\.bdf:1: 1 THRU 9999999 puts 59999994 dofs in the a-set, more than", message
    )


def test_detected_two_file_format_given_as_one_file() -> None:
    """Was 'option file does not apply to format abaqus; ...', naming no file."""
    content = ascii_op4().split(b"\n", 1)[1]  # an OP4 file without its header line
    message = _error("detect-op4-ascii", content)
    assert re.search(r"model\.dat: the content looks like abaqus, whose matrices come as", message)


def test_a_zero_by_zero_model_is_refused() -> None:
    """Was read as a body without dofs; the error came later, naming no file."""
    content = b"%%MatrixMarket matrix coordinate real symmetric\n0 0 0\n"
    message = _error("mm-stiffness", content)
    assert message.endswith("K.mtx: a 0 x 0 matrix: the model has no dofs")


def test_op4_dense_header_with_an_absurd_size() -> None:
    """Was an allocation of the header's size (MemoryError, or swapping the machine to death)."""
    binary = bytearray(binary_op4())
    binary[4:12] = struct.pack("<2i", 60000, 60000)  # columns and rows of KAAX
    message = _error("op4-binary", bytes(binary))
    assert message.endswith(
        "body.op4: matrix KAAX is 60000 x 60000 in dense format, 26.8 GiB in memory; write it in "
        "sparse format (negative OUTPUT4 unit) or check the header"
    )
    text = ascii_op4().replace(
        b"       3       3       6       2KAAX", b"   60000   60000       6       2KAAX"
    )
    message = _error("op4-ascii", text)
    assert "body.op4:1: matrix KAAX is 60000 x 60000 in dense format" in message


def test_abaqus_coordinate_equation_beyond_the_derived_count() -> None:
    """Was an allocation for 2**31 - 1 equations (17 GB of row pointers, the machine swapped):
    the matrices were assembled before the equation count derived from the .inp was checked."""
    content = (abaqus_assembly()["cube_STIF1.mtx"] + "2147483647 2147483647 1.0\n").encode()
    message = _error("abaqus-coordinate-stiffness", content)
    assert re.search(
        r"cube_STIF1\.mtx: the equation order derived from cube\.inp gives 24 equations \(8 "
        r"nodes x ux uy uz from elements C3D4\) but the matrices have 2147483647",
        message,
    ), message


def test_abaqus_non_ascii_characters_never_reach_numpy() -> None:
    """Was a segmentation fault now and then: NumPy 2.4's loadtxt reads freed memory (valgrind:
    invalid read in npy_to_int64) on some non-ASCII characters in an integer field."""
    message = _error("abaqus-coordinate", "\U000c6c13 1 2\n".encode())
    assert message.endswith(r"c_STIF1.mtx:1: character '\U000c6c13' in a data line; Abaqus "
                            "writes numbers in ASCII")  # fmt: skip
    content = (ABAQUS_K + "** a comment may hold any character: \u00e9\U000c6c13\n").encode()
    with tempfile.TemporaryDirectory() as d:
        assert run_target(TARGETS["abaqus-stiffness"], content, Path(d)) == "ok"
    message = _error("abaqus-inp", ABAQUS_INP.replace("2, 1.0", "2, 1\u00e9").encode())
    assert re.search(r"job\.inp:6: character '\u00e9' in a data line", message), message
