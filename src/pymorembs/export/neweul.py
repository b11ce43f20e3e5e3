"""The reduced body as a MATLAB ``.mat`` file of SID invariants, for Neweul-M².

Neweul-M² (MATLAB) reads elastic bodies as Standard Input Data; its own import format was not
available to us, so this file holds the SID quantities of :mod:`pymorembs.export.sid` as plain
MATLAB arrays with names that follow the SID objects (``<object>0`` = ``M0``, ``<object>1`` =
``M1``) and with the mode index last where an array has one, so that ``J1(:, :, k)`` is the
derivative with respect to ``q_k``. The equations of motion they define are those of SID_NOTES
§3; the definitions are SID_NOTES §4.3-§4.4. Units are those of the FE model (SI for the built-in
examples); ``q`` in the unit of the reduced basis (mass-normalised modes: ``Me = I``).

================  ===========  ==================================================================
field             size         meaning
================  ===========  ==================================================================
format            string       ``"pymorembs-sid-invariants"``
version           1 × 1        format version (:data:`FORMAT_VERSION`)
generator         string       ``"pymorembs <version>"``
name              string       body name
nq                1 × 1        number of elastic coordinates
mass              1 × 1        body mass ``m``
mdCM0             3 × 1        first mass moment ``∫c dm = m c_G`` (SID ``mdCM`` M0)
mdCM1             3 × nq       column k: ``∂mdCM/∂q_k = ∫Φ_k dm`` (= ``Ct0'``)
cog               3 × 1        centre of gravity ``c_G`` in the body frame
J0                3 × 3        inertia tensor about the frame origin (off-diagonals ``-∫xy dm``)
J1                3 × 3 × nq   ``J1(:, :, k) = ∂J/∂q_k`` (symmetric)
Ct0               nq × 3       ``Ct``: row k = ``(∫Φ_k dm)'``
Cr0               nq × 3       ``Cr`` at q = 0: row k = ``(∫c × Φ_k dm)'`` (+ rotary inertia)
Cr1               nq × nq × 3  ``Cr1(k, l, a) = ∂Cr(k, a)/∂q_l = ∫(Φ_l × Φ_k)_a dm``
Me                nq × nq      reduced mass matrix
Gr0               3 × 3 × nq   ``Gr0(:, :, k) = Gr_k``: gyroscopic torque ``Σ_k Gr_k q̇_k ω``
Ge0               nq × nq × 3  ``Ge0(:, :, a) = 2 Cr1(:, :, a)``; force ``Σ_a Ge0(:, :, a) q̇ ω_a``
Oe0               nq × 6       centrifugal force ``Oe(q) Ω`` at q = 0
Oe1               nq × nq × 6  ``Oe1(k, l, :) = ∂Oe(k, :)/∂q_l`` (symmetric in k, l)
Omega_order       string       ``"wx^2 wy^2 wz^2 wx*wy wy*wz wx*wz"``: the components of Ω
ksigma            nq × 1       modal force of reference stresses (zero)
Ke                nq × nq      reduced stiffness matrix
De                nq × nq      reduced viscous damping matrix
frequencies_hz    nq × 1       frequency of each coordinate (Hz)
second_order_mass string       ``"exact"`` or ``"translational"`` (see :mod:`.invariants`)
geometric_stiffening 1 × 1     1 if the body carries geometric stiffening (then the fields
                               ``K0t``, ``K0r``, ``K0w`` and the nodes' ``K0f``, ``K0m``), else 0
K0t               nq × nq × 3  ``Φᵀ K_G Φ`` of the unit translational accelerations ax ay az
K0r               nq × nq × 3  ... of the unit angular accelerations alx aly alz
K0w               nq × nq × 6  ... of the centrifugal cases (order of ``Omega_order``)
nodes             1 × n struct node frames, fields below
================  ===========  ==================================================================

Fields of ``nodes(p)``:

================  ===========  ==================================================================
id                1 × 1        FE node id
origin            3 × 1        undeformed position ``c_p`` in the body frame (SID ``origin`` M0)
phi               3 × nq       translational mode rows ``φ_p`` (``origin`` M1 and SID ``phi``)
psi               3 × nq       rotational mode rows ``ψ_p`` (zero if the node has no rotations)
has_rotations     1 × 1        1 if the node has rotational dofs, else 0
AP1               3 × 3 × nq   ``AP1(:, :, k) = skew(ψ_p(:, k))``; orientation ``I + Σ_k AP1 q_k``
K0f, K0m          nq × nq × 3  with geometric stiffening: ``Φᵀ K_G Φ`` of a unit force (moment)
                               at the node along x, y, z (zero where not computed)
================  ===========  ==================================================================

With geometric stiffening the elastic equations of SID_NOTES §3 gain, on the left-hand side,
``(Σ_a a_a K0t(:,:,a) + Σ_a α_a K0r(:,:,a) + Σ_m Ω_m K0w(:,:,m)) q`` for the frame's
translational acceleration ``a``, angular acceleration ``α`` (body frame) and ``Ω``, and
``-Σ_a F_a K0f(:,:,a) q`` (``M_a``, ``K0m``) for the forces (moments) at a node: the same terms
the SID body holds in ``Ct.M1``, ``Cr.M1``, ``Oe.M1`` and ``phi``/``psi.M1`` (SID_NOTES §4.6).
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from pymorembs.elements.rigid import skew
from pymorembs.errors import NumericalError
from pymorembs.export.deterministic import write_mat
from pymorembs.export.invariants import BodyInvariants

__all__ = ["FORMAT", "FORMAT_VERSION", "neweul_fields", "write_neweul"]

#: Value of the ``format`` field.
FORMAT = "pymorembs-sid-invariants"
#: Value of the ``version`` field; raised when a field changes meaning.
FORMAT_VERSION = 1


def neweul_fields(inv: BodyInvariants) -> dict[str, object]:
    """The variables of the ``.mat`` file (see the module table), as NumPy arrays."""
    from pymorembs import __version__

    nq = inv.nq
    kr = inv.Kr  # (3, nq, nq)
    node_type = [
        ("id", object),
        ("origin", object),
        ("phi", object),
        ("psi", object),
        ("has_rotations", object),
        ("AP1", object),
        ("K0f", object),
        ("K0m", object),
    ]
    stiff = inv.stiffening
    zero = np.zeros((nq, nq))

    def stacked(cases: tuple[str, ...]) -> np.ndarray:
        found = {} if stiff is None else stiff.cases
        return np.stack([found.get(case, zero) for case in cases], axis=-1)

    def nodal(node: int, first: int) -> np.ndarray:
        found = {} if stiff is None else stiff.nodes
        return np.stack([found.get((node, first + a), zero) for a in range(3)], axis=-1)

    nodes = np.empty((1, len(inv.nodes)), dtype=node_type)
    for p, frame in enumerate(inv.nodes):
        psi = np.zeros((3, nq)) if frame.psi is None else np.asarray(frame.psi, dtype=float)
        nodes[0, p] = (
            float(frame.node_id),
            frame.position.reshape(3, 1),
            frame.phi,
            psi,
            float(frame.psi is not None),
            skew(psi.T).transpose(1, 2, 0),  # (3, 3, nq)
            nodal(int(frame.node_id), 0),
            nodal(int(frame.node_id), 3),
        )
    return {
        "format": FORMAT,
        "version": float(FORMAT_VERSION),
        "generator": f"pymorembs {__version__}",
        "name": inv.name,
        "nq": float(nq),
        "mass": float(inv.mass),
        "mdCM0": inv.first_moment.reshape(3, 1),
        "mdCM1": inv.Ct.T.copy(),
        "cog": inv.centre_of_gravity.reshape(3, 1),
        "J0": inv.inertia,
        "J1": inv.J1.transpose(1, 2, 0),
        "Ct0": inv.Ct,
        "Cr0": inv.Cr,
        "Cr1": kr.transpose(1, 2, 0),
        "Me": inv.Me,
        "Gr0": inv.Gr.transpose(1, 2, 0),
        "Ge0": 2.0 * kr.transpose(1, 2, 0),
        "Oe0": inv.Oe0,
        "Oe1": inv.Oe1,
        "Omega_order": "wx^2 wy^2 wz^2 wx*wy wy*wz wx*wz",
        "ksigma": np.zeros((nq, 1)),
        "Ke": inv.Ke,
        "De": inv.De,
        "frequencies_hz": inv.frequencies_hz.reshape(nq, 1),
        "second_order_mass": inv.second_order_mass,
        "geometric_stiffening": float(stiff is not None),
        "K0t": stacked(("ax", "ay", "az")),
        "K0r": stacked(("alx", "aly", "alz")),
        "K0w": stacked(("wxx", "wyy", "wzz", "wxy", "wyz", "wxz")),
        "nodes": nodes,
    }


def write_neweul(path: str | os.PathLike[str], inv: BodyInvariants) -> Path:
    """Write the invariants as a MATLAB ``.mat`` file (version 5, atomically).

    Parameters
    ----------
    path : path-like
        Target file (``.mat``); its directory must exist.
    inv : BodyInvariants

    Returns
    -------
    Path

    Raises
    ------
    NumericalError
        A value is not finite; nothing is written.
    """
    fields = neweul_fields(inv)
    arrays = [v for v in fields.values() if isinstance(v, np.ndarray) and v.dtype.kind == "f"]
    arrays += [np.asarray(v, dtype=float) for node in fields["nodes"][0] for v in node]
    if not all(np.all(np.isfinite(a)) for a in arrays) or not np.isfinite(inv.mass):
        raise NumericalError("Neweul export: NaN or infinite values in the invariants")
    return write_mat(path, fields, format="5", oned_as="column", do_compression=True)
