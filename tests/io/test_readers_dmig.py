"""Nastran DMIG punch files: field formats, names, scalar points, coordinates, CD, genuine files.

The synthetic punch files are written here from a known model whose entries are exact in 8
characters (multiples of 1/4 below 10^5), so every field width must read back bit for bit. The
genuine punches of ``tests/data`` (MSC Nastran 2013, ``PARAM,EXTOUT,DMIGPCH``) are compared with
an independent parse written here and with the eigenvalues Nastran printed in its f06.
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from nastran_reference import dense_frequencies, dense_matrix, dmig_entries, f06_cycles
from pymorembs.errors import UserError
from pymorembs.io.nastran_bulk import read_bulk
from pymorembs.io.nastran_dmig import read_dmig

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
    bulk = read_bulk(write_grids(tmp_path / "g.bdf", style))
    np.testing.assert_array_equal(bulk.grid["ids"], GRIDS)
    np.testing.assert_array_equal(bulk.basic_coordinates(), XYZ)
    pch = write(tmp_path / "m.pch", [*punch_large("KAAX", K), *punch_large("MAAX", M)])
    body = read_dmig(pch, nodes=tmp_path / "g.bdf")
    assert body.has_coordinates
    np.testing.assert_array_equal(body.coordinates, XYZ)


def test_grid_include_and_nodes_csv(tmp_path: Path) -> None:
    write_grids(tmp_path / "grids.bdf")
    main = write(tmp_path / "main.bdf", ["SOL 103", "CEND", "BEGIN BULK", "INCLUDE 'grids.bdf'"])
    np.testing.assert_array_equal(read_bulk(main).grid["ids"], GRIDS)
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
    assert one_line(err) == (
        f"{path}: holds KAAX (stiffness) but no mass matrix (no MAAX); the file also holds MXX "
        "(mass); export the mass matrix too or name it with --mass-name"
    )
    with pytest.raises(UserError) as err:
        read_dmig(path, mass="maax")
    assert one_line(err) == f"{path}: no DMIG matrix named MAAX (mass); the file holds: KAAX, MXX"
    body = read_dmig(path, stiffness="kaax", mass="mxx")
    np.testing.assert_array_equal(body.mass.toarray(), M)
    for content in ("$ nothing\n", ""):
        empty = tmp_path / "e.pch"
        empty.write_text(content)
        with pytest.raises(UserError, match="holds no DMIG matrices"):
            read_dmig(empty)


def test_names_found_and_ambiguous(tmp_path: Path) -> None:
    lines = [*punch_large("KGG", K), *punch_large("MGG", M), *punch_large("K4GG", 0.5 * K)]
    body = read_dmig(write(tmp_path / "g.pch", lines))
    np.testing.assert_array_equal(body.stiffness.toarray(), K)
    assert any("KGG (stiffness) and MGG (mass) found" in note for note in body.notes)
    assert any(note.startswith("K4GG (structural damping) is not read") for note in body.notes)
    assert body.damping_matrix is None
    both = write(tmp_path / "b.pch", [*lines, *punch_large("KAAX", 2 * K), *punch_large("MAAX", M)])
    with pytest.raises(UserError) as err:
        read_dmig(both)
    assert one_line(err) == (
        f"{both}: holds several stiffness/mass pairs: KGG/MGG, KAAX/MAAX; choose one with "
        "--stiffness-name and --mass-name"
    )
    body = read_dmig(both, stiffness="kaax")  # the mass of the same suffix
    np.testing.assert_array_equal(body.stiffness.toarray(), 2 * K)


def test_scalar_points_become_scalar_coordinates(tmp_path: Path) -> None:
    """A Craig-Bampton punch: grid 101 (component 1) and modal coordinates 9001, 9002."""
    header = f"DMIG    {'KAAX':<8}{0:>8}{6:>8}{2:>8}{0:>8}{'':8}{'':8}{3:>8}"
    lines = [
        header,
        f"DMIG*   {'KAAX':<16}{101:>16}{1:>16}",
        entry(101, 1, "4.0"),
        f"DMIG*   {'KAAX':<16}{9001:>16}{0:>16}",
        entry(9001, 0, "9.0"),
        f"DMIG*   {'KAAX':<16}{9002:>16}{'':>16}",  # blank component: a scalar point too
        entry(9002, "", "16.0"),
        *punch_large("MAAX", np.eye(3), keys=[(101, 1), (9001, 0), (9002, 0)]),
    ]
    body = read_dmig(write(tmp_path / "cb.pch", lines))
    assert body.dofs.describe() == "1 node x ux + 2 scalar coordinates (q)"
    assert body.node_ids.tolist() == [101]
    assert [body.dofs.label(i) for i in range(3)] == ["101:ux", "9001:q", "9002:q"]
    np.testing.assert_array_equal(body.stiffness.toarray(), np.diag([4.0, 9.0, 16.0]))
    assert any("modal block of the mass matrix is the identity" in n for n in body.notes)
    clash = write(
        tmp_path / "clash.pch", [*lines, *punch_large("BAAX", np.eye(1), keys=[(9001, 2)])]
    )
    with pytest.raises(UserError, match="point 9001 appears as a scalar point") as err:
        read_dmig(clash)
    one_line(err)


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
        ([HEADER, f"DMIG*   {'KAAX':<16}{101:>16}{8:>16}"], 2, "column component 8 of grid"),
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
    ("card", "line", "words"),
    [
        (f"GRID    {205:>8}{1:>8}{'1.':>8}{'0.':>8}{'0.':>8}", 5, "coordinate system 1 is not"),
        (f"GRID    {205:>8}{'':8}{'1.':>8}{'0.':>8}{'0.':>8}{2:>8}", 5, "CD of GRID 205"),
        ("GRDSET          3", 3, "CP of GRID 101: coordinate system 3 is not defined"),
        (f"GRID    {101:>8}{'':8}{'1.':>8}{'0.':>8}{'0.':>8}", 6, "defined twice with different"),
    ],
)
def test_bad_grids(tmp_path: Path, card: str, line: int, words: str) -> None:
    grids = write_grids(tmp_path / "g.bdf")
    lines = grids.read_text().splitlines()
    if card.startswith(f"GRID    {205:>8}"):
        lines[-2] = card  # grid 205 itself
    else:
        lines.insert(-1, card)
    bad = write(tmp_path / "bad.bdf", lines)
    pch = write(tmp_path / "m.pch", [*punch_large("KAAX", K), *punch_large("MAAX", M)])
    with pytest.raises(UserError) as err:
        read_dmig(pch, nodes=bad)
    message = one_line(err)
    assert message.startswith(f"{bad}:{line}: "), message
    assert words in message, message


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


# ============================================================================ CD systems
def rotation_z(degrees: float) -> np.ndarray:
    t = np.radians(degrees)
    return np.array([[np.cos(t), -np.sin(t), 0.0], [np.sin(t), np.cos(t), 0.0], [0.0, 0.0, 1.0]])


def cd_grids(path: Path, cd_card: str) -> Path:
    """Grids 101, 102, 205 of XYZ; grid 102 has CD = 5."""
    lines = [cd_card]
    for g, (x, y, z) in zip(GRIDS.tolist(), XYZ.tolist(), strict=True):
        lines.append(f"GRID,{g},,{x!r},{y!r},{z!r},{5 if g == 102 else ''}")
    return write(path, lines)


def test_cd_rotation_to_basic(tmp_path: Path) -> None:
    """Matrices punched in the local axes of grid 102 read back in basic: K_b = T K_l T^T."""
    r = rotation_z(30.0)  # CORD2R 5: z as basic z, x at 30 degrees in the x-y plane
    nodes = cd_grids(
        tmp_path / "g.bdf",
        f"CORD2R,5,,0.,0.,0.,0.,0.,1.\n,{float(r[0, 0])!r},{float(r[1, 0])!r},0.",
    )
    t = np.eye(18)
    t[6:9, 6:9] = t[9:12, 9:12] = r  # basic components = R @ local components
    k_local, m_local = t.T @ K @ t, t.T @ M @ t
    lines = [*punch_free("KAAX", k_local), *punch_free("MAAX", m_local)]
    body = read_dmig(write(tmp_path / "l.pch", lines), nodes=nodes)
    np.testing.assert_allclose(body.stiffness.toarray(), K, rtol=0, atol=1e-12 * abs(K).max())
    np.testing.assert_allclose(body.mass.toarray(), M, rtol=0, atol=1e-13 * abs(M).max())
    assert any("1 grid has its components in displacement coordinate system CD = 5" in n
               for n in body.notes)  # fmt: skip


def test_cd_with_some_components(tmp_path: Path) -> None:
    """Grid 102 with only local T1: fine for a permutation (local x = basic y), else refused."""
    keys = [*KEYS[:6], (102, 1)]
    k, m = K[:7, :7], M[:7, :7]
    pch = write(tmp_path / "p.pch", [*punch_large("KAAX", k, keys), *punch_large("MAAX", m, keys)])
    permuted = cd_grids(tmp_path / "perm.bdf", "CORD2R,5,,0.,0.,0.,1.,0.,0.\n,0.,1.,0.")
    body = read_dmig(pch, nodes=permuted)
    assert body.dofs.label(6) == "102:uy"  # local x of CORD2R 5 is basic y
    np.testing.assert_array_equal(body.stiffness.toarray(), k)
    rotated = cd_grids(tmp_path / "rot.bdf", "CORD2R,5,,0.,0.,0.,0.,0.,1.\n,1.,1.,0.")
    with pytest.raises(UserError) as err:
        read_dmig(pch, nodes=rotated)
    assert one_line(err) == (
        f"{pch}: grid 102 has CD=5 and only components 1 of its translations in the matrices; "
        "its local axes mix the basic directions, so they cannot be expressed along ux..rz "
        "(export all three components)"
    )


# ============================================================================ genuine files
DATA = Path(__file__).parents[1] / "data"
MAEWING = DATA / "exportnastrankm_mAEWing1_FEMv5p2"
PYNASTRAN = DATA / "pynastran"


def test_maewing_punch_reads_exactly() -> None:
    """MSC Nastran 2013 EXTOUT punch: KAAX/MAAX (+ VAX, MUG1T, DTI), 10 digits, D exponents."""
    pch = MAEWING / "sol103_maewing1_femv5p2.pch1"
    body = read_dmig(pch)
    k_entries, m_entries = dmig_entries(pch, "KAAX"), dmig_entries(pch, "MAAX")
    assert (len(k_entries), len(m_entries)) == (1946, 712)  # stored: one triangle
    keys = [(g, c) for g in sorted({e[0] for e in k_entries}) for c in range(1, 7)]
    assert body.n_dof == len(keys) == 426 and body.n_nodes == 71
    assert [body.dofs.index(g, c - 1) for g, c in keys] == list(range(426))
    np.testing.assert_array_equal(body.stiffness.toarray(), dense_matrix(k_entries, keys))
    np.testing.assert_array_equal(body.mass.toarray(), dense_matrix(m_entries, keys))
    assert int((abs(body.mass).sum(axis=1) == 0).sum()) == 34  # massless a-set dofs
    assert "KAAX, MAAX: values with 10 significant digits" in body.notes
    assert not body.has_coordinates


def test_maewing_coordinates_from_the_f06_and_frequencies() -> None:
    """The f06 echo gives all 71 grids (8 in CORD2R systems); the rigid-body check proves it.

    Frequencies: an independent dense solution (massless directions condensed, the geometric
    rigid-body fields projected out) against the f06 of the same deck. The punch holds 10
    digits: its rounding gives the rigid-body fields Rayleigh quotients up to 40 (rad/s)^2
    (up to 1.0 Hz), a perturbation of omega^2 that bounds the shift of mode 7 (omega^2 = 2407)
    by 0.8 %; the observed difference is 0.30 %, the other modes agree to 3.5e-4.
    """
    body = read_dmig(
        MAEWING / "sol103_maewing1_femv5p2.pch1", nodes=MAEWING / "sol103_maewing1_femv5p2.f06"
    )
    assert body.has_coordinates and body.n_nodes == 71
    residual = np.nanmax(body.rigid_body_residuals())
    assert residual < 1e-10
    bulk = read_bulk(MAEWING / "sol103_maewing1_femv5p2.f06")
    rows = bulk.grid_rows(body.node_ids)
    raw = bulk.grid["xyz"][rows]  # the CP coordinates taken as basic: wrong for 8 grids
    assert int((bulk.grid["cp"][rows] != 0).sum()) == 8
    wrong = replace(body, coordinates=raw).rigid_body_residuals()
    assert np.nanmax(wrong) > 1e4 * residual
    k, m = body.stiffness.toarray(), body.mass.toarray()
    rigid = body.rigid_body_modes(body.coordinates.mean(axis=0))
    quotients = np.einsum("ij,ij->j", rigid, k @ rigid) / np.einsum("ij,ij->j", rigid, m @ rigid)
    assert 30 < np.abs(quotients).max() < 40  # the rounding of the punch, in (rad/s)^2
    ours = dense_frequencies(k, m, rigid=body.rigid_body_modes())
    published = f06_cycles(MAEWING / "sol103_maewing1_femv5p2.f06")
    assert published[:6] == [0.0] * 6
    np.testing.assert_allclose(ours[:6], 0.0, atol=5e-3)  # rounding of the dense solution
    assert abs(ours[6] / published[6] - 1) < 3.1e-3
    np.testing.assert_allclose(ours[7:14], published[7:14], rtol=3.5e-4)


def test_pynastran_dmig_punch_with_damping() -> None:
    """EXTOUT punch of pyNastran issue #326: KAAX/MAAX/BAAX on 15 grids, component 1."""
    pch = PYNASTRAN / "dmig_pch" / "dmig.pch"
    body = read_dmig(pch)
    keys = sorted({(e[0], e[1]) for e in dmig_entries(pch, "KAAX")})
    assert body.dofs.describe() == "15 nodes x ux" and len(keys) == 15
    k = dense_matrix(dmig_entries(pch, "KAAX"), keys)
    m = dense_matrix(dmig_entries(pch, "MAAX"), keys)
    d = dense_matrix(dmig_entries(pch, "BAAX"), keys)
    np.testing.assert_array_equal(body.stiffness.toarray(), k)
    np.testing.assert_array_equal(body.mass.toarray(), m)
    np.testing.assert_array_equal(body.damping_matrix.toarray(), d)
    assert len(dmig_entries(pch, "KAAX")) == 29 and len(dmig_entries(pch, "BAAX")) == 6
    assert np.count_nonzero(d.any(axis=0)) == 4  # damping on 4 dofs
    assert "BAAX read as the viscous damping matrix" in body.notes
    w2 = np.linalg.eigvalsh(np.linalg.solve(np.sqrt(m), np.linalg.solve(np.sqrt(m), k).T))
    assert w2[0] < 1e-9 * w2[-1]  # a free spring-mass chain: one rigid-body mode


@pytest.mark.parametrize(
    ("path", "words"),
    [
        (
            PYNASTRAN / "fsi" / "fsi.pch",
            "holds no DMIG matrices: a results punch ($EIGENVECTOR, 10 modes of a complex "
            "eigenvalue analysis); write the matrices with PARAM,EXTOUT,DMIGPCH",
        ),
        (
            DATA / "pyyeti_nx_extseout" / "inboard.pch",
            "holds no DMIG matrices: Nastran bulk data (CORD2R, EXTRN, 4 GRID, 3 ASET, SPOINT, "
            "42 DTI): the EXTBULK of external superelement 102; its matrices are in the OP4 "
            "file of MATOP4",
        ),
        (
            MAEWING / "sol103_maewing1_femv5p2.f06",
            "holds no DMIG matrices: a Nastran f06 bulk data echo (16 CBAR, 94 CBEAM",
        ),
    ],
)
def test_files_without_matrices_say_what_they_hold(path: Path, words: str) -> None:
    with pytest.raises(UserError) as err:
        read_dmig(path)
    message = one_line(err)
    assert message.startswith(f"{path}: {words}"), message
