"""CalculiX exports read natively (issue #27 item 5): ``info job.sti`` finds ``job.mas``,
``job.dof`` and the deck ``job.inp`` beside it, free and ``*BOUNDARY``-constrained.

References: the eigenfrequencies CalculiX itself printed for the same decks (``*_modes.dat`` of
``tests/data/calculix_c3d20_block``, 7 significant digits), the matrices as a plain numpy parse
of the files, the fixed dofs as the deck's ``*BOUNDARY`` lines say them. Every mistake (a missing
file, a ``.dof`` of another run, a shifted map, a truncated matrix) is exit 2 with one line.
"""

from __future__ import annotations

import gzip
import json
import lzma
import re
import shutil
from pathlib import Path

import numpy as np
import pytest
import scipy.linalg
import scipy.sparse

import pymorembs as pm
from info_runs import info_facts, refused
from pymorembs.errors import UserError
from pymorembs.io import calculix, detect_format, fast_text, read_body
from pymorembs.job.cli import main

DATA = Path(__file__).parents[1] / "data" / "calculix_c3d20_block"


def ccx_frequencies(name: str) -> tuple[np.ndarray, np.ndarray]:
    """Mode numbers and frequencies (cycles/time) of a CalculiX ``.dat`` eigenvalue table."""
    text = (DATA / f"{name}_modes.dat").read_text()
    table = text.split("E I G E N V A L U E   O U T P U T", 1)[1].split("P A R T I C", 1)[0]
    rows = re.findall(r"^\s+(\d+)\s+(\S+)\s+(\S+)\s+(\S+)\s+(\S+)\s*$", table, flags=re.M)
    modes = np.array([int(r[0]) for r in rows])
    return modes, np.array([float(r[3]) for r in rows])


def printed_tolerance(values: np.ndarray) -> np.ndarray:
    """Half a unit of the 7th significant digit CalculiX prints (``0.5148680E+04``)."""
    return 0.5 * 10.0 ** (np.floor(np.log10(values)) - 6)


def dense_file(path: Path, n: int) -> np.ndarray:
    """A CalculiX triangle file as the full dense matrix, parsed with plain numpy."""
    rows, cols, values = np.loadtxt(path, unpack=True)
    rows, cols = rows.astype(int) - 1, cols.astype(int) - 1
    matrix = np.zeros((n, n))
    matrix[rows, cols] = values
    matrix[cols, rows] = values
    return matrix


@pytest.fixture
def export(tmp_path: Path) -> Path:
    """A copy of the data set to change."""
    target = tmp_path / "calculix"
    shutil.copytree(DATA, target)
    return target


# ============================================================================ genuine exports
def test_free_export_gives_calculix_frequencies_and_six_rigid_body_modes(capsys):
    facts = info_facts(capsys, DATA / "free.sti")
    assert facts["n_dof"] == 96 and facts["n_fixed"] == 0 and facts["has_coordinates"]
    assert facts["rigid_body_modes"] == 6 and facts["mechanisms"] == 0
    modes, expected = ccx_frequencies("free")
    np.testing.assert_array_equal(modes, np.arange(7, 13))  # 1-6 are the rigid-body modes
    found = np.array(facts["eigenfrequencies_hz"][6:12])
    assert np.all(np.abs(found - expected) <= printed_tolerance(expected)), (found, expected)
    proof = facts["consistency"]["map"]
    assert proof["status"] == "map proved" and proof["rows_near_supports"] == 0, proof
    assert "leave no force in 96 of 96 rows" in proof["reason"], proof


def test_constrained_export_gives_calculix_frequencies(capsys):
    facts = info_facts(capsys, DATA / "fixed.sti")
    assert facts["n_dof"] == 96 and facts["n_fixed"] == 11  # 85 equations + 11 fixed dofs
    assert facts["rigid_body_modes"] == 0 and facts["mechanisms"] == 0
    modes, expected = ccx_frequencies("fixed")
    np.testing.assert_array_equal(modes, np.arange(1, 13))
    found = np.array(facts["eigenfrequencies_hz"][:12])
    assert np.all(np.abs(found - expected) <= printed_tolerance(expected)), (found, expected)
    proof = facts["consistency"]["map"]
    assert proof["status"] == "map proved" and "in 36 of 85 rows" in proof["reason"], proof


