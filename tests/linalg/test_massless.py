"""Massless dofs everywhere (issue #14, item 1), checked against dense computations written here.

The models: steel beams with lumped translational masses only -- the rotations carry no mass, as
in a Nastran ``CONM2``/lumped-mass export or a Femap punch of a beam -- and point masses attached
with an offset, whose nodal 6x6 block has rank 3 (its null space mixes the node's dofs). The
references condense the massless directions with plain numpy (coordinate-aligned for zero rows, a
global eigen-decomposition of ``M`` otherwise), independently of
:mod:`pymorembs.linalg.mass_split`.

Massless mechanisms (issue #27, item 3), directions with neither mass nor stiffness: a genuine
Femap punch of a pinned bar (``tests/data/qinterfly_pchconverter_femap``) and spring-mass chains
with a loose dof, a loose pair, a tied pair, a massless link and a coupled pair, against dense
computations and theory written here; 20,000 massless dofs against their known null space.
"""

from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
import pytest
import scipy.linalg as sla
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from pymorembs.analysis.spectrum import model_spectrum
from pymorembs.analysis.time_domain import LoadCase, simulate
from pymorembs.body import ConstraintEquations, Damping, DofTable, ElasticBody
from pymorembs.elements.beam import BeamSection, assemble_beams
from pymorembs.errors import NumericalError, UserError
from pymorembs.io.matrix_market import write_matrix_files
from pymorembs.job.cli import main
from pymorembs.linalg.mass_split import condensed_dense_eigh, mass_split
from pymorembs.preparation import Frame, Port, eliminate, prepare, validate_prepared
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
    assert summary.model["n_massless"] > 1900
    errors = {r.name: r.max_rel_error for r in summary.reductions}
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


# ------------------------------------------------- massless mechanisms (issue #27, item 3)
FEMAP = Path(__file__).parents[1] / "data" / "qinterfly_pchconverter_femap"
#: The pinned-pinned bar of the Femap deck (beam.dat): E, rho, A, I, length.
BAR = {"E": 2e11, "rho": 7850.0, "A": 3.1416e-6, "I": 7.854e-13, "L": np.sqrt(0.875)}


def projected_reference_hz(body: ElasticBody) -> np.ndarray:
    """All finite frequencies (Hz) of a body whose massless rows hold one direction without
    mass and stiffness, dense and written here.

    The massive dofs after static condensation of the massless ones, with that direction
    projected out of the massless space by hand: the complement of the null singular vector of
    ``K_00``.
    """
    k, m = body.stiffness.toarray(), body.mass.toarray()
    massless = np.flatnonzero(np.abs(m).sum(axis=1) == 0.0)
    massive = np.setdiff1d(np.arange(k.shape[0]), massless)
    k00 = k[np.ix_(massless, massless)]
    u, s, _ = np.linalg.svd(k00)
    assert s[-1] < 1e-9 * s[0] < s[-2]  # exactly one null direction
    z = u[:, :-1]  # the massless space without it
    k_zm = z.T @ k[np.ix_(massless, massive)]
    condensed = k[np.ix_(massive, massive)] - k_zm.T @ np.linalg.solve(z.T @ k00 @ z, k_zm)
    values = sla.eigh(condensed, m[np.ix_(massive, massive)], eigvals_only=True)
    return np.sign(values) * np.sqrt(np.abs(values)) / (2 * np.pi)


def femap_reference_hz() -> np.ndarray:
    """All finite frequencies (Hz) of the genuine Femap punch (:func:`projected_reference_hz`:
    its null direction lies in the 33 rotations)."""
    from pymorembs.io import read_body

    return projected_reference_hz(read_body(file=FEMAP / "beam.pch", nodes=FEMAP / "beam.dat"))


