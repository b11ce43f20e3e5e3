"""Time responses of full and reduced models side by side (paper Fig. 12), PNG without display."""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

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
    cases = list(ref.outputs)
    others = [label for label in responses if label != reference]
    n_rows = 2 if others else 1
    fig, axes = plt.subplots(
        n_rows, len(cases), figsize=(5.5 * len(cases), 3.2 * n_rows + 0.8), dpi=120,
        sharex="col", squeeze=False, height_ratios=[2, 1][:n_rows],
    )  # fmt: skip
    floor = np.finfo(float).eps
    t_ms = 1e3 * ref.times
    for col, case in enumerate(cases):
        top = axes[0, col]
        u_ref = ref.outputs[case] @ e
        top.plot(t_ms, 1e3 * u_ref, color="black", lw=1.6, label=reference)
        peak = float(np.abs(u_ref).max()) or 1.0
        for k, label in enumerate(others):
            response = responses[label]
            if case not in response.outputs or response.times.shape != ref.times.shape:
                raise UserError(f"response {label!r} does not match the reference's time grid")
            u = response.outputs[case] @ e
            (line,) = top.plot(
                t_ms, 1e3 * u, ls=(0, (4, 2)), lw=1.3, color=f"C{k % 10}", label=label
            )
            axes[1, col].semilogy(
                t_ms, np.maximum(np.abs(u - u_ref) / peak, floor), lw=1.0,
                color=line.get_color(), label=label,
            )  # fmt: skip
        top.set_title(case)
        top.set_ylabel(f"u₁ · {direction_label} [mm]")
        top.grid(True, alpha=0.3)
        top.legend(loc="best", fontsize=8)
        if others:
            bottom = axes[1, col]
            bottom.set_ylabel("|Δu · e| / max|u_full · e|")
            bottom.grid(True, which="both", alpha=0.3)
        axes[-1, col].set_xlabel("time t [ms]")
        axes[-1, col].set_xlim(float(t_ms[0]), float(t_ms[-1]))
    fig.suptitle(title)
    fig.tight_layout()
    with atomic_path(path) as tmp:
        fig.savefig(tmp, format="png")
    plt.close(fig)
    return path


__all__ = ["plot_time_responses"]


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
