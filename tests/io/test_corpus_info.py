"""``pymorembs info`` on every genuine export of the corpus (issue #14, "Done when").

For each set: the exact command line a user types, the rigid-body count, and the eigenfrequencies
against the values the source publishes, or -- where it publishes none -- against a dense
solution computed here from an independent parse of the files (plain numpy; massless directions
condensed exactly; ``tests/nastran_reference.py``). Tolerances:

* exact exports (binary doubles, 14-17 digit text): 1e-6 relative;
* published tables: the rounding of the printed value (half a unit of its last digit), at
  least 1e-6;
* a rounded export (the mAEWing1 punch, 10 significant digits): the first-order bound that
  the rounding of the punched entries puts on each frequency, which ``info`` reports with it;
  the f06 values (of the unrounded model) lie within it (mode 7: 0.3 % off, bound 2 %).

Files that hold no K and M say so in one line (exit 2).
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from abaqus_models import genuine, read_coordinate_file
from nastran_reference import dense_frequencies, dense_matrix, dmig_entries, f06_cycles
from pymorembs.job.cli import main

DATA = Path(__file__).parents[1] / "data"
MAEWING = DATA / "exportnastrankm_mAEWing1_FEMv5p2"
YETI = DATA / "pyyeti_nx_extseout"
PYNASTRAN = DATA / "pynastran"


def info(capsys, *args: str | Path, modes: int = 10) -> dict:
    code = main(["info", *map(str, args), "--modes", str(modes), "--json"])
    captured = capsys.readouterr()
    assert code == 0, captured.err
    return json.loads(captured.out)


def elastic(facts: dict) -> np.ndarray:
    zero = facts["rigid_body_modes"] + facts["mechanisms"]
    return np.array(facts["eigenfrequencies_hz"][zero:])


def published_tolerance(values: list[float], digits_after_point: int) -> np.ndarray:
    """Half a unit of the printed last digit, relative, at least 1e-6."""
    return np.maximum(0.5 * 10.0**-digits_after_point / np.abs(values), 1e-6)


# ------------------------------------------------------------------------------------ Ansys
def test_ansys_hexbeam_full_with_archive(capsys):
    """Published by the ansys-mapdl-reader docs: 1283.200, 1283.200, 5781.975, 6919.399 Hz."""
    hexbeam = DATA / "pymapdl_reader_hexbeam"
    facts = info(capsys, hexbeam / "file.full", "--nodes", hexbeam / "HexBeam.cdb", modes=4)
    assert facts["rigid_body_modes"] == 0 and facts["n_fixed"] == 63
    assert facts["has_coordinates"]
    published = [1283.200, 1283.200, 5781.975, 6919.399]
    assert np.all(
        np.abs(elastic(facts) - published) <= published_tolerance(published, 3) * published
    )


# ----------------------------------------------------------------------------------- Abaqus
def _abaqus_dense(stiffness: Path, mass: Path) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """K, M (dense, equation 3 (node - 1) + dof) and the penalty-free equations."""
    n = int(np.loadtxt(stiffness, usecols=0).max())
    k = read_coordinate_file(stiffness, n)
    m = read_coordinate_file(mass, n)
    free = np.flatnonzero(np.diag(k) < 1e30)
    return k, m, free


def test_abaqus_block_c3d4_free(capsys, tmp_path):
    k_path = genuine("exudyn_abaqus_blocks/blockC3D4_STIF1.mtx", tmp_path)
    m_path = genuine("exudyn_abaqus_blocks/blockC3D4_MASS1.mtx", tmp_path)
    inp = genuine("exudyn_abaqus_blocks/blockC3D4.inp", tmp_path)
    facts = info(capsys, "--stiffness", k_path, "--mass", m_path, "--inp", inp)
    assert facts["rigid_body_modes"] == 6 and facts["mechanisms"] == 0
    assert facts["rigid_body_decision"]["decided_by"] == "geometry"
    assert facts["dof_table"] == "214 nodes x ux uy uz"
    k, m, _ = _abaqus_dense(k_path, m_path)
    reference = dense_frequencies(k, m)
    assert np.all(np.abs(reference[:6]) < 1e-5 * reference[6])  # dense: ~1e-6 noise
    np.testing.assert_allclose(elastic(facts), reference[6:16], rtol=1e-6)


def test_abaqus_tetra_beam_clamped_by_penalties(capsys, tmp_path):
    k_path = genuine("juliafem_abaqus_tetra_beam/STIF1_coord_style.mtx", tmp_path)
    m_path = genuine("juliafem_abaqus_tetra_beam/MASS1_coord_style.mtx", tmp_path)
    inp = genuine("juliafem_abaqus_tetra_beam/abq_beam.inp", tmp_path)
    facts = info(capsys, "--stiffness", k_path, "--mass", m_path, "--inp", inp)
    assert facts["rigid_body_modes"] == 0 and facts["n_fixed"] == 27
    k, m, free = _abaqus_dense(k_path, m_path)
    reference = dense_frequencies(k[np.ix_(free, free)], m[np.ix_(free, free)])
    np.testing.assert_allclose(elastic(facts), reference[:10], rtol=1e-6)


@pytest.mark.parametrize(
    ("name", "rigid", "mechanisms"),
    [("symmetric/inner", 6, 0), ("symmetric/total", 6, 0), ("recovery/interface-beam-sub", 6, 6)],
)
def test_abaqus_substructures(capsys, tmp_path, name, rigid, mechanisms):
    """Reduced matrices without coordinates: counted by the spectrum (the file has 14 digits)."""
    path = genuine(f"abaqus_mtx_parser/{name}.mtx", tmp_path)
    facts = info(capsys, path, modes=6)
    assert facts["rigid_body_modes"] == rigid and facts["mechanisms"] == mechanisms
    assert facts["rigid_body_decision"]["decided_by"] == "spectrum"
    assert not facts["has_coordinates"]
    from pymorembs.io.abaqus_substructure import read_abaqus_substructure

    body = read_abaqus_substructure(path)  # its parse is checked in its own tests
    reference = dense_frequencies(body.stiffness.toarray(), body.mass.toarray())
    nonzero = reference[rigid + mechanisms :]
    np.testing.assert_allclose(elastic(facts), nonzero[: elastic(facts).size], rtol=1e-6)


# ---------------------------------------------------------------------------------- Nastran
def test_nastran_maewing1_punch_with_f06_coordinates(capsys):
    """MSC 2013 DMIGPCH (10 digits, 34 massless dofs), free aircraft: 6 rigid-body modes."""
    punch = MAEWING / "sol103_maewing1_femv5p2.pch1"
    f06 = MAEWING / "sol103_maewing1_femv5p2.f06"
    facts = info(capsys, punch, "--nodes", f06, modes=8)
    assert facts["rigid_body_modes"] == 6 and facts["mechanisms"] == 0
    assert facts["rigid_body_decision"]["decided_by"] == "geometry"
    assert "the spectrum agrees" in facts["rigid_body_decision"]["explanation"]
    assert facts["massless"]["dofs_without_mass"] == 34
    assert facts["rounding"].startswith("10 significant digits")
    published = np.array(f06_cycles(f06)[6:14])
    assert published[0] == pytest.approx(7.808318)
    computed, bound = elastic(facts), np.array(facts["eigenfrequency_bounds_hz"][6:])
    assert np.all(np.abs(computed - published) <= bound)
    assert np.all(bound < 0.021 * published)  # the bound says something (2 % at most)
    assert np.all(np.abs(computed[1:] - published[1:]) < 1e-3 * published[1:])


def test_nastran_maewing1_punch_without_coordinates(capsys):
    """No coordinates: the spectrum decides, and still finds the six rigid-body modes."""
    facts = info(capsys, MAEWING / "sol103_maewing1_femv5p2.pch1", modes=4)
    assert (
        facts["rigid_body_modes"] == 6 and facts["rigid_body_decision"]["decided_by"] == "spectrum"
    )
    assert not facts["has_coordinates"] and facts["units"]["system"] == "unknown"
    published = np.array(f06_cycles(MAEWING / "sol103_maewing1_femv5p2.f06")[6:10])
    bound = np.array(facts["eigenfrequency_bounds_hz"][6:])
    assert np.all(np.abs(elastic(facts) - published) <= bound)


def test_nastran_dmig_chain(capsys):
    """pyNastran's EXTOUT punch: a free 1-D spring-mass chain of 15 grids (component 1)."""
    punch = PYNASTRAN / "dmig_pch" / "dmig.pch"
    facts = info(capsys, punch, modes=8)
    assert facts["rigid_body_modes"] == 1
    k_entries, m_entries = dmig_entries(punch, "KAAX"), dmig_entries(punch, "MAAX")
    keys = sorted({key[:2] for key in (*k_entries, *m_entries)})
    reference = dense_frequencies(dense_matrix(k_entries, keys), dense_matrix(m_entries, keys))
    assert abs(reference[0]) < 1e-5 * reference[1]
    np.testing.assert_allclose(elastic(facts), reference[1:9], rtol=1e-6)