def test_the_genuine_femap_beam_with_a_massless_mechanism_gives_its_frequencies(capsys):
    """Exit 3 before (``the model has a massless mechanism``); now the torsion of the pinned bar
    is removed with a note and the frequencies are those of a dense computation."""
    files = [str(FEMAP / "beam.pch"), "--nodes", str(FEMAP / "beam.dat")]
    code = main(["info", *files, "--modes", "8", "--json"])
    facts = json.loads(capsys.readouterr().out)
    assert code == 0
    reference = femap_reference_hz()
    assert reference.size == 27  # the 27 translations carry mass
    # fixing one rotation and projecting out the null singular vector differ by what the
    # file's 10 digits leave of the null eigenvalue (-1.9e-10 scaled): 6e-9 here, against a
    # rounding bound of the frequencies themselves of 1e-3
    assert np.allclose(facts["eigenfrequencies_hz"], reference[:8], rtol=1e-7)
    # Euler-Bernoulli, pinned-pinned: f_n = n^2 pi / (2 L^2) sqrt(EI / rho A), two planes
    f1 = np.pi / (2 * BAR["L"] ** 2) * np.sqrt(BAR["E"] * BAR["I"] / (BAR["rho"] * BAR["A"]))
    theory = f1 * np.repeat([1.0, 4.0, 9.0], 2)
    assert np.allclose(facts["eigenfrequencies_hz"][:6], theory, rtol=1e-3)
    assert facts["rigid_body_modes"] == 0 and facts["mechanisms"] == 0
    assert facts["n_fixed"] == 1 and facts["n_massless"] == 32
    (note,) = [n for n in facts["notes"] if "massless mechanism" in n]
    assert re.fullmatch(
        r"a massless mechanism of 33 dofs \(nodes 1, 2, 3, 4, 5, 6, \.\.\. \(11 nodes\) rx ry rz\)"
        r" with no mass and no stiffness, decoupled from every massive dof \(residual "
        r"\d\.\de-1\d\): removed by fixing node \d+ rz \(like Nastran's AUTOSPC\)",
        note,
    )


def test_the_femap_beam_prepares_and_passes_the_deep_checks_of_a_job(tmp_path):
    """What ``pymorembs reduce`` does before any reduction: the job's preparation with the
    factorization of K + sigma M, which the massless mechanism made singular."""
    from pymorembs.job.run import prepare_and_validate
    from pymorembs.job.schema import load_job

    for name in ("beam.pch", "beam.dat"):
        (tmp_path / name).write_bytes((FEMAP / name).read_bytes())
    job = tmp_path / "job.toml"
    job.write_text(FEMAP_JOB)
    _, prepared, report = prepare_and_validate(load_job(job))
    assert "no mechanism (lowest eigenvalues)" in report.checks
    assert any("removed by fixing node" in note for note in prepared.notes)
    values, _ = eigenmodes(prepared.system, 4)
    assert np.allclose(hz(values), femap_reference_hz()[:4], rtol=1e-7)  # as above


FEMAP_JOB = """
[model]
file = "beam.pch"
nodes = "beam.dat"
[frame]
type = "none"
[[inputs]]
node = 6
directions = "ux uy uz"
[band]
f_max_hz = 60
points = 200
[[reduction]]
name = "krylov"
method = "krylov"
expansion_points_hz = [0, 30]
order = 24
"""


@pytest.mark.slow
def test_pymorembs_reduce_on_the_femap_beam(tmp_path, capsys):
    for name in ("beam.pch", "beam.dat"):
        (tmp_path / name).write_bytes((FEMAP / name).read_bytes())
    (tmp_path / "job.toml").write_text(FEMAP_JOB)
    code = main(["reduce", str(tmp_path / "job.toml"), "--out", str(tmp_path / "out")])
    assert code == 0
    summary = json.loads((tmp_path / "out" / "summary.json").read_text())
    assert any("removed by fixing node" in note for note in summary["notes"])
    assert summary["reductions"][0]["max_rel_error"] < 1e-6


