"""Sparse products and residuals in double-double arithmetic (compiled with Numba, optional).

Refined solves and the reduced matrices of SOAGA need ``A X`` or ``B - sum_i c_i A_i X`` to
more digits than double precision holds (:mod:`pymorembs.linalg.products`). ``numpy.longdouble``
(the x87 80-bit format, 64-bit mantissa) does that without any extra package, but SciPy's
sparse product in that type runs on one core only and is several times slower than a double one.

Here every term is computed exactly as an unevaluated sum ``hi + lo`` of two doubles
(error-free transformations: Dekker's product split at 2^27 + 1, Knuth's two-sum), row by row,
and the row sums are carried in double-double: the product of a double matrix with a double
block is as accurate as if it had been summed in twice the working precision (relative to the
terms ~1e-30 instead of ~1e-19 for ``longdouble``). The kernel is compiled by
Numba (a dependency of pymorembs) and runs on the PARDISO threads
(:func:`~pymorembs.linalg.backends.solver_threads`) from the main thread, on one thread
elsewhere (worker threads; Numba's default threading layer must not be entered twice at once).

The compiled product is faster than SciPy's ``longdouble`` one and agrees with it to the
``longdouble`` rounding (measurements: ``bench/RESULTS.md``).

The same compiled loop in plain double precision (:func:`multiply`, terms added in SciPy's
order, so the result is SciPy's to the bit) runs the hot ``M X`` products and residual checks of
the Krylov bases on the solver threads, where SciPy's CSR product uses one.

Without Numba, or with ``PYMOREMBS_EXTENDED=longdouble``, :func:`available` is False and the
callers use SciPy and ``longdouble``.
"""

from __future__ import annotations

import os
import threading
from collections.abc import Sequence
from functools import cache

import numpy as np
import scipy.sparse as sp

#: Environment variable: ``longdouble`` forces the ``numpy.longdouble`` products, ``auto`` (the
#: default) uses the compiled double-double kernel when Numba is installed.
EXTENDED_ENV = "PYMOREMBS_EXTENDED"


def available() -> bool:
    """The compiled kernel can be used (Numba importable, not switched off)."""
    if os.environ.get(EXTENDED_ENV, "auto").strip().lower() == "longdouble":
        return False
    return _kernels() is not None


@cache
def _kernels():
    """The module of compiled kernels, or None without Numba."""
    try:
        from pymorembs.linalg import compiled_kernels
    except ImportError:
        return None
    return compiled_kernels


