"""An exported Exudyn body in a ready Exudyn system, and its time integration.

The body is the archive of :mod:`pymorembs.export.exudyn_body` (the arrays of
:func:`~pymorembs.export.exudyn_body.exudyn_arrays`, or what
:func:`~pymorembs.export.exudyn_body.load_exudyn_body` reads back); this module runs it, the
export only writes it. :func:`build_exudyn_model` assembles a ready Exudyn system with the body,
loads at its nodes, displacement sensors at every frame node and either the reference frame fixed
to ground (``clamp="frame"``, for tangent-frame bodies) or a rigid joint at one node with the
frame free (``clamp="joint"``, e.g. for Buckens bodies); :func:`simulate_exudyn` integrates it in
time with Exudyn's implicit generalized-alpha solver, without console output and without files.

The body is an ``ObjectFFRFreducedOrder`` whose triangles (``surfaceTriangles``) Exudyn's renderer
draws as its ``triangleMesh``. Exudyn 1.12.258 renamed ``physicsMass``, ``physicsInertia`` and
``physicsCenterOfMass`` to ``mass``, ``inertia`` and ``centerOfMass``; the archive keeps the
documented ``physics*`` names and :func:`build_exudyn_model` passes them under the new ones.
Exudyn's ``ObjectFFRFreducedOrder`` has no input for the geometric stiffening of the archive's
``stiffening*`` entries; :func:`stiffening_force` applies them through the object's
``forceUserFunction``. A body with stress modes (``outputVariableModeBasis``) passes them on, so
that Exudyn's ``StressLocal`` output of the object gives the nodal stresses of its mesh nodes.
Exudyn itself is imported when a model is built, not with this module.
"""

from __future__ import annotations

import contextlib
import time
import warnings
from collections.abc import Callable, Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, NamedTuple

import numpy as np

from pymorembs.errors import NumericalError, UserError
from pymorembs.export.exudyn_body import check_exudyn_arrays, exudyn_arrays

if TYPE_CHECKING:
    from pymorembs.export.invariants import BodyInvariants

__all__ = [
    "ExudynModel",
    "ExudynResult",
    "Force",
    "build_exudyn_model",
    "simulate_exudyn",
    "stiffening_force",
]

#: A load: constant force (3,) in N in ground coordinates, or a function t (s) -> force (3,).
Force = Sequence[float] | np.ndarray | Callable[[float], Sequence[float] | np.ndarray]


@dataclass(eq=False)
class ExudynModel:
    """An assembled Exudyn system with one exported body.

    Attributes
    ----------
    system_container : exudyn.SystemContainer
    mbs : exudyn.MainSystem
        The assembled system.
    body : dict of str to ndarray
        The arrays of the body (:func:`~pymorembs.export.exudyn_body.exudyn_arrays`).
    clamp : str
        ``"frame"`` or ``"joint"``.
    joint_node : int or None
        Node id of the rigid joint (``clamp="joint"``).
    object_index, rigid_node, modal_node : int
        Indices of the ``ObjectFFRFreducedOrder``, its rigid-body node and its modal node.
    position_markers : dict of int to int
        Node id -> ``MarkerSuperElementPosition`` at the node.
    rigid_markers : dict of int to int
        Node id -> ``MarkerSuperElementRigid`` on the node's satellites (nodes with rotations).
    sensors : dict of int to int
        Node id -> sensor of the node's displacement in ground coordinates (m).
    frame_sensors : dict of str to int
        ``"angular_velocity"`` (ground coordinates, rad/s) and ``"rotation"`` (the rotation
        matrix, row-major) of the reference frame, ``"coordinates"``: the elastic coordinates.
    """

    system_container: Any
    mbs: Any
    body: dict[str, np.ndarray]
    clamp: str
    joint_node: int | None
    object_index: int
    rigid_node: int
    modal_node: int
    position_markers: dict[int, int] = field(default_factory=dict)
    rigid_markers: dict[int, int] = field(default_factory=dict)
    sensors: dict[int, int] = field(default_factory=dict)
    frame_sensors: dict[str, int] = field(default_factory=dict)


