"""Compressed model files (``.gz``, ``.bz2``, ``.xz``), read as if they were plain.

Every reader of pymorembs takes the path of a plain file (some map it into memory, hand it to a
compiled parser or to a library), so a compressed file is decompressed into a temporary folder
first and its reader gets the copy (:class:`PlainCopies`, used by
:func:`pymorembs.io.formats.read_body`); the folder is removed when the reading ends, also on an
error. Messages and notes that name the copy name the compressed file instead.

What counts as compressed is told from the content (the magic bytes of gzip, bzip2 and xz), not
from the name; the name without its compression suffix (``K.mtx`` for ``K.mtx.gz``) is the
name of the copy, so that readers which look at suffixes or derive a body name from the file
name see what they would see for the plain file. A copy lies in a folder of the same name as the
compressed file's folder (a reader that names the body after its folder sees that name).
``*INCLUDE`` and ``INCLUDE`` files of a compressed input deck are looked up beside the
compressed file (:func:`original_path`).

A damaged or truncated archive is a :class:`~pymorembs.errors.UserError` naming the file; so is a
temporary folder that cannot take the copy (a full disk), naming the folder.
"""

from __future__ import annotations

import bz2
import contextvars
import gzip
import lzma
import os
import shutil
import tempfile
import zlib
from collections.abc import Callable
from pathlib import Path
from typing import IO, Any

from pymorembs.errors import UserError, located_error
from pymorembs.io.atomic import atomic_path

__all__ = [
    "COMPRESSIONS",
    "DECOMPRESSION_ERRORS",
    "PlainCopies",
    "compression",
    "damaged_file_error",
    "open_plain",
    "original_path",
    "plain_path",
]

PathLike = str | os.PathLike[str]

#: The compressions read: name -> (file suffix, opener of a binary stream).
COMPRESSIONS: dict[str, tuple[str, Callable[..., IO[bytes]]]] = {
    "gzip": (".gz", gzip.open),
    "bzip2": (".bz2", bz2.open),
    "xz": (".xz", lzma.open),
}
_GZIP = b"\x1f\x8b"
_XZ = b"\xfd7zXZ\x00"
#: bzip2: "BZh", the block size digit, then the magic of the first block or of the stream end.
_BZIP2_BLOCKS = (b"1AY&SY", b"\x17rE8P\x90")
#: Bytes copied at a time.
_CHUNK = 1 << 20
#: What the decompressors raise on a damaged or truncated file (``bz2`` raises ``OSError``
#: without an error number).
DECOMPRESSION_ERRORS = (EOFError, lzma.LZMAError, zlib.error, gzip.BadGzipFile, OSError)

#: The compressed file of each plain copy being read (see :func:`original_path`).
_ORIGINALS: contextvars.ContextVar[dict[Path, Path] | None] = contextvars.ContextVar(
    "pymorembs_plain_copies", default=None
)


def compression(path: PathLike) -> str | None:
    """The compression of a file (a key of :data:`COMPRESSIONS`) told from its first bytes, or
    None for a plain file (or one that cannot be read: its reader then says why)."""
    try:
        with open(path, "rb") as stream:
            head = stream.read(16)
    except OSError:
        return None
    return _compression_of(head)


def _compression_of(head: bytes) -> str | None:
    if head.startswith(_GZIP):
        return "gzip"
    if head.startswith(_XZ):
        return "xz"
    if head[:3] == b"BZh" and head[3:4].isdigit() and head[3:4] != b"0":
        if head[4:10] in _BZIP2_BLOCKS:
            return "bzip2"
    return None


def plain_path(path: PathLike) -> Path:
    """``path`` without a compression suffix (``K.mtx.gz`` -> ``K.mtx``; any case)."""
    path = Path(path)
    suffixes = {suffix for suffix, _ in COMPRESSIONS.values()}
    if path.suffix.lower() in suffixes and path.stem:
        return path.with_suffix("")
    return path


def open_plain(path: PathLike) -> IO[bytes]:
    """A binary stream of the content of a file, decompressed if it is compressed.

    Raises
    ------
    OSError
        The file cannot be opened (the caller words the message).
    """
    kind = compression(path)
    if kind is None:
        return open(path, "rb")
    return COMPRESSIONS[kind][1](path, "rb")


def original_path(path: PathLike) -> Path:
    """The compressed file a plain copy was made from, or ``path`` itself.

    Readers that follow include files resolve them beside this path, so that a compressed deck
    finds its include files where the user keeps them.
    """
    originals = _ORIGINALS.get()
    if not originals:
        return Path(path)
    return originals.get(Path(path), Path(path))


