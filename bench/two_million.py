"""A SOAGA body with its error evidence at up to 2,000,000 dofs: time and memory of each stage.

rack-solid (hex20, ``build_example("rack-solid", dofs=N)``; frame at node 2, ports
``1: ux uy uz``, 1 % modal damping, band 0-1000 Hz) in one fresh process, stage by stage:

1. **build**: the FE model and its preparation (K, M of the independent dofs); the prepared
   body (with the FE model's own K and M) is then dropped, as nothing is exported here;
2. **baseline**: one factorization of ``K - (2 pi 500 Hz)^2 M`` (real symmetric indefinite,
   ordering and analysis included) and one solve with the three port loads -- the unit the
   other stages are counted in;
3. **SOAGA** (tolerance 1e-6, the reduction of ``floor_ratio.py``);
4. **reference**: the error reference of a job (``analysis/reference.py``, ``"surrogate"``: a
   SOAGA model to 1e-12, checked against the full model at 0 Hz and ``--checks`` frequencies),
   then settled on the SOAGA body's error curve (its maximum measured against the full model);
   the body's maximum error and the reference's measured deviation are reported.

Every stage reports its wall time, the peak resident memory of the process during the stage
(``VmHWM``, reset between stages) and the resident memory at its end; the factorizations
report PARDISO's own memory figures and whether they went out of core
(``PYMOREMBS_PARDISO_STORAGE``, ``--storage``). The targets: at most 20 min for stages 3 and 4
together and at most 24 GiB peak.

Usage (big runs need the machine alone: ``flock /work/locks/big``)::

    .venv/bin/python bench/two_million.py --dofs 2000000
    .venv/bin/python bench/two_million.py --dofs 300000 --storage in-core out-of-core --no-results
    .venv/bin/python bench/two_million.py --quick      # 10,000 dofs, seconds
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

import numpy as np
from _common import (
    BAND_HZ,
    build_prepared,
    emit,
    fmt_s,
    krylov_or_soaga_spec,
    machine_facts,
    markdown_table,
    peak_memory_mb,
    reset_peak_memory,
    run_child,
    update_results,
    warm_up,
)
from threadpoolctl import threadpool_limits

TARGET_S = 20 * 60
TARGET_GIB = 24.0
GRID_POINTS = 200
BASELINE_HZ = 500.0
QUICK_DOFS = 10_000


def resident_mb() -> float:
    """Resident memory of this process now, MB (``VmRSS``)."""
    for line in Path("/proc/self/status").read_text().splitlines():
        if line.startswith("VmRSS:"):
            return int(line.split()[1]) / 1024.0
    return float("nan")


class Stage:
    """Context: wall time, peak and final resident memory of one stage, into ``record``."""

    def __init__(self, record: dict, name: str) -> None:
        self.record, self.name = record, name

    def __enter__(self) -> Stage:
        reset_peak_memory()
        print(f"[{time.strftime('%H:%M:%S')}] {self.name} ...", file=sys.stderr, flush=True)
        self.tick = time.perf_counter()
        return self

    def __exit__(self, *exc: object) -> None:
        self.record[self.name] = {
            "s": time.perf_counter() - self.tick,
            "peak_mb": peak_memory_mb(),
            "end_mb": resident_mb(),
        }
        print(f"  {self.record[self.name]}", file=sys.stderr, flush=True)


def sparse_mb(matrix) -> float:
    """Memory of a CSR/CSC matrix's arrays, MB."""
    return (matrix.data.nbytes + matrix.indices.nbytes + matrix.indptr.nbytes) / 2**20


def single_precision_error(matrix) -> dict:
    """Time and error of single-precision PARDISO factors of ``matrix`` (or why refused)."""
    from pymorembs.errors import NumericalError
    from pymorembs.linalg.backends import PardisoFactor

    tick = time.perf_counter()
    try:
        factor = PardisoFactor(matrix, symmetric=True, storage="single")
    except NumericalError as exc:
        return {"s": time.perf_counter() - tick, "refused": str(exc)}
    return {"s": time.perf_counter() - tick, "error": factor.single_error}


STAGES = ("build", "baseline", "soaga", "reference")


