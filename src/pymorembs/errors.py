"""Exception classes shared by the library and the command line.

The command line maps them to exit codes: :class:`UserError` -> 2 (a mistake in the input, reported
in one line), :class:`NumericalError` -> 3 (the numbers of a valid input defeat an algorithm), any
other exception -> 1 (a bug, with traceback).
"""


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


def located_error(path: object, line: int | None, message: str) -> UserError:
    """A one-line :class:`UserError` ``path:line: message`` (``path: message`` without a line).

    Line breaks in ``message`` become spaces, so the error stays one line.
    """
    where = str(path) if line is None else f"{path}:{line}"
    return UserError(f"{where}: {' '.join(message.splitlines())}")
