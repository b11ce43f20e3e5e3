"""Abaqus ``*SUBSTRUCTURE MATRIX OUTPUT`` files: the genuine ones of abaqus-mtx-parser, bad ones.

The genuine files (``tests/data/abaqus_mtx_parser``, see SOURCE.md) come without input files
and without published frequencies: the checks are the node lists and dof maps (those the
package's own tests assert), an independent parse of the values with plain numpy, symmetry,
and positive semidefiniteness of K and M.
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest

from abaqus_models import genuine, substructure_text
from pymorembs.errors import UserError
from pymorembs.io.abaqus_substructure import read_abaqus_substructure
from pymorembs.io.formats import detect_format, read_body

SET = "abaqus_mtx_parser"
SIX = ["ux", "uy", "uz", "rx", "ry", "rz"]


@pytest.fixture(scope="module")
def unpacked(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return tmp_path_factory.mktemp("genuine")


def parse(path: Path, n: int) -> dict[str, np.ndarray]:
    """The *MATRIX blocks as dense matrices: plain numpy on the text (independent)."""
    out = {}
    for block in re.split(r"(?m)^\*MATRIX,TYPE=", path.read_text())[1:]:
        kind, _, body = block.partition("\n")
        values = np.array(body.replace(",", " ").split(), dtype=float)
        if values.size == n * n:
            out[kind.strip()] = values.reshape(n, n)
        else:
            lower = np.zeros((n, n))
            lower[np.tril_indices(n)] = values
            out[kind.strip()] = lower + np.tril(lower, -1).T
    return out


@pytest.mark.parametrize(
    ("name", "nodes"),
    [
        ("symmetric/inner.mtx", [2, 3, 4, 5, 6, 7]),
        ("symmetric/total.mtx", [8, 9, 10, 11, 12, 13]),
        ("symmetric/outer.mtx", list(range(2, 14))),
        ("unsymmetric/inner.mtx", [2, 3, 4, 5, 6, 7]),
        ("unsymmetric/total.mtx", [8, 9, 10, 11, 12, 13]),
        ("unsymmetric/outer.mtx", list(range(2, 14))),
    ],
)
def test_genuine_substructures_with_six_dofs(unpacked: Path, name: str, nodes: list[int]) -> None:
    path = genuine(f"{SET}/{name}", unpacked)
    assert detect_format(path) == "abaqus-substructure"
    body = read_body(file=path)
    n = 6 * len(nodes)
    assert body.n_dof == n and body.dofs.describe() == f"{len(nodes)} nodes x ux uy uz rx ry rz"
    np.testing.assert_array_equal(body.node_ids, nodes)
    np.testing.assert_array_equal(body.dofs.nodes, np.repeat(nodes, 6))
    assert not body.has_coordinates
    reference = parse(path, n)
    k, m = body.stiffness.toarray(), body.mass.toarray()
    np.testing.assert_array_equal(m, reference["MASS"])
    if name.startswith("unsymmetric"):
        full = reference["STIFFNESS"]
        np.testing.assert_allclose(k, 0.5 * (full + full.T), rtol=0, atol=0)
        assert np.abs(full - full.T).max() <= 2e-16 * np.abs(full).max()  # symmetric to rounding
        assert any("stiffness matrix stored full" in note for note in body.notes)
        twin = read_body(
            file=genuine(f"{SET}/{name.replace('unsymmetric', 'symmetric')}", unpacked)
        )
        np.testing.assert_allclose(k, twin.stiffness.toarray(), atol=1e-9 * np.abs(k).max())
    else:
        np.testing.assert_array_equal(k, reference["STIFFNESS"])
    assert np.array_equal(k, k.T) and np.array_equal(m, m.T)
    for matrix in (k, m):
        values = np.linalg.eigvalsh(matrix)
        assert values[0] >= -1e-12 * values[-1]  # positive semidefinite to rounding
    assert body.rigid_body_residuals()[:3].max() < 1e-12  # translations need no coordinates


def test_genuine_substructure_with_mixed_dof_counts(unpacked: Path) -> None:
    path = genuine(f"{SET}/recovery/interface-beam-sub.mtx", unpacked)
    body = read_abaqus_substructure(path)
    assert body.n_dof == 150
    assert body.dofs.describe() == "46 nodes x ux uy uz + 2 nodes x ux uy uz rx ry rz"
    counts = np.array([np.count_nonzero(body.dofs.nodes == node) for node in range(1, 49)])
    np.testing.assert_array_equal(counts, [3] * 45 + [6, 6, 3])
    reference = parse(path, 150)
    np.testing.assert_array_equal(body.stiffness.toarray(), reference["STIFFNESS"])
    np.testing.assert_array_equal(body.mass.toarray(), reference["MASS"])
    text = path.read_text().split("*MATRIX,TYPE=MASS")[1]
    assert len(text.replace(",", " ").split()) == 11325 == 150 * 151 // 2  # a lower triangle
    for matrix in (reference["STIFFNESS"], reference["MASS"]):
        values = np.linalg.eigvalsh(matrix)
        assert values[0] >= -1e-12 * values[-1]


def test_coordinates_from_a_nodes_csv(unpacked: Path, tmp_path: Path) -> None:
    path = genuine(f"{SET}/symmetric/inner.mtx", unpacked)
    nodes = tmp_path / "nodes.csv"
    nodes.write_text("id,x,y,z\n" + "".join(f"{k},{k / 10},0.0,0.0\n" for k in range(1, 9)))
    body = read_abaqus_substructure(path, inp=nodes, name="inner")
    assert body.has_coordinates and body.name == "inner"
    np.testing.assert_array_equal(body.node_position(7), [0.7, 0.0, 0.0])
    assert any(
        note.startswith("rigid-body check of the six rigid-body motions") for note in body.notes
    )
    short = tmp_path / "short.csv"
    short.write_text("id,x,y,z\n2,0,0,0\n")
    with pytest.raises(UserError, match=r"retained node 3 is not defined in .*short\.csv"):
        read_abaqus_substructure(path, inp=short)


# ============================================================================ written here
K3 = np.array([[4.0, -1.0, 0.5], [-1.0, 3.0, -0.25], [0.5, -0.25, 2.0]]) * 1e3
M3 = np.diag([1.0, 2.0, 3.0])
DOFS = ["          1,          2", "          2,          3"]  # node 7: ux uy; node 9: uy (from 2)


def write(tmp_path: Path, text: str) -> Path:
    path = tmp_path / "sub.mtx"
    path.write_text(text)
    return path


def one_line(err: pytest.ExceptionInfo[UserError]) -> str:
    message = str(err.value)
    assert "\n" not in message
    return message


def test_mixed_dofs_and_fortran_exponents(tmp_path: Path) -> None:
    text = substructure_text([7, 9], DOFS, {"STIFFNESS": K3, "MASS": M3})
    text = text.replace("3000.0", "0.3000000000000+004").replace("2.0,", "2.0D0,")
    body = read_abaqus_substructure(write(tmp_path, text))
    assert [body.dofs.label(i) for i in range(3)] == ["7:ux", "7:uy", "9:uz"]
    np.testing.assert_array_equal(body.stiffness.toarray(), K3)
    np.testing.assert_array_equal(body.mass.toarray(), M3)


def test_unsym_stiffness(tmp_path: Path) -> None:
    near = K3.copy()
    near[0, 1] *= 1 + 1e-14
    body = read_abaqus_substructure(
        write(tmp_path, substructure_text([7, 9], DOFS, {"STIFFNESS": near, "MASS": M3}, True))
    )
    np.testing.assert_allclose(body.stiffness.toarray(), K3, rtol=1e-13)
    skew = K3.copy()
    skew[2, 0] = 0.6e3
    path = write(tmp_path, substructure_text([7, 9], DOFS, {"STIFFNESS": skew, "MASS": M3}, True))
    with pytest.raises(UserError) as err:
        read_abaqus_substructure(path)
    message = one_line(err)
    assert message.startswith(f"{path}:9: *MATRIX, TYPE=STIFFNESS (stored full) is not symmetric")
    assert "entry (7:ux, 9:uz) = 500.0 but (9:uz, 7:ux) = 600.0" in message


@pytest.mark.parametrize(
    ("edit", "line", "words"),
    [
        (
            lambda t: "\n".join(t.split("\n")[:10]),  # cut inside the stiffness block
            10,
            "holds 3 of the 6 values of the lower triangle of 3 equations; is the file cut?",
        ),
        (lambda t: t.replace("*MATRIX,TYPE=MASS", "*MATRIX,TYPE=MASS\n1.0,"), 16, "holds 7 values"),
        (lambda t: t.split("*MATRIX,TYPE=MASS")[0], None, "holds only the stiffness matrix"),
        (lambda t: t.replace("         1,          2\n", "1, 8\n", 1), 6, "dof 8 is a pore"),
        (
            lambda t: t.replace("2,          3", "1,          3"),
            7,
            "node position 1: expected 2..2",
        ),
        (
            lambda t: t.replace("2,          3", "3,          3"),
            7,
            "node position 3: expected 2..2",
        ),
        (lambda t: t.replace("2000.0", "x2"), 11, "value 'x2' is not a number"),
        (lambda t: t.replace("2000.0", "nan"), 11, "value nan is not a finite number"),
        (
            lambda t: t.replace("NODES=         2", "NODES=         3"),
            3,
            "names 2 nodes but NODES=3",
        ),
        (lambda t: t.replace("         7,", "        -7,"), 3, "node -7 in the ELEMENT NODES list"),
        (lambda t: t.replace(", LINEAR", ""), 3, "without LINEAR"),
        (lambda t: t.replace("TYPE=MASS", "TYPE=LOAD"), 12, "TYPE=LOAD: expected TYPE=STIFFNESS"),
        (lambda t: t.replace("*USER ELEMENT", "*ELEMENT"), 3, "starts with *USER ELEMENT"),
    ],
)
def test_broken_substructure_files(
    tmp_path: Path, edit: object, line: int | None, words: str
) -> None:
    text = edit(substructure_text([7, 9], DOFS, {"STIFFNESS": K3, "MASS": M3}))  # type: ignore[operator]
    path = write(tmp_path, text)
    with pytest.raises(UserError) as err:
        read_abaqus_substructure(path)
    message = one_line(err)
    where = f"{path}:{line}: " if line is not None else f"{path}: "
    assert message.startswith(where), message
    assert words in message, message
