"""Mass invariants of a reduced elastic body in the floating frame of reference (SID_NOTES §4).

A reduced body is described by its FE model (node positions ``c``, mass matrix ``M`` over all dofs)
and a reduced basis ``Φ`` (n_dof × nq, no rigid-body content, SID_NOTES §4.5): the elastic
displacement is ``u = Φ q`` in the body frame. Multibody codes need integrals over the mass of
the body of products of ``c`` and ``Φ`` (the *invariants*), which :func:`compute_invariants`
computes and :class:`BodyInvariants` holds; the writers (:mod:`~pymorembs.export.sid`,
:mod:`~pymorembs.export.neweul`, the Exudyn export) only rearrange them.

First-order terms (SID_NOTES §4.2(b)), exact for every element type, with ``R = [S_t S_r]`` the
rigid-body modes of the body about its frame origin:

* ``m I = S_tᵀ M S_t``, ``m c̃ = S_rᵀ M S_t``, ``J0 = S_rᵀ M S_r`` (rotary inertia included);
* ``Ct = Φᵀ M S_t`` (= ``∫Φᵀ dm``), ``Cr = Φᵀ M S_r`` (row k = ``(∫c × Φ_k dm)ᵀ`` + rotary).

Second-order terms (SID_NOTES §4.1, §4.2(a)), from the translational mass blocks: with ``x_a``
(N) the node coordinates along axis ``a``, ``U_a = Φ[dofs of direction a]`` (N × nq) and the scalar
mass matrix ``m̄`` (N × N),

* ``S[k, a, b] = ∫ c_a Φ_{k,b} dm = x_aᵀ m̄ U_b e_k``,
* ``PP[a, b] = ∫ Φ_aᵀ Φ_b dm = U_aᵀ m̄ U_b``.

Two-node beams of the body's mesh (:class:`~pymorembs.body.ElementMesh` ``"beam2"``) enter
exactly: a section point ``x(xi) + s`` moves by ``u(xi) + theta_x(xi) e_x x s``, the fields behind
the beams' consistent mass (:func:`pymorembs.elements.beam.beam_kinematics`), integrated by Gauss
points and the section moments (:class:`_Beams`). Rigid bodies lumped at nodes (a node's 6 x 6
block of ``M`` without the beams that couples no other node, with an isotropic translational
mass: plates, point masses with rotary inertia or offset) are taken out next and enter exactly:
the mass points of such a body move as ``u_n + ψ_n × r``, and their integrals follow from the
block's mass, first moment and second moments ``∫ r rᵀ dm = tr(Θ)/2 I − Θ``
(:class:`_RigidBodies`). If the rest of ``M`` is zero or has Kronecker structure on the
translational dofs (``M[x,x] = M[y,y] = M[z,z] = m̄`` over the nodes, off-axis blocks zero, no
mass on rotational dofs -- isoparametric solids, lumped point masses), the terms are exact
(``second_order_mass = "exact"``). Otherwise (imported beams and shells with the rotary inertia
of their sections or Hermitian translation-rotation coupling, whose element fields are unknown)
``m̄`` of the rest is the mean of its three axis blocks ``M[a,a]`` and its rotational and
coupling parts are left out of the second-order terms only (``"translational"``): ``J1``,
``Gr``, ``Oe0``, ``Cr1 = Kr``, ``Ge`` and ``Oe1`` then miss those elements' own rotary-inertia
contributions (SID_NOTES §4.2(b) calls them "commonly neglected"), while ``m``, ``c``, ``J0``,
``Ct``, ``Cr``, ``Me`` remain exact.

Units: those of the FE model (SI for the built-in examples: kg, m); ``Φ`` is dimensionless if
``q`` has the length unit (mass-normalised modes: ``q`` in m·kg^½, then ``Me = I``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from pymorembs.arrays import sorted_unique
from pymorembs.body import ElasticBody
from pymorembs.display import one_line
from pymorembs.elements.beam import BeamSection
from pymorembs.elements.rigid import skew
from pymorembs.errors import UserError
from pymorembs.linalg.products import long_product

__all__ = [
    "OMEGA_ORDER",
    "BodyInvariants",
    "NodeFrame",
    "StiffeningTerms",
    "compute_invariants",
    "levi_civita",
]

#: Order of the six products of angular velocity components Ω used with ``Oe`` (SID_NOTES §0).
OMEGA_ORDER = ("wx*wx", "wy*wy", "wz*wz", "wx*wy", "wy*wz", "wx*wz")
# (row, column) pairs of a 3x3 matrix combined into the six Ω components: diagonal, then the
# symmetric sums xy, yz, xz (SID_NOTES §4.3).
_OMEGA_PAIRS = ((0, 1), (1, 2), (0, 2))

#: Relative size (to the largest translational mass entry) below which an entry of ``M`` counts
#: as zero, and two axis blocks as equal, in the Kronecker test.
KRONECKER_TOL = 1e-12


def _omega_components(matrices: np.ndarray) -> np.ndarray:
    """The six Ω coefficients ``(A_xx, A_yy, A_zz, A_xy+A_yx, A_yz+A_zy, A_xz+A_zx)``.

    ``matrices`` has shape (..., 3, 3); the result (..., 6) (SID_NOTES §4.3, Ω order of §0).
    """
    diagonal = np.diagonal(matrices, axis1=-2, axis2=-1)
    mixed = [matrices[..., a, b] + matrices[..., b, a] for a, b in _OMEGA_PAIRS]
    return np.concatenate([diagonal, np.stack(mixed, axis=-1)], axis=-1)


@dataclass(frozen=True, eq=False)
class NodeFrame:
    """An output or interface node of the reduced body (SID_NOTES §4.4).

    Attributes
    ----------
    node_id : int
        FE node id.
    position : ndarray, shape (3,)
        Undeformed position ``c_p`` in the body frame (model length unit).
    phi : ndarray, shape (3, nq)
        Translational rows of ``Φ`` at the node (ux, uy, uz; a missing dof gives a zero row).
    psi : ndarray, shape (3, nq) or None
        Rotational rows (rx, ry, rz), ``None`` if the node has no rotational dofs.
    """

    node_id: int
    position: np.ndarray
    phi: np.ndarray
    psi: np.ndarray | None


@dataclass(frozen=True, eq=False)
class StiffeningTerms:
    """Geometric stiffening of a reduced body (SID_NOTES §4.6), each matrix (nq, nq).

    Attributes
    ----------
    cases : dict of str -> ndarray
        ``K0_L = Φᵀ K_G(σ_L) Φ`` of the unit d'Alembert load cases (``ax .. wxz``).
    nodes : dict of (node id, direction code) -> ndarray
        The same for a unit force (0-2) or moment (3-5) at a frame node.
    source : str
        Where ``K_G`` came from (``"mesh"``, ``"matrices"``).
    """

    cases: dict[str, np.ndarray]
    nodes: dict[tuple[int, int], np.ndarray]
    source: str


@dataclass(frozen=True, eq=False)
class BodyInvariants:
    """Invariants of a reduced elastic body (SID_NOTES §4.1-§4.3); ``q`` has ``nq`` entries.

    Attributes
    ----------
    mass : float
        ``m = ∫dm`` (mass unit).
    first_moment : ndarray, shape (3,)
        ``∫c dm = m c_G`` (mass × length).
    inertia : ndarray, shape (3, 3)
        Inertia tensor ``J0`` about the body-frame origin (mass × length²): diagonal
        ``∫(y² + z²) dm``..., off-diagonals ``-∫xy dm``...; rotary inertia included.
    Ct : ndarray, shape (nq, 3)
        ``Φᵀ M S_t``; row k = ``(∫Φ_k dm)ᵀ``.
    Cr : ndarray, shape (nq, 3)
        ``Φᵀ M S_r``; row k = ``(∫c × Φ_k dm)ᵀ`` plus rotary inertia.
    S : ndarray, shape (nq, 3, 3)
        ``S[k, a, b] = ∫ c_a Φ_{k,b} dm`` (second-order mass model, see ``second_order_mass``).
    PP : ndarray, shape (3, 3, nq, nq)
        ``PP[a, b, k, l] = ∫ Φ_{k,a} Φ_{l,b} dm``.
    Me, Ke, De : ndarray, shape (nq, nq)
        Reduced mass, stiffness and viscous damping matrices, as given.
    frequencies_hz : ndarray, shape (nq,)
        Frequency of each coordinate (Hz), ``sqrt(Ke_kk / Me_kk) / 2π`` unless given.
    nodes : tuple of NodeFrame
        Output/interface nodes, in the order given.
    second_order_mass : {"exact", "translational"}
        Mass model of ``S`` and ``PP``: exact Kronecker solid/lumped mass, or the translational
        approximation (rotary inertia and Hermitian coupling neglected), see the module notes.
    name : str
        Body name (e.g. the SID ``new modal`` name).
    stiffening : StiffeningTerms or None
        Geometric stiffening, if the body carries it.
    """

    mass: float
    first_moment: np.ndarray
    inertia: np.ndarray
    Ct: np.ndarray
    Cr: np.ndarray
    S: np.ndarray
    PP: np.ndarray
    Me: np.ndarray
    Ke: np.ndarray
    De: np.ndarray
    frequencies_hz: np.ndarray
    nodes: tuple[NodeFrame, ...]
    second_order_mass: str
    name: str = ""
    stiffening: StiffeningTerms | None = None

    def __repr__(self) -> str:
        rows = [("mass", f"{self.mass:.6g}"), ("elastic coordinates", str(self.nq)),
                ("frame nodes", " ".join(str(node.node_id) for node in self.nodes) or "none"),
                ("second-order mass", self.second_order_mass),
                ("stiffening", "yes" if self.stiffening is not None else "no")]  # fmt: skip
        return one_line(f"BodyInvariants {self.name!r}", rows)

    # ------------------------------------------------------------------ derived (SID_NOTES §4.3)
    @property
    def nq(self) -> int:
        """Number of elastic coordinates."""
        return int(self.Me.shape[0])

    @property
    def centre_of_gravity(self) -> np.ndarray:
        """``c_G = ∫c dm / m``, shape (3,) (length)."""
        return self.first_moment / self.mass

    @property
    def C4(self) -> np.ndarray:
        """``C4_k = ∫ c̃ Φ̃_k dm = S_kᵀ - tr(S_k) I``, shape (nq, 3, 3)."""
        trace = np.trace(self.S, axis1=1, axis2=2)
        return self.S.transpose(0, 2, 1) - trace[:, None, None] * np.eye(3)

    @property
    def J1(self) -> np.ndarray:
        """``J1_k = ∂J/∂q_k = -(C4_k + C4_kᵀ)``, shape (nq, 3, 3) (symmetric tensors)."""
        c4 = self.C4
        return -(c4 + c4.transpose(0, 2, 1))

    @property
    def Gr(self) -> np.ndarray:
        """``Gr_k = -2 C4_k``, shape (nq, 3, 3): gyroscopic torque ``Σ_k Gr_k q̇_k ω``.

        ``(Gr_k)_ab = 2 (δ_ab tr S_k - S_k[b, a])``; row ``a`` = torque component, column ``b``
        multiplies ``ω_b``.
        """
        return -2.0 * self.C4

    @property
    def Kr(self) -> np.ndarray:
        """``Kr[a, k, l] = ∫(Φ_l × Φ_k)_a dm``, shape (3, nq, nq), antisymmetric in (k, l)."""
        pp = self.PP
        return np.stack([pp[2, 1] - pp[1, 2], pp[0, 2] - pp[2, 0], pp[1, 0] - pp[0, 1]])

    @property
    def C6(self) -> np.ndarray:
        """``C6_kl = ∫ Φ̃_k Φ̃_l dm``, shape (nq, nq, 3, 3).

        ``C6_kl[a, b] = PP[b, a, k, l] - δ_ab Σ_c PP[c, c, k, l]``.
        """
        trace = np.einsum("cckl->kl", self.PP)
        return self.PP.transpose(2, 3, 1, 0) - trace[:, :, None, None] * np.eye(3)

    @property
    def Oe0(self) -> np.ndarray:
        """Centrifugal term ``Oe`` at ``q = 0``, shape (nq, 6), Ω order of :data:`OMEGA_ORDER`.

        Row k = ``(C4xx, C4yy, C4zz, C4xy + C4yx, C4yz + C4zy, C4xz + C4zx)_k``: the
        generalised force ``∫Φ_kᵀ ω̃ω̃ c dm = Oe0[k] · Ω``.
        """
        return _omega_components(self.C4)

    @property
    def Oe1(self) -> np.ndarray:
        """``∂Oe[k]/∂q_l``, shape (nq, nq, 6), symmetric in (k, l); components from ``C6_kl``."""
        return _omega_components(self.C6)


# ---------------------------------------------------------------------------------- compute
def compute_invariants(
    body: ElasticBody,
    basis: np.ndarray,
    mass: np.ndarray,
    stiffness: np.ndarray,
    damping: np.ndarray | None,
    nodes: list[int] | tuple[int, ...] | np.ndarray,
    frequencies_hz: np.ndarray | None = None,
    name: str = "",
    stiffening: StiffeningTerms | None = None,
) -> BodyInvariants:
    """Invariants of the reduced body ``u = Φ q`` (SID_NOTES §4).

    Parameters
    ----------
    body : ElasticBody
        The body in its reference frame (``PreparedModel.body``): coordinates measured from the
        frame origin, ``mass`` over all dofs.
    basis : ndarray, shape (n_dof, nq)
        ``Φ`` over all dofs of ``body`` (``PreparedModel.expand(V)``, eq. 18).
    mass, stiffness : ndarray, shape (nq, nq)
        Reduced mass and stiffness (stored as ``Me``, ``Ke`` unchanged).
    damping : ndarray, shape (nq, nq), or None
        Reduced viscous damping ``De`` (``None``: zero).
    nodes : sequence of int
        Ids of the output/interface nodes that become SID node frames.
    frequencies_hz : ndarray, shape (nq,), optional
        Frequency of each coordinate; default ``sqrt(Ke_kk / Me_kk) / 2π``.
    name : str
        Body name.
    stiffening : StiffeningTerms, optional
        Projected geometric stiffness of the frame's load cases and the nodal loads.

    Returns
    -------
    BodyInvariants

    Raises
    ------
    UserError
        Shapes do not match, non-finite input, or a node is unknown or has no translational dofs.

    Notes
    -----
    Cost O(nnz(M) · nq + N · nq²) (N nodes); no dense n_dof × n_dof matrix is formed. Sums
    prone to cancellation (first moment and ``Ct`` in a centroidal frame, ``S``) are formed in
    extended precision.
    """
    n_dof = body.n_dof
    phi = np.asarray(basis, dtype=float)
    if phi.ndim != 2 or phi.shape[0] != n_dof:
        raise UserError(f"invariants: basis has shape {phi.shape}, expected ({n_dof}, nq)")
    nq = phi.shape[1]
    if nq == 0:
        raise UserError("invariants: the basis has no columns")
    me = _square(mass, nq, "mass")
    ke = _square(stiffness, nq, "stiffness")
    de = np.zeros((nq, nq)) if damping is None else _square(damping, nq, "damping")
    if not np.all(np.isfinite(phi)):
        raise UserError("invariants: basis has NaN or infinite entries")
    if np.any(np.diag(me) <= 0.0):
        raise UserError("invariants: reduced mass matrix has a non-positive diagonal entry")
    if frequencies_hz is None:
        frequencies = np.sqrt(np.clip(np.diag(ke), 0.0, None) / np.diag(me)) / (2.0 * np.pi)
    else:
        frequencies = np.asarray(frequencies_hz, dtype=float).ravel()
        if frequencies.shape != (nq,) or not np.all(np.isfinite(frequencies)):
            raise UserError(f"invariants: frequencies_hz must be {nq} finite numbers")
    frames = tuple(_node_frame(body, phi, node) for node in nodes)

    m_full = sp.csr_matrix(body.mass)
    first = _first_order(body, m_full, phi)
    rows, directions = _dof_node_rows(body)
    # exact second-order terms of the parts whose kinematics is known: the beams of the mesh
    # (their consistent mass), then rigid bodies lumped at nodes (6 x 6 blocks of their own)
    parts = [part for part in (_beams(body, phi),) if part is not None]
    m_rest = m_full
    for part in parts:
        m_rest = sp.csr_matrix(m_rest - part.matrix)
    rigid = _lumped_rigid_bodies(body, m_rest)
    if rigid is not None:
        parts.append(rigid)
        m_rest = sp.csr_matrix(m_rest - rigid.matrix)
    if m_rest is m_full:  # shares its arrays with the body's mass, which stays as it is
        m_rest = m_full.copy()
    m_rest.data[np.abs(m_rest.data) <= KRONECKER_TOL * abs(m_full).max()] = 0.0
    m_rest.eliminate_zeros()
    blocks = _translational_blocks(m_rest, rows, directions, body.n_nodes)
    exact = _is_kronecker(m_rest, blocks, directions) or (parts and m_rest.nnz == 0)
    s, pp = _second_order(body.coordinates, phi, rows, directions, blocks)
    for part in parts:
        s_part, pp_part = part.second_order(phi)
        s, pp = s + s_part, pp + pp_part
    return BodyInvariants(
        mass=first["mass"],
        first_moment=first["first_moment"],
        inertia=first["inertia"],
        Ct=first["Ct"],
        Cr=first["Cr"],
        S=s,
        PP=pp,
        Me=me,
        Ke=ke,
        De=de,
        frequencies_hz=frequencies,
        nodes=frames,
        second_order_mass="exact" if exact else "translational",
        name=str(name),
        stiffening=stiffening,
    )


def _square(matrix: np.ndarray, nq: int, label: str) -> np.ndarray:
    out = np.array(matrix.toarray() if sp.issparse(matrix) else matrix, dtype=float)
    if out.shape != (nq, nq):
        raise UserError(f"invariants: reduced {label} matrix has shape {out.shape}, expected {nq}²")
    if not np.all(np.isfinite(out)):
        raise UserError(f"invariants: reduced {label} matrix has NaN or infinite entries")
    return out


def _node_frame(body: ElasticBody, phi: np.ndarray, node: int) -> NodeFrame:
    """Translational and rotational rows of ``Φ`` at one node (SID_NOTES §4.4)."""
    node = int(node)
    if node not in body.node_index:
        raise UserError(f"invariants: node {node} does not exist in the model")
    dofs = body.dofs.of_node(node)
    directions = body.dofs.directions[dofs]
    if not np.any(directions < 3):
        raise UserError(f"invariants: node {node} has no translational dofs")
    rows = np.zeros((6, phi.shape[1]))
    rows[directions] = phi[dofs]
    psi = rows[3:].copy() if np.any(directions >= 3) else None
    return NodeFrame(node, body.node_position(node).copy(), rows[:3].copy(), psi)


def _first_order(body: ElasticBody, m_full: sp.csr_matrix, phi: np.ndarray) -> dict:
    """m, ∫c dm, J0, Ct, Cr exactly from the full M (SID_NOTES §4.2(b))."""
    rigid = body.rigid_body_modes().astype(np.longdouble)  # [S_t S_r], u = θ × c
    m_rigid = long_product(m_full, rigid)  # (n_dof, 6), extended precision (rigid: doubles)
    rmr = rigid.T @ m_rigid  # (6, 6)
    mass = float(np.mean(np.diag(rmr)[:3]))
    mc = rmr[3:, :3]  # S_rᵀ M S_t = m c̃
    first_moment = 0.5 * np.array([mc[2, 1] - mc[1, 2], mc[0, 2] - mc[2, 0], mc[1, 0] - mc[0, 1]])
    inertia = np.asarray(rmr[3:, 3:], dtype=float)
    # (nq, 6) = Φᵀ M [S_t S_r]; einsum: numpy's longdouble matmul is 6x slower (no BLAS)
    coupling = np.einsum("nk,nj->kj", phi.astype(np.longdouble), m_rigid)
    return {
        "mass": mass,
        "first_moment": np.asarray(first_moment, dtype=float),
        "inertia": 0.5 * (inertia + inertia.T),
        "Ct": np.asarray(coupling[:, :3], dtype=float),
        "Cr": np.asarray(coupling[:, 3:], dtype=float),
    }


def _dof_node_rows(body: ElasticBody) -> tuple[np.ndarray, np.ndarray]:
    """Row in ``body.coordinates`` and direction code of every dof, shapes (n_dof,)."""
    return body.node_rows(body.dofs.nodes), body.dofs.directions


def _selection(rows: np.ndarray, directions: np.ndarray, axis: int, n_nodes: int) -> sp.csr_matrix:
    """``P_a`` (N × n_dof): picks the dof of direction ``axis`` of every node (zero row if none)."""
    dofs = np.flatnonzero(directions == axis)
    return sp.csr_matrix((np.ones(dofs.size), (rows[dofs], dofs)), shape=(n_nodes, directions.size))


def _translational_blocks(
    m_full: sp.csr_matrix, rows: np.ndarray, directions: np.ndarray, n_nodes: int
) -> dict:
    """Selections ``P_a`` and the node-space mass blocks ``M_ab = P_a M P_bᵀ`` (N × N)."""
    select = [_selection(rows, directions, a, n_nodes) for a in range(3)]
    blocks = {
        (a, b): sp.csr_matrix(select[a] @ m_full @ select[b].T) for a in range(3) for b in range(3)
    }
    return {"select": select, "blocks": blocks}


def _is_kronecker(m_full: sp.csr_matrix, blocks: dict, directions: np.ndarray) -> bool:
    """Whether ``M`` is ``m̄ ⊗ I3`` on the translations and zero elsewhere (SID_NOTES §4.2(a))."""
    mm = blocks["blocks"]
    scale = max(abs(mm[(a, a)]).max() for a in range(3))
    if scale == 0.0:
        return False
    tol = KRONECKER_TOL * scale

    def small(matrix: sp.spmatrix) -> bool:
        return matrix.nnz == 0 or abs(matrix).max() <= tol

    if not (small(mm[(1, 1)] - mm[(0, 0)]) and small(mm[(2, 2)] - mm[(0, 0)])):
        return False
    if not all(small(mm[(a, b)]) for a in range(3) for b in range(3) if a != b):
        return False
    rotational = np.flatnonzero(directions >= 3)
    return rotational.size == 0 or small(m_full[rotational])


#: A node block is a lumped rigid body when its translational mass is isotropic to this
#: relative tolerance.
RIGID_BLOCK_TOL = 1e-12


@dataclass(frozen=True, eq=False)
class _RigidBodies:
    """Rigid bodies lumped at nodes: the 6 x 6 mass blocks of M that couple no other node.

    A block ``[[m I, -(m s)~], [(m s)~, Theta]]`` about node ``n`` (position ``x_n``) is the mass
    of a rigid body moving as ``u(x) = u_n + psi_n x (x - x_n)``; its second-order integrals
    follow exactly from ``m``, the first moment ``m s`` and the second moments
    ``R = int r r^T dm = tr(Theta)/2 I - Theta`` (SID_NOTES §4.2(c) generalised to
    off-centre masses).
    """

    matrix: sp.csr_matrix  # the blocks on all dofs
    dofs: np.ndarray  # (n_r, 6) equations ux .. rz of each body's node
    position: np.ndarray  # (n_r, 3)
    mass: np.ndarray  # (n_r,)
    first: np.ndarray  # (n_r, 3) m s
    second: np.ndarray  # (n_r, 3, 3) R

    def second_order(self, phi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``S`` (nq, 3, 3) and ``PP`` (3, 3, nq, nq) of the rigid bodies for a basis."""
        t = phi[self.dofs[:, :3]]  # (n_r, 3, nq) translations of the nodes
        w = phi[self.dofs[:, 3:]]  # (n_r, 3, nq) rotations
        eps = levi_civita()
        x, m, ms, r = self.position, self.mass, self.first, self.second
        w_ms = np.einsum("bcd,nck,nd->nbk", eps, w, ms)  # (psi_k x m s)_b
        s = (
            np.einsum("n,na,nbk->kab", m, x, t)
            + np.einsum("na,nbk->kab", x, w_ms)
            + np.einsum("na,nbk->kab", ms, t)
            + np.einsum("bcd,nck,nad->kab", eps, w, r)
        )
        rot = np.einsum("acd,nck->nadk", eps, w)  # (psi_k x .)_a as a matrix on r: [a, d]
        pp = (
            np.einsum("n,nak,nbl->abkl", m, t, t)
            + np.einsum("nak,nbl->abkl", t, w_ms)
            + np.einsum("nak,nbl->abkl", w_ms, t)
            + np.einsum("nadk,ndf,nbfl->abkl", rot, r, rot)
        )
        return s, pp


