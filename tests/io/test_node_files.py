"""``--nodes`` takes the node file of any FE program for every matrix format (issue #27 item 5):
an Abaqus or CalculiX ``.inp``, an Ansys ``.cdb``, Nastran bulk data or an ``.f06``, a
``nodes.csv`` -- told from the content, not the name.

References: the coordinates as the files state them (parsed here line by line), CalculiX's own
eigenfrequencies for the CalculiX matrices read through other formats, and the same body read
with a ``nodes.csv``.
"""

from __future__ import annotations

import json
import re
import shutil
from pathlib import Path

import numpy as np
import pytest
import scipy.io

from abaqus_models import genuine
from pymorembs.io import read_body, write_matrix_files
from pymorembs.io.node_files import node_file_kind, read_node_file
from pymorembs.job.cli import main

DATA = Path(__file__).parents[1] / "data"
CALCULIX = DATA / "calculix_c3d20_block"
HEXBEAM = DATA / "pymapdl_reader_hexbeam"
MAEWING = DATA / "exportnastrankm_mAEWing1_FEMv5p2"
GOOD_PCH = Path(__file__).parents[1] / "broken" / "files" / "good.pch"


def deck_nodes(path: Path) -> dict[int, list[float]]:
    """The ``*NODE`` lines of a CalculiX deck, parsed here."""
    block = path.read_text().split("*NODE, NSET=NALL\n", 1)[1].split("*", 1)[0]
    rows = [line.split(",") for line in block.splitlines()]
    return {int(row[0]): [float(v) for v in row[1:]] for row in rows}


def write_node_files(folder: Path, nodes: dict[int, list[float]]) -> dict[str, Path]:
    """The same nodes as nodes.csv, an Abaqus deck, Nastran bulk data and an Ansys archive."""
    files = {
        "csv": folder / "nodes.csv",
        "abaqus": folder / "nodes.inp",
        "nastran": folder / "nodes.bdf",
        "ansys": folder / "nodes.cdb",
    }
    rows = sorted(nodes.items())
    files["csv"].write_text(
        "id,x,y,z\n" + "".join(f"{i},{x!r},{y!r},{z!r}\n" for i, (x, y, z) in rows)
    )
    files["abaqus"].write_text(
        "*HEADING\n** coordinates only\n*NODE\n"
        + "".join(f"{i}, {x!r}, {y!r}, {z!r}\n" for i, (x, y, z) in rows)
    )
    files["nastran"].write_text(
        "BEGIN BULK\n" + "".join(f"GRID,{i},,{x!r},{y!r},{z!r}\n" for i, (x, y, z) in rows)
    )
    files["ansys"].write_text(
        f"NBLOCK,6,SOLID,{len(rows):10d},{len(rows):10d}\n(3i9,6e21.13e3)\n"
        + "".join(f"{i:9d}{0:9d}{0:9d}{x:21.13E}{y:21.13E}{z:21.13E}\n" for i, (x, y, z) in rows)
        + "N,R5.3,LOC,       -1,\n"
    )
    return files


def info(capsys, *args: str | Path) -> dict:
    code = main(["info", *map(str, args), "--modes", "12", "--json"])
    captured = capsys.readouterr()
    assert code == 0, captured.err
    return json.loads(captured.out)


def test_the_kind_of_a_node_file_is_told_from_its_content(tmp_path):
    files = write_node_files(tmp_path, {1: [0.0, 0.0, 0.0], 2: [1.0, 0.5, 0.25]})
    for kind, path in files.items():
        renamed = tmp_path / f"{kind}_nodes.txt"  # the name says nothing
        shutil.copy(path, renamed)
        assert node_file_kind(renamed) == kind
        nodes = read_node_file(renamed)
        order = np.argsort(nodes.ids)
        np.testing.assert_array_equal(nodes.ids[order], [1, 2])
        np.testing.assert_array_equal(nodes.coordinates[order], [[0, 0, 0], [1, 0.5, 0.25]])
    assert node_file_kind(CALCULIX / "free.inp") == "abaqus"
    assert node_file_kind(HEXBEAM / "HexBeam.cdb") == "ansys"
    assert node_file_kind(MAEWING / "sol103_maewing1_femv5p2.f06") == "nastran"


