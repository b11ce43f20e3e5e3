"""Sums of sparse matrices on a merged pattern (linalg/pattern.py) against SciPy's own sums."""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from pymorembs.linalg.factorization import combine
from pymorembs.linalg.pattern import SumPattern, infinity_norm, sum_pattern


def _matrices(n: int = 60, seed: int = 3) -> list[sp.csr_matrix]:
    rng = np.random.default_rng(seed)
    stiffness = sp.random(n, n, density=0.2, random_state=rng, format="csr")
    stiffness = stiffness + stiffness.T + sp.identity(n) * 5
    mass = sp.random(n, n, density=0.05, random_state=rng, format="csr")
    mass = mass + mass.T
    mass = sp.csr_matrix(mass.multiply(np.arange(n)[:, None] % 7 != 0))  # empty rows too
    damping = sp.diags(rng.random(n), format="csr")
    return [sp.csr_matrix(stiffness), mass, damping]


def test_combination_equals_scipys_sum_on_the_merged_pattern() -> None:
    k, m, d = _matrices()
    pattern = SumPattern([k, m, d])
    coefficients = [1.0, -((2 * np.pi * 37.0) ** 2), 1j * 2 * np.pi * 37.0]
    ours = pattern.combine(coefficients)
    reference = coefficients[0] * k + coefficients[1] * m + coefficients[2] * d
    assert ours.has_canonical_format and ours.dtype == np.complex128
    assert abs(ours - reference).max() <= 1e-12 * abs(reference).max()
    # one pattern for every combination: a solver recognises it by identity
    other = pattern.combine([1.0, -1.0, 0.0])
    assert other.indices is ours.indices and other.indptr is ours.indptr
    stored = [sp.csr_matrix((np.ones(a.nnz), a.indices, a.indptr), a.shape) for a in (k, m, d)]
    assert pattern.nnz == (stored[0] + stored[1] + stored[2]).nnz  # stored zeros count too


def test_extended_precision_combination_does_not_round_the_terms() -> None:
    k, m, _ = _matrices()
    c = -((2 * np.pi * 500.0) ** 2) / 3.0
    wide = combine([(1.0, k), (c, m)], np.longdouble)
    assert wide.dtype == np.longdouble
    dense = k.toarray().astype(np.longdouble) + np.longdouble(c) * m.toarray().astype(np.longdouble)
    assert np.array_equal(wide.toarray(), dense)
    rounded = combine([(1.0, k), (c, m)])
    assert not np.array_equal(rounded.toarray().astype(np.longdouble), dense)  # double rounds


def test_pattern_is_cached_per_set_of_matrices_and_norm_is_exact() -> None:
    k, m, d = _matrices()
    assert sum_pattern([k, m]) is sum_pattern([k, m])
    assert sum_pattern([k, m]) is not sum_pattern([k, d])
    for matrix in (k, m, d, sp.csr_matrix((5, 5))):
        expected = spla.norm(matrix, np.inf) if matrix.nnz else 0.0
        assert abs(infinity_norm(matrix) - expected) <= 1e-15 * expected


def test_a_pattern_that_holds_the_others_is_the_merged_one_itself() -> None:
    # stiffness and a mass on part of its pattern (a consistent mass has one entry per
    # direction of the stiffness's 3 x 3 node blocks): the merged pattern is the stiffness's
    # own arrays, so the stiffness alone (at 0 Hz) and its shifts share one pattern
    k, m, d = _matrices()
    subset = sp.csr_matrix(k.multiply(np.add.outer(np.arange(60), np.arange(60)) % 3 == 0))
    subset.sum_duplicates()
    pattern = SumPattern([k, subset, d])
    assert pattern.indices is k.indices and pattern.indptr is k.indptr
    coefficients = [1.0, -((2 * np.pi * 37.0) ** 2), 0.5]
    ours = pattern.combine(coefficients)
    reference = coefficients[0] * k + coefficients[1] * subset + coefficients[2] * d
    assert abs(ours - reference).max() <= 1e-12 * abs(reference).max()
    assert combine([(1.0, k)]).indices is k.indices  # K alone: its own pattern
    # a mass outside the stiffness's pattern: a merged pattern of its own, the same sums
    other = SumPattern([k, m])
    assert other.indices is not k.indices and other.nnz > k.nnz
    reference = k - 3.0 * m
    assert abs(other.combine([1.0, -3.0]) - reference).max() <= 1e-12 * abs(reference).max()
