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

import functools
import io
import itertools
import mmap
import os
import threading
from collections import deque
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

__all__ = [
    "PLAIN_NUMBER_BYTES",
    "CheckedReader",
    "PlainNumberScan",
    "SymmetricRoom",
    "all_distinct",
    "canonical_csr",
    "check_chunk",
    "check_chunk_numpy",
    "compiled_checks",
    "compiled_worthwhile",
    "count_line_ends",
    "count_plain_fields",
    "csr_from_sorted_coo",
    "full_from_triangle",
    "parse_coordinate_lines",
    "transpose_gap",
    "triangle_sides",
]

#: The bytes of plain decimal numbers (``-1.5e+03``) and of the white space between them.
PLAIN_NUMBER_BYTES = b"0123456789.eE+- \t\r\n"

#: Bytes scanned at a time: small enough to stay in the caches, large enough for NumPy.
_CHUNK = 1 << 20
#: Longest line accepted (a region with a longer line is refused: no number file has one).
_LONGEST_LINE = 1 << 22
#: Region bytes from which :meth:`PlainNumberScan.expect` chooses the compiled checks.
COMPILED_FROM_BYTES = 1 << 28
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
        self.compiled: bool | None = False
        self._fields: int | None = 0
        self._tail = b""
        self._done = False

    @property
    def fields(self) -> int | None:
        """Fields (maximal runs of non-white-space bytes) so far, or None if a check failed."""
        return self._fields

    def expect(self, size: int) -> None:
        """Choose the checks for a region of ``size`` bytes: the compiled ones (when Numba is
        installed) from :data:`COMPILED_FROM_BYTES` on or once they are loaded, else NumPy's
        (for a small region, loading the compiled code costs more than it saves)."""
        self.compiled = None if size >= COMPILED_FROM_BYTES or _loaded() else False

    def check(self, chunk: bytes | bytearray | memoryview) -> int | None:
        """:func:`check_chunk` of a chunk from :meth:`split` with this scan's rules."""
        return check_chunk(chunk, self.fields_per_line, self.integer_fields, compiled=self.compiled)

    def feed(self, data: bytes | bytearray | memoryview) -> bool:
        """Check the complete lines of ``data`` (the rest waits for the next chunk); False once
        a check has failed."""
        chunk = self.split(data)
        if chunk is not None:
            self.add(self.check(chunk))
        return self._fields is not None

    def finish(self) -> int | None:
        """Check the last line (which may lack its line end); :attr:`fields` or None."""
        if not self._done:
            self._done = True
            if self._tail and self._fields is not None:
                chunk = b"\n" + self._tail + b"\n"
                self.add(self.check(chunk))
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
    chunk: bytes | bytearray | memoryview,
    fields_per_line: int | None = None,
    integer_fields: int = 0,
    *,
    compiled: bool | None = None,
) -> int | None:
    """Fields of a chunk of whole lines, or None if it fails a check of :class:`PlainNumberScan`.

    ``chunk`` must start and end with a line feed (the frame is not part of the region).

    Parameters
    ----------
    chunk : bytes-like
        The lines, framed by line feeds.
    fields_per_line, integer_fields : int, optional
        See :class:`PlainNumberScan`.
    compiled : bool, optional
        True: the compiled one-pass check (Numba; ``ImportError`` without it); False: the
        vectorised NumPy check :func:`check_chunk_numpy`; None (default): the compiled check
        when Numba is installed. Both accept exactly the same bytes.

    Returns
    -------
    int or None
        Fields (maximal runs of non-white-space bytes), or None if a check fails.
    """
    kernels = _kernels() if compiled is None else (_kernels(required=True) if compiled else None)
    if kernels is None:
        return check_chunk_numpy(chunk, fields_per_line, integer_fields)
    k = int(fields_per_line or 0)
    lines = (fields_per_line, integer_fields) == _MATRIX_MARKET_LINE
    fields = kernels.plain_number_fields(
        np.frombuffer(chunk, dtype=np.uint8),
        k,
        int(integer_fields) if k else 0,
        lines,
        _CLASS_TABLE,
        _BAD_IN_LINE if lines else _BAD_TRIPLE,
    )
    return None if fields < 0 else int(fields)


def compiled_checks() -> bool:
    """Whether the compiled byte checks can be used (Numba is installed)."""
    return _kernels() is not None


@functools.cache
def _compiled_module():
    """The module of compiled checks, or None without Numba."""
    try:
        from pymorembs.io import compiled_kernels
    except ImportError:
        return None
    return compiled_kernels


def compiled_worthwhile(size: int) -> bool:
    """Whether the compiled kernels should handle a region of ``size`` bytes: Numba is
    installed and the region has :data:`COMPILED_FROM_BYTES` or more, or the kernels are loaded
    already (for a small region, loading them costs more than they save)."""
    return (size >= COMPILED_FROM_BYTES or _loaded()) and _kernels() is not None


