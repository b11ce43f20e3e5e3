"""Modal reduction (paper section 3.3): the lowest undamped eigenmodes, mass-normalised.

The eigenproblem ``K phi = omega^2 M phi`` is solved by Lanczos in shift-invert mode about a
shift ``sigma`` slightly below zero, with one sparse factorization of ``K - sigma M``. A negative
shift keeps ``K - sigma M`` positive definite for free bodies too (rigid-body modes at 0 Hz).
"""

from __future__ import annotations

import numpy as np
import scipy.sparse.linalg as spla

from pymorembs.errors import NumericalError, UserError
from pymorembs.linalg.factorization import Factorization
from pymorembs.linalg.inertia_relief import InertiaRelief
from pymorembs.reduce.projection import Projection
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
) -> tuple[np.ndarray, np.ndarray]:
    """The ``count`` lowest eigenpairs of ``(K, M)``.

    Parameters
    ----------
    system : SecondOrderSystem
        Sparse full system.
    count : int
        Number of modes.
    shift_hz : float
        The shift is ``sigma = -(2 pi shift_hz)^2``.
    elastic_only : bool
        For a free body (``system.rigid_modes`` set): skip its rigid-body modes, return the
        ``count`` lowest elastic modes.

    Returns
    -------
    eigenvalues : ndarray, shape (count,)
        ``omega_i^2`` in (rad/s)^2, ascending.
    modes : ndarray, shape (n, count)
        Mass-normalised modes, ``modes^T M modes = I``.
    """
    n = system.order
    if count < 1:
        raise UserError(f"number of modes must be at least 1, got {count}")
    if count >= n:
        raise UserError(f"{count} modes requested but the model has only {n} independent dofs")
    if elastic_only and system.rigid_modes is not None:
        # free body: shift-invert about 0 with the inertia-relief inverse K^+, which maps the
        # rigid-body modes to zero. A shift next to the null space of K would not do: rounding
        # the entries of very stiff parts (light stiff beams, E = 1e18) breaks that null space,
        # and rigid modes came out at up to 0.4 Hz, dragging the elastic ones along.
        sigma = 0.0
        operator = InertiaRelief(
            system.stiffness, system.mass, system.rigid_modes, "K (free body)"
        ).operator()
        # the refined inertia-relief solves are exact to working precision, which leaves ARPACK
        # no rounding noise to find every copy of a multiple eigenvalue at the edge of the wanted
        # set (rack-beams, Buckens: 2 of the 5-fold 460 Hz rod bending and then 474 Hz); guard
        # modes keep such a cluster inside the computed set
        guard = min(FREE_BODY_GUARD_MODES, n - count - 1)
    else:
        guard = 0
        sigma = -((2.0 * np.pi * shift_hz) ** 2)
        # ARPACK needs no refined solves: its own tolerance governs the eigenpairs
        operator = Factorization(
            [(1.0, system.stiffness), (-sigma, system.mass)], label="K - sigma M", check=False
        ).operator()
    # a fixed pseudo-random start vector: the same job gives the same modes to the last bit
    # (ARPACK's own random start differs from process to process)
    start = np.random.default_rng(20261122).standard_normal(n)
    try:
        values, vectors = spla.eigsh(
            system.stiffness, k=count + guard, M=system.mass, sigma=sigma, which="LM",
            OPinv=operator, ncv=min(n, max(2 * (count + guard) + 1, count + guard + 20)),
            v0=start,
        )  # fmt: skip
    except spla.ArpackNoConvergence as exc:
        raise NumericalError(
            f"eigenvalue solver did not converge for {count} modes ({exc})"
        ) from None
    order = np.argsort(values)[:count]
    values, vectors = values[order], vectors[:, order]
    # eigsh returns M-orthonormal vectors; normalise again against round-off.
    scale = np.sqrt(np.einsum("ij,ij->j", vectors, system.mass @ vectors))
    return values, vectors / scale


def modal_reduction(
    system: SecondOrderSystem, order: int, shift_hz: float = DEFAULT_SHIFT_HZ
) -> Projection:
    """Projection on the ``order`` lowest eigenmodes (``V = W``)."""
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
