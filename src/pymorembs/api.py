"""The Python API: read a body, prepare it, reduce it, measure it, export it.

The command line and job files are a layer on these functions; a notebook needs nothing else::

    import pymorembs as pm

    body = pm.example("rack-beams")            # or pm.read("model.h5"), pm.read("K.mtx", ...)
    prepared = pm.prepare(body, frame=pm.Frame("tangent", node=2), inputs=[(1, "ux uy uz")])
    reduced = pm.reduce(prepared, "krylov", expansion_points_hz=[0, 500, 1000], order=30)
    error = reduced.error(band_hz=(0, 1000), points=200)
    reduced.to_sid("rack.SID_FEM", nodes=[1, 2])
    reduced.to_vtu("rack.vtu")                 # the shapes for ParaView

Frequencies are in Hz, lengths, masses and times in the FE model's units.
"""

from __future__ import annotations

import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, fields, replace
from pathlib import Path
from typing import Any

import numpy as np
import scipy.sparse as sp

from pymorembs.analysis.error import error_blocks, relative_error
from pymorembs.analysis.reference import reference_response
from pymorembs.analysis.spectrum import model_facts
from pymorembs.analysis.time_domain import (
    LoadCase,
    TimeResponse,
    clamped_reduced_system,
    simulate,
)
from pymorembs.analysis.transfer import transfer_function
from pymorembs.arguments import (
    OptionError,
    described,
    node_ids,
    number,
    number_list,
    plain,
    whole,
    whole_list,
)
from pymorembs.body import DAMPING_KEYS, Damping, ElasticBody
from pymorembs.display import html_table, one_line
from pymorembs.errors import UserError
from pymorembs.examples import build_example
from pymorembs.export.invariants import BodyInvariants
from pymorembs.export.outputs import write_outputs
from pymorembs.export.registry import DEFAULT_EXPORTS, EXPORTS, MATRIX_OUTPUTS
from pymorembs.export.source import ExportSource, body_invariants, check_before_writing
from pymorembs.frequencies import frequency_grid
from pymorembs.io.formats import read_body
from pymorembs.io.reduced_file import SavedBody, read_reduced_body, write_reduced_body
from pymorembs.kinds import FrameType, choices
from pymorembs.methods import ReductionOptions, method_options
from pymorembs.preparation import (
    Frame,
    Port,
    PreparedModel,
    StressSpec,
    check_consistency,
    check_stress_spec,
    with_inertia_loads,
    with_stress_outputs,
)
from pymorembs.preparation import prepare as prepare_body
from pymorembs.preparation.interface import InterfaceSpec, add_interface_node
from pymorembs.preparation.stiffening import (
    stiffening_from_matrices,
    stiffening_from_mesh,
    with_stiffening,
)
from pymorembs.reduction.dispatch import method_projection
from pymorembs.reduction.projection import (
    Projection,
    ReducedModel,
    reduced_model,
    without_stiff_directions,
)
from pymorembs.system import SecondOrderSystem
from pymorembs.units import detect_units

__all__ = [
    "ErrorCurve",
    "ReducedBody",
    "example",
    "facts",
    "load",
    "prepare",
    "read",
    "reduce",
]

PathLike = str | os.PathLike[str]
PortLike = Port | tuple[int, str]
DampingLike = Damping | Mapping[str, Any] | np.ndarray | sp.spmatrix | sp.sparray


#: Read the FE model of a body from the files an FE program wrote: the same function as
#: :func:`pymorembs.io.read_body`, one signature and one docstring for both names.
read = read_body


def example(name: str, **options: Any) -> ElasticBody:
    """A built-in model: ``"rack-beams"``, ``"rack-solid"`` (``dofs``, ``interface``) or
    ``"blade"`` (``elements``, ``hub_radius``)."""
    return build_example(name, **options)


