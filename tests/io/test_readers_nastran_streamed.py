"""The streamed fast paths of the Nastran text readers give exactly what the strict paths give.

* DMIG punches: :func:`pymorembs.io.nastran_dmig.read_dmig` first tries a streamed two-pass
  reader of the large-field layout Nastran punches; anything else goes to the strict pass. The
  tests compare the two on the genuine punches, on punches written here with the cases the fast
  path handles (lower-triangle entries, explicit zeros, scalar points, CRLF, comments), on
  mutations of a punch (hypothesis), and check that the strict pass's messages stand.
* ASCII OP4: :func:`pymorembs.io.op4_ascii.read_ascii_op4` must return what pyNastran returns
  (values, precision, dense or sparse) or decline (None).
* :func:`pymorembs.sparse_rows.abs_row_sums` equals SciPy's ``abs(a).sum(axis=1)``.
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest
import scipy.sparse as sp
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from pyNastran.op4.op4 import OP4, Matrix

import pymorembs.sparse_rows as sparse_rows
from pymorembs.errors import UserError
from pymorembs.io import nastran_dmig
from pymorembs.io.nastran_bulk import significant_digits
from pymorembs.io.op4_ascii import read_ascii_op4

DATA = Path(__file__).parents[1] / "data"
MAEWING = DATA / "exportnastrankm_mAEWing1_FEMv5p2" / "sol103_maewing1_femv5p2.pch1"
PYNASTRAN_DMIG = DATA / "pynastran" / "dmig_pch" / "dmig.pch"
SE_OP4 = DATA / "pynastran" / "superelement_se_test_n11" / "se_test_n11.op4"


# ============================================================================ DMIG
def _strict(monkeypatch, path, **kwargs):
    with monkeypatch.context() as m:
        m.setattr(nastran_dmig, "_read_streamed", lambda *a, **k: None)
        return nastran_dmig.read_dmig(path, **kwargs)


def _streamed(path, nodes=None):
    return nastran_dmig._read_streamed(Path(path), None, None, None, nodes, None)


def _assert_same(a, b) -> None:
    for role in ("stiffness", "mass", "damping_matrix"):
        x, y = getattr(a, role), getattr(b, role)
        assert (x is None) == (y is None), role
        if x is not None:
            assert x.shape == y.shape and (x != y).nnz == 0, role
            assert x.has_sorted_indices and x.indices.dtype == y.indices.dtype, role
    np.testing.assert_array_equal(a.dofs.nodes, b.dofs.nodes)
    np.testing.assert_array_equal(a.dofs.directions, b.dofs.directions)
    np.testing.assert_array_equal(a.coordinates, b.coordinates)
    np.testing.assert_array_equal(a.fixed, b.fixed)
    assert a.notes == b.notes
    assert a.precision == b.precision
    assert a.has_coordinates == b.has_coordinates


@pytest.mark.parametrize("path", [MAEWING, PYNASTRAN_DMIG], ids=["maewing1", "pynastran"])
def test_genuine_punches_streamed_as_strict(monkeypatch, path) -> None:
    fast = _streamed(path)
    assert fast is not None  # the genuine layout is the one the fast path reads
    _assert_same(fast, _strict(monkeypatch, path))
    _assert_same(nastran_dmig.read_dmig(path), fast)


def _d(value: float) -> str:
    return f"{value:16.9E}".replace("E", "D")


def _punch(entries: dict[str, list[tuple[int, int, int, int, float]]], newline="\n") -> str:
    """Large-field DMIG cards (form 6), columns in the order given: (gj, cj, g, c, value)."""
    lines = ["$ a comment, with a comma\tand a tab"]
    for grid, x in ((1, 0.0), (2, 1.5)):
        lines += [f"GRID*   {grid:>16}{0:>16}{x:>16}{0.25:>16}", f"*       {-0.5:>16}"]
    for name, items in entries.items():
        columns = list(dict.fromkeys((gj, cj) for gj, cj, *_ in items))
        lines.append(f"DMIG    {name:<8}{0:>8}{6:>8}{2:>8}{0:>8}{'':8}{'':8}{len(columns):>8}")
        for gj, cj in columns:
            lines.append(f"DMIG*   {name:<16}{gj:>16}{cj:>16}")
            for g2, c2, g, c, v in items:
                if (g2, c2) == (gj, cj):
                    comp = "" if c is None else str(c)
                    lines.append(f"*       {g:>16}{comp:>16}{_d(v)}")
            lines.append("$")
    return newline.join(lines) + newline


K_ENTRIES = [
    (1, 1, 1, 1, 4.0),
    (1, 2, 1, 1, -1.0),
    (1, 2, 1, 2, 3.5),
    (2, 1, 1, 2, 0.0),  # an explicit zero
    (2, 1, 2, 1, 2.25),
    (2, 1, 1, 1, -0.5),  # rows out of order in a column: the coo path
    (7, 0, 7, None, 1.0),  # a scalar point (blank component)
    (7, 0, 2, 1, 0.125),  # lower triangle (7:q is after 2:ux)
]
M_ENTRIES = [(1, 1, 1, 1, 1.0), (1, 2, 1, 2, 1.0), (2, 1, 2, 1, 1.0), (7, 0, 7, 0, 1.0)]


@pytest.mark.parametrize("newline", ["\n", "\r\n"])
def test_written_punch_streamed_as_strict(monkeypatch, tmp_path, newline) -> None:
    path = tmp_path / "model.pch"
    path.write_bytes(_punch({"KAAX": K_ENTRIES, "MAAX": M_ENTRIES}, newline).encode())
    fast = _streamed(path)
    assert fast is not None
    _assert_same(fast, _strict(monkeypatch, path))
    assert fast.stiffness[2, 3] == 0.125 and fast.stiffness[3, 2] == 0.125  # mirrored


@pytest.mark.parametrize(
    ("change", "pattern"),
    [
        # the same position twice with two values: the strict message names both lines
        (
            lambda t: t.replace(
                f"{1:>16}{1:>16}{_d(4.0)}",
                f"{1:>16}{1:>16}{_d(4.0)}\n*       {1:>16}{1:>16}{_d(5.0)}",
                1,
            ),
            r"model\.pch:\d+: entry .* is given again with another value \(line \d+ has 4\.0\)",
        ),
        (
            lambda t: t.replace(_d(3.5), " 3.5.0D+00      "),
            r"model\.pch:\d+: value .* not a number",
        ),
        (
            lambda t: t.replace(f"*       {1:>16}{2:>16}", f"*       {'':>16}{2:>16}", 1),
            r"model\.pch:\d+: entry without a row grid",
        ),
        (
            lambda t: t.replace(f"{2:>16}{1:>16}{_d(2.25)}", f"{2:>16}{9:>16}{_d(2.25)}"),
            r"model\.pch:\d+: row component 9 of grid 2 is not 0-6",
        ),
        (lambda t: t.replace(_d(2.25), "            NaN "), r"model\.pch:\d+: value .*finite"),
    ],
    ids=["clash", "two-points", "no-grid", "component", "nan"],
)
def test_streamed_defers_to_the_strict_messages(tmp_path, change, pattern) -> None:
    path = tmp_path / "model.pch"
    path.write_text(change(_punch({"KAAX": K_ENTRIES, "MAAX": M_ENTRIES})))
    with pytest.raises(UserError, match=pattern) as err:
        nastran_dmig.read_dmig(path)
    assert "\n" not in str(err.value)


@pytest.mark.parametrize(
    "change",
    [
        lambda t: t.replace("*  ", "+  "),  # small-field continuation lines
        lambda t: t.replace("DMIG*   MAAX", "DMIG*,  MAAX"),  # a free-field card
        lambda t: t.replace("GRID*           ", "GRID*\t        ", 1),  # a tab in a card
        lambda t: t.replace("\n$\n", "\n$\r"),  # a lone carriage return
    ],
    ids=["small-field", "free-field", "tab", "lone-cr"],
)
def test_other_layouts_go_to_the_strict_pass(monkeypatch, tmp_path, change) -> None:
    path = tmp_path / "model.pch"
    path.write_bytes(change(_punch({"KAAX": K_ENTRIES, "MAAX": M_ENTRIES})).encode())
    with pytest.raises(nastran_dmig._SlowPath):
        _streamed(path)
    try:
        strict = _strict(monkeypatch, path)
    except UserError as err:
        with pytest.raises(UserError, match=re.escape(str(err))):
            nastran_dmig.read_dmig(path)
    else:
        _assert_same(nastran_dmig.read_dmig(path), strict)


@settings(
    max_examples=60, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
@given(
    drop=st.lists(st.integers(0, 40), max_size=3),
    swap=st.lists(st.tuples(st.integers(0, 40), st.integers(0, 40)), max_size=2),
    flip=st.lists(
        st.tuples(st.integers(0, 2000), st.sampled_from(list(b" 0-.D*+$,\t9E"))), max_size=3
    ),
)
def test_mutated_punch_streamed_or_strict(monkeypatch, tmp_path, drop, swap, flip) -> None:
    """Whatever the mutation: the public reader gives the strict pass's body or message."""
    lines = _punch({"KAAX": K_ENTRIES, "MAAX": M_ENTRIES}).splitlines()
    for a, b in swap:
        if a < len(lines) and b < len(lines):
            lines[a], lines[b] = lines[b], lines[a]
    lines = [line for k, line in enumerate(lines) if k not in drop]
    raw = bytearray("\n".join(lines).encode())
    for at, byte in flip:
        if at < len(raw):
            raw[at] = byte
    path = tmp_path / "model.pch"
    path.write_bytes(bytes(raw))
    try:
        strict = _strict(monkeypatch, path)
    except UserError as err:
        with pytest.raises(UserError) as public:
            nastran_dmig.read_dmig(path)
        assert str(public.value) == str(err)
    else:
        _assert_same(nastran_dmig.read_dmig(path), strict)


