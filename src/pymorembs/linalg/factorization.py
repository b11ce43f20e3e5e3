"""Sparse direct solves with one factorization reused for many right-hand sides.

Every large solve in pymorembs goes through :class:`Factorization`: modal shift-invert, Krylov
moments at an expansion point, frequency responses. The factorization is computed once per
matrix (per shift) and kept while the shift stays the same; solves take blocks of right-hand
sides.

FE stiffness matrices are ill-conditioned (beam models: cond(K) ~ 1e11 and more; the paper's
light stiff beams far worse), so a plain LU solve has a forward error of ~cond(K) * 1e-16, and so
does merely *forming* a shifted matrix ``K - omega^2 M`` in double precision, which rounds the
stiffness entries. Checked solves therefore use mixed-precision iterative refinement: the LU
factors of the rounded matrix serve as a preconditioner, and the residual is computed from the
exact operator -- the sum of its unrounded terms ``sum_i c_i A_i`` -- in extended precision
(``numpy.longdouble``), until the correction stops decreasing. This makes, e.g., the static and
low-frequency response of the full model accurate to ~1e-12 instead of ~1e-8.

Refinement only where it is needed: the first solve with a factorization is always refined, and
the size of its first correction measures the forward error of a plain solve with these factors
(about ``cond(A) * 1e-16`` for that kind of right-hand side). When it is below
:data:`PLAIN_ENOUGH` (responses) or :data:`BASIS_PLAIN_ENOUGH` (solves that only build a
subspace), later solves with the same factorization skip the extended-precision refinement
and only get a residual check in working precision (a double sparse product, a seventh of an
extended one) that raises on a backward error above :data:`FAIL_ABOVE`. Every
refinement stops after its first correction when that correction is below ``1e-7`` relative:
the error then contracts to its square, below :data:`REFINE_TOL`, without a second residual to
confirm it. On the rack models (plain forward error 6e-10 to 1e-8) a refined solve therefore
costs one extended residual and one extra solve; on the rack-solid with the paper's light stiff
beams in the Buckens frame (plain error 1.2e-4) refinement takes its full course.
``refine="always"`` refines every solve.

Shifted matrices ``sum_i c_i A_i`` are formed on a sparsity pattern merged once per set of terms
(:mod:`pymorembs.linalg.pattern`), in double for the factorization and in extended precision for
the residuals.

The factorization itself comes from :mod:`pymorembs.linalg.backends` (MKL PARDISO when it is
installed, else SciPy's SuperLU; ``PYMOREMBS_SOLVER`` overrides). The operator is factorized as
symmetric -- real symmetric indefinite ``L D L^T`` for real coefficients, complex symmetric for
complex ones -- when all its terms are symmetric matrices, as FE matrices are. PARDISO's own
refinement works from the rounded matrix in double precision and cannot replace the one here:
on rack-beams (n = 3,942) a plain PARDISO solve differs from the refined one by 3e-9 (SuperLU:
5e-9), the refined solutions of the two backends agree to 1.4e-12. The refinement costs about
two extended-precision residuals per solve, each several times a double sparse product.
"""

from __future__ import annotations

import weakref
from collections.abc import Sequence

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from pymorembs.errors import NumericalError
from pymorembs.linalg import double_double
from pymorembs.linalg.backends import SUPERLU_OPTIONS, SparseFactor, factorize
from pymorembs.linalg.pattern import infinity_norm, sum_pattern
from pymorembs.linalg.products import extended, multiply, wide_dtype
from pymorembs.linalg.shared_factors import active_shared_factors

