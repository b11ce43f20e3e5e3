"""The job file's ``[[reduction]]`` tables and the method registry behind them."""

from __future__ import annotations

import pytest

from pymorembs.errors import UserError
from pymorembs.job.schema import ReductionSpec, parse_job
from pymorembs.methods import KrylovOptions, method_options


def job_data(reduction: dict) -> dict:
    return {
        "model": {"example": "rack-beams"},
        "frame": {"type": "tangent", "node": 2},
        "inputs": [{"node": 1, "directions": "ux uy uz"}],
        "band": {"f_max_hz": 1000},
        "reduction": [reduction],
    }


def test_the_options_object_is_built_once_and_checked_at_construction():
    spec = ReductionSpec("k", method_options("krylov", {"expansion_points_hz": [0.0, 500.0],
                                                        "order": 12}))  # fmt: skip
    assert isinstance(spec.options, KrylovOptions)
    assert spec.options is spec.options  # not rebuilt on each access
    assert spec.options.order == 12 and spec.options.expansion_points_hz == (0.0, 500.0)
    assert spec.options.deflation_tolerance == 1e-10
    with pytest.raises(UserError, match="moments: 2 values for 1 expansion points"):
        method_options("krylov", {"expansion_points_hz": [0.0], "moments": [1, 2]})


def test_a_job_with_the_old_option_name_points_to_the_new_one(tmp_path):
    data = job_data({"method": "soaga", "order": 20, "tol": 1e-9})
    with pytest.raises(UserError) as info:
        parse_job(data, tmp_path / "old.toml")
    message = str(info.value)
    assert "[[reduction]] #1.tol: was renamed to 'deflation_tolerance'" in message
    assert "\n" not in message
    data = job_data({"method": "soaga", "order": 20, "deflation_tolerance": 1e-9})
    spec = parse_job(data, tmp_path / "new.toml").reductions[0]
    assert spec.options.deflation_tolerance == 1e-9
