"""The time-domain checks of a job (paper section 5.1, ``[time_domain]``).

For the job's load cases (a step and a harmonic force at the load node, the body clamped at the
clamp node):

1. the full FE model is integrated in time (sparse, one factorization, all cases together);
2. every reduced model of the job is integrated the same way (clamped in its own frame, see
   :func:`~pymorembs.analysis.time_domain.clamped_reduced_system`) and compared with it:
   maximum deviation relative to the peak displacement, and the speed-up;
3. with ``exudyn = true`` each reduced body is exported to Exudyn and simulated there as a
   flexible multibody system: held by its reference frame (a tangent frame at the clamp node)
   or by a rigid joint at the clamp node (any other frame, e.g. Buckens). Exudyn's nonlinear
   FFRF equations agree with the linear result only for small motion, so each case is run twice:
   at the job's load, and at 1/10,000 of it (scaled back up for the comparison). The second number
   proves the exported body; the first shows how far the linear result carries at the job's load.

With hot spots (a :class:`~pymorembs.stress.StressOperator` ``C_sigma``), step 1 records the full
model's stress history ``C_sigma q(t)`` (sparse rows on its coordinates) and step 2 each reduced
body's ``C_sigma V q_r(t)`` (the small dense ``C_sigma V``): per hot spot the peak and range of
the von Mises and of the absolute maximum principal stress, and the deviation of each reduced
history from the full one (:mod:`pymorembs.analysis.stress_history`), plotted at the worst hot
spot.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from pymorembs import ElasticBody, Frame, LoadCase, PreparedModel, ReducedModel, TimeResponse
from pymorembs.analysis import (
    StressHistory,
    build_exudyn_model,
    clamped_full_model,
    clamped_reduced_system,
    compare,
    compare_stresses,
    full_stress_rows,
    hot_spot_entries,
    hot_spot_labels,
    simulate,
    simulate_exudyn,
    stress_settings,
)
from pymorembs.export import body_invariants, exudyn_arrays
from pymorembs.job.schema import TimeDomainSpec
from pymorembs.report import plot_stress_histories, plot_time_responses
from pymorembs.stress import StressOperator

#: Load factor of the small-motion Exudyn run.
SMALL_LOAD = 1e-4
#: Spectral radius of generalized-alpha when the job does not set ``rho_inf``.
DEFAULT_RHO_INF = 0.8


def load_cases(spec: TimeDomainSpec) -> list[LoadCase]:
    """The job's load cases (paper section 5.1: step and 10 Hz harmonic of -100 (1,1,1) N)."""
    force = np.asarray(spec.force_n, dtype=float)
    cases = {
        "step": LoadCase("step", "step", force),
        "harmonic": LoadCase("harmonic", "harmonic", force, frequency_hz=spec.harmonic_hz),
    }
    return [cases[name] for name in spec.cases]