def facts(body: ElasticBody, modes: int = 10) -> dict[str, Any]:
    """What ``pymorembs info`` reports of a body as it was read (frame ``"none"``).

    The dof table, massless dofs, total mass, rigid-body modes and how their count was decided,
    coordinates, units (:func:`pymorembs.units.detect_units`) and the ``modes`` lowest elastic
    eigenfrequencies (Hz), massless directions condensed exactly.
    """
    prepared = prepare_body(body, Frame("none"), allow_rigid_body_modes=True)
    out = model_facts(body, prepared, whole("modes", modes, minimum=0))
    out["units"] = detect_units(body).as_dict()
    return out


def _ports(ports: Sequence[PortLike] | None, what: str) -> list[Port] | None:
    """Ports from a list, tuple or array of :class:`Port` or (node, directions) pairs."""
    if ports is None:
        return None
    if isinstance(ports, Port) or (
        isinstance(ports, tuple | list) and len(ports) == 2 and isinstance(plain(ports[1]), str)
    ):
        raise OptionError(what, f"give a list of ports, e.g. {what}=[(1, 'ux uy uz')]")
    if isinstance(ports, np.ndarray) and ports.ndim != 2:
        raise OptionError(what, f"must be a list of (node, directions) pairs, got "
                                f"{described(ports)}")  # fmt: skip
    if not isinstance(ports, tuple | list | np.ndarray):
        raise OptionError(what, f"must be a list of Port or (node, directions) pairs, got "
                                f"{described(ports)}")  # fmt: skip
    out = []
    for port in ports:
        if isinstance(port, Port):
            out.append(port)
        elif isinstance(port, tuple | list | np.ndarray) and len(port) == 2:
            directions = plain(port[1])
            if isinstance(directions, np.ndarray):
                directions = [str(d) for d in directions.ravel()]
            out.append(Port.parse(whole(f"{what} node", port[0], minimum=None), directions))
        else:
            raise OptionError(what, f"{described(port)} is neither a Port nor a (node, "
                                    "directions) pair")  # fmt: skip
    return out


def _band(key: str, band_hz: Any) -> tuple[float, float]:
    """A band ``(f_min, f_max)`` in Hz with ``0 <= f_min < f_max``."""
    what = "(f_min, f_max) in Hz"
    f_min, f_max = number_list(key, band_hz, what, length=2, minimum=0.0)
    if not f_max > f_min:
        raise OptionError(key, f"must be {what} with f_min < f_max, got ({f_min:g}, {f_max:g})")
    return f_min, f_max


def _frame_nodes(nodes: Any) -> list[int] | None:
    """The frame nodes of an exported body (None: the port nodes)."""
    return None if plain(nodes) is None else node_ids("nodes", nodes)


