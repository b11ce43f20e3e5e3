"""Job cost: the whole job (read, validate, error reference, reductions with their errors
against the full model, SID and Exudyn files) against the sum of its reductions.

    ratio = wall time of the whole job (``run_job``)
            / sum of the wall times of its reductions, each run alone on the prepared model
              (``pymorembs.reduce``, no shared factors) in the same process after the job

The job: tangent frame at one interface node, six ports (``ux .. rz``) at another, the default
inertia loads, 0-1000 Hz, 2 % modal damping, reductions Krylov (0/500/1000 Hz, two moments
each), SOAGA (tolerance 1e-6) and Craig-Bampton (30 fixed modes), outputs SID and Exudyn. The
models:

* ``rack-solid``: ``build_example('rack-solid', dofs=N, interface='rigid')`` (hex20), frame at
  its interface node 2, ports at a rigid interface node on the bottom face around node 1;
* ``bracket``: the CalculiX export made by ``bench/calculix_peer.py`` (tet10, about 283k
  dofs; read from its text files; another folder: ``BENCH_BRACKET``), free-free, rigid
  interfaces at its two pin holes (frame at hole B, ports at hole A).

Per stage: wall time (exclusive of the stages inside it), the factorizations made and their
time, and those served from the job's shared factors (``Factorization.reused``); the
factorizations are counted by wrapping ``Factorization.__init__`` as ``bench/floor_ratio.py``
does, plus the direct ``factorize`` calls of the model checks. ``--before`` runs the job as it
ran before the job-level sharing (no shared factors, the reference's own candidates, every
check a direct complex factorization) for comparison; ``--checks direct|iterative`` forces how
the reference's checks at f > 0 are computed (complex factorizations, or from the real factors
the job holds; default: the package's choice by size). Each run is a fresh process. On the
2-core VM of RESULTS.md freed memory goes back to the host within seconds and its next first
touch is slow (13 against 0.5 us per page, ``bench/floor_ratio.py``): the job, which allocates
first, pays more of it than the reductions alone after it. Target (issue #30, item 3): ratio
<= 2.

Usage::

    .venv/bin/python bench/job_cost.py --model rack-solid --dofs 35000 [--before]
    .venv/bin/python bench/job_cost.py --model bracket          # under flock /work/locks/big
    .venv/bin/python bench/job_cost.py --quick                  # rack-solid 6,000 dofs
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
from pathlib import Path

from _common import (
    emit,
    fmt_s,
    is_complex,
    machine_facts,
    markdown_table,
    peak_memory_mb,
    run_child,
    update_results,
)
from threadpoolctl import threadpool_limits

TARGET = 2.0
#: The bracket made and exported by ``bench/calculix_peer.py`` (its default size), or the folder
#: named by the environment variable ``BENCH_BRACKET``.
BRACKET = Path(
    os.environ.get("BENCH_BRACKET", Path(__file__).resolve().parent / ".cache/calculix-peer-283000")
)

REDUCTIONS = """
[[reduction]]
name = "krylov"
method = "krylov"
expansion_points_hz = [0, 500, 1000]
moments = [2, 2, 2]
export_inaccurate = true

[[reduction]]
name = "soaga"
method = "soaga"
tolerance = 1e-6
export_inaccurate = true

[[reduction]]
name = "craig-bampton"
method = "craig-bampton"
fixed_modes = 30
export_inaccurate = true

[damping]
kind = "modal"
ratio = 0.02

[band]
f_min_hz = 0
f_max_hz = 1000

[export]
outputs = ["sid", "exudyn"]
"""


def job_text(model: str, dofs: int | None) -> str:
    """The job file of one model (see the module docstring)."""
    if model == "rack-solid":
        head = f"""
[model]
example = "rack-solid"
dofs = {dofs}
interface = "rigid"

[[interface]]
node = 900001
position = [0.0, 0.0, -0.004]
kind = "rigid"
box = {{ min = [-0.03, -0.03, -0.0045], max = [0.03, 0.03, -0.0035] }}

[frame]
type = "tangent"
node = 2

[[inputs]]
node = 900001
directions = "ux uy uz rx ry rz"
"""
    else:
        head = f"""
[model]
file = "{BRACKET / "bracket.sti"}"

[[interface]]
node = 1000001
position = [0.090, 0.030, 0.005]
kind = "rigid"

[interface.cylinder]
point = [0.090, 0.030, 0.0]
direction = [0, 0, 1]
radius = 0.008
tolerance = 1e-6

