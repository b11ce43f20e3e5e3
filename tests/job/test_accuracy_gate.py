"""Issue #27 item 2: accuracy gates the export.

A reduced body whose largest error ε over the ports and the inertia loads exceeds its limit
(SOAGA's ``tolerance``, else 1e-2) is not written silently: the job prints the table and ends
with exit 4, its body files are not written (the evidence is), unless its ``[[reduction]]``
says ``export_inaccurate = true``. An order below one block of inputs is refused before any
work (exit 2).

The model: a straight steel cantilever along x (1 m, 50 mm square, 21 nodes), held by a tangent
frame at node 1, forces at the tip. On the beam's axis the centrifugal loads about x (``wxx``)
and the mixed one ``wyz`` vanish (``Ω × (Ω × c)`` of a point ``c = (x, 0, 0)``), so a body for a
multibody code gets 10 inertia loads beside its 3 port forces: the 13 inputs of the issue.
"""

from __future__ import annotations

import json
import shutil
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from conftest import spring_lattice
from lattice_jobs import SOAGA, lattice_job
from pymorembs.elements.beam import BeamSection
from pymorembs.errors import AccuracyNotMet, PymorembsError, UserError
from pymorembs.io.native import write_body_h5
from pymorembs.job.app import App
from pymorembs.job.app.runner import start_run
from pymorembs.job.cli import SEVERITY, main, worst
from pymorembs.job.run import judge_accuracy, prepare_and_validate, run_job
from pymorembs.job.schema import DEFAULT_ACCURACY_LIMIT, ReductionSpec, load_job
from pymorembs.methods import method_options
from test_units import straight_beam


def reduction_spec(name: str, method: str, **options: object) -> ReductionSpec:
    """A job's reduction of ``method`` with these options (checked once)."""
    return ReductionSpec(name, method_options(method, options))


BEAM_JOB = """
[model]
file = "beam.h5"

[damping]
kind = "modal"
ratio = 0.01

[frame]
type = "tangent"
node = 1

[[inputs]]
node = 21
directions = "ux uy uz"

[band]
f_max_hz = 500
points = 200

{reductions}

[export]
outputs = {outputs}
"""
KRYLOV_12 = """
[[reduction]]
name = "krylov"
method = "krylov"
expansion_points_hz = [0, 500]
order = 12
"""
#: A modal body of two modes: the two bending modes near 42 Hz, nothing else (max error 24).
MODAL_2 = """
[[reduction]]
name = "modal"
method = "modal"
order = 2
{extra}
"""
#: SOAGA stopped by its order before its tolerance: 1e-12 missed, although its error (~1e-7)
#: would meet the default limit.
SOAGA_26 = """
[[reduction]]
name = "soaga"
method = "soaga"
order = 26
tolerance = 1e-12
"""
#: An accurate body (max error ~5e-11 over the ports and the inertia loads).
KRYLOV = """
[[reduction]]
name = "krylov"
method = "krylov"
expansion_points_hz = [0, 250, 500]
moments = 2
"""
BODY_FILES = {"reduced.npz", "modal.SID_FEM"}


@pytest.fixture(scope="module")
def beam_folder(tmp_path_factory):
    folder = tmp_path_factory.mktemp("beam")
    section = BeamSection.rectangular(0.05, 0.05, E=2.1e11, nu=0.3, rho=7850.0)
    write_body_h5(straight_beam(21, np.array([1.0, 0.0, 0.0]), section), folder / "beam.h5")
    return folder


def beam_job(folder: Path, reductions: str, outputs: str = '["sid", "npz", "report"]', **tables):
    path = folder / "job.toml"
    text = BEAM_JOB.format(reductions=reductions, outputs=outputs)
    for table, body in tables.items():
        text += f"\n[{table}]\n{body}\n"
    path.write_text(text, encoding="utf-8")
    return path


