"""Moment matching by projection on second-order Krylov subspaces (paper section 3.1).

At an expansion point ``s_k`` the input Krylov subspace is (eqs. 19-21)

    G_r(A_1, A_2, P_0) = span{P_0, ..., P_{r-1}},
    P_0 = -K_k^{-1} B,  P_1 = A_1 P_0,  P_i = A_1 P_{i-1} + A_2 P_{i-2},
    A_1 = -K_k^{-1} D_k,  A_2 = -K_k^{-1} M,
    K_k = s_k^2 M + s_k D + K,  D_k = 2 s_k M + D.

A one-sided projection ``V = W`` whose span contains the union of these subspaces over all
points matches the first ``r_k`` moments of ``H(s)`` about every ``s_k``; for ``C = B^T`` (inputs
and outputs at the same dofs) and symmetric matrices, ``2 r_k`` moments match.

A two-sided (oblique) projection takes ``W`` from the output Krylov subspaces (eq. 22), the same
recurrence with ``K_k^{-T}, D_k^T, M^T`` and start block ``-K_k^{-T} C^T``. The matrices of a
:class:`SecondOrderSystem` are symmetric, so ``K_k^T = K_k`` (complex symmetric, not Hermitian,
at a damped point) and ``W`` comes from the same recurrence and the same factorization with
``C^T`` in place of ``B``. Then ``2 r_k`` moments match at every point for any ``C``.

The basis is built by a block second-order Arnoldi process: the pairs ``(P_i, gamma P_{i-1})`` are
orthonormalised in the 2n-dimensional linearised space, with reorthogonalisation and
rank-revealing deflation, and the span of their upper halves -- exactly
``span{P_0, ..., P_{r-1}}`` -- is orthonormalised again into ``V``. One factorization of ``K_k``
serves all moments at a point.

Expansion points are frequencies ``f_k`` in Hz, ``s_k = i 2 pi f_k``. Real arithmetic is used
wherever possible: at 0 Hz, and for systems without viscous damping, where with
``P_i = i^i R_i`` the recurrence ``R_i = -2 omega K_k^{-1} M R_{i-1} + K_k^{-1} M R_{i-2}`` is real
(``K_k = K - omega^2 M``). With viscous damping at ``f_k > 0`` the recurrence is complex and the
real and imaginary parts of each block enter ``V``. A structural loss factor is not part of the
recurrence.
"""

from __future__ import annotations

import copy
from collections.abc import Sequence

import numpy as np
import scipy.sparse as sp

from pymorembs.errors import UserError
from pymorembs.linalg.factorization import Factorization, basis_plain_enough
from pymorembs.linalg.inertia_relief import InertiaRelief
from pymorembs.linalg.orthogonalization import OrthonormalBasis
from pymorembs.linalg.products import multiply
from pymorembs.methods import KrylovOptions
from pymorembs.progress import Progress
from pymorembs.reduction.projection import Projection
from pymorembs.system import SecondOrderSystem

#: Safety cap on the number of moments per point when only an order is requested.
MAX_MOMENTS = 500