#: Refinement stops when the correction is below this, relative to the solution.
REFINE_TOL = 1e-12
#: At most this many refinement steps.
MAX_REFINEMENTS = 4
#: Relative backward error above which a solve is reported as failed.
FAIL_ABOVE = 1e-6
#: Estimated forward error of a plain solve up to which a factorization's later solves are not
#: refined (``refine="auto"``) when the solutions are responses that are compared or reported
#: (frequency responses, time integration, static modes): the deflation tolerance of the Krylov
#: bases (1e-10), so that a reference response is accurate to about that.
PLAIN_ENOUGH = 1e-10
#: The same for solves that only build a subspace (Krylov and SOAGA moments, ``plain_enough=``
#: of :class:`Factorization`). A projection needs the span, not the digits of each vector: on
#: rack-solid (n = 9,759, plain error 4e-9; inputs at node 1, outputs at nodes 1 and 1500) the
#: Krylov model from plain moments has the same order (39) and max epsilon (4.90e-11) as the
#: one from refined moments, at 1.0 s instead of 1.7 s. Directions below the solve error are
#: then no longer resolved: rack-beams' basis (0/500/1000 Hz, 6/5/5 moments) keeps two
#: directions of singular value ~4e-8 that refined moments deflate (order 37 instead of 35,
#: max epsilon 2.38e-10 both, highest eigenfrequency 234 kHz instead of 930 kHz). So it applies
#: from :data:`BASIS_PLAIN_MIN_ORDER` dofs on, where the refinement is worth its time: at 35,679
#: dofs it took 1.7 s of a 4.1 s Krylov reduction (16 extended residuals and 16 extra solves).
BASIS_PLAIN_ENOUGH = 1e-7
#: Smallest order at which subspace-building solves use :data:`BASIS_PLAIN_ENOUGH`
#: (:func:`basis_plain_enough`): below it refinement costs well under a second, and the tighter
#: basis of refined moments is kept.
BASIS_PLAIN_MIN_ORDER = 20_000


def basis_plain_enough(order: int) -> float:
    """The ``plain_enough`` of subspace-building solves for a system of this order."""
    return BASIS_PLAIN_ENOUGH if order >= BASIS_PLAIN_MIN_ORDER else PLAIN_ENOUGH


Terms = Sequence[tuple[complex, sp.spmatrix]]

#: Relative asymmetry ``max|A - A^T| / max|A|`` up to which a term counts as symmetric.
SYMMETRY_TOL = 1e-14

__all__ = [
    "BASIS_PLAIN_ENOUGH",
    "BASIS_PLAIN_MIN_ORDER",
    "PLAIN_ENOUGH",
    "SUPERLU_OPTIONS",
    "Factorization",
    "basis_plain_enough",
    "combine",
    "is_symmetric",
    "known_symmetric",
]

_SYMMETRIC: dict[int, bool] = {}


def _remember_symmetry(matrix: sp.spmatrix, symmetric: bool) -> None:
    """Keep whether ``matrix`` is symmetric while it lives (by identity)."""
    key = id(matrix)
    if key not in _SYMMETRIC:
        _SYMMETRIC[key] = symmetric
        weakref.finalize(matrix, _SYMMETRIC.pop, key, None)


def known_symmetric(matrix: sp.spmatrix) -> sp.spmatrix:
    """Record that ``matrix`` is exactly symmetric (it was made so, e.g. ``(A + A^T) / 2``), so
    that :func:`is_symmetric` need not compare it with its transpose; returns ``matrix``."""
    _remember_symmetry(matrix, True)
    return matrix


def is_symmetric(matrix: sp.spmatrix) -> bool:
    """``A = A^T`` up to :data:`SYMMETRY_TOL`; cached while ``matrix`` lives: O(nnz) once, and
    nothing for a matrix made symmetric (:func:`known_symmetric`)."""
    key = id(matrix)
    known = _SYMMETRIC.get(key)
    if known is None:
        a = sp.csr_matrix(matrix)
        if a.shape[0] != a.shape[1]:
            known = False
        else:
            largest = float(np.max(np.abs(a.data))) if a.nnz else 0.0
            gap = _compiled_gap(a) if a.nnz and a.dtype == np.float64 else None
            if gap is None:
                difference = abs(a - a.T)
                gap = difference.max() if difference.nnz else 0.0
            known = gap <= SYMMETRY_TOL * largest
        _remember_symmetry(matrix, bool(known))
    return known


def _compiled_gap(a: sp.csr_matrix) -> float | None:
    """``max |A - A^T|`` in one compiled pass, no ``A - A^T`` formed (at 300,000 dofs it took
    gigabytes of temporaries): :func:`~pymorembs.linalg.compiled_kernels.rows_gap`, the kernel
    of the readers' :func:`~pymorembs.io.fast_text.transpose_gap`, on the canonical form of
    ``a``; None without Numba."""
    if not double_double.available():  # Numba is not installed
        return None
    from pymorembs.linalg import compiled_kernels

    if not a.has_canonical_format:
        a = a.copy()
        a.sum_duplicates()
    return float(compiled_kernels.rows_gap(a.indptr, a.indices, a.data, 0, a.shape[0]))


