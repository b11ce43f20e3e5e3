"""Full-model responses at check frequencies without a complex factorization.

A check of the error reference needs the full model's response ``x = Z(s)^{-1} B`` with
``Z(s) = s^2 M + s D + (1 + i eta) K`` at one frequency: a complex sparse factorization, several
times the cost of a real one. When a job already holds a real factor ``F`` of ``K - tau M``
(an expansion point of the reference model or of a reduction), the response is computed from
it instead:

* iterative refinement in extended precision -- the residual ``B - Z x`` of the exact operator
  (the sum of its unrounded terms) in double-double, as
  :class:`~pymorembs.linalg.factorization.Factorization` refines its solves;
* each correction from GMRES on ``Z e = r``, right-preconditioned by a two-level
  preconditioner: the Galerkin solve on the reference model's basis ``V`` (which holds the
  modes of the band, the directions ``F`` is worst at) and ``F^{-1}`` on the rest,
  ``P^{-1} r = Q r + F^{-1} (r - Z Q r)`` with ``Q = V (V^T Z V)^{-1} V^T``.

The answer is accepted only when the refinement ended as that of a refined direct solve
ends -- the error left after the last correction below :data:`REFINE_TOL` of the solution in
every column (the last correction, or one times the residual reduction its GMRES run reached
when that is far below), or corrections no longer halving (the accuracy the conditioning
allows) -- and the normwise
backward error of the extended-precision residual is at the rounding level
(:data:`BACKWARD_TOL`): then it is the response a refined direct solve gives, to that
accuracy. Otherwise (slow convergence, no extended precision) :func:`shifted_response` returns
None and the caller factorizes.
"""

from __future__ import annotations

import weakref
from collections.abc import Sequence
from typing import Any

import numpy as np
import scipy.linalg as sla

from pymorembs.linalg import double_double
from pymorembs.linalg.backends import SparseFactor
from pymorembs.linalg.pattern import infinity_norm
from pymorembs.linalg.products import multiply

#: A correction below this, relative to the solution (each column), ends the refinement.
REFINE_TOL = 1e-12
#: Largest accepted normwise backward error ``|r| / (|Z| |x| + |b|)`` (infinity norms).
BACKWARD_TOL = 1e-14
#: Refinement steps (each a GMRES run) before giving up.
MAX_REFINEMENTS = 6
#: GMRES iterations per refinement step (each one solve with ``F`` of the whole block).
GMRES_STEPS = 25
#: A GMRES run stops once its residual fell by this factor in every column.
GMRES_REDUCTION = 1e-6

Terms = Sequence[tuple[complex, Any]]

#: ``(id(basis), id(matrix))`` -> ``(matrix, matrix @ basis)`` (:func:`basis_product`).
_BASIS_PRODUCTS: dict[tuple[int, int], tuple[Any, np.ndarray]] = {}


def apply(terms: Terms, x: np.ndarray) -> np.ndarray:
    """``sum_i c_i A_i x`` in double precision (real matrices times the real and imaginary
    parts, on the solver threads)."""
    out = None
    for coefficient, matrix in terms:
        part = coefficient * multiply(matrix, x)
        out = part if out is None else out + part
    return out


def basis_product(matrix: Any, basis: np.ndarray) -> np.ndarray:
    """``A V`` of a real sparse matrix and a coarse basis (double precision), kept while
    ``basis`` lives: the checks of one reference at different frequencies combine the same
    ``K V``, ``M V``, ``D V`` instead of multiplying again (on a 274k-dof part about a second
    per check). The entry holds ``matrix`` too, so that its ``id`` is not reused meanwhile."""
    key = (id(basis), id(matrix))
    entry = _BASIS_PRODUCTS.get(key)
    if entry is None:
        entry = (matrix, multiply(matrix, basis))
        _BASIS_PRODUCTS[key] = entry
        weakref.finalize(basis, _BASIS_PRODUCTS.pop, key, None)
    return entry[1]


def real_times(a: np.ndarray, x: np.ndarray) -> np.ndarray:
    """``a @ x`` for a real dense ``a`` and a complex ``x`` without a complex copy of ``a``."""
    return a @ x.real + 1j * (a @ x.imag)


class TwoLevel:
    """The preconditioner ``Q + F^{-1} (I - Z Q)`` of the module docstring.

    Parameters
    ----------
    terms : sequence of (scalar, sparse matrix)
        ``Z`` as its terms.
    factor : SparseFactor
        A real factor of a nearby ``K - tau M``.
    basis : ndarray, shape (n, m) or None
        The coarse space ``V`` (None: ``F^{-1}`` alone).
    """

    def __init__(self, terms: Terms, factor: SparseFactor, basis: np.ndarray | None) -> None:
        self.terms = terms
        self.factor = factor
        self.basis = basis
        self.coarse = None
        if basis is not None and basis.shape[1]:
            # Z V, shape (n, m), from the products A_i V every check of this basis shares
            self.z_basis = sum(complex(c) * basis_product(m, basis) for c, m in terms)
            self.coarse = sla.lu_factor(real_times(basis.T, self.z_basis))

    def coarse_solve(self, r: np.ndarray) -> np.ndarray:
        """``y = (V^T Z V)^{-1} V^T r``, so that ``Q r = V y``."""
        return sla.lu_solve(self.coarse, real_times(self.basis.T, r))

    def galerkin(self, r: np.ndarray) -> np.ndarray:
        """``Q r``, the coarse solve (zero without a basis)."""
        if self.coarse is None:
            return np.zeros_like(r)
        return real_times(self.basis, self.coarse_solve(r))

    def __call__(self, r: np.ndarray) -> np.ndarray:
        if self.coarse is None:
            return self.factor.solve(r)
        y = self.coarse_solve(r)
        return real_times(self.basis, y) + self.factor.solve(r - self.z_basis @ y)