class SecondOrderArnoldi:
    """Block second-order Arnoldi at one expansion point.

    Parameters
    ----------
    system : SecondOrderSystem
        Sparse full system (its viscous damping is used, the loss factor is not).
    frequency_hz : float
        Expansion point ``s = i 2 pi f``, f >= 0.
    tol : float
        Deflation tolerance of the orthonormalisation.
    plain_enough : float, optional
        Solves after the first (refined) one are not refined when it showed a plain solve error
        up to this (:class:`~pymorembs.linalg.factorization.Factorization`); default
        :func:`~pymorembs.linalg.factorization.basis_plain_enough` of the system's order.
    """

    def __init__(
        self,
        system: SecondOrderSystem,
        frequency_hz: float,
        tol: float,
        plain_enough: float | None = None,
    ) -> None:
        if plain_enough is None:
            plain_enough = basis_plain_enough(system.order)
        self.frequency_hz = float(frequency_hz)
        omega = 2.0 * np.pi * self.frequency_hz
        self.n = system.order
        self.mass = system.mass
        self.stiffness = system.stiffness
        damping = system.damping
        k_hat = [(1.0, system.stiffness), (-(omega**2), system.mass)]
        if omega == 0.0 or damping is None:
            # real recurrence; rotated (R_i) for f > 0 without damping
            self.kind = "real"
            self.d_hat = damping if omega == 0.0 else system.mass
            self.coef_d, self.coef_m = (-1.0, -1.0) if omega == 0.0 else (-2.0 * omega, 1.0)
            dtype: type = float
        else:
            self.kind = "complex"
            s = 1j * omega
            k_hat.append((s, damping))
            self.d_hat = 2.0 * s * system.mass + damping
            self.coef_d, self.coef_m = -1.0, -1.0
            dtype = complex
        label = f"K(s) at expansion point {self.frequency_hz:g} Hz"
        if omega == 0.0 and system.rigid_modes is not None:
            # free body (Buckens frame): K is singular; static solves by inertia relief
            self.factorization = InertiaRelief(
                system.stiffness, system.mass, system.rigid_modes, label, plain_enough
            )
        else:
            # the moments only span a subspace: plain solves once the first one showed that
            # they are accurate to plain_enough
            self.factorization = Factorization(k_hat, label=label, plain_enough=plain_enough)
        self.tol = tol
        self.dtype = dtype
        self.basis = OrthonormalBasis(2 * self.n, tol, dtype=dtype)
        self.block: np.ndarray | None = None
        self.gamma = 1.0
        self.input_matrix = system.input_matrix
        self.moments = 0

    def dual(self, start: np.ndarray) -> SecondOrderArnoldi:
        """The same recurrence at the same point from another start block, e.g. ``C^T``.

        The copy shares the factorization of ``K_k`` (no second factorization) and starts a new
        basis. For symmetric ``M, D, K`` this is the output Krylov subspace of eq. 22 when
        ``start = C^T``.

        Parameters
        ----------
        start : ndarray, shape (n, q)
            Replaces the input matrix ``B`` in ``P_0 = -K_k^{-1} B``.
        """
        twin = copy.copy(self)
        twin.input_matrix = np.asarray(start)
        twin.basis = OrthonormalBasis(2 * self.n, self.tol, dtype=self.dtype)
        twin.block = None
        twin.gamma = 1.0
        twin.moments = 0
        return twin

    def next_block(self) -> np.ndarray:
        """Directions of the next moment, as a real block of shape (n, k); (n, 0) when exhausted."""
        n = self.n
        if self.block is None:
            top = self.factorization.solve(self.input_matrix)  # P_0 up to sign
            self.gamma = 1.0 / self._frequency_scale(top)
            candidate = np.vstack([top, np.zeros_like(top)])
        elif self.block.shape[1] == 0:
            return np.zeros((n, 0))
        else:
            top, bottom = self.block[:n], self.block[n:]
            if self.d_hat is self.mass:  # undamped, f > 0: one product with M
                rhs = multiply(self.mass, self.coef_m * bottom / self.gamma + self.coef_d * top)
            else:
                rhs = self.coef_m * multiply(self.mass, bottom) / self.gamma
                if self.d_hat is not None:
                    rhs = rhs + self.coef_d * multiply(self.d_hat, top)
            candidate = np.vstack([self.factorization.solve(rhs), self.gamma * top])
        self.block = self.basis.add(candidate)
        self.moments += 1
        top = self.block[:n]
        return np.hstack([top.real, top.imag]) if self.kind == "complex" else top

    def _frequency_scale(self, p0: np.ndarray) -> float:
        """A circular frequency (rad/s) that balances the halves of the linearised vectors.

        ``max(omega_k, omega_R)`` with ``omega_R`` the Rayleigh quotient frequency of ``P_0``.
        """
        p = np.real(p0) if np.any(np.real(p0)) else np.imag(p0)
        num = float(np.sum(p * multiply(self.stiffness, p)))
        den = float(np.sum(p * multiply(self.mass, p)))
        omega_r = np.sqrt(num / den) if den > 0 and num > 0 else 1.0
        return max(2.0 * np.pi * self.frequency_hz, omega_r)


