"""Rational-Krylov Gramians of large models (issue #6) against the dense frequency-weighted
Gramians of the full model, which are exact on these small models."""

from __future__ import annotations

import numpy as np
import pytest
from test_gramian import free_truss, system_of

from pymorembs.analysis.error import relative_error
from pymorembs.analysis.transfer import transfer_function
from pymorembs.errors import UserError
from pymorembs.frequencies import frequency_grid
from pymorembs.reduction.gramian import frequency_weighted_gramians, gramian_reduction
from pymorembs.reduction.projection import reduced_model
from pymorembs.reduction.rational_gramian import (
    rational_gramian_reduction,
    rational_krylov_gramians,
)

LARGE_NODES = 90  # 264 dofs, 12 eigenfrequencies below 12 Hz; inputs and outputs differ
BAND = (0.0, 12.0)


@pytest.fixture(scope="module")
def lattice():
    return system_of(n_nodes=LARGE_NODES)


@pytest.fixture(scope="module")
def dense_gramians(lattice):
    """``P_p^w``, ``Q_pv^w`` of the full lattice over :data:`BAND`."""
    return frequency_weighted_gramians(lattice, BAND)


@pytest.fixture(scope="module")
def full_response(lattice):
    f = frequency_grid(*BAND, 100)
    return f, transfer_function(lattice, f)


def eigenvalues(p_p, q_pv):
    return np.clip(np.linalg.eigvalsh(p_p + q_pv)[::-1], 0.0, None)


def max_error(system, projection, frequencies, full):
    model = reduced_model(system, projection)
    return relative_error(full, transfer_function(model.system, frequencies)).max()


@pytest.mark.parametrize("band", [BAND, (3.0, 8.0)])
def test_converges_to_the_dense_gramians(lattice, dense_gramians, band):
    system = lattice
    p_p, q_pv = dense_gramians if band == BAND else frequency_weighted_gramians(system, band)
    c = system.output_matrix
    trace = np.trace(c @ p_p @ c.T)
    sigma = eigenvalues(p_p, q_pv)
    result = rational_krylov_gramians(system, band, tol=1e-10)
    assert result.converged and result.stop == "converged"
    assert result.dimension < system.order / 5  # low rank
    assert result.factorizations == len(result.shifts_hz) == result.iterations
    assert all(band[0] <= f <= band[1] for f in result.shifts_hz)
    # trace(C P C^T) (squared band-limited H2 norm) and the leading sigma_i of P + Q
    assert abs(result.h2_norm**2 - trace) < 1e-9 * trace
    leading = min(20, result.sigma.size)
    assert np.abs(result.sigma[:leading] - sigma[:leading]).max() < 1e-9 * sigma[0]
    # the low-rank Gramians themselves, entrywise
    p_low = result.low_rank_factor("p")
    q_low = result.low_rank_factor("q")
    assert np.abs(p_low @ p_low.T - p_p).max() < 1e-7 * np.abs(p_p).max()
    assert np.abs(q_low @ q_low.T - q_pv).max() < 1e-7 * np.abs(q_pv).max()
    # the Galerkin residual of the integrand is small all over the grid
    assert result.residual.max() < 1e-5


def test_a_loose_tolerance_stops_early(lattice, dense_gramians):
    band = BAND
    p_p, q_pv = dense_gramians
    sigma = eigenvalues(p_p, q_pv)
    loose = rational_krylov_gramians(lattice, band, tol=1e-3)
    tight = rational_krylov_gramians(lattice, band, tol=1e-12)
    assert loose.converged and tight.converged
    assert loose.factorizations < tight.factorizations
    assert loose.dimension < tight.dimension
    changes = [h["change"] for h in loose.history]
    assert changes[-1] <= 1e-3 < changes[-2]  # stops at the first iteration that meets it
    # the stopping quantity is an honest measure here: the loose Gramian is off by about it
    error = np.abs(loose.sigma[:5] - sigma[:5]).max() / sigma[0]
    assert 1e-12 < error < 1e-2
    # a size limit stops before convergence
    limited = rational_krylov_gramians(lattice, band, tol=1e-12, max_shifts=2)
    assert not limited.converged and limited.stop == "max_shifts"
    assert limited.factorizations == 2 and limited.shifts_hz == [0.0, 12.0]