[[interface]]
node = 1000002
position = [0.005, 0.030, 0.070]
kind = "rigid"

[interface.cylinder]
point = [0.0, 0.030, 0.070]
direction = [1, 0, 0]
radius = 0.008
tolerance = 1e-6

[frame]
type = "tangent"
node = 1000002

[[inputs]]
node = 1000001
directions = "ux uy uz rx ry rz"
"""
    return f'title = "job cost: {model}"\n' + head + REDUCTIONS


class StageClock:
    """Exclusive wall time and factorizations per stage, the stages marked by wrapping the
    job's functions; a stage inside another is subtracted from it."""

    def __init__(self) -> None:
        self.seconds: dict[str, float] = {}
        self.factorizations: dict[str, list[tuple[str, float, bool]]] = {}
        self._stack: list[list] = []  # [name, start, time of inner stages]
        self._patches: list[tuple[object, str, object]] = []

    def current(self) -> str:
        return self._stack[-1][0] if self._stack else "other"

    def wrap(self, owner: object, attribute: str, name) -> None:
        """Count the calls of ``owner.attribute`` as stage ``name`` (str, or a function of the
        call's arguments)."""
        original = getattr(owner, attribute)
        clock = self

        def timed(*args, **kwargs):
            label = name if isinstance(name, str) else name(*args, **kwargs)
            clock._stack.append([label, time.perf_counter(), 0.0])
            try:
                return original(*args, **kwargs)
            finally:
                label, start, inner = clock._stack.pop()
                spent = time.perf_counter() - start
                clock.seconds[label] = clock.seconds.get(label, 0.0) + spent - inner
                if clock._stack:
                    clock._stack[-1][2] += spent

        setattr(owner, attribute, timed)
        self._patches.append((owner, attribute, original))

    def count_factorizations(self) -> None:
        """Record every ``Factorization`` (kind, seconds, reused) and direct ``factorize``."""
        import pymorembs.linalg.backends as backends  # the model checks import it when run
        from pymorembs.linalg import factorization

        cls = factorization.Factorization
        original = cls.__init__
        clock = self

        def counted(instance, *args, **kwargs):
            terms = args[0] if args else kwargs.get("terms")
            tick = time.perf_counter()
            original(instance, *args, **kwargs)
            kind = "complex" if is_complex(terms) else "real"
            record = (kind, time.perf_counter() - tick, bool(getattr(instance, "reused", False)))
            clock.factorizations.setdefault(clock.current(), []).append(record)

        cls.__init__ = counted
        self._patches.append((cls, "__init__", original))
        direct = backends.factorize

        def factorize(matrix, *args, **kwargs):
            tick = time.perf_counter()
            factor = direct(matrix, *args, **kwargs)
            kind = "complex" if matrix.dtype.kind == "c" else "real"
            record = (kind, time.perf_counter() - tick, False)
            clock.factorizations.setdefault(clock.current(), []).append(record)
            return factor

        backends.factorize = factorize
        self._patches.append((backends, "factorize", direct))
        from pymorembs.preparation import validation

        if hasattr(validation, "_definite_stiffness"):  # K of a held body, made by PARDISO
            held = validation._definite_stiffness

            def definite(stiffness):
                tick = time.perf_counter()
                factor = held(stiffness)
                if factor is not None:
                    record = ("real", time.perf_counter() - tick, False)
                    clock.factorizations.setdefault(clock.current(), []).append(record)
                return factor

            validation._definite_stiffness = definite
            self._patches.append((validation, "_definite_stiffness", held))

    def restore(self) -> None:
        for owner, attribute, original in reversed(self._patches):
            setattr(owner, attribute, original)
        self._patches.clear()


