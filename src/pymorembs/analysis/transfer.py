"""Frequency responses ``H(i omega) = C (-omega^2 M + i omega D + (1 + i eta) K)^{-1} B``.

Full (sparse) systems: one sparse factorization per frequency, all inputs solved in one block,
never a dense inverse; the frequencies are shared out to parallel processes (or a Dask cluster)
in contiguous chunks, with the same result as one after the other. Reduced (dense) systems:
batched dense solves, or a closed form when the reduced model is in modal form
(identity mass, diagonal stiffness and damping).
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from pymorembs.linalg.factorization import Factorization
from pymorembs.linalg.inertia_relief import InertiaRelief
from pymorembs.parallel import chunks, parallel_map, usable_cores
from pymorembs.progress import Progress
from pymorembs.system import SecondOrderSystem

#: Below this order a full model's sweep runs serially unless workers are given explicitly:
#: starting processes costs more than the factorizations save.
PARALLEL_MIN_ORDER = 3000

#: Most frequencies per parallel task; fewer make the progress bar and the load balance finer.
MAX_TASKS = 64


def transfer_function(
    system: SecondOrderSystem,
    frequencies_hz: np.ndarray,
    workers: int | None = 1,
    scheduler: str | None = None,
    label: str = "frequency response",
) -> np.ndarray:
    """Frequency response matrix at each frequency.

    Parameters
    ----------
    system : SecondOrderSystem
        Full sparse or reduced dense system.
    frequencies_hz : ndarray, shape (n_f,)
        Frequencies in Hz (omega = 2 pi f).
    workers : int or None
        Full (sparse) systems: number of processes sharing the frequencies
        (:func:`pymorembs.parallel.parallel_map`); None: the usable cores for systems of order
        :data:`PARALLEL_MIN_ORDER` and more, else 1. The result does not depend on it.
    scheduler : str, optional
        Full systems: ``"local"`` or the address of a Dask scheduler to run the sweep on.
    label : str
        Label of the progress bar.

    Returns
    -------
    ndarray, complex, shape (n_f, n_outputs + n_stress, n_inputs)
        The rows of :attr:`SecondOrderSystem.observed_matrix`: the outputs, then the stress
        outputs (if any).
    """
    frequencies_hz = np.asarray(frequencies_hz, dtype=float).ravel()
    if system.is_sparse:
        if workers is None:
            workers = usable_cores() if system.order >= PARALLEL_MIN_ORDER else 1
        return _sparse_response(system, frequencies_hz, workers, scheduler, label)
    return _dense_response(system, frequencies_hz, label)


def _sparse_response(
    system: SecondOrderSystem,
    frequencies_hz: np.ndarray,
    workers: int = 1,
    scheduler: str | None = None,
    label: str = "frequency response",
) -> np.ndarray:
    observed = system.observed_matrix  # sparse CSR with stress outputs: stays sparse
    out = np.zeros((frequencies_hz.size, observed.shape[0], system.n_inputs), dtype=complex)
    # inputs/outputs on fixed dofs are zero columns of B / rows of C: nothing to solve for
    cols = np.flatnonzero(np.any(system.input_matrix != 0, axis=0))
    rows = _nonzero_rows(observed)
    if cols.size == 0 or rows.size == 0 or frequencies_hz.size == 0:
        return out
    context = (system, system.input_matrix[:, cols], observed[rows])
    n_f = frequencies_hz.size
    if workers == 1 and scheduler is None:
        tasks = [range(k, k + 1) for k in range(n_f)]
    else:
        tasks = chunks(n_f, min(MAX_TASKS, max(4 * workers, n_f // 4)))
    with Progress(label, total=n_f, unit="freq") as bar:
        parts = parallel_map(
            _response_chunk,
            [frequencies_hz[task.start : task.stop] for task in tasks],
            workers=workers,
            scheduler=scheduler,
            context=context,
            progress=bar,
            weights=[len(task) for task in tasks],
        )
    block = np.concatenate(parts)
    out[:, rows[:, None], cols[None, :]] = block
    return out


def _nonzero_rows(matrix: sp.csr_matrix | np.ndarray) -> np.ndarray:
    """Indices of the rows of a dense or sparse matrix with a nonzero entry."""
    if sp.issparse(matrix):
        return np.flatnonzero(abs(matrix).max(axis=1).toarray().ravel())
    return np.flatnonzero(np.any(matrix != 0, axis=1))


def _response_chunk(
    context: tuple[SecondOrderSystem, np.ndarray, np.ndarray], frequencies_hz: np.ndarray
) -> np.ndarray:
    """``C (K(s))^{-1} B`` of the nonzero ports at each frequency: one factorization each."""
    system, b, c = context
    out = np.empty((frequencies_hz.size, c.shape[0], b.shape[1]), dtype=complex)
    for k, f in enumerate(frequencies_hz):
        terms, scale = system.dynamic_terms(2j * np.pi * f)
        label = f"dynamic stiffness at {f:g} Hz"
        if f == 0 and system.rigid_modes is not None:  # free body: static solve by inertia relief
            factorization = InertiaRelief(system.stiffness, system.mass, system.rigid_modes, label)
            x = factorization.solve(b)
        else:
            # a job's other steps factorize K too (0 Hz), not the dynamic stiffness of a sweep
            factorization = Factorization(terms, label=label, share=f == 0)
            x = factorization.solve(b)
            if system.rigid_modes is not None:
                x = _in_complement(factorization, system.mass, system.rigid_modes, x)
        out[k] = np.asarray(c @ x) / scale
        del factorization  # free the factors before the next ones: one live factorization
    return out


def _in_complement(
    factorization: Factorization, mass, rigid: np.ndarray, x: np.ndarray
) -> np.ndarray:
    """The response of a free body in the mass-orthogonal complement of its rigid-body modes.

    ``x = Z^-1 b`` becomes the solution of ``Z x = b + M R mu`` with ``R^T M x = 0``
    (``Z = s^2 M + s D + K``): ``x - Y S^-1 (M R)^T x`` with ``Y = Z^-1 M R``,
    ``S = (M R)^T Y``. For an exact model this changes nothing (its loads are self-equilibrated
    and ``K R = 0``); for rounded entries (rigid-body modes at +-1 Hz) it takes out the
    resonances of those rounded modes, which the Buckens frame excludes.
    """
    mr = np.asarray(mass @ rigid)
    y = factorization.solve(mr.astype(x.dtype))
    return x - y @ np.linalg.solve(mr.T @ y, mr.T @ x)


def _dense_response(
    system: SecondOrderSystem, frequencies_hz: np.ndarray, label: str = "frequency response"
) -> np.ndarray:
    s = 2j * np.pi * frequencies_hz
    m, k, d = system.mass, system.stiffness, system.damping
    k_factor = 1.0 + 1j * system.loss_factor
    b, c = system.input_matrix, system.observed_matrix
    diagonal = _is_diagonal(m) and _is_diagonal(k) and (d is None or _is_diagonal(d))
    if diagonal:
        dd = np.zeros(m.shape[0]) if d is None else np.diag(d)
        denom = s[:, None] ** 2 * np.diag(m) + s[:, None] * dd + k_factor * np.diag(k)
        return np.einsum("ri,fi,ip->frp", c, 1.0 / denom, b)
    out = np.empty((s.size, c.shape[0], b.shape[1]), dtype=complex)
    with Progress(f"{label} (reduced)", total=s.size, unit="freq") as bar:
        for j, s_j in enumerate(s):  # one small dense solve per frequency, no (n_f, n, n) array
            a = s_j**2 * m + k_factor * k
            if d is not None:
                a = a + s_j * d
            out[j] = c @ np.linalg.solve(a, b)
            bar.update()
    return out


def _is_diagonal(matrix: np.ndarray, tol: float = 1e-12) -> bool:
    """Off-diagonal entries below ``tol`` times the largest diagonal entry."""
    off = matrix - np.diag(np.diag(matrix))
    return bool(np.abs(off).max(initial=0.0) <= tol * np.abs(np.diag(matrix)).max(initial=0.0))
