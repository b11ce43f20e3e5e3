"""Reading and writing bodies: Matrix Market + CSV, native HDF5, atomic writes, bad inputs."""

from __future__ import annotations

import os
from collections.abc import Callable
from pathlib import Path

import h5py
import numpy as np
import pytest
import scipy.sparse as sp

from pymorembs.body import ConstraintEquations, Damping, DofTable, ElasticBody
from pymorembs.errors import UserError
from pymorembs.io.atomic import atomic_open, atomic_path, write_bytes, write_text
from pymorembs.io.matrix_market import (
    read_matrix_directory,
    read_matrix_files,
    read_matrix_market,
    write_matrix_files,
    write_matrix_market,
)
from pymorembs.io.native import read_body_h5, write_body_h5

NODE_IDS = np.array([3, 17, 42, 1000])


def random_spd(n: int, rng: np.random.Generator, density: float = 0.25) -> sp.csr_matrix:
    """An exactly symmetric, positive definite sparse matrix with full-mantissa entries."""
    t = sp.random(n, n, density=density, random_state=rng, data_rvs=rng.standard_normal)
    return sp.csr_matrix(t + t.T + sp.diags(n + rng.random(n)))


def make_body(
    damping: Damping | None = None, explicit_damping: bool = True, name: str = "test body"
) -> ElasticBody:
    """4 nodes x 6 dofs in shuffled matrix order; constraints (one with an empty G row) and
    non-zero offsets, fixed dofs, an explicit damping matrix and Rayleigh damping."""
    rng = np.random.default_rng(7)
    nodes = np.repeat(NODE_IDS, 6)
    directions = np.tile(np.arange(6), 4)
    order = rng.permutation(24)
    dofs = DofTable(nodes[order], directions[order])
    g = sp.random(3, 24, density=0.2, random_state=rng, data_rvs=rng.standard_normal).tolil()
    g[2, :] = 0.0  # q_d = g for the last equation
    g[0, 5] = 1.0 / 3.0
    equations = ConstraintEquations(
        dependent=np.array([dofs.index(17, "uz"), dofs.index(1000, "rx"), dofs.index(42, "ry")]),
        matrix=sp.csr_matrix(g),
        offset=np.array([1e-3 / 3.0, -0.25, 2.0 / 7.0]),
    )
    return ElasticBody(
        node_ids=NODE_IDS,
        coordinates=rng.standard_normal((4, 3)) * np.array([1.0, 1e-7, 1e5]),
        dofs=dofs,
        mass=random_spd(24, rng),
        stiffness=random_spd(24, rng) * 1e7,
        damping_matrix=random_spd(24, rng) * 1e-3 if explicit_damping else None,
        constraints=equations,
        fixed=np.array([dofs.index(3, "ux"), dofs.index(3, "rz"), dofs.index(42, "uy")]),
        damping=damping if damping is not None else Damping("rayleigh", alpha=0.1, beta=1e-5),
        name=name,
    )


def assert_same_matrix(a: sp.spmatrix | None, b: sp.spmatrix | None) -> None:
    """Bit-identical values and sparsity structure after canonicalisation."""
    assert a is not None and b is not None
    a, b = sp.csr_matrix(a, copy=True), sp.csr_matrix(b, copy=True)
    for m in (a, b):
        m.sum_duplicates()
        m.eliminate_zeros()
        m.sort_indices()
    assert a.shape == b.shape
    np.testing.assert_array_equal(a.indptr, b.indptr)
    np.testing.assert_array_equal(a.indices, b.indices)
    np.testing.assert_array_equal(a.data.view(np.int64), b.data.view(np.int64))


def assert_same_tables(read: ElasticBody, body: ElasticBody) -> None:
    """Nodes, dof table, constraints and fixed dofs identical (floats bit for bit)."""
    np.testing.assert_array_equal(read.node_ids, body.node_ids)
    np.testing.assert_array_equal(read.coordinates.view(np.int64), body.coordinates.view(np.int64))
    np.testing.assert_array_equal(read.dofs.nodes, body.dofs.nodes)
    np.testing.assert_array_equal(read.dofs.directions, body.dofs.directions)
    np.testing.assert_array_equal(read.constraints.dependent, body.constraints.dependent)
    np.testing.assert_array_equal(
        read.constraints.offset.view(np.int64), body.constraints.offset.view(np.int64)
    )
    assert_same_matrix(read.constraints.matrix, body.constraints.matrix)
    np.testing.assert_array_equal(read.fixed, body.fixed)


