"""Linear time integration of full and reduced models (paper section 5.1, Fig. 12).

The paper checks its reduced models in the time domain: the rack is clamped to the surroundings
at node 2 and loaded at node 1 by a step ``F = -100 (1, 1, 1) N`` and by a harmonic force
``F = -100 sin(2 pi 10 t) (1, 1, 1) N``; the displacement of node 1 of the reduced models is
compared with that of the full FE model. Here both are integrated by the same implicit scheme
with the same fixed step, so their difference is the reduction error alone.

Integrator: generalized-alpha (Chung & Hulbert 1993) for ``M q'' + D q' + K q = B u(t)``,
``y = C q``, with the user's high-frequency spectral radius ``rho_inf`` (1: Newmark average
acceleration, the trapezoidal rule; 0: asymptotic annihilation). It is unconditionally stable and
second-order accurate for every ``rho_inf`` in [0, 1]. With a fixed step the effective matrix
``(1 - alpha_m) M + (1 - alpha_f) gamma h D + (1 - alpha_f) beta h^2 K`` is factorized once:
sparse LU (SuperLU) for full models, a dense Cholesky or LU factorization for reduced ones.
Several load cases are right-hand sides of one solve per step. No dense ``n x n`` matrix of a
full model is ever formed.

Default ``rho_inf = 0.8`` (``DEFAULT_RHO_INF``), from measurements on the rack-beams model clamped
at node 2 (3942 dofs, eigenfrequencies up to 3e7 Hz) and a 34-dimensional Krylov model of it
(stiff directions at 3e5-7e5 Hz that hold part of the static flexibility), ``h = 5e-5 s``:

* With ``rho_inf = 1`` every undamped mode keeps the spectral radius 1, however far above the
  Nyquist frequency ``1 / (2 h) = 10 kHz`` it lies: a step load leaves such content ringing at
  a period near ``2 h`` in both models, and differently in each, since their stiff directions
  differ. With mass-proportional damping only (``beta = 0``) this shows in the axial (z)
  displacement of node 1, 3000x smaller than the lateral one: full and reduced differ there
  by 2.2e-4 of its peak for ``rho_inf = 1``, 2.7e-5 for 0.9, 4.0e-6 for 0.8, 2.1e-7 for 0.5.
  Stiffness-proportional damping removes it physically (then 6e-8 for every ``rho_inf``).
* ``rho_inf = 0.8`` damps by 1.4 % per step at the Nyquist frequency and by 13-18 % per step at
  1e5-1e6 Hz, while its algorithmic damping ratio is 2e-5 at 1000 Hz and 1.5e-9 at 41 Hz and
  its period error is that of the trapezoidal rule: against the exact modal solution the error
  is 1.2e-4 (step) and 4.8e-5 (harmonic), as for ``rho_inf = 1``; ``rho_inf = 0.5`` has
  1.4x, ``rho_inf = 0`` 5x that error.

For the comparison itself the choice matters little: the largest deviation over all components,
relative to the peak displacement, is at most 1e-6 (``beta = 0``) or 3e-8 for ``rho_inf`` in
[0.5, 1].
"""

from __future__ import annotations

import time
import warnings
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Literal

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp

from pymorembs.analysis.stress_history import StressComparison, StressHistory, compare_histories
from pymorembs.body import ElasticBody
from pymorembs.display import one_line, port_labels
from pymorembs.errors import NumericalError, UserError
from pymorembs.linalg.backends import factorize
from pymorembs.linalg.mass_split import mass_split
from pymorembs.preparation import Frame, Port, PreparedModel, prepare
from pymorembs.progress import Progress
from pymorembs.system import SecondOrderSystem

#: Default time step, s: 20 steps per period of 1000 Hz, the top of the paper's band (period
#: error of the scheme ~(omega h)^2 / 12 = 0.8 % there, 1.5e-3 % at 41 Hz); 0.7 ms per step
#: for the 3942-dof clamped rack-beams model.
DEFAULT_STEP_S = 5e-5
#: Default duration, s: two periods of the 10 Hz harmonic load, eight of the first mode.
DEFAULT_DURATION_S = 0.2
#: Default high-frequency spectral radius (see the module docstring).
DEFAULT_RHO_INF = 0.8
#: Directions of the load port and the output port (the node's translations).
TRANSLATIONS = "ux uy uz"


