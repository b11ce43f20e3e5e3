"""The surface the readers give the body from shells, beams and every solid kind (issue 17).

Expected counts, areas, lengths and volumes come from the cards and element lines of the files,
parsed here with plain string slicing, and from the geometry of the models (analytic).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from mesh_checks import enclosed_volume, is_closed_and_consistent
from pymorembs.errors import UserError
from pymorembs.io.abaqus import read_abaqus
from pymorembs.io.abaqus_inp import read_inp, surface_elements
from pymorembs.io.ansys import read_ansys_full
from pymorembs.io.ansys_cdb import cdb_surface_elements, read_cdb
from pymorembs.io.nastran_bulk import bulk_surface_elements, read_bulk
from pymorembs.io.nastran_op2 import read_op2
from pymorembs.io.nastran_op4 import read_op4
from pymorembs.surface import outer_surface

DATA = Path(__file__).parents[1] / "data"
KELM = DATA / "pynastran" / "op2_kgg_kelm"
YETI = DATA / "pyyeti_nx_extseout"


def small_field_cards(path: Path, name: str) -> list[list[str]]:
    """Data fields 2-9 of the one-line small-field cards ``name`` of a bulk data file."""
    cards = []
    for line in path.read_text().splitlines():
        if line[:8].strip() == name:
            cards.append([line[8 * k : 8 * k + 8].strip() for k in range(1, 9)])
    return cards


def grids_of(*paths: Path) -> dict[int, np.ndarray]:
    """GRID id -> (x, y, z) of small-field GRID cards with CP blank or 0."""
    xyz = {}
    for path in paths:
        for f in small_field_cards(path, "GRID"):
            assert f[1] in ("", "0")
            xyz[int(f[0])] = np.array([float(v or 0) for v in f[2:5]])
    return xyz


def triangle_areas(p: np.ndarray) -> np.ndarray:
    """Areas of triangles, corner coordinates shape (n, 3, 3)."""
    return 0.5 * np.linalg.norm(np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]), axis=1)


def polygon_area(p: np.ndarray) -> float:
    """Area of a flat polygon (corners in turn), shape (k, 3)."""
    return 0.5 * float(np.linalg.norm(np.cross(p, np.roll(p, -1, axis=0)).sum(axis=0)))


def corners(xyz: dict[int, np.ndarray], ids: np.ndarray) -> np.ndarray:
    return np.array([[xyz[int(i)] for i in row] for row in np.atleast_2d(ids)])


def surface_note(body) -> str:
    notes = [n for n in body.notes if n.startswith("surface:")]
    assert len(notes) == 1
    return notes[0]


# ============================================================================ Nastran
def test_op2_deck_with_solids_shells_bars_and_rods():
    """pyNastran's static_solid_shell_bar_kelm deck (geom.inc): a CHEXA, 2 CPENTA and 2 CTETRA
    above z = 0, 4 CQUAD4 and 8 CTRIA3 below it, a CBAR, a CBEAM and 2 CROD from z = -2 to -3,
    read with the OP2 of its KGG."""
    geom = KELM / "geom.inc"
    xyz = grids_of(KELM / "static_solid_shell_bar_kelm.bdf")
    quads = np.array([f[2:6] for f in small_field_cards(geom, "CQUAD4")], dtype=np.int64)
    trias = np.array([f[2:5] for f in small_field_cards(geom, "CTRIA3")], dtype=np.int64)
    bars = [f[2:4] for name in ("CBAR", "CBEAM", "CROD") for f in small_field_cards(geom, name)]
    bars = np.array(bars, dtype=np.int64)
    assert (len(quads), len(trias), len(bars)) == (4, 8, 4)
    body = read_op2(KELM / "static_solid_shell_bar_kelm.op2", mass="KGG",
                    nodes=KELM / "static_solid_shell_bar_kelm.bdf")  # fmt: skip
    surface = body.surface
    assert surface is not None
    assert np.isin(surface.node_ids, body.node_ids).all()
    tri = surface.triangles
    below = np.array([[xyz[int(i)][2] < 0 for i in row] for row in tri]).any(axis=1)
    shells = tri[below]  # every shell has a grid below z = 0, no solid has one
    assert shells.shape[0] == len(trias) + 2 * len(quads)
    expected_area = sum(polygon_area(corners(xyz, q)[0]) for q in quads)
    expected_area += sum(polygon_area(corners(xyz, t)[0]) for t in trias)
    assert triangle_areas(corners(xyz, shells)).sum() == pytest.approx(expected_area, rel=1e-14)
    solids = tri[~below]
    # a unit cube (CHEXA), a unit cube of two wedges, a pyramid of height 1 of two tets
    assert enclosed_volume(corners(xyz, solids)) == pytest.approx(1 + 1 + 1 / 3, rel=1e-14)
    # The deck is not conforming at z = 1: the CHEXA's top quad meets the two CPENTA's bottom
    # triangles, so both stay outer faces there (up and down, a unit square each); the others
    # form the closed skin of the union.
    at_one = np.array([[xyz[int(i)][2] == 1 for i in row] for row in solids]).all(axis=1)
    p = corners(xyz, solids[at_one])
    up = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])[:, 2] > 0
    assert triangle_areas(p[up]).sum() == pytest.approx(1.0)
    assert triangle_areas(p[~up]).sum() == pytest.approx(1.0)
    assert is_closed_and_consistent(solids[~at_one])
    lines = np.sort(surface.lines, axis=1)
    assert sorted(map(tuple, lines.tolist())) == sorted(map(tuple, np.sort(bars, 1).tolist()))
    length = sum(np.linalg.norm(xyz[int(a)] - xyz[int(b)]) for a, b in bars)
    assert np.linalg.norm(np.diff(corners(xyz, surface.lines), axis=1), axis=2).sum() == (
        pytest.approx(length, rel=1e-14)
    )
    note = surface_note(body)
    assert "2 tet4, 1 hex8, 2 wedge6 elements" in note and "8 tri3, 4 quad4 shell" in note
    assert f"({tri.shape[0]} triangles, 4 lines)" in note
    # the mass check stays solids only: the shells and beams keep the mesh away
    assert any("no element mesh for geometric stiffening" in n for n in body.notes)


def test_fsi_deck_fluid_hexes_and_plate_quads():
    """fsi.bdf: 4 CQUAD4 on grids 1-9 (a plate) and 8 CHEXA fluid cells on grids 209-235."""
    path = DATA / "pynastran" / "fsi" / "fsi.bdf"
    xyz = grids_of(path)
    quads = np.array([f[2:6] for f in small_field_cards(path, "CQUAD4")], dtype=np.int64)
    bulk = read_bulk(path)
    elements = bulk_surface_elements(bulk)
    assert [(k, c.shape) for k, c in elements.blocks] == [("hex8", (8, 8)), ("quad4", (4, 4))]
    ids = np.array(sorted(xyz))
    surface = outer_surface(elements.blocks, ids, np.array([xyz[i] for i in ids]))
    tri = surface.triangles
    plate = np.isin(tri, quads).all(axis=1)
    assert plate.sum() == 2 * len(quads)
    area = sum(polygon_area(corners(xyz, q)[0]) for q in quads)
    assert triangle_areas(corners(xyz, tri[plate])).sum() == pytest.approx(area, rel=1e-14)
    fluid = tri[~plate]
    assert fluid.shape[0] == 2 * 24  # the 2 x 2 x 2 block's outer quads
    assert is_closed_and_consistent(fluid)
    box = np.array([xyz[int(i)] for i in np.unique(fluid)])
    assert enclosed_volume(corners(xyz, fluid)) == pytest.approx(np.prod(np.ptp(box, 0)), 1e-12)


def test_superelement_boundary_body_has_no_surface_and_says_why():
    """pyYeti's inboard.blk has 66 CBAR on 26 grids; the Craig-Bampton matrices hold 4 of them."""
    for name, bars in (("inboard", 66), ("outboard", 51)):
        blk = YETI / f"{name}.blk"
        cbar = [card for card in blk.read_text().splitlines() if card.startswith("CBAR")]
        assert len(cbar) == bars
        elements = bulk_surface_elements(read_bulk(blk))
        assert [(k, c.shape) for k, c in elements.blocks] == [("line2", (bars, 2))]
        used = np.unique(elements.blocks[0][1])
        body = read_op4(YETI / f"{name}.op4", dofs=YETI / f"{name}.pch", nodes=blk)
        assert body.surface is None
        outside = np.setdiff1d(used, body.node_ids)
        assert surface_note(body).startswith(
            f"surface: none, {outside.size} of the {used.size} nodes of the elements are not "
            f"nodes of the body (first {outside[0]}"
        )


