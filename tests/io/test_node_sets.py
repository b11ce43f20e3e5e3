"""Named node sets of the deck reach ``ElasticBody.node_sets`` (issue #29: hot spots given as a
node set): CalculiX/Abaqus ``*NSET`` (with ``GENERATE``, ``NSET=`` of ``*NODE``, ``INSTANCE=``
in the assembly), Ansys ``CMBLOCK`` node components, the native file."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

import pymorembs as pm
from pymorembs.errors import UserError
from pymorembs.io.abaqus_inp import named_node_sets, read_inp
from pymorembs.io.ansys_cdb import read_cdb
from pymorembs.io.native import read_body_h5, write_body_h5

DATA = Path(__file__).parents[1] / "data"
PARTS = DATA / "calculix_stress_parts"
HEXBEAM = DATA / "pymapdl_reader_hexbeam"


def test_calculix_bar_sets_are_its_end_faces():
    """TIP and CLAMP of the genuine bar deck are the nodes at x = L and x = 0 (told from the
    coordinates, not from the deck's lists); NALL (``*NODE, NSET=NALL``) is every node."""
    body = pm.read(PARTS / "bar.sti.gz")
    assert list(body.node_sets) == ["NALL", "CLAMP", "TIP"]
    x = body.coordinates[:, 0]
    assert np.array_equal(body.node_sets["TIP"], np.sort(body.node_ids[np.isclose(x, x.max())]))
    assert np.array_equal(body.node_sets["CLAMP"], np.sort(body.node_ids[np.isclose(x, 0.0)]))
    assert np.array_equal(body.node_sets["NALL"], np.sort(body.node_ids))
    assert "node sets 3 (NALL, CLAMP, TIP)" in repr(body)


def test_abaqus_generate_and_assembly_set_of_an_instance():
    """abq_beam.inp (Abaqus/CAE): ``*Nset, nset=solid, generate`` 1..518 in the part, and
    ``*Nset, nset=fixed, instance=beam-1`` in the assembly, whose labels are the instance's."""
    sets = named_node_sets(read_inp(DATA / "juliafem_abaqus_tetra_beam" / "abq_beam.inp"))
    assert sorted(sets) == ["FIXED", "SOLID"]
    assert np.array_equal(sets["SOLID"], np.arange(1, 519))
    assert sets["FIXED"].tolist() == [3, 4, 6, 7, 293, 395, 511, 512, 514]


def test_names_without_case_and_sets_of_part_instances(tmp_path):
    """``*nset, nset=Tip`` is TIP; a part's set in two instances becomes INSTANCE.NAME."""
    deck = tmp_path / "two.inp"
    deck.write_text(
        "*PART, NAME=P\n*NODE\n1, 0., 0., 0.\n2, 1., 0., 0.\n*nset, nset=Tip\n2\n*END PART\n"
        "*ASSEMBLY, NAME=A\n*INSTANCE, NAME=I1, PART=P\n*END INSTANCE\n"
        "*INSTANCE, NAME=I2, PART=P\n5., 0., 0.\n*END INSTANCE\n*END ASSEMBLY\n"
    )
    model = read_inp(deck)
    sets = named_node_sets(model)
    assert sorted(sets) == ["I1.TIP", "I2.TIP"]
    tips = [model.coordinates[np.searchsorted(model.node_ids, sets[k])][0, 0] for k in sorted(sets)]
    assert tips == [1.0, 6.0]


def test_ansys_node_components_match_the_mapdl_reader():
    """HexBeam.cdb's CMBLOCK node components (ranges ``j, -k``) equal those of the
    ansys-mapdl-reader library, and reach the body read with the archive."""
    reader = pytest.importorskip("ansys.mapdl.reader")
    archive = read_cdb(HEXBEAM / "HexBeam.cdb")
    theirs = reader.Archive(str(HEXBEAM / "HexBeam.cdb"), parse_vtk=False).node_components
    assert sorted(archive.node_components) == sorted(theirs) == ["NCOMP2", "NODE_SELECTION"]
    for name, nodes in theirs.items():
        assert np.array_equal(archive.node_components[name], np.sort(nodes))
    body = pm.read(HEXBEAM / "file.full", nodes=HEXBEAM / "HexBeam.cdb")
    for name, nodes in archive.node_components.items():
        assert np.array_equal(body.node_sets[name], nodes[np.isin(nodes, body.node_ids)])


def test_a_cmblock_range_without_start_is_refused(tmp_path):
    text = (HEXBEAM / "HexBeam.cdb").read_text()
    broken = text.replace(
        "CMBLOCK,NCOMP2  ,NODE,      42", "CMBLOCK,NCOMP2  ,NODE,       1\n(8i10)\n        -4\nX", 1
    )
    (tmp_path / "broken.cdb").write_text(broken)
    with pytest.raises(UserError, match=r"broken\.cdb:\d+: CMBLOCK NCOMP2: a range -k follows"):
        read_cdb(tmp_path / "broken.cdb")


def test_native_file_keeps_them(tmp_path):
    body = pm.read(PARTS / "bar8.sti.gz")
    write_body_h5(body, tmp_path / "b.h5")
    back = read_body_h5(tmp_path / "b.h5")
    assert list(back.node_sets) == list(body.node_sets)
    for name, nodes in body.node_sets.items():
        assert np.array_equal(back.node_sets[name], nodes)


def test_a_set_of_unknown_nodes_is_refused():
    body = pm.read(PARTS / "bar8.sti.gz")
    with pytest.raises(UserError, match="node set EXTRA: node 123456 is not in the node list"):
        replace(body, node_sets={"extra": [1, 123456]})
    assert body.with_node_sets({"extra": np.array([123456])}).node_sets["EXTRA"].size == 0
