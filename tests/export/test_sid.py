"""SID (.SID_FEM) files: FEMBS files read, self-checks, brute-force dynamics, rack round trips."""

from __future__ import annotations

import re
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from test_invariants import cross_matrix, lumped_body
from threadpoolctl import threadpool_limits

from pymorembs.errors import NumericalError, UserError
from pymorembs.examples import build_example
from pymorembs.export.invariants import compute_invariants
from pymorembs.export.sid import (
    check_sid,
    check_sid_details,
    read_sid,
    sid_invariants,
    write_sid,
)
from pymorembs.linalg.products import extended_product
from pymorembs.preparation import Frame, Port, prepare
from pymorembs.reduction.modal import modal_reduction
from pymorembs.reduction.projection import reduced_model

REFERENCE = Path(__file__).parents[1] / "data" / "pymbs_fembs_sid"
FIVE_NODE = REFERENCE / "fembs_five_node_model.sid_fem"
FEMBS_FILES = sorted(REFERENCE.glob("fembs_*.sid_fem"))


# ================================================================================ FEMBS files
def test_all_four_fembs_files_are_read():
    assert len(FEMBS_FILES) == 4
    counts = {}
    for path in FEMBS_FILES:
        sid = read_sid(path)
        counts[path.name] = (sid.n_nodes, sid.nq, len(sid.nodes), len(sid.objects))
        assert sid.geometric_stiffening and sid.second_order_mass is None
        assert sid.nelastq == sid.nq == len(sid.ielastq)
    assert counts == {
        "fembs_example.sid_fem": (3, 3, 3, 11),
        "fembs_example_3_ev.sid_fem": (3, 3, 3, 11),
        "fembs_example_all_ev.sid_fem": (3, 6, 3, 11),
        "fembs_five_node_model.sid_fem": (5, 2, 5, 11),
    }


def test_five_node_file_values_land_at_their_indices():
    sid = read_sid(FIVE_NODE)
    assert list(sid.nodes) == [2519, 2523, 2520, 2521, 2522]  # file order
    assert sid.mass == 7.78470518692e02 and sid.name == ""
    assert np.allclose(sid.ielastq_frequencies_hz, [49.640, 63.453])
    ap = sid.nodes[2519]["AP"]
    assert ap.structure == 3 and np.array_equal(ap.m0, np.eye(3))
    assert ap.m1[1, 0, 0] == -2.03947509235e-04  # m1( 2, 1, 1): row 2, mode 1, column 1
    assert ap.m1[0, 1, 2] == -3.41399920341e-04  # m1( 1, 2, 3): row 1, mode 2, column 3
    origin = sid.nodes[2523]["origin"]  # tab-indented lines and "= 0" entries
    assert np.array_equal(origin.m0[:, 0], [4.46999126300e-01, 0.0, 0.0])
    assert origin.m1[2, 0, 0] == 5.84209454510e-02
    assert sid.nodes[2519]["origin"].m0.tolist() == [[0.0], [0.0], [0.0]]  # no m0 lines
    objects = sid.objects
    assert objects["Ct"].order == 1 and objects["Ct"].structure == 0 and not objects["Ct"].m1.any()
    assert objects["Gr"].m0[2, 0] == 4.34476628889e01 and objects["Gr"].m0.shape == (3, 6)
    assert objects["Oe"].m1[0, 1, 4] == 1.49649493812  # m1( 1, 2, 5)
    assert np.array_equal(objects["Me"].m0, np.eye(2))  # structure 2, diagonal only
    assert objects["De"].m0[1, 1] == pytest.approx(0.02 * objects["Ke"].m0[1, 1], rel=1e-11)
    values = sid_invariants(sid)
    assert values["inertia"][0, 1] == -1.33160e03 and values["inertia"][2, 1] == -8.15742e-01
    assert values["inertia"][0, 2] == -4.85084 and values["inertia"][2, 2] == 1.09244e04
    assert values["centre_of_gravity"][0] == pytest.approx(2.41505687484e03 / 7.78470518692e02)


