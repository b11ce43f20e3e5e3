"""The reference of the error curves: a reference model checked against the full model.

Everything here is compared with the full model's own frequency response, computed
independently (one sparse factorization per frequency) on the same grid.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from pymorembs.analysis.error import relative_error
from pymorembs.analysis.reference import (
    SURROGATE_TOLERANCE,
    ReferenceResponse,
    check_frequencies,
    choose_kind,
    reference_response,
)
from pymorembs.analysis.transfer import transfer_function
from pymorembs.errors import UserError
from pymorembs.examples import build_example
from pymorembs.frequencies import frequency_grid
from pymorembs.job.cli import main
from pymorembs.job.run import run_reduction
from pymorembs.job.schema import ReductionSpec, load_job
from pymorembs.methods import method_options
from pymorembs.preparation import Frame, Port, prepare
from pymorembs.reduction.projection import reduced_model

DEMO = Path(__file__).resolve().parents[2] / "examples" / "rack-beams-demo.toml"
BAND = (0.0, 1000.0)


@pytest.fixture(scope="module")
def rack():
    """rack-beams (3,996 dofs), tangent frame at node 2, 1 % modal damping, ports at 1 and 2."""
    from pymorembs.body import Damping

    body = build_example("rack-beams").with_damping(Damping("modal", ratio=0.01))
    ports = [Port.parse(1, "ux uy uz"), Port.parse(2, "ux uy uz")]
    return prepare(body, Frame("tangent", 2), ports, ports).system


@pytest.fixture(scope="module")
def grid():
    return frequency_grid(*BAND, 200)


@pytest.fixture(scope="module")
def full(rack, grid):
    return transfer_function(rack, grid, workers=1)


@pytest.fixture(scope="module")
def surrogate(rack, grid):
    return reference_response(rack, grid, "surrogate", checks=4)


def test_surrogate_is_the_full_response_to_its_measured_accuracy(surrogate, full, grid):
    assert surrogate.kind == "surrogate"
    assert surrogate.parameters["order"] < 100  # a small model, not the full one
    # checked frequencies: the full model's response itself
    exact = surrogate.exact
    assert exact[0] and grid[0] == 0.0  # the static response is always checked
    assert np.count_nonzero(exact) >= 5  # 0 Hz, estimator maximum, response peak, 2 gaps
    assert np.allclose(surrogate.response[exact], full[exact], rtol=1e-13, atol=0)
    # everywhere else within a few times the accuracy: the deviation measured at the checks,
    # at least the tolerance of the surrogate's estimator
    deviation = relative_error(full, surrogate.response)
    assert surrogate.accuracy < 1e-9
    assert deviation.max() <= 3 * surrogate.accuracy + 1e-13
    assert surrogate.accuracy == max(*surrogate.deviation.values(), SURROGATE_TOLERANCE)


def test_error_curves_from_the_surrogate_match_the_full_ones(rack, surrogate, full):
    spec = ReductionSpec("m", method_options("modal", {"order": 20}))
    modal = reduced_model(rack, run_reduction(rack, spec, BAND))
    reduced = transfer_function(modal.system, surrogate.frequencies_hz)
    true = relative_error(full, reduced)
    assert true.max() > 1e-4  # an error far above the reference's accuracy ...
    estimate = surrogate.errors(reduced)
    # ... is resolved: |eps_sur - eps| <= delta (1 + eps) / (1 - delta), delta <= 3 accuracy
    delta = 3 * surrogate.accuracy + 1e-13
    assert np.all(np.abs(estimate - true) <= delta * (1 + true) / (1 - delta))
    assert surrogate.resolved(estimate)


def test_settle_measures_the_maximum_against_the_full_model(rack, grid, full):
    spec = ReductionSpec(
        "k", method_options("krylov", {"expansion_points_hz": [0.0, 1000.0], "moments": [4, 4]})
    )
    krylov = reduced_model(rack, run_reduction(rack, spec, BAND))
    reduced = transfer_function(krylov.system, grid)
    true = relative_error(full, reduced)
    reference = reference_response(rack, grid, "surrogate", checks=0)
    exact_before = reference.exact.copy()
    settled = reference.settled(reduced)
    # a new value; the old one is as it was
    np.testing.assert_array_equal(reference.exact, exact_before)
    assert np.count_nonzero(settled.exact) > np.count_nonzero(exact_before)
    assert len(settled.deviation) > len(reference.deviation)
    with pytest.raises(ValueError, match="read-only"):
        settled.response[0] = 0.0
    reference = settled
    eps = reference.errors(reduced)
    top = int(np.argmax(eps))
    assert reference.exact[top]
    assert eps[top] == pytest.approx(true[top], rel=1e-12)
    # the reported maximum can miss the true one only by the reference's own error
    assert true.max() - 3 * reference.accuracy - 1e-13 <= eps.max() <= true.max() * (1 + 1e-12)


def test_a_bad_reference_model_is_exposed_by_its_checks(rack, grid, full):
    """A reference 1e-3 off everywhere: the checks measure 1e-3 and replace it there."""
    bad = ReferenceResponse(grid, full * (1 + 1e-3), "surrogate", np.zeros(grid.size, bool), rack)
    bad = bad.checked([0.0, 500.0])
    assert bad.accuracy == pytest.approx(1e-3, rel=1e-9)  # ||H - 1.001 H|| / ||H||
    assert np.count_nonzero(bad.exact) == 2
    assert not bad.resolved(np.full(grid.size, 5e-3))
    assert bad.resolved(np.full(grid.size, 2e-2))


def test_check_frequencies_fill_the_gaps_between_expansion_points():
    grid = np.linspace(0.0, 1000.0, 1001)
    magnitude = np.exp(-(((grid - 300.0) / 5.0) ** 2))  # one resonance at 300 Hz
    chosen = check_frequencies(grid, [0.0, 1000.0], None, 3, magnitude)
    assert chosen == [300.0, 650.0, 475.0]  # the peak, then the middles of the largest gaps
    estimate = (np.array([10.0, 812.3]), np.array([1e-14, 1e-12]))
    assert check_frequencies(grid, [0.0], estimate, 1) == [812.0]
    assert check_frequencies(grid, [0.0], estimate, 0) == []
    # frequencies checked already count and are avoided; the peak is checked whatever they are
    assert check_frequencies(grid, [0.0, 1000.0], None, 3, magnitude, checked=[650.0]) == [
        300.0,
        475.0,  # 0-300-650-1000: the middle of the first of the two largest gaps
    ]
    assert check_frequencies(grid, [0.0, 1000.0], None, 3, magnitude, checked=[300.0, 650.0]) == [
        475.0
    ]
    many = [100.0, 200.0, 400.0, 500.0]
    assert check_frequencies(grid, [0.0], estimate, 2, magnitude, checked=many) == [812.0, 300.0]
    assert check_frequencies(grid, [0.0], estimate, 2, magnitude, checked=[812.0, 300.0]) == []


def test_completed_checks_the_weakest_frequencies_and_counts_earlier_checks(rack, grid, full):
    """The job's order: the reductions' maxima first, then the estimator's maximum, the peak
    and the largest gaps until there are ``count`` checks above 0 Hz."""
    reference = reference_response(rack, grid, "surrogate", checks=0)
    assert np.flatnonzero(reference.exact).tolist() == [0]  # 0 Hz only
    up_front = reference_response(rack, grid, "surrogate", checks=4)
    # without earlier checks: the same frequencies as the checks made up front
    completed = reference.completed(4)
    np.testing.assert_array_equal(completed.exact, up_front.exact)
    # after a settle check, which counts: one full solve fewer, the weakest still checked
    spec = ReductionSpec("m", method_options("modal", {"order": 12}))
    modal = transfer_function(reduced_model(rack, run_reduction(rack, spec, BAND)).system, grid)
    settled = reference.settled(modal)
    top = grid[np.flatnonzero(settled.exact & ~reference.exact)]
    assert top.size == 1 and top[0] not in grid[up_front.exact]
    merged = settled.completed(4)
    assert np.count_nonzero(merged.exact) == np.count_nonzero(up_front.exact)
    magnitude = np.linalg.norm(reference.response, axis=(1, 2))
    points = reference.parameters["expansion_points_hz"]
    weakest = check_frequencies(grid, points, reference.estimate_curve, 2, magnitude)
    assert len(set(weakest)) == 2 and set(weakest) <= set(grid[merged.exact])
    assert np.allclose(merged.response[merged.exact], full[merged.exact], rtol=1e-13, atol=0)
    # checking again changes nothing; a full reference has nothing to complete
    assert merged.completed(4) is merged
    exact = ReferenceResponse(grid, full, "full", np.ones(grid.size, bool), rack)
    assert exact.completed(4) is exact


def test_auto_uses_the_full_model_for_small_systems_only():
    assert choose_kind("auto", 4000) == "full"
    assert choose_kind("auto", 35_000) == "surrogate"
    assert choose_kind("full", 300_000) == "full"
    with pytest.raises(UserError, match="reference must be one of"):
        choose_kind("fast", 10)


def test_job_with_a_surrogate_reference(tmp_path, capsys):
    """The demo job on a checked reference model reports the full model's maximum errors."""
    text = DEMO.read_text().replace("points = 400", 'points = 200\nreference = "surrogate"')
    text = text.replace('outputs = ["npz", "mtx", "mat", "sid", "neweul", "exudyn", "report"]',
                        'outputs = ["npz", "report"]')  # fmt: skip
    job = tmp_path / "job.toml"
    job.write_text(text)
    assert main(["reduce", str(job), "--out", str(tmp_path / "out"), "--quiet"]) == 0
    summary = json.loads((tmp_path / "out" / "summary.json").read_text())
    reference = summary["reference"]
    assert reference["kind"] == "surrogate" and reference["accuracy"] < 1e-9
    assert len(reference["checks_hz"]) == reference["exact_frequencies"] >= 5
    parsed = load_job(job)
    prepared = prepare(
        build_example("rack-beams").with_damping(parsed.damping),
        parsed.frame,
        list(parsed.inputs),
        list(parsed.outputs),
    )
    system, independent = prepared.system, prepared.elimination.independent
    grid = frequency_grid(*parsed.band_hz, parsed.points)
    for entry in summary["reductions"]:
        table = np.loadtxt(tmp_path / "out" / entry["name"] / "error.csv", delimiter=",",
                           skiprows=1)  # fmt: skip
        assert table.shape == (grid.size, 3)
        checked = table[:, 2] == 1
        top = int(np.argmax(table[:, 1]))
        assert checked[top] and checked[0]
        assert entry["max_rel_error"] == table[top, 1]
        # the maximum, recomputed from the full model and the written reduced matrices
        model = np.load(tmp_path / "out" / entry["name"] / "reduced.npz")
        at = grid[[0, top]]
        full = transfer_function(system, at)
        s = 2j * np.pi * at[1]
        a = s**2 * model["M"] + (1 + 1j * system.loss_factor) * model["K"]  # as the full model
        h = model["C"] @ np.linalg.solve(a, model["B"])
        recomputed = float(relative_error(full[1:], h[None])[0])
        assert recomputed == pytest.approx(entry["max_rel_error"], rel=1e-6)
        # and no worse than the Galerkin projection of the full matrices on the written V, in
        # NumPy's longdouble (independent of pymorembs' products)
        v = model["V"][independent].astype(np.longdouble)
        mass_r, stiffness_r = (
            np.asarray(v.T @ (matrix.astype(np.longdouble) @ v), dtype=float)
            for matrix in (system.mass, system.stiffness)
        )
        a = s**2 * mass_r + (1 + 1j * system.loss_factor) * stiffness_r
        v = np.asarray(v, dtype=float)
        b, c = system.input_matrix, system.output_matrix
        h = (c @ v) @ np.linalg.solve(a, v.T @ b)
        galerkin = float(relative_error(full[1:], h[None])[0])
        if entry["max_rel_error"] > 1e-6:  # modal-40: 4e-4
            assert galerkin == pytest.approx(entry["max_rel_error"], rel=1e-6)
        else:  # krylov: 4e-10 written, 3e-12 for the exact projection
            assert galerkin <= entry["max_rel_error"] + 1e-11
    report = (tmp_path / "out" / "report.html").read_text()
    assert "a reference model of order" in report
    capsys.readouterr()


