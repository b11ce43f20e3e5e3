"""Frequency-weighted Gramians of large models by rational Krylov projection (paper section 3.2).

The paper computes the frequency-weighted position Gramians ``P_p^w`` and ``Q_pv^w`` densely
(small models) or approximates them by a two-step approach or a POD, and names iterative solvers
(LR-ADI, Smith) for large models as "under current research". This module is such a solver: a
Galerkin projection onto a growing rational Krylov subspace, the approach of the rational Krylov
subspace method (RKSM) for Lyapunov equations (Druskin & Simoncini, "Adaptive rational Krylov
subspaces for large-scale dynamical systems", Systems & Control Letters 60, 2011), here for the
second-order, frequency-weighted Gramians.

Galerkin condition
------------------
With an orthonormal real basis ``V`` (N, k) and the one-sided projection of the second-order
system, ``(V^T M V, V^T D V, V^T K V, V^T B, C V)``, the first-order (descriptor) form of the
projected system is the Galerkin projection of the full one with ``Z = diag(V, V)``: for
``E = diag(I, M)``, ``A = [[0, I], [-K, -D]]``, ``B_1 = [0; B]`` (paper eq. 5, ``E x' = A x +
B_1 u``) the projected matrices are ``Z^T E Z``, ``Z^T A Z``, ``Z^T B_1``. The Galerkin
approximation ``P ~ Z X Z^T`` of the Lyapunov equation ``A P E^T + E P A^T + B_1 B_1^T = 0``
-- the residual orthogonal to ``Z`` -- is therefore the controllability Gramian ``X`` of the
projected system, and the same holds for the band-limited integral

    P_p^w = 1/(2 pi) int_band R(i w) B B^T R(i w)^H dw ~ V X_P V^T,
    X_P = 1/(2 pi) int_band R_V(i w) V^T B B^T V R_V(i w)^H dw,   R_V = (V^T Z(s) V)^-1,

``Z(s) = s^2 M + s D + K``: the integrand is approximated by its Galerkin solution
``V R_V(i w) V^T B`` at every frequency. ``X_P`` and ``X_Q`` (the same with ``C^T``) are the dense
frequency-weighted Gramians of :mod:`pymorembs.reduction.gramian`, applied to the projected system.

Subspace
--------
``V`` spans ``R(i w_j) [B, C^T]`` (real and imaginary parts) and, with ``moments >= 2``, the
next blocks of the second-order Krylov recurrence at the same shift (paper eq. 20,
``P_i = -R(s_j) ((2 s_j M + D) P_{i-1} + M P_{i-2})``) -- one sparse factorization per shift
(:func:`pymorembs.reduction.gramian.resolvent`, inertia relief at 0 Hz for a free body). The
interpolation property of rational Krylov spaces makes the Galerkin integrand exact at every
shift (``R(s_j) B`` lies in ``span(V)``), with ``moments`` derivatives matched there.

Shifts: the band ends ``f_min`` and ``f_max`` first; then, greedily, the frequency of a grid over
the band (log-spaced and equidistant, as the SOAGA estimator grid) where the relative Galerkin
residual of the integrand

    rho(w) = max(||B - Z(i w) V x_B(w)||_F / ||B||_F, ||C^T - Z(i w) V x_C(w)||_F / ||C||_F),
    x_B = R_V(i w) V^T B,  x_C = R_V(i w) V^T C^T

is largest (the adaptive pole choice of RKSM maximises the residual along the spectral region;
here the band of the imaginary axis is the region that matters). A shift whose solutions add no
direction (all deflated: the residual there is at its rounding floor, ``~ deflation_tol`` times
the condition of ``Z``) excludes its neighbourhood from later choices. ``rho`` is evaluated with the
full sparse matrices but without any N x N matrix and without a solve: from a QR factorization
of ``Y = [F, K V, D V, M V]`` (``F = [B, C^T]``) updated column block by column block, the
residual is ``Y c(w)`` with a short coefficient vector ``c(w)``, so ``||Y c|| = ||R_Y c||`` --
accurate also when the residual is tiny (no cancellation as in a Gram matrix). The products
``K V`` etc. are computed in extended precision once per column.

Stopping rule
-------------
On the Gramian itself: after every shift, the squared band-limited H2 norm ``trace(C X_P C^T)``
and the eigenvalues ``sigma_i`` of ``X_P + X_Q`` (the ``sigma_i^PQ`` of eq. 24) are compared with
those of the previous iteration; the iteration stops when

    max(|Delta trace| / trace, max_i |Delta sigma_i| / sigma_1) <= tol

(``i`` over the leading ``n_sigma`` eigenvalues, all by default) in ``patience`` consecutive
iterations (and ``V`` has at least ``min_dim`` columns: when the Gramian has converged with
fewer, further moments at the last shift fill the basis without a new factorization), or when
the basis has ``max_dim`` columns or ``max_shifts`` shifts were used.

What is exact and what is approximate
-------------------------------------
* Exact (to rounding): ``X_P``, ``X_Q`` are the frequency-weighted Gramians of the projected
  system (computed by the dense code, with its damping model: viscous ``D`` plus the viscous
  equivalent of a modal damping ratio); the nonzero eigenvalues of ``V (X_P + X_Q) V^T`` are
  those of ``X_P + X_Q`` (``V`` orthonormal); with viscous damping (Rayleigh, explicit) the
  Galerkin integrand ``V R_V V^T B`` equals the true ``R B`` at every shift (with ``moments``
  derivatives). With a loss factor the shifts solve the frequency-response operator
  ``s^2 M + s D + (1 + i eta) K`` while the Gramians use the viscous model: the space is still
  good, the interpolation is then not exact.
* Approximate: ``V X_P V^T ~ P_p^w``. There is no computable bound on the distance to the true
  Gramian; the stopping rule measures the change between iterations and ``rho`` the residual
  of the integrand, both indicators. On the test models
  (tests/reduction/test_rational_gramian.py) with
  ``tol = 1e-10`` the trace agrees with that of the dense Gramians of the full model to
  ``1e-9`` (relative), the leading ``sigma_i`` to ``1e-9 sigma_1``, the matrices entrywise to
  ``1e-7``; with ``tol = 1e-3`` the ``sigma_i`` are off by ``1e-12 .. 1e-2`` of ``sigma_1``.
  The reduced models are as accurate (eq. 27) as those from the dense Gramians.
* The a-priori bound of eq. 24 (``sqrt(sum_{j > n} sigma_j)``, and with the ``kappa`` sampled on
  the projected system) holds for the projected system: it bounds the band-limited H2 distance
  between the projected model (dimension ``k``) and the reduced one. The projected model's own
  error is not in it -- as for the two-step approach, but here the projected model is refined
  until its Gramian stops changing, and its final residual ``rho`` is reported.

Frequencies are in Hz at the interface, ``w = 2 pi f`` in rad/s inside.
"""

