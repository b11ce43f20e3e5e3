"""Time responses of full and reduced models side by side (paper Fig. 12), PNG without display."""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

from pymorembs.analysis.stress_history import StressHistory, compare_histories
from pymorembs.analysis.time_domain import TimeResponse
from pymorembs.errors import UserError
from pymorembs.io.atomic import atomic_path

#: The load direction of paper section 5.1, ``(1, 1, 1) / sqrt(3)``.
DIAGONAL = np.ones(3) / np.sqrt(3.0)


def plot_time_responses(
    responses: dict[str, TimeResponse],
    path: Path,
    reference: str | None = None,
    direction: np.ndarray = DIAGONAL,
    title: str = "Displacement of node 1: full and reduced models",
    direction_label: str = "(1,1,1)/√3",
) -> Path:
    """Displacement along ``direction`` over time, one column per load case (Fig. 12).

    The top row shows ``u(t) . e`` in mm for every model: the reference (full) model as a solid
    black line, the reduced models coloured and dashed. The bottom row shows the deviation of
    each reduced model from the reference, ``|(u_red - u_ref) . e|`` relative to
    ``max_t |u_ref . e|``, on a log scale.

    Parameters
    ----------
    responses : dict of label -> TimeResponse
        All on the same time grid with the same load cases; outputs (n_t, 3) displacements in m.
    path : Path
        PNG file to write (atomically).
    reference : str, optional
        Label of the full model; default the first entry.
    direction : ndarray, shape (3,)
        Direction ``e`` of the plotted displacement (normalised here); default the load
        direction ``(1, 1, 1) / sqrt(3)`` of the paper.
    title : str
    direction_label : str
        How ``e`` is named in the axis label.
    """
    if not responses:
        raise UserError("no time response to plot")
    reference = next(iter(responses)) if reference is None else reference
    if reference not in responses:
        raise UserError(f"reference {reference!r} is not among the responses")
    ref = responses[reference]
    e = np.asarray(direction, dtype=float).ravel()
    if e.shape != (3,) or not np.linalg.norm(e) > 0:
        raise UserError("the plot direction must be a non-zero vector of 3 components")
    e = e / np.linalg.norm(e)
    series = {}
    for label, response in responses.items():
        if response.times.shape != ref.times.shape or set(ref.outputs) - set(response.outputs):
            raise UserError(f"response {label!r} does not match the reference's time grid")
        series[label] = {case: 1e3 * (response.outputs[case] @ e) for case in ref.outputs}
    return _history_figure(
        ref.times,
        series,
        reference,
        path,
        titles={case: case for case in ref.outputs},
        ylabel=f"u₁ · {direction_label} [mm]",
        deviation_label="|Δu · e| / max|u_full · e|",
        title=title,
    )


def plot_stress_histories(
    histories: dict[str, dict[str, StressHistory]],
    path: Path,
    reference: str | None = None,
    title: str = "von Mises stress at the worst hot spot",
    unit: str = "model stress unit",
) -> Path:
    """The von Mises stress over time at the worst hot spot, one column per load case.

    The worst hot spot of a case is the one where some history deviates most from the
    reference's, relative to the reference's peak at that point
    (:func:`~pymorembs.analysis.stress_history.compare_histories`). Top row: ``sigma_vM(t)``
    there for every history, the reference solid black, the others dashed; bottom row
    ``|sigma_vM - sigma_vM,ref|`` over the reference's peak at that point, log scale.

    Parameters
    ----------
    histories : dict of label -> (dict of case name -> StressHistory)
        All at the same hot spots on the same time grid (e.g. ``TimeResponse.stresses`` of the
        full and the reduced models).
    path : Path
        PNG file to write (atomically).
    reference : str, optional
        Label of the reference (the full model); default the first entry.
    title : str
    unit : str
        The stress unit named on the axis.
    """
    if not histories:
        raise UserError("no stress history to plot")
    reference = next(iter(histories)) if reference is None else reference
    if reference not in histories:
        raise UserError(f"reference {reference!r} is not among the stress histories")
    ref = histories[reference]
    series: dict[str, dict[str, np.ndarray]] = {label: {} for label in histories}
    titles = {}
    for case, history in ref.items():
        worst, largest = 0, -1.0
        for label, others in histories.items():
            if label == reference:
                continue
            if case not in others:
                raise UserError(f"stress history {label!r} lacks the load case {case!r}")
            spots = compare_histories(others[case], history).hot_spots
            k = int(np.argmax([spot.max_rel_deviation for spot in spots]))
            if spots[k].max_rel_deviation > largest:
                worst, largest = k, spots[k].max_rel_deviation
        for label, others in histories.items():
            series[label][case] = others[case].von_mises[:, worst]
        titles[case] = f"{case}: hot spot {history.points[worst]}"
    return _history_figure(
        next(iter(ref.values())).times,
        series,
        reference,
        path,
        titles=titles,
        ylabel=f"σ_vM [{unit}]",
        deviation_label="|Δσ_vM| / max σ_vM,ref",
        title=title,
    )