def measure(model: str, dofs: int | None, before: bool, checks: str = "default") -> dict:
    """Run the job, then each reduction alone, in this process; the measurements
    (``checks``: ``"direct"`` or ``"iterative"`` forces how the reference's checks at f > 0
    are computed, ``"default"`` leaves the package's choice)."""
    import pymorembs.analysis.reference as reference_module
    import pymorembs.job.run as run
    from pymorembs import reduce
    from pymorembs.job.schema import load_job
    from pymorembs.linalg import shared_factorizations

    if before:  # the job as it was: nothing shared, the reference's own candidates
        run.shared_factorizations = lambda: shared_factorizations(0.0)
        run.expansion_candidates = lambda options, band: []
        if hasattr(reference_module, "ITERATIVE_CHECKS"):
            reference_module.ITERATIVE_CHECKS = False
    if checks != "default":
        reference_module.ITERATIVE_CHECKS = checks == "iterative"
        if checks == "iterative":  # at every size
            reference_module.ITERATIVE_MIN_ORDER = 0
    clock = StageClock()
    clock.count_factorizations()
    prepared_box: list = []

    def keep_prepared(original):
        def inner(*args, **kwargs):
            out = original(*args, **kwargs)
            prepared_box.append(out[1])
            return out

        return inner

    run._prepared_for_job = keep_prepared(run._prepared_for_job)
    clock.wrap(run, "prepare_and_validate", "read + validate")
    clock.wrap(run, "with_inertia_loads", "inertia loads")
    clock.wrap(run, "_reference", "error reference")
    clock.wrap(run, "_reduce_one", lambda prepared, spec, *a, **k: f"reduction {spec.name}")
    clock.wrap(run, "_settled", "settle checks")
    clock.wrap(run.ReferenceResponse, "settled_all", "settle checks")
    if hasattr(run, "_completed"):  # the weakest frequencies, checked after the reductions
        clock.wrap(run.ReferenceResponse, "completed", "remaining checks")
    clock.wrap(run, "_judged", "errors + body files")
    clock.wrap(run, "_write_summary", "summary + plots")
    with tempfile.TemporaryDirectory(prefix="job_cost_") as folder:
        path = Path(folder) / "job.toml"
        path.write_text(job_text(model, dofs))
        job = load_job(path)
        tick = time.perf_counter()
        try:
            summary = run.run_job(job, Path(folder) / "out")
        except run.AccuracyNotMet as exc:  # the body files of that reduction not written
            summary = exc.summary
        job_s = time.perf_counter() - tick
    clock.restore()
    job_peak_mb = peak_memory_mb()
    prepared = prepared_box[0]
    alone: dict[str, dict] = {}
    counter = StageClock()
    counter.count_factorizations()
    for spec in job.reductions:
        counter._stack.append([spec.name, 0.0, 0.0])
        tick = time.perf_counter()
        reduce(prepared, spec.options, band_hz=job.band_hz, name=spec.name)
        alone[spec.name] = {"seconds": time.perf_counter() - tick}
        counter._stack.pop()
        made = counter.factorizations.get(spec.name, [])
        alone[spec.name]["factorizations"] = len(made)
    counter.restore()
    reductions_alone_s = sum(r["seconds"] for r in alone.values())
    stages = {}
    for name in sorted(set(clock.seconds) | set(clock.factorizations)):
        made = [r for r in clock.factorizations.get(name, []) if not r[2]]
        stages[name] = {
            "seconds": clock.seconds.get(name, 0.0),
            "made": len(made),
            "made_complex": sum(1 for r in made if r[0] == "complex"),
            "factorization_s": sum(r[1] for r in made),
            "reused": sum(1 for r in clock.factorizations.get(name, []) if r[2]),
        }
    accounted = sum(s["seconds"] for s in stages.values())
    stages["other"] = {
        "seconds": job_s - accounted + stages.get("other", {}).get("seconds", 0.0),
        **{k: stages.get("other", {}).get(k, 0) for k in ("made", "made_complex", "reused")},
        "factorization_s": stages.get("other", {}).get("factorization_s", 0.0),
    }
    reference = summary.reference
    errors = {r.name: r.accuracy.max for r in summary.reductions}
    return {
        "model": model,
        "n": prepared.reduction_system.order,
        "before": before,
        "job_s": job_s,
        "reductions_alone_s": reductions_alone_s,
        "alone": alone,
        "stages": stages,
        "ratio": job_s / reductions_alone_s,
        "reference_order": reference.get("order"),
        "reference_points_hz": reference.get("expansion_points_hz"),
        "reference_accuracy": reference.get("accuracy"),
        "exact_frequencies": reference.get("exact_frequencies"),
        "max_errors": errors,
        "peak_mb": job_peak_mb,
    }


STAGE_ORDER = [
    "read + validate",
    "inertia loads",
    "error reference",
    "reduction krylov",
    "reduction soaga",
    "reduction craig-bampton",
    "settle checks",
    "remaining checks",
    "errors + body files",
    "summary + plots",
    "other",
]