def _loaded() -> bool:
    """Whether the compiled kernels were loaded already (then they cost nothing more)."""
    return _compiled_module.cache_info().currsize > 0 and _compiled_module() is not None


def _kernels(required: bool = False):
    """:func:`_compiled_module`; with ``required`` an ``ImportError`` if there is none."""
    kernels = _compiled_module()
    if kernels is None and required:
        raise ImportError("the compiled byte checks need Numba (pip install numba)")
    return kernels


def check_chunk_numpy(
    chunk: bytes | bytearray | memoryview,
    fields_per_line: int | None = None,
    integer_fields: int = 0,
) -> int | None:
    """:func:`check_chunk` with NumPy's vectorised operations (no compiled code).

    The checks run on the bytes that are not digits (white space, signs, points, exponent letters:
    a sixth of a typical file), the *entries*, in file order, each with one flag: whether digits
    follow it. A run of white entries without digits between them is one separator (a line end
    if it holds a line feed; a carriage return must be part of a line end, as strict parsers
    read a lone one as a line break). Then every rule of :class:`PlainNumberScan` on the
    characters of a number concerns an entry and its two neighbours, and is looked up in a
    table of entry triples (:data:`_BAD_TRIPLE`); the fields of a line are the separators
    between two line ends.
    """
    u = np.frombuffer(chunk, dtype=np.uint8)
    scratch, non_digit = _scratch(u.size)
    np.greater(np.subtract(u, 48, out=scratch), 9, out=non_digit)
    where = np.flatnonzero(non_digit)  # the entries; the first and the last are line feeds
    kind = np.frombuffer(u[where].tobytes().translate(_CLASS_OF_BYTE), dtype=np.uint8)
    digits_after = np.empty(where.size, dtype=bool)
    np.greater(np.diff(where), 1, out=digits_after[:-1])
    digits_after[-1] = False
    white = kind <= _NL
    merged = white[:-1] & white[1:] & ~digits_after[:-1]  # followed directly by white
    if merged.any():
        kind, digits_after = _one_entry_per_run(kind, digits_after, merged)
        white = kind <= _NL
    code = kind << 1
    code |= digits_after
    pairs = code[:-1] << 4
    pairs |= code[1:]
    triples = pairs[:-1].astype(np.uint16) << 4
    triples |= code[2:]
    lines = (fields_per_line, integer_fields) == _MATRIX_MARKET_LINE
    if (_BAD_IN_LINE if lines else _BAD_TRIPLE).take(triples).any():
        return None
    if lines:
        # the table proved every line "digits blank digits blank number" (module docstring of
        # _bad_in_line); the first line is checked here (entry 0 is the frame's line end)
        if kind.size > 1 and kind[1] != _SP:
            return None
        return 3 * (int(np.count_nonzero(kind == _NL)) - 1)
    separators = np.flatnonzero(white)
    fields = separators.size - 1
    if fields_per_line:
        k = fields_per_line
        if fields % k:
            return None
        # separator t (from 0, a line end) precedes field t % k of its line: the separators are
        # one line end, then per line k - 1 blanks and a line end
        ends = (kind[separators[1:]] == _NL).reshape(-1, k)
        if not ends[:, -1].all() or ends[:, :-1].any():
            return None
        if integer_fields:
            # no sign, point or letter in fields 0 .. integer_fields - 1: the separator before
            # the first such entry of a field is followed directly by it
            after = separators + 1
            after[-1] = separators[-1]  # the last entry, a line end
            special = ~white[after]
            columns = _integer_columns(k, integer_fields)
            if special[0] or special[1:].reshape(-1, k)[:, columns].any():
                return None
    return fields


#: Runs of white entries longer than this are merged by cumulative sums.
_SHORT_RUN = 16