class ExudynResult(NamedTuple):
    """Result of :func:`simulate_exudyn`.

    Attributes
    ----------
    times : ndarray, shape (n_t,)
        Output times (s), from 0 to the end time.
    displacements : dict of int to ndarray (n_t, 3)
        Node id -> displacement of the node in ground coordinates (m): reference-frame motion plus
        elastic deformation.
    wall_time_s : float
        Wall-clock time of the time integration (s).
    angular_velocity : ndarray, shape (n_t, 3)
        Of the reference frame, ground coordinates (rad/s).
    rotation : ndarray, shape (n_t, 3, 3)
        Orientation of the reference frame (body-frame to ground coordinates).
    coordinates : ndarray, shape (n_t, nq)
        The elastic coordinates ``q``; the elastic deflection of a node in the body frame is
        its rows of ``modeBasis`` times ``q``.
    """

    times: np.ndarray
    displacements: dict[int, np.ndarray]
    wall_time_s: float
    angular_velocity: np.ndarray | None = None
    rotation: np.ndarray | None = None
    coordinates: np.ndarray | None = None


@contextlib.contextmanager
def _quiet_exudyn() -> Iterator[None]:
    """Silence Exudyn's console output (``exudyn.config.printToConsole``) for a block."""
    import exudyn

    old = exudyn.config.printToConsole
    exudyn.config.printToConsole = False
    try:
        yield
    finally:
        exudyn.config.printToConsole = old


def _body_arrays(body_data: BodyInvariants | Mapping[str, np.ndarray]) -> dict[str, np.ndarray]:
    if isinstance(body_data, Mapping):
        arrays = {key: np.asarray(value) for key, value in body_data.items()}
        check_exudyn_arrays(arrays, "exudyn body")
        return arrays
    return exudyn_arrays(body_data)


def _damping_matrix(arrays: Mapping[str, np.ndarray], damping: Any) -> np.ndarray | None:
    if isinstance(damping, str):
        if damping == "exported":
            d = arrays["dampingMatrixReduced"]
            return d if np.any(d) else None
        if damping == "none":
            return None
    else:
        try:
            alpha, beta = (float(x) for x in damping)
        except (TypeError, ValueError):
            alpha = beta = float("nan")
        if np.isfinite(alpha) and np.isfinite(beta) and alpha >= 0 and beta >= 0:
            d = alpha * arrays["massMatrixReduced"] + beta * arrays["stiffnessMatrixReduced"]
            return d if np.any(d) else None
    raise UserError(
        f"exudyn model: damping must be 'exported', 'none' or (alpha 1/s, beta s) >= 0, "
        f"got {damping!r}"
    )


def _matrix_container(matrix: np.ndarray) -> Any:
    import exudyn

    container = exudyn.MatrixContainer()
    container.SetWithDenseMatrix(np.ascontiguousarray(matrix, dtype=float), useDenseMatrix=True)
    return container


