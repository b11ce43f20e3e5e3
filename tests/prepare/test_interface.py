"""Interface nodes (paper section 2.2): node selection and the four couplings."""

from __future__ import annotations

import numpy as np
import pytest
from test_prepare import lagrange_response

from conftest import space_truss, spring_lattice
from pymorembs.analysis.transfer import transfer_function
from pymorembs.errors import UserError
from pymorembs.preparation import Frame, Port, prepare
from pymorembs.preparation.interface import (
    LIGHT_STIFF_BEAM,
    InterfaceSpec,
    add_interface_node,
    select_nodes,
)

# the truss: 4 x 3 x 2 nodes at 0.1 m spacing; face x = 0.3 holds nodes 19..24
FACE = (np.array([0.25, -1.0, -1.0]), np.array([0.35, 1.0, 1.0]))
CENTRE = (0.3, 0.1, 0.05)


def truss_with(kind: str, **params) -> tuple:
    truss = space_truss()
    face = select_nodes(truss, box=FACE)
    spec = InterfaceSpec(node=900, position=CENTRE, coupled=tuple(face), kind=kind, **params)
    return truss, face, add_interface_node(truss, spec)


def static_at_interface(body, force, clamp=(1, 2, 3, 4, 5, 6)):
    """Displacement of node 900 under a force there, the x = 0 face clamped."""
    held = body.with_fixed(np.concatenate([body.dofs.of_node(n) for n in clamp]))
    ports = [Port.parse(900, "ux uy uz")]
    prepared = prepare(held, Frame("none"), ports, ports)
    return (transfer_function(prepared.system, [0.0])[0] @ force).real


def test_select_nodes_by_cylinder_box_and_ids():
    truss = space_truss()
    axis = ((0.0, 0.1, 0.0), (1.0, 0.0, 0.0))  # along x through y = 0.1, z = 0
    shell = select_nodes(truss, cylinder=(*axis, 0.1, 1e-9))
    assert len(shell) == 4 * 3  # y = 0 and y = 0.2 at z = 0, y = 0.1 at z = 0.1
    filled = select_nodes(truss, cylinder=(*axis, 0.1))
    assert len(filled) == 4 * 4  # the shell plus the axis nodes
    both = select_nodes(truss, cylinder=(*axis, 0.1), box=((-1, -1, -1), (0.05, 1, 1)))
    assert len(both) == 4
    assert list(select_nodes(truss, ids=[3, 1])) == [1, 3]
    with pytest.raises(UserError, match="node 999"):
        select_nodes(truss, ids=[999])
    with pytest.raises(UserError, match="no node"):
        select_nodes(truss, box=((5, 5, 5), (6, 6, 6)))


def test_rigid_coupling_moves_the_face_rigidly_and_keeps_six_rigid_modes():
    truss, face, body = truss_with("rigid")
    assert body.n_dof == truss.n_dof + 6
    assert len(body.constraints) == 3 * len(face)
    rigid = body.rigid_body_modes()  # rigid motions satisfy the coupling exactly
    dep = body.constraints.dependent
    assert np.allclose(body.constraints.matrix @ rigid, rigid[dep], atol=1e-14)
    prepared = prepare(body, Frame("none"), allow_rigid_body_modes=True)
    assert prepared.system.order == truss.n_dof + 6 - 3 * len(face)


def test_distributing_coupling_is_statically_equivalent_and_does_not_stiffen():
    truss, _, body = truss_with("distributing")
    c = body.constraints
    master = c.dependent  # the interface node's 6 dofs are the dependent ones
    assert sorted(body.dofs.nodes[master]) == [900] * 6
    rigid = body.rigid_body_modes()
    assert np.allclose(c.matrix @ rigid, rigid[master], atol=1e-14)  # follows rigid motion
    # a unit force at the interface node is distributed (G^T) into a statically equivalent set
    positions = np.array([body.node_position(n) for n in body.dofs.nodes])
    for direction in range(3):
        loads = c.matrix.T @ np.eye(6)[direction]
        forces = loads.reshape(-1)[: truss.n_dof].reshape(-1, 3)
        assert np.allclose(forces.sum(axis=0), np.eye(3)[direction])
        moment = np.cross(positions[: truss.n_dof : 3] - CENTRE, forces).sum(axis=0)
        assert np.allclose(moment, 0.0, atol=1e-12)
    # no stiffening: the clamped truss is as stiff with the RBE3 as without
    u = static_at_interface(body, np.array([0.0, 0.0, 1.0]))
    assert u[2] > static_at_interface(truss_with("rigid")[2], np.array([0.0, 0.0, 1.0]))[2]


