"""Storage of PARDISO's factors: out of core and single precision solve as in core, double."""

from __future__ import annotations

import gc
import os

import numpy as np
import pytest
import scipy.sparse as sp

from pymorembs.errors import NumericalError, UserError
from pymorembs.linalg import backends
from pymorembs.linalg.backends import PardisoFactor, available_backends, pardiso_storage
from pymorembs.linalg.factorization import Factorization

pytestmark = pytest.mark.skipif(
    "pardiso" not in available_backends(), reason="MKL PARDISO is not available"
)


def laplacian(n: int, dimensions: int) -> sp.csr_matrix:
    """The finite-difference Laplacian of an ``n**dimensions`` grid (symmetric positive
    definite; condition number about ``(2 n / pi)**2``)."""
    line = sp.diags([-np.ones(n - 1), 2 * np.ones(n), -np.ones(n - 1)], [-1, 0, 1])
    eye = sp.identity(n)
    total = sp.csr_matrix((n**dimensions, n**dimensions))
    for axis in range(dimensions):
        parts = [line if k == axis else eye for k in range(dimensions)]
        term = parts[0]
        for part in parts[1:]:
            term = sp.kron(term, part)
        total = total + term
    return sp.csr_matrix(total)


@pytest.fixture
def fresh(monkeypatch: pytest.MonkeyPatch, tmp_path) -> None:
    """No cached families (each test makes its own handles); out-of-core files under tmp_path."""
    monkeypatch.setattr(backends, "_FAMILIES", {})
    monkeypatch.setenv(backends.OOC_DIR_ENV, str(tmp_path))


def shifted(k: sp.csr_matrix, shift: complex) -> list[tuple[complex, sp.csr_matrix]]:
    """Terms of ``K - shift I`` (indefinite for a real shift inside the spectrum)."""
    return [(1.0, k), (-shift, sp.identity(k.shape[0], format="csr"))]


@pytest.mark.usefixtures("fresh")
@pytest.mark.parametrize("shift", [0.0, 1.3, 1.3 + 0.2j])
def test_out_of_core_solves_as_in_core(monkeypatch: pytest.MonkeyPatch, tmp_path, shift) -> None:
    k = laplacian(12, 3)
    rhs = np.random.default_rng(1).standard_normal((k.shape[0], 3))
    solutions = {}
    for storage in ("in-core", "out-of-core"):
        monkeypatch.setenv(backends.STORAGE_ENV, storage)
        solver = Factorization(shifted(k, shift), backend="pardiso", refine="always")
        assert solver.factor.out_of_core == (storage == "out-of-core")
        solutions[storage] = solver.solve(rhs)
        plain = solver.factor.solve(rhs)
        if storage == "out-of-core":
            assert len(os.listdir(solver.factor._files.directory)) > 0  # the factor files
    exact = solutions["in-core"]
    scale = np.abs(exact).max()
    # the same double-precision factorization, written to files: the same digits
    assert np.abs(solutions["out-of-core"] - exact).max() <= 1e-13 * scale
    assert np.abs(plain - exact).max() <= 1e-12 * scale


@pytest.mark.usefixtures("fresh")
def test_out_of_core_files_go_with_their_handle(monkeypatch: pytest.MonkeyPatch, tmp_path):
    monkeypatch.setenv(backends.STORAGE_ENV, "out-of-core")
    monkeypatch.setenv(backends.FAMILIES_ENV, "0")  # own handle: released with the factor
    factor = backends.factorize(laplacian(10, 3), symmetric=True, backend="pardiso")
    assert factor.out_of_core and os.listdir(tmp_path)
    del factor
    gc.collect()
    assert os.listdir(tmp_path) == []


@pytest.mark.usefixtures("fresh")
def test_out_of_core_factors_have_handles_of_their_own(monkeypatch: pytest.MonkeyPatch) -> None:
    # several factors of one handle out of core gave a wrong solve in about one run of eight
    monkeypatch.setenv(backends.STORAGE_ENV, "out-of-core")
    k = laplacian(10, 3)
    rhs = np.ones(k.shape[0])
    matrices = [sp.csr_matrix(k - s * sp.identity(k.shape[0])) for s in (0.1, 0.7, 2.2)]
    factors = [backends.factorize(a, symmetric=True, backend="pardiso") for a in matrices]
    assert all(f._family is None and f.out_of_core for f in factors)
    for a, factor in zip(matrices, factors, strict=True):
        np.testing.assert_allclose(a @ factor.solve(rhs), rhs, rtol=0, atol=1e-11)