def build_exudyn_model(
    body_data: BodyInvariants | Mapping[str, np.ndarray],
    *,
    clamp: str = "frame",
    joint_node: int | None = None,
    loads: Sequence[tuple[int, Force]] = (),
    damping: str | tuple[float, float] = "exported",
    gravity: Sequence[float] | None = None,
    hinge_axis: Sequence[float] | None = None,
    torques: Sequence[Force] = (),
    initial_angular_velocity: Sequence[float] | None = None,
    initial_coordinates: Sequence[float] | None = None,
) -> ExudynModel:
    """Build a ready Exudyn system with the exported body.

    The body is an ``ObjectFFRFreducedOrder`` (``computeFFRFterms=True``: the FFRF mass matrix and
    quadratic velocity terms are evaluated by Exudyn) on a ``NodeRigidBodyEP`` for the reference
    frame, placed at the ground origin with the identity orientation (ground coordinates =
    body-frame coordinates at t = 0), and a ``NodeGenericODE2`` for the elastic coordinates.

    Parameters
    ----------
    body_data : dict or BodyInvariants
        The arrays of :func:`~pymorembs.export.exudyn_body.exudyn_arrays` /
        :func:`~pymorembs.export.exudyn_body.load_exudyn_body`, or the invariants.
    clamp : {"frame", "joint"}
        ``"frame"``: the reference frame is fixed to ground by a ``GenericJoint`` on the rigid
        node (tangent-frame bodies: the frame node is clamped, the body deforms about it).
        ``"joint"``: the frame is free; a ``GenericJoint`` (all six axes locked) fixes the
        ``MarkerSuperElementRigid`` of ``joint_node`` to ground (e.g. Buckens bodies).
    joint_node : int, optional
        Node id of the joint; needed for ``clamp="joint"``; the node must have rotational dofs.
    loads : sequence of (node id, force)
        Forces at frame nodes in ground coordinates (N): a constant vector (3,) or a function of
        time ``t`` (s) returning one (a Python user function, evaluated every step).
    damping : "exported", "none" or (alpha, beta)
        Modal damping: the exported ``De``, none, or Rayleigh ``alpha Me + beta Ke`` (1/s, s).
    gravity : (3,) float, optional
        Gravitational acceleration in ground coordinates (m/s²), applied through Exudyn's
        ``LoadMassProportional`` (which uses ``m``, the centre of mass and ``mPhitTPsi``).
    hinge_axis : (3,) float, optional
        Make the joint of ``clamp`` a revolute joint: rotation about this axis (ground
        coordinates, through the joint point) stays free.
    torques : sequence of torque
        Torques (N m, ground coordinates; constant or functions of time) on the reference frame.
    initial_angular_velocity : (3,) float, optional
        Angular velocity of the reference frame at t = 0 (rad/s; must agree with the joint).
    initial_coordinates : (nq,) float, optional
        Elastic coordinates at t = 0.

    A body with ``stiffening*`` entries (geometric stiffening, SID_NOTES §4.6) gets the
    generalised force ``-sum_L c_L K0_L q`` on its elastic coordinates through the object's
    ``forceUserFunction``: the centrifugal cases weighted by the products of the frame's angular
    velocity, the acceleration cases by the frame's acceleration less ``gravity`` and by its
    angular acceleration, the node-force cases by the forces of ``loads`` (all in body
    coordinates; the frame's accelerations are those of the current iterate of the implicit
    solver). Joint reactions and ``torques`` on the frame node stiffen
    nothing: a tangent frame's support already carries them in the load cases.

    Returns
    -------
    ExudynModel

    Raises
    ------
    UserError
        Unknown clamp, node or damping, a joint node without rotations, or a bad load.
    """
    import exudyn
    import exudyn.itemInterface as eii

    arrays = _body_arrays(body_data)
    node_ids = [int(n) for n in arrays["nodeIds"]]
    mesh_of = dict(zip(node_ids, (int(i) for i in arrays["nodeMeshIndices"]), strict=True))
    satellites_of = {
        n: [int(i) for i in row]
        for n, row in zip(node_ids, arrays["satelliteMeshIndices"], strict=True)
        if row[0] >= 0
    }
    _check_clamp(clamp, joint_node, node_ids, satellites_of)
    damping_matrix = _damping_matrix(arrays, damping)
    forces = [_checked_force(node, force, node_ids) for node, force in loads]
    frame_torques = [_checked_vector(torque, "torque", "N m") for torque in torques]
    hinge = None
    if hinge_axis is not None:
        hinge = np.asarray(_checked_vector(hinge_axis, "hinge axis", "-"), dtype=float)
        if not np.linalg.norm(hinge) > 0:
            raise UserError("exudyn model: the hinge axis must not be zero")
        hinge = hinge / np.linalg.norm(hinge)
    g = None if gravity is None else np.asarray(gravity, dtype=float)
    if g is not None and (g.shape != (3,) or not np.all(np.isfinite(g))):
        raise UserError(f"exudyn model: gravity must be 3 finite numbers (m/s²), got {gravity!r}")
    nq = arrays["massMatrixReduced"].shape[0]
    triangles = arrays.get("surfaceTriangles")
    if triangles is not None:
        triangles = np.asarray(triangles, dtype=np.int64).tolist()

    with _quiet_exudyn():
        sc = exudyn.SystemContainer()
        mbs = sc.AddSystem()
        spin = np.zeros(3) if initial_angular_velocity is None else initial_angular_velocity
        spin = np.asarray(_checked_vector(spin, "initial angular velocity", "rad/s"))
        start = np.zeros(nq) if initial_coordinates is None else initial_coordinates
        start = np.asarray(start, dtype=float).ravel()
        if start.shape != (nq,) or not np.all(np.isfinite(start)):
            raise UserError(f"exudyn model: initial_coordinates must be {nq} finite numbers")
        rigid = mbs.AddNode(
            eii.NodeRigidBodyEP(
                referenceCoordinates=[0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0],
                # Euler parameters at p = (1, 0, 0, 0): dp/dt = (0, omega / 2)
                initialVelocities=[0.0, 0.0, 0.0, 0.0, *(0.5 * spin).tolist()],
            )
        )
        modal = mbs.AddNode(
            eii.NodeGenericODE2(
                numberOfODE2Coordinates=nq,
                referenceCoordinates=[0.0] * nq,
                initialCoordinates=start.tolist(),
                initialCoordinates_t=[0.0] * nq,
            )
        )
        extra = {}
        if "outputVariableModeBasis" in arrays:  # stress modes: Exudyn's StressLocal output
            extra["outputVariableModeBasis"] = arrays["outputVariableModeBasis"]
            extra["outputVariableTypeModeBasis"] = getattr(
                exudyn.OutputVariableType, str(arrays["outputVariableTypeModeBasis"])
            )
        if any(key.startswith("stiffening") for key in arrays):
            extra["forceUserFunction"] = stiffening_force(arrays, rigid, g, forces)
        obj = mbs.AddObject(
            eii.ObjectFFRFreducedOrder(
                name=str(arrays["bodyName"]),
                nodeNumbers=[rigid, modal],
                massMatrixReduced=_matrix_container(arrays["massMatrixReduced"]),
                stiffnessMatrixReduced=_matrix_container(arrays["stiffnessMatrixReduced"]),
                dampingMatrixReduced=(
                    [] if damping_matrix is None else _matrix_container(damping_matrix)
                ),
                modeBasis=arrays["modeBasis"],
                referencePositions=arrays["referencePositions"],
                # physicsMass/-Inertia/-CenterOfMass are named mass/inertia/centerOfMass since
                # Exudyn 1.12.258
                mass=float(arrays["physicsMass"]),
                inertia=arrays["physicsInertia"],
                centerOfMass=arrays["physicsCenterOfMass"],
                mPsiTildePsi=arrays["mPsiTildePsi"],
                mPsiTildePsiTilde=arrays["mPsiTildePsiTilde"],
                mPhitTPsi=arrays["mPhitTPsi"],
                mPhitTPsiTilde=arrays["mPhitTPsiTilde"],
                mXRefTildePsi=arrays["mXRefTildePsi"],
                mXRefTildePsiTilde=arrays["mXRefTildePsiTilde"],
                computeFFRFterms=True,
                # Exudyn's renderer draws the deforming surface as its FEM route does
                # (ObjectFFRFreducedOrderInterface: triangleMesh = the surface triangles)
                visualization=eii.VObjectFFRFreducedOrder(
                    show=triangles is not None, triangleMesh=[] if triangles is None else triangles
                ),
                **extra,
            )
        )
        model = ExudynModel(sc, mbs, arrays, clamp, joint_node, obj, rigid, modal)
        for n in node_ids:
            model.position_markers[n] = mbs.AddMarker(
                eii.MarkerSuperElementPosition(
                    bodyNumber=obj, meshNodeNumbers=[mesh_of[n]], weightingFactors=[1.0]
                )
            )
            model.sensors[n] = mbs.AddSensor(
                eii.SensorSuperElement(
                    bodyNumber=obj,
                    meshNodeNumber=mesh_of[n],
                    outputVariableType=exudyn.OutputVariableType.Displacement,
                    writeToFile=False,
                    storeInternal=True,
                )
            )
        for n, satellites in satellites_of.items():
            model.rigid_markers[n] = mbs.AddMarker(
                eii.MarkerSuperElementRigid(
                    bodyNumber=obj, meshNodeNumbers=satellites, weightingFactors=[1.0 / 6.0] * 6
                )
            )

        ground = mbs.AddObject(eii.ObjectGround())
        if clamp == "frame":
            body_marker = mbs.AddMarker(eii.MarkerNodeRigid(nodeNumber=rigid))
            ground_position = np.zeros(3)
        else:
            body_marker = model.rigid_markers[int(joint_node)]
            first = 3 * mesh_of[int(joint_node)]
            ground_position = arrays["referencePositions"][first : first + 3]
        ground_marker = mbs.AddMarker(
            eii.MarkerBodyRigid(
                bodyNumber=ground, localPosition=[float(x) for x in ground_position]
            )
        )
        joint = {"constrainedAxes": [1, 1, 1, 1, 1, 1]}
        if hinge is not None:  # joint frames with z along the hinge: rotation about z free
            frame = _frame_with_z(hinge).tolist()
            joint = {"constrainedAxes": [1, 1, 1, 1, 1, 0], "rotationMarker0": frame,
                     "rotationMarker1": frame}  # fmt: skip
        with warnings.catch_warnings():  # rotationMarker0/1: deprecated, supported until 2031
            warnings.simplefilter("ignore", DeprecationWarning)
            mbs.AddObject(
                eii.GenericJoint(
                    markerNumbers=[ground_marker, body_marker],
                    visualization=eii.VGenericJoint(show=False),
                    **joint,
                )
            )
        for node, force in forces:
            mbs.AddLoad(_force_load(eii, model.position_markers[node], force))
        if frame_torques:
            frame_marker = mbs.AddMarker(eii.MarkerNodeRigid(nodeNumber=rigid))
            for torque in frame_torques:
                mbs.AddLoad(_force_load(eii, frame_marker, torque, kind="torque"))
        for key, node, variable in (
            ("angular_velocity", rigid, exudyn.OutputVariableType.AngularVelocity),
            ("rotation", rigid, exudyn.OutputVariableType.RotationMatrix),
            ("coordinates", modal, exudyn.OutputVariableType.Coordinates),
        ):
            model.frame_sensors[key] = mbs.AddSensor(
                eii.SensorNode(
                    nodeNumber=node,
                    outputVariableType=variable,
                    writeToFile=False,
                    storeInternal=True,
                )
            )
        if g is not None:
            mass_marker = mbs.AddMarker(eii.MarkerBodyMass(bodyNumber=obj))
            mbs.AddLoad(eii.LoadMassProportional(markerNumber=mass_marker, loadVector=list(g)))
        mbs.Assemble()
    return model


