"""Readers for Ansys exports: the binary .full file and Matrix Market files with a mapping file."""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pytest
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from pymorembs.errors import UserError
from pymorembs.io.ansys import read_ansys_full, read_ansys_mmf

examples = pytest.importorskip("ansys.mapdl.reader.examples")


def _one_line_error(excinfo: pytest.ExceptionInfo[UserError], path: Path, line: int | None = None):
    """The message is one line that starts with the file (and line)."""
    message = str(excinfo.value)
    assert "\n" not in message
    prefix = f"{path}:{line}: " if line is not None else f"{path}"
    assert message.startswith(prefix), message
    return message


# ============================================================================ .full
@pytest.fixture(scope="module")
def full_body():
    return read_ansys_full(examples.fullfile)


def test_full_example_eigenfrequencies(full_body):
    """First four eigenfrequencies of the library's example with the fixed dofs eliminated."""
    body = full_body
    assert body.n_dof == 963
    assert body.name == "file"
    for matrix in (body.stiffness, body.mass):
        assert abs(matrix - matrix.T).max() == 0.0
        assert sp.tril(matrix, -1).nnz > 0 and sp.triu(matrix, 1).nnz > 0  # both triangles
    free = np.setdiff1d(np.arange(body.n_dof), body.fixed)
    k = body.stiffness[free][:, free].tocsc()
    m = body.mass[free][:, free].tocsc()
    eigenvalues = spla.eigsh(k, k=6, M=m, sigma=0.0, which="LM", return_eigenvectors=False)
    frequencies = np.sort(np.sqrt(eigenvalues))[:4] / (2 * np.pi)
    np.testing.assert_allclose(frequencies, [1283.20, 1283.20, 5781.97, 6919.40], rtol=1e-4)


def test_full_fixed_dofs_and_dof_table(full_body):
    """Constrained dofs become fixed dofs with empty rows; the dof table matches the library."""
    from ansys.mapdl.reader import read_binary

    body = full_body
    full = read_binary(examples.fullfile)
    dof_ref, _, _ = full.load_km(sort=False)
    np.testing.assert_array_equal(body.dofs.nodes, dof_ref[:, 0])
    np.testing.assert_array_equal(body.dofs.directions, dof_ref[:, 1])  # UX UY UZ only
    constrained = {(int(n), int(d)) for n, d in full.const}
    fixed = {(int(body.dofs.nodes[i]), int(body.dofs.directions[i])) for i in body.fixed}
    assert fixed == constrained and len(fixed) == 63
    assert body.stiffness[body.fixed].nnz == 0 and body.mass[body.fixed].nnz == 0
    assert body.damping_matrix is None
    assert np.all(body.coordinates == 0.0)


def test_full_with_nodes_csv(tmp_path):
    body0 = read_ansys_full(examples.fullfile)
    ids = np.unique(body0.dofs.nodes)
    rows = [f"{n},{0.5 * n},{-1.25 * n},{2.0}" for n in ids[::-1]] + ["99999,1,2,3"]
    nodes = tmp_path / "nodes.csv"
    nodes.write_text("id,x,y,z\n" + "\n".join(rows) + "\n")
    body = read_ansys_full(examples.fullfile, nodes=nodes, name="block")
    assert body.name == "block"
    np.testing.assert_array_equal(body.node_position(ids[3]), [0.5 * ids[3], -1.25 * ids[3], 2.0])
    short = tmp_path / "short.csv"
    short.write_text("id,x,y,z\n" + "\n".join(rows[1:]) + "\n")
    with pytest.raises(UserError) as excinfo:
        read_ansys_full(examples.fullfile, nodes=short)
    assert f"node {ids[-1]} " in _one_line_error(excinfo, short)


@pytest.mark.parametrize("size", [0, 30, 500, 2000, 300_000, 801_592])
def test_full_truncated(tmp_path, size):
    path = tmp_path / "cut.full"
    path.write_bytes(Path(examples.fullfile).read_bytes()[:size])
    with pytest.raises(UserError) as excinfo:
        read_ansys_full(path)
    _one_line_error(excinfo, path)


def test_full_corrupt_matrix_block(tmp_path):
    """A damaged record length inside the stiffness block is caught before the C reader."""
    data = bytearray(Path(examples.fullfile).read_bytes())
    pointer = 536  # ptrSTF of the example file (words)
    data[4 * pointer : 4 * pointer + 4] = (10**6).to_bytes(4, "little")
    path = tmp_path / "bad.full"
    path.write_bytes(bytes(data))
    with pytest.raises(UserError, match="stiffness matrix: damaged record") as excinfo:
        read_ansys_full(path)
    _one_line_error(excinfo, path)


