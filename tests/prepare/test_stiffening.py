"""Geometric stiffening written into SID (issue #15 item 2): the rotating blade from the file.

The reference is a direct eigen-solution of the full blade in its rotating frame,
``(K + Omega² (K_G - M_xy)) u = omega² M u`` (K_G of the centrifugal prestress of a unit angular
velocity about z, spin softening ``M_xy``, Coriolis left out on both sides), solved with scipy;
the reduced body's frequencies come from the SID file as written and read back:
``(Ke + Omega² Oe.M1[:, :, wzz]) q = omega² Me q``.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import scipy.linalg as sla
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from conftest import blade_job
from pymorembs.analysis.exudyn_model import build_exudyn_model, simulate_exudyn
from pymorembs.elements.solid import assemble_solid_geometric
from pymorembs.errors import UserError
from pymorembs.examples.blade import blade, blade_mesh
from pymorembs.export.exudyn_body import exudyn_arrays, load_exudyn_body
from pymorembs.export.sid import check_sid, read_sid
from pymorembs.io.matrix_market import write_matrix_market
from pymorembs.job.cli import main
from pymorembs.job.schema import parse_job

ELEMENTS = 12
RHO_A = 7850.0 * 0.04 * 0.01  # kg/m
JOB = f"""
[model]
example = "blade"
elements = {ELEMENTS}

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
outputs = ["sid", "exudyn", "neweul"]
nodes = [1]
"""


def full_rotating_hz(omega: float, k_g: sp.spmatrix) -> np.ndarray:
    body = blade(elements=ELEMENTS)
    free = np.setdiff1d(np.arange(body.n_dof), body.fixed)
    k, m = body.stiffness.tocsr(), body.mass.tocsr()
    in_plane = sp.diags(np.tile([1.0, 1.0, 0.0], body.n_nodes))
    a = (k + omega**2 * (k_g - in_plane @ m @ in_plane))[free][:, free]
    values = spla.eigsh(a.tocsc(), k=3, M=m[free][:, free].tocsc(), sigma=0.0)[0]
    return np.sqrt(np.sort(values)) / (2 * np.pi)


def centrifugal_k_g() -> sp.csr_matrix:
    """K_G of the d'Alembert load -M W_zz c of a unit angular velocity about z (scipy solve)."""
    body, mesh = blade(elements=ELEMENTS), blade_mesh(elements=ELEMENTS)
    free = np.setdiff1d(np.arange(body.n_dof), body.fixed)
    k, m = body.stiffness.tocsr(), body.mass.tocsr()
    x, y, _ = mesh.coordinates.T
    load = m @ np.column_stack([x, y, 0 * x]).ravel()
    u = np.zeros(body.n_dof)
    u[free] = spla.spsolve(k[free][:, free].tocsc(), load[free])
    return assemble_solid_geometric(
        "hex20", mesh.coordinates, mesh.elements, u, 2.1e11, 0.3
    ).tocsr()


def sid_rotating_hz(path: Path, omega: float) -> np.ndarray:
    sid = read_sid(path)
    me, ke, oe1 = sid.objects["Me"].m0, sid.objects["Ke"].m0, sid.objects["Oe"].first
    values = sla.eigh(ke + omega**2 * oe1[:, :, 2], me, eigvals_only=True)
    return np.sqrt(np.sort(values)[:3]) / (2 * np.pi)


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    folder = tmp_path_factory.mktemp("stiff")
    k_g = centrifugal_k_g()
    write_matrix_market(folder / "KG_wzz.mtx", k_g)
    out = {}
    for name, table in (
        ("mesh", '[stiffening]\nsource = "mesh"\n'),
        ("matrices", '[stiffening]\nsource = "matrices"\nmatrices = { wzz = "KG_wzz.mtx" }\n'),
        ("none", ""),
    ):
        (folder / f"{name}.toml").write_text(JOB + table)
        assert main(["reduce", str(folder / f"{name}.toml"), "--out", str(folder / name),
                     "--quiet"]) == 0  # fmt: skip
        out[name] = folder / name
    return out, k_g


def test_stiffened_frequencies_from_the_sid_match_the_full_model(runs):
    folders, k_g = runs
    path = folders["mesh"] / "krylov" / "krylov.SID_FEM"
    sid = read_sid(path)
    assert sid.geometric_stiffening and check_sid(sid) == []
    w1 = 2 * np.pi * full_rotating_hz(0.0, k_g)[0]
    for ratio in (0.5, 1.0, 2.0):
        full = full_rotating_hz(ratio * w1, k_g)
        np.testing.assert_allclose(sid_rotating_hz(path, ratio * w1), full, rtol=1e-4)
    # and the stiffening is real: +48 % flapwise at Omega = omega_1 (rotating beam: 1.4765)
    assert full_rotating_hz(w1, k_g)[0] / full_rotating_hz(0.0, k_g)[0] == pytest.approx(
        1.476, rel=5e-3
    )