def _check_clamp(
    clamp: str, joint_node: int | None, node_ids: list[int], satellites_of: dict
) -> None:
    if clamp == "frame":
        if joint_node is not None:
            raise UserError("exudyn model: joint_node is only used with clamp='joint'")
        return
    if clamp != "joint":
        raise UserError(f"exudyn model: clamp must be 'frame' or 'joint', got {clamp!r}")
    if joint_node is None:
        raise UserError("exudyn model: clamp='joint' needs joint_node")
    if int(joint_node) not in node_ids:
        raise UserError(
            f"exudyn model: joint node {joint_node} is not a frame node of the body "
            f"(nodes: {node_ids})"
        )
    if int(joint_node) not in satellites_of:
        raise UserError(
            f"exudyn model: joint node {joint_node} has no rotational dofs, so a rigid joint "
            "cannot act on it; export a node with rotations (e.g. an RBE2 interface node)"
        )


def _euler_parameter_rotation(p: np.ndarray) -> np.ndarray:
    """Rotation matrix (3, 3), body to ground, of the Euler parameters ``p = (p0, p1, p2, p3)``."""
    p0, p1, p2, p3 = p
    return 2.0 * np.array(
        [
            [p0 * p0 + p1 * p1 - 0.5, p1 * p2 - p0 * p3, p1 * p3 + p0 * p2],
            [p1 * p2 + p0 * p3, p0 * p0 + p2 * p2 - 0.5, p2 * p3 - p0 * p1],
            [p1 * p3 - p0 * p2, p2 * p3 + p0 * p1, p0 * p0 + p3 * p3 - 0.5],
        ]
    )


