"""Vectorised checks and conversions shared by the text readers.

The readers parse the bulk of their numbers with compiled parsers (fast_matrix_market through
``scipy.io.mmread``, NumPy's ``loadtxt``). Such parsers are lenient in ways pymorembs is not:
fast_matrix_market, for example, ignores whatever follows the third number of a line and starts
a number where the previous one stopped, so ``1 1 1.0D+03`` reads as 1.0, ``1 1 1,5`` (a decimal
comma) as 1.0, ``1 1 1.0 2.0`` as 1.0, ``1 1 1.0.5`` as 1.0 and ``1 1.5 2.0`` as entry (1, 1) =
0.5. :func:`count_plain_fields` and :class:`PlainNumberScan` check cheaply, with NumPy over the
raw bytes, that a region of a file holds nothing such a parser misreads (the rules are listed
at :class:`PlainNumberScan`), so that a reader can take the fast result or else fall back to its
strict line-by-line pass, which then names the bad line. :class:`CheckedReader` runs the checks
on the bytes while a parser reads them, so that a large file is read from disk once.
"""

from __future__ import annotations

import io
import os
import threading
from collections import deque
from concurrent.futures import Future, ThreadPoolExecutor

import numpy as np
import scipy.sparse as sp

__all__ = [
    "PLAIN_NUMBER_BYTES",
    "CheckedReader",
    "PlainNumberScan",
    "count_plain_fields",
    "csr_from_sorted_coo",
]

#: The bytes of plain decimal numbers (``-1.5e+03``) and of the white space between them.
PLAIN_NUMBER_BYTES = b"0123456789.eE+- \t\r\n"

#: Bytes scanned at a time: small enough to stay in the caches, large enough for NumPy.
_CHUNK = 1 << 20
#: Longest line accepted (a region with a longer line is refused: no number file has one).
_LONGEST_LINE = 1 << 22
#: Threads of :func:`count_plain_fields` that check chunks while the calling thread reads.
_WORKERS = 2

_NEWLINE, _POINT = 10, 46
#: The plain bytes that are not digits.
_NOT_DIGITS = PLAIN_NUMBER_BYTES[10:]


class PlainNumberScan:
    """Checks of a text region of plain numbers, fed chunk by chunk.

    The region fails (:attr:`fields` becomes None) when it holds

    * any byte but ``0123456789.eE+-`` and white space (space, tab, carriage return, line feed):
      a letter as in ``1.0D+03`` or ``nan``, a comma, a comment sign, a NUL byte, non-ASCII text;
    * a sign directly after a digit or a decimal point (``0.12-105``, a Fortran exponent without
      its letter, which lenient parsers read as 0.12), or not followed by a digit or a point;
    * an exponent letter not followed by a digit or a sign, or not preceded by a digit or a point
      (``1.5e``, ``e5``, ``.e5``; e.g. a number cut short at the end of a truncated file);
    * a decimal point without a digit on either side (``.``, ``-.e5``);
    * a second decimal point or exponent letter in a number, or a point after the exponent
      letter (``1.0.5``, ``1..0``, ``1e5e3``, ``1e5.0``, ``1e-5.0``);
    * with ``fields_per_line``: a line that holds another number of fields (blank lines are
      fine);
    * with ``integer_fields``: a decimal point, exponent letter or sign in one of the first
      ``integer_fields`` fields of a line (``1 1.5 2.0``, ``1e0 1 2.0``).

    What passes consists of white-space separated fields that each read, whole, as a decimal
    number ``[sign] digits [. digits] [e [sign] digits]`` (digits before or after the point),
    the integer fields as ``digits``: exactly what a strict parser (Python's ``float`` and
    ``int``) accepts of these bytes. A parser that reads one number per field and stops at the
    first byte that cannot continue a number (fast_matrix_market, ``np.fromstring``) reads every
    field whole, so its numbers equal the strict ones.

    Parameters
    ----------
    fields_per_line : int, optional
        Fields every non-blank line must hold.
    integer_fields : int
        Leading fields of every line that must be unsigned integers (with ``fields_per_line``).
    """

    def __init__(self, fields_per_line: int | None = None, integer_fields: int = 0) -> None:
        self.fields_per_line = fields_per_line
        self.integer_fields = integer_fields if fields_per_line else 0
        self._fields: int | None = 0
        self._tail = b""
        self._done = False

    @property
    def fields(self) -> int | None:
        """Fields (maximal runs of non-white-space bytes) so far, or None if a check failed."""
        return self._fields

    def feed(self, data: bytes | bytearray | memoryview) -> bool:
        """Check the complete lines of ``data`` (the rest waits for the next chunk); False once
        a check has failed."""
        chunk = self.split(data)
        if chunk is not None:
            self.add(check_chunk(chunk, self.fields_per_line, self.integer_fields))
        return self._fields is not None

    def finish(self) -> int | None:
        """Check the last line (which may lack its line end); :attr:`fields` or None."""
        if not self._done:
            self._done = True
            if self._tail and self._fields is not None:
                chunk = b"\n" + self._tail + b"\n"
                self.add(check_chunk(chunk, self.fields_per_line, self.integer_fields))
            self._tail = b""
        return self._fields

    def split(self, data: bytes | bytearray | memoryview) -> bytes | None:
        """The complete lines of the kept tail plus ``data``, framed by line ends as
        :func:`check_chunk` needs them; the rest is kept. None if there is no complete line
        (or a line is too long, which fails the scan)."""
        if self._fields is None:
            return None
        raw = data if isinstance(data, bytes) else bytes(data)
        cut = raw.rfind(b"\n")
        if cut < 0:
            self._tail += raw
            if len(self._tail) > _LONGEST_LINE:
                self._fields = None
            return None
        view = memoryview(raw)
        chunk = b"".join((b"\n", self._tail, view[: cut + 1]))
        self._tail = bytes(view[cut + 1 :])
        return chunk

    def add(self, fields: int | None) -> None:
        """Count the fields of a checked chunk (None: the chunk failed)."""
        if self._fields is not None:
            self._fields = None if fields is None else self._fields + fields


