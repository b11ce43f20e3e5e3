"""Sparse matrix products in extended precision.

For a smooth block ``V`` (static deflections, low modes), ``K V`` is small while the entries of
``K`` are large: in double precision the product loses ~log10(cond K) digits to cancellation.
Computing it in extended precision and rounding the result keeps reduced matrices ``V^T K V``
and solve residuals accurate to working precision, which the exactness of moment matching (e.g.
of the static response) relies on. Extended precision is double-double from the compiled kernel
of :mod:`pymorembs.linalg.double_double` when Numba is installed, else ``numpy.longdouble``
(64-bit mantissa on x86-64).
"""

from __future__ import annotations

import weakref

import numpy as np
import scipy.sparse as sp

from pymorembs.linalg import double_double

_EXTENDED: dict[int, sp.csr_matrix] = {}


def extended(matrix: sp.spmatrix) -> sp.csr_matrix:
    """An extended-precision copy of a sparse matrix, cached while ``matrix`` lives."""
    key = id(matrix)
    copy = _EXTENDED.get(key)
    if copy is None:
        wide = np.clongdouble if np.iscomplexobj(matrix.data) else np.longdouble
        copy = sp.csr_matrix(matrix).astype(wide)
        _EXTENDED[key] = copy
        weakref.finalize(matrix, _EXTENDED.pop, key, None)
    return copy


def wide_dtype(*values: object) -> type:
    """``numpy.clongdouble`` if any value is complex, else ``numpy.longdouble``."""
    return np.clongdouble if any(np.iscomplexobj(v) for v in values) else np.longdouble


def extended_product(matrix: sp.spmatrix | np.ndarray, block: np.ndarray) -> np.ndarray:
    """``matrix @ block`` computed in extended precision, returned in double precision.

    Parameters
    ----------
    matrix : sparse matrix or ndarray, shape (n, n)
    block : ndarray, shape (n, k) or (n,)
    """
    block = np.asarray(block)
    if not sp.issparse(matrix):
        return np.asarray(matrix @ block)
    if double_double.available() and not np.iscomplexobj(matrix.data):
        if np.iscomplexobj(block):
            return (
                double_double.product(matrix, block.real)[0]
                + 1j * (double_double.product(matrix, block.imag)[0])
            )
        return double_double.product(matrix, block)[0]
    product = extended(matrix) @ block.astype(wide_dtype(block, matrix.data))
    return np.asarray(product, dtype=np.result_type(block.dtype, matrix.dtype))


def long_product(matrix: sp.spmatrix, block: np.ndarray) -> np.ndarray:
    """``matrix @ block`` for a real sparse matrix in extended precision, kept as
    ``numpy.longdouble`` (for sums that cancel further, e.g. the mass invariants).

    With Numba the compiled double-double product, ``hi + lo`` rounded to ``longdouble`` (a
    64-bit mantissa: at least as accurate as the ``longdouble`` product it replaces, many times
    faster than SciPy's generic ``longdouble`` kernel); else that product.

    Parameters
    ----------
    matrix : sparse matrix, shape (n, m), real
    block : ndarray, shape (m, k) or (m,), real (``longdouble`` entries must be doubles)
    """
    block = np.asarray(block)
    if double_double.available() and not np.iscomplexobj(matrix.data):
        hi, lo = double_double.product(matrix, np.asarray(block, dtype=float))
        return hi.astype(np.longdouble) + lo.astype(np.longdouble)
    return np.asarray(extended(matrix) @ block.astype(np.longdouble))


def multiply(matrix: sp.spmatrix | np.ndarray, block: np.ndarray) -> np.ndarray:
    """``matrix @ block`` in double precision; for a real sparse matrix on the solver threads
    (:func:`pymorembs.linalg.double_double.multiply`) when Numba is installed.

    Parameters
    ----------
    matrix : sparse matrix or ndarray, shape (n, m)
    block : ndarray, shape (m, k) or (m,), real or complex
    """
    block = np.asarray(block)
    if not (sp.issparse(matrix) and double_double.available()) or np.iscomplexobj(matrix.data):
        return np.asarray(matrix @ block)
    if np.iscomplexobj(block):
        columns = block.reshape(block.shape[0], -1)
        k = columns.shape[1]
        both = double_double.multiply(matrix, np.hstack([columns.real, columns.imag]))
        return (both[:, :k] + 1j * both[:, k:]).reshape((both.shape[0], *block.shape[1:]))
    return double_double.multiply(matrix, block)