def test_user_matrices_give_the_same_body(runs):
    folders, k_g = runs
    w1 = 2 * np.pi * full_rotating_hz(0.0, k_g)[0]
    for ratio in (1.0, 2.0):
        mesh = sid_rotating_hz(folders["mesh"] / "krylov" / "krylov.SID_FEM", ratio * w1)
        given = sid_rotating_hz(folders["matrices"] / "krylov" / "krylov.SID_FEM", ratio * w1)
        np.testing.assert_allclose(given, mesh, rtol=1e-6)


def test_without_stiffening_the_blade_softens_and_the_summary_says_what_carries_it(runs):
    folders, k_g = runs
    plain = read_sid(folders["none"] / "krylov" / "krylov.SID_FEM")
    assert not plain.geometric_stiffening
    w1 = 2 * np.pi * full_rotating_hz(0.0, k_g)[0]
    f = sid_rotating_hz(folders["none"] / "krylov" / "krylov.SID_FEM", w1)
    assert f[0] == pytest.approx(w1 / (2 * np.pi), rel=1e-4)  # flapwise: no stiffening at all
    summary = json.loads((folders["mesh"] / "summary.json").read_text())
    assert summary["model"]["stiffening"]["source"] == "mesh"
    assert summary["model"]["stiffening"]["node_loads"] == ["1:ux", "1:uy", "1:uz"]
    body = load_exudyn_body(folders["mesh"] / "krylov" / "krylov_exudyn.npz")
    nq = body["massMatrixReduced"].shape[0]
    assert body["stiffeningOmega"].shape == (6, nq, nq) and np.any(body["stiffeningOmega"][2])
    assert np.any(body["stiffeningAcceleration"]) and np.any(body["stiffeningNodeForces"])
    assert "neweul" in summary["model"]["stiffening"]["written_to"]


def test_a_tip_tension_stiffens_through_the_node_force_jacobian(runs):
    """phi.M1 = -K0 of a unit tip force: the SID equation ``Ke q + ... = phi(q)^T F`` gives
    ``(Ke - F phi.M1[x]) q`` under a tip tension F, checked against the full K + F K_G."""
    folders, _ = runs
    sid = read_sid(folders["mesh"] / "krylov" / "krylov.SID_FEM")
    phi1 = sid.nodes[1]["phi"].first  # (3, nq, nq), [a, l, k]
    me, ke = sid.objects["Me"].m0, sid.objects["Ke"].m0
    force = 5000.0  # N along +x at the tip
    reduced = np.sqrt(sla.eigh(ke - force * phi1[0].T, me, eigvals_only=True)[:2]) / (2 * np.pi)
    body, mesh = blade(elements=ELEMENTS), blade_mesh(elements=ELEMENTS)
    free = np.setdiff1d(np.arange(body.n_dof), body.fixed)
    k, m = body.stiffness.tocsr(), body.mass.tocsr()
    tip = np.zeros(body.n_dof)
    tip[body.dofs.index(1, 0)] = 1.0
    u = np.zeros(body.n_dof)
    u[free] = spla.spsolve(k[free][:, free].tocsc(), tip[free])
    k_g = assemble_solid_geometric("hex20", mesh.coordinates, mesh.elements, u, 2.1e11, 0.3).tocsr()
    a = (k + force * k_g)[free][:, free]
    full = np.sqrt(np.sort(spla.eigsh(a.tocsc(), k=2, M=m[free][:, free].tocsc(), sigma=0)[0]))
    np.testing.assert_allclose(reduced, full / (2 * np.pi), rtol=1e-5)
    plain = np.sqrt(sla.eigh(ke, me, eigvals_only=True)[0]) / (2 * np.pi)
    assert reduced[0] > 1.01 * plain  # the tension stiffens the first flapwise mode


@pytest.mark.parametrize(
    ("table", "message"),
    [
        ({"source": "grid"}, r"\[stiffening\]\.source: must be 'mesh', 'matrices' or 'none'"),
        ({"source": "matrices"}, r"needs at least one load case file"),
        ({"source": "matrices", "matrices": {"wz": "a.mtx"}}, r"unknown load case 'wz'"),
        ({"source": "matrices", "matrices": {"wzz": "none.mtx"}}, r"wzz: file .* not found"),
        ({"source": "mesh", "kind": "pre"}, r"kind: must be 'geometric' or 'prestressed'"),
    ],
)
def test_bad_stiffening_tables(tmp_path, table, message):
    with pytest.raises(UserError, match=message):
        parse_job(blade_job(stiffening=table), tmp_path / "job.toml")


