"""The fast paths of the Matrix Market and CSV readers agree with their strict passes.

``read_matrix_market`` first tries fast_matrix_market (``scipy.io.mmread``) behind byte-level
checks (:func:`pymorembs.io.fast_text.count_plain_fields`), the CSV tables first try NumPy's
``loadtxt``; anything doubtful goes to the strict line-by-line pass, which names the bad line.
The property tested here: whatever the fast path returns is exactly what the strict pass returns
(same CSR arrays, same tables), and the public functions behave as the strict pass alone (same
result or the same one-line error). The strict pass is obtained by switching the fast path off.
"""

from __future__ import annotations

import mmap
import re
import warnings
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numpy as np
import pytest
import scipy.sparse as sp
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from pymorembs.body import DofTable
from pymorembs.errors import UserError
from pymorembs.io import fast_text
from pymorembs.io import matrix_market as mm
from pymorembs.io.fast_text import count_plain_fields, csr_from_sorted_coo

GENERAL = "%%MatrixMarket matrix coordinate real general\n"
SYMMETRIC = "%%MatrixMarket matrix coordinate real symmetric\n"


@pytest.fixture(autouse=True)
def fast_path_for_small_files(monkeypatch):
    """The fast path is tried from 64 KiB of entries on; here for every file."""
    monkeypatch.setattr(mm, "_FAST_FROM_BYTES", 0)


def outcome(call):
    """The result of ``call`` or the message of its UserError (without the file name)."""
    try:
        return call()
    except UserError as err:
        message = str(err)
        assert "\n" not in message
        return message.split(": ", 1)[1]


def same(a, b) -> bool:
    """Equal results: identical canonical CSR arrays, equal arrays/tuples, or equal messages."""
    if isinstance(a, str) or isinstance(b, str):
        return a == b
    if sp.issparse(a) or sp.issparse(b):
        return (
            sp.issparse(a)
            and sp.issparse(b)
            and a.shape == b.shape
            and np.array_equal(a.indptr, b.indptr)
            and np.array_equal(a.indices, b.indices)
            and np.array_equal(a.data, b.data)
        )
    if isinstance(a, tuple | list):
        return len(a) == len(b) and all(same(x, y) for x, y in zip(a, b, strict=True))
    if isinstance(a, DofTable):
        return np.array_equal(a.nodes, b.nodes) and np.array_equal(a.directions, b.directions)
    if hasattr(a, "dependent"):  # ConstraintEquations
        return (
            np.array_equal(a.dependent, b.dependent)
            and same(a.matrix, b.matrix)
            and np.array_equal(a.offset, b.offset)
        )
    return np.array_equal(a, b)


def strict(monkeypatch, call):
    """``call`` with the fast paths switched off."""
    with monkeypatch.context() as patch:
        patch.setattr(mm, "_read_coordinate_fast", lambda path: None)
        patch.setattr(mm, "_csv_fast", lambda path, header, kinds: None)
        patch.setattr(mm, "_constraints_fast", lambda path, table: None)
        return outcome(call)


def check_matrix_file(tmp_path: Path, monkeypatch, text: str | bytes) -> tuple[object, object]:
    """Write ``text``; the fast path's matrix (or None) and the strict result, checked equal."""
    path = tmp_path / "a.mtx"
    path.write_bytes(text.encode() if isinstance(text, str) else text)
    fast = mm._read_coordinate_fast(path)
    if fast is not None:
        matrix, symmetric = fast
        raw = text if isinstance(text, bytes) else text.encode()
        assert symmetric == (b"symmetric" in raw.split(b"\n")[0].lower())
        fast = matrix
    reference = strict(monkeypatch, lambda: mm.read_matrix_market(path))
    if fast is not None:
        assert same(fast, reference), (text, fast, reference)
    assert same(outcome(lambda: mm.read_matrix_market(path)), reference)
    return fast, reference


# ============================================================================ Matrix Market
@pytest.mark.parametrize(
    ("text", "fast"),
    [
        (GENERAL + "2 2 3\n1 1 1.0\n1 2 0.5\n2 2 2.0\n", True),
        (GENERAL + "2 2 3\n2 2 2.0\n1 1 1.0\n1 2 0.5\n", True),  # unsorted
        (SYMMETRIC + "3 3 4\n1 1 1.0\n2 1 0.5\n2 2 2.0\n3 3 1\n", True),  # lower
        (SYMMETRIC + "3 3 4\n1 1 1.0\n1 2 0.5\n2 2 2.0\n3 3 1\n", True),  # upper
        (SYMMETRIC + "3 3 4\n3 3 1\n2 1 0.5\n1 1 1.0\n2 2 2.0\n", True),
        (SYMMETRIC + "3 3 4\n1 1 0.0\n2 1 -0.0\n3 1 0\n3 3 1.0\n", True),  # explicit zeros
        (GENERAL + "   2   2   2\n    1    1   1.5e+00\n    2    2  -2.5E-01\n", True),
        ((GENERAL + "2 2 2\n1 1 1.0\n2 2 2.0\n").replace("\n", "\r\n"), True),
        (GENERAL + "2 2 2\n1\t1\t1.0\n2\t2\t2.0\n", True),
        (GENERAL + "2 2 2\n\n1 1 1.0\n\n2 2 2.0\n\n", True),
        (GENERAL + "% comment\n%\n\n2 2 2\n1 1 0.0\n2 2 -0.0\n", True),  # explicit zeros
        (GENERAL + "2 2 2\n1 1 1.0\n2 2 2.0", True),  # no final line end
        (GENERAL.replace("real", "double") + "2 2 1\n1 1 1\n", True),
        (GENERAL + "2 2 0\n", True),
        # the strict pass decides (and names the line where the file is wrong)
        (SYMMETRIC + "2 2 3\n1 1 1.0\n2 1 0.5\n1 2 0.5\n", False),  # both triangles
        (GENERAL + "2 2 3\n1 1 1.0\n1 1 0.5\n2 2 2.0\n", False),  # given twice
        (SYMMETRIC + "2 2 3\n1 1 1.0\n2 1 0.5\n2 1 0.5\n", False),
        (GENERAL + "2 2 2\n1 1 1.0D+03\n2 2 2.0\n", False),  # Fortran exponent
        (GENERAL + "2 2 2\n1 1 1,5\n2 2 2.0\n", False),  # decimal comma
        (GENERAL + "2 2 2\n1 1 1.0 0.0\n2 2 2.0 0.0\n", False),  # complex values
        (GENERAL + "2 2 2\n1 1\n2 2\n", False),  # pattern values
        (GENERAL + "2 2 2\n1 1 0.1-105\n2 2 2.0\n", False),  # exponent without its letter
        (GENERAL + "2 2 2\n1 1 1-2\n2 2 2.0\n", False),
        (GENERAL + "2 2 2\n1 1 0x1p3\n2 2 2.0\n", False),
        (GENERAL + "2 2 2\n1 1 1.5e\n2 2 2.0\n", False),  # exponent without digits
        (GENERAL + "2 2 2\n1 1 1e.5\n2 2 2.0\n", False),
        (GENERAL + "2 2 2\n1 1 1ee5\n2 2 2.0\n", False),
        (GENERAL + "2 2 2\n1 1 1.0-\n2 2 2.0\n", False),  # sign without digits
        (GENERAL + "2 2 2\n1 1 2.0\n2 2 1.5E-", False),  # cut short at the end
        (GENERAL + "2 2 2\n1 1 nan\n2 2 2.0\n", False),
        (GENERAL + "2 2 2\n1 1 1e400\n2 2 2.0\n", False),  # overflows to inf
        (GENERAL + "2 2 2\n1 1 1.0 % note\n2 2 2.0\n", False),  # comment after an entry
        (GENERAL + "2 2 2\n1 1 1.0\n% note\n2 2 2.0\n", False),
        (GENERAL + "2 2 2\n1 -0 1.0\n2 2 2.0\n", False),
        (GENERAL + "2 2 2\n3 1 1.0\n2 2 2.0\n", False),  # outside
        (GENERAL + "2 2 3\n1 1 1.0\n2 2 2.0\n", False),  # count
        (GENERAL + "2 2 1\n1 1 1.0\n2 2 2.0\n", False),
        (GENERAL + "2 2 2\n+1 1 1.0\n2 2 +2.0\n", False),  # leading plus: strict pass
        (GENERAL.replace("real", "integer") + "2 2 2\n1 1 1.5\n2 2 2\n", False),
        # an upper-case banner: the compiled parser takes it, fast_matrix_market does not
        (GENERAL.upper() + "2 2 1\n1 1 1.0\n", (True, False)),
        ("\ufeff" + GENERAL + "2 2 1\n1 1 1.0\n", False),  # byte order mark
        (GENERAL + "2 2 2\n1 1 1.0\r2 2 2.0\r", False),  # old Mac line ends
        (GENERAL + "2 2 1\n1 1 1.0\x00\n", False),
        (GENERAL + "2 2 1\n1 1 1.0\u00a0\n", False),  # non-ASCII blank
    ],
)
@pytest.mark.parametrize("route", ["compiled", "fast_matrix_market"])
def test_fast_path_equals_the_strict_pass(tmp_path, monkeypatch, text, fast, route) -> None:
    """Both fast routes (the compiled one-pass parser and fast_matrix_market behind the byte
    checks) give the strict pass's matrix or leave the file to it."""
    if route == "fast_matrix_market":
        monkeypatch.setattr(mm, "_parse_compiled", lambda *args: None)
    elif not fast_text.compiled_checks():
        pytest.skip("the compiled parser needs Numba")
    result, reference = check_matrix_file(tmp_path, monkeypatch, text)
    if isinstance(fast, tuple):
        fast = fast[route != "compiled"]
    assert (result is not None) == fast, reference


