"""Abaqus *MATRIX OUTPUT files: both layouts, one or both triangles, .inp nodes, bad inputs.

The files are written here from a known model (3 nodes x 6 dofs, random symmetric matrices with
full-mantissa values) so that reading them back must give the same matrices bit for bit.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from pymorembs.errors import UserError
from pymorembs.io.abaqus import read_abaqus, read_inp_nodes

NODES = np.array([10, 20, 30])
COORDS = np.array([[0.0, 0.0, 0.0], [0.5, -1.25, 2.0], [1.0, 3.0e-3, -7.5]])
#: (node, Abaqus dof 1..6) of every equation, sorted by node and dof
KEYS = [(int(node), dof) for node in NODES for dof in range(1, 7)]


def spd(n: int, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    a = rng.standard_normal((n, n))
    a[np.abs(a) < 0.6] = 0.0  # some sparsity
    return a @ a.T + n * np.eye(n)


K = spd(18, 1) * 1e6
M = spd(18, 2)
M[15:, :] = M[:, 15:] = 0.0  # node 30 rotations are massless


def number(value: float, style: str) -> str:
    """A float that reads back exactly: repr, or 17 digits with an E or D exponent."""
    value = float(value)
    if style == "repr":
        return repr(value)
    text = f"{value:.16E}"
    return text.replace("E", "D") if style == "D" else text


def write_input(
    path: Path,
    matrix: np.ndarray,
    keys: list[tuple[int, int]] = KEYS,
    triangle: str = "lower",
    style: str = "repr",
    extras: bool = False,
) -> Path:
    """Matrix-input layout ``node, dof, node, dof, value`` by columns, like Abaqus writes it."""
    lines = ["** stiffness written by the test", ""] if extras else []
    n = matrix.shape[0]
    for j in range(n):
        rows = {"lower": range(j, n), "upper": range(j + 1), "square": range(n)}[triangle]
        for i in rows:
            if matrix[i, j] != 0.0:
                (ni, di), (nj, dj) = keys[i], keys[j]
                lines.append(f"{ni},{di}, {nj},{dj},  {number(matrix[i, j], style)}")
                if extras and len(lines) % 7 == 0:
                    lines.extend(["", "**  a comment inside the data"])
    path.write_text("\n".join(lines) + "\n")
    return path


def write_coordinate(path: Path, matrix: np.ndarray, separator: str = " ") -> Path:
    """FORMAT=COORDINATE layout ``row column value`` (lower triangle, from 1)."""
    rows, cols = np.nonzero(np.tril(matrix))
    text = "".join(
        f"{i + 1}{separator}{j + 1}{separator}{float(matrix[i, j])!r}\n"
        for i, j in zip(rows.tolist(), cols.tolist(), strict=True)
    )
    path.write_text(text)
    return path


def write_inp(path: Path, nodes: np.ndarray = NODES, coords: np.ndarray = COORDS) -> Path:
    lines = ["*Heading", "model for the test, *NODE in the heading is text", "** comment"]
    lines += ["*Node,", " nset=all"]  # a keyword line continued on the next line
    for node, (x, y, z) in zip(nodes.tolist(), coords.tolist(), strict=True):
        lines.append(f"{node:8d}, {x!r}, {y!r}, {z!r}")
    lines += ["*Element, type=B31, elset=beam", "1, 10, 20", "2, 20, 30", "*End Step"]
    path.write_text("\n".join(lines) + "\n")
    return path


def one_line(err: pytest.ExceptionInfo[UserError]) -> str:
    message = str(err.value)
    assert "\n" not in message
    return message


# ============================================================================ good files
@pytest.mark.parametrize("style", ["repr", "E", "D"])
def test_matrix_input_reads_back_exactly(tmp_path: Path, style: str) -> None:
    k = write_input(tmp_path / "job_STIF2.mtx", K, style=style, extras=True)
    m = write_input(tmp_path / "job_MASS2.mtx", M, style=style)
    body = read_abaqus(k, m, inp=write_inp(tmp_path / "job.inp"))
    assert body.name == "job"
    assert body.dofs.nodes.tolist() == [n for n, _ in KEYS]
    assert body.dofs.directions.tolist() == [d - 1 for _, d in KEYS]
    np.testing.assert_array_equal(body.stiffness.toarray(), K)
    np.testing.assert_array_equal(body.mass.toarray(), M)
    np.testing.assert_array_equal(body.node_ids, NODES)
    np.testing.assert_array_equal(body.coordinates, COORDS)
    assert body.damping_matrix is None


@pytest.mark.parametrize("triangle", ["upper", "square"])
def test_upper_triangle_and_square_storage(tmp_path: Path, triangle: str) -> None:
    k = write_input(tmp_path / "k.mtx", K, triangle=triangle)
    m = write_input(tmp_path / "m.mtx", M, triangle=triangle)
    body = read_abaqus(k, m, name="square")
    np.testing.assert_array_equal(body.stiffness.toarray(), K)
    np.testing.assert_array_equal(body.mass.toarray(), M)
    assert body.name == "square"
    np.testing.assert_array_equal(body.coordinates, np.zeros((3, 3)))


def test_one_triangle_in_another_equation_order(tmp_path: Path) -> None:
    """Abaqus stores one triangle in its own equation order: sides of our diagonal mix."""
    rng = np.random.default_rng(4)
    lines = []
    for i, j in zip(*np.nonzero(np.tril(K)), strict=True):
        if rng.random() < 0.5:
            i, j = j, i
        (ni, di), (nj, dj) = KEYS[i], KEYS[j]
        lines.append(f"{ni},{di}, {nj},{dj}, {float(K[i, j])!r}")
    k = tmp_path / "k.mtx"
    k.write_text("\n".join(lines) + "\n")
    body = read_abaqus(k, write_input(tmp_path / "m.mtx", M))
    np.testing.assert_array_equal(body.stiffness.toarray(), K)


def test_massless_dofs_and_dofs_only_in_mass(tmp_path: Path) -> None:
    """The dof table is the union; node 30 rotations have no mass, node 40 ux no stiffness."""
    m_keys = [*KEYS[:15], (40, 1)]
    m = np.zeros((16, 16))
    m[:15, :15] = M[:15, :15]
    m[15, 15] = 3.5
    k_file = write_input(tmp_path / "k.mtx", K)
    m_file = write_input(tmp_path / "m.mtx", m, keys=m_keys)
    nodes = np.append(NODES, 40)
    coords = np.vstack([COORDS, [9.0, 8.0, 7.0]])
    body = read_abaqus(k_file, m_file, inp=write_inp(tmp_path / "a.inp", nodes, coords))
    assert body.n_dof == 19
    assert body.dofs.label(18) == "40:ux"
    expected_k = np.zeros((19, 19))
    expected_k[:18, :18] = K
    expected_m = np.zeros((19, 19))
    expected_m[:15, :15] = M[:15, :15]
    expected_m[18, 18] = 3.5
    np.testing.assert_array_equal(body.stiffness.toarray(), expected_k)
    np.testing.assert_array_equal(body.mass.toarray(), expected_m)
    assert not body.mass[15:18].count_nonzero()  # massless rotations of node 30
    np.testing.assert_array_equal(body.node_position(40), [9.0, 8.0, 7.0])


def test_damping_matrix(tmp_path: Path) -> None:
    d = spd(18, 3) * 1e-2
    body = read_abaqus(
        write_input(tmp_path / "k.mtx", K),
        write_input(tmp_path / "m.mtx", M),
        damping=write_input(tmp_path / "job_DMPV1.mtx", d, triangle="upper"),
    )
    np.testing.assert_array_equal(body.damping_matrix.toarray(), d)
    structural = write_input(tmp_path / "job_DMPS1.mtx", d)
    with pytest.raises(UserError, match="structural damping") as err:
        read_abaqus(tmp_path / "k.mtx", tmp_path / "m.mtx", damping=structural)
    one_line(err)


@pytest.mark.parametrize("separator", [" ", ",", "   "])
def test_coordinate_layout_with_dofs_table(tmp_path: Path, separator: str) -> None:
    k = write_coordinate(tmp_path / "k.mtx", K, separator)
    m = write_coordinate(tmp_path / "m.mtx", M, separator)
    dofs = tmp_path / "dofs.csv"
    names = ["ux", "uy", "uz", "rx", "ry", "rz"]
    dofs.write_text("node,direction\n" + "".join(f"{n},{names[d - 1]}\n" for n, d in KEYS))
    nodes = tmp_path / "nodes.csv"
    nodes.write_text(
        "id,x,y,z\n"
        + "".join(
            f"{n},{x!r},{y!r},{z!r}\n"
            for n, (x, y, z) in zip(NODES.tolist(), COORDS.tolist(), strict=True)
        )
    )
    body = read_abaqus(k, m, dofs=dofs, inp=nodes)
    np.testing.assert_array_equal(body.stiffness.toarray(), K)
    np.testing.assert_array_equal(body.mass.toarray(), M)
    assert body.dofs.label(4) == "10:ry"
    np.testing.assert_array_equal(body.coordinates, COORDS)
    with pytest.raises(UserError, match=r"dofs\.csv") as err:
        read_abaqus(k, m)
    assert "FORMAT=COORDINATE" in one_line(err)


def test_inp_nodes_include_and_two_dimensional_lines(tmp_path: Path) -> None:
    (tmp_path / "more.inp").write_text("** included\n*NODE\n30, 1., 2.0D0\n")
    inp = tmp_path / "model.inp"
    inp.write_text(
        "*HEADING\n** c\n*NODE, NSET=A\n10, 0., 0., 0.\n\n20, 1.5, , -2.\n"
        "*INCLUDE, INPUT=more.inp\n*ELEMENT, TYPE=B31\n1, 10, 20\n"
    )
    ids, coords = read_inp_nodes(inp)
    assert ids.tolist() == [10, 20, 30]
    np.testing.assert_array_equal(coords, [[0, 0, 0], [1.5, 0, -2], [1, 2, 0]])


# ============================================================================ bad files
def good_files(tmp_path: Path) -> tuple[Path, Path]:
    return write_input(tmp_path / "k.mtx", K), write_input(tmp_path / "m.mtx", M)


def test_node_missing_in_inp(tmp_path: Path) -> None:
    k, m = good_files(tmp_path)
    inp = write_inp(tmp_path / "a.inp", NODES[:2], COORDS[:2])
    with pytest.raises(UserError) as err:
        read_abaqus(k, m, inp=inp)
    message = one_line(err)
    assert message.startswith(f"{k}:")
    assert "node 30 is not defined in" in message and "a.inp" in message


@pytest.mark.parametrize(
    ("text", "line", "words"),
    [
        ("1,1, 1,1, 2.0\n2,1, 1,1, -1.0\n2,1, 1\n", 3, "is the line cut"),
        ("1,1, 1,1, 2.0\n2,1, 1,1, nan\n2,1, 2,1, 3.0\n", 2, "not a finite number"),
        ("1,1, 1,1, 2.0\n2,1, 1,1, -1.0\n1,1, 2,1, -1.5\n2,1, 2,1, 3.0\n", 3, "not symmetric"),
        ("1,1, 1,1, 2.0\n2,1, 1,1, -1.0\n2,1, 1,1, -1.5\n", 3, "line 2 has -1.0"),
        ("1,1, 1,1, 2.0\n1,8, 1,1, 1.0\n", 2, "dof 8 of node 1 is a pore"),
        ("1,1, 1,1, 2.0\n1,11, 1,11, 1.0\n", 2, "temperature"),
        ("1,1, 1,1, 2.0\n-3,1, 1,1, 1.0\n", 2, "internal node"),
        ("1,1, 1,1, 2.0\n1,1, 2,1, x\n", 2, "value 'x' is not a number"),
        ("1,1, 1,1, 2.0\n1,a, 1,1, 1.0\n", 2, "row dof 'a' is not an integer"),
        ("1, 1, 1, 2.0\n", 1, "4 fields"),
        ("** header\n*MATRIX, TYPE=STIFFNESS\n1,1,1,1,2.0\n", 2, "keyword line"),
        ("1,1, 1,1, 2.0\n2,1, 1,1, -1.0\n1,1, 2,1, -1.0\n1,2, 1,1, 0.5\n", 4, "no mirror entry"),
    ],
)
def test_bad_stiffness_file(tmp_path: Path, text: str, line: int, words: str) -> None:
    k = tmp_path / "k.mtx"
    k.write_text(text)
    m = tmp_path / "m.mtx"
    m.write_text("1,1, 1,1, 1.0\n")
    with pytest.raises(UserError) as err:
        read_abaqus(k, m)
    message = one_line(err)
    assert message.startswith(f"{k}:{line}: "), message
    assert words in message


def test_identical_duplicates_are_read_once(tmp_path: Path) -> None:
    k = tmp_path / "k.mtx"
    k.write_text("1,1, 1,1, 2.0\n2,1, 1,1, -1.0\n2,1, 1,1, -1.0\n2,1, 2,1, 3.0\n")
    m = tmp_path / "m.mtx"
    m.write_text("1,1, 1,1, 1.0\n2,1, 2,1, 1.0\n")
    body = read_abaqus(k, m)
    np.testing.assert_array_equal(body.stiffness.toarray(), [[2.0, -1.0], [-1.0, 3.0]])


@pytest.mark.parametrize(
    ("text", "words"),
    [
        ("", "no matrix entries"),
        ("** only a comment\n\n", "no matrix entries"),
    ],
)
def test_empty_files(tmp_path: Path, text: str, words: str) -> None:
    k = tmp_path / "k.mtx"
    k.write_text(text)
    with pytest.raises(UserError, match=words) as err:
        read_abaqus(k, k)
    assert one_line(err).startswith(f"{k}: ")


def test_mixed_layouts_and_misplaced_dofs(tmp_path: Path) -> None:
    k, m = good_files(tmp_path)
    coordinate = write_coordinate(tmp_path / "c.mtx", M)
    with pytest.raises(UserError, match="same FORMAT") as err:
        read_abaqus(k, coordinate)
    one_line(err)
    dofs = tmp_path / "dofs.csv"
    dofs.write_text("node,direction\n10,ux\n")
    with pytest.raises(UserError, match="only used with FORMAT=COORDINATE"):
        read_abaqus(k, m, dofs=dofs)
    short = tmp_path / "short.csv"
    short.write_text("node,direction\n10,ux\n10,uy\n")
    big = write_coordinate(tmp_path / "big.mtx", K)
    with pytest.raises(UserError, match="outside the 2 equations") as err:
        read_abaqus(big, big, dofs=short)
    assert one_line(err).startswith(f"{big}:")


def test_missing_file(tmp_path: Path) -> None:
    k, _ = good_files(tmp_path)
    with pytest.raises(UserError, match="file not found") as err:
        read_abaqus(k, tmp_path / "nope.mtx")
    one_line(err)


@pytest.mark.parametrize(
    ("inp_text", "line", "words"),
    [
        ("*PART, NAME=P\n*NODE\n10, 0., 0., 0.\n", 1, "parts and assemblies"),
        ("*NODE, SYSTEM=C\n10, 1., 0., 0.\n", 1, "SYSTEM=C"),
        ("*NODE\n10, 0., 0., 0.\n*TRANSFORM, NSET=A\n1.,0.,0.,0.,1.,0.\n", 3, "*TRANSFORM"),
        ("*NODE\n10, 0., 0., 0.\n10, 1., 0., 0.\n", 3, "defined twice"),
        ("*NODE\nten, 0., 0., 0.\n", 2, "not an integer"),
        ("*NODE\n10, 0., zero, 0.\n", 2, "coordinate y"),
        ("*NGEN, NSET=A\n1, 5\n", 1, "*NGEN"),
    ],
)
def test_bad_inp(tmp_path: Path, inp_text: str, line: int, words: str) -> None:
    k, m = good_files(tmp_path)
    inp = tmp_path / "bad.inp"
    inp.write_text(inp_text)
    with pytest.raises(UserError) as err:
        read_abaqus(k, m, inp=inp)
    message = one_line(err)
    assert message.startswith(f"{inp}:{line}: "), message
    assert words in message
