"""The reduced matrices for MATLAB and for pyMOR.

``reduced.mat`` holds the same arrays as ``reduced.npz`` (see :func:`reduced_arrays`): the reduced
``M``, ``K``, ``D`` (viscous, for simulation), ``B``, ``C``, the basis ``V`` on all dofs of the
body (eq. 18) with its dof table, the eigenfrequencies in Hz and the port labels.

:func:`to_pymor` wraps a model as a pyMOR ``SecondOrderModel``, ``M x'' + E x' + K x = B u``,
``y = C_p x`` (pyMOR's ``E`` is the damping matrix). pyMOR is an optional dependency
(``pip install pymorembs[pymor]``).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import scipy.sparse as sp

from pymorembs.errors import UserError
from pymorembs.export import deterministic
from pymorembs.preparation import PreparedModel
from pymorembs.reduction.projection import ReducedModel
from pymorembs.system import SecondOrderSystem


def reduced_arrays(model: ReducedModel, prepared: PreparedModel) -> dict[str, np.ndarray]:
    """The arrays of a reduced model that ``reduced.npz`` and ``reduced.mat`` hold.

    Returns
    -------
    dict
        ``M``, ``K``, ``D`` (order, order); ``B`` (order, n_inputs); ``C`` (n_outputs, order);
        ``V`` (n_dof, order), the basis on all dofs of ``prepared.body`` (eq. 18);
        ``eigenfrequencies_hz`` (order,); ``dof_nodes``, ``dof_directions`` (n_dof,), direction
        codes 0..5 = ux uy uz rx ry rz; ``input_labels``, ``output_labels``.
    """
    system = model.system
    dofs = prepared.body.dofs
    return {
        "M": np.asarray(system.mass),
        "K": np.asarray(system.stiffness),
        "D": model.damping_matrix,
        "B": np.asarray(system.input_matrix),
        "C": np.asarray(system.output_matrix),
        "V": prepared.expand(model.projection.V),
        "eigenfrequencies_hz": model.eigenfrequencies_hz,
        "dof_nodes": dofs.nodes,
        "dof_directions": dofs.directions,
        "input_labels": np.array(system.input_labels),
        "output_labels": np.array(system.output_labels),
    }


def write_reduced_mat(path: str | Path, arrays: dict[str, np.ndarray]) -> Path:
    """Write ``arrays`` (see :func:`reduced_arrays`) as ``reduced.mat``, atomically: a MATLAB 5
    file with the labels as cell arrays and a ``format`` entry, through the byte-reproducible
    :func:`pymorembs.export.deterministic.write_mat`."""
    data: dict[str, Any] = {key: _matlab(value) for key, value in arrays.items()}
    data["format"] = "pymorembs reduced matrices"
    return deterministic.write_mat(path, data, do_compression=True, oned_as="column")


def _matlab(value: np.ndarray) -> np.ndarray:
    """Labels as a MATLAB cell array of strings; numbers unchanged."""
    value = np.asarray(value)
    if value.dtype.kind in "US":
        cells = np.empty((value.size, 1), dtype=object)
        cells[:, 0] = [str(v) for v in value]
        return cells
    return value


def to_pymor(system: SecondOrderSystem, damping: np.ndarray | sp.spmatrix | None = None) -> Any:
    """A pyMOR ``SecondOrderModel`` of ``system`` (sparse full or dense reduced).

    Parameters
    ----------
    system : SecondOrderSystem
        ``M q'' + D q' + K q = B u``, ``y = C q``.
    damping : array or sparse matrix, optional
        Viscous damping to use instead of ``system.damping`` (e.g.
        :attr:`ReducedModel.damping_matrix`, which includes a modal damping ratio).

    Raises
    ------
    UserError
        If pyMOR is not installed, or the system has a loss factor (modal damping ratio) and no
        viscous ``damping`` is given: pyMOR's model has viscous damping only.
    """
    try:
        from pymor.models.iosys import SecondOrderModel
    except ImportError:
        raise UserError("the pyMOR adapter needs pyMOR: pip install 'pymorembs[pymor]'") from None
    if damping is None:
        if np.any(np.asarray(system.modal_damping_ratio) != 0):
            raise UserError(
                "to_pymor: a modal damping ratio is a loss factor, not a viscous matrix; pass "
                "damping= (e.g. ReducedModel.damping_matrix)"
            )
        damping = system.damping
    if damping is None:
        damping = (
            sp.csr_matrix(system.mass.shape) if system.is_sparse else np.zeros_like(system.mass)
        )
    matrices = [system.mass, damping, system.stiffness]
    if system.is_sparse:
        matrices = [sp.csc_matrix(m) for m in matrices]
    else:
        matrices = [np.asarray(m, dtype=float) for m in matrices]
    b = np.asarray(system.input_matrix, dtype=float)
    c = np.asarray(system.output_matrix, dtype=float)
    return SecondOrderModel.from_matrices(*matrices, b, c)


__all__ = ["reduced_arrays", "to_pymor", "write_reduced_mat"]