# ---------------------------------------------------------------------------------- load cases
@dataclass(frozen=True, eq=False)
class LoadCase:
    """A force history on the inputs of a model (the three translations of the load node).

    Parameters
    ----------
    name : str
        Label (e.g. ``"step"``).
    kind : {"step", "harmonic"}
        ``"step"``: ``f(t) = F`` for ``t > 0`` and ``f(0) = 0``; ``"harmonic"``:
        ``f(t) = F sin(2 pi frequency_hz t)``. Both vanish at ``t = 0``: the model starts at rest
        (zero displacement and velocity). The step jumps to ``F`` right after; its initial
        acceleration is ``M^-1 B F`` (see :func:`integrate`).
    force_n : ndarray, shape (p,)
        Amplitude ``F``, N: along x, y, z of the load node (``p = 3``) for the clamped models of
        this module; in general one component per input of the system.
    frequency_hz : float
        Frequency of the harmonic load, Hz (not rad/s).
    """

    name: str
    kind: Literal["step", "harmonic"]
    force_n: np.ndarray
    frequency_hz: float = 10.0

    def __post_init__(self) -> None:
        if self.kind not in ("step", "harmonic"):
            raise UserError(f"load case {self.name!r}: kind must be 'step' or 'harmonic'")
        force = np.asarray(self.force_n, dtype=float).ravel()
        if not np.all(np.isfinite(force)):
            raise UserError(f"load case {self.name!r}: the force must be finite")
        if not (np.isfinite(self.frequency_hz) and self.frequency_hz >= 0):
            raise UserError(f"load case {self.name!r}: frequency must be a number >= 0 Hz")
        object.__setattr__(self, "force_n", force)

    def initial_force(self) -> np.ndarray:
        """Force right after the start, ``u(0+)``, shape (p,), N: ``F`` for a step, else 0."""
        return self.force_n.copy() if self.kind == "step" else np.zeros_like(self.force_n)

    def force(self, t: np.ndarray) -> np.ndarray:
        """Force at the times ``t`` (s, shape (n_t,)), shape (n_t, p), N."""
        t = np.atleast_1d(np.asarray(t, dtype=float))
        if self.kind == "step":
            return np.where(t[:, None] > 0.0, self.force_n[None, :], 0.0)
        return np.sin(2.0 * np.pi * self.frequency_hz * t)[:, None] * self.force_n[None, :]


def paper_load_cases() -> list[LoadCase]:
    """The two load cases of paper section 5.1 at node 1: step and 10 Hz harmonic, 100 N."""
    force = -100.0 * np.ones(3)
    return [
        LoadCase("step", "step", force),
        LoadCase("harmonic", "harmonic", force, frequency_hz=10.0),
    ]


# ----------------------------------------------------------------------------------- results
@dataclass(frozen=True, eq=False)
class TimeResponse:
    """Outputs of a time integration.

    Attributes
    ----------
    times : ndarray, shape (n_t,)
        ``t_k = k h``, s, from 0.
    outputs : dict of case name -> ndarray, shape (n_t, r)
        Output ``y = C q`` per load case (for the clamped rack: ux, uy, uz of node 1, m).
    wall_time_s : float
        Wall time of the integration including the factorization, s.
    factorization_s : float
        Wall time of the factorization alone, s.
    order : int
        Number of coordinates of the integrated model.
    rho_inf : float
        Spectral radius used.
    output_labels : tuple of str
    stresses : dict of case name -> StressHistory
        The stress history at the hot spots per load case (empty: no stress rows were given to
        :func:`simulate`).
    """

    times: np.ndarray
    outputs: dict[str, np.ndarray]
    wall_time_s: float
    factorization_s: float
    order: int
    rho_inf: float
    output_labels: tuple[str, ...] = field(default=())
    stresses: dict[str, StressHistory] = field(default_factory=dict)

    @property
    def step_s(self) -> float:
        return float(self.times[1] - self.times[0]) if self.times.size > 1 else 0.0

    def __repr__(self) -> str:
        end = float(self.times[-1]) if self.times.size else 0.0
        rows = [("cases", " ".join(self.outputs) or "none"),
                ("steps", f"{self.times.size} x {self.step_s:g} s to {end:g} s"),
                ("outputs", port_labels(self.output_labels)),
                ("order", str(self.order))]  # fmt: skip
        return one_line("TimeResponse", rows)


