"""Verified, reproducible outputs: byte-identical files from two runs, provenance in the
summary, atomic writes and no unsafe parsing anywhere in ``src/``."""

from __future__ import annotations

import hashlib
import json
import os
import re
import subprocess
import sys
import time
import zipfile
from pathlib import Path

import numpy as np
import pytest
import scipy.io

from pymorembs.export.deterministic import DEFAULT_TIME, fixed_time, write_mat, write_npz

ROOT = Path(__file__).resolve().parents[2]
SRC = ROOT / "src" / "pymorembs"
DEMO = ROOT / "examples" / "rack-beams-demo.toml"
#: Files that must be byte-identical between runs (everything but the timed summary/report).
COMPARED = (".sid_fem", ".mtx", ".mat", ".npz", ".csv")


def _run_demo(out: Path, seed: str) -> None:
    """The demo job in a fresh process, with its own hash seed (set order, dict of sets ...)."""
    env = {**os.environ, "PYTHONHASHSEED": seed}
    env.pop("SOURCE_DATE_EPOCH", None)
    done = subprocess.run(
        [
            sys.executable,
            "-m",
            "pymorembs.job.cli",
            "reduce",
            str(DEMO),
            "--out",
            str(out),
            "--quiet",
        ],
        capture_output=True,
        text=True,
        env=env,
        timeout=600,
    )
    assert done.returncode == 0, done.stderr


@pytest.fixture(scope="module")
def two_runs(tmp_path_factory) -> tuple[Path, Path]:
    base = tmp_path_factory.mktemp("reproducible")
    first, second = base / "run1", base / "run2"
    _run_demo(first, "1")
    time.sleep(2.1)  # zip archives store times in 2 s steps: a timestamp would now differ
    _run_demo(second, "2")
    return first, second


def _files(folder: Path, reduction: str) -> list[Path]:
    return sorted(
        p.relative_to(folder)
        for p in (folder / reduction).iterdir()
        if p.suffix.lower() in COMPARED
    )


@pytest.mark.slow
def test_krylov_files_are_byte_identical(two_runs):
    first, second = two_runs
    names = _files(first, "krylov")
    kinds = {p.suffix.lower() for p in names}
    assert kinds == set(COMPARED), kinds  # SID, Matrix Market, MATLAB, NumPy, CSV all there
    assert names == _files(second, "krylov")
    different = [str(p) for p in names if (first / p).read_bytes() != (second / p).read_bytes()]
    assert different == []


@pytest.mark.slow
def test_modal_files_are_byte_identical(two_runs):
    first, second = two_runs
    names = _files(first, "modal-40")
    different = [str(p) for p in names if (first / p).read_bytes() != (second / p).read_bytes()]
    assert different == []


def _without_timings(value):
    if isinstance(value, dict):
        return {
            k: _without_timings(v)
            for k, v in value.items()
            if not (k.endswith("_s") or k in ("seconds", "timings_s"))
        }
    if isinstance(value, list):
        return [_without_timings(v) for v in value]
    return value


@pytest.mark.slow
def test_summary_records_inputs_software_and_settings(two_runs):
    first, second = two_runs
    summary = json.loads((first / "summary.json").read_text())
    provenance = summary["provenance"]
    digest = hashlib.sha256(DEMO.read_bytes()).hexdigest()
    assert provenance["inputs"] == {str(DEMO): digest}
    assert provenance["model"] == {"example": "rack-beams", "options": {}}
    software = provenance["software"]
    assert software["numpy"] == np.__version__ and software["scipy"] == scipy.__version__
    assert software["python"] == ".".join(map(str, sys.version_info[:3]))
    for key in ("pymorembs", "platform", "pypardiso", "mkl", "h5py"):
        assert key in software
    assert provenance["solver"]["requested"] in ("auto", "superlu", "pardiso")
    settings = provenance["settings"]
    assert settings["band_hz"] == [0.0, 1000.0] and settings["points"] == 400
    assert [r["name"] for r in settings["reductions"]] == ["modal-40", "krylov"]
    assert settings["reductions"][1]["order"] == 48
    assert settings["inertia_loads"]["active"] is True  # the demo exports SID, Exudyn, Neweul
    assert summary["units"]["system"] == "m-kg-s-N"
    assert "symmetric matrices" in summary["validation"]["checks"]
    report = (first / "report.html").read_text()
    assert '<td class="text">unit system</td><td class="text">m-kg-s-N (m, kg, s, N;' in report
    # the rest of the summary is reproducible too, except the times and the modal reduction
    other = json.loads((second / "summary.json").read_text())
    a, b = _without_timings(summary), _without_timings(other)
    for s in (a, b):
        s["reductions"] = [r for r in s["reductions"] if r["name"] != "modal-40"]
        s["validation"]["facts"].pop("lowest_eigenvalues")  # an iterative estimate
    assert a == b