def test_nastran_cards_of_every_drawn_kind_and_the_undrawn_ones(tmp_path):
    """Quadratic cards with all edge grids, one with blanks (drawn through its corners), CONROD's
    grid fields, CPENTA/CPYRAM, and springs, masses and rigid elements counted as not drawn."""
    xyz = {i + 1: np.array(p, float) for i, p in enumerate(
        [(0, 0, 0), (2, 0, 0), (2, 2, 0), (0, 2, 0), (1, 0, 0), (2, 1, 0), (1, 2, 0), (0, 1, 0)]
    )}  # fmt: skip
    lines = [f"GRID    {i:8d}        {p[0]:8.1f}{p[1]:8.1f}{p[2]:8.1f}" for i, p in xyz.items()]
    lines += [
        "CQUAD8  1       1       1       2       3       4       5       6",
        "        7       8",
        "CTRIA6  2       1       1       2       3       5       6",  # G6 blank: corners only
        "CONROD  3       1       3       5",
        "CBUSH   4       2       1       2",
        "CONM2   5       3       0       1.",
        "RBE2    6       1       123456  2       3",
        "ENDDATA",
    ]
    path = tmp_path / "cards.bdf"
    path.write_text("\n".join(lines) + "\n")
    elements = bulk_surface_elements(read_bulk(path))
    kinds = {k: c.tolist() for k, c in elements.blocks}
    assert kinds == {"tri3": [[1, 2, 3]], "quad8": [[1, 2, 3, 4, 5, 6, 7, 8]], "line2": [[1, 3]]}
    assert elements.skipped == {"CBUSH": 1, "CONM2": 1, "RBE2": 1}
    ids = np.array(sorted(xyz))
    surface = outer_surface(elements.blocks, ids, np.array([xyz[i] for i in ids]))
    assert surface.triangles.shape[0] == 6 + 1
    assert triangle_areas(corners(xyz, surface.triangles)).sum() == pytest.approx(4.0 + 2.0)


