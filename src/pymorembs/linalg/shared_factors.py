"""Sparse factors shared by the steps of one job, within a memory budget.

A job factorizes the same matrices in several steps: ``K`` for the inertia loads, for the
static check of the error reference and for a Krylov expansion point at 0 Hz; ``K - sigma M``
at the expansion points of the reference model and again at the same points of a Krylov or
SOAGA reduction. While :func:`shared_factorizations` is open, every
:class:`~pymorembs.linalg.factorization.Factorization` of the same terms (the same matrix
objects with the same coefficients, on the same backend) takes the factor made first instead
of factorizing again. Factors are kept up to a memory budget (bytes); over it, the factor used
least often goes first (the least recently used among equals, never the one just made): ``K``
serves the inertia loads, the static check, every expansion point at 0 Hz and the static
fields of the body files, while a Craig-Bampton factor of the interior is used once. A factor
larger than the whole budget is not kept.

The key of a matrix is the identity of its arrays (their addresses), and each kept entry holds
its matrices, so an address cannot be reused by another matrix while the entry lives. A
matrix changed in place after it was factorized would be wrong with or without the cache:
pymorembs never does that (its systems are immutable values).
"""

from __future__ import annotations

import contextlib
import threading
from collections import OrderedDict
from collections.abc import Iterator, Sequence
from typing import Any

import numpy as np
import scipy.sparse as sp

from pymorembs.linalg.backends import SparseFactor, default_backend
from pymorembs.parallel import available_memory_bytes

__all__ = ["SharedFactors", "active_shared_factors", "shared_factorizations"]

#: Default budget of :func:`shared_factorizations`: this fraction of the memory available when
#: it opens. A 300k-dof tet10 part's real factor of ``K - sigma M`` holds 1-2 GB; the job
#: around it needed about 8 GB with one complex factor at a time, which the checks from real
#: factors no longer make.
DEFAULT_BUDGET_FRACTION = 0.4

Key = tuple[Any, ...]

_ACTIVE: list[SharedFactors] = []
_LOCK = threading.Lock()


def matrix_identity(matrix: Any) -> tuple[Any, ...]:
    """The identity of a matrix's storage: format, shape and the addresses of its arrays."""
    if sp.issparse(matrix):
        arrays = [getattr(matrix, name, None) for name in ("data", "indices", "indptr")]
        addresses = tuple(a.__array_interface__["data"][0] for a in arrays if a is not None)
        return (matrix.format, matrix.shape, matrix.nnz, addresses)
    array = np.asarray(matrix)
    return ("dense", array.shape, array.dtype.str, array.__array_interface__["data"][0])


class SharedFactors:
    """The factors kept for reuse by one job (see the module docstring).

    Parameters
    ----------
    budget_bytes : float
        Most memory the kept factors may hold (their
        :attr:`~pymorembs.linalg.backends.SparseFactor.held_bytes`), bytes.

    Attributes
    ----------
    made : int
        Factors made while the cache was open (each a real factorization).
    reused : int
        Factorizations served from the cache instead.
    dropped : int
        Factors dropped to stay within the budget (or too large to keep).
    """

    def __init__(self, budget_bytes: float) -> None:
        self.budget_bytes = float(budget_bytes)
        self.made = 0
        self.reused = 0
        self.dropped = 0
        self._entries: OrderedDict[Key, tuple[list[tuple[complex, Any]], SparseFactor]] = (
            OrderedDict()
        )
        self._uses: dict[Key, int] = {}

    @staticmethod
    def key(terms: Sequence[tuple[complex, Any]], symmetric: bool, backend: str | None) -> Key:
        """The key of a factorization of ``sum_i c_i A_i`` (the terms in their order)."""
        parts = tuple((complex(c), matrix_identity(m)) for c, m in terms)
        return (parts, bool(symmetric), backend or default_backend())

    @property
    def bytes_held(self) -> int:
        """Memory of the factors kept now, bytes."""
        return sum(factor.held_bytes for _, factor in self._entries.values())

    def __len__(self) -> int:
        return len(self._entries)

    def get(self, key: Key) -> SparseFactor | None:
        """The factor kept under ``key`` (then the most recently used), or None."""
        with _LOCK:
            entry = self._entries.get(key)
            if entry is None:
                return None
            self._entries.move_to_end(key)
            self._uses[key] += 1
            self.reused += 1
            return entry[1]

    def put(self, key: Key, terms: Sequence[tuple[complex, Any]], factor: SparseFactor) -> None:
        """Keep a newly made factor, dropping the least used ones (the least recently used
        among equals) while over the budget; the new factor itself stays."""
        with _LOCK:
            self.made += 1
            if factor.held_bytes > self.budget_bytes:
                self.dropped += 1
                return
            self._entries[key] = (list(terms), factor)
            self._uses[key] = 1
            while self.bytes_held > self.budget_bytes:
                # entries run from least to most recently used: min keeps the first of equals
                victim = min((k for k in self._entries if k != key), key=self._uses.__getitem__)
                del self._entries[victim], self._uses[victim]
                self.dropped += 1

    def real_shifts(self, stiffness: Any, mass: Any) -> list[tuple[float, SparseFactor]]:
        """The kept real factors of ``K - tau M`` (``K`` alone: ``tau = 0``) of these matrices,
        as ``(tau, factor)`` with ``tau`` in (rad/s)^2, most recently used last."""
        k_id, m_id = matrix_identity(stiffness), matrix_identity(mass)
        found = []
        for (parts, _, _), (_, factor) in self._entries.items():
            if factor.dtype.kind == "c" or not parts or parts[0] != (1.0, k_id):
                continue
            if len(parts) == 1:
                found.append((0.0, factor))
            elif len(parts) == 2 and parts[1][1] == m_id and parts[1][0].imag == 0.0:
                found.append((-parts[1][0].real, factor))
        return found

    def clear(self) -> None:
        """Drop every kept factor (their memory is freed when no solver uses them)."""
        with _LOCK:
            self._entries.clear()
            self._uses.clear()


def active_shared_factors() -> SharedFactors | None:
    """The innermost open :func:`shared_factorizations` cache, or None."""
    return _ACTIVE[-1] if _ACTIVE else None


@contextlib.contextmanager
def shared_factorizations(budget_bytes: float | None = None) -> Iterator[SharedFactors]:
    """Share equal factorizations within the block, keeping at most ``budget_bytes`` of factors
    (default :data:`DEFAULT_BUDGET_FRACTION` of the memory available now).

    The factors are dropped when the block ends.

    Examples
    --------
    >>> with shared_factorizations(2e9) as shared:   # doctest: +SKIP
    ...     Factorization(k); Factorization(k)       # one factorization, then the same factor
    >>> shared.made, shared.reused                   # doctest: +SKIP
    (1, 1)
    """
    if budget_bytes is None:
        budget_bytes = DEFAULT_BUDGET_FRACTION * available_memory_bytes()
    cache = SharedFactors(budget_bytes)
    _ACTIVE.append(cache)
    try:
        yield cache
    finally:
        _ACTIVE.remove(cache)
        cache.clear()
