"""One factor per matrix within a job: :func:`pymorembs.linalg.shared_factorizations`.

The factorizations are counted at the backend (``factorize``), and every shared solve is
compared with a solve by SciPy's own sparse LU of the same matrix, written here.
"""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from pymorembs.linalg import factorization, shared_factorizations
from pymorembs.linalg.factorization import Factorization
from pymorembs.linalg.shared_factors import active_shared_factors

N = 200


@pytest.fixture()
def pencil():
    """A stiffness (a 1-D chain fixed at one end) and a lumped mass, shape (N, N)."""
    main = np.full(N, 2.0)
    main[-1] = 1.0
    stiffness = sp.diags([main, -np.ones(N - 1), -np.ones(N - 1)], [0, 1, -1], format="csr")
    mass = sp.diags(np.linspace(1.0, 2.0, N), format="csr")
    return 1e4 * stiffness, mass


@pytest.fixture()
def counted(monkeypatch):
    """The number of backend factorizations made (a one-element list)."""
    made = [0]
    original = factorization.factorize

    def counting(*args, **kwargs):
        made[0] += 1
        return original(*args, **kwargs)

    monkeypatch.setattr(factorization, "factorize", counting)
    return made


def scipy_solve(terms, rhs):
    matrix = sum(c * m for c, m in terms)
    return spla.splu(sp.csc_matrix(matrix)).solve(rhs)


def test_the_same_terms_are_factorized_once_within_the_block(pencil, counted):
    k, m = pencil
    rhs = np.random.default_rng(1).standard_normal((N, 2))
    shift = [(1.0, k), (-3.0, m)]
    with shared_factorizations(1e9) as shared:
        first = Factorization(shift)
        second = Factorization(list(shift))  # equal terms, another list
        third = Factorization([(1.0, k), (-4.0, m)])  # another shift: its own factor
        assert (first.reused, second.reused, third.reused) == (False, True, False)
        assert second.factor is first.factor
        assert (shared.made, shared.reused, counted[0]) == (2, 1, 2)
        for f, terms in ((second, shift), (third, [(1.0, k), (-4.0, m)])):
            x = f.solve(rhs)
            assert np.allclose(x, scipy_solve(terms, rhs), rtol=1e-9, atol=0)
    assert active_shared_factors() is None
    Factorization(shift)  # outside the block: factorized again
    assert counted[0] == 3


def test_a_copy_of_a_matrix_is_another_matrix(pencil, counted):
    k, m = pencil
    with shared_factorizations(1e9):
        Factorization([(1.0, k), (-3.0, m)])
        Factorization([(1.0, k.copy()), (-3.0, m)])
    assert counted[0] == 2


def test_nothing_is_kept_beyond_the_budget(pencil, counted):
    k, m = pencil
    with shared_factorizations(0.0) as shared:
        Factorization(k)
        assert not Factorization(k).reused
        assert (len(shared), shared.dropped, counted[0]) == (0, 2, 2)
    one = Factorization(k).factor.memory_bytes
    with shared_factorizations(1.5 * one) as shared:  # room for one: the older one goes
        Factorization(k)
        Factorization([(1.0, k), (-1.0, m)])
        assert len(shared) == 1 and shared.dropped == 1
        assert not Factorization(k).reused
        assert Factorization(k).reused


def test_the_real_shifts_of_a_pencil_are_found(pencil):
    k, m = pencil
    with shared_factorizations(1e9) as shared:
        Factorization(k)
        Factorization([(1.0, k), (-5.0, m)])
        Factorization([(1.0, k), (-5.0 + 1.0j, m)])  # complex: not a real shift
        Factorization([(1.0, m), (-5.0, k)])  # not K - tau M
        shifts = sorted(tau for tau, _ in shared.real_shifts(k, m))
    assert shifts == [0.0, 5.0]


def test_over_the_budget_the_least_used_factor_goes_first(pencil, counted):
    """K serves many steps of a job, an interior factor one: K stays when a third arrives."""
    k, m = pencil
    one = Factorization(k).factor.memory_bytes
    with shared_factorizations(2.5 * one) as shared:  # room for two
        Factorization(k)
        assert Factorization(k).reused  # K used twice
        Factorization([(1.0, k), (-1.0, m)])  # used once, more recently than K
        Factorization([(1.0, k), (-2.0, m)])  # over the budget: the shift at -1 goes
        assert len(shared) == 2 and shared.dropped == 1
        assert Factorization(k).reused
        assert Factorization([(1.0, k), (-2.0, m)]).reused  # the new one stayed
        assert not Factorization([(1.0, k), (-1.0, m)]).reused
    assert counted[0] == 5


def test_pardiso_factors_of_one_pattern_are_counted_each_once(pencil, monkeypatch):
    """PARDISO keeps the shifts of one pattern in one handle, and its memory counts are the
    handle's: the count of the third factor covers all three. The budget takes each factor's
    own share, so three fit where three shares fit."""
    from pymorembs.linalg import backends

    if "pardiso" not in backends.available_backends():
        pytest.skip("PARDISO is not installed")
    monkeypatch.setenv("PYMOREMBS_SOLVER", "pardiso")
    k, m = pencil
    shifts = [[(1.0, k)], [(1.0, k), (-1.0, m)], [(1.0, k), (-2.0, m)]]
    factors = [Factorization(terms, share=False).factor for terms in shifts]
    assert all(f.backend == "pardiso" for f in factors)
    counts = [f.memory_bytes for f in factors]
    assert counts[0] < counts[1] < counts[2]  # the handle's total, growing
    own = [f.held_bytes for f in factors]
    assert own[0] == own[1] == own[2] == factors[0].nnz_factor * 12  # float64 + index
    with shared_factorizations(3.5 * own[0]) as shared:
        for terms in shifts:
            Factorization(terms)
        assert len(shared) == 3 and shared.dropped == 0
        assert all(Factorization(terms).reused for terms in shifts)
