"""Nastran bulk data: card formats, coordinate systems, displacement systems, sets, f06 echoes.

Synthetic cards check each rule against coordinates computed by hand here; the genuine files of
``tests/data`` (NX 9 and MSC 2013/2017 output: EXTBULK punches, ASMBULK files, f06 echoes) check
that the reader understands what the programs write.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from pymorembs.errors import UserError
from pymorembs.io.nastran_bulk import read_bulk, reals_of_fields, significant_digits

DATA = Path(__file__).parents[1] / "data"
MAEWING = DATA / "exportnastrankm_mAEWing1_FEMv5p2" / "sol103_maewing1_femv5p2.f06"
YETI = DATA / "pyyeti_nx_extseout"
N11 = DATA / "pynastran" / "superelement_se_test_n11"


def write(path: Path, text: str) -> Path:
    path.write_text(text)
    return path


def one_line(err: pytest.ExceptionInfo[UserError], prefix: str) -> str:
    message = str(err.value)
    assert "\n" not in message
    assert message.startswith(prefix), message
    return message


def coordinates(bulk, ids) -> np.ndarray:
    rows = bulk.grid_rows(np.array(ids))
    assert (rows >= 0).all()
    return bulk.basic_coordinates(rows)


# ============================================================================ formats
def test_small_large_free_fields_continuations_tabs_and_exponents(tmp_path: Path) -> None:
    text = "\n".join(
        [
            "$ a comment line",
            "GRID           1             1.5    -2.0   .25        ",
            "GRID*                  2                          1.5+3       -.5-2      $ inline",
            "*                 2.5D+1",
            "GRID,3,,1.,2.,3.",
            "GRID\t4\t\t7.\t8.\t9.",
            "grid           5              1.      2.",  # lower case, X3 blank = 0
            "GRID           6              1.      2.      3.",
            "+                                               ",  # an empty continuation
            "ENDDATA",
            "GRID           9              9.      9.      9.",  # after ENDDATA: not read
        ]
    )
    bulk = read_bulk(write(tmp_path / "a.bdf", text))
    np.testing.assert_array_equal(bulk.grid["ids"], [1, 2, 3, 4, 5, 6])
    expected = [
        [1.5, -2.0, 0.25],
        [1500.0, -0.005, 25.0],
        [1.0, 2.0, 3.0],
        [7.0, 8.0, 9.0],
        [1.0, 2.0, 0.0],
        [1.0, 2.0, 3.0],
    ]
    np.testing.assert_array_equal(bulk.basic_coordinates(), expected)
    assert bulk.counts["GRID"] == 6


def test_vectorised_grids_match_the_python_parse(tmp_path: Path) -> None:
    """50,000 GRIDs in each format: the numpy path gives the numbers Python's float() gives."""
    rng = np.random.default_rng(3)
    n = 50_000
    xyz = np.round(rng.normal(size=(n, 3)) * 100, 3)
    small = [
        f"GRID    {i + 1:<8}{'':8}{x:<8.3f}{y:<8.3f}{z:<8.3f}" for i, (x, y, z) in enumerate(xyz)
    ]
    large = []
    for i, (x, y, z) in enumerate(xyz):
        large += [f"GRID*   {i + 1:>16}{'':16}{x:>16.9E}{y:>16.9E}", f"*       {z:>16.9E}"]
    free = [f"GRID,{i + 1},,{x!r},{y!r},{z!r}" for i, (x, y, z) in enumerate(xyz.tolist())]
    for name, lines in (("small", small), ("large", large), ("free", free)):
        bulk = read_bulk(write(tmp_path / f"{name}.bdf", "\n".join(lines) + "\n"))
        np.testing.assert_array_equal(bulk.grid["ids"], np.arange(1, n + 1))
        np.testing.assert_array_equal(bulk.basic_coordinates(), xyz)


def test_number_conversion_and_digits() -> None:
    fields = [b"  1.5+3 ", b"-.5-2   ", b"2.5D+01 ", b"3.      ", b"        ", b" 7      "]
    block = np.array(fields, dtype="S8").view(np.uint8).reshape(-1, 8)
    values = reals_of_fields(block, np.arange(6), Path("x"), "X")
    np.testing.assert_array_equal(values, [1500.0, -0.005, 25.0, 3.0, 0.0, 7.0])
    digits = [b" 3.309464213D+06", b"-2.053437033D+06", b" 1.556000000D+02", b"   0.00125      "]
    block = np.array(digits, dtype="S16").view(np.uint8).reshape(-1, 16)
    np.testing.assert_array_equal(significant_digits(block), [10, 10, 10, 3])
    bad = np.array([b"1.5X+3  "], dtype="S8").view(np.uint8).reshape(1, 8)
    with pytest.raises(UserError, match=r"^x:9: X '1.5X\+3' is not a number$"):
        reals_of_fields(bad, np.array([9]), Path("x"), "X")


