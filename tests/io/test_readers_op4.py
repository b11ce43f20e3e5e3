"""Nastran OP4 files: forms, names, dof tables from dofs.csv or bulk data, genuine EXTSEOUT sets.

The synthetic files are written here (binary records by hand, ASCII by pyNastran's writer). The
genuine ones (``tests/data``: NX 9 and MSC 2017 EXTSEOUT, pyNastran's test files) prove the row
order of external superelements: the rigid-body check, the identity mass block of the modal
coordinates and the fixed-interface frequencies that Nastran printed in the f06.
"""

from __future__ import annotations

import struct
from pathlib import Path

import numpy as np
import pytest
import scipy.linalg as sla
import scipy.sparse as sp

from nastran_reference import f06_cycles
from pymorembs.body import ElasticBody
from pymorembs.errors import UserError
from pymorembs.io.nastran_op4 import read_op4

op4_module = pytest.importorskip("pyNastran.op4.op4")
from pyNastran.op2.result_objects.matrix import Matrix  # noqa: E402

# A chain of four grids (2, 5, 7, 9) with one axial dof each plus a rotation at grid 9; the
# rotation has stiffness but no mass (a zero column in M: a massless dof).
K = np.array(
    [
        [2.0e3, -1.0e3, 0.0, 0.0, 0.0],
        [-1.0e3, 2.0e3, -1.0e3, 0.0, 0.0],
        [0.0, -1.0e3, 2.0e3, -1.0e3, 0.0],
        [0.0, 0.0, -1.0e3, 1.0e3, 50.0],
        [0.0, 0.0, 0.0, 50.0, 30.0],
    ]
)
M = np.diag([1.0, 2.0, 2.0, 1.0, 0.0])
M[0, 1] = M[1, 0] = 0.25
B = 0.01 * K + 0.5 * M
DOFS_CSV = "node,direction\n2,ux\n5,ux\n7,ux\n9,ux\n9,rz\n"
NODES = [2, 5, 7, 9, 9]
DIRS = [0, 0, 0, 0, 5]


def _one_line_error(excinfo: pytest.ExceptionInfo[UserError], path: Path, line: int | None = None):
    message = str(excinfo.value)
    assert "\n" not in message
    prefix = f"{path}:{line}: " if line is not None else f"{path}"
    assert message.startswith(prefix), message
    return message


def _record(payload: bytes) -> bytes:
    """A Fortran unformatted sequential record."""
    return struct.pack("<i", len(payload)) + payload + struct.pack("<i", len(payload))


def write_binary_op4(path: Path, matrices: dict[str, tuple[int, np.ndarray]], sparse: bool):
    """Binary OUTPUT4, real double precision, in the dense (IROW > 0) or sparse (IROW = 0) form.

    pyNastran's binary writer is not usable (it fails for real matrices), so the test writes the
    records itself: header (NCOL, NROW, FORM, TYPE, NAME), one record per non-null column
    (ICOL, IROW, NW, values; sparse: strings headed by IS = IROW + 65536 (L + 1)), and the
    closing record for column NCOL + 1.
    """
    out = b""
    for name, (form, a) in matrices.items():
        nrows, ncols = a.shape
        out += _record(struct.pack("<4i", ncols, nrows, form, 2) + name.ljust(8).encode())
        for j in range(ncols):
            nonzero = np.flatnonzero(a[:, j])
            if nonzero.size == 0:
                continue  # null columns are not written
            if not sparse:
                first, last = nonzero[0], nonzero[-1] + 1
                values = a[first:last, j].astype("<f8")
                head = struct.pack("<3i", j + 1, first + 1, 2 * values.size)
                out += _record(head + values.tobytes())
                continue
            body, n_words = b"", 0
            for run in np.split(nonzero, np.flatnonzero(np.diff(nonzero) != 1) + 1):
                words = 2 * run.size
                body += struct.pack("<i", 65536 * (words + 1) + int(run[0]) + 1)
                body += a[run, j].astype("<f8").tobytes()
                n_words += 1 + words
            out += _record(struct.pack("<3i", j + 1, 0, n_words) + body)
        out += _record(struct.pack("<3i", ncols + 1, 1, 2) + struct.pack("<d", 1.0))
    path.write_bytes(out)


