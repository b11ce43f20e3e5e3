"""The element numbers of the file reach ``ElementMesh.element_ids`` (issue #29: stress points
are named by them): Abaqus/CalculiX decks, Ansys ``.cdb``, Nastran bulk data, the native file."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from box_meshes import box_mesh, solid_body

from pymorembs.io.abaqus_inp import read_inp, solid_blocks
from pymorembs.io.ansys_cdb import cdb_solid_blocks, read_cdb
from pymorembs.io.nastran_bulk import bulk_solid_blocks, read_bulk
from pymorembs.io.native import read_body_h5, write_body_h5
from pymorembs.io.solid_mesh import element_mesh

DATA = Path(__file__).parents[1] / "data"
NODES = "1, 0., 0., 0.\n2, 1., 0., 0.\n3, 0., 1., 0.\n4, 0., 0., 1.\n5, 1., 1., 1.\n"


def test_abaqus_deck_labels(tmp_path):
    deck = tmp_path / "two.inp"
    deck.write_text(
        f"*NODE\n{NODES}*ELEMENT, TYPE=C3D4, ELSET=ALL\n11, 1, 2, 3, 4\n5, 2, 3, 4, 5\n"
        "*MATERIAL, NAME=STEEL\n*ELASTIC\n2.1e11, 0.3\n"
        "*SOLID SECTION, ELSET=ALL, MATERIAL=STEEL\n"
    )
    assert element_mesh(solid_blocks(read_inp(deck))).element_ids.tolist() == [11, 5]


def test_nastran_eids(tmp_path):
    bulk = tmp_path / "two.bdf"
    grids = "".join(
        f"GRID,{line.split(',')[0]},,{','.join(line.split(',')[1:]).replace(' ', '')}\n"
        for line in NODES.splitlines()
    )
    bulk.write_text(
        f"BEGIN BULK\n{grids}CTETRA,42,1,1,2,3,4\nCTETRA,7,1,2,3,4,5\n"
        "PSOLID,1,1\nMAT1,1,2.1e11,,0.3\nENDDATA\n"
    )
    blocks = bulk_solid_blocks(read_bulk(bulk))
    assert not isinstance(blocks, str), blocks
    assert element_mesh(blocks).element_ids.tolist() == [42, 7]


def test_ansys_cdb_element_numbers():
    path = DATA / "pymapdl_reader_hexbeam" / "HexBeam.cdb"
    archive = read_cdb(path)
    blocks = cdb_solid_blocks(archive, path)
    assert not isinstance(blocks, str), blocks
    assert np.array_equal(element_mesh(blocks).element_ids, archive.element_ids)


def test_native_file_keeps_them(tmp_path):
    points, connectivity = box_mesh("tet4", (1, 1, 1), (1.0, 1.0, 1.0))
    body = solid_body("tet4", points, connectivity, 2.1e11, 0.3)
    write_body_h5(body, tmp_path / "b.h5")
    assert np.array_equal(read_body_h5(tmp_path / "b.h5").mesh.element_ids, body.mesh.element_ids)
