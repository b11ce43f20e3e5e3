"""The eigenfrequencies of a prepared model, with its rigid-body modes counted right.

What ``pymorembs info`` reports, as a library function (:func:`model_spectrum`):

* **Massless directions** are condensed exactly (:mod:`pymorembs.linalg.mass_split`): only the
  ``rank(M)`` finite eigenvalues exist.
* **Rigid-body modes** are decided twice, and the answers are compared:

  - *by the spectrum*: the lowest eigenpairs of ``(K, M)`` are computed without any assumption;
    a mode counts as a zero-energy mode when its eigenvalue lies within the bound that the
    rounding of the exported entries puts on it (:func:`~pymorembs.linalg.rounding.
    eigenvalue_bounds`; at least the rounding of the computation itself). An exact model gives
    rigid-body eigenvalues near 1e-10 of that bound's scale; a 10-digit punch of a free
    aircraft gives them at up to 1 Hz, some negative, while its first wing mode at 7.8 Hz is 25
    times beyond its bound -- a plain gap criterion cannot tell them apart, the bound can;
  - *by geometry*, where the nodes have coordinates: the six rigid-body fields, restricted to
    the motions the fixed dofs and constraints admit, are unresisted when their Rayleigh
    quotients lie within the same bound.

  With coordinates, geometry decides (its fields are exact) and the spectrum cross-checks;
  without, the spectrum decides. Zero-energy modes beyond six are mechanisms. The explanation
  says which way it went and with which numbers.
* **Elastic modes** of a body with rigid-body modes are computed in the mass-orthogonal
  complement of those modes (inertia relief), never by a shift next to the null space: that
  keeps rounded rigid-body modes from mixing into the elastic ones.
* **Rounding bounds**: per elastic frequency, how far it may move by the rounding of the file's
  entries (first order), so published frequencies can be compared within a justified tolerance.
* **Craig-Bampton superelements** (nodal plus scalar coordinates): the fixed-interface
  frequencies of the modal coordinates as well.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp

from pymorembs.body import ElasticBody
from pymorembs.errors import UserError
from pymorembs.linalg.factorization import Factorization
from pymorembs.linalg.mass_split import MassSplit, dense_condensation, mass_split
from pymorembs.linalg.rounding import eigenvalue_bounds, relative_rounding
from pymorembs.preparation import PreparedModel, with_rigid_modes
from pymorembs.preparation.rigid_modes import NAMES, admissible_rigid_fields
from pymorembs.reduction.modal import eigenmodes, shifted_factorization

#: Up to this many independent dofs the eigenproblem is solved densely (all eigenpairs).
DENSE_LIMIT = 600
#: At most six rigid-body modes; further zero-energy modes are mechanisms.
RIGID_MAX = 6
#: Eigenpairs the probe computes to count zero-energy modes (more while all are zero-energy).
PROBE_EXTRA = RIGID_MAX + 2
#: A ratio of consecutive eigenvalues from which the lower ones count as zero-energy modes
#: (a frequency ratio of 1000).
GAP = 1e6
#: The fixed-interface modes of a superelement are computed up to this many scalar coordinates.
FIXED_INTERFACE_LIMIT = 2000


@dataclass(frozen=True, eq=False)
class RigidBodyModes:
    """The rigid-body (zero-energy) modes of a prepared model and how they were found.

    Attributes
    ----------
    count : int
        Rigid-body modes (at most six).
    mechanisms : int
        Zero-energy modes beyond the rigid-body ones (a model in pieces, a free hinge).
    motions : ndarray, shape (n_independent, count + mechanisms)
        The modes on the independent dofs, mass-orthonormal.
    labels : tuple of str
        Names of the rigid-body modes where geometry decided (their axes), else empty.
    decided_by : str
        ``"geometry"``, ``"spectrum"``, ``"frame"`` (Buckens: removed by the frame) or
        ``"none"`` (no zero-energy mode).
    explanation : str
        One sentence with the numbers of the decision.
    computed_hz : ndarray
        The frequencies the zero-energy modes have in the matrices as given (signed: a
        negative value is ``-sqrt(-lambda) / 2 pi`` of a negative eigenvalue), Hz.
    """

    count: int
    mechanisms: int
    motions: np.ndarray
    labels: tuple[str, ...]
    decided_by: str
    explanation: str
    computed_hz: np.ndarray


@dataclass(frozen=True, eq=False)
class Spectrum:
    """Eigenfrequencies of a prepared model (see the module docstring).

    Attributes
    ----------
    rigid : RigidBodyModes
    elastic_hz : ndarray, shape (k,)
        The lowest elastic eigenfrequencies, Hz.
    elastic_bound_hz : ndarray, shape (k,)
        First-order bound of their change by the rounding of the file's entries, Hz.
    rounding : str
        How the entries were stored (e.g. ``"10 significant digits"``).
    eps : float
        Relative rounding of the entries used for the bounds.
    massless : MassSplit
        The massless directions of the prepared system's mass matrix.
    fixed_interface_hz : ndarray or None
        Fixed-interface frequencies of the scalar (modal) coordinates of a superelement, Hz.
    """

    rigid: RigidBodyModes
    elastic_hz: np.ndarray
    elastic_bound_hz: np.ndarray
    rounding: str
    eps: float
    massless: MassSplit
    fixed_interface_hz: np.ndarray | None

    @property
    def frequencies_hz(self) -> np.ndarray:
        """The zero-energy modes as 0 Hz, then the elastic frequencies (Hz)."""
        zeros = np.zeros(self.rigid.count + self.rigid.mechanisms)
        return np.concatenate([zeros, self.elastic_hz])


def model_spectrum(body: ElasticBody, prepared: PreparedModel, modes: int) -> Spectrum:
    """Rigid-body modes, the ``modes`` lowest elastic eigenfrequencies and their bounds.

    Parameters
    ----------
    body : ElasticBody
        The body as read (its entries tell the rounding of the file).
    prepared : PreparedModel
        The body in its frame (``Frame("none")`` for the model as it is).
    modes : int
        Number of elastic eigenfrequencies.

    Returns
    -------
    Spectrum

    Raises
    ------
    UserError
        ``modes < 1``.
    NumericalError
        The eigensolver failed, or the mass matrix is not positive semidefinite.
    """
    if modes < 1:
        raise UserError(f"--modes must be at least 1, got {modes}")
    system = prepared.system
    split = mass_split(system.mass)
    eps, rounding = relative_rounding(body.stiffness, body.mass, body.precision)
    dense = system.order <= DENSE_LIMIT
    # one factorization of K - sigma M for the probe and the elastic modes; no other shift
    # shares its pattern here, so it takes a handle of its own, whose one-vector solves (a
    # hundred or so, ARPACK's) run on one thread
    shifted = None if dense else shifted_factorization(system, share_analysis=False)
    if system.rigid_modes is not None:  # Buckens frame: removed by the frame
        rigid = RigidBodyModes(
            count=system.rigid_modes.shape[1],
            mechanisms=0,
            motions=system.rigid_modes,
            labels=NAMES,
            decided_by="frame",
            explanation="the Buckens frame removes the six rigid-body modes",
            computed_hz=np.zeros(system.rigid_modes.shape[1]),
        )
    else:
        rigid = _rigid_body_modes(prepared, split, eps, modes, dense, shifted)
    zero = rigid.count + rigid.mechanisms
    count = min(modes, split.rank - zero - (0 if dense else 1))
    if count < 1:
        raise UserError(
            f"the model has no elastic mode with mass: {split.rank} massive directions, "
            f"{zero} of them zero-energy modes"
        )
    values, vectors = _elastic_modes(system, split, rigid.motions[:, :zero], count, dense, shifted)
    bounds = eigenvalue_bounds(system.stiffness, system.mass, values, vectors, eps)
    hz = _hz(values)
    bound_hz = np.where(values > 0, bounds / (8 * np.pi**2 * np.maximum(hz, 1e-300)), np.inf)
    return Spectrum(
        rigid=rigid,
        elastic_hz=hz,
        elastic_bound_hz=bound_hz,
        rounding=rounding,
        eps=eps,
        massless=split,
        fixed_interface_hz=_fixed_interface(prepared),
    )


def _hz(values: np.ndarray) -> np.ndarray:
    """Signed frequencies, Hz: ``sign(lambda) sqrt(|lambda|) / 2 pi``."""
    return np.sign(values) * np.sqrt(np.abs(values)) / (2 * np.pi)


def _probe(
    prepared: PreparedModel,
    split: MassSplit,
    count: int,
    dense: bool,
    eps: float,
    shifted: Factorization | None,
) -> tuple[np.ndarray, np.ndarray]:
    """The lowest eigenpairs of the prepared system, no assumption about rigid-body modes.

    Dense: all of them. Sparse: at least ``count``, more while every computed one is a
    zero-energy mode (a model with many mechanisms), up to ``rank(M) - 1``.
    """
    system = prepared.system
    if dense:
        condensation = dense_condensation(_dense(system.stiffness), _dense(system.mass), split)
        values, z = sla.eigh(condensation.stiffness, condensation.mass)
        return values, condensation.expand(z)
    while True:
        values, vectors = eigenmodes(system, count, shifted=shifted)
        zero = _zero_energy_count(system, values, vectors, eps)
        if zero < count or count >= split.rank - 1:
            return values, vectors
        count = min(2 * count, split.rank - 1)


def _zero_energy_count(system, values: np.ndarray, vectors: np.ndarray, eps: float) -> int:
    """How many of the lowest eigenvalues belong to zero-energy modes.

    The larger of two counts: the leading eigenvalues within the first-order bound of the
    rounding of the entries, and the modes below the first gap of :data:`GAP` in the
    eigenvalues (a frequency ratio of 1000, which no two consecutive elastic modes show).
    """
    bound = eigenvalue_bounds(system.stiffness, system.mass, values, vectors, eps)
    within = np.abs(values) <= bound
    by_bound = int(np.argmin(within)) if not within.all() else within.size
    magnitude = np.maximum.accumulate(np.abs(values))
    gaps = np.flatnonzero(values[1:] > GAP * np.maximum(magnitude[:-1], 1e-300))
    by_gap = int(gaps[0]) + 1 if gaps.size else 0
    return max(by_bound, by_gap)


def _rigid_body_modes(
    prepared: PreparedModel,
    split: MassSplit,
    eps: float,
    modes: int,
    dense: bool,
    shifted: Factorization | None,
) -> RigidBodyModes:
    """Count the zero-energy modes by the spectrum and, with coordinates, by geometry (the
    probe's eigen-analysis with the factorization ``shifted``, None for dense models)."""
    system = prepared.system
    stiffness, mass = system.stiffness, system.mass
    # the count needs the zero-energy modes and the next one only (the probe doubles while all
    # are zero-energy); the elastic modes come from the complement (_elastic_modes), so a probe
    # of the requested modes as well would only cost Lanczos vectors
    probe = min(split.rank - (0 if dense else 1), PROBE_EXTRA)
    values, vectors = _probe(prepared, split, probe, dense, eps, shifted)
    spectral = _zero_energy_count(system, values, vectors, eps)
    above = (
        f"{_hz(values[spectral : spectral + 1])[0]:.4g} Hz"
        if spectral < values.size
        else "beyond the computed modes"
    )
    computed = _hz(values[:spectral])
    floor = f"|f| <= {np.abs(computed).max():.3g} Hz" if spectral else ""
    body = prepared.body
    located = (
        body.has_coordinates
        and body.n_nodes > 0
        and bool(np.ptp(body.coordinates, axis=0).max(initial=0.0) > 0)
    )
    admissible = admissible_rigid_fields(body, prepared.elimination)
    fields = admissible.fields
    if not located:
        count = min(spectral, RIGID_MAX)
        if spectral:
            explanation = (
                f"by the spectrum (no node coordinates to cross-check): {spectral} computed "
                f"mode{'s' if spectral > 1 else ''} with zero energy, i.e. within the bound that "
                "the rounding of the entries puts on eigenvalues or below a gap of 1000x in "
                f"frequency ({floor}); the next mode is at {above}"
            )
        else:
            explanation = (
                "by the spectrum (no node coordinates to cross-check): no mode lies within the "
                f"rounding bound or below a gap; the lowest is at {above}"
            )
        return RigidBodyModes(
            count=count,
            mechanisms=spectral - count,
            motions=_mass_orthonormal(vectors[:, :spectral], mass),
            labels=(),
            decided_by="spectrum" if spectral else "none",
            explanation=explanation,
            computed_hz=computed,
        )
    # geometry: Rayleigh quotients of the admissible rigid-body fields
    if fields.shape[1] == 0:
        fields = np.zeros((system.order, 0))
    gram = fields.T @ (mass @ fields)
    norms = np.sqrt(np.clip(np.diag(gram), 0.0, None))
    massive = norms > 1e-12 * max(norms.max(initial=0.0), 1e-300)
    fields, gram = fields[:, massive], gram[np.ix_(massive, massive)]
    energy = fields.T @ (stiffness @ fields)
    rho, y = sla.eigh(0.5 * (energy + energy.T), 0.5 * (gram + gram.T))
    motions = fields @ y
    free = np.abs(rho) <= eigenvalue_bounds(stiffness, mass, rho, motions, eps)
    geometric = int(np.argmin(free)) if not free.all() else free.size
    motions = motions[:, :geometric]
    selection = np.zeros((massive.size, geometric))
    selection[massive] = y[:, :geometric]
    labels = tuple(admissible.labels(selection)) if geometric else ()
    mechanisms = max(spectral - geometric, 0)
    if mechanisms:  # zero-energy modes that are not rigid-body motions
        extra = vectors[:, :spectral]
        extra = extra - motions @ (motions.T @ (mass @ extra))
        q, r = np.linalg.qr(extra)
        keep = np.abs(np.diag(r)) > 1e-6 * np.abs(np.diag(r)).max(initial=0.0)
        extra = q[:, keep][:, :mechanisms]
        mechanisms = extra.shape[1]
        motions = np.column_stack([motions, extra])
    if fields.shape[1] == 0:
        explanation = "by geometry: the fixed dofs and constraints admit no rigid-body motion"
    elif geometric == 0:
        explanation = (
            "by geometry: none of the rigid-body motions the fixed dofs and constraints admit is "
            "unresisted"
        )
    else:
        explanation = (
            f"by geometry: {geometric} rigid-body field{'s carry' if geometric > 1 else ' carries'}"
            " a strain energy within the rounding of the entries"
        )
    if spectral == geometric:
        explanation += (
            f"; the spectrum agrees ({spectral} mode{'s' if spectral != 1 else ''} "
            f"{floor or 'within the bound'}, next at {above})"
        )
    elif spectral > geometric:
        explanation += (
            f"; the spectrum has {spectral} zero-energy modes ({floor}): {mechanisms} "
            f"mechanism{'s' if mechanisms != 1 else ''} besides"
        )
    else:
        explanation += (
            f"; only {spectral} computed modes lie within the rounding bound ({floor or 'none'}, "
            f"next at {above}): the geometric count is kept"
        )
    return RigidBodyModes(
        count=geometric,
        mechanisms=mechanisms,
        motions=_mass_orthonormal(motions, mass) if motions.shape[1] else motions,
        labels=labels,
        decided_by="geometry" if geometric or mechanisms else "none",
        explanation=explanation,
        computed_hz=computed,
    )


def _mass_orthonormal(motions: np.ndarray, mass: sp.spmatrix | np.ndarray) -> np.ndarray:
    gram = motions.T @ (mass @ motions)
    return motions @ np.linalg.inv(np.linalg.cholesky(0.5 * (gram + gram.T))).T


def _elastic_modes(
    system,
    split: MassSplit,
    motions: np.ndarray,
    count: int,
    dense: bool,
    shifted: Factorization | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """The ``count`` lowest eigenpairs in the mass-orthogonal complement of ``motions``
    (sparse: Lanczos with the probe's factorization ``shifted`` of ``K - sigma M``)."""
    if not dense:
        elastic = with_rigid_modes(system, motions) if motions.shape[1] else system
        return eigenmodes(elastic, count, elastic_only=motions.shape[1] > 0, shifted=shifted)
    condensation = dense_condensation(_dense(system.stiffness), _dense(system.mass), split)
    k, b = condensation.stiffness, condensation.mass
    if motions.shape[1]:
        rigid = condensation.restrict(motions)
        complement = sla.null_space((b @ rigid).T)  # z with R_z^T B z = 0
        k = complement.T @ k @ complement
        b = complement.T @ b @ complement
    else:
        complement = None
    values, z = sla.eigh(0.5 * (k + k.T), 0.5 * (b + b.T), subset_by_index=(0, count - 1))
    if complement is not None:
        z = complement @ z
    return values, condensation.expand(z)


def _fixed_interface(prepared: PreparedModel) -> np.ndarray | None:
    """Frequencies (Hz) of ``(K_qq, M_qq)`` on the scalar coordinates of a superelement."""
    body, system = prepared.body, prepared.system
    scalar = body.dofs.scalar[prepared.elimination.independent]
    q = np.flatnonzero(scalar)
    if q.size == 0 or q.size == scalar.size or q.size > FIXED_INTERFACE_LIMIT:
        return None
    k = (
        _dense(system.stiffness)[np.ix_(q, q)]
        if not sp.issparse(system.stiffness)
        else (sp.csr_matrix(system.stiffness)[q][:, q].toarray())
    )
    m = sp.csr_matrix(system.mass)[q][:, q].toarray()
    try:
        values = sla.eigh(0.5 * (k + k.T), 0.5 * (m + m.T), eigvals_only=True)
    except np.linalg.LinAlgError:
        return None
    return _hz(values)


def _dense(matrix: sp.spmatrix | np.ndarray) -> np.ndarray:
    return matrix.toarray() if sp.issparse(matrix) else np.asarray(matrix)


def model_facts(body: ElasticBody, prepared: PreparedModel, modes: int) -> dict[str, Any]:
    """Sizes, mass, massless dofs, rigid-body modes and the lowest elastic eigenfrequencies (Hz).

    What ``pymorembs info`` prints (and ``--json`` gives): a plain dictionary.

    The eigen-analysis is :func:`pymorembs.analysis.spectrum.model_spectrum`: massless
    directions condensed exactly, rigid-body modes decided by the spectrum within the rounding
    bound of the file's entries and, with coordinates, by geometry.
    """
    spectrum = model_spectrum(body, prepared, modes)
    rigid = spectrum.rigid
    frequencies = spectrum.frequencies_hz
    bounds = np.concatenate([np.zeros(rigid.count + rigid.mechanisms), spectrum.elastic_bound_hz])
    facts: dict[str, Any] = {
        "name": body.name,
        "n_dof": prepared.body.n_dof,
        "n_nodes": prepared.body.n_nodes,
        "n_dependent": int(prepared.elimination.dependent.size),
        "n_fixed": int(prepared.elimination.fixed.size),
        "n_independent": prepared.system.order,
        "n_massless": spectrum.massless.n_massless,
        "massless": {
            "directions": spectrum.massless.n_massless,
            "dofs_without_mass": int(spectrum.massless.zero_rows.size),
            "directions_in_mass_blocks": spectrum.massless.n_block_null,
        },
        "dof_table": body.dofs.describe(),
        "has_coordinates": bool(body.has_coordinates),
        "node_sets": {name: int(ids.size) for name, ids in body.node_sets.items()},
        "notes": [*body.notes, *prepared.notes],  # the reader's, then the preparation's
        "total_mass": body.total_mass(),
        "rigid_body_modes": rigid.count,
        "rigid_body_motions": list(rigid.labels),
        "mechanisms": rigid.mechanisms,
        "rigid_body_decision": {
            "decided_by": rigid.decided_by,
            "explanation": rigid.explanation,
            "computed_hz": rigid.computed_hz.tolist(),
        },
        "rounding": spectrum.rounding,
        "eigenfrequencies_hz": frequencies.tolist(),
        "eigenfrequency_bounds_hz": bounds.tolist(),
    }
    if spectrum.fixed_interface_hz is not None:
        facts["fixed_interface_hz"] = spectrum.fixed_interface_hz.tolist()
    return facts
