"""Sparse stress outputs through the system, the transfer function, the reference and the
reductions, and their error eps_s against a dense direct computation written here."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
import scipy.sparse as sp

from conftest import spring_lattice
from pymorembs.analysis.error import error_blocks, stress_block
from pymorembs.analysis.reference import reference_response
from pymorembs.analysis.transfer import transfer_function
from pymorembs.body import Damping
from pymorembs.preparation import Frame, Port, prepare
from pymorembs.reduction.krylov import krylov_reduction
from pymorembs.reduction.projection import reduced_model
from pymorembs.reduction.soaga import soaga_reduction
from pymorembs.system import SecondOrderSystem

FREQUENCIES = np.array([0.0, 3.0, 17.0, 41.0])


@pytest.fixture(scope="module")
def system() -> SecondOrderSystem:
    """The 40-node spring lattice with 3 force inputs, and 12 sparse "stress" rows: differences
    of neighbouring dofs (what a strain is), 2 entries each."""
    body = spring_lattice(n_nodes=40, damping=Damping("rayleigh", alpha=2.0, beta=1e-5))
    ports = [Port.parse(70, "ux uy"), Port.parse(40, "uz")]
    base = prepare(body, Frame("tangent", 10), ports).system
    rng = np.random.default_rng(7)
    first = rng.choice(base.order - 1, 12, replace=False)
    rows = np.repeat(np.arange(12), 2)
    cols = np.column_stack([first, first + 1]).ravel()
    values = np.tile([-1.0, 1.0], 12) * 1e3
    stress = sp.csr_matrix((values, (rows, cols)), shape=(12, base.order))
    labels = tuple(f"p{i}:sxx" for i in range(12))
    return replace(base, stress_matrix=stress, stress_labels=labels)


def dense_response(system: SecondOrderSystem, basis: np.ndarray | None = None) -> np.ndarray:
    """``[C; C_s] (s^2 M + s D + K)^-1 B`` with dense matrices, on ``span(basis)`` if given."""
    m, k, d = (np.asarray(a.toarray()) for a in (system.mass, system.stiffness, system.damping))
    c = np.vstack([system.output_matrix, system.stress_matrix.toarray()])
    b = system.input_matrix
    out = []
    for f in FREQUENCIES:
        s = 2j * np.pi * f
        a = s * s * m + s * d + k
        if basis is None:
            out.append(c @ np.linalg.solve(a, b))
        else:
            v = basis
            out.append(c @ v @ np.linalg.solve(v.T @ a @ v, v.T @ b))
    return np.array(out)


def test_stress_rows_stay_sparse_and_come_after_the_outputs(system):
    assert sp.issparse(system.stress_matrix) and sp.issparse(system.observed_matrix)
    assert system.observed_labels[-12:] == system.stress_labels
    h = transfer_function(system, FREQUENCIES)
    assert h.shape == (4, system.n_outputs + 12, system.n_inputs)
    expected = dense_response(system)
    assert np.max(np.abs(h - expected)) <= 1e-9 * np.max(np.abs(expected))


def test_projection_gives_the_dense_stress_rows_c_s_v(system):
    projection = krylov_reduction(system, [0.0, 20.0], moments=3)
    model = reduced_model(system, projection)
    v = model.projection.V
    assert isinstance(model.system.stress_matrix, np.ndarray)
    np.testing.assert_allclose(model.system.stress_matrix, system.stress_matrix @ v, atol=1e-12)
    assert model.system.stress_labels == system.stress_labels


def test_blocks_keep_ports_and_stresses_apart(system):
    ports, inertia = error_blocks(system)
    stress = stress_block(system)
    assert inertia is None
    assert ports.shape == stress.shape == (system.n_outputs + 12, system.n_inputs)
    assert not (ports & stress).any() and (ports | stress).all()
    assert stress_block(replace(system, stress_matrix=None, stress_labels=())) is None


def test_stress_error_against_a_dense_direct_computation(system):
    """eps_s(f) = ||H_s - H_s_bar||_F / ||H_s||_F (eq. 27) over the stress rows, both H from
    dense solves here; the reduction is not exact there (eps_s > 1e-6 somewhere)."""
    projection = krylov_reduction(system, [0.0], moments=2)
    model = reduced_model(system, projection)
    reference = reference_response(system, FREQUENCIES, "full")
    eps_s = reference.stress_errors(transfer_function(model.system, FREQUENCIES))
    full = dense_response(system)[:, system.n_outputs :]
    reduced = dense_response(system, model.projection.V)[:, system.n_outputs :]
    expected = np.linalg.norm(full - reduced, axis=(1, 2)) / np.linalg.norm(full, axis=(1, 2))
    assert expected.max() > 1e-6
    np.testing.assert_allclose(eps_s, expected, rtol=1e-6, atol=1e-12)
    # the ports' curve is that of the outputs alone, as without stress outputs
    plain = replace(system, stress_matrix=None, stress_labels=())
    eps = reference.errors(transfer_function(model.system, FREQUENCIES))
    plain_eps = reference_response(plain, FREQUENCIES, "full").errors(
        transfer_function(reduced_model(plain, projection).system, FREQUENCIES)
    )
    np.testing.assert_allclose(eps, plain_eps, rtol=1e-9, atol=1e-14)


def test_targeted_system_appends_the_weighted_stress_rows(system):
    assert system.targeted() is system
    targeted = replace(system, stress_targeted=True, stress_weight=0.5).targeted()
    assert targeted.n_stress == 0 and targeted.n_outputs == system.n_outputs + 12
    np.testing.assert_array_equal(
        targeted.output_matrix[system.n_outputs :], 0.5 * system.stress_matrix.toarray()
    )


def test_soaga_estimates_the_stress_error_and_holds_to_it_when_targeted(system):
    plain = soaga_reduction(system, (0.0, 50.0), tolerance=1e-4)
    targeted = soaga_reduction(replace(system, stress_targeted=True), (0.0, 50.0), tolerance=1e-4)
    assert plain.parameters["stress_targeted"] is False
    assert targeted.parameters["stress_targeted"] is True
    assert targeted.parameters["stress_estimate"] <= 1e-4
    assert targeted.order >= plain.order