def test_read_gives_the_files_matrices_and_the_decks_fixed_dofs():
    body = pm.read(DATA / "fixed.sti")
    dofs = np.loadtxt(DATA / "fixed.dof", dtype=str)
    n = dofs.size
    np.testing.assert_array_equal(body.dofs.nodes[:n], [int(d.split(".")[0]) for d in dofs])
    np.testing.assert_array_equal(body.dofs.directions[:n], [int(d[-1]) - 1 for d in dofs])
    for name, matrix in (("sti", body.stiffness), ("mas", body.mass)):
        full = matrix.toarray()
        np.testing.assert_array_equal(full[:n, :n], dense_file(DATA / f"fixed.{name}", n))
        assert not np.any(full[n:]) and not np.any(full[:, n:])  # fixed: empty rows, columns
    # *BOUNDARY: NFIX, 1 (the nodes at x = 0) / 103, 2, 3 / 118, 3
    at_x0 = [103, 118, 127, 142, 151, 160, 175, 184]
    expected = {(node, 0) for node in at_x0} | {(103, 1), (103, 2), (118, 2)}
    fixed = set(zip(body.dofs.nodes[body.fixed], body.dofs.directions[body.fixed], strict=True))
    assert fixed == expected
    np.testing.assert_array_equal(body.fixed, np.arange(n, n + 11))
    # coordinates: the deck's *NODE lines (listed in reverse label order there)
    deck = {}
    for line in (DATA / "fixed.inp").read_text().split("*ELEMENT")[0].splitlines()[3:]:
        label, *xyz = line.split(",")
        deck[int(label)] = [float(v) for v in xyz]
    np.testing.assert_array_equal(body.coordinates, [deck[int(i)] for i in body.node_ids])
    assert body.mesh is not None and body.surface is not None


def test_frequencies_of_the_read_body_match_a_dense_solution_of_the_files():
    """Independent: the files parsed by numpy, the generalised eigenproblem solved densely."""
    body = pm.read(DATA / "free.sti")
    k, m = dense_file(DATA / "free.sti", 96), dense_file(DATA / "free.mas", 96)
    expected = np.sqrt(np.abs(scipy.linalg.eigh(k, m, eigvals_only=True)[6:12])) / (2 * np.pi)
    found = np.sqrt(
        np.abs(scipy.linalg.eigh(body.stiffness.toarray(), body.mass.toarray())[0][6:12])
    ) / (2 * np.pi)
    np.testing.assert_allclose(found, expected, rtol=1e-12)


def test_detection_and_the_other_ways_to_name_the_files(tmp_path):
    assert detect_format(DATA / "free.sti") == "calculix"
    assert detect_format(DATA / "free.dof") == "calculix"
    reference = read_body(file=DATA / "free.sti")
    for options in (
        {"format": "calculix", "file": DATA / "free.sti"},
        {"stiffness": DATA / "free.sti", "mass": DATA / "free.mas"},
        {"file": DATA / "free.sti", "nodes": DATA / "free.inp"},
        {"file": DATA / "free.sti", "inp": DATA / "free.inp", "dofs": DATA / "free.dof"},
    ):
        fmt = options.pop("format", None)
        body = read_body(format=fmt, **options)
        assert (body.stiffness != reference.stiffness).nnz == 0
        np.testing.assert_array_equal(body.coordinates, reference.coordinates)
    # the files under other names, given one by one
    for suffix in ("sti", "mas", "dof", "inp"):
        shutil.copy(DATA / f"free.{suffix}", tmp_path / f"other_{suffix}.txt")
    body = read_body(
        format="calculix",
        file=tmp_path / "other_sti.txt",
        mass=tmp_path / "other_mas.txt",
        dofs=tmp_path / "other_dof.txt",
        inp=tmp_path / "other_inp.txt",
    )
    assert (body.mass != reference.mass).nnz == 0


def test_the_compiled_parse_gives_the_same_matrices(monkeypatch):
    """Large files go through the compiled kernel: the same matrices as the NumPy parse."""
    plain = read_body(file=DATA / "fixed.sti")
    monkeypatch.setattr(calculix, "COMPILED_FROM_BYTES", 0)
    compiled = read_body(file=DATA / "fixed.sti")
    for a, b in ((plain.stiffness, compiled.stiffness), (plain.mass, compiled.mass)):
        assert a.shape == b.shape and (a != b).nnz == 0
        np.testing.assert_array_equal(a.indices, b.indices)


#: Every CalculiX export committed under tests/data (directory, job).
EXPORTS = [
    ("calculix_c3d20_block", "fixed"),
    ("calculix_c3d20_block", "free"),
    ("calculix_map_check", "clamped"),
    ("calculix_map_check", "free"),
    *(("calculix_stress_parts", job) for job in ("bar", "bar8", "barr", "plate", "plate4")),
]


def plain_csr(path: Path, n: int) -> scipy.sparse.csr_matrix:
    """A CalculiX triangle file parsed with ``np.loadtxt`` and mirrored by SciPy, without its
    zeros: the reference the reader must equal bit for bit."""
    rows, cols, values = np.loadtxt(path, unpack=True)
    rows, cols = rows.astype(np.int64) - 1, cols.astype(np.int64) - 1
    off = rows != cols
    full = scipy.sparse.coo_matrix(
        (np.r_[values, values[off]], (np.r_[rows, cols[off]], np.r_[cols, rows[off]])),
        shape=(n, n),
    ).tocsr()
    full.eliminate_zeros()
    full.sort_indices()
    return full