def test_include_sections_duplicates_and_executive(tmp_path: Path) -> None:
    (tmp_path / "sub").mkdir()
    write(tmp_path / "sub" / "grids.bdf", "GRID           2              2.      0.      0.\n")
    deck = "\n".join(
        [
            "SOL 103",
            "CEND",
            "TITLE = GRID 7 in the case control is not a card",
            "BEGIN BULK",
            "INCLUDE 'sub/",
            "  grids.bdf'",
            "GRID           1              1.      0.      0.",
            "BEGIN SUPER      102",
            "GRID           1              1.      0.      0.",  # identical: allowed
            "SPOINT  1001    THRU    1004",
            "ENDDATA",
        ]
    )
    bulk = read_bulk(write(tmp_path / "deck.dat", deck))
    np.testing.assert_array_equal(bulk.grid["ids"], [1, 2])
    np.testing.assert_array_equal(bulk.scalar_points(), [1001, 1002, 1003, 1004])
    assert bulk.sections == {102} and bulk.superelement() == 102
    assert "SOL" not in bulk.counts and "TITLE" not in bulk.counts


@pytest.mark.parametrize(
    ("text", "line", "words"),
    [
        (
            "GRID           1              1.\nBEGIN BULK\n+       1.\n",
            3,
            "continuation line without",
        ),
        ("     2.\n", 1, "continuation line without a card"),
        ("GRID           1              1.\n7       1.\n", 2, "neither a card nor a continu"),
        ("GRID           1       0      1.      x\n", 1, "GRID X2 'x' is not a number"),
        ("GRID           1       A      1.\n", 1, "GRID CP 'A' is not an integer"),
        ("GRID                         1.\n", 1, "GRID ID is missing"),
        ("GRID,1,,1.,2.,3.,,,,5,6\n", 1, "more than 8 data fields"),
        ("GRID,1,,1.,2.,3.\nGRID,1,,1.,2.,4.\n", 2, "GRID 1 is defined twice with different"),
        (
            "INCLUDE 'missing.bdf'\n",
            None,
            "file not found (expected Nastran bulk data, included from",
        ),
        ("INCLUDE 'loop.bdf'\n", 1, "INCLUDE loop"),
        ("INCLUDE nothing\n", 1, "INCLUDE without a quoted file name"),
    ],
)
def test_bad_cards(tmp_path: Path, text: str, line: int | None, words: str) -> None:
    path = write(tmp_path / "loop.bdf", text)
    with pytest.raises(UserError) as err:
        read_bulk(path)
    message = str(err.value)
    assert "\n" not in message
    if line is not None:
        assert message.startswith(f"{path}:{line}: "), message
    assert words in message, message


# ============================================================================ coordinate systems
def card(*fields: object) -> str:
    """A small-field card: every field right-aligned in 8 columns."""
    return "".join(f"{f!s:<8}" if k == 0 else f"{f!s:>8}" for k, f in enumerate(fields))


SYSTEMS = "\n".join(
    [
        card("CORD2R", 1, "", "1.", "2.", "3.", "1.", "2.", "4.") + "+",
        card("+", "2.", "2.", "3."),
        "CORD2R*                2               1             0.0             0.0*",
        "*                    0.0             1.0             0.0             0.0*",
        "*                    0.0             1.0             0.0",
        "CORD2C,3,,0.,0.,0.,0.,0.,1.",
        ",1.,0.,0.",
        card("CORD2S", 4, "", "0.", "0.", "0.", "0.", "0.", "1."),
        card("", "1.", "0.", "0."),
        card("CORD1R", 5, 101, 102, 103, 6, 101, 103, 102),
        card("GRID", 101, "", "10.", "0.", "0."),
        card("GRID", 102, "", "10.", "0.", "1."),
        card("GRID", 103, "", "11.", "1.", "0."),
        card("GRID", 1, 1, "1.", "1.", "1."),
        card("GRID", 2, 2, "1.", "2.", "3."),
        card("GRID", 3, 3, "2.", "90.", "5.", 3),
        card("GRID", 4, 4, "2.", "90.", "90."),
        card("GRID", 5, 5, "1.", "2.", "3.", 6),
        card("GRID", 6, 4, "2.", "0.", "0.", 4),
        card("GRID", 7, 0, "0.", "0.", "7.", 3),
    ]
)