def test_messages_of_the_strict_pass_are_kept(tmp_path, monkeypatch) -> None:
    path = tmp_path / "bad.mtx"
    path.write_text(GENERAL + "2 2 2\n1 1 1.0D+03\n2 2 2.0\n")
    with pytest.raises(UserError, match=r"bad\.mtx:3: value '1\.0D\+03' is not a number$"):
        mm.read_matrix_market(path)
    path.write_text(SYMMETRIC + "2 2 3\n1 1 1.0\n2 1 0.5\n2 1 0.5\n")
    with pytest.raises(UserError, match=r"bad\.mtx:5: entry \(2, 1\) is given twice"):
        mm.read_matrix_market(path)


def test_written_files_take_the_fast_path(tmp_path, monkeypatch) -> None:
    """pymorembs' own files never need the strict pass (it would read the lines)."""
    rng = np.random.default_rng(3)
    a = sp.random(60, 60, density=0.2, random_state=rng, format="csr")
    for matrix in (a + a.T, a + 1e-9 * sp.eye(60)):  # symmetric and general storage
        path = mm.write_matrix_market(tmp_path / "w.mtx", matrix)
        with monkeypatch.context() as patch:
            patch.setattr(mm, "read_text_lines", lambda *args: pytest.fail("strict pass used"))
            read = mm.read_matrix_market(path)
        assert (read != sp.csr_matrix(matrix)).nnz == 0
        assert read.has_canonical_format


# Random files: a small matrix in a random layout, then a random edit drawn from the mistakes
# and oddities that lenient parsers accept (among them a second decimal point or exponent letter
# in a number and a decimal point or exponent in an index).
EDITS = [
    "", "", "", "D", "d", ",", ";", "%", " 0", " 15", "\t", "x", "nan", "inf", "-", "+", "0x",
    "\x00", "\u00e9", "\r", "\n", "\n\n", " ", "#", "_", "1_0", "-1", "+-", ".", "..", ".5",
    "e", "E", "e5", "e-", ".e5", "1.", "e+3", " .", ". ", "5.0",
]  # fmt: skip


@st.composite
def matrix_files(draw):
    n = draw(st.integers(1, 5))
    symmetric = draw(st.booleans())
    positions = draw(st.lists(st.tuples(st.integers(0, n - 1), st.integers(0, n - 1)), max_size=12))
    if symmetric:
        lower = draw(st.booleans())
        positions = [(max(ij), min(ij)) if lower else (min(ij), max(ij)) for ij in positions]
    positions = list(dict.fromkeys(positions))
    if draw(st.booleans()):
        positions.sort()
    values = draw(
        st.lists(
            st.floats(allow_nan=False, allow_infinity=False, width=64),
            min_size=len(positions),
            max_size=len(positions),
        )
    )
    style = draw(st.sampled_from(["{!r}", "{:.15e}", "{:g}", "{:.3E}", "{: .15e}"]))
    sep = draw(st.sampled_from([" ", "  ", "\t", "   "]))
    lines = [
        f"{i + 1}{sep}{j + 1}{sep}{style.format(v)}"
        for (i, j), v in zip(positions, values, strict=True)
    ]
    if lines and draw(st.booleans()):  # one edit at a random place of one line
        k = draw(st.integers(0, len(lines) - 1))
        at = draw(st.integers(0, len(lines[k])))
        edit = draw(st.sampled_from(EDITS))
        lines[k] = lines[k][:at] + edit + lines[k][at:]
    count = len(positions) + draw(st.sampled_from([0, 0, 0, 1, -1]))
    banner = SYMMETRIC if symmetric else GENERAL
    end = draw(st.sampled_from(["\n", "\r\n"]))
    return (banner + f"{n} {n} {count}\n" + "\n".join(lines) + "\n").replace("\n", end)


