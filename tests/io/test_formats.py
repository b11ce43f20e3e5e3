"""Format detection from file content and the read_body dispatcher."""

from __future__ import annotations

import struct
import sys
import types
from pathlib import Path

import numpy as np
import pytest
import scipy.sparse as sp

from pymorembs.body import DofTable, ElasticBody
from pymorembs.errors import UserError
from pymorembs.io.formats import FORMATS, detect_format, read_body
from pymorembs.io.matrix_market import write_matrix_files, write_matrix_market
from pymorembs.io.native import write_body_h5
from pymorembs.io.reader_support import assemble_symmetric

ABAQUS_K = "1,1, 1,1, 4.0\n1,2, 1,1, 1.0D+00\n1,2, 1,2, 3.0\n"
ABAQUS_M = "1,1, 1,1, 2.0\n1,2, 1,2, 2.0\n"
DMIG = (
    "$ punch\n"
    "DMIG    KAAX           0       6       1       0                       2\n"
    "DMIG    KAAX           1       1               1       1      4.\n"
    "DMIG    KAAX           1       2               1       1      1.\n"
    "+       " + "       1       2      3.\n"
    "DMIG    MAAX           0       6       1       0                       2\n"
    "DMIG    MAAX           1       1               1       1      2.\n"
    "DMIG    MAAX           1       2               1       2      2.\n"
)
K_DENSE = np.array([[4.0, 1.0], [1.0, 3.0]])
M_DENSE = np.diag([2.0, 2.0])


def small_body(name: str = "small") -> ElasticBody:
    return ElasticBody(
        node_ids=np.array([1]),
        coordinates=np.zeros((1, 3)),
        dofs=DofTable(np.array([1, 1]), np.array([0, 1])),
        mass=sp.csr_matrix(M_DENSE),
        stiffness=sp.csr_matrix(K_DENSE),
        name=name,
    )


def write(path: Path, content: str | bytes) -> Path:
    if isinstance(content, bytes):
        path.write_bytes(content)
    else:
        path.write_text(content)
    return path


def one_line(err: pytest.ExceptionInfo[UserError]) -> str:
    message = str(err.value)
    assert "\n" not in message
    return message


# ============================================================================ detection
def test_detect_each_format_despite_misleading_names(tmp_path: Path) -> None:
    assert detect_format(write_body_h5(small_body(), tmp_path / "model.txt")) == "native"
    mm = write_matrix_market(tmp_path / "k.pch", sp.csr_matrix(K_DENSE))
    assert detect_format(mm) == "matrix-market"
    assert detect_format(write(tmp_path / "k.op4", ABAQUS_K)) == "abaqus"
    coordinate = "** coordinate layout\n\n1 1 4.0\n2 1 1.0\n2 2 3.0\n"
    assert detect_format(write(tmp_path / "c.h5", coordinate)) == "abaqus"
    assert detect_format(write(tmp_path / "d.mtx", DMIG)) == "nastran-dmig"
    op4_ascii = "       2       2       6       2KAAX    1P,3E23.16\n       1       1       2\n"
    assert detect_format(write(tmp_path / "o.mtx", op4_ascii)) == "nastran-op4"
    op4_binary = struct.pack("<5i8si", 24, 2, 2, 6, 2, b"KAAX    ", 24) + bytes(64)
    assert detect_format(write(tmp_path / "o.full", op4_binary)) == "nastran-op4"
    op4_big_endian = struct.pack(">5i8si", 24, 2, 2, 6, 2, b"MAAX    ", 24)
    assert detect_format(write(tmp_path / "o.bin", op4_big_endian)) == "nastran-op4"
    full = struct.pack("<3i", 100, 0, 4) + bytes(400)
    assert detect_format(write(tmp_path / "f.pch", full)) == "ansys-full"