def test_unknown_reference_kind_is_a_user_error(tmp_path):
    text = DEMO.read_text().replace("points = 400", 'points = 400\nreference = "fast"')
    job = tmp_path / "job.toml"
    job.write_text(text)
    with pytest.raises(UserError, match=r"\[band\]\.reference: must be one of"):
        load_job(job)


def test_reference_bar_says_its_tolerance_is_internal(rack, capsys):
    """Issue #16: the surrogate's bar showed "tolerance 1e-12" as if it were the user's."""
    from pymorembs import progress

    with progress.settings("on"):
        reference_response(rack, frequency_grid(*BAND, 40), "surrogate", checks=0)
    err = capsys.readouterr().err
    assert "reference model (soaga)" in err
    assert "internal SOAGA tolerance of the surrogate reference 1e-12" in err
    assert "(tolerance 1e-12)" not in err


def test_settle_all_judges_every_reduction_against_the_same_checks(rack, grid, full):
    """Two reductions settled together: every maximum lies on a frequency checked against the
    full model, and each curve is the one a second round would give (nothing moves any more)."""
    spec = ReductionSpec(
        "k", method_options("krylov", {"expansion_points_hz": [0.0, 1000.0], "moments": [4, 4]})
    )
    krylov = reduced_model(rack, run_reduction(rack, spec, BAND))
    modal_spec = ReductionSpec("m", method_options("modal", {"order": 8}))
    modal = reduced_model(rack, run_reduction(rack, modal_spec, BAND))
    responses = [transfer_function(m.system, grid) for m in (krylov, modal)]
    reference = reference_response(rack, grid, "surrogate", checks=0)
    reference = reference.settled_all(responses)
    curves = [reference.errors(response) for response in responses]
    assert reference.settled_all(responses) is reference  # settled: nothing moves any more
    for eps, response in zip(curves, responses, strict=True):
        assert reference.exact[int(np.argmax(eps))]
        np.testing.assert_array_equal(eps, reference.errors(response))
        exact = reference.exact
        np.testing.assert_allclose(eps[exact], relative_error(full, response)[exact], rtol=1e-12)
