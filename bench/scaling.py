"""Scaling curve: Krylov (or SOAGA) reduction time and peak memory of rack-solid vs dofs.

Each size is built and reduced in a fresh process (frame at node 2, ports ``1: ux uy uz``,
band 0-1000 Hz, 1 % modal damping; the reduction of ``floor_ratio.py``). Measured: build time,
reduction time, the time spent in the factorizations (counted by wrapping
``Factorization.__init__``), peak memory of the process and of the reduction alone. Sizes whose
build alone would exceed the available memory (estimated from 3.2 GB at 300,000 dofs) are
skipped. The curve is drawn log-log into ``bench/scaling.png``.

Usage::

    .venv/bin/python bench/scaling.py --dofs 35000 70000 150000 300000 [1000000]
    .venv/bin/python bench/scaling.py --quick      # 7,500 and 10,000 dofs, under a minute
"""

from __future__ import annotations

import argparse
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
from _common import (
    BENCH,
    BUILD_BYTES_PER_DOF,
    available_memory_bytes,
    emit,
    fmt_s,
    machine_facts,
    markdown_table,
    run_child,
    update_results,
)
from floor_ratio import measure

PLOT = BENCH / "scaling.png"
QUICK_SIZES = [7500, 10000]


def plot(results: list[dict], method: str, path=PLOT) -> None:
    """Times and peak memory against the number of independent dofs, log-log."""
    n = [r["n"] for r in results]
    fig, (ax_t, ax_m) = plt.subplots(1, 2, figsize=(11, 4.2))
    ax_t.loglog(n, [r["reduction_s"] for r in results], "o-", label=f"{method} reduction")
    ax_t.loglog(n, [r["factorization_s"] for r in results], "s--", label="of which factorizations")
    ax_t.loglog(
        n,
        [r["factorization_s"] / max(r["n_real"] + r["n_complex"], 1) for r in results],
        "^:",
        label="one factorization (mean)",
    )
    ax_t.loglog(n, [r["build_s"] for r in results], "x-.", label="model build")
    ax_t.set_xlabel("independent dofs")
    ax_t.set_ylabel("wall time [s]")
    ax_t.legend()
    ax_m.loglog(n, [r["peak_mb"] / 1024 for r in results], "o-", label="peak RSS (process)")
    reduction = [r for r in results if r.get("reduction_peak_mb")]
    if reduction:
        ax_m.loglog(
            [r["n"] for r in reduction],
            [r["reduction_peak_mb"] / 1024 for r in reduction],
            "s--",
            label="peak RSS during the reduction",
        )
    ax_m.set_xlabel("independent dofs")
    ax_m.set_ylabel("memory [GiB]")
    ax_m.legend()
    for ax in (ax_t, ax_m):
        ax.grid(True, which="both", alpha=0.3)
    fig.suptitle(f"rack-solid: {method} reduction, 0–1000 Hz, ports 1: ux uy uz")
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--dofs", type=int, nargs="+", default=[35000, 70000, 150000, 300000])
    parser.add_argument("--method", choices=("krylov", "soaga"), default="krylov")
    parser.add_argument("--quick", action="store_true", help=f"sizes {QUICK_SIZES} only")
    parser.add_argument(
        "--memory-gb", type=float, help="memory to plan with (default: MemAvailable)"
    )
    parser.add_argument(
        "--no-results", action="store_true", help="do not write RESULTS.md or the plot"
    )
    parser.add_argument("--child", action="store_true", help=argparse.SUPPRESS)
    args = parser.parse_args()
    sizes = QUICK_SIZES if args.quick else sorted(args.dofs)
    if args.child:
        emit(measure("rack-solid", sizes[0], args.method, "modal", floor=False))
        return

    memory = args.memory_gb * 1024**3 if args.memory_gb else available_memory_bytes()
    results, rows, failed = [], [], False
    for dofs in sizes:
        need = dofs * BUILD_BYTES_PER_DOF
        if need > memory:
            print(f"{dofs}: skipped (build ≈ {need / 1e9:.1f} GB > {memory / 1e9:.1f} GB)")
            rows.append([dofs, "skipped", f"build ≈ {need / 1e9:.1f} GB", *[""] * 6])
            continue
        print(f"{dofs} dofs: {args.method} reduction ...", flush=True)
        r = run_child([__file__, "--child", "--method", args.method, "--dofs", str(dofs)])
        if "failed" in r:
            failed = True
            print("  " + r["failed"])
            rows.append([dofs, "failed", r["failed"], *[""] * 6])
            continue
        results.append(r)
        count = r["n_real"] + r["n_complex"]
        print(f"  {fmt_s(r['reduction_s'])} s, peak {r['peak_mb']:.0f} MB", flush=True)
        rows.append(
            [
                dofs,
                r["n"],
                r["order"],
                fmt_s(r["build_s"]),
                fmt_s(r["reduction_s"]),
                f"{count} ({r['n_real']} real)",
                fmt_s(r["factorization_s"]),
                f"{r['peak_mb'] / 1024:.2f}",
                f"{r['reduction_peak_mb'] / 1024:.2f}" if r.get("reduction_peak_mb") else "–",
            ]
        )
    headers = [
        "--dofs",
        "independent dofs",
        "order",
        "build [s]",
        "reduction [s]",
        "factorizations",
        "in factorizations [s]",
        "peak RSS [GiB]",
        "peak RSS of the reduction [GiB]",
    ]
    table = markdown_table(headers, rows)
    print(table)
    if results and not args.no_results:  # the plot belongs to the RESULTS.md section
        plot(results, args.method)
        print(f"written: {PLOT}")
    if not args.no_results:
        body = (
            f"rack-solid, {args.method} reduction (frame at node 2, ports `1: ux uy uz`, band "
            "0–1000 Hz, 1 % modal damping), one fresh process per size; "
            f"plot: `bench/{PLOT.name}`.\n\n"
            f"{table}\n\n![scaling](scaling.png)"
        )
        name = args.method + (", quick" if args.quick else "")
        path = update_results(f"Scaling ({name})", body, machine_facts())
        print(f"written: {path}")
    sys.exit(1 if failed else 0)


if __name__ == "__main__":
    main()
