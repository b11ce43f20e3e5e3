"""Distributed backend (issue #30 item 6): MUMPS over MPI against the default backend, one run.

Run under MPI, one process per rank (rank 0 does the measuring, the others serve MUMPS)::

    mpiexec -n 2 .venv/bin/python bench/distributed.py --dofs 35000 300000

For each rack-solid size, in this order, in one process on rank 0:

1. one factorization of ``A = K - (2 pi 500 Hz)^2 M`` (real symmetric indefinite) and of
   ``(1 + 0.02 i) K - (2 pi 500 Hz)^2 M`` (complex symmetric) by the default backend (the
   baseline: PARDISO where installed) and by MUMPS on all ranks, each followed by one solve of
   the six columns ``[B, M B]`` (``B`` the three port forces): wall times, the factors' memory as
   each solver counts it (PARDISO's peak, MUMPS's ``INFOG(22)``), MUMPS's memory per rank
   (``INFO(22)`` factorization, ``INFO(26)`` solve) and each rank's peak resident memory, the
   relative residual ``|A x - b| / |b|`` of each solution (a backward-error check nobody here
   wrote: only the matrix and the vector) and the relative difference of the two solutions;
2. the Krylov reduction of ``bench/floor_ratio.py`` (points 0, 500, 1000 Hz; moments 6, 5, 5)
   once with each backend: the two bodies compared by their eigenfrequencies (all of them) and
   by their transfer functions at the port (3 x 3, 401 points on 0-1000 Hz): the largest
   difference relative to the largest entry of the default body's response at that frequency;
   and each body's eigenfrequencies in the band against the full model's (ARPACK, shift-invert
   about 0 with the default backend), to see whether the two bodies differ by less than
   either differs from the model.

The section "Distributed backend" of ``bench/RESULTS.md`` is replaced by the results.
"""

from __future__ import annotations

import argparse
import os
import sys
import time

import numpy as np
import scipy.sparse as sp
from _common import (
    BAND_HZ,
    build_prepared,
    command_line,
    fmt_s,
    krylov_or_soaga_spec,
    machine_facts,
    markdown_table,
    peak_memory_mb,
    update_results,
    warm_up,
)
from threadpoolctl import threadpool_limits

from pymorembs.linalg.backends import SOLVER_ENV, default_backend, factorize
from pymorembs.linalg.mumps_mpi import BACKEND, rank_statistics, serve_solver_ranks

#: Shift of the factorized matrices, Hz (inside the band, so ``A`` is indefinite).
SHIFT_HZ = 500.0
#: Loss factor of the complex matrix.
LOSS = 0.02


def solve_pair(matrix: sp.csr_matrix, rhs: np.ndarray, backend: str | None) -> dict:
    """Factorize and solve once; times, memory, residual, the solution."""
    tick = time.perf_counter()
    factor = factorize(matrix, symmetric=True, backend=backend)
    factor_s = time.perf_counter() - tick
    tick = time.perf_counter()
    x = factor.solve(rhs)
    solve_s = time.perf_counter() - tick
    residual = np.linalg.norm(matrix @ x - rhs) / np.linalg.norm(rhs)
    result = {
        "backend": factor.backend,
        "factor_s": factor_s,
        "solve_s": solve_s,
        "factor_gb": factor.memory_bytes / 1e9,
        "nnz_factor": factor.nnz_factor,
        "residual": float(residual),
        "x": x,
    }
    if factor.backend == BACKEND:
        result["ranks"] = rank_statistics()
        result["ordering"] = factor.ordering
    del factor
    return result


def reduce_with(system, backend: str | None):
    """The Krylov body of ``system`` with the backend (None: the default); its seconds."""
    from pymorembs.job.run import run_reduction
    from pymorembs.reduction import reduced_model

    if backend is None:
        os.environ.pop(SOLVER_ENV, None)
    else:
        os.environ[SOLVER_ENV] = backend
    try:
        with threadpool_limits(limits=1, user_api="blas"):
            tick = time.perf_counter()
            projection = run_reduction(system, krylov_or_soaga_spec("krylov"), BAND_HZ)
            body = reduced_model(system, projection)
            return body, time.perf_counter() - tick
    finally:
        os.environ[SOLVER_ENV] = BACKEND