from __future__ import annotations

import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from pymorembs.errors import UserError
from pymorembs.frequencies import frequency_grid
from pymorembs.linalg.orthogonalization import OrthonormalBasis
from pymorembs.methods import GramianOptions
from pymorembs.reduction.gramian import (
    KAPPA_POINTS,
    ModalForm,
    band_gramians,
    band_in_rad_s,
    projection_from_gramians,
    resolvent,
    stress_gramian,
)
from pymorembs.reduction.projection import Projection
from pymorembs.reduction.soaga import BlockProducts
from pymorembs.system import SecondOrderSystem

#: Default stopping tolerance on the relative change of the Gramian quantities.
DEFAULT_TOL = 1e-8
#: Default largest basis dimension.
DEFAULT_MAX_DIM = 300
#: The least value of each whole-number keyword of the solver (:func:`check_solver_keywords`).
LEAST_COUNTS = {"max_dim": 1, "max_shifts": 1, "moments": 1, "grid_points": 2, "patience": 1}
#: Default largest number of shifts (= sparse factorizations).
DEFAULT_MAX_SHIFTS = 40
#: Default number of log-spaced (and as many equidistant) frequencies of the shift grid.
DEFAULT_GRID_POINTS = 100
#: Singular values (of unit columns) below this are rounding in the residual basis.
RANK_TOL = 1e-13
#: A shift that adds no direction excludes the grid points closer than this times the band
#: width plus five times this times its frequency from later shifts.
DEAD_RADIUS = 0.01
#: Stop after this many shifts in a row that added no direction.
MAX_DEAD = 3
#: Frequencies per batch of reduced solves on the residual grid.
CHUNK = 64


