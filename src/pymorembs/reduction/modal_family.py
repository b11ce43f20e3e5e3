"""Improved modal reduction (paper section 3.3): best modes, response modes, Craig-Bampton.

Plain modal reduction keeps the lowest eigenmodes, whatever the inputs and outputs are. The
methods here use the ports:

* :func:`best_modes` -- the ``n`` modes with the largest approximate Hankel singular values
  (eq. 26), the "improved modal" reduction of the paper's Fig. 9 and 10;
* :func:`modes_with_frm` -- eigenmodes plus frequency response modes
  ``Phi_frm = (K - omega_frm^2 M)^{-1} B`` (section 3.3), e.g. the paper's best 40 modes plus one
  frequency response mode at 1 Hz (order 46 on the rack with 6 inputs);
* :func:`craig_bampton` -- the component mode synthesis of Craig and Bampton: static constraint
  modes of the interface dofs plus fixed-interface normal modes.

All of them return a one-sided :class:`~pymorembs.reduction.projection.Projection` (``W is V``); the
basis is put into modal form by :func:`~pymorembs.reduction.projection.reduced_model`.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence

import numpy as np
import scipy.sparse as sp

from pymorembs.errors import NumericalError, UserError
from pymorembs.linalg.factorization import Factorization
from pymorembs.linalg.inertia_relief import InertiaRelief
from pymorembs.linalg.mass_split import condensed_dense_eigh
from pymorembs.linalg.orthogonalization import OrthonormalBasis
from pymorembs.methods import CraigBamptonOptions, ModalOptions, OptionError
from pymorembs.preparation.inertia_loads import is_inertia_label
from pymorembs.reduction.modal import DEFAULT_SHIFT_HZ, eigenmodes, lowest_modes
from pymorembs.reduction.projection import Projection
from pymorembs.system import SecondOrderSystem

#: Damping ratio used in eq. 26 when neither the system nor the caller gives one. For a constant
#: ratio it only scales all approximate Hankel singular values alike (the choice of modes does
#: not depend on it); it matters for the reported values only.
DEFAULT_DAMPING_RATIO = 0.01

#: Eigenvalues closer than this (relative) form a cluster of repeated eigenvalues, whose modes
#: are rotated before ranking (see :func:`rotate_clusters`). Symmetric FE models repeat
#: eigenvalues to ~1e-13; distinct ones of real structures differ by far more.
CLUSTER_RTOL = 1e-8

#: A mode whose ``||C phi|| ||phi^T B||`` is below this fraction of the largest is neither
#: controllable nor observable up to round-off: its approximate HSV counts as 0 for the ranking
#: (ties then go to the lowest mode, so the choice does not depend on round-off).
NEGLIGIBLE = 1e-12

#: Largest interior block whose fixed-interface eigenproblem is solved densely when (nearly) all
#: its modes are asked for (Lanczos needs fewer modes than dofs).
DENSE_INTERIOR_LIMIT = 5000


# --------------------------------------------------------------------------------------------
# best modes (eq. 26)
# --------------------------------------------------------------------------------------------


def default_candidates(order: int, n: int) -> int:
    """Number of candidate modes for :func:`best_modes`: ``max(3 order, order + 20)``, < ``n``."""
    return int(min(max(3 * order, order + 20), n - 1))


def modal_damping_ratios(
    system: SecondOrderSystem,
    eigenvalues: np.ndarray,
    modes: np.ndarray,
    damping_ratio: float | None = None,
) -> tuple[np.ndarray, str]:
    """Modal damping ratios ``xi_i`` of mass-normalised modes, for eq. 25-26.

    In this order of precedence:

    1. ``system.modal_damping_ratio`` if it is > 0 (constant, source ``"modal"``);
    2. the ``damping_ratio`` argument if given (constant, ``"argument"``);
    3. viscous damping ``D`` of the system (Rayleigh or explicit):
       ``xi_i = phi_i^T D phi_i / (2 omega_i)`` -- exact for proportional damping, where
       ``Phi^T D Phi = diag(2 xi_i omega_i)`` (eq. 25) -- plus ``eta / 2`` for a structural loss
       factor ``eta`` on top (``"viscous"``);
    4. a loss factor alone: ``xi = eta / 2``, its equivalent at resonance (``"loss factor"``);
    5. :data:`DEFAULT_DAMPING_RATIO` (``"default"``).

    A mode that the viscous damping does not damp at all (``phi_i^T D phi_i = 0``, possible with
    explicit dampers) gets :data:`DEFAULT_DAMPING_RATIO`: eq. 26 would make it infinite.

    Returns
    -------
    ratios : ndarray, shape (k,)
    source : str
        Which of the rules above applied.
    """
    k = eigenvalues.size
    if system.modal_damping_ratio > 0:
        return np.full(k, float(system.modal_damping_ratio)), "modal"
    if damping_ratio is not None:
        if not np.isfinite(damping_ratio) or damping_ratio <= 0:
            raise UserError(f"best modes: damping ratio must be > 0, got {damping_ratio!r}")
        return np.full(k, float(damping_ratio)), "argument"
    if system.damping is not None:
        omega = np.sqrt(np.clip(eigenvalues, 0.0, None))
        modal_d = np.einsum("ij,ij->j", modes, np.asarray(system.damping @ modes))
        with np.errstate(divide="ignore", invalid="ignore"):
            ratios = modal_d / (2.0 * omega) + 0.5 * system.loss_factor
        ratios = np.where(np.isfinite(ratios) & (ratios > 0), ratios, DEFAULT_DAMPING_RATIO)
        return ratios, "viscous"
    if system.loss_factor > 0:
        return np.full(k, 0.5 * float(system.loss_factor)), "loss factor"
    return np.full(k, DEFAULT_DAMPING_RATIO), "default"


def rotate_clusters(
    eigenvalues: np.ndarray,
    modes: np.ndarray,
    input_matrix: np.ndarray,
    output_matrix: np.ndarray,
    rtol: float = CLUSTER_RTOL,
) -> tuple[np.ndarray, int]:
    """Modes of repeated eigenvalues rotated to a basis defined by the ports, not by chance.

    The modes of an ``m``-fold eigenvalue are any mass-orthonormal basis ``Phi_c Q`` of the
    eigenspace (the eigensolver's is random), and eq. 26 depends on that basis: one
    controllable direction spread over ``m`` modes gets ``m`` small values instead of one large
    one. Each cluster is rotated by the left singular vectors ``U`` of
    ``[B_c / ||B_c||_F, C_c^T / ||C_c||_F]`` (``B_c = Phi_c^T B``, ``C_c = C Phi_c``): the result
    ``Phi_c U`` is independent of the basis the solver returned, its first modes carry the
    transfer of the cluster and the rest, those neither controllable nor observable, get 0.
    For collocated ports (``C = B^T``) eq. 26 then gives the exact Hankel singular values of
    the cluster, the singular values of ``C_c B_c / (4 omega xi)``.

    Parameters
    ----------
    eigenvalues : ndarray, shape (k,), ascending
    modes : ndarray, shape (n, k), mass-normalised
    input_matrix, output_matrix : ndarray, shapes (n, p) and (r, n)
    rtol : float
        Consecutive eigenvalues ``lambda_i <= lambda_{i+1} <= (1 + rtol) lambda_i`` are repeated.

    Returns
    -------
    modes : ndarray, shape (n, k)
        A copy with each cluster rotated (still mass-orthonormal).
    clusters : int
        Number of clusters of two or more modes.
    """
    modes = np.array(modes, copy=True)
    gaps = np.diff(eigenvalues) > rtol * np.abs(eigenvalues[1:])
    starts = np.flatnonzero(np.concatenate([[True], gaps]))
    ends = np.append(starts[1:], eigenvalues.size)
    clusters = 0
    for start, end in zip(starts, ends, strict=True):
        if end - start < 2:
            continue
        clusters += 1
        block = modes[:, start:end]
        parts = [block.T @ input_matrix, (output_matrix @ block).T]
        scaled = [part / np.linalg.norm(part) for part in parts if np.linalg.norm(part) > 0]
        if scaled:
            u, _, _ = np.linalg.svd(np.hstack(scaled))
            modes[:, start:end] = block @ u
    return modes, clusters


def approximate_hsv(
    eigenvalues: np.ndarray,
    modes: np.ndarray,
    input_matrix: np.ndarray,
    output_matrix: np.ndarray,
    ratios: np.ndarray,
) -> np.ndarray:
    """Approximate Hankel singular values of modes (paper eq. 26).

    ``sigma_i = ||C_tilde[:, i]||_2 ||B_tilde[i, :]||_2 / (4 omega_i xi_i)`` with
    ``C_tilde = C Phi`` and ``B_tilde = Phi^T B`` for mass-normalised modes ``Phi``.

    Parameters
    ----------
    eigenvalues : ndarray, shape (k,)
        ``omega_i^2``.
    modes : ndarray, shape (n, k)
        Mass-normalised modes.
    input_matrix, output_matrix : ndarray, shapes (n, p) and (r, n)
    ratios : ndarray, shape (k,)
        Modal damping ratios ``xi_i``.

    Returns
    -------
    ndarray, shape (k,)
        A mode neither controllable nor observable gets 0; a mode at 0 Hz that is both gets
        ``inf`` (an undamped integrator).
    """
    observability = np.linalg.norm(output_matrix @ modes, axis=0)
    controllability = np.linalg.norm(modes.T @ input_matrix, axis=1)
    numerator = observability * controllability
    omega = np.sqrt(np.clip(eigenvalues, 0.0, None))
    with np.errstate(divide="ignore", invalid="ignore"):
        sigma = numerator / (4.0 * omega * ratios)
    return np.where(numerator == 0, 0.0, sigma)


def best_modes(
    system: SecondOrderSystem,
    order: int,
    candidates: int | None = None,
    damping_ratio: float | None = None,
    shift_hz: float = DEFAULT_SHIFT_HZ,
) -> Projection:
    """The ``order`` eigenmodes with the largest approximate Hankel singular values (eq. 26).

    The ``candidates`` lowest (elastic) eigenmodes ``Phi`` are computed, mass-normalised, and
    ranked by ``sigma_i = ||C Phi_i||_2 ||Phi_i^T B||_2 / (4 omega_i xi_i)`` -- the modal form
    (eq. 25) of a proportionally damped system makes the dyad ``C_i B_i / (omega_i^2 - omega^2
    + 2 i xi_i omega_i omega)`` of mode ``i`` the part of ``H`` it carries (eq. 25-26). A mode
    that the inputs do not excite or the outputs do not see is skipped, whatever its frequency.

    Two refinements make the choice reproducible: the modes of a repeated eigenvalue are
    rotated to a basis set by the ports (:func:`rotate_clusters`; the paper's rack, symmetric,
    has five-fold eigenvalues), and modes whose eq. 26 numerator is round-off
    (:data:`NEGLIGIBLE`) rank as 0, so when fewer than ``order`` modes take part in the
    transfer the rest are the lowest of the others (``negligible_modes_chosen`` counts them).

    Parameters
    ----------
    system : SecondOrderSystem
        Sparse full system with inputs and outputs.
    order : int
        Number of modes kept.
    candidates : int, optional
        Number of lowest modes to choose from; default ``max(3 order, order + 20)`` capped at
        ``n - 1``. Modes above the highest candidate are never considered.
    damping_ratio : float, optional
        Modal damping ratio for eq. 26; see :func:`modal_damping_ratios` for when it is used
        (the system's modal damping ratio comes first). With a constant ratio the choice does
        not depend on it; with Rayleigh damping ``xi_i`` varies and the choice does.
    shift_hz : float
        Shift of the eigensolver, see :func:`~pymorembs.reduction.modal.eigenmodes`.

    Returns
    -------
    Projection
        ``V`` = the chosen mass-normalised modes in ascending frequency. ``parameters``:
        ``mode_indices`` (0-based positions of the chosen modes among the candidates, lowest
        mode 0, ascending), ``mode_frequencies_hz``, ``approximate_hsv`` (sigma of *all*
        candidates sorted descending, for a decay plot as the paper's Fig. 11),
        ``approximate_hsv_modes`` (the candidate index of each of those values),
        ``damping_source``, ``negligible_modes_chosen``, ``repeated_eigenvalue_clusters`` and
        ``highest_candidate_chosen`` (True: more candidates might change the choice).

    Raises
    ------
    OptionError
        A bad ``order``, ``candidates`` or ``shift_hz``, checked by
        :class:`~pymorembs.methods.ModalOptions` (``select = "best"``) with its message.
    UserError
        What only the system can tell (:func:`ranked_modes`).
    """
    options = ModalOptions(order=order, select="best", candidates=candidates, shift_hz=shift_hz)
    return ranked_modes(system, options.order, options.candidates, damping_ratio, options.shift_hz)


def ranked_modes(
    system: SecondOrderSystem,
    order: int,
    candidates: int | None,
    damping_ratio: float | None,
    shift_hz: float,
) -> Projection:
    """The projection of :func:`best_modes` from checked values.

    ``order >= 1``, ``candidates`` (None or above ``order``) and ``shift_hz`` (Hz) are those of
    a :class:`~pymorembs.methods.ModalOptions`, checked there; only what depends on the system
    is checked here.

    Raises
    ------
    UserError
        An order or a number of candidates not below the independent dofs, or a system without
        inputs or outputs.
    """
    n = system.order
    if order >= n:
        raise UserError(
            f"best modes: {order} modes requested but the model has only {n} independent dofs"
        )
    if system.n_inputs == 0 or system.n_outputs == 0:
        raise UserError("best modes: the system needs inputs and outputs to rank its modes")
    count = default_candidates(order, n) if candidates is None else candidates
    if count >= n:
        raise UserError(
            f"best modes: candidates must lie between the order {order} and {n - 1}, got {count}"
        )
    values, modes = eigenmodes(system, count, shift_hz, elastic_only=True)
    b, c = system.input_matrix, system.output_matrix
    modes, clusters = rotate_clusters(values, modes, b, c)
    ratios, source = modal_damping_ratios(system, values, modes, damping_ratio)
    sigma = approximate_hsv(values, modes, b, c, ratios)
    numerator = np.linalg.norm(c @ modes, axis=0) * np.linalg.norm(modes.T @ b, axis=1)
    negligible = numerator <= NEGLIGIBLE * numerator.max(initial=0.0)
    ranking = np.argsort(-np.where(negligible, 0.0, sigma), kind="stable")  # ties: lower mode
    chosen = np.sort(ranking[:order])
    descending = np.argsort(-sigma, kind="stable")
    frequencies = np.sqrt(np.clip(values, 0.0, None)) / (2.0 * np.pi)
    v = modes[:, chosen]
    return Projection(
        V=v,
        W=v,
        method="best-modes",
        parameters={
            "order": order,
            "candidates": count,
            "shift_hz": float(shift_hz),
            "damping_source": source,
            "mode_indices": chosen.tolist(),
            "mode_frequencies_hz": frequencies[chosen].tolist(),
            "approximate_hsv": sigma[descending].tolist(),
            "approximate_hsv_modes": descending.tolist(),
            "negligible_modes_chosen": int(np.count_nonzero(negligible[chosen])),
            "repeated_eigenvalue_clusters": clusters,
            "highest_candidate_hz": float(frequencies[-1]),
            "highest_candidate_chosen": bool(chosen[-1] == count - 1 and count < n - 1),
        },
    )


# --------------------------------------------------------------------------------------------
# eigenmodes plus frequency response modes
# --------------------------------------------------------------------------------------------


def frequency_response_modes(system: SecondOrderSystem, frequency_hz: float) -> np.ndarray:
    """``Phi_frm = (K - omega^2 M)^{-1} B`` at ``omega = 2 pi f`` (section 3.3), shape (n, p).

    At 0 Hz these are the static attachment modes ``K^{-1} B``; for a free body (``rigid_modes``
    set) the inertia relief attachment modes ``K^+ B``. Viscous damping and the loss factor are
    not part of the modes (they are real).
    """
    omega = 2.0 * np.pi * float(frequency_hz)
    label = f"K - omega^2 M at {frequency_hz:g} Hz (frequency response modes)"
    if omega == 0.0 and system.rigid_modes is not None:
        solver = InertiaRelief(system.stiffness, system.mass, system.rigid_modes, label)
    else:
        solver = Factorization([(1.0, system.stiffness), (-(omega**2), system.mass)], label=label)
    return solver.solve(system.input_matrix)


def modes_with_frm(
    system: SecondOrderSystem,
    order: int,
    frm_hz: float | Sequence[float],
    modes: str = "best",
    tol: float = 1e-10,
    *,
    candidates: int | None = None,
    damping_ratio: float | None = None,
    shift_hz: float = DEFAULT_SHIFT_HZ,
) -> Projection:
    """Eigenmodes plus frequency response modes (paper section 3.3 and section 5).

    ``V = orth[Phi, Phi_frm(f_1), Phi_frm(f_2), ...]`` with ``Phi`` the ``order`` best (eq. 26,
    :func:`best_modes`) or lowest eigenmodes and ``Phi_frm(f) = (K - (2 pi f)^2 M)^{-1} B``
    (:func:`frequency_response_modes`). The combined space need not have full rank (the paper's
    "one problem"): the blocks are orthonormalised one after the other with reorthogonalisation
    and rank-revealing deflation (:class:`~pymorembs.linalg.orthogonalization.OrthonormalBasis`),
    so a frequency response mode that lies in the span of the modes and the earlier blocks
    within ``tol`` (after scaling to unit length) is dropped, not kept as a near-dependent
    column. With a frequency response mode at 0 Hz the static response is exact,
    ``H_bar(0) = H(0)``.

    Parameters
    ----------
    system : SecondOrderSystem
        Sparse full system.
    order : int
        Number of eigenmodes.
    frm_hz : float or sequence of float
        Frequencies (Hz, >= 0) of the frequency response modes; must not be eigenfrequencies.
    modes : {"best", "lowest"}
        Which eigenmodes.
    tol : float
        Deflation tolerance.
    candidates, damping_ratio, shift_hz
        Passed to :func:`best_modes` (``shift_hz`` also for ``"lowest"``).

    Returns
    -------
    Projection
        ``V`` with orthonormal columns (Euclidean), ``order + sum(frm_directions)`` of them.
        ``parameters``: those of the eigenmodes, and ``frm_hz``, ``frm_directions`` (directions
        each frequency added), ``frm_deflated`` (inputs whose modes were dropped there).

    Raises
    ------
    OptionError
        A bad ``order``, ``candidates``, ``shift_hz`` or frequency, checked by
        :class:`~pymorembs.methods.ModalOptions` with its message (``modes``, its ``select``,
        with this function's).
    UserError
        No frequency, or what only the system can tell (:func:`modes_and_responses`).
    """
    if np.ndim(frm_hz) > 0 and np.size(frm_hz) == 0:
        raise UserError("modes with FRM: at least one frequency response mode frequency is needed")
    try:
        options = ModalOptions(order=order, select=modes, candidates=candidates, frm_hz=frm_hz,
                               shift_hz=shift_hz)  # fmt: skip
    except OptionError as error:
        if error.key != "select":
            raise
        # the argument is called `modes` here: the options' check, said in its name
        raise UserError(
            f"modes with FRM: modes must be 'best' or 'lowest', got {modes!r}"
        ) from None
    return modes_and_responses(system, options, tol, damping_ratio)


def modes_and_responses(
    system: SecondOrderSystem,
    options: ModalOptions,
    tol: float = 1e-10,
    damping_ratio: float | None = None,
) -> Projection:
    """The projection of :func:`modes_with_frm` on checked ``modal`` options with ``frm_hz``
    (``order``, ``select``, ``candidates``, ``shift_hz``); only what depends on the system is
    checked here."""
    order, modes, shift_hz, points = (options.order, options.select, options.shift_hz,
                                      list(options.frm_hz))  # fmt: skip
    if modes == "best":
        eigen = ranked_modes(system, order, options.candidates, damping_ratio, shift_hz)
    else:
        values, vectors = eigenmodes(system, order, shift_hz, elastic_only=True)
        frequencies = np.sqrt(np.clip(values, 0.0, None)) / (2.0 * np.pi)
        eigen = Projection(
            V=vectors,
            W=vectors,
            method="modal",
            parameters={
                "order": order,
                "shift_hz": float(shift_hz),
                "mode_indices": list(range(order)),
                "mode_frequencies_hz": frequencies.tolist(),
            },
        )
    if system.n_inputs == 0:
        raise UserError("modes with FRM: the system has no inputs")

    basis = OrthonormalBasis(system.order, tol)
    basis.add(eigen.V)
    if basis.size != eigen.order:
        raise NumericalError(
            f"modes with FRM: the {eigen.order} eigenmodes span only {basis.size} directions "
            f"at tolerance {tol:g}"
        )
    added, deflated = [], []
    for f in points:
        new = basis.add(frequency_response_modes(system, f))
        added.append(int(new.shape[1]))
        deflated.append(system.n_inputs - int(new.shape[1]))
    v = basis.matrix
    parameters = dict(eigen.parameters)
    parameters.update(
        {
            "modes": modes,
            "eigenmodes": eigen.order,
            "order": int(v.shape[1]),
            "frm_hz": points,
            "frm_directions": added,
            "frm_deflated": deflated,
            "tol": float(tol),
        }
    )
    return Projection(V=v, W=v, method=f"{modes}-modes+frm", parameters=parameters)


# --------------------------------------------------------------------------------------------
# Craig-Bampton
# --------------------------------------------------------------------------------------------


def boundary_dofs_of_inputs(system: SecondOrderSystem) -> np.ndarray:
    """Indices of the independent dofs the inputs act on: the nonzero rows of ``B``.

    ``np.flatnonzero(np.any(system.input_matrix != 0, axis=1))``, ascending -- the interface
    of :func:`craig_bampton` when the ports are the attachment points. An input on a dependent
    dof (a constraint equation) acts on every independent dof of its equation, so all of them
    are returned. Not for free bodies in the Buckens frame: their inputs act through the
    self-equilibrated part ``B - M R R^T B`` on every dof with mass; pass the interface dofs
    there explicitly.
    """
    if system.rigid_modes is not None:
        raise UserError(
            "craig-bampton: the inputs of a free body (Buckens frame) act on every dof through "
            "inertia relief; give the boundary dofs explicitly"
        )
    return np.flatnonzero(np.any(system.input_matrix != 0, axis=1))


def craig_bampton(
    system: SecondOrderSystem,
    boundary_dofs: Sequence[int] | np.ndarray,
    n_fixed_modes: int,
    shift_hz: float = DEFAULT_SHIFT_HZ,
    tol: float = 1e-10,
    static_loads: np.ndarray | None = None,
) -> Projection:
    """Craig-Bampton reduction: constraint modes plus fixed-interface normal modes.

    With the dofs split into boundary ``b`` (the interface) and interior ``i``,

        V = [[I,      0    ],
             [Psi_i,  Phi_i]],    Psi_i = -K_ii^{-1} K_ib,    K_ii Phi_i = M_ii Phi_i Lambda,

    rows ordered as ``(b, i)`` here for display only (``V`` has the rows of the system's dofs).
    Column ``j`` of the constraint modes ``Psi`` is the static deflection for a unit
    displacement of boundary dof ``j`` with the other boundary dofs held and the interior free
    of load; ``Phi_i`` are the ``n_fixed_modes`` lowest mass-normalised modes of the interior
    with the whole boundary held. Since the static response to any load on the boundary dofs
    lies in ``span(Psi)``, it is reproduced exactly; with all interior modes ``V`` spans
    everything. Being a Rayleigh-Ritz method, the reduced eigenvalues approach the exact ones
    from above as ``n_fixed_modes`` grows. The paper (section 1 and 3.3) names the component
    mode method of [7] as the substructuring state of the art that frequency response modes
    generalise.

    ``K_ii`` is factorized once (sparse LU with refined solves); the interior modes come from a
    shift-invert Lanczos run on ``(K_ii, M_ii)`` (dense for (nearly) all interior modes).

    Parameters
    ----------
    system : SecondOrderSystem
        Sparse full system.
    boundary_dofs : sequence of int
        Indices of the interface dofs among the system's independent dofs (0-based, distinct).
        For ports at the interface: :func:`boundary_dofs_of_inputs`; from nodes, look the dofs
        up in the elimination of the prepared model. They must hold the body (``K_ii``
        nonsingular): a free body needs at least a statically determinate support among them.
    n_fixed_modes : int
        Number of fixed-interface normal modes (0: Guyan / static condensation).
    shift_hz : float
        Shift of the interior eigensolver.
    tol : float
        Deflation tolerance for free bodies and of the static load modes (below).
    static_loads : ndarray, shape (n, k), optional
        Loads on the interior (e.g. the inertia loads of the frame motion) whose static
        responses with the boundary held, ``K_ii^{-1} f_i``, are added after the interior modes,
        made mass-orthogonal to them and normalised; a response already spanned (below ``tol``
        relative) is left out. The static response to such a load is then reproduced exactly.

    Returns
    -------
    Projection
        ``V = [Psi, Phi_i, X]`` (columns in the order of ``boundary_dofs``, then the interior
        modes ascending, then the static load modes), unnormalised: the first
        ``len(boundary_dofs)`` reduced coordinates are the boundary displacements. For a free
        body (``system.rigid_modes`` set) the rigid-body part is removed (``V - R R^T M V``)
        and the ``r`` directions that were rigid motions are deflated: ``V`` is then an
        orthonormal basis of the elastic part, of size ``n_b + n_fixed_modes + n_load - r``.
        ``parameters``: ``boundary_dofs``,
        ``constraint_modes``, ``fixed_modes``, ``static_load_modes``,
        ``fixed_interface_frequencies_hz``.

    Raises
    ------
    OptionError
        A bad ``n_fixed_modes`` (its ``fixed_modes``) or ``shift_hz``, checked by
        :class:`~pymorembs.methods.CraigBamptonOptions` with its message.
    UserError
        Bad boundary dofs, or what only the system can tell (:func:`fixed_interface_basis`).
    """
    options = CraigBamptonOptions(fixed_modes=n_fixed_modes, shift_hz=shift_hz)
    return fixed_interface_basis(system, boundary_dofs, options.fixed_modes, options.shift_hz,
                                 tol, static_loads)  # fmt: skip


def fixed_interface_basis(
    system: SecondOrderSystem,
    boundary_dofs: Sequence[int] | np.ndarray,
    n_fixed_modes: int,
    shift_hz: float,
    tol: float = 1e-10,
    static_loads: np.ndarray | None = None,
) -> Projection:
    """The projection of :func:`craig_bampton` from checked ``fixed_modes >= 0`` and shift (Hz)
    of a :class:`~pymorembs.methods.CraigBamptonOptions`; the boundary dofs and what depends on
    the system (the modes the interior has, the support of a free body) are checked here."""
    n = system.order
    boundary = np.asarray(boundary_dofs).ravel()
    if boundary.size == 0:
        raise UserError("craig-bampton: at least one boundary dof is needed")
    if not np.issubdtype(boundary.dtype, np.integer):
        raise UserError("craig-bampton: boundary dofs must be integer indices")
    if boundary.min() < 0 or boundary.max() >= n:
        raise UserError(f"craig-bampton: boundary dofs must lie in [0, {n}), got {boundary}")
    if np.unique(boundary).size != boundary.size:
        raise UserError("craig-bampton: boundary dofs repeat")
    interior = np.setdiff1d(np.arange(n), boundary)
    n_i = interior.size
    k = n_fixed_modes
    if k > n_i:
        raise UserError(
            f"craig-bampton: the number of fixed-interface modes must lie in [0, {n_i}] "
            f"(interior dofs), got {k}"
        )
    rigid = system.rigid_modes
    if rigid is not None and np.linalg.matrix_rank(rigid[boundary]) < rigid.shape[1]:
        raise UserError(
            "craig-bampton: the boundary dofs do not hold the free body (they leave a "
            "rigid-body motion free); choose boundary dofs that support it"
        )

    stiffness = sp.csr_matrix(system.stiffness)
    mass = sp.csr_matrix(system.mass)
    k_ii = stiffness[interior][:, interior].tocsc()
    k_ib = stiffness[interior][:, boundary]
    m_ii = mass[interior][:, interior].tocsr()

    v = np.zeros((n, boundary.size + k))
    v[boundary, np.arange(boundary.size)] = 1.0
    frequencies = np.zeros(0)
    if n_i > 0:
        try:
            factorization = Factorization(k_ii, label="K_ii (interior, boundary held)")
            v[interior, : boundary.size] = factorization.solve(-k_ib.toarray())
        except NumericalError as exc:
            raise UserError(
                f"craig-bampton: the boundary dofs do not hold the body ({exc})"
            ) from None
        if k > 0:
            values, phi = _interior_modes(k_ii, m_ii, k, shift_hz)
            v[interior, boundary.size :] = phi
            frequencies = np.sqrt(np.clip(values, 0.0, None)) / (2.0 * np.pi)
        if static_loads is not None and static_loads.shape[1]:
            phi = v[interior, boundary.size :]
            extra = _static_load_modes(factorization, m_ii, phi, interior, n, static_loads, tol)
            v = np.hstack([v, extra])
    load_modes = v.shape[1] - boundary.size - k

    removed = 0
    if rigid is not None:
        for _ in range(2):
            v = v - rigid @ (rigid.T @ np.asarray(system.mass @ v))
        basis = OrthonormalBasis(n, tol)
        basis.add(v)
        removed = v.shape[1] - basis.size
        v = basis.matrix
    return Projection(
        V=v,
        W=v,
        method="craig-bampton",
        parameters={
            "order": int(v.shape[1]),
            "boundary_dofs": boundary.tolist(),
            "constraint_modes": int(boundary.size),
            "fixed_modes": k,
            "static_load_modes": int(load_modes),
            "fixed_interface_frequencies_hz": frequencies.tolist(),
            "shift_hz": float(shift_hz),
            "rigid_directions_removed": int(removed),
        },
    )


def _static_load_modes(
    factorization: Factorization,
    m_ii: sp.spmatrix,
    phi: np.ndarray,
    interior: np.ndarray,
    n: int,
    loads: np.ndarray,
    tol: float,
) -> np.ndarray:
    """Static responses ``K_ii^{-1} f_i`` (boundary held) as columns of all ``n`` dofs.

    Made mass-orthogonal to the mass-normalised interior modes ``phi`` (n_i, k) and orthonormal
    to each other; the ones already spanned (below ``tol`` relative) are left out. Their boundary
    rows are zero, so the boundary coordinates of the Craig-Bampton basis keep their meaning.
    """
    x = factorization.solve(np.asarray(loads, dtype=float)[interior])
    for _ in range(2):
        x = x - phi @ (phi.T @ (m_ii @ x))
    basis = OrthonormalBasis(interior.size, tol)
    basis.add(x)
    modes = np.zeros((n, basis.size))
    modes[interior] = basis.matrix
    return modes


def _interior_modes(
    k_ii: sp.spmatrix, m_ii: sp.spmatrix, count: int, shift_hz: float
) -> tuple[np.ndarray, np.ndarray]:
    """The ``count`` lowest mass-normalised eigenpairs of the interior ``(K_ii, M_ii)``."""
    n_i = k_ii.shape[0]
    if count < n_i - 1:
        interior = SecondOrderSystem(
            mass=m_ii,
            stiffness=k_ii,
            damping=None,
            input_matrix=np.zeros((n_i, 0)),
            output_matrix=np.zeros((0, n_i)),
        )
        return eigenmodes(interior, count, shift_hz)
    if n_i > DENSE_INTERIOR_LIMIT:
        raise UserError(
            f"craig-bampton: {count} of {n_i} interior modes asked for; at most {n_i - 2} for an "
            f"interior of more than {DENSE_INTERIOR_LIMIT} dofs"
        )
    values, vectors = condensed_dense_eigh(k_ii.toarray(), m_ii.toarray())
    if values.size < count:
        raise UserError(
            f"craig-bampton: {count} fixed-interface modes asked for, but the interior has only "
            f"{values.size} modes with mass ({n_i - values.size} massless directions)"
        )
    return values[:count], vectors[:, :count]


def modal_from_options(
    system: SecondOrderSystem, options: ModalOptions, band_hz: tuple[float, float] | None = None
) -> Projection:
    """The ``modal`` method on its checked options: the lowest modes
    (:func:`~pymorembs.reduction.modal.lowest_modes`), the best ones (:func:`ranked_modes`), or
    either with frequency-response modes (:func:`modes_and_responses`); ``band_hz`` unused."""
    if options.frm_hz:
        return modes_and_responses(system, options)
    if options.select == "best":
        return ranked_modes(system, options.order, options.candidates, None, options.shift_hz)
    return lowest_modes(system, options.order, options.shift_hz)


def craig_bampton_from_options(
    system: SecondOrderSystem,
    options: CraigBamptonOptions,
    band_hz: tuple[float, float] | None = None,
) -> Projection:
    """The ``craig-bampton`` method on its checked options: the boundary is the dofs of the port
    inputs; the inertia loads among the inputs add their static responses with the boundary
    held (``band_hz`` unused)."""
    inertia = np.array([is_inertia_label(label) for label in system.input_labels], dtype=bool)
    ports = dataclasses.replace(system, input_matrix=system.input_matrix[:, ~inertia])
    return fixed_interface_basis(
        system,
        boundary_dofs_of_inputs(ports),
        options.fixed_modes,
        shift_hz=options.shift_hz,
        static_loads=system.input_matrix[:, inertia] if inertia.any() else None,
    )