def test_structure_codes_of_the_hand_edited_files():
    sid = read_sid(REFERENCE / "fembs_example_3_ev.sid_fem")
    ap = sid.nodes[3]["AP"]  # structure 4, no entries: identity
    assert ap.structure == 4 and ap.order == 0 and np.array_equal(ap.m0, np.eye(3))
    assert sid.nodes[3]["psi"].order == 1 and not sid.nodes[3]["psi"].m1.any()
    edited = read_sid(REFERENCE / "fembs_example.sid_fem")  # structure 4 with the 1s listed
    assert np.array_equal(edited.nodes[3]["AP"].m0, np.eye(3))
    me = read_sid(REFERENCE / "fembs_example_all_ev.sid_fem").objects["Me"]
    # structure 2 with both triangles listed: kept as written (they differ in the 10th digit)
    assert me.m0[4, 5] == 1.67948988050e-13 and me.m0[5, 4] == 1.67921232475e-13


def test_self_checks_on_the_fembs_files():
    """Checks 1-4 and the symmetry of Oe.M1 hold to the 12 printed digits (≤ 2e-12)."""
    for path in FEMBS_FILES:
        sid = read_sid(path)
        assert check_sid(sid, rtol=5e-12) == [], path.name
    details = {
        label: (status, dev) for label, status, dev in check_sid_details(read_sid(FIVE_NODE))
    }
    passed = [label for label, (status, _) in details.items() if status == "pass"]
    assert len(passed) == 7 and max(details[label][1] for label in passed) < 2e-12
    skipped = [label[:4] for label, (status, _) in details.items() if status.startswith("skip")]
    assert skipped == ["5 Cr", "6 Oe"]  # Geo_Stiff= yes
    # forced, they fail: Cr.M1 = antisymmetric Kr + a symmetric part (K0r), and Oe.M1 has K0ω
    assert len(check_sid(read_sid(FIVE_NODE), strict=True)) == 2
    cr1 = read_sid(FIVE_NODE).objects["Cr"].m1  # [k, l, a]
    antisymmetric = 0.5 * (cr1 - cr1.transpose(1, 0, 2))
    assert np.abs(antisymmetric[:, :, 1]).max() < 1e-12  # about y: only the symmetric K0r
    assert np.abs(antisymmetric[0, 1, 0]) == pytest.approx(0.902252673434)


# ============================================================ brute force (SID_NOTES §4.8 item 7)
def sid_inertia_forces(sid, a, alpha, w, q, qd, qdd):
    """Left side minus velocity terms of the SID equations of motion (SID_NOTES §3).

    Returns the forces (3,), torques (3,) and elastic forces (nq,) that balance the applied
    loads, from the objects of a parsed SID file (Gr and Ge read axis-major).
    """
    obj, nq = sid.objects, sid.nq
    mc = obj["mdCM"].at(q)[:, 0]
    j6 = obj["J"].at(q)[:, 0]
    jq = np.array([[j6[0], j6[3], j6[4]], [j6[3], j6[1], j6[5]], [j6[4], j6[5], j6[2]]])
    ct, cr = obj["Ct"].at(q), obj["Cr"].at(q)  # (nq, 3)
    gr = obj["Gr"].m0.reshape(3, 3, nq)  # [a, b, k]
    ge = obj["Ge"].m0.reshape(nq, 3, nq)  # [k, a, l]
    omega = np.array([w[0] ** 2, w[1] ** 2, w[2] ** 2, w[0] * w[1], w[1] * w[2], w[0] * w[2]])
    wx = cross_matrix(w)
    force = sid.mass * a - cross_matrix(mc) @ alpha + ct.T @ qdd
    force += wx @ wx @ mc + 2 * wx @ (ct.T @ qd)
    torque = cross_matrix(mc) @ a + jq @ alpha + cr.T @ qdd
    torque += wx @ jq @ w + np.einsum("abk,k,b->a", gr, qd, w)
    elastic = ct @ a + cr @ alpha + obj["Me"].m0 @ qdd
    elastic += np.einsum("kal,l,a->k", ge, qd, w) + obj["Oe"].at(q) @ omega
    return force, torque, elastic