@dataclass(eq=False)
class RationalKrylovGramians:
    """Low-rank frequency-weighted Gramians ``P_p^w ~ V X_P V^T``, ``Q_pv^w ~ V X_Q V^T``.

    Attributes
    ----------
    basis : ndarray, shape (N, k)
        ``V``, orthonormal columns (elastic for a free body).
    x_p, x_q : ndarray, shape (k, k)
        Frequency-weighted position Gramians of the projected system, units ``(q/u)^2 rad/s``
        (with the ``1/(2 pi)`` of the H2 norm, as in
        :func:`~pymorembs.reduction.gramian.frequency_weighted_gramians`).
    projected : SecondOrderSystem
        The projected (dense) system ``system.project(V)``.
    modal : ModalForm
        Its modal form as the dense Gramian code used it (for the ``kappa`` of eq. 24).
    band_hz : (float, float)
    sigma : ndarray, shape (k,)
        Eigenvalues of ``X_P + X_Q`` (= the nonzero ones of ``V (X_P + X_Q) V^T``), descending.
    h2_norm : float
        ``sqrt(trace(C V X_P V^T C^T))``, the band-limited H2 norm of the projected system.
    shifts_hz : list of float
        The shifts in the order used, Hz.
    factorizations : int
        Sparse factorizations (one per shift; an inertia-relief factorization at 0 Hz counts).
    converged : bool
        The stopping rule was met (not a size limit).
    stop : str
        ``"converged"``, ``"max_dim"``, ``"max_shifts"`` or ``"exhausted"`` (:data:`MAX_DEAD`
        shifts in a row added no direction, or no grid point is left).
    history : list of dict
        Per iteration: ``shift_hz``, ``new_factorization`` (False: more moments at the same
        shift), ``moments`` (computed at that shift so far), ``dimension``, ``h2_norm``,
        ``change`` (the quantity of the stopping rule, inf for the first), ``max_residual``
        (max of ``rho`` over the grid), ``seconds`` (elapsed).
    grid_hz, residual : ndarray, shape (n_grid,)
        The shift grid and ``rho`` on it for the final basis.
    """

    basis: np.ndarray
    x_p: np.ndarray
    x_q: np.ndarray
    projected: SecondOrderSystem
    modal: ModalForm
    band_hz: tuple[float, float]
    sigma: np.ndarray
    h2_norm: float
    shifts_hz: list[float]
    factorizations: int
    converged: bool
    stop: str
    history: list[dict[str, Any]] = field(default_factory=list)
    grid_hz: np.ndarray | None = None
    residual: np.ndarray | None = None

    @property
    def dimension(self) -> int:
        """``k``, the number of columns of ``V``."""
        return int(self.basis.shape[1])

    @property
    def iterations(self) -> int:
        """Number of shifts processed."""
        return len(self.history)

    def low_rank_factor(self, which: str = "p", rtol: float = 1e-14) -> np.ndarray:
        """``L`` (N, r) with ``V X V^T = L L^T`` for ``X = X_P`` (``"p"``) or ``X_Q`` (``"q"``).

        From the eigendecomposition ``X = U diag(lambda) U^T``: ``L = V U sqrt(lambda)`` with the
        eigenvalues above ``rtol`` times the largest (the rest are rounding).
        """
        if which not in ("p", "q"):
            raise UserError(f"low_rank_factor: which must be 'p' or 'q', got {which!r}")
        x = self.x_p if which == "p" else self.x_q
        values, vectors = np.linalg.eigh(0.5 * (x + x.T))
        keep = values > rtol * max(float(values.max(initial=0.0)), np.finfo(float).tiny)
        return self.basis @ (vectors[:, keep] * np.sqrt(values[keep]))


