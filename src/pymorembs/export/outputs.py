"""Write the files a job asks for (``[export] outputs``) for one reduced model.

=========  ==============================================================================
output     files (in the reduction's folder)
=========  ==============================================================================
``npz``    ``reduced.npz``: reduced M, K, D, B, C, the basis V on all dofs, dof table
``mtx``    ``M.mtx``, ``K.mtx``, ``D.mtx``, ``B.mtx``, ``C.mtx`` (Matrix Market)
``mat``    ``reduced.mat``: the arrays of ``reduced.npz`` for MATLAB
``sid``    ``<name>.SID_FEM``: Standard Input Data for Simpack and other codes
``neweul`` ``<name>_neweul.mat``: the SID invariants for Neweul-M²
``exudyn`` ``<name>_exudyn.npz``: the data of an Exudyn ``ObjectFFRFreducedOrder``
``vtu``    ``<name>.vtu``: the surface with every shape function and static response
           (:mod:`pymorembs.export.vtu`), for ParaView
=========  ==============================================================================

The body outputs (``sid``, ``neweul``, ``exudyn``) need a one-sided (Galerkin) projection, so that
the reduced matrices are ``V^T M V`` and ``V^T K V`` of a real displacement basis.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np
import scipy.io

from pymorembs.errors import NumericalError, UserError
from pymorembs.export.invariants import BodyInvariants, StiffeningTerms, compute_invariants
from pymorembs.io.atomic import atomic_path
from pymorembs.prepare import PreparedModel
from pymorembs.reduction.projection import ReducedModel
from pymorembs.system import check_damping

from .deterministic import write_npz
from .matrices import reduced_arrays, write_reduced_mat

BODY_OUTPUTS = ("sid", "neweul", "exudyn")


def body_invariants(
    model: ReducedModel, prepared: PreparedModel, nodes: Sequence[int], name: str
) -> BodyInvariants:
    """The mass invariants of a reduced body (SID_NOTES section 4) for its frame ``nodes``."""
    if not model.projection.one_sided:
        raise UserError(
            f"reduction '{name}': SID, Neweul-M² and Exudyn bodies need a one-sided (Galerkin) "
            "projection; drop two_sided or write only matrices"
        )
    basis = prepared.expand(model.projection.V)  # eq. 18: all dofs
    stiffening = None
    if prepared.stiffening is not None:
        cases, loads = prepared.stiffening.projected(model.projection.V)
        stiffening = StiffeningTerms(cases, loads, prepared.stiffening.source)
    return compute_invariants(
        prepared.body,
        basis,
        model.system.mass,
        model.system.stiffness,
        model.damping_matrix,
        nodes,
        frequencies_hz=model.eigenfrequencies_hz,
        name=name,
        stiffening=stiffening,
    )


def check_before_writing(model: ReducedModel, name: str) -> None:
    """Refuse a reduced model that is not fit to be written.

    Checks (:meth:`~pymorembs.system.SecondOrderSystem.check_reduced`): finite ``V``, ``M``,
    ``K``, ``D``, ``B``, ``C``; symmetric ``M``, ``K``, ``D``; positive definite ``M``;
    positive semidefinite ``K`` and the viscous damping written for simulation
    (:attr:`ReducedModel.damping_matrix`, which includes a modal damping ratio). An oblique
    (two-sided) model has non-symmetric 2x2 blocks for complex pairs; it is checked for finite
    entries here, its stability when it is formed
    (:func:`~pymorembs.reduction.projection.reduced_model`).

    Raises
    ------
    NumericalError
        Naming the reduction and the failed check; nothing has been written.
    """
    try:
        if not np.all(np.isfinite(model.projection.V)):
            raise NumericalError("the basis V has NaN or infinite entries")
        if model.projection.one_sided:
            model.system.check_reduced()
            check_damping(np.asarray(model.damping_matrix), "reduced damping matrix (written)")
        else:  # W^T K V of complex pairs is block diagonal, not symmetric: checked when formed
            system = model.system
            for label, matrix in (
                ("mass", system.mass),
                ("stiffness", system.stiffness),
                ("damping", model.damping_matrix),
                ("input", system.input_matrix),
                ("output", system.output_matrix),
            ):
                if not np.all(np.isfinite(np.asarray(matrix))):
                    raise NumericalError(f"reduced {label} matrix has NaN or infinite entries")
    except NumericalError as exc:
        raise NumericalError(f"reduction '{name}': {exc}; nothing was written") from None


def write_outputs(
    model: ReducedModel,
    prepared: PreparedModel,
    name: str,
    outputs: Sequence[str],
    nodes: Sequence[int],
    folder: Path,
) -> list[str]:
    """Write the ``outputs`` of one reduced model into ``folder``; return the file names."""
    from pymorembs.export.exudyn_body import surface_mesh, write_exudyn_body
    from pymorembs.export.neweul import write_neweul
    from pymorembs.export.sid import write_sid
    from pymorembs.export.vtu import write_reduced_vtu

    check_before_writing(model, name)
    names: list[str] = []
    arrays = reduced_arrays(model, prepared)
    if "npz" in outputs:
        write_npz(folder / "reduced.npz", arrays, compress=True)
        names.append("reduced.npz")
    if "mtx" in outputs:
        for key in ("M", "K", "D", "B", "C"):
            with atomic_path(folder / f"{key}.mtx") as tmp:
                scipy.io.mmwrite(str(tmp), np.asarray(arrays[key]), precision=17)
            names.append(f"{key}.mtx")
    if "mat" in outputs:
        write_reduced_mat(folder / "reduced.mat", arrays)
        names.append("reduced.mat")
    if "vtu" in outputs:
        write_reduced_vtu(folder / f"{name}.vtu", model, prepared)
        names.append(f"{name}.vtu")
    if any(kind in outputs for kind in BODY_OUTPUTS):
        invariants = body_invariants(model, prepared, nodes, name)
        if "sid" in outputs:
            write_sid(
                folder / f"{name}.SID_FEM",
                invariants,
                comment=f"SID generated by pymorembs, reduction {name}",
            )
            names.append(f"{name}.SID_FEM")
        if "neweul" in outputs:
            write_neweul(folder / f"{name}_neweul.mat", invariants)
            names.append(f"{name}_neweul.mat")
        if "exudyn" in outputs:
            surface = surface_mesh(prepared.body, prepared.expand(model.projection.V))
            write_exudyn_body(folder / f"{name}_exudyn.npz", invariants, surface=surface)
            names.append(f"{name}_exudyn.npz")
    return names


__all__ = ["BODY_OUTPUTS", "body_invariants", "check_before_writing", "write_outputs"]
