"""Massless directions of a mass matrix, found without factorizing or inverting ``M``.

A singular mass matrix is normal in FE models: beam and shell rotations without rotary inertia,
the nodes of rigid elements and multipoint constraints, Nastran's massless a-set dofs (zero rows
of ``M``), and point masses without rotary inertia on a node with rotational dofs or attached
with an offset (a nodal 6x6 block of rank 3, whose null space mixes the dofs of the node). An
eigenproblem ``K x = lambda M x`` then has infinite eigenvalues, one per massless direction, and
methods that need a definite mass (a Cholesky factor, ``M``-orthonormal Lanczos vectors, the
first-order form of eq. 5) must condense those directions exactly.

:func:`mass_split` finds them from the structure of ``M``: the connected components of its
sparsity graph are small for lumped and point masses (one node, or a few nodes coupled by an
offset mass) and one large component for a consistent mass of a mesh. A zero row is massless; a
small component (at most :data:`SMALL_BLOCK` dofs) is decomposed densely and its eigenvectors with
eigenvalues below :data:`MASSLESS_TOL` times the component's largest are massless; a large
component is taken as positive definite (a consistent element mass with a positive diagonal is;
its massless dofs, if any, are zero rows). The result is an orthonormal basis ``Q_m`` of the
massive directions and ``Q_0`` of the massless ones, with

    M = Q_m B Q_m^T,   B = Q_m^T M Q_m  positive definite,   M Q_0 = 0  (to rounding).

The finite eigenpairs of ``(K, M)`` are then those of the condensed pencil: for a shift-invert
operator ``A = (K - sigma M)^-1`` (or the inertia-relief inverse of a free body), with
``z = Q_m^T x``,

    (Q_m^T A Q_m) B z = mu z,   lambda = sigma + 1 / mu,   x = (lambda - sigma) A Q_m B z,

a symmetric problem in the ``B`` inner product of size ``rank(M)``: exact static condensation of
the massless directions (the Schur complement of ``K - sigma M`` on them) without ever forming
it. :func:`condensed_dense_eigh` does the same densely for small models.

The condensation needs ``K_00 = Q_0^T K Q_0`` regular. Directions with neither mass nor stiffness
(massless mechanisms) are found by :mod:`pymorembs.linalg.massless_mechanisms` and removed from
the body before any of this by :func:`pymorembs.preparation.prepare`.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp
import scipy.sparse.csgraph as csgraph

from pymorembs.errors import NumericalError

#: A direction of a small mass block is massless when its eigenvalue is below this fraction of
#: the block's largest one. Rounding of a 10-digit export leaves null eigenvalues near 1e-11 of
#: the block's largest; genuine small inertias (rotary inertia of a sensor) are 1e-6 and above.
MASSLESS_TOL = 1e-8
#: A mass block with an eigenvalue below minus this fraction of its largest is not positive
#: semidefinite (a wrong mass matrix, not rounding).
NEGATIVE_TOL = 1e-6
#: Connected components of the mass graph up to this size are decomposed densely.
SMALL_BLOCK = 96


@dataclass(frozen=True, eq=False)
class MassSplit:
    """The massive and massless directions of a mass matrix (see the module docstring).

    Attributes
    ----------
    massive : sparse matrix, shape (n, m)
        Orthonormal basis ``Q_m`` of the massive directions (``m = rank M``): unit vectors of the
        dofs of large components and of single massive dofs, eigenvectors of small blocks.
    massless : sparse matrix, shape (n, n - m)
        Orthonormal basis ``Q_0`` of the massless directions.
    mass : sparse matrix, shape (m, m)
        ``B = Q_m^T M Q_m``, positive definite.
    zero_rows : ndarray of int
        Equations whose row of ``M`` is zero (massless dofs in the narrow sense).
    """

    massive: sp.csr_matrix
    massless: sp.csr_matrix
    mass: sp.csr_matrix
    zero_rows: np.ndarray

    @property
    def n(self) -> int:
        return int(self.massive.shape[0])

    @property
    def rank(self) -> int:
        """Number of massive directions (finite eigenvalues of ``(K, M)``)."""
        return int(self.massive.shape[1])

    @property
    def n_massless(self) -> int:
        """Number of massless directions (infinite eigenvalues of ``(K, M)``)."""
        return self.n - self.rank

    @property
    def n_block_null(self) -> int:
        """Massless directions inside mass blocks, beyond the zero rows."""
        return self.n_massless - int(self.zero_rows.size)

    @property
    def singular(self) -> bool:
        return self.n_massless > 0

    @cached_property
    def massless_dofs(self) -> np.ndarray:
        """Equations that take part in a massless direction (zero rows and block null spaces)."""
        return np.unique(self.massless.tocoo().row)

    def describe(self) -> str:
        """One line for reports, e.g. ``"60 (34 dofs without mass, 26 directions ...)"``."""
        if not self.singular:
            return "none"
        parts = []
        if self.zero_rows.size:
            parts.append(f"{self.zero_rows.size} dofs without any mass entry")
        if self.n_block_null:
            parts.append(
                f"{self.n_block_null} directions inside mass blocks (e.g. point masses without "
                "rotary inertia)"
            )
        return f"{self.n_massless} ({'; '.join(parts)})"


def mass_split(mass: sp.spmatrix | np.ndarray) -> MassSplit:
    """Massive and massless directions of a symmetric positive semidefinite mass matrix.

    Parameters
    ----------
    mass : sparse matrix or ndarray, shape (n, n)

    Returns
    -------
    MassSplit

    Raises
    ------
    NumericalError
        A mass block that is clearly indefinite (an eigenvalue below
        ``-NEGATIVE_TOL`` times its largest) or a dof of a large block with a non-positive
        diagonal entry.
    """
    m = sp.csr_matrix(mass, dtype=float)  # (a CSR matrix's own arrays)
    if not np.all(m.data[: m.nnz]):  # stored zeros: dropped from a copy, not from ``mass``
        m = m.copy()
        m.eliminate_zeros()
    n = m.shape[0]
    row_nnz = np.diff(m.indptr)
    zero_rows = np.flatnonzero(row_nnz == 0)

    def regular_only() -> MassSplit:  # M itself is the massive part: no copy
        return MassSplit(sp.identity(n, format="csr"), sp.csr_matrix((n, 0)), m, zero_rows)

    if zero_rows.size == 0 and _diagonal_only(m):
        _check_positive(m.diagonal(), np.arange(n))
        return regular_only()
    _, labels = csgraph.connected_components(m, directed=False)
    sizes = np.bincount(labels)
    size_of = sizes[labels]
    # regular: single massive dofs and the dofs of large components, kept as unit vectors
    regular = np.flatnonzero((row_nnz > 0) & ((size_of == 1) | (size_of > SMALL_BLOCK)))
    _check_positive(m.diagonal()[regular], regular)
    small = np.flatnonzero((sizes >= 2) & (sizes <= SMALL_BLOCK))
    coo = m.tocoo() if small.size else None
    groups = []  # (vectors, values, dofs, keep) per block size
    for size in np.unique(sizes[small]).tolist():
        components = small[sizes[small] == size]
        vectors, values, dofs = block_eigen(coo, labels, components, size)
        scale = values.max(axis=1, keepdims=True)
        if np.any(values < -NEGATIVE_TOL * scale):
            bad = int(np.argmax((values < -NEGATIVE_TOL * scale).any(axis=1)))
            raise NumericalError(
                f"the mass matrix is not positive semidefinite: the mass block of equations "
                f"{', '.join(str(int(d) + 1) for d in dofs[bad][:6])} has the eigenvalue "
                f"{values[bad].min():.3e}"
            )
        groups.append((vectors, values, dofs, values > MASSLESS_TOL * scale))
    if zero_rows.size == 0 and all(keep.all() for *_, keep in groups):
        return regular_only()
    massive_cols: list[sp.coo_matrix] = []
    massless_cols: list[sp.coo_matrix] = []
    eigenvalues: list[np.ndarray] = []
    for vectors, values, dofs, keep in groups:
        size = dofs.shape[1]
        for flag, out in ((keep, massive_cols), (~keep, massless_cols)):
            block, column = np.nonzero(flag)
            if block.size:
                rows = dofs[block]  # (k, size): the equations of each kept eigenvector
                data = vectors[block, :, column]  # (k, size)
                cols = np.repeat(np.arange(block.size), size)
                out.append(
                    sp.coo_matrix((data.ravel(), (rows.ravel(), cols)), shape=(n, block.size))
                )
        eigenvalues.append(values[keep])
    unit = sp.coo_matrix(
        (np.ones(regular.size), (regular, np.arange(regular.size))), shape=(n, regular.size)
    )
    massive = sp.hstack([unit, *massive_cols], format="csr")
    zero = sp.coo_matrix(
        (np.ones(zero_rows.size), (zero_rows, np.arange(zero_rows.size))),
        shape=(n, zero_rows.size),
    )
    massless = sp.hstack([zero, *massless_cols], format="csr")
    b = sp.block_diag(
        [m[regular][:, regular], sp.diags(np.concatenate([np.zeros(0), *eigenvalues]))],
        format="csr",
    )
    return MassSplit(massive, massless, b, zero_rows)


def _diagonal_only(m: sp.csr_matrix) -> bool:
    """Whether every stored entry lies on the diagonal."""
    rows = np.repeat(np.arange(m.shape[0]), np.diff(m.indptr))
    return bool(np.array_equal(rows, m.indices))


def _check_positive(diagonal: np.ndarray, dofs: np.ndarray) -> None:
    bad = np.flatnonzero(diagonal <= 0)
    if bad.size:
        raise NumericalError(
            f"the mass matrix is not positive semidefinite: equation {int(dofs[bad[0]]) + 1} has "
            f"the diagonal entry {diagonal[bad[0]]:.3e} but other entries in its row"
        )


def block_eigen(
    coo: sp.coo_matrix, labels: np.ndarray, components: np.ndarray, size: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Eigenpairs of the diagonal blocks of a symmetric matrix on some of its connected
    components (all of ``size`` rows), batched in one ``eigh`` call.

    Parameters
    ----------
    coo : sparse matrix in COO format, shape (n, n)
        The symmetric matrix (e.g. ``M``).
    labels : ndarray of int, shape (n,)
        Component of each row (``scipy.sparse.csgraph.connected_components``).
    components : ndarray of int, shape (k,)
        The components to decompose, each of ``size`` rows.
    size : int

    Returns
    -------
    vectors : ndarray, shape (k, size, size)
        Eigenvectors (columns) per block.
    values : ndarray, shape (k, size)
        Eigenvalues per block, ascending.
    dofs : ndarray of int, shape (k, size)
        The rows of each block, ascending.
    """
    slot = np.full(labels.max() + 1, -1, dtype=np.int64)
    slot[components] = np.arange(components.size)
    dof_slot = slot[labels]
    members = np.flatnonzero(dof_slot >= 0)
    order = members[np.argsort(dof_slot[members], kind="stable")]
    dofs = order.reshape(components.size, size)
    position = np.empty(labels.size, dtype=np.int64)
    position[dofs] = np.arange(size)[None, :]
    mine = dof_slot[coo.row] >= 0
    blocks = np.zeros((components.size, size, size))
    np.add.at(
        blocks,
        (dof_slot[coo.row[mine]], position[coo.row[mine]], position[coo.col[mine]]),
        coo.data[mine],
    )
    blocks = 0.5 * (blocks + blocks.transpose(0, 2, 1))
    values, vectors = np.linalg.eigh(blocks)
    return vectors, values, dofs


