"""Frequency-weighted Gramians, Gramian/POD reduction and the eq. 24 bound, against independent
dense computations: Lyapunov equations of the first-order form (paper eq. 5), numerical
quadrature of the Gramian integrals and of the band-limited H2 error."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
import scipy.linalg as sla
import scipy.sparse as sp
from scipy.integrate import quad_vec

from conftest import space_truss, spring_lattice
from pymorembs.analysis.error import relative_error
from pymorembs.analysis.transfer import transfer_function
from pymorembs.body import Damping
from pymorembs.errors import UserError
from pymorembs.frequencies import frequency_grid
from pymorembs.preparation import Frame, Port, prepare
from pymorembs.reduction import gramian
from pymorembs.reduction.gramian import (
    frequency_weighted_gramians,
    gramian_reduction,
    pod_reduction,
    quadrature,
)
from pymorembs.reduction.krylov import krylov_reduction
from pymorembs.reduction.projection import reduced_model
from pymorembs.system import SecondOrderSystem

INPUTS = [Port.parse(70, "ux uy"), Port.parse(40, "uz")]
OUTPUTS = [Port.parse(50, "ux uy uz")]
RAYLEIGH = Damping("rayleigh", alpha=2.0, beta=1e-5)


def system_of(damping=RAYLEIGH, outputs=OUTPUTS, n_nodes=12):
    body = spring_lattice(n_nodes=n_nodes, damping=damping)
    return prepare(body, Frame("tangent", 10), INPUTS, outputs).system


def with_dashpot(system):
    """Rayleigh damping plus a dashpot between two dofs: non-proportional damping."""
    d = system.damping.toarray()
    i, j = 5, 17
    d[[i, j], [i, j]] += 30.0
    d[i, j] -= 30.0
    d[j, i] -= 30.0
    return replace(system, damping=sp.csr_matrix(d))


def dense(matrix):
    return matrix.toarray() if sp.issparse(matrix) else np.asarray(matrix)


def first_order(system):
    """Paper eq. 5 in the state ``[s0 q; q']`` (a scalar scaling s0 balances the blocks, so that
    the Lyapunov solver's forward error is small), with ``B_1``, ``C_1^T`` of the dual input."""
    m, k, d = dense(system.mass), dense(system.stiffness), dense(system.damping)
    n = m.shape[0]
    m_inv = np.linalg.inv(m)
    s0 = np.sqrt(np.abs(np.linalg.eigvals(m_inv @ k)).max())
    a = np.block([[np.zeros((n, n)), s0 * np.eye(n)], [-m_inv @ k / s0, -m_inv @ d]])
    b1 = np.vstack([np.zeros_like(system.input_matrix), m_inv @ system.input_matrix])
    dual = np.vstack([np.zeros_like(system.output_matrix.T), m_inv @ system.output_matrix.T])
    return a, b1, dual, s0


def eigenfrequencies_rad(system):
    values = sla.eigh(dense(system.stiffness), dense(system.mass), eigvals_only=True)
    return np.sqrt(np.clip(values, 0.0, None))


def band_quadrature(integrand, system, band_hz):
    """``1/(2 pi) int_{w1 <= |w| <= w2} g dw = 1/pi int_{w1}^{w2} Re g dw`` by adaptive quadrature
    with the eigenfrequencies as break points."""
    w1, w2 = 2 * np.pi * band_hz[0], 2 * np.pi * band_hz[1]
    points = [w for w in eigenfrequencies_rad(system) if w1 < w < w2]
    value, _ = quad_vec(integrand, w1, w2, points=points or None, epsrel=1e-11, limit=5000)
    return np.real(value) / np.pi


def relative(a, b):
    return np.abs(a - b).max() / np.abs(b).max()


# ----------------------------------------------------------------------------------------------
# (a) Gramians


@pytest.mark.parametrize("kind", ["rayleigh", "dashpot"])
def test_full_band_gramians_solve_the_lyapunov_equations(kind):
    system = system_of() if kind == "rayleigh" else with_dashpot(system_of())
    n = system.order
    a, b1, dual, s0 = first_order(system)
    p = sla.solve_continuous_lyapunov(a, -b1 @ b1.T)
    p_p, q_pv = frequency_weighted_gramians(system, (0.0, np.inf))
    assert relative(p_p, p[:n, :n] / s0**2) < 1e-10
    # Q_pv = M^-T Q_v M^-1 with Q the observability Gramian: A^T Q + Q A + C_1^T C_1 = 0
    c1 = np.hstack([system.output_matrix / s0, np.zeros_like(system.output_matrix)])  # y = C q
    q = sla.solve_continuous_lyapunov(a.T, -c1.T @ c1)
    m_inv = np.linalg.inv(dense(system.mass))
    assert relative(q_pv, m_inv @ q[n:, n:] @ m_inv) < 1e-10
    # ... which is the position Gramian of the dual system (input C^T)
    p_dual = sla.solve_continuous_lyapunov(a, -dual @ dual.T)
    assert relative(q_pv, p_dual[:n, :n] / s0**2) < 1e-10
    assert np.allclose(p_p, p_p.T, rtol=0, atol=1e-14 * np.abs(p_p).max())


@pytest.mark.parametrize("kind", ["rayleigh", "dashpot"])
@pytest.mark.parametrize("band", [(0.0, 40.0), (20.0, 80.0)])
def test_band_gramians_equal_the_frequency_integral(kind, band):
    """The matrix-logarithm formula against quadrature of
    ``1/(2 pi) int (i w I - A)^-1 B_1 B_1^T (i w I - A)^-H dw`` over the band (both signs)."""
    system = system_of() if kind == "rayleigh" else with_dashpot(system_of())
    n = system.order
    a, b1, dual, s0 = first_order(system)
    identity = np.eye(2 * n)

    def integrand(rhs):
        def g(w):
            x = np.linalg.solve(1j * w * identity - a, rhs)[:n] / s0
            return x @ x.conj().T

        return g

    p_ref = band_quadrature(integrand(b1), system, band)
    q_ref = band_quadrature(integrand(dual), system, band)
    p_p, q_pv = frequency_weighted_gramians(system, band)
    assert relative(p_p, p_ref) < 1e-10
    assert relative(q_pv, q_ref) < 1e-10


def test_collocated_ports_give_equal_gramians():
    system = system_of(outputs=INPUTS)  # C = B^T
    p_p, q_pv = frequency_weighted_gramians(system, (5.0, 60.0))
    assert relative(q_pv, p_p) < 1e-13


def test_critically_damped_mode_uses_the_matrix_logarithm():
    """A mode with d = 2 omega has no eigenvector basis: the general path (Lyapunov + logm)."""
    omega = np.array([3.0, 7.0, 20.0])
    d = np.diag([2.0 * omega[0], 0.3, 0.5])  # first mode critically damped
    rng = np.random.default_rng(3)
    q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    system = SecondOrderSystem(
        mass=np.eye(3),
        stiffness=q @ np.diag(omega**2) @ q.T,
        damping=q @ d @ q.T,
        input_matrix=rng.normal(size=(3, 2)),
        output_matrix=rng.normal(size=(1, 3)),
    )
    a, b1, _, s0 = first_order(system)
    p = sla.solve_continuous_lyapunov(a, -b1 @ b1.T)[:3, :3] / s0**2
    assert relative(frequency_weighted_gramians(system, (0.0, np.inf))[0], p) < 1e-10
    band = (0.2, 2.5)
    identity = np.eye(6)

    def g(w):
        x = np.linalg.solve(1j * w * identity - a, b1)[:3] / s0
        return x @ x.conj().T

    p_band = band_quadrature(g, system, band)
    assert relative(frequency_weighted_gramians(system, band)[0], p_band) < 1e-9


def test_damping_models():
    undamped = system_of(damping=None)
    with pytest.raises(UserError, match="undamped"):
        frequency_weighted_gramians(undamped, (0.0, 50.0))
    # a modal damping ratio is viscous modal damping M Phi diag(2 xi omega) Phi^T M
    modal = system_of(damping=Damping("modal", ratio=0.02))
    p_modal, _ = frequency_weighted_gramians(modal, (0.0, 50.0))
    p_given, _ = frequency_weighted_gramians(undamped, (0.0, 50.0), damping_ratio=0.02)
    assert relative(p_given, p_modal) < 1e-13
    m, k = dense(modal.mass), dense(modal.stiffness)
    values, phi = sla.eigh(k, m)
    viscous = m @ phi @ np.diag(2 * 0.02 * np.sqrt(values)) @ phi.T @ m
    explicit = replace(undamped, damping=viscous)
    assert relative(frequency_weighted_gramians(explicit, (0.0, 50.0))[0], p_modal) < 1e-8


def free_truss():
    body = replace(space_truss(), damping=Damping("rayleigh", alpha=5.0, beta=2e-6))
    nodes = body.node_ids
    inputs = [Port.parse(int(nodes[0]), "ux uy uz")]
    outputs = [Port.parse(int(nodes[-1]), "ux uy uz"), Port.parse(int(nodes[5]), "uz")]
    return prepare(body, Frame("buckens"), inputs, outputs).system


def test_free_body_drops_unexcited_rigid_modes():
    system = free_truss()
    assert system.rigid_modes is not None
    band = (100.0, 3000.0)
    m, k, d = dense(system.mass), dense(system.stiffness), dense(system.damping)
    b = system.input_matrix

    def g(w):  # R(i w) B is regular for w > 0
        x = np.linalg.solve(-(w**2) * m + 1j * w * d + k, b)
        return x @ x.conj().T

    p_ref = band_quadrature(g, system, band)
    p_p, _ = frequency_weighted_gramians(system, band)
    assert relative(p_p, p_ref) < 1e-8
    # reduction: an elastic basis, and the reduced model is stable
    model = reduced_model(system, gramian_reduction(system, band, order=10))
    assert np.abs(system.rigid_modes.T @ (system.mass @ model.projection.V)).max() < 1e-10
    assert model.eigenfrequencies_hz.min() > 1.0
    # inputs on a rigid-body mode: no Gramian
    pushed = replace(system, input_matrix=system.input_matrix + m @ system.rigid_modes[:, :1])
    with pytest.raises(UserError, match="rigid-body"):
        frequency_weighted_gramians(pushed, band)


# ----------------------------------------------------------------------------------------------
# (b) POD


def dominant(matrix, count):
    values, vectors = np.linalg.eigh(matrix)
    return values[::-1], vectors[:, ::-1][:, :count]


def largest_angle(u, v):
    """Sine of the largest principal angle between the spans of orthonormal u and v."""
    return float(np.linalg.norm(u - v @ (v.T @ u), 2))


@pytest.mark.parametrize("band", [(0.0, 40.0), (20.0, 80.0)])
def test_pod_approximates_the_gramian(band):
    sparse = with_dashpot(system_of())
    system = replace(  # dense: 800 small dense solves
        sparse,
        mass=dense(sparse.mass),
        stiffness=dense(sparse.stiffness),
        damping=dense(sparse.damping),
    )
    p_p, q_pv = frequency_weighted_gramians(system, band)
    sigma, vectors = dominant(p_p + q_pv, 6)
    errors = []
    for count in (40, 800):
        pod = pod_reduction(system, band, order=6, n_snapshots=count)
        approx = np.array(pod.parameters["sigma"][:6])
        errors.append(np.abs(approx - sigma[:6]).max() / sigma[0])
        assert np.allclose(pod.V.T @ pod.V, np.eye(6), atol=1e-12)
    assert errors[1] < 1e-5
    assert errors[1] < 1e-2 * errors[0]
    assert largest_angle(pod.V, vectors) < 1e-4


def test_pod_trapezoid_of_a_free_body_starts_at_zero_hz():
    """0 Hz is a node of the trapezoidal rule: solved by inertia relief."""
    system = free_truss()
    band = (0.0, 2000.0)
    frequencies, weights = quadrature(band, 400, "trapezoid")
    assert frequencies[0] == 0.0 and weights.sum() == pytest.approx(2 * np.pi * 2000.0)
    pod = pod_reduction(system, band, order=8, n_snapshots=400, rule="trapezoid")
    p_p, q_pv = frequency_weighted_gramians(system, band)
    sigma, vectors = dominant(p_p + q_pv, 8)
    approx = np.array(pod.parameters["sigma"][:8])
    assert np.abs(approx - sigma[:8]).max() < 1e-3 * sigma[0]
    # the basis is elastic: mass-orthogonal to the rigid-body modes
    rigid = system.rigid_modes
    assert np.abs(rigid.T @ (system.mass @ pod.V)).max() < 1e-10
    assert largest_angle(pod.V[:, :4], vectors) < 1e-2


# ----------------------------------------------------------------------------------------------
# (c) the error bound of eq. 24


def poles_and_residues(system):
    """``H(s) = sum_i c_i b_i^T / (s - lambda_i)`` from the eigenvectors of paper eq. 5."""
    m, k, d = dense(system.mass), dense(system.stiffness), dense(system.damping)
    n = m.shape[0]
    m_inv = np.linalg.inv(m)
    a = np.block([[np.zeros((n, n)), np.eye(n)], [-m_inv @ k, -m_inv @ d]])
    b1 = np.vstack([np.zeros_like(system.input_matrix), m_inv @ system.input_matrix])
    c1 = np.hstack([system.output_matrix, np.zeros_like(system.output_matrix)])
    lam, x = np.linalg.eig(a)
    return lam, c1 @ x, np.linalg.solve(x, b1)


def h2_error(system, reduced, band_hz, points=20):
    """Band-limited H2 error ``(1/(2 pi) int_band ||H - H_bar||_F^2 dw)^(1/2)``, the H2 norm of
    ``H`` for ``reduced = None``: composite Gauss-Legendre quadrature on panels that resolve
    every resonance peak (break points at ``Im lambda + {0, +-1/2, ..., +-16} |Re lambda|``)."""
    parts = [(1.0, poles_and_residues(system))]
    if reduced is not None:
        parts.append((-1.0, poles_and_residues(reduced)))
    w1, w2 = 2 * np.pi * band_hz[0], 2 * np.pi * band_hz[1]
    steps = np.array([0.0, 0.5, 1.0, 2.0, 4.0, 8.0, 16.0])
    breaks = [np.linspace(w1, w2, 101)]
    for _, (lam, _, _) in parts:
        breaks += [
            np.abs(lam.imag)[:, None] + np.abs(lam.real)[:, None] * s for s in (steps, -steps)
        ]
    breaks = np.unique(np.clip(np.concatenate([b.ravel() for b in breaks]), w1, w2))
    x, weights = np.polynomial.legendre.leggauss(points)
    half, centre = 0.5 * np.diff(breaks), 0.5 * (breaks[1:] + breaks[:-1])
    nodes = (centre[:, None] + half[:, None] * x).ravel()
    weights = (half[:, None] * weights).ravel()
    response = sum(
        sign * np.einsum("ri,fi,ip->frp", right, 1.0 / (1j * nodes[:, None] - lam), left)
        for sign, (lam, right, left) in parts
    )
    integrand = np.sum(np.abs(response) ** 2, axis=(1, 2))
    return float(np.sqrt(np.sum(weights * integrand) / np.pi))


@pytest.mark.parametrize(
    ("damping", "band"),
    [
        (RAYLEIGH, (0.0, 50.0)),
        (Damping("rayleigh", alpha=0.5, beta=1e-6), (0.0, 100.0)),  # light damping
        (RAYLEIGH, (15.0, 70.0)),
    ],
)
def test_error_bound_is_above_the_true_h2_error(damping, band):
    system = system_of(damping=damping)
    p_p, _ = frequency_weighted_gramians(system, band)
    c = system.output_matrix
    norm = h2_error(system, None, band)
    assert np.sqrt(np.trace(c @ p_p @ c.T)) == pytest.approx(norm, rel=1e-8)
    for order in (2, 4, 6, 10, 15, 20):
        projection = gramian_reduction(system, band, order=order)
        reduced = reduced_model(system, projection).system
        true = h2_error(system, reduced, band)
        parameters = projection.parameters
        assert parameters["h2_norm"] == pytest.approx(norm, rel=1e-8)
        assert true <= projection.error_bound
        assert true <= parameters["a_priori_bound"]  # eq. 24 with kappa = kappa_T = 1
        sigma = np.array(parameters["sigma"])
        assert parameters["neglected_sum"] == pytest.approx(sigma[order:].sum())


# ----------------------------------------------------------------------------------------------
# (d) automatic order


@pytest.mark.parametrize("tolerance", [1e-1, 1e-3, 1e-5, 1e-7])
def test_tolerance_gives_the_smallest_admissible_order(tolerance):
    system = system_of()
    band = (0.0, 50.0)
    p_p, q_pv = frequency_weighted_gramians(system, band)
    sigma = np.clip(np.linalg.eigvalsh(p_p + q_pv)[::-1], 0, None)
    expected = next(
        n for n in range(1, sigma.size + 1) if np.append(sigma, 0)[n] <= tolerance * sigma[0]
    )
    projection = gramian_reduction(system, band, tolerance=tolerance)
    assert projection.order == projection.parameters["order"] == expected
    indicator = projection.parameters["indicator"]
    assert indicator[expected - 1] <= tolerance
    assert expected == 1 or indicator[expected - 2] > tolerance
    # an order with a tolerance caps it
    capped = gramian_reduction(system, band, order=3, tolerance=tolerance)
    assert capped.order == min(3, expected)
    # the POD uses the same indicator on its approximate eigenvalues
    pod = pod_reduction(system, band, tolerance=tolerance, n_snapshots=60)
    indicator = pod.parameters["indicator"]
    n = pod.order
    assert indicator[n - 1] <= tolerance and (n == 1 or indicator[n - 2] > tolerance)
    singular = np.array(pod.parameters["singular_values"])
    assert np.allclose(np.array(pod.parameters["sigma"]), singular**2)


# ----------------------------------------------------------------------------------------------
# (e) two-step approach


def test_two_step_matches_the_dense_gramian_reduction():
    system = system_of(n_nodes=120)  # 354 dofs, 10 eigenfrequencies below 5 Hz
    band = (0.0, 5.0)
    medium = krylov_reduction(system, np.linspace(0.0, 5.0, 6), moments=3)
    f = frequency_grid(*band, 100)
    full = transfer_function(system, f)

    def max_error(projection):
        model = reduced_model(system, projection)
        return relative_error(full, transfer_function(model.system, f)).max()

    two_step = gramian_reduction(system, band, order=30, medium=medium, kappa_points=0)
    direct = gramian_reduction(system, band, order=30, kappa_points=0)
    assert two_step.error_bound is None
    assert two_step.method == "two-step gramian" and two_step.order == 30
    assert two_step.parameters["medium_order"] == medium.order
    e_two, e_direct = max_error(two_step), max_error(direct)
    assert e_direct < 1e-6
    assert e_two < max(3.0 * e_direct, 1e-7)
    # the medium model's Gramian eigenvalues approximate those of the full model
    sigma_two = np.array(two_step.parameters["sigma"][:10])
    sigma_direct = np.array(direct.parameters["sigma"][:10])
    assert np.abs(sigma_two - sigma_direct).max() < 1e-3 * sigma_direct[0]


# ----------------------------------------------------------------------------------------------
# options


def test_bad_options(monkeypatch):
    system = system_of()
    with pytest.raises(UserError, match=r"order.*tolerance"):
        gramian_reduction(system, (0.0, 50.0))
    with pytest.raises(UserError, match="f_min < f_max"):
        gramian_reduction(system, (50.0, 10.0), order=3)
    with pytest.raises(UserError, match="finite"):
        gramian_reduction(system, (0.0, np.inf), order=3)
    with pytest.raises(UserError, match="tolerance"):
        gramian_reduction(system, (0.0, 50.0), tolerance=2.0)
    with pytest.raises(UserError, match="exceeds"):
        gramian_reduction(system, (0.0, 50.0), order=system.order + 1)
    with pytest.raises(UserError, match="exceeds"):
        pod_reduction(system, (0.0, 50.0), order=200, n_snapshots=4)
    with pytest.raises(UserError, match="rule"):
        pod_reduction(system, (0.0, 50.0), order=3, rule="simpson")
    monkeypatch.setattr(gramian, "MAX_DENSE_ORDER", 20)
    with pytest.raises(UserError, match="two-step"):
        gramian_reduction(system, (0.0, 50.0), order=3)
