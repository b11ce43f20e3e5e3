"""Compiled kernels of the text readers (only imported with Numba).

:func:`plain_number_fields` walks the bytes of a chunk once and applies the rules of
:class:`~pymorembs.io.fast_text.PlainNumberScan` in the same terms as the vectorised
``check_chunk_numpy``: the non-digit bytes are the *entries*, a run of white bytes is one entry
of the highest class in the run, each entry carries whether digits follow it, and every entry
between two others is judged by the table of entry triples of the vectorised check (so both
accept exactly the same bytes). It holds the GIL for none of its work, so it runs beside the
threads of the parser that reads the same bytes.

:func:`mirror_counts` / :func:`mirror_rows` complete a stored triangle to the full symmetric CSR
matrix and :func:`rows_gap` finds ``max |A - A^T|``, each in one pass over the entries
(:func:`mirror_parallel`, :func:`transpose_gap_parallel`: the same on several threads).
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
    row of its column. Returns whether the triangle is the lower one (an entry below the
    diagonal)."""
    n = indptr.size - 1
    lower = False
    for i in range(n):
        for q in range(indptr[i], indptr[i + 1]):
            j = indices[q]
            out_indptr[i + 1] += 1
            if j != i:
                out_indptr[j + 1] += 1
                if j < i:
                    lower = True
    for i in range(n):
        out_indptr[i + 1] += out_indptr[i]
    return lower


@numba.njit(cache=True, nogil=True)
def mirror_rows(
    indptr, indices, data, out_indptr, out_indices, out_data, lower, first, last
):  # pragma: no cover - compiled
    """Fill rows ``first .. last - 1`` of the full symmetric matrix of a canonical triangle.

    A row of the lower triangle is its own entries (columns up to ``i``) followed by the
    mirrored ones (columns after ``i``); of the upper triangle first the mirrored ones, then its
    own. The mirrored entries of row ``j`` are the entries ``(i, j)``, ``i != j``, of the other
    rows, found by visiting those rows in increasing order, so they come out sorted.
    """
    n = indptr.size - 1
    position = np.empty(last - first, dtype=out_indptr.dtype)
    for i in range(first, last):
        own = indptr[i + 1] - indptr[i]
        start = out_indptr[i] if lower else out_indptr[i + 1] - own
        for k in range(own):
            out_indices[start + k] = indices[indptr[i] + k]
            out_data[start + k] = data[indptr[i] + k]
        position[i - first] = out_indptr[i] + own if lower else out_indptr[i]
    # the rows that hold entries of columns first .. last - 1 off the diagonal
    rows_from, rows_to = (first, n) if lower else (0, last)
    for i in range(rows_from, rows_to):
        row = indices[indptr[i] : indptr[i + 1]]
        # the columns first .. last - 1 of the row (sorted)
        for q in range(indptr[i] + np.searchsorted(row, first), indptr[i + 1]):
            j = indices[q]
            if j >= last:
                break
            if j != i:
                p = position[j - first]
                out_indices[p] = i
                out_data[p] = data[q]
                position[j - first] = p + 1


@numba.njit(cache=True, nogil=True, parallel=True)
def mirror_parallel(
    indptr, indices, data, out_indptr, out_indices, out_data, lower, parts
):  # pragma: no cover - compiled
    """:func:`mirror_rows` of all rows in ``parts`` contiguous ranges on Numba's threads."""
    n = indptr.size - 1
    for part in numba.prange(parts):
        mirror_rows(
            indptr,
            indices,
            data,
            out_indptr,
            out_indices,
            out_data,
            lower,
            n * part // parts,
            n * (part + 1) // parts,
        )


@numba.njit(cache=True, nogil=True, parallel=True)
def transpose_gap_parallel(indptr, indices, data, parts):  # pragma: no cover - compiled
    """``max |A - A^T|`` of a canonical square CSR matrix (NaN if a difference is NaN), the rows
    shared out to Numba's threads in ``parts`` contiguous ranges (:func:`rows_gap` each)."""
    n = indptr.size - 1
    gaps = np.zeros(parts)
    for part in numba.prange(parts):
        gaps[part] = rows_gap(indptr, indices, data, n * part // parts, n * (part + 1) // parts)
    gap = 0.0
    for part in range(parts):
        if gaps[part] != gaps[part]:
            return gaps[part]
        if gaps[part] > gap:
            gap = gaps[part]
    return gap


@numba.njit(cache=True, nogil=True)
def rows_gap(indptr, indices, data, first, last):  # pragma: no cover - compiled
    """``max |a_ij - a_ji|`` over the entries ``(i, j)`` of rows ``first .. last - 1``.

    Entry ``(i, j)`` is compared with ``(j, i)`` (or zero where there is none). Row ``j`` is
    searched with a cursor of its own: the rows ``i`` that look into it come in increasing
    order, and so do the columns ``i`` sought there, so each cursor only moves forward and the
    whole comparison is one pass over the entries.
    """
    cursor = indptr[:-1].copy()
    gap = 0.0
    for i in range(first, last):
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
