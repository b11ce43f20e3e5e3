"""A reduction job end to end: model -> prepare -> reduce (each method) -> check -> write.

All files of a run are written into a temporary folder next to the output folder, which replaces
the output folder only when the whole job succeeded: a failed run leaves no partial output.
"""

from __future__ import annotations

import contextlib
import dataclasses
import errno
import hashlib
import importlib.metadata
import json
import os
import platform
import shutil
import signal
import tempfile
import threading
import time
from collections.abc import Callable, Iterator, Mapping
from pathlib import Path
from typing import Any

import numpy as np
import scipy

from pymorembs import (
    DIRECTIONS,
    AccuracyNotMet,
    ElasticBody,
    InterfaceSpec,
    NumericalError,
    PreparedModel,
    PymorembsError,
    ReducedModel,
    SecondOrderSystem,
    UserError,
    __version__,
    example,
    reduce,
    select_nodes,
)
from pymorembs.analysis import (
    HISTORY_FILE,
    ReferenceResponse,
    choose_kind,
    clamped_full_system,
    error_blocks,
    frequency_grid,
    history_arrays,
    large_motion_checks,
    reference_response,
    relative_error,
    transfer_function,
)
from pymorembs.export import (
    BODY_OUTPUTS,
    MATRIX_OUTPUTS,
    stress_modes_note,
    write_npz,
    write_outputs,
)
from pymorembs.io import atomic_path, check_output_folder, model_files, read_body, write_text
from pymorembs.job.schema import Job, ModelSpec, ReductionSpec
from pymorembs.job.summary import (
    Accuracy,
    InertiaErrors,
    JobSummary,
    ReductionSummary,
    StressErrors,
)
from pymorembs.job.time_domain_checks import time_domain_checks
from pymorembs.linalg import SharedFactors, default_backend, mass_split, shared_factorizations
from pymorembs.preparation import (
    ValidationReport,
    add_interface_node,
    check_stress_spec,
    inertia_load_cases,
    prepare,
    stiffening_from_matrices,
    stiffening_from_mesh,
    validate_body,
    validate_prepared,
    with_inertia_loads,
    with_stiffening,
    with_stress_outputs,
)
from pymorembs.progress import Progress as ProgressBar
from pymorembs.reduction import (
    Projection,
    aims_at_stresses,
    expansion_candidates,
    explicit_step_s,
    first_stage,
    method_projection,
)
from pymorembs.report import (
    plot_decay,
    plot_large_motion,
    plot_large_motion_stresses,
    plot_relative_errors,
    reductions_scene,
    write_report,
)
from pymorembs.stress import StressOperator
from pymorembs.units import band_unit_warnings, detect_units, frequency_warnings

Progress = Callable[[str], None]

#: Parameters of a projection that hold descending singular values, and their labels in the
#: decay plot (paper Fig. 11).
DECAY_SERIES = (
    ("approximate_hsv", "approximate HSV (eq. 26)"),
    ("sigma", "eigenvalues of P_p + Q_pv (indicator)"),
)


def load_model(spec: ModelSpec) -> ElasticBody:
    """The body a job's ``[model]`` names: a built-in example or model files of any format."""
    if spec.example is not None:
        return example(spec.example, **spec.options.given())
    return read_body(format=spec.format, **spec.files, **spec.names)


def load_job_model(job: Job) -> ElasticBody:
    """The model of a job with its interface nodes; errors name the job file and ``[model]``."""
    try:
        body = load_model(job.model)
    except UserError as exc:
        raise UserError(f"{job.path}: [model]: {exc}") from None
    return add_interfaces(body, job)


def add_interfaces(body: ElasticBody, job: Job) -> ElasticBody:
    """The body with the job's ``[[interface]]`` nodes added and coupled (paper section 2.2)."""
    for k, spec in enumerate(job.interfaces, start=1):
        try:
            coupled = select_nodes(body, ids=spec.ids, cylinder=spec.cylinder, box=spec.box)
            body = add_interface_node(
                body,
                InterfaceSpec(
                    node=spec.node,
                    position=spec.position,
                    coupled=tuple(int(n) for n in coupled),
                    kind=spec.kind,
                    **spec.parameters,
                ),
            )
        except UserError as exc:
            raise UserError(f"{job.path}: [[interface]] #{k}: {exc}") from None
    return body


def job_interfaces(body: ElasticBody, job: Job) -> list[tuple[str, int, np.ndarray]]:
    """The job's interface nodes and the nodes each is coupled to, for the viewer.

    ``body`` is the model with the interfaces added (:func:`add_interfaces`); the coupled nodes
    are selected again as :func:`add_interfaces` did, leaving out the interface nodes that were
    not there yet (the selection tests every node alone, so the result is the same).

    Returns
    -------
    list of (name, node id, coupled node ids)
    """
    added = np.array([spec.node for spec in job.interfaces], dtype=np.int64)
    out = []
    for k, spec in enumerate(job.interfaces):
        coupled = select_nodes(body, ids=spec.ids, cylinder=spec.cylinder, box=spec.box)
        coupled = coupled[~np.isin(coupled, added[k:])]
        out.append((f"interface {spec.node} ({spec.kind})", int(spec.node), coupled))
    return out


def prepare_job(job: Job) -> tuple[ElasticBody, PreparedModel]:
    """Load the model of a job, add its interface nodes, set its damping and prepare it.

    The O(nnz) checks of :mod:`pymorembs.preparation.validation` run on the way (not the
    factorization); see :func:`prepare_and_validate`.
    """
    body, prepared, _ = prepare_and_validate(job, deep=False)
    return body, prepared


def prepare_and_validate(
    job: Job, deep: bool = True
) -> tuple[ElasticBody, PreparedModel, ValidationReport]:
    """Load, check and prepare the model of a job; nothing expensive runs before the checks.

    Order: model and interfaces; :func:`~pymorembs.preparation.validation.validate_body` (sizes,
    symmetry, finiteness, diagonals, constraints, the job's nodes and ports);
    :func:`check_requests` (export and time-domain requests); frame and elimination (with the
    structural rigid-body-mode check of :func:`~pymorembs.preparation.prepare`);
    :func:`~pymorembs.preparation.validation.validate_prepared` (dangling and free dofs, orders,
    inputs, and with ``deep`` one factorization for inertia and mechanisms).

    Returns
    -------
    body : ElasticBody
        The body with interfaces and the job's damping.
    prepared : PreparedModel
    report : ValidationReport
    """
    body = load_job_model(job)
    if job.damping is not None:
        body = body.with_damping(job.damping)
    report = validate_job_body(body, job)
    check_requests(job, body)
    if job.stress is not None:  # the hot spots' ids and the mesh: cheap, before the frame
        try:
            check_stress_spec(body, job.stress)
        except UserError as exc:
            raise UserError(f"{job.path}: {exc}") from None
    try:
        prepared = prepare(body, job.frame, list(job.inputs), list(job.outputs))
    except PymorembsError as exc:  # also a massless mechanism that K cannot have (exit 3)
        raise type(exc)(f"{job.path}: {exc}") from None
    check_job_orders(prepared, job, report)  # cheap: before the factorization
    try:
        deep_report = validate_prepared(prepared, deep=deep)
    except PymorembsError as exc:
        raise type(exc)(f"{job.path}: {exc}") from None
    return body, prepared, report.merge(deep_report)


def validate_job_body(body: ElasticBody, job: Job) -> ValidationReport:
    """:func:`~pymorembs.preparation.validation.validate_body`, then the job's nodes on the body."""
    try:
        report = validate_body(body)
    except PymorembsError as exc:
        raise type(exc)(f"{job.path}: {exc}") from None
    check_job_nodes(body, job, report)
    return report


def _where(job: Job, key: str) -> str:
    """The prefix ``file: key: `` of a message about a job."""
    return f"{job.path}: {key}: "