def write_ascii_op4(path: Path, matrices: dict[str, tuple[int, object]]):
    """ASCII OUTPUT4 with pyNastran's writer (dense for arrays, sparse for coo matrices)."""
    op4_module.OP4(debug=None).write_op4(
        str(path),
        {name: Matrix(name, form, data) for name, (form, data) in matrices.items()},
        name_order=list(matrices),
        is_binary=False,
    )


@pytest.fixture
def dofs_csv(tmp_path):
    path = tmp_path / "dofs.csv"
    path.write_text(DOFS_CSV)
    return path


def _check(body):
    np.testing.assert_allclose(body.stiffness.toarray(), K, rtol=1e-15)
    np.testing.assert_allclose(body.mass.toarray(), M, rtol=1e-15)
    np.testing.assert_array_equal(body.dofs.nodes, NODES)
    np.testing.assert_array_equal(body.dofs.directions, DIRS)
    assert body.fixed.size == 0


@pytest.mark.parametrize(
    "kind", ["ascii-dense", "ascii-sparse", "binary-dense", "binary-sparse", "ascii-triangle"]
)
def test_op4_forms(tmp_path, dofs_csv, kind):
    path = tmp_path / "body.op4"
    if kind == "ascii-dense":
        write_ascii_op4(path, {"KAAX": (6, K), "MAAX": (6, M)})
    elif kind == "ascii-sparse":
        write_ascii_op4(path, {"KAAX": (6, sp.coo_matrix(K)), "MAAX": (6, sp.coo_matrix(M))})
    elif kind == "ascii-triangle":  # form 6 with only the lower triangle stored
        write_ascii_op4(path, {"KAAX": (6, np.tril(K)), "MAAX": (6, sp.coo_matrix(np.triu(M)))})
    else:
        sparse = kind == "binary-sparse"
        write_binary_op4(path, {"KAAX": (6, K), "MAAX": (6, M)}, sparse=sparse)
    body = read_op4(path, dofs=dofs_csv)
    _check(body)
    assert body.name == "body" and body.damping_matrix is None


def test_op4_names_damping_and_nodes(tmp_path, dofs_csv):
    path = tmp_path / "model.op4"
    write_binary_op4(
        path,
        {"KAAX": (6, K), "MAAX": (6, M), "BAAX": (6, B), "KGG": (1, 2 * K), "MGG": (1, 2 * M)},
        sparse=True,
    )
    with pytest.raises(
        UserError, match=r"holds several stiffness/mass pairs: KAAX/MAAX \(5 x 5\),"
    ):
        read_op4(path, dofs=dofs_csv)
    body = read_op4(path, stiffness="kaax", dofs=dofs_csv)  # MAAX, and BAAX by default
    np.testing.assert_allclose(body.damping_matrix.toarray(), B, rtol=1e-15)
    assert "BAAX read as the viscous damping matrix" in body.notes
    body = read_op4(path, stiffness="kgg", mass="Mgg", damping="baax", dofs=dofs_csv, name="x")
    np.testing.assert_allclose(body.stiffness.toarray(), 2 * K, rtol=1e-15)
    assert body.name == "x"
    nodes = tmp_path / "nodes.csv"
    nodes.write_text("id,x,y,z\n2,0,0,0\n5,1,0,0\n7,2,0,0\n9,3,0,0.5\n")
    body = read_op4(path, mass="maax", dofs=dofs_csv, nodes=nodes)
    np.testing.assert_array_equal(body.node_position(9), [3.0, 0.0, 0.5])


BULK = """$ a-set of the body (small field, free field, large field, continuation)
SOL 103
CEND
EXTSEOUT(ASMBULK,EXTID=100,MATOP4=30)
BEGIN BULK
PARAM   OLDSEQ  -1
GRID           9        3.0     0.0     0.5
GRID,7,,2.,0.,0.
{grid_large_1}
{grid_large_2}
GRID           2              0.      0.      0.
ASET1   1       2       THRU    7
ASET,9,16
ENDDATA
""".format(
    grid_large_1=f"{'GRID*':<8}{'5':>16}{'':>16}{'1.+0':>16}{'0.0':>16}",
    grid_large_2=f"{'*':<8}{'0.0':>16}",
)