def time_domain_checks(
    spec: TimeDomainSpec,
    body: ElasticBody,
    frame: Frame,
    prepared: PreparedModel,
    models: dict[str, ReducedModel],
    nodes: list[int],
    figure: Path,
    say: Callable[[str], None],
    stress: StressOperator | None = None,
    stress_figure: Path | None = None,
    histories: dict[str, dict[str, StressHistory]] | None = None,
) -> dict[str, Any]:
    """Run the checks, plot Fig. 12 into ``figure`` and return the summary entry.

    Parameters
    ----------
    spec : TimeDomainSpec
    body : ElasticBody
        The job's body before the frame is applied (interfaces and damping added).
    frame : Frame
        The job's reference frame.
    prepared : PreparedModel
        The prepared body of the reductions.
    models : dict of name -> ReducedModel
        The job's reduced models (two-sided ones are skipped: no displacement basis).
    nodes : list of int
        Frame nodes of the exported bodies (must contain the clamp and load nodes).
    figure : Path
        PNG file of the time responses.
    say : callable
        Progress lines.
    stress : StressOperator, optional
        The hot spots on the dofs of ``body``: the stress histories are recorded and compared.
    stress_figure : Path, optional
        PNG file of the von Mises stress at the worst hot spot (with ``stress``).
    histories : dict, optional
        Filled (with ``stress``) with the stress histories by load case and body: the full
        model's under ``"full"``, each reduced body's under its reduction's name.
    """
    rho_inf = DEFAULT_RHO_INF if spec.rho_inf is None else spec.rho_inf
    cases = load_cases(spec)
    n_steps = round(spec.duration_s / spec.step_s)
    full_model = clamped_full_model(body, spec.clamp_node, spec.load_node)
    full_system = full_model.system
    say(
        f"time domain: full model ({full_system.order} dofs), {len(cases)} load case(s), "
        f"{n_steps} steps of {spec.step_s:g} s"
        + (f", stresses at {stress.n_points} hot spot(s)" if stress is not None else "")
    )
    points = () if stress is None else hot_spot_labels(stress)
    rows_full = None if stress is None else full_stress_rows(full_model, stress.matrix)
    full = simulate(full_system, cases, spec.duration_s, spec.step_s, rho_inf, rows_full, points)
    responses: dict[str, TimeResponse] = {f"full FE model ({full.order} dofs)": full}
    recorded = (
        {case.name: {"full": full.stresses[case.name]} for case in cases}
        if stress is not None
        else {}
    )
    rows: dict[str, dict[str, dict[str, Any]]] = {case.name: {} for case in cases}
    skipped = []
    for name, model in models.items():
        if not model.projection.one_sided:
            skipped.append(name)
            continue
        say(f"time domain: reduction '{name}'")
        basis = prepared.expand(model.projection.V)
        system = clamped_reduced_system(
            prepared.body,
            basis,
            model.system.mass,
            model.system.stiffness,
            model.damping_matrix,
            spec.clamp_node,
            spec.load_node,
        )
        # C_sigma V: the rigid motion of a floating frame held by a joint has no strain
        modes = None if stress is None else np.asarray(stress.matrix @ basis)
        reduced = simulate(system, cases, spec.duration_s, spec.step_s, rho_inf, modes, points)
        responses[f"{name} (n = {model.projection.order})"] = reduced
        result = compare(full, reduced)
        stresses = {} if stress is None else compare_stresses(full, reduced)
        for case in cases:
            rows[case.name][name] = {
                "name": name,
                "max_rel_deviation": result["max_rel_deviation"][case.name],
                "speedup": result["speedup"],
                "time_s": reduced.wall_time_s,
            }
            if stress is not None:
                rows[case.name][name]["stress"] = stresses[case.name].to_json()
                recorded[case.name][name] = reduced.stresses[case.name]
        if spec.exudyn:
            say(f"time domain: reduction '{name}' in Exudyn")
            exudyn = _exudyn_runs(spec, frame, prepared, model, name, nodes, cases, rho_inf)
            responses[f"{name} in Exudyn"] = exudyn["response"]
            for case in cases:
                rows[case.name][name].update(
                    {
                        "exudyn_max_rel_deviation": _deviation(
                            exudyn["response"].outputs[case.name], reduced.outputs[case.name]
                        ),
                        "exudyn_small_load_max_rel_deviation": _deviation(
                            exudyn["small"][case.name], reduced.outputs[case.name]
                        ),
                        "exudyn_time_s": exudyn["time_s"][case.name],
                        "exudyn_clamp": exudyn["clamp"],
                    }
                )
    plot_time_responses(
        responses,
        figure,
        title=f"Displacement of node {spec.load_node}, body clamped at node {spec.clamp_node}",
    )
    if histories is not None and stress is not None:
        histories.update(recorded)
    if stress is not None and stress_figure is not None:
        plot_stress_histories(
            {label: r.stresses for label, r in responses.items() if r.stresses},
            stress_figure,
            title=f"von Mises stress at the worst hot spot, body clamped at node "
            f"{spec.clamp_node}, loaded at node {spec.load_node}",
        )
    entry = {
        "settings": {
            "clamp_node": spec.clamp_node,
            "load_node": spec.load_node,
            "force_n": list(spec.force_n),
            "harmonic_hz": spec.harmonic_hz,
            "duration_s": spec.duration_s,
            "step_s": spec.step_s,
            "rho_inf": rho_inf,
            "integrator": "generalized-alpha (Chung-Hulbert)",
        },
        "full_model": {
            "order": full.order,
            "wall_time_s": full.wall_time_s,
            "factorization_s": full.factorization_s,
        },
        "cases": [
            {
                "name": case.name,
                "kind": case.kind,
                "peak_displacement_m": float(np.abs(full.outputs[case.name]).max()),
                **hot_spot_entries(full.stresses.get(case.name)),
                "reductions": list(rows[case.name].values()),
            }
            for case in cases
        ],
        "skipped": skipped,
    }
    if stress is not None:
        entry["stress"] = stress_settings(
            stress, f"the full FE model ({full.order} dofs), C_sigma q(t)"
        )
    return entry


def _deviation(candidate: np.ndarray, reference: np.ndarray) -> float:
    """``max |candidate - reference| / max |reference|`` over time and components."""
    return float(np.abs(candidate - reference).max() / np.abs(reference).max())


def _exudyn_runs(
    spec: TimeDomainSpec,
    frame: Frame,
    prepared: PreparedModel,
    model: ReducedModel,
    name: str,
    nodes: list[int],
    cases: list[LoadCase],
    rho_inf: float,
) -> dict[str, Any]:
    """Simulate the exported body in Exudyn for each case, at full and at small load."""
    arrays = exudyn_arrays(body_invariants(model, prepared, nodes, name))
    held_by_frame = frame.kind == "tangent" and frame.node == spec.clamp_node
    clamp = "frame" if held_by_frame else "joint"
    outputs, small, seconds = {}, {}, {}
    times = None
    for case in cases:
        for factor, store in ((1.0, outputs), (SMALL_LOAD, small)):
            force = _force_function(case, factor)
            exudyn_model = build_exudyn_model(
                arrays,
                clamp=clamp,
                joint_node=None if held_by_frame else spec.clamp_node,
                loads=[(spec.load_node, force)],
            )
            result = simulate_exudyn(
                exudyn_model,
                spec.duration_s,
                spec.step_s,
                nodes=[spec.load_node],
                spectral_radius=rho_inf,
            )
            store[case.name] = result.displacements[spec.load_node] / factor
            if factor == 1.0:
                seconds[case.name] = result.wall_time_s
                times = result.times
    response = TimeResponse(
        times=times,
        outputs=outputs,
        wall_time_s=float(sum(seconds.values())),
        factorization_s=0.0,
        order=model.projection.order,
        rho_inf=rho_inf,
        output_labels=tuple(f"{spec.load_node}:{d}" for d in ("ux", "uy", "uz")),
    )
    return {"response": response, "small": small, "time_s": seconds, "clamp": clamp}


def _force_function(case: LoadCase, factor: float) -> Callable[[float], np.ndarray]:
    """The force of ``case`` times ``factor`` as Exudyn's load function of time (s -> N).

    A step acts already at t = 0 here: Exudyn computes consistent initial accelerations from the
    loads at t = 0, which then equal the acceleration right after the step that
    :func:`~pymorembs.analysis.time_domain.simulate` starts from.
    """
    if case.kind == "step":
        constant = factor * case.initial_force()
        return lambda _t: constant
    return lambda t: factor * case.force(np.array([t]))[0]


__all__ = ["load_cases", "time_domain_checks"]