# --------------------------------------------------------------------------------- integrator
@dataclass(frozen=True)
class GeneralizedAlpha:
    """Parameters of the generalized-alpha method (Chung & Hulbert 1993).

    From the spectral radius at infinite frequency ``rho_inf`` in [0, 1]:
    ``alpha_m = (2 rho - 1) / (rho + 1)``, ``alpha_f = rho / (rho + 1)``,
    ``gamma = 1/2 - alpha_m + alpha_f``, ``beta = (1 - alpha_m + alpha_f)^2 / 4``;
    second-order accurate, unconditionally stable, minimal low-frequency dissipation for the
    given high-frequency dissipation. ``rho_inf = 1`` gives ``alpha_m = alpha_f = 1/2``,
    ``beta = 1/4``, ``gamma = 1/2``: Newmark's average acceleration method, i.e. the trapezoidal
    rule for ``(q, v)`` (with the load of :func:`integrate` sampled at mid-step).
    """

    rho_inf: float

    def __post_init__(self) -> None:
        if not 0.0 <= self.rho_inf <= 1.0:
            raise UserError(f"rho_inf must lie in [0, 1], got {self.rho_inf!r}")

    @property
    def alpha_m(self) -> float:
        return (2.0 * self.rho_inf - 1.0) / (self.rho_inf + 1.0)

    @property
    def alpha_f(self) -> float:
        return self.rho_inf / (self.rho_inf + 1.0)

    @property
    def gamma(self) -> float:
        return 0.5 - self.alpha_m + self.alpha_f

    @property
    def beta(self) -> float:
        return 0.25 * (1.0 - self.alpha_m + self.alpha_f) ** 2


def integrate(
    system: SecondOrderSystem,
    load_cases: Sequence[LoadCase],
    step_s: float,
    n_steps: int,
    rho_inf: float = DEFAULT_RHO_INF,
    observed: sp.spmatrix | np.ndarray | None = None,
) -> tuple[np.ndarray, float]:
    """Generalized-alpha integration from rest of ``M q'' + D q' + K q = B u(t)``, ``y = C q``.

    Each step solves the balance at the intermediate time ``t_{n+1-alpha_f} = t_n +
    (1 - alpha_f) h`` (Chung & Hulbert 1993),

        (1 - alpha_m) M a_{n+1} + alpha_m M a_n + D v_{n+1-alpha_f} + K q_{n+1-alpha_f}
            = B u(t_{n+1-alpha_f}),

    with ``x_{n+1-alpha_f} = (1 - alpha_f) x_{n+1} + alpha_f x_n`` and Newmark's updates
    ``q_{n+1} = q_n + h v_n + h^2 ((1/2 - beta) a_n + beta a_{n+1})``,
    ``v_{n+1} = v_n + h ((1 - gamma) a_n + gamma a_{n+1})``, for the acceleration ``a_{n+1}``.

    The model starts at rest, ``q_0 = v_0 = 0``. The load is sampled inside the steps, never at
    ``t = 0`` itself, so a load switched on at ``t = 0+`` acts over the whole first step. The
    initial acceleration is that right after the switch-on, ``a_0 = M^{-1} B u(0+)``: one solve
    with ``M``, only when some ``u(0+)`` is non-zero (a step). ``a_0 = 0`` instead would cost one
    order of accuracy for ``rho_inf < 1`` (on a single oscillator the observed order drops to
    1.0 for ``rho_inf = 0.9`` and 0.5); for ``rho_inf = 1`` ``a_0`` drops out.

    Parameters
    ----------
    system : SecondOrderSystem
        Sparse full or dense reduced system with ``p`` inputs and ``r`` outputs. A structural loss
        factor is a frequency-domain model only: :class:`UserError`.
    load_cases : sequence of LoadCase
        Their forces (``p`` components each) are columns of one right-hand side block.
    step_s : float
        Time step ``h``, s.
    n_steps : int
        Number of steps.
    rho_inf : float
        Spectral radius at infinite frequency, in [0, 1].
    observed : sparse matrix or ndarray, shape (r_o, n), optional
        Further output rows applied to ``q`` at every step after ``C`` (e.g. the stress rows
        ``C_sigma`` at hot spots, sparse for a full model: no dense ``r_o x n`` block is formed).

    Returns
    -------
    outputs : ndarray, shape (n_steps + 1, r + r_o, n_cases)
        ``y(t_k)`` at ``t_k = k h`` (the ``r`` outputs, then the ``r_o`` observed rows);
        ``y(0) = 0``.
    factorization_s : float
        Wall time of the factorization(s), s.
    """
    if system.loss_factor:
        raise UserError(
            "the system has a structural loss factor (a modal damping ratio), which is a "
            "frequency-domain model only; use Rayleigh damping or the reduced model's viscous "
            "damping matrix (ReducedModel.damping_matrix)"
        )
    if not (np.isfinite(step_s) and step_s > 0):
        raise UserError(f"time step must be a positive number of seconds, got {step_s!r}")
    if n_steps < 1:
        raise UserError(f"at least one time step is needed, got {n_steps}")
    if not load_cases:
        raise UserError("no load case given")
    if observed is not None and observed.shape[1] != system.order:
        raise UserError(
            f"the observed rows have {observed.shape[1]} columns, the model {system.order} "
            "coordinates"
        )
    for case in load_cases:
        if case.force_n.size != system.n_inputs:
            raise UserError(
                f"load case {case.name!r} has {case.force_n.size} force components, the model "
                f"has {system.n_inputs} inputs"
            )
    scheme = GeneralizedAlpha(rho_inf)
    am, af, beta, gamma, h = scheme.alpha_m, scheme.alpha_f, scheme.beta, scheme.gamma, step_s
    sample = h * (np.arange(n_steps) + (1.0 - af))  # t_{n+1-alpha_f}, n = 0 .. n_steps - 1
    loads = np.stack([case.force(sample) for case in load_cases], axis=-1)  # (n_steps, p, cases)
    start = np.column_stack([case.initial_force() for case in load_cases])  # (p, cases)

    # effective matrix divided by (1 - alpha_f) beta h^2, so that K keeps the coefficient 1
    scale = (1.0 - af) * beta * h * h
    tick = time.perf_counter()
    solve = _factorize(system, c_d=(1.0 - af) * gamma * h / scale, c_m=(1.0 - am) / scale)
    a = _initial_acceleration(system, start)
    factorization_s = time.perf_counter() - tick

    # the right-hand side needs K, D and M times three blocks: one product with the stacked
    # operator [K, D, M] of shape (n, 3 n) per step. The matrices are not scaled: rounding the
    # entries of K would spoil K q for smooth q, which cancels to ~1/cond(K) of |K| |q|.
    n_dof, n_cases = system.order, len(load_cases)
    blocks = [x for x in (system.stiffness, system.damping, system.mass) if x is not None]
    if system.is_sparse:
        stacked = sp.hstack(blocks, format="csr")
    else:
        stacked = np.hstack([np.asarray(x) for x in blocks])
    damped = len(blocks) == 3
    b, c = system.input_matrix, system.output_matrix
    w = np.zeros((stacked.shape[1], n_cases))  # q, v at t_{n+1-alpha_f}, alpha_m a_n
    q = np.zeros_like(a)
    v = np.zeros_like(a)
    r = c.shape[0]
    out = np.zeros((n_steps + 1, r + (0 if observed is None else observed.shape[0]), n_cases))
    c_qa, c_va, c_a, c_v = h * h * (0.5 - beta), h * (1.0 - gamma), beta * h * h, gamma * h
    label = f"time integration ({'full' if system.is_sparse else 'reduced'}, n = {n_dof})"
    with Progress(label, total=n_steps, unit="step") as bar:  # drawn every ~1 % of the steps
        for n in range(n_steps):
            dq = h * v + c_qa * a  # Newmark predictors minus the old state
            dv = c_va * a
            w[:n_dof] = q + (1.0 - af) * dq
            if damped:
                w[n_dof : 2 * n_dof] = v + (1.0 - af) * dv
            w[-n_dof:] = am * a
            a = solve(b @ loads[n] - stacked @ w) / scale
            q += dq + c_a * a
            v += dv + c_v * a
            out[n + 1, :r] = c @ q
            if observed is not None:
                out[n + 1, r:] = observed @ q
            bar.update()
    return out, factorization_s


