"""Geometric stiffness of 20-node hexahedra (issue #15 item 2, the element part).

Checked against closed forms (a uniform uniaxial prestress) and, on the built-in blade spinning
about its hub, against an independent Ritz solution of the rotating Euler-Bernoulli cantilever.
"""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse.linalg as spla

from pymorembs.elements.solid import assemble_solid_geometric
from pymorembs.examples.blade import blade, blade_mesh

E, NU, RHO, B, H, L = 2.1e11, 0.3, 7850.0, 0.04, 0.01, 1.0


def test_uniaxial_prestress_gives_the_string_stiffness():
    mesh = blade_mesh(hub_radius=0.3, length=0.2, elements=4)
    x, y, z = mesh.coordinates.T
    strain = 1e-4
    prestress = np.column_stack([strain * x, -NU * strain * y, -NU * strain * z]).ravel()
    k_g = assemble_solid_geometric("hex20", mesh.coordinates, mesh.elements, prestress, E, NU)
    volume = 0.2 * B * H
    slope = 0.7  # a transverse displacement u_z = slope * x: sigma_xx * slope² * V
    test = np.column_stack([0 * x, 0 * x, slope * x]).ravel()
    assert test @ (k_g @ test) == pytest.approx(E * strain * slope**2 * volume, rel=1e-12)
    # K_G = g (x) I_3: the same energy for the field along y; a rigid translation has none
    test_y = np.column_stack([0 * x, slope * x, 0 * x]).ravel()
    assert test_y @ (k_g @ test_y) == pytest.approx(E * strain * slope**2 * volume, rel=1e-12)
    shift = np.tile([0.1, -0.2, 0.3], x.size)
    assert abs(shift @ (k_g @ shift)) < 1e-12 * abs(test @ (k_g @ test))


def rotating_beam_hz(omega: float, hub: float, n: int = 10) -> float:
    """First flapwise frequency (Hz) of a rotating Euler-Bernoulli cantilever, Ritz with
    w = sum c_j x^(j+1) (j = 1..n), centrifugal tension T(x) = rho A omega² [R (L-x) + (L²-x²)/2].
    """
    xi, wi = np.polynomial.legendre.leggauss(60)
    x, w = 0.5 * L * (xi + 1.0), 0.5 * L * wi
    j = np.arange(1, n + 1)[:, None]
    phi, d1, d2 = x ** (j + 1), (j + 1) * x**j, (j + 1) * j * x ** (j - 1)
    area, inertia = B * H, B * H**3 / 12
    tension = RHO * area * omega**2 * (hub * (L - x) + 0.5 * (L**2 - x**2))
    k = E * inertia * (d2 * w) @ d2.T + (d1 * tension * w) @ d1.T
    m = RHO * area * (phi * w) @ phi.T
    values = np.linalg.eigvals(np.linalg.solve(m, k))
    return float(np.sqrt(np.min(values.real)) / (2 * np.pi))


def solid_flap_hz(hub: float, omegas: list[float]) -> list[float]:
    """Lowest frequency (Hz) of K + omega² K_G of the solid blade, K_G from the static response
    to the centrifugal load of a unit angular velocity about z (scipy eigsh, root dofs removed)."""
    body = blade(hub_radius=hub, elements=24)
    mesh = blade_mesh(hub_radius=hub, elements=24)
    free = np.setdiff1d(np.arange(body.n_dof), body.fixed)
    k, m = body.stiffness.tocsr(), body.mass.tocsr()
    x, y, _ = mesh.coordinates.T
    load = m @ np.column_stack([x, y, 0 * x]).ravel()  # -M (omega x (omega x c)), omega = e_z
    u = np.zeros(body.n_dof)
    u[free] = spla.spsolve(k[free][:, free].tocsc(), load[free])
    k_g = assemble_solid_geometric("hex20", mesh.coordinates, mesh.elements, u, E, NU).tocsr()
    out = []
    for omega in omegas:
        a = (k + omega**2 * k_g)[free][:, free]
        values = spla.eigsh(a.tocsc(), k=1, M=m[free][:, free].tocsc(), sigma=0.0)[0]
        out.append(float(np.sqrt(values[0]) / (2 * np.pi)))
    return out


@pytest.mark.parametrize("hub", [0.0, 0.5])
def test_rotating_blade_stiffens_like_the_rotating_beam(hub):
    f0 = rotating_beam_hz(0.0, hub)
    omegas = [0.0, 2 * np.pi * f0, 4 * np.pi * f0]  # 0, once and twice the bending frequency
    solid = solid_flap_hz(hub, omegas)
    beam = [rotating_beam_hz(w, hub) for w in omegas]
    # the stiffening ratio f(omega) / f(0) of the solid within 0.5 % of the beam's
    for s, b in zip(solid[1:], beam[1:], strict=True):
        assert s / solid[0] == pytest.approx(b / beam[0], rel=5e-3)
    assert solid[1] > 1.4 * solid[0]  # about 1.476 at hub 0: Southwell's 1.193 gives 1.481
    if hub == 0.0:
        assert beam[1] / beam[0] == pytest.approx(np.sqrt(1 + 1.193), rel=5e-3)


@pytest.mark.parametrize("hub", [0.0, 0.5])
def test_rotating_beam_elements_stiffen_like_the_ritz_beam(hub):
    """The mesh route on two-node beams: a body of 30 beams, K_G of the centrifugal load case."""
    from pymorembs.body import DofTable, ElasticBody, ElementMesh
    from pymorembs.elements.beam import BeamSection, assemble_beams
    from pymorembs.preparation import Frame, prepare
    from pymorembs.preparation.stiffening import stiffening_from_mesh

    section = BeamSection.rectangular(B, H, E=E, nu=NU, rho=RHO)
    ids = np.arange(1, 32)
    xyz = np.column_stack([hub + np.linspace(0.0, L, ids.size), 0 * ids, 0 * ids])
    elements = np.column_stack([ids[:-1], ids[1:]])
    up = np.array([0.0, 0.0, 1.0])
    k, m = assemble_beams(ids, xyz, elements, section, 6 * np.arange(ids.size)[:, None]
                          + np.arange(6), up=up)  # fmt: skip
    mesh = ElementMesh("beam2", elements, E, NU, section=section, up=(0.0, 0.0, 1.0))
    dofs = DofTable(np.repeat(ids, 6), np.tile(np.arange(6), ids.size))
    body = ElasticBody(ids, xyz, dofs, m, k, fixed=np.arange(6), mesh=mesh)
    system = prepare(body, Frame("none")).system
    k_g = stiffening_from_mesh(prepare(body, Frame("none")), cases=("wzz",)).cases["wzz"]
    f0 = rotating_beam_hz(0.0, hub)
    for ratio in (1.0, 2.0):
        omega = ratio * 2 * np.pi * f0
        a = (system.stiffness + omega**2 * k_g).tocsc()
        values = spla.eigsh(a, k=1, M=system.mass.tocsc(), sigma=0.0)[0]
        assert np.sqrt(values[0]) / (2 * np.pi) == pytest.approx(
            rotating_beam_hz(omega, hub), rel=1e-3
        )
