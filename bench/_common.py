"""Shared helpers of the benchmark scripts: the model, machine facts, peak memory, RESULTS.md.

Every benchmark runs each measured method in a fresh Python process (``run_child``), so that
peak memory and timings of one method are not influenced by another; the child prints one line
``RESULT {json}`` that the parent reads.
"""

from __future__ import annotations

import datetime
import json
import os
import platform
import re
import resource
import shlex
import subprocess
import sys
import time
from importlib import metadata
from pathlib import Path
from typing import Any

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from pymorembs.linalg.factorization import combine, is_symmetric

BENCH = Path(__file__).resolve().parent
RESULTS = BENCH / "RESULTS.md"
CACHE = BENCH / ".cache"
#: The band of the paper's comparison (Hz) and its port: the three forces/displacements at node 1
#: of the rack, frame at node 2 (``examples/rack-solid-compare.toml``, node 1 only).
BAND_HZ = (0.0, 1000.0)
FRAME_NODE = 2
PORT_NODE = 1
#: Peak memory of building the 300,000-dof rack-solid (docs/models.md), scaled linearly.
BUILD_BYTES_PER_DOF = 3.2e9 / 300_000
RESULT_TAG = "RESULT "


# --------------------------------------------------------------------------- the model


def build_prepared(example: str, dofs: int | None, damping: str = "modal"):
    """The prepared rack: frame at node 2, inputs and outputs ``1: ux uy uz``.

    Parameters
    ----------
    example : {"rack-solid", "rack-beams"}
    dofs : int or None
        About this many dofs (rack-solid only).
    damping : {"modal", "rayleigh"}
        ``"modal"``: 1 % in every mode, as in the paper's comparison (loss factor; real shifted
        stiffness matrices for Krylov/SOAGA). ``"rayleigh"``: ``D = 2e-6 s * K`` (a viscous
        matrix, needed by pyMOR's ``SecondOrderModel``; complex shifted matrices).

    Returns
    -------
    prepared : pymorembs.preparation.PreparedModel
    build_s : float
        Wall time of building the FE model.
    """
    from pymorembs.examples import build_example

    tick = time.perf_counter()
    options = {"dofs": dofs} if example == "rack-solid" else {}
    body = build_example(example, **options)
    build_s = time.perf_counter() - tick
    return prepare_damped(body, FRAME_NODE, PORT_NODE, damping), build_s


def prepare_damped(body, frame_node: int, port_node: int, damping: str = "modal"):
    """``body`` damped (``"modal"``: 1 % in every mode; ``"rayleigh"``: ``D = 2e-6 s * K``),
    tangent frame at ``frame_node``, inputs and outputs ``port_node: ux uy uz``."""
    from pymorembs.body import Damping
    from pymorembs.preparation import Frame, Port, prepare

    if damping == "modal":
        body = body.with_damping(Damping("modal", ratio=0.01))
    else:
        body = body.with_damping(Damping("rayleigh", beta=2e-6))
    ports = [Port.parse(port_node, "ux uy uz")]
    return prepare(body, Frame("tangent", frame_node), ports, ports)


def krylov_or_soaga_spec(method: str):
    """The :class:`~pymorembs.job.schema.ReductionSpec` of the floor-ratio and scaling runs."""
    from pymorembs.job.schema import ReductionSpec
    from pymorembs.methods import method_options

    if method == "krylov":  # as in examples/rack-beams-demo.toml
        options = {"expansion_points_hz": [0.0, 500.0, 1000.0], "moments": [6, 5, 5]}
        return ReductionSpec("krylov", method_options("krylov", options))
    return ReductionSpec("soaga", method_options("soaga", {"tolerance": 1e-6}))


# --------------------------------------------------------------------------- factorizations


def assemble(terms: Any) -> sp.csc_matrix:
    """``sum_i c_i A_i`` of the ``terms`` given to ``Factorization`` (or one sparse matrix)."""
    if sp.issparse(terms):
        return sp.csc_matrix(terms)
    return combine(terms)


def is_complex(terms: Any) -> bool:
    """Whether the operator of ``terms`` is complex (a coefficient or a matrix)."""
    if sp.issparse(terms):
        return np.iscomplexobj(terms.data)
    return any(complex(c).imag != 0 or np.iscomplexobj(getattr(m, "data", m)) for c, m in terms)