# ============================================================================ round trips
def test_matrix_market_round_trip_is_exact(tmp_path: Path) -> None:
    body = make_body()
    paths = write_matrix_files(body, tmp_path / "model")
    assert set(paths) == {"stiffness", "mass", "damping", "dofs", "nodes", "constraints", "fixed"}
    assert (
        paths["stiffness"].read_text().startswith("%%MatrixMarket matrix coordinate real symmetric")
    )
    read = read_matrix_files(**paths)
    assert_same_matrix(read.stiffness, body.stiffness)
    assert_same_matrix(read.mass, body.mass)
    assert_same_matrix(read.damping_matrix, body.viscous_damping())
    assert read.damping.kind == "none"
    assert_same_tables(read, body)
    assert read.name == "model"
    again = read_matrix_directory(tmp_path / "model", name="again")
    assert again.name == "again"
    assert_same_matrix(again.stiffness, body.stiffness)
    assert_same_tables(again, body)


def test_constraints_csv_layout(tmp_path: Path) -> None:
    body = make_body()
    paths = write_matrix_files(body, tmp_path)
    lines = paths["constraints"].read_text().splitlines()
    assert lines[0] == "dependent_node,dependent_direction,offset,node,direction,coefficient"
    assert f"42,ry,{2.0 / 7.0!r},,," in lines  # the empty G row
    assert sum(line.startswith("17,uz,") for line in lines) == body.constraints.matrix[0].nnz
    assert paths["dofs"].read_text().splitlines()[0] == "node,direction"
    assert paths["nodes"].read_text().splitlines()[0] == "id,x,y,z"


def test_rewrite_removes_stale_optional_files(tmp_path: Path) -> None:
    write_matrix_files(make_body(), tmp_path)
    plain = ElasticBody(
        node_ids=[1, 2],
        coordinates=np.zeros((2, 3)),
        dofs=DofTable([1, 2], [0, 0]),
        mass=sp.eye(2),
        stiffness=sp.csr_matrix([[2.0, -1.0], [-1.0, 2.0]]),
    )
    paths = write_matrix_files(plain, tmp_path)
    assert set(paths) == {"stiffness", "mass", "dofs", "nodes"}
    assert sorted(p.name for p in tmp_path.iterdir()) == ["K.mtx", "M.mtx", "dofs.csv", "nodes.csv"]
    read = read_matrix_directory(tmp_path)
    assert read.damping_matrix is None and len(read.constraints) == 0 and read.fixed.size == 0


def test_generic_dof_table_and_origin_nodes(tmp_path: Path) -> None:
    k = tmp_path / "k.mtx"
    k.write_text("%%MatrixMarket matrix coordinate real general\n3 3 3\n1 1 1.0\n2 2 2.0\n3 3 3\n")
    body = read_matrix_files(k, k)
    np.testing.assert_array_equal(body.dofs.nodes, [1, 2, 3])
    np.testing.assert_array_equal(body.dofs.directions, [0, 0, 0])
    np.testing.assert_array_equal(body.node_ids, [1, 2, 3])
    assert not body.coordinates.any()


@pytest.mark.parametrize(
    "damping",
    [Damping("rayleigh", alpha=0.1, beta=1e-5), Damping("modal", ratio=0.02), Damping()],
)
@pytest.mark.parametrize("explicit_damping", [True, False])
def test_hdf5_round_trip_is_bit_exact(
    tmp_path: Path, damping: Damping, explicit_damping: bool
) -> None:
    body = make_body(damping, explicit_damping, name="rack Ä/2")
    path = write_body_h5(body, tmp_path / "body.h5")
    read = read_body_h5(path)
    assert read.name == body.name
    assert read.damping == body.damping
    assert_same_matrix(read.stiffness, body.stiffness)
    assert_same_matrix(read.mass, body.mass)
    if explicit_damping:
        assert_same_matrix(read.damping_matrix, body.damping_matrix)
    else:
        assert read.damping_matrix is None
    assert_same_tables(read, body)
    # the stored CSR arrays are exactly those of the body, not only equal after canonicalisation
    np.testing.assert_array_equal(read.constraints.matrix.indptr, body.constraints.matrix.indptr)
    np.testing.assert_array_equal(read.stiffness.data, body.stiffness.data)


