"""The MATLAB .mat reader: storage checked on MATLAB-written files, model rules on built ones.

Genuine files (written by MATLAB, unchanged): ``tests/data/pymatreader_sparse`` (pymatreader's
``generate_testdata.m``: sparse matrices of every shape saved as v4, v6, v7 and v7.3, with the
values as CSV written by the same MATLAB run) and ``tests/data/scipy_matlab`` (SciPy's test
files, among them a v7.3 file of MATLAB 7.4). No MATLAB-written second-order model (M, K, B, C)
with a licence was found, so the model-level cases are files written here with
``scipy.io.savemat`` (v5) and with ``h5py`` in the layout of the genuine v7.3 files.
"""

from __future__ import annotations

from pathlib import Path

import h5py
import numpy as np
import pytest
import scipy.io as sio
import scipy.linalg as sl
import scipy.sparse as sp

from pymorembs.body import SCALAR
from pymorembs.errors import UserError
from pymorembs.io.formats import detect_format, read_body
from pymorembs.io.matlab import mat_variables, read_mat_variables, read_matlab

DATA = Path(__file__).parents[1] / "data"
SPARSE = DATA / "pymatreader_sparse"
SCIPY = DATA / "scipy_matlab"
SHAPES = {"col": (10, 1), "row": (1, 10), "wide": (10, 20), "square": (10, 10), "tall": (20, 10)}


# ============================================================================ genuine storage
def assert_identical(value, other) -> None:
    """Two loaded variables hold the same numbers in the same shape (sparse or dense)."""
    if sp.issparse(value):
        assert sp.issparse(other) and value.shape == other.shape and (value != other).nnz == 0
    else:
        np.testing.assert_array_equal(value, other)


@pytest.mark.parametrize("version", ["4", "6", "7", "73"])
def test_matlab_written_sparse_matrices(version):
    """Every sparse shape of pymatreader's MATLAB files equals MATLAB's own CSV of it."""
    path = SPARSE / f"sparse_v{version}.mat"
    listed = {v.name: v for v in mat_variables(path)}
    assert listed["A_square"].kind == "sparse" and listed["A_tall"].shape == (20, 10)
    values = read_mat_variables(path)
    assert values["N"].shape == (1, 1) and float(values["N"][0, 0]) == 10.0
    assert values["i"].shape == (1, 5) and values["v"].shape == (5, 1)  # v7.3: transposed back
    for name, shape in SHAPES.items():
        matrix = values[f"A_{name}"]
        assert sp.issparse(matrix) and matrix.shape == shape and matrix.nnz == 5
        reference = np.loadtxt(SPARSE / f"sparse_{name}.csv", delimiter=",").reshape(shape)
        np.testing.assert_allclose(matrix.toarray(), reference, rtol=0, atol=1e-15)
        empty = values[f"A_empty_{name}"]
        assert empty.shape == shape and empty.nnz == 0
    assert values["A_empty"].shape == (0, 0)
    assert values["A_single"].toarray().tolist() == [[1.0]]


def test_v73_and_v7_hold_the_same_numbers():
    """MATLAB wrote the same workspace in both versions: the HDF5 route reads it bit for bit."""
    v7 = read_mat_variables(SPARSE / "sparse_v7.mat")
    v73 = read_mat_variables(SPARSE / "sparse_v73.mat")
    assert set(v7) == set(v73)
    for name, value in v7.items():
        assert_identical(value, v73[name])