def test_full_wrong_files(tmp_path):
    text = tmp_path / "notes.full"
    text.write_text("this is a text file, not a matrix file\n" * 20)
    with pytest.raises(UserError, match="not an Ansys binary file") as excinfo:
        read_ansys_full(text)
    _one_line_error(excinfo, text)
    rst = tmp_path / "result.full"
    shutil.copy(examples.rstfile, rst)
    with pytest.raises(UserError, match=r"Result File, not a \.full file") as excinfo:
        read_ansys_full(rst)
    _one_line_error(excinfo, rst)
    with pytest.raises(UserError, match="file not found") as excinfo:
        read_ansys_full(tmp_path / "missing.full")
    _one_line_error(excinfo, tmp_path / "missing.full")
    with pytest.raises(UserError, match="is a directory"):
        read_ansys_full(tmp_path)


# ============================================================================ MMF + mapping
# A spring-mass model: node 10 (UX, UY), node 20 (UX), node 30 (ROTZ).
K = np.array(
    [
        [3.0e4, -1.0e3, -2.0e4, 0.0],
        [-1.0e3, 2.0e4, 0.0, -5.0e2],
        [-2.0e4, 0.0, 3.5e4, -1.5e3],
        [0.0, -5.0e2, -1.5e3, 4.0e3],
    ]
)
M = np.array(
    [
        [2.0, 0.1, 0.0, 0.0],
        [0.1, 2.0, 0.0, 0.0],
        [0.0, 0.0, 1.5, 0.0],
        [0.0, 0.0, 0.0, 0.02],
    ]
)
D = 1e-3 * K
NODES = [10, 10, 20, 30]
DIRS = [0, 1, 0, 5]

MAPPING = """Matrix Eqn   Node   DOF

       1       10     UX
       2       10     UY
       3       20     UX
       4       30   ROTZ
"""


def _mtx_lower(matrix: np.ndarray, comment: bool = True) -> str:
    """Matrix Market with symmetric storage (lower triangle), comments and blank lines."""
    rows, cols = np.nonzero(np.tril(matrix))
    lines = ["%%MatrixMarket matrix coordinate real symmetric"]
    if comment:
        lines += ["% written like *EXPORT,MatK,MMF", ""]
    lines.append(f"{matrix.shape[0]} {matrix.shape[1]} {rows.size}")
    for i, j in zip(rows, cols, strict=True):
        lines.append(f"{i + 1} {j + 1} {float(matrix[i, j])!r}")
        if comment and i == 2:
            lines.append("")
    return "\n".join(lines) + "\n"


def _mtx_general(matrix: np.ndarray) -> str:
    rows, cols = np.nonzero(matrix)
    lines = ["%%MatrixMarket matrix coordinate real general", f"4 4 {rows.size}"]
    lines += [f"{i + 1} {j + 1} {float(matrix[i, j])!r}" for i, j in zip(rows, cols, strict=True)]
    return "\n".join(lines) + "\n"


@pytest.fixture
def mmf(tmp_path):
    files = {
        "stiffness": tmp_path / "K.mtx",
        "mass": tmp_path / "M.mtx",
        "mapping": tmp_path / "spring.mapping",
    }
    files["stiffness"].write_text(_mtx_lower(K))
    files["mass"].write_text(_mtx_general(M))
    files["mapping"].write_text(MAPPING)
    return files


def test_mmf_reads_known_model(mmf, tmp_path):
    body = read_ansys_mmf(**mmf)
    np.testing.assert_array_equal(body.stiffness.toarray(), K)
    np.testing.assert_array_equal(body.mass.toarray(), M)
    np.testing.assert_array_equal(body.dofs.nodes, NODES)
    np.testing.assert_array_equal(body.dofs.directions, DIRS)
    np.testing.assert_array_equal(body.node_ids, [10, 20, 30])
    assert body.name == "spring" and body.fixed.size == 0 and body.damping_matrix is None

    (tmp_path / "D.mtx").write_text(_mtx_lower(D, comment=False))
    nodes = tmp_path / "nodes.csv"
    nodes.write_text("id,x,y,z\n10,0,0,0\n20,1.5,0,0\n30,3,0.5,0\n")
    body = read_ansys_mmf(**mmf, damping=tmp_path / "D.mtx", nodes=nodes, name="s")
    np.testing.assert_allclose(body.damping_matrix.toarray(), D)
    np.testing.assert_array_equal(body.node_position(30), [3.0, 0.5, 0.0])


def test_mmf_mapping_rows_in_any_order(mmf):
    mmf["mapping"].write_text(
        "! dof mapping\nMatrix Eqn, Node, DOF\n3 20 ux\n1 10 UX\n4 30 rotz\n2 10 UY\n"
    )
    body = read_ansys_mmf(**mmf)
    np.testing.assert_array_equal(body.dofs.nodes, NODES)
    np.testing.assert_array_equal(body.dofs.directions, DIRS)


