"""Two-sided Krylov, oblique block diagonalisation and SOAGA against independent computations."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.linalg as sla
import scipy.sparse as sp
from test_reduce import OUTPUTS, moments_of, system_of
from threadpoolctl import threadpool_limits

import pymorembs.reduction.krylov as krylov_module
from pymorembs.analysis.error import relative_error
from pymorembs.analysis.transfer import transfer_function
from pymorembs.body import Damping
from pymorembs.errors import NumericalError, UserError
from pymorembs.frequencies import frequency_grid
from pymorembs.linalg.factorization import Factorization
from pymorembs.preparation import Port
from pymorembs.reduction.krylov import krylov_reduction
from pymorembs.reduction.projection import Projection, reduced_model
from pymorembs.reduction.soaga import GlobalSecondOrderArnoldi, soaga_reduction
from pymorembs.system import SecondOrderSystem

RAYLEIGH = Damping("rayleigh", alpha=2.0, beta=1e-5)
BAND = (0.0, 100.0)  # 40 modes of the 50-node lattice below 100 Hz
#: Below this the "true" error is round-off of the full solves, not reduction error.
ERROR_FLOOR = 1e-11


@pytest.fixture(autouse=True)
def single_threaded_blas():
    """As the command line does: threaded BLAS on small blocks is slow on small machines."""
    with threadpool_limits(1, "blas"):
        yield


@pytest.fixture(scope="module")
def lattice_system() -> SecondOrderSystem:
    """144 dofs, Rayleigh damping, 3 inputs, 3 outputs elsewhere (C != B^T).

    The lattice is a cantilever whose lowest frequency falls as 1 / n^2: 50 nodes keep the
    full solves' round-off (which the "true" errors contain) below :data:`ERROR_FLOOR`.
    """
    return system_of(RAYLEIGH, n_nodes=50)


@pytest.fixture(scope="module")
def full_response(lattice_system):
    """The full transfer function on the estimator grid of ``soaga_reduction(..., BAND)``."""
    cache: dict[bytes, np.ndarray] = {}

    def response(frequencies_hz: np.ndarray) -> np.ndarray:
        key = frequencies_hz.tobytes()
        if key not in cache:
            with threadpool_limits(1, "blas"):
                cache[key] = transfer_function(lattice_system, frequencies_hz)
        return cache[key]

    return response


def _relative_moment_errors(system, reduced, points, count):
    """``|m_j - m_bar_j| / |m_j|`` per point and moment; 0 where both moments vanish (the odd
    moments at 0 Hz without damping: ``H`` is a function of ``s^2``)."""
    errors = []
    for f in points:
        s0 = 2j * np.pi * f
        full, red = moments_of(system, s0, count), moments_of(reduced, s0, count)
        scale = np.linalg.norm(full[0])
        row = []
        for j in range(count):
            size = np.linalg.norm(full[j])
            difference = np.linalg.norm(red[j] - full[j])
            row.append(difference / size if size > 1e-12 * scale else difference / scale)
        errors.append(row)
    return np.array(errors)


# --- two-sided Krylov (eqs. 21-22) ---------------------------------------------------------------


@pytest.mark.parametrize(
    ("damping", "points", "moments", "control"),
    [
        (None, [0.0, 25.0], [3, 2], True),  # real, and rotated real recurrence
        (RAYLEIGH, [40.0], [2], True),  # complex recurrence
        (RAYLEIGH, [0.0, 15.0, 40.0], [2, 2, 3], False),
    ],
)
def test_two_sided_krylov_matches_twice_the_moments(damping, points, moments, control):
    system = system_of(damping, outputs=OUTPUTS)
    assert np.linalg.norm(system.output_matrix - system.input_matrix.T) > 0.5  # C != B^T
    projection = krylov_reduction(system, points, moments=moments, two_sided=True)
    assert projection.V.shape == projection.W.shape
    assert not projection.one_sided
    assert projection.parameters["output_moments"] == moments
    reduced = system.project(projection.V, projection.W)  # W^T (.) V, no post-processing
    for f, r in zip(points, moments, strict=True):
        errors = _relative_moment_errors(system, reduced, [f], 2 * r)[0]
        assert errors.max() <= 1e-8, (f, errors)
    if control:  # the one-sided projection on V alone misses some of these moments
        one_sided = system.project(krylov_reduction(system, points, moments=moments).V)
        missed = [
            _relative_moment_errors(system, one_sided, [f], 2 * r)[0].max()
            for f, r in zip(points, moments, strict=True)
        ]
        assert max(missed) > 1e-6


def test_two_sided_bases_are_padded_to_one_size():
    """One output, three inputs: W gets more moments until it is as large as V."""
    system = system_of(RAYLEIGH, outputs=[Port.parse(50, "ux")])
    points, moments = [0.0, 30.0], [2, 2]
    projection = krylov_reduction(system, points, moments=moments, two_sided=True)
    # V: 0 Hz 2 x 3 columns, 30 Hz (complex) 2 x 6; W starts with 2 x 1 and 2 x 2
    assert projection.V.shape == projection.W.shape == (system.order, 18)
    assert projection.parameters["moments"] == moments
    assert all(m > 2 for m in projection.parameters["output_moments"])
    reduced = system.project(projection.V, projection.W)
    errors = _relative_moment_errors(system, reduced, points, 4)
    assert errors.max() < 1e-8


def test_two_sided_needs_outputs_and_keeps_one_factorization_per_point(monkeypatch):
    labels = []

    class Counting(Factorization):
        def __init__(self, terms, label="matrix", check=True, **options):
            labels.append(label)
            super().__init__(terms, label=label, check=check, **options)

    monkeypatch.setattr(krylov_module, "Factorization", Counting)
    system = system_of(RAYLEIGH)
    krylov_reduction(system, [10.0, 30.0], order=20, two_sided=True)
    assert len(labels) == 2
    no_outputs = SecondOrderSystem(
        system.mass, system.stiffness, system.damping, system.input_matrix,
        np.zeros((0, system.order)),
    )  # fmt: skip
    with pytest.raises(UserError, match="needs outputs"):
        krylov_reduction(no_outputs, [10.0], moments=2, two_sided=True)


# --- oblique block diagonalisation (paper section 2.3) -------------------------------------------


def test_oblique_block_diagonalisation_keeps_the_transfer_function():
    system = system_of()  # undamped; a two-sided model need not be stable (its pencil is not
    # symmetric): about 0 Hz alone this one has real positive eigenvalues, with a second point
    # (15, 25 Hz) complex ones
    projection = krylov_reduction(system, [0.0], moments=[4], two_sided=True)
    raw = system.project(projection.V, projection.W)
    model = reduced_model(system, projection)
    v, w = model.projection.V, model.projection.W
    order = v.shape[1]
    np.testing.assert_allclose(w.T @ (system.mass @ v), np.eye(order), atol=1e-9)
    stiffness = w.T @ (system.stiffness @ v)
    scale = np.abs(np.diag(stiffness)).max()
    np.testing.assert_allclose(stiffness, model.system.stiffness, atol=1e-9 * scale)
    assert np.array_equal(model.system.mass, np.eye(order))
    # the eigenvalues are those of the oblique pencil
    values = np.sort(sla.eigvals(raw.stiffness, raw.mass).real)
    np.testing.assert_allclose(
        np.sort((2 * np.pi * model.eigenfrequencies_hz) ** 2), values, rtol=1e-8
    )
    f = np.concatenate([frequency_grid(0.0, 100.0, 200), np.linspace(0.0, 100.0, 201)])
    change = relative_error(transfer_function(raw, f), transfer_function(model.system, f))
    assert change.max() <= 1e-10


def test_oblique_complex_pairs_become_real_2x2_blocks():
    """A damped oblique model whose pencil has complex eigenvalues but which is stable."""
    rng = np.random.default_rng(12)
    n = 12
    a = rng.normal(size=(n, n))
    k = a @ a.T + n * np.eye(n)
    m = np.diag(rng.uniform(0.5, 2.0, n))
    system = SecondOrderSystem(
        sp.csr_matrix(m), sp.csr_matrix(k), sp.csr_matrix(0.5 * m + 0.05 * k),
        rng.normal(size=(n, 2)), rng.normal(size=(2, n)),
    )  # fmt: skip
    v = np.linalg.qr(rng.normal(size=(n, 5)))[0]
    w = np.linalg.qr(rng.normal(size=(n, 5)))[0]
    raw = system.project(v, w)
    values = sla.eigvals(raw.stiffness, raw.mass)
    assert np.count_nonzero(values.imag > 1e-6 * np.abs(values)) >= 1  # really complex
    model = reduced_model(system, Projection(v, w, "oblique"))
    pairs = model.projection.parameters["complex_eigenvalue_pairs"]
    assert pairs == np.count_nonzero(values.imag > 0)
    stiffness = model.system.stiffness
    blocks = 0
    i = 0
    while i < 5:  # real diagonal entries and [[a, b], [-b, a]] blocks, nothing else
        if i + 1 < 5 and stiffness[i, i + 1] != 0:
            a_, b_ = stiffness[i, i], stiffness[i, i + 1]
            np.testing.assert_array_equal(stiffness[i : i + 2, i : i + 2], [[a_, b_], [-b_, a_]])
            assert np.any(np.isclose(values, a_ + 1j * b_, rtol=1e-10))
            blocks, i = blocks + 1, i + 2
        else:
            i += 1
    assert blocks == pairs
    assert np.count_nonzero(stiffness) == 5 + 2 * pairs
    np.testing.assert_allclose(model.projection.W.T @ m @ model.projection.V, np.eye(5), atol=1e-12)
    f = np.linspace(0.0, 2.0, 101)
    change = relative_error(transfer_function(raw, f), transfer_function(model.system, f))
    assert change.max() <= 1e-10


def test_unstable_oblique_model_is_rejected():
    """Two-sided projections need not preserve stability; such a model is never returned."""
    system = system_of(RAYLEIGH)
    projection = krylov_reduction(system, [0.0, 15.0, 40.0], moments=[2, 2, 3], two_sided=True)
    with pytest.raises(NumericalError, match="unstable"):
        reduced_model(system, projection)


# --- SOAGA ---------------------------------------------------------------------------------------


@pytest.mark.parametrize(("damping", "frequency_hz"), [(None, 0.0), (None, 25.0), (RAYLEIGH, 15.0)])
def test_global_arnoldi_blocks_are_frobenius_orthonormal_and_match_moments(damping, frequency_hz):
    system = system_of(damping)
    process = GlobalSecondOrderArnoldi(system, frequency_hz, 1e-10)
    tops = [process.next_block() for _ in range(4)]
    gram = np.array([[np.vdot(a, b) for b in process.blocks] for a in process.blocks])
    np.testing.assert_allclose(gram, np.eye(len(process.blocks)), atol=1e-12)
    assert all(block.shape == (2 * system.order, system.n_inputs) for block in process.blocks)
    u, sigma, _ = np.linalg.svd(np.hstack(tops), full_matrices=False)
    v = u[:, sigma > 1e-10 * sigma[0]]
    errors = _relative_moment_errors(system, system.project(v), [frequency_hz], 4)[0]
    assert errors.max() < 1e-8  # the 4 blocks match 4 moments: the span is the Krylov space


def test_soaga_meets_the_tolerance_and_its_estimate_tracks_the_true_error(
    lattice_system, full_response
):
    system = lattice_system
    projection = soaga_reduction(system, BAND, tolerance=1e-4)
    parameters = projection.parameters
    assert parameters["stop"] == "tolerance"
    assert projection.method == "soaga" and projection.one_sided
    assert projection.error_estimate <= 1e-4
    assert parameters["order"] == projection.order < system.order / 2
    assert parameters["factorizations"] == len(parameters["expansion_points_hz"])
    assert set(parameters["expansion_points_hz"]) <= set(parameters["candidates_hz"])
    assert parameters["iterations"] == len(parameters["sequence_hz"])
    assert parameters["estimate_history"][-1] == projection.error_estimate
    v = projection.V
    np.testing.assert_allclose(v.T @ (system.mass @ v), np.eye(v.shape[1]), atol=1e-10)

    grid, estimate = projection.error_curve
    assert grid.size >= 200 and grid[0] == 0.0 and grid[-1] == BAND[1]
    assert projection.error_estimate == estimate.max()
    model = reduced_model(system, projection)
    true = relative_error(full_response(grid), transfer_function(model.system, grid))
    assert true.max() <= 1e-4
    above = true > ERROR_FLOOR
    assert np.count_nonzero(above) > 0.5 * grid.size
    ratio = estimate[above] / true[above]
    assert ratio.min() >= 0.1 and ratio.max() <= 10.0
    # and on a finer grid the estimator never saw
    fine = np.linspace(*BAND, 1001)[1::2]
    true = relative_error(transfer_function(system, fine), transfer_function(model.system, fine))
    assert true.max() <= 1e-4


@pytest.mark.parametrize("order", [20, 40])
def test_soaga_estimate_tracks_the_error_of_unconverged_models(
    lattice_system, full_response, order
):
    projection = soaga_reduction(lattice_system, BAND, max_order=order)
    assert projection.order == order and projection.parameters["stop"] == "max_order"
    grid, estimate = projection.error_curve
    model = reduced_model(lattice_system, projection)
    true = relative_error(full_response(grid), transfer_function(model.system, grid))
    assert true.max() > 1e-2  # far from converged
    above = true > ERROR_FLOOR
    ratio = estimate[above] / true[above]
    assert ratio.min() >= 0.1 and ratio.max() <= 10.0


def test_soaga_factorizes_only_chosen_points_and_each_once(monkeypatch):
    labels = []

    class Counting(Factorization):
        def __init__(self, terms, label="matrix", check=True, **options):
            labels.append(label)
            super().__init__(terms, label=label, check=check, **options)

    monkeypatch.setattr(krylov_module, "Factorization", Counting)
    system = system_of(RAYLEIGH)
    projection = soaga_reduction(system, BAND, n_candidates=8, block_per_step=1, max_order=30)
    used = projection.parameters["expansion_points_hz"]
    assert len(labels) == len(set(labels)) == len(used) < 8
    assert sum(projection.parameters["moments"]) >= len(projection.parameters["sequence_hz"])


def test_soaga_block_per_step_and_given_candidates():
    system = system_of()  # undamped: real recurrences, 3 columns per moment
    projection = soaga_reduction(
        system, (5.0, 60.0), candidates_hz=[50.0, 10.0, 30.0], block_per_step=2, max_order=24
    )
    parameters = projection.parameters
    assert parameters["candidates_hz"] == [10.0, 30.0, 50.0]
    assert parameters["sequence_hz"][0] == 10.0
    assert parameters["moments"][0] >= 2
    grid, _ = projection.error_curve
    assert grid[0] == 5.0 and grid[-1] == 60.0
    assert projection.order == 24


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"band_hz": (10.0, 5.0), "tolerance": 1e-3}, "f_min < f_max"),
        ({"band_hz": "abc", "tolerance": 1e-3}, "two frequencies"),
        ({"band_hz": BAND}, "tolerance"),
        ({"band_hz": BAND, "tolerance": -1.0}, "> 0"),
        ({"band_hz": BAND, "max_order": 10**6}, "max_order"),
        ({"band_hz": BAND, "max_order": 5, "candidates_hz": []}, "at least one"),
        ({"band_hz": BAND, "max_order": 5, "candidates_hz": [1.0, 1.0]}, "repeat"),
        ({"band_hz": BAND, "max_order": 5, "candidates_hz": [-1.0]}, ">= 0"),
        ({"band_hz": BAND, "max_order": 5, "block_per_step": 0}, "block_per_step"),
        ({"band_hz": BAND, "max_order": 5, "n_candidates": 0}, "n_candidates"),
    ],
)
def test_bad_soaga_options(kwargs, message):
    with pytest.raises(UserError, match=message):
        soaga_reduction(system_of(n_nodes=8), **kwargs)


def test_soaga_opens_no_point_without_memory_for_its_factorization(lattice_system, monkeypatch):
    """When another factorization would not fit, SOAGA goes on with the points it has."""
    import pymorembs.reduction.soaga as soaga_module

    free = soaga_reduction(lattice_system, BAND, tolerance=1e-8)
    assert free.parameters["factorizations"] > 1 and not free.parameters["memory_limited"]
    monkeypatch.setattr(soaga_module, "available_memory_bytes", lambda: 1.0)  # 1 byte left
    tight = soaga_reduction(lattice_system, BAND, tolerance=1e-8)
    assert tight.parameters["factorizations"] == 1
    assert tight.parameters["memory_limited"]
    assert tight.parameters["stop"] in ("memory", "tolerance", "exhausted")
    assert tight.order > 0
