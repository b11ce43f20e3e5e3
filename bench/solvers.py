"""Sparse solvers (issue #30 item 1): the project's MKL PARDISO against its SuperLU.

Both backends of :mod:`pymorembs.linalg.backends`, as a reduction calls them
(``factorize(A, symmetric=True, backend=...)``), factorize the same matrices:

* ``real``: ``A = K - sigma M`` with ``sigma = (2 pi 1000 Hz)^2``, inside the spectrum of every
  model here (symmetric indefinite: PARDISO ``mtype -2``, SuperLU with the project's settings);
* ``complex``: ``A = (1 + 0.02 i) K - sigma M``, a loss factor of 2 % at the same frequency
  (complex symmetric: PARDISO ``mtype 6``, SuperLU's complex LU).

Models, each sized to ``--dofs``:

* ``hex20``: ``build_example("rack-solid", dofs=N)`` prepared as in every benchmark here (frame at
  node 2, ports ``1: ux uy uz``; ``bench/_common.build_prepared``): the matrices of the
  prepared system, i.e. after the elimination of the rack's constraint equations -- the
  matrices a reduction factorizes;
* ``tet10``: the steel box of ``bench/stress_modes.py`` (quadratic tetrahedra,
  ``tests/stress/box_meshes.py``), free, with a lumped mass of steel (7850 kg/m^3) spread
  evenly over its dofs (the box's own mass is a unit placeholder).

Every factorization runs in a fresh process (``_common.run_child``) that loads the cached
matrices, forms ``A``, resets its peak memory and then factorizes ``A`` and solves 20 random
right-hand sides in one call. Reported: factor time, solve time, peak RSS above the loaded
model, the factor's nonzeros, the backward error ``max_j |A x_j - b_j|_inf / (|A|_inf
|x_j|_inf + |b_j|_inf)`` and, for PARDISO's real factor, the number of negative eigenvalues
(its inertia). SuperLU runs under a time limit (``--superlu-limit``) and is then reported as
"not finished in N s"; its complex factorization is skipped when the real one did not finish
(it costs more). The ratios are SuperLU's time over PARDISO's, from this run.

Two smaller tables decide the ``auto`` rule and the note of the backends: the time to load MKL
(the first PARDISO use of a fresh process), and both backends' factor + solve times on small
models (rack-beams, rack-solid, the tet10 box; real shift), in one process after MKL is loaded,
best of 3.

``--superlu-matrices`` measures only SuperLU on three matrices of the 35,000-dof rack-solid (the
free body, the same without its interface node and dependent dofs, the prepared system), in a
section of its own: the free body's fill is twice the prepared system's. ``--small-complex``
measures only the small models with the complex shift, also in a section of its own.

Usage::

    .venv/bin/python bench/solvers.py --dofs 35000 150000
    .venv/bin/python bench/solvers.py --superlu-matrices
    .venv/bin/python bench/solvers.py --quick --no-results
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import _common as common
import numpy as np
import scipy.sparse as sp

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests" / "stress"))

FREQUENCY_HZ = 1000.0
LOSS_FACTOR = 0.02
RIGHT_HAND_SIDES = 20
STEEL_DENSITY = 7850.0  # kg/m^3
MODELS = ("hex20", "tet10")
SHIFTS = ("real", "complex")
BACKENDS = ("pardiso", "superlu")
SMALL = (
    "rack-beams",
    "hex20:7365",
    "hex20:10000",
    "hex20:20000",
    "tet10:2000",
    "tet10:5000",
    "tet10:10000",
    "tet10:20000",
)


# --------------------------------------------------------------------------- the models


def cache_path(model: str, dofs: int) -> Path:
    return common.CACHE / f"solvers-{model}-{dofs}.npz"


def build(model: str, dofs: int, source: str | None = None) -> dict:
    """Build (or, ``bracket``, read from ``source``) one model and cache its ``K`` and ``M``."""
    tick = time.perf_counter()
    if model == "bracket":
        import pymorembs

        body = pymorembs.read(source)
        stiffness, mass = body.stiffness, body.mass
    elif model == "hex20":
        prepared, _ = common.build_prepared("rack-solid", dofs)
        stiffness, mass = prepared.system.stiffness, prepared.system.mass
    else:
        from box_meshes import box_mesh, solid_body
        from stress_modes import SIZE, counts_for

        points, connectivity = box_mesh("tet10", counts_for(dofs), SIZE)
        body = solid_body("tet10", points, connectivity, 2.1e11, 0.3)
        stiffness = body.stiffness
        n = stiffness.shape[0]
        mass = sp.identity(n, format="csr") * (STEEL_DENSITY * float(np.prod(SIZE)) / (n / 3))
    stiffness, mass = sp.csr_matrix(stiffness), sp.csr_matrix(mass)
    common.CACHE.mkdir(exist_ok=True)
    np.savez(
        cache_path(model, dofs),
        **{f"k_{k}": v for k, v in _arrays(stiffness).items()},
        **{f"m_{k}": v for k, v in _arrays(mass).items()},
    )
    return {"n": stiffness.shape[0], "nnz": int(stiffness.nnz), "s": time.perf_counter() - tick}


def _arrays(matrix: sp.csr_matrix) -> dict[str, np.ndarray]:
    return {"data": matrix.data, "indices": matrix.indices, "indptr": matrix.indptr}


def load(model: str, dofs: int) -> tuple[sp.csr_matrix, sp.csr_matrix]:
    """The cached ``K`` and ``M`` of a model."""
    stored = np.load(cache_path(model, dofs))
    n = stored["k_indptr"].size - 1
    k, m = (
        sp.csr_matrix(
            (stored[f"{p}_data"], stored[f"{p}_indices"], stored[f"{p}_indptr"]), shape=(n, n)
        )
        for p in ("k", "m")
    )
    return k, m


def shifted(stiffness: sp.csr_matrix, mass: sp.csr_matrix, shift: str) -> sp.csr_matrix:
    """``A`` of the ``real`` or ``complex`` shift, canonical CSR."""
    sigma = (2.0 * np.pi * FREQUENCY_HZ) ** 2
    factor = 1.0 + 1j * LOSS_FACTOR if shift == "complex" else 1.0
    matrix = sp.csr_matrix(factor * stiffness - sigma * mass)
    matrix.sum_duplicates()
    matrix.sort_indices()
    return matrix


# --------------------------------------------------------------------------- measurements


def measure(model: str, dofs: int, backend: str, shift: str) -> dict:
    """Factorize ``A`` of one model and shift by one backend and solve 20 right-hand sides."""
    from pymorembs.linalg.backends import available_backends, factorize

    available_backends()  # loads MKL: not part of the factor time
    matrix = shifted(*load(model, dofs), shift)
    rng = np.random.default_rng(0)
    rhs = rng.standard_normal((matrix.shape[0], RIGHT_HAND_SIDES))
    base_mb = common.peak_memory_mb() if common.reset_peak_memory() else 0.0
    tick = time.perf_counter()
    factor = factorize(matrix, symmetric=True, backend=backend)
    factor_s = time.perf_counter() - tick
    tick = time.perf_counter()
    solution = factor.solve(rhs)
    solve_s = time.perf_counter() - tick
    peak_mb = common.peak_memory_mb() - base_mb
    residual = np.abs(matrix @ solution - rhs).max(axis=0)
    norm = np.abs(matrix).sum(axis=1).max()
    backward = residual / (norm * np.abs(solution).max(axis=0) + np.abs(rhs).max(axis=0))
    inertia = getattr(factor, "inertia", None)
    return {
        "n": matrix.shape[0],
        "nnz": int(matrix.nnz),
        "backend": factor.backend,
        "factor_s": factor_s,
        "solve_s": solve_s,
        "peak_mb": peak_mb,
        "nnz_factor": int(factor.nnz_factor),
        "backward_error": float(backward.max()),
        "negative": None if inertia is None or shift == "complex" else int(inertia[1]),
    }


def mkl_load() -> dict:
    """Seconds of the first PARDISO use in a fresh process (pypardiso finds and loads MKL)."""
    from pymorembs.linalg import backends

    tick = time.perf_counter()
    works = "pardiso" in backends.available_backends()
    return {"load_s": time.perf_counter() - tick, "works": works}


def small(name: str, shift: str = "real") -> dict:
    """Both backends on a small model, after MKL is loaded; best of 3 (of fewer when one takes
    more than 10 s).

    ``name``: ``rack-beams`` (prepared as the others) or ``MODEL:DOFS`` of :data:`MODELS`;
    ``shift``: ``real`` or ``complex``.
    """
    from pymorembs.linalg.backends import available_backends, factorize

    if name == "rack-beams":
        prepared, _ = common.build_prepared("rack-beams", None)
        stiffness, mass = prepared.system.stiffness, prepared.system.mass
    else:
        model, dofs = name.split(":")
        build(model, int(dofs))
        stiffness, mass = load(model, int(dofs))
        cache_path(model, int(dofs)).unlink()
    matrix = shifted(sp.csr_matrix(stiffness), sp.csr_matrix(mass), shift)
    rhs = np.random.default_rng(0).standard_normal((matrix.shape[0], RIGHT_HAND_SIDES))
    result: dict = {"model": name.split(":")[0], "n": matrix.shape[0], "nnz": int(matrix.nnz)}
    for backend in available_backends():
        best, spent = np.inf, 0.0
        for _ in range(3):
            tick = time.perf_counter()
            factorize(matrix, symmetric=True, backend=backend).solve(rhs)
            elapsed = time.perf_counter() - tick
            best, spent = min(best, elapsed), spent + elapsed
            if spent > 10.0:
                break
        result[backend] = best
    return result


def superlu_matrices() -> dict:
    """SuperLU (project settings) on three matrices of the 35,000-dof rack-solid at 500 Hz.

    The free body's ``K - sigma M`` (36,765 dofs), the same without the six dofs of node 2 (the
    interface node, joined to its hole by light stiff beams) and without the 1,080 dependent
    dofs of its constraint equations, and the prepared system of the benchmarks (tangent frame
    at node 2, constraints eliminated): wall and CPU seconds of the factorization, L + U.
    """
    import scipy.sparse.linalg as spla

    from pymorembs.examples import build_example
    from pymorembs.linalg.backends import SUPERLU_OPTIONS

    sigma = (2.0 * np.pi * 500.0) ** 2
    body = build_example("rack-solid", dofs=35000)
    free = sp.csc_matrix(body.stiffness - sigma * body.mass)
    hub = [body.dofs.index(2, d) for d in ("ux", "uy", "uz", "rx", "ry", "rz")]
    keep = np.setdiff1d(np.arange(free.shape[0]), [*body.constraints.dependent, *hub])
    prepared, _ = common.build_prepared("rack-solid", 35000)
    system = prepared.system
    matrices = {
        "free body": free,
        "free body without node 2 and the dependent dofs": sp.csc_matrix(free[keep][:, keep]),
        "prepared (the benchmarks' matrix)": sp.csc_matrix(system.stiffness - sigma * system.mass),
    }
    result = {}
    for name, matrix in matrices.items():
        wall, cpu = time.perf_counter(), time.process_time()
        lu = spla.splu(matrix, **SUPERLU_OPTIONS)
        result[name] = {
            "n": matrix.shape[0],
            "wall_s": time.perf_counter() - wall,
            "cpu_s": time.process_time() - cpu,
            "lu_nnz": int(lu.nnz),
        }
        del lu
    return result


# --------------------------------------------------------------------------- the report


def ratio(superlu: dict, pardiso: dict, key: str, limit: float) -> str:
    """SuperLU's time over PARDISO's (a lower bound when SuperLU did not finish)."""
    if key not in pardiso:
        return "–"
    if "failed" in superlu:
        return f"> {limit / pardiso[key]:.0f}" if key == "factor_s" else "–"
    return f"{superlu[key] / pardiso[key]:.1f}"


def table_rows(model: str, shift: str, results: dict[str, dict], limit: float) -> list[list]:
    """The table rows of one model and shift, PARDISO's with the ratios against SuperLU."""
    rows = []
    for backend, result in results.items():
        if "failed" in result:
            rows.append([model, f"{result['n']:,}", shift, backend, result["failed"]] + ["–"] * 5)
            continue
        negative = "" if result["negative"] is None else f", {result['negative']} neg. eig."
        ratios = ""
        if backend == "pardiso" and "superlu" in results:
            superlu = results["superlu"]
            ratios = " / ".join(
                ratio(superlu, result, key, limit) for key in ("factor_s", "solve_s")
            )
        rows.append(
            [
                model,
                f"{result['n']:,}",
                shift,
                backend if result["backend"] == backend else f"{backend} → {result['backend']}",
                common.fmt_s(result["factor_s"]),
                common.fmt_s(result["solve_s"]),
                f"{result['peak_mb']:.0f}",
                f"{result['nnz_factor'] / 1e6:.1f} M{negative}",
                f"{result['backward_error']:.1e}",
                ratios,
            ]
        )
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--dofs", type=int, nargs="+", default=[35000, 150000])
    parser.add_argument("--models", nargs="+", choices=MODELS, default=list(MODELS))
    parser.add_argument("--superlu-limit", type=float, default=200.0, help="seconds")
    parser.add_argument("--small", nargs="*", default=list(SMALL), help="rack-beams, MODEL:DOFS")
    parser.add_argument("--quick", action="store_true", help="tet10 at 5,000 dofs")
    parser.add_argument("--no-results", action="store_true")
    parser.add_argument(
        "--bracket",
        metavar="FILE",
        help="only a CalculiX export (its .sti; the matrices as pymorembs reads them), own section",
    )
    parser.add_argument(
        "--small-complex",
        action="store_true",
        help="only the small models with the complex shift (its own section)",
    )
    parser.add_argument(
        "--superlu-matrices",
        action="store_true",
        help="only SuperLU on the free and the prepared 35k rack-solid (its own section)",
    )
    parser.add_argument("--child", nargs="+", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.child:
        kind, *rest = args.child
        if kind == "build":
            common.emit(build(rest[0], int(rest[1]), *rest[2:]))
        elif kind == "measure":
            common.emit(measure(rest[0], int(rest[1]), rest[2], rest[3]))
        elif kind == "superlu-matrices":
            common.emit(superlu_matrices())
        elif kind == "load":
            common.emit(mkl_load())
        else:
            common.emit(small(*rest))
        return
    script = str(Path(__file__).resolve())
    if args.superlu_matrices:
        body = superlu_matrices_report(common.run_child([script, "--child", "superlu-matrices"]))
        publish("Sparse solvers: SuperLU on the 35k rack-solid", body, args.no_results)
        return
    if args.small_complex:
        runs = [common.run_child([script, "--child", "small", n, "complex"]) for n in args.small]
        body = small_table(runs, "complex")
        publish("Sparse solvers: small models, complex shift", body, args.no_results)
        return
    if args.bracket:
        from pymorembs.linalg.backends import available_backends

        backends = [b for b in BACKENDS if b in available_backends()]
        notes: list[str] = []
        rows = model_rows(script, "bracket", 0, backends, args.superlu_limit, notes, args.bracket)
        body = solver_table(rows, args.superlu_limit) + "".join(f"\n- {n}" for n in notes)
        publish("Sparse solvers: CalculiX bracket (tet10)", body, args.no_results)
        return
    if args.quick:
        args.dofs, args.models, args.small = [5000], ["tet10"], ["rack-beams", "tet10:2000"]
    from pymorembs.linalg.backends import available_backends

    backends = [b for b in BACKENDS if b in available_backends()]
    rows, notes = [], []
    for dofs in args.dofs:
        for model in args.models:
            rows += model_rows(script, model, dofs, backends, args.superlu_limit, notes)
    loads = [common.run_child([script, "--child", "load"]) for _ in range(3)]
    smalls = [common.run_child([script, "--child", "small", name]) for name in args.small]
    body = report(rows, loads, smalls, args.superlu_limit) + "".join(
        f"\n- {note}" for note in notes
    )
    publish("Sparse solvers", body, args.no_results)


def publish(section: str, body: str, no_results: bool) -> None:
    """Print a section and, unless ``no_results``, write it to ``bench/RESULTS.md``."""
    print(body)
    if not no_results:
        common.update_results(section, body, common.machine_facts())


def model_rows(
    script: str, model: str, dofs: int, backends: list, limit: float, notes: list, *source: str
) -> list[list]:
    """Build one model (``source``: the bracket's file) and measure every backend and shift in
    fresh processes; its table rows (failures of the build go to ``notes``)."""
    built = common.run_child([script, "--child", "build", model, str(dofs), *source])
    if "failed" in built:
        notes.append(f"{model} {dofs}: build {built['failed']}")
        return []
    print(f"{model} {dofs}: n {built['n']}, built in {built['s']:.1f} s", flush=True)
    rows: list[list] = []
    real: dict[str, dict] = {}
    for shift in SHIFTS:
        results: dict[str, dict] = {}
        for backend in backends:
            if backend == "superlu" and "failed" in real.get(backend, {}):
                skipped = "not run (the real shift did not finish)"
                results[backend] = {"failed": skipped, "n": built["n"]}
                continue
            child = [script, "--child", "measure", model, str(dofs), backend, shift]
            result = common.run_child(child, timeout=limit if backend == "superlu" else None)
            if result.get("failed", "").startswith("timeout"):
                result["failed"] = f"not finished in {limit:.0f} s"
            result.setdefault("n", built["n"])
            results[backend] = result
            print(f"  {shift} {backend}: {result}", flush=True)
        if shift == "real":
            real = results
        rows += table_rows(model, shift, results, limit)
    cache_path(model, dofs).unlink(missing_ok=True)
    return rows


def superlu_matrices_report(result: dict) -> str:
    """The paragraph of :func:`superlu_matrices`."""
    if "failed" in result:
        return f"SuperLU on the three 35k matrices: {result['failed']}"
    parts = [
        f"{name} (n = {r['n']:,}): {r['wall_s']:.2f} s wall, {r['cpu_s']:.2f} s CPU,"
        f" L + U {r['lu_nnz'] / 1e6:.1f} M"
        for name, r in result.items()
        if isinstance(r, dict)
    ]
    return (
        "SuperLU (project settings, one process) on three matrices of"
        " `build_example('rack-solid', dofs=35000)`, `K − σM` at 500 Hz: " + "; ".join(parts) + "."
    )


def small_table(smalls: list, shift: str) -> str:
    """The table of :func:`small` results (one shift)."""
    rows = []
    for r in smalls:
        if "failed" in r:
            rows.append([r["failed"], "", "", "", "", ""])
            continue
        times = [common.fmt_s(r.get(b, float("nan"))) for b in ("superlu", "pardiso")]
        share = r["superlu"] / r["pardiso"] if "pardiso" in r else float("nan")
        rows.append([r["model"], f"{r['n']:,}", f"{r['nnz'] / 1e6:.2f} M", *times, f"{share:.2f}"])
    headers = ["model", "n", "nnz(A)", "SuperLU", "PARDISO", "SuperLU / PARDISO"]
    return (
        f"Small models ({shift} shift, factor + solve ×{RIGHT_HAND_SIDES}, MKL loaded,"
        " best of 3, fewer past 10 s; s):\n\n" + common.markdown_table(headers, rows)
    )


def report(rows: list, loads: list, smalls: list, limit: float) -> str:
    """The section of the default run: the models, the loading of MKL, the small models."""
    text = solver_table(rows, limit)
    ok = [r for r in loads if "failed" not in r]
    if ok:
        text += (
            "\n\nLoading MKL: the first PARDISO use of a fresh process (pypardiso finds and"
            " loads `mkl_rt`, a 3×3 test factorization), 3 processes: "
            + ", ".join(f"{r['load_s']:.2f}" for r in ok)
            + " s."
        )
    return text + "\n\n" + small_table(smalls, "real")


def solver_table(rows: list, limit: float) -> str:
    """The table of :func:`table_rows` with its explanation."""
    headers = [
        "model",
        "n",
        "shift",
        "backend",
        "factor s",
        f"solve ×{RIGHT_HAND_SIDES} s",
        "peak MB",
        "factor nnz",
        "backward error",
        "SuperLU / PARDISO (factor / solve)",
    ]
    text = common.markdown_table(headers, rows)
    text += (
        f"\n\nShifts at {FREQUENCY_HZ:.0f} Hz: real `K − σM`,"
        f" complex `(1 + {LOSS_FACTOR} i) K − σM`."
        f" SuperLU time limit {limit:.0f} s. Peak MB: the process's peak RSS above the loaded"
        " model (factorization and solve). `→ superlu`: PARDISO perturbed pivots and the backend"
        " fell back to SuperLU."
    )
    return text


if __name__ == "__main__":
    main()
