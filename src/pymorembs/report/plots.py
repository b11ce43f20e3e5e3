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
) -> Path:
    """Relative error ``eps(f)`` (eq. 27) of each reduction over frequency, log scale (Fig. 9/10).

    Parameters
    ----------
    frequencies_hz : ndarray, shape (n_f,)
        Frequencies in Hz (0 Hz is drawn at the left edge of the axis).
    errors : dict of name -> ndarray, shape (n_f,)
    path : Path
        PNG file to write (atomically).
    """
    fig, ax = plt.subplots(figsize=(8, 4.5), dpi=120)
    markers = "os^vD<>ph*"
    for k, (name, eps) in enumerate(errors.items()):
        floor = np.finfo(float).eps
        ax.semilogy(
            frequencies_hz,
            np.maximum(eps, floor),
            label=name,
            lw=1.4,
            marker=markers[k % len(markers)],
            markevery=max(1, len(eps) // 12),
            ms=4,
        )
    ax.set_xlabel("frequency f [Hz]")
    ax.set_ylabel(r"relative error $\epsilon(f)$ (eq. 27)")
    ax.set_xlim(float(frequencies_hz.min()), float(frequencies_hz.max()))
    ax.grid(True, which="both", alpha=0.3)
    ax.set_title(title)
    ax.legend(loc="best", fontsize=8)
    fig.tight_layout()
    with atomic_path(path) as tmp:
        fig.savefig(tmp, format="png")
    plt.close(fig)
    return path