def point_mass_forces(c, m, p, a, alpha, w, q, qd, qdd):
    """The same for point masses m_i at r_i = c_i + Φ_i q (Φ_i = p[i], body frame)."""
    u, ud, udd = p @ q, p @ qd, p @ qdd
    r = c + u
    acc = a + np.cross(alpha, r) + np.cross(w, np.cross(w, r)) + 2 * np.cross(w, ud) + udd
    force = m @ acc
    torque = np.einsum("i,ia->a", m, np.cross(r, acc))
    elastic = np.einsum("i,iak,ia->k", m, p, acc)
    # the part of the torque SID truncates: J's q² term and Gr's q q̇ term (SID_NOTES §3)
    dropped = np.cross(u, np.cross(alpha, u)) + np.cross(u, np.cross(w, np.cross(w, u)))
    dropped += 2 * np.cross(u, np.cross(w, ud))
    return force, torque, elastic, m @ dropped


@pytest.fixture(scope="module")
def lumped_file(tmp_path_factory):
    body, phi, m, _ = lumped_body(n_nodes=11, nq=4, seed=3)
    me = phi.T @ (body.mass @ phi)
    inv = compute_invariants(body, phi, me, np.diag([1e3, 2e3, 5e3, 9e3]), None, [100, 114, 121])
    path = write_sid(tmp_path_factory.mktemp("sid") / "lumped.SID_FEM", inv, comment="lumped")
    return body, phi, m, inv, path


def test_brute_force_point_mass_dynamics_equal_the_sid_equations(lumped_file):
    body, phi, m, inv, path = lumped_file
    sid = read_sid(path)  # Gr, Ge, Oe... as written to and read back from the file
    assert check_sid(sid) == []
    c = body.coordinates
    p = phi.reshape(-1, 3, inv.nq)
    rng = np.random.default_rng(11)
    for _ in range(5):
        a, alpha, w = rng.normal(size=(3, 3))
        q, qd, qdd = 0.05 * rng.normal(size=(3, inv.nq))
        force, torque, elastic = sid_inertia_forces(sid, a, alpha, w, q, qd, qdd)
        exact_f, exact_t, exact_e, dropped = point_mass_forces(c, m, p, a, alpha, w, q, qd, qdd)
        assert np.abs(force - exact_f).max() <= 1e-10 * np.abs(exact_f).max()
        assert np.abs(elastic - exact_e).max() <= 1e-10 * np.abs(exact_e).max()
        assert np.abs(dropped).max() > 1e-4 * np.abs(exact_t).max()  # the test sees them
        assert np.abs(torque + dropped - exact_t).max() <= 1e-10 * np.abs(exact_t).max()


def test_brute_force_rejects_the_per_mode_gr_layout_and_transposed_blocks(lumped_file):
    """The comparison fixes index orders: per-mode Gr blocks or Gr_kᵀ break it."""
    body, phi, m, inv, path = lumped_file
    sid = read_sid(path)
    nq = inv.nq
    gr = sid.objects["Gr"]
    blocks = gr.m0.reshape(3, 3, nq)  # [a, b, k]
    variants = {
        "per-mode": blocks.transpose(0, 2, 1).reshape(3, 3 * nq),  # m0(a, 3k + b)
        "transposed": blocks.transpose(1, 0, 2).reshape(3, 3 * nq),  # (Gr_k)_ba
    }
    rng = np.random.default_rng(12)
    a, alpha, w = rng.normal(size=(3, 3))
    q, qd, qdd = 0.05 * rng.normal(size=(3, nq))
    exact_t, dropped = point_mass_forces(body.coordinates, m, phi.reshape(-1, 3, nq),
                                         a, alpha, w, q, qd, qdd)[1::2]  # fmt: skip
    for label, m0 in variants.items():
        sid.objects["Gr"] = replace(gr, m0=m0)
        torque = sid_inertia_forces(sid, a, alpha, w, q, qd, qdd)[1]
        assert np.abs(torque + dropped - exact_t).max() > 1e-3 * np.abs(exact_t).max(), label


