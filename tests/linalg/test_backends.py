"""Sparse direct solver backends: SuperLU always, MKL PARDISO when installed."""

from __future__ import annotations

import gc

import numpy as np
import pytest
import scipy.sparse as sp

from pymorembs.errors import NumericalError, UserError
from pymorembs.examples import build_example
from pymorembs.linalg import backends
from pymorembs.linalg.backends import available_backends, default_backend, factorize
from pymorembs.linalg.factorization import Factorization, is_symmetric
from pymorembs.preparation import Frame, Port, prepare

BACKENDS = available_backends()
N = 60


def _random_symmetric(kind: str, seed: int = 0) -> sp.csr_matrix:
    """A sparse well-conditioned test matrix: "spd", "indefinite", "complex" (symmetric) or
    "nonsymmetric"."""
    rng = np.random.default_rng(seed)
    a = sp.random(N, N, density=0.08, random_state=rng)
    if kind == "nonsymmetric":
        return sp.csr_matrix(a + sp.diags(4.0 + rng.random(N)))
    a = a + a.T
    if kind == "spd":
        return sp.csr_matrix(a + sp.diags(np.abs(a).sum(axis=1).A1 + 1.0))
    signs = np.where(np.arange(N) % 2 == 0, 1.0, -1.0)
    shifted = sp.csr_matrix(a + sp.diags(signs * (np.abs(a).sum(axis=1).A1 + 1.0)))
    if kind == "indefinite":
        return shifted
    return sp.csr_matrix(shifted + 0.3j * sp.diags(rng.random(N)) + 0.05j * a)


@pytest.mark.parametrize("backend", BACKENDS)
@pytest.mark.parametrize("kind", ["spd", "indefinite", "complex", "nonsymmetric"])
def test_solutions_match_dense(backend: str, kind: str) -> None:
    matrix = _random_symmetric(kind)
    symmetric = kind != "nonsymmetric"
    factor = factorize(matrix, symmetric=symmetric, backend=backend)
    assert factor.backend == backend
    assert factor.seconds >= 0 and factor.nnz_factor > 0 and factor.memory_bytes > 0
    rng = np.random.default_rng(1)
    block = rng.standard_normal((N, 4))
    dense = matrix.toarray()
    x = factor.solve(block)  # several right-hand sides in one call
    assert x.shape == (N, 4)
    np.testing.assert_allclose(x, np.linalg.solve(dense, block), rtol=0, atol=1e-12)
    vector = block[:, 0] + 1j * block[:, 1]  # one vector; complex with a real factor too
    np.testing.assert_allclose(
        factor.solve(vector), np.linalg.solve(dense, vector), rtol=0, atol=1e-12
    )
    assert factor.solve(np.zeros((N, 0))).shape == (N, 0)


@pytest.mark.parametrize("backend", BACKENDS)
def test_symmetric_factor_reads_upper_triangle_only(backend: str) -> None:
    matrix = _random_symmetric("indefinite")
    # the lower triangle of a symmetric matrix carries no information; PARDISO ignores it
    factor = factorize(matrix, symmetric=True, backend=backend)
    b = np.arange(N, dtype=float)
    np.testing.assert_allclose(matrix @ factor.solve(b), b, rtol=0, atol=1e-10)


@pytest.mark.parametrize("backend", BACKENDS)
def test_singular_matrix_is_a_numerical_error(backend: str) -> None:
    singular = sp.csr_matrix(np.array([[1.0, 1.0, 0.0], [1.0, 1.0, 0.0], [0.0, 0.0, 2.0]]))
    with pytest.raises(NumericalError, match="singular"):
        factorize(singular, symmetric=True, backend=backend)
    with pytest.raises(NumericalError, match=r"^K is singular"):
        Factorization(singular, label="K", backend=backend).solve(np.ones(3))


@pytest.mark.parametrize("backend", BACKENDS)
def test_factorization_uses_backend_and_refines(backend: str) -> None:
    k = _random_symmetric("spd", seed=3)
    m = sp.diags(np.linspace(1.0, 2.0, N)).tocsr()
    terms = [(1.0, k), (-(0.5 + 0.1j), m)]
    factorization = Factorization(terms, label="test", backend=backend)
    assert factorization.symmetric and factorization.factor.backend == backend
    rhs = np.random.default_rng(2).standard_normal((N, 3))
    dense = k.toarray() - (0.5 + 0.1j) * m.toarray()
    np.testing.assert_allclose(
        factorization.solve(rhs), np.linalg.solve(dense, rhs), rtol=0, atol=1e-13
    )


