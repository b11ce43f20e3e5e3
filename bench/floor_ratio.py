"""Floor ratio: how close a Krylov/SOAGA reduction comes to the cost of its factorizations.

    ratio = wall time of the reduction / sum over its factorizations of the time of ONE
            factorization of the same kind of matrix (real K - sigma M, or the complex dynamic
            stiffness) by the fastest available backend, measured in the same run.

The model is ``rack-solid`` (frame at node 2, inputs and outputs ``1: ux uy uz``, band
0-1000 Hz, 1 % modal damping as in ``examples/rack-solid-compare.toml``). The factorizations
of the reduction are counted by wrapping ``Factorization.__init__``. Each size runs in a fresh
process. Target (issue #6): ratio <= 1.5 at 35k and 300k dofs.

Usage::

    .venv/bin/python bench/floor_ratio.py --dofs 35000 300000 [--method krylov|soaga]
    .venv/bin/python bench/floor_ratio.py --quick      # rack-beams, 3,996 dofs, seconds
"""

from __future__ import annotations

import argparse
import sys
import time

import numpy as np
from _common import (
    BAND_HZ,
    FactorizationCounter,
    assemble,
    build_prepared,
    emit,
    fastest,
    fmt_s,
    krylov_or_soaga_spec,
    machine_facts,
    markdown_table,
    peak_memory_mb,
    reset_peak_memory,
    run_child,
    time_backends,
    update_results,
    warm_up,
)
from threadpoolctl import threadpool_limits

TARGET = 1.5


def measure(
    example: str,
    dofs: int | None,
    method: str,
    damping: str,
    floor: bool,
    repeat: int = 1,
    superlu_max: int = 100_000,
) -> dict:
    """Build, prepare and reduce one model in this process; the measurements.

    Parameters
    ----------
    example, dofs, damping
        The model (see ``_common.build_prepared``).
    method : {"krylov", "soaga"}
    floor : bool
        Also time one factorization of each kind of matrix by every available backend.
    repeat : int
        Best of this many timings per backend.
    superlu_max : int
        SuperLU is timed only up to this many dofs (if another backend is available).

    Returns
    -------
    dict
        ``n``, ``build_s``, ``reduction_s``, ``order``, factorization counts and times
        (``n_real``, ``n_complex``, ``factorization_s``), ``peak_mb`` (whole process),
        ``reduction_peak_mb`` (from the end of the preparation), and with ``floor`` the backend
        times per kind and ``ratio``.
    """
    from pymorembs.job.run import run_reduction

    if floor:
        warm_up()
    prepared, build_s = build_prepared(example, dofs, damping)
    system = prepared.system
    spec = krylov_or_soaga_spec(method)
    peak_before = peak_memory_mb()
    reset = reset_peak_memory()
    # BLAS on one thread, as the command line runs it (PARDISO keeps its own threads)
    with FactorizationCounter() as counter, threadpool_limits(limits=1, user_api="blas"):
        tick = time.perf_counter()
        projection = run_reduction(system, spec, BAND_HZ)
        reduction_s = time.perf_counter() - tick
    result = {
        "example": example,
        "n": system.order,
        "method": method,
        "build_s": build_s,
        "reduction_s": reduction_s,
        "order": projection.order,
        "n_real": counter.count("real"),
        "n_complex": counter.count("complex"),
        "factorization_s": counter.seconds(),
        "reported_factorizations": projection.parameters.get("factorizations"),
        # why SOAGA opened the points it did (None for Krylov)
        "expansion_points_hz": projection.parameters.get("expansion_points_hz"),
        "stop": projection.parameters.get("stop"),
        "memory_limited": projection.parameters.get("memory_limited"),
        "reduction_peak_mb": peak_memory_mb() if reset else None,
        "peak_mb": max(peak_before, peak_memory_mb()),
    }
    if floor:
        floor_s = 0.0
        reference = {  # the kind the run did not factorize, for the record (not in the floor)
            "real": [(1.0, system.stiffness), (-((2 * np.pi * 500.0) ** 2), system.mass)],
            "complex": _complex_dynamic_stiffness(system, 500.0),
        }
        for kind in ("real", "complex"):
            terms = counter.first_terms.get(kind)
            limit = superlu_max if terms is not None else 0  # no slow SuperLU for the record
            times = time_backends(
                assemble(reference[kind] if terms is None else terms), repeat, limit
            )
            name, seconds = fastest(times)
            result[f"{kind}_backends"] = times
            result[f"{kind}_fastest"] = [name, seconds]
            floor_s += counter.count(kind) * seconds
        result["floor_s"] = floor_s
        result["ratio"] = reduction_s / floor_s if floor_s > 0 else None  # None: nothing timed
    return result


