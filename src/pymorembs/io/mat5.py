"""A bounds-checked reader of MATLAB level-5 MAT-files (``save -v6``, ``-v7``; the default).

``scipy.io.loadmat`` crashes the interpreter (segmentation fault in its compiled reader) on
damaged v5 files: 5 of 300 randomly mutated copies of a small valid file in a trial, e.g. a
sparse matrix whose dimension element is cut to one entry. This module reads the layout itself
with NumPy and checks every length before it is used; it reads what a body needs -- numeric
arrays and sparse matrices -- and lists the other variables (cells, structs, strings, objects)
by class without reading their content.

Layout (MathWorks, "MAT-File Format"): a 128-byte header (116 bytes of text, 8 bytes subsystem
offset, the version ``0x0100`` and the endian indicator ``IM``, read as ``MI`` in a big-endian
file); then data elements, each a tag (type, number of bytes; a *small* element packs both in 4
bytes, with the upper 16 bits the byte count, and holds up to 4 bytes of data) and its data,
padded to 8 bytes. A variable is an ``miMATRIX`` element (type 14), possibly inside an
``miCOMPRESSED`` element (type 15, zlib); it holds the array flags (class in the low byte,
complex ``0x0800``, logical ``0x0200``; then ``nzmax``), the dimensions (int32), the name, and
the real and imaginary parts -- for a sparse matrix the row indices ``ir``, the column pointers
``jc`` (int32) and the values (compressed sparse columns).
"""

from __future__ import annotations

import struct
import zlib
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import scipy.sparse as sp

from pymorembs.errors import located_error

__all__ = ["Mat5Entry", "is_v5", "load_v5", "scan_v5"]

_MI_MATRIX, _MI_COMPRESSED = 14, 15
_NUMBER_TYPES = {1: "i1", 2: "u1", 3: "i2", 4: "u2", 5: "i4", 6: "u4", 7: "f4", 9: "f8"}
_NUMBER_TYPES.update({12: "i8", 13: "u8"})
_CLASSES = {
    1: "cell",
    2: "struct",
    3: "object",
    4: "char",
    5: "sparse",
    6: "double",
    7: "single",
    8: "int8",
    9: "uint8",
    10: "int16",
    11: "uint16",
    12: "int32",
    13: "uint32",
    14: "int64",
    15: "uint64",
    16: "function",
    17: "opaque",
}
_NUMERIC_CLASSES = set(range(6, 16))
_COMPLEX, _LOGICAL = 0x0800, 0x0200
_EXPANDED_LIMIT = 1 << 32  # bytes one compressed variable may expand to


@dataclass(frozen=True, eq=False)
class Mat5Entry:
    """One top-level variable: its header and where its data elements lie."""

    name: str
    shape: tuple[int, ...]
    kind: str  # MATLAB class, "sparse", or "logical"
    buffer: bytes | memoryview
    start: int  # first data element after the name
    end: int
    flags: int
    complex: bool
    endian: str  # "<" or ">", the byte order of the file


def is_v5(head: bytes) -> bool:
    """Whether the first 128 bytes are a level-5 MAT-file header (version 0x0100)."""
    if len(head) < 128 or 0 in head[:4]:
        return False
    return head[126:128] in (b"IM", b"MI") and _version(head) == 1


def _version(head: bytes) -> int:
    """The major version (1 for level 5, 2 for the HDF5-based 7.3) in the file's byte order."""
    return head[125] if head[126:128] == b"IM" else head[124]


