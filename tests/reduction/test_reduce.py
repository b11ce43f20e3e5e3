"""Modal and Krylov reduction against independent dense computations."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
import scipy.linalg as sla

from conftest import spring_lattice
from pymorembs.analysis.error import relative_error
from pymorembs.analysis.transfer import transfer_function
from pymorembs.body import Damping
from pymorembs.errors import UserError
from pymorembs.frequencies import frequency_grid
from pymorembs.preparation import Frame, Port, prepare
from pymorembs.reduction.krylov import krylov_reduction
from pymorembs.reduction.modal import modal_reduction
from pymorembs.reduction.projection import reduced_model

INPUTS = [Port.parse(70, "ux uy"), Port.parse(40, "uz")]
OUTPUTS = [Port.parse(50, "ux uy uz")]


def system_of(damping=None, outputs=OUTPUTS, n_nodes=40):
    body = spring_lattice(n_nodes=n_nodes, damping=damping)
    return prepare(body, Frame("tangent", 10), INPUTS, outputs).system


def dense_moments(m, d, k, b, c, s0, count):
    """Moments m_j of H(s) = sum_j m_j (s - s0)^j, from the definition with dense algebra.

    (s^2 M + s D + K) X(s) = B expanded about s0:
    K_hat X_0 = B,  K_hat X_j = -(D_hat X_{j-1} + M X_{j-2}).
    """
    m, k = np.asarray(m, dtype=complex), np.asarray(k, dtype=complex)
    d = np.zeros_like(m) if d is None else np.asarray(d, dtype=complex)
    k_hat = s0**2 * m + s0 * d + k
    d_hat = 2 * s0 * m + d
    xs = [np.linalg.solve(k_hat, b)]
    for j in range(1, count):
        rhs = d_hat @ xs[-1] + (m @ xs[-2] if j > 1 else 0)
        xs.append(-np.linalg.solve(k_hat, rhs))
    return [c @ x for x in xs]


def moments_of(system, s0, count):
    def dense(a):
        return None if a is None else (a.toarray() if hasattr(a, "toarray") else a)

    return dense_moments(
        dense(system.mass),
        dense(system.damping),
        dense(system.stiffness),
        system.input_matrix,
        system.output_matrix,
        s0,
        count,
    )


@pytest.mark.parametrize(
    ("damping", "points", "moments"),
    [
        (None, [0.0, 25.0], [3, 2]),  # real, and rotated real recurrence
        (Damping("rayleigh", alpha=2.0, beta=1e-5), [0.0, 15.0, 40.0], [2, 2, 3]),  # complex
    ],
)
@pytest.mark.usefixtures("each_solver")
def test_krylov_matches_moments(damping, points, moments):
    system = system_of(damping)
    projection = krylov_reduction(system, points, moments=moments)
    reduced = reduced_model(system, projection).system
    for f, r in zip(points, moments, strict=True):
        s0 = 2j * np.pi * f
        full = moments_of(system, s0, r + 1)
        red = moments_of(reduced, s0, r + 1)
        for j in range(r):  # one-sided projection: r moments match
            assert np.linalg.norm(red[j] - full[j]) <= 1e-8 * np.linalg.norm(full[j])
    # control: a modal basis of the same size does not match these moments
    modal = reduced_model(system, modal_reduction(system, projection.order)).system
    s0 = 2j * np.pi * points[-1]
    full, red = moments_of(system, s0, 2), moments_of(modal, s0, 2)
    assert np.linalg.norm(red[1] - full[1]) > 1e-6 * np.linalg.norm(full[1])


def test_krylov_matches_twice_the_moments_for_collocated_ports():
    system = system_of(outputs=INPUTS)  # C = B^T, symmetric matrices
    projection = krylov_reduction(system, [0.0, 30.0], moments=2)
    reduced = reduced_model(system, projection).system
    for f in (0.0, 30.0):
        s0 = 2j * np.pi * f
        full, red = moments_of(system, s0, 4), moments_of(reduced, s0, 4)
        for j in range(4):
            assert np.linalg.norm(red[j] - full[j]) <= 1e-8 * np.linalg.norm(full[j])


@pytest.mark.usefixtures("each_solver")
def test_krylov_static_response_is_exact():
    system = system_of(Damping("rayleigh", alpha=1.0, beta=1e-6))
    model = reduced_model(system, krylov_reduction(system, [0.0, 20.0], order=12))
    assert model.projection.order == 12
    f = np.array([0.0])
    eps = relative_error(transfer_function(system, f), transfer_function(model.system, f))
    assert eps[0] <= 1e-10


def test_krylov_order_cuts_round_robin_and_basis_is_orthonormal():
    system = system_of()
    projection = krylov_reduction(system, [0.0, 10.0, 30.0], order=17)
    v = projection.V
    assert v.shape == (system.order, 17)
    assert np.allclose(v.T @ v, np.eye(17), atol=1e-12)
    # undamped: at 0 Hz the odd moments vanish (H is a function of s^2), so 0 Hz needs 3 blocks
    # for 6 columns; 3 inputs: 6 + 6 + 5 columns
    assert projection.parameters["moments"] == [3, 2, 2]


def test_krylov_deflates_dependent_directions():
    system = system_of()
    # the same input twice: the block has rank 3, not 6
    doubled = replace(
        system,
        input_matrix=np.hstack([system.input_matrix, 2 * system.input_matrix]),
        input_labels=(),
    )
    # undamped at 0 Hz: P_0, P_1 = 0, P_2 -> 3 + 0 + 3 directions, however often B repeats
    assert krylov_reduction(doubled, [0.0], moments=3).order == 6
    assert krylov_reduction(system, [0.0], moments=3).order == 6
    assert krylov_reduction(doubled, [0.0], moments=2).order == 3


def test_modal_reduction_equals_dense_eigenproblem():
    system = system_of(n_nodes=30)
    k, m = system.stiffness.toarray(), system.mass.toarray()
    values = sla.eigh(k, m, eigvals_only=True)
    model = reduced_model(system, modal_reduction(system, 8))
    assert np.allclose((2 * np.pi * model.eigenfrequencies_hz) ** 2, values[:8], rtol=1e-9)
    v = model.projection.V
    assert np.allclose(v.T @ (system.mass @ v), np.eye(8), atol=1e-10)


def test_all_modes_reproduce_the_full_response():
    system = system_of(Damping("rayleigh", alpha=0.5, beta=2e-6), n_nodes=8)
    k, m = system.stiffness.toarray(), system.mass.toarray()
    _, vectors = sla.eigh(k, m)
    from pymorembs.reduction.projection import Projection

    model = reduced_model(system, Projection(vectors, vectors, "all-modes"))
    f = frequency_grid(0.0, 200.0, 200)
    eps = relative_error(transfer_function(system, f), transfer_function(model.system, f))
    assert eps.max() < 1e-9


def test_modal_damping_ratio_gives_diagonal_damping():
    system = system_of(Damping("modal", ratio=0.02))
    model = reduced_model(system, modal_reduction(system, 5))
    omega = 2 * np.pi * model.eigenfrequencies_hz
    assert np.allclose(model.damping_matrix, np.diag(2 * 0.02 * omega))
    assert model.system.damping is None  # the frequency response uses the loss factor
    assert system.loss_factor == pytest.approx(0.04)


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"expansion_points_hz": []}, "must be a list of .* got an empty list"),
        ({"expansion_points_hz": [-5.0], "moments": 2}, ">= 0"),
        ({"expansion_points_hz": [1.0, 1.0], "moments": 2}, "repeat"),
        ({"expansion_points_hz": [1.0]}, "moments"),
        ({"expansion_points_hz": [1.0, 2.0], "moments": [1, 2, 3]}, "moments: 3 values for 2"),
        ({"expansion_points_hz": [1.0], "order": 10**6}, "exceeds"),
    ],
)
def test_bad_krylov_options(kwargs, message):
    with pytest.raises(UserError, match=message):
        krylov_reduction(system_of(), **kwargs)


def test_modal_order_larger_than_model():
    with pytest.raises(UserError, match="modes requested"):
        modal_reduction(system_of(n_nodes=8), 100)


def test_krylov_keeps_a_weak_input():
    """An input 1e-11 times weaker than the others still gets its moments matched."""
    system = system_of()
    b = system.input_matrix.copy()
    b[:, 1] *= 1e-11
    weak = replace(system, input_matrix=b)
    model = reduced_model(weak, krylov_reduction(weak, [0.0, 20.0], moments=2))
    f = np.array([0.0, 20.0])  # the expansion points: moments match there
    full, red = transfer_function(weak, f), transfer_function(model.system, f)
    column = np.linalg.norm(red[:, :, 1] - full[:, :, 1], axis=1) / np.linalg.norm(
        full[:, :, 1], axis=1
    )
    assert column.max() < 1e-9


def test_the_parameters_of_a_projection_are_read_only():
    """Issue #28: a projection is complete when built; a further fact makes a new one."""
    projection = modal_reduction(system_of(n_nodes=8), 4)
    with pytest.raises(TypeError):
        projection.parameters["order"] = 5  # type: ignore[index]
    later = projection.with_parameters(order_capped_by_first_stage=4)
    assert later.parameters["order_capped_by_first_stage"] == 4
    assert "order_capped_by_first_stage" not in projection.parameters
    assert later.V is projection.V and dict(later.parameters) == {
        **projection.parameters,
        "order_capped_by_first_stage": 4,
    }


def test_expansion_candidates_are_the_points_a_method_factorizes_at():
    """Krylov's expansion points, SOAGA's candidates (default: equidistant from 1e-3 f_max),
    nothing for the modal methods: what a job's error reference chooses its points from."""
    from pymorembs.methods import method_options
    from pymorembs.reduction import expansion_candidates

    krylov = method_options("krylov", {"expansion_points_hz": [0, 500, 1000], "order": 12})
    assert expansion_candidates(krylov, (0.0, 1000.0)) == [0.0, 500.0, 1000.0]
    soaga = method_options("soaga", {"tolerance": 1e-6, "n_candidates": 4})
    assert expansion_candidates(soaga, (0.0, 1000.0)) == pytest.approx([1.0, 334.0, 667.0, 1000.0])
    given = method_options("soaga", {"order": 20, "candidates_hz": [100, 300]})
    assert expansion_candidates(given, (0.0, 1000.0)) == [100.0, 300.0]
    assert expansion_candidates(method_options("modal", {"order": 10}), (0.0, 1000.0)) == []
