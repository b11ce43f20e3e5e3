"""The inertia loads of the moving reference frame as inputs of the elastic body.

In the floating frame of reference every dof is loaded by the motion of the frame (paper eq. 2:
``h_e`` holds the inertia forces of the frame's translational and angular acceleration, the
centrifugal and Coriolis forces, gravity). A reduced body that is accurate at its ports can miss a
direction these loads excite -- a Krylov body built from forces on the axis of a shaft has no
torsion -- and then be wrong in the multibody run. The d'Alembert load cases of the frame motion
(SID_NOTES section 4.6) are therefore added as input columns of the second-order system, with
collocated outputs, so that every reduction method spans their responses and the error of
eq. 27 can be measured for them.

The load cases, in the body frame (coordinates ``c_i`` of the prepared body, relative to the
frame origin), as nodal accelerations ``a`` of unit frame motion; the load is ``f = -M a``:

=============  =============================================================================
``ax ay az``   translational acceleration ``e_a`` (gravity is one of them): ``a = S_t e_a``
``alx aly      angular acceleration ``e_a``: ``a = S_r e_a`` (translations ``e_a x c_i``,
alz``          rotational dofs ``e_a``)
``wxx wyy wzz  centrifugal loads of the angular velocity ``Omega``: ``omega~ omega~ c_i =
wxy wyz wxz``  sum_m W_m c_i Omega_m`` with ``W_xx = diag(0, -1, -1)``, ``W_xy = e_x e_y^T +
               e_y e_x^T`` ...; ``a = W_m c_i`` on the translational dofs
=============  =============================================================================

Coriolis forces ``-2 M (omega x q')`` are proportional to the elastic velocity, not a load case
of their own: they act along ``M`` times the elastic motion, which the basis spans already. The
gyroscopic moments ``omega x (Theta omega)`` of nodal rotary inertias are not included in the
centrifugal cases (their rotational rows are zero).

Each column is scaled so that its static compliance ``b^T K^+ b`` equals the median compliance
of the port forces: the inertia loads then neither dominate nor vanish beside the ports in the
methods that weigh inputs (Gramians, POD, SOAGA's greedy choice); for moment-matching methods the
scale does not change the space. A load case with no elastic effect is dropped and named: in the
Buckens frame the translational and angular accelerations are balanced by the rigid-body motion
(their d'Alembert loads are rigid-body loads), in a tangent frame with all six frame dofs fixed
none is; a body without coordinates has only the translational cases.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, replace

import numpy as np

from pymorembs.body import ElasticBody
from pymorembs.errors import UserError
from pymorembs.linalg.factorization import Factorization
from pymorembs.linalg.inertia_relief import InertiaRelief
from pymorembs.system import SecondOrderSystem

__all__ = [
    "INERTIA_LOAD_CASES",
    "InertiaLoads",
    "acceleration_fields",
    "elastic_loads",
    "inertia_loads",
    "is_inertia_label",
    "static_compliances",
    "static_solver",
]

#: The load cases in the order of their columns (names as in ``[stiffening] matrices``).
INERTIA_LOAD_CASES = (
    "ax",
    "ay",
    "az",
    "alx",
    "aly",
    "alz",
    "wxx",
    "wyy",
    "wzz",
    "wxy",
    "wyz",
    "wxz",
)
#: Label prefix of the inertia inputs and outputs of a system.
LABEL_PREFIX = "inertia:"
#: A load case whose elastic part is below this fraction of its load has no elastic effect.
NEGLIGIBLE = 1e-9

_CENTRIFUGAL = {
    "wxx": np.diag([0.0, -1.0, -1.0]),
    "wyy": np.diag([-1.0, 0.0, -1.0]),
    "wzz": np.diag([-1.0, -1.0, 0.0]),
    "wxy": np.array([[0.0, 1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 0.0]]),
    "wyz": np.array([[0.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, 1.0, 0.0]]),
    "wxz": np.array([[0.0, 0.0, 1.0], [0.0, 0.0, 0.0], [1.0, 0.0, 0.0]]),
}


@dataclass(frozen=True, eq=False)
class InertiaLoads:
    """Inertia load cases as ports of the independent dofs.

    Attributes
    ----------
    cases : tuple of str
        The load cases kept (columns), from :data:`INERTIA_LOAD_CASES`.
    input_matrix : ndarray, shape (n_independent, k)
        Scaled d'Alembert loads ``s_j * P^T T^T (-M a_j)`` (``T``: elimination; ``P^T``: the
        self-equilibrated part in the Buckens frame).
    scales : ndarray, shape (k,)
        The scale ``s_j`` of each column (1 / (unit of the frame acceleration) in model units).
    dropped : tuple of str
        Load cases asked for that have no elastic effect, each with the reason.
    """

    cases: tuple[str, ...]
    input_matrix: np.ndarray
    scales: np.ndarray
    dropped: tuple[str, ...] = ()

    def __repr__(self) -> str:
        dropped = f", dropped {len(self.dropped)}" if self.dropped else ""
        return f"<InertiaLoads: cases {' '.join(self.cases)}{dropped}>"

    @property
    def labels(self) -> tuple[str, ...]:
        """Port labels ``inertia:<case>`` of the inputs and of their collocated outputs."""
        return tuple(LABEL_PREFIX + case for case in self.cases)

    @property
    def output_matrix(self) -> np.ndarray:
        """Collocated outputs ``B_I^T``, shape (k, n_independent): the generalised coordinates
        the frame's equations see (``a_j^T M q``, scaled)."""
        return self.input_matrix.T

    def augment(self, system: SecondOrderSystem) -> SecondOrderSystem:
        """``system`` with these loads appended to its inputs and their outputs to its outputs."""
        return replace(
            system,
            input_matrix=np.hstack([system.input_matrix, self.input_matrix]),
            output_matrix=np.vstack([system.output_matrix, self.output_matrix]),
            input_labels=(*system.input_labels, *self.labels),
            output_labels=(*system.output_labels, *self.labels),
        )


