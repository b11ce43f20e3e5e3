"""Frequency responses ``H(i omega) = C (-omega^2 M + i omega D + (1 + i eta) K)^{-1} B``.

Full (sparse) systems: one sparse factorization per frequency, all inputs solved in one block,
never a dense inverse. Reduced (dense) systems: batched dense solves, or a closed form when the
reduced model is in modal form (identity mass, diagonal stiffness and damping).
"""

from __future__ import annotations

import numpy as np

from pymorembs.linalg.factorization import Factorization
from pymorembs.linalg.inertia_relief import InertiaRelief
from pymorembs.system import SecondOrderSystem


def transfer_function(system: SecondOrderSystem, frequencies_hz: np.ndarray) -> np.ndarray:
    """Frequency response matrix at each frequency.

    Parameters
    ----------
    system : SecondOrderSystem
        Full sparse or reduced dense system.
    frequencies_hz : ndarray, shape (n_f,)
        Frequencies in Hz (omega = 2 pi f).

    Returns
    -------
    ndarray, complex, shape (n_f, n_outputs, n_inputs)
    """
    frequencies_hz = np.asarray(frequencies_hz, dtype=float).ravel()
    if system.is_sparse:
        return _sparse_response(system, frequencies_hz)
    return _dense_response(system, frequencies_hz)


def _sparse_response(system: SecondOrderSystem, frequencies_hz: np.ndarray) -> np.ndarray:
    out = np.zeros((frequencies_hz.size, system.n_outputs, system.n_inputs), dtype=complex)
    # inputs/outputs on fixed dofs are zero columns of B / rows of C: nothing to solve for
    cols = np.flatnonzero(np.any(system.input_matrix != 0, axis=0))
    rows = np.flatnonzero(np.any(system.output_matrix != 0, axis=1))
    if cols.size == 0 or rows.size == 0:
        return out
    b = system.input_matrix[:, cols]
    c = system.output_matrix[rows]
    for k, f in enumerate(frequencies_hz):
        terms, scale = system.dynamic_terms(2j * np.pi * f)
        label = f"dynamic stiffness at {f:g} Hz"
        if f == 0 and system.rigid_modes is not None:  # free body: static solve by inertia relief
            factorization = InertiaRelief(system.stiffness, system.mass, system.rigid_modes, label)
        else:
            factorization = Factorization(terms, label=label)
        out[k][np.ix_(rows, cols)] = (c @ factorization.solve(b)) / scale
    return out


def _dense_response(system: SecondOrderSystem, frequencies_hz: np.ndarray) -> np.ndarray:
    s = 2j * np.pi * frequencies_hz
    m, k, d = system.mass, system.stiffness, system.damping
    k_factor = 1.0 + 1j * system.loss_factor
    b, c = system.input_matrix, system.output_matrix
    diagonal = _is_diagonal(m) and _is_diagonal(k) and (d is None or _is_diagonal(d))
    if diagonal:
        dd = np.zeros(m.shape[0]) if d is None else np.diag(d)
        denom = s[:, None] ** 2 * np.diag(m) + s[:, None] * dd + k_factor * np.diag(k)
        return np.einsum("ri,fi,ip->frp", c, 1.0 / denom, b)
    out = np.empty((s.size, c.shape[0], b.shape[1]), dtype=complex)
    for j, s_j in enumerate(s):  # one small dense solve per frequency, no (n_f, n, n) array
        a = s_j**2 * m + k_factor * k
        if d is not None:
            a = a + s_j * d
        out[j] = c @ np.linalg.solve(a, b)
    return out


def _is_diagonal(matrix: np.ndarray, tol: float = 1e-12) -> bool:
    """Off-diagonal entries below ``tol`` times the largest diagonal entry."""
    off = matrix - np.diag(np.diag(matrix))
    return bool(np.abs(off).max(initial=0.0) <= tol * np.abs(np.diag(matrix)).max(initial=0.0))
