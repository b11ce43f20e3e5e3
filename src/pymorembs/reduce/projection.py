"""The common result of every reduction method: a projection ``q = V q_bar`` with test space W.

Every reductor returns a :class:`Projection`; :func:`reduced_model` applies it (paper eq. 3-4),
post-processes the basis so that the reduced mass is the identity and the reduced stiffness
diagonal, adds the damping model, and checks the result before anyone writes it.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np
import scipy.linalg as sla

from pymorembs.errors import NumericalError
from pymorembs.linalg.products import extended_product
from pymorembs.system import SecondOrderSystem


@dataclass(frozen=True, eq=False)
class Projection:
    """Bases of a Petrov-Galerkin projection.

    Attributes
    ----------
    V : ndarray, shape (n, order)
        Trial basis: ``q = V q_bar`` (independent dofs).
    W : ndarray, shape (n, order)
        Test basis; the same object as ``V`` for a one-sided (orthogonal) projection.
    method : str
        Name of the method (``"modal"``, ``"krylov"``...).
    parameters : dict
        Settings the method was run with and facts it found (JSON-serialisable).
    error_estimate : float or None
        Estimated max relative error on the band, for methods that have one.
    error_bound : float or None
        A-priori error bound, for methods that have one.
    error_curve : (ndarray, ndarray) or None
        ``(frequencies_hz, estimate)``: an error estimator as a function of frequency (SOAGA),
        both shape (n_f,), for plots next to the true error.
    """

    V: np.ndarray
    W: np.ndarray
    method: str
    parameters: dict[str, Any] = field(default_factory=dict)
    error_estimate: float | None = None
    error_bound: float | None = None
    error_curve: tuple[np.ndarray, np.ndarray] | None = None

    @property
    def order(self) -> int:
        return int(self.V.shape[1])

    @property
    def one_sided(self) -> bool:
        return self.W is self.V


@dataclass(frozen=True, eq=False)
class ReducedModel:
    """A reduced second-order model and the projection it came from.

    Attributes
    ----------
    projection : Projection
        With ``V`` (and ``W``) post-processed: ``V^T M V = I`` and ``V^T K V = diag(omega^2)``.
    system : SecondOrderSystem
        Dense reduced system ``(M_bar, D_bar, K_bar, B_bar, C_bar)``.
    eigenfrequencies_hz : ndarray, shape (order,)
        Undamped eigenfrequencies of the reduced model, Hz.
    """

    projection: Projection
    system: SecondOrderSystem
    eigenfrequencies_hz: np.ndarray

    @property
    def damping_matrix(self) -> np.ndarray:
        """Viscous damping of the reduced model for simulation, shape (order, order).

        The projected viscous damping (Rayleigh, explicit) plus, for a modal damping ratio xi,
        ``diag(2 xi omega_bar_i)`` in the reduced eigenbasis (paper eq. 25). The frequency
        responses use the loss factor instead (see :class:`pymorembs.body.Damping`).
        """
        system = self.system
        damping = np.zeros_like(system.mass) if system.damping is None else system.damping
        omega = 2.0 * np.pi * self.eigenfrequencies_hz
        return damping + np.diag(2.0 * system.modal_damping_ratio * omega)


def reduced_model(system: SecondOrderSystem, projection: Projection) -> ReducedModel:
    """Project ``system``, diagonalise, add damping and check (paper section 2.3).

    For a one-sided projection the reduced eigenproblem ``K_bar x = lambda M_bar x`` is solved and
    ``V <- V X``, which makes ``M_bar = I`` and ``K_bar = diag(omega_bar_i^2)`` -- the block
    diagonal form the paper asks for, exactly the modal form for simulation. Rayleigh and
    explicit damping are projected; a modal damping ratio gives
    :attr:`ReducedModel.damping_matrix`.
    """
    if not projection.one_sided:
        raise NotImplementedError("oblique projections come with the two-sided methods")
    v = projection.V
    if not np.all(np.isfinite(v)):
        raise NumericalError(f"{projection.method}: basis has NaN or infinite entries")
    if system.rigid_modes is not None:
        v = _elastic_part(v, system, projection.method)
    first = system.project(v)
    eigenvalues, vectors = _reduced_eigenproblem(first.stiffness, first.mass, projection.method)
    v = v @ vectors
    reduced = system.project(v)
    # V^T M V = I and V^T K V = diag(lambda) up to round-off: make them exact.
    eigenvalues = np.where(
        np.abs(eigenvalues) < 1e-12 * np.abs(eigenvalues).max(), 0.0, eigenvalues
    )
    reduced = replace(reduced, mass=np.eye(v.shape[1]), stiffness=np.diag(eigenvalues))
    reduced.check_reduced()
    if system.rigid_modes is not None:
        # once more on the final, mass-normalised basis: the eigen-transformation amplifies the
        # round-off of stiff directions. K R = 0, R^T B_e = 0 and C_e R = 0, so this changes
        # none of the reduced matrices (V^T M V only by the square of the removed part).
        v = v - system.rigid_modes @ (system.rigid_modes.T @ extended_product(system.mass, v))
    new_projection = replace(projection, V=v, W=v)
    frequencies = np.sqrt(np.clip(eigenvalues, 0.0, None)) / (2.0 * np.pi)
    return ReducedModel(new_projection, reduced, frequencies)


def _elastic_part(v: np.ndarray, system: SecondOrderSystem, method: str) -> np.ndarray:
    """The basis made mass-orthogonal to the rigid-body modes (Buckens frame, eq. 6).

    ``V <- V - R R^T M V`` twice (reorthogonalisation), then orthonormalised again; a direction
    that was (nearly) rigid is an error, not silently dropped.
    """
    rigid = system.rigid_modes
    for _ in range(2):
        v = v - rigid @ (rigid.T @ extended_product(system.mass, v))
    q, r = np.linalg.qr(v)
    diagonal = np.abs(np.diag(r))
    if diagonal.min() < 1e-8 * diagonal.max():
        raise NumericalError(
            f"{method}: the basis contains (nearly) rigid-body motions; it has only "
            f"{int(np.count_nonzero(diagonal >= 1e-8 * diagonal.max()))} elastic directions"
        )
    return q


def _reduced_eigenproblem(
    stiffness: np.ndarray, mass: np.ndarray, method: str
) -> tuple[np.ndarray, np.ndarray]:
    """Eigenpairs of ``K_bar x = lambda M_bar x`` with ``X^T M_bar X = I``, ascending.

    When ``K_bar`` is positive definite the flexibility form ``M_bar y = mu K_bar y`` is solved
    (``lambda = 1 / mu``): its absolute errors are relative to the largest ``mu``, so the small
    eigenvalues -- which carry the static and low-frequency response -- are accurate to working
    precision even when the basis also holds stiff directions (Krylov bases span static
    deflections with their high-frequency content). Otherwise (rigid-body modes) the direct form.
    """
    try:
        mu, y = sla.eigh(mass, stiffness)
    except np.linalg.LinAlgError:
        mu = None
    if mu is not None and mu.min() > 0:
        eigenvalues = 1.0 / mu[::-1]
        return eigenvalues, y[:, ::-1] * np.sqrt(eigenvalues)
    try:
        return sla.eigh(stiffness, mass)
    except np.linalg.LinAlgError as exc:
        raise NumericalError(
            f"{method}: reduced mass matrix is not positive definite ({exc})"
        ) from None