def test_detect_dmig_after_other_punch_output(tmp_path: Path) -> None:
    """DMIG cards far into the file (after 100 kB of other punch output) are still found."""
    other = "$TITLE   = displacements\n" + "$ other output\n" * 8000
    assert detect_format(write(tmp_path / "x.txt", other + DMIG)) == "nastran-dmig"


def test_detect_directory(tmp_path: Path) -> None:
    write_matrix_files(small_body(), tmp_path / "body")
    assert detect_format(tmp_path / "body") == "matrix-market"
    (tmp_path / "empty").mkdir()
    with pytest.raises(UserError, match=r"without K\.mtx"):
        detect_format(tmp_path / "empty")


def test_real_ansys_full_file_if_installed() -> None:
    examples = pytest.importorskip("ansys.mapdl.reader.examples")
    full = Path(examples.__file__).parent / "file.full"
    rst = Path(examples.__file__).parent / "file.rst"
    if not full.exists():
        pytest.skip("ansys-mapdl-reader ships no example .full file")
    assert detect_format(full) == "ansys-full"
    with pytest.raises(UserError, match=r"result file \(\.rst\)") as err:
        detect_format(rst)
    one_line(err)


@pytest.mark.parametrize(
    ("content", "words"),
    [
        ("node,direction\n1,ux\n", ""),
        ("", "the file is empty"),
        ("*HEADING\n*NODE\n1, 0., 0., 0.\n", "Abaqus input file"),
        (b"\x00\x01\x02\x03binary", ""),
        ("1,1,1,1\n", ""),
    ],
)
def test_unknown_content(tmp_path: Path, content: str | bytes, words: str) -> None:
    path = write(tmp_path / "model.pch", content)
    with pytest.raises(UserError) as err:
        detect_format(path)
    message = one_line(err)
    assert message.startswith(f"{path}: cannot tell the file format")
    assert message.endswith(f"give --format (format= in Python; one of {', '.join(FORMATS)})")
    assert words in message
    if not words:
        assert "the name suggests nastran-dmig" in message


def test_missing_file(tmp_path: Path) -> None:
    with pytest.raises(UserError, match="file not found"):
        detect_format(tmp_path / "nothing.h5")


# ============================================================================ read_body
def test_read_body_detects_abaqus_and_dmig(tmp_path: Path) -> None:
    k = write(tmp_path / "job_STIF1.mtx", ABAQUS_K)
    m = write(tmp_path / "job_MASS1.mtx", ABAQUS_M)
    body = read_body(stiffness=k, mass=m)
    assert body.name == "job"
    np.testing.assert_array_equal(body.stiffness.toarray(), K_DENSE)
    np.testing.assert_array_equal(body.mass.toarray(), M_DENSE)
    body = read_body(file=write(tmp_path / "model.pch", DMIG), name="dm")
    assert body.name == "dm"
    np.testing.assert_array_equal(body.stiffness.toarray(), K_DENSE)
    np.testing.assert_array_equal(body.mass.toarray(), M_DENSE)


def test_format_override(tmp_path: Path) -> None:
    """An explicit format skips detection; the wrong one fails in the reader."""
    k = write(tmp_path / "k.bin", ABAQUS_K)
    m = write(tmp_path / "m.bin", ABAQUS_M)
    body = read_body(format="Abaqus", stiffness=k, mass=m)
    np.testing.assert_array_equal(body.stiffness.toarray(), K_DENSE)
    dmig = write(tmp_path / "k.mtx", DMIG)
    body = read_body(format="nastran_dmig", file=dmig, stiffness_name="kaax", mass_name="Maax")
    np.testing.assert_array_equal(body.mass.toarray(), M_DENSE)
    with pytest.raises(UserError, match="holds no DMIG matrices") as err:
        read_body(format="nastran-dmig", file=k)
    one_line(err)
    with pytest.raises(UserError, match="unknown format 'ansys'"):
        read_body(format="ansys", file=k)


