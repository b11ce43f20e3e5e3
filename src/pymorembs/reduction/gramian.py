"""Reduction with frequency-weighted Gramian matrices (paper section 3.2).

Gramians
--------
The second-order system ``M q'' + D q' + K q = B u, y = C q`` in the first-order form of paper
eq. 5, ``x = [q; q']``,

    A = [[0, I], [-M^-1 K, -M^-1 D]],  B_1 = [0; M^-1 B],  C_1 = [C, 0],

has, when it is asymptotically stable, the controllability Gramian ``P``, the solution of the
Lyapunov equation ``A P + P A^T + B_1 B_1^T = 0``, which is also the frequency integral

    P = 1/(2 pi) int_{-inf}^{inf} (i w I - A)^-1 B_1 B_1^T (i w I - A)^-H dw.

The frequency-weighted Gramian of a band ``w_1 <= |w| <= w_2`` (rad/s) keeps the part of the
integral over the band, ``P_w = P(w_2) - P(w_1)`` with ``P(w)`` the integral over ``[-w, w]``.
It follows from ``P`` and a matrix logarithm (Gawronski and Juang, "Model reduction in limited
time and frequency intervals", Int. J. Systems Sci. 21, 1990; Antoulas, "Approximation of
Large-Scale Dynamical Systems", SIAM 2005 -- the paper's ref. [19]):

    P(w) = S(w) P + P S(w)^H,   S(w) = i/(2 pi) logm((A + i w I)(A - i w I)^-1),

with ``S(0) = 0`` and ``S(w) -> I/2`` for ``w -> inf`` (the principal logarithm; ``A`` stable).
Proof in one line: ``B_1 B_1^T = (i w I - A) P + P (i w I - A)^H`` by the Lyapunov equation, so
the integrand is ``(i w I - A)^-1 P + P (i w I - A)^-H``, and
``1/(2 pi) int_{-w}^{w} (i v I - A)^-1 dv = S(w)``. All of these are real for real ``A``.

The position controllability Gramian is the upper left block ``P_p = [I 0] P [I 0]^T``. Since
the upper right block of ``(s I - A)^-1`` is ``R(s) M`` with ``R(s) = (s^2 M + s D + K)^-1``,

    P_p^w = 1/(2 pi) int_band R(i w) B B^T R(i w)^H dw,

and the band-limited H2 norm of the system is ``||H W||^2 = trace(C P_p^w C^T)``. The Gramian
``Q_pv = M^-T Q_v M^-1`` of the paper (``Q_v`` the lower right block of the observability
Gramian) is the position controllability Gramian of the dual system with input ``C^T``; for
symmetric ``M``, ``D``, ``K`` that is the same system with input ``C^T``:

    Q_pv^w = 1/(2 pi) int_band R(i w)^H C^T C R(i w) dw.

For ``C = B^T`` the two are equal.

Computation
-----------
The dense system is first transformed to its mass-normalised undamped eigenmodes ``Phi``
(``Phi^T M Phi = I``, ``Phi^T K Phi = Omega^2``); then ``P_p = Phi P_eta Phi^T`` with
``P_eta`` the position Gramian of the modal system ``(I, Phi^T D Phi, Omega^2, Phi^T B)``.
Modal coordinates need no ``M^-1``, keep everything symmetric, and separate the rigid-body modes
of a free body (they are neither excited nor observed -- the Buckens frame -- and would make the
system unstable; they are dropped). The first-order form used is the balanced one,
``x = [Omega eta; eta']``, ``A = [[0, Omega], [-Omega, -D_eta]]`` -- the same system as eq. 5
in other state coordinates, but with entries of size ``omega`` instead of ``omega^2``.

* Modal damping matrix ``D_eta`` diagonal (Rayleigh damping, a modal damping ratio): ``A`` is
  diagonalised in closed form, mode by mode (eigenvalues ``lambda = -d/2 +- sqrt(d^2/4 -
  omega^2)``), and the matrix functions above become scalar functions of the eigenvalues:
  ``P_eta = (B_eta B_eta^T) o W`` (Hadamard product) with
  ``W_rs = sum_{a, b} c_ra conj(c_sb) (F_ra + conj F_sb) / -(lambda_ra + conj lambda_sb)``,
  ``c_r+- = +-1 / (lambda_r+ - lambda_r-)`` the residues of ``1 / (s^2 + d_r s + omega_r^2)``
  and ``F = f(w_2) - f(w_1)``, ``f(w) = i/(2 pi) Log((lambda + i w) / (lambda - i w))`` -- the
  eigenvalues of ``S(w)``. Cost O(n^2) after the eigenproblem.
* Otherwise (a general damping matrix, or a critically damped mode): the Lyapunov equation is
  solved by :func:`scipy.linalg.solve_continuous_lyapunov` and ``S(w)`` by
  :func:`scipy.linalg.logm`, O(n^3) on the 2n-dimensional state.

A damping model is needed (an undamped system has no Gramian): the viscous damping ``D`` plus,
for a modal damping ratio ``xi``, ``M Phi diag(2 xi omega) Phi^T M`` -- the viscous modal damping
that :attr:`~pymorembs.reduction.projection.ReducedModel.damping_matrix` gives a reduced model. A
loss factor ``eta`` alone counts as ``xi = eta / 2``.

Reduction and error bound
-------------------------
The projection ``V = W`` spans the dominant eigenvectors of ``P_p^w + Q_pv^w`` (eigenvalues
``sigma_1 >= sigma_2 >= ...``, the ``sigma_i^PQ`` of the paper). Paper eq. 24 bounds the
band-limited H2 error by the neglected eigenvalues,

    ||(H - H_bar) W||_H2^2 <= 1/(2 pi) max(kappa, kappa_T) sum_{j > n} sigma_j^PQ,

with constants ``kappa``, ``kappa_T`` the paper does not define (it refers to its refs. [17, 32],
a dissertation and a paper not available here).
Here the Gramians carry the factor ``1/(2 pi)`` of the H2 norm, so the ``1/(2 pi)`` of eq. 24 is
already in ``sigma_j``, and the constants are derived as follows. With
``Z(s) = s^2 M + s D + K``, ``R_bar(s) = (V^T Z V)^-1`` and ``V_perp`` an orthonormal complement
of the orthonormal ``V``, the error is

    H - H_bar = C Pi(s) V_perp V_perp^T R(s) B = C R(s) V_perp V_perp^T Pi_T(s) B,
    Pi(s) = I - V R_bar V^T Z,  Pi_T(s) = I - Z V R_bar V^T

(``Pi`` is an oblique projector with ``Pi V = 0``), so with
``kappa = sup_band ||C Pi(i w)||_2^2`` and ``kappa_T = sup_band ||Pi_T(i w) B||_2^2``

    ||(H - H_bar) W||^2 <= min(kappa tr(V_perp^T P_p^w V_perp), kappa_T tr(V_perp^T Q_pv^w V_perp))
                        <= max(kappa, kappa_T) sum_{j > n} sigma_j.

:func:`gramian_reduction` stores the a-priori part ``sqrt(sum_{j > n} sigma_j)`` (eq. 24 with
``kappa = kappa_T = 1``) and the a-posteriori bound with ``kappa``, ``kappa_T`` evaluated on a
frequency grid over the band (a sampled supremum -- see :func:`gramian_reduction`). All of it
concerns the viscous model the Gramians use: a modal damping ratio enters the frequency
responses of pymorembs as a loss factor instead, which differs away from the resonances.

Large models
------------
Two ways avoid the O(n^3) Gramians of a large model: the two-step approach (paper ref. [9]) --
the Gramians of a medium-sized model from a first (Krylov, modal) reduction stand in for those of
the full model -- and a POD of frequency-domain snapshots (paper ref. [17]), which approximates
the Gramian integral by quadrature, :func:`pod_reduction`. Both lose the strict bound.

Frequencies are in Hz at the interface, ``w = 2 pi f`` in rad/s inside.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp

from pymorembs.errors import NumericalError, UserError
from pymorembs.linalg.factorization import Factorization
from pymorembs.linalg.inertia_relief import InertiaRelief
from pymorembs.linalg.mass_split import condensed_dense_eigh, mass_split
from pymorembs.linalg.orthogonalization import OrthonormalBasis
from pymorembs.linalg.products import extended_product
from pymorembs.methods import GramianOptions, PodOptions
from pymorembs.reduction.krylov import moment_matching
from pymorembs.reduction.projection import Projection, ReducedModel, reduced_model
from pymorembs.reduction.soaga import adaptive_arnoldi, candidate_points
from pymorembs.system import SecondOrderSystem

#: Largest number of dofs for which dense Gramians of the full model are computed.
MAX_DENSE_ORDER = 2000
#: Eigenvalues ``omega^2`` below this times the largest count as rigid-body modes.
RIGID_TOL = 1e-10
#: Modes with ``|d^2/4 - omega^2|^(1/2) < CRITICAL_TOL * omega`` are (nearly) critically damped:
#: their closed-form eigenvectors are ill-conditioned, the general (logm) path is used.
CRITICAL_TOL = 1e-3
#: What an undamped body needs for its Gramians: the damping of a job or of the Python API.
DAMPING_REMEDY = (
    'give the body damping: [damping] kind = "modal" with ratio (or "rayleigh" with alpha, '
    'beta) in a job, damping=pymorembs.Damping("modal", ratio=0.02) in pymorembs.prepare'
)

#: A modal damping matrix whose off-diagonal entries are below this times its largest diagonal
#: entry is diagonal: the rounding of ``Phi^T D Phi`` for Rayleigh damping (~1e-12 at 600 dofs).
DIAGONAL_TOL = 1e-10
#: Frequencies of the grid on which kappa and kappa_T are sampled.
KAPPA_POINTS = 400


# --------------------------------------------------------------------------------------------
# band and damping


def band_in_rad_s(band_hz: Sequence[float], allow_infinite: bool) -> tuple[float, float]:
    """``(w_1, w_2)`` in rad/s from ``(f_min, f_max)`` in Hz, checked."""
    try:
        f_min, f_max = (float(f) for f in band_hz)
    except (TypeError, ValueError):
        raise UserError(
            f"band must be two frequencies (f_min, f_max) in Hz, got {band_hz!r}"
        ) from None
    if not (np.isfinite(f_min) and 0.0 <= f_min < f_max) or np.isnan(f_max):
        raise UserError(f"band must satisfy 0 <= f_min < f_max (Hz), got [{f_min}, {f_max}]")
    if not np.isfinite(f_max) and not allow_infinite:
        raise UserError(f"band must end at a finite frequency (Hz), got [{f_min}, {f_max}]")
    return 2.0 * np.pi * f_min, 2.0 * np.pi * f_max


def _dense(matrix: sp.spmatrix | np.ndarray | None) -> np.ndarray | None:
    if matrix is None:
        return None
    return matrix.toarray() if sp.issparse(matrix) else np.asarray(matrix, dtype=float)


@dataclass(frozen=True)
class ModalForm:
    """The elastic part of a dense system in mass-normalised undamped eigenmodes.

    ``modes`` (n, m) with ``modes^T M modes = I``, ``omega`` (m,) rad/s > 0, ``damping`` (m, m)
    the modal viscous damping, ``inputs`` (m, p) = ``modes^T B``, ``outputs_t`` (m, r) =
    ``modes^T C^T``.
    """

    modes: np.ndarray
    omega: np.ndarray
    damping: np.ndarray
    inputs: np.ndarray
    outputs_t: np.ndarray


def _eigenmodes(
    k: np.ndarray, m: np.ndarray, rigid_modes: np.ndarray | None
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``omega^2`` (ascending), mass-normalised modes and a mask of the rigid-body modes.

    Positive definite ``K``: the flexibility form ``M y = mu K y`` (``omega^2 = 1 / mu``), whose
    low eigenvalues are accurate to working precision however stiff the model (as in
    :func:`~pymorembs.reduction.projection.reduced_model`). A free body (``rigid_modes`` given): its
    lowest ``r`` modes are the rigid ones. Otherwise eigenvalues below :data:`RIGID_TOL` times the
    largest count as rigid. Massless directions of ``M`` (infinite eigenvalues) have no mode:
    they are condensed statically (:mod:`pymorembs.linalg.mass_split`).
    """
    split = mass_split(m)  # massless directions (infinite eigenvalues) are left out
    if rigid_modes is None:
        try:
            mu, y = sla.eigh(m, k)
        except np.linalg.LinAlgError:
            mu = None
        if mu is not None:
            mu, y = mu[mu.size - split.rank :], y[:, mu.size - split.rank :]
        if mu is not None and mu.min() > 0:
            values = 1.0 / mu[::-1]
            return values, y[:, ::-1] * np.sqrt(values), np.zeros(values.size, dtype=bool)
    try:
        values, modes = condensed_dense_eigh(k, m, split)
    except (np.linalg.LinAlgError, NumericalError) as exc:
        raise NumericalError(f"gramian: eigenproblem of (K, M) failed ({exc})") from None
    if rigid_modes is not None:
        rigid = np.arange(values.size) < rigid_modes.shape[1]
    else:
        scale = max(float(np.abs(values).max(initial=0.0)), np.finfo(float).tiny)
        rigid = values <= RIGID_TOL * scale
    return values, modes, rigid


