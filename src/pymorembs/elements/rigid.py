"""Rigid bodies: cross-product matrices and the 6x6 mass matrix at a reference node."""

from __future__ import annotations

import numpy as np


def skew(v: np.ndarray) -> np.ndarray:
    """Cross-product matrices ``[v]x`` (``[v]x w = v x w``), shape (..., 3) -> (..., 3, 3)."""
    v = np.asarray(v, dtype=float)
    zero = np.zeros(v.shape[:-1])
    x, y, z = v[..., 0], v[..., 1], v[..., 2]
    return np.stack(
        [np.stack([zero, -z, y], -1), np.stack([z, zero, -x], -1), np.stack([-y, x, zero], -1)],
        axis=-2,
    )


def rigid_body_mass_matrix(mass: float, inertia: np.ndarray, offset: np.ndarray) -> np.ndarray:
    """6×6 mass matrix of a rigid body in the dofs (u, theta) of a reference node.

    Parameters
    ----------
    mass : float
        Mass ``m`` (kg).
    inertia : ndarray, shape (3, 3)
        Inertia tensor ``J_G`` about the centre of gravity (kg·m²).
    offset : ndarray, shape (3,)
        Centre of gravity minus reference node position, ``c`` (m).

    Returns
    -------
    ndarray, shape (6, 6)
        ``[[m I, -m [c]x], [m [c]x, J_G - m [c]x [c]x]]`` (kg, kg·m, kg·m²).
    """
    c = skew(offset)
    return np.block([[mass * np.eye(3), -mass * c], [mass * c, np.asarray(inertia) - mass * c @ c]])
