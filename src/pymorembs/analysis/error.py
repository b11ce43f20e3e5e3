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
    """Entries of ``H`` (n_outputs + n_stress, n_inputs) of the ports and of the inertia loads.

    ``H`` has the rows of :attr:`SecondOrderSystem.observed_matrix`
    (:func:`~pymorembs.analysis.transfer.transfer_function`). Ports: port outputs to port
    inputs, the ``eps`` of eq. 27 as without inertia loads. Inertia loads: every entry with an
    inertia load as input or its collocated output (how the frame motion deforms the body at
    the ports and in the generalised coordinates the frame's equations see). None when the
    system has no inertia loads. Stress outputs belong to neither: :func:`stress_block`.
    """
    cols = np.array([is_inertia_label(label) for label in system.input_labels], dtype=bool)
    rows = np.array([is_inertia_label(label) for label in system.output_labels], dtype=bool)
    ports = ~rows[:, None] & ~cols[None, :]
    inertia = None if ports.all() else ~ports
    stress = np.zeros((system.n_stress, system.n_inputs), dtype=bool)
    ports = np.vstack([ports, stress])
    return ports, (None if inertia is None else np.vstack([inertia, stress]))


def stress_block(system: SecondOrderSystem) -> np.ndarray | None:
    """Entries of ``H`` (n_outputs + n_stress, n_inputs) of the stress outputs, the third
    block beside :func:`error_blocks`' ports and inertia loads.

    Every stress output under every input (the port forces and the scaled inertia loads): the
    ``eps_s`` of eq. 27 is the relative error of the hot spots' stress response to all loads
    the reduction was built for. None when the system has no stress outputs.
    """
    if system.n_stress == 0:
        return None
    entries = np.zeros((system.n_outputs + system.n_stress, system.n_inputs), dtype=bool)
    entries[system.n_outputs :] = True
    return entries
