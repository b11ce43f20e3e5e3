"""Linear combinations ``sum_i c_i A_i`` of sparse matrices on one shared sparsity pattern.

Every expansion point, modal shift and frequency of a reduction factorizes a matrix of the same
form, ``K - omega^2 M (+ i omega D)``. SciPy forms each such sum by merging the patterns of the
terms anew (``csr_plus_csr``) and then converting and sorting the result, about 0.1 s per shift
at 35,000 dofs (4.8 M nonzeros) -- a sixth of a PARDISO factorization. :class:`SumPattern`
merges the patterns once and keeps, for every term, the positions of its entries in the merged
pattern; a combination is then one gather-and-add per term over the data arrays, in double
precision or, without rounding the terms first, in extended precision (``numpy.longdouble``).

The merged pattern is canonical CSR (sorted column indices, no duplicates) and its ``indptr``
and ``indices`` arrays are shared by all combinations, so a solver can recognise the pattern
(and reuse its fill-reducing ordering) without comparing it entry by entry.
"""

from __future__ import annotations

import weakref
from collections.abc import Sequence

import numpy as np
import scipy.sparse as sp

from pymorembs.linalg import double_double

__all__ = ["SumPattern", "infinity_norm", "sum_pattern"]


class SumPattern:
    """The union of the sparsity patterns of some square sparse matrices.

    Parameters
    ----------
    matrices : sequence of sparse matrices, all of shape (n, n)

    Attributes
    ----------
    shape : tuple of int
    indptr, indices : ndarray of int32
        The merged pattern, canonical CSR.
    positions : list of ndarray
        ``positions[i][k]`` is where the ``k``-th stored entry of ``matrices[i]`` (canonical CSR
        order) sits in the merged pattern.
    """

    def __init__(self, matrices: Sequence[sp.spmatrix]) -> None:
        parts = [_canonical(m) for m in matrices]
        shape = parts[0].shape
        if any(p.shape != shape for p in parts):
            raise ValueError("matrices of different shapes cannot be combined")
        self.shape = shape
        self._data = [p.data for p in parts]
        self._aligned: list[np.ndarray] | None = None
        contained = _contained(parts)
        if contained is not None:  # one pattern holds all others: it is the merged one
            self.indptr, self.indices, self.positions = contained
            return
        if len(parts) > 52:
            raise ValueError("at most 52 matrices can be combined")
        # the merged pattern, each entry flagged with bit i if matrix i stores it (flags in the
        # narrowest integer type: at millions of dofs every byte per entry is gigabytes)
        flag_type = np.int8 if len(parts) < 8 else np.int64
        union = _flagged(parts[0], 0, flag_type)
        for i, part in enumerate(parts[1:], start=1):
            union = union + _flagged(part, i, flag_type)  # positive flags: no entry cancels
        union.sum_duplicates()
        flags = union.data.astype(np.int64)
        first = parts[0]
        if union.nnz == first.nnz and first.indices.dtype == first.indptr.dtype == np.int32:
            # the first matrix (the stiffness) stores the merged pattern: share its arrays
            self.indptr, self.indices = first.indptr, first.indices
        else:
            self.indptr = union.indptr.astype(np.int32)
            self.indices = union.indices.astype(np.int32)
        del union
        # both patterns are sorted the same way, so the k-th entry of matrix i is the k-th
        # merged entry that carries flag i
        index_type = np.int32 if flags.size < 2**31 else np.int64
        self.positions = [
            np.flatnonzero((flags >> i) & 1).astype(index_type) for i in range(len(parts))
        ]

    @property
    def nnz(self) -> int:
        """Stored entries of the merged pattern."""
        return int(self.indices.size)

    def combine(self, coefficients: Sequence[complex], dtype: type | None = None) -> sp.csr_matrix:
        """``sum_i c_i A_i`` on the merged pattern.

        Parameters
        ----------
        coefficients : sequence of scalars, one per matrix
        dtype : numpy dtype, optional
            Of the result (e.g. ``numpy.longdouble`` to add the unrounded terms in extended
            precision); default ``result_type`` of coefficients and matrices.

        Returns
        -------
        scipy.sparse.csr_matrix, shape (n, n)
            Canonical; shares ``indptr`` and ``indices`` with every other combination.
        """
        if len(coefficients) != len(self.positions):
            raise ValueError(f"{len(coefficients)} coefficients for {len(self.positions)} terms")
        if dtype is None:
            dtype = np.result_type(*coefficients, *self._data)
        active = [
            (np.asarray(c, dtype=dtype), values)
            for c, values in zip(coefficients, self._aligned_data(), strict=True)
            if c != 0
        ]
        if not active:
            data = np.zeros(self.nnz, dtype=dtype)
        else:  # whole-array products, no gather or scatter
            data = np.multiply(active[0][1], active[0][0], dtype=dtype)
            compiled = double_double.available() and data.dtype == np.float64
            scratch = np.empty_like(data) if len(active) > 1 and not compiled else None
            for coefficient, values in active[1:]:
                if compiled and values.dtype == np.float64:  # one pass, no scratch array
                    from pymorembs.linalg import compiled_kernels

                    compiled_kernels.scaled_add(data, float(coefficient), values)
                    continue
                if scratch is None:
                    scratch = np.empty_like(data)
                np.multiply(values, coefficient, out=scratch, dtype=dtype)
                data += scratch
        combined = sp.csr_matrix(self.shape, dtype=dtype)
        combined.data, combined.indices, combined.indptr = data, self.indices, self.indptr
        combined.has_canonical_format = True
        return combined

    def _aligned_data(self) -> list[np.ndarray]:
        """The data of every matrix on the merged pattern (zeros where it stores nothing).

        A matrix whose pattern is the merged one (the stiffness, usually) is used as is; the
        others get one array of the merged size each, built on first use (at 300,000 dofs the
        mass matrix's costs 0.4 GB and saves a 16 M-entry gather and scatter per shift).
        """
        if self._aligned is None:
            aligned = []
            for where, values in zip(self.positions, self._data, strict=True):
                if where.size == self.nnz:
                    aligned.append(values)
                else:
                    full = np.zeros(self.nnz, dtype=values.dtype)
                    full[where] = values
                    aligned.append(full)
            self._aligned = aligned
        return self._aligned


