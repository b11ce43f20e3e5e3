"""Large-scale Gramians (issue #6): rational-Krylov Gramians vs the two-step approach vs POD.

On ``rack-solid`` (frame at node 2, inputs and outputs ``1: ux uy uz``, Rayleigh damping
``D = 2e-6 s * K``), band 0-1000 Hz, three ways to the dominant eigenspace of the
frequency-weighted Gramians ``P_p^w + Q_pv^w`` (paper section 3.2) of the large model:

* ``rational-krylov``: :func:`pymorembs.reduction.rational_gramian.rational_gramian_reduction`,
  Galerkin projection on an adaptive rational Krylov subspace, stopped when the Gramian stops
  changing (no fixed first-stage order);
* ``two-step``: what ``run_reduction`` does for method ``gramian`` on a large model -- SOAGA to
  order 132 (first tolerance 1e-10), then the dense Gramians of that medium model;
* ``pod``: :func:`pymorembs.reduction.gramian.pod_reduction`, 40 Gauss snapshots.

Each at order 35 and with the tolerance 1e-6 of the eq. 24 indicator ``sigma_{n+1} / sigma_1``.
For each: wall time of the reduction, sparse factorizations (``Factorization`` objects created,
inertia relief included), peak memory of its process (each method runs in a fresh process; the
peak is reset after building the model where Linux allows), and the largest relative error eps
(paper eq. 27) over the 201 frequencies of the error grid against the full model's response,
computed once and cached in ``bench/.cache/`` (:func:`peers.full_response`).

Usage::

    .venv/bin/python bench/large_gramian.py --dofs 10000
    .venv/bin/python bench/large_gramian.py --dofs 35000     # full response ~5-8 min once
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np
from _common import (
    BAND_HZ,
    FactorizationCounter,
    build_prepared,
    emit,
    fmt_s,
    machine_facts,
    markdown_table,
    peak_memory_mb,
    reset_peak_memory,
    run_child,
    update_results,
)
from peers import full_response

ORDER = 35
TOLERANCE = 1e-6
SNAPSHOTS = 40
#: Method name -> what it is.
METHODS = {
    "rational-krylov": f"rational-Krylov Gramians, order {ORDER}",
    "two-step": f"SOAGA to 132 + dense Gramians, order {ORDER}",
    "pod": f"POD, {SNAPSHOTS} snapshots, order {ORDER}",
    "rational-krylov-tol": f"rational-Krylov Gramians, tolerance {TOLERANCE:g}",
    "two-step-tol": f"SOAGA to 132 + dense Gramians, tolerance {TOLERANCE:g}",
    "pod-tol": f"POD, {SNAPSHOTS} snapshots, tolerance {TOLERANCE:g}",
}


def reduce(method: str, system):
    """The projection of ``method`` and facts about it (dimension of the intermediate space)."""
    from pymorembs.job.run import run_reduction
    from pymorembs.job.schema import ReductionSpec
    from pymorembs.methods import method_options
    from pymorembs.reduction.gramian import pod_reduction
    from pymorembs.reduction.rational_gramian import rational_gramian_reduction

    base = method.removesuffix("-tol")
    order, tolerance = (None, TOLERANCE) if method.endswith("-tol") else (ORDER, None)
    if base == "rational-krylov":
        projection = rational_gramian_reduction(system, BAND_HZ, order=order, tolerance=tolerance)
        parameters = projection.parameters
        facts = {
            "space": parameters["krylov_dimension"],
            "detail": f"{parameters['factorizations']} shifts, {parameters['iterations']} "
            f"iterations, stop: {parameters['stop']}, last change "
            f"{parameters['gramian_change']:.0e}",
            "shifts_hz": [round(f, 1) for f in parameters["shifts_hz"]],
        }
    elif base == "two-step":
        options = {"order": order, "tolerance": tolerance}
        spec = ReductionSpec(method, method_options("gramian", options))
        projection = run_reduction(system, spec, BAND_HZ)
        parameters = projection.parameters
        facts = {"space": parameters["medium_order"], "detail": "medium model (SOAGA)"}
        capped = parameters.get("order_capped_by_first_stage")
        if capped:
            facts["detail"] += f"; order capped at {capped}"
    else:
        projection = pod_reduction(
            system, BAND_HZ, order=order, tolerance=tolerance, n_snapshots=SNAPSHOTS
        )
        facts = {"space": 2 * SNAPSHOTS * system.n_inputs, "detail": "snapshot columns"}
    return projection, facts


def child(method: str, dofs: int, cache: Path) -> dict:
    """Build the model, reduce it with ``method`` and measure (runs in its own process)."""
    from pymorembs.analysis.error import relative_error
    from pymorembs.analysis.transfer import transfer_function
    from pymorembs.reduction.projection import reduced_model

    prepared, _ = build_prepared("rack-solid", dofs, "rayleigh")
    system = prepared.system
    reset = reset_peak_memory()
    tick = time.perf_counter()
    with FactorizationCounter() as counter:
        projection, facts = reduce(method, system)
        reduced = reduced_model(system, projection).system
    seconds = time.perf_counter() - tick
    peak = peak_memory_mb()
    data = np.load(cache)
    eps = relative_error(data["response"], transfer_function(reduced, data["frequencies"]))
    return {
        "method": method,
        "n": system.order,
        "order": reduced.order,
        "seconds": seconds,
        "factorizations": len(counter.calls),
        "factorization_s": counter.seconds(),
        "peak_mb": peak,
        "peak_is_method_only": reset,
        "max_eps": float(np.max(eps)),
        "a_priori_bound": projection.parameters.get("a_priori_bound"),
        **facts,
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--dofs", type=int, default=10000, help="rack-solid size (default 10k)")
    parser.add_argument("--methods", nargs="+", choices=list(METHODS), default=list(METHODS))
    parser.add_argument("--points", type=int, default=200, help="error grid (+ 0 Hz)")
    parser.add_argument("--timeout", type=float, default=3600, help="per method, seconds")
    parser.add_argument("--no-results", action="store_true", help="do not write RESULTS.md")
    parser.add_argument("--child", metavar="METHOD", help=argparse.SUPPRESS)
    parser.add_argument("--cache", type=Path, help=argparse.SUPPRESS)
    args = parser.parse_args()

    if args.child:
        emit(child(args.child, args.dofs, args.cache))
        return

    cache = full_response("rack-solid", args.dofs, args.points)
    cached = np.load(cache)
    results = {}
    for method in args.methods:
        print(f"{method} ...", flush=True)
        argv = [__file__, "--child", method, "--cache", str(cache), "--dofs", str(args.dofs)]
        results[method] = r = run_child(argv, timeout=args.timeout)
        print("  " + (r.get("failed") or f"{fmt_s(r['seconds'])} s, max eps {r['max_eps']:.1e}"))

    rows = []
    for method, r in results.items():
        if "failed" in r:
            rows.append([method, METHODS[method], "", "", r["failed"], "", "", "", ""])
            continue
        rows.append(
            [
                method,
                METHODS[method],
                r["order"],
                f"{r['space']} ({r['detail']})",
                fmt_s(r["seconds"]),
                f"{r['factorizations']} ({fmt_s(r['factorization_s'])} s)",
                f"{r['peak_mb']:.0f}",
                f"{r['max_eps']:.1e}",
                "" if r["a_priori_bound"] is None else f"{r['a_priori_bound']:.1e}",
            ]
        )
    headers = [
        "name",
        "method",
        "order",
        "intermediate space",
        "time [s]",
        "factorizations (time)",
        "peak RSS [MB]",
        "max ε",
        "sqrt(Σ neglected σ)",
    ]
    table = markdown_table(headers, rows)
    print(table)
    shifts = results.get("rational-krylov", {}).get("shifts_hz")
    note = f"Shifts of `rational-krylov` (Hz, in order): {shifts}." if shifts else ""
    if not args.no_results:
        n = int(cached["n"])
        body = (
            f"Model: rack-solid ({n} independent dofs), frame at node 2, ports `1: ux uy uz`, "
            "Rayleigh damping D = 2e-6 s · K, band 0–1000 Hz; max ε (eq. 27) over "
            f"{cached['frequencies'].size} frequencies (full response: "
            f"{float(cached['seconds']):.0f} s, cached). Each method in a fresh process; peak "
            "RSS measured from after the model build (Linux `clear_refs`); time includes "
            "`reduced_model`. The last column is the a-priori part of eq. 24 "
            "(κ = κ_T = 1) from the method's own Gramian eigenvalues (POD: approximate).\n\n"
            f"{table}\n\n{note}"
        )
        path = update_results(f"Large-scale Gramians ({args.dofs} dofs)", body, machine_facts())
        print(f"written: {path}")
    sys.exit(1 if any("failed" in r for r in results.values()) else 0)


if __name__ == "__main__":
    main()
