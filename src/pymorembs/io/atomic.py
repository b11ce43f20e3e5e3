"""Atomic file writing: a file is either written completely or not touched at all.

Every file pymorembs writes goes through :func:`atomic_path` (or one of the helpers built on it).
The data are written to a temporary file in the directory of the target and moved onto the target
with :func:`os.replace` only when writing succeeded, so a reader never sees a half-written file
and an existing file survives a failed write unchanged::

    with atomic_path("out/K.mtx") as tmp:
        scipy.io.mmwrite(tmp, matrix)          # any writer that takes a path

    with atomic_open("out/dofs.csv") as fh:    # a text (or binary) file object
        fh.write("node,direction\\n")

    write_text("out/summary.txt", text)        # one call for text or bytes
    write_bytes("out/picture.png", data)

The temporary file is named ``.<stem>.<random>.tmp<suffix>`` (hidden, and it keeps the target's
extension so writers that choose the format from the extension, like Matplotlib's ``savefig``,
still work). It is created with the permissions of a new file (``0o666`` minus the umask); when the
target exists already its permission bits are kept.
"""

from __future__ import annotations

import os
import secrets
import stat
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import IO, Any

from pymorembs.errors import UserError

__all__ = ["atomic_open", "atomic_path", "check_output_folder", "write_bytes", "write_text"]


@contextmanager
def atomic_path(target: str | os.PathLike[str], *, fsync: bool = True) -> Iterator[Path]:
    """Yield a temporary path next to ``target``; move it onto ``target`` on success.

    Parameters
    ----------
    target : path-like
        The file to write. Its directory must exist.
    fsync : bool
        Flush the temporary file to disk before the move (default), so that after a crash the
        target holds either the old or the complete new content.

    Yields
    ------
    Path
        An empty file in the directory of ``target``, created for this call. Write to it (or
        replace it) inside the ``with`` block.

    Raises
    ------
    UserError
        The temporary file cannot be created or moved onto the target (missing directory, no
        permission, target is a directory).

    Notes
    -----
    If the ``with`` block raises, the temporary file is deleted, the exception propagates and the
    target is left as it was (absent, or with its old content).
    """
    target = Path(target)
    tmp = _create_temporary(target)
    try:
        yield tmp
        if fsync:
            _fsync(tmp)
        _keep_mode(target, tmp)
        try:
            os.replace(tmp, target)
        except OSError as err:
            raise UserError(f"{target}: cannot write: {_reason(err)}") from None
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise


@contextmanager
def atomic_open(
    target: str | os.PathLike[str],
    mode: str = "w",
    *,
    encoding: str | None = "utf-8",
    newline: str | None = "\n",
    fsync: bool = True,
) -> Iterator[IO[Any]]:
    """Open a file object whose content replaces ``target`` when the block ends without error.

    Parameters
    ----------
    target : path-like
        The file to write.
    mode : {"w", "wb"}
        Text or binary writing.
    encoding, newline : str or None
        As for :func:`open` in text mode (ignored for ``"wb"``); the default writes UTF-8 with
        ``\\n`` line ends on every platform.
    fsync : bool
        See :func:`atomic_path`.
    """
    if mode not in ("w", "wb"):
        raise ValueError(f"atomic_open: mode must be 'w' or 'wb', not {mode!r}")
    with atomic_path(target, fsync=fsync) as tmp:
        if mode == "wb":
            with open(tmp, "wb") as fh:
                yield fh
        else:
            with open(tmp, "w", encoding=encoding, newline=newline) as fh:
                yield fh


def write_text(target: str | os.PathLike[str], text: str, *, encoding: str = "utf-8") -> Path:
    """Write ``text`` atomically to ``target`` (``\\n`` line ends); return the target path."""
    with atomic_open(target, "w", encoding=encoding) as fh:
        fh.write(text)
    return Path(target)


def write_bytes(target: str | os.PathLike[str], data: bytes) -> Path:
    """Write ``data`` atomically to ``target``; return the target path."""
    with atomic_open(target, "wb") as fh:
        fh.write(data)
    return Path(target)


def check_output_folder(folder: str | os.PathLike[str]) -> Path:
    """Check before any work that ``folder`` can be (or already is) a writable folder.

    Parameters
    ----------
    folder : path-like
        The output folder; it need not exist, nor its parents.

    Returns
    -------
    Path
        ``folder`` as a path.

    Raises
    ------
    UserError
        ``folder`` or one of its parents is an existing file, or the nearest existing folder is
        not writable (one line; a job then stops before reading its model).
    """
    folder = Path(folder)
    existing = folder
    while not existing.exists() and existing != existing.parent:
        if existing.is_symlink():  # a dangling link: cannot be made a folder
            raise UserError(f"{folder}: the output folder lies at the broken link {existing}")
        existing = existing.parent
    if not existing.is_dir():
        what = "is an existing file" if existing == folder else f"lies below the file {existing}"
        raise UserError(f"{folder}: the output folder {what}")
    if not os.access(existing, os.W_OK | os.X_OK):
        raise UserError(f"{folder}: cannot write the output folder: {existing} is not writable")
    return folder


def _create_temporary(target: Path) -> Path:
    """Create an empty, not yet existing file next to ``target`` and return its path."""
    for _ in range(100):
        tmp = target.with_name(f".{target.stem}.{secrets.token_hex(4)}.tmp{target.suffix}")
        try:
            fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o666)
        except FileExistsError:
            continue
        except OSError as err:
            raise UserError(f"{target}: cannot write: {_reason(err)}") from None
        os.close(fd)
        return tmp
    raise UserError(f"{target}: cannot write: no free temporary file name")  # pragma: no cover


def _fsync(path: Path) -> None:
    """Flush ``path`` to disk; silently skipped where the platform cannot do it."""
    try:
        fd = os.open(path, os.O_RDONLY)
    except OSError:
        return
    try:
        os.fsync(fd)
    except OSError:  # pragma: no cover - e.g. file systems without fsync
        pass
    finally:
        os.close(fd)


def _keep_mode(target: Path, tmp: Path) -> None:
    """Give ``tmp`` the permission bits of an existing ``target``."""
    try:
        mode = stat.S_IMODE(target.stat().st_mode)
    except OSError:
        return
    try:
        os.chmod(tmp, mode)
    except OSError:  # pragma: no cover - e.g. not the owner; the default mode is fine
        pass


def _reason(err: OSError) -> str:
    """The operating system's short reason for ``err`` (one line)."""
    return err.strerror or type(err).__name__
