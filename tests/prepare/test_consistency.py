"""Consistency checks of issue #27 item 1: a wrong map or unit is exit 2, genuine files pass.

Every broken case is made from a genuine or built-in model by the one mistake a user makes
(a mass file in another dof order, coordinates in mm, a dof table shifted by a node, point
masses in one direction) and goes through the command line or ``validate_body``; the genuine
ones are the corpus files (``tests/data``, copies of ``../shared/corpus``), the CalculiX exports
of ``tests/data/calculix_map_check`` and the built-in examples.
"""

from __future__ import annotations

import hashlib
import lzma
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
import scipy.io
import scipy.sparse as sp

from abaqus_models import genuine
from conftest import spring_lattice
from info_runs import info_facts, refused
from pymorembs.body import DofTable
from pymorembs.errors import UserError
from pymorembs.examples import build_example
from pymorembs.io.formats import read_body
from pymorembs.io.native import write_body_h5
from pymorembs.job.cli import main
from pymorembs.preparation import validate_body
from pymorembs.preparation.consistency import check_consistency, mechanism_or_map
from pymorembs.preparation.stiffening import geometric_stiffness

DATA = Path(__file__).parents[1] / "data"
CALCULIX = DATA / "calculix_map_check"
#: SHA-256 of the unpacked CalculiX matrices (README of the folder).
CALCULIX_SHA256 = {
    "clamped.sti": "e08522f2916c40a520210f41c8b4f821273e2dc0e6b16aab26e971c3b657f55a",
    "clamped.mas": "9b175de89d7bd9716241b83e33d867b6fee0cd120f054cbe7fc571d21f834a78",
    "free.sti": "3c33fbb52f9b445eeb560e45b60ed8a277f10b4c76441c4b4dd2ecb802bebccf",
    "free.mas": "1a541c3394cd24f39d85408548f5221bbc8e2355fd64460de0c4192676a4080e",
}
DIRECTION = {"1": "ux", "2": "uy", "3": "uz"}


# ------------------------------------------------------------------------------ CalculiX
def calculix(job: str, folder: Path, shift: int = 0) -> list[str | Path]:
    """The command-line options of a CalculiX export as Abaqus COORDINATE files, with the
    ``dofs.csv`` a user writes from ``job.dof`` (``shift``: every equation labelled with the
    node ``shift`` places later in the list of its nodes, the mistake of a shifted table)."""
    paths = {}
    for suffix in ("sti", "mas"):
        name = f"{job}.{suffix}"
        data = lzma.decompress((CALCULIX / f"{name}.xz").read_bytes())
        assert hashlib.sha256(data).hexdigest() == CALCULIX_SHA256[name]
        paths[suffix] = folder / name
        paths[suffix].write_bytes(data)
    entries = [line.split(".") for line in (CALCULIX / f"{job}.dof").read_text().split()]
    nodes = sorted({int(node) for node, _ in entries})
    moved = {n: nodes[(k + shift) % len(nodes)] for k, n in enumerate(nodes)}
    dofs = folder / f"{job}_dofs.csv"
    dofs.write_text(
        "node,direction\n" + "".join(f"{moved[int(n)]},{DIRECTION[d]}\n" for n, d in entries)
    )
    return [
        "--format", "abaqus", "--stiffness", paths["sti"], "--mass", paths["mas"],
        "--dofs", dofs, "--inp", CALCULIX / f"{job}.inp",
    ]  # fmt: skip


@pytest.mark.parametrize(
    ("path", "fitting", "near"),
    [
        ("calculix_map_check/free.sti.xz", 132, 0),  # 44 nodes x 3, nothing held
        ("calculix_map_check/clamped.sti.xz", 72, 36),  # 8 nodes removed, 12 nodes beside them
        ("calculix_c3d20_block/free.sti", 96, 0),
        ("calculix_c3d20_block/fixed.sti", 36, 49),  # 11 dofs fixed, 12 nodes clear of them
    ],
)
def test_calculix_exports_prove_their_map(capsys, path, fitting, near):
    """Read natively (``info job.sti``): free exports fit the six fields in every row; the
    constrained ones (``*BOUNDARY`` removed the fixed dofs) in the rows of the nodes that share
    no element with a held node -- the count CalculiX's deck gives -- while the rows beside the
    supports carry their reactions."""
    facts = info_facts(capsys, DATA / path)
    proof = facts["consistency"]["map"]
    assert proof["status"] == "map proved"
    assert (proof["rows"] - near, proof["rows_near_supports"]) == (fitting, near)
    assert proof["residual"] < 1e-12  # 14 digits: far below a wrong map's 1e-1 .. 1
    assert facts["consistency"]["warnings"] == []