class _Reader:
    def __init__(self, path: Path, endian: str) -> None:
        self.path = path
        self.e = endian

    def fail(self, message: str):
        return located_error(self.path, None, f"damaged MAT-file: {message}")

    def tag(self, buf, pos: int, end: int) -> tuple[int, int, int, int]:
        """(type, byte count, data start, next element) of the element at ``pos``."""
        if pos + 8 > end:
            raise self.fail(f"element at byte {pos} is cut short")
        (word,) = struct.unpack_from(self.e + "I", buf, pos)
        if word >> 16:  # small element: byte count in the upper half, data in the next 4 bytes
            kind, count = word & 0xFFFF, word >> 16
            if count > 4:
                raise self.fail(f"small element at byte {pos} announces {count} bytes")
            return kind, count, pos + 4, pos + 8
        (count,) = struct.unpack_from(self.e + "I", buf, pos + 4)
        start = pos + 8
        if start + count > end:
            raise self.fail(f"element at byte {pos} announces {count} bytes past its end")
        padded = start + count if word == _MI_COMPRESSED else start + -(-count // 8) * 8
        return word, count, start, min(padded, end)

    def numbers(self, buf, pos: int, end: int, what: str) -> tuple[np.ndarray, int]:
        """A numeric data element and the position after it."""
        kind, count, start, after = self.tag(buf, pos, end)
        code = _NUMBER_TYPES.get(kind)
        if code is None:
            raise self.fail(f"{what}: element type {kind} is not numeric")
        size = np.dtype(code).itemsize
        if count % size:
            raise self.fail(f"{what}: {count} bytes are not whole numbers of type {code}")
        dtype = np.dtype(code).newbyteorder(self.e)
        return np.frombuffer(buf, dtype=dtype, count=count // size, offset=start), after


def scan_v5(path: Path, data: bytes) -> list[Mat5Entry]:
    """The top-level variables of a v5 file (headers checked, data located, nothing loaded)."""
    endian = "<" if data[126:128] == b"IM" else ">"
    reader = _Reader(path, endian)
    entries: list[Mat5Entry] = []
    pos, end = 128, len(data)
    while pos < end:
        if end - pos < 8 and not any(data[pos:]):
            break  # zero padding at the end
        kind, count, start, after = reader.tag(data, pos, end)
        if kind == _MI_COMPRESSED:
            buf = _inflate(reader, data[start : start + count], pos)
            inner_kind, inner_count, inner_start, _ = reader.tag(buf, 0, len(buf))
            if inner_kind != _MI_MATRIX:
                raise reader.fail(f"compressed element at byte {pos} holds no matrix")
            entries.append(_matrix_header(reader, buf, inner_start, inner_start + inner_count))
        elif kind == _MI_MATRIX:
            entries.append(_matrix_header(reader, data, start, start + count))
        else:
            raise reader.fail(f"top-level element of type {kind} at byte {pos} is not a matrix")
        pos = after
    return entries


def _inflate(reader: _Reader, packed: bytes, pos: int) -> bytes:
    inflater = zlib.decompressobj()
    try:
        out = inflater.decompress(packed, _EXPANDED_LIMIT)
    except zlib.error as err:
        raise reader.fail(f"compressed element at byte {pos}: {err}") from None
    if inflater.unconsumed_tail:
        raise reader.fail(f"compressed element at byte {pos} expands beyond 4 GiB")
    return out


def _matrix_header(reader: _Reader, buf, start: int, end: int) -> Mat5Entry:
    flags, pos = reader.numbers(buf, start, end, "array flags")
    if flags.size != 2:
        raise reader.fail("array flags must hold 2 numbers")
    flag_word = int(flags[0])
    dims, pos = reader.numbers(buf, pos, end, "dimensions")
    if dims.dtype.kind != "i" or dims.size < 2 or np.any(dims < 0):
        raise reader.fail("dimensions must be 2 or more non-negative int32 numbers")
    name_kind, name_count, name_start, pos = reader.tag(buf, pos, end)
    if name_kind not in (1, 2):
        raise reader.fail("the array name is not text")
    name = bytes(buf[name_start : name_start + name_count]).decode("latin-1")
    kind = _CLASSES.get(flag_word & 0xFF, f"class {flag_word & 0xFF}")
    if flag_word & _LOGICAL and kind in ("uint8", "double", "sparse"):
        kind = "sparse" if kind == "sparse" else "logical"
    shape = tuple(int(d) for d in dims)
    complex_ = bool(flag_word & _COMPLEX)
    return Mat5Entry(name, shape, kind, buf, pos, end, flag_word, complex_, reader.e)


def load_v5(path: Path, entry: Mat5Entry) -> np.ndarray | sp.csc_matrix:
    """The values of a numeric or sparse variable (checked against its dimensions)."""
    reader = _Reader(path, entry.endian)
    if entry.kind == "sparse":
        return _sparse(reader, entry)
    count = int(np.prod(entry.shape, dtype=np.int64))
    real, pos = reader.numbers(entry.buffer, entry.start, entry.end, f"{entry.name} values")
    if real.size != count:
        raise reader.fail(f"{entry.name}: {real.size} values for dimensions {entry.shape}")
    values = real.astype(np.float64)
    if entry.complex:
        imag, _ = reader.numbers(entry.buffer, pos, entry.end, f"{entry.name} imaginary part")
        if imag.size != count:
            raise reader.fail(f"{entry.name}: {imag.size} imaginary parts for {count} values")
        values = values + 1j * imag.astype(np.float64)
    return values.reshape(entry.shape, order="F")


def _sparse(reader: _Reader, entry: Mat5Entry) -> sp.csc_matrix:
    if len(entry.shape) != 2:
        raise reader.fail(f"{entry.name}: a sparse matrix has 2 dimensions, not {len(entry.shape)}")
    rows, columns = entry.shape
    buf, end = entry.buffer, entry.end
    ir, pos = reader.numbers(buf, entry.start, end, f"{entry.name} row indices")
    jc, pos = reader.numbers(buf, pos, end, f"{entry.name} column pointers")
    if jc.size != columns + 1:
        raise reader.fail(f"{entry.name}: {jc.size} column pointers for {columns} columns")
    jc = jc.astype(np.int64)
    nnz = int(jc[-1]) if jc.size else 0
    if jc[0] != 0 or np.any(np.diff(jc) < 0) or nnz > ir.size:
        raise reader.fail(f"{entry.name}: column pointers out of order or beyond the row indices")
    ir = ir[:nnz].astype(np.int64)
    if nnz and (ir.min() < 0 or ir.max() >= rows):
        raise reader.fail(f"{entry.name}: a row index lies outside {rows} rows")
    if pos >= end and entry.flags & _LOGICAL:
        values = np.ones(nnz)
    else:
        real, pos = reader.numbers(buf, pos, end, f"{entry.name} values")
        if real.size < nnz:
            raise reader.fail(f"{entry.name}: {real.size} values for {nnz} nonzeros")
        values = real[:nnz].astype(np.float64)
        if entry.complex:
            imag, _ = reader.numbers(buf, pos, end, f"{entry.name} imaginary part")
            if imag.size < nnz:
                raise reader.fail(f"{entry.name}: {imag.size} imaginary parts for {nnz}")
            values = values + 1j * imag[:nnz].astype(np.float64)
    return sp.csc_matrix((values, ir, jc), shape=(rows, columns))