def _modal_form(system: SecondOrderSystem, damping_ratio: float | None) -> ModalForm:
    """Eigenmodes of a dense (or small sparse) system and its damping model; checks stability."""
    if system.order > MAX_DENSE_ORDER:
        raise UserError(
            f"gramian: the model has {system.order} dofs, more than the {MAX_DENSE_ORDER} for "
            "dense Gramians; use the two-step approach (a medium model) or the POD"
        )
    m, k, d = _dense(system.mass), _dense(system.stiffness), _dense(system.damping)
    m, k = 0.5 * (m + m.T), 0.5 * (k + k.T)
    values, modes, rigid = _eigenmodes(k, m, system.rigid_modes)
    b, c_t = system.input_matrix, system.output_matrix.T
    inputs, outputs_t = modes.T @ b, modes.T @ c_t
    if np.any(rigid):
        # rigid-body modes: the system is not asymptotically stable unless they are neither
        # excited nor observed (free body in the Buckens frame); then they are dropped
        for label, part in (("inputs", inputs), ("outputs", outputs_t)):
            total = np.linalg.norm(part)
            if total > 0 and np.linalg.norm(part[rigid]) > 1e-8 * total:
                raise UserError(
                    f"gramian: the {label} act on {int(rigid.sum())} rigid-body mode(s) "
                    "(zero eigenfrequency): the system is not asymptotically stable and has no "
                    "Gramian; use a frame that fixes the rigid-body motion"
                )
    keep = ~rigid
    if not np.any(keep):
        raise UserError("gramian: the model has no elastic modes")
    modes, omega = modes[:, keep], np.sqrt(values[keep])
    inputs, outputs_t = inputs[keep], outputs_t[keep]
    n_modes = omega.size
    damping = np.zeros((n_modes, n_modes)) if d is None else modes.T @ d @ modes
    damping = 0.5 * (damping + damping.T)
    ratio = system.modal_damping_ratio or 0.5 * system.loss_factor
    if not ratio and d is None:
        if damping_ratio is None:
            raise UserError(
                f"gramian: the system is undamped, so it has no Gramian; {DAMPING_REMEDY}"
            )
        ratio = float(damping_ratio)
    if ratio:
        damping = damping + np.diag(2.0 * ratio * omega)
    weak = np.diag(damping) <= 1e-12 * omega
    if np.any(weak):
        raise UserError(
            f"gramian: {int(weak.sum())} mode(s) are undamped (lowest at "
            f"{omega[weak].min() / (2 * np.pi):.4g} Hz): the system is not asymptotically "
            f"stable and has no Gramian; {DAMPING_REMEDY}"
        )
    return ModalForm(modes, omega, damping, inputs, outputs_t)