def _factorize(system: SecondOrderSystem, c_d: float, c_m: float) -> Callable:
    """Solver of ``(K + c_d D + c_m M) x = rhs``, factorized once.

    Sparse: the fastest backend of :mod:`pymorembs.linalg.backends` (PARDISO when installed,
    else SuperLU with the symmetric settings of :mod:`pymorembs.linalg.factorization`), without
    the iterative refinement of :class:`~pymorembs.linalg.factorization.Factorization`: the
    shifted matrix is far better conditioned than ``K`` (``c_m ~ 4 / h^2`` lifts every
    eigenvalue of the pencil to at least ``(2 / h)^2``), and on rack-beams refinement changes the
    solution by 1e-13 but takes 2 ms per solve instead of 0.35 ms.
    Dense: Cholesky when the matrix is symmetric positive definite, else LU.
    """
    m, d, k = system.mass, system.damping, system.stiffness
    if system.is_sparse:
        matrix = k + c_m * m
        if d is not None:
            matrix = matrix + c_d * d
        try:
            factor = factorize(sp.csr_matrix(matrix), symmetric=True)
        except NumericalError as exc:
            raise NumericalError(f"the effective matrix of the time step: {exc}") from None
        return factor.solve
    matrix = np.asarray(k) + c_m * np.asarray(m)
    if d is not None:
        matrix = matrix + c_d * np.asarray(d)
    # LAPACK's triangular solves directly: the SciPy wrappers cost more than the solve itself
    # at the size of a reduced model (~10 us per step)
    if np.array_equal(matrix, matrix.T):
        try:
            factor, lower = sla.cho_factor(matrix, check_finite=False)
        except np.linalg.LinAlgError:
            pass
        else:
            (potrs,) = sla.get_lapack_funcs(("potrs",), (factor,))
            return lambda rhs: potrs(factor, rhs, lower=lower)[0]
    factor, pivots = sla.lu_factor(matrix, check_finite=False)
    (getrs,) = sla.get_lapack_funcs(("getrs",), (factor,))
    return lambda rhs: getrs(factor, pivots, rhs)[0]


