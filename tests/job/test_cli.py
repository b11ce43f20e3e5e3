"""The command line: outputs of example/info/reduce, and exit code 2 with one line on bad input."""

from __future__ import annotations

import json
import re
import shutil
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
import scipy.linalg as sla

from conftest import spring_lattice
from pymorembs.io.matrix_market import read_matrix_files, write_matrix_files
from pymorembs.io.native import read_body_h5, write_body_h5
from pymorembs.job.cli import main

ROOT = Path(__file__).resolve().parents[2]
DEMO = ROOT / "examples" / "rack-beams-demo.toml"

SMALL_JOB = """
[model]
{model}

[frame]
type = "tangent"
node = 10

[[inputs]]
node = 60
directions = "ux uy"

[[inputs]]
node = 120
directions = "uz"

[band]
f_max_hz = 200

[[reduction]]
name = "modal-6"
method = "modal"
order = 6
export_inaccurate = true

[[reduction]]
name = "kry"
method = "krylov"
expansion_points_hz = [0, 100]
moments = 2
export_inaccurate = true
{extra}
"""
# The two bodies of SMALL_JOB are poor on purpose (max error 1.9 and 3.5e2 on the undamped
# lattice up to 200 Hz): the tests with it are about the command line, so they are written
# anyway (export_inaccurate); the accuracy gate has its own tests (test_accuracy_gate.py).


@pytest.fixture
def lattice_files(tmp_path):
    body = spring_lattice()
    folder = tmp_path / "lattice"
    write_matrix_files(body, folder)
    write_body_h5(body, folder / "model.h5")
    return folder


def write_job(tmp_path, model='file = "lattice/model.h5"', extra="", name="job.toml"):
    path = tmp_path / name
    path.write_text(SMALL_JOB.format(model=model, extra=extra))
    return path


def run(argv, capsys):
    code = main([str(a) for a in argv])
    captured = capsys.readouterr()
    return code, captured.out, captured.err


@pytest.mark.slow
def test_demo_job_meets_the_foundation_targets(tmp_path, capsys):
    """Issue #2: Krylov max eps <= 1e-4 with order <= 48, exact static response."""
    code, out, err = run(["reduce", DEMO, "--out", tmp_path / "demo"], capsys)
    assert code == 0, err
    summary = json.loads((tmp_path / "demo" / "summary.json").read_text())
    assert summary["model"]["n_dof"] == 3996
    assert summary["model"]["n_inputs"] == 6 and summary["model"]["n_outputs"] == 6
    assert summary["band_hz"] == [0.0, 1000.0]
    assert summary["n_frequencies"] >= 201
    entries = {r["name"]: r for r in summary["reductions"]}
    krylov = entries["krylov"]
    assert krylov["order"] <= 48
    assert krylov["max_rel_error"] <= 1e-4
    assert krylov["static_rel_error"] <= 1e-10
    assert entries["modal-40"]["order"] == 40
    for entry in summary["reductions"]:
        assert entry["error_estimate"] is None and entry["error_bound"] is None
        for name in entry["files"]:
            assert (tmp_path / "demo" / name).is_file()
        npz = np.load(tmp_path / "demo" / entry["name"] / "reduced.npz")
        assert npz["V"].shape == (3996, entry["order"])
        assert np.allclose(npz["M"], np.eye(entry["order"]))
    assert (tmp_path / "demo" / "error.png").read_bytes()[:4] == b"\x89PNG"
    assert "krylov" in out and "max rel. error" in out
    # issue #16: a newcomer's first run shows no warnings (it printed six); issue #27: the two
    # notes (the ports at the frame node: inputs, outputs) on stderr, as the docs say
    assert summary["warnings"] == [] and len(summary["notes"]) == 2
    assert err.splitlines() == [f"pymorembs: note: {note}" for note in summary["notes"]]
    assert all(entry["accuracy"]["met"] for entry in summary["reductions"])
    # issue #27: the table of the README and of docs/tour.md is what this run printed, values
    # at the rounding level as the bounds they show
    for page in (ROOT / "README.md", ROOT / "docs" / "tour.md"):
        shown = documented_table(page.read_text(encoding="utf-8"))
        assert [row[0] for row in shown] == ["modal-40", "krylov"], page
        for row in shown:
            assert_row_as_shown(row, printed_row(out, row[0]), page)