def measure(dofs: int, checks: int, until: str = "reference", single: bool = False) -> dict:
    """The stages up to ``until`` in this process (module docstring); the measurements.

    ``single``: also factorize the baseline matrix in single precision and measure the error of
    one solve with it (a known solution; ``PardisoFactor(storage="single")``)."""
    from pymorembs.analysis.reference import reference_response
    from pymorembs.analysis.transfer import transfer_function
    from pymorembs.frequencies import frequency_grid
    from pymorembs.job.run import run_reduction
    from pymorembs.linalg.factorization import Factorization
    from pymorembs.reduction.projection import reduced_model

    stages: dict = {}
    result: dict = {"stages": stages, "storage": os.environ.get("PYMOREMBS_PARDISO_STORAGE")}
    with Stage(stages, "build"):
        prepared, build_s = build_prepared("rack-solid", dofs, "modal")
        system = prepared.system
        del prepared  # the body's own K and M: no export here, only the body and its evidence
    result["build_example_s"] = build_s
    result["n"] = system.order
    result["K_mb"], result["M_mb"] = sparse_mb(system.stiffness), sparse_mb(system.mass)
    result["K_nnz"] = int(system.stiffness.nnz)
    warm_up()  # MKL and the compiled kernels loaded outside the timings
    with threadpool_limits(limits=1, user_api="blas"):
        with Stage(stages, "baseline"):
            sigma = (2 * np.pi * BASELINE_HZ) ** 2
            tick = time.perf_counter()
            one = Factorization([(1.0, system.stiffness), (-sigma, system.mass)], label="baseline")
            result["factorization_s"] = time.perf_counter() - tick
            tick = time.perf_counter()
            one.solve(system.input_matrix.toarray() if hasattr(system.input_matrix, "toarray")
                      else system.input_matrix)  # fmt: skip
            result["solve_s"] = time.perf_counter() - tick
            factor = one.factor
            result["factor"] = {
                "backend": factor.backend,
                "nnz": factor.nnz_factor,
                "out_of_core": bool(getattr(factor, "out_of_core", False)),
                "pardiso_kib": getattr(factor, "memory_report", None),
                "plain_error": one.plain_error,
            }
            if single:
                result["single"] = single_precision_error(one.matrix)
            del one, factor
        if until == "baseline":
            return finish(result)
        with Stage(stages, "soaga"):
            projection = run_reduction(system, krylov_or_soaga_spec("soaga"), BAND_HZ)
            model = reduced_model(system, projection)
        result["order"] = projection.order
        result["soaga"] = {
            k: projection.parameters.get(k)
            for k in ("factorizations", "expansion_points_hz", "stop", "memory_limited")
        }
        result["soaga"]["estimate"] = projection.error_estimate
        if until == "soaga":
            return finish(result)
        grid = frequency_grid(*BAND_HZ, GRID_POINTS)
        with Stage(stages, "reference"):
            reference = reference_response(system, grid, "surrogate", checks=checks)
            reduced = transfer_function(model.system, grid)
            reference = reference.settled(reduced)
            eps = reference.errors(reduced)
        result["reference"] = {
            "order": reference.parameters.get("order"),
            "factorizations": reference.parameters.get("factorizations"),
            "exact_frequencies": int(np.count_nonzero(reference.exact)),
            "accuracy": reference.accuracy,
        }
        result["max_eps"] = float(np.max(eps))
        result["max_eps_exact"] = bool(reference.exact[int(np.argmax(eps))])
        result["resolved"] = reference.resolved(eps)
    return finish(result)


def finish(result: dict) -> dict:
    """The measurements with the peak over all stages run."""
    result["peak_mb"] = max(s["peak_mb"] for s in result["stages"].values())
    return result


