"""ElasticBody helpers (top-level module ``pymorembs.body``)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from conftest import spring_lattice
from pymorembs.errors import UserError


def test_with_notes_adds_notes_and_shares_everything_else():
    body = spring_lattice()
    noted = body.with_notes("dof table: proved", "units: SI")
    assert noted.notes == (*body.notes, "dof table: proved", "units: SI")
    assert noted.stiffness is body.stiffness and noted.mass is body.mass
    assert noted.dofs is body.dofs and noted.n_dof == body.n_dof
    assert "units: SI" not in body.notes  # the original is untouched (frozen value)


def test_matrices_must_be_finite_even_where_their_sum_overflows():
    """The finiteness check adds the entries first: a sum that overflows does not refuse a
    body whose entries are all finite, and NaN or inf is refused with the matrix named."""
    body = spring_lattice()
    huge = body.stiffness.copy()
    huge.data[:] = 1e308  # finite entries whose sum is inf
    assert np.all(dataclasses.replace(body, stiffness=huge).stiffness.data == 1e308)
    for bad in (np.inf, -np.inf, np.nan):
        mass = body.mass.copy()
        mass.data[-1] = bad
        with pytest.raises(UserError, match="mass matrix has NaN or infinite entries"):
            dataclasses.replace(body, mass=mass)


def test_a_matrix_with_repeated_entries_is_summed_on_a_copy():
    """A CSR matrix with repeated entries (as assembled element by element) gives a body with
    the summed, canonical matrix, and the caller's matrix keeps its arrays: ``csr_matrix(A)``
    shares them, and summing in place once left ``A`` with fewer entries than its arrays."""
    import scipy.sparse as sp

    body = spring_lattice()
    k = body.stiffness.tocoo()
    extra = np.arange(5)  # five entries stored twice, the second copy half of the first
    rows, cols = np.r_[k.row, k.row[extra]], np.r_[k.col, k.col[extra]]
    values = np.r_[k.data, 0.5 * k.data[extra]]
    order = np.lexsort((cols, rows))
    indptr = np.searchsorted(rows[order], np.arange(k.shape[0] + 1)).astype(np.int32)
    given = sp.csr_matrix((values[order], cols[order].astype(np.int32), indptr), shape=k.shape)
    arrays = [a.copy() for a in (given.data, given.indices, given.indptr)]
    made = dataclasses.replace(body, stiffness=given).stiffness
    assert made.has_canonical_format and made.nnz == k.nnz
    expected = body.stiffness.toarray()
    expected[k.row[extra], k.col[extra]] *= 1.5
    assert np.array_equal(made.toarray(), expected)
    for before, after in zip(arrays, (given.data, given.indices, given.indptr), strict=True):
        assert np.array_equal(before, after)
    assert given.nnz == given.data.size == k.nnz + 5
