"""Modal reduction (paper section 3.3): the lowest undamped eigenmodes, mass-normalised.

The eigenproblem ``K phi = omega^2 M phi`` is solved by Lanczos in shift-invert mode about a
shift ``sigma`` slightly below zero, with one sparse factorization of ``K - sigma M``. A negative
shift keeps ``K - sigma M`` positive definite for clamped bodies; free bodies use the
inertia-relief inverse instead (their rigid-body modes are known). Massless dofs are condensed
exactly (:mod:`pymorembs.linalg.mass_split`).
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from pymorembs.errors import NumericalError, UserError
from pymorembs.linalg.factorization import Factorization
from pymorembs.linalg.mass_split import mass_split
from pymorembs.methods import ModalOptions
from pymorembs.reduction.projection import Projection
from pymorembs.system import SecondOrderSystem

#: Default shift frequency: sigma = -(2 pi * 1 Hz)^2 (rad/s)^2.
DEFAULT_SHIFT_HZ = 1.0
#: Modes computed beyond the requested ones for a free body (see :func:`eigenmodes`).
FREE_BODY_GUARD_MODES = 5


def eigenmodes(
    system: SecondOrderSystem,
    count: int,
    shift_hz: float = DEFAULT_SHIFT_HZ,
    elastic_only: bool = False,
    shifted: Factorization | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """The ``count`` lowest eigenpairs of ``(K, M)``.

    A singular mass matrix (massless dofs or directions, see
    :mod:`pymorembs.linalg.mass_split`) is handled by exact static condensation of its massless
    directions: Lanczos runs on the condensed pencil of size ``rank(M)`` in the inner product of
    the massive part, and the eigenvectors are recovered on all dofs with one more solve.

    Parameters
    ----------
    system : SecondOrderSystem
        Sparse full system.
    count : int
        Number of modes, >= 1 (checked by the caller: the ``order`` of
        :class:`~pymorembs.methods.ModalOptions`, or a count the caller computed).
    shift_hz : float
        The shift is ``sigma = -(2 pi shift_hz)^2``.
    elastic_only : bool
        For a free body (``system.rigid_modes`` set): skip its rigid-body modes, return the
        ``count`` lowest elastic modes.
    shifted : Factorization, optional
        The factorization of ``K - sigma M`` (:func:`shifted_factorization` with the same
        ``shift_hz``), when the caller has it already: one factorization for several
        eigen-analyses of the same matrices.

    Returns
    -------
    eigenvalues : ndarray, shape (count,)
        ``omega_i^2`` in (rad/s)^2, ascending.
    modes : ndarray, shape (n, count)
        Mass-normalised modes, ``modes^T M modes = I``.

    Raises
    ------
    UserError
        More modes than the model has (with mass).
    """
    n = system.order
    split = mass_split(system.mass)
    free = elastic_only and system.rigid_modes is not None
    available = split.rank - (system.rigid_modes.shape[1] if free else 0)
    if count >= available:
        if split.singular:
            raise UserError(
                f"{count} modes requested but the model has only {available} "
                f"{'elastic ' if free else ''}modes with mass ({n} independent dofs, "
                f"{split.n_massless} of them massless directions)"
            )
        raise UserError(f"{count} modes requested but the model has only {n} independent dofs")
    sigma = shift_sigma(shift_hz)
    if shifted is None:
        shifted = shifted_factorization(system, shift_hz)
    operator_of_shift = shifted.operator()
    if free:
        # free body: the pencil restricted to the mass-orthogonal complement of its rigid-body
        # modes (Galerkin), by shift-invert with a bordered solve. Neither a shift next to the
        # null space of K (rounding the entries of very stiff parts, light stiff beams or a
        # 10-digit punch, breaks that null space and puts rigid modes at up to 1 Hz, which drag
        # the elastic ones along) nor a support-based inertia relief (which then depends on the
        # supports: 3.6 % on the first elastic mode of a free aircraft from a 10-digit punch).
        operator = _complement_operator(operator_of_shift, system.mass, system.rigid_modes)
        # every copy of a multiple eigenvalue at the edge of the wanted set must be found
        # (rack-beams, Buckens: the 5-fold 460 Hz rod bending and then 474 Hz); guard modes
        # keep such a cluster inside the computed set
        guard = min(FREE_BODY_GUARD_MODES, available - count - 1)
    else:
        operator = operator_of_shift
        guard = 0
    size = split.rank
    mass = system.mass
    if split.singular:  # the condensed pencil (module docstring of mass_split)
        massive, mass = split.massive, split.mass
        full = operator

        def condensed(w: np.ndarray) -> np.ndarray:
            return (massive.T @ full.matmat(massive @ w.reshape(size, -1))).reshape(w.shape)

        operator = spla.LinearOperator((size, size), matvec=condensed, matmat=condensed)
    # a fixed pseudo-random start vector: the same job gives the same modes to the last bit
    # (ARPACK's own random start differs from process to process)
    start = np.random.default_rng(20261122).standard_normal(n)
    if free:  # a start vector in the complement of the rigid-body modes
        start -= system.rigid_modes @ (system.rigid_modes.T @ (system.mass @ start))
    start = split.massive.T @ start if split.singular else start
    wanted = count + guard
    try:
        values, vectors = spla.eigsh(
            operator, k=wanted, M=mass, sigma=sigma, which="LM", OPinv=operator,
            ncv=min(size, max(2 * wanted + 1, wanted + 20)), v0=start,
        )  # fmt: skip
    except spla.ArpackNoConvergence as exc:
        raise NumericalError(
            f"eigenvalue solver did not converge for {count} modes ({exc})"
        ) from None
    order = np.argsort(values)[:count]
    values, vectors = values[order], vectors[:, order]
    if split.singular:  # x = (lambda - sigma) A Q_m B z on all dofs
        vectors = full.matmat(split.massive @ (split.mass @ vectors)) * (values - sigma)
    # eigsh returns M-orthonormal vectors; normalise again against round-off.
    scale = np.sqrt(np.einsum("ij,ij->j", vectors, system.mass @ vectors))
    return values, vectors / scale


def shift_sigma(shift_hz: float) -> float:
    """The shift ``sigma = -(2 pi shift_hz)^2`` in (rad/s)^2 of a shift frequency in Hz."""
    return -((2.0 * np.pi * shift_hz) ** 2)


def shifted_factorization(
    system: SecondOrderSystem, shift_hz: float = DEFAULT_SHIFT_HZ, share_analysis: bool = True
) -> Factorization:
    """The factorization of ``K - sigma M`` that :func:`eigenmodes` uses (unrefined solves:
    ARPACK's own tolerance governs the eigenpairs). ``share_analysis=False``: a PARDISO handle
    of its own, whose solves -- ARPACK's, one vector each -- run on one thread
    (:class:`~pymorembs.linalg.factorization.Factorization`)."""
    sigma = shift_sigma(shift_hz)
    return Factorization(
        [(1.0, system.stiffness), (-sigma, system.mass)],
        label="K - sigma M",
        check=False,
        share_analysis=share_analysis,
    )


def _complement_operator(
    shifted: spla.LinearOperator, mass: sp.spmatrix | np.ndarray, rigid: np.ndarray
) -> spla.LinearOperator:
    """Shift-invert on the mass-orthogonal complement of ``rigid`` (mass-orthonormal, (n, r)).

    ``x = OP w`` solves ``(K - sigma M) x = w + M R mu`` with ``R^T M x = 0``:
    ``x = (I - Y S^-1 (M R)^T) (K - sigma M)^-1 w`` with ``Y = (K - sigma M)^-1 M R`` and
    ``S = (M R)^T Y``, r extra solves once. Its eigenvalues are ``1 / (lambda - sigma)`` of the
    pencil restricted to the complement.
    """
    mr = np.asarray(mass @ rigid)
    y = shifted.matmat(mr)
    s = mr.T @ y

    def apply(w: np.ndarray) -> np.ndarray:
        x = shifted.matmat(w.reshape(w.shape[0], -1))
        x = x - y @ np.linalg.solve(s, mr.T @ x)
        return x.reshape(w.shape)

    return spla.LinearOperator(shifted.shape, matvec=apply, matmat=apply, dtype=float)


def modal_reduction(
    system: SecondOrderSystem, order: int, shift_hz: float = DEFAULT_SHIFT_HZ
) -> Projection:
    """Projection on the ``order`` lowest eigenmodes (``V = W``).

    ``order`` and ``shift_hz`` (Hz) are those of the ``modal`` method, checked by its options
    class :class:`~pymorembs.methods.ModalOptions` (the one check of a job file,
    :func:`pymorembs.reduce` and this function alike); :func:`lowest_modes` computes them.

    Raises
    ------
    OptionError
        A bad argument (:class:`~pymorembs.methods.ModalOptions`, with its message).
    UserError
        More modes than the model has.
    """
    options = ModalOptions(order=order, shift_hz=shift_hz)
    return lowest_modes(system, options.order, options.shift_hz)


def lowest_modes(system: SecondOrderSystem, order: int, shift_hz: float) -> Projection:
    """The projection of :func:`modal_reduction` from checked values (``order >= 1`` modes, the
    shift in Hz >= 0); only what depends on the system is checked here."""
    values, modes = eigenmodes(system, order, shift_hz, elastic_only=True)
    frequencies = np.sqrt(np.clip(values, 0.0, None)) / (2.0 * np.pi)
    return Projection(
        V=modes,
        W=modes,
        method="modal",
        parameters={
            "order": order,
            "shift_hz": shift_hz,
            "highest_mode_hz": float(frequencies[-1]),
        },
    )
