"""``[stress] sets = [...]``: hot spots given as node sets of the deck (issue #29 item 3), on the
genuine CalculiX bar of tests/data/calculix_stress_parts (its deck has ``*NSET, NSET=TIP``)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from pymorembs.errors import UserError
from pymorembs.job.cli import main
from pymorembs.job.run import prepare_job
from pymorembs.job.schema import load_job
from pymorembs.preparation import StressSpec, check_stress_spec, with_stress_outputs
from pymorembs.preparation.interface import InterfaceSpec, add_interface_node

PARTS = Path(__file__).parents[1] / "data" / "calculix_stress_parts"

JOB = """
[model]
file = "{model}"
[frame]
type = "none"
[[inputs]]
node = 5
directions = "ux uy uz"
[band]
f_max_hz = 5000
[[reduction]]
name = "modal"
method = "modal"
order = 6
[stress]
{stress}
"""


def job_file(folder: Path, stress: str, part: str = "bar") -> Path:
    path = folder / "job.toml"
    model = (PARTS / f"{part}.sti.gz").as_posix()
    path.write_text(JOB.format(model=model, stress=stress), encoding="utf-8")
    return path


def deck_set(part: str, name: str) -> list[int]:
    """The node labels of ``*NSET, NSET=name`` as the deck lists them (read here by hand)."""
    deck = (PARTS / f"{part}.inp").read_text()
    listed = deck.split(f"*NSET, NSET={name}\n")[1].split("*")[0]
    return [int(v) for v in listed.replace(",", " ").split()]


def hot_spots(folder: Path, stress: str):
    _, prepared = prepare_job(load_job(job_file(folder, stress)))
    return with_stress_outputs(prepared, load_job(job_file(folder, stress)).stress).hot_spots


@pytest.mark.parametrize("location", ["integration", "nodes"])
def test_a_set_gives_the_hot_spots_of_its_nodes_listed(tmp_path, location):
    tip = deck_set("bar", "TIP")
    by_set = hot_spots(tmp_path, f'sets = ["tip"]\nlocation = "{location}"')
    listed = hot_spots(tmp_path, f'nodes = {tip}\nlocation = "{location}"')
    assert by_set.as_dict() == listed.as_dict()
    assert by_set.operator.n_points == (21 if location == "nodes" else 4 * 27)
    assert (by_set.operator.matrix != listed.operator.matrix).nnz == 0


@pytest.mark.parametrize(
    ("stress", "message"),
    [
        (
            'sets = ["FILLET"]',
            "[stress].sets: FILLET is not a node set of the model (known: NALL, CLAMP, TIP)",
        ),
        ("sets = [3]", "[stress].sets: must be a list of node set names, got [3]"),
        ('sets = "TIP"', "[stress].sets: must be a list of node set names, got 'TIP'"),
    ],
)
def test_bad_sets_exit_2_with_one_line(tmp_path, capsys, stress, message):
    code = main(["reduce", str(job_file(tmp_path, stress)), "--out", str(tmp_path / "out")])
    err = capsys.readouterr().err
    lines = [line for line in err.splitlines() if line.startswith("pymorembs: error:")]
    assert code == 2 and len(lines) == 1 and message in lines[0] and "job.toml" in lines[0], err
    assert "frequency response" not in err and not (tmp_path / "out").exists()


def test_a_set_with_a_node_outside_the_elements():
    """A set that holds a node no element uses (here the reference node of a rigid interface):
    the message for such nodes; a set of no node of the model is refused too."""
    import pymorembs as pm

    body = pm.read(PARTS / "bar8.sti.gz")
    coupled = add_interface_node(body, InterfaceSpec(99999, (0.09, 0.0, 0.0), (5, 6, 7, 8)))
    coupled = coupled.with_node_sets({"REF": np.array([99999]), "GONE": np.array([4242])})
    with pytest.raises(UserError, match=r"^\[stress\]\.sets: node 99999 of set REF is not a node "
                                        "of the mesh's elements$"):  # fmt: skip
        check_stress_spec(coupled, StressSpec(sets=("TIP", "ref")))
    with pytest.raises(UserError, match=r"^\[stress\]\.sets: set GONE holds no node of the model$"):
        check_stress_spec(coupled, StressSpec(sets=("gone",)))


def test_sets_reach_the_api_too():
    import pymorembs as pm

    body = pm.read(PARTS / "bar8.sti.gz")
    tip = deck_set("bar8", "TIP")
    a = pm.prepare(body, "none", inputs=[pm.Port(5, "ux uy uz")], stress={"sets": ["Tip"]})
    b = pm.prepare(body, "none", inputs=[pm.Port(5, "ux uy uz")], stress={"nodes": tip})
    assert np.array_equal(a.hot_spots.operator.element_ids, b.hot_spots.operator.element_ids)
    assert (a.system.stress_matrix != b.system.stress_matrix).nnz == 0