def test_mesh_source_needs_elements(tmp_path, capsys):
    """Matrix files carry no elements: the mesh route says so (and what to do) before any work."""
    from pymorembs.io.matrix_market import write_matrix_files

    write_matrix_files(blade(elements=4), tmp_path / "model")
    job = JOB.replace('example = "blade"\nelements = 12', 'stiffness = "model/K.mtx"\n'
                      'mass = "model/M.mtx"\ndofs = "model/dofs.csv"\nnodes = "model/nodes.csv"\n'
                      'fixed = "model/fixed.csv"')  # fmt: skip
    (tmp_path / "job.toml").write_text(job + '[stiffening]\nsource = "mesh"\n')
    assert main(["reduce", str(tmp_path / "job.toml"), "--out", str(tmp_path / "out")]) == 2
    assert 'source = "mesh" needs the elements' in capsys.readouterr().err
    assert not (tmp_path / "out").exists()


#: The simulations of the reduced blade in Exudyn (5-7 s each on 2 cores) are in the slow set
#: (`make test-slow`, which CI runs too).
exudyn_run = pytest.mark.slow


def exudyn_models(elements: int = ELEMENTS, order: int = 8):
    from pymorembs.export.source import body_invariants
    from pymorembs.preparation import Frame, Port, prepare
    from pymorembs.preparation.stiffening import stiffening_from_mesh, with_stiffening
    from pymorembs.reduction.modal import modal_reduction
    from pymorembs.reduction.projection import reduced_model

    body = blade(elements=elements)
    ports = [Port.parse(1, "ux uy uz")]
    plain = prepare(body, Frame("none"), ports, ports)
    stiffened = with_stiffening(plain, stiffening_from_mesh(plain, nodes=[1]))
    model = reduced_model(plain.system, modal_reduction(plain.system, order))
    return model, {
        "plain": exudyn_arrays(body_invariants(model, plain, [1, 2], "plain")),
        "stiffened": exudyn_arrays(body_invariants(model, stiffened, [1, 2], "stiffened")),
    }


@exudyn_run
def test_exudyn_body_spinning_at_its_flap_frequency_vibrates_stiffened():
    """Steady spin about z at Omega = omega_1 with a small flap deflection: the flap vibration in
    Exudyn at the reduced body's stiffened frequency (linear (Ke + Omega² Oe.M1) prediction)."""
    pytest.importorskip("exudyn")
    model, arrays = exudyn_models()
    omega = 2 * np.pi * model.eigenfrequencies_hz[0]
    start = np.zeros(model.projection.order)
    start[0] = 1e-3
    found = {}
    for name, body in arrays.items():
        exudyn = build_exudyn_model(body, clamp="frame", hinge_axis=[0, 0, 1],
                                    initial_angular_velocity=[0, 0, omega],
                                    initial_coordinates=start, damping="none")  # fmt: skip
        result = simulate_exudyn(exudyn, 2.0, 5e-4, spectral_radius=0.95)
        x = result.coordinates[:, 0] - result.coordinates[:, 0].mean()
        spectrum = np.abs(np.fft.rfft(x * np.hanning(x.size), n=32 * x.size))
        found[name] = np.fft.rfftfreq(32 * x.size, 5e-4)[np.argmax(spectrum)]
        assert np.linalg.norm(result.angular_velocity[-1]) == pytest.approx(omega, rel=1e-6)
    me, ke = np.eye(model.projection.order), np.diag(model.system.stiffness)
    k0 = arrays["stiffened"]["stiffeningOmega"][2]  # wzz
    # flapwise motion has no spin softening (omega x (omega x u) has no z part): K0 alone
    linear = np.sqrt(sla.eigh(np.diag(ke) + omega**2 * k0, me, eigvals_only=True))
    assert found["plain"] == pytest.approx(model.eigenfrequencies_hz[0], rel=5e-3)
    assert found["stiffened"] == pytest.approx(linear[0] / (2 * np.pi), rel=5e-3)
    assert found["stiffened"] > 1.45 * found["plain"]