def test_cp_systems_rid_chains_and_cord1(tmp_path: Path) -> None:
    bulk = read_bulk(write(tmp_path / "s.bdf", SYSTEMS))
    xyz = coordinates(bulk, [1, 2, 3, 4, 5])
    np.testing.assert_allclose(xyz[0], [2.0, 3.0, 4.0], atol=1e-15)  # shifted basic axes
    # system 2 in system 1: z along basic x, x along basic y, so y along basic z
    np.testing.assert_allclose(xyz[1], [1 + 3.0, 2 + 1.0, 3 + 2.0], atol=1e-14)
    np.testing.assert_allclose(xyz[2], [0.0, 2.0, 5.0], atol=1e-14)  # r 2, theta 90, z 5
    np.testing.assert_allclose(xyz[3], [0.0, 2.0, 0.0], atol=1e-14)  # r 2, theta 90, phi 90
    # CORD1R 5: origin grid 101, z towards 102 (basic z), x-z plane through 103 (x, y mix)
    ex = np.array([1.0, 1.0, 0.0]) / np.sqrt(2)
    ey = np.cross([0.0, 0.0, 1.0], ex)
    np.testing.assert_allclose(xyz[4], [10, 0, 0] + 1 * ex + 2 * ey + 3 * np.array([0, 0, 1.0]))


def test_displacement_systems(tmp_path: Path) -> None:
    bulk = read_bulk(write(tmp_path / "s.bdf", SYSTEMS))
    rows = bulk.grid_rows(np.array([3, 5, 6, 7]))
    axes = bulk.displacement_axes(rows, bulk.basic_coordinates(rows))
    # grid 3 at theta = 90 in the cylindrical system 3: e_r = y, e_theta = -x, e_z = z
    np.testing.assert_allclose(axes[0], [[0, -1, 0], [1, 0, 0], [0, 0, 1]], atol=1e-15)
    # grid 5 with CD = 6 (CORD1R: z towards 103, x-z plane through 102)
    z = np.array([1.0, 1.0, 0.0]) / np.sqrt(2)
    y = np.cross(z, [0.0, 0.0, 1.0])
    np.testing.assert_allclose(axes[1], np.column_stack([np.cross(y, z), y, z]), atol=1e-15)
    # grid 6 on the x axis of spherical system 4 (theta = 0 is its z axis: on the polar axis)
    np.testing.assert_allclose(axes[2], np.eye(3), atol=1e-15)
    # grid 7 on the z axis of cylindrical system 3: its rectangular axes
    np.testing.assert_allclose(axes[3], np.eye(3), atol=1e-15)


@pytest.mark.parametrize(
    ("cards", "words"),
    [
        (
            "CORD2R,7,8,0.,0.,0.,0.,0.,1.\n,1.,0.,0.\nCORD2R,8,7,0.,0.,0.,0.,0.,1.\n,1.,0.,0.\n",
            "coordinate systems refer to each other: 7 -> 8 -> 7",
        ),
        ("", "CP of GRID 1: coordinate system 7 is not defined in the file"),
        ("CORD2R,7,,0.,0.,0.,0.,0.,1.\n,0.,0.,2.\n", "points A, B and C are collinear"),
        ("CORD2R,7,,0.,0.,0.,0.,0.,0.\n,1.,0.,0.\n", "points A and B coincide"),
        (
            "CORD2R,7,,0.,0.,0.,0.,0.,1.\n,1.,0.,0.\nCORD2R,7,,1.,0.,0.,0.,0.,1.\n,1.,0.,0.\n",
            "coordinate system 7 is defined twice with different data",
        ),
    ],
)
def test_bad_systems(tmp_path: Path, cards: str, words: str) -> None:
    path = write(tmp_path / "s.bdf", cards + "GRID,1,7,1.,2.,3.\n")
    bulk = read_bulk(path) if "twice" not in words else None
    with pytest.raises(UserError) as err:
        (bulk or read_bulk(path)).basic_coordinates()
    message = one_line(err, f"{path}:")
    assert words in message, message


# ============================================================================ sets
def test_analysis_set_order_and_scalar_points(tmp_path: Path) -> None:
    text = """\
GRID,30,,0.,0.,0.
GRID,10,,1.,0.,0.
GRID,20,,2.,0.,0.
SPOINT,25,THRU,26
ASET1,123,10,THRU,30
BSET,20,456
QSET1,0,25,26
"""
    aset = read_bulk(write(tmp_path / "a.bdf", text)).analysis_set()
    keys = list(zip(aset.ids.tolist(), aset.directions.tolist(), strict=True))
    assert keys == [
        (10, 0), (10, 1), (10, 2),
        (20, 0), (20, 1), (20, 2), (20, 3), (20, 4), (20, 5),
        (25, 6), (26, 6),
        (30, 0), (30, 1), (30, 2),
    ]  # fmt: skip
    assert aset.modal and not aset.assumed
    np.testing.assert_array_equal(aset.scalars, [25, 26])
    assert aset.source == "ASET1, BSET, QSET1"