@pytest.mark.parametrize(("folder", "job"), EXPORTS)
def test_the_compiled_parse_reads_every_export_bit_for_bit(tmp_path, monkeypatch, folder, job):
    """Every committed export through the compiled kernel (zeros left out while parsing, the
    triangle completed in its room): the matrices of a plain ``loadtxt`` parse, to the last
    bit, with the fixed dofs' empty rows after them; the room holds no memory beyond them."""
    if not fast_text.compiled_checks():
        pytest.skip("needs Numba")
    source = Path(__file__).parents[1] / "data" / folder
    for suffix in ("sti", "mas", "dof", "inp"):  # decompressed: the kernel maps plain files
        plain = source / f"{job}.{suffix}"
        packed = [p for p in source.glob(f"{job}.{suffix}.*") if p.suffix in (".gz", ".xz")]
        opener = {".gz": gzip.open, ".xz": lzma.open}
        data = plain.read_bytes() if plain.exists() else opener[packed[0].suffix](packed[0]).read()
        (tmp_path / f"{job}.{suffix}").write_bytes(data)
    monkeypatch.setattr(calculix, "COMPILED_FROM_BYTES", 0)

    def no_strict_pass(*args):
        raise AssertionError("the compiled parse refused a genuine export")

    monkeypatch.setattr(calculix, "_parse_strictly", no_strict_pass)
    body = calculix.read_calculix(tmp_path / f"{job}.sti")
    n = len((tmp_path / f"{job}.dof").read_text().split())
    for suffix, matrix in (("sti", body.stiffness), ("mas", body.mass)):
        expected = plain_csr(tmp_path / f"{job}.{suffix}", n)
        nnz = expected.nnz
        np.testing.assert_array_equal(matrix.indptr[: n + 1], expected.indptr)
        assert np.all(matrix.indptr[n:] == nnz)  # the fixed dofs: empty rows
        np.testing.assert_array_equal(matrix.indices, expected.indices)
        np.testing.assert_array_equal(matrix.data.view(np.uint64), expected.data.view(np.uint64))
        assert matrix.indices.size == matrix.data.size == nnz


def test_a_job_names_the_export_by_its_sti_file(tmp_path, capsys):
    job = tmp_path / "job.toml"
    job.write_text(
        f'[model]\nfile = "{(DATA / "fixed.sti").as_posix()}"\n\n[frame]\ntype = "none"\n\n'
        '[[inputs]]\nnode = 196\ndirections = "ux uy uz"\n\n[band]\nf_max_hz = 2000\n\n'
        '[[reduction]]\nname = "krylov"\nmethod = "krylov"\nexpansion_points_hz = [0, 1000]\n'
        'order = 24\n\n[export]\noutputs = ["npz"]\n'
    )
    facts = info_facts(capsys, job, modes=3)
    _, expected = ccx_frequencies("fixed")
    found = np.array(facts["eigenfrequencies_hz"][:3])
    assert np.all(np.abs(found - expected[:3]) <= printed_tolerance(expected[:3]))


@pytest.mark.slow
def test_a_job_on_the_export_reduces(tmp_path, capsys):
    job = tmp_path / "job.toml"
    for suffix in ("sti", "mas", "dof", "inp"):
        shutil.copy(DATA / f"fixed.{suffix}", tmp_path / f"fixed.{suffix}")
    job.write_text(
        '[model]\nfile = "fixed.sti"\n\n[frame]\ntype = "none"\n\n'
        '[[inputs]]\nnode = 196\ndirections = "ux uy uz"\n\n[band]\nf_max_hz = 2000\n'
        'points = 200\n\n[[reduction]]\nname = "krylov"\nmethod = "krylov"\n'
        'expansion_points_hz = [0, 1000]\norder = 24\n\n[export]\noutputs = ["npz"]\n'
    )
    code = main(["reduce", str(job), "--out", str(tmp_path / "out"), "--quiet"])
    assert code == 0, capsys.readouterr().err
    summary = json.loads((tmp_path / "out" / "summary.json").read_text())
    assert (tmp_path / "out" / "krylov" / "reduced.npz").is_file()
    assert summary["reductions"][0]["max_rel_error"] < 1e-8


# ============================================================================ mistakes
def test_a_missing_mass_or_dof_file_is_one_line(export, capsys):
    (export / "free.mas").unlink()
    line = refused(capsys, export / "free.sti")
    assert re.match(r".*free\.mas: not found beside free\.sti: the mass matrix", line), line
    (export / "fixed.dof").unlink()
    line = refused(capsys, export / "fixed.sti")
    assert re.match(r".*fixed\.dof: not found beside fixed\.sti: the dof of every", line), line
    (export / "fixed.inp").unlink()
    line = refused(capsys, export / "fixed.sti", "--dofs", export / "free.dof")
    assert "fixed.inp: not found beside fixed.sti: the input deck" in line


