"""Long fuzzing runs of the FE file readers (outside the test suite).

Uses the targets and strategies of ``tests/test_fuzz_readers.py`` with a large budget: for every
reader, ``--examples`` random inputs and ``--examples`` mutations of a valid file. The property is
the same as in the tests: the reader returns a consistent body or raises a one-line
``UserError`` naming the file. A failure is shrunk by hypothesis and printed with its input;
the run goes on with the next reader. Each input also gets a time limit (``--timeout``, seconds):
a slower read is reported as a hang.

Usage (from the repository root)::

    .venv/bin/python fuzz/fuzz_readers.py --examples 20000
    .venv/bin/python fuzz/fuzz_readers.py --examples 2000 --only dmig-punch abaqus-inp
    .venv/bin/python fuzz/fuzz_readers.py --list

Exit code 0 if every reader held the property, 1 otherwise.
"""

from __future__ import annotations

import argparse
import faulthandler
import resource
import signal
import sys
import tempfile
import time
import traceback
from pathlib import Path

from hypothesis import HealthCheck, given, settings
from hypothesis import seed as hypothesis_seed

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))
sys.path.insert(0, str(ROOT / "src"))

import test_fuzz_readers as fz  # noqa: E402


class Hang(BaseException):
    """A single read took longer than the time limit.

    A ``BaseException``, so that the readers' ``except Exception`` around third-party code
    cannot turn it into a ``UserError``.
    """


def _alarm(signum: int, frame: object) -> None:
    raise Hang("the reader took longer than the time limit")


def fuzz(key: str, kind: str, examples: int, timeout: float, seed: int) -> dict[str, object]:
    """Run one target with one strategy; return counts, wall time and the failure, if any."""
    target = fz.TARGETS[key]
    strategy = fz.random_input(target.binary) if kind == "random" else fz.mutations(target)
    count = {"inputs": 0, "ok": 0, "user_error": 0, "slowest_s": 0.0}

    @settings(
        max_examples=examples,
        deadline=None,
        database=None,
        derandomize=False,
        suppress_health_check=list(HealthCheck),
    )
    @hypothesis_seed(seed)
    @given(content=strategy)
    def check(content: bytes) -> None:
        count["inputs"] += 1
        start = time.perf_counter()
        signal.setitimer(signal.ITIMER_REAL, timeout)
        try:
            with tempfile.TemporaryDirectory() as d:
                outcome = fz.run_target(target, content, Path(d))
        finally:
            signal.setitimer(signal.ITIMER_REAL, 0)
        count["slowest_s"] = max(count["slowest_s"], time.perf_counter() - start)
        count["ok" if outcome == "ok" else "user_error"] += 1

    start = time.perf_counter()
    failure = None
    try:
        check()
    except BaseException as err:
        if isinstance(err, KeyboardInterrupt):
            raise
        frames = traceback.extract_tb(err.__traceback__)[-3:]
        where = "".join(traceback.format_list(frames)).rstrip()
        failure = "".join(traceback.format_exception_only(type(err), err)).strip()
        failure = failure.split("\nFailing test case", 1)[0]  # the input comes in the notes
        notes = [note[:600] for note in getattr(err, "__notes__", [])[:1]]
        failure += "\n" + where + "\n" + "\n".join(notes)
    return {**count, "wall_s": time.perf_counter() - start, "failure": failure}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--examples", type=int, default=20000, help="inputs per reader and kind")
    parser.add_argument("--timeout", type=float, default=10.0, help="seconds per input")
    parser.add_argument("--seed", type=int, default=0, help="random seed of the run")
    parser.add_argument("--only", nargs="*", help="target keys (default: all)")
    parser.add_argument("--kind", choices=("random", "mutated", "both"), default="both")
    parser.add_argument("--memory-gb", type=float, default=3.0, help="address-space limit")
    parser.add_argument("--list", action="store_true", help="list the targets and exit")
    args = parser.parse_args(argv)
    if args.list:
        for key, target in fz.TARGETS.items():
            print(f"{key:20s} fuzzes {target.name}")
        return 0
    if args.memory_gb > 0:  # an absurd size in a header then raises MemoryError, not OOM
        limit = int(args.memory_gb * 2**30)
        resource.setrlimit(resource.RLIMIT_AS, (limit, limit))
    faulthandler.enable()  # a crash in C code (HDF5, ansys-mapdl-reader) prints a stack
    signal.signal(signal.SIGALRM, _alarm)
    keys = args.only or list(fz.TARGETS)
    kinds = ("random", "mutated") if args.kind == "both" else (args.kind,)
    failed = 0
    total_start = time.perf_counter()
    print(
        f"{'target':20s} {'kind':8s} {'inputs':>7s} {'ok':>6s} {'user err':>8s} "
        f"{'wall s':>7s} {'slowest s':>9s}  result",
        flush=True,
    )
    for key in keys:
        for kind in kinds:
            r = fuzz(key, kind, args.examples, args.timeout, args.seed)
            result = "pass" if r["failure"] is None else "FAIL"
            print(
                f"{key:20s} {kind:8s} {r['inputs']:7d} {r['ok']:6d} {r['user_error']:8d} "
                f"{r['wall_s']:7.1f} {r['slowest_s']:9.3f}  {result}",
                flush=True,
            )
            if r["failure"] is not None:
                failed += 1
                print("    " + str(r["failure"]).replace("\n", "\n    "), flush=True)
    print(f"total wall time {time.perf_counter() - total_start:.0f} s; {failed} failing runs")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
