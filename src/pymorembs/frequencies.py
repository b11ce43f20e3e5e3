"""Frequency grids over a band (Hz): where errors are measured and methods place their shifts.

Below the reduction methods (SOAGA and the rational Krylov Gramian pick their shifts on it) and
the analysis (the error curves of paper eq. 27 are evaluated on it).
"""

from __future__ import annotations

import numpy as np

__all__ = ["DEFAULT_POINTS", "frequency_grid"]

#: Number of log-spaced frequencies in an error grid unless asked otherwise.
DEFAULT_POINTS = 400


def frequency_grid(f_min_hz: float, f_max_hz: float, points: int = DEFAULT_POINTS) -> np.ndarray:
    """Log-spaced frequencies over the band, in Hz.

    ``points`` frequencies log-spaced from ``max(f_min, 1e-3 f_max)`` to ``f_max``; when the band
    starts at 0 Hz, 0 Hz itself is added in front (the static response), so the grid then has
    ``points + 1`` entries.
    """
    if not (np.isfinite(f_min_hz) and np.isfinite(f_max_hz)) or not 0 <= f_min_hz < f_max_hz:
        raise ValueError(f"band must satisfy 0 <= f_min < f_max, got [{f_min_hz}, {f_max_hz}]")
    lower = max(f_min_hz, 1e-3 * f_max_hz)
    grid = np.geomspace(lower, f_max_hz, points)
    return np.concatenate([[0.0], grid]) if f_min_hz == 0 else grid