def prepare(
    body: ElasticBody,
    frame: Frame | str = "none",
    *,
    node: int | None = None,
    inputs: Sequence[PortLike] | None = None,
    outputs: Sequence[PortLike] | None = None,
    interfaces: Sequence[InterfaceSpec] = (),
    inertia_loads: bool | Sequence[str] = False,
    stiffening: str | Mapping[str, PathLike] | None = None,
    stiffening_nodes: Sequence[int] = (),
    damping: DampingLike | None = None,
    stress: StressSpec | Mapping[str, Any] | None = None,
) -> PreparedModel:
    """The body in its reference frame with its inputs and outputs (paper sections 2.1-2.3).

    Parameters
    ----------
    body : ElasticBody
    frame : Frame or {"tangent", "buckens", "none"}
        The floating frame of reference: ``"tangent"`` holds ``node`` and measures from it,
        ``"buckens"`` puts the origin in the centre of gravity (free body), ``"none"`` keeps the
        model's own fixed dofs.
    node : int, optional
        The tangent frame's node (with a frame given by name).
    inputs, outputs : sequence of Port or (node, directions), optional
        Unit forces/moments in and displacements/rotations out, e.g. ``(1, "ux uy uz")``;
        outputs default to the inputs' dofs, both to the ports the model file brought.
    interfaces : sequence of InterfaceSpec
        Interface nodes added first (paper section 2.2), e.g. a rigid coupling to a hole.
    inertia_loads : bool or sequence of str
        The d'Alembert loads of the frame motion as further inputs (all twelve cases with
        ``True``, or the named ones: ``ax ay az alx aly alz wxx wyy wzz wxy wyz wxz``). Use them
        for a body that goes into a multibody code.
    stiffening : "mesh" or dict of str -> path, optional
        Geometric stiffening from the model's elements, or one Matrix Market ``K_G`` file per
        load case.
    stiffening_nodes : sequence of int
        Frame nodes whose unit forces also get their stiffening (``"mesh"`` only).
    damping : Damping, mapping or matrix, optional
        The damping of the body (default: what it carries, undamped for a model read without
        one). A :class:`~pymorembs.body.Damping` -- ``Damping("modal", ratio=0.02)`` (the
        damping ratio of every mode), ``Damping("rayleigh", alpha=2.0, beta=1e-5)``
        (``D = alpha M + beta K``, alpha in 1/s, beta in s) or ``Damping("none")`` -- or the
        same as a mapping with the keys of a job's ``[damping]`` table
        (``{"kind": "modal", "ratio": 0.02}``) replaces the body's damping model; a damping
        matrix read with the model stays and is added. A matrix, sparse or dense, shape
        (n_dof, n_dof), in the body's dof order (force x time / length), replaces the body's
        explicit damping matrix; the damping model stays.
    stress : StressSpec or mapping, optional
        Hot spots whose six stress components become further outputs (sparse rows ``C_s``):
        a :class:`~pymorembs.preparation.StressSpec` or a mapping with the keys of a job's
        ``[stress]`` table, e.g. ``{"count": 10}`` (the 10 points of highest von Mises stress in
        the static responses to every input), ``{"elements": [12, 13], "target": True}``.
        Their error ``eps_s`` is :attr:`ErrorCurve.stress`; ``target`` makes the reductions aim
        at them. Needs the body's element mesh.

    Returns
    -------
    PreparedModel
        Carries its frame (``prepared.frame``).
    """
    node = whole("node", node, minimum=None)
    if isinstance(frame, str):
        frame = Frame(frame, node)
    elif not isinstance(frame, Frame):
        raise OptionError(
            "frame", f"must be a Frame or {choices(FrameType)}, got {described(frame)}"
        )
    elif node is not None:
        raise UserError("prepare: give node only with a frame given by name")
    if isinstance(interfaces, InterfaceSpec) or not all(
        isinstance(spec, InterfaceSpec) for spec in interfaces
    ):
        raise OptionError("interfaces", "must be a list of InterfaceSpec")
    nodes = (
        [] if plain(stiffening_nodes) is None else node_ids("stiffening_nodes", stiffening_nodes)
    )
    consistency = check_consistency(body)  # a wrong dof map or unit mix: UserError, before work
    if damping is not None:
        body = _with_damping(body, damping)
    for spec in interfaces:
        body = add_interface_node(body, spec)
    ins = _ports(inputs, "inputs")
    outs = ins if outputs is None else _ports(outputs, "outputs")
    cases = _inertia_cases(inertia_loads)
    hot_spots = _stress_spec(stress)
    if hot_spots is not None:
        check_stress_spec(body, hot_spots)  # a mesh and known ids, before any work
    prepared = prepare_body(body, frame, ins, outs)
    prepared = replace(
        prepared,
        warnings=(*consistency["warnings"], *prepared.warnings),
        notes=(*consistency["notes"], *prepared.notes),
    )
    if cases is not None:
        prepared = (
            with_inertia_loads(prepared) if cases == () else with_inertia_loads(prepared, cases)
        )
    if hot_spots is not None:
        prepared = with_stress_outputs(prepared, hot_spots)
    if stiffening is not None:
        if stiffening == "mesh":
            terms = stiffening_from_mesh(prepared, nodes=nodes)
        elif isinstance(stiffening, Mapping):
            terms = stiffening_from_matrices(prepared, dict(stiffening))
        else:
            raise UserError(
                f"prepare: stiffening must be 'mesh' or a dict of load case -> K_G file, "
                f"got {stiffening!r}"
            )
        prepared = with_stiffening(prepared, terms)
    return prepared