def is_inertia_label(label: str) -> bool:
    """Whether a port label is one of an inertia load (``inertia:<case>``)."""
    return label.startswith(LABEL_PREFIX)


def acceleration_fields(
    body: ElasticBody, cases: tuple[str, ...] = INERTIA_LOAD_CASES
) -> np.ndarray:
    """Nodal accelerations ``a_j`` of the unit frame motions, shape (n_dof, len(cases)).

    Translational rows hold accelerations, rotational rows angular accelerations; scalar
    coordinates do not move. Coordinates are those of ``body`` (its frame origin at 0).
    """
    unknown = [c for c in cases if c not in INERTIA_LOAD_CASES]
    if unknown:
        raise UserError(
            f"unknown inertia load case {unknown[0]!r}; use {', '.join(INERTIA_LOAD_CASES)}"
        )
    rigid = body.rigid_body_modes()  # translations, then rotations about the origin
    positions = body.dof_positions()
    out = np.zeros((body.n_dof, len(cases)))
    for j, case in enumerate(cases):
        index = INERTIA_LOAD_CASES.index(case)
        if index < 6:
            out[:, j] = rigid[:, index]
        else:
            w = _CENTRIFUGAL[case]
            d = body.dofs.directions
            for axis in range(3):
                rows = d == axis
                out[rows, j] = positions[rows] @ w[axis]
    return out


def static_compliances(system: SecondOrderSystem, loads: np.ndarray, label: str) -> np.ndarray:
    """``b_j^T K^+ b_j`` for each column of ``loads`` (n, k), one factorization.

    ``K^+``: the inverse of the stiffness, or for a free body (``system.rigid_modes`` set) the
    inertia-relief solve on the mass-orthogonal complement of the rigid-body modes.
    """
    if loads.shape[1] == 0:
        return np.zeros(0)
    x = static_solver(system, label).solve(loads)
    return np.einsum("ij,ij->j", loads, x)