# --------------------------------------------------------------------------------------------
# Gramians


def _log_weight(lam: np.ndarray, w: float) -> np.ndarray:
    """Eigenvalues ``i/(2 pi) Log((lambda + i w) / (lambda - i w))`` of ``S(w)``."""
    if w == 0.0:
        return np.zeros_like(lam)
    if not np.isfinite(w):
        return np.full_like(lam, 0.5)
    # (lambda + i w) / (lambda - i w) = 1 + 2 i w / (lambda - i w): log1p keeps the digits of
    # modes far above the band, where the ratio is close to 1
    return 1j / (2.0 * np.pi) * np.log1p(2j * w / (lam - 1j * w))


def _weight_matrix(omega: np.ndarray, d: np.ndarray, w1: float, w2: float) -> np.ndarray | None:
    """``W`` with ``P_eta = (B_eta B_eta^T) o W`` for diagonal modal damping ``d``.

    None if a mode is (nearly) critically damped.
    """
    disc = np.sqrt((0.25 * d * d - omega * omega).astype(complex))
    if np.any(np.abs(disc) < CRITICAL_TOL * omega):
        return None
    lam_minus = -0.5 * d - disc
    # overdamped modes (real disc): the small root from the product omega^2, not by cancellation
    lam_plus = np.where(disc.imag == 0.0, omega * omega / lam_minus, -0.5 * d + disc)
    lam = np.stack([lam_plus, lam_minus], axis=1)  # (m, 2)
    residue = 1.0 / (2.0 * disc)
    c = np.stack([residue, -residue], axis=1)
    f = _log_weight(lam, w2) - _log_weight(lam, w1)
    w = np.zeros((omega.size, omega.size), dtype=complex)
    for a in (0, 1):
        for b in (0, 1):
            denominator = lam[:, a, None] + np.conj(lam[None, :, b])
            numerator = f[:, a, None] + np.conj(f[None, :, b])
            w -= c[:, a, None] * np.conj(c[None, :, b]) * numerator / denominator
    return w.real


def _matrix_log_weight(a: np.ndarray, w: float) -> np.ndarray:
    """``S(w) = i/(2 pi) logm((A + i w I)(A - i w I)^-1)``, real."""
    n = a.shape[0]
    if w == 0.0:
        return np.zeros((n, n))
    if not np.isfinite(w):
        return 0.5 * np.eye(n)
    identity = np.eye(n)
    ratio = np.linalg.solve(a - 1j * w * identity, a + 1j * w * identity)  # factors commute
    return (1j / (2.0 * np.pi) * sla.logm(ratio)).real


def _modal_gramians(
    modal: ModalForm, w1: float, w2: float, inputs: Sequence[np.ndarray]
) -> list[np.ndarray]:
    """Position Gramians ``P_eta`` of the modal system over the band, one per input matrix."""
    omega, damping = modal.omega, modal.damping
    diagonal = np.diag(damping)
    off = damping - np.diag(diagonal)
    weights = None
    if np.abs(off).max(initial=0.0) <= DIAGONAL_TOL * np.abs(diagonal).max(initial=0.0):
        weights = _weight_matrix(omega, diagonal, w1, w2)
    if weights is not None:
        gramians = [(b @ b.T) * weights for b in inputs]
    else:
        gramians = _general_gramians(omega, damping, w1, w2, inputs)
    return [0.5 * (g + g.T) for g in gramians]


def _general_gramians(
    omega: np.ndarray, damping: np.ndarray, w1: float, w2: float, inputs: Sequence[np.ndarray]
) -> list[np.ndarray]:
    """Lyapunov equation and matrix logarithm on ``A = [[0, Omega], [-Omega, -D_eta]]``."""
    m = omega.size
    a = np.block([[np.zeros((m, m)), np.diag(omega)], [-np.diag(omega), -damping]])
    weight = _matrix_log_weight(a, w2) - _matrix_log_weight(a, w1)
    gramians = []
    for b in inputs:
        b1 = np.vstack([np.zeros_like(b), b])
        p = sla.solve_continuous_lyapunov(a, -(b1 @ b1.T))
        p_band = weight @ p + p @ weight.T
        gramians.append(p_band[:m, :m] / np.outer(omega, omega))
    return gramians