class FactorizationCounter:
    """Counts the calls of ``Factorization.__init__`` and their wall time, real and complex.

    Use as a context manager around a reduction; it patches the class and restores it. The
    terms of every call are kept (references to the matrices and the coefficients, no copy) so
    that the very matrices the reduction factorized can be factorized again afterwards:
    ``terms[kind]`` lists them in call order, ``first_terms[kind]`` is the first.
    """

    def __init__(self) -> None:
        self.calls: list[tuple[str, float]] = []
        self.first_terms: dict[str, Any] = {}
        self.terms: dict[str, list[Any]] = {}

    def __enter__(self) -> FactorizationCounter:
        from pymorembs.linalg import factorization

        self._cls = factorization.Factorization
        self._original = original = self._cls.__init__
        counter = self

        def counted(instance, *args, **kwargs):
            terms = args[0] if args else kwargs.get("terms")
            kind = "complex" if is_complex(terms) else "real"
            tick = time.perf_counter()
            original(instance, *args, **kwargs)
            counter.calls.append((kind, time.perf_counter() - tick))
            counter.first_terms.setdefault(kind, terms)
            counter.terms.setdefault(kind, []).append(terms)

        self._cls.__init__ = counted
        return self

    def __exit__(self, *exc: object) -> None:
        self._cls.__init__ = self._original

    def count(self, kind: str) -> int:
        return sum(1 for k, _ in self.calls if k == kind)

    def seconds(self, kind: str | None = None) -> float:
        return sum(t for k, t in self.calls if kind is None or k == kind)


def time_backends(
    matrix: sp.csc_matrix, repeat: int = 1, splu_limit: int = 10**9, only: str | None = None
) -> dict:
    """Wall time of one factorization of ``matrix`` by every available backend (best of repeat),
    or by the backend named ``only`` (a key of the returned dict).

    Backends: SciPy ``splu`` with the project's SuperLU settings; ``pypardiso`` (real matrices:
    general ``mtype=11`` and symmetric indefinite ``mtype=-2`` on the upper triangle), if
    importable; every backend of ``pymorembs.linalg.backends.available_backends()`` in
    symmetric mode (or, without that module, ``Factorization(matrix, check=False)``). SuperLU
    is skipped above ``splu_limit`` dofs when another backend exists.

    Returns
    -------
    dict
        backend name -> seconds (or an error string).
    """
    from pymorembs.linalg import factorization

    options = getattr(factorization, "SUPERLU_OPTIONS", None) or {
        "permc_spec": "MMD_AT_PLUS_A",
        "diag_pivot_thresh": 0.01,
        "options": {"SymmetricMode": True},
    }
    backends: dict[str, Any] = {}
    try:
        import pypardiso
    except ImportError:
        pypardiso = None
    if pypardiso is not None and not np.iscomplexobj(matrix.data):
        backends["pypardiso (mtype 11)"] = lambda: _pardiso(pypardiso, matrix.tocsr(), 11)
        upper = sp.triu(matrix, format="csr")
        backends["pypardiso (mtype -2)"] = lambda: _pardiso(pypardiso, upper, -2)
    try:  # the project's solver backends (pymorembs.linalg.backends), symmetric mode
        from pymorembs.linalg import backends as project

        for name in project.available_backends():
            backends[f"pymorembs {name}"] = lambda name=name: _standalone(project, matrix, name)
    except (ImportError, AttributeError):  # older layout: whatever Factorization uses
        backends["pymorembs Factorization"] = lambda: factorization.Factorization(
            matrix, check=False
        )
    backends["scipy splu (project settings)"] = lambda: spla.splu(matrix, **options)
    if matrix.shape[0] > splu_limit:  # SuperLU is far slower there; keep it only if alone
        slow = {"scipy splu (project settings)", "pymorembs superlu"}
        if set(backends) - slow:
            backends = {k: v for k, v in backends.items() if k not in slow}
    if only is not None:
        backends = {only: backends[only]}
    times: dict[str, Any] = {}
    for name, factorize in backends.items():
        try:
            best = np.inf
            for _ in range(repeat):
                tick = time.perf_counter()
                handle = factorize()
                best = min(best, time.perf_counter() - tick)
                del handle
            times[name] = best
        except Exception as exc:  # a backend that cannot do this matrix is reported, not fatal
            times[name] = f"failed: {type(exc).__name__}: {exc}"[:120]
    return times