def test_calculix_export_read_as_abaqus_files_proves_its_map(capsys, tmp_path):
    """The same clamped export with a hand-written dofs.csv: the reader no longer knows the
    removed nodes, so the 36 rows beside them are rows held by springs to ground."""
    facts = info_facts(capsys, *calculix("clamped", tmp_path))
    proof = facts["consistency"]["map"]
    assert proof["status"] == "map proved"
    assert (proof["rows"], proof["rows_near_supports"]) == (108, 36)


@pytest.mark.parametrize("job", ["free", "clamped"])
def test_calculix_map_shifted_by_one_node_is_refused(capsys, tmp_path, job):
    err = refused(capsys, *calculix(job, tmp_path, shift=1))
    assert "this map does not fit K" in err and "shifted by a node" in err


# ---------------------------------------------------------------------------- rack-beams
@pytest.fixture(scope="module")
def rack_files(tmp_path_factory) -> Path:
    folder = tmp_path_factory.mktemp("rack")
    assert main(["example", "rack-beams", "--out", str(folder)]) == 0
    return folder


def matrix_files(folder: Path, **replaced: Path) -> list[str | Path]:
    files = {
        "stiffness": folder / "K.mtx", "mass": folder / "M.mtx", "dofs": folder / "dofs.csv",
        "nodes": folder / "nodes.csv", "constraints": folder / "constraints.csv",
    } | replaced  # fmt: skip
    return [x for key, path in files.items() for x in (f"--{key}", path)]


def test_rack_files_pass(capsys, rack_files):
    facts = info_facts(capsys, *matrix_files(rack_files))
    assert facts["consistency"]["map"]["status"] == "map proved"
    assert facts["consistency"]["map"]["residual"] < 1e-14
    assert facts["consistency"]["rigid_mass"]["rigid"] is True


def test_mass_in_direction_major_order_is_refused(capsys, rack_files, tmp_path):
    """M.mtx rewritten with its equations ordered by direction, then node (K stays node-major):
    read as it is, the total mass is 1.34 instead of 1.39 and every node's mass differs by
    direction."""
    mass = sp.csr_matrix(scipy.io.mmread(rack_files / "M.mtx"))
    table = np.genfromtxt(rack_files / "dofs.csv", delimiter=",", names=True, dtype=None)
    codes = {name: k for k, name in enumerate(["ux", "uy", "uz", "rx", "ry", "rz"])}
    directions = np.array(
        [codes[d.decode() if isinstance(d, bytes) else d] for d in table["direction"]]
    )
    order = np.lexsort((table["node"], directions))  # file row k holds equation order[k]
    moved = tmp_path / "M_direction_major.mtx"
    scipy.io.mmwrite(moved, mass[order][:, order])
    err = refused(capsys, *matrix_files(rack_files, mass=moved))
    assert "the mass matrix does not fit" in err and "direction-major where K is node-major" in err


def test_lumped_mass_direction_major(tmp_path):
    body = read_body(
        stiffness=genuine("exudyn_abaqus_blocks/blockC3D4_STIF1.mtx", tmp_path),
        mass=DATA / "exudyn_abaqus_blocks/blockC3D4_MASS1.mtx",
        inp=DATA / "exudyn_abaqus_blocks/blockC3D4.inp",
    )
    order = np.lexsort((body.dofs.nodes, body.dofs.directions))
    moved = replace(body, mass=body.mass[order][:, order])
    masses = [moved.mass.diagonal()[body.dofs.directions == d].sum() for d in range(3)]
    np.testing.assert_allclose(masses, 11600.0, rtol=1e-12)  # the totals cannot tell
    with pytest.raises(UserError, match=r"different centres of gravity.*214 of 214"):
        validate_body(moved)


def test_pm_prepare_refuses_the_wrong_order_and_the_unit_mix_too():
    """The Python API runs the same checks as info and jobs, before any work."""
    import pymorembs as pm

    body = pm.example("rack-beams")
    order = np.lexsort((body.dofs.nodes, body.dofs.directions))
    with pytest.raises(UserError, match="the mass matrix does not fit the dof table"):
        pm.prepare(replace(body, mass=body.mass[order][:, order]), "tangent", node=2)
    with pytest.raises(UserError, match="the coordinates look like mm"):
        pm.prepare(replace(body, coordinates=1e3 * body.coordinates), "tangent", node=2)
    assert pm.prepare(body, "tangent", node=2, inputs=[(1, "ux")]).warnings == ()