def test_reduction_matches_the_dense_gramian_reduction(lattice, full_response):
    system = lattice
    band = BAND
    f, full = full_response
    for order in (10, 30):
        dense = gramian_reduction(system, band, order=order, kappa_points=0)
        krylov = rational_gramian_reduction(system, band, order=order, kappa_points=0)
        assert krylov.method == "gramian" and krylov.order == order
        parameters = krylov.parameters
        assert parameters["gramian_solver"] == "rational-krylov"
        assert parameters["converged"] and parameters["factorizations"] >= 2
        assert parameters["krylov_dimension"] >= order
        e_dense = max_error(system, dense, f, full)
        e_krylov = max_error(system, krylov, f, full)
        assert e_krylov < 1.1 * e_dense + 1e-9
        sigma = np.array(parameters["sigma"][:order])
        sigma_dense = np.array(dense.parameters["sigma"][:order])
        assert np.abs(sigma - sigma_dense).max() < 1e-8 * sigma_dense[0]
    assert e_dense < 1e-6  # order 30 is accurate: the comparison above is not between failures
    # automatic order (eq. 24 indicator) and the a-posteriori bound
    for tolerance in (1e-3, 1e-6):
        dense = gramian_reduction(system, band, tolerance=tolerance, kappa_points=40)
        krylov = rational_gramian_reduction(system, band, tolerance=tolerance, kappa_points=40)
        assert krylov.order == dense.order
        assert krylov.parameters["solver_tol"] == pytest.approx(min(1e-8, 1e-2 * tolerance))
        # sigma only: equal; with kappa sampled on the projected instead of the full model: close
        a_priori = krylov.parameters["a_priori_bound"]
        assert a_priori == pytest.approx(dense.parameters["a_priori_bound"], rel=1e-4)
        assert krylov.error_bound == pytest.approx(dense.error_bound, rel=0.1)


def test_order_above_the_converged_dimension_grows_the_space(lattice):
    band = BAND
    loose = rational_krylov_gramians(lattice, band, tol=1e-3)
    order = loose.dimension + 2
    projection = rational_gramian_reduction(lattice, band, order=order, tol=1e-3, kappa_points=0)
    assert projection.order == order
    assert projection.parameters["krylov_dimension"] >= order
    assert projection.parameters["factorizations"] > loose.factorizations
    # beyond what the shifts can give: the order is capped, and that is recorded
    capped = rational_gramian_reduction(
        lattice, band, order=150, tol=1e-3, kappa_points=0, max_shifts=3
    )
    parameters = capped.parameters
    assert parameters["stop"] == "max_shifts" and not parameters["converged"]
    assert capped.order == parameters["order_capped_by_krylov_dimension"] < 150


def test_free_body():
    """Buckens frame: rigid-body modes neither excited nor observed; 0 Hz by inertia relief."""
    system = free_truss()
    band = (0.0, 2000.0)
    p_p, q_pv = frequency_weighted_gramians(system, band)
    sigma = eigenvalues(p_p, q_pv)
    result = rational_krylov_gramians(system, band, tol=1e-10)
    assert result.converged and result.shifts_hz[0] == 0.0
    assert np.abs(result.sigma[:8] - sigma[:8]).max() < 1e-8 * sigma[0]
    rigid = system.rigid_modes
    assert np.abs(rigid.T @ (system.mass @ result.basis)).max() < 1e-10
    projection = rational_gramian_reduction(system, band, order=8)
    dense = gramian_reduction(system, band, order=8)
    model = reduced_model(system, projection)
    assert np.abs(rigid.T @ (system.mass @ model.projection.V)).max() < 1e-10
    assert model.eigenfrequencies_hz.min() > 1.0
    f = frequency_grid(*band, 100)
    full = transfer_function(system, f)
    assert max_error(system, projection, f, full) < 1.1 * max_error(system, dense, f, full) + 1e-9


def test_bad_options(lattice):
    band = BAND
    with pytest.raises(UserError, match="tol"):
        rational_krylov_gramians(lattice, band, tol=0.0)
    with pytest.raises(UserError, match="moments"):
        rational_krylov_gramians(lattice, band, moments=0)
    with pytest.raises(UserError, match="finite"):
        rational_krylov_gramians(lattice, (0.0, np.inf))
    with pytest.raises(UserError, match=r"order.*tolerance"):
        rational_gramian_reduction(lattice, band)
    with pytest.raises(UserError, match="max_dim"):
        rational_gramian_reduction(lattice, band, order=50, max_dim=20)
    with pytest.raises(UserError, match="'p' or 'q'"):
        rational_krylov_gramians(lattice, band, tol=1e-3).low_rank_factor("x")


def test_job_option_first_stage_rational_krylov(lattice, tmp_path):
    """``first_stage = "rational-krylov"`` in a job reaches this solver (no medium model)."""
    from pymorembs.job.run import run_reduction
    from pymorembs.job.schema import ReductionSpec
    from pymorembs.methods import method_options

    options = {"order": 10, "first_stage": "rational-krylov", "convergence_tolerance": 1e-8}
    spec = ReductionSpec("rk", method_options("gramian", options))
    projection = run_reduction(lattice, spec, BAND)
    direct = rational_gramian_reduction(lattice, BAND, order=10, tol=1e-8)
    assert projection.parameters["gramian_solver"] == "rational-krylov"
    assert "medium_order" not in projection.parameters or not projection.parameters["two_step"]
    assert projection.order == 10
    assert np.allclose(projection.parameters["sigma"], direct.parameters["sigma"], rtol=1e-12)