def test_cpenta15_and_cpyram13_cards_give_closed_skins(tmp_path):
    """A unit wedge (CPENTA, 15 grids) and a pyramid (CPYRAM, 13 grids) with their edge grids
    at the middle of the edges: closed, outward skins of volume 1/2 and 1/3."""
    wedge = [(0, 0, 0), (1, 0, 0), (0, 1, 0), (0, 0, 1), (1, 0, 1), (0, 1, 1)]
    pyramid = [(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0), (0.5, 0.5, 1)]
    # Nastran edge order: CPENTA G7-G9 bottom, G10-G12 vertical, G13-G15 top; CPYRAM G6-G9
    # the base, G10-G13 to the apex
    wedge_edges = [(0, 1), (1, 2), (2, 0), (0, 3), (1, 4), (2, 5), (3, 4), (4, 5), (5, 3)]
    pyramid_edges = [(0, 1), (1, 2), (2, 3), (3, 0), (0, 4), (1, 4), (2, 4), (3, 4)]
    for card, points, edges, volume in (
        ("CPENTA", wedge, wedge_edges, 0.5),
        ("CPYRAM", pyramid, pyramid_edges, 1 / 3),
    ):
        p = np.array(points, float)
        p = np.vstack([p, [(p[a] + p[b]) / 2 for a, b in edges]])
        ids = np.arange(1, p.shape[0] + 1)
        grids = [
            f"GRID    {i:8d}        {x:8.3f}{y:8.3f}{z:8.3f}"
            for i, (x, y, z) in zip(ids, p, strict=True)
        ]
        fields = [f"{i:<8d}" for i in ids]
        text = f"{card:<8s}1       1       " + "".join(fields[:6]) + "\n"
        rest = fields[6:]
        while rest:
            text += "        " + "".join(rest[:8]) + "\n"
            rest = rest[8:]
        path = tmp_path / f"{card}.bdf"
        path.write_text("\n".join(grids) + "\n" + text + "ENDDATA\n")
        elements = bulk_surface_elements(read_bulk(path))
        assert [k for k, _ in elements.blocks] == [
            {"CPENTA": "wedge15", "CPYRAM": "pyramid13"}[card]
        ]
        surface = outer_surface(elements.blocks, ids, p)
        assert np.array_equal(surface.node_ids, ids)  # every edge grid on the skin
        assert is_closed_and_consistent(surface.triangles)
        assert enclosed_volume(p[surface.triangles - 1]) == pytest.approx(volume, rel=1e-12)


