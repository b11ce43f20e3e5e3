"""Preparation of a body for reduction (paper section 2): frame, ports, elimination.

:func:`prepare` turns an :class:`~pymorembs.body.ElasticBody` into the second-order system of its
independent dofs, ``M* q'' + D* q' + K* q = B* u + f*,  y = C* q`` (eqs. 11-17), and keeps the map
back to all dofs (eq. 18). A public subpackage (``docs/api.md``, "The public surface"): besides
:func:`prepare` its ``__all__`` holds the other steps of :func:`pymorembs.prepare` (interface
nodes, inertia loads, geometric stiffening) and the checks of
:mod:`~pymorembs.preparation.validation`.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from functools import cached_property

import numpy as np
import scipy.sparse as sp

from pymorembs.body import ElasticBody
from pymorembs.display import html_table, one_line, port_rows
from pymorembs.errors import NumericalError, UserError
from pymorembs.kinds import FrameType, choices
from pymorembs.linalg.mass_split import mass_split
from pymorembs.preparation.buckens_frame import buckens_frame, centre_of_gravity
from pymorembs.preparation.consistency import check_consistency, mechanism_or_map
from pymorembs.preparation.elimination import Elimination, eliminate
from pymorembs.preparation.hot_spots import (
    HotSpots,
    StressSpec,
    check_stress_spec,
    hot_spot_operator,
)
from pymorembs.preparation.inertia_loads import (
    INERTIA_LOAD_CASES,
    InertiaLoads,
    elastic_loads,
    inertia_loads,
    static_solver,
)
from pymorembs.preparation.interface import InterfaceSpec, add_interface_node, select_nodes
from pymorembs.preparation.mechanism_removal import mechanism_ports, remove_massless_mechanisms
from pymorembs.preparation.ports import Port, selection_matrix
from pymorembs.preparation.rigid_modes import free_rigid_body_modes
from pymorembs.preparation.stiffening import (
    Stiffening,
    stiffening_from_matrices,
    stiffening_from_mesh,
    with_stiffening,
)
from pymorembs.preparation.tangent_frame import tangent_frame
from pymorembs.preparation.validation import ValidationReport, validate_body, validate_prepared
from pymorembs.system import SecondOrderSystem

__all__ = [
    "INERTIA_LOAD_CASES",
    "Frame",
    "HotSpots",
    "InertiaLoads",
    "InterfaceSpec",
    "Port",
    "PreparedModel",
    "Stiffening",
    "StressSpec",
    "ValidationReport",
    "add_interface_node",
    "buckens_frame",
    "centre_of_gravity",
    "check_consistency",
    "check_stress_spec",
    "eliminate",
    "inertia_load_cases",
    "mechanism_or_map",
    "prepare",
    "select_nodes",
    "stiffening_from_matrices",
    "stiffening_from_mesh",
    "tangent_frame",
    "validate_body",
    "validate_prepared",
    "with_inertia_loads",
    "with_rigid_modes",
    "with_stiffening",
    "with_stress_outputs",
]


@dataclass(frozen=True)
class Frame:
    """Choice of the reference frame.

    ``kind`` is a :class:`~pymorembs.kinds.FrameType`; its name is taken too
    (``Frame("tangent", 2).kind is FrameType.TANGENT``); an unknown name is a :class:`UserError`.
    ``kind = "tangent"`` with ``node``: tangent frame at that node (paper section 2.1).
    ``kind = "buckens"``: Buckens frame, origin in the centre of gravity, shape functions
    mass-orthogonal to the rigid-body modes (free body).
    ``kind = "none"``: the body as given (its own fixed dofs only).
    """

    kind: FrameType = FrameType.TANGENT
    node: int | None = None

    def __post_init__(self) -> None:
        kind = FrameType.lookup(self.kind)  # a name ("tangent") is taken and stored as its kind
        if kind is None:
            raise UserError(f"frame type {self.kind!r} is unknown; use {choices(FrameType)}")
        object.__setattr__(self, "kind", kind)

    def describe(self) -> str:
        """One phrase, e.g. ``"tangent at node 2"``, ``"buckens"``."""
        if self.kind is FrameType.TANGENT:
            return f"{self.kind.value} at node {self.node}"
        return self.kind.value

    def apply(self, body: ElasticBody) -> ElasticBody:
        if self.kind is FrameType.TANGENT:
            if self.node is None:
                raise UserError("tangent frame needs a node")
            return tangent_frame(body, self.node)
        if self.kind is FrameType.BUCKENS:
            return buckens_frame(body)
        return body  # FrameType.NONE: the body as given


@dataclass(frozen=True, eq=False)
class PreparedModel:
    """A body ready for reduction.

    Attributes
    ----------
    body : ElasticBody
        The body in its reference frame (translated coordinates, frame dofs fixed).
    elimination : Elimination
        ``q = T q_i + t``.
    system : SecondOrderSystem
        The sparse system of the independent dofs with the ports.
    warnings : tuple of str
        Facts that may be mistakes (e.g. an explicit output on the frame's fixed dofs).
    inertia : InertiaLoads or None
        The inertia loads of the frame motion, when they are inputs too
        (:func:`with_inertia_loads`).
    stiffening : Stiffening or None
        Geometric stiffness of the unit loads of the frame motion
        (:mod:`pymorembs.preparation.stiffening`), when the exported bodies carry it.
    frame : Frame or None
        The reference frame the body was prepared in.
    notes : tuple of str
        Facts of the setup that are no mistake, e.g. forces at the frame node: they move the
        reference frame only (the usual joint node of a multibody model).
    hot_spots : HotSpots or None
        The points whose stresses are outputs of the system (:func:`with_stress_outputs`).
    """

    body: ElasticBody
    elimination: Elimination
    system: SecondOrderSystem
    warnings: tuple[str, ...] = ()
    inertia: InertiaLoads | None = None
    stiffening: Stiffening | None = None
    frame: Frame | None = None
    notes: tuple[str, ...] = ()
    hot_spots: HotSpots | None = None

    def summary(self) -> list[tuple[str, str]]:
        """The facts ``repr`` and a notebook show, as (label, text) rows: frame, independent
        dofs, inputs, outputs, inertia loads, stiffening, damping, warnings."""
        system = self.system
        rows = [
            ("frame", "not recorded" if self.frame is None else self.frame.describe()),
            ("independent dofs", f"{system.order} of {self.body.n_dof}"),
            *port_rows(system.input_labels, system.output_labels),
        ]
        if self.inertia is not None:
            rows.append(("inertia loads", " ".join(self.inertia.cases)))
        if self.stiffening is not None:
            rows.append(("stiffening", f"{self.stiffening.source}, "
                                       f"{len(self.stiffening.cases)} load cases"))  # fmt: skip
        body = self.body
        rows.append(("damping", body.damping.describe(matrix=body.damping_matrix is not None)))
        if self.warnings:
            rows.append(("warnings", str(len(self.warnings))))
        return rows

    def __repr__(self) -> str:
        return one_line(f"PreparedModel {self.body.name!r}", self.summary())

    def _repr_html_(self) -> str:
        return html_table(f"PreparedModel {self.body.name!r}", self.summary())

    @cached_property
    def reduction_system(self) -> SecondOrderSystem:
        """The system the reduction methods see: the ports, then the inertia loads (if any)."""
        return self.system if self.inertia is None else self.inertia.augment(self.system)

    def expand(self, basis: np.ndarray) -> np.ndarray:
        """A basis of the independent dofs expanded to all dofs (eq. 18), shape (n_dof, n)."""
        return self.elimination.expand(basis)

    @cached_property
    def static_response(self) -> np.ndarray:
        """``K^+ B`` of :attr:`reduction_system`: the static deformation under each input,
        shape (n_independent, n_inputs); solved once (one factorization) and kept with the
        model, so every reduction of a job reuses it.

        ``K^+`` is the solve of the reduction methods: a factorization of ``K`` in a frame that
        holds the body, inertia relief (the deformation mass-orthogonal to the rigid-body
        modes) for a free body in the Buckens frame. Columns are per unit input, the inertia
        loads with their scale (:attr:`InertiaLoads.scales`).
        """
        system = self.reduction_system
        if system.n_inputs == 0:
            return np.zeros((system.order, 0))
        return static_solver(system, "K (static response to the inputs)").solve(system.input_matrix)


def prepare(
    body: ElasticBody,
    frame: Frame,
    inputs: list[Port] | None = None,
    outputs: list[Port] | None = None,
    allow_rigid_body_modes: bool = False,
) -> PreparedModel:
    """Apply the frame, eliminate dependent and fixed dofs and assemble ``B*`` and ``C*``.

    Parameters
    ----------
    body : ElasticBody
    frame : Frame
    inputs, outputs : list of Port, optional
        Forces/moments in and displacements/rotations out. Without either, the ports that came
        with the model file (``body.ports``: ``B`` and ``C``, or ``C = B^T``) are used; a body
        without them gets empty input and output matrices.
    allow_rigid_body_modes : bool
        Accept a body that can still move as a rigid body (e.g. for its eigenfrequencies).
        Otherwise such a body is a :class:`UserError` naming the free motions: the reduction
        methods of this frame need a stiffness matrix without rigid-body modes.
    """
    try:
        framed = frame.apply(body)
    except UserError as exc:
        raise UserError(f"[frame]: {exc}") from None
    elimination = eliminate(framed)
    if elimination.n_independent == 0:
        raise UserError("the model has no independent dofs left after fixing and elimination")
    mass = elimination.matrix(framed.mass)
    stiffness = elimination.matrix(framed.stiffness)
    framed, elimination, removal = remove_massless_mechanisms(framed, elimination, mass, stiffness)
    mass, stiffness = removal.restrict(mass), removal.restrict(stiffness)
    if elimination.n_independent == 0:
        raise UserError("the model has no independent dofs left after fixing and elimination")
    warnings: list[str] = []
    notes: list[str] = list(removal.notes)
    n_i = elimination.n_independent
    model_ports = body.ports if not inputs and not outputs else None
    if model_ports is not None and model_ports.inputs is not None:
        b_all, input_labels = model_ports.inputs, list(model_ports.input_labels)
        if model_ports.outputs is None:
            c_all, output_labels = b_all, list(model_ports.input_labels)
        else:
            c_all, output_labels = model_ports.outputs.T, list(model_ports.output_labels)
        reading = mechanism_ports(
            removal, b_all, input_labels, c_all, output_labels, "model ports: "
        )
        warnings += reading.values()
        b = elimination.inputs(b_all)
        c = elimination.outputs(c_all.T)
        notes += _zero_ports(b, input_labels, "input", axis=0)
        mirrored = model_ports.outputs is None  # the outputs are the inputs' dofs
        zero = _zero_ports(c, output_labels, "output", axis=1, told=set(reading))
        (notes if mirrored else warnings).extend(zero)
    else:
        if inputs:
            b_all, input_labels = _selection(framed, inputs, "inputs")
            mechanism_ports(removal, b_all, input_labels, None, [], "[[inputs]]: ")
            b = elimination.inputs(b_all)
            notes += _zero_ports(b, input_labels, "input", axis=0)
        else:
            b, input_labels = np.zeros((n_i, 0)), []
        if outputs:
            c_all, output_labels = _selection(framed, outputs, "outputs")
            reading = mechanism_ports(removal, None, [], c_all, output_labels)
            warnings += reading.values()
            c = elimination.outputs(c_all.T)
            mirrored = inputs is not None and list(outputs) == list(inputs)
            zero = _zero_ports(c, output_labels, "output", axis=1, told=set(reading))
            (notes if mirrored else warnings).extend(zero)
        else:
            c, output_labels = np.zeros((0, n_i)), []

    damping = framed.damping
    modal = damping.kind == "modal"
    system = SecondOrderSystem(
        mass=mass,
        stiffness=stiffness,
        damping=elimination.matrix(framed.viscous_damping()),
        input_matrix=b,
        output_matrix=c,
        loss_factor=2.0 * damping.ratio if modal else 0.0,
        modal_damping_ratio=damping.ratio if modal else 0.0,
        input_labels=tuple(input_labels),
        output_labels=tuple(output_labels),
        static_load=elimination.load(framed.stiffness),
    )
    warnings += _massless_ports(system)
    if frame.kind == "buckens":
        try:
            elastic = _elastic_system(framed, elimination, system)
        except UserError as exc:
            if not removal.count:
                raise
            removed = "; ".join(removal.descriptions)
            raise UserError(f"{exc}; removed as massless mechanisms before: {removed}") from None
        return PreparedModel(
            framed, elimination, elastic, tuple(warnings), frame=frame, notes=tuple(notes)
        )
    if not allow_rigid_body_modes:
        free = free_rigid_body_modes(framed, elimination, system)
        if free:
            where = (
                f"the tangent frame at node {frame.node}"
                if frame.kind == "tangent"
                else "the fixed dofs and constraints of the model"
            )
            raise UserError(
                f"[frame]: {where} leave{'s' if frame.kind == 'tangent' else ''} "
                f"{len(free)} rigid-body motion{'s' if len(free) > 1 else ''} free "
                f"({'; '.join(free)}): the stiffness is singular; fix a node with rotational "
                "dofs or more nodes"
            )
    return PreparedModel(
        framed, elimination, system, tuple(warnings), frame=frame, notes=tuple(notes)
    )


def with_inertia_loads(
    prepared: PreparedModel, cases: tuple[str, ...] = INERTIA_LOAD_CASES
) -> PreparedModel:
    """The prepared model with the inertia loads of the frame motion as further inputs.

    See :mod:`pymorembs.preparation.inertia_loads` (load cases, scaling). Costs one factorization of
    the stiffness (the compliances that scale the loads). Load cases without elastic effect are
    dropped and named in the warnings.
    """
    loads = inertia_loads(prepared.body, prepared.system, prepared.elimination.inputs, cases)
    warnings = list(prepared.warnings)
    if not loads.cases:
        warnings.append("inertia loads: none of the load cases deforms the body in this frame")
    return replace(prepared, inertia=loads if loads.cases else None, warnings=tuple(warnings))


def with_stress_outputs(prepared: PreparedModel, spec: StressSpec) -> PreparedModel:
    """The prepared model with the stresses at the hot spots of ``spec`` as further outputs.

    The six components at each hot spot become rows of
    :attr:`~pymorembs.system.SecondOrderSystem.stress_matrix` (sparse, ``C_s = S T`` on the
    independent dofs; :mod:`pymorembs.preparation.hot_spots`). Found hot spots and targeted
    stresses cost one static factorization of the stiffness (the static responses to every
    input, ports and inertia loads alike); given ones that are not targeted cost none. A
    targeted stress block is weighted so that its static response has the Frobenius norm of the
    outputs' (:attr:`~pymorembs.system.SecondOrderSystem.stress_weight`).
    """
    system = prepared.reduction_system
    static = None
    if spec.automatic or spec.target:
        label = "K (static responses to the inputs, for the hot spots)"
        static = static_solver(system, label).solve(system.input_matrix)
    responses = None if static is None else prepared.expand(static)
    operator = hot_spot_operator(prepared.body, spec, responses)
    stress = sp.csr_matrix(operator.matrix @ prepared.elimination.transform)
    weight = 1.0
    if static is not None:
        outputs = float(np.linalg.norm(system.output_matrix @ static))
        stresses = float(np.linalg.norm(stress @ static))
        if outputs > 0 and stresses > 0:
            weight = outputs / stresses
    found = "highest von Mises" if spec.automatic else "given"
    extended = replace(
        prepared.system,
        stress_matrix=stress,
        stress_labels=operator.labels(),
        stress_weight=weight,
        stress_targeted=spec.target,
    )
    hot_spots = HotSpots(operator, found, spec.target, weight)
    out = replace(prepared, system=extended, hot_spots=hot_spots)
    if static is not None:  # K^+ B of the same inputs: the cached static response, solved once
        out.__dict__["static_response"] = static
    return out


def inertia_load_cases(
    prepared: PreparedModel, cases: tuple[str, ...] = INERTIA_LOAD_CASES
) -> tuple[str, ...]:
    """The load cases :func:`with_inertia_loads` keeps as inputs, without its factorization.

    Costs one product of the mass matrix with the cases' acceleration fields, so the inputs a
    reduction will see can be counted before any expensive step. :func:`with_inertia_loads`
    may drop a further case whose static response is zero (a load that is not zero but does
    not deform the body: possible only at the rounding level).
    """
    kept, _, _ = elastic_loads(prepared.body, prepared.system, prepared.elimination.inputs, cases)
    return kept


def _elastic_system(
    body: ElasticBody, elimination: Elimination, system: SecondOrderSystem
) -> SecondOrderSystem:
    """The system of a free body in the Buckens frame: elastic inputs and outputs only.

    With the mass-orthonormal rigid-body modes ``R`` (independent dofs), loads act through their
    self-equilibrated part ``B_e = (I - M R R^T) B`` and outputs read the deformation relative to
    the frame, ``C_e = C (I - R R^T M)``; ``H_e(s) = C_e (s^2 M + s D + K)^-1 B_e`` is then finite
    at ``s = 0`` (inertia relief).
    """
    free = free_rigid_body_modes(body, elimination, system)
    if len(free) != 6:
        raise UserError(
            f"[frame]: the Buckens frame needs a free body with six rigid-body modes; this one "
            f"has {len(free)}" + (f" ({'; '.join(free)})" if free else "")
        )
    return with_rigid_modes(system, body.rigid_body_modes()[elimination.independent])


def with_rigid_modes(system: SecondOrderSystem, motions: np.ndarray) -> SecondOrderSystem:
    """The system restricted to its elastic part, given its rigid-body motions (n, r).

    The motions are made mass-orthonormal (``R^T M R = I``); inputs and outputs act on the
    elastic part only (see :func:`_elastic_system`); static solves then use inertia relief.
    """
    gram = motions.T @ (system.mass @ motions)
    rigid = motions @ np.linalg.inv(np.linalg.cholesky(gram)).T  # R^T M R = I
    mass_rigid = system.mass @ rigid
    return replace(
        system,
        input_matrix=system.input_matrix - mass_rigid @ (rigid.T @ system.input_matrix),
        output_matrix=system.output_matrix - (system.output_matrix @ rigid) @ mass_rigid.T,
        rigid_modes=rigid,
    )


def _selection(body: ElasticBody, ports: list[Port], what: str) -> tuple:
    try:
        return selection_matrix(body, ports)
    except UserError as exc:
        raise UserError(f"[[{what}]]: {exc}") from None


#: A port counts as acting on massless directions from this share of its norm on.
MASSLESS_PORT_SHARE = 0.01


def _massless_ports(system: SecondOrderSystem) -> list[str]:
    """Warnings for ports that act (partly) on massless directions of the mass matrix.

    Such an input (a moment at a beam node without rotary inertia) has a static part that is
    transmitted without inertia: the transfer ``H(s)`` of collocated ports then holds a constant
    part that a reduced body with a positive definite mass can carry only through a very stiff
    mode, and eigenmode-based methods (modal reduction, the Gramians of the dense modal form)
    miss it; methods that span static responses (Krylov at 0 Hz, SOAGA, Craig-Bampton, modal
    with frequency response modes, the two-step Gramian) keep it.
    """
    if not system.input_labels and not system.output_labels:
        return []
    try:
        split = mass_split(system.mass)
    except NumericalError:  # an indefinite mass: the validation names it
        return []
    if not split.singular:
        return []
    out = []
    for what, matrix, labels in (
        ("input", system.input_matrix, system.input_labels),
        ("output", system.output_matrix.T, system.output_labels),
    ):
        if matrix.size == 0:
            continue
        total = np.linalg.norm(matrix, axis=0)
        share = np.linalg.norm(split.massless.T @ matrix, axis=0) / np.where(total > 0, total, 1)
        for label, value in zip(labels, share, strict=True):
            if value >= MASSLESS_PORT_SHARE:
                out.append(
                    f"{what} {label} acts on massless directions ({100 * value:.0f} % of it): its "
                    "static part is transmitted without inertia; modal reduction and the dense "
                    "Gramian miss it, Krylov, SOAGA, Craig-Bampton and modal with frm_hz keep it"
                )
    return out


def _zero_ports(
    matrix: np.ndarray, labels: list[str], what: str, axis: int, told: set[str] | None = None
) -> list[str]:
    """One line per node for the ports that act only on fixed dofs of the frame (zero column
    of B / row of C), e.g. ``inputs 2:ux uy uz act on ...``; ports in ``told`` (already
    warned about as reading a removed massless mechanism) are left out."""
    norms = np.abs(matrix).max(axis=axis) if matrix.size else np.zeros(len(labels))
    by_node: dict[str, list[str]] = {}
    for label, norm in zip(labels, norms, strict=True):
        if norm == 0.0 and label not in (told or set()):
            node, _, direction = label.rpartition(":")
            by_node.setdefault(node or label, []).append(direction if node else "")
    lines = []
    for node, directions in by_node.items():
        several = len(directions) > 1
        label = f"{node}:{' '.join(directions)}" if all(directions) else node
        lines.append(
            f"{what}{'s' if several else ''} {label} act{'' if several else 's'} on fixed dofs "
            f"of the frame: no elastic transfer ({'they move' if several else 'it moves'} the "
            "reference frame only)"
        )
    return lines
