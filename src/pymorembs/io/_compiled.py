"""Compiled kernels of the text readers (only imported with Numba).

:func:`plain_number_fields` walks the bytes of a chunk once and applies the rules of
:class:`~pymorembs.io.fast_text.PlainNumberScan` in the same terms as the vectorised
``check_chunk_numpy``: the non-digit bytes are the *entries*, a run of white bytes is one entry
of the highest class in the run, each entry carries whether digits follow it, and every entry
between two others is judged by the table of entry triples of the vectorised check (so both
accept exactly the same bytes). It holds the GIL for none of its work, so it runs beside the
threads of the parser that reads the same bytes.

:func:`mirror_counts` / :func:`mirror_fill` complete a stored triangle to the full symmetric CSR
matrix and :func:`transpose_gap` finds ``max |A - A^T|``, each in one pass over the entries.
"""

from __future__ import annotations

import numba
import numpy as np

#: Entry classes, as in :mod:`pymorembs.io.fast_text` (white first: space/tab, CR, LF).
_CR, _NL = 1, 2


@numba.njit(cache=True, nogil=True)
def plain_number_fields(
    chunk, fields_per_line, integer_fields, lines, classes, bad
):  # pragma: no cover - compiled
    """Fields of ``chunk`` (uint8, whole lines framed by line feeds), or -1 if a check fails.

    ``classes``: entry class of each byte value; ``bad``: the triple table (``_BAD_TRIPLE``, or
    ``_BAD_IN_LINE`` with ``lines`` for the Matrix Market line layout); ``fields_per_line`` 0
    for no layout check.
    """
    n = chunk.size
    if n == 0:
        return 0
    k = fields_per_line
    a = np.int64(0)  # codes (class * 2 + digits follow) of the two entries before the current
    b = np.int64(0)
    done = 0  # entries finished so far
    kind = -1  # class of the current entry (-1: none yet)
    digits = 0  # whether digits follow the current entry
    whites = 0  # white entries (separators) finished
    line_ends = 0
    second = -1  # class of the second entry
    integer_next = False  # the last finished entry is a separator before an integer field
    for i in range(n):
        byte = chunk[i]
        if byte - 48 <= 9 and byte >= 48:
            digits = 1
            continue
        c = np.int64(classes[byte])
        if kind >= 0 and kind <= _NL and c <= _NL and digits == 0:
            if c > kind:  # one more white byte of the run: the run takes the highest class
                kind = c
            continue
        if kind >= 0:
            # finish the current entry, then judge the entry before it between its neighbours
            code = kind * 2 + digits
            if done >= 2 and bad[(a << 8) | (b << 4) | code]:
                return -1
            if done == 1:
                second = kind
            if kind <= _NL:
                if kind == _NL:
                    line_ends += 1
                if not lines and k > 0:
                    if whites > 0 and (kind == _NL) != (whites % k == 0):
                        return -1  # a line of another number of fields
                    integer_next = whites % k < integer_fields
                whites += 1
            elif integer_next:
                return -1  # a sign, point or letter in an integer field
            else:
                integer_next = False
            a, b = b, code
            done += 1
        kind = c
        digits = 0
    # the last entry (the frame's line end: no digits follow)
    code = kind * 2
    if done >= 2 and bad[(a << 8) | (b << 4) | code]:
        return -1
    if done == 1:
        second = kind
    if kind <= _NL:
        if kind == _NL:
            line_ends += 1
        if not lines and k > 0 and whites > 0 and (kind == _NL) != (whites % k == 0):
            return -1
        whites += 1
    elif integer_next:
        return -1
    done += 1
    if lines:
        if done > 1 and second != 0:
            return -1  # the first line does not start "digits blank"
        return 3 * (line_ends - 1)
    fields = whites - 1
    if k > 0 and fields % k:
        return -1
    return fields


@numba.njit(cache=True, nogil=True)
def mirror_counts(indptr, indices, out_indptr):  # pragma: no cover - compiled
    """Row pointer of the full symmetric matrix of a triangle in CSR form (``out_indptr``, n + 1
    entries, zeroed by the caller): every entry counts in its row and, off the diagonal, in the
    row of its column."""
    n = indptr.size - 1
    for i in range(n):
        for q in range(indptr[i], indptr[i + 1]):
            j = indices[q]
            out_indptr[i + 1] += 1
            if j != i:
                out_indptr[j + 1] += 1
    for i in range(n):
        out_indptr[i + 1] += out_indptr[i]


@numba.njit(cache=True, nogil=True)
def mirror_fill(indptr, indices, data, out_indptr, out_indices, out_data):  # pragma: no cover
    """Fill the full symmetric matrix of a canonical triangle (lower or upper) in CSR form.

    Rows are visited in order and every entry ``(i, j)`` is appended to row ``i`` and, off the
    diagonal, ``(j, i)`` to row ``j``. A row of the lower triangle receives its own entries
    (columns up to ``i``) before the mirrored ones (columns after ``i``, from later rows, in
    increasing order); of the upper triangle first the mirrored ones (from earlier rows) and
    then its own: either way the rows come out sorted.
    """
    n = indptr.size - 1
    position = out_indptr[:-1].copy()
    for i in range(n):
        for q in range(indptr[i], indptr[i + 1]):
            j = indices[q]
            value = data[q]
            p = position[i]
            out_indices[p] = j
            out_data[p] = value
            position[i] = p + 1
            if j != i:
                p = position[j]
                out_indices[p] = i
                out_data[p] = value
                position[j] = p + 1


@numba.njit(cache=True, nogil=True)
def transpose_gap(indptr, indices, data):  # pragma: no cover - compiled
    """``max |A - A^T|`` of a canonical square CSR matrix (NaN if a difference is NaN).

    Entry ``(i, j)`` is compared with ``(j, i)`` (or zero where there is none). Row ``j`` is
    searched with a cursor of its own: the rows ``i`` that look into it come in increasing
    order, and so do the columns ``i`` sought there, so each cursor only moves forward and the
    whole comparison is one pass over the entries.
    """
    n = indptr.size - 1
    cursor = indptr[:-1].copy()
    gap = 0.0
    for i in range(n):
        for q in range(indptr[i], indptr[i + 1]):
            j = indices[q]
            p = cursor[j]
            end = indptr[j + 1]
            while p < end and indices[p] < i:
                p += 1
            cursor[j] = p
            if p < end and indices[p] == i:
                difference = abs(data[q] - data[p])
            else:
                difference = abs(data[q])
            if difference != difference:
                return difference
            if difference > gap:
                gap = difference
    return gap