def test_hdf5_compresses_big_arrays(tmp_path: Path) -> None:
    n = 3000
    body = ElasticBody(
        node_ids=np.arange(1, n + 1),
        coordinates=np.zeros((n, 3)),
        dofs=DofTable(np.arange(1, n + 1), np.zeros(n, dtype=np.int64)),
        mass=sp.eye(n, format="csr"),
        stiffness=sp.diags([-1.0, 2.0, -1.0], [-1, 0, 1], shape=(n, n), format="csr"),
    )
    path = write_body_h5(body, tmp_path / "big.h5")
    with h5py.File(path) as f:
        assert f["nodes/coordinates"].compression == "gzip"
        assert f["stiffness/data"].compression == "gzip"
        assert f.attrs["format"] == "pymorembs-body" and f.attrs["version"] == 2
    assert_same_matrix(read_body_h5(path).stiffness, body.stiffness)


# ============================================================================ Matrix Market details
def test_hand_written_symmetric_storage(tmp_path: Path) -> None:
    path = tmp_path / "sym.mtx"
    path.write_text(
        "%%MatrixMarket matrix coordinate real symmetric\n"
        "% a comment\n"
        "\n"
        "3 3 5\n"
        "1 1 4.0\n"
        "2 1 -1.5\n"
        "2 2 4\n"
        "3 2 -1e-1   % trailing comment\n"
        "3 3 4.0\n"
    )
    expected = np.array([[4.0, -1.5, 0.0], [-1.5, 4.0, -0.1], [0.0, -0.1, 4.0]])
    np.testing.assert_array_equal(read_matrix_market(path).toarray(), expected)
    upper = tmp_path / "upper.mtx"
    upper.write_text(
        "%%MatrixMarket matrix coordinate real symmetric\n3 3 3\n1 2 -1.5\n2 3 -0.1\n3 3 1\n"
    )
    np.testing.assert_array_equal(
        read_matrix_market(upper).toarray(),
        [[0.0, -1.5, 0.0], [-1.5, 0.0, -0.1], [0.0, -0.1, 1.0]],
    )


def test_array_format(tmp_path: Path) -> None:
    general = tmp_path / "general.mtx"
    general.write_text("%%MatrixMarket matrix array real general\n2 2\n1\n2\n2\n5\n")
    np.testing.assert_array_equal(read_matrix_market(general).toarray(), [[1, 2], [2, 5]])
    symmetric = tmp_path / "symmetric.mtx"
    symmetric.write_text("%%MatrixMarket matrix array integer symmetric\n2 2\n1\n2\n5\n")
    np.testing.assert_array_equal(read_matrix_market(symmetric).toarray(), [[1, 2], [2, 5]])


def test_general_storage_for_nearly_symmetric_matrix(tmp_path: Path) -> None:
    a = sp.csr_matrix([[2.0, 1.0], [1.0 + 1e-14, 3.0]])
    path = write_matrix_market(tmp_path / "a.mtx", a)
    assert "general" in path.read_text().splitlines()[0]
    assert_same_matrix(read_matrix_market(path), a)


# ============================================================================ bad inputs
def expect_error(call: Callable[[], object], *fragments: str) -> str:
    """Run ``call``; it must raise a one-line UserError containing every fragment."""
    with pytest.raises(UserError) as info:
        call()
    message = str(info.value)
    assert "\n" not in message
    for fragment in fragments:
        assert fragment in message, message
    return message


@pytest.fixture
def model(tmp_path: Path) -> dict[str, Path]:
    """A valid directory written from :func:`make_body`; tests spoil one file."""
    return write_matrix_files(make_body(), tmp_path / "model")


def replace_line(path: Path, number: int, text: str) -> None:
    """Replace line ``number`` (from 1) of a text file."""
    lines = path.read_text().splitlines()
    lines[number - 1] = text
    path.write_text("\n".join(lines) + "\n")


def test_missing_file(model: dict[str, Path]) -> None:
    model["mass"].unlink()
    expect_error(lambda: read_matrix_files(**model), "M.mtx", "not found")


def test_not_a_matrix_market_file(model: dict[str, Path]) -> None:
    model["stiffness"].write_text("hello world\n1 2 3\n")
    expect_error(lambda: read_matrix_files(**model), "K.mtx:1:", "not a Matrix Market file")