def product(matrix: sp.spmatrix, block: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``matrix @ block`` as a double-double ``(hi, lo)``.

    Each entry is accurate as if summed in twice the working precision (the bound of Ogita, Rump
    & Oishi's Dot2: ``|hi + lo - exact| <= gamma_k^2 sum |a_ij x_j|`` with ``gamma_k ~ k 2^-53``
    for rows of k entries), so ``hi`` is the exact value rounded to double unless the row cancels
    to below ~1e-16 of its terms.

    Parameters
    ----------
    matrix : sparse matrix, shape (n, m), real
    block : ndarray, shape (m, k) or (m,), real

    Returns
    -------
    hi, lo : ndarray, shape (n, k) or (n,)
    """
    csr, columns, shape = _operands(matrix, block)
    hi = np.empty((csr.shape[0], columns.shape[1]))
    lo = np.zeros_like(hi)
    kernels = _kernels()
    kernel = kernels.product_parallel if _parallel() else kernels.product_serial
    if hi.size:
        _with_threads(kernel, csr.indptr, csr.indices, csr.data, columns, hi, lo)
    return hi.reshape(shape), lo.reshape(shape)


def multiply(matrix: sp.spmatrix, block: np.ndarray) -> np.ndarray:
    """``matrix @ block`` in double precision on the solver threads (SciPy's order of terms).

    Parameters
    ----------
    matrix : sparse matrix, shape (n, m), real
    block : ndarray, shape (m, k) or (m,), real

    Returns
    -------
    ndarray, shape (n, k) or (n,)
    """
    csr, columns, shape = _operands(matrix, block)
    out = np.zeros((csr.shape[0], columns.shape[1]))
    kernels = _kernels()
    kernel = kernels.multiply_parallel if _parallel() else kernels.multiply_serial
    if out.size:
        _with_threads(kernel, csr.indptr, csr.indices, csr.data, columns, out)
    return out.reshape(shape)


def _operands(
    matrix: sp.spmatrix, block: np.ndarray
) -> tuple[sp.csr_matrix, np.ndarray, tuple[int, ...]]:
    """Real CSR matrix, contiguous 2-D float64 block, and the shape of the result."""
    if _kernels() is None:
        raise RuntimeError("the compiled kernels need Numba (pip install numba)")
    csr = _canonical(matrix)
    x = np.asarray(block)
    if x.shape[0] != csr.shape[1]:
        raise ValueError(f"shapes {csr.shape} and {x.shape} do not match")
    columns = np.ascontiguousarray(x.reshape(x.shape[0], -1), dtype=np.float64)
    return csr, columns, (csr.shape[0], *x.shape[1:])


def residual(
    rhs: np.ndarray, terms: Sequence[tuple[complex, sp.spmatrix]], x: np.ndarray
) -> np.ndarray:
    """``rhs - sum_i c_i A_i x`` in double-double, rounded to double.

    Parameters
    ----------
    rhs : ndarray, shape (n, k) or (n,), real or complex
    terms : sequence of (scalar, sparse matrix)
        Real matrices; the scalars may be complex.
    x : ndarray, like ``rhs``

    Returns
    -------
    ndarray, like ``x`` (complex if ``rhs``, ``x`` or a scalar is)
    """
    x2 = x.reshape(x.shape[0], -1)
    k = x2.shape[1]
    complex_x = np.iscomplexobj(x2)
    stacked = np.hstack([x2.real, x2.imag]) if complex_x else x2
    rhs2 = np.asarray(rhs).reshape(rhs.shape[0], -1)
    real_hi, real_lo = rhs2.real.astype(np.float64), np.zeros(rhs2.shape)
    imag_hi = rhs2.imag.astype(np.float64) if np.iscomplexobj(rhs2) else np.zeros(rhs2.shape)
    imag_lo = np.zeros(rhs2.shape)
    any_complex = complex_x or np.iscomplexobj(rhs2)
    for coefficient, matrix in terms:
        p_hi, p_lo = product(matrix, stacked)
        if complex_x:
            parts = ((p_hi[:, :k], p_lo[:, :k]), (p_hi[:, k:], p_lo[:, k:]))
        else:
            parts = ((p_hi, p_lo), None)
        c_re, c_im = float(np.real(coefficient)), float(np.imag(coefficient))
        any_complex = any_complex or c_im != 0.0
        # (c_re + i c_im)(P_re + i P_im), subtracted from the residual
        real_hi, real_lo = _subtract_scaled(real_hi, real_lo, c_re, parts[0])
        imag_hi, imag_lo = _subtract_scaled(imag_hi, imag_lo, c_im, parts[0])
        if parts[1] is not None:
            real_hi, real_lo = _subtract_scaled(real_hi, real_lo, -c_im, parts[1])
            imag_hi, imag_lo = _subtract_scaled(imag_hi, imag_lo, c_re, parts[1])
    result = real_hi + real_lo
    if any_complex:
        result = result + 1j * (imag_hi + imag_lo)
    return result.reshape(x.shape)


def _subtract_scaled(
    hi: np.ndarray, lo: np.ndarray, scale: float, part: tuple[np.ndarray, np.ndarray]
) -> tuple[np.ndarray, np.ndarray]:
    """``(hi + lo) - scale * (p_hi + p_lo)`` in double-double, into ``hi`` and ``lo`` (2-D, own
    arrays): one compiled pass, no temporaries (NumPy's elementwise version made a dozen
    arrays of the block's size per call, half the time of a residual at 300,000 dofs)."""
    if scale != 0.0:
        p_hi, p_lo = part
        _kernels().subtract_scaled(hi, lo, float(scale), p_hi, p_lo)
    return hi, lo


def _canonical(matrix: sp.spmatrix) -> sp.csr_matrix:
    """Real CSR with int32/int64 indices as stored (no copy of a CSR matrix)."""
    csr = matrix if isinstance(matrix, sp.csr_matrix) else sp.csr_matrix(matrix)
    if np.iscomplexobj(csr.data):
        raise ValueError("the double-double product takes real matrices")
    if csr.data.dtype != np.float64:
        csr = csr.astype(np.float64)
    return csr


def _parallel() -> bool:
    """Run on several threads: from the main thread, with more than one solver thread."""
    from pymorembs.linalg.backends import solver_threads

    return threading.current_thread() is threading.main_thread() and solver_threads() > 1


def _with_threads(kernel, *args) -> None:
    """Call ``kernel`` with Numba's thread count set to the solver threads."""
    import numba

    from pymorembs.linalg.backends import solver_threads

    count = max(1, min(solver_threads(), numba.config.NUMBA_NUM_THREADS))
    previous = numba.get_num_threads()
    numba.set_num_threads(count)
    try:
        kernel(*args)
    finally:
        numba.set_num_threads(previous)