def _with_damping(body: ElasticBody, damping: DampingLike) -> ElasticBody:
    """The body with the damping of :func:`prepare`'s ``damping`` argument."""
    if isinstance(damping, Damping):
        return body.with_damping(damping)
    if isinstance(damping, Mapping):
        values = dict(damping)
        kind = plain(values.pop("kind", None))
        if kind is None:
            raise OptionError("damping", "a mapping needs 'kind' ('modal', 'rayleigh' or 'none')")
        if not isinstance(kind, str) or kind not in DAMPING_KEYS:
            raise OptionError("damping", f"kind must be 'none', 'rayleigh' or 'modal', got "
                                         f"{described(kind)}")  # fmt: skip
        for key in values:
            if key not in DAMPING_KEYS[kind]:
                takes = ", ".join(DAMPING_KEYS[kind]) or "nothing"
                raise OptionError("damping", f"unknown key {key!r} for kind {kind!r} (it takes "
                                             f"{takes})")  # fmt: skip
        if kind == "modal" and "ratio" not in values:
            raise OptionError("damping", "kind 'modal' needs 'ratio' (e.g. 0.02)")
        try:
            return body.with_damping(Damping(kind, **values))
        except UserError as exc:
            raise OptionError("damping", str(exc)) from None
    if sp.issparse(damping) or isinstance(damping, np.ndarray):
        n = body.n_dof
        if damping.shape != (n, n):
            raise OptionError("damping", f"a damping matrix must have the shape (n_dof, n_dof) = "
                                         f"({n}, {n}), got {damping.shape}")  # fmt: skip
        if damping.dtype.kind not in "iuf":
            raise OptionError("damping", f"a damping matrix must hold real numbers, got "
                                         f"{described(damping)}")  # fmt: skip
        try:
            return replace(body, damping_matrix=sp.csr_matrix(damping, dtype=float))
        except UserError as exc:
            raise OptionError("damping", str(exc)) from None
    raise OptionError("damping", f"must be a Damping, a mapping like {{'kind': 'modal', 'ratio': "
                                 f"0.02}} or a matrix, got {described(damping)}")  # fmt: skip


def _stress_spec(value: Any) -> StressSpec | None:
    """``stress``: None, a :class:`StressSpec`, or a mapping of its keys (a job's ``[stress]``)."""
    if value is None or isinstance(value, StressSpec):
        return value
    if not isinstance(value, Mapping):
        raise OptionError("stress", f"must be a StressSpec or a dict, got {described(value)}")
    known = [f.name for f in fields(StressSpec)]
    for key in value:
        if key not in known:
            raise OptionError("stress", f"unknown key {key!r} (keys: {', '.join(known)})")
    values = dict(value)
    for key in ("nodes", "elements"):
        if key in values:
            values[key] = whole_list(f"stress.{key}", values[key], f"{key[:-1]} ids")
    if values.get("box") is not None:
        values["box"] = tuple(tuple(float(x) for x in corner) for corner in values["box"])
    return StressSpec(**values)


def _inertia_cases(value: Any) -> tuple[str, ...] | None:
    """``inertia_loads``: None (none), ``()`` (all twelve cases) or the named cases."""
    single = plain(value)
    if isinstance(single, bool):
        return () if single else None
    if isinstance(single, str):
        raise OptionError("inertia_loads", f"give a list of load cases, e.g. ['{single}']")
    if isinstance(value, np.ndarray) and value.ndim == 1:
        value = value.tolist()
    if not isinstance(value, list | tuple) or not all(isinstance(c, str) for c in value):
        raise OptionError("inertia_loads", f"must be true, false or a list of load cases "
                                           f"(ax ay az ...), got {described(value)}")  # fmt: skip
    return tuple(value) if value else None