def test_nonsymmetric_terms_are_factorized_as_nonsymmetric() -> None:
    a = _random_symmetric("nonsymmetric")
    assert not is_symmetric(a)
    assert is_symmetric(_random_symmetric("indefinite"))
    factorization = Factorization(a)
    assert not factorization.symmetric
    b = np.ones(N)
    np.testing.assert_allclose(a @ factorization.solve(b), b, rtol=0, atol=1e-12)


def test_environment_selects_the_backend(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("PYMOREMBS_SOLVER", "superlu")
    assert default_backend() == "superlu"
    assert factorize(_random_symmetric("spd"), symmetric=True).backend == "superlu"
    assert Factorization(_random_symmetric("spd")).factor.backend == "superlu"
    monkeypatch.setenv("PYMOREMBS_SOLVER", "auto")
    assert default_backend() == BACKENDS[-1]
    # small matrices go to SuperLU under "auto": PARDISO's fixed costs dominate there
    assert factorize(_random_symmetric("spd"), symmetric=True).backend == "superlu"
    monkeypatch.setenv("PYMOREMBS_SOLVER", "umfpack")
    with pytest.raises(UserError, match="PYMOREMBS_SOLVER"):
        default_backend()
    monkeypatch.setenv("PYMOREMBS_SOLVER", "pardiso")
    if "pardiso" in BACKENDS:
        assert default_backend() == "pardiso"
    else:
        with pytest.raises(UserError, match="not available"):
            default_backend()
    with pytest.raises(UserError, match="unknown solver backend"):
        factorize(_random_symmetric("spd"), symmetric=True, backend="mumps")


def test_superlu_is_always_available() -> None:
    assert available_backends()[0] == "superlu"


def test_thread_count_from_environment(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("PYMOREMBS_SOLVER_THREADS", "1")
    assert backends.solver_threads() == 1
    monkeypatch.setenv("PYMOREMBS_SOLVER_THREADS", "two")
    with pytest.raises(UserError, match="PYMOREMBS_SOLVER_THREADS"):
        backends.solver_threads()
    monkeypatch.delenv("PYMOREMBS_SOLVER_THREADS")
    assert backends.solver_threads() >= 1


# --- PARDISO only -------------------------------------------------------------------------------


@pytest.fixture
def pardiso() -> None:
    if "pardiso" not in BACKENDS:  # not installed, or MKL not loadable
        pytest.skip("MKL PARDISO is not available")
    pytest.importorskip("pypardiso")


@pytest.mark.usefixtures("pardiso")
def test_pardiso_matrix_types_and_inertia() -> None:
    indefinite = factorize(_random_symmetric("indefinite"), symmetric=True, backend="pardiso")
    assert indefinite.mtype == -2 and indefinite.perturbed_pivots == 0
    eigenvalues = np.linalg.eigvalsh(_random_symmetric("indefinite").toarray())
    assert indefinite.inertia == (np.sum(eigenvalues > 0), np.sum(eigenvalues < 0))
    assert factorize(_random_symmetric("complex"), symmetric=True, backend="pardiso").mtype == 6
    nonsymmetric = _random_symmetric("nonsymmetric")
    assert factorize(nonsymmetric, symmetric=False, backend="pardiso").mtype == 11
    assert factorize(nonsymmetric * (1 + 1j), symmetric=False, backend="pardiso").mtype == 13


@pytest.mark.usefixtures("pardiso")
def test_pardiso_factors_are_independent_and_freed(monkeypatch) -> None:
    monkeypatch.setenv(backends.FAMILIES_ENV, "0")  # every factor its own handle
    a, b = _random_symmetric("indefinite", 5), _random_symmetric("complex", 6)
    first = factorize(a, symmetric=True, backend="pardiso")
    second = factorize(b, symmetric=True, backend="pardiso")  # its own handle
    rhs = np.ones(N)
    np.testing.assert_allclose(a @ first.solve(rhs), rhs, atol=1e-12)
    np.testing.assert_allclose(b @ second.solve(rhs), rhs, atol=1e-12)
    handle = first._pt
    del first
    gc.collect()
    assert not handle.any()  # phase -1 released the memory
    np.testing.assert_allclose(b @ second.solve(rhs), rhs, atol=1e-12)


@pytest.mark.usefixtures("pardiso")
def test_pardiso_perturbed_pivots_fall_back_to_superlu() -> None:
    # nearly singular: PARDISO would perturb the pivot; SuperLU factorizes it exactly
    nearly = sp.csr_matrix(np.array([[1.0, 1.0], [1.0, 1.0 + 1e-15]]))
    factor = factorize(nearly, symmetric=True, backend="pardiso")
    assert factor.backend == "superlu"


@pytest.mark.usefixtures("pardiso")
def test_pardiso_reuses_the_ordering_of_a_pattern() -> None:
    k = _random_symmetric("spd", seed=7)
    m = sp.diags(np.linspace(1.0, 2.0, N)).tocsr()
    rhs = np.ones(N)
    for shift in (0.3, 0.7, 0.3 + 0.2j):  # same pattern, new values (real and complex)
        a = sp.csr_matrix(k - shift * m)
        factor = factorize(a, symmetric=True, backend="pardiso")
        np.testing.assert_allclose(a @ factor.solve(rhs), rhs, atol=1e-12)
    assert factor._iparm[4] == 1  # the stored ordering was given to PARDISO


@pytest.mark.usefixtures("pardiso")
def test_pardiso_family_shares_the_analysis_and_frees_its_slots(monkeypatch) -> None:
    """Factors of one pattern share a handle (one analysis), solve independently, give their slot
    back when collected, and the handle is released with the family's last factor."""
    monkeypatch.setattr(backends, "_FAMILIES", {})
    k = _random_symmetric("spd", seed=11)
    m = sp.diags(np.linspace(1.0, 2.0, N)).tocsr()
    matrices = [sp.csr_matrix(k - shift * m) for shift in (0.2, 0.5, 0.9)]
    factors = [factorize(a, symmetric=True, backend="pardiso") for a in matrices]
    family = factors[0]._family
    assert family is not None and all(f._family is family for f in factors)
    assert sorted(f._mnum for f in factors) == [2, 3, 4]
    rhs = np.ones(N)
    for a, factor in zip(matrices, factors, strict=True):  # each its own numeric factor
        np.testing.assert_allclose(a @ factor.solve(rhs), rhs, atol=1e-12)
    slot = factors[1]._mnum
    del factors[1]
    gc.collect()
    assert slot in family.free
    again = factorize(matrices[2] * 2.0, symmetric=True, backend="pardiso")  # reuses the slot
    assert again._mnum == slot
    np.testing.assert_allclose((matrices[2] * 2.0) @ again.solve(rhs), rhs, atol=1e-12)
    np.testing.assert_allclose(matrices[0] @ factors[0].solve(rhs), rhs, atol=1e-12)
    handle = family.pt
    backends._FAMILIES.clear()
    del factors, factor, again, family
    gc.collect()
    assert not handle.any()  # phase -1 with the last factor of the dropped family


@pytest.mark.usefixtures("pardiso")
def test_auto_sends_complex_matrices_to_pardiso_from_a_smaller_size(monkeypatch) -> None:
    """SciPy's complex SuperLU is many times slower than its real one: ``auto`` leaves complex
    matrices on SuperLU only below :data:`AUTO_MIN_NNZ_COMPLEX`."""
    monkeypatch.delenv("PYMOREMBS_SOLVER", raising=False)
    real, complex_ = _random_symmetric("indefinite"), _random_symmetric("complex")
    assert backends.AUTO_MIN_NNZ_COMPLEX < backends.AUTO_MIN_NNZ
    monkeypatch.setattr(backends, "AUTO_MIN_NNZ_COMPLEX", complex_.nnz)
    assert real.nnz >= complex_.nnz and real.nnz < backends.AUTO_MIN_NNZ
    assert factorize(real, symmetric=True).backend == "superlu"
    assert factorize(complex_, symmetric=True).backend == "pardiso"
    monkeypatch.setattr(backends, "AUTO_MIN_NNZ_COMPLEX", complex_.nnz + 1)
    assert factorize(complex_, symmetric=True).backend == "superlu"


# --- without PARDISO: SuperLU and one note for large models -------------------------------------


@pytest.fixture
def without_pardiso(monkeypatch: pytest.MonkeyPatch) -> None:
    """As where MKL is missing: PARDISO does not work, ``auto`` is chosen, no note written yet."""
    monkeypatch.setattr(backends, "_pardiso_works", lambda: False)
    monkeypatch.delenv("PYMOREMBS_SOLVER", raising=False)
    backends._write_fast_solver_note.cache_clear()
    yield
    backends._write_fast_solver_note.cache_clear()


@pytest.mark.usefixtures("without_pardiso")
def test_large_model_on_superlu_gets_one_note(monkeypatch, capsys) -> None:
    matrix = _random_symmetric("indefinite")
    monkeypatch.setattr(backends, "AUTO_MIN_NNZ", 0)  # as a large model
    monkeypatch.setattr(backends, "NOTE_MIN_NNZ", matrix.nnz)
    monkeypatch.setattr(backends.platform, "system", lambda: "Linux")
    monkeypatch.setattr(backends.platform, "machine", lambda: "x86_64")
    assert available_backends() == ["superlu"] and default_backend() == "superlu"
    for _ in range(3):  # three factorizations, one line
        assert factorize(matrix, symmetric=True).backend == "superlu"
    Factorization(matrix).solve(np.ones(N))
    factorize(_random_symmetric("complex"), symmetric=True)
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("pymorembs: note: ")
    assert "(MKL PARDISO) is not available" in err and "pip install 'pymorembs[fast]'" in err


@pytest.mark.usefixtures("without_pardiso")
def test_note_names_a_platform_without_mkl_wheels(monkeypatch, capsys) -> None:
    monkeypatch.setattr(backends, "NOTE_MIN_NNZ", 0)
    monkeypatch.setattr(backends.platform, "system", lambda: "Darwin")
    monkeypatch.setattr(backends.platform, "machine", lambda: "arm64")
    factorize(_random_symmetric("spd"), symmetric=True)
    err = capsys.readouterr().err
    assert "MKL publishes no wheels for Darwin arm64" in err and "pip install" not in err
    monkeypatch.setenv("PYMOREMBS_SOLVER", "pardiso")
    with pytest.raises(UserError, match=r"not available.*no wheels for Darwin arm64"):
        default_backend()


@pytest.mark.usefixtures("without_pardiso")
def test_complex_matrices_get_the_note_from_a_smaller_size(monkeypatch, capsys) -> None:
    complex_ = _random_symmetric("complex")
    monkeypatch.setattr(backends, "AUTO_MIN_NNZ_COMPLEX", complex_.nnz)
    monkeypatch.setattr(backends, "NOTE_MIN_NNZ", complex_.nnz + 1)
    factorize(complex_.real.tocsr(), symmetric=True)  # real: below NOTE_MIN_NNZ
    assert capsys.readouterr().err == ""
    assert factorize(complex_, symmetric=True).backend == "superlu"
    assert capsys.readouterr().err.startswith("pymorembs: note: the fast sparse solver")


@pytest.mark.usefixtures("without_pardiso")
def test_no_note_for_small_models_or_a_chosen_superlu(monkeypatch, capsys) -> None:
    matrix = _random_symmetric("spd")
    monkeypatch.setattr(backends, "NOTE_MIN_NNZ", matrix.nnz + 1)
    factorize(matrix, symmetric=True)  # small
    monkeypatch.setattr(backends, "NOTE_MIN_NNZ", 0)
    monkeypatch.setenv("PYMOREMBS_SOLVER", "superlu")  # asked for
    factorize(matrix, symmetric=True)
    monkeypatch.delenv("PYMOREMBS_SOLVER")
    factorize(matrix, symmetric=True, backend="superlu")  # asked for by the caller
    assert capsys.readouterr().err == ""


def test_no_note_with_pardiso(monkeypatch, capsys) -> None:
    monkeypatch.setattr(backends, "_pardiso_works", lambda: True)
    monkeypatch.setattr(backends, "NOTE_MIN_NNZ", 0)
    monkeypatch.delenv("PYMOREMBS_SOLVER", raising=False)
    backends._write_fast_solver_note.cache_clear()
    factorize(_random_symmetric("spd"), symmetric=True)  # small: SuperLU, but PARDISO is there
    assert capsys.readouterr().err == ""


def test_upper_triangle_keeps_the_entries_on_and_above_the_diagonal() -> None:
    rng = np.random.default_rng(5)
    a = sp.random(40, 40, density=0.2, random_state=rng, format="csr")
    a = sp.csr_matrix(a + a.T + sp.identity(40))
    upper, key = backends._upper_triangle(a)
    assert key is not None and upper.has_canonical_format
    assert abs(upper - sp.triu(a)).max() == 0 and upper.nnz == sp.triu(a).nnz
    again, same = backends._upper_triangle(
        sp.csr_matrix((2 * a.data, a.indices, a.indptr), a.shape)
    )
    assert same == key and abs(again - 2 * sp.triu(a)).max() == 0
    hole = sp.csr_matrix(a - sp.diags(a.diagonal()))  # no stored diagonal: zeros added
    hole.eliminate_zeros()
    upper, key = backends._upper_triangle(hole)
    assert key is None and upper.nnz == sp.triu(hole).nnz + 40


def _dense_symmetric(a: sp.spmatrix) -> bool:
    """The definition of ``is_symmetric`` on the dense matrix."""
    d = a.toarray()
    return bool(np.abs(d - d.T).max() <= 1e-14 * np.abs(d).max())


@pytest.mark.parametrize("compiled", [True, False])
@pytest.mark.parametrize("seed", range(4))
def test_symmetry_check_agrees_with_the_dense_definition(seed: int, compiled: bool, monkeypatch):
    """Both ways of ``is_symmetric``: the compiled one-pass gap (the kernel of the readers'
    ``transpose_gap``) and, without Numba, ``|A - A^T|`` formed."""
    from pymorembs.linalg import double_double, factorization

    if compiled and not double_double.available():
        pytest.skip("Numba is not installed")
    if not compiled:
        monkeypatch.setattr(factorization, "_compiled_gap", lambda a: None)

    rng = np.random.default_rng(seed)
    n = 60
    base = sp.random(n, n, density=0.08, random_state=seed, format="csr")
    symmetric = (base + base.T + sp.identity(n)).tocsr()
    i, j = symmetric.nonzero()
    off = np.flatnonzero(i != j)
    k = off[rng.integers(off.size)]
    cases = {"symmetric": symmetric}
    for relative in (1e-10, 1e-16):  # above and below the tolerance (1e-14)
        bumped = symmetric.copy().tolil()
        bumped[i[k], j[k]] += relative * abs(symmetric).max()
        cases[f"bumped {relative}"] = bumped.tocsr()
    lonely = symmetric.copy().tolil()  # an entry whose mirror is not stored
    empty = np.argwhere(symmetric.toarray() == 0)
    r, c = empty[rng.integers(len(empty))]
    lonely[r, c] = 0.5
    cases["lonely entry"] = lonely.tocsr()
    zero_mirror = lonely.tocsr()  # the same, with an explicit zero stored as its mirror
    zero_mirror = (zero_mirror + sp.csr_matrix(([0.0], ([c], [r])), shape=(n, n))).tocsr()
    cases["explicit zero mirror"] = zero_mirror
    explicit_zeros = symmetric.copy()  # stored zeros on one side only are still symmetric
    explicit_zeros.data[explicit_zeros.data < 0.05] = 0.0
    cases["stored zeros"] = explicit_zeros
    unsorted = symmetric.copy()
    unsorted.indices = unsorted.indices.copy()
    for row in range(n):  # reverse the column order of every row: not canonical
        start, end = unsorted.indptr[row], unsorted.indptr[row + 1]
        unsorted.indices[start:end] = unsorted.indices[start:end][::-1].copy()
        unsorted.data[start:end] = unsorted.data[start:end][::-1].copy()
    unsorted.has_sorted_indices = False
    cases["unsorted"] = unsorted
    for name, matrix in cases.items():
        factorization._SYMMETRIC.clear()
        assert is_symmetric(matrix) == _dense_symmetric(matrix), name
    assert not _dense_symmetric(cases["bumped 1e-10"]) and _dense_symmetric(cases["bumped 1e-16"])
    assert not _dense_symmetric(cases["lonely entry"])


def test_a_matrix_made_symmetric_is_known_without_a_comparison(monkeypatch) -> None:
    """The elimination's ``(A + A^T) / 2`` is recorded as symmetric: no transpose gap is computed
    for it, or for the prepared model's matrices, while a new matrix still is compared, and
    found asymmetric when it is."""
    from pymorembs.linalg import factorization
    from pymorembs.preparation.elimination import symmetric_part

    rng = np.random.default_rng(3)
    base = sp.random(50, 50, density=0.1, random_state=3, format="csr") + sp.identity(50)
    base = sp.csr_matrix(base + 1e-3 * sp.random(50, 50, density=0.1, random_state=4))
    base.sum_duplicates()
    made = symmetric_part(base)
    compared = []

    def gap(a):
        compared.append(a.shape)
        return float(abs(a - a.T).max())

    monkeypatch.setattr(factorization, "_compiled_gap", gap)
    assert is_symmetric(made) and not compared
    assert np.array_equal(made.toarray(), made.toarray().T)
    prepared = prepare(build_example("rack-beams"), Frame("tangent", 2), [Port.parse(1, "uz")])
    system = prepared.system
    assert is_symmetric(system.stiffness) and is_symmetric(system.mass) and not compared
    bumped = made.copy()
    bumped.data[rng.integers(bumped.nnz)] *= 1 + 1e-8
    assert not is_symmetric(bumped) and compared == [(50, 50)]
