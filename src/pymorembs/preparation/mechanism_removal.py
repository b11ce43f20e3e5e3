"""Massless mechanisms of a body in its frame: removed with a note, or refused.

A direction of the independent dofs with neither mass nor stiffness (a dof nothing touches, or
several massless dofs that move together unresisted, such as the rotation of a pinned straight
beam about its own axis when only its translations carry mass) has no finite answer in the
static condensation of the massless dofs, and every solve with ``K - omega^2 M`` is singular on
it. :func:`remove_massless_mechanisms` finds these directions
(:func:`~pymorembs.linalg.massless_mechanisms.massless_mechanisms`, sparse, after the frame and
the constraint elimination, which may hold or create them) and

* removes those decoupled from every massive dof -- always the case for a positive
  semidefinite ``K`` -- by fixing one dof per direction, as Nastran's ``PARAM,AUTOSPC`` does.
  The body keeps them among its fixed dofs; a note names the dofs of each direction and the dof
  that was fixed. Frequencies and every response of the massive dofs stay the same;
* refuses a direction that is coupled to other dofs (:class:`~pymorembs.errors.NumericalError`,
  exit code 3: the stiffness matrix is not positive semidefinite there, the same verdict as the
  other checks of an indefinite ``K``), naming its dofs and the dof it pulls at.

:func:`mechanism_ports` then refuses an input that loads a removed direction (a load without
any stiffness against it has no static answer) and warns about an output that reads one (its
part along that motion is undetermined; fixing makes it 0 at the fixed dof).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
import scipy.sparse as sp

from pymorembs.body import DIRECTIONS, ElasticBody
from pymorembs.errors import NumericalError, UserError
from pymorembs.linalg.mass_split import mass_split
from pymorembs.linalg.massless_mechanisms import MasslessMechanisms, massless_mechanisms
from pymorembs.linalg.rounding import relative_rounding
from pymorembs.preparation.elimination import Elimination

#: A port acts on (reads) a removed direction from this share of its norm on.
PORT_SHARE = 1e-6
#: Nodes named in a note or message before ``...``.
SHOWN_NODES = 6
AUTOSPC = "like Nastran's AUTOSPC"


@dataclass(frozen=True, eq=False)
class MechanismRemoval:
    """The massless mechanisms removed from a body in its frame.

    Attributes
    ----------
    directions : sparse matrix, shape (n_dof, k)
        The removed directions over all dofs of the body (dependent dofs through the constraint
        equations).
    fixed : ndarray of int, shape (k,)
        The equations fixed to remove them.
    kept : ndarray of int, shape (n_i - k,)
        Positions, among the independent dofs before the removal, of those that stay.
    descriptions : tuple of str
        Per direction, its dofs (``node 7 rz``, ``nodes 1, 2, ... (11 nodes) rx ry rz``).
    held : tuple of str
        Per direction, the dof fixed to remove it (``node 1 rz``).
    notes : tuple of str
        One line per connected part (all single dofs in one line), for ``info`` and the job's
        summary.
    """

    directions: sp.csc_matrix
    fixed: np.ndarray
    kept: np.ndarray
    descriptions: tuple[str, ...]
    held: tuple[str, ...]
    notes: tuple[str, ...]

    @property
    def count(self) -> int:
        """Number of removed directions."""
        return int(self.fixed.size)

    def restrict(self, matrix: sp.spmatrix) -> sp.csr_matrix:
        """A matrix of the independent dofs before the removal, on those that stay (the matrix
        itself when nothing was removed: no copy)."""
        if self.count == 0:
            return matrix if isinstance(matrix, sp.csr_matrix) else sp.csr_matrix(matrix)
        return sp.csr_matrix(sp.csr_matrix(matrix)[self.kept][:, self.kept])


def remove_massless_mechanisms(
    body: ElasticBody,
    elimination: Elimination,
    mass: sp.csr_matrix,
    stiffness: sp.csr_matrix,
) -> tuple[ElasticBody, Elimination, MechanismRemoval]:
    """Fix one dof per decoupled direction without mass and stiffness; refuse coupled ones.

    Parameters
    ----------
    body : ElasticBody
        The body in its frame.
    elimination : Elimination
        Its elimination (:func:`~pymorembs.preparation.elimination.eliminate`).
    mass, stiffness : sparse matrix, shape (n_i, n_i)
        ``T^T M T`` and ``T^T K T`` of its independent dofs.

    Returns
    -------
    body, elimination
        Unchanged when there is nothing to remove, else with the further fixed dofs (the
        elimination without their columns of ``T``: :meth:`MechanismRemoval.restrict` gives
        the matrices of the remaining independent dofs).
    removal : MechanismRemoval

    Raises
    ------
    NumericalError
        A direction without mass and without stiffness of its own is coupled to other dofs
        (``K`` is indefinite there).
    """
    n_i = elimination.n_independent
    nothing = MechanismRemoval(
        sp.csc_matrix((body.n_dof, 0)), np.zeros(0, dtype=np.int64), np.arange(n_i), (), (), ()
    )
    try:
        split = mass_split(mass)
    except NumericalError:  # an indefinite mass: the validation names it
        return body, elimination, nothing
    if not split.singular:
        return body, elimination, nothing
    eps, _ = relative_rounding(body.stiffness, body.mass, body.precision)
    found = massless_mechanisms(stiffness, split, eps)
    if found.count == 0:
        return body, elimination, nothing
    independent = elimination.independent
    pointer, rows = found.vectors.indptr, found.vectors.indices
    descriptions = tuple(
        _dofs(body, independent[rows[pointer[j] : pointer[j + 1]]]) for j in range(found.count)
    )
    coupled = np.flatnonzero(found.coupled)
    if coupled.size:
        j = int(coupled[np.argmax(found.residual[coupled])])
        target = int(found.largest[j])
        pulled = f" is coupled to {_dofs(body, independent[[target]])}" if target >= 0 else ""
        raise NumericalError(
            f"[model]: the stiffness matrix is not positive semidefinite: a massless direction "
            f"without stiffness of its own ({descriptions[j]}){pulled} (residual "
            f"{found.residual[j]:.1e} of the stiffness scale, rounding would be below "
            f"{found.tolerance:.0e}); check the exported stiffness matrix"
        )
    fixed = independent[found.pivots]
    kept = np.setdiff1d(np.arange(n_i), found.pivots)
    removal = MechanismRemoval(
        directions=sp.csc_matrix(elimination.transform @ found.vectors),
        fixed=fixed,
        kept=kept,
        descriptions=descriptions,
        held=tuple(_dofs(body, [dof]) for dof in fixed),
        notes=_notes(body, found, descriptions, fixed),
    )
    body = replace(body, fixed=np.union1d(body.fixed, fixed))
    # fixing independent dofs drops their columns of T; dependent rows and offsets stay
    held = Elimination(
        independent=independent[kept],
        dependent=elimination.dependent,
        fixed=np.union1d(elimination.fixed, fixed),
        transform=sp.csr_matrix(elimination.transform[:, kept]),
        offset=elimination.offset,
    )
    return body, held, removal


def mechanism_ports(
    removal: MechanismRemoval,
    inputs: sp.spmatrix | np.ndarray | None,
    input_labels: list[str],
    outputs: sp.spmatrix | np.ndarray | None,
    output_labels: list[str],
    where: str = "",
) -> dict[str, str]:
    """Refuse inputs on removed directions; warnings for outputs that read them.

    Parameters
    ----------
    removal : MechanismRemoval
    inputs, outputs : sparse matrix or ndarray, shape (n_dof, p) and (n_dof, r), optional
        ``B`` and ``C^T`` over all dofs of the body.
    input_labels, output_labels : list of str
    where : str
        Prefix of the message (the job table of the ports).

    Returns
    -------
    dict of str to str
        Per output that reads a removed direction, its label and the warning.

    Raises
    ------
    UserError
        An input loads a removed direction.
    """
    if removal.count == 0:
        return {}
    warnings = {}
    for what, matrix, labels in (
        ("input", inputs, input_labels),
        ("output", outputs, output_labels),
    ):
        if matrix is None or not labels:
            continue
        matrix = sp.csc_matrix(matrix)
        total = np.sqrt(np.asarray(matrix.multiply(matrix).sum(axis=0)).ravel())
        along = np.abs((removal.directions.T @ matrix).toarray())  # (k, p), unit directions
        share = along / np.where(total > 0, total, 1.0)
        for column in np.flatnonzero(share.max(axis=0, initial=0.0) >= PORT_SHARE):
            j = int(np.argmax(share[:, column]))
            direction = removal.descriptions[j]
            if what == "input":
                raise UserError(
                    f"{where}input {labels[column]} loads a direction without mass and "
                    f"stiffness ({direction}): the load has no static answer; remove the input "
                    "or connect that dof"
                )
            warnings[labels[column]] = (
                f"output {labels[column]} reads a direction without mass and stiffness "
                f"({direction}), removed by fixing {removal.held[j]}: its part along that "
                "motion is undetermined and taken as 0 there"
            )
    return warnings


def _notes(
    body: ElasticBody, found: MasslessMechanisms, descriptions: tuple[str, ...], fixed: np.ndarray
) -> tuple[str, ...]:
    """One note for all single dofs, one per connected part of several dofs."""
    notes = []
    single = np.flatnonzero(found.single)
    if single.size:
        count = f" ({single.size} dofs, removed {AUTOSPC})" if single.size > 1 else ""
        notes.append(
            f"{_dofs(body, fixed[single])}: no mass and no stiffness"
            + (count or f" (removed {AUTOSPC})")
        )
    for part in np.unique(found.group[~found.single]).tolist():
        members = np.flatnonzero((found.group == part) & ~found.single)
        several = members.size > 1
        rows = np.unique(found.vectors[:, members].indices)
        worst = float(found.residual[members].max())
        notes.append(
            f"{f'{members.size} massless mechanisms' if several else 'a massless mechanism'} "
            f"of {rows.size} dofs ({descriptions[members[0]]}) with no mass and no stiffness, "
            f"decoupled from every massive dof (residual {worst:.1e}): removed by fixing "
            f"{_dofs(body, fixed[members])} ({AUTOSPC})"
        )
    return tuple(notes)


def _dofs(body: ElasticBody, equations: np.ndarray) -> str:
    """Dofs by node, nodes with the same directions together: ``node 7 rz``,
    ``nodes 1, 2, 3 rx ry rz``, ``nodes 1, 2, ... (11 nodes) rx ry rz; node 12 rz``."""
    equations = np.unique(np.asarray(equations, dtype=np.int64))
    nodes = body.dofs.nodes[equations]
    directions = body.dofs.directions[equations]
    by_node: dict[int, list[int]] = {}
    for node, direction in zip(nodes.tolist(), directions.tolist(), strict=True):
        by_node.setdefault(node, []).append(direction)
    by_set: dict[tuple[int, ...], list[int]] = {}
    for node, codes in sorted(by_node.items()):
        by_set.setdefault(tuple(sorted(codes)), []).append(node)
    parts = []
    for codes, members in by_set.items():
        names = " ".join(DIRECTIONS[c] for c in codes)
        shown = ", ".join(str(n) for n in members[:SHOWN_NODES])
        if len(members) > SHOWN_NODES:
            shown += f", ... ({len(members)} nodes)"
        parts.append(f"node{'s' if len(members) > 1 else ''} {shown} {names}")
    return "; ".join(parts)
