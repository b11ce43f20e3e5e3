"""Compiled sparse kernels of :mod:`pymorembs.linalg.double_double` (only imported with Numba)."""

from __future__ import annotations

import numba
import numpy as np

#: Dekker's splitter for IEEE double: 2^27 + 1.
SPLITTER = 134217729.0


@numba.njit(cache=True, nogil=True, inline="always")
def _row(i, indptr, indices, data, x, out_hi, out_lo, s, c):  # pragma: no cover - compiled
    """Row ``i`` of ``A X`` in double-double; ``s``, ``c`` are scratch of length k."""
    k = out_hi.shape[1]
    s[:] = 0.0
    c[:] = 0.0
    for q in range(indptr[i], indptr[i + 1]):
        col = indices[q]
        a = data[q]
        t = SPLITTER * a
        a_hi = t - (t - a)
        a_lo = a - a_hi
        for j in range(k):
            xv = x[col, j]
            t = SPLITTER * xv
            x_hi = t - (t - xv)
            x_lo = xv - x_hi
            p = a * xv  # two-product: p + e = a * xv exactly
            e = ((a_hi * x_hi - p) + a_hi * x_lo + a_lo * x_hi) + a_lo * x_lo
            total = s[j] + p  # two-sum: total + err = s + p exactly
            virtual = total - s[j]
            c[j] += ((s[j] - (total - virtual)) + (p - virtual)) + e
            s[j] = total
    for j in range(k):
        hi = s[j] + c[j]
        out_hi[i, j] = hi
        out_lo[i, j] = c[j] - (hi - s[j])


@numba.njit(cache=True, nogil=True, parallel=True)
def product_parallel(indptr, indices, data, x, out_hi, out_lo):  # pragma: no cover - compiled
    """``A X`` in double-double, rows shared out to Numba's threads."""
    n, k = out_hi.shape
    for i in numba.prange(n):
        _row(i, indptr, indices, data, x, out_hi, out_lo, np.empty(k), np.empty(k))


@numba.njit(cache=True, nogil=True)
def product_serial(indptr, indices, data, x, out_hi, out_lo):  # pragma: no cover - compiled
    """``A X`` in double-double on the calling thread."""
    k = out_hi.shape[1]
    s, c = np.empty(k), np.empty(k)
    for i in range(out_hi.shape[0]):
        _row(i, indptr, indices, data, x, out_hi, out_lo, s, c)


@numba.njit(cache=True, nogil=True)
def subtract_scaled(hi, lo, scale, p_hi, p_lo):  # pragma: no cover - compiled
    """``(hi + lo) -= scale * (p_hi + p_lo)`` in double-double, elementwise and in place, for
    2-D arrays: Dekker's two-product of ``-scale`` and ``p_hi``, Knuth's two-sum, then the
    renormalisation -- the operations of NumPy's vectorised version in the same order."""
    a = -scale
    t = SPLITTER * a
    a_hi = t - (t - a)
    a_lo = a - a_hi
    for i in range(hi.shape[0]):
        for j in range(hi.shape[1]):
            b = p_hi[i, j]
            product = a * b
            t = SPLITTER * b
            b_hi = t - (t - b)
            b_lo = b - b_hi
            error = ((a_hi * b_hi - product) + a_hi * b_lo + a_lo * b_hi) + a_lo * b_lo
            error = error - scale * p_lo[i, j]
            h = hi[i, j]
            total = h + product
            virtual = total - h
            carry = (h - (total - virtual)) + (product - virtual)
            carry = carry + lo[i, j] + error
            new_hi = total + carry
            hi[i, j] = new_hi
            lo[i, j] = carry - (new_hi - total)


@numba.njit(cache=True, nogil=True, inline="always")
def _plain_row(i, indptr, indices, data, x, out):  # pragma: no cover - compiled
    """Row ``i`` of ``A X`` in double precision, terms added in stored order (as SciPy)."""
    k = out.shape[1]
    for j in range(k):
        out[i, j] = 0.0
    for q in range(indptr[i], indptr[i + 1]):
        col = indices[q]
        a = data[q]
        for j in range(k):
            out[i, j] += a * x[col, j]


@numba.njit(cache=True, nogil=True, parallel=True)
def multiply_parallel(indptr, indices, data, x, out):  # pragma: no cover - compiled
    """``A X`` in double precision, rows shared out to Numba's threads."""
    for i in numba.prange(out.shape[0]):
        _plain_row(i, indptr, indices, data, x, out)


@numba.njit(cache=True, nogil=True)
def multiply_serial(indptr, indices, data, x, out):  # pragma: no cover - compiled
    """``A X`` in double precision on the calling thread."""
    for i in range(out.shape[0]):
        _plain_row(i, indptr, indices, data, x, out)


@numba.njit(cache=True, nogil=True)
def subset_positions(indptr, indices, sub_indptr, sub_indices, out):  # pragma: no cover - compiled
    """Where each stored entry of the canonical CSR pattern ``sub`` sits in the canonical CSR
    pattern ``(indptr, indices)`` (into ``out``); False as soon as one is not there."""
    for i in range(indptr.size - 1):
        q, end = indptr[i], indptr[i + 1]
        for p in range(sub_indptr[i], sub_indptr[i + 1]):
            column = sub_indices[p]
            while q < end and indices[q] < column:
                q += 1
            if q == end or indices[q] != column:
                return False
            out[p] = q
            q += 1
    return True


@numba.njit(cache=True, nogil=True)
def scaled_add(out, coefficient, values):  # pragma: no cover - compiled
    """``out += coefficient * values`` elementwise in one pass (NumPy's rounding: the product
    is rounded, then added)."""
    for i in range(out.size):
        out[i] += coefficient * values[i]


@numba.njit(cache=True, nogil=True)
def upper_positions(indptr, indices, keep, upper_indptr):  # pragma: no cover - compiled
    """The entries ``j >= i`` of a canonical CSR pattern: their positions into ``keep`` (length
    at least their number), the row starts of the upper triangle into ``upper_indptr`` (n + 1);
    returns (their number, whether every diagonal entry is stored)."""
    count = 0
    diagonals = 0
    upper_indptr[0] = 0
    for i in range(indptr.size - 1):
        for q in range(indptr[i], indptr[i + 1]):
            if indices[q] >= i:
                if indices[q] == i:
                    diagonals += 1
                keep[count] = q
                count += 1
        upper_indptr[i + 1] = count
    return count, diagonals == indptr.size - 1


@numba.njit(cache=True, nogil=True)
def rows_gap(indptr, indices, data, first, last):  # pragma: no cover - compiled
    """``max |a_ij - a_ji|`` over the entries ``(i, j)`` of rows ``first .. last - 1``.

    Entry ``(i, j)`` is compared with ``(j, i)`` (or zero where there is none). Row ``j`` is
    searched with a cursor of its own: the rows ``i`` that look into it come in increasing
    order, and so do the columns ``i`` sought there, so each cursor only moves forward and the
    whole comparison is one pass over the entries.
    """
    cursor = indptr[:-1].copy()
    gap = 0.0
    for i in range(first, last):
        for q in range(indptr[i], indptr[i + 1]):
            j = indices[q]
            p = cursor[j]
            end = indptr[j + 1]
            while p < end and indices[p] < i:
                p += 1
            cursor[j] = p
            if p < end and indices[p] == i:
                difference = abs(data[q] - data[p])
            else:
                difference = abs(data[q])
            if difference != difference:
                return difference
            if difference > gap:
                gap = difference
    return gap
