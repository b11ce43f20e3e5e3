"""The modal assurance criterion (MAC) between two sets of shape functions.

For columns ``v_i`` of ``A`` and ``w_j`` of ``B`` over the same dofs,

    MAC_ij = |v_i^H W w_j|^2 / ((v_i^H W v_i) (w_j^H W w_j)),

with the weight ``W`` the body's mass matrix ``M`` (the mass-weighted MAC: two shape functions
of a structure are alike when they move the same mass the same way, whatever their values at
massless or stiff dofs) or the identity (the plain MAC over all dofs). Values lie in [0, 1];
a basis against itself has 1 on the diagonal. ``M`` stays sparse: the only products are
``M @ A`` and ``M @ B`` (n_dof x k each), never an n_dof x n_dof array.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from pymorembs.errors import UserError

__all__ = ["mac"]


def mac(
    a: np.ndarray, b: np.ndarray, mass: sp.spmatrix | sp.sparray | np.ndarray | None = None
) -> np.ndarray:
    """The MAC between the columns of ``a`` and of ``b``, weighted by ``mass`` if given.

    Parameters
    ----------
    a : ndarray, shape (n_dof, k_a)
        Shape functions (columns); real or complex.
    b : ndarray, shape (n_dof, k_b)
        Shape functions over the same dofs.
    mass : sparse matrix, shape (n_dof, n_dof), optional
        The symmetric positive semi-definite weight, e.g. the body's mass matrix (kg, kg m,
        kg m^2 by dof); None: the plain MAC (the identity).

    Returns
    -------
    ndarray, shape (k_a, k_b)
        MAC_ij in [0, 1]; 0 where a column has zero (mass-weighted) norm.

    Raises
    ------
    UserError
        The bases or the mass matrix do not have the same number of dofs.
    """
    a = np.asarray(a)
    b = np.asarray(b)
    if a.ndim == 1:
        a = a[:, None]
    if b.ndim == 1:
        b = b[:, None]
    if a.ndim != 2 or b.ndim != 2 or a.shape[0] != b.shape[0]:
        raise UserError(f"MAC: the bases have shapes {a.shape} and {b.shape}, not the same dofs")
    if mass is None:
        ma, mb = a, b
    else:
        if mass.shape != (a.shape[0], a.shape[0]):
            raise UserError(
                f"MAC: the mass matrix has shape {mass.shape}, the bases {a.shape[0]} dofs"
            )
        ma, mb = mass @ a, mass @ b
    cross = np.abs(a.conj().T @ mb) ** 2
    norm_a = np.real(np.einsum("ij,ij->j", a.conj(), ma))
    norm_b = np.real(np.einsum("ij,ij->j", b.conj(), mb))
    norms = np.outer(norm_a, norm_b)
    valid = norms > 0
    out = np.zeros(norms.shape)
    out[valid] = cross[valid] / norms[valid]
    return np.clip(out, 0.0, 1.0)
