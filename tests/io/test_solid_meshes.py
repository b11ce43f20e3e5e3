"""Geometric stiffening from imported solid meshes (issue #15 item 2, second source).

References, all independent of the code under test:

- the stiffness matrices Abaqus wrote for the genuine C3D4, C3D20R and C3D10 models
  (tests/data, parsed here with plain numpy): the element kinematics of
  :mod:`pymorembs.elements.solid` with the material of the ``.inp`` reproduce them to 1e-13,
  which proves node order, Gauss rule and material;
- closed forms: linear fields (patch test: strain energy ``V sigma : eps``), rigid motions, the
  string stiffness of a uniaxial prestress;
- Euler's buckling load of the clamped C3D10 beam;
- the built-in blade (hex20) written as an Abaqus ``.inp`` with its matrices: the same SID as the
  built-in route.
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
import scipy.linalg as sl
import scipy.sparse as sp
import scipy.sparse.linalg as spla
from threadpoolctl import threadpool_limits

from abaqus_models import genuine, read_coordinate_file
from pymorembs.elements.solid import (
    SOLID_KINDS,
    assemble_solid_geometric,
    assemble_solid_stiffness,
    solid_forces,
    solid_geometric_matrices,
    solid_stiffness,
    solid_stresses,
)
from pymorembs.errors import UserError
from pymorembs.examples.blade import blade, blade_mesh
from pymorembs.export.sid import read_sid
from pymorembs.io.abaqus import read_abaqus, read_abaqus_stiffness
from pymorembs.io.native import read_body_h5, write_body_h5
from pymorembs.io.solid_mesh import mesh_problem
from pymorembs.job.cli import main
from pymorembs.preparation import Frame, prepare
from pymorembs.preparation.stiffening import geometric_stiffness, stiffening_from_mesh

BLOCKS = "exudyn_abaqus_blocks"
BEAM = "juliafem_abaqus_tetra_beam"

# natural node coordinates of each kind, written out here (Abaqus order)
_TET4 = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], dtype=float)
_TET10 = np.vstack(
    [
        _TET4,
        [(_TET4[a] + _TET4[b]) / 2 for a, b in ((0, 1), (1, 2), (2, 0), (0, 3), (1, 3), (2, 3))],
    ]
)
_HEX8 = np.array(
    [[-1, -1, -1], [1, -1, -1], [1, 1, -1], [-1, 1, -1],
     [-1, -1, 1], [1, -1, 1], [1, 1, 1], [-1, 1, 1]], dtype=float
)  # fmt: skip
_EDGES20 = [(0, 1), (1, 2), (2, 3), (3, 0), (4, 5), (5, 6), (6, 7), (7, 4),
            (0, 4), (1, 5), (2, 6), (3, 7)]  # fmt: skip
_HEX20 = np.vstack([_HEX8, [(_HEX8[a] + _HEX8[b]) / 2 for a, b in _EDGES20]])
NATURAL = {"tet4": _TET4, "tet10": _TET10, "hex8": _HEX8, "hex20": _HEX20, "hex20r": _HEX20}
REFERENCE_VOLUME = {"tet4": 1 / 6, "tet10": 1 / 6, "hex8": 8.0, "hex20": 8.0, "hex20r": 8.0}


@pytest.fixture(scope="module")
def unpacked(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return tmp_path_factory.mktemp("genuine")


def affine_element(kind: str, seed: int = 0) -> tuple[np.ndarray, float]:
    """One element of ``kind`` mapped by a random affine map, and its volume."""
    rng = np.random.default_rng(seed)
    a = np.eye(3) + 0.3 * rng.standard_normal((3, 3))
    if np.linalg.det(a) < 0:
        a[:, 0] *= -1
    nodes = NATURAL[kind] @ a.T + rng.standard_normal(3)
    return nodes[None], abs(np.linalg.det(a)) * REFERENCE_VOLUME[kind]


@pytest.mark.parametrize("kind", sorted(SOLID_KINDS))
def test_shape_functions_interpolate_and_differentiate(kind):
    spec = SOLID_KINDS[kind]
    values, _ = spec.shape_functions(NATURAL[kind])
    np.testing.assert_allclose(values, np.eye(spec.nodes), atol=1e-14)  # N_a(x_b) = delta_ab
    points = np.random.default_rng(1).uniform(0.05, 0.2, (5, 3))
    values, derivatives = spec.shape_functions(points)
    np.testing.assert_allclose(values.sum(axis=1), 1.0, rtol=1e-14)
    step = 1e-6
    for k in range(3):
        shifted = points.copy()
        shifted[:, k] += step
        back = points.copy()
        back[:, k] -= step
        numeric = (spec.shape_functions(shifted)[0] - spec.shape_functions(back)[0]) / (2 * step)
        np.testing.assert_allclose(derivatives[..., k], numeric, atol=1e-8)
    assert spec.weights.sum() == pytest.approx(REFERENCE_VOLUME[kind], rel=1e-14)


@pytest.mark.parametrize("kind", sorted(SOLID_KINDS))
def test_element_forces_are_the_stiffness_times_the_fields(kind):
    """``solid_forces`` (nodal forces of the stresses, no matrix formed) equals the element
    stiffness matrix times the fields, for distorted elements of one and of several
    materials, and gives zero for a rigid motion."""
    rng = np.random.default_rng(4)
    nodes = np.concatenate([affine_element(kind, seed)[0] for seed in range(6)])
    nodes = nodes + 0.02 * rng.standard_normal(nodes.shape)  # curved edges, not affine
    fields = rng.standard_normal((6, SOLID_KINDS[kind].nodes, 3, 3))
    for young, poisson in ((2.1e5, 0.3), (rng.uniform(1e3, 1e5, 6), rng.uniform(0.0, 0.45, 6))):
        matrices = solid_stiffness(kind, nodes, young, poisson)
        expected = matrices @ fields.reshape(6, -1, 3)
        forces = solid_forces(kind, nodes, fields, young, poisson)
        np.testing.assert_allclose(forces, expected, rtol=0, atol=1e-12 * np.abs(expected).max())
    rotation = np.cross([0.3, -0.2, 0.5], nodes) + np.array([1.0, 2.0, 3.0])  # rotation, shift
    rigid = solid_forces(kind, nodes, rotation[..., None], 2.1e5, 0.3)
    assert np.abs(rigid).max() < 1e-10 * np.abs(expected).max()


@pytest.mark.parametrize("kind", sorted(SOLID_KINDS))
def test_patch_test_rigid_motions_and_string_stiffness(kind):
    nodes, volume = affine_element(kind)
    E, nu = 2.0e11, 0.27
    k = solid_stiffness(kind, nodes, E, nu)[0]
    grad = np.array([[1.0, 0.2, -0.3], [0.4, -0.5, 0.1], [0.0, 0.6, 0.7]]) * 1e-3
    u = nodes[0] @ grad.T  # a linear field u = grad x
    eps = 0.5 * (grad + grad.T)
    lam, mu = E * nu / ((1 + nu) * (1 - 2 * nu)), E / (2 * (1 + nu))
    sigma = lam * np.trace(eps) * np.eye(3) + 2 * mu * eps
    assert u.ravel() @ k @ u.ravel() == pytest.approx(volume * np.sum(sigma * eps), rel=1e-12)
    spin = np.array([[0.0, -1.0, 2.0], [1.0, 0.0, -0.5], [-2.0, 0.5, 0.0]])
    rigid = (nodes[0] @ spin.T + [1.0, -2.0, 3.0]).ravel()
    assert np.abs(k @ rigid).max() < 1e-12 * np.abs(k).max() * np.abs(rigid).max()
    # the stresses of the linear field, at every Gauss point
    stresses = solid_stresses(kind, nodes, u[None], E, nu)
    np.testing.assert_allclose(stresses[0], np.broadcast_to(sigma, stresses[0].shape), rtol=1e-12)
    # a uniaxial prestress sigma_xx = s stiffens a field w = slope x (any direction) by s slope² V
    s, slope = 3.0e6, 0.7
    prestress = np.zeros_like(stresses)
    prestress[..., 0, 0] = s
    g = solid_geometric_matrices(kind, nodes, prestress)[0]
    w = slope * nodes[0][:, 0]
    assert w @ g @ w == pytest.approx(s * slope**2 * volume, rel=1e-12)
    assert abs(np.ones(len(w)) @ g @ np.ones(len(w))) < 1e-9 * s * volume


@pytest.mark.parametrize(
    ("inp", "files", "kind", "young"),
    [
        (f"{BLOCKS}/blockC3D4.inp", ("blockC3D4_STIF1.mtx", "blockC3D4_MASS1.mtx"), "tet4", 2e11),
        (f"{BLOCKS}/blockC3D20R.inp", ("blockC3D20R_STIF1.mtx",), "hex20r", 2e11),
        (
            f"{BEAM}/abq_beam.inp",
            ("STIF1_coord_style.mtx", "MASS1_coord_style.mtx"),
            "tet10",
            208e3,
        ),
    ],
)
def test_element_kinematics_reproduce_the_stiffness_abaqus_wrote(unpacked, inp, files, kind, young):
    folder = inp.rsplit("/", 1)[0]
    paths = [genuine(f"{folder}/{name}", unpacked) for name in files]
    inp_path = genuine(inp, unpacked)
    if len(paths) == 2:
        body = read_abaqus(paths[0], paths[1], inp=inp_path)
    else:
        body = read_abaqus_stiffness(paths[0], inp=inp_path)
    mesh = body.mesh
    assert mesh is not None and mesh.element == kind
    assert (mesh.young, mesh.poisson) == (young, 0.3)  # *ELASTIC of the .inp
    # equation 3 (node - 1) + dof (the files' convention, proved by the reader's own tests)
    np.testing.assert_array_equal(body.node_ids, np.arange(1, body.n_nodes + 1))
    ours = assemble_solid_stiffness(
        kind, body.coordinates, body.node_rows(mesh.connectivity), mesh.young, mesh.poisson
    ).toarray()
    written = read_coordinate_file(paths[0], body.n_dof)
    kept = np.diag(written) < 1e30  # not an Abaqus penalty diagonal (1e36, clamped dofs)
    written[np.diag_indices_from(written)] = np.where(kept, np.diag(written), 0.0)
    ours[np.diag_indices_from(ours)] = np.where(kept, np.diag(ours), 0.0)
    assert np.abs(ours - written).max() <= 1e-13 * np.abs(written).max()


def test_clamped_c3d10_beam_buckles_at_the_euler_load(unpacked):
    """K from Abaqus, K_G from the element kinematics: a compressive tip load P buckles the
    20 x 20 x 500 mm cantilever at pi² E I / (4 L²) = 27.37 kN (Euler). The mesh (233 C3D10,
    two quadratic elements across) is stiff by about 0.5 % and shear softens by 0.1 %: 1 %."""
    body = read_abaqus(
        genuine(f"{BEAM}/STIF1_coord_style.mtx", unpacked),
        genuine(f"{BEAM}/MASS1_coord_style.mtx", unpacked),
        inp=genuine(f"{BEAM}/abq_beam.inp", unpacked),
    )
    free = np.setdiff1d(np.arange(body.n_dof), body.fixed)
    k = body.stiffness.toarray()[np.ix_(free, free)]
    tip = body.node_ids[np.isclose(body.coordinates[:, 2], 500.0)]
    force = np.zeros(body.n_dof)
    force[body.dofs.positions(tip, 2)] = -1.0 / tip.size  # 1 N compression, resultant on axis
    u = np.zeros(body.n_dof)
    u[free] = np.linalg.solve(k, force[free])
    k_g = geometric_stiffness(body, u).toarray()[np.ix_(free, free)]
    with threadpool_limits(1):
        mu = sl.eigh(-k_g, k, eigvals_only=True, subset_by_index=[free.size - 2, free.size - 1])
    loads = np.sort(1.0 / mu)  # the two bending directions (square section)
    euler = np.pi**2 * 208000.0 * (20.0**4 / 12) / (4 * 500.0**2)
    np.testing.assert_allclose(loads, euler, rtol=0.01)
    assert loads[0] > euler  # a displacement model is stiff


# ------------------------------------------------------------------ the blade as an Abaqus model
def write_blade_as_abaqus(folder: Path, elements: int = 12) -> dict[str, Path]:
    """The built-in blade as an ``.inp`` (C3D20, its material) with FORMAT=COORDINATE K and M;
    the clamped root as Abaqus writes it (1e36 penalty diagonals)."""
    body, mesh = blade(elements=elements), blade_mesh(elements=elements)
    lines = ["*Heading", "** the pymorembs blade", "*Node"]
    lines += [
        f"{i}, {x:.17g}, {y:.17g}, {z:.17g}"
        for i, (x, y, z) in zip(mesh.node_ids, mesh.coordinates, strict=True)
    ]
    lines.append("*Element, type=C3D20, elset=blade")
    for e, conn in enumerate(mesh.node_ids[mesh.elements], start=1):
        ids = [str(e), *map(str, conn)]
        lines += [", ".join(ids[:16]) + ",", ", ".join(ids[16:])]
    lines += ["*Solid Section, elset=blade, material=steel", ",", "*Material, name=steel",
              "*Density", "7850.,", "*Elastic", "2.1e11, 0.3"]  # fmt: skip
    paths = {"inp": folder / "blade.inp"}
    paths["inp"].write_text("\n".join(lines) + "\n")
    for name, matrix in (("STIF1", body.stiffness.tocoo()), ("MASS1", body.mass.tocoo())):
        values = matrix.data.copy()
        if name == "STIF1":
            values[np.isin(matrix.row, body.fixed) & (matrix.row == matrix.col)] = 1e36
        paths[name] = folder / f"blade_{name}.mtx"
        paths[name].write_text(
            "".join(
                f"{r + 1} {c + 1} {v:.17g}\n"
                for r, c, v in zip(matrix.row, matrix.col, values, strict=True)
            )
        )
    return paths


JOB = """
[model]
{model}