def krylov_reduction(
    system: SecondOrderSystem,
    expansion_points_hz: Sequence[float],
    moments: int | Sequence[int] | None = None,
    order: int | None = None,
    tol: float = 1e-10,
    two_sided: bool = False,
) -> Projection:
    """Second-order Krylov reduction at several expansion points (eqs. 19-22).

    The arguments are those of the ``krylov`` method, checked by its options class
    :class:`~pymorembs.methods.KrylovOptions` (``tol`` is its ``deflation_tolerance``), the one
    check of a job file, :func:`pymorembs.reduce` and this function alike.

    Parameters
    ----------
    system : SecondOrderSystem
        Sparse full system with input matrix ``B``.
    expansion_points_hz : sequence of float
        Frequencies ``f_k >= 0`` in Hz, none repeated; ``s_k = i 2 pi f_k``.
    moments : int or sequence of int, optional
        Number of moments (blocks) per point: ``r_k``. One number applies to all points.
    order : int, optional
        Size of the reduced model. Without ``moments``, blocks are added round-robin over the
        points, lowest moments first, until the basis has this size (the last block is cut to
        its dominant directions). With ``moments`` too, it caps the size.
    tol : float
        Deflation tolerance (relative).
    two_sided : bool
        False: one-sided projection ``V = W`` on the input Krylov subspaces (eq. 21), ``r_k``
        moments match at every point (``2 r_k`` for ``C = B^T``). True: oblique projection,
        ``V`` from the input subspaces (eq. 21) and ``W`` from the output subspaces (eq. 22),
        one factorization per point for both; ``2 r_k`` moments match at every point for any
        ``C``. ``V`` and ``W`` get the same size: the smaller basis is padded with further
        moments of its own (round-robin over the points), and only if its subspaces are
        exhausted is the larger one cut to the size of the smaller.

    Returns
    -------
    Projection
        ``parameters`` holds the points, the moments computed per point (for ``two_sided`` also
        ``output_moments``, those of ``W``) and the factorizations.

    Raises
    ------
    OptionError
        A bad argument (:class:`~pymorembs.methods.KrylovOptions`, with its message).
    UserError
        What only the system can tell (see :func:`moment_matching`).
    """
    options = KrylovOptions(
        expansion_points_hz=expansion_points_hz,
        order=order,
        moments=moments,
        two_sided=two_sided,
        deflation_tolerance=tol,
    )
    return krylov_from_options(system, options)


def krylov_from_options(
    system: SecondOrderSystem,
    options: KrylovOptions,
    band_hz: tuple[float, float] | None = None,
) -> Projection:
    """The ``krylov`` method on its checked options (``band_hz``: unused, the signature of
    every method of :func:`~pymorembs.reduction.dispatch.method_projection`)."""
    return moment_matching(
        system,
        options.expansion_points_hz,
        options.moments,
        options.order,
        options.deflation_tolerance,
        options.two_sided,
    )


def moment_matching(
    system: SecondOrderSystem,
    points: tuple[float, ...],
    moments: int | tuple[int, ...] | None,
    order: int | None,
    tol: float,
    two_sided: bool,
) -> Projection:
    """The Krylov basis of :func:`krylov_reduction` from checked values.

    The values are those of a :class:`~pymorembs.methods.KrylovOptions` (points in Hz,
    moments, order, deflation tolerance, two-sided), or of the Krylov first stage of a
    :class:`~pymorembs.methods.GramianOptions`: checked there, used here as they are. Only what
    depends on the system is checked here.

    Raises
    ------
    UserError
        An order above the independent dofs, a system without inputs, a two-sided projection
        without outputs or with asymmetric matrices, or inputs (outputs) that are zero on the
        independent dofs.
    """
    if isinstance(moments, int):
        moments = (moments,) * len(points)
    if order is not None and order > system.order:
        raise UserError(f"krylov: order {order} exceeds the {system.order} independent dofs")
    if system.n_inputs == 0:
        raise UserError("krylov: the system has no inputs")
    if two_sided:
        if system.n_outputs == 0:
            raise UserError("krylov: a two-sided projection needs outputs")
        _check_symmetric(system)

    basis = OrthonormalBasis(system.order, tol)
    basis_w = OrthonormalBasis(system.order, tol) if two_sided else None
    arnoldi: list[SecondOrderArnoldi] = []
    duals: list[SecondOrderArnoldi] = []
    sides = 2 if two_sided else 1
    total = sides * (sum(moments) if order is None else order)
    bar = Progress("krylov", total=total, unit="moment" if order is None else "column", every=1)
    with bar:
        if order is None:
            # the moments fix the work: one point at a time, each factorization freed after use
            # (kept for a two-sided projection, whose bases may need padding to one size)
            computed = []
            for f, m in zip(points, moments, strict=True):
                process = _start(system, f, tol, bar)
                _advance(basis, process, m, None, bar)
                computed.append(process.moments)
                if two_sided:
                    dual = process.dual(system.output_matrix.T)
                    _advance(basis_w, dual, m, None, bar)
                    arnoldi.append(process)
                    duals.append(dual)
                # free this factorization before the next one is computed: two factors of a
                # large model at once would double the peak memory (and page it in again)
                del process
        else:
            # round-robin over the points, lowest moments first, until `order` columns
            limits = list(moments or (MAX_MOMENTS,) * len(points))
            arnoldi = [_start(system, f, tol, bar) for f in points]
            _round_robin(basis, arnoldi, limits, order, bar)
            if two_sided:
                duals = [process.dual(system.output_matrix.T) for process in arnoldi]
                _round_robin(basis_w, duals, limits, order, bar)
            computed = [process.moments for process in arnoldi]
        bar.finish()  # exhausted bases end the work early
    if two_sided:
        # pad the smaller basis with further moments of its own, up to the size of the larger
        if basis.size < basis_w.size:
            _round_robin(basis, arnoldi, [MAX_MOMENTS] * len(points), basis_w.size)
        elif basis_w.size < basis.size:
            _round_robin(basis_w, duals, [MAX_MOMENTS] * len(points), basis.size)
        computed = [process.moments for process in arnoldi]
    v = basis.matrix
    if v.shape[1] == 0:
        raise UserError("krylov: the input matrix is zero on the independent dofs")
    parameters = {
        "expansion_points_hz": list(points),
        "moments": computed,
        "factorizations": len(points),
    }
    w = v
    if two_sided:
        w = basis_w.matrix
        if w.shape[1] == 0:
            raise UserError("krylov: the output matrix is zero on the independent dofs")
        size = min(v.shape[1], w.shape[1])  # both subspaces exhausted: cut the larger one
        v, w = v[:, :size], w[:, :size]
        parameters["output_moments"] = [process.moments for process in duals]
        parameters["two_sided"] = True
    parameters["order"] = int(v.shape[1])
    return Projection(V=v, W=w, method="krylov", parameters=parameters)


