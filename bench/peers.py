"""Peers: pyMOR, SciPy and pymorembs reductions of the same model over the same band.

On ``rack-solid`` (frame at node 2, inputs and outputs ``1: ux uy uz``, Rayleigh damping
``D = 2e-6 s * K`` -- pyMOR's ``SecondOrderModel`` needs a damping matrix), band 0-1000 Hz:

* pyMOR ``SOBTpReductor`` (second-order balanced truncation, position Gramians), r = 35;
* pyMOR ``SOBHIReductor`` (bitangential Hermite interpolation at 0 Hz and 17 conjugate pairs
  ``±i 2 pi f`` equidistant over the band, fixed random tangent directions), r = 35;
* SciPy ``eigsh`` modal: 40 modes by shift-invert about -(2 pi 1 Hz)^2, Galerkin projection;
* pymorembs: ``modal-40``, ``krylov`` (0, 500, 1000 Hz; 6, 5, 5 moments), ``soaga`` (tolerance
  1e-6), ``gramian`` (two-step, order 35), ``pod`` (order 35, 40 snapshots).

For each: wall time of the reduction, peak memory of its process (each method runs in a fresh
process; the peak is reset after building the model where Linux allows), and the largest
relative error eps (paper eq. 27) over the error grid of the band. The full model's response on
that grid is computed once and cached in ``bench/.cache/``.

Usage::

    .venv/bin/python bench/peers.py --dofs 10000          # SOBTp alone takes ~15 min
    .venv/bin/python bench/peers.py --quick               # rack-beams, 3,996 dofs
"""

from __future__ import annotations

import argparse
import hashlib
import sys
import time
from pathlib import Path