def check_job_nodes(body: ElasticBody, job: Job, report: ValidationReport) -> None:
    """Nodes the job names exist; no port acts on a dof the model fixes itself."""
    fixed = set(int(i) for i in body.fixed)
    for key, ports in (("[[inputs]]", job.inputs), ("[[outputs]]", job.outputs)):
        for k, port in enumerate(ports, start=1):
            where = _where(job, f"{key} #{k}")
            indices = body.dofs.of_node(port.node)
            if indices.size == 0:
                raise UserError(f"{where}node {port.node} has no dofs in the model")
            for code in port.directions:
                try:
                    index = body.dofs.index(port.node, code)
                except UserError as exc:
                    raise UserError(f"{where}{exc}") from None
                if index in fixed:
                    raise UserError(
                        f"{where}node {port.node} {DIRECTIONS[code]} is a fixed dof of the "
                        "model (a support): a force there acts on the ground; choose a free dof "
                        "or remove the support"
                    )
    if job.frame.kind == "tangent" and job.frame.node is not None:
        if body.dofs.of_node(job.frame.node).size == 0:
            raise UserError(
                f"{_where(job, '[frame]')}node {job.frame.node} does not exist in the model "
                "(or has no dofs)"
            )
    report.checks.append("nodes of the job")


def check_job_orders(prepared: PreparedModel, job: Job, report: ValidationReport) -> None:
    """The job's reduction orders lie below the number of independent dofs and hold at least
    one block of inputs where a method builds its basis from such blocks; its inputs reach the
    elastic body."""
    system = prepared.system
    n = system.order
    inputs = np.asarray(system.input_matrix)
    if inputs.size and not np.any(inputs):
        raise UserError(
            f"{job.path}: [[inputs]]: every input acts on a fixed dof of the frame; the "
            "elastic body has no input to reduce for (choose inputs away from the frame node)"
        )
    block = None
    for k, spec in enumerate(job.reductions, start=1):
        if spec.order is not None and spec.order >= n:
            raise UserError(
                f"{job.path}: [[reduction]] #{k}.order: {spec.order} is not below the "
                f"{n} independent dofs of the model; choose a smaller order"
            )
        fixed_modes = getattr(spec.options, "fixed_modes", None)
        if fixed_modes is not None and fixed_modes >= n:
            raise UserError(
                f"{job.path}: [[reduction]] #{k}.fixed_modes: {fixed_modes} is not below the "
                f"{n} independent dofs of the model"
            )
        key, order = _block_order(spec, n)
        if order is None:
            continue
        block = block or InputBlock.of(prepared, job)
        needed, what = block.columns(two_sided=getattr(spec.options, "two_sided", False))
        if order < needed < n:  # (a block as large as the model: no reduction keeps it)
            raise UserError(
                f"{job.path}: [[reduction]] #{k}.{key}: {order} is below one block of the "
                f"{what}, the first block of a {spec.method} basis; "
                + _block_remedy(spec, key, needed, block)
            )
    report.checks.append("orders and inputs of the job")


@dataclasses.dataclass(frozen=True)
class InputBlock:
    """The columns of one block of a block Krylov space: the port inputs and outputs that reach
    the elastic body, and the inertia loads the job adds to both (collocated).

    Attributes
    ----------
    inputs, outputs : int
        Port inputs (outputs) that are not zero on the independent dofs (a port on a fixed
        frame dof adds nothing).
    loads : tuple of str
        The inertia load cases that will be inputs and outputs
        (:func:`~pymorembs.preparation.inertia_load_cases`).
    """

    inputs: int
    outputs: int
    loads: tuple[str, ...]

    @classmethod
    def of(cls, prepared: PreparedModel, job: Job) -> InputBlock:
        """The block of a prepared model (before its inertia loads are added) and a job."""
        system = prepared.system
        inputs = np.asarray(system.input_matrix)
        outputs = np.asarray(system.output_matrix)
        loads: tuple[str, ...] = ()
        if job.inertia_loads.active(job.export.outputs):
            loads = inertia_load_cases(prepared, job.inertia_loads.cases)
        return cls(
            int(np.count_nonzero(np.any(inputs != 0, axis=0))),
            int(np.count_nonzero(np.any(outputs != 0, axis=1))),
            loads,
        )

    def columns(self, two_sided: bool = False) -> tuple[int, str]:
        """The columns of one block (the larger of input and output blocks for a two-sided
        projection) and how they are made up, e.g. ``"13 inputs (3 port inputs + 10 inertia
        loads)"``."""
        count, kind = self.inputs, "input"
        if two_sided and self.outputs > self.inputs:
            count, kind = self.outputs, "output"
        total = count + len(self.loads)
        if not self.loads:
            return total, f"{total} {kind}s"
        return total, f"{total} {kind}s ({count} port {kind}s + {len(self.loads)} inertia loads)"


def _block_order(spec: ReductionSpec, n_dofs: int) -> tuple[str, int | None]:
    """The key and value of the order a reduction builds from blocks of inputs (None: none).

    ``krylov``: its ``order`` (the basis size, or the cap of its ``moments``); ``soaga``: its
    ``order`` (the largest order); ``gramian``: a given ``first_order`` of the medium model
    (or of the rational Krylov space) the Gramians are computed from, where there is one.
    """
    if spec.method in ("krylov", "soaga"):
        return "order", spec.order
    if spec.method == "gramian" and first_stage(spec.options.first_stage, n_dofs) != "none":
        return "first_order", spec.options.first_order
    return "order", None


def _block_remedy(spec: ReductionSpec, key: str, needed: int, block: InputBlock) -> str:
    """What to do about an order below one block of inputs."""
    options = [f"raise the {key.replace('_', ' ')} to >= {needed}"]
    if spec.method == "soaga":
        options.append("give 'tolerance' without 'order' (the order chosen by the error)")
    elif spec.method == "krylov":
        options.append("use SOAGA (order chosen by the error)")
    if block.loads:
        options.append("fewer inertia loads ([inertia_loads] cases)")
    return ", ".join(options[:-1]) + f" or {options[-1]}"


def run_reduction(
    system: SecondOrderSystem, spec: ReductionSpec, band_hz: tuple[float, float]
) -> Projection:
    """Run one reduction method on a prepared system (band in Hz for the band-aware methods)."""
    return method_projection(system, spec.options, band_hz)


#: A reduction whose error under the inertia loads exceeds this and ...
INERTIA_WARNING = 1e-2
#: ... this many times its error over the ports gets a warning: it misses a direction the frame
#: motion excites.
INERTIA_RATIO = 100.0


def export_nodes(job: Job) -> list[int]:
    """The frame nodes of the exported body: ``[export] nodes``, else the port nodes.

    The clamp and load nodes of ``[time_domain]`` are added (the multibody check needs them).
    """
    if job.export.nodes is not None:
        nodes = list(job.export.nodes)
    else:
        nodes = [port.node for port in (*job.inputs, *job.outputs)]
    if job.time_domain is not None:
        nodes += [job.time_domain.load_node, job.time_domain.clamp_node]
    return list(dict.fromkeys(nodes))


