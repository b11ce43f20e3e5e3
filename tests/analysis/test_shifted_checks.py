"""Checks of the error reference from a real factor the job holds (analysis/shifted_checks.py).

Every response is compared with the full model's response computed here another way: a dense
(or SciPy sparse LU) complex solve of the dynamic stiffness ``(1 + i eta) K - omega^2 M``
written out in the test.
"""

from __future__ import annotations

import numpy as np
import pytest
import scipy.linalg as sla
import scipy.sparse as sp
import scipy.sparse.linalg as spla

import pymorembs.analysis.reference as reference_module
import pymorembs.analysis.shifted_checks as shifted_checks
from pymorembs.analysis.error import relative_error
from pymorembs.analysis.reference import reference_response
from pymorembs.analysis.shifted_checks import shifted_response
from pymorembs.analysis.transfer import transfer_function
from pymorembs.body import Damping
from pymorembs.examples import build_example
from pymorembs.frequencies import frequency_grid
from pymorembs.linalg import factorization, shared_factorizations
from pymorembs.linalg.backends import factorize
from pymorembs.preparation import Frame, Port, prepare
from pymorembs.system import SecondOrderSystem

N = 300
ETA = 0.04


@pytest.fixture(scope="module")
def chain():
    """A fixed-free chain of 300 masses with a 4 % loss factor, two inputs, all outputs."""
    main = np.full(N, 2.0)
    main[-1] = 1.0
    k = 4e6 * sp.diags([main, -np.ones(N - 1), -np.ones(N - 1)], [0, 1, -1], format="csr")
    m = sp.diags(np.linspace(1.0, 2.0, N), format="csr")
    b = np.zeros((N, 2))
    b[N - 1, 0] = 1.0
    b[N // 2, 1] = 1.0
    return SecondOrderSystem(m, k, None, b, np.eye(N), loss_factor=ETA)


def dense_response(system, frequency_hz):
    """``x = ((1 + i eta) K - omega^2 M)^{-1} B`` by a dense complex solve."""
    omega = 2 * np.pi * frequency_hz
    z = (
        1 + 1j * system.loss_factor
    ) * system.stiffness.toarray() - omega**2 * system.mass.toarray()
    return np.linalg.solve(z, system.input_matrix)


def low_modes(system, count):
    """The ``count`` lowest eigenvalues and mass-normalised modes (dense)."""
    values, vectors = sla.eigh(system.stiffness.toarray(), system.mass.toarray())
    return values[:count], vectors[:, :count]


@pytest.mark.parametrize("frequency_hz", [3.0, 30.0, 47.5])
def test_a_check_from_a_nearby_real_factor_is_the_full_response(chain, frequency_hz):
    _, basis = low_modes(chain, 16)  # the modes up to about 53 Hz
    tau = (2 * np.pi * 40.0) ** 2  # one expansion point for all three frequencies
    factor = factorize(sp.csc_matrix(chain.stiffness - tau * chain.mass), symmetric=True)
    terms, scale = chain.dynamic_terms(2j * np.pi * frequency_hz)
    x, facts = shifted_response(terms, chain.input_matrix, factor, basis)
    assert x is not None, facts
    expected = dense_response(chain, frequency_hz)
    assert np.linalg.norm(x / scale - expected) <= 1e-11 * np.linalg.norm(expected)
    assert facts["backward_error"] <= shifted_checks.BACKWARD_TOL


def test_each_gmres_step_costs_one_solve_with_the_factor(chain):
    """The preconditioned blocks of the GMRES steps are kept: the correction is their
    combination, so a check makes one solve with the real factor per step and none more."""
    _, basis = low_modes(chain, 16)
    tau = (2 * np.pi * 40.0) ** 2
    factor = factorize(sp.csc_matrix(chain.stiffness - tau * chain.mass), symmetric=True)
    solves = []
    solve = factor.solve

    def counted(rhs):
        solves.append(rhs.shape)
        return solve(rhs)

    factor.solve = counted
    terms, scale = chain.dynamic_terms(2j * np.pi * 30.0)
    x, facts = shifted_response(terms, chain.input_matrix, factor, basis)
    assert x is not None and facts["refinements"] >= 1
    assert len(solves) == facts["gmres_steps"]
    expected = dense_response(chain, 30.0)
    assert np.linalg.norm(x / scale - expected) <= 1e-11 * np.linalg.norm(expected)


def test_an_answer_that_cannot_be_certified_is_refused(chain, monkeypatch):
    """160 Hz lies among ~40 modes that neither the basis nor the factor at 40 Hz resolve."""
    monkeypatch.setattr(shifted_checks, "MAX_REFINEMENTS", 2)
    _, basis = low_modes(chain, 16)
    tau = (2 * np.pi * 40.0) ** 2
    factor = factorize(sp.csc_matrix(chain.stiffness - tau * chain.mass), symmetric=True)
    terms, _ = chain.dynamic_terms(2j * np.pi * 160.0)
    x, facts = shifted_response(terms, chain.input_matrix, factor, basis)
    assert x is None and facts["refinements"] == shifted_checks.MAX_REFINEMENTS


@pytest.fixture(scope="module")
def rack():
    """rack-beams (3,996 dofs), tangent frame at node 2, 2 % modal damping, ports at 1 and 2."""
    body = build_example("rack-beams").with_damping(Damping("modal", ratio=0.02))
    ports = [Port.parse(1, "ux uy uz"), Port.parse(2, "ux uy uz")]
    return prepare(body, Frame("tangent", 2), ports, ports).system


def splu_response(system, frequencies_hz):
    """The full model's ``H`` by one SciPy complex sparse LU per frequency (plain solves:
    rack-beams' stiffness has cond ~1e11, so they are accurate to ~1e-6 only)."""
    out = []
    for f in frequencies_hz:
        omega = 2 * np.pi * f
        z = (1 + 1j * system.loss_factor) * system.stiffness - omega**2 * system.mass
        x = spla.splu(sp.csc_matrix(z)).solve(system.input_matrix.astype(complex))
        out.append(np.asarray(system.output_matrix @ x))
    return np.array(out)


@pytest.mark.slow
def test_the_checks_of_a_job_need_no_complex_factorization(rack, monkeypatch):
    """With the job's factors shared, every check at f > 0 comes from a real factor; the
    checked responses are the full model's, and so is every settled maximum error."""
    grid = frequency_grid(0.0, 1000.0, 120)
    kinds = []
    original = factorization.factorize

    def counting(matrix, *args, **kwargs):
        kinds.append(matrix.dtype.kind)
        return original(matrix, *args, **kwargs)

    monkeypatch.setattr(factorization, "factorize", counting)
    monkeypatch.setattr(reference_module, "ITERATIVE_CHECKS", True)
    monkeypatch.setattr(reference_module, "ITERATIVE_MIN_ORDER", 0)  # rack-beams is below it
    with shared_factorizations(1e9):
        reference = reference_response(rack, grid, "surrogate", checks=4)
        assert "c" not in kinds
        assert reference.parameters["checks_from_real_factors"] == 4  # 0 Hz: a real solve
        worse = reference.response * (1 + 1e-5 * np.sin(np.arange(grid.size)))[:, None, None]
        settled = reference.settled(worse)
    assert "c" not in kinds
    exact = np.flatnonzero(settled.exact)
    # the previous way: one refined complex factorization per frequency
    full = transfer_function(rack, grid[exact], workers=1)
    assert relative_error(full, settled.response[exact]).max() <= 1e-10
    plain = splu_response(rack, grid[exact])  # and SciPy's, to its accuracy
    assert relative_error(plain, settled.response[exact]).max() <= 1e-5
    eps_true = relative_error(full, worse[exact])
    eps = settled.errors(worse)
    assert np.argmax(eps) in exact  # the maximum lies on a checked frequency
    assert eps.max() == pytest.approx(eps_true.max(), rel=1e-6)
    # the previous way (complex factorizations, no sharing) gives the same reference
    monkeypatch.setattr(reference_module, "ITERATIVE_CHECKS", False)
    before = reference_response(rack, grid, "surrogate", checks=4)
    assert "c" in kinds
    both = np.flatnonzero(before.exact & reference.exact)
    assert both.size >= 4
    assert relative_error(before.response[both], reference.response[both]).max() <= 1e-10


def test_checks_of_one_basis_share_its_products(chain):
    """``Z V`` of the coarse space: the products ``A_i V`` are made once per basis and
    combined per frequency, to the same bits as multiplying ``Z`` out at each frequency."""
    _, basis = low_modes(chain, 12)
    factor = factorize(chain.stiffness, True)
    before = len(shifted_checks._BASIS_PRODUCTS)
    for frequency_hz in (30.0, 55.0):
        terms, _ = chain.dynamic_terms(2j * np.pi * frequency_hz)
        two_level = shifted_checks.TwoLevel(terms, factor, basis)
        direct = shifted_checks.apply(terms, basis.astype(complex))
        np.testing.assert_array_equal(two_level.z_basis, direct)
    kept = [key for key in shifted_checks._BASIS_PRODUCTS if key[0] == id(basis)]
    assert len(kept) == len(terms) and len(shifted_checks._BASIS_PRODUCTS) == before + len(kept)
    del basis, kept, two_level
    import gc

    gc.collect()
    assert len(shifted_checks._BASIS_PRODUCTS) == before  # freed with the basis