# ============================================================================ writer checks
def test_written_file_has_the_fembs_layout(lumped_file):
    *_, path = lumped_file
    text = path.read_text()
    lines = text.splitlines()
    assert re.match(r"^\s+3\s+4\s+:No\. nodes, No\. modes:SID generated by pymorembs ", lines[0])
    assert "Geo_Stiff= no, second-order mass= exact; lumped" in lines[0]
    assert not re.search(r"\d[eE][+-]\d", text)  # Fortran D exponents only
    numbers = re.findall(r"=\s*(\S*D\S*)$", text, flags=re.MULTILINE)
    assert numbers and all(re.fullmatch(r"-?\d\.\d{11}D[+-]\d\d", n) for n in numbers)
    assert "new frame" not in text and re.search(r"^\s+frame$", text, flags=re.MULTILINE)
    # loop orders: m0 row-major; m1 column j outermost, then row i, then mode k
    for name in ("Oe", "Cr", "J", "Gr"):
        block = re.search(rf"^\s+{name}\n(.*?)^\s+end {name}$", text, re.MULTILINE | re.DOTALL)
        m0 = [tuple(map(int, t)) for t in re.findall(r"m0\(\s*(\d+),\s*(\d+)\)", block[1])]
        m1 = [tuple(map(int, t)) for t in re.findall(r"m1\(\s*(\d+),\s*(\d+),\s*(\d+)\)", block[1])]
        assert m0 == sorted(m0)
        assert m1 == sorted(m1, key=lambda ikj: (ikj[2], ikj[0], ikj[1]))
    assert len(re.findall(r"m1\(", text)) > 100


def test_line_shapes_match_the_fembs_five_node_file(lumped_file):
    *_, path = lumped_file

    def shape(line: str) -> str:
        line = re.sub(r"(new modal\s+=).*", r"\1 <name>", line.rstrip())
        return re.sub(r" *(?<![A-Za-z])[-+]?\d[\d.]*(?:D[+-]\d+)?", "#", line)

    reference = [shape(line) for line in FIVE_NODE.read_text().splitlines()[1:] if "\t" not in line]
    ours = [shape(line) for line in path.read_text().splitlines()[1:]]
    assert set(ours) <= set(reference), set(ours) - set(reference)

    # the skeleton after the frame (object names and Taylor headers) is the same
    def skeleton(shapes):
        rest = shapes[shapes.index("           end frame") :]
        return [s for s in rest if not re.search(r"m[01]\(", s)]

    ours_skeleton, reference_skeleton = skeleton(ours), skeleton(reference)
    assert [s for s in ours_skeleton if "=" not in s] == [
        s for s in reference_skeleton if "=" not in s
    ]
    assert len(ours_skeleton) == len(reference_skeleton)


def test_write_refuses_non_finite_or_inconsistent_data(tmp_path, lumped_file):
    *_, inv, _ = lumped_file
    target = tmp_path / "bad.SID_FEM"
    ct = inv.Ct.copy()
    ct[1, 2] = np.nan
    with pytest.raises(NumericalError, match=r"NaN or infinite values in .*Ct"):
        write_sid(target, replace(inv, Ct=ct))
    with pytest.raises(NumericalError, match="check 6"):  # Me is not Φᵀ M Φ
        write_sid(target, replace(inv, Me=2.0 * inv.Me))
    assert list(tmp_path.iterdir()) == []