# ============================================================================ Abaqus
ABAQUS_MODEL = """*HEADING
shells, beams, a solid and point masses
*NODE
1, 0., 0., 0.
2, 1., 0., 0.
3, 1., 1., 0.
4, 0., 1., 0.
5, 0., 0., 1.
6, 1., 0., 1.
7, 1., 1., 1.
8, 0., 1., 1.
9, 2., 0., 0.
10, 2., 1., 0.
11, 3., 0., 0.
12, 3., 1., 0.
13, 0., 0., 3.
14, 0., 0., 4.
15, 0., 0., 5.
*ELEMENT, TYPE=C3D8
1, 1, 2, 3, 4, 5, 6, 7, 8
*ELEMENT, TYPE=S4R
2, 4, 3, 2, 1
3, 2, 9, 10, 3
*ELEMENT, TYPE=S3
4, 9, 11, 12
*ELEMENT, TYPE=B31
5, 5, 13, 9
*ELEMENT, TYPE=B32
6, 13, 14, 15
*ELEMENT, TYPE=MASS
7, 15
*ELEMENT, TYPE=ROTARYI
8, 12
"""


def test_abaqus_shells_beams_and_a_solid(tmp_path):
    """S4R 2 lies on the cube's bottom face (drawn once), S4R 3 and S3 4 beside it; B31 with an
    orientation node (not drawn), B32 through its middle node; MASS and ROTARYI not drawn. Read
    through the reader with diagonal K and M in the MATRIX INPUT layout."""
    path = tmp_path / "mixed.inp"
    path.write_text(ABAQUS_MODEL)
    model = read_inp(path)
    elements = surface_elements(model)
    assert elements.skipped == {"MASS": 1, "ROTARYI": 1}
    xyz = dict(zip(model.node_ids.tolist(), model.coordinates, strict=True))
    surface = outer_surface(elements.blocks, model.node_ids, model.coordinates)
    assert surface.triangles.shape[0] == 12 + 2 + 1  # cube; S4R 3 (2); S3 (1); S4R 2 none
    cube = np.isin(surface.triangles, np.arange(1, 9)).all(axis=1)
    assert is_closed_and_consistent(surface.triangles[cube])
    assert enclosed_volume(corners(xyz, surface.triangles[cube])) == pytest.approx(1.0)
    plates = triangle_areas(corners(xyz, surface.triangles[~cube])).sum()
    assert plates == pytest.approx(1.0 + 0.5)
    assert surface.lines.tolist() == [[5, 13], [13, 14], [14, 15]]
    keys = [(n, d) for n in range(1, 16) for d in range(1, 7) if d <= 3 or n not in (6, 7, 8)]
    diagonal = "".join(f"{n},{d}, {n},{d},  1.0\n" for n, d in keys)
    for name in ("k.mtx", "m.mtx"):
        (tmp_path / name).write_text(diagonal)
    body = read_abaqus(tmp_path / "k.mtx", tmp_path / "m.mtx", inp=path)
    assert np.array_equal(body.surface.triangles, surface.triangles)
    assert np.array_equal(body.surface.lines, surface.lines)
    assert surface_note(body) == (
        "surface: outer faces of 1 hex8 elements; 2 quad4, 1 tri3 shell elements; 1 line2, "
        "1 line3 line elements (15 triangles, 3 lines; not drawn: 1 MASS, 1 ROTARYI) for viewers"
    )


# ============================================================================ Ansys
def cdb_text(nodes: dict[int, tuple[float, float, float]], types: dict[int, int],
             elements: list[tuple[int, list[int]]]) -> str:  # fmt: skip
    """A small archive: ET commands, NBLOCK, EBLOCK (solid format, type and nodes per element)."""
    out = [f"ET,{itype},{number}" for itype, number in types.items()]
    out += [f"NBLOCK,6,SOLID,{max(nodes):10d},{len(nodes):10d}", "(3i9,6e21.13e3)"]
    for i, (x, y, z) in nodes.items():
        out.append(f"{i:9d}{0:9d}{0:9d}{x:21.13E}{y:21.13E}{z:21.13E}")
    out += ["N,R5.3,LOC,       -1,", f"EBLOCK,19,SOLID,{len(elements):10d},{len(elements):10d}",
            "(19i10)"]  # fmt: skip
    for number, (itype, ids) in enumerate(elements, start=1):
        fields = [1, itype, 1, 1, 0, 0, 0, 0, len(ids), 0, number, *ids]
        out.append("".join(f"{v:10d}" for v in fields[:19]))
        if len(fields) > 19:
            out.append("".join(f"{v:10d}" for v in fields[19:]))
    out.append("        -1")
    return "\n".join(out) + "\n"


