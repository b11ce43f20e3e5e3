"""The large-motion checks of a job (``[large_motion]``): the exported bodies in Exudyn.

A reduced body accurate at its ports can still be wrong in a multibody run, where the frame's
motion loads every node (paper eq. 2). This check runs every exported body of a job in Exudyn
(``ObjectFFRFreducedOrder``, the nonlinear FFRF equations) through two large motions, hinged by
a revolute joint at ``joint_node``, and compares it with a converged reference body:

``pendulum``
    Gravity ``gravity_m_s2`` perpendicular to the hinge and to the line from the joint to the
    centre of gravity: released from rest with its centre of gravity level with the hinge, the
    body swings down through 90° and beyond. The hinge axis is perpendicular to that line and
    as close to the body's z axis as possible.
``spin-up``
    No gravity; a torque ``tau(t) = tau_0 sin²(pi t / spin_up_s)`` about the skew axis
    ``spin_axis`` for ``0 <= t <= spin_up_s`` (zero after), with ``tau_0`` chosen so that the
    rigid body reaches ``spin_rad_s``. Angular acceleration, then centrifugal loads about an axis
    off every symmetry axis.

The reference is the modal body of order ``reference_order`` (lowest eigenmodes, capped by the
model); its own convergence is measured by the modal body of half that order, whose deviation is
reported as ``reference_convergence``. Compared (each relative to the reference's peak): the
frame's angular velocity (rad/s, ground coordinates) and the elastic deflection in the body frame
of every frame node of the export and of one node off every symmetry axis of the body (the
node farthest from the three planes through the centre of gravity parallel to the coordinate
planes).

With hot spots (a :class:`~pymorembs.stress.StressOperator` ``C_sigma``) every run also gives
the stress history at them, ``C_sigma V q(t)`` from the body's elastic coordinates ``q(t)`` in
Exudyn (``V`` the body's basis on all dofs). No full model is run through the large motions, so
each body's history is compared with that of the same modal reference body (and the reference's
with the modal body of half its order, its convergence); the figures are those of
:mod:`pymorembs.analysis.stress_history`.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from pymorembs.analysis.exudyn_model import build_exudyn_model, simulate_exudyn
from pymorembs.analysis.stress_history import (
    compare_histories,
    hot_spot_entries,
    hot_spot_labels,
    stress_history,
    stress_settings,
)
from pymorembs.body import ElasticBody
from pymorembs.errors import UserError
from pymorembs.export.exudyn_body import exudyn_arrays
from pymorembs.export.source import body_invariants
from pymorembs.preparation import Frame, PreparedModel
from pymorembs.reduction.modal import modal_reduction
from pymorembs.reduction.projection import ReducedModel, reduced_model
from pymorembs.stress import StressOperator

__all__ = [
    "LARGE_MOTION_CASES",
    "LargeMotionResult",
    "LargeMotionSettings",
    "large_motion_checks",
    "off_axis_node",
]

#: The motions of the check.
LARGE_MOTION_CASES = ("pendulum", "spin-up")
#: Default skew spin axis in body-frame coordinates (normalised).
DEFAULT_SPIN_AXIS = (0.3, 0.2, 1.0)
#: Default spin rate as a fraction of the reference body's lowest angular eigenfrequency.
SPIN_FRACTION = 0.3
#: Steps per period of the reference body's lowest eigenfrequency (default step size).
STEPS_PER_PERIOD = 50


@dataclass(frozen=True)
class LargeMotionSettings:
    """What to run (``[large_motion]`` of a job; units s, rad/s, m/s²).

    ``step_s``, ``spin_rad_s`` and ``spin_up_s`` None: from the reference body
    (:data:`STEPS_PER_PERIOD` steps per period of its lowest eigenfrequency, :data:`SPIN_FRACTION`
    of that frequency, half the duration).
    """

    joint_node: int
    cases: tuple[str, ...] = LARGE_MOTION_CASES
    duration_s: float = 1.0
    step_s: float | None = None
    spin_rad_s: float | None = None
    spin_axis: tuple[float, float, float] = DEFAULT_SPIN_AXIS
    spin_up_s: float | None = None
    gravity_m_s2: float = 9.81
    reference_order: int = 120
    rho_inf: float = 0.9


#: The runs of one motion: the reference body's and, by name, every reduced body's; each with
#: ``times`` (s), ``angular_velocity`` (n_t, 3; rad/s, ground coordinates), ``angle`` (n_t,;
#: rad, about the hinge), ``deflections`` (node id -> (n_t, 3); m, body frame),
#: ``coordinates`` (n_t, n; the body's elastic coordinates), ``wall_time_s`` and, with hot
#: spots, ``stresses`` (a
#: :class:`~pymorembs.analysis.stress_history.StressHistory`).
MotionRuns = tuple[dict[str, Any], dict[str, dict[str, Any]]]


@dataclass(frozen=True)
class LargeMotionResult:
    """What :func:`large_motion_checks` found: the summary entry and the runs behind it.

    Attributes
    ----------
    summary : dict
        The summary entry (JSON values): the reference (order, convergence), the off-axis
        node, and per motion its parameters and per reduction the deviations from the
        reference.
    runs : dict of motion name -> MotionRuns
        Per motion the reference run and every reduced body's run, for a plot
        (:func:`pymorembs.report.plot_large_motion`).
    off_axis_node : int
        The node off every symmetry axis whose deflection the plot shows.
    """

    summary: dict[str, Any]
    runs: dict[str, MotionRuns]
    off_axis_node: int


def off_axis_node(body: ElasticBody, joint: np.ndarray | None = None) -> int:
    """A moving node off every symmetry axis of the body.

    Among the nodes with a free translational dof, the one farthest from all three planes through
    the centre of the nodes parallel to the coordinate planes (relative to the body's extent per
    axis); of equally far ones, the one farthest from ``joint`` (a position, default the frame
    origin).
    """
    free = np.ones(body.n_dof, dtype=bool)
    free[body.fixed] = False
    candidates = np.unique(body.dofs.nodes[free & (body.dofs.directions < 3)])
    xyz = body.coordinates[body.node_rows(candidates)]
    centre = body.coordinates.mean(axis=0)
    extent = np.ptp(body.coordinates, axis=0)
    extent = np.where(extent > 0, extent, 1.0)
    off = np.round(np.min(np.abs(xyz - centre) / extent, axis=1), 6)
    far = np.linalg.norm(xyz - (np.zeros(3) if joint is None else joint), axis=1)
    return int(candidates[np.lexsort((-far, -off))[0]])


def _unit(vector: np.ndarray) -> np.ndarray:
    return vector / np.linalg.norm(vector)


def _inertia_about(arrays: dict[str, np.ndarray], point: np.ndarray) -> np.ndarray:
    """Inertia tensor of the undeformed body about ``point`` (body frame), kg m²."""
    mass = float(arrays["physicsMass"])
    first = mass * np.asarray(arrays["physicsCenterOfMass"], dtype=float)
    j_origin = np.asarray(arrays["physicsInertia"], dtype=float)
    p = np.asarray(point, dtype=float)
    return (
        j_origin
        + (mass * p @ p - 2.0 * p @ first) * np.eye(3)
        - (mass * np.outer(p, p) - np.outer(first, p) - np.outer(p, first))
    )


@dataclass(frozen=True)
class _Motion:
    name: str
    hinge_axis: np.ndarray
    gravity: np.ndarray | None
    torque: Callable[[float], np.ndarray] | None
    parameters: dict[str, Any]


def _motions(
    settings: LargeMotionSettings, arrays: dict, joint: np.ndarray, spin_rad_s: float
) -> list[_Motion]:
    out = []
    centre = np.asarray(arrays["physicsCenterOfMass"], dtype=float)
    arm = centre - joint
    for name in settings.cases:
        if name == "pendulum":
            if np.linalg.norm(arm) <= 1e-9 * max(1.0, np.linalg.norm(joint)):
                raise UserError(
                    "[large_motion]: the joint node lies in the centre of gravity: a pendulum "
                    "needs a joint away from it (choose another joint_node or cases = "
                    '["spin-up"])'
                )
            d = _unit(arm)
            hinge = np.array([0.0, 0.0, 1.0]) - d[2] * d  # closest to z, perpendicular to arm
            if np.linalg.norm(hinge) < 1e-6:
                hinge = np.array([1.0, 0.0, 0.0]) - d[0] * d
            hinge = _unit(hinge)
            gravity = settings.gravity_m_s2 * _unit(np.cross(hinge, d))
            out.append(
                _Motion(
                    name,
                    hinge,
                    gravity,
                    None,
                    {"hinge_axis": hinge.tolist(), "gravity_m_s2": gravity.tolist()},
                )
            )
        else:
            axis = _unit(np.asarray(settings.spin_axis, dtype=float))
            inertia = float(axis @ _inertia_about(arrays, joint) @ axis)
            up = settings.spin_up_s if settings.spin_up_s is not None else settings.duration_s / 2
            peak = 2.0 * inertia * spin_rad_s / up

            def torque(t: float, axis=axis, peak=peak, up=up) -> np.ndarray:
                return (peak * np.sin(np.pi * t / up) ** 2 if t <= up else 0.0) * axis

            out.append(
                _Motion(name, axis, None, torque, {"spin_axis": axis.tolist(),
                        "spin_rad_s": spin_rad_s, "spin_up_s": up, "peak_torque_n_m": peak})
            )  # fmt: skip
    return out


def _run(
    arrays: dict,
    motion: _Motion,
    clamp: str,
    joint_node: int | None,
    step: float,
    settings: LargeMotionSettings,
    stress: tuple[np.ndarray, tuple[str, ...]] | None = None,
) -> dict[str, Any]:
    """One Exudyn run: times, frame angular velocity, elastic deflections of the frame nodes
    and, with ``stress`` (``C_sigma V`` of the body, shape (6 n_points, n), and the hot spots'
    labels), the stress history at the hot spots."""
    model = build_exudyn_model(
        arrays,
        clamp=clamp,
        joint_node=joint_node,
        gravity=None if motion.gravity is None else motion.gravity.tolist(),
        hinge_axis=motion.hinge_axis.tolist(),
        torques=[] if motion.torque is None else [motion.torque],
    )
    result = simulate_exudyn(model, settings.duration_s, step, spectral_radius=settings.rho_inf)
    basis = np.asarray(arrays["modeBasis"])
    deflections = {
        int(node): result.coordinates @ basis[3 * int(i) : 3 * int(i) + 3].T
        for node, i in zip(arrays["nodeIds"], arrays["nodeMeshIndices"], strict=True)
    }
    helper = _unit(
        np.cross(motion.hinge_axis, np.eye(3)[int(np.argmin(np.abs(motion.hinge_axis)))])
    )
    turned = np.einsum("tij,j->ti", result.rotation, helper)
    angle = np.unwrap(np.arctan2(np.cross(helper, turned) @ motion.hinge_axis, turned @ helper))
    run = {
        "times": result.times,
        "angular_velocity": result.angular_velocity,
        "angle": angle,
        "deflections": deflections,
        "coordinates": result.coordinates,
        "wall_time_s": result.wall_time_s,
    }
    if stress is not None:
        run["stresses"] = stress_history(result.times, result.coordinates, *stress)
    return run


def _deviation(run: dict, reference: dict, nodes: list[int]) -> dict[str, Any]:
    """Deviations of a run from the reference, each relative to the reference's peak."""
    w, w_ref = run["angular_velocity"], reference["angular_velocity"]
    frame = float(np.max(np.linalg.norm(w - w_ref, axis=1)) / np.max(np.linalg.norm(w_ref, axis=1)))
    peaks = {n: float(np.max(np.linalg.norm(reference["deflections"][n], axis=1))) for n in nodes}
    scale = max(max(peaks.values()), np.finfo(float).tiny)
    per_node = {}
    for n in nodes:
        error = float(
            np.max(np.linalg.norm(run["deflections"][n] - reference["deflections"][n], axis=1))
        )
        per_node[str(n)] = {
            "reference_peak_m": peaks[n],
            "max_abs_deviation_m": error,
            "max_rel_deviation": error / scale,
        }
    deviation = {
        "frame_max_rel_deviation": frame,
        "deflection_max_rel_deviation": max(v["max_rel_deviation"] for v in per_node.values()),
        "nodes": per_node,
        "wall_time_s": run["wall_time_s"],
    }
    if "stresses" in reference:
        deviation["stress"] = compare_histories(run["stresses"], reference["stresses"]).to_json()
    return deviation


