"""Orthonormal bases with reorthogonalisation and rank-revealing deflation."""

from __future__ import annotations

import numpy as np


class OrthonormalBasis:
    """An orthonormal basis (Euclidean inner product) grown block by block.

    Each new block is orthogonalised twice against the basis (classical Gram-Schmidt with
    reorthogonalisation, "twice is enough"), then split by an SVD into directions that are new
    and directions that lie in the span already within the tolerance (deflation). Directions of
    a block enter in order of decreasing singular value, so a basis cut at a given size keeps the
    dominant part of the last block.

    Parameters
    ----------
    n : int
        Length of the vectors.
    tol : float
        A direction is deflated when, after scaling the block's columns to unit norm and
        orthogonalising, its singular value is below ``tol``.
    dtype : numpy dtype
        ``float`` or ``complex``.
    """

    def __init__(self, n: int, tol: float = 1e-10, dtype: type = float) -> None:
        self.n = n
        self.tol = tol
        # columns in Fortran order with room to grow: adding a block copies the block only, not
        # the whole basis, and the first ``size`` columns are one contiguous array for BLAS
        self._storage = np.zeros((n, 0), dtype=dtype, order="F")
        self._size = 0

    @property
    def size(self) -> int:
        return self._size

    @property
    def matrix(self) -> np.ndarray:
        """The basis, shape (n, size), with orthonormal columns (a view, Fortran order)."""
        return self._storage[:, : self._size]

    def orthogonalize(self, block: np.ndarray, passes: int = 2) -> np.ndarray:
        """The block minus its projection on the basis, ``passes`` times (block classical
        Gram-Schmidt, two BLAS-3 products per pass)."""
        q = self.matrix
        for _ in range(passes):
            # (q^H b) without copying the conjugate of the whole basis
            coefficients = (block.conj().T @ q).conj().T if np.iscomplexobj(q) else q.T @ block
            block = block - q @ coefficients
        return block

    def add(
        self, block: np.ndarray, limit: int | None = None, reference: float = 0.0
    ) -> np.ndarray:
        """Add the new directions of ``block`` (n, k); return them, shape (n, k_new).

        Every column is scaled to unit norm first, so a direction is judged new or not by its
        own size, not by the largest column of the block (a weak input must not be deflated
        because another input is strong). Columns whose norm is below ``tol * reference`` are
        dropped as round-off (e.g. the part of unit vectors that should be zero). At most
        ``limit`` directions are added (the dominant ones).
        """
        block = np.asarray(block)
        if block.ndim == 1:
            block = block[:, None]
        norms = np.linalg.norm(block, axis=0)
        keep = np.isfinite(norms) & (norms > self.tol * reference) & (norms > 0)
        if not np.any(keep) or (limit is not None and limit <= 0):
            return block[:, :0]
        block = block[:, keep] / norms[keep]
        rest = self.orthogonalize(block)
        u, s, _ = np.linalg.svd(rest, full_matrices=False)
        count = int(np.count_nonzero(s > self.tol))
        if limit is not None:
            count = min(count, limit)
        # guard against loss of orthogonality: ``u = rest v / s`` magnifies what is left of the
        # basis in ``rest`` (~1e-16) by up to 1 / tol; one pass takes a unit vector that is
        # that close to orthogonal down to round-off (it loses nothing to cancellation)
        new = self.orthogonalize(u[:, :count], passes=1)
        new, _ = np.linalg.qr(new)
        self._append(new)
        return new

    def _append(self, new: np.ndarray) -> None:
        """Store the columns ``new`` (n, k) after the basis, growing the storage by half."""
        k = new.shape[1]
        if self._size + k > self._storage.shape[1]:
            capacity = min(self.n, max(self._size + k, self._storage.shape[1] * 3 // 2, 8))
            grown = np.empty((self.n, capacity), dtype=self._storage.dtype, order="F")
            grown[:, : self._size] = self._storage[:, : self._size]
            self._storage = grown
        self._storage[:, self._size : self._size + k] = new
        self._size += k
