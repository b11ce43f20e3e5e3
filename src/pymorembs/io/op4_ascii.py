"""Vectorised reader of ASCII (formatted) OUTPUT4 files with real matrices.

pyNastran reads an ASCII OP4 file line by line and value by value in Python; for a 2 GB export
of a 300,000-dof model that takes minutes and ten times the matrices' memory. This reader
streams the file in blocks (:mod:`pymorembs.io.line_blocks`) and classifies every line with
NumPy:

* a matrix header (``%8i%8i%8i%8i%-8s`` and a Fortran format such as ``1P,3E22.15``; the only
  lines with a comma), parsed like pyNastran parses it;
* an integer line: a column header ``ICOL IROW NW`` (three integers) or, in the sparse format, a
  string header (``IROW`` of the string; BIGMAT: two integers ``L+1 IROW``, else one,
  ``IS = 65536 (L + 1) + IROW``);
* a value line: numbers of the format's width, one ``E`` each, touching (``-1.0E+00-2.0E+00``);
  all value lines of a matrix are cut into fixed-width fields and converted by one ``astype``.

It returns exactly what pyNastran returns for the files it accepts (the values converted to the
precision of the matrix type, ``float32`` for type 1), with the sparse matrices as CSC matrices,
and None for anything it does not read the same way -- complex matrices, blank lines, tabs,
trailing blanks, a string header where pyNastran would read something else, repeated names,
rows out of order or out of range, a column word count that would stop pyNastran early -- so
that the caller can give such a file to pyNastran (and its messages) instead.
"""

from __future__ import annotations

import itertools
import os
from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp

from pymorembs.io.line_blocks import iter_line_blocks, line_starts

__all__ = ["Op4Matrix", "read_ascii_op4"]

#: Bytes of value and integer lines.
_NUMERIC = b"0123456789 .+-E\n"
_SPACE, _MINUS, _E, _COMMA = (ord(c) for c in " -E,")
#: Widest integer line read (three fields of up to 10 characters).
_INT_WIDTH = 32
_H, _C, _S, _V = 1, 2, 3, 4
#: Largest dense-format matrix read here (bytes); larger ones go to the caller's checks.
DENSE_LIMIT = 4 << 30


@dataclass
class Op4Matrix:
    """One matrix as pyNastran gives it: ``data`` a dense array (dense format) or a CSC matrix
    (sparse format) of ``float32`` (type 1) or ``float64`` (type 2)."""

    name: str
    form: int
    tin: int
    data: np.ndarray | sp.csc_matrix


class _NotHandled(Exception):
    """The file is one this reader does not read exactly as pyNastran does."""


@dataclass
class _Matrix:
    name: str
    ncols: int
    nrows: int
    form: int
    tin: int
    big: bool
    width: int
    line: int
    sparse: bool | None = None
    capacity: int = 0
    rows: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int32))
    values: np.ndarray = field(default_factory=lambda: np.zeros(0))
    stored: int = 0
    counts: np.ndarray | None = None

    @property
    def dtype(self) -> type:
        return np.float32 if self.tin == 1 else np.float64


def read_ascii_op4(path: str | os.PathLike[str]) -> dict[str, Op4Matrix] | None:
    """The matrices of an ASCII OP4 file by name (in file order), or None if this reader does
    not read the file exactly as pyNastran does (then use pyNastran)."""
    try:
        size = os.path.getsize(path)
    except OSError:
        return None
    reader = _Reader(size)
    try:
        for text, ends, first in iter_line_blocks(path):
            reader.block(text, ends, first)
        return reader.finish()
    except Exception:  # _NotHandled, a bad number or anything else: pyNastran decides
        return None


