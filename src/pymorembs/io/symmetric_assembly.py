"""Fast assembly of a symmetric matrix from the entries of one triangle (or of both, sorted).

FE programs write a symmetric matrix as one triangle: sorted in row-major order in their own
equation order (Abaqus ``FORMAT=MATRIX INPUT``, whose equation order is not the order of the
node labels), or as both triangles with each off-diagonal entry followed by its mirror
(Abaqus/CAE ``FORMAT=COORDINATE``). :func:`assemble_symmetric_triangle` builds the full CSR
matrix of such entries in SciPy's compiled code (a counting sort by rows, or no sort at all when
the entries are sorted already) instead of sorting every entry by its position in NumPy, and
the full matrix is the triangle plus its transpose.

It returns exactly the matrix that :func:`pymorembs.io.reader_support.assemble_symmetric` returns
for the same entries (same pattern, same values), or None whenever that function would raise an
error or the entries are in none of these layouts; the caller then uses ``assemble_symmetric``,
which also names the offending lines.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from pymorembs.io.fast_text import canonical_csr

__all__ = ["assemble_symmetric_triangle", "half_of_entries", "symmetric_from_half"]

#: Entries handled at a time (the temporary arrays of a block stay in the caches).
_BLOCK = 1 << 16
#: Entries per block of rows in :func:`_row_counts` (each block costs a pass over ``n``).
_ROW_BLOCK = 1 << 20


def assemble_symmetric_triangle(
    rows: np.ndarray,
    cols: np.ndarray,
    values: np.ndarray,
    n: int,
    tolerance: float,
    base: int = 0,
) -> sp.csr_matrix | None:
    """The full symmetric ``n x n`` matrix of the entries of a triangle, or None.

    :func:`half_of_entries` followed by :func:`symmetric_from_half` (call those two to free the
    entries in between, which saves memory).
    """
    half = half_of_entries(rows, cols, values, n, tolerance, base)
    return None if half is None else symmetric_from_half(half)


def half_of_entries(
    rows: np.ndarray,
    cols: np.ndarray,
    values: np.ndarray,
    n: int,
    tolerance: float,
    base: int = 0,
) -> sp.csr_matrix | None:
    """Every position of the entries once, as a canonical CSR matrix without explicit zeros
    (the full matrix is it plus its transpose, the diagonal once), or None.

    Accepted layouts (``lo = min(row, col)``, ``hi = max(row, col)``, entries in file order):

    * every position ``(hi, lo)`` at most once, in any order (one triangle, in the writer's
      equation order; an entry may lie on either side of the diagonal);
    * the positions ``(lo, hi)`` (or ``(hi, lo)``) never decreasing in row-major order, a
      position at most twice, and then on consecutive lines in both orientations (an
      off-diagonal entry and its mirror) with values that differ by at most ``tolerance`` times
      the largest entry (their mean is used); when some position occurs twice the file stores
      both triangles, and every off-diagonal entry without its mirror must be at most that
      bound in magnitude (``assemble_symmetric``'s square storage).

    Parameters
    ----------
    rows, cols : ndarray of int, shape (nnz,)
        Equation numbers from ``base`` (below ``n + base``) in file order; int32 saves memory
        (and, with ``base`` 0, copies).
    values : ndarray of float, shape (nnz,)
    n : int
        Matrix size.
    tolerance : float
        Relative symmetry tolerance (``SYMMETRY_TOLERANCE`` of the Matrix Market reader).
    base : int
        The number of the first equation (1 for equation numbers counted from 1).

    Returns
    -------
    scipy.sparse.csr_matrix or None
        None for no entries, a NaN or infinity, a position repeated otherwise than as a sorted
        mirror pair, asymmetric mirrors or a lone entry of a square file (the caller's general
        assembly decides and names the line). A position given in both orientations in an
        unsorted file is found only by :func:`symmetric_from_half`.
    """
    nnz = values.size
    if nnz == 0 or n <= 0 or n >= 2**31 - 1:
        return None
    biggest = 0.0
    for start in range(0, nnz, _BLOCK):
        block = np.abs(values[start : start + _BLOCK])
        if not np.isfinite(block).all():
            return None
        biggest = max(biggest, float(block.max()))
    limit = tolerance * biggest
    for upper in (True, False):
        kept = _sorted_count(rows, cols, upper)
        if kept is not None:
            return _sorted_half(rows, cols, values, n, limit, base, upper, kept)
    r = rows if base == 0 else rows - base
    c = cols if base == 0 else cols - base
    half = sp.csr_matrix((values, (r, c)), shape=(n, n))  # SciPy's counting sort by rows
    if half.nnz != nnz:  # a position given twice in one orientation (summed here)
        return None
    half.eliminate_zeros()
    return half


def symmetric_from_half(half: sp.csr_matrix) -> sp.csr_matrix | None:
    """``half + half^T`` with the diagonal once (canonical, exactly symmetric), or None when
    some off-diagonal position of ``half`` is given in both orientations or nothing is left.
    """
    n = half.shape[0]
    if half.nnz == 0:
        return None
    lower, above, diagonal = _row_counts(half)
    full = sp.csr_matrix(half + half.T)  # canonical: a merge of sorted rows
    if full.nnz != 2 * half.nnz - int(np.count_nonzero(diagonal)):
        return None  # a position in both orientations: they overlapped in the sum
    # the diagonal was added twice: halve it (exact) at its place in every row
    where = (full.indptr[:-1] + lower + above)[diagonal]
    full.data[where] *= 0.5
    if not np.isfinite(full.data[where]).all():  # a diagonal near the float limit overflowed
        return None
    del n
    return full


def _row_counts(half: sp.csr_matrix) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per row ``r`` of ``half``: entries left of the diagonal, entries above the diagonal in
    column ``r``, and whether ``(r, r)`` is stored (so that in ``half + half^T`` the diagonal
    of row ``r`` comes after the first two counts)."""
    n = half.shape[0]
    indptr, indices = half.indptr, half.indices
    lower = np.zeros(n, dtype=np.int64)
    above = np.zeros(n, dtype=np.int64)
    diagonal = np.zeros(n, dtype=bool)
    rows_per_block = max(1, _ROW_BLOCK * n // max(half.nnz, 1))
    for r0 in range(0, n, rows_per_block):
        r1 = min(n, r0 + rows_per_block)
        cols = indices[indptr[r0] : indptr[r1]]
        row = np.repeat(np.arange(r0, r1, dtype=np.int32), np.diff(indptr[r0 : r1 + 1]))
        lower[r0:r1] = np.bincount(row[cols < row] - r0, minlength=r1 - r0)
        above += np.bincount(cols[cols > row], minlength=n)
        diagonal[row[cols == row]] = True
    return lower, above, diagonal


def _sorted_count(rows: np.ndarray, cols: np.ndarray, upper: bool) -> int | None:
    """Entries left after merging mirror pairs, when the positions ``(lo, hi)`` (``upper``) or
    ``(hi, lo)`` never decrease; None otherwise."""
    repeats = 0
    for start in range(0, rows.size, _BLOCK):
        first, second, _ = _window(rows, cols, start, upper, 1, 0)
        same = first[1:] == first[:-1]
        if not np.all((first[1:] > first[:-1]) | (same & (second[1:] >= second[:-1]))):
            return None
        repeats += int(np.count_nonzero(same & (second[1:] == second[:-1])))
    return rows.size - repeats


def _window(
    rows: np.ndarray, cols: np.ndarray, start: int, upper: bool, before: int, after: int
) -> tuple[np.ndarray, np.ndarray, int]:
    """(first, second) of entries ``start - before .. start + _BLOCK + after`` (clipped) and
    the offset of entry ``start`` in them."""
    a = max(start - before, 0)
    r = rows[a : start + _BLOCK + after]
    c = cols[a : start + _BLOCK + after]
    lo, hi = np.minimum(r, c), np.maximum(r, c)
    return (lo, hi, start - a) if upper else (hi, lo, start - a)


def _sorted_half(
    rows: np.ndarray,
    cols: np.ndarray,
    values: np.ndarray,
    n: int,
    limit: float,
    base: int,
    upper: bool,
    kept: int,
) -> sp.csr_matrix | None:
    """The CSR triangle of sorted entries (:func:`_sorted_count`), mirror pairs merged."""
    square = kept < rows.size  # some position twice: both triangles are stored
    indices = np.empty(kept, dtype=np.int32)
    data = np.empty(kept)
    counts = np.zeros(n, dtype=np.int64)
    at = 0
    for start in range(0, rows.size, _BLOCK):
        first, second, k = _window(rows, cols, start, upper, 2, 1)
        stop = min(start + _BLOCK, rows.size)
        size = stop - start
        repeat = np.zeros(first.size, dtype=bool)  # repeat[i]: entry i repeats entry i - 1
        repeat[1:] = (first[1:] == first[:-1]) & (second[1:] == second[:-1])
        if start == 0:
            repeat[0] = False
        v = values[start - k : start - k + first.size]
        mine = slice(k, k + size)
        own = repeat[mine]
        if square:
            r = rows[start - k : start - k + first.size]
            c = cols[start - k : start - k + first.size]
            flip = r > c
            twice = np.flatnonzero(own) + k
            if np.any(repeat[twice - 1]) or np.any(flip[twice] == flip[twice - 1]):
                return None  # a position three times, or twice in one orientation
            if np.any(np.abs(v[twice] - v[twice - 1]) > limit):
                return None
            follows = np.zeros(size, dtype=bool)  # the next entry is the mirror
            follows[: first.size - k - 1] = repeat[k + 1 : k + size + 1][: first.size - k - 1]
            lonely = ~own & ~follows & (first[mine] != second[mine])
            if np.any(np.abs(v[mine][lonely]) > limit):
                return None
            value = v[mine].copy()
            pair = np.flatnonzero(follows)
            value[pair] = 0.5 * (value[pair] + v[k + 1 + pair])  # exact for equal values
        else:
            value = v[mine]
        keep = ~own
        count = int(np.count_nonzero(keep))
        indices[at : at + count] = second[mine][keep]
        data[at : at + count] = value[keep]
        rows_of = first[mine][keep]  # sorted: counted over its own range of rows
        if count:
            low = int(rows_of[0])
            counts[low - base : int(rows_of[-1]) + 1 - base] += np.bincount(rows_of - low)
        at += count
    if base:
        indices -= base
    indptr = np.zeros(n + 1, dtype=np.int32 if kept < 2**31 - 1 else np.int64)
    np.cumsum(counts, out=indptr[1:])
    half = canonical_csr(data, indices, indptr, (n, n))
    half.eliminate_zeros()
    return half