def _held_by_frame(frame: Frame, prepared: PreparedModel, joint: int) -> bool:
    """Whether the hinge acts on the reference frame (the body is held by its frame).

    So it is for a tangent frame at the joint node, and for the frame ``"none"`` of a body with
    fixed dofs (e.g. the blade clamped to its hub), whose joint node must then lie at the frame
    origin. Otherwise the hinge acts on the joint node, which needs rotational dofs.
    """
    if frame.kind == "tangent":
        return frame.node == joint
    if frame.kind == "none" and prepared.body.fixed.size:
        position = prepared.body.node_position(joint)
        size = float(np.ptp(prepared.body.coordinates, axis=0).max())
        if np.linalg.norm(position) > 1e-9 * max(size, 1.0):
            raise UserError(
                f"[large_motion]: the body is held by its fixed dofs, so the hinge acts on its "
                f"frame at the origin; joint node {joint} lies at {position.tolist()}: choose a "
                "node at the origin"
            )
        return True
    return False


def large_motion_checks(
    settings: LargeMotionSettings,
    frame: Frame,
    prepared: PreparedModel,
    models: dict[str, ReducedModel],
    nodes: list[int],
    say: Callable[[str], None],
    stress: StressOperator | None = None,
) -> LargeMotionResult:
    """Run the checks for every one-sided reduced body.

    Returns the summary entry (the reference's order and convergence, the off-axis node, and per
    motion its parameters and per reduction the deviations of :func:`_deviation`) with the runs
    behind it; plotting them is the caller's. With ``stress`` (the hot spots on the dofs of
    ``prepared.body``) every run gives the stress history there, compared with the reference
    body's (module docstring).
    """
    joint = settings.joint_node
    extra = off_axis_node(prepared.body, prepared.body.node_position(joint))
    frame_nodes = list(dict.fromkeys([*nodes, joint, extra]))
    system = prepared.system
    order = min(settings.reference_order, system.order - 1)
    bodies: dict[str, ReducedModel] = {}
    for label, count in (("reference", order), ("reference/2", max(1, order // 2))):
        bodies[label] = reduced_model(system, modal_reduction(system, count))
    held_by_frame = _held_by_frame(frame, prepared, joint)
    clamp, joint_node = ("frame", None) if held_by_frame else ("joint", joint)
    every = {**bodies, **models}
    arrays = {name: exudyn_arrays(body_invariants(model, prepared, frame_nodes, name))
              for name, model in every.items()}  # fmt: skip
    stresses: dict[str, tuple[np.ndarray, tuple[str, ...]] | None] = dict.fromkeys(every)
    if stress is not None:
        points = hot_spot_labels(stress)
        for name, model in every.items():  # C_sigma V: (6 n_points, n), small and dense
            stresses[name] = (np.asarray(stress.matrix @ prepared.expand(model.projection.V)),
                              points)  # fmt: skip
    lowest = float(bodies["reference"].eigenfrequencies_hz.min())
    step = settings.step_s or min(1e-3, 1.0 / (STEPS_PER_PERIOD * lowest))
    spin = settings.spin_rad_s or SPIN_FRACTION * 2.0 * np.pi * lowest
    joint_position = prepared.body.node_position(joint)
    cases, runs_for_plot = [], {}
    for motion in _motions(settings, arrays["reference"], joint_position, spin):
        say(f"large motion '{motion.name}' in Exudyn: reference (modal {order}) and each body")
        runs = {
            name: _run(a, motion, clamp, joint_node, step, settings, stresses[name])
            for name, a in arrays.items()
        }
        reference = runs.pop("reference")
        convergence = _deviation(runs.pop("reference/2"), reference, frame_nodes)
        rows = [
            {"name": name, **_deviation(run, reference, frame_nodes)} for name, run in runs.items()
        ]
        cases.append(
            {
                "name": motion.name,
                **motion.parameters,
                "swing_deg": float(np.degrees(np.max(np.abs(reference["angle"])))),
                "reference_peak_angular_velocity_rad_s": float(
                    np.max(np.linalg.norm(reference["angular_velocity"], axis=1))
                ),
                "reference_convergence": {
                    k: convergence[k]
                    for k in ("frame_max_rel_deviation", "deflection_max_rel_deviation")
                }
                | (
                    {"stress_max_rel_deviation": convergence["stress"]["max_rel_deviation"]}
                    if stress is not None
                    else {}
                ),
                **hot_spot_entries(reference.get("stresses")),
                "reductions": rows,
            }
        )
        runs_for_plot[motion.name] = (reference, runs)
    summary = {
        "joint_node": joint,
        "clamp": clamp,
        "off_axis_node": extra,
        "nodes": frame_nodes,
        "duration_s": settings.duration_s,
        "step_s": step,
        "reference": {"method": "modal", "order": order, "lowest_frequency_hz": lowest},
        "cases": cases,
        "covers": "frame angular velocity and elastic deflections (body frame) of the listed "
        "nodes, each relative to the reference body's peak, over the whole motion",
    }
    if stress is not None:
        summary["stress"] = stress_settings(
            stress,
            f"the modal reference body of order {order} in Exudyn, C_sigma V q(t) (no full "
            "model is run through the large motions)",
        )
    return LargeMotionResult(summary, runs_for_plot, extra)