def _initial_acceleration(system: SecondOrderSystem, start: np.ndarray) -> np.ndarray:
    """``a_0 = M^-1 B u(0+)`` at rest, shape (n, n_cases); no solve when ``u(0+) = 0``.

    A singular mass matrix is split into its massive and massless directions
    (:mod:`pymorembs.linalg.mass_split`): the massive part of ``a_0`` solves
    ``B a_m = Q_m^T B u(0+)``, the massless part is 0 (a massless direction has no inertia; the
    first step brings it into static equilibrium). A step load on massless directions makes
    their displacement jump at ``t = 0``, which a model starting at rest cannot follow exactly:
    that is warned about.
    """
    a = np.zeros((system.order, start.shape[1]))
    if not np.any(start):
        return a
    rhs = system.input_matrix @ start
    split = mass_split(system.mass)
    if split.singular:
        loaded = np.linalg.norm(split.massless.T @ rhs) > 1e-12 * np.linalg.norm(rhs)
        if loaded:
            warnings.warn(
                f"the load jumps at t = 0 on some of the {split.n_massless} massless directions: "
                "their displacement jumps too, which the integration from rest follows only "
                "after its first steps",
                stacklevel=3,
            )
        reduced = split.massive.T @ rhs
        solve = factorize(sp.csr_matrix(split.mass), symmetric=True).solve
        a[:] = split.massive @ solve(reduced)
        return a
    try:
        if system.is_sparse:
            a[:] = factorize(sp.csr_matrix(system.mass), symmetric=True).solve(rhs)
        else:
            a[:] = sla.solve(system.mass, rhs, assume_a="sym")
    except (NumericalError, np.linalg.LinAlgError) as exc:
        raise NumericalError(f"the initial acceleration M^-1 B u(0+): {exc}") from None
    return a


def simulate(
    system: SecondOrderSystem,
    load_cases: Sequence[LoadCase],
    duration_s: float = DEFAULT_DURATION_S,
    step_s: float = DEFAULT_STEP_S,
    rho_inf: float = DEFAULT_RHO_INF,
    stress_rows: sp.spmatrix | np.ndarray | None = None,
    hot_spots: Sequence[str] = (),
) -> TimeResponse:
    """Response from rest of a (clamped) model to load cases on its inputs.

    ``n = round(duration_s / step_s)`` steps of the generalized-alpha method
    (:func:`integrate`); all load cases are integrated together.

    Parameters
    ----------
    system : SecondOrderSystem
        With three inputs (forces x, y, z at the load node, N) and its outputs (e.g. the
        displacements of that node, m), such as :func:`clamped_full_system` or
        :func:`clamped_reduced_system` return. A constant load from constraint offsets
        (``static_load``) is not applied: the response is that to the load cases alone.
    load_cases : sequence of LoadCase
        Integrated together, as right-hand sides of one solve per step.
    duration_s, step_s : float
        End time and fixed step, s (defaults: 0.2 s and 5e-5 s).
    rho_inf : float
        Spectral radius of the generalized-alpha method at infinite frequency (default 0.8).
    stress_rows : sparse matrix or ndarray, shape (6 n_points, order), optional
        The stress at hot spots from the coordinates of ``system``: ``C_sigma T`` (sparse) for
        the full model (:func:`full_stress_rows`), ``C_sigma V`` (dense, small) for a reduced
        one; rows point-major, components xx, yy, zz, xy, xz, yz
        (:class:`pymorembs.stress.StressOperator`). The response then has
        :attr:`TimeResponse.stresses`.
    hot_spots : sequence of str
        The hot spots' labels (``n_points``), e.g.
        :func:`~pymorembs.analysis.stress_history.hot_spot_labels` of the operator.

    Returns
    -------
    TimeResponse
    """
    if not load_cases:
        raise UserError("no load case given")
    names = [case.name for case in load_cases]
    if len(set(names)) != len(names):
        raise UserError(f"load case names repeat: {names}")
    if not (np.isfinite(duration_s) and duration_s > 0):
        raise UserError(f"duration must be a positive number of seconds, got {duration_s!r}")
    if not (np.isfinite(step_s) and 0 < step_s <= duration_s):
        raise UserError(f"time step must be a number of seconds in (0, duration], got {step_s!r}")
    n_points = len(hot_spots)
    if stress_rows is not None and stress_rows.shape[0] != 6 * n_points:
        raise UserError(
            f"{stress_rows.shape[0]} stress rows for {n_points} hot spots (six components each)"
        )
    n_steps = round(duration_s / step_s)
    tick = time.perf_counter()
    out, factorization_s = integrate(system, load_cases, step_s, n_steps, rho_inf, stress_rows)
    wall = time.perf_counter() - tick
    times = step_s * np.arange(n_steps + 1)
    r = system.n_outputs
    stresses = {}
    if stress_rows is not None:
        stresses = {name: StressHistory(times, out[:, r:, j], tuple(hot_spots))
                    for j, name in enumerate(names)}  # fmt: skip
    return TimeResponse(
        times=times,
        outputs={name: out[:, :r, j] for j, name in enumerate(names)},
        wall_time_s=wall,
        factorization_s=factorization_s,
        order=system.order,
        rho_inf=rho_inf,
        output_labels=system.output_labels,
        stresses=stresses,
    )