def documented_table(text: str) -> list[list[str]]:
    """The rows of the demo's table in a page (the code block after the 'reduction ...
    method ... order' header line), each as [name, method, order, max, at 0 Hz, inertia, time]
    with a bound such as '< 1e-8' kept as one cell."""
    lines = text[text.index("reduction            method") :].split("```", 1)[0].splitlines()
    return [re.findall(r"<\s*\S+|\S+", line) for line in lines[1:] if line.strip()]


def printed_row(out: str, name: str) -> list[str]:
    return next(line.split() for line in out.splitlines() if line.startswith(f"{name} "))


def assert_row_as_shown(shown: list[str], printed: list[str], page: Path) -> None:
    """Names, method and order equal; a number equal to the digits shown; a bound holds."""
    assert shown[:3] == printed[:3], page
    for cell, value in zip(shown[3:6], printed[3:6], strict=True):
        if cell.startswith("<"):
            assert float(value) < float(cell[1:]), (page, shown[0], cell, value)
        else:
            digits = len(cell.split("e")[0].replace(".", "").lstrip("0")) - 1
            assert float(value) == pytest.approx(float(cell), rel=10.0**-digits), (page, cell)


def test_example_writes_model_files_that_read_back_equal(tmp_path, capsys):
    code, _out, _ = run(["example", "rack-beams", "--out", tmp_path / "rack"], capsys)
    assert code == 0
    folder = tmp_path / "rack"
    for name in ("model.h5", "K.mtx", "M.mtx", "dofs.csv", "nodes.csv", "constraints.csv"):
        assert (folder / name).is_file(), name
    native = read_body_h5(folder / "model.h5")
    plain = read_matrix_files(
        stiffness=folder / "K.mtx",
        mass=folder / "M.mtx",
        dofs=folder / "dofs.csv",
        nodes=folder / "nodes.csv",
        constraints=folder / "constraints.csv",
    )
    assert (native.stiffness != plain.stiffness).nnz == 0
    assert (native.mass != plain.mass).nnz == 0
    assert np.array_equal(native.dofs.nodes, plain.dofs.nodes)
    assert np.array_equal(native.constraints.dependent, plain.constraints.dependent)


def test_info_matches_a_dense_eigensolution(tmp_path, capsys):
    body = spring_lattice(constraints=False)
    write_matrix_files(body, tmp_path)
    code, out, _ = run(
        [
            "info",
            "--stiffness",
            tmp_path / "K.mtx",
            "--mass",
            tmp_path / "M.mtx",
            "--dofs",
            tmp_path / "dofs.csv",
            "--modes",
            5,
            "--json",
        ],
        capsys,
    )
    assert code == 0
    facts = json.loads(out)
    expected = np.sqrt(
        sla.eigh(body.stiffness.toarray(), body.mass.toarray(), eigvals_only=True)[:5]
    ) / (2 * np.pi)
    assert np.allclose(facts["eigenfrequencies_hz"], expected, rtol=1e-10)
    assert facts["n_dof"] == body.n_dof
    m = body.mass.toarray()
    translations = [np.arange(axis, body.n_dof, 3) for axis in range(3)]
    expected_mass = np.mean([m[np.ix_(t, t)].sum() for t in translations])
    assert facts["total_mass"] == pytest.approx(expected_mass, rel=1e-12)


def test_info_reports_six_rigid_body_modes_of_the_free_rack(tmp_path, capsys):
    run(["example", "rack-beams", "--out", tmp_path], capsys)
    code, out, _ = run(["info", tmp_path / "model.h5", "--modes", 8], capsys)
    assert code == 0
    assert "rigid-body modes  6" in out
    assert out.count("(rigid-body mode") == 6
    assert "1.38" in out  # total mass about 1.39 kg


def test_job_with_matrix_files_and_relative_paths(tmp_path, lattice_files, capsys):
    model = (
        'stiffness = "lattice/K.mtx"\nmass = "lattice/M.mtx"\ndofs = "lattice/dofs.csv"\n'
        'nodes = "lattice/nodes.csv"\nconstraints = "lattice/constraints.csv"'
    )
    job = write_job(tmp_path, model=model)
    code, _, err = run(["reduce", job, "--out", tmp_path / "out", "--quiet"], capsys)
    assert code == 0, err
    summary = json.loads((tmp_path / "out" / "summary.json").read_text())
    assert summary["model"]["n_dependent"] == 3


