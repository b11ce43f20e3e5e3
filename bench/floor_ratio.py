"""Floor ratio: how close a Krylov/SOAGA reduction comes to the cost of its factorizations.

    ratio = wall time of the reduction / sum over its factorizations of the time of ONE
            standalone factorization of the very matrix it factorized (real K - sigma M, or
            the complex dynamic stiffness), by the fastest available backend, measured in the
            same run after the reduction.

Every matrix the reduction factorized is factorized again standalone (the counter keeps their
terms): the first of each kind by every backend, which picks the fastest, every further one by
that backend. (Until December 2026 the unit was the first matrix alone, times the count: for
Krylov that is ``K`` at 0 Hz, positive definite, while the reduction also factorizes the
indefinite ``K - sigma M`` at 500 and 1000 Hz.)

Two models, each at every size: ``rack-solid`` (hex20; frame at node 2, inputs and outputs
``1: ux uy uz``, band 0-1000 Hz, 1 % modal damping as in ``examples/rack-solid-compare.toml``)
and ``tet10-box`` (the tet10 steel box of ``stress_modes.py`` with a consistent mass, rigid
interfaces on its end faces: ``_tet10_box.py``). The factorizations of the reduction are counted
by wrapping ``Factorization.__init__``. Each model, size and method runs in a fresh process.
Target (issue #30 item 4): ratio <= 1.2 at 35k and <= 1.1 at 300k dofs.

``--profile`` also profiles the measured reduction (cProfile) and prints where the time outside
the factorizations goes, by phase (``PHASES``).

Usage::

    .venv/bin/python bench/floor_ratio.py --dofs 35000 300000 [--method krylov soaga]
        [--model rack-solid tet10-box] [--profile]
    .venv/bin/python bench/floor_ratio.py --quick      # rack-beams, 3,996 dofs, seconds
"""

from __future__ import annotations

import argparse
import cProfile
import pstats
import sys
import time
from pathlib import Path

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

#: Targets of issue #30 item 4: up to this many dofs ``TARGETS[0]``, above ``TARGETS[1]``.
TARGETS = ((100_000, 1.2), (None, 1.1))
MODELS = ("rack-solid", "tet10-box")

#: Phases of a reduction for ``--profile``: name -> (function, its caller or None), where a
#: function is (file name, function name); the time of a phase is the cumulative time of its
#: functions (called from that caller), minus that of the phases listed under ``"minus"``.
PHASES = {
    "factorizations (PARDISO analysis and numeric phase)": {
        "plus": [(("backends.py", "factorize"), ("factorization.py", "__init__"))],
        "minus": [(("backends.py", "_upper_triangle"), None)],
    },
    "shifted matrices (combine, symmetry, norms, upper triangle)": {
        "plus": [(("factorization.py", "__init__"), None)],
        "minus": [(("backends.py", "factorize"), ("factorization.py", "__init__"))],
        "add": [(("backends.py", "_upper_triangle"), None)],
    },
    "solves (forward/backward substitution)": {"plus": [(("backends.py", "solve"), None)]},
    "refinement residuals and backward checks": {
        "plus": [(("factorization.py", "solve"), None)],
        "minus": [(("backends.py", "solve"), ("factorization.py", "solve"))],
    },
    "products with M, D, K for the moments": {
        "plus": [
            (("products.py", "multiply"), ("krylov.py", "next_block")),
            (("products.py", "multiply"), ("soaga.py", "next_parts")),
            (("krylov.py", "_frequency_scale"), None),
        ],
    },
    "orthogonalization (bases, Frobenius blocks, look-ahead complement)": {
        "plus": [
            (("orthogonalization.py", "add"), None),
            (("soaga.py", "add"), None),
            (("soaga.py", "_complement"), None),
        ],
    },
    "SOAGA: extended products K V, M V, D V": {"plus": [(("soaga.py", "update"), None)]},
    "SOAGA: error estimator": {"plus": [(("soaga.py", "_estimate"), None)]},
    "SOAGA: mass orthonormalisation": {"plus": [(("soaga.py", "_mass_orthonormal"), None)]},
}