def check_requests(job: Job, body: ElasticBody) -> None:
    """Reject export and time-domain requests that cannot be met, before any expensive step.

    Raises
    ------
    UserError
        A frame node of ``[export]`` or a node of ``[time_domain]`` is not in the model or
        lacks the dofs it needs; a body output of a two-sided reduction; a time-domain check
        without viscous damping.
    """

    def dofs_of(node: int, key: str) -> set[int]:
        indices = body.dofs.of_node(node)
        if indices.size == 0:
            raise UserError(f"{job.path}: {key}: node {node} has no dofs in the model")
        return {int(d) for d in body.dofs.directions[indices]}

    if not job.inputs and (body.ports is None or body.ports.inputs is None):
        raise UserError(
            f"{job.path}: [[inputs]] is missing and the model brings no input matrix B of its "
            "own; give [[inputs]] (node and directions)"
        )
    wants_body = any(kind in job.export.outputs for kind in BODY_OUTPUTS)
    if job.large_motion is not None:
        _check_large_motion(job, body, dofs_of)
    spec = job.time_domain
    if "vtu" in job.export.outputs and not body.has_coordinates:
        raise UserError(
            f"{job.path}: the model has no node coordinates, which the VTU file ([export] "
            'outputs = ["vtu"]) needs; give the nodes (nodes = nodes.csv or the FE input file)'
        )
    if (wants_body or spec is not None) and not body.has_coordinates:
        raise UserError(
            f"{job.path}: the model has no node coordinates, which the "
            f"{'[time_domain] check' if spec is not None else 'bodies for multibody codes'} "
            "need; give the nodes (nodes = nodes.csv or the FE input file) or write only "
            f"matrices ([export] outputs = {json.dumps(list(MATRIX_OUTPUTS))})"
        )
    if wants_body or (spec is not None and spec.exudyn):
        for node in export_nodes(job):
            if not {0, 1, 2} <= dofs_of(node, "[export] nodes"):
                raise UserError(
                    f"{job.path}: [export] nodes: node {node} lacks translational dofs "
                    "(a frame node of the body needs ux uy uz)"
                )
        _require_one_sided(job, "SID, Neweul-M² and Exudyn bodies need", "or write only matrices")
    if spec is None:
        return
    if not {0, 1, 2} <= dofs_of(spec.load_node, "[time_domain] load_node"):
        raise UserError(
            f"{job.path}: [time_domain] load_node: node {spec.load_node} lacks ux uy uz"
        )
    held_by_frame = job.frame.kind == "tangent" and job.frame.node == spec.clamp_node
    clamp_dofs = dofs_of(spec.clamp_node, "[time_domain] clamp_node")
    if not held_by_frame and clamp_dofs != set(range(6)):
        raise UserError(
            f"{job.path}: [time_domain] clamp_node: node {spec.clamp_node} needs all six dofs "
            "to clamp a body whose frame is elsewhere (add an interface node there)"
        )
    if body.damping.kind == "modal":
        raise UserError(
            f"{job.path}: [time_domain]: modal damping is a loss factor in the frequency domain "
            "and has no damping matrix of the full model; use Rayleigh damping "
            '([damping] kind = "rayleigh")'
        )
    clamped = clamped_full_system(body, spec.clamp_node, spec.load_node)
    if not np.any(clamped.input_matrix):
        raise UserError(
            f"{job.path}: [time_domain]: node {spec.load_node} cannot move when the body is "
            f"clamped at node {spec.clamp_node} (both on one rigid part?); choose other nodes"
        )


def _require_one_sided(job: Job, what: str, alternative: str = "") -> None:
    """Refuse two-sided reductions where bodies are needed (``what``: who needs them)."""
    for reduction in job.reductions:
        if getattr(reduction.options, "two_sided", False):
            raise UserError(
                f"{job.path}: reduction '{reduction.name}': {what} a one-sided (Galerkin) "
                f"projection; drop two_sided {alternative}".rstrip()
            )


def _check_large_motion(job: Job, body: ElasticBody, dofs_of: Callable) -> None:
    """``[large_motion]`` needs Exudyn, coordinates, one-sided reductions and a joint it can
    act on (the frame's node, or a node with all six dofs)."""
    spec = job.large_motion
    try:
        import exudyn  # noqa: F401
    except ImportError:
        raise UserError(
            f"{job.path}: [large_motion] needs Exudyn (pip install exudyn), which is not installed"
        ) from None
    if not body.has_coordinates:
        raise UserError(f"{job.path}: [large_motion] needs node coordinates; the model has none")
    directions = dofs_of(spec.joint_node, "[large_motion] joint_node")
    on_frame = (job.frame.kind == "tangent" and job.frame.node == spec.joint_node) or (
        job.frame.kind == "none" and body.fixed.size > 0
    )
    if not on_frame and directions != set(range(6)):
        raise UserError(
            f"{job.path}: [large_motion] joint_node: node {spec.joint_node} needs all six dofs "
            "for a hinge on a body whose frame is elsewhere (add an interface node there, or "
            "use a tangent frame at it)"
        )
    _require_one_sided(job, "[large_motion] needs")


def run_job(
    job: Job,
    out_dir: str | Path,
    progress: Progress | None = None,
    workers: int | None = 1,
    scheduler: str | None = None,
) -> JobSummary:
    """Run ``job`` and write its results into ``out_dir``; return the summary (written as
    ``summary.json`` by its :meth:`~pymorembs.job.summary.JobSummary.to_json`).

    Written: ``summary.json``, ``error.png`` (all reductions), per reduction a folder with the
    files of ``[export] outputs``, ``error.csv`` and ``error.png``, and with ``[time_domain]``
    ``time.png``. A reduction whose max error ε (ports and inertia loads) exceeds its limit
    (:attr:`~pymorembs.job.schema.ReductionSpec.accuracy_limit`) gets only its error files,
    unless it says ``export_inaccurate = true``; its summary entry's ``accuracy`` says so.

    Parameters
    ----------
    job : Job
        The job.
    out_dir : str or Path
        Output folder.
    progress : callable, optional
        Receives one line per stage and per warning.
    workers : int or None
        Processes for the frequency response of the full model (default 1; None: the usable
        cores for models of 3,000 dofs and more, as the command line does; see
        :func:`pymorembs.analysis.transfer.transfer_function`). The results do not depend on
        it.
    scheduler : str, optional
        ``"local"`` or a Dask scheduler address to run that frequency response on.

    Raises
    ------
    AccuracyNotMet
        After everything was written, when a reduction missed its accuracy limit and its body
        files were therefore not written (``exc.summary`` is the summary).
    UserError
        Bad input (before any expensive step), or an output device that is full, over its
        quota or read-only (the output folder is then left as it was).
    """
    say = progress or (lambda _msg: None)
    n_stages = job.stage_count()
    started = [False]
    with ProgressBar(f"job {Path(job.path).stem}", total=n_stages, unit="stage", every=1) as bar:

        def stage(message: str, short: str, line: bool = True) -> None:
            """A new stage: one step of the bar (``short`` after it) and the line ``message``."""
            if started[0]:
                bar.update()
            started[0] = True
            bar.describe(short)
            if line:
                say(message)

        return _run_job(job, Path(out_dir), say, stage, workers, scheduler)


def _run_job(
    job: Job,
    out_dir: Path,
    say: Progress,
    stage: Callable[..., None],
    workers: int | None,
    scheduler: str | None,
) -> JobSummary:
    """The steps of :func:`run_job`: prepare, reference, reductions, checks, summary."""
    check_output_folder(out_dir)  # a file in the way fails now, not after all the work
    with output_errors(out_dir), _staging(out_dir) as staging:  # an unwritable device: now
        with shared_factorizations() as shared:  # one factor per matrix for all the steps
            summary = _run_in(job, staging, say, stage, workers, scheduler, shared)
    failed = [r for r in summary.reductions if not r.accuracy.exported]
    if failed:
        raise AccuracyNotMet(_accuracy_message(job, failed), summary)
    return summary


def _accuracy_message(job: Job, failed: list[ReductionSummary]) -> str:
    """The one line of :class:`AccuracyNotMet`: the reductions, their errors and limits."""
    parts = []
    for entry in failed:
        accuracy = entry.accuracy
        where = f"ports {accuracy.ports:.2g}"
        if accuracy.inertia_loads is not None:
            where += f", inertia loads {accuracy.inertia_loads:.2g}"
        if accuracy.stress is not None:
            where += f", stresses {accuracy.stress:.2g}"
        parts.append(
            f"reduction '{entry.name}' max error {accuracy.max:.2g} > "
            f"{accuracy.limit:.2g} ({where})"
        )
    its = "its" if len(failed) == 1 else "their"
    aim = _stress_remedy(job, failed)
    return (
        f"{job.path}: accuracy not met: {'; '.join(parts)}; {its} body files were not written "
        f"(summary.json and the error plots were): raise the order, choose another method, {aim}"
        f"or set export_inaccurate = true in {its} [[reduction]] to write them anyway"
    )


