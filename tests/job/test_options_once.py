"""Issue #28: every method option is checked once, by its options class, on its way from the
job file (or :func:`pymorembs.reduce`, or the method's Python function) to the algorithm; the
algorithms below the options take checked values and check only what the system tells.

The Krylov case is ``tests/job/test_schema.py``; these are the other methods.
"""

from __future__ import annotations

import pytest

from conftest import spring_lattice
from pymorembs import reduce
from pymorembs.body import Damping
from pymorembs.errors import UserError
from pymorembs.job.run import run_reduction
from pymorembs.job.schema import parse_job
from pymorembs.methods import METHODS
from pymorembs.preparation import Frame, Port, prepare
from pymorembs.reduction import gramian, krylov, modal, modal_family, rational_gramian, soaga
from pymorembs.reduction.gramian import pod_reduction, quadrature
from pymorembs.reduction.modal import modal_reduction
from pymorembs.reduction.modal_family import (
    best_modes,
    boundary_dofs_of_inputs,
    craig_bampton,
    modes_with_frm,
)
from pymorembs.reduction.rational_gramian import rational_gramian_reduction

BAND = (0.0, 500.0)

#: The method functions that check their arguments: the job path must not pass through them.
CHECKING = (
    "modal_reduction",
    "best_modes",
    "modes_with_frm",
    "craig_bampton",
    "soaga_reduction",
    "krylov_reduction",
    "gramian_reduction",
    "pod_reduction",
    "rational_gramian_reduction",
    "rational_krylov_gramians",
)

#: A ``[[reduction]]`` table of each case and the same request as a direct Python call.
CASES = {
    "modal": ({"method": "modal", "order": 4}, lambda s: modal_reduction(s, 4)),
    "modal-best": (
        {"method": "modal", "order": 4, "select": "best"},
        lambda s: best_modes(s, 4),
    ),
    "modal-frm": (
        {"method": "modal", "order": 4, "frm_hz": [0.0]},
        lambda s: modes_with_frm(s, 4, [0.0]),
    ),
    "craig-bampton": (
        {"method": "craig-bampton", "fixed_modes": 3},
        lambda s: craig_bampton(s, boundary_dofs_of_inputs(s), 3),
    ),
    "soaga": ({"method": "soaga", "order": 9, "candidates_hz": [0.0, 200.0]}, None),
    "pod": (
        {"method": "pod", "order": 4, "snapshots": 6},
        lambda s: pod_reduction(s, BAND, order=4, n_snapshots=6),
    ),
    "gramian-soaga": (
        {
            "method": "gramian",
            "order": 4,
            "first_stage": "soaga",
            "first_order": 12,
            "first_tolerance": 1e-8,
        },
        None,
    ),
    "gramian-rational": (
        {
            "method": "gramian",
            "order": 4,
            "first_stage": "rational-krylov",
            "convergence_tolerance": 1e-6,
        },
        lambda s: rational_gramian_reduction(s, BAND, order=4, tol=1e-6),
    ),
}


def job_data(reduction: dict) -> dict:
    return {
        "model": {"example": "rack-beams"},
        "frame": {"type": "tangent", "node": 10},
        "inputs": [{"node": 40, "directions": "ux uy uz"}],
        "band": {"f_max_hz": BAND[1]},
        "reduction": [reduction],
    }


@pytest.fixture(scope="module")
def prepared():
    ports = [Port.parse(40, "ux uy uz")]
    body = spring_lattice(n_nodes=12, damping=Damping("modal", ratio=0.02))
    return prepare(body, Frame("tangent", 10), ports, ports)


def counted_checks(monkeypatch, method: str) -> list[object]:
    """The options objects whose class checks them (``__post_init__``), as they are checked."""
    cls = METHODS[method]
    checks: list[object] = []
    check = cls.__post_init__

    def counted(options):
        checks.append(options)
        check(options)

    monkeypatch.setattr(cls, "__post_init__", counted)
    return checks


def refuse_checking_functions(monkeypatch) -> None:
    """Make every method function that checks its arguments fail wherever it is looked up."""
    for module in (modal, modal_family, soaga, krylov, gramian, rational_gramian):
        for name in CHECKING:
            if hasattr(module, name):

                def refused(*args, _name=name, **kwargs):
                    raise AssertionError(f"the checked options went through {_name}")

                monkeypatch.setattr(module, name, refused)


@pytest.mark.parametrize("case", list(CASES))
def test_a_job_option_is_checked_once_on_its_way_to_the_algorithm(
    case, prepared, monkeypatch, tmp_path
):
    table, _ = CASES[case]
    checks = counted_checks(monkeypatch, table["method"])
    spec = parse_job(job_data(table), tmp_path / "job.toml").reductions[0]
    assert len(checks) == 1 and checks[0] is spec.options  # the parser's check
    refuse_checking_functions(monkeypatch)
    projection = run_reduction(prepared.system, spec, BAND)
    assert len(checks) == 1  # none on the way down
    assert projection.order > 0


@pytest.mark.parametrize("case", list(CASES))
def test_pm_reduce_and_the_method_function_check_an_option_once(case, prepared, monkeypatch):
    table, direct = CASES[case]
    options = {key: value for key, value in table.items() if key != "method"}
    checks = counted_checks(monkeypatch, table["method"])
    reduce(prepared, table["method"], band_hz=BAND, **options)
    assert len(checks) == 1
    if direct is not None:
        checks.clear()
        direct(prepared.system)
        assert len(checks) == 1  # the function builds the options object, which checks


@pytest.mark.parametrize(
    ("table", "message"),
    [
        ({"method": "soaga", "order": 9, "candidates_hz": [100.0, 100.0]},
         r"\[\[reduction\]\] #1\.candidates_hz: points repeat: \[100\.0, 100\.0\]"),
        ({"method": "gramian", "order": 4, "first_stage": "soaga", "first_tolerance": 0.0},
         r"\[\[reduction\]\] #1\.first_tolerance: must be > 0, got 0\.0"),
        ({"method": "gramian", "order": 4, "first_stage": "rational-krylov",
          "convergence_tolerance": 0.0},
         r"\[\[reduction\]\] #1\.convergence_tolerance: must be > 0, got 0\.0"),
    ],
)  # fmt: skip
def test_options_the_algorithms_refused_are_refused_when_the_job_is_read(table, message, tmp_path):
    """The algorithms below no longer check them: their options class does, before any work."""
    with pytest.raises(UserError, match=message):
        parse_job(job_data(table), tmp_path / "job.toml")


def test_the_pod_snapshots_are_checked_by_the_options_only(prepared):
    """``pod_reduction`` refuses what a job refuses, by the options' message; the quadrature
    below takes the checked count as it is."""
    with pytest.raises(UserError, match="snapshots: must be >= 4, got 3"):
        pod_reduction(prepared.system, BAND, order=2, n_snapshots=3)
    nodes, weights = quadrature(BAND, 1)  # only the options refuse a single node
    assert nodes.size == weights.size == 1
