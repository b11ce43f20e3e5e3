"""Plots of a reduction job (PNG, no display needed)."""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

from pymorembs.io.atomic import atomic_path


def plot_relative_errors(
    frequencies_hz: np.ndarray,
    errors: dict[str, np.ndarray],
    path: Path,
    title: str = "Relative error of the reduced models",
    estimates: dict[str, tuple[np.ndarray, np.ndarray]] | None = None,
    checked: np.ndarray | None = None,
    reference_accuracy: float | None = None,
) -> Path:
    """Relative error ``eps(f)`` (eq. 27) of each reduction over frequency, log scale (Fig. 9/10).

    Parameters
    ----------
    frequencies_hz : ndarray, shape (n_f,)
        Frequencies in Hz (0 Hz is drawn at the left edge of the axis).
    errors : dict of name -> ndarray, shape (n_f,)
    path : Path
        PNG file to write (atomically).
    estimates : dict of name -> (frequencies_hz, estimate), optional
        Error estimators as functions of frequency, drawn dashed in the colour of their
        reduction (paper Fig. 10).
    checked : ndarray of bool, shape (n_f,), optional
        Frequencies where the error was measured against the full model (the others against a
        reference model): drawn as black-edged markers.
    reference_accuracy : float, optional
        The reference model's measured relative deviation from the full model: a dotted line.
    """
    fig, ax = plt.subplots(figsize=(8, 4.5), dpi=120)
    markers = "os^vD<>ph*"
    floor = np.finfo(float).eps
    estimates = estimates or {}
    for k, (name, eps) in enumerate(errors.items()):
        (line,) = ax.semilogy(
            frequencies_hz, np.maximum(eps, floor), label=name, lw=1.4,
            marker=markers[k % len(markers)], markevery=max(1, len(eps) // 12), ms=4,
        )  # fmt: skip
        if checked is not None and np.any(checked):
            ax.semilogy(
                frequencies_hz[checked], np.maximum(eps[checked], floor), ls="none",
                marker=markers[k % len(markers)], ms=6, mfc=line.get_color(), mec="k",
                label="checked against the full model" if k == 0 else None,
            )  # fmt: skip
        if name in estimates:
            f_est, est = estimates[name]
            ax.semilogy(
                f_est,
                np.maximum(est, floor),
                ls="--",
                lw=1.2,
                color=line.get_color(),
                label=f"{name}: estimator",
            )
    if reference_accuracy:
        ax.axhline(
            max(reference_accuracy, floor), color="0.4", ls=":", lw=1.0,
            label="reference model: deviation from the full model",
        )  # fmt: skip
    ax.set_xlabel("frequency f [Hz]")
    ax.set_ylabel(r"relative error $\epsilon(f)$ (eq. 27)")
    ax.set_xlim(float(frequencies_hz.min()), float(frequencies_hz.max()))
    return _finish(fig, ax, title, path)


def plot_decay(
    series: dict[str, np.ndarray],
    path: Path,
    title: str = "Decay of approximate HSVs and Gramian eigenvalues",
) -> Path:
    """Normalised decay of singular values over the index (paper Fig. 11).

    Parameters
    ----------
    series : dict of label -> ndarray, shape (n_i,)
        Values in descending order (e.g. approximate Hankel singular values of eq. 26, the
        eigenvalues of the frequency-weighted Gramians); each is plotted as ``sigma_i / sigma_1``
        over ``i``, which for the Gramians is the error indicator ``sigma_{i+1} / sigma_1`` of a
        model of order ``i``.
    path : Path
        PNG file to write (atomically).
    """
    fig, ax = plt.subplots(figsize=(8, 4.5), dpi=120)
    for label, values in series.items():
        values = np.asarray(values, dtype=float)
        values = values[values > 0]
        if values.size == 0:
            continue
        values = values[values > 1e-30 * values[0]]  # below: round-off, not decay
        index = np.arange(1, values.size + 1)
        ax.semilogy(index, values / values[0], label=label, lw=1.4, marker=".", ms=4)
    ax.set_xlabel("dimension i of the reduced model")
    ax.set_ylabel(r"$\sigma_i / \sigma_1$")
    return _finish(fig, ax, title, path)


def _finish(fig: plt.Figure, ax: plt.Axes, title: str, path: Path) -> Path:
    """Grid, title and legend; write the PNG atomically and release the figure."""
    ax.grid(True, which="both", alpha=0.3)
    ax.set_title(title)
    ax.legend(loc="best", fontsize=8)
    fig.tight_layout()
    with atomic_path(path) as tmp:
        fig.savefig(tmp, format="png")
    plt.close(fig)
    return path