class _Residuals:
    """Galerkin residuals ``F - Z(s) V x(s)`` of the integrand on a frequency grid.

    Keeps ``Y = [F, K V, D V, M V]`` (column blocks appended as ``V`` grows) as ``Q R`` with
    orthonormal ``Q`` (block classical Gram-Schmidt, twice, then a QR of the rest); the residual
    ``Y c(s)`` has the norm ``||R c(s)||``.
    """

    def __init__(self, system: SecondOrderSystem, rhs: np.ndarray, groups: list[slice]) -> None:
        self.system = system
        self.rhs = rhs
        self.groups = groups
        self.scale = np.array([np.linalg.norm(rhs[:, g]) or 1.0 for g in groups])
        self.q, self.r = np.linalg.qr(rhs)
        self.segments: list[tuple[str, int, int]] = [("f", 0, rhs.shape[1])]
        self.count = 0

    def update(self, products: BlockProducts, size: int) -> None:
        """Append ``K V``, ``D V``, ``M V`` of the columns ``count:size`` of ``V``."""
        if size == self.count:
            return
        blocks = []
        for key in ("k", "d", "m"):
            columns = products.columns[key]
            if key == "d" and self.system.damping is None:
                continue
            blocks.append(columns[:, self.count : size])
            self.segments.append((key, self.count, size))
        y = np.hstack(blocks)
        # columns of unit norm: K V and M V differ by orders of magnitude
        norms = np.linalg.norm(y, axis=0)
        norms = np.where(norms > 0, norms, 1.0)
        y = y / norms
        coefficients = np.zeros((self.q.shape[1], y.shape[1]))
        for _ in range(2):
            step = self.q.T @ y
            y = y - self.q @ step
            coefficients += step
        # rank-revealing: D V is a combination of K V and M V for Rayleigh damping, and a
        # rounding-level rest must not enter Q (it would not be orthogonal to it)
        u, singular, w_t = np.linalg.svd(y, full_matrices=False)
        keep = singular > RANK_TOL
        q_new = u[:, keep]
        q_new = q_new - self.q @ (self.q.T @ q_new)
        q_new, correction = np.linalg.qr(q_new)
        r_new = correction @ (singular[keep, None] * w_t[keep])
        coefficients *= norms
        r_new = r_new * norms
        old = self.r.shape[1]
        r = np.zeros((self.r.shape[0] + r_new.shape[0], old + y.shape[1]))
        r[: self.r.shape[0], :old] = self.r
        r[: self.r.shape[0], old:] = coefficients
        r[self.r.shape[0] :, old:] = r_new
        self.q, self.r = np.hstack([self.q, q_new]), r
        self.count = size

    def relative(
        self, projected: SecondOrderSystem, rhs_v: np.ndarray, frequencies_hz: np.ndarray
    ) -> np.ndarray:
        """``rho(f)``: the largest relative residual norm of the groups at each frequency.

        ``projected`` is ``system.project(V)``, ``rhs_v = V^T F``, frequencies in Hz.
        """
        eta = 1.0 + 1j * projected.loss_factor
        m, k, d = projected.mass, projected.stiffness, projected.damping
        result = np.empty(frequencies_hz.size)
        p = self.rhs.shape[1]
        for start in range(0, frequencies_hz.size, CHUNK):
            s = 2j * np.pi * frequencies_hz[start : start + CHUNK]
            stack = (s**2)[:, None, None] * m[None] + eta * k[None]
            if d is not None:
                stack = stack + s[:, None, None] * d[None]
            x = np.linalg.solve(stack, np.broadcast_to(rhs_v, (s.size, *rhs_v.shape)))
            coefficient = {"k": np.full(s.size, -eta), "d": -s, "m": -(s**2)}
            c = np.zeros((s.size, self.r.shape[1], p), dtype=complex)
            c[:, :p, :] = np.eye(p)
            column = p
            for key, first, last in self.segments[1:]:
                width = last - first
                c[:, column : column + width] = coefficient[key][:, None, None] * x[:, first:last]
                column += width
            residual = self.r[None] @ c  # (n_s, m, p)
            norms = np.stack(
                [np.linalg.norm(residual[:, :, g], axis=(1, 2)) for g in self.groups], axis=1
            )
            result[start : start + s.size] = np.max(norms / self.scale, axis=1)
        return result


def _projected(
    system: SecondOrderSystem, v: np.ndarray, products: BlockProducts, cache: dict[str, np.ndarray]
) -> SecondOrderSystem:
    """``system.project(V)`` from the cached products ``K V``, ``M V``, ``D V``.

    ``cache`` holds the reduced matrices of the previous (leading) columns of ``V``; only the
    new rows and columns are computed.
    """

    def reduce(key: str) -> np.ndarray:
        old = cache.get(key, np.zeros((0, 0)))
        start = old.shape[0]
        block = v.T @ products.columns[key][:, start:]  # (k, k - start)
        reduced = np.zeros((v.shape[1], v.shape[1]))
        reduced[:start, :start] = old
        reduced[:start, start:] = block[:start]
        reduced[start:, :start] = block[:start].T
        reduced[start:, start:] = 0.5 * (block[start:] + block[start:].T)
        cache[key] = reduced
        return reduced

    return replace(
        system,
        mass=reduce("m"),
        stiffness=reduce("k"),
        damping=None if system.damping is None else reduce("d"),
        input_matrix=v.T @ system.input_matrix,
        output_matrix=system.output_matrix @ v,
        static_load=None,
        rigid_modes=None,  # V is elastic
        stress_matrix=None,  # the Gramians of the outputs: targeted stresses are among them
        stress_labels=(),
    )


class _Shift:
    """The second-order Krylov recurrence (paper eq. 20) at one shift: one factorization.

    ``P_0 = R(s_0) F``, ``P_1 = -R(s_0) D_0 P_0``, ``P_i = -R(s_0) (D_0 P_{i-1} + M P_{i-2})``
    with ``D_0 = 2 s_0 M + D`` (the Taylor coefficients of ``R(s) F`` about ``s_0 = i 2 pi f``).
    """

    def __init__(self, system: SecondOrderSystem, frequency_hz: float, rhs: np.ndarray) -> None:
        self.frequency_hz = frequency_hz
        self.solve = resolvent(system, frequency_hz)
        self.s = 2j * np.pi * frequency_hz
        self.mass, self.damping = system.mass, system.damping
        self.rhs = rhs
        self.last: list[np.ndarray] = []  # the last two blocks
        self.moments = 0
        self.exhausted = False

    def advance(self, count: int) -> list[np.ndarray]:
        """The next ``count`` blocks, shape (N, p') each, complex for ``f > 0`` with damping."""
        new = []
        for _ in range(count):
            if not self.last:
                block = self.solve(self.rhs)
            else:
                load = (2.0 * self.s) * (self.mass @ self.last[-1]) if self.s else 0.0
                if self.damping is not None:
                    load = load + self.damping @ self.last[-1]
                if len(self.last) == 2:
                    load = load + self.mass @ self.last[-2]
                block = -self.solve(load) if np.any(load) else np.zeros_like(self.last[-1])
            self.last = [*self.last[-1:], block]
            self.moments += 1
            new.append(block)
        return new


