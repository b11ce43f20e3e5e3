"""The compiled double-double sparse products against exact rational arithmetic."""

from __future__ import annotations

from fractions import Fraction

import numpy as np
import pytest
import scipy.sparse as sp

from pymorembs.linalg import double_double
from pymorembs.linalg.factorization import Factorization
from pymorembs.linalg.products import extended_product, long_product, multiply

needs_numba = pytest.mark.skipif(not double_double.available(), reason="Numba not installed")


def _exact_product(matrix: sp.csr_matrix, block: np.ndarray) -> list[list[Fraction]]:
    """``matrix @ block`` in exact rational arithmetic (every double is a fraction)."""
    rows = []
    for i in range(matrix.shape[0]):
        start, stop = matrix.indptr[i], matrix.indptr[i + 1]
        row = []
        for j in range(block.shape[1]):
            total = Fraction(0)
            for q in range(start, stop):
                column = int(matrix.indices[q])
                total += Fraction(float(matrix.data[q])) * Fraction(float(block[column, j]))
            row.append(total)
        rows.append(row)
    return rows


def _cancelling_case(seed: int, n: int = 40, k: int = 3) -> tuple[sp.csr_matrix, np.ndarray]:
    """A matrix with entries over 12 decades whose rows nearly cancel on the first column of
    the block: each diagonal entry is set to ``-sum_j a_ij x_j / x_i`` (rounded), so the exact
    products there are ~1e-16 of their largest term, where double precision keeps no digit."""
    rng = np.random.default_rng(seed)
    dense = rng.standard_normal((n, n)) * 10.0 ** rng.uniform(-6, 6, (n, n))
    dense[rng.random((n, n)) < 0.7] = 0.0
    block = rng.standard_normal((n, k))
    np.fill_diagonal(dense, 0.0)
    dense[np.arange(n), np.arange(n)] = -(dense @ block[:, 0]) / block[:, 0]
    return sp.csr_matrix(dense), block


@needs_numba
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_product_is_the_exact_product_rounded(seed: int) -> None:
    matrix, block = _cancelling_case(seed)
    hi, lo = double_double.product(matrix, block)
    exact = _exact_product(matrix, block)
    u = Fraction(1, 2**53)
    for i in range(matrix.shape[0]):
        start, stop = matrix.indptr[i], matrix.indptr[i + 1]
        gamma = (stop - start) * u / (1 - (stop - start) * u)
        for j in range(block.shape[1]):
            value = exact[i][j]
            terms = sum(
                abs(Fraction(float(matrix.data[q])) * Fraction(float(block[matrix.indices[q], j])))
                for q in range(start, stop)
            )
            # the bound of a dot product summed in twice the working precision (Ogita, Rump &
            # Oishi 2005, Dot2): hi is the exact value rounded, up to gamma^2 of the terms
            floor = 2 * gamma**2 * terms
            assert abs(Fraction(float(hi[i, j])) - value) <= u * abs(value) + floor
            assert abs(Fraction(float(hi[i, j])) + Fraction(float(lo[i, j])) - value) <= floor
    plain = matrix @ block  # double precision keeps no digit in the first column
    assert np.median(np.abs(plain[:, 0] - hi[:, 0]) / np.abs(hi[:, 0])) > 1e-3


@needs_numba
def test_serial_and_parallel_kernels_agree_bit_for_bit(monkeypatch) -> None:
    matrix, block = _cancelling_case(5, n=300, k=4)
    parallel = double_double.product(matrix, block)
    plain = double_double.multiply(matrix, block)
    monkeypatch.setattr(double_double, "_parallel", lambda: False)
    serial = double_double.product(matrix, block)
    assert np.array_equal(parallel[0], serial[0]) and np.array_equal(parallel[1], serial[1])
    assert np.array_equal(double_double.multiply(matrix, block), plain)