@pytest.fixture(scope="module")
def gated(beam_folder):
    """One run of the beam job with a poor modal body, a SOAGA body that misses its tolerance
    and an accurate Krylov body (the command in this process); its code, stdout, stderr and
    output folder."""
    import contextlib
    import io

    folder = beam_folder / "gated"
    folder.mkdir()
    shutil.copy(beam_folder / "beam.h5", folder / "beam.h5")
    job = beam_job(folder, MODAL_2.format(extra="") + SOAGA_26 + KRYLOV)
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        code = main(["reduce", str(job), "--out", str(folder / "out")])
    return code, out.getvalue(), err.getvalue(), job, folder / "out"


def run(argv, capsys):
    code = main([str(a) for a in argv])
    captured = capsys.readouterr()
    return code, captured.out, captured.err


@pytest.fixture
def beam(beam_folder, tmp_path):
    shutil.copy(beam_folder / "beam.h5", tmp_path / "beam.h5")
    return tmp_path


# ---------------------------------------------------------------- an order below one block
def test_the_beam_job_of_the_issue_is_refused_before_any_work(beam, capsys):
    """Krylov order 12 with 3 port inputs + 10 inertia loads: exit 2, the remedy in the line,
    before the frequency response (the issue's body had max error 12.8)."""
    job = beam_job(beam, KRYLOV_12)
    code, out, err = run(["reduce", job, "--out", beam / "out"], capsys)
    assert code == 2
    assert err.count("\n") == 1
    assert err.startswith(f"pymorembs: error: {job}: [[reduction]] #1.order: 12 is below one ")
    assert "block of the 13 inputs (3 port inputs + 10 inertia loads)" in err
    assert (
        "raise the order to >= 13, use SOAGA (order chosen by the error) or fewer inertia loads "
        "([inertia_loads] cases)" in err
    )
    assert "frequency response" not in out and not (beam / "out").exists()
    assert not [p for p in beam.iterdir() if p.name.startswith(".out.")]


def test_one_block_is_counted_as_the_method_sees_it(beam):
    """The block holds the inertia load cases that deform the body: 'wxx' and 'wyz' vanish on
    the beam's axis; a Krylov space from moments (no order), a modal order and an order of one
    block are accepted; SOAGA's order and a two-sided projection's outputs count too."""

    def check(reductions, outputs='["sid"]', **tables):
        prepare_and_validate(load_job(beam_job(beam, reductions, outputs, **tables)))

    check(KRYLOV_12.replace("order = 12", "order = 13"))
    check(KRYLOV_12.replace("order = 12", "moments = 1"))
    check(MODAL_2.format(extra=""))
    # ax and the two vanishing loads: one inertia load, 4 inputs
    cases = 'cases = ["ax", "wxx", "wyz"]'
    with pytest.raises(UserError, match=r"3 is below one block of the 4 inputs \(3 port inputs "):
        check(KRYLOV_12.replace("order = 12", "order = 3"), inertia_loads=cases)
    check(KRYLOV_12.replace("order = 12", "order = 4"), inertia_loads=cases)
    # no body for a multibody code: no inertia loads, and no mention of them
    with pytest.raises(UserError, match=r"is below one block of the 3 inputs, .*krylov basis; "):
        check(KRYLOV_12.replace("order = 12", "order = 2"), outputs='["npz"]')
    gramian = '[[reduction]]\nmethod = "gramian"\norder = 2\nexpansion_points_hz = [0]\n'
    with pytest.raises(UserError, match=r"#1\.first_order: 5 is below one block of the 13 in"):
        check(gramian + 'first_stage = "krylov"\nfirst_order = 5\n')  # its medium model
    check(gramian + 'first_stage = "krylov"\nfirst_order = 13\n')
    check(gramian.replace("order = 2", "order = 2\nfirst_order = 5"))  # 126 dofs: no first stage
    soaga = '[[reduction]]\nmethod = "soaga"\ntolerance = 1e-6\norder = 12\n'
    with pytest.raises(UserError, match=r"give 'tolerance' without 'order' \(the order chosen by"):
        check(soaga)
    # two-sided: one input, three outputs (no inertia loads with matrices only)
    two_sided = BEAM_JOB.replace('directions = "ux uy uz"', 'directions = "uy"')
    two_sided = two_sided.replace("[band]", '[[outputs]]\nnode = 21\ndirections = "all"\n\n[band]')
    krylov = KRYLOV_12.replace("order = 12", "order = 2\ntwo_sided = true")
    (beam / "two.toml").write_text(two_sided.format(reductions=krylov, outputs='["npz"]'))
    with pytest.raises(UserError, match="2 is below one block of the 6 outputs"):
        prepare_and_validate(load_job(beam / "two.toml"))
    one_sided = two_sided.format(
        reductions=krylov.replace("two_sided = true", ""), outputs='["npz"]'
    )
    (beam / "one.toml").write_text(one_sided)
    prepare_and_validate(load_job(beam / "one.toml"))  # one input: a block of one column