def _complex_dynamic_stiffness(system, frequency_hz: float) -> list:
    """The terms of ``-omega^2 M + i omega D + (1 + i eta) K`` (complex even without damping)."""
    omega = 2 * np.pi * frequency_hz
    terms = [(1.0, system.stiffness), (complex(-(omega**2)), system.mass)]
    if system.damping is not None:
        terms.append((1j * omega, system.damping))
    elif system.loss_factor:
        terms[0] = (1.0 + 1j * system.loss_factor, system.stiffness)
    else:
        terms.append((1e-3j * omega, system.mass))  # a little mass damping, to be complex
    return terms


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--dofs", type=int, nargs="+", default=[35000], help="rack-solid sizes")
    parser.add_argument("--method", choices=("krylov", "soaga"), default="krylov")
    parser.add_argument(
        "--damping",
        choices=("modal", "rayleigh"),
        default="modal",
        help="modal: real shifted matrices (default); rayleigh: complex ones",
    )
    parser.add_argument("--quick", action="store_true", help="rack-beams (3,996 dofs) only")
    parser.add_argument("--repeat", type=int, default=1, help="best of N backend timings")
    parser.add_argument(
        "--superlu-max-dofs", type=int, default=100_000, help="time SuperLU up to this size"
    )
    parser.add_argument("--no-results", action="store_true", help="do not write RESULTS.md")
    parser.add_argument("--child", action="store_true", help=argparse.SUPPRESS)
    args = parser.parse_args()

    example = "rack-beams" if args.quick else "rack-solid"
    sizes = [None] if args.quick else args.dofs
    if args.child:
        r = measure(
            example, sizes[0], args.method, args.damping, True, args.repeat, args.superlu_max_dofs
        )
        emit(r)
        return

    rows, failed = [], False
    for dofs in sizes:
        argv = [__file__, "--child", "--method", args.method, "--damping", args.damping]
        argv += ["--repeat", str(args.repeat), "--superlu-max-dofs", str(args.superlu_max_dofs)]
        argv += ["--quick"] if args.quick else ["--dofs", str(dofs)]
        print(f"{example}{f' {dofs}' if dofs else ''}: {args.method} reduction ...", flush=True)
        r = run_child(argv)
        if "failed" in r:
            failed = True
            rows.append([example, dofs or "", args.method, r["failed"], *[""] * 7])
            continue
        reported = r.get("reported_factorizations")
        if reported is not None and reported != r["n_real"] + r["n_complex"]:
            print(
                f"  warning: the method reports {reported} factorizations, the counter saw "
                f"{r['n_real'] + r['n_complex']} (factorizations in other processes?)"
            )
        fast = {k: r.get(f"{k}_fastest") for k in ("real", "complex")}
        one = "<br>".join(
            f"{k} ×{r['n_' + k]}: {fmt_s(v[1])} s ({v[0]})" for k, v in fast.items() if v
        )
        ratio = r["ratio"]
        rows.append(
            [
                example,
                r["n"],
                args.method,
                r["order"],
                fmt_s(r["reduction_s"]),
                f"{r['n_real']} / {r['n_complex']}",
                fmt_s(r["factorization_s"]),
                one,
                fmt_s(r["floor_s"]),
                f"**{ratio:.2f}**" if ratio is not None else "n/a",
                f"{r['peak_mb']:.0f}",
            ]
        )
        print(f"  ratio {ratio:.2f} (target <= {TARGET})" if ratio else "  no factorization")
        if r.get("stop") is not None:
            points = ", ".join(f"{f:g}" for f in r.get("expansion_points_hz") or [])
            limited = r["memory_limited"]
            print(f"  stop: {r['stop']}; memory limited: {limited}; points [Hz]: {points}")
    headers = [
        "model",
        "dofs (independent)",
        "method",
        "order",
        "reduction [s]",
        "factorizations real / complex",
        "of which in Factorization [s]",
        "one factorization, fastest backend",
        "floor = count × one [s]",
        "ratio",
        "peak RSS [MB]",
    ]
    table = markdown_table(headers, rows)
    print(table)
    if not args.no_results:
        body = (
            f"Wall time of a {args.method} reduction of the rack (frame at node 2, ports "
            f"`1: ux uy uz`, band 0–1000 Hz, {args.damping} damping) ÷ (number of factorizations "
            "× time of one factorization of the same kind of matrix by the fastest available "
            f"backend, same run). Target ≤ {TARGET}.\n\n" + table
        )
        name = f"{args.method}, {args.damping} damping" + (", quick" if args.quick else "")
        path = update_results(f"Floor ratio ({name})", body, machine_facts())
        print(f"written: {path}")
    sys.exit(1 if failed else 0)


if __name__ == "__main__":
    main()