def test_coordinates_in_mm_on_the_beam_model(capsys, rack_files, tmp_path):
    nodes = np.loadtxt(rack_files / "nodes.csv", delimiter=",", skiprows=1)
    scaled = tmp_path / "nodes_mm.csv"
    np.savetxt(
        scaled, np.column_stack([nodes[:, 0], 1e3 * nodes[:, 1:]]), delimiter=",",
        header="id,x,y,z", comments="", fmt=["%d", "%.17g", "%.17g", "%.17g"],
    )  # fmt: skip
    err = refused(capsys, *matrix_files(rack_files, nodes=scaled))
    assert "the coordinates look like mm while K and M are in m-kg-s-N units" in err
    assert "times 0.001" in err


def test_coordinates_in_mm_on_a_solid_with_its_mesh():
    """The blade (hex20, steel in SI) with its coordinates in mm: mass / element volume is
    7.85e-6, which is steel only with the coordinates x 0.001."""
    body = build_example("blade")
    with pytest.raises(UserError, match=r"look like mm while K and M are in m-kg-s-N.*7850 kg"):
        validate_body(replace(body, coordinates=1e3 * body.coordinates))


def test_shifted_table_of_a_free_beam_model_is_refused():
    """A node shift along straight beams of equal elements is a rigid translation there; the
    rows where the beams meet show it."""
    body = build_example("rack-beams")
    ids = np.unique(body.dofs.nodes)
    following = dict(zip(ids.tolist(), np.roll(ids, -1).tolist(), strict=True))
    table = replace(body.dofs, nodes=np.array([following[int(n)] for n in body.dofs.nodes]))
    with pytest.raises(UserError, match="this map does not fit K"):
        check_consistency(replace(body, dofs=table, mesh=None, surface=None))


def rack_with_geometric_stiffness(strain: float):
    """rack-beams with the geometric stiffness of its rods stretched (``strain`` > 0) or
    compressed uniformly along z (``u_z = strain z``, axial force ``E A strain``)."""
    body = build_example("rack-beams")
    z = body.coordinates[body.node_rows(body.dofs.nodes), 2]
    displacement = np.where(body.dofs.directions == 2, strain * z, 0.0)
    return replace(body, stiffness=body.stiffness + geometric_stiffness(body, displacement))


@pytest.mark.parametrize("strain", [1e-3, -2e-4])  # tension near yield; compression below buckling
def test_a_prestressed_stiffness_is_not_refused(strain):
    """A stiffness with the geometric stiffness of a preload step: the rigid rotations leave
    forces where the rods' stress turns with them, far below the strain itself; the run goes on
    with "map not proved" and a warning that names the prestress."""
    report = validate_body(rack_with_geometric_stiffness(strain))
    proof = report.facts["consistency"]["map"]
    assert proof["status"] == "map not proved"
    assert 0 < proof["rows_unexplained"] < 0.01 * proof["rows"]
    assert proof["unexplained_residual"] < abs(strain)
    assert any("map not proved" in w and "prestressed stiffness" in w for w in report.warnings)


def test_a_spring_between_two_separated_nodes_is_not_refused():
    """An isotropic spring ``k I`` between nodes of two rods (a scalar spring, a bushing without
    offset) resists the rigid rotations in exactly its six rows: "map not proved", not exit 2."""
    body = build_example("rack-beams")
    nodes = [1050, 3120]  # rods 1 and 3, (25, 20, 63) and (-25, -20, 148) mm
    a, b = [[body.dofs.index(node, d) for d in ("ux", "uy", "uz")] for node in nodes]
    gap = np.diff(body.coordinates[body.node_rows(nodes)], axis=0)
    assert np.all(np.abs(gap) >= 0.04)  # apart in x, y and z: every rotation stretches it
    spring = sp.lil_matrix(body.stiffness.shape)
    for i, j in zip(a, b, strict=True):
        spring[i, i] = spring[j, j] = 1e6
        spring[i, j] = spring[j, i] = -1e6
    report = validate_body(replace(body, stiffness=body.stiffness + spring.tocsr()))
    proof = report.facts["consistency"]["map"]
    assert proof["status"] == "map not proved" and proof["rows_unexplained"] == 6
    assert any("springs between separated nodes" in w for w in report.warnings)


def test_springs_to_ground_are_supports():
    """The spring lattice of the tests is held by springs to ground at the x, y, z of nodes 10,
    20 and 30: those 9 rows carry reactions, the central springs fit every rigid motion."""
    facts = validate_body(spring_lattice(constraints=False)).facts["consistency"]
    assert facts["map"]["status"] == "map proved"
    assert facts["map"]["rows_near_supports"] == 9 and facts["map"]["rows"] == 36