@dataclass(frozen=True, eq=False)
class ErrorCurve:
    """The relative error of eq. 27 over a band.

    Attributes
    ----------
    frequencies_hz : ndarray, shape (n_f,)
    relative : ndarray, shape (n_f,)
        ``||H - H_r||_F / ||H||_F`` over the ports (port outputs to port inputs).
    inertia : ndarray, shape (n_f,), or None
        The same over the inertia loads (None without them).
    reference : str
        ``"full"`` or ``"surrogate"``: what ``H`` is.
    stress : ndarray, shape (n_f,), or None
        ``eps_s``: the same over the stress outputs at the hot spots under every input (None
        without them; :func:`~pymorembs.analysis.error.stress_block`).
    """

    frequencies_hz: np.ndarray
    relative: np.ndarray
    inertia: np.ndarray | None
    reference: str
    stress: np.ndarray | None = None

    @property
    def max(self) -> float:
        """The largest error over the ports."""
        return float(np.max(self.relative))

    def summary(self) -> list[tuple[str, str]]:
        """The facts ``repr`` and a notebook show, as (label, text) rows: the band, the largest
        error and where, over the inertia loads, the reference."""
        f = self.frequencies_hz
        worst = int(np.argmax(self.relative))
        rows = [
            ("band", f"{f.min():g} ... {f.max():g} Hz, {f.size} frequencies"),
            ("max", f"{self.max:.3e} at {f[worst]:.4g} Hz"),
        ]
        if self.inertia is not None:
            rows.append(("max inertia loads", f"{self.max_inertia:.3e}"))
        if self.stress is not None:
            rows.append(("max stresses", f"{self.max_stress:.3e}"))
        rows.append(("reference", self.reference))
        return rows

    def __repr__(self) -> str:
        return one_line("ErrorCurve", self.summary())

    def _repr_html_(self) -> str:
        return html_table("ErrorCurve", self.summary())

    @property
    def max_inertia(self) -> float | None:
        """The largest error over the inertia loads, or None."""
        return None if self.inertia is None else float(np.max(self.inertia))

    @property
    def max_stress(self) -> float | None:
        """The largest error over the stress outputs, or None."""
        return None if self.stress is None else float(np.max(self.stress))