def _standalone(project, matrix: sp.spmatrix, name: str):
    """One complete factorization by the project's backend ``name``, as a standalone call makes
    it: the caches of orderings, upper-triangle patterns and factor families (which a reduction
    reuses across the shifts of one pattern) are emptied first, so METIS and the symbolic
    analysis run as in the other backends' timings."""
    for cache in ("_ORDERINGS", "_UPPER", "_FAMILIES"):
        getattr(project, cache, {}).clear()
    return project.factorize(matrix, True, name)


def _pardiso(pypardiso, matrix: sp.csr_matrix, mtype: int):
    solver = pypardiso.PyPardisoSolver(mtype=mtype)
    solver.factorize(matrix)
    solver.free_memory(everything=True)
    return solver


def fastest(times: dict) -> tuple[str, float]:
    """The fastest backend of :func:`time_backends` and its time."""
    numbers = {k: v for k, v in times.items() if isinstance(v, float)}
    if not numbers:
        return "no backend succeeded", float("nan")
    name = min(numbers, key=numbers.get)
    return name, numbers[name]


def warm_up() -> None:
    """Load the solver libraries (MKL, the compiled double-double kernel) once, so that loading
    is not timed."""
    small = sp.eye(50, format="csc") * 2.0
    time_backends(small)
    try:
        from pymorembs.linalg import double_double
    except ImportError:  # an older pymorembs
        return
    if double_double.available():  # every compiled kernel of a reduction, so none compiles
        double_double.product(small, np.ones((50, 2)))
        double_double.multiply(small, np.ones((50, 2)))
        combine([(1.0, sp.csr_matrix(small)), (-1.0, sp.identity(50, format="csr"))])
        is_symmetric(sp.csr_matrix(small))


# --------------------------------------------------------------------------- memory, processes


def reset_peak_memory() -> bool:
    """Reset the peak resident set size of this process (Linux ``clear_refs``); success."""
    try:
        Path("/proc/self/clear_refs").write_text("5")
        return True
    except OSError:
        return False


def peak_memory_mb() -> float:
    """Peak resident set size of this process in MB (``VmHWM``, else ``ru_maxrss``)."""
    try:
        for line in Path("/proc/self/status").read_text().splitlines():
            if line.startswith("VmHWM:"):
                return int(line.split()[1]) / 1024.0
    except OSError:
        pass
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def emit(result: dict) -> None:
    """Print the result of a child process as its last line."""
    print(RESULT_TAG + json.dumps(result), flush=True)


def run_child(
    argv: list[str], timeout: float | None = None, env: dict[str, str] | None = None
) -> dict:
    """Run ``python argv`` in a fresh process (``env``: variables set on top of this process's);
    its ``RESULT`` line, or the reason it failed."""
    command = [sys.executable, *argv]
    environment = None if env is None else {**os.environ, **env}
    tick = time.perf_counter()
    try:
        done = subprocess.run(
            command, capture_output=True, text=True, timeout=timeout, env=environment
        )
    except subprocess.TimeoutExpired:
        return {"failed": f"timeout after {timeout:.0f} s"}
    for line in reversed(done.stdout.splitlines()):
        if line.startswith(RESULT_TAG):
            result = json.loads(line[len(RESULT_TAG) :])
            result["process_s"] = time.perf_counter() - tick
            return result
    tail = (done.stderr.strip().splitlines() or ["no output"])[-1]
    reason = f"exit {done.returncode}" if done.returncode >= 0 else f"signal {-done.returncode}"
    return {"failed": f"{reason}: {tail}"[:200]}


def rss_mb() -> float:
    """This process's resident memory now (``VmRSS``), MB."""
    for line in Path("/proc/self/status").read_text().splitlines():
        if line.startswith("VmRSS:"):
            return int(line.split()[1]) / 1024.0
    return float("nan")


def available_memory_bytes() -> float:
    """``MemAvailable`` of ``/proc/meminfo`` (bytes); infinite if unknown."""
    try:
        for line in Path("/proc/meminfo").read_text().splitlines():
            if line.startswith("MemAvailable:"):
                return int(line.split()[1]) * 1024.0
    except OSError:
        pass
    return float("inf")


# --------------------------------------------------------------------------- report