def check_chunk(
    chunk: bytes, fields_per_line: int | None = None, integer_fields: int = 0
) -> int | None:
    """Fields of a chunk of whole lines, or None if it fails a check of :class:`PlainNumberScan`.

    ``chunk`` must start and end with a line feed (the frame is not part of the region). The
    checks run on the bytes that are not digits (white space, signs, points, exponent letters:
    a sixth of a typical file), in file order: a field starts after a white byte that is
    followed by digits or by another such byte, and two such bytes are neighbours in the file
    unless digits lie between them.
    """
    u = np.frombuffer(chunk, dtype=np.uint8)
    scratch, non_digit = _scratch(u.size)
    np.greater(np.subtract(u, 48, out=scratch), 9, out=non_digit)
    kind = np.compress(non_digit, u)  # the entries: every byte but the digits, in order
    if kind.tobytes().translate(None, _NOT_DIGITS):
        return None  # a byte that is not part of a plain number or white space
    # digits between entry j and entry j + 1 (the last byte, a line feed, is an entry)
    digit_next = np.logical_not(non_digit[1:], out=scratch.view(bool)[1:])
    digits_after = np.compress(non_digit[:-1], digit_next)
    white = kind <= 32
    starts = white[:-1] & (digits_after | ~white[1:])  # a field starts after entry j
    point = kind == _POINT
    letter = (kind | 32) == 101  # e, E
    special = ~white
    sign = special & ~point & ~letter  # + and -
    # neighbours: a digit when digits lie between two entries, else the neighbouring entry
    adjacent = ~digits_after
    digit_before = np.concatenate(([False], digits_after))
    digit_after = np.concatenate((digits_after, [False]))
    point_before = np.concatenate(([False], point[:-1] & adjacent))
    point_after = np.concatenate((point[1:] & adjacent, [False]))
    sign_after = np.concatenate((sign[1:] & adjacent, [False]))
    bad = sign & (digit_before | point_before | ~(digit_after | point_after))
    bad |= letter & ~((digit_after | sign_after) & (digit_before | point_before))
    bad |= point & ~(digit_before | digit_after)
    # within a field (no white entry between): no point or letter after a letter, no point
    # after a point; a sign between them lies directly after the letter (checked above)
    bad[:-1] |= (point[:-1] & point[1:]) | (letter[:-1] & (point[1:] | letter[1:]))
    bad[:-2] |= letter[:-2] & sign[1:-1] & (point[2:] | letter[2:])
    if bad.any():
        return None
    fields = int(np.count_nonzero(starts))
    if fields_per_line:
        # fields started up to each entry (the chunk holds less than 2**31 bytes)
        before = np.concatenate(([0], np.cumsum(starts, dtype=np.int32)))
        per_line = np.diff(before[np.flatnonzero(kind == _NEWLINE)])
        if np.any((per_line != 0) & (per_line != fields_per_line)):
            return None
        # every line holds the same number of fields: field q (from 1) of the chunk is field
        # (q - 1) % fields_per_line + 1 of its line
        if integer_fields:
            index = (before[np.flatnonzero(special)] - 1) % fields_per_line
            if np.any(index < integer_fields):
                return None  # a point, letter or sign in an integer field
    return fields


_SCRATCH = threading.local()