def test_calculix_matrices_as_abaqus_files_take_the_deck_as_nodes(tmp_path, capsys):
    """The issue's case: ``--nodes job.inp`` was refused for the Abaqus format. (The equations
    come from a dofs.csv written from the ``.dof``: the block is symmetric under the inversion
    through its centre, which maps the deck's node order onto the label order, so the order
    derived from the deck alone is ambiguous, and refused as such.)"""
    shutil.copy(CALCULIX / "free.sti", tmp_path / "job_STIF1.mtx")
    shutil.copy(CALCULIX / "free.mas", tmp_path / "job_MASS1.mtx")
    directions = {"1": "ux", "2": "uy", "3": "uz"}
    rows = [line.split(".") for line in (CALCULIX / "free.dof").read_text().split()]
    dofs = tmp_path / "dofs.csv"
    dofs.write_text("node,direction\n" + "".join(f"{n},{directions[d]}\n" for n, d in rows))
    facts = info(
        capsys,
        "--stiffness",
        tmp_path / "job_STIF1.mtx",
        "--mass",
        tmp_path / "job_MASS1.mtx",
        "--dofs",
        dofs,
        "--nodes",
        CALCULIX / "free.inp",
    )
    assert facts["rigid_body_modes"] == 6 and facts["has_coordinates"]
    dat = (CALCULIX / "free_modes.dat").read_text().split("P A R T I C")[0]
    expected = np.array([float(r) for r in re.findall(r"^\s+\d+\s+\S+\s+\S+\s+(\S+)", dat, re.M)])
    found = np.array(facts["eigenfrequencies_hz"][6:12])
    np.testing.assert_allclose(found, expected, rtol=1e-6)


@pytest.mark.parametrize("kind", ["csv", "abaqus", "nastran", "ansys"])
def test_every_node_file_gives_a_matrix_market_body_its_coordinates(tmp_path, kind):
    body = read_body(file=CALCULIX / "free.sti")
    written = write_matrix_files(body, tmp_path / "plain")
    nodes = deck_nodes(CALCULIX / "free.inp")
    files = write_node_files(tmp_path, nodes)
    read = read_body(
        stiffness=written["stiffness"],
        mass=written["mass"],
        dofs=written["dofs"],
        nodes=files[kind],
    )
    np.testing.assert_array_equal(
        read.coordinates[read.node_rows(body.node_ids)], [nodes[int(i)] for i in body.node_ids]
    )
    residuals = read.rigid_body_residuals()
    assert np.nanmax(residuals) < 1e-12  # the rotations too: the coordinates fit K


def test_a_calculix_deck_gives_a_matlab_body_its_coordinates(tmp_path):
    body = read_body(file=CALCULIX / "free.sti")
    written = write_matrix_files(body, tmp_path / "plain")
    scipy.io.savemat(tmp_path / "body.mat", {"K": body.stiffness, "M": body.mass})
    read = read_body(file=tmp_path / "body.mat", dofs=written["dofs"], nodes=CALCULIX / "free.inp")
    found = read.coordinates[read.node_rows(body.node_ids)]
    np.testing.assert_array_equal(found, body.coordinates)
    assert np.nanmax(read.rigid_body_residuals()) < 1e-12


@pytest.mark.parametrize("kind", ["csv", "abaqus", "nastran"])
def test_an_ansys_full_file_takes_any_node_file(tmp_path, kind):
    archive = read_node_file(HEXBEAM / "HexBeam.cdb")
    nodes = dict(zip(archive.ids.tolist(), archive.coordinates.tolist(), strict=True))
    files = write_node_files(tmp_path, nodes)
    reference = read_body(file=HEXBEAM / "file.full", nodes=HEXBEAM / "HexBeam.cdb")
    body = read_body(file=HEXBEAM / "file.full", nodes=files[kind])
    np.testing.assert_array_equal(
        body.coordinates[body.node_rows(reference.node_ids)], reference.coordinates
    )
    assert body.fixed.size == reference.fixed.size == 63


@pytest.mark.parametrize("kind", ["csv", "abaqus", "ansys", "nastran"])
def test_a_dmig_punch_takes_any_node_file(tmp_path, kind):
    files = write_node_files(tmp_path, {101: [0.0, 0.0, 0.0], 102: [2.0, 0.0, 0.0]})
    body = read_body(file=GOOD_PCH, nodes=files[kind])
    found = body.coordinates[body.node_rows([101, 102])]
    np.testing.assert_array_equal(found, [[0, 0, 0], [2, 0, 0]])
    assert body.has_coordinates


def test_a_node_file_of_no_known_kind_is_one_line(tmp_path, capsys):
    notes = tmp_path / "notes.txt"
    notes.write_text("coordinates are in the drawing\n")
    body = read_body(file=CALCULIX / "free.sti")
    written = write_matrix_files(body, tmp_path / "plain")
    arguments = ["--stiffness", written["stiffness"], "--mass", written["mass"], "--nodes", notes]
    code = main(["info", *map(str, arguments)])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1
    expected = r"pymorembs: error: .*notes\.txt: no node coordinates: neither a nodes\.csv"
    assert re.match(expected, err[0]), err


def test_an_abaqus_substructure_takes_nodes_as_inp(tmp_path):
    """``nodes`` is the ``inp`` option of the Abaqus formats: a deck, bulk data, an archive."""
    path = genuine("abaqus_mtx_parser/symmetric/inner.mtx", tmp_path)
    files = write_node_files(tmp_path, {k: [k / 10, 0.0, 0.0] for k in range(1, 9)})
    for kind in ("abaqus", "nastran", "ansys"):
        body = read_body(file=path, nodes=files[kind])
        assert body.has_coordinates
        np.testing.assert_array_equal(body.node_position(7), [0.7, 0.0, 0.0])
