"""The common result of every reduction method: a projection ``q = V q_bar`` with test space W.

Every reductor returns a :class:`Projection`; :func:`reduced_model` applies it (paper eq. 3-4),
post-processes the basis so that the reduced mass is the identity and the reduced stiffness
diagonal, adds the damping model, and checks the result before anyone writes it.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field, replace
from types import MappingProxyType
from typing import Any

import numpy as np
import scipy.linalg as sla

from pymorembs.display import frequency_range, html_table, one_line, port_rows
from pymorembs.errors import NumericalError, UserError
from pymorembs.linalg.products import extended_product
from pymorembs.system import SecondOrderSystem


@dataclass(frozen=True, eq=False)
class Projection:
    """Bases of a Petrov-Galerkin projection.

    Attributes
    ----------
    V : ndarray, shape (n, order)
        Trial basis: ``q = V q_bar`` (independent dofs).
    W : ndarray, shape (n, order)
        Test basis; the same object as ``V`` for a one-sided (orthogonal) projection.
    method : str
        Name of the method (``"modal"``, ``"krylov"``...).
    parameters : mapping
        Settings the method was run with and facts it found (JSON values), read-only and
        complete when the projection is built: a further fact makes a new projection
        (:meth:`with_parameters`).
    error_estimate : float or None
        Estimated max relative error on the band, for methods that have one.
    error_bound : float or None
        A-priori error bound, for methods that have one.
    error_curve : (ndarray, ndarray) or None
        ``(frequencies_hz, estimate)``: an error estimator as a function of frequency (SOAGA),
        both shape (n_f,), for plots next to the true error.
    """

    V: np.ndarray
    W: np.ndarray
    method: str
    parameters: Mapping[str, Any] = field(default_factory=dict)
    error_estimate: float | None = None
    error_bound: float | None = None
    error_curve: tuple[np.ndarray, np.ndarray] | None = None

    def __post_init__(self) -> None:
        # a read-only copy, so that nobody writes into a projection after it is built
        object.__setattr__(self, "parameters", MappingProxyType(dict(self.parameters)))

    def with_parameters(self, **facts: Any) -> Projection:
        """This projection with ``facts`` (JSON values) added to its parameters."""
        return replace(self, parameters={**self.parameters, **facts})

    @property
    def order(self) -> int:
        return int(self.V.shape[1])

    @property
    def one_sided(self) -> bool:
        return self.W is self.V

    def summary(self) -> list[tuple[str, str]]:
        """The facts ``repr`` shows, as (label, text) rows: bases, estimates, parameters."""
        sides = "V = W" if self.one_sided else "V and W (oblique)"
        rows = [("basis", f"{self.V.shape[0]} x {self.order}, {sides}")]
        if self.error_estimate is not None:
            rows.append(("error estimate", f"{self.error_estimate:.3g}"))
        if self.error_bound is not None:
            rows.append(("error bound", f"{self.error_bound:.3g}"))
        if self.error_curve is not None:
            rows.append(("estimator curve", f"{np.size(self.error_curve[0])} frequencies"))
        if self.parameters:
            rows.append(("parameters", " ".join(sorted(self.parameters))))
        return rows

    def __repr__(self) -> str:
        return one_line(f"Projection {self.method!r}", self.summary())


@dataclass(frozen=True, eq=False)
class ReducedModel:
    """A reduced second-order model and the projection it came from.

    Attributes
    ----------
    projection : Projection
        With ``V`` (and ``W``) post-processed: ``V^T M V = I`` and ``V^T K V = diag(omega^2)``;
        for an oblique projection ``W^T M V = I`` and ``W^T K V`` block diagonal.
    system : SecondOrderSystem
        Dense reduced system ``(M_bar, D_bar, K_bar, B_bar, C_bar)``.
    eigenfrequencies_hz : ndarray, shape (order,)
        Undamped eigenfrequencies of the reduced model, Hz (for an oblique projection
        ``|omega_bar_i^2|^(1/2) / (2 pi)``, both members of a complex pair alike).
    """

    projection: Projection
    system: SecondOrderSystem
    eigenfrequencies_hz: np.ndarray

    def summary(self) -> list[tuple[str, str]]:
        """The facts ``repr`` and a notebook show, as (label, text) rows: order, the range of
        the eigenfrequencies, inputs, outputs, damping."""
        system = self.system
        rows = [
            ("order", f"{self.projection.order}" + ("" if self.projection.one_sided
                                                    else " (oblique)")),
            ("eigenfrequencies", frequency_range(self.eigenfrequencies_hz)),
            *port_rows(system.input_labels, system.output_labels),
        ]  # fmt: skip
        return [*rows, *[row for row in system.summary() if row[0] == "damping"]]

    def __repr__(self) -> str:
        return one_line(f"ReducedModel {self.projection.method!r}", self.summary())

    def _repr_html_(self) -> str:
        return html_table(f"ReducedModel {self.projection.method!r}", self.summary())

    @property
    def damping_matrix(self) -> np.ndarray:
        """Viscous damping of the reduced model for simulation, shape (order, order).

        The projected viscous damping (Rayleigh, explicit) plus, for a modal damping ratio xi,
        ``diag(2 xi omega_bar_i)`` in the reduced eigenbasis (paper eq. 25). The frequency
        responses use the loss factor instead (see :class:`pymorembs.body.Damping`).
        """
        system = self.system
        damping = np.zeros_like(system.mass) if system.damping is None else system.damping
        omega = 2.0 * np.pi * self.eigenfrequencies_hz
        return damping + np.diag(2.0 * system.modal_damping_ratio * omega)


def explicit_step_s(eigenfrequencies_hz: np.ndarray) -> float | None:
    """Largest stable step of an explicit integrator for a reduced model, in s.

    The central-difference limit ``2 / omega_max`` (``omega_max = 2 pi f_max``, rad/s) of the
    undamped model; damping lowers it slightly (by the factor ``sqrt(1 + xi^2) - xi``). None for
    a model without a positive eigenfrequency.
    """
    top = float(np.max(eigenfrequencies_hz, initial=0.0))
    return 2.0 / (2.0 * np.pi * top) if top > 0 else None


def without_stiff_directions(
    system: SecondOrderSystem, model: ReducedModel, max_frequency_hz: float
) -> ReducedModel:
    """The reduced model without its eigen-directions above ``max_frequency_hz`` (Hz).

    The reduced model is in its eigenbasis (:func:`reduced_model`), so the directions are its
    columns: those with an undamped eigenfrequency above the limit are removed from ``V`` (and
    ``W``) and the model is formed again from the system (a Galerkin projection on the kept
    directions; for an oblique model a complex pair is kept or removed as a whole). The
    projection's ``parameters`` record ``max_frequency_hz``, ``removed_directions`` and
    ``removed_frequencies_hz``. A limit that removes every direction is a :class:`UserError`.
    """
    frequencies = model.eigenfrequencies_hz
    keep = frequencies <= max_frequency_hz
    if keep.all():
        return model
    if not keep.any():
        raise UserError(
            f"{model.projection.method}: max_frequency_hz = {max_frequency_hz:g} removes every "
            f"direction (lowest eigenfrequency {frequencies.min():.4g} Hz)"
        )
    projection = model.projection
    v = projection.V[:, keep]
    w = v if projection.one_sided else projection.W[:, keep]
    parameters = {
        **projection.parameters,
        "max_frequency_hz": float(max_frequency_hz),
        "removed_directions": int(np.count_nonzero(~keep)),
        "removed_frequencies_hz": frequencies[~keep].tolist(),
    }
    return reduced_model(system, replace(projection, V=v, W=w, parameters=parameters))


def reduced_model(system: SecondOrderSystem, projection: Projection) -> ReducedModel:
    """Project ``system``, diagonalise, add damping and check (paper section 2.3).

    For a one-sided projection the reduced eigenproblem ``K_bar x = lambda M_bar x`` is solved and
    ``V <- V X``, which makes ``M_bar = I`` and ``K_bar = diag(omega_bar_i^2)`` -- the block
    diagonal form the paper asks for, exactly the modal form for simulation. Rayleigh and
    explicit damping are projected; a modal damping ratio gives
    :attr:`ReducedModel.damping_matrix`.

    For an oblique projection (``W`` not ``V``, e.g. two-sided Krylov, eqs. 21-22) the reduced
    matrices ``W^T M V`` and ``W^T K V`` are not symmetric. The pencil ``(K_bar, M_bar)`` is
    diagonalised by its right eigenvectors ``X`` and the left ones ``Y = (M_bar X)^{-T}``
    (block diagonalisation, the paper's reference [16]): ``V <- V X``, ``W <- W Y`` give
    ``W^T M V = I`` and ``W^T K V`` block diagonal in real arithmetic -- ``omega_bar_i^2`` on
    the diagonal for real eigenvalues, a 2x2 block ``[[a, b], [-b, a]]`` for a complex pair
    ``a +- i b`` (basis ``Re x, Im x``). The transfer function is unchanged. Damping is
    projected, ``W^T D V``, and transformed likewise; a modal damping ratio gives
    ``diag(2 xi |omega_bar_i|)``. The model is checked: finite, ``M_bar = I``, no eigenvalue
    ``omega_bar^2`` with a negative real part, and no pole of the (damped) reduced model in the
    right half-plane.
    """
    if not projection.one_sided:
        return _oblique_model(system, projection)
    v = projection.V
    if not np.all(np.isfinite(v)):
        raise NumericalError(f"{projection.method}: basis has NaN or infinite entries")
    if system.rigid_modes is not None:
        v = _elastic_part(v, system, projection.method)
    first = system.project(v)
    eigenvalues, vectors = _reduced_eigenproblem(first.stiffness, first.mass, projection.method)
    v = v @ vectors
    reduced = system.project(v)
    # V^T M V = I and V^T K V = diag(lambda) up to round-off: make them exact.
    eigenvalues = np.where(
        np.abs(eigenvalues) < 1e-12 * np.abs(eigenvalues).max(), 0.0, eigenvalues
    )
    reduced = replace(reduced, mass=np.eye(v.shape[1]), stiffness=np.diag(eigenvalues))
    reduced.check_reduced()
    if system.rigid_modes is not None:
        # once more on the final, mass-normalised basis: the eigen-transformation amplifies the
        # round-off of stiff directions. K R = 0, R^T B_e = 0 and C_e R = 0, so this changes
        # none of the reduced matrices (V^T M V only by the square of the removed part).
        v = v - system.rigid_modes @ (system.rigid_modes.T @ extended_product(system.mass, v))
    new_projection = replace(projection, V=v, W=v)
    frequencies = np.sqrt(np.clip(eigenvalues, 0.0, None)) / (2.0 * np.pi)
    return ReducedModel(new_projection, reduced, frequencies)


#: Largest deviation of ``W^T M V`` from the identity (relative) after block diagonalisation.
OBLIQUE_MASS_TOL = 1e-6


def _oblique_model(system: SecondOrderSystem, projection: Projection) -> ReducedModel:
    """:func:`reduced_model` for ``W`` not ``V``: block diagonalisation of the oblique pencil."""
    method = projection.method
    v, w = projection.V, projection.W
    if v.shape != w.shape:
        raise NumericalError(f"{method}: V has shape {v.shape} but W has shape {w.shape}")
    if not (np.all(np.isfinite(v)) and np.all(np.isfinite(w))):
        raise NumericalError(f"{method}: basis has NaN or infinite entries")
    if system.rigid_modes is not None:
        v = _elastic_part(v, system, method)
        w = _elastic_part(w, system, method)
    first = system.project(v, w)
    eigenvalues, blocks, x = _oblique_eigenproblem(first.stiffness, first.mass, method)
    y = np.linalg.solve((first.mass @ x).T, np.eye(x.shape[1]))  # Y^T M_bar X = I
    v, w = v @ x, w @ y
    reduced = system.project(v, w)
    order = v.shape[1]
    deviation = float(np.max(np.abs(reduced.mass - np.eye(order)), initial=0.0))
    if not np.isfinite(deviation) or deviation > OBLIQUE_MASS_TOL:
        raise NumericalError(
            f"{method}: the reduced pencil cannot be diagonalised accurately (W^T M V deviates "
            f"from the identity by {deviation:.1e}; the eigenvectors are ill-conditioned)"
        )
    # exact modal form: M_bar = I, K_bar block diagonal from the eigenvalues
    tiny = 1e-12 * float(np.abs(eigenvalues).max(initial=0.0))
    stiffness = np.zeros((order, order))
    for start, size in blocks:
        a = eigenvalues[start].real
        a = 0.0 if abs(eigenvalues[start]) < tiny else a
        if size == 1:
            stiffness[start, start] = a
        else:
            b = eigenvalues[start].imag
            stiffness[start : start + 2, start : start + 2] = [[a, b], [-b, a]]
    reduced = replace(reduced, mass=np.eye(order), stiffness=stiffness)
    frequencies = np.sqrt(np.abs(eigenvalues)) / (2.0 * np.pi)
    pairs = sum(1 for _, size in blocks if size == 2)
    parameters = {**projection.parameters, "complex_eigenvalue_pairs": pairs}
    model = ReducedModel(replace(projection, V=v, W=w, parameters=parameters), reduced, frequencies)
    _check_oblique(model, eigenvalues, method)
    return model


def _oblique_eigenproblem(
    stiffness: np.ndarray, mass: np.ndarray, method: str
) -> tuple[np.ndarray, list[tuple[int, int]], np.ndarray]:
    """Real block eigenbasis of the nonsymmetric pencil ``K_bar x = lambda M_bar x``.

    Like :func:`_reduced_eigenproblem`, the flexibility form ``M_bar x = mu K_bar x`` is solved
    when ``K_bar`` is nonsingular (small ``lambda = 1 / mu`` to working precision).

    Returns
    -------
    eigenvalues : ndarray, complex, shape (order,)
        ``lambda_i`` in the order of the columns, ascending real part; a complex pair as
        ``a + i b, a - i b`` (``b > 0``) in two adjacent columns.
    blocks : list of (start, size)
        The diagonal blocks: size 1 for a real eigenvalue, 2 for a complex pair.
    x : ndarray, real, shape (order, order)
        Columns ``x_i`` (real eigenvalue) or ``Re x, Im x`` (pair), unit norm (per pair), with
        ``K_bar X = M_bar X Lambda_block``.
    """
    order = stiffness.shape[0]
    values = vectors = None
    try:
        mu, vectors = sla.eig(mass, stiffness)
        if np.all(np.isfinite(mu)) and np.all(mu != 0):
            values = 1.0 / mu
    except (np.linalg.LinAlgError, ValueError):
        pass
    if values is None:
        try:
            values, vectors = sla.eig(stiffness, mass)
        except (np.linalg.LinAlgError, ValueError) as exc:
            raise NumericalError(f"{method}: reduced eigenproblem failed ({exc})") from None
        if not np.all(np.isfinite(values)):
            raise NumericalError(f"{method}: reduced mass matrix is singular")
    # group into real eigenvalues and complex-conjugate pairs (LAPACK returns exact pairs);
    # a unit is (real part, index of the eigenvalue with Im > 0 or the real one, is a pair)
    units: list[tuple[float, int, bool]] = []
    used = np.zeros(order, dtype=bool)
    for i in range(order):
        if used[i]:
            continue
        used[i] = True
        if values[i].imag == 0.0:  # real QZ: real eigenvalues come out exactly real
            units.append((values[i].real, i, False))
            continue
        partners = np.flatnonzero(~used)
        if partners.size == 0:
            raise NumericalError(f"{method}: unpaired complex eigenvalue {values[i]:.3e}")
        j = int(partners[np.argmin(np.abs(values[partners] - np.conj(values[i])))])
        used[j] = True
        upper = i if values[i].imag > 0 else j
        units.append((values[upper].real, upper, True))
    units.sort(key=lambda unit: unit[0])
    x = np.zeros((order, order))
    eigenvalues = np.zeros(order, dtype=complex)
    blocks: list[tuple[int, int]] = []
    column = 0
    for _, i, pair in units:
        vector = vectors[:, i]
        if pair:
            both = np.column_stack([vector.real, vector.imag])
            x[:, column : column + 2] = both / np.linalg.norm(both)
            eigenvalues[column : column + 2] = values[i], np.conj(values[i])
            blocks.append((column, 2))
            column += 2
        else:
            # a real eigenvalue of a real pencil has a real eigenvector up to a complex factor
            k = int(np.argmax(np.abs(vector)))
            vector = (vector * np.conj(vector[k]) / abs(vector[k])).real
            x[:, column] = vector / np.linalg.norm(vector)
            eigenvalues[column] = values[i].real
            blocks.append((column, 1))
            column += 1
    return eigenvalues, blocks, x


def _check_oblique(model: ReducedModel, eigenvalues: np.ndarray, method: str) -> None:
    """Finite entries, ``M_bar = I``, ``Re omega_bar^2 >= 0`` and no unstable pole."""
    system = model.system
    for label, matrix in (
        ("stiffness", system.stiffness),
        ("damping", system.damping),
        ("input", system.input_matrix),
        ("output", system.output_matrix),
    ):
        if matrix is not None and not np.all(np.isfinite(matrix)):
            raise NumericalError(f"{method}: reduced {label} matrix has NaN or infinite entries")
    scale = float(np.abs(eigenvalues).max(initial=0.0))
    worst = float(eigenvalues.real.min(initial=0.0))
    if worst < -1e-8 * scale:
        raise NumericalError(
            f"{method}: the reduced stiffness has an eigenvalue with negative real part "
            f"({worst:.3e}): the reduced model is unstable"
        )
    poles = _poles(system.stiffness, model.damping_matrix, np.sqrt(np.abs(eigenvalues)))
    unstable = poles.real > 1e-8 * np.abs(poles) + 1e-14 * float(np.abs(poles).max(initial=0.0))
    if np.any(unstable):
        pole = poles[np.argmax(np.where(unstable, poles.real, -np.inf))]
        raise NumericalError(
            f"{method}: the reduced model has a pole in the right half-plane ({pole:.3e} rad/s):"
            " it is unstable"
        )


def _poles(stiffness: np.ndarray, damping: np.ndarray, omega: np.ndarray) -> np.ndarray:
    """Poles of ``q'' + D q' + K q`` (``M = I``), from the scaled first-order form.

    With ``z = [Omega q, q']`` and ``Omega = diag(omega_i)`` the system matrix
    ``[[0, Omega], [-K Omega^{-1}, -D]]`` has entries of the size of the frequencies, so the
    poles are accurate relative to each other even when the frequencies span many decades.
    """
    order = stiffness.shape[0]
    omega = np.where(omega > 0, omega, 1.0)
    a = np.zeros((2 * order, 2 * order))
    a[:order, order:] = np.diag(omega)
    a[order:, :order] = -stiffness / omega[None, :]
    a[order:, order:] = -damping
    return np.linalg.eigvals(a)


def _elastic_part(v: np.ndarray, system: SecondOrderSystem, method: str) -> np.ndarray:
    """The basis made mass-orthogonal to the rigid-body modes (Buckens frame, eq. 6).

    ``V <- V - R R^T M V`` twice (reorthogonalisation), then orthonormalised again; a direction
    that was (nearly) rigid is an error, not silently dropped.
    """
    rigid = system.rigid_modes
    for _ in range(2):
        v = v - rigid @ (rigid.T @ extended_product(system.mass, v))
    q, r = np.linalg.qr(v)
    diagonal = np.abs(np.diag(r))
    if diagonal.min() < 1e-8 * diagonal.max():
        raise NumericalError(
            f"{method}: the basis contains (nearly) rigid-body motions; it has only "
            f"{int(np.count_nonzero(diagonal >= 1e-8 * diagonal.max()))} elastic directions"
        )
    return q


def _reduced_eigenproblem(
    stiffness: np.ndarray, mass: np.ndarray, method: str
) -> tuple[np.ndarray, np.ndarray]:
    """Eigenpairs of ``K_bar x = lambda M_bar x`` with ``X^T M_bar X = I``, ascending.

    When ``K_bar`` is positive definite the flexibility form ``M_bar y = mu K_bar y`` is solved
    (``lambda = 1 / mu``): its absolute errors are relative to the largest ``mu``, so the small
    eigenvalues -- which carry the static and low-frequency response -- are accurate to working
    precision even when the basis also holds stiff directions (Krylov bases span static
    deflections with their high-frequency content). Otherwise (rigid-body modes) the direct form.
    """
    try:
        mu, y = sla.eigh(mass, stiffness)
    except np.linalg.LinAlgError:
        mu = None
    if mu is not None and mu.min() > 0:
        eigenvalues = 1.0 / mu[::-1]
        return eigenvalues, y[:, ::-1] * np.sqrt(eigenvalues)
    try:
        return sla.eigh(stiffness, mass)
    except np.linalg.LinAlgError as exc:
        raise NumericalError(
            f"{method}: reduced mass matrix is not positive definite ({exc})"
        ) from None