def _stress_remedy(job: Job, failed: list[ReductionSummary]) -> str:
    """The remedy for reductions that missed their limit on untargeted stresses ('' if none):
    target them, or, where the job targets them already, a method that uses them."""
    missed = [
        e
        for e in failed
        if (e.accuracy.stress or 0.0) > e.accuracy.limit and not (e.stress and e.stress.targeted)
    ]
    if not missed or job.stress is None:
        return ""
    if not job.stress.target:
        return "aim at the stresses ([stress] target = true), "
    return "aim at the stresses with SOAGA or the Gramians (which use [stress] target), "


def _run_in(
    job: Job,
    staging: Path,
    say: Progress,
    stage: Callable[..., None],
    workers: int | None,
    scheduler: str | None,
    shared: SharedFactors | None = None,
) -> JobSummary:
    """Everything of :func:`_run_job` that writes into the ``staging`` folder (``shared``: the
    job's factors, dropped once the reductions are judged)."""
    timings: dict[str, float] = {}
    clock = time.perf_counter()
    body, prepared, validation = _prepared_for_job(job, say, stage, timings)
    units = detect_units(body)
    warnings = [*prepared.warnings, *validation.warnings, *units.warnings]
    warnings += band_unit_warnings(job.band_hz)
    for warning in warnings:
        say(f"warning: {warning}")
    notes = list(prepared.notes)
    if "stress_recovery" in job.export.outputs and stress_modes_note(prepared.body):
        notes.append(stress_modes_note(prepared.body))  # written without points, saying why
    for note in notes:  # facts of the setup, no mistake: not warnings
        say(f"note: {note}")
    reference = _reference(job, prepared, say, stage, workers, scheduler)
    nodes = export_nodes(job)
    reference, reduced_runs = _reduce_all(job, prepared, reference, stage)
    reference = _completed(job, reference, reduced_runs, say)
    results = _judged(job, prepared, reference, reduced_runs, staging, nodes, warnings, say)
    entries, errors, estimates, decay, models = results
    if shared is not None:
        shared.clear()  # their memory to the checks and exports
    timings["reference_s"] = reference.seconds
    computed = [f for e in entries for f in e.eigenfrequencies_hz]
    for warning in frequency_warnings(units, job.band_hz, np.asarray(computed)):
        warnings.append(warning)
        say(f"warning: {warning}")
    figures = [_error_figure(job, prepared, reference, errors, estimates, staging)]
    overview = ["summary.json", "error.png"]
    if decay:
        plot_decay(decay, staging / "decay.png")
        overview.append("decay.png")
        figures.append((staging / "decay.png", "Decay of singular values (paper Fig. 11)"))
    checks = {}
    hot_spots = None if prepared.hot_spots is None else prepared.hot_spots.operator
    done = _checks_in_time(
        job, body, prepared, models, nodes, staging, stage, say, timings, hot_spots
    )
    for key, (result, drawn) in done.items():
        checks[key] = result
        overview += [figure[0].name for figure in drawn]
        figures += drawn
        entries = _attach_rows(entries, key, result)
    if (staging / HISTORY_FILE).exists():
        overview.append(HISTORY_FILE)
    if "report" in job.export.outputs:
        overview.append("report.html")
    timings["total_s"] = time.perf_counter() - clock
    summary = JobSummary(
        pymorembs_version=__version__,
        job=str(job.path),
        model=_model_summary(job, body, prepared),
        units=units.as_dict(),
        validation=validation.as_dict(),
        band_hz=job.band_hz,
        n_frequencies=int(reference.frequencies_hz.size),
        reference=reference.as_dict(),
        reductions=tuple(entries),
        warnings=warnings,
        notes=notes,
        timings_s=timings,
        files=overview,
        provenance=provenance(job, validation),
        checks=checks,
        title=job.title,
    )
    scene = None
    if "report" in job.export.outputs:
        scene = reductions_scene(prepared, models, interfaces=job_interfaces(body, job))
    _write_summary(job, summary, figures, scene, staging)
    return summary


def _prepared_for_job(
    job: Job, say: Progress, stage: Callable[..., None], timings: dict[str, float]
) -> tuple[ElasticBody, PreparedModel, ValidationReport]:
    """The first stage: the checked and prepared model, with the job's inertia loads and
    geometric stiffening (``timings`` gets the times of these steps)."""
    clock = time.perf_counter()
    stage(
        "loading the model, interfaces, frame, constraint elimination, inputs and outputs",
        "loading the model",
    )
    body, prepared, validation = prepare_and_validate(job)  # before anything expensive
    timings["prepare_s"] = time.perf_counter() - clock
    timings["validation_s"] = validation.seconds
    if job.inertia_loads.active(job.export.outputs):
        tick = time.perf_counter()
        say("inertia loads of the frame motion as further inputs (one static factorization)")
        prepared = with_inertia_loads(prepared, job.inertia_loads.cases)
        timings["inertia_loads_s"] = time.perf_counter() - tick
    if job.stiffening.source != "none":
        tick = time.perf_counter()
        say(f"geometric stiffening from the {job.stiffening.source} (one static factorization)")
        prepared = _with_stiffening(prepared, job)
        timings["stiffening_s"] = time.perf_counter() - tick
    if job.stress is not None:
        tick = time.perf_counter()
        say("stresses at the hot spots as further outputs")
        try:
            prepared = with_stress_outputs(prepared, job.stress)
        except UserError as exc:
            raise UserError(f"{job.path}: {exc}") from None
        timings["stress_s"] = time.perf_counter() - tick
    return body, prepared, validation


def _reference(
    job: Job,
    prepared: PreparedModel,
    say: Progress,
    stage: Callable[..., None],
    workers: int | None,
    scheduler: str | None,
) -> ReferenceResponse:
    """The second stage: the reference response on the job's error grid (the full model's, or
    a checked reference model's), of the system every reduction sees."""
    system = prepared.reduction_system
    frequencies = frequency_grid(*job.band_hz, job.points)
    kind = choose_kind(job.reference, system.order)
    stage(
        f"frequency response of the full model at {frequencies.size} frequencies"
        if kind == "full"
        else f"reference model for the error at {frequencies.size} frequencies, checked "
        "against the full model",
        "reference response",
    )
    points = [f for spec in job.reductions for f in expansion_candidates(spec.options, job.band_hz)]
    # 0 Hz checked now; the weakest frequencies after the reductions' maxima (_completed)
    reference = reference_response(system, frequencies, kind, 0, workers, scheduler, points or None)
    if reference.kind == "surrogate":
        say(
            f"reference model of order {reference.parameters['order']}: checked against the "
            "full model at each reduction's largest error and where it is weakest"
        )
    return reference


def _completed(
    job: Job,
    reference: ReferenceResponse,
    reduced_runs: list[tuple[ReducedModel, np.ndarray, float]],
    say: Progress,
) -> ReferenceResponse:
    """The reference settled for every reduction and checked at ``[band] check_points``
    frequencies at least, those of the settling counted
    (:meth:`~pymorembs.analysis.ReferenceResponse.completed`); the largest deviation said."""
    if reference.kind != "surrogate":
        return reference
    reference = reference.completed(job.check_points)
    reference = reference.settled_all([response for _, response, _ in reduced_runs])
    say(
        f"reference model: largest deviation from the full model at {len(reference.deviation)} "
        f"checked frequencies {reference.accuracy:.1e}"
    )
    return reference


@contextlib.contextmanager
def _staging(out_dir: Path) -> Iterator[Path]:
    """A temporary folder ``.<name>.*`` next to ``out_dir`` for the files of a run; it replaces
    the output folder's entries when the block succeeds (not interrupted by SIGINT or SIGTERM
    half-way, :func:`_signals_held`) and is removed when it fails or is interrupted."""
    parent = out_dir.resolve().parent
    parent.mkdir(parents=True, exist_ok=True)
    staging = Path(tempfile.mkdtemp(prefix=f".{out_dir.name}.", dir=parent))
    try:
        yield staging
        with _signals_held():
            _replace_folder(staging, out_dir)
    except BaseException:
        shutil.rmtree(staging, ignore_errors=True)
        raise