def test_light_stiff_beams_approach_the_rigid_coupling():
    force = np.array([0.0, 1.0, 1.0])
    rigid = static_at_interface(truss_with("rigid")[2], force)
    light = static_at_interface(truss_with("beams", diameter=5e-3, **LIGHT_STIFF_BEAM)[2], force)
    steel = static_at_interface(truss_with("beams", diameter=1e-3)[2], force)
    assert np.linalg.norm(light - rigid) < 1e-4 * np.linalg.norm(rigid)
    assert np.linalg.norm(steel - rigid) > 1e-2 * np.linalg.norm(rigid)  # thin steel: soft


def test_beam_spider_adds_its_mass_and_rotational_dofs():
    truss, face, body = truss_with("beams", diameter=2e-3, youngs_modulus=2.1e11, density=7850.0)
    arms = np.array([truss.node_position(n) for n in face]) - CENTRE
    beam_mass = 7850.0 * np.pi * 1e-6 * np.linalg.norm(arms, axis=1).sum()
    assert body.total_mass() == pytest.approx(truss.total_mass() + beam_mass, rel=1e-12)
    assert body.n_dof == truss.n_dof + 6 + 3 * len(face)  # face nodes got rx ry rz


def test_springs_give_the_series_stiffness():
    k, c = 1e5, 7.0
    truss, face, body = truss_with("springs", stiffness=k, damping=c)
    assert body.n_dof == truss.n_dof + 3  # translations only
    clamp = tuple(int(n) for n in truss.node_ids)  # the truss held rigidly: only springs remain
    u = static_at_interface(body, np.array([1.0, 2.0, 3.0]), clamp=clamp)
    assert np.allclose(u, np.array([1.0, 2.0, 3.0]) / (len(face) * k), rtol=1e-10)
    node = body.dofs.index(900, "uz")
    assert body.damping_matrix[node, node] == pytest.approx(len(face) * c)


def test_tangent_frame_at_a_distributing_interface_node_holds_it():
    """Frame at an RBE3-like (dependent) node: q_node = 0, checked with Lagrange multipliers."""
    _, _, body = truss_with("distributing")
    framed = prepare(body, Frame("tangent", 900), [Port.parse(5, "ux uy")], [Port.parse(5, "ux")])
    node = body.dofs.of_node(900)
    assert np.allclose(framed.elimination.transform[node].toarray(), 0.0, atol=1e-13)
    # reference: the body's own constraints plus q_900 = 0 as Lagrange rows (nothing eliminated)
    f = 3.0
    load = np.zeros((body.n_dof, 2))
    load[body.dofs.index(5, "ux"), 0] = load[body.dofs.index(5, "uy"), 1] = 1.0
    q = lagrange_response(body.with_fixed(node), f, load, offsets=False)
    h = transfer_function(framed.system, [f])[0]
    assert np.allclose(h, q[[body.dofs.index(5, "ux")]], rtol=1e-8)


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"node": 1}, "exists already"),
        ({"coupled": (1, 9999)}, "9999"),
        ({"kind": "glue"}, "unknown"),
        ({"coupled": ()}, "no nodes"),
        ({"kind": "springs"}, "stiffness"),
        ({"kind": "distributing", "coupled": (1, 2)}, "3 nodes"),
        ({"kind": "distributing", "coupled": (1, 7, 13)}, "on a line"),
    ],
)
def test_bad_interfaces(kwargs, message):
    truss = space_truss()
    spec = {"node": 900, "position": CENTRE, "coupled": (19, 20, 21), "kind": "rigid", **kwargs}
    with pytest.raises(UserError, match=message):
        add_interface_node(truss, InterfaceSpec(**spec))


def test_rigid_coupling_of_dependent_dofs_is_refused():
    body = spring_lattice()  # node 120's dofs are dependent already
    spec = InterfaceSpec(node=900, position=(0, 0, 0), coupled=(110, 120), kind="rigid")
    with pytest.raises(UserError, match="already dependent"):
        add_interface_node(body, spec)
