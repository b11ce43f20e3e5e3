"""The runs of the page's job: one at a time, each in the work folder under its own number.

:class:`RunController` writes the job's text as ``job-N.toml`` into the work folder and starts
``pymorembs reduce`` on it in a child process (:func:`~pymorembs.job.app.runner.start_run`,
output ``run-N/``); it reports the run's progress and cancels it. The parsed job a run was
started with stays with it (:meth:`RunController.job_of`): the results read the run's
interfaces from there.
"""

from __future__ import annotations

import tempfile
import threading
from collections.abc import Callable
from pathlib import Path
from typing import Any

from pymorembs.errors import UserError
from pymorembs.io.atomic import write_text
from pymorembs.job.app.runner import Run, start_run
from pymorembs.job.schema import Job, load_job


class RunController:
    """Start, follow and cancel the runs of the page's job.

    Parameters
    ----------
    workdir : Path, optional
        Where runs write (``job-1.toml``, ``run-1/``, ...); default a new temporary folder.

    Attributes
    ----------
    run : Run or None
        The last run started.
    runs : int
        How many runs were started (the number of the last one).
    """

    def __init__(self, workdir: Path | None = None) -> None:
        self.workdir = Path(workdir or tempfile.mkdtemp(prefix="pymorembs-app-")).resolve()
        self.workdir.mkdir(parents=True, exist_ok=True)
        self.lock = threading.Lock()
        self.run: Run | None = None
        self._started: tuple[Run, Job] | None = None
        self.runs = 0

    def start(self, valid_job: Callable[[], tuple[str, Job]]) -> dict[str, Any]:
        """Write the job into the work folder and run it (one run at a time).

        Parameters
        ----------
        valid_job : callable
            Gives the job file's TOML text and the same job parsed (its stage count sizes the
            progress bar), or raises :class:`UserError` when the job is not valid; called once
            no run is going on.
        """
        with self.lock:
            if self.run is not None and self.run.state == "running":
                raise UserError("a run is going on; cancel it first")
            if self.run is not None and self.run.alive:
                raise UserError("the cancelled run is still ending; run again in a moment")
            text, job = valid_job()
            self.runs += 1
            path = self.workdir / f"job-{self.runs}.toml"
            write_text(path, text)
            self.run = start_run(path, self.workdir / f"run-{self.runs}", job.stage_count())
            self._started = (self.run, job)
            return self.run.as_dict()

    def status(self) -> dict[str, Any]:
        """The run's progress (``{"state": "idle"}`` before the first run)."""
        return {"state": "idle"} if self.run is None else self.run.as_dict()

    def cancel(self) -> dict[str, Any]:
        """End the run going on, if any."""
        if self.run is not None:
            self.run.cancel()
        return self.status()

    def finished(self) -> Run:
        """The last run, finished (``"done"``, its results written).

        Raises
        ------
        UserError
            No run has finished yet (none started, or the last one runs, failed or was
            cancelled).
        """
        run = self.run
        if run is None or run.state != "done":
            raise UserError("no finished run yet")
        return run

    def job_of(self, run: Run) -> Job:
        """The parsed job of ``run``: the one it was started with (read from its job file when
        the run was not started here, e.g. handed in by a script)."""
        started = self._started
        if started is not None and started[0] is run:
            return started[1]
        return load_job(run.job)
