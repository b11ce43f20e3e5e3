"""Genuine Abaqus ``*MATRIX OUTPUT, FORMAT=COORDINATE`` exports with their input files.

Files (``tests/data``, see each SOURCE.md): Abaqus/CAE 2021 blocks of Exudyn (C3D4 with K and M,
C3D20R with K only; input files with parts and one instance) and the clamped C3D10 beam of
JuliaFEM (``*Boundary`` in the matrix step: 1e36 penalty diagonals). No source publishes
frequencies, so every reference is computed here independently: the files are parsed with plain
numpy into dense matrices (equation ``3 (node - 1) + dof``, the Exudyn convention) and solved
with dense ``scipy.linalg.eigh``.
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
import scipy.linalg as sl
from threadpoolctl import threadpool_limits

from abaqus_models import genuine, read_coordinate_file
from pymorembs.errors import UserError
from pymorembs.io.abaqus import read_abaqus, read_abaqus_stiffness
from pymorembs.io.formats import read_body
from pymorembs.preparation.consistency import body_rounding, check_map

BLOCKS = "exudyn_abaqus_blocks"
BEAM = "juliafem_abaqus_tetra_beam"


@pytest.fixture(scope="module")
def unpacked(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return tmp_path_factory.mktemp("genuine")


def frequencies(k: np.ndarray, m: np.ndarray, count: int) -> np.ndarray:
    """The lowest ``count`` eigenfrequencies (Hz) of a dense pencil, negative roots as zero."""
    with threadpool_limits(1):  # one BLAS thread: several times faster on the shared 2 cores
        values = sl.eigh(k, m, eigvals_only=True, driver="gv")[:count]
    return np.sqrt(np.maximum(values, 0.0)) / (2 * np.pi)


def test_block_c3d4_stiffness_and_mass(unpacked: Path) -> None:
    k_path = genuine(f"{BLOCKS}/blockC3D4_STIF1.mtx", unpacked)
    m_path = genuine(f"{BLOCKS}/blockC3D4_MASS1.mtx", unpacked)
    inp = genuine(f"{BLOCKS}/blockC3D4.inp", unpacked)
    body = read_body(stiffness=k_path, mass=m_path, inp=inp)
    assert body.name == "blockC3D4"
    assert body.n_dof == 642 and body.stiffness.nnz == 22042 and body.mass.nnz == 642
    assert body.dofs.describe() == "214 nodes x ux uy uz"
    np.testing.assert_array_equal(body.dofs.nodes, np.repeat(np.arange(1, 215), 3))
    np.testing.assert_array_equal(body.dofs.directions, np.tile([0, 1, 2], 214))
    k, m = read_coordinate_file(k_path, 642), read_coordinate_file(m_path, 642)
    np.testing.assert_array_equal(body.stiffness.toarray(), k)  # the file as it stands
    np.testing.assert_array_equal(body.mass.toarray(), m)
    assert np.array_equal(k, k.T) and body.fixed.size == 0 and body.has_coordinates
    # coordinates: the *Node lines under *Instance, name=block-1 (not moved)
    np.testing.assert_array_equal(body.node_position(1), [4.0, 1.0, 1.0])
    np.testing.assert_array_equal(body.node_position(214), [0.979166746, 0.149305627, 0.743850052])
    residuals = body.rigid_body_residuals()
    assert np.all(residuals < 1e-15), residuals
    assert (
        "dof table: 214 nodes x ux uy uz in the *NODE order of blockC3D4.inp (elements C3D4)"
        in (body.notes)
    )
    proof = check_map(body, body_rounding(body))  # the one proof (the reader writes none)
    assert proof.proved and "leave no force in 642 of 642 rows" in proof.reason, proof
    assert any("instance: block-1 of part block not moved" in note for note in body.notes)
    # independent spectrum of the free block: 6 rigid modes, then the elastic ones
    f = frequencies(k, m, 16)  # (the matrices of the body are these, see above)
    assert np.all(f[:6] < 1e-5 * f[6]) and f[6] > 400.0


def test_block_c3d20r_stiffness_only(unpacked: Path) -> None:
    k_path = genuine(f"{BLOCKS}/blockC3D20R_STIF1.mtx", unpacked)
    inp = genuine(f"{BLOCKS}/blockC3D20R.inp", unpacked)
    with pytest.raises(UserError) as err:
        read_abaqus(k_path, inp=inp)
    message = str(err.value)
    assert "\n" not in message and message.startswith(f"{k_path}: no mass file given")
    body = read_abaqus_stiffness(k_path, inp=inp)
    assert body.n_dof == 513 and body.stiffness.nnz == 52799 and body.mass.nnz == 0
    assert body.dofs.describe() == "171 nodes x ux uy uz"
    k = read_coordinate_file(k_path, 513)
    np.testing.assert_array_equal(body.stiffness.toarray(), k)
    assert np.all(body.rigid_body_residuals() < 1e-15)
    assert any("no mass matrix" in note for note in body.notes)
    # independently: K is positive semidefinite with exactly the six rigid-body modes
    with threadpool_limits(1):
        values = np.linalg.eigvalsh(k)
    assert np.all(values[:6] < 1e-12 * values[-1]) and values[6] > 1e-6 * values[-1]


def test_clamped_beam_with_penalty_diagonals(unpacked: Path) -> None:
    k_path = genuine(f"{BEAM}/STIF1_coord_style.mtx", unpacked)
    m_path = genuine(f"{BEAM}/MASS1_coord_style.mtx", unpacked)
    inp = genuine(f"{BEAM}/abq_beam.inp", unpacked)
    body = read_abaqus(k_path, m_path, inp=inp)
    assert body.n_dof == 1554 and body.dofs.describe() == "518 nodes x ux uy uz"
    k, m = read_coordinate_file(k_path, 1554), read_coordinate_file(m_path, 1554)
    penalty = np.flatnonzero(np.diag(k) == 1e36)
    # the nset "fixed" of abq_beam.inp, dofs 1-3 (*Boundary in the matrix step)
    clamped = np.array([3, 4, 6, 7, 293, 395, 511, 512, 514])
    np.testing.assert_array_equal(penalty, (3 * (clamped[:, None] - 1) + np.arange(3)).ravel())
    np.testing.assert_array_equal(body.fixed, penalty)
    note = next(n for n in body.notes if "penalty" in n)
    assert note.startswith("27 dofs of 9 nodes fixed in the matrix step (*BOUNDARY, 1e36 penalty")
    # everything but the penalty diagonal is the file as it stands
    got = body.stiffness.toarray()
    off = ~np.eye(1554, dtype=bool)
    np.testing.assert_array_equal(got[off], k[off])
    free = np.setdiff1d(np.arange(1554), penalty)
    np.testing.assert_array_equal(np.diag(got)[free], np.diag(k)[free])
    np.testing.assert_array_equal(body.mass.toarray(), m)
    # the rebuilt diagonal: a rigid translation gives no force in the row (computed here)
    direction = np.arange(1554) % 3
    for i in penalty:
        same = (direction == direction[i]) & (np.arange(1554) != i)
        assert got[i, i] == pytest.approx(-k[i, same].sum(), rel=1e-12)
    # so the rebuilt K is the free-free stiffness: six rigid-body modes (on every row now) and
    # positive semidefinite (K + 1e-12 |K| I has a Cholesky factor)
    rigid = replace(body, fixed=np.zeros(0, dtype=np.int64)).rigid_body_residuals()
    assert np.all(rigid < 1e-15), rigid
    with threadpool_limits(1):
        sl.cholesky(got + 1e-12 * np.abs(got).max() * np.eye(1554))
    # the clamped body is the file's free rows and columns (equal above); its frequencies
    reference = frequencies(k[np.ix_(free, free)], m[np.ix_(free, free)], 10)
    assert 60.0 < reference[0] < 70.0  # first bending mode of the 500 mm cantilever


def test_the_proof_picks_the_node_order_or_refuses(unpacked: Path, tmp_path: Path) -> None:
    """The genuine C3D4 matrices with edited input files: which node order fits is proved."""
    k_path = genuine(f"{BLOCKS}/blockC3D4_STIF1.mtx", unpacked)
    m_path = genuine(f"{BLOCKS}/blockC3D4_MASS1.mtx", unpacked)
    lines = genuine(f"{BLOCKS}/blockC3D4.inp", unpacked).read_text().split("\n")
    start = lines.index("*Node") + 1
    end = next(k for k in range(start, len(lines)) if lines[k].startswith("*"))
    nodes = lines[start:end]

    def variant(file_name: str, node_lines: list[str]) -> Path:
        path = tmp_path / file_name
        path.write_text("\n".join([*lines[:start], *node_lines, *lines[end:]]))
        return path

    def note(body: object) -> str:
        return next(n for n in body.notes if n.startswith("dof table"))  # type: ignore[attr-defined]

    # nodes listed last to first: only the order of the labels fits
    body = read_abaqus(k_path, m_path, inp=variant("reversed.inp", nodes[::-1]))
    assert "in the order of labels in each instance of reversed.inp" in note(body)
    np.testing.assert_array_equal(body.dofs.nodes[:3], [1, 1, 1])
    # coordinates of nodes 1 and 2 exchanged: no order fits
    label_1, rest_1 = nodes[0].split(",", 1)
    label_2, rest_2 = nodes[1].split(",", 1)
    exchanged = [f"{label_1},{rest_2}", f"{label_2},{rest_1}", *nodes[2:]]
    with pytest.raises(UserError) as err:
        read_abaqus(k_path, m_path, inp=variant("exchanged.inp", exchanged))
    message = str(err.value)
    assert "\n" not in message
    assert message.startswith(f"{k_path}: the equation order derived from exchanged.inp does "
                              "not fit the matrices: rigid-body residual")  # fmt: skip
    assert message.endswith("give the dof of every equation as dofs (a dofs.csv with header "
                            "node,direction)")  # fmt: skip