def table_of(r: dict) -> str:
    """One run's stages as a markdown table."""
    rows = []
    for name in STAGE_ORDER + sorted(set(r["stages"]) - set(STAGE_ORDER)):
        s = r["stages"].get(name)
        if s is None:
            continue
        made = f"{s['made']}" + (f" ({s['made_complex']} complex)" if s["made_complex"] else "")
        rows.append([name, fmt_s(s["seconds"]), made, fmt_s(s["factorization_s"]), s["reused"]])
    total_made = sum(s["made"] for s in r["stages"].values())
    total_reused = sum(s["reused"] for s in r["stages"].values())
    rows.append(["**whole job**", f"**{fmt_s(r['job_s'])}**", total_made, "", total_reused])
    for name, a in r["alone"].items():
        rows.append([f"{name} alone", fmt_s(a["seconds"]), a["factorizations"], "", ""])
    rows.append(["**Σ reductions alone**", f"**{fmt_s(r['reductions_alone_s'])}**", "", "", ""])
    headers = ["stage", "wall [s]", "factorizations made", "of which in them [s]", "reused"]
    return markdown_table(headers, rows)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--model", choices=("rack-solid", "bracket"), default="rack-solid")
    parser.add_argument("--dofs", type=int, default=35000, help="rack-solid size")
    parser.add_argument("--before", action="store_true", help="also the job as it was")
    parser.add_argument("--quick", action="store_true", help="rack-solid, 7,400 dofs")
    parser.add_argument("--no-results", action="store_true", help="do not write RESULTS.md")
    parser.add_argument(
        "--checks",
        choices=("default", "direct", "iterative"),
        default="default",
        help="how the reference's checks at f > 0 are computed (default: the package's choice)",
    )
    parser.add_argument("--child", action="store_true", help=argparse.SUPPRESS)
    parser.add_argument("--as-before", action="store_true", help=argparse.SUPPRESS)
    args = parser.parse_args()
    dofs = 7400 if args.quick else (args.dofs if args.model == "rack-solid" else None)
    if args.child:
        # BLAS on one thread, as the command line runs a job (PARDISO keeps its own threads)
        with threadpool_limits(limits=1, user_api="blas"):
            emit(measure(args.model, dofs, args.as_before, args.checks))
        return
    if args.model == "bracket" and not (BRACKET / "bracket.sti").exists():
        sys.exit(f"{BRACKET} holds no bracket.sti: make it with bench/calculix_peer.py")
    runs = {}
    for before in [True, False] if args.before else [False]:
        argv = [__file__, "--child", "--model", args.model, "--dofs", str(dofs or 0)]
        argv += ["--as-before"] if before else []
        argv += ["--checks", args.checks]
        label = "before" if before else "now"
        print(f"{args.model} ({label}) ...", flush=True)
        r = run_child(argv)
        if "failed" in r:
            print(f"  failed: {r['failed']}")
            sys.exit(1)
        runs[label] = r
        alone = r["reductions_alone_s"]
        print(f"  n = {r['n']}: job {r['job_s']:.1f} s, reductions alone {alone:.1f} s,")
        print(f"  ratio {r['ratio']:.2f} (target <= {TARGET})")
        print(f"  max errors {r['max_errors']}; reference order {r['reference_order']},")
        print(f"  points {r['reference_points_hz']}, accuracy {r['reference_accuracy']}")
    parts = []
    for label, r in runs.items():
        what = "as it was (nothing shared)" if label == "before" else "now"
        parts.append(
            f"**{r['model']}, {r['n']} dofs, {what}**: job {fmt_s(r['job_s'])} s, Σ reductions "
            f"alone {fmt_s(r['reductions_alone_s'])} s, **ratio {r['ratio']:.2f}**; reference "
            f"order {r['reference_order']} at {r['reference_points_hz']} Hz, accuracy "
            f"{r['reference_accuracy']:.1e}, {r['exact_frequencies']} frequencies checked "
            f"against the full model; max errors "
            + ", ".join(f"{k} {v:.2e}" for k, v in r["max_errors"].items())
            + f"; peak RSS {r['peak_mb']:.0f} MB.\n\n"
            + table_of(r)
        )
    text = "\n\n".join(parts)
    print(text)
    if not args.no_results:
        body = (
            "The whole job (read, validate, inertia loads, error reference checked against the "
            "full model, Krylov/SOAGA/Craig–Bampton with their errors, SID and Exudyn files) ÷ "
            "the sum of its three reductions each run alone on the prepared model (same "
            f"process, after the job). Target ≤ {TARGET}.\n\n" + text
        )
        name = f"Job cost ({args.model}{'' if args.model == 'bracket' else f' {dofs}'})"
        path = update_results(name, body, machine_facts())
        print(f"written: {path}")


if __name__ == "__main__":
    main()
