"""Sparse direct solves with one factorization reused for many right-hand sides.

Every large solve in pymorembs goes through :class:`Factorization`: modal shift-invert, Krylov
moments at an expansion point, frequency responses. The factorization is computed once per
matrix (per shift) and kept while the shift stays the same; solves take blocks of right-hand
sides and are checked by their residual, with one step of iterative refinement when the residual
is not small (ill-conditioned models such as the paper's light stiff beams).
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from pymorembs.errors import NumericalError

#: Refinement stops when the correction is below this, relative to the solution.
REFINE_TOL = 1e-14
#: At most this many refinement steps.
MAX_REFINEMENTS = 4
#: Relative backward error above which a solve is reported as failed.
FAIL_ABOVE = 1e-6


class Factorization:
    """LU factorization of a sparse square matrix (SuperLU).

    Parameters
    ----------
    matrix : sparse matrix, shape (n, n)
        Real or complex. Never densified.
    label : str
        What the matrix is, for error messages (e.g. ``"K - w^2 M at 500 Hz"``).
    check : bool
        Check the residual of every solve and refine once if needed.
    """

    def __init__(self, matrix: sp.spmatrix, label: str = "matrix", check: bool = True) -> None:
        self.matrix = sp.csc_matrix(matrix)
        self.label = label
        self.check = check
        self.shape = self.matrix.shape
        self.dtype = self.matrix.dtype
        try:
            self._lu = spla.splu(self.matrix)
        except RuntimeError as exc:  # "Factor is exactly singular"
            raise NumericalError(f"{label} is singular ({exc})") from None
        self._norm = float(spla.norm(self.matrix, np.inf)) or 1.0
        self._extended: sp.csc_matrix | None = None

    def solve(self, rhs: np.ndarray) -> np.ndarray:
        """Solve ``A X = rhs`` for a vector (n,) or a block (n, k), real or complex."""
        rhs = np.asarray(rhs)
        if np.iscomplexobj(rhs) and not np.iscomplexobj(self.matrix.data):
            return self.solve(rhs.real) + 1j * self.solve(rhs.imag)
        x = self._lu.solve(rhs)
        if not self.check:
            return x
        for _ in range(MAX_REFINEMENTS):
            correction = self._lu.solve(self._residual(rhs, x))
            x = x + correction
            if np.linalg.norm(correction) <= REFINE_TOL * np.linalg.norm(x):
                break
        rel = self._relative(rhs - self.matrix @ x, x, rhs)
        if not np.isfinite(rel) or rel > FAIL_ABOVE:
            raise NumericalError(
                f"solve with {self.label} is inaccurate (relative residual {rel:.1e}); "
                "the matrix is singular or nearly so"
            )
        return x

    def _residual(self, rhs: np.ndarray, x: np.ndarray) -> np.ndarray:
        """``rhs - A x`` computed in extended precision, rounded to working precision."""
        if self._extended is None:
            wide = np.clongdouble if np.iscomplexobj(self.matrix.data) else np.longdouble
            self._extended = sp.csr_matrix(self.matrix).astype(wide)
        wide_x = x.astype(self._extended.dtype)
        return np.asarray(rhs - self._extended @ wide_x, dtype=x.dtype)

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
