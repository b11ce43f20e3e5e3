"""Exception classes shared by the library and the command line.

The command line maps them to exit codes: :class:`UserError` -> 2 (a mistake in the input, reported
in one line), :class:`NumericalError` -> 3 (the numbers of a valid input defeat an algorithm),
:class:`AccuracyNotMet` -> 4 (a job ran to its end, but a reduced body misses its accuracy limit),
any other exception -> 1 (a bug, with traceback).
"""

from typing import Any


class PymorembsError(Exception):
    """Base class of all errors pymorembs raises on purpose."""

    exit_code = 1


class UserError(PymorembsError):
    """Bad input: a wrong file, an unknown node, an impossible option.

    The message is one line that names the file or key and what is wrong.
    """

    exit_code = 2


class NumericalError(PymorembsError):
    """A numerical failure on valid input (singular factorization, no convergence...)."""

    exit_code = 3


class AccuracyNotMet(PymorembsError):
    """A job ran to its end, but at least one reduced body's error exceeds its limit.

    Raised after the job's output folder was written: ``summary.json``, the error curves and
    plots (and the report) are the evidence; the body files of the reductions that missed their
    limit were not written (unless the job allowed it, ``export_inaccurate = true``, which does
    not raise). The message is one line naming the reductions, their errors and limits.

    Attributes
    ----------
    summary : pymorembs.job.summary.JobSummary
        The job's summary, written to ``summary.json`` (its ``to_json``).
    """

    exit_code = 4

    def __init__(self, message: str, summary: Any) -> None:
        super().__init__(message)
        self.summary = summary


def located_error(path: object, line: int | None, message: str) -> UserError:
    """A one-line :class:`UserError` ``path:line: message`` (``path: message`` without a line).

    Line breaks in ``message`` become spaces, so the error stays one line.
    """
    where = str(path) if line is None else f"{path}:{line}"
    return UserError(f"{where}: {' '.join(message.splitlines())}")