def rational_krylov_gramians(
    system: SecondOrderSystem,
    band_hz: Sequence[float],
    tol: float = DEFAULT_TOL,
    max_dim: int = DEFAULT_MAX_DIM,
    **keywords: Any,
) -> RationalKrylovGramians:
    """Frequency-weighted Gramians ``P_p^w``, ``Q_pv^w`` of a large sparse model, low rank.

    Galerkin projection on an adaptive second-order rational Krylov subspace (module notes).

    The arguments are checked here (:func:`check_solver_keywords`); :func:`galerkin_gramians`
    runs on them and holds the defaults of the further keywords.

    Parameters
    ----------
    system : SecondOrderSystem
        Sparse (or dense) full system with symmetric ``M``, ``D``, ``K``; damped as
        :func:`~pymorembs.reduction.gramian.frequency_weighted_gramians` requires. A free body
        (``rigid_modes``) needs ``B``, ``C`` free of rigid-body parts (Buckens frame).
    band_hz : (float, float)
        ``(f_min, f_max)`` in Hz, finite, ``0 <= f_min < f_max``.
    tol : float
        Stopping tolerance: relative change of ``trace(C P_p^w C^T)`` and of the leading
        ``sigma_i / sigma_1`` between successive shifts.
    max_dim : int
        Largest dimension ``k`` of ``V``.
    max_shifts : int
        Largest number of shifts (sparse factorizations).
    moments : int
        Blocks of the second-order Krylov recurrence per shift (1: ``R(s_j) F`` only; 2: also
        its derivative -- Hermite interpolation at every shift).
    initial_shifts_hz : sequence of float, optional
        First shifts in Hz (default ``f_min`` and ``f_max``); the stopping rule is checked only
        after all of them.
    grid_points : int
        The shift grid: ``grid_points`` log-spaced (:func:`frequency_grid`, 0 Hz added for a
        band from 0) and ``grid_points`` equidistant frequencies over the band.
    n_sigma : int, optional
        Number of leading eigenvalues in the stopping rule (default all).
    patience : int
        Consecutive iterations that must meet the tolerance.
    min_dim : int
        The iteration stops only once ``V`` has at least this many columns (e.g. the order of
        the reduced model to be taken from it). When the Gramian has converged with fewer,
        further moments are computed at the last shift (no new factorization) while they add
        directions, then new shifts.
    damping_ratio : float, optional
        As in :func:`~pymorembs.reduction.gramian.frequency_weighted_gramians` (undamped models).
    deflation_tol : float
        Directions with less than this (relative) outside ``span(V)`` are dropped.

    Returns
    -------
    RationalKrylovGramians
        ``V``, ``X_P``, ``X_Q`` and the diagnostics (shifts in Hz, factorizations, history).
    """
    if not (np.isfinite(tol) and tol > 0):
        raise UserError(f"rational-krylov: tol must be a number > 0, got {tol!r}")
    check_solver_keywords({"max_dim": max_dim, **keywords})
    return galerkin_gramians(system, band_hz, tol, max_dim, **keywords)


def check_solver_keywords(keywords: Mapping[str, Any]) -> None:
    """Check the keywords of :func:`galerkin_gramians` given in ``keywords``: the whole numbers
    of :data:`LEAST_COUNTS` and the initial shifts (Hz). The others (``n_sigma``, ``min_dim``,
    ``damping_ratio``, ``deflation_tol``) are used as given.

    Raises
    ------
    UserError
        A count that is no whole number or below its least value, or a shift that is no
        frequency >= 0.
    """
    for name, low in LEAST_COUNTS.items():
        value = keywords.get(name, low)
        if int(value) != value or value < low:
            raise UserError(f"rational-krylov: {name} must be an integer >= {low}, got {value!r}")
    if keywords.get("initial_shifts_hz") is None:
        return
    shifts = [float(f) for f in keywords["initial_shifts_hz"]]
    if not shifts or any(not (np.isfinite(f) and f >= 0) for f in shifts):
        raise UserError(f"rational-krylov: initial shifts must be frequencies >= 0 Hz: {shifts}")


