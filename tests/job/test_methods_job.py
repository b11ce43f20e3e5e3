"""All reduction methods through a job on rack-beams: relations the paper reports, and outputs."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from pymorembs.job.cli import main

ROOT = Path(__file__).resolve().parents[2]
HEAD = (ROOT / "examples" / "rack-beams-demo.toml").read_text().split("[[reduction]]")[0]

METHODS = """
[[reduction]]
name = "lowest-40"
method = "modal"
order = 40

[[reduction]]
name = "best-40"
method = "modal"
select = "best"
order = 40

[[reduction]]
name = "best-40-frm"
method = "modal"
select = "best"
order = 40
frm_hz = [1]

[[reduction]]
name = "cb"
method = "craig-bampton"
fixed_modes = 20

[[reduction]]
name = "soaga"
method = "soaga"
tolerance = 1e-4

[[reduction]]
name = "krylov-gramian"
method = "gramian"
order = 10
first_stage = "soaga"

[[reduction]]
name = "pod"
method = "pod"
tolerance = 1e-10
"""


@pytest.fixture(scope="module")
def summary(tmp_path_factory):
    folder = tmp_path_factory.mktemp("methods")
    job = folder / "job.toml"
    job.write_text(HEAD + METHODS)
    assert main(["reduce", str(job), "--out", str(folder / "out"), "--quiet"]) == 0
    data = json.loads((folder / "out" / "summary.json").read_text())
    return folder / "out", {r["name"]: r for r in data["reductions"]}, data


def test_best_modes_beat_the_lowest_and_frm_makes_statics_exact(summary):
    _, r, _ = summary
    assert r["best-40"]["max_rel_error"] < 0.1 * r["lowest-40"]["max_rel_error"]
    assert r["best-40-frm"]["static_rel_error"] < 1e-10
    assert r["lowest-40"]["static_rel_error"] > 1e-8
    assert r["cb"]["static_rel_error"] < 1e-10  # constraint modes: exact statics at the inputs


def test_soaga_meets_its_tolerance_and_its_estimate_tracks_the_error(summary):
    folder, r, _ = summary
    soaga = r["soaga"]
    assert soaga["max_rel_error"] <= 1e-4
    assert soaga["error_estimate"] <= 1e-4
    assert 0.1 < soaga["error_estimate"] / soaga["max_rel_error"] < 10
    curve = np.loadtxt(folder / "soaga" / "error_estimate.csv", delimiter=",", skiprows=1)
    assert curve.shape[1] == 2 and curve.shape[0] >= 200


def test_two_step_gramian_is_small_and_accurate(summary):
    _, r, _ = summary
    gram = r["krylov-gramian"]
    assert gram["order"] == 10
    assert gram["max_rel_error"] < r["lowest-40"]["max_rel_error"]  # 10 beat 40 modes
    sigma = np.asarray(gram["parameters"]["sigma"])
    assert np.all(np.diff(sigma) <= 0) and sigma[0] > 0
    pod = r["pod"]
    indicator = np.asarray(pod["parameters"]["indicator"])
    n = pod["order"]
    assert indicator[n - 1] <= 1e-10 and (n == 1 or indicator[n - 2] > 1e-10)  # smallest n


def test_overview_plots_are_written(summary):
    folder, _, data = summary
    assert "decay.png" in data["files"]
    for name in ("error.png", "decay.png"):
        assert (folder / name).read_bytes()[:4] == b"\x89PNG"


@pytest.mark.parametrize(
    ("reduction", "message"),
    [
        ('method = "modal"\norder = 4\nselect = "worst"', "must be 'lowest' or 'best'"),
        ('method = "modal"\norder = 40\ncandidates = 30', "must exceed the order"),
        ('method = "craig-bampton"\norder = 5\nfixed_modes = 3', "set by the inputs"),
        ('method = "soaga"', "soaga needs 'order'"),
        ('method = "soaga"\ntolerance = 2.0', "must lie in (0, 1)"),
        ('method = "gramian"', "gramian needs 'order' or 'tolerance'"),
        ('method = "gramian"\norder = 5\nfirst_stage = "magic"', "first_stage"),
        (
            'method = "gramian"\norder = 5\nfirst_stage = "krylov"\nexpansion_points_hz = [0]',
            "[[reduction]] #1: the krylov first stage needs 'moments' or 'first_order'",
        ),
        ('method = "pod"\ntolerance = 1e-6\nsnapshot = 20', "did you mean 'snapshots'"),
        (
            'method = "krylov"\nexpansion_points_hz = [0]\nmoments = 2\ntwo_sided = "yes"',
            "true or false",
        ),
    ],
)
def test_bad_method_options(reduction, message, tmp_path, capsys):
    job = tmp_path / "bad.toml"
    job.write_text(HEAD + '[[reduction]]\nname = "r"\n' + reduction + "\n")
    assert main(["reduce", str(job), "--out", str(tmp_path / "out"), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert message in err and err.count("\n") == 1