def gmres_block(
    terms: Terms, precondition: TwoLevel, r: np.ndarray
) -> tuple[np.ndarray, int, float]:
    """An approximate solution of ``Z e = r`` (n, k) by right-preconditioned GMRES, the ``k``
    columns run side by side (each step one preconditioner solve of the whole block); the
    number of steps and the largest relative residual ``|r - Z e| / |r|`` of a column.

    The preconditioned blocks ``P^{-1} v_j`` of the steps are kept (as flexible GMRES keeps
    them), so that the solution ``P^{-1} (sum_j v_j y_j) = sum_j (P^{-1} v_j) y_j`` costs no
    further solve: one preconditioner solve per step instead of one more per run (a check that
    converges in one step per refinement needs half the solves). They take as much memory as
    the Krylov blocks ``v_j`` themselves."""
    k = r.shape[1]
    beta = np.linalg.norm(r, axis=0)
    beta = np.where(beta > 0, beta, 1.0)
    basis = [r / beta]
    preconditioned = []
    hessenberg = np.zeros((GMRES_STEPS + 1, GMRES_STEPS, k), dtype=complex)
    steps = 0
    for j in range(GMRES_STEPS):
        preconditioned.append(precondition(basis[j]))
        w = apply(terms, preconditioned[j])
        for i in range(j + 1):  # modified Gram-Schmidt, column by column
            h = np.einsum("nk,nk->k", basis[i].conj(), w)
            hessenberg[i, j] = h
            w = w - basis[i] * h
        norm = np.linalg.norm(w, axis=0)
        hessenberg[j + 1, j] = norm
        steps = j + 1
        residuals = _least_squares(hessenberg[: steps + 1, :steps], beta)[1]
        if np.all(residuals <= GMRES_REDUCTION) or np.any(norm == 0):
            break
        basis.append(w / np.where(norm > 0, norm, 1.0))
    y, residuals = _least_squares(hessenberg[: steps + 1, :steps], beta)
    correction = sum(preconditioned[i] * y[i] for i in range(steps))
    return correction, steps, float(np.max(residuals))


def _least_squares(h: np.ndarray, beta: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per column: ``y = argmin |beta e1 - H y|`` and the relative residual of the minimum."""
    m, steps, k = h.shape
    y = np.zeros((steps, k), dtype=complex)
    relative = np.zeros(k)
    for col in range(k):
        target = np.zeros(m, dtype=complex)
        target[0] = beta[col]
        solution, *_ = np.linalg.lstsq(h[:, :, col], target, rcond=None)
        y[:, col] = solution
        relative[col] = np.linalg.norm(target - h[:, :, col] @ solution) / beta[col]
    return y, relative


def shifted_response(
    terms: Terms, rhs: np.ndarray, factor: SparseFactor, basis: np.ndarray | None
) -> tuple[np.ndarray | None, dict[str, float]]:
    """``x = Z^{-1} rhs`` from a real factor of a nearby shift (module docstring).

    Parameters
    ----------
    terms : sequence of (scalar, sparse matrix)
        ``Z`` as a sum of real sparse matrices with (complex) coefficients.
    rhs : ndarray, shape (n, k)
    factor : SparseFactor
        A real factor of ``K - tau M``.
    basis : ndarray, shape (n, m) or None
        The coarse space (the reference model's basis).

    Returns
    -------
    x : ndarray, complex, shape (n, k), or None
        The certified solution, or None when it could not be certified.
    facts : dict
        ``refinements``, ``gmres_steps`` (preconditioner solves), ``backward_error`` and
        ``correction`` (the last relative one).
    """
    facts = {"refinements": 0, "gmres_steps": 0, "backward_error": np.inf, "correction": np.inf}
    real_terms = all(np.isrealobj(m.data) for _, m in terms)
    if not (double_double.available() and real_terms):
        return None, facts
    rhs = np.asarray(rhs, dtype=complex).reshape(rhs.shape[0], -1)
    precondition = TwoLevel(terms, factor, basis)
    norm = sum(abs(c) * infinity_norm(m) for c, m in terms) or 1.0
    x = precondition.galerkin(rhs)
    previous, stagnated = np.inf, False
    for step in range(MAX_REFINEMENTS):
        residual = double_double.residual(rhs, terms, x).astype(complex, copy=False)
        correction, steps, reduction = gmres_block(terms, precondition, residual)
        facts["gmres_steps"] += steps
        x = x + correction
        size = np.linalg.norm(correction, axis=0)
        scale = np.maximum(np.linalg.norm(x, axis=0), np.finfo(float).tiny)
        facts["refinements"] = step + 1
        facts["correction"] = float(np.max(size / scale))
        # GMRES cut the residual of this step by ``reduction``: the error left after a
        # correction c is ~c * reduction, below REFINE_TOL without another run to confirm it
        # (the backward error below certifies the result)
        if facts["correction"] * reduction <= 0.01 * REFINE_TOL:
            facts["correction"] *= reduction
            break
        if facts["correction"] <= REFINE_TOL:
            break
        if facts["correction"] > 0.5 * previous:  # stagnating, as refined direct solves stop
            stagnated = True
            break
        previous = facts["correction"]
    residual = double_double.residual(rhs, terms, x)
    scale = norm * np.abs(x).max(axis=0) + np.abs(rhs).max(axis=0)
    facts["backward_error"] = float(
        np.max(np.abs(residual).max(axis=0) / np.maximum(scale, 1e-300))
    )
    if (facts["correction"] > REFINE_TOL and not stagnated) or facts[
        "backward_error"
    ] > BACKWARD_TOL:
        return None, facts
    return x, facts