@contextlib.contextmanager
def _signals_held() -> Iterator[None]:
    """Hold SIGINT and SIGTERM while the block runs, then act on one that came meanwhile.

    Only the main thread receives Python's signal handlers; elsewhere the block cannot be
    interrupted by them and runs as it is.
    """
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    came: list[int] = []
    held = (signal.SIGINT, signal.SIGTERM)
    previous = {sig: signal.signal(sig, lambda number, _frame: came.append(number)) for sig in held}
    try:
        yield
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, signal.SIG_DFL if handler is None else handler)
        for number in came[:1]:
            signal.raise_signal(number)


_ELSEWHERE = "write elsewhere with --out"
_FREE = "free some space, or write elsewhere with --out"
#: What an ``OSError`` of the output device means, by ``errno``: the problem (naming the
#: folder) and the remedy.
OUTPUT_DEVICE_ERRORS = {
    errno.ENOSPC: ("no space left on the device of {folder}", _FREE),
    errno.EDQUOT: ("the disk quota is exceeded on the device of {folder}", _FREE),
    errno.EROFS: ("{folder} lies on a read-only file system", _ELSEWHERE),
    errno.EACCES: ("no permission to write into {folder}", _ELSEWHERE),
    errno.EPERM: ("no permission to write into {folder}", _ELSEWHERE),
}
#: What a job's run left when its output device failed (the staging folder is removed).
NOTHING_WRITTEN = "nothing of this run was written"
#: Of these, the errors that count only where they name a file of the output (a full device
#: is the output's; a refused permission may be an input's).
_NAMED_ONLY = (errno.EACCES, errno.EPERM)


def output_device_error(
    exc: BaseException, folder: Path, outcome: str = NOTHING_WRITTEN
) -> UserError | None:
    """The one-line error for an output device that is full, over its quota, read-only or
    refuses the writing, or None when ``exc`` is something else; ``outcome`` says what was left
    (empty: nothing said).

    ``exc`` or an exception it was raised from or while handling (a writer's own error that
    wraps the ``OSError``) is an ``OSError`` of :data:`OUTPUT_DEVICE_ERRORS`. The line names
    ``folder`` when the error names no file or a file of the output (``folder`` or its temporary
    sibling ``.<name>.*``), else the folder of the file it names.
    """
    folder = Path(folder)
    seen: set[int] = set()
    current: BaseException | None = exc
    while current is not None and id(current) not in seen:
        seen.add(id(current))
        if isinstance(current, OSError) and current.errno in OUTPUT_DEVICE_ERRORS:
            named = None if current.filename is None else Path(os.fsdecode(current.filename))
            ours = named is None or _is_output(named, folder)
            if ours or current.errno not in _NAMED_ONLY:
                where = folder if ours else named.parent
                problem, remedy = OUTPUT_DEVICE_ERRORS[current.errno]
                left = f"; {outcome}" if outcome else ""
                return UserError(f"{problem.format(folder=where)}{left} ({remedy})")
        current = current.__cause__ or current.__context__
    return None


def _is_output(path: Path, folder: Path) -> bool:
    """Whether ``path`` is ``folder``, its temporary sibling ``.<name>.*`` or lies in them."""
    parent = folder.resolve().parent
    path = path.resolve()
    return any(
        p.parent == parent and (p.name == folder.name or p.name.startswith(f".{folder.name}."))
        for p in (path, *path.parents)
    )


@contextlib.contextmanager
def output_errors(folder: Path, outcome: str = NOTHING_WRITTEN) -> Iterator[None]:
    """Turn an error of a full, over-quota or read-only output device inside the block into
    the one-line :class:`UserError` of :func:`output_device_error` (exit 2)."""
    try:
        yield
    except (OSError, PymorembsError) as exc:
        error = output_device_error(exc, folder, outcome)
        if error is None:
            raise
        raise error from None


def _reduce_all(
    job: Job, prepared: PreparedModel, reference: ReferenceResponse, stage: Callable[..., None]
) -> tuple[ReferenceResponse, list[tuple[ReducedModel, np.ndarray, float]]]:
    """One stage per reduction; the reference settled for all of them
    (:meth:`ReferenceResponse.settled_all`) and each reduction's model, response and time."""
    reduced_runs = []
    for spec in job.reductions:
        stage(f"reduction '{spec.name}' ({spec.method})", f"reduction '{spec.name}'")
        run = _reduce_one(prepared, spec, job.band_hz, reference)
        reference = _settled(spec, reference, run[1])  # its maximum checked at once
        reduced_runs.append(run)
    return reference.settled_all([response for _, response, _ in reduced_runs]), reduced_runs


def _checks_in_time(
    job: Job,
    body: ElasticBody,
    prepared: PreparedModel,
    models: dict[str, ReducedModel],
    nodes: list[int],
    staging: Path,
    stage: Callable[..., None],
    say: Progress,
    timings: dict[str, float],
    stress: StressOperator | None = None,
) -> dict[str, tuple[dict[str, Any], list[tuple[Path, str]]]]:
    """The stages of ``[time_domain]`` (full and reduced models in time) and ``[large_motion]``
    (the bodies in Exudyn) the job asks for: by summary key, the check's entry and its figures
    (file, caption). With ``stress`` (the hot spots on the dofs of the job's body) both give
    the stress histories there, each with a figure of them, and the histories themselves go
    into ``staging`` as :data:`~pymorembs.analysis.HISTORY_FILE`."""
    done: dict[str, Any] = {}
    histories: dict[str, dict[str, dict[str, Any]]] = {}
    if job.time_domain is not None:
        stage("time domain", "time domain", line=False)  # time_domain_checks says more
        tick = time.perf_counter()
        figure, stress_figure = staging / "time.png", staging / "time_stress.png"
        histories["time_domain"] = {}
        result = time_domain_checks(
            job.time_domain, body, job.frame, prepared, models, nodes, figure, say,
            stress, stress_figure, histories["time_domain"],
        )  # fmt: skip
        timings["time_domain_s"] = time.perf_counter() - tick
        drawn = [(figure, "Time responses (paper Fig. 12)")]
        if stress is not None:
            drawn.append((stress_figure, "von Mises stress at the worst hot spot: full FE "
                                         "model against the reduced models"))  # fmt: skip
        done["time_domain"] = result, drawn
    if job.large_motion is not None:
        stage("large motion in Exudyn", "large motion", line=False)
        tick = time.perf_counter()
        figure = staging / "large_motion.png"
        checks = large_motion_checks(
            job.large_motion, job.frame, prepared, one_sided(models), nodes, say, stress
        )
        plot_large_motion(checks.runs, checks.off_axis_node, figure)
        result = checks.summary
        timings["large_motion_s"] = time.perf_counter() - tick
        order = result["reference"]["order"]
        caption = f"Large motions in Exudyn: each body against the modal reference of order {order}"
        drawn = [(figure, caption)]
        if stress is not None:
            stress_figure = staging / "large_motion_stress.png"
            plot_large_motion_stresses(checks.runs, stress_figure, order)
            histories["large_motion"] = {
                motion: {"reference": reference["stresses"]}
                | {name: run["stresses"] for name, run in runs.items()}
                for motion, (reference, runs) in checks.runs.items()
            }
            drawn.append((stress_figure, "von Mises stress at the worst hot spot in the large "
                          "motions: each body against the modal reference of order "
                          f"{order}"))  # fmt: skip
        done["large_motion"] = result, drawn
    if stress is not None and any(histories.values()):
        write_npz(staging / HISTORY_FILE, history_arrays(histories, stress.coordinates))
    return done