def test_native_with_name_constraints_and_fixed(tmp_path: Path) -> None:
    h5 = write_body_h5(small_body(), tmp_path / "b.h5")
    fixed = write(tmp_path / "fixed.csv", "node,direction\n1,uy\n")
    constraints = write(
        tmp_path / "constraints.csv",
        "dependent_node,dependent_direction,offset,node,direction,coefficient\n1,uy,0.0,1,ux,0.5\n",
    )
    body = read_body(file=h5, name="renamed", fixed=fixed, constraints=constraints)
    assert body.name == "renamed"
    assert body.fixed.tolist() == [1]
    assert body.constraints.dependent.tolist() == [1]
    assert body.constraints.matrix.toarray().tolist() == [[0.5, 0.0]]


def test_matrix_market_files_and_directory(tmp_path: Path) -> None:
    paths = write_matrix_files(small_body(), tmp_path / "body")
    body = read_body(stiffness=paths["stiffness"], mass=paths["mass"], dofs=paths["dofs"])
    assert body.dofs.label(1) == "1:uy"
    body = read_body(file=tmp_path / "body", name="dir")
    assert body.name == "dir"
    np.testing.assert_array_equal(body.stiffness.toarray(), K_DENSE)
    with pytest.raises(UserError, match="not both"):
        read_body(format="matrix-market", file=tmp_path / "body", stiffness=paths["stiffness"])


def fake_module(monkeypatch: pytest.MonkeyPatch, name: str, **functions) -> list:
    """Install a stand-in for a reader module written elsewhere; return its call log."""
    calls: list = []
    module = types.ModuleType(name)
    for function in functions:

        def reader(*args, _name=function, **kwargs):
            calls.append((_name, args, kwargs))
            return small_body("fake")

        setattr(module, function, reader)
    monkeypatch.setitem(sys.modules, name, module)
    return calls


