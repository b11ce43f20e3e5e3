"""Fast assembly of a symmetric matrix from the entries of one triangle (or of both, sorted).

FE programs write a symmetric matrix as one triangle: sorted in row-major order in their own
equation order (Abaqus ``FORMAT=MATRIX INPUT``, whose equation order is not the order of the
node labels), or as both triangles with each off-diagonal entry followed by its mirror
(Abaqus/CAE ``FORMAT=COORDINATE``). :func:`assemble_symmetric_triangle` builds the full CSR
matrix of such entries in SciPy's compiled code (a counting sort by rows, or no sort at all when
the entries are sorted already) instead of sorting every entry by its position in NumPy, and
the full matrix is the triangle plus its transpose.

It returns exactly the matrix that :func:`pymorembs.io.formats.assemble_symmetric` returns for
the same entries (same pattern, same values), or None whenever that function would raise an
error or the entries are in none of these layouts; the caller then uses ``assemble_symmetric``,
which also names the offending lines.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from pymorembs.io.fast_text import csr_from_sorted_coo

__all__ = ["assemble_symmetric_triangle"]

#: Entries compared at a time (temporary arrays stay small).
_BLOCK = 1 << 20


def assemble_symmetric_triangle(
    rows: np.ndarray, cols: np.ndarray, values: np.ndarray, n: int, tolerance: float
) -> sp.csr_matrix | None:
    """The full symmetric ``n x n`` matrix of the entries of a triangle, or None.

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
        Equation indices (from 0, below ``n``) in file order; int32 saves memory.
    values : ndarray of float, shape (nnz,)
    n : int
        Matrix size.
    tolerance : float
        Relative symmetry tolerance (``SYMMETRY_TOLERANCE`` of the Matrix Market reader).

    Returns
    -------
    scipy.sparse.csr_matrix or None
        Canonical, exactly symmetric, without explicit zeros; None for no entries, a NaN or
        infinity, a position repeated otherwise than as a sorted mirror pair, asymmetric mirrors
        or a lone entry of a square file (the caller's general assembly decides and names the
        line).
    """
    nnz = values.size
    if nnz == 0 or n <= 0 or n >= 2**31 - 1:
        return None
    if not all(np.isfinite(values[s : s + _BLOCK]).all() for s in range(0, nnz, _BLOCK)):
        return None
    lo = np.minimum(rows, cols).astype(np.int32, copy=False)
    hi = np.maximum(rows, cols).astype(np.int32, copy=False)
    if _nondecreasing(lo):  # (lo, hi) by rows: the upper triangle
        triangle = _sorted_triangle(rows, cols, values, lo, hi, n, tolerance)
        upper = True
    elif _nondecreasing(hi):  # (hi, lo) by rows: the lower triangle
        triangle = _sorted_triangle(rows, cols, values, hi, lo, n, tolerance)
        upper = False
    else:  # one triangle in another order: a counting sort by rows (SciPy's coo -> csr)
        triangle = sp.csr_matrix((values, (hi, lo)), shape=(n, n))  # sums repeated positions
        upper = False
        if triangle.nnz != nnz:  # a position given twice: the general assembly decides
            return None
    del lo, hi
    if triangle is None:
        return None
    triangle.eliminate_zeros()
    if triangle.nnz == 0:
        return None
    full = sp.csr_matrix(triangle + triangle.T)  # canonical: a merge of sorted rows
    # the diagonal was added twice: halve it (exact) at its place in every row
    indptr = triangle.indptr
    count = np.diff(indptr)
    last = np.maximum(indptr[1:] - 1, 0)
    nonempty = count > 0
    if upper:  # rows hold (r, c >= r): the diagonal is the first entry of a row
        has_diagonal = nonempty & (triangle.indices[np.minimum(indptr[:-1], last)] == np.arange(n))
        before = np.bincount(triangle.indices, minlength=n)[:n] - has_diagonal
    else:  # rows hold (r, c <= r): the diagonal is the last entry of a row
        has_diagonal = nonempty & (triangle.indices[last] == np.arange(n))
        before = count - has_diagonal
    where = (full.indptr[:-1] + before)[has_diagonal]
    full.data[where] *= 0.5
    if not np.isfinite(full.data[where]).all():  # a diagonal near the float limit overflowed
        return None
    return full


def _sorted_triangle(
    rows: np.ndarray,
    cols: np.ndarray,
    values: np.ndarray,
    first: np.ndarray,
    second: np.ndarray,
    n: int,
    tolerance: float,
) -> sp.csr_matrix | None:
    """The CSR triangle of entries sorted by (first, second), mirror pairs merged, or None."""
    repeat = _repeats(first, second)  # None: not sorted by (first, second)
    if repeat is None:
        return None
    if repeat.any():
        data = _merge_mirrors(rows, cols, values, first, second, repeat, tolerance)
        if data is None:
            return None
        keep = ~repeat
        first, second = first[keep], second[keep]
    else:
        data = np.ascontiguousarray(values)
    return csr_from_sorted_coo(first, second, data, n)


def _nondecreasing(a: np.ndarray) -> bool:
    for start in range(0, a.size - 1, _BLOCK):
        block = a[start : start + _BLOCK + 1]
        if not np.all(block[1:] >= block[:-1]):
            return False
    return True


def _repeats(first: np.ndarray, second: np.ndarray) -> np.ndarray | None:
    """``repeat[k]``: entry ``k`` has the position of entry ``k - 1``; None if out of order."""
    repeat = np.zeros(first.size, dtype=bool)
    for start in range(0, first.size - 1, _BLOCK):
        f = first[start : start + _BLOCK + 1]
        s = second[start : start + _BLOCK + 1]
        same = f[1:] == f[:-1]
        if not np.all((f[1:] > f[:-1]) | (same & (s[1:] >= s[:-1]))):
            return None
        np.logical_and(same, s[1:] == s[:-1], out=repeat[start + 1 : start + f.size])
    return repeat


def _merge_mirrors(
    rows: np.ndarray,
    cols: np.ndarray,
    values: np.ndarray,
    first: np.ndarray,
    second: np.ndarray,
    repeat: np.ndarray,
    tolerance: float,
) -> np.ndarray | None:
    """Values of the first entry of every position (the mean of a mirror pair), or None."""
    at = np.flatnonzero(repeat)  # entry at[i] repeats entry at[i] - 1
    if np.any(np.diff(at) == 1):  # a position three times
        return None
    mirrored = (rows[at] > cols[at]) != (rows[at - 1] > cols[at - 1])
    if not mirrored.all():  # the same orientation twice (or a diagonal twice)
        return None
    limit = tolerance * max(
        float(np.abs(values[s : s + _BLOCK]).max()) for s in range(0, values.size, _BLOCK)
    )
    a, b = values[at - 1], values[at]
    if not np.all(np.abs(a - b) <= limit):
        return None
    paired = repeat.copy()
    paired[at - 1] = True
    lonely = ~paired & (first != second)
    del paired
    if np.any(np.abs(values[lonely]) > limit):
        return None
    del lonely
    data = values[~repeat]
    data[at - np.arange(1, at.size + 1)] = 0.5 * (a + b)  # exact for equal values
    return data
