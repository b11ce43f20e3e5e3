"""Compressed inputs (``.gz``, ``.bz2``, ``.xz``) read as the files they hold, every format
(issue #27 item 6): the same body as from the plain files, detection through the compression,
a damaged archive one line naming it, nothing left in the temporary folder.

References: the plain files read by the same readers (which the other reader tests check), and
the SHA-256 of the genuine Abaqus files stored xz-compressed in ``tests/data`` (their unpacked
bytes are the originals).
"""

from __future__ import annotations

import bz2
import gzip
import lzma
import re
import shutil
import tempfile
from pathlib import Path

import numpy as np
import pytest

from abaqus_models import genuine
from info_runs import refused
from pymorembs.body import ElasticBody
from pymorembs.io import detect_format, read_body, write_body_h5, write_matrix_files
from pymorembs.job.cli import main

DATA = Path(__file__).parents[1] / "data"
CALCULIX = DATA / "calculix_c3d20_block"
HEXBEAM = DATA / "pymapdl_reader_hexbeam"
EXUDYN = DATA / "exudyn_abaqus_blocks"
OPENERS = {".gz": gzip.open, ".bz2": bz2.open, ".xz": lzma.open}


def compress(path: Path, suffix: str, target: Path | None = None) -> Path:
    """``path`` compressed into ``target`` (default: beside it) with the suffix's method."""
    target = target if target is not None else path.parent
    out = target / f"{path.name}{suffix}"
    with open(path, "rb") as source, OPENERS[suffix](out, "wb") as sink:
        shutil.copyfileobj(source, sink)
    return out


def same_body(a: ElasticBody, b: ElasticBody) -> None:
    for x, y in ((a.stiffness, b.stiffness), (a.mass, b.mass)):
        assert x.shape == y.shape and (x != y).nnz == 0
    np.testing.assert_array_equal(a.dofs.nodes, b.dofs.nodes)
    np.testing.assert_array_equal(a.dofs.directions, b.dofs.directions)
    np.testing.assert_array_equal(a.node_ids, b.node_ids)
    np.testing.assert_array_equal(a.coordinates, b.coordinates)
    np.testing.assert_array_equal(a.fixed, b.fixed)
    assert a.name == b.name


@pytest.fixture
def temporary(tmp_path, monkeypatch) -> Path:
    """The temporary folder of the plain copies (checked empty afterwards)."""
    folder = tmp_path / "temporary"
    folder.mkdir()
    monkeypatch.setattr(tempfile, "tempdir", str(folder))
    return folder


def test_a_compressed_matrix_market_file_reads_like_the_plain_one(tmp_path, temporary, capsys):
    """The issue's case: ``K.mtx.gz`` gave "cannot tell the file format", then "not a text
    file"."""
    plain = write_matrix_files(read_body(file=CALCULIX / "free.sti"), tmp_path / "body")
    reference = read_body(**{key: plain[key] for key in ("stiffness", "mass", "dofs", "nodes")})
    for suffix in OPENERS:
        k, m = compress(plain["stiffness"], suffix), compress(plain["mass"], suffix)
        assert detect_format(k) == "matrix-market"
        body = read_body(stiffness=k, mass=m, dofs=plain["dofs"], nodes=plain["nodes"])
        same_body(body, reference)
        assert main(["info", "--stiffness", str(k), "--mass", str(m), "--modes", "3"]) == 0
        capsys.readouterr()
    assert not any(temporary.iterdir())


def test_a_folder_of_compressed_files_reads_like_the_plain_folder(tmp_path, temporary):
    body = read_body(file=CALCULIX / "fixed.sti")
    write_matrix_files(body, tmp_path / "block")
    reference = read_body(file=tmp_path / "block")
    for path in sorted((tmp_path / "block").iterdir()):
        compress(path, ".xz")
        path.unlink()
    assert detect_format(tmp_path / "block") == "matrix-market"
    same_body(read_body(file=tmp_path / "block"), reference)
    assert reference.name == "block" and reference.fixed.size == 11
    assert not any(temporary.iterdir())


@pytest.mark.parametrize("suffix", sorted(OPENERS))
def test_a_compressed_calculix_export_reads_like_the_plain_one(tmp_path, temporary, suffix):
    reference = read_body(file=CALCULIX / "fixed.sti")
    for name in ("fixed.sti", "fixed.mas", "fixed.dof", "fixed.inp"):
        compress(CALCULIX / name, suffix, tmp_path)
    assert detect_format(tmp_path / f"fixed.sti{suffix}") == "calculix"
    body = read_body(file=tmp_path / f"fixed.sti{suffix}")  # the others found beside it
    same_body(body, reference)
    assert [note.replace(suffix, "") for note in body.notes] == list(reference.notes)
    # only some compressed, under other names
    shutil.copy(CALCULIX / "fixed.dof", tmp_path / "fixed.dof")
    body = read_body(file=tmp_path / f"fixed.sti{suffix}", mass=tmp_path / f"fixed.mas{suffix}")
    same_body(body, reference)
    assert not any(temporary.iterdir())