def test_a_loose_pair_of_nodes_is_a_mechanism_not_a_wrong_map(capsys, tmp_path):
    """The lattice plus two nodes joined only to each other by ``k I`` (resisting their
    rotation): ``info`` reports 3 mechanisms (the pair translating) and "map not proved" for the
    pair's rows, not "this map does not fit K"."""
    body = spring_lattice(constraints=False)
    spring = 1e5 * np.array([[1.0, -1.0], [-1.0, 1.0]])
    pair = DofTable(np.repeat([130, 140], 3), np.tile([0, 1, 2], 2))
    loose = replace(
        body,
        node_ids=np.concatenate([body.node_ids, [130, 140]]),
        coordinates=np.vstack([body.coordinates, [[2.0, 0.3, 0.4], [2.5, 0.7, 0.1]]]),
        dofs=DofTable(
            np.concatenate([body.dofs.nodes, pair.nodes]),
            np.concatenate([body.dofs.directions, pair.directions]),
        ),
        stiffness=sp.block_diag([body.stiffness, sp.kron(spring, sp.eye(3))], format="csr"),
        mass=sp.block_diag([body.mass, sp.eye(6)], format="csr"),
    )
    write_body_h5(loose, tmp_path / "loose.h5")
    facts = info_facts(capsys, tmp_path / "loose.h5")
    assert (facts["rigid_body_modes"], facts["mechanisms"]) == (0, 3)
    proof = facts["consistency"]["map"]
    assert proof["status"] == "map not proved" and proof["rows_unexplained"] == 6


def test_mechanism_or_map_only_for_a_free_body_with_rotations_missing():
    """``info``'s line for a free body whose map is wrong: six zero modes in the spectrum, three
    geometric ones and unexplained rows; not for a held body, a real mechanism, a proved map."""
    wrong = {"map": {"rows_unexplained": 40, "reason": "..."}}
    assert "this map does not fit K" in mechanism_or_map(wrong, 3, 3)
    assert mechanism_or_map(wrong, 0, 3) is None  # a held body with a loose part
    assert mechanism_or_map(wrong, 6, 1) is None  # a free body with a hinge
    assert mechanism_or_map(wrong, 3, 6) is None  # a free body and a loose part
    assert mechanism_or_map({"map": {"rows_unexplained": 0}}, 3, 3) is None


def test_directional_point_masses_give_a_note():
    """Point masses in x only at three nodes (a Nastran CMASS, a scalar mass): the translations
    see different masses, a note says where, nothing is refused."""
    body = build_example("rack-beams")
    mass = sp.lil_matrix(body.mass)
    nodes = [int(n) for n in np.unique(body.dofs.nodes)[10:13]]
    for node in nodes:
        index = body.dofs.index(node, "ux")
        mass[index, index] += 0.1
    report = validate_body(replace(body, mass=sp.csr_matrix(mass)))
    facts = report.facts["consistency"]
    seen = facts["rigid_mass"]["masses"]
    assert seen[0] == pytest.approx(seen[1] + 0.3, rel=1e-12) and seen[1] == pytest.approx(seen[2])
    assert facts["rigid_mass"]["anisotropic_nodes"] == 3
    assert any(note.startswith("directional masses") for note in facts["notes"])
    assert facts["map"]["status"] == "map proved"


def test_rigid_body_mass_of_the_blade_is_that_of_its_steel_box():
    """The blade is a straight steel box a x b x c (hex20, consistent mass): its centre of
    gravity is the box's centre and its principal moments m (b^2 + c^2) / 12 ... (analytic)."""
    body = build_example("blade")
    facts = check_consistency(body)["rigid_mass"]
    low, high = body.coordinates.min(axis=0), body.coordinates.max(axis=0)
    a, b, c = np.sort(high - low)[::-1]
    m = facts["masses"][0]
    np.testing.assert_allclose(facts["masses"], 7850.0 * a * b * c, rtol=1e-12)
    np.testing.assert_allclose(facts["centre_of_gravity"], (low + high) / 2, atol=1e-12)
    expected = np.sort([m * (b**2 + c**2) / 12, m * (a**2 + c**2) / 12, m * (a**2 + b**2) / 12])
    np.testing.assert_allclose(facts["principal_inertia"], expected, rtol=1e-10)