def test_a_free_straight_beam_without_rotary_inertia_has_five_rigid_body_modes(capsys, tmp_path):
    """Turning about its own axis moves only massless rotations: no rigid-body mode but a
    massless mechanism (before: exit 3). The Buckens frame, which needs six, says why."""
    body = beam_body(10, clamped=False)
    write_matrix_files(body, tmp_path)
    code = main(["info", str(tmp_path), "--modes", "6", "--json"])
    facts = json.loads(capsys.readouterr().out)
    assert code == 0
    assert facts["rigid_body_modes"] == 5 and facts["mechanisms"] == 0
    assert [n for n in facts["notes"] if re.fullmatch(
        r"a massless mechanism of 11 dofs \(nodes 1, 2, 3, 4, 5, 6, \.\.\. \(11 nodes\) rx\) "
        r"with no mass and no stiffness, decoupled from every massive dof \(residual .*\): "
        r"removed by fixing node \d+ rx \(like Nastran's AUTOSPC\)", n)]  # fmt: skip
    reference = projected_reference_hz(body)
    assert np.all(np.abs(reference[:5]) < 1e-4 * reference[5])
    assert np.allclose(facts["eigenfrequencies_hz"][5:], reference[5:11], rtol=1e-8)
    ports = [Port.parse(3, "uz")]
    why = (
        r"; removed as massless mechanisms before: nodes 1, 2, 3, 4, 5, 6, \.\.\. \(11 nodes\) rx$"
    )
    with pytest.raises(UserError, match=r"six rigid-body modes; this one has 5 .*" + why):
        prepare(body, Frame("buckens"), ports, ports)


def chain_body(extra: str = "", n: int = 12) -> ElasticBody:
    """A spring-mass chain along x (nodes 1..n, ux), held by a spring to ground at node 1.

    ``extra``: ``"loose"`` -- node 100 with no mass and no stiffness; ``"pair"`` -- nodes 100
    and 101 without mass, joined by a spring to each other only (a massless mechanism of two
    dofs: both move together); ``"coupled"`` -- that pair with a stiffness term between node
    100 and node 5 (no stiffness of its own to balance it: K is indefinite there);
    ``"constrained"`` -- nodes 100 and 101 without mass and stiffness, 101 tied to 100 by the
    constraint equation ``q_101 = 2 q_100``; ``"attached"`` -- the pair as a massless link
    between nodes 5 and 9 (springs of 300 N/m from node 5 to 100 and 200 N/m from 101 to 9):
    condensed, not a mechanism.
    """
    masses = 1.0 + 0.1 * np.arange(n)
    springs = 1.0e3 * (1.0 + 0.05 * np.arange(n))  # ground-1, 1-2, ..., (n-1)-n
    k = np.diag(springs + np.append(springs[1:], 0.0))
    k -= np.diag(springs[1:], 1) + np.diag(springs[1:], -1)
    m = np.diag(masses)
    extra_ids = {"": [], "loose": [100], "pair": [100, 101], "coupled": [100, 101]}
    extra_ids["attached"] = extra_ids["constrained"] = [100, 101]
    ids = np.concatenate([np.arange(1, n + 1), extra_ids[extra]]).astype(int)
    size = ids.size
    k_all, m_all = np.zeros((size, size)), np.zeros((size, size))
    k_all[:n, :n], m_all[:n, :n] = k, m
    if extra in ("pair", "coupled", "attached"):
        k_all[n:, n:] = 500.0 * np.array([[1.0, -1.0], [-1.0, 1.0]])
    if extra == "coupled":
        k_all[n, 4] = k_all[4, n] = 0.1 * np.sqrt(500.0 * k[4, 4])  # the 2x2 minors pass
    if extra == "attached":
        for massless, massive, spring in ((n, 4, 300.0), (n + 1, 8, 200.0)):
            k_all[massless, massless] += spring
            k_all[massive, massive] += spring
            k_all[massless, massive] = k_all[massive, massless] = -spring
    constraints = None
    if extra == "constrained":
        tie = sp.csr_matrix(([2.0], ([0], [n])), shape=(1, size))
        constraints = ConstraintEquations(np.array([n + 1]), tie, np.zeros(1))
    return ElasticBody(
        node_ids=ids,
        coordinates=np.column_stack([ids.astype(float), np.zeros(size), np.zeros(size)]),
        dofs=DofTable(ids, np.zeros(size, dtype=int)),
        mass=sp.csr_matrix(m_all),
        stiffness=sp.csr_matrix(k_all),
        constraints=constraints,
        name=f"chain-{extra or 'plain'}",
    )


def chain_hz(n: int = 12) -> np.ndarray:
    """The frequencies (Hz) of the plain chain: dense, from its own matrices."""
    plain = chain_body("", n)
    values = sla.eigh(plain.stiffness.toarray(), plain.mass.toarray(), eigvals_only=True)
    return np.sqrt(values) / (2 * np.pi)