def test_scipy_files_of_matlab_4_2_to_7_4():
    expected = np.array([[1, 2, 3, 4, 5], [2, 0, 0, 0, 0], [3, 0, 0, 0, 0]], dtype=float)
    for name in ("testsparse_4.2c_SOL2.mat", "testsparse_7.4_GLNX86.mat"):
        (matrix,) = read_mat_variables(SCIPY / name).values()
        np.testing.assert_array_equal(matrix.toarray(), expected)
    (dense,) = read_mat_variables(SCIPY / "testmatrix_7.4_GLNX86.mat").values()
    np.testing.assert_array_equal(dense, expected)
    # a v7.3 file of MATLAB 7.4 (its header says "MATLAB 7.0 MAT-file"): detected and read
    h5 = SCIPY / "testhdf5_7.4_GLNX86.mat"
    assert detect_format(h5) == "matlab"
    (row,) = read_mat_variables(h5).values()
    (same,) = read_mat_variables(SCIPY / "testdouble_7.4_GLNX86.mat").values()
    assert row.shape == (1, 9)
    np.testing.assert_array_equal(row, same)
    np.testing.assert_allclose(row.ravel(), np.linspace(0, 2 * np.pi, 9), rtol=1e-15)
    (complex_sparse,) = read_mat_variables(SCIPY / "testsparsecomplex_7.4_GLNX86.mat").values()
    assert complex_sparse[0, 0] == 1 + 1j


def test_own_v5_reader_equals_scipy_on_the_genuine_files():
    """pymorembs reads level-5 files itself (scipy's reader crashes on damaged ones): on every
    MATLAB-written v5 file here it gives what scipy.io.loadmat gives."""
    files = [*sorted(SCIPY.glob("*_7.4_GLNX86.mat")), *(SPARSE / f"sparse_v{v}.mat" for v in "67")]
    files.remove(SCIPY / "testhdf5_7.4_GLNX86.mat")
    compared = 0
    for path in files:
        ours = read_mat_variables(path)
        theirs = sio.loadmat(path)
        listed = {v.name: v for v in mat_variables(path)}
        assert {n: (v.shape, v.kind) for n, v in listed.items()} == {
            n: (tuple(shape), kind) for n, shape, kind in sio.whosmat(path)
        }
        for name, value in ours.items():
            assert_identical(value, theirs[name])
            compared += 1
    assert compared >= 20


@pytest.mark.parametrize(
    ("name", "variable", "pattern"),
    [
        ("testsparsecomplex_7.4_GLNX86.mat", "testsparsecomplex", "testsparsecomplex is complex"),
        ("teststruct_7.4_GLNX86.mat", "teststruct", r"teststruct \(1x1 struct\) is a struct, not"),
        ("testcell_7.4_GLNX86.mat", "testcell", "is a cell, not a matrix"),
        ("testsparse_7.4_GLNX86.mat", "testsparse", "is 3 x 5, not square"),
    ],
)
def test_genuine_files_that_hold_no_model(name, variable, pattern):
    with pytest.raises(UserError, match=pattern) as info:
        read_matlab(SCIPY / name, stiffness=variable, mass=variable)
    assert str(info.value).startswith(str(SCIPY / name)) and "\n" not in str(info.value)


# ============================================================================ models
N = 6


def chain():
    """A free-fixed chain of 6 masses: K tridiagonal, consistent-like M, Rayleigh D, B, C."""
    k = sp.diags([-np.ones(N - 1), np.r_[2 * np.ones(N - 1), 1.0], -np.ones(N - 1)], [-1, 0, 1])
    k = sp.csc_matrix(1e4 * k)
    m = sp.csc_matrix(
        sp.diags([0.1 * np.ones(N - 1), np.ones(N), 0.1 * np.ones(N - 1)], [-1, 0, 1])
    )
    d = sp.csc_matrix(0.5 * m + 1e-4 * k)
    b = np.zeros((N, 2))
    b[0, 0], b[-1, 1] = 1.0, 2.0
    c = np.zeros((1, N))
    c[0, 2] = 1.0
    return k, m, d, b, c