def _scratch(size: int) -> tuple[np.ndarray, np.ndarray]:
    """Two arrays (bytes, booleans) of ``size`` elements, kept per thread: fresh arrays of the
    size of a chunk cost more (page faults) than the checks that fill them."""
    kept = getattr(_SCRATCH, "arrays", None)
    if kept is None or kept[0].size < size:
        kept = (
            np.empty(max(size, _CHUNK + 2), dtype=np.uint8),
            np.empty(max(size, _CHUNK + 2), bool),
        )
        _SCRATCH.arrays = kept
    return kept[0][:size], kept[1][:size]


def count_plain_fields(
    path: str | os.PathLike[str],
    offset: int = 0,
    *,
    fields_per_line: int | None = None,
    integer_fields: int = 0,
) -> int | None:
    """Number of white-space separated plain numeric fields in a file from byte ``offset`` on.

    Returns None when the region fails a check of :class:`PlainNumberScan` (with
    ``fields_per_line`` and ``integer_fields`` as there) or the file cannot be read. The chunks
    are checked by worker threads while the calling thread reads the next one.

    Parameters
    ----------
    path : path-like
        The file.
    offset : int
        Byte offset of the region (e.g. the first byte after a header).
    fields_per_line, integer_fields : int, optional
        See :class:`PlainNumberScan`.

    Returns
    -------
    int or None
        Number of fields (maximal runs of non-white-space bytes), or None as described.
    """
    scan = PlainNumberScan(fields_per_line, integer_fields)
    try:
        small = os.path.getsize(path) - offset <= _CHUNK
        if small:  # one chunk: checked here, without threads
            with open(path, "rb") as stream:
                stream.seek(offset)
                scan.feed(stream.read())
            return scan.finish()
    except OSError:
        return None
    pending: deque[Future[int | None]] = deque()
    try:
        with open(path, "rb", buffering=0) as stream, ThreadPoolExecutor(_WORKERS) as workers:
            stream.seek(offset)
            while True:
                block = stream.read(_CHUNK)
                if not block:
                    break
                chunk = scan.split(block)
                if chunk is None:
                    if scan.fields is None:
                        return None
                    continue
                pending.append(
                    workers.submit(check_chunk, chunk, fields_per_line, scan.integer_fields)
                )
                while len(pending) > _WORKERS or (pending and pending[0].done()):
                    scan.add(pending.popleft().result())
                if scan.fields is None:
                    return None
            for job in pending:
                scan.add(job.result())
    except OSError:
        return None
    return scan.finish()


class CheckedReader(io.RawIOBase):
    """A binary file whose bytes from ``offset`` on pass through a :class:`PlainNumberScan`.

    Hand it (in an ``io.BufferedReader``) to a parser such as ``scipy.io.mmread``: the file is
    read once, and checked while the parser reads. A failed check makes the next read raise
    ``ValueError`` (so the parser stops); afterwards :attr:`fields` is None. :attr:`fields` is
    the field count once the parser has read to the end of the file (else None).

    Parameters
    ----------
    path : path-like
        The file.
    offset : int
        First byte of the checked region (the header before it passes unchecked).
    scan : PlainNumberScan
        The checks.
    patch : tuple of (int, bytes), optional
        Bytes to show instead of the file's at a position within the header (e.g. ``general``
        in place of ``symmetric`` in a Matrix Market banner).
    """

    def __init__(
        self,
        path: str | os.PathLike[str],
        offset: int,
        scan: PlainNumberScan,
        patch: tuple[int, bytes] | None = None,
    ) -> None:
        super().__init__()
        self._file = open(path, "rb", buffering=0)  # closed in close()
        self._position = 0
        self._offset = offset
        self._scan = scan
        self._patch = patch
        self._eof = False

    def readable(self) -> bool:
        return True

    def readinto(self, buffer) -> int:
        if self._scan.fields is None:
            raise ValueError("the bytes fail the plain-number checks")
        size = self._file.readinto(buffer)
        view = memoryview(buffer).cast("B")
        if self._patch is not None:
            start, patch = self._patch
            first = max(start - self._position, 0)
            last = min(start + len(patch) - self._position, size)
            if first < last:
                shift = self._position + first - start
                view[first:last] = patch[shift : shift + last - first]
        skip = min(max(self._offset - self._position, 0), size)
        self._position += size
        if size == 0:
            self._eof = True
            self._scan.finish()
        elif skip < size:
            self._scan.feed(view[skip:size])
        if self._scan.fields is None:
            raise ValueError("the bytes fail the plain-number checks")
        return size

    @property
    def fields(self) -> int | None:
        """Fields of the region once it was read to its end and passed every check, else None."""
        return self._scan.fields if self._eof else None

    def close(self) -> None:
        self._file.close()
        super().close()


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
