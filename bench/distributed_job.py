"""Distributed backend (issue #30 item 6): a whole job under ``mpiexec`` against the default one.

The job of ``bench/job_cost.py`` (read, validate, inertia loads, error reference checked
against the full model, Krylov, SOAGA and Craig-Bampton with their errors, SID and Exudyn
files) is run twice by the command line, each in its own process:

1. ``pymorembs reduce job.toml --workers 1`` with the default backend (PARDISO where installed);
2. ``PYMOREMBS_SOLVER=mumps-mpi mpiexec -n RANKS --bind-to none pymorembs reduce job.toml
   --workers 1``: every factorization and solve of the job on MUMPS over all ranks.

Wall time and peak resident memory of each (``wait4``: the largest process of the tree), and
the two jobs' bodies compared as linear maps, which does not depend on the basis each solver
happened to build: for every reduction the response ``Phi (K_r (1 + i eta) - w^2 M_r)^-1 Phi^T``
(the job's loss factor, :func:`response`) of its Exudyn body at 60 mesh dofs drawn at random
(the same for both; 41 frequencies over the band) and of its SID body at its nodes, the largest
difference relative to the default body's response; the order, the maximum
error of the job's own evidence (ports and inertia loads, against each job's reference), the
eigenfrequencies in the band and the mass. ``RESULTS.md``: section "Distributed backend: a
whole job".

Usage::

    .venv/bin/python bench/distributed_job.py --model bracket      # under flock /work/locks/big
    .venv/bin/python bench/distributed_job.py --dofs 35000         # rack-solid
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from _common import fmt_s, machine_facts, markdown_table, update_results
from job_cost import BRACKET, job_text

from pymorembs.analysis import transfer_function
from pymorembs.export.sid import read_sid
from pymorembs.system import SecondOrderSystem

ROOT = Path(__file__).resolve().parents[1]
CLI = ROOT / ".venv" / "bin" / "pymorembs"
#: Mesh dofs at which the two bodies' responses are compared.
SAMPLE = 60
#: The loss factor of the job (``[damping] kind = "modal"``, ``ratio = 0.02``: ``eta = 2 xi``).
LOSS_FACTOR = 0.04


def run(command: list[str], env: dict[str, str], cwd: Path, log: str) -> dict:
    """Run ``command`` (output into ``cwd / log``): wall time (s) and the peak resident memory
    of its largest process, GB (``wait4``: ``mpiexec`` waits for its ranks, whose peaks count)."""
    with open(cwd / log, "w") as out:
        tick = time.perf_counter()
        process = subprocess.Popen(command, cwd=cwd, env=env, stdout=out, stderr=subprocess.STDOUT)
        _, status, usage = os.wait4(process.pid, 0)
        seconds = time.perf_counter() - tick
    if os.waitstatus_to_exitcode(status) != 0:
        tail = (cwd / log).read_text(errors="replace")[-2000:]
        sys.exit(f"{' '.join(command)} failed:\n{tail}")
    return {"seconds": seconds, "peak_gb": usage.ru_maxrss / 1e6}


def response(
    points: np.ndarray, mass: np.ndarray, stiffness: np.ndarray, frequencies_hz
) -> np.ndarray:
    """``P (K (1 + i eta) - w^2 M)^-1 P^T`` of a reduced body with the rows ``P`` at some points
    (:func:`pymorembs.analysis.transfer_function`), shape (n_f, k, k): the job's damping, the
    loss factor ``eta = 2 xi`` (:data:`LOSS_FACTOR`), on which its errors are measured. The
    bodies' viscous modal damping ``diag(2 xi omega_i)`` (paper eq. 25, the files' ``De``) is
    not compared: it depends on each body's own eigenfrequencies, also on the stiff directions
    far above the band that the two solvers' bases hold differently (docs/performance.md, "A
    whole job under mpiexec")."""
    system = SecondOrderSystem(mass, stiffness, None, points.T, points, loss_factor=LOSS_FACTOR)
    return transfer_function(system, np.asarray(frequencies_hz))


def mesh_response(body: np.lib.npyio.NpzFile, dofs: np.ndarray, frequencies_hz) -> np.ndarray:
    """The Exudyn body's response at ``dofs`` to forces there, shape (n_f, k, k)."""
    matrices = (body[f"{name}MatrixReduced"] for name in ("mass", "stiffness"))
    return response(body["modeBasis"][dofs], *matrices, frequencies_hz)


def port_response(sid_file: Path, frequencies_hz: np.ndarray) -> np.ndarray:
    """The SID body's response at its frame nodes (translations and rotations) to forces and
    moments there, shape (n_f, 6 n, 6 n)."""
    sid = read_sid(sid_file)
    rows = []
    for objects in sid.nodes.values():
        rows += [objects[name].m0 for name in ("phi", "psi") if name in objects]
    matrices = (sid.objects[name].m0 for name in ("Me", "Ke"))
    return response(np.vstack(rows), *matrices, frequencies_hz)


def relative_difference(a: np.ndarray, b: np.ndarray) -> float:
    """Largest ``||a - b|| / ||a||`` over the frequencies (first axis)."""
    return float(np.max(np.linalg.norm(a - b, axis=(1, 2)) / np.linalg.norm(a, axis=(1, 2))))


