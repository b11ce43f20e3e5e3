"""Cost of the error curves (issue #6): checked reference model vs the full frequency sweep.

For ``rack-solid`` (frame at node 2, inputs and outputs ``1: ux uy uz``, Rayleigh damping
``D = 2e-6 s * K``, band 0-1000 Hz, error grid of 201 frequencies) in a fresh process per size:

* the Krylov reduction of ``floor_ratio.py`` (points 0, 500, 1000 Hz; moments 6, 5, 5), timed;
* the reference of its error curve with ``reference = "surrogate"``
  (:func:`pymorembs.analysis.reference.reference_response`: a SOAGA reference model, checked
  against the full model at 0 Hz and 4 more frequencies), timed, and the check of the
  reduction's maximum (:meth:`ReferenceResponse.settled`);
* one complex factorization of the full model at 500 Hz (the cost of one frequency of the full
  sweep), and from it the full sweep of 201 frequencies shared by the usable cores -- the
  ``reference = "full"`` alternative; where ``bench/.cache`` holds the full response of this
  model (``peers.py``, ``large_gramian.py``), the measured sweep time and the true deviation
  of the reference model over all 201 frequencies are reported too.

Usage::

    .venv/bin/python bench/reference.py --dofs 10000 35000
    .venv/bin/python bench/reference.py --dofs 300000 --no-results
"""

from __future__ import annotations

import argparse
import glob
import sys
import time

import numpy as np
from _common import (
    BAND_HZ,
    BENCH,
    build_prepared,
    emit,
    fmt_s,
    krylov_or_soaga_spec,
    machine_facts,
    markdown_table,
    peak_memory_mb,
    run_child,
    update_results,
)
from threadpoolctl import threadpool_limits

POINTS = 200


def measure(dofs: int) -> dict:
    """One size in this process: reduction, reference, one full-model frequency."""
    from pymorembs.analysis.error import relative_error
    from pymorembs.analysis.reference import reference_response
    from pymorembs.analysis.transfer import transfer_function
    from pymorembs.frequencies import frequency_grid
    from pymorembs.job.run import run_reduction
    from pymorembs.linalg.factorization import Factorization
    from pymorembs.parallel import usable_cores
    from pymorembs.reduction.projection import reduced_model

    prepared, _ = build_prepared("rack-solid", dofs, "rayleigh")
    system = prepared.system
    grid = frequency_grid(*BAND_HZ, POINTS)
    with threadpool_limits(limits=1, user_api="blas"):
        tick = time.perf_counter()
        model = reduced_model(
            system, run_reduction(system, krylov_or_soaga_spec("krylov"), BAND_HZ)
        )
        reduction_s = time.perf_counter() - tick
        tick = time.perf_counter()
        reference = reference_response(system, grid, "surrogate", workers=None)
        reference_s = time.perf_counter() - tick
        reduced = transfer_function(model.system, grid)
        tick = time.perf_counter()
        reference = reference.settled(reduced)
        eps = reference.errors(reduced)
        settle_s = time.perf_counter() - tick
        terms, _ = system.dynamic_terms(2j * np.pi * 500.0)
        tick = time.perf_counter()
        Factorization(terms, label="one frequency").solve(system.input_matrix)
        one_s = time.perf_counter() - tick
    result = {
        "n": system.order,
        "reduction_s": reduction_s,
        "reduction_order": model.projection.order,
        "reference_s": reference_s,
        "settle_s": settle_s,
        "reference_order": reference.parameters["order"],
        "reference_factorizations": reference.parameters["factorizations"],
        "checks": int(np.count_nonzero(reference.exact)),
        "accuracy": reference.accuracy,
        "max_eps": float(eps.max()),
        "one_frequency_s": one_s,
        "cores": usable_cores(),
        "full_sweep_estimate_s": grid.size * one_s / usable_cores(),
        "peak_mb": peak_memory_mb(),
    }
    cached = glob.glob(
        str(BENCH / ".cache" / f"rack-solid-{system.order}-rayleigh-*-{POINTS}-*.npz")
    )
    if cached:
        data = np.load(cached[0])
        full = data["response"]
        true_deviation = relative_error(full, reference.response)
        true_eps = relative_error(full, reduced)
        result.update(
            full_sweep_measured_s=float(data["seconds"]),
            true_deviation=float(true_deviation.max()),
            true_max_eps=float(true_eps.max()),
        )
    return result


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--dofs", type=int, nargs="+", default=[10000, 35000])
    parser.add_argument("--no-results", action="store_true", help="do not write RESULTS.md")
    parser.add_argument("--child", action="store_true", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.child:
        emit(measure(args.dofs[0]))
        return
    rows, failed = [], False
    for dofs in args.dofs:
        print(f"{dofs} dofs ...", flush=True)
        r = run_child([__file__, "--child", "--dofs", str(dofs)])
        if "failed" in r:
            failed = True
            print("  " + r["failed"])
            continue
        print(
            f"  reduction {fmt_s(r['reduction_s'])} s, reference {fmt_s(r['reference_s'])} s "
            f"(+{fmt_s(r['settle_s'])} s settle), "
            f"full sweep ≈ {fmt_s(r['full_sweep_estimate_s'])} s",
            flush=True,
        )
        measured = r.get("full_sweep_measured_s")
        rows.append(
            [
                r["n"],
                f"{fmt_s(r['reduction_s'])} (n = {r['reduction_order']})",
                f"{fmt_s(r['reference_s'] + r['settle_s'])} (n = {r['reference_order']}, "
                f"{r['reference_factorizations']} fact., {r['checks']} checks)",
                f"{fmt_s(r['one_frequency_s'])}",
                f"{fmt_s(r['full_sweep_estimate_s'])}"
                + ("" if measured is None else f" (measured once: {fmt_s(measured)})"),
                f"{r['accuracy']:.1e}",
                "–" if "true_deviation" not in r else f"{r['true_deviation']:.1e}",
                f"{r['max_eps']:.2e}"
                + ("" if "true_max_eps" not in r else f" (true {r['true_max_eps']:.2e})"),
                f"{r['peak_mb'] / 1024:.2f}",
            ]
        )
    headers = [
        "independent dofs",
        "Krylov reduction [s]",
        "reference model + checks [s]",
        "one full frequency [s]",
        "full sweep, 201 frequencies [s]",
        "deviation at checks",
        "true deviation (all 201)",
        "Krylov max ε",
        "peak RSS [GiB]",
    ]
    table = markdown_table(headers, rows)
    print(table)
    if not args.no_results and rows:
        body = (
            "rack-solid, Rayleigh damping `D = 2e-6 s * K`, frame at node 2, ports `1: ux uy uz`, "
            "band 0–1000 Hz, 201 frequencies; one fresh process per size. The full sweep is "
            "201 × one complex factorization and solve ÷ usable cores (the `reference = "
            '"full"` path); the reference is `reference = "surrogate"` including the check of '
            "the Krylov model's maximum.\n\n" + table
        )
        path = update_results("Error reference (surrogate vs full)", body, machine_facts())
        print(f"written: {path}")
    sys.exit(1 if failed else 0)


if __name__ == "__main__":
    main()
