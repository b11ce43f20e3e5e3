"""The public API (issue #16 item 1): read -> prepare -> reduce -> error -> export, from
``import pymorembs`` alone, against a dense computation of the same model and against the job
route; the method options checked once (issue #16 item 2)."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest
import scipy.io

import pymorembs as pm
from pymorembs.export.exudyn_body import load_exudyn_body
from pymorembs.export.sid import check_sid, read_sid
from pymorembs.io.matrix_market import write_matrix_files
from pymorembs.job.cli import main


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    folder = tmp_path_factory.mktemp("api")
    write_matrix_files(pm.example("rack-beams"), folder / "model")
    return folder


def test_read_is_the_one_read_of_the_io_layer(files):
    """Issue #28: one read signature; ``pm.read`` is ``pymorembs.io.read_body``, and the first
    file given with a mass file is the stiffness file."""
    import pymorembs.io

    assert pm.read is pymorembs.io.read_body
    model = files / "model"
    first = pm.read(model / "K.mtx", mass=model / "M.mtx", dofs=model / "dofs.csv")
    named = pm.read(stiffness=model / "K.mtx", mass=model / "M.mtx", dofs=model / "dofs.csv")
    assert (first.stiffness != named.stiffness).nnz == 0 and first.n_dof == named.n_dof


def dense_response(prepared: pm.PreparedModel, frequencies_hz: np.ndarray) -> np.ndarray:
    """H(f) = C (K - w^2 M + i w D)^-1 B with dense matrices (the model has a few hundred dofs)."""
    system = prepared.reduction_system
    k, m = system.stiffness.toarray(), system.mass.toarray()
    d = np.zeros_like(k) if system.damping is None else system.damping.toarray()
    b, c = np.asarray(system.input_matrix), np.asarray(system.output_matrix)
    out = []
    for f in frequencies_hz:
        w = 2 * np.pi * f
        out.append(c @ np.linalg.solve(k - w**2 * m + 1j * w * d, b))
    return np.array(out)


def test_the_readme_flow_from_files_to_a_checked_sid(files, tmp_path):
    body = pm.read(files / "model" / "K.mtx", mass=files / "model" / "M.mtx",
                   dofs=files / "model" / "dofs.csv", nodes=files / "model" / "nodes.csv",
                   constraints=files / "model" / "constraints.csv")  # fmt: skip
    prepared = pm.prepare(body, frame=pm.Frame("tangent", node=2), inputs=[(1, "ux uy uz")])
    assert prepared.frame == pm.Frame("tangent", node=2)
    reduced = pm.reduce(prepared, "krylov", expansion_points_hz=[0, 500, 1000], order=30)
    assert reduced.order == 30 and reduced.method == "krylov"
    error = reduced.error(band_hz=(0, 1000), points=60)
    assert 0 < error.max < 1e-6 and error.inertia is None
    sid = read_sid(reduced.to_sid(tmp_path / "rack.SID_FEM", nodes=[1, 2]))
    assert check_sid(sid) == [] and sid.nq == 30
    exudyn = load_exudyn_body(reduced.to_exudyn(tmp_path / "rack_exudyn.npz", nodes=[1, 2]))
    np.testing.assert_allclose(exudyn["eigenfrequenciesHz"], reduced.eigenfrequencies_hz)
    written = reduced.to_matrices(tmp_path / "matrices")
    assert {p.name for p in written} >= {"reduced.npz", "K.mtx", "M.mtx"}
    k = scipy.io.mmread(tmp_path / "matrices" / "K.mtx")
    np.testing.assert_allclose(np.asarray(k), np.asarray(reduced.system.stiffness), rtol=1e-15)


@pytest.mark.slow
def test_the_error_curve_equals_dense_solutions_of_both_models(files):
    body = pm.read(files / "model" / "K.mtx", mass=files / "model" / "M.mtx",
                   dofs=files / "model" / "dofs.csv", nodes=files / "model" / "nodes.csv",
                   constraints=files / "model" / "constraints.csv")  # fmt: skip
    prepared = pm.prepare(body, frame=pm.Frame("tangent", node=2), inputs=[(1, "ux uy uz")])
    # the error curve against dense solutions of the full and the reduced model, on a modal
    # body whose error (1e-3 .. 1) lies far above the round-off of a dense solve
    modal = pm.reduce(prepared, "modal", order=10)
    coarse = modal.error(band_hz=(0, 1000), points=40)
    f = coarse.frequencies_hz[::8]
    full = dense_response(prepared, f)
    h = modal.system
    mine = np.array([
        np.asarray(h.output_matrix) @ np.linalg.solve(
            np.asarray(h.stiffness) - (2 * np.pi * x) ** 2 * np.asarray(h.mass)
            + 2j * np.pi * x * (0 if h.damping is None else np.asarray(h.damping)),
            np.asarray(h.input_matrix))
        for x in f
    ])  # fmt: skip
    expected = np.linalg.norm(full - mine, axis=(1, 2)) / np.linalg.norm(full, axis=(1, 2))
    # dense LU of the ill-conditioned K - w^2 M leaves ~1e-8 of round-off in eps
    np.testing.assert_allclose(coarse.relative[::8], expected, rtol=1e-5, atol=5e-8)


@pytest.mark.slow  # 4-10 s: in the slow set (make test stays within its budget)
def test_api_and_job_give_the_same_body(files, tmp_path):
    """The same reduction through a job file: the same order, frequencies and errors."""
    job = tmp_path / "job.toml"
    job.write_text(f"""
