"""The distributed backend (issue #30 item 6): MUMPS over MPI, ``PYMOREMBS_SOLVER=mumps-mpi``.

Without mpi4py or MUMPS (``make mpi`` installs them) the tests that run MUMPS skip; the others
check what needs no MPI. MUMPS runs in child processes only: MPI initialized in the test
process would stay initialized for the tests that fork worker pools after it.
"""

from __future__ import annotations

import ctypes
import ctypes.util
import importlib.util
import json
import os
import shutil
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest
import scipy.sparse as sp

from pymorembs.errors import UserError
from pymorembs.job.cli import main
from pymorembs.linalg import backends
from pymorembs.linalg.mumps_mpi import MumpsStruct, launched_ranks, serve_solver_ranks

ROOT = Path(__file__).resolve().parents[2]
HAVE_MUMPS = importlib.util.find_spec("mpi4py") is not None and all(
    ctypes.util.find_library(f"{kind}mumps") for kind in "dz"
)
needs_mumps = pytest.mark.skipif(not HAVE_MUMPS, reason="mpi4py or MUMPS not installed (make mpi)")
needs_mpiexec = pytest.mark.skipif(
    not HAVE_MUMPS or shutil.which("mpiexec") is None,
    reason="mpi4py, MUMPS or mpiexec missing (make mpi)",
)