def combine(terms: Terms, dtype: type | None = None) -> sp.csr_matrix:
    """``sum_i c_i A_i`` in working precision (rounded), or in ``dtype``; canonical CSR.

    Sparse terms are added on their merged pattern (:func:`~pymorembs.linalg.pattern.sum_pattern`,
    cached), so all combinations of the same matrices share one pattern.
    """
    terms = [(c, m) for c, m in terms if c != 0]
    if len(terms) == 1 and terms[0][0] == 1 and dtype is None and sp.issparse(terms[0][1]):
        single = terms[0][1]
        if isinstance(single, sp.csr_matrix) and single.has_canonical_format:
            return single  # its own index arrays: the pattern of its shifts (sum_pattern)
        single = sp.csr_matrix(single)
        if not single.has_canonical_format:
            single = single.copy()
            single.sum_duplicates()
        return single
    if terms and all(sp.issparse(m) for _, m in terms):
        pattern = sum_pattern([m for _, m in terms])
        return pattern.combine([c for c, _ in terms], dtype)
    total = None
    for coefficient, matrix in terms:
        if coefficient == 0:
            continue
        part = matrix if coefficient == 1 else coefficient * matrix
        total = part if total is None else total + part
    return sp.csr_matrix(total, dtype=dtype)


class Factorization:
    """Sparse factorization of ``A = sum_i c_i A_i``, with refined solves.

    Parameters
    ----------
    terms : sequence of (scalar, sparse matrix), or a sparse matrix
        The operator as a sum of scaled sparse matrices, e.g.
        ``[(1, K), (-omega**2, M)]``; a single matrix means ``[(1, matrix)]``.
    label : str
        What the matrix is, for error messages (e.g. ``"K(s) at 500 Hz"``).
    check : bool
        Refine solves and check their backward error.
    backend : {"superlu", "pardiso"}, optional
        Default :func:`pymorembs.linalg.backends.default_backend`.
    refine : {"auto", "always"}
        ``"auto"``: refine the first solve, and later ones only if the first showed a plain
        solve error above ``plain_enough`` (module docstring); ``"always"``: every solve.
    plain_enough : float
        Default :data:`PLAIN_ENOUGH`; :data:`BASIS_PLAIN_ENOUGH` for solves that only build a
        subspace.
    share : bool
        Take and keep the factor in an open
        :func:`~pymorembs.linalg.shared_factors.shared_factorizations` cache (False: a factor
        used once, e.g. one frequency of a sweep).
    share_analysis : bool
        PARDISO: share the analysis of the sparsity pattern with the other shifts (default); or
        an own handle, whose solves run on one thread (:func:`~pymorembs.linalg.backends.
        factorize`): for one factorization with many one-vector solves.

    Attributes
    ----------
    factor : SparseFactor
        The backend's factorization (``factor.backend``, ``factor.seconds`` in s,
        ``factor.nnz_factor``).
    symmetric : bool
        Factorized as (real or complex) symmetric: all terms are symmetric.
    plain_error : float or None
        Estimated relative forward error of a plain (unrefined) solve, from the first
        correction of the refined solves so far (largest); None before the first solve.
    extended_residuals : int
        Extended-precision residuals computed so far (for benchmarks).
    reused : bool
        The factor was taken from an open
        :func:`~pymorembs.linalg.shared_factors.shared_factorizations` cache (the same terms
        were factorized before), not made anew.
    """

    def __init__(
        self,
        terms: Terms | sp.spmatrix,
        label: str = "matrix",
        check: bool = True,
        backend: str | None = None,
        refine: str = "auto",
        plain_enough: float = PLAIN_ENOUGH,
        share: bool = True,
        share_analysis: bool = True,
    ):
        if refine not in ("auto", "always"):
            raise ValueError(f"refine must be 'auto' or 'always', got {refine!r}")
        self.plain_enough = float(plain_enough)
        if sp.issparse(terms):
            terms = [(1.0, terms)]
        self.terms = [(c, m) for c, m in terms if c != 0]
        self.matrix = combine(self.terms)
        self.label = label
        self.check = check
        self.refine = refine
        self.plain_error: float | None = None
        self.extended_residuals = 0
        self.shape = self.matrix.shape
        self.dtype = self.matrix.dtype
        self.symmetric = all(is_symmetric(matrix) for _, matrix in self.terms)
        # within a job's shared_factorizations block: the factor of the same terms made before
        shared = active_shared_factors() if share else None
        key = shared.key(self.terms, self.symmetric, backend) if shared is not None else None
        found = shared.get(key) if shared is not None else None
        self.reused = found is not None
        try:
            self.factor: SparseFactor = (
                found
                if found is not None
                else factorize(self.matrix, self.symmetric, backend, share_analysis)
            )
        except NumericalError as exc:  # one line that names the matrix
            text = str(exc)
            named = text.replace("the matrix", label, 1)
            raise NumericalError(named if named != text else f"{label}: {text}") from None
        if shared is not None and found is None:
            shared.put(key, self.terms, self.factor)
        # an upper bound of ||A||_inf (for the backward error), from the cached norms of the terms
        self._norm = sum(abs(c) * _norm_of(m) for c, m in self.terms) or 1.0

    def solve(self, rhs: np.ndarray) -> np.ndarray:
        """Solve ``A X = rhs`` for a vector (n,) or a block (n, k), real or complex."""
        rhs = np.asarray(rhs)
        if np.iscomplexobj(rhs) and not np.iscomplexobj(self.matrix.data):
            # real and imaginary parts as one real block: one solve per refinement step
            block = rhs.reshape(rhs.shape[0], -1)
            k = block.shape[1]
            both = self.solve(np.column_stack([block.real, block.imag]))
            return (both[:, :k] + 1j * both[:, k:]).reshape(rhs.shape)
        x = self.factor.solve(rhs)
        if not self.check:
            return x
        if self._plain_is_enough():
            residual = rhs - multiply(self.matrix, x.reshape(x.shape[0], -1)).reshape(x.shape)
            self._check_backward(residual, x, rhs)
            return x
        previous = np.inf
        for step in range(MAX_REFINEMENTS):
            residual = self._residual(rhs, x)
            self._check_backward(residual, x, rhs)
            correction = self.factor.solve(residual)
            x = x + correction
            sizes = _column_norms(correction)
            if step == 0:  # the forward error of the plain solve, column by column
                first = float(np.max(sizes / np.maximum(_column_norms(x), np.finfo(float).tiny)))
                self.plain_error = max(self.plain_error or 0.0, first)
                # refinement contracts the error by about ``first`` per step: after this one it
                # is ~first**2, below the tolerance without another residual to confirm it
                if first * first <= 0.01 * REFINE_TOL:
                    break
            size = float(np.sqrt(np.sum(sizes**2)))
            # every column converged, or stagnating at the rounding level of x itself
            if np.all(sizes <= REFINE_TOL * _column_norms(x)) or size > 0.5 * previous:
                break
            previous = size
        return x

    def _plain_is_enough(self) -> bool:
        """Whether solves may skip refinement (``refine="auto"``, module docstring)."""
        return (
            self.refine == "auto"
            and self.plain_error is not None
            and self.plain_error <= self.plain_enough
        )

    def _check_backward(self, residual: np.ndarray, x: np.ndarray, rhs: np.ndarray) -> None:
        """Raise :class:`NumericalError` if the backward error exceeds :data:`FAIL_ABOVE`."""
        block = (a.reshape(a.shape[0], -1) for a in (residual, x, rhs))
        backward = self._relative(*block)
        if not np.isfinite(backward) or backward > FAIL_ABOVE:
            raise NumericalError(
                f"solve with {self.label} is inaccurate (relative residual {backward:.1e}); "
                "the matrix is singular or nearly so"
            )

    def _residual(self, rhs: np.ndarray, x: np.ndarray) -> np.ndarray:
        """``rhs - sum_i c_i A_i x`` in extended precision, rounded to working precision.

        Double-double (:mod:`pymorembs.linalg.double_double`) when Numba is installed and the
        matrices are real, else ``numpy.longdouble``.

        The matrices are real (K, M, D), so the real and imaginary parts of ``x`` are multiplied
        as one real block; only the scalar coefficients are complex.
        """
        self.extended_residuals += 1
        if double_double.available() and not any(np.iscomplexobj(m.data) for _, m in self.terms):
            # compiled double-double: one pass per term, no extended copies of the matrices
            return double_double.residual(rhs, self.terms, x).astype(x.dtype, copy=False)
        complex_x = np.iscomplexobj(x)
        columns = x.shape[1] if x.ndim == 2 else 1
        parts = np.column_stack([x.real, x.imag]) if complex_x else x.reshape(x.shape[0], -1)
        parts = parts.astype(np.longdouble)
        residual = rhs.reshape(rhs.shape[0], -1).astype(wide_dtype(x, rhs))
        # the first residual of a factorization (often its only one) multiplies the terms one
        # by one -- their extended copies are cached for all shifts -- later ones use the sum
        combined = self._combined_extended() if self.extended_residuals > 1 else None
        if combined is not None:  # one extended product instead of one per term
            product = combined @ parts
            if complex_x:
                product = product[:, :columns] + 1j * product[:, columns:]
            residual = residual - product
            return np.asarray(residual, dtype=x.dtype).reshape(x.shape)
        for coefficient, matrix in self.terms:
            if np.iscomplexobj(matrix.data):  # general case, slower
                product = extended(matrix) @ x.reshape(x.shape[0], -1).astype(np.clongdouble)
            else:
                product = extended(matrix) @ parts
                if complex_x:
                    product = product[:, :columns] + 1j * product[:, columns:]
            residual = residual - wide_dtype(coefficient)(coefficient) * product
        return np.asarray(residual, dtype=x.dtype).reshape(x.shape)

    def _combined_extended(self) -> sp.csr_matrix | None:
        """``sum_i c_i A_i`` summed in extended precision, for real terms; None otherwise.

        The terms are summed without rounding to double (the reason they are kept apart), so one
        extended product gives the same residual to ~1e-19 relative as one product per term, at
        about half the cost for ``K - sigma M``. Built for the second residual of a factorization
        and kept with it (about 1.5 times the memory of ``A`` in double).
        """
        if not hasattr(self, "_combined"):
            real = all(np.isrealobj(c) or np.imag(c) == 0 for c, _ in self.terms) and not any(
                np.iscomplexobj(m.data) for _, m in self.terms
            )
            combined = None
            if real and len(self.terms) > 1:
                real_terms = [(np.real(c), m) for c, m in self.terms]
                combined = combine(real_terms, np.longdouble)
            self._combined = combined
        return self._combined

    def _relative(self, residual: np.ndarray, x: np.ndarray, rhs: np.ndarray) -> float:
        """Normwise backward error ``|r| / (|A| |x| + |b|)`` (infinity norms, worst column)."""
        r = np.abs(residual).max(axis=0)
        scale = self._norm * np.abs(x).max(axis=0) + np.abs(rhs).max(axis=0)
        scale = np.where(scale > 0, scale, 1.0)
        return float(np.max(r / scale)) if np.size(r) else 0.0

    def operator(self) -> spla.LinearOperator:
        """The inverse as a :class:`scipy.sparse.linalg.LinearOperator` (for ``eigsh``)."""
        return spla.LinearOperator(
            self.shape, matvec=self.solve, matmat=self.solve, dtype=self.dtype
        )


_NORMS: dict[int, float] = {}


def _norm_of(matrix: sp.spmatrix) -> float:
    """:func:`~pymorembs.linalg.pattern.infinity_norm`, cached while ``matrix`` lives."""
    key = id(matrix)
    known = _NORMS.get(key)
    if known is None:
        known = _NORMS[key] = infinity_norm(matrix)
        weakref.finalize(matrix, _NORMS.pop, key, None)
    return known


def _column_norms(a: np.ndarray) -> np.ndarray:
    """Euclidean norms of the columns (one value for a vector), without BLAS (threaded level-1
    BLAS can be slow on small machines)."""
    squares = a.real**2 + a.imag**2 if np.iscomplexobj(a) else a * a
    return np.sqrt(np.atleast_1d(np.sum(squares, axis=0)))