def blas_library() -> str:
    """The file of ``libblas.so.3`` this process loaded (MUMPS's BLAS), links resolved."""
    try:
        with open("/proc/self/maps", encoding="utf-8") as maps:
            paths = {line.split()[-1] for line in maps if "libblas.so" in line}
    except OSError:
        return "unknown"
    return ", ".join(sorted(os.path.realpath(p) for p in paths)) or "none loaded"


def full_frequencies_hz(system, count: int, backend: str) -> np.ndarray:
    """The ``count`` lowest eigenfrequencies of the full model (Hz): ARPACK in shift-invert
    mode about 0 with a refined factorization of ``K`` by ``backend``."""
    from scipy.sparse.linalg import eigsh

    from pymorembs.linalg.factorization import Factorization

    inverse = Factorization(system.stiffness, "K", backend=backend).operator()
    values = eigsh(system.stiffness, count, system.mass, sigma=0.0, OPinv=inverse,
                   return_eigenvectors=False)  # fmt: skip
    return np.sort(np.sqrt(np.abs(values))) / (2 * np.pi)


def measure(dofs: int) -> dict:
    """All measurements of one size (see the module docstring)."""
    from pymorembs.analysis import frequency_grid, transfer_function

    prepared, build_s = build_prepared("rack-solid", dofs)
    system = prepared.system
    n = system.order
    print(f"rack-solid {n} dofs (built in {build_s:.0f} s)", flush=True)
    omega2 = (2 * np.pi * SHIFT_HZ) ** 2
    stiffness, mass = sp.csr_matrix(system.stiffness), sp.csr_matrix(system.mass)
    forces = np.asarray(system.input_matrix, dtype=float)
    rhs = np.column_stack([forces, mass @ forces])
    result: dict = {"n": n, "build_s": build_s, "nnz": int(stiffness.nnz), "nnz_mass": mass.nnz}
    os.environ.pop(SOLVER_ENV, None)
    baseline = default_backend()
    os.environ[SOLVER_ENV] = BACKEND
    for kind, matrix in (
        ("real", (stiffness - omega2 * mass).tocsr()),
        ("complex", ((1 + 1j * LOSS) * stiffness - omega2 * mass).tocsr()),
    ):
        default = solve_pair(matrix, rhs, baseline)
        print(f"  {kind}: {default['backend']} {default['factor_s']:.1f} s", flush=True)
        mumps = solve_pair(matrix, rhs, BACKEND)
        print(f"  {kind}: mumps {mumps['factor_s']:.1f} s", flush=True)
        x_default, x_mumps = default.pop("x"), mumps.pop("x")
        difference = np.linalg.norm(x_mumps - x_default) / np.linalg.norm(x_default)
        result[kind] = {"default": default, "mumps": mumps, "difference": float(difference)}
        del matrix
    bodies = {}
    for name, backend in (("default", baseline), ("mumps", BACKEND)):
        body, seconds = reduce_with(system, None if name == "default" else backend)
        bodies[name] = body
        result[f"reduction_{name}_s"] = seconds
        print(f"  krylov with {name}: order {body.projection.order}, {seconds:.1f} s", flush=True)
    first, second = bodies["default"], bodies["mumps"]
    result["order"] = [first.projection.order, second.projection.order]
    if first.projection.order == second.projection.order:
        f1, f2 = np.sort(first.eigenfrequencies_hz), np.sort(second.eigenfrequencies_hz)
        differences = np.abs(f2 - f1) / f1
        inside = f1 <= BAND_HZ[1]
        result["band_modes"] = int(np.count_nonzero(inside))
        result["frequency_difference"] = float(np.max(differences[inside], initial=0.0))
        result["outside_difference"] = float(np.max(differences[~inside], initial=0.0))
        full = full_frequencies_hz(system, int(np.count_nonzero(inside)) + 4, baseline)
        for name, frequencies in (("default", f1), ("mumps", f2)):
            ritz = frequencies[inside]
            result[f"modal_error_{name}"] = float(np.max(np.abs(ritz - full[: ritz.size]) / ritz))
    grid = frequency_grid(*BAND_HZ, 400)
    h1 = transfer_function(first.system, grid)
    h2 = transfer_function(second.system, grid)
    scale = np.max(np.abs(h1).reshape(h1.shape[0], -1), axis=1)
    result["transfer_difference"] = float(
        np.max(np.abs(h2 - h1).reshape(h1.shape[0], -1).max(axis=1) / scale)
    )
    result["host_peak_mb"] = peak_memory_mb()
    return result


