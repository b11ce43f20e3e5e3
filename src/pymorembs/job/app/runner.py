"""A job run off the page's request threads: ``pymorembs reduce`` in a child process.

The child is the command line itself (``python -m pymorembs.job.cli reduce JOB --out DIR``), so
a run from the page is a run of the saved job file, and Cancel ends the process (and its
workers) without leaving anything half-written: the job layer writes into a temporary folder
and renames it only at the end. Progress comes from the stage lines the command prints
(``loading the model``, ``frequency response ...``, ``reduction 'name'``).
"""

from __future__ import annotations

import os
import shutil
import signal
import subprocess
import sys
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

#: Lines of ``pymorembs reduce`` that start a stage (after the ``[   1.23 s]`` time stamp).
STAGE_STARTS = (
    "loading the model", "frequency response", "reference model", "reduction '", "time domain",
    "large motion",
)  # fmt: skip
#: Stages whose every line starts alike (``time domain: reduction 'k'``): the first begins it.
ONE_STAGE = ("time domain", "large motion")


@dataclass
class Run:
    """One run of a job file: its process, progress and outcome.

    Attributes
    ----------
    job : Path
        The job file it runs.
    out : Path
        The output folder (``summary.json`` there once it succeeded).
    stages : int
        The stages the job has (:meth:`~pymorembs.job.schema.Job.stage_count`).
    state : str
        ``"running"``, ``"done"``, ``"failed"`` or ``"cancelled"``. A run that ended with
        exit code 4 (accuracy not met) is ``"done"``: its results are written, the bodies
        that missed their limit are marked in them; :attr:`error` holds its line.
    exit_code : int or None
        The command's exit code once it ended.
    """

    job: Path
    out: Path
    stages: int
    state: str = "running"
    done_stages: int = 0
    stage: str = "starting"
    lines: list[str] = field(default_factory=list)
    error: str = ""
    exit_code: int | None = None
    started: float = field(default_factory=time.time)
    ended: float | None = None
    process: subprocess.Popen | None = None
    #: Held while the state changes: a Cancel and the end of the process do not cross.
    lock: threading.Lock = field(default_factory=threading.Lock, repr=False, compare=False)

    @property
    def alive(self) -> bool:
        """The child process is still there (a cancelled run's, until it has ended)."""
        return self.process is not None and self.process.poll() is None

    @property
    def fraction(self) -> float:
        """Share of the work done, 0..1 (stages begun, the current one counted half)."""
        if self.state == "done":
            return 1.0
        return min(0.99, max(0.0, (self.done_stages - 0.5) / max(self.stages, 1)))

    def read_line(self, line: str) -> None:
        """Take one line the command printed: into the log, and the stage it begins, if any."""
        line = line.rstrip()
        if not line:
            return
        self.lines.append(line)
        text = line.split("] ", 1)[-1]
        start = next((s for s in STAGE_STARTS if text.startswith(s)), None)
        if start is None:
            return
        if not (start in ONE_STAGE and self.stage.startswith(start)):
            self.done_stages += 1
        self.stage = text

    def as_dict(self) -> dict[str, Any]:
        """The run for the page: state, share done, stage, the last lines of its log."""
        return {
            "state": self.state,
            "fraction": self.fraction,
            "stage": self.stage,
            "lines": self.lines[-12:],
            "error": self.error,
            "exit_code": self.exit_code,
            "seconds": (self.ended or time.time()) - self.started,
            "job": str(self.job),
            "out": str(self.out),
        }

    def cancel(self, grace_s: float = 10.0) -> None:
        """End the child process and its workers (a cancelled run writes nothing).

        SIGTERM first, so that the job layer removes its temporary folder on the way out; what
        still runs after ``grace_s`` seconds is killed. (Not SIGINT: a child started by an app
        that was itself started in the background of a shell script or by ``nohup`` inherits
        SIGINT ignored, and a cancel by SIGINT did nothing until the kill.)
        """
        process = self.process
        with self.lock:
            if self.state != "running" or process is None or process.poll() is not None:
                return
            self.state = "cancelled"
        _signal_group(process.pid, signal.SIGTERM)
        timer = threading.Timer(grace_s, _kill_if_alive, args=(process,))
        timer.daemon = True
        timer.start()

    def remove_staging(self) -> None:
        """Remove the temporary folders of the job layer next to :attr:`out` (``.run-1.*``):
        a run killed after the grace time could not remove its own."""
        for folder in self.out.parent.glob(f".{self.out.name}.*"):
            shutil.rmtree(folder, ignore_errors=True)


def _signal_group(pid: int, sig: int) -> None:
    try:
        os.killpg(pid, sig)
    except ProcessLookupError:
        pass


def _kill_if_alive(process: subprocess.Popen) -> None:
    if process.poll() is None:
        _signal_group(process.pid, signal.SIGKILL)


def start_run(job: Path, out: Path, stages: int) -> Run:
    """Start ``pymorembs reduce job --out out`` in a child process and follow it in a thread.

    Parameters
    ----------
    job : Path
        The job file.
    out : Path
        The output folder of the run.
    stages : int
        The stages the job has (:attr:`Run.stages`).

    Returns
    -------
    Run
        The run, ``"running"``; its state changes when the process ends.
    """
    run = Run(job=job, out=out, stages=stages)
    env = dict(os.environ)
    source = str(Path(__file__).resolve().parents[3])  # the folder holding the package
    env["PYTHONPATH"] = os.pathsep.join(p for p in (source, env.get("PYTHONPATH", "")) if p)
    env["PYTHONUNBUFFERED"] = "1"
    run.process = subprocess.Popen(
        [sys.executable, "-m", "pymorembs.job.cli", "reduce", str(job), "--out", str(out)],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        stdin=subprocess.DEVNULL,
        text=True,
        env=env,
        start_new_session=True,  # its own process group: Cancel ends its workers too
    )
    threading.Thread(target=_follow, args=(run,), daemon=True).start()
    return run


def _follow(run: Run) -> None:
    process = run.process
    assert process is not None and process.stdout is not None and process.stderr is not None
    errors: list[str] = []
    reader = threading.Thread(target=lambda: errors.extend(process.stderr), daemon=True)
    reader.start()
    for line in process.stdout:
        run.read_line(line)
    code = process.wait()
    reader.join(timeout=5)
    ended = time.time()
    message = [e.strip() for e in errors if e.strip().startswith("pymorembs: error")]
    with run.lock:
        run.exit_code = code
        if run.state == "cancelled":
            run.stage = "cancelled"
            run.remove_staging()
        elif code == 0:
            run.state, run.stage = "done", "done"
        elif code == ACCURACY_NOT_MET and (run.out / "summary.json").is_file():
            run.state, run.stage = "done", "done, accuracy not met"
            run.error = message[-1] if message else "accuracy not met"
        else:
            run.state = "failed"
            lines = message or [e.strip() for e in errors if e.strip()]
            run.error = lines[-1] if lines else f"pymorembs reduce exited with code {code}"
        run.ended = ended  # last: an ended run has nothing left to clean up
    for line in errors:
        if line.startswith(("pymorembs: warning", "pymorembs: note")):
            run.lines.append(line.rstrip())


#: The exit code of a job whose results are written but a body missed its accuracy limit.
ACCURACY_NOT_MET = 4
