"""Command line: ``pymorembs example | info | reduce``.

Exit codes: 0 success; 2 a user mistake (one line on stderr naming the file or key and the
problem); 3 a numerical failure on valid input (one line with the cause); 1 a bug (traceback).
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from pathlib import Path
from typing import Any, NoReturn

import numpy as np
import scipy.linalg as sla
from threadpoolctl import threadpool_limits

from pymorembs import __version__
from pymorembs.body import ElasticBody
from pymorembs.config import MODEL_FORMATS, load_job
from pymorembs.errors import PymorembsError, UserError
from pymorembs.examples import EXAMPLES, build_example
from pymorembs.io.formats import read_body
from pymorembs.io.matrix_market import write_matrix_files
from pymorembs.io.native import write_body_h5
from pymorembs.pipeline import add_interfaces, load_model, run_job
from pymorembs.prepare import Frame, PreparedModel, prepare, with_rigid_modes
from pymorembs.prepare.rigid_modes import free_rigid_body_motions
from pymorembs.reduce.modal import eigenmodes

#: Below this size ``info`` solves the eigenproblem densely.
DENSE_LIMIT = 600


class _Parser(argparse.ArgumentParser):
    """argparse with one-line errors and exit code 2."""

    def error(self, message: str) -> NoReturn:
        sys.stderr.write(f"{self.prog}: error: {message} (see --help)\n")
        raise SystemExit(2)


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(prog="pymorembs", description=__doc__.splitlines()[0])
    parser.add_argument("--version", action="version", version=f"pymorembs {__version__}")
    sub = parser.add_subparsers(dest="command", required=True, parser_class=_Parser)

    ex = sub.add_parser("example", help="write a built-in example model")
    ex.add_argument("name", help=f"example name: {', '.join(EXAMPLES)}")
    ex.add_argument("--out", required=True, type=Path, help="output folder")
    ex.add_argument("--dofs", type=int, help="rack-solid: about this many dofs (35000)")
    ex.add_argument("--interface", help="rack-solid: interface variant of node 2")

    info = sub.add_parser("info", help="facts and eigenfrequencies of a model or a job")
    info.add_argument(
        "model",
        nargs="?",
        type=Path,
        help="model file (.h5, .full, .pch, .op4, ...) or a job file (.toml)",
    )
    info.add_argument("--format", choices=MODEL_FORMATS, help="file format (default: detected)")
    info.add_argument("--stiffness", type=Path, help="stiffness matrix file")
    info.add_argument("--mass", type=Path, help="mass matrix file")
    info.add_argument("--damping", type=Path, help="damping matrix file")
    info.add_argument("--dofs", type=Path, help="dof table CSV (node,direction)")
    info.add_argument("--nodes", type=Path, help="nodes: CSV (id,x,y,z) or FE input file")
    info.add_argument("--constraints", type=Path, help="constraint equations CSV")
    info.add_argument("--fixed", type=Path, help="fixed dofs CSV (node,direction)")
    info.add_argument("--mapping", type=Path, help="Ansys dof mapping file (*SMAT MMF export)")
    info.add_argument("--inp", type=Path, help="Abaqus input file with the *NODE data")
    info.add_argument("--stiffness-name", help="name of the stiffness matrix (Nastran: KAAX)")
    info.add_argument("--mass-name", help="name of the mass matrix (Nastran: MAAX)")
    info.add_argument("--modes", type=int, default=10, help="number of elastic eigenfrequencies")
    info.add_argument("--json", action="store_true", help="print JSON")

    red = sub.add_parser("reduce", help="run a reduction job (TOML)")
    red.add_argument("job", type=Path, help="job file")
    red.add_argument("--out", type=Path, help="output folder (default: out/<job name>)")
    red.add_argument("--quiet", action="store_true", help="print nothing but errors")
    return parser


def main(argv: list[str] | None = None) -> int:
    """Entry point of the ``pymorembs`` command; returns the exit code.

    BLAS runs with ``PYMOREMBS_BLAS_THREADS`` threads (default 1): the heavy work is sparse and
    single-threaded, and threaded level-1 BLAS on small vectors (inside ARPACK, norms, dots) was
    measured 5-7x slower on a 2-core machine.
    """
    args = build_parser().parse_args(argv)
    threads = os.environ.get("PYMOREMBS_BLAS_THREADS", "1")
    if not threads.isdigit() or int(threads) < 1:
        sys.stderr.write(
            f"pymorembs: error: PYMOREMBS_BLAS_THREADS must be a whole number >= 1, "
            f"got {threads!r}\n"
        )
        return 2
    with threadpool_limits(limits=int(threads), user_api="blas"):
        return _run(args)


def _run(args: argparse.Namespace) -> int:
    try:
        if args.command == "example":
            return _example(args)
        if args.command == "info":
            return _info(args)
        return _reduce(args)
    except PymorembsError as exc:
        message = " ".join(str(exc).split())  # always one line
        sys.stderr.write(f"pymorembs: error: {message}\n")
        return exc.exit_code


def _example(args: argparse.Namespace) -> int:
    options = {
        key: getattr(args, key) for key in ("dofs", "interface") if getattr(args, key) is not None
    }
    body = build_example(args.name, **options)
    out: Path = args.out
    if out.exists() and not out.is_dir():
        raise UserError(f"{out}: exists and is not a folder")
    out.mkdir(parents=True, exist_ok=True)
    write_body_h5(body, out / "model.h5")
    written = write_matrix_files(body, out)
    names = ["model.h5", *sorted(p.name for p in written.values())]
    print(f"{args.name}: {body.n_dof} dofs, {body.n_nodes} nodes -> {out}/ ({', '.join(names)})")
    return 0


INFO_FILES = (
    "stiffness",
    "mass",
    "damping",
    "dofs",
    "nodes",
    "constraints",
    "fixed",
    "mapping",
    "inp",
    "stiffness_name",
    "mass_name",
)


def _prepared_for_info(args: argparse.Namespace) -> tuple[ElasticBody, PreparedModel]:
    """The model of ``info``: a job (with its interfaces and frame) or model files as they are."""
    given = {key: getattr(args, key) for key in INFO_FILES if getattr(args, key) is not None}
    if args.model is not None and args.model.suffix.lower() == ".toml":
        if given or args.format:
            raise UserError("info: a job file brings its own model; give no file options")
        job = load_job(args.model)
        body = add_interfaces(load_model(job.model), job)
        try:
            return body, prepare(body, job.frame, allow_rigid_body_modes=True)
        except UserError as exc:
            raise UserError(f"{args.model}: {exc}") from None
    if args.model is None and not ("stiffness" in given and "mass" in given):
        raise UserError("info: give a model file, a job file, or both --stiffness and --mass")
    if args.model is not None and ("stiffness" in given or "mass" in given):
        raise UserError("info: give either a model file or --stiffness/--mass, not both")
    files = {"file": args.model} if args.model is not None else {}
    body = read_body(args.format, **files, **given)
    return body, prepare(body, Frame("none"), allow_rigid_body_modes=True)


def model_facts(body: ElasticBody, prepared: PreparedModel, modes: int) -> dict[str, Any]:
    """Sizes, mass, rigid-body modes and the ``modes`` lowest elastic eigenfrequencies (Hz).

    Rigid-body modes are the motions the fixed dofs and constraints leave free and unresisted
    (:func:`pymorembs.prepare.rigid_modes.free_rigid_body_modes`), reported as 0 Hz. Massless
    dofs are fine: the shift-invert eigensolver needs only ``K - sigma M`` to be regular, which
    is equivalent to the static condensation of the massless dofs.
    """
    if modes < 1:
        raise UserError(f"--modes must be at least 1, got {modes}")
    system = prepared.system
    free, motions = free_rigid_body_motions(prepared.body, prepared.elimination, system)
    n = system.order
    count = min(modes, n - len(free) - 1)
    values = None
    if n <= DENSE_LIMIT and not free:
        try:
            values = sla.eigh(
                system.stiffness.toarray(),
                system.mass.toarray(),
                eigvals_only=True,
                subset_by_index=[0, count - 1],
            )
        except np.linalg.LinAlgError:  # singular mass (massless dofs): shift-invert instead
            values = None
    if values is None:
        # a free body: elastic modes by inertia relief, never a shift next to the null space
        elastic = with_rigid_modes(system, motions) if free else system
        values, _ = eigenmodes(elastic, count, elastic_only=True)
    elastic_hz = np.sqrt(np.clip(values, 0.0, None)) / (2 * np.pi)
    frequencies = np.concatenate([np.zeros(len(free)), elastic_hz])
    return {
        "name": body.name,
        "n_dof": prepared.body.n_dof,
        "n_nodes": prepared.body.n_nodes,
        "n_dependent": int(prepared.elimination.dependent.size),
        "n_fixed": int(prepared.elimination.fixed.size),
        "n_independent": n,
        "total_mass": body.total_mass(),
        "rigid_body_modes": len(free),
        "rigid_body_motions": free,
        "eigenfrequencies_hz": frequencies.tolist(),
    }


def _info(args: argparse.Namespace) -> int:
    body, prepared = _prepared_for_info(args)
    facts = model_facts(body, prepared, args.modes)
    if args.json:
        print(json.dumps(facts, indent=2))
        return 0
    print(f"model             {facts['name']}")
    print(
        f"dofs              {facts['n_dof']} ({facts['n_independent']} independent, "
        f"{facts['n_dependent']} dependent, {facts['n_fixed']} fixed)"
    )
    print(f"nodes             {facts['n_nodes']}")
    print(f"total mass        {facts['total_mass']:.6g} (model mass unit)")
    print(f"rigid-body modes  {facts['rigid_body_modes']}")
    print("eigenfrequencies [Hz]:")
    for k, f in enumerate(facts["eigenfrequencies_hz"], start=1):
        print(f"  {k:4d}  {f:12.4f}" + ("  (rigid-body mode)" if f == 0.0 else ""))
    return 0


def _reduce(args: argparse.Namespace) -> int:
    job = load_job(args.job)
    out = args.out or Path("out") / args.job.stem
    start = time.perf_counter()

    def progress(message: str) -> None:
        if not args.quiet:
            print(f"[{time.perf_counter() - start:7.2f} s] {message}", flush=True)

    summary = run_job(job, out, progress)
    if not args.quiet:
        print()
        print(
            f"{'reduction':<20} {'method':<14} {'order':>5} {'max rel. error':>15} "
            f"{'error at 0 Hz':>14} {'time [s]':>9}"
        )
        for r in summary["reductions"]:
            static = "-" if r["static_rel_error"] is None else f"{r['static_rel_error']:.2e}"
            print(
                f"{r['name']:<20} {r['method']:<14} {r['order']:>5} "
                f"{r['max_rel_error']:>15.3e} {static:>14} {r['time_s']:>9.2f}"
            )
        print(
            f"\nband {summary['band_hz'][0]:g}-{summary['band_hz'][1]:g} Hz, "
            f"{summary['n_frequencies']} frequencies; results in {out}/summary.json"
        )
    return 0


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
