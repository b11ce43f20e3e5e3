"""The mass-weighted MAC against a dense computation on a small model, and its properties."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.linalg as sla
import scipy.sparse as sp

from pymorembs import UserError, example
from pymorembs.analysis import mac


@pytest.fixture(scope="module")
def blade():
    """The blade with 4 elements (423 dofs, 63 fixed) and its first 10 modes from a dense
    eigensolution of the free dofs, zero on the fixed ones."""
    body = example("blade", elements=4)
    free = np.setdiff1d(np.arange(body.n_dof), body.fixed)
    K = body.stiffness.toarray()[np.ix_(free, free)]
    M = body.mass.toarray()[np.ix_(free, free)]
    _, modes = sla.eigh(K, M, subset_by_index=(0, 9))
    V = np.zeros((body.n_dof, 10))
    V[free] = modes
    return body, V


def dense_mac(a: np.ndarray, b: np.ndarray, M: np.ndarray) -> np.ndarray:
    """MAC_ij = |a_i^H M b_j|^2 / ((a_i^H M a_i)(b_j^H M b_j)), entry by entry."""
    out = np.zeros((a.shape[1], b.shape[1]))
    for i in range(a.shape[1]):
        for j in range(b.shape[1]):
            x, y = a[:, i], b[:, j]
            norms = (x.conj() @ M @ x).real * (y.conj() @ M @ y).real
            out[i, j] = abs(x.conj() @ M @ y) ** 2 / norms
    return out


def test_mass_weighted_mac_is_the_dense_formula(blade):
    body, V = blade
    rng = np.random.default_rng(3)
    W = V @ rng.normal(size=(10, 7)) + 0.05 * rng.normal(size=(body.n_dof, 7))
    dense = dense_mac(V, W, body.mass.toarray())
    assert np.allclose(mac(V, W, body.mass), dense, rtol=1e-10, atol=1e-14)
    assert np.allclose(mac(V, W), dense_mac(V, W, np.eye(body.n_dof)), rtol=1e-10, atol=1e-14)
    # complex shapes: the conjugate transpose
    Z = W + 1j * (V @ rng.normal(size=(10, 7)))
    assert np.allclose(mac(V, Z, body.mass), dense_mac(V, Z, body.mass.toarray()), rtol=1e-10)


def test_modes_against_themselves(blade):
    body, V = blade
    weighted = mac(V, V, body.mass)
    assert np.allclose(np.diag(weighted), 1.0, atol=1e-12)
    # the modes are M-orthogonal: the mass-weighted MAC is the identity ...
    assert np.abs(weighted - np.eye(10)).max() < 1e-10
    # ... and the plain one is not (the dofs are translations and rotations of unequal mass)
    assert np.abs(mac(V, V) - np.eye(10)).max() > 1e-3
    assert np.allclose(np.diag(mac(V, V)), 1.0, atol=1e-12)
    # scaling a column changes nothing
    assert np.allclose(mac(V * np.arange(1, 11), -3 * V, body.mass), weighted, atol=1e-12)


def test_zero_columns_and_wrong_sizes(blade):
    body, V = blade
    A = V.copy()
    A[:, 2] = 0.0
    out = mac(A, V, sp.csr_matrix(body.mass))
    assert np.all(out[2] == 0.0) and out[0, 0] == pytest.approx(1.0)
    with pytest.raises(UserError, match="not the same dofs"):
        mac(V, V[:-1])
    with pytest.raises(UserError, match="the mass matrix has shape"):
        mac(V, V, body.mass[:-1, :-1])
