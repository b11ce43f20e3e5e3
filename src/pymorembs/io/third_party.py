"""One-line descriptions of exceptions raised by third-party readers (SciPy, h5py, ...).

The readers turn every exception of a library they call into a :class:`~pymorembs.errors.UserError`
of one line; :func:`reason` gives the text after the file name.
"""

from __future__ import annotations

__all__ = ["reason"]


def reason(err: BaseException) -> str:
    """One line describing a third-party exception, e.g. ``"ValueError: bad header"``."""
    text = " ".join(str(err).split())
    if isinstance(err, OSError) and err.strerror:
        text = err.strerror
    if isinstance(err, MemoryError):
        text = "not enough memory"
    kind = type(err).__name__
    if kind == "error":  # e.g. struct.error
        kind = f"{type(err).__module__}.error"
    return f"{kind}: {text}" if text else kind