@pytest.mark.parametrize(
    ("text", "line", "words"),
    [
        ("GRID,1,,0.,0.,0.\nASET,1,0\n", 2, "1 is a GRID; component 0"),
        ("SPOINT,5\nASET,5,1\n", 2, "5 is a scalar point (SPOINT)"),
        ("ASET,1,17\n", 1, "component '17' is not 0 or digits 1-6"),
        ("ASET,1,123\nSEQGP,1,2\n", 2, "SEQGP resequences the points"),
        ("ASET,1,123\nPARAM,OLDSEQ,4\n", 2, "PARAM,OLDSEQ,4 resequences"),
        ("OMIT1,123,5\n", 1, "OMIT1 defines the a-set as the dofs not omitted"),
        ("ASET1,1,20,THRU,10\n", 1, "20 THRU 10 is empty"),
    ],
)
def test_bad_sets(tmp_path: Path, text: str, line: int, words: str) -> None:
    path = write(tmp_path / "a.bdf", text)
    with pytest.raises(UserError) as err:
        read_bulk(path).analysis_set()
    message = one_line(err, f"{path}:{line}: ")
    assert words in message, message


def test_thru_ranges_are_bounded(tmp_path: Path) -> None:
    path = write(tmp_path / "a.bdf", "ASET1,123456,1,THRU,9999999\n")
    with pytest.raises(UserError, match=r"1 THRU 9999999 puts 59999994 dofs in the a-set"):
        read_bulk(path).analysis_set(limit=3)


# ============================================================================ f06 echoes
ECHO = """\
1    MSC.NASTRAN JOB                                                   PAGE     4
0                                                 S O R T E D   B U L K   D A T A   E C H O
                 ENTRY
                 COUNT        .   1  ..   2  ..   3  ..   4  ..   5  ..   6  ..   7  ..   8
                    1-        CORD2C  5               0.      0.      0.      0.      0.      1.
                    2-        +       1.      0.      0.
                    3-        GRID    1       5       2.      90.     1.
1    MSC.NASTRAN JOB                                                   PAGE     5
0                                                 S O R T E D   B U L K   D A T A   E C H O
                 ENTRY
                 COUNT        .   1  ..   2  ..   3  ..   4  ..   5  ..   6  ..   7  ..   8
                    4-        GRID    2               3.      4.      5.
                              ENDDATA
0                       TOTAL COUNT=         4
    GRID    9               0.      0.      0.
"""
UNSORTED = """\
0                                              I N P U T   B U L K   D A T A   E C H O
                 ENTRY
                 COUNT        .   1  ..   2  ..   3  ..   4  ..   5  ..   6  ..   7  ..   8
                              $ a comment
                              GRID    7               1.      2.      3.
                              GRID*   8                               4.              5.
                              *       6.
                              ENDDATA
"""


@pytest.mark.parametrize("text", [ECHO, UNSORTED])
def test_f06_echo(tmp_path: Path, text: str) -> None:
    path = write(tmp_path / "run.f06", text)
    bulk = read_bulk(path)
    assert bulk.kind == "f06 bulk data echo"
    if text is ECHO:
        np.testing.assert_array_equal(bulk.grid["ids"], [1, 2])
        np.testing.assert_allclose(bulk.basic_coordinates(), [[0, 2, 1], [3, 4, 5]], atol=1e-15)
        assert bulk.grid["line"].tolist() == [7, 12]  # lines of the f06
    else:
        np.testing.assert_array_equal(bulk.grid["ids"], [7, 8])
        np.testing.assert_array_equal(bulk.basic_coordinates(), [[1, 2, 3], [4, 5, 6]])


# ============================================================================ genuine files
def cord2r(a, b, c) -> tuple[np.ndarray, np.ndarray]:
    """Origin and axes (columns) of a CORD2R from its points, computed here independently."""
    a, b, c = (np.asarray(p, dtype=float) for p in (a, b, c))
    z = (b - a) / np.linalg.norm(b - a)
    x = (c - a) - np.dot(c - a, z) * z
    x /= np.linalg.norm(x)
    return a, np.column_stack([x, np.cross(z, x), z])


