"""Compiled kernels of the text readers (only imported with Numba).

:func:`plain_number_fields` walks the bytes of a chunk once and applies the rules of
:class:`~pymorembs.io.fast_text.PlainNumberScan` in the same terms as the vectorised
``check_chunk_numpy``: the non-digit bytes are the *entries*, a run of white bytes is one entry
of the highest class in the run, each entry carries whether digits follow it, and every entry
between two others is judged by the table of entry triples of the vectorised check (so both
accept exactly the same bytes). It holds the GIL for none of its work, so it runs beside the
threads of the parser that reads the same bytes.

:func:`mirror_counts` / :func:`mirror_rows` complete a stored triangle to the full symmetric CSR
matrix (:func:`rows_in_place`: a lower triangle in the arrays that hold it), in one pass over the
entries (``max |A - A^T|`` in one pass: :func:`pymorembs.linalg.compiled_kernels.rows_gap`).

:func:`coordinate_lines` parses the entry lines of a Matrix Market or CalculiX file and
:func:`count_lines` counts lines eight bytes at a time.

Every kernel is serial and releases the GIL (``nogil``): :mod:`pymorembs.io.fast_text` runs
them on Python threads, a part of the work each. None uses Numba's parallel compilation, whose
first compilation (after installing, before the cache is written) costs seconds more than the
threads save in a read.
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


@numba.njit(cache=True, nogil=True)
def rows_in_place(
    indptr, indices, data, offset, out_indptr, slots, first, last, own, mirrored
):  # pragma: no cover - compiled
    """Rows ``first .. last - 1`` of a lower triangle completed to the full symmetric CSR matrix
    in the arrays that hold it.

    Row ``i`` of the canonical lower triangle is ``indices[offset + indptr[i] : offset +
    indptr[i + 1]]`` (and the same slice of ``data``); ``out_indptr`` is the full matrix's row
    pointer (:func:`mirror_counts`) and ``slots[j]`` the next place of a mirrored entry in row
    ``j``, first ``out_indptr[j] + indptr[j + 1] - indptr[j]`` (after the row's own entries;
    advanced here). The full matrix is written to the front of the same arrays: with ``own``
    each entry of row ``i`` moves to its place in full row ``i``, with ``mirrored`` its mirror
    image ``(j, i)``, off the diagonal, goes to the next slot of row ``j`` (rows in increasing
    order, so the mirrored entries come out sorted). Both at once, for all rows in order, is
    the one-thread completion.

    No write reaches an entry not yet read if ``offset`` is at least the number of entries below
    the diagonal: the full rows before row ``i`` end at ``out_indptr[i] = indptr[i] +`` (entries
    below the diagonal in the columns before ``i``) ``<= offset + indptr[i]``, where row ``i`` is
    read, and each entry of row ``i`` moves to the front or stays. Two threads may do ``own``
    and ``mirrored`` of a block of rows whose full rows end before the block's first entry
    (:func:`pymorembs.io.fast_text.complete_lower_in_place`).
    """
    for i in range(first, last):
        w = out_indptr[i]
        for q in range(offset + indptr[i], offset + indptr[i + 1]):
            j = indices[q]
            v = data[q]
            if own:
                indices[w] = j
                data[w] = v
                w += 1
            if mirrored and j != i:
                p = slots[j]
                indices[p] = i
                data[p] = v
                slots[j] = p + 1


# ---------------------------------------------------------------------------- coordinate lines
_U64 = np.uint64
_LOW32 = np.uint64(0xFFFFFFFF)
_TOP = np.uint64(1) << np.uint64(63)
_TWO53 = np.uint64(1) << np.uint64(53)
#: Exact powers of ten as doubles (10**0 .. 10**22: every one of them is a double).
_EXACT_TENS = np.array([10.0**k for k in range(23)])
#: Decimal exponents covered by :data:`POWERS_OF_FIVE`.
SMALLEST_POWER, LARGEST_POWER = -342, 308


def _powers_of_five() -> np.ndarray:
    """The 128 most significant bits of ``5**q`` for ``q`` in ``SMALLEST_POWER ..
    LARGEST_POWER`` (two words per power, high word first) as the Eisel-Lemire conversion needs
    them: ``5**q`` scaled into ``[2**127, 2**128)`` and cut for ``q >= 0``; for ``q < 0``
    ``2**b // 5**-q + 1`` with ``b`` such that it is a 128-bit number (``b`` larger and the
    result cut for ``q < -27``), an upper bound of the scaled reciprocal."""
    words = []
    for q in range(SMALLEST_POWER, LARGEST_POWER + 1):
        if q < 0:
            power = 5**-q
            z = power.bit_length() if power & (power - 1) else power.bit_length() - 1
            b = z + 127 if q >= -27 else 2 * z + 128
            c = (1 << b) // power + 1
            while c >= 1 << 128:
                c >>= 1
        else:
            c = 5**q
            while c < 1 << 127:
                c <<= 1
            while c >= 1 << 128:
                c >>= 1
        words += [c >> 64, c & (2**64 - 1)]
    return np.array(words, dtype=np.uint64)


#: :func:`_powers_of_five` (1,302 words).
POWERS_OF_FIVE = _powers_of_five()


@numba.njit(cache=True, nogil=True)
def _product_128(a, b):  # pragma: no cover - compiled
    """(high, low) words of the 128-bit product of two 64-bit words."""
    a_lo, a_hi = a & _LOW32, a >> _U64(32)
    b_lo, b_hi = b & _LOW32, b >> _U64(32)
    p0, p1, p2, p3 = a_lo * b_lo, a_lo * b_hi, a_hi * b_lo, a_hi * b_hi
    middle = (p0 >> _U64(32)) + (p1 & _LOW32) + (p2 & _LOW32)
    low = (middle << _U64(32)) | (p0 & _LOW32)
    high = p3 + (p1 >> _U64(32)) + (p2 >> _U64(32)) + (middle >> _U64(32))
    return high, low


@numba.njit(cache=True, nogil=True)
def decimal_to_bits(w, q, powers):  # pragma: no cover - compiled
    """IEEE bits of the double nearest to ``w * 10**q`` (ties to even), for a decimal
    significand ``0 < w < 2**64`` (at most 19 digits, so exact) and ``SMALLEST_POWER <= q <=
    LARGEST_POWER``; 0 when the result would be subnormal or overflow (the caller then leaves
    the number to a strict parser).

    The Eisel-Lemire method (Lemire, "Number parsing at a gigabyte per second", 2021): the
    normalised significand times the 128-bit power of five of :data:`POWERS_OF_FIVE` gives the
    leading 54 bits of the result and the binary exponent from ``q * log2(10)``; the second
    word of the power is needed only when the low bits of the first product are all ones, and
    Mushtak and Lemire ("Fast number parsing without fallback", 2023) proved that the two words
    always decide the rounding for significands of at most 19 digits.
    """
    shift = _U64(0)
    for step in (32, 16, 8, 4, 2, 1):
        if w < (_U64(1) << _U64(64 - step)):
            w = w << _U64(step)
            shift += _U64(step)
    index = 2 * (q - SMALLEST_POWER)
    high, low = _product_128(w, powers[index])
    if (high & _U64(0x1FF)) == _U64(0x1FF):
        second_high, _ = _product_128(w, powers[index + 1])
        low = low + second_high
        if second_high > low:
            high = high + _U64(1)
    upper = high >> _U64(63)
    drop = upper + _U64(9)
    mantissa = high >> drop
    power2 = ((217706 * q) >> 16) + 63 + np.int64(upper) - np.int64(shift) + 1023
    if power2 <= 0:
        return _U64(0)  # subnormal
    if low <= _U64(1) and -4 <= q <= 23 and (mantissa & _U64(3)) == _U64(1):
        if (mantissa << drop) == high:
            mantissa = mantissa & ~_U64(1)  # exactly half way: round to even
    mantissa = mantissa + (mantissa & _U64(1))
    mantissa = mantissa >> _U64(1)
    if mantissa >= (_U64(2) << _U64(52)):
        mantissa = _U64(1) << _U64(52)
        power2 += 1
    mantissa = mantissa & ~(_U64(1) << _U64(52))
    if power2 >= 0x7FF:
        return _U64(0)  # overflow
    return mantissa | (_U64(power2) << _U64(52))


#: Every byte of a word: 0x7F, 0x80, the line feed; every other byte; every 16-bit 1.
_SEVENS = np.uint64(0x7F7F7F7F7F7F7F7F)
_HIGHS = np.uint64(0x8080808080808080)
_LINE_FEEDS = np.uint64(0x0A0A0A0A0A0A0A0A)
_EVEN_BYTES = np.uint64(0x00FF00FF00FF00FF)
_ONES_16 = np.uint64(0x0001000100010001)


@numba.njit(cache=True, nogil=True)
def _word(buffer, i):  # pragma: no cover - compiled
    """The bytes ``buffer[i : i + 8]`` as one little-endian word (one load: the unsigned index
    has no wraparound of negative values, so the byte loads combine)."""
    u = np.uintp(i)
    word = _U64(0)
    for k in range(8):
        word |= _U64(buffer[u + np.uintp(k)]) << _U64(8 * k)
    return word


@numba.njit(cache=True, nogil=True)
def count_lines(buffer, first, last):  # pragma: no cover - compiled
    """Line feeds in ``buffer[first:last]``, eight bytes at a time.

    A byte of ``word ^ 0x0A..0A`` is zero exactly at a line feed; ``((x & 0x7F..7F) + 0x7F..7F)
    | x`` has the high bit of every non-zero byte set (no carry crosses a byte), so the line
    feeds are the clear high bits. They are added up in the bytes of ``lanes`` (at most 255 words
    at a time, so that no byte overflows), the bytes in pairs, and the four pair sums (at most
    2,040) by one multiplication.
    """
    count = 0
    i = first
    while i + 8 <= last:
        lanes = _U64(0)
        stop = min(last - 8, i + 8 * 254)
        while i <= stop:
            x = _word(buffer, i) ^ _LINE_FEEDS
            lanes += (~(((x & _SEVENS) + _SEVENS) | x) & _HIGHS) >> _U64(7)
            i += 8
        pairs = (lanes & _EVEN_BYTES) + ((lanes >> _U64(8)) & _EVEN_BYTES)  # 16-bit lanes
        count += np.int64((pairs * _ONES_16) >> _U64(48))
    for k in range(i, last):
        count += buffer[k] == 10
    return count


@numba.njit(cache=True, nogil=True)
def _sign(buffer, i):  # pragma: no cover - compiled
    """(whether ``buffer[i]`` is a minus sign, the index after an optional sign)."""
    byte = buffer[i]
    if byte == 45 or byte == 43:
        return byte == 45, i + 1
    return False, i


@numba.njit(cache=True, nogil=True)
def _digits(buffer, i, w):  # pragma: no cover - compiled
    """(``w`` continued by the decimal digits from ``buffer[i]`` on (modulo ``2**64``), the
    index after them)."""
    byte = buffer[i]
    while byte - 48 <= 9 and byte >= 48:
        w = w * _U64(10) + _U64(byte - 48)
        i += 1
        byte = buffer[i]
    return w, i


@numba.njit(cache=True, nogil=True)
def _long_significand(buffer, start, stop):  # pragma: no cover - compiled
    """(significand, decimal exponent, exact) of the digits and point in ``buffer[start:stop]``
    without leading zeros and at most 19 significant digits; ``exact`` is false when a
    non-zero digit beyond the 19th would be dropped."""
    w = _U64(0)
    significant = 0
    exponent = 0
    after_point = False
    exact = True
    for i in range(start, stop):
        byte = buffer[i]
        if byte == 46:
            after_point = True
            continue
        if significant < 19:
            if w != 0 or byte != 48:
                w = w * _U64(10) + _U64(byte - 48)
                significant += 1
            if after_point:
                exponent -= 1
        else:
            if not after_point:
                exponent += 1
            exact &= byte == 48
    return w, exponent, exact


@numba.njit(cache=True, nogil=True)
def coordinate_lines(
    buffer, first, last, n, rows, cols, values, bits, at, powers, upper_columns
):  # pragma: no cover - compiled
    """Parse the lines ``row column value`` of ``buffer[first:last]`` (whole lines, each ending
    in a line feed) into ``rows``, ``cols`` (from 0), ``values`` from index ``at`` on.

    A line is accepted only in the plain form ``[blanks] digits blanks digits blanks number
    [blanks] [CR] LF`` (blanks: spaces and tabs; number: ``[sign] digits [. digits]`` or
    ``[sign] . digits``, then optionally ``e|E [sign] digits``), with indices ``1 .. n`` and at
    most 19 significant digits in the number whose value is a normal double or zero. Every
    other form (blank, comment, a decimal comma, a Fortran ``D`` exponent, ...) fails the
    parse, which the caller leaves to its strict pass; so does an entry beyond the end of
    ``rows``.

    With ``upper_columns`` the lines must be the upper triangle column by column, as CalculiX
    writes it: ``row <= column`` and every line's ``(column, row)`` after the previous line's
    (each position once); entries off the diagonal whose value is zero are checked but not
    stored (the diagonal always is). The order across parts is the caller's to check, with the
    keys returned.

    Values are exactly the doubles a correctly rounding parser (Python's ``float``) gives: the
    significand times an exact power of ten in one rounding where both are exact doubles
    (``w <= 2**53``, ``|q| <= 22``), else :func:`decimal_to_bits`. ``bits`` is ``values``
    viewed as ``uint64``.

    Returns
    -------
    lines, stored, first_key, last_key : int
        Lines parsed (-1 if one fails), entries stored, and with ``upper_columns`` the key
        ``column * 2**32 + row`` of the first and last line (-1 without lines or without
        ``upper_columns``).
    """
    i = first
    k = at
    lines = 0
    first_key = -1
    previous = np.int64(-1)
    capacity = rows.size
    while i < last:
        if k >= capacity:
            return -1, 0, -1, -1
        byte = buffer[i]
        while byte == 32 or byte == 9:
            i += 1
            byte = buffer[i]
        # the two indices: unsigned digits (at most 10)
        index = 0
        for field in range(2):
            start = i
            value = 0
            byte = buffer[i]
            while byte - 48 <= 9 and byte >= 48:
                value = value * 10 + (byte - 48)
                i += 1
                byte = buffer[i]
            if i == start or i - start > 10 or value < 1 or value > n:
                return -1, 0, -1, -1
            if byte != 32 and byte != 9:
                return -1, 0, -1, -1
            while byte == 32 or byte == 9:
                i += 1
                byte = buffer[i]
            if field == 0:
                index = value
        if upper_columns:
            key = (np.int64(value) << 32) | np.int64(index)
            if index > value or key <= previous:
                return -1, 0, -1, -1
            if lines == 0:
                first_key = key
            previous = key
        lines += 1
        rows[k] = index - 1
        cols[k] = value - 1
        # the number
        negative, i = _sign(buffer, i)
        # the significand: up to 19 digits in one word (a longer one is read again with care)
        start = i
        w, i = _digits(buffer, i, _U64(0))
        digits = i - start
        exponent = 0
        byte = buffer[i]
        if byte == 46:
            point = i + 1
            w, i = _digits(buffer, point, w)
            exponent = point - i
            digits += i - point
            byte = buffer[i]
        if digits == 0:
            return -1, 0, -1, -1
        if digits > 19:
            w, exponent, exact = _long_significand(buffer, start, i)
            if not exact:
                return -1, 0, -1, -1
        if byte == 101 or byte == 69:
            minus, i = _sign(buffer, i + 1)
            byte = buffer[i]
            start = i
            power = 0
            while byte - 48 <= 9 and byte >= 48:
                if power < 100000:
                    power = power * 10 + (byte - 48)
                i += 1
                byte = buffer[i]
            if i == start:
                return -1, 0, -1, -1
            exponent += -power if minus else power
        while byte == 32 or byte == 9:
            i += 1
            byte = buffer[i]
        if byte == 13:
            i += 1
            byte = buffer[i]
        if byte != 10:
            return -1, 0, -1, -1
        i += 1
        if w == 0:
            if upper_columns and index != value:
                continue  # a zero off the diagonal: not stored
            values[k] = -0.0 if negative else 0.0
        elif w <= _TWO53 and -22 <= exponent <= 22:
            x = np.float64(w)
            x = x * _EXACT_TENS[exponent] if exponent >= 0 else x / _EXACT_TENS[-exponent]
            values[k] = -x if negative else x
        else:
            if exponent < SMALLEST_POWER or exponent > LARGEST_POWER:
                return -1, 0, -1, -1
            word = decimal_to_bits(w, exponent, powers)
            if word == 0:
                return -1, 0, -1, -1
            bits[k] = word | (_TOP if negative else _U64(0))
        k += 1
    return lines, k - at, first_key, previous if upper_columns else np.int64(-1)
