"""pyNastran's OP2 reader, importable with the NumPy of this project.

pyNastran 1.4.1 (the pinned version) binds ``numpy.in1d`` at import time in two modules of its
OP2 reader (``op2_interface/transforms.py`` and ``tables/ogf_gridPointForces/ogf_objects.py``);
NumPy 2.4 removed ``in1d``, so ``import pyNastran.op2.op2`` fails with an ``AttributeError``.
That name is the only one missing (checked with ``grep -rn "np\\.in1d" pyNastran/``).
:func:`op2_class` puts an equivalent ``numpy.in1d`` (``numpy.isin`` on the flattened first
argument, which is what ``in1d`` was) into NumPy only when it is missing, right before importing
the reader -- nowhere else. It also gives a logger that stays silent, so that pyNastran prints
nothing on the terminal.
"""

from __future__ import annotations

from typing import Any

import numpy as np

__all__ = ["op2_class", "quiet_logger"]


def _in1d(ar1: Any, ar2: Any, assume_unique: bool = False, invert: bool = False) -> np.ndarray:
    """``numpy.in1d`` as NumPy < 2.4 had it: membership of the flattened ``ar1`` in ``ar2``."""
    return np.isin(np.ravel(ar1), ar2, assume_unique=assume_unique, invert=invert)


def op2_class() -> type:
    """The class ``pyNastran.op2.op2.OP2`` (raises ``ImportError`` without pyNastran)."""
    if not hasattr(np, "in1d"):
        np.in1d = _in1d  # type: ignore[attr-defined]  # noqa: NPY201 (the shim itself)
    from pyNastran.op2.op2 import OP2

    return OP2


def quiet_logger() -> Any:
    """A pyNastran logger that prints nothing below CRITICAL."""
    from cpylog import SimpleLogger

    return SimpleLogger(level="critical")