def galerkin_gramians(
    system: SecondOrderSystem,
    band_hz: Sequence[float],
    tol: float,
    max_dim: int,
    max_shifts: int = DEFAULT_MAX_SHIFTS,
    moments: int = 2,
    initial_shifts_hz: Sequence[float] | None = None,
    grid_points: int = DEFAULT_GRID_POINTS,
    n_sigma: int | None = None,
    patience: int = 1,
    min_dim: int = 0,
    damping_ratio: float | None = None,
    deflation_tol: float = 1e-10,
) -> RationalKrylovGramians:
    """The iteration of :func:`rational_krylov_gramians` from checked values.

    ``tol > 0`` and ``max_dim >= 1`` are checked by the caller: by
    :func:`rational_krylov_gramians`, or as ``convergence_tolerance`` and ``first_order`` of a
    :class:`~pymorembs.methods.GramianOptions`; the other keywords by
    :func:`check_solver_keywords`. The band and what depends on the system are checked here.
    Parameters and result as in :func:`rational_krylov_gramians`.
    """
    w1, w2 = band_in_rad_s(band_hz, allow_infinite=False)
    f_min, f_max = w1 / (2.0 * np.pi), w2 / (2.0 * np.pi)
    if system.n_inputs == 0 and system.n_outputs == 0:
        raise UserError("rational-krylov: the system has neither inputs nor outputs")
    shifts = [f_min, f_max] if initial_shifts_hz is None else [float(f) for f in initial_shifts_hz]
    rigid_count = 0 if system.rigid_modes is None else system.rigid_modes.shape[1]
    max_dim = min(int(max_dim), system.order - rigid_count)

    b, c_t = system.input_matrix, system.output_matrix.T
    collocated = b.shape == c_t.shape and np.array_equal(b, c_t)
    rhs = b if collocated else np.hstack([b, c_t])
    p = b.shape[1]
    groups = [slice(0, p)] if collocated else [slice(0, p), slice(p, p + c_t.shape[1])]
    groups = [g for g in groups if g.stop > g.start]
    grid = np.unique(
        np.concatenate(
            [frequency_grid(f_min, f_max, grid_points), np.linspace(f_min, f_max, grid_points)]
        )
    )
    mass = system.mass
    basis = OrthonormalBasis(system.order, deflation_tol)
    offset = 0
    if system.rigid_modes is not None:
        # free body: the elastic dofs are the Euclidean complement of span(M R) (R^T M x = 0);
        # with these directions first in the basis, every later direction is elastic to working
        # precision, also those that are amplified rounding of nearly dependent solutions
        offset = basis.add(np.asarray(mass @ system.rigid_modes)).shape[1]
    products = BlockProducts(system)
    residuals = _Residuals(system, rhs, groups)
    history: list[dict[str, Any]] = []
    used: list[float] = []
    dead: list[float] = []  # shifts that added no direction
    reduced_cache: dict[str, np.ndarray] = {}
    tick = time.perf_counter()
    previous: tuple[float, np.ndarray] | None = None
    calm = 0
    stop = "max_shifts"
    state = None
    current: _Shift | None = None
    pad = False  # extend the recurrence at the current shift instead of a new factorization
    while shifts or pad:
        if pad:
            f = current.frequency_hz
        else:
            f = shifts.pop(0)
            used.append(f)
            current = _Shift(system, f, rhs)
        before = basis.size
        for block in current.advance(int(moments)):
            parts = [block.real, block.imag] if np.iscomplexobj(block) else [block]
            for part in parts:
                if basis.size - offset < max_dim:
                    basis.add(part, limit=max_dim - basis.size + offset, reference=1.0)
        if basis.size == before:  # nothing new here: no more moments at this shift either
            current.exhausted = True
            if not pad:
                dead.append(f)
        v = basis.matrix[:, offset:]
        if v.shape[1] == 0:
            raise UserError("rational-krylov: the inputs and outputs are zero on the elastic dofs")
        products.update(v)
        residuals.update(products, v.shape[1])
        projected = _projected(system, v, products, reduced_cache)
        x_p, x_q, modal = band_gramians(projected, w1, w2, damping_ratio)
        sigma = np.clip(np.linalg.eigvalsh(x_p + x_q)[::-1], 0.0, None)
        c_v = projected.output_matrix
        trace = max(float(np.trace(c_v @ x_p @ c_v.T)), 0.0)
        change = np.inf
        if previous is not None:
            change = _change(previous, (trace, sigma), n_sigma)
        previous = (trace, sigma)
        rho = residuals.relative(projected, v.T @ rhs, grid)
        history.append(
            {
                "shift_hz": f,
                "new_factorization": not pad,
                "moments": current.moments,
                "dimension": int(v.shape[1]),
                "h2_norm": float(np.sqrt(trace)),
                "change": float(change),
                "max_residual": float(np.max(rho)),
                "seconds": time.perf_counter() - tick,
            }
        )
        state = (v, x_p, x_q, projected, modal, sigma, trace, rho)
        pad = False
        if shifts:  # the initial shifts first
            continue
        calm = calm + 1 if change <= tol else 0
        if calm >= patience and v.shape[1] >= min_dim:
            stop = "converged"
            break
        if v.shape[1] >= max_dim:
            stop = "max_dim"
            break
        if calm >= patience and not current.exhausted:
            # converged, but fewer than min_dim directions: more moments at the current shift
            # (no new factorization) as long as they add directions
            pad = True
            continue
        if len(used) >= max_shifts:
            stop = "max_shifts"
            break
        if len(dead) >= MAX_DEAD and dead[-MAX_DEAD:] == used[-MAX_DEAD:]:
            stop = "exhausted"  # the space reachable from the band is (numerically) complete
            break
        free = ~np.isin(grid, used)
        for f_dead in dead:  # the residual there is at its rounding floor: look elsewhere
            free &= np.abs(grid - f_dead) > DEAD_RADIUS * (f_max - f_min) + 5 * DEAD_RADIUS * f_dead
        if not np.any(free):
            stop = "exhausted"
            break
        shifts.append(float(grid[free][int(np.argmax(rho[free]))]))

    v, x_p, x_q, projected, modal, sigma, trace, rho = state
    return RationalKrylovGramians(
        basis=v,
        x_p=x_p,
        x_q=x_q,
        projected=projected,
        modal=modal,
        band_hz=(f_min, f_max),
        sigma=sigma,
        h2_norm=float(np.sqrt(trace)),
        shifts_hz=used,
        factorizations=len(used),
        converged=stop == "converged",
        stop=stop,
        history=history,
        grid_hz=grid,
        residual=rho,
    )


