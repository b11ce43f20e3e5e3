"""Command line of pymorembs: ``pymorembs example | info | reduce | app``.

Exit codes: 0 success; 2 a user mistake (one line on stderr naming the file or key and the
problem), also a full, over-quota or read-only output device; 3 a numerical failure on valid
input (one line with the cause); 4 accuracy not met (the job ran and wrote its results, but a
reduced body missed its accuracy limit and was not written; the table, then one line); 130 and
143 interrupted by SIGINT (Ctrl-C) or SIGTERM (one line, temporary files removed); 1 a bug
(traceback). ``reduce`` with several job files runs them all and exits with the worst code of
its jobs (:data:`SEVERITY`), with one line per failing job.

Streams: the stage lines and the table go to stdout (not with ``--quiet``); warnings, notes and
errors go to stderr, one line each, also with ``--quiet``.
"""

from __future__ import annotations

import argparse
import json
import os
import signal
import sys
import threading
import time
import traceback
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import fields
from pathlib import Path
from typing import Any, NoReturn

import numpy as np
from threadpoolctl import threadpool_limits

from pymorembs import (
    AccuracyNotMet,
    ElasticBody,
    Frame,
    PreparedModel,
    PymorembsError,
    UserError,
    __version__,
    progress,
)
from pymorembs.analysis import model_facts
from pymorembs.examples import EXAMPLES, RACK_SOLID_INTERFACES, ExampleOptions, build_example
from pymorembs.io import read_body, write_body_h5, write_matrix_files
from pymorembs.job.run import load_job_model, output_errors, run_job, validate_job_body
from pymorembs.job.schema import MODEL_FORMATS, load_job
from pymorembs.job.summary import Accuracy, JobSummary
from pymorembs.linalg import serve_solver_ranks
from pymorembs.parallel import dask_client, usable_cores
from pymorembs.preparation import ValidationReport, mechanism_or_map, prepare, validate_body
from pymorembs.units import detect_units, frequency_warnings


class _Parser(argparse.ArgumentParser):
    """argparse with one-line errors and exit code 2."""

    def error(self, message: str) -> NoReturn:
        sys.stderr.write(f"{self.prog}: error: {message} (see --help)\n")
        raise SystemExit(2)