def frequency_weighted_gramians(
    system: SecondOrderSystem,
    band_hz: Sequence[float],
    damping_ratio: float | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Frequency-weighted position Gramians ``P_p^w`` and ``Q_pv^w`` (paper section 3.2).

    Parameters
    ----------
    system : SecondOrderSystem
        A dense system (a reduced model), or a sparse one with at most
        :data:`MAX_DENSE_ORDER` dofs; symmetric ``M``, ``D``, ``K``. Damping: the viscous ``D``
        plus the viscous modal damping of a modal damping ratio (or of ``loss_factor / 2``).
    band_hz : (float, float)
        ``(f_min, f_max)`` in Hz, ``0 <= f_min < f_max``; ``f_max = inf`` gives the ordinary
        (unweighted) Gramians. The band is ``2 pi f_min <= |w| <= 2 pi f_max`` (rad/s), both
        signs of the frequency, as in the H2 norm.
    damping_ratio : float, optional
        Modal damping ratio used only when the system has no damping at all.

    Returns
    -------
    P_p : ndarray, shape (n, n)
        ``1/(2 pi) int_band R(i w) B B^T R(i w)^H dw`` with ``R(s) = (s^2 M + s D + K)^-1``: the
        upper left block of the frequency-weighted controllability Gramian of eq. 5. Units of
        ``(q / u)^2 rad/s``; ``trace(C P_p C^T)`` is the squared band-limited H2 norm.
    Q_pv : ndarray, shape (n, n)
        The same for the dual system with input ``C^T`` (``= M^-T Q_v M^-1``).

    Raises
    ------
    UserError
        If the system is undamped (not asymptotically stable), its inputs or outputs act on
        rigid-body modes, or it is too large for dense Gramians.
    """
    w1, w2 = band_in_rad_s(band_hz, allow_infinite=True)
    p_p, q_pv, _ = band_gramians(system, w1, w2, damping_ratio)
    return p_p, q_pv


def band_gramians(
    system: SecondOrderSystem, w1: float, w2: float, damping_ratio: float | None
) -> tuple[np.ndarray, np.ndarray, ModalForm]:
    """``P_p^w``, ``Q_pv^w`` over ``w1 <= |w| <= w2`` (rad/s) and the modal form used."""
    modal = _modal_form(system, damping_ratio)
    p_eta, q_eta = _modal_gramians(modal, w1, w2, [modal.inputs, modal.outputs_t])
    phi = modal.modes
    p_p, q_pv = phi @ p_eta @ phi.T, phi @ q_eta @ phi.T
    return 0.5 * (p_p + p_p.T), 0.5 * (q_pv + q_pv.T), modal


def stress_gramian(system: SecondOrderSystem, modal: ModalForm, w1: float, w2: float) -> np.ndarray:
    """``Q_s^w``: the ``Q_pv^w`` of the stress outputs ``C_s`` of ``system`` (the dual system
    with input ``C_s^T``) over ``w1 <= |w| <= w2`` (rad/s), in the modal form ``modal`` of
    :func:`band_gramians`; shape (n, n), units ``(stress / u)^2 rad/s`` per unit ``q``."""
    phi = modal.modes
    stress_t = np.asarray(system.stress_matrix @ phi).T
    (q_eta,) = _modal_gramians(modal, w1, w2, [stress_t])
    q_s = phi @ q_eta @ phi.T
    return 0.5 * (q_s + q_s.T)


# --------------------------------------------------------------------------------------------
# reduction


def error_indicator(sigma: np.ndarray) -> np.ndarray:
    """``sigma_{i+1} / sigma_1`` for reduced orders ``i = 1, ..., N`` (paper Fig. 11).

    Parameters
    ----------
    sigma : ndarray, shape (N,)
        Eigenvalues of ``P_p^w + Q_pv^w``, descending, >= 0.

    Returns
    -------
    ndarray, shape (N,)
        Entry ``i - 1`` belongs to order ``i``; ``sigma_{N+1} = 0``.
    """
    sigma = np.asarray(sigma, dtype=float)
    if sigma.size == 0 or sigma[0] <= 0:
        return np.zeros(sigma.size)
    return np.append(sigma[1:], 0.0) / sigma[0]


def select_order(
    sigma: np.ndarray, order: int | None = None, tolerance: float | None = None
) -> int:
    """The reduced order from the eigenvalues ``sigma`` (descending).

    With ``tolerance``: the smallest ``n >= 1`` with ``sigma_{n+1} / sigma_1 <= tolerance``
    (the error indicator of paper section 3.2 / Fig. 11); with ``order`` too, at most ``order``.
    With ``order`` only: ``order``.
    """
    available = int(np.asarray(sigma).size)
    if tolerance is not None:
        indicator = error_indicator(sigma)
        n = int(np.argmax(indicator <= tolerance)) + 1  # indicator[-1] = 0 <= tolerance
        if order is not None:
            n = min(n, int(order))
    else:
        n = int(order)
    if n > available:
        raise UserError(f"order {n} exceeds the {available} directions available")
    return n


def block_union(
    spectra: Sequence[tuple[np.ndarray, np.ndarray]],
    order: int | None = None,
    tolerance: float | None = None,
) -> tuple[np.ndarray, list[int]]:
    """An orthonormal basis of the dominant eigenvectors of several Gramian sums, each block
    held to the tolerance by itself.

    Every block (e.g. the ports' ``P_p + Q_pv`` and the stresses' ``P_p + Q_s``) keeps the
    directions :func:`select_order` would keep for it alone with ``tolerance``; their union is
    the basis. The eigenvectors enter in the order of their relative eigenvalue
    ``sigma_i / sigma_1`` in their block (the dominant one of each block first), the ones
    already in the span dropped (a residual below 1e-10), until the basis has ``order``
    columns. So the basis contains the one each block would get alone with ``tolerance``, and
    a block's weight has no say: each is judged by its own largest eigenvalue.

    Parameters
    ----------
    spectra : sequence of (sigma, vectors)
        Per block the eigenvalues (k,), descending, and eigenvectors (k, k) of its Gramian sum,
        as :func:`_dominant` gives them.
    order : int, optional
        The largest size of the basis.
    tolerance : float, optional
        The error indicator of each block (:func:`error_indicator`); without it every direction
        is a candidate and ``order`` decides.

    Returns
    -------
    basis : ndarray, shape (k, n)
        Orthonormal.
    counts : list of int
        The directions each block brought that were not in the span yet.
    """
    candidates = []
    for block, (sigma, _) in enumerate(spectra):
        kept = select_order(sigma, None, tolerance) if tolerance is not None else sigma.size
        ratios = sigma[:kept] / sigma[0] if sigma.size and sigma[0] > 0 else np.zeros(kept)
        candidates += [(-float(ratio), block, i) for i, ratio in enumerate(ratios)]
    size = spectra[0][1].shape[0]
    basis = OrthonormalBasis(size, 1e-10)
    counts = [0] * len(spectra)
    for _, block, i in sorted(candidates):
        if order is not None and basis.size >= order:
            break
        counts[block] += basis.add(spectra[block][1][:, i]).shape[1]
    if order is not None and tolerance is None and basis.size < order:
        raise UserError(f"order {order} exceeds the {basis.size} directions available")
    return basis.matrix, counts


def _dominant(matrix: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Eigenvalues (descending, clipped at 0) and eigenvectors of a symmetric PSD matrix."""
    values, vectors = np.linalg.eigh(0.5 * (matrix + matrix.T))
    values, vectors = values[::-1], vectors[:, ::-1]
    return np.clip(values, 0.0, None), vectors


def _medium_basis(system: SecondOrderSystem, medium: Projection | ReducedModel) -> np.ndarray:
    """Orthonormal basis (Euclidean) of the first-step space, elastic for a free body."""
    if isinstance(medium, Projection):
        medium = reduced_model(system, medium)
    if not isinstance(medium, ReducedModel):
        raise UserError("gramian: 'medium' must be a Projection or a ReducedModel")
    basis = medium.projection.V
    if basis.shape[0] != system.order:
        raise UserError(
            f"gramian: the medium basis has {basis.shape[0]} rows, the system {system.order} dofs"
        )
    q, r = np.linalg.qr(basis)
    diagonal = np.abs(np.diag(r))
    keep = diagonal > 1e-12 * diagonal.max()
    return q[:, keep]


def gramian_reduction(
    system: SecondOrderSystem,
    band_hz: Sequence[float],
    order: int | None = None,
    tolerance: float | None = None,
    medium: Projection | ReducedModel | None = None,
    damping_ratio: float | None = None,
    kappa_points: int = KAPPA_POINTS,
) -> Projection:
    """Projection on the dominant eigenspace of ``P_p^w + Q_pv^w`` (paper section 3.2).

    Parameters
    ----------
    system : SecondOrderSystem
        The full system: dense, or sparse with at most :data:`MAX_DENSE_ORDER` dofs unless
        ``medium`` is given. Damping as in :func:`frequency_weighted_gramians`.
    band_hz : (float, float)
        Frequency band ``(f_min, f_max)`` in Hz of the weighting, finite.
    order : int, optional
        Size ``n`` of the reduced model; with ``tolerance`` the largest size.
    tolerance : float, optional
        Automatic order: the smallest ``n`` with ``sigma_{n+1} / sigma_1 <= tolerance``, the error
        indicator of paper section 3.2 and Fig. 11 (see :func:`select_order`).
    medium : Projection or ReducedModel, optional
        Two-step approach (paper ref. [9]): the first-step reduction (Krylov, modal) of a large
        system. Its basis, made elastic and mass-normalised by
        :func:`~pymorembs.reduction.projection.reduced_model` and then orthonormalised, is ``V_m``;
        the Gramians are those of the dense medium model ``system.project(V_m)``, and
        ``V = V_m V_gram``. Everything reported (eigenvalues, bound) then belongs to the medium
        model: the error of the first step is not in the bound.
    damping_ratio : float, optional
        Modal damping ratio for the Gramians of an undamped system (without it an undamped system
        is an error).
    kappa_points : int
        Number of log-spaced frequencies on which ``kappa`` and ``kappa_T`` are sampled, to which
        the damped eigenfrequencies of the reduced model in the band are added (0: no bound).

    Returns
    -------
    Projection
        ``V = W`` with orthonormal columns, method ``"gramian"`` (``"two-step gramian"``).
        ``error_bound`` is the band-limited H2 error bound of eq. 24 in the form derived in the
        module notes, ``sqrt(max(kappa, kappa_T) sum_{j > n} sigma_j)``, with ``kappa`` and
        ``kappa_T`` sampled on the frequency grid (a-posteriori: they depend on the reduced
        model). It is absolute, in units of ``H sqrt(rad/s)``; divide by ``h2_norm`` for a
        relative value. ``parameters``:

        * ``band_hz``, ``order``, ``tolerance``, ``two_step``, ``medium_order``;
        * ``sigma``: all eigenvalues ``sigma_i^PQ`` of ``P_p^w + Q_pv^w``, descending, clipped at
          0, units ``(q/u)^2 rad/s`` (the Gramians include the ``1/(2 pi)`` of the H2 norm);
        * ``indicator``: ``sigma_{i+1} / sigma_1`` for ``i = 1 ... N`` (entry ``i - 1``);
        * ``neglected_sum``: ``sum_{j > n} sigma_j``;
        * ``h2_norm``: ``||H W||_H2 = sqrt(trace(C P_p^w C^T))`` of the (medium) model;
        * ``a_priori_bound``: ``sqrt(neglected_sum)``, eq. 24 with ``kappa = kappa_T = 1``.
          Known before the reduced model is, but not proven (``kappa`` can exceed 1 at low
          orders); the tests find it above the true error;
        * ``kappa``, ``kappa_T``: the sampled constants (None with ``kappa_points = 0``).

    Raises
    ------
    OptionError
        A bad ``order`` or ``tolerance``, checked by :class:`~pymorembs.methods.GramianOptions`.
    UserError
        A bad band, an undamped system, or a large system without ``medium``.
    """
    checked = GramianOptions(order=order, tolerance=tolerance)
    return _dominant_projection(
        system, band_hz, checked.order, checked.tolerance, medium, damping_ratio, kappa_points
    )


def _dominant_projection(
    system: SecondOrderSystem,
    band_hz: Sequence[float],
    order: int | None,
    tolerance: float | None,
    medium: Projection | ReducedModel | None,
    damping_ratio: float | None = None,
    kappa_points: int = KAPPA_POINTS,
) -> Projection:
    """:func:`gramian_reduction` with ``order`` and ``tolerance`` checked."""
    w1, w2 = band_in_rad_s(band_hz, allow_infinite=False)
    if medium is not None:
        outer = _medium_basis(system, medium)
        working = system.project(outer)
    elif system.order > MAX_DENSE_ORDER:
        raise UserError(
            f"gramian: the model has {system.order} dofs, more than the {MAX_DENSE_ORDER} for "
            "dense Gramians; give a first-step reduction ('medium', two-step approach) or use "
            "the POD"
        )
    else:
        outer, working = None, system
    p_p, q_pv, modal = band_gramians(working, w1, w2, damping_ratio)
    stress = None
    if system.stress_targeted and working.stress_matrix is not None:
        stress = stress_gramian(working, modal, w1, w2)
    return projection_from_gramians(
        working,
        outer,
        (p_p, q_pv, modal),
        (w1, w2),
        order,
        tolerance,
        kappa_points,
        method="gramian" if outer is None else "two-step gramian",
        parameters={
            "two_step": outer is not None,
            "medium_order": None if outer is None else int(outer.shape[1]),
        },
        stress=stress,
    )


# --------------------------------------------------------------------------------------------
# the two-step method (paper section 3.2): its first stage


#: Order and estimated error target of the SOAGA first stage when the options give none.
FIRST_SOAGA_ORDER = 132
FIRST_SOAGA_TOLERANCE = 1e-10


def first_stage(requested: str | None, n_dofs: int) -> str:
    """The first stage of the ``gramian`` method on a model of ``n_dofs`` independent dofs.

    Parameters
    ----------
    requested : {"soaga", "krylov", "rational-krylov", "none"} or None
        The ``first_stage`` option (:class:`~pymorembs.methods.GramianOptions`).
    n_dofs : int
        Independent dofs of the model.

    Returns
    -------
    str
        ``requested`` if given; else ``"soaga"`` above :data:`MAX_DENSE_ORDER` dofs (the dense
        Gramians of the full model are out of reach) and ``"none"`` up to it.
    """
    if requested is not None:
        return requested
    return "soaga" if n_dofs > MAX_DENSE_ORDER else "none"


def medium_model(
    system: SecondOrderSystem, options: GramianOptions, band_hz: tuple[float, float]
) -> Projection | None:
    """The medium model of the two-step reduction (paper section 3.2), or None.

    Its first stage is :func:`first_stage`: SOAGA (``first_order``, default
    :data:`FIRST_SOAGA_ORDER`; ``first_tolerance``, default :data:`FIRST_SOAGA_TOLERANCE`),
    Krylov (``expansion_points_hz``, ``moments``, ``first_order`` as its order), or none. The
    rational Krylov first stage has no medium model
    (:func:`~pymorembs.reduction.rational_gramian.rational_gramian_reduction`).
    """
    stage = first_stage(options.first_stage, system.order)
    if stage == "none":
        return None
    if stage == "soaga":
        band_in_rad_s(band_hz, allow_infinite=False)  # the band is no option: checked here
        f_min, f_max = (float(f) for f in band_hz)
        tolerance = options.first_tolerance
        order = options.first_order
        return adaptive_arnoldi(
            system,
            (f_min, f_max),
            candidate_points(f_min, f_max, None, None),
            FIRST_SOAGA_TOLERANCE if tolerance is None else tolerance,
            FIRST_SOAGA_ORDER if order is None else order,
            1e-10,
        )
    return moment_matching(
        system, options.expansion_points_hz, options.moments, options.first_order, 1e-10, False
    )


def gramian_from_options(
    system: SecondOrderSystem, options: GramianOptions, band_hz: tuple[float, float]
) -> Projection:
    """The ``gramian`` method on its checked options, with a medium model or none
    (:func:`medium_model`; the rational Krylov first stage is
    :func:`~pymorembs.reduction.rational_gramian.rational_gramian_from_options`).

    The order is capped by the medium model's (a two-step model cannot exceed it); a capped
    projection says so in ``parameters["order_capped_by_first_stage"]``.
    """
    medium = medium_model(system, options, band_hz)
    order = options.order
    if medium is not None and order is not None and order > medium.order:
        order = medium.order
    projection = _dominant_projection(system, band_hz, order, options.tolerance, medium)
    if order == options.order:
        return projection
    return projection.with_parameters(order_capped_by_first_stage=medium.order)


def projection_from_gramians(
    working: SecondOrderSystem,
    outer: np.ndarray | None,
    gramians: tuple[np.ndarray, np.ndarray, ModalForm],
    band_rad: tuple[float, float],
    order: int | None,
    tolerance: float | None,
    kappa_points: int,
    method: str,
    parameters: dict,
    stress: np.ndarray | None = None,
) -> Projection:
    """The projection on the dominant eigenvectors of ``P_p^w + Q_pv^w`` of ``working``.

    Shared by :func:`gramian_reduction` and the large-scale solver of
    :mod:`pymorembs.reduction.rational_gramian`.

    With targeted stresses (``stress``, their Gramian ``Q_s^w``) the basis is the union of the
    dominant eigenvectors of ``P_p^w + Q_pv^w`` and of ``P_p^w + Q_s^w``, each block held to
    ``tolerance`` by its own indicator (:func:`block_union`; ``parameters``: ``orders`` the
    directions each block brought, ``stress_sigma``). The basis contains the untargeted one,
    so the neglected sum of the ports' block still bounds the ports' error (eq. 24): with a
    single sum ``P_p + Q_pv + w^2 Q_s`` its eigenvectors would mix the blocks, the ports'
    dominant directions would no longer be in the basis, and the ports' error would grow.

    Parameters
    ----------
    working : SecondOrderSystem
        The system whose Gramians are given: the full one, or ``system.project(outer)``.
    outer : ndarray, shape (N, k), or None
        Orthonormal basis with ``working = system.project(outer)``; ``V = outer V_gram``.
    gramians : (P_p, Q_pv, modal form)
        Of ``working``, shape (k, k) each, as ``band_gramians`` returns them.
    band_rad : (float, float)
        ``(w_1, w_2)`` in rad/s.
    order, tolerance, kappa_points :
        As in :func:`gramian_reduction`.
    method : str
        The projection's method name.
    parameters : dict
        Entries placed after ``band_hz``, ``order``, ``tolerance`` in ``Projection.parameters``.
    """
    w1, w2 = band_rad
    p_p, q_pv, modal = gramians
    sigma, vectors = _dominant(p_p + q_pv)
    if stress is None:
        n = select_order(sigma, order, tolerance)
        v_small = vectors[:, :n]
        kept = n
    else:
        stress_sigma, stress_vectors = _dominant(p_p + stress)
        v_small, counts = block_union(
            [(sigma, vectors), (stress_sigma, stress_vectors)], order, tolerance
        )
        n, kept = v_small.shape[1], counts[0]
        parameters = {
            **parameters,
            "orders": {"outputs": counts[0], "stresses": counts[1]},
            "stress_sigma": [float(s) for s in stress_sigma],
        }
    v = v_small if outer is None else outer @ v_small
    neglected = float(np.sum(sigma[kept:]))
    c = working.output_matrix
    h2 = float(np.sqrt(max(float(np.trace(c @ p_p @ c.T)), 0.0)))
    kappa = kappa_t = bound = None
    if kappa_points > 0:
        kappa, kappa_t = _kappas(working, modal, v_small, w1, w2, kappa_points)
        bound = float(np.sqrt(max(kappa, kappa_t) * neglected))
    return Projection(
        V=v,
        W=v,
        method=method,
        parameters={
            "band_hz": [w1 / (2.0 * np.pi), w2 / (2.0 * np.pi)],
            "order": n,
            "tolerance": tolerance,
            **parameters,
            "sigma": [float(s) for s in sigma],
            "indicator": [float(x) for x in error_indicator(sigma)],
            "neglected_sum": neglected,
            "h2_norm": h2,
            "a_priori_bound": float(np.sqrt(neglected)),
            "kappa": kappa,
            "kappa_T": kappa_t,
        },
        error_bound=bound,
    )


def _kappas(
    system: SecondOrderSystem, modal: ModalForm, v: np.ndarray, w1: float, w2: float, points: int
) -> tuple[float, float]:
    """``kappa = max ||C Pi(i w)||_2^2`` and ``kappa_T = max ||Pi_T(i w) B||_2^2`` on a grid.

    ``Pi = I - V R_bar V^T Z`` and ``Pi_T = I - Z V R_bar V^T`` with ``Z(s) = s^2 M + s D_v + K``,
    ``D_v`` the viscous damping the Gramians used, ``R_bar = (V^T Z V)^-1``. The grid: ``points``
    log-spaced frequencies over the band (from ``max(w1, 1e-3 w2)``; 0 too if the band starts
    there) and the damped eigenfrequencies of the reduced model inside the band, where the
    peaks of ``||C Pi||`` lie.
    """
    m, k = _dense(system.mass), _dense(system.stiffness)
    mphi = m @ modal.modes
    d = mphi @ modal.damping @ mphi.T  # = D_v (on the elastic modes: Phi^T M Phi = I)
    b, c = system.input_matrix, system.output_matrix
    mv, kv, dv = m @ v, k @ v, d @ v
    vmv, vkv, vdv = v.T @ mv, v.T @ kv, v.T @ dv
    cv, vb = c @ v, v.T @ b
    grid = np.geomspace(max(w1, 1e-3 * w2), w2, points)
    if w1 == 0.0:
        grid = np.append(grid, 0.0)
    size = v.shape[1]
    companion = np.block(
        [
            [np.zeros((size, size)), np.eye(size)],
            [-np.linalg.solve(vmv, vkv), -np.linalg.solve(vmv, vdv)],
        ]
    )
    damped = np.abs(np.linalg.eigvals(companion).imag)
    grid = np.concatenate([grid, damped[(damped >= w1) & (damped <= w2)]])
    kappa = kappa_t = 0.0
    for w in grid:
        s = 1j * w
        zv = s * s * mv + s * dv + kv
        reduced = s * s * vmv + s * vdv + vkv
        c_pi = c - cv @ np.linalg.solve(reduced, zv.T)  # Z symmetric: V^T Z = (Z V)^T
        pi_b = b - zv @ np.linalg.solve(reduced, vb)
        kappa = max(kappa, _norm2(c_pi) ** 2)
        kappa_t = max(kappa_t, _norm2(pi_b) ** 2)
    return float(kappa), float(kappa_t)


def _norm2(a: np.ndarray) -> float:
    """Spectral norm (0 for an empty matrix)."""
    return float(np.linalg.norm(a, 2)) if a.size else 0.0


# --------------------------------------------------------------------------------------------
# POD


def quadrature(
    band_hz: Sequence[float], n_snapshots: int, rule: str = "gauss"
) -> tuple[np.ndarray, np.ndarray]:
    """Nodes (Hz) and weights (rad/s) for ``int_{w1}^{w2} g(w) dw`` over the band.

    ``rule = "gauss"``: Gauss-Legendre in ``w`` (nodes inside the band);
    ``"trapezoid"``: equally spaced nodes including both ends (0 Hz if the band starts there).
    The weights sum to ``w2 - w1``. ``n_snapshots`` is checked by the caller (the ``snapshots``
    of :class:`~pymorembs.methods.PodOptions`, at least 4).
    """
    w1, w2 = band_in_rad_s(band_hz, allow_infinite=False)
    count = n_snapshots
    if rule == "gauss":
        x, wts = np.polynomial.legendre.leggauss(count)
        nodes = 0.5 * (w2 - w1) * x + 0.5 * (w1 + w2)
        weights = 0.5 * (w2 - w1) * wts
    elif rule == "trapezoid":
        nodes = np.linspace(w1, w2, count)
        weights = np.full(count, (w2 - w1) / (count - 1))
        weights[[0, -1]] *= 0.5
    else:
        raise UserError(f"pod: quadrature rule {rule!r} is unknown; use 'gauss' or 'trapezoid'")
    return nodes / (2.0 * np.pi), weights


def resolvent(system: SecondOrderSystem, frequency_hz: float) -> Callable[[np.ndarray], np.ndarray]:
    """``rhs -> (-w^2 M + i w D + (1 + i eta) K)^-1 rhs`` at ``w = 2 pi f``; elastic part for free
    bodies.

    Sparse systems: one :class:`Factorization` of the exact terms (inertia relief at 0 Hz for a
    free body), kept by the returned function for any number of solves; dense systems: a dense
    solve. The solutions are mass-orthogonal to the rigid-body modes of a free body.

    Parameters
    ----------
    system : SecondOrderSystem
    frequency_hz : float
        ``f >= 0`` in Hz.

    Returns
    -------
    callable
        ``solve(rhs)`` for ``rhs`` of shape (n, k), real or complex; complex result for
        ``f > 0`` with damping.
    """
    terms, scale = system.dynamic_terms(2j * np.pi * frequency_hz)
    label = f"dynamic stiffness at {frequency_hz:g} Hz"
    rigid = system.rigid_modes
    if system.is_sparse:
        if frequency_hz == 0.0 and rigid is not None:
            solver = InertiaRelief(system.stiffness, system.mass, rigid, label).solve
        else:
            solver = Factorization(terms, label=label).solve
    else:
        matrix = sum(coefficient * np.asarray(a) for coefficient, a in terms)

        def solver(rhs: np.ndarray) -> np.ndarray:
            try:
                return np.linalg.solve(matrix, rhs)
            except np.linalg.LinAlgError:
                raise NumericalError(f"{label} is singular") from None

    def solve(rhs: np.ndarray) -> np.ndarray:
        x = solver(rhs) / scale
        if rigid is not None:  # rigid-body part: zero in exact arithmetic (R^T B = 0)
            x = x - rigid @ (rigid.T @ extended_product(system.mass, x))
        return x

    return solve


def _resolvent_solve(system: SecondOrderSystem, frequency_hz: float, rhs: np.ndarray) -> np.ndarray:
    """``(-w^2 M + i w D + (1 + i eta) K)^-1 rhs`` at ``w = 2 pi f`` (see :func:`resolvent`)."""
    return resolvent(system, frequency_hz)(rhs)


def pod_reduction(
    system: SecondOrderSystem,
    band_hz: Sequence[float],
    order: int | None = None,
    tolerance: float | None = None,
    n_snapshots: int = 40,
    rule: str = "gauss",
) -> Projection:
    """POD approximation of the dominant eigenspace of ``P_p^w + Q_pv^w`` (paper ref. [17]).

    The Gramian integral is approximated by quadrature over the band with frequency-domain
    snapshots ``X_k = R(i w_k) B``, ``R(s) = (s^2 M + s D + (1 + i eta) K)^-1``:

        P_p^w = 1/(2 pi) int_{w1 <= |w| <= w2} R B B^T R^H dw
              = 1/pi int_{w1}^{w2} Re(R B B^T R^H) dw
              ~ 1/pi sum_k w_k (Re X_k Re X_k^T + Im X_k Im X_k^T) = Y_B Y_B^T

    using ``R(-i w) = conj R(i w)`` (a loss factor changes sign with ``w``); likewise
    ``Q_pv^w ~ Y_C Y_C^T`` from ``R(i w_k) C^T`` (for ``C = B^T``: ``Q_pv = P_p``, and
    ``Y = sqrt(2) Y_B``). ``V`` is the leading left singular vectors of
    ``Y = [Y_B, Y_C]``, ``Y`` with columns ``sqrt(w_k / pi) Re X_k``, ``sqrt(w_k / pi) Im X_k``;
    no n x n matrix is formed. The squared singular values ``s_i^2`` approximate the eigenvalues
    ``sigma_i^PQ`` of the Gramian sum, and the order follows from the same indicator
    ``sigma_{n+1} / sigma_1 = (s_{n+1} / s_1)^2`` as in :func:`gramian_reduction`.

    Parameters
    ----------
    system : SecondOrderSystem
        Sparse full system (or a dense one). Its damping as in the frequency response: viscous
        ``D`` and the loss factor ``eta`` (for a modal damping ratio); snapshots of an undamped
        system are valid unless a node hits an eigenfrequency.
    band_hz : (float, float)
        Frequency band ``(f_min, f_max)`` in Hz, finite.
    order, tolerance :
        As in :func:`gramian_reduction`; the order is at most the number of snapshot columns.
    n_snapshots : int
        Number of quadrature nodes (one factorization each), at least 4. Resonances narrower
        than the node spacing make the Gramian estimate rough, the subspace less so.
    rule : {"gauss", "trapezoid"}
        Quadrature in ``w`` (see :func:`quadrature`). The trapezoid rule includes 0 Hz when the
        band starts there (inertia relief for a free body).

    Returns
    -------
    Projection
        ``V = W`` orthonormal, method ``"pod"``, no ``error_bound`` (the Gramians are
        approximate). ``parameters``: ``band_hz``, ``order``, ``tolerance``, ``n_snapshots``,
        ``rule``, ``snapshot_frequencies_hz``, ``singular_values`` (all ``s_i``, descending),
        ``sigma`` (``s_i^2``), ``indicator`` (``sigma_{i+1} / sigma_1``, entry ``i - 1`` for order
        ``i``), ``neglected_sum`` and ``a_priori_bound = sqrt(neglected_sum)`` -- eq. 24 with
        ``kappa = kappa_T = 1`` from the approximate eigenvalues (an estimate, not a bound).

    Raises
    ------
    OptionError
        A bad ``order``, ``tolerance`` or ``n_snapshots`` (its ``snapshots``), checked by
        :class:`~pymorembs.methods.PodOptions` with its message.
    UserError
        A bad band or ``rule``, a system without inputs and outputs, or an order above the
        snapshot columns.
    """
    checked = PodOptions(order=order, tolerance=tolerance, snapshots=n_snapshots)
    return _snapshot_projection(
        system, band_hz, checked.order, checked.tolerance, checked.snapshots, rule
    )


def pod_from_options(
    system: SecondOrderSystem, options: PodOptions, band_hz: tuple[float, float]
) -> Projection:
    """The ``pod`` method on its checked options."""
    return _snapshot_projection(
        system, band_hz, options.order, options.tolerance, options.snapshots, "gauss"
    )


def _snapshot_projection(
    system: SecondOrderSystem,
    band_hz: Sequence[float],
    order: int | None,
    tolerance: float | None,
    n_snapshots: int,
    rule: str,
) -> Projection:
    """:func:`pod_reduction` with ``order``, ``tolerance`` and ``n_snapshots`` checked."""
    frequencies, weights = quadrature(band_hz, n_snapshots, rule)
    if system.n_inputs == 0 and system.n_outputs == 0:
        raise UserError("pod: the system has neither inputs nor outputs")
    b, c_t = system.input_matrix, system.output_matrix.T
    collocated = b.shape == c_t.shape and np.array_equal(b, c_t)
    rhs = b if collocated else np.hstack([b, c_t])
    blocks = []
    for f, weight in zip(frequencies, weights, strict=True):
        x = _resolvent_solve(system, float(f), rhs)
        factor = np.sqrt(weight / np.pi) * (np.sqrt(2.0) if collocated else 1.0)
        blocks.append(factor * x.real)
        if np.iscomplexobj(x) and np.any(x.imag):
            blocks.append(factor * x.imag)
    snapshots = np.hstack(blocks)
    u, s, _ = np.linalg.svd(snapshots, full_matrices=False)
    sigma = s * s
    n = select_order(sigma, order, tolerance)
    v = u[:, :n]
    neglected = float(np.sum(sigma[n:]))
    lo, hi = band_in_rad_s(band_hz, allow_infinite=False)
    return Projection(
        V=v,
        W=v,
        method="pod",
        parameters={
            "band_hz": [lo / (2.0 * np.pi), hi / (2.0 * np.pi)],
            "order": n,
            "tolerance": tolerance,
            "n_snapshots": int(n_snapshots),
            "rule": rule,
            "snapshot_frequencies_hz": [float(f) for f in frequencies],
            "singular_values": [float(x) for x in s],
            "sigma": [float(x) for x in sigma],
            "indicator": [float(x) for x in error_indicator(sigma)],
            "neglected_sum": neglected,
            "a_priori_bound": float(np.sqrt(neglected)),
        },
    )