def machine_facts() -> dict[str, str]:
    """Cores, RAM, CPU, versions and BLAS threads of this machine and environment."""
    facts = {
        "date (UTC)": datetime.datetime.now(datetime.UTC).strftime("%Y-%m-%d %H:%M"),
        "cores": f"{len(os.sched_getaffinity(0))} usable ({os.cpu_count()} logical)",
        "RAM": _meminfo_total(),
        "CPU": _cpu_model(),
        "python": platform.python_version(),
    }
    for package in ("numpy", "scipy", "pymorembs", "pymor", "pypardiso", "mkl"):
        try:
            facts[package] = metadata.version(package)
        except metadata.PackageNotFoundError:
            facts[package] = "not installed"
    facts["load average at the end (1, 5, 15 min)"] = _load_average()
    names = ("OMP_NUM_THREADS", "MKL_NUM_THREADS", "OPENBLAS_NUM_THREADS", "PYMOREMBS_SOLVER")
    settings = [f"{k}={os.environ[k]}" for k in names if k in os.environ]
    settings += [f"{k}={v}" for k, v in os.environ.items() if k.startswith("PYMOREMBS_SOLVER_")]
    facts["thread settings"] = ", ".join(settings) or "none (library defaults)"
    warm_up()  # loads the solver libraries (MKL), so that their thread pools are listed
    try:
        from threadpoolctl import threadpool_info

        pools = [
            f"{p.get('internal_api')} {p.get('version') or ''} ({p.get('num_threads')} threads)"
            for p in threadpool_info()
        ]
        facts["BLAS/OpenMP threads"] = "; ".join(pools) or "none loaded"
    except ImportError:
        facts["BLAS/OpenMP threads"] = "unknown (threadpoolctl missing)"
    return facts


def _load_average() -> str:
    try:
        return " ".join(Path("/proc/loadavg").read_text().split()[:3])
    except OSError:
        return "unknown"


def _meminfo_total() -> str:
    try:
        kb = int(re.search(r"MemTotal:\s+(\d+)", Path("/proc/meminfo").read_text()).group(1))
        return f"{kb / 1024**2:.1f} GiB"
    except (OSError, AttributeError):
        return "unknown"


def _cpu_model() -> str:
    try:
        match = re.search(r"model name\s*:\s*(.+)", Path("/proc/cpuinfo").read_text())
        return match.group(1).strip() if match else platform.processor() or "unknown"
    except OSError:
        return platform.processor() or "unknown"


def markdown_table(headers: list[str], rows: list[list[Any]]) -> str:
    """A Markdown table (also printed to the terminal as is)."""
    lines = ["| " + " | ".join(headers) + " |", "|" + "---|" * len(headers)]
    lines += ["| " + " | ".join(str(c) for c in row) + " |" for row in rows]
    return "\n".join(lines)


def command_line() -> str:
    """The command that ran this script, as it can be typed again from the repository root."""
    script = Path(sys.argv[0]).resolve()
    try:
        script = script.relative_to(BENCH.parent)
    except ValueError:
        pass
    return " ".join([".venv/bin/python", shlex.quote(str(script)), *map(shlex.quote, sys.argv[1:])])


def update_results(section: str, body: str, facts: dict[str, str]) -> Path:
    """Write ``## section`` of ``bench/RESULTS.md`` (replacing an older one), with the facts.

    Sections of the other benchmarks are left as they are.
    """
    facts_md = "\n".join(f"- {k}: {v}" for k, v in facts.items())
    text = f"## {section}\n\nCommand: `{command_line()}`\n\n{body.strip()}\n\n{facts_md}\n"
    old = (
        RESULTS.read_text(encoding="utf-8")
        if RESULTS.exists()
        else (
            "# Benchmark results\n\nWritten by the scripts in `bench/` (see `bench/README.md`); "
            "each section is replaced when its script runs again.\n"
        )
    )
    pattern = re.compile(rf"^## {re.escape(section)}\n.*?(?=^## |\Z)", re.S | re.M)
    if pattern.search(old):
        new = pattern.sub(lambda _m: text + "\n", old).rstrip() + "\n"
    else:
        new = old.rstrip() + "\n\n" + text
    RESULTS.write_text(new, encoding="utf-8")
    return RESULTS


def fmt_s(seconds: Any) -> str:
    """Seconds for a table: 3 significant digits, whole numbers from 100 s."""
    if not isinstance(seconds, int | float):
        return str(seconds)
    return f"{seconds:.0f}" if seconds >= 100 else f"{seconds:.3g}"