def compare(full: TimeResponse, reduced: TimeResponse) -> dict[str, object]:
    """Deviation and speed-up of a reduced model's response against the full model's.

    Returns
    -------
    dict
        ``max_rel_deviation``: dict case -> ``max_t,i |y_red,i(t) - y_full,i(t)| /
        max_t,i |y_full,i(t)|`` (over time and output components); ``worst_rel_deviation``: the
        largest of these; ``speedup``: full wall time / reduced wall time (each including its
        factorization); ``full_wall_time_s``, ``reduced_wall_time_s``.
    """
    if full.times.shape != reduced.times.shape or not np.allclose(full.times, reduced.times):
        raise UserError("the responses to compare have different time grids")
    missing = sorted(set(full.outputs) - set(reduced.outputs))
    if missing:
        raise UserError(f"the reduced response lacks the load case(s) {missing}")
    deviation = {}
    for name, y_full in full.outputs.items():
        y_red = reduced.outputs[name]
        if y_red.shape != y_full.shape:
            raise UserError(f"load case {name!r}: outputs of shapes {y_full.shape}, {y_red.shape}")
        peak, worst = float(np.abs(y_full).max()), float(np.abs(y_red - y_full).max())
        deviation[name] = worst / peak if peak > 0 else (0.0 if worst == 0 else np.inf)
    return {
        "max_rel_deviation": deviation,
        "worst_rel_deviation": max(deviation.values()),
        "speedup": full.wall_time_s / reduced.wall_time_s,
        "full_wall_time_s": full.wall_time_s,
        "reduced_wall_time_s": reduced.wall_time_s,
    }


def compare_stresses(full: TimeResponse, reduced: TimeResponse) -> dict[str, StressComparison]:
    """The stress history of a reduced model against the full model's, per load case.

    Both responses must carry :attr:`TimeResponse.stresses` at the same hot spots (see
    :func:`~pymorembs.analysis.stress_history.compare_histories` for the figures).
    """
    if not full.stresses or not reduced.stresses:
        raise UserError("the responses to compare carry no stress history (no stress rows)")
    missing = sorted(set(full.stresses) - set(reduced.stresses))
    if missing:
        raise UserError(f"the reduced response lacks the stresses of load case(s) {missing}")
    return {name: compare_histories(reduced.stresses[name], history)
            for name, history in full.stresses.items()}  # fmt: skip


# ------------------------------------------------------------------------------------- models
def clamped_full_model(body: ElasticBody, clamp_node: int, load_node: int) -> PreparedModel:
    """The prepared model behind :func:`clamped_full_system` (its ``system`` is that system).

    Its :attr:`~pymorembs.preparation.PreparedModel.elimination` maps the system's coordinates
    to all dofs of the body, e.g. for the stress rows (:func:`full_stress_rows`).
    """
    if body.damping.kind == "modal":
        raise UserError(
            "modal damping has no viscous damping matrix of the full model (it is a loss factor "
            "in the frequency domain); use Rayleigh damping for time-domain checks"
        )
    port = Port.parse(load_node, TRANSLATIONS)
    return prepare(body, Frame("tangent", node=clamp_node), inputs=[port], outputs=[port])


