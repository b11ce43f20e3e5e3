"""Linear second-order input/output systems, full (sparse) and reduced (dense).

``M q'' + D q' + (1 + i eta) K q = B u,  y = C q``  (paper eq. 4, with ``eta`` the loss factor
used for a modal damping ratio, see :class:`pymorembs.body.Damping`).

The transfer matrix is ``H(s) = C (s^2 M + s D + (1 + i eta) K)^{-1} B`` with ``s = i omega``,
omega in rad/s.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np
import scipy.sparse as sp

from pymorembs.display import one_line, port_rows
from pymorembs.errors import NumericalError
from pymorembs.linalg.products import extended_product


@dataclass(frozen=True, eq=False)
class SecondOrderSystem:
    """A second-order MIMO system.

    Parameters
    ----------
    mass, stiffness : sparse matrix or ndarray, shape (n, n)
        Symmetric ``M`` and ``K``. Sparse for full models, dense for reduced ones.
    damping : sparse matrix or ndarray, shape (n, n), or None
        Viscous damping ``D`` (None: no viscous damping).
    input_matrix : ndarray, shape (n, p)
        ``B``.
    output_matrix : ndarray, shape (r, n)
        ``C``.
    loss_factor : float
        Structural loss factor ``eta`` on the stiffness in the frequency domain (0: none).
    modal_damping_ratio : float
        Damping ratio for the viscous modal damping of a reduced model in the time domain
        (0: none). Kept alongside ``loss_factor = 2 * ratio``.
    input_labels, output_labels : tuple of str
        Names of the inputs and outputs, e.g. ``"1:ux"``.
    static_load : ndarray, shape (n,), optional
        Constant load ``f*`` from constraint offsets (eq. 16).
    rigid_modes : ndarray, shape (n, r), optional
        Mass-orthonormal rigid-body modes of a free body (Buckens frame): ``K`` is singular,
        ``B`` and ``C`` act on the elastic part only, static solves use inertia relief.
    stress_matrix : sparse matrix or ndarray, shape (r_s, n), optional
        ``C_s``: further outputs, the stress components at hot spots (rows of a
        :class:`~pymorembs.stress.StressOperator` on the independent dofs, model stress unit
        per model length). Sparse for full models, dense ``C_s V`` for reduced ones. They are
        outputs of the transfer function (:attr:`observed_matrix`, after ``C``) but not of the
        reduction methods unless ``stress_targeted`` is set (:meth:`targeted`).
    stress_labels : tuple of str
        Names of the stress outputs, e.g. ``"e12.ip3:sxx"``.
    stress_weight : float
        Factor on ``C_s`` where the stress outputs join ``C`` for a reduction method
        (:meth:`targeted`): it gives the stress block the weight of the port block, since
        stresses and displacements differ in unit and size.
    stress_targeted : bool
        Whether the reduction methods take the stress outputs as outputs (stress-targeted
        reduction: SOAGA's estimator, the Gramians' stress block, the POD's snapshots).
    """

    mass: sp.csr_matrix | np.ndarray
    stiffness: sp.csr_matrix | np.ndarray
    damping: sp.csr_matrix | np.ndarray | None
    input_matrix: np.ndarray
    output_matrix: np.ndarray
    loss_factor: float = 0.0
    modal_damping_ratio: float = 0.0
    input_labels: tuple[str, ...] = ()
    output_labels: tuple[str, ...] = ()
    static_load: np.ndarray | None = field(default=None)
    rigid_modes: np.ndarray | None = field(default=None)
    stress_matrix: sp.csr_matrix | np.ndarray | None = field(default=None)
    stress_labels: tuple[str, ...] = ()
    stress_weight: float = 1.0
    stress_targeted: bool = False

    def __post_init__(self) -> None:
        n = self.mass.shape[0]
        for label, matrix in (("stiffness", self.stiffness), ("damping", self.damping)):
            if matrix is not None and matrix.shape != (n, n):
                raise ValueError(f"{label} has shape {matrix.shape}, expected ({n}, {n})")
        b = np.asarray(self.input_matrix)
        c = np.asarray(self.output_matrix)
        if b.ndim != 2 or b.shape[0] != n:
            raise ValueError(f"input matrix has shape {b.shape}, expected ({n}, p)")
        if c.ndim != 2 or c.shape[1] != n:
            raise ValueError(f"output matrix has shape {c.shape}, expected (r, {n})")
        if self.stress_matrix is not None:
            stress = self.stress_matrix
            stress = sp.csr_matrix(stress) if sp.issparse(stress) else np.asarray(stress)
            if stress.ndim != 2 or stress.shape[1] != n:
                raise ValueError(f"stress matrix has shape {stress.shape}, expected (r, {n})")
            if len(self.stress_labels) != stress.shape[0]:
                raise ValueError(
                    f"{len(self.stress_labels)} stress labels for {stress.shape[0]} stress outputs"
                )
            object.__setattr__(self, "stress_matrix", stress)
        elif self.stress_labels:
            raise ValueError("stress labels without a stress matrix")
        object.__setattr__(self, "input_matrix", b)
        object.__setattr__(self, "output_matrix", c)
        if not self.input_labels:
            object.__setattr__(self, "input_labels", tuple(f"u{i}" for i in range(b.shape[1])))
        if not self.output_labels:
            object.__setattr__(self, "output_labels", tuple(f"y{i}" for i in range(c.shape[0])))

    def summary(self) -> list[tuple[str, str]]:
        """The facts ``repr`` shows, as (label, text) rows: order, inputs, outputs, damping."""
        form = f"sparse, {self.stiffness.nnz} entries in K" if self.is_sparse else "dense"
        damping = []
        if self.damping is not None:
            damping.append("viscous D")
        if self.loss_factor:
            damping.append(f"loss factor {self.loss_factor:g}")
        if self.modal_damping_ratio:
            damping.append(f"modal ratio {self.modal_damping_ratio:g}")
        rows = [
            ("order", f"{self.order} ({form})"),
            *port_rows(self.input_labels, self.output_labels),
            ("damping", ", ".join(damping) or "none"),
        ]
        if self.rigid_modes is not None:
            rows.append(("rigid-body modes", str(self.rigid_modes.shape[1])))
        if self.stress_matrix is not None:
            targeted = ", targeted" if self.stress_targeted else ""
            rows.append(("stress outputs", f"{self.n_stress}{targeted}"))
        return rows

    def __repr__(self) -> str:
        return one_line("SecondOrderSystem", self.summary())

    @property
    def order(self) -> int:
        """Number of (independent) coordinates ``n``."""
        return int(self.mass.shape[0])

    @property
    def n_inputs(self) -> int:
        return int(self.input_matrix.shape[1])

    @property
    def n_outputs(self) -> int:
        return int(self.output_matrix.shape[0])

    @property
    def n_stress(self) -> int:
        """Number of stress outputs (rows of :attr:`stress_matrix`; 0 without)."""
        return 0 if self.stress_matrix is None else int(self.stress_matrix.shape[0])

    @property
    def observed_matrix(self) -> sp.csr_matrix | np.ndarray:
        """All rows of the transfer function: ``C`` and below it ``C_s``, shape
        (n_outputs + n_stress, n).

        Sparse (CSR) when the stress matrix is sparse: nothing of ``C_s`` becomes dense.
        """
        if self.stress_matrix is None:
            return self.output_matrix
        if sp.issparse(self.stress_matrix):
            return sp.vstack([sp.csr_matrix(self.output_matrix), self.stress_matrix], "csr")
        return np.vstack([self.output_matrix, self.stress_matrix])

    @property
    def observed_labels(self) -> tuple[str, ...]:
        """Labels of the rows of :attr:`observed_matrix`: the outputs, then the stresses."""
        return (*self.output_labels, *self.stress_labels)

    def targeted(self) -> SecondOrderSystem:
        """The system a reduction method sees.

        Itself, unless ``stress_targeted`` is set: then the stress outputs, scaled by
        ``stress_weight``, are appended to ``C`` as ordinary outputs, so that a method that
        uses ``C`` (the POD's snapshots, the rational Krylov Gramians' space) aims at them;
        SOAGA, the Gramians and Krylov take the stress block as it is
        (:data:`~pymorembs.reduction.dispatch.STRESS_BLOCK_AS_IS`). ``C_s`` becomes dense here,
        ``8 r_s n`` bytes: the size of the ``r_s`` solves a method does with ``C^T`` anyway.
        """
        if not self.stress_targeted or self.stress_matrix is None:
            return self
        stress = self.stress_matrix
        dense = stress.toarray() if sp.issparse(stress) else np.asarray(stress)
        return replace(
            self,
            output_matrix=np.vstack([self.output_matrix, self.stress_weight * dense]),
            output_labels=self.observed_labels,
            stress_matrix=None,
            stress_labels=(),
            stress_targeted=False,
        )

    @property
    def is_sparse(self) -> bool:
        return sp.issparse(self.stiffness)

    def dynamic_terms(self, s: complex) -> tuple[list[tuple[complex, Any]], complex]:
        """The dynamic stiffness ``s^2 M + s D + (1 + i eta) K`` at ``s`` (rad/s), factored.

        Returns ``(terms, c)``: the dynamic stiffness equals ``c * sum(coef * matrix)`` with
        ``c = 1 + i eta`` and terms ``[(1, K), (s^2 / c, M), (s / c, D)]``. The stiffness keeps
        the coefficient 1, so it is never rounded by a scaling: FE stiffness matrices are so
        ill-conditioned (cond ~1e11 for beam models) that rounding ``(1 + i eta) K`` entry by
        entry already moves the static response by ~1e-10. All coefficients are real when ``s``
        is real and ``eta = 0``.
        """
        s = complex(s)
        c = 1.0 + 1j * self.loss_factor
        if s.imag == 0.0 and self.loss_factor == 0.0:
            s, c = s.real, 1.0
        terms: list[tuple[complex, Any]] = [(1.0, self.stiffness)]
        if s != 0:
            terms.append(((s * s) / c, self.mass))
            if self.damping is not None:
                terms.append((s / c, self.damping))
        return terms, c

    def project(self, basis_v: np.ndarray, basis_w: np.ndarray | None = None) -> SecondOrderSystem:
        """Petrov-Galerkin projection ``W^T (.) V`` (paper eq. 3-4); ``W = V`` if not given.

        Returns a dense reduced system; for ``W = V`` the reduced matrices are symmetrised
        exactly (they are symmetric up to round-off).
        """
        v = np.asarray(basis_v)
        w = v if basis_w is None else np.asarray(basis_w)
        one_sided = basis_w is None or basis_w is basis_v

        def reduce(matrix: sp.csr_matrix | np.ndarray | None) -> np.ndarray | None:
            if matrix is None:
                return None
            reduced = w.T @ extended_product(matrix, v)
            return 0.5 * (reduced + reduced.T) if one_sided else reduced

        stress = None if self.stress_matrix is None else np.asarray(self.stress_matrix @ v)
        return SecondOrderSystem(
            mass=reduce(self.mass),
            stiffness=reduce(self.stiffness),
            damping=reduce(self.damping),
            input_matrix=w.T @ self.input_matrix,
            output_matrix=self.output_matrix @ v,
            loss_factor=self.loss_factor,
            modal_damping_ratio=self.modal_damping_ratio,
            input_labels=self.input_labels,
            output_labels=self.output_labels,
            static_load=None if self.static_load is None else w.T @ self.static_load,
            stress_matrix=stress,
            stress_labels=self.stress_labels,
            stress_weight=self.stress_weight,
        )

    def check_reduced(self) -> None:
        """Check a dense reduced model before it is written.

        Finite entries, symmetric ``M``, ``K`` (and ``D``), positive definite ``M``, positive
        semidefinite ``K`` and ``D`` (stability). Raises :class:`NumericalError` naming the failure.
        """
        if self.is_sparse:
            raise ValueError("check_reduced is for dense reduced models")
        named = {"mass": self.mass, "stiffness": self.stiffness, "damping": self.damping}
        for label, matrix in named.items():
            if matrix is None:
                continue
            if not np.all(np.isfinite(matrix)):
                raise NumericalError(f"reduced {label} matrix has NaN or infinite entries")
            scale = max(float(np.max(np.abs(matrix))), np.finfo(float).tiny)
            asym = float(np.max(np.abs(matrix - matrix.T))) / scale
            if asym > 1e-8:
                raise NumericalError(
                    f"reduced {label} matrix is not symmetric (relative asymmetry {asym:.1e})"
                )
        if not (np.all(np.isfinite(self.input_matrix)) and np.all(np.isfinite(self.output_matrix))):
            raise NumericalError("reduced input or output matrix has NaN or infinite entries")
        mass_eig = np.linalg.eigvalsh(self.mass)
        if mass_eig[0] <= 1e-12 * max(mass_eig[-1], 0.0):
            raise NumericalError(
                f"reduced mass matrix is not positive definite (smallest eigenvalue "
                f"{mass_eig[0]:.3e}, largest {mass_eig[-1]:.3e})"
            )
        stiff_eig = np.linalg.eigvalsh(self.stiffness)
        if stiff_eig[0] < -1e-8 * max(abs(stiff_eig[-1]), np.finfo(float).tiny):
            raise NumericalError(
                f"reduced stiffness matrix is indefinite (smallest eigenvalue {stiff_eig[0]:.3e}):"
                " the reduced model is unstable"
            )
        if self.damping is not None:
            check_damping(np.asarray(self.damping))


def check_damping(damping: np.ndarray, label: str = "reduced damping matrix") -> None:
    """Raise :class:`NumericalError` unless a dense damping matrix is finite, symmetric and PSD.

    A damping matrix with a negative eigenvalue feeds energy in: the model is unstable.
    Tolerances as for the stiffness: asymmetry 1e-8, smallest eigenvalue >= -1e-8 x largest.
    """
    damping = np.asarray(damping, dtype=float)
    if damping.size == 0:
        return
    if not np.all(np.isfinite(damping)):
        raise NumericalError(f"{label} has NaN or infinite entries")
    scale = max(float(np.max(np.abs(damping))), np.finfo(float).tiny)
    asym = float(np.max(np.abs(damping - damping.T))) / scale
    if asym > 1e-8:
        raise NumericalError(f"{label} is not symmetric (relative asymmetry {asym:.1e})")
    values = np.linalg.eigvalsh(0.5 * (damping + damping.T))
    if values[0] < -1e-8 * max(abs(values[-1]), np.finfo(float).tiny):
        raise NumericalError(
            f"{label} is indefinite (smallest eigenvalue {values[0]:.3e}): it feeds energy in, "
            "the reduced model is unstable"
        )