# -------------------------------------------------------------------- no false alarm
CORPUS = {
    "hexbeam": {
        "file": "pymapdl_reader_hexbeam/file.full",
        "nodes": "pymapdl_reader_hexbeam/HexBeam.cdb",
    },
    "blockC3D4": {
        "stiffness": "exudyn_abaqus_blocks/blockC3D4_STIF1.mtx",
        "mass": "exudyn_abaqus_blocks/blockC3D4_MASS1.mtx",
        "inp": "exudyn_abaqus_blocks/blockC3D4.inp",
    },
    "tetra-beam": {
        "stiffness": "juliafem_abaqus_tetra_beam/STIF1_coord_style.mtx",
        "mass": "juliafem_abaqus_tetra_beam/MASS1_coord_style.mtx",
        "inp": "juliafem_abaqus_tetra_beam/abq_beam.inp",
    },
    "substructure-inner": {"file": "abaqus_mtx_parser/symmetric/inner.mtx"},
    "substructure-total": {"file": "abaqus_mtx_parser/symmetric/total.mtx"},
    "substructure-outer": {"file": "abaqus_mtx_parser/symmetric/outer.mtx"},
    "substructure-recovery": {"file": "abaqus_mtx_parser/recovery/interface-beam-sub.mtx"},
    "maewing-f06": {
        "file": "exportnastrankm_mAEWing1_FEMv5p2/sol103_maewing1_femv5p2.pch1",
        "nodes": "exportnastrankm_mAEWing1_FEMv5p2/sol103_maewing1_femv5p2.f06",
    },
    "maewing": {"file": "exportnastrankm_mAEWing1_FEMv5p2/sol103_maewing1_femv5p2.pch1"},
    "dmig-chain": {"file": "pynastran/dmig_pch/dmig.pch"},
    "inboard": {
        "file": "pyyeti_nx_extseout/inboard.op4",
        "dofs": "pyyeti_nx_extseout/inboard.pch",
    },
    "outboard": {
        "file": "pyyeti_nx_extseout/outboard.op4",
        "dofs": "pyyeti_nx_extseout/outboard.pch",
    },
    "bset-notall6": {
        "file": "pyyeti_nx_extseout/reduced_bset_notall6/reduced_bset_notall6.op4",
        "dofs": "pyyeti_nx_extseout/reduced_bset_notall6/reduced_bset_notall6.pch",
    },
    "se_test_n11": {
        "file": "pynastran/superelement_se_test_n11/se_test_n11.op4",
        "dofs": "pynastran/superelement_se_test_n11/se_test_n11.pch",
    },
    "extse10": {"file": "pynastran/extse_op4/extse10.op4"},
}  # fmt: skip
#: Those whose map can be proved: coordinates and translational dofs.
PROVED = {"hexbeam", "blockC3D4", "tetra-beam", "maewing-f06", "inboard", "outboard",
          "bset-notall6", "se_test_n11"}  # fmt: skip


@pytest.mark.slow  # corpus-wide: 15 exports
@pytest.mark.parametrize("name", sorted(CORPUS))
def test_corpus_files_pass_and_say_whether_the_map_is_proved(tmp_path, name):
    """Every genuine export of the corpus (tests/data holds the copies of ../shared/corpus):
    no error, no warning, "map proved" wherever coordinates allow it."""
    body = read_body(**{key: genuine(path, tmp_path) for key, path in CORPUS[name].items()})
    report = validate_body(body)
    facts = report.facts["consistency"]
    assert facts["warnings"] == []
    assert facts["map"]["status"] == ("map proved" if name in PROVED else "map not proved")
    if name in PROVED:
        assert facts["map"]["residual"] < 1e-6


@pytest.mark.parametrize(
    "name", ["rack-beams", pytest.param("rack-solid", marks=pytest.mark.slow), "blade"]
)
def test_examples_pass_with_their_map_proved(name):
    facts = validate_body(build_example(name)).facts["consistency"]
    assert facts["warnings"] == [] and facts["notes"] == []
    assert facts["map"]["status"] == "map proved" and facts["map"]["residual"] < 1e-13
    if name != "rack-beams":  # solids: steel in SI, from the mesh volume
        assert facts["material"]["systems"] == ["m-kg-s-N"]
        assert facts["material"]["density"] == pytest.approx(7850, rel=2e-3)


def test_shared_corpus_is_the_tested_copy():
    """The corpus beside the repository (where present) holds the same files as tests/data."""
    shared = Path(__file__).parents[3] / "shared" / "corpus"
    if not shared.is_dir():
        pytest.skip("../shared/corpus is not beside this clone")
    for spec in CORPUS.values():
        for path in spec.values():
            original = shared / path
            copy = DATA / path
            if copy.exists() and original.exists():
                assert original.read_bytes() == copy.read_bytes(), path