def _write_summary(
    job: Job,
    summary: JobSummary,
    figures: list[tuple[Path, str]],
    scene: dict[str, Any] | None,
    staging: Path,
) -> None:
    """``report.html`` (if asked for, with the 3D ``scene``) and ``summary.json`` into
    ``staging``."""
    data = summary.to_json()
    if "report" in job.export.outputs:
        write_report(staging / "report.html", data, figures, _job_text(job.path), scene=scene)
    write_text(staging / "summary.json", json.dumps(data, indent=2, allow_nan=False) + "\n")


def _judged(
    job: Job,
    prepared: PreparedModel,
    reference: ReferenceResponse,
    reduced_runs: list[tuple[ReducedModel, np.ndarray, float]],
    staging: Path,
    nodes: list[int],
    warnings: list[str],
    say: Progress,
) -> tuple[list[ReductionSummary], dict, dict, dict, dict[str, ReducedModel]]:
    """Every reduction's errors against the same reference (settled for all of them,
    :meth:`ReferenceResponse.settled_all`), its files written into ``staging`` and its summary
    entry; the warnings they call for are added.

    Returns the entries, the error curves (ports, inertia loads and stresses), the estimator
    curves, the singular value decays and the reduced models, by reduction name.
    """
    entries, errors, estimates, decay, models = [], {}, {}, {}, {}
    all_eps = [
        _finite(spec, reference, reference.errors(response))
        for spec, (_, response, _) in zip(job.reductions, reduced_runs, strict=True)
    ]
    ports, inertia = error_blocks(prepared.reduction_system)
    for spec, (model, response, elapsed), eps in zip(
        job.reductions, reduced_runs, all_eps, strict=True
    ):
        eps_inertia = None
        if inertia is not None:  # eq. 27 over the ports, and over the inertia loads
            eps_inertia = relative_error(reference.response, response, inertia)
            eps = relative_error(reference.response, response, ports)
        eps_stress = reference.stress_errors(response)  # and over the hot spots' stresses
        accuracy = judge_accuracy(spec, eps, eps_inertia, eps_stress)
        outputs = job.export.outputs if accuracy.exported else ()
        entry = _write_one(
            prepared, spec, model, (eps, eps_inertia, eps_stress), elapsed, reference, staging,
            outputs, nodes, accuracy,
        )  # fmt: skip
        projection = model.projection
        models[spec.name] = model
        if projection.error_curve is not None:
            estimates[spec.name] = projection.error_curve
        for key, label in DECAY_SERIES:
            values = np.asarray(projection.parameters.get(key, []), dtype=float)
            if values.size and not any(np.array_equal(values, v) for v in decay.values()):
                decay[f"{spec.name}: {label}"] = values
        if spec.method == "krylov" and spec.order is not None and entry.order < spec.order:
            warnings.append(
                f"reduction '{spec.name}': order {entry.order} instead of {spec.order}: "
                "the Krylov space is exhausted (the reduced model is exact for these ports)"
            )
            say(f"warning: {warnings[-1]}")
        missing = inertia_warning(spec.name, eps, eps_inertia)
        if missing:
            warnings.append(missing)
            say(f"warning: {missing}")
        entries.append(entry)
        errors[spec.name] = eps
        if eps_inertia is not None:
            errors[f"{spec.name} (inertia loads)"] = eps_inertia
        if eps_stress is not None:
            errors[f"{spec.name} (stresses)"] = eps_stress
    return entries, errors, estimates, decay, models


def judge_accuracy(
    spec: ReductionSpec,
    eps: np.ndarray,
    eps_inertia: np.ndarray | None,
    eps_stress: np.ndarray | None = None,
) -> Accuracy:
    """Whether a reduction meets its accuracy limit, and whether its body files are written.

    Parameters
    ----------
    spec : ReductionSpec
        The reduction (its limit: :attr:`~pymorembs.job.schema.ReductionSpec.accuracy_limit`).
    eps : ndarray
        ``eps(f)`` of eq. 27 over the ports.
    eps_inertia : ndarray or None
        ``eps(f)`` over the inertia loads (None: they are not inputs).
    eps_stress : ndarray or None
        ``eps(f)`` over the stress outputs at the hot spots (None: no ``[stress]``).

    Returns
    -------
    Accuracy
        The ``accuracy`` entry of the reduction in ``summary.json``: ``met`` (max error <=
        limit), ``limit``, ``limit_from`` (``"tolerance"`` or ``"default"``), ``max`` (over the
        ports, the inertia loads and the stresses), ``ports``, ``inertia_loads`` (None without
        them), ``stress`` (None without stress outputs), ``export_inaccurate`` (the job's flag)
        and ``exported`` (the body files are written: met, or allowed by the flag).
    """
    limit, source = spec.accuracy_limit
    ports = float(np.max(eps))
    loads = None if eps_inertia is None else float(np.max(eps_inertia))
    stress = None if eps_stress is None else float(np.max(eps_stress))
    largest = max(ports, loads or 0.0, stress or 0.0)
    met = largest <= limit
    return Accuracy(
        met=met,
        limit=limit,
        limit_from=source,
        max=largest,
        ports=ports,
        inertia_loads=loads,
        export_inaccurate=spec.export_inaccurate,
        exported=met or spec.export_inaccurate,
        stress=stress,
    )


def _attach_rows(
    entries: list[ReductionSummary], key: str, checks: dict[str, Any]
) -> list[ReductionSummary]:
    """Each reduction's summary entry with its rows of a check (per case name)."""
    return [
        entry.with_check(
            key,
            {
                case["name"]: row
                for case in checks["cases"]
                for row in case["reductions"]
                if row["name"] == entry.name
            },
        )
        for entry in entries
    ]


def _error_figure(
    job: Job,
    prepared: PreparedModel,
    reference: ReferenceResponse,
    errors: dict[str, np.ndarray],
    estimates: dict[str, np.ndarray],
    staging: Path,
) -> tuple[Path, str]:
    """``error.png`` of every reduction's eq. 27 error, and its caption."""
    plot_relative_errors(
        reference.frequencies_hz,
        errors,
        staging / "error.png",
        title=job.title or "Relative error of the reduced models",
        estimates=estimates,
        **_reference_marks(reference),
    )
    caption = "Relative error ε(f) of eq. 27 of every reduction"
    if prepared.inertia is not None:
        caption += (
            " over the ports, and '(inertia loads)' over the inertia loads of the frame motion"
        )
    if reference.kind == "surrogate":
        caption += (
            f" against a reference model of order {reference.parameters['order']}, "
            "checked against the full model at the black-edged points (its measured "
            "deviation: dotted)"
        )
    if estimates:
        caption += "; dashed: the error estimators"
    return staging / "error.png", caption


def _model_summary(job: Job, body: ElasticBody, prepared: PreparedModel) -> dict[str, Any]:
    """The ``model`` entry of ``summary.json``: sizes, ports, inertia loads, stiffening, mass."""
    system = prepared.reduction_system
    massless = mass_split(system.mass)
    return {
        "name": body.name,
        "n_dof": body.n_dof,
        "n_nodes": body.n_nodes,
        "n_independent": system.order,
        "n_dependent": int(prepared.elimination.dependent.size),
        "n_fixed": int(prepared.elimination.fixed.size),
        "n_massless": massless.n_massless,
        "massless": {
            "dofs_without_mass": int(massless.zero_rows.size),
            "directions_in_mass_blocks": massless.n_block_null,
        },
        "dof_table": body.dofs.describe(),
        "has_coordinates": bool(body.has_coordinates),
        "notes": list(body.notes),
        "n_inputs": prepared.system.n_inputs,
        "n_outputs": prepared.system.n_outputs,
        "inputs": list(prepared.system.input_labels),
        "outputs": list(prepared.system.output_labels),
        "inertia_loads": _inertia_summary(prepared),
        "stress": None if prepared.hot_spots is None else prepared.hot_spots.as_dict(),
        "stiffening": None
        if prepared.stiffening is None
        else {
            "source": prepared.stiffening.source,
            "cases": sorted(prepared.stiffening.cases),
            "node_loads": [f"{n}:{DIRECTIONS[d]}" for n, d in sorted(prepared.stiffening.nodes)],
            "written_to": list(BODY_OUTPUTS),
        },
        "total_mass": body.total_mass(),
        "damping": {
            "kind": body.damping.kind,
            "alpha": body.damping.alpha,
            "beta": body.damping.beta,
            "ratio": body.damping.ratio,
        },
        "frame": {"type": job.frame.kind, "node": job.frame.node},
    }