#: What ``pymorembs --help`` says the tool does.
DESCRIPTION = """\
Reduce the finite-element model of an elastic body (matrices from Ansys, Abaqus,
Nastran, MATLAB or plain files) to a small, accurate body for flexible multibody
simulation: modal, Krylov and Gramian methods with a measured error, exported as
SID (Simpack), Neweul-M2 data, an Exudyn body and reduced matrices."""
#: The epilog of ``pymorembs --help``: the usual sequence and the exit codes.
EPILOG = """\
a first session:
  pymorembs example rack-beams --out model     write a built-in model
  pymorembs info model/model.h5                what was read: dofs, units, modes
  pymorembs reduce job.toml --out out/job      reduce as the job file says

exit codes: 0 success, 2 a user mistake (one line naming the file or key) or a
full or read-only output device, 3 a numerical failure on valid input, 4 accuracy
not met (results written, the inaccurate bodies not), 130/143 interrupted
(SIGINT/SIGTERM), 1 a bug (traceback).
The job file format: docs/jobs.md (and the examples/*.toml files)."""
JOB_HELP = (
    "Run reduction jobs. A job is a TOML file: [model] (a file or a built-in example), "
    "[frame], [[inputs]]/[[outputs]], [band], one [[reduction]] per method, [export]; "
    "see docs/jobs.md and examples/*.toml."
)


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(
        prog="pymorembs",
        description=DESCRIPTION,
        epilog=EPILOG,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument("--version", action="version", version=f"pymorembs {__version__}")
    sub = parser.add_subparsers(dest="command", required=True, parser_class=_Parser)

    ex = sub.add_parser(
        "example",
        help="write a built-in example model",
        description="Write a built-in example model (native .h5 and Matrix Market files).",
    )
    ex.add_argument("name", help=f"example name: {', '.join(EXAMPLES)}")
    ex.add_argument("--out", required=True, type=Path, help="output folder")
    ex.add_argument("--dofs", type=int, help="rack-solid: about this many dofs (35000)")
    ex.add_argument(
        "--interface",
        help=f"rack-solid: coupling of the interface node 2 to its hole, one of "
        f"{', '.join(RACK_SOLID_INTERFACES)} (default light-beams)",
    )
    ex.add_argument("--hub-radius", type=float, help="blade: root distance from the axis (m)")
    ex.add_argument("--elements", type=int, help="blade: elements along the length (40)")

    info = sub.add_parser("info", help="facts and eigenfrequencies of a model or a job")
    info.add_argument(
        "model",
        nargs="?",
        type=Path,
        help="model file (.h5, .full, .pch, .op4, CalculiX .sti, ...; also .gz, .bz2, .xz) or "
        "a job file (.toml)",
    )
    info.add_argument("--format", choices=MODEL_FORMATS, help="file format (default: detected)")
    info.add_argument("--stiffness", type=Path, help="stiffness matrix file")
    info.add_argument("--mass", type=Path, help="mass matrix file")
    info.add_argument("--damping", type=Path, help="damping matrix file")
    info.add_argument(
        "--dofs", type=Path, help="dof table CSV (node,direction), or the CalculiX .dof"
    )
    info.add_argument("--nodes", type=Path, help="nodes: CSV (id,x,y,z) or FE input file")
    info.add_argument("--constraints", type=Path, help="constraint equations CSV")
    info.add_argument("--fixed", type=Path, help="fixed dofs CSV (node,direction)")
    info.add_argument("--mapping", type=Path, help="Ansys dof mapping file (*SMAT MMF export)")
    info.add_argument("--inp", type=Path, help="Abaqus input file or CalculiX deck")
    info.add_argument(
        "--stiffness-name", help="name of the stiffness matrix (default: found in the file)"
    )
    info.add_argument("--mass-name", help="name of the mass matrix (default: found in the file)")
    info.add_argument("--damping-name", help="name of a viscous damping matrix in the file")
    info.add_argument("--modes", type=int, default=10, help="number of elastic eigenfrequencies")
    info.add_argument("--json", action="store_true", help="print JSON")

    red = sub.add_parser("reduce", help="run reduction jobs (TOML)", description=JOB_HELP)
    red.add_argument("job", type=Path, nargs="+", help="job file(s)")
    red.add_argument(
        "--out", type=Path, help="output folder of a single job (default: out/<job name>)"
    )
    red.add_argument(
        "--quiet", action="store_true", help="print nothing but errors, warnings and notes"
    )
    red.add_argument(
        "--workers",
        type=int,
        help=f"processes for the full model's frequency response (default: {usable_cores()}, "
        "the usable cores)",
    )
    red.add_argument(
        "--scheduler",
        metavar="ADDRESS",
        help="run on Dask: 'local' (a local cluster) or a scheduler address; several job files "
        "run as parallel tasks, a single job's frequency response is shared out",
    )
    red.add_argument(
        "--progress",
        action="store_true",
        help="draw progress bars on stderr even when it is not a terminal (not with --quiet)",
    )
    web = sub.add_parser(
        "app",
        help="a local web page that edits, runs and compares jobs",
        description="Serve the job editor on http://127.0.0.1:PORT: open a model, pick "
        "interfaces in 3D, add reductions, run, compare (docs/app.md).",
    )
    web.add_argument(
        "model",
        nargs="?",
        type=Path,
        help="model file (.h5, .full, .pch, ...) or job file (.toml); default the built-in "
        "rack-solid",
    )
    web.add_argument(
        "--format", choices=MODEL_FORMATS, help="model file format (default: detected)"
    )
    web.add_argument("--port", type=int, default=8765, help="port on 127.0.0.1 (8765)")
    web.add_argument("--no-browser", action="store_true", help="do not open a browser")
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
    with threadpool_limits(limits=int(threads), user_api="blas"), _sigterm_raises():
        try:
            return _run(args)
        except KeyboardInterrupt:  # SIGINT, Ctrl-C: the clean-ups ran on the way out
            return _ended_by_signal("interrupted", INTERRUPTED)
        except Terminated:
            return _ended_by_signal("terminated", TERMINATED)


#: Exit codes of a run ended by SIGINT and SIGTERM (128 + the signal number, as a shell says).
INTERRUPTED, TERMINATED = 128 + signal.SIGINT, 128 + signal.SIGTERM


class Terminated(BaseException):
    """SIGTERM, raised in the main thread so that every clean-up runs as for Ctrl-C (temporary
    folders removed, worker processes ended); not an ``Exception``, so that nothing treats it
    as an error of the work it interrupted."""


def _raise_terminated(_number: int, _frame: Any) -> None:
    raise Terminated


@contextmanager
def _sigterm_raises() -> Iterator[None]:
    """SIGTERM raises :class:`Terminated` inside the block (in the main thread; elsewhere
    Python cannot install a handler, and the block runs as it is)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = signal.signal(signal.SIGTERM, _raise_terminated)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, signal.SIG_DFL if previous is None else previous)


def _ended_by_signal(what: str, code: int) -> int:
    """The one line of a run ended by a signal; its exit code."""
    try:
        sys.stderr.write(f"pymorembs: {what}\n")
        sys.stderr.flush()
    except (OSError, ValueError):  # stderr gone too
        pass
    return code


def _run(args: argparse.Namespace) -> int:
    try:
        if serve_solver_ranks():  # a rank > 0 of `mpiexec` serves rank 0's factorizations
            return 0
        if args.command == "example":
            return _example(args)
        if args.command == "info":
            return _info(args)
        if args.command == "app":
            return _app(args)
        return _reduce(args)
    except BrokenPipeError:  # the reader of the output went away (e.g. `| head`)
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())  # no error at exit
        return 0
    except PymorembsError as exc:
        message = " ".join(str(exc).split())  # always one line
        sys.stderr.write(f"pymorembs: error: {message}\n")
        return exc.exit_code
    except Exception:  # anything else is a bug: the traceback, and a request to report it
        traceback.print_exc(file=sys.stderr)
        sys.stderr.write(f"pymorembs: error: {BUG_REPORT}\n")
        return 1


#: The last line after the traceback of an unexpected exception (exit code 1).
BUG_REPORT = (
    "this is a bug in pymorembs; please report it with the job file (or the command line) "
    "and this traceback"
)


def _example(args: argparse.Namespace) -> int:
    given = {option.name: getattr(args, option.name) for option in fields(ExampleOptions)}
    body = build_example(args.name, **ExampleOptions(**given).given())
    out: Path = args.out
    if out.exists() and not out.is_dir():
        raise UserError(f"{out}: exists and is not a folder")
    with output_errors(out, outcome="the files written before are complete"):
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
    "damping_name",
)


def _prepared_for_info(
    args: argparse.Namespace,
) -> tuple[ElasticBody, PreparedModel, ValidationReport]:
    """The model of ``info``: a job (with its interfaces and frame) or model files as they are,
    with the report of :func:`~pymorembs.preparation.validate_body`."""
    given = {key: getattr(args, key) for key in INFO_FILES if getattr(args, key) is not None}
    if args.model is not None and args.model.suffix.lower() == ".toml":
        if given or args.format:
            raise UserError("info: a job file brings its own model; give no file options")
        job = load_job(args.model)
        body = load_job_model(job)
        report = validate_job_body(body, job)
        try:
            return body, prepare(body, job.frame, allow_rigid_body_modes=True), report
        except PymorembsError as exc:
            raise type(exc)(f"{args.model}: {exc}") from None
    if args.model is None and "stiffness" not in given:
        raise UserError("info: give a model file, a job file, or --stiffness and --mass")
    if args.model is not None and ("stiffness" in given or "mass" in given):
        raise UserError("info: give either a model file or --stiffness/--mass, not both")
    files = {"file": args.model} if args.model is not None else {}
    body = read_body(format=args.format, **files, **given)
    report = validate_body(body)
    return body, prepare(body, Frame("none"), allow_rigid_body_modes=True), report


def _info(args: argparse.Namespace) -> int:
    body, prepared, report = _prepared_for_info(args)
    facts = model_facts(body, prepared, args.modes)
    consistency = report.facts["consistency"]
    wrong_map = mechanism_or_map(consistency, facts["rigid_body_modes"], facts["mechanisms"])
    if wrong_map is not None:
        raise UserError(wrong_map)
    facts["consistency"] = consistency
    units = detect_units(body)
    facts["units"] = units.as_dict()
    warnings = [*report.warnings, *units.warnings]
    if args.model is not None and args.model.suffix.lower() == ".toml":
        band = load_job(args.model).band_hz
        warnings += frequency_warnings(units, band, np.asarray(facts["eigenfrequencies_hz"]))
    for warning in warnings:
        sys.stderr.write(f"pymorembs: warning: {warning}\n")
    if args.json:
        print(json.dumps(facts, indent=2))
        return 0
    _print_facts(facts, units.describe())
    return 0


def _print_facts(facts: dict[str, Any], units: str) -> None:
    """The facts of ``info`` as text."""
    massless = facts["massless"]
    print(f"model             {facts['name']}")
    print(
        f"dofs              {facts['n_dof']} ({facts['n_independent']} independent, "
        f"{facts['n_dependent']} dependent, {facts['n_fixed']} fixed)"
    )
    print(f"dof table         {facts['dof_table']}")
    if massless["directions"]:
        parts = []
        if massless["dofs_without_mass"]:
            parts.append(f"{massless['dofs_without_mass']} dofs without any mass entry")
        if massless["directions_in_mass_blocks"]:
            parts.append(
                f"{massless['directions_in_mass_blocks']} directions inside mass blocks "
                "(point masses without rotary inertia, ...)"
            )
        print(f"massless          {massless['directions']} ({'; '.join(parts)}); condensed exactly")
    else:
        print("massless          none")
    coordinates = "" if facts["has_coordinates"] else " (no coordinates in the model files)"
    print(f"nodes             {facts['n_nodes']}{coordinates}")
    sets = list(facts["node_sets"].items())
    if sets:
        listed = ", ".join(f"{name} ({count})" for name, count in sets[:8])
        print(f"node sets         {len(sets)}: {listed}{', ...' if len(sets) > 8 else ''}")
    print(f"total mass        {facts['total_mass']:.6g} (model mass unit)")
    print(f"unit system       {units}")
    rigid = facts["rigid_body_modes"]
    decision = facts["rigid_body_decision"]["explanation"]
    print(f"rigid-body modes  {rigid} ({decision})")
    if facts["mechanisms"]:
        print(f"mechanisms        {facts['mechanisms']} further zero-energy modes")
    print(f"matrix entries    {facts['rounding']}")
    proof = facts["consistency"]["map"]
    print(f"dof map           {proof['status']}: {proof['reason']}")
    for note in facts["notes"] + facts["consistency"]["notes"]:
        print(f"note              {note}")
    labels = facts["rigid_body_motions"]
    bounds = facts["eigenfrequency_bounds_hz"]
    rounded = facts["rounding"] != "full double precision"
    header = "  (+- first-order bound of the file's rounding)" if rounded else ""
    print(f"eigenfrequencies [Hz]:{header}")
    zero = rigid + facts["mechanisms"]
    for k, (f, bound) in enumerate(zip(facts["eigenfrequencies_hz"], bounds, strict=True)):
        if k < rigid:
            what = f"rigid-body mode: {labels[k]}" if k < len(labels) else "rigid-body mode"
            print(f"  {k + 1:4d}  {f:12.4f}  ({what})")
        elif k < zero:
            if k == rigid:  # all mechanisms on one line
                span = f"{k + 1}-{zero}" if zero > k + 1 else f"{k + 1}"
                print(
                    f"  {span:>4}  {f:12.4f}  ({facts['mechanisms']} zero-energy modes: mechanisms)"
                )
        else:
            spread = f"  +- {bound:.3g}" if rounded else ""
            print(f"  {k + 1:4d}  {f:12.4f}{spread}")
    if "fixed_interface_hz" in facts:
        values = facts["fixed_interface_hz"]
        print(
            "fixed-interface modes [Hz] (modal coordinates of the superelement): "
            + ", ".join(f"{f:.6g}" for f in values[:12])
            + (" ..." if len(values) > 12 else "")
        )


def _app(args: argparse.Namespace) -> int:
    from pymorembs.job.app import serve

    if not 0 <= args.port <= 65535:
        raise UserError(f"--port must be 0..65535, got {args.port}")
    return serve(args.model, args.port, open_browser=not args.no_browser, format=args.format)


def _reduce(args: argparse.Namespace) -> int:
    jobs: list[Path] = args.job
    if args.out is not None and len(jobs) > 1:
        raise UserError("--out takes a single job file; several jobs write out/<job name> each")
    if args.workers is not None and args.workers < 1:
        raise UserError(f"--workers must be at least 1, got {args.workers}")
    stems = [job.stem for job in jobs]
    twice = sorted({stem for stem in stems if stems.count(stem) > 1})
    if twice:
        raise UserError(f"job names given twice (one output folder each): {', '.join(twice)}")
    bars = "off" if args.quiet else ("on" if args.progress else "auto")
    with progress.settings(bars):
        if len(jobs) == 1:
            return _reduce_job(jobs[0], args.out, args.quiet, args.workers, args.scheduler)
        if args.scheduler is not None:
            return _reduce_on_dask(jobs, args)
        codes = []
        for path in jobs:
            codes.append(_guarded(path, args))
        return worst(codes)


#: Exit codes from good to bad: success, accuracy not met (the job ran and wrote its results),
#: user mistake and numerical failure (the job wrote nothing), bug.
SEVERITY = (0, 4, 2, 3, 1)


def worst(codes: list[int]) -> int:
    """The worst exit code: a bug (1) over a numerical failure (3) over a user mistake (2)
    over accuracy not met (4) over success (0)."""
    return max(codes, key=SEVERITY.index, default=0)


def _guarded(path: Path, args: argparse.Namespace) -> int:
    """One of several jobs, one after the other: one line on stderr if it fails."""
    if not args.quiet:
        print(f"job {path}")
    try:
        return _reduce_job(path, None, args.quiet, args.workers, None)
    except PymorembsError as exc:
        _job_error(path, str(exc))
        return exc.exit_code
    except Exception as exc:  # a bug: the other jobs still run
        _job_error(path, f"internal error ({type(exc).__name__}: {exc}); run it alone for details")
        return 1


def _job_error(path: Path, message: str) -> None:
    """One line on stderr naming the job (unless the message names its file already)."""
    message = " ".join(message.split())
    if not message.startswith(str(path)):
        message = f"{path}: {message}"
    sys.stderr.write(f"pymorembs: error: {message}\n")


def _reduce_job(
    path: Path, out: Path | None, quiet: bool, workers: int | None, scheduler: str | None
) -> int:
    job = load_job(path)
    out = out or Path("out") / path.stem
    start = time.perf_counter()

    def say(message: str) -> None:
        if message.startswith(STDERR_LINES):  # one line on stderr each, even with --quiet
            progress.write(f"pymorembs: {message}", file=sys.stderr)
        elif not quiet:
            progress.write(f"[{time.perf_counter() - start:7.2f} s] {message}")

    try:
        summary = run_job(job, out, say, workers=workers, scheduler=scheduler)
    except AccuracyNotMet as exc:  # the table first: the numbers behind the error line
        if not quiet:
            _print_summary(exc.summary, out)
        raise
    if not quiet:
        _print_summary(summary, out)
    return 0


#: Messages of a job that go to stderr (warnings and notes); the others are stage lines.
STDERR_LINES = ("warning: ", "note: ")


def _print_summary(summary: JobSummary, out: Path) -> None:
    inertia = summary.inertia_loads is not None
    stress = summary.model.get("stress")
    print()
    print(
        f"{'reduction':<20} {'method':<14} {'order':>5} {'max rel. error':>15} "
        f"{'error at 0 Hz':>14}"
        + (f" {'inertia loads':>14}" if inertia else "")
        + (f" {'stresses':>10} {'estimate':>9}" if stress else "")
        + " time [s]"
    )
    for r in summary.reductions:
        static = "-" if r.static_rel_error is None else f"{r.static_rel_error:.2e}"
        loads = f" {r.inertia_loads.max_rel_error:>14.3e}" if inertia and r.inertia_loads else ""
        if stress and r.stress:
            estimate = "-" if r.stress.estimate is None else f"{r.stress.estimate:.2e}"
            loads += f" {r.stress.max_rel_error:>10.3e} {estimate:>9}"
        print(
            f"{r.name:<20} {r.method:<14} {r.order:>5} "
            f"{r.max_rel_error:>15.3e} {static:>14}{loads} {r.time_s:>8.2f}"
            + accuracy_mark(r.accuracy)
        )
    covers = "errors over the ports"
    if inertia:
        cases = " ".join(summary.inertia_loads["cases"])
        covers += f"; 'inertia loads': over the inertia loads of the frame motion ({cases})"
    if stress:
        aimed = ", targeted" if stress["targeted"] else ""
        covers += (
            f"; 'stresses': over the stresses at {stress['points']} hot spots ({stress['chosen']}"
            f"{aimed}) under every input, 'estimate' SOAGA's"
        )
    print(
        f"\nband {summary.band_hz[0]:g}-{summary.band_hz[1]:g} Hz, "
        f"{summary.n_frequencies} frequencies, {covers}; results in {out}/summary.json"
    )


def accuracy_mark(accuracy: Accuracy) -> str:
    """The mark of a table row whose reduction missed its accuracy limit ("" if it met it)."""
    if accuracy.met:
        return ""
    written = "written (export_inaccurate)" if accuracy.exported else "body not written"
    return f"  ! above its limit {accuracy.limit:.0e}: {written}"


def _job_task(path: str, out: str, threads: int) -> tuple[int, str, JobSummary | None]:
    """A whole job on a Dask worker: ``(exit code, one-line message, summary)``; the summary
    is None where the job wrote none, the message empty for success."""
    try:
        os.environ.setdefault("PYMOREMBS_SOLVER_THREADS", "1")  # jobs share the cores
        with threadpool_limits(limits=threads, user_api="blas"), progress.settings("off"):
            return 0, "", run_job(load_job(Path(path)), Path(out), None, workers=1)
    except AccuracyNotMet as exc:
        return exc.exit_code, str(exc), exc.summary
    except PymorembsError as exc:
        return exc.exit_code, str(exc), None
    except Exception as exc:  # a bug; the traceback stays in the worker's log
        message = f"internal error ({type(exc).__name__}: {exc}); run it alone for details"
        return 1, message, None


def _reduce_on_dask(jobs: list[Path], args: argparse.Namespace) -> int:
    """Several jobs as independent tasks on a Dask cluster; their results as they finish.

    Job files, models and output folders are passed as absolute paths: a remote cluster must
    see the same file system.
    """
    from distributed import as_completed

    threads = int(os.environ.get("PYMOREMBS_BLAS_THREADS", "1"))
    codes = []
    with dask_client(args.scheduler, args.workers) as client:
        futures = {
            client.submit(
                _job_task,
                str(path.resolve()),
                str((Path("out") / path.stem).resolve()),
                threads,
                pure=False,
                key=f"pymorembs-job-{k}-{path.stem}",
            ): path
            for k, path in enumerate(jobs)
        }
        if not args.quiet:
            print(f"{len(jobs)} jobs on Dask ({args.scheduler})")
        with progress.Progress("jobs", total=len(jobs), unit="job", every=1) as bar:
            for future in as_completed(futures):
                path = futures[future]
                try:
                    code, message, summary = future.result()
                except Exception as exc:  # the task itself failed (a worker died, ...)
                    code, message = 1, f"Dask task failed ({type(exc).__name__}: {exc})"
                    summary = None
                codes.append(code)
                bar.update()
                if summary is not None and not args.quiet:
                    progress.write(f"\njob {path}: {'done' if code == 0 else 'written'}")
                    _print_summary(summary, Path("out") / path.stem)
                if code:
                    _job_error(path, message)
    return worst(codes)


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