def test_dispatch_to_ansys_and_op4(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    ansys = fake_module(monkeypatch, "pymorembs.io.ansys", read_ansys_full=1, read_ansys_mmf=1)
    op4 = fake_module(monkeypatch, "pymorembs.io.nastran_op4", read_op4=1)
    full = write(tmp_path / "a.full", struct.pack("<3i", 100, 0, 4) + bytes(64))
    read_body(file=full, nodes=tmp_path / "n.csv", name="a")
    assert ansys[-1] == ("read_ansys_full", (full,), {"nodes": tmp_path / "n.csv", "name": "a"})
    k = write_matrix_market(tmp_path / "k.mtx", sp.csr_matrix(K_DENSE))
    m = write_matrix_market(tmp_path / "m.mtx", sp.csr_matrix(M_DENSE))
    mapping = write(tmp_path / "k.mapping", "whatever\n")
    read_body(stiffness=k, mass=m, mapping=mapping)
    assert ansys[-1] == (
        "read_ansys_mmf",
        (k, m, mapping),
        {"damping": None, "nodes": None, "name": None},
    )
    op4_file = write(tmp_path / "x.op4", struct.pack("<5i8si", 24, 2, 2, 6, 2, b"KAAX    ", 24))
    body = read_body(file=op4_file, stiffness_name="KXX", damping="BAAX", dofs=tmp_path / "d.csv")
    assert body.name == "fake"
    assert op4[-1] == (
        "read_op4",
        (op4_file,),
        {
            "dofs": tmp_path / "d.csv",
            "nodes": None,
            "name": None,
            "stiffness": "KXX",
            "damping": "BAAX",
        },
    )


@pytest.mark.parametrize(
    ("fmt", "options", "words"),
    [
        ("abaqus", {"mapping": "x.map"}, "option mapping does not apply to format abaqus"),
        ("nastran-dmig", {"inp": "a.inp", "dofs": "d.csv"}, "options dofs, inp do not apply"),
        ("native", {"stiffness": "k.mtx"}, "option stiffness does not apply to format native"),
        ("matrix-market", {"mapping": "m"}, "option mapping does not apply"),
        ("abaqus", {"stiffness": "k.mtx"}, "no mass file given"),
        ("ansys-mmf", {"stiffness": "k", "mass": "m"}, "missing: mapping"),
        ("nastran-op4", {}, "missing: file"),
        (None, {}, "no model given"),
    ],
)
def test_option_errors(fmt: str | None, options: dict, words: str) -> None:
    with pytest.raises(UserError) as err:
        read_body(format=fmt, **options)
    assert words in one_line(err)


def test_detected_format_rejects_foreign_options(tmp_path: Path) -> None:
    k = write(tmp_path / "k.mtx", ABAQUS_K)
    with pytest.raises(UserError, match="option mapping does not apply to format abaqus"):
        read_body(stiffness=k, mass=k, mapping=tmp_path / "map.txt")


# ============================================================================ assembly
def test_assemble_symmetric_both_triangles_and_duplicates() -> None:
    rows = np.array([0, 1, 0, 1, 1])
    cols = np.array([0, 0, 1, 1, 0])
    values = np.array([2.0, -1.0, -1.0, 3.0, -1.0])
    lines = [10, 11, 12, 13, 14]
    matrix = assemble_symmetric(
        rows, cols, values, 3, path=Path("f"), line_of=lines.__getitem__, label=str
    )
    np.testing.assert_array_equal(matrix.toarray(), [[2, -1, 0], [-1, 3, 0], [0, 0, 0]])
    values[4] = -2.0
    with pytest.raises(UserError, match=r"^f:14: entry \(1, 0\) = -2.0 is given again"):
        assemble_symmetric(
            rows, cols, values, 3, path=Path("f"), line_of=lines.__getitem__, label=str
        )


# ============================================================================ byte order marks
BOM = b"\xef\xbb\xbf"


def with_bom(path: Path) -> Path:
    """The file as a Windows editor saves UTF-8 text: a byte order mark in front."""
    path.write_bytes(BOM + path.read_bytes())
    return path


def test_text_files_with_a_byte_order_mark_read_as_without(tmp_path: Path) -> None:
    """Issue #16: files saved by Windows editors start with a UTF-8 byte order mark."""
    from pymorembs.io.reader_support import is_nodes_csv

    paths = write_matrix_files(small_body(), tmp_path / "body")
    for path in paths.values():
        with_bom(path)
    assert detect_format(paths["stiffness"]) == "matrix-market"
    assert is_nodes_csv(paths["nodes"])
    body = read_body(
        stiffness=paths["stiffness"], mass=paths["mass"], dofs=paths["dofs"], nodes=paths["nodes"]
    )
    np.testing.assert_array_equal(body.stiffness.toarray(), K_DENSE)
    np.testing.assert_array_equal(body.mass.toarray(), M_DENSE)
    assert body.dofs.label(1) == "1:uy"
    for name, text in [("k.inp", ABAQUS_K), ("d.pch", DMIG)]:
        path = tmp_path / name
        path.write_bytes(BOM + text.encode())
        assert detect_format(path) == ("abaqus" if name == "k.inp" else "nastran-dmig")
    body = read_body(file=tmp_path / "d.pch")
    np.testing.assert_array_equal(body.stiffness.toarray(), K_DENSE)


def test_missing_dofs_csv_is_named_not_nodes_csv(tmp_path: Path) -> None:
    """Issue #16: without dofs.csv the generic dof table (equation i: ux of node i) meets the
    real node ids of nodes.csv; the message named nodes.csv as the broken file."""
    paths = write_matrix_files(small_body(), tmp_path / "body")
    paths["dofs"].unlink()
    for options in [
        {"file": tmp_path / "body"},
        {k: paths[k] for k in ("stiffness", "mass", "nodes")},
    ]:
        with pytest.raises(UserError) as err:
            read_body(**options)
        message = one_line(err)
        assert message.startswith(f"{paths['stiffness']}: no dof table (dofs.csv) given")
        assert "equation 2 is ux of node 2" in message and message.endswith("does not list")
