"""Vectorised checks and conversions shared by the text readers.

The readers parse the bulk of their numbers with compiled parsers (fast_matrix_market through
``scipy.io.mmread``, NumPy's ``loadtxt``). Such parsers are lenient in ways pymorembs is not:
fast_matrix_market, for example, ignores whatever follows the third number of a line, so
``1 1 1.0D+03`` reads as 1.0, ``1 1 1,5`` (a decimal comma) as 1.0 and ``1 1 1.0 2.0`` as 1.0.
:func:`count_plain_fields` checks cheaply, with NumPy over the raw bytes, that a region of a
file holds nothing such a parser misreads (the exceptions are listed there), so that a reader
can take the fast result or else fall back to its strict line-by-line pass, which then names the
bad line.
"""

from __future__ import annotations

import itertools
import os
from concurrent.futures import Future, ThreadPoolExecutor

import numpy as np
import scipy.sparse as sp

__all__ = [
    "PLAIN_NUMBER_BYTES",
    "count_plain_fields",
    "csr_from_sorted_coo",
]

#: The bytes of plain decimal numbers (``-1.5e+03``) and of the white space between them.
PLAIN_NUMBER_BYTES = b"0123456789.eE+- \t\r\n"

#: Bytes scanned at a time: small enough to stay in the caches, large enough for NumPy.
_CHUNK = 1 << 20
#: Bytes of the previous chunk kept in front of the next one (for the checks of byte pairs and
#: triples that cross a chunk boundary).
_CARRY = 2


def count_plain_fields(path: str | os.PathLike[str], offset: int = 0) -> int | None:
    """Number of white-space separated plain numeric fields in a file from byte ``offset`` on.

    Returns None when the region holds

    * any byte but ``0123456789.eE+-`` and white space (space, tab, carriage return, line feed):
      a letter as in ``1.0D+03`` or ``nan``, a comma, a comment sign, a NUL byte, non-ASCII text;
    * a sign directly after a digit or a decimal point (``0.12-105``, a Fortran exponent without
      its letter, which lenient parsers read as 0.12);
    * an exponent letter without digits (``1.5e``, ``1.5e+``; e.g. a number cut short at the end
      of a truncated file);

    or when the file cannot be read. Together with a parser that reads one number per field and
    stops at the first byte that cannot continue a number, it proves that every number was read
    whole, except for numbers malformed in their points and exponent letters alone (``1.0.5``,
    ``1e5e5``, ``1e5.0``: such a parser reads the valid front part) and a decimal fraction in a
    field that must hold an integer (whether a field is an integer depends on its place in the
    line, which these checks do not see). Finding those needs the field structure of every line
    and would double the cost of the scan.

    The scan runs over chunks of the file: one ``bytes.translate`` pass per chunk, and a few
    NumPy comparisons per byte in a second thread, on the previous chunk, meanwhile.

    Parameters
    ----------
    path : path-like
        The file.
    offset : int
        Byte offset of the region (e.g. the first byte after a header).

    Returns
    -------
    int or None
        Number of fields (maximal runs of non-white-space bytes), or None as described.
    """
    slots = [_Slot() for _ in range(2)]  # one chunk is checked while the next one is read
    carry = b" " * _CARRY  # the bytes before the region count as white space
    fields = 0
    pending: list[Future[int | None]] = []
    try:
        with open(path, "rb", buffering=0) as stream, ThreadPoolExecutor(1) as worker:
            stream.seek(offset)
            for index in itertools.count():
                slot = slots[index % 2]
                if len(pending) == 2:  # the slot's previous chunk must be done
                    result = pending.pop(0).result()
                    if result is None:
                        return None
                    fields += result
                slot.buffer[:_CARRY] = carry
                size = stream.readinto(slot.view[_CARRY:])
                if not size:
                    break
                end = _CARRY + size
                chunk = slot.buffer if size == _CHUNK else bytes(slot.buffer[:end])
                if chunk.translate(None, PLAIN_NUMBER_BYTES):
                    return None  # a byte that is not part of a plain number or white space
                carry = bytes(slot.buffer[end - _CARRY : end])
                pending.append(worker.submit(slot.check, end))
            for job in pending:
                result = job.result()
                if result is None:
                    return None
                fields += result
    except OSError:
        return None
    # the region ends as if followed by white space: an exponent cut short at the very end
    if carry.lower().endswith((b"e", b"e+", b"e-")):
        return None
    return fields


