"""pyNastran's OP2 reader, importable with the NumPy of this project, without changing NumPy.

pyNastran 1.4.1 (the pinned version) binds ``numpy.in1d`` when its modules are imported
(``in1d = np.in1d`` in ``op2_interface/transforms.py``, ``tables/ogf_gridPointForces/
ogf_objects.py`` and ``bdf/bdf.py``; ``from numpy import in1d`` in ``op2/vector_utils.py``);
NumPy 2.4 removed ``in1d``, so ``import pyNastran.op2.op2`` fails with an ``AttributeError``.
That name is the only one missing (checked with ``grep -rn "in1d" pyNastran/``).
:func:`numpy_with_in1d` gives NumPy an equivalent ``in1d`` (``numpy.isin`` on the flattened
first argument, which is what ``in1d`` was) for one block only, where it is missing, and takes
it away again when the block ends: the calls into pyNastran (:func:`op2_class`, the reading of
a file in :mod:`pymorembs.io.nastran_op2`) run inside it, the rest of the process sees NumPy as
it is. :func:`quiet_logger` gives a logger that stays silent, so that pyNastran prints nothing
on the terminal.
"""

from __future__ import annotations

import contextlib
from collections.abc import Iterator
from typing import Any

import numpy as np

__all__ = ["numpy_with_in1d", "op2_class", "quiet_logger"]


def _in1d(ar1: Any, ar2: Any, assume_unique: bool = False, invert: bool = False) -> np.ndarray:
    """``numpy.in1d`` as NumPy < 2.4 had it: membership of the flattened ``ar1`` in ``ar2``."""
    return np.isin(np.ravel(ar1), ar2, assume_unique=assume_unique, invert=invert)


@contextlib.contextmanager
def numpy_with_in1d() -> Iterator[None]:
    """``numpy.in1d`` for the block: NumPy's own where it has one, else the equivalent
    :func:`_in1d`, removed again when the block ends (also on an exception)."""
    if hasattr(np, "in1d"):
        yield
        return
    np.in1d = _in1d  # type: ignore[attr-defined]  # noqa: NPY201 (the shim itself)
    try:
        yield
    finally:
        del np.in1d  # type: ignore[attr-defined]  # noqa: NPY201


def op2_class() -> type:
    """The class ``pyNastran.op2.op2.OP2`` (raises ``ImportError`` without pyNastran).

    Its modules are imported with :func:`numpy_with_in1d`; reading a file with it may import
    more of pyNastran, so read inside :func:`numpy_with_in1d` too.
    """
    with numpy_with_in1d():
        from pyNastran.op2.op2 import OP2

    return OP2


def quiet_logger() -> Any:
    """A pyNastran logger that prints nothing below CRITICAL."""
    from cpylog import SimpleLogger

    return SimpleLogger(level="critical")
