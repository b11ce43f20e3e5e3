"""Reduced matrices for MATLAB (.mat) and the pyMOR adapter."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.io

from conftest import spring_lattice
from pymorembs.analysis.transfer import transfer_function
from pymorembs.body import Damping
from pymorembs.errors import UserError
from pymorembs.export.matrices import reduced_arrays, to_pymor, write_reduced_mat
from pymorembs.preparation import Frame, Port, prepare
from pymorembs.reduction.krylov import krylov_reduction
from pymorembs.reduction.projection import reduced_model


def prepared_lattice(damping: Damping):
    body = spring_lattice(30, damping=damping)
    ports = [Port.parse(50, "ux uy"), Port.parse(200, "uz")]
    return prepare(body, Frame("none"), ports, ports)


def reduced(prepared):
    projection = krylov_reduction(prepared.system, [0.0, 30.0], moments=[3, 3])
    return reduced_model(prepared.system, projection)


def test_mat_file_holds_the_npz_arrays(tmp_path):
    prepared = prepared_lattice(Damping("rayleigh", alpha=0.5, beta=1e-4))
    model = reduced(prepared)
    arrays = reduced_arrays(model, prepared)
    write_reduced_mat(tmp_path / "reduced.mat", arrays)
    data = scipy.io.loadmat(tmp_path / "reduced.mat")
    for key in ("M", "K", "D", "B", "C", "V"):
        np.testing.assert_array_equal(data[key], arrays[key])
    np.testing.assert_array_equal(data["eigenfrequencies_hz"].ravel(), model.eigenfrequencies_hz)
    assert [str(c[0]) for c in data["input_labels"].ravel()] == list(model.system.input_labels)
    # the basis on all dofs is the one of eq. 18: V^T M V reproduces the reduced mass
    basis = data["V"]
    np.testing.assert_allclose(basis.T @ (prepared.body.mass @ basis), data["M"], atol=1e-10)


def test_pymor_model_has_our_transfer_function():
    pytest.importorskip("pymor")
    prepared = prepared_lattice(Damping("rayleigh", alpha=0.5, beta=1e-4))
    model = reduced(prepared)
    frequencies = np.array([0.0, 7.5, 31.0, 120.0])
    for system, damping in ((prepared.system, None), (model.system, model.damping_matrix)):
        pymor_model = to_pymor(system, damping)
        ours = transfer_function(system, frequencies)  # (n_f, outputs, inputs)
        theirs = np.stack(
            [pymor_model.transfer_function.eval_tf(2j * np.pi * f) for f in frequencies]
        )
        np.testing.assert_allclose(theirs, ours, rtol=1e-9, atol=1e-14 * np.abs(ours).max())


def test_pymor_refuses_a_loss_factor_without_viscous_damping():
    pytest.importorskip("pymor")
    prepared = prepared_lattice(Damping("modal", ratio=0.02))
    with pytest.raises(UserError, match="loss factor"):
        to_pymor(prepared.system)