def test_maewing_f06_echo() -> None:
    """MSC Nastran 2013 f06: 159 GRID cards in the sorted echo, 40 in CORD2R systems."""
    bulk = read_bulk(MAEWING)
    assert bulk.counts["GRID"] == 159 and bulk.counts["CORD2R"] == 4
    assert bulk.grid["ids"].size == 159
    assert int((bulk.grid["cp"] != 0).sum()) == 40
    assert not bulk.grid["cd"].any()
    # echo lines 509-510: CORD2R 101 13.64 -1.16 0. 13.64 -1.16 1. / 17.34 -2.75 0.
    origin, axes = cord2r([13.64, -1.16, 0.0], [13.64, -1.16, 1.0], [17.34, -2.75, 0.0])
    np.testing.assert_allclose(
        coordinates(bulk, [5012])[0], origin + axes @ [1.63, -12.45, 0.0], rtol=1e-14
    )
    np.testing.assert_array_equal(coordinates(bulk, [1050])[0], [14.6731, -36.3055, 0.0])


def test_pyyeti_extbulk_inboard() -> None:
    """NX 9 EXTBULK: EXTRN, ASET, SPOINT; grid 11 with CD = 10, a CORD2R that permutes axes."""
    bulk = read_bulk(YETI / "inboard.pch")
    assert bulk.superelement() == 102
    aset = bulk.analysis_set()
    assert aset.modal and aset.superelement == 102
    np.testing.assert_array_equal(aset.boundary_grids, [3, 11, 19, 27])
    np.testing.assert_array_equal(aset.scalars, np.arange(2995001, 2995009))
    assert aset.ids.tolist() == [g for g in (3, 11, 19, 27) for _ in range(6)] + list(
        range(2995001, 2995009)
    )
    rows = bulk.grid_rows(np.array([11]))
    axes = bulk.displacement_axes(rows, bulk.basic_coordinates(rows))[0]
    np.testing.assert_array_equal(axes, [[0, 0, 1], [1, 0, 0], [0, 1, 0]])  # x_l = y_b ...
    # the f06 of the same run echoes the input deck: BSET1 + QSET1 give the same rows
    echo = read_bulk(YETI / "inboard.out").analysis_set()
    np.testing.assert_array_equal(echo.ids, aset.ids)
    np.testing.assert_array_equal(echo.directions, aset.directions)


def test_asmbulk_seconct() -> None:
    inboard = read_bulk(YETI / "inboard.asm").analysis_set()
    assert inboard.assumed and inboard.ids.size == 32
    notall6 = read_bulk(YETI / "reduced_bset_notall6" / "reduced_bset_notall6.asm").analysis_set()
    assert notall6.ids.size == 4 * 6 + 10  # SECONCT has no components: six assumed
    extbulk = read_bulk(YETI / "reduced_bset_notall6" / "reduced_bset_notall6.pch").analysis_set()
    assert extbulk.ids.size == 29
    assert extbulk.ids[18] == 475 and extbulk.directions[18] == 1  # grid 475: component 2 only


def test_msc_extbulk_cord2r_chain() -> None:
    """MSC 2017 EXTBULK: boundary grids in CORD2R 20110001, CD in systems defined in it."""
    bulk = read_bulk(N11 / "se_test_n11.pch")
    # CORD2R* 20110001 (large field, short exponents): A, B, C in basic
    a = [0.193357753101591, 1.00748371824434, 2.49724450009028]
    b = [11.4986577555288, 12.3121940571224, 101.210940186196]
    c = [99.5439273715777, 1.00748371824433, -8.8809942249643]
    origin, axes = cord2r(a, b, c)
    np.testing.assert_allclose(
        coordinates(bulk, [20110010])[0], origin + axes @ [0.18, -5.55467e-10, 0.0], rtol=1e-13
    )
    # GRID 20110038: X2 written as '7.271236428543-4' (short exponent in a 16-column field)
    np.testing.assert_allclose(
        coordinates(bulk, [20110038])[0],
        origin + axes @ [-0.00245876878293, 7.271236428543e-4, -0.1036],
        rtol=1e-13,
    )
    # CD system 20110003 is defined in 20110001 by points along its own axes: same axes
    rows = bulk.grid_rows(np.array([20110010]))
    np.testing.assert_allclose(
        bulk.displacement_axes(rows, coordinates(bulk, [20110010]))[0], axes, atol=1e-15
    )
    aset = bulk.analysis_set()
    assert aset.ids.size == 11 * 6 + 39 and aset.source == "ASET, EXTRN"