def _contained(
    parts: list[sp.csr_matrix],
) -> tuple[np.ndarray, np.ndarray, list[np.ndarray]] | None:
    """The pattern of the largest of ``parts`` (its own ``indptr`` and ``indices`` arrays) and
    the positions of every part in it, when it holds all the others' entries (a stiffness
    matrix and a consistent or lumped mass); None otherwise or without the compiled kernels.

    Sharing the largest matrix's arrays lets a solver recognise that matrix alone (``K`` at
    0 Hz) and its shifts ``K - sigma M`` as one pattern.
    """
    if not double_double.available():
        return None
    from pymorembs.linalg import compiled_kernels

    largest = max(parts, key=lambda p: p.nnz)
    if largest.indptr.dtype != np.int32 or largest.indices.dtype != np.int32:
        return None
    positions = []
    for part in parts:
        if part is largest:
            positions.append(np.arange(largest.nnz))
            continue
        where = np.empty(part.nnz, dtype=np.int64)
        inside = compiled_kernels.subset_positions(
            largest.indptr, largest.indices, part.indptr, part.indices, where
        )
        if not inside:
            return None
        positions.append(where)
    return largest.indptr, largest.indices, positions


def _canonical(matrix: sp.spmatrix) -> sp.csr_matrix:
    """``matrix`` itself if it is canonical CSR (its index arrays are the very same objects, by
    which a solver recognises the pattern), else a canonical CSR copy (or view)."""
    if isinstance(matrix, sp.csr_matrix) and matrix.has_canonical_format:
        return matrix
    part = sp.csr_matrix(matrix)
    if not part.has_canonical_format:
        part = part.copy()
        part.sum_duplicates()
    return part


def _infinity_norm(matrix: sp.csr_matrix) -> float:
    """``max_i sum_j |a_ij|`` of a canonical CSR matrix, O(nnz), the pattern not copied."""
    if matrix.nnz == 0:
        return 0.0
    absolute = sp.csr_matrix((np.abs(matrix.data), matrix.indices, matrix.indptr), matrix.shape)
    return float(np.max(absolute @ np.ones(matrix.shape[1])))


def _flagged(part: sp.csr_matrix, bit: int, dtype: type = np.int64) -> sp.csr_matrix:
    """The pattern of ``part`` with all stored values ``2**bit`` (of ``dtype``)."""
    values = np.full(part.nnz, 2**bit, dtype=dtype)
    return sp.csr_matrix((values, part.indices, part.indptr), shape=part.shape)


_PATTERNS: dict[tuple[int, ...], SumPattern] = {}


def sum_pattern(matrices: Sequence[sp.spmatrix]) -> SumPattern:
    """The :class:`SumPattern` of ``matrices``, cached while all of them live.

    The cache is keyed by the identity of the matrix objects (FE matrices are not modified in
    place in pymorembs) and an entry is dropped as soon as one of its matrices is collected.
    """
    key = tuple(id(m) for m in matrices)
    pattern = _PATTERNS.get(key)
    if pattern is None:
        pattern = SumPattern(matrices)
        _PATTERNS[key] = pattern
        for matrix in matrices:
            weakref.finalize(matrix, _PATTERNS.pop, key, None)
    return pattern


def infinity_norm(matrix: sp.spmatrix) -> float:
    """``max_i sum_j |a_ij|`` of a sparse matrix (the matrix infinity norm), O(nnz)."""
    return _infinity_norm(_canonical(matrix))