@pytest.mark.parametrize(
    ("op4", "dofs", "marker", "skip", "count"),
    [
        ("inboard.op4", "inboard.pch", "(AFTER AUGMENTATION OF RESIDUAL VECTORS)", 0, 8),
        ("outboard.op4", "outboard.pch", None, None, 16),
    ],
)
def test_nastran_craig_bampton_superelements(capsys, op4, dofs, marker, skip, count):
    """NX 9 EXTSEOUT: the fixed-interface modes equal those of the .out (7 printed digits)."""
    facts = info(capsys, YETI / op4, "--dofs", YETI / dofs, modes=6)
    assert facts["rigid_body_modes"] == 6
    if marker is None:  # outboard.out is not copied: its table, line 599 ff.
        published = [
            1.650001, 1.650249, 1.674265, 1.674687, 7.025350, 7.025411, 10.91274, 10.91454,
            13.98578, 13.99172, 25.13473, 25.13995, 42.17271, 42.19338, 46.71595, 46.89473,
        ]  # fmt: skip
    else:
        published = f06_cycles(YETI / "inboard.out", marker, skip)[:count]
    fixed = np.array(facts["fixed_interface_hz"][:count])
    np.testing.assert_allclose(fixed, published, rtol=1e-6)


@pytest.mark.parametrize(
    ("args", "rigid"),
    [
        (
            (
                "superelement_se_test_n11/se_test_n11.op4",
                "--dofs",
                "superelement_se_test_n11/se_test_n11.pch",
            ),
            6,
        ),
        (("extse_op4/extse10.op4",), 6),
    ],
    ids=["se_test_n11", "extse10"],
)
def test_nastran_op4_superelements_against_a_dense_solution(capsys, args, rigid):
    from pymorembs.io.formats import read_body

    paths = [a if a.startswith("--") else PYNASTRAN / a for a in args]
    facts = info(capsys, *paths, modes=6)
    assert facts["rigid_body_modes"] == rigid
    options = {"file": paths[0]} | ({"dofs": paths[2]} if len(paths) > 2 else {})
    body = read_body(**options)  # order and CD rotation are checked in the reader tests
    free = np.setdiff1d(np.arange(body.n_dof), body.fixed)
    k = body.stiffness[free][:, free].toarray()
    m = body.mass[free][:, free].toarray()
    raw = dense_frequencies(k, m)
    # se_test_n11 is single precision (OP4 type 1): its rigid-body modes come out at 0.1 Hz, so
    # the elastic ones are compared in the mass-orthogonal complement of the rigid-body fields
    # (as info computes them: Galerkin), which takes their rounding-made coupling out
    assert np.all(np.abs(raw[:rigid]) < 2e-3 * raw[rigid])
    fields = body.rigid_body_modes(body.coordinates.mean(axis=0))[free] if body.n_nodes else None
    # massless directions: the mass eigenvalues from 1e-8 to 1e-6 of the largest are rounding
    # noise of single precision (the count stays 9 over that range, as info finds)
    reference = dense_frequencies(k, m, fields, tol=1e-7)[rigid:]
    computed = elastic(facts)
    np.testing.assert_allclose(computed, reference[: computed.size], rtol=1e-6)


@pytest.mark.parametrize(
    ("path", "says"),
    [
        (PYNASTRAN / "fsi" / "fsi.pch", "holds no DMIG matrices: a results punch"),
        (PYNASTRAN / "testplate_kgg" / "testplate_kgg.op4", "holds KGG (stiffness, 726 x 726)"),
        (PYNASTRAN / "op2_kgg_kelm" / "static_solid_shell_bar_kelm.op2", "no mass matrix"),
        (YETI / "inboard.pch", "EXTBULK"),
    ],
    ids=["results-punch", "kgg-only-op4", "op2-without-mgg", "extbulk-as-model"],
)
def test_files_without_k_and_m_say_what_they_hold(capsys, path, says):
    assert main(["info", str(path)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and says in err and str(path) in err
