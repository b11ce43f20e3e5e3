"""Mass invariants of reduced bodies (SID_NOTES §4): point masses, rotary inertia, hex20 solids."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp
from threadpoolctl import threadpool_limits

from pymorembs.body import DofTable, ElasticBody
from pymorembs.elements.hex20 import HEX20_NODES, assemble_hex20, hex20_shape_functions
from pymorembs.errors import UserError
from pymorembs.export.invariants import compute_invariants


def cross_matrix(v: np.ndarray) -> np.ndarray:
    """[v]x for vectors (..., 3), written out here (independent of the code under test)."""
    x, y, z = v[..., 0], v[..., 1], v[..., 2]
    o = np.zeros_like(x)
    return np.stack(
        [np.stack([o, -z, y], -1), np.stack([z, o, -x], -1), np.stack([-y, x, o], -1)], -2
    )


def lumped_body(n_nodes=9, nq=4, seed=0, rotary=False, anisotropic=False):
    """Point masses at random positions (optionally with rotary inertia), random Φ.

    Φ vanishes at the first node (a tangent frame there), so Ct and Cr are not zero.
    Returns the body, Φ (n_dof, nq), masses (N,) or (N, 3), Θ (N, 3, 3) or None.
    """
    rng = np.random.default_rng(seed)
    per_node = 6 if rotary else 3
    ids = 100 + 7 * np.arange(n_nodes)
    coords = rng.normal(size=(n_nodes, 3)) + np.array([0.3, -0.2, 0.5])
    masses = rng.uniform(0.5, 2.0, size=(n_nodes, 3) if anisotropic else n_nodes)
    blocks = []
    thetas = None
    if rotary:
        a = rng.normal(size=(n_nodes, 3, 3))
        thetas = 0.1 * (a @ a.transpose(0, 2, 1) + np.eye(3))
    for i in range(n_nodes):
        block = np.zeros((per_node, per_node))
        block[:3, :3] = np.diag(masses[i] * np.ones(3))
        if rotary:
            block[3:, 3:] = thetas[i]
        blocks.append(block)
    dofs = DofTable(np.repeat(ids, per_node), np.tile(np.arange(per_node), n_nodes))
    n = per_node * n_nodes
    body = ElasticBody(ids, coords, dofs, sp.csr_matrix(sp.block_diag(blocks)), sp.eye(n).tocsr())
    phi = rng.normal(size=(n, nq))
    phi[:per_node] = 0.0
    return body, phi, masses, thetas


def reduced(body, phi):
    m = phi.T @ (body.mass @ phi)
    return m, np.diag(np.arange(1.0, phi.shape[1] + 1)) * 1e4


def test_point_masses_every_invariant_equals_the_explicit_sums():
    body, phi, m, _ = lumped_body()
    me, ke = reduced(body, phi)
    inv = compute_invariants(body, phi, me, ke, None, [100, 121], name="lumped")
    c = body.coordinates
    p = phi.reshape(-1, 3, phi.shape[1])  # Φ_i, (N, 3, nq)
    assert inv.second_order_mass == "exact"
    assert inv.mass == pytest.approx(m.sum(), rel=1e-15)
    assert np.allclose(inv.first_moment, m @ c, rtol=1e-14)
    assert np.allclose(inv.centre_of_gravity, m @ c / m.sum(), rtol=1e-14)
    # J0 = Σ m c̃ᵀ c̃ (tensor, off-diagonals -Σ m x y)
    cx = cross_matrix(c)
    j0 = np.einsum("i,iba,ibc->ac", m, cx, cx)
    assert np.allclose(inv.inertia, j0, rtol=1e-14)
    assert inv.inertia[0, 1] == pytest.approx(-np.sum(m * c[:, 0] * c[:, 1]), rel=1e-13)
    assert np.allclose(inv.Ct, np.einsum("i,iak->ka", m, p), rtol=1e-13)
    assert np.allclose(inv.Cr, np.einsum("i,iab,ibk->ka", m, cx, p), rtol=1e-13)
    assert np.allclose(inv.S, np.einsum("i,ia,ibk->kab", m, c, p), rtol=1e-13)
    assert np.allclose(inv.PP, np.einsum("i,iak,ibl->abkl", m, p, p), rtol=1e-13)
    # C4_k = Σ m c̃ Φ̃_k, C6_kl = Σ m Φ̃_k Φ̃_l, Kr[a, k, l] = Σ m (Φ_l × Φ_k)_a
    px = cross_matrix(p.transpose(0, 2, 1))  # (N, nq, 3, 3)
    c4 = np.einsum("i,iab,ikbc->kac", m, cx, px)
    assert np.allclose(inv.C4, c4, rtol=1e-13, atol=1e-13)
    assert np.allclose(inv.Gr, -2 * c4, rtol=1e-13, atol=1e-13)
    assert np.allclose(inv.C6, np.einsum("i,ikab,ilbc->klac", m, px, px), rtol=1e-13, atol=1e-13)
    cross = np.cross(p.transpose(0, 2, 1)[:, None, :, :], p.transpose(0, 2, 1)[:, :, None, :])
    assert np.allclose(inv.Kr, np.einsum("i,ikla->akl", m, cross), rtol=1e-13, atol=1e-13)

    # J1_k = ∂/∂q_k of J(q) = Σ m (|r|² I - r rᵀ), r = c + Φ q: central differences (exact
    # for a quadratic)
    def inertia(q):
        r = c + p @ q
        return np.einsum("i,iba,ibc->ac", m, cross_matrix(r), cross_matrix(r))

    for k in range(phi.shape[1]):
        e = np.zeros(phi.shape[1])
        e[k] = 1.0
        assert np.allclose(inv.J1[k], (inertia(e) - inertia(-e)) / 2, rtol=1e-12, atol=1e-12)
    # Oe: Σ m Φ_kᵀ ω̃ω̃ r = (Oe0 + Oe1 q)·Ω for random ω and q
    rng = np.random.default_rng(5)
    w, q = rng.normal(size=3), rng.normal(size=phi.shape[1])
    ww = cross_matrix(w) @ cross_matrix(w)
    omega = np.array([w[0] ** 2, w[1] ** 2, w[2] ** 2, w[0] * w[1], w[1] * w[2], w[0] * w[2]])
    exact = np.einsum("i,iak,ab,ib->k", m, p, ww, c + p @ q)
    assert np.allclose((inv.Oe0 + np.einsum("klm,l->km", inv.Oe1, q)) @ omega, exact, rtol=1e-12)
    # reduced matrices stored as given; node frames are the rows of Φ
    assert np.array_equal(inv.Me, me) and np.array_equal(inv.Ke, ke)
    assert np.allclose(inv.frequencies_hz, np.sqrt(np.diag(ke) / np.diag(me)) / (2 * np.pi))
    assert [f.node_id for f in inv.nodes] == [100, 121]
    assert np.array_equal(inv.nodes[1].phi, phi[9:12]) and inv.nodes[1].psi is None
    assert np.array_equal(inv.nodes[1].position, c[3]) and inv.name == "lumped"


def test_rotary_inertia_enters_first_order_terms_exactly():
    body, phi, m, theta = lumped_body(rotary=True)
    me, ke = reduced(body, phi)
    inv = compute_invariants(body, phi, me, ke, 0.01 * ke, [107])
    c = body.coordinates
    p = phi.reshape(-1, 6, phi.shape[1])
    u, psi = p[:, :3], p[:, 3:]
    cx = cross_matrix(c)
    assert inv.second_order_mass == "exact"  # point masses with rotary inertia: rigid bodies
    j0 = np.einsum("i,iba,ibc->ac", m, cx, cx) + theta.sum(axis=0)  # SID_NOTES §4.2(c)
    assert np.allclose(inv.inertia, j0, rtol=1e-14)
    cr = np.einsum("i,iab,ibk->ka", m, cx, u) + np.einsum("iab,ibk->ka", theta, psi)
    assert np.allclose(inv.Cr, cr, rtol=1e-13)
    assert np.allclose(inv.Ct, np.einsum("i,iak->ka", m, u), rtol=1e-13)
    # second-order terms: the point masses plus the rotary inertia of each lumped body, whose
    # mass points r (about the node) have int r r^T dm = R = tr(Theta)/2 I - Theta; the field
    # psi x r = skew(psi) r gives int r (psi_k x r)^T dm = R skew(psi_k)^T and
    # int (psi_k x r)(psi_l x r)^T dm = skew(psi_k) R skew(psi_l)^T
    second = 0.5 * np.trace(theta, axis1=1, axis2=2)[:, None, None] * np.eye(3) - theta
    s = np.einsum("i,ia,ibk->kab", m, c, u)
    pp = np.einsum("i,iak,ibl->abkl", m, u, u)
    for i in range(len(m)):
        for k in range(phi.shape[1]):
            s[k] += second[i] @ cross_matrix(psi[i, :, k]).T
            for j in range(phi.shape[1]):
                pp[:, :, k, j] += (
                    cross_matrix(psi[i, :, k]) @ second[i] @ cross_matrix(psi[i, :, j]).T
                )
    assert np.allclose(inv.S, s, rtol=1e-13, atol=1e-14 * np.abs(s).max())
    assert np.allclose(inv.PP, pp, rtol=1e-13, atol=1e-14 * np.abs(pp).max())
    assert np.array_equal(inv.nodes[0].psi, psi[1]) and np.array_equal(inv.De, 0.01 * ke)


def test_direction_dependent_masses_use_the_mean_translational_mass():
    body, phi, m, _ = lumped_body(anisotropic=True)
    inv = compute_invariants(body, phi, *reduced(body, phi), None, [100])
    p = phi.reshape(-1, 3, phi.shape[1])
    assert inv.second_order_mass == "translational"
    assert inv.mass == pytest.approx(m.sum(axis=0).mean(), rel=1e-14)
    mean = m.mean(axis=1)
    assert np.allclose(inv.S, np.einsum("i,ia,ibk->kab", mean, body.coordinates, p), rtol=1e-13)
    # first-order terms stay exact with the direction-dependent masses
    assert np.allclose(inv.Ct, np.einsum("ia,iak->ka", m, p), rtol=1e-13)


def hex20_box(lower, size, counts, seed=0):
    """A brick ``lower + [0, size]`` meshed with 20-node hexahedra on a random tensor grid."""
    rng = np.random.default_rng(seed)
    axes = []
    for lo, length, n in zip(lower, size, counts, strict=True):
        steps = rng.uniform(0.5, 1.5, size=n)
        corners = lo + length * np.concatenate([[0.0], np.cumsum(steps)]) / steps.sum()
        half = np.empty(2 * n + 1)
        half[0::2], half[1::2] = corners, 0.5 * (corners[:-1] + corners[1:])
        axes.append(half)
    grid = np.stack(np.meshgrid(*[np.arange(a.size) for a in axes], indexing="ij"), -1)
    keep = (grid % 2).sum(axis=-1) <= 1  # serendipity: no face or volume centres
    number = -np.ones(keep.shape, dtype=np.int64)
    number[keep] = np.arange(keep.sum())
    points = grid[keep]
    coords = np.column_stack([axes[d][points[:, d]] for d in range(3)])
    elements = []
    for i in range(counts[0]):
        for j in range(counts[1]):
            for k in range(counts[2]):
                at = (np.array([2 * i + 1, 2 * j + 1, 2 * k + 1]) + HEX20_NODES).astype(int)
                elements.append(number[at[:, 0], at[:, 1], at[:, 2]])
    return coords, np.array(elements)


def test_hex20_box_mass_centre_and_inertia_are_analytic_and_mass_is_kronecker():
    lower, size, rho = np.array([0.3, -0.1, 0.2]), np.array([0.4, 0.25, 0.15]), 7850.0
    coords, elements = hex20_box(lower, size, (3, 2, 2))
    stiffness, mass = assemble_hex20(coords, elements, 2.1e11, 0.3, rho)
    n_nodes = coords.shape[0]
    ids = np.arange(1, n_nodes + 1)
    dofs = DofTable(np.repeat(ids, 3), np.tile(np.arange(3), n_nodes))
    body = ElasticBody(ids, coords, dofs, mass, stiffness)
    rng = np.random.default_rng(2)
    phi = rng.normal(size=(3 * n_nodes, 3))
    with threadpool_limits(1):
        inv = compute_invariants(body, phi, phi.T @ (mass @ phi), np.eye(3), None, [1])
    m = rho * np.prod(size)
    centre = lower + size / 2
    a, b, c = size
    j_g = m / 12 * np.diag([b**2 + c**2, a**2 + c**2, a**2 + b**2])
    j0 = j_g + m * (centre @ centre * np.eye(3) - np.outer(centre, centre))  # parallel axes
    assert inv.second_order_mass == "exact"
    assert inv.mass == pytest.approx(m, rel=1e-12)
    assert np.allclose(inv.centre_of_gravity, centre, rtol=1e-12, atol=0)
    assert np.abs(inv.inertia - j0).max() <= 1e-12 * np.abs(j0).max()
    # S and PP against Gauss quadrature (4 points per direction, exact here) of the continuum
    s_ref, pp_ref = _quadrature(coords, elements, phi, rho)
    assert np.abs(inv.S - s_ref).max() <= 1e-12 * np.abs(s_ref).max()
    assert np.abs(inv.PP - pp_ref).max() <= 1e-12 * np.abs(pp_ref).max()


def _quadrature(coords, elements, phi, rho):
    """∫ c_a Φ_{k,b} dm and ∫ Φ_{k,a} Φ_{l,b} dm by 4 × 4 × 4 Gauss points per element."""
    g, w = np.polynomial.legendre.leggauss(4)
    points = np.stack(np.meshgrid(g, g, g, indexing="ij"), -1).reshape(-1, 3)
    weights = np.einsum("i,j,k->ijk", w, w, w).ravel()
    values, derivatives = hex20_shape_functions(points)  # (q, 20), (q, 20, 3)
    nq = phi.shape[1]
    u = phi.reshape(-1, 3, nq)
    s = np.zeros((nq, 3, 3))
    pp = np.zeros((3, 3, nq, nq))
    for element in elements:
        x = coords[element]  # (20, 3)
        jac = np.einsum("qak,ai->qik", derivatives, x)
        dm = rho * weights * np.linalg.det(jac)  # (q,)
        pos = values @ x  # (q, 3)
        field = np.einsum("qa,abk->qbk", values, u[element])  # (q, 3, nq)
        s += np.einsum("q,qa,qbk->kab", dm, pos, field)
        pp += np.einsum("q,qak,qbl->abkl", dm, field, field)
    return s, pp


def test_bad_input_is_a_user_error():
    body, phi, _, _ = lumped_body()
    me, ke = reduced(body, phi)
    with pytest.raises(UserError, match="node 5 does not exist"):
        compute_invariants(body, phi, me, ke, None, [5])
    with pytest.raises(UserError, match="basis has shape"):
        compute_invariants(body, phi[:-1], me, ke, None, [100])
    with pytest.raises(UserError, match="stiffness matrix has shape"):
        compute_invariants(body, phi, me, ke[:2], None, [100])
    bad = phi.copy()
    bad[4, 1] = np.nan
    with pytest.raises(UserError, match="NaN"):
        compute_invariants(body, bad, me, ke, None, [100])
    rot, rot_phi, _, _ = lumped_body(rotary=True)
    only_rotations = ElasticBody(
        rot.node_ids, rot.coordinates, DofTable(rot.dofs.nodes[3:], rot.dofs.directions[3:]),
        rot.mass[3:, 3:], rot.stiffness[3:, 3:],
    )  # fmt: skip
    with pytest.raises(UserError, match="node 100 has no translational dofs"):
        compute_invariants(only_rotations, rot_phi[3:], me, ke, None, [100])


def test_rigid_bodies_at_nodes_against_their_point_clouds():
    """Each node carries a rigid body made of 7 point masses (its 6 x 6 block of M); the
    second-order invariants from the blocks equal the sums over the points (SID_NOTES §4.1)."""
    rng = np.random.default_rng(5)
    xyz = rng.normal(size=(3, 3))
    clouds = [(xyz[n] + 0.3 * rng.normal(size=(7, 3)), rng.uniform(0.5, 2.0, 7)) for n in range(3)]
    mass = np.zeros((18, 18))
    for i, (points, masses) in enumerate(clouds):
        link = np.zeros((len(masses), 3, 6))  # u = u_n + psi x r = u_n - skew(r) psi
        link[:, :, :3] = np.eye(3)
        link[:, :, 3:] = -cross_matrix(points - xyz[i])
        mass[6 * i : 6 * i + 6, 6 * i : 6 * i + 6] = np.einsum("p,pia,pib->ab", masses, link, link)
    a = rng.normal(size=(18, 18))
    stiffness = a @ a.T + 18 * np.eye(18)
    ids = np.arange(1, 4)
    body = ElasticBody(ids, xyz, DofTable(np.repeat(ids, 6), np.tile(np.arange(6), 3)),
                       sp.csr_matrix(mass), sp.csr_matrix(stiffness))  # fmt: skip
    phi = rng.normal(size=(18, 4))
    inv = compute_invariants(body, phi, phi.T @ mass @ phi, phi.T @ stiffness @ phi, None, [1])
    s, pp = np.zeros((4, 3, 3)), np.zeros((3, 3, 4, 4))
    for i, (points, masses) in enumerate(clouds):
        u = phi[6 * i : 6 * i + 3][None] - np.einsum(
            "pab,bk->pak", cross_matrix(points - xyz[i]), phi[6 * i + 3 : 6 * i + 6]
        )
        s += np.einsum("p,pa,pbk->kab", masses, points, u)
        pp += np.einsum("p,pak,pbl->abkl", masses, u, u)
    assert inv.second_order_mass == "exact"
    np.testing.assert_allclose(inv.S, s, rtol=0, atol=1e-13 * np.abs(s).max())
    np.testing.assert_allclose(inv.PP, pp, rtol=0, atol=1e-13 * np.abs(pp).max())


def test_rack_beams_torsion_mode_keeps_its_plate_inertia():
    """Issue #15 item 3: the torsion mode of rack-beams (lower plate about z) had 78 % of its
    mass missing from the second-order terms; with the plates as rigid bodies it has all of it
    but the rods' own torsional inertia."""
    from pymorembs.examples import build_example
    from pymorembs.export.source import body_invariants
    from pymorembs.preparation import Frame, Port, prepare
    from pymorembs.reduction.modal import modal_reduction
    from pymorembs.reduction.projection import reduced_model

    ports = [Port.parse(1, "ux")]
    prepared = prepare(build_example("rack-beams"), Frame("tangent", 2), ports, ports)
    model = reduced_model(prepared.system, modal_reduction(prepared.system, 4))
    inv = body_invariants(model, prepared, [1, 2], "rack")
    share = np.einsum("aakk->k", inv.PP) / np.diag(inv.Me)
    torsion = int(np.argmin(np.abs(model.eigenfrequencies_hz - 100.9)))
    assert model.eigenfrequencies_hz[torsion] == pytest.approx(100.9, abs=0.1)
    # plates as rigid bodies, the rods with their consistent-mass kinematics: all of it
    assert inv.second_order_mass == "exact"
    np.testing.assert_allclose(share, 1.0, rtol=1e-10)