def measure(
    example: str,
    dofs: int | None,
    method: str,
    damping: str,
    floor: bool,
    repeat: int = 1,
    superlu_max: int = 100_000,
    profile: bool = False,
) -> dict:
    """Build, prepare and reduce one model in this process; the measurements.

    Parameters
    ----------
    example, dofs, damping
        The model: ``"rack-solid"`` or ``"rack-beams"`` (``_common.build_prepared``), or
        ``"tet10-box"`` (``_tet10_box.tet10_box_prepared``).
    method : {"krylov", "soaga"}
    floor : bool
        Also time one factorization of each kind of matrix by every available backend.
    repeat : int
        Best of this many timings per backend.
    superlu_max : int
        SuperLU is timed only up to this many dofs (if another backend is available).
    profile : bool
        Profile the reduction (cProfile) and return its time by phase (``phases``).

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
    if example == "tet10-box":
        from _tet10_box import tet10_box_prepared

        prepared, build_s = tet10_box_prepared(dofs, damping)
    else:
        prepared, build_s = build_prepared(example, dofs, damping)
    system = prepared.system
    spec = krylov_or_soaga_spec(method)
    peak_before = peak_memory_mb()
    reset = reset_peak_memory()
    # BLAS on one thread, as the command line runs it (PARDISO keeps its own threads)
    profiler = cProfile.Profile() if profile else None
    with FactorizationCounter() as counter, threadpool_limits(limits=1, user_api="blas"):
        tick = time.perf_counter()
        if profiler is not None:
            profiler.enable()
        projection = run_reduction(system, spec, BAND_HZ)
        if profiler is not None:
            profiler.disable()
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
        "factorization_calls_s": [seconds for _, seconds in counter.calls],
        "reported_factorizations": projection.parameters.get("factorizations"),
        # why SOAGA opened the points it did (None for Krylov)
        "expansion_points_hz": projection.parameters.get("expansion_points_hz"),
        "stop": projection.parameters.get("stop"),
        "memory_limited": projection.parameters.get("memory_limited"),
        "reduction_peak_mb": peak_memory_mb() if reset else None,
        "peak_mb": max(peak_before, peak_memory_mb()),
    }
    if profiler is not None:
        result["phases"] = phase_times(pstats.Stats(profiler), reduction_s)
    if floor:
        floor_s = 0.0
        reference = {  # the kind the run did not factorize, for the record (not in the floor)
            "real": [(1.0, system.stiffness), (-((2 * np.pi * 500.0) ** 2), system.mass)],
            "complex": _complex_dynamic_stiffness(system, 500.0),
        }
        for kind in ("real", "complex"):
            factorized = counter.terms.get(kind, [])
            limit = superlu_max if factorized else 0  # no slow SuperLU for the record
            first = factorized[0] if factorized else reference[kind]
            times = time_backends(assemble(first), repeat, limit)
            name, seconds = fastest(times)
            result[f"{kind}_backends"] = times
            result[f"{kind}_fastest"] = [name, seconds]
            # every further matrix the reduction factorized, again, by that backend
            units = [seconds] if factorized else []
            for terms in factorized[1:]:
                again = time_backends(assemble(terms), repeat, limit, only=name)[name]
                units.append(again if isinstance(again, float) else float("nan"))
            result[f"{kind}_units"] = units
            floor_s += sum(units)
        result["floor_s"] = floor_s
        result["ratio"] = reduction_s / floor_s if floor_s > 0 else None  # None: nothing timed
    return result


def phase_times(stats: pstats.Stats, total_s: float) -> dict[str, float]:
    """Seconds of each of :data:`PHASES` in a profile of one reduction, and the rest."""
    table = stats.stats  # (file, line, name) -> (calls, primitive, tottime, cumtime, callers)

    def matches(key: tuple, what: tuple[str, str]) -> bool:
        return Path(key[0]).name == what[0] and key[2] == what[1]

    def seconds(function: tuple[str, str], caller: tuple[str, str] | None) -> float:
        total = 0.0
        for key, (_, _, _, cumulative, callers) in table.items():
            if not matches(key, function):
                continue
            if caller is None:
                total += cumulative
            else:
                total += sum(v[3] for k, v in callers.items() if matches(k, caller))
        return total

    phases = {}
    for name, parts in PHASES.items():
        value = sum(seconds(*p) for p in parts["plus"] + parts.get("add", []))
        phases[name] = value - sum(seconds(*p) for p in parts.get("minus", []))
    phases["rest"] = total_s - sum(phases.values())
    return phases


def target_for(dofs: int) -> float:
    """The target ratio at this size (:data:`TARGETS`)."""
    for limit, target in TARGETS:
        if limit is None or dofs <= limit:
            return target
    raise AssertionError("TARGETS ends with None")


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
    parser.add_argument("--dofs", type=int, nargs="+", default=[35000], help="model sizes")
    parser.add_argument(
        "--method", choices=("krylov", "soaga"), nargs="+", default=["krylov", "soaga"]
    )
    parser.add_argument("--model", choices=MODELS, nargs="+", default=list(MODELS))
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
    parser.add_argument("--profile", action="store_true", help="time by phase (cProfile)")
    parser.add_argument("--no-results", action="store_true", help="do not write RESULTS.md")
    parser.add_argument("--child", action="store_true", help=argparse.SUPPRESS)
    args = parser.parse_args()

    models = ["rack-beams"] if args.quick else args.model
    sizes = [None] if args.quick else args.dofs
    if args.child:
        r = measure(models[0], sizes[0], args.method[0], args.damping, True, args.repeat,
                    args.superlu_max_dofs, args.profile)  # fmt: skip
        emit(r)
        return

    rows, profiles, failed = [], [], False
    for model in models:
        for dofs in sizes:
            for method in args.method:
                argv = [__file__, "--child", "--method", method, "--damping", args.damping]
                argv += ["--repeat", str(args.repeat)]
                argv += ["--superlu-max-dofs", str(args.superlu_max_dofs)]
                argv += ["--quick"] if args.quick else ["--model", model, "--dofs", str(dofs)]
                argv += ["--profile"] if args.profile else []
                print(f"{model}{f' {dofs}' if dofs else ''}: {method} reduction ...", flush=True)
                r = run_child(argv)
                if "failed" in r:
                    failed = True
                    rows.append([model, dofs or "", method, r["failed"], *[""] * 8])
                    continue
                rows.append(_row(model, method, r))
                if "phases" in r:
                    profiles.append((f"{model} {r['n']} {method}", r))
    headers = [
        "model",
        "dofs (independent)",
        "method",
        "order",
        "reduction [s]",
        "factorizations real / complex",
        "of which in Factorization [s] (each)",
        "standalone factorization of each factorized matrix, fastest backend",
        "floor = sum of the standalone ones [s]",
        "ratio",
        "target",
        "peak RSS [MB]",
    ]
    table = markdown_table(headers, rows)
    print(table)
    body = (
        f"Wall time of a Krylov and a SOAGA reduction ({args.damping} damping, band 0–1000 Hz) "
        "÷ (sum over its factorizations of one standalone factorization of the very matrix "
        "it factorized, ordering included, by the fastest available backend, same run: the "
        "first matrix of each kind by every backend, the others by the fastest of those). "
        "rack-solid: hex20, frame at node 2, ports `1: ux uy uz`; tet10-box: the tet10 steel "
        "box with a consistent mass, rigid interfaces on its end faces (frame at one, ports "
        "`ux uy uz` at the other; `bench/_tet10_box.py`). Krylov: points 0, 500, 1000 Hz, "
        "moments 6, 5, 5; SOAGA: tolerance 1e-6. Target (issue #30): ≤ 1.2 up to 100k dofs, "
        "≤ 1.1 above.\n\n" + table
    )
    if profiles:
        phase_table = _phase_table(profiles)
        print(phase_table)
        body += (
            "\n\nWhere the time goes (`--profile`: cProfile of the measured reduction; "
            "seconds by phase, `bench/floor_ratio.py` PHASES):\n\n" + phase_table
        )
    if not args.no_results:
        name = f"{args.damping} damping" + (", quick" if args.quick else "")
        path = update_results(f"Floor ratio ({name})", body, machine_facts())
        print(f"written: {path}")
    sys.exit(1 if failed else 0)


def _row(model: str, method: str, r: dict) -> list:
    """One row of the results table from a child's result ``r`` (and its lines on stdout)."""
    reported = r.get("reported_factorizations")
    if reported is not None and reported != r["n_real"] + r["n_complex"]:
        print(
            f"  warning: the method reports {reported} factorizations, the counter saw "
            f"{r['n_real'] + r['n_complex']} (factorizations in other processes?)"
        )
    fast = {k: r.get(f"{k}_fastest") for k in ("real", "complex")}
    one = "<br>".join(
        f"{k} ×{r['n_' + k]}: {_units(r.get(f'{k}_units') or [v[1]])} s ({v[0]})"
        for k, v in fast.items()
        if v
    )
    ratio, target = r["ratio"], target_for(r["n"])
    if ratio:
        met = "met" if ratio <= target else "NOT met"
        print(f"  ratio {ratio:.2f} (target <= {target}: {met})")
    else:
        print("  no factorization")
    if r.get("stop") is not None:
        points = ", ".join(f"{f:g}" for f in r.get("expansion_points_hz") or [])
        print(f"  stop: {r['stop']}; memory limited: {r['memory_limited']}; points [Hz]: {points}")
    return [
        model,
        r["n"],
        method,
        r["order"],
        fmt_s(r["reduction_s"]),
        f"{r['n_real']} / {r['n_complex']}",
        f"{fmt_s(r['factorization_s'])} ({_units(r.get('factorization_calls_s', []))})",
        one,
        fmt_s(r["floor_s"]),
        f"**{ratio:.2f}**" if ratio is not None else "n/a",
        f"≤ {target}",
        f"{r['peak_mb']:.0f}",
    ]


def _units(units: list[float]) -> str:
    """The standalone times of the factorized matrices, ``a + b + c`` (s)."""
    return " + ".join(fmt_s(u) for u in units)


def _phase_table(profiles: list[tuple[str, dict]]) -> str:
    """Seconds by phase (rows) of every profiled run (columns), with the floor for scale."""
    headers = ["phase", *[name for name, _ in profiles]]
    rows = [[phase, *[fmt_s(r["phases"][phase]) for _, r in profiles]] for phase in PHASES]
    rows.append(
        ["rest (Python, copies, progress)", *[fmt_s(r["phases"]["rest"]) for _, r in profiles]]
    )
    rows.append(["**reduction**", *[f"**{fmt_s(r['reduction_s'])}**" for _, r in profiles]])
    rows.append(["floor", *[fmt_s(r["floor_s"]) for _, r in profiles]])
    return markdown_table(headers, rows)


if __name__ == "__main__":
    main()
