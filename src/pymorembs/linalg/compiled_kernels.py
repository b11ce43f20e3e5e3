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
