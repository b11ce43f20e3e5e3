"""Stress modes of a large tet10 body (issue #29 item 5): time and memory of the stress operator.

The body: a steel box 4 x 2 x 1.2 m of quadratic tetrahedra (a structured grid of cells, each cut
into six tetrahedra, ``tests/stress/box_meshes.py``), its stiffness assembled from the elements
(:func:`pymorembs.elements.solid.assemble_solid_stiffness`), sized to ``--dofs``. A basis of 40
random columns stands for the shape functions of a reduced body.

For each location (``integration``: the 4 integration points of every element; ``nodes``:
averaged at the nodes), in a fresh process after building the model (peak memory reset there):
the time to build the operator (:func:`pymorembs.stress_operator`), the time to apply it to
the basis (the stress modes, ``(n_points, 6, 40)``), the operator's size and the peak memory:
``tracemalloc``'s peak of the arrays allocated by the build (and with the stress modes), in a
second build after the timed one, and the process's peak RSS above the built model (which
undercounts: the build reuses memory the assembly freed).

Baselines of the same process and run: one product ``K @ V`` of the model's stiffness with the
40 columns (a set of sparse matrix-vector products), the time to assemble ``K`` from the
elements (the model's own making), and the size of the model's matrices ``K`` and ``M`` (a
consistent mass has ``K``'s pattern, so ``2 x`` the bytes of ``K``). Target: seconds, peak
memory within the model's matrices.

Usage::

    .venv/bin/python bench/stress_modes.py --dofs 300000
    .venv/bin/python bench/stress_modes.py --quick --no-results
"""

from __future__ import annotations

import argparse
import sys
import time
import tracemalloc
from pathlib import Path

import numpy as np
from _common import (
    emit,
    fmt_s,
    machine_facts,
    markdown_table,
    peak_memory_mb,
    reset_peak_memory,
    run_child,
    update_results,
)

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests" / "stress"))

MODES = 40
SIZE = (4.0, 2.0, 1.2)  # m
LOCATIONS = ("integration", "nodes")


def counts_for(dofs: int) -> tuple[int, int, int]:
    """Cells along x, y, z (ratio 42 : 21 : 13) whose tet10 mesh has about ``dofs`` dofs
    (``3 (2 nx + 1)(2 ny + 1)(2 nz + 1)``: every half-grid point is a node)."""
    scale = 1.0
    for _ in range(60):
        counts = tuple(max(1, round(scale * c)) for c in (42, 21, 13))
        got = 3 * np.prod([2 * c + 1 for c in counts])
        scale *= (dofs / got) ** (1 / 3)
    return counts  # type: ignore[return-value]


def nbytes(matrix) -> int:
    return int(matrix.data.nbytes + matrix.indices.nbytes + matrix.indptr.nbytes)


def measure(location: str, dofs: int) -> dict:
    """Build the model, then the operator of ``location`` and the stress modes (one child)."""
    from box_meshes import box_mesh, solid_body

    import pymorembs as pm

    tick = time.perf_counter()
    points, connectivity = box_mesh("tet10", counts_for(dofs), SIZE)
    body = solid_body("tet10", points, connectivity, 2.1e11, 0.3)
    assemble_s = time.perf_counter() - tick
    basis = np.random.default_rng(0).standard_normal((body.n_dof, MODES))
    stiffness = body.stiffness
    tick = time.perf_counter()
    stiffness @ basis
    product_s = time.perf_counter() - tick
    reset_peak_memory()
    before = peak_memory_mb()
    tick = time.perf_counter()
    op = pm.stress_operator(body, location=location)
    build_s = time.perf_counter() - tick
    tick = time.perf_counter()
    modes = op(basis)
    apply_s = time.perf_counter() - tick
    rss_above = peak_memory_mb() - before
    operator_mb, modes_mb, points = nbytes(op.matrix) / 1e6, modes.nbytes / 1e6, op.n_points
    del op, modes
    tracemalloc.start()  # again, counting every array allocated (NumPy reports to it)
    op = pm.stress_operator(body, location=location)
    built_mb = tracemalloc.get_traced_memory()[1] / 1e6
    op(basis)
    peak_mb = tracemalloc.get_traced_memory()[1] / 1e6
    tracemalloc.stop()
    return {
        "dofs": body.n_dof,
        "elements": int(connectivity.shape[0]),
        "points": points,
        "assemble_s": assemble_s,
        "product_s": product_s,
        "build_s": build_s,
        "apply_s": apply_s,
        "operator_mb": operator_mb,
        "modes_mb": modes_mb,
        "model_mb": 2 * nbytes(stiffness) / 1e6,
        "build_peak_mb": built_mb,
        "peak_mb": peak_mb,
        "rss_above_mb": rss_above,
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--dofs", type=int, nargs="+", default=[300_000])
    parser.add_argument("--quick", action="store_true", help="a 20,000-dof body")
    parser.add_argument("--no-results", action="store_true", help="leave RESULTS.md alone")
    parser.add_argument("--child", nargs=2, metavar=("LOCATION", "DOFS"), help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.child:
        emit(measure(args.child[0], int(args.child[1])))
        return
    sizes = [20_000] if args.quick else args.dofs
    rows = []
    for dofs in sizes:
        for location in LOCATIONS:
            r = run_child([__file__, "--child", location, str(dofs)])
            if "failed" in r:
                rows.append([dofs, location, r["failed"], *[""] * 10])
                continue
            rows.append(
                [
                    r["dofs"],
                    f"{r['elements']} tet10",
                    location,
                    r["points"],
                    fmt_s(r["build_s"]),
                    fmt_s(r["apply_s"]),
                    fmt_s(r["product_s"]),
                    f"{(r['build_s'] + r['apply_s']) / r['product_s']:.3g}",
                    fmt_s(r["assemble_s"]),
                    f"{r['operator_mb']:.0f}",
                    f"{r['modes_mb']:.0f}",
                    f"{r['model_mb']:.0f}",
                    f"{r['build_peak_mb']:.0f}",
                    f"**{r['build_peak_mb'] / r['model_mb']:.2f}**",
                    f"{r['peak_mb']:.0f}",
                    f"{r['rss_above_mb']:.0f}",
                ]
            )
    headers = [
        "dofs", "elements", "location", "points", "build [s]", f"apply to {MODES} modes [s]",
        f"K @ V ({MODES} columns) [s]", "(build + apply) / (K @ V)", "assembling K [s]",
        "operator [MB]", "stress modes [MB]", "K + M [MB]", "peak of the build [MB]",
        "build peak / (K + M)", "peak with the modes [MB]", "RSS above the model [MB]",
    ]  # fmt: skip
    table = markdown_table(headers, rows)
    print(table)
    if not args.no_results:
        body = (
            f"Stress modes ({MODES} random columns) of a tet10 steel box (structured cells cut "
            "into six tetrahedra) at its integration points and nodes; each location in a fresh "
            "process, peak RSS reset after the model is built. Baselines of the same process: "
            f"`K @ V` with the {MODES} columns, the assembly of `K` from the elements, the bytes "
            "of `K` and of a consistent `M` of the same pattern. Peaks: `tracemalloc` of the "
            "arrays allocated by the build (then with the stress modes too), and the RSS above "
            "the built model. Target: seconds, build peak within the model's matrices "
            "(ratio <= 1).\n\n" + table
        )
        update_results("Stress modes (tet10)", body, machine_facts())


if __name__ == "__main__":
    main()