def row(r: dict) -> list:
    """One table row of a measurement."""
    s = {key: {"s": float("nan"), "peak_mb": float("nan")} for key in STAGES} | r["stages"]
    job_s = s["soaga"]["s"] + s["reference"]["s"]
    f = r["factor"]
    kib = f["pardiso_kib"] or {}
    r = {
        "order": "–",
        "soaga": {"factorizations": "–"},
        "max_eps": float("nan"),
        "max_eps_exact": False,
    } | r
    r.setdefault("reference", {"accuracy": float("nan")})
    return [
        r["n"],
        r.get("storage") or "auto",
        f"{fmt_s(s['build']['s'])} / {s['build']['peak_mb'] / 1024:.1f}",
        f"{fmt_s(r['factorization_s'])} + {fmt_s(r['solve_s'])} / "
        f"{s['baseline']['peak_mb'] / 1024:.1f}" + (" (out of core)" if f["out_of_core"] else ""),
        f"{kib.get('factors_in_core', 0) / 2**20:.1f}",
        f"{fmt_s(s['soaga']['s'])} / {s['soaga']['peak_mb'] / 1024:.1f}",
        f"{r['order']} ({r['soaga']['factorizations']} fact.)",
        f"{fmt_s(s['reference']['s'])} / {s['reference']['peak_mb'] / 1024:.1f}",
        f"{r['max_eps']:.2e}" + (" (full model)" if r["max_eps_exact"] else ""),
        f"{r['reference']['accuracy']:.1e}",
        f"{fmt_s(job_s)} ({job_s / r['factorization_s']:.1f}×)",
        f"{r['peak_mb'] / 1024:.1f}",
    ]


HEADERS = [
    "independent dofs",
    "storage",
    "build [s / GiB]",
    "baseline: factorization + solve [s] / GiB",
    "PARDISO factors in core [GiB]",
    "SOAGA [s / GiB]",
    "order",
    "reference + checks [s / GiB]",
    "max ε of the body",
    "reference deviation",
    "SOAGA + evidence [s] (÷ baseline factorization)",
    "peak [GiB]",
]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--dofs", type=int, default=2_000_000)
    parser.add_argument(
        "--storage",
        nargs="+",
        default=[None],
        choices=("auto", "in-core", "out-of-core"),
        help="PYMOREMBS_PARDISO_STORAGE of the runs (default: as set, else auto)",
    )
    parser.add_argument("--checks", type=int, default=4, help="reference checks besides 0 Hz")
    parser.add_argument(
        "--until", choices=STAGES[1:], default="reference", help="the last stage to run"
    )
    parser.add_argument(
        "--single", action="store_true", help="also measure single-precision factors"
    )
    parser.add_argument("--quick", action="store_true", help=f"{QUICK_DOFS} dofs only")
    parser.add_argument("--no-results", action="store_true", help="do not write RESULTS.md")
    parser.add_argument("--child", action="store_true", help=argparse.SUPPRESS)
    args = parser.parse_args()
    dofs = QUICK_DOFS if args.quick else args.dofs
    if args.child:
        emit(measure(dofs, args.checks, args.until, args.single))
        return
    rows, failed = [], False
    for storage in args.storage:
        if storage is not None:
            os.environ["PYMOREMBS_PARDISO_STORAGE"] = storage
        print(f"{dofs} dofs, storage {storage or 'as set'} ...", flush=True)
        argv = ["--dofs", str(dofs), "--checks", str(args.checks), "--until", args.until]
        argv += ["--single"] if args.single else []
        r = run_child([__file__, "--child", *argv])
        if "failed" in r:
            failed = True
            print("  " + r["failed"])
            rows.append([dofs, storage or "auto", "failed: " + r["failed"], *[""] * 9])
            continue
        print("  " + str(r), flush=True)
        rows.append(row(r))
    table = markdown_table(HEADERS, rows)
    print(table)
    if not args.no_results:
        body = (
            "rack-solid (hex20; frame at node 2, ports `1: ux uy uz`, 1 % modal damping, band "
            f"0–1000 Hz, error grid of {GRID_POINTS + 1} frequencies), one fresh process per "
            "row. Baseline: one factorization of K − (2π·500 Hz)²M in the same process. "
            f"Targets: SOAGA + evidence ≤ {TARGET_S // 60} min, peak ≤ {TARGET_GIB:.0f} GiB. "
            "Times in s, memory = peak resident set of the stage.\n\n" + table
        )
        name = "Two million dofs" + (", quick" if args.quick else "")
        print(f"written: {update_results(name, body, machine_facts())}")
    sys.exit(1 if failed else 0)


if __name__ == "__main__":
    main()
