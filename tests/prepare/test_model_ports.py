"""Inputs and outputs that come with the model file (``B``, ``C`` of a ``.mat`` benchmark).

A job without ``[[inputs]]`` reduces for the model's own ports; the reduced model must match
``C (s^2 M + s D + K)^-1 B`` computed here with plain numpy.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
import scipy.sparse as sp

from conftest import spring_lattice
from pymorembs.body import ModelPorts
from pymorembs.errors import UserError
from pymorembs.io.native import write_body_h5
from pymorembs.job.cli import main
from pymorembs.job.run import run_job
from pymorembs.job.schema import load_job
from pymorembs.preparation import Frame, Port, prepare
from pymorembs.preparation.interface import InterfaceSpec, add_interface_node


def body_with_ports(with_outputs: bool = True):
    body = spring_lattice(10, constraints=False)
    n = body.n_dof
    rng = np.random.default_rng(3)
    b = np.zeros((n, 2))
    b[5, 0] = 1.0
    b[10:20, 1] = rng.normal(size=10)  # a distributed load
    c = rng.normal(size=(3, n)) if with_outputs else None
    ports = ModelPorts(
        sp.csr_matrix(b),
        None if c is None else sp.csr_matrix(c),
        ("f", "p"),
        ("a", "b", "c") if with_outputs else (),
    )
    return replace(body, ports=ports), b, c


def test_prepare_uses_the_model_ports_unless_the_job_gives_its_own():
    body, b, c = body_with_ports()
    system = prepare(body, Frame("none")).system
    assert np.array_equal(system.input_matrix, b) and np.array_equal(system.output_matrix, c)
    assert system.input_labels == ("f", "p") and system.output_labels == ("a", "b", "c")
    own = prepare(body, Frame("none"), [Port.parse(20, "ux")], [Port.parse(20, "ux")]).system
    assert own.input_labels == ("20:ux",)
    body, b, _ = body_with_ports(with_outputs=False)
    system = prepare(body, Frame("none")).system
    assert np.array_equal(system.output_matrix, b.T)  # C = B^T


def test_interface_nodes_pad_the_model_ports():
    body, b, _ = body_with_ports()
    grown = add_interface_node(
        body, InterfaceSpec(node=999, position=(0.0, 0.0, 0.0), coupled=(10, 20), kind="rigid")
    )
    assert grown.ports.inputs.shape == (grown.n_dof, 2)
    assert grown.ports.outputs.shape == (3, grown.n_dof)
    assert np.array_equal(grown.ports.inputs.toarray()[: body.n_dof], b)


JOB = """
[model]
file = "model.h5"
[frame]
type = "none"
[band]
f_max_hz = 400
points = 200
[[reduction]]
name = "krylov"
method = "krylov"
expansion_points_hz = [0, 200]
moments = [4, 3]
export_inaccurate = true  # max error 47 between the points (undamped): the test is on the ports
"""


def test_a_job_without_inputs_reduces_for_the_model_ports(tmp_path):
    body, b, c = body_with_ports()
    write_body_h5(body, tmp_path / "model.h5")
    (tmp_path / "job.toml").write_text(JOB)
    summary = run_job(load_job(tmp_path / "job.toml"), tmp_path / "out", None, workers=1)
    assert summary.model["inputs"] == ["f", "p"]
    assert summary.model["outputs"] == ["a", "b", "c"]
    data = np.load(tmp_path / "out" / "krylov" / "reduced.npz")
    k, m = body.stiffness.toarray(), body.mass.toarray()
    for f in (0.0, 200.0):  # the expansion points: the reduced model interpolates H there
        w = 2 * np.pi * f
        full = c @ np.linalg.solve(k - w * w * m, b)
        reduced = data["C"] @ np.linalg.solve(data["K"] - w * w * data["M"], data["B"])
        assert np.linalg.norm(full - reduced) < 1e-8 * np.linalg.norm(full)


def test_a_job_without_inputs_for_a_model_without_ports_is_refused(tmp_path, capsys):
    body, _, _ = body_with_ports()
    write_body_h5(replace(body, ports=None), tmp_path / "model.h5")
    (tmp_path / "job.toml").write_text(JOB)
    assert main(["reduce", str(tmp_path / "job.toml"), "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert "[[inputs]] is missing and the model brings no input matrix B" in err
    assert err.count("\n") == 1


def test_model_ports_must_fit_the_model():
    body, _, _ = body_with_ports()
    with pytest.raises(UserError, match="B has 5 rows but the model has 30 dofs"):
        replace(body, ports=ModelPorts(sp.csr_matrix(np.ones((5, 1)))))
    with pytest.raises(UserError, match="2 labels for 1 inputs"):
        ModelPorts(sp.csr_matrix(np.ones((5, 1))), input_labels=("a", "b"))