def hermite_beam_points(p1, p2, up, width, height, rho, dofs):
    """Mass points of one rectangular beam element and their displacements, written out from the
    element's textbook fields: linear axial and torsion, cubic Hermite bending (``ry = -w'``),
    a section point at ``(y, z)`` moving by ``theta_x e_x x s``. Returns positions (P, 3), masses
    (P,) and displacements (P, 3, nq) for element dofs ``dofs`` (12, nq) in global directions."""
    length = np.linalg.norm(p2 - p1)
    ex = (p2 - p1) / length
    ez = up - (up @ ex) * ex
    ez /= np.linalg.norm(ez)
    ey = np.cross(ez, ex)
    rot = np.array([ex, ey, ez])
    loc = np.concatenate([rot @ dofs[3 * i : 3 * i + 3] for i in range(4)])  # (12, nq) local
    g, gw = np.polynomial.legendre.leggauss(5)
    positions, masses, moves = [], [], []
    for xi, wx in zip(0.5 * (g + 1), 0.5 * gw, strict=True):
        h = [1 - 3 * xi**2 + 2 * xi**3, length * (xi - 2 * xi**2 + xi**3),
             3 * xi**2 - 2 * xi**3, length * (xi**3 - xi**2)]  # fmt: skip
        u = (1 - xi) * loc[0] + xi * loc[6]
        v = h[0] * loc[1] + h[1] * loc[5] + h[2] * loc[7] + h[3] * loc[11]
        w = h[0] * loc[2] - h[1] * loc[4] + h[2] * loc[8] - h[3] * loc[10]
        twist = (1 - xi) * loc[3] + xi * loc[9]
        for y, wy in zip(0.5 * width * g, 0.5 * width * gw, strict=True):
            for z, wz in zip(0.5 * height * g, 0.5 * height * gw, strict=True):
                local = np.array([u, v - z * twist, w + y * twist])  # (3, nq)
                positions.append(p1 + xi * (p2 - p1) + y * ey + z * ez)
                masses.append(rho * length * wx * wy * wz)
                moves.append(rot.T @ local)
    return np.array(positions), np.array(masses), np.array(moves)