@needs_numba
def test_multiply_is_scipys_double_product() -> None:
    """Same terms in the same order as SciPy's CSR product: the same doubles (vectors, blocks,
    complex blocks through :func:`~pymorembs.linalg.products.multiply`)."""
    matrix, block = _cancelling_case(6, n=200, k=5)
    assert np.array_equal(double_double.multiply(matrix, block), matrix @ block)
    assert np.array_equal(double_double.multiply(matrix, block[:, 2]), matrix @ block[:, 2])
    z = block[:, 0] - 2j * block[:, 1]
    assert np.array_equal(multiply(matrix, z), matrix @ z)
    assert np.array_equal(multiply(matrix.toarray(), block), matrix.toarray() @ block)


@needs_numba
def test_residual_with_complex_coefficients_matches_longdouble(monkeypatch) -> None:
    """``rhs - (K - w^2 M + i w D) x`` at a near-solution: double-double and longdouble give
    the same residual to the longdouble rounding, both far from the double-precision one."""
    rng = np.random.default_rng(7)
    n = 200
    k = sp.random(n, n, density=0.05, random_state=3, format="csr")
    k = k + k.T + sp.eye(n) * 50.0
    m = sp.diags(1.0 + rng.random(n), format="csr")
    d = 1e-3 * k
    terms = [(1.0, k), (-(30.0**2) * 1e-2, m), (1j * 30.0, d)]
    rhs = rng.standard_normal((n, 2)) + 1j * rng.standard_normal((n, 2))
    factorization = Factorization(terms, check=False)
    x = factorization.solve(rhs)
    double = factorization._residual(rhs, x)
    monkeypatch.setenv(double_double.EXTENDED_ENV, "longdouble")
    assert not double_double.available()
    wide = factorization._residual(rhs, x)
    scale = np.max(np.abs(rhs))
    assert np.max(np.abs(double - wide)) <= 1e-18 * scale
    combined = factorization.matrix @ x
    assert np.max(np.abs((rhs - combined) - wide)) > 1e-3 * np.max(np.abs(wide))


@needs_numba
def test_extended_product_uses_the_kernel_for_complex_blocks() -> None:
    matrix, block = _cancelling_case(3)
    z = block + 1j * block[::-1]
    product = extended_product(matrix, z)
    assert np.array_equal(product.real, double_double.product(matrix, block)[0])
    assert np.array_equal(product.imag, double_double.product(matrix, block[::-1])[0])


def test_longdouble_switch_is_honoured(monkeypatch) -> None:
    monkeypatch.setenv(double_double.EXTENDED_ENV, "longdouble")
    assert not double_double.available()
    matrix, block = _cancelling_case(4)
    exact = _exact_product(matrix, block)
    product = extended_product(matrix, block)  # the longdouble path, rounded to double
    errors = [
        float(abs(Fraction(float(product[i, 0])) - exact[i][0]) / abs(exact[i][0]))
        for i in range(matrix.shape[0])
    ]
    plain = (matrix @ block)[:, 0]
    double_errors = np.abs(plain - product[:, 0]) / np.abs(product[:, 0])
    # a 64-bit mantissa keeps about 3 decimal digits of rows that cancel to 1e-16; double none
    assert np.median(errors) < 1e-2 < np.median(double_errors)


def test_plain_moments_give_the_accuracy_of_refined_ones(monkeypatch) -> None:
    """Large models build Krylov bases from unrefined solves (``BASIS_PLAIN_ENOUGH``); forced on
    rack-beams, the model's error against the full model (eq. 27, 0-1000 Hz) stays that of the
    refined basis, while the solves skip their extended residuals."""
    from pymorembs.analysis.error import relative_error
    from pymorembs.analysis.transfer import transfer_function
    from pymorembs.examples import build_example
    from pymorembs.linalg import factorization
    from pymorembs.preparation import Frame, Port, prepare
    from pymorembs.reduction.krylov import krylov_reduction
    from pymorembs.reduction.projection import reduced_model

    ports = [Port.parse(1, "ux uy uz")]
    system = prepare(build_example("rack-beams"), Frame("tangent", 2), ports, ports).system
    grid = np.concatenate([[0.0], np.geomspace(1.0, 1000.0, 60)])
    full = transfer_function(system, grid)
    residuals = []
    original = factorization.Factorization._residual

    def counting(self, rhs, x):
        residuals.append(1)
        return original(self, rhs, x)

    monkeypatch.setattr(factorization.Factorization, "_residual", counting)
    errors = {}
    for order in (system.order + 1, 0):  # refined (small model), then plain moments
        monkeypatch.setattr(factorization, "BASIS_PLAIN_MIN_ORDER", order)
        residuals.clear()
        projection = krylov_reduction(system, [0.0, 500.0, 1000.0], [6, 5, 5])
        model = reduced_model(system, projection)
        errors[order] = relative_error(full, transfer_function(model.system, grid)).max()
        if order == 0:
            assert len(residuals) == 3  # one refined solve per expansion point
        else:
            assert len(residuals) >= 16  # every moment refined
    refined, plain = errors[system.order + 1], errors[0]
    # Both sit at the floor of the comparison (about 1e-9); where they land within it depends on
    # the BLAS kernels (AVX2: within 5 % of each other; AVX-512: 8.2e-10 and 1.3e-9).
    assert refined < 2e-9 and plain < 2e-9
    assert plain <= 2.0 * refined