def test_the_count_is_what_with_inertia_loads_keeps(beam_folder):
    """The cheap count (no factorization) names the cases the factorized loads keep: on the
    beam's axis all but wxx and wyz; the free beam in the Buckens frame only the centrifugal
    ones of those (its accelerations are balanced by the rigid-body motion)."""
    from pymorembs.io.native import read_body_h5
    from pymorembs.preparation import Frame, Port, inertia_load_cases, prepare, with_inertia_loads

    body = read_body_h5(beam_folder / "beam.h5")
    tip = [Port.parse(21, "ux uy uz")]
    held = prepare(body, Frame("tangent", 1), tip, tip)
    kept = ("ax", "ay", "az", "alx", "aly", "alz", "wyy", "wzz", "wxy", "wxz")
    assert inertia_load_cases(held) == kept == with_inertia_loads(held).inertia.cases
    free = prepare(body, Frame("buckens"), tip, tip)
    centrifugal = ("wyy", "wzz", "wxy", "wxz")
    assert inertia_load_cases(free) == centrifugal == with_inertia_loads(free).inertia.cases


# ---------------------------------------------------------------------- the gate at the end
def files_in(folder: Path) -> set[str]:
    return {p.name for p in folder.iterdir()}


def test_an_inaccurate_body_ends_with_exit_4_and_is_not_written(gated):
    """The issue's "modal body at ε = 1.6 exported as good": exit 4 after the table, its SID and
    npz not written, its error curve and the summary (marked) are; the accurate body of the
    same job is written."""
    code, out, err, job, out_dir = gated
    assert code == 4
    assert err.count("\n") == 1
    assert err.startswith(f"pymorembs: error: {job}: accuracy not met: reduction 'modal' max ")
    assert "reduction 'soaga' max error" in err and "'krylov'" not in err
    assert "export_inaccurate = true" in err
    summary = json.loads((out_dir / "summary.json").read_text())
    entries = {r["name"]: r for r in summary["reductions"]}
    modal, krylov = entries["modal"]["accuracy"], entries["krylov"]["accuracy"]
    # the evidence: the largest error of the curves written, over ports and inertia loads
    table = np.loadtxt(out_dir / "modal" / "error.csv", delimiter=",", skiprows=1)
    assert modal["max"] == pytest.approx(table[:, 1:3].max(), rel=1e-12)
    assert modal["ports"] == pytest.approx(table[:, 1].max(), rel=1e-12)
    assert modal["inertia_loads"] == pytest.approx(table[:, 2].max(), rel=1e-12)
    assert modal["max"] > 1.0 and modal["limit"] == DEFAULT_ACCURACY_LIMIT
    assert (modal["met"], modal["exported"], modal["limit_from"]) == (False, False, "default")
    assert krylov["met"] and krylov["exported"] and krylov["max"] < 1e-8
    assert summary["accuracy"] == {
        "met": False,
        "not_met": ["modal", "soaga"],
        "not_exported": ["modal", "soaga"],
    }
    # the folder holds exactly what the summary lists: no body of 'modal'
    assert files_in(out_dir / "modal") == {"error.csv", "error.png"}
    assert {f"modal/{n}" for n in files_in(out_dir / "modal")} == set(entries["modal"]["files"])
    assert {"reduced.npz", "krylov.SID_FEM"} <= files_in(out_dir / "krylov")
    assert {"summary.json", "error.png", "report.html"} <= files_in(out_dir)
    # the table came first, its rows marked; the report says it on top and in the table
    row = next(line for line in out.splitlines() if line.startswith("modal "))
    assert row.endswith("! above its limit 1e-02: body not written")
    assert f"{modal['max']:.3e}" in row
    assert "! above" not in next(line for line in out.splitlines() if line.startswith("krylov "))
    report = (out_dir / "report.html").read_text(encoding="utf-8")
    assert 'id="accuracy-not-met"' in report and "its body files were not written" in report
    assert "NOT MET (&gt; 0.01), not written" in report


