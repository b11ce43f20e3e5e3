"""A text file as blocks of whole lines, for readers that parse lines with NumPy.

A reader that streams a large export (a 2 GB Nastran punch or OP4 file) holds one block of a few
megabytes at a time instead of the whole file, and finds its lines with one vectorised pass.
"""

from __future__ import annotations

import os
from collections.abc import Iterator

import numpy as np

__all__ = ["UTF8_BOM", "IrregularText", "iter_line_blocks", "line_starts"]

#: The UTF-8 byte order mark that Windows editors put at the start of a text file.
UTF8_BOM = b"\xef\xbb\xbf"

#: Bytes read at a time.
BLOCK_BYTES = 1 << 23


class IrregularText(Exception):
    """The file cannot be read, or has line ends other than ``\\n`` and ``\\r\\n``."""


def iter_line_blocks(
    path: str | os.PathLike[str], size: int = BLOCK_BYTES
) -> Iterator[tuple[np.ndarray, np.ndarray, int]]:
    """The file in blocks of whole lines: ``(text, ends, first)``.

    ``text`` is a read-only uint8 array of about ``size`` bytes that ends with a line feed (one
    is added after a last line without it); ``ends`` are the positions of its line feeds, so line
    ``k`` of the block is ``text[ends[k - 1] + 1 : ends[k]]``; ``first`` is the index (from 0)
    of the block's first line in the file. A UTF-8 byte order mark is dropped and ``\\r\\n``
    becomes ``\\n``.

    Raises
    ------
    IrregularText
        The file cannot be opened or read, or holds a carriage return not followed by a line
        feed (a line end of its own for Python's ``splitlines``): the caller reads such a file
        with its strict parser, which has the message.
    """
    try:
        f = open(path, "rb")  # closed by the with block below
    except OSError:
        raise IrregularText from None
    with f:
        carry, first, start = b"", 0, True
        while True:
            try:
                data = f.read(size)
            except OSError:
                raise IrregularText from None
            if start:
                data = data.removeprefix(UTF8_BOM)
            start = False
            if not data:
                if not carry:
                    return
                data, carry = carry + b"\n", b""
            elif carry:
                data = carry + data
            cut = data.rfind(b"\n") + 1
            if cut == 0:
                carry = data
                continue
            block, carry = data[:cut], data[cut:]
            del data
            if b"\r" in block:
                if block.count(b"\r") != block.count(b"\r\n"):
                    raise IrregularText
                block = block.replace(b"\r\n", b"\n")
            text = np.frombuffer(block, dtype=np.uint8)
            ends = np.flatnonzero(text == 10)
            yield text, ends, first
            first += ends.size


def line_starts(ends: np.ndarray) -> np.ndarray:
    """Start positions of the lines whose line feeds are at ``ends``."""
    starts = np.empty(ends.size, dtype=np.int64)
    starts[:1] = 0
    starts[1:] = ends[:-1] + 1
    return starts