def test_ansys_shells_beams_and_degenerate_solids(tmp_path):
    """SHELL181 quad and triangle (K = L), BEAM188 with its orientation node, BEAM189 through
    its middle node K, a SOLID185 prism (K = L, O = P) and tetrahedron, a SOLID187 without its
    midside nodes (drawn through its corners), MASS21 not drawn."""
    nodes = {1: (0, 0, 0), 2: (1, 0, 0), 3: (1, 1, 0), 4: (0, 1, 0), 5: (0, 0, 1), 6: (1, 0, 1),
             7: (1, 1, 1), 8: (0, 1, 1), 9: (2, 0, 0), 10: (2, 1, 0), 11: (0, 0, -1),
             12: (0, 0, -2), 13: (0, 0, -1.5), 14: (5, 5, 5), 15: (3, 0, 0), 16: (4, 0, 0),
             17: (3, 1, 0), 18: (3, 0, 1), 19: (6, 0, 0), 20: (7, 0, 0), 21: (6, 1, 0),
             22: (6, 0, 1)}  # fmt: skip
    types = {1: 181, 2: 188, 3: 189, 4: 185, 5: 21, 6: 187}
    elements = [
        (1, [2, 9, 10, 3]),
        (1, [9, 15, 10, 10]),  # triangle
        (2, [1, 11, 14]),  # orientation node 14
        (3, [11, 12, 13, 14]),  # K = 13 the middle, L = 14 the orientation
        (4, [1, 2, 3, 3, 5, 6, 7, 7]),  # prism
        (4, [15, 16, 17, 17, 18, 18, 18, 18]),  # tetrahedron
        (5, [14]),
        (6, [19, 20, 21, 22, 0, 0, 0, 0, 0, 0]),  # SOLID187, midside nodes dropped (0)
    ]
    path = tmp_path / "mixed.cdb"
    path.write_text(cdb_text(nodes, types, elements))
    found = cdb_surface_elements(read_cdb(path))
    assert found.skipped == {"MASS21": 1}
    kinds: dict[str, list[list[int]]] = {}
    for kind, connectivity in found.blocks:
        kinds.setdefault(kind, []).extend(connectivity.tolist())
    assert kinds == {
        "quad4": [[2, 9, 10, 3]],
        "tri3": [[9, 15, 10]],
        "line2": [[1, 11]],
        "line3": [[11, 13, 12]],
        "wedge6": [[1, 2, 3, 5, 6, 7]],
        "tet4": [[15, 16, 17, 18], [19, 20, 21, 22]],
    }
    ids = np.array(sorted(nodes))
    xyz = {i: np.array(p, float) for i, p in nodes.items()}
    surface = outer_surface(found.blocks, ids, np.array([xyz[i] for i in ids]))
    assert surface.triangles.shape[0] == 2 + 1 + 8 + 4 + 4
    assert surface.lines.tolist() == [[1, 11], [11, 13], [13, 12]]
    solid = np.isin(surface.triangles, [1, 2, 3, 5, 6, 7]).all(axis=1)
    assert enclosed_volume(corners(xyz, surface.triangles[solid])) == pytest.approx(0.5)


def test_hexbeam_archive_skin_is_its_box():
    """HexBeam.cdb: 40 SOLID186 (2 x 2 x 10) filling a 1 x 1 x 5 box: 88 outer quadratic faces
    of 6 triangles each, closed, enclosing the box's volume; the reader of the .full with the
    archive as nodes gives the body this surface."""
    archive_path = DATA / "pymapdl_reader_hexbeam" / "HexBeam.cdb"
    archive = read_cdb(archive_path)
    found = cdb_surface_elements(archive)
    assert [(k, c.shape) for k, c in found.blocks] == [("hex20", (40, 20))]
    assert found.skipped == {}
    surface = outer_surface(found.blocks, archive.node_ids, archive.coordinates)
    assert surface.triangles.shape[0] == 6 * (4 * 2 * 10 + 2 * 2 * 2)
    assert is_closed_and_consistent(surface.triangles)
    xyz = dict(zip(archive.node_ids.tolist(), archive.coordinates, strict=True))
    box = np.prod(np.ptp(archive.coordinates, axis=0))
    assert enclosed_volume(corners(xyz, surface.triangles)) == pytest.approx(box, rel=1e-12)
    body = read_ansys_full(DATA / "pymapdl_reader_hexbeam" / "file.full", nodes=archive_path)
    assert np.array_equal(body.surface.triangles, surface.triangles)
    assert surface_note(body) == (
        f"surface: outer faces of 40 hex20 elements ({surface.triangles.shape[0]} triangles) "
        "for viewers"
    )