def test_binary_file_as_matrix_market(model: dict[str, Path]) -> None:
    model["stiffness"].write_bytes(b"\x89HDF\r\n\x1a\n\xff\xfe")
    expect_error(lambda: read_matrix_files(**model), "K.mtx", "not a text file")


def test_non_square_matrix(tmp_path: Path) -> None:
    path = tmp_path / "rect.mtx"
    path.write_text("%%MatrixMarket matrix coordinate real general\n2 3 1\n1 1 1.0\n")
    expect_error(lambda: read_matrix_market(path), "rect.mtx:2:", "2 x 3, not square")


@pytest.mark.parametrize(("field", "reason"), [("complex", "complex"), ("pattern", "pattern")])
def test_complex_and_pattern_rejected(tmp_path: Path, field: str, reason: str) -> None:
    path = tmp_path / "c.mtx"
    path.write_text(f"%%MatrixMarket matrix coordinate {field} general\n1 1 1\n1 1 1 0\n")
    expect_error(lambda: read_matrix_market(path), "c.mtx:1:", reason)


def test_size_mismatch_between_k_and_m(model: dict[str, Path]) -> None:
    write_matrix_market(model["mass"], sp.eye(23))
    expect_error(lambda: read_matrix_files(**model), "M.mtx", "23 x 23", "K.mtx")


def test_dof_count_mismatch(model: dict[str, Path]) -> None:
    lines = model["dofs"].read_text().splitlines()
    model["dofs"].write_text("\n".join(lines[:-1]) + "\n")
    expect_error(lambda: read_matrix_files(**model), "dofs.csv", "23 dofs", "24 x 24")


def test_unknown_direction_in_dofs(model: dict[str, Path]) -> None:
    replace_line(model["dofs"], 5, "17,uw")
    expect_error(lambda: read_matrix_files(**model), "dofs.csv:5:", "unknown direction 'uw'")


def test_duplicate_dof(model: dict[str, Path]) -> None:
    first = model["dofs"].read_text().splitlines()[1]
    replace_line(model["dofs"], 7, first.upper())
    expect_error(lambda: read_matrix_files(**model), "dofs.csv:7:", "listed twice", "line 2")


def test_non_numeric_coordinate(model: dict[str, Path]) -> None:
    replace_line(model["nodes"], 3, "17, 1.0, abc, 2.0")
    expect_error(lambda: read_matrix_files(**model), "nodes.csv:3:", "y 'abc' is not a number")


def test_dof_node_missing_in_nodes(model: dict[str, Path]) -> None:
    lines = model["nodes"].read_text().splitlines()
    model["nodes"].write_text("\n".join(line for line in lines if not line.startswith("42,")))
    dof_line = 1 + next(
        i for i, line in enumerate(model["dofs"].read_text().splitlines()) if line.startswith("42,")
    )
    expect_error(
        lambda: read_matrix_files(**model), f"dofs.csv:{dof_line}:", "node 42", "nodes.csv"
    )


def test_asymmetric_stiffness(model: dict[str, Path]) -> None:
    k = read_matrix_market(model["stiffness"]).tolil()
    k[4, 1] += 1.0e3
    write_matrix_market(model["stiffness"], k)
    message = expect_error(lambda: read_matrix_files(**model), "K.mtx", "not symmetric")
    assert "(5, 2)" in message or "(2, 5)" in message


def test_nan_in_matrix(tmp_path: Path) -> None:
    path = tmp_path / "nan.mtx"
    path.write_text("%%MatrixMarket matrix coordinate real general\n2 2 2\n1 1 1.0\n2 2 nan\n")
    expect_error(lambda: read_matrix_market(path), "nan.mtx:4:", "not a finite number")


@pytest.mark.parametrize(
    ("line", "fragment"),
    [
        ("1 1", "2 values, expected 3"),
        ("1 x 1.0", "column 'x' is not an integer"),
        ("1 1 one", "value 'one' is not a number"),
        ("3 1 1.0", "outside the 2 x 2 matrix"),
        ("1 1 5.0", "given twice (first on line 3)"),
    ],
)
def test_malformed_entry_line(tmp_path: Path, line: str, fragment: str) -> None:
    path = tmp_path / "bad.mtx"
    path.write_text(f"%%MatrixMarket matrix coordinate real general\n2 2 2\n1 1 1.0\n{line}\n")
    expect_error(lambda: read_matrix_market(path), "bad.mtx:4:", fragment)


