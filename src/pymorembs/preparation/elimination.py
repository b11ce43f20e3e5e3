"""Elimination of dependent and fixed dofs (paper section 2.3, eqs. 9-18).

The dofs of a body fall into three families: independent ``q_i``, dependent ``q_d`` given by the
constraint equations ``q_d = G_M q_i + g`` (eq. 9), and constrained ``q_c = 0`` (eq. 10). With the
transformation ``q = T q_i + t``, where ``T`` stacks the identity (independent rows), ``G_M``
(dependent rows) and zeros (fixed rows), and ``t`` holds ``g`` in the dependent rows, the
matrices of the independent dofs are ``M* = T^T M T`` etc. -- the compact form of eqs. 13-15 --
and the constant load is ``f* = -T^T K t`` (eq. 16). Loads on dependent dofs are distributed by
``B* = T^T B`` (eq. 17) and outputs read ``C* = C T``. After reduction a basis of the independent
dofs is expanded to all dofs by ``V = T V_i`` (eq. 18).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components

from pymorembs.body import ElasticBody
from pymorembs.errors import UserError
from pymorembs.linalg.factorization import known_symmetric


@dataclass(frozen=True, eq=False)
class Elimination:
    """The map ``q = T q_i + t`` from independent to all dofs.

    Attributes
    ----------
    independent, dependent, fixed : ndarray of int
        Equation indices of the three dof families (disjoint, together all equations).
    transform : sparse matrix, shape (n_dof, n_i)
        ``T``.
    offset : ndarray, shape (n_dof,)
        ``t`` (``g`` in the dependent rows, resolved through chained equations).
    """

    independent: np.ndarray
    dependent: np.ndarray
    fixed: np.ndarray
    transform: sp.csr_matrix
    offset: np.ndarray

    @property
    def n_independent(self) -> int:
        return int(self.independent.size)

    def __repr__(self) -> str:
        return (f"<Elimination: independent {self.independent.size}, dependent "
                f"{self.dependent.size}, fixed {self.fixed.size}>")  # fmt: skip

    def matrix(self, matrix: sp.spmatrix | None) -> sp.csr_matrix | None:
        """``T^T A T`` -- eqs. 13-15 for A = M, D, K."""
        if matrix is None:
            return None
        reduced = sp.csr_matrix(self.transform.T @ (matrix @ self.transform))
        reduced.sum_duplicates()  # canonical: sorted columns
        return symmetric_part(reduced)

    def load(self, stiffness: sp.spmatrix) -> np.ndarray:
        """``f* = -T^T K t`` (eq. 16)."""
        return -(self.transform.T @ (stiffness @ self.offset))

    def inputs(self, input_matrix: sp.spmatrix | np.ndarray) -> np.ndarray:
        """``B* = T^T B`` (eq. 17): loads on dependent dofs distributed to independent dofs."""
        return np.asarray(sp.csr_matrix(self.transform.T @ input_matrix).toarray())

    def outputs(self, output_matrix: sp.spmatrix | np.ndarray) -> np.ndarray:
        """``C* = C T``: outputs at dependent dofs read through the constraint equations."""
        return np.asarray(sp.csr_matrix(output_matrix @ self.transform).toarray())

    def expand(self, basis: np.ndarray) -> np.ndarray:
        """Basis over all dofs from a basis of the independent dofs, ``T V_i`` (eq. 18).

        Fixed rows are zero (``V_c = 0``); dependent rows are ``G_M V_i``. The offset ``g`` is not
        part of a basis: a constant displacement belongs to the affine part ``t`` of the map
        (the paper's ``V_d = G_M V_i - g`` mixes the two).
        """
        return np.asarray(self.transform @ basis)


def eliminate(body: ElasticBody) -> Elimination:
    """Split the dofs of ``body`` into families and build ``T`` and ``t``.

    Chained constraint equations (a dependent dof that depends on another dependent dof) are
    resolved; a dependent dof that is also fixed, or cyclic equations, are user errors.
    """
    n = body.n_dof
    constraints = body.constraints
    dependent = constraints.dependent
    fixed = body.fixed
    both = np.intersect1d(dependent, fixed)
    if both.size:
        raise UserError(
            f"dof {body.dofs.label(both[0])} is both dependent (constraint equation) and fixed"
        )
    is_dependent = np.zeros(n, dtype=bool)
    is_dependent[dependent] = True
    is_fixed = np.zeros(n, dtype=bool)
    is_fixed[fixed] = True
    independent = np.flatnonzero(~is_dependent & ~is_fixed)

    g_matrix, g_offset = _resolve_chains(body, is_dependent)
    # q_d = G[:, independent] q_i + G[:, fixed] * 0 + g
    g_independent = sp.csr_matrix(g_matrix[:, independent])

    identity = sp.csr_matrix(
        (np.ones(independent.size), (independent, np.arange(independent.size))),
        shape=(n, independent.size),
    )
    placed = sp.csr_matrix(
        (np.ones(dependent.size), (dependent, np.arange(dependent.size))),
        shape=(n, dependent.size),
    )
    transform = sp.csr_matrix(identity + placed @ g_independent)
    offset = np.zeros(n)
    offset[dependent] = g_offset
    return Elimination(independent, dependent, fixed, transform, offset)


def _resolve_chains(
    body: ElasticBody, is_dependent: np.ndarray
) -> tuple[sp.csr_matrix, np.ndarray]:
    """``G`` and ``g`` with no dependent dof on a right-hand side.

    With ``G = G_dd + G_dr`` split into columns of dependent and other dofs,
    ``q_d = G_dd q_d + G_dr q_r + g`` has the solution ``q_d = sum_k G_dd^k (G_dr q_r + g)``,
    a finite sum when the chains are acyclic (``G_dd`` nilpotent). Cycles are found structurally
    (strongly connected components of the graph "dependent -> dependent"), whatever the
    coefficients; the sum is formed with sparse products, one per chain level.
    """
    constraints = body.constraints
    g_matrix = sp.csr_matrix(constraints.matrix)
    dependent = constraints.dependent
    g_dd = sp.csr_matrix(g_matrix[:, dependent])
    g_dd.eliminate_zeros()
    if g_dd.nnz == 0:
        return g_matrix, constraints.offset
    cycle = _cyclic_dof(g_dd)
    if cycle is not None:
        raise UserError(
            f"constraint equations are cyclic: dof {body.dofs.label(dependent[cycle])} depends "
            "on itself through dependent dofs"
        )
    term = sp.csr_matrix(g_matrix @ sp.diags((~is_dependent).astype(float)))  # G_dr
    term.eliminate_zeros()
    offset_term = constraints.offset
    resolved, resolved_offset = term, offset_term
    for _ in range(dependent.size):  # acyclic: ends after the longest chain
        term = sp.csr_matrix(g_dd @ term)
        term.eliminate_zeros()
        offset_term = g_dd @ offset_term
        if term.nnz == 0 and not np.any(offset_term):
            break
        resolved = resolved + term
        resolved_offset = resolved_offset + offset_term
    return sp.csr_matrix(resolved), resolved_offset


def _cyclic_dof(g_dd: sp.csr_matrix) -> int | None:
    """Position of a dependent dof on a cycle of the graph "dependent -> dependent", or None."""
    if np.any(g_dd.diagonal() != 0):
        return int(np.flatnonzero(g_dd.diagonal() != 0)[0])
    count, labels = connected_components(g_dd, directed=True, connection="strong")
    if count == g_dd.shape[0]:
        return None
    sizes = np.bincount(labels)
    return int(np.flatnonzero(sizes[labels] > 1)[0])


def symmetric_part(matrix: sp.csr_matrix) -> sp.csr_matrix:
    """``(A + A^T) / 2`` of a canonical CSR matrix: exact symmetry despite round-off.

    Where the pattern is symmetric (FE matrices), the transpose stored as CSC has the same
    ``indptr`` and ``indices`` as ``A``, so the mean is taken on the data arrays in place of a
    sparse sum (which would hold ``A``, ``A^T`` and the sum at once: gigabytes at millions of
    dofs); any other pattern takes the sparse sum.
    """
    transpose = matrix.tocsc()  # the CSR arrays of A^T
    transpose.sort_indices()
    if np.array_equal(transpose.indptr, matrix.indptr) and np.array_equal(
        transpose.indices, matrix.indices
    ):
        data = 0.5 * (matrix.data + transpose.data)
        del transpose
        out = sp.csr_matrix((data, matrix.indices, matrix.indptr), shape=matrix.shape, copy=False)
        out.has_canonical_format = True
        return known_symmetric(out)
    return known_symmetric(sp.csr_matrix(0.5 * (matrix + matrix.T)))