def save_v73(path: Path, variables: dict) -> Path:
    """Write variables the way MATLAB's save -v7.3 does (see the genuine sparse_v73.mat)."""
    with h5py.File(path, "w", userblock_size=512) as f:
        for name, value in variables.items():
            if sp.issparse(value):
                a = sp.csc_matrix(value)
                a.sort_indices()
                group = f.create_group(name)
                group.attrs["MATLAB_class"] = np.bytes_("double")
                group.attrs["MATLAB_sparse"] = np.uint64(a.shape[0])
                group["jc"] = a.indptr.astype(np.uint64)
                if a.nnz:
                    group["ir"] = a.indices.astype(np.uint64)
                    group["data"] = a.data
            else:
                array = np.atleast_2d(np.asarray(value))
                if np.iscomplexobj(array):
                    compound = np.dtype([("real", "<f8"), ("imag", "<f8")])
                    stored = np.empty(array.T.shape, dtype=compound)
                    stored["real"], stored["imag"] = array.T.real, array.T.imag
                else:
                    stored = array.T.astype(float)
                dataset = f.create_dataset(name, data=stored)
                dataset.attrs["MATLAB_class"] = np.bytes_("double")
    text = b"MATLAB 7.3 MAT-file, Platform: GLNXA64, Created on: pymorembs test HDF5 schema 1.00 ."
    header = text.ljust(116) + bytes(8) + b"\x00\x02IM"
    with open(path, "r+b") as f:
        f.write(header)
    return path


def save_v5(path: Path, variables: dict) -> Path:
    sio.savemat(path, variables, format="5", do_compression=True)
    return path


SAVERS = {"v5": save_v5, "v73": save_v73}


@pytest.mark.parametrize("version", sorted(SAVERS))
def test_morwiki_convention_m_e_k_b_c(tmp_path, version):
    """M x'' + E x' + K x = B u, y = C x: E is the damping, B and C the ports."""
    k, m, d, b, c = chain()
    path = SAVERS[version](tmp_path / "chain.mat", {"M": m, "E": d, "K": k, "B": b, "C": c})
    assert detect_format(path) == "matlab"
    body = read_matlab(path)
    assert body.name == "chain" and body.n_dof == N and not body.has_coordinates
    assert abs(body.stiffness - k).max() == 0.0 and abs(body.mass - m).max() == 0.0
    assert abs(body.damping_matrix - d).max() == 0.0
    np.testing.assert_array_equal(body.ports.inputs.toarray(), b)
    np.testing.assert_array_equal(body.ports.outputs.toarray(), c)
    assert np.all(body.dofs.directions == SCALAR) and body.dofs.nodes.tolist() == list(range(1, 7))
    assert body.node_ids.size == 0
    assert "6 scalar coordinates (q) numbered 1..6" in body.notes[0]
    assert (
        body.notes[1]
        == "variables of chain.mat: K = stiffness, M = mass, E = damping, B = inputs, C = outputs"
    )
    # an independent eigen solution of the numbers put into the file
    expected = sl.eigh(k.toarray(), m.toarray(), eigvals_only=True)
    got = sl.eigh(body.stiffness.toarray(), body.mass.toarray(), eigvals_only=True)
    np.testing.assert_allclose(got, expected, rtol=1e-14)


@pytest.mark.parametrize("version", sorted(SAVERS))
def test_structural_convention_m_c_k(tmp_path, version):
    k, m, d, b, c = chain()
    save = SAVERS[version]
    body = read_matlab(save(tmp_path / "a.mat", {"M": m, "C": d, "K": k}))
    assert abs(body.damping_matrix - d).max() == 0.0 and body.ports is None
    body = read_matlab(save(tmp_path / "b.mat", {"M": m, "C": d, "K": k, "B": b, "F": c}))
    assert abs(body.damping_matrix - d).max() == 0.0
    np.testing.assert_array_equal(body.ports.outputs.toarray(), c)
    square_c = np.eye(N)
    path = save(tmp_path / "c.mat", {"M": m, "C": square_c, "K": k, "B": b})
    with pytest.raises(UserError, match=r"variable C is 6 x 6 next to B: it may be the damping"):
        read_matlab(path)
    as_output = read_matlab(path, damping="none")
    assert as_output.damping_matrix is None
    np.testing.assert_array_equal(as_output.ports.outputs.toarray(), square_c)
    as_damping = read_matlab(path, damping="C")
    assert abs(as_damping.damping_matrix - sp.eye(N)).max() == 0.0
    assert as_damping.ports.outputs is None  # C = B^T then