@dataclass(frozen=True, eq=False)
class DenseCondensation:
    """A dense pencil ``(K, M)`` with its massless directions condensed statically.

    Attributes
    ----------
    stiffness : ndarray, shape (m, m)
        ``K_c = K_mm - K_m0 K_00^-1 K_0m`` in the massive coordinates ``z = Q_m^T x``.
    mass : ndarray, shape (m, m)
        ``B = Q_m^T M Q_m``, positive definite.
    massive, massless : ndarray, shapes (n, m) and (n, n - m)
        ``Q_m`` and ``Q_0``.
    static : ndarray, shape (n - m, m)
        ``K_00^-1 K_0m``: the massless part of a field follows its massive part statically.
    """

    stiffness: np.ndarray
    mass: np.ndarray
    massive: np.ndarray
    massless: np.ndarray
    static: np.ndarray

    def expand(self, z: np.ndarray) -> np.ndarray:
        """Fields on all dofs from massive coordinates, shape (n,) or (n, k)."""
        return self.massive @ z - self.massless @ (self.static @ z)

    def restrict(self, x: np.ndarray) -> np.ndarray:
        """Massive coordinates ``Q_m^T x`` of fields on all dofs."""
        return self.massive.T @ x


def dense_condensation(
    stiffness: np.ndarray, mass: np.ndarray, split: MassSplit | None = None
) -> DenseCondensation:
    """Condense the massless directions of a dense pencil (see :class:`DenseCondensation`).

    ``K_00`` must be regular: a massless mechanism has no finite answer (:func:`pymorembs.
    preparation.prepare` removes those decoupled from the massive dofs).

    Raises
    ------
    NumericalError
        ``K_00`` is singular.
    """
    k = 0.5 * (stiffness + stiffness.T)
    if split is None:
        split = mass_split(mass)
    if not split.singular:
        n = k.shape[0]
        return DenseCondensation(
            k, 0.5 * (mass + mass.T), np.eye(n), np.zeros((n, 0)), np.zeros((0, n))
        )
    qm = split.massive.toarray()
    q0 = split.massless.toarray()
    k_mm, k_m0, k_00 = qm.T @ k @ qm, qm.T @ k @ q0, q0.T @ k @ q0
    try:
        lower = sla.cho_factor(k_00)
    except np.linalg.LinAlgError:
        raise NumericalError(
            f"the stiffness of the {split.n_massless} massless directions is singular or "
            "indefinite: the model has a massless mechanism"
        ) from None
    static = sla.cho_solve(lower, k_m0.T)
    condensed = k_mm - k_m0 @ static
    return DenseCondensation(0.5 * (condensed + condensed.T), split.mass.toarray(), qm, q0, static)


def condensed_dense_eigh(
    stiffness: np.ndarray, mass: np.ndarray, split: MassSplit | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """All finite eigenpairs of a dense pencil ``(K, M)`` with a possibly singular ``M``.

    Parameters
    ----------
    stiffness, mass : ndarray, shape (n, n)
    split : MassSplit, optional
        :func:`mass_split` of ``mass`` if already known.

    Returns
    -------
    eigenvalues : ndarray, shape (m,)
        ``omega^2`` in (rad/s)^2, ascending (``m = rank M``).
    modes : ndarray, shape (n, m)
        Full eigenvectors (massless dofs included), ``X^T M X = I``.
    """
    condensation = dense_condensation(stiffness, mass, split)
    values, z = sla.eigh(condensation.stiffness, condensation.mass)
    return values, condensation.expand(z)