@dataclass(frozen=True, eq=False)
class ReducedBody:
    """A reduced body: the prepared model, the checked reduced model and how it was made.

    Attributes
    ----------
    prepared : PreparedModel
    model : ReducedModel
        The projection (``V``, ``W``), the reduced system and its eigenfrequencies.
    options : ReductionOptions
        The method and its options.
    name : str
        Used in exported files.
    before_removal : ReducedModel or None
        The reduced model before its eigen-directions above ``options.max_frequency_hz`` were
        removed (None: nothing was removed), to measure what the removal costs.
    """

    prepared: PreparedModel
    model: ReducedModel
    options: ReductionOptions
    name: str = "body"
    before_removal: ReducedModel | None = None

    @property
    def method(self) -> str:
        return self.options.method

    def summary(self) -> list[tuple[str, str]]:
        """The facts ``repr`` and a notebook show, as (label, text) rows: method and options,
        order, eigenfrequencies, the body, frame, inputs and outputs, damping."""
        given = self.options.given()
        options = ", ".join(f"{key}={value}" for key, value in given.items())
        rows = [("method", f"{self.method}" + (f" ({options})" if options else "")),
                ("body", f"{self.prepared.body.name!r}")]  # fmt: skip
        model = self.model.summary()
        rows += [row for row in model if row[0] in ("order", "eigenfrequencies")]
        if self.before_removal is not None:
            removed = self.before_removal.projection.order - self.order
            rows.append(("removed", f"{removed} directions above {self.options.max_frequency_hz:g}"
                                    " Hz"))  # fmt: skip
        rows += [row for row in self.prepared.summary() if row[0] == "frame"]
        rows += [row for row in model if row[0].startswith(("inputs", "outputs", "damping"))]
        return rows

    def __repr__(self) -> str:
        return one_line(f"ReducedBody {self.name!r}", self.summary())

    def _repr_html_(self) -> str:
        return html_table(f"ReducedBody {self.name!r}", self.summary())

    @property
    def projection(self) -> Projection:
        return self.model.projection

    @property
    def system(self) -> SecondOrderSystem:
        """The reduced second-order system (``M = I``, ``K = diag(w^2)`` for Galerkin bases)."""
        return self.model.system

    @property
    def order(self) -> int:
        return self.model.projection.order

    @property
    def eigenfrequencies_hz(self) -> np.ndarray:
        return self.model.eigenfrequencies_hz

    @property
    def basis(self) -> np.ndarray:
        """``V`` on all dofs of the prepared body (eq. 18), shape (n_dof, order)."""
        return self.prepared.expand(self.model.projection.V)

    def error(
        self,
        band_hz: tuple[float, float],
        points: int = 400,
        reference: str = "full",
        workers: int | None = 1,
    ) -> ErrorCurve:
        """The relative error of eq. 27 against the full model over a band.

        Parameters
        ----------
        band_hz : (f_min, f_max)
            Band in Hz; ``points`` log-spaced frequencies (plus 0 Hz when f_min = 0).
        reference : {"full", "surrogate", "auto"}
            ``"full"``: the full model at every frequency (one sparse factorization each);
            ``"surrogate"``: a reference model checked against the full model at the maximum of
            the error and a few other frequencies (large models).
        workers : int, optional
            Processes for the full model's frequency sweep.
        """
        reference = plain(reference)
        if reference not in ("full", "surrogate", "auto"):
            raise UserError(f"error: reference must be 'full', 'surrogate' or 'auto', got "
                            f"{described(reference)}")  # fmt: skip
        f_min, f_max = _band("band_hz", band_hz)
        frequencies = frequency_grid(f_min, f_max, whole("points", points))
        workers = whole("workers", workers)
        system = self.prepared.reduction_system
        if system.input_matrix.shape[1] == 0 or system.output_matrix.shape[0] == 0:
            raise UserError("error: the prepared model has no inputs or no outputs to compare")
        ref = reference_response(system, frequencies, reference, workers=workers)
        response = transfer_function(self.model.system, frequencies)
        ref = ref.settled(response)  # the maximum on a frequency checked against the full model
        ports, inertia = error_blocks(system)
        return ErrorCurve(
            frequencies,
            relative_error(ref.response, response, ports),
            None if inertia is None else relative_error(ref.response, response, inertia),
            ref.kind,
            ref.stress_errors(response),
        )

    def save(self, path: PathLike) -> Path:
        """Write the body to an HDF5 file that :func:`load` reads back (conventionally
        ``.h5``): everything it holds -- the prepared model with its sparse matrices, the bases
        and the reduced matrices, options and name -- so that the loaded body gives the same
        error curves and exported files. Written atomically; the layout is in ``docs/api.md``
        ("Saving and loading"), readable with h5py alone."""
        saved = SavedBody(self.prepared, self.model, self.method, self.options.given(),
                          self.name, self.before_removal)  # fmt: skip
        return write_reduced_body(path, saved)

    def invariants(self, nodes: Sequence[int] | None = None) -> BodyInvariants:
        """The mass invariants (SID_NOTES section 4) with these frame nodes (default: the port
        nodes)."""
        return body_invariants(
            self.model, self.prepared, self._nodes(_frame_nodes(nodes)), self.name
        )

    def to_sid(self, path: PathLike, nodes: Sequence[int] | None = None) -> Path:
        """Write the body as a SID file (Simpack, ``.SID_FEM``), checked before it is written."""
        return self._write("sid", path, nodes)

    def to_exudyn(self, path: PathLike, nodes: Sequence[int] | None = None) -> Path:
        """Write the body for Exudyn's ``ObjectFFRFreducedOrder`` (``.npz``), with the surface
        triangles Exudyn's renderer draws (:func:`~pymorembs.export.exudyn_body.surface_mesh`)."""
        return self._write("exudyn", path, nodes)

    def to_neweul(self, path: PathLike, nodes: Sequence[int] | None = None) -> Path:
        """Write the body as Neweul-M² data (``.mat``)."""
        return self._write("neweul", path, nodes)

    def to_vtu(self, path: PathLike) -> Path:
        """Write the surface with every shape function and the static response to every input
        as a VTU file for ParaView (:mod:`pymorembs.export.vtu`: array names and units)."""
        return self._write("vtu", path)

    def to_stress_recovery(self, path: PathLike) -> Path:
        """Write the stress and strain modes of every shape function and static response at the
        integration points and nodes (HDF5, conventionally ``<name>.stress.h5``;
        :mod:`pymorembs.export.recovery`, layout in ``docs/recovery.md``)."""
        return self._write("stress_recovery", path)

    def to_matrices(self, folder: PathLike, formats: Sequence[str] = DEFAULT_EXPORTS) -> list[Path]:
        """Write the reduced matrices (``reduced.npz``, ``M K D B C.mtx``, ``reduced.mat``):
        ``formats`` of :data:`~pymorembs.export.registry.MATRIX_OUTPUTS` (default
        ``npz``, ``mtx``)."""
        given = formats
        formats = [formats] if isinstance(plain(formats), str) else formats
        if isinstance(formats, np.ndarray) and formats.ndim == 1:
            formats = [plain(f) for f in formats]
        quoted = ", ".join(f"'{kind}'" for kind in MATRIX_OUTPUTS)
        if not isinstance(formats, list | tuple) or not all(isinstance(f, str) for f in formats):
            raise OptionError("formats", f"must be a list of {quoted}, got {described(given)}")
        unknown = sorted(set(formats) - set(MATRIX_OUTPUTS))
        if unknown:
            raise UserError(f"to_matrices: unknown formats {unknown} ({', '.join(MATRIX_OUTPUTS)})")
        folder = Path(folder)
        if folder.exists() and not folder.is_dir():
            raise UserError(f"to_matrices: {folder} exists and is not a folder")
        folder.mkdir(parents=True, exist_ok=True)
        names = write_outputs(self.model, self.prepared, self.name, list(formats), [], folder)
        return [folder / name for name in names]

    def simulate(
        self,
        load_cases: Sequence[LoadCase],
        *,
        clamp_node: int,
        load_node: int,
        duration_s: float = 0.2,
        step_s: float = 5e-5,
        rho_inf: float = 0.8,
    ) -> TimeResponse:
        """The linear response of the body held at ``clamp_node`` to forces at ``load_node``.

        The reduced model clamped by a rigid joint (:func:`~pymorembs.analysis.time_domain.
        clamped_reduced_system`: a tangent frame at the node, or the linearised floating body
        on the joint otherwise), integrated from rest by the generalized-alpha method.

        Parameters
        ----------
        load_cases : sequence of LoadCase
            Force histories along x, y, z of ``load_node`` (N), e.g. ``LoadCase("step", "step",
            [0, 0, -100])``.
        clamp_node, load_node : int
            Node ids (the clamp node needs all six dofs unless the frame holds it).
        duration_s, step_s : float
            End time and fixed step (s).
        rho_inf : float
            Spectral radius of the generalized-alpha method at infinite frequency.

        Returns
        -------
        TimeResponse
            Displacements of ``load_node`` (m) per load case.
        """
        if isinstance(load_cases, LoadCase) or not all(
            isinstance(case, LoadCase) for case in load_cases
        ):
            raise OptionError("load_cases", "must be a list of LoadCase")
        clamp = whole("clamp_node", clamp_node, minimum=None)
        load = whole("load_node", load_node, minimum=None)
        duration, step = number("duration_s", duration_s), number("step_s", step_s)
        if not 0 < step <= duration:
            raise OptionError("step_s", f"must lie in (0, duration_s], got {step!r}")
        system = clamped_reduced_system(
            self.prepared.body, self.basis, np.asarray(self.system.mass),
            np.asarray(self.system.stiffness), self.model.damping_matrix, clamp, load,
        )  # fmt: skip
        return simulate(system, list(load_cases), duration, step, number("rho_inf", rho_inf))

    def _write(self, kind: str, path: PathLike, nodes: Sequence[int] | None = None) -> Path:
        """Write the one file of the export ``kind`` (:data:`~pymorembs.export.registry.EXPORTS`)
        at ``path``, after :func:`~pymorembs.export.source.check_before_writing`; a body for a
        multibody code with these frame nodes (default: the port nodes)."""
        check_before_writing(self.model, self.name)
        export = EXPORTS[kind]
        options = None
        if export.options is not None:
            options = export.options(nodes=tuple(self._nodes(_frame_nodes(nodes))))
        target = Path(path)
        export.write(ExportSource(self.model, self.prepared, self.name), options, (target,))
        return target

    def _nodes(self, nodes: Sequence[int] | None) -> list[int]:
        if nodes is not None:
            return [int(n) for n in nodes]
        labels = (*self.prepared.system.input_labels, *self.prepared.system.output_labels)
        found = []
        for label in labels:
            head = str(label).split(":")[0]
            if head.isdigit():
                found.append(int(head))
        if not found:
            raise UserError(f"{self.name}: give the frame nodes of the exported body (nodes=[...])")
        return list(dict.fromkeys(found))