def test_the_genuine_xz_compressed_abaqus_files_read_as_their_originals(tmp_path, temporary):
    """tests/data keeps some Abaqus exports xz-compressed; read directly they give the body of
    the unpacked originals (whose SHA-256 the test helper checks)."""
    stiffness = "exudyn_abaqus_blocks/blockC3D4_STIF1.mtx"
    unpacked = genuine(stiffness, tmp_path)
    options = {"mass": EXUDYN / "blockC3D4_MASS1.mtx", "inp": EXUDYN / "blockC3D4.inp"}
    reference = read_body(stiffness=unpacked, **options)
    body = read_body(stiffness=DATA / f"{stiffness}.xz", **options)
    same_body(body, reference)
    assert not any(temporary.iterdir())


def test_binary_formats_read_through_the_compression(tmp_path, temporary):
    """The Ansys .full (binary records) with its .cdb, and the native HDF5 file."""
    reference = read_body(file=HEXBEAM / "file.full", nodes=HEXBEAM / "HexBeam.cdb")
    full = compress(HEXBEAM / "file.full", ".bz2", tmp_path)
    cdb = compress(HEXBEAM / "HexBeam.cdb", ".xz", tmp_path)
    assert detect_format(full) == "ansys-full"
    body = read_body(file=full, nodes=cdb)
    same_body(body, reference)
    assert body.surface is not None and reference.surface is not None  # the .cdb's elements
    np.testing.assert_array_equal(body.surface.triangles, reference.surface.triangles)
    h5 = tmp_path / "model.h5"
    write_body_h5(reference, h5)
    packed = compress(h5, ".gz")
    assert detect_format(packed) == "native"
    same_body(read_body(file=packed), reference)
    assert not any(temporary.iterdir())


def test_a_compressed_deck_finds_its_include_files_beside_it(tmp_path, temporary):
    deck = (CALCULIX / "free.inp").read_text()
    nodes = deck[deck.index("*NODE") : deck.index("*ELEMENT")]
    (tmp_path / "nodes.inp").write_text(nodes)
    (tmp_path / "deck.inp").write_text(deck.replace(nodes, "*INCLUDE, INPUT=nodes.inp\n"))
    compress(tmp_path / "deck.inp", ".gz")
    (tmp_path / "deck.inp").unlink()
    for name in ("free.sti", "free.mas", "free.dof"):
        shutil.copy(CALCULIX / name, tmp_path / name.replace("free", "deck"))
    body = read_body(file=tmp_path / "deck.sti")
    np.testing.assert_array_equal(
        body.coordinates, read_body(file=CALCULIX / "free.sti").coordinates
    )
    assert not any(temporary.iterdir())


@pytest.mark.parametrize("suffix", sorted(OPENERS))
def test_a_damaged_archive_is_one_line_naming_it(tmp_path, temporary, capsys, suffix):
    plain = write_matrix_files(read_body(file=CALCULIX / "free.sti"), tmp_path / "body")
    k = compress(plain["stiffness"], suffix)
    data = k.read_bytes()
    cut = tmp_path / f"cut_K.mtx{suffix}"
    cut.write_bytes(data[: len(data) // 2])  # truncated
    line = refused(capsys, "--stiffness", cut, "--mass", plain["mass"])
    assert re.match(rf".*cut_K\.mtx{re.escape(suffix)}: a damaged or truncated", line), line
    line = refused(capsys, "--format", "matrix-market", "--stiffness", cut, "--mass", plain["mass"])
    assert re.match(rf".*cut_K\.mtx{re.escape(suffix)}: a damaged or truncated", line), line
    broken = tmp_path / f"broken_K.mtx{suffix}"
    middle = len(data) // 2
    broken.write_bytes(
        data[:middle] + bytes(b ^ 0xFF for b in data[middle : middle + 64]) + data[middle + 64 :]
    )
    line = refused(capsys, "--stiffness", broken, "--mass", plain["mass"])
    assert re.match(rf".*broken_K\.mtx{re.escape(suffix)}: a damaged or truncated", line), line
    assert not any(temporary.iterdir())


def test_a_mistake_inside_a_compressed_file_names_the_compressed_file(tmp_path, temporary, capsys):
    plain = write_matrix_files(read_body(file=CALCULIX / "free.sti"), tmp_path / "body")
    lines = plain["stiffness"].read_text().splitlines()
    lines[4] = lines[4].replace(" ", " x", 1)
    bad = tmp_path / "bad_K.mtx"
    bad.write_text("\n".join(lines) + "\n")
    packed = compress(bad, ".gz")
    line = refused(capsys, "--stiffness", packed, "--mass", plain["mass"])
    assert re.match(r".*bad_K\.mtx\.gz:5: .*not a", line), line
    assert str(temporary) not in line
    assert not any(temporary.iterdir())