[frame]
type = "none"

[[inputs]]
node = 1
directions = "ux uy uz"

[band]
f_max_hz = 100
points = 200
reference = "surrogate"

[[reduction]]
name = "krylov"
method = "krylov"
expansion_points_hz = [0, 50]
order = 30

[export]
outputs = ["sid"]
nodes = [1]

[stiffening]
source = "mesh"
"""


def sid_rotating_hz(path: Path, omega: float) -> np.ndarray:
    """Lowest three frequencies (Hz) of a SID body spinning about z: Ke + omega² Oe1[:, :, wzz]."""
    sid = read_sid(path)
    me, ke, oe1 = sid.objects["Me"].m0, sid.objects["Ke"].m0, sid.objects["Oe"].first
    values = sl.eigh(ke + omega**2 * oe1[:, :, 2], me, eigvals_only=True)
    return np.sqrt(np.sort(values)[:3]) / (2 * np.pi)


def full_rotating_hz(elements: int, omega: float) -> np.ndarray:
    """Lowest three frequencies (Hz) of the full built-in blade spinning about z (its root on
    the axis): K + omega² (K_G(wzz) - M_xy), K_G from the static centrifugal response."""
    body, mesh = blade(elements=elements), blade_mesh(elements=elements)
    free = np.setdiff1d(np.arange(body.n_dof), body.fixed)
    k, m = body.stiffness.tocsr(), body.mass.tocsr()
    x, y, _ = mesh.coordinates.T
    load = m @ np.column_stack([x, y, 0 * x]).ravel()
    u = np.zeros(body.n_dof)
    u[free] = spla.spsolve(k[free][:, free].tocsc(), load[free])
    k_g = assemble_solid_geometric("hex20", mesh.coordinates, mesh.elements, u, 2.1e11, 0.3)
    in_plane = sp.diags(np.tile([1.0, 1.0, 0.0], body.n_nodes))
    a = (k + omega**2 * (k_g - in_plane @ m @ in_plane))[free][:, free]
    values = spla.eigsh(a.tocsc(), k=3, M=m[free][:, free].tocsc(), sigma=0.0)[0]
    return np.sqrt(np.sort(values)) / (2 * np.pi)


def test_blade_read_from_abaqus_files_gives_a_stiffened_sid(tmp_path):
    """End to end: the blade as Abaqus files, reduce + SID export with Geo_Stiff from the .inp
    mesh; the spinning SID body against a direct solution of the full built-in model."""
    paths = write_blade_as_abaqus(tmp_path, elements=4)
    model = f'stiffness = "{paths["STIF1"]}"\nmass = "{paths["MASS1"]}"\ninp = "{paths["inp"]}"'
    (tmp_path / "job.toml").write_text(JOB.format(model=model))
    out = tmp_path / "out"
    assert main(["reduce", str(tmp_path / "job.toml"), "--out", str(out), "--quiet"]) == 0
    path = out / "krylov" / "krylov.SID_FEM"
    assert read_sid(path).geometric_stiffening
    still = full_rotating_hz(4, 0.0)
    for ratio in (1.0, 2.0):
        omega = ratio * 2 * np.pi * still[0]
        full = full_rotating_hz(4, omega)
        np.testing.assert_allclose(sid_rotating_hz(path, omega), full, rtol=1e-4)
        assert full[0] > 1.4 * still[0] * ratio**0.5  # stiffened (without K_G it would soften)


def test_the_blade_read_from_the_inp_stiffens_like_the_built_in_one(tmp_path):
    """Every load case's K_G (static solves included) from the .inp route and the built-in one.

    The K read back differs from the built-in one by round-off (3e-16, the reader's symmetric
    assembly); the centrifugal cases keep that (1e-14), the bending-type cases (transverse
    accelerations and forces, whose K_G comes from bending stresses) amplify it to 3e-10."""
    paths = write_blade_as_abaqus(tmp_path, elements=4)
    body = read_abaqus(paths["STIF1"], paths["MASS1"], inp=paths["inp"])
    built = blade(elements=4)
    assert body.mesh.element == "hex20" and (body.mesh.young, body.mesh.poisson) == (2.1e11, 0.3)
    np.testing.assert_array_equal(body.mesh.connectivity, built.mesh.connectivity)
    ours = stiffening_from_mesh(prepare(body, Frame("none")), nodes=[1])
    theirs = stiffening_from_mesh(prepare(built, Frame("none")), nodes=[1])
    assert sorted(ours.cases) == sorted(theirs.cases) and len(ours.nodes) == 3
    for key, matrix in (*theirs.cases.items(), *theirs.nodes.items()):
        other = ours.cases[key] if isinstance(key, str) else ours.nodes[key]
        assert abs(other - matrix).max() <= 1e-9 * abs(matrix).max(), key
    for case in ("wxx", "wyy", "wzz", "ax"):
        matrix = theirs.cases[case]
        assert abs(ours.cases[case] - matrix).max() <= 1e-12 * abs(matrix).max(), case


def test_the_tet10_mesh_travels_in_the_native_file(unpacked, tmp_path):
    body = read_abaqus(
        genuine(f"{BEAM}/STIF1_coord_style.mtx", unpacked),
        genuine(f"{BEAM}/MASS1_coord_style.mtx", unpacked),
        inp=genuine(f"{BEAM}/abq_beam.inp", unpacked),
    )
    write_body_h5(body, tmp_path / "beam.h5")
    back = read_body_h5(tmp_path / "beam.h5")
    assert back.mesh.element == "tet10" and back.mesh.young == 208000.0
    np.testing.assert_array_equal(back.mesh.connectivity, body.mesh.connectivity)
    # The outer skin travels too: closed, outward, holding the volume of the tetrahedra.
    triangles = back.surface.triangles
    np.testing.assert_array_equal(triangles, body.surface.triangles)
    p = body.coordinates[body.node_rows(triangles)]
    enclosed = np.einsum("ij,ij->i", p[:, 0], np.cross(p[:, 1], p[:, 2])).sum() / 6.0
    c = body.coordinates[body.node_rows(body.mesh.connectivity[:, :4])]
    volume = np.abs(np.linalg.det(c[:, 1:] - c[:, :1])).sum() / 6.0
    assert enclosed == pytest.approx(volume, rel=1e-12)
    assert any(note.startswith("surface: outer faces of") for note in body.notes)


# ------------------------------------------------------------------ what the reader refuses
TWO_TETS = """*Node
1, 0., 0., 0.
2, 1., 0., 0.
3, 0., 1., 0.
4, 0., 0., 1.
5, 1., 1., 1.
*Element, type={type}, elset=all
1, 1, 2, 3, 4
2, 2, 3, 4, 5
{extra}{section}
*Material, name=steel
*Elastic{elastic_type}
{elastic}
"""


def tet_model(folder: Path, **fields: str) -> dict[str, Path]:
    """Two C3D4 tetrahedra in an .inp with their K (nodes 1-3 clamped by Abaqus penalties) and
    a unit M as FORMAT=COORDINATE files."""
    spec = {"type": "C3D4", "extra": "", "section": "*Solid Section, elset=all, material=steel",
            "elastic_type": "", "elastic": "2.0e11, 0.3", **fields}  # fmt: skip
    (folder / "tets.inp").write_text(TWO_TETS.format(**spec))
    xyz = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1], [1, 1, 1]], dtype=float)
    k = assemble_solid_stiffness("tet4", xyz, np.array([[0, 1, 2, 3], [1, 2, 3, 4]]), 2e11, 0.3)
    k = k.tocoo()
    values = np.where((k.row == k.col) & (k.row < 9), 1e36, k.data)  # nodes 1-3 clamped
    entries = zip(k.row, k.col, values, strict=True)
    (folder / "K.mtx").write_text("".join(f"{r + 1} {c + 1} {v:.17g}\n" for r, c, v in entries))
    (folder / "M.mtx").write_text("".join(f"{i + 1} {i + 1} 1.0\n" for i in range(15)))
    return {"inp": folder / "tets.inp", "K": folder / "K.mtx", "M": folder / "M.mtx"}


@pytest.mark.parametrize(
    ("fields", "why"),
    [
        ({"extra": "*Element, type=T3D2\n3, 1, 5\n"}, "T3D2, whose geometric stiffness is not"),
        ({"type": "C3D8R"}, "C3D8R, whose geometric stiffness is not implemented"),
        ({"section": ""}, "lies in no *SOLID SECTION"),
        (
            {"section": "*Solid Section, elset=all, material=rubber"},
            "material rubber, which is not",
        ),
        ({"elastic_type": ", type=ENGINEERING CONSTANTS"}, "TYPE=ENGINEERING CONSTANTS; only ISO"),
        ({"elastic": "2.0e11, 0.3, 20.\n1.9e11, 0.3, 200."}, "has 2 data lines"),
        ({"section": "*Solid Section, elset=some, material=steel"}, "element set some, which is"),
        ({"elastic": "1.0e11, 0.3"}, "E = 1e+11, nu = 0.3 differs from the model's K by 5.0e-01"),
    ],
)
def test_models_without_a_usable_mesh_are_read_and_stiffening_says_why(tmp_path, fields, why):
    paths = tet_model(tmp_path, **fields)
    body = read_abaqus(paths["K"], paths["M"], inp=paths["inp"])
    assert body.mesh is None and why in mesh_problem(body)


def test_mesh_error_is_one_line(tmp_path, capsys):
    paths = tet_model(tmp_path, type="C3D8R")
    job = JOB.format(
        model=f'stiffness = "{paths["K"]}"\nmass = "{paths["M"]}"\ninp = "{paths["inp"]}"'
    )
    job = job.replace("node = 1\n", "node = 5\n").replace("order = 30", "order = 2")
    (tmp_path / "job.toml").write_text(job.replace("[0, 50]", "[0]"))
    assert main(["reduce", str(tmp_path / "job.toml"), "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and 'source = "mesh" needs the elements' in err and "C3D8R" in err


def test_an_element_naming_an_unknown_node_is_refused(tmp_path):
    paths = tet_model(tmp_path)
    text = paths["inp"].read_text().replace("2, 2, 3, 4, 5", "2, 2, 3, 4, 9")
    paths["inp"].write_text(text)
    with pytest.raises(UserError, match="names node 9, which is not defined"):
        read_abaqus(paths["K"], paths["M"], inp=paths["inp"])


def test_an_inverted_element_is_a_user_error():
    nodes = _TET4[[0, 2, 1, 3]][None]
    with pytest.raises(UserError, match="non-positive Jacobian"):
        solid_stiffness("tet4", nodes, 2e11, 0.3)


# ------------------------------------------------------------------ Ansys SOLID186 (HexBeam)
HEXBEAM = Path(__file__).parents[1] / "data" / "pymapdl_reader_hexbeam"


def test_solid186_kinematics_reproduce_the_ansys_stiffness_with_the_material_of_its_run():
    """The genuine file.full does not come from the run of HexBeam.cdb's material (EX 7e10,
    PRXY 0.35): the reader refuses that mesh. K is linear in Lame's (lambda, mu); fitted to the
    free-free block of file.full, the 2 x 2 x 2 rule (SOLID186's default) reproduces it to 1e-13
    with E = 1.69e7, nu = 0.31, the full 3 x 3 x 3 rule misses by 2 %. With that material the
    archive's mesh is accepted."""
    from pymorembs.io.ansys import read_ansys_full

    body = read_ansys_full(HEXBEAM / "file.full", nodes=HEXBEAM / "HexBeam.cdb")
    assert body.mesh is None
    assert "hex20r elements with E = 7e+10, nu = 0.35 differs from the model's K" in mesh_problem(
        body
    )
    from pymorembs.io.ansys_cdb import read_cdb

    archive = read_cdb(HEXBEAM / "HexBeam.cdb")
    rows = body.node_rows(archive.element_nodes.reshape(-1, 20))
    equations = body.dofs.positions(body.node_ids[:, None], np.arange(3)).ravel()
    free = np.setdiff1d(np.arange(body.n_dof), body.fixed)
    target = body.stiffness.toarray()[np.ix_(free, free)].ravel()
    residual, fitted = {}, {}
    for kind in ("hex20r", "hex20"):
        parts = []
        for k in lame_parts(kind, body.coordinates, rows):  # K = lambda K_lambda + mu K_mu
            dense = np.zeros((body.n_dof, body.n_dof))
            dense[np.ix_(equations, equations)] = k.toarray()
            parts.append(dense[np.ix_(free, free)].ravel())
        basis = np.column_stack(parts)
        (lam, mu), *_ = np.linalg.lstsq(basis, target, rcond=None)
        residual[kind] = np.abs(basis @ [lam, mu] - target).max() / np.abs(target).max()
        fitted[kind] = (mu * (3 * lam + 2 * mu) / (lam + mu), lam / (2 * (lam + mu)))
    assert residual["hex20r"] < 1e-13 and residual["hex20"] > 1e-2
    young, poisson = fitted["hex20r"]
    assert young == pytest.approx(1.69e7, rel=1e-12) and poisson == pytest.approx(0.31, rel=1e-12)


def lame_parts(kind, coordinates, rows):
    """``K_lambda`` and ``K_mu`` of a mesh (``K = lambda K_lambda + mu K_mu``), from the
    stiffness of the Lame pairs (1, 1) and (2, 1)."""

    def k_of(lam, mu):
        young, poisson = mu * (3 * lam + 2 * mu) / (lam + mu), lam / (2 * (lam + mu))
        return assemble_solid_stiffness(kind, coordinates, rows, young, poisson)

    one, two = k_of(1.0, 1.0), k_of(2.0, 1.0)
    return two - one, 2.0 * one - two


def test_hexbeam_archive_with_the_material_of_the_run_gives_the_mesh(tmp_path):
    from pymorembs.io.ansys import read_ansys_full

    text = (HEXBEAM / "HexBeam.cdb").read_text()
    text = text.replace("7.000000000E+10", "1.690000000E+07").replace("0.350000000", "0.310000000")
    (tmp_path / "HexBeam.cdb").write_text(text)
    body = read_ansys_full(HEXBEAM / "file.full", nodes=tmp_path / "HexBeam.cdb")
    assert body.mesh is not None and body.mesh.element == "hex20r"
    assert (body.mesh.young, body.mesh.poisson) == (1.69e7, 0.31)
    assert body.mesh.connectivity.shape == (40, 20)
    assert "their stiffness reproduces K" in body.notes[-1]


# ------------------------------------------------------------------ Nastran CTETRA / CHEXA
def large_field(name: str, values: list) -> list[str]:
    """A large-field card (``NAME*``, 4 fields of 16 per line, ``*`` continuations)."""
    text = [sixteen(v) if isinstance(v, float) else str(v) for v in values]
    lines = [f"{name + '*':<8}" + "".join(f"{t:>16}" for t in text[:4])]
    for k in range(4, len(text), 4):
        lines.append(f"{'*':<8}" + "".join(f"{t:>16}" for t in text[k : k + 4]))
    return lines


def sixteen(value: float) -> str:
    """The most digits of ``value`` that fit a 16-column field."""
    for digits in range(17, 5, -1):
        text = f"{value:.{digits}g}"
        if len(text) <= 16:
            return text
    raise AssertionError(value)


def write_nastran_model(folder: Path, body, card: str, connectivity: np.ndarray, material: str):
    """GRID, solid element, PSOLID and MAT1 cards and the body's K and M as DMIG (KAAX, MAAX,
    upper triangles in free field, every dof in the a-set) in one punch-like file."""
    lines = ["$ written by the test"]
    for nid, (x, y, z) in zip(body.node_ids, body.coordinates, strict=True):
        lines += large_field("GRID", [int(nid), 0, float(x), float(y), float(z), 0])
    for eid, grids in enumerate(connectivity, start=1):
        lines += large_field(card, [eid, 7, *map(int, grids)])
    lines += ["PSOLID,7,3", material]
    for name, matrix in (("KAAX", body.stiffness), ("MAAX", body.mass)):
        upper = sp.triu(sp.csr_matrix(matrix)).tocsc()
        lines.append(f"DMIG,{name},0,6,2,0,,,{body.n_dof}")
        for j in range(body.n_dof):
            rows = upper.indices[upper.indptr[j] : upper.indptr[j + 1]]
            if not rows.size:
                continue
            values = upper.data[upper.indptr[j] : upper.indptr[j + 1]]
            gj, cj = int(body.dofs.nodes[j]), int(body.dofs.directions[j]) + 1
            entries = [
                f"{int(body.dofs.nodes[i])},{int(body.dofs.directions[i]) + 1},{float(v)!r}"
                for i, v in zip(rows, values, strict=True)
            ]  # free field: every digit (the blade's K is ill-conditioned)
            lines.append(f"DMIG,{name},{gj},{cj},,{entries[0]}")
            lines += ["," + ",,".join(entries[k : k + 2]) for k in range(1, len(entries), 2)]
    path = folder / "model.pch"
    path.write_text("\n".join(lines) + "\n")
    return path


def test_chexa20_and_mat1_give_the_blade_mesh(tmp_path):
    """The free blade as Nastran cards: CHEXA grids in Nastran's order (edges G13-G16 along the
    blade's thickness direction before the face G17-G20), MAT1 with E and NU."""
    from pymorembs.io.nastran_dmig import read_dmig

    built = blade(elements=4)
    free = replace(built, fixed=np.zeros(0, dtype=np.int64))
    hex20 = built.mesh.connectivity
    nastran = np.empty_like(hex20)
    nastran[:, [*range(12), 16, 17, 18, 19, 12, 13, 14, 15]] = hex20  # written in CHEXA order
    path = write_nastran_model(tmp_path, free, "CHEXA", nastran, "MAT1,3,2.1+11,,0.3")
    body = read_dmig(path, nodes=path)
    assert body.mesh is not None, body.notes
    assert body.mesh.element == "hex20" and (body.mesh.young, body.mesh.poisson) == (2.1e11, 0.3)
    np.testing.assert_array_equal(body.mesh.connectivity, hex20)
    u = np.random.default_rng(5).standard_normal(body.n_dof) * 1e-4
    a, b = geometric_stiffness(built, u), geometric_stiffness(body, u)
    assert abs(a - b).max() <= 1e-12 * abs(a).max()


def test_ctetra10_beam_with_the_abaqus_matrices(unpacked, tmp_path):
    """The genuine C3D10 beam written as CTETRA cards with MAT1 E, G (NU derived) and its Abaqus
    K and M: the same tet10 mesh, accepted by the stiffness check."""
    from pymorembs.io.nastran_dmig import read_dmig

    beam = read_abaqus(
        genuine(f"{BEAM}/STIF1_coord_style.mtx", unpacked),
        genuine(f"{BEAM}/MASS1_coord_style.mtx", unpacked),
        inp=genuine(f"{BEAM}/abq_beam.inp", unpacked),
    )
    shear = 208000.0 / 2.6
    path = write_nastran_model(
        tmp_path, beam, "CTETRA", beam.mesh.connectivity, f"MAT1,3,208000.,{shear!r}"
    )
    body = read_dmig(path, nodes=path)
    assert body.mesh is not None and body.mesh.element == "tet10"
    assert body.mesh.poisson == pytest.approx(0.3, rel=1e-14)
    np.testing.assert_array_equal(body.mesh.connectivity, beam.mesh.connectivity)
    assert any("their stiffness reproduces K" in note for note in body.notes)


def test_nastran_shells_next_to_solids_leave_no_mesh(tmp_path):
    from pymorembs.io.nastran_dmig import read_dmig

    built = replace(blade(elements=4), fixed=np.zeros(0, dtype=np.int64))
    nastran = built.mesh.connectivity[:, [*range(12), 16, 17, 18, 19, 12, 13, 14, 15]]
    path = write_nastran_model(tmp_path, built, "CHEXA", nastran, "MAT1,3,2.1+11,,0.3")
    path.write_text(path.read_text() + "CQUAD4,99,7,1,2,3,4\n")
    body = read_dmig(path, nodes=path)
    assert body.mesh is None and "CQUAD4 elements" in mesh_problem(body)


def test_elements_of_two_materials(tmp_path):
    """Two *SOLID SECTION s with different materials: one E, nu per element, checked against
    the K of the two materials, kept in the native file."""
    inp = TWO_TETS.format(
        type="C3D4",
        extra="*Elset, elset=one\n1\n*Elset, elset=two\n2\n",
        section="*Solid Section, elset=one, material=steel\n"
        "*Solid Section, elset=two, material=alu\n*Material, name=alu\n*Elastic\n7.0e10, 0.33",
        elastic_type="",
        elastic="2.0e11, 0.3",
    )
    (tmp_path / "tets.inp").write_text(inp)
    xyz = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1], [1, 1, 1]], dtype=float)
    conn = np.array([[0, 1, 2, 3], [1, 2, 3, 4]])
    k = assemble_solid_stiffness("tet4", xyz, conn, np.array([2e11, 7e10]), np.array([0.3, 0.33]))
    reference = assemble_solid_stiffness("tet4", xyz, conn[:1], 2e11, 0.3)
    reference = reference + assemble_solid_stiffness("tet4", xyz, conn[1:], 7e10, 0.33)
    assert abs(k - reference).max() <= 1e-15 * abs(reference).max()  # per-element materials
    k = k.tocoo()
    values = np.where((k.row == k.col) & (k.row < 9), 1e36, k.data)
    entries = zip(k.row, k.col, values, strict=True)
    (tmp_path / "K.mtx").write_text("".join(f"{r + 1} {c + 1} {v:.17g}\n" for r, c, v in entries))
    (tmp_path / "M.mtx").write_text("".join(f"{i + 1} {i + 1} 1.0\n" for i in range(15)))
    body = read_abaqus(tmp_path / "K.mtx", tmp_path / "M.mtx", inp=tmp_path / "tets.inp")
    assert body.mesh is not None, body.notes
    np.testing.assert_array_equal(body.mesh.young, [2e11, 7e10])
    np.testing.assert_array_equal(body.mesh.poisson, [0.3, 0.33])
    assert "2 materials" in body.notes[-1]
    write_body_h5(body, tmp_path / "tets.h5")
    back = read_body_h5(tmp_path / "tets.h5")
    np.testing.assert_array_equal(back.mesh.young, body.mesh.young)
    u = np.random.default_rng(2).standard_normal(body.n_dof)
    assert abs(geometric_stiffness(back, u) - geometric_stiffness(body, u)).max() == 0.0