def _reduce_one(
    prepared: PreparedModel,
    spec: ReductionSpec,
    band_hz: tuple[float, float],
    reference: ReferenceResponse,
) -> tuple[ReducedModel, np.ndarray, float]:
    """Reduce (:func:`pymorembs.reduce`); the checked reduced model, its response on the grid
    and the reduction time (s).

    With ``max_frequency_hz``, what the removal of the stiff directions costs goes into the
    projection's parameters: the errors before it.
    """
    tick = time.perf_counter()
    reduced = reduce(prepared, spec.options, band_hz=band_hz, name=spec.name)
    elapsed = time.perf_counter() - tick
    model = reduced.model
    if reduced.before_removal is not None:
        model = _with_removal_cost(prepared, reduced.before_removal, model, reference)
    response = transfer_function(model.system, reference.frequencies_hz)
    return model, response, elapsed


def _with_removal_cost(
    prepared: PreparedModel,
    before: ReducedModel,
    model: ReducedModel,
    reference: ReferenceResponse,
) -> ReducedModel:
    """``model`` with the errors of ``before`` (the model before the removal of its stiff
    directions) in the parameters of its projection, to compare with the entry's own."""
    response = transfer_function(before.system, reference.frequencies_hz)
    ports, inertia = error_blocks(prepared.reduction_system)
    frequencies = reference.frequencies_hz
    costs = {}
    for key, block in (("", ports), ("inertia_", inertia)):
        if block is None:
            continue
        eps = relative_error(reference.response, response, block)
        costs[f"{key}max_rel_error_before_removal"] = float(eps.max())
        if frequencies[0] == 0.0:
            costs[f"{key}static_rel_error_before_removal"] = float(eps[0])
    return dataclasses.replace(model, projection=model.projection.with_parameters(**costs))


def inertia_warning(name: str, eps: np.ndarray, eps_inertia: np.ndarray | None) -> str | None:
    """A warning when a reduction is far less accurate under the inertia loads than at the ports.

    Given when the largest error under the inertia loads exceeds :data:`INERTIA_WARNING` and
    :data:`INERTIA_RATIO` times the largest error over the ports.
    """
    if eps_inertia is None:
        return None
    ports, loads = float(np.max(eps)), float(np.max(eps_inertia))
    if loads <= max(INERTIA_WARNING, INERTIA_RATIO * ports):
        return None
    return (
        f"reduction '{name}': max error {ports:.1e} over the ports but {loads:.1e} under the "
        "inertia loads of the frame motion: the body misses directions the frame's motion "
        "excites (raise the order, or add frm_hz / expansion points)"
    )


def one_sided(models: dict[str, ReducedModel]) -> dict[str, ReducedModel]:
    """The reduced models with a Galerkin projection (those that give bodies)."""
    return {name: model for name, model in models.items() if model.projection.one_sided}


def _with_stiffening(prepared: PreparedModel, job: Job) -> PreparedModel:
    """The prepared model with the geometric stiffening of ``[stiffening]``."""
    spec = job.stiffening
    try:
        if spec.source == "mesh":
            stiffening = stiffening_from_mesh(prepared, nodes=export_nodes(job))
        else:
            stiffening = stiffening_from_matrices(prepared, dict(spec.matrices), spec.kind)
    except UserError as exc:
        raise UserError(f"{job.path}: {exc}") from None
    return with_stiffening(prepared, stiffening)


def _inertia_summary(prepared: PreparedModel) -> dict[str, Any] | None:
    """The inertia loads of a prepared model for the summary (None: not used)."""
    loads = prepared.inertia
    if loads is None:
        return None
    return {
        "cases": list(loads.cases),
        "dropped": list(loads.dropped),
        "scales": loads.scales.tolist(),
        "scaling": "each load's static compliance equals the median of the port forces'",
    }


def _settled(
    spec: ReductionSpec, reference: ReferenceResponse, response: np.ndarray
) -> ReferenceResponse:
    """The reference with the maximum of the reduction's ``eps(f)`` (eq. 27) on a frequency
    checked against the full model; a :class:`NumericalError` if ``eps`` is not finite."""
    settled = reference.settled(response)
    _finite(spec, settled, settled.errors(response))
    return settled


def _finite(spec: ReductionSpec, reference: ReferenceResponse, eps: np.ndarray) -> np.ndarray:
    """``eps`` if it is finite everywhere; else a :class:`NumericalError` naming a frequency."""
    if not np.all(np.isfinite(eps)):
        bad = reference.frequencies_hz[~np.isfinite(eps)][0]
        raise NumericalError(
            f"reduction '{spec.name}': the error at {bad:g} Hz is not finite (a frequency on an "
            "undamped resonance? add damping or move the band)"
        )
    return eps


def _write_one(
    prepared: PreparedModel,
    spec: ReductionSpec,
    model: ReducedModel,
    errors: tuple[np.ndarray, np.ndarray | None, np.ndarray | None],
    elapsed: float,
    reference: ReferenceResponse,
    staging: Path,
    outputs: tuple[str, ...],
    nodes: list[int],
    accuracy: Accuracy,
) -> ReductionSummary:
    """Write a reduction's files into ``staging/<name>``; its entry of the summary (with its
    ``accuracy``, :func:`judge_accuracy`).

    ``errors``: ``eps(f)`` over the ports, over the inertia loads and over the stresses (None
    without them);
    ``outputs``: the body files to write (none for a body that missed its accuracy limit),
    besides its error curve and plot, which are always written.
    """
    eps, eps_inertia, eps_stress = errors
    projection = model.projection
    frequencies = reference.frequencies_hz
    static = float(eps[0]) if frequencies[0] == 0.0 else None
    folder = safe_child(staging, spec.name)
    folder.mkdir()
    files = write_outputs(model, prepared, spec.name, outputs, nodes, folder)
    curve = {} if projection.error_curve is None else {spec.name: projection.error_curve}
    curves = {spec.name: eps}
    if eps_inertia is not None:
        curves[f"{spec.name} (inertia loads)"] = eps_inertia
    if eps_stress is not None:
        curves[f"{spec.name} (stresses)"] = eps_stress
    plot_relative_errors(
        frequencies,
        curves,
        folder / "error.png",
        title=f"Relative error of '{spec.name}' ({spec.method}, n = {projection.order})",
        estimates=curve,
        **_reference_marks(reference),
    )
    table = np.column_stack([frequencies, eps])
    header = "frequency_hz,relative_error"
    if eps_inertia is not None:
        table = np.column_stack([table, eps_inertia])
        header += ",relative_error_inertia_loads"
    if eps_stress is not None:
        table = np.column_stack([table, eps_stress])
        header += ",relative_error_stresses"
    if reference.kind == "surrogate":  # 1: measured against the full model, 0: surrogate
        table = np.column_stack([table, reference.exact.astype(float)])
        header += ",checked_against_full_model"
    with atomic_path(folder / "error.csv") as tmp:
        np.savetxt(tmp, table, delimiter=",", header=header, comments="")
    files += ["error.png", "error.csv"]
    if curve:
        with atomic_path(folder / "error_estimate.csv") as tmp:
            np.savetxt(
                tmp,
                np.column_stack(projection.error_curve),
                delimiter=",",
                header="frequency_hz,estimated_relative_error",
                comments="",
            )
        files.append("error_estimate.csv")
    inertia = None
    if eps_inertia is not None:
        inertia = InertiaErrors(
            max_rel_error=float(np.max(eps_inertia)),
            static_rel_error=float(eps_inertia[0]) if frequencies[0] == 0.0 else None,
        )
    return ReductionSummary(
        name=spec.name,
        method=spec.method,
        order=model.projection.order,
        max_rel_error=float(np.max(eps)),
        static_rel_error=static,
        error_estimate=projection.error_estimate,
        error_bound=projection.error_bound,
        reference_resolved=reference.resolved(eps),
        time_s=elapsed,
        parameters=_jsonable(projection.parameters),
        eigenfrequencies_hz=model.eigenfrequencies_hz.tolist(),
        highest_frequency_hz=float(model.eigenfrequencies_hz.max(initial=0.0)),
        explicit_step_s=explicit_step_s(model.eigenfrequencies_hz),
        files=[f"{spec.name}/{name}" for name in files],
        accuracy=accuracy,
        inertia_loads=inertia,
        stress=_stress_errors(eps_stress, frequencies, projection, prepared, spec),
    )