def test_digit_histogram_counts_as_significant_digits() -> None:
    rng = np.random.default_rng(3)
    values = rng.standard_normal(500) * 10.0 ** rng.integers(-30, 30, 500)
    texts = [f"{v:16.9E}" for v in values] + ["-0.000000000E+00", " 0.100000000E+01"]
    texts += ["       1.556E+02", "  12.5000000E+00", "       0.0001234", "           -1.50"]
    for group in (texts[:502], texts):  # Nastran's layout alone, and mixed layouts
        fields = np.frombuffer("".join(group).encode(), dtype=np.uint8).reshape(-1, 16)
        expected = np.bincount(significant_digits(fields), minlength=17)
        np.testing.assert_array_equal(nastran_dmig._digit_histogram(fields.copy()), expected)


# ============================================================================ ASCII OP4
def _pynastran(path):
    return OP4(debug=None).read_op4(str(path))


def _assert_as_pynastran(path) -> None:
    fast, ref = read_ascii_op4(path), _pynastran(path)
    assert fast is not None and list(fast) == list(ref)
    for name, matrix in ref.items():
        mine = fast[name]
        assert mine.form == matrix.form and mine.tin == matrix.tin
        assert mine.data.dtype == matrix.data.dtype and mine.data.shape == matrix.data.shape
        assert sp.issparse(mine.data) == sp.issparse(matrix.data)
        if sp.issparse(matrix.data):
            a, b = sp.csr_matrix(mine.data), sp.csr_matrix(matrix.data)
            assert a.nnz == b.nnz and (a != b).nnz == 0
        else:
            np.testing.assert_array_equal(mine.data, matrix.data)