def full_stress_rows(prepared: PreparedModel, stress: sp.spmatrix) -> sp.csr_matrix:
    """Stress rows on the independent dofs of ``prepared``, ``C_sigma T``, sparse.

    Parameters
    ----------
    prepared : PreparedModel
        E.g. :func:`clamped_full_model`; ``q = T q_i + t`` (the constant offset ``t`` is no
        response to the load cases and is left out, as by :func:`simulate`).
    stress : sparse matrix, shape (6 n_points, n_dof)
        ``StressOperator.matrix`` on the dofs of the body ``prepared`` was made from.

    Returns
    -------
    scipy.sparse.csr_matrix, shape (6 n_points, n_independent)
    """
    transform = prepared.elimination.transform
    if stress.shape[1] != transform.shape[0]:
        raise UserError(
            f"the stress operator acts on {stress.shape[1]} dofs, the body has {transform.shape[0]}"
        )
    return sp.csr_matrix(stress @ transform)


def clamped_full_system(body: ElasticBody, clamp_node: int, load_node: int) -> SecondOrderSystem:
    """The full FE model clamped at ``clamp_node``, loaded and observed at ``load_node``.

    The body is prepared with a tangent frame at ``clamp_node`` (all its dofs held), forces on
    ux uy uz of ``load_node`` as inputs (N) and the displacements ux uy uz of that node as
    outputs (m). The viscous damping is the body's explicit damping matrix plus Rayleigh
    damping. A modal damping ratio has no damping matrix of the full model -- it is a loss factor
    in the frequency domain only -- so it is a :class:`UserError`.

    Parameters
    ----------
    body : ElasticBody
        The original body (not a prepared one).
    clamp_node, load_node : int
        Node ids.
    """
    return clamped_full_model(body, clamp_node, load_node).system


#: ``|K R| / (|K| |R|)`` above which the rigid-body fields are not free (springs to ground).
RIGID_TOL = 1e-8
#: Rows of ``Phi`` at the clamp node below this (relative to ``max |Phi|``) count as held.
HELD_TOL = 1e-12