def _change(
    previous: tuple[float, np.ndarray], current: tuple[float, np.ndarray], n_sigma: int | None
) -> float:
    """``max(|Delta trace| / trace, max_i |Delta sigma_i| / sigma_1)`` (module notes)."""
    (trace_0, sigma_0), (trace_1, sigma_1) = previous, current
    size = max(sigma_0.size, sigma_1.size)
    a, b = np.zeros(size), np.zeros(size)
    a[: sigma_0.size], b[: sigma_1.size] = sigma_0, sigma_1
    if n_sigma is not None:
        a, b = a[:n_sigma], b[:n_sigma]
    scale = max(float(sigma_1[0]) if sigma_1.size else 0.0, np.finfo(float).tiny)
    trace_change = abs(trace_1 - trace_0) / max(trace_1, np.finfo(float).tiny)
    return max(trace_change, float(np.max(np.abs(b - a), initial=0.0)) / scale)


def rational_gramian_reduction(
    system: SecondOrderSystem,
    band_hz: Sequence[float],
    order: int | None = None,
    tolerance: float | None = None,
    tol: float | None = None,
    max_dim: int = DEFAULT_MAX_DIM,
    damping_ratio: float | None = None,
    kappa_points: int = KAPPA_POINTS,
    **options: Any,
) -> Projection:
    """Gramian reduction of a large model with rational-Krylov Gramians (no two-step detour).

    The Gramians come from :func:`rational_krylov_gramians`; the projection is then built
    exactly as :func:`~pymorembs.reduction.gramian.gramian_reduction` builds it: ``V`` spans the
    dominant eigenvectors of ``V_k (X_P + X_Q) V_k^T`` (``V_k`` the Krylov basis), the order from
    ``order`` or from the indicator ``sigma_{n+1} / sigma_1 <= tolerance`` of eq. 24.

    Parameters
    ----------
    system : SecondOrderSystem
        Large sparse system (any size; also dense).
    band_hz : (float, float)
        ``(f_min, f_max)`` in Hz, finite.
    order, tolerance :
        As in :func:`~pymorembs.reduction.gramian.gramian_reduction`.
    tol : float, optional
        Stopping tolerance of the Gramian iteration. Default ``min(1e-8, 1e-2 tolerance)``:
        the eigenvalues that decide the order are then converged well below the tolerance.
    max_dim : int
        Largest Krylov dimension.
    damping_ratio : float, optional
        For undamped models.
    kappa_points : int
        As in :func:`~pymorembs.reduction.gramian.gramian_reduction` (sampled on the projected
        system).
    **options :
        Further keywords of :func:`rational_krylov_gramians` (``max_shifts``, ``moments``,
        ``grid_points``, ``n_sigma``, ``patience``, ``initial_shifts_hz``).

    Returns
    -------
    Projection
        ``V = W`` orthonormal, method ``"gramian"``. ``parameters`` as in ``gramian_reduction``
        (``sigma``, ``indicator``, ``neglected_sum``, ``h2_norm``, ``a_priori_bound``, ``kappa``,
        ``kappa_T``: all of the projected system, see the module notes for what that means)
        plus ``gramian_solver = "rational-krylov"``, ``krylov_dimension``, ``shifts_hz``,
        ``factorizations``, ``iterations``, ``converged``, ``stop``, ``solver_tol``,
        ``gramian_change`` (the last value of the stopping quantity), ``max_residual`` (the
        largest relative Galerkin residual of the integrand over the shift grid) and
        ``history``. ``error_bound`` as in ``gramian_reduction``.

    Raises
    ------
    OptionError
        A bad ``order``, ``tolerance``, ``tol`` (its ``convergence_tolerance``) or ``max_dim``
        (its ``first_order``), checked by :class:`~pymorembs.methods.GramianOptions` with its
        message.
    UserError
        A bad band or further solver keyword (:func:`check_solver_keywords`), or an order above
        ``max_dim``.
    """
    checked = GramianOptions(
        order=order,
        tolerance=tolerance,
        first_stage="rational-krylov",
        first_order=max_dim,
        convergence_tolerance=tol,
    )
    check_solver_keywords(options)
    return _rational_projection(
        system,
        band_hz,
        checked.order,
        checked.tolerance,
        checked.convergence_tolerance,
        checked.first_order,
        damping_ratio,
        kappa_points,
        **options,
    )