def test_entry_count_mismatch(tmp_path: Path) -> None:
    path = tmp_path / "few.mtx"
    path.write_text("%%MatrixMarket matrix coordinate real general\n2 2 3\n1 1 1.0\n2 2 1.0\n")
    expect_error(lambda: read_matrix_market(path), "few.mtx:2:", "announces 3 entries")


def test_both_triangles_in_symmetric_file(tmp_path: Path) -> None:
    path = tmp_path / "both.mtx"
    path.write_text(
        "%%MatrixMarket matrix coordinate real symmetric\n2 2 3\n1 1 1.0\n2 1 0.5\n1 2 0.5\n"
    )
    expect_error(lambda: read_matrix_market(path), "both.mtx:5:", "one triangle")


def test_missing_csv_header(model: dict[str, Path]) -> None:
    lines = model["fixed"].read_text().splitlines()
    model["fixed"].write_text("\n".join(lines[1:]) + "\n")
    expect_error(lambda: read_matrix_files(**model), "fixed.csv:1:", "expected 'node,direction'")


def test_fixed_dof_not_in_table(model: dict[str, Path]) -> None:
    with model["fixed"].open("a") as fh:
        fh.write("# a comment\n\n   99 , ux\n")
    expect_error(lambda: read_matrix_files(**model), "fixed.csv:7:", "node 99")


@pytest.mark.parametrize(
    ("row", "fragment"),
    [
        ("17,uz,5.0,3,ux,1.0", "differs from"),
        ("1000,rx,-0.25,3,ux,", "all given or all empty"),
        ("42,ry,0.5,,,", "differs from"),
        ("17,uz,nan,,,", "not a finite number"),
    ],
)
def test_bad_constraint_rows(model: dict[str, Path], row: str, fragment: str) -> None:
    with model["constraints"].open("a") as fh:
        fh.write(row + "\n")
    number = len(model["constraints"].read_text().splitlines())
    expect_error(lambda: read_matrix_files(**model), f"constraints.csv:{number}:", fragment)


def test_duplicate_constraint_term(model: dict[str, Path]) -> None:
    lines = model["constraints"].read_text().splitlines()
    with model["constraints"].open("a") as fh:
        fh.write(lines[1] + "\n")
    expect_error(
        lambda: read_matrix_files(**model),
        f"constraints.csv:{len(lines) + 1}:",
        "given twice (first on line 2)",
    )


def test_csv_tolerates_comments_blank_lines_spaces_and_case(model: dict[str, Path]) -> None:
    text = model["dofs"].read_text().upper().replace(",", " ,  ")
    model["dofs"].write_text("# exported by hand\n\n" + text)
    read = read_matrix_files(**model)
    np.testing.assert_array_equal(read.dofs.nodes, make_body().dofs.nodes)


def test_h5_without_marker(tmp_path: Path) -> None:
    path = tmp_path / "other.h5"
    with h5py.File(path, "w") as f:
        f["data"] = np.arange(3)
    expect_error(lambda: read_body_h5(path), "other.h5", "format marker")


def test_text_file_as_h5(tmp_path: Path) -> None:
    path = tmp_path / "text.h5"
    path.write_text("this is not HDF5\n")
    expect_error(lambda: read_body_h5(path), "text.h5", "not an HDF5 file")


def test_missing_h5(tmp_path: Path) -> None:
    expect_error(lambda: read_body_h5(tmp_path / "none.h5"), "none.h5", "not found")


def test_newer_h5_version(tmp_path: Path) -> None:
    path = write_body_h5(make_body(), tmp_path / "new.h5")
    with h5py.File(path, "a") as f:
        f.attrs["version"] = 3
    expect_error(lambda: read_body_h5(path), "new.h5", "version 3 is newer")


def test_damaged_h5(tmp_path: Path) -> None:
    path = write_body_h5(make_body(), tmp_path / "damaged.h5")
    with h5py.File(path, "a") as f:
        del f["stiffness/indptr"]
        f["stiffness/indptr"] = np.arange(3)
    expect_error(lambda: read_body_h5(path), "damaged.h5", "/stiffness", "CSR")
    with h5py.File(path, "a") as f:
        del f["mass"]
    expect_error(lambda: read_body_h5(path), "damaged.h5", "/mass is missing")