def stiffening_force(
    arrays: Mapping[str, np.ndarray],
    rigid: int,
    gravity: Sequence[float] | None = None,
    forces: Sequence[tuple[int, Any]] = (),
) -> Callable[..., list[float]]:
    """``forceUserFunction`` of the geometric stiffening (SID_NOTES §4.6) of an exported body.

    For a body placed in one's own Exudyn system: pass the result as ``forceUserFunction`` of
    its ``ObjectFFRFreducedOrder`` (:func:`build_exudyn_model` does).

    Parameters
    ----------
    arrays : dict
        The body (:func:`~pymorembs.export.exudyn_body.load_exudyn_body`) with its
        ``stiffening*`` entries.
    rigid : int
        Exudyn node number of the body's reference node (``NodeRigidBodyEP``).
    gravity : (3,) float, optional
        Gravitational acceleration in ground coordinates (m/s²) as applied to the body.
    forces : sequence of (node id, force)
        The forces applied at frame nodes, in ground coordinates (N): constant (3,) or a
        function of time returning one.

    The generalised force on the elastic coordinates is ``-(sum_m Omega_m K0_m + sum_a c_a K0_a
    + sum_a alpha_a K0_al,a + sum_(n,a) f_na K0_na) q``, all in body coordinates: ``Omega_m``
    the six products of the frame's angular velocity ``2 G(p) dp/dt`` (order of
    :data:`~pymorembs.export.exudyn_body.CENTRIFUGAL_CASES`); ``c = A^T (r'' - g)`` the frame's
    acceleration less gravity (the load case ``ax`` is the d'Alembert load of a unit frame
    acceleration, and gravity ``g`` loads the body as a frame acceleration ``-g`` does);
    ``alpha = A^T alpha_ground`` the angular
    acceleration; ``f_n = A^T F_n(t)`` the forces applied at frame nodes. The accelerations are
    the reference node's of the current iterate (Exudyn's ``Current`` configuration), so the
    implicit solver iterates them to convergence with the rest of the step. The object's
    coordinates are the reference node's (3 positions, 4 Euler parameters as displacements from
    (1, 0, 0, 0)) followed by the elastic coordinates.
    """
    import exudyn

    nq = arrays["massMatrixReduced"].shape[0]

    def flat(key: str) -> np.ndarray | None:
        value = arrays.get(key)
        if value is None or not np.any(value):
            return None
        return np.asarray(value, dtype=float).reshape(-1, nq * nq)

    omega_k0 = flat("stiffeningOmega")
    acceleration_k0 = flat("stiffeningAcceleration")
    angular_k0 = flat("stiffeningAngularAcceleration")
    node_k0 = flat("stiffeningNodeForces")
    index_of = {int(n): i for i, n in enumerate(arrays["nodeIds"])}
    node_terms = []
    if node_k0 is not None:
        node_terms = [
            (node_k0[3 * index_of[int(n)] : 3 * index_of[int(n)] + 3], f) for n, f in forces
        ]
    g = np.zeros(3) if gravity is None else np.asarray(gravity, dtype=float)
    current = exudyn.ConfigurationType.Current
    kinds = exudyn.OutputVariableType

    def force(mbs: Any, t: float, index: int, q: Any, q_t: Any) -> list[float]:
        q, q_t = np.asarray(q), np.asarray(q_t)
        p = np.array([1.0, 0.0, 0.0, 0.0]) + q[3:7]
        p0, p1, p2, p3 = p
        gp = np.array([[-p1, p0, p3, -p2], [-p2, -p3, p0, p1], [-p3, p2, -p1, p0]])
        rotation = _euler_parameter_rotation(p)
        weights = np.zeros(nq * nq)
        if omega_k0 is not None:
            wx, wy, wz = 2.0 * gp @ q_t[3:7]
            weights += np.array([wx * wx, wy * wy, wz * wz, wx * wy, wy * wz, wx * wz]) @ omega_k0
        if acceleration_k0 is not None:
            a = np.asarray(mbs.GetNodeOutput(rigid, kinds.Acceleration, configuration=current))
            weights += (rotation.T @ (a - g)) @ acceleration_k0
        if angular_k0 is not None:
            alpha = mbs.GetNodeOutput(rigid, kinds.AngularAcceleration, configuration=current)
            weights += (rotation.T @ np.asarray(alpha)) @ angular_k0
        for k0, f in node_terms:
            weights += (rotation.T @ np.asarray(f(t) if callable(f) else f, dtype=float)) @ k0
        out = np.zeros(q.size)
        out[7:] = -(weights.reshape(nq, nq) @ q[7:])
        return out.tolist()

    return force