def static_solver(system: SecondOrderSystem, label: str) -> Factorization | InertiaRelief:
    """The static solve ``K^+`` of a system: a factorization of ``K``, or for a free body
    (``system.rigid_modes`` set) inertia relief on the mass-orthogonal complement."""
    if system.rigid_modes is not None:
        return InertiaRelief(system.stiffness, system.mass, system.rigid_modes, label)
    return Factorization(system.stiffness, label=label)


def elastic_loads(
    body: ElasticBody,
    system: SecondOrderSystem,
    transform_inputs: Callable[[np.ndarray], np.ndarray],
    cases: tuple[str, ...] = INERTIA_LOAD_CASES,
) -> tuple[tuple[str, ...], np.ndarray, list[str]]:
    """The unscaled d'Alembert loads of the load cases that deform the body.

    The first step of :func:`inertia_loads`, without its factorization: one product with the
    mass matrix (parameters as there). A case is dropped when the body has no coordinates for it
    or its load is balanced by the rigid-body motion (Buckens frame) or vanishes (e.g. the
    centrifugal load about the axis of a straight beam).

    Returns
    -------
    cases : tuple of str
        The cases kept.
    loads : ndarray, shape (n_independent, len(cases))
        Their loads on the independent dofs (the self-equilibrated part in the Buckens frame).
    dropped : list of str
        The cases dropped, each with the reason.
    """
    cases = tuple(dict.fromkeys(cases))
    if not body.has_coordinates:
        kept = tuple(c for c in cases if c in ("ax", "ay", "az"))
        dropped = [f"{c} (no coordinates)" for c in cases if c not in kept]
        cases = kept
    else:
        dropped = []
    loads_all = -(body.mass @ acceleration_fields(body, cases))
    loads = np.asarray(transform_inputs(loads_all), dtype=float)
    size = np.linalg.norm(loads, axis=0)
    if system.rigid_modes is not None:  # the self-equilibrated part (Buckens frame)
        rigid = system.rigid_modes
        loads = loads - system.mass @ (rigid @ (rigid.T @ loads))
    elastic = np.linalg.norm(loads, axis=0)
    keep = elastic > NEGLIGIBLE * np.where(size > 0, size, 1.0)
    for case, ok in zip(cases, keep, strict=True):
        if not ok:
            why = (
                "balanced by the rigid-body motion"
                if system.rigid_modes is not None
                else ("no elastic effect")
            )
            dropped.append(f"{case} ({why})")
    cases = tuple(c for c, ok in zip(cases, keep, strict=True) if ok)
    return cases, loads[:, keep], dropped


def inertia_loads(
    body: ElasticBody,
    system: SecondOrderSystem,
    transform_inputs: Callable[[np.ndarray], np.ndarray],
    cases: tuple[str, ...] = INERTIA_LOAD_CASES,
) -> InertiaLoads:
    """The scaled inertia load ports of a prepared body.

    Parameters
    ----------
    body : ElasticBody
        The body in its reference frame (coordinates relative to the frame origin).
    system : SecondOrderSystem
        Its system of independent dofs with the port inputs (scaled against their compliance);
        ``rigid_modes`` set for a free body in the Buckens frame.
    transform_inputs : callable
        Loads on all dofs (n_dof, k) to loads on the independent dofs (the transpose of the
        elimination, ``T^T``).
    cases : tuple of str
        Load cases wanted (:data:`INERTIA_LOAD_CASES`).
    """
    cases, loads, dropped = elastic_loads(body, system, transform_inputs, cases)
    ports = system.input_matrix
    compliance = static_compliances(
        system, np.hstack([ports, loads]), "K (compliance of the inertia loads)"
    )
    port_c, load_c = compliance[: ports.shape[1]], compliance[ports.shape[1] :]
    positive = port_c[port_c > 0]
    target = float(np.median(positive)) if positive.size else 1.0
    soft = load_c > 0  # a load with a zero static response has no elastic effect either
    dropped += [f"{c} (no elastic effect)" for c, ok in zip(cases, soft, strict=True) if not ok]
    cases = tuple(c for c, ok in zip(cases, soft, strict=True) if ok)
    scales = np.sqrt(target / load_c[soft])
    return InertiaLoads(cases, loads[:, soft] * scales, scales, tuple(dropped))