def test_writing_asymmetric_body_is_refused(tmp_path: Path) -> None:
    body = make_body()
    k = body.stiffness.tolil()
    k[0, 1] += 1e3
    bad = ElasticBody(
        node_ids=body.node_ids,
        coordinates=body.coordinates,
        dofs=body.dofs,
        mass=body.mass,
        stiffness=k,
        name="skew",
    )
    expect_error(lambda: write_matrix_files(bad, tmp_path), "'skew'", "stiffness", "not symmetric")
    assert not any(tmp_path.iterdir())


# ============================================================================ atomic writing
def test_atomic_write_failure_leaves_no_target_and_no_temporary(tmp_path: Path) -> None:
    target = tmp_path / "out.txt"
    with pytest.raises(RuntimeError, match="boom"), atomic_path(target) as tmp:
        tmp.write_text("half")
        raise RuntimeError("boom")
    assert list(tmp_path.iterdir()) == []


def test_atomic_write_failure_keeps_existing_target(tmp_path: Path) -> None:
    target = write_text(tmp_path / "out.csv", "old\n")
    os.chmod(target, 0o640)
    with pytest.raises(RuntimeError), atomic_open(target) as fh:
        fh.write("new")
        raise RuntimeError("writer failed")
    assert target.read_text() == "old\n"
    assert [p.name for p in tmp_path.iterdir()] == ["out.csv"]
    write_text(target, "new\n")
    assert target.read_text() == "new\n"
    assert target.stat().st_mode & 0o777 == 0o640


def test_atomic_temporary_is_a_hidden_sibling_with_the_same_extension(tmp_path: Path) -> None:
    target = tmp_path / "picture.png"
    with atomic_path(target) as tmp:
        assert tmp.parent == tmp_path and tmp.exists()
        assert tmp.name.startswith(".picture.") and tmp.suffix == ".png"
        assert not target.exists()
    assert write_bytes(target, b"\x00\x01") == target
    assert target.read_bytes() == b"\x00\x01"


def test_atomic_write_into_missing_directory(tmp_path: Path) -> None:
    expect_error(lambda: write_text(tmp_path / "no" / "such.txt", "x"), "such.txt", "cannot write")


def test_failed_h5_write_keeps_old_file(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    path = write_body_h5(make_body(name="old"), tmp_path / "body.h5")
    import pymorembs.io.native as native

    def broken(*args: object, **kwargs: object) -> None:
        raise OSError("disk full")

    monkeypatch.setattr(native, "put_csr", broken)
    with pytest.raises(OSError, match="disk full"):
        write_body_h5(make_body(name="new"), path)
    assert read_body_h5(path).name == "old"
    assert [p.name for p in tmp_path.iterdir()] == ["body.h5"]


def test_h5_keeps_scalar_dofs_notes_ports_and_missing_coordinates(tmp_path: Path) -> None:
    """Version 2: scalar coordinates, the reader's notes, model ports and has_coordinates."""
    from pymorembs.body import ModelPorts

    b = sp.csr_matrix(np.array([[1.0], [0.0], [0.5]]))
    c = sp.csr_matrix(np.array([[0.0, 1.0, 0.0], [0.0, 0.0, 2.0]]))
    body = ElasticBody(
        node_ids=np.array([1, 2]),
        coordinates=np.zeros((2, 3)),
        dofs=DofTable(np.array([1, 2, 9]), np.array([0, 1, 6])),
        mass=sp.identity(3, format="csr"),
        stiffness=sp.identity(3, format="csr") * 4.0,
        has_coordinates=False,
        notes=("dof table from the file", "no coordinates"),
        ports=ModelPorts(b, c, ("f",), ("y1", "y2")),
    )
    back = read_body_h5(write_body_h5(body, tmp_path / "v2.h5"))
    assert back.has_coordinates is False
    assert back.notes == body.notes
    assert back.dofs.label(2) == "9:q"
    assert (back.ports.inputs != b).nnz == 0 and (back.ports.outputs != c).nnz == 0
    assert back.ports.input_labels == ("f",) and back.ports.output_labels == ("y1", "y2")
    assert np.all(back.rigid_body_modes()[2] == 0.0)  # a scalar point does not move rigidly