def test_names_are_case_insensitive_and_can_be_given(tmp_path):
    k, m, _, b, _ = chain()
    body = read_matlab(
        save_v5(tmp_path / "lower.mat", {"m": m, "k": k, "b": b, "D": np.ones((2, 1))})
    )
    assert body.damping_matrix is None and body.ports.inputs.shape == (N, 2)  # D: feedthrough
    assert "not used: D" in body.notes[1]
    path = save_v5(tmp_path / "both.mat", {"K": k, "k": 2 * k, "M": m})
    with pytest.raises(UserError, match="variables K and k could both be the stiffness"):
        read_matlab(path)
    assert abs(read_matlab(path, stiffness="k").stiffness - 2 * k).max() == 0.0
    path = save_v5(tmp_path / "named.mat", {"Kmat": k, "Mmat": m})
    with pytest.raises(UserError, match=r"no stiffness matrix: the file holds Kmat \(6x6 sparse\)"):
        read_matlab(path)
    body = read_matlab(path, stiffness="kmat", mass="Mmat")
    assert abs(body.mass - m).max() == 0.0
    with pytest.raises(UserError, match="no variable named 'Kx' for the stiffness"):
        read_matlab(path, stiffness="Kx", mass="Mmat")


def test_dofs_and_nodes_make_the_body_nodal(tmp_path):
    k, m, *_ = chain()
    path = save_v73(tmp_path / "chain.mat", {"M": m, "K": k})
    dofs = tmp_path / "dofs.csv"
    dofs.write_text("node,direction\n" + "".join(f"{10 * (i + 1)},ux\n" for i in range(N)))
    nodes = tmp_path / "nodes.csv"
    nodes.write_text("id,x,y,z\n" + "".join(f"{10 * (i + 1)},{i},0,0\n" for i in range(N)))
    body = read_matlab(path, dofs=dofs, nodes=nodes)
    assert body.has_coordinates and body.node_position(30).tolist() == [2.0, 0.0, 0.0]
    assert body.notes[0] == "dof table: 6 nodes x ux from dofs.csv, coordinates from nodes.csv"
    assert not read_matlab(path, dofs=dofs).has_coordinates
    with pytest.raises(UserError, match="need the dof table"):
        read_matlab(path, nodes=nodes)
    dofs.write_text("node,direction\n10,ux\n")
    with pytest.raises(UserError, match=r"1 dofs but the matrices of .* are 6 x 6"):
        read_matlab(path, dofs=dofs)


def test_read_body_dispatches_with_matrix_names(tmp_path):
    k, m, *_ = chain()
    path = save_v73(tmp_path / "x.mat", {"Kx": k, "Mx": m})
    body = read_body(file=path, stiffness_name="Kx", mass_name="Mx", name="named")
    assert body.name == "named" and abs(body.stiffness - k).max() == 0.0


def _broken(tmp_path: Path, version: str, **variables) -> Path:
    return SAVERS[version](tmp_path / f"bad_{version}.mat", variables)


