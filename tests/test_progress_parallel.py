"""Progress bars and parallel work: same results in parallel, quiet with --quiet (issue #6)."""

from __future__ import annotations

import json
import operator
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from threadpoolctl import threadpool_limits

from conftest import spring_lattice
from lattice_jobs import lattice_job
from processes import live_children, running
from pymorembs import progress
from pymorembs.analysis.transfer import transfer_function
from pymorembs.errors import NumericalError
from pymorembs.frequencies import frequency_grid
from pymorembs.io.native import write_body_h5
from pymorembs.job.cli import main, worst
from pymorembs.job.run import prepare_job
from pymorembs.job.schema import load_job
from pymorembs.parallel import chunks, dask_available, parallel_map, usable_cores

ROOT = Path(__file__).resolve().parents[1]

needs_dask = pytest.mark.skipif(not dask_available(), reason="dask.distributed not installed")

MODAL = (
    'name = "modal-{order}"\nmethod = "modal"\norder = {order}\n'
    "export_inaccurate = true  # a few modes of the undamped lattice: poor bodies, on purpose"
)


@pytest.fixture(scope="module")
def rack_buckens():
    """The rack-beams example, free (Buckens frame): 0 Hz needs inertia relief."""
    job = load_job(ROOT / "examples" / "rack-beams-buckens.toml")
    _, prepared = prepare_job(job)
    return prepared.system, frequency_grid(0.0, job.band_hz[1], 9)


def test_parallel_sweep_equals_the_serial_one_bit_for_bit(rack_buckens):
    system, frequencies = rack_buckens
    assert system.rigid_modes is not None and frequencies[0] == 0.0
    with threadpool_limits(limits=1, user_api="blas"):  # as the command line and the workers
        serial = transfer_function(system, frequencies)
    parallel = transfer_function(system, frequencies, workers=2)
    assert parallel.shape == serial.shape
    assert np.array_equal(parallel, serial)


@needs_dask
@pytest.mark.slow
def test_sweep_on_a_dask_local_cluster_equals_the_serial_one(rack_buckens):
    system, frequencies = rack_buckens
    with threadpool_limits(limits=1, user_api="blas"):
        serial = transfer_function(system, frequencies[:4])
    on_dask = transfer_function(system, frequencies[:4], workers=2, scheduler="local")
    # the model travels pickled to other interpreters: equal to rounding, not always bit for bit
    assert np.abs(on_dask - serial).max() <= 1e-14 * np.abs(serial).max()


class Unpicklable:
    """A context that cannot be pickled: workers can only get it by inheritance (fork)."""

    def __init__(self, data: np.ndarray):
        self.data = data

    def __reduce__(self):
        raise TypeError("this context must not be pickled")


def _scaled_sum(context: Unpicklable, k: int) -> float:
    return float(context.data.sum() * k)


def _fail_on_three(k: int) -> int:
    if k == 3:
        raise NumericalError("three is singular")
    return k


def test_process_pool_inherits_the_context_and_keeps_the_order():
    context = Unpicklable(np.arange(100_000, dtype=float))
    expected = [float(context.data.sum() * k) for k in range(7)]
    bar = progress.Progress("test", total=7, force=False)
    assert parallel_map(_scaled_sum, range(7), workers=2, context=context, progress=bar) == (
        expected
    )
    assert parallel_map(_scaled_sum, range(7), workers=1, context=context) == expected


def test_process_pool_reraises_the_error_of_a_task():
    with pytest.raises(NumericalError, match="three is singular"):
        parallel_map(_fail_on_three, range(6), workers=2)


def test_chunks_cover_the_range_in_order():
    for n, parts in ((1, 4), (10, 3), (201, 8), (5, 5)):
        pieces = chunks(n, parts)
        assert [k for piece in pieces for k in piece] == list(range(n))
        assert len(pieces) == min(n, parts)
    assert usable_cores() >= 1


@needs_dask
def test_parallel_map_on_a_dask_local_cluster():
    assert parallel_map(operator.mul, [1, 2, 3], workers=2, scheduler="local", context=10) == [
        10,
        20,
        30,
    ]