class PlainCopies:
    """Plain copies of the compressed files among the paths of a reader's options.

    Use as a context manager around the reading::

        with PlainCopies({"stiffness": k, "mass": m}) as copies:
            body = read(**copies.paths)
            notes = [copies.named(note) for note in body.notes]

    A :class:`~pymorembs.errors.UserError` raised in the block leaves it with the paths of the
    copies replaced by those of the compressed files (:meth:`named`); the copies are removed
    when the block ends.

    Parameters
    ----------
    paths : dict of str -> path-like
        Option name -> file; files that are not compressed (and folders) stay as they are.

    Attributes
    ----------
    paths : dict of str -> Path
        The same options, compressed files replaced by their plain copies.
    """

    def __init__(self, paths: dict[str, PathLike]) -> None:
        self._given = {key: Path(value) for key, value in paths.items()}
        self.paths: dict[str, Path] = dict(self._given)
        self._folder: Path | None = None
        self._copies: dict[Path, Path] = {}  # copy -> compressed file
        self._token: contextvars.Token | None = None

    def __enter__(self) -> PlainCopies:
        try:
            for key, path in self._given.items():
                kind = compression(path) if path.is_file() else None
                if kind is not None:
                    self.paths[key] = self._copy(path, kind)
        except BaseException:
            self._remove()
            raise
        self._token = _ORIGINALS.set({**(_ORIGINALS.get() or {}), **self._copies})
        return self

    def __exit__(self, kind: type[BaseException] | None, error: BaseException | None, _: Any):
        if self._token is not None:
            _ORIGINALS.reset(self._token)
            self._token = None
        self._remove()
        if isinstance(error, UserError) and self._copies:
            raise UserError(self.named(str(error))) from None
        return False

    @property
    def compressed(self) -> bool:
        """Whether any file was compressed."""
        return bool(self._copies)

    def named(self, text: str) -> str:
        """``text`` with every path of a copy replaced by the compressed file's path."""
        for copy, original in self._copies.items():
            text = text.replace(str(copy), str(original))
            text = text.replace(str(copy.parent) + os.sep, str(original.parent) + os.sep)
        return text

    def _copy(self, path: Path, kind: str) -> Path:
        """Decompress ``path`` into the temporary folder; the copy's path."""
        if self._folder is None:
            self._folder = Path(tempfile.mkdtemp(prefix="pymorembs-plain-"))
        folder = self._folder / str(len(self._copies)) / (path.resolve().parent.name or "files")
        target = folder / plain_path(path).name
        if target == path.resolve():  # pragma: no cover - a copy never lies beside its file
            raise UserError(f"{path}: cannot decompress the file onto itself")
        try:
            folder.mkdir(parents=True)
            source = COMPRESSIONS[kind][1](path, "rb")
        except OSError as err:
            raise located_error(
                self._folder, None, f"cannot decompress {path} here: {err.strerror or err}"
            ) from None
        with source, atomic_path(target, fsync=False) as tmp, open(tmp, "wb") as out:
            while True:
                try:
                    chunk = source.read(_CHUNK)
                except DECOMPRESSION_ERRORS as err:
                    raise damaged_file_error(path, err) from None
                if not chunk:
                    break
                try:
                    out.write(chunk)
                except OSError as err:
                    raise located_error(
                        self._folder,
                        None,
                        f"cannot decompress {path} into this temporary folder: "
                        f"{err.strerror or err} (set TMPDIR to a folder with room)",
                    ) from None
        self._copies[target] = path
        return target

    def _remove(self) -> None:
        if self._folder is not None:
            shutil.rmtree(self._folder, ignore_errors=True)
            self._folder = None


def damaged_file_error(path: PathLike, err: BaseException) -> UserError:
    """The one-line error for an exception of :data:`DECOMPRESSION_ERRORS` while reading the
    compressed file ``path``: a damaged or truncated file, or (an ``OSError`` with an error
    number) a read error."""
    if isinstance(err, OSError) and err.errno is not None:
        return located_error(path, None, f"cannot read: {err.strerror or err}")
    kind = compression(path) or "compressed"
    if isinstance(err, EOFError):
        reason = "the file ends before the end of the compressed data"
    else:
        reason = " ".join(str(err).split()) or type(err).__name__
    return located_error(path, None, f"a damaged or truncated {kind} file ({reason})")