def test_genuine_ascii_op4_as_pynastran() -> None:
    _assert_as_pynastran(SE_OP4)  # MSC 2017.1: sparse, one-word string headers, 23 matrices


K = np.array([[4.0, -1.0, 0.0], [-1.0, 3.5, 0.25], [0.0, 0.25, 2.0]]) * 1e6
M = np.diag([1.0, 2.0, 3.0])


@pytest.mark.parametrize("kind", ["dense", "sparse", "triangle", "double"])
def test_pynastran_written_ascii_op4_as_pynastran(tmp_path, kind) -> None:
    path = tmp_path / "body.op4"
    if kind == "dense":
        matrices = {"KAAX": (6, K.astype(np.float32)), "MAAX": (6, M.astype(np.float32))}
    elif kind == "sparse":
        matrices = {"KAAX": (6, sp.coo_matrix(K)), "MAAX": (6, sp.coo_matrix(M))}
    elif kind == "triangle":
        matrices = {"KAAX": (6, np.tril(K)), "MAAX": (6, sp.coo_matrix(np.triu(M)))}
    else:
        matrices = {"KAAX": (6, K), "MAAX": (2, sp.coo_matrix(M))}
    OP4(debug=None).write_op4(
        str(path),
        {name: Matrix(name, form, data) for name, (form, data) in matrices.items()},
        name_order=list(matrices),
        is_binary=False,
    )
    _assert_as_pynastran(path)