class _Reader:
    """The state carried from block to block."""

    def __init__(self, size: int) -> None:
        self.remaining = size  # bytes not yet read: a bound on a matrix's number of values
        self.matrices: list[_Matrix] = []
        self.state = "start"  # "start", "first" (column line next), "body", "skip", "done"
        self.col = 0  # current column (from 1), 0 before the first
        self.nwords = 0  # its word count
        self.cum = 0  # values read in it
        self.must_column = False  # pyNastran's word count ran out: a column header follows
        self.anchored = False  # the row of the next value is known (string or dense column)
        self.next_row = 0  # row (from 1) of the next value
        self.last_key = -1  # col * (nrows + 1) + row of the last value

    def block(self, text: np.ndarray, ends: np.ndarray, first: int) -> None:
        """Classify the lines of a block and read them, matrix by matrix."""
        starts = line_starts(ends)
        lengths = ends - starts
        if np.any(lengths == 0):
            raise _NotHandled  # pyNastran ends the file at a blank header line
        comma = np.zeros(ends.size, dtype=bool)
        if text.tobytes().translate(None, _NUMERIC):  # other bytes: only in header lines
            other = np.flatnonzero(~np.isin(text, np.frombuffer(_NUMERIC, np.uint8)))
            line = np.searchsorted(ends, other)
            comma[line[text[other] == _COMMA]] = True
            if not comma[line].all() or np.any((text[other] < 32) | (text[other] > 126)):
                raise _NotHandled
        e_lines = np.searchsorted(ends, np.flatnonzero(text == _E))
        e_count = np.bincount(e_lines, minlength=ends.size)
        kind = np.where(comma, _H, np.where(e_count > 0, _V, _C))
        heads = np.flatnonzero(kind == _H).tolist()
        for a, b in itertools.pairwise([0, *heads, ends.size]):
            if a < b and kind[a] == _H:
                self._header(text[starts[a] : ends[a]].tobytes().decode("ascii"), first + a)
                a += 1
            if a < b:
                self._segment(text, starts[a:b], lengths[a:b], kind[a:b], e_count[a:b])
        self.remaining = max(self.remaining - text.size, 0)

    def _header(self, line: str, number: int) -> None:
        """A matrix header line, parsed as pyNastran parses it."""
        if self.state not in ("start", "done"):
            raise _NotHandled
        line = line.rstrip()
        ncols_text, nrows_text, form_text, type_text = line[0:32].split()
        nrows, ncols, form, tin = (int(t) for t in (nrows_text, ncols_text, form_text, type_text))
        if nrows == 0 or ncols <= 0 or tin not in (1, 2):
            raise _NotHandled
        big = nrows < 0 or nrows > 65535
        width = int(line[40:].strip().split(",")[1].split("E")[1].split(".")[0])
        name = line[32:40].strip()
        if width <= 0 or any(m.name == name for m in self.matrices):
            raise _NotHandled
        matrix = _Matrix(name, ncols, abs(nrows), form, tin, big, width, number)
        # room for as many values as the rest of the file can hold: pages never written are
        # never in memory, and the values need no list of pieces and no concatenation
        matrix.capacity = self.remaining // width + 1
        matrix.rows = np.empty(matrix.capacity, dtype=np.int32)
        matrix.values = np.empty(matrix.capacity, dtype=matrix.dtype)
        matrix.counts = np.zeros(ncols + 1, dtype=np.int64)
        self.matrices.append(matrix)
        self.state = "first"
        self.col = self.nwords = self.cum = self.next_row = 0
        self.must_column = self.anchored = False
        self.last_key = -1

    def _segment(
        self,
        text: np.ndarray,
        starts: np.ndarray,
        lengths: np.ndarray,
        kind: np.ndarray,
        e_count: np.ndarray,
    ) -> None:
        """Lines of one matrix (no header among them) within a block."""
        if not self.matrices or self.state in ("start", "done"):
            raise _NotHandled
        m = self.matrices[-1]
        count = np.where(kind == _V, lengths // m.width, 0)
        value = kind == _V
        if np.any(lengths[value] % m.width) or np.any(e_count[value] != count[value]):
            raise _NotHandled
        if self.state == "skip":  # the value line after the closing column
            if kind.size != 1 or count[0] != 1:
                raise _NotHandled
            self.state = "done"
            return
        ints = np.flatnonzero(~value)
        tokens, numbers = _integers(text, starts[ints], lengths[ints])
        if np.any((tokens < 1) | (tokens > 3)):
            raise _NotHandled
        at = np.concatenate([[0], np.cumsum(tokens)[:-1]])  # first number of each integer line
        kind[ints] = np.where(tokens == 3, _C, _S)
        if self.state == "first":
            if kind[0] != _C:
                raise _NotHandled
            m.sparse = bool(numbers[at[0] + 1] == 0)
            self.state = "body"
        # line index -> its numbers (for integer lines)
        first_number = np.full(kind.size, -1, dtype=np.int64)
        first_number[ints] = at
        column_lines = np.flatnonzero(kind == _C)
        icol = numbers[first_number[column_lines]]
        closing = np.flatnonzero(icol > m.ncols)
        stop = kind.size
        if closing.size:
            stop = int(column_lines[closing[0]])
            after = kind.size - stop - 1
            if closing[0] != column_lines.size - 1 or after > 1:
                raise _NotHandled
            if after == 1 and count[-1] != 1:
                raise _NotHandled
            column_lines, icol = column_lines[:-1], icol[:-1]
        ntok = np.zeros(kind.size, dtype=np.int64)
        ntok[ints] = tokens
        self._body(
            m,
            text,
            starts,
            lengths,
            kind[:stop],
            count[:stop],
            numbers,
            first_number,
            ntok,
            column_lines,
            icol,
            next_is_column=bool(closing.size),
        )
        if closing.size:
            self.state = "done" if kind.size - stop == 2 else "skip"

    def _body(
        self,
        m,
        text,
        starts,
        lengths,
        kind,
        count,
        numbers,
        first_number,
        ntok,
        column_lines,
        icol,
        next_is_column: bool,
    ) -> None:
        """Column headers, string headers and values before the closing column."""
        n = kind.size
        if n == 0:
            return
        if np.any(np.diff(np.concatenate([[self.col], icol])) <= 0):
            raise _NotHandled  # columns must increase
        if self.must_column and kind[0] != _C:
            raise _NotHandled
        position = np.arange(n)
        last_column = np.maximum.accumulate(np.where(kind == _C, position, -1))
        string_lines = np.flatnonzero(kind == _S)
        if m.sparse:
            s_first = first_number[string_lines]
            big = m.big
            if np.any(ntok[string_lines] != (2 if big else 1)):
                raise _NotHandled  # pyNastran would read another line as the string header
            if big:
                anchor_row = numbers[s_first + 1] if string_lines.size else np.zeros(0, np.int64)
            else:
                first_words = numbers[s_first] if string_lines.size else np.zeros(0, np.int64)
                if np.any(first_words <= 0):
                    raise _NotHandled
                anchor_row = first_words % 65536
            anchor_lines = string_lines
        else:
            if string_lines.size:
                raise _NotHandled  # a string header in a dense matrix
            anchor_lines = column_lines
            anchor_row = numbers[first_number[column_lines] + 1]
        if np.any(anchor_row < 1):
            raise _NotHandled
        value_lines = np.flatnonzero(kind == _V)
        counts = count[value_lines]
        v_first = np.concatenate([[0], np.cumsum(counts)])  # values before each value line
        total = int(v_first[-1])
        anchor_of = np.maximum.accumulate(np.where(np.isin(position, anchor_lines), position, -1))
        row_of_anchor = np.zeros(n, dtype=np.int64)
        row_of_anchor[anchor_lines] = anchor_row
        values_before = np.zeros(n + 1, dtype=np.int64)  # values before line p
        values_before[value_lines + 1] = counts
        values_before = np.cumsum(values_before)
        a = anchor_of[value_lines]
        c = last_column[value_lines]
        carried = a < 0
        if m.sparse and np.any((a >= 0) & (a < c)):
            raise _NotHandled  # values of a new column before its first string header
        if np.any(carried & (c >= 0)) or (carried.any() and not self.anchored):
            raise _NotHandled
        start_row = np.where(
            carried,
            self.next_row + values_before[value_lines],
            row_of_anchor[np.maximum(a, 0)]
            + values_before[value_lines]
            - values_before[np.maximum(a, 0)],
        )
        column = np.where(c >= 0, numbers[first_number[np.maximum(c, 0)]], self.col)
        if np.any(column < 1):
            raise _NotHandled
        rows = np.repeat(start_row - v_first[:-1], counts) + np.arange(total)
        cols = np.repeat(column, counts)
        if total:
            if rows.max() > m.nrows:
                raise _NotHandled
            key = cols * (m.nrows + 1) + rows
            if key[0] <= self.last_key or np.any(np.diff(key) <= 0):
                raise _NotHandled
            self.last_key = int(key[-1])
        # pyNastran's word count: when it reaches 0 exactly, a column header must follow
        nwords_of = np.where(c >= 0, numbers[first_number[np.maximum(c, 0)] + 2], self.nwords)
        cum_start = np.where(c >= 0, values_before[np.maximum(c, 0)], -self.cum)
        cum_after = values_before[value_lines + 1] - cum_start
        hits = np.flatnonzero(cum_after == nwords_of)
        follow = value_lines[hits] + 1
        inside = follow < n
        if np.any(kind[follow[inside]] != _C):
            raise _NotHandled
        self.must_column = bool((~inside).any()) and not next_is_column
        # values
        if total:
            values = self._parse(m, text, starts, lengths, value_lines)
            end = m.stored + total
            if end > m.capacity:
                raise _NotHandled
            m.rows[m.stored : end] = rows - 1
            m.values[m.stored : end] = values
            m.stored = end
            m.counts += np.bincount(cols, minlength=m.ncols + 1)[: m.ncols + 1]
        # state for the next block
        if column_lines.size:
            last = int(column_lines[-1])
            self.col = int(numbers[first_number[last]])
            self.nwords = int(numbers[first_number[last] + 2])
            self.cum = int(values_before[n] - values_before[last])
        else:
            self.cum += total
        last_anchor = int(anchor_of[-1])
        if last_anchor >= 0 and (not m.sparse or last_anchor > last_column[-1]):
            self.anchored = True
            self.next_row = int(
                row_of_anchor[last_anchor] + values_before[n] - values_before[last_anchor]
            )
        elif last_column[-1] >= 0:
            self.anchored = not m.sparse
            self.next_row = 0
        else:
            self.next_row += total

    @staticmethod
    def _parse(m, text, starts, lengths, value_lines) -> np.ndarray:
        """The values of the value lines, fixed-width fields converted by one ``astype``."""
        first, last = int(value_lines[0]), int(value_lines[-1])
        a, b = int(starts[first]), int(starts[last] + lengths[last])
        keep = np.zeros(last + 1 - first, dtype=bool)
        keep[value_lines - first] = True
        span = lengths[first : last + 1] + 1
        mask = np.repeat(keep, span)
        mask[np.cumsum(span) - 1] = False  # the line feeds
        fields = text[a : b + 1][mask]
        values = np.ascontiguousarray(fields).view(f"S{m.width}").astype(m.dtype)
        if not np.isfinite(values).all():
            raise _NotHandled
        return values

    def finish(self) -> dict[str, Op4Matrix]:
        """The matrices, once the whole file is read."""
        if self.state not in ("done", "skip"):  # pyNastran stops at the end of the file too
            raise _NotHandled
        out: dict[str, Op4Matrix] = {}
        for m in self.matrices:
            rows, values = m.rows[: m.stored], m.values[: m.stored]
            counts = m.counts[1:]
            if m.sparse:
                indptr = np.concatenate([[0], np.cumsum(counts)]).astype(np.int64)
                index = np.int32 if indptr[-1] < 2**31 - 1 else np.int64
                data = sp.csc_matrix(
                    (values, rows.astype(index, copy=False), indptr.astype(index)),
                    shape=(m.nrows, m.ncols),
                )
                data.has_sorted_indices = True
            else:
                if m.nrows * m.ncols * np.dtype(m.dtype).itemsize > DENSE_LIMIT:
                    raise _NotHandled
                data = np.zeros((m.nrows, m.ncols), dtype=m.dtype)
                data[rows, np.repeat(np.arange(m.ncols), counts)] = values
            out[m.name] = Op4Matrix(m.name, m.form, m.tin, data)
        return out


def _integers(
    text: np.ndarray, starts: np.ndarray, lengths: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """(tokens per line, all integers in order) of integer lines (digits, blanks, minus signs
    only at the start of a token)."""
    if starts.size == 0:
        return np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int64)
    if np.any(lengths > _INT_WIDTH):
        raise _NotHandled
    columns = np.arange(_INT_WIDTH)
    inside = columns[None, :] < lengths[:, None]
    block = np.where(inside, text[np.minimum(starts[:, None] + columns, text.size - 1)], _SPACE)
    block = block.astype(np.uint8)
    filled = block != _SPACE
    begin = filled.copy()
    begin[:, 1:] &= ~filled[:, :-1]
    minus = block == _MINUS
    digit = (block >= ord("0")) & (block <= ord("9"))
    if np.any(filled & ~digit & ~minus) or np.any(minus & ~begin):
        raise _NotHandled
    after = np.zeros_like(minus)
    after[:, :-1] = minus[:, :-1] & ~digit[:, 1:]
    if after.any() or np.any(minus[:, -1]):
        raise _NotHandled
    tokens = begin.sum(axis=1)
    rows = np.hstack([block, np.full((block.shape[0], 1), 10, dtype=np.uint8)])
    numbers = np.fromstring(rows.tobytes(), dtype=np.int64, sep=" ")
    if numbers.size != int(tokens.sum()):
        raise _NotHandled
    return tokens, numbers