def test_attach_surface_notes_without_drawn_elements_or_coordinates():
    """Only springs and masses: no surface, the note counts them; no coordinates: said so."""
    from dataclasses import replace

    from pymorembs.io.element_surface import SurfaceElements, attach_surface

    body = read_op2(KELM / "static_solid_shell_bar_kelm.op2", mass="KGG")
    body = replace(body, surface=None, notes=())
    only = SurfaceElements(skipped={"CBUSH": 2, "CONM2": 3})
    bare = attach_surface(body, only)
    assert bare.surface is None
    assert bare.notes == (
        "surface: none, no element of a drawn kind (not drawn: 3 CONM2, 2 CBUSH)",
    )
    assert attach_surface(body, SurfaceElements()) is body
    quad = SurfaceElements()
    quad.add("quad4", np.array([[1, 2, 3, 4]]))
    blind = attach_surface(replace(body, has_coordinates=False), quad)
    assert blind.surface is None
    assert blind.notes == ("surface: the file gives no coordinates; nodes cannot be drawn",)
    drawn = attach_surface(body, quad)
    assert drawn.surface.triangles.shape == (2, 3)
    assert drawn.notes == ("surface: 1 quad4 shell elements (2 triangles) for viewers",)


def test_a_grid_field_that_is_no_integer_is_named(tmp_path):
    path = tmp_path / "bad.bdf"
    path.write_text(
        "GRID    1               0.      0.      0.\nCROD    1       1       1       2.5\n"
    )
    with pytest.raises(UserError, match=r"bad.bdf:2: CROD grid '2.5' is not an integer"):
        bulk_surface_elements(read_bulk(path))
    path.write_text("CROD    1       1       1       1_0\n")
    with pytest.raises(UserError, match=r"bad.bdf:1: CROD grid '1_0' is not an integer"):
        bulk_surface_elements(read_bulk(path))


def test_small_large_and_free_field_element_cards_give_the_same_elements(tmp_path):
    """One-line small-field cards take the reader's numpy path, the others the card path."""
    grids = "".join(f"GRID    {i:<8}        {i:<8.1f}{i % 2:<8.1f}0.\n" for i in range(1, 7))
    decks = {
        "small": "CQUAD4  1       1       1       2       4       3\n"
        "CTRIA3  2       1       3       4       5\nCROD    3       1       5       6\n",
        "free": "CQUAD4,1,1,1,2,4,3\nCTRIA3,2,1,3,4,5\nCROD,3,1,5,6\n",
        "large": f"CQUAD4* {1:<16}{1:<16}{1:<16}{2:<16}\n*       {4:<16}{3:<16}\n"
        f"CTRIA3* {2:<16}{1:<16}{3:<16}{4:<16}\n*       {5:<16}\n"
        f"CROD*   {3:<16}{1:<16}{5:<16}{6:<16}\n",
        "continued": "CQUAD4  1       1       1       2       4       3       0.      0.\n"
        "                        0.1     0.1     0.1     0.1\n"
        "CTRIA3  2       1       3       4       5\nCROD    3       1       5       6\n",
    }
    found = {}
    for name, cards in decks.items():
        path = tmp_path / f"{name}.bdf"
        path.write_text(grids + cards)
        bulk = read_bulk(path)
        assert sorted(bulk.element_grids) == (["CQUAD4", "CROD", "CTRIA3"] if name == "small"
                                              else ["CROD", "CTRIA3"] if name == "continued"
                                              else [])  # fmt: skip
        elements = bulk_surface_elements(bulk)
        found[name] = {kind: c.tolist() for kind, c in elements.blocks}
    expected = {"tri3": [[3, 4, 5]], "quad4": [[1, 2, 4, 3]], "line2": [[5, 6]]}
    assert all(f == expected for f in found.values()), found
