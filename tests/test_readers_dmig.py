"""Nastran DMIG punch files: small, large and free field, continuations, GRID nodes, bad inputs.

The punch files are written here from a known model whose entries are exact in 8 characters
(multiples of 1/4 below 10^5), so every field width must read back bit for bit.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from pymorembs.errors import UserError
from pymorembs.io.nastran_dmig import read_dmig, read_grid_nodes

GRIDS = np.array([101, 102, 205])
XYZ = np.array([[0.0, 0.0, 0.0], [1.5, -2.0, 0.25], [3.0, 0.5, -1.0]])
KEYS = [(int(g), c) for g in GRIDS for c in range(1, 7)]  # (grid, component 1..6)


def known_matrices() -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(5)
    a = rng.integers(-6, 7, size=(18, 18)).astype(float)
    a[rng.random((18, 18)) < 0.5] = 0.0
    k = (a @ a.T + 40 * np.eye(18)) * 4.25  # exact multiples of 1/4
    m = np.diag(rng.integers(1, 40, size=18) / 4.0)
    m[0, 6] = m[6, 0] = 0.5  # a little coupling
    m[15:, :] = m[:, 15:] = 0.0  # grid 205 rotations are massless
    return k, m


K, M = known_matrices()


def columns(matrix: np.ndarray, keys: list[tuple[int, int]], triangle: str = "upper"):
    """(column key, [(row key, value), ...]) like Nastran punches them (rows up to the column)."""
    n = matrix.shape[0]
    for j in range(n):
        rows = range(j + 1) if triangle == "upper" else range(j, n)
        entries = [(keys[i], float(matrix[i, j])) for i in rows if matrix[i, j] != 0.0]
        if entries:
            yield keys[j], entries


def small(value: float) -> str:
    text = repr(value)
    assert len(text) <= 8, text
    return text


def large(value: float, exponent: str = "D") -> str:
    return f"{value:16.9E}".replace("E", exponent)


def punch_large(name: str, matrix: np.ndarray, keys=KEYS, triangle="upper", ifo=6) -> list[str]:
    lines = [f"DMIG    {name:<8}{0:>8}{ifo:>8}{2:>8}{0:>8}{'':8}{'':8}{len(keys):>8}"]
    for (gj, cj), entries in columns(matrix, keys, triangle):
        lines.append(f"DMIG*   {name:<16}{gj:>16}{cj:>16}")
        lines += [f"*       {g:>16}{c:>16}{large(v)}" for (g, c), v in entries]
    return lines


def punch_small(name: str, matrix: np.ndarray, keys=KEYS, triangle="upper") -> list[str]:
    lines = [f"DMIG    {name:<8}{0:>8}{6:>8}{1:>8}{0:>8}{'':8}{'':8}{len(keys):>8}"]
    for number, ((gj, cj), entries) in enumerate(columns(matrix, keys, triangle)):
        (g, c), v = entries[0]
        # columns 73-80 hold a continuation label, as Nastran punches them
        lines.append(
            f"DMIG    {name:<8}{gj:>8}{cj:>8}{'':8}{g:>8}{c:>8}{small(v):>8}{'':8}+C{number}"
        )
        rest = entries[1:]
        for k in range(0, len(rest), 2):
            pair = rest[k : k + 2]
            text = "".join(f"{g:>8}{c:>8}{small(v):>8}{'':8}" for (g, c), v in pair)
            lines.append(f"+C{number:<6}{text}")
    return lines


def punch_free(name: str, matrix: np.ndarray, keys=KEYS) -> list[str]:
    lines = [f"DMIG,{name},0,6,1,0,,,{len(keys)}"]
    for (gj, cj), entries in columns(matrix, keys):
        (g, c), v = entries[0]
        lines.append(f"DMIG,{name},{gj},{cj},,{g},{c},{v!r}")
        rest = entries[1:]
        for k in range(0, len(rest), 2):
            lines.append("," + ",".join(f"{g},{c},{v!r}," for (g, c), v in rest[k : k + 2]))
    return lines


def write(path: Path, lines: list[str]) -> Path:
    path.write_text("\n".join(lines) + "\n")
    return path


def write_grids(path: Path, style: str = "small", grids=GRIDS, xyz=XYZ) -> Path:
    lines = ["$ grids", "BEGIN BULK"]
    for g, (x, y, z) in zip(grids.tolist(), xyz.tolist(), strict=True):
        if style == "small":
            lines.append(f"GRID    {g:>8}{'':8}{small(x):>8}{small(y):>8}{small(z):>8}")
        elif style == "large":
            lines.append(f"GRID*   {g:>16}{'':16}{large(x, 'E'):>16}{large(y, 'E'):>16}")
            lines.append(f"*       {large(z, 'E'):>16}{'0':>16}")
        else:
            lines.append(f"GRID,{g},0,{x!r},{y!r},{z!r}")
    lines.append("ENDDATA")
    return write(path, lines)


def expected_order(body) -> list[int]:
    return [body.dofs.index(g, c - 1) for g, c in KEYS]


def one_line(err: pytest.ExceptionInfo[UserError]) -> str:
    message = str(err.value)
    assert "\n" not in message
    return message


# ============================================================================ good files
@pytest.mark.parametrize("writer", [punch_large, punch_small, punch_free])
def test_field_formats_read_back_exactly(tmp_path: Path, writer) -> None:
    lines = ["$ punched by the test", *writer("KAAX", K), "$ mass", "", *writer("MAAX", M)]
    body = read_dmig(write(tmp_path / "model.pch", lines), nodes=write_grids(tmp_path / "g.bdf"))
    assert body.name == "model"
    assert body.dofs.nodes.tolist() == [g for g, _ in KEYS]
    assert body.dofs.directions.tolist() == [c - 1 for _, c in KEYS]
    np.testing.assert_array_equal(body.stiffness.toarray(), K)
    np.testing.assert_array_equal(body.mass.toarray(), M)
    assert not body.mass[15:18].count_nonzero()  # massless rotations of grid 205
    np.testing.assert_array_equal(body.node_ids, GRIDS)
    np.testing.assert_array_equal(body.coordinates, XYZ)


def test_lower_triangle_and_square_form(tmp_path: Path) -> None:
    lines = punch_small("KAAX", K, triangle="lower")
    lines += punch_large("MAAX", M, ifo=1)  # IFO=1 (square) gives both triangles
    for (gj, cj), entries in columns(np.tril(M, -1), KEYS, triangle="lower"):
        lines.append(f"DMIG*   {'MAAX':<16}{gj:>16}{cj:>16}")
        lines += [f"*       {g:>16}{c:>16}{large(v, 'E')}" for (g, c), v in entries]
    body = read_dmig(write(tmp_path / "a.pch", lines))
    np.testing.assert_array_equal(body.stiffness.toarray(), K)
    np.testing.assert_array_equal(body.mass.toarray(), M)


def test_nastran_short_exponents_and_tabs(tmp_path: Path) -> None:
    lines = [
        "DMIG    KAAX           0       6       1       0                       2",
        "DMIG    KAAX         101       1             101       1 2.125+3",
        "DMIG\tKAAX\t101\t2\t\t101\t1\t-.5\t\t+",
        "+\t101\t2\t25.-1",
        "DMIG    MAAX           0       6       1       0                       2",
        "DMIG    MAAX         101       1             101       1      1.",
        "DMIG    MAAX         101       2             101       2 1.25D+0",
    ]
    body = read_dmig(write(tmp_path / "t.pch", lines))
    np.testing.assert_array_equal(body.stiffness.toarray(), [[2125.0, -0.5], [-0.5, 2.5]])
    np.testing.assert_array_equal(body.mass.toarray(), [[1.0, 0.0], [0.0, 1.25]])


def test_different_dof_sets_and_custom_names(tmp_path: Path) -> None:
    """Stiffness on grids 101, 102; mass adds grid 300 (only in M) and a damping matrix."""
    k_keys, m_keys = KEYS[:12], [*KEYS[:6], (300, 2)]
    k = K[:12, :12]
    m = np.diag([1.0, 2.0, 3.0, 0.5, 0.5, 0.5, 7.25])
    d = 0.25 * np.eye(12)
    lines = [
        *punch_large("kgg", k, keys=k_keys),
        *punch_small("MGG", m, keys=m_keys),
        *punch_free("BGG", d, keys=k_keys),
        f"DMIG    {'PAX':<8}{0:>8}{9:>8}{1:>8}{0:>8}{'':8}{'':8}{1:>8}",
        f"DMIG*   {'PAX':<16}{1:>16}{0:>16}",
        entry(101, 1, "1.000000000E+05"),
    ]
    body = read_dmig(
        write(tmp_path / "x.pch", lines), stiffness="KGG", mass="mgg", damping="bgg", name="x"
    )
    assert body.n_dof == 13
    assert body.dofs.label(12) == "300:uy"
    np.testing.assert_array_equal(body.stiffness.toarray()[:12, :12], k)
    assert not body.stiffness[12].count_nonzero()  # only in the mass matrix
    expected_m = np.zeros((13, 13))
    expected_m[:6, :6] = m[:6, :6]
    expected_m[12, 12] = 7.25
    np.testing.assert_array_equal(body.mass.toarray(), expected_m)
    np.testing.assert_array_equal(body.damping_matrix.toarray()[:12, :12], d)
    assert not body.mass[6:12].count_nonzero()  # grid 102 is massless


@pytest.mark.parametrize("style", ["small", "large", "free"])
def test_grid_cards(tmp_path: Path, style: str) -> None:
    ids, xyz = read_grid_nodes(write_grids(tmp_path / "g.bdf", style))
    np.testing.assert_array_equal(ids, GRIDS)
    np.testing.assert_array_equal(xyz, XYZ)


def test_grid_include_and_nodes_csv(tmp_path: Path) -> None:
    write_grids(tmp_path / "grids.bdf")
    main = write(tmp_path / "main.bdf", ["SOL 103", "CEND", "BEGIN BULK", "INCLUDE 'grids.bdf'"])
    ids, _ = read_grid_nodes(main)
    np.testing.assert_array_equal(ids, GRIDS)
    nodes = tmp_path / "nodes.csv"
    nodes.write_text(
        "id,x,y,z\n"
        + "".join(f"{g},{x},{y},{z}\n" for g, (x, y, z) in zip(GRIDS, XYZ.tolist(), strict=True))
    )
    pch = write(tmp_path / "m.pch", [*punch_large("KAAX", K), *punch_large("MAAX", M)])
    np.testing.assert_array_equal(read_dmig(pch, nodes=nodes).coordinates, XYZ)


# ============================================================================ bad files
def test_missing_matrix_lists_names(tmp_path: Path) -> None:
    path = write(tmp_path / "k.pch", [*punch_large("KAAX", K), *punch_large("MXX", M)])
    with pytest.raises(UserError) as err:
        read_dmig(path)
    message = one_line(err)
    assert message == f"{path}: no DMIG matrix named MAAX (mass); the file holds: KAAX, MXX"
    for content in ("$ nothing\n", ""):
        empty = tmp_path / "e.pch"
        empty.write_text(content)
        with pytest.raises(UserError, match="no DMIG cards at all"):
            read_dmig(empty)


def entry(grid: int, component: int | str, value: str) -> str:
    """A large-field continuation line with one entry."""
    return f"*       {grid:>16}{component:>16}{value:>16}"


HEADER = f"DMIG    {'KAAX':<8}{0:>8}{6:>8}{1:>8}{0:>8}{'':8}{'':8}{18:>8}"
COLUMN = f"DMIG*   {'KAAX':<16}{101:>16}{1:>16}"


@pytest.mark.parametrize(
    ("lines", "line", "words"),
    [
        ([HEADER, COLUMN, entry(101, "", "")[:40]], 3, "without a value"),
        ([HEADER, COLUMN, entry(101, 1, "nan")], 3, "finite"),
        ([HEADER, COLUMN, entry(101, 1, "1.5X+03")], 3, "'1.5X+03'"),
        ([HEADER, COLUMN, entry("1x1", 1, "1.0E+03")], 3, "'1x1'"),  # type: ignore[arg-type]
        ([HEADER, COLUMN, entry(101, 0, "1.0E+03")], 3, "scalar"),
        ([HEADER, COLUMN, entry(101, 7, "1.0E+03")], 3, "component 7"),
        ([HEADER.replace(f"{6:>8}", f"{9:>8}", 1), COLUMN], 1, "rectangular (IFO=9)"),
        ([HEADER.replace(f"{1:>8}{0:>8}", f"{3:>8}{0:>8}", 1), COLUMN], 1, "complex"),
        ([COLUMN, entry(101, 1, "1.0E+03")], 1, "no header card"),
        ([HEADER, HEADER], 2, "second header card"),
        ([HEADER, COLUMN, "1.0E+03"], 3, "neither a card nor a continuation"),
        (
            [
                HEADER,
                COLUMN,
                entry(101, 1, "4.0E+00"),
                entry(102, 1, "1.0E+00"),
                f"DMIG*   {'KAAX':<16}{102:>16}{1:>16}",
                entry(101, 1, "2.0E+00"),
            ],
            6,
            "not symmetric",
        ),
        ([HEADER, COLUMN, entry(101, 1, "4.0"), COLUMN, entry(101, 1, "5.0")], 5, "line 3 has 4.0"),
        ([HEADER, f"DMIG*   {'KAAX':<16}{101:>16}{0:>16}"], 2, "column 101 with component 0"),
        ([HEADER, "DMIG,KAAX,101,1,,101,1,4.0,,101,2,1.0"], 2, "more than 8 data fields"),
    ],
)
def test_bad_stiffness(tmp_path: Path, lines: list[str], line: int, words: str) -> None:
    path = write(tmp_path / "bad.pch", [*lines, *punch_large("MAAX", M)])
    with pytest.raises(UserError) as err:
        read_dmig(path)
    message = one_line(err)
    assert message.startswith(f"{path}:{line}: "), message
    assert words in message, message


def test_square_form_must_be_symmetric(tmp_path: Path) -> None:
    lines = [*punch_large("KAAX", K, ifo=1), *punch_large("MAAX", M)]
    path = write(tmp_path / "sq.pch", lines)
    with pytest.raises(UserError, match="no mirror entry") as err:
        read_dmig(path)
    one_line(err)


@pytest.mark.parametrize(
    ("card", "words"),
    [
        (f"GRID    {205:>8}{1:>8}{'1.':>8}{'0.':>8}{'0.':>8}", "CP=1"),
        (f"GRID    {205:>8}{'':8}{'1.':>8}{'0.':>8}{'0.':>8}{2:>8}", "CD=2"),
        ("GRDSET          3", "GRDSET sets CP=3"),
        (f"GRID    {101:>8}{'':8}{'1.':>8}{'0.':>8}{'0.':>8}", "defined twice"),
    ],
)
def test_bad_grids(tmp_path: Path, card: str, words: str) -> None:
    grids = write_grids(tmp_path / "g.bdf")
    lines = grids.read_text().splitlines()
    lines.insert(-1, card)
    bad = write(tmp_path / "bad.bdf", lines)
    pch = write(tmp_path / "m.pch", [*punch_large("KAAX", K), *punch_large("MAAX", M)])
    with pytest.raises(UserError) as err:
        read_dmig(pch, nodes=bad)
    message = one_line(err)
    assert message.startswith(f"{bad}:{len(lines) - 1}: "), message
    assert words in message
    if words.startswith("CP"):
        assert "not supported" in message


def test_grid_missing_in_nodes(tmp_path: Path) -> None:
    nodes = write_grids(tmp_path / "g.bdf", grids=GRIDS[:2], xyz=XYZ[:2])
    lines = [*punch_large("KAAX", K), *punch_large("MAAX", M)]
    pch = write(tmp_path / "m.pch", lines)
    with pytest.raises(UserError) as err:
        read_dmig(pch, nodes=nodes)
    message = one_line(err)
    first = next(i for i, text in enumerate(lines, 1) if "205" in text)
    assert message.startswith(f"{pch}:{first}: grid 205 has no GRID card in {nodes}")


def test_not_a_punch_file(tmp_path: Path) -> None:
    binary = tmp_path / "b.pch"
    binary.write_bytes(b"\x00\x01\x02")
    with pytest.raises(UserError, match="binary") as err:
        read_dmig(binary)
    one_line(err)
    with pytest.raises(UserError, match="file not found"):
        read_dmig(tmp_path / "none.pch")