def _one_entry_per_run(
    kind: np.ndarray, digits_after: np.ndarray, merged: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Entry classes and flags with each run of white entries replaced by its last entry, of
    the highest class in the run (a line feed if the run holds one; else a carriage return,
    which ends no line and is refused; else a blank). ``merged[j]``: entry ``j`` is white and
    followed directly by a white entry."""
    kind = kind.copy()
    lifted = np.flatnonzero(merged & (kind[:-1] > _SP))  # a merged line feed or return
    if lifted.size:
        end = lifted + 1  # the last entry of the run of each
        for _ in range(_SHORT_RUN):
            longer = merged[np.minimum(end, merged.size - 1)] & (end < merged.size)
            if not longer.any():
                break
            end[longer] += 1
        else:  # long runs: the highest class from cumulative counts per run
            keep = np.ones(kind.size, dtype=bool)
            np.logical_not(merged, out=keep[:-1])
            kept = np.flatnonzero(keep)
            holds = [
                np.diff(np.cumsum(kind == cls, dtype=np.int64)[kept], prepend=0) > 0
                for cls in (_CR, _NL)
            ]
            kind = kind[kept]
            for cls, held in zip((_CR, _NL), holds, strict=True):
                kind[held] = cls
            return kind, digits_after[kept]
        np.maximum.at(kind, end, kind[lifted])
    keep = np.ones(kind.size, dtype=bool)
    np.logical_not(merged, out=keep[:-1])
    return kind[keep], digits_after[keep]


def _integer_columns(k: int, integer_fields: int) -> list[int]:
    """Columns c (separator 1 + c of a line, modulo k) that precede an integer field."""
    return [c for c in range(k) if (c + 1) % k < integer_fields]


# entry classes (after :data:`_CLASS_OF_BYTE`); white first, in the order in which a run of
# white entries takes the class of its highest
_SP, _CR, _NL, _POINT_CLASS, _LETTER, _SIGN, _BAD = range(7)
#: Class of every byte (digits never reach the table: they are not entries).
_CLASS_OF_BYTE = bytes(
    {
        **dict.fromkeys(b"\n", _NL),
        **dict.fromkeys(b" \t", _SP),
        **dict.fromkeys(b"\r", _CR),
        **dict.fromkeys(b".", _POINT_CLASS),
        **dict.fromkeys(b"eE", _LETTER),
        **dict.fromkeys(b"+-", _SIGN),
    }.get(b, _BAD)
    for b in range(256)
)


def _bad_triple(a: int, b: int, c: int) -> bool:
    """Whether entry ``b`` (code: class * 2 + digits follow) between ``a`` and ``c`` breaks a
    rule of :class:`PlainNumberScan`."""
    (ka, da), (kb, db), kc = divmod(a, 2), divmod(b, 2), c >> 1
    if kb in (_BAD, _CR):
        return True  # a byte of no plain number, or a carriage return that ends no line
    if kb in (_SP, _NL):
        return False  # white: the rules concern the characters of numbers
    digit_before, digit_after = bool(da), bool(db)
    point_before = ka == _POINT_CLASS and not da
    point_after = kc == _POINT_CLASS and not db
    sign_after = kc == _SIGN and not db
    if kb == _SIGN and (digit_before or point_before or not (digit_after or point_after)):
        return True
    if kb == _LETTER and not ((digit_after or sign_after) and (digit_before or point_before)):
        return True
    if kb == _POINT_CLASS and not (digit_before or digit_after):
        return True
    # within a number: no point or letter after a letter, no point after a point, and after
    # a letter and its sign neither
    if kb == _POINT_CLASS and kc == _POINT_CLASS:
        return True
    if kb == _LETTER and kc in (_POINT_CLASS, _LETTER):
        return True
    return ka == _LETTER and kb == _SIGN and kc in (_POINT_CLASS, _LETTER)


#: :func:`_bad_triple` of every triple of entry codes ``(a << 8) | (b << 4) | c``.
_BAD_TRIPLE = np.array(
    [_bad_triple(t >> 8, (t >> 4) & 15, t & 15) for t in range(1 << 12)], dtype=bool
)


#: (fields per line, integer fields) of a Matrix Market coordinate file, checked by table.
_MATRIX_MARKET_LINE = (3, 2)


def _bad_in_line(a: int, b: int, c: int) -> bool:
    """:func:`_bad_triple`, and whether entry ``b`` breaks the layout of a coordinate line.

    After the merging of white runs a line is ``NL d SP d SP x NL`` with ``d`` digits and ``x``
    a number: every blank follows a line end and precedes a blank (the first) or follows a
    blank and precedes no blank (the second); a line end follows no line end (a line of one
    field) and precedes a blank; a sign, point or letter follows the second blank or another
    such entry (so it lies in the third field) and precedes no blank.
    """
    if _bad_triple(a, b, c):
        return True
    ka, kb, kc = a >> 1, b >> 1, c >> 1
    if kb == _SP:
        return not ((ka == _NL and kc == _SP) or (ka == _SP and kc != _SP))
    if kb == _NL:
        return ka == _NL or kc != _SP
    return ka == _NL or kc == _SP


#: :func:`_bad_in_line` of every triple of entry codes.
_BAD_IN_LINE = np.array(
    [_bad_in_line(t >> 8, (t >> 4) & 15, t & 15) for t in range(1 << 12)], dtype=bool
)
#: :data:`_CLASS_OF_BYTE` as an array, for the compiled check.
_CLASS_TABLE = np.frombuffer(_CLASS_OF_BYTE, dtype=np.uint8)


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
        region = os.path.getsize(path) - offset
        scan.expect(region)
        small = region <= _CHUNK
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
                pending.append(workers.submit(scan.check, chunk))
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
    read once, and checked while the parser reads, by a worker thread (NumPy releases the GIL
    in its loops, so the checks overlap the parser's own threads); at most
    :data:`_PENDING_CHUNKS` chunks wait for their check. A failed check makes a later read
    raise ``ValueError`` (so the parser stops); afterwards :attr:`fields` is None.
    :attr:`fields` is the field count once the parser has read to the end of the file and
    every chunk is checked (else None).

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
        self._pending: deque[Future[int | None]] = deque()
        self._worker = ThreadPoolExecutor(1)  # shut down in close()
        scan.expect(os.fstat(self._file.fileno()).st_size - offset)

    def readable(self) -> bool:
        return True

    def readinto(self, buffer) -> int:
        self._collect(_PENDING_CHUNKS)
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
            self._collect(0)
            self._eof = True
            self._scan.finish()
        elif skip < size:
            chunk = self._scan.split(view[skip:size])
            if chunk is not None:
                self._pending.append(self._worker.submit(self._scan.check, chunk))
        if self._scan.fields is None:
            raise ValueError("the bytes fail the plain-number checks")
        return size

    @property
    def fields(self) -> int | None:
        """Fields of the region once it was read to its end and passed every check, else None."""
        return self._scan.fields if self._eof else None

    def _collect(self, left: int) -> None:
        """Count the checked chunks; wait until at most ``left`` chunks are unchecked."""
        pending = self._pending
        while pending and (len(pending) > left or pending[0].done()):
            self._scan.add(pending.popleft().result())

    def close(self) -> None:
        self._worker.shutdown(wait=True, cancel_futures=True)
        self._pending.clear()
        self._file.close()
        super().close()


#: Chunks of a :class:`CheckedReader` that may wait for their check (16 MiB of memory).
_PENDING_CHUNKS = 16


def canonical_csr(
    data: np.ndarray, indices: np.ndarray, indptr: np.ndarray, shape: tuple[int, int]
) -> sp.csr_matrix:
    """A CSR matrix on the given arrays (no copy), marked canonical: the caller built them
    sorted and without duplicates, so SciPy need not look again.

    The arrays may be the start of larger ones (e.g. a :class:`SymmetricRoom`'s): SciPy's
    constructor would copy a view of less than half of its array (its ``prune``), so arrays
    of one index type that pass the checks of its ``check_format`` are set on an empty matrix
    of the shape (others go through the constructor).

    Parameters
    ----------
    data, indices : ndarray, shape (nnz,)
        Longer arrays are cut to ``indptr[-1]`` entries (views).
    indptr : ndarray, shape (shape[0] + 1,)
    shape : tuple of int

    Returns
    -------
    scipy.sparse.csr_matrix
    """
    nnz = int(indptr[-1]) if indptr.ndim == 1 and indptr.size else -1
    plain = (
        data.ndim == 1
        and indices.shape == data.shape
        and indptr.shape == (shape[0] + 1,)
        and indices.dtype.kind == "i"
        and indptr.dtype == indices.dtype
        and indptr[0] == 0
        and 0 <= nnz <= data.size
    )
    if plain:
        matrix = sp.csr_matrix(shape, dtype=data.dtype)
        if nnz < data.size:
            indices, data = indices[:nnz], data[:nnz]
        matrix.indptr, matrix.indices, matrix.data = indptr, indices, data
    else:
        matrix = sp.csr_matrix((data, indices, indptr), shape=shape, copy=False)
    matrix.has_sorted_indices = True
    matrix.has_canonical_format = True
    return matrix


#: Stored entries from which :func:`full_from_triangle` and :func:`transpose_gap` use the
#: compiled kernels (for fewer, loading them costs more than they save).
COMPILED_FROM_ENTRIES = 1 << 23


def full_from_triangle(stored: sp.csr_matrix) -> sp.csr_matrix | None:
    """The full symmetric matrix of a canonical CSR matrix holding one triangle (either), by the
    compiled kernels (on the solver threads, :func:`_threads`): row ``i`` is row ``i`` of
    the lower triangle followed by row ``i`` of the upper one without its diagonal entry;
    explicit zeros are kept.

    Returns None without Numba or, unless the kernels are loaded already, below
    :data:`COMPILED_FROM_ENTRIES` entries (the caller then uses its NumPy path).

    Parameters
    ----------
    stored : scipy.sparse.csr_matrix, shape (n, n)
        Canonical (sorted, no duplicates), entries on one side of the diagonal only.

    Returns
    -------
    scipy.sparse.csr_matrix or None
        Canonical, shape (n, n).
    """
    kernels = _kernels() if stored.nnz >= COMPILED_FROM_ENTRIES or _loaded() else None
    if kernels is None:
        return None
    n = stored.shape[0]
    counts = np.zeros(n + 1, dtype=np.int64)
    lower = kernels.mirror_counts(stored.indptr, stored.indices, counts)
    total = int(counts[-1])
    index = stored.indices.dtype if total < 2**31 - 1 else np.dtype(np.int64)
    indptr = counts.astype(index, copy=False)
    del counts
    indices = np.empty(total, dtype=index)
    data = np.empty(total, dtype=stored.data.dtype)
    arrays = (stored.indptr, stored.indices.astype(index, copy=False), stored.data)
    _over_ranges(kernels.mirror_rows, (*arrays, indptr, indices, data, lower), n, _threads(n))
    return canonical_csr(data, indices, indptr, (n, n))


class SymmetricRoom:
    """Arrays for the ``entries`` stored entries of a lower triangle with room to complete it,
    in the same memory, to the full symmetric matrix.

    A parser fills :attr:`rows`, :attr:`cols` and :attr:`values` (shape (entries,)); once the
    triangle is a canonical CSR matrix that holds :attr:`cols` and :attr:`values` as its arrays
    (:func:`csr_from_sorted_coo`), :meth:`full` completes it where it lies. Reading a large
    symmetric file then touches the memory of the full matrix and no other of its size: on a
    virtual machine that returns freed memory to its host, touching memory for the first time
    costs more than the parse.

    Parameters
    ----------
    entries : int
        Stored entries, fewer than ``(2**31 - 1) // 2`` (:meth:`fits`).
    """

    def __init__(self, entries: int) -> None:
        if not self.fits(entries):
            raise ValueError(f"{entries} entries need 64-bit indices")
        self._indices = np.empty(2 * entries, dtype=np.int32)
        self._data = np.empty(2 * entries)
        #: Row indices from 0, shape (entries,); overwritten by :meth:`full`.
        self.rows = self._indices[:entries]
        #: Column indices from 0, shape (entries,).
        self.cols = self._indices[entries:]
        #: Values, shape (entries,).
        self.values = self._data[entries:]

    @staticmethod
    def fits(entries: int) -> bool:
        """Whether the full matrix of ``entries`` stored entries has 32-bit indices."""
        return 0 < entries < (2**31 - 1) // 2

    def full(self, triangle: sp.csr_matrix) -> sp.csr_matrix | None:
        """The full symmetric matrix of ``triangle``, completed in place (compiled kernel, in
        blocks on two threads: :func:`complete_lower_in_place`); explicit zeros are kept.

        ``triangle`` may hold fewer entries than the room has (a parser that left some out):
        its arrays must start where :attr:`cols` and :attr:`values` start. The room's arrays
        are then cut to the full matrix's entries (the memory after them is given back, without
        a copy), so that the result holds no more memory than it needs.

        Returns None, and leaves everything as it was, without Numba, if ``triangle`` is not
        canonical, holds entries above the diagonal, or does not hold :attr:`cols` and
        :attr:`values` as its arrays. Afterwards :attr:`rows`, :attr:`cols` and :attr:`values`
        are empty and ``triangle`` must not be used.

        Parameters
        ----------
        triangle : scipy.sparse.csr_matrix, shape (n, n)

        Returns
        -------
        scipy.sparse.csr_matrix or None
            Canonical, shape (n, n); its arrays are this room's memory.
        """
        entries = self.cols.size
        held = (
            triangle.nnz <= entries
            and triangle.indices.ctypes.data == self.cols.ctypes.data
            and triangle.data.ctypes.data == self.values.ctypes.data
            and triangle.indices.dtype == np.int32
            and triangle.data.dtype == np.float64
        )
        if not held or not triangle.has_canonical_format or triangle_sides(triangle)[1]:
            return None
        kernels = _kernels()
        if kernels is None:
            return None
        n = triangle.shape[0]
        counts = np.zeros(n + 1, dtype=np.int64)
        kernels.mirror_counts(triangle.indptr, triangle.indices, counts)
        total = int(counts[-1])
        indptr = counts.astype(np.int32)
        del counts
        complete_lower_in_place(triangle.indptr, self._indices, self._data, entries, indptr)
        if total < self._indices.size:
            # cut in place (realloc: a large array keeps its address and gives the pages after
            # the cut back); the views on the old arrays, the room's and the triangle's, are
            # not used again
            self._indices.resize(total, refcheck=False)
            self._data.resize(total, refcheck=False)
        self.rows = self.cols = self._indices[:0]
        self.values = self._data[:0]
        return canonical_csr(self._data, self._indices, indptr, (n, n))


#: Entries of a block below which :func:`complete_lower_in_place` goes on with one thread.
_MIRROR_BLOCK = 1 << 16


def complete_lower_in_place(
    indptr: np.ndarray, indices: np.ndarray, data: np.ndarray, offset: int, out_indptr: np.ndarray
) -> None:
    """A lower triangle completed to the full symmetric matrix in the arrays that hold it
    (:func:`~pymorembs.io.compiled_kernels.rows_in_place`), on two threads where there are
    (Numba needed).

    The rows are taken in blocks ``a .. b - 1`` whose full rows end before the block's first
    entry is read (``out_indptr[b] <= offset + indptr[a]``): then no write of the block reaches
    an entry of the block, so one thread moves the triangle's own entries while the other
    writes their mirror images, each to places of its own. Once a block holds fewer than
    :data:`_MIRROR_BLOCK` entries (near the end of a triangle with few diagonal entries, the
    room left between the full rows and the entries still to be read) the rest is done on one
    thread, as on a single core.

    Parameters
    ----------
    indptr : ndarray of int32, shape (n + 1,)
        Row pointer of the canonical lower triangle, whose entries start at ``offset`` in
        ``indices`` and ``data``.
    indices, data : ndarray (int32, float64)
        The arrays that hold the triangle and receive the full matrix at their front.
    offset : int
        At least the number of entries below the diagonal.
    out_indptr : ndarray of int32, shape (n + 1,)
        Row pointer of the full matrix (:func:`~pymorembs.io.compiled_kernels.mirror_counts`).
    """
    kernels = _kernels(required=True)
    n = indptr.size - 1
    slots = out_indptr[:-1] + np.diff(indptr)  # after each row's own entries
    arrays = (indptr, indices, data, offset, out_indptr, slots)
    two = _threads(2) > 1
    a = 0
    while a < n:
        b = min(int(np.searchsorted(out_indptr, offset + indptr[a], side="right")) - 1, n)
        if not two or b <= a or indptr[b] - indptr[a] < _MIRROR_BLOCK:
            kernels.rows_in_place(*arrays, a, n, True, True)
            return
        _concurrently(
            [
                functools.partial(kernels.rows_in_place, *arrays, a, b, True, False),
                functools.partial(kernels.rows_in_place, *arrays, a, b, False, True),
            ]
        )
        a = b


def triangle_sides(matrix: sp.csr_matrix) -> tuple[bool, bool]:
    """Whether a canonical CSR matrix has entries below and above the diagonal (from the first
    and last entry of each row: one look per row).

    Parameters
    ----------
    matrix : scipy.sparse.csr_matrix, shape (n, n)
        Canonical (sorted, no duplicates).

    Returns
    -------
    below, above : bool
    """
    indptr, indices = matrix.indptr, matrix.indices
    rows = np.flatnonzero(np.diff(indptr))
    below = bool(np.any(indices[indptr[rows]] < rows))
    above = bool(np.any(indices[indptr[rows + 1] - 1] > rows))
    return below, above


def transpose_gap(a: sp.csr_matrix) -> float | None:
    """``max |A - A^T|`` of a canonical square CSR matrix (NaN if it holds NaN) by the compiled
    kernel, in one pass without forming ``A^T`` (on the solver threads, :func:`_threads`).

    None without Numba, if ``a`` is not canonical or, unless the kernels are loaded already,
    below :data:`COMPILED_FROM_ENTRIES` entries.

    Parameters
    ----------
    a : scipy.sparse.csr_matrix, shape (n, n)

    Returns
    -------
    float or None
    """
    if not a.has_canonical_format or a.shape[0] != a.shape[1]:
        return None
    kernels = _kernels() if a.nnz >= COMPILED_FROM_ENTRIES or _loaded() else None
    if kernels is None:
        return None
    from pymorembs.linalg import compiled_kernels as linalg_kernels  # Numba is installed

    n = a.shape[0]
    gaps = _over_ranges(linalg_kernels.rows_gap, (a.indptr, a.indices, a.data), n, _threads(n))
    nan = [gap for gap in gaps if gap != gap]
    return float(nan[0] if nan else max(gaps))


def _threads(parts: int) -> int:
    """Threads for ``parts`` parts of work: at most the solver threads
    (``PYMOREMBS_SOLVER_THREADS``, else the cores this process may use), at least one."""
    from pymorembs.linalg.backends import solver_threads

    return max(1, min(solver_threads(), parts))


def _concurrently(calls: list) -> list:
    """The results of ``calls`` (of compiled kernels, which release the GIL), each on a thread of
    its own, the first on the calling thread."""
    if len(calls) == 1:
        return [calls[0]()]
    with ThreadPoolExecutor(len(calls) - 1) as pool:
        others = [pool.submit(call) for call in calls[1:]]
        first = calls[0]()
        return [first, *(job.result() for job in others)]


def _over_ranges(kernel, arrays: tuple, size: int, parts: int) -> list:
    """``kernel(*arrays, first, last)`` for ``parts`` equal ranges ``first .. last`` of
    ``0 .. size``, concurrently (:func:`_concurrently`); the results in range order."""
    bounds = np.linspace(0, size, parts + 1).astype(np.int64).tolist()
    calls = [functools.partial(kernel, *arrays, a, b) for a, b in itertools.pairwise(bounds)]
    return _concurrently(calls)


#: Bytes of a file parsed at a time by :func:`parse_coordinate_lines`.
_PARSE_BLOCK = 1 << 24
#: Bytes of a block from which a thread of its own parses (or counts) a part of it.
_PART_BYTES = 1 << 20
#: Bytes searched for the last line end of a block (no line of a number file is this long).
_LINE_SEARCH = 1 << 16
#: ``madvise`` advice that drops parsed pages of a mapped file from the process (Linux).
_UNMAP = getattr(mmap, "MADV_DONTNEED", None)


def parse_coordinate_lines(
    path: str | os.PathLike[str],
    offset: int,
    n: int,
    entries: int,
    out: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None,
    *,
    upper_columns: bool = False,
) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
    """The entries of the coordinate lines ``row column value`` of a file from byte ``offset``
    on, parsed and checked in one pass by the compiled kernel, or None.

    Every line must have the plain form of :func:`~pymorembs.io.compiled_kernels.
    coordinate_lines` (indices ``1 .. n``), and there must be ``entries`` lines; the values are
    the correctly rounded doubles of the decimal numbers, as Python's ``float`` reads them.
    The file is mapped into memory and parsed in blocks of :data:`_PARSE_BLOCK` bytes, each in
    parts on the solver threads (:func:`_threads`).

    Returns None without Numba, for any line of another form, another number of lines, a
    number that needs more than 19 significant digits or is subnormal, or a read error: the
    caller then reads the file by its general path, which names a bad line.

    Parameters
    ----------
    path : path-like
        The file.
    offset : int
        Byte offset of the first entry line.
    n : int
        Matrix size (indices count from 1 to ``n``).
    entries : int
        Entry lines announced by the size line.
    out : tuple of ndarray, optional
        ``rows``, ``cols`` (int32) and ``values`` (float64) of shape (entries,) to fill, e.g.
        those of a :class:`SymmetricRoom`; by default new arrays.
    upper_columns : bool
        The lines must be the upper triangle column by column (``row <= column``, each
        position after the one of the line before: CalculiX's order), else None; entries off
        the diagonal whose value is zero are left out (fewer entries are returned).

    Returns
    -------
    rows, cols : ndarray of int32, shape (stored,)
        Indices counted from 0, in file order (the start of ``out``'s arrays if given);
        ``stored`` is ``entries`` unless ``upper_columns`` left zeros out.
    values : ndarray of float64, shape (stored,)
    """
    kernels = _kernels()
    if kernels is None or entries <= 0 or n >= 2**31 - 1:
        return None
    if out is None:
        index = np.int32
        out = (np.empty(entries, dtype=index), np.empty(entries, dtype=index), np.empty(entries))
    rows, cols, values = out
    target = _Entries(rows, cols, values, values.view(np.uint64), n, upper_columns)
    try:
        with (
            open(path, "rb") as stream,
            mmap.mmap(stream.fileno(), 0, access=mmap.ACCESS_READ) as mapped,
        ):
            done = _parse_mapped(kernels, mapped, offset, target)
    except (OSError, ValueError):  # unreadable, or empty (nothing to map)
        return None
    if done != entries:
        return None
    stored = target.stored
    if stored == rows.size:
        return rows, cols, values
    return rows[:stored], cols[:stored], values[:stored]


def count_line_ends(path: str | os.PathLike[str]) -> int | None:
    """Line feeds in a file, counted by the compiled kernel
    (:func:`~pymorembs.io.compiled_kernels.count_lines`) through a memory map, in parts on the
    solver threads.

    Parameters
    ----------
    path : path-like
        The file.

    Returns
    -------
    int or None
        The count; None without Numba or when the file cannot be mapped (unreadable or empty).
    """
    kernels = _kernels()
    if kernels is None:
        return None
    try:
        with (
            open(path, "rb") as stream,
            mmap.mmap(stream.fileno(), 0, access=mmap.ACCESS_READ) as mapped,
        ):
            return _count_mapped(kernels, mapped)
    except (OSError, ValueError):
        return None


def _count_mapped(kernels, mapped: mmap.mmap) -> int:
    """Line feeds of a mapped file (:func:`count_line_ends`), in blocks of
    :data:`_PARSE_BLOCK` bytes whose pages are unmapped again once counted (as the parse does):
    the file never counts in the process's memory by more than a block."""
    data = np.frombuffer(mapped, dtype=np.uint8)
    try:
        total, start = 0, 0
        while start < data.size:
            stop = min(start + _PARSE_BLOCK, data.size)
            total += _count_buffer(kernels, data[start:stop])
            if _UNMAP is not None:
                mapped.madvise(_UNMAP, start, stop - start)
            start = stop
        return total
    finally:
        del data  # the mapping closes only without exports of its buffer


def _count_buffer(kernels, buffer: np.ndarray) -> int:
    """Line feeds of ``buffer`` (bytes), in parts on the solver threads (at least
    :data:`_PART_BYTES` each)."""
    parts = _threads(buffer.size // _PART_BYTES)
    return sum(_over_ranges(kernels.count_lines, (buffer,), buffer.size, parts))


@dataclass
class _Entries:
    """The arrays :func:`parse_coordinate_lines` fills and how far it got."""

    rows: np.ndarray
    cols: np.ndarray
    values: np.ndarray
    bits: np.ndarray  # values viewed as uint64
    n: int
    upper_columns: bool
    stored: int = 0  # entries stored so far
    last_key: int = -1  # key of the last line parsed (upper_columns)


def _parse_mapped(kernels, mapped: mmap.mmap, offset: int, target: _Entries) -> int:
    """Lines parsed from the mapped file's bytes ``offset ..`` into ``target`` (see
    :func:`parse_coordinate_lines`), or -1.

    The kernels read the page cache through the mapping, without a copy. Blocks of
    :data:`_PARSE_BLOCK` bytes end at a line end; each block's pages are unmapped again once it
    is parsed, so that the file never counts in the process's memory by more than a block.
    White space at the end of the file (blank lines) holds no entry; the last line, which then
    has no line end, is parsed from a copy with one.
    """
    data = np.frombuffer(mapped, dtype=np.uint8)
    try:
        end = data.size
        while end > offset:  # the end of the last line
            tail = data[max(offset, end - _LINE_SEARCH) : end].tobytes()
            kept = tail.rstrip(b" \t\r\n")
            end -= len(tail) - len(kept)
            if kept:
                break
        before = data[max(offset, end - _LINE_SEARCH) : end].tobytes().rfind(b"\n")
        last_start = offset if before < 0 else max(offset, end - _LINE_SEARCH) + before + 1
        if end > offset and before < 0 and end - offset > _LINE_SEARCH:
            return -1  # a last line longer than any line of numbers
        done, start, unmapped = 0, offset, 0
        while start < last_start:
            stop = min(start + _PARSE_BLOCK, last_start)
            search = data[max(start, stop - _LINE_SEARCH) : stop].tobytes()
            at = search.rfind(b"\n")
            if at < 0:
                return -1  # no line end in the search window: not a file of number lines
            cut = stop - len(search) + at + 1
            lines = _parse_block(kernels, data[start:cut], target)
            if lines is None:
                return -1
            done += lines
            start = cut
            page = start - start % mmap.PAGESIZE
            if page > unmapped and _UNMAP is not None:
                mapped.madvise(_UNMAP, unmapped, page - unmapped)
                unmapped = page
        if last_start < end:
            line = np.append(data[last_start:end], np.uint8(_NEWLINE))
            lines = _parse_block(kernels, line, target)
            if lines is None:
                return -1
            done += lines
        return done
    finally:
        del data  # the mapping closes only without exports of its buffer


def _parse_block(kernels, buffer: np.ndarray, target: _Entries) -> int | None:
    """Lines of ``buffer`` (whole lines) parsed into ``target``'s entries from
    ``target.stored`` on, in parts on the solver threads (at least :data:`_PART_BYTES`
    each), or None.

    Part ``p`` writes from the entry after the lines of the parts before it (counted first);
    with ``upper_columns``, which leaves zeros out, the parts' entries are then moved together,
    and the order of the lines is checked across the parts and blocks by their first and last
    keys.
    """
    size = buffer.size
    parts = _threads(size // _PART_BYTES)
    bounds = [0]
    for p in range(1, parts):
        aim = max(size * p // parts, bounds[-1])
        stop = min(aim + _LINE_SEARCH, size)
        at = buffer[aim:stop].tobytes().find(b"\n")
        bounds.append(bounds[-1] if at < 0 else aim + at + 1)
    bounds.append(size)
    done = target.stored
    starts = [done]
    if parts > 1:  # the lines before each part (the last part's are not needed)
        counts = _concurrently(
            [
                functools.partial(kernels.count_lines, buffer, first, last)
                for first, last in itertools.pairwise(bounds[:-1])
            ]
        )
        starts += (done + np.cumsum(counts)).tolist()
    t = target
    arrays = (t.n, t.rows, t.cols, t.values, t.bits)
    tail = (kernels.POWERS_OF_FIVE, t.upper_columns)
    results = _concurrently(
        [
            functools.partial(kernels.coordinate_lines, buffer, first, last, *arrays, start, *tail)
            for first, last, start in zip(bounds[:-1], bounds[1:], starts, strict=True)
        ]
    )
    total = 0
    for (lines, stored, first_key, last_key), start, following in zip(
        results, starts, [*starts[1:], None], strict=True
    ):
        if lines < 0 or (following is not None and start + lines != following):
            return None
        if lines and t.upper_columns:
            if first_key <= t.last_key:
                return None  # a position not after the one of the line before
            t.last_key = last_key
        if start != t.stored:
            for array in (t.rows, t.cols, t.values):
                array[t.stored : t.stored + stored] = array[start : start + stored]
        t.stored += stored
        total += lines
    return total


def all_distinct(keys: np.ndarray) -> bool:
    """Whether no value of a 1-D array occurs twice (by one sort: NumPy's hash-based
    ``unique`` is many times slower on integer keys that are all distinct).

    Parameters
    ----------
    keys : ndarray, shape (k,)

    Returns
    -------
    bool
    """
    ordered = np.sort(keys)
    return not bool(np.any(ordered[1:] == ordered[:-1]))


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
    return canonical_csr(values, cols.astype(index, copy=False), indptr, (n, n))
