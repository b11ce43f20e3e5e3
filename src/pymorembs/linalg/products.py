"""Sparse matrix products in extended precision.

For a smooth block ``V`` (static deflections, low modes), ``K V`` is small while the entries of
``K`` are large: in double precision the product loses ~log10(cond K) digits to cancellation.
Computing it in ``numpy.longdouble`` (64-bit mantissa on x86-64) and rounding the result keeps the
reduced matrices ``V^T K V`` accurate to working precision, which the exactness of moment matching
(e.g. the static response) relies on.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp


def extended_product(matrix: sp.spmatrix | np.ndarray, block: np.ndarray) -> np.ndarray:
    """``matrix @ block`` computed in extended precision, returned in the block's precision.

    Parameters
    ----------
    matrix : sparse matrix or ndarray, shape (n, n)
    block : ndarray, shape (n, k) or (n,)
    """
    block = np.asarray(block)
    if not sp.issparse(matrix):
        return np.asarray(matrix @ block)
    complex_valued = np.iscomplexobj(block) or np.iscomplexobj(matrix.data)
    wide = np.clongdouble if complex_valued else np.longdouble
    product = sp.csr_matrix(matrix).astype(wide) @ block.astype(wide)
    return np.asarray(product, dtype=np.result_type(block.dtype, matrix.dtype))