import numpy as np
from _common import (
    BAND_HZ,
    CACHE,
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

ORDER = 35
MODES = 40
#: Method name -> (library, what it is).
METHODS = {
    "pymor-sobtp": ("pyMOR", f"SOBTpReductor, r = {ORDER}"),
    "pymor-sobhi": ("pyMOR", f"SOBHIReductor, r = {ORDER}"),
    "scipy-eigsh": ("SciPy", f"eigsh shift-invert, {MODES} modes"),
    "modal-40": ("pymorembs", f"modal, {MODES} modes"),
    "krylov": ("pymorembs", "krylov 0/500/1000 Hz, 6/5/5 moments"),
    "soaga": ("pymorembs", "soaga, tolerance 1e-6"),
    "gramian": ("pymorembs", f"gramian two-step, order {ORDER}"),
    "pod": ("pymorembs", f"pod, order {ORDER}, 40 snapshots"),
}
BASELINE = "pymor-sobtp"
OURS = "gramian"


def _residual_kind() -> bytes:
    """How refined solves compute residuals here (part of the cache key)."""
    try:
        from pymorembs.linalg import double_double
    except ImportError:  # an older pymorembs
        return b"longdouble"
    return b"double-double" if double_double.available() else b"longdouble"


def full_response(example: str, dofs: int | None, points: int) -> Path:
    """The cache file with the full model's response on the error grid (computed if missing).

    The file name holds the model, its number of dofs, damping, band, grid size and a hash of
    the matrices and of the kind of residual the refined solves use, so a changed model is never
    compared with an old response. (Responses refined with ``longdouble`` residuals differ from
    the double-double ones by up to 4.4e-11 at rack-solid's 42 Hz resonance, where PARDISO and
    SuperLU refined with double-double agree to 5e-20.)
    """
    from pymorembs.analysis.transfer import transfer_function
    from pymorembs.frequencies import frequency_grid

    prepared, _ = build_prepared(example, dofs, "rayleigh")
    system = prepared.system
    fingerprint = hashlib.sha1(
        b"".join(
            np.ascontiguousarray(a).tobytes()
            for a in (system.stiffness.data, system.mass.data, system.input_matrix)
        )
        + _residual_kind()
    ).hexdigest()[:10]
    band = f"{BAND_HZ[0]:g}-{BAND_HZ[1]:g}Hz"
    path = CACHE / f"{example}-{system.order}-rayleigh-{band}-{points}-{fingerprint}.npz"
    if path.exists():
        return path
    frequencies = frequency_grid(*BAND_HZ, points)
    print(f"full response at {frequencies.size} frequencies (cached in {path}) ...", flush=True)
    tick = time.perf_counter()
    response = transfer_function(system, frequencies)
    CACHE.mkdir(exist_ok=True)
    tmp = path.with_suffix(".tmp.npz")
    np.savez(
        tmp,
        frequencies=frequencies,
        response=response,
        n=system.order,
        seconds=time.perf_counter() - tick,
    )
    tmp.replace(path)
    return path


def reduce(method: str, system) -> tuple[object, dict]:
    """Run ``method`` on the full ``system``; the reduced system and facts about the method."""
    if method.startswith("pymor-"):
        return _pymor(method, system)
    if method == "scipy-eigsh":
        import scipy.sparse.linalg as spla

        sigma = -((2 * np.pi * 1.0) ** 2)
        _, modes = spla.eigsh(system.stiffness, k=MODES, M=system.mass, sigma=sigma)
        return system.project(modes), {}
    from pymorembs.job.run import run_reduction
    from pymorembs.job.schema import ReductionSpec
    from pymorembs.methods import method_options
    from pymorembs.reduction.projection import reduced_model

    options = {
        "modal-40": ("modal", {"order": MODES}),
        "krylov": ("krylov", {"expansion_points_hz": [0, 500, 1000], "moments": [6, 5, 5]}),
        "soaga": ("soaga", {"tolerance": 1e-6}),
        "gramian": ("gramian", {"order": ORDER}),
        "pod": ("pod", {"order": ORDER, "snapshots": 40}),
    }
    spec = ReductionSpec(method, method_options(*options[method]))
    projection = run_reduction(system, spec, BAND_HZ)
    capped = projection.parameters.get("order_capped_by_first_stage")
    facts = {"note": f"capped at {capped} by its first stage"} if capped else {}
    return reduced_model(system, projection).system, facts


def _pymor(method: str, system) -> tuple[object, dict]:
    """pyMOR's reductor on ``to_pymor(system)``; the reduced model as a dense system."""
    from pymor.algorithms.to_matrix import to_matrix
    from pymor.core.logger import set_log_levels
    from pymor.reductors.interpolation import SOBHIReductor
    from pymor.reductors.sobt import SOBTpReductor

    from pymorembs.export.matrices import to_pymor
    from pymorembs.system import SecondOrderSystem

    set_log_levels({"pymor": "WARNING"})
    fom = to_pymor(system)
    if method == "pymor-sobtp":
        rom = SOBTpReductor(fom).reduce(ORDER)
    else:
        pairs = (ORDER - 1) // 2
        freqs = np.linspace(BAND_HZ[1] / pairs, BAND_HZ[1], pairs)
        sigma = np.concatenate([[0.0], 2j * np.pi * freqs, -2j * np.pi * freqs])
        rng = np.random.default_rng(0)
        half = (
            rng.standard_normal((pairs, fom.dim_input)),
            rng.standard_normal((pairs, fom.dim_output)),
        )
        first = rng.standard_normal((1, fom.dim_input)), rng.standard_normal((1, fom.dim_output))
        b = np.vstack([first[0], half[0], half[0]])
        c = np.vstack([first[1], half[1], half[1]])
        rom = SOBHIReductor(fom).reduce(sigma, b, c)

    def dense(operator):
        return np.asarray(to_matrix(operator, format="dense"))

    reduced = SecondOrderSystem(
        mass=dense(rom.M),
        stiffness=dense(rom.K),
        damping=dense(rom.E),
        input_matrix=dense(rom.B),
        output_matrix=dense(rom.Cp),
    )
    return reduced, {}


def child(method: str, example: str, dofs: int | None, cache: Path) -> dict:
    """Build the model, reduce it with ``method`` and measure (runs in its own process)."""
    from pymorembs.analysis.error import relative_error
    from pymorembs.analysis.transfer import transfer_function

    prepared, _ = build_prepared(example, dofs, "rayleigh")
    reset = reset_peak_memory()
    tick = time.perf_counter()
    reduced, facts = reduce(method, prepared.system)
    seconds = time.perf_counter() - tick
    peak = peak_memory_mb()
    data = np.load(cache)
    eps = relative_error(data["response"], transfer_function(reduced, data["frequencies"]))
    return {
        "method": method,
        "n": prepared.system.order,
        "order": reduced.order,
        "seconds": seconds,
        "peak_mb": peak,
        "peak_is_method_only": reset,
        "max_eps": float(np.max(eps)),
        **facts,
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--dofs", type=int, default=10000, help="rack-solid size (default 10k)")
    parser.add_argument("--quick", action="store_true", help="rack-beams (3,996 dofs) instead")
    parser.add_argument("--methods", nargs="+", choices=list(METHODS), default=list(METHODS))
    parser.add_argument("--points", type=int, default=200, help="error grid (+ 0 Hz)")
    parser.add_argument("--timeout", type=float, default=7200, help="per method, seconds")
    parser.add_argument("--no-results", action="store_true", help="do not write RESULTS.md")
    parser.add_argument("--child", metavar="METHOD", help=argparse.SUPPRESS)
    parser.add_argument("--cache", type=Path, help=argparse.SUPPRESS)
    args = parser.parse_args()

    example, dofs = ("rack-beams", None) if args.quick else ("rack-solid", args.dofs)
    if args.child:
        emit(child(args.child, example, dofs, args.cache))
        return

    cache = full_response(example, dofs, args.points)
    cached = np.load(cache)
    results = {}
    for method in args.methods:
        print(f"{method} ...", flush=True)
        argv = [__file__, "--child", method, "--cache", str(cache)]
        argv += ["--quick"] if args.quick else ["--dofs", str(dofs)]
        results[method] = r = run_child(argv, timeout=args.timeout)
        print("  " + (r.get("failed") or f"{fmt_s(r['seconds'])} s, max eps {r['max_eps']:.1e}"))

    base = results.get(BASELINE, {}).get("seconds")
    rows = []
    for method, r in results.items():
        library, what = METHODS[method]
        if "failed" in r:
            rows.append([library, method, what, "", r["failed"], "", "", ""])
            continue
        speedup = f"{base / r['seconds']:.0f}×" if base else "–"
        rows.append(
            [
                library,
                method,
                what + (f" ({r['note']})" if "note" in r else ""),
                r["order"],
                fmt_s(r["seconds"]),
                f"{r['peak_mb']:.0f}",
                f"{r['max_eps']:.1e}",
                speedup,
            ]
        )
    headers = ["library", "name", "method", "order", "time [s]", "peak RSS [MB]", "max ε"]
    headers.append(f"speed-up vs {BASELINE}")
    table = markdown_table(headers, rows)
    print(table)
    ours = results.get(OURS, {})
    summary = ""
    if base and "seconds" in ours:
        baseline = results[BASELINE]
        summary = (
            f"Our Gramian two-step ({ours['max_eps']:.1e}) vs SOBTp ({baseline['max_eps']:.1e}): "
            f"**{base / ours['seconds']:.0f}× faster** (target ≥ 100× at equal or better "
            "accuracy)."
        )
        print(summary)
    if not args.no_results:
        n = int(cached["n"])
        body = (
            f"Model: {example} ({n} independent dofs), frame at node 2, ports `1: ux uy uz`, "
            "Rayleigh damping D = 2e-6 s · K, band 0–1000 Hz; max ε (eq. 27) over "
            f"{cached['frequencies'].size} frequencies (full response: "
            f"{float(cached['seconds']):.0f} s, cached). Each method in a fresh process; peak "
            "RSS measured from after the model build (Linux `clear_refs`).\n\n"
            f"{table}\n\n{summary}"
        )
        name = "quick" if args.quick else f"{dofs} dofs"
        path = update_results(f"Peers ({name})", body, machine_facts())
        print(f"written: {path}")
    sys.exit(1 if any("failed" in r for r in results.values()) else 0)


if __name__ == "__main__":
    main()