def test_nx_nastran_element_matrices_of_ctetra_and_chexa():
    """The genuine NX Nastran 2412 OP2 holds each element's stiffness (KELM, packed upper
    triangles; no KDICT to order their dofs, so spectra are compared, which no node order
    changes). Its two CTETRA (MAT1 E = 2.9e7, G = 1.1e7, NU = 0.32) are the tet4 kinematics with
    E and NU (3e-16; with E from G and NU: 1e-3 off); its CHEXA (8 grids) is not the plain
    2 x 2 x 2 hexahedron (10 % off: NX's own formulation), which is why a CHEXA8 mesh is only
    attached when its K check passes."""
    from pymorembs.io.pynastran_compat import op2_class, quiet_logger

    op2 = op2_class()(debug=False, log=quiet_logger())
    folder = Path(__file__).parents[1] / "data" / "pynastran" / "op2_kgg_kelm"
    op2.read_op2(str(folder / "static_solid_shell_bar_kelm.op2"), skip_undefined_matrices=True)
    kelm = np.asarray(op2.matrices["KELM"].data)

    def spectrum(size: int, column: np.ndarray) -> np.ndarray:
        a = np.zeros((size, size))
        a[np.triu_indices(size)] = column[: size * (size + 1) // 2]
        return np.linalg.eigvalsh(a + np.triu(a, 1).T)

    def closest(ours: np.ndarray) -> float:
        size = ours.shape[0]
        theirs = [spectrum(size, kelm[:, j]) for j in range(kelm.shape[1])]
        ref = np.linalg.eigvalsh(ours)
        return min(np.abs(t - ref).max() / ref.max() for t in theirs)

    xyz = {
        1: (0, 0, 0),
        2: (1, 0, 0),
        3: (1, 1, 0),
        4: (0, 1, 0),
        5: (1, 1, 1),
        6: (0, 1, 1),
        7: (0, 0, 1),
        8: (1, 0, 1),
        9: (1, 1, 2),
        10: (0, 1, 2),
        11: (1, 0, 2),
        12: (0, 0, 2),
        13: (0.5, 0.5, 3),
    }  # fmt: skip  (the GRID cards of geom.inc / the .bdf)
    for grids in ([10, 11, 9, 13], [10, 12, 11, 13]):  # CTETRA 4 and 5
        nodes = np.array([xyz[g] for g in grids], dtype=float)
        nodes = nodes[[0, 2, 1, 3]] if np.linalg.det(nodes[1:] - nodes[0]) < 0 else nodes
        assert closest(solid_stiffness("tet4", nodes[None], 2.9e7, 0.32)[0]) < 1e-14
        assert closest(solid_stiffness("tet4", nodes[None], 2 * 1.1e7 * 1.32, 0.32)[0]) > 1e-4
    hexa = np.array([xyz[g] for g in (2, 3, 4, 1, 8, 5, 6, 7)], dtype=float)  # CHEXA 1
    assert closest(solid_stiffness("hex8", hexa[None], 2.9e7, 0.32)[0]) > 0.05


def ritz_rotating_cantilever_hz(omega: float, n: int = 10) -> float:
    """First flapwise frequency (Hz) of a rotating Euler-Bernoulli cantilever, root on the axis:
    Ritz with w = sum c_j z^(j+1), tension T(z) = rho A omega² (L² - z²) / 2 (the 20 x 20 x
    500 mm steel beam of abq_beam.inp, mm-t-s units)."""
    e, rho, side, length = 208000.0, 7.85e-9, 20.0, 500.0
    xi, wi = np.polynomial.legendre.leggauss(60)
    z, w = 0.5 * length * (xi + 1.0), 0.5 * length * wi
    j = np.arange(1, n + 1)[:, None]
    phi, d1, d2 = z ** (j + 1), (j + 1) * z**j, (j + 1) * j * z ** (j - 1)
    area, inertia = side**2, side**4 / 12
    tension = rho * area * omega**2 * 0.5 * (length**2 - z**2)
    k = e * inertia * (d2 * w) @ d2.T + (d1 * tension * w) @ d1.T
    m = rho * area * (phi * w) @ phi.T
    return float(np.sqrt(sl.eigh(k, m, eigvals_only=True)[0]) / (2 * np.pi))


def test_spinning_c3d10_beam_stiffens_like_the_rotating_cantilever(unpacked):
    """The C3D10 beam spun about the x axis through its root centre: its first x-bending
    (flapwise: out of the plane of rotation, no spin softening) frequency of K + Omega² K_G(wxx)
    over the non-rotating one, against the Ritz ratio of the rotating Euler-Bernoulli beam
    (1.4766 at Omega = omega_1, 2.3692 at 2 omega_1; the mesh gives 1.4738 and 2.3621, within
    0.3 %: its stiffness error cancels in the ratio, 66.82 Hz against Euler-Bernoulli's 66.52)."""
    body = read_abaqus(
        genuine(f"{BEAM}/STIF1_coord_style.mtx", unpacked),
        genuine(f"{BEAM}/MASS1_coord_style.mtx", unpacked),
        inp=genuine(f"{BEAM}/abq_beam.inp", unpacked),
    )
    free = np.setdiff1d(np.arange(body.n_dof), body.fixed)
    k, m = body.stiffness.tocsr(), body.mass.tocsr()
    x, y, z = body.coordinates.T
    load = m @ np.column_stack([0 * x, y + 20.0, z]).ravel()  # unit Omega about x at (0, -20, 0)
    u = np.zeros(body.n_dof)
    u[free] = spla.spsolve(k[free][:, free].tocsc(), load[free])
    k_g = geometric_stiffness(body, u).tocsr()
    in_plane = sp.diags((body.dofs.directions > 0).astype(float))  # y, z: spin softening
    along_x = body.dofs.directions[free] == 0

    def first_hz(omega: float) -> float:
        a = (k + omega**2 * (k_g - in_plane @ m @ in_plane))[free][:, free]
        values, vectors = spla.eigsh(a.tocsc(), k=4, M=m[free][:, free].tocsc(), sigma=0.0)
        share = np.sum(vectors[along_x] ** 2, axis=0) / np.sum(vectors**2, axis=0)
        flapwise = values[share > 0.5]  # the x-bending modes (out of the plane of rotation)
        return float(np.sqrt(flapwise.min()) / (2 * np.pi))

    still = first_hz(0.0)
    assert still == pytest.approx(ritz_rotating_cantilever_hz(0.0), rel=0.02)
    for ratio in (1.0, 2.0):
        omega = ratio * 2 * np.pi * ritz_rotating_cantilever_hz(0.0)
        expected = ritz_rotating_cantilever_hz(omega) / ritz_rotating_cantilever_hz(0.0)
        assert first_hz(omega) / still == pytest.approx(expected, rel=5e-3)


@pytest.mark.slow
def test_blade_read_from_nastran_cards_gives_a_stiffened_sid(tmp_path):
    """End to end from Nastran: the blade's DMIG K and M with GRID/CHEXA/PSOLID/MAT1 cards and
    its clamped root as fixed.csv; the spinning SID body against the full built-in model."""
    from pymorembs.io.matrix_market import write_matrix_files

    built = blade(elements=4)
    free = replace(built, fixed=np.zeros(0, dtype=np.int64))
    nastran = built.mesh.connectivity[:, [*range(12), 16, 17, 18, 19, 12, 13, 14, 15]]
    path = write_nastran_model(tmp_path, free, "CHEXA", nastran, "MAT1,3,2.1+11,,0.3")
    write_matrix_files(built, tmp_path / "csv")
    model = f'file = "{path}"\nnodes = "{path}"\nfixed = "{tmp_path / "csv" / "fixed.csv"}"'
    (tmp_path / "job.toml").write_text(JOB.format(model=model))
    out = tmp_path / "out"
    assert main(["reduce", str(tmp_path / "job.toml"), "--out", str(out), "--quiet"]) == 0
    sid = out / "krylov" / "krylov.SID_FEM"
    assert read_sid(sid).geometric_stiffening
    still = full_rotating_hz(4, 0.0)
    for ratio in (1.0, 2.0):
        omega = ratio * 2 * np.pi * still[0]
        np.testing.assert_allclose(
            sid_rotating_hz(sid, omega), full_rotating_hz(4, omega), rtol=1e-4
        )