def test_op4_dofs_from_bulk_data(tmp_path):
    path = tmp_path / "body.op4"
    write_ascii_op4(path, {"KAAX": (6, sp.coo_matrix(K)), "MAAX": (6, sp.coo_matrix(M))})
    bulk = tmp_path / "body.bdf"
    bulk.write_text(BULK)
    body = read_op4(path, dofs=bulk)
    _check(body)
    np.testing.assert_array_equal(body.node_ids, [2, 5, 7, 9])
    np.testing.assert_allclose(body.coordinates[:, 0], [0.0, 1.0, 2.0, 3.0])
    np.testing.assert_array_equal(body.node_position(9), [3.0, 0.0, 0.5])
    # without GRID cards the THRU range takes every id (and the size check catches the excess)
    no_grids = tmp_path / "aset.dat"
    no_grids.write_text("ASET1,1,2,5,7\nASET,9,61\n")
    body = read_op4(path, dofs=no_grids)
    _check(body)
    assert np.all(body.coordinates == 0.0)
    thru = tmp_path / "thru.dat"
    thru.write_text("ASET1,1,2,THRU,7\nASET,9,61\n")
    with pytest.raises(UserError, match=r"8 dofs but matrix KAAX in .* is 5 x 5") as excinfo:
        read_op4(path, dofs=thru)
    _one_line_error(excinfo, thru)


@pytest.mark.parametrize(
    ("text", "line", "pattern"),
    [
        ("ASET1,1,2,5,7\nQSET1,0,101,THRU,110\n", None, "13 dofs but matrix KAAX"),
        ("GRID,2,,0.,0.,0.,3\nASET1,1,2,5,7\nASET,9,16\n", 1, "CD of GRID 2: coordinate system 3"),
        ("ASET1,1,2,5,7\nASET,9,0\n", 2, "scalar point"),
        ("ASET1,1,2,5,7\nASET,9,17\n", 2, "component '17'"),
        ("ASET1,1,2,5,7\nSEQGP,9,1\nASET,9,16\n", 2, "SEQGP"),
        ("GRID,2,1,0.,0.,0.\nASET1,1,2,5,7\nASET,9,16\n", 1, "CP of GRID 2: coordinate system 1"),
        ("GRID,2,,0.,abc,0.\nASET1,1,2,5,7\nASET,9,16\n", 1, "'abc' is not a number"),
    ],
)
def test_op4_bad_bulk_data(tmp_path, text, line, pattern):
    path = tmp_path / "body.op4"
    write_ascii_op4(path, {"KAAX": (6, K), "MAAX": (6, M)})
    bulk = tmp_path / "aset.bdf"
    bulk.write_text(text + "GRID,5,,1.,0.,0.\nGRID,7,,2.,0.,0.\nGRID,9,,3.,0.,0.\n")
    with pytest.raises(UserError) as excinfo:
        read_op4(path, dofs=bulk)
    message = _one_line_error(excinfo, bulk, line)
    assert pattern in message, message


def test_op4_missing_matrix_and_sizes(tmp_path, dofs_csv):
    path = tmp_path / "body.op4"
    write_ascii_op4(path, {"KAAX": (6, K), "MAAX": (6, M)})
    with pytest.raises(
        UserError, match=r"no matrix named KGG \(stiffness\); the file holds: KAAX, MAAX"
    ):
        read_op4(path, stiffness="KGG", dofs=dofs_csv)
    with pytest.raises(UserError, match=r"no matrix named BHH \(damping\)") as e:
        read_op4(path, damping="BHH", dofs=dofs_csv)
    _one_line_error(e, path)
    body = read_op4(path)  # no dof table: scalar coordinates 1..5
    assert body.dofs.describe() == "5 scalar coordinates (q)" and body.n_nodes == 0
    assert body.dofs.nodes.tolist() == [1, 2, 3, 4, 5] and not body.has_coordinates
    assert any(note.startswith("no dof table: the 5 equations") for note in body.notes)
    short = tmp_path / "short.csv"
    short.write_text("node,direction\n2,ux\n5,ux\n7,ux\n9,ux\n")
    with pytest.raises(UserError, match="4 dofs but matrix KAAX") as e:
        read_op4(path, dofs=short)
    _one_line_error(e, short)

    mismatch = tmp_path / "mismatch.op4"
    write_ascii_op4(mismatch, {"KAAX": (6, K), "MAAX": (6, M[:4, :4])})
    with pytest.raises(UserError, match="matrix MAAX is 4 x 4 but KAAX is 5 x 5") as e:
        read_op4(mismatch, dofs=dofs_csv)
    _one_line_error(e, mismatch)