@pytest.mark.parametrize("version", sorted(SAVERS))
@pytest.mark.parametrize(
    ("case", "pattern"),
    [
        ("missing_k", r"no stiffness matrix: the file holds M \(6x6 .*\); name it"),
        ("first_order", "looks like a first-order system A, B, C, E"),
        ("non_square", r"variable K \(stiffness\) is 6 x 5, not square"),
        ("sizes", r"variable M \(mass\) is 5 x 5; K is 6 x 6"),
        ("complex", "variable K is complex"),
        ("unsymmetric", r"variable K \(stiffness\): matrix is not symmetric"),
        ("nan", "variable M has NaN or infinite entries"),
        ("b_rows", r"input matrix B is 2 x 6, expected 6 rows \(stored transposed\?"),
        ("c_columns", r"output matrix C is 6 x 1, expected 6 columns \(stored transposed\?"),
        ("c_without_b", "output matrix C without an input matrix B"),
        ("empty", r"variable K \(stiffness\) is empty"),
    ],
)
def test_broken_models(tmp_path, version, case, pattern):
    k, m, _, b, c = chain()
    variables = {
        "missing_k": {"M": m},
        "first_order": {"A": k, "B": b, "C": c, "E": m},
        "non_square": {"K": k[:, :5], "M": m},
        "sizes": {"K": k, "M": m[:5, :5]},
        "complex": {"K": k.toarray() * (1 + 0.01j), "M": m},
        "unsymmetric": {"K": k + sp.csc_matrix(([5.0], ([0], [3])), shape=(N, N)), "M": m},
        "nan": {"K": k, "M": np.where(m.toarray() > 0.5, np.nan, m.toarray())},
        "b_rows": {"K": k, "M": m, "B": b.T},
        "c_columns": {"K": k, "M": m, "B": b, "C": c.T},
        "c_without_b": {"K": k, "M": m, "C": np.ones((2, N))},
        "empty": {"K": sp.csc_matrix((0, 0)), "M": sp.csc_matrix((0, 0))},
    }[case]
    path = _broken(tmp_path, version, **variables)
    with pytest.raises(UserError, match=pattern) as info:
        read_matlab(path)
    message = str(info.value)
    assert message.startswith(str(path)) and "\n" not in message


def test_files_that_are_not_mat_files(tmp_path):
    from pymorembs.io.native import write_body_h5

    k, m, *_ = chain()
    native = write_body_h5(
        read_matlab(save_v5(tmp_path / "ok.mat", {"K": k, "M": m})), tmp_path / "n.h5"
    )
    plain = tmp_path / "plain.mat"
    with h5py.File(plain, "w") as f:
        f["K"] = np.eye(3)
    text = tmp_path / "text.mat"
    text.write_text("K = [1 2; 3 4]\n")
    cases = {
        native: "without MATLAB variables",
        plain: "without MATLAB variables",
        text: "not a MATLAB .mat file",
        tmp_path / "none.mat": "file not found",
        tmp_path: "is a directory",
    }
    empty = tmp_path / "empty.mat"
    empty.write_bytes(b"")
    cases[empty] = "empty file"
    truncated = tmp_path / "cut.mat"
    truncated.write_bytes((SPARSE / "sparse_v7.mat").read_bytes()[:700])
    cases[truncated] = "damaged MAT-file: element at byte 636 announces 110 bytes past its end"
    for path, pattern in cases.items():
        with pytest.raises(UserError, match=pattern) as info:
            read_matlab(path)
        assert str(info.value).startswith(str(path)) and "\n" not in str(info.value)


def test_damaged_v73_sparse_matrix(tmp_path):
    k, m, *_ = chain()
    path = save_v73(tmp_path / "bad.mat", {"K": k, "M": m})
    with h5py.File(path, "r+") as f:
        ir = f["K"]["ir"][()]
        ir[3] = 99
        del f["K"]["ir"]
        f["K"]["ir"] = ir
    with pytest.raises(UserError, match=r"variable 'K': damaged sparse matrix \(jc, ir, data\)"):
        read_matlab(path)


def test_dense_variables_are_bounded(tmp_path):
    path = tmp_path / "huge.mat"
    save_v73(path, {"M": np.eye(2)})
    with h5py.File(path, "r+") as f:
        dataset = f.create_dataset("K", shape=(20000, 20000), dtype="<f8")
        dataset.attrs["MATLAB_class"] = np.bytes_("double")
    with pytest.raises(UserError, match=r"variable K \(20000x20000 double\) is dense and needs"):
        read_matlab(path)