def test_worst_exit_code_ranks_bug_over_numerical_over_user():
    assert worst([0, 2, 0]) == 2
    assert worst([2, 3, 0]) == 3
    assert worst([3, 1, 2]) == 1
    assert worst([0, 0]) == 0


@pytest.fixture
def two_jobs(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    write_body_h5(spring_lattice(), tmp_path / "model.h5")
    paths = []
    for order in (4, 6):
        path = tmp_path / f"job{order}.toml"
        path.write_text(lattice_job(MODAL.format(order=order)))
        paths.append(path)
    return paths


def _summary(tmp_path: Path, stem: str) -> dict:
    return json.loads((tmp_path / "out" / stem / "summary.json").read_text())


@needs_dask
@pytest.mark.slow
def test_two_jobs_on_a_local_dask_cluster(two_jobs, tmp_path, capfd):
    code = main(["reduce", *map(str, two_jobs), "--scheduler", "local", "--workers", "2"])
    out, err = capfd.readouterr()
    assert code == 0, err
    for order, path in zip((4, 6), two_jobs, strict=True):
        summary = _summary(tmp_path, path.stem)
        assert summary["reductions"][0]["order"] == order
        assert f"job {path}: done" in out
    assert out.count("results in") == 2


@pytest.mark.slow
def test_several_jobs_one_after_another_quiet_and_worst_exit_code(two_jobs, tmp_path, capfd):
    """--quiet: nothing on stdout or stderr; a failing job: one line, the others still run."""
    code = main(["reduce", *map(str, two_jobs), "--quiet", "--workers", "2"])
    out, err = capfd.readouterr()
    assert (code, out, err) == (0, "", "")
    assert _summary(tmp_path, "job4")["reductions"][0]["order"] == 4
    assert _summary(tmp_path, "job6")["reductions"][0]["order"] == 6

    missing = tmp_path / "missing.toml"
    code = main(["reduce", str(missing), str(two_jobs[0]), "--quiet"])
    out, err = capfd.readouterr()
    assert code == 2 and out == ""
    assert err.count("\n") == 1 and "missing.toml" in err


def test_out_takes_a_single_job(two_jobs, capfd):
    code = main(["reduce", *map(str, two_jobs), "--out", "somewhere"])
    err = capfd.readouterr().err
    assert code == 2 and "--out takes a single job" in err and err.count("\n") == 1


@pytest.mark.slow
def test_progress_bars_on_stderr_only_when_forced(two_jobs, tmp_path, capfd):
    code = main(["reduce", str(two_jobs[0]), "--out", str(tmp_path / "a")])
    out, err = capfd.readouterr()
    assert code == 0 and err == ""  # stderr is not a terminal: no bars
    assert "frequency response of the full model at 401 frequencies" in out
    code = main(["reduce", str(two_jobs[0]), "--out", str(tmp_path / "b"), "--progress"])
    out, err = capfd.readouterr()
    assert code == 0
    assert "frequency response (full model)" in err and "job job4" in err
    assert "frequency response of the full model at 401 frequencies" in out  # lines as before
    assert progress.mode() == "auto"  # restored after the command


def test_progress_is_throttled_and_silent_when_off(capsys):
    with progress.Progress("steps", total=10_000, unit="step", force=True) as bar:
        assert bar.every == 100
        for _ in range(10_000):
            bar.update()
    assert "steps" in capsys.readouterr().err
    with progress.settings("off"), progress.Progress("steps", total=10) as bar:
        assert not bar.active
        bar.update(10)
    assert capsys.readouterr().err == ""


def test_krylov_and_soaga_iterations_show_progress(rack_buckens, capsys):
    from pymorembs.reduction.krylov import krylov_reduction
    from pymorembs.reduction.soaga import soaga_reduction

    system, _ = rack_buckens
    with progress.settings("on"):
        krylov_reduction(system, [0.0, 100.0], [2, 2])
        err = capsys.readouterr().err
        assert "krylov" in err and "moment" in err and "factorizing at 100 Hz" in err
        soaga_reduction(system, (0.0, 200.0), tolerance=1e-3)
        err = capsys.readouterr().err
        assert "soaga" in err and "estimated error" in err
    with progress.settings("off"):
        krylov_reduction(system, [0.0], [2])
    assert capsys.readouterr().err == ""


def test_soaga_bar_has_no_total_when_the_estimator_ends_the_work(rack_buckens, capsys):
    """Issue #16: the bar promised the full order (thousands of columns, an ETA of minutes) and
    stopped at a few dozen. With a tolerance it counts columns only; with an order cap alone
    the cap is the total."""
    import re

    from pymorembs.reduction.soaga import soaga_reduction

    system, _ = rack_buckens
    with progress.settings("on"):
        projection = soaga_reduction(system, (0.0, 200.0), tolerance=1e-3)
        err = capsys.readouterr().err
        assert projection.order < system.order // 10
        assert "soaga" in err and f"/{system.order}" not in err
        assert re.search(r"\d+/\d+", err) is None and "<" not in err  # no total, no ETA
        assert f"{projection.order}column" in err  # the count where the work ended
        soaga_reduction(system, (0.0, 200.0), max_order=12)
        err = capsys.readouterr().err
        assert "12/12" in err


def test_finish_ends_a_bar_at_its_count(capsys):
    with progress.Progress("cap", total=100, unit="column", force=True) as bar:
        bar.update(18)
        bar.finish()
        assert bar.total == bar.count == 18
    assert "18/18" in capsys.readouterr().err


def wait_until(condition, seconds: float) -> bool:
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        if condition():
            return True
        time.sleep(0.05)
    return condition()


needs_proc = pytest.mark.skipif(not Path("/proc/self/stat").exists(), reason="needs /proc")


@pytest.mark.slow
@needs_proc
def test_sweep_workers_end_when_the_run_is_killed(tmp_path):
    """Issue #16: a run killed with SIGKILL left its forked sweep workers asleep for hours.
    The demo job's full-model sweep on two workers; the run is killed during the sweep."""
    script = Path(sys.executable).with_name("pymorembs")
    run = subprocess.Popen(
        [str(script), "reduce", str(ROOT / "examples" / "rack-beams-demo.toml"), "--out",
         str(tmp_path / "out"), "--workers", "2", "--quiet"],
        stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
    )  # fmt: skip
    workers: list[int] = []
    try:
        assert wait_until(lambda: len(live_children(run.pid)) >= 2 or run.poll() is not None, 60)
        workers = live_children(run.pid)
        assert run.poll() is None and len(workers) >= 2  # the sweep runs
        run.send_signal(signal.SIGKILL)
        run.wait(timeout=10)
        assert wait_until(lambda: not any(running(pid) for pid in workers), 5)
    finally:
        if run.poll() is None:
            run.kill()
        for pid in workers:
            if running(pid):
                os.kill(pid, signal.SIGKILL)


FALLBACK = """
import os, sys, time
from pymorembs import parallel
parent = os.getpid()
child = os.fork()
if child == 0:
    sys.platform = "darwin"  # no prctl: the watcher thread
    parallel.PARENT_POLL_S = 0.05
    parallel.die_with_parent(parent)
    time.sleep(60)
    os._exit(0)
print(child, flush=True)
time.sleep(60)
"""


@needs_proc
def test_without_prctl_a_thread_ends_the_orphan():
    """The portable fallback of die_with_parent: a thread that sees the parent change."""
    middle = subprocess.Popen([sys.executable, "-c", FALLBACK], stdout=subprocess.PIPE, text=True)
    child = int(middle.stdout.readline())
    try:
        time.sleep(0.3)
        assert running(child)
        middle.kill()
        middle.wait(timeout=10)
        assert wait_until(lambda: not running(child), 5)
    finally:
        if running(child):
            os.kill(child, signal.SIGKILL)
        middle.stdout.close()