def test_a_tolerance_given_is_the_limit(gated):
    """SOAGA stopped by its order before its tolerance: 1e-12 missed (exit 4, limit from the
    tolerance, nothing but its error files written), although the same curve meets the
    default limit of a SOAGA body without a tolerance."""
    _, out, _, _, out_dir = gated
    summary = json.loads((out_dir / "summary.json").read_text())
    entry = next(r for r in summary["reductions"] if r["name"] == "soaga")
    assert entry["order"] == 26 and entry["parameters"]["stop"] == "max_order"
    assert entry["accuracy"]["limit"] == 1e-12 and entry["accuracy"]["limit_from"] == "tolerance"
    assert 1e-12 < entry["accuracy"]["max"] < DEFAULT_ACCURACY_LIMIT
    assert files_in(out_dir / "soaga") == {"error.csv", "error.png", "error_estimate.csv"}
    row = next(line for line in out.splitlines() if line.startswith("soaga "))
    assert row.endswith("! above its limit 1e-12: body not written")
    table = np.loadtxt(out_dir / "soaga" / "error.csv", delimiter=",", skiprows=1)
    without = judge_accuracy(reduction_spec("soaga", "soaga", order=26), table[:, 1], table[:, 2])
    assert without.met and without.exported and without.limit_from == "default"


def test_export_inaccurate_writes_the_body_marked(beam, capsys):
    job = beam_job(beam, MODAL_2.format(extra="export_inaccurate = true"))
    out_dir = beam / "out"
    code, out, err = run(["reduce", job, "--out", out_dir], capsys)
    assert code == 0 and err == ""
    summary = json.loads((out_dir / "summary.json").read_text())
    (entry,) = summary["reductions"]
    accuracy = entry["accuracy"]
    assert (accuracy["met"], accuracy["exported"], accuracy["export_inaccurate"]) == (
        False,
        True,
        True,
    )
    assert summary["accuracy"] == {"met": False, "not_met": ["modal"], "not_exported": []}
    assert BODY_FILES <= files_in(out_dir / "modal")
    assert summary["provenance"]["settings"]["reductions"][0]["export_inaccurate"] is True
    row = next(line for line in out.splitlines() if line.startswith("modal "))
    assert row.endswith("! above its limit 1e-02: written (export_inaccurate)")
    report = (out_dir / "report.html").read_text(encoding="utf-8")
    assert "its body files are written (export_inaccurate = true)" in report
    assert "NOT MET (&gt; 0.01), written anyway" in report


def test_the_limit_of_each_method():
    """SOAGA's tolerance is an error target (the limit); the tolerance of gramian and pod is a
    ratio of singular values (σ_n+1 / σ_1), not an error: they get the default."""
    assert reduction_spec("s", "soaga", tolerance=1e-7).accuracy_limit == (
        1e-7,
        "tolerance",
    )
    assert reduction_spec("s", "soaga", order=20).accuracy_limit == (1e-2, "default")
    assert reduction_spec("g", "gramian", tolerance=1e-9).accuracy_limit == (
        1e-2,
        "default",
    )
    assert reduction_spec("p", "pod", tolerance=1e-9).accuracy_limit[1] == "default"
    assert reduction_spec("m", "modal", order=4).accuracy_limit == (
        DEFAULT_ACCURACY_LIMIT,
        "default",
    )


def test_export_inaccurate_must_be_a_boolean(beam, capsys):
    job = beam_job(beam, MODAL_2.format(extra='export_inaccurate = "yes"'))
    code, _, err = run(["reduce", job, "--out", beam / "out"], capsys)
    assert code == 2 and err.count("\n") == 1
    assert "[[reduction]] #1.export_inaccurate: must be true or false, got 'yes'" in err