def clamped_reduced_system(
    prepared_body: ElasticBody,
    basis: np.ndarray,
    mass: np.ndarray,
    stiffness: np.ndarray,
    damping: np.ndarray | None,
    clamp_node: int,
    load_node: int,
) -> SecondOrderSystem:
    """The reduced model clamped at ``clamp_node``, loaded and observed at ``load_node``.

    Parameters
    ----------
    prepared_body : ElasticBody
        The body in the frame of the reduction (``PreparedModel.body``).
    basis : ndarray, shape (n_dof, n)
        Shape functions ``Phi`` on all dofs of ``prepared_body``, ``prepared.expand(V)``
        (eq. 18).
    mass, stiffness : ndarray, shape (n, n)
        Reduced ``M_e = Phi^T M Phi`` and ``K_e = Phi^T K Phi`` (``ReducedModel.system``).
    damping : ndarray, shape (n, n), or None
        Reduced viscous damping (``ReducedModel.damping_matrix``).
    clamp_node, load_node : int
        Node ids.

    Returns
    -------
    SecondOrderSystem
        Dense, in the coordinates ``q`` of the reduced model; inputs the forces ux uy uz at
        ``load_node`` (N), outputs its displacements (m), ``C = B^T``.

    Notes
    -----
    (a) The frame already holds ``clamp_node`` (a tangent frame there: ``Phi`` vanishes at the
    node): ``M_e``, ``D``, ``K_e`` as given, ``B`` the rows of ``Phi`` at the load node.

    (b) Otherwise -- a Buckens frame, or a tangent frame at another node -- the motion of the
    body is a rigid motion of its frame, ``R r`` with the six rigid-body fields ``R`` of
    ``prepared_body`` (about its coordinate origin), plus the elastic field ``Phi q``. Holding
    ``clamp_node``, which needs all six dofs ux..rz, by a rigid joint means ``R_2 r + Phi_2 q =
    0`` (``R_2``, ``Phi_2`` the node's rows), so ``r = -A q`` with ``A = R_2^{-1} Phi_2`` and the
    displacement field is ``Phi_c q``, ``Phi_c = Phi - R A``: the linearised multibody model of
    the floating body on that joint. From the mass invariants ``M_rr = R^T M R`` and
    ``M_re = R^T M Phi`` (zero in a Buckens frame),

        M_c = M_e - A^T M_re - M_re^T A + A^T M_rr A,    K_c = K_e,

    as ``K R = 0`` (checked: the body must be free of springs to ground). The damping is
    ``alpha M_c + beta K_c`` for Rayleigh damping of the body, plus ``Phi_c^T D_x Phi_c`` for
    an explicit damping matrix ``D_x``; a body without viscous damping of its own (e.g. a
    modal damping ratio) keeps the given ``damping`` (for modal damping an approximation: the
    damping of the unclamped modes). ``B`` holds the rows of ``Phi_c`` at the load node.
    """
    dofs = prepared_body.dofs
    phi = np.asarray(basis, dtype=float)
    if phi.ndim != 2 or phi.shape[0] != prepared_body.n_dof:
        raise UserError(
            f"basis has shape {phi.shape} but the body has {prepared_body.n_dof} dofs; expand "
            "it to all dofs (PreparedModel.expand)"
        )
    order = phi.shape[1]
    mass = np.asarray(mass, dtype=float)
    stiffness = np.asarray(stiffness, dtype=float)
    damping = None if damping is None else np.asarray(damping, dtype=float)
    for label, matrix in (("mass", mass), ("stiffness", stiffness), ("damping", damping)):
        if matrix is not None and matrix.shape != (order, order):
            raise UserError(
                f"reduced {label} matrix has shape {matrix.shape}, expected ({order}, {order})"
            )
    load_rows = dofs.indices(load_node, TRANSLATIONS)
    clamp_rows = dofs.of_node(clamp_node)
    if clamp_rows.size == 0:
        raise UserError(f"clamp node {clamp_node} has no dofs in the model")
    labels = tuple(f"{load_node}:{name}" for name in TRANSLATIONS.split())

    def system(m: np.ndarray, d: np.ndarray | None, b: np.ndarray) -> SecondOrderSystem:
        return SecondOrderSystem(
            mass=m,
            stiffness=stiffness,
            damping=d,
            input_matrix=b,
            output_matrix=b.T.copy(),
            input_labels=labels,
            output_labels=labels,
        )

    scale = float(np.abs(phi).max(initial=0.0))
    if float(np.abs(phi[clamp_rows]).max()) <= HELD_TOL * scale:  # (a) held by the frame
        return system(mass, damping, phi[load_rows].T)

    # (b) a floating frame, held by a rigid joint at the node
    clamp_rows = clamp_rows[np.argsort(dofs.directions[clamp_rows])]
    if not np.array_equal(dofs.directions[clamp_rows], np.arange(6)):
        present = " ".join(dofs.label(i).split(":")[1] for i in clamp_rows)
        raise UserError(
            f"clamp node {clamp_node} has the dofs {present}: a rigid joint that holds the "
            "floating frame needs all six (ux uy uz rx ry rz)"
        )
    rigid = prepared_body.rigid_body_modes()
    k_all, m_all = prepared_body.stiffness, prepared_body.mass
    k_norm = float(abs(k_all).sum(axis=1).max()) or 1.0
    unresisted = np.linalg.norm(k_all @ rigid, axis=0) / (k_norm * np.linalg.norm(rigid, axis=0))
    if unresisted.max() > RIGID_TOL:
        raise UserError(
            f"the stiffness resists rigid-body motion (|K R| / |K| |R| = {unresisted.max():.1e}):"
            f" the body is supported elsewhere, so holding node {clamp_node} through its frame is"
            " not defined"
        )
    rigid_node = rigid[clamp_rows]
    if np.linalg.cond(rigid_node) > 1e12:
        raise UserError(f"the rigid-body fields at clamp node {clamp_node} are singular")
    coupling = np.linalg.solve(rigid_node, phi[clamp_rows])  # A = R_2^-1 Phi_2, (6, n)
    m_rr = rigid.T @ (m_all @ rigid)
    m_re = rigid.T @ (m_all @ phi)
    mass_c = mass - coupling.T @ m_re - m_re.T @ coupling + coupling.T @ (m_rr @ coupling)
    mass_c = 0.5 * (mass_c + mass_c.T)
    rayleigh = prepared_body.damping.kind == "rayleigh"
    explicit = prepared_body.damping_matrix
    damping_c = damping
    if rayleigh or explicit is not None:
        damping_c = np.zeros_like(mass_c)
        if rayleigh:
            damping_c += prepared_body.damping.alpha * mass_c
            damping_c += prepared_body.damping.beta * stiffness
        if explicit is not None:
            phi_c = phi - rigid @ coupling
            damping_c += phi_c.T @ (explicit @ phi_c)
    return system(mass_c, damping_c, (phi[load_rows] - rigid[load_rows] @ coupling).T)


__all__ = [
    "DEFAULT_DURATION_S",
    "DEFAULT_RHO_INF",
    "DEFAULT_STEP_S",
    "GeneralizedAlpha",
    "LoadCase",
    "TimeResponse",
    "clamped_full_model",
    "clamped_full_system",
    "clamped_reduced_system",
    "compare",
    "compare_stresses",
    "full_stress_rows",
    "integrate",
    "paper_load_cases",
    "simulate",
]
