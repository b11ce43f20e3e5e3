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
#: Threads that check chunks while the calling thread reads and translates the next one.
_WORKERS = 2
#: Bytes of the previous chunk kept in front of the next one (for the checks of byte pairs and
#: triples that cross a chunk boundary).
_CARRY = 2


def count_plain_fields(path: str | os.PathLike[str], offset: int = 0) -> int | None:
    """Number of white-space separated plain numeric fields in a file from byte ``offset`` on.

    Returns None when the region holds

    * any byte but ``0123456789.eE+-`` and white space (space, tab, carriage return, line feed):
      a letter as in ``1.0D+03`` or ``nan``, a comma, a comment sign, a NUL byte, non-ASCII text;
    * a sign directly after a digit or a decimal point (``0.12-105``, a Fortran exponent without
      its letter, which lenient parsers read as 0.12) or not followed by a digit or a point;
    * an exponent letter not followed by a digit or a sign (``1.5e``, ``1e.5``, ``1ee5``; e.g. a
      number cut short at the end of a truncated file);

    or when the file cannot be read. Together with a parser that reads one number per field and
    stops at the first byte that cannot continue a number, it proves that every number was read
    whole, except for a second decimal point or exponent in a number (``1.0.5``, ``1e5e5``,
    ``1e5.0``: such a parser reads the valid front part) and a decimal fraction in a
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
    try:
        size = os.path.getsize(path) - offset
    except OSError:
        return None
    if size <= _CHUNK:  # one chunk: checked here, without threads
        slot = _Slot(max(size, 0))
        try:
            with open(path, "rb", buffering=0) as stream:
                stream.seek(offset)
                size = stream.readinto(slot.view[_CARRY:])
        except OSError:
            return None
        chunk = bytes(slot.buffer[_CARRY : _CARRY + size])
        if chunk.translate(None, PLAIN_NUMBER_BYTES) or chunk[-1:] in (b"+", b"-", b"e", b"E"):
            return None
        return slot.check(_CARRY + size)
    slots = [_Slot(_CHUNK) for _ in range(_WORKERS + 1)]  # chunks are checked while one is read
    carry = b" " * _CARRY  # the bytes before the region count as white space
    fields = 0
    pending: list[Future[int | None]] = []
    try:
        with open(path, "rb", buffering=0) as stream, ThreadPoolExecutor(_WORKERS) as worker:
            stream.seek(offset)
            for index in itertools.count():
                slot = slots[index % len(slots)]
                if len(pending) == len(slots):  # the slot's previous chunk must be done
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
    # the last byte is followed by nothing: a sign or exponent letter there is cut short
    if carry[-1:] in (b"+", b"-", b"e", b"E"):
        return None
    return fields


class _Slot:
    """A chunk buffer of :func:`count_plain_fields` with the scratch arrays of its checks."""

    def __init__(self, size: int) -> None:
        self.buffer = bytearray(b" " * _CARRY + bytes(size))  # white space before the region
        self.view = memoryview(self.buffer)
        self.data = np.frombuffer(self.buffer, dtype=np.uint8)
        self.white, self.sign, self.other = (
            np.empty(len(self.buffer), dtype=bool) for _ in range(3)
        )
        self.scratch = np.empty_like(self.data)

    def check(self, end: int) -> int | None:
        """Fields starting in ``buffer[_CARRY:end]`` (the carry holds the two bytes before),
        or None at a sign or exponent letter in the wrong place (see
        :func:`count_plain_fields`). A sign or exponent letter in the last byte is checked
        with the next chunk (or at the end of the region), where it lies in the carry."""
        u = self.data[:end]
        w = np.less_equal(u, 32, out=self.white[:end])
        fields = int(np.count_nonzero(w[_CARRY - 1 : end - 1] > w[_CARRY:end]))
        # signs (0x2B, 0x2D: the plain bytes with b & 0xF9 == 0x29) and exponent letters
        # (0x45, 0x65: b & 0xDF == 0x45); their neighbours are checked where they are
        scratch, sign, other = self.scratch[:end], self.sign[:end], self.other[:end]
        np.equal(np.bitwise_and(u, 0xF9, out=scratch), 0x29, out=sign)
        np.equal(np.bitwise_and(u, 0xDF, out=scratch), 0x45, out=other)
        special = np.logical_or(sign, other, out=sign)
        at = np.flatnonzero(special[1 : end - 1]) + 1
        if at.size and _misplaced(u[at], u[at - 1], u[at + 1]).any():
            return None
        return fields


def _misplaced(byte: np.ndarray, before: np.ndarray, after: np.ndarray) -> np.ndarray:
    """Which signs and exponent letters ``byte`` (with their neighbours) cannot belong to a
    plain number: a sign after a digit or point or not followed by one; an exponent letter not
    followed by a digit or sign."""
    sign = (byte & 0xF9) == 0x29
    digit_or_point_after = (after - np.uint8(46)) <= 11
    digit_or_sign_after = ((after - np.uint8(48)) <= 9) | ((after & 0xF9) == 0x29)
    digit_or_point_before = (before - np.uint8(46)) <= 11
    return np.where(sign, digit_or_point_before | ~digit_or_point_after, ~digit_or_sign_after)


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
