"""The served job schema is generated: a field added to a table's dataclass appears in it."""

from dataclasses import dataclass, field

from pymorembs.job import shape
from pymorembs.job.schema import InterfaceNodeSpec, Job, ModelSpec, ReductionSpec, in_file


def names(table: str) -> list[str]:
    return [key["name"] for key in shape.job_schema()["tables"][table]]


def test_a_new_field_of_a_table_appears_in_the_schema(monkeypatch):
    @dataclass(frozen=True)
    class Reduction(ReductionSpec):
        comment: str = ""

    @dataclass(frozen=True)
    class JobWithAuthor(Job):
        author: str = field(default="", metadata=in_file(key="written_by"))

    @dataclass(frozen=True)
    class Interface(InterfaceNodeSpec):
        label: str | None = None

    for name, cls in [("ReductionSpec", Reduction), ("Job", JobWithAuthor),
                      ("InterfaceNodeSpec", Interface)]:  # fmt: skip
        monkeypatch.setattr(shape, name, cls)
    assert names("reduction") == ["name", "method", "export_inaccurate", "comment"]
    assert names("job") == ["title", "written_by"]
    assert names("interface")[-1] == "label"


def test_the_generated_tables_are_the_files_keys():
    assert names("inputs") == names("outputs") == ["node", "directions"]
    interface = {key["name"]: key for key in shape.job_schema()["tables"]["interface"]}
    assert interface["nodes"] == {"name": "nodes", "type": "tuple[int, ...] | None",
                                  "default": None, "required": False}  # fmt: skip
    assert interface["node"]["required"] and "parameters" not in interface
    model = names("model")
    assert model[:3] == ["example", "format", "file"] and model.count("dofs") == 1
    assert {"stiffness_name", "hub_radius", "elements"} <= set(model)
    band = {key["name"]: key for key in shape.job_schema()["tables"]["band"]}
    assert band["reference"] == {"name": "reference", "type": "str", "default": "auto",
                                 "required": False}  # fmt: skip
    export = {key["name"]: key for key in shape.job_schema()["tables"]["export"]}
    assert export["outputs"]["type"] == "tuple[str, ...]"
    assert ModelSpec().options.given() == {}