@pytest.mark.parametrize(
    ("extra", "note"),
    [
        ("loose", r"node 100 ux: no mass and no stiffness \(removed like Nastran's AUTOSPC\)"),
        (
            "constrained",
            r"node 100 ux: no mass and no stiffness \(removed like Nastran's AUTOSPC\)",
        ),
        (
            "pair",
            r"a massless mechanism of 2 dofs \(nodes 100, 101 ux\) with no mass and no stiffness,"
            r" decoupled from every massive dof \(residual .*\): removed by fixing node 100 ux "
            r"\(like Nastran's AUTOSPC\)",
        ),
    ],
)
def test_a_decoupled_dof_or_pair_without_mass_and_stiffness_changes_no_frequency(
    extra, note, tmp_path, capsys
):
    """Before: ``info`` exit 3 (``massless mechanism``), a job exit 2 (``neither mass nor
    stiffness``) or 3 (``K + sigma M is singular``)."""
    body = chain_body(extra)
    write_matrix_files(body, tmp_path)
    code = main(["info", str(tmp_path), "--modes", "12", "--json"])
    facts = json.loads(capsys.readouterr().out)
    assert code == 0
    assert np.allclose(facts["eigenfrequencies_hz"], chain_hz(), rtol=1e-10)
    assert [n for n in facts["notes"] if re.fullmatch(note, n)]
    prepared = prepare(body, Frame("none"))
    assert prepared.body.fixed.tolist() == [body.dofs.index(100, "ux")]
    again = eliminate(prepared.body)  # the elimination of the held body, from scratch
    assert np.array_equal(again.independent, prepared.elimination.independent)
    assert np.array_equal(again.fixed, prepared.elimination.fixed)
    assert abs(again.transform - prepared.elimination.transform).max() == 0.0
    assert validate_prepared(prepared).checks[-1] == "no mechanism (lowest eigenvalues)"
    values, _ = eigenmodes(prepared.system, 5)
    assert np.allclose(hz(values), chain_hz()[:5], rtol=1e-10)


def test_a_massless_link_between_two_masses_is_condensed_not_removed():
    body = chain_body("attached")
    prepared = prepare(body, Frame("none"))
    assert prepared.body.fixed.size == 0 and prepared.notes == ()
    # reference: the link is three springs in series (300, 500, 200 N/m) between nodes 5 and 9
    series = 1.0 / (1.0 / 300.0 + 1.0 / 500.0 + 1.0 / 200.0)
    k = chain_body("").stiffness.toarray()
    k[np.ix_([4, 8], [4, 8])] += series * np.array([[1.0, -1.0], [-1.0, 1.0]])
    expected = sla.eigh(k, chain_body("").mass.toarray(), eigvals_only=True)
    values, _ = eigenmodes(prepared.system, 6)
    assert np.allclose(values, expected[:6], rtol=1e-10)
    assert not np.allclose(hz(values), chain_hz()[:6], rtol=1e-3)  # the link does count


def test_a_massless_mechanism_coupled_to_a_massive_dof_is_refused_in_one_line(tmp_path, capsys):
    body = chain_body("coupled")
    with pytest.raises(NumericalError) as info:
        prepare(body, Frame("none"))
    message = str(info.value)
    assert message.startswith(
        "[model]: the stiffness matrix is not positive semidefinite: a massless direction "
        "without stiffness of its own (nodes 100, 101 ux) is coupled to node 5 ux"
    )
    assert "\n" not in message
    write_matrix_files(body, tmp_path)
    assert main(["info", str(tmp_path)]) == 3
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "(nodes 100, 101 ux) is coupled to node 5 ux" in err


def test_ports_on_a_removed_direction():
    body = chain_body("loose")
    with pytest.raises(UserError, match=r"^\[\[inputs\]\]: input 100:ux loads a direction "
                       r"without mass and stiffness \(node 100 ux\)"):  # fmt: skip
        prepare(body, Frame("none"), inputs=[Port.parse(100, "ux")], outputs=[])
    prepared = prepare(body, Frame("none"), [Port.parse(3, "ux")], [Port.parse(100, "ux")])
    assert prepared.warnings == (
        "output 100:ux reads a direction without mass and stiffness (node 100 ux), removed by "
        "fixing node 100 ux: its part along that motion is undetermined and taken as 0 there",
    )


