"""Static solves of free bodies by inertia relief, without factorizing a singular matrix.

The stiffness ``K`` of a free body is singular: ``K R = 0`` for its rigid-body modes ``R``. For a
load with no rigid-body part (``R^T f = 0``, self-equilibrated) ``K x = f`` has one solution that
is mass-orthogonal to the rigid-body modes (``R^T M x = 0``): the elastic deformation of the
Buckens frame. It is found by holding six dofs that suppress the rigid motion and nothing else
(a statically determinate support, chosen by column-pivoted QR of ``R^T`` so that ``R`` restricted
to them is well conditioned): the support reactions of a self-equilibrated load vanish, so the
supported solution differs from the wanted one by a rigid motion only, which is then removed.
General loads are first made self-equilibrated, ``f - M R R^T f`` (the inertia relief: the
d'Alembert forces of the rigid-body acceleration the load would cause).
"""

from __future__ import annotations

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from pymorembs.linalg.factorization import PLAIN_ENOUGH, Factorization

#: Most Galerkin refinement steps of a static solve (each: one product with ``K``, one solve).
GALERKIN_STEPS = 40
#: The projected residual ``P^T (f - K x)`` at which a static solve is done, relative to ``f``.
GALERKIN_TOL = 1e-13
#: ... or relative to ``| |K| |x| |``: the rounding floor of the residual itself.
ROUNDING_FLOOR = 16 * np.finfo(float).eps


class InertiaRelief:
    """``x = K^+ f``: the M-orthogonal static deformation of a free body.

    The supported solve is exact when ``K R = 0``. When it is not quite (the entries of ``K``
    rounded by an export to 10 digits: rigid-body eigenvalues at +-1 Hz of a free aircraft), the
    supported solution depends on the supports -- by 8 % there. The solve therefore refines it
    to the Galerkin solution on the mass-orthogonal complement of ``R``, which does not depend
    on them: ``x in span(R)^perp_M`` with ``P^T (f - K x) = 0``, ``P^T = I - M R R^T``, by
    ``x <- x + K_s^+ P^T (f - K x)`` with the supported solve ``K_s^+`` as preconditioner
    (a factor 10 per step there; for an exact model the first residual is at rounding level and
    nothing is added).

    Parameters
    ----------
    stiffness, mass : sparse matrix, shape (n, n)
    rigid_modes : ndarray, shape (n, r)
        Rigid-body modes, mass-orthonormal (``R^T M R = I``).
    label : str
        For error messages.
    plain_enough : float
        See :class:`~pymorembs.linalg.factorization.Factorization`.
    """

    def __init__(
        self,
        stiffness: sp.spmatrix,
        mass: sp.spmatrix,
        rigid_modes: np.ndarray,
        label: str,
        plain_enough: float = PLAIN_ENOUGH,
    ) -> None:
        self.stiffness = stiffness
        self._abs: sp.csr_matrix | None = None
        self.mass = mass
        self.rigid = rigid_modes
        n, r = rigid_modes.shape
        _, _, pivots = sla.qr(rigid_modes.T, mode="economic", pivoting=True)
        self.support = np.sort(pivots[:r])
        self.free = np.setdiff1d(np.arange(n), self.support)
        held = sp.csr_matrix(stiffness)[self.free][:, self.free]
        self.factorization = Factorization(
            held, label=f"{label} (inertia relief)", plain_enough=plain_enough
        )
        self.shape = (n, n)

    def equilibrate(self, loads: np.ndarray) -> np.ndarray:
        """The self-equilibrated part ``f - M R R^T f`` of loads, shape (n,) or (n, k)."""
        return loads - self.mass @ (self.rigid @ (self.rigid.T @ loads))

    def solve(self, loads: np.ndarray) -> np.ndarray:
        """Static deformation under the self-equilibrated part of ``loads`` (Galerkin)."""
        balanced = self.equilibrate(np.asarray(loads))
        x = self._supported(balanced)
        scale = np.linalg.norm(balanced)
        previous = np.inf
        for step in range(GALERKIN_STEPS):
            residual = self.equilibrate(balanced - self.stiffness @ x)
            size = np.linalg.norm(residual)
            if size <= GALERKIN_TOL * scale or size > 0.5 * previous:
                break  # done, or stagnating
            # a first residual at the rounding floor of K x (~eps |K| |x|) needs no refinement:
            # an exact model with very stiff parts (light stiff beams)
            if step == 0 and size <= ROUNDING_FLOOR * np.linalg.norm(self._absolute() @ np.abs(x)):
                break
            previous = size
            x = x + self._supported(residual)
        return x

    def _absolute(self) -> sp.csr_matrix:
        """``|K|``, made when a refinement first needs its rounding floor."""
        if self._abs is None:
            self._abs = abs(sp.csr_matrix(self.stiffness))
        return self._abs

    def _supported(self, balanced: np.ndarray) -> np.ndarray:
        """The supported solve of a self-equilibrated load, made M-orthogonal to ``R``."""
        x = np.zeros_like(balanced)
        x[self.free] = self.factorization.solve(balanced[self.free])
        return x - self.rigid @ (self.rigid.T @ (self.mass @ x))

    def operator(self) -> spla.LinearOperator:
        """``K^+`` as a :class:`scipy.sparse.linalg.LinearOperator` (for ``eigsh``)."""
        return spla.LinearOperator(self.shape, matvec=self.solve, matmat=self.solve, dtype=float)