def _history_figure(
    times: np.ndarray,
    series: dict[str, dict[str, np.ndarray]],
    reference: str,
    path: Path,
    titles: dict[str, str],
    ylabel: str,
    deviation_label: str,
    title: str,
) -> Path:
    """One column per case: the reference (solid black) and the others (dashed) on top, their
    deviation from the reference relative to its peak below (log scale)."""
    ref = series[reference]
    others = [label for label in series if label != reference]
    n_rows = 2 if others else 1
    fig, axes = plt.subplots(
        n_rows, len(titles), figsize=(5.5 * len(titles), 3.2 * n_rows + 0.8), dpi=120,
        sharex="col", squeeze=False, height_ratios=[2, 1][:n_rows],
    )  # fmt: skip
    floor = np.finfo(float).eps
    t_ms = 1e3 * times
    for col, case in enumerate(titles):
        top = axes[0, col]
        top.plot(t_ms, ref[case], color="black", lw=1.6, label=reference)
        peak = float(np.abs(ref[case]).max()) or 1.0
        for k, label in enumerate(others):
            values = series[label][case]
            (line,) = top.plot(
                t_ms, values, ls=(0, (4, 2)), lw=1.3, color=f"C{k % 10}", label=label
            )
            axes[1, col].semilogy(
                t_ms, np.maximum(np.abs(values - ref[case]) / peak, floor), lw=1.0,
                color=line.get_color(), label=label,
            )  # fmt: skip
        top.set_title(titles[case])
        top.set_ylabel(ylabel)
        top.grid(True, alpha=0.3)
        top.legend(loc="best", fontsize=8)
        if others:
            bottom = axes[1, col]
            bottom.set_ylabel(deviation_label)
            bottom.grid(True, which="both", alpha=0.3)
        axes[-1, col].set_xlabel("time t [ms]")
        axes[-1, col].set_xlim(float(t_ms[0]), float(t_ms[-1]))
    fig.suptitle(title, wrap=True)
    fig.tight_layout()
    with atomic_path(path) as tmp:
        fig.savefig(tmp, format="png")
    plt.close(fig)
    return path


__all__ = [
    "plot_large_motion",
    "plot_large_motion_stresses",
    "plot_stress_histories",
    "plot_time_responses",
]


def plot_large_motion(runs: dict[str, tuple[dict, dict[str, dict]]], node: int, path: Path) -> Path:
    """The large-motion checks: one column per motion (``[large_motion]`` of a job).

    Top: the magnitude of the frame's angular velocity (rad/s) of the reference body (solid
    black) and of every reduced body (dashed). Bottom: the magnitude of the elastic deflection
    (mm, body frame) of ``node`` (the node off every symmetry axis).

    Parameters
    ----------
    runs : dict of motion name -> (reference run, {body name: run})
        Runs with ``times`` (s), ``angular_velocity`` (n_t, 3) and ``deflections`` (node ->
        (n_t, 3) in m): ``runs`` of :class:`pymorembs.analysis.LargeMotionResult`.
    node : int
    path : Path
        PNG file to write (atomically).
    """
    if not runs:
        raise UserError("large-motion plot: no runs")
    fig, axes = plt.subplots(2, len(runs), figsize=(5.5 * len(runs), 6.0), squeeze=False)
    for column, (motion, (reference, others)) in enumerate(runs.items()):
        top, bottom = axes[0, column], axes[1, column]
        for label, run, style in [
            ("reference", reference, {"color": "black", "linewidth": 1.6}),
            *((name, r, {"linestyle": "--", "linewidth": 1.1}) for name, r in others.items()),
        ]:
            t = run["times"]
            top.plot(t, np.linalg.norm(run["angular_velocity"], axis=1), label=label, **style)
            bottom.plot(t, 1e3 * np.linalg.norm(run["deflections"][node], axis=1), **style)
        top.set_title(f"{motion}: frame angular velocity")
        top.set_ylabel("|ω| [rad/s]")
        bottom.set_title(f"elastic deflection of node {node}")
        bottom.set_ylabel("|u| [mm]")
        bottom.set_xlabel("time [s]")
        for ax in (top, bottom):
            ax.grid(True, alpha=0.3)
        top.legend(fontsize=8)
    fig.tight_layout()
    with atomic_path(path) as tmp:
        fig.savefig(tmp, format="png", dpi=110)
    plt.close(fig)
    return path


def plot_large_motion_stresses(
    runs: dict[str, tuple[dict, dict[str, dict]]], path: Path, reference_order: int
) -> Path:
    """The stress histories of the large-motion checks: one column per motion, the von Mises
    stress at the worst hot spot of every body against the modal reference body
    (:func:`plot_stress_histories`).

    Parameters
    ----------
    runs : dict of motion name -> (reference run, {body name: run})
        ``runs`` of :class:`pymorembs.analysis.LargeMotionResult`, each run with its
        ``stresses``.
    path : Path
        PNG file to write (atomically).
    reference_order : int
        The reference body's order (for its label).
    """
    label = f"reference (modal {reference_order})"
    histories: dict[str, dict[str, StressHistory]] = {label: {}}
    for motion, (reference, others) in runs.items():
        if "stresses" not in reference:
            raise UserError("large-motion stress plot: the runs have no stress histories")
        histories[label][motion] = reference["stresses"]
        for name, run in others.items():
            histories.setdefault(name, {})[motion] = run["stresses"]
    return plot_stress_histories(
        histories,
        path,
        reference=label,
        title="Large motions in Exudyn: von Mises stress at the worst hot spot",
    )
