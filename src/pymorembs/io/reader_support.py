"""Helpers the file readers share: the text of a file, whether a file is a ``nodes.csv``, the
checked assembly of a symmetric sparse matrix from (row, column, value) entries, and the
collection of nodes by a recursive scanner.
"""

from __future__ import annotations

import os
from collections.abc import Callable
from pathlib import Path
from typing import Literal

import numpy as np
import scipy.sparse as sp

from pymorembs.errors import located_error
from pymorembs.io.line_blocks import UTF8_BOM
from pymorembs.io.matrix_market import SYMMETRY_TOLERANCE, encoding_note

__all__ = ["assemble_symmetric", "collect_nodes", "grown_csr", "is_nodes_csv", "read_text"]

PathLike = str | os.PathLike[str]


def assemble_symmetric(
    rows: np.ndarray,
    cols: np.ndarray,
    values: np.ndarray,
    n: int,
    *,
    path: Path,
    line_of: Callable[[int], int | None],
    label: Callable[[int], str],
    storage: Literal["auto", "symmetric", "square"] = "auto",
) -> sp.csr_matrix:
    """Assemble a symmetric ``n x n`` matrix from entries of a text file, checking them.

    Parameters
    ----------
    rows, cols : ndarray of int
        Equation indices (from 0) of the entries, in file order.
    values : ndarray of float
        The entries.
    n : int
        Size of the matrix.
    path : Path
        The file, for messages.
    line_of : callable
        Line number of entry ``k`` (called only to build an error message).
    label : callable
        Readable name of equation ``i`` for messages, e.g. ``"12:uy"``.
    storage : {"auto", "symmetric", "square"}
        ``"symmetric"``: each off-diagonal pair may be given once (either triangle, mirrored) or
        twice with equal values. ``"square"``: the file stores the full matrix, so an entry
        without its mirror entry means the mirror is zero. ``"auto"``: ``"square"`` when some
        off-diagonal position is given in both orientations, else ``"symmetric"``. (The side of
        the diagonal alone says nothing: a writer stores one triangle in *its* equation order,
        which need not be the order of the dof table.)

    Returns
    -------
    scipy.sparse.csr_matrix
        The full, exactly symmetric matrix without explicit zeros.

    Raises
    ------
    UserError
        ``path:line: problem`` for a NaN or infinite value, the same position given twice with
        different values (both lines named), or mirror entries that differ by more than
        :data:`~pymorembs.io.matrix_market.SYMMETRY_TOLERANCE` times the largest entry.
        Identical repeated entries are tolerated (read once).
    """
    rows = np.asarray(rows, dtype=np.int64)
    cols = np.asarray(cols, dtype=np.int64)
    values = np.asarray(values, dtype=np.float64)

    def value(k: int) -> float:
        return float(values[k])

    bad = np.flatnonzero(~np.isfinite(values))
    if bad.size:
        k = int(bad[0])
        raise located_error(path, line_of(k), f"value {value(k)!r} is not a finite number")
    if values.size == 0:
        return sp.csr_matrix((n, n))
    lo, hi = np.minimum(rows, cols), np.maximum(rows, cols)
    key = (hi * n + lo) * 2 + (rows > cols)
    order = np.argsort(key, kind="stable")
    skey, sval = key[order], values[order]

    def where(k: int) -> str:
        return f"({label(int(rows[k]))}, {label(int(cols[k]))})"

    repeat = skey[1:] == skey[:-1]
    if repeat.any():
        clash = np.flatnonzero(repeat & (sval[1:] != sval[:-1]))
        if clash.size:
            c = int(clash[np.argmin(order[clash + 1])])
            first, second = int(order[c]), int(order[c + 1])
            raise located_error(
                path,
                line_of(second),
                f"entry {where(second)} = {value(second)!r} is given again with another value "
                f"(line {line_of(first)} has {value(first)!r})",
            )
        keep = np.concatenate([[True], ~repeat])
        order, skey, sval = order[keep], skey[keep], sval[keep]

    limit = SYMMETRY_TOLERANCE * float(np.max(np.abs(values)))
    position = skey // 2
    pairs = np.flatnonzero(position[1:] == position[:-1])  # upper at i, lower at i + 1
    if pairs.size:
        gap = np.abs(sval[pairs] - sval[pairs + 1])
        bad = pairs[gap > limit]
        if bad.size:
            later = np.maximum(order[bad], order[bad + 1])
            i = int(bad[np.argmin(later)])
            first, second = sorted((int(order[i]), int(order[i + 1])))
            raise located_error(
                path,
                line_of(second),
                f"matrix is not symmetric: entry {where(second)} = {value(second)!r} but the "
                f"mirror entry on line {line_of(first)} is {value(first)!r}",
            )
        sval[pairs] = 0.5 * (sval[pairs] + sval[pairs + 1])  # exact for equal values
    if storage == "auto":
        storage = "square" if pairs.size else "symmetric"
    single = np.ones(skey.size, dtype=bool)
    single[pairs] = single[pairs + 1] = False
    if storage == "square":
        lonely = single & (position // n != position % n) & (np.abs(sval) > limit)
        if lonely.any():
            k = int(np.min(order[lonely]))
            if pairs.size:
                a, b = sorted((int(order[pairs[0]]), int(order[pairs[0] + 1])))
                why = f"other entries are given in both triangles (e.g. lines {line_of(a)} and "
                why += f"{line_of(b)}), so the file stores the square matrix and the mirror is 0"
            else:
                why = "the matrix is stored square (both triangles), so the mirror is 0"
            raise located_error(
                path,
                line_of(k),
                f"matrix is not symmetric: entry {where(k)} = {value(k)!r} has no mirror entry "
                f"({label(int(cols[k]))}, {label(int(rows[k]))}); {why}",
            )
    keep = np.ones(skey.size, dtype=bool)
    keep[pairs + 1] = False
    position, sval = position[keep], sval[keep]
    hi, lo = position // n, position % n
    off = hi != lo
    matrix = sp.csr_matrix(
        (
            np.concatenate([sval, sval[off]]),
            (np.concatenate([hi, lo[off]]), np.concatenate([lo, hi[off]])),
        ),
        shape=(n, n),
    )
    matrix.eliminate_zeros()
    matrix.sort_indices()
    return matrix


def grown_csr(matrix: sp.csr_matrix, n: int) -> sp.csr_matrix:
    """A square CSR matrix grown to ``n x n`` by empty rows and columns at its end (no copy of
    the entries).

    Parameters
    ----------
    matrix : scipy.sparse.csr_matrix, shape (m, m)
        ``m <= n``.
    n : int
        The new size.

    Returns
    -------
    scipy.sparse.csr_matrix, shape (n, n)
        ``matrix`` itself when ``m == n``.
    """
    size = matrix.shape[0]
    if size == n:
        return matrix
    indptr = np.concatenate([matrix.indptr, np.full(n - size, matrix.indptr[-1])])
    return sp.csr_matrix((matrix.data, matrix.indices, indptr), shape=(n, n), copy=False)


def read_text(path: Path, kind: str) -> str:
    """The whole text of a file (newlines normalised to ``\\n``), or a one-line :class:`UserError`.

    ``kind`` names what the file should be, e.g. ``"an Abaqus matrix file"``.
    """
    text: str | None = None
    try:
        with open(path, encoding="utf-8-sig", errors="strict") as f:
            text = f.read()
    except FileNotFoundError:
        raise located_error(path, None, f"file not found (expected {kind})") from None
    except IsADirectoryError:
        raise located_error(path, None, f"is a directory, expected {kind}") from None
    except UnicodeDecodeError:
        pass
    except OSError as err:
        raise located_error(path, None, f"cannot read: {err.strerror or err}") from None
    if text is None:  # not UTF-8: read as Latin-1, which decodes any byte
        with open(path, "rb") as f:
            text = f.read().decode("latin-1").replace("\r\n", "\n").replace("\r", "\n")
    if "\x00" in text:
        with open(path, "rb") as f:
            note = encoding_note(f.read(512))
        raise located_error(path, None, f"a binary file, expected {kind}{note}")
    return text


def is_nodes_csv(path: Path) -> bool:
    """Whether ``path`` looks like a ``nodes.csv`` (first content line ``id,x,y,z``)."""
    try:
        with open(path, "rb") as f:
            head = f.read(4096).removeprefix(UTF8_BOM).decode("latin-1")
    except OSError:
        return False
    for line in head.splitlines():
        text = line.strip()
        if not text or text.startswith("#"):
            continue
        return "".join(text.lower().split()).startswith("id,x,y,z")
    return False


def collect_nodes(scan: Callable[..., None], path: PathLike) -> tuple[np.ndarray, np.ndarray]:
    """Node ids and coordinates gathered by a recursive file scanner.

    ``scan(path, ids, xyz, seen, stack)`` appends to ``ids`` and ``xyz``, records where each id
    was seen in ``seen`` (to report duplicates) and follows includes, with ``stack`` the files
    being read (to report include loops).
    """
    ids: list[int] = []
    xyz: list[tuple[float, float, float]] = []
    seen: dict[int, tuple[Path, int]] = {}
    scan(Path(path), ids, xyz, seen, ())
    return np.array(ids, dtype=np.int64), np.array(xyz, dtype=float).reshape(-1, 3)