[model]
stiffness = "{files / "model" / "K.mtx"}"
mass = "{files / "model" / "M.mtx"}"
dofs = "{files / "model" / "dofs.csv"}"
nodes = "{files / "model" / "nodes.csv"}"
constraints = "{files / "model" / "constraints.csv"}"
[frame]
type = "tangent"
node = 2
[[inputs]]
node = 1
directions = "ux uy uz"
[band]
f_max_hz = 1000
points = 200
[[reduction]]
name = "modal"
method = "modal"
order = 12
export_inaccurate = true  # max error 0.15: the test compares, it does not judge
[[reduction]]
name = "soaga"
method = "soaga"
tolerance = 1e-6
""")
    assert main(["reduce", str(job), "--out", str(tmp_path / "out"), "--quiet"]) == 0
    summary = json.loads((tmp_path / "out" / "summary.json").read_text())
    by_name = {r["name"]: r for r in summary["reductions"]}
    prepared = pm.prepare(pm.read(files / "model" / "K.mtx", mass=files / "model" / "M.mtx",
                                  dofs=files / "model" / "dofs.csv",
                                  nodes=files / "model" / "nodes.csv",
                                  constraints=files / "model" / "constraints.csv"),
                          "tangent", node=2, inputs=[(1, "ux uy uz")])  # fmt: skip
    for name, options in (("modal", {"order": 12}), ("soaga", {"tolerance": 1e-6})):
        reduced = pm.reduce(prepared, name, band_hz=(0, 1000), **options)
        assert reduced.order == by_name[name]["order"]
        error = reduced.error((0, 1000), points=200)
        assert error.max == pytest.approx(by_name[name]["max_rel_error"], rel=1e-6)


@pytest.mark.parametrize(
    ("method", "options", "message"),
    [
        ("krylov", {"order": 30}, "missing key 'expansion_points_hz'"),
        (
            "krylov",
            {"expansion_points_hz": [0], "oder": 30},
            "oder: unknown option of krylov; did you mean 'order'",
        ),
        ("krylow", {}, "unknown method 'krylow'; did you mean 'krylov'"),
        (
            "soaga",
            {"order": 10, "tol": 1e-10},
            "tol: was renamed to 'deflation_tolerance'",
        ),
        ("modal", {}, "modal reduction needs 'order'"),
        ("modal", {"order": 4, "candidates": 3}, "candidates: must exceed the order 4"),
        ("soaga", {"tolerance": 2.0}, r"tolerance: must lie in \(0, 1\)"),
        ("soaga", {"tolerance": 1e-6}, r"soaga needs band_hz=\(f_min, f_max\)"),
        ("gramian", {"order": 5, "first_stage": "arnoldi"}, "first_stage: must be 'soaga'"),
    ],
)
def test_bad_options_are_named(method, options, message):
    body = pm.example("rack-beams")
    prepared = pm.prepare(body, "tangent", node=2, inputs=[(1, "ux")])
    with pytest.raises(pm.UserError, match=message):
        pm.reduce(prepared, method, **options)


def test_the_registry_documents_every_option():
    from pymorembs.methods import options_table

    table = options_table()
    for name, cls in pm.METHODS.items():
        for field in [f.name for f in dataclasses.fields(cls)]:
            owner = "every method" if field == "max_frequency_hz" else name
            row = [line for line in table.splitlines() if line.startswith(f"| {owner} | `{field}`")]
            assert len(row) == 1 and not row[0].endswith("|  |"), (name, field)  # a meaning
    assert "| krylov | `deflation_tolerance` | `1e-10` |" in table
    assert "| pod | `snapshots` | `40` |" in table
    assert "| modal | `order` | required |" in table and "``" not in table


def test_facts_are_what_info_prints(files, capsys):
    body = pm.read(files / "model" / "K.mtx", mass=files / "model" / "M.mtx",
                   dofs=files / "model" / "dofs.csv", nodes=files / "model" / "nodes.csv",
                   constraints=files / "model" / "constraints.csv")  # fmt: skip
    facts = pm.facts(body, modes=5)
    assert main(["info", "--stiffness", str(files / "model" / "K.mtx"),
                 "--mass", str(files / "model" / "M.mtx"),
                 "--dofs", str(files / "model" / "dofs.csv"),
                 "--nodes", str(files / "model" / "nodes.csv"),
                 "--constraints", str(files / "model" / "constraints.csv"),
                 "--json", "--modes", "5"]) == 0  # fmt: skip
    printed = json.loads(capsys.readouterr().out)
    np.testing.assert_allclose(facts["eigenfrequencies_hz"], printed["eigenfrequencies_hz"])
    assert facts["rigid_body_modes"] == printed["rigid_body_modes"] == 6
    assert facts["units"] == printed["units"]


def test_simulate_follows_the_full_model_held_at_the_frame_node():
    """ReducedBody.simulate against the full FE model clamped at node 2 (a separate sparse
    integration of the same load): the step response at node 1 within 1 % of its peak."""
    from pymorembs.analysis.time_domain import clamped_full_system, simulate

    rack = pm.example("rack-beams")
    rack = dataclasses.replace(rack, damping=pm.Damping("rayleigh", beta=2e-5))
    prepared = pm.prepare(rack, "tangent", node=2, inputs=[(1, "ux uy uz")])
    reduced = pm.reduce(prepared, "krylov", expansion_points_hz=[0, 500], order=30)
    step = [pm.LoadCase("step", "step", [0.0, 0.0, -100.0])]
    mine = reduced.simulate(step, clamp_node=2, load_node=1, duration_s=0.05, step_s=1e-4)
    full = simulate(clamped_full_system(rack, 2, 1), step, 0.05, 1e-4)
    a, b = mine.outputs["step"], full.outputs["step"]
    assert a.shape == b.shape and np.abs(b).max() > 1e-6
    assert np.abs(a - b).max() <= 1e-2 * np.abs(b).max()


def test_the_job_reference_holds_the_generated_options_table():
    from pathlib import Path

    from pymorembs.methods import options_table

    text = (Path(__file__).parents[1] / "docs" / "jobs.md").read_text(encoding="utf-8")
    block = text.split("<!-- options-table:start -->\n")[1].split("<!-- options-table:end -->")[0]
    assert block == options_table(), "regenerate the table in docs/jobs.md (see its section)"


def test_max_frequency_keeps_the_model_before_the_removal():
    """``reduce`` with ``max_frequency_hz`` (the one place the job layer reduces through) keeps
    the uncut model: it equals the reduction without the limit, and the cut model holds its
    eigenfrequencies at or below the limit."""
    from pymorembs.methods import method_options

    prepared = pm.prepare(pm.example("rack-beams"), "tangent", node=2, inputs=[(1, "ux uy uz")])
    options = {"expansion_points_hz": [0, 500], "order": 24}
    plain = pm.reduce(prepared, "krylov", **options)
    assert plain.before_removal is None and plain.eigenfrequencies_hz.max() > 3000.0
    settings = method_options("krylov", {**options, "max_frequency_hz": 3000.0})
    cut = pm.reduce(prepared, settings, name="cut")
    assert cut.options is settings and cut.name == "cut" and cut.method == "krylov"
    assert cut.eigenfrequencies_hz.max() <= 3000.0 < cut.before_removal.eigenfrequencies_hz.max()
    np.testing.assert_allclose(
        cut.before_removal.eigenfrequencies_hz, plain.eigenfrequencies_hz, rtol=1e-9
    )
    kept = plain.eigenfrequencies_hz[plain.eigenfrequencies_hz <= 3000.0]
    np.testing.assert_allclose(cut.eigenfrequencies_hz, kept, rtol=1e-6)
    with pytest.raises(pm.UserError, match="beside an options object"):
        pm.reduce(prepared, settings, order=10)