# ------------------------------------------------------------ the API, several jobs, the app
POOR = 'name = "modal-4"\nmethod = "modal"\norder = 4'


@pytest.fixture(scope="module")
def lattice_folder(tmp_path_factory):
    folder = tmp_path_factory.mktemp("lattice")
    write_body_h5(spring_lattice(), folder / "model.h5")
    (folder / "poor.toml").write_text(lattice_job(POOR, points=200))
    (folder / "good.toml").write_text(lattice_job(SOAGA, points=200))
    return folder


@pytest.fixture(scope="module")
def poor_run(lattice_folder):
    """The poor lattice job through the API once: the exception and the folder written."""
    out = lattice_folder / "api"
    with pytest.raises(AccuracyNotMet) as raised:
        run_job(load_job(lattice_folder / "poor.toml"), out)
    return raised.value, out


def test_run_job_raises_accuracy_not_met_after_writing(poor_run):
    error, out = poor_run
    assert isinstance(error, PymorembsError) and error.exit_code == 4
    assert error.summary.accuracy["not_exported"] == ["modal-4"]
    written = json.loads((out / "summary.json").read_text())
    assert written["reductions"][0]["accuracy"] == error.summary.reductions[0].accuracy.to_json()
    assert files_in(out / "modal-4") == {"error.csv", "error.png"}


def test_accuracy_not_met_ranks_below_the_failures():
    """4 ranks below 2 and 3 (those jobs wrote nothing; one with 4 wrote its results)."""
    assert SEVERITY == (0, 4, 2, 3, 1)
    assert worst([0, 4]) == 4 and worst([4, 2]) == 2 and worst([3, 4]) == 3
    assert worst([4, 1, 2]) == 1 and worst([4, 0, 4]) == 4


@pytest.mark.slow
def test_several_jobs_exit_with_the_worst_code(lattice_folder, tmp_path, capsys, monkeypatch):
    """Both jobs run; the poor one prints its table and one line, the exit code is 4."""
    monkeypatch.chdir(tmp_path)
    poor, good = lattice_folder / "poor.toml", lattice_folder / "good.toml"
    code, out, err = run(["reduce", poor, good], capsys)
    assert code == 4
    assert err.count("\n") == 1 and f"{poor}: accuracy not met" in err
    assert (tmp_path / "out" / "good" / "soaga" / "reduced.npz").is_file()
    assert files_in(tmp_path / "out" / "poor" / "modal-4") == {"error.csv", "error.png"}
    assert "! above its limit" in out  # the poor job's table was printed


def test_the_app_shows_a_run_that_missed_its_accuracy(poor_run, tmp_path, monkeypatch):
    """Exit 4 is a finished run: its results are shown with the mark, the line kept."""
    _, written = poor_run
    script = tmp_path / "exit-4-python"  # the child: the results above, then exit 4
    script.write_text(
        "#!/bin/sh\n"
        f'cp -r "{written}" "$6"\n'
        "echo \"pymorembs: error: job.toml: accuracy not met: reduction 'modal-4' ...\" >&2\n"
        "exit 4\n",
        encoding="utf-8",
    )
    script.chmod(0o755)
    monkeypatch.setattr(sys, "executable", str(script))
    app = App(tmp_path / "work")
    app.runs.run = start_run(tmp_path / "job.toml", tmp_path / "work" / "run-1", stages=3)
    deadline = time.monotonic() + 30
    while app.runs.run.ended is None:  # the thread that follows the child has seen its end
        assert time.monotonic() < deadline
        time.sleep(0.05)
    status = app.runs.status()
    assert status["state"] == "done" and status["exit_code"] == 4
    assert "accuracy not met" in status["error"]
    results = app.results.table()
    (row,) = results["reductions"]
    assert row["accuracy"]["met"] is False and row["accuracy"]["exported"] is False
    assert results["accuracy"]["not_exported"] == ["modal-4"]
    assert app.results.file("modal-4/error.csv").is_file()
    with pytest.raises(UserError, match=r"no file 'modal-4/reduced\.npz'"):
        app.results.file("modal-4/reduced.npz")