def _start(system: SecondOrderSystem, frequency_hz: float, tol: float, bar: Progress):
    """The Arnoldi process at one expansion point (its factorization), shown on ``bar``."""
    bar.describe(f"factorizing at {frequency_hz:g} Hz")
    process = SecondOrderArnoldi(system, frequency_hz, tol)
    bar.describe(f"moments at {frequency_hz:g} Hz")
    return process


def _round_robin(
    basis: OrthonormalBasis,
    processes: list[SecondOrderArnoldi],
    limits: list[int],
    order: int,
    bar: Progress | None = None,
) -> None:
    """Add blocks round-robin over ``processes``, lowest moments first, until ``basis`` has
    ``order`` columns, every process is exhausted or has computed ``limits[k]`` moments."""
    active = [k for k, process in enumerate(processes) if process.moments < limits[k]]
    while active and basis.size < order:
        for k in list(active):
            if basis.size >= order:
                break
            process = processes[k]
            if not _advance(basis, process, 1, order, bar) or process.moments >= limits[k]:
                active.remove(k)


def _check_symmetric(system: SecondOrderSystem) -> None:
    """The output Krylov subspace (eq. 22) reuses the input recurrence only for symmetric
    ``M, D, K``; raise :class:`UserError` otherwise."""
    named = (("mass", system.mass), ("stiffness", system.stiffness), ("damping", system.damping))
    for label, matrix in named:
        if matrix is None:
            continue
        difference = matrix - matrix.T
        asym = abs(difference).max() if sp.issparse(difference) else np.abs(difference).max()
        scale = abs(matrix).max() if sp.issparse(matrix) else np.abs(matrix).max()
        if asym > 1e-12 * max(float(scale), np.finfo(float).tiny):
            raise UserError(
                f"krylov: a two-sided projection needs a symmetric {label} matrix "
                f"(relative asymmetry {asym / scale:.1e})"
            )


def _advance(
    basis: OrthonormalBasis,
    process: SecondOrderArnoldi,
    blocks: int,
    order: int | None,
    bar: Progress | None = None,
) -> bool:
    """Add up to ``blocks`` further moments of ``process`` to ``basis`` (at most ``order``
    columns in all); False when the Krylov space of ``process`` is exhausted. ``bar`` advances
    by one per moment (``order`` None) or per column added."""
    for _ in range(blocks):
        block = process.next_block()
        if block.shape[1] == 0:
            return False
        room = None if order is None else order - basis.size
        added = basis.add(block, limit=room, reference=1.0).shape[1]  # tops of unit 2n-vectors
        if bar is not None:
            bar.update(1 if order is None else added)
        if order is not None and basis.size >= order:
            break
    return True