@pytest.mark.parametrize("kernel", ["double-double", "longdouble"])
def test_long_product_keeps_the_extended_digits(kernel: str, monkeypatch) -> None:
    """The mass invariants' products: on rows that cancel to 1e-16 of their terms the
    ``longdouble`` result holds the digits a 64-bit mantissa can (the double-double kernel's
    ``hi + lo`` rounded to it, or SciPy's ``longdouble`` product without Numba)."""
    if kernel == "longdouble":
        monkeypatch.setenv(double_double.EXTENDED_ENV, "longdouble")
    elif not double_double.available():
        pytest.skip("Numba not installed")
    matrix, block = _cancelling_case(5)
    exact = _exact_product(matrix, block)
    product = long_product(matrix, block)
    assert product.dtype == np.longdouble and product.shape == block.shape

    def fraction(value: np.longdouble) -> Fraction:  # exact: 64 bits fit into two doubles
        hi = float(value)
        return Fraction(hi) + Fraction(float(value - np.longdouble(hi)))

    errors = [
        abs(fraction(product[i, 0]) - exact[i][0]) / abs(exact[i][0])
        for i in range(matrix.shape[0])
    ]
    # 64 bits keep about 3 digits of a row that cancels to 1e-16 (double: none); the
    # double-double kernel loses nothing before the rounding to longdouble
    assert float(np.median(errors)) < (1e-2 if kernel == "longdouble" else 1e-12)


@needs_numba
def test_compiled_subtract_scaled_is_the_elementwise_formula_bit_for_bit() -> None:
    """The residual's accumulation step, ``(hi + lo) - s (p_hi + p_lo)``, against Dekker's
    two-product and Knuth's two-sum written here with NumPy, on column slices as the residual
    passes them."""
    from pymorembs.linalg import compiled_kernels

    split = 134217729.0  # 2^27 + 1

    def two_product(a, b):
        p = a * b
        t = split * a
        a_hi = t - (t - a)
        t = split * b
        b_hi = t - (t - b)
        return p, ((a_hi * b_hi - p) + a_hi * (b - b_hi) + (a - a_hi) * b_hi) + (a - a_hi) * (
            b - b_hi
        )

    rng = np.random.default_rng(7)
    block_hi = rng.standard_normal((500, 8)) * 10.0 ** rng.uniform(-8, 8, (500, 8))
    block_lo = block_hi * 1e-17 * rng.standard_normal((500, 8))
    hi = rng.standard_normal((500, 4)) * 1e3
    lo = hi * 1e-17 * rng.standard_normal((500, 4))
    for scale in (2.5, -1e-7, 3.0e11):
        p_hi, p_lo = block_hi[:, 4:], block_lo[:, 4:]  # a strided half, as for imaginary parts
        product, error = two_product(-scale, p_hi)
        error = error - scale * p_lo
        total = hi + product
        virtual = total - hi
        carry = (hi - (total - virtual)) + (product - virtual) + lo + error
        expected_hi = total + carry
        expected_lo = carry - (expected_hi - total)
        compiled_kernels.subtract_scaled(hi, lo, scale, p_hi, p_lo)
        np.testing.assert_array_equal(hi, expected_hi)
        np.testing.assert_array_equal(lo, expected_lo)
