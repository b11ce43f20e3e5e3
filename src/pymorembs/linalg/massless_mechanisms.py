"""Massless mechanisms: directions with neither mass nor stiffness, found without going dense.

The massless directions ``Q_0`` of a mass matrix (:mod:`pymorembs.linalg.mass_split`) are
condensed statically, which needs ``K_00 = Q_0^T K Q_0`` to be regular. A direction
``N = Q_0 x`` with ``K_00 x = 0`` has neither mass nor stiffness of its own: a dof that nothing
touches (a grid's rotation used only by solid elements or rods), or a motion of several massless
dofs together (the rotation of a straight beam with lumped translational masses about its own
axis when its translations are pinned at both ends -- every node turns alike, nothing resists,
nothing carries inertia).

**When it may be removed.** For a positive semidefinite ``K``, ``x^T K_00 x = 0`` forces
``K_10 x = 0``: the direction is decoupled from every massive dof, ``K N = 0`` and ``M N = 0``.
Holding it (fixing one dof that takes part in it) then changes neither the finite eigenpairs nor
any response of the massive dofs: every field plus a multiple of ``N`` has the same energy, so a
field with that dof at zero is as good as any. This is what Nastran's ``PARAM,AUTOSPC`` does
for singular dofs. A direction with ``K_00 x = 0`` but ``K_10 x != 0`` is impossible for a
semidefinite ``K``: the matrix is indefinite there (or nearly a mechanism that moves masses), and
no removal is right.

**How they are found** (:func:`massless_mechanisms`), in the Jacobi-scaled block
``A = D^-1/2 K_00 D^-1/2`` (``D = diag K_00``: unit diagonal, so tolerances do not depend on
units, translations and rotations alike):

* directions of ``Q_0`` with ``D = 0`` (no stiffness entry on their diagonal) are candidates as
  they are;
* the others fall into the connected components of the graph of ``A``. Components of up to
  :data:`DENSE_COMPONENT` dofs are decomposed densely, batched by size; their eigenvectors with
  eigenvalues below the tolerance are candidates;
* the larger components (all of them together) are factorized once, ``A + tau I`` with
  ``tau`` the tolerance (symmetric positive definite, with SuperLU or PARDISO), and a block of
  random vectors goes through a few steps of inverse iteration and a Rayleigh-Ritz step: null
  directions of ``A`` are amplified by ``1 / tau`` over the smallest stiff eigenvalue
  ``lambda_1``, by ``(lambda_1 + tau) / tau`` (``1e6`` and more) per step. One step decides
  when no Ritz value comes near zero; null ones are iterated until they are eigenvectors to well
  below the tolerance. The block doubles while every Ritz value is null, so it ends larger than
  the number of null directions. The basis is split by component (the null space of a
  block-diagonal matrix is the direct sum of theirs).

This scales: nothing is formed densely beyond the components of at most
:data:`DENSE_COMPONENT` dofs and the ``n_0 x block`` Ritz block; the one factorization is of the
massless block only -- for a shell model with massless rotations, three of six dofs per node,
about an eighth of the flops of factorizing ``K`` -- and none at all when every massless
direction lies in a small component or has no stiffness entry (the usual zero rows), or when
``M`` is regular.

**The decision.** A candidate is null when its Rayleigh quotient in ``A`` lies below the
tolerance ``max(NULL_TOL, ROUNDING_FACTOR * eps)`` (``eps``: the relative rounding of the
file's entries, :func:`~pymorembs.linalg.rounding.relative_rounding`); a 10-digit Femap punch
of a pinned beam gives its torsion direction ``-1.9e-10`` and the next ``1.6e-2``. It is
decoupled when the residual ``K N``, in the coordinates ``[Q_m Q_0]`` scaled by their own
stiffness diagonals, is below the same tolerance relative to ``N`` (there ``1.9e-10``: the
null eigenvalue itself; the part on the massive dofs is ``2.5e-12``).

**Removal.** Fixing the dofs of :attr:`MasslessMechanisms.pivots` removes exactly the null
directions: per connected part, Gaussian elimination with partial pivoting on the null vectors
picks one dof per direction where they are large (among near-equal entries the first), so that
the vectors restricted to those dofs are regular.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
import scipy.sparse.csgraph as csgraph

from pymorembs.linalg.backends import factorize
from pymorembs.linalg.mass_split import MassSplit, block_eigen

#: An eigenvalue of the Jacobi-scaled massless block ``A`` (unit diagonal) below this is a null
#: direction in a model stored in full double precision (rounding puts true null directions
#: near 1e-15; the softest stiff massless direction of a straight torsion chain of ``n``
#: elements held at one end lies near ``(pi / 2n)^2 / 2``, 2e-9 at 25,000 elements).
NULL_TOL = 1e-10
#: For a file rounded to a few digits the tolerance is at least this many times its relative
#: rounding ``eps`` (a 10-digit punch: 5e-8).
ROUNDING_FACTOR = 100.0
#: Connected components of ``A`` up to this size are decomposed densely (batched by size).
DENSE_COMPONENT = 32
#: Most entries (component count x size^2) of one batch of dense components.
DENSE_BATCH = 4_000_000
#: First block size of the inverse iteration and its most steps.
START_BLOCK = 4
MAX_STEPS = 12
#: The search ends after a step whose smallest Ritz value exceeds this many tolerances (after
#: one step a null direction outweighs the rest of a random block by ``lambda_1 / tau``).
CLEAR = 1e4
#: Null Ritz vectors are settled when ``|A v - theta v|`` is below this fraction of the
#: tolerance (their entries then hold to ~1e-3 of it, so near-equal entries pick the same
#: pivot dof on every machine).
SETTLED = 1e-3
#: Entries within this fraction of the largest count as equal when a pivot dof is chosen.
PIVOT_TIE = 1e-8
_SEED = 20261205


@dataclass(frozen=True, eq=False)
class MasslessMechanisms:
    """The directions without mass and without stiffness of a pencil ``(K, M)``.

    Attributes
    ----------
    vectors : sparse matrix, shape (n, k)
        The directions ``N`` (columns of unit 2-norm), each supported on the dofs of one
        connected part of the massless block.
    energy : ndarray, shape (k,)
        Rayleigh quotient of each direction in the Jacobi-scaled massless block (0 for a
        direction without a stiffness entry).
    residual : ndarray, shape (k,)
        ``|K N|`` in the stiffness-scaled coordinates, relative to ``N`` in them: rounding for a
        decoupled direction, more where it is coupled to other dofs.
    largest : ndarray of int, shape (k,)
        The equation where that residual is largest (-1 where it is zero): the dof a coupled
        direction pulls at.
    group : ndarray of int, shape (k,)
        The connected part of the massless block each direction lies in (directions of one part
        share dofs); a direction without a stiffness entry is a part of its own.
    pivots : ndarray of int, shape (k,)
        Equations whose fixing removes exactly these directions (one per direction, within its
        part, where it is large).
    tolerance : float
        The tolerance of both tests (module docstring).
    """

    vectors: sp.csc_matrix
    energy: np.ndarray
    residual: np.ndarray
    largest: np.ndarray
    group: np.ndarray
    pivots: np.ndarray
    tolerance: float

    @property
    def count(self) -> int:
        """Number of directions without mass and stiffness."""
        return int(self.energy.size)

    @property
    def coupled(self) -> np.ndarray:
        """Boolean mask, shape (k,): directions whose residual exceeds the tolerance (``K`` is
        indefinite there, or nearly a mechanism that moves masses): they cannot be removed."""
        return self.residual > self.tolerance

    @property
    def single(self) -> np.ndarray:
        """Boolean mask, shape (k,): directions that are one dof (a unit vector)."""
        return np.diff(self.vectors.indptr) == 1


def massless_mechanisms(
    stiffness: sp.spmatrix, split: MassSplit, eps: float = 0.0
) -> MasslessMechanisms:
    """The null directions of ``K`` on the massless directions of ``M`` and their coupling.

    Parameters
    ----------
    stiffness : sparse matrix, shape (n, n)
        Symmetric ``K`` of the independent dofs.
    split : MassSplit
        :func:`~pymorembs.linalg.mass_split.mass_split` of the mass matrix of the same dofs.
    eps : float
        Relative rounding of the file's entries (0: full double precision).

    Returns
    -------
    MasslessMechanisms
        Empty when ``M`` is regular or ``K_00`` is.
    """
    n = split.n
    tolerance = max(NULL_TOL, ROUNDING_FACTOR * float(eps))
    if not split.singular:
        return _none(n, tolerance)
    k = sp.csr_matrix(stiffness, dtype=float)
    q0 = sp.csc_matrix(split.massless)
    k00 = sp.csr_matrix(q0.T @ (k @ q0))
    k00 = sp.csr_matrix(0.5 * (k00 + k00.T))
    d0 = k00.diagonal()
    loose = np.flatnonzero(d0 <= 0.0)
    stiff = np.flatnonzero(d0 > 0.0)
    root = 1.0 / np.sqrt(d0[stiff])
    a = sp.csr_matrix(sp.diags(root) @ k00[stiff][:, stiff] @ sp.diags(root))
    # candidates: (coefficients on the massless directions (n0, j), group labels (j,))
    found: list[tuple[sp.csc_matrix, np.ndarray]] = []
    n0 = q0.shape[1]
    if loose.size:
        unit = sp.csc_matrix(
            (np.ones(loose.size), (loose, np.arange(loose.size))), shape=(n0, loose.size)
        )
        found.append((unit, -1 - np.arange(loose.size)))  # each a part of its own
    if stiff.size:
        _, labels = csgraph.connected_components(a, directed=False)
        sizes = np.bincount(labels)
        for vectors, groups in (
            _dense_null(a, labels, sizes, tolerance),
            _sparse_null(a, labels, sizes, tolerance),
        ):
            if groups.size:
                scaled = sp.csc_matrix(vectors)
                on_massless = sp.csc_matrix(
                    (root[scaled.indices] * scaled.data, stiff[scaled.indices], scaled.indptr),
                    shape=(n0, scaled.shape[1]),
                )
                found.append((on_massless, groups))
    if not found:
        return _none(n, tolerance)
    coefficients = sp.hstack([f[0] for f in found], format="csc")
    coefficients = sp.csc_matrix(coefficients @ sp.diags(1.0 / _column_norms(coefficients)))
    vectors = sp.csc_matrix(q0 @ coefficients)  # unit columns: Q_0 is orthonormal
    vectors.eliminate_zeros()
    _, group = np.unique(np.concatenate([f[1] for f in found]), return_inverse=True)
    energy, residual, largest = _tests(k, split, coefficients, d0)
    return MasslessMechanisms(
        vectors=vectors,
        energy=energy,
        residual=residual,
        largest=largest,
        group=group,
        pivots=_pivots(vectors, group),
        tolerance=tolerance,
    )


def _none(n: int, tolerance: float) -> MasslessMechanisms:
    empty = np.zeros(0, dtype=np.int64)
    return MasslessMechanisms(
        sp.csc_matrix((n, 0)), np.zeros(0), np.zeros(0), empty, empty, empty, tolerance
    )


def _dense_null(
    a: sp.csr_matrix, labels: np.ndarray, sizes: np.ndarray, tolerance: float
) -> tuple[sp.csc_matrix, np.ndarray]:
    """Null vectors of the components of 2 to :data:`DENSE_COMPONENT` dofs (batched ``eigh``).

    Returns the vectors on the rows of ``a`` (unit norm), shape (n_a, j), and their component.
    """
    n_a = a.shape[0]
    small = np.flatnonzero((sizes >= 2) & (sizes <= DENSE_COMPONENT))
    if small.size == 0:
        return sp.csc_matrix((n_a, 0)), np.zeros(0, dtype=np.int64)
    coo = a.tocoo()
    columns: list[sp.coo_matrix] = []
    groups: list[np.ndarray] = []
    for size in np.unique(sizes[small]).tolist():
        components = small[sizes[small] == size]
        per_batch = max(1, DENSE_BATCH // (size * size))
        for start in range(0, components.size, per_batch):
            batch = components[start : start + per_batch]
            vectors, values, dofs = block_eigen(coo, labels, batch, size)
            block, column = np.nonzero(values <= tolerance)
            if block.size == 0:
                continue
            data = vectors[block, :, column]  # (j, size)
            cols = np.repeat(np.arange(block.size), size)
            columns.append(
                sp.coo_matrix((data.ravel(), (dofs[block].ravel(), cols)), shape=(n_a, block.size))
            )
            groups.append(batch[block])
    if not columns:
        return sp.csc_matrix((n_a, 0)), np.zeros(0, dtype=np.int64)
    return sp.hstack(columns, format="csc"), np.concatenate(groups)


def _sparse_null(
    a: sp.csr_matrix, labels: np.ndarray, sizes: np.ndarray, tolerance: float
) -> tuple[np.ndarray, np.ndarray]:
    """Null vectors of the components above :data:`DENSE_COMPONENT` dofs: one factorization of
    ``A_L + tau I`` over all of them, block inverse iteration, Rayleigh-Ritz; split by component.

    Returns the vectors on the rows of ``a`` (unit norm), shape (n_a, j), and their component.
    """
    n_a = a.shape[0]
    rows = np.flatnonzero(sizes[labels] > DENSE_COMPONENT)
    if rows.size == 0:
        return np.zeros((n_a, 0)), np.zeros(0, dtype=np.int64)
    block_matrix = sp.csr_matrix(a[rows][:, rows])
    n_l = rows.size
    factor = factorize(sp.csc_matrix(block_matrix + tolerance * sp.identity(n_l)), symmetric=True)
    rng = np.random.default_rng(_SEED)
    width = min(n_l, START_BLOCK)
    while True:
        x = rng.standard_normal((n_l, width))
        for _ in range(MAX_STEPS):
            x, _ = np.linalg.qr(factor.solve(x))
            projected = x.T @ (block_matrix @ x)
            theta, y = np.linalg.eigh(0.5 * (projected + projected.T))
            ritz = x @ y
            null = theta <= tolerance
            if not null.any():
                if theta[0] > CLEAR * tolerance:
                    break  # nothing near zero: a null direction would dominate the block by now
                continue
            misfit = np.linalg.norm(
                block_matrix @ ritz[:, null] - ritz[:, null] * theta[null], axis=0
            )
            if np.all(misfit <= SETTLED * tolerance):
                break
        if null.all() and width < n_l:
            width = min(2 * width, n_l)
            continue
        break
    basis = ritz[:, null]
    if basis.shape[1] == 0:
        return np.zeros((n_a, 0)), np.zeros(0, dtype=np.int64)
    # the null space of a block-diagonal matrix is the direct sum of those of its blocks: the
    # rows of one component span its own null vectors (singular values 1, the rest rounding)
    owner = labels[rows]
    weight = np.bincount(owner, weights=np.einsum("ij,ij->i", basis, basis), minlength=sizes.size)
    vectors: list[np.ndarray] = []
    groups: list[int] = []
    for component in np.flatnonzero(weight > 0.25).tolist():
        mine = np.flatnonzero(owner == component)
        u, s, _ = np.linalg.svd(basis[mine], full_matrices=False)
        for column in np.flatnonzero(s > 0.5):
            full = np.zeros(n_a)
            full[rows[mine]] = u[:, column]
            vectors.append(full)
            groups.append(component)
    return np.column_stack(vectors), np.asarray(groups, dtype=np.int64)


def _tests(
    k: sp.csr_matrix, split: MassSplit, coefficients: sp.csc_matrix, d0: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Energy, relative residual and the equation of the largest residual of each direction.

    The directions are ``N = Q_0 x`` (``x``: the columns of ``coefficients``). The residual
    ``K N`` is taken in the coordinates ``[Q_m Q_0]`` of the split, each scaled by ``1 / sqrt``
    of its own stiffness diagonal ``w`` (the median of the positive ones where it has none), and
    divided by the size of ``N`` in the same scaled coordinates, ``|x / w_0|``; the energy is
    ``x^T K_00 x / |x / w_0|^2``.
    """
    qm, q0 = sp.csc_matrix(split.massive), sp.csc_matrix(split.massless)
    dm = np.asarray(qm.multiply(k @ qm).sum(axis=0)).ravel()
    diagonal = np.concatenate([dm, d0])
    positive = diagonal[diagonal > 0]
    typical = float(np.median(positive)) if positive.size else 1.0
    w = 1.0 / np.sqrt(np.where(diagonal > 0, diagonal, typical))
    w0 = w[qm.shape[1] :]
    basis = sp.hstack([qm, q0], format="csc")
    residual = sp.csc_matrix(basis.T @ (k @ sp.csc_matrix(q0 @ coefficients)))
    size = _column_norms(sp.diags(1.0 / w0) @ coefficients)
    k00_x = residual[qm.shape[1] :]
    energy = np.asarray(coefficients.multiply(k00_x).sum(axis=0)).ravel() / size**2
    residual = sp.csc_matrix(sp.diags(w) @ residual)
    relative = _column_norms(residual) / size
    largest = np.full(size.size, -1, dtype=np.int64)
    for j in range(size.size):
        start, stop = residual.indptr[j], residual.indptr[j + 1]
        if stop > start:
            coordinate = int(residual.indices[start + np.argmax(np.abs(residual.data[start:stop]))])
            dof = basis[:, coordinate]
            largest[j] = int(dof.indices[np.argmax(np.abs(dof.data))])
    return energy, relative, largest


def _column_norms(matrix: sp.spmatrix) -> np.ndarray:
    """2-norms of the columns of a sparse matrix."""
    matrix = sp.csc_matrix(matrix)
    return np.sqrt(np.asarray(matrix.multiply(matrix).sum(axis=0)).ravel())


def _pivots(vectors: sp.csc_matrix, group: np.ndarray) -> np.ndarray:
    """One equation per direction whose fixing removes the directions (module docstring)."""
    pivots = np.zeros(group.size, dtype=np.int64)
    for part in np.unique(group).tolist():
        columns = np.flatnonzero(group == part)
        sub = vectors[:, columns]
        rows = np.unique(sub.indices)
        dense = sub[rows].toarray()  # the part's dofs x its directions
        for j in range(columns.size):
            magnitude = np.abs(dense[:, j])
            best = int(np.flatnonzero(magnitude >= (1.0 - PIVOT_TIE) * magnitude.max())[0])
            pivots[columns[j]] = rows[best]
            if j + 1 < columns.size:
                dense[:, j + 1 :] -= np.outer(dense[:, j] / dense[best, j], dense[best, j + 1 :])
    return pivots
