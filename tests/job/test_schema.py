"""The job file's ``[[reduction]]`` tables and the method registry behind them."""

from __future__ import annotations

import pytest

from conftest import spring_lattice
from pymorembs import reduce
from pymorembs.errors import UserError
from pymorembs.job.run import run_reduction
from pymorembs.job.schema import ReductionSpec, load_job, parse_job
from pymorembs.methods import KrylovOptions, method_options
from pymorembs.preparation import Frame, Port, prepare
from pymorembs.reduction import dispatch, krylov


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


KRYLOV_JOB = """
[model]
example = "rack-beams"

[frame]
type = "tangent"
node = 10

[[inputs]]
node = 40
directions = "ux uy uz"

[band]
f_max_hz = 500

[[reduction]]
method = "krylov"
expansion_points_hz = [0, 200]
moments = 2
"""


def test_a_krylov_option_is_checked_once_and_never_climbs_back(tmp_path, monkeypatch):
    """Issue #28: from the job file to the algorithm, ``expansion_points_hz`` is checked by
    ``KrylovOptions`` once, and the algorithm receives the very object the spec holds (nothing
    converted back up and rebuilt); the Python API and a direct call check it once too."""
    checks = []
    check = KrylovOptions.__post_init__

    def counted(options):
        checks.append(options.expansion_points_hz)
        check(options)

    monkeypatch.setattr(KrylovOptions, "__post_init__", counted)
    received = []
    run_krylov = dispatch.METHOD_FUNCTIONS["krylov"]

    def spy(system, options, band_hz):
        received.append(options)
        return run_krylov(system, options, band_hz)

    monkeypatch.setitem(dispatch.METHOD_FUNCTIONS, "krylov", spy)
    points = []
    match = krylov.moment_matching

    def algorithm(system, expansion_points_hz, *rest):
        points.append(expansion_points_hz)
        return match(system, expansion_points_hz, *rest)

    monkeypatch.setattr(krylov, "moment_matching", algorithm)
    (tmp_path / "job.toml").write_text(KRYLOV_JOB)
    spec = load_job(tmp_path / "job.toml").reductions[0]
    ports = [Port.parse(40, "ux uy uz")]
    prepared = prepare(spring_lattice(n_nodes=12), Frame("tangent", 10), ports, ports)
    projection = run_reduction(prepared.system, spec, (0.0, 500.0))
    assert len(checks) == 1  # the parser's, none on the way down
    assert received == [spec.options] and received[0] is spec.options
    assert points[0] is spec.options.expansion_points_hz == (0.0, 200.0)
    assert projection.parameters["expansion_points_hz"] == [0.0, 200.0]
    checks.clear()
    reduce(prepared, "krylov", expansion_points_hz=[0, 200], moments=2)
    assert len(checks) == 1
    checks.clear()
    krylov.krylov_reduction(prepared.system, [0, 200], moments=2)
    assert len(checks) == 1
