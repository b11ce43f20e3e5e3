"""Neweul-M² export: a .mat file of SID invariants, checked against point-mass dynamics."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
import scipy.io
from test_invariants import cross_matrix, lumped_body

from pymorembs.errors import NumericalError
from pymorembs.export.invariants import compute_invariants
from pymorembs.export.neweul import FORMAT, FORMAT_VERSION, write_neweul
from pymorembs.export.sid import read_sid, write_sid


@pytest.fixture(scope="module")
def lumped(tmp_path_factory):
    body, phi, m, _ = lumped_body(n_nodes=10, nq=3, seed=7)
    inv = compute_invariants(
        body, phi, phi.T @ (body.mass @ phi), np.diag([4e2, 9e2, 2e3]), None, [107, 135],
        name="lumped",
    )  # fmt: skip
    folder = tmp_path_factory.mktemp("neweul")
    path = write_neweul(folder / "lumped", inv)  # no suffix: written exactly there
    return body, phi, m, inv, path, folder


def test_fields_shapes_and_format(lumped):
    *_, inv, path, folder = lumped
    assert sorted(p.name for p in folder.iterdir()) == ["lumped"]
    data = scipy.io.loadmat(path, squeeze_me=False)
    nq = inv.nq
    shapes = {
        "mass": (1, 1), "nq": (1, 1), "mdCM0": (3, 1), "mdCM1": (3, nq), "cog": (3, 1),
        "J0": (3, 3), "J1": (3, 3, nq), "Ct0": (nq, 3), "Cr0": (nq, 3), "Cr1": (nq, nq, 3),
        "Me": (nq, nq), "Gr0": (3, 3, nq), "Ge0": (nq, nq, 3), "Oe0": (nq, 6),
        "Oe1": (nq, nq, 6), "ksigma": (nq, 1), "Ke": (nq, nq), "De": (nq, nq),
        "frequencies_hz": (nq, 1), "nodes": (1, 2),
    }  # fmt: skip
    assert {name: data[name].shape for name in shapes} == shapes
    cells = scipy.io.loadmat(path, simplify_cells=True)
    assert cells["format"] == FORMAT and cells["version"] == FORMAT_VERSION
    assert cells["generator"].startswith("pymorembs ") and cells["name"] == "lumped"
    assert cells["second_order_mass"] == "exact"
    assert cells["Omega_order"] == "wx^2 wy^2 wz^2 wx*wy wy*wz wx*wz"
    node = cells["nodes"][1]
    assert node["id"] == 135 and node["has_rotations"] == 0
    assert np.array_equal(node["phi"], inv.nodes[1].phi) and not node["psi"].any()


def test_the_mat_fields_give_point_mass_dynamics(lumped):
    """Every term of SID_NOTES §3 from the .mat fields against sums over the point masses."""
    body, phi, m, inv, path, _ = lumped
    d = scipy.io.loadmat(path, squeeze_me=True)
    c = body.coordinates
    p = phi.reshape(-1, 3, inv.nq)
    rng = np.random.default_rng(3)
    w, qd = rng.normal(size=3), rng.normal(size=inv.nq)
    q = 0.01 * rng.normal(size=inv.nq)
    omega = np.array([w[0] ** 2, w[1] ** 2, w[2] ** 2, w[0] * w[1], w[1] * w[2], w[0] * w[2]])
    r = c + p @ q
    # first moment, inertia tensor (to first order in q), Cr(q)
    assert np.allclose(d["mdCM0"] + d["mdCM1"] @ q, m @ r, rtol=1e-13)
    cx = cross_matrix(c)
    j_linear = -np.einsum("i,iab,ibc->ac", m, cx, cross_matrix(p @ q))
    j_linear = j_linear + j_linear.T  # ∂/∂q of Σ m r̃ᵀ r̃ at q = 0, applied to q
    assert np.allclose(d["J0"] + d["J1"] @ q, np.einsum("i,iba,ibc->ac", m, cx, cx) + j_linear)
    cr_exact = np.einsum("i,iab,ibk->ka", m, cross_matrix(r), p)
    assert np.allclose(d["Cr0"] + np.einsum("kla,l->ka", d["Cr1"], q), cr_exact, rtol=1e-12)
    # gyroscopic torque 2 Σ m c × (ω × Φ q̇) = Σ_k Gr0(:, :, k) q̇_k ω
    gyro = 2 * np.einsum("i,ia->a", m, np.cross(c, np.cross(w, p @ qd)))
    assert np.allclose(d["Gr0"] @ qd @ w, gyro, rtol=1e-12)
    # elastic Coriolis and centrifugal forces Σ m Φᵀ (2 ω × Φ q̇ + ω × (ω × r))
    coriolis = np.einsum("i,iak,ia->k", m, p, 2 * np.cross(w, p @ qd))
    assert np.allclose(np.einsum("kla,l,a->k", d["Ge0"], qd, w), coriolis, rtol=1e-12)
    centrifugal = np.einsum("i,iak,ia->k", m, p, np.cross(w, np.cross(w, r)))
    oe = d["Oe0"] + np.einsum("klm,l->km", d["Oe1"], q)
    assert np.allclose(oe @ omega, centrifugal, rtol=1e-12)
    assert np.allclose(d["Me"], np.einsum("i,iak,ial->kl", m, p, p), rtol=1e-13)


def test_agrees_with_the_sid_file(lumped, tmp_path):
    *_, inv, path, _ = lumped
    d = scipy.io.loadmat(path, squeeze_me=True)
    sid = read_sid(write_sid(tmp_path / "same.SID_FEM", inv))
    nq = inv.nq
    gr_file = sid.objects["Gr"].m0.reshape(3, 3, nq)  # axis-major [a, b, k]
    ge_file = sid.objects["Ge"].m0.reshape(nq, 3, nq).transpose(0, 2, 1)  # [k, l, a]
    for mat, file in [(d["Gr0"], gr_file), (d["Ge0"], ge_file), (d["Oe1"], sid.objects["Oe"].m1),
                      (d["Cr1"], sid.objects["Cr"].m1)]:  # fmt: skip
        assert np.abs(mat - file).max() <= 1e-11 * np.abs(file).max()


def test_rotating_nodes_get_psi_and_ap1(tmp_path):
    body, phi, _, _ = lumped_body(rotary=True, nq=2)
    inv = compute_invariants(body, phi, phi.T @ (body.mass @ phi), np.eye(2), None, [107])
    node = scipy.io.loadmat(write_neweul(tmp_path / "r.mat", inv), simplify_cells=True)["nodes"]
    psi = phi[9:12]
    assert node["has_rotations"] == 1 and np.array_equal(node["psi"], psi)
    for k in range(2):
        assert np.array_equal(node["AP1"][:, :, k], cross_matrix(psi[:, k]))
    # point masses with rotary inertia are rigid bodies at their nodes: exact second order
    assert scipy.io.loadmat(tmp_path / "r.mat", simplify_cells=True)["second_order_mass"] == (
        "exact"
    )


def test_non_finite_values_are_refused_and_nothing_is_written(lumped, tmp_path):
    *_, inv, _, _ = lumped
    ke = inv.Ke.copy()
    ke[0, 0] = np.inf
    with pytest.raises(NumericalError, match="NaN or infinite"):
        write_neweul(tmp_path / "bad.mat", replace(inv, Ke=ke))
    assert list(tmp_path.iterdir()) == []