def test_the_dof_file_of_another_run_is_one_line(capsys):
    line = refused(capsys, DATA / "free.sti", "--dofs", DATA / "fixed.dof")
    assert re.search(r"fixed\.dof: 11 dofs of the elements of free\.inp .* have no equation", line)
    line = refused(capsys, DATA / "fixed.sti", "--dofs", DATA / "free.dof")
    assert re.search(
        r"free\.dof:1: node 103 ux has an equation, but \*BOUNDARY \(fixed\.inp:\d+\)", line
    )


@pytest.mark.parametrize("name", ["free", "fixed"])
def test_a_map_shifted_by_one_node_is_refused(export, capsys, name):
    """The same dofs in another order: only the consistency checks can tell, and they do (the
    rigid-body fields for the free body, the rigid-body mass already for the fixed one)."""
    lines = (export / f"{name}.dof").read_text().split()
    (export / f"{name}.dof").write_text("\n".join(lines[3:] + lines[:3]) + "\n")
    line = refused(capsys, export / f"{name}.sti")
    expected = {
        "free": r"\[model\]: this map does not fit K: in \d+ of 96 rows away from the supports",
        "fixed": r"\[model\]: the mass matrix does not fit the dof table: the rigid translations",
    }[name]
    assert re.search(expected, line), line


def test_a_dof_file_naming_nodes_the_deck_lacks_is_refused(export, capsys):
    text = (export / "free.dof").read_text()
    (export / "free.dof").write_text(text.replace("196.3", "199.3"))
    line = refused(capsys, export / "free.sti")
    assert re.search(r"free\.dof:96: node 199 is not defined in free\.inp", line), line
    (export / "free.dof").write_text(text.replace("106.2", "106.2 x"))
    line = refused(capsys, export / "free.sti")
    assert re.search(r"free\.dof:5: '106\.2 x' is not node\.direction", line), line
    (export / "free.dof").write_text(text.replace("106.2", "106.1"))
    line = refused(capsys, export / "free.sti")
    assert re.search(r"free\.dof:5: node 106 ux is listed again \(first on line 4\)", line), line


def test_matrices_of_another_run_are_refused(export, capsys):
    shutil.copy(DATA / "fixed.mas", export / "free.mas")  # 85 equations for the 96 of free.dof
    line = refused(capsys, export / "free.sti")
    assert re.search(r"free\.mas: no diagonal entry for equation 86 .* of free\.dof", line), line
    shutil.copy(DATA / "free.sti", export / "fixed.sti")  # 96 equations for the 85 of fixed.dof
    line = refused(capsys, export / "fixed.sti")
    assert re.search(r"fixed\.sti:\d+: entry \(\d+, 86\) lies outside the 85 equations", line)
    cut = (DATA / "free.sti").read_text()[:-200]  # a truncated file: its last line cut short
    (export / "free.sti").write_text(cut[: cut.rfind(" ")])
    shutil.copy(DATA / "free.mas", export / "free.mas")
    line = refused(capsys, export / "free.sti")
    assert re.search(r"free\.sti:\d+: 2 values, expected 3", line), line


def test_a_dof_eliminated_by_a_constraint_is_refused(export, capsys):
    """A dof without equation that no *BOUNDARY fixes (as *EQUATION leaves it) is not guessed."""
    deck = (export / "fixed.inp").read_text()
    (export / "fixed.inp").write_text(deck.replace("118, 3\n", ""))
    line = refused(capsys, export / "fixed.sti")
    expected = r"fixed\.dof: node 118 uz of the elements of fixed\.inp has no equation, and no "
    assert re.search(expected + r"\*BOUNDARY fixes it", line), line


def test_element_types_calculix_expands_are_refused(export):
    deck = (export / "free.inp").read_text()
    (export / "free.inp").write_text(deck.replace("TYPE=C3D20", "TYPE=S8R"))
    with pytest.raises(UserError, match=r"free\.inp:\d+: element type S8R: CalculiX expands"):
        read_body(file=export / "free.sti")


def test_the_other_files_of_an_export_point_to_the_sti(capsys):
    assert re.match(
        r".*free\.mas: the mass matrix of a CalculiX export; give the stiffness file free\.sti",
        refused(capsys, DATA / "free.mas"),
    )
    assert "the dof file of a CalculiX export" in refused(capsys, DATA / "free.dof")
    line = refused(capsys, DATA / "free.inp")
    assert "the input deck of a CalculiX export; give its stiffness file free.sti" in line
