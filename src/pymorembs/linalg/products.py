"""Sparse matrix products in extended precision.

For a smooth block ``V`` (static deflections, low modes), ``K V`` is small while the entries of
``K`` are large: in double precision the product loses ~log10(cond K) digits to cancellation.
Computing it in ``numpy.longdouble`` (64-bit mantissa on x86-64) and rounding the result keeps
reduced matrices ``V^T K V`` and solve residuals accurate to working precision, which the
exactness of moment matching (e.g. of the static response) relies on.
"""

from __future__ import annotations

import weakref

import numpy as np
import scipy.sparse as sp

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
    product = extended(matrix) @ block.astype(wide_dtype(block, matrix.data))
    return np.asarray(product, dtype=np.result_type(block.dtype, matrix.dtype))