def levi_civita() -> np.ndarray:
    """The permutation symbol ``eps[a, b, c]`` (``(u x v)_a = eps[a, b, c] u_b v_c``)."""
    eps = np.zeros((3, 3, 3))
    for a, b, c in ((0, 1, 2), (1, 2, 0), (2, 0, 1)):
        eps[a, b, c], eps[a, c, b] = 1.0, -1.0
    return eps


def _lumped_rigid_bodies(body: ElasticBody, lumped: sp.csr_matrix) -> _RigidBodies | None:
    """The node blocks of a mass matrix that are rigid bodies of their own, or None.

    A node qualifies when it has all six dofs, its rows of ``lumped`` (``M`` without the beams
    of the mesh, so that plates lumped at beam nodes qualify too) couple only its own dofs (no
    other node), its rotational block is not zero and its translational block is ``m I``.
    """
    directions, nodes = body.dofs.directions, body.dofs.nodes
    rotational = sorted_unique(nodes[directions >= 3])
    if rotational.size == 0:
        return None
    # the six equations ux .. rz of every node that has them all
    table = body.dofs.positions(rotational[:, None], np.arange(6))
    complete = np.all(table >= 0, axis=1)
    node_rows = body.node_rows(rotational)
    scale = max(float(abs(lumped).max()) if lumped.nnz else 0.0, np.finfo(float).tiny)
    found = []
    for dofs, row in zip(table[complete], node_rows[complete], strict=True):
        block_rows = lumped[dofs]
        if block_rows.nnz == 0:
            continue
        block = block_rows[:, dofs].toarray()
        outside = abs(block_rows).sum() - np.abs(block).sum()
        if outside > RIGID_BLOCK_TOL * scale:
            continue  # coupled to other nodes: not a rigid body of its own
        mass = block[0, 0]
        inertia = block[3:, 3:]
        if not mass > 0 or not np.abs(inertia).max() > 0:
            continue
        if np.abs(block[:3, :3] - mass * np.eye(3)).max() > RIGID_BLOCK_TOL * mass:
            continue
        coupling = block[:3, 3:]  # -(m s)~
        first = np.array([-coupling[2, 1], -coupling[0, 2], -coupling[1, 0]])
        if np.abs(coupling + skew(first)).max() > RIGID_BLOCK_TOL * scale:
            continue
        second = 0.5 * np.trace(inertia) * np.eye(3) - inertia
        found.append((dofs, body.coordinates[row], mass, first, second, block))
    if not found:
        return None
    n = body.n_dof
    dofs = np.array([f[0] for f in found])
    values = np.array([f[5] for f in found])
    r = np.broadcast_to(dofs[:, :, None], values.shape).ravel()
    c = np.broadcast_to(dofs[:, None, :], values.shape).ravel()
    matrix = sp.csr_matrix((values.ravel(), (r, c)), shape=(n, n))
    return _RigidBodies(
        matrix,
        dofs,
        np.array([f[1] for f in found]),
        np.array([f[2] for f in found]),
        np.array([f[3] for f in found]),
        np.array([f[4] for f in found]),
    )


