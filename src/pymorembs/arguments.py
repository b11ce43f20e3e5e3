"""Arguments given from Python: numbers and lists of numbers, as Python or NumPy values.

The API (:mod:`pymorembs.api`) and the method options (:mod:`pymorembs.methods`) take a number
as a Python ``int`` or ``float``, a NumPy scalar (``np.float64(500.0)``, ``np.int32(3)``) or a
0-d array, and a list of numbers as a list, a tuple or a 1-d NumPy array. The checkers here turn
each into plain Python values (``float``, ``int``, ``tuple``), so that what is built from them
compares, prints and serialises alike whatever the caller gave, and raise :class:`OptionError`
naming the argument for a value of the wrong type, shape or range -- one line, an array
described by its shape and type rather than printed.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from pymorembs.errors import UserError

__all__ = [
    "OptionError",
    "described",
    "flag",
    "frequencies",
    "node_ids",
    "number",
    "number_list",
    "plain",
    "whole",
    "whole_list",
]

#: Longest representation of a bad value quoted in a message (characters).
QUOTE_LIMIT = 60


class OptionError(UserError):
    """A bad option or argument; ``key`` names it (None: a missing combination of options)."""

    def __init__(self, key: str | None, problem: str) -> None:
        super().__init__(problem if key is None else f"{key}: {problem}")
        self.key = key
        self.problem = problem


def plain(value: Any) -> Any:
    """A NumPy scalar or 0-d array as the Python value it holds; anything else unchanged."""
    if isinstance(value, np.ndarray) and value.ndim == 0:
        return value.item()
    if isinstance(value, np.generic):
        return value.item()
    return value


def described(value: Any) -> str:
    """A bad value for a one-line message: an array by its shape and type, others by a
    ``repr`` cut to :data:`QUOTE_LIMIT` characters."""
    if isinstance(value, np.ndarray):
        return f"an array of shape {value.shape} ({value.dtype})"
    text = " ".join(repr(value).split())
    return text if len(text) <= QUOTE_LIMIT else text[: QUOTE_LIMIT - 3] + "..."


def number(key: str, value: Any, minimum: float | None = None) -> float | None:
    """A finite number (``>= minimum`` if given) as ``float``; None stays None."""
    value = plain(value)
    if value is None:
        return None
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise OptionError(key, f"must be a number, got {described(value)}")
    if not math.isfinite(value):
        raise OptionError(key, f"must be finite, got {value!r}")
    if minimum is not None and value < minimum:
        raise OptionError(key, f"must be >= {minimum}, got {value!r}")
    return float(value)


def whole(key: str, value: Any, minimum: int | None = 1) -> int | None:
    """A whole number (``>= minimum`` unless that is None) as ``int``; None stays None. A float
    is refused, also ``30.0``, as in a job file."""
    value = plain(value)
    if value is None:
        return None
    if isinstance(value, bool) or not isinstance(value, int):
        raise OptionError(key, f"must be a whole number, got {described(value)}")
    if minimum is not None and value < minimum:
        raise OptionError(key, f"must be >= {minimum}, got {value!r}")
    return int(value)


def flag(key: str, value: Any) -> bool:
    """``True`` or ``False`` (also ``np.bool_``)."""
    value = plain(value)
    if not isinstance(value, bool):
        raise OptionError(key, f"must be true or false, got {described(value)}")
    return value


def _items(key: str, value: Any, what: str) -> list[Any]:
    """The entries of a list, tuple or 1-d array as plain Python values."""
    if isinstance(value, np.ndarray):
        if value.ndim != 1:
            raise OptionError(key, f"must be {what}, got {described(value)}")
        return [plain(item) for item in value]
    if not isinstance(value, list | tuple):
        raise OptionError(key, f"must be {what}, got {described(value)}")
    return [plain(item) for item in value]


def number_list(
    key: str,
    value: Any,
    what: str = "a list of numbers",
    length: int | None = None,
    minimum: float | None = None,
) -> tuple[float, ...]:
    """A list, tuple or 1-d array of finite numbers (``>= minimum``), of ``length`` entries if
    given, as a tuple of floats. ``what`` says in the message what the argument must be."""
    items = _items(key, value, what)
    if length is not None and len(items) != length:
        raise OptionError(key, f"must be {what}, got {len(items)} values")
    for item in items:
        if isinstance(item, bool) or not isinstance(item, int | float) or not math.isfinite(item):
            raise OptionError(key, f"must be {what}, got an entry {described(item)}")
        if minimum is not None and item < minimum:
            raise OptionError(key, f"must be {what}, got {item!r}")
    return tuple(float(item) for item in items)


def whole_list(
    key: str, value: Any, what: str = "a list of whole numbers", minimum: int | None = None
) -> tuple[int, ...]:
    """A list, tuple or 1-d integer array of whole numbers (``>= minimum``) as a tuple of ints."""
    items = _items(key, value, what)
    for item in items:
        if isinstance(item, bool) or not isinstance(item, int):
            raise OptionError(key, f"must be {what}, got an entry {described(item)}")
        if minimum is not None and item < minimum:
            raise OptionError(key, f"must be {what}, got {item!r}")
    return tuple(int(item) for item in items)


def frequencies(key: str, value: Any) -> tuple[float, ...]:
    """A non-empty list of finite frequencies >= 0 in Hz (one number is a list of one)."""
    what = "a list of finite frequencies >= 0 in Hz"
    single = plain(value)
    if isinstance(single, int | float) and not isinstance(single, bool):
        value = [single]
    points = number_list(key, value, what, minimum=0.0)
    if not points:
        raise OptionError(key, f"must be {what}, got an empty list")
    return points


def node_ids(key: str, value: Any) -> list[int]:
    """Node ids: one whole number or a list, tuple or 1-d array of them, as a list of ints."""
    single = plain(value)
    if isinstance(single, int) and not isinstance(single, bool):
        return [int(single)]
    return list(whole_list(key, value, "node ids (whole numbers)"))