def test_job_and_tables_saved_with_a_byte_order_mark(tmp_path, lattice_files, capsys):
    """Issue #16: a Windows editor saves UTF-8 with a byte order mark; the job file and the
    CSV tables of such an editor read as without it."""
    model = (
        'stiffness = "lattice/K.mtx"\nmass = "lattice/M.mtx"\ndofs = "lattice/dofs.csv"\n'
        'nodes = "lattice/nodes.csv"\nconstraints = "lattice/constraints.csv"'
    )
    job = write_job(tmp_path, model=model)
    for path in [job, *lattice_files.glob("*.csv")]:
        path.write_bytes(b"\xef\xbb\xbf" + path.read_bytes())
    code, _, err = run(["reduce", job, "--out", tmp_path / "out", "--quiet"], capsys)
    assert code == 0, err
    summary = json.loads((tmp_path / "out" / "summary.json").read_text())
    assert summary["model"]["n_dependent"] == 3 and summary["model"]["n_nodes"] == 12


@pytest.mark.slow
def test_second_run_replaces_results_and_keeps_other_files(tmp_path, lattice_files, capsys):
    job = write_job(tmp_path)
    out = tmp_path / "out"
    assert run(["reduce", job, "--out", out, "--quiet"], capsys)[0] == 0
    (out / "notes.txt").write_text("mine")
    (out / "kry" / "stale.txt").write_text("old")
    assert run(["reduce", job, "--out", out, "--quiet"], capsys)[0] == 0
    assert (out / "notes.txt").read_text() == "mine"
    assert not (out / "kry" / "stale.txt").exists()
    assert [p.name for p in tmp_path.iterdir() if p.name.startswith(".")] == []


BAD_JOBS = [
    ("[band]\nf_max_hz = 200\n[[[", "invalid TOML"),
    (None, "unknown key 'f_max'; did you mean 'f_max_hz'"),
    (None, "node 77"),
    (None, "unknown example"),
    (None, "unknown method 'krilov'; did you mean 'krylov'"),
    (None, "is not below the 30 independent dofs"),
    (None, "f_max_hz"),
    (None, "used by another reduction"),
    (None, "moments: 2 values for 3 expansion points"),
    (None, "[frame]: node 999 does not exist"),
    (None, "not a valid name"),
    (None, "must be a whole number"),
    (None, "missing key 'node'"),
    (None, "unknown direction"),
    (None, "must be a finite number"),
    (None, "deflation_tolerance: must be >= 1e-15"),
    (None, "tol: was renamed to 'deflation_tolerance'"),
]


def mutate(text: str, case: int) -> str:
    """The small job, broken in one way per case (same order as BAD_JOBS)."""
    edits = {
        1: ("f_max_hz = 200", "f_max = 200"),
        2: ("node = 120", "node = 77"),
        3: ('file = "lattice/model.h5"', 'example = "rack-bems"'),
        4: ('method = "krylov"', 'method = "krilov"'),
        5: ("order = 6", "order = 5000"),
        6: ("f_max_hz = 200", "f_max_hz = 0"),
        7: ('name = "kry"', 'name = "modal-6"'),
        8: (
            "expansion_points_hz = [0, 100]\nmoments = 2",
            "expansion_points_hz = [0, 100, 150]\nmoments = [1, 2]",
        ),
        9: ("node = 10", "node = 999"),
        10: ('name = "kry"', 'name = "../escape"'),
        11: ("order = 6", 'order = "six"'),
        12: ("node = 60\n", ""),
        13: ('directions = "uz"', 'directions = "uw"'),
        14: ("f_max_hz = 200", "f_max_hz = inf"),
        15: ("moments = 2", "moments = 2\ndeflation_tolerance = 0"),
        16: ("moments = 2", "moments = 2\ntol = 1e-10"),
    }
    old, new = edits[case]
    assert old in text
    return text.replace(old, new, 1)