def compare(default: Path, distributed: Path, band_hz: tuple[float, float]) -> list[dict]:
    """Each reduction of the two jobs side by side (module docstring)."""
    summaries = [json.loads((d / "summary.json").read_text()) for d in (default, distributed)]
    rows = []
    rng = np.random.default_rng(1)
    frequencies = np.linspace(*band_hz, 41)
    for a, b in zip(*(s["reductions"] for s in summaries), strict=True):
        name = a["name"]
        bodies = [np.load(d / name / f"{name}_exudyn.npz") for d in (default, distributed)]
        dofs = np.sort(rng.choice(bodies[0]["modeBasis"].shape[0], SAMPLE, replace=False))
        h_a, h_b = (mesh_response(body, dofs, frequencies) for body in bodies)
        p_a, p_b = (
            port_response(d / name / f"{name}.SID_FEM", frequencies) for d in (default, distributed)
        )
        f_a, f_b = (np.asarray(body["eigenfrequenciesHz"]) for body in bodies)
        band = f_a <= band_hz[1]
        same = f_a.size == f_b.size
        rows.append(
            {
                "name": name,
                "orders": (a["order"], b["order"]),
                "max_errors": (a["accuracy"]["max"], b["accuracy"]["max"]),
                "port_difference": relative_difference(p_a, p_b),
                "response_difference": relative_difference(h_a, h_b),
                "in_band_hz": f_a[band].round(3).tolist(),
                "eigenfrequency_difference": float(
                    np.max(np.abs(f_a[band] - f_b[band]) / f_a[band])
                    if same and band.any()
                    else np.nan
                ),
                "masses": (float(bodies[0]["physicsMass"]), float(bodies[1]["physicsMass"])),
            }
        )
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--model", choices=("rack-solid", "bracket"), default="rack-solid")
    parser.add_argument("--dofs", type=int, default=35000, help="rack-solid size")
    parser.add_argument("--ranks", type=int, default=2)
    parser.add_argument("--no-results", action="store_true", help="do not write RESULTS.md")
    args = parser.parse_args()
    if shutil.which("mpiexec") is None:
        sys.exit("mpiexec not found: install the distributed backend first (make mpi)")
    if args.model == "bracket" and not (BRACKET / "bracket.sti").exists():
        sys.exit(f"{BRACKET} holds no bracket.sti: make it with bench/calculix_peer.py")
    band = (0.0, 1000.0)  # the band of job_cost's job
    with tempfile.TemporaryDirectory(prefix="distributed_job_") as folder:
        work = Path(folder)
        (work / "job.toml").write_text(job_text(args.model, args.dofs))
        env = dict(os.environ)
        env.pop("PYMOREMBS_SOLVER", None)
        base = [str(CLI), "reduce", "job.toml", "--workers", "1", "--out"]
        print("default backend ...", flush=True)
        default = run([*base, "default"], env, work, "default.log")
        mpi = ["mpiexec", "-n", str(args.ranks), "--bind-to", "none"]
        if os.geteuid() == 0:
            mpi.append("--allow-run-as-root")
        print(f"MUMPS on {args.ranks} ranks ...", flush=True)
        distributed = run(
            [*mpi, *base, "distributed"], {**env, "PYMOREMBS_SOLVER": "mumps-mpi"}, work, "mpi.log"
        )
        rows = compare(work / "default", work / "distributed", band)
        model = json.loads((work / "default" / "summary.json").read_text())["model"]
    dofs = f"{model['n_independent']:,}"
    t_default, t_mpi = default["seconds"], distributed["seconds"]
    lines = [
        f"**{args.model}, {dofs} dofs**: the job of `bench/job_cost.py` by the command line, "
        f"default backend {fmt_s(t_default)} s, MUMPS on {args.ranks} ranks {fmt_s(t_mpi)} s "
        f"(ratio {t_mpi / t_default:.2f}); largest process {default['peak_gb']:.1f} GB "
        f"(default) and {distributed['peak_gb']:.1f} GB (a rank).",
        "",
    ]
    table = [
        [
            r["name"],
            f"{r['orders'][0]} / {r['orders'][1]}",
            f"{r['max_errors'][0]:.3e} / {r['max_errors'][1]:.3e}",
            f"{r['port_difference']:.1e}",
            f"{r['response_difference']:.1e}",
            ", ".join(f"{f:g}" for f in r["in_band_hz"]),
            f"{r['eigenfrequency_difference']:.1e}",
            f"{r['masses'][0]:.12g} / {r['masses'][1]:.12g}",
        ]
        for r in rows
    ]
    headers = [
        "reduction",
        "order default / MUMPS",
        "max error (ports, inertia loads) default / MUMPS",
        "SID body at its frame nodes: largest relative difference",
        f"Exudyn body, forces at {SAMPLE} mesh dofs: largest relative difference",
        "eigenfrequencies in the band [Hz]",
        "their largest relative difference",
        "mass [kg] default / MUMPS",
    ]
    body = "\n".join(lines) + markdown_table(headers, table)
    print(body)
    if not args.no_results:
        print("written:", update_results("Distributed backend: a whole job", body, machine_facts()))


if __name__ == "__main__":
    main()