def test_op4_bad_matrices(tmp_path, dofs_csv):
    unsymmetric = K.copy()
    unsymmetric[0, 1] = -900.0
    path = tmp_path / "bad.op4"
    write_binary_op4(path, {"KAAX": (1, unsymmetric), "MAAX": (6, M)}, sparse=False)
    with pytest.raises(UserError, match="matrix KAAX: matrix is not symmetric") as e:
        read_op4(path, dofs=dofs_csv)
    _one_line_error(e, path)
    empty = M.copy()
    empty[3, 3] = 0.0
    k = K.copy()
    k[3, :] = k[:, 3] = 0.0
    write_binary_op4(path, {"KAAX": (6, k), "MAAX": (6, empty)}, sparse=True)
    body = read_op4(path, dofs=dofs_csv)  # a dof nothing touches: fixed, as AUTOSPC would
    assert body.fixed.tolist() == [3]
    assert "1 dofs have neither stiffness nor mass (9:ux): fixed" in " ".join(body.notes)
    rect = tmp_path / "rect.op4"
    write_ascii_op4(rect, {"KAAX": (2, K[:, :4]), "MAAX": (6, M)})
    with pytest.raises(UserError, match=r"holds no stiffness and mass matrices: KAAX \(5 x 4\)"):
        read_op4(rect, dofs=dofs_csv)
    with pytest.raises(UserError, match="5 x 4, not square"):
        read_op4(rect, stiffness="KAAX", dofs=dofs_csv)


