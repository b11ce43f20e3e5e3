"""Each FE format through the command line: info works, a malformed file exits 2 in one line."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest

from pymorembs.job.cli import main

GOOD_ABAQUS = """** stiffness, matrix input layout: node, dof, node, dof, value (one triangle)
1,1, 1,1, 2.0E+06
1,1, 2,1, -1.0E+06
2,1, 2,1, 1.0E+06
"""
GOOD_ABAQUS_MASS = "1,1, 1,1, 1.0\n2,1, 2,1, 1.0\n"


def run(argv, capsys):
    code = main([str(a) for a in argv])
    captured = capsys.readouterr()
    return code, captured.out, captured.err


def test_info_on_an_abaqus_model(tmp_path, capsys):
    (tmp_path / "job_STIF1.mtx").write_text(GOOD_ABAQUS)
    (tmp_path / "job_MASS1.mtx").write_text(GOOD_ABAQUS_MASS)
    code, out, err = run(
        [
            "info",
            "--stiffness",
            tmp_path / "job_STIF1.mtx",
            "--mass",
            tmp_path / "job_MASS1.mtx",
            "--modes",
            1,
            "--json",
        ],
        capsys,
    )
    assert code == 0, err
    # two masses of 1 kg, springs 1e6 N/m to ground and between: omega^2 = (3 -+ sqrt 5)/2 1e6
    expected = (((3 - 5**0.5) / 2 * 1e6) ** 0.5) / (2 * 3.141592653589793)
    assert json.loads(out)["eigenfrequencies_hz"][0] == pytest.approx(expected, rel=1e-10)


def test_info_on_the_ansys_example_full_file(capsys):
    from ansys.mapdl.reader import examples

    code, out, err = run(["info", examples.fullfile, "--modes", 4, "--json"], capsys)
    assert code == 0, err
    frequencies = json.loads(out)["eigenfrequencies_hz"]
    assert frequencies == pytest.approx([1283.20, 1283.20, 5781.97, 6919.40], abs=0.01)


@pytest.mark.slow  # 4-10 s: in the slow set (make test stays within its budget)
def test_info_on_rack_solid(tmp_path, capsys):
    assert run(["example", "rack-solid", "--dofs", 8000, "--out", tmp_path], capsys)[0] == 0
    code, out, _ = run(["info", tmp_path / "model.h5", "--modes", 3, "--json"], capsys)
    assert code == 0
    facts = json.loads(out)
    assert facts["rigid_body_modes"] == 6
    assert 100.0 < facts["eigenfrequencies_hz"][6] < 112.0  # rack-beams: 105.3 Hz


def _truncated_full(tmp_path: Path) -> Path:
    from ansys.mapdl.reader import examples

    data = Path(examples.fullfile).read_bytes()
    path = tmp_path / "cut.full"
    path.write_bytes(data[: len(data) // 3])
    return path


MALFORMED = {
    # name: (files to write {name: text}, argv after "info", expected text in the message)
    "abaqus-nan": (
        {"a_STIF1.mtx": "1,1, 1,1, nan\n", "a_MASS1.mtx": "1,1, 1,1, 1.0\n"},
        ["--stiffness", "a_STIF1.mtx", "--mass", "a_MASS1.mtx"],
        "a_STIF1.mtx:1",
    ),
    "abaqus-conflict": (
        {"b_STIF1.mtx": GOOD_ABAQUS + "1,1, 1,1, 3.0E+06\n", "b_MASS1.mtx": GOOD_ABAQUS_MASS},
        ["--stiffness", "b_STIF1.mtx", "--mass", "b_MASS1.mtx"],
        "b_STIF1.mtx:",
    ),
    "dmig-truncated": (
        {
            "m.pch": "DMIG    KAAX           0       6       2       0\n"
            "DMIG    KAAX           1       1\n*       1       1  1.0D+\n"
        },
        ["m.pch"],
        "m.pch",
    ),
    "mmf-nonsymmetric": (
        {
            "K.mtx": "%%MatrixMarket matrix coordinate real general\n2 2 3\n"
            "1 1 2.0\n1 2 -1.0\n2 2 1.0\n",
            "M.mtx": "%%MatrixMarket matrix coordinate real general\n2 2 2\n1 1 1.0\n2 2 1.0\n",
            "map.mapping": "Matrix Eqn   Node   DOF\n1 1 UX\n2 2 UX\n",
        },
        ["--stiffness", "K.mtx", "--mass", "M.mtx", "--mapping", "map.mapping"],
        "not symmetric",
    ),
    "mtx-wrong-header": (
        {
            "K2.mtx": "%%MatrixMarket matrix wrongthing real general\n1 1 1\n1 1 1\n",
            "M2.mtx": "%%MatrixMarket matrix coordinate real general\n1 1 1\n1 1 1\n",
        },
        ["--stiffness", "K2.mtx", "--mass", "M2.mtx"],
        "K2.mtx",
    ),
    "h5-text": ({"model.h5": "this is not HDF5\n"}, ["model.h5"], "model.h5"),
    "op4-truncated": (
        {"k.op4": "       2       2       6       2KAAX    1P,3E23.16\n       1       1       2\n"},
        ["k.op4", "--dofs", "dofs.csv"],
        "k.op4",
    ),
}


@pytest.mark.parametrize("case", sorted(MALFORMED))
def test_malformed_file_of_each_format_exits_2(case, tmp_path, capsys, monkeypatch):
    files, argv, message = MALFORMED[case]
    monkeypatch.chdir(tmp_path)
    (tmp_path / "dofs.csv").write_text("node,direction\n1,ux\n2,ux\n")
    for name, text in files.items():
        (tmp_path / name).write_text(text)
    code, _, err = run(["info", *argv], capsys)
    assert code == 2, err
    assert err.count("\n") == 1 and "Traceback" not in err
    assert message in err


def test_truncated_ansys_full_file_exits_2(tmp_path, capsys):
    path = _truncated_full(tmp_path)
    code, _, err = run(["info", path], capsys)
    assert code == 2 and err.count("\n") == 1 and "cut.full" in err
    shutil.rmtree(tmp_path)
