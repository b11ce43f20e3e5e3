"""Stiff directions of reduced bodies (issue #15 item 4): top frequency, explicit step, removal."""

from __future__ import annotations

import json

import numpy as np
import pytest

from pymorembs.analysis.transfer import transfer_function
from pymorembs.errors import UserError
from pymorembs.examples import build_example
from pymorembs.job.cli import main
from pymorembs.job.schema import parse_job
from pymorembs.preparation import Frame, Port, prepare
from pymorembs.reduction.krylov import krylov_reduction
from pymorembs.reduction.projection import explicit_step_s, reduced_model, without_stiff_directions

PORTS = [Port.parse(1, "ux uy uz")]


@pytest.fixture(scope="module")
def krylov():
    body = build_example("rack-beams")
    system = prepare(body, Frame("tangent", 2), PORTS, PORTS).system
    model = reduced_model(system, krylov_reduction(system, [0.0, 500.0], order=24))
    return system, model


def central_difference_growth(model, step: float, steps: int = 4000) -> float:
    """Largest |q| over a free undamped run of the reduced model from a unit start, x'' = -K x."""
    k = np.diag(model.system.stiffness)
    x_old = x = np.ones(k.size)  # at rest in a unit deflection
    top = 1.0
    for _ in range(steps):
        x_old, x = x, 2.0 * x - x_old - step**2 * k * x
        top = max(top, float(np.abs(x).max()))
        if top > 1e8:
            break
    return top


def test_the_explicit_step_is_the_central_difference_limit(krylov):
    _, model = krylov
    step = explicit_step_s(model.eigenfrequencies_hz)
    assert step == pytest.approx(1.0 / (np.pi * model.eigenfrequencies_hz.max()), rel=1e-14)
    assert central_difference_growth(model, 0.99 * step) < 1e3  # stable: bounded
    assert central_difference_growth(model, 1.01 * step) > 1e6  # unstable: grows


def test_removing_stiff_directions_drops_exactly_their_modal_terms(krylov):
    system, model = krylov
    frequencies = model.eigenfrequencies_hz
    limit = float(np.sort(frequencies)[-5] * 1.001)  # the four highest go
    cut = without_stiff_directions(system, model, limit)
    assert cut.projection.order == model.projection.order - 4
    assert cut.projection.parameters["removed_directions"] == 4
    assert cut.eigenfrequencies_hz.max() <= limit
    np.testing.assert_allclose(
        np.sort(cut.eigenfrequencies_hz), np.sort(frequencies[frequencies <= limit]), rtol=1e-7
    )
    # the model is in its eigenbasis (M = I, K = diag): removing directions removes their terms
    f = np.array([0.0, 120.0, 800.0])
    h, h_cut = transfer_function(model.system, f), transfer_function(cut.system, f)
    b, c = model.system.input_matrix, model.system.output_matrix
    omega2 = np.diag(model.system.stiffness)
    removed = np.flatnonzero(frequencies > limit)
    terms = sum(
        np.einsum("r,p->rp", c[:, i], b[i])[None]
        / (omega2[i] - (2 * np.pi * f[:, None, None]) ** 2)
        for i in removed
    )
    np.testing.assert_allclose(h_cut, h - terms, rtol=1e-8, atol=1e-11 * np.abs(h).max())
    with pytest.raises(UserError, match="removes every direction"):
        without_stiff_directions(system, model, 0.5 * frequencies.min())
    assert without_stiff_directions(system, model, 2 * frequencies.max()) is model


def test_job_option_and_summary(tmp_path):
    base = {
        "model": {"example": "rack-beams"},
        "frame": {"type": "tangent", "node": 2},
        "inputs": [{"node": 1, "directions": "ux uy uz"}],
        "band": {"f_max_hz": 1000.0, "points": 200},
        "reduction": [
            {"name": "k", "method": "krylov", "expansion_points_hz": [0, 500], "order": 24},
            {
                "name": "k-cut",
                "method": "krylov",
                "expansion_points_hz": [0, 500],
                "order": 24,
                "max_frequency_hz": 3000.0,
            },
        ],
    }
    with pytest.raises(UserError, match=r"max_frequency_hz: must be a frequency > 0"):
        parse_job(
            {**base, "reduction": [{**base["reduction"][1], "max_frequency_hz": 0}]}, tmp_path
        )
    job = tmp_path / "job.toml"
    job.write_text(to_toml(base))
    assert main(["reduce", str(job), "--out", str(tmp_path / "out"), "--quiet"]) == 0
    summary = json.loads((tmp_path / "out" / "summary.json").read_text())
    full, cut = summary["reductions"]
    assert full["highest_frequency_hz"] == pytest.approx(max(full["eigenfrequencies_hz"]))
    assert full["explicit_step_s"] == pytest.approx(1 / (np.pi * full["highest_frequency_hz"]))
    assert full["highest_frequency_hz"] > 3000.0 >= cut["highest_frequency_hz"]
    removed = cut["parameters"]["removed_directions"]
    assert cut["order"] == full["order"] - removed > 0
    # the cost is reported: the errors before the removal are those of the uncut reduction
    before = cut["parameters"]["max_rel_error_before_removal"]
    assert before == pytest.approx(full["max_rel_error"], rel=1e-6)
    assert cut["max_rel_error"] >= before
    assert cut["parameters"]["static_rel_error_before_removal"] == pytest.approx(
        full["static_rel_error"], rel=1e-6, abs=1e-14
    )


def to_toml(data: dict) -> str:
    """The few TOML shapes these jobs need (tables, arrays of tables, scalars, lists)."""

    def value(v):
        if isinstance(v, str):
            return json.dumps(v)
        if isinstance(v, list):
            return "[" + ", ".join(value(x) for x in v) + "]"
        return repr(v)

    lines = []
    for key, item in data.items():
        for table in item if isinstance(item, list) else [item]:
            lines.append(f"[[{key}]]" if isinstance(item, list) else f"[{key}]")
            lines += [f"{k} = {value(v)}" for k, v in table.items()]
    return "\n".join(lines) + "\n"


def test_to_toml_round_trip(tmp_path):
    import tomllib

    data = {"a": {"x": 1.5, "s": "t"}, "b": [{"n": [1, 2]}, {"n": [3]}]}
    assert tomllib.loads(to_toml(data)) == data