@pytest.mark.parametrize("kind", ["ascii", "binary"])
def test_op4_truncated_and_not_op4(tmp_path, dofs_csv, kind):
    path = tmp_path / "body.op4"
    if kind == "ascii":
        write_ascii_op4(path, {"KAAX": (6, sp.coo_matrix(K)), "MAAX": (6, sp.coo_matrix(M))})
    else:
        write_binary_op4(path, {"KAAX": (6, K), "MAAX": (6, M)}, sparse=True)
    data = path.read_bytes()
    cut = tmp_path / "cut.op4"
    for size in (1, 30, len(data) // 3, len(data) - 40):
        cut.write_bytes(data[:size])
        with pytest.raises(UserError) as excinfo:
            read_op4(cut, dofs=dofs_csv)
        _one_line_error(excinfo, cut)
    text = tmp_path / "notes.op4"
    text.write_text("this is not an OP4 file\n")
    with pytest.raises(UserError, match="cannot read the OP4 file") as excinfo:
        read_op4(text, dofs=dofs_csv)
    _one_line_error(excinfo, text)
    with pytest.raises(UserError, match="file not found"):
        read_op4(tmp_path / "missing.op4", dofs=dofs_csv)


# ============================================================================ genuine EXTSEOUT
DATA = Path(__file__).parents[1] / "data"
YETI = DATA / "pyyeti_nx_extseout"
NOTALL6 = YETI / "reduced_bset_notall6"
N11 = DATA / "pynastran" / "superelement_se_test_n11"
#: outboard.out (not copied), line 599 ff.: the fixed-interface modes of SE 101 [Hz]
OUTBOARD_MODES = [
    1.650001, 1.650249, 1.674265, 1.674687, 7.025350, 7.025411, 10.91274, 10.91454,
    13.98578, 13.99172, 25.13473, 25.13995, 42.17271, 42.19338, 46.71595, 46.89473,
]  # fmt: skip


def fixed_interface(body) -> np.ndarray:
    """Frequencies of the modal block (dense generalized eigenproblem, computed here)."""
    q = np.flatnonzero(body.dofs.scalar)
    k = body.stiffness[q][:, q].toarray()
    m = body.mass[q][:, q].toarray()
    return np.sqrt(np.abs(sla.eigh(k, m, eigvals_only=True))) / (2 * np.pi)


def reordered(body, order: np.ndarray):
    """The same matrices with the dof table permuted (a wrong row order on purpose)."""
    table = body.dofs.subset(order)
    return ElasticBody(
        node_ids=body.node_ids,
        coordinates=body.coordinates,
        dofs=table,
        mass=body.mass,
        stiffness=body.stiffness,
    )


def test_nx_inboard_craig_bampton_superelement() -> None:
    """NX 9 EXTSEOUT of SE 102: KXX/MXX rows = boundary grids x 123456, then SPOINTs, ascending."""
    body = read_op4(YETI / "inboard.op4", dofs=YETI / "inboard.pch")
    assert body.dofs.describe() == "4 nodes x ux uy uz rx ry rz + 8 scalar coordinates (q)"
    assert body.dofs.nodes[:24].tolist() == [g for g in (3, 11, 19, 27) for _ in range(6)]
    assert body.dofs.nodes[24:].tolist() == list(range(2995001, 2995009))
    assert (
        "Craig-Bampton superelement 102: 4 nodes x ux uy uz rx ry rz (24 boundary dofs) + 8 "
        "modal coordinates (SPOINT 2995001-2995008)"
    ) in body.notes
    q = np.flatnonzero(body.dofs.scalar)
    np.testing.assert_array_equal(body.mass[q][:, q].toarray(), np.eye(8))
    assert not body.stiffness[q][:, np.flatnonzero(~body.dofs.scalar)].count_nonzero()
    assert np.nanmax(body.rigid_body_residuals()) < 1e-13  # order, coordinates and CD right
    # the component modes Nastran printed (f06, after residual vector augmentation; 8 kept)
    published = f06_cycles(YETI / "inboard.out", "(AFTER AUGMENTATION OF RESIDUAL VECTORS)")
    np.testing.assert_allclose(fixed_interface(body), published[:8], rtol=1e-6)
    # wrong alternatives fail the checks: modal coordinates first, or no CD rotation of grid 11
    first = reordered(body, np.r_[24:32, 0:24])
    assert np.nanmax(first.rigid_body_residuals()) > 1e-3
    no_cd = [n for n in body.notes if n.startswith("without the CD rotation")]
    assert no_cd == ["without the CD rotation the rigid-body residual would be 7.8e-03"]
    # the ASMBULK .asm and the f06 of the run (BSET1/QSET1 echoed) give the same dof table
    for dofs in (YETI / "inboard.asm", YETI / "inboard.out"):
        other = read_op4(YETI / "inboard.op4", dofs=dofs)
        np.testing.assert_array_equal(other.dofs.nodes, body.dofs.nodes)
        np.testing.assert_array_equal(other.dofs.directions, body.dofs.directions)
        np.testing.assert_array_equal(other.stiffness.toarray(), body.stiffness.toarray())


def test_coordinates_without_a_dof_table_are_refused_in_one_line(capsys) -> None:
    """GRID cards beside an OP4 that has no dof table: no equation belongs to a grid, so the
    coordinates cannot be used; said before any eigen-analysis (was a crash in info)."""
    from pymorembs.job.cli import main

    with pytest.raises(UserError, match="no equation of the matrices belongs to a grid"):
        read_op4(YETI / "inboard.op4", nodes=YETI / "inboard.blk")
    assert main(["info", str(YETI / "inboard.op4"), "--nodes", str(YETI / "inboard.blk")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "give the dof table as well" in err[0], err


def test_nx_outboard_craig_bampton_superelement() -> None:
    body = read_op4(YETI / "outboard.op4", dofs=YETI / "outboard.pch")
    assert body.dofs.describe() == "4 nodes x ux uy uz rx ry rz + 22 scalar coordinates (q)"
    assert np.nanmax(body.rigid_body_residuals()) < 1e-13
    np.testing.assert_allclose(fixed_interface(body)[:16], OUTBOARD_MODES, rtol=1e-6)


def test_boundary_grid_with_one_component() -> None:
    """EXTSEOUT of SE 75: grid 475 in the b-set with component 2 only (pyyeti's edge case)."""
    body = read_op4(NOTALL6 / "reduced_bset_notall6.op4", dofs=NOTALL6 / "reduced_bset_notall6.pch")
    assert body.n_dof == 29
    assert body.dofs.label(18) == "475:uy" and body.dofs.label(19) == "7590001:q"
    q = np.flatnonzero(body.dofs.scalar)
    np.testing.assert_array_equal(body.mass.diagonal()[q], 1.0)  # what pyyeti's test asserts
    np.testing.assert_allclose(body.mass[q][:, q].toarray(), np.eye(10), atol=1e-12)
    assert np.nanmax(body.rigid_body_residuals()) < 1e-10
    assert ["KAA (stiffness) and MAA (mass)" in n for n in body.notes].count(True) == 1
    with pytest.raises(UserError) as err:  # the .asm lists no components: six are assumed
        read_op4(NOTALL6 / "reduced_bset_notall6.op4", dofs=NOTALL6 / "reduced_bset_notall6.asm")
    assert str(err.value).endswith(
        "34 dofs but matrix KAA in "
        f"{NOTALL6 / 'reduced_bset_notall6.op4'} is 29 x 29 (the .asm does not list the "
        "components of its grids; give the EXTBULK .pch)"
    )


def test_msc_superelement_with_coordinate_systems() -> None:
    """MSC 2017 EXTSEOUT of SE 111 (ASCII, single precision), grids in CORD2R systems.

    Its EXTBULK leaves CD blank on grids 20110031 and 20110038 (CP = 20110001). Read as basic,
    the rigid-body check fails (2.3e-3) although the matrices have six zero modes (the dense
    solution below); read as CD = CP it passes at the single-precision level: the reader takes
    that reading and says so. M_qq = I and K_bq = 0 confirm the Craig-Bampton rows.
    """
    body = read_op4(N11 / "se_test_n11.op4", dofs=N11 / "se_test_n11.pch")
    assert body.dofs.describe() == "11 nodes x ux uy uz rx ry rz + 39 scalar coordinates (q)"
    q, b = np.flatnonzero(body.dofs.scalar), np.flatnonzero(~body.dofs.scalar)
    np.testing.assert_array_equal(body.mass[q][:, q].toarray(), np.eye(39))
    assert not body.stiffness[b][:, q].count_nonzero()
    fixed = [body.dofs.label(i) for i in body.fixed]
    grids = (20110031, 20110032, 20110033, 20110034, 20110038)
    assert fixed == [f"{g}:{d}" for g in grids for d in ("rx", "ry", "rz")]
    assert "KAA, MAA: real single precision (OP4 type 1)" in body.notes
    assert np.nanmax(body.rigid_body_residuals()) < 1e-8
    assert any(n.startswith("grids 20110031, 20110038 have a blank CD") for n in body.notes)
    keep = np.setdiff1d(np.arange(body.n_dof), body.fixed)
    k = body.stiffness.toarray()[np.ix_(keep, keep)]
    m = body.mass.toarray()[np.ix_(keep, keep)]
    frequencies = np.sqrt(np.abs(sla.eigh(k, m, eigvals_only=True))) / (2 * np.pi)
    assert frequencies[5] < 0.2 and frequencies[6] > 100  # free: six rigid-body modes


def test_op4_without_dof_table_and_without_mass() -> None:
    body = read_op4(DATA / "pynastran" / "extse_op4" / "extse10.op4")
    assert body.dofs.describe() == "12 scalar coordinates (q)"
    assert body.stiffness.nnz == 72 and body.mass.nnz == 72
    path = DATA / "pynastran" / "testplate_kgg" / "testplate_kgg.op4"
    with pytest.raises(UserError) as err:
        read_op4(path)
    assert str(err.value) == (
        f"{path}: holds KGG (stiffness, 726 x 726) but no mass matrix (no MGG); export the mass "
        "matrix too or name it with --mass-name"
    )
