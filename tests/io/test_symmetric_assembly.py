"""The fast symmetric assembly of triangle files against the general one, entry for entry.

:func:`pymorembs.io.symmetric_assembly.assemble_symmetric_triangle` must return exactly the
matrix of :func:`pymorembs.io.reader_support.assemble_symmetric` (pattern and values bit for bit),
or
None wherever that function raises or the layout is not one it handles; here on random small
matrices in every layout the Abaqus files use (sorted lower or upper triangle, both triangles
with each mirror on the next line, one triangle in another equation order), with and without
mistakes, and with blocks of 2 and 3 entries so that every block boundary is crossed.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import scipy.sparse as sp

import pymorembs.io.symmetric_assembly as assembly
from pymorembs.errors import UserError
from pymorembs.io.reader_support import assemble_symmetric
from pymorembs.io.symmetric_assembly import assemble_symmetric_triangle

TOLERANCE = 1e-10


def general(rows: np.ndarray, cols: np.ndarray, values: np.ndarray, n: int):
    try:
        return assemble_symmetric(
            rows, cols, values, n, path=Path("k.mtx"), line_of=lambda k: k + 1, label=str
        )
    except UserError:
        return None


def entries(rng: np.random.Generator, layout: str):
    """(rows, cols, values, n) of a random symmetric matrix written in ``layout``."""
    n = int(rng.integers(1, 12))
    a = sp.random(n, n, density=rng.uniform(0.2, 1.0), random_state=int(rng.integers(1 << 30)))
    a = a.toarray()
    if rng.random() < 0.3:
        a = np.round(a, 1)  # exact zeros and equal values
    a = a + a.T
    triangle = sp.tril(a, format="coo") if layout == "lower" else sp.triu(a, format="coo")
    order = np.lexsort((triangle.col, triangle.row))
    r, c, v = triangle.row[order], triangle.col[order], triangle.data[order]
    if layout == "mirrored":  # both triangles, each mirror on the next line (Abaqus/CAE)
        off = r != c
        twice = np.repeat(np.arange(r.size), np.where(off, 2, 1))
        second = np.zeros(twice.size, dtype=bool)
        second[1:] = twice[1:] == twice[:-1]
        r, c = np.where(second, c[twice], r[twice]), np.where(second, r[twice], c[twice])
        noise = rng.choice([0.0, 0.0, 1e-13, 1e-3])  # within or beyond the tolerance
        v = v[twice] * (1.0 + np.where(second, noise, 0.0))
    if layout == "unsorted":  # one triangle in the writer's own equation order
        perm = rng.permutation(r.size)
        flip = rng.random(r.size) < 0.5
        r, c = np.where(flip, c, r)[perm], np.where(flip, r, c)[perm]
        v = v[perm]
    if r.size and rng.random() < 0.25:  # a mistake or an oddity
        k = int(rng.integers(r.size))
        kind = int(rng.integers(5))
        v = v.copy()
        if kind == 0:
            v[k] = np.nan
        elif kind == 1:  # a repeated line, with the same or another value
            r, c = np.insert(r, k, r[k]), np.insert(c, k, c[k])
            v = np.insert(v, k, v[k] + rng.choice([0.0, 1.0]))
        elif kind == 2:
            v[k] = 0.0
        elif kind == 3:
            r, c, v = r[::-1], c[::-1], v[::-1]
        else:  # a lone mirror
            r, c, v = np.append(r, c[k]), np.append(c, r[k]), np.append(v, v[k])
    return r.astype(np.int64), c.astype(np.int64), v.astype(float), n


@pytest.mark.parametrize("block", [2, 3, 1 << 16])
@pytest.mark.parametrize("layout", ["lower", "upper", "mirrored", "unsorted"])
def test_same_matrix_as_the_general_assembly(monkeypatch, block: int, layout: str) -> None:
    monkeypatch.setattr(assembly, "_BLOCK", block)
    monkeypatch.setattr(assembly, "_ROW_BLOCK", block)
    rng = np.random.default_rng(block + len(layout))
    fast_count = 0
    for _ in range(200):
        r, c, v, n = entries(rng, layout)
        base = int(rng.integers(2))
        fast = assemble_symmetric_triangle(
            (r + base).astype(np.int32), (c + base).astype(np.int32), v, n, TOLERANCE, base
        )
        slow = general(r, c, v, n)
        if fast is None:
            continue
        fast_count += 1
        assert slow is not None, (r, c, v)
        assert fast.has_canonical_format
        np.testing.assert_array_equal(fast.indptr, slow.indptr)
        np.testing.assert_array_equal(fast.indices, slow.indices)
        np.testing.assert_array_equal(fast.data, slow.data)
    assert fast_count > 100  # the fast path was taken for most files


def test_refused_where_the_general_assembly_must_decide() -> None:
    r = np.array([0, 1, 1], dtype=np.int32)
    c = np.array([0, 0, 1], dtype=np.int32)
    ok = assemble_symmetric_triangle(r, c, np.array([2.0, 1.0, 3.0]), 2, TOLERANCE)
    np.testing.assert_array_equal(ok.toarray(), [[2.0, 1.0], [1.0, 3.0]])
    for rows, cols, values in [
        ([0, 1, 1], [0, 0, 1], [2.0, np.inf, 3.0]),  # not finite
        ([0, 1, 1, 1], [0, 0, 0, 1], [2.0, 1.0, 1.5, 3.0]),  # a position twice, other value
        ([0, 1, 0, 1], [0, 0, 1, 1], [2.0, 1.0, 1.1, 3.0]),  # mirrors differ
        ([0, 1, 0], [1, 0, 0], [1.0, 1.0, 2.0]),  # unsorted, both orientations
        ([0, 0, 1, 1], [0, 0, 0, 1], [2.0, 2.0, 1.0, 3.0]),  # a diagonal twice
    ]:
        got = assemble_symmetric_triangle(
            np.array(rows, dtype=np.int32),
            np.array(cols, dtype=np.int32),
            np.array(values),
            2,
            TOLERANCE,
        )
        assert got is None, (rows, cols, values)
