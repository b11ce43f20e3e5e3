"""The kinds of the library are the enums of pymorembs.kinds, in the Python API and in a job."""

from pathlib import Path

import pytest

from pymorembs import Damping, Frame, UserError
from pymorembs.job.schema import parse_job
from pymorembs.kinds import DampingKind, FrameType, InterfaceKind, ReferenceKind
from pymorembs.preparation import InterfaceSpec


def test_a_frame_takes_a_name_and_holds_its_type():
    assert Frame("tangent", 2).kind is FrameType.TANGENT
    assert Frame(FrameType.BUCKENS).kind is FrameType.BUCKENS
    assert Frame().kind is FrameType.TANGENT and Frame("none").kind == "none"
    assert Frame("tangent", 2).describe() == "tangent at node 2"
    with pytest.raises(UserError, match="frame type 'spinning' is unknown"):
        Frame("spinning")


def test_damping_takes_a_name_and_holds_its_kind():
    assert Damping("modal", ratio=0.02).kind is DampingKind.MODAL
    assert Damping().kind is DampingKind.NONE
    assert Damping("rayleigh", alpha=1.0).describe() == "rayleigh, alpha 1 1/s, beta 0 s"
    with pytest.raises(UserError, match="does not belong to kind 'none', which takes no values"):
        Damping("none", ratio=0.1)


def test_an_interface_takes_a_name_and_holds_its_kind():
    spec = InterfaceSpec(node=9, position=(0.0, 0.0, 0.0), coupled=(1, 2, 3), kind="beams")
    assert spec.kind is InterfaceKind.BEAMS


def test_a_job_holds_the_kinds_of_its_frame_damping_and_interfaces():
    data = {
        "model": {"example": "rack-beams"},
        "frame": {"type": "tangent", "node": 2},
        "damping": {"kind": "modal", "ratio": 0.01},
        "interface": [
            {"node": 7, "position": [0, 0, 0], "kind": "springs", "nodes": [1], "stiffness": 1e6}
        ],
        "band": {"f_max_hz": 100.0},
        "reduction": [{"method": "modal", "order": 4}],
    }
    job = parse_job(data, Path("job.toml"))
    assert job.frame.kind is FrameType.TANGENT
    assert job.damping is not None and job.damping.kind is DampingKind.MODAL
    assert job.interfaces[0].kind is InterfaceKind.SPRINGS


def test_a_job_holds_its_export_and_reference_kinds():
    from pymorembs.export import EXPORTS, OutputKind

    assert [kind.value for kind in OutputKind] == list(EXPORTS)  # made from the registry
    data = {
        "model": {"example": "rack-beams"},
        "frame": {"type": "none"},
        "band": {"f_max_hz": 100.0, "reference": "full"},
        "reduction": [{"method": "modal", "order": 4}],
        "export": {"outputs": ["sid", "npz"]},
    }
    job = parse_job(data, Path("job.toml"))
    assert job.export.outputs == (OutputKind.SID, OutputKind.NPZ)
    assert all(type(kind) is OutputKind for kind in job.export.outputs)
    assert job.band.reference is ReferenceKind.FULL and job.reference == "full"


def test_a_jobs_example_options_are_typed():
    from pymorembs.examples import ExampleOptions
    from pymorembs.job.schema import ModelSpec

    data = {
        "model": {"example": "blade", "hub_radius": 0.1, "elements": 8},
        "frame": {"type": "none"},
        "band": {"f_max_hz": 100.0},
        "reduction": [{"method": "modal", "order": 4}],
    }
    job = parse_job(data, Path("job.toml"))
    assert job.model.options == ExampleOptions(hub_radius=0.1, elements=8)
    assert job.model.options.given() == {"hub_radius": 0.1, "elements": 8}
    given = ModelSpec(example="rack-solid", options={"dofs": 2000})  # by name, as the app gives
    assert given.options == ExampleOptions(dofs=2000)
    with pytest.raises(UserError, match="example blade has no option 'dofs'"):
        ModelSpec(example="blade", options={"dofs": 2000})
    data["model"]["elements"] = 2
    with pytest.raises(UserError, match=r"\[model\]\.elements: must be >= 4, got 2"):
        parse_job(data, Path("job.toml"))