@dataclass(frozen=True, eq=False)
class _Beams:
    """The two-node beams of a body's mesh with the fields of their consistent mass.

    A section point ``x(xi) + s`` moves by ``u(xi) + theta_x(xi) e_x x s``
    (:func:`pymorembs.elements.beam.beam_kinematics`); with the section moments ``R = int s s^T
    dA`` and ``Q = int (e_x x s)(e_x x s)^T dA`` (principal axes, scaled to the section's
    ``Ip``) the second-order integrals are ``S[k,a,b] = int rho A x_a u_bk + rho theta_k
    T_ab dx`` with ``T_ab = int s_a (e_x x s)_b dA`` and ``PP[a,b,k,l] = int rho A u_ak u_bl +
    rho theta_k theta_l Q_ab dx``, integrated exactly by Gauss points.
    """

    matrix: sp.csr_matrix  # the beams' consistent mass on all dofs
    p1: np.ndarray  # (n_el, 3)
    p2: np.ndarray  # (n_el, 3)
    equations: np.ndarray  # (n_el, 12), -1 for a dof the body does not have
    section: BeamSection
    up: np.ndarray | None

    def second_order(self, phi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``S`` (nq, 3, 3) and ``PP`` (3, 3, nq, nq) of the beams for a basis (n_dof, nq)."""
        from pymorembs.elements.beam import GAUSS_POINTS, GAUSS_WEIGHTS, beam_kinematics

        nq = phi.shape[1]
        padded = np.vstack([phi, np.zeros((1, nq))])  # row -1: a dof the body lacks
        sec = self.section
        c = sec.Ip / (sec.Iy + sec.Iz)
        s_out, pp_out = np.zeros((nq, 3, 3)), np.zeros((3, 3, nq, nq))
        chunk = max(1, 4_000_000 // (GAUSS_POINTS.size * 4 * 12 * max(nq, 1)))
        for start in range(0, self.p1.shape[0], chunk):
            part = slice(start, start + chunk)
            up = self.up if self.up is None or self.up.ndim == 1 else self.up[part]
            length, rot, disp, twist = beam_kinematics(
                self.p1[part], self.p2[part], GAUSS_POINTS, up
            )
            q = padded[self.equations[part]]  # (n, 12, nq)
            u = np.einsum("ngaj,njk->ngak", disp, q)  # centreline displacement
            theta = np.einsum("ngj,njk->ngk", twist, q)
            xi = GAUSS_POINTS[None, :, None]
            x = self.p1[part][:, None] + xi * (self.p2[part] - self.p1[part])[:, None]
            w_a = sec.rho * sec.area * length[:, None] * GAUSS_WEIGHTS  # (n, g), kg
            w_i = sec.rho * length[:, None] * GAUSS_WEIGHTS  # (n, g), kg/m²
            ey, ez = rot[:, 1], rot[:, 2]
            t = c * (
                sec.Iz * np.einsum("na,nb->nab", ey, ez) - sec.Iy * np.einsum("na,nb->nab", ez, ey)
            )
            qq = c * (
                sec.Iz * np.einsum("na,nb->nab", ez, ez) + sec.Iy * np.einsum("na,nb->nab", ey, ey)
            )
            s_out += np.einsum("ng,nga,ngbk->kab", w_a, x, u)
            s_out += np.einsum("ng,ngk,nab->kab", w_i, theta, t)
            pp_out += np.einsum("ng,ngak,ngbl->abkl", w_a, u, u)
            pp_out += np.einsum("ng,ngk,ngl,nab->abkl", w_i, theta, theta, qq)
        return s_out, pp_out


def _beams(body: ElasticBody, phi: np.ndarray) -> _Beams | None:
    """The beams of the body's mesh (``"beam2"``), or None."""
    mesh = body.mesh
    if mesh is None or mesh.element != "beam2":
        return None
    from pymorembs.elements.beam import assemble_beams

    index = body.dofs.positions(body.node_ids[:, None], np.arange(6))  # (n_nodes, 6)
    up = None if mesh.up is None else np.asarray(mesh.up, dtype=float)
    rows = body.node_rows(mesh.connectivity)  # (n_el, 2)
    used = np.unique(rows)
    if np.any(index[used] < 0):
        return None  # a beam node without all six dofs: the translational model applies
    _, matrix = assemble_beams(
        body.node_ids, body.coordinates, mesh.connectivity, mesh.section,
        np.where(index >= 0, index, 0), up=up, n_dof=body.n_dof,
    )  # fmt: skip
    coordinates = np.asarray(body.coordinates, dtype=float)
    return _Beams(
        sp.csr_matrix(matrix),
        coordinates[rows[:, 0]],
        coordinates[rows[:, 1]],
        index[rows].reshape(-1, 12),
        mesh.section,
        up,
    )


def _second_order(
    coordinates: np.ndarray,
    phi: np.ndarray,
    rows: np.ndarray,
    directions: np.ndarray,
    blocks: dict,
) -> tuple[np.ndarray, np.ndarray]:
    """``S`` (nq, 3, 3) and ``PP`` (3, 3, nq, nq) with ``m̄`` = mean of ``M_aa`` (§4.2(a))."""
    select = blocks["select"]
    mm = blocks["blocks"]
    m_bar = sp.csr_matrix((mm[(0, 0)] + mm[(1, 1)] + mm[(2, 2)]) / 3.0)
    u = [np.asarray(select[a] @ phi) for a in range(3)]  # U_a, (N, nq)
    m_u = [long_product(m_bar, u_b) for u_b in u]  # m̄ U_b, extended
    x = np.asarray(coordinates, dtype=np.longdouble)
    nq = phi.shape[1]
    s = np.empty((nq, 3, 3))
    for b in range(3):
        s[:, :, b] = np.asarray(m_u[b].T @ x, dtype=float)  # S[k, a, b] = (m̄ U_b)[:, k] · x_a
    pp = np.empty((3, 3, nq, nq))
    m_u64 = [np.asarray(block, dtype=float) for block in m_u]
    for a in range(3):
        for b in range(a, 3):
            block = u[a].T @ m_u64[b]
            if a == b:
                block = 0.5 * (block + block.T)
            pp[a, b] = block
            pp[b, a] = block.T  # PP[b, a, l, k] = PP[a, b, k, l] exactly
    return s, pp