@pytest.mark.parametrize(
    ("text", "line", "pattern"),
    [
        (MAPPING.replace("     UY", "     UQ"), 4, "unknown dof label 'UQ'"),
        (MAPPING.replace("     UY", "   TEMP"), 4, "dof TEMP is not structural"),
        (MAPPING.replace("20     UX", "10     UX"), 5, "dof 10:UX is listed twice"),
        (MAPPING.replace("       3 ", "       2 "), 5, "equation 2 is listed twice"),
        (MAPPING.replace("30   ROTZ", "30   ROTZ  7"), 6, "4 fields, expected 3"),
        (MAPPING + "   five   30   UZ\n", 7, "expected 'equation node dof'"),
        (MAPPING.replace("       4 ", "       0 "), 6, "must be at least 1"),
    ],
)
def test_mmf_bad_mapping_lines(mmf, text, line, pattern):
    mmf["mapping"].write_text(text)
    with pytest.raises(UserError, match=pattern) as excinfo:
        read_ansys_mmf(**mmf)
    _one_line_error(excinfo, mmf["mapping"], line)


def test_mmf_bad_mapping_size(mmf):
    mmf["mapping"].write_text(MAPPING.replace("       4       30   ROTZ\n", ""))
    with pytest.raises(UserError, match=r"matrix is 4 x 4 but .* maps 3 equations") as excinfo:
        read_ansys_mmf(**mmf)
    _one_line_error(excinfo, mmf["stiffness"])
    mmf["mapping"].write_text(MAPPING.replace("       4 ", "       5 "))
    with pytest.raises(UserError, match="equation 4 is missing") as excinfo:
        read_ansys_mmf(**mmf)
    _one_line_error(excinfo, mmf["mapping"])
    mmf["mapping"].write_text("Matrix Eqn   Node   DOF\n")
    with pytest.raises(UserError, match="no equation rows"):
        read_ansys_mmf(**mmf)


def test_mmf_bad_matrices(mmf):
    text = _mtx_lower(K)
    mmf["stiffness"].write_text(text[: text.rindex("\n", 0, -1)] + "\n")  # last entry cut off
    with pytest.raises(UserError, match="announces 8 entries") as excinfo:
        read_ansys_mmf(**mmf)
    _one_line_error(excinfo, mmf["stiffness"], 4)

    mmf["stiffness"].write_text(text.replace("4 4 4000.0", "4 4 nan"))
    with pytest.raises(UserError, match="not a finite number") as excinfo:
        read_ansys_mmf(**mmf)
    line = text.splitlines().index("4 4 4000.0") + 1
    _one_line_error(excinfo, mmf["stiffness"], line)

    unsymmetric = K.copy()
    unsymmetric[0, 2] = -1.9e4
    mmf["stiffness"].write_text(_mtx_general(unsymmetric))
    with pytest.raises(UserError, match="not symmetric") as excinfo:
        read_ansys_mmf(**mmf)
    _one_line_error(excinfo, mmf["stiffness"])

    mmf["stiffness"].write_text(_mtx_lower(K))
    mmf["mass"].write_text("%%MatrixMarket matrix coordinate real general\n3 3 1\n1 1 1.0\n")
    with pytest.raises(UserError, match="matrix is 3 x 3 but") as excinfo:
        read_ansys_mmf(**mmf)
    _one_line_error(excinfo, mmf["mass"])


def test_mmf_empty_dof_and_missing_node(mmf, tmp_path):
    k = K.copy()
    k[3, :] = k[:, 3] = 0.0
    m = M.copy()
    m[3, 3] = 0.0
    mmf["stiffness"].write_text(_mtx_lower(k))
    mmf["mass"].write_text(_mtx_general(m))
    with pytest.raises(UserError, match=r"equation 4 \(30:rz\) has neither stiffness nor mass"):
        read_ansys_mmf(**mmf)
    mmf["stiffness"].write_text(_mtx_lower(K))
    mmf["mass"].write_text(_mtx_general(M))
    nodes = tmp_path / "nodes.csv"
    nodes.write_text("id,x,y,z\n10,0,0,0\n20,1,0,0\n")
    with pytest.raises(UserError, match="node 30 of") as excinfo:
        read_ansys_mmf(**mmf, nodes=nodes)
    _one_line_error(excinfo, nodes)


def test_full_damping_matrix_code_path(monkeypatch):
    """The damping block is read like K and M; fake one by pointing at the stiffness block."""
    import dataclasses

    import pymorembs.io.ansys as ansys_io

    real_scan = ansys_io._scan_full_file

    def scan_with_damping(path):
        info = real_scan(path)
        return dataclasses.replace(info, damping=(536, 39023))  # ptrSTF, ntermK of the example

    monkeypatch.setattr(ansys_io, "_scan_full_file", scan_with_damping)
    body = read_ansys_full(examples.fullfile)
    assert body.damping_matrix is not None
    assert abs(body.damping_matrix - body.stiffness).max() == 0.0