def full_prestressed_hz(load: np.ndarray) -> float:
    """First frequency (Hz) of the full blade prestressed by a static load (n_dof,): K + K_G."""
    body, mesh = blade(elements=ELEMENTS), blade_mesh(elements=ELEMENTS)
    free = np.setdiff1d(np.arange(body.n_dof), body.fixed)
    k, m = body.stiffness.tocsr(), body.mass.tocsr()
    u = np.zeros(body.n_dof)
    u[free] = spla.spsolve(k[free][:, free].tocsc(), load[free])
    k_g = assemble_solid_geometric("hex20", mesh.coordinates, mesh.elements, u, 2.1e11, 0.3).tocsr()
    a = (k + k_g)[free][:, free]
    value = spla.eigsh(a.tocsc(), k=1, M=m[free][:, free].tocsc(), sigma=0)[0][0]
    return float(np.sqrt(value) / (2 * np.pi))


def flap_hz(result, step: float) -> float:
    """Dominant frequency (Hz) of the first elastic coordinate."""
    x = result.coordinates[:, 0] - result.coordinates[:, 0].mean()
    spectrum = np.abs(np.fft.rfft(x * np.hanning(x.size), n=32 * x.size))
    return float(np.fft.rfftfreq(32 * x.size, step)[np.argmax(spectrum)])


@exudyn_run
@pytest.mark.parametrize("load", ["gravity", "tip force"])
def test_exudyn_body_under_an_axial_load_vibrates_stiffened(load):
    """Gravity along the blade (the acceleration load case ax, weighted by A^T (r'' - g)) and a
    tip tension (the node-force case) stiffen the Exudyn body's flapwise vibration as the full
    model K + K_G of the same static load predicts."""
    pytest.importorskip("exudyn")
    model, arrays = exudyn_models()
    body = blade(elements=ELEMENTS)
    start = np.zeros(model.projection.order)
    start[0] = 1e-3
    if load == "gravity":
        g = 3000.0  # m/s² along +x: the blade hangs outward, in tension
        options = {"gravity": [g, 0.0, 0.0]}
        static = body.mass @ np.tile([g, 0.0, 0.0], body.n_nodes)
    else:
        options = {"loads": [(1, [3000.0, 0.0, 0.0])]}  # N at the tip, along +x
        static = np.zeros(body.n_dof)
        static[body.dofs.index(1, 0)] = 3000.0
    found = {}
    for name, data in arrays.items():
        exudyn = build_exudyn_model(data, clamp="frame", initial_coordinates=start,
                                    damping="none", **options)  # fmt: skip
        found[name] = flap_hz(simulate_exudyn(exudyn, 2.0, 5e-4, spectral_radius=0.95), 5e-4)
    full = full_prestressed_hz(static)
    assert found["stiffened"] == pytest.approx(full, rel=5e-3)
    assert found["plain"] == pytest.approx(model.eigenfrequencies_hz[0], rel=5e-3)
    assert found["stiffened"] > 1.05 * found["plain"]


def test_the_stiffening_force_takes_every_input_in_body_coordinates():
    """The force user function against a direct sum: a rotated frame, angular velocity,
    acceleration, angular acceleration, gravity and a node force (time function)."""
    pytest.importorskip("exudyn")
    import exudyn
    from scipy.spatial.transform import Rotation

    from pymorembs.analysis.exudyn_model import stiffening_force

    _, arrays = exudyn_models(elements=4, order=4)
    data = dict(arrays["stiffened"])
    nq = data["massMatrixReduced"].shape[0]
    rng = np.random.default_rng(3)
    for key in ("stiffeningOmega", "stiffeningAcceleration", "stiffeningAngularAcceleration"):
        data[key] = rng.standard_normal(data[key].shape)  # make every case count
    data["stiffeningNodeForces"] = rng.standard_normal((data["nodeIds"].size, 3, nq, nq))
    turn = Rotation.from_rotvec([0.3, -0.5, 0.8])
    x, y, z, w = turn.as_quat()
    p = np.array([w, x, y, z])
    omega_body = np.array([1.5, -2.0, 0.7])
    # dp/dt = G(p)^T omega_body / 2 for unit p
    gp = np.array([[-x, w, z, -y], [-y, -z, w, x], [-z, y, -x, w]])
    q = np.concatenate([[0.1, 0.2, 0.3], p - [1, 0, 0, 0], rng.standard_normal(nq)])
    q_t = np.concatenate([[0.0] * 3, 0.5 * gp.T @ omega_body, np.zeros(nq)])
    a, alpha, g = np.array([1.0, -4.0, 2.0]), np.array([0.5, 3.0, -1.0]), np.array([0, 0, -9.81])

    class Outputs:
        def GetNodeOutput(self, node, kind, configuration):
            assert configuration == exudyn.ConfigurationType.Current
            return {exudyn.OutputVariableType.Acceleration: a,
                    exudyn.OutputVariableType.AngularAcceleration: alpha}[kind]  # fmt: skip

    def tip_force(t):
        return np.array([10.0 * t, 2.0, -3.0])

    force = stiffening_force(data, 0, g, [(1, tip_force)])
    out = np.asarray(force(Outputs(), 0.5, 0, q, q_t))
    to_body = turn.as_matrix().T
    wx, wy, wz = omega_body
    weights = np.concatenate([
        [wx * wx, wy * wy, wz * wz, wx * wy, wy * wz, wx * wz],
        to_body @ (a - g), to_body @ alpha, to_body @ tip_force(0.5),
    ])  # fmt: skip
    row = int(np.flatnonzero(data["nodeIds"] == 1)[0])
    k0 = np.concatenate([data["stiffeningOmega"], data["stiffeningAcceleration"],
                         data["stiffeningAngularAcceleration"],
                         data["stiffeningNodeForces"][row]])  # fmt: skip
    expected = -np.einsum("c,cij,j->i", weights, k0, q[7:])
    np.testing.assert_allclose(out[7:], expected, rtol=1e-12, atol=1e-12 * np.abs(expected).max())
    assert not np.any(out[:7])