class _Slot:
    """A chunk buffer of :func:`count_plain_fields` with the scratch arrays of its checks."""

    def __init__(self) -> None:
        self.buffer = bytearray(_CARRY + _CHUNK)
        self.view = memoryview(self.buffer)
        self.data = np.frombuffer(self.buffer, dtype=np.uint8)
        self.white, self.sign, self.other, self.pair = (
            np.empty(len(self.buffer), dtype=bool) for _ in range(4)
        )
        self.scratch = np.empty_like(self.data)

    def check(self, end: int) -> int | None:
        """Fields starting in ``buffer[_CARRY:end]`` (the carry holds the bytes before), or
        None at a sign after a digit or point or an exponent letter without digits."""
        u = self.data[:end]
        w = np.less_equal(u, 32, out=self.white[:end])
        fields = int(np.count_nonzero(w[_CARRY - 1 : end - 1] > w[_CARRY:end]))
        # a sign (0x2B, 0x2D: the only plain bytes with b & 0xF9 == 0x29) after a digit or a
        # point (0x2E .. 0x39, less the absent '/')
        s = np.equal(np.bitwise_and(u, 0xF9, out=self.scratch[:end]), 0x29, out=self.sign[:end])
        d = np.less_equal(np.subtract(u, 46, out=self.scratch[:end]), 11, out=self.other[:end])
        if np.any(np.logical_and(s[1:], d[:-1], out=self.pair[: end - 1])):
            return None
        # an exponent letter followed by white space, or by a sign and white space
        e = np.equal(np.bitwise_or(u, 0x20, out=self.scratch[:end]), 0x65, out=self.other[:end])
        if np.any(np.logical_and(e[:-1], w[1:], out=self.pair[: end - 1])):
            return None
        triple = np.logical_and(e[:-2], s[1:-1], out=self.pair[: end - 2])
        if np.any(np.logical_and(triple, w[2:], out=triple)):
            return None
        return fields


def csr_from_sorted_coo(
    rows: np.ndarray, cols: np.ndarray, values: np.ndarray, n: int
) -> sp.csr_matrix | None:
    """The ``n`` x ``n`` CSR matrix of coordinate entries in strict row-major order, or None.

    Matrices written by FE programs and by pymorembs itself list their entries row by row with
    increasing columns; then the CSR arrays are the column and value arrays themselves plus a
    row pointer, with no sort and no copy. None is returned when the entries are not strictly
    increasing in (row, column) order (unsorted, or an entry given twice), so that the caller
    can use the general conversion.

    Parameters
    ----------
    rows, cols : ndarray of int, shape (nnz,)
        Row and column indices counted from 0, within ``0 .. n - 1``.
    values : ndarray of float, shape (nnz,)
    n : int
        Matrix size.

    Returns
    -------
    scipy.sparse.csr_matrix or None
        Canonical (sorted, no duplicates); explicit zeros are kept.
    """
    index = np.int32 if max(n, rows.size) < 2**31 - 1 else np.int64
    for start in range(0, rows.size - 1, _CHUNK):  # in blocks that stay in the caches
        r = rows[start : start + _CHUNK + 1]
        c = cols[start : start + _CHUNK + 1]
        step = r[1:] > r[:-1]
        if not np.all(step | ((r[1:] == r[:-1]) & (c[1:] > c[:-1]))):
            return None
    indptr = np.searchsorted(rows, np.arange(n + 1, dtype=rows.dtype)).astype(index)
    matrix = sp.csr_matrix(
        (values, cols.astype(index, copy=False), indptr), shape=(n, n), copy=False
    )
    matrix.has_sorted_indices = True
    matrix.has_canonical_format = True
    return matrix