@settings(
    max_examples=300, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
@given(text=matrix_files())
def test_random_files_fast_equals_strict(tmp_path, monkeypatch, text) -> None:
    check_matrix_file(tmp_path, monkeypatch, text)


@pytest.mark.parametrize(
    ("line", "message"),
    [
        ("1 1.5 2.0", "column '1.5' is not an integer"),
        ("1 1.0 2.0", "column '1.0' is not an integer"),
        ("1.0 1 2.0", "row '1.0' is not an integer"),
        ("1e0 1 2.0", "row '1e0' is not an integer"),
        ("1 1e0 2.0", "column '1e0' is not an integer"),
        ("1 1.5e3 2", "column '1.5e3' is not an integer"),
        ("1 1.5 2", "column '1.5' is not an integer"),
        ("1 1 1.0.5", "value '1.0.5' is not a number"),
        ("1 1 1..0", "value '1..0' is not a number"),
        ("1 1 1e5e5", "value '1e5e5' is not a number"),
        ("1 1 1e5.0", "value '1e5.0' is not a number"),
        ("1 1 1e-5.0", "value '1e-5.0' is not a number"),
        ("1 1 1.5e3.0", "value '1.5e3.0' is not a number"),
        ("1 1 .e5", "value '.e5' is not a number"),
        ("1 1 e5", "value 'e5' is not a number"),
        ("1 1 +-1", "value '+-1' is not a number"),
        ("1 1 1e", "value '1e' is not a number"),
        ("1 1 1e+", "value '1e+' is not a number"),
        ("1 1 1e-.5", "value '1e-.5' is not a number"),
        ("1 1 0x10", "value '0x10' is not a number"),
        ("1 1 1.0,", "value '1.0,' is not a number"),
        ("1 1 -.", "value '-.' is not a number"),
    ],
)
def test_malformed_numbers_give_the_error_of_the_strict_pass(
    tmp_path, monkeypatch, line, message
) -> None:
    """Were read silently wrong by the fast path (``1.0.5`` as 1.0, ``1 1.5 2.0`` as entry
    (1, 1) = 0.5): now the fast path declines and the strict pass names the line."""
    path = tmp_path / "gap.mtx"
    path.write_text(GENERAL + f"2 2 2\n{line}\n2 2 2.0\n")
    assert mm._read_coordinate_fast(path) is None
    with pytest.raises(UserError, match=rf"^{re.escape(str(path))}:3: {re.escape(message)}$"):
        mm.read_matrix_market(path)


@pytest.mark.parametrize("line", ["1 1 5.", "1 1 -.5", "1 1 1.e5", "1 1 00.5", "01 1 1", "1 1 +.5"])
def test_odd_but_valid_numbers_read_as_the_strict_pass_reads_them(
    tmp_path, monkeypatch, line
) -> None:
    check_matrix_file(tmp_path, monkeypatch, GENERAL + f"2 2 2\n{line}\n2 2 2.0\n")


# ============================================================================ byte checks
@pytest.mark.parametrize("chunk", [1, 2, 3, 5, 7, 64])
def test_field_count_and_signs_across_chunk_boundaries(tmp_path, monkeypatch, chunk) -> None:
    monkeypatch.setattr(fast_text, "_CHUNK", chunk)
    path = tmp_path / "f.txt"
    path.write_bytes(b"HEAD\n 12 3  -4.5e-06\n\n7\t8 9.0 \r\n10 11 .5")
    assert count_plain_fields(path, offset=5) == 9
    path.write_bytes(b"HEAD\n 12 3 4.5-06\n")
    assert count_plain_fields(path, offset=5) is None
    path.write_bytes(b"HEAD\n 12 3 4.-06\n")
    assert count_plain_fields(path, offset=5) is None
    path.write_bytes(b"HEAD\n 12 3 1D+03\n")
    assert count_plain_fields(path, offset=5) is None
    for text in (b"HEAD\n1 2 3.5e", b"HEAD\n1 2 3.5e-", b"HEAD\n1 2 3.5e \n", b"HEAD\n1 2 - 3\n"):
        path.write_bytes(text)
        assert count_plain_fields(path, offset=5) is None, text
    path.write_bytes(b"HEAD\n1 2 3.5e-7\n4 5 -.5E+1")
    assert count_plain_fields(path, offset=5) == 6


def test_field_count_of_missing_and_empty_files(tmp_path) -> None:
    assert count_plain_fields(tmp_path / "none.txt") is None
    (tmp_path / "empty.txt").write_bytes(b"")
    assert count_plain_fields(tmp_path / "empty.txt") == 0


def test_csr_from_sorted_coo() -> None:
    rows, cols = np.array([0, 0, 2, 2], dtype=np.int32), np.array([0, 3, 1, 2], dtype=np.int32)
    values = np.array([1.0, 0.0, -2.0, 3.0])
    a = csr_from_sorted_coo(rows, cols, values, 4)
    assert same(a, sp.csr_matrix((values, (rows, cols)), shape=(4, 4)))
    assert a.nnz == 4 and a.has_canonical_format  # the explicit zero is kept
    assert csr_from_sorted_coo(rows[::-1], cols[::-1], values, 4) is None
    assert csr_from_sorted_coo(rows, np.array([0, 3, 1, 1], dtype=np.int32), values, 4) is None


# ============================================================================ symmetry test
def test_check_symmetric_fast_and_general_patterns() -> None:
    a = sp.csr_matrix(np.array([[4.0, 1.0, 0.0], [1.0, 3.0, 0.0], [0.0, 0.0, 2.0]]))
    mm.check_symmetric(a, "a")  # symmetric pattern
    b = a.tolil()
    b[0, 2] = 1e-12  # one-sided tiny entry: pattern asymmetric, within the tolerance
    mm.check_symmetric(b.tocsr(), "b")
    b[0, 2] = 1e-3
    with pytest.raises(UserError, match=r"^b: matrix is not symmetric: entry \(1, 3\) = 0\.001"):
        mm.check_symmetric(b.tocsr(), "b")
    c = a.copy()
    c.data[1] = np.nan
    with pytest.raises(UserError, match="not symmetric"):
        mm.check_symmetric(c, "c")


# ============================================================================ CSV tables
DOF_TABLE = DofTable(np.array([1, 1, 2, 5]), np.array([0, 1, 5, 6]))

CSV_CASES = [
    ("dofs.csv", "node,direction\n1,ux\n1,uy\n2,rz\n5,q\n", True),
    ("dofs.csv", "Node , Direction\r\n 1 , UX \r\n1,uy\r\n2,RZ\r\n5,Q\r\n", True),
    ("dofs.csv", "node,direction\n1,ux\n\n1,uy\n2,rz\n", True),  # blank line: line numbers
    ("dofs.csv", "# comment\nnode,direction\n1,ux\n", False),
    ("dofs.csv", 'node,direction\n1,"ux"\n', False),
    ("dofs.csv", "node,direction\n1,ux\n1,UX\n", False),  # twice
    ("dofs.csv", "node,direction\n1,uxx\n", False),
    ("dofs.csv", "node,direction\n1,ux      y\n", False),  # would be cut by NumPy
    ("dofs.csv", "node,direction\n1.0,ux\n", False),
    ("dofs.csv", f"node,direction\n{2**60},ux\n", False),
    ("dofs.csv", "node,direction\n1,ux,3\n", False),
    ("dofs.csv", "node,direction\n   \n1,ux\n", False),
    ("nodes.csv", "id,x,y,z\n1,0.0,1e-3,-2\n2, 1.5 ,2,3\n5,0,0,0\n", True),
    ("nodes.csv", "id,x,y,z\n1,nan,0,0\n", False),
    ("nodes.csv", "id,x,y,z\n1,0,0,0\n1,1,1,1\n", False),
    ("nodes.csv", "id,x,y,z\n1,1_0,0,0\n", False),
    ("nodes.csv", "id,x,y,z\n1,0,0\n", False),
    ("fixed.csv", "node,direction\n2,rz\n1,ux\n", True),
    ("fixed.csv", "node,direction\n3,ux\n", False),
    ("constraints.csv", "dependent_node,dependent_direction,offset,node,direction,coefficient\n"
     "2,rz,0.0,1,ux,0.5\n2,rz,0.0,1,uy,0.25\n1,uy,1e-3,5,q,-1\n", True),
    ("constraints.csv", "dependent_node,dependent_direction,offset,node,direction,coefficient\n"
     "2,rz,0.0,1,ux,0.5\n2,rz,0.5,1,uy,0.25\n", False),  # offsets differ
    ("constraints.csv", "dependent_node,dependent_direction,offset,node,direction,coefficient\n"
     "2,rz,0.0,1,ux,0.5\n2,rz,0.0,1,ux,0.25\n", False),  # a term twice
    ("constraints.csv", "dependent_node,dependent_direction,offset,node,direction,coefficient\n"
     "2,rz,0.0,,,\n", False),  # q_d = offset
    ("constraints.csv", "dependent_node,dependent_direction,offset,node,direction,coefficient\n"
     "2,rz,0.0,9,ux,1\n", False),
]  # fmt: skip


def _read_table(name: str, path: Path):
    if name == "dofs.csv":
        return mm.read_dofs_csv(path)
    if name == "nodes.csv":
        return mm.read_nodes_csv(path)
    if name == "fixed.csv":
        return mm.read_fixed_csv(path, DOF_TABLE)
    return mm.read_constraints_csv(path, DOF_TABLE)


@pytest.mark.parametrize(("name", "text", "fast"), CSV_CASES)
def test_csv_fast_path_equals_the_strict_pass(tmp_path, monkeypatch, name, text, fast) -> None:
    path = tmp_path / name
    path.write_bytes(text.encode())
    reference = strict(monkeypatch, lambda: _read_table(name, path))
    result = outcome(lambda: _read_table(name, path))
    assert same(result, reference), (result, reference)
    with monkeypatch.context() as patch:  # whether the fast path decided alone
        patch.setattr(mm, "_read_csv", lambda *args: pytest.fail("strict pass used"))
        try:
            _read_table(name, path)
            used_fast = True
        except BaseException as err:  # pytest.fail raises outcomes.Failed
            assert not isinstance(err, UserError)
            used_fast = False
    assert used_fast == fast


def test_csv_errors_name_the_line(tmp_path) -> None:
    path = tmp_path / "dofs.csv"
    path.write_text("node,direction\n1,ux\n2,uy\n1,UX\n")
    with pytest.raises(UserError, match=re.escape("dofs.csv:4: dof 1:ux is listed twice")):
        mm.read_dofs_csv(path)


def test_index_at_the_int64_limit_is_named_without_a_warning(tmp_path) -> None:
    """Was a RuntimeWarning (scalar overflow) beside the message, a second line on stderr."""
    path = tmp_path / "limit.mtx"
    path.write_text(GENERAL + "2 2 1\n-9223372036854775808 1 1.0\n")
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        with pytest.raises(UserError, match=re.escape("entry (-9223372036854775808, 1) lies")):
            mm.read_matrix_market(path)


def test_fast_path_from_64_kib_of_entries(tmp_path, monkeypatch) -> None:
    monkeypatch.setattr(mm, "_FAST_FROM_BYTES", 1 << 16)
    small = mm.write_matrix_market(tmp_path / "small.mtx", sp.eye(10, format="csr"))
    assert mm._read_coordinate_fast(small) is None  # the strict pass reads it
    rng = np.random.default_rng(5)
    a = sp.random(400, 400, density=0.05, random_state=rng, format="csr")
    large = mm.write_matrix_market(tmp_path / "large.mtx", a + a.T)
    assert large.stat().st_size > 1 << 16
    with monkeypatch.context() as patch:
        patch.setattr(mm, "read_text_lines", lambda *args: pytest.fail("strict pass used"))
        read = mm.read_matrix_market(large)
    assert (read != a + a.T).nnz == 0


def test_lone_carriage_return_after_the_head_goes_to_the_strict_pass(tmp_path) -> None:
    """A carriage return inside a line ends the line for the strict pass but not for
    fast_matrix_market, which read ``15001 15001\\r15001.5`` as one entry: the header check
    catches it in the first 64 KiB only, the byte checks everywhere."""
    n = 20000
    lines = [f"{i} {i} {i}.5" for i in range(1, n + 1)]
    lines[15000] = "15001 15001\r15001.5"
    path = tmp_path / "cr.mtx"
    path.write_bytes((GENERAL + f"{n} {n} {n}\n" + "\n".join(lines) + "\n").encode())
    assert path.read_bytes().index(b"\r") > mm._HEAD_BYTES
    assert mm._read_coordinate_fast(path) is None
    with pytest.raises(UserError, match=r"cr\.mtx:15003: 2 values, expected 3 \(row column"):
        mm.read_matrix_market(path)


@pytest.mark.parametrize(
    ("text", "fields"),
    [
        (b"\n1 2 3\r\n4 5 6.0\r\n", 6),
        (b"\n1 2 3\r  \n\n 4 5 6.0 \r\r\n", 6),
        (b"\n" + b" " * 40 + b"1 2 3\n" + b"\r\n" * 30 + b"4\t5\t6\n", 6),
        (b"\n1 2 3\r4 5 6.0\n", None),  # a carriage return that ends no line
        (b"\n1 2\r 3\n", None),
        (b"\n1 2 3" + b" " * 30 + b"\r" + b" " * 30 + b"4 5 6\n", None),
    ],
)
def test_carriage_returns_end_lines_or_fail_the_check(text, fields) -> None:
    assert fast_text.check_chunk(text, 3, 2) == fields
    assert fast_text.check_chunk(text) == (None if fields is None else fields)


# ============================================================================ compiled checks
needs_numba = pytest.mark.skipif(
    not fast_text.compiled_checks(), reason="the compiled checks need Numba"
)

#: Bytes of the random chunks: digits (often), the other plain bytes and a few bad ones.
_CHUNK_BYTES = st.sampled_from(
    [b"0", b"1", b"7", b"9", b"0", b"3"] * 3
    + [b".", b"e", b"E", b"+", b"-", b" ", b" ", b"\t", b"\r", b"\n", b"\n", b"\r\n"]
    + [b"d", b",", b"\x00", b"%", b"\xc3", b"/", b":"]
)


@st.composite
def number_chunks(draw) -> bytes:
    """Framed chunks of random bytes; half of them well-formed lines with one random edit."""
    if draw(st.booleans()):
        body = b"".join(draw(st.lists(_CHUNK_BYTES, max_size=80)))
    else:
        fields = st.one_of(
            st.integers(0, 10**6).map(str),
            st.floats(allow_nan=False, allow_infinity=False).map(repr),
            st.floats(allow_nan=False, allow_infinity=False).map("{:.6E}".format),
        )
        lines = draw(st.lists(st.lists(fields, min_size=1, max_size=4).map(" ".join), max_size=6))
        body = "\n".join(lines).encode()
        if body and draw(st.booleans()):
            at = draw(st.integers(0, len(body)))
            body = body[:at] + draw(_CHUNK_BYTES) + body[at:]
    return b"\n" + body + b"\n"


@needs_numba
@settings(max_examples=1000, deadline=None)
@given(
    chunk=number_chunks(),
    layout=st.sampled_from([(None, 0), (1, 0), (2, 1), (3, 0), (3, 1), (3, 2), (3, 3), (4, 2)]),
)
def test_compiled_check_equals_the_numpy_check(chunk, layout) -> None:
    """The one-pass compiled check accepts exactly the bytes the vectorised check accepts and
    counts the same fields, for every layout (the Matrix Market line (3, 2) has its own
    table)."""
    expected = fast_text.check_chunk_numpy(chunk, *layout)
    assert fast_text.check_chunk(chunk, *layout, compiled=True) == expected


@needs_numba
@pytest.mark.parametrize(
    ("chunk", "layout", "fields"),
    [
        (b"\n1 2 3.5\n\n4 5 -6e-7\n", (3, 2), 6),
        (b"\n1 2 3.5\n4 5\n", (3, 2), None),  # a line of two fields
        (b"\n1 2.0 3.5\n", (3, 2), None),  # a point in an integer field
        (b"\n1 2 3.5\r4 5 6\n", (3, 2), None),  # a lone carriage return
        (b"\n1 2 3.5\r\n4 5 6\r\n", (3, 2), 6),
        (b"\n1 2 1.0.5\n", (None, 0), None),
        (b"\n1 -2 +.5 7e+3\n", (None, 0), 4),
        (b"\n1 -2 +.5 7e+3\n", (4, 1), 4),
        (b"\n1 -2 +.5 7e+3\n", (4, 2), None),  # a sign in the second integer field
        (b"\n" + b"9" * 5000 + b" 1\n", (2, 2), 2),  # long runs of digits
        (b"\n" + b" " * 5000 + b"1 2\n", (2, 0), 2),  # and of blanks
    ],
)
def test_compiled_check_of_known_chunks(chunk, layout, fields) -> None:
    """Known answers, independent of either implementation."""
    assert fast_text.check_chunk(chunk, *layout, compiled=True) == fields
    assert fast_text.check_chunk_numpy(chunk, *layout) == fields


def _random_triangle(rng, n: int, density: float, lower: bool) -> sp.csr_matrix:
    """A random canonical triangle with explicit zeros and an empty row or two."""
    a = sp.random(n, n, density=density, random_state=rng, format="coo")
    keep = a.row >= a.col if lower else a.row <= a.col
    a = sp.coo_matrix((a.data[keep], (a.row[keep], a.col[keep])), shape=(n, n)).tocsr()
    a.sort_indices()
    a.data[::5] = 0.0  # explicit zeros stay entries
    return a


def _check_full_of_triangle(stored: sp.csr_matrix, full: sp.csr_matrix) -> None:
    """``full`` is the symmetric matrix of the triangle ``stored``: the values of the dense
    formula, and the pattern (explicit zeros included) of each stored entry and its mirror
    image, canonical."""
    dense = stored.toarray()
    assert np.array_equal(full.toarray(), dense + dense.T - np.diag(np.diag(dense)))
    pattern = sp.coo_matrix(stored)
    off = pattern.row != pattern.col
    expected = set(zip(pattern.row.tolist(), pattern.col.tolist(), strict=True)) | set(
        zip(pattern.col[off].tolist(), pattern.row[off].tolist(), strict=True)
    )
    got = sp.coo_matrix(full)
    assert set(zip(got.row.tolist(), got.col.tolist(), strict=True)) == expected
    assert got.nnz == len(expected)
    assert full.has_canonical_format
    assert all(np.all(np.diff(full.indices[full.indptr[i] : full.indptr[i + 1]]) > 0)
               for i in range(full.shape[0]))  # fmt: skip


def _in_room(stored: sp.csr_matrix) -> tuple[fast_text.SymmetricRoom, sp.csr_matrix]:
    """A room filled with the entries of ``stored`` (row by row) and the triangle on its arrays."""
    room = fast_text.SymmetricRoom(stored.nnz)
    entries = sp.coo_matrix(stored)
    room.rows[:], room.cols[:], room.values[:] = entries.row, entries.col, entries.data
    triangle = fast_text.csr_from_sorted_coo(room.rows, room.cols, room.values, stored.shape[0])
    return room, triangle


@needs_numba
def test_lower_triangle_completed_in_its_own_arrays() -> None:
    """The room's in-place completion gives the dense formula's matrix and pattern, for
    triangles with explicit zeros, empty rows, rows without their diagonal, a diagonal alone and
    a full lower triangle (the most entries below the diagonal: no room to spare)."""
    rng = np.random.default_rng(5)
    cases = [_random_triangle(rng, n, density, True) for n, density in ((1, 1.0), (9, 0.4),
             (80, 0.1), (80, 0.7), (300, 0.02))]  # fmt: skip
    cases += [sp.csr_matrix(np.tril(rng.random((12, 12)))), sp.identity(5, format="csr")]
    no_diagonal = sp.csr_matrix(np.tril(rng.random((6, 6)), -1))
    cases.append(no_diagonal)
    for stored in cases:
        stored.sort_indices()
        room, triangle = _in_room(stored)
        full = room.full(triangle)
        assert full is not None
        _check_full_of_triangle(stored, full)
        assert full.indices.ctypes.data == room.rows.ctypes.data  # no second copy


def _banded_triangle(rng, n: int, band: int, diagonal: bool) -> sp.csr_matrix:
    """The lower triangle of a random symmetric band matrix, as an FE matrix in a good order
    stores it (with or without its diagonal)."""
    a = sp.random(n, n, density=0.5, random_state=rng, format="coo")
    keep = (a.row >= a.col) & (a.row - a.col <= band) & (diagonal | (a.row != a.col))
    a = sp.csr_matrix((a.data[keep], (a.row[keep], a.col[keep])), shape=(n, n))
    if diagonal:
        a = sp.csr_matrix(a + sp.identity(n))
    a.sort_indices()
    return a


@needs_numba
@pytest.mark.parametrize("block", [1, 200])
def test_two_thread_completion_equals_the_one_thread_one(monkeypatch, block) -> None:
    """The two-thread completion in blocks writes exactly the arrays of the one-thread pass: for
    band matrices of many blocks, a triangle without diagonal entries (no block fits: every
    row on one thread), a full lower triangle and a diagonal alone; the result is the dense
    formula's. ``block``: the smallest block done on two threads (from 200 entries on, the
    small blocks at the end go to one thread)."""
    from pymorembs.io import compiled_kernels as kernels

    monkeypatch.setattr(fast_text, "_MIRROR_BLOCK", block)
    rng = np.random.default_rng(12)
    cases = [_banded_triangle(rng, n, band, diagonal) for n, band, diagonal in
             ((2000, 12, True), (3000, 40, True), (500, 30, False), (1, 0, True))]  # fmt: skip
    cases += [sp.csr_matrix(np.tril(rng.random((40, 40)))), sp.identity(50, format="csr")]
    for stored in cases:
        stored.sort_indices()
        outcome = []
        for threads in ("1", "2"):
            monkeypatch.setenv("PYMOREMBS_SOLVER_THREADS", threads)
            room, triangle = _in_room(stored)
            counts = np.zeros(stored.shape[0] + 1, dtype=np.int64)
            kernels.mirror_counts(triangle.indptr, triangle.indices, counts)
            total = int(counts[-1])
            indptr = counts.astype(np.int32)
            fast_text.complete_lower_in_place(
                triangle.indptr, room._indices, room._data, stored.nnz, indptr
            )
            outcome.append((room._indices[:total].copy(), room._data[:total].copy(), indptr))
        (indices, data, indptr), (indices_2, data_2, _) = outcome
        assert np.array_equal(indices, indices_2) and np.array_equal(data, data_2)
        n = stored.shape[0]
        _check_full_of_triangle(stored, fast_text.canonical_csr(data_2, indices_2, indptr, (n, n)))


@needs_numba
def test_compiled_line_count() -> None:
    """Line feeds counted eight bytes at a time: any start and end (not multiples of eight),
    bytes that differ from a line feed in one bit or have the high bit set, more than 255 words
    and more than 2,040 line feeds in one run of lanes; against NumPy's count."""
    from pymorembs.io import compiled_kernels as kernels

    rng = np.random.default_rng(13)
    alphabet = np.array([10, 10, 32, 48, 0, 255, 0x8A, 0x0B, 0x0E, 0x2A], dtype=np.uint8)
    buffers = [rng.choice(alphabet, size) for size in (0, 5, 8, 17, 999, 5000)]
    buffers += [np.full(20000, 10, dtype=np.uint8)]
    for buffer in buffers:
        for _ in range(20):
            first, last = np.sort(rng.integers(0, buffer.size + 1, 2))
            expected = int(np.count_nonzero(buffer[first:last] == 10))
            assert kernels.count_lines(buffer, first, last) == expected
        assert kernels.count_lines(buffer, 0, buffer.size) == np.count_nonzero(buffer == 10)


@needs_numba
def test_room_refuses_what_it_cannot_complete_in_place() -> None:
    """An upper triangle (its mirrored entries would land on entries not yet read) and a matrix
    that does not hold the room's arrays are left to the caller, untouched."""
    rng = np.random.default_rng(6)
    upper = _random_triangle(rng, 30, 0.3, False)
    room, triangle = _in_room(upper)
    before = (room.rows.copy(), room.cols.copy(), room.values.copy())
    assert room.full(triangle) is None
    assert all(np.array_equal(a, b) for a, b in zip(before, (room.rows, room.cols, room.values),
                                                     strict=True))  # fmt: skip
    lower = _random_triangle(rng, 30, 0.3, True)
    room, _ = _in_room(lower)
    assert room.full(lower.copy()) is None  # the same numbers in other arrays
    assert fast_text.SymmetricRoom.fits(1) and not fast_text.SymmetricRoom.fits(2**30)
    with pytest.raises(ValueError, match="64-bit"):
        fast_text.SymmetricRoom(2**30)


@needs_numba
@pytest.mark.parametrize("lower", [True, False])
def test_compiled_mirror_of_a_triangle(monkeypatch, lower) -> None:
    monkeypatch.setattr(fast_text, "COMPILED_FROM_ENTRIES", 0)
    rng = np.random.default_rng(11)
    for n in (1, 7, 60):
        stored = _random_triangle(rng, n, 0.3, lower)
        full = fast_text.full_from_triangle(stored)
        _check_full_of_triangle(stored, full)
        with monkeypatch.context() as patch:  # the NumPy path
            patch.setattr(mm, "full_from_triangle", lambda stored: None)
            assert same(mm._mirrored(stored, lower), full)
        with ThreadPoolExecutor(1) as pool:  # off the main thread: the one-thread kernel
            assert same(pool.submit(fast_text.full_from_triangle, stored).result(), full)


@needs_numba
def test_compiled_transpose_gap(monkeypatch) -> None:
    monkeypatch.setattr(fast_text, "COMPILED_FROM_ENTRIES", 0)
    rng = np.random.default_rng(3)
    for n, density in ((1, 1.0), (9, 0.4), (50, 0.1), (50, 0.6)):
        a = sp.random(n, n, density=density, random_state=rng, format="csr")
        a.sort_indices()
        for matrix in (a, a + a.T, (a + a.T).tolil()):
            matrix = sp.csr_matrix(matrix)
            matrix.sum_duplicates()
            dense = matrix.toarray()
            expected = np.max(np.abs(dense - dense.T))
            assert fast_text.transpose_gap(matrix) == expected
            with ThreadPoolExecutor(1) as pool:  # off the main thread: the one-thread kernel
                assert pool.submit(fast_text.transpose_gap, matrix).result() == expected
    b = sp.csr_matrix(np.array([[1.0, 2.0], [2.0, np.nan]]))
    assert np.isnan(fast_text.transpose_gap(b))
    unsorted = sp.csr_matrix((np.ones(2), np.array([1, 0]), np.array([0, 2, 2])), shape=(2, 2))
    assert fast_text.transpose_gap(unsorted) is None


def test_numpy_paths_give_the_compiled_results(tmp_path, monkeypatch) -> None:
    """Without Numba (kernels switched off) a symmetric and a general file with an asymmetric
    pattern read to the same matrices, and the symmetry test finds the same gap."""
    rng = np.random.default_rng(8)
    lower = _random_triangle(rng, 80, 0.2, True)
    general = sp.random(80, 80, density=0.2, random_state=rng, format="csr")
    general.sort_indices()
    entries = sp.coo_matrix(lower)
    lines = [
        f"{i + 1} {j + 1} {v!r}\n"
        for i, j, v in zip(entries.row, entries.col, entries.data.tolist(), strict=True)
    ]
    path = tmp_path / "s.mtx"
    path.write_text(SYMMETRIC + f"80 80 {lower.nnz}\n" + "".join(lines))
    monkeypatch.setattr(fast_text, "COMPILED_FROM_ENTRIES", 0)
    monkeypatch.setattr(fast_text, "COMPILED_FROM_BYTES", 0)
    results = []
    for kernels in (fast_text._kernels, lambda required=False: None):
        with monkeypatch.context() as patch:
            patch.setattr(fast_text, "_kernels", kernels)
            results.append((mm.read_matrix_market(path), mm._transpose_gap(general)))
    (compiled, gap), (plain, plain_gap) = results
    dense = lower.toarray()
    assert np.array_equal(plain.toarray(), dense + dense.T - np.diag(np.diag(dense)))
    assert same(compiled, plain)
    assert gap == plain_gap == np.max(np.abs(general.toarray() - general.toarray().T))


# ============================================================================ compiled parser
def _parse_lines(tmp_path: Path, numbers: list[str], n: int = 9):
    """The values of ``numbers`` on lines ``i j number`` by the compiled parser (or None)."""
    path = tmp_path / "lines.mtx"
    lines = "".join(f"{k % n + 1} {(k * 5) % n + 1} {x}\n" for k, x in enumerate(numbers))
    path.write_text(lines)
    parsed = fast_text.parse_coordinate_lines(path, 0, n, len(numbers))
    if parsed is not None:
        rows, cols, _ = parsed
        k = np.arange(len(numbers))
        assert np.array_equal(rows, k % n) and np.array_equal(cols, (k * 5) % n)
    return parsed


def _bits(values) -> np.ndarray:
    return np.asarray(values, dtype=float).view(np.uint64)


@needs_numba
@settings(
    max_examples=40, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
@given(
    seed=st.integers(0, 2**32 - 1),
    style=st.sampled_from(["{!r}", "{:.15E}", "{:.16e}", "{:.18e}", "{:.17g}", "{:.6e}", "{:f}"]),
)
def test_compiled_parser_rounds_as_python_float(tmp_path, seed, style) -> None:
    """Random doubles of every binade, written in the styles of FE programs and pymorembs, read
    to the very doubles Python's correctly rounding ``float`` gives (bit for bit)."""
    rng = np.random.default_rng(seed)
    x = rng.integers(0, 2**63, size=2000, dtype=np.int64).view(np.float64)
    x = x[np.isfinite(x) & (np.abs(x) >= 2.2250738585072014e-308)]
    x = np.concatenate([x, rng.standard_normal(500) * 10.0 ** rng.integers(-12, 13, 500)])
    numbers = [style.format(v) for v in np.where(rng.random(x.size) < 0.5, -x, x).tolist()]
    numbers = [t for t in numbers if len(t.replace("-", "").split("e")[0].split("E")[0]) <= 20]
    parsed = _parse_lines(tmp_path, numbers)
    assert parsed is not None
    assert np.array_equal(_bits(parsed[2]), _bits([float(t) for t in numbers]))


@needs_numba
def test_compiled_parser_hard_cases(tmp_path) -> None:
    """Ties between two doubles (decimal integers half way, rounded to even), the limits of
    the normal range, 19 significant digits, zeros and long digit strings."""
    rng = np.random.default_rng(5)
    halfway = [
        str((int(m) * 2 + 1) << (k - 53))
        for k in range(53, 63)
        for m in rng.integers(2**52, 2**53, 50, dtype=np.int64)
    ]
    numbers = [
        *halfway,
        "9007199254740993",
        "9007199254740995",
        "1e23",
        "8.98846567431158e307",
        "1.7976931348623157e308",
        "1.7976931348623158e308",
        "2.2250738585072014e-308",
        "9999999999999999999",
        "1.234567890123456789e-200",
        "0.1",
        "-0.0",
        "0e999999",
        "000000000000000000000000123.456",
        "0.000000000000000000000000000123456",
        "123456789012345678900000",
        "1.",
        ".5",
        "+.5e-3",
        "-7E+0",
    ]
    parsed = _parse_lines(tmp_path, numbers)
    assert parsed is not None
    assert np.array_equal(_bits(parsed[2]), _bits([float(t) for t in numbers]))


@needs_numba
@pytest.mark.parametrize(
    "number",
    [
        "4.9e-324",  # subnormal
        "2.2250738585072011e-308",
        "1.7976931348623159e308",  # overflows
        "1e309",
        "12345678901234567891",  # a 20th significant digit
        "1.2345678901234567891",
        "1,5",
        "1.0D+03",
        "nan",
        "inf",
        "1e",
        "e5",
        ".e5",
        ".",
        "-",
        "1.0.5",
        "1e5.0",
        "0x10",
        "1.5 %",
        "1e+",
        "1.0 2.0",
    ],
)
def test_compiled_parser_leaves_other_numbers_to_the_strict_pass(tmp_path, number) -> None:
    assert _parse_lines(tmp_path, ["1.0", number, "2.0"]) is None


@needs_numba
@pytest.mark.parametrize(
    ("text", "entries"),
    [
        (b"  1\t1  1.0 \r\n", 1),
        (b"1 1 1.0", 1),  # no final line end
        (b"1 1 1.0\n\n \r\n\t\n", 1),  # blank lines at the end of the file
        (b"\n1 1 1.0\n", None),  # a blank line before an entry: the general path
        (b"1 1 1.0\r\r\n", 1),  # white space at the end of the file
        (b"1 1 1.0\r\r\n1 1 1.0\n", None),  # a carriage return inside the entries
        (b"0 1 1.0\n", None),  # index outside 1 .. n
        (b"10 1 1.0\n", None),
        (b"1 1.0 1.0\n", None),
        (b"+1 1 1.0\n", None),
        (b"1 1\n", None),
        (b"1 1 1.0\n2 2 2.0\n", None),  # more lines than announced
        (b"1 1 1.0\n2 2 2.0", None),  # and the last without its line end
        (b"", None),  # an empty file (nothing to map)
        (b" \r\n\n\t", None),  # white space only
        (b"1 1 " + b"0" * 70000 + b"1.0", None),  # a last line longer than any line of numbers
    ],
)
def test_compiled_parser_line_forms(tmp_path, text, entries) -> None:
    path = tmp_path / "a.txt"
    path.write_bytes(text)
    parsed = fast_text.parse_coordinate_lines(path, 0, 9, 1)
    assert (parsed is None) == (entries is None)
    if parsed is not None:
        assert parsed[0].tolist() == [0] and parsed[1].tolist() == [0]
        assert parsed[2].tolist() == [1.0]


@needs_numba
def test_compiled_parser_across_blocks(tmp_path, monkeypatch) -> None:
    """Lines cut by the block and part boundaries read whole; fewer lines than announced fail."""
    monkeypatch.setattr(fast_text, "_PARSE_BLOCK", 37)
    monkeypatch.setattr(fast_text, "_LINE_SEARCH", 64)
    rng = np.random.default_rng(9)
    values = rng.standard_normal(300)
    numbers = [repr(v) for v in values.tolist()]
    parsed = _parse_lines(tmp_path, numbers)
    assert parsed is not None
    assert np.array_equal(parsed[2], values)
    path = tmp_path / "lines.mtx"
    assert fast_text.parse_coordinate_lines(path, 0, 9, 301) is None
    with ThreadPoolExecutor(1) as pool:  # off the main thread: the one-thread kernel
        again = pool.submit(fast_text.parse_coordinate_lines, path, 0, 9, 300).result()
    assert np.array_equal(again[2], values)
    # after a header; with blank lines at the end, or the last line without its line end
    head = b"%%MatrixMarket matrix coordinate real general\n9 9 300\n"
    body = path.read_bytes().rstrip(b"\n")
    k = np.arange(300)
    for end in (b"\r\n\n  \n\t", b""):
        path.write_bytes(head + body + end)
        rows, cols, parsed_values = fast_text.parse_coordinate_lines(path, len(head), 9, 300)
        assert np.array_equal(rows, k % 9) and np.array_equal(cols, (k * 5) % 9)
        assert np.array_equal(parsed_values, values)


def test_line_ends_are_counted_block_by_block(tmp_path, monkeypatch):
    """``count_line_ends`` maps a large file in blocks and unmaps each once counted (so a
    CalculiX matrix file of 374 MB does not count in the reader's memory); the count is that of
    the whole file, also where a block ends inside a line or on a line end."""
    if not fast_text.compiled_checks():
        pytest.skip("needs Numba")
    rng = np.random.default_rng(3)
    lines = [
        f"{i} {j} {v!r}\n"
        for i, j, v in zip(range(1, 4001), range(1, 4001), rng.normal(size=4000), strict=True)
    ]
    data = "".join(lines).encode() + b"9 9 1.0"  # the last line without its line end
    path = tmp_path / "job.sti"
    path.write_bytes(data)
    monkeypatch.setattr(fast_text, "_PARSE_BLOCK", mmap.PAGESIZE)
    assert len(data) > 10 * mmap.PAGESIZE
    assert fast_text.count_line_ends(path) == data.count(b"\n") == 4000


# ============================================================================ CalculiX's order
def _upper_lines(rng, n: int, zeros: float) -> tuple[list[tuple[int, int, str]], np.ndarray]:
    """Lines ``row column value`` (from 1) of a random upper triangle column by column, as
    CalculiX writes it: every diagonal entry, a share ``zeros`` of the entries written as zero
    (also some diagonal ones, in CalculiX's and other zero spellings), and the dense matrix."""
    zero_forms = ["0.0000000000000e+00", "-0.0000000000000e+00", "0", "0.0", "-0.", "0e5"]
    lines, dense = [], np.zeros((n, n))
    for column in range(n):
        for row in sorted({*rng.choice(column + 1, size=min(column, 4)).tolist(), column}):
            if rng.random() < zeros:
                text = zero_forms[int(rng.integers(len(zero_forms)))]
            else:
                text = f"{rng.standard_normal() * 10.0 ** rng.integers(-8, 9):.13e}"
            lines.append((row + 1, column + 1, text))
            dense[row, column] = dense[column, row] = float(text)
    return lines, dense


def _write_lines(path: Path, lines) -> Path:
    path.write_text("".join(f"{r} {c}  {v}\n" for r, c, v in lines))
    return path


@needs_numba
@pytest.mark.parametrize(("block", "part", "threads"), [(1 << 24, 1 << 20, "1"), (97, 40, "2")])
def test_calculix_order_leaves_zeros_out(tmp_path, monkeypatch, block, part, threads) -> None:
    """With ``upper_columns`` the entries off the diagonal that are zero are not stored, the
    others (every diagonal entry among them, also a zero one) are, in file order; also when the
    lines are parsed in many blocks of two parts each, whose entries are moved together."""
    monkeypatch.setattr(fast_text, "_PARSE_BLOCK", block)
    monkeypatch.setattr(fast_text, "_PART_BYTES", part)
    monkeypatch.setenv("PYMOREMBS_SOLVER_THREADS", threads)
    rng = np.random.default_rng(21)
    n = 60
    lines, _ = _upper_lines(rng, n, 0.6)
    path = _write_lines(tmp_path / "job.mas", lines)
    parsed = fast_text.parse_coordinate_lines(path, 0, n, len(lines), upper_columns=True)
    assert parsed is not None
    kept = [(r - 1, c - 1, float(v)) for r, c, v in lines if r == c or float(v) != 0.0]
    assert len(kept) < len(lines)  # zeros were left out
    rows, cols, values = parsed
    assert rows.tolist() == [k[0] for k in kept] and cols.tolist() == [k[1] for k in kept]
    assert np.array_equal(_bits(values), _bits([k[2] for k in kept]))
    # without the CalculiX order every line is stored
    everything = fast_text.parse_coordinate_lines(path, 0, n, len(lines))
    assert everything is not None and everything[0].size == len(lines)


@needs_numba
@pytest.mark.parametrize(
    "edit",
    [
        "zero twice",  # a position given twice (the second a zero, which is not stored)
        "zero below",  # a zero below the diagonal
        "zero out of order",
        "entry below",
        "entry out of order",
    ],
)
@pytest.mark.parametrize("block", [1 << 24, 61])
def test_calculix_order_is_checked_on_every_line(tmp_path, monkeypatch, edit, block) -> None:
    """A line out of CalculiX's order fails the parse (the strict pass then names it), also
    when it is a zero that is not stored and when the order breaks across blocks and parts."""
    monkeypatch.setattr(fast_text, "_PARSE_BLOCK", block)
    monkeypatch.setattr(fast_text, "_PART_BYTES", 30)
    monkeypatch.setenv("PYMOREMBS_SOLVER_THREADS", "2")
    rng = np.random.default_rng(22)
    n = 30
    lines, _ = _upper_lines(rng, n, 0.0)
    at = len(lines) // 2
    row, column, _ = lines[at]
    if edit == "zero twice":
        lines.insert(at + 1, (row, column, "0.0"))
    elif edit == "zero below":
        lines.insert(at, (column + 1, column, "0.0"))
    elif edit == "zero out of order":
        lines.insert(at, (1, column + 1, "0.0"))
    elif edit == "entry below":
        lines.insert(at, (column + 1, column, "1.5"))
    else:
        lines[at], lines[at + 3] = lines[at + 3], lines[at]
    path = _write_lines(tmp_path / "job.sti", lines)
    assert fast_text.parse_coordinate_lines(path, 0, n, len(lines), upper_columns=True) is None
    assert fast_text.parse_coordinate_lines(path, 0, n, len(lines)) is not None


@needs_numba
def test_room_with_fewer_entries_is_cut_to_the_full_matrix() -> None:
    """A triangle with fewer entries than its room (zeros left out by the parser) is completed
    in place, and the room's arrays are cut to the full matrix: no memory beyond it is held."""
    rng = np.random.default_rng(23)
    stored = _banded_triangle(rng, 400, 6, True)
    room = fast_text.SymmetricRoom(3 * stored.nnz)  # room for three times the entries
    entries = sp.coo_matrix(stored)
    k = stored.nnz
    room.rows[:k], room.cols[:k], room.values[:k] = entries.row, entries.col, entries.data
    triangle = csr_from_sorted_coo(room.rows[:k], room.cols[:k], room.values[:k], 400)
    assert triangle.indices.ctypes.data == room.cols.ctypes.data  # no copy of the view
    full = room.full(triangle)
    assert full is not None
    _check_full_of_triangle(stored, full)
    dense = stored.toarray()
    assert np.array_equal(full.toarray(), dense + dense.T - np.diag(np.diag(dense)))
    assert full.indices.size == full.data.size == full.nnz
    assert full.indices.base is None and full.data.base is None  # the room's own, cut


def test_canonical_csr_keeps_views_and_converts_the_rest() -> None:
    """A view of less than a half of its array stays a view (SciPy's constructor copies it);
    arrays of two index types go through the constructor, to the same matrix."""
    indices = np.array([0, 2, 1, 0, 1, 2, 9, 9, 9, 9], dtype=np.int32)
    data = np.arange(10.0)
    indptr = np.array([0, 2, 3, 4], dtype=np.int32)
    a = fast_text.canonical_csr(data[:4], indices[:4], indptr, (3, 3))
    assert a.indices.ctypes.data == indices.ctypes.data and a.data.ctypes.data == data.ctypes.data
    expected = np.array([[0.0, 0.0, 1.0], [0.0, 2.0, 0.0], [3.0, 0.0, 0.0]])
    assert np.array_equal(a.toarray(), expected)
    b = fast_text.canonical_csr(data[:4], indices[:4], indptr.astype(np.int64), (3, 3))
    assert np.array_equal(b.toarray(), expected) and b.has_canonical_format
    c = fast_text.canonical_csr(data, indices, indptr, (3, 3))  # longer arrays: cut
    assert c.nnz == 4 and c.indices.size == 4 and np.array_equal(c.toarray(), expected)
    with pytest.raises(ValueError):
        fast_text.canonical_csr(data[:4], indices[:4], indptr[:3], (3, 3))