def _frame_with_z(axis: np.ndarray) -> np.ndarray:
    """A rotation matrix whose third column is the unit vector ``axis``."""
    helper = np.eye(3)[int(np.argmin(np.abs(axis)))]
    x = np.cross(helper, axis)
    x /= np.linalg.norm(x)
    return np.column_stack([x, np.cross(axis, x), axis])


def _checked_vector(value: Force, what: str, unit: str) -> Any:
    """A constant vector (3,) as ndarray, or a function of time returning one (checked at 0)."""
    if callable(value):
        try:
            probe = np.asarray(value(0.0), dtype=float)
        except Exception as exc:
            raise UserError(f"exudyn model: the {what} (a function of time) fails: {exc}") from None
        if probe.shape != (3,):
            raise UserError(
                f"exudyn model: the {what} (a function of time) returns shape {probe.shape}, "
                "expected (3,)"
            )
        return value
    try:
        vector = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        vector = np.full(0, np.nan)
    if vector.shape != (3,) or not np.all(np.isfinite(vector)):
        raise UserError(f"exudyn model: the {what} must be 3 finite numbers ({unit})")
    return vector


def _checked_force(node: int, force: Force, node_ids: list[int]) -> tuple[int, Any]:
    """``(node id, force)`` with a constant force as ndarray (3,); checks node and shape."""
    if int(node) not in node_ids:
        raise UserError(
            f"exudyn model: load at node {node}, which is not a frame node of the body "
            f"(nodes: {node_ids})"
        )
    return int(node), _checked_vector(force, f"load at node {node}", "N")