def run_python(script: str, ranks: int = 0, timeout: float = 120) -> dict:
    """Run ``script`` in a child Python (under ``mpiexec -n ranks`` if ranks > 0) with this
    checkout first on the path; the JSON it prints last on rank 0."""
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join(
        p for p in (str(ROOT / "src"), str(ROOT / "tests"), env.get("PYTHONPATH", "")) if p
    )
    env.update(PYMOREMBS_SOLVER="mumps-mpi", OMP_NUM_THREADS="1")
    env.update(OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1")  # CI runs as root
    command = [sys.executable, "-c", textwrap.dedent(script)]
    if ranks:
        command = ["mpiexec", "--oversubscribe", "--bind-to", "none", "-n", str(ranks), *command]
    done = subprocess.run(command, capture_output=True, text=True, env=env, timeout=timeout)
    assert done.returncode == 0, done.stderr[-2000:]
    return json.loads(done.stdout.strip().splitlines()[-1])


def test_structure_has_the_layout_of_the_mumps_5_5_header() -> None:
    # sizeof / offsetof of DMUMPS_STRUC_C compiled from Debian's dmumps_c.h (libmumps-dev 5.5.1)
    assert ctypes.sizeof(MumpsStruct) == 8360
    assert MumpsStruct.rhs.offset == 5600
    assert MumpsStruct.version_number.offset == 7072
    assert MumpsStruct.metis_options.offset == 8196


def test_without_a_launcher_nothing_is_served(monkeypatch) -> None:
    for name in ("OMPI_COMM_WORLD_SIZE", "PMI_SIZE"):
        monkeypatch.delenv(name, raising=False)
    assert launched_ranks() == 1
    assert serve_solver_ranks() is False


def test_several_ranks_need_the_distributed_solver(monkeypatch, capsys) -> None:
    monkeypatch.setenv("OMPI_COMM_WORLD_SIZE", "2")
    monkeypatch.setenv("PYMOREMBS_SOLVER", "pardiso")
    monkeypatch.setenv("OMPI_COMM_WORLD_RANK", "1")
    assert serve_solver_ranks() is True  # rank 1 ends quietly ...
    monkeypatch.setenv("OMPI_COMM_WORLD_RANK", "0")
    with pytest.raises(UserError, match="PYMOREMBS_SOLVER=mumps-mpi"):
        serve_solver_ranks()
    assert main(["info", "no-model.h5"]) == 2  # ... rank 0 says why, in one line
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "2 MPI ranks" in err and "Traceback" not in err


def test_asking_for_mumps_where_it_is_missing_is_a_user_error(monkeypatch) -> None:
    monkeypatch.setenv("PYMOREMBS_SOLVER", "mumps-mpi")
    factory, _works, install = backends.OPTIONAL_BACKENDS["mumps-mpi"]
    monkeypatch.setitem(backends.OPTIONAL_BACKENDS, "mumps-mpi", (factory, lambda: False, install))
    with pytest.raises(UserError, match="make mpi"):
        backends.default_backend()
    with pytest.raises(UserError, match="make mpi"):
        backends.factorize(sp.eye(3, format="csr"), True, "mumps-mpi")


SOLVES = """
    import json, sys
    import numpy as np, scipy.sparse as sp
    from pymorembs.linalg import serve_solver_ranks
    if serve_solver_ranks():  # ranks > 0 under mpiexec
        sys.exit(0)
    from conftest import spring_lattice
    from pymorembs.errors import NumericalError
    from pymorembs.linalg.backends import factorize
    from pymorembs.linalg.mumps_mpi import rank_statistics

    body = spring_lattice(40)
    k, m = sp.csr_matrix(body.stiffness), sp.csr_matrix(body.mass)
    n = k.shape[0]
    rng = np.random.default_rng(1)
    skew = sp.random(n, n, density=0.05, random_state=rng) * 1e4
    matrices = {  # K - omega^2 M across the lowest modes; complex; not symmetric
        "indefinite": (k - (2 * np.pi * 60) ** 2 * m, True),
        "complex": ((1 + 0.02j) * k - (2 * np.pi * 60) ** 2 * m, True),
        "nonsymmetric": (k - (2 * np.pi * 60) ** 2 * m + skew - skew.T * 0.5, False),
    }
    rhs = rng.standard_normal((n, 4)) + 1j * rng.standard_normal((n, 4))
    out = {}
    for name, (matrix, symmetric) in matrices.items():
        matrix = sp.csr_matrix(matrix)
        mumps = factorize(matrix, symmetric, "mumps-mpi")
        dense = np.linalg.solve(matrix.toarray(), rhs)  # a dense LU, no sparse code of ours
        for label, b, want in (("block", rhs, dense), ("vector", rhs[:, 0], dense[:, 0])):
            x = mumps.solve(b)
            out[f"{name} {label}"] = float(np.linalg.norm(x - want) / np.linalg.norm(want))
        out[f"{name} backend"] = mumps.backend
        out[f"{name} entries"] = mumps.nnz_factor
    try:
        factorize(sp.csr_matrix(k - k), True, "mumps-mpi")
        out["singular"] = "factorized"
    except NumericalError as exc:
        out["singular"] = str(exc)
    out["ranks"] = len(rank_statistics())
    print(json.dumps(out))
"""


def check_solves(result: dict, ranks: int) -> None:
    for name in ("indefinite", "complex", "nonsymmetric"):
        assert result[f"{name} backend"] == "mumps-mpi"
        assert result[f"{name} entries"] > 0
        assert result[f"{name} block"] < 1e-10, name
        assert result[f"{name} vector"] < 1e-10, name
    assert "singular" in result["singular"]
    assert result["ranks"] == ranks


@pytest.mark.slow  # 2-4 s: a child Python with MPI
@needs_mumps
def test_solves_match_a_dense_solve_on_one_rank() -> None:
    check_solves(run_python(SOLVES), ranks=1)


@pytest.mark.slow
@needs_mpiexec
def test_solves_match_a_dense_solve_on_two_ranks() -> None:
    check_solves(run_python(SOLVES, ranks=2), ranks=2)


BODY = """
    import json, os, sys
    import numpy as np
    from pymorembs.linalg import serve_solver_ranks
    if serve_solver_ranks():
        sys.exit(0)
    from conftest import spring_lattice
    from pymorembs.analysis import transfer_function
    from pymorembs.frequencies import frequency_grid
    from pymorembs.job.run import run_reduction
    from pymorembs.job.schema import ReductionSpec
    from pymorembs.methods import method_options
    from pymorembs.preparation import Frame, Port, prepare
    from pymorembs.reduction import reduced_model

    ports = [Port.parse(60, "ux uy")]
    system = prepare(spring_lattice(40), Frame("tangent", 10), ports, ports).system
    options = {"expansion_points_hz": [0.0, 100.0], "moments": [4, 4]}
    spec = ReductionSpec("krylov", method_options("krylov", options))
    responses, backends = {}, {}
    for solver in ("superlu", "mumps-mpi"):
        os.environ["PYMOREMBS_SOLVER"] = solver
        body = reduced_model(system, run_reduction(system, spec, (0.0, 200.0)))
        responses[solver] = transfer_function(body.system, frequency_grid(0.0, 200.0, 50))
    os.environ["PYMOREMBS_SOLVER"] = "superlu"
    full = transfer_function(system, frequency_grid(0.0, 200.0, 50))
    scale = np.abs(full).max(axis=(1, 2))[:, None, None]
    print(json.dumps({
        solver: float(np.max(np.abs(h - full) / scale)) for solver, h in responses.items()
    } | {"between": float(np.max(np.abs(responses["mumps-mpi"] - responses["superlu"]) / scale))}))
"""


@pytest.mark.slow
@needs_mpiexec
def test_two_ranks_give_the_body_of_the_default_backend() -> None:
    result = run_python(BODY, ranks=2)
    # the same body to the solvers' accuracy, far below either body's error against the full
    # model's response (SuperLU)
    assert result["between"] < 1e-9
    assert result["between"] < 1e-3 * result["superlu"]
    assert result["mumps-mpi"] < 1.01 * result["superlu"]


@pytest.mark.slow
@needs_mpiexec
def test_the_command_line_runs_on_two_ranks(tmp_path) -> None:
    from conftest import spring_lattice
    from pymorembs.io.native import write_body_h5

    write_body_h5(spring_lattice(40), tmp_path / "model.h5")
    env = dict(os.environ, PYMOREMBS_SOLVER="mumps-mpi", OMP_NUM_THREADS="1")
    env.update(OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1")
    env["PYTHONPATH"] = os.pathsep.join(p for p in (str(ROOT / "src"), env.get("PYTHONPATH")) if p)
    argv = [sys.executable, "-m", "pymorembs.job.cli", "info", str(tmp_path / "model.h5")]
    argv += ["--modes", "6"]
    runs = {}
    launcher = ["mpiexec", "--oversubscribe", "--bind-to", "none", "-n", "2"]
    for name, prefix in (("one", []), ("two", launcher)):
        done = subprocess.run([*prefix, *argv], capture_output=True, text=True, env=env)
        assert done.returncode == 0, done.stderr[-2000:]
        runs[name] = done.stdout
    assert runs["one"] == runs["two"]
