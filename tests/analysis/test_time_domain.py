"""Time integration of full and reduced models (paper section 5.1) against independent references.

References: closed-form responses of damped oscillators (modal superposition for several dofs),
an independent trapezoidal rule on the first-order form, static solves with SuperLU, and the
eigenfrequencies of the clamped full model from ARPACK.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
import scipy.linalg as sla
import scipy.sparse as sp
import scipy.sparse.linalg as spla
from threadpoolctl import threadpool_limits

from conftest import space_truss, spring_lattice
from pymorembs.analysis.time_domain import (
    DEFAULT_RHO_INF,
    GeneralizedAlpha,
    LoadCase,
    clamped_full_system,
    clamped_reduced_system,
    compare,
    paper_load_cases,
    simulate,
)
from pymorembs.body import Damping
from pymorembs.errors import UserError
from pymorembs.examples import build_example
from pymorembs.preparation import Frame, Port, prepare
from pymorembs.reduction.krylov import krylov_reduction
from pymorembs.reduction.modal import modal_reduction
from pymorembs.reduction.projection import reduced_model
from pymorembs.report.time_plots import plot_time_responses
from pymorembs.system import SecondOrderSystem


@pytest.fixture(autouse=True)
def one_thread():
    with threadpool_limits(1):
        yield


# ----------------------------------------------------------------------------- references
def oscillator_response(omega2, damping, load, t, case: LoadCase) -> np.ndarray:
    """Closed-form response from rest of ``x'' + c x' + omega^2 x = p u(t)``, per mode.

    ``omega2``, ``damping`` (c), ``load`` (p): shape (k,); ``t``: shape (n_t,). Returns (n_t, k)
    for ``u`` a unit step at 0+ or ``sin(Omega t)``. With the roots ``l1, l2`` of
    ``l^2 + c l + omega^2`` (complex for underdamped, real for overdamped modes):
    step ``x = p / omega^2 (1 - (l2 e^{l1 t} - l1 e^{l2 t}) / (l2 - l1))``; harmonic: the
    stationary part ``Im(H e^{i Omega t})``, ``H = p / (omega^2 - Omega^2 + i c Omega)``, plus the
    free vibration ``c1 e^{l1 t} + c2 e^{l2 t}`` that starts it from rest.
    """
    w2 = np.asarray(omega2, dtype=complex)
    c = np.asarray(damping, dtype=complex)
    root = np.sqrt(c * c / 4.0 - w2)
    l1, l2 = -c / 2.0 + root, -c / 2.0 - root
    t = np.asarray(t)[:, None]
    if case.kind == "step":
        return np.real(load / w2 * (1.0 - (l2 * np.exp(l1 * t) - l1 * np.exp(l2 * t)) / (l2 - l1)))
    big = 2.0 * np.pi * case.frequency_hz
    h = load / (w2 - big**2 + 1j * c * big)
    x0, v0 = -np.imag(h), -np.imag(1j * big * h)
    c1 = (v0 - l2 * x0) / (l1 - l2)
    return np.imag(h * np.exp(1j * big * t)) + np.real(
        c1 * np.exp(l1 * t) + (x0 - c1) * np.exp(l2 * t)
    )


def modal_reference(system: SecondOrderSystem, alpha, beta, case: LoadCase, t) -> np.ndarray:
    """Exact response (n_t, r) of a Rayleigh-damped system by modal superposition."""
    k = system.stiffness.toarray() if sp.issparse(system.stiffness) else system.stiffness
    m = system.mass.toarray() if sp.issparse(system.mass) else system.mass
    w2, modes = sla.eigh(k, m)
    load = modes.T @ system.input_matrix @ case.force_n
    eta = oscillator_response(w2, alpha + beta * w2, load, t, case)
    return eta @ (system.output_matrix @ modes).T


def trapezoidal_states(m, k, d, b, case: LoadCase, h: float, n_steps: int) -> np.ndarray:
    """The trapezoidal rule on ``z = (q, v)`` from rest, load sampled at mid-step: the
    displacements ``q(t_k)``, shape (n_steps + 1, n) (dense matrices; independent of
    :func:`~pymorembs.analysis.time_domain.integrate`)."""
    n = m.shape[0]
    e = np.block([[np.eye(n), np.zeros((n, n))], [np.zeros((n, n)), m]])
    a_mat = np.block([[np.zeros((n, n)), np.eye(n)], [-k, -d]])
    left, right = sla.lu_factor(e - h / 2 * a_mat), e + h / 2 * a_mat
    z = np.zeros((n_steps + 1, 2 * n))
    for step in range(n_steps):
        load = np.concatenate([np.zeros(n), b @ case.force(np.array([(step + 0.5) * h]))[0]])
        z[step + 1] = sla.lu_solve(left, right @ z[step] + h * load)
    return z[:, :n]


def dense_system(m, k, d, b, c) -> SecondOrderSystem:
    return SecondOrderSystem(
        mass=np.atleast_2d(m), stiffness=np.atleast_2d(k), damping=np.atleast_2d(d),
        input_matrix=np.atleast_2d(b), output_matrix=np.atleast_2d(c),
    )  # fmt: skip


def rel_error(y, reference) -> float:
    return float(np.abs(y - reference).max() / np.abs(reference).max())


# ------------------------------------------------------------------------ small oscillators
def test_load_cases_of_the_paper():
    step, harmonic = paper_load_cases()
    t = np.array([0.0, 1e-9, 0.025, 0.05])
    assert np.array_equal(step.force(t)[0], np.zeros(3))
    assert np.allclose(step.force(t)[1:], -100.0)
    assert np.allclose(harmonic.force(t)[:, 0], [0.0, -100 * np.sin(2e-8 * np.pi), -100.0, 0.0])
    assert np.array_equal(step.initial_force(), [-100.0] * 3)
    assert np.array_equal(harmonic.initial_force(), np.zeros(3))
    with pytest.raises(UserError, match="kind"):
        LoadCase("x", "ramp", np.ones(3))


def test_generalized_alpha_parameters():
    trapezoidal = GeneralizedAlpha(1.0)
    assert (trapezoidal.alpha_m, trapezoidal.alpha_f) == (0.5, 0.5)
    assert (trapezoidal.beta, trapezoidal.gamma) == (0.25, 0.5)
    annihilating = GeneralizedAlpha(0.0)
    assert (annihilating.alpha_m, annihilating.alpha_f) == (-1.0, 0.0)
    assert (annihilating.beta, annihilating.gamma) == (1.0, 1.5)
    with pytest.raises(UserError, match="rho_inf"):
        GeneralizedAlpha(1.5)


SDOF_CASES = [
    LoadCase("step", "step", np.array([3.0])),
    LoadCase("harmonic", "harmonic", np.array([3.0]), frequency_hz=3.0),
]


@pytest.mark.parametrize("rho_inf", [1.0, DEFAULT_RHO_INF, 0.5, 0.0])
def test_single_dof_converges_to_the_closed_form_at_second_order(rho_inf):
    mass, omega, zeta = 2.0, 2 * np.pi * 5.0, 0.05
    system = dense_system(mass, mass * omega**2, 2 * zeta * omega * mass, 1.0, 1.0)
    errors = []
    for step in (2e-3, 1e-3, 5e-4):
        response = simulate(system, SDOF_CASES, duration_s=1.0, step_s=step, rho_inf=rho_inf)
        row = []
        for case in SDOF_CASES:
            exact = oscillator_response(
                omega**2, 2 * zeta * omega, case.force_n / mass, response.times, case
            )
            row.append(rel_error(response.outputs[case.name], exact))
        errors.append(row)
    errors = np.array(errors)  # (steps, cases)
    orders = np.log2(errors[:-1] / errors[1:])
    assert orders.min() > 1.95, orders
    assert errors[-1].max() < 5e-4  # omega h = 0.016: period error ~2e-5 per period


def test_two_dof_rayleigh_system_matches_modal_superposition():
    m = np.array([[2.0, 0.3], [0.3, 1.0]])
    k = 1e4 * np.array([[3.0, -1.0], [-1.0, 1.0]])
    alpha, beta = 1.5, 2e-4
    b = np.array([[1.0], [0.5]])
    system = dense_system(m, k, alpha * m + beta * k, b, np.array([[0.0, 1.0], [1.0, 0.0]]))
    response = simulate(system, SDOF_CASES, duration_s=0.5, step_s=1e-4)  # omega h <= 0.02
    for case in SDOF_CASES:
        reference = modal_reference(system, alpha, beta, case, response.times)
        assert rel_error(response.outputs[case.name], reference) < 1e-4  # measured 4e-5


def test_rho_one_is_the_trapezoidal_rule():
    """rho_inf = 1: the trapezoidal rule on z = (q, v), load sampled at mid-step (independent)."""
    rng = np.random.default_rng(4)
    a = rng.normal(size=(3, 3))
    m = a @ a.T + 3 * np.eye(3)
    a = rng.normal(size=(3, 3))
    k = 1e3 * (a @ a.T + np.eye(3))
    d = 0.01 * k + 0.5 * m
    b, c = rng.normal(size=(3, 1)), rng.normal(size=(2, 3))
    h, n_steps = 1e-3, 300
    response = simulate(dense_system(m, k, d, b, c), SDOF_CASES, n_steps * h, h, rho_inf=1.0)
    for case in SDOF_CASES:
        y = trapezoidal_states(m, k, d, b, case, h, n_steps) @ c.T
        assert rel_error(response.outputs[case.name], y) < 1e-11


def test_sparse_and_dense_paths_agree():
    body = spring_lattice(n_nodes=30, damping=Damping("rayleigh", alpha=2.0, beta=1e-4))
    port = [Port.parse(200, "ux uy uz")]
    system = prepare(body, Frame("tangent", 10), port, port).system
    dense = replace(
        system,
        mass=system.mass.toarray(),
        stiffness=system.stiffness.toarray(),
        damping=system.damping.toarray(),
    )
    cases = paper_load_cases()
    sparse_response = simulate(system, cases, duration_s=0.3, step_s=1e-3)
    dense_response = simulate(dense, cases, duration_s=0.3, step_s=1e-3)
    for case in cases:
        y = sparse_response.outputs[case.name]
        assert np.abs(y).max() > 0
        assert rel_error(dense_response.outputs[case.name], y) < 1e-11


def test_loss_factor_is_not_a_time_domain_model():
    system = replace(dense_system(1.0, 1.0, 0.0, 1.0, 1.0), loss_factor=0.04)
    with pytest.raises(UserError, match="loss factor"):
        simulate(system, SDOF_CASES)


# ------------------------------------------------------------------------------ rack-beams
def rayleigh(zeta: float, f1_hz: float, f2_hz: float) -> Damping:
    """Rayleigh damping with the ratio ``zeta`` at two frequencies (Hz)."""
    w1, w2 = 2 * np.pi * f1_hz, 2 * np.pi * f2_hz
    return Damping("rayleigh", alpha=2 * zeta * w1 * w2 / (w1 + w2), beta=2 * zeta / (w1 + w2))


RACK_DAMPING = rayleigh(0.02, 41.57, 1000.0)  # 2 % at the first mode and the top of the band


@pytest.fixture(scope="module")
def rack():
    return build_example("rack-beams").with_damping(RACK_DAMPING)


@pytest.fixture(scope="module")
def full_system(rack):
    return clamped_full_system(rack, clamp_node=2, load_node=1)


@pytest.fixture(scope="module")
def full_response(full_system):
    with threadpool_limits(1):
        return simulate(full_system, paper_load_cases())  # 0.2 s, h = 5e-5 s: 4000 steps


@pytest.fixture(scope="module")
def tangent_model(rack):
    port = [Port.parse(1, "ux uy uz")]
    prepared = prepare(rack, Frame("tangent", 2), port, port)
    model = reduced_model(
        prepared.system, krylov_reduction(prepared.system, [0.0, 300.0, 800.0], moments=[4, 3, 3])
    )
    return clamped_reduced_system(
        prepared.body, prepared.expand(model.projection.V), model.system.mass,
        model.system.stiffness, model.damping_matrix, clamp_node=2, load_node=1,
    )  # fmt: skip


def test_rack_tangent_krylov_model_follows_the_full_model(
    full_system, full_response, tangent_model
):
    assert full_system.order == 3942 and tangent_model.order < 40
    reduced = simulate(tangent_model, paper_load_cases())
    result = compare(full_response, reduced)
    # the issue asks for < 1 %; this Krylov model is far better (measured 2e-8)
    assert result["worst_rel_deviation"] < 1e-5, result
    assert result["speedup"] > 1.0
    step = full_response.outputs["step"]
    assert 12e-3 < np.abs(step[:, :2]).max() < 13e-3  # overshoot ~2x the 6.35 mm static value


def test_rack_step_settles_at_the_static_deflection(rack, tangent_model):
    damped = rack.with_damping(Damping("rayleigh", alpha=150.0, beta=6e-6))  # decay ~e^(-75 t)
    full = clamped_full_system(damped, 2, 1)
    step = paper_load_cases()[:1]
    damping = 150.0 * tangent_model.mass + 6e-6 * tangent_model.stiffness
    reduced = replace(tangent_model, damping=damping)
    static = full.output_matrix @ spla.spsolve(
        full.stiffness.tocsc(), full.input_matrix @ step[0].force_n
    )
    assert -6.4e-3 < static[0] < -6.3e-3  # 4 rods guided-guided: 100 N / 15.8 kN/m
    for system in (full, reduced):
        end = simulate(system, step, duration_s=0.3, step_s=2e-4).outputs["step"][-1]
        assert np.abs(end - static).max() < 1e-6 * np.abs(static).max()


def test_rack_temporal_convergence_against_the_modal_solution(tangent_model):
    """Reduced rack model, exact modal solution: the error falls 4x per halved step."""
    errors = []
    alpha, beta = RACK_DAMPING.alpha, RACK_DAMPING.beta
    for step in (1e-4, 5e-5, 2.5e-5):
        response = simulate(tangent_model, paper_load_cases(), duration_s=0.1, step_s=step)
        row = []
        for case in paper_load_cases():
            exact = modal_reference(tangent_model, alpha, beta, case, response.times)
            row.append(rel_error(response.outputs[case.name], exact))
        errors.append(row)
    errors = np.array(errors)
    assert np.log2(errors[:-1] / errors[1:]).min() > 1.9, errors
    assert errors[1].max() < 2e-4  # the default step: 1.2e-4 (step), 4.6e-5 (harmonic)


@pytest.fixture(scope="module")
def buckens(rack):
    ports = [Port.parse(1, "ux uy uz"), Port.parse(2, "all")]
    return prepare(rack, Frame("buckens"), ports, ports)


def clamped_from(prepared, projection):
    model = reduced_model(prepared.system, projection)
    basis = prepared.expand(model.projection.V)
    system = clamped_reduced_system(
        prepared.body, basis, model.system.mass, model.system.stiffness, model.damping_matrix, 2, 1
    )
    return system, basis


def frequencies_hz(system, count=3):
    values = sla.eigh(system.stiffness, system.mass, eigvals_only=True)[:count]
    return np.sqrt(values) / (2 * np.pi)


def test_buckens_model_held_at_node_2_matches_the_clamped_full_model(
    buckens, full_system, full_response
):
    body = buckens.body
    rigid = body.rigid_body_modes()
    assert np.abs(body.stiffness @ rigid).max() < 1e-12 * abs(body.stiffness).max()  # K R = 0
    values = spla.eigsh(full_system.stiffness, k=3, M=full_system.mass, sigma=0.0)[0]
    reference = np.sort(np.sqrt(values)) / (2 * np.pi)
    assert reference == pytest.approx([41.57, 41.62, 100.93], abs=0.01)

    krylov, basis = clamped_from(
        buckens, krylov_reduction(buckens.system, [0.0, 300.0, 800.0], moments=[2, 1, 1])
    )
    assert np.abs(rigid.T @ (body.mass @ basis)).max() < 1e-10  # Buckens: M_re = 0
    assert frequencies_hz(krylov) == pytest.approx(reference, rel=1e-7)
    result = compare(full_response, simulate(krylov, paper_load_cases()))
    assert result["worst_rel_deviation"] < 1e-5, result  # measured 1.4e-9

    # 20 free-free modes, no static correction: the clamped frequencies come out 7e-5 high
    modal, _ = clamped_from(buckens, modal_reduction(buckens.system, 20))
    error = frequencies_hz(modal) / reference - 1
    assert np.all(error > 0) and error.max() < 2e-4
    result = compare(full_response, simulate(modal, paper_load_cases()))
    assert 1e-5 < result["worst_rel_deviation"] < 1e-2, result  # measured 7.8e-4


def test_tangent_frame_at_another_node_is_held_through_its_frame(rack, full_response):
    """A tangent frame at node 1 clamped at node 2: the general case, M_re != 0."""
    port = [Port.parse(2, "all")]
    prepared = prepare(rack, Frame("tangent", 1), port, port)
    system, basis = clamped_from(
        prepared, krylov_reduction(prepared.system, [0.0, 300.0], moments=[3, 2])
    )
    rigid = prepared.body.rigid_body_modes()
    assert np.abs(rigid.T @ (prepared.body.mass @ basis)).max() > 0.1
    assert frequencies_hz(system) == pytest.approx([41.568, 41.624, 100.932], abs=2e-3)
    result = compare(full_response, simulate(system, paper_load_cases()))
    assert result["worst_rel_deviation"] < 1e-4, result  # measured 1.8e-6


def test_modal_damping_has_no_full_time_domain_model(rack):
    with pytest.raises(UserError, match="Rayleigh"):
        clamped_full_system(rack.with_damping(Damping("modal", ratio=0.02)), 2, 1)


def test_holding_a_floating_frame_needs_six_dofs_at_the_node():
    truss = space_truss()
    ports = [Port.parse(1, "ux uy uz")]
    prepared = prepare(truss, Frame("buckens"), ports, ports)
    model = reduced_model(prepared.system, modal_reduction(prepared.system, 6))
    with pytest.raises(UserError, match="all six"):
        clamped_reduced_system(
            prepared.body, prepared.expand(model.projection.V), model.system.mass,
            model.system.stiffness, None, clamp_node=24, load_node=1,
        )  # fmt: skip


def test_plot_of_full_and_reduced_responses(tmp_path, full_response, tangent_model):
    reduced = simulate(tangent_model, paper_load_cases())
    path = plot_time_responses(
        {"full (3942 dofs)": full_response, f"Krylov (n = {tangent_model.order})": reduced},
        tmp_path / "fig12.png",
    )
    assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    with pytest.raises(UserError, match="reference"):
        plot_time_responses({"a": reduced}, tmp_path / "x.png", reference="b")


def test_singular_mass_starts_at_zero_acceleration_with_a_warning():
    """A step on a massless dof: a_0 = M^-1 B u(0+) does not exist; the integration still runs."""
    k = [[2e4, -1e4], [-1e4, 1e4]]
    system = dense_system(np.diag([1.0, 0.0]), k, 50 * np.eye(2), [[0], [1]], [[1, 0]])
    with pytest.warns(UserWarning, match="massless directions"):
        response = simulate(system, SDOF_CASES[:1], duration_s=1.0, step_s=1e-3)
    # static end value: K x = b F with F = 3 -> x_1 = 3 / 1e4
    assert response.outputs["step"][-1, 0] == pytest.approx(3e-4, rel=1e-6)