def rational_gramian_from_options(
    system: SecondOrderSystem, options: GramianOptions, band_hz: tuple[float, float]
) -> Projection:
    """The ``gramian`` method with ``first_stage = "rational-krylov"`` on its checked options
    (``first_order``: the largest Krylov dimension, ``convergence_tolerance``: ``tol``)."""
    max_dim = DEFAULT_MAX_DIM if options.first_order is None else options.first_order
    return _rational_projection(
        system, band_hz, options.order, options.tolerance, options.convergence_tolerance, max_dim
    )


def _rational_projection(
    system: SecondOrderSystem,
    band_hz: Sequence[float],
    order: int | None,
    tolerance: float | None,
    tol: float | None,
    max_dim: int,
    damping_ratio: float | None = None,
    kappa_points: int = KAPPA_POINTS,
    **options: Any,
) -> Projection:
    """:func:`rational_gramian_reduction` with ``order``, ``tolerance``, ``tol``, ``max_dim`` and
    the solver keywords checked."""
    w1, w2 = band_in_rad_s(band_hz, allow_infinite=False)
    if tol is None:
        tol = DEFAULT_TOL if tolerance is None else min(DEFAULT_TOL, 1e-2 * tolerance)
    if order is not None and order > min(max_dim, system.order):
        raise UserError(f"order {order} exceeds max_dim = {min(max_dim, system.order)}")
    result = galerkin_gramians(
        system.targeted(),  # the space holds the targeted stresses' Gramian too
        band_hz,
        tol=tol,
        max_dim=max_dim,
        min_dim=0 if order is None else int(order),
        damping_ratio=damping_ratio,
        **options,
    )
    last = result.history[-1]
    extra = {}
    if order is not None and order > result.dimension:  # the Krylov space is exhausted
        extra["order_capped_by_krylov_dimension"] = result.dimension
        order = result.dimension
    projected, gramians, stress = result.projected, (result.x_p, result.x_q, result.modal), None
    if system.targeted() is not system:
        # the blocks apart again: the ports' Gramians and the stresses' (unweighted) Q_s
        rows = system.n_outputs
        projected = replace(
            projected,
            output_matrix=projected.output_matrix[:rows],
            output_labels=system.output_labels,
            stress_matrix=projected.output_matrix[rows:] / system.stress_weight,
            stress_labels=system.stress_labels,
        )
        gramians = band_gramians(projected, w1, w2, damping_ratio)
        stress = stress_gramian(projected, gramians[2], w1, w2)
    return projection_from_gramians(
        projected,
        result.basis,
        gramians,
        (w1, w2),
        order,
        tolerance,
        kappa_points,
        method="gramian",
        parameters={
            "gramian_solver": "rational-krylov",
            "two_step": False,
            "medium_order": None,
            "krylov_dimension": result.dimension,
            "shifts_hz": result.shifts_hz,
            "factorizations": result.factorizations,
            "iterations": result.iterations,
            "converged": result.converged,
            "stop": result.stop,
            "solver_tol": tol,
            "gramian_change": last["change"],
            "max_residual": last["max_residual"],
            "history": result.history,
            **extra,
        },
        stress=stress,
    )