# ===================================================================== bad files: UserError
@pytest.mark.parametrize(
    ("edit", "message"),
    [
        (lambda t: t[: len(t) // 2], "unexpected end of file"),
        (lambda t: t.replace("    5   2", "    6   2", 1), "announces 6 nodes"),
        (lambda t: t.replace("    5   2", "    5   3", 1), "nelastq = 2 but the header"),
        (lambda t: t.replace("=-5.77787524927D-05", "=-5.7778X524927D-05", 1), "not a number"),
        (lambda t: t.replace("           Gr      ", "           Gx      ", 1), "unknown keyword"),
        (lambda t: t.replace("m0( 3, 6)             = 5.6", "m0( 3, 7)             = 5.6"),
         "outside 3 × 6"),
        (lambda t: t.replace("structure             =    0", "structure             =    9", 1),
         "structure 9"),
        (lambda t: t.replace("nq                    =    2", "nq                    =    3", 1),
         "nq = 3 but"),
        (lambda t: "garbage\n" + t, "header line"),
        (lambda t: t.replace(" end part", " end part\n part"), "after 'end part'"),
    ],
)  # fmt: skip
def test_bad_files_are_user_errors_with_file_and_line(tmp_path, edit, message):
    path = tmp_path / "edited.sid_fem"
    path.write_text(edit(FIVE_NODE.read_text()))
    with pytest.raises(UserError, match=re.escape(message)) as info:
        read_sid(path)
    assert re.match(rf"^{re.escape(str(path))}:\d+: ", str(info.value))


def test_structure_violations_and_missing_files(tmp_path, lumped_file):
    *_, path = lumped_file
    text = path.read_text()
    edited = tmp_path / "edited.sid_fem"
    # an entry off the diagonal of a structure-1 object (Ke is diagonal)
    ke = re.search(r"^\s+Ke\n(?:.*\n)*?.*m0\( 1, 1\).*\n", text, re.MULTILINE)
    edited.write_text(text.replace(ke[0], ke[0] + " m0( 1, 2) = 1.0D+00\n"))
    with pytest.raises(UserError, match="off the diagonal"):
        read_sid(edited)
    edited.write_text(text.replace("end Me", " m1( 1, 1, 1) = 1.0D+00\n end Me"))
    with pytest.raises(UserError, match="m1 entry in an object of order 0"):
        read_sid(edited)
    with pytest.raises(UserError, match="cannot read"):
        read_sid(tmp_path / "missing.sid_fem")


# ======================================================== done when: the racks, written and read
def independent_rigid_body_data(body):
    """m, ∫c dm and J0 from the full M with R = [S_t S_r] built here dof by dof."""
    n = body.n_dof
    s_t, s_r = np.zeros((n, 3)), np.zeros((n, 3))
    position = dict(zip(body.node_ids.tolist(), body.coordinates, strict=True))
    for i, (node, d) in enumerate(zip(body.dofs.nodes, body.dofs.directions, strict=True)):
        if d < 3:
            s_t[i, d] = 1.0
            s_r[i] = -cross_matrix(position[int(node)])[d]  # u = θ × c = -c̃ θ
        else:
            s_r[i, d - 3] = 1.0
    mass = body.mass
    m = (s_t.T @ (mass @ s_t)).trace() / 3
    mc = s_r.T @ (mass @ s_t)  # = m c̃
    return m, np.array([mc[2, 1], mc[0, 2], mc[1, 0]]), s_r.T @ (mass @ s_r)


CASES = {
    "beams-tangent": ("rack-beams", {}, Frame("tangent", 2), "exact"),
    "beams-buckens": ("rack-beams", {}, Frame("buckens"), "exact"),
    "solid-tangent": ("rack-solid", {"dofs": 7400, "interface": "rigid"}, Frame("tangent", 2),
                      "exact"),
    "solid-buckens": ("rack-solid", {"dofs": 7400, "interface": "rigid"}, Frame("buckens"),
                      "exact"),
}  # fmt: skip


@pytest.mark.parametrize("case", list(CASES))
def test_racks_written_and_read_keep_rigid_body_data_and_reduced_matrices(tmp_path, case):
    example, options, frame, second_order = CASES[case]
    ports = [Port.parse(1, "ux uy uz"), Port.parse(2, "ux uy uz")]
    with threadpool_limits(1):
        body = build_example(example, **options)
        prepared = prepare(body, frame, ports, ports)
        model = reduced_model(prepared.system, modal_reduction(prepared.system, 8))
        phi = prepared.expand(model.projection.V)
        inv = compute_invariants(
            prepared.body, phi, model.system.mass, model.system.stiffness,
            model.damping_matrix, [1, 2], model.eigenfrequencies_hz, name=example,
        )  # fmt: skip
        sid = read_sid(write_sid(tmp_path / f"{case}.SID_FEM", inv))
        frame_body = prepared.body
        m, first_moment, inertia = independent_rigid_body_data(frame_body)
        me = phi.T @ extended_product(frame_body.mass, phi)
        ke = phi.T @ extended_product(frame_body.stiffness, phi)
    assert inv.second_order_mass == second_order
    assert check_sid(sid) == []
    values = sid_invariants(sid)
    length = np.abs(frame_body.coordinates).max()
    assert values["mass"] == pytest.approx(m, rel=1e-10)
    assert np.abs(values["first_moment"] - first_moment).max() <= 1e-10 * m * length
    assert np.abs(values["inertia"] - inertia).max() <= 1e-10 * np.abs(inertia).max()
    assert np.abs(values["Me"] - me).max() <= 1e-10 * np.abs(me).max()
    assert np.abs(values["Ke"] - ke).max() <= 1e-9 * np.abs(ke).max()  # 1.05e-10 on AVX-512
    assert np.abs(inv.Me - me).max() <= 1e-10 and np.abs(inv.Ke - ke).max() <= 1e-9 * ke.max()
    # node frames: origin and phi of node 1 are its position and rows of Φ
    node = sid.nodes[1]
    rows = [frame_body.dofs.index(1, d) for d in range(3)]
    assert np.allclose(node["origin"].m0[:, 0], frame_body.node_position(1), rtol=1e-11)
    assert np.abs(node["phi"].m0 - phi[rows]).max() <= 1e-11 * np.abs(phi[rows]).max()
    assert sid.nodes[1]["AP"].order == 1
    if frame.kind == "tangent":  # the frame node does not move
        assert not sid.nodes[2]["phi"].m0.any() and sid.nodes[2]["AP"].structure == 4
    else:  # Buckens: mean axes, ∫Φ dm = 0, centre of gravity at the origin
        assert np.abs(inv.Ct).max() < 1e-12 and np.abs(values["first_moment"]).max() < 1e-14
    if second_order == "translational":
        labels = {label[0]: status for label, status, _ in check_sid_details(sid)}
        assert labels["6"].startswith("skipped: second-order terms from the translational")


def test_sid_invariants_needs_the_objects(lumped_file):
    *_, path = lumped_file
    sid = read_sid(path)
    del sid.objects["J"]
    with pytest.raises(UserError, match="lacks J"):
        sid_invariants(sid)


def test_preparation_and_invariants_leave_the_callers_matrices_as_they_were():
    """Neither the preparation (the mass split of the massless-mechanism search) nor the body
    invariants change a matrix they were given: ``csr_matrix(A)`` shares ``A``'s arrays, and
    dropping small or stored-zero entries in place once left the body's mass with fewer entries
    than its arrays hold (a later merged pattern of it then failed). The solid rack has stored
    zeros in M and no beams, so both paths run."""
    body = build_example("rack-solid", dofs=7400)  # its eliminated M stores 216 zeros
    snapshot = [a.copy() for a in (body.mass.data, body.mass.indices, body.mass.indptr)]
    ports = [Port.parse(1, "ux uy uz")]
    with threadpool_limits(1):
        prepared = prepare(body, Frame("tangent", 2), ports, ports)
        mass = prepared.system.mass
        assert mass.nnz == mass.data.size and not np.all(mass.data)  # stored zeros kept
        frame_body = prepared.body
        framed = [a.copy() for a in (frame_body.mass.data, frame_body.mass.indptr)]
        model = reduced_model(prepared.system, modal_reduction(prepared.system, 6))
        compute_invariants(
            frame_body, prepared.expand(model.projection.V), model.system.mass,
            model.system.stiffness, model.damping_matrix, [1, 2], model.eigenfrequencies_hz,
        )  # fmt: skip
    now = (body.mass.data, body.mass.indices, body.mass.indptr)
    for before, after in zip(snapshot, now, strict=True):
        assert np.array_equal(before, after)
    assert np.array_equal(framed[0], frame_body.mass.data)
    assert np.array_equal(framed[1], frame_body.mass.indptr)
    assert frame_body.mass.nnz == frame_body.mass.data.size
