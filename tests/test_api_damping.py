"""Issue #27 item 7: damping from Python -- ``pm.prepare(..., damping=...)`` with the job's
``[damping]`` keys -- checked against independent computations: the poles of the reduced body
carry the modal damping ratio, a Rayleigh body's reduced damping is ``alpha M_bar + beta K_bar``
formed from the FE matrices, a damping matrix given as such is projected; the Gramian's advice
for an undamped body names what exists."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp

import pymorembs as pm
from conftest import space_truss
from pymorembs.job.schema import parse_job

ALPHA, BETA = 2.0, 1e-5  # 1/s, s


@pytest.fixture(scope="module")
def rack():
    return pm.example("rack-beams")


def reduce_rack(rack, damping):
    prepared = pm.prepare(rack, "tangent", node=2, inputs=[(1, "ux uy uz")], damping=damping)
    return pm.reduce(prepared, "krylov", expansion_points_hz=[0.0, 500.0], order=12)


def damping_ratios(mass: np.ndarray, damping: np.ndarray, stiffness: np.ndarray) -> np.ndarray:
    """-Re(p) / |p| of the oscillating poles (Im p > 0) of M q'' + D q' + K q = 0, ascending
    (first-order companion form, dense)."""
    n = mass.shape[0]
    lower = [-np.linalg.solve(mass, stiffness), -np.linalg.solve(mass, damping)]
    a = np.block([[np.zeros((n, n)), np.eye(n)], lower])
    poles = np.linalg.eigvals(a)
    poles = poles[poles.imag > 0]
    return np.sort(-poles.real / np.abs(poles))


def test_a_modal_ratio_damps_every_mode_of_the_reduced_body_by_it(rack):
    reduced = reduce_rack(rack, pm.Damping("modal", ratio=0.02))
    assert reduced.prepared.body.damping == pm.Damping("modal", ratio=0.02)
    system = reduced.system
    assert system.modal_damping_ratio == 0.02 and system.loss_factor == pytest.approx(0.04)
    ratios = damping_ratios(np.asarray(system.mass), reduced.model.damping_matrix,
                            np.asarray(system.stiffness))  # fmt: skip
    np.testing.assert_allclose(ratios, 0.02, rtol=1e-9)
    # the same from the keys of a job's [damping] table
    table = reduce_rack(rack, {"kind": "modal", "ratio": 0.02})
    np.testing.assert_array_equal(table.model.damping_matrix, reduced.model.damping_matrix)


def test_rayleigh_damping_reduces_to_alpha_m_plus_beta_k_of_the_fe_matrices(rack):
    reduced = reduce_rack(rack, {"kind": "rayleigh", "alpha": ALPHA, "beta": BETA})
    # independent: V^T (alpha M + beta K) V with the FE matrices of the body as built and the
    # basis on all its dofs (fixed rows zero), against the reduced D_bar
    basis = reduced.basis
    d = basis.T @ ((ALPHA * rack.mass + BETA * rack.stiffness) @ basis)
    np.testing.assert_allclose(reduced.system.damping, d, atol=1e-9 * np.abs(d).max())
    m_bar, k_bar = np.asarray(reduced.system.mass), np.asarray(reduced.system.stiffness)
    np.testing.assert_allclose(reduced.system.damping, ALPHA * m_bar + BETA * k_bar,
                               atol=1e-9 * np.abs(d).max())  # fmt: skip
    omega = 2 * np.pi * reduced.eigenfrequencies_hz  # zeta_i = alpha / (2 w) + beta w / 2
    expected = np.sort(ALPHA / (2 * omega) + BETA * omega / 2)
    ratios = damping_ratios(m_bar, np.asarray(reduced.system.damping), k_bar)
    np.testing.assert_allclose(ratios, expected[expected < 1], rtol=1e-7)  # overdamped: no pair


def test_a_damping_matrix_is_projected_as_given(rack):
    matrix = ALPHA * rack.mass  # sparse, over all dofs of the body
    reduced = reduce_rack(rack, matrix)
    basis = reduced.basis
    d = basis.T @ (matrix @ basis)  # V^T D V, written here
    np.testing.assert_allclose(reduced.system.damping, d, atol=1e-12 * np.abs(d).max())
    # and alpha I, as V^T M V = I to the rounding of the basis (1.2e-10 off the diagonal on an
    # AVX-512 host, below 1e-10 on another)
    np.testing.assert_allclose(reduced.system.damping, ALPHA * np.eye(reduced.order), atol=1e-9)
    assert reduced.prepared.body.damping == pm.Damping()  # the model's own: undamped
    truss = space_truss()  # a dense matrix, on a small body
    ports = {"inputs": [(1, "ux uy uz")]}
    dense = pm.prepare(truss, "buckens", **ports, damping=(BETA * truss.stiffness).toarray())
    rayleigh = pm.prepare(truss, "buckens", **ports, damping=pm.Damping("rayleigh", beta=BETA))
    assert (dense.system.damping != rayleigh.system.damping).nnz == 0


@pytest.mark.parametrize(
    "table", [{"kind": "modal", "ratio": 0.02}, {"kind": "rayleigh", "alpha": ALPHA, "beta": BETA}]
)
def test_the_mapping_takes_the_keys_of_the_jobs_damping_table(rack, tmp_path, table):
    job = parse_job({
        "model": {"example": "rack-beams"},
        "damping": table,
        "frame": {"type": "tangent", "node": 2},
        "inputs": [{"node": 1, "directions": "ux"}],
        "band": {"f_max_hz": 1000},
        "reduction": [{"method": "modal", "order": 4}],
    }, tmp_path / "job.toml")  # fmt: skip
    prepared = pm.prepare(rack, "tangent", node=2, inputs=[(1, "ux")], damping=table)
    assert prepared.body.damping == job.damping


@pytest.mark.parametrize(
    ("damping", "message"),
    [
        ({"kind": "modal"}, "damping: kind 'modal' needs 'ratio'"),
        ({"kind": "modal", "ratio": 0.02, "alpha": 1.0},
         r"damping: unknown key 'alpha' for kind 'modal' \(it takes ratio\)"),
        ({"kind": "viscous"}, "damping: kind must be 'none', 'rayleigh' or 'modal', got 'viscous'"),
        ({"ratio": 0.02}, "damping: a mapping needs 'kind'"),
        ({"kind": "modal", "ratio": 2}, r"modal damping ratio must lie in \(0, 1\), got 2.0"),
        ({"kind": "rayleigh", "alpha": "2"}, "damping alpha must be a number, got '2'"),
        (0.02, "damping: must be a Damping, a mapping like .* or a matrix, got 0.02"),
        (np.eye(3), r"a damping matrix must have the shape \(n_dof, n_dof\) = \(3996, 3996\), "
                    r"got \(3, 3\)"),
        (sp.eye(3996, format="csr") * np.nan, "damping matrix has NaN or infinite entries"),
    ],
)  # fmt: skip
def test_a_wrong_damping_is_one_line(rack, damping, message):
    with pytest.raises(pm.UserError, match=message) as caught:
        pm.prepare(rack, "tangent", node=2, inputs=[(1, "ux")], damping=damping)
    assert "\n" not in str(caught.value)


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"kind": "modal", "ratio": 0.02, "alpha": 1.0},
         "damping alpha does not belong to kind 'modal', which takes ratio"),
        ({"kind": "rayleigh", "alpha": 1.0, "ratio": 0.02},
         "damping ratio does not belong to kind 'rayleigh', which takes alpha and beta"),
        ({"kind": "none", "beta": 1e-5}, "damping beta does not belong to kind 'none'"),
        ({"kind": "modal", "ratio": [0.02]}, r"damping ratio must be a number, got \[0.02\]"),
    ],
)  # fmt: skip
def test_a_damping_never_ignores_a_value(kwargs, message):
    with pytest.raises(pm.UserError, match=message):
        pm.Damping(**kwargs)
    assert pm.Damping("modal", ratio=np.float32(0.5)).ratio == 0.5


def test_the_gramian_of_an_undamped_body_names_the_damping_that_exists():
    truss = space_truss()
    with pytest.raises(pm.UserError) as caught:
        undamped = pm.prepare(truss, "buckens", inputs=[(1, "ux uy uz")])
        pm.reduce(undamped, "gramian", band_hz=(0, 3000), order=6)
    message = str(caught.value)
    assert "damping_ratio" not in message and "\n" not in message
    assert '[damping] kind = "modal"' in message
    assert 'damping=pymorembs.Damping("modal", ratio=0.02) in pymorembs.prepare' in message
    # what it advises works
    prepared = pm.prepare(truss, "buckens", inputs=[(1, "ux uy uz")],
                          damping=pm.Damping("modal", ratio=0.02))  # fmt: skip
    assert pm.reduce(prepared, "gramian", band_hz=(0, 3000), order=6).order == 6
