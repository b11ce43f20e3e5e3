"""Abaqus *MATRIX OUTPUT files: both layouts, one or both triangles, .inp nodes, bad inputs.

The files are written here from a known model (3 nodes x 6 dofs, random symmetric matrices with
full-mantissa values) so that reading them back must give the same matrices bit for bit.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from abaqus_models import (
    coordinate_text,
    cube,
    element_lines,
    matrix_input_text,
    node_lines,
    rotate,
    solid_matrices,
)
from pymorembs.elements.beam import BeamSection, element_matrices
from pymorembs.errors import UserError
from pymorembs.io.abaqus import read_abaqus, read_abaqus_stiffness, read_inp_nodes
from pymorembs.preparation.consistency import body_rounding, check_map

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
        ("*PART, NAME=P\n*NODE\n10, 0., 0., 0.\n", 1, "never instanced"),
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


# ============================================================================ parts, instances
# Models assembled here from linear tetrahedra and beams (tests/abaqus_models.py), so that K has
# the rigid-body null space of a real export; the input files have the layout Abaqus/CAE writes.
def cube_part_inp(
    path: Path, labels: list[int], instances: list[list[str]], extra: str = ""
) -> Path:
    """A part "cube" (8 nodes, 6 C3D4) and one *Instance per entry of ``instances``."""
    xyz, tets = cube()
    label = np.array(labels)
    lines = ["*Heading", "** Generated by: Abaqus/CAE 2021", "*Part, name=cube", "*Node"]
    lines += node_lines(label, xyz)
    lines += ["*Element, type=C3D4", *element_lines(label[tets]), "*End Part", "**"]
    lines += ["*Assembly, name=Assembly", "**"]
    for k, placement in enumerate(instances):
        lines += [f"*Instance, name=cube-{k + 1}, part=cube", *placement, "*End Instance", "**"]
    lines += [extra, "*End Assembly", "*Step", "*MATRIX GENERATE, STIFFNESS, MASS",
              "*MATRIX OUTPUT, STIFFNESS, MASS, FORMAT=COORDINATE", "*End Step"]  # fmt: skip
    path.write_text("\n".join(lines) + "\n")
    return path


A, B, ANGLE = np.array([0.5, -1.0, 2.0]), np.array([1.5, 0.0, 3.0]), 37.0


def placed_cube(translation: np.ndarray | None = None) -> np.ndarray:
    """Coordinates of the cube translated, then rotated about A-B by ANGLE degrees."""
    xyz, _ = cube()
    moved = xyz + (0.0 if translation is None else translation)
    return rotate(moved, A, B, ANGLE)


def rotation_lines(translation: tuple[float, float, float]) -> list[str]:
    return [", ".join(repr(float(v)) for v in translation),
            ", ".join(repr(float(v)) for v in [*A, *B, ANGLE])]  # fmt: skip


def test_coordinate_files_with_a_translated_and_rotated_instance(tmp_path: Path) -> None:
    labels = [11, 12, 13, 14, 15, 16, 17, 18]
    inp = cube_part_inp(tmp_path / "model.inp", labels, [rotation_lines((2.0, 0.5, -1.0))])
    _, tets = cube()
    xyz = placed_cube(np.array([2.0, 0.5, -1.0]))
    k, m = solid_matrices(xyz, tets)
    (tmp_path / "job_STIF1.mtx").write_text(coordinate_text(k))
    (tmp_path / "job_MASS1.mtx").write_text(coordinate_text(m))
    body = read_abaqus(tmp_path / "job_STIF1.mtx", tmp_path / "job_MASS1.mtx", inp=inp)
    np.testing.assert_array_equal(body.node_ids, labels)
    np.testing.assert_allclose(body.coordinates, xyz, atol=1e-14)
    np.testing.assert_array_equal(body.stiffness.toarray(), k)
    assert body.dofs.describe() == "8 nodes x ux uy uz"
    assert any("cube-1 of part cube translated by (2, 0.5, -1) and rotated by 37 degrees" in n
               for n in body.notes), body.notes  # fmt: skip
    proof = check_map(body, body_rounding(body))  # the one proof (the reader writes none)
    assert proof.proved and "leave no force in 24 of 24 rows" in proof.reason, proof
    # the same matrices with the rotation left out of the input file: refused
    plain = cube_part_inp(tmp_path / "plain.inp", labels, [["2.0, 0.5, -1.0"]])
    with pytest.raises(UserError, match=r"derived from plain\.inp does not fit") as err:
        read_abaqus(tmp_path / "job_STIF1.mtx", tmp_path / "job_MASS1.mtx", inp=plain)
    one_line(err)


def test_two_instances_an_assembly_truss_and_node_ids(tmp_path: Path) -> None:
    """Labels repeat across instances: ids k * 10**d + label; numbering follows the instances."""
    labels = [1, 2, 3, 4, 5, 6, 7, 8]
    truss = "*Element, type=T3D2, elset=link\n1, cube-1.8, cube-2.1"
    inp = cube_part_inp(
        tmp_path / "two.inp", labels, [[], rotation_lines((3.0, 0.0, 0.0))], extra=truss
    )
    xyz1, tets = cube()
    xyz2 = placed_cube(np.array([3.0, 0.0, 0.0]))
    xyz = np.vstack([xyz1, xyz2])
    k, m = solid_matrices(xyz, np.vstack([tets, tets + 8]))
    # the truss from node 8 of cube-1 to node 1 of cube-2 (axial stiffness only)
    axis = xyz[8] - xyz[7]
    unit = axis / np.linalg.norm(axis)
    block = 1e9 * np.outer(unit, unit)
    for (i, j), sign in {(7, 7): 1, (8, 8): 1, (7, 8): -1, (8, 7): -1}.items():
        k[3 * i : 3 * i + 3, 3 * j : 3 * j + 3] += sign * block
    k = 0.5 * (k + k.T)
    (tmp_path / "two_STIF1.mtx").write_text(coordinate_text(k))
    (tmp_path / "two_MASS1.mtx").write_text(coordinate_text(m))
    body = read_abaqus(tmp_path / "two_STIF1.mtx", tmp_path / "two_MASS1.mtx", inp=inp)
    np.testing.assert_array_equal(body.node_ids, [11, 12, 13, 14, 15, 16, 17, 18,
                                                  21, 22, 23, 24, 25, 26, 27, 28])  # fmt: skip
    np.testing.assert_allclose(body.coordinates, xyz, atol=1e-14)
    assert any("node ids are (cube-1: 10 + label, cube-2: 20 + label)" in n for n in body.notes)
    assert np.all(body.rigid_body_residuals() < 1e-14)
    # with the second instance not rotated, the truss direction is wrong: refused
    wrong = cube_part_inp(tmp_path / "wrong.inp", labels, [[], ["3.0, 0.0, 0.0"]], extra=truss)
    with pytest.raises(UserError, match="does not fit the matrices") as err:
        read_abaqus(tmp_path / "two_STIF1.mtx", tmp_path / "two_MASS1.mtx", inp=wrong)
    one_line(err)
    # matrix-input files of several instances: refused, the labels are not known
    keys = [(int(node), d) for node in range(1, 17) for d in (1, 2, 3)]
    (tmp_path / "in_STIF1.mtx").write_text(matrix_input_text(k, keys))
    (tmp_path / "in_MASS1.mtx").write_text(matrix_input_text(m, keys))
    with pytest.raises(UserError, match="nodes in 2 places") as err:
        read_abaqus(tmp_path / "in_STIF1.mtx", tmp_path / "in_MASS1.mtx", inp=inp)
    assert one_line(err).startswith(f"{inp}: ")


def test_matrix_input_with_one_rotated_instance(tmp_path: Path) -> None:
    labels = [5, 9, 2, 7, 30, 31, 32, 40]
    inp = cube_part_inp(tmp_path / "one.inp", labels, [rotation_lines((0.0, 0.0, 0.0))])
    _, tets = cube()
    xyz = placed_cube()
    k, m = solid_matrices(xyz, tets)
    keys = [(label, d) for label in labels for d in (1, 2, 3)]
    order = np.argsort([label * 8 + d for label, d in keys])  # the reader's table order
    (tmp_path / "one_STIF2.mtx").write_text(matrix_input_text(k, keys))
    (tmp_path / "one_MASS2.mtx").write_text(matrix_input_text(m, keys))
    body = read_abaqus(tmp_path / "one_STIF2.mtx", tmp_path / "one_MASS2.mtx", inp=inp)
    np.testing.assert_array_equal(body.stiffness.toarray(), k[np.ix_(order, order)])
    for label, point in zip(labels, xyz, strict=True):
        np.testing.assert_allclose(body.node_position(label), point, atol=1e-14)
    assert "node labels = the labels of instance cube-1 (part cube)" in body.notes
    proof = check_map(body, body_rounding(body))  # the one proof (the reader writes none)
    assert proof.proved and "leave no force in 24 of 24 rows" in proof.reason, proof
    # matrices of the unrotated cube with the rotated instance: the proof fails
    k0, _ = solid_matrices(cube()[0], tets)
    (tmp_path / "flat_STIF2.mtx").write_text(matrix_input_text(k0, keys))
    with pytest.raises(
        UserError, match=r"node labels of instance cube-1 \(part cube\) in one\.inp"
    ):
        read_abaqus(tmp_path / "flat_STIF2.mtx", tmp_path / "one_MASS2.mtx", inp=inp)


def test_penalties_on_beam_rotations_are_rebuilt_exactly(tmp_path: Path) -> None:
    """A B31 frame clamped at node 1 (all six dofs): the rebuilt diagonal is the true one."""
    section = BeamSection.circular(0.02, E=2.1e11, nu=0.3, rho=7850.0)
    xyz = np.array([[0.0, 0.0, 0.0], [0.4, 0.1, 0.0], [0.7, 0.5, 0.3], [1.0, 0.2, 0.9]])
    n = 24
    k, m = np.zeros((n, n)), np.zeros((n, n))
    for a, b in ((0, 1), (1, 2), (2, 3), (1, 3)):
        ke, me = element_matrices(xyz[a], xyz[b], section)
        eq = np.r_[6 * a : 6 * a + 6, 6 * b : 6 * b + 6]
        k[np.ix_(eq, eq)] += ke
        m[np.ix_(eq, eq)] += me
    k, m = 0.5 * (k + k.T), 0.5 * (m + m.T)
    with_penalty = k.copy()
    with_penalty[np.arange(6), np.arange(6)] = 1e36
    (tmp_path / "frame_STIF1.mtx").write_text(coordinate_text(with_penalty))
    (tmp_path / "frame_MASS1.mtx").write_text(coordinate_text(m))
    inp = tmp_path / "frame.inp"
    inp.write_text(
        "\n".join(
            [
                "*Node",
                *node_lines([1, 2, 3, 4], xyz),
                "*Element, type=B31",
                "1, 1, 2",
                "2, 2, 3",
                "3, 3, 4",
                "4, 2, 4",
            ]
        )
        + "\n"
    )
    body = read_abaqus(tmp_path / "frame_STIF1.mtx", tmp_path / "frame_MASS1.mtx", inp=inp)
    assert body.dofs.describe() == "4 nodes x ux uy uz rx ry rz"
    np.testing.assert_array_equal(body.fixed, np.arange(6))
    rebuilt = body.stiffness.toarray()
    np.testing.assert_allclose(np.diag(rebuilt)[:6], np.diag(k)[:6], rtol=1e-8)  # rotations too
    off = ~np.eye(n, dtype=bool)
    np.testing.assert_array_equal(rebuilt[off], k[off])
    np.testing.assert_array_equal(np.diag(rebuilt)[6:], np.diag(k)[6:])
    assert any(n.startswith("6 dofs of 1 node fixed in the matrix step") for n in body.notes)
    # without coordinates (dofs.csv) the rotational diagonals cannot be rebuilt: row sums
    dofs = tmp_path / "dofs.csv"
    names = ["ux", "uy", "uz", "rx", "ry", "rz"]
    dofs.write_text("node,direction\n" + "".join(f"{a},{d}\n" for a in range(1, 5) for d in names))
    blind = read_abaqus(tmp_path / "frame_STIF1.mtx", tmp_path / "frame_MASS1.mtx", dofs=dofs)
    got = blind.stiffness.toarray()
    np.testing.assert_allclose(np.diag(got)[:3], np.diag(k)[:3], rtol=1e-9)
    np.testing.assert_allclose(
        np.diag(got)[3:6], np.abs(k[3:6]).sum(axis=1) - np.abs(np.diag(k)[3:6])
    )
    assert any("for 3 of them as the sum of the row's absolute couplings" in n for n in blind.notes)
    assert not blind.has_coordinates


def test_planar_beam_model(tmp_path: Path) -> None:
    """B21 elements: dofs ux uy rz; the out-of-plane rigid fields have no entries (NaN)."""
    section = BeamSection.circular(0.02, E=2.1e11, nu=0.3, rho=7850.0)
    xyz = np.array([[0.0, 0.0, 0.0], [0.5, 0.2, 0.0], [1.0, -0.1, 0.0]])
    planar = np.array([0, 1, 5])
    keep = np.r_[planar, planar + 6]
    n = 9
    k = np.zeros((n, n))
    for a, b in ((0, 1), (1, 2)):
        ke, _ = element_matrices(xyz[a], xyz[b], section, up=np.array([0.0, 0.0, 1.0]))
        eq = np.r_[3 * a : 3 * a + 3, 3 * b : 3 * b + 3]
        k[np.ix_(eq, eq)] += ke[np.ix_(keep, keep)]
    k = 0.5 * (k + k.T)
    (tmp_path / "p_STIF1.mtx").write_text(coordinate_text(k))
    inp = tmp_path / "p.inp"
    inp.write_text("\n".join(["*Node", *node_lines([1, 2, 3], xyz), "*Element, type=B21",
                              "1, 1, 2", "2, 2, 3"]) + "\n")  # fmt: skip
    body = read_abaqus_stiffness(tmp_path / "p_STIF1.mtx", inp=inp)
    assert body.dofs.describe() == "3 nodes x ux uy rz"
    residuals = body.rigid_body_residuals()
    assert np.isnan(residuals[[2, 3, 4]]).all() and np.all(residuals[[0, 1, 5]] < 1e-14)


@pytest.mark.parametrize(
    ("element", "words"),
    [
        ("C3D8H", "element type C3D8H is a hybrid element"),
        ("C3D10M", "a modified element"),
        ("S4R5", "a shell with 5 dofs"),
        ("CONN3D2", "a connector, gap, coupling or rigid element"),
        ("C3D8T", "a coupled temperature-displacement element"),
        ("CAX4", "an axisymmetric element"),
        ("U1", "a user element"),
        ("XYZ9", "a type pymorembs does not know"),
    ],
)
def test_element_types_whose_equations_cannot_be_derived(
    tmp_path: Path, element: str, words: str
) -> None:
    xyz, tets = cube()
    k, m = solid_matrices(xyz, tets)
    (tmp_path / "c_STIF1.mtx").write_text(coordinate_text(k))
    (tmp_path / "c_MASS1.mtx").write_text(coordinate_text(m))
    inp = tmp_path / "c.inp"
    lines = ["*Node", *node_lines(range(1, 9), xyz), "*Element, type=C3D4"]
    lines += [*element_lines(tets + 1), f"*Element, type={element}", "7, 1, 2"]
    inp.write_text("\n".join(lines) + "\n")
    with pytest.raises(UserError) as err:
        read_abaqus(tmp_path / "c_STIF1.mtx", tmp_path / "c_MASS1.mtx", inp=inp)
    message = one_line(err)
    assert message.startswith(f"{inp}:17: element type {element} is "), message
    assert words in message and "cannot tell which equations Abaqus gives it" in message


def test_wrong_dof_count_unused_nodes_and_broken_structure(tmp_path: Path) -> None:
    xyz, tets = cube()
    k, m = solid_matrices(xyz, tets)
    (tmp_path / "c_STIF1.mtx").write_text(coordinate_text(k))
    (tmp_path / "c_MASS1.mtx").write_text(coordinate_text(m))

    def read(text: str) -> str:
        inp = tmp_path / "c.inp"
        inp.write_text(text)
        with pytest.raises(UserError) as err:
            read_abaqus(tmp_path / "c_STIF1.mtx", tmp_path / "c_MASS1.mtx", inp=inp)
        return one_line(err)

    nodes = "\n".join(["*Node", *node_lines(range(1, 9), xyz)])
    solids = "\n".join(["*Element, type=C3D4", *element_lines(tets + 1)])
    message = read(f"{nodes}\n*Element, type=B31\n1, 1, 2\n{solids}\n")
    assert "gives 30 equations (6 nodes x ux uy uz + 2 nodes x ux uy uz rx ry rz from elements " \
        "B31 C3D4) but the matrices have 24" in message  # fmt: skip
    # a node no element uses has no dofs: 9 nodes, 24 equations, accepted
    extra = "\n".join([nodes, "99, 5.0, 5.0, 5.0", solids]) + "\n"
    (tmp_path / "ok.inp").write_text(extra)
    body = read_abaqus(tmp_path / "c_STIF1.mtx", tmp_path / "c_MASS1.mtx", inp=tmp_path / "ok.inp")
    assert 99 not in body.dofs.nodes and body.n_dof == 24
    assert "not defined" in read(f"{nodes}\n*Element, type=C3D4\n1, 1, 2, 3, 77\n")
    assert "*ELGEN" in read(f"{nodes}\n{solids}\n*ELGEN, ELSET=A\n1, 2\n")
    assert "no *ELEMENT data" in read(f"{nodes}\n")
    assert "*END PART inside the model" in read(f"{nodes}\n*End Part\n")
    assert "names part other, which is not defined" in read(
        "*Part, name=p\n*End Part\n*Assembly, name=A\n*Instance, name=i, part=other\n"
        "*End Instance\n*End Assembly\n"
    )
    assert "2 values, expected the translation tx, ty, tz" in read(
        "*Part, name=p\n*End Part\n*Assembly, name=A\n*Instance, name=i, part=p\n"
        "1., 2.\n*End Instance\n*End Assembly\n"
    )
    assert "the rotation axis points a and b coincide" in read(
        "*Part, name=p\n*End Part\n*Assembly, name=A\n*Instance, name=i, part=p\n"
        "0., 0., 0.\n1., 1., 1., 1., 1., 1., 30.\n*End Instance\n*End Assembly\n"
    )
    message = read(f"{nodes}\n*Element, type=C3D4\n1, 1, 2, 3\n2, 1, 2, 3, 4\n")
    assert "element with 4 nodes, but the element on line 11" in message


# ============================================================================ the fast path
def _mirrored_coordinate(path: Path, matrix: np.ndarray, newline: str = "\n") -> Path:
    """Both triangles, upper row by row, each off-diagonal entry followed by its mirror (the
    layout of Abaqus/CAE 2021), ``% .15e`` values."""
    lines = []
    for i, j in zip(*np.nonzero(np.triu(matrix)), strict=True):
        lines.append(f"{i + 1} {j + 1} {matrix[i, j]: .15e}")
        if i != j:
            lines.append(f"{j + 1} {i + 1} {matrix[j, i]: .15e}")
    path.write_bytes((newline.join(lines) + newline).encode())
    return path


def _dofs_csv(path: Path) -> Path:
    names = ["ux", "uy", "uz", "rx", "ry", "rz"]
    path.write_text("node,direction\n" + "".join(f"{n},{names[d - 1]}\n" for n, d in KEYS))
    return path


@pytest.mark.parametrize("newline", ["\n", "\r\n", "\r"])
def test_coordinate_files_with_mirrors_on_the_next_line(tmp_path: Path, newline: str) -> None:
    k_values = np.array([float(f"{x:.15e}") for x in K.ravel()]).reshape(K.shape)
    m_values = np.array([float(f"{x:.15e}") for x in M.ravel()]).reshape(M.shape)
    k = _mirrored_coordinate(tmp_path / "k.mtx", k_values, newline)
    m = _mirrored_coordinate(tmp_path / "m.mtx", m_values, newline)
    body = read_abaqus(k, m, dofs=_dofs_csv(tmp_path / "dofs.csv"))
    np.testing.assert_array_equal(body.stiffness.toarray(), k_values)  # every line read
    np.testing.assert_array_equal(body.mass.toarray(), m_values)


@pytest.mark.parametrize(
    ("line", "words"),
    [
        ("2 1 1.0.5", "value '1.0.5' is not a number"),  # read as 1.0 by lenient parsers
        ("2 1.5 1.0", "column '1.5' is not an integer"),  # read as (2, 1) = 0.5 by them
        ("2 1 1.0e5e5", "value '1.0e5e5' is not a number"),
        ("2 3000000000 1.0", "lies outside the 2 equations"),  # beyond the int32 fast parse
    ],
)
def test_numbers_the_fast_parse_must_not_misread(tmp_path: Path, line: str, words: str) -> None:
    k = tmp_path / "k.mtx"
    k.write_text(f"1 1 2.0\n{line}\n2 2 3.0\n")
    m = tmp_path / "m.mtx"
    m.write_text("1 1 1.0\n2 2 1.0\n")
    dofs = tmp_path / "dofs.csv"
    dofs.write_text("node,direction\n1,ux\n1,uy\n")
    with pytest.raises(UserError, match=r"k\.mtx:2: ") as err:
        read_abaqus(k, m, dofs=dofs)
    assert words in one_line(err)


def test_matrix_input_fast_parse_refuses_wide_dofs_and_labels(tmp_path: Path) -> None:
    m = write_input(tmp_path / "m.mtx", M)
    for line, words in [
        ("10,300, 10,1, 1.0", "dof 300 of node 10"),  # beyond the int8 dof column
        ("2147483648,1, 10,1, 1.0", "node label 2147483648"),  # beyond the int32 labels
    ]:
        k = tmp_path / "k.mtx"
        k.write_text(write_input(tmp_path / "k0.mtx", K).read_text() + line + "\n")
        with pytest.raises(UserError, match=r"k\.mtx:\d+: ") as err:
            read_abaqus(k, m)
        assert words in one_line(err)
