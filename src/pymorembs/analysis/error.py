"""The relative error of a reduced model over a frequency band (paper eq. 27)."""

from __future__ import annotations

import numpy as np

from pymorembs.preparation.inertia_loads import is_inertia_label
from pymorembs.system import SecondOrderSystem


def relative_error(
    full: np.ndarray, reduced: np.ndarray, entries: np.ndarray | None = None
) -> np.ndarray:
    """``eps(omega) = ||H - H_bar||_F / ||H||_F`` (eq. 27) at each frequency.

    Parameters
    ----------
    full, reduced : ndarray, shape (n_f, n_outputs, n_inputs)
    entries : ndarray of bool, shape (n_outputs, n_inputs), optional
        Only these entries of ``H`` (a block, e.g. the ports' or the inertia loads'); default all.

    Returns
    -------
    ndarray, shape (n_f,)
    """
    if entries is not None:
        full, reduced = full[:, entries], reduced[:, entries]
        difference = np.linalg.norm(full - reduced, axis=1)
        reference = np.linalg.norm(full, axis=1)
    else:
        difference = np.linalg.norm(full - reduced, axis=(1, 2))
        reference = np.linalg.norm(full, axis=(1, 2))
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(
            reference > 0, difference / reference, np.where(difference > 0, np.inf, 0.0)
        )


def error_blocks(system: SecondOrderSystem) -> tuple[np.ndarray, np.ndarray | None]:
    """Entries of ``H`` (n_outputs, n_inputs) of the ports and of the inertia loads.

    Ports: port outputs to port inputs, the ``eps`` of eq. 27 as without inertia loads. Inertia
    loads: every entry with an inertia load as input or its collocated output (how the frame
    motion deforms the body at the ports and in the generalised coordinates the frame's
    equations see). None when the system has no inertia loads.
    """
    cols = np.array([is_inertia_label(label) for label in system.input_labels], dtype=bool)
    rows = np.array([is_inertia_label(label) for label in system.output_labels], dtype=bool)
    ports = ~rows[:, None] & ~cols[None, :]
    return ports, (None if ports.all() else ~ports)