BIGMAT = """\
       3      -3       6       2KAAX    1P,3E22.15
       1       0       6
       3       1
 4.000000000000000E+06-1.000000000000000E+06
       2       0       7
       4       1
-1.000000000000000E+06 3.500000000000000E+06 2.500000000000000E+05
       3       0       6
       3       2
 2.500000000000000E+05 2.000000000000000E+06
       4       1       1
 1.000000000000000E+00
"""


def test_bigmat_op4_as_pynastran(tmp_path) -> None:
    path = tmp_path / "body.op4"
    path.write_text(BIGMAT)
    _assert_as_pynastran(path)
    np.testing.assert_array_equal(read_ascii_op4(path)["KAAX"].data.toarray(), K)


@pytest.mark.parametrize(
    "change",
    [
        lambda t: t.replace("2KAAX", "4KAAX"),  # complex
        lambda t: t.replace("       4       1\n", "\n       4       1\n"),  # a blank line
        lambda t: t.replace("       3       2\n", "       3\n"),  # one-word string in BIGMAT
        lambda t: t.replace("       4       1\n-1.0", "       4       0\n-1.0"),  # row 0
        lambda t: t.replace(" 2.000000000000000E+06\n", " 2.00000000000000E+06\n"),  # width
        lambda t: t + "trailing text\n",
    ],
    ids=["complex", "blank", "string", "row-0", "width", "trailing"],
)
def test_ascii_op4_layouts_left_to_pynastran(tmp_path, change) -> None:
    path = tmp_path / "body.op4"
    path.write_text(change(BIGMAT))
    assert read_ascii_op4(path) is None


# ============================================================================ row sums
def test_abs_row_sums_as_scipy(monkeypatch) -> None:
    monkeypatch.setattr(sparse_rows, "_ENTRIES_PER_BLOCK", 7)  # many blocks
    a = sp.random(60, 50, density=0.1, random_state=4, format="csr")
    a.data -= 0.5
    keep = np.ones(60)
    keep[5] = 0.0  # an empty row
    a = sp.csr_matrix(sp.diags(keep) @ a)
    a.eliminate_zeros()
    expected = np.asarray(abs(a).sum(axis=1)).ravel()
    np.testing.assert_array_equal(sparse_rows.abs_row_sums(a), expected)
    np.testing.assert_array_equal(sparse_rows.abs_row_sums(a.tocsc()), expected)
    assert sparse_rows.abs_row_sums(sp.csr_matrix((4, 4))).tolist() == [0.0] * 4