def _force_load(eii: Any, marker: int, force: Any, kind: str = "force") -> Any:
    """A ``LoadForceVector`` (or ``LoadTorqueVector``) in ground directions: constant, or a
    Python user function of t."""
    load = eii.LoadForceVector if kind == "force" else eii.LoadTorqueVector
    if not callable(force):
        return load(markerNumber=marker, loadVector=[float(x) for x in force])

    def user_function(mbs: Any, t: float, load_vector: Any) -> list[float]:
        return [float(x) for x in np.asarray(force(t), dtype=float)]

    return load(
        markerNumber=marker, loadVector=[0.0, 0.0, 0.0], loadVectorUserFunction=user_function
    )


def simulate_exudyn(
    model: ExudynModel,
    duration_s: float,
    step_s: float,
    nodes: Sequence[int] | None = None,
    *,
    spectral_radius: float = 0.9,
) -> ExudynResult:
    """Integrate the model in time with Exudyn's implicit generalized-alpha solver.

    Constant step size ``step_s`` (the end time is ``duration_s`` rounded to whole steps);
    Newton iterations to Exudyn's default tolerances. Every call starts again from the model's
    initial state (at rest). No console output, no solution, sensor or solver-information files.

    Parameters
    ----------
    model : ExudynModel
        From :func:`build_exudyn_model`.
    duration_s, step_s : float
        End time and step size (s).
    nodes : sequence of int, optional
        Node ids whose displacement to return; default: all frame nodes.
    spectral_radius : float
        Spectral radius at infinity of generalized-alpha (1: no numerical damping).

    Returns
    -------
    ExudynResult
        Times (s) and node displacements in ground coordinates (m) at every step, wall time (s).

    Raises
    ------
    UserError
        Bad times or an unknown node.
    NumericalError
        The solver fails.
    """
    import exudyn

    if not (np.isfinite(duration_s) and np.isfinite(step_s) and 0 < step_s <= duration_s):
        raise UserError(
            f"exudyn simulation: need 0 < step_s <= duration_s, got {step_s!r}, {duration_s!r}"
        )
    wanted = list(model.sensors) if nodes is None else [int(n) for n in nodes]
    unknown = [n for n in wanted if n not in model.sensors]
    if unknown:
        raise UserError(f"exudyn simulation: node {unknown[0]} is not a frame node of the body")
    n_steps = round(duration_s / step_s)
    settings = exudyn.SimulationSettings()
    ti = settings.timeIntegration
    ti.endTime = n_steps * step_s
    ti.numberOfSteps = n_steps
    ti.automaticStepSize = False
    ti.adaptiveStep = False
    ti.verboseMode = 0
    ti.verboseModeFile = 0
    ti.generalizedAlpha.spectralRadius = float(spectral_radius)
    settings.solution.file.write = False
    settings.solution.restart.write = False
    settings.solution.sensors.active = True
    settings.solution.sensors.writePeriod = step_s
    settings.show.computationTime = False
    settings.show.globalTimers = False
    settings.show.statistics = False
    with _quiet_exudyn():
        start = time.perf_counter()
        try:
            ok = model.mbs.SolveDynamic(settings, storeSolver=False)
        except exudyn.SolverError as exc:
            raise NumericalError(
                f"exudyn simulation: the time integration failed ({exc})"
            ) from None
        wall = time.perf_counter() - start
    if not ok:
        raise NumericalError("exudyn simulation: the time integration failed")
    displacements = {}
    times = np.zeros(0)
    for n in wanted:
        data = np.asarray(model.mbs.GetSensorStoredData(model.sensors[n]))
        times, displacements[n] = data[:, 0], data[:, 1:4]
    frame = {
        key: np.asarray(model.mbs.GetSensorStoredData(sensor))[:, 1:]
        for key, sensor in model.frame_sensors.items()
    }
    rotation = frame.get("rotation")
    return ExudynResult(
        times,
        displacements,
        wall,
        frame.get("angular_velocity"),
        None if rotation is None else rotation.reshape(-1, 3, 3),
        frame.get("coordinates"),
    )