def test_npz_and_mat_writers_store_a_fixed_time(tmp_path, monkeypatch):
    monkeypatch.delenv("SOURCE_DATE_EPOCH", raising=False)
    arrays = {"M": np.eye(3), "labels": np.array(["1:ux", "2:uy"]), "n": np.arange(4)}
    write_npz(tmp_path / "a.npz", arrays, compress=True)
    write_mat(tmp_path / "a.mat", arrays, do_compression=True)
    first = (tmp_path / "a.npz").read_bytes(), (tmp_path / "a.mat").read_bytes()
    time.sleep(2.1)
    write_npz(tmp_path / "a.npz", arrays, compress=True)
    write_mat(tmp_path / "a.mat", arrays, do_compression=True)
    assert ((tmp_path / "a.npz").read_bytes(), (tmp_path / "a.mat").read_bytes()) == first
    with zipfile.ZipFile(tmp_path / "a.npz") as archive:
        assert {i.date_time for i in archive.infolist()} == {DEFAULT_TIME}
    loaded = np.load(tmp_path / "a.npz", allow_pickle=False)
    assert np.array_equal(loaded["M"], np.eye(3)) and list(loaded["labels"]) == ["1:ux", "2:uy"]
    mat = scipy.io.loadmat(tmp_path / "a.mat")
    assert np.array_equal(mat["M"], np.eye(3))
    assert first[1].startswith(b"MATLAB 5.0 MAT-file, Platform: pymorembs, Created on: Tue Jan")

    monkeypatch.setenv("SOURCE_DATE_EPOCH", "1700000000")  # 2023-11-14 22:13:20 UTC
    assert fixed_time() == (2023, 11, 14, 22, 13, 20)
    write_npz(tmp_path / "b.npz", arrays)
    with zipfile.ZipFile(tmp_path / "b.npz") as archive:
        assert {i.date_time for i in archive.infolist()} == {(2023, 11, 14, 22, 13, 20)}
    write_mat(tmp_path / "b.mat", arrays)
    assert b"Created on: Tue Nov 14 22:13:20 2023" in (tmp_path / "b.mat").read_bytes()[:116]


def _code_lines(path: Path) -> list[tuple[int, str]]:
    """Lines of a source file without comments and docstrings (a simple scan)."""
    lines, in_doc = [], False
    for number, line in enumerate(path.read_text().splitlines(), start=1):
        stripped = line.strip()
        quotes = stripped.count('"""')
        if in_doc:
            in_doc = quotes % 2 == 0
            continue
        if stripped.startswith('"""'):
            in_doc = quotes == 1
            continue
        lines.append((number, line.split("#")[0]))
    return lines


#: Calls that can write files; their target must be the temporary path of ``atomic_path``
#: (``tmp``) or a file object opened on it (``fh``).
WRITERS = re.compile(
    r"(savefig|np\.save\w*|savemat|mmwrite|savetxt|h5py\.File|zipfile\.ZipFile|(?<![\w.])open)"
    r"\(\s*(?:str\()?([\w.]+)(.*)"
)
WRITE_MODE = re.compile(r"[\"'](w|wb|a|ab|x|xb|r\+b|r\+)[\"']")


def test_every_file_is_written_through_atomic_path():
    offenders, seen = [], 0
    for path in SRC.rglob("*.py"):
        if path.name == "atomic.py":
            continue
        for number, line in _code_lines(path):
            for match in WRITERS.finditer(line):
                call, target, rest = match.groups()
                if call in ("open", "h5py.File", "zipfile.ZipFile") and not WRITE_MODE.search(rest):
                    continue  # reading
                seen += 1
                if target not in ("tmp", "fh"):
                    offenders.append(f"{path.relative_to(ROOT)}:{number}: {line.strip()}")
    assert seen >= 9  # the scan finds the writers (zip, mat, mtx, csv, png, h5 ...)
    assert offenders == []


