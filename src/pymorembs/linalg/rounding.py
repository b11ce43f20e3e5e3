"""How precisely a file stores its matrices, and what that rounding does to eigenvalues.

FE programs export matrices with a fixed number of significant digits: a Nastran DMIG punch in
large field holds 10 (``3.309464213D+06``), small field 5 or 6, single-precision binary OP4
about 7, Abaqus and most other text exports 14 to 17. Rounding an entry ``K_ij`` changes it by at
most ``eps |K_ij|`` with ``eps = 0.5 * 10^(1 - digits)``, and, to first order, an eigenvalue
``lambda`` with the mass-normalised eigenvector ``x`` by at most

    |d lambda| <= eps (|x|^T |K| |x| + |lambda| |x|^T |M| |x|),

which is large where big entries cancel: the rigid-body modes of a model with stiff elements
come out at a few tenths of a hertz, and low elastic modes move by a fraction of a percent
(a free aircraft from a 10-digit punch: its first wing mode by 0.3 %). :func:`eigenvalue_bounds`
gives this bound per mode; it decides which computed modes are rigid-body modes
(:mod:`pymorembs.analysis.spectrum`) and says how far published frequencies may lie from those of
the exported matrices.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

#: Rounding of values stored as binary doubles, and the floor for the computation itself:
#: factorizations and Lanczos add errors of a few units of 1e-16 relative to the entries.
COMPUTATION_EPS = 1e-14
#: Exports with fewer digits than this hold exact round numbers (hand-made or test models),
#: not values rounded to that many digits.
MIN_ROUNDED_DIGITS = 5
#: Largest digit count told apart from a full double (the test below is exact up to here).
MAX_DIGITS = 14
_SAMPLE = 20_000


def significant_digits(*arrays: np.ndarray) -> int | None:
    """The number of significant decimal digits the values were rounded to, or None.

    None means the values are full binary doubles (more than :data:`MAX_DIGITS` digits, as
    written by binary formats and by text writers that print 15 to 17 digits) or exact numbers
    with fewer than :data:`MIN_ROUNDED_DIGITS` digits. A sample of at most 20,000 non-zero
    values is tested: the smallest ``d`` for which every sampled value, scaled by
    ``10^(d - 1 - floor(log10 |v|))``, is an integer.
    """
    values = _sample(arrays)
    values = np.abs(values[np.isfinite(values) & (values != 0.0)])
    if values.size == 0:
        return None
    exponent = np.floor(np.log10(values))
    for digits in range(1, MAX_DIGITS + 1):
        scaled = values * 10.0 ** (digits - 1 - exponent)
        if np.all(np.abs(scaled - np.rint(scaled)) <= 1e-6 + 8e-16 * scaled):
            return digits if digits >= MIN_ROUNDED_DIGITS else None
    return None


def relative_rounding(
    stiffness: sp.spmatrix, mass: sp.spmatrix, precision: float | None = None
) -> tuple[float, str]:
    """``eps`` of the stored entries of ``K`` and ``M`` and a phrase describing it.

    ``precision`` given (the reader knew it, :attr:`pymorembs.body.ElasticBody.precision`): that.
    Otherwise from the values: decimal text rounded to ``d`` digits: ``0.5 * 10^(1 - d)``;
    values that are exactly single precision: ``2^-24``; otherwise :data:`COMPUTATION_EPS` (the
    rounding of the computation dominates).
    """
    if precision is not None:
        if precision == 2.0**-24:
            text = "single precision"
        else:
            digits = 1.0 - np.log10(2.0 * precision)
            text = (
                f"{round(digits)} significant digits"
                if abs(digits - round(digits)) < 1e-9
                else f"relative rounding {precision:.1e}"
            )
        return max(float(precision), COMPUTATION_EPS), f"{text} (as the file stores them)"
    k = sp.csr_matrix(stiffness).data
    m = sp.csr_matrix(mass).data
    digits = significant_digits(k, m)
    if digits is not None:
        return max(0.5 * 10.0 ** (1 - digits), COMPUTATION_EPS), f"{digits} significant digits"
    both = _sample((k, m))
    if both.size and np.array_equal(both.astype(np.float32).astype(float), both):
        return 2.0**-24, "single precision"
    return COMPUTATION_EPS, "full double precision"


def _sample(arrays: tuple[np.ndarray, ...]) -> np.ndarray:
    """At most :data:`_SAMPLE` values of each array (evenly strided), without copying them all."""
    parts = []
    for a in arrays:
        flat = np.asarray(a).ravel()
        step = flat.size // _SAMPLE + 1
        parts.append(np.asarray(flat[::step], dtype=float))
    return np.concatenate(parts) if parts else np.zeros(0)


def eigenvalue_bounds(
    stiffness: sp.spmatrix | np.ndarray,
    mass: sp.spmatrix | np.ndarray,
    eigenvalues: np.ndarray,
    modes: np.ndarray,
    eps: float,
) -> np.ndarray:
    """First-order bound of the change of each eigenvalue by rounding the entries, shape (k,).

    Parameters
    ----------
    stiffness, mass : sparse matrix or ndarray, shape (n, n)
    eigenvalues : ndarray, shape (k,)
        ``omega^2`` in (rad/s)^2.
    modes : ndarray, shape (n, k)
        Mass-normalised eigenvectors.
    eps : float
        Relative rounding of the entries (:func:`relative_rounding`).

    Returns
    -------
    ndarray, shape (k,)
        ``eps (|x|^T |K| |x| + |lambda| |x|^T |M| |x|)`` in (rad/s)^2 (module docstring).
    """
    x = np.abs(np.asarray(modes, dtype=float))
    k_abs = abs(stiffness) if sp.issparse(stiffness) else np.abs(stiffness)
    m_abs = abs(mass) if sp.issparse(mass) else np.abs(mass)
    kx = np.einsum("ij,ij->j", x, k_abs @ x)
    mx = np.einsum("ij,ij->j", x, m_abs @ x)
    return eps * (kx + np.abs(eigenvalues) * mx)