def _stress_errors(
    eps_stress: np.ndarray | None,
    frequencies: np.ndarray,
    projection: Projection,
    prepared: PreparedModel,
    spec: ReductionSpec,
) -> StressErrors | None:
    """A reduction's ``stress`` entry: ε over the stress outputs, SOAGA's estimate of it;
    ``targeted`` only where the job aims at the stresses and the method uses them
    (:func:`~pymorembs.reduction.aims_at_stresses`)."""
    if eps_stress is None:
        return None
    return StressErrors(
        max_rel_error=float(np.max(eps_stress)),
        static_rel_error=float(eps_stress[0]) if frequencies[0] == 0.0 else None,
        estimate=projection.parameters.get("stress_estimate"),
        targeted=bool(prepared.system.stress_targeted) and aims_at_stresses(spec.options),
    )


def _reference_marks(reference: ReferenceResponse) -> dict[str, Any]:
    """Plot options that show a surrogate reference: its checked frequencies and accuracy."""
    if reference.kind != "surrogate":
        return {}
    return {"checked": reference.exact, "reference_accuracy": reference.accuracy}


def safe_child(folder: Path, name: str) -> Path:
    """``folder / name``, refused unless it is a direct child of ``folder``.

    A name from a job file must not be absolute, contain a path separator or ``..``, or be a
    hidden name: output files never escape the output folder.

    Raises
    ------
    UserError
        Naming the offending name.
    """
    pure = Path(name)
    if (
        not name
        or pure.is_absolute()
        or len(pure.parts) != 1
        or name in (".", "..")
        or name.startswith(".")
        or "/" in name
        or "\\" in name
    ):
        raise UserError(
            f"output name {name!r} would leave the output folder; use letters, digits, _ . + -"
        )
    child = folder / name
    if child.resolve().parent != folder.resolve():
        raise UserError(f"output name {name!r} would leave the output folder")
    return child


def sha256_of(path: Path) -> str:
    """SHA-256 of a file's bytes, hex (read in 1 MiB blocks)."""
    digest = hashlib.sha256()
    with open(path, "rb") as fh:  # reading only
        for block in iter(lambda: fh.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()


def _version(package: str) -> str | None:
    try:
        return importlib.metadata.version(package)
    except importlib.metadata.PackageNotFoundError:
        return None


def provenance(job: Job, validation: ValidationReport | None = None) -> dict[str, Any]:
    """Where a result came from: input files with their SHA-256, software, settings.

    Returns
    -------
    dict
        ``inputs``: ``{path: sha256}`` of the job file and every model file it names or that is
        read beside them (a CalculiX export's ``.mas``, ``.dof`` and deck; built-in
        examples: their name and options); ``software``: versions of pymorembs, Python, NumPy,
        SciPy, h5py, pypardiso and mkl (None when not installed), the platform; ``solver``: the
        requested and default sparse backend, and the one of the validation factorization;
        ``environment``: the ``PYMOREMBS_*`` variables and ``SOURCE_DATE_EPOCH`` that are set;
        ``settings``: the parsed job.
    """
    # a job parsed from a dictionary (parse_job) may name a file that does not exist
    inputs = {str(job.path): sha256_of(Path(job.path))} if Path(job.path).is_file() else {}
    for path in model_files(job.model.files, job.model.format).values():
        if Path(path).is_file():
            inputs[str(path)] = sha256_of(Path(path))
    software = {
        "pymorembs": __version__,
        "python": platform.python_version(),
        "numpy": np.__version__,
        "scipy": scipy.__version__,
        **{name: _version(name) for name in ("h5py", "pypardiso", "mkl", "matplotlib")},
        "platform": platform.platform(),
    }
    try:
        default = default_backend()
    except PymorembsError:
        default = None
    solver = {
        "requested": os.environ.get("PYMOREMBS_SOLVER", "auto"),
        "default": default,
        "validation": None if validation is None else validation.facts.get("factorization_backend"),
    }
    environment = {
        key: value
        for key, value in sorted(os.environ.items())
        if key.startswith("PYMOREMBS_") or key == "SOURCE_DATE_EPOCH"
    }
    return {
        "inputs": inputs,
        "model": (
            {"example": job.model.example, "options": job.model.options.given()}
            if job.model.example is not None
            else {
                "format": job.model.format,
                "files": {k: str(v) for k, v in job.model.files.items()},
            }
        ),
        "software": software,
        "solver": solver,
        "environment": environment,
        "settings": job_settings(job),
    }


def job_settings(job: Job) -> dict[str, Any]:
    """The parsed job as JSON-ready data (what the run actually used)."""
    damping = job.damping
    return {
        "frame": {"type": job.frame.kind, "node": job.frame.node},
        "damping": None
        if damping is None
        else {
            "kind": damping.kind,
            "alpha": damping.alpha,
            "beta": damping.beta,
            "ratio": damping.ratio,
        },
        "inputs": [label for port in job.inputs for label in port.labels()],
        "outputs": [label for port in job.outputs for label in port.labels()],
        "band_hz": list(job.band_hz),
        "points": job.points,
        "reductions": [
            {
                "name": spec.name,
                "method": spec.method,
                "order": spec.order,
                "options": _jsonable(spec.written_options()),
                "export_inaccurate": spec.export_inaccurate,
            }
            for spec in job.reductions
        ],
        "export": {
            "outputs": list(job.export.outputs),
            "nodes": None if job.export.nodes is None else list(job.export.nodes),
        },
        "interfaces": len(job.interfaces),
        "time_domain": job.time_domain is not None,
        "inertia_loads": {
            "active": job.inertia_loads.active(job.export.outputs),
            "enabled": job.inertia_loads.enabled,
            "cases": list(job.inertia_loads.cases),
        },
    }


def _job_text(path: Path) -> str:
    try:
        return Path(path).read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError):
        return ""


def _replace_folder(staging: Path, target: Path) -> None:
    """Move the finished files of ``staging`` into ``target``; remove ``staging``.

    Entries of an earlier run with the same names are replaced; other files in ``target`` are
    left alone. ``summary.json`` moves last, so its presence marks a complete result.
    """
    if target.exists() and not target.is_dir():
        raise UserError(f"{target}: output path exists and is not a folder")
    target.mkdir(parents=True, exist_ok=True)
    entries = sorted(staging.iterdir(), key=lambda p: p.name == "summary.json")
    for entry in entries:
        destination = target / entry.name
        if destination.is_dir() and not destination.is_symlink():
            old = staging / f".old-{entry.name}"
            destination.rename(old)
        elif destination.exists() or destination.is_symlink():
            destination.unlink()
        entry.rename(destination)
    shutil.rmtree(staging, ignore_errors=True)


def _jsonable(value: Any) -> Any:
    if isinstance(value, Mapping):
        return {str(k): _jsonable(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_jsonable(v) for v in value]
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, np.generic):
        return value.item()
    return value


__all__ = [
    "add_interfaces",
    "check_job_nodes",
    "check_job_orders",
    "judge_accuracy",
    "load_job_model",
    "load_model",
    "output_device_error",
    "output_errors",
    "prepare_and_validate",
    "prepare_job",
    "provenance",
    "run_job",
    "run_reduction",
    "safe_child",
    "validate_job_body",
]
