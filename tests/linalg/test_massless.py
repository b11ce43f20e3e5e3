"""Massless dofs everywhere (issue #14, item 1), checked against dense computations written here.

The models: steel beams with lumped translational masses only -- the rotations carry no mass, as
in a Nastran ``CONM2``/lumped-mass export or a Femap punch of a beam -- and point masses attached
with an offset, whose nodal 6x6 block has rank 3 (its null space mixes the node's dofs). The
references condense the massless directions with plain numpy (coordinate-aligned for zero rows, a
global eigen-decomposition of ``M`` otherwise), independently of
:mod:`pymorembs.linalg.mass_split`.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import scipy.linalg as sla
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from pymorembs.analysis.spectrum import model_spectrum
from pymorembs.analysis.time_domain import LoadCase, simulate
from pymorembs.body import Damping, DofTable, ElasticBody
from pymorembs.elements.beam import BeamSection, assemble_beams
from pymorembs.errors import NumericalError
from pymorembs.io.matrix_market import write_matrix_files
from pymorembs.job.cli import main
from pymorembs.linalg.mass_split import condensed_dense_eigh, mass_split
from pymorembs.prepare import Frame, Port, prepare
from pymorembs.reduction.gramian import gramian_reduction
from pymorembs.reduction.krylov import krylov_reduction
from pymorembs.reduction.modal import eigenmodes
from pymorembs.reduction.projection import reduced_model

SECTION = BeamSection.rectangular(0.04, 0.01, E=2.1e11, nu=0.3, rho=7850.0)


def beam_body(
    n_el: int, *, clamped: bool, bent: bool = False, offset_masses: bool = False
) -> ElasticBody:
    """A 1 m steel beam of ``n_el`` elements, lumped translational mass, massless rotations.

    ``bent``: the beam runs along a space curve (so that every rigid rotation moves masses);
    ``offset_masses``: point masses of 0.2 kg hang 50 mm beside every fourth node (rank-3
    blocks). ``clamped``: node 1 is fixed (6 dofs).
    """
    ids = np.arange(1, n_el + 2)
    s = np.linspace(0.0, 1.0, n_el + 1)
    if bent:
        xyz = np.column_stack([s, 0.2 * np.sin(2.0 * s), 0.1 * s**2])
    else:
        xyz = np.column_stack([s, np.zeros_like(s), np.zeros_like(s)])
    elements = np.column_stack([ids[:-1], ids[1:]])
    dof_index = 6 * np.arange(ids.size)[:, None] + np.arange(6)
    k, _ = assemble_beams(ids, xyz, elements, SECTION, dof_index, up=np.array([0.0, 0.3, 1.0]))
    lengths = np.linalg.norm(np.diff(xyz, axis=0), axis=1)
    node_mass = np.zeros(ids.size)
    node_mass[:-1] += 0.5 * lengths * SECTION.rho * SECTION.area
    node_mass[1:] += 0.5 * lengths * SECTION.rho * SECTION.area
    m = np.zeros((6 * ids.size, 6 * ids.size))
    for i, mass in enumerate(node_mass):
        m[6 * i : 6 * i + 3, 6 * i : 6 * i + 3] = mass * np.eye(3)
    if offset_masses:
        e = np.array([0.0, 0.05, 0.02])
        skew = np.array([[0, -e[2], e[1]], [e[2], 0, -e[0]], [-e[1], e[0], 0]])
        t = np.hstack([np.eye(3), -skew])  # u_point = u + theta x e
        for i in range(2, ids.size, 4):
            m[6 * i : 6 * i + 6, 6 * i : 6 * i + 6] += 0.2 * t.T @ t
    return ElasticBody(
        node_ids=ids,
        coordinates=xyz,
        dofs=DofTable(np.repeat(ids, 6), np.tile(np.arange(6), ids.size)),
        mass=sp.csr_matrix(m),
        stiffness=k,
        fixed=np.arange(6) if clamped else np.zeros(0, dtype=np.int64),
        name="beam",
    )


def dense_reference(body: ElasticBody, sigma: float = -1.0e3) -> np.ndarray:
    """All finite eigenvalues (rad/s)^2 of the free dofs, condensed with plain numpy.

    In flexibility form, which keeps the low eigenvalues accurate to working precision: with
    ``M = U diag(m) U^T`` (massless directions: ``m ~ 0``) and ``F = (K - sigma M)^-1``, the
    massive block ``U_m^T F U_m`` is the inverse of the statically condensed shifted stiffness,
    so the eigenvalues ``mu`` of ``m^1/2 U_m^T F U_m m^1/2`` are ``1 / (lambda - sigma)``.
    """
    free = np.setdiff1d(np.arange(body.n_dof), body.fixed)
    k = body.stiffness[free][:, free].toarray()
    m = body.mass[free][:, free].toarray()
    values, vectors = np.linalg.eigh(m)
    massive = values > 1e-10 * values.max()
    um, root = vectors[:, massive], np.sqrt(values[massive])
    flexibility = np.linalg.inv(k - sigma * m)
    mu = np.linalg.eigvalsh(root[:, None] * (um.T @ flexibility @ um) * root[None, :])
    return np.sort(sigma + 1.0 / mu)


def hz(values: np.ndarray) -> np.ndarray:
    return np.sqrt(np.abs(values)) / (2 * np.pi)


# ------------------------------------------------------------------------- the split itself
def test_split_finds_zero_rows_and_the_null_space_of_offset_point_masses():
    body = beam_body(12, clamped=False, bent=True, offset_masses=True)
    split = mass_split(body.mass)
    assert split.zero_rows.size == 3 * 13 - 3 * 3  # rotations without mass (3 nodes carry some)
    # a node with a point mass at offset e: lumped translations + the point mass give rank 5,
    # the rotation about e stays massless (one direction per such block)
    assert split.n_block_null == 3
    m = body.mass.toarray()
    qm, q0, b = split.massive.toarray(), split.massless.toarray(), split.mass.toarray()
    assert np.allclose(qm.T @ qm, np.eye(split.rank), atol=1e-14)
    assert np.allclose(qm.T @ q0, 0.0, atol=1e-14)
    assert np.abs(qm @ b @ qm.T - m).max() < 1e-14 * np.abs(m).max()
    assert np.abs(m @ q0).max() < 1e-14 * np.abs(m).max()
    assert np.linalg.eigvalsh(b).min() > 0
    assert split.rank == np.linalg.matrix_rank(m, tol=1e-10 * np.abs(m).max())


def test_split_refuses_an_indefinite_mass_block():
    m = np.diag([1.0, 1.0, 0.0])
    m[0, 1] = m[1, 0] = 2.0  # eigenvalues -1 and 3
    with pytest.raises(NumericalError, match="not positive semidefinite"):
        mass_split(sp.csr_matrix(m))


def test_dense_condensation_matches_the_plain_reference():
    body = beam_body(8, clamped=True, offset_masses=True)
    free = np.arange(6, body.n_dof)
    values, modes = condensed_dense_eigh(
        body.stiffness[free][:, free].toarray(), body.mass[free][:, free].toarray()
    )
    assert np.allclose(values, dense_reference(body), rtol=1e-9)
    m = body.mass[free][:, free].toarray()
    assert np.allclose(modes.T @ m @ modes, np.eye(values.size), atol=1e-8)


# ------------------------------------------------------------------------------ eigenmodes
def test_sparse_eigenmodes_of_a_cantilever_with_massless_rotations():
    """The Femap beam of the issue: ARPACK failed; now the condensed pencil is solved."""
    body = beam_body(10, clamped=True)  # 60 free dofs, 30 of them massless
    system = prepare(body, Frame("none")).system
    values, modes = eigenmodes(system, 12)
    reference = dense_reference(body)
    assert reference.size == 30
    assert np.allclose(values, reference[:12], rtol=1e-9)
    assert np.allclose(modes.T @ (system.mass @ modes), np.eye(12), atol=1e-9)
    residual = system.stiffness @ modes - (system.mass @ modes) * values
    assert np.abs(residual).max() < 1e-8 * abs(system.stiffness).max()
    with pytest.raises(Exception, match="only 30 modes with mass"):
        eigenmodes(system, 30)


def test_info_on_a_cantilever_with_massless_rotations(tmp_path, capsys):
    """More than DENSE_LIMIT dofs: the sparse path of info, with its massless count."""
    body = beam_body(120, clamped=True)  # 726 dofs, 720 free, 360 massless
    write_matrix_files(body, tmp_path)
    code = main(["info", str(tmp_path), "--modes", "8", "--json"])
    facts = json.loads(capsys.readouterr().out)
    assert code == 0
    assert facts["n_massless"] == 360 and facts["massless"]["dofs_without_mass"] == 360
    assert facts["rigid_body_modes"] == 0
    # cond(K) = 1.3e10 for 120 beam elements: any backward-stable solve (dense or sparse)
    # knows the lowest eigenvalue to about eps * cond = 1.5e-6, so that is the tolerance
    reference = hz(dense_reference(body)[:8])
    assert np.allclose(facts["eigenfrequencies_hz"], reference, rtol=1e-6)


def test_free_bent_beam_with_offset_masses_has_six_rigid_body_modes(capsys, tmp_path):
    body = beam_body(14, clamped=False, bent=True, offset_masses=True)
    write_matrix_files(body, tmp_path)
    code = main(["info", str(tmp_path), "--modes", "6", "--json"])
    facts = json.loads(capsys.readouterr().out)
    assert code == 0
    assert facts["rigid_body_modes"] == 6
    assert facts["rigid_body_decision"]["decided_by"] == "geometry"
    assert "the spectrum agrees" in facts["rigid_body_decision"]["explanation"]
    reference = dense_reference(body)
    assert np.all(hz(reference[:6]) < 1e-4 * hz(reference[6]))
    assert np.allclose(facts["eigenfrequencies_hz"][6:], hz(reference[6:12]), rtol=1e-8)
    assert facts["eigenfrequencies_hz"][:6] == [0.0] * 6


def test_spectrum_of_a_free_beam_without_coordinates_counts_by_the_spectrum():
    body = beam_body(14, clamped=False, bent=True, offset_masses=True)
    blind = ElasticBody(
        node_ids=body.node_ids,
        coordinates=np.zeros_like(body.coordinates),
        dofs=body.dofs,
        mass=body.mass,
        stiffness=body.stiffness,
        has_coordinates=False,
    )
    spectrum = model_spectrum(blind, prepare(blind, Frame("none"), allow_rigid_body_modes=True), 5)
    assert spectrum.rigid.count == 6 and spectrum.rigid.decided_by == "spectrum"
    assert np.allclose(spectrum.elastic_hz, hz(dense_reference(body)[6:11]), rtol=1e-8)


# -------------------------------------------------------------------------------- methods
def _dense_transfer(system, omegas):
    """H(i w) of a prepared sparse system by plain sparse LU, shape (len(w), r, p)."""
    out = []
    d = system.damping if system.damping is not None else 0.0 * system.mass
    for w in omegas:
        z = (system.stiffness - w * w * system.mass + 1j * w * d).tocsc()
        out.append(system.output_matrix @ spla.spsolve(z, system.input_matrix.astype(complex)))
    return np.array(out)


def _reduced_transfer(reduced, omegas):
    return np.array(
        [
            reduced.output_matrix
            @ np.linalg.solve(
                reduced.stiffness - w * w * reduced.mass + 1j * w * reduced.damping,
                reduced.input_matrix,
            )
            for w in omegas
        ]
    )


def _relative(full, approx):
    return np.linalg.norm(full - approx, axis=(1, 2)) / np.linalg.norm(full, axis=(1, 2))


def test_dense_gramian_and_krylov_on_a_model_with_massless_dofs():
    """Ports on massive dofs: both converge. A moment on a massless rotation (ry at a node whose
    point mass is offset): prepare warns, Krylov keeps its static part, the dense Gramian not."""
    body = beam_body(10, clamped=True, offset_masses=True).with_damping(
        Damping("rayleigh", alpha=3.0)
    )
    omegas = 2 * np.pi * np.array([3.0, 40.0, 250.0])
    ports = [Port.parse(11, "uz rx")]  # rx has mass through the offset point mass
    prepared = prepare(body, Frame("none"), inputs=ports, outputs=ports)
    assert not any("massless" in w for w in prepared.warnings)
    system = prepared.system
    full = _dense_transfer(system, omegas)
    gramian = reduced_model(system, gramian_reduction(system, (0.0, 500.0), order=12)).system
    assert _relative(full, _reduced_transfer(gramian, omegas)).max() < 1e-5
    ports = [Port.parse(11, "uz ry")]
    prepared = prepare(body, Frame("none"), inputs=ports, outputs=ports)
    assert any(w.startswith("input 11:ry acts on massless directions") for w in prepared.warnings)
    system = prepared.system
    full = _dense_transfer(system, omegas)
    krylov = reduced_model(system, krylov_reduction(system, [0.0, 200.0], moments=[4, 3])).system
    assert _relative(full, _reduced_transfer(krylov, omegas)).max() < 1e-6


def test_time_integration_with_massless_dofs_follows_the_exact_solution():
    """Step load on a massive dof of a cantilever with massless rotations, D = alpha M."""
    alpha = 20.0
    body = beam_body(10, clamped=True).with_damping(Damping("rayleigh", alpha=alpha))
    port = [Port.parse(11, "uz")]
    system = prepare(body, Frame("none"), inputs=port, outputs=port).system
    case = LoadCase("step", "step", np.array([10.0]))
    response = simulate(system, [case], duration_s=0.05, step_s=2e-5)
    # exact: modal superposition of the condensed pencil (written here, dense)
    free = np.arange(6, body.n_dof)
    k = body.stiffness[free][:, free].toarray()
    m = body.mass[free][:, free].toarray()
    tip = int(np.flatnonzero((body.dofs.nodes[free] == 11) & (body.dofs.directions[free] == 2))[0])
    massless = np.flatnonzero(np.diag(m) == 0.0)
    massive = np.setdiff1d(np.arange(free.size), massless)
    kc = k[np.ix_(massive, massive)] - k[np.ix_(massive, massless)] @ np.linalg.solve(
        k[np.ix_(massless, massless)], k[np.ix_(massless, massive)]
    )
    w2, phi = sla.eigh(kc, m[np.ix_(massive, massive)])
    f = np.zeros(massive.size)
    f[np.searchsorted(massive, tip)] = 10.0
    t = response.times
    omega = np.sqrt(w2)
    zeta = alpha / (2 * omega)
    wd = omega * np.sqrt(1 - zeta**2)
    decay = np.exp(-zeta[None, :] * omega[None, :] * t[:, None])
    shape = 1 - decay * (
        np.cos(wd * t[:, None]) + (zeta / np.sqrt(1 - zeta**2)) * np.sin(wd * t[:, None])
    )
    exact = shape @ (phi[np.searchsorted(massive, tip)] * (phi.T @ f) / w2)
    computed = response.outputs["step"][:, 0]
    assert np.abs(computed - exact).max() < 2e-3 * np.abs(exact).max()


@pytest.fixture(scope="module")
def massless_rack(tmp_path_factory) -> Path:
    """rack-beams with the mass of every rod rotation removed (1,992 massless dofs)."""
    from dataclasses import replace

    from pymorembs.examples import build_example
    from pymorembs.io.native import write_body_h5

    body = build_example("rack-beams")
    keep = ~((body.dofs.directions >= 3) & ~np.isin(body.dofs.nodes, [1, 2]))
    scale = sp.diags(keep.astype(float))
    mass = sp.csr_matrix(scale @ body.mass @ scale)
    mass.eliminate_zeros()
    folder = tmp_path_factory.mktemp("massless_rack")
    write_body_h5(replace(body, mass=mass, name="rack-beams-massless"), folder / "model.h5")
    return folder


JOB = """
[model]
file = "model.h5"
[damping]
kind = "rayleigh"
alpha = 5.0
[frame]
{frame}
[[inputs]]
node = 1
directions = "ux uy uz rx"
[band]
f_max_hz = 1000
points = 200
[[reduction]]
name = "modal"
method = "modal"
order = 30
frm_hz = [1]
[[reduction]]
name = "krylov"
method = "krylov"
expansion_points_hz = [0, 500, 1000]
moments = [6, 5, 5]
[[reduction]]
name = "soaga"
method = "soaga"
tolerance = 1e-6
[[reduction]]
name = "gramian"
method = "gramian"
order = 30
[[reduction]]
name = "pod"
method = "pod"
order = 30
{extra}
"""


@pytest.mark.slow
@pytest.mark.parametrize(
    ("frame", "extra"),
    [
        (
            'type = "tangent"\nnode = 2',
            '[[reduction]]\nname = "cb"\nmethod = "craig-bampton"\nfixed_modes = 20',
        ),
        ('type = "buckens"', ""),
    ],
    ids=["tangent", "buckens"],
)
def test_every_method_reduces_a_model_with_massless_dofs(massless_rack, frame, extra):
    from pymorembs.job.run import prepare_job, run_job
    from pymorembs.job.schema import load_job

    job_file = massless_rack / f"job_{frame.split()[2].strip(chr(34))}.toml"
    job_file.write_text(JOB.format(frame=frame, extra=extra))
    out = massless_rack / f"out_{job_file.stem}"
    summary = run_job(load_job(job_file), out, None, workers=1)
    assert summary["model"]["n_massless"] > 1900
    errors = {r["name"]: r["max_rel_error"] for r in summary["reductions"]}
    assert errors["krylov"] < 1e-6 and errors["soaga"] < 1e-5 and errors["pod"] < 1e-6
    assert errors["gramian"] < 1e-5 and errors["modal"] < 1e-2
    # the full transfer function, independently: plain sparse LU of the prepared system
    _, prepared = prepare_job(load_job(job_file))
    omegas = 2 * np.pi * np.array([7.0, 300.0])
    full = _dense_transfer(prepared.system, omegas)
    data = np.load(out / "krylov" / "reduced.npz")
    approx = np.array(
        [
            data["C"]
            @ np.linalg.solve(data["K"] - w * w * data["M"] + 1j * w * data["D"], data["B"])
            for w in omegas
        ]
    )
    assert _relative(full, approx).max() < 1e-6
