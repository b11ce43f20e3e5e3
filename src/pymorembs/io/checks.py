"""Helpers shared by the readers (public names, one place).

:func:`make_body` builds an :class:`~pymorembs.body.ElasticBody` and puts the file name in front
of its consistency errors; :func:`reason` turns an exception of a third-party library (pyNastran,
ansys-mapdl-reader) into one readable line; :func:`require_file` refuses a missing, empty or
unreadable file before a third-party reader sees it.
"""

from __future__ import annotations

from pathlib import Path

from pymorembs.body import ElasticBody
from pymorembs.errors import UserError

__all__ = ["make_body", "reason", "require_file"]


def make_body(source: Path, **fields: object) -> ElasticBody:
    """``ElasticBody(**fields)``; its :class:`UserError` gets ``source:`` in front."""
    try:
        return ElasticBody(**fields)  # type: ignore[arg-type]
    except UserError as err:
        raise UserError(f"{source}: {err}") from None


def reason(err: BaseException) -> str:
    """One line describing an exception, e.g. ``"struct.error: unpack requires 4 bytes"``."""
    if isinstance(err, MemoryError):
        text = "not enough memory"
    elif isinstance(err, OSError) and err.strerror:
        text = err.strerror
    else:
        text = " ".join(str(err).split())
    kind = type(err).__name__
    if kind == "error":  # e.g. struct.error
        kind = f"{type(err).__module__}.error"
    return f"{kind}: {text}" if text else kind


def require_file(path: Path, kind: str) -> None:
    """Raise :class:`UserError` unless ``path`` is a non-empty readable file (``kind``: what)."""
    try:
        if not path.is_file():
            what = "is a directory" if path.is_dir() else "file not found"
            raise UserError(f"{path}: {what} (expected {kind})")
        if path.stat().st_size == 0:
            raise UserError(f"{path}: empty file (expected {kind})")
    except OSError as err:
        raise UserError(f"{path}: cannot read: {reason(err)}") from None