#: The size of the cluster plan of docs/performance.md.
PROJECTED_DOFS = 20_000_000


def projection_table(small: dict, large: dict) -> str:
    """Figures of ``large`` extrapolated to :data:`PROJECTED_DOFS` by the power law through
    ``small`` and ``large`` (see the text of the section); a Markdown table."""
    n1, n2, n = small["n"], large["n"], PROJECTED_DOFS
    rows = []

    def extrapolate(label: str, y1: float, y2: float, unit: str) -> None:
        exponent = np.log(y2 / y1) / np.log(n2 / n1)
        value = y2 * (n / n2) ** exponent
        rows.append([label, f"{y1:.3g}", f"{y2:.3g}", f"{exponent:.2f}", f"{value:.3g} {unit}"])

    for kind in ("real", "complex"):
        a, b = small[kind]["mumps"], large[kind]["mumps"]
        label = f"MUMPS factorization memory (INFOG(22)), all ranks, {kind} [GB]"
        extrapolate(label, a["factor_gb"], b["factor_gb"], "GB")
        extrapolate(f"MUMPS factorization, 2 ranks, {kind} [s]", a["factor_s"], b["factor_s"], "s")
        extrapolate(f"MUMPS solve of 6 columns, {kind} [s]", a["solve_s"], b["solve_s"], "s")
    per_row = large["nnz"] / n2, large["nnz_mass"] / n2
    gigabytes = 12 * n / 1e9
    rows.append(["rank 0: K and M as read", "", "", "", f"{gigabytes * sum(per_row):.3g} GB"])
    rows.append(
        ["rank 0: one shifted matrix K - w^2 M", "", "", "", f"{gigabytes * per_row[0]:.3g} GB"]
    )
    upper = (per_row[0] + 1) / 2
    rows.append(
        [
            "rank 0: its upper triangle and the rows sent to the ranks",
            "",
            "",
            "",
            f"{(12 + 16) * upper * n / 1e9:.3g} GB",
        ]
    )
    order = large["order"][0]
    rows.append(
        [f"rank 0: a basis of {order} columns", "", "", "", f"{8 * n * order / 1e9:.3g} GB"]
    )
    return markdown_table(
        ["figure", f"at {n1:,}", f"at {n2:,}", "exponent a", f"at {n:,} dofs"], rows
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--dofs", type=int, nargs="+", default=[35000], help="rack-solid sizes")
    parser.add_argument("--no-results", action="store_true", help="do not write RESULTS.md")
    args = parser.parse_args()
    os.environ[SOLVER_ENV] = BACKEND  # every rank: the ranks > 0 serve MUMPS
    if serve_solver_ranks():
        return
    ranks = rank_statistics()
    warm_up()
    rows, memory_rows, body_rows = [], [], []
    measured = []
    for dofs in args.dofs:
        r = measure(dofs)
        measured.append(r)
        for kind in ("real", "complex"):
            d, m = r[kind]["default"], r[kind]["mumps"]
            rows.append(
                [
                    r["n"],
                    kind,
                    f"{d['backend']} {fmt_s(d['factor_s'])} s, {d['factor_gb']:.2f} GB",
                    f"{fmt_s(m['factor_s'])} s, {m['factor_gb']:.2f} GB ({m['ordering']})",
                    f"{m['factor_s'] / d['factor_s']:.2f}",
                    f"{fmt_s(d['solve_s'])} / {fmt_s(m['solve_s'])}",
                    f"{d['residual']:.1e} / {m['residual']:.1e}",
                    f"{r[kind]['difference']:.1e}",
                ]
            )
            for rank, stats in enumerate(m["ranks"]):
                memory_rows.append(
                    [
                        r["n"],
                        kind,
                        rank,
                        f"{stats['factor_space'] / 1e6:.1f}",
                        f"{stats['factorization_mb']:.0f}",
                        f"{stats['solve_mb']:.0f}",
                        f"{stats['peak_rss_mb']:.0f}",
                    ]
                )
        body_rows.append(
            [
                r["n"],
                " / ".join(map(str, r["order"])),
                f"{fmt_s(r['reduction_default_s'])} / {fmt_s(r['reduction_mumps_s'])}",
                f"{r.get('band_modes', '?')}: {r.get('frequency_difference', float('nan')):.1e}",
                f"{r.get('outside_difference', float('nan')):.1e}",
                f"{r['transfer_difference']:.1e}",
                f"{r.get('modal_error_default', float('nan')):.1e} / "
                f"{r.get('modal_error_mumps', float('nan')):.1e}",
                f"{r['host_peak_mb']:.0f}",
            ]
        )
        print(body_rows[-1], flush=True)
    factor_table = markdown_table(
        [
            "dofs",
            "matrix",
            "default backend: factorization",
            "MUMPS on all ranks (ordering)",
            "MUMPS / default",
            "solve of 6 columns [s] default / MUMPS",
            "residual default / MUMPS",
            "solutions differ by",
        ],
        rows,
    )
    memory_table = markdown_table(
        [
            "dofs",
            "matrix",
            "rank",
            "factor space [M entries]",
            "factorization [MB]",
            "solve [MB]",
            "peak RSS of the rank [MB]",
        ],
        memory_rows,
    )
    body_table = markdown_table(
        [
            "dofs",
            "Krylov order default / MUMPS",
            "reduction [s] default / MUMPS",
            "eigenfrequencies in the band: count, largest difference",
            "eigenfrequencies above the band: largest difference",
            "transfer functions differ by",
            "in-band eigenfrequencies against the full model's, default / MUMPS body",
            "rank 0 peak RSS [MB]",
        ],
        body_rows,
    )
    projection = projection_table(measured[0], measured[-1]) if len(measured) > 1 else ""
    print(factor_table, memory_table, body_table, projection, sep="\n\n")
    if args.no_results:
        return
    text = (
        "Rack-solid; rank 0 measures, the other ranks serve MUMPS. One factorization and one "
        "solve of each matrix by the default backend and by MUMPS on all ranks (shift 500 Hz; "
        "complex: loss factor 0.02); residual "
        "|A x - b| / |b| of the six right-hand sides [B, M B]; MUMPS's memory per rank as it "
        "counts it (INFO(22), INFO(26); MB = 1e6 bytes) and each rank's peak resident memory "
        "(rank 0 also holds the model and the default backend's run).\n\n"
        f"{factor_table}\n\n{memory_table}\n\nThe same Krylov body (points 0, 500, 1000 Hz, "
        "moments 6, 5, 5) with each backend: largest relative difference of the "
        "eigenfrequencies, and of the transfer functions at the port (401 frequencies on "
        "0-1000 Hz, relative to the largest entry at each frequency); each body's eigenfrequencies "
        "in the band against the full model's (ARPACK in shift-invert mode, default backend).\n\n"
        f"{body_table}"
    )
    if projection:
        text += (
            f"\n\nProjection to {PROJECTED_DOFS:,} dofs of the same kind of model: each figure "
            "y measured at the two sizes n1 < n2 extrapolated as y2 (n / n2)^a with "
            "a = ln(y2 / y1) / ln(n2 / n1) (a power law fitted on two points, not a "
            "measurement); rank 0's arrays from the measured entries per row (8-byte values, "
            "4-byte indices).\n\n" + projection
        )
    facts = machine_facts()
    facts["MPI ranks"] = str(len(ranks))
    facts["BLAS of MUMPS"] = blas_library()
    path = update_results("Distributed backend", text, facts)
    # the command as it ran: under mpiexec
    plain = f"Command: `{command_line()}`"
    launched = f"Command: `mpiexec -n {len(ranks)} --bind-to none {command_line()}`"
    path.write_text(path.read_text(encoding="utf-8").replace(plain, launched), encoding="utf-8")


if __name__ == "__main__":
    sys.exit(main())