@pytest.mark.slow
@pytest.mark.usefixtures("fresh")
def test_auto_goes_out_of_core_when_the_factors_do_not_fit(monkeypatch) -> None:
    monkeypatch.setenv(backends.STORAGE_ENV, "auto")
    monkeypatch.setenv(backends.FAMILIES_ENV, "0")  # each its own analysis and decision
    k = laplacian(30, 3)  # factors of 39 MB in core, 12 MB permanent, 8 MB out of core
    rhs = np.ones(k.shape[0])
    monkeypatch.setattr(backends, "available_memory_bytes", lambda: 2.0**40)
    roomy = PardisoFactor(k, symmetric=True)
    monkeypatch.setattr(backends, "available_memory_bytes", lambda: 60e6)  # core: 28 MB
    tight = PardisoFactor(k, symmetric=True)
    assert not roomy.out_of_core and tight.out_of_core
    np.testing.assert_allclose(tight.solve(rhs), roomy.solve(rhs), rtol=1e-13, atol=0)


def test_single_precision_factors_measure_their_error() -> None:
    a = laplacian(12, 3)  # well conditioned: cond about 60
    rhs = np.random.default_rng(2).standard_normal((a.shape[0], 2))
    exact = np.linalg.solve(a.toarray(), rhs)  # dense, written separately
    single = PardisoFactor(a, symmetric=True, storage="single")
    assert 1e-9 < single.single_error < backends.SINGLE_MAX_ERROR
    error = np.abs(single.solve(rhs) - exact).max() / np.abs(exact).max()
    assert 1e-9 < error < 1e-4  # single precision, returned as double
    assert single.solve(rhs).dtype == np.float64


def test_single_precision_refuses_ill_conditioned_matrices() -> None:
    stiff = laplacian(4000, 1)  # cond about 6e6: a single-precision solve is off by ~1e-1
    with pytest.raises(NumericalError, match=r"single-precision factors .* too inaccurate"):
        PardisoFactor(stiff, symmetric=True, storage="single")


@pytest.mark.usefixtures("fresh")
@pytest.mark.parametrize("families", ["1", "0"])
def test_integer_overflow_retries_with_the_64_bit_interface(monkeypatch, families) -> None:
    """PARDISO's error -8 (factors beyond 2**31 entries) makes a new handle on ``pardiso_64``,
    which solves as the 32-bit one."""
    monkeypatch.setenv(backends.FAMILIES_ENV, families)
    original = backends._pardiso

    def overflowing(pt, maxfct, mnum, mtype, phase, data, indptr, indices, perm, iparm, *rest):
        if iparm.dtype == np.int32 and phase in (11, 12):
            raise backends._PardisoError("PARDISO failed with error -8 (overflow)", -8)
        return original(pt, maxfct, mnum, mtype, phase, data, indptr, indices, perm, iparm, *rest)

    k = laplacian(10, 3)
    a = sp.csr_matrix(k - 0.7 * sp.identity(k.shape[0]))
    rhs = np.ones(k.shape[0])
    expected = PardisoFactor(a, symmetric=True).solve(rhs)
    backends._FAMILIES.clear()
    monkeypatch.setattr(backends, "_pardiso", overflowing)
    factor = PardisoFactor(a, symmetric=True)
    assert factor.index64 and factor.nnz_factor > 0
    np.testing.assert_allclose(factor.solve(rhs), expected, rtol=1e-12, atol=0)
    second = PardisoFactor(sp.csr_matrix(k - 0.3 * sp.identity(k.shape[0])), symmetric=True)
    assert second.index64  # the family (or the ordering) of the pattern stays 64-bit


def test_storage_from_the_environment(monkeypatch: pytest.MonkeyPatch, tmp_path) -> None:
    monkeypatch.delenv(backends.STORAGE_ENV, raising=False)
    assert pardiso_storage() == "in-core"
    monkeypatch.setenv(backends.STORAGE_ENV, " Out-of-Core ")
    assert pardiso_storage() == "out-of-core"
    monkeypatch.setenv(backends.STORAGE_ENV, "single")  # for measurements only
    with pytest.raises(UserError, match="PYMOREMBS_PARDISO_STORAGE must be"):
        pardiso_storage()
    monkeypatch.setenv(backends.STORAGE_ENV, "out-of-core")
    monkeypatch.setenv(backends.OOC_DIR_ENV, str(tmp_path / "missing"))
    with pytest.raises(UserError, match="PYMOREMBS_PARDISO_OOC_DIR"):
        PardisoFactor(laplacian(5, 1), symmetric=True)