@pytest.mark.parametrize("case", range(len(BAD_JOBS)))
def test_bad_job_exits_2_with_one_line_and_no_output(case, tmp_path, lattice_files, capsys):
    text, message = BAD_JOBS[case]
    job = tmp_path / "bad.toml"
    job.write_text(
        text
        if text is not None
        else mutate(SMALL_JOB.format(model='file = "lattice/model.h5"', extra=""), case)
    )
    out = tmp_path / "out"
    code, _stdout, err = run(["reduce", job, "--out", out, "--quiet"], capsys)
    assert code == 2
    assert err.count("\n") == 1 and "Traceback" not in err
    assert message in err
    assert str(job) in err or "rack-bems" in err or "node" in err or "modes" in err
    assert not out.exists()
    assert [p.name for p in tmp_path.iterdir() if p.name.startswith(".")] == []


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["reduce", "missing.toml"], "job file not found"),
        (["reduce", "job.toml", "--bogus"], "unrecognized arguments"),
        (["frobnicate"], "invalid choice"),
        (["example", "rack-solidd", "--out", "x"], "unknown example"),
        (["info", "nothing.h5"], "nothing.h5"),
        (["info", "--stiffness", "K.mtx"], "K.mtx: no mass file given"),
        (["info", "--mass", "M.mtx"], "or --stiffness and --mass"),
        (["info", "--stiffness", "bad.mtx", "--mass", "bad.mtx"], "bad.mtx"),
        (["info", "text.h5"], "text.h5"),
        (["info", "--stiffness", "K.mtx", "--mass", "M.mtx", "--modes", "0"], "--modes"),
        (["example", "rack-beams", "--out", "afile"], "afile"),
    ],
)
def test_bad_command_line_exits_2_with_one_line(argv, message, tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    write_matrix_files(spring_lattice(constraints=False), tmp_path)
    (tmp_path / "bad.mtx").write_text(
        "%%MatrixMarket matrix coordinate real general\n3 3 1\n1 1 x\n"
    )
    (tmp_path / "text.h5").write_text("not hdf5")
    (tmp_path / "afile").write_text("")
    with pytest.raises(SystemExit) as exit_info:
        raise SystemExit(main(argv))
    err = capsys.readouterr().err
    assert exit_info.value.code == 2
    assert err.count("\n") == 1 and "Traceback" not in err
    assert message in err


def test_reduced_folder_is_written_only_on_success(tmp_path, lattice_files, capsys, monkeypatch):
    """A job whose second reduction fails numerically (exit 3) leaves nothing behind, not even
    the first reduction's files."""
    import pymorembs.job.run as pipeline
    from pymorembs.errors import NumericalError

    original = pipeline.reduce  # the job layer reduces through pymorembs.reduce
    calls = []

    def failing(prepared, method, **options):
        calls.append(options["name"])
        if options["name"] == "kry":
            raise NumericalError("the expansion point 100 Hz is an eigenfrequency")
        return original(prepared, method, **options)

    monkeypatch.setattr(pipeline, "reduce", failing)
    job = write_job(tmp_path)
    code, _, err = run(["reduce", job, "--out", tmp_path / "out"], capsys)
    assert calls == ["modal-6", "kry"]  # the first reduction ran and was staged
    assert code == 3
    assert err.count("\n") == 1 and "Traceback" not in err
    assert "pymorembs: error: " in err and "is an eigenfrequency" in err
    assert not (tmp_path / "out").exists()
    assert [p.name for p in tmp_path.iterdir() if p.name.startswith(".")] == []
    shutil.rmtree(lattice_files)


def test_unexpected_exception_exits_1_with_traceback_and_bug_request(
    tmp_path, lattice_files, capsys, monkeypatch
):
    import pymorembs.job.run as pipeline

    def broken(prepared, method, **options):
        raise ZeroDivisionError("an internal slip")

    monkeypatch.setattr(pipeline, "reduce", broken)
    job = write_job(tmp_path)
    code, _, err = run(["reduce", job, "--out", tmp_path / "out", "--quiet"], capsys)
    assert code == 1
    assert "Traceback (most recent call last)" in err
    assert "ZeroDivisionError: an internal slip" in err
    last = err.strip().splitlines()[-1]
    assert last == (
        "pymorembs: error: this is a bug in pymorembs; please report it with the job file "
        "(or the command line) and this traceback"
    )
    assert "http" not in err.split("Traceback")[0] and "http" not in last
    assert not (tmp_path / "out").exists()


def test_invalid_toml_names_the_line(tmp_path, capsys):
    job = tmp_path / "job.toml"
    job.write_text('[model]\nexample = "rack-beams"\n\n[frame]\nnode = \n')
    code, _, err = run(["reduce", job, "--out", tmp_path / "out"], capsys)
    assert code == 2 and err.count("\n") == 1
    assert f"{job}:5: invalid TOML: " in err and "(column 8)" in err


@pytest.mark.slow  # 4-10 s: in the slow set (make test stays within its budget)
def test_ports_at_the_frame_node_are_notes_unless_outputs_are_asked_there(tmp_path, capsys):
    """The demo's ports at the frame node (node 2): forces there move the reference frame only,
    the usual joint of a multibody model -- a note, one line per node and side. Outputs asked
    explicitly at the frame node are identically zero: a warning, one line. Issue #27: notes
    and warnings on stderr (as docs/commands.md says), both also with --quiet."""
    text = DEMO.read_text().split("[[reduction]]")[0]
    # 12 modes are not enough up to 1000 Hz (max error 0.15): written anyway, the test is on notes
    text += '[[reduction]]\nname = "m"\nmethod = "modal"\norder = 12\nexport_inaccurate = true\n'
    text = text.replace("points = 400", "points = 200")
    job = tmp_path / "demo.toml"
    job.write_text(text)
    code, out, err = run(["reduce", job, "--out", tmp_path / "out"], capsys)
    assert code == 0
    inputs_note = (
        "pymorembs: note: inputs 2:ux uy uz act on fixed dofs of the frame: no elastic transfer "
        "(they move the reference frame only)"
    )
    outputs_note = inputs_note.replace("inputs", "outputs")
    assert err.splitlines() == [inputs_note, outputs_note]
    assert "fixed dofs of the frame" not in out and "modal" in out  # stdout: stages, table
    summary = json.loads((tmp_path / "out" / "summary.json").read_text())
    assert summary["warnings"] == [] and len(summary["notes"]) == 2
    outputs = (
        '[[outputs]]\nnode = 1\ndirections = "ux"\n\n[[outputs]]\nnode = 2\ndirections = "uz"\n'
    )
    job.write_text(text.replace("[band]", outputs + "\n[band]"))
    code, out, err = run(["reduce", job, "--out", tmp_path / "out2", "--quiet"], capsys)
    assert code == 0 and out == ""
    assert err.splitlines() == [
        "pymorembs: warning: output 2:uz acts on fixed dofs of the frame: no elastic transfer "
        "(it moves the reference frame only)",
        inputs_note,
    ]


def test_info_handles_massless_dofs(tmp_path, capsys):
    """Zero mass on some dofs: no traceback; the finite eigenvalues of (K, M) are reported."""
    body = spring_lattice(constraints=False)
    m = body.mass.tolil()
    for i in (4, 10, 11):
        m[i, :] = 0
        m[:, i] = 0
    write_matrix_files(replace(body, mass=m.tocsr()), tmp_path)
    code, out, err = run(
        [
            "info",
            "--stiffness",
            tmp_path / "K.mtx",
            "--mass",
            tmp_path / "M.mtx",
            "--modes",
            4,
            "--json",
        ],
        capsys,
    )
    assert code == 0, err
    values = sla.eig(body.stiffness.toarray(), m.toarray(), right=False)
    finite = np.sort(values[np.isfinite(values)].real)
    expected = np.sqrt(finite[:4]) / (2 * np.pi)
    assert np.allclose(json.loads(out)["eigenfrequencies_hz"], expected, rtol=1e-8)


TRUSS_JOB = """
[model]
stiffness = "truss/K.mtx"
mass = "truss/M.mtx"
dofs = "truss/dofs.csv"
nodes = "truss/nodes.csv"

[[interface]]
node = 900
position = [0.3, 0.1, 0.05]
kind = "beams"
box = {{ min = [0.25, -1, -1], max = [0.35, 1, 1] }}
youngs_modulus = 1e18
density = 100
diameter = 0.005
{extra}
[frame]
type = "tangent"
node = 900

[[inputs]]
node = 1
directions = "ux uy uz"

[band]
f_max_hz = 2000

[[reduction]]
name = "kry"
method = "krylov"
expansion_points_hz = [0, 1000]
moments = 3
"""


@pytest.fixture
def truss_files(tmp_path):
    from conftest import space_truss

    write_matrix_files(space_truss(), tmp_path / "truss")
    return tmp_path


def test_job_with_an_interface_node(truss_files, capsys):
    job = truss_files / "job.toml"
    job.write_text(TRUSS_JOB.format(extra=""))
    code, _, err = run(["reduce", job, "--out", truss_files / "out", "--quiet"], capsys)
    assert code == 0, err
    summary = json.loads((truss_files / "out" / "summary.json").read_text())
    # 24 truss nodes x 3 + node 900 (6) + rotations of the 6 face nodes (3 each)
    assert summary["model"]["n_dof"] == 72 + 6 + 18
    assert summary["reductions"][0]["static_rel_error"] < 1e-10


def test_info_on_a_buckens_job_reports_rigid_and_elastic_modes(capsys):
    code, out, _ = run(
        ["info", ROOT / "examples" / "rack-beams-buckens.toml", "--modes", 3, "--json"], capsys
    )
    assert code == 0
    facts = json.loads(out)
    assert facts["rigid_body_modes"] == 6
    assert facts["eigenfrequencies_hz"][:6] == [0.0] * 6
    assert facts["eigenfrequencies_hz"][6] == pytest.approx(105.34, abs=0.01)
    assert len(facts["eigenfrequencies_hz"]) == 9


@pytest.mark.parametrize(
    ("old", "new", "message"),
    [
        ('kind = "beams"', 'kind = "glue"', "must be one of rigid"),
        ("box = {", "boxx = {", "unknown key 'boxx'; did you mean 'box'"),
        ("position = [0.3, 0.1, 0.05]", "position = [0.3, 0.1]", "3 finite numbers"),
        ("max = [0.35, 1, 1]", "max = [0.35, 1, 1], mid = 1", "unknown key 'mid'"),
        ("min = [0.25, -1, -1]", "min = [5, 5, 5]", "no node of the model"),
        ("node = 900\nposition", "node = 1\nposition", "exists already"),
        ('kind = "beams"', 'kind = "springs"', "unknown key 'youngs_modulus'"),
        (
            'kind = "beams"\nbox = { min = [0.25, -1, -1], max = [0.35, 1, 1] }\n'
            "youngs_modulus = 1e18\ndensity = 100\ndiameter = 0.005",
            'kind = "springs"\nnodes = [19, 20]\ndamping = 2.0',
            "springs need 'stiffness'",
        ),
    ],
)
def test_bad_interface_tables(old, new, message, truss_files, capsys):
    text = TRUSS_JOB.format(extra="")
    assert old in text
    job = truss_files / "bad.toml"
    job.write_text(text.replace(old, new, 1))
    code, _, err = run(["reduce", job, "--out", truss_files / "out", "--quiet"], capsys)
    assert code == 2 and err.count("\n") == 1
    assert message in err and "[[interface]] #1" in err


def test_reduction_folder_replaces_a_symlink_instead_of_writing_through_it(
    tmp_path, lattice_files, capsys
):
    """An existing ``out/kry`` symlink to a folder elsewhere: the result replaces the link, the
    folder it pointed to is not touched."""
    outside = tmp_path / "elsewhere"
    outside.mkdir()
    (outside / "precious.txt").write_text("keep")
    out = tmp_path / "out"
    out.mkdir()
    (out / "kry").symlink_to(outside, target_is_directory=True)
    job = write_job(tmp_path)
    code, _, err = run(["reduce", job, "--out", out, "--quiet"], capsys)
    assert code == 0, err
    assert not (out / "kry").is_symlink() and (out / "kry" / "reduced.npz").is_file()
    assert sorted(p.name for p in outside.iterdir()) == ["precious.txt"]


@pytest.mark.parametrize("name", ["../x", "/tmp/x", "a/b", ".hidden", "..", "", "a\\b"])
def test_safe_child_refuses_names_that_leave_the_folder(name, tmp_path):
    from pymorembs.errors import UserError
    from pymorembs.job.run import safe_child

    with pytest.raises(UserError, match="would leave the output folder"):
        safe_child(tmp_path, name)
    assert safe_child(tmp_path, "krylov-1.b+c") == tmp_path / "krylov-1.b+c"


FULL_JOB = """
title = "t"
[model]
file = "lattice/model.h5"
[[interface]]
node = 900
position = [0, 0, 0]
kind = "rigid"
nodes = [10, 20]
cylinder = { point = [0, 0, 0], direction = [0, 0, 1], radius = 1.0 }
box = { min = [-1, -1, -1], max = [1, 1, 1] }
[damping]
kind = "rayleigh"
alpha = 0.1
[frame]
type = "tangent"
node = 10
[[inputs]]
node = 60
directions = "ux"
[[outputs]]
node = 60
directions = "ux"
[band]
f_max_hz = 200
[[reduction]]
name = "m"
method = "modal"
order = 4
[export]
outputs = ["npz"]
[time_domain]
clamp_node = 10
load_node = 60
"""

#: (line to misspell in FULL_JOB, where the error is reported, the suggestion)
MISSPELLED = [
    ('title = "t"', "job", "title"),
    ('file = "lattice/model.h5"', "[model]", "file"),
    ('kind = "rigid"', "[[interface]] #1", "kind"),
    ("radius = 1.0 }", "[[interface]] #1.cylinder", "radius"),
    ("max = [1, 1, 1] }", "[[interface]] #1.box", "max"),
    ("alpha = 0.1", "[damping]", "alpha"),
    ('type = "tangent"', "[frame]", "type"),
    ('directions = "ux"\n[[outputs]]', "[[inputs]] #1", "directions"),
    ('directions = "ux"\n[band]', "[[outputs]] #1", "directions"),
    ("f_max_hz = 200", "[band]", "f_max_hz"),
    ("order = 4", "[[reduction]] #1", "order"),
    ('outputs = ["npz"]', "[export]", "outputs"),
    ("load_node = 60", "[time_domain]", "load_node"),
]


@pytest.mark.parametrize(("line", "where", "key"), MISSPELLED, ids=[m[1] for m in MISSPELLED])
def test_a_misspelled_key_in_every_table_is_named_with_a_suggestion(line, where, key, tmp_path):
    """Every table of a job: a key with a doubled letter is an error naming table, key and the
    valid key (``did you mean``), never silently ignored."""
    from pymorembs.errors import UserError
    from pymorembs.job.schema import load_job

    load_job_text = FULL_JOB
    assert line in load_job_text
    typo = key[:2] + key[1] + key[2:]  # e.g. 'tiitle'
    path = tmp_path / "job.toml"
    path.write_text(load_job_text)
    load_job(path)  # the intact job is valid
    path.write_text(load_job_text.replace(line, line.replace(key, typo, 1), 1))
    with pytest.raises(UserError) as info:
        load_job(path)
    message = str(info.value)
    assert message.startswith(f"{path}: {where}")
    assert f"'{typo}'" in message and f"'{key}'" in message


def test_help_says_what_the_tool_does_and_where_the_job_format_is(capsys):
    """Issue #16 day-one: no raw markup, what the tool does, the job format, the variants."""
    for argv, expected in (
        (["--help"], ["finite-element model of an elastic body", "exit codes", "docs/jobs.md"]),
        (["reduce", "--help"], ["docs/jobs.md", "[[reduction]]"]),
        (["example", "--help"], ["rigid", "distributing", "springs", "blade"]),
    ):
        with pytest.raises(SystemExit) as stop:
            main(argv)
        assert stop.value.code == 0
        text = " ".join(capsys.readouterr().out.split())
        assert "``" not in text
        for phrase in expected:
            assert phrase in text, (argv, phrase)


def test_a_job_parsed_from_a_dictionary_runs_without_a_job_file(tmp_path):
    """Issue #16: run_job on parse_job(dict, path) with no file at path hashed no file."""
    import tomllib

    from pymorembs.job.run import run_job
    from pymorembs.job.schema import parse_job

    text = """
[model]
example = "rack-beams"
[frame]
type = "tangent"
node = 2
[[inputs]]
node = 1
directions = "ux"
[band]
f_max_hz = 500
points = 200
[[reduction]]
method = "modal"
order = 6
export_inaccurate = true  # max error 1.8: the test is about the job file's hash
"""
    job = parse_job(tomllib.loads(text), tmp_path / "never-written.toml")
    summary = run_job(job, tmp_path / "out")
    assert summary.reductions[0].order == 6
    assert str(tmp_path / "never-written.toml") not in summary.provenance["inputs"]


@pytest.mark.parametrize("below", ["", "out"])
def test_out_at_or_below_a_file_fails_before_any_work(below, tmp_path, lattice_files, capsys):
    """Issue #16: ``--out`` at or below an existing file computed the whole job first and then
    failed with a traceback."""
    job = write_job(tmp_path)
    blocker = tmp_path / "some.txt"
    blocker.write_text("not a folder\n")
    out = blocker / below if below else blocker
    code, stdout, err = run(["reduce", job, "--out", out], capsys)
    assert code == 2 and err.count("\n") == 1 and "Traceback" not in err
    assert err.startswith(f"pymorembs: error: {out}: the output folder ")
    assert ("below the file" in err) == bool(below)
    assert "loading the model" not in stdout  # nothing was started
    assert blocker.read_text() == "not a folder\n"


def test_the_stiffness_file_as_the_mass_file_exits_2(tmp_path, lattice_files, capsys):
    """Issue #16: K given twice (the same file, or a copy of it as M.mtx) ran to exit 0."""
    shutil.copy(lattice_files / "K.mtx", lattice_files / "K-copy.mtx")
    for mass, words in (("K.mtx", "given as both the stiffness and the mass"),
                        ("K-copy.mtx", "the mass matrix is the stiffness matrix")):  # fmt: skip
        model = f'stiffness = "lattice/K.mtx"\nmass = "lattice/{mass}"\ndofs = "lattice/dofs.csv"'
        job = write_job(tmp_path, model=model)
        code, out, err = run(["reduce", job, "--out", tmp_path / "out"], capsys)
        assert code == 2 and err.count("\n") == 1 and words in err, err
        assert "frequency response" not in out and not (tmp_path / "out").exists()


def test_a_band_in_rad_per_s_warns_on_the_console_and_in_the_summary(
    tmp_path, lattice_files, capsys
):
    job = write_job(tmp_path)
    job.write_text(job.read_text().replace("f_max_hz = 200", "f_max_hz = 1256.64"))
    code, out, err = run(["reduce", job, "--out", tmp_path / "out", "--quiet"], capsys)
    assert code == 0 and out == ""
    [line] = err.splitlines()
    assert line.startswith("pymorembs: warning: band f_max_hz = 1256.64 is 2 pi x 200")
    summary = json.loads((tmp_path / "out" / "summary.json").read_text())
    assert line.removeprefix("pymorembs: warning: ") in summary["warnings"]


def test_outputs_vtu_writes_a_readable_file_per_reduction(tmp_path, lattice_files, capsys):
    """``[export] outputs = ["vtu"]``: ``<name>.vtu`` per reduction, listed in the summary."""
    import meshio

    job = write_job(tmp_path, extra='[export]\noutputs = ["vtu"]')
    out = tmp_path / "out"
    code, _, err = run(["reduce", job, "--out", out, "--quiet"], capsys)
    assert code == 0, err
    summary = json.loads((out / "summary.json").read_text())
    body = spring_lattice()
    assert [entry["name"] for entry in summary["reductions"]] == ["modal-6", "kry"]
    for entry in summary["reductions"]:
        name = entry["name"]
        assert sorted(p.name for p in (out / name).glob("*.vtu")) == [f"{name}.vtu"]
        assert f"{name}/{name}.vtu" in entry["files"]
        mesh = meshio.read(out / name / f"{name}.vtu")
        assert np.array_equal(mesh.point_data["node_id"], body.node_ids)
        assert [block.type for block in mesh.cells] == ["vertex"]  # no elements: the nodes
        shapes = [key for key in mesh.point_data if key.startswith("shape_")]
        assert len(shapes) == entry["order"] > 0
        assert {"static_60_ux", "static_60_uy", "static_120_uz"} <= set(mesh.point_data)


def test_outputs_vtu_of_a_model_without_coordinates_exits_2_before_reducing(
    tmp_path, lattice_files, capsys
):
    write_body_h5(replace(spring_lattice(), has_coordinates=False), tmp_path / "bare.h5")
    job = write_job(tmp_path, model='file = "bare.h5"', extra='[export]\noutputs = ["vtu"]')
    out = tmp_path / "out"
    code, _, err = run(["reduce", job, "--out", out, "--quiet"], capsys)
    assert code == 2 and err.count("\n") == 1
    assert "no node coordinates" in err and "VTU" in err
    assert not out.exists()