@exudyn_run
def test_exudyn_spin_up_above_the_edgewise_frequency_is_stable_only_when_stiffened():
    pytest.importorskip("exudyn")
    model, arrays = exudyn_models()
    target = 1.2 * 2 * np.pi * model.eigenfrequencies_hz[1]  # above the in-plane frequency
    inertia = RHO_A * 1.0**3 / 3  # rigid blade about its root, kg m²
    peak = 2 * inertia * target / 1.0  # sin² torque over 1 s reaches the target

    def torque(t):
        return np.array([0.0, 0.0, peak * np.sin(np.pi * t) ** 2 if t <= 1.0 else 0.0])

    tip = {}
    for name, body in arrays.items():
        exudyn = build_exudyn_model(body, clamp="frame", hinge_axis=[0, 0, 1], torques=[torque])
        result = simulate_exudyn(exudyn, 1.5, 5e-4)
        rows = body["modeBasis"][3 * int(body["nodeMeshIndices"][0]) :][:3]
        tip[name] = float(np.abs(result.coordinates @ rows.T).max())
        if name == "stiffened":
            assert np.linalg.norm(result.angular_velocity[-1]) == pytest.approx(target, rel=2e-2)
    assert tip["stiffened"] < 0.02  # m: bent by the angular acceleration only
    assert tip["plain"] > 10 * tip["stiffened"]  # the softened edgewise mode runs away


def test_neweul_file_holds_the_same_stiffening_as_the_sid(runs):
    import scipy.io

    folders, _ = runs
    sid = read_sid(folders["mesh"] / "krylov" / "krylov.SID_FEM")
    mat = scipy.io.loadmat(folders["mesh"] / "krylov" / "krylov_neweul.mat", squeeze_me=False)
    assert mat["geometric_stiffening"].item() == 1.0
    scale = np.abs(sid.objects["Oe"].first).max()
    np.testing.assert_allclose(
        mat["Oe1"] + mat["K0w"], sid.objects["Oe"].first, rtol=0, atol=1e-10 * scale
    )
    node = mat["nodes"][0, 0]
    phi1 = sid.nodes[1]["phi"].first  # [a, l, k] = -K0f[k, l, a]
    np.testing.assert_allclose(
        -node["K0f"].transpose(2, 1, 0), phi1, rtol=0, atol=1e-10 * np.abs(phi1).max()
    )
    plain = scipy.io.loadmat(folders["none"] / "krylov" / "krylov_neweul.mat")
    assert plain["geometric_stiffening"].item() == 0.0 and not np.any(plain["K0w"])


@pytest.mark.parametrize("name", ["blade", "rack-beams"])
def test_the_elements_travel_in_the_native_file(tmp_path, name):
    from pymorembs.examples import build_example
    from pymorembs.io.native import read_body_h5, write_body_h5

    body = build_example(name)
    back = read_body_h5(write_body_h5(body, tmp_path / "model.h5"))
    assert back.mesh.element == body.mesh.element
    np.testing.assert_array_equal(back.mesh.connectivity, body.mesh.connectivity)
    assert (back.mesh.young, back.mesh.poisson) == (body.mesh.young, body.mesh.poisson)
    assert back.mesh.section == body.mesh.section and back.mesh.up == body.mesh.up