def test_beam_second_order_terms_equal_the_point_cloud_of_their_sections():
    """Issue #15 item 3: a frame of beams (skew elements, rectangular section) -- S and PP from
    the consistent-mass kinematics equal the sums over mass points of the sections, and the
    exact identities sum_a PP[a, a] = Phi^T M Phi and eps S = Cr (first order, from M) hold."""
    from pymorembs.body import ElementMesh
    from pymorembs.elements.beam import BeamSection, assemble_beams

    section = BeamSection.rectangular(0.04, 0.015, E=2.1e11, nu=0.3, rho=7850.0)
    rng = np.random.default_rng(8)
    xyz = np.array([[0.0, 0, 0], [0.5, 0.1, 0.0], [0.9, 0.3, 0.2], [1.2, 0.2, 0.6]])
    xyz += 0.02 * rng.normal(size=xyz.shape)
    ids = np.array([1, 2, 3, 4])
    elements = np.array([[1, 2], [2, 3], [3, 4]])
    up = np.array([0.2, 0.1, 1.0])
    index = np.arange(24).reshape(4, 6)
    stiffness, mass = assemble_beams(ids, xyz, elements, section, index, up=up)
    mesh = ElementMesh("beam2", elements, 2.1e11, 0.3, section=section, up=tuple(up))
    body = ElasticBody(ids, xyz, DofTable(np.repeat(ids, 6), np.tile(np.arange(6), 4)), mass,
                       stiffness + sp.identity(24), mesh=mesh)  # fmt: skip
    phi = rng.normal(size=(24, 5))
    inv = compute_invariants(body, phi, phi.T @ mass @ phi, np.eye(5), None, [1])
    s, pp = np.zeros((5, 3, 3)), np.zeros((3, 3, 5, 5))
    for a, b in elements - 1:
        dofs = np.concatenate([phi[6 * a : 6 * a + 6], phi[6 * b : 6 * b + 6]])
        points, masses, moves = hermite_beam_points(xyz[a], xyz[b], up, 0.04, 0.015, 7850.0, dofs)
        s += np.einsum("p,pa,pbk->kab", masses, points, moves)
        pp += np.einsum("p,pak,pbl->abkl", masses, moves, moves)
    assert inv.second_order_mass == "exact"
    np.testing.assert_allclose(inv.S, s, rtol=0, atol=1e-12 * np.abs(s).max())
    np.testing.assert_allclose(inv.PP, pp, rtol=0, atol=1e-12 * np.abs(pp).max())
    me = phi.T @ mass @ phi
    np.testing.assert_allclose(np.einsum("aakl->kl", inv.PP), me, atol=1e-12 * np.abs(me).max())
    eps = np.zeros((3, 3, 3))
    for i, j, k in ((0, 1, 2), (1, 2, 0), (2, 0, 1)):
        eps[i, j, k], eps[i, k, j] = 1.0, -1.0
    cr = np.einsum("abc,kbc->ka", eps, inv.S)
    np.testing.assert_allclose(cr, inv.Cr, atol=1e-12 * np.abs(inv.Cr).max())