def load(path: PathLike) -> ReducedBody:
    """Read a reduced body written by :meth:`ReducedBody.save`.

    Raises
    ------
    UserError
        One line naming the file: missing, not such a file (an FE model: read it with
        :func:`read`), of a newer format version, incomplete or damaged.
    """
    saved = read_reduced_body(path)
    try:
        options = method_options(saved.method, saved.options)
    except UserError as exc:
        raise UserError(f"{path}: /options: {exc}") from None
    return ReducedBody(saved.prepared, saved.model, options, saved.name, saved.before_removal)


def reduce(
    prepared: PreparedModel,
    method: str | ReductionOptions,
    *,
    band_hz: tuple[float, float] | None = None,
    name: str | None = None,
    **options: Any,
) -> ReducedBody:
    """Reduce a prepared model with one method (paper section 3).

    Parameters
    ----------
    prepared : PreparedModel
    method : str or ReductionOptions
        One of :data:`pymorembs.methods.METHODS`: ``modal``, ``craig-bampton``, ``krylov``,
        ``soaga``, ``gramian``, ``pod``; or a checked options object of one
        (:func:`~pymorembs.methods.method_options`), then without further ``options``.
    band_hz : (f_min, f_max), optional
        The band (Hz) of the band-aware methods (``soaga``, ``gramian``, ``pod``); required
        for them.
    name : str, optional
        Name of the body in exported files (default: the method).
    **options
        The method's options (:mod:`pymorembs.methods`), e.g. ``order=30``,
        ``expansion_points_hz=[0, 500]``, ``tolerance=1e-6``, ``max_frequency_hz=2000``.

    Returns
    -------
    ReducedBody
        Checked (finite, symmetric, positive reduced matrices) before it is returned.
    """
    if isinstance(method, ReductionOptions):
        if options:
            raise UserError(f"reduce: options {sorted(options)} beside an options object")
        settings = method
    else:
        settings = method_options(method, options)
    if band_hz is None:
        if settings.method in ("soaga", "gramian", "pod"):
            raise UserError(f"reduce: {settings.method} needs band_hz=(f_min, f_max) in Hz")
        band_hz = (0.0, 1.0)
    band = _band("band_hz", band_hz)
    system = prepared.reduction_system
    model = reduced_model(system, method_projection(system, settings, band))
    before = None
    limit = settings.max_frequency_hz
    if limit is not None and model.eigenfrequencies_hz.max() > limit:
        before, model = model, without_stiff_directions(system, model, limit)
    name = settings.method if name is None else str(name)
    return ReducedBody(prepared, model, settings, name, before)