UNSAFE = re.compile(
    r"\bimport\s+(pickle|marshal|shelve|dill)\b|\bpickle\.|(?<![\w.])(eval|exec)\(|"
    r"allow_pickle\s*=\s*True|yaml\.load\(|\bcloudpickle\b"
)


def test_no_pickle_eval_or_exec_in_src():
    offenders = [
        f"{path.relative_to(ROOT)}:{number}: {line.strip()}"
        for path in SRC.rglob("*.py")
        for number, line in _code_lines(path)
        if UNSAFE.search(line)
    ]
    assert offenders == []


@pytest.mark.parametrize(
    ("change", "message"),
    [
        ("stiffness", "reduced stiffness matrix is indefinite"),
        ("damping", "reduced damping matrix is indefinite"),
        ("mass", "reduced mass matrix is not positive definite"),
        ("nan", "reduced input or output matrix has NaN"),
        ("asymmetric", "reduced stiffness matrix is not symmetric"),
    ],
)
def test_a_bad_reduced_model_is_refused_and_nothing_written(change, message, tmp_path):
    from dataclasses import replace

    from conftest import spring_lattice
    from pymorembs.body import Damping
    from pymorembs.errors import NumericalError
    from pymorembs.export.outputs import write_outputs
    from pymorembs.preparation import Frame, Port, prepare
    from pymorembs.reduction.krylov import krylov_reduction
    from pymorembs.reduction.projection import reduced_model

    ports = [Port.parse(60, "ux uy")]
    body = spring_lattice(damping=Damping("rayleigh", alpha=0.5, beta=1e-4))
    prepared = prepare(body, Frame("tangent", 10), ports, ports)
    model = reduced_model(prepared.system, krylov_reduction(prepared.system, [0.0], moments=3))
    folder = tmp_path / "kry"
    folder.mkdir()
    write_outputs(model, prepared, "kry", ("npz", "mtx", "mat"), [60], folder)  # the good one
    assert len(list(folder.iterdir())) == 7
    folder = tmp_path / "bad"
    folder.mkdir()
    system = model.system
    k, m, d = (np.array(a, dtype=float) for a in (system.stiffness, system.mass, system.damping))
    if change == "stiffness":
        k[0, 0] = -abs(k).max()
    elif change == "damping":
        d[1, 1] = -abs(d).max()
    elif change == "mass":
        m[2, 2] = -1.0
    elif change == "asymmetric":
        k[0, 1] += 1e-3 * abs(k).max()
    b = np.array(system.input_matrix)
    if change == "nan":
        b[0, 0] = np.nan
    bad = replace(model, system=replace(system, stiffness=k, mass=m, damping=d, input_matrix=b))
    with pytest.raises(NumericalError) as info:
        write_outputs(bad, prepared, "bad", ("npz", "mtx", "mat"), [60], folder)
    assert message in str(info.value) and "nothing was written" in str(info.value)
    assert list(folder.iterdir()) == []


def test_provenance_hashes_the_files_found_beside_a_calculix_export(tmp_path):
    """A CalculiX job names only job.sti; the .mas, .dof and deck read beside it are inputs too."""
    from pymorembs.job.run import provenance
    from pymorembs.job.schema import load_job

    data = Path(__file__).parents[1] / "data" / "calculix_c3d20_block"
    job_file = tmp_path / "job.toml"
    job_file.write_text(
        f'[model]\nfile = "{(data / "free.sti").as_posix()}"\n\n[frame]\ntype = "buckens"\n\n'
        '[[inputs]]\nnode = 1\ndirections = "ux"\n\n[band]\nf_max_hz = 1000\n\n'
        '[[reduction]]\nname = "modal"\nmethod = "modal"\norder = 6\n',
        encoding="utf-8",
    )
    inputs = provenance(load_job(job_file))["inputs"]
    expected = {job_file} | {data / f"free.{ext}" for ext in ("sti", "mas", "dof", "inp")}
    assert {Path(p).resolve() for p in inputs} == {p.resolve() for p in expected}
    mas = next(p for p in inputs if p.endswith("free.mas"))
    assert inputs[mas] == hashlib.sha256((data / "free.mas").read_bytes()).hexdigest()