def _chain_laplacian(n: int, k: float) -> sp.csr_matrix:
    """Stiffness of ``n`` dofs joined in a row by springs ``k``, free at both ends."""
    diagonal = np.full(n, 2.0 * k)
    diagonal[[0, -1]] = k
    return sp.csr_matrix(sp.diags([diagonal, -k * np.ones(n - 1), -k * np.ones(n - 1)], [0, 1, -1]))


def test_twenty_thousand_massless_dofs_with_eight_null_directions_stay_sparse():
    """200 masses in a held chain; 20,000 massless dofs: five chains of 4,000 (two hung on the
    masses, three free: each moves as a whole without mass and stiffness) and five dofs that
    nothing touches. The null space is known exactly: constants on the free chains, unit
    vectors on the loose dofs."""
    import time
    import tracemalloc

    from pymorembs.linalg.massless_mechanisms import massless_mechanisms

    n_m, length, n_loose = 200, 4000, 5
    held = _chain_laplacian(n_m, 1e4).tolil()
    held[0, 0] += 1e4
    chains = [_chain_laplacian(length, 50.0 * (c + 1)) for c in range(5)]
    k = sp.block_diag([held, *chains, sp.csr_matrix((n_loose, n_loose))], format="lil")
    for c in (3, 4):  # hung on masses 30 and 40 by a spring at their first dof
        i, j = n_m + c * length, 10 * c
        k[i, i] += 70.0
        k[j, j] += 70.0
        k[i, j] = k[j, i] = -70.0
    k = sp.csr_matrix(k)
    n = k.shape[0]
    m = sp.diags(np.concatenate([np.linspace(1.0, 2.0, n_m), np.zeros(n - n_m)]), format="csr")
    expected = np.zeros((n, 8))
    for c in range(3):
        expected[n_m + c * length : n_m + (c + 1) * length, c] = 1.0 / np.sqrt(length)
    expected[n - n_loose + np.arange(n_loose), 3 + np.arange(n_loose)] = 1.0

    start = time.perf_counter()
    found = massless_mechanisms(k, mass_split(m))
    seconds = time.perf_counter() - start
    tracemalloc.start()
    massless_mechanisms(k, mass_split(m))
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    assert seconds < 1.0
    assert peak < 64e6  # one dense 20,000 x 20,000 matrix would be 3.2 GB
    assert found.count == 8 and not found.coupled.any()
    vectors = found.vectors.toarray()
    cosines = np.linalg.svd(expected.T @ vectors, compute_uv=False)
    assert np.allclose(cosines, 1.0, atol=1e-10)  # the same space
    assert np.abs(k @ vectors).max() < 1e-10 * abs(k).max()
    # fixing the pivots removes the whole null space: one in each free chain, the loose dofs
    assert np.linalg.matrix_rank(vectors[found.pivots]) == 8
    owner = (np.sort(found.pivots) - n_m) // length
    assert owner.tolist() == [0, 1, 2, 5, 5, 5, 5, 5]


def test_two_null_directions_in_one_massless_part_get_two_pivots():
    """K_00 = 100 v v^T on three massless dofs (one connected part, rank 1): a plane of null
    directions; two dofs fixed, and the third carries the stiffness."""
    from pymorembs.linalg.massless_mechanisms import massless_mechanisms

    v = np.array([1.0, -2.0, 0.5])
    k = sp.block_diag([sp.csr_matrix([[3.0]]), sp.csr_matrix(100.0 * np.outer(v, v))], "csr")
    m = sp.diags([1.0, 0.0, 0.0, 0.0], format="csr")
    found = massless_mechanisms(k, mass_split(m))
    assert found.count == 2 and found.group.tolist() == [0, 0]
    assert not found.coupled.any()
    assert np.abs(found.vectors.toarray()[1:].T @ v).max() < 1e-12
    assert sorted(found.pivots.tolist()) in ([1, 3], [1, 2], [2, 3])
    assert 0 not in found.pivots
    rest = np.setdiff1d([1, 2, 3], found.pivots)
    assert k[rest][:, rest].toarray()[0, 0] > 0
